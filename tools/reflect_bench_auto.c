/* `reflect bench --fit-auto FILE` and `reflect bench --auto-table`: AUTO's
   models fitted from measurements, and AUTO checked against every method
   (docs/methods/auto.md). Both measure the same way: per built-in scene and
   camera, each reflector drawn by each method in turn (the others DIRECT),
   its time over DIRECT's and its reflection error against RAYTRACE over
   that reflector's pixels alone. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "cli_options.h"
#include "reflect_bench.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static const char *const usage_auto =
    "usage: reflect bench --fit-auto FILE [--size WxH] [--threads N] [--repeats N] [--jobs N] [--methods LIST]\n"
    "                                    [--depth N] [--scenes LIST] [--fit-from FILE.csv]\n"
    "       reflect bench --auto-table [--models FILE] [--size WxH] [--threads N] [--repeats N] [--jobs N]\n"
    "                                  [--methods LIST] [--depth N] [--scenes LIST] [--out FILE.md]\n"
    "\n"
    "The scenes: every built-in one, \"open\" (a mirror sphere with\n"
    "everything else far away) and \"pair\" (two mirror spheres side by side,\n"
    "each reflecting the other, among the same far boxes).\n"
    "\n"
    "--fit-auto: renders every scene from its own camera and two\n"
    "fit cameras (orbited and dollied) at WxH and its own camera at half\n"
    "that, each reflector by each method (the others DIRECT); measures the\n"
    "method's CPU time over DIRECT's (the least of N runs) and its reflection\n"
    "error against RAYTRACE over that reflector (the mean in pixels, a wrong\n"
    "point or a hole counting as the reflector's linear size), and fits per\n"
    "(method, reflector class) AUTO's cost and error models (least squares,\n"
    "no coefficient below zero; the error model raised by its largest\n"
    "under-prediction), written to\n"
    "FILE in the format refl_auto_models_parse reads, the measurements to\n"
    "FILE.csv (--fit-from FILE.csv fits them again without measuring).\n"
    "\n"
    "--auto-table: for every scene, its own camera and two hidden\n"
    "cameras (not used by the fit), at budgets 0.5, 1, 2 and 8 px: the same\n"
    "per-reflector measurements, then AUTO's frame against the frame of the\n"
    "fastest measured method per reflector that meets the budget (time ratio,\n"
    "goal <= 1.2) and whether AUTO's choice is over budget (goal: never).\n"
    "A markdown table on stdout (and in --out).\n"
    "\n"
    "  --size WxH     frame size (default 320x240)\n"
    "  --threads N    worker threads (default 1); times are the process's CPU time\n"
    "  --depth N      bounces of every frame, the truth's too (default 0: the library's, 6);\n"
    "                 fit at the depth AUTO will draw at: past a method's own bounces the\n"
    "                 tracer follows the path, at a cost\n"
    "  --repeats N    runs per timing, the fastest kept (default 3)\n"
    "  --jobs N       scenes measured at once, each in a process of its own (default 1)\n"
    "  --scenes LIST  comma-separated scenes (default: every built-in one, open and pair)\n"
    "  --methods LIST comma-separated methods measured (default\n"
    "                 raytrace,envmap,planar,c3rc,sbc,spoc,graphcam; layered-em\n"
    "                 takes tens of seconds a frame)\n"
    "  --models FILE  AUTO's models (default: those built into the library)\n";

#define AUTO_MAX_REFLECTORS 16

typedef struct auto_opts {
    int width, height, threads, repeats;
    int depth;                  /* --depth: bounces of every frame, the truth's too (0: the default) */
    refl_method methods[REFL_METHOD_COUNT];
    int method_count;
    const char *fit_path, *models_path, *out_path;
    const char *fit_from;       /* --fit-from CSV: the measurements of an earlier fit */
    const char *scenes;         /* --scenes LIST; NULL: every built-in one, open and pair */
    int table;
    int jobs;                   /* scenes measured at once, in child processes */
} auto_opts;

/* One reflector of one view, measured by every method. */
typedef struct auto_reflector {
    int object;
    refl_auto_features features;
    int measured[REFL_METHOD_COUNT]; /* 1: the method drew it */
    double ms[REFL_METHOD_COUNT], error[REFL_METHOD_COUNT];
} auto_reflector;

typedef struct auto_view {
    int count;
    double ms_direct;
    auto_reflector r[AUTO_MAX_REFLECTORS];
} auto_view;

/* A camera variant: orbited about the target's vertical by `degrees`, the
   eye's distance to it times `dolly`. */
typedef struct auto_camera {
    const char *name;
    float degrees, dolly;
    int width_div;              /* the frame size divided by this */
} auto_camera;

