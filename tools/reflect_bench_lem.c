/* reflect bench --only lem and --only lem-sweeps: paper 001 (Hakura and
   Snyder's hybrid rendering) measured the paper's way.

   lem: its section 6 table on the `hybrid` scene (a glass teapot, a mirror
   cup, a ring of columns, distant walls), 640x480 3x3 subsampled (spp 9:
   the tessellation's t in subpixels), t = 3 and 5, per layer count (1 to
   REFL_LEM_MAX_LAYERS, and the default): each a renderer's second frame,
   its maps kept (the paper's frame times leave the precomputed maps out),
   its phases (vertex ray tracing, texture coordinates and drawing,
   tessellation, the frame), rays and triangle tests (and of those, the
   vertices': the paths cast at the lens objects alone), against greedy
   RAYTRACE of the same frame (desc.raytrace.greedy, the paper's
   reference), the reduction factors beside the paper's and the full ray
   tree's extra cost. A table on stdout, dir/lem_table.csv and
   dir/lem_table.md.

   lem-sweeps: where the paper says the method fails, at 160x120: eyes off
   the samples (azimuth between them, elevation off the circle), the
   samples' spacing, the layers, a diffuse column moved from its place to
   touching the teapot, the tessellation's t and angle, and a column moved
   after the maps were built (the renderer keeps its stale maps:
   layered_em.keep_stale_maps, beside fresh maps of the moved scene). Per
   setting the PSNR and the mean absolute error over the lens pixels
   against greedy RAYTRACE, the traced pixels (lens pixels no tessellation
   triangle covered, or whose paths left through the other lens), rays and
   time; every pixel must be finite. dir/lem_sweeps.csv, dir/lem_sweeps.md
   and the chart dir/lem_sweeps.png. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../bench/grid_peer.h"
#include "reflect_bench.h"

enum { LEM_DEPTH = 6 };        /* reflect render's default bounces, enough for the greedy paths */
#define LEM_PI 3.14159265358979

/* ---- shared -------------------------------------------------------------------------- */

/* Error of f against truth over the lens pixels (the truth's reflector
   stencil), on colour clamped to [0, 1]: PSNR, and the mean absolute
   channel difference in 8-bit levels. Non-finite channels of f anywhere
   are counted. */
typedef struct lem_error {
    double psnr, mean_abs;
    long long pixels, nonfinite;
} lem_error;

static float lem_clamp01(float x) { return x < 0.0f ? 0.0f : x > 1.0f ? 1.0f : x; }

static lem_error lem_measure(const refl_frame *f, const refl_frame *truth) {
    lem_error e;
    double se = 0.0, ae = 0.0;
    long long i, n = (long long)f->width * f->height;
    int c;
    memset(&e, 0, sizeof e);
    for (i = 0; i < 4 * n; ++i) e.nonfinite += !isfinite(f->rgba[i]);
    for (i = 0; i < n; ++i) {
        if (!truth->stencil[i]) continue;
        ++e.pixels;
        for (c = 0; c < 3; ++c) {
            double d = (double)lem_clamp01(f->rgba[4 * i + c]) - (double)lem_clamp01(truth->rgba[4 * i + c]);
            if (!isfinite(d)) continue;
            se += d * d;
            ae += fabs(d);
        }
    }
    if (e.pixels) {
        double mse = se / (3.0 * (double)e.pixels);
        e.psnr = mse > 0.0 ? 10.0 * log10(1.0 / mse) : 99.0;
        e.mean_abs = 255.0 * ae / (3.0 * (double)e.pixels);
    }
    return e;
}

/* dir/name opened for writing, or NULL (said on stderr). */
static FILE *lem_open(const char *dir, const char *name) {
    char path[1024];
    FILE *f;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    f = fopen(path, "w");
    if (!f) fprintf(stderr, "reflect bench: cannot write %s\n", path);
    return f;
}

static int lem_object(const refl_scene *s, const char *name) {
    int i;
    for (i = 0; i < s->object_count; ++i)
        if (!strcmp(s->objects[i].name, name)) return i;
    return -1;
}

/* An object's world-space bounds. */
static void lem_bounds(const refl_scene *s, int object, refl_vec3 *lo, refl_vec3 *hi) {
    int n = refl_object_world_positions(s, object, NULL), k;
    float *p = n > 0 ? (float *)malloc(3 * sizeof(float) * (size_t)n) : NULL;
    *lo = refl_v3(1e30f, 1e30f, 1e30f);
    *hi = refl_v3(-1e30f, -1e30f, -1e30f);
    if (!p) return;
    refl_object_world_positions(s, object, p);
    for (k = 0; k < n; ++k) {
        *lo = refl_v3(fminf(lo->x, p[3 * k]), fminf(lo->y, p[3 * k + 1]), fminf(lo->z, p[3 * k + 2]));
        *hi = refl_v3(fmaxf(hi->x, p[3 * k]), fmaxf(hi->y, p[3 * k + 1]), fmaxf(hi->z, p[3 * k + 2]));
    }
    free(p);
}

static refl_vec3 lem_centre(const refl_scene *s, int object) {
    refl_vec3 lo, hi;
    lem_bounds(s, object, &lo, &hi);
    return refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
}

/* The view with its eye turned about the vertical through c by azimuth
   degrees and raised about c by elevation degrees (its distance from c
   kept), looking where it looked. */
static refl_view lem_turned(refl_view v, refl_vec3 c, double azimuth, double elevation) {
    refl_vec3 off = refl_v3_sub(v.eye, c);
    float a = (float)(azimuth * LEM_PI / 180.0), e = (float)(elevation * LEM_PI / 180.0);
    float r = sqrtf(off.x * off.x + off.z * off.z), el0 = atan2f(off.y, r), len = refl_v3_length(off);
    float az = atan2f(off.x, off.z) + a, el = el0 + e;
    v.eye = refl_v3_add(c, refl_v3(len * cosf(el) * sinf(az), len * sinf(el), len * cosf(el) * cosf(az)));
    return v;
}

/* The scene's camera at w x h. */
static refl_view lem_camera(const refl_scene *s, int w, int h) {
    refl_view v = s->camera;
    v.width = w;
    v.height = h;
    return v;
}

static refl_render_desc lem_desc(int threads, int spp) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.threads = threads;
    d.depth = LEM_DEPTH;
    d.spp = spp;
    return d;
}

/* The scene's camera at w x h into *v, and greedy RAYTRACE of it (the
   truth) into truth; 0 on failure. */
static int lem_camera_truth(const refl_scene *s, int w, int h, int threads, refl_view *v, refl_frame *truth) {
    refl_render_desc d = lem_desc(threads, 1);
    *v = s->camera;
    v->width = w;
    v->height = h;
    d.method = REFL_RAYTRACE;
    d.raytrace.greedy = 1;
    return refl_render(s, v, &d, truth) == REFL_OK;
}

/* ---- section 6's table ------------------------------------------------------------------ */

typedef struct lem_col {
    int layers;                   /* 0: the default */
    float t;
    double ms_first, ms_trace, ms_draw, ms_tess, ms_base, ms_frame;
    long long rays, tests, vertex_tests, traced, vertices;
    lem_error greedy, full;
} lem_col;

/* A renderer's first frame (inferring its maps) and second (keeping
   them) of v; the second's stats and error into c. */
static int lem_table_col(const refl_scene *s, const refl_view *v, int threads, const refl_frame *greedy,
                         const refl_frame *full, refl_frame *f, lem_col *c) {
    refl_render_desc d = lem_desc(threads, 9);
    refl_renderer *rr = NULL;
    int ok;
    d.method = REFL_LAYERED_EM;
    d.layered_em.layers = c->layers;
    d.layered_em.edge_px = c->t;
    ok = refl_renderer_create(s, &d, &rr) == REFL_OK && refl_renderer_render(rr, v, f) == REFL_OK;
    c->ms_first = f->stats.ms_total;
    ok = ok && refl_renderer_render(rr, v, f) == REFL_OK;
    refl_renderer_destroy(rr);
    if (!ok) return 0;
    c->ms_trace = f->stats.layered_em.ms_trace;
    c->ms_draw = f->stats.layered_em.ms_draw;
    c->ms_tess = f->stats.layered_em.ms_tessellate;
    c->ms_base = f->stats.ms_base;
    c->ms_frame = f->stats.ms_total;
    c->rays = f->stats.rays;
    c->tests = f->stats.triangle_tests;
    c->vertex_tests = f->stats.layered_em.vertex_tests;
    c->traced = f->stats.layered_em.traced_pixels;
    c->vertices = f->stats.layered_em.vertices;
    c->greedy = lem_measure(f, greedy);
    c->full = lem_measure(f, full);
    return c->greedy.nonfinite == 0;
}

static double lem_ratio(double a, double b) { return b > 0.0 ? a / b : 0.0; }

/* dir/name.csv and dir/name.md opened for writing; 0 (and said) when not. */
static int lem_open_pair(const char *dir, const char *name, FILE **csv, FILE **md) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s.csv", dir, name);
    *csv = fopen(path, "w");
    snprintf(path, sizeof path, "%s/%s.md", dir, name);
    *md = fopen(path, "w");
    if (!*csv || !*md) fprintf(stderr, "reflect bench: cannot write %s/%s.{csv,md}\n", dir, name);
    return *csv && *md;
}

/* dir/name.md, written, to stdout. */
static void lem_echo(const char *dir, const char *name) {
    char path[1024], line[4096];
    FILE *in;
    snprintf(path, sizeof path, "%s/%s.md", dir, name);
    in = fopen(path, "r");
    while (in && fgets(line, sizeof line, in)) fputs(line, stdout);
    if (in) fclose(in);
    fprintf(stderr, "wrote %s/%s.csv and %s\n", dir, name, path);
}

