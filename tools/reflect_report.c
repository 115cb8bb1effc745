/* reflect bench --report DIR: one static HTML page (DIR/index.html, plain
   HTML with PNG images, no network) that puts the measurements side by
   side for a researcher or a class:
     - per scene, time against reflection error with every method as a
       labelled curve (each point names its setting; exact methods sit at
       the chart's left edge, named "exact"), and PSNR and holes panels;
     - a picture grid (scene x method, RAYTRACE first) and per-pixel error
       heat maps against RAYTRACE;
     - a failure gallery: the worst frames of each method along camera
       paths (`reflect path`, run as a child process), with flicker and
       error per frame;
     - cost growth (time against pixels and reflector triangles) with every
       method, and time broken down by phase.
   Charts come from gnuplot (pngcairo), as the rest of `reflect bench`.
   The page ends with a short inline script that counts the images that
   loaded and writes the count into <body data-check=...>:
   tests/report_test.sh reads it from headless Chromium. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "../bench/embree_peer.h"
#include "image_io.h"
#include "reflect_bench.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- heat maps (also reflect compare --diff) ------------------------------- */

/* Black through blue, red and yellow to white over 0..1: dark where the
   images agree, so the eye goes to where they do not. */
static void heat_color(double t, uint8_t rgb[3]) {
    static const double stops[5][3] = {{0, 0, 0}, {0.1, 0.1, 0.9}, {0.9, 0.1, 0.1}, {1, 0.9, 0}, {1, 1, 1}};
    double x = (t < 0 ? 0 : t > 1 ? 1 : t) * 4.0;
    int k = x >= 4.0 ? 3 : (int)x, c;
    double f = x - k;
    for (c = 0; c < 3; ++c) rgb[c] = (uint8_t)(255.0 * (stops[k][c] + f * (stops[k + 1][c] - stops[k][c])) + 0.5);
}

void refl_heat_map(const uint8_t *a, const uint8_t *b, long long count, int channels, int full_scale,
                   uint8_t *rgb) {
    long long i;
    for (i = 0; i < count; ++i) {
        int c, worst = 0;
        for (c = 0; c < channels; ++c) {
            int d = abs((int)a[4 * i + c] - (int)b[4 * i + c]);
            if (d > worst) worst = d;
        }
        heat_color((double)worst / full_scale, rgb + 3 * i);
    }
}

/* ---- what the report measures ---------------------------------------------- */

enum { REPORT_HEAT_SCALE = 64, REPORT_MAX_SETTINGS = 48, REPORT_MAX_ROWS = 1024, REPORT_MAX_SERIES = 16 };

/* One setting of one method: a point of its curve. */
typedef struct report_setting {
    refl_method method;
    char series[24];              /* the curve: the method's name, or "embree" */
    char label[24];               /* the point's setting, e.g. "128" (cube size) */
    int envmap_size, sbc_ray_factor, embree;
    float density;
    int picture;                  /* the setting shown in the picture grid and heat maps */
} report_setting;

/* One measured setting on one scene and size. */
typedef struct report_row {
    char scene[32], sweep[16];    /* sweep: "base", "pixels" or "reflector" */
    const report_setting *set;
    int width, height;
    long long reflector_tris;
    double ms, ms_build, ms_base, ms_reflect, ms_composite;
    refl_reflection_error rerr;
    double psnr;
    int handed_over, applies;
} report_row;

typedef struct report {
    const char *dir;
    int quick, threads, repeats, width, height;
    report_setting sets[REPORT_MAX_SETTINGS];
    int set_count;
    report_row *rows;
    int row_count;
    refl_embree *embree;          /* for the current scene */
    FILE *html;
    int images;                   /* <img> written, for the page's own check */
    char skipped[4096];           /* settings whose render failed, as HTML list items */
} report;

static void add_setting(report *rp, refl_method m, const char *series, const char *label, int picture) {
    report_setting *s = &rp->sets[rp->set_count++];
    memset(s, 0, sizeof *s);
    s->method = m;
    snprintf(s->series, sizeof s->series, "%s", series);
    snprintf(s->label, sizeof s->label, "%s", label);
    s->picture = picture;
}

/* Every built method but DIRECT (it reflects nothing) and RAYTRACE (the
   truth, yet also a point: exact, and its time), over its settings. */
static void report_settings(report *rp) {
    static const int envmap_quick[] = {32, 128}, envmap_full[] = {16, 32, 64, 128, 256};
    static const float c3rc_quick[] = {30.0f, 60.0f}, c3rc_full[] = {250.0f, 1000.0f, 0.0f};
    static const int sbc_factors[] = {4, 2};
    refl_method m;
    int k, n;
    char label[24];
    add_setting(rp, REFL_RAYTRACE, "raytrace", "exact", 1);
    add_setting(rp, REFL_RAYTRACE, "embree", "exact", 0);
    rp->sets[rp->set_count - 1].embree = 1;
    for (m = REFL_ENVMAP; m < REFL_METHOD_COUNT; m = (refl_method)(m + 1)) {
        const char *name = refl_method_name(m);
        if (!refl_method_is_built(m)) continue;
        if (m == REFL_ENVMAP) {
            n = rp->quick ? 2 : 5;
            for (k = 0; k < n; ++k) {
                int size = rp->quick ? envmap_quick[k] : envmap_full[k];
                snprintf(label, sizeof label, "%d", size);
                add_setting(rp, m, name, label, size == 128);
                rp->sets[rp->set_count - 1].envmap_size = size;
            }
        } else if (m == REFL_C3RC) {
            n = rp->quick ? 2 : 3;
            for (k = 0; k < n; ++k) {
                float d = rp->quick ? c3rc_quick[k] : c3rc_full[k];
                if (d > 0.0f) snprintf(label, sizeof label, "%g/u2", d);
                else snprintf(label, sizeof label, "auto");
                add_setting(rp, m, name, label, k == n - 1);
                rp->sets[rp->set_count - 1].density = d;
            }
        } else if (m == REFL_SBC) {
            for (k = 0; k < 2; ++k) {
                snprintf(label, sizeof label, "1/%d rays", sbc_factors[k] * sbc_factors[k]);
                add_setting(rp, m, name, label, k == 1);
                rp->sets[rp->set_count - 1].sbc_ray_factor = sbc_factors[k];
            }
        } else {
            add_setting(rp, m, name, "default", 1);
        }
    }
}

