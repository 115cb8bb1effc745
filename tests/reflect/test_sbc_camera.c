/* The sample-based camera (paper 003, section IV): ray maps built
   analytically from a desired view and a reflector (planar mirror, convex
   sphere, concave spherical cap, almost planar sphere), the tree checked
   against the truth: points on the map's own rays and on rays traced at
   sub-pixel ray-map positions must project, and the first reflector point
   they give must land within error_px desired-view pixels of the true one
   (pinhole leaves, the paper's guarantee; VII-A) or within the ray map's
   spacing (ray-list leaves). Also: one pinhole leaf for a planar mirror,
   exactly the mirror point; exact ray lists for parallel rays (no pinhole
   fits them); max_depth; more leaves for a tighter error; consistent
   stats; determinism; points outside every frustum; bad input; allocation
   failure at every allocation. */
#include <criterion/criterion.h>

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

/* ---- analytic scenes ------------------------------------------------------ */

enum { SC_PLANE, SC_CONVEX, SC_CONCAVE };

typedef struct scene_t {
    int kind;
    double c[3], r;          /* spheres */
    double cap_y;            /* concave: the cap is the sphere below y = cap_y */
    double half;             /* plane y = 0: |x|, |z| <= half */
    double lo[3], hi[3];     /* the scene box: heads lie on it */
    double eye[3], fwd[3], right[3], up[3]; /* right, up scaled by tan(fov / 2) */
    int vw, vh;              /* desired view */
    int mw, mh;              /* ray map: vw / ds x vh / ds */
    double ds;               /* down-sampling factor */
    refl_mat4 vp;
} scene_t;

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void cross3(const double *a, const double *b, double *o) {
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}
static void norm3(double *a) {
    double l = sqrt(dot3(a, a));
    a[0] /= l; a[1] /= l; a[2] /= l;
}
static refl_vec3 fv(const double *a) { return refl_v3((float)a[0], (float)a[1], (float)a[2]); }
static void dv(refl_vec3 v, double *o) { o[0] = v.x; o[1] = v.y; o[2] = v.z; }

static void set_view(scene_t *s, double ex, double ey, double ez, double tx, double ty, double tz, double fovy_deg,
                     int vw, int vh, int ds) {
    double up[3] = {0, 1, 0}, t = tan(0.5 * fovy_deg * 3.14159265358979323846 / 180.0), aspect = (double)vw / vh;
    int k;
    refl_mat4 view, proj;
    s->eye[0] = ex; s->eye[1] = ey; s->eye[2] = ez;
    s->fwd[0] = tx - ex; s->fwd[1] = ty - ey; s->fwd[2] = tz - ez;
    norm3(s->fwd);
    cross3(s->fwd, up, s->right);
    norm3(s->right);
    cross3(s->right, s->fwd, s->up);
    for (k = 0; k < 3; ++k) { s->right[k] *= t * aspect; s->up[k] *= t; }
    s->vw = vw; s->vh = vh; s->ds = ds;
    s->mw = vw / ds; s->mh = vh / ds;
    view = refl_mat4_look_at(refl_v3((float)ex, (float)ey, (float)ez), refl_v3((float)tx, (float)ty, (float)tz),
                             refl_v3(0, 1, 0));
    proj = refl_mat4_perspective((float)(fovy_deg * 3.14159265358979323846 / 180.0), (float)aspect, 0.05f, 100.0f);
    s->vp = refl_mat4_mul(proj, view);
}

static void set_box(scene_t *s, double x0, double y0, double z0, double x1, double y1, double z1) {
    s->lo[0] = x0; s->lo[1] = y0; s->lo[2] = z0;
    s->hi[0] = x1; s->hi[1] = y1; s->hi[2] = z1;
}

/* The view ray through window point (wx, wy), reflected: tail (= first
   point) and head on the box; 0 when it misses the reflector. */
static int trace(const scene_t *s, double wx, double wy, double *tail, double *head) {
    double nx = 2 * wx / s->vw - 1, ny = 1 - 2 * wy / s->vh, d[3], n[3], t = -1, tf = DBL_MAX, dn;
    int k;
    for (k = 0; k < 3; ++k) d[k] = s->fwd[k] + nx * s->right[k] + ny * s->up[k];
    norm3(d);
    if (s->kind == SC_PLANE) {
        if (!(d[1] < 0)) return 0;
        t = -s->eye[1] / d[1];
        for (k = 0; k < 3; ++k) tail[k] = s->eye[k] + t * d[k];
        if (fabs(tail[0]) > s->half || fabs(tail[2]) > s->half) return 0;
        n[0] = 0; n[1] = 1; n[2] = 0;
    } else {
        double oc[3], b, c, disc, q;
        for (k = 0; k < 3; ++k) oc[k] = s->eye[k] - s->c[k];
        b = dot3(oc, d);
        c = dot3(oc, oc) - s->r * s->r;
        disc = b * b - c;
        if (disc < 0) return 0;
        q = sqrt(disc);
        t = s->kind == SC_CONVEX ? -b - q : -b + q; /* outside: near root; inside: far root */
        if (!(t > 0)) return 0;
        for (k = 0; k < 3; ++k) tail[k] = s->eye[k] + t * d[k];
        for (k = 0; k < 3; ++k) n[k] = (tail[k] - s->c[k]) / s->r;
        if (s->kind == SC_CONCAVE) {
            if (tail[1] > s->cap_y) return 0;
            for (k = 0; k < 3; ++k) n[k] = -n[k];
        }
    }
    dn = dot3(d, n);
    for (k = 0; k < 3; ++k) d[k] -= 2 * dn * n[k];
    for (k = 0; k < 3; ++k) {
        if (tail[k] < s->lo[k] || tail[k] > s->hi[k]) return 0;
        if (d[k] > 1e-12) tf = fmin(tf, (s->hi[k] - tail[k]) / d[k]);
        else if (d[k] < -1e-12) tf = fmin(tf, (s->lo[k] - tail[k]) / d[k]);
    }
    if (!(tf > 1e-6)) return 0;
    for (k = 0; k < 3; ++k) head[k] = tail[k] + tf * d[k];
    return 1;
}