static const auto_camera fit_cameras[] = {
    {"own", 0.0f, 1.0f, 1}, {"fit-a", -12.0f, 0.75f, 1}, {"fit-b", 8.0f, 0.9f, 1}, {"own-half", 0.0f, 1.0f, 2}};
static const auto_camera table_cameras[] = {{"own", 0.0f, 1.0f, 1}, {"hidden-a", 22.0f, 0.85f, 1},
                                            {"hidden-b", -27.0f, 0.95f, 1}};
static const float budgets[] = {0.5f, 1.0f, 2.0f, 8.0f};

static refl_view camera_view(const refl_scene *s, const auto_camera *c, int w, int h) {
    refl_view v = s->camera;
    refl_vec3 d = refl_v3_sub(v.eye, v.target);
    float a = c->degrees * 3.14159265f / 180.0f, ca = cosf(a), sa = sinf(a);
    d = refl_v3(ca * d.x + sa * d.z, d.y, -sa * d.x + ca * d.z);
    v.eye = refl_v3_add(v.target, refl_v3_scale(d, c->dolly));
    v.width = w / c->width_div;
    v.height = h / c->width_div;
    v.znear = v.zfar = 0.0f; /* from the scene's bounds, for the moved eye */
    return v;
}

/* CPU milliseconds of this process (every thread's): a frame's cost that
   other processes' load does not inflate, as wall-clock time would. */