int refl_bench_lem(const char *dir, int threads, int quick) {
    enum { MAX_COLS = 2 * (REFL_LEM_MAX_LAYERS + 1) };
    static const float ts[2] = {3.0f, 5.0f};
    static const double paper_rays[2] = {6.0, 10.8}, paper_tests[2] = {14.2, 25.7};
    const int w = quick ? 160 : 640, h = quick ? 120 : 480;
    refl_scene *s = refl_bench_builtin("hybrid", 0);
    refl_frame *greedy = NULL, *full = NULL, *f = NULL;
    refl_render_desc d = lem_desc(threads, 9);
    lem_col cols[MAX_COLS];
    refl_stats gs, fs;
    lem_error full_err;
    refl_view v;
    FILE *csv = NULL, *md = NULL;
    int ncols = 0, i, k, best = -1, ok = 1;
    if (!s || refl_frame_create(w, h, NULL, &greedy) != REFL_OK || refl_frame_create(w, h, NULL, &full) != REFL_OK ||
        refl_frame_create(w, h, NULL, &f) != REFL_OK) {
        fprintf(stderr, "reflect bench: the hybrid scene could not be set up\n");
        ok = 0;
        goto done;
    }
    v = lem_camera(s, w, h);
    printf("hybrid (paper 001 section 6), %dx%d 3x3 subsampled, depth %d, %s threads\n", w, h, LEM_DEPTH,
           threads ? "given" : "all");
    d.method = REFL_RAYTRACE;
    d.raytrace.greedy = 1;
    if (refl_render(s, &v, &d, greedy) != REFL_OK) ok = 0;
    gs = greedy->stats;
    printf("greedy RAYTRACE: %.0f ms, %lld rays, %lld triangle tests\n", gs.ms_total, gs.rays, gs.triangle_tests);
    fflush(stdout);
    d.raytrace.greedy = 0;
    if (ok && refl_render(s, &v, &d, full) != REFL_OK) ok = 0;
    fs = full->stats;
    full_err = lem_measure(full, greedy);
    printf("full ray tree RAYTRACE: %.0f ms, %lld rays, %lld triangle tests, %.2f dB from greedy\n", fs.ms_total,
           fs.rays, fs.triangle_tests, full_err.psnr);
    fflush(stdout);
    /* layers REFL_LEM_MAX_LAYERS down to 1, then the default (0) */
    for (k = REFL_LEM_MAX_LAYERS; ok && k >= 0; --k)
        for (i = 0; ok && i < 2; ++i) {
            lem_col *c = &cols[ncols];
            memset(c, 0, sizeof *c);
            c->layers = k;
            c->t = ts[i];
            fprintf(stderr, "reflect bench: LAYERED_EM layers %d t %.0f ...\n", c->layers, c->t);
            if (!lem_table_col(s, &v, threads, greedy, full, f, c)) {
                fprintf(stderr, "reflect bench: LAYERED_EM layers %d t %.0f failed (or a non-finite pixel)\n",
                        c->layers, c->t);
                ok = 0;
                break;
            }
            printf("layers %d t %.0f: first frame %.0f ms; kept: trace %.0f, draw %.0f, tessellate %.0f, base %.0f, "
                   "frame %.0f ms; %lld rays, %lld tests, %lld traced px; %.2f dB (full tree %.2f dB)\n",
                   c->layers, c->t, c->ms_first, c->ms_trace, c->ms_draw, c->ms_tess, c->ms_base, c->ms_frame, c->rays,
                   c->tests, c->traced, c->greedy.psnr, c->full.psnr);
            fflush(stdout);
            ++ncols;
        }
    if (!ok) goto done;
    /* the best layer count: the highest PSNR against greedy RAYTRACE at t = 3 */
    for (i = 0; i < ncols; i += 2)
        if (cols[i].layers && (best < 0 || cols[i].greedy.psnr > cols[best].greedy.psnr)) best = i;

    if (!lem_open_pair(dir, "lem_table", &csv, &md)) {
        ok = 0;
        goto done;
    }
    fprintf(csv, "method,layers,t_subpx,width,height,first_frame_ms,trace_ms,draw_ms,tessellate_ms,base_ms,frame_ms,"
                 "rays,triangle_tests,traced_pixels,vertices,psnr_greedy_db,mean_abs_greedy,psnr_full_db,"
                 "time_reduction,ray_reduction,test_reduction,vertex_tests\n");
    fprintf(csv, "raytrace-greedy,,,%d,%d,,,,,,%.1f,%lld,%lld,,,,,,,,,\n", w, h, gs.ms_total, gs.rays, gs.triangle_tests);
    fprintf(csv, "raytrace-full,,,%d,%d,,,,,,%.1f,%lld,%lld,,,%.3f,%.3f,,,,,\n", w, h, fs.ms_total, fs.rays,
            fs.triangle_tests, full_err.psnr, full_err.mean_abs);
    for (i = 0; i < ncols; ++i) {
        const lem_col *c = &cols[i];
        fprintf(csv, "layered-em,%d,%.0f,%d,%d,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%lld,%lld,%lld,%lld,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,"
                     "%lld\n",
                c->layers, c->t, w, h, c->ms_first, c->ms_trace, c->ms_draw, c->ms_tess, c->ms_base, c->ms_frame,
                c->rays, c->tests, c->traced, c->vertices, c->greedy.psnr, c->greedy.mean_abs, c->full.psnr,
                lem_ratio(gs.ms_total, c->ms_frame), lem_ratio((double)gs.rays, (double)c->rays),
                lem_ratio((double)gs.triangle_tests, (double)c->tests), c->vertex_tests);
    }
    /* the markdown table: the paper's columns, then ours */
    fprintf(md, "`hybrid`, %dx%d 3x3 subsampled (t in subpixels), depth %d; LAYERED_EM: a renderer's second frame "
                "(maps kept); layers 0 is the default; best (by PSNR at t = 3): %d layer%s\n\n",
            w, h, LEM_DEPTH, cols[best].layers, cols[best].layers == 1 ? "" : "s");
    fprintf(md, "| | paper t = 3 | paper t = 5 |");
    for (i = 0; i < ncols; ++i) fprintf(md, " layers %d t = %.0f%s |", cols[i].layers, cols[i].t, i / 2 == best / 2 ? " (best)" : "");
    fprintf(md, "\n|---|---|---|");
    for (i = 0; i < ncols; ++i) fprintf(md, "---|");
#define LEM_ROW(label, p3, p5, fmt, expr)                                                                              \
    do {                                                                                                               \
        fprintf(md, "\n| %s | %s | %s |", label, p3, p5);                                                              \
        for (i = 0; i < ncols; ++i) {                                                                                  \
            const lem_col *c = &cols[i];                                                                               \
            (void)c;                                                                                                   \
            fprintf(md, " " fmt " |", expr);                                                                           \
        }                                                                                                              \
    } while (0)
    LEM_ROW("ray tracing at vertices (ms)", "13480", "7820", "%.0f", c->ms_trace);
    LEM_ROW("texture coordinates + rendering (ms)", "3280", "1830", "%.0f", c->ms_draw);
    LEM_ROW("tessellation (ms)", "2110", "830", "%.0f", c->ms_tess);
    LEM_ROW("base pass: the rest of the scene rasterised (ms)", "", "", "%.0f", c->ms_base);
    LEM_ROW("frame (ms)", "18870", "10480", "%.0f", c->ms_frame);
    LEM_ROW("first frame, inferring the maps (ms)", "", "", "%.0f", c->ms_first);
    LEM_ROW("greedy ray tracing of the frame (ms)", "480000", "480000", "%.0f", gs.ms_total);
    LEM_ROW("time reduction", "×25.4", "×45.8", "×%.2f", lem_ratio(gs.ms_total, c->ms_frame));
    LEM_ROW("rays", "1,023,876", "570,481", "%lld", c->rays);
    LEM_ROW("greedy ray tracing's rays", "6,153,735", "6,153,735", "%lld", gs.rays);
    LEM_ROW("ray reduction", "×6", "×10.8", "×%.2f", lem_ratio((double)gs.rays, (double)c->rays));
    LEM_ROW("triangle tests", "11,878,133", "6,543,993", "%lld", c->tests);
    LEM_ROW("of which tracing the vertices", "", "", "%lld", c->vertex_tests);
    LEM_ROW("greedy ray tracing's triangle tests", "168,313,768", "168,313,768", "%lld", gs.triangle_tests);
    LEM_ROW("triangle test reduction", "×14.2", "×25.7", "×%.2f", lem_ratio((double)gs.triangle_tests, (double)c->tests));
    /* the test reduction is the ray reduction times the ratio of these two */
    LEM_ROW("triangle tests per ray", "11.6", "11.5", "%.1f", lem_ratio((double)c->tests, (double)c->rays));
    LEM_ROW("greedy ray tracing's triangle tests per ray", "27.4", "27.4", "%.1f",
            lem_ratio((double)gs.triangle_tests, (double)gs.rays));
    LEM_ROW("lens pixels traced", "", "", "%lld", c->traced);
    LEM_ROW("PSNR over the lenses against greedy RAYTRACE (dB)", "", "", "%.2f", c->greedy.psnr);
    LEM_ROW("mean abs error over the lenses (8-bit levels)", "", "", "%.2f", c->greedy.mean_abs);
    LEM_ROW("PSNR over the lenses against full RAYTRACE (dB)", "", "", "%.2f", c->full.psnr);
#undef LEM_ROW
    fprintf(md, "\n\nThe full ray tree (RAYTRACE's default) against greedy RAYTRACE of the same frame: %.0f ms against "
                "%.0f (×%.2f; paper ×5), %lld rays (×%.2f), %lld triangle tests (×%.2f); %.2f dB over the lenses.\n",
            fs.ms_total, gs.ms_total, lem_ratio(fs.ms_total, gs.ms_total), fs.rays,
            lem_ratio((double)fs.rays, (double)gs.rays), fs.triangle_tests,
            lem_ratio((double)fs.triangle_tests, (double)gs.triangle_tests), full_err.psnr);
    for (i = 0; i < ncols; ++i) {
        const lem_col *c = &cols[i];
        double rr = lem_ratio((double)gs.rays, (double)c->rays), tr = lem_ratio((double)gs.triangle_tests, (double)c->tests);
        double pr = paper_rays[i & 1], pt = paper_tests[i & 1];
        fprintf(md, "\nlayers %d t = %.0f: ray reduction ×%.2f against the paper's ×%.1f (%s a factor of 1.5), "
                    "triangle tests ×%.2f against ×%.1f (%s).",
                c->layers, c->t, rr, pr, rr >= pr / 1.5 && rr <= pr * 1.5 ? "within" : "outside", tr, pt,
                tr >= pt / 1.5 && tr <= pt * 1.5 ? "within" : "outside");
    }
    fprintf(md, "\n");
    fputs("\n", stdout);
    fclose(md);
    md = NULL;
    lem_echo(dir, "lem_table");
done:
    if (csv) fclose(csv);
    if (md) fclose(md);
    refl_frame_destroy(greedy);
    refl_frame_destroy(full);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    return ok;
}

/* ---- the stability sweeps -------------------------------------------------------------- */

enum { SW_LEM_W = 160, SW_LEM_H = 120, SW_LEM_MAX_ROWS = 192 };

typedef struct lem_sweep_row {
    char sweep[16], series[16], setting[48];
    double x, ms;
    lem_error e;
    long long traced, rays;
} lem_sweep_row;

typedef struct lem_sweeps {
    const refl_scene *s;
    int threads;
    refl_frame *truth, *f;
    lem_sweep_row rows[SW_LEM_MAX_ROWS];
    int count;
} lem_sweeps;

