/* The colour pipeline: frames keep linear colour unclamped, so an HDR sky
   survives into the frame (and from there into EXR files) in every method
   that shows it; the display transform (exposure, tone map, sRGB) gives
   the known answers of its equations. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdint.h>

#include "../../reflect.h"
#include "refl_test_util.h"

Test(refl_colour, display_channel_known_answers) {
    refl_display_desc d;
    memset(&d, 0, sizeof d);
    /* sRGB 128 decodes to linear 0.21586; and back */
    cr_assert_eq(refl_display_channel(0.2158605f, NULL), 128);
    cr_assert_eq(refl_display_channel(0.0f, NULL), 0);
    cr_assert_eq(refl_display_channel(1.0f, NULL), 255);
    cr_assert_eq(refl_display_channel(4.0f, NULL), 255, "no tone map: clipped");
    cr_assert_eq(refl_display_channel(-1.0f, NULL), 0);
    cr_assert_eq(refl_display_channel(NAN, NULL), 0);
    cr_assert_eq(refl_display_channel(INFINITY, NULL), 255);
    /* the linear segment below 0.0031308: 12.92 x */
    cr_assert_eq(refl_display_channel(0.002f, NULL), 7); /* 0.02584 * 255 = 6.59 */
    d.exposure = -2.0f; /* 4 -> 1 */
    cr_assert_eq(refl_display_channel(4.0f, &d), 255);
    cr_assert_eq(refl_display_channel(0.863442f, &d), 128); /* 0.2158605 * 4 */
    d.exposure = 0.0f;
    d.tonemap = REFL_TONEMAP_REINHARD; /* 4 -> 0.8 -> sRGB 0.9063 -> 231 */
    cr_assert_eq(refl_display_channel(4.0f, &d), 231);
    cr_assert_eq(refl_display_channel(1e30f, &d), 255);
    cr_assert_eq(refl_display_channel(INFINITY, &d), 255);
    d.tonemap = REFL_TONEMAP_ACES; /* 1 -> 2.54 / 3.16 = 0.80380 -> sRGB 0.9085 -> 232 */
    cr_assert_eq(refl_display_channel(1.0f, &d), 232);
    cr_assert_eq(refl_display_channel(INFINITY, &d), 255);
    cr_assert_eq(refl_display_channel(1e30f, &d), 255);
}

Test(refl_colour, frame_to_srgb8_encodes_every_pixel_and_keeps_alpha) {
    refl_frame *f;
    uint8_t out[4 * 2];
    cr_assert_eq(refl_frame_create(2, 1, NULL, &f), REFL_OK);
    f->rgba[0] = f->rgba[1] = f->rgba[2] = 0.2158605f;
    f->rgba[3] = 1.0f;
    f->rgba[4] = 2.0f; f->rgba[5] = 0.0f; f->rgba[6] = NAN;
    f->rgba[7] = 0.5f;
    refl_frame_to_srgb8(f, NULL, out);
    cr_assert(out[0] == 128 && out[1] == 128 && out[2] == 128 && out[3] == 255);
    cr_assert(out[4] == 255 && out[5] == 0 && out[6] == 0 && out[7] == 128);
    refl_frame_destroy(f);
}

/* A sky of linear 4: every method shows 4 on the sky's pixels, and on its
   reflectors something brighter than 1 (the teapot reflects the sky). */
Test(refl_colour, an_hdr_sky_survives_into_every_method_s_frame, .timeout = 120) {
    int m;
    for (m = REFL_DIRECT; m < REFL_METHOD_COUNT; ++m) {
        refl_view v;
        refl_scene *s = tu_refl_builtin("default", &v, 64, 48);
        refl_render_desc d = tu_refl_one_bounce((refl_method)m, 2);
        refl_frame *f;
        float brightest = 0.0f;
        int i, c, sky = 0, n = 64 * 48;
        s->environment.type = REFL_ENV_COLOR; /* a constant sky */
        s->environment.intensity = 1.0f;
        for (c = 0; c < 3; ++c) s->environment.color[c] = 4.0f;
        cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &f), REFL_OK);
        if (refl_render(s, &v, &d, f) == REFL_ERROR_UNSUPPORTED) {
            refl_frame_destroy(f);
            refl_scene_destroy(s);
            continue;
        }
        for (i = 0; i < n; ++i) {
            if (!f->stencil[i] && f->depth[i] >= 1.0f) {
                ++sky;
                for (c = 0; c < 3; ++c)
                    cr_assert_eq(f->rgba[4 * i + c], 4.0f, "%s: sky pixel %d: %g", refl_method_name((refl_method)m), i,
                                 f->rgba[4 * i + c]);
            }
            if (f->stencil[i]) brightest = fmaxf(brightest, f->rgba[4 * i + 1]);
        }
        cr_assert_gt(sky, n / 4, "%s: %d sky pixels", refl_method_name((refl_method)m), sky);
        if (m != REFL_DIRECT)
            cr_assert_gt(brightest, 1.0f, "%s: the brightest reflector pixel is %g", refl_method_name((refl_method)m),
                         brightest);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
}
