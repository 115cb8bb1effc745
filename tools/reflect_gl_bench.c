/* reflect_gl_bench.c - the GL path's numbers (reflect_gl.h): every
   camera's projection, GLSL against C, and PLANAR, C3RC and SBC frames
   through GL against the CPU path; a line per row on stdout and CSV rows. Shared by
   reflect_gl (tools/reflect_gl_main.c) and `reflect bench --gl`. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "cli_options.h"
#include "reflect_gl.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "name_in_list.h"

/* DIR/gl_frames.png: each GL frame's time against the CPU path's (ms, log
   axes, a point per method, scene and size, labelled so), and
   DIR/gl_projection.png: each camera's GLSL projection rate against its
   C one, from the two CSVs through gnuplot; the diagonal is "as fast". */
static int rgl__frames_chart(const char *dir, const char *renderer) {
    char path[1200], cmd[1300];
    FILE *f;
    int r;
    snprintf(path, sizeof path, "%s/gl_frames.gp", dir);
    if (!(f = fopen(path, "w"))) return -1;
    fprintf(f,
            "set terminal pngcairo size 1000,700\nset output '%s/gl_frames.png'\nset datafile separator comma\n"
            "set logscale xy\nset grid\nset key top left\n"
            "set title 'GL frame (GL + the CPU share) against the CPU path, %s'\n"
            "set xlabel 'CPU path frame (ms)'\nset ylabel 'GL path frame (ms)'\n"
            "plot '%s/gl_frames.csv' skip 1 using ($10*1e3):($7*1e3) with points pt 7 title 'method, scene, size', \\\n"
            "     '' skip 1 using ($10*1e3):($7*1e3):(sprintf('%%s %%s %%dx%%d', strcol(3), strcol(2), $4, $5)) "
            "with labels offset 1,0.5 left font ',8' notitle, \\\n"
            "     x with lines dt 2 title 'as fast'\n"
            "set output '%s/gl_projection.png'\n"
            "set title 'Projection rate, GLSL (transform feedback) against C (one thread), %s'\n"
            "set xlabel 'C projection (M points/s)'\nset ylabel 'GLSL projection (M points/s)'\n"
            "plot '%s/gl_projection.csv' skip 1 using 11:9 with points pt 7 title 'camera', \\\n"
            "     '' skip 1 using 11:9:2 with labels offset 1,0.5 left font ',8' notitle, \\\n"
            "     x with lines dt 2 title 'as fast'\n",
            dir, renderer, dir, dir, renderer, dir);
    fclose(f);
    snprintf(cmd, sizeof cmd, "gnuplot '%s'", path);
    r = system(cmd);
    if (r != 0) fprintf(stderr, "reflect bench --gl: gnuplot failed on %s (is gnuplot-nox installed?)\n", path);
    else printf("wrote %s/gl_frames.png and %s/gl_projection.png\n", dir, dir);
    return r != 0 ? -1 : 0;
}

