/* reflect path: every method along a camera path, against RAYTRACE at the
   same depth: per frame its time, reflection error and PSNR over the
   reflectors, and its flicker (refl_measure_flicker: how much more its
   reflector pixels change from frame to frame than the truth's do). Each
   method renders through one renderer kept along the path, as an
   application would. Writes DIR/PATH.csv, a summary table on stdout (the
   worst frame of each method, and the frames where it pops), and with
   --images the numbered frames DIR/METHOD-0000.png ... for a video.

   A pop is a frame that changes far more than the frames around it (a
   sample, group or model switch): frame k > 0 pops when its
   flicker exceeds POP_FACTOR times the median flicker of the frames within
   POP_WINDOW of it (k itself left out) and POP_FLICKER_FLOOR levels, or
   its mean reflection error moved from frame k - 1 by more than POP_FACTOR
   times the median such move within POP_WINDOW and POP_ERROR_FLOOR pixels
   (no move counts to or from a frame where no point matched: its mean is 0).
   Medians of the neighbours, not of the whole path: an error that grows
   steadily faster (a dolly into a focus) is a trend, not a pop. The floors
   keep a method that follows the truth almost exactly (medians near 0) from
   popping on noise. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli_options.h"
#include "gltf_load.h"
#include "image_io.h"
#include "reflect_bench.h"

static const char *const usage_path =
    "usage: reflect path [SCENE.glb | --builtin NAME] [options]\n"
    "\n"
    "Renders every built method (or --methods) along a camera path and\n"
    "measures each frame against RAYTRACE at the same depth.\n"
    "\n"
    "  --path P           orbit (default): 60 degrees around the camera's target;\n"
    "                     dolly: towards the target, from 1 to 0.3 of its distance;\n"
    "                     pan: the target swept sideways across half the view;\n"
    "                     focus: towards the target to 0.05 of its distance\n"
    "                     (into a concave mirror's focus);\n"
    "                     rim: from half the distance, eye and target sideways from\n"
    "                     the largest reflector's middle to 1.5 of its half-width\n"
    "                     beyond it: the view crosses the reflector's edge, where its\n"
    "                     curvature ends (the concave bowl's rim)\n"
    "  --frames N         frames along the path, 2..10000 (default 30)\n"
    "  --methods LIST     comma-separated method names (default: every built method\n"
    "                     but raytrace and direct)\n"
    "  --size WxH         frame size (default 160x120)\n"
    "  --depth N          bounces, for the truth too (default 1)\n"
    "  --threads N        worker threads (default: one per CPU)\n"
    "  --out DIR          where PATH.csv goes (default out/path)\n"
    "  --images           also write DIR/METHOD-NNNN.png for every frame\n";

typedef struct path_options {
    const char *file, *builtin, *path, *out;
    refl_method methods[REFL_METHOD_COUNT];
    int method_count, frames, width, height, depth, threads, images;
} path_options;

static int path_fail(const char *what, const char *value) {
    fprintf(stderr, "reflect path: %s%s\n", what, value ? value : "");
    return 2;
}

static int parse_methods(const char *list, path_options *o) {
    char buf[256], *tok, *save = NULL;
    if (strlen(list) >= sizeof buf) return 0;
    strcpy(buf, list);
    for (tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        refl_method m = refl_method_from_name(tok);
        if (!m || !refl_method_is_built(m) || o->method_count == REFL_METHOD_COUNT) return 0;
        o->methods[o->method_count++] = m;
    }
    return o->method_count > 0;
}

/* The options that take a value, and the paths (their name is what is
   kept: it names the CSV too). */
static const char *const path_value_options[] = {"--builtin", "--path",    "--frames", "--methods",
                                                 "--size",    "--depth",   "--threads", "--out", NULL};
static const cli_choice paths[] = {{"orbit", 0}, {"dolly", 0}, {"pan", 0}, {"focus", 0}, {"rim", 0}, {NULL, 0}};

