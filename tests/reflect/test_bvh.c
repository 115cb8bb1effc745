/* The triangle BVH: agreement with brute force, watertightness on closed
   meshes (rays through vertices and edges included), occlusion against
   intersection, the default scene, determinism, the wide tree against the
   binary one and its SIMD box tests against the scalar ones (every
   built-in scene and the shared assets), bad input, allocation failure
   at every allocation, and queries bounded by tmax against the triangle
   test on every triangle (rays starting next to a surface). */
#define _POSIX_C_SOURCE 200809L
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include "../../reflect.h"
#include "../../tools/gltf_load.h"
#include "../reflect_testing.h"
#include "../test_util.h"
#include "refl_test_util.h"


static float rnd(refl_rng *r, float lo, float hi) { return lo + (hi - lo) * refl_rng_float(r); }

static refl_vec3 rnd_dir(refl_rng *r) {
    for (;;) {
        refl_vec3 d = refl_v3(rnd(r, -1, 1), rnd(r, -1, 1), rnd(r, -1, 1));
        float l = refl_v3_length(d);
        if (l > 0.05f && l <= 1) return refl_v3_scale(d, 1 / l);
    }
}

static int add_object(refl_scene *s, refl_mesh *m, refl_mat4 transform) {
    refl_object o;
    int mi = refl_scene_add_mesh(s, m), oi;
    cr_assert(mi >= 0);
    if (s->material_count == 0) {
        refl_material mat;
        memset(&mat, 0, sizeof mat);
        cr_assert(refl_scene_add_material(s, &mat) >= 0);
    }
    memset(&o, 0, sizeof o);
    o.mesh = mi;
    o.transform = transform;
    oi = refl_scene_add_object(s, &o);
    cr_assert(oi >= 0);
    return oi;
}

/* `objects` objects of `per` random triangles each (some small, some
   large), under random rotations, scales and translations. */
static refl_scene *random_scene(uint64_t seed, int objects, int per) {
    refl_rng r = refl_rng_seed(seed);
    refl_scene *s = NULL;
    refl_material mat;
    int i, k;
    float *pos = (float *)malloc(sizeof(float) * 9 * (size_t)per);
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    memset(&mat, 0, sizeof mat);
    cr_assert(refl_scene_add_material(s, &mat) >= 0);
    for (i = 0; i < objects; ++i) {
        refl_mesh_desc d;
        refl_mesh *m = NULL;
        refl_mat4 t;
        for (k = 0; k < per; ++k) {
            float cx = rnd(&r, -3, 3), cy = rnd(&r, -3, 3), cz = rnd(&r, -3, 3), size = rnd(&r, 0.05f, 1.0f);
            int j;
            for (j = 0; j < 3; ++j) {
                pos[9 * k + 3 * j] = cx + rnd(&r, -size, size);
                pos[9 * k + 3 * j + 1] = cy + rnd(&r, -size, size);
                pos[9 * k + 3 * j + 2] = cz + rnd(&r, -size, size);
            }
        }
        memset(&d, 0, sizeof d);
        d.positions = pos;
        d.vertex_count = 3 * per;
        cr_assert_eq(refl_mesh_create(&d, &m), REFL_OK);
        t = refl_mat4_mul(refl_mat4_translate(refl_v3(rnd(&r, -2, 2), rnd(&r, -2, 2), rnd(&r, -2, 2))),
                          refl_mat4_mul(refl_mat4_rotate(rnd_dir(&r), rnd(&r, 0, 6.28f)),
                                        refl_mat4_scale(refl_v3(rnd(&r, 0.5f, 1.5f), rnd(&r, 0.5f, 1.5f),
                                                                rnd(&r, 0.5f, 1.5f)))));
        add_object(s, m, t);
    }
    free(pos);
    return s;
}

/* Triangle t of object i in world space: 3 corners, x y z each. */
static void world_triangle(const refl_scene *s, int i, int t, float tri[9]) {
    const refl_mesh *m = s->meshes[s->objects[i].mesh];
    int j;
    for (j = 0; j < 3; ++j) {
        const float *p = m->positions + 3 * (size_t)m->indices[3 * (size_t)t + j];
        refl_vec3 w = refl_mat4_point(s->objects[i].transform, refl_v3(p[0], p[1], p[2]));
        tri[3 * j] = w.x, tri[3 * j + 1] = w.y, tri[3 * j + 2] = w.z;
    }
}

/* Reference: every triangle, Moeller-Trumbore in double. *margin gets the
   smallest barycentric of the closest hit, to excuse rays that graze an
   edge (where float and double may rightly disagree). */
static int brute_force(const refl_scene *s, refl_vec3 o, refl_vec3 d, float tmin, float tmax, refl_hit *hit,
                       double *margin) {
    int i, t, found = 0;
    double best = tmax;
    for (i = 0; i < s->object_count; ++i) {
        const refl_mesh *m = s->meshes[s->objects[i].mesh];
        for (t = 0; t < m->triangle_count; ++t) {
            double v[3][3], e1[3], e2[3], p[3], q[3], tv[3], det, u, w, tt;
            float tri[9];
            int j;
            world_triangle(s, i, t, tri);
            for (j = 0; j < 9; ++j) v[j / 3][j % 3] = tri[j];
            for (j = 0; j < 3; ++j) {
                e1[j] = v[1][j] - v[0][j];
                e2[j] = v[2][j] - v[0][j];
                tv[j] = (j == 0 ? o.x : j == 1 ? o.y : o.z) - v[0][j];
            }
            p[0] = d.y * e2[2] - d.z * e2[1];
            p[1] = d.z * e2[0] - d.x * e2[2];
            p[2] = d.x * e2[1] - d.y * e2[0];
            det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
            if (det == 0) continue;
            u = (tv[0] * p[0] + tv[1] * p[1] + tv[2] * p[2]) / det;
            q[0] = tv[1] * e1[2] - tv[2] * e1[1];
            q[1] = tv[2] * e1[0] - tv[0] * e1[2];
            q[2] = tv[0] * e1[1] - tv[1] * e1[0];
            w = (d.x * q[0] + d.y * q[1] + d.z * q[2]) / det;
            tt = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
            if (u < 0 || w < 0 || u + w > 1) continue;
            if (!(tt > tmin && tt < best)) continue;
            best = tt;
            found = 1;
            hit->t = (float)tt;
            hit->object = i;
            hit->triangle = t;
            hit->u = (float)u;
            hit->v = (float)w;
            *margin = fmin(fmin(u, w), 1 - u - w);
        }
    }
    return found;
}

static void random_ray(refl_rng *r, refl_vec3 *o, refl_vec3 *d) {
    *o = refl_v3(rnd(r, -6, 6), rnd(r, -6, 6), rnd(r, -6, 6));
    /* Aim near the scene, so most rays hit something. */
    *d = refl_v3_sub(refl_v3(rnd(r, -3, 3), rnd(r, -3, 3), rnd(r, -3, 3)), *o);
    /* Some axis-aligned components: infinite inverse directions. */
    if (refl_rng_u32(r) % 8 == 0) d->x = 0;
    if (refl_rng_u32(r) % 8 == 0) d->y = 0;
    if (d->x == 0 && d->y == 0 && d->z == 0) d->z = 1;
}