int rgl_bench_projection(rgl_context *g, long long points, int repeats, int check, FILE *csv) {
    int i, failed = 0;
    char err[1024];
    if (csv)
        fprintf(csv, "renderer,camera,points,projected,disagree,max_rel,p999_rel,gl_seconds,gl_mpoints_per_s,"
                     "cpu_seconds,cpu_mpoints_per_s,fixture\n");
    for (i = 0; i < RGL_CAMERAS; ++i) {
        rgl_validation v;
        if (rgl_validate(g, i, points, repeats, &v, err, sizeof err) != 0) {
            fprintf(stderr, "reflect_gl: camera %d: %s\n", i, err);
            failed = 1;
            continue;
        }
        printf("%-12s %9lld points, %9lld projected, %6lld disagree (%.2e), max rel %.2e, p99.9 %.2e, "
               "GL %.2f M/s, C %.2f M/s, leaves %lld/%lld  [%s]\n",
               v.camera, v.points, v.projected, v.disagree, (double)v.disagree / (double)v.points, v.max_rel,
               v.p999_rel, v.points / v.gl_seconds * 1e-6, v.points / v.cpu_seconds * 1e-6, v.pinhole_points, v.raylist_points, v.note);
        if (csv)
            fprintf(csv, "\"%s\",%s,%lld,%lld,%lld,%.3e,%.3e,%.6f,%.3f,%.6f,%.3f,\"%s\"\n", rgl_renderer(g), v.camera,
                    v.points, v.projected, v.disagree, v.max_rel, v.p999_rel, v.gl_seconds,
                    v.points / v.gl_seconds * 1e-6, v.cpu_seconds, v.points / v.cpu_seconds * 1e-6, v.note);
        if (check && !rgl_validation_ok(&v)) {
            fprintf(stderr, "reflect_gl: %s: GLSL and C disagree beyond the bounds\n", v.camera);
            failed = 1;
        }
    }
    if (check) { /* validate: the impostor hooks' fragment-side marches too, one ray a point */
        int (*const march[2])(rgl_context *, long long, rgl_validation *, char *, size_t) = {
            rgl_validate_spoc_impostor, rgl_validate_graphcam_impostor};
        for (i = 0; i < 2; ++i) {
            rgl_validation v;
            if (march[i](g, points, &v, err, sizeof err) != 0) {
                fprintf(stderr, "reflect_gl: impostor march %d: %s\n", i, err);
                failed = 1;
                continue;
            }
            printf("%-12s %9lld rays,   %9lld hit both, %6lld disagree, max rel %.2e, p99.9 %.2e  [%s]\n", v.camera,
                   v.points, v.projected, v.disagree, v.max_rel, v.p999_rel, v.note);
            if (v.disagree > 0 || v.p999_rel > 1e-4) {
                fprintf(stderr, "reflect_gl: %s: the GLSL march and C disagree beyond the bounds\n", v.camera);
                failed = 1;
            }
        }
    }
    return failed;
}

double rgl_mirror_psnr(const refl_frame *cpu, const refl_frame *gl, const float *gl_rgb) {
    uint8_t *c = (uint8_t *)malloc((size_t)cpu->width * cpu->height * 4);
    double se = 0.0;
    long long count = 0, i;
    if (!c) return NAN;
    refl_frame_to_srgb8(cpu, NULL, c);
    for (i = 0; i < (long long)cpu->width * cpu->height; ++i) {
        int k;
        if (!gl->stencil[i]) continue;
        for (k = 0; k < 3; ++k) {
            double d = (double)c[4 * i + k] - (double)refl_display_channel(gl_rgb[3 * i + k], NULL);
            se += d * d;
        }
        count += 3;
    }
    free(c);
    if (!count) return NAN;
    return se == 0.0 ? INFINITY : 10.0 * log10(255.0 * 255.0 / (se / (double)count));
}

static double seconds_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A CPU frame of method m (one bounce; GRAPHCAM through graph camera gc,
   NULL: the view's pinhole; LAYERED_EM as the GL path draws it,
   rgl_lem_desc); NULL on failure. *secs: its time. */
static refl_frame *cpu_frame(const refl_scene *s, const refl_view *v, refl_method m, const refl_graphcam *gc,
                             double *secs) {
    refl_render_desc d;
    refl_frame *f = NULL;
    double t;
    memset(&d, 0, sizeof d);
    d.method = m;
    d.depth = 1;
    d.graphcam.camera = gc;
    if (m == REFL_LAYERED_EM) rgl_lem_desc(&d);
    if (refl_frame_create(v->width, v->height, NULL, &f) != REFL_OK) return NULL;
    t = seconds_now();
    if (refl_render(s, v, &d, f) != REFL_OK) {
        refl_frame_destroy(f);
        return NULL;
    }
    *secs = seconds_now() - t;
    return f;
}

/* The GL frame, best of three where one takes under a second (the first
   compiles llvmpipe's shader variants). */
static int rgl_render_best(rgl_context *g, refl_method m, const refl_graphcam *gc, const refl_scene *s,
                           const refl_view *v, refl_frame *f, float *rgb, rgl_frame_stats *st, char *err, size_t n) {
    rgl_frame_stats best;
    int k;
    for (k = 0; k < 3; ++k) {
        if ((m == REFL_GRAPHCAM ? rgl_render_graphcam(g, s, v, gc, f, rgb, st, err, n)
                                : rgl_render(g, m, s, v, f, rgb, st, err, n)) != 0)
            return -1;
        if (k == 0 || st->gl_seconds + st->shade_seconds < best.gl_seconds + best.shade_seconds) best = *st;
        if (best.gl_seconds + best.shade_seconds > 1.0) break;
    }
    *st = best;
    return 0;
}

