/* cam_c3rc: the continuous 3-ray camera (C3RC) of paper 000, section 5.
   A C3RC replaces the reflected rays of one reflector triangle: the tails
   v1, v2, v3 are the triangle's vertices, d1, d2, d3 the unit reflected rays
   there, and the view volume is swept by the triangle T(t) with vertices
   vi + t di, t >= 0. A point P projects to (a, b, c, t) when
       P = a (v1 + t d1) + b (v2 + t d2) + c (v3 + t d3),  a, b, c >= 0,
   so the image point a v1 + b v2 + c v3 moves continuously across an edge
   two C3RCs share (they share its two rays).

   Projection: with e1 = v2 - v1, e2 = v3 - v1, f1 = d2 - d1, f2 = d3 - d1,
   P lies in T(t)'s plane where
       F(t) = det(e1 + t f1, e2 + t f2, P - v1 - t d1) = 0,
   a cubic whose coefficients are affine in P (three dot products; the
   leading one is constant). The roots are found without dividing by the
   leading coefficient, which vanishes for almost parallel rays: t is
   bounded above by geometry, [0, T] is split at the critical points into
   monotone pieces and each piece with a sign change is solved by
   safeguarded Halley iteration. Each root is accepted by its barycentrics
   in T(t).

   Section 5.1 (refl_c3rc_multiple_intervals): the sweep values where the
   rays are not all on one side of T(t)'s plane; every projection of a
   point that projects more than once lies there (proved below).

   Section 5.2 (refl_c3rc_box_visible), made conservative: a box is
   rejected only when nothing that can bound the truncated view volume
   reaches it; the argument is at the function. */
#include "internal.h"

/* cam->pre[] layout (doubles, all from the stored float tails and unit rays):
     0..2    N0 = e1 x e2
     3..5    N1 = e1 x f2 + f1 x e2
     6..8    N2 = f1 x f2
     9..12   m0..m3: coefficient k of F(t) is N_k . (P - ctr) + m_k (N3 = 0)
     13..15  ctr, the tails' centroid
     16      R = max |vi - ctr|
     17      1/m, at most 1e7; m = distance from the origin to the triangle
             (d1, d2, d3) = the least |a d1 + b d2 + c d3|
     18..20  |e1||e2|, |e1||f2| + |f1||e2|, |f1||f2|: rounding bounds
     21..23  e1    24..26 e2    27..29 f1    30..32 f2    33..35 d1
     36..38  u = ctr - v1
     39      |u| */
#define REFL__C3RC_N0 0
#define REFL__C3RC_N1 3
#define REFL__C3RC_N2 6
#define REFL__C3RC_M 9
#define REFL__C3RC_CTR 13
#define REFL__C3RC_R 16
#define REFL__C3RC_INVM 17
#define REFL__C3RC_L 18
#define REFL__C3RC_E1 21
#define REFL__C3RC_E2 24
#define REFL__C3RC_F1 27
#define REFL__C3RC_F2 30
#define REFL__C3RC_D1 33
#define REFL__C3RC_U 36
#define REFL__C3RC_ULEN 39

#define REFL__C3RC_BARY_TOL 1e-6   /* api.h: barycentrics this far outside count */
#define REFL__C3RC_MAX_INVM 1e7    /* t <= 1e7 * distance when the rays can cancel */

/* ---- double helpers ---------------------------------------------------------- */

static double refl__c3rc_dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void refl__c3rc_cross(const double *a, const double *b, double *o) {
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

static double refl__c3rc_len(const double *a) { return sqrt(refl__c3rc_dot(a, a)); }

static void refl__c3rc_sub(const double *a, const double *b, double *o) {
    o[0] = a[0] - b[0]; o[1] = a[1] - b[1]; o[2] = a[2] - b[2];
}

static void refl__c3rc_load(refl_vec3 v, double *o) { o[0] = v.x; o[1] = v.y; o[2] = v.z; }

static int refl__c3rc_finite3(refl_vec3 v) { return refl__isfinite(v.x) && refl__isfinite(v.y) && refl__isfinite(v.z); }

/* Distance from the origin to triangle (a, b, c): Ericson's closest point
   on a triangle, with the query point at the origin. */
static double refl__c3rc_origin_distance(const double *a, const double *b, const double *c) {
    double ab[3], ac[3], bc[3], p[3], d1, d2, d3, d4, d5, d6, va, vb, vc, v, w;
    int k;
    refl__c3rc_sub(b, a, ab);
    refl__c3rc_sub(c, a, ac);
    d1 = -refl__c3rc_dot(ab, a);
    d2 = -refl__c3rc_dot(ac, a);
    if (d1 <= 0.0 && d2 <= 0.0) return refl__c3rc_len(a);
    d3 = -refl__c3rc_dot(ab, b);
    d4 = -refl__c3rc_dot(ac, b);
    if (d3 >= 0.0 && d4 <= d3) return refl__c3rc_len(b);
    vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        v = d1 / (d1 - d3);
        for (k = 0; k < 3; ++k) p[k] = a[k] + v * ab[k];
        return refl__c3rc_len(p);
    }
    d5 = -refl__c3rc_dot(ab, c);
    d6 = -refl__c3rc_dot(ac, c);
    if (d6 >= 0.0 && d5 <= d6) return refl__c3rc_len(c);
    vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        w = d2 / (d2 - d6);
        for (k = 0; k < 3; ++k) p[k] = a[k] + w * ac[k];
        return refl__c3rc_len(p);
    }
    va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        refl__c3rc_sub(c, b, bc);
        for (k = 0; k < 3; ++k) p[k] = b[k] + w * bc[k];
        return refl__c3rc_len(p);
    }
    /* inside: the distance to the plane */
    refl__c3rc_cross(ab, ac, p);
    v = refl__c3rc_len(p);
    return v > 0.0 ? fabs(refl__c3rc_dot(p, a)) / v : refl__c3rc_len(a);
}

