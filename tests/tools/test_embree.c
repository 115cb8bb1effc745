/* refl_bvh against Embree (bench/embree_peer.h): on every built-in scene
   and every glTF asset in ../shared/assets, primary rays from the scene's
   camera and one mirror ray from each primary hit must find the same
   object, triangle and distance in both. Two watertight tests may rightly
   differ only where a ray grazes an edge, or where two triangles hold the
   same hit point (coincident surfaces: both answers are right, a tie);
   every difference is classified and counted (run with --verbose to see
   the counts), and any other kind fails the test. Random rays against
   brute force: tests/reflect/test_bvh.c. */
#define _XOPEN_SOURCE 700
#include <criterion/criterion.h>

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "../../bench/embree_peer.h"
#include "../../reflect.h"
#include "../../tools/gltf_load.h"
#include "../test_util.h"

/* Tests run from the repository root. */
#define ASSETS "../shared/assets"

/* 320 x 240: 77k primary rays per scene, and up to as many mirror rays. */
#define EMB_WIDTH 320
#define EMB_HEIGHT 240
/* Barycentric distance to an edge below which a ray grazes it. */
#define EMB_EDGE 1e-4
/* Distances agree within this, relative, or within the rounding error
   bound of the watertight test (watertight_t_error). */
#define EMB_T_REL 1e-4
/* At most one ray in 10^4 may disagree (and only at edges). */
#define EMB_MIN_AGREEMENT 0.9999

/* Under AddressSanitizer refl_bvh_build takes about 30 s for the million
   triangles of MetalRoughSpheres (2 s plain): the sanitized run leaves
   such scenes to the plain one. */
#if defined(__SANITIZE_ADDRESS__)
#define EMB_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define EMB_SANITIZED 1
#endif
#endif
#ifdef EMB_SANITIZED
#define EMB_MAX_TRIANGLES 500000
#else
#define EMB_MAX_TRIANGLES LLONG_MAX
#endif

typedef struct emb_tally {
    long long rays, primary, mirror;
    /* Different answers, both right: each hit point lies on the other's
       triangle at the same distance (coincident surfaces, which some
       assets have: TransmissionTest, or a shared edge or vertex). */
    long long ties;
    /* Same triangle, t apart by more than EMB_T_REL but within refl_bvh's
       rounding bound (watertight_t_error): slivers near the origin. */
    long long t_rounding;
    /* Disagreements: */
    long long at_edge;        /* a hit within EMB_EDGE of its triangle's edge */
    long long elsewhere;      /* anything else: a bug in one of them */
    char first[512];          /* the first disagreement not at an edge */
} emb_tally;

static void world_triangle(const refl_scene *s, int object, int triangle, double v[3][3]) {
    const refl_object *o = &s->objects[object];
    const refl_mesh *m = s->meshes[o->mesh];
    int j;
    for (j = 0; j < 3; ++j) {
        const float *p = m->positions + 3 * (size_t)m->indices[3 * (size_t)triangle + j];
        refl_vec3 w = refl_mat4_point(o->transform, refl_v3(p[0], p[1], p[2]));
        v[j][0] = w.x;
        v[j][1] = w.y;
        v[j][2] = w.z;
    }
}

static double edge_margin(const refl_hit *h) { return fmin(fmin(h->u, h->v), 1.0 - h->u - h->v); }

/* Whether point p lies on triangle (object, triangle): its projection onto
   the plane inside within EMB_EDGE (barycentric) and its distance to the
   plane under `tolerance`. */