Test(refl_bvh, matches_brute_force_on_random_scenes) {
    int scene_i;
    for (scene_i = 0; scene_i < 3; ++scene_i) {
        refl_scene *s = random_scene(1234 + scene_i, 5, 80);
        refl_bvh *bvh = NULL;
        refl_rng r = refl_rng_seed(99 + scene_i);
        long long nodes, tris;
        int i, hits = 0, grazing = 0;
        cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
        refl_bvh_stats(bvh, &nodes, &tris);
        cr_assert_eq(tris, 400);
        cr_assert(nodes >= 1 && nodes <= 2 * tris - 1);
        for (i = 0; i < 20000; ++i) {
            refl_vec3 o, d;
            refl_hit a, b;
            double margin = 1;
            int ha, hb;
            float tmin = (i % 5 == 0) ? 0.3f : 0.0f, tmax = (i % 7 == 0) ? 0.8f : INFINITY;
            random_ray(&r, &o, &d);
            memset(&a, 0, sizeof a);
            memset(&b, 0, sizeof b);
            ha = refl_bvh_intersect(bvh, o, d, tmin, tmax, &a);
            hb = brute_force(s, o, d, tmin, tmax, &b, &margin);
            if (ha != hb || (ha && (a.object != b.object || a.triangle != b.triangle))) {
                /* Only rays within a hair of an edge may disagree. */
                cr_assert(margin < 1e-5, "ray %d: bvh %d (%d/%d t=%g) vs brute %d (%d/%d t=%g) margin %g", i, ha,
                          a.object, a.triangle, ha ? a.t : 0, hb, b.object, b.triangle, hb ? b.t : 0, margin);
                ++grazing;
                continue;
            }
            if (!ha) continue;
            ++hits;
            cr_assert(fabsf(a.t - b.t) <= 1e-5f * fabsf(b.t) + 1e-6f, "ray %d: t %.9g vs %.9g", i, a.t, b.t);
            cr_assert(fabsf(a.u - b.u) < 1e-3f && fabsf(a.v - b.v) < 1e-3f, "ray %d: uv", i);
        }
        cr_assert(hits > 2000, "only %d hits", hits);
        cr_assert(grazing <= 2, "%d grazing disagreements", grazing);
        refl_bvh_destroy(bvh);
        refl_scene_destroy(s);
    }
}

/* Every ray from inside a closed mesh must hit it: directions at random,
   at every vertex and at every edge's midpoint and endpoints. */
static void check_closed(refl_scene *s, refl_vec3 centre, int random_rays) {
    refl_bvh *bvh = NULL;
    refl_rng r = refl_rng_seed(7);
    const refl_mesh *m = s->meshes[s->objects[0].mesh];
    refl_mat4 tr = s->objects[0].transform;
    int i, j;
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    for (i = 0; i < random_rays; ++i) {
        refl_vec3 d = rnd_dir(&r);
        cr_assert(refl_bvh_intersect(bvh, centre, d, 0, INFINITY, NULL), "random ray %d escaped", i);
    }
    for (i = 0; i < m->vertex_count; ++i) {
        const float *p = m->positions + 3 * i;
        refl_vec3 w = refl_mat4_point(tr, refl_v3(p[0], p[1], p[2]));
        refl_hit h;
        cr_assert(refl_bvh_intersect(bvh, centre, refl_v3_sub(w, centre), 0, INFINITY, &h),
                  "ray at vertex %d escaped", i);
        /* ... and it hits that vertex, at t = 1 */
        cr_assert(fabsf(h.t - 1) < 1e-4f, "vertex %d: t %g", i, h.t);
    }
    for (i = 0; i < m->triangle_count; ++i)
        for (j = 0; j < 3; ++j) {
            const float *p = m->positions + 3 * m->indices[3 * i + j];
            const float *q = m->positions + 3 * m->indices[3 * i + (j + 1) % 3];
            refl_vec3 a = refl_mat4_point(tr, refl_v3(p[0], p[1], p[2]));
            refl_vec3 b = refl_mat4_point(tr, refl_v3(q[0], q[1], q[2]));
            int k;
            for (k = 1; k < 8; ++k) {
                float f = (float)k / 8;
                refl_vec3 e = refl_v3_add(refl_v3_scale(a, 1 - f), refl_v3_scale(b, f));
                cr_assert(refl_bvh_intersect(bvh, centre, refl_v3_sub(e, centre), 0, INFINITY, NULL),
                          "ray at edge %d/%d (%g) escaped", i, j, f);
                cr_assert(refl_bvh_occluded(bvh, centre, refl_v3_sub(e, centre), 0, INFINITY));
            }
        }
    refl_bvh_destroy(bvh);
}

Test(refl_bvh, closed_meshes_are_watertight) {
    refl_scene *s = NULL;
    refl_mesh *m = NULL, *sub = NULL;
    refl_mat4 t = refl_mat4_mul(refl_mat4_translate(refl_v3(0.3f, -1.7f, 2.1f)),
                                refl_mat4_rotate(refl_v3_normalize(refl_v3(1, 2, 3)), 0.7f));
    /* A sphere, moved and turned so its world floats are not round. */
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(1.3f, 48, 24, NULL, &m), REFL_OK);
    add_object(s, m, t);
    check_closed(s, refl_mat4_point(t, refl_v3(0, 0, 0)), 100000);
    refl_scene_destroy(s);

    /* A subdivided box, seen from its centre and in its own frame: rays
       along the faces' diagonals and through the corners. */
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(2, 2, 2), NULL, &m), REFL_OK);
    cr_assert_eq(refl_mesh_subdivide(m, 0.5f, &sub), REFL_OK);
    refl_mesh_destroy(m);
    add_object(s, sub, refl_mat4_identity());
    check_closed(s, refl_v3(0, 0, 0), 20000);
    refl_scene_destroy(s);
}

Test(refl_bvh, occluded_agrees_with_intersect) {
    refl_scene *s = random_scene(77, 4, 100);
    refl_bvh *bvh = NULL;
    refl_rng r = refl_rng_seed(5);
    int i;
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    for (i = 0; i < 20000; ++i) {
        refl_vec3 o, d;
        float tmax = (i % 3 == 0) ? rnd(&r, 0.1f, 1.0f) : INFINITY;
        random_ray(&r, &o, &d);
        cr_assert_eq(refl_bvh_occluded(bvh, o, d, 0, tmax), refl_bvh_intersect(bvh, o, d, 0, tmax, NULL) != 0,
                     "ray %d", i);
    }
    refl_bvh_destroy(bvh);
    refl_scene_destroy(s);
}

static int object_named(const refl_scene *s, const char *name) {
    int i;
    for (i = 0; i < s->object_count; ++i)
        if (!strcmp(s->objects[i].name, name)) return i;
    return -1;
}

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Primary rays through pixel centres of the scene's camera. */
static refl_vec3 camera_ray(const refl_view *v, int w, int h, float px, float py) {
    refl_vec3 f = refl_v3_normalize(refl_v3_sub(v->target, v->eye));
    refl_vec3 right = refl_v3_normalize(refl_v3_cross(f, v->up));
    refl_vec3 up = refl_v3_cross(right, f);
    float th = tanf((v->fovy_degrees > 0 ? v->fovy_degrees : 45.0f) * 3.14159265f / 360.0f);
    float sx = (2 * px / w - 1) * th * w / h, sy = (1 - 2 * py / h) * th;
    return refl_v3_add(f, refl_v3_add(refl_v3_scale(right, sx), refl_v3_scale(up, sy)));
}

