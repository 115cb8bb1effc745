/* `reflect bench`: every method x scene x parameter setting, timed (median
   of several runs) and measured against the ray-traced reference of the
   same scene, view and size; a CSV, and gnuplot charts of time against
   reflection error (one curve per method) and of cost growth (time against
   resolution, diffuse triangles and reflector triangles). Embree, plugged
   into RAYTRACE as its ray caster, is a row in every table: what a CPU user
   would pick instead. DESIGN.md section 6. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "../bench/embree_peer.h"
#include "cli_options.h"
#include "reflect_bench.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static const char *const usage_bench =
    "usage: reflect bench [--full] [--only c3rc|sbc|path|graphcam|spoc|spoc-sweeps|lem|lem-sweeps|lem-options|lem-share|lem-grid|lem-grid-calib] [--out DIR] [--repeats N] [--threads N] [--depth N]\n"
    "       reflect bench --report DIR [--quick] [--repeats N] [--threads N]\n"
    "\n"
    "Renders every method on the built-in scenes over their parameter settings\n"
    "(ENVMAP: cube sizes, C3RC: densities, SBC: ray map factors), times each\n"
    "setting (the median of N runs), measures its reflection error in pixels\n"
    "and its image error against RAYTRACE of the same scene, view and size,\n"
    "and writes DIR/bench.csv and the charts\n"
    "DIR/time_vs_error_SCENE.png, DIR/growth_{resolution,diffuse,reflector,depth}.png\n"
    "and DIR/refraction_incidence.png (PLANAR's slab against the incidence angle),\n"
    "and C3RC's tables (DIR/c3rc_tables.csv, paper 000's Tables 1 and 2) and\n"
    "DIR/c3rc_triangle_size.png (its cameras' error against triangle size)\n"
    "(gnuplot), and SBC's (DIR/sbc_fig19.csv, paper 003's Fig. 19: reflected\n"
    "rays, coverage, SBC size and construction time at quarter and half\n"
    "resolution ray maps, and the projection rate of pinhole and ray-list\n"
    "leaves; also printed), and SBC's speed against RAYTRACE (our BVH and\n"
    "Embree) at 640x480, 1920x1080 and 3840x2160 with its error and where its\n"
    "time goes (DIR/sbc_resolution.csv; printed with the crossover), and a\n"
    "camera path of 30 frames on the default scene rendered per frame by\n"
    "refl_render and by one renderer kept along the path (DIR/path.csv), and\n"
    "paper 004's maze through its graph camera: construction and frame time\n"
    "of both intersection algorithms against RAYTRACE (DIR/graphcam_maze.csv),\n"
    "and, with --full or --only spoc, its Tables 1 and 2 on the two teapots:\n"
    "SPOC frame times along a 60-frame path at four output and four impostor\n"
    "sizes (DIR/spoc_teapots.csv), and SPOC's stability sweeps on them (orbit,\n"
    "touching teapots, impostor size, thin glass; DIR/spoc_sweeps.csv).\n"
    "With --full or --only lem, paper 001's section 6 table on the hybrid\n"
    "scene (LAYERED_EM's phases, rays and triangle tests at 640x480 3x3\n"
    "subsampled, t = 3 and 5, against greedy RAYTRACE; DIR/lem_table.{csv,md}),\n"
    "and with --only lem-sweeps LAYERED_EM's stability sweeps at 160x120\n"
    "(DIR/lem_sweeps.{csv,md,png}), with --only lem-options its options beyond\n"
    "the defaults on hybrid and glass (DIR/lem_options.md), with --only lem-share\n"
    "the lenses' shared outer layer against their own (DIR/lem_share.md), with --only lem-grid\n"
    "the table's rays and triangle tests with a uniform grid as the ray caster\n"
    "beside our BVH, per grid resolution, and with the grid's resolution\n"
    "fitted to the paper's triangle tests a ray (DIR/lem_grid.{csv,md},\n"
    "DIR/lem_grid_calibrated.{csv,md}); --only lem-grid-calib: the same without\n"
    "the sweep, PBRT's resolution and the fitted one (DIR/lem_grid_calib.{csv,md},\n"
    "DIR/lem_grid_calibrated.{csv,md}).\n"
    "RAYTRACE through Embree is a row in every table.\n"
    "\n"
    "  --full        every built-in scene, 5 runs each (default: the default\n"
    "                scene, 3 runs); sizes 320x240 to 1920x1080 either way;\n"
    "                SBC's resolution sweep runs 3840x2160 once unless --full\n"
    "  --only NAME   only c3rc's tables, sbc's (Fig. 19 and the resolution\n"
    "                sweep), the camera path (path), the maze (graphcam) or\n"
    "                the teapots' SPOC tables (spoc) or SPOC's stability\n"
    "                sweeps (spoc-sweeps), or LAYERED_EM's section 6 table\n"
    "                (lem), its stability sweeps (lem-sweeps), its options\n"
    "                (lem-options), its shared outer layer (lem-share) or\n"
    "                its triangle tests through uniform grids (lem-grid;\n"
    "                lem-grid-calib: without the sweep)\n"
    "  --out DIR     where to write (default out/bench)\n"
    "  --repeats N   runs per setting (median kept)\n"
    "  --threads N   worker threads (default: one per CPU)\n"
    "  --depth N     reflection bounces, the same for every method (default 1:\n"
    "                what single-bounce methods such as ENVMAP model)\n"
    "  --report DIR  instead: a static HTML page DIR/index.html (charts of time\n"
    "                against error, PSNR and holes per scene, a picture grid, error\n"
    "                heat maps, the worst frames along camera paths, cost growth and\n"
    "                time by phase; 320x240, every built-in scene)\n"
    "  --quick       with --report: two scenes at 64x48, few settings, one run each;\n"
    "                with --only lem, lem-grid or lem-grid-calib: 160x120\n"
    "                instead of 640x480;\n"
    "                with --only lem-options: 160x120 alone\n";

typedef struct bench_opts {
    int full, repeats, threads, depth;
    char out[512];
    char only[16];                /* "c3rc", "sbc", "path", "graphcam", "spoc" or "spoc-sweeps": just those
                                     tables; "": everything */
    const char *report;           /* --report DIR: the HTML page instead (tools/reflect_report.c) */
    int quick;                    /* --quick: the report's small version */
} bench_opts;

