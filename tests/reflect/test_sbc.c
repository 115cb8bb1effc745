/* SBC, the sample-based camera method (paper 003): against the one-bounce
   ray-traced reference with the reflection-error metric, at a small size.
   What is asserted: a well-formed frame (DIRECT's bytes off the
   reflectors, points NaN in all three coordinates or none, opaque
   reflector pixels), the same bytes for any thread count, and the
   accuracy measured as a regression bound (the 1 px goal holds in
   pinhole leaves; ray lists and holes at silhouettes keep the image short
   of it, see m_sbc.c); bad desc values. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

static refl_render_desc sbc_desc(refl_method m, int threads) { return tu_refl_one_bounce(m, threads); }

/* Measured (128x96, ray map factor 2, 1 px camera bound): default mean
   0.62, p95 1.41 px, wrong 0.2%, holes 11.2%, 49 pinhole and 65 ray-list
   leaves; concave mean 0.26, p95 1.41 px, wrong 3.8%, holes 2.7%, all
   ray lists (the mirror focuses every group's rays; mean 0.57, p95 3.16
   px, wrong 7.4%, holes 4.5% before the sheets and crack filling). When SBC
   landed (tiles as groups): default mean 1.96, p95 7.1 px, wrong 0.3%,
   holes 17.7%; concave mean 0.59, p95 3.6 px, holes 6.7%. The bounds are
   the measurements with a little room. */
static void sbc_accuracy(const char *name, double max_mean, double max_p95, double max_wrong, double max_holes) {
    refl_view v;
    refl_scene *s = tu_refl_builtin(name, &v, 128, 96);
    refl_render_desc d = sbc_desc(REFL_SBC, 2), t = sbc_desc(REFL_RAYTRACE, 2), dd = sbc_desc(REFL_DIRECT, 2);
    refl_frame *f = tu_refl_render(s, &v, &d), *truth = tu_refl_render(s, &v, &t), *direct = tu_refl_render(s, &v, &dd);
    refl_reflection_error e;
    tu_assert_reflector_frame(f, direct);
    cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &e), REFL_OK);
    cr_log_info("SBC %s 128x96: mean %.2f p95 %.2f max %.1f px, wrong %.3f, holes %.3f, %lld pinhole and %lld ray-list "
                "leaves", name, e.mean, e.p95, e.max, e.wrong, e.empty, f->stats.sbc.pinhole_leaves, f->stats.sbc.ray_leaves);
    cr_assert(e.pixels > 500, "%lld reflector pixels", e.pixels);
    cr_assert(e.mean <= max_mean && e.p95 <= max_p95, "%s: mean %.2f p95 %.2f", name, e.mean, e.p95);
    cr_assert(e.wrong <= max_wrong && e.empty <= max_holes, "%s: wrong %.3f holes %.3f", name, e.wrong, e.empty);
    cr_assert(f->stats.sbc.pinhole_leaves + f->stats.sbc.ray_leaves > 0 && f->stats.rays > 0);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_frame_destroy(direct);
    refl_scene_destroy(s);
}

Test(refl_sbc, default_scene_accuracy, .timeout = 120) { sbc_accuracy("default", 0.75, 1.5, 0.01, 0.13); }
/* the bowl's tiles meet without cracks (refl_sbc_seams): holes 0.2%, 2.7% when a
   reflected triangle across a tile border was split 4 times and dropped */
Test(refl_sbc, concave_mirror_accuracy, .timeout = 120) { sbc_accuracy("concave", 0.4, 2.0, 0.05, 0.005); }

/* The ball at the bowl's focus lies across the caustic: its near side's
   reflected triangles straddle the fold of the group's rays, too wide to
   draw, and the depth test showed the ball's far side there, a ring of
   bright streaks across the bowl. In a group whose rays fold, a point the
   ray map's samples contradict goes to the tracer (SBC-traced), so the
   image is the truth's (measured at 160x120: wrong 0.01%, PSNR 46.5 dB
   over the reflector; without it wrong 3.4%, PSNR 24.2 dB). */