static long long reflector_triangles(const refl_scene *s) {
    long long n = 0;
    int i;
    for (i = 0; i < s->object_count; ++i)
        if (s->materials[s->objects[i].material].type != REFL_DIFFUSE) n += s->meshes[s->objects[i].mesh]->triangle_count;
    return n;
}

/* Writes a frame's colour as an 8-bit PNG DIR/NAME; into rgba8 when given. */
static int write_frame_png(const report *rp, const char *name, const refl_frame *f, uint8_t *rgba8) {
    char path[1024], err[256];
    size_t n = (size_t)f->width * (size_t)f->height;
    uint8_t *px = rgba8 ? rgba8 : (uint8_t *)malloc(n * 4);
    refl_result r;
    if (!px) return 0;
    refl_frame_to_srgb8(f, NULL, px);
    snprintf(path, sizeof path, "%s/%s", rp->dir, name);
    r = refl_image_write(path, f->width, f->height, 4, px, NULL, err, sizeof err);
    if (r != REFL_OK) fprintf(stderr, "reflect bench: %s\n", err);
    if (!rgba8) free(px);
    return r == REFL_OK;
}

static int write_heat_png(const report *rp, const char *name, const uint8_t *test, const uint8_t *truth, int w, int h) {
    char path[1024], err[256];
    uint8_t *rgb = (uint8_t *)malloc((size_t)w * (size_t)h * 3);
    refl_result r;
    if (!rgb) return 0;
    refl_heat_map(test, truth, (long long)w * h, 3, REPORT_HEAT_SCALE, rgb);
    snprintf(path, sizeof path, "%s/%s", rp->dir, name);
    r = refl_image_write(path, w, h, 3, rgb, NULL, err, sizeof err);
    if (r != REFL_OK) fprintf(stderr, "reflect bench: %s\n", err);
    free(rgb);
    return r == REFL_OK;
}

/* Renders one setting, timed, and measures it against the truth. */
static int measure(report *rp, const refl_scene *s, const refl_view *v, const report_setting *set,
                   const refl_frame *truth, refl_frame *f, report_row *row) {
    refl_render_desc d;
    refl_image_error ie;
    double ms, fastest;
    refl_result r;
    char err[256];
    memset(&d, 0, sizeof d);
    d.method = set->method;
    d.threads = rp->threads;
    d.depth = 1;
    d.envmap.size = set->envmap_size;
    d.c3rc.point_density = set->density;
    d.sbc.ray_factor = set->sbc_ray_factor;
    if (set->embree) {
        if (!rp->embree) rp->embree = refl_embree_create(s, rp->threads, err, sizeof err);
        if (!rp->embree) {
            fprintf(stderr, "reflect bench: Embree: %s\n", err);
            return 0;
        }
        d.raytrace.caster.intersect = refl_embree_intersect;
        d.raytrace.caster.occluded = refl_embree_occluded;
        d.raytrace.caster.user = rp->embree;
    }
    r = refl_bench_timed_render(s, v, &d, rp->repeats, f, &ms, &fastest);
    if (r != REFL_OK) { /* left out, and said so on the page */
        size_t used = strlen(rp->skipped);
        fprintf(stderr, "reflect bench: report: %s (%s) on %s: %s %s\n", set->series, set->label, row->scene,
                refl_result_string(r), f->message);
        if (r != REFL_ERROR_UNSUPPORTED && used + 200 < sizeof rp->skipped)
            snprintf(rp->skipped + used, sizeof rp->skipped - used, "<li>%s (%s) on %s, %dx%d: %s</li>\n",
                     set->series, set->label, row->scene, v->width, v->height, refl_result_string(r));
        return -1;
    }
    row->set = set;
    row->width = v->width;
    row->height = v->height;
    row->reflector_tris = reflector_triangles(s);
    row->ms = ms;
    row->ms_build = f->stats.ms_build;
    row->ms_base = f->stats.ms_base;
    row->ms_reflect = f->stats.ms_reflect;
    row->ms_composite = f->stats.ms_composite;
    row->handed_over = f->stats.handed_over;
    if (refl_measure_reflection_error(f, truth, NULL, &row->rerr) != REFL_OK ||
        refl_measure_image_error(f, truth, 1, 0.0f, &ie) != REFL_OK)
        return 0;
    row->psnr = ie.psnr;
    row->applies = row->rerr.empty < 0.99 && !(row->rerr.pixels > 0 && row->rerr.matched == 0);
    fprintf(stderr, "  %-9s %-10s %-10s %-9s %4dx%-4d %8.1f ms  %6.2f px  holes %5.3f  PSNR %6.2f dB\n", row->scene,
            row->sweep, set->series, set->label, v->width, v->height, ms, row->rerr.mean, row->rerr.empty, ie.psnr);
    return 1;
}

/* Every setting on one scene and view, with the picture grid's frames and
   heat maps (DIR/img/SCENE-SERIES.png and -heat.png); without pictures
   (the cost-growth sweeps), the picture settings only. */
