/* cam_sbc_fit: the sample-based camera's pinhole leaves (paper 003 IV,
   FitPinholeCamera and Error; docs/methods/sbc.md, "The sample-based
   camera").

   Pinhole fit: the centre of projection o is the least-squares point
   nearest every ray line (o x d = t x d per ray, solved as the normal
   equations sum(I - d d^T) o = sum(I - d d^T) t in double); the image plane
   is the least-squares plane of the tails, its normal n oriented along the
   mean ray direction. A point p maps through o onto the plane, to (u, v) in
   an orthonormal basis there; the frustum is the bounding rectangle of the
   tails' and heads' images. f(u, v), the first reflector point, is a
   quadratic (1, u, v, u^2, uv, v^2 per coordinate, u and v normalised to
   the rectangle) fitted to f(image of tail) = first and f(image of head) =
   first over every ray. The fit's error is the largest distance, in
   desired-view pixels, between the view projections of f at a tail's or
   head's image and of the ray's true first point; the camera is a leaf when
   it is below error_px. A pinhole leaf projects p as the fit maps it (z:
   p's height over the image plane).

   Beyond the paper: the fit also accepts a converging camera (o in front
   of the plane, where the rays of a concave reflector meet beyond the
   scene box; p then projects only between the plane and o), and a point
   projects when it lies no lower than the lowest tail or head (less a
   margin), not only beyond the plane: the tails of a curved patch lie on
   both sides of their least-squares plane. Large sets are tried on an even
   subsample first, so hopeless fits cost little (see refl__sbc_fit_ok).

   Also beyond the paper: f takes a third argument, the projective depth s
   = h / (h - ho) of p (0 on the plane), and adds s times an affine map of
   (u, v): a curved reflector's rays are astigmatic (they do not meet in
   one point), so a ray's points drift across the image as s grows, and
   along any line the drift is linear in s. The error is also checked
   half-way along each ray (in s), so the bound holds between a ray's ends,
   not only at them. */
#include "cam_sbc_internal.h"

/* Eigen-decomposition of a symmetric 3x3 (cyclic Jacobi): val descending,
   vec[i] the unit eigenvector of val[i]. Fixed order of operations, so the
   same on every machine. */