/* The ray map: entry (i, j) traced through window point ((i + .5) ds, (j + .5) ds). */
static void make_map(const scene_t *s, refl_sbc_ray *rays, uint8_t *valid) {
    int i, j;
    for (j = 0; j < s->mh; ++j)
        for (i = 0; i < s->mw; ++i) {
            double tl[3], hd[3];
            int k = j * s->mw + i;
            memset(&rays[k], 0, sizeof rays[k]);
            valid[k] = (uint8_t)trace(s, (i + 0.5) * s->ds, (j + 0.5) * s->ds, tl, hd);
            if (!valid[k]) {
                rays[k].tail = rays[k].head = rays[k].first = refl_v3(NAN, NAN, NAN); /* never read */
                continue;
            }
            rays[k].tail = rays[k].first = fv(tl);
            rays[k].head = fv(hd);
        }
}

/* Desired-view window position of a world point (the contract's formula). */
static void to_pixel(const scene_t *s, refl_vec3 p, double *x, double *y) {
    const float *m = s->vp.m;
    double cx = m[0] * (double)p.x + m[4] * (double)p.y + m[8] * (double)p.z + m[12];
    double cy = m[1] * (double)p.x + m[5] * (double)p.y + m[9] * (double)p.z + m[13];
    double cw = m[3] * (double)p.x + m[7] * (double)p.y + m[11] * (double)p.z + m[15];
    *x = (cx / cw + 1) * 0.5 * s->vw;
    *y = (1 - cy / cw) * 0.5 * s->vh;
}
static double px_dist(const scene_t *s, refl_vec3 a, refl_vec3 b) {
    double ax, ay, bx, by;
    to_pixel(s, a, &ax, &ay);
    to_pixel(s, b, &bx, &by);
    return hypot(ax - bx, ay - by);
}

typedef struct built_t {
    scene_t s;
    refl_sbc_ray *rays;
    uint8_t *valid;
    refl_sbc *sbc;
    refl_sbc_stats st;
} built_t;

static refl_sbc_desc make_desc(const scene_t *s, float error_px) {
    refl_sbc_desc d;
    memset(&d, 0, sizeof d);
    d.error_px = error_px;
    d.view_proj = s->vp;
    d.width = s->vw;
    d.height = s->vh;
    return d;
}

static void build(built_t *b, const scene_t *s, float error_px, int max_depth) {
    refl_sbc_desc d = make_desc(s, error_px);
    refl_result r;
    size_t n = (size_t)s->mw * s->mh;
    b->s = *s;
    b->rays = (refl_sbc_ray *)malloc(n * sizeof(refl_sbc_ray));
    b->valid = (uint8_t *)malloc(n);
    cr_assert(b->rays && b->valid);
    make_map(s, b->rays, b->valid);
    d.max_depth = max_depth;
    b->sbc = NULL;
    r = refl_sbc_build(b->rays, b->valid, s->mw, s->mh, &d, &b->sbc);
    cr_assert_eq(r, REFL_OK, "refl_sbc_build: %s", refl_result_string(r));
    refl_sbc_get_stats(b->sbc, &b->st);
}

static void unbuild(built_t *b) {
    refl_sbc_destroy(b->sbc);
    free(b->rays);
    free(b->valid);
}

static void check_stats(const built_t *b) {
    const refl_sbc_stats *st = &b->st;
    long long nv = 0;
    int k;
    for (k = 0; k < b->s.mw * b->s.mh; ++k) nv += b->valid[k] != 0;
    cr_assert_eq(st->rays, nv);
    cr_assert(st->pinhole_leaves >= 0 && st->ray_leaves >= 0);
    cr_assert_eq(st->nodes, 2 * (st->pinhole_leaves + st->ray_leaves) - 1, "nodes %d, leaves %d + %d", st->nodes,
                 st->pinhole_leaves, st->ray_leaves);
    cr_assert(st->depth >= 0 && st->depth <= 40);
    cr_assert(st->depth > 0 || st->nodes == 1);
    cr_assert(st->bytes > 0);
}

/* A random ray-map position whose 4 x 4 neighbourhood of rays is valid
   (map coordinates: entry i's centre at i + 0.5); 0 after many misses. */
static int interior_position(const built_t *b, tu_rng *rng, int on_sample, double *x, double *y) {
    int tries;
    for (tries = 0; tries < 1000; ++tries) {
        double fx = tu_rng_range(rng, 1.5, b->s.mw - 1.5), fy = tu_rng_range(rng, 1.5, b->s.mh - 1.5);
        int i0, j0, i, j, ok = 1;
        if (on_sample) { fx = floor(fx) + 0.5; fy = floor(fy) + 0.5; }
        i0 = (int)floor(fx - 0.5);
        j0 = (int)floor(fy - 0.5);
        for (j = j0 - 1; j <= j0 + 2 && ok; ++j)
            for (i = i0 - 1; i <= i0 + 2 && ok; ++i)
                ok = i >= 0 && j >= 0 && i < b->s.mw && j < b->s.mh && b->valid[j * b->s.mw + i];
        if (ok) { *x = fx; *y = fy; return 1; }
    }
    return 0;
}

typedef struct acc_t {
    int tested, missed;
    double max_err, sum_err;
    int over;                /* errors above error_px + 1e-3 */
} acc_t;

