/* Helpers shared by the reflect.h tests: a frame rendered or the test
   fails, scene objects in one call, a counting allocator and the runs
   that fail each allocation in turn. Include after
   <criterion/criterion.h> and "../reflect.h". */
#ifndef REFL_TEST_UTIL_H
#define REFL_TEST_UTIL_H

#include <math.h>
#include <stdint.h>
#include <string.h>
#include "../test_util.h"

/* A new frame of the view rendered with desc (asserting success). */
static inline refl_frame *tu_refl_render(const refl_scene *s, const refl_view *v, const refl_render_desc *d) {
    refl_frame *f = NULL;
    refl_result r;
    cr_assert_eq(refl_frame_create(v->width, v->height, NULL, &f), REFL_OK);
    r = refl_render(s, v, d, f);
    cr_assert_eq(r, REFL_OK, "refl_render (%s): %s", refl_method_name(d->method), refl_result_string(r));
    return f;
}

/* A render desc of method m on `threads` threads, every option its default. */
static inline refl_render_desc tu_refl_desc(refl_method m, int threads) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = m;
    d.threads = threads;
    return d;
}

/* A render desc of method m on `threads` threads, one bounce. */
static inline refl_render_desc tu_refl_one_bounce(refl_method m, int threads) {
    refl_render_desc d = tu_refl_desc(m, threads);
    d.depth = 1;
    return d;
}

/* Greedy RAYTRACE on `threads` threads: paper 001's two-term paths, the
   truth LAYERED_EM's maps approximate. */
static inline refl_render_desc tu_refl_greedy_raytrace(int threads) {
    refl_render_desc d = tu_refl_desc(REFL_RAYTRACE, threads);
    d.raytrace.greedy = 1;
    return d;
}

/* Built-in scene `name` (asserting success) and its camera at w x h. */
static inline refl_scene *tu_refl_builtin(const char *name, refl_view *v, int w, int h) {
    refl_scene *s = NULL;
    cr_assert_eq(refl_scene_builtin(name, NULL, &s), REFL_OK);
    *v = s->camera;
    v->width = w;
    v->height = h;
    return s;
}

/* Pixel i's linear colour as 8-bit levels (tu_unorm8): what the tests
   compare against expected 8-bit values. */
static inline void tu_pixel8(const refl_frame *f, size_t i, int out[4]) {
    int c;
    for (c = 0; c < 4; ++c) out[c] = tu_unorm8(f->rgba[4 * i + (size_t)c]);
}

/* A 64-bit FNV-1a digest of a frame's colour, depth, stencil and points:
   equal digests, the same bytes. */
static inline uint64_t tu_refl_digest(const refl_frame *f) {
    size_t n = (size_t)f->width * (size_t)f->height, i;
    const unsigned char *parts[4];
    size_t sizes[4];
    uint64_t h = 0xCBF29CE484222325ull;
    int k;
    parts[0] = (const unsigned char *)f->rgba; sizes[0] = 4 * n * sizeof(float);
    parts[1] = (const unsigned char *)f->depth; sizes[1] = n * sizeof(float);
    parts[2] = f->stencil; sizes[2] = n;
    parts[3] = (const unsigned char *)f->points; sizes[3] = 3 * n * sizeof(float);
    for (k = 0; k < 4; ++k)
        for (i = 0; i < sizes[k]; ++i) h = (h ^ parts[k][i]) * 0x100000001B3ull;
    return h;
}

/* Whether two frame points are the same: both none (NaN) or equal in
   every coordinate. */
static inline int tu_refl_same_point(const float *a, const float *b) {
    return (a[0] != a[0] && b[0] != b[0]) || (a[0] == b[0] && a[1] == b[1] && a[2] == b[2]);
}

/* A view from eye towards target, y up, 45 degrees vertical, w x h. */
static inline refl_view tu_refl_view(refl_vec3 eye, refl_vec3 target, int w, int h) {
    refl_view v;
    memset(&v, 0, sizeof v);
    v.eye = eye;
    v.target = target;
    v.up = refl_v3(0, 1, 0);
    v.fovy_degrees = 45.0f;
    v.width = w;
    v.height = h;
    return v;
}

/* An object of `mesh` (the scene takes it) with a fresh material of the
   given type and colour; its index. */
