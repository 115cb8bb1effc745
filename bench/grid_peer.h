/* grid_peer.h - a uniform grid as a peer of refl_bvh: the accelerator of a
   2001 ray tracer (paper 001 names none; a uniform grid was the common
   one), for `reflect bench --only lem-grid` (tools/reflect_bench_lem.c),
   which measures what paper 001's section 6 counts, triangle tests, with
   it. Bench and tests only, never part of the headers (DESIGN.md section 7).

       refl_grid_desc gd = {0};                 // every object, PBRT's density
       refl_grid *g = refl_grid_create(scene, &gd);
       refl_ray_caster c = refl_grid_caster(g); // RAYTRACE's desc.raytrace.caster,
       ...                                      // refl_lens_tessellate's caster
       refl_grid_counts(g, &rays, &tests);
       refl_grid_destroy(g);

   The grid holds the chosen objects' world triangles (refl_mat4_point; the
   non-finite ones left out, as refl_bvh does; a degenerate one, which
   refl_bvh leaves out, is tested and never hit) in cells of
   one size over their bounds; a triangle goes into every cell its bounds
   overlap. A ray walks the cells it crosses in order (3D-DDA, Amanatides
   and Woo 1987) and tests each triangle once (mailboxing, without state:
   a triangle's cells along a ray are consecutive, so it is tested in the
   first of them, where the cell the ray came from is not one of its own),
   with refl_bvh's watertight test (refl_ray_triangle) and its order of
   ties (lower object, then triangle): the same hits. Resolution: PBRT's GridAccel (Pharr and
   Humphreys 2004), per_side times the cube root of the triangle count
   cells along the bounds' longest side, the other sides in proportion
   (cells near cubes), at least 1 and at most max_side a side. */
#ifndef REFL_GRID_PEER_H
#define REFL_GRID_PEER_H

#include "../reflect.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct refl_grid refl_grid;

typedef struct refl_grid_desc {
    const unsigned char *objects; /* per scene object, nonzero: in the grid; NULL: every object */
    float per_side;          /* cells along the longest side per cube root of the triangles; 0: 3 */
    int max_side;            /* cells a side at most; 0: 64 (PBRT's) */
} refl_grid_desc;

/* NULL on failure (no memory, a mesh index out of range). An empty grid
   (no triangle) hits nothing. desc NULL: every object, the defaults. */
refl_grid *refl_grid_create(const refl_scene *scene, const refl_grid_desc *desc);
void refl_grid_destroy(refl_grid *grid);

/* The refl_ray_caster functions (grid is the refl_grid): closest hit or any
   hit of origin + t * dir with tmin < t < tmax, as refl_bvh_intersect and
   refl_bvh_occluded. hit may be NULL. Thread-safe. */
int refl_grid_intersect(void *grid, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax, refl_hit *hit);
int refl_grid_occluded(void *grid, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax);
refl_ray_caster refl_grid_caster(refl_grid *grid);

/* Rays cast (calls of either function) and triangle tests made (one per
   ray and distinct triangle tested, hit or missed) since the grid was
   made: sums over every thread, the same for any thread count. */
void refl_grid_counts(const refl_grid *grid, long long *rays, long long *tests);
/* Its cells a side, triangles, and triangle references (a triangle in k
   cells counts k). Any pointer may be NULL. */
void refl_grid_shape(const refl_grid *grid, int cells[3], long long *triangles, long long *references);

/* A cost of the grid's resolution that falls as the cells get finer (the
   bench's: a greedy RAYTRACE frame's triangle tests per ray through a grid
   of the scene at per_side); below 0 on failure. */
typedef double (*refl_grid_cost)(void *user, float per_side);

typedef struct refl_grid_fit {
    float per_side;          /* the last resolution tried; the fit where converged */
    double cost;             /* its cost */
    int evaluations;         /* the costs measured */
    int converged;           /* |cost / target - 1| <= tolerance */
} refl_grid_fit;

/* The per_side at which cost comes within tolerance (a share: 0.01 is 1%)
   of target: [lo, hi] widened (halved, doubled) until its costs bracket
   the target, then narrowed by interpolation on log cost against log
   per_side (a grid's cost is near a power of its cells), kept inside the
   bracket's middle 80% so that it always shrinks. The cost is a step
   function (cells come in whole numbers), so the target may fall in a step:
   then it stops unconverged once the bracket is narrower than a share of
   1e-4, or after max_evaluations (0: 40) costs, or on a cost's failure.
   Returns fit->converged. */
int refl_grid_fit_per_side(refl_grid_cost cost, void *user, double target, double tolerance, float lo, float hi,
                           int max_evaluations, refl_grid_fit *fit);

/* Agreement with refl_bvh (bvh over the whole scene) on `rays` random rays
   from seed: from random points in the scene's bounds, half towards a
   random point of a random triangle of the grid, half in random
   directions; each closest hit must be the first hit refl_bvh finds on
   the grid's objects (the object, triangle, t, u and v bit for bit: the
   same test), each any-hit answer before a random distance whether that
   first hit lies before it.
   Returns the rays that disagree (0: all agree), the first described in
   first (may be NULL). Its rays count in the grid's counts. */
long long refl_grid_agreement(refl_grid *grid, const refl_scene *scene, const refl_bvh *bvh, int rays,
                              unsigned seed, char *first, size_t first_size);

#ifdef __cplusplus
}
#endif
#endif /* REFL_GRID_PEER_H */