/* ---- init -------------------------------------------------------------------- */

REFL_API refl_result refl_c3rc_init(refl_c3rc *cam, const refl_vec3 v[3], const refl_vec3 d[3]) {
    double V[3][3], D[3][3], *q, len, m, t[3];
    int i, k;
    if (!cam || !v || !d) return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < 3; ++i) {
        if (!refl__c3rc_finite3(v[i]) || !refl__c3rc_finite3(d[i])) return REFL_ERROR_INVALID_ARGUMENT;
        refl__c3rc_load(d[i], D[i]);
        if (!(refl__c3rc_dot(D[i], D[i]) > 0.0)) return REFL_ERROR_INVALID_ARGUMENT;
    }
    memset(cam, 0, sizeof *cam);
    for (i = 0; i < 3; ++i) {
        /* scale first: a tiny or huge direction would under- or overflow */
        len = REFL__MAX(REFL__MAX(fabs(D[i][0]), fabs(D[i][1])), fabs(D[i][2]));
        for (k = 0; k < 3; ++k) D[i][k] /= len;
        len = refl__c3rc_len(D[i]);
        cam->v[i] = v[i];
        cam->d[i] = refl_v3((float)(D[i][0] / len), (float)(D[i][1] / len), (float)(D[i][2] / len));
        /* everything below is derived from the stored floats */
        refl__c3rc_load(cam->v[i], V[i]);
        refl__c3rc_load(cam->d[i], D[i]);
    }
    q = cam->pre;
    refl__c3rc_sub(V[1], V[0], q + REFL__C3RC_E1);
    refl__c3rc_sub(V[2], V[0], q + REFL__C3RC_E2);
    refl__c3rc_sub(D[1], D[0], q + REFL__C3RC_F1);
    refl__c3rc_sub(D[2], D[0], q + REFL__C3RC_F2);
    for (k = 0; k < 3; ++k) q[REFL__C3RC_D1 + k] = D[0][k];
    refl__c3rc_cross(q + REFL__C3RC_E1, q + REFL__C3RC_E2, q + REFL__C3RC_N0);
    refl__c3rc_cross(q + REFL__C3RC_E1, q + REFL__C3RC_F2, q + REFL__C3RC_N1);
    refl__c3rc_cross(q + REFL__C3RC_F1, q + REFL__C3RC_E2, t);
    for (k = 0; k < 3; ++k) q[REFL__C3RC_N1 + k] += t[k];
    refl__c3rc_cross(q + REFL__C3RC_F1, q + REFL__C3RC_F2, q + REFL__C3RC_N2);
    for (k = 0; k < 3; ++k) {
        q[REFL__C3RC_CTR + k] = (V[0][k] + V[1][k] + V[2][k]) / 3.0;
        q[REFL__C3RC_U + k] = q[REFL__C3RC_CTR + k] - V[0][k];
    }
    /* F(t) = (n0 + t n1 + t^2 n2) . (w + u - t d1), w = P - ctr */
    q[REFL__C3RC_M + 0] = refl__c3rc_dot(q + REFL__C3RC_N0, q + REFL__C3RC_U);
    q[REFL__C3RC_M + 1] = refl__c3rc_dot(q + REFL__C3RC_N1, q + REFL__C3RC_U) -
                          refl__c3rc_dot(q + REFL__C3RC_N0, q + REFL__C3RC_D1);
    q[REFL__C3RC_M + 2] = refl__c3rc_dot(q + REFL__C3RC_N2, q + REFL__C3RC_U) -
                          refl__c3rc_dot(q + REFL__C3RC_N1, q + REFL__C3RC_D1);
    q[REFL__C3RC_M + 3] = -refl__c3rc_dot(q + REFL__C3RC_N2, q + REFL__C3RC_D1);
    q[REFL__C3RC_R] = 0.0;
    for (i = 0; i < 3; ++i) {
        refl__c3rc_sub(V[i], q + REFL__C3RC_CTR, t);
        q[REFL__C3RC_R] = REFL__MAX(q[REFL__C3RC_R], refl__c3rc_len(t));
    }
    m = refl__c3rc_origin_distance(D[0], D[1], D[2]) * (1.0 - 1e-9);
    q[REFL__C3RC_INVM] = m * REFL__C3RC_MAX_INVM > 1.0 ? 1.0 / m : REFL__C3RC_MAX_INVM;
    {
        double le1 = refl__c3rc_len(q + REFL__C3RC_E1), le2 = refl__c3rc_len(q + REFL__C3RC_E2);
        double lf1 = refl__c3rc_len(q + REFL__C3RC_F1), lf2 = refl__c3rc_len(q + REFL__C3RC_F2);
        q[REFL__C3RC_L + 0] = le1 * le2;
        q[REFL__C3RC_L + 1] = le1 * lf2 + lf1 * le2;
        q[REFL__C3RC_L + 2] = lf1 * lf2;
    }
    q[REFL__C3RC_ULEN] = refl__c3rc_len(q + REFL__C3RC_U);
    return REFL_OK;
}