static double cpu_ms(void) {
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

/* The least CPU time of `repeats` renders; the last frame kept in f. */
static refl_result timed(const refl_scene *s, const refl_view *v, const refl_render_desc *d, int repeats,
                         refl_frame *f, double *ms) {
    int k;
    *ms = 1e300;
    for (k = 0; k < repeats; ++k) {
        double t0 = cpu_ms();
        refl_result r = refl_render(s, v, d, f);
        double t = cpu_ms() - t0;
        if (r != REFL_OK) return r;
        *ms = t < *ms ? t : *ms;
    }
    return REFL_OK;
}

/* The reflection error of test over object k's pixels of truth: the mean
   in pixels, a wrong point or a hole counting as the linear size s. */
static refl_result reflector_error(const refl_frame *test, const refl_frame *truth, refl_frame *masked, int k,
                                   double s, double *out) {
    size_t i, n = (size_t)truth->width * (size_t)truth->height;
    uint8_t id = (uint8_t)(k < 254 ? k + 1 : 255);
    refl_reflection_error e;
    refl_result r;
    memcpy(masked->points, truth->points, n * 3 * sizeof(float));
    for (i = 0; i < n; ++i) masked->stencil[i] = truth->stencil[i] == id ? id : 0;
    r = refl_measure_reflection_error(test, masked, NULL, &e);
    if (r != REFL_OK) return r;
    *out = e.pixels ? e.mean * (double)e.matched / (double)e.pixels + (e.wrong + e.empty) * s : 0.0;
    return REFL_OK;
}

/* Every reflector of the view by every method (the others DIRECT). */
static int measure_view(const refl_scene *s, const refl_view *v, const auto_opts *o, auto_view *out) {
    refl_frame *truth = NULL, *test = NULL, *masked = NULL;
    refl_method *per = (refl_method *)calloc((size_t)s->object_count + 1, sizeof(refl_method));
    refl_render_desc d;
    int i, m, ok = 0;
    memset(out, 0, sizeof *out);
    memset(&d, 0, sizeof d);
    d.threads = o->threads;
    d.depth = o->depth;
    if (!per || refl_frame_create(v->width, v->height, NULL, &truth) != REFL_OK ||
        refl_frame_create(v->width, v->height, NULL, &test) != REFL_OK ||
        refl_frame_create(v->width, v->height, NULL, &masked) != REFL_OK)
        goto done;
    d.method = REFL_RAYTRACE;
    if (refl_render(s, v, &d, truth) != REFL_OK) goto done;
    d.method = REFL_DIRECT;
    if (timed(s, v, &d, o->repeats, test, &out->ms_direct) != REFL_OK) goto done;
    for (i = 0; i < s->object_count && out->count < AUTO_MAX_REFLECTORS; ++i) {
        auto_reflector *ar = &out->r[out->count];
        if (s->materials[s->objects[i].material].type == REFL_DIFFUSE) continue;
        memset(ar, 0, sizeof *ar);
        ar->object = i;
        if (refl_auto_reflector_features(s, v, test, i, &ar->features) != REFL_OK) goto done;
        if (ar->features.pixels == 0) continue;
        out->count++;
    }
    for (i = 0; i < s->object_count; ++i) per[i] = REFL_DIRECT;
    d.object_methods = per;
    d.object_method_count = s->object_count;
    for (i = 0; i < out->count; ++i) {
        auto_reflector *ar = &out->r[i];
        for (m = 0; m < o->method_count; ++m) {
            refl_method me = o->methods[m];
            double ms;
            per[ar->object] = me;
            if (timed(s, v, &d, o->repeats, test, &ms) != REFL_OK) goto done;
            if (test->stats.handed_over) continue; /* it cannot draw this one */
            ar->measured[me] = 1;
            ar->ms[me] = ms - out->ms_direct > 0.01 ? ms - out->ms_direct : 0.01;
            if (reflector_error(test, truth, masked, ar->object, sqrt((double)ar->features.pixels), &ar->error[me]) !=
                REFL_OK)
                goto done;
        }
        per[ar->object] = REFL_DIRECT;
    }
    ok = 1;
done:
    free(per);
    refl_frame_destroy(truth);
    refl_frame_destroy(test);
    refl_frame_destroy(masked);
    return ok;
}

/* Two scenes of the bench's own beside the built-in ones: "open", a mirror
   sphere with everything else far away (boxes 15 to 25 of its radii off,
   the sky behind), where what it reflects is effectively at infinity; and
   "pair", the same sphere with the two nearest boxes brought to either side
   of it and made mirrors, so that a part of each one's reflection is
   another mirror (its paths go past the first bounce: the `beyond`
   feature). */
static refl_scene *bench_scene(int pair) {
    static const float at[4][3] = {{9.0f, 1.0f, 0.0f}, {-7.0f, 3.0f, -8.0f}, {0.0f, -6.0f, -10.0f}, {4.0f, 6.0f, 8.0f}};
    static const float near_at[2][3] = {{1.4f, 1.0f, -0.4f}, {-1.4f, 1.0f, -0.4f}};
    refl_scene *s = NULL;
    refl_mesh *m = NULL;
    refl_material mirror = refl_material_mirror(0.9f);
    int k;
    if (refl_scene_create(NULL, &s) != REFL_OK) return NULL;
    if (refl_mesh_sphere(0.5f, 48, 24, NULL, &m) != REFL_OK ||
        refl_scene_add(s, m, &mirror, refl_mat4_translate(refl_v3(0.0f, 1.0f, 0.0f))) < 0) {
        refl_scene_destroy(s);
        return NULL;
    }
    for (k = 0; k < 4; ++k) {
        refl_material box = refl_material_diffuse(0.2f + 0.2f * (float)k, 0.7f - 0.15f * (float)k, 0.3f);
        const float *p = pair && k < 2 ? near_at[k] : at[k];
        m = NULL;
        if (refl_mesh_box(refl_v3(2.0f, 2.0f, 2.0f), NULL, &m) != REFL_OK ||
            refl_scene_add(s, m, pair && k < 2 ? &mirror : &box, refl_mat4_translate(refl_v3(p[0], p[1], p[2]))) <
                0) {
            refl_scene_destroy(s);
            return NULL;
        }
    }
    s->camera.eye = refl_v3(0.0f, 1.4f, pair ? 3.4f : 2.6f);
    s->camera.target = refl_v3(0.0f, 1.0f, 0.0f);
    s->camera.up = refl_v3(0.0f, 1.0f, 0.0f);
    s->camera.fovy_degrees = 45.0f;
    s->has_camera = 1;
    refl_scene_complete(s);
    return s;
}

static refl_scene *load_builtin(const char *name) {
    refl_scene *s = NULL;
    refl_builtin_desc bd;
    if (!strcmp(name, "open") || !strcmp(name, "pair")) return bench_scene(name[0] == 'p');
    memset(&bd, 0, sizeof bd);
    return refl_scene_builtin(name, &bd, &s) == REFL_OK ? s : NULL;
}

/* ---- the fit ----------------------------------------------------------------- */

typedef struct auto_sample {
    int method, cls;
    refl_auto_features f;
    double ms, error;
} auto_sample;

/* Least squares of y on the rows' `terms` terms (at most 4) with no
   coefficient below zero (a cost or an error that falls as a reflector
   grows is an artefact of few samples, and extrapolates to nonsense): while
   the solution has a negative coefficient, its most negative term is
   dropped and the rest solved again; terms the samples leave singular are
   dropped too. c[] is zero for dropped terms. */
static void fit_terms(const double (*x)[4], const double *y, int n, int terms, float *c) {
    double *a = (double *)malloc((size_t)n * 4 * sizeof(double)), sol[4];
    int use[4] = {1, 1, 1, 1}, i, j, cols, tries;
    for (j = 0; j < terms; ++j) c[j] = 0.0f;
    if (!a) return;
    for (tries = 0; tries < terms; ++tries) {
        int worst = -1, col[4];
        for (cols = 0, j = 0; j < terms; ++j)
            if (use[j]) col[cols++] = j;
        if (!cols || cols > n) {
            if (cols) use[col[cols - 1]] = 0;
            continue;
        }
        for (i = 0; i < n; ++i)
            for (j = 0; j < cols; ++j) a[i * cols + j] = x[i][col[j]];
        if (refl_least_squares(a, y, n, cols, sol, NULL) != REFL_OK) {
            use[col[cols - 1]] = 0; /* the last term the samples cannot tell apart */
            continue;
        }
        for (j = 0; j < cols; ++j)
            if (sol[j] < 0.0 && (worst < 0 || sol[j] < sol[worst])) worst = j;
        if (worst < 0) {
            for (j = 0; j < cols; ++j) c[col[j]] = (float)sol[j];
            break;
        }
        use[col[worst]] = 0;
    }
    free(a);
}

static void fit_models(const auto_sample *smp, int n, refl_auto_models *out) {
    double (*x)[4] = (double(*)[4])malloc((size_t)(n ? n : 1) * sizeof *x);
    double *y = (double *)malloc((size_t)(n ? n : 1) * sizeof(double));
    int m, c, i, k;
    memset(out, 0, sizeof *out);
    if (!x || !y) goto done;
    for (m = 0; m < REFL_METHOD_COUNT; ++m)
        for (c = 0; c < REFL_AUTO_CLASS_COUNT; ++c) {
            refl_auto_model *md = &out->model[m][c];
            const auto_sample *own[4096];
            int count = 0;
            float worst = 0.0f;
            for (i = 0; i < n && count < 4096; ++i)
                if (smp[i].method == m && smp[i].cls == c) own[count++] = &smp[i];
            if (!count) continue;
            for (k = 0; k < count; ++k) {
                x[k][0] = 1.0;
                x[k][1] = (double)own[k]->f.pixels / 1000.0;
                x[k][2] = own[k]->f.scene_triangles / 1000.0;
                x[k][3] = (double)own[k]->f.pixels * own[k]->f.beyond / 1000.0;
                y[k] = own[k]->ms;
            }
            fit_terms((const double(*)[4])x, y, count, 4, md->cost);
            for (k = 0; k < count; ++k) {
                double sq = sqrt((double)own[k]->f.pixels);
                x[k][0] = 1.0;
                x[k][1] = sq;
                x[k][2] = sq * own[k]->f.nearness;
                y[k] = own[k]->error;
            }
            fit_terms((const double(*)[4])x, y, count, 3, md->error);
            md->fitted = 1;
            md->samples = count;
            /* an upper envelope: no measurement above its prediction */
            for (k = 0; k < count; ++k) {
                float e;
                refl_auto_predict(md, &own[k]->f, &e, NULL);
                if ((float)own[k]->error - e > worst) worst = (float)own[k]->error - e;
            }
            md->error[0] += worst;
        }
done:
    free(x);
    free(y);
}

static int parse_methods(const char *list, auto_opts *o) {
    char buf[256], *tok, *save = NULL;
    snprintf(buf, sizeof buf, "%s", list);
    o->method_count = 0;
    for (tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        refl_method m = refl_method_from_name(tok);
        if (m == REFL_METHOD_DEFAULT || m == REFL_DIRECT || m == REFL_AUTO || o->method_count >= REFL_METHOD_COUNT) {
            fprintf(stderr, "reflect bench: --methods: '%s' is not a method that draws reflectors\n", tok);
            return 0;
        }
        o->methods[o->method_count++] = m;
    }
    return o->method_count > 0;
}

/* Runs scene_fn on every built-in scene, "open" and "pair", `jobs` scenes at a time in child
   processes (fork), each writing to a temporary file of its own; then
   hands the files, in scene order, to collect. 0 when a scene failed. */
typedef int (*scene_fn)(const char *scene, const auto_opts *o, const void *user, FILE *out);
typedef int (*collect_fn)(FILE *in, void *state);

static int each_scene(const auto_opts *o, scene_fn fn, const void *user, collect_fn collect, void *state) {
    const char *const *builtin = refl_builtin_names();
    const char *names[64];
    FILE *files[64];
    pid_t pids[64];
    int n = 0, i, ok = 1, running = 0, next = 0;
    while (builtin[n] && n < 63) {
        names[n] = builtin[n];
        ++n;
    }
    names[n++] = "open";
    names[n++] = "pair";
    if (o->scenes) { /* the listed ones, in the order above */
        char list[520];
        int kept = 0;
        snprintf(list, sizeof list, ",%s,", o->scenes);
        for (i = 0; i < n; ++i) {
            char key[80];
            snprintf(key, sizeof key, ",%s,", names[i]);
            if (strstr(list, key)) names[kept++] = names[i];
        }
        n = kept;
        if (!n) {
            fprintf(stderr, "reflect bench: --scenes '%s' names no built-in scene (nor open, pair)\n", o->scenes);
            return 0;
        }
    }
    for (i = 0; i < n; ++i) {
        files[i] = tmpfile();
        pids[i] = -1;
        if (!files[i]) return 0;
    }
    /* keep `jobs` children running; a child's exit status is its result */
    while (next < n || running) {
        if (next < n && running < o->jobs) {
            fflush(NULL);
            pids[next] = fork();
            if (pids[next] == 0) {
                int r = fn(names[next], o, user, files[next]);
                fflush(files[next]);
                _exit(r ? 0 : 1);
            }
            if (pids[next] < 0) ok = 0;
            else running++;
            next++;
        } else {
            int status;
            pid_t done = wait(&status);
            if (done < 0) break;
            running--;
            if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) ok = 0;
        }
    }
    for (i = 0; i < n; ++i) {
        rewind(files[i]);
        if (ok && !collect(files[i], state)) ok = 0;
        fclose(files[i]);
    }
    return ok;
}

