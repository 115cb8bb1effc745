/* reflect bench --only spoc: paper 004's Tables 1 and 2 on the built-in
   two-teapot scene, the paper's way: frame times (average, min, max) along
   a 60-frame camera path. Table 1: output 640x480 to 1280x1024 with a
   512-texel impostor; Table 2: impostor 128 to 1024 texels at 640x480, with
   the longest ray projection (marching steps of one ray through one
   impostor). Beside each SPOC row, RAYTRACE (ours and Embree's) on the same
   frames, and the reflection error and PSNR over the mirror against
   RAYTRACE, which the paper does not report. One bounce and one depth
   layer (spoc.layers 1), as the paper's reflections and impostors. A table on stdout (the paper's rows beside ours) and
   dir/spoc_teapots.csv. reflect bench --only spoc-sweeps: the stability
   sweeps at the end of this file. */
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

/* ---- reflect bench --only spoc-sweeps: where paper 004 says impostors fail ----

   The teapots at 160x120, one bounce (two through glass), each setting
   against RAYTRACE of the same scene and view: the camera orbiting the
   teapots' midpoint in azimuth (the mirror's rays that reach the diffuse
   teapot leave it further and further from its centre, at grazing angles,
   so they meet the impostor from directions far from its reference
   direction, reflector centre to object centre), the diffuse teapot moved
   towards the mirror until they touch and overlap, the impostor's size,
   and the mirror teapot replaced by a glass sphere flattened along z (the
   view's axis) to a thin lens. SPOC with its defaults but the swept
   setting; GRAPHCAM (its one-frustum view camera, the only graph camera
   this scene has) beside it where its camera applies: the orbit and the
   touching teapots. Per row the reflection error, PSNR over the mirror,
   the pixels RAYTRACE's tracer drew for the impostor, the march steps and
   the frame time, and the count of non-finite colour channels, which must
   be 0 (the bench fails otherwise). A table on stdout and
   dir/spoc_sweeps.csv. */

enum { SW_W = 160, SW_H = 120 };

static int sw_object(const refl_scene *s, const char *name) {
    int i;
    for (i = 0; i < s->object_count; ++i)
        if (!strcmp(s->objects[i].name, name)) return i;
    return -1;
}

/* The object's world vertices (malloc; count in *n), NULL on failure. */
static float *sw_positions(const refl_scene *s, int object, int *n) {
    float *p;
    *n = refl_object_world_positions(s, object, NULL);
    if (*n <= 0 || !(p = (float *)malloc(3 * sizeof(float) * (size_t)*n))) return NULL;
    refl_object_world_positions(s, object, p);
    return p;
}

static void sw_box(const float *p, int n, refl_vec3 *lo, refl_vec3 *hi) {
    int k;
    *lo = refl_v3(1e30f, 1e30f, 1e30f);
    *hi = refl_v3(-1e30f, -1e30f, -1e30f);
    for (k = 0; k < n; ++k) {
        lo->x = fminf(lo->x, p[3 * k]); lo->y = fminf(lo->y, p[3 * k + 1]); lo->z = fminf(lo->z, p[3 * k + 2]);
        hi->x = fmaxf(hi->x, p[3 * k]); hi->y = fmaxf(hi->y, p[3 * k + 1]); hi->z = fmaxf(hi->z, p[3 * k + 2]);
    }
}

static refl_vec3 sw_centre(const float *p, int n) {
    refl_vec3 lo, hi;
    sw_box(p, n, &lo, &hi);
    return refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
}

/* The least distance between a vertex of a (moved by shift) and one of b:
   about the meshes' gap, 0 where they touch or overlap. */
static float sw_gap(const float *a, int na, refl_vec3 shift, const float *b, int nb) {
    float best = 1e30f;
    int i, j;
    for (i = 0; i < na; ++i) {
        float x = a[3 * i] + shift.x, y = a[3 * i + 1] + shift.y, z = a[3 * i + 2] + shift.z;
        for (j = 0; j < nb; ++j) {
            float dx = x - b[3 * j], dy = y - b[3 * j + 1], dz = z - b[3 * j + 2], d = dx * dx + dy * dy + dz * dz;
            best = d < best ? d : best;
        }
    }
    return sqrtf(best);
}

/* How far the truth's query rays are from the SPOC's reference direction
   (the mirror's box centre to the diffuse teapot's): over the mirror
   pixels whose true reflected point lies on the diffuse teapot, the mean
   and largest angle in degrees between that direction and the ray from
   the mirror's surface (the pixel's view ray met through a BVH) to the
   point. 0 pixels: both -1. */
