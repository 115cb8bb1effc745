/* RAYTRACE, the reference: a plane mirror shows the analytic mirror image
   (also far from the origin, where careless ray offsets cause acne), a
   glass slab shifts what is behind it by Snell's law, shadows fall where
   the geometry says, the Fresnel terms give their textbook values,
   exhausted bounces show what DIRECT shows, another ray caster gives the
   same bytes, and the output (and the triangle tests counted) is the same
   for every thread count. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

static refl_frame *render_rt(const refl_scene *s, const refl_view *v, int depth, int shadows, int threads) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = REFL_RAYTRACE;
    d.depth = depth;
    d.lighting.shadows = shadows;
    d.threads = threads;
    return tu_refl_render(s, v, &d);
}

/* The world ray of a pixel centre, from the camera's basis in double
   precision (as gluLookAt and gluPerspective define the view). */
static void pixel_ray(const refl_scene *s, const refl_view *v, int x, int y, double o[3], double d[3]) {
    double f[3], r[3], u[3], len, t = tan(0.5 * (v->fovy_degrees > 0 ? v->fovy_degrees : 45.0) * 3.14159265358979323846 / 180.0);
    double nx = 2.0 * (x + 0.5) / v->width - 1.0, ny = 1.0 - 2.0 * (y + 0.5) / v->height;
    double aspect = (double)v->width / v->height;
    refl_vec3 origin;
    int k;
    f[0] = (double)v->target.x - v->eye.x; f[1] = (double)v->target.y - v->eye.y; f[2] = (double)v->target.z - v->eye.z;
    len = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    for (k = 0; k < 3; ++k) f[k] /= len;
    r[0] = f[1] * v->up.z - f[2] * v->up.y; r[1] = f[2] * v->up.x - f[0] * v->up.z; r[2] = f[0] * v->up.y - f[1] * v->up.x;
    len = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    for (k = 0; k < 3; ++k) r[k] /= len;
    u[0] = r[1] * f[2] - r[2] * f[1]; u[1] = r[2] * f[0] - r[0] * f[2]; u[2] = r[0] * f[1] - r[1] * f[0];
    for (k = 0; k < 3; ++k) d[k] = f[k] + r[k] * nx * t * aspect + u[k] * ny * t;
    len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (k = 0; k < 3; ++k) d[k] /= len;
    /* the near plane is the library's choice: take its origin, check it lies on this ray */
    refl_view_ray(v, s, (float)x + 0.5f, (float)y + 0.5f, &origin, NULL, NULL);
    o[0] = origin.x; o[1] = origin.y; o[2] = origin.z;
}

/* Slab test against the box [lo, hi]: entry distance, or -1. */
static double ray_box(const double o[3], const double d[3], const double lo[3], const double hi[3]) {
    double t0 = 0.0, t1 = 1e300;
    int k;
    for (k = 0; k < 3; ++k) {
        double a, b;
        if (d[k] == 0.0) {
            if (o[k] < lo[k] || o[k] > hi[k]) return -1.0;
            continue;
        }
        a = (lo[k] - o[k]) / d[k];
        b = (hi[k] - o[k]) / d[k];
        if (a > b) { double t = a; a = b; b = t; }
        if (a > t0) t0 = a;
        if (b < t1) t1 = b;
    }
    return t0 <= t1 && t0 > 0.0 ? t0 : -1.0;
}

static void add_directional(refl_scene *s, refl_vec3 dir, float k) {
    refl_light l;
    memset(&l, 0, sizeof l);
    l.type = REFL_LIGHT_DIRECTIONAL;
    l.direction = dir;
    l.color[0] = l.color[1] = l.color[2] = k;
    cr_assert(refl_scene_add_light(s, &l) >= 0);
}

/* A mirror floor (y = off.y) under a diffuse box, everything shifted by
   off: every mirror pixel must show the point where the mirrored ray
   meets the box, and that point shaded. */
