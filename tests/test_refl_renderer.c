/* The renderer that lives across frames, options validation that names
   the rule broken, and per-reflector dispatch. */
#include <criterion/criterion.h>
#include <stdint.h>
#include <stdio.h>

#include "../reflect.h"
#include "refl_test_util.h"

static uint64_t digest(const refl_frame *f) {
    size_t n = (size_t)f->width * (size_t)f->height, i;
    uint64_t h = 0xCBF29CE484222325ull;
    const unsigned char *parts[4];
    size_t sizes[4];
    int k;
    parts[0] = f->color; sizes[0] = 4 * n;
    parts[1] = (const unsigned char *)f->depth; sizes[1] = n * sizeof(float);
    parts[2] = f->stencil; sizes[2] = n;
    parts[3] = (const unsigned char *)f->points; sizes[3] = 3 * n * sizeof(float);
    for (k = 0; k < 4; ++k)
        for (i = 0; i < sizes[k]; ++i) h = (h ^ parts[k][i]) * 0x100000001B3ull;
    return h;
}

/* Frame k of a camera path orbiting the scene's camera around its target. */
static refl_view path_view(const refl_scene *s, int k, int w, int h) {
    refl_view v = s->camera;
    refl_vec3 off = refl_v3_sub(v.eye, v.target);
    float a = 0.04f * (float)k, c = cosf(a), sn = sinf(a);
    v.eye = refl_v3_add(v.target, refl_v3(c * off.x + sn * off.z, off.y, -sn * off.x + c * off.z));
    v.width = w;
    v.height = h;
    return v;
}

/* Each frame of a camera path through one renderer renders refl_render's
   bytes, and the scene-wide models (BVH, C3RC's points and kd-tree) are
   built at the first frame only. */
static void check_path(const char *scene, refl_render_desc d, int builds_first) {
    refl_view v;
    refl_scene *s = tu_refl_builtin(scene, &v, 64, 48);
    refl_renderer *rr = NULL;
    refl_frame *kept = NULL;
    int k;
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_frame_create(64, 48, NULL, &kept), REFL_OK);
    for (k = 0; k < 6; ++k) {
        refl_view vk = path_view(s, k, 64, 48);
        refl_frame *fresh = tu_refl_render(s, &vk, &d);
        cr_assert_eq(refl_renderer_render(rr, &vk, kept), REFL_OK);
        cr_assert_eq(digest(kept), digest(fresh), "%s, %s, frame %d: the renderer's bytes differ from refl_render's",
                     scene, refl_method_name(d.method), k);
        cr_assert_eq(fresh->stats.scene_models_built, builds_first, "%s: refl_render builds %d models",
                     refl_method_name(d.method), fresh->stats.scene_models_built);
        cr_assert_eq(kept->stats.scene_models_built, k == 0 ? builds_first : 0, "%s, frame %d: %d models rebuilt",
                     refl_method_name(d.method), k, kept->stats.scene_models_built);
        refl_frame_destroy(fresh);
    }
    /* a change to the scene rebuilds them */
    refl_scene_touch(s);
    cr_assert_eq(refl_renderer_render(rr, &v, kept), REFL_OK);
    cr_assert_eq(kept->stats.scene_models_built, builds_first);
    refl_frame_destroy(kept);
    refl_renderer_destroy(rr);
    refl_scene_destroy(s);
}

Test(refl_renderer, a_camera_path_keeps_the_bvh_and_the_kd_tree, .timeout = 120) {
    refl_render_desc d = tu_refl_one_bounce(REFL_RAYTRACE, 2);
    d.depth = 0;
    check_path("default", d, 1);
    check_path("glass", d, 1);
    d.method = REFL_SBC;
    check_path("default", d, 1);
    d.sbc.trace_fallback = 1;
    check_path("concave", d, 1);
    d = tu_refl_one_bounce(REFL_C3RC, 2);
    d.c3rc.point_density = 400.0f;
    check_path("default", d, 1);
    d = tu_refl_one_bounce(REFL_ENVMAP, 2);
    check_path("default", d, 0);
    d.method = REFL_PLANAR;
    check_path("mirror-room", d, 0);
}