static int fit_scene(const char *name, const auto_opts *o, const void *user, FILE *out) {
    refl_scene *s = load_builtin(name);
    int ci, i, m, ok = 1;
    (void)user;
    if (!s) return 0;
    for (ci = 0; ok && ci < (int)(sizeof fit_cameras / sizeof fit_cameras[0]); ++ci) {
        refl_view v = camera_view(s, &fit_cameras[ci], o->width, o->height);
        auto_view av;
        fprintf(stderr, "fit: %s %s %dx%d\n", name, fit_cameras[ci].name, v.width, v.height);
        if (!measure_view(s, &v, o, &av)) { ok = 0; break; }
        for (i = 0; i < av.count; ++i)
            for (m = 0; m < REFL_METHOD_COUNT; ++m)
                if (av.r[i].measured[m]) {
                    auto_sample smp;
                    memset(&smp, 0, sizeof smp);
                    smp.method = m;
                    smp.cls = av.r[i].features.reflector_class;
                    smp.f = av.r[i].features;
                    smp.ms = av.r[i].ms[m];
                    smp.error = av.r[i].error[m];
                    if (fwrite(&smp, sizeof smp, 1, out) != 1) ok = 0;
                }
    }
    refl_scene_destroy(s);
    return ok;
}

typedef struct fit_state {
    auto_sample *smp;
    int n, cap;
} fit_state;