/* n points on true reflected rays (half on the map's own rays, half traced
   at sub-pixel positions), at random distances along them: each must
   project; the error in desired-view pixels of what it gives. */
static void accuracy(const built_t *b, int n, uint64_t seed, double error_px, acc_t *a) {
    tu_rng rng = tu_rng_make(seed);
    int i;
    memset(a, 0, sizeof *a);
    for (i = 0; i < n; ++i) {
        double x, y, tl[3], hd[3], f, p[3];
        refl_vec3 truth, got, pf;
        float z = -1;
        int k, on = i & 1;
        cr_assert(interior_position(b, &rng, on, &x, &y), "no interior ray-map position");
        if (on) {
            const refl_sbc_ray *r = &b->rays[(int)y * b->s.mw + (int)x];
            dv(r->tail, tl);
            dv(r->head, hd);
            truth = r->first;
        } else {
            cr_assert(trace(&b->s, x * b->s.ds, y * b->s.ds, tl, hd));
            truth = fv(tl);
        }
        f = tu_rng_range(&rng, 0.01, 0.99);
        for (k = 0; k < 3; ++k) p[k] = tl[k] + f * (hd[k] - tl[k]);
        pf = fv(p);
        a->tested++;
        if (!refl_sbc_project(b->sbc, pf, &got, &z)) {
            a->missed++;
            continue;
        }
        cr_assert(z >= 0 && isfinite(z));
        {
            double e = px_dist(&b->s, got, truth);
            a->max_err = fmax(a->max_err, e);
            a->sum_err += e;
            if (e > error_px + 1e-3) a->over++;
        }
    }
}

/* ---- scenes ---------------------------------------------------------------- */

/* 320 x 240 desired views, 80 x 60 ray maps: a down-sampling factor of 4 */
#define DS 4

/* a square mirror in y = 0, seen obliquely */
static scene_t plane_scene(void) {
    scene_t s;
    memset(&s, 0, sizeof s);
    s.kind = SC_PLANE;
    s.half = 3;
    set_box(&s, -5, -1, -5, 5, 5, 5);
    set_view(&s, 0.3, 2.5, 4.5, 0, 0, 0, 50, 320, 240, DS);
    return s;
}

/* a unit sphere, whole in view: its silhouette included */
static scene_t sphere_full_scene(void) {
    scene_t s;
    memset(&s, 0, sizeof s);
    s.kind = SC_CONVEX;
    s.r = 1;
    set_box(&s, -6, -6, -6, 6, 6, 6);
    set_view(&s, 0.4, 0.8, 4, 0, 0, 0, 40, 320, 240, DS);
    return s;
}

/* a radius-4 sphere filling the view: every ray on the sphere */
static scene_t sphere_close_scene(void) {
    scene_t s = sphere_full_scene();
    s.r = 4;
    s.c[2] = -3;
    set_view(&s, 0.4, 0.8, 4, 0, 0, 0, 14, 320, 240, DS);
    return s;
}

/* a concave cap: the bowl of a radius-6 sphere below y = 2.5, seen from
   above; its rays converge towards the image of the eye, beyond the box's
   top */
static scene_t concave_scene(void) {
    scene_t s;
    memset(&s, 0, sizeof s);
    s.kind = SC_CONCAVE;
    s.c[1] = 6;
    s.r = 6;
    s.cap_y = 2.5;
    set_box(&s, -6, -0.5, -6, 6, 3.5, 6);
    set_view(&s, 0.3, 7, 1, 0, 0, 0, 50, 320, 240, DS);
    return s;
}

/* a radius-1000 sphere whose top is the mirror's centre: almost planar */
static scene_t flat_sphere_scene(void) {
    scene_t s = plane_scene();
    s.kind = SC_CONVEX;
    s.r = 1000;
    s.c[1] = -1000;
    return s;
}

/* the error a ray-list leaf may have: one ray-map spacing in view pixels */
static const double ray_list_bound = DS;

/* ---- tests ---------------------------------------------------------------------- */

Test(refl_sbc_camera, planar_mirror_is_one_exact_camera) {
    built_t b;
    scene_t s = plane_scene();
    tu_rng rng = tu_rng_make(11);
    double mirror_eye[3];
    int i, k;
    acc_t a;
    build(&b, &s, 1.0f, 0);
    check_stats(&b);
    cr_assert_eq(b.st.nodes, 1);
    cr_assert_eq(b.st.pinhole_leaves, 1);
    cr_assert_eq(b.st.ray_leaves, 0);
    cr_assert_eq(b.st.depth, 0);
    mirror_eye[0] = s.eye[0]; mirror_eye[1] = -s.eye[1]; mirror_eye[2] = s.eye[2];
    /* a point in front of the mirror, where the view sees the mirror past
       it: exactly where its line to the mirrored eye crosses the mirror */
    for (i = 0; i < 2000; ++i) {
        double x, y, tl[3], hd[3], p[3], q[3], want[3], s0, w;
        refl_vec3 got, pf;
        float z;
        cr_assert(interior_position(&b, &rng, 0, &x, &y));
        cr_assert(trace(&s, x * s.ds, y * s.ds, tl, hd));
        w = tu_rng_range(&rng, 0.001, 1.0);
        for (k = 0; k < 3; ++k) p[k] = tl[k] + w * (hd[k] - tl[k]);
        pf = fv(p);
        dv(pf, q);
        s0 = mirror_eye[1] / (mirror_eye[1] - q[1]);
        for (k = 0; k < 3; ++k) want[k] = mirror_eye[k] + s0 * (q[k] - mirror_eye[k]);
        cr_assert(refl_sbc_project(b.sbc, pf, &got, &z), "point %d (%g %g %g) did not project", i, pf.x, pf.y, pf.z);
        cr_assert(fabs(got.x - want[0]) <= 1e-3 && fabs(got.y) <= 1e-3 && fabs(got.z - want[2]) <= 1e-3,
                  "got (%g %g %g), want (%g %g %g)", got.x, got.y, got.z, want[0], want[1], want[2]);
        cr_assert(fabs(z - q[1]) <= 1e-3, "z %g, height %g", z, q[1]);
    }
    accuracy(&b, 2000, 12, 1.0, &a);
    cr_assert_eq(a.missed, 0);
    cr_assert(a.max_err < 0.01, "planar error %g px", a.max_err);
    /* behind the mirror, and where no reflected ray goes: nothing */
    for (i = 0; i < 1000; ++i) {
        refl_vec3 p = refl_v3((float)tu_rng_range(&rng, -4, 4), (float)tu_rng_range(&rng, -0.9, -0.01),
                              (float)tu_rng_range(&rng, -4, 4)), got;
        float z;
        cr_assert_not(refl_sbc_project(b.sbc, p, &got, &z), "behind the mirror: (%g %g %g)", p.x, p.y, p.z);
    }
    {
        refl_vec3 got;
        float z;
        cr_assert_not(refl_sbc_project(b.sbc, refl_v3(0, 0.5f, -40), &got, &z));
        cr_assert_not(refl_sbc_project(b.sbc, refl_v3(30, 1, 0), &got, &z));
        cr_assert_not(refl_sbc_project(b.sbc, refl_v3(0, 1, 30), &got, &z));
        cr_assert_not(refl_sbc_project(b.sbc, refl_v3(0, -30, 0), &got, &z));
        cr_assert_not(refl_sbc_project(b.sbc, refl_v3(NAN, 1, 0), &got, &z));
    }
    unbuild(&b);
}