static int point_on_triangle(const refl_scene *s, int object, int triangle, const double p[3], double tolerance) {
    double v[3][3], e1[3], e2[3], w[3], n[3], nn, dist, d11, d12, d22, dw1, dw2, det, b1, b2;
    int k;
    world_triangle(s, object, triangle, v);
    for (k = 0; k < 3; ++k) {
        e1[k] = v[1][k] - v[0][k];
        e2[k] = v[2][k] - v[0][k];
        w[k] = p[k] - v[0][k];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (nn == 0) return 0;
    dist = fabs(w[0] * n[0] + w[1] * n[1] + w[2] * n[2]) / nn;
    d11 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
    d12 = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
    d22 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
    dw1 = w[0] * e1[0] + w[1] * e1[1] + w[2] * e1[2];
    dw2 = w[0] * e2[0] + w[1] * e2[1] + w[2] * e2[2];
    det = d11 * d22 - d12 * d12;
    if (det == 0) return 0;
    b1 = (dw1 * d22 - dw2 * d12) / det;
    b2 = (dw2 * d11 - dw1 * d12) / det;
    return dist <= tolerance && b1 >= -EMB_EDGE && b2 >= -EMB_EDGE && 1 - b1 - b2 >= -EMB_EDGE;
}

static void hit_point(refl_vec3 o, refl_vec3 d, float t, double p[3]) {
    p[0] = o.x + (double)t * d.x;
    p[1] = o.y + (double)t * d.y;
    p[2] = o.z + (double)t * d.z;
}

/* The bound on the rounding error of t in refl_bvh's watertight test
   (Woop, Benthin and Wald 2013) in float, as derived in pbrt-v3 (section
   3.9.6): in the ray's sheared frame, errors of the edge functions e_i
   carry into t = sum(e_i z_i) / sum(e_i) as
       3 (gamma3 maxE maxZ + deltaE maxZ + deltaZ maxE) / |det|,
   which grows for slivers (small det against the coordinates: a mirror
   ray that re-hits a long thin triangle near its origin can be off by
   1e-3 of t). Evaluated in double from the same float vertices. */
static double gamma_n(int n) {
    double u = FLT_EPSILON * 0.5;
    return n * u / (1 - n * u);
}

static double watertight_t_error(const refl_scene *s, refl_vec3 o, refl_vec3 d, const refl_hit *h) {
    double v[3][3], p[3][3], xt[3], yt[3], zt[3], e[3], dir[3] = {d.x, d.y, d.z}, org[3] = {o.x, o.y, o.z};
    double sx, sy, sz, max_x = 0, max_y = 0, max_z = 0, max_e = 0, dx, dy, dz, de, det;
    int kz, kx, ky, i, k;
    world_triangle(s, h->object, h->triangle, v);
    kz = fabs(dir[0]) >= fabs(dir[1]) ? (fabs(dir[0]) >= fabs(dir[2]) ? 0 : 2)
                                      : (fabs(dir[1]) >= fabs(dir[2]) ? 1 : 2);
    kx = (kz + 1) % 3;
    ky = (kx + 1) % 3;
    sx = -dir[kx] / dir[kz];
    sy = -dir[ky] / dir[kz];
    sz = 1 / dir[kz];
    for (i = 0; i < 3; ++i) {
        for (k = 0; k < 3; ++k) p[i][k] = v[i][k] - org[k];
        xt[i] = p[i][kx] + sx * p[i][kz];
        yt[i] = p[i][ky] + sy * p[i][kz];
        zt[i] = sz * p[i][kz];
        max_x = fmax(max_x, fabs(xt[i]));
        max_y = fmax(max_y, fabs(yt[i]));
        max_z = fmax(max_z, fabs(zt[i]));
    }
    e[0] = xt[1] * yt[2] - yt[1] * xt[2];
    e[1] = xt[2] * yt[0] - yt[2] * xt[0];
    e[2] = xt[0] * yt[1] - yt[0] * xt[1];
    for (i = 0; i < 3; ++i) max_e = fmax(max_e, fabs(e[i]));
    det = fabs(e[0] + e[1] + e[2]);
    if (det == 0) return INFINITY;
    dz = gamma_n(3) * max_z;
    dx = gamma_n(5) * (max_x + max_z);
    dy = gamma_n(5) * (max_y + max_z);
    de = 2 * (gamma_n(2) * max_x * max_y + dy * max_x + dx * max_y);
    return 3 * (gamma_n(3) * max_e * max_z + de * max_z + dz * max_e) / det;
}

/* How far apart (in t) two correct hits on h's triangle may be (Embree's
   own error is far smaller: it intersects the plane). */
static double t_tolerance(const refl_scene *s, refl_vec3 o, refl_vec3 d, const refl_hit *h) {
    return fmax(EMB_T_REL * fabs((double)h->t), watertight_t_error(s, o, d, h));
}

/* Compares one ray's results; 1 when they agree (or tie). */
static int compare(const refl_scene *s, emb_tally *tally, const char *what, refl_vec3 o, refl_vec3 d, int ha,
                   const refl_hit *a, int hb, const refl_hit *b) {
    int same_triangle = ha && hb && a->object == b->object && a->triangle == b->triangle;
    double dt = ha && hb ? fabs((double)a->t - b->t) : 0, pa[3], pb[3], tol;
    ++tally->rays;
    if (!ha && !hb) return 1;
    if (same_triangle) {
        if (dt <= EMB_T_REL * fabs((double)b->t)) return 1;
        if (dt <= t_tolerance(s, o, d, a)) {
            ++tally->t_rounding;
            return 1;
        }
    } else if ((ha && edge_margin(a) < EMB_EDGE) || (hb && edge_margin(b) < EMB_EDGE)) {
        ++tally->at_edge;
        return 0;
    } else if (ha && hb) {
        hit_point(o, d, a->t, pa);
        hit_point(o, d, b->t, pb);
        tol = fmax(t_tolerance(s, o, d, a), t_tolerance(s, o, d, b));
        if (dt <= tol && point_on_triangle(s, b->object, b->triangle, pa, tol * refl_v3_length(d)) &&
            point_on_triangle(s, a->object, a->triangle, pb, tol * refl_v3_length(d))) {
            ++tally->ties;
            return 1;
        }
    }
    if (tally->elsewhere++ == 0)
        snprintf(tally->first, sizeof tally->first,
                 "%s ray o=(%.9g %.9g %.9g) d=(%.9g %.9g %.9g): refl_bvh %d (object %d triangle %d t %.9g u %g v %g)"
                 ", embree %d (object %d triangle %d t %.9g u %g v %g)",
                 what, o.x, o.y, o.z, d.x, d.y, d.z, ha, ha ? a->object : -1, ha ? a->triangle : -1, ha ? a->t : 0,
                 ha ? a->u : 0, ha ? a->v : 0, hb, hb ? b->object : -1, hb ? b->triangle : -1, hb ? b->t : 0,
                 hb ? b->u : 0, hb ? b->v : 0);
    return 0;
}

/* The mirror ray at a hit: about the interpolated normal turned towards
   the viewer, starting just off the surface on the viewer's side. 0 when
   the normal is unusable. */
static int mirror_ray(const refl_scene *s, refl_vec3 o, refl_vec3 d, const refl_hit *h, float offset,
                      refl_vec3 *ro, refl_vec3 *rd) {
    const refl_object *obj = &s->objects[h->object];
    const refl_mesh *m = s->meshes[obj->mesh];
    const uint32_t *tri = m->indices + 3 * (size_t)h->triangle;
    double v[3][3];
    refl_vec3 ng, n, p, unit_d;
    refl_mat4 inverse;
    float w0 = 1 - h->u - h->v;
    int k;
    world_triangle(s, h->object, h->triangle, v);
    ng = refl_v3_normalize(refl_v3_cross(
        refl_v3((float)(v[1][0] - v[0][0]), (float)(v[1][1] - v[0][1]), (float)(v[1][2] - v[0][2])),
        refl_v3((float)(v[2][0] - v[0][0]), (float)(v[2][1] - v[0][1]), (float)(v[2][2] - v[0][2]))));
    n = refl_v3(0, 0, 0);
    for (k = 0; k < 3; ++k) {
        const float *nk = m->normals + 3 * (size_t)tri[k];
        float wk = k == 0 ? w0 : k == 1 ? h->u : h->v;
        n = refl_v3_add(n, refl_v3_scale(refl_v3(nk[0], nk[1], nk[2]), wk));
    }
    if (!refl_mat4_invert(obj->transform, &inverse)) return 0;
    n = refl_v3_normalize(refl_mat4_dir(refl_mat4_transpose(inverse), n));
    if (refl_v3_length(n) == 0 || refl_v3_length(ng) == 0) return 0;
    unit_d = refl_v3_normalize(d);
    if (refl_v3_dot(n, unit_d) > 0) n = refl_v3_scale(n, -1);
    if (refl_v3_dot(ng, unit_d) > 0) ng = refl_v3_scale(ng, -1);
    p = refl_v3_add(o, refl_v3_scale(d, h->t));
    *ro = refl_v3_add(p, refl_v3_scale(ng, offset));
    *rd = refl_v3_reflect(unit_d, n);
    return refl_v3_length(*rd) > 0;
}

/* A view for scenes without a camera, framing the bounds (as the `reflect`
   command does). */
static refl_view scene_view(const refl_scene *s) {
    refl_view v = s->camera;
    if (!s->has_camera) {
        refl_vec3 lo, hi, c;
        float diag;
        refl_scene_bounds(s, &lo, &hi);
        c = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
        diag = refl_v3_length(refl_v3_sub(hi, lo));
        memset(&v, 0, sizeof v);
        v.eye = refl_v3_add(c, refl_v3(0.35f * diag, 0.45f * diag, 1.1f * diag));
        v.target = c;
        v.up = refl_v3(0, 1, 0);
        v.fovy_degrees = 45.0f;
    }
    if (refl_v3_length(v.up) == 0) v.up = refl_v3(0, 1, 0);
    v.width = EMB_WIDTH;
    v.height = EMB_HEIGHT;
    return v;
}

/* Traces the scene with both and checks the tallies. */
static void check_scene(const char *name, const refl_scene *s) {
    refl_bvh *bvh = NULL;
    refl_embree *emb;
    refl_view view = scene_view(s);
    refl_mat4 view_m, proj_m;
    refl_vec3 right, up, forward, lo, hi;
    emb_tally tally;
    char err[256];
    float offset;
    long long disagree;
    int x, y;

    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK, "%s: refl_bvh_build", name);
    emb = refl_embree_create(s, 0, err, sizeof err);
    cr_assert(emb, "%s: %s", name, err);
    memset(&tally, 0, sizeof tally);

    /* Rays through pixel centres of the same frustum the rasteriser uses. */
    refl_view_matrices(&view, s, &view_m, &proj_m);
    right = refl_v3(view_m.m[0], view_m.m[4], view_m.m[8]);
    up = refl_v3(view_m.m[1], view_m.m[5], view_m.m[9]);
    forward = refl_v3(-view_m.m[2], -view_m.m[6], -view_m.m[10]);
    refl_scene_bounds(s, &lo, &hi);
    offset = 1e-5f * refl_v3_length(refl_v3_sub(hi, lo));

    for (y = 0; y < view.height; ++y)
        for (x = 0; x < view.width; ++x) {
            float ndc_x = 2.0f * (x + 0.5f) / view.width - 1, ndc_y = 1 - 2.0f * (y + 0.5f) / view.height;
            refl_vec3 d = refl_v3_add(forward, refl_v3_add(refl_v3_scale(right, ndc_x / proj_m.m[0]),
                                                           refl_v3_scale(up, ndc_y / proj_m.m[5])));
            refl_vec3 ro, rd;
            refl_hit a, b;
            int ha, hb;
            memset(&a, 0, sizeof a);
            memset(&b, 0, sizeof b);
            ha = refl_bvh_intersect(bvh, view.eye, d, 0, INFINITY, &a);
            hb = refl_embree_intersect(emb, view.eye, d, 0, INFINITY, &b);
            ++tally.primary;
            /* Mirror rays only where the two agree on where they start. */
            if (!compare(s, &tally, "primary", view.eye, d, ha, &a, hb, &b) || !ha) continue;
            if (!mirror_ray(s, view.eye, d, &a, offset, &ro, &rd)) continue;
            ha = refl_bvh_intersect(bvh, ro, rd, 0, INFINITY, &a);
            hb = refl_embree_intersect(emb, ro, rd, 0, INFINITY, &b);
            ++tally.mirror;
            compare(s, &tally, "mirror", ro, rd, ha, &a, hb, &b);
        }

    disagree = tally.at_edge + tally.elsewhere;
    cr_log_info("embree vs refl_bvh, %s: %lld rays (%lld primary, %lld mirror): %lld agree (%lld with t only "
                "within refl_bvh's rounding bound), %lld tie on coincident triangles, %lld disagree (%lld grazing "
                "an edge, %lld elsewhere)",
                name, tally.rays, tally.primary, tally.mirror, tally.rays - disagree - tally.ties, tally.t_rounding,
                tally.ties, disagree, tally.at_edge, tally.elsewhere);
    cr_expect(tally.primary == (long long)view.width * view.height);
    cr_expect_eq(tally.elsewhere, 0, "%s: %lld disagreements not at an edge; first: %s", name, tally.elsewhere,
                 tally.first);
    cr_expect((double)(tally.rays - disagree) >= EMB_MIN_AGREEMENT * (double)tally.rays,
              "%s: %lld of %lld rays disagree", name, disagree, tally.rays);
    refl_embree_destroy(emb);
    refl_bvh_destroy(bvh);
}

