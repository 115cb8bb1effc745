/* reflect bench --only graphcam: paper 004's maze (section 6.2) through its
   graph camera: per method, along a short camera path around the mirror
   sphere at 640x480, the impostor's construction time, the frame time
   (average, min, max) and the reflection error and PSNR against RAYTRACE
   of the same frame (which the paper does not report), with both of the
   paper's intersection algorithms, ENVMAP and RAYTRACE (ours and Embree's)
   in the same run; then the step-count sweep the issue asks for (each
   algorithm at a finer and a coarser step than its default, 960 x 588).
   Per row also the share of the mirror's rays the impostor could not
   answer, which RAYTRACE's tracer drew. A table on stdout and
   dir/graphcam_maze.csv. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../bench/embree_peer.h"
#include "reflect_bench.h"

enum { GC_FRAMES = 8 };

typedef struct gc_method {
    const char *name;
    refl_method method;
    int algorithm, size, embree;  /* GRAPHCAM: algorithm, impostor width (0: none, the view's) */
    float step;                   /* GRAPHCAM: 0 the default (SEGMENTS: 1 pixel; UNIFORM: bounds / 2048) */
} gc_method;

static const gc_method gc_methods[] = {
    {"raytrace", REFL_RAYTRACE, 0, 0, 0, 0.0f},
    {"embree", REFL_RAYTRACE, 0, 0, 1, 0.0f},
    {"envmap-256", REFL_ENVMAP, 0, 0, 0, 0.0f},
    {"graphcam-view", REFL_GRAPHCAM, REFL_GRAPHCAM_SEGMENTS, 0, 0, 0.0f},
    {"graphcam-alg2", REFL_GRAPHCAM, REFL_GRAPHCAM_SEGMENTS, 1920, 0, 0.0f},
    {"graphcam-alg1", REFL_GRAPHCAM, REFL_GRAPHCAM_UNIFORM, 1920, 0, 0.0f},
    {"graphcam-alg2-960", REFL_GRAPHCAM, REFL_GRAPHCAM_SEGMENTS, 960, 0, 0.0f},
    /* the step sweep */
    {"alg2-960-step0.25", REFL_GRAPHCAM, REFL_GRAPHCAM_SEGMENTS, 960, 0, 0.25f},
    {"alg2-960-step4", REFL_GRAPHCAM, REFL_GRAPHCAM_SEGMENTS, 960, 0, 4.0f},
    {"alg1-960-step0.004", REFL_GRAPHCAM, REFL_GRAPHCAM_UNIFORM, 960, 0, 0.004f},
    {"alg1-960-step0.1", REFL_GRAPHCAM, REFL_GRAPHCAM_UNIFORM, 960, 0, 0.1f},
};

/* Frame k: the scene camera turned about the mirror sphere by -12..12 degrees. */
static refl_view gc_view(const refl_scene *s, int k) {
    refl_view v = s->camera;
    refl_vec3 c = refl_v3(0.3f, 0.5f, -1.6f), off = refl_v3_sub(v.eye, c);
    float a = (float)((-12.0 + 24.0 * k / (GC_FRAMES - 1)) * 3.14159265358979 / 180.0), co = cosf(a), sn = sinf(a);
    v.eye = refl_v3_add(c, refl_v3(co * off.x + sn * off.z, off.y, -sn * off.x + co * off.z));
    v.width = 640;
    v.height = 480;
    return v;
}

