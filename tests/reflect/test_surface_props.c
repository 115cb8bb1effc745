/* Paper 003's reflector surface properties (section V-D): the Fresnel
   blend (the mirror share's weight in cos^2 of the incidence, scaled to
   [fresnel_min, fresnel_max]) and the distance fade (quadratic in the
   distance from the reflector to what it reflects, from fade_max at 0 to
   fade_min at fade_distance and beyond). Known answers of the formulas,
   then each method's frame against the same frame without the fade: every
   mirror pixel must be scaled by the fade of the distance to the point it
   shows (its own frame->points), to within the colours' rounding. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

static refl_material mirror(void) {
    refl_material m;
    memset(&m, 0, sizeof m);
    m.type = REFL_MIRROR;
    m.color[0] = m.color[1] = m.color[2] = m.color[3] = 1.0f;
    return m;
}

Test(refl_surface_props, fresnel_blend_known_answers) {
    refl_material m = mirror();
    cr_assert_float_eq(refl_material_reflectance(&m, 0.5f), 1.0f, 1e-7, "off: unchanged");
    m.fresnel_min = 0.2f;
    m.fresnel_max = 0.8f;
    cr_assert_float_eq(refl_material_reflectance(&m, 1.0f), 0.2f, 1e-6, "facing the eye: the minimum");
    cr_assert_float_eq(refl_material_reflectance(&m, 0.0f), 0.8f, 1e-6, "grazing: the maximum");
    cr_assert_float_eq(refl_material_reflectance(&m, 0.5f), 0.8f - 0.6f * 0.25f, 1e-6);
    m.reflectance = 0.5f; /* scales the blend */
    cr_assert_float_eq(refl_material_reflectance(&m, 0.0f), 0.4f, 1e-6);
    m.type = REFL_PARTIAL;
    m.mirror_weight = 0.5f;
    cr_assert_float_eq(refl_material_reflectance(&m, 0.0f), 0.2f, 1e-6);
}

Test(refl_surface_props, fade_known_answers) {
    refl_material m = mirror(), glass;
    cr_assert_float_eq(refl_material_fade(&m, 3.0f), 1.0f, 1e-7, "off: no fade");
    m.fade_distance = 2.0f;
    m.fade_min = 0.1f;
    m.fade_max = 0.9f;
    cr_assert_float_eq(refl_material_fade(&m, 0.0f), 0.9f, 1e-6);
    cr_assert_float_eq(refl_material_fade(&m, 1.0f), 0.9f - 0.8f * 0.25f, 1e-6);
    cr_assert_float_eq(refl_material_fade(&m, 2.0f), 0.1f, 1e-6);
    cr_assert_float_eq(refl_material_fade(&m, 50.0f), 0.1f, 1e-6);
    cr_assert_float_eq(refl_material_fade(&m, INFINITY), 0.1f, 1e-6, "the environment: wholly faded");
    cr_assert_float_eq(refl_material_fade(&m, NAN), 0.1f, 1e-6);
    cr_assert_float_eq(refl_material_fade(NULL, 1.0f), 1.0f, 1e-7);
    glass = m;
    glass.type = REFL_GLASS;
    cr_assert_float_eq(refl_material_fade(&glass, 1.0f), 1.0f, 1e-7, "glass does not fade");
}

Test(refl_surface_props, non_finite_fields) {
    refl_scene *s = NULL;
    refl_material m = mirror();
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    m.fresnel_min = NAN;
    cr_assert_eq(refl_scene_add_material(s, &m), REFL_ERROR_INVALID_ARGUMENT);
    m = mirror();
    m.fade_distance = INFINITY;
    cr_assert_eq(refl_scene_add_material(s, &m), REFL_ERROR_INVALID_ARGUMENT);
    m = mirror();
    m.fade_max = NAN;
    cr_assert_eq(refl_scene_add_material(s, &m), REFL_ERROR_INVALID_ARGUMENT);
    /* edited by hand past the check: no NaN comes out (NaN weighs 0) */
    m = mirror();
    m.fresnel_min = NAN;
    m.fresnel_max = 0.5f;
    m.fade_distance = 1.0f;
    m.fade_min = NAN;
    m.fade_max = 1.0f;
    cr_assert(isfinite(refl_material_reflectance(&m, 0.3f)));
    cr_assert_float_eq(refl_material_fade(&m, 2.0f), 0.0f, 1e-7);
    refl_scene_destroy(s);
}