static int measure_scene(report *rp, const char *scene, const char *sweep, const refl_scene *s, const refl_view *v,
                         int pictures) {
    refl_frame *truth = NULL, *f = NULL;
    refl_render_desc d;
    uint8_t *truth8 = NULL, *test8 = NULL;
    size_t n = (size_t)v->width * (size_t)v->height;
    char name[128];
    int i, ok = 1;
    if (refl_frame_create(v->width, v->height, NULL, &truth) != REFL_OK ||
        refl_frame_create(v->width, v->height, NULL, &f) != REFL_OK || !(truth8 = (uint8_t *)malloc(n * 4)) ||
        !(test8 = (uint8_t *)malloc(n * 4)))
        ok = 0;
    memset(&d, 0, sizeof d);
    d.method = REFL_RAYTRACE;
    d.threads = rp->threads;
    d.depth = 1;
    if (ok && refl_render(s, v, &d, truth) != REFL_OK) ok = 0;
    if (ok) refl_frame_to_srgb8(truth, NULL, truth8);
    for (i = 0; ok && i < rp->set_count; ++i) {
        report_row *row;
        int r;
        if (rp->row_count == REPORT_MAX_ROWS) break;
        row = &rp->rows[rp->row_count];
        memset(row, 0, sizeof *row);
        snprintf(row->scene, sizeof row->scene, "%s", scene);
        snprintf(row->sweep, sizeof row->sweep, "%s", sweep);
        if (!pictures && !rp->sets[i].picture) continue; /* the sweeps: one setting a method */
        r = measure(rp, s, v, &rp->sets[i], truth, f, row);
        if (r < 0) continue;
        if (!r) ok = 0;
        if (!ok) break;
        rp->row_count++;
        if (pictures && rp->sets[i].picture) {
            snprintf(name, sizeof name, "img/%s-%s.png", scene, rp->sets[i].series);
            ok = write_frame_png(rp, name, f, test8);
            snprintf(name, sizeof name, "img/%s-%s-heat.png", scene, rp->sets[i].series);
            if (ok) ok = write_heat_png(rp, name, test8, truth8, v->width, v->height);
        }
    }
    refl_embree_destroy(rp->embree);
    rp->embree = NULL;
    refl_frame_destroy(truth);
    refl_frame_destroy(f);
    free(truth8);
    free(test8);
    if (!ok) fprintf(stderr, "reflect bench: report: %s failed\n", scene);
    return ok;
}

/* ---- charts ----------------------------------------------------------------- */

typedef double (*report_axis)(const report_row *r);
static double axis_ms(const report_row *r) { return r->ms; }
static double axis_error(const report_row *r) { return r->rerr.mean; }
static double axis_psnr(const report_row *r) { return isinf(r->psnr) || r->psnr > 60.0 ? 60.0 : r->psnr; }
static double axis_holes(const report_row *r) { return 100.0 * r->rerr.empty; }
static double axis_pixels(const report_row *r) { return (double)r->width * r->height; }
static double axis_reflector(const report_row *r) { return (double)r->reflector_tris; }

/* One colour per method on every chart, by its place in the method enum;
   Embree last. */
static const char *series_color(const char *series) {
    static const char *const palette[] = {"#999999", "#808000", "#000000", "#1f77b4", "#ff7f0e", "#2ca02c",
                                          "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#7f7f7f"};
    refl_method m = refl_method_from_name(series);
    const int last = (int)(sizeof palette / sizeof palette[0]) - 1;
    return palette[m > 0 && (int)m < last ? (int)m : last];
}

/* The rows of one scene and sweep that reflect something. */
static int take(const report_row *r, const char *scene, const char *sweep) {
    return !strcmp(r->scene, scene) && !strcmp(r->sweep, sweep) && r->applies;
}

/* One line per series ("x y label" rows, a gnuplot block per series) and a
   chart of them, each point labelled with its setting when labels is set.
   exact_x > 0: points with x == 0 drawn at exact_x (a log axis). */
static int series_chart(const report *rp, const char *scene, const char *sweep, const char *name, const char *title,
                        const char *xlabel, const char *ylabel, report_axis x, report_axis y, int logx, int logy,
                        int labels, double exact_x) {
    char path[1024], script[16384], names[REPORT_MAX_SERIES][24], keys[REPORT_MAX_SERIES][56],
        first_label[REPORT_MAX_SERIES][24];
    FILE *fp;
    size_t len;
    int i, j, n = 0, exact_rows = 0;
    for (i = 0; i < rp->row_count; ++i) {
        int seen = -1;
        if (!take(&rp->rows[i], scene, sweep)) continue;
        for (j = 0; j < n; ++j)
            if (!strcmp(names[j], rp->rows[i].set->series)) seen = j;
        if (seen < 0 && n < REPORT_MAX_SERIES) {
            snprintf(names[n], 24, "%s", rp->rows[i].set->series);
            snprintf(first_label[n], 24, "%s", rp->rows[i].set->label);
            /* without point labels, the key names the series' one setting */
            if (labels) snprintf(keys[n], sizeof keys[n], "%s", names[n]);
            else snprintf(keys[n], sizeof keys[n], "%s (%s)", names[n], rp->rows[i].set->label);
            ++n;
        } else if (seen >= 0 && !labels && strcmp(rp->rows[i].set->label, first_label[seen])) {
            snprintf(keys[seen], sizeof keys[seen], "%s (settings vary)", names[seen]);
        }
    }
    if (!n) return 1; /* nothing to draw: the page says so */
    snprintf(path, sizeof path, "%s/%s.dat", rp->dir, name);
    if (!(fp = fopen(path, "w"))) return 0;
    for (j = 0; j < n; ++j) {
        fprintf(fp, "# %s\n", names[j]);
        for (i = 0; i < rp->row_count; ++i) {
            const report_row *r = &rp->rows[i];
            double xv = x(r), yv = y(r), label_y = yv;
            int exact;
            if (!take(r, scene, sweep) || strcmp(names[j], r->set->series)) continue;
            exact = exact_x > 0.0 && xv <= 0.0;
            if (exact) xv = exact_x;
            /* the exact methods' points meet on one line at often the same
               time: their labels (series and setting) climb one by one */
            if (exact && logy) label_y = yv * pow(1.35, exact_rows++);
            fprintf(fp, "%g %g \"%s%s%s\" %g\n", xv, yv, exact ? names[j] : "", exact ? ": " : "", r->set->label,
                    label_y);
        }
        fprintf(fp, "\n\n");
    }
    fclose(fp);
    len = (size_t)snprintf(script, sizeof script,
                           "set terminal pngcairo size 900,560 noenhanced\nset output '%s/%s.png'\n"
                           "set title '%s'\nset xlabel '%s'\nset ylabel '%s'\n%s%s"
                           "set grid\nset key outside right\nset offsets graph 0.05, graph 0.05, graph 0.08, graph 0.08\n",
                           rp->dir, name, title, xlabel, ylabel, logx ? "set logscale x\n" : "",
                           logy ? "set logscale y\n" : "");
    if (!logy) len += (size_t)snprintf(script + len, sizeof script - len, "set yrange [0:*]\n");
    if (exact_x > 0.0)
        len += (size_t)snprintf(script + len, sizeof script - len,
                                "set arrow from %g, graph 0 to %g, graph 1 nohead dashtype 2 lc rgb 'gray50'\n"
                                "set label 'exact (0 px)' at %g, graph 0.97 left offset 0.5,0 textcolor rgb 'gray30'\n",
                                exact_x, exact_x, exact_x);
    len += (size_t)snprintf(script + len, sizeof script - len, "plot ");
    for (j = 0; j < n && len < sizeof script; ++j) {
        len += (size_t)snprintf(script + len, sizeof script - len,
                                "%s'%s' index %d using 1:2 with linespoints pt 7 lw 2 lc rgb '%s' title '%s'", j ? ", " : "",
                                path, j, series_color(names[j]), keys[j]);
        if (labels && len < sizeof script)
            len += (size_t)snprintf(script + len, sizeof script - len,
                                    ", '%s' index %d using 1:4:3 with labels offset 0.6,%g left font ',8' tc rgb '%s' "
                                    "notitle",
                                    /* on a linear axis, points of several series often share a value
                                       (no holes, identical PSNR): their labels staggered */
                                    path, j, 0.6 + (logy ? 0.0 : 0.9 * (j % 4)), series_color(names[j]));
    }
    if (len >= sizeof script - 2) return 0;
    strcat(script, "\n");
    snprintf(path, sizeof path, "%s/%s.gp", rp->dir, name);
    return refl_bench_gnuplot(path, script);
}