static void check_plane_mirror(refl_vec3 off) {
    static const float white[3] = {1, 1, 1}, orange[3] = {0.9f, 0.5f, 0.2f};
    refl_scene *s;
    refl_mesh *plane, *box;
    refl_view v;
    refl_frame *f;
    /* Reflected rays start 4 float ulps (of the largest coordinate) off the
       mirror; this grazing view stretches that about 3 times along the
       floor. A self-hit (acne) would show a point on the mirror itself,
       metres away. */
    double lo[3], hi[3], tol = 2e-4 + 4e-6 * fmax(fabs(off.x), fmax(fabs(off.y), fabs(off.z)));
    int mirror, x, y, checked = 0, on_box = 0, edges = 0;
    tu_check chk = {0};
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(20.0f, 4, NULL, &plane), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(2, 2, 2), NULL, &box), REFL_OK);
    mirror = tu_refl_add_object(s, plane, REFL_MIRROR, white, refl_mat4_translate(off));
    tu_refl_add_object(s, box, REFL_DIFFUSE, orange, refl_mat4_translate(refl_v3_add(off, refl_v3(0.5f, 2.0f, -1.0f))));
    add_directional(s, refl_v3(-0.3f, -1.0f, -0.5f), 0.8f);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 0.15f;
    s->environment.color[0] = 0.3f; s->environment.color[1] = 0.5f; s->environment.color[2] = 0.8f;
    lo[0] = off.x - 0.5; lo[1] = off.y + 1.0; lo[2] = off.z - 2.0;
    hi[0] = off.x + 1.5; hi[1] = off.y + 3.0; hi[2] = off.z + 0.0;
    memset(&v, 0, sizeof v);
    v.eye = refl_v3_add(off, refl_v3(0.0f, 2.5f, 9.0f));
    v.target = refl_v3_add(off, refl_v3(0.0f, 0.0f, 0.0f));
    v.up = refl_v3(0, 1, 0);
    v.width = 160; v.height = 120;
    f = render_rt(s, &v, 1, 0, 2);
    for (y = 0; y < v.height; ++y)
        for (x = 0; x < v.width; ++x) {
            size_t i = (size_t)y * (size_t)v.width + (size_t)x;
            double o[3], d[3], m[3], r[3], t, p[3], g[3], gl[3], gh[3], sl[3], sh[3];
            const float *got = f->points + 3 * i;
            int k;
            if (f->stencil[i] != mirror + 1) continue;
            pixel_ray(s, &v, x, y, o, d);
            t = (off.y - o[1]) / d[1];
            for (k = 0; k < 3; ++k) { m[k] = o[k] + t * d[k]; r[k] = d[k]; }
            r[1] = -r[1];
            /* pixels whose mirrored ray grazes a box edge may go either way */
            for (k = 0; k < 3; ++k) {
                gl[k] = lo[k] - tol; gh[k] = hi[k] + tol;
                sl[k] = lo[k] + tol; sh[k] = hi[k] - tol;
            }
            if ((ray_box(m, r, gl, gh) > 0) != (ray_box(m, r, sl, sh) > 0)) { ++edges; continue; }
            t = ray_box(m, r, lo, hi);
            ++checked;
            if (t < 0) {
                TU_CHECK(&chk, isnan(got[0]), "pixel %d,%d: shows %g,%g,%g where the mirror shows the sky", x, y,
                         got[0], got[1], got[2]);
                continue;
            }
            ++on_box;
            for (k = 0; k < 3; ++k) p[k] = m[k] + t * r[k];
            for (k = 0; k < 3; ++k) g[k] = got[k];
            TU_CHECK(&chk, fabs(g[0] - p[0]) + fabs(g[1] - p[1]) + fabs(g[2] - p[2]) < tol,
                     "pixel %d,%d: shows %.6f,%.6f,%.6f, the mirror image is %.6f,%.6f,%.6f", x, y, g[0], g[1],
                     g[2], p[0], p[1], p[2]);
            {
                /* the colour: the shared diffuse model at the true point, on
                   its face (within tol of another face, either may show) */
                refl_vec3 n = refl_v3(0, 0, 0);
                float rgb[3];
                int c;
                for (k = 0; k < 3; ++k) {
                    if (fabs(p[k] - lo[k]) < 4 * tol) ((float *)&n)[k] = -1.0f;
                    if (fabs(p[k] - hi[k]) < 4 * tol) ((float *)&n)[k] = 1.0f;
                }
                if (fabsf(n.x) + fabsf(n.y) + fabsf(n.z) != 1.0f) continue; /* by an edge */
                refl_shade_diffuse(s, &s->materials[1], refl_v3((float)p[0], (float)p[1], (float)p[2]), n, NULL,
                                   rgb);
                for (c = 0; c < 3; ++c) {
                    int want = (int)(fminf(fmaxf(rgb[c], 0.0f), 1.0f) * 255.0f + 0.5f);
                    TU_CHECK(&chk, abs((int)tu_unorm8(f->rgba[4 * i + (size_t)c]) - want) <= 1,
                             "pixel %d,%d channel %d: %d, the shaded mirror image is %d", x, y, c,
                             tu_unorm8(f->rgba[4 * i + (size_t)c]), want);
                }
            }
        }
    cr_log_info("plane mirror at offset %g: %d pixels checked (%d on the box), %d at box edges skipped", off.x,
                checked, on_box, edges);
    cr_assert(on_box > 400 && edges < on_box / 2, "the view must show the box in the mirror (%d, %d)", on_box,
              edges);
    TU_CHECK_DONE(&chk);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

