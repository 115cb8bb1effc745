/* reflect bench --only spoc: paper 004's Tables 1 and 2 on the built-in
   two-teapot scene, the paper's way: frame times (average, min, max) along
   a 60-frame camera path. Table 1: output 640x480 to 1280x1024 with a
   512-texel impostor; Table 2: impostor 128 to 1024 texels at 640x480, with
   the longest ray projection (marching steps of one ray through one
   impostor). Beside each SPOC row, RAYTRACE (ours and Embree's) on the same
   frames, and the reflection error and PSNR over the mirror against
   RAYTRACE, which the paper does not report. One bounce and one depth
   layer (spoc.layers 1), as the paper's reflections and impostors. A table on stdout (the paper's rows beside ours) and
   dir/spoc_teapots.csv. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../bench/embree_peer.h"
#include "reflect_bench.h"

enum { SP_FRAMES = 60, SP_SIZES = 4 };

/* The paper's rows (fps with 8x MSAA on an NVIDIA 8800 Ultra). */
static const int sp_out_w[SP_SIZES] = {640, 800, 1024, 1280}, sp_out_h[SP_SIZES] = {480, 600, 768, 1024};
static const double sp_paper_t1[3][SP_SIZES] = {{52.4, 42.78, 36.1, 23.9}, {36, 28, 24, 10}, {70, 56, 58, 44}};
static const int sp_imp[SP_SIZES] = {128, 256, 512, 1024};
static const double sp_paper_t2_fps[SP_SIZES] = {103.3, 83.4, 42.78, 28.9};
static const int sp_paper_t2_len[SP_SIZES] = {72, 164, 346, 640};

/* Frame k of the path: the scene camera swung about the teapots' midpoint
   by -30..30 degrees and raised and lowered by 0.5. */
static refl_view sp_view(const refl_scene *s, int k, int w, int h) {
    refl_view v = s->camera;
    refl_vec3 c = refl_v3(-0.05f, 0.4f, 0.65f), off = refl_v3_sub(v.eye, c);
    double u = (double)k / (SP_FRAMES - 1);
    float a = (float)((-30.0 + 60.0 * u) * 3.14159265358979 / 180.0), co = cosf(a), sn = sinf(a);
    v.eye = refl_v3_add(c, refl_v3(co * off.x + sn * off.z, off.y + 0.5f * (float)sin(2.0 * 3.14159265358979 * u),
                                   -sn * off.x + co * off.z));
    v.width = w;
    v.height = h;
    return v;
}

/* One row's sums over the path. */
typedef struct sp_acc {
    double build, total, mn, mx, reflect, psnr, emean, ep95, wrong, empty;
    long long steps, rays, max_steps;
    int n;
} sp_acc;

static void sp_add(sp_acc *a, const refl_frame *f, const refl_frame *truth) {
    refl_image_error ie;
    refl_reflection_error re;
    if (!a->n) a->mn = 1e30;
    a->build += f->stats.ms_build;
    a->total += f->stats.ms_total;
    a->mn = f->stats.ms_total < a->mn ? f->stats.ms_total : a->mn;
    a->mx = f->stats.ms_total > a->mx ? f->stats.ms_total : a->mx;
    a->reflect += f->stats.ms_reflect;
    if (truth && refl_measure_image_error(f, truth, 1, 2.0f / 255.0f, &ie) == REFL_OK &&
        refl_measure_reflection_error(f, truth, NULL, &re) == REFL_OK) {
        a->psnr += isfinite(ie.psnr) ? ie.psnr : 99.0;
        a->emean += re.mean;
        a->ep95 += re.p95;
        a->wrong += re.wrong;
        a->empty += re.empty;
    }
    a->steps += f->stats.spoc.steps;
    a->rays += f->stats.rays;
    if (f->stats.spoc.max_steps > a->max_steps) a->max_steps = f->stats.spoc.max_steps;
    a->n++;
}

static void sp_row(FILE *csv, const char *table, const char *method, int w, int h, int imp, const sp_acc *a,
                   double rt_avg) {
    double n = a->n ? a->n : 1;
    printf("%-6s %-9s %4dx%-4d %8d %9.1f %9.1f %8.1f %8.1f %7.2f %8.2f %8.3f %7.4f %9lld\n", table, method, w, h, imp,
           a->build / n, a->total / n, a->mn, a->mx, rt_avg > 0 ? (a->total / n) / rt_avg : 0.0, a->psnr / n,
           a->emean / n, a->empty / n, a->max_steps);
    fprintf(csv, "%s,%s,%d,%d,%d,%d,%.2f,%.2f,%.2f,%.2f,%.2f,%.3f,%.3f,%.4f,%.4f,%.5f,%.5f,%.2f,%lld\n", table,
                method, w, h, imp, a->n, a->build / n, a->total / n, a->mn, a->mx, a->reflect / n,
                rt_avg > 0 ? (a->total / n) / rt_avg : 0.0, a->psnr / n, a->emean / n, a->ep95 / n, a->wrong / n,
                a->empty / n, a->rays ? (double)a->steps / (double)a->rays : 0.0, a->max_steps);
}

/* Renders d into f, 0 on failure (said). */
static int sp_render(const refl_scene *s, const refl_view *v, const refl_render_desc *d, refl_frame *f) {
    refl_result r = refl_render(s, v, d, f);
    if (r != REFL_OK) fprintf(stderr, "reflect bench: %s on teapots: %s\n", refl_method_name(d->method), refl_result_string(r));
    return r == REFL_OK;
}

