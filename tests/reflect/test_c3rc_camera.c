/* The continuous 3-ray camera (paper 000, section 5): projection against
   points built from known (a, b, c, t) on many random cameras (divergent,
   convergent, almost parallel rays, almost planar sweeps, tiny and large
   triangles), against the closed-form cubic, a camera with known double
   projections, points known to lie outside, continuity across a shared
   edge, the section 5.1 intervals (every multiple projection lies inside
   them) and the conservative box test against brute force. All geometry
   here is recomputed in double from the camera's stored floats. */
#include <criterion/criterion.h>

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

/* ---- helpers -------------------------------------------------------------- */

/* Test-local generator (splitmix64). */
static uint64_t sm_state;
static uint64_t sm_next(void) {
    uint64_t z = (sm_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static double U(double lo, double hi) { return lo + (hi - lo) * ((double)(sm_next() >> 11) * 0x1.0p-53); }

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void cross3(const double *a, const double *b, double *o) {
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}
static double len3(const double *a) { return sqrt(dot3(a, a)); }
static double det3(const double *a, const double *b, const double *c) {
    double x[3];
    cross3(a, b, x);
    return dot3(x, c);
}
static void norm3(double *a) {
    double l = len3(a);
    a[0] /= l; a[1] /= l; a[2] /= l;
}
static void rnd_unit(double *o) {
    do { o[0] = U(-1, 1); o[1] = U(-1, 1); o[2] = U(-1, 1); } while (dot3(o, o) > 1 || dot3(o, o) < 0.01);
    norm3(o);
}
static refl_vec3 fvec(const double *a) { return refl_v3((float)a[0], (float)a[1], (float)a[2]); }
static void dvec(refl_vec3 v, double *o) { o[0] = v.x; o[1] = v.y; o[2] = v.z; }

/* A camera and its stored floats, in double. */
typedef struct cam3 {
    refl_c3rc cam;
    double v[3][3], d[3][3];
    double size;               /* longest base edge */
} cam3;

static void cam_make(cam3 *c, const double v[3][3], const double d[3][3]) {
    refl_vec3 fv[3], fd[3];
    int i, k;
    for (i = 0; i < 3; ++i) { fv[i] = fvec(v[i]); fd[i] = fvec(d[i]); }
    cr_assert_eq(refl_c3rc_init(&c->cam, fv, fd), REFL_OK);
    c->size = 0;
    for (i = 0; i < 3; ++i) {
        dvec(c->cam.v[i], c->v[i]);
        dvec(c->cam.d[i], c->d[i]);
        cr_assert(fabs(len3(c->d[i]) - 1) < 1e-6, "direction %d not unit: %g", i, len3(c->d[i]));
    }
    for (i = 0; i < 3; ++i) {
        double e[3];
        for (k = 0; k < 3; ++k) e[k] = c->v[(i + 1) % 3][k] - c->v[i][k];
        if (len3(e) > c->size) c->size = len3(e);
    }
}

/* vertex i of the sweeping triangle T(t) */
static void sweep_vertex(const cam3 *c, int i, double t, double *o) {
    int k;
    for (k = 0; k < 3; ++k) o[k] = c->v[i][k] + t * c->d[i][k];
}
static void sweep_point(const cam3 *c, const double *abc, double t, double *o) {
    double V[3];
    int i, k;
    o[0] = o[1] = o[2] = 0;
    for (i = 0; i < 3; ++i) {
        sweep_vertex(c, i, t, V);
        for (k = 0; k < 3; ++k) o[k] += abc[i] * V[k];
    }
}
/* E1(t), E2(t) */
static void sweep_edges(const cam3 *c, double t, double *E1, double *E2) {
    double V0[3], V1[3], V2[3];
    int k;
    sweep_vertex(c, 0, t, V0);
    sweep_vertex(c, 1, t, V1);
    sweep_vertex(c, 2, t, V2);
    for (k = 0; k < 3; ++k) { E1[k] = V1[k] - V0[k]; E2[k] = V2[k] - V0[k]; }
}
/* the side of T(t)'s plane ray j crosses towards: dj . (E1 x E2) */
static double side(const cam3 *c, int j, double t) {
    double E1[3], E2[3], n[3];
    sweep_edges(c, t, E1, E2);
    cross3(E1, E2, n);
    return dot3(c->d[j], n) / (len3(n) + 1e-300);
}
/* 1 when all three rays cross T(t)'s plane the same way, by a margin */
static int sides_agree(const cam3 *c, double t, double margin) {
    double s0 = side(c, 0, t), s1 = side(c, 1, t), s2 = side(c, 2, t);
    return (s0 > margin && s1 > margin && s2 > margin) || (s0 < -margin && s1 < -margin && s2 < -margin);
}

/* |a(V1 - P) + b(V2 - P) + c(V3 - P)| at t: how well a projection
   reconstructs P */
static double residual(const cam3 *c, const refl_c3rc_projection *pr, const double *P) {
    double abc[3] = {pr->a, pr->b, pr->c}, V[3], r[3] = {0, 0, 0}, s = abc[0] + abc[1] + abc[2];
    int i, k;
    for (i = 0; i < 3; ++i) {
        sweep_vertex(c, i, pr->t, V);
        for (k = 0; k < 3; ++k) r[k] += abc[i] / s * (V[k] - P[k]);
    }
    return len3(r);
}

/* Checks every output of a projection: count, order, ranges. */
static void check_outputs(const refl_c3rc_projection *pr, int n) {
    int i;
    cr_assert(n >= 0 && n <= 3, "count %d", n);
    for (i = 0; i < n; ++i) {
        cr_assert(pr[i].a >= 0 && pr[i].b >= 0 && pr[i].c >= 0 && pr[i].a <= 1 && pr[i].b <= 1 && pr[i].c <= 1,
                  "barycentrics %g %g %g", pr[i].a, pr[i].b, pr[i].c);
        cr_assert(fabs(pr[i].a + pr[i].b + pr[i].c - 1) < 1e-6, "sum %g", pr[i].a + pr[i].b + pr[i].c);
        cr_assert(pr[i].t >= 0 && pr[i].t <= FLT_MAX, "t %g", pr[i].t);
        if (i > 0) cr_assert(pr[i].t >= pr[i - 1].t, "not ascending: %g then %g", pr[i - 1].t, pr[i].t);
    }
}

enum { FAM_DIVERGENT, FAM_CONVERGENT, FAM_PARALLEL, FAM_PLANAR, FAM_SMALL, FAM_LARGE, FAM_WIDE, FAM_COUNT };
static const char *const fam_name[FAM_COUNT] = {"divergent", "convergent", "parallel", "planar",
                                                "small",     "large",      "wide"};

/* A random camera of a family; *reach: how far along the rays to build
   points. */
static void random_camera(cam3 *c, int fam, double *reach) {
    double n[3], t1[3], t2[3], ctr[3], V[3][3], D[3][3], e1[3], e2[3], x[3], size, k, noise;
    int i, j;
    rnd_unit(n);
    rnd_unit(t1);
    cross3(n, t1, t2);
    norm3(t2);
    cross3(t2, n, t1);
    size = fam == FAM_SMALL ? 1e-3 * U(0.5, 2) : fam == FAM_LARGE ? 100 * U(0.5, 2) : U(0.3, 3);
    for (j = 0; j < 3; ++j)
        ctr[j] = fam == FAM_SMALL ? U(-1, 1) * size : fam == FAM_LARGE ? U(-300, 300) : U(-3, 3);
    for (;;) {
        double sliver = fam == FAM_PLANAR && (sm_next() & 1) ? 0.02 : 1.0;
        for (i = 0; i < 3; ++i) {
            double a = U(-1, 1), b = U(-1, 1) * sliver;
            for (j = 0; j < 3; ++j) V[i][j] = ctr[j] + size * (a * t1[j] + b * t2[j]);
        }
        for (j = 0; j < 3; ++j) { e1[j] = V[1][j] - V[0][j]; e2[j] = V[2][j] - V[0][j]; }
        cross3(e1, e2, x);
        if (len3(x) > 0.01 * sliver * size * size) break;
    }
    *reach = 3 * size;
    for (i = 0; i < 3; ++i) {
        switch (fam) {
        case FAM_PARALLEL: /* rays about 1e-4 rad apart */
            rnd_unit(x);
            for (j = 0; j < 3; ++j) D[i][j] = n[j] + 1e-4 * x[j];
            *reach = 10 * size;
            break;
        case FAM_PLANAR: { /* rays 1e-3..1e-2 rad off the base plane: a thin wedge */
            double th = pow(10.0, U(-3, -2));
            for (j = 0; j < 3; ++j) D[i][j] = t1[j] + 0.1 * U(-1, 1) * t2[j] + th * n[j];
            break;
        }
        case FAM_WIDE:
            rnd_unit(x);
            for (j = 0; j < 3; ++j) D[i][j] = n[j] + 1.5 * U(0, 1) * x[j];
            break;
        default:
            k = fam == FAM_CONVERGENT || ((fam == FAM_SMALL || fam == FAM_LARGE) && (sm_next() & 1))
                    ? U(-3, -0.3)
                    : U(0.2, 1.5);
            noise = fam == FAM_CONVERGENT ? U(0, 1) : 0.2;
            rnd_unit(x);
            for (j = 0; j < 3; ++j) D[i][j] = n[j] + k * (V[i][j] - ctr[j]) / size + noise * U(0, 1) * x[j];
        }
        norm3(D[i]);
    }
    cam_make(c, (const double(*)[3])V, (const double(*)[3])D);
}

/* Random barycentrics, now and then on an edge or at a vertex. */
static void random_abc(double *abc) {
    double a = U(0, 1), b = U(0, 1);
    uint64_t r = sm_next() % 20;
    if (a + b > 1) { a = 1 - a; b = 1 - b; }
    abc[0] = a; abc[1] = b; abc[2] = 1 - a - b;
    if (r == 0) abc[sm_next() % 3] = 0;
    if (r == 1) { abc[0] = abc[1] = abc[2] = 0; abc[sm_next() % 3] = 1; }
    if (r <= 1) {
        double s = abc[0] + abc[1] + abc[2];
        abc[0] /= s; abc[1] /= s; abc[2] /= s;
    }
}

/* The projection (a, b, c, t) of Pf next to the construction (abc, t):
   Newton on P(b, c, t) = Pf, J = [E1 E2 D]. 0 where that is ill-posed:
   J nearly singular (a fold of the volume, or a very thin camera), no
   convergence (the rounding took the point off the volume at a fold) or
   the answer far from the start (rounding effects above 1e-3). */
static int follow_rounding(const cam3 *c, const double *abc, double t, const double *Pf, double *ex) {
    double x[3] = {abc[1], abc[2], t}, scale = c->size + fabs(t);
    int it, k, converged = 0;
    for (it = 0; it < 12 && !converged; ++it) {
        double w[3] = {1 - x[0] - x[1], x[0], x[1]}, Q[3], r[3], E1[3], E2[3], D[3], J, d0, d1, d2;
        sweep_point(c, w, x[2], Q);
        sweep_edges(c, x[2], E1, E2);
        for (k = 0; k < 3; ++k) {
            r[k] = Pf[k] - Q[k];
            D[k] = w[0] * c->d[0][k] + w[1] * c->d[1][k] + w[2] * c->d[2][k];
        }
        J = det3(E1, E2, D);
        if (!(fabs(J) > 1e-6 * len3(E1) * len3(E2) * len3(D))) return 0;
        d0 = det3(r, E2, D) / J;
        d1 = det3(E1, r, D) / J;
        d2 = det3(E1, E2, r) / J;
        x[0] += d0; x[1] += d1; x[2] += d2;
        converged = fabs(d0) + fabs(d1) + fabs(d2) / scale < 1e-12;
    }
    if (!converged || !(fabs(x[0] - abc[1]) < 1e-3 && fabs(x[1] - abc[2]) < 1e-3 && fabs(x[2] - t) < 1e-3 * scale)) return 0;
    ex[0] = 1 - x[0] - x[1];
    ex[1] = x[0];
    ex[2] = x[1];
    ex[3] = x[2];
    return 1;
}

/* ---- bad input -------------------------------------------------------------- */

Test(refl_c3rc_camera, init_rejects_bad_input) {
    refl_c3rc cam;
    refl_vec3 v[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    refl_vec3 d[3] = {{0, 0, 1}, {0, 0, 2}, {0.1f, 0, 1}};
    refl_vec3 bad[3];
    refl_c3rc_projection pr[3];
    float iv[4][2];
    int i, k;
    cr_assert_eq(refl_c3rc_init(NULL, v, d), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_c3rc_init(&cam, NULL, d), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_c3rc_init(&cam, v, NULL), REFL_ERROR_INVALID_ARGUMENT);
    for (i = 0; i < 3; ++i)
        for (k = 0; k < 3; ++k) {
            float vals[3] = {NAN, INFINITY, -INFINITY};
            int w;
            for (w = 0; w < 3; ++w) {
                memcpy(bad, v, sizeof bad);
                (&bad[i].x)[k] = vals[w];
                cr_assert_eq(refl_c3rc_init(&cam, bad, d), REFL_ERROR_INVALID_ARGUMENT);
                memcpy(bad, d, sizeof bad);
                (&bad[i].x)[k] = vals[w];
                cr_assert_eq(refl_c3rc_init(&cam, v, bad), REFL_ERROR_INVALID_ARGUMENT);
            }
        }
    for (i = 0; i < 3; ++i) {
        memcpy(bad, d, sizeof bad);
        bad[i] = refl_v3(0, 0, 0);
        cr_assert_eq(refl_c3rc_init(&cam, v, bad), REFL_ERROR_INVALID_ARGUMENT);
    }
    /* directions of any length are normalised, tiny and huge included */
    memcpy(bad, d, sizeof bad);
    bad[0] = refl_v3(0, 0, 1e-40f);
    bad[1] = refl_v3(0, 3e38f, 3e38f);
    cr_assert_eq(refl_c3rc_init(&cam, v, bad), REFL_OK);
    for (i = 0; i < 3; ++i) cr_assert(fabsf(refl_v3_length(cam.d[i]) - 1) < 1e-6f);
    cr_assert(cam.d[0].z == 1.0f);
    /* NULL everywhere else: nothing, no crash */
    cr_assert_eq(refl_c3rc_init(&cam, v, d), REFL_OK);
    cr_assert_eq(refl_c3rc_project(NULL, refl_v3(0.2f, 0.2f, 1), pr), 0);
    cr_assert_eq(refl_c3rc_project(&cam, refl_v3(0.2f, 0.2f, 1), NULL), 0);
    cr_assert_eq(refl_c3rc_multiple_intervals(NULL, INFINITY, iv), 0);
    cr_assert_eq(refl_c3rc_multiple_intervals(&cam, INFINITY, NULL), 0);
    cr_assert_eq(refl_c3rc_box_visible(NULL, refl_v3(-1, -1, -1), refl_v3(1, 1, 1), INFINITY), 0);
    /* and the good camera works */
    cr_assert_eq(refl_c3rc_project(&cam, refl_v3(0.2f, 0.2f, 1), pr), 1);
    cr_assert(fabsf(pr[0].t - 1) < 0.1f);
}

/* A collinear base is allowed; it projects nothing at t = 0, but its
   sweeping triangles open up in front of it. */
Test(refl_c3rc_camera, degenerate_base) {
    cam3 c;
    double v[3][3] = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, d[3][3] = {{-0.3, -0.3, 1}, {0, 0.3, 1}, {0.3, -0.3, 1}};
    double abc[3] = {0.2, 0.5, 0.3}, P[3];
    refl_c3rc_projection pr[3];
    int i, n;
    for (i = 0; i < 3; ++i) norm3(d[i]);
    cam_make(&c, v, d);
    for (i = 0; i <= 10; ++i) {
        n = refl_c3rc_project(&c.cam, refl_v3(0.2f * (float)i, 0, 0), pr);
        check_outputs(pr, n);
        cr_assert(n == 0 || pr[0].t > 0, "point %d of the segment projects at t = 0", i);
    }
    sweep_point(&c, abc, 1.0, P);
    n = refl_c3rc_project(&c.cam, fvec(P), pr);
    check_outputs(pr, n);
    cr_assert_eq(n, 1);
    cr_assert(fabs(pr[0].t - 1) < 1e-5 && fabs(pr[0].a - 0.2) < 1e-5 && fabs(pr[0].b - 0.5) < 1e-5,
              "%g %g %g %g", pr[0].a, pr[0].b, pr[0].c, pr[0].t);
}

/* ---- exactness ---------------------------------------------------------------- */

/* Points a V1(t) + b V2(t) + c V3(t) project back to (a, b, c, t). The
   point is rounded to floats on the way in; the expected values follow
   that rounding to first order (J^-1 dP, J = [E1 E2 D]), and points where
   that correction is itself large (the map is ill-conditioned there: near
   a fold, or on a very thin camera) are only checked for their residual. */
Test(refl_c3rc_camera, projection_exact_random_cameras) {
    int fam, cams, p, i, n, checked = 0, skipped = 0, pushed_off = 0, total = 0, skipped_fam[FAM_COUNT] = {0};
    double worst_abc = 0, worst_t = 0;
    sm_state = 1;
    for (fam = 0; fam < FAM_COUNT; ++fam)
        for (cams = 0; cams < 120; ++cams) {
            cam3 c;
            double reach;
            random_camera(&c, fam, &reach);
            for (p = 0; p < 40; ++p) {
                double abc[3], t, P[3], Pf[3], ex[4], tol_t;
                refl_c3rc_projection pr[3];
                int found = 0, k;
                random_abc(abc);
                t = sm_next() % 16 == 0 ? 0.0 : U(0, reach);
                sweep_point(&c, abc, t, P);
                dvec(fvec(P), Pf);
                n = refl_c3rc_project(&c.cam, fvec(P), pr);
                check_outputs(pr, n);
                ++total;
                /* every projection reconstructs the point */
                for (i = 0; i < n; ++i) {
                    double res = residual(&c, &pr[i], Pf);
                    cr_assert(res <= 1e-5 * (c.size + pr[i].t) + 1e-6 * len3(Pf),
                              "%s camera %d point %d: projection %d residual %g (t %g)", fam_name[fam], cams, p, i,
                              res, pr[i].t);
                }
                /* expected values for the float point: Newton on (b, c, t)
                   from the construction */
                if (!follow_rounding(&c, abc, t, Pf, ex)) {
                    ++skipped;
                    ++skipped_fam[fam];
                    continue;
                }
                if (ex[0] < -0.9e-6 || ex[1] < -0.9e-6 || ex[2] < -0.9e-6 || ex[3] < -1e-6 * c.size) {
                    ++pushed_off; /* rounding moved a point of an edge out of the volume */
                    continue;
                }
                tol_t = 1e-5 * (ex[3] > c.size ? ex[3] : c.size);
                for (k = 0; k < 3; ++k) ex[k] = ex[k] < 0 ? 0 : ex[k];
                if (ex[3] < 0) ex[3] = 0;
                for (i = 0; i < n; ++i) {
                    double da = fabs(pr[i].a - ex[0]), db = fabs(pr[i].b - ex[1]), dc = fabs(pr[i].c - ex[2]);
                    double dt = fabs(pr[i].t - ex[3]);
                    double m = da > db ? da : db;
                    m = m > dc ? m : dc;
                    if (m <= 1e-5 && dt <= tol_t) {
                        found = 1;
                        if (m > worst_abc) worst_abc = m;
                        if (dt / (tol_t * 1e5) > worst_t) worst_t = dt / (tol_t * 1e5);
                    }
                }
                cr_assert(found, "%s camera %d point %d: (%.9g %.9g %.9g, t %.9g) not among %d projections%s%.9g %.9g "
                          "%.9g t %.9g", fam_name[fam], cams, p, ex[0], ex[1], ex[2], ex[3], n, n ? ": first " : "",
                          n ? pr[0].a : 0.0, n ? pr[0].b : 0.0, n ? pr[0].c : 0.0, n ? pr[0].t : 0.0);
                ++checked;
            }
        }
    cr_log_info("exactness: %d points, %d checked against their construction (%d ill-conditioned, %d rounded off "
                "an edge: residual only); worst barycentric error %.2g, worst t error %.2g relative",
                total, checked, skipped, pushed_off, worst_abc, worst_t);
    for (fam = 0; fam < FAM_COUNT; ++fam)
        cr_assert(skipped_fam[fam] * 20 < total / FAM_COUNT, "%s cameras: %d of %d points ill-conditioned",
                  fam_name[fam], skipped_fam[fam], total / FAM_COUNT);
}

/* The same points against the closed-form cubic (refl_solve_cubic on
   coefficients interpolated here in long double) and barycentrics solved
   here: the count and every value must agree, except where the answer
   hinges on rounding (a root at a barycentric or t boundary, or two roots
   close together). */
Test(refl_c3rc_camera, projection_agrees_with_closed_form) {
    int fam, cams, p, i, j, compared = 0, ambiguous = 0, triples = 0;
    sm_state = 2;
    for (fam = 0; fam < FAM_COUNT; ++fam)
        for (cams = 0; cams < 60; ++cams) {
            cam3 c;
            double reach;
            random_camera(&c, fam, &reach);
            for (p = 0; p < 40; ++p) {
                double abc[3], P[3], roots[3], co[4], exp_t[3], exp_abc[3][3], s = c.size;
                long double F[4];
                refl_c3rc_projection pr[3];
                int n, nr, ne = 0, amb = 0, k;
                if (p % 2) {
                    random_abc(abc);
                    sweep_point(&c, abc, U(0, reach), P);
                } else {
                    /* anywhere around the volume */
                    random_abc(abc);
                    sweep_point(&c, abc, U(0, reach), P);
                    for (k = 0; k < 3; ++k) P[k] += U(-1, 1) * s;
                }
                dvec(fvec(P), P);
                /* F = det(E1(t), E2(t), P - V1(t)) at t = 0, s, 2s, 3s, then
                   forward differences to monomial coefficients in u = t / s */
                for (k = 0; k < 4; ++k) {
                    double E1[3], E2[3], V0[3], W[3];
                    long double x[3], y[3], z[3];
                    int m;
                    sweep_edges(&c, k * s, E1, E2);
                    sweep_vertex(&c, 0, k * s, V0);
                    for (m = 0; m < 3; ++m) {
                        W[m] = P[m] - V0[m];
                        x[m] = E1[m]; y[m] = E2[m]; z[m] = W[m];
                    }
                    F[k] = x[0] * (y[1] * z[2] - y[2] * z[1]) - x[1] * (y[0] * z[2] - y[2] * z[0]) +
                           x[2] * (y[0] * z[1] - y[1] * z[0]);
                }
                {
                    long double d1 = F[1] - F[0], d2 = F[2] - 2 * F[1] + F[0], d3 = F[3] - 3 * F[2] + 3 * F[1] - F[0];
                    /* in u = t / h: F = F0 + d1 u + d2 u(u-1)/2 + d3 u(u-1)(u-2)/6 */
                    long double a3 = d3 / 6, a2 = d2 / 2 - d3 / 2, a1 = d1 - d2 / 2 + d3 / 3, a0 = F[0];
                    co[0] = (double)a3; co[1] = (double)a2; co[2] = (double)a1; co[3] = (double)a0;
                }
                nr = refl_solve_cubic(co[0], co[1], co[2], co[3], roots);
                for (i = 0; i < nr; ++i) {
                    double t = roots[i] * s, E1[3], E2[3], V0[3], W[3], nn[3], x[3], b, cc, a;
                    if (t < -1e-4 * s) continue;
                    if (t < 1e-4 * s) amb = 1;
                    for (j = 0; j < nr; ++j)
                        if (j != i && fabs(roots[j] * s - t) < 1e-3 * (s + fabs(t))) amb = 1;
                    sweep_edges(&c, t, E1, E2);
                    sweep_vertex(&c, 0, t, V0);
                    for (k = 0; k < 3; ++k) W[k] = P[k] - V0[k];
                    cross3(E1, E2, nn);
                    cross3(W, E2, x);
                    b = dot3(x, nn) / dot3(nn, nn);
                    cross3(E1, W, x);
                    cc = dot3(x, nn) / dot3(nn, nn);
                    a = 1 - b - cc;
                    if (fabs(a) < 1e-4 || fabs(b) < 1e-4 || fabs(cc) < 1e-4) amb = 1;
                    if (a >= 0 && b >= 0 && cc >= 0 && t >= 0) {
                        exp_t[ne] = t;
                        exp_abc[ne][0] = a; exp_abc[ne][1] = b; exp_abc[ne][2] = cc;
                        ++ne;
                    }
                }
                n = refl_c3rc_project(&c.cam, fvec(P), pr);
                check_outputs(pr, n);
                if (amb) { ++ambiguous; continue; }
                ++compared;
                if (n == 3) ++triples;
                cr_assert_eq(n, ne, "%s camera %d point %d: %d projections, the closed form has %d", fam_name[fam], cams,
                             p, n, ne);
                for (i = 0; i < n; ++i) {
                    double tol_t = 1e-5 * (exp_t[i] > s ? exp_t[i] : s);
                    cr_assert(fabs(pr[i].t - exp_t[i]) <= tol_t && fabs(pr[i].a - exp_abc[i][0]) <= 1e-5 &&
                                  fabs(pr[i].b - exp_abc[i][1]) <= 1e-5 && fabs(pr[i].c - exp_abc[i][2]) <= 1e-5,
                              "%s camera %d point %d, projection %d: %g %g %g t %g, closed form %g %g %g t %g",
                              fam_name[fam], cams, p, i, pr[i].a, pr[i].b, pr[i].c, pr[i].t, exp_abc[i][0],
                              exp_abc[i][1], exp_abc[i][2], exp_t[i]);
                }
            }
        }
    cr_log_info("closed form: %d points compared (%d with three projections), %d near a boundary skipped", compared,
                triples, ambiguous);
    cr_assert(ambiguous * 10 < compared, "%d ambiguous of %d", ambiguous, compared);
}

/* Points known to lie outside: where all three rays cross the plane of
   T(t*) the same way, T(t*) is the only sweeping triangle touching that
   plane (the others lie strictly on either side; see cam_c3rc.c). So a
   point of that plane outside T(t*), or of T(t*) with t* < 0 (behind the
   base), has no projection at all. */
Test(refl_c3rc_camera, outside_and_behind_project_nothing) {
    int fam, cams, p, tested_out = 0, tested_behind = 0;
    sm_state = 3;
    for (fam = 0; fam < FAM_COUNT; ++fam)
        for (cams = 0; cams < 60; ++cams) {
            cam3 c;
            double reach;
            random_camera(&c, fam, &reach);
            for (p = 0; p < 40; ++p) {
                double abc[3], P[3], t;
                refl_c3rc_projection pr[3];
                int n, behind = p % 2, k;
                if (behind) {
                    t = -U(1e-3, 1) * c.size;
                    random_abc(abc);
                } else {
                    /* one barycentric well below zero */
                    t = U(0, reach);
                    random_abc(abc);
                    k = (int)(sm_next() % 3);
                    abc[k] = -U(0.01, 1);
                    abc[(k + 1) % 3] = 1 - abc[k] - abc[(k + 2) % 3];
                }
                if (!sides_agree(&c, t, 1e-3)) continue;
                sweep_point(&c, abc, t, P);
                n = refl_c3rc_project(&c.cam, fvec(P), pr);
                cr_assert_eq(n, 0, "%s camera %d point %d (%s, t %g, %g %g %g): %d projections, first t %g",
                             fam_name[fam], cams, p, behind ? "behind" : "outside", t, abc[0], abc[1], abc[2], n,
                             pr[0].t);
                if (behind) ++tested_behind;
                else ++tested_out;
            }
        }
    cr_log_info("outside: %d points beside the volume, %d behind the base", tested_out, tested_behind);
    cr_assert(tested_out > 3000 && tested_behind > 3000, "%d %d", tested_out, tested_behind);
}

/* ---- multiple projections ---------------------------------------------------- */

/* A camera whose sweeping triangle turns over itself. T(1) is the
   triangle A = (-1,-1,1), (1,-1,1), (0,1,1) in the plane z = 1; the rays
   run along u1 = u2 = (0, .6, .8), u3 = (0, -.8, -.6), so T(3) = A + 2u is
   the triangle (-1,.2,2.6), (1,.2,2.6), (0,-.6,-.2), which cuts z = 1 on
   y = -9/35, x in [-3/7, 3/7] (A spans x in [-22/35, 22/35] there). Every
   point (x, -9/35, 1) of that segment lies in T(1) at
   ((22/35 - x)/2, (22/35 + x)/2, 13/35) and in T(3) at
   ((3/7 - x)/2, (3/7 + x)/2, 4/7); the directions are coplanar (x = 0), so
   the cubic is a quadratic and there is no third projection. */
Test(refl_c3rc_camera, known_double_projection) {
    cam3 c;
    double v[3][3] = {{-1, -1.6, 0.2}, {1, -1.6, 0.2}, {0, 1.8, 1.6}};
    double d[3][3] = {{0, 0.6, 0.8}, {0, 0.6, 0.8}, {0, -0.8, -0.6}};
    float iv[4][2];
    int i, j, ni;
    cam_make(&c, v, d);
    ni = refl_c3rc_multiple_intervals(&c.cam, INFINITY, iv);
    cr_assert(ni >= 1);
    for (i = 0; i <= 40; ++i) {
        double x = -0.4 + 0.02 * i, P[3] = {x, -9.0 / 35.0, 1};
        double want[2][4] = {{(22.0 / 35 - x) / 2, (22.0 / 35 + x) / 2, 13.0 / 35, 1},
                             {(3.0 / 7 - x) / 2, (3.0 / 7 + x) / 2, 4.0 / 7, 3}};
        refl_c3rc_projection pr[3];
        int n = refl_c3rc_project(&c.cam, fvec(P), pr);
        check_outputs(pr, n);
        cr_assert_eq(n, 2, "x = %g: %d projections", x, n);
        for (j = 0; j < 2; ++j) {
            int in = 0, k;
            cr_assert(fabs(pr[j].a - want[j][0]) < 1e-5 && fabs(pr[j].b - want[j][1]) < 1e-5 &&
                          fabs(pr[j].c - want[j][2]) < 1e-5 && fabs(pr[j].t - want[j][3]) < 1e-5,
                      "x = %g projection %d: %.7g %.7g %.7g t %.7g, want %.7g %.7g %.7g t %g", x, j, pr[j].a, pr[j].b,
                      pr[j].c, pr[j].t, want[j][0], want[j][1], want[j][2], want[j][3]);
            cr_assert(residual(&c, &pr[j], P) < 1e-5);
            for (k = 0; k < ni; ++k) in |= pr[j].t >= iv[k][0] && pr[j].t <= iv[k][1];
            cr_assert(in, "t = %g outside the intervals", pr[j].t);
        }
    }
}

/* Section 5.1: every projection of a point that projects more than once
   lies inside refl_c3rc_multiple_intervals' intervals (all of them, not
   just one), and a camera with no interval projects nothing twice. The
   intervals themselves are checked against the sides sampled here. */
Test(refl_c3rc_camera, multiple_projections_inside_intervals) {
    int fam, cams, p, i, j, multi = 0, triple = 0, points = 0, no_interval_cams = 0, no_interval_points = 0;
    sm_state = 4;
    for (fam = 0; fam < FAM_COUNT; ++fam)
        for (cams = 0; cams < (fam == FAM_CONVERGENT || fam == FAM_WIDE ? 400 : 60); ++cams) {
            cam3 c;
            double reach;
            float iv[4][2], ivt[4][2], tmax;
            int ni, nt;
            random_camera(&c, fam, &reach);
            ni = refl_c3rc_multiple_intervals(&c.cam, INFINITY, iv);
            cr_assert(ni >= 0 && ni <= 4);
            for (i = 0; i < ni; ++i) {
                cr_assert(iv[i][0] >= 0 && iv[i][0] <= iv[i][1], "[%g, %g]", iv[i][0], iv[i][1]);
                if (i > 0) cr_assert(iv[i][0] > iv[i - 1][1], "not disjoint and ascending");
            }
            /* a finite tmax clips the same intervals */
            tmax = (float)U(0.1, 2) * (float)reach;
            nt = refl_c3rc_multiple_intervals(&c.cam, tmax, ivt);
            for (i = 0; i < nt; ++i) cr_assert(ivt[i][0] >= 0 && ivt[i][1] <= tmax * (1 + 1e-6f));
            /* against the sides sampled on a grid */
            for (j = 0; j <= 200; ++j) {
                double t = reach * 2 * j / 200.0;
                int in = 0, in_t = 0;
                for (i = 0; i < ni; ++i) in |= t >= iv[i][0] - 1e-6 * (t + c.size) && t <= iv[i][1] + 1e-6 * (t + c.size);
                for (i = 0; i < nt; ++i) in_t |= t >= ivt[i][0] - 1e-6 * (t + c.size) && t <= ivt[i][1] + 1e-6 * (t + c.size);
                if (sides_agree(&c, t, 1e-6)) {
                    int strict = 1;
                    for (i = 0; i < ni; ++i)
                        strict &= !(t > iv[i][0] + 1e-6 * (t + c.size) && t < iv[i][1] - 1e-6 * (t + c.size));
                    cr_assert(strict, "%s camera %d: t = %g inside an interval where the sides agree", fam_name[fam],
                              cams, t);
                } else {
                    double s0 = side(&c, 0, t), s1 = side(&c, 1, t), s2 = side(&c, 2, t);
                    if (fabs(s0) > 1e-6 && fabs(s1) > 1e-6 && fabs(s2) > 1e-6) {
                        cr_assert(in, "%s camera %d: t = %g: sides %g %g %g disagree outside the intervals",
                                  fam_name[fam], cams, t, s0, s1, s2);
                        if (t <= tmax * (1 - 1e-6)) cr_assert(in_t, "t = %g missing with tmax %g", t, tmax);
                    }
                }
            }
            if (ni == 0) ++no_interval_cams;
            for (p = 0; p < 60; ++p) {
                double abc[3], P[3];
                refl_c3rc_projection pr[3];
                int n, k;
                random_abc(abc);
                sweep_point(&c, abc, U(0, 2 * reach), P);
                if (p % 3 == 0)
                    for (k = 0; k < 3; ++k) P[k] += U(-0.2, 0.2) * c.size;
                n = refl_c3rc_project(&c.cam, fvec(P), pr);
                check_outputs(pr, n);
                ++points;
                if (ni == 0) {
                    ++no_interval_points;
                    cr_assert(n <= 1, "%s camera %d has no interval but a point projects %d times", fam_name[fam], cams,
                              n);
                }
                if (n < 2) continue;
                ++multi;
                triple += n == 3;
                for (i = 0; i < n; ++i) {
                    int in = 0;
                    double slack = 1e-6 * (pr[i].t + c.size);
                    cr_assert(residual(&c, &pr[i], P) <= 1e-5 * (c.size + pr[i].t) + 1e-6 * len3(P));
                    for (j = 0; j < ni; ++j) in |= pr[i].t >= iv[j][0] - slack && pr[i].t <= iv[j][1] + slack;
                    cr_assert(in, "%s camera %d point %d: projection %d of %d at t = %g outside every interval",
                              fam_name[fam], cams, p, i, n, pr[i].t);
                }
            }
        }
    cr_log_info("multiple projections: %d of %d points (%d triple), all inside the intervals; %d cameras without "
                "an interval, %d of their points, none projected twice",
                multi, points, triple, no_interval_cams, no_interval_points);
    cr_assert(multi > 500 && triple > 0 && no_interval_cams > 100, "%d %d %d", multi, triple, no_interval_cams);
}

/* ---- continuity ----------------------------------------------------------------- */

/* Do T(t) of two adjacent cameras (consistently ordered) face the same
   way, i.e. lie on opposite sides of their shared edge? */
static int same_facing(const cam3 *a, const cam3 *b, double t) {
    double E1[3], E2[3], na[3], nb[3];
    sweep_edges(a, t, E1, E2);
    cross3(E1, E2, na);
    sweep_edges(b, t, E1, E2);
    cross3(E1, E2, nb);
    return dot3(na, nb) > 0.1 * len3(na) * len3(nb);
}

/* Two C3RCs of adjacent triangles of a sphere share an edge and its two
   rays. A point on (or a hair off) the wall between them projects in at
   least one (where neither volume folds), and where it projects in both
   with the shared edge's weights, the image points and t agree. Convex
   (divergent rays) and concave (convergent) reflectors. */
Test(refl_c3rc_camera, continuous_across_shared_edge) {
    int trial, p, both = 0, points = 0, on_wall = 0, folded = 0, exact = 0;
    sm_state = 5;
    for (trial = 0; trial < 200; ++trial) {
        int concave = trial % 2, i, k;
        double eye[3] = {0, 0, concave ? 0.3 : 4}, ctr[3], t1[3], t2[3], h = U(0.05, 0.3);
        double V[4][3], Dd[4][3], va[3][3], da[3][3], vb[3][3], db[3][3];
        double uv[4][2] = {{-1, -0.6}, {0, 0.8}, {0, -0.8}, {1, 0.6}};
        cam3 A, B;
        do {
            rnd_unit(ctr);
        } while (concave ? ctr[2] > -0.5 : ctr[2] < 0.5);
        rnd_unit(t1);
        cross3(ctr, t1, t2);
        norm3(t2);
        cross3(t2, ctr, t1);
        for (i = 0; i < 4; ++i) {
            double n[3], in[3], dn;
            uv[i][0] += U(-0.2, 0.2);
            uv[i][1] += U(-0.2, 0.2);
            for (k = 0; k < 3; ++k) V[i][k] = ctr[k] + h * (uv[i][0] * t1[k] + uv[i][1] * t2[k]);
            norm3(V[i]);
            for (k = 0; k < 3; ++k) {
                n[k] = concave ? -V[i][k] : V[i][k];
                in[k] = V[i][k] - eye[k];
            }
            norm3(in);
            dn = dot3(in, n);
            for (k = 0; k < 3; ++k) Dd[i][k] = in[k] - 2 * dn * n[k];
        }
        /* A = (v0, v1, v2), B = (v3, v2, v1): they share v1, v2 */
        memcpy(va[0], V[0], sizeof va[0]); memcpy(va[1], V[1], sizeof va[0]); memcpy(va[2], V[2], sizeof va[0]);
        memcpy(da[0], Dd[0], sizeof da[0]); memcpy(da[1], Dd[1], sizeof da[0]); memcpy(da[2], Dd[2], sizeof da[0]);
        memcpy(vb[0], V[3], sizeof vb[0]); memcpy(vb[1], V[2], sizeof vb[0]); memcpy(vb[2], V[1], sizeof vb[0]);
        memcpy(db[0], Dd[3], sizeof db[0]); memcpy(db[1], Dd[2], sizeof db[0]); memcpy(db[2], Dd[1], sizeof db[0]);
        cam_make(&A, (const double(*)[3])va, (const double(*)[3])da);
        cam_make(&B, (const double(*)[3])vb, (const double(*)[3])db);
        for (p = 0; p < 60; ++p) {
            double al = U(0, 1), t = U(0, concave ? 1.0 : 3.0), P[3], V1[3], V2[3], off[3], e[3], hs;
            refl_c3rc_projection pa[3], pb[3];
            int na, nb, ia, ib, hair = p % 2;
            sweep_vertex(&A, 1, t, V1);
            sweep_vertex(&A, 2, t, V2);
            rnd_unit(off);
            /* a hair: a millionth of the edge at t, and away from its ends
               (beyond them lie other triangles' cameras) */
            for (k = 0; k < 3; ++k) e[k] = V2[k] - V1[k];
            hs = hair ? 1e-6 * len3(e) : 0;
            if (hair) al = U(0.01, 0.99);
            for (k = 0; k < 3; ++k) P[k] = (1 - al) * V1[k] + al * V2[k] + hs * off[k];
            na = refl_c3rc_project(&A.cam, fvec(P), pa);
            nb = refl_c3rc_project(&B.cam, fvec(P), pb);
            check_outputs(pa, na);
            check_outputs(pb, nb);
            /* where a volume folds, or one of the two triangles at t has
               turned over (near the caustic of the concave mirror), both
               volumes may lie on the same side of the wall, and a point's
               projections move by the square root of its rounding; not
               there */
            if (!(sides_agree(&A, t, 1e-3) && sides_agree(&B, t, 1e-3) && same_facing(&A, &B, t))) {
                ++folded;
                continue;
            }
            {
                ++points;
                cr_assert(na + nb >= 1, "trial %d point %d (alpha %g, t %g): a crack between the cameras", trial, p, al,
                          t);
                if (!hair) {
                    ++exact;
                    both += na > 0 && nb > 0;
                }
            }
            for (ia = 0; ia < na; ++ia)
                for (ib = 0; ib < nb; ++ib) {
                    /* the same point of the shared wall: A's and B's first
                       vertices unused, same t. The point's float rounding
                       moves the image by up to about 6e-8 |E(0)| / |E(t)|
                       (E the shared edge), large near the caustic. */
                    double ia_img[3], ib_img[3], diff[3], E0[3], Et[3], tol;
                    if (pa[ia].a > 1e-4 || pb[ib].a > 1e-4 || fabs(pa[ia].t - pb[ib].t) > 1e-3 * (1 + t)) continue;
                    sweep_vertex(&A, 2, pa[ia].t, Et);
                    sweep_vertex(&A, 1, pa[ia].t, E0);
                    for (k = 0; k < 3; ++k) Et[k] -= E0[k];
                    for (k = 0; k < 3; ++k) E0[k] = A.v[2][k] - A.v[1][k];
                    tol = 1e-5 + 1e-6 * len3(E0) / len3(Et);
                    for (k = 0; k < 3; ++k) {
                        ia_img[k] = pa[ia].a * A.v[0][k] + pa[ia].b * A.v[1][k] + pa[ia].c * A.v[2][k];
                        ib_img[k] = pb[ib].a * B.v[0][k] + pb[ib].b * B.v[1][k] + pb[ib].c * B.v[2][k];
                        diff[k] = ia_img[k] - ib_img[k];
                    }
                    cr_assert(len3(diff) <= tol, "trial %d point %d: images differ by %g", trial, p, len3(diff));
                    cr_assert(fabs(pa[ia].t - pb[ib].t) <= 1e-5 * (1 + t), "t %g vs %g", pa[ia].t, pb[ib].t);
                    ++on_wall;
                }
        }
    }
    cr_log_info("continuity: %d points on or by the shared wall (%d more where it folds), %d of the %d on it "
                "projected in both cameras, %d image pairs compared", points, folded, both, exact, on_wall);
    cr_assert(points > 6000 && both * 10 > exact * 9, "only %d of %d points projected in both cameras", both, exact);
}

/* ---- box test --------------------------------------------------------------------- */

/* Is some point of the box [lo, hi] projected with t <= tmax? Witnesses
   from a grid and random points of the box, and from points of the volume
   that fall in the box (which finds thin volumes the grid misses). */
static int brute_visible(const cam3 *c, const float *lo, const float *hi, double tmax, double reach) {
    int i, j, k, n, g = 8;
    refl_c3rc_projection pr[3];
    for (i = 0; i < g * g * g + 200; ++i) {
        float P[3];
        for (k = 0; k < 3; ++k) {
            double u = i < g * g * g ? ((i / (k == 0 ? 1 : k == 1 ? g : g * g)) % g) / (double)(g - 1) : U(0, 1);
            P[k] = (float)(lo[k] + (hi[k] - lo[k]) * u);
            if (P[k] < lo[k]) P[k] = lo[k];
            if (P[k] > hi[k]) P[k] = hi[k];
        }
        n = refl_c3rc_project(&c->cam, refl_v3(P[0], P[1], P[2]), pr);
        if (n > 0 && pr[0].t <= tmax) return 1;
    }
    for (j = 0; j < 3000; ++j) {
        double abc[3], P[3], t = U(0, tmax < 1e30 ? tmax : 4 * reach);
        random_abc(abc);
        sweep_point(c, abc, t, P);
        for (k = 0; k < 3; ++k)
            if (P[k] < lo[k] || P[k] > hi[k]) break;
        if (k == 3) return 1;
    }
    return 0;
}

/* Never 0 for a box holding a point that projects (t <= tmax); and it does
   reject most boxes that are clearly outside. */
Test(refl_c3rc_camera, box_visible_conservative) {
    int fam, cams, b, kind, empty_far = 0, rejected_far = 0, empty_near = 0, rejected_near = 0, visible = 0;
    int thin = 0, empty_far_inf = 0, rejected_far_inf = 0, touching = 0;
    sm_state = 6;
    for (fam = 0; fam < FAM_COUNT; ++fam)
        for (cams = 0; cams < 12; ++cams) {
            cam3 c;
            double reach, tmax;
            random_camera(&c, fam, &reach);
            tmax = cams % 4 == 0 ? INFINITY : U(0.3, 1.5) * reach;
            for (b = 0; b < 36; ++b) {
                double C[3], half[3], abc[3], dir[3], W[3], tw;
                float lo[3], hi[3];
                int k, vis, brute, has_w = 0;
                kind = b % 6;
                random_abc(abc);
                if (kind == 0) {         /* around a point of the volume */
                    sweep_point(&c, abc, U(0, tmax < 1e30 ? tmax : reach), C);
                    for (k = 0; k < 3; ++k) {
                        C[k] += U(-0.5, 0.5) * c.size;
                        half[k] = U(0.02, 1) * c.size;
                    }
                } else if (kind == 1) {  /* straddling the base */
                    sweep_point(&c, abc, 0, C);
                    for (k = 0; k < 3; ++k) half[k] = U(0.05, 0.5) * c.size;
                } else if (kind == 2) {  /* big, around a thin part of the volume */
                    sweep_point(&c, abc, U(0, tmax < 1e30 ? tmax : reach), C);
                    for (k = 0; k < 3; ++k) half[k] = U(1, 3) * c.size;
                } else if (kind == 3) {  /* far away */
                    rnd_unit(dir);
                    for (k = 0; k < 3; ++k) {
                        C[k] = c.v[0][k] + U(10, 50) * c.size * dir[k];
                        half[k] = U(0.1, 1) * c.size;
                    }
                } else {
                    /* a box of any size holding, anywhere in it, a point W of
                       the volume's boundary: on a wall (kind 4), on the base
                       or on the cap at tmax (kind 5) */
                    double hs = pow(10.0, U(-4, 0)) * c.size;
                    tw = tmax < 1e30 ? tmax : reach;
                    if (kind == 4) {
                        int e = (int)(sm_next() % 3);
                        abc[e] = U(0, 1);
                        abc[(e + 1) % 3] = 1 - abc[e];
                        abc[(e + 2) % 3] = 0;
                        tw = U(0, tw);
                    } else if (sm_next() & 1) {
                        tw = 0;
                    }
                    sweep_point(&c, abc, tw, W);
                    has_w = 1;
                    for (k = 0; k < 3; ++k) {
                        half[k] = hs * U(0.2, 1);
                        C[k] = W[k] + U(-1, 1) * half[k];
                    }
                }
                for (k = 0; k < 3; ++k) {
                    lo[k] = (float)(C[k] - half[k]);
                    hi[k] = (float)(C[k] + half[k]);
                }
                if (has_w)
                    for (k = 0; k < 3; ++k)
                        if (!(W[k] >= lo[k] && W[k] <= hi[k])) has_w = 0;
                vis = refl_c3rc_box_visible(&c.cam, refl_v3(lo[0], lo[1], lo[2]), refl_v3(hi[0], hi[1], hi[2]),
                                            (float)tmax);
                cr_assert(vis == 0 || vis == 1);
                brute = has_w || brute_visible(&c, lo, hi, tmax, reach);
                touching += has_w;
                cr_assert(vis || !brute, "%s camera %d box %d (kind %d, tmax %g): rejected, but a point in it projects",
                          fam_name[fam], cams, b, kind, tmax);
                visible += brute;
                if (!brute && kind == 3) { ++empty_far; rejected_far += !vis; }
                if (!brute && kind == 3 && tmax > 1e30) { ++empty_far_inf; rejected_far_inf += !vis; }
                if (!brute && kind < 3) { ++empty_near; rejected_near += !vis; }
            }
        }
    /* thin volumes through big boxes, no corner inside: rays almost
       parallel from a small triangle */
    for (b = 0; b < 100; ++b) {
        cam3 c;
        double v[3][3], d[3][3], axis[3], P[3], abc[3] = {1 / 3.0, 1 / 3.0, 1 / 3.0}, off[3];
        float lo[3], hi[3];
        int i, k, vis;
        rnd_unit(axis);
        for (i = 0; i < 3; ++i) {
            rnd_unit(off);
            for (k = 0; k < 3; ++k) {
                v[i][k] = 0.01 * off[k];
                d[i][k] = axis[k] + 1e-3 * U(-1, 1);
            }
            norm3(d[i]);
        }
        cam_make(&c, (const double(*)[3])v, (const double(*)[3])d);
        sweep_point(&c, abc, U(2, 4), P);
        for (k = 0; k < 3; ++k) {
            lo[k] = (float)(P[k] - U(0.2, 1));
            hi[k] = (float)(P[k] + U(0.2, 1));
        }
        cr_assert(brute_visible(&c, lo, hi, 10, 5));
        vis = refl_c3rc_box_visible(&c.cam, refl_v3(lo[0], lo[1], lo[2]), refl_v3(hi[0], hi[1], hi[2]),
                                    b % 2 ? 10.0f : INFINITY);
        cr_assert(vis, "thin volume %d through a box: rejected", b);
        ++thin;
    }
    cr_log_info("box test: %d boxes with a projecting point (%d holding a point of the volume's boundary), all "
                "kept; %d thin volumes through boxes kept; rejected %d of %d empty far boxes (%d of %d with no tmax), "
                "%d of %d empty boxes near the volume",
                visible, touching, thin, rejected_far, empty_far, rejected_far_inf, empty_far_inf, rejected_near,
                empty_near);
    cr_assert(empty_far > 50 && rejected_far * 2 > empty_far, "rejected only %d of %d far boxes", rejected_far,
              empty_far);
    cr_assert(empty_far_inf > 20 && rejected_far_inf * 2 > empty_far_inf, "rejected only %d of %d far boxes",
              rejected_far_inf, empty_far_inf);
}

/* Boxes straddling the base, inside and beside the walls, and boxes inside
   the volume: exactly decidable cases. */
Test(refl_c3rc_camera, box_visible_simple_cases) {
    cam3 c;
    double v[3][3] = {{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}}, d[3][3] = {{-0.2, -0.2, 1}, {0.2, -0.2, 1}, {0, 0.2, 1}};
    int i;
    for (i = 0; i < 3; ++i) norm3(d[i]);
    cam_make(&c, v, d);
    /* straddling the base inside the walls */
    cr_assert(refl_c3rc_box_visible(&c.cam, refl_v3(-0.1f, -0.1f, -0.1f), refl_v3(0.1f, 0.1f, 0.1f), INFINITY));
    /* wholly inside */
    cr_assert(refl_c3rc_box_visible(&c.cam, refl_v3(-0.1f, -0.1f, 1), refl_v3(0.1f, 0.1f, 1.2f), INFINITY));
    /* holding the whole truncated volume */
    cr_assert(refl_c3rc_box_visible(&c.cam, refl_v3(-5, -5, -5), refl_v3(5, 5, 5), 1.0f));
    /* behind the base, beside the walls, beyond tmax */
    cr_assert(!refl_c3rc_box_visible(&c.cam, refl_v3(-0.5f, -0.5f, -2), refl_v3(0.5f, 0.5f, -0.1f), INFINITY));
    cr_assert(!refl_c3rc_box_visible(&c.cam, refl_v3(3, -0.5f, 0.5f), refl_v3(4, 0.5f, 1), INFINITY));
    cr_assert(!refl_c3rc_box_visible(&c.cam, refl_v3(-0.1f, -0.1f, 3), refl_v3(0.1f, 0.1f, 4), 2.0f));
    cr_assert(refl_c3rc_box_visible(&c.cam, refl_v3(-0.1f, -0.1f, 3), refl_v3(0.1f, 0.1f, 4), INFINITY));
    /* an empty box, a negative tmax; a NaN or unbounded box may hold anything */
    cr_assert(!refl_c3rc_box_visible(&c.cam, refl_v3(1, 1, 1), refl_v3(0, 0, 0), INFINITY));
    cr_assert(!refl_c3rc_box_visible(&c.cam, refl_v3(-1, -1, -1), refl_v3(1, 1, 1), -1.0f));
    cr_assert(refl_c3rc_box_visible(&c.cam, refl_v3(NAN, 0, 0), refl_v3(1, 1, 1), INFINITY));
    cr_assert(refl_c3rc_box_visible(&c.cam, refl_v3(-INFINITY, 0, 0), refl_v3(INFINITY, 1, 1), INFINITY));
}

/* ---- extremes ---------------------------------------------------------------------- */

/* Huge coordinates, tiny triangles, absurd points: no NaN, sane outputs. */
Test(refl_c3rc_camera, extremes_produce_no_nan) {
    static const float probes[] = {0, 1e-30f, 1e-4f, 1, 1e6f, 1e30f, FLT_MAX, INFINITY, NAN};
    int trial, p, k, n, i;
    sm_state = 7;
    for (trial = 0; trial < 60; ++trial) {
        cam3 c;
        double v[3][3], d[3][3], off = trial % 3 == 0 ? 0 : trial % 3 == 1 ? 1e6 : 1e3;
        double size = trial % 2 ? 1e-4 : 1.0, x[3];
        float iv[4][2];
        for (i = 0; i < 3; ++i) {
            rnd_unit(x);
            for (k = 0; k < 3; ++k) v[i][k] = off + size * x[k];
            rnd_unit(d[i]);
            if (trial % 4 == 0) { d[i][0] = 0.3 * d[i][0]; d[i][1] = 0.3 * d[i][1]; d[i][2] = 1; }
        }
        cam_make(&c, (const double(*)[3])v, (const double(*)[3])d);
        n = refl_c3rc_multiple_intervals(&c.cam, INFINITY, iv);
        for (i = 0; i < n; ++i) cr_assert(iv[i][0] == iv[i][0] && iv[i][1] == iv[i][1]);
        for (p = 0; p < 200; ++p) {
            refl_c3rc_projection pr[3];
            float P[3];
            if (p < 81) {
                for (k = 0; k < 3; ++k) P[k] = (float)(off + probes[(p / (k == 0 ? 1 : k == 1 ? 9 : 27)) % 9] *
                                                                 ((p + k) % 2 ? -1 : 1));
            } else if (p < 84) {
                for (k = 0; k < 3; ++k) P[k] = (float)v[p - 81][k];
            } else {
                double abc[3], Q[3];
                random_abc(abc);
                sweep_point(&c, abc, U(0, 1e3) * size, Q);
                for (k = 0; k < 3; ++k) P[k] = (float)(Q[k] + (p % 2 ? U(-1, 1) * size : 0));
            }
            n = refl_c3rc_project(&c.cam, refl_v3(P[0], P[1], P[2]), pr);
            check_outputs(pr, n);
            for (i = 0; i < n; ++i)
                cr_assert(pr[i].a == pr[i].a && pr[i].b == pr[i].b && pr[i].c == pr[i].c && pr[i].t == pr[i].t);
            if (p < 81) {
                float lo[3], hi[3];
                for (k = 0; k < 3; ++k) { lo[k] = P[k] < (float)off ? P[k] : (float)off; hi[k] = P[k] < (float)off ? (float)off : P[k]; }
                i = refl_c3rc_box_visible(&c.cam, refl_v3(lo[0], lo[1], lo[2]), refl_v3(hi[0], hi[1], hi[2]),
                                          p % 2 ? INFINITY : 1e3f);
                cr_assert(i == 0 || i == 1);
            }
        }
    }
}
