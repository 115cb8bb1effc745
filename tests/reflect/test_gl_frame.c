/* PLANAR through GL (tools/reflect_gl_frame.c) against PLANAR on the CPU:
   the same points in the mirrors (reflection error in pixels, with the
   CPU frame as the truth) and the same colours there (PSNR over the
   mirrors' pixels). Skipped, saying why, where no EGL device exists. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "../../tools/reflect_gl.h"
#include "refl_test_util.h"

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/lsan_interface.h>
#define LSAN_OFF() __lsan_disable()
#define LSAN_ON() __lsan_enable()
#else
#define LSAN_OFF() ((void)0)
#define LSAN_ON() ((void)0)
#endif

static uint8_t srgb8(float v) {
    float s = v <= 0.0f ? 0.0f : v >= 1.0f ? 1.0f : v <= 0.0031308f ? 12.92f * v : 1.055f * powf(v, 1.0f / 2.4f) - 0.055f;
    return (uint8_t)(s * 255.0f + 0.5f);
}

Test(refl_gl_frame, planar_matches_cpu, .timeout = 120) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("mirror-room", &v, 160, 120);
    refl_render_desc d = tu_refl_one_bounce(REFL_PLANAR, 2);
    refl_frame *cpu = tu_refl_render(s, &v, &d), *gl = NULL;
    refl_reflection_error e;
    rgl_frame_stats st;
    rgl_context *g = NULL;
    float *rgb = malloc((size_t)v.width * v.height * 3 * sizeof(float));
    uint8_t *c = malloc((size_t)v.width * v.height * 4);
    char err[1024];
    double se = 0.0, psnr;
    long long i, count = 0;
    int r;
    cr_assert(rgb && c);
    LSAN_OFF();
    r = rgl_create(&g, err, sizeof err);
    LSAN_ON();
    if (r != 0) {
        const char *req = getenv("GL_PEER_REQUIRED");
        fprintf(stderr, "test_gl_frame: no EGL device: %s\n", err);
        if (req && *req && strcmp(req, "0") != 0) cr_assert_fail("no EGL device: %s (GL_PEER_REQUIRED is set)", err);
        cr_skip_test("no EGL device: %s", err);
    }
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
    refl_frame_to_srgb8(cpu, c);
    for (i = 0; i < (long long)v.width * v.height; ++i) {
        int k;
        if (!gl->stencil[i]) continue;
        for (k = 0; k < 3; ++k) {
            double dd = (double)c[4 * i + k] - (double)srgb8(rgb[3 * i + k]);
            se += dd * dd;
        }
        count += 3;
    }
    cr_assert_gt(count, 3000);
    psnr = se == 0.0 ? INFINITY : 10.0 * log10(255.0 * 255.0 / (se / (double)count));
    cr_log_info("PSNR over the mirrors' pixels: %.1f dB", psnr);
    cr_assert_gt(psnr, 40.0);
    free(rgb);
    free(c);
    refl_frame_destroy(gl);
    refl_frame_destroy(cpu);
    refl_scene_destroy(s);
}