/* ---- projection -------------------------------------------------------------- */

static double refl__c3rc_eval(const double *c, double t) { return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]; }

/* The root of the cubic c in (lo, hi), where it is monotone and F(lo) has
   the sign of flo, F(hi) the other: Halley steps (cubic convergence for
   one more multiply-add; Newton where Halley's denominator is not
   positive) from the false-position point, bisection whenever a step
   leaves the bracket or does not halve the previous one (as Numerical
   Recipes' rtsafe). Done when the step is below full precision or below
   what the rounding in F allows (M bounds it): the root is only that well
   defined. */
static double refl__c3rc_root(const double *c, const double *M, double lo, double hi, double flo, double fhi) {
    double x, ax, dxold, f, df, d2f, den, xn, step, tol, floor_tol = 1e-18 * fabs(hi);
    int it;
    x = lo + (hi - lo) * (flo / (flo - fhi));
    if (!(x > lo && x < hi)) x = 0.5 * (lo + hi);
    dxold = hi - lo;
    for (it = 0; it < 100; ++it) {
        f = refl__c3rc_eval(c, x);
        if (f == 0.0) return x;
        df = (3.0 * c[3] * x + 2.0 * c[2]) * x + c[1];
        if ((f < 0.0) == (flo < 0.0)) lo = x;
        else hi = x;
        if (df != 0.0) {
            d2f = 6.0 * c[3] * x + 2.0 * c[2];
            den = 2.0 * df * df - f * d2f;
            step = den > 0.0 ? 2.0 * f * df / den : f / df;
            xn = x - step;
            ax = fabs(x);
            tol = (2.0 * DBL_EPSILON * ax + floor_tol) * fabs(df) + ((M[3] * ax + M[2]) * ax + M[1]) * ax + M[0];
            if (fabs(f) <= tol) return xn > lo && xn < hi ? xn : x;
            if (xn > lo && xn < hi && fabs(2.0 * step) < fabs(dxold)) {
                dxold = step;
                x = xn;
                continue;
            }
        }
        xn = 0.5 * (lo + hi);
        dxold = xn - x;
        if (xn <= lo || xn >= hi) return xn;
        x = xn;
    }
    return x;
}

/* Barycentrics of P (w = P - ctr) in T(t), by T(t)'s normal; 1 and the
   clamped, renormalised values when they are all >= -BARY_TOL. */