/* One measured setting: a CSV row and a chart point. */
typedef struct bench_row {
    char scene[32], method[24], series[24];
    char param[24];               /* the sweep: base, resolution, diffuse, reflector */
    double value;                 /* the method's setting (ENVMAP: cube size) */
    int width, height, threads, depth;
    int applies;                  /* the method reflects something here (not all holes) */
    long long diffuse_tris, reflector_tris;
    double ms_median, ms_min;
    refl_reflection_error rerr;
    refl_image_error ierr;
    long long rays, model_bytes;
} bench_row;

typedef struct bench_table {
    bench_row *rows;
    int count, capacity;
} bench_table;

static bench_row *bench_add(bench_table *t) {
    if (t->count == t->capacity) {
        int cap = t->capacity ? 2 * t->capacity : 64;
        bench_row *r = (bench_row *)realloc(t->rows, (size_t)cap * sizeof(bench_row));
        if (!r) return NULL;
        t->rows = r;
        t->capacity = cap;
    }
    memset(&t->rows[t->count], 0, sizeof(bench_row));
    return &t->rows[t->count++];
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

double refl_bench_median(double *v, int n) {
    qsort(v, (size_t)n, sizeof v[0], cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double refl_bench_now_ms(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

/* Diffuse and reflector triangles of a scene. */
static void count_triangles(const refl_scene *s, long long *diffuse, long long *reflector) {
    int i;
    *diffuse = *reflector = 0;
    for (i = 0; i < s->object_count; ++i) {
        long long n = s->meshes[s->objects[i].mesh]->triangle_count;
        if (s->materials[s->objects[i].material].type == REFL_DIFFUSE) *diffuse += n;
        else *reflector += n;
    }
}

refl_result refl_bench_timed_render(const refl_scene *s, const refl_view *v, const refl_render_desc *d, int repeats,
                                    refl_frame *f, double *median, double *fastest) {
    double t[32];
    int k, n = repeats < 1 ? 1 : repeats > 32 ? 32 : repeats;
    for (k = 0; k < n; ++k) {
        refl_result r = refl_render(s, v, d, f);
        if (r != REFL_OK) return r;
        t[k] = f->stats.ms_total;
    }
    *median = refl_bench_median(t, n);
    *fastest = t[0];
    return REFL_OK;
}

/* The methods of one row set: name, series (the chart's curve), render
   settings. ENVMAP runs once per cube size. At most BENCH_METHODS_MAX. */
#define BENCH_METHODS_MAX 32
typedef struct bench_method {
    const char *method, *series, *param;
    refl_method m;
    int envmap_size, embree;
    float density;                /* C3RC: points per unit area (0: automatic) */
    int sbc_ray_factor;           /* SBC: one reflected ray per factor x factor pixels */
    int sbc_trace_fallback;       /* SBC: refl_render_desc.sbc.trace_fallback */
} bench_method;

/* Renders RAYTRACE's truth of `depth` bounces into *truth, unless it holds
   that depth already (*truth_depth). */
static int bench_truth(const refl_scene *s, const refl_view *view, int threads, int depth, refl_frame *truth,
                       int *truth_depth) {
    refl_render_desc d;
    if (*truth_depth == depth) return 1;
    memset(&d, 0, sizeof d);
    d.method = REFL_RAYTRACE;
    d.threads = threads;
    d.depth = depth;
    *truth_depth = refl_render(s, view, &d, truth) == REFL_OK ? depth : -1;
    return *truth_depth == depth;
}

/* Runs every method on one scene and view against its RAYTRACE reference
   of the depth the method models (its own row too: error 0 by definition,
   and its time); appends rows. */
static int bench_scene(bench_table *table, const bench_opts *o, const char *scene_name, const refl_scene *s,
                       const refl_view *view, const bench_method *methods, int method_count) {
    refl_frame *truth = NULL, *f = NULL;
    refl_render_desc d;
    refl_embree *embree = NULL;
    char err[256];
    double ms, fastest;
    long long diffuse, reflector;
    int i, ok = 1, truth_depth = -1;
    count_triangles(s, &diffuse, &reflector);
    if (refl_frame_create(view->width, view->height, NULL, &truth) != REFL_OK ||
        refl_frame_create(view->width, view->height, NULL, &f) != REFL_OK) {
        fprintf(stderr, "reflect bench: out of memory\n");
        refl_frame_destroy(truth);
        return 0;
    }
    for (i = 0; ok && i < method_count; ++i) {
        const bench_method *bm = &methods[i];
        bench_row *row;
        refl_result r;
        memset(&d, 0, sizeof d);
        d.method = bm->m;
        d.threads = o->threads;
        d.depth = o->depth;
        d.envmap.size = bm->envmap_size;
        d.c3rc.point_density = bm->density;
        d.sbc.ray_factor = bm->sbc_ray_factor;
        d.sbc.trace_fallback = bm->sbc_trace_fallback;
        if (bm->embree) {
            if (!embree) embree = refl_embree_create(s, o->threads, err, sizeof err);
            if (!embree) {
                fprintf(stderr, "reflect bench: Embree: %s\n", err);
                ok = 0;
                break;
            }
            d.raytrace.caster.intersect = refl_embree_intersect;
            d.raytrace.caster.occluded = refl_embree_occluded;
            d.raytrace.caster.user = embree;
        }
        r = refl_bench_timed_render(s, view, &d, o->repeats, f, &ms, &fastest);
        if (r == REFL_ERROR_UNSUPPORTED) continue; /* a method not built yet */
        if (r != REFL_OK) {
            fprintf(stderr, "reflect bench: %s on %s: %s\n", bm->method, scene_name, refl_result_string(r));
            ok = 0;
            break;
        }
        row = bench_add(table);
        if (!row) { ok = 0; break; }
        snprintf(row->scene, sizeof row->scene, "%s", scene_name);
        snprintf(row->method, sizeof row->method, "%s", bm->method);
        snprintf(row->series, sizeof row->series, "%s", bm->series);
        snprintf(row->param, sizeof row->param, "%s", bm->param);
        row->value = bm->m == REFL_C3RC ? bm->density : bm->m == REFL_SBC ? bm->sbc_ray_factor : bm->envmap_size;
        row->width = view->width;
        row->height = view->height;
        row->threads = o->threads;
        row->depth = f->stats.depth; /* a one-bounce method against one-bounce truth */
        if (!bench_truth(s, view, o->threads, row->depth > 1 ? row->depth : 1, truth, &truth_depth)) {
            fprintf(stderr, "reflect bench: RAYTRACE of depth %d on %s failed\n", row->depth, scene_name);
            ok = 0;
            break;
        }
        row->diffuse_tris = diffuse;
        row->reflector_tris = reflector;
        row->ms_median = ms;
        row->ms_min = fastest;
        row->rays = f->stats.rays;
        row->model_bytes = f->stats.model_bytes;
        if (refl_measure_reflection_error(f, truth, NULL, &row->rerr) != REFL_OK ||
            refl_measure_image_error(f, truth, 1, 0.0f, &row->ierr) != REFL_OK)
            memset(&row->rerr, 0, sizeof row->rerr);
        /* DIRECT, or PLANAR without planar mirrors, reflects nothing: it
           has no place on the error chart */
        row->applies = row->rerr.empty < 0.99;
        fprintf(stderr, "  %-10s %-12s %-9s %4dx%-4d %7.1f ms  error %6.2f px (p95 %6.2f, wrong %5.3f, empty %5.3f)  "
                        "PSNR %6.2f dB\n",
                scene_name, bm->series, bm->param, view->width, view->height, ms, row->rerr.mean, row->rerr.p95,
                row->rerr.wrong, row->rerr.empty, row->ierr.psnr);
    }
    refl_embree_destroy(embree);
    refl_frame_destroy(truth);
    refl_frame_destroy(f);
    return ok;
}

/* ---- output ---------------------------------------------------------------- */

static int write_csv(const bench_table *t, const char *path) {
    FILE *fp = fopen(path, "w");
    int i;
    if (!fp) return 0;
    fprintf(fp, "scene,method,series,sweep,setting,depth,width,height,threads,diffuse_triangles,reflector_triangles,"
                "ms_median,ms_min,error_mean_px,error_p95_px,error_max_px,wrong,empty,psnr_db,rmse,"
                "over_threshold,rays,model_bytes\n");
    for (i = 0; i < t->count; ++i) {
        const bench_row *r = &t->rows[i];
        fprintf(fp, "%s,%s,%s,%s,%g,%d,%d,%d,%d,%lld,%lld,%.3f,%.3f,%.4f,%.4f,%.4f,%.5f,%.5f,%.3f,%.6f,%.5f,%lld,%lld\n",
                r->scene, r->method, r->series, r->param, r->value, r->depth, r->width, r->height, r->threads,
                r->diffuse_tris, r->reflector_tris, r->ms_median, r->ms_min, r->rerr.mean, r->rerr.p95,
                r->rerr.max, r->rerr.wrong, r->rerr.empty, isinf(r->ierr.psnr) ? 999.0 : r->ierr.psnr,
                r->ierr.rmse, r->ierr.over_threshold, r->rays, r->model_bytes);
    }
    return fclose(fp) == 0;
}

/* Writes one gnuplot data block per series of the rows that `take`
   selects, x and y chosen by the caller; returns the number of blocks and
   their names. */
typedef double (*bench_axis)(const bench_row *r);
static int write_blocks(const bench_table *t, const char *path, int (*take)(const bench_row *, const void *),
                        const void *arg, bench_axis x, bench_axis y, char names[][24], int max_names) {
    FILE *fp = fopen(path, "w");
    int i, j, n = 0;
    if (!fp) return -1;
    for (i = 0; i < t->count; ++i) {
        int seen = 0;
        if (!take(&t->rows[i], arg)) continue;
        for (j = 0; j < n; ++j) seen |= !strcmp(names[j], t->rows[i].series);
        if (!seen && n < max_names) snprintf(names[n++], 24, "%s", t->rows[i].series);
    }
    for (j = 0; j < n; ++j) {
        fprintf(fp, "# %s\n", names[j]);
        for (i = 0; i < t->count; ++i)
            if (take(&t->rows[i], arg) && !strcmp(names[j], t->rows[i].series))
                fprintf(fp, "%g %g\n", x(&t->rows[i]), y(&t->rows[i]));
        fprintf(fp, "\n\n");
    }
    fclose(fp);
    return n;
}

int refl_bench_gnuplot(const char *script_path, const char *script) {
    FILE *fp = fopen(script_path, "w");
    char cmd[1200];
    if (!fp) return 0;
    fputs(script, fp);
    fclose(fp);
    snprintf(cmd, sizeof cmd, "gnuplot '%s'", script_path);
    if (system(cmd) != 0) {
        fprintf(stderr, "reflect bench: gnuplot failed on %s (is gnuplot-nox installed?)\n", script_path);
        return 0;
    }
    return 1;
}

/* A chart: blocks from write_blocks, one line per series. */
static int chart(const char *dir, const char *name, const char *title, const char *xlabel, const char *ylabel,
                 int logx, const char *dat, char names[][24], int n) {
    char script[8192], path[1024];
    size_t len;
    int j;
    len = (size_t)snprintf(script, sizeof script,
                           "set terminal pngcairo size 900,600 noenhanced\n"
                           "set output '%s/%s.png'\n"
                           "set title '%s'\nset xlabel '%s'\nset ylabel '%s'\n"
                           "set logscale y\n%s"
                           "set grid\nset key outside right\n"
                           "plot ",
                           dir, name, title, xlabel, ylabel, logx ? "set logscale x\n" : "");
    for (j = 0; j < n && len < sizeof script; ++j)
        len += (size_t)snprintf(script + len, sizeof script - len, "%s'%s' index %d using 1:2 with linespoints title '%s'",
                                j ? ", " : "", dat, j, names[j]);
    if (len < sizeof script) snprintf(script + len, sizeof script - len, "\n");
    snprintf(path, sizeof path, "%s/%s.gp", dir, name);
    return refl_bench_gnuplot(path, script);
}

static int take_scene(const bench_row *r, const void *scene) {
    return !strcmp(r->scene, (const char *)scene) && !strncmp(r->param, "base", 4) && r->applies;
}
static int take_sweep(const bench_row *r, const void *sweep) {
    return !strncmp(r->param, (const char *)sweep, strlen((const char *)sweep));
}
/* Reflection error of the error chart: exact methods sit at 0.01 px, on a
   log axis. */
static double axis_error(const bench_row *r) {
    if (r->rerr.pixels > 0 && r->rerr.matched == 0) return NAN; /* nothing lands anywhere right: off the chart */
    return r->rerr.mean > 0.01 ? r->rerr.mean : 0.01;
}
static double axis_ms(const bench_row *r) { return r->ms_median; }
static double axis_pixels(const bench_row *r) { return (double)r->width * r->height; }
static double axis_diffuse(const bench_row *r) { return (double)r->diffuse_tris; }
static double axis_reflector(const bench_row *r) { return (double)r->reflector_tris; }
static double axis_depth(const bench_row *r) { return (double)r->depth; }
static double axis_setting(const bench_row *r) { return r->value; }

/* ---- the sweeps ------------------------------------------------------------ */

static const int envmap_sizes[] = {16, 32, 64, 128, 256, 512};
/* C3RC's setting: points per unit area (0: from the view) */
static const float c3rc_densities[] = {250.0f, 1000.0f, 0.0f, 16000.0f};

/* SBC's setting: the ray map's down-sampling factor */
static const int sbc_ray_factors[] = {4, 2};

/* The methods of the error chart: exact ones once, ENVMAP per cube size,
   C3RC per density, SBC per ray map factor, without and with its
   ray-traced fallback. */
static int base_methods(bench_method *m, int full) {
    int n = 0, k;
    memset(m, 0, BENCH_METHODS_MAX * sizeof(*m));
    m[n].method = "raytrace"; m[n].series = "raytrace"; m[n].param = "base"; m[n].m = REFL_RAYTRACE; ++n;
    m[n].method = "raytrace"; m[n].series = "embree"; m[n].param = "base"; m[n].m = REFL_RAYTRACE; m[n].embree = 1; ++n;
    m[n].method = "direct"; m[n].series = "direct"; m[n].param = "base"; m[n].m = REFL_DIRECT; ++n;
    m[n].method = "planar"; m[n].series = "planar"; m[n].param = "base"; m[n].m = REFL_PLANAR; ++n;
    for (k = 0; k < (int)(sizeof envmap_sizes / sizeof envmap_sizes[0]); ++k) {
        if (!full && envmap_sizes[k] > 256) break;
        m[n].method = "envmap"; m[n].series = "envmap"; m[n].param = "base";
        m[n].m = REFL_ENVMAP; m[n].envmap_size = envmap_sizes[k]; ++n;
    }
    for (k = 0; k < (int)(sizeof c3rc_densities / sizeof c3rc_densities[0]); ++k) {
        if (!full && c3rc_densities[k] > 4000.0f) break;
        m[n].method = "c3rc"; m[n].series = "c3rc"; m[n].param = "base";
        m[n].m = REFL_C3RC; m[n].density = c3rc_densities[k]; ++n;
    }
    for (k = 0; k < (int)(sizeof sbc_ray_factors / sizeof sbc_ray_factors[0]); ++k) {
        m[n].method = "sbc"; m[n].series = "sbc"; m[n].param = "base";
        m[n].m = REFL_SBC; m[n].sbc_ray_factor = sbc_ray_factors[k]; ++n;
        m[n].method = "sbc"; m[n].series = "sbc-fallback"; m[n].param = "base";
        m[n].m = REFL_SBC; m[n].sbc_ray_factor = sbc_ray_factors[k]; m[n].sbc_trace_fallback = 1; ++n;
    }
    return n;
}

/* One setting per method, for the cost-growth sweeps. */
static int growth_methods(bench_method *m, const char *sweep) {
    int n = 0;
    memset(m, 0, BENCH_METHODS_MAX * sizeof(*m));
    m[n].method = "raytrace"; m[n].series = "raytrace"; m[n].param = sweep; m[n].m = REFL_RAYTRACE; ++n;
    m[n].method = "raytrace"; m[n].series = "embree"; m[n].param = sweep; m[n].m = REFL_RAYTRACE; m[n].embree = 1; ++n;
    m[n].method = "direct"; m[n].series = "direct"; m[n].param = sweep; m[n].m = REFL_DIRECT; ++n;
    m[n].method = "envmap"; m[n].series = "envmap-128"; m[n].param = sweep; m[n].m = REFL_ENVMAP;
    m[n].envmap_size = 128; ++n;
    m[n].method = "c3rc"; m[n].series = "c3rc"; m[n].param = sweep; m[n].m = REFL_C3RC; ++n;
    return n;
}

refl_scene *refl_bench_builtin(const char *name, int tess) {
    refl_builtin_desc bd;
    refl_scene *s = NULL;
    memset(&bd, 0, sizeof bd);
    bd.teapot_tess = tess;
    if (refl_scene_builtin(name, &bd, &s) != REFL_OK) return NULL;
    return s;
}

/* Splits the diffuse meshes' edges down to max_edge: more diffuse
   triangles, the same picture. */
static int subdivide_diffuse(refl_scene *s, float max_edge) {
    int i;
    for (i = 0; i < s->object_count; ++i) {
        refl_object *o = &s->objects[i];
        refl_mesh *finer;
        if (s->materials[o->material].type != REFL_DIFFUSE) continue;
        if (refl_mesh_subdivide(s->meshes[o->mesh], max_edge, &finer) != REFL_OK) return 0;
        refl_mesh_destroy(s->meshes[o->mesh]);
        s->meshes[o->mesh] = finer;
    }
    return 1;
}

/* A glass slab (ior 1.5, 0.4 thick) before a striped wall, for PLANAR's
   refraction against the incidence angle. */
static refl_scene *slab_scene(void) {
    refl_scene *s;
    refl_mesh *m;
    refl_material mat;
    refl_object o;
    refl_light l;
    int k;
    if (refl_scene_create(NULL, &s) != REFL_OK) return NULL;
    memset(&l, 0, sizeof l);
    l.type = REFL_LIGHT_DIRECTIONAL;
    l.direction = refl_v3(0.3f, -0.5f, -1.0f);
    l.color[0] = l.color[1] = l.color[2] = 0.8f;
    refl_scene_add_light(s, &l);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 0.2f;
    s->environment.color[0] = 0.4f; s->environment.color[1] = 0.6f; s->environment.color[2] = 0.9f;
    for (k = 0; k < 13; ++k) { /* stripes 0.5 wide, 2 behind the slab */
        memset(&mat, 0, sizeof mat);
        memset(&o, 0, sizeof o);
        mat.color[0] = k % 2 ? 0.9f : 0.1f; mat.color[1] = k % 3 ? 0.8f : 0.2f; mat.color[2] = k % 2 ? 0.2f : 0.7f;
        mat.color[3] = 1.0f;
        if (k == 12) { /* and a second slab of glass */
            mat.type = REFL_GLASS;
            mat.ior = 1.5f;
        }
        if (refl_mesh_box(k == 12 ? refl_v3(2.0f, 2.0f, 0.4f) : refl_v3(0.5f, 4.0f, 0.1f), NULL, &m) != REFL_OK) {
            refl_scene_destroy(s);
            return NULL;
        }
        o.mesh = refl_scene_add_mesh(s, m);
        o.material = refl_scene_add_material(s, &mat);
        o.transform = k == 12 ? refl_mat4_identity()
                              : refl_mat4_translate(refl_v3(-2.75f + 0.5f * (float)k, 0.0f, -2.0f));
        if (o.mesh < 0 || o.material < 0 || refl_scene_add_object(s, &o) < 0) {
            refl_scene_destroy(s);
            return NULL;
        }
    }
    s->camera.eye = refl_v3(0, 0, 5);
    s->camera.up = refl_v3(0, 1, 0);
    s->has_camera = 1;
    return s;
}

static refl_view view_of(const refl_scene *s, int w, int h) {
    refl_view v = s->camera;
    v.width = w;
    v.height = h;
    return v;
}

/* The papers' own tables: paper 000's (C3RC's tables and its cameras'
   error against triangle size) and paper 003's Fig. 19 (SBC), or the one
   --only names. */
static int paper_tables(const bench_opts *o) {
    if ((!o->only[0] || !strcmp(o->only, "c3rc")) && !refl_bench_c3rc(o->out, o->threads, o->repeats, o->full)) {
        fprintf(stderr, "reflect bench: the C3RC tables failed\n");
        return 0;
    }
    if ((!o->only[0] || !strcmp(o->only, "sbc")) && !refl_bench_sbc(o->out, o->threads, o->repeats, o->full)) {
        fprintf(stderr, "reflect bench: the SBC table failed\n");
        return 0;
    }
    if ((!o->only[0] || !strcmp(o->only, "sbc")) &&
        !refl_bench_sbc_sweep(o->out, o->threads, o->repeats, o->full)) {
        fprintf(stderr, "reflect bench: the SBC resolution sweep failed\n");
        return 0;
    }
    if ((!o->only[0] || !strcmp(o->only, "path")) && !refl_bench_path(o->out, o->threads)) {
        fprintf(stderr, "reflect bench: the camera path failed\n");
        return 0;
    }
    if ((!o->only[0] || !strcmp(o->only, "graphcam")) && !refl_bench_graphcam(o->out, o->threads)) {
        fprintf(stderr, "reflect bench: the maze's graph camera table failed\n");
        return 0;
    }
    /* 60 frames at four output and four impostor sizes: minutes, so only when asked for */
    if (((!o->only[0] && o->full) || !strcmp(o->only, "spoc")) && !refl_bench_spoc(o->out, o->threads)) {
        fprintf(stderr, "reflect bench: the SPOC tables failed\n");
        return 0;
    }
    if (((!o->only[0] && o->full) || !strcmp(o->only, "spoc-sweeps")) && !refl_bench_spoc_sweeps(o->out, o->threads)) {
        fprintf(stderr, "reflect bench: the SPOC sweeps failed\n");
        return 0;
    }
    if (((!o->only[0] && o->full) || !strcmp(o->only, "lem")) && !refl_bench_lem(o->out, o->threads, o->quick)) {
        fprintf(stderr, "reflect bench: the LAYERED_EM table failed\n");
        return 0;
    }
    if ((!strcmp(o->only, "lem-grid") || !strcmp(o->only, "lem-grid-calib")) &&
        !refl_bench_lem_grid(o->out, o->threads, o->quick, !strcmp(o->only, "lem-grid"))) {
        fprintf(stderr, "reflect bench: the LAYERED_EM grid table failed\n");
        return 0;
    }
    if (!strcmp(o->only, "lem-options") && !refl_bench_lem_options(o->out, o->threads, o->quick)) {
        fprintf(stderr, "reflect bench: the LAYERED_EM options failed\n");
        return 0;
    }
    if (!strcmp(o->only, "lem-share") && !refl_bench_lem_share(o->out, o->threads)) {
        fprintf(stderr, "reflect bench: the LAYERED_EM shared layer failed\n");
        return 0;
    }
    if (!strcmp(o->only, "lem-sweeps") && !refl_bench_lem_sweeps(o->out, o->threads)) {
        fprintf(stderr, "reflect bench: the LAYERED_EM sweeps failed\n");
        return 0;
    }
    return 1;
}

/* The options that take a value, and the paper tables --only runs (by
   name: paper_tables compares it). */
static const char *const bench_value_options[] = {"--report", "--only", "--out", "--repeats", "--threads", "--depth", NULL};
static const cli_choice only_tables[] = {
    {"c3rc", 0}, {"sbc", 0}, {"path", 0}, {"graphcam", 0},
    {"spoc", 0}, {"spoc-sweeps", 0}, {"lem", 0}, {"lem-sweeps", 0},
    {"lem-options", 0}, {"lem-share", 0}, {"lem-grid", 0}, {"lem-grid-calib", 0},
    {NULL, 0}};

int refl_cli_bench(int argc, char **argv) {
    bench_opts o;
    bench_table table;
    bench_method methods[BENCH_METHODS_MAX];
    char path[1024], names[16][24];
    const char *scenes_quick[] = {"default", NULL};
    const char *const *scenes;
    int i, n, ok = 1;
    unsigned long long given = 0; /* the value options seen (cli_given_twice) */
    memset(&o, 0, sizeof o);
    memset(&table, 0, sizeof table);
    snprintf(o.out, sizeof o.out, "out/bench");
    o.depth = 1;
    for (i = 2; i < argc; ++i) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (v && cli_given_twice("reflect bench", bench_value_options, a, &given)) return 2;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(usage_bench, stdout);
            return 0;
        } else if (!strcmp(a, "--full")) {
            o.full = 1;
        } else if (!strcmp(a, "--report") && v) {
            o.report = v;
            ++i;
        } else if (!strcmp(a, "--quick")) {
            o.quick = 1;
        } else if (!strcmp(a, "--only") && v) {
            int table_index;
            if (!parse_choice("reflect bench", a, v, only_tables, &table_index)) return 2;
            snprintf(o.only, sizeof o.only, "%s", v);
            ++i;
        } else if (!strcmp(a, "--out") && v) {
            snprintf(o.out, sizeof o.out, "%s", v);
            ++i;
        } else if ((!strcmp(a, "--repeats") || !strcmp(a, "--threads") || !strcmp(a, "--depth")) && v) {
            char *end;
            long x = strtol(v, &end, 10);
            if (*end || x < (a[2] == 'r' ? 1 : 0) || x > 64) {
                fprintf(stderr, "reflect bench: bad %s '%s'\n", a, v);
                return 2;
            }
            if (a[2] == 'r') o.repeats = (int)x;
            else if (a[2] == 't') o.threads = (int)x;
            else o.depth = (int)x;
            ++i;
        } else {
            fprintf(stderr, "reflect bench: unknown option '%s'\n\n%s", a, usage_bench);
            return 2;
        }
    }
    if (!o.repeats) o.repeats = o.full ? 5 : 3;
    if (o.report) return refl_bench_report(o.report, o.threads, o.repeats, o.quick) ? 0 : 1;
    if (o.quick && strcmp(o.only, "lem") && strcmp(o.only, "lem-options") && strcmp(o.only, "lem-grid") &&
        strcmp(o.only, "lem-grid-calib")) {
        fprintf(stderr, "reflect bench: --quick goes with --report, --only lem, lem-options, lem-grid or "
                        "lem-grid-calib\n");
        return 2;
    }
    if (mkdir(o.out, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "reflect bench: cannot create %s: %s\n", o.out, strerror(errno));
        return 1;
    }
    fprintf(stderr, "reflect bench: %d runs per setting (median), %s threads, depth %d -> %s\n", o.repeats,
            o.threads ? "given" : "all", o.depth, o.out);
    if (o.only[0]) return paper_tables(&o) ? 0 : 1;

    /* (a) time against reflection error, per scene */
    scenes = o.full ? refl_builtin_names() : scenes_quick;
    n = base_methods(methods, o.full);
    for (i = 0; ok && scenes[i]; ++i) {
        refl_scene *s = refl_bench_builtin(scenes[i], 0);
        refl_view v;
        if (!s) { ok = 0; break; }
        v = view_of(s, 640, 480);
        ok = bench_scene(&table, &o, scenes[i], s, &v, methods, n);
        refl_scene_destroy(s);
    }
    /* (b) cost growth on the default scene */
    if (ok) {
        static const int sizes[][2] = {{320, 240}, {640, 480}, {1280, 720}, {1920, 1080}};
        refl_scene *s = refl_bench_builtin("default", 0);
        n = growth_methods(methods, "resolution");
        for (i = 0; ok && s && i < 4; ++i) {
            refl_view v = view_of(s, sizes[i][0], sizes[i][1]);
            ok = bench_scene(&table, &o, "default", s, &v, methods, n);
        }
        refl_scene_destroy(s);
    }
    if (ok) {
        static const float edges[] = {0.0f, 1.0f, 0.5f, 0.25f, 0.125f};
        n = growth_methods(methods, "diffuse");
        for (i = 0; ok && i < (o.full ? 5 : 4); ++i) {
            refl_scene *s = refl_bench_builtin("default", 0);
            refl_view v;
            if (!s || (edges[i] > 0.0f && !subdivide_diffuse(s, edges[i]))) ok = 0;
            if (ok) {
                v = view_of(s, 640, 480);
                ok = bench_scene(&table, &o, "default", s, &v, methods, n);
            }
            refl_scene_destroy(s);
        }
    }
    if (ok) {
        static const int tess[] = {4, 8, 16, 32, 64};
        n = growth_methods(methods, "reflector");
        for (i = 0; ok && i < (o.full ? 5 : 4); ++i) {
            refl_scene *s = refl_bench_builtin("default", tess[i]);
            refl_view v;
            if (!s) { ok = 0; break; }
            v = view_of(s, 640, 480);
            ok = bench_scene(&table, &o, "default", s, &v, methods, n);
            refl_scene_destroy(s);
        }
    }
    if (ok) {
        /* paper 002's cost: recursion depth in the mirror room, beside
           RAYTRACE at the same depth */
        refl_scene *s = refl_bench_builtin("mirror-room", 0);
        bench_opts od = o;
        memset(methods, 0, 3 * sizeof methods[0]);
        methods[0].method = "planar"; methods[0].series = "planar"; methods[0].param = "depth";
        methods[0].m = REFL_PLANAR;
        methods[1].method = "raytrace"; methods[1].series = "raytrace"; methods[1].param = "depth";
        methods[1].m = REFL_RAYTRACE;
        methods[2].method = "raytrace"; methods[2].series = "embree"; methods[2].param = "depth";
        methods[2].m = REFL_RAYTRACE; methods[2].embree = 1;
        for (i = 1; ok && s && i <= 6; ++i) {
            refl_view v = view_of(s, 640, 480);
            od.depth = i;
            ok = bench_scene(&table, &od, "mirror-room", s, &v, methods, 3);
        }
        if (!s) ok = 0;
        refl_scene_destroy(s);
    }
    if (ok) {
        /* paper 002's refraction: one shift for the whole slab, so its
           error grows with the incidence angle */
        refl_scene *s = slab_scene();
        bench_opts od = o;
        memset(methods, 0, sizeof methods[0]);
        methods[0].method = "planar"; methods[0].series = "planar-slab"; methods[0].param = "incidence";
        methods[0].m = REFL_PLANAR;
        od.depth = 2; /* in and out of the slab */
        for (i = 0; ok && s && i <= 7; ++i) {
            float a = (float)(10 * i) * 3.14159265f / 180.0f;
            refl_view v = view_of(s, 640, 480);
            int before = table.count;
            v.eye = refl_v3(5.0f * sinf(a), 0.0f, 5.0f * cosf(a));
            v.target = refl_v3(0, 0, 0);
            ok = bench_scene(&table, &od, "slab", s, &v, methods, 1);
            if (ok && table.count > before) table.rows[table.count - 1].value = 10 * i;
        }
        if (!s) ok = 0;
        refl_scene_destroy(s);
    }
    if (!ok) {
        free(table.rows);
        return 1;
    }
    snprintf(path, sizeof path, "%s/bench.csv", o.out);
    if (!write_csv(&table, path)) {
        fprintf(stderr, "reflect bench: cannot write %s\n", path);
        free(table.rows);
        return 1;
    }
    fprintf(stderr, "wrote %s\n", path);
    for (i = 0; scenes[i]; ++i) {
        char dat[1024], name[64], title[128];
        snprintf(dat, sizeof dat, "%s/time_vs_error_%s.dat", o.out, scenes[i]);
        snprintf(name, sizeof name, "time_vs_error_%s", scenes[i]);
        snprintf(title, sizeof title, "%s scene, 640x480: time per frame against reflection error", scenes[i]);
        n = write_blocks(&table, dat, take_scene, scenes[i], axis_error, axis_ms, names, 16);
        if (n > 0) chart(o.out, name, title, "mean reflection error (pixels; exact methods at 0.01)",
                         "ms per frame (median)", 1, dat, names, n);
    }
    {
        static const char *sweeps[] = {"resolution", "diffuse", "reflector", "depth"};
        static const char *xlabels[] = {"pixels", "diffuse triangles", "reflector triangles",
                                        "recursion depth"};
        bench_axis xs[] = {axis_pixels, axis_diffuse, axis_reflector, axis_depth};
        for (i = 0; i < 4; ++i) {
            char dat[1024], name[64], title[128];
            snprintf(dat, sizeof dat, "%s/growth_%s.dat", o.out, sweeps[i]);
            snprintf(name, sizeof name, "growth_%s", sweeps[i]);
            snprintf(title, sizeof title, "%s: time per frame against %s", i == 3 ? "mirror room" : "default scene",
                     xlabels[i]);
            n = write_blocks(&table, dat, take_sweep, sweeps[i], xs[i], axis_ms, names, 16);
            if (n > 0) chart(o.out, name, title, xlabels[i], "ms per frame (median)", i != 3, dat, names, n);
        }
    }
    {
        char dat[1024];
        snprintf(dat, sizeof dat, "%s/refraction_incidence.dat", o.out);
        n = write_blocks(&table, dat, take_sweep, "incidence", axis_setting, axis_error, names, 16);
        if (n > 0)
            chart(o.out, "refraction_incidence", "PLANAR slab refraction against RAYTRACE (640x480)",
                  "incidence angle of the view axis (degrees)", "mean reflection error (pixels)", 0, dat, names, n);
    }
    if (!paper_tables(&o)) {
        free(table.rows);
        return 1;
    }
    fprintf(stderr, "wrote %s/*.png\n", o.out);
    free(table.rows);
    return 0;
}