Test(embree, builtin_scenes) {
    const char *const *names = refl_builtin_names();
    int i;
    for (i = 0; names[i]; ++i) {
        refl_scene *s = NULL;
        cr_assert_eq(refl_scene_builtin(names[i], NULL, &s), REFL_OK, "%s", names[i]);
        check_scene(names[i], s);
        refl_scene_destroy(s);
    }
    cr_assert(i >= 4);
}

static void check_asset(const char *file) {
    struct stat st;
    char path[512], err[1024];
    refl_scene *s = NULL;
    refl_result r;
    if (stat(ASSETS, &st) != 0 || !S_ISDIR(st.st_mode))
        cr_skip_test("%s is absent: the asset tests need the shared assets next to the repository", ASSETS);
    snprintf(path, sizeof path, "%s/%s", ASSETS, file);
    /* The file's own units: scales from millimetres to hundreds. */
    r = refl_gltf_load(path, NULL, &s, err, sizeof err);
    cr_assert_eq(r, REFL_OK, "%s: %d (%s)", path, r, err);
    if (refl_scene_triangles(s) > EMB_MAX_TRIANGLES) {
        long long n = refl_scene_triangles(s);
        refl_scene_destroy(s);
        cr_skip_test("%s: %lld triangles are too slow to build under the sanitizers", file, n);
    }
    check_scene(file, s);
    refl_scene_destroy(s);
}