/* Section VII-A: where every leaf is a pinhole camera, every point on a
   true reflected ray projects within error_px of the truth. */
static void pinhole_guarantee(const scene_t *s, float error_px, int min_leaves, uint64_t seed) {
    built_t b;
    acc_t a;
    build(&b, s, error_px, 0);
    check_stats(&b);
    cr_assert_eq(b.st.ray_leaves, 0, "%d ray-list leaves", b.st.ray_leaves);
    cr_assert(b.st.pinhole_leaves >= min_leaves, "%d pinhole leaves", b.st.pinhole_leaves);
    accuracy(&b, 4000, seed, error_px, &a);
    cr_assert_eq(a.missed, 0, "%d of %d points did not project", a.missed, a.tested);
    cr_assert_eq(a.over, 0, "%d points over %g px; largest %g px", a.over, error_px, a.max_err);
    unbuild(&b);
}

/* At least two leaves: one camera cannot fit the close sphere. (The
   leaf camera's map has a term linear in the projective depth, which
   absorbs the rays' astigmatism: 4 leaves fit this sphere at 1 px where
   the paper's quadratic alone needed more than 8.) */
Test(refl_sbc_camera, convex_sphere_within_error_px) {
    scene_t s = sphere_close_scene();
    pinhole_guarantee(&s, 1.0f, 2, 21);
    pinhole_guarantee(&s, 4.0f, 2, 22);
}

Test(refl_sbc_camera, concave_cap_converging_within_error_px) {
    scene_t s = concave_scene();
    refl_sbc_ray *rays = (refl_sbc_ray *)malloc(sizeof(refl_sbc_ray) * (size_t)(s.mw * s.mh));
    uint8_t *valid = (uint8_t *)malloc((size_t)(s.mw * s.mh));
    int i = s.mh / 2 * s.mw + s.mw / 2, k, conv = 0, n = 0;
    /* the map's rays converge: neighbours' heads closer than their tails */
    make_map(&s, rays, valid);
    for (k = i - 10; k < i + 10; ++k) {
        double t0[3], t1[3], h0[3], h1[3], dt, dh;
        int j;
        if (!valid[k] || !valid[k + 1]) continue;
        dv(rays[k].tail, t0); dv(rays[k + 1].tail, t1); dv(rays[k].head, h0); dv(rays[k + 1].head, h1);
        for (j = 0; j < 3; ++j) { t0[j] -= t1[j]; h0[j] -= h1[j]; }
        dt = sqrt(dot3(t0, t0));
        dh = sqrt(dot3(h0, h0));
        conv += dh < 0.8 * dt;
        ++n;
    }
    free(rays);
    free(valid);
    cr_assert(n >= 15 && conv == n, "%d of %d neighbour pairs converge", conv, n);
    pinhole_guarantee(&s, 1.0f, 8, 31);
}

Test(refl_sbc_camera, nearly_planar_within_error_px) {
    scene_t s = flat_sphere_scene();
    built_t b;
    pinhole_guarantee(&s, 1.0f, 1, 41);
    build(&b, &s, 1.0f, 0);
    cr_assert(b.st.pinhole_leaves <= 8, "%d leaves for an almost planar mirror", b.st.pinhole_leaves);
    unbuild(&b);
}

/* The silhouette: ray-list leaves where no camera fits; every point still
   projects, within the ray map's spacing. */
Test(refl_sbc_camera, sphere_silhouette_ray_lists) {
    scene_t s = sphere_full_scene();
    built_t b;
    acc_t a;
    build(&b, &s, 1.0f, 0);
    check_stats(&b);
    cr_assert(b.st.pinhole_leaves > 0 && b.st.ray_leaves > 0, "leaves %d + %d", b.st.pinhole_leaves,
              b.st.ray_leaves);
    accuracy(&b, 4000, 51, 1.0, &a);
    cr_assert_eq(a.missed, 0, "%d of %d points did not project", a.missed, a.tested);
    cr_assert(a.max_err <= ray_list_bound, "largest error %g px", a.max_err);
    cr_assert(a.sum_err / a.tested < 0.5, "mean error %g px", a.sum_err / a.tested);
    unbuild(&b);
}