static int fit_collect(FILE *in, void *state) {
    fit_state *st = (fit_state *)state;
    auto_sample smp;
    while (fread(&smp, sizeof smp, 1, in) == 1) {
        if (st->n == st->cap) {
            int cap = st->cap ? 2 * st->cap : 256;
            auto_sample *p = (auto_sample *)realloc(st->smp, (size_t)cap * sizeof smp);
            if (!p) return 0;
            st->smp = p;
            st->cap = cap;
        }
        st->smp[st->n++] = smp;
    }
    return 1;
}

/* The measurements as CSV (FILE.csv beside the models), to refit from
   with --fit-from without measuring again. */
static int samples_write(const fit_state *st, const char *path) {
    FILE *f = fopen(path, "w");
    int i;
    if (!f) return 0;
    fprintf(f, "method,class,pixels,nearness,scene_triangles,ms,error_px,beyond\n");
    for (i = 0; i < st->n; ++i)
        fprintf(f, "%s,%s,%lld,%.9g,%.9g,%.9g,%.9g,%.9g\n", refl_method_name((refl_method)st->smp[i].method),
                refl_auto_class_name(st->smp[i].cls), st->smp[i].f.pixels, (double)st->smp[i].f.nearness,
                (double)st->smp[i].f.scene_triangles, st->smp[i].ms, st->smp[i].error, (double)st->smp[i].f.beyond);
    return fclose(f) == 0;
}

static int samples_read(fit_state *st, const char *path) {
    FILE *f = fopen(path, "r");
    char line[256], method[32], cls[32];
    if (!f) return 0;
    while (fgets(line, sizeof line, f)) {
        auto_sample smp;
        float near, tris, beyond = 0.0f;
        memset(&smp, 0, sizeof smp);
        /* the beyond column is the last; files without it read as 0 */
        if (sscanf(line, "%31[^,],%31[^,],%lld,%f,%f,%lf,%lf,%f", method, cls, &smp.f.pixels, &near, &tris, &smp.ms,
                   &smp.error, &beyond) < 7)
            continue; /* the header */
        smp.f.beyond = beyond;
        smp.method = (int)refl_method_from_name(method);
        for (smp.cls = 0; smp.cls < REFL_AUTO_CLASS_COUNT && strcmp(cls, refl_auto_class_name(smp.cls)); ++smp.cls) {}
        smp.f.reflector_class = smp.cls;
        smp.f.nearness = near;
        smp.f.scene_triangles = tris;
        if (st->n == st->cap) {
            int cap = st->cap ? 2 * st->cap : 256;
            auto_sample *p = (auto_sample *)realloc(st->smp, (size_t)cap * sizeof smp);
            if (!p) break;
            st->smp = p;
            st->cap = cap;
        }
        st->smp[st->n++] = smp;
    }
    fclose(f);
    return st->n > 0;
}

