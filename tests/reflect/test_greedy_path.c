/* Paper 001's greedy ray paths (refl_greedy_paths) with known answers: a
   glass slab at normal incidence (F_R = 0.04, F_T = 0.96^2 = 0.9216, G =
   tint exp(-a h), no deflection), at oblique incidence (the exit ray
   parallel to the eye ray, shifted by h sin(theta - theta_t) / cos
   theta_t), a right-angle prism whose hypotenuse reflects totally (45
   degrees inside, past the critical 41.8), a sphere through its centre;
   mirrors (one term) and bad rays. Then RAYTRACE's greedy option: its
   pixel is T F_T G_T + R F_R G_R of the same paths, mirror-only scenes give
   the same bytes as the full tree, and glass costs fewer rays. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "refl_test_util.h"

typedef tu_refl_traced lens_fixture;

static lens_fixture fixture(refl_mesh *mesh, const refl_material *m, refl_mat4 transform) {
    return tu_refl_traced_object(mesh, m, transform);
}

static void fixture_free(lens_fixture *f) { tu_refl_traced_free(f); }

static refl_material absorbing_glass(float attenuation) {
    refl_material g = refl_material_glass(1.5f);
    g.tint[0] = 1.0f;
    g.tint[1] = 0.8f;
    g.tint[2] = 0.5f;
    g.attenuation = attenuation;
    return g;
}

/* A slab h thick (z in [-h/2, h/2]), 8 x 8 wide. */
static lens_fixture slab(float h, const refl_material *m) {
    refl_mesh *mesh = NULL;
    cr_assert_eq(refl_mesh_box(refl_v3(8.0f, 8.0f, h), NULL, &mesh), REFL_OK);
    return fixture(mesh, m, refl_mat4_identity());
}

static void assert_v3_near(refl_vec3 a, refl_vec3 b, float eps, const char *what) {
    cr_assert(fabsf(a.x - b.x) <= eps && fabsf(a.y - b.y) <= eps && fabsf(a.z - b.z) <= eps,
              "%s: (%g %g %g), expected (%g %g %g)", what, a.x, a.y, a.z, b.x, b.y, b.z);
}

Test(greedy_path, slab_normal_incidence) {
    const float h = 0.5f, a = 0.4f;
    refl_material g = absorbing_glass(a);
    lens_fixture f = slab(h, &g);
    refl_greedy_paths_result r;
    long long rays = 0;
    int c;
    refl_greedy_paths(f.scene, &f.caster, refl_v3(0.3f, -0.2f, 5.0f), refl_v3(0, 0, -1), 0, &r, &rays);
    cr_assert_eq(r.terms, 2);
    cr_assert_eq(r.object, 0);
    /* reflection: 0.04 and straight back out */
    cr_assert(r.reflect.exited);
    cr_assert_eq(r.reflect.length, 1);
    cr_assert_eq(r.reflect.reflected, 1u);
    cr_assert_float_eq(r.reflect.fresnel, 0.04f, 1e-5f);
    assert_v3_near(r.reflect.exit_direction, refl_v3(0, 0, 1), 1e-6f, "R exit");
    for (c = 0; c < 3; ++c) cr_assert_float_eq(r.reflect.attenuation[c], 1.0f, 1e-6f);
    /* refraction: in and out, both refracting (0.96 each), undeflected */
    cr_assert(r.refract.exited);
    cr_assert_eq(r.refract.length, 2);
    cr_assert_eq(r.refract.reflected, 0u);
    cr_assert_float_eq(r.refract.fresnel, 0.9216f, 1e-5f);
    cr_assert_float_eq(r.refract.inside_length, h, 1e-5f);
    for (c = 0; c < 3; ++c) cr_assert_float_eq(r.refract.attenuation[c], g.tint[c] * expf(-a * h), 1e-5f);
    assert_v3_near(r.refract.exit_direction, refl_v3(0, 0, -1), 1e-6f, "T exit");
    assert_v3_near(r.refract.exit_origin, refl_v3(0.3f, -0.2f, -h / 2), 1e-5f, "T exit point");
    /* the eye ray, the reflection's exit, the refraction's inner and exit rays */
    cr_assert_eq(rays, 4);
    fixture_free(&f);
}