/* max_depth 1: the root's two halves are ray lists (section VII-A's "one
   ray map pixel or better"), max_depth 3 bounds the tree. */
Test(refl_sbc_camera, ray_lists_only_and_max_depth) {
    scene_t s = sphere_full_scene();
    built_t b;
    acc_t a;
    build(&b, &s, 1.0f, 1);
    check_stats(&b);
    cr_assert_eq(b.st.depth, 1);
    cr_assert_eq(b.st.pinhole_leaves, 0);
    cr_assert_eq(b.st.ray_leaves, 2);
    accuracy(&b, 4000, 61, 1.0, &a);
    cr_assert_eq(a.missed, 0, "%d of %d points did not project", a.missed, a.tested);
    cr_assert(a.max_err <= ray_list_bound, "largest error %g px", a.max_err);
    unbuild(&b);
    build(&b, &s, 1.0f, 3);
    check_stats(&b);
    cr_assert(b.st.depth <= 3);
    accuracy(&b, 2000, 62, 1.0, &a);
    cr_assert_eq(a.missed, 0);
    cr_assert(a.max_err <= ray_list_bound, "largest error %g px", a.max_err);
    unbuild(&b);
}

Test(refl_sbc_camera, tighter_error_more_leaves) {
    scene_t scenes[2];
    int k;
    scenes[0] = sphere_full_scene();
    scenes[1] = sphere_close_scene();
    for (k = 0; k < 2; ++k) {
        built_t fine, mid, coarse;
        build(&fine, &scenes[k], 0.25f, 0);
        build(&mid, &scenes[k], 1.0f, 0);
        build(&coarse, &scenes[k], 4.0f, 0);
        check_stats(&fine);
        check_stats(&coarse);
        cr_assert(fine.st.nodes > mid.st.nodes && mid.st.nodes > coarse.st.nodes, "scene %d: nodes %d, %d, %d", k,
                  fine.st.nodes, mid.st.nodes, coarse.st.nodes);
        unbuild(&fine);
        unbuild(&mid);
        unbuild(&coarse);
    }
}

/* Same input, same tree: every answer identical to the bit, also through
   another allocator; valid = NULL is the all-ones mask. */
Test(refl_sbc_camera, deterministic) {
    scene_t s = sphere_full_scene();
    built_t b;
    refl_sbc *other = NULL, *nomask = NULL, *mask = NULL;
    refl_sbc_desc d = make_desc(&s, 1.0f);
    refl_sbc_stats st;
    tu_alloc_counter cnt;
    tu_rng rng = tu_rng_make(71);
    int i, hits = 0;
    build(&b, &s, 1.0f, 0);
    memset(&cnt, 0, sizeof cnt);
    d.allocator = tu_refl_counting(&cnt);
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &d, &other), REFL_OK);
    refl_sbc_get_stats(other, &st);
    cr_assert(memcmp(&st, &b.st, sizeof st) == 0);
    for (i = 0; i < 20000; ++i) {
        refl_vec3 p = refl_v3((float)tu_rng_range(&rng, -3, 3), (float)tu_rng_range(&rng, -3, 3),
                              (float)tu_rng_range(&rng, -3, 5)), f1, f2;
        float z1 = 0, z2 = 0;
        int r1 = refl_sbc_project(b.sbc, p, &f1, &z1), r2 = refl_sbc_project(other, p, &f2, &z2);
        cr_assert_eq(r1, r2);
        if (r1) {
            ++hits;
            cr_assert(memcmp(&f1, &f2, sizeof f1) == 0 && memcmp(&z1, &z2, sizeof z1) == 0);
        }
    }
    cr_assert(hits > 1000, "%d hits", hits);
    refl_sbc_destroy(other);
    cr_assert_eq(cnt.allocs, cnt.frees);
    unbuild(&b);

    s = sphere_close_scene();
    build(&b, &s, 1.0f, 0);
    for (i = 0; i < s.mw * s.mh; ++i) cr_assert(b.valid[i], "ray %d missed the sphere", i);
    d = make_desc(&s, 1.0f);
    cr_assert_eq(refl_sbc_build(b.rays, NULL, s.mw, s.mh, &d, &nomask), REFL_OK);
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &d, &mask), REFL_OK);
    for (i = 0; i < 5000; ++i) {
        refl_vec3 p = refl_v3((float)tu_rng_range(&rng, -2, 2), (float)tu_rng_range(&rng, -2, 2),
                              (float)tu_rng_range(&rng, 1, 5)), f1, f2;
        float z1 = 0, z2 = 0;
        int r1 = refl_sbc_project(nomask, p, &f1, &z1), r2 = refl_sbc_project(mask, p, &f2, &z2);
        cr_assert_eq(r1, r2);
        if (r1) cr_assert(memcmp(&f1, &f2, sizeof f1) == 0 && memcmp(&z1, &z2, sizeof z1) == 0);
    }
    refl_sbc_destroy(nomask);
    refl_sbc_destroy(mask);
    unbuild(&b);
}

/* Parallel rays (an orthographic view of a planar mirror): no centre of
   projection exists, so no pinhole camera fits and the tree ends in ray
   lists, whose bilinear interpolation is exact on a regular grid. */