/* Greedy RAYTRACE of v into sw->truth. */
static int lem_truth(lem_sweeps *sw, const refl_view *v) {
    refl_render_desc d = lem_desc(sw->threads, 1);
    d.method = REFL_RAYTRACE;
    d.raytrace.greedy = 1;
    return refl_render(sw->s, v, &d, sw->truth) == REFL_OK;
}

/* Renders v (through rr, else refl_render with d: maps of its own) and
   measures it against sw->truth; 0 on failure or a non-finite pixel. */
static int lem_sweep_row_add(lem_sweeps *sw, const char *sweep, const char *series, const char *setting, double x,
                             refl_renderer *rr, const refl_render_desc *d, const refl_view *v) {
    lem_sweep_row *r;
    refl_result res = rr ? refl_renderer_render(rr, v, sw->f) : refl_render(sw->s, v, d, sw->f);
    if (res != REFL_OK || sw->count >= SW_LEM_MAX_ROWS) {
        fprintf(stderr, "reflect bench: %s %s %s: %s\n", sweep, series, setting,
                res != REFL_OK ? refl_result_string(res) : "too many rows");
        return 0;
    }
    r = &sw->rows[sw->count++];
    snprintf(r->sweep, sizeof r->sweep, "%s", sweep);
    snprintf(r->series, sizeof r->series, "%s", series);
    snprintf(r->setting, sizeof r->setting, "%s", setting);
    r->x = x;
    r->e = lem_measure(sw->f, sw->truth);
    r->ms = sw->f->stats.ms_total;
    r->traced = sw->f->stats.layered_em.traced_pixels;
    r->rays = sw->f->stats.rays;
    printf("%-10s %-8s %-26s %7.2f %7.2f %6lld %6lld %8lld %8.0f %4lld\n", r->sweep, r->series, r->setting, r->e.psnr,
           r->e.mean_abs, r->e.pixels, r->traced, r->rays, r->ms, r->e.nonfinite);
    fflush(stdout);
    if (r->e.nonfinite) fprintf(stderr, "reflect bench: %s %s: %lld non-finite channels\n", sweep, setting, r->e.nonfinite);
    return r->e.nonfinite == 0;
}

/* A renderer of d for the sweep; NULL on failure. */
static refl_renderer *lem_renderer(const lem_sweeps *sw, const refl_render_desc *d) {
    refl_renderer *rr = NULL;
    return refl_renderer_create(sw->s, d, &rr) == REFL_OK ? rr : NULL;
}

/* Writes the CSV, the markdown table and the chart (PSNR per setting, a
   panel per sweep). */
static int lem_sweeps_write(const lem_sweeps *sw, const char *dir) {
    static const char *const panels[][3] = {
        {"azimuth", "eye turned about the teapot (degrees from the first frame)", "PSNR (dB)"},
        {"elevation", "eye raised off the circle (degrees)", "PSNR (dB)"},
        {"spacing", "sample spacing (degrees); mean over 6 eyes", "PSNR (dB)"},
        {"layers", "layers", "PSNR (dB)"},
        {"near", "gap between the column and the teapot (scene units)", "PSNR (dB)"},
        {"edge", "tessellation t (pixels)", "PSNR (dB)"},
        {"angle", "tessellation angle (degrees)", "PSNR (dB)"},
        {"moved", "column moved after the maps (scene units)", "PSNR (dB)"},
        {"disocclusion", "0 neither, 1 simultaneous inference, 2 direct images, 3 both (2 layers)", "PSNR (dB)"},
        {"shell", "shell kind: 0 auto, 1 sphere, 2 cylinder, 3 box, 4 quad (2 layers)", "PSNR (dB)"},
    };
    char path[1024], dat[1024], script[16384];
    FILE *csv, *md, *dp;
    size_t len = 0;
    int i, j, p, ok = 1;
    snprintf(path, sizeof path, "%s/lem_sweeps.csv", dir);
    csv = fopen(path, "w");
    snprintf(path, sizeof path, "%s/lem_sweeps.md", dir);
    md = fopen(path, "w");
    snprintf(dat, sizeof dat, "%s/lem_sweeps.dat", dir);
    dp = fopen(dat, "w");
    if (!csv || !md || !dp) {
        fprintf(stderr, "reflect bench: cannot write the sweeps' files in %s\n", dir);
        if (csv) fclose(csv);
        if (md) fclose(md);
        if (dp) fclose(dp);
        return 0;
    }
    fprintf(csv, "sweep,series,setting,x,psnr_db,mean_abs_levels,lens_pixels,traced_pixels,rays,frame_ms,nonfinite\n");
    fprintf(md, "| sweep | series | setting | PSNR (dB) | mean abs (levels) | lens px | traced px | rays | ms |\n"
                "|---|---|---|---|---|---|---|---|---|\n");
    for (i = 0; i < sw->count; ++i) {
        const lem_sweep_row *r = &sw->rows[i];
        fprintf(csv, "%s,%s,\"%s\",%g,%.3f,%.3f,%lld,%lld,%lld,%.1f,%lld\n", r->sweep, r->series, r->setting, r->x,
                r->e.psnr, r->e.mean_abs, r->e.pixels, r->traced, r->rays, r->ms, r->e.nonfinite);
        fprintf(md, "| %s | %s | %s | %.2f | %.2f | %lld | %lld | %lld | %.0f |\n", r->sweep, r->series, r->setting,
                r->e.psnr, r->e.mean_abs, r->e.pixels, r->traced, r->rays, r->ms);
    }
    fclose(csv);
    fclose(md);
    /* a gnuplot block per sweep and series, in the panels' order */
    len += (size_t)snprintf(script + len, sizeof script - len,
                            "set terminal pngcairo size 1400,1600 noenhanced\nset output '%s/lem_sweeps.png'\n"
                            "set multiplot layout 4,3 title 'LAYERED_EM against greedy RAYTRACE over the lens pixels, "
                            "hybrid %dx%d'\nset grid\nset key bottom left\n",
                            dir, SW_LEM_W, SW_LEM_H);
    for (p = 0, j = 0; p < (int)(sizeof panels / sizeof *panels); ++p) {
        char series[8][16];
        int ns = 0, k, first = 1;
        for (i = 0; i < sw->count; ++i) {
            int seen = 0;
            if (strcmp(sw->rows[i].sweep, panels[p][0])) continue;
            for (k = 0; k < ns; ++k) seen |= !strcmp(series[k], sw->rows[i].series);
            if (!seen && ns < 8) snprintf(series[ns++], 16, "%s", sw->rows[i].series);
        }
        if (!ns) continue;
        len += (size_t)snprintf(script + len, sizeof script - len, "set title '%s'\nset xlabel '%s'\nset ylabel '%s'\nplot ",
                                panels[p][0], panels[p][1], panels[p][2]);
        for (k = 0; k < ns; ++k, ++j) {
            fprintf(dp, "# %s %s\n", panels[p][0], series[k]);
            for (i = 0; i < sw->count; ++i)
                if (!strcmp(sw->rows[i].sweep, panels[p][0]) && !strcmp(sw->rows[i].series, series[k]))
                    fprintf(dp, "%g %g %g\n", sw->rows[i].x, sw->rows[i].e.psnr, sw->rows[i].e.mean_abs);
            fprintf(dp, "\n\n");
            len += (size_t)snprintf(script + len, sizeof script - len, "%s'%s' index %d using 1:2 with linespoints title '%s'",
                                    first ? "" : ", ", dat, j, series[k]);
            first = 0;
        }
        len += (size_t)snprintf(script + len, sizeof script - len, "\n");
    }
    snprintf(script + (len < sizeof script ? len : sizeof script - 1),
             sizeof script - (len < sizeof script ? len : sizeof script - 1), "unset multiplot\n");
    fclose(dp);
    snprintf(path, sizeof path, "%s/lem_sweeps.gp", dir);
    ok = refl_bench_gnuplot(path, script);
    if (ok) fprintf(stderr, "wrote %s/lem_sweeps.csv, lem_sweeps.md and lem_sweeps.png\n", dir);
    return ok;
}