/* Time per phase (stats.ms_*) of each method's picture setting on one
   scene, stacked; "other" is what the phases do not cover. */
static int phase_chart(const report *rp, const char *scene, const char *name) {
    char path[1024], script[4096];
    FILE *fp;
    int i, rows = 0;
    snprintf(path, sizeof path, "%s/%s.dat", rp->dir, name);
    if (!(fp = fopen(path, "w"))) return 0;
    fprintf(fp, "# method build base reflect composite other (ms)\n");
    for (i = 0; i < rp->row_count; ++i) {
        const report_row *r = &rp->rows[i];
        double other = r->ms - r->ms_build - r->ms_base - r->ms_reflect - r->ms_composite;
        if (strcmp(r->scene, scene) || strcmp(r->sweep, "base") || !r->set->picture) continue;
        fprintf(fp, "\"%s (%s)\" %g %g %g %g %g\n", r->set->series, r->set->label, r->ms_build, r->ms_base, r->ms_reflect,
                r->ms_composite, other > 0 ? other : 0);
        ++rows;
    }
    fclose(fp);
    if (!rows) return 1;
    snprintf(script, sizeof script,
             "set terminal pngcairo size 900,520 noenhanced\nset output '%s/%s.png'\n"
             "set title '%s scene, %dx%d: where each method spends its frame (the setting in the picture grid)'\n"
             "set xlabel 'method (setting)'\nset ylabel 'ms per frame (median frame of %d)'\nset grid ytics\n"
             "set style data histograms\nset style histogram rowstacked\nset style fill solid 0.8 border -1\n"
             "set boxwidth 0.7\nset key outside right\nset xtics rotate by -30\n"
             "plot '%s' using 2:xtic(1) title 'build (models)', '' using 3 title 'base pass', "
             "'' using 4 title 'reflect', '' using 5 title 'composite', '' using 6 title 'other'\n",
             rp->dir, name, scene, rp->width, rp->height, rp->repeats, path);
    snprintf(path, sizeof path, "%s/%s.gp", rp->dir, name);
    return refl_bench_gnuplot(path, script);
}

/* ---- the stability sweeps ---------------------------------------------------- */

typedef struct path_frame_row {
    char method[24];
    int frame, pop;
    double ms, mean_px, flicker;
} path_frame_row;

/* Runs `reflect path` (this binary) on one scene and path with --images
   into DIR/NAME/, then reads back its CSV. */
static int run_path(const report *rp, const char *scene, const char *path, const char *sub, int frames, int w, int h,
                    path_frame_row **out, int *count) {
    char self[1024], cmd[3072], file[1200], line[512];
    ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
    FILE *fp;
    int cap = 0, pop_col = -1;
    *out = NULL;
    *count = 0;
    if (len <= 0) return 0;
    self[len] = '\0';
    snprintf(cmd, sizeof cmd, "'%s' path --builtin %s --path %s --frames %d --size %dx%d --threads %d --out '%s/%s' "
                              "--images > '%s/%s/summary.txt' 2>&1",
             self, scene, path, frames, w, h, rp->threads, rp->dir, sub, rp->dir, sub);
    snprintf(file, sizeof file, "%s/%s", rp->dir, sub);
    mkdir(file, 0777);
    if (system(cmd) != 0) {
        fprintf(stderr, "reflect bench: report: reflect path failed: %s\n", cmd);
        return 0;
    }
    snprintf(file, sizeof file, "%s/%s/%s.csv", rp->dir, sub, path);
    if (!(fp = fopen(file, "r"))) return 0;
    while (fgets(line, sizeof line, fp)) {
        char *field[16], *save = NULL, *tok;
        int nf = 0;
        path_frame_row *r;
        for (tok = strtok_r(line, ",\n", &save); tok && nf < 16; tok = strtok_r(NULL, ",\n", &save)) field[nf++] = tok;
        if (nf < 11) continue;
        if (!strcmp(field[0], "path")) { /* the header: find the pop column, if any */
            int k;
            for (k = 0; k < nf; ++k)
                if (!strcmp(field[k], "pop")) pop_col = k;
            continue;
        }
        if (*count == cap) {
            path_frame_row *grown = (path_frame_row *)realloc(*out, (size_t)(cap = cap ? 2 * cap : 64) * sizeof **out);
            if (!grown) break;
            *out = grown;
        }
        r = &(*out)[(*count)++];
        memset(r, 0, sizeof *r);
        snprintf(r->method, sizeof r->method, "%s", field[1]);
        r->frame = atoi(field[2]);
        r->ms = atof(field[3]);
        r->mean_px = atof(field[4]);
        r->flicker = atof(field[9]);
        r->pop = pop_col >= 0 && pop_col < nf ? atoi(field[pop_col]) : 0;
    }
    fclose(fp);
    return *count > 0;
}