static int run_fit(const auto_opts *o) {
    refl_auto_models models;
    fit_state st;
    char csv[600];
    size_t len;
    char *text;
    FILE *f;
    memset(&st, 0, sizeof st);
    snprintf(csv, sizeof csv, "%s.csv", o->fit_path);
    if (o->fit_from ? !samples_read(&st, o->fit_from)
                    : !each_scene(o, fit_scene, NULL, fit_collect, &st) || !samples_write(&st, csv)) {
        fprintf(stderr, "reflect bench: the measurements failed or %s could not be %s\n",
                o->fit_from ? o->fit_from : csv, o->fit_from ? "read" : "written");
        free(st.smp);
        return 0;
    }
    fit_models(st.smp, st.n, &models);
    free(st.smp);
    len = refl_auto_models_format(&models, NULL, 0);
    text = (char *)malloc(len + 1);
    if (!text) return 0;
    refl_auto_models_format(&models, text, len + 1);
    f = fopen(o->fit_path, "w");
    if (!f) {
        fprintf(stderr, "reflect bench: cannot write %s\n", o->fit_path);
        free(text);
        return 0;
    }
    fprintf(f, "# AUTO's models: reflect bench --fit-auto at %dx%d, depth %d, %d thread%s, the least CPU time of %d runs;\n"
               "# %d measurements. Format: docs/methods/auto.md\n",
            o->width, o->height, o->depth ? o->depth : REFL_DEFAULT_DEPTH, o->threads, o->threads == 1 ? "" : "s",
            o->repeats, st.n);
    fputs(text, f);
    fclose(f);
    fputs(text, stdout);
    free(text);
    return 1;
}

/* ---- the table --------------------------------------------------------------- */

/* Frame times already measured in one view, by what drew each reflector
   (AUTO's frames and the given ones apart): a budget whose choices repeat
   another's reuses its time. */
typedef struct time_cache {
    char key[8][160];
    double ms[8];
    int count;
} time_cache;

static double *cached(time_cache *c, const char *key) {
    int i;
    for (i = 0; i < c->count; ++i)
        if (!strcmp(c->key[i], key)) return &c->ms[i];
    return NULL;
}

typedef struct table_counts {
    int rows, over, slow;
    double worst;
} table_counts;