/* A mirror sphere over a floor among boxes; its material's fade set by
   the caller through the material index *mirror_material. */
static refl_scene *fade_scene(int *mirror_material) {
    static const float grey[3] = {0.7f, 0.7f, 0.7f}, red[3] = {0.9f, 0.2f, 0.1f}, silver[3] = {1, 1, 1};
    refl_scene *s = NULL;
    refl_mesh *floor = NULL, *box = NULL, *ball = NULL;
    int k;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(12.0f, 8, NULL, &floor), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(0.8f, 1.6f, 0.8f), NULL, &box), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(1.0f, 48, 24, NULL, &ball), REFL_OK);
    tu_refl_add_object(s, floor, REFL_DIFFUSE, grey, refl_mat4_translate(refl_v3(0, -1.0f, 0)));
    tu_refl_add_object(s, box, REFL_DIFFUSE, red, refl_mat4_translate(refl_v3(-1.8f, -0.2f, -1.0f)));
    k = tu_refl_add_object(s, ball, REFL_MIRROR, silver, refl_mat4_identity());
    tu_refl_add_point_light(s, refl_v3(3.0f, 5.0f, 4.0f), 1.0f, 0.0f);
    *mirror_material = s->objects[k].material;
    return s;
}

/* The surface point pixel i of frame f shows: its window depth taken back
   through the view (the frame's own surface, rasterised or traced). */
static refl_vec3 surface_point(const refl_view *v, const refl_scene *s, const refl_frame *f, int i) {
    refl_mat4 view_m, proj_m, inv;
    float nx = 2.0f * ((float)(i % v->width) + 0.5f) / (float)v->width - 1.0f;
    float ny = 1.0f - 2.0f * ((float)(i / v->width) + 0.5f) / (float)v->height;
    refl_view_matrices(v, s, &view_m, &proj_m);
    cr_assert(refl_mat4_invert(refl_mat4_mul(proj_m, view_m), &inv));
    return refl_mat4_point(inv, refl_v3(nx, ny, 2.0f * f->depth[i] - 1.0f));
}

static void check_method_fades(refl_method method) {
    int mat, i, checked = 0, faded = 0, n;
    refl_scene *s = fade_scene(&mat);
    refl_view v = tu_refl_view(refl_v3(0.3f, 0.8f, 4.0f), refl_v3(0, -0.2f, 0), 160, 120);
    refl_render_desc d = tu_refl_one_bounce(method, 2);
    refl_frame *plain, *fade;
    refl_material *m = &s->materials[mat];
    plain = tu_refl_render(s, &v, &d);
    m->fade_distance = 3.0f;
    m->fade_min = 0.2f;
    m->fade_max = 1.0f;
    fade = tu_refl_render(s, &v, &d);
    n = v.width * v.height;
    for (i = 0; i < n; ++i) {
        const float *p = fade->points + 3 * i;
        refl_vec3 q;
        float f, dist;
        int c;
        if (!fade->stencil[i]) continue;
        q = surface_point(&v, s, fade, i);
        dist = isfinite(p[0]) ? refl_v3_length(refl_v3_sub(refl_v3(p[0], p[1], p[2]), q)) : INFINITY;
        f = refl_material_fade(m, dist);
        for (c = 0; c < 3; ++c) {
            float want = (float)tu_unorm8(plain->rgba[4 * i + c]) * f, got = (float)tu_unorm8(fade->rgba[4 * i + c]);
            cr_assert(fabsf(got - want) <= 1.5f + 0.01f * want, "%s pixel %d channel %d: %g, want %g (fade %g at %g)",
                      refl_method_name(method), i, c, got, want, f, dist);
        }
        ++checked;
        faded += f < 0.99f;
    }
    cr_log_info("%s: %d mirror pixels checked, %d faded", refl_method_name(method), checked, faded);
    cr_assert(checked > 1000 && faded > checked / 2, "%d pixels, %d faded", checked, faded);
    refl_frame_destroy(plain);
    refl_frame_destroy(fade);
    refl_scene_destroy(s);
}

Test(refl_surface_props, raytrace_fades_by_the_reflected_distance) { check_method_fades(REFL_RAYTRACE); }
Test(refl_surface_props, sbc_fades_by_the_reflected_distance) { check_method_fades(REFL_SBC); }
Test(refl_surface_props, envmap_fades_by_the_reflected_distance) { check_method_fades(REFL_ENVMAP); }
Test(refl_surface_props, c3rc_fades_by_the_reflected_distance) { check_method_fades(REFL_C3RC); }