/* A per-frame chart of one path: flicker of every method, pops marked. */
static int path_chart(const report *rp, const char *sub, const char *title, const path_frame_row *rows, int count) {
    char path[1024], script[8192], names[REPORT_MAX_SERIES][24];
    FILE *fp;
    size_t len;
    int i, j, n = 0;
    for (i = 0; i < count; ++i) {
        int seen = 0;
        for (j = 0; j < n; ++j) seen |= !strcmp(names[j], rows[i].method);
        if (!seen && n < REPORT_MAX_SERIES) snprintf(names[n++], 24, "%s", rows[i].method);
    }
    snprintf(path, sizeof path, "%s/%s/flicker.dat", rp->dir, sub);
    if (!(fp = fopen(path, "w"))) return 0;
    for (j = 0; j < n; ++j) {
        fprintf(fp, "# %s: frame flicker pop\n", names[j]);
        for (i = 0; i < count; ++i)
            if (!strcmp(rows[i].method, names[j]) && rows[i].frame > 0)
                fprintf(fp, "%d %g %d\n", rows[i].frame, rows[i].flicker, rows[i].pop);
        fprintf(fp, "\n\n");
    }
    fclose(fp);
    len = (size_t)snprintf(script, sizeof script,
                           "set terminal pngcairo size 900,560 noenhanced\nset output '%s/%s/flicker.png'\n"
                           "set title '%s'\nset xlabel 'frame'\n"
                           "set ylabel 'flicker: mean excess over the truth (8-bit levels)'\n"
                           "set grid\nset key outside right\nset xtics %d\nplot ",
                           rp->dir, sub, title, count > 10 * n ? 5 : 1);
    for (j = 0; j < n && len < sizeof script; ++j)
        len += (size_t)snprintf(script + len, sizeof script - len,
                                "%s'%s' index %d using 1:2 with linespoints pt 7 ps 0.6 lc rgb '%s' title '%s (default)', "
                                "'%s' index %d using 1:($3 > 0 ? $2 : 1/0) with points pt 6 ps 2.5 lc rgb '%s' notitle",
                                j ? ", " : "", path, j, series_color(names[j]), names[j], path, j,
                                series_color(names[j]));
    if (len >= sizeof script - 2) return 0;
    strcat(script, "\n");
    snprintf(path, sizeof path, "%s/%s/flicker.gp", rp->dir, sub);
    return refl_bench_gnuplot(path, script);
}

/* ---- the page --------------------------------------------------------------- */

static void img(report *rp, const char *src, const char *alt, int width) {
    if (width > 0) fprintf(rp->html, "<img src=\"%s\" alt=\"%s\" width=\"%d\">", src, alt, width);
    else fprintf(rp->html, "<img src=\"%s\" alt=\"%s\">", src, alt);
    rp->images++;
}

static int file_exists(const report *rp, const char *name) {
    char path[1200];
    struct stat st;
    snprintf(path, sizeof path, "%s/%s", rp->dir, name);
    return stat(path, &st) == 0;
}

/* A chart when gnuplot drew it; a line saying why not otherwise. */
static void chart_or_note(report *rp, const char *name, const char *alt) {
    char src[256];
    snprintf(src, sizeof src, "%s.png", name);
    if (file_exists(rp, src)) {
        fprintf(rp->html, "<figure>");
        img(rp, src, alt, 0);
        fprintf(rp->html, "</figure>\n");
    } else {
        fprintf(rp->html, "<p class=note>%s: no method reflected anything here.</p>\n", alt);
    }
}

static void page_head(report *rp, const char *const *scenes) {
    int i;
    fprintf(rp->html,
            "<!DOCTYPE html>\n<html lang=en>\n<head>\n<meta charset=utf-8>\n<title>reflect.h: methods against "
            "the truth</title>\n<style>\nbody{font-family:sans-serif;max-width:1200px;margin:1em auto;padding:0 1em;"
            "color:#222}\ntable{border-collapse:collapse;margin:0.5em 0}\ntd,th{border:1px solid #ccc;padding:2px "
            "6px;font-size:13px;text-align:right}\nth{background:#eee}\ntd.l,th.l{text-align:left}\n"
            ".grid td{text-align:center;vertical-align:top}\n.grid img{image-rendering:pixelated;display:block}\n"
            "figure{margin:0.5em 0}\n.note{color:#666;font-style:italic}\nimg{max-width:100%%}\n</style>\n"
            /* counted from the start: an image may fail before the page's end is parsed */
            "<script>\nvar errors = 0;\nwindow.addEventListener('error', function () { errors++; }, true);\n</script>\n"
            "</head>\n"
            "<body>\n<h1>reflect.h: every method against the ray-traced truth</h1>\n");
    fprintf(rp->html,
            "<p>Written by <code>reflect bench --report%s</code>: frames of %dx%d, one reflection bounce, each "
            "time the median of %d frame%s on %s. Error is measured against RAYTRACE of the same scene, view and "
            "size (docs/metrics.md in the repository): the <b>reflection "
            "error</b> is how far, in pixels, each reflected point lands from where the truth shows it; "
            "<b>holes</b> are reflector pixels where the truth shows a point and the method none; <b>PSNR</b> is "
            "over the reflector pixels. Scenes:",
            rp->quick ? " --quick" : "", rp->width, rp->height, rp->repeats, rp->repeats > 1 ? "s" : "",
            rp->threads ? "the given threads" : "every CPU");
    for (i = 0; scenes[i]; ++i) fprintf(rp->html, " <a href=\"#scene-%s\">%s</a>", scenes[i], scenes[i]);
    fprintf(rp->html, ". Below them: the <a href=\"#pictures\">picture grid</a>, <a href=\"#heat\">error heat "
                      "maps</a>, <a href=\"#stability\">stability and failures</a>, <a href=\"#growth\">cost "
                      "growth</a> and <a href=\"#phases\">time by phase</a>.</p>\n");
}