static void refl__sbc_eigen3(const double A[3][3], double val[3], double vec[3][3]) {
    double a[3][3], v[3][3];
    int i, j, k, sweep, p, q, order[3];
    memcpy(a, A, sizeof a);
    for (i = 0; i < 3; ++i)
        for (j = 0; j < 3; ++j) v[i][j] = i == j ? 1.0 : 0.0;
    for (sweep = 0; sweep < 32; ++sweep) {
        double off = fabs(a[0][1]) + fabs(a[0][2]) + fabs(a[1][2]);
        double diag = fabs(a[0][0]) + fabs(a[1][1]) + fabs(a[2][2]);
        if (!(off > 1e-300) || off <= 1e-18 * diag) break;
        for (p = 0; p < 2; ++p)
            for (q = p + 1; q < 3; ++q) {
                double apq = a[p][q], theta, tt, c, s;
                if (apq == 0.0) continue;
                theta = (a[q][q] - a[p][p]) / (2.0 * apq);
                tt = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                c = 1.0 / sqrt(tt * tt + 1.0);
                s = tt * c;
                for (k = 0; k < 3; ++k) { /* A <- A J */
                    double akp = a[k][p], akq = a[k][q];
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for (k = 0; k < 3; ++k) { /* A <- J^T A */
                    double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for (k = 0; k < 3; ++k) { /* V <- V J */
                    double vkp = v[k][p], vkq = v[k][q];
                    v[k][p] = c * vkp - s * vkq;
                    v[k][q] = s * vkp + c * vkq;
                }
            }
    }
    for (i = 0; i < 3; ++i) order[i] = i;
    for (i = 0; i < 2; ++i) /* descending; ties keep index order */
        for (j = i + 1; j < 3; ++j)
            if (a[order[j]][order[j]] > a[order[i]][order[i]]) { k = order[i]; order[i] = order[j]; order[j] = k; }
    for (i = 0; i < 3; ++i) {
        val[i] = a[order[i]][order[i]];
        for (k = 0; k < 3; ++k) vec[i][k] = v[k][order[i]];
        refl__sbc_normalize(vec[i]);
    }
}

/* Solves G x = R (G symmetric positive definite, k x k row-major; R k x m,
   overwritten by x) by Cholesky; 0 when a pivot falls below rel times the
   largest diagonal entry (singular to working precision). */
static int refl__sbc_cholesky(double *G, int k, double *R, int m, double rel) {
    double big = 0.0;
    int i, j, l;
    for (i = 0; i < k; ++i) big = REFL__MAX(big, G[i * k + i]);
    if (!(big > 0.0) || !refl__sbc_finite(big)) return 0;
    for (j = 0; j < k; ++j) {
        double d = G[j * k + j];
        for (l = 0; l < j; ++l) d -= G[j * k + l] * G[j * k + l];
        if (!(d > rel * big)) return 0;
        d = sqrt(d);
        G[j * k + j] = d;
        for (i = j + 1; i < k; ++i) {
            double s = G[i * k + j];
            for (l = 0; l < j; ++l) s -= G[i * k + l] * G[j * k + l];
            G[i * k + j] = s / d;
        }
    }
    for (l = 0; l < m; ++l) {
        for (i = 0; i < k; ++i) { /* L y = r */
            double s = R[i * m + l];
            for (j = 0; j < i; ++j) s -= G[i * k + j] * R[j * m + l];
            R[i * m + l] = s / G[i * k + i];
        }
        for (i = k - 1; i >= 0; --i) { /* L^T x = y */
            double s = R[i * m + l];
            for (j = i + 1; j < k; ++j) s -= G[j * k + i] * R[j * m + l];
            R[i * m + l] = s / G[i * k + i];
        }
    }
    return 1;
}

/* ---- the leaf camera --------------------------------------------------------- */

/* p's image (u, v) through o, and its height h over the image plane; 0 when
   p lies below the tails or not between o and infinity on the rays' side. */
static int refl__sbc_cam_uv(const refl__sbc_cam *k, const double *p, double *u, double *v, double *h) {
    double w[3], pc[3], hp, den, s;
    w[0] = p[0] - k->o[0]; w[1] = p[1] - k->o[1]; w[2] = p[2] - k->o[2];
    pc[0] = p[0] - k->c[0]; pc[1] = p[1] - k->c[1]; pc[2] = p[2] - k->c[2];
    hp = refl__sbc_dot(pc, k->n);
    if (!(hp >= k->hmin)) return 0;
    den = k->ho - hp;
    if (!(k->ho * den > 0.0)) return 0; /* diverging: in front of o; converging: before o */
    s = k->ho / den;
    *u = k->ocu + s * refl__sbc_dot(w, k->eu);
    *v = k->ocv + s * refl__sbc_dot(w, k->ev);
    *h = hp;
    return refl__sbc_finite(*u) && refl__sbc_finite(*v);
}

/* The projective depth of height h: 0 on the image plane, towards 1 at
   infinity (diverging), negative before o (converging). Along any line,
   a point's image moves linearly in it. */
static double refl__sbc_cam_s(const refl__sbc_cam *k, double h) { return h / (h - k->ho); }

static void refl__sbc_basis(const refl__sbc_cam *k, double u, double v, double s, double b[12]) {
    double x = (u - k->norm[0]) * k->norm[2], y = (v - k->norm[1]) * k->norm[3];
    b[0] = 1.0; b[1] = x; b[2] = y; b[3] = x * x; b[4] = x * y; b[5] = y * y;
    b[6] = s; b[7] = s * x; b[8] = s * y; b[9] = s * b[3]; b[10] = s * b[4]; b[11] = s * b[5];
}

/* f(u, v, s), as returned */
static refl_vec3 refl__sbc_cam_eval(const refl__sbc_cam *k, double u, double v, double s) {
    double b[12], f[3];
    int i, j;
    refl__sbc_basis(k, u, v, s, b);
    for (i = 0; i < 3; ++i) {
        f[i] = 0.0;
        for (j = 0; j < 12; ++j) f[i] += k->coef[i][j] * b[j];
    }
    return refl_v3((float)f[0], (float)f[1], (float)f[2]);
}

static int refl__sbc_cam_project(const refl__sbc_cam *k, const double *p, refl_vec3 *first, float *z) {
    double u, v, h;
    if (!refl__sbc_cam_uv(k, p, &u, &v, &h)) return 0;
    if (!(u >= k->rect[0] && u <= k->rect[1] && v >= k->rect[2] && v <= k->rect[3])) return 0;
    *first = refl__sbc_cam_eval(k, u, v, refl__sbc_cam_s(k, h));
    *z = (float)REFL__MAX(h, 0.0);
    return 1;
}

/* ---- fitting ------------------------------------------------------------------ */

/* Desired-view pixel of a world point; 0 behind the eye. */
static int refl__sbc_pixel(const refl__sbc_builder *b, const double *p, double *x, double *y) {
    const double *m = b->vp;
    double cx = m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12];
    double cy = m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13];
    double cw = m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15];
    if (!(cw > 0.0)) return 0;
    *x = (cx / cw + 1.0) * 0.5 * (double)b->width;
    *y = (1.0 - cy / cw) * 0.5 * (double)b->height;
    return refl__sbc_finite(*x) && refl__sbc_finite(*y);
}