/* C3RC's view-dependent default density is fixed at the renderer's first
   frame: the same bytes as refl_render of later frames at that density,
   found as the density refl_render of the first frame reports. */
Test(refl_renderer, c3rc_default_density_is_the_first_frames, .timeout = 120) {
    refl_view v0, v3;
    refl_scene *s = tu_refl_builtin("default", &v0, 64, 48);
    refl_render_desc d = tu_refl_one_bounce(REFL_C3RC, 2);
    refl_renderer *rr = NULL;
    refl_frame *first, *kept = NULL, *fresh;
    double area_density;
    v0 = path_view(s, 0, 64, 48);
    v3 = path_view(s, 3, 64, 48);
    first = tu_refl_render(s, &v0, &d);
    cr_assert(first->stats.c3rc.points > 1000);
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_frame_create(64, 48, NULL, &kept), REFL_OK);
    cr_assert_eq(refl_renderer_render(rr, &v0, kept), REFL_OK);
    cr_assert_eq(digest(kept), digest(first));
    cr_assert_eq(refl_renderer_render(rr, &v3, kept), REFL_OK);
    cr_assert_eq(kept->stats.c3rc.points, first->stats.c3rc.points, "the points were sampled again");
    /* refl_render of the same view samples at its own density */
    fresh = tu_refl_render(s, &v3, &d);
    area_density = (double)fresh->stats.c3rc.points / (double)first->stats.c3rc.points;
    cr_log_info("points: first frame %lld, frame 3 alone %lld (ratio %.3f)", first->stats.c3rc.points,
                fresh->stats.c3rc.points, area_density);
    refl_frame_destroy(fresh);
    refl_frame_destroy(first);
    refl_frame_destroy(kept);
    refl_renderer_destroy(rr);
    refl_scene_destroy(s);
}

typedef struct bad_option {
    const char *rule;        /* what frame->message starts with */
    void (*set)(refl_render_desc *d);
} bad_option;

static void bad_method(refl_render_desc *d) { d->method = (refl_method)99; }
static void bad_threads(refl_render_desc *d) { d->threads = -1; }
static void bad_depth(refl_render_desc *d) { d->depth = -2; }
static void bad_shadows(refl_render_desc *d) { d->lighting.shadows = 2; }
static void bad_soft(refl_render_desc *d) { d->lighting.soft_shadow_samples = 1025; }
static void bad_volumes(refl_render_desc *d) { d->lighting.light_volumes = -1; }
static void bad_caustics(refl_render_desc *d) { d->lighting.caustic_samples = 5000; }
static void bad_translucency(refl_render_desc *d) { d->lighting.translucency = NAN; }
static void bad_object_methods(refl_render_desc *d) { d->object_method_count = 3; }
static void bad_object_method(refl_render_desc *d) {
    static const refl_method m[2] = {REFL_SBC, (refl_method)-4};
    d->object_methods = m;
    d->object_method_count = 2;
}
static void bad_object_raytrace(refl_render_desc *d) {
    static const refl_method m[1] = {REFL_RAYTRACE};
    d->object_methods = m;
    d->object_method_count = 1;
}
static int never_occluded(void *user, refl_vec3 o, refl_vec3 dir, float tmin, float tmax) {
    (void)user; (void)o; (void)dir; (void)tmin; (void)tmax;
    return 0;
}
static void bad_caster(refl_render_desc *d) { d->raytrace.caster.occluded = never_occluded; }
static void bad_envmap(refl_render_desc *d) { d->envmap.size = 8193; }
static void bad_culling(refl_render_desc *d) { d->planar.no_culling = 7; }
static void bad_density(refl_render_desc *d) { d->c3rc.point_density = -1.0f; }
static void bad_leaf(refl_render_desc *d) { d->c3rc.kd_leaf_points = -5; }
static void bad_splat(refl_render_desc *d) { d->c3rc.max_splat = 65; }
static void bad_split(refl_render_desc *d) { d->c3rc.camera_split_px = INFINITY; }
static void bad_error(refl_render_desc *d) { d->sbc.error_px = -0.5f; }
static void bad_factor(refl_render_desc *d) { d->sbc.ray_factor = 65; }
static void bad_batch(refl_render_desc *d) { d->sbc.batch_groups = 255; }
static void bad_fallback(refl_render_desc *d) { d->sbc.trace_fallback = 2; }
static void bad_mixed(refl_render_desc *d) { d->sbc.mixed_levels = 7; }
static void bad_morphs(refl_render_desc *d) { d->sbc.morph_count = 1; }
static void bad_points_last(refl_render_desc *d) { d->debug.points_last = 3; }