Test(refl_raytrace, plane_mirror_shows_the_analytic_mirror_image) { check_plane_mirror(refl_v3(0, 0, 0)); }

/* Ulps at 1e4 are 1e-3: an offset of a fixed epsilon would leave the ray
   on the mirror (acne) or skip the box's nearby faces. */
Test(refl_raytrace, plane_mirror_far_from_the_origin_has_no_acne) {
    check_plane_mirror(refl_v3(1.0e4f, -5.0e3f, 2.0e4f));
}

/* A glass slab over a floor: light leaves parallel to how it entered,
   shifted sideways; the point shown is where the shifted ray meets the
   floor (the stronger, refracted branch). */
Test(refl_raytrace, glass_slab_shifts_the_floor_by_snells_law) {
    static const float grey[3] = {0.7f, 0.7f, 0.7f};
    refl_scene *s;
    refl_mesh *floor_mesh, *slab;
    refl_view v;
    refl_frame *f;
    int glass, x, y, checked = 0;
    const double ior = 1.5, top = 1.25, bottom = 0.75, half = 2.0;
    double max_shift = 0.0;
    tu_check chk = {0};
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(30.0f, 2, NULL, &floor_mesh), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(4.0f, 0.5f, 4.0f), NULL, &slab), REFL_OK);
    tu_refl_add_object(s, floor_mesh, REFL_DIFFUSE, grey, refl_mat4_identity());
    glass = tu_refl_add_object(s, slab, REFL_GLASS, grey, refl_mat4_translate(refl_v3(0, 1.0f, 0)));
    s->materials[s->objects[glass].material].ior = (float)ior;
    add_directional(s, refl_v3(0.2f, -1.0f, -0.3f), 0.8f);
    memset(&v, 0, sizeof v);
    v.eye = refl_v3(0.0f, 4.0f, 5.0f);
    v.target = refl_v3(0.0f, 0.5f, 0.0f);
    v.up = refl_v3(0, 1, 0);
    v.width = 160; v.height = 120;
    f = render_rt(s, &v, 4, 0, 2);
    for (y = 0; y < v.height; ++y)
        for (x = 0; x < v.width; ++x) {
            size_t i = (size_t)y * (size_t)v.width + (size_t)x;
            double o[3], d[3], m1[3], in[3], m2[3], p[3], t, cos_i, eta = 1.0 / ior, k2, cos_t;
            const float *got = f->points + 3 * i;
            int k;
            if (f->stencil[i] != glass + 1) continue;
            pixel_ray(s, &v, x, y, o, d);
            t = (top - o[1]) / d[1];
            for (k = 0; k < 3; ++k) m1[k] = o[k] + t * d[k];
            /* the top face only, away from its edges */
            if (fabs(m1[0]) > half - 0.05 || fabs(m1[2]) > half - 0.05) continue;
            cos_i = -d[1];
            k2 = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
            cos_t = sqrt(k2);
            for (k = 0; k < 3; ++k) in[k] = eta * d[k];
            in[1] += eta * cos_i - cos_t; /* n = +y */
            t = (bottom - m1[1]) / in[1];
            for (k = 0; k < 3; ++k) m2[k] = m1[k] + t * in[k];
            if (fabs(m2[0]) > half - 0.05 || fabs(m2[2]) > half - 0.05) continue; /* leaves by a side */
            t = (0.0 - m2[1]) / d[1];
            for (k = 0; k < 3; ++k) p[k] = m2[k] + t * d[k];
            ++checked;
            {
                /* the sideways shift against the unrefracted ray */
                double q = (0.0 - o[1]) / d[1], dx = p[0] - (o[0] + q * d[0]), dz = p[2] - (o[2] + q * d[2]);
                max_shift = fmax(max_shift, sqrt(dx * dx + dz * dz));
            }
            TU_CHECK(&chk, fabs(got[0] - p[0]) + fabs(got[1] - p[1]) + fabs(got[2] - p[2]) < 1e-4,
                     "pixel %d,%d: shows %.6f,%.6f,%.6f, Snell's law says %.6f,%.6f,%.6f", x, y, got[0], got[1],
                     got[2], p[0], p[1], p[2]);
        }
    cr_log_info("glass slab: %d pixels checked, largest sideways shift %.3f", checked, max_shift);
    cr_assert(checked > 1000 && max_shift > 0.05, "the view must look through the slab (%d, %g)", checked,
              max_shift);
    TU_CHECK_DONE(&chk);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