Test(greedy_path, slab_oblique_lateral_shift) {
    const float h = 0.5f, n = 1.5f;
    refl_material g = absorbing_glass(0.0f);
    lens_fixture f = slab(h, &g);
    float theta;
    for (theta = 10.0f; theta <= 70.0f; theta += 20.0f) {
        float th = theta * 3.14159265f / 180.0f, tt = asinf(sinf(th) / n);
        refl_vec3 d = refl_v3(sinf(th), 0.0f, -cosf(th)), o = refl_v3(-3.0f * sinf(th), 0.1f, 3.0f * cosf(th));
        refl_vec3 q;
        refl_greedy_paths_result r;
        float shift, along, expected_f;
        refl_greedy_paths(f.scene, &f.caster, o, d, 0, &r, NULL);
        cr_assert_eq(r.terms, 2);
        cr_assert_eq(r.refract.length, 2);
        assert_v3_near(r.refract.exit_direction, d, 1e-5f, "parallel exit");
        /* the exit point's distance from the eye ray's line */
        q = refl_v3_sub(r.refract.exit_origin, o);
        along = refl_v3_dot(q, d);
        shift = refl_v3_length(refl_v3_sub(q, refl_v3_scale(d, along)));
        cr_assert_float_eq(shift, h * sinf(th - tt) / cosf(tt), 1e-4f, "theta %g: shift %g", theta, shift);
        cr_assert_float_eq(r.refract.inside_length, h / cosf(tt), 1e-4f);
        /* F_T: the same transmittance in and out (Stokes) */
        expected_f = 1.0f - refl_fresnel_dielectric(cosf(th), 1.0f, n);
        cr_assert_float_eq(r.refract.fresnel, expected_f * expected_f, 1e-4f);
        cr_assert_float_eq(r.reflect.fresnel, refl_fresnel_dielectric(cosf(th), 1.0f, n), 1e-6f);
    }
    fixture_free(&f);
}

/* A right-angle prism along y: cross-section (x, z) = (0, 0), (2, 0),
   (0, -2); faces z = 0 (up), x = 0 and the hypotenuse x - z = 2. Flat
   normals, triangles wound outwards. */
static refl_mesh *prism(void) {
    static const float xz[3][2] = {{0, 0}, {2, 0}, {0, -2}};
    float pos[8 * 9], nrm[8 * 9], cx = 2.0f / 3.0f, cz = -2.0f / 3.0f;
    int quads[3][2] = {{0, 1}, {1, 2}, {2, 0}}, t = 0, k, v;
    float tri[8][3][3];
    refl_mesh_desc d;
    refl_mesh *m = NULL;
    /* the two ends */
    for (k = 0; k < 3; ++k) {
        tri[0][k][0] = xz[k][0], tri[0][k][1] = -1.0f, tri[0][k][2] = xz[k][1];
        tri[1][k][0] = xz[k][0], tri[1][k][1] = 1.0f, tri[1][k][2] = xz[k][1];
    }
    t = 2;
    for (k = 0; k < 3; ++k) {
        const float *p = xz[quads[k][0]], *q = xz[quads[k][1]];
        float c[4][3] = {{p[0], -1, p[1]}, {q[0], -1, q[1]}, {q[0], 1, q[1]}, {p[0], 1, p[1]}};
        memcpy(tri[t][0], c[0], sizeof c[0]), memcpy(tri[t][1], c[1], sizeof c[0]), memcpy(tri[t][2], c[2], sizeof c[0]);
        ++t;
        memcpy(tri[t][0], c[0], sizeof c[0]), memcpy(tri[t][1], c[2], sizeof c[0]), memcpy(tri[t][2], c[3], sizeof c[0]);
        ++t;
    }
    for (t = 0; t < 8; ++t) {
        refl_vec3 a = refl_v3(tri[t][0][0], tri[t][0][1], tri[t][0][2]);
        refl_vec3 b = refl_v3(tri[t][1][0], tri[t][1][1], tri[t][1][2]);
        refl_vec3 c = refl_v3(tri[t][2][0], tri[t][2][1], tri[t][2][2]);
        refl_vec3 n = refl_v3_normalize(refl_v3_cross(refl_v3_sub(b, a), refl_v3_sub(c, a)));
        refl_vec3 mid = refl_v3_scale(refl_v3_add(refl_v3_add(a, b), c), 1.0f / 3.0f);
        if (refl_v3_dot(n, refl_v3_sub(mid, refl_v3(cx, 0.0f, cz))) < 0.0f) { /* wind outwards */
            refl_vec3 s = b;
            b = c;
            c = s;
            n = refl_v3_scale(n, -1.0f);
        }
        {
            refl_vec3 vs[3];
            vs[0] = a, vs[1] = b, vs[2] = c;
            for (v = 0; v < 3; ++v) {
                pos[9 * t + 3 * v] = vs[v].x, pos[9 * t + 3 * v + 1] = vs[v].y, pos[9 * t + 3 * v + 2] = vs[v].z;
                nrm[9 * t + 3 * v] = n.x, nrm[9 * t + 3 * v + 1] = n.y, nrm[9 * t + 3 * v + 2] = n.z;
            }
        }
    }
    memset(&d, 0, sizeof d);
    d.positions = pos;
    d.normals = nrm;
    d.vertex_count = 24;
    cr_assert_eq(refl_mesh_create(&d, &m), REFL_OK);
    return m;
}