int refl_bench_graphcam(const char *dir, int threads) {
    refl_scene *s = NULL;
    refl_graphcam *cams = calloc(2, sizeof(refl_graphcam));
    refl_frame *truth[GC_FRAMES], *f = NULL;
    refl_embree *emb = NULL;
    char path[1024], err[256];
    FILE *csv;
    int i, k, ok = 1;
    memset(truth, 0, sizeof truth);
    if (!cams || refl_scene_builtin("maze", NULL, &s) != REFL_OK || refl_graphcam_maze(&cams[0], 1920, 1176) != REFL_OK ||
        refl_graphcam_maze(&cams[1], 960, 588) != REFL_OK || refl_frame_create(640, 480, NULL, &f) != REFL_OK) {
        fprintf(stderr, "reflect bench: the maze could not be set up\n");
        free(cams);
        refl_scene_destroy(s);
        return 0;
    }
    snprintf(path, sizeof path, "%s/graphcam_maze.csv", dir);
    csv = fopen(path, "w");
    if (!csv) {
        fprintf(stderr, "reflect bench: cannot write %s\n", path);
        ok = 0;
    } else {
        fprintf(csv, "method,impostor_width,frames,construct_ms_avg,frame_ms_avg,frame_ms_min,frame_ms_max,"
                     "reflect_ms_avg,psnr_db,error_px_mean,error_px_p95,wrong,empty,traced,steps_per_ray,max_steps\n");
    }
    printf("maze (paper 004 section 6.2), 640x480, %d frames around the mirror sphere, %s threads\n", GC_FRAMES,
           threads ? "given" : "all");
    printf("%-18s %9s %10s %10s %8s %8s %8s %8s %9s %6s %6s %7s %9s\n", "method", "impostor", "construct", "frame avg",
           "min", "max", "reflect", "PSNR", "err px", "empty", "traced", "steps", "max steps");
    for (k = 0; ok && k < GC_FRAMES; ++k) {
        refl_view v = gc_view(s, k);
        refl_render_desc d;
        memset(&d, 0, sizeof d);
        d.method = REFL_RAYTRACE;
        d.threads = threads;
        d.depth = 1;
        if (refl_frame_create(640, 480, NULL, &truth[k]) != REFL_OK || refl_render(s, &v, &d, truth[k]) != REFL_OK) ok = 0;
    }
    for (i = 0; ok && i < (int)(sizeof gc_methods / sizeof gc_methods[0]); ++i) {
        const gc_method *m = &gc_methods[i];
        double build = 0, total = 0, mn = 1e30, mx = 0, refl = 0, psnr = 0, emean = 0, ep95 = 0, wrong = 0, empty = 0;
        long long steps = 0, rays = 0, max_steps = 0, traced = 0;
        for (k = 0; ok && k < GC_FRAMES; ++k) {
            refl_view v = gc_view(s, k);
            refl_render_desc d;
            refl_image_error ie;
            refl_reflection_error re;
            memset(&d, 0, sizeof d);
            d.method = m->method;
            d.threads = threads;
            d.depth = 1;
            d.graphcam.algorithm = m->algorithm;
            d.graphcam.step = m->step;
            d.graphcam.camera = m->size == 1920 ? &cams[0] : m->size == 960 ? &cams[1] : NULL;
            if (m->embree) {
                if (!emb) emb = refl_embree_create(s, threads, err, sizeof err);
                if (!emb) {
                    fprintf(stderr, "reflect bench: Embree: %s\n", err);
                    ok = 0;
                    break;
                }
                d.raytrace.caster.intersect = refl_embree_intersect;
                d.raytrace.caster.occluded = refl_embree_occluded;
                d.raytrace.caster.user = emb;
            }
            if (refl_render(s, &v, &d, f) != REFL_OK || refl_measure_image_error(f, truth[k], 1, 2.0f / 255.0f, &ie) != REFL_OK ||
                refl_measure_reflection_error(f, truth[k], NULL, &re) != REFL_OK) {
                fprintf(stderr, "reflect bench: %s on the maze failed\n", m->name);
                ok = 0;
                break;
            }
            build += f->stats.ms_build;
            total += f->stats.ms_total;
            mn = f->stats.ms_total < mn ? f->stats.ms_total : mn;
            mx = f->stats.ms_total > mx ? f->stats.ms_total : mx;
            refl += f->stats.ms_reflect;
            psnr += isfinite(ie.psnr) ? ie.psnr : 99.0;
            emean += re.mean;
            ep95 += re.p95;
            wrong += re.wrong;
            empty += re.empty;
            steps += f->stats.graphcam.steps;
            rays += f->stats.graphcam.rays;
            traced += f->stats.graphcam.traced;
            if (f->stats.graphcam.max_steps > max_steps) max_steps = f->stats.graphcam.max_steps;
        }
        if (!ok) break;
        printf("%-18s %9d %10.1f %10.1f %8.1f %8.1f %8.1f %8.2f %9.3f %6.3f %6.3f %7.1f %9lld\n", m->name,
               m->method == REFL_GRAPHCAM ? (m->size ? m->size : 1280) : 0, build / GC_FRAMES, total / GC_FRAMES, mn, mx,
               refl / GC_FRAMES, psnr / GC_FRAMES, emean / GC_FRAMES, empty / GC_FRAMES,
               rays ? (double)traced / (double)rays : 0.0, rays ? (double)steps / (double)rays : 0.0, max_steps);
        fprintf(csv, "%s,%d,%d,%.2f,%.2f,%.2f,%.2f,%.2f,%.3f,%.4f,%.4f,%.5f,%.5f,%.5f,%.2f,%lld\n", m->name,
                m->method == REFL_GRAPHCAM ? (m->size ? m->size : 1280) : 0, GC_FRAMES, build / GC_FRAMES,
                total / GC_FRAMES, mn, mx, refl / GC_FRAMES, psnr / GC_FRAMES, emean / GC_FRAMES, ep95 / GC_FRAMES,
                wrong / GC_FRAMES, empty / GC_FRAMES, rays ? (double)traced / (double)rays : 0.0,
                rays ? (double)steps / (double)rays : 0.0, max_steps);
    }
    if (csv) fclose(csv);
    if (ok) fprintf(stderr, "wrote %s\n", path);
    for (k = 0; k < GC_FRAMES; ++k) refl_frame_destroy(truth[k]);
    refl_embree_destroy(emb);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    free(cams);
    return ok;
}