Test(refl_sbc_camera, parallel_rays_exact_ray_lists) {
    enum { N = 24 };
    refl_sbc_ray rays[N * N];
    refl_sbc_desc d;
    refl_sbc *sbc = NULL;
    refl_sbc_stats st;
    double dir[3] = {0.3, 1, 0.2};
    tu_rng rng = tu_rng_make(91);
    int i, j, k;
    norm3(dir);
    for (j = 0; j < N; ++j)
        for (i = 0; i < N; ++i) {
            double t[3] = {i * 0.125 - 1.5, 0, j * 0.125 - 1.5}, h[3];
            for (k = 0; k < 3; ++k) h[k] = t[k] + 4 * dir[k];
            rays[j * N + i].tail = rays[j * N + i].first = fv(t);
            rays[j * N + i].head = fv(h);
        }
    memset(&d, 0, sizeof d);
    d.view_proj = refl_mat4_mul(refl_mat4_perspective(1.0f, 1.0f, 0.1f, 100.0f),
                                refl_mat4_look_at(refl_v3(0, 5, 1), refl_v3(0, 0, 0), refl_v3(0, 1, 0)));
    d.width = d.height = 256;
    cr_assert_eq(refl_sbc_build(rays, NULL, N, N, &d, &sbc), REFL_OK);
    refl_sbc_get_stats(sbc, &st);
    cr_assert_eq(st.pinhole_leaves, 0);
    cr_assert(st.ray_leaves > 1);
    for (k = 0; k < 2000; ++k) {
        double x = tu_rng_range(&rng, 0, N - 1), y = tu_rng_range(&rng, 0, N - 1), w = tu_rng_range(&rng, 0, 4);
        double t[3] = {x * 0.125 - 1.5, 0, y * 0.125 - 1.5}, p[3];
        refl_vec3 got;
        float z;
        for (i = 0; i < 3; ++i) p[i] = t[i] + w * dir[i];
        cr_assert(refl_sbc_project(sbc, fv(p), &got, &z), "(%g %g) at %g did not project", x, y, w);
        cr_assert(fabs(got.x - t[0]) < 1e-4 && fabs(got.y) < 1e-4 && fabs(got.z - t[2]) < 1e-4,
                  "got (%g %g %g), want (%g 0 %g)", got.x, got.y, got.z, t[0], t[2]);
        cr_assert(fabs(z - w) < 1e-3 * (1 + w), "z %g, want %g", z, w);
    }
    refl_sbc_destroy(sbc);
}

/* Rays that fold: tails (u, y, 0), directions (-u^2, 0, 1), so at height
   z a ray lies at x = u - z u^2, which turns back at u = 1 / (2 z): each
   ray meets the caustic x = 1 / (4 z) at z = 1 / (2 u). At z = 1 the point
   x = 0.24 lies on two rays, u = 0.4 (its fold at z = 1.25, ahead) and
   u = 0.6 (at z = 0.83, behind): one image before its ray's fold, one past
   it. refl_sbc_project keeps the nearer (the paper's one per group);
   refl_sbc_project_sheets gives both. */
Test(refl_sbc_camera, folded_rays_one_image_per_sheet) {
    enum { NU = 21, NY = 8 };
    refl_sbc_ray rays[NU * NY];
    refl_sbc_desc d;
    refl_sbc *sbc = NULL;
    refl_sbc_stats st;
    refl_vec3 got, first[REFL_SBC_SHEETS];
    float z, zs[REFL_SBC_SHEETS];
    double p[3] = {0.24, 0.125, 1.0};
    int i, j, mask;
    for (j = 0; j < NY; ++j)
        for (i = 0; i < NU; ++i) {
            double u = 0.3 + 0.025 * i, t[3] = {u, 0.05 * j, 0.0}, h[3] = {u - 2.0 * u * u, 0.05 * j, 2.0};
            rays[j * NU + i].tail = rays[j * NU + i].first = fv(t);
            rays[j * NU + i].head = fv(h);
        }
    memset(&d, 0, sizeof d);
    d.view_proj = refl_mat4_mul(refl_mat4_perspective(1.0f, 1.0f, 0.1f, 100.0f),
                                refl_mat4_look_at(refl_v3(0.5f, 0.2f, -3.0f), refl_v3(0.5f, 0.2f, 0.0f),
                                                  refl_v3(0, 1, 0)));
    d.width = d.height = 256;
    d.error_px = 0.01f; /* no pinhole fits the fold: ray lists */
    cr_assert_eq(refl_sbc_build(rays, NULL, NU, NY, &d, &sbc), REFL_OK);
    refl_sbc_get_stats(sbc, &st);
    cr_assert_eq(st.sheets, 2, "%d sheets", st.sheets);
    cr_assert_eq(refl_sbc_leaf_at(sbc, fv(p)), REFL_SBC_LEAF_RAY_LIST);
    mask = refl_sbc_project_sheets(sbc, fv(p), REFL_SBC_SHEETS, first, zs);
    cr_assert_eq(mask, 3, "mask %d", mask);
    cr_assert(fabs(first[0].x - 0.4) < 1e-3 && fabs(first[0].y - 0.125) < 1e-3 && fabs(first[0].z) < 1e-4,
              "sheet 0: (%g %g %g)", first[0].x, first[0].y, first[0].z);
    cr_assert(fabs(first[1].x - 0.6) < 1e-3 && fabs(first[1].y - 0.125) < 1e-3 && fabs(first[1].z) < 1e-4,
              "sheet 1: (%g %g %g)", first[1].x, first[1].y, first[1].z);
    /* z: the distance along the ray from its tail, sqrt(1 + u^4) */
    cr_assert(fabs(zs[0] - sqrt(1.0 + 0.0256)) < 1e-3 && fabs(zs[1] - sqrt(1.0 + 0.1296)) < 1e-3, "z %g %g", zs[0],
              zs[1]);
    cr_assert(refl_sbc_project(sbc, fv(p), &got, &z));
    cr_assert(fabs(got.x - first[0].x) < 1e-6 && fabs(z - zs[0]) < 1e-6, "one image: the nearer");
    /* past every caustic point of the map (x > 1 / (4 z)): no ray there */
    p[0] = 0.3;
    cr_assert_eq(refl_sbc_project_sheets(sbc, fv(p), REFL_SBC_SHEETS, first, zs), 0);
    /* asking for fewer sheets fills fewer; none is an error */
    p[0] = 0.24;
    cr_assert_eq(refl_sbc_project_sheets(sbc, fv(p), 1, first, zs), 1);
    cr_assert_eq(refl_sbc_project_sheets(sbc, fv(p), 0, first, zs), 0);
    cr_assert_eq(refl_sbc_project_sheets(NULL, fv(p), 2, first, zs), 0);
    refl_sbc_destroy(sbc);
}

