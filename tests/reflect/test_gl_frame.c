/* PLANAR through GL (tools/reflect_gl_frame.c) against PLANAR on the CPU:
   the same points in the mirrors (reflection error in pixels, with the
   CPU frame as the truth) and the same colours there (PSNR over the
   mirrors' pixels), and a curved mirror's pixels handed to the CPU as CPU
   PLANAR hands them over. C3RC and SBC through GL (reflect_gl_c3rc.c,
   reflect_gl_sbc.c): their reflection error against one-bounce RAYTRACE
   within a pixel of the CPU path's, on the default scene, the concave
   bowl and (C3RC, its gaps traced) hybrid; SPOC and GRAPHCAM through GL (reflect_gl_impostor.c) likewise
   on the teapots (SPOC), the maze and the default scene (GRAPHCAM). Skipped, saying why, where no EGL
   device exists (test_gl_context.h). */
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

/* Method m through GL and on the CPU, both measured against one-bounce
   RAYTRACE on built-in scene `scene` at w x h: the GL frame's mean
   reflection error within 1 px of the CPU frame's, with most reflector
   pixels matched. GRAPHCAM draws with graph camera `gc` on both paths
   (NULL: the view's pinhole). The GL frame's stats and the CPU frame's
   C3RC stats in *gl_st and *cpu_c3rc when not NULL. */
static void gl_within_a_pixel_of_cpu_at(const char *scene, refl_method m, int w, int h, long long min_matched,
                                        const refl_graphcam *gc, rgl_frame_stats *gl_st,
                                        refl_c3rc_frame_stats *cpu_c3rc) {
    refl_view v;
    refl_scene *s = tu_refl_builtin(scene, &v, w, h);
    refl_render_desc d = tu_refl_one_bounce(m, 2), dt = tu_refl_one_bounce(REFL_RAYTRACE, 2);
    refl_frame *cpu, *truth = tu_refl_render(s, &v, &dt), *gl = NULL;
    refl_reflection_error eg, ec;
    rgl_frame_stats st;
    rgl_context *g = tu_gl_context("test_gl_frame");
    float *rgb = malloc((size_t)v.width * v.height * 3 * sizeof(float));
    char err[1024];
    int r;
    d.graphcam.camera = gc;
    cpu = tu_refl_render(s, &v, &d);
    cr_assert_not_null(rgb);
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &gl), REFL_OK);
    LSAN_OFF();
    r = m == REFL_GRAPHCAM ? rgl_render_graphcam(g, s, &v, gc, gl, rgb, &st, err, sizeof err)
                           : rgl_render(g, m, s, &v, gl, rgb, &st, err, sizeof err);
    rgl_destroy(g);
    LSAN_ON();
    cr_assert_eq(r, 0, "%s", err);
    cr_assert_eq(refl_measure_reflection_error(gl, truth, NULL, &eg), REFL_OK);
    cr_assert_eq(refl_measure_reflection_error(cpu, truth, NULL, &ec), REFL_OK);
    cr_log_info("%s on %s against RAYTRACE: GL %lld matched, mean %.3f px (wrong %.4f, empty %.4f); "
                "CPU %lld matched, mean %.3f px (wrong %.4f, empty %.4f)",
                refl_method_name(m), scene, eg.matched, eg.mean, eg.wrong, eg.empty, ec.matched, ec.mean, ec.wrong,
                ec.empty);
    cr_assert_gt(eg.matched, min_matched, "%s on %s: %lld pixels matched", refl_method_name(m), scene, eg.matched);
    cr_assert_leq(eg.mean, ec.mean + 1.0, "%s on %s: GL %.3f px, CPU %.3f px", refl_method_name(m), scene, eg.mean,
                  ec.mean);
    if (gl_st) *gl_st = st;
    if (cpu_c3rc) *cpu_c3rc = cpu->stats.c3rc;
    free(rgb);
    refl_frame_destroy(gl);
    refl_frame_destroy(truth);
    refl_frame_destroy(cpu);
    refl_scene_destroy(s);
}