static inline int tu_refl_add_object(refl_scene *s, refl_mesh *mesh, refl_material_type type, const float rgb[3],
                                     refl_mat4 xf) {
    refl_material m;
    refl_object o;
    int k;
    memset(&m, 0, sizeof m);
    memset(&o, 0, sizeof o);
    m.type = type;
    m.color[0] = rgb[0]; m.color[1] = rgb[1]; m.color[2] = rgb[2]; m.color[3] = 1.0f;
    o.mesh = refl_scene_add_mesh(s, mesh);
    o.material = refl_scene_add_material(s, &m);
    o.transform = xf;
    cr_assert(o.mesh >= 0 && o.material >= 0);
    k = refl_scene_add_object(s, &o);
    cr_assert(k >= 0);
    return k;
}

/* A white point light of the given intensity and radius (0: a point). */
static inline void tu_refl_add_point_light(refl_scene *s, refl_vec3 position, float intensity, float radius) {
    refl_light l;
    memset(&l, 0, sizeof l);
    l.type = REFL_LIGHT_POINT;
    l.position = position;
    l.color[0] = l.color[1] = l.color[2] = intensity;
    l.radius = radius;
    cr_assert(refl_scene_add_light(s, &l) >= 0);
}

/* An allocator counting into c (tests/test_util.h's tu_count_alloc). */
static inline refl_allocator tu_refl_counting(tu_alloc_counter *c) {
    refl_allocator a;
    a.alloc = tu_count_alloc;
    a.free = tu_count_free;
    a.user = c;
    return a;
}

/* Renders v with d into f once (OK), then again failing each allocation
   that render made, one per run: each run OUT_OF_MEMORY and leaking
   nothing (c counts the scene's allocator). Returns how many allocations
   the render makes. */
static inline long tu_refl_fail_each_render_allocation(const refl_scene *s, const refl_view *v,
                                                       const refl_render_desc *d, refl_frame *f, tu_alloc_counter *c) {
    long base = c->attempts, needed, k;
    cr_assert_eq(refl_render(s, v, d, f), REFL_OK);
    needed = c->attempts - base;
    for (k = 1; k <= needed; ++k) {
        long live = c->allocs - c->frees;
        c->fail_at = c->attempts + k;
        cr_assert_eq(refl_render(s, v, d, f), REFL_ERROR_OUT_OF_MEMORY, "failing allocation %ld of %ld", k, needed);
        cr_assert_eq(c->allocs - c->frees, live, "allocation %ld failed: leaked", k);
    }
    c->fail_at = 0;
    return needed;
}

/* What tu_refl_default_allocation_failures saw. */
typedef struct tu_refl_failed_runs {
    long runs;         /* runs made: one per allocation failed, the last reaching none (or max_runs) */
    int scene_failed;  /* a run's scene build failed */
    int render_failed; /* a run's render failed */
} tu_refl_failed_runs;

/* Every allocation of building `default` (teapot_tess 2) and rendering it
   at 32 x 24 with d may fail, each in turn from the first (up to
   max_runs): each run OUT_OF_MEMORY (no scene) or a success, and nothing
   leaked. */
static inline tu_refl_failed_runs tu_refl_default_allocation_failures(const refl_render_desc *d, long max_runs) {
    tu_refl_failed_runs out;
    long k;
    memset(&out, 0, sizeof out);
    for (k = 1; k < max_runs; ++k) {
        tu_alloc_counter c;
        refl_builtin_desc bd;
        refl_scene *s = NULL;
        refl_result r;
        memset(&c, 0, sizeof c);
        c.fail_at = k;
        memset(&bd, 0, sizeof bd);
        bd.teapot_tess = 2;
        bd.allocator = tu_refl_counting(&c);
        r = refl_scene_builtin("default", &bd, &s);
        if (r == REFL_OK) {
            refl_frame *f = NULL;
            refl_view v = s->camera;
            v.width = 32;
            v.height = 24;
            if (refl_frame_create(32, 24, &bd.allocator, &f) == REFL_OK) {
                r = refl_render(s, &v, d, f);
                cr_assert(r == REFL_OK || r == REFL_ERROR_OUT_OF_MEMORY, "k=%ld: %s", k, refl_result_string(r));
                if (r != REFL_OK) out.render_failed = 1;
                refl_frame_destroy(f);
            }
            refl_scene_destroy(s);
        } else {
            cr_assert_null(s);
            cr_assert_eq(r, REFL_ERROR_OUT_OF_MEMORY, "k=%ld: %s", k, refl_result_string(r));
            out.scene_failed = 1;
        }
        cr_assert_eq(c.allocs, c.frees, "k=%ld: %ld allocations, %ld frees", k, c.allocs, c.frees);
        if (!c.failed) break; /* ran to the end without reaching allocation k */
    }
    out.runs = k;
    return out;
}

