/* `reflect bench`, SBC part: SBC's speed against RAYTRACE (through our
   BVH and through Embree) across resolutions, at the accuracy each
   reaches.

   The default scene, one bounce, at 640x480, 1920x1080 and 3840x2160;
   per size RAYTRACE through refl_bvh (the reference: its last frame is the
   truth the others are measured against, its own error 0 by definition),
   RAYTRACE through Embree (its scene built once, outside the timing, as
   the other bench tables do; refl_bvh is built inside every frame), and
   SBC at ray map factors 4 and 2, each also with its ray-traced fallback
   (refl_render_desc.sbc.trace_fallback: a pixel no reflected triangle
   covers, or whose point the samples around it contradict, is rendered
   as RAYTRACE renders it, and the groups' edges are left to it). Each row: the median frame time
   (stats.ms_total) of `repeats` runs, but one run at 3840x2160 unless
   --full (SBC takes tens of seconds a frame there); the process CPU time
   per frame and the cores it kept busy (CPU time over wall time): on a
   machine shared with other jobs a frame's wall time depends on who else
   runs, its CPU time much less, so both are compared; where the time goes (the
   frame's stats: ms_build, ms_base, ms_reflect, ms_composite, and for SBC
   its pinhole and ray-list leaves, rays, vertex projections and reflected
   triangles drawn); the reflection error against the reference
   (refl_measure_reflection_error); and the wall and CPU time over
   Embree's at that size. Then per method a least-squares line of ms
   (wall, then CPU) against pixels, and where SBC's line meets Embree's and
   our tracer's: the crossover. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "../bench/cost_fit.h"
#include "../bench/embree_peer.h"
#include "reflect_bench.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define SWEEP_SIZES 3
#define SWEEP_METHODS 6

/* What a row renders. */
typedef struct sweep_method {
    const char *name;
    refl_method method;
    int embree;                   /* RAYTRACE's rays through Embree */
    int ray_factor;               /* SBC: refl_render_desc.sbc.ray_factor */
    int trace_fallback;           /* SBC: refl_render_desc.sbc.trace_fallback */
} sweep_method;

static const sweep_method sweep_methods[SWEEP_METHODS] = {
    {"raytrace-bvh", REFL_RAYTRACE, 0, 0, 0},
    {"raytrace-embree", REFL_RAYTRACE, 1, 0, 0},
    {"sbc-4", REFL_SBC, 0, 4, 0},
    {"sbc-2", REFL_SBC, 0, 2, 0},
    {"sbc-4-traced", REFL_SBC, 0, 4, 1},
    {"sbc-2-traced", REFL_SBC, 0, 2, 1},
};
enum { SWEEP_BVH, SWEEP_EMBREE, SWEEP_FIRST_SBC };

static const int sweep_sizes[SWEEP_SIZES][2] = {{640, 480}, {1920, 1080}, {3840, 2160}};

typedef struct sweep_row {
    int width, height, method, runs;
    double ms, ms_min;            /* median and fastest of the runs' stats.ms_total */
    double cpu_ms;                /* process CPU time per run */
    double cores;                 /* process CPU time over wall time, over the runs */
    double vs_embree, cpu_vs_embree; /* ms and cpu_ms over Embree's at this size */
    refl_stats stats;             /* the last run's */
    refl_reflection_error error;  /* against raytrace-bvh of this size */
    refl_sbc_camera_error cams;   /* SBC: its cameras alone (refl_sbc_measure_camera_error), untimed */
} sweep_row;