/* The assets of test_gltf.c, one test each so they run in parallel. */
Test(embree, teapot) { check_asset("teapot.glb"); }
Test(embree, bunny) { check_asset("bunny.glb"); }
Test(embree, bunny_10k) { check_asset("bunny_10k.glb"); }
Test(embree, xyzrgb_dragon_100k) { check_asset("xyzrgb_dragon_100k.glb"); }
Test(embree, box) { check_asset("Box.glb"); }
Test(embree, duck) { check_asset("Duck.glb"); }
Test(embree, suzanne) { check_asset("Suzanne.glb"); }
Test(embree, metal_rough_spheres) { check_asset("MetalRoughSpheresNoTextures.glb"); }
Test(embree, water_bottle) { check_asset("WaterBottle.glb"); }
Test(embree, transmission_test) { check_asset("TransmissionTest.glb"); }
Test(embree, attenuation_test) { check_asset("AttenuationTest.glb"); }
Test(embree, toy_car) { check_asset("ToyCar.glb"); }

/* The caster interface: occlusion agrees with intersection, and bad rays
   miss, as refl_bvh's contract says. */
Test(embree, caster_contract) {
    refl_scene *s = NULL;
    refl_embree *emb;
    refl_ray_caster caster;
    refl_rng rng = refl_rng_seed(3);
    refl_hit h;
    char err[256];
    int i;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    emb = refl_embree_create(s, 1, err, sizeof err);
    cr_assert(emb, "%s", err);
    caster.intersect = refl_embree_intersect;
    caster.occluded = refl_embree_occluded;
    caster.user = emb;
    for (i = 0; i < 20000; ++i) {
        refl_vec3 o = refl_v3(12 * refl_rng_float(&rng) - 6, 6 * refl_rng_float(&rng), 12 * refl_rng_float(&rng) - 6);
        refl_vec3 d =
            refl_v3(2 * refl_rng_float(&rng) - 1, 2 * refl_rng_float(&rng) - 1, 2 * refl_rng_float(&rng) - 1);
        float tmax = i % 3 == 0 ? refl_rng_float(&rng) * 4 : INFINITY;
        cr_assert_eq(caster.occluded(caster.user, o, d, 0, tmax) != 0,
                     caster.intersect(caster.user, o, d, 0, tmax, NULL) != 0, "ray %d", i);
    }
    cr_assert(caster.intersect(caster.user, refl_v3(0, 50, 0), refl_v3(0, -1, 0), 0, INFINITY, &h));
    cr_assert(h.t > 40 && h.t < 50 && h.object >= 0 && h.object < s->object_count);
    cr_assert_not(caster.intersect(caster.user, refl_v3(0, 50, 0), refl_v3(0, 0, 0), 0, INFINITY, &h));
    cr_assert_not(caster.intersect(caster.user, refl_v3(NAN, 50, 0), refl_v3(0, -1, 0), 0, INFINITY, &h));
    cr_assert_not(caster.intersect(caster.user, refl_v3(0, 50, 0), refl_v3(0, -1, 0), 5, 5, &h));
    cr_assert_not(caster.occluded(caster.user, refl_v3(0, 50, 0), refl_v3(0, -1, 0), 0, 10));
    refl_embree_destroy(emb);
    refl_scene_destroy(s);
    cr_assert_null(refl_embree_create(NULL, 0, err, sizeof err));
    cr_assert(strlen(err) > 0);
}