Test(refl_raytrace, fresnel_terms_have_their_textbook_values) {
    double n1 = 1.0, n2 = 1.5, theta_b = atan(n2 / n1), ci = cos(theta_b), st = n1 / n2 * sin(theta_b);
    double ct = sqrt(1.0 - st * st), rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    double crit = asin(n2 > n1 ? n1 / n2 : n2 / n1);
    refl_material m;
    /* normal incidence: ((n1 - n2) / (n1 + n2))^2, the same both ways */
    cr_assert_float_eq(refl_fresnel_dielectric(1.0f, 1.0f, 1.5f), 0.04f, 1e-6);
    cr_assert_float_eq(refl_fresnel_dielectric(1.0f, 1.5f, 1.0f), 0.04f, 1e-6);
    /* Brewster's angle: the p-polarised part vanishes */
    cr_assert_float_eq(refl_fresnel_dielectric((float)ci, 1.0f, 1.5f), (float)(0.5 * rs * rs), 1e-5);
    /* total internal reflection from inside glass, beyond the critical angle */
    cr_assert_eq(refl_fresnel_dielectric((float)cos(crit + 1e-3), 1.5f, 1.0f), 1.0f);
    cr_assert(refl_fresnel_dielectric((float)cos(crit - 1e-3), 1.5f, 1.0f) < 1.0f);
    cr_assert_float_eq(refl_fresnel_dielectric(0.0f, 1.0f, 1.5f), 1.0f, 1e-6); /* grazing */
    cr_assert_eq(refl_fresnel_dielectric(0.5f, 1.0f, 0.0f), 1.0f);              /* nonsense: no NaN */
    memset(&m, 0, sizeof m);
    cr_assert_eq(refl_material_reflectance(&m, 0.5f), 0.0f);
    m.type = REFL_MIRROR;
    cr_assert_eq(refl_material_reflectance(&m, 0.5f), 1.0f);
    m.reflectance = 0.5f;
    m.fresnel = 1;
    cr_assert_float_eq(refl_material_reflectance(&m, 1.0f), 0.5f, 1e-6);
    cr_assert_float_eq(refl_material_reflectance(&m, 0.0f), 1.0f, 1e-6);
    cr_assert_float_eq(refl_material_reflectance(&m, 0.5f), 0.5f + 0.5f / 32.0f, 1e-6); /* Schlick */
    m.type = REFL_PARTIAL;
    m.mirror_weight = 0.25f;
    cr_assert_float_eq(refl_material_reflectance(&m, 1.0f), 0.125f, 1e-6);
    m.type = REFL_GLASS;
    cr_assert_float_eq(refl_material_reflectance(&m, 1.0f), 0.04f, 1e-6);
}

