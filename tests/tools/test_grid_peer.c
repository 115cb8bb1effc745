/* The uniform grid (bench/grid_peer.h) against refl_bvh on `hybrid`, paper
   001's section 6 scene (a small teapot and cup in a wide room: the grid's
   hard case): random rays (refl_grid_agreement) must find the same object,
   triangle and t, bit for bit (the same watertight test and order of
   ties), and any-hit rays the same answer, at a coarse, the default and a
   fine resolution; a grid of the lens objects alone the first lens
   surface refl_bvh finds along the ray. Each triangle is tested at most once a ray (a one-cell grid
   tests all of them), and RAYTRACE through the grid counts the same tests
   and gives the same bytes on 1 and 2 threads. */
#include <criterion/criterion.h>

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../../bench/grid_peer.h"
#include "../../reflect.h"
#include "../test_util.h"

/* per grid: the bench checks 200000 more before it measures */
#define GRID_RAYS (tu_sanitized() ? 5000 : 25000)

static refl_scene *grid_hybrid(void) {
    refl_scene *s = NULL;
    cr_assert_eq(refl_scene_builtin("hybrid", NULL, &s), REFL_OK);
    return s;
}

/* refl_grid_agreement at per_side, the lens objects alone or all. */
static void grid_agrees(const refl_scene *s, const refl_bvh *bvh, float per_side, int lenses_only) {
    unsigned char lenses[64];
    refl_grid_desc gd;
    refl_grid *g;
    char first[512];
    long long bad;
    int i;
    cr_assert_leq(s->object_count, 64);
    memset(&gd, 0, sizeof gd);
    gd.per_side = per_side;
    for (i = 0; i < s->object_count; ++i) lenses[i] = s->materials[s->objects[i].material].type != REFL_DIFFUSE;
    if (lenses_only) gd.objects = lenses;
    g = refl_grid_create(s, &gd);
    cr_assert_not_null(g);
    bad = refl_grid_agreement(g, s, bvh, GRID_RAYS, 12345u, first, sizeof first);
    refl_grid_destroy(g);
    cr_assert_eq(bad, 0, "per_side %g, lenses only %d: %lld of %d rays disagree; first: %s", per_side, lenses_only, bad,
                 GRID_RAYS, first);
}

Test(grid_peer, same_hits_as_the_bvh_on_hybrid) {
    refl_scene *s = grid_hybrid();
    refl_bvh *bvh = NULL;
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    grid_agrees(s, bvh, 0.75f, 0);
    grid_agrees(s, bvh, 0.0f, 0); /* the default: PBRT's 3 */
    grid_agrees(s, bvh, 12.0f, 0);
    grid_agrees(s, bvh, 0.0f, 1);
    refl_bvh_destroy(bvh);
    refl_scene_destroy(s);
}

/* Each triangle once a ray: a grid of one cell tests every triangle of a
   ray that crosses it and finds no hit early (closest hit: all), and no
   ray of a fine grid tests more than the grid holds. */
Test(grid_peer, tests_each_triangle_once_a_ray) {
    refl_scene *s = grid_hybrid();
    refl_grid_desc gd;
    refl_grid *one, *fine;
    long long n, tests0, tests1, rays;
    int cells[3], i;
    memset(&gd, 0, sizeof gd);
    gd.per_side = 1e-6f;
    one = refl_grid_create(s, &gd);
    gd.per_side = 12.0f;
    fine = refl_grid_create(s, &gd);
    cr_assert(one && fine);
    refl_grid_shape(one, cells, &n, NULL);
    cr_assert(cells[0] == 1 && cells[1] == 1 && cells[2] == 1);
    cr_assert_eq(n, refl_scene_triangles(s));
    for (i = 0; i < 2000; ++i) { /* from the eye, over the teapot and cup and past them */
        refl_vec3 o = s->camera.eye, d = refl_v3_sub(refl_v3(-1.0f + 0.001f * (float)i, 0.3f + 0.0002f * (float)i, -0.5f), o);
        refl_hit h;
        refl_grid_counts(one, NULL, &tests0);
        refl_grid_intersect(one, o, d, 0.0f, FLT_MAX, &h);
        refl_grid_counts(one, NULL, &tests1);
        cr_assert_eq(tests1 - tests0, n, "ray %d: %lld tests of %lld triangles", i, tests1 - tests0, n);
        refl_grid_counts(fine, NULL, &tests0);
        refl_grid_intersect(fine, o, d, 0.0f, FLT_MAX, &h);
        refl_grid_counts(fine, &rays, &tests1);
        cr_assert_leq(tests1 - tests0, n);
        cr_assert_eq(rays, i + 1);
    }
    refl_grid_destroy(one);
    refl_grid_destroy(fine);
    refl_scene_destroy(s);
}