Test(greedy_path, prism_total_internal_reflection) {
    const float a = 0.3f;
    refl_material g = absorbing_glass(a);
    lens_fixture f = fixture(prism(), &g, refl_mat4_identity());
    refl_greedy_paths_result r;
    int c;
    refl_greedy_paths(f.scene, &f.caster, refl_v3(0.5f, 0.2f, 3.0f), refl_v3(0, 0, -1), 0, &r, NULL);
    cr_assert_eq(r.terms, 2);
    /* in (T), the hypotenuse at 45 degrees: totally reflected (R), out through x = 0 (T) */
    cr_assert(r.refract.exited);
    cr_assert_eq(r.refract.length, 3);
    cr_assert_eq(r.refract.reflected, 2u, "choices %x", r.refract.reflected);
    cr_assert_float_eq(r.refract.fresnel, 0.9216f, 1e-5f);
    cr_assert_float_eq(r.refract.inside_length, 2.0f, 1e-5f);
    for (c = 0; c < 3; ++c) cr_assert_float_eq(r.refract.attenuation[c], g.tint[c] * expf(-2.0f * a), 1e-5f);
    assert_v3_near(r.refract.exit_direction, refl_v3(-1, 0, 0), 1e-5f, "turned by 90 degrees");
    assert_v3_near(r.refract.exit_origin, refl_v3(0.0f, 0.2f, -1.5f), 1e-5f, "exit point");
    fixture_free(&f);
}

Test(greedy_path, inside_past_critical_angle_reflects) {
    /* from inside a slab at 50 degrees (critical: asin(1/1.5) = 41.8): every
       interface reflects totally, and the path never leaves */
    refl_material g = absorbing_glass(0.0f);
    lens_fixture f = slab(0.5f, &g);
    refl_greedy_paths_result r;
    float th = 50.0f * 3.14159265f / 180.0f;
    refl_greedy_paths(f.scene, &f.caster, refl_v3(0, 0, 0), refl_v3(sinf(th), 0, -cosf(th)), 6, &r, NULL);
    cr_assert_eq(r.terms, 2);
    cr_assert_float_eq(r.reflect.fresnel, 1.0f, 1e-6f);
    cr_assert_eq(r.refract.fresnel, 0.0f, "no refracted term past the critical angle");
    cr_assert_not(r.reflect.exited);
    cr_assert_eq(r.reflect.length, 6);
    cr_assert_eq(r.reflect.reflected, 63u);
    /* below it (30 degrees), refraction carries more: the path leaves at once */
    th = 30.0f * 3.14159265f / 180.0f;
    refl_greedy_paths(f.scene, &f.caster, refl_v3(0, 0, 0), refl_v3(sinf(th), 0, -cosf(th)), 6, &r, NULL);
    cr_assert(r.refract.exited);
    cr_assert_eq(r.refract.length, 1);
    cr_assert_float_eq(r.refract.fresnel, 1.0f - refl_fresnel_dielectric(cosf(th), 1.5f, 1.0f), 1e-6f);
    fixture_free(&f);
}

Test(greedy_path, sphere_through_centre) {
    refl_material g = absorbing_glass(0.0f);
    refl_mesh *mesh = NULL;
    lens_fixture f;
    refl_greedy_paths_result r;
    cr_assert_eq(refl_mesh_sphere(1.0f, 96, 48, NULL, &mesh), REFL_OK);
    f = fixture(mesh, &g, refl_mat4_identity());
    refl_greedy_paths(f.scene, &f.caster, refl_v3(0.0f, 0.0f, 4.0f), refl_v3(0, 0, -1), 0, &r, NULL);
    cr_assert_eq(r.refract.length, 2);
    cr_assert_float_eq(r.refract.inside_length, 2.0f, 2e-3f);
    assert_v3_near(r.refract.exit_direction, refl_v3(0, 0, -1), 1e-3f, "undeflected");
    fixture_free(&f);
}

