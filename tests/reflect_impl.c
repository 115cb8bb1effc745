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

refl_result refl__testing_shadow_mask(rast_context *rc, const refl_scene *scene, refl_mat4 vp, refl_vec3 eye,
                                      const float *depth, int width, int height, const uint8_t *region,
                                      uint8_t region_value, uint8_t *lit, const rast_targets *restore,
                                      refl_stats *st) {
    return refl__shadow_mask(rc, scene, vp, eye, depth, width, height, region, region_value, lit, restore, st);
}

refl_result refl__testing_shadow_mask_mode(rast_context *rc, const refl_scene *scene, refl_mat4 vp, refl_vec3 eye,
                                           const float *depth, int width, int height, const uint8_t *region,
                                           uint8_t region_value, uint8_t *lit, const rast_targets *restore,
                                           refl_stats *st, int mode, unsigned *used_zfail) {
    return refl__shadow_mask_mode(rc, scene, vp, eye, depth, width, height, region, region_value, lit, restore, st,
                                  (refl__shadow_mode)mode, used_zfail);
}

refl_result refl__testing_shade_lit(rast_context *rc, const refl_scene *scene, refl_mat4 vp, int skip,
                                    const uint8_t *lit, int width, int height, int stencil_ref, int all_pixels,
                                    refl_stats *st) {
    return refl__shade_lit(rc, scene, vp, skip, lit, width, height, stencil_ref, all_pixels, st);
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