/* A caster that answers with Embree and checks every query against
   refl_bvh, tallying as check_scene does (one thread: the tally is
   shared). */
typedef struct emb_checked {
    const refl_scene *scene;
    refl_bvh *bvh;
    refl_embree *embree;
    emb_tally tally;          /* closest-hit queries */
    emb_tally shadow;         /* occlusion queries where the two differ, as closest hits */
    long long occluded;
} emb_checked;

static int checked_intersect(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax, refl_hit *hit) {
    emb_checked *c = (emb_checked *)user;
    refl_hit a, b;
    int ha, hb;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    ha = refl_bvh_intersect(c->bvh, o, d, tmin, tmax, &a);
    hb = refl_embree_intersect(c->embree, o, d, tmin, tmax, &b);
    compare(c->scene, &c->tally, "RAYTRACE", o, d, ha, &a, hb, &b);
    if (hb && hit) *hit = b;
    return hb;
}

static int checked_occluded(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    emb_checked *c = (emb_checked *)user;
    int ours = refl_bvh_occluded(c->bvh, o, d, tmin, tmax);
    int theirs = refl_embree_occluded(c->embree, o, d, tmin, tmax);
    ++c->occluded;
    if (ours != theirs) { /* which hit makes the difference, and where */
        refl_hit a, b;
        int ha, hb;
        memset(&a, 0, sizeof a);
        memset(&b, 0, sizeof b);
        ha = refl_bvh_intersect(c->bvh, o, d, tmin, tmax, &a);
        hb = refl_embree_intersect(c->embree, o, d, tmin, tmax, &b);
        if (compare(c->scene, &c->shadow, "shadow", o, d, ha, &a, hb, &b)) ++c->shadow.elsewhere;
    }
    return theirs;
}