Test(refl_sbc, concave_fold_contradictions_go_to_the_tracer, .timeout = 120) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("concave", &v, 160, 120);
    refl_render_desc d = sbc_desc(REFL_SBC, 2), t = sbc_desc(REFL_RAYTRACE, 2);
    refl_frame *f = tu_refl_render(s, &v, &d), *truth = tu_refl_render(s, &v, &t);
    refl_reflection_error e;
    refl_image_error img;
    cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &e), REFL_OK);
    cr_assert_eq(refl_measure_image_error(f, truth, 1, 0.0f, &img), REFL_OK);
    cr_log_info("SBC concave 160x120: mean %.3f, wrong %.4f, holes %.4f, PSNR %.2f dB, %lld rays", e.mean, e.wrong,
                e.empty, img.psnr, f->stats.rays);
    cr_assert(e.wrong <= 0.002 && e.empty <= 0.002, "wrong %.4f, holes %.4f", e.wrong, e.empty);
    cr_assert(img.psnr >= 35.0, "PSNR %.2f dB", img.psnr);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

Test(refl_sbc, same_bytes_for_any_thread_count, .timeout = 120) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 96, 72);
    refl_render_desc a = sbc_desc(REFL_SBC, 1), b = sbc_desc(REFL_SBC, 3);
    refl_frame *fa = tu_refl_render(s, &v, &a), *fb = tu_refl_render(s, &v, &b);
    size_t n = (size_t)v.width * (size_t)v.height;
    cr_assert_eq(memcmp(fa->rgba, fb->rgba, (4 * n) * sizeof(float)), 0);
    cr_assert_eq(memcmp(fa->points, fb->points, 3 * n * sizeof(float)), 0);
    refl_frame_destroy(fa);
    refl_frame_destroy(fb);
    refl_scene_destroy(s);
}

/* Groups are projected and drawn in batches (the stencil holds 254 group
   values; past that the batches reuse them): the frame must be the same
   bytes whatever the batch. */
Test(refl_sbc, same_bytes_for_any_group_batch, .timeout = 120) {
    static const int batches[] = {1, 7};
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 96, 72);
    refl_render_desc d = sbc_desc(REFL_SBC, 2);
    refl_frame *ref = tu_refl_render(s, &v, &d);
    size_t n = (size_t)v.width * (size_t)v.height, k;
    cr_assert(ref->stats.sbc.pinhole_leaves + ref->stats.sbc.ray_leaves > 7, "too few groups for batches to matter");
    for (k = 0; k < sizeof batches / sizeof batches[0]; ++k) {
        refl_frame *f;
        d.sbc.batch_groups = batches[k];
        f = tu_refl_render(s, &v, &d);
        cr_assert_eq(memcmp(ref->rgba, f->rgba, (4 * n) * sizeof(float)), 0, "batch %d: colour differs", batches[k]);
        cr_assert_eq(memcmp(ref->points, f->points, 3 * n * sizeof(float)), 0, "batch %d: points differ", batches[k]);
        refl_frame_destroy(f);
    }
    refl_frame_destroy(ref);
    refl_scene_destroy(s);
}

Test(refl_sbc, bad_desc_values) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 32, 24);
    refl_frame *f = NULL;
    refl_render_desc d = sbc_desc(REFL_SBC, 1);
    cr_assert_eq(refl_frame_create(32, 24, NULL, &f), REFL_OK);
    d.sbc.error_px = -1.0f;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.sbc.error_px = NAN;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.sbc.error_px = 0.0f;
    d.sbc.ray_factor = -2;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.sbc.ray_factor = 65;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.sbc.ray_factor = 0;
    d.sbc.batch_groups = -1;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.sbc.batch_groups = 255;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.sbc.batch_groups = 0;
    d.sbc.trace_fallback = 2; /* a flag: 0 or 1 */
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.sbc.trace_fallback = -1;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.sbc.trace_fallback = 0;
    d.sbc.mixed_levels = 7; /* four times the triangles per level: 6 at most */
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}