static void sw_query_angles(const refl_scene *s, const refl_view *v, const refl_frame *truth, int mirror, int diffuse,
                            double *mean, double *max) {
    refl_bvh *bvh = NULL;
    float *mp, *dp;
    int nm, nd, x, y;
    long long n = 0;
    refl_vec3 lo, hi, ref;
    *mean = *max = -1.0;
    mp = sw_positions(s, mirror, &nm);
    dp = sw_positions(s, diffuse, &nd);
    if (mp && dp && refl_bvh_build(s, NULL, &bvh) == REFL_OK) {
        sw_box(dp, nd, &lo, &hi);
        ref = refl_v3_normalize(refl_v3_sub(sw_centre(dp, nd), sw_centre(mp, nm)));
        *mean = 0.0;
        for (y = 0; y < truth->height; ++y)
            for (x = 0; x < truth->width; ++x) {
                size_t i = (size_t)y * (size_t)truth->width + (size_t)x;
                const float *p = truth->points + 3 * i;
                refl_vec3 o, dir, q;
                refl_hit hit;
                float tmax;
                double a;
                if (truth->stencil[i] != mirror + 1 || !isfinite(p[0]) || p[0] < lo.x - 0.01f || p[0] > hi.x + 0.01f ||
                    p[1] < lo.y - 0.01f || p[1] > hi.y + 0.01f || p[2] < lo.z - 0.01f || p[2] > hi.z + 0.01f)
                    continue;
                refl_view_ray(v, s, (float)x + 0.5f, (float)y + 0.5f, &o, &dir, &tmax);
                if (!refl_bvh_intersect(bvh, o, dir, 0.0f, tmax, &hit) || hit.object != mirror) continue;
                q = refl_v3_add(o, refl_v3_scale(dir, hit.t)); /* on the mirror */
                q = refl_v3_normalize(refl_v3_sub(refl_v3(p[0], p[1], p[2]), q));
                a = acos(fmax(-1.0, fmin(1.0, (double)refl_v3_dot(q, ref)))) * 180.0 / 3.14159265358979;
                *mean += a;
                *max = a > *max ? a : *max;
                ++n;
            }
        *mean = n ? *mean / (double)n : -1.0;
    }
    refl_bvh_destroy(bvh);
    free(mp);
    free(dp);
}

/* Renders one setting and its row; 0 on failure or a non-finite pixel. */
static int sw_row(FILE *csv, const char *sweep, const char *setting, const double angle[2], const refl_scene *s,
                  const refl_view *v, const refl_render_desc *d, const refl_frame *truth, refl_frame *f) {
    refl_reflection_error re;
    refl_image_error ie;
    long long bad = 0, k, traced, steps, max_steps;
    const char *name = d->method != REFL_SPOC                          ? refl_method_name(d->method)
                       : d->spoc.glass == REFL_SPOC_GLASS_EXACT_EXIT ? "spoc-exact"
                       : d->spoc.glass == REFL_SPOC_GLASS_ESTIMATE   ? "spoc-est"
                       : d->spoc.layers == 1                         ? "spoc-1lay"
                                                                     : "spoc";
    if (!sp_render(s, v, d, f)) return 0;
    for (k = 0; k < 4LL * f->width * f->height; ++k) bad += !isfinite(f->rgba[k]);
    if (refl_measure_reflection_error(f, truth, NULL, &re) != REFL_OK ||
        refl_measure_image_error(f, truth, 1, 2.0f / 255.0f, &ie) != REFL_OK)
        return 0;
    if (d->method == REFL_SPOC) {
        traced = f->stats.spoc.traced;
        steps = f->stats.spoc.steps;
        max_steps = f->stats.spoc.max_steps;
    } else {
        traced = f->stats.graphcam.traced;
        steps = f->stats.graphcam.steps;
        max_steps = f->stats.graphcam.max_steps;
    }
    {
        double psnr = isfinite(ie.psnr) ? ie.psnr : 99.0;
        long long imps = f->stats.spoc.impostors;
        printf("%-10s %-20s %5.0f %5.0f %-10s %7.3f %7.2f %7.4f %7.4f %6.2f %6lld %9lld %6lld %5lld %8.1f %4lld\n",
               sweep, setting, angle[0], angle[1], name, re.mean, re.p95, re.wrong, re.empty, psnr, traced, steps,
               max_steps, imps, f->stats.ms_total, bad);
        fprintf(csv, "%s,%s,%.2f,%.2f,%s,%.4f,%.4f,%.5f,%.5f,%.3f,%lld,%lld,%lld,%lld,%.2f,%lld\n", sweep, setting,
                angle[0], angle[1], name, re.mean, re.p95, re.wrong, re.empty, psnr, traced, steps, max_steps, imps,
                f->stats.ms_total, bad);
    }
    fflush(stdout);
    if (bad) fprintf(stderr, "reflect bench: %s %s %s: %lld non-finite channels\n", sweep, setting, name, bad);
    return !bad;
}