static int refl__c3rc_bary(const double *q, const double *w, double t, double *abc) {
    double E1[3], E2[3], W[3], n[3], x[3], n2, a, b, c, s;
    int k;
    for (k = 0; k < 3; ++k) {
        E1[k] = q[REFL__C3RC_E1 + k] + t * q[REFL__C3RC_F1 + k];
        E2[k] = q[REFL__C3RC_E2 + k] + t * q[REFL__C3RC_F2 + k];
        W[k] = w[k] + q[REFL__C3RC_U + k] - t * q[REFL__C3RC_D1 + k];
    }
    refl__c3rc_cross(E1, E2, n);
    n2 = refl__c3rc_dot(n, n);
    /* T(t) degenerate (a segment) to within rounding: no barycentrics */
    if (!(n2 > 1e-28 * refl__c3rc_dot(E1, E1) * refl__c3rc_dot(E2, E2) && n2 <= DBL_MAX)) return 0;
    refl__c3rc_cross(W, E2, x);
    b = refl__c3rc_dot(x, n) / n2;
    refl__c3rc_cross(E1, W, x);
    c = refl__c3rc_dot(x, n) / n2;
    a = 1.0 - b - c;
    if (!(a >= -REFL__C3RC_BARY_TOL && b >= -REFL__C3RC_BARY_TOL && c >= -REFL__C3RC_BARY_TOL)) return 0;
    a = REFL__CLAMP(a, 0.0, 1.0);
    b = REFL__CLAMP(b, 0.0, 1.0);
    c = REFL__CLAMP(c, 0.0, 1.0);
    s = a + b + c;
    abc[0] = a / s; abc[1] = b / s; abc[2] = c / s;
    return 1;
}

/* Every valid projection, ascending in t, into out; how many. */
static int refl__c3rc_project(const refl_c3rc *cam, refl_vec3 p, refl_c3rc_projection *out) {
    const double *q = cam->pre;
    double w[3], c[4], x[4], f[4], M[4], r, T, rho, disc, s, qq, r1, r2, abc[3], cand[6];
    int nx, i, n = 0, nc = 0, pos = 0, neg = 0;
    w[0] = (double)p.x - q[REFL__C3RC_CTR + 0];
    w[1] = (double)p.y - q[REFL__C3RC_CTR + 1];
    w[2] = (double)p.z - q[REFL__C3RC_CTR + 2];
    r = sqrt(refl__c3rc_dot(w, w));
    if (!(r <= DBL_MAX)) return 0; /* NaN or infinite */
    c[0] = refl__c3rc_dot(q + REFL__C3RC_N0, w) + q[REFL__C3RC_M + 0];
    c[1] = refl__c3rc_dot(q + REFL__C3RC_N1, w) + q[REFL__C3RC_M + 1];
    c[2] = refl__c3rc_dot(q + REFL__C3RC_N2, w) + q[REFL__C3RC_M + 2];
    c[3] = q[REFL__C3RC_M + 3];
    /* P = B + t D with B in the base and D in the triangle of directions:
       t |D| = |P - B| <= |P - ctr| + R, |D| >= m */
    T = (r + q[REFL__C3RC_R]) * q[REFL__C3RC_INVM] * 1.001;
    /* M: a bound on the rounding in F(t) (coefficients of a polynomial in
       |t|). A critical value within it is taken for zero, so a point at a
       double root (a fold of the volume) keeps its projection. */
    rho = r + q[REFL__C3RC_ULEN];
    M[0] = 64.0 * DBL_EPSILON * (q[REFL__C3RC_L + 0] * rho);
    M[1] = 64.0 * DBL_EPSILON * (q[REFL__C3RC_L + 1] * rho + q[REFL__C3RC_L + 0]);
    M[2] = 64.0 * DBL_EPSILON * (q[REFL__C3RC_L + 2] * rho + q[REFL__C3RC_L + 1]);
    M[3] = 64.0 * DBL_EPSILON * q[REFL__C3RC_L + 2];
    /* Like the barycentrics, t may fall short of 0 by a millionth of the
       triangle's size (reported as 0): a point on the reflector rounded to
       floats still projects. A degenerate base has no such margin; there a
       value of F(0) within rounding counts as a root at 0. */
    x[0] = -2e-6 * q[REFL__C3RC_R];
    f[0] = refl__c3rc_eval(c, x[0]);
    if (fabs(f[0]) <= ((M[3] * -x[0] + M[2]) * -x[0] + M[1]) * -x[0] + M[0]) f[0] = 0.0;
    nx = 1;
    /* critical points: 3 c3 t^2 + 2 c2 t + c1 = 0, the stable way */
    disc = c[2] * c[2] - 3.0 * c[3] * c[1];
    if (disc >= 0.0) {
        s = sqrt(disc);
        qq = -(c[2] + (c[2] >= 0.0 ? s : -s));
        if (qq != 0.0) {
            r1 = qq / (3.0 * c[3]); /* +-inf when c3 = 0: dropped below */
            r2 = c[1] / qq;
            if (r1 > r2) { s = r1; r1 = r2; r2 = s; }
            if (r1 > x[0] && r1 < T) x[nx++] = r1;
            if (r2 > x[0] && r2 < T && r2 != r1) x[nx++] = r2;
        }
    }
    for (i = 1; i < nx; ++i) {
        f[i] = refl__c3rc_eval(c, x[i]);
        if (fabs(f[i]) <= ((M[3] * x[i] + M[2]) * x[i] + M[1]) * x[i] + M[0]) f[i] = 0.0;
    }
    x[nx] = T;
    f[nx] = refl__c3rc_eval(c, T);
    for (i = 0; i <= nx; ++i) {
        pos |= f[i] > 0.0;
        neg |= f[i] < 0.0;
    }
    if (pos != neg) {
        /* one strict sign at every breakpoint: no root (the common case) */
        for (i = 0; i <= nx; ++i)
            if (f[i] == 0.0) break;
        if (i > nx) return 0;
    }
    for (i = 0; i < nx; ++i) {
        if (f[i] == 0.0) cand[nc++] = x[i];
        else if ((f[i] < 0.0 && f[i + 1] > 0.0) || (f[i] > 0.0 && f[i + 1] < 0.0))
            cand[nc++] = refl__c3rc_root(c, M, x[i], x[i + 1], f[i], f[i + 1]);
    }
    if (f[nx] == 0.0) cand[nc++] = T;
    for (i = 0; i < nc && n < 3; ++i) {
        if (!(cand[i] <= (double)FLT_MAX) || !refl__c3rc_bary(q, w, cand[i], abc)) continue;
        out[n].a = (float)abc[0];
        out[n].b = (float)abc[1];
        out[n].c = (float)abc[2];
        out[n].t = cand[i] > 0.0 ? (float)cand[i] : 0.0f;
        ++n;
    }
    return n;
}