/* f over the images (u, v, s: 3 per sample, tail then head per ray) of
   the set's rays, by the normal equations: the quadratic in (u, v) plus
   s times an affine one, or when that is singular its leading blocks (the
   quadratic, the affine, the constant). 0 when nothing fits. */
static int refl__sbc_fit_map(const refl__sbc_builder *b, const int *list, int n, const double *uv,
                             refl__sbc_cam *k) {
    static const int orders[5] = {12, 9, 6, 3, 1};
    double qc[3] = {0.0, 0.0, 0.0}, G9[144], R9[36];
    int o, i, j, l, e;
    for (i = 0; i < n; ++i) {
        refl_vec3 q = b->rays[list[i]].first;
        qc[0] += q.x; qc[1] += q.y; qc[2] += q.z;
    }
    for (j = 0; j < 3; ++j) qc[j] /= (double)n;
    memset(G9, 0, sizeof G9);
    memset(R9, 0, sizeof R9);
    for (i = 0; i < n; ++i) {
        refl_vec3 f = b->rays[list[i]].first;
        double q[3];
        /* centred: the coefficients carry only the variation */
        q[0] = (double)f.x - qc[0];
        q[1] = (double)f.y - qc[1];
        q[2] = (double)f.z - qc[2];
        for (e = 0; e < 3; ++e) {
            /* tail, head, and half-way (in s) between: the ends alone
               leave f free to bow along the ray */
            const double *t = uv + 6 * i, *h = t + 3;
            double bs[12];
            if (e < 2) refl__sbc_basis(k, t[3 * e], t[3 * e + 1], t[3 * e + 2], bs);
            else refl__sbc_basis(k, 0.5 * (t[0] + h[0]), 0.5 * (t[1] + h[1]), 0.5 * (t[2] + h[2]), bs);
            for (j = 0; j < 12; ++j) {
                for (l = 0; l <= j; ++l) G9[j * 12 + l] += bs[j] * bs[l];
                for (l = 0; l < 3; ++l) R9[j * 3 + l] += bs[j] * q[l];
            }
        }
    }
    for (o = 0; o < 5; ++o) {
        int nb = orders[o];
        double G[144], R[36];
        for (j = 0; j < nb; ++j) {
            for (l = 0; l <= j; ++l) G[j * nb + l] = G[l * nb + j] = G9[j * 12 + l];
            for (l = 0; l < 3; ++l) R[j * 3 + l] = R9[j * 3 + l];
        }
        if (refl__sbc_cholesky(G, nb, R, 3, 1e-11)) {
            memset(k->coef, 0, sizeof k->coef);
            for (l = 0; l < 3; ++l) {
                for (j = 0; j < nb; ++j) k->coef[l][j] = R[j * 3 + l];
                k->coef[l][0] += qc[l];
            }
            return 1;
        }
    }
    return 0;
}

