/* desc.spp: each pixel the mean of sqrt(spp) x sqrt(spp) samples, and the
   depth, stencil and point of its centre sample, so that with an odd side
   the reflection error compares with truth exactly as at one sample. */
#include <criterion/criterion.h>
#include <math.h>

#include "../../reflect.h"
#include "refl_test_util.h"

static refl_frame *render_spp(const char *scene, refl_method m, int spp, int w, int h) {
    refl_view v;
    refl_scene *s = tu_refl_builtin(scene, &v, w, h);
    refl_render_desc d = tu_refl_one_bounce(m, 2);
    refl_frame *f;
    d.spp = spp;
    f = tu_refl_render(s, &v, &d);
    refl_scene_destroy(s);
    return f;
}

Test(refl_spp, an_odd_side_keeps_the_pixel_centres_depth_stencil_and_points, .timeout = 120) {
    static const refl_method methods[] = {REFL_RAYTRACE, REFL_ENVMAP, REFL_PLANAR, REFL_C3RC, REFL_SBC};
    size_t k;
    for (k = 0; k < sizeof methods / sizeof methods[0]; ++k) {
        refl_frame *one = render_spp("default", methods[k], 1, 48, 36), *nine = render_spp("default", methods[k], 9, 48, 36);
        size_t i, n = 48 * 36;
        const char *name = refl_method_name(methods[k]);
        int stencil_differs = 0;
        if (methods[k] == REFL_RAYTRACE) { /* every pixel from its own ray: the same bits */
            cr_assert_eq(memcmp(one->stencil, nine->stencil, n), 0, "%s: stencil", name);
            cr_assert_eq(memcmp(one->depth, nine->depth, n * sizeof(float)), 0, "%s: depth", name);
            for (i = 0; i < n; ++i)
                cr_assert(tu_refl_same_point(one->points + 3 * i, nine->points + 3 * i), "%s: point %zu", name, i);
        }
        /* rasterised at three times the size, the same sample positions
           snap to a finer grid: the same depth to rounding, the stencil
           alike but at a few edge pixels */
        for (i = 0; i < n; ++i) {
            stencil_differs += one->stencil[i] != nine->stencil[i];
            if (one->stencil[i] == nine->stencil[i])
                cr_assert(fabsf(one->depth[i] - nine->depth[i]) < 1e-5f, "%s: depth %zu: %.9g %.9g", name, i,
                          one->depth[i], nine->depth[i]);
        }
        cr_assert_leq(stencil_differs, (int)n / 200, "%s: %d stencil values differ", name, stencil_differs);
        for (i = 0; i < n; ++i) cr_assert_eq(nine->rgba[4 * i + 3], 1.0f, "%s: pixel %zu is not opaque", name, i);
        refl_frame_destroy(one);
        refl_frame_destroy(nine);
    }
}

/* The colour is the mean of the samples: a frame rendered at three times
   the size, averaged 3 x 3, gives the same floats (to rounding). */
Test(refl_spp, each_pixel_is_the_mean_of_its_samples) {
    refl_frame *nine = render_spp("glass", REFL_RAYTRACE, 9, 40, 30), *fine = render_spp("glass", REFL_RAYTRACE, 1, 120, 90);
    int x, y, c, sx, sy, edges = 0;
    for (y = 0; y < 30; ++y)
        for (x = 0; x < 40; ++x)
            for (c = 0; c < 3; ++c) {
                float sum = 0.0f;
                for (sy = 0; sy < 3; ++sy)
                    for (sx = 0; sx < 3; ++sx) sum += fine->rgba[4 * ((size_t)(3 * y + sy) * 120 + (size_t)(3 * x + sx)) + c];
                cr_assert(fabsf(nine->rgba[4 * ((size_t)y * 40 + (size_t)x) + c] - sum / 9.0f) < 1e-5f, "pixel %d,%d", x, y);
                edges += fabsf(fine->rgba[4 * ((size_t)(3 * y) * 120 + (size_t)(3 * x)) + c] - sum / 9.0f) > 0.05f;
            }
    cr_assert_gt(edges, 20, "the view must have edges the samples smooth (%d)", edges);
    refl_frame_destroy(nine);
    refl_frame_destroy(fine);
}

Test(refl_spp, a_sample_count_that_is_not_a_square_is_refused_by_name) {
    static const int bad[] = {-1, 2, 3, 8, 65, 81};
    refl_render_desc d;
    const char *why;
    size_t k;
    memset(&d, 0, sizeof d);
    for (k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        d.spp = bad[k];
        cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT, "spp %d", bad[k]);
        cr_assert(strstr(why, "spp") != NULL, "%s", why);
    }
    d.spp = 64;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_OK);
}

/* The fine frame may not exceed the rasteriser's targets. */
Test(refl_spp, a_fine_frame_past_the_target_size_is_refused) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 4000, 2);
    refl_render_desc d = tu_refl_one_bounce(REFL_DIRECT, 1);
    refl_frame *f;
    d.spp = 25;
    cr_assert_eq(refl_frame_create(4000, 2, NULL, &f), REFL_OK);
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_SIZE);
    cr_assert(strstr(f->message, "spp") != NULL, "%s", f->message);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}