/* The frames benched: each method on the scenes it is measured on (a
   comma-separated list: PLANAR's planar mirrors, and the default scene's
   curved one it hands to the CPU), unless a scene list names others. */
static const struct {
    const char *name, *scenes;
    refl_method m;
} rgl_frame_rows[] = {
    {"planar", "mirror-room,default", REFL_PLANAR},
    {"c3rc", "default", REFL_C3RC},
    {"sbc", "default", REFL_SBC},
    {"spoc", "teapots", REFL_SPOC},
    {"graphcam", "maze,default", REFL_GRAPHCAM},
    {"layered-em", "hybrid", REFL_LAYERED_EM},
};

/* Whether method `name` is in the comma-separated list (NULL or empty: all). */
static int rgl_listed(const char *list, const char *name) { return !list || !*list || name_in_list(list, name, ','); }

/* The built-in scenes `--scenes all` stands for. */
static const char *const rgl_all_scenes = "default,mirror-room,concave,glass,maze,teapots,hybrid";

/* The n-th name of the comma-separated list into buf; 0 past its end. */
static int rgl_list_item(const char *list, int n, char *buf, size_t size) {
    const char *p = list, *end;
    for (; n > 0 && p; --n) {
        p = strchr(p, ',');
        if (p) ++p;
    }
    if (!p || !*p) return 0;
    end = strchr(p, ',');
    if (!end) end = p + strlen(p);
    if ((size_t)(end - p) >= size) return 0;
    memcpy(buf, p, (size_t)(end - p));
    buf[end - p] = 0;
    return 1;
}