static void scene_section(report *rp, const char *scene) {
    char name[128], alt[256];
    int i;
    fprintf(rp->html, "<h2 id=\"scene-%s\">%s</h2>\n", scene, scene);
    snprintf(name, sizeof name, "time_vs_error_%s", scene);
    snprintf(alt, sizeof alt, "%s: time against reflection error", scene);
    chart_or_note(rp, name, alt);
    snprintf(name, sizeof name, "psnr_%s", scene);
    snprintf(alt, sizeof alt, "%s: PSNR against time", scene);
    chart_or_note(rp, name, alt);
    snprintf(name, sizeof name, "holes_%s", scene);
    snprintf(alt, sizeof alt, "%s: holes against time", scene);
    chart_or_note(rp, name, alt);
    fprintf(rp->html, "<table>\n<tr><th class=l>method</th><th class=l>setting</th><th>ms</th><th>mean px</th>"
                      "<th>p95 px</th><th>wrong</th><th>holes</th><th>PSNR dB</th><th>handed to the tracer</th></tr>\n");
    for (i = 0; i < rp->row_count; ++i) {
        const report_row *r = &rp->rows[i];
        if (strcmp(r->scene, scene) || strcmp(r->sweep, "base")) continue;
        fprintf(rp->html, "<tr><td class=l>%s</td><td class=l>%s</td><td>%.1f</td>", r->set->series, r->set->label,
                r->ms);
        if (r->applies)
            fprintf(rp->html, "<td>%.3f</td><td>%.2f</td><td>%.2f%%</td><td>%.2f%%</td>", r->rerr.mean, r->rerr.p95,
                    100.0 * r->rerr.wrong, 100.0 * r->rerr.empty);
        else
            fprintf(rp->html, "<td colspan=4 class=l>reflects nothing here</td>");
        if (isinf(r->psnr)) fprintf(rp->html, "<td>identical</td>");
        else fprintf(rp->html, "<td>%.2f</td>", r->psnr);
        fprintf(rp->html, "<td>%d</td></tr>\n", r->handed_over);
    }
    fprintf(rp->html, "</table>\n");
}

/* The picture grid (heat = 0) or the heat maps (heat = 1): scene x series. */
static void grid_section(report *rp, const char *const *scenes, int heat) {
    int i, j;
    fprintf(rp->html, "<table class=grid>\n<tr><th class=l>scene</th>");
    for (j = 0; j < rp->set_count; ++j)
        if (rp->sets[j].picture && (!heat || j > 0)) fprintf(rp->html, "<th>%s</th>", rp->sets[j].series);
    fprintf(rp->html, "</tr>\n");
    for (i = 0; scenes[i]; ++i) {
        fprintf(rp->html, "<tr><th class=l>%s</th>", scenes[i]);
        for (j = 0; j < rp->set_count; ++j) {
            const report_setting *s = &rp->sets[j];
            char src[256], alt[256];
            if (!s->picture || (heat && j == 0)) continue;
            snprintf(src, sizeof src, "img/%s-%s%s.png", scenes[i], s->series, heat ? "-heat" : "");
            snprintf(alt, sizeof alt, "%s, %s (%s)%s", scenes[i], s->series, s->label, heat ? ", error heat map" : "");
            fprintf(rp->html, "<td>");
            if (file_exists(rp, src)) {
                img(rp, src, alt, rp->width < 200 ? 2 * rp->width : rp->width);
                fprintf(rp->html, "%s", s->label);
            } else {
                fprintf(rp->html, "&mdash;");
            }
            fprintf(rp->html, "</td>");
        }
        fprintf(rp->html, "</tr>\n");
    }
    fprintf(rp->html, "</table>\n");
}

/* The legend of the heat maps: the colour ramp as an image. */
static int heat_legend(const report *rp) {
    enum { W = 256, H = 14 };
    uint8_t rgb[W * H * 3];
    char path[1024], err[256];
    int x, y;
    for (x = 0; x < W; ++x)
        for (y = 0; y < H; ++y) heat_color((double)x / (W - 1), rgb + 3 * (y * W + x));
    snprintf(path, sizeof path, "%s/img/heat-legend.png", rp->dir);
    return refl_image_write(path, W, H, 3, rgb, NULL, err, sizeof err) == REFL_OK;
}

typedef struct report_path {
    const char *scene, *path, *sub;
} report_path;

/* One path's chart and its failure gallery: per method the frame that
   flickers most (beside the frame before it and the truth) and the frame
   with the largest reflection error. */