static void gl_graphcam_within_a_pixel_of_cpu(const char *scene, refl_method m, long long min_matched,
                                              const refl_graphcam *gc) {
    gl_within_a_pixel_of_cpu_at(scene, m, 160, 120, min_matched, gc, NULL, NULL);
}

static void gl_within_a_pixel_of_cpu(const char *scene, refl_method m, long long min_matched) {
    gl_graphcam_within_a_pixel_of_cpu(scene, m, min_matched, NULL);
}

Test(refl_gl_frame, c3rc_within_a_pixel_of_cpu, .timeout = 240) { gl_within_a_pixel_of_cpu("default", REFL_C3RC, 500); }

Test(refl_gl_frame, sbc_within_a_pixel_of_cpu, .timeout = 240) { gl_within_a_pixel_of_cpu("default", REFL_SBC, 500); }

/* The concave bowl: its cameras fold (C3RC's points denser on the ball it
   magnifies, its sweep past the scene's diagonal) and it shows itself. */
Test(refl_gl_frame, c3rc_concave_within_a_pixel_of_cpu, .timeout = 240) {
    gl_within_a_pixel_of_cpu("concave", REFL_C3RC, 5000);
}

Test(refl_gl_frame, sbc_concave_within_a_pixel_of_cpu, .timeout = 240) {
    gl_within_a_pixel_of_cpu("concave", REFL_SBC, 5000);
}

/* The default scene's teapot is curved: PLANAR through GL hands it to the
   CPU as CPU PLANAR does (its tracer), so its reflection is there too. */
Test(refl_gl_frame, planar_curved_within_a_pixel_of_cpu, .timeout = 120) {
    gl_within_a_pixel_of_cpu("default", REFL_PLANAR, 500);
}

/* SPOC's impostors marched per fragment (reflect_gl_impostor.c), the
   exact part and the missed rays on the CPU, on paper 004's teapots. */
Test(refl_gl_frame, spoc_teapots_within_a_pixel_of_cpu, .timeout = 120) {
    gl_within_a_pixel_of_cpu("teapots", REFL_SPOC, 500);
}

/* GRAPHCAM's impostor marched per fragment (reflect_gl_impostor.c): the
   maze through its graph camera (15 frusta, 960 x 588), and the default
   scene through the view's pinhole. */
Test(refl_gl_frame, graphcam_maze_within_a_pixel_of_cpu, .timeout = 120) {
    refl_graphcam *cam = malloc(sizeof *cam);
    cr_assert_not_null(cam);
    cr_assert_eq(refl_graphcam_maze(cam, 960, 588), REFL_OK);
    gl_graphcam_within_a_pixel_of_cpu("maze", REFL_GRAPHCAM, 500, cam);
    free(cam);
}

Test(refl_gl_frame, graphcam_within_a_pixel_of_cpu, .timeout = 120) {
    gl_within_a_pixel_of_cpu("default", REFL_GRAPHCAM, 500);
}

/* Hybrid at 160 x 480 (a tall frame: the density of 480 rows on few
   pixels): the 2 million points' cap spaces the points wider than the
   view wants, and the floor behind the objects shows through gaps in
   their points. The CPU path hands those pixels to its tracer; the GL
   path finds them with the same test (refl_c3rc_in_gap) and traces them
   on the CPU, about as many. */
Test(refl_gl_frame, c3rc_hybrid_gaps_traced, .timeout = 240) {
    rgl_frame_stats st;
    refl_c3rc_frame_stats cpu;
    memset(&st, 0, sizeof st);
    memset(&cpu, 0, sizeof cpu);
    gl_within_a_pixel_of_cpu_at("hybrid", REFL_C3RC, 160, 480, 1500, NULL, &st, &cpu);
    cr_log_info("gap pixels traced: GL %lld, CPU %lld", st.traced, cpu.traced);
    cr_assert_gt(cpu.traced, 100, "the CPU path traced %lld gap pixels", cpu.traced);
    cr_assert(st.traced >= cpu.traced / 2 && st.traced <= 2 * cpu.traced, "gap pixels traced: GL %lld, CPU %lld",
              st.traced, cpu.traced);
}