REFL_API int refl_c3rc_project(const refl_c3rc *cam, refl_vec3 p, refl_c3rc_projection out[3]) {
    if (!cam || !out) return 0;
    return refl__c3rc_project(cam, p, out);
}

/* ---- section 5.1: where multiple projections can occur ----------------------- */

/* Ray j sits on the side s_j(t) = dj . (E1(t) x E2(t)) of T(t)'s plane,
   s_j(t) = dj.N0 + t dj.N1 + t^2 dj.N2 (the t^2 coefficient is det(d1, d2,
   d3) for every j, so for large t the signs agree unless the rays are
   coplanar). The intervals are the closed pieces of [0, tmax] between the
   roots of the three quadratics where the signs are not all one strict
   sign.

   The property (and why it holds): a point whose projections number two
   or more has ALL of them at sweep values inside the intervals; so a
   camera with no interval projects nothing twice. Proof: let t* lie
   outside every interval, so all s_j(t*) > 0, say. Ray j meets the plane
   of T(t*) once, at its vertex vj + t* dj, crossing it towards the
   positive side; so for t > t* all three vertices of T(t), hence all of
   T(t), lie strictly on the positive side, and for t < t* strictly on the
   negative side. T(t*) meets no other T(t): a point of it projects once.
   (Verified in tests/reflect/test_c3rc_camera.c over thousands of random
   convergent cameras.) It also bounds the folds of the volume: the map
   (a, b, c, t) -> P has Jacobian det(E1, E2, D) = a s1 + b s2 + c s3
   (D = a d1 + b d2 + c d3; at a projection dF/dt = -J), which cannot
   vanish outside the intervals.

   Signs within a relative 1e-12 of zero count as zero, which is neither
   strict sign: conservative for a (near-)planar sweep. */
static int refl__c3rc_intervals(const refl_c3rc *cam, double tmax, double out[4][2]) {
    const double *q = cam->pre;
    double s[3][3], dj[3], br[8], tmp[2], lo, hi, mid, scale, v, ln[3];
    int nb = 0, j, i, k, n = 0, flag, pos, neg, nr;
    ln[0] = refl__c3rc_len(q + REFL__C3RC_N0);
    ln[1] = refl__c3rc_len(q + REFL__C3RC_N1);
    ln[2] = refl__c3rc_len(q + REFL__C3RC_N2);
    for (j = 0; j < 3; ++j) {
        refl__c3rc_load(cam->d[j], dj);
        s[j][0] = refl__c3rc_dot(dj, q + REFL__C3RC_N0);
        s[j][1] = refl__c3rc_dot(dj, q + REFL__C3RC_N1);
        s[j][2] = refl__c3rc_dot(dj, q + REFL__C3RC_N2);
        nr = refl_solve_quadratic(s[j][2], s[j][1], s[j][0], tmp);
        for (i = 0; i < nr; ++i)
            if (tmp[i] > 0.0 && tmp[i] < tmax) br[nb++] = tmp[i];
    }
    /* sort the (at most 6) breakpoints */
    for (i = 1; i < nb; ++i)
        for (k = i; k > 0 && br[k - 1] > br[k]; --k) { v = br[k]; br[k] = br[k - 1]; br[k - 1] = v; }
    for (i = 0; i <= nb; ++i) {
        lo = i == 0 ? 0.0 : br[i - 1];
        hi = i == nb ? tmax : br[i];
        if (hi < lo || (hi == lo && !(i == 0 && nb == 0))) continue;
        if (hi <= DBL_MAX) mid = 0.5 * (lo + hi);
        else mid = 2.0 * lo + 1.0; /* beyond the last root: any point will do */
        scale = 1e-12 * ((ln[2] * mid + ln[1]) * mid + ln[0]);
        pos = neg = 0;
        for (j = 0; j < 3; ++j) {
            v = (s[j][2] * mid + s[j][1]) * mid + s[j][0];
            pos += v > scale;
            neg += v < -scale;
        }
        flag = !(pos == 3 || neg == 3);
        if (!flag) continue;
        if (n > 0 && out[n - 1][1] >= lo) out[n - 1][1] = hi; /* adjacent: merge */
        else if (n < 4) {
            out[n][0] = lo;
            out[n][1] = hi;
            ++n;
        }
    }
    return n;
}