/* A box over a white floor under a light from straight above: with
   shadows, the floor is dark exactly under the box. */
Test(refl_raytrace, hard_shadows_fall_under_the_box) {
    static const float white[3] = {1, 1, 1};
    refl_scene *s;
    refl_mesh *floor_mesh, *box;
    refl_view v;
    refl_frame *lit, *shadowed;
    int x, y, under = 0, open = 0;
    tu_check chk = {0};
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(10.0f, 2, NULL, &floor_mesh), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(1, 1, 1), NULL, &box), REFL_OK);
    tu_refl_add_object(s, floor_mesh, REFL_DIFFUSE, white, refl_mat4_identity());
    tu_refl_add_object(s, box, REFL_DIFFUSE, white, refl_mat4_translate(refl_v3(0, 2.0f, 0)));
    add_directional(s, refl_v3(0, -1, 0), 0.5f);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 0.2f;
    memset(&v, 0, sizeof v);
    v.eye = refl_v3(3.0f, 6.0f, 4.0f);
    v.target = refl_v3(0, 0, 0);
    v.up = refl_v3(0, 1, 0);
    v.width = 160; v.height = 120;
    lit = render_rt(s, &v, 1, 0, 2);
    shadowed = render_rt(s, &v, 1, 1, 2);
    for (y = 0; y < v.height; ++y)
        for (x = 0; x < v.width; ++x) {
            size_t i = (size_t)y * (size_t)v.width + (size_t)x;
            double o[3], d[3], t, px, pz, lo[3] = {-0.5, 1.5, -0.5}, hi[3] = {0.5, 2.5, 0.5};
            int in_shadow;
            pixel_ray(s, &v, x, y, o, d);
            if (ray_box(o, d, lo, hi) > 0) continue; /* the box itself */
            t = -o[1] / d[1];
            px = o[0] + t * d[0];
            pz = o[2] + t * d[2];
            if (t < 0 || fabs(px) > 4.9 || fabs(pz) > 4.9) continue;
            if (fabs(fabs(px) - 0.5) < 0.02 || fabs(fabs(pz) - 0.5) < 0.02) continue; /* shadow edge */
            in_shadow = fabs(px) < 0.5 && fabs(pz) < 0.5;
            under += in_shadow;
            open += !in_shadow;
            TU_CHECK(&chk, fabsf(lit->rgba[4 * i] - 0.7f) < 1e-5f, "pixel %d,%d unshadowed: %g, want 0.7", x, y,
                     lit->rgba[4 * i]);
            TU_CHECK(&chk, fabsf(shadowed->rgba[4 * i] - (in_shadow ? 0.2f : 0.7f)) < 1e-5f, "pixel %d,%d: %g, want %s",
                     x, y, shadowed->rgba[4 * i], in_shadow ? "0.2 (shadow)" : "0.7 (lit)");
        }
    cr_assert(under > 100 && open > 1000, "the view must show the shadow (%d, %d)", under, open);
    TU_CHECK_DONE(&chk);
    cr_assert(shadowed->stats.rays > lit->stats.rays, "shadow rays are counted");
    refl_frame_destroy(lit);
    refl_frame_destroy(shadowed);
    refl_scene_destroy(s);
}

