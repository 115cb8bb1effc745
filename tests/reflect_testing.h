/* Private functions of reflect.h for the tests that call them
   (tests/reflect/test_shadow.c). tests/reflect_impl.c defines the
   refl__testing_ functions after the implementation, where the refl__
   statics they forward to are in scope, so no test compiles a copy of the
   implementation. A test then uses the internals under their own names
   (the second part). Not API. */
#ifndef REFL_TESTING_H
#define REFL_TESTING_H
#include "../reflect.h"

/* refl__shadow_job's fields, in its order (checked in reflect_impl.c). */
typedef struct refl__testing_shadow_job {
    rast_context *rc;
    const refl_scene *scene;
    refl_mat4 vp;
    refl_vec3 eye;
    const float *depth;
    int width, height;
    const uint8_t *region;
    uint8_t region_value;
    const rast_targets *restore;
    refl_stats *st;
} refl__testing_shadow_job;

/* refl__shadow_mask, refl__shadow_mask_mode, refl__shade_lit and
   refl__draw_scene (src/reflect/internal.h); mode is a refl__shadow_mode. */
refl_result refl__testing_shadow_mask(const refl__testing_shadow_job *job, uint8_t *lit);
refl_result refl__testing_shadow_mask_mode(const refl__testing_shadow_job *job, uint8_t *lit, int mode,
                                           unsigned *used_zfail);
refl_result refl__testing_shade_lit(const refl__testing_shadow_job *job, int skip, const uint8_t *lit,
                                    int all_pixels);
refl_result refl__testing_draw_scene(rast_context *rc, const refl_scene *scene, refl_mat4 vp, int skip,
                                     refl_stats *st);
/* refl__view_rays_init for the view, then refl__view_rays_get at (px, py). */
void refl__testing_view_ray(const refl_view *v, const refl_scene *scene, float px, float py, refl_vec3 *origin,
                            refl_vec3 *dir, float *tmax);

/* refl_bvh_build keeping the binary tree besides the wide one, and a
   trace through one of the traversals of bvh.c: 0 the wide tree (SIMD box
   tests where built, AVX2 where the CPU has it), 1 the wide tree lane by
   lane, 2 the binary tree (only in a tree built by the former), 3 the
   wide tree without AVX2. */
refl_result refl__testing_bvh_build_binary_too(const refl_scene *scene, refl_bvh **out_bvh);
/* refl_bvh_build_threads keeping the binary tree too, its parallel passes
   taking jobs of `grain` triangles or more (so that small scenes take
   the parallel path); whether two BVHs hold the same binary tree, wide
   tree and triangle blocks, byte for byte. */
refl_result refl__testing_bvh_build_threads(const refl_scene *scene, const refl_allocator *a, int threads, int grain,
                                            refl_bvh **out_bvh);
int refl__testing_bvh_same(const refl_bvh *a, const refl_bvh *b);
/* Four rays together (refl_bvh_intersect4, or refl_bvh_occluded4 when
   any_hit) through the wide tree's traversal `path` (0, 1 or 3 as in
   refl__testing_bvh_intersect_path). */
unsigned refl__testing_bvh_trace4_path(const refl_bvh *bvh, const refl_vec3 origin[4], const refl_vec3 dir[4],
                                       const float tmin[4], const float tmax[4], int any_hit, int path,
                                       refl_hit hit[4]);
int refl__testing_bvh_intersect_path(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax,
                                     int path, refl_hit *hit);
/* refl__bvh_tests_counted: the triangle tests of every trace so far, summed
   (a frame's stats.triangle_tests is its difference across the frame). */
long long refl__testing_bvh_tests_counted(void);
/* LAYERED_EM's cylinder shell (refl__lem_fit_cylinder) on the world axes,
   around the vertical through c, fitted to hits pos[3 n] about a lens
   whose box is (lo, hi); kind 0 when out of memory. */
refl_lem_shell refl__testing_lem_fit_cylinder(const float *pos, int n, refl_vec3 c, refl_vec3 lo, refl_vec3 hi);

#ifndef REFL_IMPLEMENTATION
/* The internals under their own names, as the tests call them. The mode
   values are checked against the implementation's in reflect_impl.c. */
#define REFL__MIN(a, b) ((a) < (b) ? (a) : (b))
#define REFL__MAX(a, b) ((a) > (b) ? (a) : (b))
typedef enum refl__shadow_mode { REFL__SHADOW_AUTO = 0, REFL__SHADOW_ZPASS, REFL__SHADOW_ZFAIL } refl__shadow_mode;
#define refl__shadow_job refl__testing_shadow_job
#define refl__shadow_mask refl__testing_shadow_mask
#define refl__shadow_mask_mode refl__testing_shadow_mask_mode
#define refl__shade_lit refl__testing_shade_lit
#define refl__draw_scene refl__testing_draw_scene

/* A view's rays: the view kept, each ray set up again when asked for. */
typedef struct refl__view_rays {
    refl_view view;
    const refl_scene *scene;
} refl__view_rays;

static inline void refl__view_rays_init(refl__view_rays *r, const refl_view *v, const refl_scene *scene) {
    r->view = *v;
    r->scene = scene;
}

static inline void refl__view_rays_get(const refl__view_rays *r, float px, float py, refl_vec3 *origin,
                                       refl_vec3 *dir, float *tmax) {
    refl__testing_view_ray(&r->view, r->scene, px, py, origin, dir, tmax);
}
#endif

#endif