REFL_API int refl_c3rc_multiple_intervals(const refl_c3rc *cam, float tmax, float out[4][2]) {
    double iv[4][2], tm;
    int n, i;
    if (!cam || !out || tmax < 0.0f) return 0;
    tm = tmax == tmax ? (double)tmax : (double)INFINITY; /* NaN: no limit */
    n = refl__c3rc_intervals(cam, tm, iv);
    for (i = 0; i < n; ++i) {
        /* rounded outwards */
        out[i][0] = (float)iv[i][0];
        if ((double)out[i][0] > iv[i][0]) out[i][0] = nextafterf(out[i][0], -INFINITY);
        out[i][1] = (float)iv[i][1];
        if ((double)out[i][1] < iv[i][1]) out[i][1] = nextafterf(out[i][1], INFINITY);
        if (out[i][0] < 0.0f) out[i][0] = 0.0f;
    }
    return n;
}

/* ---- section 5.2: box against view volume ------------------------------------ */

/* Does the segment A + l D, l in [0, lmax], meet box [lo, hi]? (slabs; in
   double, on the wall's double rulings, which refl_ray_box's floats would
   round) */
static int refl__c3rc_segment_box(const double *A, const double *D, double lmax, const double *lo, const double *hi) {
    double l0 = 0.0, l1 = lmax, a, b, inv;
    int k;
    for (k = 0; k < 3; ++k) {
        if (fabs(D[k]) < 1e-300) {
            if (A[k] < lo[k] || A[k] > hi[k]) return 0;
            continue;
        }
        inv = 1.0 / D[k];
        a = (lo[k] - A[k]) * inv;
        b = (hi[k] - A[k]) * inv;
        if (a > b) { inv = a; a = b; b = inv; }
        if (a > l0) l0 = a;
        if (b < l1) l1 = b;
        if (l0 > l1) return 0;
    }
    return 1;
}

/* Roots of A x^2 + B x + C (not all zero), the stable way; -1 when the
   polynomial vanishes identically. */
static int refl__c3rc_quadratic(double A, double B, double C, double *r) {
    double disc, s, qq;
    if (A == 0.0) {
        if (B == 0.0) return C == 0.0 ? -1 : 0;
        r[0] = -C / B;
        return 1;
    }
    disc = B * B - 4.0 * A * C;
    if (disc < 0.0) return 0;
    s = sqrt(disc);
    qq = -0.5 * (B + (B >= 0.0 ? s : -s));
    if (qq == 0.0) { r[0] = 0.0; return 1; }
    r[0] = qq / A;
    r[1] = C / qq;
    return 2;
}

/* Does the side wall S(al, l) = A(al) + l D(al), A = va + al ea, D = da +
   al fa, al in [0, 1], l in [0, T], meet box [lo, hi]? For each al the wall
   holds a segment (a ruling), and the set of feasible (al, l) is cut out of
   [0, 1] x [0, T] by six bilinear inequalities lo_k <= A_k + l D_k <= hi_k,
   each bounded by a hyperbola (or a line pair) with no vertical tangent.
   If that set is not empty, its least al is at al = 0, where two of those
   curves cross (a quadratic in al once l is eliminated), where one crosses
   l = 0 or l = T (the base edge or the top edge meets a face plane: linear),
   or on a vertical line of a degenerate curve (where D_k(al) = 0). Testing
   the ruling at each of those al is therefore exact; the box is already
   grown by the caller's tolerance. This is the paper's "wall curve against
   the four face edges" test together with the curve ends it leaves out. */