int refl_bench_lem_sweeps(const char *dir, int threads) {
    static const double azimuths[] = {0, 1, 2, 3, 4, 6, 8, 12, 16, 24};
    static const double elevations[] = {0, 2.5, 5, 10, 20, 30, 45};
    static const int samples[] = {90, 45, 30, 20, 15, 11}; /* 4 to 32.7 degrees apart */
    static const double spacing_eyes[] = {0, 3, 6, 9, 12, 15};
    static const float edges[] = {0.5f, 1.0f, 2.0f, 3.0f, 5.0f, 8.0f, 16.0f};
    static const float angles[] = {1.0f, 3.0f, 6.0f, 12.0f, 24.0f, 48.0f};
    static const float near_share[] = {0.0f, 0.5f, 0.75f, 0.9f, 1.0f};
    static const float moved[] = {0.0f, 0.25f, 0.5f, 1.0f, 2.0f};
    refl_scene *s = refl_bench_builtin("hybrid", 0);
    lem_sweeps *sw = (lem_sweeps *)calloc(1, sizeof *sw);
    refl_render_desc d = lem_desc(threads, 1);
    refl_renderer *rr = NULL;
    refl_view v0, v;
    refl_vec3 teapot_c = refl_v3(0, 0, 0), along = refl_v3(0, 0, 0);
    char setting[48];
    int teapot = -1, column = -1, ok = 1, k;
    size_t i, j;
    if (s) teapot = lem_object(s, "glass teapot");
    if (!s || !sw || teapot < 0 || refl_frame_create(SW_LEM_W, SW_LEM_H, NULL, &sw->truth) != REFL_OK ||
        refl_frame_create(SW_LEM_W, SW_LEM_H, NULL, &sw->f) != REFL_OK) {
        fprintf(stderr, "reflect bench: the LAYERED_EM sweeps could not start\n");
        ok = 0;
        goto done;
    }
    sw->s = s;
    sw->threads = threads;
    d.method = REFL_LAYERED_EM;
    v0 = s->camera;
    v0.width = SW_LEM_W;
    v0.height = SW_LEM_H;
    teapot_c = lem_centre(s, teapot);
    /* the column behind the teapot as the camera sees it: the most of it in the glass */
    {
        refl_vec3 look = refl_v3_sub(teapot_c, v0.eye);
        float best = -2.0f;
        look.y = 0.0f;
        look = refl_v3_normalize(look);
        for (k = 0; k < s->object_count; ++k) {
            refl_vec3 to;
            float a;
            if (strcmp(s->objects[k].name, "column")) continue;
            to = refl_v3_sub(lem_centre(s, k), teapot_c);
            to.y = 0.0f;
            a = refl_v3_dot(refl_v3_normalize(to), look);
            if (a > best) best = a, column = k, along = refl_v3_normalize(to);
        }
    }
    if (column < 0) {
        fprintf(stderr, "reflect bench: hybrid has no column\n");
        ok = 0;
        goto done;
    }
    printf("hybrid %dx%d, LAYERED_EM against greedy RAYTRACE over the lens pixels, depth %d, %s threads\n", SW_LEM_W,
           SW_LEM_H, LEM_DEPTH, threads ? "given" : "all");
    printf("%-10s %-8s %-26s %7s %7s %6s %6s %8s %8s %4s\n", "sweep", "series", "setting", "PSNR", "abs", "lens",
           "traced", "rays", "ms", "NaN");

    /* 1. off-sample eyes: one renderer, its circles fixed at the first
       frame's eye, the eye then turned about the teapot (between and past
       the samples, 8 degrees apart) and raised off the circle */
    rr = lem_renderer(sw, &d);
    ok = rr != NULL;
    for (i = 0; ok && i < sizeof azimuths / sizeof *azimuths; ++i) {
        v = lem_turned(v0, teapot_c, azimuths[i], 0.0);
        snprintf(setting, sizeof setting, "azimuth %+.0f", azimuths[i]);
        ok = lem_truth(sw, &v) && lem_sweep_row_add(sw, "azimuth", "default", setting, azimuths[i], rr, &d, &v);
    }
    for (i = 0; ok && i < sizeof elevations / sizeof *elevations; ++i) {
        v = lem_turned(v0, teapot_c, 0.0, elevations[i]);
        snprintf(setting, sizeof setting, "elevation %+.1f", elevations[i]);
        ok = lem_truth(sw, &v) && lem_sweep_row_add(sw, "elevation", "default", setting, elevations[i], rr, &d, &v);
    }
    refl_renderer_destroy(rr);
    rr = NULL;

    /* 2. the samples' spacing: per spacing a renderer, its error averaged
       over eyes turned 0 to 15 degrees (each eye a row; the chart's point
       is their mean) */
    for (i = 0; ok && i < sizeof samples / sizeof *samples; ++i) {
        double spacing = 360.0 / samples[i], sum_psnr = 0.0, sum_abs = 0.0;
        int first = sw->count;
        d.layered_em.samples = samples[i];
        ok = (rr = lem_renderer(sw, &d)) != NULL;
        for (j = 0; ok && j < sizeof spacing_eyes / sizeof *spacing_eyes; ++j) {
            v = lem_turned(v0, teapot_c, spacing_eyes[j], 0.0);
            snprintf(setting, sizeof setting, "%d samples (%.1f deg), eye %+.0f", samples[i], spacing, spacing_eyes[j]);
            ok = lem_truth(sw, &v) && lem_sweep_row_add(sw, "spacing-eye", "default", setting, spacing, rr, &d, &v);
            if (ok) sum_psnr += sw->rows[sw->count - 1].e.psnr, sum_abs += sw->rows[sw->count - 1].e.mean_abs;
        }
        refl_renderer_destroy(rr);
        rr = NULL;
        if (ok && sw->count < SW_LEM_MAX_ROWS) { /* the mean over the eyes, charted */
            lem_sweep_row *r = &sw->rows[sw->count++];
            int n = sw->count - 1 - first;
            *r = sw->rows[first];
            snprintf(r->sweep, sizeof r->sweep, "spacing");
            snprintf(r->setting, sizeof r->setting, "%d samples (%.1f deg), mean", samples[i], spacing);
            r->e.psnr = sum_psnr / n;
            r->e.mean_abs = sum_abs / n;
        }
    }
    d.layered_em.samples = 0;

    /* 3. layers 1 to REFL_LEM_MAX_LAYERS, at the first eye and 4 degrees off */
    for (k = 1; ok && k <= REFL_LEM_MAX_LAYERS; ++k) {
        d.layered_em.layers = k;
        ok = (rr = lem_renderer(sw, &d)) != NULL;
        for (j = 0; ok && j < 2; ++j) {
            v = lem_turned(v0, teapot_c, 4.0 * (double)j, 0.0);
            snprintf(setting, sizeof setting, "%d layer%s, eye %+d", k, k == 1 ? "" : "s", 4 * (int)j);
            ok = lem_truth(sw, &v) && lem_sweep_row_add(sw, "layers", j ? "eye +4" : "eye 0", setting, k, rr, &d, &v);
        }
        refl_renderer_destroy(rr);
        rr = NULL;
    }
    d.layered_em.layers = 0;

    /* 4. a diffuse column moved from its place towards the teapot until
       it touches it (the first 0.02 step whose bounds gap is under 0.02);
       each placement's maps its own */
    if (ok) {
        refl_mat4 original = s->objects[column].transform;
        refl_vec3 tlo, thi, clo, chi;
        float dist = 0.0f, gap0;
        lem_bounds(s, teapot, &tlo, &thi);
        lem_bounds(s, column, &clo, &chi);
        /* the horizontal gap between the boxes along `along` (the column's
           box is thin; the teapot's bounds, a little generous, stand for it) */
        for (;; dist += 0.02f) {
            refl_vec3 c = refl_v3_sub(refl_v3_scale(refl_v3_add(clo, chi), 0.5f), refl_v3_scale(along, dist));
            float hx = 0.5f * (chi.x - clo.x), hz = 0.5f * (chi.z - clo.z);
            float gx = fmaxf(0.0f, fmaxf(tlo.x - (c.x + hx), (c.x - hx) - thi.x));
            float gz = fmaxf(0.0f, fmaxf(tlo.z - (c.z + hz), (c.z - hz) - thi.z));
            if (sqrtf(gx * gx + gz * gz) < 0.02f || dist > 20.0f) break;
        }
        gap0 = dist;
        for (i = 0; ok && i < sizeof near_share / sizeof *near_share; ++i) {
            float m = near_share[i] * gap0;
            s->objects[column].transform = refl_mat4_mul(refl_mat4_translate(refl_v3_scale(along, -m)), original);
            refl_scene_touch(s);
            snprintf(setting, sizeof setting, "moved %.2f, gap %.2f", m, gap0 - m);
            ok = lem_truth(sw, &v0) && lem_sweep_row_add(sw, "near", "default", setting, gap0 - m, NULL, &d, &v0);
        }
        s->objects[column].transform = original;
        refl_scene_touch(s);
    }

    /* 5. the tessellation's thresholds: t (pixels here: no subsampling) and the angle */
    for (i = 0; ok && i < sizeof edges / sizeof *edges; ++i) {
        d.layered_em.edge_px = edges[i];
        snprintf(setting, sizeof setting, "t %.1f px", edges[i]);
        ok = lem_truth(sw, &v0) && lem_sweep_row_add(sw, "edge", "default", setting, edges[i], NULL, &d, &v0);
    }
    d.layered_em.edge_px = 0.0f;
    for (i = 0; ok && i < sizeof angles / sizeof *angles; ++i) {
        d.layered_em.angle_degrees = angles[i];
        snprintf(setting, sizeof setting, "angle %.0f deg", angles[i]);
        ok = lem_truth(sw, &v0) && lem_sweep_row_add(sw, "angle", "default", setting, angles[i], NULL, &d, &v0);
    }
    d.layered_em.angle_degrees = 0.0f;

    /* 6. a column moved sideways after the maps were built: a renderer
       that keeps its maps through the change (layered_em.keep_stale_maps:
       what the paper warns of), beside maps inferred for the moved scene */
    if (ok) {
        refl_mat4 original = s->objects[column].transform;
        refl_vec3 side = refl_v3_normalize(refl_v3_cross(refl_v3(0, 1, 0), along));
        refl_render_desc ds = d;
        ds.layered_em.keep_stale_maps = 1;
        ok = (rr = lem_renderer(sw, &ds)) != NULL && lem_truth(sw, &v0) &&
             refl_renderer_render(rr, &v0, sw->f) == REFL_OK; /* the maps, of the column in place */
        for (i = 0; ok && i < sizeof moved / sizeof *moved; ++i) {
            s->objects[column].transform = refl_mat4_mul(refl_mat4_translate(refl_v3_scale(side, moved[i])), original);
            refl_scene_touch(s);
            snprintf(setting, sizeof setting, "moved %.2f", moved[i]);
            ok = lem_truth(sw, &v0) && lem_sweep_row_add(sw, "moved", "stale", setting, moved[i], rr, &ds, &v0) &&
                 lem_sweep_row_add(sw, "moved", "fresh", setting, moved[i], NULL, &d, &v0);
        }
        refl_renderer_destroy(rr);
        rr = NULL;
        s->objects[column].transform = original;
        refl_scene_touch(s);
    }

    /* 7. disocclusion prevention: each sample's maps from its own view
       alone or from its neighbours' too (section 4.3's simultaneous
       inference), with and without the direct images (x: 0 neither, 1
       simultaneous, 2 direct images, 3 both, the default); and 8. every
       shell kind (x: refl_lem_shell_kind). Each at the first eye and
       halfway between two samples (4 degrees off), two layers. */
    for (k = 0; ok && k < 4; ++k) {
        static const char *const names[] = {"neither", "simultaneous", "direct images", "both"};
        refl_render_desc dd = d;
        dd.layered_em.layers = 2;
        dd.layered_em.single_view = !(k & 1);
        dd.layered_em.direct_images = k & 2 ? 1 : -1;
        for (j = 0; ok && j < 2; ++j) {
            v = lem_turned(v0, teapot_c, 4.0 * (double)j, 0.0);
            ok = lem_truth(sw, &v) &&
                 lem_sweep_row_add(sw, "disocclusion", j ? "eye +4" : "eye 0", names[k], k, NULL, &dd, &v);
        }
    }
    for (k = REFL_LEM_SHELL_AUTO; ok && k <= REFL_LEM_SHELL_QUAD; ++k) {
        static const char *const names[] = {"auto", "sphere", "cylinder", "box", "quad"};
        refl_render_desc dd = d;
        dd.layered_em.layers = 2;
        dd.layered_em.shell = k;
        for (j = 0; ok && j < 2; ++j) {
            v = lem_turned(v0, teapot_c, 4.0 * (double)j, 0.0);
            ok = lem_truth(sw, &v) && lem_sweep_row_add(sw, "shell", j ? "eye +4" : "eye 0", names[k], k, NULL, &dd, &v);
        }
    }

    if (ok) ok = lem_sweeps_write(sw, dir);
done:
    refl_renderer_destroy(rr);
    if (sw) {
        refl_frame_destroy(sw->truth);
        refl_frame_destroy(sw->f);
    }
    free(sw);
    refl_scene_destroy(s);
    return ok;
}

/* ---- options: the other lens as a layer, the direct images ------------------------------ */

/* One setting of lem-options: the options it changes from the defaults. */
typedef struct lem_option {
    const char *name;
    int layers, lens_layers, direct_from, direct_confidence;
} lem_option;