/* Every colour byte opaque on reflectors; points NaN in all three or none,
   and only on reflector pixels; non-reflector pixels DIRECT's bytes. */
static inline void tu_assert_reflector_frame(const refl_frame *f, const refl_frame *direct) {
    int i, n = f->width * f->height;
    for (i = 0; i < n; ++i) {
        const float *p = f->points + 3 * i;
        int nan_count = (p[0] != p[0]) + (p[1] != p[1]) + (p[2] != p[2]);
        cr_assert(nan_count == 0 || nan_count == 3, "pixel %d: partly NaN point", i);
        cr_assert_eq(f->stencil[i], direct->stencil[i]);
        if (!f->stencil[i]) {
            cr_assert_eq(memcmp(f->rgba + 4 * i, direct->rgba + 4 * i, (4) * sizeof(float)), 0, "pixel %d differs from DIRECT", i);
            cr_assert_eq(nan_count, 3, "pixel %d off the reflectors has a point", i);
        } else {
            cr_assert(isfinite(p[0]) || nan_count == 3);
            cr_assert_eq(tu_unorm8(f->rgba[4 * i + 3]), 255);
        }
    }
}

/* The glass pixels of f (by its stencil) are truth's colours, bit for bit
   (a method that hands glass to RAYTRACE's tracer); how many there were. */
static inline int tu_assert_glass_as_truth(const refl_scene *s, const refl_frame *f, const refl_frame *truth) {
    int i, shown = 0;
    for (i = 0; i < f->width * f->height; ++i) {
        int object = f->stencil[i] - 1;
        if (object < 0 || s->materials[s->objects[object].material].type != REFL_GLASS) continue;
        ++shown;
        cr_assert_eq(memcmp(f->rgba + 4 * (size_t)i, truth->rgba + 4 * (size_t)i, 4 * sizeof(float)), 0, "pixel %d", i);
    }
    return shown;
}

/* A scene of objects and a BVH over them as a ray caster (refl_greedy_paths,
   refl_lens_tessellate, refl_lem_record_view). */
typedef struct tu_refl_traced {
    refl_scene *scene;
    refl_bvh *bvh;
    refl_ray_caster caster;
} tu_refl_traced;

static inline int tu_refl_bvh_intersect(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax, refl_hit *hit) {
    return refl_bvh_intersect((const refl_bvh *)user, o, d, tmin, tmax, hit);
}

/* Scene s (taken: tu_refl_traced_free destroys it) and its BVH. */
static inline tu_refl_traced tu_refl_traced_scene(refl_scene *s) {
    tu_refl_traced t;
    memset(&t, 0, sizeof t);
    t.scene = s;
    cr_assert_eq(refl_bvh_build(s, NULL, &t.bvh), REFL_OK);
    t.caster.intersect = tu_refl_bvh_intersect;
    t.caster.user = t.bvh;
    return t;
}

/* A new scene of the one object (mesh taken) and its BVH. */
static inline tu_refl_traced tu_refl_traced_object(refl_mesh *mesh, const refl_material *m, refl_mat4 transform) {
    refl_scene *s = NULL;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_scene_add(s, mesh, m, transform), 0);
    return tu_refl_traced_scene(s);
}

static inline void tu_refl_traced_free(tu_refl_traced *t) {
    refl_bvh_destroy(t->bvh);
    refl_scene_destroy(t->scene);
}

/* A 64 x 32 texture of colour rings and stripes on a diagonal ramp,
   added to s (its id): every texel different, so a map that puts it in
   the wrong place shows. */
static inline int tu_refl_add_rings(refl_scene *s) {
    enum { W = 64, H = 32 };
    float tex[W * H * 4];
    int x, y;
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            float *p = tex + 4 * (y * W + x), r = sqrtf((float)((x - 20) * (x - 20) + (y - 12) * (y - 12)));
            p[0] = 0.5f + 0.4f * sinf(2.0f * r);
            p[1] = 0.15f + 0.7f * (float)(x + y) / (W + H);
            p[2] = 0.5f + 0.4f * cosf(2.0f * (float)x);
            p[3] = 1.0f;
        }
    return refl_scene_add_texture(s, W, H, tex);
}

#endif