/* LAYERED_EM through GL (reflect_gl_lem.c) against the CPU path's frame of
   the same desc on hybrid (the mirror cup, and the glass teapot's two
   terms): GL's layer lookups and composite give the lens pixels the CPU's
   colours (PSNR over the lenses' pixels; the tessellation's edges cover
   a pixel differently here and there), and the same pixels go to the
   tracer. */
Test(refl_gl_frame, layered_em_matches_cpu, .timeout = 120) {
    tu_gl_lem_vs_cpu m = tu_gl_layered_em_vs_cpu("test_gl_frame", NULL);
    cr_log_info("LAYERED_EM GL vs CPU: %lld lens pixels, PSNR %.1f dB; traced GL %lld, CPU %lld", m.lens_pixels,
                m.psnr, m.gl.traced, m.cpu_traced);
    cr_assert_gt(m.lens_pixels, 300);
    cr_assert_gt(m.psnr, 38.0);
    cr_assert(llabs(m.gl.traced - m.cpu_traced) <= 2 + m.cpu_traced / 10, "traced: GL %lld, CPU %lld", m.gl.traced,
              m.cpu_traced);
}

/* The glass C3RC, SBC, SPOC and GRAPHCAM through GL do not draw comes from
   the CPU as their CPU methods hand it over: on `glass` at one bounce,
   every glass pixel of the GL frame is one-bounce RAYTRACE's, bit for
   bit (not DIRECT's black), for each of the four. */
Test(refl_gl_frame, glass_traced_as_the_cpu_methods_hand_it_over, .timeout = 240) {
    static const refl_method methods[] = {REFL_C3RC, REFL_SBC, REFL_SPOC, REFL_GRAPHCAM};
    refl_view v;
    refl_scene *s = tu_refl_builtin("glass", &v, 80, 60);
    refl_render_desc dt = tu_refl_one_bounce(REFL_RAYTRACE, 2);
    refl_frame *truth = tu_refl_render(s, &v, &dt), *gl = NULL;
    rgl_context *g = tu_gl_context("test_gl_frame");
    float *rgb = malloc((size_t)v.width * v.height * 3 * sizeof(float));
    char err[1024];
    int k, i, c, r;
    cr_assert_not_null(rgb);
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &gl), REFL_OK);
    for (k = 0; k < 4; ++k) {
        rgl_frame_stats st;
        long long glass = 0;
        LSAN_OFF();
        r = rgl_render(g, methods[k], s, &v, gl, rgb, &st, err, sizeof err);
        LSAN_ON();
        cr_assert_eq(r, 0, "%s: %s", refl_method_name(methods[k]), err);
        cr_assert_eq(st.handed, 2, "%s: %d glass objects handed to the CPU", refl_method_name(methods[k]), st.handed);
        for (i = 0; i < v.width * v.height; ++i) {
            int object = truth->stencil[i] - 1;
            if (object < 0 || s->materials[s->objects[object].material].type != REFL_GLASS) continue;
            ++glass;
            for (c = 0; c < 3; ++c)
                cr_assert_eq(rgb[3 * i + c], truth->rgba[4 * i + c], "%s: pixel %d", refl_method_name(methods[k]), i);
        }
        cr_assert_gt(glass, 100, "%lld glass pixels", glass);
        cr_assert_eq(st.handed_pixels, glass, "%s: %lld pixels traced, %lld glass", refl_method_name(methods[k]),
                     st.handed_pixels, glass);
    }
    LSAN_OFF();
    rgl_destroy(g);
    LSAN_ON();
    free(rgb);
    refl_frame_destroy(gl);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}
