/* The GL tests' context (tools/reflect_gl.h): created, or the test skipped
   saying why where no EGL device exists (GL_PEER_REQUIRED=1 turns the skip
   into a failure, as for the rasteriser's GL peer). Mesa keeps (and at
   eglTerminate drops) allocations that LeakSanitizer reports from an
   unloaded module: GL work runs between LSAN_OFF and LSAN_ON. Include after
   <criterion/criterion.h>, "../../reflect.h", "../../tools/reflect_gl.h"
   and "refl_test_util.h". */
#ifndef TEST_GL_CONTEXT_H
#define TEST_GL_CONTEXT_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/lsan_interface.h>
#define LSAN_OFF() __lsan_disable()
#define LSAN_ON() __lsan_enable()
#else
#define LSAN_OFF() ((void)0)
#define LSAN_ON() ((void)0)
#endif

static inline rgl_context *tu_gl_context(const char *test) {
    rgl_context *g = NULL;
    char err[1024];
    int r;
    LSAN_OFF();
    r = rgl_create(&g, err, sizeof err);
    LSAN_ON();
    if (r != 0) {
        const char *req = getenv("GL_PEER_REQUIRED");
        fprintf(stderr, "%s: no EGL device: %s\n", test, err);
        if (req && *req && strcmp(req, "0") != 0) cr_assert_fail("no EGL device: %s (GL_PEER_REQUIRED is set)", err);
        cr_skip_test("no EGL device: %s", err);
    }
    return g;
}

/* LAYERED_EM through GL against the CPU path's frame of the same desc. */
typedef struct tu_gl_lem_vs_cpu {
    double psnr;           /* GL against CPU over the lens pixels (rgl_mirror_psnr) */
    long long lens_pixels; /* the GL frame's lens pixels (its stencil) */
    long long cpu_traced;  /* the CPU frame's pixels handed to the tracer */
    rgl_frame_stats gl;    /* the GL frame's stats */
} tu_gl_lem_vs_cpu;

/* LAYERED_EM of desc d (NULL: rgl_lem_desc's) on `hybrid` at 80 x 60,
   through GL (rgl_render_layered_em_desc) and on the CPU; GL's success
   and hybrid's two lenses asserted. */
static inline tu_gl_lem_vs_cpu tu_gl_layered_em_vs_cpu(const char *test, const refl_render_desc *d) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("hybrid", &v, 80, 60);
    refl_render_desc dc;
    refl_frame *cpu, *gl = NULL;
    rgl_context *g = tu_gl_context(test);
    float *rgb = (float *)malloc((size_t)v.width * v.height * 3 * sizeof(float));
    char err[1024];
    tu_gl_lem_vs_cpu out;
    long long i;
    int r;
    if (d) dc = *d;
    else rgl_lem_desc(&dc);
    cpu = tu_refl_render(s, &v, &dc);
    cr_assert_not_null(rgb);
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &gl), REFL_OK);
    LSAN_OFF();
    r = rgl_render_layered_em_desc(g, s, &v, d, gl, rgb, &out.gl, err, sizeof err);
    rgl_destroy(g);
    LSAN_ON();
    cr_assert_eq(r, 0, "%s", err);
    cr_assert_eq(out.gl.mirrors, 2, "hybrid's two lenses, got %d", out.gl.mirrors);
    out.lens_pixels = 0;
    for (i = 0; i < (long long)v.width * v.height; ++i) out.lens_pixels += gl->stencil[i] != 0;
    out.psnr = rgl_mirror_psnr(cpu, gl, rgb);
    out.cpu_traced = cpu->stats.layered_em.traced_pixels;
    free(rgb);
    refl_frame_destroy(gl);
    refl_frame_destroy(cpu);
    refl_scene_destroy(s);
    return out;
}

#endif