static int table_scene(const char *name, const auto_opts *o, const void *user, FILE *out) {
    const refl_auto_models *models = (const refl_auto_models *)user;
    refl_scene *s = load_builtin(name);
    refl_method *per;
    table_counts tc;
    int ci, bi, i, k, ok = 1;
    memset(&tc, 0, sizeof tc);
    if (!s) return 0;
    per = (refl_method *)calloc((size_t)s->object_count + 1, sizeof(refl_method));
    for (ci = 0; ok && per && ci < (int)(sizeof table_cameras / sizeof table_cameras[0]); ++ci) {
        refl_view v = camera_view(s, &table_cameras[ci], o->width, o->height);
        refl_frame *f = NULL;
        time_cache auto_times, given_times;
        auto_view av;
        fprintf(stderr, "table: %s %s %dx%d\n", name, table_cameras[ci].name, v.width, v.height);
        memset(&auto_times, 0, sizeof auto_times);
        memset(&given_times, 0, sizeof given_times);
        if (!measure_view(s, &v, o, &av) || refl_frame_create(v.width, v.height, NULL, &f) != REFL_OK) {
            ok = 0;
            break;
        }
        for (bi = 0; ok && bi < (int)(sizeof budgets / sizeof budgets[0]); ++bi) {
            refl_render_desc d;
            char chosen[160] = "", oracle[160] = "";
            double ms_auto, ms_oracle, ratio, *hit;
            int over_here = 0;
            memset(&d, 0, sizeof d);
            d.threads = o->threads;
            d.depth = o->depth;
            d.method = REFL_AUTO;
            d.automatic.error_budget_px = budgets[bi];
            d.automatic.models = models;
            if (timed(s, &v, &d, 1, f, &ms_auto) != REFL_OK) { ok = 0; break; }
            /* reflectors off screen (not measured: no pixel to judge) keep AUTO's choice */
            for (i = 0; i < s->object_count; ++i) per[i] = REFL_DIRECT;
            for (k = 0; k < f->stats.automatic.count && k < REFL_AUTO_MAX_CHOICES; ++k)
                per[f->stats.automatic.choices[k].object] = f->stats.automatic.choices[k].method;
            for (i = 0; i < av.count; ++i) {
                const auto_reflector *ar = &av.r[i];
                int best = -1, met = 0;
                refl_method a = REFL_RAYTRACE;
                for (k = 0; k < f->stats.automatic.count && k < REFL_AUTO_MAX_CHOICES; ++k)
                    if (f->stats.automatic.choices[k].object == ar->object) a = f->stats.automatic.choices[k].method;
                for (k = 0; k < REFL_METHOD_COUNT; ++k)
                    if (ar->measured[k] && ar->error[k] <= budgets[bi]) {
                        met = 1;
                        if (best < 0 || ar->ms[k] < ar->ms[best]) best = k;
                    }
                per[ar->object] = best >= 0 ? (refl_method)best : REFL_RAYTRACE;
                if (met && (!ar->measured[a] || ar->error[a] > budgets[bi])) over_here++;
                snprintf(chosen + strlen(chosen), sizeof chosen - strlen(chosen), "%s%s", i ? ", " : "",
                         refl_method_name(a));
                snprintf(oracle + strlen(oracle), sizeof oracle - strlen(oracle), "%s%s", i ? ", " : "",
                         refl_method_name(per[ar->object]));
            }
            /* AUTO's frame and the given one, timed in turns (the machine's load on both alike) */
            if ((hit = cached(&auto_times, chosen)) != NULL) ms_auto = *hit;
            if (!(hit = cached(&given_times, oracle))) {
                refl_render_desc g = d;
                ms_oracle = 1e300;
                g.method = REFL_DIRECT;
                g.object_methods = per;
                g.object_method_count = s->object_count;
                for (k = 0; k < o->repeats && ok; ++k) {
                    double t = 0.0;
                    if (k && !cached(&auto_times, chosen)) {
                        if (timed(s, &v, &d, 1, f, &t) != REFL_OK) ok = 0;
                        ms_auto = t < ms_auto ? t : ms_auto;
                    }
                    if (ok && timed(s, &v, &g, 1, f, &t) != REFL_OK) ok = 0;
                    ms_oracle = t < ms_oracle ? t : ms_oracle;
                }
                if (given_times.count < 8) {
                    snprintf(given_times.key[given_times.count], 160, "%s", oracle);
                    given_times.ms[given_times.count++] = ms_oracle;
                }
            } else {
                ms_oracle = *hit;
                for (k = 1; k < o->repeats && ok && !cached(&auto_times, chosen); ++k) {
                    double t = 0.0;
                    if (timed(s, &v, &d, 1, f, &t) != REFL_OK) ok = 0;
                    ms_auto = t < ms_auto ? t : ms_auto;
                }
            }
            if (!ok) break;
            if (!cached(&auto_times, chosen) && auto_times.count < 8) {
                snprintf(auto_times.key[auto_times.count], 160, "%s", chosen);
                auto_times.ms[auto_times.count++] = ms_auto;
            }
            ratio = ms_auto / (ms_oracle > 0.001 ? ms_oracle : 0.001);
            tc.worst = ratio > tc.worst ? ratio : tc.worst;
            tc.rows++;
            tc.over += over_here > 0;
            tc.slow += ratio > 1.2;
            fprintf(out, "| %s | %s | %g | %s | %s | %.1f | %.1f | %.2f | %s |\n", name, table_cameras[ci].name,
                    (double)budgets[bi], chosen, oracle, ms_auto, ms_oracle, ratio, over_here ? "**yes**" : "no");
        }
        refl_frame_destroy(f);
    }
    fprintf(out, "#counts %d %d %d %.17g\n", tc.rows, tc.over, tc.slow, tc.worst);
    free(per);
    refl_scene_destroy(s);
    return ok && per;
}

typedef struct table_state {
    FILE *md;
    table_counts all;
} table_state;

static int table_collect(FILE *in, void *state) {
    table_state *st = (table_state *)state;
    char line[512];
    while (fgets(line, sizeof line, in)) {
        table_counts c;
        if (sscanf(line, "#counts %d %d %d %lf", &c.rows, &c.over, &c.slow, &c.worst) == 4) {
            st->all.rows += c.rows;
            st->all.over += c.over;
            st->all.slow += c.slow;
            st->all.worst = c.worst > st->all.worst ? c.worst : st->all.worst;
            continue;
        }
        fputs(line, stdout);
        if (st->md) fputs(line, st->md);
    }
    return 1;
}