static int refl__c3rc_wall_box(const double *va, const double *vb, const double *da, const double *db, double T,
                               const double *lo, const double *hi) {
    double ea[3], fa[3], al[64], A[3], D[3], r[2], pk, pl, a;
    int n = 0, k, l, ck, cl, i, nr;
    refl__c3rc_sub(vb, va, ea);
    refl__c3rc_sub(db, da, fa);
    al[n++] = 0.0;
    al[n++] = 1.0;
    for (k = 0; k < 3; ++k) {
        if (fa[k] != 0.0) al[n++] = -da[k] / fa[k];
        for (ck = 0; ck < 2; ++ck) {
            double c = ck ? hi[k] : lo[k];
            if (ea[k] != 0.0) al[n++] = (c - va[k]) / ea[k];                                    /* l = 0 */
            if (ea[k] + T * fa[k] != 0.0) al[n++] = (c - va[k] - T * da[k]) / (ea[k] + T * fa[k]); /* l = T */
        }
    }
    for (k = 0; k < 3; ++k)
        for (l = k + 1; l < 3; ++l)
            for (ck = 0; ck < 2; ++ck)
                for (cl = 0; cl < 2; ++cl) {
                    /* (pk - al ea_k) D_l(al) - (pl - al ea_l) D_k(al) = 0 */
                    pk = (ck ? hi[k] : lo[k]) - va[k];
                    pl = (cl ? hi[l] : lo[l]) - va[l];
                    nr = refl__c3rc_quadratic(ea[l] * fa[k] - ea[k] * fa[l],
                                              pk * fa[l] - ea[k] * da[l] - pl * fa[k] + ea[l] * da[k],
                                              pk * da[l] - pl * da[k], r);
                    for (i = 0; i < nr; ++i) al[n++] = r[i];
                }
    for (i = 0; i < n; ++i) {
        a = al[i];
        if (!(a >= -1e-9 && a <= 1.0 + 1e-9)) continue;
        a = REFL__CLAMP(a, 0.0, 1.0);
        for (k = 0; k < 3; ++k) {
            A[k] = va[k] + a * ea[k];
            D[k] = da[k] + a * fa[k];
        }
        if (refl__c3rc_segment_box(A, D, T, lo, hi)) return 1;
    }
    return 0;
}

static int refl__c3rc_aabb_overlap(const double (*P)[3], int count, const double *lo, const double *hi) {
    double mn, mx;
    int i, k;
    for (k = 0; k < 3; ++k) {
        mn = mx = P[0][k];
        for (i = 1; i < count; ++i) {
            mn = REFL__MIN(mn, P[i][k]);
            mx = REFL__MAX(mx, P[i][k]);
        }
        if (mx < lo[k] || mn > hi[k]) return 0;
    }
    return 1;
}

/* The triangles T(t0) and T(t1) (six points), whose hull holds the sweep
   between them. */
static void refl__c3rc_slab(const double (*V)[3], const double (*D)[3], double t0, double t1, double (*P)[3]) {
    int i, k;
    for (i = 0; i < 3; ++i)
        for (k = 0; k < 3; ++k) {
            P[i][k] = V[i][k] + t0 * D[i][k];
            P[3 + i][k] = V[i][k] + t1 * D[i][k];
        }
}

/* Conservative box test. Let V_T be the volume swept for t in [0, T].
   Every boundary point of V_T is the image of a boundary point of the
   parameter prism (the base T(0), the top T(T), the three side walls with
   l in [0, T]) or of a fold (J = 0, see above, only at t inside the
   section 5.1 intervals): elsewhere the map is a local diffeomorphism and
   its image is interior. Suppose the box B meets V_T but
     (a) B misses the hull of T(t0) and T(t1) for every interval [t0, t1],
     (b) B misses every wall (each is tested against the whole box), and
     (c) B misses T(0) or T(T) (their bounding boxes).
   Then B meets the boundary of V_T only in one cap, say T(0) (T(T) alike);
   the cap's edges lie on the walls, so B's section by the cap's plane lies
   inside the cap. If the plane cuts B's interior, it splits B into two
   convex pieces, each missing the boundary of V_T, so each lies wholly in
   V_T or wholly outside it; near the cap (J != 0 there by (a)) V_T fills
   one side, so one piece is inside V_T, and it holds a corner of B, which
   projects with t <= T. If the plane only touches B, the touching face,
   edge or corner lies in the cap: its corners project (t = 0 or T). If B
   meets no cap at all it lies wholly inside V_T. So with (d) "no corner of
   B projects with t <= T", B cannot meet V_T.
   T is tmax, but never more than a bound on the t of any point of the box,
   which keeps every test finite. Points that project within the
   barycentric (or t) tolerance lie near V_T: the box is grown by that
   much, and the argument applies to the grown box. */