Test(refl_bvh, default_scene) {
    refl_scene *s = NULL;
    refl_bvh *bvh = NULL;
    refl_hit h;
    long long nodes, tris;
    int teapot, x, y, hits = 0;
    double t0, dt;
    const int w = 640, hgt = 480;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    teapot = object_named(s, "teapot");
    cr_assert(teapot >= 0);
    t0 = now_s();
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    dt = now_s() - t0;
    refl_bvh_stats(bvh, &nodes, &tris);
    cr_assert(tris > 0 && tris <= refl_scene_triangles(s));
    cr_log_info("default scene: %lld nodes, %lld triangles (of %lld), built in %.1f ms", nodes, tris,
                refl_scene_triangles(s), dt * 1e3);

    /* Straight down onto the lid (through its knob's pole, then just off it). */
    cr_assert(refl_bvh_intersect(bvh, refl_v3(0, 50, 0), refl_v3(0, -1, 0), 0, INFINITY, &h));
    cr_assert_eq(h.object, teapot);
    cr_assert(refl_bvh_intersect(bvh, refl_v3(0.031f, 50, -0.017f), refl_v3(0, -1, 0), 0, INFINITY, &h));
    cr_assert_eq(h.object, teapot);

    cr_assert(s->has_camera);
    cr_assert(refl_bvh_intersect(bvh, s->camera.eye, refl_v3_sub(s->camera.target, s->camera.eye), 0, INFINITY,
                                 &h));
    cr_assert(refl_bvh_intersect(bvh, s->camera.eye, camera_ray(&s->camera, w, hgt, w * 0.5f, hgt * 0.5f), 0,
                                 INFINITY, &h));

    /* Throughput, single-threaded, primary rays at 640x480. */
    t0 = now_s();
    for (y = 0; y < hgt; ++y)
        for (x = 0; x < w; ++x)
            hits += refl_bvh_intersect(bvh, s->camera.eye, camera_ray(&s->camera, w, hgt, x + 0.5f, y + 0.5f), 0,
                                       INFINITY, &h);
    dt = now_s() - t0;
    cr_log_info("default scene: %d of %d primary rays hit, %.2f Mrays/s", hits, w * hgt, w * hgt / dt * 1e-6);
    cr_assert(hits > w * hgt / 4);
    refl_bvh_destroy(bvh);
    refl_scene_destroy(s);
}

Test(refl_bvh, deterministic) {
    refl_scene *s = random_scene(4242, 6, 60);
    refl_bvh *a = NULL, *b = NULL;
    refl_rng r = refl_rng_seed(11);
    long long na, ta, nb, tb;
    int i;
    cr_assert_eq(refl_bvh_build(s, NULL, &a), REFL_OK);
    cr_assert_eq(refl_bvh_build(s, NULL, &b), REFL_OK);
    refl_bvh_stats(a, &na, &ta);
    refl_bvh_stats(b, &nb, &tb);
    cr_assert_eq(na, nb);
    cr_assert_eq(ta, tb);
    for (i = 0; i < 5000; ++i) {
        refl_vec3 o, d;
        refl_hit ha, hb;
        int ra, rb;
        random_ray(&r, &o, &d);
        memset(&ha, 0, sizeof ha);
        memset(&hb, 0, sizeof hb);
        ra = refl_bvh_intersect(a, o, d, 0, INFINITY, &ha);
        rb = refl_bvh_intersect(b, o, d, 0, INFINITY, &hb);
        cr_assert_eq(ra, rb);
        cr_assert_eq(memcmp(&ha, &hb, sizeof ha), 0, "ray %d", i);
    }
    refl_bvh_destroy(a);
    refl_bvh_destroy(b);
    refl_scene_destroy(s);
}

/* ---- the wide tree against the binary one ----------------------------------- */

/* Tests run from the repository root. */
#define BVH_ASSETS "../shared/assets"

/* Random rays per scene, and the primary grid's divisor: fewer under the
   sanitizers, whose run has a time bound (make test). */
#define BVH_RANDOM_RAYS (tu_sanitized() ? 2000 : 20000)
#define BVH_GRID_DIV (tu_sanitized() ? 2 : 1)

/* One ray through the four traversals (tests/reflect_testing.h): the wide
   tree with SIMD box tests (AVX2 where the CPU has it), lane by lane, the
   binary tree, and the wide tree with SSE2 alone must return the same
   hit, bit for bit. Returns the hit flag. */
static int same_hit_every_way(const refl_bvh *bvh, refl_vec3 o, refl_vec3 d, float tmin, float tmax,
                              const char *what, long long i, refl_hit *out) {
    refl_hit h[4];
    int r[4], k;
    for (k = 0; k < 4; ++k) {
        memset(&h[k], 0, sizeof h[k]);
        r[k] = refl__testing_bvh_intersect_path(bvh, o, d, tmin, tmax, k, &h[k]);
    }
    for (k = 1; k < 4; ++k) {
        cr_assert_eq(r[k], r[0], "%s ray %lld: traversal %d hit %d, wide %d", what, i, k, r[k], r[0]);
        cr_assert_eq(memcmp(&h[k], &h[0], sizeof h[0]), 0,
                     "%s ray %lld: traversal %d names object %d triangle %d t %.9g, wide object %d triangle %d "
                     "t %.9g", what, i, k, h[k].object, h[k].triangle, h[k].t, h[0].object, h[0].triangle, h[0].t);
    }
    /* the public entry points take the wide tree */
    cr_assert_eq(refl_bvh_intersect(bvh, o, d, tmin, tmax, &h[1]), r[0]);
    cr_assert(!r[0] || memcmp(&h[1], &h[0], sizeof h[0]) == 0);
    cr_assert_eq(refl_bvh_occluded(bvh, o, d, tmin, tmax), r[0], "%s ray %lld: occluded", what, i);
    if (out) *out = h[0];
    return r[0];
}

/* Primary rays through the pixel centres of w x h from the scene's
   camera, the mirror ray of each hit about the
   geometric normal, and random rays across the bounds, some with a finite
   tmax, some starting at a hit's distance (ties at tmin). */