int refl_bench_spoc(const char *dir, int threads) {
    refl_scene *s = NULL;
    refl_embree *emb = NULL;
    refl_frame *truth = NULL, *f = NULL;
    char path[1024], err[256];
    FILE *csv;
    int i, k, ok = 1;
    if (refl_scene_builtin("teapots", NULL, &s) != REFL_OK) {
        fprintf(stderr, "reflect bench: the teapots scene could not be built\n");
        return 0;
    }
    emb = refl_embree_create(s, threads, err, sizeof err);
    if (!emb) {
        fprintf(stderr, "reflect bench: Embree: %s\n", err);
        refl_scene_destroy(s);
        return 0;
    }
    snprintf(path, sizeof path, "%s/spoc_teapots.csv", dir);
    if (!(csv = fopen(path, "w"))) {
        fprintf(stderr, "reflect bench: cannot write %s\n", path);
        refl_embree_destroy(emb);
        refl_scene_destroy(s);
        return 0;
    }
    fprintf(csv, "table,method,width,height,impostor,frames,construct_ms_avg,frame_ms_avg,frame_ms_min,frame_ms_max,"
                 "reflect_ms_avg,time_over_raytrace,psnr_db,error_px_mean,error_px_p95,wrong,empty,steps_per_ray,"
                 "max_steps\n");
    printf("teapots (paper 004 Tables 1 and 2), %d frames along a path, one bounce, %s threads\n", SP_FRAMES,
           threads ? "given" : "all");
    printf("%-6s %-9s %9s %8s %9s %9s %8s %8s %7s %8s %8s %7s %9s\n", "table", "method", "output", "impostor",
           "construct", "frame avg", "min", "max", "/ RT", "PSNR", "err px", "empty", "max steps");
    /* Table 1: output sizes; Table 2 shares the 640x480 path (i == 0) */
    for (i = 0; ok && i < SP_SIZES; ++i) {
        int w = sp_out_w[i], h = sp_out_h[i], j;
        sp_acc rt, em, sp[SP_SIZES];
        memset(&rt, 0, sizeof rt);
        memset(&em, 0, sizeof em);
        memset(sp, 0, sizeof sp);
        refl_frame_destroy(truth);
        refl_frame_destroy(f);
        truth = f = NULL;
        if (refl_frame_create(w, h, NULL, &truth) != REFL_OK || refl_frame_create(w, h, NULL, &f) != REFL_OK) {
            ok = 0;
            break;
        }
        for (k = 0; ok && k < SP_FRAMES; ++k) {
            refl_view v = sp_view(s, k, w, h);
            refl_render_desc d;
            memset(&d, 0, sizeof d);
            d.threads = threads;
            d.depth = 1;
            d.method = REFL_RAYTRACE;
            ok = sp_render(s, &v, &d, truth);
            if (ok) sp_add(&rt, truth, NULL);
            d.raytrace.caster.intersect = refl_embree_intersect;
            d.raytrace.caster.occluded = refl_embree_occluded;
            d.raytrace.caster.user = emb;
            ok = ok && sp_render(s, &v, &d, f);
            if (ok) sp_add(&em, f, NULL);
            memset(&d.raytrace, 0, sizeof d.raytrace);
            d.method = REFL_SPOC;
            d.spoc.layers = 1; /* the paper's impostor: one depth layer */
            for (j = 0; ok && j < SP_SIZES; ++j) {
                if (i > 0 && sp_imp[j] != 512) continue;
                d.spoc.size = sp_imp[j];
                ok = sp_render(s, &v, &d, f);
                if (ok) sp_add(&sp[j], f, truth);
            }
        }
        if (!ok) break;
        {
            double rt_avg = rt.total / SP_FRAMES;
            sp_row(csv, i ? "1" : "1,2", "raytrace", w, h, 0, &rt, rt_avg);
            sp_row(csv, i ? "1" : "1,2", "embree", w, h, 0, &em, rt_avg);
            for (j = 0; j < SP_SIZES; ++j)
                if (sp[j].n) sp_row(csv, sp_imp[j] == 512 ? (i ? "1" : "1,2") : "2", "spoc", w, h, sp_imp[j], &sp[j], rt_avg);
        }
        fflush(stdout);
    }
    if (ok) {
        printf("\npaper, Table 1 (fps avg / min / max):");
        for (i = 0; i < SP_SIZES; ++i)
            printf("  %dx%d %.1f / %.0f / %.0f", sp_out_w[i], sp_out_h[i], sp_paper_t1[0][i], sp_paper_t1[1][i],
                   sp_paper_t1[2][i]);
        printf("\npaper, Table 2 (640x480; fps, max ray projection px):");
        for (i = 0; i < SP_SIZES; ++i) printf("  %d: %.1f, %d", sp_imp[i], sp_paper_t2_fps[i], sp_paper_t2_len[i]);
        printf("\n");
    }
    fclose(csv);
    if (ok) fprintf(stderr, "wrote %s\n", path);
    refl_frame_destroy(truth);
    refl_frame_destroy(f);
    refl_embree_destroy(emb);
    refl_scene_destroy(s);
    return ok;
}