static void refl__sbc_centroid(const refl__sbc_builder *b, const int *list, int n, double c[3], double m[3]) {
    int i, j;
    c[0] = c[1] = c[2] = 0.0;
    m[0] = m[1] = m[2] = 0.0;
    for (i = 0; i < n; ++i) {
        const refl_sbc_ray *r = &b->rays[list[i]];
        const float *d = b->dir + 3 * (size_t)list[i];
        c[0] += r->tail.x; c[1] += r->tail.y; c[2] += r->tail.z;
        m[0] += d[0]; m[1] += d[1]; m[2] += d[2];
    }
    for (j = 0; j < 3; ++j) c[j] /= (double)n;
}

/* The centre of projection o, the least-squares point nearest every ray
   line: sum (I - d d^T) (o - c) = sum (I - d d^T) (t - c), relative to the
   tails' centroid c for precision; C (may be NULL) gets the tails' scatter
   about c. 0 when the rays are (nearly) parallel: no finite centre. */
static int refl__sbc_centre(const refl__sbc_builder *b, const int *list, int n, const double c[3], double o[3],
                            double C[3][3]) {
    double A[9], rhs[3], S[3][3];
    int i, j, l;
    memset(A, 0, sizeof A);
    memset(rhs, 0, sizeof rhs);
    memset(S, 0, sizeof S);
    for (i = 0; i < n; ++i) {
        const refl_sbc_ray *r = &b->rays[list[i]];
        const float *d = b->dir + 3 * (size_t)list[i];
        double t[3], dd[3], td;
        t[0] = r->tail.x - c[0]; t[1] = r->tail.y - c[1]; t[2] = r->tail.z - c[2];
        dd[0] = d[0]; dd[1] = d[1]; dd[2] = d[2];
        td = refl__sbc_dot(t, dd);
        for (j = 0; j < 3; ++j) {
            for (l = 0; l <= j; ++l) {
                A[j * 3 + l] -= dd[j] * dd[l];
                S[j][l] += t[j] * t[l];
            }
            rhs[j] += t[j] - dd[j] * td;
        }
    }
    for (j = 0; j < 3; ++j) {
        A[j * 3 + j] += (double)n;
        for (l = 0; l < j; ++l) {
            A[l * 3 + j] = A[j * 3 + l];
            S[l][j] = S[j][l];
        }
    }
    if (C) memcpy(C, S, sizeof S);
    if (!refl__sbc_cholesky(A, 3, rhs, 1, 1e-12)) return 0;
    for (j = 0; j < 3; ++j) o[j] = c[j] + rhs[j];
    return 1;
}

/* FitPinholeCamera, then Error: the largest desired-view pixel distance,
   at the set's tails and heads, between the camera's first point and the
   true one, through the very projection refl_sbc_project uses. Stops at
   the first distance over `limit` and returns it; INFINITY when no camera
   can be fitted at all. uv: scratch for 6 n doubles. */