static int run_table(const auto_opts *o) {
    refl_auto_models models;
    table_state st;
    char line[512];
    int ok;
    memset(&st, 0, sizeof st);
    if (o->models_path) {
        char msg[200];
        if (refl_auto_models_load(o->models_path, &models, msg, sizeof msg) != REFL_OK) {
            fprintf(stderr, "reflect bench: %s\n", msg);
            return 0;
        }
    } else {
        refl_auto_models_builtin(&models);
    }
    if (o->out_path && !(st.md = fopen(o->out_path, "w"))) {
        fprintf(stderr, "reflect bench: cannot write %s\n", o->out_path);
        return 0;
    }
    snprintf(line, sizeof line,
             "| scene | camera | budget px | AUTO's choices | fastest meeting it | AUTO ms | that ms | ratio | over budget |\n"
             "|---|---|---|---|---|---|---|---|---|\n");
    fputs(line, stdout);
    if (st.md) fputs(line, st.md);
    ok = each_scene(o, table_scene, &models, table_collect, &st);
    if (ok) {
        snprintf(line, sizeof line,
                 "\n%d rows at %dx%d, depth %d, %d thread%s a frame: AUTO over 1.2x the fastest in %d, worst "
                 "%.2fx; over budget where a method meets it in %d.\n",
                 st.all.rows, o->width, o->height, o->depth ? o->depth : REFL_DEFAULT_DEPTH, o->threads,
                 o->threads == 1 ? "" : "s", st.all.slow, st.all.worst, st.all.over);
        fputs(line, stdout);
        if (st.md) fputs(line, st.md);
    }
    if (st.md) fclose(st.md);
    return ok;
}

/* The options that take a value. */
static const char *const auto_value_options[] = {"--fit-auto", "--fit-from", "--models",  "--out",  "--scenes", "--methods",
                                                 "--size",     "--threads",  "--repeats", "--jobs", "--depth",  NULL};

int refl_bench_auto(int argc, char **argv) {
    auto_opts o;
    int i;
    unsigned long long given = 0; /* the value options seen (cli_given_twice) */
    memset(&o, 0, sizeof o);
    o.width = 320;
    o.height = 240;
    o.threads = 1;
    o.repeats = 3;
    o.jobs = 1;
    parse_methods("raytrace,envmap,planar,c3rc,sbc,spoc,graphcam", &o);
    for (i = 2; i < argc; ++i) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (v && cli_given_twice("reflect bench", auto_value_options, a, &given)) return 2;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(usage_auto, stdout);
            return 0;
        } else if (!strcmp(a, "--fit-auto") && v) {
            o.fit_path = v;
            ++i;
        } else if (!strcmp(a, "--fit-from") && v) {
            o.fit_from = v;
            ++i;
        } else if (!strcmp(a, "--auto-table")) {
            o.table = 1;
        } else if (!strcmp(a, "--models") && v) {
            o.models_path = v;
            ++i;
        } else if (!strcmp(a, "--out") && v) {
            o.out_path = v;
            ++i;
        } else if (!strcmp(a, "--scenes") && v) {
            o.scenes = v;
            ++i;
        } else if (!strcmp(a, "--methods") && v) {
            if (!parse_methods(v, &o)) return 2;
            ++i;
        } else if (!strcmp(a, "--size") && v) {
            if (sscanf(v, "%dx%d", &o.width, &o.height) != 2 || o.width < 16 || o.height < 16 || o.width > 4096 ||
                o.height > 4096) {
                fprintf(stderr, "reflect bench: bad --size '%s' (WxH, 16 to 4096)\n", v);
                return 2;
            }
            ++i;
        } else if ((!strcmp(a, "--threads") || !strcmp(a, "--repeats") || !strcmp(a, "--jobs") ||
                    !strcmp(a, "--depth")) &&
                   v) {
            char *end;
            long x = strtol(v, &end, 10);
            if (*end || x < (a[2] == 't' || a[2] == 'd' ? 0 : 1) || x > (a[2] == 'r' ? 32 : 64)) {
                fprintf(stderr, "reflect bench: bad %s '%s'\n", a, v);
                return 2;
            }
            if (a[2] == 'r') o.repeats = (int)x;
            else if (a[2] == 'j') o.jobs = (int)x;
            else if (a[2] == 'd') o.depth = (int)x;
            else o.threads = (int)x;
            ++i;
        } else {
            fprintf(stderr, "reflect bench: unknown option '%s'\n\n%s", a, usage_auto);
            return 2;
        }
    }
    if (!o.fit_path == !o.table) {
        fprintf(stderr, "reflect bench: one of --fit-auto FILE and --auto-table\n\n%s", usage_auto);
        return 2;
    }
    return (o.table ? run_table(&o) : run_fit(&o)) ? 0 : 1;
}
