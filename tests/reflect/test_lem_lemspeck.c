/* LAYERED_EM's maps are CGLS's unconstrained least squares: a texel held
   only by small bilinear weights in rows across a sharp edge (the floor
   under `hybrid`'s glass teapot, seen by the refracted exit rays) swings
   below 0 to fit its neighbours. A pixel whose lookup lands on it got a
   negative colour and was drawn black where greedy RAYTRACE is bright.
   Radiance is never negative: neither may the maps' colours be. */
#include <criterion/criterion.h>
#include "../../reflect.h"
#include "refl_test_util.h"

static refl_frame *render(const refl_scene *s, const refl_view *v, refl_method m) {
    refl_render_desc d = tu_refl_desc(m, 2);
    d.raytrace.greedy = 1; /* RAYTRACE's option; LAYERED_EM keeps its defaults */
    return tu_refl_render(s, v, &d);
}

Test(lem_lemspeck, default_maps_draw_no_negative_colour) {
    /* `hybrid` at 160 x 120, default options: lens pixels with a negative
       channel, and black ones where greedy RAYTRACE has a channel over 0.2 */
    refl_view v;
    refl_scene *s = tu_refl_builtin("hybrid", &v, 160, 120);
    refl_frame *truth, *lem;
    size_t n = (size_t)v.width * (size_t)v.height, px;
    int pixels = 0, negative = 0, black = 0;
    truth = render(s, &v, REFL_RAYTRACE);
    lem = render(s, &v, REFL_LAYERED_EM);
    for (px = 0; px < n; ++px) {
        const float *a = lem->rgba + 4 * px, *t = truth->rgba + 4 * px;
        if (truth->stencil[px] == 0) continue;
        ++pixels;
        negative += a[0] < 0.0f || a[1] < 0.0f || a[2] < 0.0f;
        black += a[0] <= 0.0f && a[1] <= 0.0f && a[2] <= 0.0f && (t[0] > 0.2f || t[1] > 0.2f || t[2] > 0.2f);
    }
    cr_log_info("hybrid 160x120: %d of the lenses' %d pixels negative, %d black where greedy RAYTRACE is bright",
                negative, pixels, black);
    cr_assert_gt(pixels, 1000);
    cr_assert_eq(negative, 0, "%d of the lenses' %d pixels have a negative channel", negative, pixels);
    cr_assert_eq(black, 0, "%d of the lenses' %d pixels black where greedy RAYTRACE is bright", black, pixels);
    refl_frame_destroy(truth);
    refl_frame_destroy(lem);
    refl_scene_destroy(s);
}