static int stability_section(report *rp, const report_path *p, int frames, int w, int h) {
    path_frame_row *rows = NULL;
    char title[256], src[256], alt[256];
    int count = 0, i, j, ok;
    ok = run_path(rp, p->scene, p->path, p->sub, frames, w, h, &rows, &count);
    snprintf(title, sizeof title, "%s scene, %s path, %dx%d, %d frames: flicker per frame (circles: pops)", p->scene,
             p->path, w, h, frames);
    if (ok) ok = path_chart(rp, p->sub, title, rows, count);
    fprintf(rp->html, "<h3>%s, %s path</h3>\n", p->scene, p->path);
    if (!ok) {
        fprintf(rp->html, "<p class=note>reflect path failed here.</p>\n");
        free(rows);
        return 0;
    }
    fprintf(rp->html, "<p>Command: <code>reflect path --builtin %s --path %s --frames %d --size %dx%d --images</code>; "
                      "per-frame numbers in <a href=\"%s/%s.csv\">%s.csv</a>.</p>\n<figure>",
            p->scene, p->path, frames, w, h, p->sub, p->path, p->path);
    snprintf(src, sizeof src, "%s/flicker.png", p->sub);
    img(rp, src, title, 0);
    fprintf(rp->html, "</figure>\n<table class=grid>\n<tr><th class=l>method</th><th>frame before</th>"
                      "<th>worst flicker</th><th>truth</th><th>largest error</th><th>truth</th></tr>\n");
    for (i = 0; i < count; ++i) {
        int worst_f = -1, worst_e = -1, first = 1;
        for (j = 0; j < i; ++j) first &= strcmp(rows[j].method, rows[i].method) != 0;
        if (!first) continue;
        for (j = 0; j < count; ++j) {
            if (strcmp(rows[j].method, rows[i].method)) continue;
            if (rows[j].frame > 0 && (worst_f < 0 || rows[j].flicker > rows[worst_f].flicker)) worst_f = j;
            if (worst_e < 0 || rows[j].mean_px > rows[worst_e].mean_px) worst_e = j;
        }
        fprintf(rp->html, "<tr><th class=l>%s</th>", rows[i].method);
        if (worst_f >= 0) {
            const path_frame_row *r = &rows[worst_f];
            const char *who[3] = {r->method, r->method, "raytrace"};
            int k, frame[3] = {r->frame - 1, r->frame, r->frame};
            for (k = 0; k < 3; ++k) {
                snprintf(src, sizeof src, "%s/%s-%04d.png", p->sub, who[k], frame[k]);
                snprintf(alt, sizeof alt, "%s, frame %d", who[k], frame[k]);
                fprintf(rp->html, "<td>");
                img(rp, src, alt, 2 * w);
                if (k == 1) fprintf(rp->html, "frame %d: %.2f levels%s", r->frame, r->flicker, r->pop ? " (pop)" : "");
                else fprintf(rp->html, "frame %d", frame[k]);
                fprintf(rp->html, "</td>");
            }
        } else {
            fprintf(rp->html, "<td colspan=3>&mdash;</td>");
        }
        {
            const path_frame_row *r = &rows[worst_e];
            const char *who[2] = {r->method, "raytrace"};
            int k;
            for (k = 0; k < 2; ++k) {
                snprintf(src, sizeof src, "%s/%s-%04d.png", p->sub, who[k], r->frame);
                snprintf(alt, sizeof alt, "%s, frame %d", who[k], r->frame);
                fprintf(rp->html, "<td>");
                img(rp, src, alt, 2 * w);
                if (k == 0) fprintf(rp->html, "frame %d: %.2f px", r->frame, r->mean_px);
                else fprintf(rp->html, "frame %d", r->frame);
                fprintf(rp->html, "</td>");
            }
        }
        fprintf(rp->html, "</tr>\n");
    }
    fprintf(rp->html, "</table>\n");
    free(rows);
    return 1;
}

/* The page's own check, for a reader and for tests/report_test.sh: after
   load, <body data-check="images=N broken=B errors=E">. */
static void page_tail(report *rp) {
    fprintf(rp->html,
            "<p id=check class=note>Images on this page: %d.</p>\n"
            "<script>\nwindow.addEventListener('load', function () {\n  var imgs = document.images, broken = 0, i;\n"
            "  for (i = 0; i < imgs.length; i++) if (!imgs[i].complete || imgs[i].naturalWidth === 0) broken++;\n"
            "  document.body.setAttribute('data-check', 'images=' + imgs.length + ' broken=' + broken + ' errors=' + "
            "errors);\n  document.getElementById('check').textContent = 'Images on this page: ' + imgs.length + ', "
            "' + broken + ' failed to load.';\n});\n</script>\n</body>\n</html>\n",
            rp->images);
}