int rgl_bench_frames(rgl_context *g, const char *sizes, const char *methods, const char *scenes, long long truth_max,
                     FILE *csv) {
    int ri, si, failed = 0;
    char scene_buf[64];
    refl_graphcam *gc = NULL; /* the maze's, made when first needed */
    if (scenes && !strcmp(scenes, "all")) scenes = rgl_all_scenes;
    if (csv)
        fprintf(csv, "renderer,scene,method,width,height,cameras,gl_frame_s,gl_draw_s,cpu_share_s,cpu_method_s,"
                     "gl_vs_cpu_mean_px,gl_vs_cpu_wrong,gl_vs_cpu_empty,psnr_reflectors_db,gl_vs_truth_mean_px,"
                     "cpu_vs_truth_mean_px,gl_mvertices_per_s,gl_points,gl_projections,cpu_points,cpu_projections,"
                     "cpu_filled_px\n");
    for (ri = 0; ri < (int)(sizeof rgl_frame_rows / sizeof rgl_frame_rows[0]); ++ri)
        for (si = 0; rgl_list_item(scenes && *scenes ? scenes : rgl_frame_rows[ri].scenes, si, scene_buf, sizeof scene_buf);
             ++si) {
        const char *p = sizes, *scene = scene_buf;
        const char *name = rgl_frame_rows[ri].name;
        refl_method m = rgl_frame_rows[ri].m;
        /* (LAYERED_EM infers its maps on the CPU each frame: run when named) */
        if (!rgl_listed(methods, name) || (m == REFL_LAYERED_EM && !(methods && *methods))) continue;
        while (*p) {
            int w = 0, h = 0;
            refl_scene *s = NULL;
            refl_view v;
            refl_frame *gf = NULL, *cf = NULL, *tf = NULL;
            float *rgb = NULL;
            rgl_frame_stats st;
            refl_reflection_error e_gc, e_gt, e_ct;
            double cpu_s = 0.0, truth_s = 0.0, psnr;
            char err[512];
            if (sscanf(p, "%dx%d", &w, &h) != 2 || w < 1 || h < 1) {
                fprintf(stderr, "reflect_gl: bad size list %s\n", sizes);
                return 2;
            }
            p = strchr(p, ',');
            p = p ? p + 1 : "";
            if (refl_scene_builtin(scene, NULL, &s) != REFL_OK) {
                fprintf(stderr, "reflect_gl: no built-in scene %s\n", scene);
                return 2;
            }
            v = s->camera;
            v.width = w;
            v.height = h;
            memset(&e_gt, 0, sizeof e_gt);
            memset(&e_ct, 0, sizeof e_ct);
            rgb = (float *)malloc((size_t)w * h * 3 * sizeof(float));
            if (!rgb || refl_frame_create(w, h, NULL, &gf) != REFL_OK) return 1;
            /* GRAPHCAM on the maze: its graph camera at the paper's 1920 x 1176 */
            if (m == REFL_GRAPHCAM && !strcmp(scene, "maze") && !gc &&
                (!(gc = (refl_graphcam *)malloc(sizeof *gc)) || refl_graphcam_maze(gc, 0, 0) != REFL_OK)) {
                free(rgb);
                free(gc);
                refl_frame_destroy(gf);
                refl_scene_destroy(s);
                return 1;
            }
            if (rgl_render_best(g, m, strcmp(scene, "maze") ? NULL : gc, s, &v, gf, rgb, &st, err, sizeof err) != 0) {
                fprintf(stderr, "reflect_gl: %s %s %dx%d: %s\n", name, scene, w, h, err);
                failed = 1;
            } else if (!(cf = cpu_frame(s, &v, m, strcmp(scene, "maze") ? NULL : gc, &cpu_s))) {
                fprintf(stderr, "reflect_gl: the CPU %s frame failed\n", name);
                failed = 1;
            } else {
                refl_measure_reflection_error(gf, cf, NULL, &e_gc);
                psnr = rgl_mirror_psnr(cf, gf, rgb);
                /* (LAYERED_EM is compared with its CPU frame alone: its lens pixels show
                   no point) */
                if (m != REFL_LAYERED_EM && (long long)w * h <= truth_max &&
                    (tf = cpu_frame(s, &v, REFL_RAYTRACE, NULL, &truth_s))) {
                    refl_measure_reflection_error(gf, tf, NULL, &e_gt);
                    refl_measure_reflection_error(cf, tf, NULL, &e_ct);
                }
                printf("%-6s %-11s %4dx%-4d %5d cameras: GL frame %.1f ms (GL %.1f, CPU's share %.1f), CPU %s %.1f ms; "
                       "GL vs CPU: %lld px matched, mean %.3f px, wrong %.4f, empty %.4f, PSNR %.1f dB over reflectors",
                       name, scene, w, h, st.mirrors, 1e3 * (st.gl_seconds + st.shade_seconds), 1e3 * st.gl_seconds,
                       1e3 * st.shade_seconds, name, 1e3 * cpu_s, e_gc.matched, e_gc.mean, e_gc.wrong, e_gc.empty, psnr);
                if (m == REFL_C3RC)
                    printf("; points: GL %lld (%lld projected), CPU %lld (%lld projected); traced: GL %lld px, CPU %lld px",
                           st.points, st.projections, cf->stats.c3rc.points, cf->stats.c3rc.projections, st.traced,
                           cf->stats.c3rc.traced);
                if (m == REFL_LAYERED_EM)
                    printf("; traced: GL %lld px, CPU %lld px", st.traced, cf->stats.layered_em.traced_pixels);
                if (m == REFL_SPOC)
                    printf("; %d impostors; march steps: GL %lld, CPU %lld; traced: GL %lld px, CPU %lld px", st.mirrors,
                           st.projections, cf->stats.spoc.steps, st.traced, cf->stats.spoc.traced);
                if (m == REFL_GRAPHCAM)
                    printf("; %d frusta; march steps: GL %lld, CPU %lld; traced: GL %lld px, CPU %lld px", st.mirrors,
                           st.projections, cf->stats.graphcam.steps, st.traced, cf->stats.graphcam.traced);
                if (m == REFL_PLANAR && st.handed)
                    printf("; %d reflectors to the CPU (%d traced), %lld px", st.handed, st.handed_over, st.traced);
                if (tf)
                    printf("; vs RAYTRACE: GL %.3f px (%lld px matched), CPU %.3f px (%lld px matched)", e_gt.mean,
                           e_gt.matched, e_ct.mean, e_ct.matched);
                printf("\n");
                if (csv)
                    fprintf(csv, "\"%s\",%s,%s,%d,%d,%d,%.6f,%.6f,%.6f,%.6f,%.4f,%.5f,%.5f,%.2f,%.4f,%.4f,%.3f,%lld,%lld,%lld,%lld,%lld\n",
                            rgl_renderer(g), scene, name, w, h, st.mirrors, st.gl_seconds + st.shade_seconds,
                            st.gl_seconds, st.shade_seconds, cpu_s, e_gc.mean, e_gc.wrong, e_gc.empty, psnr,
                            tf ? e_gt.mean : NAN, tf ? e_ct.mean : NAN, st.vertices / st.gl_seconds * 1e-6, st.points,
                            st.projections, m == REFL_C3RC ? cf->stats.c3rc.points : 0,
                            m == REFL_C3RC ? cf->stats.c3rc.projections : m == REFL_SPOC       ? cf->stats.spoc.steps
                            : m == REFL_GRAPHCAM ? cf->stats.graphcam.steps
                                                 : 0,
                            st.traced);
                fflush(stdout);
                if (csv) fflush(csv);
            }
            free(rgb);
            refl_frame_destroy(gf);
            refl_frame_destroy(cf);
            refl_frame_destroy(tf);
            refl_scene_destroy(s);
        }
    }
    free(gc);
    return failed;
}