static void check_wide_matches_binary(const char *name, const refl_scene *s, int w, int h) {
    refl_bvh *bvh = NULL;
    refl_view v = s->camera;
    refl_vec3 lo, hi, c;
    refl_rng r = refl_rng_seed(2024);
    float diag;
    long long i = 0, hits = 0;
    int x, y;
    cr_assert_eq(refl__testing_bvh_build_binary_too(s, &bvh), REFL_OK, "%s", name);
    refl_scene_bounds(s, &lo, &hi);
    c = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    diag = refl_v3_length(refl_v3_sub(hi, lo));
    cr_assert(s->has_camera, "%s", name);
    w /= BVH_GRID_DIV;
    h /= BVH_GRID_DIV;
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x, ++i) {
            refl_vec3 d = camera_ray(&v, w, h, x + 0.5f, y + 0.5f), ng, p;
            refl_hit a;
            float e[3][3];
            int k;
            if (!same_hit_every_way(bvh, v.eye, d, 0, INFINITY, "primary", i, &a)) continue;
            ++hits;
            /* the same ray again from its hit's distance, and up to it */
            same_hit_every_way(bvh, v.eye, d, a.t, INFINITY, "from the hit", i, NULL);
            same_hit_every_way(bvh, v.eye, d, 0, a.t, "up to the hit", i, NULL);
            /* the mirror ray about the geometric normal, from the hit */
            {
                const refl_object *o = &s->objects[a.object];
                const refl_mesh *m = s->meshes[o->mesh];
                for (k = 0; k < 3; ++k) {
                    const float *q = m->positions + 3 * (size_t)m->indices[3 * (size_t)a.triangle + k];
                    refl_vec3 wv = refl_mat4_point(o->transform, refl_v3(q[0], q[1], q[2]));
                    e[k][0] = wv.x;
                    e[k][1] = wv.y;
                    e[k][2] = wv.z;
                }
                ng = refl_v3_normalize(refl_v3_cross(refl_v3(e[1][0] - e[0][0], e[1][1] - e[0][1], e[1][2] - e[0][2]),
                                                     refl_v3(e[2][0] - e[0][0], e[2][1] - e[0][1], e[2][2] - e[0][2])));
                p = refl_v3_add(v.eye, refl_v3_scale(d, a.t));
                if (refl_v3_dot(ng, d) > 0) ng = refl_v3_scale(ng, -1);
                same_hit_every_way(bvh, refl_v3_add(p, refl_v3_scale(ng, 1e-5f * diag)),
                                    refl_v3_reflect(refl_v3_normalize(d), ng), 0, INFINITY, "mirror", i, NULL);
            }
        }
    for (i = 0; i < BVH_RANDOM_RAYS; ++i) {
        refl_vec3 o = refl_v3_add(c, refl_v3_scale(rnd_dir(&r), rnd(&r, 0, diag)));
        refl_vec3 d = rnd_dir(&r);
        if (refl_rng_u32(&r) % 8 == 0) d.x = 0; /* infinite inverse directions */
        same_hit_every_way(bvh, o, d, 0, i % 3 ? INFINITY : rnd(&r, 0, diag), "random", i, NULL);
    }
    cr_log_info("%s: wide, lane-by-lane and binary traversals agree on %dx%d primary rays (%lld hits), their "
                "mirror rays and %d random rays", name, w, h, hits, BVH_RANDOM_RAYS);
    refl_bvh_destroy(bvh);
}

Test(refl_bvh, wide_matches_binary_on_builtin_scenes) {
    const char *const *names = refl_builtin_names();
    int i;
    for (i = 0; names[i]; ++i) {
        refl_scene *s = NULL;
        cr_assert_eq(refl_scene_builtin(names[i], NULL, &s), REFL_OK, "%s", names[i]);
        check_wide_matches_binary(names[i], s, 160, 120);
        refl_scene_destroy(s);
    }
    /* coincident copies of one triangle: every hit a tie, broken by index */
    {
        refl_scene *s = random_scene(555, 3, 40);
        int k;
        for (k = 0; k < 2; ++k) {
            refl_object o = s->objects[0];
            cr_assert(refl_scene_add_object(s, &o) >= 0);
        }
        refl_scene_complete(s);
        check_wide_matches_binary("coincident copies", s, 64, 48);
        refl_scene_destroy(s);
    }
}

static void check_asset(const char *file) {
    struct stat st;
    char path[512], err[1024];
    refl_scene *s = NULL;
    refl_result r;
    if (stat(BVH_ASSETS, &st) != 0 || !S_ISDIR(st.st_mode))
        cr_skip_test("%s is absent: the asset tests need the shared assets next to the repository", BVH_ASSETS);
    snprintf(path, sizeof path, "%s/%s", BVH_ASSETS, file);
    r = refl_gltf_load(path, NULL, &s, err, sizeof err);
    cr_assert_eq(r, REFL_OK, "%s: %d (%s)", path, r, err);
    refl_scene_complete(s); /* a camera framing it, where the file has none */
    check_wide_matches_binary(file, s, 96, 72);
    refl_scene_destroy(s);
}

/* The assets of test_gltf.c but MetalRoughSpheres' million triangles (too
   slow to build under the sanitizers), one test each so they run in
   parallel. */
Test(refl_bvh_wide, teapot) { check_asset("teapot.glb"); }
Test(refl_bvh_wide, bunny) { check_asset("bunny.glb"); }
Test(refl_bvh_wide, bunny_10k) { check_asset("bunny_10k.glb"); }
Test(refl_bvh_wide, xyzrgb_dragon_100k) { check_asset("xyzrgb_dragon_100k.glb"); }
Test(refl_bvh_wide, box) { check_asset("Box.glb"); }
Test(refl_bvh_wide, duck) { check_asset("Duck.glb"); }
Test(refl_bvh_wide, suzanne) { check_asset("Suzanne.glb"); }
Test(refl_bvh_wide, water_bottle) { check_asset("WaterBottle.glb"); }
Test(refl_bvh_wide, transmission_test) { check_asset("TransmissionTest.glb"); }
Test(refl_bvh_wide, attenuation_test) { check_asset("AttenuationTest.glb"); }
Test(refl_bvh_wide, toy_car) { check_asset("ToyCar.glb"); }

/* Degenerate and non-finite triangles are dropped; thousands of copies of
   one triangle (every centroid equal) still build within the depth limit
   and still hit. */
Test(refl_bvh, degenerate_and_pathological_input) {
    refl_scene *s = NULL;
    refl_mesh *m = NULL;
    refl_mesh_desc d;
    refl_bvh *bvh = NULL;
    refl_hit h;
    long long nodes, tris;
    const int copies = 5000;
    float *pos = (float *)malloc(sizeof(float) * 9 * (copies + 2));
    int i;
    static const float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    static const float flat[9] = {0, 0, 0, 1, 1, 1, 2, 2, 2};   /* zero area */
    for (i = 0; i < copies; ++i) memcpy(pos + 9 * i, tri, sizeof tri);
    memcpy(pos + 9 * copies, flat, sizeof flat);
    memcpy(pos + 9 * (copies + 1), tri, sizeof tri);
    pos[9 * (copies + 1)] = 1e30f;                                /* becomes inf under the scale below */
    memset(&d, 0, sizeof d);
    d.positions = pos;
    d.vertex_count = 3 * (copies + 2);
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_create(&d, &m), REFL_OK);
    free(pos);
    add_object(s, m, refl_mat4_scale(refl_v3(1e10f, 1, 1)));
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    refl_bvh_stats(bvh, &nodes, &tris);
    cr_assert_eq(tris, copies);
    cr_assert(refl_bvh_intersect(bvh, refl_v3(1e9f, 0.25f, 5), refl_v3(0, 0, -1), 0, INFINITY, &h));
    cr_assert(fabsf(h.t - 5) < 1e-5f);
    cr_assert(h.triangle < copies);
    cr_assert(!refl_bvh_intersect(bvh, refl_v3(1e9f, 0.25f, 5), refl_v3(0, 0, 1), 0, INFINITY, &h));
    /* NaN and zero rays never hit. */
    cr_assert(!refl_bvh_intersect(bvh, refl_v3(NAN, 0.25f, 5), refl_v3(0, 0, -1), 0, INFINITY, &h));
    cr_assert(!refl_bvh_intersect(bvh, refl_v3(1e9f, 0.25f, 5), refl_v3(0, 0, 0), 0, INFINITY, &h));
    refl_bvh_destroy(bvh);
    refl_scene_destroy(s);
}