static const bad_option bad_options[] = {
    {"method:", bad_method},
    {"threads:", bad_threads},
    {"depth:", bad_depth},
    {"lighting.shadows:", bad_shadows},
    {"lighting.soft_shadow_samples:", bad_soft},
    {"lighting.light_volumes:", bad_volumes},
    {"lighting.caustic_samples:", bad_caustics},
    {"lighting.translucency:", bad_translucency},
    {"object_methods:", bad_object_methods},
    {"object_methods:", bad_object_method},
    {"object_methods:", bad_object_raytrace},
    {"raytrace.caster:", bad_caster},
    {"envmap.size:", bad_envmap},
    {"planar.no_culling:", bad_culling},
    {"c3rc.point_density:", bad_density},
    {"c3rc.kd_leaf_points:", bad_leaf},
    {"c3rc.max_splat:", bad_splat},
    {"c3rc.camera_split_px:", bad_split},
    {"sbc.error_px:", bad_error},
    {"sbc.ray_factor:", bad_factor},
    {"sbc.batch_groups:", bad_batch},
    {"sbc.trace_fallback:", bad_fallback},
    {"sbc.mixed_levels:", bad_mixed},
    {"sbc.morphs:", bad_morphs},
    {"debug.points_last:", bad_points_last},
};

/* Every bad option value makes refl_render, refl_renderer_create and
   refl_validate_render_desc refuse the desc, naming the option; whatever
   the method (options of methods not used are checked too). */
Test(refl_renderer, every_bad_option_is_refused_by_name) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 16, 12);
    refl_frame *f = NULL;
    size_t i;
    int m;
    cr_assert_eq(refl_frame_create(16, 12, NULL, &f), REFL_OK);
    for (m = REFL_DIRECT; m <= REFL_C3RC; ++m)
        for (i = 0; i < sizeof bad_options / sizeof bad_options[0]; ++i) {
            refl_render_desc d = tu_refl_one_bounce((refl_method)m, 1);
            refl_renderer *rr = (refl_renderer *)&d;
            const char *why = NULL;
            bad_options[i].set(&d);
            if (m == REFL_RAYTRACE && bad_options[i].set == bad_object_raytrace) continue;
            cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT, "%s", bad_options[i].rule);
            cr_assert(why && !strncmp(why, bad_options[i].rule, strlen(bad_options[i].rule)),
                      "method %d: expected a message naming %s, got \"%s\"", m, bad_options[i].rule, why);
            cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT, "%s", bad_options[i].rule);
            cr_assert_str_eq(f->message, why);
            cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_ERROR_INVALID_ARGUMENT);
            cr_assert_null(rr);
        }
    /* the defaults are valid, and a good frame clears the message */
    cr_assert_eq(refl_validate_render_desc(NULL, NULL), REFL_OK);
    cr_assert_eq(refl_render(s, &v, NULL, f), REFL_OK);
    cr_assert_str_eq(f->message, "");
    /* a bad view is named too */
    v.fovy_degrees = 180.0f;
    cr_assert_eq(refl_render(s, &v, NULL, f), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert(!strncmp(f->message, "view.fovy_degrees:", 18), "%s", f->message);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* A planar mirror, a mirror sphere and a few diffuse objects. */
static refl_scene *two_mirrors(refl_view *v, int *plane, int *sphere) {
    refl_scene *s = NULL;
    refl_mesh *m = NULL;
    const float grey[3] = {0.9f, 0.9f, 0.9f}, red[3] = {0.8f, 0.2f, 0.1f}, blue[3] = {0.2f, 0.3f, 0.8f};
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(6.0f, 1, NULL, &m), REFL_OK);
    *plane = tu_refl_add_object(s, m, REFL_MIRROR, grey, refl_mat4_identity());
    cr_assert_eq(refl_mesh_sphere(0.8f, 32, 16, NULL, &m), REFL_OK);
    *sphere = tu_refl_add_object(s, m, REFL_MIRROR, grey, refl_mat4_translate(refl_v3(0.0f, 0.8f, 0.0f)));
    cr_assert_eq(refl_mesh_box(refl_v3(0.8f, 0.8f, 0.8f), NULL, &m), REFL_OK);
    tu_refl_add_object(s, m, REFL_DIFFUSE, red, refl_mat4_translate(refl_v3(1.6f, 0.4f, -0.8f)));
    cr_assert_eq(refl_mesh_torus(0.5f, 0.2f, 24, 12, NULL, &m), REFL_OK);
    tu_refl_add_object(s, m, REFL_DIFFUSE, blue, refl_mat4_translate(refl_v3(-1.5f, 0.3f, 0.9f)));
    tu_refl_add_point_light(s, refl_v3(2.0f, 5.0f, 3.0f), 1.0f, 0.0f);
    *v = tu_refl_view(refl_v3(0.5f, 2.6f, 5.0f), refl_v3(0.0f, 0.5f, 0.0f), 96, 72);
    return s;
}