/* A mirror ball beside a half-mirror ball: with one bounce the first ball
   shows the second as DIRECT draws it (its diffuse share), with two it
   adds the second's reflection; the environment shows, weighted by the
   reflectance, wherever rays escape. */
Test(refl_raytrace, exhausted_bounces_show_what_direct_shows_and_misses_the_environment) {
    static const float white[3] = {1, 1, 1}, green[3] = {0.2f, 0.8f, 0.4f};
    refl_scene *s;
    refl_mesh *a, *b;
    refl_view v;
    refl_frame *one, *two;
    int x, y, ball_in_ball = 0, sky = 0, brighter = 0, half;
    tu_check chk = {0};
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(1.0f, 96, 48, NULL, &a), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(1.0f, 96, 48, NULL, &b), REFL_OK);
    tu_refl_add_object(s, a, REFL_MIRROR, white, refl_mat4_translate(refl_v3(-1.2f, 0, 0)));
    half = tu_refl_add_object(s, b, REFL_PARTIAL, green, refl_mat4_translate(refl_v3(1.2f, 0, 0)));
    s->materials[0].reflectance = 0.5f;
    s->materials[s->objects[half].material].mirror_weight = 0.5f;
    add_directional(s, refl_v3(-1.0f, -0.5f, -0.5f), 0.9f);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 0.1f;
    s->environment.color[0] = 0.2f; s->environment.color[1] = 0.4f; s->environment.color[2] = 0.6f;
    memset(&v, 0, sizeof v);
    v.eye = refl_v3(0, 0.5f, 6.0f);
    v.target = refl_v3(0, 0, 0);
    v.up = refl_v3(0, 1, 0);
    v.width = 160; v.height = 120;
    one = render_rt(s, &v, 1, 0, 2);
    two = render_rt(s, &v, 2, 0, 2);
    for (y = 0; y < v.height; ++y)
        for (x = 0; x < v.width; ++x) {
            size_t i = (size_t)y * (size_t)v.width + (size_t)x;
            const float *p = one->points + 3 * i;
            refl_vec3 n;
            float rgb[3];
            int c;
            if (one->stencil[i] != 1) continue;
            if (isnan(p[0])) {
                /* the sky, at half strength: 0.1 0.2 0.3 */
                ++sky;
                TU_CHECK(&chk, tu_unorm8(one->rgba[4 * i]) == 26 && tu_unorm8(one->rgba[4 * i + 1]) == 51 && tu_unorm8(one->rgba[4 * i + 2]) == 77,
                         "pixel %d,%d: %d %d %d, want the environment at half", x, y, tu_unorm8(one->rgba[4 * i]),
                         tu_unorm8(one->rgba[4 * i + 1]), tu_unorm8(one->rgba[4 * i + 2]));
                continue;
            }
            n = refl_v3(p[0] - 1.2f, p[1], p[2]);
            TU_CHECK(&chk, fabsf(refl_v3_length(n) - 1.0f) < 0.01f, "pixel %d,%d: %g %g %g is not on the other ball",
                     x, y, p[0], p[1], p[2]);
            ++ball_in_ball;
            refl_shade_diffuse(s, &s->materials[s->objects[half].material], refl_v3(p[0], p[1], p[2]), n, NULL, rgb);
            for (c = 0; c < 3; ++c) {
                int want = (int)(0.5f * 0.5f * fminf(rgb[c], 1.0f) * 255.0f + 0.5f);
                TU_CHECK(&chk, abs((int)tu_unorm8(one->rgba[4 * i + (size_t)c]) - want) <= 1,
                         "pixel %d,%d channel %d: one bounce shows %d, the diffuse share is %d", x, y, c,
                         tu_unorm8(one->rgba[4 * i + (size_t)c]), want);
                TU_CHECK(&chk, tu_unorm8(two->rgba[4 * i + (size_t)c]) >= tu_unorm8(one->rgba[4 * i + (size_t)c]),
                         "pixel %d,%d: a second bounce took light away", x, y);
            }
            brighter += tu_unorm8(two->rgba[4 * i + 2]) > tu_unorm8(one->rgba[4 * i + 2]);
        }
    cr_assert(ball_in_ball > 50 && sky > 1000 && brighter > ball_in_ball / 2, "%d %d %d", ball_in_ball, sky,
              brighter);
    TU_CHECK_DONE(&chk);
    refl_frame_destroy(one);
    refl_frame_destroy(two);
    refl_scene_destroy(s);
}