Test(refl_bvh, bad_input_and_empty_scene) {
    refl_scene *s = NULL;
    refl_bvh *bvh = (refl_bvh *)1;
    refl_hit h;
    long long nodes = -1, tris = -1;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_bvh_build(NULL, NULL, &bvh), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(bvh);
    cr_assert_eq(refl_bvh_build(s, NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_bvh_intersect(NULL, refl_v3(0, 0, 0), refl_v3(0, 0, 1), 0, INFINITY, &h), 0);
    cr_assert_eq(refl_bvh_occluded(NULL, refl_v3(0, 0, 0), refl_v3(0, 0, 1), 0, INFINITY), 0);
    refl_bvh_stats(NULL, &nodes, &tris);
    cr_assert(nodes == 0 && tris == 0);
    refl_bvh_destroy(NULL);

    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    refl_bvh_stats(bvh, &nodes, &tris);
    cr_assert(nodes == 0 && tris == 0);
    cr_assert_eq(refl_bvh_intersect(bvh, refl_v3(0, 0, 0), refl_v3(0, 0, 1), 0, INFINITY, &h), 0);
    cr_assert_eq(refl_bvh_occluded(bvh, refl_v3(0, 0, 0), refl_v3(0, 0, 1), 0, INFINITY), 0);
    refl_bvh_stats(bvh, NULL, NULL);
    refl_bvh_destroy(bvh);
    refl_scene_destroy(s);
}

Test(refl_bvh, allocation_failure_at_every_allocation) {
    refl_scene *s = random_scene(31, 3, 50);
    tu_alloc_counter c;
    refl_allocator a;
    refl_bvh *bvh = NULL;
    long attempts, i;
    memset(&c, 0, sizeof c);
    a = tu_refl_counting(&c);
    cr_assert_eq(refl_bvh_build(s, &a, &bvh), REFL_OK);
    attempts = c.attempts;
    cr_assert(attempts >= 2);
    cr_assert(refl_bvh_intersect(bvh, refl_v3(0, 0, -20), refl_v3(0, 0, 1), 0, INFINITY, NULL) ||
              !refl_bvh_intersect(bvh, refl_v3(0, 0, -20), refl_v3(0, 0, 1), 0, INFINITY, NULL));
    refl_bvh_destroy(bvh);
    cr_assert_eq(c.allocs, c.frees);
    for (i = 1; i <= attempts; ++i) {
        memset(&c, 0, sizeof c);
        c.fail_at = i;
        bvh = (refl_bvh *)1;
        cr_assert_eq(refl_bvh_build(s, &a, &bvh), REFL_ERROR_OUT_OF_MEMORY, "failing allocation %ld", i);
        cr_assert_null(bvh);
        cr_assert_eq(c.failed, 1);
        cr_assert_eq(c.allocs, c.frees, "leak when allocation %ld fails", i);
    }
    refl_scene_destroy(s);
}

/* Refitting (refl_bvh_refit): after an object of the default scene moves
   (turned and shifted), the refit tree finds, bit for bit, the hits and
   occlusions of a tree built anew, since the closest hit does not depend
   on the tree; a scene with another object cannot be refit. */
static refl_mat4 moved(refl_mat4 m) {
    return refl_mat4_mul(refl_mat4_translate(refl_v3(0.3f, 0.1f, -0.2f)),
                         refl_mat4_mul(refl_mat4_rotate(refl_v3(0, 1, 0), 0.7f), m));
}

Test(refl_bvh, a_refit_tree_finds_the_hits_of_a_rebuilt_one) {
    refl_scene *s;
    refl_bvh *refit, *rebuilt;
    refl_rng rng;
    refl_vec3 lo, hi;
    int i, k, most = 0, hits = 0;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    cr_assert_eq(refl_bvh_build(s, NULL, &refit), REFL_OK);
    for (k = 1; k < s->object_count; ++k) /* the object of most triangles (the teapot) */
        if (s->meshes[s->objects[k].mesh]->triangle_count > s->meshes[s->objects[most].mesh]->triangle_count) most = k;
    s->objects[most].transform = moved(s->objects[most].transform);
    refl_scene_touch(s);
    cr_assert_eq(refl_bvh_refit(refit, s), REFL_OK);
    cr_assert_eq(refl_bvh_build(s, NULL, &rebuilt), REFL_OK);
    refl_scene_bounds(s, &lo, &hi);
    rng = refl_rng_seed(24);
    for (i = 0; i < 3000; ++i) {
        refl_vec3 o = refl_v3(rnd(&rng, lo.x, hi.x), rnd(&rng, lo.y, hi.y), rnd(&rng, lo.z, hi.z)), d = rnd_dir(&rng);
        refl_hit a, b;
        int ha = refl_bvh_intersect(refit, o, d, 0.0f, 1e30f, &a), hb = refl_bvh_intersect(rebuilt, o, d, 0.0f, 1e30f, &b);
        cr_assert_eq(ha, hb, "ray %d", i);
        if (ha) {
            cr_assert(a.t == b.t && a.object == b.object && a.triangle == b.triangle && a.u == b.u && a.v == b.v,
                      "ray %d: (%d, %d) at %g against (%d, %d) at %g", i, a.object, a.triangle, a.t, b.object,
                      b.triangle, b.t);
            hits += a.object == most;
        }
        cr_assert_eq(refl_bvh_occluded(refit, o, d, 0.0f, 2.0f), refl_bvh_occluded(rebuilt, o, d, 0.0f, 2.0f));
    }
    cr_assert(hits > 100, "the moved object is met (%d rays)", hits);
    {
        refl_mesh *box;
        cr_assert_eq(refl_mesh_box(refl_v3(1, 1, 1), NULL, &box), REFL_OK);
        add_object(s, box, refl_mat4_identity());
        cr_assert_eq(refl_bvh_refit(rebuilt, s), REFL_ERROR_UNSUPPORTED);
    }
    refl_bvh_destroy(rebuilt);
    refl_bvh_destroy(refit);
    refl_scene_destroy(s);
}

/* Through the persistent renderer: a moved object's frame is refit, not
   built (stats.scene_models_built), and has the bytes of refl_render's. */
Test(refl_bvh, the_renderer_refits_its_bvh_when_an_object_moves) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 64, 48);
    refl_render_desc d = tu_refl_one_bounce(REFL_RAYTRACE, 2);
    refl_renderer *rr;
    refl_frame *f, *fresh;
    int k;
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &f), REFL_OK);
    cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK);
    cr_assert_eq(f->stats.scene_models_built, 1);
    for (k = 0; k < s->object_count; ++k)
        if (s->materials[s->objects[k].material].type != REFL_DIFFUSE) break;
    cr_assert(k < s->object_count);
    s->objects[k].transform = moved(s->objects[k].transform);
    refl_scene_touch(s);
    cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK);
    cr_assert_eq(f->stats.scene_models_built, 0, "refit, not built");
    fresh = tu_refl_render(s, &v, &d);
    cr_assert_eq(tu_refl_digest(f), tu_refl_digest(fresh));
    refl_frame_destroy(fresh);
    refl_frame_destroy(f);
    refl_renderer_destroy(rr);
    refl_scene_destroy(s);
}

/* ---- the build on several threads ------------------------------------------- */

/* refl_bvh_build_threads gives the tree of refl_bvh_build, byte for byte
   (binary tree, wide tree, triangle blocks), for 1, 2 and 4 threads; with
   a grain of `grain` triangles a job, so that a small scene takes the
   parallel passes too. */