/* refl_sbc_desc.links: no unit frustum spans a neighbour pair whose link
   is not set. The folded map above meets (0.2419, 0.125, 1) at u = 0.41
   (between columns 4 and 5, rows 2 and 3) and u = 0.59 (columns 11 and
   12): cutting columns 11 and 12 apart takes sheet 1's image away, cutting
   (4, 2) from the row below takes sheet 0's, and every link set is the
   map without links. */
Test(refl_sbc_camera, links_cut_unit_frustums) {
    enum { NU = 21, NY = 8 };
    refl_sbc_ray rays[NU * NY];
    uint8_t links[NU * NY];
    refl_sbc_desc d;
    refl_vec3 first[REFL_SBC_SHEETS], plain[REFL_SBC_SHEETS];
    float zs[REFL_SBC_SHEETS], zp[REFL_SBC_SHEETS];
    const refl_vec3 p = {0.2419f, 0.125f, 1.0f};
    int i, j, k, cut, mask[4];
    for (j = 0; j < NY; ++j)
        for (i = 0; i < NU; ++i) {
            double u = 0.3 + 0.025 * i, t[3] = {u, 0.05 * j, 0.0}, h[3] = {u - 2.0 * u * u, 0.05 * j, 2.0};
            rays[j * NU + i].tail = rays[j * NU + i].first = fv(t);
            rays[j * NU + i].head = fv(h);
        }
    memset(&d, 0, sizeof d);
    d.view_proj = refl_mat4_mul(refl_mat4_perspective(1.0f, 1.0f, 0.1f, 100.0f),
                                refl_mat4_look_at(refl_v3(0.5f, 0.2f, -3.0f), refl_v3(0.5f, 0.2f, 0.0f),
                                                  refl_v3(0, 1, 0)));
    d.width = d.height = 256;
    d.error_px = 0.01f; /* ray lists */
    for (cut = 0; cut < 4; ++cut) {
        refl_sbc *sbc = NULL;
        memset(links, 3, sizeof links);
        if (cut == 1)
            for (j = 0; j < NY; ++j) links[j * NU + 11] &= (uint8_t)~1u;
        if (cut == 2) links[2 * NU + 4] &= (uint8_t)~2u;
        d.links = cut == 3 ? NULL : links;
        cr_assert_eq(refl_sbc_build(rays, NULL, NU, NY, &d, &sbc), REFL_OK);
        mask[cut] = refl_sbc_project_sheets(sbc, p, REFL_SBC_SHEETS, cut ? first : plain, cut ? zs : zp);
        if (cut == 3)
            for (k = 0; k < REFL_SBC_SHEETS; ++k)
                if (mask[3] >> k & 1)
                    cr_assert(first[k].x == plain[k].x && zs[k] == zp[k], "sheet %d: links all set, the same image", k);
        refl_sbc_destroy(sbc);
    }
    cr_assert_eq(mask[0], 3, "every link set: %d", mask[0]);
    cr_assert(fabs(plain[0].x - 0.41) < 1e-3 && fabs(plain[1].x - 0.59) < 1e-3, "%g %g", plain[0].x, plain[1].x);
    cr_assert_eq(mask[1], 1, "columns 11 and 12 cut apart: %d", mask[1]);
    cr_assert_eq(mask[2], 2, "(4, 2) cut from the row below: %d", mask[2]);
    cr_assert_eq(mask[3], 3, "no links: %d", mask[3]);
}

/* Behind the reflector and where no reflected ray can go: nothing. */
Test(refl_sbc_camera, outside_every_frustum) {
    scene_t scenes[3];
    tu_rng rng = tu_rng_make(81);
    int k, i;
    scenes[0] = sphere_full_scene();
    scenes[1] = sphere_close_scene();
    scenes[2] = concave_scene();
    for (k = 0; k < 3; ++k) {
        const scene_t *s = &scenes[k];
        built_t b;
        refl_vec3 got;
        float z;
        build(&b, s, 1.0f, k == 0 ? 1 : 0); /* the first one: ray lists */
        for (i = 0; i < 2000; ++i) {
            double d[3], r, p[3];
            int j;
            do { d[0] = tu_rng_range(&rng, -1, 1); d[1] = tu_rng_range(&rng, -1, 1); d[2] = tu_rng_range(&rng, -1, 1);
            } while (dot3(d, d) > 1 || dot3(d, d) < 0.01);
            norm3(d);
            /* convex: inside the sphere; concave: outside it, under the bowl */
            r = s->kind == SC_CONVEX ? tu_rng_range(&rng, 0, 0.95) * s->r : s->r * tu_rng_range(&rng, 1.05, 1.5);
            for (j = 0; j < 3; ++j) p[j] = s->c[j] + r * d[j];
            if (s->kind == SC_CONCAVE && p[1] > 0) p[1] = -p[1] * 0.1 - 0.05;
            cr_assert_not(refl_sbc_project(b.sbc, fv(p), &got, &z), "scene %d: (%g %g %g) projects", k, p[0], p[1],
                          p[2]);
        }
        /* far behind the reflector, seen from the eye */
        {
            double p[3];
            int j;
            for (j = 0; j < 3; ++j) p[j] = s->c[j] + 40 * s->fwd[j];
            if (s->kind == SC_CONCAVE) p[1] = -40; /* under the bowl */
            cr_assert_not(refl_sbc_project(b.sbc, fv(p), &got, &z), "scene %d: far point projects", k);
        }
        unbuild(&b);
    }
}