static void expect_same_frames(const refl_frame *a, const refl_frame *b, const char *what) {
    size_t n = (size_t)a->width * (size_t)a->height;
    cr_assert_eq(tu_first_diff(a->rgba, b->rgba, (4 * n) * sizeof(float)), -1, "%s: colour differs", what);
    cr_assert_eq(tu_first_diff(a->depth, b->depth, sizeof(float) * n), -1, "%s: depth differs", what);
    cr_assert_eq(tu_first_diff(a->stencil, b->stencil, n), -1, "%s: stencil differs", what);
    cr_assert_eq(tu_first_diff(a->points, b->points, 3 * sizeof(float) * n), -1, "%s: points differ", what);
}

Test(refl_raytrace, same_bytes_for_every_thread_count) {
    const char *names[] = {"default", "glass", "mirror-room"};
    int k, t, threads[] = {2, 3, 8};
    for (k = 0; k < 3; ++k) {
        refl_scene *s;
        refl_view v;
        refl_frame *one;
        size_t i, n;
        cr_assert_eq(refl_scene_builtin(names[k], NULL, &s), REFL_OK);
        v = s->camera;
        v.width = 97; v.height = 61; /* tiles cut at odd places */
        one = render_rt(s, &v, 0, 1, 1);
        n = (size_t)v.width * (size_t)v.height;
        for (i = 0; i < 4 * n; ++i) cr_assert(tu_unorm8(one->rgba[i]) <= 255);
        for (i = 0; i < n; ++i) cr_assert(one->depth[i] >= 0.0f && one->depth[i] <= 1.0f, "%s", names[k]);
        cr_assert(one->stats.triangle_tests > 0, "%s: triangle tests counted", names[k]);
        for (t = 0; t < 3; ++t) {
            refl_frame *other = render_rt(s, &v, 0, 1, threads[t]);
            char what[64];
            snprintf(what, sizeof what, "%s, %d threads", names[k], threads[t]);
            expect_same_frames(one, other, what);
            cr_assert_eq(other->stats.triangle_tests, one->stats.triangle_tests, "%s: triangle tests", what);
            refl_frame_destroy(other);
        }
        refl_frame_destroy(one);
        refl_scene_destroy(s);
    }
}

/* The pruned tree stops a branch under 1/1024 of its pixel's weight, which
   cannot move an 8-bit pixel: every branch kept (raytrace.unpruned, as
   paper 001 counts its full tree) casts more rays, and the frame moves by at
   most one level anywhere. */
Test(refl_raytrace, pruned_branches_move_no_pixel_by_more_than_one_level) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("glass", &v, 64, 48);
    refl_render_desc d;
    refl_frame *pruned, *all;
    size_t i, n = (size_t)v.width * (size_t)v.height;
    int moved = 0;
    memset(&d, 0, sizeof d);
    d.method = REFL_RAYTRACE;
    d.depth = 10;
    pruned = tu_refl_render(s, &v, &d);
    d.raytrace.unpruned = 1;
    all = tu_refl_render(s, &v, &d);
    cr_assert_gt(all->stats.rays, pruned->stats.rays + pruned->stats.rays / 2, "%lld against %lld rays",
                 all->stats.rays, pruned->stats.rays);
    for (i = 0; i < 4 * n; ++i) {
        int a = tu_unorm8(pruned->rgba[i]), b = tu_unorm8(all->rgba[i]);
        cr_assert_leq(abs(a - b), 1, "channel %zu: %d against %d", i, a, b);
        moved += a != b;
    }
    cr_log_info("unpruned: %lld rays against %lld, %d channels moved by one level", all->stats.rays,
                pruned->stats.rays, moved);
    refl_frame_destroy(pruned);
    refl_frame_destroy(all);
    refl_scene_destroy(s);
}