int refl_bench_lem_options(const char *dir, int threads, int quick) {
    static const char *const scenes[2] = {"hybrid", "glass"};
    static const int sizes[2][2] = {{160, 120}, {320, 240}};
    static const lem_option opts[] = {
        {"defaults", 0, 0, 0, 0},
        {"lens_layers 1", 0, 1, 0, 0},
        {"layers 2", 2, 0, 0, 0},
        {"layers 2, lens_layers 1", 2, 1, 0, 0},
        {"direct centre, distance", 0, 0, REFL_LEM_DIRECT_FROM_CENTRE, REFL_LEM_DIRECT_DISTANCE},
        {"direct viewpoint, coverage", 0, 0, REFL_LEM_DIRECT_FROM_VIEWPOINT, REFL_LEM_DIRECT_COVERAGE},
        {"direct viewpoint, distance", 0, 0, REFL_LEM_DIRECT_FROM_VIEWPOINT, REFL_LEM_DIRECT_DISTANCE},
        {"direct material, coverage", 0, 0, REFL_LEM_DIRECT_FROM_MATERIAL, REFL_LEM_DIRECT_COVERAGE},
        {"direct material, distance", 0, 0, REFL_LEM_DIRECT_FROM_MATERIAL, REFL_LEM_DIRECT_DISTANCE},
    };
    const int nopts = (int)(sizeof opts / sizeof opts[0]);
    FILE *md = lem_open(dir, "lem_options.md");
    int sc, sz, k, ok = 1;
    if (!md) return 0;
    fprintf(md, "| scene | size | setting | PSNR lenses (dB) | PSNR where defaults trace (dB) | traced px | direct rows "
                "| frame ms | of it, maps ms |\n|---|---|---|---|---|---|---|---|---|\n");
    printf("%-7s %-8s %-28s %7s %7s %6s %7s %8s %8s\n", "scene", "size", "setting", "lenses", "traced", "px", "direct",
           "ms", "maps ms");
    for (sc = 0; sc < 2 && ok; ++sc)
        for (sz = 0; sz < (quick ? 1 : 2) && ok; ++sz) {
            const int w = sizes[sz][0], h = sizes[sz][1];
            refl_scene *s = refl_bench_builtin(scenes[sc], 0);
            refl_frame *truth = NULL, *full = NULL, *f = NULL;
            unsigned char *mask = (unsigned char *)calloc((size_t)w * h, 1);
            refl_render_desc d = lem_desc(threads, 1);
            refl_view v;
            long long i, n = (long long)w * h, nm = 0;
            ok = s && mask && refl_frame_create(w, h, NULL, &truth) == REFL_OK &&
                 refl_frame_create(w, h, NULL, &full) == REFL_OK && refl_frame_create(w, h, NULL, &f) == REFL_OK;
            if (ok) {
                ok = lem_camera_truth(s, w, h, threads, &v, truth);
                d.method = REFL_RAYTRACE;
                ok = ok && refl_render(s, &v, &d, full) == REFL_OK;
            }
            for (k = 0; k < nopts && ok; ++k) {
                double se = 0.0;
                lem_error e;
                int c;
                d = lem_desc(threads, 1);
                d.method = REFL_LAYERED_EM;
                d.layered_em.layers = opts[k].layers;
                d.layered_em.lens_layers = opts[k].lens_layers;
                d.layered_em.direct_from = opts[k].direct_from;
                d.layered_em.direct_confidence = opts[k].direct_confidence;
                ok = refl_render(s, &v, &d, f) == REFL_OK;
                if (!ok) break;
                e = lem_measure(f, truth);
                ok = e.nonfinite == 0;
                /* the pixels the defaults trace: there their frame is the full tree's own */
                for (i = 0; i < n && k == 0; ++i)
                    if (truth->stencil[i] && f->stats.layered_em.traced_pixels &&
                        !memcmp(f->rgba + 4 * i, full->rgba + 4 * i, 3 * sizeof(float)))
                        mask[i] = 1, ++nm;
                for (i = 0; i < n; ++i)
                    for (c = 0; mask[i] && c < 3; ++c) {
                        double x = (double)lem_clamp01(f->rgba[4 * i + c]) - (double)lem_clamp01(truth->rgba[4 * i + c]);
                        se += x * x;
                    }
                printf("%-7s %3dx%-4d %-28s %7.2f %7.2f %6lld %7lld %8.0f %8.0f\n", scenes[sc], w, h, opts[k].name,
                       e.psnr, nm ? 10.0 * log10(3.0 * (double)nm / (se > 0.0 ? se : 1e-30)) : 0.0,
                       f->stats.layered_em.traced_pixels, f->stats.layered_em.direct_rows, f->stats.ms_total,
                       f->stats.ms_build);
                fprintf(md, "| %s | %dx%d | %s | %.2f | %.2f | %lld | %lld | %.0f | %.0f |\n", scenes[sc], w, h,
                        opts[k].name, e.psnr, nm ? 10.0 * log10(3.0 * (double)nm / (se > 0.0 ? se : 1e-30)) : 0.0,
                        f->stats.layered_em.traced_pixels, f->stats.layered_em.direct_rows, f->stats.ms_total,
                        f->stats.ms_build);
                fflush(stdout);
            }
            free(mask);
            refl_frame_destroy(truth);
            refl_frame_destroy(full);
            refl_frame_destroy(f);
            refl_scene_destroy(s);
        }
    fclose(md);
    return ok;
}

/* ---- the lenses' shared outer layer (section 4.3) ---------------------------------------------- */

/* PSNR of f against truth over lens object `object`'s pixels (truth's
   stencil object + 1); every lens where object < 0. */
static double lem_lens_psnr(const refl_frame *f, const refl_frame *truth, int object) {
    double se = 0.0;
    long long i, n = (long long)f->width * f->height, px = 0;
    int c;
    for (i = 0; i < n; ++i) {
        if (!truth->stencil[i] || (object >= 0 && truth->stencil[i] != object + 1)) continue;
        ++px;
        for (c = 0; c < 3; ++c) {
            double d = (double)lem_clamp01(f->rgba[4 * i + c]) - (double)lem_clamp01(truth->rgba[4 * i + c]);
            se += d * d;
        }
    }
    return px && se > 0.0 ? 10.0 * log10(3.0 * (double)px / se) : 99.0;
}