static int parse_path_options(int argc, char **argv, path_options *o) {
    int i, path;
    unsigned long long given = 0; /* the value options seen (cli_given_twice) */
    memset(o, 0, sizeof *o);
    o->path = "orbit";
    o->out = "out/path";
    o->frames = 30;
    o->width = 160;
    o->height = 120;
    o->depth = 1;
    for (i = 2; i < argc; ++i) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        char extra;
        int takes = strcmp(a, "--images") && strcmp(a, "--help") && strcmp(a, "-h") && a[0] == '-';
        if (takes && !v) return path_fail("needs a value: ", a);
        if (takes && cli_given_twice("reflect path", path_value_options, a, &given)) return 2;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(usage_path, stdout);
            return 1;
        } else if (!strcmp(a, "--images")) {
            o->images = 1;
            continue;
        } else if (!strcmp(a, "--builtin")) {
            o->builtin = v;
        } else if (!strcmp(a, "--path")) {
            if (!parse_choice("reflect path", a, v, paths, &path)) return 2;
            o->path = v;
        } else if (!strcmp(a, "--frames")) {
            if (sscanf(v, "%d%c", &o->frames, &extra) != 1 || o->frames < 2 || o->frames > 10000)
                return path_fail("--frames: 2..10000, not ", v);
        } else if (!strcmp(a, "--methods")) {
            if (!parse_methods(v, o)) return path_fail("--methods: built method names separated by commas, not ", v);
        } else if (!strcmp(a, "--size")) {
            if (sscanf(v, "%dx%d%c", &o->width, &o->height, &extra) != 2 || o->width < 1 || o->height < 1 ||
                o->width > 4096 || o->height > 4096)
                return path_fail("--size: WxH, each 1..4096, not ", v);
        } else if (!strcmp(a, "--depth")) {
            if (sscanf(v, "%d%c", &o->depth, &extra) != 1 || o->depth < 1 || o->depth > 64)
                return path_fail("--depth: 1..64, not ", v);
        } else if (!strcmp(a, "--threads")) {
            if (sscanf(v, "%d%c", &o->threads, &extra) != 1 || o->threads < 0 || o->threads > RAST_MAX_THREADS)
                return path_fail("--threads: 0..64, not ", v);
        } else if (!strcmp(a, "--out")) {
            o->out = v;
        } else if (a[0] == '-') {
            return path_fail("unknown option (see reflect path --help): ", a);
        } else {
            if (o->file) return path_fail("more than one scene given: ", a);
            o->file = a;
            continue;
        }
        ++i;
    }
    if (!o->file && !o->builtin) o->builtin = "default";
    if (!o->method_count) {
        refl_method m;
        for (m = (refl_method)1; m < REFL_METHOD_COUNT; m = (refl_method)(m + 1))
            if (refl_method_is_built(m) && m != REFL_RAYTRACE && m != REFL_DIRECT) o->methods[o->method_count++] = m;
    }
    return 0;
}

/* The world-space middle and half-width (along `side`) of the reflector
   with the most triangles; 0 when the scene has none. */
static float largest_reflector(const refl_scene *s, refl_vec3 side, refl_vec3 *middle) {
    int i, best = -1, v;
    float lo = 0.0f, hi = 0.0f;
    refl_vec3 a = refl_v3(0, 0, 0), b = refl_v3(0, 0, 0);
    for (i = 0; i < s->object_count; ++i)
        if (s->materials[s->objects[i].material].type != REFL_DIFFUSE &&
            (best < 0 || s->meshes[s->objects[i].mesh]->triangle_count > s->meshes[s->objects[best].mesh]->triangle_count))
            best = i;
    if (best < 0) return 0.0f;
    for (v = 0; v < s->meshes[s->objects[best].mesh]->vertex_count; ++v) {
        const float *q = s->meshes[s->objects[best].mesh]->positions + 3 * v;
        refl_vec3 p = refl_mat4_point(s->objects[best].transform, refl_v3(q[0], q[1], q[2]));
        float t = refl_v3_dot(p, side);
        if (!v || t < lo) { lo = t; a = p; }
        if (!v || t > hi) { hi = t; b = p; }
    }
    *middle = refl_v3_scale(refl_v3_add(a, b), 0.5f);
    return 0.5f * (hi - lo);
}