static void check_same_tree_any_threads(const char *name, const refl_scene *s, int grain) {
    static const int threads[] = {2, 4, 3};
    refl_bvh *one = NULL;
    int k;
    cr_assert_eq(refl__testing_bvh_build_threads(s, NULL, 1, grain, &one), REFL_OK, "%s", name);
    for (k = 0; k < 3; ++k) {
        refl_bvh *more = NULL;
        cr_assert_eq(refl__testing_bvh_build_threads(s, NULL, threads[k], grain, &more), REFL_OK, "%s", name);
        cr_assert(refl__testing_bvh_same(one, more), "%s: %d threads (grain %d) build another tree", name, threads[k],
                  grain);
        refl_bvh_destroy(more);
    }
    refl_bvh_destroy(one);
}

Test(refl_bvh_threads, same_tree_for_every_thread_count) {
    const char *const *names = refl_builtin_names();
    refl_scene *s = NULL;
    refl_bvh *bvh = (refl_bvh *)1;
    struct stat st;
    char err[1024];
    int i;
    for (i = 0; names[i]; ++i) {
        cr_assert_eq(refl_scene_builtin(names[i], NULL, &s), REFL_OK, "%s", names[i]);
        check_same_tree_any_threads(names[i], s, 64);
        refl_scene_destroy(s);
    }
    /* random triangles of several objects: jobs that cross from one object to the next */
    s = random_scene(77, 5, 400);
    check_same_tree_any_threads("random", s, 16);
    cr_assert_eq(refl_bvh_build_threads(s, NULL, -1, &bvh), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(bvh);
    /* the parallel build fails cleanly at every allocation */
    {
        tu_alloc_counter c;
        refl_allocator a;
        long attempts, k;
        memset(&c, 0, sizeof c);
        a = tu_refl_counting(&c);
        cr_assert_eq(refl__testing_bvh_build_threads(s, &a, 2, 16, &bvh), REFL_OK);
        refl_bvh_destroy(bvh);
        attempts = c.attempts;
        for (k = 1; k <= attempts; ++k) {
            memset(&c, 0, sizeof c);
            c.fail_at = k;
            cr_assert_eq(refl__testing_bvh_build_threads(s, &a, 2, 16, &bvh), REFL_ERROR_OUT_OF_MEMORY,
                         "failing allocation %ld", k);
            cr_assert_null(bvh);
            cr_assert_eq(c.allocs, c.frees, "leak when allocation %ld fails", k);
        }
    }
    refl_scene_destroy(s);
    if (stat(BVH_ASSETS, &st) != 0 || !S_ISDIR(st.st_mode))
        cr_skip_test("%s is absent: the asset tests need the shared assets next to the repository", BVH_ASSETS);
    cr_assert_eq(refl_gltf_load(BVH_ASSETS "/xyzrgb_dragon_100k.glb", NULL, &s, err, sizeof err), REFL_OK, "%s", err);
    check_same_tree_any_threads("xyzrgb_dragon_100k", s, 8192); /* the library's grain */
    check_same_tree_any_threads("xyzrgb_dragon_100k", s, 500);
    refl_scene_destroy(s);
}

/* ---- packets of four rays --------------------------------------------------- */

/* Four rays together give each ray the single-ray hit, bit for bit, and
   its occlusion, through every wide traversal (AVX2 where the CPU has it,
   SSE2, lane by lane). */
static void same_hits_as_single_rays(const refl_bvh *bvh, const refl_vec3 o[4], const refl_vec3 d[4],
                                     const float tmin[4], const float tmax[4], const char *what, long long i) {
    static const int paths[] = {0, 1, 3};
    refl_hit one[4], four[4];
    unsigned expect = 0, blocked = 0;
    int k, p;
    for (k = 0; k < 4; ++k) {
        memset(&one[k], 0, sizeof one[k]);
        expect |= (unsigned)refl_bvh_intersect(bvh, o[k], d[k], tmin[k], tmax[k], &one[k]) << k;
        blocked |= (unsigned)refl_bvh_occluded(bvh, o[k], d[k], tmin[k], tmax[k]) << k;
    }
    for (p = 0; p < 3; ++p) {
        unsigned got;
        memset(four, 0, sizeof four);
        got = refl__testing_bvh_trace4_path(bvh, o, d, tmin, tmax, 0, paths[p], four);
        cr_assert_eq(got, expect, "%s %lld, path %d: hits %x, single rays %x", what, i, paths[p], got, expect);
        for (k = 0; k < 4; ++k)
            cr_assert(!(expect >> k & 1) || memcmp(&one[k], &four[k], sizeof one[k]) == 0,
                      "%s %lld, path %d: ray %d names object %d triangle %d t %.9g, single object %d triangle %d "
                      "t %.9g", what, i, paths[p], k, four[k].object, four[k].triangle, four[k].t, one[k].object,
                      one[k].triangle, one[k].t);
        got = refl__testing_bvh_trace4_path(bvh, o, d, tmin, tmax, 1, paths[p], NULL);
        cr_assert_eq(got, blocked, "%s %lld, path %d: occluded %x, single rays %x", what, i, paths[p], got, blocked);
    }
    cr_assert_eq(refl_bvh_intersect4(bvh, o, d, tmin, tmax, four), expect);
    cr_assert_eq(refl_bvh_occluded4(bvh, o, d, tmin, tmax), blocked);
}

/* Per built-in scene: primary rays of a 2 x 2 pixel block together, the
   mirror rays of their hits about the geometric normal, shadow rays from
   the hits to the first light (coherent packets), and random rays, some
   with a bound or no direction (incoherent ones, dead lanes). */
Test(refl_bvh_packets, same_hits_as_single_rays) {
    const char *const *names = refl_builtin_names();
    int si;
    for (si = 0; names[si]; ++si) {
        refl_scene *s = NULL;
        refl_bvh *bvh = NULL;
        refl_view v;
        refl_vec3 lo, hi, c, light;
        refl_rng r = refl_rng_seed(99);
        float diag;
        const int w = 64, h = 48;
        long long i;
        int x, y, k;
        cr_assert_eq(refl_scene_builtin(names[si], NULL, &s), REFL_OK, "%s", names[si]);
        cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
        v = s->camera;
        refl_scene_bounds(s, &lo, &hi);
        c = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
        diag = refl_v3_length(refl_v3_sub(hi, lo));
        light = s->light_count > 0 && s->lights[0].type == REFL_LIGHT_POINT ? s->lights[0].position
                                                                           : refl_v3_add(hi, refl_v3(0, diag, 0));
        for (y = 0; y < h; y += 2)
            for (x = 0; x < w; x += 2) {
                refl_vec3 o[4], d[4], mo[4], md[4], so[4], sd[4];
                float tmin[4] = {0, 0, 0, 0}, tmax[4] = {INFINITY, INFINITY, INFINITY, INFINITY}, smax[4];
                for (k = 0; k < 4; ++k) {
                    refl_hit a;
                    o[k] = v.eye;
                    d[k] = camera_ray(&v, w, h, x + (k & 1) + 0.5f, y + (k >> 1) + 0.5f);
                    mo[k] = so[k] = v.eye;
                    md[k] = sd[k] = d[k];
                    smax[k] = 0.5f;
                    if (refl_bvh_intersect(bvh, o[k], d[k], 0, INFINITY, &a)) {
                        const refl_object *ob = &s->objects[a.object];
                        const refl_mesh *m = s->meshes[ob->mesh];
                        refl_vec3 e[3], ng, p = refl_v3_add(v.eye, refl_v3_scale(d[k], a.t));
                        int j;
                        for (j = 0; j < 3; ++j) {
                            const float *q = m->positions + 3 * (size_t)m->indices[3 * (size_t)a.triangle + j];
                            e[j] = refl_mat4_point(ob->transform, refl_v3(q[0], q[1], q[2]));
                        }
                        ng = refl_v3_normalize(refl_v3_cross(refl_v3_sub(e[1], e[0]), refl_v3_sub(e[2], e[0])));
                        if (refl_v3_dot(ng, d[k]) > 0) ng = refl_v3_scale(ng, -1);
                        p = refl_v3_add(p, refl_v3_scale(ng, 1e-5f * diag));
                        mo[k] = so[k] = p;
                        md[k] = refl_v3_reflect(refl_v3_normalize(d[k]), ng);
                        sd[k] = refl_v3_sub(light, p);
                        smax[k] = 1.0f;
                    }
                }
                i = (long long)y * w + x;
                same_hits_as_single_rays(bvh, o, d, tmin, tmax, "primary", i);
                same_hits_as_single_rays(bvh, mo, md, tmin, tmax, "mirror", i);
                same_hits_as_single_rays(bvh, so, sd, tmin, smax, "shadow", i);
            }
        for (i = 0; i < 2000; ++i) {
            refl_vec3 o[4], d[4];
            float tmin[4], tmax[4];
            for (k = 0; k < 4; ++k) {
                o[k] = refl_v3_add(c, refl_v3_scale(rnd_dir(&r), rnd(&r, 0, diag)));
                d[k] = rnd_dir(&r);
                if (refl_rng_u32(&r) % 8 == 0) d[k].x = 0;
                if (refl_rng_u32(&r) % 16 == 0) d[k] = refl_v3(0, 0, 0); /* no ray: a dead lane */
                tmin[k] = refl_rng_u32(&r) % 4 ? 0.0f : rnd(&r, 0, 0.5f * diag);
                tmax[k] = refl_rng_u32(&r) % 3 ? INFINITY : tmin[k] + rnd(&r, 0, diag);
            }
            same_hits_as_single_rays(bvh, o, d, tmin, tmax, "random", i);
        }
        refl_bvh_destroy(bvh);
        refl_scene_destroy(s);
    }
}

/* stats.triangle_tests, the paper 001 way: one test per ray and real
   triangle of every leaf the ray visits, the spare lanes of a leaf's last
   4-triangle block not counted. Five triangles stacked a hair apart are
   one leaf (no split saves area: SAH keeps them together) of two blocks,
   three lanes spare: five tests per ray through them on every traversal,
   single rays or packets; three are one block, one lane spare: three; a
   ray that misses the tree's box tests none. */
static refl_scene *stacked_triangles(int n) {
    refl_scene *s = NULL;
    refl_mesh_desc d;
    refl_mesh *m = NULL;
    float pos[9 * 5];
    int k;
    cr_assert(n <= 5);
    for (k = 0; k < n; ++k) {
        float z = -0.01f * (float)k, tri[9] = {-1, -1, 0, 1, -1, 0, 0, 1, 0};
        int j;
        for (j = 0; j < 3; ++j) tri[3 * j + 2] = z;
        memcpy(pos + 9 * k, tri, sizeof tri);
    }
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    memset(&d, 0, sizeof d);
    d.positions = pos;
    d.vertex_count = 3 * n;
    cr_assert_eq(refl_mesh_create(&d, &m), REFL_OK);
    add_object(s, m, refl_mat4_identity());
    return s;
}

Test(refl_bvh, counts_one_test_per_ray_and_real_triangle) {
    static const int sizes[] = {5, 3}, paths4[] = {0, 1, 3};
    int si, p;
    for (si = 0; si < 2; ++si) {
        const int n = sizes[si];
        refl_scene *s = stacked_triangles(n);
        refl_bvh *bvh = NULL;
        refl_vec3 o[4], d[4];
        float tmin[4] = {0, 0, 0, 0}, tmax[4] = {INFINITY, INFINITY, INFINITY, INFINITY};
        refl_hit h, four[4];
        long long before;
        int k;
        cr_assert_eq(refl__testing_bvh_build_binary_too(s, &bvh), REFL_OK);
        for (k = 0; k < 4; ++k) {
            o[k] = refl_v3(-0.2f + 0.1f * (float)k, 0.1f, 1.0f);
            d[k] = refl_v3(0, 0, -1);
        }
        for (p = 0; p < 4; ++p) { /* wide (SIMD), wide lane by lane, binary, wide SSE2 */
            before = refl__testing_bvh_tests_counted();
            cr_assert(refl__testing_bvh_intersect_path(bvh, o[0], d[0], 0, INFINITY, p, &h));
            cr_assert_eq(h.triangle, 0, "%d triangles, path %d: the nearest is the first", n, p);
            cr_assert_eq(refl__testing_bvh_tests_counted() - before, n, "%d triangles, path %d: %lld tests", n, p,
                         refl__testing_bvh_tests_counted() - before);
        }
        for (p = 0; p < 3; ++p) {
            before = refl__testing_bvh_tests_counted();
            cr_assert_eq(refl__testing_bvh_trace4_path(bvh, o, d, tmin, tmax, 0, paths4[p], four), 0xfu);
            cr_assert_eq(refl__testing_bvh_tests_counted() - before, 4 * n, "%d triangles, packet path %d: %lld tests",
                         n, paths4[p], refl__testing_bvh_tests_counted() - before);
        }
        before = refl__testing_bvh_tests_counted();
        cr_assert(!refl_bvh_intersect(bvh, refl_v3(5, 5, 1), refl_v3(0, 0, -1), 0, INFINITY, &h));
        cr_assert_eq(refl__testing_bvh_tests_counted() - before, 0, "%d triangles: a miss tests nothing", n);
        refl_bvh_destroy(bvh);
        refl_scene_destroy(s);
    }
}

/* ---- bounds against the triangle test ----------------------------------------- */

/* The hit refl_ray_triangle reports within [tmin, tmax] on each of the
   scene's triangles, the least (t, object, triangle): what every query
   bounded by them must return, whatever boxes hold the triangles. */
static int every_triangle(const refl_scene *s, refl_vec3 o, refl_vec3 d, float tmin, float tmax, refl_hit *best) {
    int i, t, found = 0;
    for (i = 0; i < s->object_count; ++i) {
        const refl_mesh *m = s->meshes[s->objects[i].mesh];
        for (t = 0; t < m->triangle_count; ++t) {
            float tri[9];
            refl_hit h;
            world_triangle(s, i, t, tri);
            /* refl_ray_triangle takes t == tmax, the queries do not */
            if (!refl_ray_triangle(o, d, tri, tmin, tmax, &h) || !(h.t < tmax)) continue;
            if (found && !(h.t < best->t)) continue; /* a tie goes to the earlier object, triangle */
            h.object = i;
            h.triangle = t;
            *best = h;
            found = 1;
        }
    }
    return found;
}

/* Every traversal, single rays (same_hit_every_way) and packets of four,
   finds what every_triangle finds within [tmin, tmax]. */
static void bounded_as_every_triangle(const refl_scene *s, const refl_bvh *bvh, refl_vec3 o, refl_vec3 d, float tmin,
                                      float tmax, const char *what, long long i) {
    static const int paths4[] = {0, 1, 3};
    refl_hit want, got, four[4];
    refl_vec3 o4[4] = {o, o, o, o}, d4[4] = {d, d, d, d};
    float tmin4[4] = {tmin, tmin, tmin, tmin}, tmax4[4] = {tmax, tmax, tmax, tmax};
    int found = every_triangle(s, o, d, tmin, tmax, &want), p;
    cr_assert_eq(same_hit_every_way(bvh, o, d, tmin, tmax, what, i, &got), found,
                 "%s %lld in (%.9g, %.9g): the tree %s, the triangle test %s (object %d triangle %d t %.9g)", what, i,
                 tmin, tmax, found ? "misses" : "hits", found ? "hits" : "misses", found ? want.object : got.object,
                 found ? want.triangle : got.triangle, found ? want.t : got.t);
    cr_assert(!found || (got.object == want.object && got.triangle == want.triangle && got.t == want.t),
              "%s %lld: the tree names object %d triangle %d t %.9g, the triangle test object %d triangle %d t %.9g",
              what, i, got.object, got.triangle, got.t, want.object, want.triangle, want.t);
    for (p = 0; p < 3; ++p) {
        cr_assert_eq(refl__testing_bvh_trace4_path(bvh, o4, d4, tmin4, tmax4, 0, paths4[p], four), found ? 0xfu : 0u,
                     "%s %lld: packet path %d", what, i, paths4[p]);
        cr_assert(!found || four[3].t == want.t);
        cr_assert_eq(refl__testing_bvh_trace4_path(bvh, o4, d4, tmin4, tmax4, 1, paths4[p], NULL), found ? 0xfu : 0u,
                     "%s %lld: occluded packet path %d", what, i, paths4[p]);
    }
}

/* A ray starting 1e-5 from a wall whose far corner is 25 away: the
   watertight test's t rounds on the scale of the corners' distance from
   the origin (it says 1.611e-5 where the plane is at 1.714e-5), the box's
   entry on the scale of t (1.663e-5, the wall being a float's step off
   its axis). A bound between the two, 0.7% past the reported hit, must
   keep it, as the unbounded query and the triangle test have it: boxes
   are culled with the ray's slack beyond the bound. The same ray on the
   builtin hybrid scene, where the uniform grid's agreement found it. */
Test(refl_bvh, a_bound_keeps_a_hit_whose_t_rounds_below_its_box) {
    const float wall[9] = {0x1.e4cccep+3f, 0x1.4p+2f, 0x1.ep+3f, 0x1.e4cccep+3f, 0.0f, 0x1.ep+3f,
                           0x1.e4ccccp+3f, 0.0f, -0x1.ep+3f};
    const refl_vec3 o = refl_v3(0x1.e4ccd8p+3f, 0x1.ba37ecp+1f, 0x1.4d8f14p+3f),
                    d = refl_v3(-0x1.25897p-2f, 0x1.2beeep-2f, -0x1.9f1ad8p-2f);
    const float bound = 0x1.104b08p-16f;
    refl_scene *s = NULL;
    refl_bvh *bvh = NULL;
    refl_mesh_desc md;
    refl_mesh *m = NULL;
    refl_hit h;
    int i;
    cr_assert(refl_ray_triangle(o, d, wall, 0.0f, INFINITY, &h));
    cr_assert(h.t < bound && h.t > 0.99f * bound, "the wall at t %.9g", h.t);
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    memset(&md, 0, sizeof md);
    md.positions = wall;
    md.vertex_count = 3;
    cr_assert_eq(refl_mesh_create(&md, &m), REFL_OK);
    add_object(s, m, refl_mat4_identity());
    cr_assert_eq(refl__testing_bvh_build_binary_too(s, &bvh), REFL_OK);
    bounded_as_every_triangle(s, bvh, o, d, 0.0f, INFINITY, "wall", 0);
    bounded_as_every_triangle(s, bvh, o, d, 0.0f, bound, "wall", 1);
    bounded_as_every_triangle(s, bvh, o, d, 0.0f, nextafterf(h.t, INFINITY), "wall", 2);
    refl_bvh_destroy(bvh);
    refl_scene_destroy(s);

    cr_assert_eq(refl_scene_builtin("hybrid", NULL, &s), REFL_OK);
    cr_assert_eq(refl__testing_bvh_build_binary_too(s, &bvh), REFL_OK);
    cr_assert(refl_bvh_intersect(bvh, o, d, 0.0f, INFINITY, &h));
    for (i = 0; i < 2; ++i)
        bounded_as_every_triangle(s, bvh, o, d, 0.0f, i == 0 ? bound : nextafterf(h.t, INFINITY), "hybrid", i);
    refl_bvh_destroy(bvh);
    refl_scene_destroy(s);
}

/* Rays leaving the surfaces of two builtin scenes (the origin a random
   point of a random triangle, moved 1e-7 to 1e-2 off it either way; a
   random direction, or one grazing the triangle), bounded by their hit
   (just past it, 1% past it), each against every triangle. A bound tmin
   gets no slack (refl__bvh_ray_slack in src/reflect/bvh.c): not tested. */
Test(refl_bvh, bounded_queries_find_what_the_triangle_test_finds) {
    static const char *const scenes[] = {"hybrid", "maze"};
    int si;
    for (si = 0; si < 2; ++si) {
        refl_scene *s = NULL;
        refl_bvh *bvh = NULL;
        refl_rng r = refl_rng_seed(2006u + (uint64_t)si);
        long long i;
        cr_assert_eq(refl_scene_builtin(scenes[si], NULL, &s), REFL_OK);
        cr_assert_eq(refl__testing_bvh_build_binary_too(s, &bvh), REFL_OK);
        for (i = 0; i < 150; ++i) {
            const refl_object *ob = &s->objects[refl_rng_u32(&r) % (uint32_t)s->object_count];
            const refl_mesh *m = s->meshes[ob->mesh];
            uint32_t t = refl_rng_u32(&r) % (uint32_t)m->triangle_count;
            float a = rnd(&r, 0, 1), b = rnd(&r, 0, 1 - a), off = powf(10.0f, rnd(&r, -7, -2));
            refl_vec3 v[3], n, o, d;
            refl_hit h;
            int j;
            for (j = 0; j < 3; ++j) {
                const float *p = m->positions + 3 * (size_t)m->indices[3 * (size_t)t + j];
                v[j] = refl_mat4_point(ob->transform, refl_v3(p[0], p[1], p[2]));
            }
            n = refl_v3_normalize(refl_v3_cross(refl_v3_sub(v[1], v[0]), refl_v3_sub(v[2], v[0])));
            o = refl_v3_add(refl_v3_add(refl_v3_scale(v[0], 1 - a - b), refl_v3_scale(v[1], a)),
                            refl_v3_scale(v[2], b));
            o = refl_v3_add(o, refl_v3_scale(n, refl_rng_u32(&r) % 2 ? off : -off));
            d = rnd_dir(&r);
            if (i % 2) d = refl_v3_add(refl_v3_sub(d, refl_v3_scale(n, refl_v3_dot(d, n))),
                                       refl_v3_scale(n, rnd(&r, -0.1f, 0.1f)));
            bounded_as_every_triangle(s, bvh, o, d, 0.0f, INFINITY, scenes[si], i);
            if (!refl_bvh_intersect(bvh, o, d, 0.0f, INFINITY, &h)) continue;
            bounded_as_every_triangle(s, bvh, o, d, 0.0f, nextafterf(h.t, INFINITY), scenes[si], i);
            bounded_as_every_triangle(s, bvh, o, d, 0.0f, 1.01f * h.t, scenes[si], i);
        }
        refl_bvh_destroy(bvh);
        refl_scene_destroy(s);
    }
}