Test(greedy_path, mirror_is_one_term) {
    refl_material m = refl_material_mirror(0.8f);
    lens_fixture f = slab(0.5f, &m);
    refl_greedy_paths_result r;
    refl_greedy_paths(f.scene, &f.caster, refl_v3(0, 0, 5), refl_v3_normalize(refl_v3(0.2f, 0, -1)), 0, &r, NULL);
    cr_assert_eq(r.terms, 1);
    cr_assert_float_eq(r.reflect.fresnel, 0.8f, 1e-6f);
    cr_assert_eq(r.refract.fresnel, 0.0f);
    assert_v3_near(r.reflect.exit_direction, refl_v3_normalize(refl_v3(0.2f, 0, 1)), 1e-6f, "mirrored");
    /* a miss and bad rays: no terms, no NaN */
    refl_greedy_paths(f.scene, &f.caster, refl_v3(0, 0, 5), refl_v3(0, 0, 1), 0, &r, NULL);
    cr_assert_eq(r.terms, 0);
    cr_assert_eq(r.object, -1);
    refl_greedy_paths(f.scene, &f.caster, refl_v3(0, 0, 5), refl_v3(NAN, 0, -1), 0, &r, NULL);
    cr_assert_eq(r.terms, 0);
    refl_greedy_paths(NULL, &f.caster, refl_v3(0, 0, 5), refl_v3(0, 0, -1), 0, &r, NULL);
    cr_assert_eq(r.terms, 0);
    fixture_free(&f);
}

/* ---- RAYTRACE's greedy option ------------------------------------------------- */

static refl_frame *raytrace(const refl_scene *s, const refl_view *v, int greedy, int threads) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = REFL_RAYTRACE;
    d.threads = threads;
    d.raytrace.greedy = greedy;
    return tu_refl_render(s, v, &d);
}

Test(greedy_path, raytrace_pixel_is_the_two_terms) {
    /* a tinted slab under a constant sky seen straight on: the centre pixel
       is sky (0.04 + 0.9216 tint exp(-a h)) */
    const float h = 0.5f, a = 0.4f;
    refl_material g = absorbing_glass(a);
    lens_fixture f = slab(h, &g);
    refl_environment env;
    refl_view v = tu_refl_view(refl_v3(0, 0, 5), refl_v3(0, 0, 0), 33, 33);
    refl_frame *fr;
    size_t centre = 16 * 33 + 16;
    int c;
    memset(&env, 0, sizeof env);
    env.type = REFL_ENV_COLOR;
    env.color[0] = 0.9f, env.color[1] = 0.6f, env.color[2] = 0.3f;
    cr_assert_eq(refl_scene_set_environment(f.scene, &env), REFL_OK);
    fr = raytrace(f.scene, &v, 1, 2);
    for (c = 0; c < 3; ++c) {
        float expected = env.color[c] * (0.04f + 0.9216f * g.tint[c] * expf(-a * h));
        cr_assert_float_eq(fr->rgba[4 * centre + (size_t)c], expected, 1e-4f, "channel %d", c);
    }
    refl_frame_destroy(fr);
    fixture_free(&f);
}

Test(greedy_path, mirror_scenes_same_bytes) {
    static const char *const names[] = {"default", "mirror-room", "concave"};
    int k;
    for (k = 0; k < 3; ++k) {
        refl_view v;
        refl_scene *s = tu_refl_builtin(names[k], &v, 96, 72);
        refl_frame *full = raytrace(s, &v, 0, 2), *greedy = raytrace(s, &v, 1, 2);
        cr_assert_eq(tu_refl_digest(full), tu_refl_digest(greedy), "%s", names[k]);
        cr_assert_eq(full->stats.rays, greedy->stats.rays);
        refl_frame_destroy(full);
        refl_frame_destroy(greedy);
        refl_scene_destroy(s);
    }
}

Test(greedy_path, glass_fewer_rays_any_threads) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("glass", &v, 96, 72);
    refl_frame *full = raytrace(s, &v, 0, 2), *g1 = raytrace(s, &v, 1, 1), *g3 = raytrace(s, &v, 1, 3);
    cr_assert_lt(g1->stats.rays, full->stats.rays);
    cr_assert_neq(tu_refl_digest(full), tu_refl_digest(g1), "the glass differs");
    cr_assert_eq(tu_refl_digest(g1), tu_refl_digest(g3));
    refl_frame_destroy(full);
    refl_frame_destroy(g1);
    refl_frame_destroy(g3);
    refl_scene_destroy(s);
}