/* Frame k of n along the path, from the scene's camera. */
static refl_view path_view(const refl_scene *s, const path_options *o, int k) {
    refl_view v = s->camera;
    refl_vec3 off = refl_v3_sub(v.eye, v.target);
    refl_vec3 up = refl_v3_length(v.up) > 0.0f ? v.up : refl_v3(0, 1, 0);
    refl_vec3 side = refl_v3_normalize(refl_v3_cross(off, up));
    float u = (float)k / (float)(o->frames - 1);
    if (!strcmp(o->path, "orbit")) {
        float a = u * 1.04719755f, c = cosf(a), sn = sinf(a); /* 60 degrees about +y */
        v.eye = refl_v3_add(v.target, refl_v3(c * off.x + sn * off.z, off.y, -sn * off.x + c * off.z));
    } else if (!strcmp(o->path, "dolly") || !strcmp(o->path, "focus")) {
        float end = !strcmp(o->path, "dolly") ? 0.3f : 0.05f;
        v.eye = refl_v3_add(v.target, refl_v3_scale(off, 1.0f + (end - 1.0f) * u));
    } else if (!strcmp(o->path, "rim")) { /* from the reflector's middle out over its edge */
        refl_vec3 middle = v.target, shift;
        float half = largest_reflector(s, side, &middle);
        float along = refl_v3_dot(refl_v3_sub(middle, v.target), side);
        shift = refl_v3_scale(side, along + 1.5f * half * u);
        v.target = refl_v3_add(v.target, shift);
        v.eye = refl_v3_add(v.target, refl_v3_scale(off, 0.5f));
    } else { /* pan: eye and target sideways, across half the view's width at the target */
        float fov = v.fovy_degrees > 0.0f ? v.fovy_degrees : 45.0f;
        float half = refl_v3_length(off) * tanf(fov * 0.00872664626f) * (float)o->width / (float)o->height;
        refl_vec3 shift = refl_v3_scale(side, half * (u - 0.5f));
        v.eye = refl_v3_add(v.eye, shift);
        v.target = refl_v3_add(v.target, shift);
    }
    v.width = o->width;
    v.height = o->height;
    return v;
}

static refl_scene *path_scene(const path_options *o) {
    refl_scene *s = NULL;
    char err[512] = "";
    refl_result r;
    if (o->builtin) {
        r = refl_scene_builtin(o->builtin, NULL, &s);
        if (r != REFL_OK) fprintf(stderr, "reflect path: built-in scene '%s': %s\n", o->builtin, refl_result_string(r));
    } else {
        r = refl_gltf_load(o->file, NULL, &s, err, sizeof err);
        if (r != REFL_OK) fprintf(stderr, "reflect path: %s\n", err[0] ? err : refl_result_string(r));
    }
    if (r == REFL_OK && !s->has_camera) refl_scene_complete(s);
    return r == REFL_OK ? s : NULL;
}

static int write_png(const char *dir, const char *method, int k, const refl_frame *f) {
    char path[1024], err[256];
    size_t i, n = (size_t)f->width * (size_t)f->height;
    uint8_t *px = (uint8_t *)malloc(n * 4);
    refl_result r;
    if (!px) return 0;
    refl_frame_to_srgb8(f, NULL, px);
    for (i = 0; i < n; ++i) memmove(px + 3 * i, px + 4 * i, 3);
    snprintf(path, sizeof path, "%s/%s-%04d.png", dir, method, k);
    r = refl_image_write(path, f->width, f->height, 3, px, NULL, err, sizeof err);
    free(px);
    if (r != REFL_OK) fprintf(stderr, "reflect path: %s\n", err);
    return r == REFL_OK;
}

/* One method's figures for one frame (flicker: 0 at frame 0). */
typedef struct path_sample {
    double ms, psnr;
    refl_reflection_error e;
    refl_flicker fl;
    int pop;
} path_sample;

