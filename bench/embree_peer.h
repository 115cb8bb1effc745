/* embree_peer.h - Embree 3 as a peer of refl_bvh: the same scene, the same
   hit record, for the agreement tests (tests/tools/test_embree.c) and the ray
   benchmark (bench/bench_rays.c). Bench and tests only, never part of the
   headers (DESIGN.md section 7); links with -lembree3.

       char err[256];
       refl_embree *e = refl_embree_create(scene, 0, err, sizeof err);
       if (!e) { fprintf(stderr, "%s\n", err); exit(1); }
       refl_ray_caster c = {refl_embree_intersect, refl_embree_occluded, e};
       ...                                  // RAYTRACE through Embree
       refl_embree_destroy(e);

   The scene is built once, like refl_bvh_build: one triangle geometry per
   object, geomID = object index, primID mapped back to the triangle index
   in the object's mesh, vertices in world space (refl_mat4_point), and the
   degenerate and non-finite triangles that refl_bvh leaves out left out
   here too. Robust traversal (RTC_SCENE_FLAG_ROBUST) and high build
   quality, so it is as watertight as refl_bvh and as fast as Embree gets. */
#ifndef REFL_EMBREE_PEER_H
#define REFL_EMBREE_PEER_H

#include <stddef.h>

#include "../reflect.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct refl_embree refl_embree;

/* threads: Embree's build threads (0: all). NULL on failure, with a one-line
   reason in err (may be NULL): bad meshes, Embree errors, no memory. */
refl_embree *refl_embree_create(const refl_scene *scene, int threads, char *err, size_t err_size);
void refl_embree_destroy(refl_embree *embree);

/* The refl_ray_caster functions (peer is the refl_embree): closest hit or
   any hit of origin + t * dir with tmin < t < tmax, as refl_bvh_intersect
   and refl_bvh_occluded. hit may be NULL. */
int refl_embree_intersect(void *peer, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax, refl_hit *hit);
int refl_embree_occluded(void *peer, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax);

/* ---- batches, for the benchmark ------------------------------------------------ */

typedef enum refl_embree_api {
    REFL_EMBREE_SINGLE = 0,  /* rtcIntersect1 per ray */
    REFL_EMBREE_STREAM       /* rtcIntersect1M on chunks of REFL_EMBREE_CHUNK rays */
} refl_embree_api;

#define REFL_EMBREE_CHUNK 256

/* Runs fn over [0, count) in `threads` contiguous slices, one pthread each
   (the caller's thread takes the first slice; threads <= 1: no threads).
   Every tracer in the benchmark is split this way. */
void refl_embree_split(long long count, int threads, void (*fn)(void *user, long long begin, long long end),
                       void *user);

/* Closest hits of rays i in [0, count): origins[i] + t * dirs[i] for
   tmin < t < tmax, split as refl_embree_split does; hits[i].object is -1 on a
   miss. coherent: a hint to Embree (primary rays). The rays are not
   checked (finite, nonzero directions), to time Embree alone. */
void refl_embree_trace(const refl_embree *embree, refl_embree_api api, int coherent, const refl_vec3 *origins,
                       const refl_vec3 *dirs, long long count, float tmin, float tmax, int threads, refl_hit *hits);

#ifdef __cplusplus
}
#endif
#endif /* REFL_EMBREE_PEER_H */