/* Embree plugged into RAYTRACE through refl_ray_caster (shadows on, so
   both functions run): every query agrees with refl_bvh as in
   check_scene. Pixels may still differ where a tie between coincident
   triangles (both right) sends a ray on different ways: the glass scene's
   slab stands on the floor, its bottom face in the floor's plane. */
Test(embree, raytrace_through_embree) {
    const char *const *names = refl_builtin_names();
    int i;
    for (i = 0; names[i]; ++i) {
        refl_scene *s = NULL;
        refl_frame *ours = NULL, *theirs = NULL;
        refl_render_desc rd;
        refl_view view;
        refl_result r;
        emb_checked checked;
        char err[256];
        long long p, differ = 0, pixels, disagree, shadow_disagree;
        cr_assert_eq(refl_scene_builtin(names[i], NULL, &s), REFL_OK);
        view = s->camera;
        view.width = 160;
        view.height = 120;
        pixels = (long long)view.width * view.height;
        cr_assert_eq(refl_frame_create(view.width, view.height, NULL, &ours), REFL_OK);
        cr_assert_eq(refl_frame_create(view.width, view.height, NULL, &theirs), REFL_OK);
        memset(&rd, 0, sizeof rd);
        rd.method = REFL_RAYTRACE;
        rd.threads = 1;
        rd.lighting.shadows = 1;
        r = refl_render(s, &view, &rd, ours);
        if (r == REFL_ERROR_UNSUPPORTED) {
            refl_frame_destroy(ours);
            refl_frame_destroy(theirs);
            refl_scene_destroy(s);
            cr_skip_test("RAYTRACE is not built yet");
        }
        cr_assert_eq(r, REFL_OK, "%s: %s", names[i], refl_result_string(r));

        memset(&checked, 0, sizeof checked);
        checked.scene = s;
        cr_assert_eq(refl_bvh_build(s, NULL, &checked.bvh), REFL_OK);
        checked.embree = refl_embree_create(s, 0, err, sizeof err);
        cr_assert(checked.embree, "%s", err);
        rd.raytrace.caster.intersect = checked_intersect;
        rd.raytrace.caster.occluded = checked_occluded;
        rd.raytrace.caster.user = &checked;
        cr_assert_eq(refl_render(s, &view, &rd, theirs), REFL_OK, "%s", names[i]);
        for (p = 0; p < pixels; ++p) {
            int c, worst = 0;
            for (c = 0; c < 4; ++c) {
                int d = abs(tu_unorm8(ours->rgba[4 * p + c]) - tu_unorm8(theirs->rgba[4 * p + c]));
                if (d > worst) worst = d;
            }
            differ += worst > 2;
        }
        disagree = checked.tally.at_edge + checked.tally.elsewhere;
        shadow_disagree = checked.shadow.at_edge + checked.shadow.elsewhere;
        cr_log_info("RAYTRACE through Embree, %s: %lld of %lld pixels differ; %lld closest-hit queries: %lld tie on "
                    "coincident triangles, %lld disagree (%lld grazing an edge, %lld elsewhere); %lld occlusion "
                    "queries: %lld disagree (%lld grazing an edge, %lld elsewhere)",
                    names[i], differ, pixels, checked.tally.rays, checked.tally.ties, disagree, checked.tally.at_edge,
                    checked.tally.elsewhere, checked.occluded, shadow_disagree, checked.shadow.at_edge,
                    checked.shadow.elsewhere);
        cr_expect(checked.tally.rays > pixels && checked.occluded > 0, "%s: the caster was not used", names[i]);
        cr_expect_eq(checked.tally.elsewhere, 0, "%s: %s", names[i], checked.tally.first);
        cr_expect_eq(checked.shadow.elsewhere, 0, "%s: occlusion differs: %s", names[i], checked.shadow.first);
        cr_expect((double)disagree <= (1 - EMB_MIN_AGREEMENT) * (double)checked.tally.rays,
                  "%s: %lld of %lld queries disagree", names[i], disagree, checked.tally.rays);
        cr_expect((double)shadow_disagree <= (1 - EMB_MIN_AGREEMENT) * (double)checked.occluded,
                  "%s: %lld of %lld occlusion queries disagree", names[i], shadow_disagree, checked.occluded);
        /* Only ties and grazing rays may change a pixel. */
        cr_expect(differ <= checked.tally.ties + disagree + shadow_disagree, "%s: %lld pixels differ", names[i],
                  differ);
        refl_embree_destroy(checked.embree);
        refl_bvh_destroy(checked.bvh);
        refl_frame_destroy(ours);
        refl_frame_destroy(theirs);
        refl_scene_destroy(s);
    }
}

