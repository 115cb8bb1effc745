/* The reflect.h implementation (rast.h is implemented in rast_impl.c),
   compiled once per build for the tests, the benchmarks and the `reflect`
   command, with the private functions of reflect_testing.h.
   POSIX for clock_gettime: the stats carry wall-clock timings. */
#define _POSIX_C_SOURCE 200809L
#define REFL_IMPLEMENTATION
#include "../reflect.h"
#include "reflect_testing.h"

/* reflect_testing.h's copy of refl__shadow_mode has its values. */
typedef char refl__testing_modes_match[REFL__SHADOW_AUTO == 0 && REFL__SHADOW_ZPASS == 1 &&
                                       REFL__SHADOW_ZFAIL == 2 ? 1 : -1];

static refl__shadow_job refl__testing_job(const refl__testing_shadow_job *t) {
    refl__shadow_job job;
    job.rc = t->rc;
    job.scene = t->scene;
    job.vp = t->vp;
    job.eye = t->eye;
    job.depth = t->depth;
    job.width = t->width;
    job.height = t->height;
    job.region = t->region;
    job.region_value = t->region_value;
    job.restore = t->restore;
    job.st = t->st;
    return job;
}
/* reflect_testing.h's copy of refl__shadow_job has its size (the copy above names every field) */
typedef char refl__testing_jobs_match[sizeof(refl__testing_shadow_job) == sizeof(refl__shadow_job) ? 1 : -1];

refl_result refl__testing_shadow_mask(const refl__testing_shadow_job *t, uint8_t *lit) {
    refl__shadow_job job = refl__testing_job(t);
    return refl__shadow_mask(&job, lit);
}

refl_result refl__testing_shadow_mask_mode(const refl__testing_shadow_job *t, uint8_t *lit, int mode,
                                           unsigned *used_zfail) {
    refl__shadow_job job = refl__testing_job(t);
    return refl__shadow_mask_mode(&job, lit, (refl__shadow_mode)mode, used_zfail);
}

refl_result refl__testing_shade_lit(const refl__testing_shadow_job *t, int skip, const uint8_t *lit, int all_pixels) {
    refl__shadow_job job = refl__testing_job(t);
    return refl__shade_lit(&job, skip, lit, all_pixels);
}

refl_result refl__testing_draw_scene(rast_context *rc, const refl_scene *scene, refl_mat4 vp, int skip,
                                     refl_stats *st) {
    return refl__draw_scene(rc, scene, vp, skip, st);
}

void refl__testing_view_ray(const refl_view *v, const refl_scene *scene, float px, float py, refl_vec3 *origin,
                            refl_vec3 *dir, float *tmax) {
    refl__view_rays r;
    refl__view_rays_init(&r, v, scene);
    refl__view_rays_get(&r, px, py, origin, dir, tmax);
}

refl_result refl__testing_bvh_build_binary_too(const refl_scene *scene, refl_bvh **out_bvh) {
    return refl__bvh_build_ex(scene, NULL, 1, NULL, REFL__BVH_GRAIN, out_bvh);
}

refl_result refl__testing_bvh_build_threads(const refl_scene *scene, const refl_allocator *a, int threads, int grain,
                                            refl_bvh **out_bvh) {
    return refl__bvh_build_threads_ex(scene, a, threads, 1, grain, out_bvh);
}

unsigned refl__testing_bvh_trace4_path(const refl_bvh *bvh, const refl_vec3 origin[4], const refl_vec3 dir[4],
                                       const float tmin[4], const float tmax[4], int any_hit, int path,
                                       refl_hit hit[4]) {
    return refl__bvh_trace4(bvh, origin, dir, tmin, tmax, any_hit, path, hit);
}

int refl__testing_bvh_same(const refl_bvh *a, const refl_bvh *b) {
    return a->node_count == b->node_count && a->wide_count == b->wide_count && a->block_count == b->block_count &&
           a->tri_count == b->tri_count &&
           memcmp(a->nodes, b->nodes, sizeof *a->nodes * (size_t)a->node_count) == 0 &&
           memcmp(a->wide, b->wide, sizeof *a->wide * (size_t)a->wide_count) == 0 &&
           memcmp(a->blocks, b->blocks, sizeof *a->blocks * (size_t)a->block_count) == 0;
}

int refl__testing_bvh_intersect_path(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax,
                                     int path, refl_hit *hit) {
    return refl__bvh_trace(bvh, origin, dir, tmin, tmax, 0, path, hit);
}

long long refl__testing_bvh_tests_counted(void) { return refl__bvh_tests_counted(); }

refl_lem_shell refl__testing_lem_fit_cylinder(const float *pos, int n, refl_vec3 c, refl_vec3 lo, refl_vec3 hi) {
    static const refl_vec3 world[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    float *scratch = (float *)malloc(sizeof(float) * (size_t)(n > 0 ? n : 1));
    refl_lem_shell sh;
    memset(&sh, 0, sizeof sh);
    if (scratch) sh = refl__lem_fit_cylinder(pos, n, c, lo, hi, world, scratch);
    free(scratch);
    return sh;
}