/* RAYTRACE with the grid as its caster: the same bytes and counts on 1 and
   2 threads. */
Test(grid_peer, raytrace_through_the_grid_is_deterministic) {
    refl_scene *s = grid_hybrid();
    refl_frame *f[2] = {NULL, NULL};
    long long tests[2], rays[2];
    int k;
    for (k = 0; k < 2; ++k) {
        refl_grid *g = refl_grid_create(s, NULL);
        refl_render_desc d;
        refl_view v = s->camera;
        v.width = 64;
        v.height = 48;
        cr_assert_not_null(g);
        memset(&d, 0, sizeof d);
        d.method = REFL_RAYTRACE;
        d.depth = 6;
        d.threads = k + 1;
        d.raytrace.greedy = 1;
        d.raytrace.caster = refl_grid_caster(g);
        cr_assert_eq(refl_frame_create(64, 48, NULL, &f[k]), REFL_OK);
        cr_assert_eq(refl_render(s, &v, &d, f[k]), REFL_OK);
        refl_grid_counts(g, &rays[k], &tests[k]);
        cr_assert_eq(rays[k], f[k]->stats.rays, "the grid's rays %lld, the frame's %lld", rays[k], f[k]->stats.rays);
        refl_grid_destroy(g);
    }
    cr_assert_eq(tests[0], tests[1]);
    cr_assert(tests[0] > rays[0]);
    cr_assert_eq(memcmp(f[0]->rgba, f[1]->rgba, 64 * 48 * 4 * sizeof(float)), 0);
    refl_frame_destroy(f[0]);
    refl_frame_destroy(f[1]);
    refl_scene_destroy(s);
}

/* refl_ray_triangle, the test the grid shares with refl_bvh: a hit's t, u
   and v; the bounds exclusive at tmin, inclusive at tmax; no hit on a
   degenerate triangle, which refl_bvh leaves out. */
Test(grid_peer, ray_triangle_is_the_bvh_test) {
    const float tri[9] = {0, 0, 2, 1, 0, 2, 0, 1, 2}, flat[9] = {0, 0, 2, 1, 1, 2, 2, 2, 2};
    refl_hit h;
    memset(&h, 0, sizeof h);
    cr_assert(refl_ray_triangle(refl_v3(0.25f, 0.25f, 0), refl_v3(0, 0, 1), tri, 0.0f, FLT_MAX, &h));
    cr_assert(h.t == 2.0f && h.u == 0.25f && h.v == 0.25f, "t %g u %g v %g", h.t, h.u, h.v);
    cr_assert(refl_ray_triangle(refl_v3(0.25f, 0.25f, 0), refl_v3(0, 0, 1), tri, 0.0f, 2.0f, &h));
    cr_assert(!refl_ray_triangle(refl_v3(0.25f, 0.25f, 0), refl_v3(0, 0, 1), tri, 2.0f, FLT_MAX, &h));
    cr_assert(!refl_ray_triangle(refl_v3(0.75f, 0.75f, 0), refl_v3(0, 0, 1), tri, 0.0f, FLT_MAX, &h));
    cr_assert(!refl_ray_triangle(refl_v3(1, 1, 0), refl_v3(0, 0, 1), flat, 0.0f, FLT_MAX, &h));
}