/* The options that take a value. */
static const char *const gl_value_options[] = {"--out", "--sizes", "--methods", "--scenes", "--points", "--repeats", NULL};

int rgl_cli_bench(int argc, char **argv) {
    const char *dir = "out/bench", *sizes = "320x240,640x480", *methods = NULL, *scenes = NULL;
    long long points = 1000000;
    int repeats = 5, i, failed;
    unsigned long long given = 0; /* the value options seen (cli_given_twice) */
    rgl_context *g = NULL;
    char err[1024], path[1024];
    FILE *csv;
    for (i = 2; i < argc; ++i) {
        if (i + 1 < argc && cli_given_twice("reflect bench", gl_value_options, argv[i], &given)) return 2;
        if (!strcmp(argv[i], "--gl")) continue;
        if (!strcmp(argv[i], "--out") && i + 1 < argc) dir = argv[++i];
        else if (!strcmp(argv[i], "--sizes") && i + 1 < argc) sizes = argv[++i];
        else if (!strcmp(argv[i], "--methods") && i + 1 < argc) methods = argv[++i];
        else if (!strcmp(argv[i], "--scenes") && i + 1 < argc) scenes = argv[++i];
        else if (!strcmp(argv[i], "--points") && i + 1 < argc) points = atoll(argv[++i]);
        else if (!strcmp(argv[i], "--repeats") && i + 1 < argc) repeats = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: reflect bench --gl [--out DIR] [--sizes WxH,...] [--methods planar,c3rc,sbc,spoc,graphcam]\n"
                            "                         [--scenes NAME,...|all] [--points N] [--repeats R]\n"
                            "  DIR/gl_projection.csv: every camera's projection rate, GLSL beside C\n"
                            "  DIR/gl_frames.csv: PLANAR (mirror-room, default), C3RC and SBC (default),\n"
                            "                     SPOC (teapots), GRAPHCAM (maze, default) frames through GL\n"
                            "                     against the CPU path (--scenes: every method on these\n"
                            "                     built-in scenes instead)\n"
                            "  DIR/gl_frames.png, DIR/gl_projection.png: their charts (gnuplot)\n");
            return !strcmp(argv[i], "--help") ? 0 : 2;
        }
    }
    if (rgl_create(&g, err, sizeof err) != 0) {
        fprintf(stderr, "reflect: bench --gl: no GL context: %s\n", err);
        return 1;
    }
    printf("GL renderer: %s (%s)\n", rgl_renderer(g), rgl_version(g));
    snprintf(path, sizeof path, "mkdir -p '%s'", dir);
    if (system(path) != 0) {
        rgl_destroy(g);
        return 1;
    }
    snprintf(path, sizeof path, "%s/gl_projection.csv", dir);
    if (!(csv = fopen(path, "w"))) {
        rgl_destroy(g);
        return 1;
    }
    failed = rgl_bench_projection(g, points, repeats, 0, csv);
    fclose(csv);
    snprintf(path, sizeof path, "%s/gl_frames.csv", dir);
    if (!(csv = fopen(path, "w"))) {
        rgl_destroy(g);
        return 1;
    }
    failed |= rgl_bench_frames(g, sizes, methods, scenes, 640 * 480, csv);
    fclose(csv);
    printf("wrote %s/gl_projection.csv and %s/gl_frames.csv\n", dir, dir);
    if (rgl__frames_chart(dir, rgl_renderer(g)) != 0) failed = 1;
    rgl_destroy(g);
    return failed;
}