/* RAYTRACE's truth for s and v, the query rays' angles to the reference
   (-1 where the mirror teapot is not a mirror), then each desc of ds. */
static int sw_rows(FILE *csv, const char *sweep, const char *setting, const refl_scene *s, const refl_view *v,
                   const refl_render_desc *ds, int count, int mirror, int diffuse, refl_frame *truth, refl_frame *f) {
    refl_render_desc rt = ds[0];
    double angle[2] = {-1.0, -1.0};
    int i, ok;
    rt.method = REFL_RAYTRACE;
    ok = sp_render(s, v, &rt, truth);
    if (ok && s->materials[s->objects[mirror].material].type == REFL_MIRROR)
        sw_query_angles(s, v, truth, mirror, diffuse, &angle[0], &angle[1]);
    for (i = 0; ok && i < count; ++i) ok = sw_row(csv, sweep, setting, angle, s, v, &ds[i], truth, f);
    return ok;
}

int refl_bench_spoc_sweeps(const char *dir, int threads) {
    static const float azimuths[] = {-120, -90, -60, -30, 0, 30, 60, 90, 120, 180};
    static const int sizes[] = {32, 64, 128, 256, 512, 1024};
    static const float thickness[] = {1.0f, 0.5f, 0.25f, 0.1f, 0.03f};
    refl_scene *s = NULL;
    refl_frame *truth = NULL, *f = NULL;
    refl_render_desc ds[3];
    refl_view v;
    char path[1024], setting[64];
    float *mp = NULL, *dp = NULL;
    int mirror, diffuse, nm = 0, nd = 0, ok = 1;
    size_t i;
    FILE *csv;
    if (refl_scene_builtin("teapots", NULL, &s) != REFL_OK) {
        fprintf(stderr, "reflect bench: the teapots scene could not be built\n");
        return 0;
    }
    mirror = sw_object(s, "mirror teapot");
    diffuse = sw_object(s, "diffuse teapot");
    snprintf(path, sizeof path, "%s/spoc_sweeps.csv", dir);
    if (mirror < 0 || diffuse < 0 || !(mp = sw_positions(s, mirror, &nm)) || !(dp = sw_positions(s, diffuse, &nd)) ||
        refl_frame_create(SW_W, SW_H, NULL, &truth) != REFL_OK || refl_frame_create(SW_W, SW_H, NULL, &f) != REFL_OK ||
        !(csv = fopen(path, "w"))) {
        fprintf(stderr, "reflect bench: the SPOC sweeps could not start (%s)\n", path);
        free(mp);
        free(dp);
        refl_frame_destroy(truth);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
        return 0;
    }
    fprintf(csv, "sweep,setting,query_deg_mean,query_deg_max,method,error_px_mean,error_px_p95,wrong,empty,psnr_db,"
                 "traced,steps,max_steps,impostors,"
                 "frame_ms,nonfinite\n");
    printf("teapots %dx%d, against RAYTRACE of the same scene and view, %s threads\n", SW_W, SW_H,
           threads ? "given" : "all");
    printf("%-10s %-20s %5s %5s %-10s %7s %7s %7s %7s %6s %6s %9s %6s %5s %8s %4s\n", "sweep", "setting", "ray", "max",
           "method", "mean px",
           "p95 px", "wrong", "empty", "PSNR", "traced", "steps", "max", "imps", "ms", "NaN");
    memset(ds, 0, sizeof ds);
    ds[0].threads = ds[1].threads = ds[2].threads = threads;
    ds[0].depth = ds[1].depth = ds[2].depth = 1;
    ds[0].method = ds[1].method = REFL_SPOC;
    ds[1].spoc.layers = 1; /* the paper's impostor */
    ds[2].method = REFL_GRAPHCAM;
    /* 1. the camera orbiting the teapots' midpoint (sp_view's centre) */
    for (i = 0; ok && i < sizeof azimuths / sizeof *azimuths; ++i) {
        refl_vec3 c = refl_v3(-0.05f, 0.4f, 0.65f), off;
        float a = azimuths[i] * 3.14159265f / 180.0f;
        v = s->camera;
        off = refl_v3_sub(v.eye, c);
        v.eye = refl_v3_add(c, refl_v3(cosf(a) * off.x + sinf(a) * off.z, off.y, -sinf(a) * off.x + cosf(a) * off.z));
        v.target = c;
        v.width = SW_W;
        v.height = SW_H;
        snprintf(setting, sizeof setting, "azimuth %+.0f", azimuths[i]);
        ok = sw_rows(csv, "orbit", setting, s, &v, ds, 3, mirror, diffuse, truth, f);
    }
    v = s->camera;
    v.width = SW_W;
    v.height = SW_H;
    /* 2. the diffuse teapot moved towards the mirror: its original place,
       two steps, touching (the first 0.02 step whose vertex gap is under
       0.02) and 0.1, 0.2 and 0.3 past it, overlapping */
    if (ok) {
        refl_mat4 original = s->objects[diffuse].transform;
        refl_vec3 towards = refl_v3_sub(sw_centre(mp, nm), sw_centre(dp, nd)), shift;
        float touch = 0.0f, moves[7];
        int j;
        towards.y = 0.0f;
        towards = refl_v3_normalize(towards);
        while (touch < 5.0f && sw_gap(dp, nd, refl_v3_scale(towards, touch), mp, nm) > 0.02f) touch += 0.02f;
        moves[0] = 0.0f;
        moves[1] = 0.4f * touch;
        moves[2] = 0.8f * touch;
        moves[3] = touch;
        moves[4] = touch + 0.1f;
        moves[5] = touch + 0.2f;
        moves[6] = touch + 0.3f;
        for (j = 0; ok && j < 7; ++j) {
            shift = refl_v3_scale(towards, moves[j]);
            s->objects[diffuse].transform = refl_mat4_mul(refl_mat4_translate(shift), original);
            snprintf(setting, sizeof setting, "moved %.2f (%+.2f)", moves[j], moves[j] - touch);
            ok = sw_rows(csv, "touching", setting, s, &v, ds, 3, mirror, diffuse, truth, f);
        }
        s->objects[diffuse].transform = original;
    }
    /* 3. the impostor's size */
    for (i = 0; ok && i < sizeof sizes / sizeof *sizes; ++i) {
        ds[0].spoc.size = ds[1].spoc.size = sizes[i];
        snprintf(setting, sizeof setting, "size %d", sizes[i]);
        ok = sw_rows(csv, "impostor", setting, s, &v, ds, 2, mirror, diffuse, truth, f);
    }
    ds[0].spoc.size = ds[1].spoc.size = 0;
    /* 4. a thin refractor: the mirror teapot turned into a glass sphere of
       its height, flattened along z, both glass modes, two bounces */
    if (ok) {
        refl_mesh *sphere = NULL;
        refl_vec3 c = sw_centre(mp, nm), lo, hi;
        refl_material *m;
        int mesh;
        refl_mesh_bounds(s->meshes[s->objects[mirror].mesh], &lo, &hi);
        ok = refl_mesh_sphere(0.25f * (hi.y - lo.y), 96, 48, NULL, &sphere) == REFL_OK &&
             (mesh = refl_scene_add_mesh(s, sphere)) >= 0;
        if (ok) {
            s->objects[mirror].mesh = mesh;
            m = &s->materials[s->objects[mirror].material];
            m->type = REFL_GLASS;
            m->ior = 1.5f;
            m->fresnel = 1;
        }
        ds[0].depth = ds[1].depth = 2;
        ds[0].spoc.size = ds[1].spoc.size = 256;
        ds[0].spoc.glass = REFL_SPOC_GLASS_EXACT_EXIT;
        ds[1].spoc.layers = 0;
        ds[1].spoc.glass = REFL_SPOC_GLASS_ESTIMATE;
        for (i = 0; ok && i < sizeof thickness / sizeof *thickness; ++i) {
            s->objects[mirror].transform =
                refl_mat4_mul(refl_mat4_translate(c), refl_mat4_scale(refl_v3(1.0f, 1.0f, thickness[i])));
            snprintf(setting, sizeof setting, "z scale %.2f", thickness[i]);
            ok = sw_rows(csv, "thin glass", setting, s, &v, ds, 2, mirror, diffuse, truth, f);
        }
    }
    fclose(csv);
    if (ok) fprintf(stderr, "wrote %s\n", path);
    free(mp);
    free(dp);
    refl_frame_destroy(truth);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    return ok;
}