static double cpu_ms(void) {
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

/* Renders one row's method `runs` times into f and fills the row's time
   and stats. */
static int sweep_render(const refl_scene *s, const refl_view *v, const sweep_method *m, refl_embree *embree,
                        int threads, int runs, refl_frame *f, sweep_row *row) {
    refl_render_desc d;
    double wall0, cpu0, wall;
    refl_result r;
    memset(&d, 0, sizeof d);
    d.method = m->method;
    d.threads = threads;
    d.depth = 1;
    d.sbc.ray_factor = m->ray_factor;
    d.sbc.trace_fallback = m->trace_fallback;
    if (m->embree) {
        refl_ray_caster c = {refl_embree_intersect, refl_embree_occluded, embree};
        d.raytrace.caster = c;
    }
    wall0 = refl_bench_now_ms();
    cpu0 = cpu_ms();
    r = refl_bench_timed_render(s, v, &d, runs, f, &row->ms, &row->ms_min);
    wall = refl_bench_now_ms() - wall0;
    if (r != REFL_OK) {
        fprintf(stderr, "reflect bench: %s at %dx%d: %s\n", m->name, v->width, v->height, refl_result_string(r));
        return 0;
    }
    row->cpu_ms = (cpu_ms() - cpu0) / runs;
    row->cores = wall > 0.0 ? row->cpu_ms * runs / wall : 0.0;
    row->runs = runs;
    row->stats = f->stats;
    return 1;
}

static int write_sweep_csv(const char *path, const sweep_row *rows, int n, int threads) {
    FILE *fp = fopen(path, "w");
    int i;
    if (!fp) return 0;
    fprintf(fp, "width,height,pixels,method,ray_factor,trace_fallback,threads,runs,ms_median,ms_min,cpu_ms,cores_busy,"
                "vs_embree,"
                "cpu_vs_embree,ms_build,ms_base,"
                "ms_reflect,ms_composite,pinhole_leaves,ray_list_leaves,rays,projections,projected,triangles,"
                "model_bytes,error_mean_px,error_p95_px,error_max_px,wrong,holes,"
                "pinhole_samples,pinhole_samples_p95_px,pinhole_samples_max_px,pinhole_samples_missed,"
                "ray_list_samples,ray_list_samples_p95_px,ray_list_samples_max_px,ray_list_samples_missed\n");
    for (i = 0; i < n; ++i) {
        const sweep_row *r = &rows[i];
        const refl_stats *st = &r->stats;
        fprintf(fp, "%d,%d,%lld,%s,%d,%d,%d,%d,%.3f,%.3f,%.3f,%.3f,%.4f,%.4f,%.3f,%.3f,%.3f,%.3f,%lld,%lld,%lld,%lld,"
                    "%lld,%lld,%lld,%.4f,%.4f,%.4f,%.5f,%.5f,%lld,%.4f,%.4f,%.5f,%lld,%.4f,%.4f,%.5f\n",
                r->width, r->height, (long long)r->width * r->height, sweep_methods[r->method].name,
                sweep_methods[r->method].ray_factor, sweep_methods[r->method].trace_fallback, threads, r->runs, r->ms,
                r->ms_min, r->cpu_ms, r->cores,
                r->vs_embree, r->cpu_vs_embree, st->ms_build,
                st->ms_base, st->ms_reflect, st->ms_composite, st->sbc.pinhole_leaves, st->sbc.ray_leaves, st->rays, st->sbc.projections,
                st->sbc.projected, st->triangles, st->model_bytes, r->error.mean, r->error.p95, r->error.max,
                r->error.wrong, r->error.empty, r->cams.pinhole_samples.pixels, r->cams.pinhole_samples.p95,
                r->cams.pinhole_samples.max, r->cams.pinhole_samples.wrong, r->cams.ray_list_samples.pixels,
                r->cams.ray_list_samples.p95, r->cams.ray_list_samples.max, r->cams.ray_list_samples.wrong);
    }
    return fclose(fp) == 0;
}

static void print_row(const sweep_row *r) {
    const refl_stats *st = &r->stats;
    const sweep_method *m = &sweep_methods[r->method];
    printf("%4dx%-4d %-15s %4d %9.1f %9.1f %5.2f %6.2f %6.2f | %7.1f %6.1f %8.1f %6.1f", r->width, r->height,
           m->name, r->runs, r->ms, r->cpu_ms, r->cores, r->vs_embree, r->cpu_vs_embree, st->ms_build, st->ms_base,
           st->ms_reflect, st->ms_composite);
    if (m->method == REFL_SBC)
        printf(" %6lld/%-6lld %6lld %9lld %9lld", st->sbc.pinhole_leaves, st->sbc.ray_leaves, st->rays, st->sbc.projections,
               st->triangles);
    else
        printf(" %13s %6s %9s %9s", "-", "-", "-", "-");
    printf(" | %6.2f %6.2f %7.2f %5.1f%% %5.1f%%\n", r->error.mean, r->error.p95, r->error.max,
           100.0 * r->error.wrong, 100.0 * r->error.empty);
}

/* SBC's cameras alone at the ray map's samples, by leaf kind: the paper's
   bound is the requested error (1 px) in pinhole leaves, the ray map's
   factor in ray lists. */
static void print_cameras(const sweep_row *rows, int n) {
    int i;
    printf("SBC's cameras alone (refl_sbc_measure_camera_error), each ray-traced point at a ray map sample\n"
           "through its own group: p95 and max px, share not projecting (paper: pinhole within 1 px, ray\n"
           "lists within the factor)\n%-9s %-6s | %7s %6s %6s %6s | %8s %6s %7s %6s\n",
           "size", "method", "pinhole", "p95", "max", "none", "ray list", "p95", "max", "none");
    for (i = 0; i < n; ++i) {
        const sweep_row *r = &rows[i];
        const refl_sbc_camera_error *c = &r->cams;
        if (sweep_methods[r->method].method != REFL_SBC || sweep_methods[r->method].trace_fallback) continue;
        printf("%4dx%-4d %-6s | %7lld %6.2f %6.2f %5.1f%% | %8lld %6.2f %7.2f %5.1f%%\n", r->width, r->height,
               sweep_methods[r->method].name, c->pinhole_samples.pixels, c->pinhole_samples.p95,
               c->pinhole_samples.max, 100.0 * c->pinhole_samples.wrong, c->ray_list_samples.pixels,
               c->ray_list_samples.p95, c->ray_list_samples.max, 100.0 * c->ray_list_samples.wrong);
    }
}

/* Where SBC's line meets a tracer's, said in words. */
static void print_crossover(const char *sbc, refl_cost_line a, const char *peer, refl_cost_line b, double lo,
                            double hi) {
    double x;
    int meet = refl_cost_crossover(a, b, &x);
    /* where SBC is faster: beyond the crossover if its cost grows slower */
    const char *side = a.per_unit < b.per_unit ? "above" : "below";
    printf("  %s against %s: ", sbc, peer);
    if (!meet) {
        printf("no crossover: %s is %s at every size", sbc,
               a.fixed + a.per_unit * lo < b.fixed + b.per_unit * lo ? "faster" : "slower");
        /* the ratio the lines approach as the image grows */
        if (b.per_unit > 0.0) printf(" (%.1fx as the image grows)", a.per_unit / b.per_unit);
        printf("\n");
    } else if (x >= lo && x <= hi) {
        printf("crossover at %.2f Mpx, in range; %s is faster %s it\n", x * 1e-6, sbc, side);
    } else {
        double w = sqrt(x * 16.0 / 9.0);
        printf("none in range; the lines meet at %.2f Mpx (%.0fx%.0f at 16:9), %s is faster only %s it\n",
               x * 1e-6, w, w * 9.0 / 16.0, sbc, side);
    }
}

/* Per method a line of ms (wall or CPU) against pixels (and how far the
   measured values stray from it), and SBC's crossovers. */
static void print_fits(const sweep_row *rows, int nsizes, int cpu) {
    refl_cost_line line[SWEEP_METHODS];
    double px[SWEEP_SIZES], ms[SWEEP_SIZES];
    int m, k, fitted[SWEEP_METHODS];
    printf("%s ms against pixels (least squares over the %d sizes; misfit: the largest |line - ms| / ms):\n",
           cpu ? "CPU" : "wall", nsizes);
    for (m = 0; m < SWEEP_METHODS; ++m) {
        double misfit = 0.0;
        for (k = 0; k < nsizes; ++k) {
            const sweep_row *r = &rows[k * SWEEP_METHODS + m];
            px[k] = (double)r->width * r->height;
            ms[k] = cpu ? r->cpu_ms : r->ms;
        }
        fitted[m] = refl_cost_fit(px, ms, nsizes, &line[m]);
        if (!fitted[m]) continue;
        for (k = 0; k < nsizes; ++k) {
            double off = fabs(line[m].fixed + line[m].per_unit * px[k] - ms[k]) / ms[k];
            misfit = off > misfit ? off : misfit;
        }
        printf("  %-15s %9.1f ms + %8.2f ms per Mpx (misfit %.0f%%)\n", sweep_methods[m].name, line[m].fixed,
               line[m].per_unit * 1e6, 100.0 * misfit);
    }
    for (m = SWEEP_FIRST_SBC; m < SWEEP_METHODS; ++m) {
        if (!fitted[m]) continue;
        if (fitted[SWEEP_EMBREE])
            print_crossover(sweep_methods[m].name, line[m], "Embree", line[SWEEP_EMBREE], px[0], px[nsizes - 1]);
        if (fitted[SWEEP_BVH])
            print_crossover(sweep_methods[m].name, line[m], "our BVH", line[SWEEP_BVH], px[0], px[nsizes - 1]);
    }
}

/* Per SBC setting: its time over Embree's at each size, and whether its
   frames are as accurate as the reference's (error 0 by definition). */
static void print_verdicts(const sweep_row *rows, int nsizes) {
    int m, k;
    for (m = SWEEP_FIRST_SBC; m < SWEEP_METHODS; ++m) {
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {0.0, 0.0, 0.0};
        printf("  %s: wall (CPU) time over Embree's", sweep_methods[m].name);
        for (k = 0; k < nsizes; ++k) {
            const sweep_row *r = &rows[k * SWEEP_METHODS + m];
            double v[3];
            int i;
            printf("%s %.1fx (%.1fx) at %dx%d", k ? "," : "", r->vs_embree, r->cpu_vs_embree, r->width, r->height);
            v[0] = r->error.mean;
            v[1] = r->error.p95;
            v[2] = 100.0 * r->error.empty;
            for (i = 0; i < 3; ++i) {
                lo[i] = v[i] < lo[i] ? v[i] : lo[i];
                hi[i] = v[i] > hi[i] ? v[i] : hi[i];
            }
        }
        printf(";\n    mean error %.2f to %.2f px, p95 %.1f to %.1f px, holes %.1f to %.1f%%: %s\n", lo[0], hi[0],
               lo[1], hi[1], lo[2], hi[2],
               hi[1] <= 1.0 ? "at the reference's accuracy (p95 within 1 px)"
                            : "NOT at equal accuracy (p95 above 1 px): the times compare unequal images");
    }
}

int refl_bench_sbc_sweep(const char *dir, int threads, int repeats, int full) {
    sweep_row rows[SWEEP_SIZES * SWEEP_METHODS];
    refl_builtin_desc bd;
    refl_scene *s = NULL;
    refl_embree *embree = NULL;
    char path[1024], err[256];
    int k, m, ok = 1, n = 0;
    memset(rows, 0, sizeof rows);
    memset(&bd, 0, sizeof bd);
    if (threads <= 0) threads = (int)sysconf(_SC_NPROCESSORS_ONLN); /* what 0 means to refl_render */
    if (refl_scene_builtin("default", &bd, &s) != REFL_OK) return 0;
    if (!(embree = refl_embree_create(s, threads, err, sizeof err))) {
        fprintf(stderr, "reflect bench: Embree: %s\n", err);
        refl_scene_destroy(s);
        return 0;
    }
    printf("\nSBC against RAYTRACE (our BVH; Embree as its ray caster), default scene, one bounce, %d threads;\n"
           "ms: median wall time of %d runs (3840x2160: %s); cpu ms: process CPU time per run; cores: CPU\n"
           "over wall time (below %d: other jobs or serial parts); /Embree: wall and CPU time over Embree's at\n"
           "that size; build/base/reflect/comp: the last frame's phases in ms; SBC: leaves pinhole/ray list, rays,\n"
           "vertex projections, reflected triangles drawn; error against RAYTRACE (BVH) of the same size\n",
           threads, repeats, full ? "the same" : "1 run, --full for more", threads);
    printf("%-9s %-15s %4s %9s %9s %5s %13s | %7s %6s %8s %6s %13s %6s %9s %9s | %6s %6s %7s %6s %6s\n",
           "size", "method", "runs", "ms", "cpu ms", "cores", "/Embree w, cpu", "build", "base", "reflect", "comp",
           "leaves p/r", "rays", "projs", "tris", "mean", "p95", "max", "wrong", "holes");
    for (k = 0; ok && k < SWEEP_SIZES; ++k) {
        refl_frame *truth = NULL, *f = NULL;
        refl_view v = s->camera;
        int runs = full || k < SWEEP_SIZES - 1 ? repeats : 1;
        v.width = sweep_sizes[k][0];
        v.height = sweep_sizes[k][1];
        ok = refl_frame_create(v.width, v.height, NULL, &truth) == REFL_OK &&
             refl_frame_create(v.width, v.height, NULL, &f) == REFL_OK;
        for (m = 0; ok && m < SWEEP_METHODS; ++m) {
            sweep_row *r = &rows[n++];
            refl_frame *into = m == SWEEP_BVH ? truth : f;
            r->width = v.width;
            r->height = v.height;
            r->method = m;
            ok = sweep_render(s, &v, &sweep_methods[m], embree, threads, runs, into, r) &&
                 refl_measure_reflection_error(into, truth, NULL, &r->error) == REFL_OK;
            /* the cameras, once per factor: the fallback leaves them as they are */
            if (ok && sweep_methods[m].method == REFL_SBC && !sweep_methods[m].trace_fallback) {
                refl_render_desc d;
                memset(&d, 0, sizeof d);
                d.threads = threads;
                d.sbc.ray_factor = sweep_methods[m].ray_factor;
                ok = refl_sbc_measure_camera_error(s, &v, &d, truth, &r->cams) == REFL_OK;
            }
        }
        for (m = 0; ok && m < SWEEP_METHODS; ++m) {
            sweep_row *r = &rows[n - SWEEP_METHODS + m];
            const sweep_row *e = &rows[n - SWEEP_METHODS + SWEEP_EMBREE];
            r->vs_embree = r->ms / e->ms;
            r->cpu_vs_embree = r->cpu_ms / e->cpu_ms;
            print_row(r);
        }
        fflush(stdout);
        refl_frame_destroy(truth);
        refl_frame_destroy(f);
    }
    refl_embree_destroy(embree);
    refl_scene_destroy(s);
    if (!ok) return 0;
    print_cameras(rows, n);
    print_fits(rows, SWEEP_SIZES, 0);
    print_fits(rows, SWEEP_SIZES, 1);
    print_verdicts(rows, SWEEP_SIZES);
    snprintf(path, sizeof path, "%s/sbc_resolution.csv", dir);
    if (!write_sweep_csv(path, rows, n, threads)) return 0;
    fprintf(stderr, "wrote %s\n", path);
    return 1;
}
