/* reflect bench --only path: a camera path through the default scene, each
   frame rendered twice: by refl_render (everything built for the frame)
   and by one refl_renderer kept along the path (the thread pool, the BVH
   and C3RC's points and kd-tree built once). Both give the same bytes; the
   table says what keeping the models saves per frame. */
#include <stdio.h>
#include <string.h>
#include <math.h>

#include "reflect_bench.h"

enum { PATH_FRAMES = 30 };

typedef struct path_method {
    const char *name;
    refl_method method;
    float density;               /* C3RC: set, so both renderings sample alike */
    int trace_fallback;
} path_method;

static const path_method path_methods[] = {
    {"raytrace", REFL_RAYTRACE, 0.0f, 0},
    {"c3rc-d250", REFL_C3RC, 250.0f, 0},
    {"sbc", REFL_SBC, 0.0f, 0},
    {"sbc-fallback", REFL_SBC, 0.0f, 1},
};

/* Frame k of 30: a quarter orbit around the scene camera's target. */
static refl_view path_view(const refl_scene *s, int k, int w, int h) {
    refl_view v = s->camera;
    refl_vec3 off = refl_v3_sub(v.eye, v.target);
    float a = (float)(0.5 * 3.14159265358979 * k / (PATH_FRAMES - 1)), c = cosf(a), sn = sinf(a);
    v.eye = refl_v3_add(v.target, refl_v3(c * off.x + sn * off.z, off.y, -sn * off.x + c * off.z));
    v.width = w;
    v.height = h;
    return v;
}

typedef struct path_result {
    double ms[PATH_FRAMES];       /* wall time per frame, refl_render or refl_renderer_render */
    double build_ms[PATH_FRAMES]; /* stats.ms_build */
    int models;                   /* scene-wide models built over the path */
    unsigned long long digest;    /* of every frame's colour */
} path_result;

static unsigned long long fnv(unsigned long long h, const uint8_t *p, size_t n) {
    size_t i;
    for (i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001B3ull;
    return h;
}

static int run_path(const refl_scene *s, const refl_render_desc *d, int keep, int w, int h, path_result *out) {
    refl_renderer *rr = NULL;
    refl_frame *f = NULL;
    refl_result r = refl_frame_create(w, h, NULL, &f);
    int k;
    memset(out, 0, sizeof *out);
    out->digest = 0xCBF29CE484222325ull;
    if (r == REFL_OK && keep) r = refl_renderer_create(s, d, &rr);
    for (k = 0; r == REFL_OK && k < PATH_FRAMES; ++k) {
        refl_view v = path_view(s, k, w, h);
        double t0 = refl_bench_now_ms();
        r = keep ? refl_renderer_render(rr, &v, f) : refl_render(s, &v, d, f);
        out->ms[k] = refl_bench_now_ms() - t0;
        out->build_ms[k] = f->stats.ms_build;
        out->models += f->stats.scene_models_built;
        out->digest = fnv(out->digest, (const uint8_t *)f->rgba, (size_t)w * (size_t)h * 4 * sizeof(float));
    }
    if (r != REFL_OK) fprintf(stderr, "reflect bench: path with %s: %s\n", refl_method_name(d->method),
                              refl_result_string(r));
    refl_renderer_destroy(rr);
    refl_frame_destroy(f);
    return r == REFL_OK;
}

static double mean_of(const double *v, int n) {
    double sum = 0.0;
    int i;
    for (i = 0; i < n; ++i) sum += v[i];
    return n ? sum / n : 0.0;
}

int refl_bench_path(const char *dir, int threads) {
    char path[1024];
    refl_scene *s = NULL;
    FILE *fp;
    const int w = 640, h = 480;
    size_t m;
    int ok = 1;
    if (refl_scene_builtin("default", NULL, &s) != REFL_OK) return 0;
    snprintf(path, sizeof path, "%s/path.csv", dir);
    if (!(fp = fopen(path, "w"))) {
        fprintf(stderr, "reflect bench: cannot write %s\n", path);
        refl_scene_destroy(s);
        return 0;
    }
    fprintf(fp, "method,mode,width,height,frames,threads,first_ms,median_ms,mean_ms,mean_build_ms,models_built\n");
    printf("\nCamera path: default scene, %dx%d, %d frames (a quarter orbit), %s threads; per frame ms\n", w, h,
           PATH_FRAMES, threads ? "given" : "all");
    printf("%-13s %-9s %9s %9s %9s %9s %7s\n", "method", "mode", "first", "median", "mean", "build", "models");
    for (m = 0; ok && m < sizeof path_methods / sizeof path_methods[0]; ++m) {
        const path_method *pm = &path_methods[m];
        path_result res[2];
        refl_render_desc d;
        int keep;
        memset(&d, 0, sizeof d);
        d.method = pm->method;
        d.threads = threads;
        d.depth = 1;
        d.c3rc.point_density = pm->density;
        d.sbc.trace_fallback = pm->trace_fallback;
        for (keep = 0; ok && keep < 2; ++keep) {
            const char *mode = keep ? "renderer" : "rebuild";
            double sorted[PATH_FRAMES - 1], median, mean, build;
            ok = run_path(s, &d, keep, w, h, &res[keep]);
            if (!ok) break;
            /* the steady state: every frame after the first */
            memcpy(sorted, res[keep].ms + 1, sizeof sorted);
            median = refl_bench_median(sorted, PATH_FRAMES - 1);
            mean = mean_of(res[keep].ms + 1, PATH_FRAMES - 1);
            build = mean_of(res[keep].build_ms + 1, PATH_FRAMES - 1);
            printf("%-13s %-9s %9.1f %9.1f %9.1f %9.1f %7d\n", pm->name, mode, res[keep].ms[0], median, mean, build,
                   res[keep].models);
            fprintf(fp, "%s,%s,%d,%d,%d,%d,%.3f,%.3f,%.3f,%.3f,%d\n", pm->name, mode, w, h, PATH_FRAMES, threads,
                    res[keep].ms[0], median, mean, build, res[keep].models);
        }
        if (ok && res[0].digest != res[1].digest) {
            fprintf(stderr, "reflect bench: %s: the renderer's frames differ from refl_render's\n", pm->name);
            ok = 0;
        }
    }
    printf("(first: frame 0; median, mean and build: frames 1 to %d; build: stats.ms_build; models: scene-wide "
           "models built over the path)\n",
           PATH_FRAMES - 1);
    if (fclose(fp) != 0) ok = 0;
    refl_scene_destroy(s);
    return ok;
}