int refl_bench_lem_share(const char *dir, int threads) {
    static const char *const scenes[2] = {"hybrid", "glass"};
    static const int layers[3] = {1, 2, 3};
    static const int shells[2] = {REFL_LEM_SHELL_AUTO, REFL_LEM_SHELL_SPHERE};
    const int w = 160, h = 120;
    FILE *md = lem_open(dir, "lem_share.md");
    int sc, ly, sh, share, ok = 1;
    if (!md) return 0;
    fprintf(md, "| scene | layers | shell | shared | map bytes | maps | PSNR lenses (dB) | per lens (dB) | maps ms |\n"
                "|---|---|---|---|---|---|---|---|---|\n");
    printf("%-7s %6s %-6s %6s %10s %4s %7s  %s\n", "scene", "layers", "shell", "shared", "map bytes", "maps", "lenses",
           "per lens");
    for (sc = 0; sc < 2 && ok; ++sc) {
        refl_scene *s = refl_bench_builtin(scenes[sc], 0);
        refl_frame *truth = NULL, *f = NULL;
        refl_render_desc d;
        refl_view v;
        ok = s && refl_frame_create(w, h, NULL, &truth) == REFL_OK && refl_frame_create(w, h, NULL, &f) == REFL_OK &&
             lem_camera_truth(s, w, h, threads, &v, truth);
        for (ly = 0; ly < 3 && ok; ++ly)
            for (sh = 0; sh < 2 && ok; ++sh)
                for (share = 0; share < 2 && ok; ++share) {
                    char per[256] = "";
                    size_t used = 0;
                    int i;
                    d = lem_desc(threads, 1);
                    d.method = REFL_LAYERED_EM;
                    d.layered_em.layers = layers[ly];
                    d.layered_em.shell = shells[sh];
                    d.layered_em.share_outer_layer = share ? 1 : -1;
                    ok = refl_render(s, &v, &d, f) == REFL_OK && lem_measure(f, truth).nonfinite == 0;
                    for (i = 0; ok && i < s->object_count; ++i)
                        if (s->materials[s->objects[i].material].type == REFL_GLASS ||
                            s->materials[s->objects[i].material].type == REFL_MIRROR)
                            used += (size_t)snprintf(per + used, sizeof per - used, "%s%s %.2f", used ? ", " : "",
                                                     s->objects[i].name, lem_lens_psnr(f, truth, i));
                    if (!ok) break;
                    printf("%-7s %6d %-6s %6s %10lld %4d %7.2f  %s\n", scenes[sc], layers[ly], sh ? "sphere" : "auto",
                           share ? "yes" : "no", f->stats.model_bytes, f->stats.layered_em.maps_held,
                           lem_lens_psnr(f, truth, -1), per);
                    fprintf(md, "| %s | %d | %s | %s | %lld | %d | %.2f | %s | %.0f |\n", scenes[sc], layers[ly],
                            sh ? "sphere" : "auto", share ? "yes" : "no", f->stats.model_bytes,
                            f->stats.layered_em.maps_held, lem_lens_psnr(f, truth, -1), per, f->stats.ms_build);
                    fflush(stdout);
                }
        refl_frame_destroy(truth);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
    fclose(md);
    return ok;
}

/* ---- section 6's triangle tests through a uniform grid ------------------------------------ */

/* lem-grid: the section 6 table's rays and triangle tests (default layers,
   t = 3 and 5) with a uniform grid (bench/grid_peer.h) as the ray caster
   beside refl_bvh: greedy RAYTRACE through a grid of the whole scene, and
   LAYERED_EM's frame with its vertices traced through a grid of the lens
   objects alone (refl_lens_tessellate with the grid, the frame's view and
   options: the paper's "ray tracing only through the lens object's
   geometry") and its lens pixels left to the tracer through the scene's
   grid (desc.raytrace.caster). Per grid resolution (PBRT's heuristic,
   per_side 3, and a sweep around it, or PBRT's alone), and at the
   resolution calibrated on the paper's own ray tracer: the per_side (one
   rule for both grids) at which greedy RAYTRACE's tests a ray through the
   scene's grid are the paper's 27.35, LAYERED_EM's side then predicted;
   with the full ray tree's extra cost. Checked first: each grid's hits are
   refl_bvh's on random rays; the grid's RAYTRACE frame is the BVH's, byte
   for byte; the grid's tessellation has the frame's vertices and rays. */

enum { LG_SWEEP = 5, LG_DEFAULT = 2, LG_DENSITIES = LG_SWEEP + 1 };
static const float lg_sweep[LG_SWEEP] = {0.75f, 1.5f, 3.0f, 6.0f, 12.0f};
/* The paper's ray tracer's cost a ray (section 6: 168,313,768 triangle
   tests in 6,153,735 rays, greedy paths, uniformly sampled): the calibrated
   grid's resolution is the one at which greedy RAYTRACE's tests a ray
   through the scene's grid come within LG_FIT_TOLERANCE of it. */
#define LG_PAPER_TESTS_PER_RAY (168313768.0 / 6153735.0)
#define LG_FIT_TOLERANCE 0.01

/* The caster a renderer keeps in its desc: the current grid, or with none
   refl_bvh (counted in the frame's stats as the library's own traces). */
typedef struct lg_switch {
    refl_grid *grid;
    const refl_bvh *bvh;
} lg_switch;

static int lg_intersect(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax, refl_hit *hit) {
    const lg_switch *sw = (const lg_switch *)user;
    return sw->grid ? refl_grid_intersect(sw->grid, o, d, tmin, tmax, hit) : refl_bvh_intersect(sw->bvh, o, d, tmin, tmax, hit);
}

static int lg_occluded(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    const lg_switch *sw = (const lg_switch *)user;
    return sw->grid ? refl_grid_occluded(sw->grid, o, d, tmin, tmax) : refl_bvh_occluded(sw->bvh, o, d, tmin, tmax);
}

/* One LAYERED_EM frame's counts: rays and triangle tests, those of its
   vertices and of its traced lens pixels. */
typedef struct lg_lem {
    long long rays, tests, vertex_rays, vertex_tests, traced_rays, traced_tests, vertices, traced_pixels;
    int matches;             /* grid: the tessellation's vertices and rays are the frame's */
} lg_lem;

/* Per accelerator (-1 refl_bvh, else a density): greedy RAYTRACE and both t. */
typedef struct lg_row {
    int cells[2][3];         /* the scene's grid, the lenses' */
    long long refs[2];
    long long rt_rays, rt_tests;
    double rt_ms;
    int rt_same;             /* the frame's bytes are refl_bvh's */
    lg_lem lem[2];
} lg_row;

static long long lg_tests(refl_grid *g) {
    long long t;
    refl_grid_counts(g, NULL, &t);
    return t;
}

static long long lg_rays(refl_grid *g) {
    long long r;
    refl_grid_counts(g, &r, NULL);
    return r;
}

/* The lens objects' tessellations for the frame's (subsampled) view through
   the lenses' grid: vertices, rays and the grid's tests into e. */
static int lg_tessellate(const refl_scene *s, refl_grid *lenses, const refl_view *fine, float t, int threads, lg_lem *e) {
    refl_ray_caster c = refl_grid_caster(lenses);
    refl_lens_tess_desc td;
    long long t0 = lg_tests(lenses);
    int i;
    memset(&td, 0, sizeof td);
    td.edge_px = t;
    td.max_interfaces = LEM_DEPTH; /* as the method: its depth */
    td.threads = threads;
    e->vertices = e->vertex_rays = 0;
    for (i = 0; i < s->object_count; ++i) {
        refl_lens_tess *tess = NULL;
        if (s->materials[s->objects[i].material].type == REFL_DIFFUSE) continue;
        if (refl_lens_tessellate(s, &c, i, fine, &td, &tess) != REFL_OK) return 0;
        e->vertices += tess->vertex_count;
        e->vertex_rays += tess->rays;
        refl_lens_tess_destroy(tess);
    }
    e->vertex_tests = lg_tests(lenses) - t0;
    return 1;
}

static const char *lg_within(double ours, double paper) {
    return ours >= paper / 1.5 && ours <= paper * 1.5 ? "within 1.5" : "outside 1.5";
}

/* The calibrated block: per accelerator (refl_bvh, PBRT's grid, the grid
   calibrated to the paper's tests a ray) the tests a ray and both
   reductions beside the paper's with a verdict, and the full ray tree's
   extra cost; dir/lem_grid_calibrated.{csv,md}, echoed. */
static int lg_write_calibrated(const char *dir, int w, int h, const refl_grid_fit *fit, const lg_row *bvh,
                               const lg_row *pbrt, const lg_row *cal, const refl_stats *full_bvh,
                               const refl_stats *full_cal) {
    static const double paper_rays[2] = {6.0, 10.8}, paper_tests[2] = {14.2, 25.7};
    static const double paper_lem_tpr[2] = {11878133.0 / 1023876.0, 6543993.0 / 570481.0};
    const lg_row *rows[3] = {bvh, pbrt, cal};
    const refl_stats *full[2] = {full_bvh, full_cal};
    const long long eye = 9LL * w * h; /* one eye ray a sample, either ray tree */
    FILE *csv, *md;
    int k, i;
    if (!lem_open_pair(dir, "lem_grid_calibrated", &csv, &md)) {
        if (csv) fclose(csv);
        if (md) fclose(md);
        return 0;
    }
    fprintf(csv, "caster,per_side,greedy_tests_per_ray,lem_tests_per_ray_t3,lem_tests_per_ray_t5,ray_reduction_t3,"
                 "ray_reduction_t5,test_reduction_t3,test_reduction_t5,full_tree_rays,full_tree_tests,full_tree_ms\n");
    fprintf(md, "`hybrid`, %dx%d 3x3 subsampled, depth %d, default layers. The calibrated grid's resolution, per_side "
                "%.4f (%dx%dx%d cells for the scene, %dx%dx%d for the lenses: the same rule), is fitted so that greedy "
                "RAYTRACE through the scene's grid tests the paper's %.2f triangles a ray (168,313,768 / 6,153,735; "
                "%.2f, within %g%%, after %d frames); its LAYERED_EM columns are predictions of that one fit.\n\n",
            w, h, LEM_DEPTH, fit->per_side, cal->cells[0][0], cal->cells[0][1], cal->cells[0][2], cal->cells[1][0],
            cal->cells[1][1], cal->cells[1][2], LG_PAPER_TESTS_PER_RAY, fit->cost, 100.0 * LG_FIT_TOLERANCE,
            fit->evaluations);
    fprintf(md, "| accelerator | greedy RT tests a ray | LAYERED_EM tests a ray t = 3 | t = 5 | ray reduction t = 3 "
                "| t = 5 | triangle test reduction t = 3 | t = 5 |\n|---|---|---|---|---|---|---|---|\n");
    fprintf(md, "| paper | %.2f | %.2f | %.2f | ×%.1f | ×%.1f | ×%.1f | ×%.1f |\n", LG_PAPER_TESTS_PER_RAY,
            paper_lem_tpr[0], paper_lem_tpr[1], paper_rays[0], paper_rays[1], paper_tests[0], paper_tests[1]);
    for (k = 0; k < 3; ++k) {
        const lg_row *r = rows[k];
        double tpr[2], rr[2], tr[2];
        for (i = 0; i < 2; ++i) {
            tpr[i] = lem_ratio((double)r->lem[i].tests, (double)r->lem[i].rays);
            rr[i] = lem_ratio((double)r->rt_rays, (double)r->lem[i].rays);
            tr[i] = lem_ratio((double)r->rt_tests, (double)r->lem[i].tests);
        }
        fprintf(md, "| %s | %.2f | %.2f (%s) | %.2f (%s) | ×%.2f (%s) | ×%.2f (%s) | ×%.2f (%s) | ×%.2f (%s) |\n",
                k == 0 ? "refl_bvh" : k == 1 ? "grid, PBRT's resolution (per_side 3)" : "grid, calibrated (per_side fitted)",
                lem_ratio((double)r->rt_tests, (double)r->rt_rays), tpr[0], lg_within(tpr[0], paper_lem_tpr[0]), tpr[1],
                lg_within(tpr[1], paper_lem_tpr[1]), rr[0], lg_within(rr[0], paper_rays[0]), rr[1],
                lg_within(rr[1], paper_rays[1]), tr[0], lg_within(tr[0], paper_tests[0]), tr[1],
                lg_within(tr[1], paper_tests[1]));
        fprintf(csv, "%s,%g,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,", k == 0 ? "bvh" : k == 1 ? "grid-pbrt" : "grid-calibrated",
                k == 0 ? 0.0 : k == 1 ? 3.0 : (double)fit->per_side, lem_ratio((double)r->rt_tests, (double)r->rt_rays),
                tpr[0], tpr[1], rr[0], rr[1], tr[0], tr[1]);
        if (k == 1)
            fprintf(csv, ",,\n");
        else
            fprintf(csv, "%lld,%lld,%.1f\n", full[k / 2]->rays, full[k / 2]->triangle_tests, full[k / 2]->ms_total);
    }
    fprintf(md, "\nThe full ray tree (RAYTRACE's default, depth %d) against greedy RAYTRACE of the same frame, the "
                "paper's \"additional factor of 5\" (section 6, the ray tracer's cost; Figure 2: \"5 times more ray "
                "queries\"; within 1.5 of ×5 or not):\n\n| accelerator | rays | rays past the %lld eye rays | triangle tests | time |\n"
                "|---|---|---|---|---|\n", LEM_DEPTH, eye);
    for (k = 0; k < 2; ++k) {
        const lg_row *r = rows[2 * k];
        const refl_stats *f = full[k];
        double xr = lem_ratio((double)f->rays, (double)r->rt_rays), xl = lem_ratio((double)(f->rays - eye), (double)(r->rt_rays - eye));
        double xt = lem_ratio((double)f->triangle_tests, (double)r->rt_tests), xm = lem_ratio(f->ms_total, r->rt_ms);
        fprintf(md, "| %s | ×%.2f (%lld against %lld; %s) | ×%.2f (%s) | ×%.2f (%lld against %lld; %s) | ×%.2f (%s) |\n",
                k ? "grid, calibrated" : "refl_bvh", xr, f->rays, r->rt_rays, lg_within(xr, 5.0), xl, lg_within(xl, 5.0),
                xt, f->triangle_tests, r->rt_tests, lg_within(xt, 5.0), xm, lg_within(xm, 5.0));
    }
    fclose(csv);
    fclose(md);
    fputs("\n", stdout);
    lem_echo(dir, "lem_grid_calibrated");
    return 1;
}

/* The calibration's cost: greedy RAYTRACE of the frame through a grid of
   the whole scene at per_side (PBRT's cap lifted, as the sweep), its
   triangle tests a ray. */
typedef struct lg_fit_frame {
    const refl_scene *s;
    const refl_view *v;
    refl_frame *f;
    int threads;
} lg_fit_frame;

static double lg_fit_cost(void *user, float per_side) {
    const lg_fit_frame *ff = (const lg_fit_frame *)user;
    refl_render_desc d = lem_desc(ff->threads, 9);
    refl_grid_desc gd;
    refl_grid *g;
    long long rays, tests;
    int ok;
    memset(&gd, 0, sizeof gd);
    gd.per_side = per_side;
    gd.max_side = 1024;
    g = refl_grid_create(ff->s, &gd);
    if (!g) return -1.0;
    d.method = REFL_RAYTRACE;
    d.raytrace.greedy = 1;
    d.raytrace.caster = refl_grid_caster(g);
    ok = refl_render(ff->s, ff->v, &d, ff->f) == REFL_OK;
    refl_grid_counts(g, &rays, &tests);
    refl_grid_destroy(g);
    if (!ok || rays <= 0) return -1.0;
    printf("calibration: per_side %.4f, greedy RAYTRACE %.2f tests a ray (target %.2f)\n", per_side,
           (double)tests / (double)rays, LG_PAPER_TESTS_PER_RAY);
    fflush(stdout);
    return (double)tests / (double)rays;
}

int refl_bench_lem_grid(const char *dir, int threads, int quick, int sweep) {
    static const float ts[2] = {3.0f, 5.0f};
    static const double paper_rays[2] = {6.0, 10.8}, paper_tests[2] = {14.2, 25.7};
    const int w = quick ? 160 : 640, h = quick ? 120 : 480, check_rays = quick ? 50000 : 200000;
    refl_scene *s = refl_bench_builtin("hybrid", 0);
    refl_grid *grid[LG_DENSITIES][2];
    float per_side[LG_DENSITIES];
    refl_grid_fit fit;
    lg_fit_frame ff;
    refl_stats full_bvh, full_fit;
    refl_bvh *bvh = NULL;
    refl_frame *truth = NULL, *f = NULL;
    refl_renderer *rr = NULL;
    unsigned char lens[256];
    lg_row bvh_row, rows[LG_DENSITIES];
    lg_switch sw;
    refl_view v, fine;
    char first[512];
    FILE *csv = NULL, *md = NULL;
    int k, i, a, n = 0, pbrt, fitted = 0, ok = 1;
    double t0;
    memset(&fit, 0, sizeof fit);
    memset(&full_bvh, 0, sizeof full_bvh);
    memset(&full_fit, 0, sizeof full_fit);
    memset(grid, 0, sizeof grid);
    memset(&bvh_row, 0, sizeof bvh_row);
    memset(rows, 0, sizeof rows);
    if (!s || s->object_count > 256 || refl_frame_create(w, h, NULL, &truth) != REFL_OK ||
        refl_frame_create(w, h, NULL, &f) != REFL_OK || refl_bvh_build(s, NULL, &bvh) != REFL_OK) {
        fprintf(stderr, "reflect bench: the hybrid scene could not be set up\n");
        ok = 0;
        goto done;
    }
    v = lem_camera(s, w, h);
    fine = v; /* the method's view: spp 9 renders 3 times wider and higher */
    fine.width = 3 * w;
    fine.height = 3 * h;
    for (i = 0; i < s->object_count; ++i) lens[i] = s->materials[s->objects[i].material].type != REFL_DIFFUSE;
    printf("hybrid (paper 001 section 6), %dx%d 3x3 subsampled, depth %d, %s threads: triangle tests through "
           "uniform grids beside refl_bvh\n", w, h, LEM_DEPTH, threads ? "given" : "all");
    /* the resolutions: the sweep (or PBRT's alone), then the calibrated one */
    if (sweep)
        for (k = 0; k < LG_SWEEP; ++k) per_side[n++] = lg_sweep[k];
    else
        per_side[n++] = lg_sweep[LG_DEFAULT];
    pbrt = sweep ? LG_DEFAULT : 0;
    ff.s = s;
    ff.v = &v;
    ff.f = f;
    ff.threads = threads;
    if (!refl_grid_fit_per_side(lg_fit_cost, &ff, LG_PAPER_TESTS_PER_RAY, LG_FIT_TOLERANCE, lg_sweep[LG_DEFAULT],
                                4.0f * lg_sweep[LG_DEFAULT], 0, &fit)) {
        fprintf(stderr, "reflect bench: the grid's resolution did not converge on the paper's %.2f tests a ray "
                        "(within %g%%): per_side %.4f gave %.2f after %d frames\n", LG_PAPER_TESTS_PER_RAY,
                100.0 * LG_FIT_TOLERANCE, fit.per_side, fit.cost, fit.evaluations);
        ok = 0;
        goto done;
    }
    printf("calibrated: per_side %.4f, %.2f tests a ray (the paper's %.2f), %d frames\n", fit.per_side, fit.cost,
           LG_PAPER_TESTS_PER_RAY, fit.evaluations);
    fitted = n;
    per_side[n++] = fit.per_side;
    /* the grids, each checked against refl_bvh first */
    for (k = 0; k < n && ok; ++k)
        for (a = 0; a < 2 && ok; ++a) {
            refl_grid_desc gd;
            long long bad;
            memset(&gd, 0, sizeof gd);
            gd.per_side = per_side[k];
            gd.max_side = k == pbrt ? 0 : 1024; /* PBRT's cap of 64 a side at its own density, lifted for the others */
            gd.objects = a ? lens : NULL;
            grid[k][a] = refl_grid_create(s, &gd);
            if (!grid[k][a]) {
                fprintf(stderr, "reflect bench: grid %g could not be built\n", per_side[k]);
                ok = 0;
                break;
            }
            refl_grid_shape(grid[k][a], rows[k].cells[a], NULL, &rows[k].refs[a]);
            bad = refl_grid_agreement(grid[k][a], s, bvh, check_rays, 2001u + (unsigned)k, first, sizeof first);
            printf("grid %-5g %s: %dx%dx%d cells, %lld references; %d random rays: %lld differ from refl_bvh\n",
                   per_side[k], a ? "lenses" : "scene ", rows[k].cells[a][0], rows[k].cells[a][1],
                   rows[k].cells[a][2], rows[k].refs[a], check_rays, bad);
            if (bad) {
                fprintf(stderr, "reflect bench: the grid's hits are not refl_bvh's: %s\n", first);
                ok = 0;
            }
        }
    fflush(stdout);
    /* greedy RAYTRACE: refl_bvh, then each grid */
    {
        refl_render_desc d = lem_desc(threads, 9);
        d.method = REFL_RAYTRACE;
        d.raytrace.greedy = 1;
        ok = ok && refl_render(s, &v, &d, truth) == REFL_OK;
        bvh_row.rt_rays = truth->stats.rays;
        bvh_row.rt_tests = truth->stats.triangle_tests;
        bvh_row.rt_ms = truth->stats.ms_total;
        bvh_row.rt_same = 1;
        printf("greedy RAYTRACE, refl_bvh: %lld rays, %lld tests (%.1f a ray), %.0f ms\n", bvh_row.rt_rays,
               bvh_row.rt_tests, lem_ratio((double)bvh_row.rt_tests, (double)bvh_row.rt_rays), bvh_row.rt_ms);
        for (k = 0; k < n && ok; ++k) {
            long long r0 = lg_rays(grid[k][0]), t1 = lg_tests(grid[k][0]);
            d.raytrace.caster = refl_grid_caster(grid[k][0]);
            ok = refl_render(s, &v, &d, f) == REFL_OK;
            rows[k].rt_rays = lg_rays(grid[k][0]) - r0;
            rows[k].rt_tests = lg_tests(grid[k][0]) - t1;
            rows[k].rt_ms = f->stats.ms_total;
            rows[k].rt_same = !memcmp(f->rgba, truth->rgba, (size_t)w * h * 4 * sizeof(float));
            printf("greedy RAYTRACE, grid %g: %lld rays (the frame's %lld), %lld tests (%.1f a ray), %.0f ms, %s\n",
                   per_side[k], rows[k].rt_rays, f->stats.rays, rows[k].rt_tests,
                   lem_ratio((double)rows[k].rt_tests, (double)rows[k].rt_rays), rows[k].rt_ms,
                   rows[k].rt_same ? "the same bytes" : "OTHER BYTES");
            ok = ok && rows[k].rt_rays == f->stats.rays;
            fflush(stdout);
        }
        /* the full ray tree's extra cost (the paper's factor of 5), through
           refl_bvh and through the calibrated grid */
        d.raytrace.greedy = 0;
        d.raytrace.caster.intersect = NULL;
        d.raytrace.caster.occluded = NULL;
        d.raytrace.caster.user = NULL;
        ok = ok && refl_render(s, &v, &d, f) == REFL_OK;
        full_bvh = f->stats;
        if (ok) {
            long long r0 = lg_rays(grid[fitted][0]), t1 = lg_tests(grid[fitted][0]);
            d.raytrace.caster = refl_grid_caster(grid[fitted][0]);
            ok = refl_render(s, &v, &d, f) == REFL_OK;
            full_fit = f->stats;
            full_fit.rays = lg_rays(grid[fitted][0]) - r0;
            full_fit.triangle_tests = lg_tests(grid[fitted][0]) - t1;
        }
        if (ok)
            printf("full ray tree RAYTRACE: refl_bvh %lld rays, %lld tests, %.0f ms; calibrated grid %lld rays, %lld "
                   "tests, %.0f ms\n", full_bvh.rays, full_bvh.triangle_tests, full_bvh.ms_total, full_fit.rays,
               full_fit.triangle_tests, full_fit.ms_total);
        fflush(stdout);
    }
    /* LAYERED_EM (default layers), per t: one renderer, its maps kept;
       frames with its traced lens pixels through refl_bvh, then each grid */
    sw.bvh = bvh;
    for (i = 0; i < 2 && ok; ++i) {
        refl_render_desc d = lem_desc(threads, 9);
        d.method = REFL_LAYERED_EM;
        d.layered_em.edge_px = ts[i];
        d.raytrace.caster.intersect = lg_intersect;
        d.raytrace.caster.occluded = lg_occluded;
        d.raytrace.caster.user = &sw;
        sw.grid = NULL;
        fprintf(stderr, "reflect bench: LAYERED_EM t %.0f, its maps ...\n", ts[i]);
        t0 = refl_bench_now_ms();
        ok = refl_renderer_create(s, &d, &rr) == REFL_OK && refl_renderer_render(rr, &v, f) == REFL_OK;
        ok = ok && refl_renderer_render(rr, &v, f) == REFL_OK;
        if (!ok) break;
        {
            lg_lem *e = &bvh_row.lem[i];
            e->rays = f->stats.rays;
            e->tests = f->stats.triangle_tests;
            e->vertex_tests = f->stats.layered_em.vertex_tests;
            e->traced_tests = e->tests - e->vertex_tests;
            e->vertices = f->stats.layered_em.vertices;
            e->traced_pixels = f->stats.layered_em.traced_pixels;
            e->matches = 1;
            printf("LAYERED_EM t %.0f, refl_bvh: %lld rays, %lld tests (%.1f a ray), of which the vertices' %lld; "
                   "%lld vertices, %lld lens pixels traced (%.0f s with the maps)\n",
                   ts[i], e->rays, e->tests, lem_ratio((double)e->tests, (double)e->rays), e->vertex_tests, e->vertices,
                   e->traced_pixels, (refl_bench_now_ms() - t0) / 1000.0);
        }
        for (k = 0; k < n && ok; ++k) {
            lg_lem *e = &rows[k].lem[i];
            long long r0 = lg_rays(grid[k][0]), t1 = lg_tests(grid[k][0]);
            sw.grid = grid[k][0];
            ok = refl_renderer_render(rr, &v, f) == REFL_OK;
            e->traced_rays = lg_rays(grid[k][0]) - r0;
            e->traced_tests = lg_tests(grid[k][0]) - t1;
            e->traced_pixels = f->stats.layered_em.traced_pixels;
            ok = ok && lg_tessellate(s, grid[k][1], &fine, ts[i], threads, e);
            if (!ok) break;
            e->rays = e->vertex_rays + e->traced_rays;
            e->tests = e->vertex_tests + e->traced_tests;
            /* the frame's vertex paths go through its split casters (the
               lenses' BVH, the rest asked for anything before a lens hit)
               and its visibility rays through the whole scene: the lenses'
               grid alone must trace the same mesh */
            e->matches = e->vertices == f->stats.layered_em.vertices && e->rays == f->stats.rays &&
                         f->stats.triangle_tests == f->stats.layered_em.vertex_tests;
            printf("LAYERED_EM t %.0f, grid %g: %lld rays, %lld tests (%.1f a ray): vertices %lld rays %lld tests (%.1f "
                   "a ray), traced pixels %lld rays %lld tests; %lld vertices; the frame's mesh and rays: %s\n",
                   ts[i], per_side[k], e->rays, e->tests, lem_ratio((double)e->tests, (double)e->rays), e->vertex_rays,
                   e->vertex_tests, lem_ratio((double)e->vertex_tests, (double)e->vertex_rays), e->traced_rays,
                   e->traced_tests, e->vertices, e->matches ? "the same" : "DIFFERENT");
            fflush(stdout);
        }
        refl_renderer_destroy(rr);
        rr = NULL;
    }
    if (!ok) goto done;

    if (!lem_open_pair(dir, sweep ? "lem_grid" : "lem_grid_calib", &csv, &md)) {
        ok = 0;
        goto done;
    }
    fprintf(csv, "caster,per_side,scene_cells,lens_cells,t_subpx,width,height,greedy_rays,greedy_tests,greedy_ms,"
                 "greedy_same_bytes,lem_rays,lem_tests,vertex_rays,vertex_tests,traced_rays,traced_tests,vertices,"
                 "same_mesh,ray_reduction,test_reduction\n");
    for (k = -1; k < n; ++k) {
        const lg_row *r = k < 0 ? &bvh_row : &rows[k];
        for (i = 0; i < 2; ++i) {
            const lg_lem *e = &r->lem[i];
            fprintf(csv, "%s,%g,%dx%dx%d,%dx%dx%d,%.0f,%d,%d,%lld,%lld,%.1f,%d,%lld,%lld,%lld,%lld,%lld,%lld,%lld,%d,%.3f,%.3f\n",
                    k < 0 ? "bvh" : k == fitted ? "grid-calibrated" : "grid", k < 0 ? 0.0 : (double)per_side[k], r->cells[0][0], r->cells[0][1],
                    r->cells[0][2], r->cells[1][0], r->cells[1][1], r->cells[1][2], ts[i], w, h, r->rt_rays, r->rt_tests,
                    r->rt_ms, r->rt_same, e->rays, e->tests, k < 0 ? 0 : e->vertex_rays, e->vertex_tests,
                    k < 0 ? 0 : e->traced_rays, e->traced_tests, e->vertices, e->matches,
                    lem_ratio((double)r->rt_rays, (double)e->rays), lem_ratio((double)r->rt_tests, (double)e->tests));
        }
    }
    /* the table at PBRT's density beside refl_bvh and the paper */
    {
        const lg_row *g = &rows[pbrt], *b = &bvh_row;
        fprintf(md, "`hybrid`, %dx%d 3x3 subsampled (t in subpixels), depth %d, default layers. refl_bvh: the "
                    "section 6 table's own counts; grid: greedy RAYTRACE through a uniform grid of the whole scene, "
                    "LAYERED_EM's vertices through a grid of the lens objects alone and its traced lens pixels "
                    "through the scene's grid; grids of PBRT's resolution (3 cube roots of the triangles along the "
                    "longest side: %dx%dx%d cells for the scene, %dx%dx%d for the lenses)\n\n",
                w, h, LEM_DEPTH, g->cells[0][0], g->cells[0][1], g->cells[0][2], g->cells[1][0], g->cells[1][1],
                g->cells[1][2]);
        fprintf(md, "| | paper t = 3 | paper t = 5 | refl_bvh t = 3 | refl_bvh t = 5 | grid t = 3 | grid t = 5 |\n"
                    "|---|---|---|---|---|---|---|\n");
#define LG_ROW(label, p3, p5, fmt, expr)                                                                               \
    do {                                                                                                               \
        const lg_row *rs[2] = {b, g};                                                                                  \
        int q_, j_;                                                                                                    \
        fprintf(md, "| %s | %s | %s |", label, p3, p5);                                                                \
        for (q_ = 0; q_ < 2; ++q_)                                                                                     \
            for (j_ = 0; j_ < 2; ++j_) {                                                                               \
                const lg_row *r = rs[q_];                                                                              \
                const lg_lem *e = &r->lem[j_];                                                                         \
                (void)e;                                                                                               \
                fprintf(md, " " fmt " |", expr);                                                                       \
            }                                                                                                          \
        fprintf(md, "\n");                                                                                             \
    } while (0)
        LG_ROW("greedy ray tracing's rays", "6,153,735", "6,153,735", "%lld", r->rt_rays);
        LG_ROW("LAYERED_EM's rays", "1,023,876", "570,481", "%lld", e->rays);
        LG_ROW("ray reduction", "×6", "×10.8", "×%.2f", lem_ratio((double)r->rt_rays, (double)e->rays));
        LG_ROW("greedy ray tracing's triangle tests", "168,313,768", "168,313,768", "%lld", r->rt_tests);
        LG_ROW("LAYERED_EM's triangle tests", "11,878,133", "6,543,993", "%lld", e->tests);
        LG_ROW("of which tracing the vertices", "", "", "%lld", e->vertex_tests);
        LG_ROW("of which the lens pixels traced", "", "", "%lld", e->traced_tests);
        LG_ROW("triangle test reduction", "×14.2", "×25.7", "×%.2f", lem_ratio((double)r->rt_tests, (double)e->tests));
        LG_ROW("greedy ray tracing's triangle tests per ray", "27.4", "27.4", "%.1f",
               lem_ratio((double)r->rt_tests, (double)r->rt_rays));
        LG_ROW("LAYERED_EM's triangle tests per ray", "11.6", "11.5", "%.1f", lem_ratio((double)e->tests, (double)e->rays));
#undef LG_ROW
        for (i = 0; i < 2; ++i) {
            double tr = lem_ratio((double)g->rt_tests, (double)g->lem[i].tests);
            double rr2 = lem_ratio((double)g->rt_rays, (double)g->lem[i].rays);
            fprintf(md, "\nt = %.0f through the grid: ray reduction ×%.2f against the paper's ×%.1f (%s), triangle "
                        "tests ×%.2f against ×%.1f (%s).", ts[i], rr2, paper_rays[i], lg_within(rr2, paper_rays[i]), tr,
                    paper_tests[i], lg_within(tr, paper_tests[i]));
        }
    }
    /* the sweep over the grids' resolution */
    fprintf(md, "\n\nBy the grids' resolution (per_side: cells along the longest side per cube root of the triangles; "
                "PBRT's is 3, capped at 64 a side; the sweep lifts the cap):\n\n"
                "| per_side | scene cells | lens cells | greedy RT tests a ray | LAYERED_EM vertex tests a ray (t = 3) "
                "| LAYERED_EM tests a ray (t = 3) | test reduction t = 3 (paper ×14.2) | t = 5 (paper ×25.7) "
                "| greedy RT ms | checks |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for (k = 0; k < n; ++k) {
        const lg_row *r = &rows[k];
        double t3 = lem_ratio((double)r->rt_tests, (double)r->lem[0].tests);
        double t5 = lem_ratio((double)r->rt_tests, (double)r->lem[1].tests);
        fprintf(md, "| %g%s | %dx%dx%d | %dx%dx%d | %.1f | %.1f | %.1f | ×%.2f (%s) | ×%.2f (%s) | %.0f | %s |\n",
                per_side[k], k == pbrt ? " (PBRT)" : k == fitted ? " (calibrated)" : "", r->cells[0][0], r->cells[0][1], r->cells[0][2],
                r->cells[1][0], r->cells[1][1], r->cells[1][2], lem_ratio((double)r->rt_tests, (double)r->rt_rays),
                lem_ratio((double)r->lem[0].vertex_tests, (double)r->lem[0].vertex_rays),
                lem_ratio((double)r->lem[0].tests, (double)r->lem[0].rays), t3, lg_within(t3, paper_tests[0]), t5,
                lg_within(t5, paper_tests[1]), r->rt_ms,
                r->rt_same && r->lem[0].matches && r->lem[1].matches ? "same bytes, same mesh and rays"
                : !r->rt_same                                        ? "OTHER BYTES"
                                                                     : "OTHER MESH OR RAYS");
    }
    fprintf(md, "| refl_bvh | | | %.1f | | %.1f | ×%.2f | ×%.2f | %.0f | |\n",
            lem_ratio((double)bvh_row.rt_tests, (double)bvh_row.rt_rays),
            lem_ratio((double)bvh_row.lem[0].tests, (double)bvh_row.lem[0].rays),
            lem_ratio((double)bvh_row.rt_tests, (double)bvh_row.lem[0].tests),
            lem_ratio((double)bvh_row.rt_tests, (double)bvh_row.lem[1].tests), bvh_row.rt_ms);
    fclose(md);
    md = NULL;
    fputs("\n", stdout);
    lem_echo(dir, sweep ? "lem_grid" : "lem_grid_calib");
    ok = lg_write_calibrated(dir, w, h, &fit, &bvh_row, &rows[pbrt], &rows[fitted], &full_bvh, &full_fit);
done:
    if (csv) fclose(csv);
    if (md) fclose(md);
    refl_renderer_destroy(rr);
    for (k = 0; k < n; ++k) {
        refl_grid_destroy(grid[k][0]);
        refl_grid_destroy(grid[k][1]);
    }
    refl_bvh_destroy(bvh);
    refl_frame_destroy(truth);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    return ok;
}