/* One frame, each reflector its own method: each reflector's pixels are
   those a frame of its method alone gives it (one bounce), the rest the
   base pass's. (C3RC's density is set: its default follows the
   reflectors it draws.) */
Test(refl_renderer, each_reflector_with_its_own_method, .timeout = 60) {
    static const refl_method pairs[][2] = {{REFL_PLANAR, REFL_SBC}, {REFL_PLANAR, REFL_ENVMAP},
                                           {REFL_ENVMAP, REFL_C3RC}, {REFL_DIRECT, REFL_SBC}};
    refl_view v;
    int plane, sphere, k;
    refl_scene *s = two_mirrors(&v, &plane, &sphere);
    for (k = 0; k < (int)(sizeof pairs / sizeof pairs[0]); ++k) {
        refl_method per_object[2];
        refl_render_desc d = tu_refl_one_bounce(pairs[k][0], 2);
        refl_frame *alone0, *alone1, *mixed;
        d.c3rc.point_density = 300.0f;
        alone0 = tu_refl_render(s, &v, &d);
        long long on[2] = {0, 0};
        int i;
        d.method = pairs[k][1];
        alone1 = tu_refl_render(s, &v, &d);
        per_object[plane] = pairs[k][0];
        per_object[sphere] = pairs[k][1];
        d.method = REFL_DIRECT;
        d.object_methods = per_object;
        d.object_method_count = 2;
        mixed = tu_refl_render(s, &v, &d);
        for (i = 0; i < v.width * v.height; ++i) {
            const refl_frame *want = mixed->stencil[i] == plane + 1 ? alone0 : alone1;
            cr_assert_eq(mixed->stencil[i], alone0->stencil[i]);
            on[mixed->stencil[i] == plane + 1] += mixed->stencil[i] != 0;
            cr_assert_eq(memcmp(mixed->color + 4 * i, want->color + 4 * i, 4), 0,
                         "%s + %s: pixel %d (stencil %d) differs from its method's own frame",
                         refl_method_name(pairs[k][0]), refl_method_name(pairs[k][1]), i, mixed->stencil[i]);
            cr_assert(tu_refl_same_point(mixed->points + 3 * i, want->points + 3 * i),
                      "%s + %s: pixel %d (stencil %d): point (%g %g %g), its method's own (%g %g %g)",
                      refl_method_name(pairs[k][0]), refl_method_name(pairs[k][1]), i, mixed->stencil[i],
                      mixed->points[3 * i], mixed->points[3 * i + 1], mixed->points[3 * i + 2], want->points[3 * i],
                      want->points[3 * i + 1], want->points[3 * i + 2]);
        }
        cr_assert(on[0] > 200 && on[1] > 200, "the view shows %lld sphere and %lld plane pixels", on[0], on[1]);
        refl_frame_destroy(alone0);
        refl_frame_destroy(alone1);
        refl_frame_destroy(mixed);
    }
    refl_scene_destroy(s);
}