REFL_API int refl_c3rc_box_visible(const refl_c3rc *cam, refl_vec3 lo, refl_vec3 hi, float tmax) {
    const double *q;
    double blo[3], bhi[3], V[3][3], D[3][3], P[6][3], iv[4][2], far2, e, T, Tbox, delta, tc;
    refl_c3rc_projection pr[3];
    int i, k, n, j;
    if (!cam || tmax < 0.0f) return 0;
    q = cam->pre;
    refl__c3rc_load(lo, blo);
    refl__c3rc_load(hi, bhi);
    far2 = 0.0;
    for (k = 0; k < 3; ++k) {
        if (!(blo[k] - blo[k] == 0.0 && bhi[k] - bhi[k] == 0.0)) return 1; /* unbounded or NaN: maybe */
        if (blo[k] > bhi[k]) return 0;                                      /* empty */
        e = REFL__MAX(fabs(blo[k] - q[REFL__C3RC_CTR + k]), fabs(bhi[k] - q[REFL__C3RC_CTR + k]));
        far2 += e * e;
    }
    /* every point of the box projects (if at all) with t <= Tbox */
    Tbox = (sqrt(far2) + q[REFL__C3RC_R]) * q[REFL__C3RC_INVM] * 1.01;
    T = tmax == tmax && (double)tmax < Tbox ? (double)tmax : Tbox;
    delta = 10.0 * REFL__C3RC_BARY_TOL * (2.0 * q[REFL__C3RC_R] + 2.0 * T) + 1e-30;
    for (k = 0; k < 3; ++k) {
        /* grown, then rounded outwards to floats: the corners projected
           below are exactly this box's */
        float fl = (float)(blo[k] - delta), fh = (float)(bhi[k] + delta);
        if ((double)fl > blo[k] - delta) fl = nextafterf(fl, -INFINITY);
        if ((double)fh < bhi[k] + delta) fh = nextafterf(fh, INFINITY);
        if (!refl__isfinite(fl) || !refl__isfinite(fh)) return 1;
        blo[k] = fl;
        bhi[k] = fh;
    }
    for (i = 0; i < 3; ++i) {
        refl__c3rc_load(cam->v[i], V[i]);
        refl__c3rc_load(cam->d[i], D[i]);
    }
    /* the truncated volume lies in the hull of T(0) and T(T) */
    refl__c3rc_slab((const double(*)[3])V, (const double(*)[3])D, 0.0, T, P);
    if (!refl__c3rc_aabb_overlap((const double(*)[3])P, 6, blo, bhi)) return 0;
    /* (c) both caps near the box */
    if (refl__c3rc_aabb_overlap((const double(*)[3])P, 3, blo, bhi) &&
        refl__c3rc_aabb_overlap((const double(*)[3])(P + 3), 3, blo, bhi))
        return 1;
    /* a wall's corner inside: cheap, and common for small boxes */
    for (i = 0; i < 6; ++i) {
        for (k = 0; k < 3; ++k)
            if (P[i][k] < blo[k] || P[i][k] > bhi[k]) break;
        if (k == 3) return 1;
    }
    /* (a) folds */
    n = refl__c3rc_intervals(cam, T, iv);
    for (j = 0; j < n; ++j) {
        double t0 = iv[j][0], t1 = iv[j][1], pad = 1e-9 * (t1 + 2.0 * q[REFL__C3RC_R]);
        double S[6][3];
        t0 = REFL__MAX(0.0, t0 - pad);
        t1 = REFL__MIN(T, t1 + pad);
        refl__c3rc_slab((const double(*)[3])V, (const double(*)[3])D, t0, t1, S);
        if (refl__c3rc_aabb_overlap((const double(*)[3])S, 6, blo, bhi)) return 1;
    }
    /* (d) corners */
    tc = T * (1.0 + 1e-6);
    for (i = 0; i < 8; ++i) {
        refl_vec3 c = refl_v3((float)(i & 1 ? bhi[0] : blo[0]), (float)(i & 2 ? bhi[1] : blo[1]),
                              (float)(i & 4 ? bhi[2] : blo[2]));
        n = refl__c3rc_project(cam, c, pr);
        if (n > 0 && (double)pr[0].t <= tc) return 1;
    }
    /* (b) walls */
    for (i = 0; i < 3; ++i) {
        j = (i + 1) % 3;
        if (refl__c3rc_wall_box(V[i], V[j], D[i], D[j], T, blo, bhi)) return 1;
    }
    return 0;
}