int refl_bench_report(const char *dir, int threads, int repeats, int quick) {
    static const char *const quick_scenes[] = {"default", "concave", NULL};
    static const report_path quick_paths[] = {{"default", "orbit", "path-default-orbit"}};
    static const report_path full_paths[] = {{"default", "orbit", "path-default-orbit"},
                                             {"concave", "focus", "path-concave-focus"},
                                             {"concave", "rim", "path-concave-rim"},
                                             {"glass", "orbit", "path-glass-orbit"}};
    static const int quick_sizes[][2] = {{32, 24}, {64, 48}}, full_sizes[][2] = {{160, 120}, {320, 240}, {640, 480}};
    static const int quick_tess[] = {4, 8}, full_tess[] = {4, 8, 16, 32};
    const char *const *scenes = quick ? quick_scenes : refl_builtin_names();
    report rp;
    char path[1200];
    int i, ok = 1, path_count;
    const report_path *paths;
    memset(&rp, 0, sizeof rp);
    rp.dir = dir;
    rp.quick = quick;
    rp.threads = threads;
    rp.repeats = quick ? 1 : repeats;
    rp.width = quick ? 64 : 320;
    rp.height = quick ? 48 : 240;
    report_settings(&rp);
    snprintf(path, sizeof path, "%s/img", dir);
    if ((mkdir(dir, 0777) != 0 && errno != EEXIST) || (mkdir(path, 0777) != 0 && errno != EEXIST)) {
        fprintf(stderr, "reflect bench: cannot create %s: %s\n", path, strerror(errno));
        return 0;
    }
    if (!(rp.rows = (report_row *)calloc(REPORT_MAX_ROWS, sizeof *rp.rows))) return 0;
    /* per scene at the report's size, with pictures */
    for (i = 0; ok && scenes[i]; ++i) {
        refl_scene *s = refl_bench_builtin(scenes[i], 0);
        refl_view v;
        if (!s) { ok = 0; break; }
        v = s->camera;
        v.width = rp.width;
        v.height = rp.height;
        ok = measure_scene(&rp, scenes[i], "base", s, &v, 1);
        refl_scene_destroy(s);
    }
    /* cost growth on the default scene: pixels, then reflector triangles */
    for (i = 0; ok && i < (quick ? 2 : 3); ++i) {
        refl_scene *s = refl_bench_builtin("default", 0);
        refl_view v;
        if (!s) { ok = 0; break; }
        v = s->camera;
        v.width = quick ? quick_sizes[i][0] : full_sizes[i][0];
        v.height = quick ? quick_sizes[i][1] : full_sizes[i][1];
        ok = measure_scene(&rp, "default", "pixels", s, &v, 0);
        refl_scene_destroy(s);
    }
    for (i = 0; ok && i < (quick ? 2 : 4); ++i) {
        refl_scene *s = refl_bench_builtin("default", quick ? quick_tess[i] : full_tess[i]);
        refl_view v;
        if (!s) { ok = 0; break; }
        v = s->camera;
        v.width = rp.width;
        v.height = rp.height;
        ok = measure_scene(&rp, "default", "reflector", s, &v, 0);
        refl_scene_destroy(s);
    }
    snprintf(path, sizeof path, "%s/index.html", dir);
    if (ok && !(rp.html = fopen(path, "w"))) {
        fprintf(stderr, "reflect bench: cannot write %s\n", path);
        ok = 0;
    }
    if (ok) ok = heat_legend(&rp);
    if (ok) page_head(&rp, scenes);
    for (i = 0; ok && scenes[i]; ++i) {
        char name[128], title[256];
        double exact_x = 1e9;
        int k;
        for (k = 0; k < rp.row_count; ++k) /* exact points: a third of the least error drawn */
            if (take(&rp.rows[k], scenes[i], "base") && rp.rows[k].rerr.mean > 0.0 && rp.rows[k].rerr.mean < exact_x)
                exact_x = rp.rows[k].rerr.mean;
        exact_x = exact_x < 1e9 ? exact_x / 3.0 : 0.01;
        snprintf(name, sizeof name, "time_vs_error_%s", scenes[i]);
        snprintf(title, sizeof title, "%s scene, %dx%d: time per frame against reflection error (points: settings)",
                 scenes[i], rp.width, rp.height);
        ok = series_chart(&rp, scenes[i], "base", name, title, "mean reflection error (pixels)",
                          "ms per frame (median)", axis_error, axis_ms, 1, 1, 1, exact_x);
        snprintf(name, sizeof name, "psnr_%s", scenes[i]);
        snprintf(title, sizeof title, "%s scene, %dx%d: PSNR over the reflectors (identical: drawn at 60 dB)",
                 scenes[i], rp.width, rp.height);
        if (ok) ok = series_chart(&rp, scenes[i], "base", name, title, "ms per frame (median)", "PSNR (dB)", axis_ms,
                                  axis_psnr, 1, 0, 1, 0.0);
        snprintf(name, sizeof name, "holes_%s", scenes[i]);
        snprintf(title, sizeof title, "%s scene, %dx%d: holes (reflector pixels left empty)", scenes[i], rp.width,
                 rp.height);
        if (ok) ok = series_chart(&rp, scenes[i], "base", name, title, "ms per frame (median)",
                                  "holes (% of reflector pixels)", axis_ms, axis_holes, 1, 0, 1, 0.0);
        if (ok) scene_section(&rp, scenes[i]);
    }
    if (ok) {
        fprintf(rp.html, "<h2 id=pictures>Picture grid</h2>\n<p>Each method at the setting named under its "
                         "picture (the last point of its curve), beside RAYTRACE.</p>\n");
        grid_section(&rp, scenes, 0);
        fprintf(rp.html, "<h2 id=heat>Error heat maps</h2>\n<p>Per pixel, the largest R, G or B difference from "
                         "RAYTRACE in 8-bit levels: ");
        img(&rp, "img/heat-legend.png", "heat map colour ramp", 256);
        fprintf(rp.html, " 0 (black) to %d or more (white).</p>\n", REPORT_HEAT_SCALE);
        grid_section(&rp, scenes, 1);
        fprintf(rp.html, "<h2 id=stability>Stability along camera paths, and the failure gallery</h2>\n<p>Each "
                         "method rendered along a path through one renderer kept across frames, against RAYTRACE "
                         "(<code>reflect path</code>, docs/stability.md). Flicker is how much more a method's "
                         "reflector pixels change from one frame to the next than the truth's do. The gallery shows, "
                         "per method, the frame that flickers most beside the one before it and the truth, and the "
                         "frame with the largest reflection error.</p>\n");
    }
    paths = quick ? quick_paths : full_paths;
    path_count = quick ? (int)(sizeof quick_paths / sizeof quick_paths[0])
                       : (int)(sizeof full_paths / sizeof full_paths[0]);
    for (i = 0; ok && i < path_count; ++i) ok = stability_section(&rp, &paths[i], quick ? 6 : 30, quick ? 48 : 160,
                                                                  quick ? 36 : 120);
    if (ok) {
        char title[256];
        fprintf(rp.html, "<h2 id=growth>Cost growth</h2>\n");
        snprintf(title, sizeof title, "default scene: time per frame against pixels (every method, its picture "
                                      "settings and the others)");
        ok = series_chart(&rp, "default", "pixels", "growth_pixels", title, "pixels per frame",
                          "ms per frame (median)", axis_pixels, axis_ms, 1, 1, 0, 0.0);
        snprintf(title, sizeof title, "default scene, %dx%d: time per frame against reflector triangles (teapot "
                                      "tessellation)", rp.width, rp.height);
        if (ok) ok = series_chart(&rp, "default", "reflector", "growth_reflector", title, "reflector triangles",
                                  "ms per frame (median)", axis_reflector, axis_ms, 1, 1, 0, 0.0);
        if (ok) {
            chart_or_note(&rp, "growth_pixels", "time against pixels");
            chart_or_note(&rp, "growth_reflector", "time against reflector triangles");
        }
    }
    if (ok) {
        fprintf(rp.html, "<h2 id=phases>Time by phase</h2>\n<p>From each frame's <code>refl_stats</code>: models "
                         "built, the base pass, the reflection pass and compositing; other is the rest of the "
                         "frame.</p>\n");
        for (i = 0; ok && scenes[i]; ++i) {
            char name[128], alt[128];
            snprintf(name, sizeof name, "phases_%s", scenes[i]);
            snprintf(alt, sizeof alt, "%s: time by phase", scenes[i]);
            ok = phase_chart(&rp, scenes[i], name);
            if (ok) chart_or_note(&rp, name, alt);
        }
    }
    if (ok && rp.skipped[0]) fprintf(rp.html, "<h2>Not measured</h2>\n<ul>\n%s</ul>\n", rp.skipped);
    if (ok) page_tail(&rp);
    if (rp.html && fclose(rp.html) != 0) ok = 0;
    if (ok) fprintf(stderr, "wrote %s (%d images)\n", path, rp.images);
    free(rp.rows);
    return ok;
}