static double refl__sbc_fit(const refl__sbc_builder *b, const int *list, int n, double limit, double *uv,
                            refl__sbc_cam *k) {
    double C[3][3], val[3], vec[3][3], m[3], c[3], ext, hlo, tlo, thi, worst = 0.0;
    int i, j, e;
    if (n < 2) return INFINITY;
    memset(k, 0, sizeof *k);
    refl__sbc_centroid(b, list, n, c, m);
    if (!(refl__sbc_normalize(m) > 1e-6 * (double)n)) return INFINITY; /* the rays cancel: no mean direction */
    /* parallel rays: no finite centre (and no pinhole) */
    if (!refl__sbc_centre(b, list, n, c, k->o, C)) return INFINITY;
    memcpy(k->c, c, sizeof k->c);
    /* image plane: the tails' least-squares plane; where the tails are too
       thin to define one, the plane through their principal axis facing
       the rays as much as it can */
    refl__sbc_eigen3((const double(*)[3])C, val, vec);
    memcpy(k->n, vec[2], sizeof k->n);
    if (refl__sbc_dot(k->n, m) < 0.0)
        for (j = 0; j < 3; ++j) k->n[j] = -k->n[j];
    if (!(val[1] > 4.0 * val[2]) || refl__sbc_dot(k->n, m) < 0.05) {
        double dm = refl__sbc_dot(m, vec[0]);
        for (j = 0; j < 3; ++j) k->n[j] = val[0] > 4.0 * val[1] ? m[j] - dm * vec[0][j] : m[j];
        if (!(refl__sbc_normalize(k->n) > 1e-3)) memcpy(k->n, m, sizeof k->n);
    }
    /* u along the principal axis (a tight rectangle), v completing the frame */
    {
        double dn = refl__sbc_dot(vec[0], k->n);
        for (j = 0; j < 3; ++j) k->eu[j] = vec[0][j] - dn * k->n[j];
        if (!(refl__sbc_normalize(k->eu) > 1e-3)) {
            double ax[3] = {0.0, 0.0, 0.0};
            int best = 0;
            for (j = 1; j < 3; ++j)
                if (fabs(k->n[j]) < fabs(k->n[best])) best = j;
            ax[best] = 1.0;
            refl__sbc_cross(k->n, ax, k->eu);
            refl__sbc_normalize(k->eu);
        }
        refl__sbc_cross(k->n, k->eu, k->ev);
    }
    {
        double oc[3];
        for (j = 0; j < 3; ++j) oc[j] = k->o[j] - k->c[j];
        k->ho = refl__sbc_dot(oc, k->n);
        k->ocu = refl__sbc_dot(oc, k->eu);
        k->ocv = refl__sbc_dot(oc, k->ev);
        ext = sqrt(val[0] + val[1] + val[2]) + sqrt(refl__sbc_dot(oc, oc));
        if (!(fabs(k->ho) > 1e-9 * ext)) return INFINITY; /* o on the image plane */
    }
    /* the lowest tail or head bounds what projects, less a margin for the
       reflector between the tails (below them where it is concave) */
    hlo = tlo = DBL_MAX;
    thi = -DBL_MAX;
    for (i = 0; i < n; ++i) {
        const refl_sbc_ray *r = &b->rays[list[i]];
        for (e = 0; e < 2; ++e) {
            double p[3], pc[3], h;
            refl__sbc_load(e ? r->head : r->tail, p);
            for (j = 0; j < 3; ++j) pc[j] = p[j] - k->c[j];
            h = refl__sbc_dot(pc, k->n);
            hlo = REFL__MIN(hlo, h);
            if (e == 0) {
                tlo = REFL__MIN(tlo, h);
                thi = REFL__MAX(thi, h);
            }
        }
    }
    k->hmin = hlo - 0.25 * (thi - tlo) - 1e-9 * ext;
    /* the frustum: the images' bounding rectangle */
    k->rect[0] = k->rect[2] = DBL_MAX;
    k->rect[1] = k->rect[3] = -DBL_MAX;
    for (i = 0; i < n; ++i) {
        const refl_sbc_ray *r = &b->rays[list[i]];
        for (e = 0; e < 2; ++e) {
            double p[3], u, v, h;
            refl__sbc_load(e ? r->head : r->tail, p);
            if (!refl__sbc_cam_uv(k, p, &u, &v, &h)) return INFINITY; /* a ray on the wrong side of o */
            uv[6 * i + 3 * e] = u;
            uv[6 * i + 3 * e + 1] = v;
            uv[6 * i + 3 * e + 2] = refl__sbc_cam_s(k, h);
            k->rect[0] = REFL__MIN(k->rect[0], u);
            k->rect[1] = REFL__MAX(k->rect[1], u);
            k->rect[2] = REFL__MIN(k->rect[2], v);
            k->rect[3] = REFL__MAX(k->rect[3], v);
        }
    }
    {
        /* a hair wider: the same points must land inside however the
           compiler contracts the arithmetic */
        double wu = k->rect[1] - k->rect[0], wv = k->rect[3] - k->rect[2], pad = 1e-9 * (wu + wv + ext);
        k->rect[0] -= pad; k->rect[1] += pad; k->rect[2] -= pad; k->rect[3] += pad;
        k->norm[0] = 0.5 * (k->rect[0] + k->rect[1]);
        k->norm[1] = 0.5 * (k->rect[2] + k->rect[3]);
        k->norm[2] = 2.0 / (k->rect[1] - k->rect[0]);
        k->norm[3] = 2.0 / (k->rect[3] - k->rect[2]);
    }
    if (!refl__sbc_fit_map(b, list, n, uv, k)) return INFINITY;
    if (!(b->error_px <= DBL_MAX)) return 0.0; /* no error bound: any camera will do */
    for (i = 0; i < n; ++i) {
        const double *tp = b->truth + 2 * (size_t)list[i];
        if (!refl__sbc_finite(tp[0])) return INFINITY; /* its first point is behind the eye */
        for (e = 0; e < 3; ++e) {
            /* refl_sbc_project's steps: the same (u, v, s), inside the
               rectangle built from it, above hmin, then f; beyond the
               paper, also half-way along the ray (in s, along which the
               image moves linearly), so the bound holds between the ends */
            const double *t = uv + 6 * i, *h = t + 3;
            double q[3], x, y, d, w[3];
            for (j = 0; j < 3; ++j) w[j] = e == 0 ? t[j] : e == 1 ? h[j] : 0.5 * (t[j] + h[j]);
            refl__sbc_load(refl__sbc_cam_eval(k, w[0], w[1], w[2]), q);
            if (!refl__sbc_pixel(b, q, &x, &y)) return INFINITY;
            d = sqrt((x - tp[0]) * (x - tp[0]) + (y - tp[1]) * (y - tp[1]));
            if (!(d <= limit)) return refl__sbc_finite(d) ? d : INFINITY;
            worst = REFL__MAX(worst, d);
        }
    }
    return worst;
}

/* 1 when a camera fits the set with an error below error_px. A large set
   is first tried on an even subsample: the least-squares fit to fewer rays
   fits them at least about as well, so a subsample error far over the
   bound means the whole set fails too, at a fraction of the cost (a wrong
   guess only costs a split; every accepted camera is checked in full). */
static int refl__sbc_fit_ok(refl__sbc_builder *b, const int *list, int n, refl__sbc_cam *k) {
    enum { SUB = 32 };
    if (n > 2 * SUB && b->error_px <= DBL_MAX) {
        int sub[SUB], i;
        for (i = 0; i < SUB; ++i) sub[i] = list[(int)(((long long)i * n + n / 2) / SUB)];
        if (!(refl__sbc_fit(b, sub, SUB, 2.0 * b->error_px, b->uv, k) <= 2.0 * b->error_px)) return 0;
    }
    return refl__sbc_fit(b, list, n, b->error_px, b->uv, k) < b->error_px;
}