enum { POP_FACTOR = 3, POP_WINDOW = 4 };
static const double POP_FLICKER_FLOOR = 2.0, POP_ERROR_FLOOR = 0.25;

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The median of v[k - POP_WINDOW .. k + POP_WINDOW] without v[k], over
   indices 1 .. n - 1 (v[0] is not a change). */
static double local_median(const double *v, int n, int k) {
    double near[2 * POP_WINDOW];
    int j, m = 0;
    for (j = k - POP_WINDOW; j <= k + POP_WINDOW; ++j)
        if (j >= 1 && j < n && j != k) near[m++] = v[j];
    if (!m) return 0.0;
    qsort(near, (size_t)m, sizeof(double), cmp_double);
    return m % 2 ? near[m / 2] : 0.5 * (near[m / 2 - 1] + near[m / 2]);
}

/* Marks the pops of one method's frames (the rule at the top of the file);
   returns how many. */
static int mark_pops(path_sample *f, int n) {
    double *flicker = (double *)malloc((size_t)n * sizeof(double)), *moved = (double *)malloc((size_t)n * sizeof(double));
    int k, pops = 0;
    if (!flicker || !moved) {
        free(flicker);
        free(moved);
        return 0;
    }
    for (k = 1; k < n; ++k) {
        flicker[k] = f[k].fl.mean;
        /* a frame where nothing matched has mean 0: no move to or from it */
        moved[k] = f[k].e.matched && f[k - 1].e.matched ? fabs(f[k].e.mean - f[k - 1].e.mean) : 0.0;
    }
    for (k = 1; k < n; ++k) {
        f[k].pop = (flicker[k] > POP_FACTOR * local_median(flicker, n, k) && flicker[k] > POP_FLICKER_FLOOR) ||
                   (moved[k] > POP_FACTOR * local_median(moved, n, k) && moved[k] > POP_ERROR_FLOOR);
        pops += f[k].pop;
    }
    free(flicker);
    free(moved);
    return pops;
}