/* Degenerate and non-finite triangles are left out, as refl_bvh leaves
   them, and the rest keep their mesh indices; broken meshes are refused
   with a message. */
Test(embree, skipped_triangles_and_bad_meshes) {
    /* triangle 0: a point, 1: NaN, 2: a line, 3: the one that counts */
    static const float positions[] = {0, 0, 0, 0, 0, 0, 0, 0, 0,   0, 0, 0, 1, 0, 0, 0, 1, 0,
                                      0, 0, 0, 1, 1, 0, 2, 2, 0,   -1, -1, 0, 1, -1, 0, 0, 1, 0};
    float pos[36];
    refl_scene *s = NULL;
    refl_mesh *m = NULL;
    refl_mesh_desc md;
    refl_material mat;
    refl_object o;
    refl_embree *emb;
    refl_hit h;
    char err[256];
    memcpy(pos, positions, sizeof pos);
    memset(&md, 0, sizeof md);
    md.positions = pos;
    md.vertex_count = 12;
    cr_assert_eq(refl_mesh_create(&md, &m), REFL_OK);
    m->positions[3 * 3] = NAN; /* after creation: refl_mesh_create refuses NaN */
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    memset(&mat, 0, sizeof mat);
    memset(&o, 0, sizeof o);
    o.mesh = refl_scene_add_mesh(s, m);
    o.material = refl_scene_add_material(s, &mat);
    o.transform = refl_mat4_translate(refl_v3(0, 0, -5));
    cr_assert(o.mesh >= 0 && o.material >= 0);
    cr_assert(refl_scene_add_object(s, &o) >= 0);
    cr_assert(refl_scene_add_object(s, &o) >= 0); /* geomID 1: the same, further on */
    s->objects[1].transform = refl_mat4_translate(refl_v3(0, 0, -7));

    emb = refl_embree_create(s, 1, err, sizeof err);
    cr_assert(emb, "%s", err);
    cr_assert(refl_embree_intersect(emb, refl_v3(0.1f, -0.2f, 0), refl_v3(0, 0, -1), 0, INFINITY, &h));
    cr_assert_eq(h.object, 0);
    cr_assert_eq(h.triangle, 3);
    cr_assert_float_eq(h.t, 5.0f, 1e-5f);
    /* the barycentrics refl_bvh gives */
    {
        refl_bvh *bvh = NULL;
        refl_hit b;
        cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
        cr_assert(refl_bvh_intersect(bvh, refl_v3(0.1f, -0.2f, 0), refl_v3(0, 0, -1), 0, INFINITY, &b));
        cr_assert(fabsf(h.u - b.u) < 1e-6f && fabsf(h.v - b.v) < 1e-6f, "u %g %g v %g %g", h.u, b.u, h.v, b.v);
        refl_bvh_destroy(bvh);
    }
    /* past the first copy, the second */
    cr_assert(refl_embree_intersect(emb, refl_v3(0.1f, -0.2f, 0), refl_v3(0, 0, -1), 5.5f, INFINITY, &h));
    cr_assert_eq(h.object, 1);
    cr_assert_eq(h.triangle, 3);
    /* Open interval: a hit at exactly tmin or tmax does not count (RAYTRACE
       skips the triangle a ray leaves by casting again from its t). */
    {
        refl_vec3 o = refl_v3(0.1f, -0.2f, 0), d = refl_v3(0, 0, -1);
        float t0;
        cr_assert(refl_embree_intersect(emb, o, d, 0, INFINITY, &h));
        t0 = h.t;
        cr_assert(refl_embree_intersect(emb, o, d, t0, INFINITY, &h));
        cr_assert_eq(h.object, 1);
        cr_assert_not(refl_embree_intersect(emb, o, d, 0, t0, &h));
        cr_assert_not(refl_embree_occluded(emb, o, d, 0, t0));
        cr_assert(refl_embree_occluded(emb, o, d, 0, nextafterf(t0, INFINITY)));
    }
    refl_embree_destroy(emb);

    m->indices[4] = 99; /* out of range */
    cr_assert_null(refl_embree_create(s, 1, err, sizeof err));
    cr_assert(strstr(err, "indexes past"), "%s", err);
    m->indices[4] = 4;
    s->objects[1].mesh = 7;
    cr_assert_null(refl_embree_create(s, 1, err, sizeof err));
    cr_assert(strstr(err, "missing mesh"), "%s", err);
    s->objects[1].mesh = 0;
    refl_scene_destroy(s);
}