Test(refl_sbc_camera, empty_group_and_bad_input) {
    scene_t s = sphere_full_scene();
    built_t b;
    refl_sbc_desc d = make_desc(&s, 1.0f), bad;
    refl_sbc *sbc = (refl_sbc *)(uintptr_t)1;
    refl_sbc_stats st;
    uint8_t *none;
    refl_vec3 got;
    float z;
    int i, first_valid = -1;
    build(&b, &s, 1.0f, 0);
    none = (uint8_t *)calloc((size_t)(s.mw * s.mh), 1);
    cr_assert_eq(refl_sbc_build(b.rays, none, s.mw, s.mh, &d, &sbc), REFL_OK);
    refl_sbc_get_stats(sbc, &st);
    cr_assert(st.rays == 0 && st.nodes == 1 && st.pinhole_leaves + st.ray_leaves == 1);
    cr_assert_not(refl_sbc_project(sbc, refl_v3(0, 0, 2), &got, &z));
    refl_sbc_destroy(sbc);
    free(none);

    sbc = (refl_sbc *)(uintptr_t)1;
    cr_assert_eq(refl_sbc_build(NULL, b.valid, s.mw, s.mh, &d, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(sbc);
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, NULL, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &d, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, 0, s.mh, &d, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, -1, &d, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    bad = d; bad.error_px = -1;
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &bad, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    bad = d; bad.error_px = NAN;
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &bad, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    bad = d; bad.width = 0;
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &bad, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    bad = d; bad.height = -3;
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &bad, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    bad = d; bad.max_depth = -1;
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &bad, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    bad = d; bad.view_proj.m[5] = INFINITY;
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &bad, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    /* non-finite data: an error in a valid entry, ignored in an invalid one
       (make_map fills those with NaN); with valid NULL every entry counts */
    cr_assert_eq(refl_sbc_build(b.rays, NULL, s.mw, s.mh, &d, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    for (i = 0; i < s.mw * s.mh && first_valid < 0; ++i)
        if (b.valid[i]) first_valid = i;
    b.rays[first_valid].head.y = INFINITY;
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &d, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    b.rays[first_valid].head.y = 0;
    b.rays[first_valid].first.x = NAN;
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &d, &sbc), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(sbc);
    /* no error bound: the view is not needed */
    bad = d; bad.error_px = INFINITY; bad.width = bad.height = 0;
    b.rays[first_valid].first = b.rays[first_valid].tail;
    cr_assert_eq(refl_sbc_build(b.rays, b.valid, s.mw, s.mh, &bad, &sbc), REFL_OK);
    refl_sbc_get_stats(sbc, &st);
    cr_assert(st.pinhole_leaves >= 1);
    refl_sbc_destroy(sbc);
    /* NULL everywhere else */
    refl_sbc_destroy(NULL);
    refl_sbc_get_stats(NULL, &st);
    cr_assert_eq(st.nodes, 0);
    refl_sbc_get_stats(b.sbc, NULL);
    cr_assert_not(refl_sbc_project(NULL, refl_v3(0, 0, 2), &got, &z));
    unbuild(&b);
}

/* Every allocation failing in turn: OUT_OF_MEMORY, nothing leaked. */
Test(refl_sbc_camera, allocation_failure) {
    scene_t s = sphere_full_scene();
    refl_sbc_ray *rays;
    uint8_t *valid;
    refl_sbc_desc d;
    refl_sbc *sbc = NULL;
    refl_sbc_stats st;
    tu_alloc_counter cnt;
    long total, k;
    set_view(&s, 0.4, 0.8, 4, 0, 0, 0, 40, 160, 120, DS);
    rays = (refl_sbc_ray *)malloc(sizeof(refl_sbc_ray) * (size_t)(s.mw * s.mh));
    valid = (uint8_t *)malloc((size_t)(s.mw * s.mh));
    make_map(&s, rays, valid);
    d = make_desc(&s, 1.0f);
    memset(&cnt, 0, sizeof cnt);
    d.allocator = tu_refl_counting(&cnt);
    cr_assert_eq(refl_sbc_build(rays, valid, s.mw, s.mh, &d, &sbc), REFL_OK);
    refl_sbc_get_stats(sbc, &st);
    cr_assert(st.pinhole_leaves > 0 && st.ray_leaves > 0, "leaves %d + %d", st.pinhole_leaves, st.ray_leaves);
    refl_sbc_destroy(sbc);
    cr_assert_eq(cnt.allocs, cnt.frees);
    total = cnt.attempts;
    cr_assert(total > 10, "%ld allocations", total);
    for (k = 1; k <= total; ++k) {
        refl_result r;
        memset(&cnt, 0, sizeof cnt);
        cnt.fail_at = k;
        sbc = (refl_sbc *)(uintptr_t)1;
        r = refl_sbc_build(rays, valid, s.mw, s.mh, &d, &sbc);
        cr_assert_eq(r, REFL_ERROR_OUT_OF_MEMORY, "allocation %ld of %ld failed: %s", k, total,
                     refl_result_string(r));
        cr_assert_null(sbc);
        cr_assert_eq(cnt.failed, 1);
        cr_assert_eq(cnt.allocs, cnt.frees, "allocation %ld: %ld allocs, %ld frees", k, cnt.allocs, cnt.frees);
    }
    free(rays);
    free(valid);
}
