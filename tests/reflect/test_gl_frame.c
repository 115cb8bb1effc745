/* PLANAR through GL (tools/reflect_gl_frame.c) against PLANAR on the CPU:
   the same points in the mirrors (reflection error in pixels, with the
   CPU frame as the truth) and the same colours there (PSNR over the
   mirrors' pixels). Skipped, saying why, where no EGL device exists
   (test_gl_context.h). */
#include <criterion/criterion.h>
#include "../../reflect.h"
#include "../../tools/reflect_gl.h"
#include "refl_test_util.h"
#include "test_gl_context.h"

Test(refl_gl_frame, planar_matches_cpu, .timeout = 120) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("mirror-room", &v, 160, 120);
    refl_render_desc d = tu_refl_one_bounce(REFL_PLANAR, 2);
    refl_frame *cpu = tu_refl_render(s, &v, &d), *gl = NULL;
    refl_reflection_error e;
    rgl_frame_stats st;
    rgl_context *g = tu_gl_context("test_gl_frame");
    float *rgb = malloc((size_t)v.width * v.height * 3 * sizeof(float));
    char err[1024];
    double psnr;
    int r;
    cr_assert_not_null(rgb);
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &gl), REFL_OK);
    LSAN_OFF();
    r = rgl_render_planar(g, s, &v, gl, rgb, &st, err, sizeof err);
    rgl_destroy(g);
    LSAN_ON();
    cr_assert_eq(r, 0, "%s", err);
    cr_assert_eq(st.mirrors, 4, "mirror-room's four mirrors, got %d", st.mirrors);
    cr_assert_eq(refl_measure_reflection_error(gl, cpu, NULL, &e), REFL_OK);
    cr_log_info("GL vs CPU PLANAR: %lld matched, mean %.3f px, wrong %.4f, empty %.4f", e.matched, e.mean, e.wrong,
                e.empty);
    cr_assert_gt(e.matched, 1000);
    cr_assert_lt(e.mean, 1.0);
    cr_assert_lt(e.wrong + e.empty, 0.01);
    psnr = rgl_mirror_psnr(cpu, gl, rgb);
    cr_log_info("PSNR over the mirrors' pixels: %.1f dB", psnr);
    cr_assert_gt(psnr, 40.0);
    free(rgb);
    refl_frame_destroy(gl);
    refl_frame_destroy(cpu);
    refl_scene_destroy(s);
}