int refl_cli_path(int argc, char **argv) {
    path_options o;
    refl_scene *s;
    refl_renderer *rr[REFL_METHOD_COUNT + 1] = {0};
    refl_frame *now[REFL_METHOD_COUNT + 1] = {0}, *prev[REFL_METHOD_COUNT + 1] = {0};
    path_sample *samples = NULL; /* [method][frame] */
    char csv_path[1024];
    FILE *csv = NULL;
    int code = 1, k, m, r = parse_path_options(argc, argv, &o);
    if (r) return r == 1 ? 0 : 2;
    if (!(s = path_scene(&o))) return 1;
    mkdir(o.out, 0777); /* may exist */
    snprintf(csv_path, sizeof csv_path, "%s/%s.csv", o.out, o.path);
    if (!(samples = (path_sample *)calloc((size_t)o.method_count * (size_t)o.frames, sizeof *samples))) goto done;
    /* renderer o.method_count is the truth's */
    for (m = 0; m <= o.method_count; ++m) {
        refl_render_desc d;
        memset(&d, 0, sizeof d);
        d.method = m < o.method_count ? o.methods[m] : REFL_RAYTRACE;
        d.depth = o.depth;
        d.threads = o.threads;
        if (refl_renderer_create(s, &d, &rr[m]) != REFL_OK || refl_frame_create(o.width, o.height, NULL, &now[m]) != REFL_OK ||
            refl_frame_create(o.width, o.height, NULL, &prev[m]) != REFL_OK) {
            fprintf(stderr, "reflect path: cannot set up %s\n", refl_method_name(d.method));
            goto done;
        }
    }
    for (k = 0; k < o.frames; ++k) {
        refl_view v = path_view(s, &o, k);
        refl_frame *truth = now[o.method_count];
        refl_result rt = refl_renderer_render(rr[o.method_count], &v, truth);
        if (rt != REFL_OK) {
            fprintf(stderr, "reflect path: frame %d: raytrace: %s %s\n", k, refl_result_string(rt), truth->message);
            goto done;
        }
        for (m = 0; m < o.method_count; ++m) {
            const char *name = refl_method_name(o.methods[m]);
            path_sample *f = &samples[(size_t)m * (size_t)o.frames + (size_t)k];
            refl_image_error ie;
            refl_result rm = refl_renderer_render(rr[m], &v, now[m]);
            if (rm != REFL_OK) {
                fprintf(stderr, "reflect path: frame %d: %s: %s %s\n", k, name, refl_result_string(rm), now[m]->message);
                goto done;
            }
            refl_measure_reflection_error(now[m], truth, NULL, &f->e);
            refl_measure_image_error(now[m], truth, 1, 0.0f, &ie);
            if (k > 0) refl_measure_flicker(prev[m], now[m], prev[o.method_count], truth, &f->fl);
            f->ms = now[m]->stats.ms_total;
            f->psnr = isinf(ie.psnr) ? 999.0 : ie.psnr;
            if (o.images && !write_png(o.out, name, k, now[m])) goto done;
        }
        if (o.images && !write_png(o.out, "raytrace", k, truth)) goto done;
        for (m = 0; m <= o.method_count; ++m) { /* this frame becomes the previous one */
            refl_frame *t = prev[m];
            prev[m] = now[m];
            now[m] = t;
        }
        if (isatty(2)) fprintf(stderr, "\rreflect path: %s, frame %d of %d%s", o.path, k + 1, o.frames,
                               k + 1 == o.frames ? "\n" : "");
    }
    if (!(csv = fopen(csv_path, "w"))) {
        fprintf(stderr, "reflect path: cannot write %s\n", csv_path);
        goto done;
    }
    fprintf(csv, "path,method,frame,ms,mean_px,p95_px,wrong,empty,psnr_db,flicker_mean,flicker_p95,pop\n");
    printf("%-12s %10s %10s %14s %13s %-22s %s\n", "method", "mean ms", "mean px", "flicker mean", "flicker p95",
           "worst frame (flicker)", "pops (frames)");
    for (m = 0; m < o.method_count; ++m) {
        path_sample *f = &samples[(size_t)m * (size_t)o.frames];
        double ms = 0.0, px = 0.0, fm = 0.0, fp = 0.0;
        int worst = 1, pops = mark_pops(f, o.frames), printed = 0;
        char worst_text[64];
        for (k = 0; k < o.frames; ++k) {
            fprintf(csv, "%s,%s,%d,%.3f,%.4f,%.4f,%.5f,%.5f,%.3f,%.4f,%.1f,%d\n", o.path, refl_method_name(o.methods[m]),
                    k, f[k].ms, f[k].e.mean, f[k].e.p95, f[k].e.wrong, f[k].e.empty, f[k].psnr, f[k].fl.mean,
                    f[k].fl.p95, f[k].pop);
            ms += f[k].ms;
            px += f[k].e.mean;
            if (k > 0) {
                fm += f[k].fl.mean;
                fp += f[k].fl.p95;
                if (f[k].fl.mean > f[worst].fl.mean) worst = k;
            }
        }
        snprintf(worst_text, sizeof worst_text, "%d (%.3f)", worst, f[worst].fl.mean);
        printf("%-12s %10.2f %10.3f %14.3f %13.2f %-22s %d", refl_method_name(o.methods[m]), ms / o.frames,
               px / o.frames, fm / (o.frames - 1), fp / (o.frames - 1), worst_text, pops);
        for (k = 1; k < o.frames; ++k)
            if (f[k].pop && printed++ < 8) printf("%s%d", printed == 1 ? " (" : ", ", k);
        printf("%s\n", printed > 8 ? ", ...)" : printed ? ")" : "");
    }
    printf("per frame: %s\n", csv_path);
    code = 0;
done:
    if (csv && fclose(csv) != 0) code = 1;
    for (m = 0; m <= o.method_count; ++m) {
        refl_renderer_destroy(rr[m]);
        refl_frame_destroy(now[m]);
        refl_frame_destroy(prev[m]);
    }
    free(samples);
    refl_scene_destroy(s);
    return code;
}