/* A caller's ray caster (here the BVH again, behind the interface) gives
   the same bytes; one without an occlusion query still casts shadows. */
static int cast_intersect(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax, refl_hit *hit) {
    return refl_bvh_intersect((const refl_bvh *)user, o, d, tmin, tmax, hit);
}
static int cast_occluded(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    return refl_bvh_occluded((const refl_bvh *)user, o, d, tmin, tmax);
}

Test(refl_raytrace, a_callers_ray_caster_gives_the_same_frame) {
    refl_scene *s;
    refl_bvh *bvh;
    refl_view v;
    refl_frame *own, *theirs;
    refl_render_desc d;
    int pass;
    cr_assert_eq(refl_scene_builtin("glass", NULL, &s), REFL_OK);
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    v = s->camera;
    v.width = 120; v.height = 90;
    own = render_rt(s, &v, 0, 1, 2);
    for (pass = 0; pass < 2; ++pass) {
        memset(&d, 0, sizeof d);
        d.method = REFL_RAYTRACE;
        d.lighting.shadows = 1;
        d.raytrace.caster.intersect = cast_intersect;
        d.raytrace.caster.occluded = pass == 0 ? cast_occluded : NULL;
        d.raytrace.caster.user = bvh;
        cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &theirs), REFL_OK);
        cr_assert_eq(refl_render(s, &v, &d, theirs), REFL_OK);
        expect_same_frames(own, theirs, pass == 0 ? "caster" : "caster without occluded");
        refl_frame_destroy(theirs);
    }
    refl_frame_destroy(own);
    refl_bvh_destroy(bvh);
    refl_scene_destroy(s);
}

Test(refl_raytrace, bad_arguments_are_errors) {
    refl_scene *s;
    refl_view v;
    refl_frame *f;
    refl_render_desc d;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 8; v.height = 8;
    cr_assert_eq(refl_frame_create(8, 8, NULL, &f), REFL_OK);
    memset(&d, 0, sizeof d);
    d.method = REFL_RAYTRACE;
    d.depth = -1;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.depth = 0;
    v.eye.x = NAN;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    v = s->camera;
    v.width = 8; v.height = 9;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_SIZE);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* Every allocation RAYTRACE makes (the BVH, its tables, the workers) can
   fail: an error comes back and nothing leaks. */
Test(refl_raytrace, allocation_failure_at_every_allocation_leaks_nothing) {
    tu_alloc_counter c;
    refl_builtin_desc bd;
    refl_scene *s;
    refl_view v;
    refl_frame *f;
    refl_render_desc d = tu_refl_desc(REFL_RAYTRACE, 2);
    long needed;
    memset(&c, 0, sizeof c);
    memset(&bd, 0, sizeof bd);
    bd.allocator = tu_refl_counting(&c);
    bd.teapot_tess = 4;
    cr_assert_eq(refl_scene_builtin("glass", &bd, &s), REFL_OK);
    v = s->camera;
    v.width = 24; v.height = 16;
    cr_assert_eq(refl_frame_create(24, 16, NULL, &f), REFL_OK);
    needed = tu_refl_fail_each_render_allocation(s, &v, &d, f, &c);
    cr_assert(needed >= 3, "%ld allocations", needed);
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_OK);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    cr_assert_eq(c.allocs, c.frees);
}
