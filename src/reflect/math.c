/* Math: vectors, column-major 4x4 matrices with GL's conventions,
   quaternions, the robust quadratic and cubic solvers, least squares by
   Householder QR, and the deterministic random numbers.

   SOLVERS
       Coefficients are rescaled by powers of two (exact) before anything is
       squared, so 1e150 or 1e-150 coefficients neither overflow nor
       underflow. The quadratic uses q = -(b + sign(b) sqrt(disc)) / 2 and
       the roots q / a and c / q (no cancellation); its discriminant is
       computed with exact products (Dekker's two-product), so a distinct
       pair of close roots stays distinct. A negative discriminant that is
       within rounding of zero is a double root. A vanishing leading
       coefficient is no special case beyond a == 0: the near roots stay
       accurate and the far root is returned while it is representable.
       The cubic is Kahan's QBC: substitute x = 2^k y so every root has
       |y| <= 1 (Fujiwara's bound; Horner never overflows), find one real
       root by Newton's method from outside (monotone), deflate forwards or
       backwards (whichever is stable for that root), solve the quadratic,
       then polish every root with at most two guarded Newton steps.

   LEAST SQUARES
       Columns are equilibrated (scaled by a power of two close to their
       norms), then Householder QR with column pivoting; the condition
       estimate is max |r_ii| / min |r_ii| of the pivoted R, which with
       pivoting is a cheap and usually tight estimate of cond(A D). */
#include "internal.h"

/* ---- vectors ---------------------------------------------------------- */

REFL_API refl_vec3 refl_v3(float x, float y, float z) {
    refl_vec3 v;
    v.x = x; v.y = y; v.z = z;
    return v;
}

REFL_API refl_vec3 refl_v3_add(refl_vec3 a, refl_vec3 b) { return refl_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
REFL_API refl_vec3 refl_v3_sub(refl_vec3 a, refl_vec3 b) { return refl_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
REFL_API refl_vec3 refl_v3_scale(refl_vec3 a, float s) { return refl_v3(a.x * s, a.y * s, a.z * s); }
REFL_API float refl_v3_dot(refl_vec3 a, refl_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

REFL_API refl_vec3 refl_v3_cross(refl_vec3 a, refl_vec3 b) {
    return refl_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

/* In double: no overflow for large floats, and correctly rounded sqrt. */
REFL_API float refl_v3_length(refl_vec3 a) {
    double x = a.x, y = a.y, z = a.z;
    return (float)sqrt(x * x + y * y + z * z);
}

REFL_API refl_vec3 refl_v3_normalize(refl_vec3 a) {
    double x = a.x, y = a.y, z = a.z, l = sqrt(x * x + y * y + z * z);
    if (!(l > 0.0) || l > DBL_MAX) return l > DBL_MAX ? a : refl_v3(0.0f, 0.0f, 0.0f);
    return refl_v3((float)(x / l), (float)(y / l), (float)(z / l));
}

REFL_API refl_vec3 refl_v3_reflect(refl_vec3 d, refl_vec3 n) {
    return refl_v3_sub(d, refl_v3_scale(n, 2.0f * refl_v3_dot(d, n)));
}

/* GLSL's refract(I, N, eta). */
REFL_API int refl_v3_refract(refl_vec3 d, refl_vec3 n, float eta, refl_vec3 *out) {
    float c = refl_v3_dot(n, d);
    float k = 1.0f - eta * eta * (1.0f - c * c);
    if (k < 0.0f) return 0;
    if (out) *out = refl_v3_sub(refl_v3_scale(d, eta), refl_v3_scale(n, eta * c + sqrtf(k)));
    return 1;
}

/* ---- rays and boxes ---------------------------------------------------- */

/* Slabs: per axis dir moves along, the t where the ray crosses the box's
   two planes; the ray is in the box from the latest entry to the earliest
   exit. An axis dir does not move along only checks origin. The far
   plane's t is computed as (plane - origin) / dir whichever side it is on,
   so a caller that wants only where a ray from inside leaves gets exactly
   that quotient. */
REFL_API int refl_ray_box(refl_vec3 origin, refl_vec3 dir, refl_vec3 lo, refl_vec3 hi, float *t_in, float *t_out) {
    float oo[3] = {origin.x, origin.y, origin.z}, dd[3] = {dir.x, dir.y, dir.z};
    float a[3] = {lo.x, lo.y, lo.z}, b[3] = {hi.x, hi.y, hi.z};
    float t0 = 0.0f, t1 = INFINITY;
    int k, inside = 1;
    for (k = 0; k < 3; ++k) {
        float ta, tb;
        if (dd[k] == 0.0f) {
            if (oo[k] < a[k] || oo[k] > b[k]) inside = 0;
            continue;
        }
        ta = (a[k] - oo[k]) / dd[k];
        tb = (b[k] - oo[k]) / dd[k];
        t0 = REFL__MAX(t0, REFL__MIN(ta, tb));
        t1 = REFL__MIN(t1, REFL__MAX(ta, tb));
    }
    if (t_in) *t_in = t0;
    if (t_out) *t_out = t1;
    return inside && t0 <= t1;
}

/* ---- matrices ---------------------------------------------------------- */

REFL_API refl_mat4 refl_mat4_identity(void) {
    refl_mat4 r;
    memset(&r, 0, sizeof r);
    r.m[0] = r.m[5] = r.m[10] = r.m[15] = 1.0f;
    return r;
}

REFL_API refl_mat4 refl_mat4_mul(refl_mat4 a, refl_mat4 b) {
    refl_mat4 r;
    int c, i, k;
    for (c = 0; c < 4; ++c)
        for (i = 0; i < 4; ++i) {
            float s = 0.0f;
            for (k = 0; k < 4; ++k) s += a.m[k * 4 + i] * b.m[c * 4 + k];
            r.m[c * 4 + i] = s;
        }
    return r;
}

REFL_API refl_mat4 refl_mat4_translate(refl_vec3 t) {
    refl_mat4 r = refl_mat4_identity();
    r.m[12] = t.x; r.m[13] = t.y; r.m[14] = t.z;
    return r;
}

REFL_API refl_mat4 refl_mat4_scale(refl_vec3 s) {
    refl_mat4 r = refl_mat4_identity();
    r.m[0] = s.x; r.m[5] = s.y; r.m[10] = s.z;
    return r;
}

/* glRotate: counter-clockwise about the axis (normalised; a zero axis
   gives the identity). */
REFL_API refl_mat4 refl_mat4_rotate(refl_vec3 axis, float radians) {
    refl_mat4 r = refl_mat4_identity();
    refl_vec3 u = refl_v3_normalize(axis);
    double c = cos((double)radians), s = sin((double)radians), t = 1.0 - c;
    double x = u.x, y = u.y, z = u.z;
    if (u.x == 0.0f && u.y == 0.0f && u.z == 0.0f) return r;
    r.m[0] = (float)(x * x * t + c);
    r.m[1] = (float)(y * x * t + z * s);
    r.m[2] = (float)(x * z * t - y * s);
    r.m[4] = (float)(x * y * t - z * s);
    r.m[5] = (float)(y * y * t + c);
    r.m[6] = (float)(y * z * t + x * s);
    r.m[8] = (float)(x * z * t + y * s);
    r.m[9] = (float)(y * z * t - x * s);
    r.m[10] = (float)(z * z * t + c);
    return r;
}

/* The rotation of q / |q| (2 / |q|^2 instead of 2); zero: identity. */
REFL_API refl_mat4 refl_mat4_from_quat(refl_quat q) {
    refl_mat4 r = refl_mat4_identity();
    double x = q.x, y = q.y, z = q.z, w = q.w, n = x * x + y * y + z * z + w * w, s;
    if (!(n > 0.0) || n > DBL_MAX) return r;
    s = 2.0 / n;
    r.m[0] = (float)(1.0 - s * (y * y + z * z));
    r.m[1] = (float)(s * (x * y + z * w));
    r.m[2] = (float)(s * (x * z - y * w));
    r.m[4] = (float)(s * (x * y - z * w));
    r.m[5] = (float)(1.0 - s * (x * x + z * z));
    r.m[6] = (float)(s * (y * z + x * w));
    r.m[8] = (float)(s * (x * z + y * w));
    r.m[9] = (float)(s * (y * z - x * w));
    r.m[10] = (float)(1.0 - s * (x * x + y * y));
    return r;
}

/* Cofactor inverse in double. Singular when det is 0, not finite, or tiny
   against Hadamard's bound (the product of the row norms, >= |det|): the
   ratio is scale-free, so diag(1e-6, ...) inverts and a nearly dependent
   row set does not. */
REFL_API int refl_mat4_invert(refl_mat4 a, refl_mat4 *out) {
    double m[16], inv[16], det, bound = 1.0;
    int i, r;
    for (i = 0; i < 16; ++i) m[i] = a.m[i];
    for (r = 0; r < 4; ++r)
        bound *= sqrt(m[r] * m[r] + m[4 + r] * m[4 + r] + m[8 + r] * m[8 + r] + m[12 + r] * m[12 + r]);
    inv[0] = m[5] * m[10] * m[15] - m[5] * m[11] * m[14] - m[9] * m[6] * m[15] + m[9] * m[7] * m[14] +
             m[13] * m[6] * m[11] - m[13] * m[7] * m[10];
    inv[4] = -m[4] * m[10] * m[15] + m[4] * m[11] * m[14] + m[8] * m[6] * m[15] - m[8] * m[7] * m[14] -
             m[12] * m[6] * m[11] + m[12] * m[7] * m[10];
    inv[8] = m[4] * m[9] * m[15] - m[4] * m[11] * m[13] - m[8] * m[5] * m[15] + m[8] * m[7] * m[13] +
             m[12] * m[5] * m[11] - m[12] * m[7] * m[9];
    inv[12] = -m[4] * m[9] * m[14] + m[4] * m[10] * m[13] + m[8] * m[5] * m[14] - m[8] * m[6] * m[13] -
              m[12] * m[5] * m[10] + m[12] * m[6] * m[9];
    inv[1] = -m[1] * m[10] * m[15] + m[1] * m[11] * m[14] + m[9] * m[2] * m[15] - m[9] * m[3] * m[14] -
             m[13] * m[2] * m[11] + m[13] * m[3] * m[10];
    inv[5] = m[0] * m[10] * m[15] - m[0] * m[11] * m[14] - m[8] * m[2] * m[15] + m[8] * m[3] * m[14] +
             m[12] * m[2] * m[11] - m[12] * m[3] * m[10];
    inv[9] = -m[0] * m[9] * m[15] + m[0] * m[11] * m[13] + m[8] * m[1] * m[15] - m[8] * m[3] * m[13] -
             m[12] * m[1] * m[11] + m[12] * m[3] * m[9];
    inv[13] = m[0] * m[9] * m[14] - m[0] * m[10] * m[13] - m[8] * m[1] * m[14] + m[8] * m[2] * m[13] +
              m[12] * m[1] * m[10] - m[12] * m[2] * m[9];
    inv[2] = m[1] * m[6] * m[15] - m[1] * m[7] * m[14] - m[5] * m[2] * m[15] + m[5] * m[3] * m[14] +
             m[13] * m[2] * m[7] - m[13] * m[3] * m[6];
    inv[6] = -m[0] * m[6] * m[15] + m[0] * m[7] * m[14] + m[4] * m[2] * m[15] - m[4] * m[3] * m[14] -
             m[12] * m[2] * m[7] + m[12] * m[3] * m[6];
    inv[10] = m[0] * m[5] * m[15] - m[0] * m[7] * m[13] - m[4] * m[1] * m[15] + m[4] * m[3] * m[13] +
              m[12] * m[1] * m[7] - m[12] * m[3] * m[5];
    inv[14] = -m[0] * m[5] * m[14] + m[0] * m[6] * m[13] + m[4] * m[1] * m[14] - m[4] * m[2] * m[13] -
              m[12] * m[1] * m[6] + m[12] * m[2] * m[5];
    inv[3] = -m[1] * m[6] * m[11] + m[1] * m[7] * m[10] + m[5] * m[2] * m[11] - m[5] * m[3] * m[10] -
             m[9] * m[2] * m[7] + m[9] * m[3] * m[6];
    inv[7] = m[0] * m[6] * m[11] - m[0] * m[7] * m[10] - m[4] * m[2] * m[11] + m[4] * m[3] * m[10] +
             m[8] * m[2] * m[7] - m[8] * m[3] * m[6];
    inv[11] = -m[0] * m[5] * m[11] + m[0] * m[7] * m[9] + m[4] * m[1] * m[11] - m[4] * m[3] * m[9] -
              m[8] * m[1] * m[7] + m[8] * m[3] * m[5];
    inv[15] = m[0] * m[5] * m[10] - m[0] * m[6] * m[9] - m[4] * m[1] * m[10] + m[4] * m[2] * m[9] +
              m[8] * m[1] * m[6] - m[8] * m[2] * m[5];
    det = m[0] * inv[0] + m[1] * inv[4] + m[2] * inv[8] + m[3] * inv[12];
    if (!(fabs(det) > 1e-10 * bound) || !(fabs(det) <= DBL_MAX) || !(bound <= DBL_MAX)) return 0;
    {
        refl_mat4 res;
        for (i = 0; i < 16; ++i) {
            double v = inv[i] / det;
            if (!(fabs(v) <= FLT_MAX)) return 0; /* not representable in float */
            res.m[i] = (float)v;
        }
        if (out) *out = res;
    }
    return 1;
}

REFL_API refl_mat4 refl_mat4_transpose(refl_mat4 a) {
    refl_mat4 r;
    int c, i;
    for (c = 0; c < 4; ++c)
        for (i = 0; i < 4; ++i) r.m[i * 4 + c] = a.m[c * 4 + i];
    return r;
}

/* w = 1 in, divided by the resulting w unless it is 0 or 1. */
REFL_API refl_vec3 refl_mat4_point(refl_mat4 a, refl_vec3 p) {
    const float *m = a.m;
    float x = m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12];
    float y = m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13];
    float z = m[2] * p.x + m[6] * p.y + m[10] * p.z + m[14];
    float w = m[3] * p.x + m[7] * p.y + m[11] * p.z + m[15];
    if (w != 1.0f && w != 0.0f) {
        x /= w; y /= w; z /= w;
    }
    return refl_v3(x, y, z);
}

REFL_API refl_vec3 refl_mat4_dir(refl_mat4 a, refl_vec3 d) {
    const float *m = a.m;
    return refl_v3(m[0] * d.x + m[4] * d.y + m[8] * d.z, m[1] * d.x + m[5] * d.y + m[9] * d.z,
                   m[2] * d.x + m[6] * d.y + m[10] * d.z);
}

/* gluPerspective: f = cot(fovy / 2). */
REFL_API refl_mat4 refl_mat4_perspective(float fovy_radians, float aspect, float znear, float zfar) {
    refl_mat4 r;
    double f = 1.0 / tan(0.5 * (double)fovy_radians), nf = (double)znear - (double)zfar;
    memset(&r, 0, sizeof r);
    r.m[0] = (float)(f / aspect);
    r.m[5] = (float)f;
    r.m[10] = (float)(((double)zfar + znear) / nf);
    r.m[11] = -1.0f;
    r.m[14] = (float)(2.0 * zfar * znear / nf);
    return r;
}

/* gluLookAt: rows s, u, -f, then the translation by -eye. */
REFL_API refl_mat4 refl_mat4_look_at(refl_vec3 eye, refl_vec3 target, refl_vec3 up) {
    refl_mat4 r = refl_mat4_identity();
    refl_vec3 f = refl_v3_normalize(refl_v3_sub(target, eye));
    refl_vec3 s = refl_v3_normalize(refl_v3_cross(f, up));
    refl_vec3 u = refl_v3_cross(s, f);
    r.m[0] = s.x; r.m[4] = s.y; r.m[8] = s.z;
    r.m[1] = u.x; r.m[5] = u.y; r.m[9] = u.z;
    r.m[2] = -f.x; r.m[6] = -f.y; r.m[10] = -f.z;
    r.m[12] = -refl_v3_dot(s, eye);
    r.m[13] = -refl_v3_dot(u, eye);
    r.m[14] = refl_v3_dot(f, eye);
    return r;
}

/* ---- quaternions -------------------------------------------------------- */

static refl_quat refl__quat(double x, double y, double z, double w) {
    refl_quat q;
    q.x = (float)x; q.y = (float)y; q.z = (float)z; q.w = (float)w;
    return q;
}

/* Zero axis: the identity. */
REFL_API refl_quat refl_quat_axis_angle(refl_vec3 axis, float radians) {
    refl_vec3 u = refl_v3_normalize(axis);
    double s = sin(0.5 * (double)radians), c = cos(0.5 * (double)radians);
    if (u.x == 0.0f && u.y == 0.0f && u.z == 0.0f) return refl__quat(0, 0, 0, 1);
    return refl__quat(u.x * s, u.y * s, u.z * s, c);
}

/* Hamilton product: rotating by the result is rotating by b, then a. */
REFL_API refl_quat refl_quat_mul(refl_quat a, refl_quat b) {
    return refl__quat((double)a.w * b.x + (double)a.x * b.w + (double)a.y * b.z - (double)a.z * b.y,
                      (double)a.w * b.y - (double)a.x * b.z + (double)a.y * b.w + (double)a.z * b.x,
                      (double)a.w * b.z + (double)a.x * b.y - (double)a.y * b.x + (double)a.z * b.w,
                      (double)a.w * b.w - (double)a.x * b.x - (double)a.y * b.y - (double)a.z * b.z);
}

/* Zero (or not finite) gives the identity. */
REFL_API refl_quat refl_quat_normalize(refl_quat q) {
    double x = q.x, y = q.y, z = q.z, w = q.w, n = sqrt(x * x + y * y + z * z + w * w);
    if (!(n > 0.0) || n > DBL_MAX) return refl__quat(0, 0, 0, 1);
    return refl__quat(x / n, y / n, z / n, w / n);
}

/* v + 2 w (u x v) + 2 u x (u x v) for the normalised q = (u, w). */
REFL_API refl_vec3 refl_quat_rotate(refl_quat q, refl_vec3 v) {
    double x = q.x, y = q.y, z = q.z, w = q.w, n = sqrt(x * x + y * y + z * z + w * w);
    double tx, ty, tz;
    if (!(n > 0.0) || n > DBL_MAX) return v;
    x /= n; y /= n; z /= n; w /= n;
    tx = 2.0 * (y * v.z - z * v.y);
    ty = 2.0 * (z * v.x - x * v.z);
    tz = 2.0 * (x * v.y - y * v.x);
    return refl_v3((float)(v.x + w * tx + (y * tz - z * ty)), (float)(v.y + w * ty + (z * tx - x * tz)),
                   (float)(v.z + w * tz + (x * ty - y * tx)));
}

/* The angle comes from atan2(|a - b|, |a + b|), accurate for nearly equal
   quaternions where acos(dot) is not; below 1e-9 rad the weights are the
   linear ones to double precision anyway. */
REFL_API refl_quat refl_quat_slerp(refl_quat qa, refl_quat qb, float t) {
    refl_quat na = refl_quat_normalize(qa), nb = refl_quat_normalize(qb);
    double a[4], b[4], d = 0.0, dm = 0.0, ds = 0.0, theta, wa, wb, r[4];
    int i;
    a[0] = na.x; a[1] = na.y; a[2] = na.z; a[3] = na.w;
    b[0] = nb.x; b[1] = nb.y; b[2] = nb.z; b[3] = nb.w;
    for (i = 0; i < 4; ++i) d += a[i] * b[i];
    if (d < 0.0) /* q and -q are the same rotation: take the short way */
        for (i = 0; i < 4; ++i) b[i] = -b[i];
    for (i = 0; i < 4; ++i) {
        dm += (a[i] - b[i]) * (a[i] - b[i]);
        ds += (a[i] + b[i]) * (a[i] + b[i]);
    }
    theta = 2.0 * atan2(sqrt(dm), sqrt(ds)); /* angle between a and b on the 4-sphere */
    if (theta < 1e-9) {
        wa = 1.0 - t;
        wb = t;
    } else {
        double s = sin(theta);
        wa = sin((1.0 - t) * theta) / s;
        wb = sin(t * theta) / s;
    }
    for (i = 0; i < 4; ++i) r[i] = wa * a[i] + wb * b[i];
    return refl_quat_normalize(refl__quat(r[0], r[1], r[2], r[3]));
}

/* ---- polynomial roots ------------------------------------------------------ */

/* a * b = p + e exactly (Dekker), barring overflow and underflow. */
static void refl__two_prod(double a, double b, double *p, double *e) {
    const double split = 134217729.0; /* 2^27 + 1 */
    double ca = split * a, cb = split * b;
    double ah = ca - (ca - a), al = a - ah, bh = cb - (cb - b), bl = b - bh;
    *p = a * b;
    *e = ((ah * bh - *p) + ah * bl + al * bh) + al * bl;
}

static int refl__finite(double v) { return v - v == 0.0; }

static void refl__sort(double *r, int n) {
    int i, j;
    for (i = 1; i < n; ++i)
        for (j = i; j > 0 && r[j] < r[j - 1]; --j) {
            double t = r[j];
            r[j] = r[j - 1];
            r[j - 1] = t;
        }
}

/* Roots of a y^2 + b y + c with max(|a|, |b|, |c|) in [0.5, 1), a != 0,
   c != 0, both of magnitude well above underflow. */
static int refl__quadratic_scaled(double a, double b, double c, double r[2]) {
    double bb, bbe, ac, ace, disc, q;
    refl__two_prod(b, b, &bb, &bbe);
    refl__two_prod(4.0 * a, c, &ac, &ace);
    disc = (bb - ac) + (bbe - ace);
    /* A negative discriminant within rounding of the coefficients is a
       double root: they were computed, so their last bits are noise. */
    if (disc < 0.0 && -disc > 8.0 * DBL_EPSILON * REFL__MAX(bb, fabs(ac))) return 0;
    if (disc <= 0.0) {
        r[0] = r[1] = -b / (2.0 * a);
        return 2;
    }
    q = -0.5 * (b + (b < 0.0 ? -sqrt(disc) : sqrt(disc)));
    r[0] = q / a;
    r[1] = b == 0.0 ? -r[0] : c / q; /* symmetric roots exactly so */
    refl__sort(r, 2);
    return 2;
}

/* Keeps the finite entries of r[0..n), in order. */
static int refl__keep_finite(double *r, int n) {
    int i, k = 0;
    for (i = 0; i < n; ++i)
        if (refl__finite(r[i])) r[k++] = r[i];
    return k;
}

REFL_API int refl_solve_quadratic(double a, double b, double c, double roots[2]) {
    double r[2], ma, mb, mc, sa, sb, sc;
    int ea, eb, ec, k, e, n;
    if (!refl__finite(a) || !refl__finite(b) || !refl__finite(c)) return 0;
    if (a == 0.0) {
        if (b == 0.0) return c == 0.0 ? -1 : 0;
        r[0] = -c / b;
        if (!refl__finite(r[0])) return 0;
        if (r[0] == 0.0) r[0] = 0.0; /* no -0 */
        roots[0] = r[0];
        return 1;
    }
    if (c == 0.0) {
        r[0] = 0.0;
        r[1] = -b / a;
        if (r[1] == 0.0) r[1] = 0.0;
        n = refl__keep_finite(r, 2);
        refl__sort(r, n);
        memcpy(roots, r, (size_t)n * sizeof(double));
        return n;
    }
    /* x = 2^k y with k balancing |a| 2^2k against |c|, then every
       coefficient divided by 2^e, the largest exponent: all exact. */
    ma = frexp(a, &ea);
    mb = b != 0.0 ? frexp(b, &eb) : 0.0;
    mc = frexp(c, &ec);
    if (b == 0.0) eb = INT_MIN / 4;
    k = (ec - ea) / 2;
    e = REFL__MAX(REFL__MAX(ea + 2 * k, eb + k), ec);
    sa = ldexp(ma, ea + 2 * k - e);
    sb = ldexp(mb, eb + k - e);
    sc = ldexp(mc, ec - e);
    if (fabs(sa) < 1e-270 || fabs(sc) < 1e-270) {
        /* b outweighs a c by more than 1e270: the roots are -c/b and -b/a
           to far better than double precision */
        r[0] = ldexp(-mc / mb, ec - eb);
        r[1] = ldexp(-mb / ma, eb - ea);
        n = 2;
    } else {
        n = refl__quadratic_scaled(sa, sb, sc, r);
        if (n == 2) {
            r[0] = ldexp(r[0], k);
            r[1] = ldexp(r[1], k);
        }
    }
    n = refl__keep_finite(r, n);
    refl__sort(r, n);
    memcpy(roots, r, (size_t)n * sizeof(double));
    return n;
}

/* Horner for a y^3 + b y^2 + c y + d at y: value, derivative and the
   forward-deflated quadratic a y^2 + b1 y + c2. */
static void refl__cubic_eval(double y, double a, double b, double c, double d, double *q, double *dq,
                             double *b1, double *c2) {
    double q0 = a * y;
    *b1 = q0 + b;
    *c2 = *b1 * y + c;
    *dq = (q0 + *b1) * y + *c2;
    *q = *c2 * y + d;
}

static int refl__ceil_div(int n, int d) { return n >= 0 ? (n + d - 1) / d : -((-n) / d); }

static double refl__cubic_value(const double p[4], double y) {
    return ((p[0] * y + p[1]) * y + p[2]) * y + p[3];
}

/* Newton steps that are kept only when they lower |p(y)|. */
static double refl__cubic_polish(const double p[4], double y) {
    int it;
    double v = refl__cubic_value(p, y);
    for (it = 0; it < 2 && v != 0.0; ++it) {
        double dv = (3.0 * p[0] * y + 2.0 * p[1]) * y + p[2], yn, vn;
        if (dv == 0.0 || !refl__finite(dv)) break;
        yn = y - v / dv;
        vn = refl__cubic_value(p, yn);
        if (!(fabs(vn) < fabs(v))) break;
        y = yn;
        v = vn;
    }
    return y;
}

/* When the roots' magnitudes differ by more than about 2^330, a scaled
   coefficient underflows; then, by the Newton polygon of the exponents,
   either one root is at least 2^64 larger than the others (a is negligible
   for them: they solve b x^2 + c x + d, the far one is -b/a + c/b, from the
   sum of the roots) or one is 2^64 smaller (d is negligible for the others:
   a x^2 + b x + c, the near one -d/c from the product). The relative
   errors of dropping the term are below 2^-64. -1 when neither applies. */
static int refl__cubic_split(const double co[4], const double m[4], const int ex[4], double r[3]) {
    double gap_far = -1.0, gap_near = -1.0, la, lb, lc, ld;
    int n;
    la = ex[0] + log2(fabs(m[0]));
    lb = m[1] != 0.0 ? ex[1] + log2(fabs(m[1])) : -1e9;
    lc = m[2] != 0.0 ? ex[2] + log2(fabs(m[2])) : -1e9;
    ld = ex[3] + log2(fabs(m[3]));
    /* vertex of b on the upper hull: slope to a below both slopes to c, d */
    if (m[1] != 0.0) gap_far = REFL__MIN(lb - lc, (lb - ld) / 2.0) - (la - lb);
    /* vertex of c: slope from d above both slopes to b, a */
    if (m[2] != 0.0) gap_near = (lc - ld) - REFL__MAX(lb - lc, (la - lc) / 2.0);
    if (gap_far >= 64.0 && gap_far >= gap_near) {
        double c_b = ldexp(m[2] / m[1], ex[2] - ex[1]);
        n = refl_solve_quadratic(co[1], co[2], co[3], r);
        r[n] = ldexp(-m[1] / m[0], ex[1] - ex[0]) + c_b;
        return refl__keep_finite(r, n + 1);
    }
    if (gap_near >= 64.0) {
        n = refl_solve_quadratic(co[0], co[1], co[2], r);
        r[n] = ldexp(-m[3] / m[2], ex[3] - ex[2]);
        return refl__keep_finite(r, n + 1);
    }
    return -1;
}

REFL_API int refl_solve_cubic(double a, double b, double c, double d, double roots[3]) {
    double p[4], r[3], m[4], co[4], y, q, dq, b1, c2, t, rr, s, y0;
    int ex[4], i, k, e, n, it;
    if (!refl__finite(a) || !refl__finite(b) || !refl__finite(c) || !refl__finite(d)) return 0;
    if (a == 0.0) return refl_solve_quadratic(b, c, d, roots);
    if (d == 0.0) {
        n = refl_solve_quadratic(a, b, c, r); /* a != 0: n >= 0 */
        r[n++] = 0.0;
        refl__sort(r, n);
        memcpy(roots, r, (size_t)n * sizeof(double));
        return n;
    }
    /* x = 2^k y with every |y| <= 1/2 (Fujiwara: |x| <= 2 max(|b/a|,
       |c/a|^1/2, |d/2a|^1/3)), then coefficients divided by a 2^3k. */
    co[0] = a; co[1] = b; co[2] = c; co[3] = d;
    m[0] = frexp(a, &ex[0]);
    m[1] = b != 0.0 ? frexp(b, &ex[1]) : 0.0;
    m[2] = c != 0.0 ? frexp(c, &ex[2]) : 0.0;
    m[3] = frexp(d, &ex[3]);
    k = refl__ceil_div(ex[3] - ex[0] + 1, 3);
    if (b != 0.0) k = REFL__MAX(k, ex[1] - ex[0] + 1);
    if (c != 0.0) k = REFL__MAX(k, refl__ceil_div(ex[2] - ex[0] + 1, 2));
    k += 2;
    e = ex[0] + 3 * k;
    for (i = 0; i < 4; ++i) p[i] = m[i] != 0.0 ? ldexp(m[i], ex[i] + (3 - i) * k - e) : 0.0;
    for (i = 1; i < 4; ++i)
        if (m[i] != 0.0 && fabs(p[i]) < 1e-300) break;
    if (i < 4 && (n = refl__cubic_split(co, m, ex, r)) >= 0) {
        /* roots too far apart for one scaling; the split is exact enough */
        refl__sort(r, n);
        memcpy(roots, r, (size_t)n * sizeof(double));
        return n;
    } else {
        /* Kahan's QBC: from the inflection point, step out beyond a real
           root, then Newton inwards (monotone: stop when it turns). */
        y = -(p[1] / p[0]) / 3.0;
        refl__cubic_eval(y, p[0], p[1], p[2], p[3], &q, &dq, &b1, &c2);
        t = q / p[0];
        rr = cbrt(fabs(t));
        s = t < 0.0 ? -1.0 : 1.0;
        t = -dq / p[0];
        if (t > 0.0) rr = 1.324718 * REFL__MAX(rr, sqrt(t));
        y0 = y - s * rr;
        if (y0 != y) {
            /* near a multiple root rounding noise in q can throw the last
               step far past the root: keep the iterate of least |q| */
            double best = y0, bq = DBL_MAX;
            it = 0;
            do {
                y = y0;
                refl__cubic_eval(y, p[0], p[1], p[2], p[3], &q, &dq, &b1, &c2);
                if (fabs(q) < bq) { bq = fabs(q); best = y; }
                y0 = dq == 0.0 ? y : y - (q / dq) / 1.000000000000001;
            } while (s * y0 > s * y && ++it < 200);
            if (best != y) {
                y = best;
                refl__cubic_eval(y, p[0], p[1], p[2], p[3], &q, &dq, &b1, &c2);
            }
            /* a root far from zero deflates stably backwards */
            if (fabs(p[0]) * y * y > fabs(p[3] / y)) {
                c2 = -p[3] / y;
                b1 = (c2 - p[2]) / y;
            }
        }
        r[0] = y;
        n = 1 + refl_solve_quadratic(p[0], b1, c2, r + 1); /* p[0] != 0: >= 0 */
    }
    for (i = 0; i < n; ++i) r[i] = ldexp(refl__cubic_polish(p, r[i]), k);
    n = refl__keep_finite(r, n);
    refl__sort(r, n);
    memcpy(roots, r, (size_t)n * sizeof(double));
    return n;
}

/* ---- least squares ---------------------------------------------------------- */

REFL_API refl_result refl_least_squares(const double *A, const double *b, int rows, int cols, double *x,
                                        double *condition) {
    double *w, z[32], cond, rmax = 0.0, rmin = DBL_MAX;
    int perm[32], scale[32], i, j, k;
    size_t n;
    if (!A || !b || !x || cols < 1 || cols > 32 || rows < cols) return REFL_ERROR_INVALID_ARGUMENT;
    if ((size_t)rows > (size_t)-1 / sizeof(double) / (size_t)(cols + 1)) return REFL_ERROR_INVALID_SIZE;
    n = (size_t)rows;
    /* column-major working copy, b as the last column */
    w = (double *)refl__alloc(NULL, n * (size_t)(cols + 1) * sizeof(double));
    if (!w) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < rows; ++i) {
        for (j = 0; j < cols; ++j) w[(size_t)j * n + (size_t)i] = A[(size_t)i * (size_t)cols + (size_t)j];
        w[(size_t)cols * n + (size_t)i] = b[i];
    }
    for (i = 0; i <= cols; ++i) {
        const double *c = w + (size_t)i * n;
        size_t r;
        for (r = 0; r < n; ++r)
            if (!refl__finite(c[r])) {
                refl__free(NULL, w);
                return REFL_ERROR_INVALID_ARGUMENT;
            }
    }
    /* equilibrate: column j times 2^-scale[j], close to unit norm (exact) */
    for (j = 0; j < cols; ++j) {
        double *c = w + (size_t)j * n, big = 0.0, s = 0.0;
        size_t r;
        perm[j] = j;
        scale[j] = 0;
        for (r = 0; r < n; ++r) big = REFL__MAX(big, fabs(c[r]));
        if (big == 0.0) continue; /* zero column: r_jj = 0 below */
        frexp(big, &scale[j]);
        for (r = 0; r < n; ++r) c[r] = ldexp(c[r], -scale[j]);
        for (r = 0; r < n; ++r) s += c[r] * c[r];
        frexp(sqrt(s), &k);
        scale[j] += k;
        for (r = 0; r < n; ++r) c[r] = ldexp(c[r], -k);
    }
    /* Householder QR with column pivoting; R's upper triangle in place */
    for (k = 0; k < cols; ++k) {
        double best = -1.0, sigma, alpha, x0, vtv, *ck;
        int p = k;
        size_t r, kk = (size_t)k;
        for (j = k; j < cols; ++j) {
            const double *c = w + (size_t)j * n;
            double s = 0.0;
            for (r = kk; r < n; ++r) s += c[r] * c[r];
            if (s > best) { best = s; p = j; }
        }
        if (p != k) {
            double *cp = w + (size_t)p * n, *c = w + kk * n;
            int t = perm[k];
            for (r = 0; r < n; ++r) { double v = c[r]; c[r] = cp[r]; cp[r] = v; }
            perm[k] = perm[p];
            perm[p] = t;
        }
        ck = w + kk * n;
        sigma = sqrt(best);
        if (sigma == 0.0) { /* the rest is zero: rank deficient */
            for (j = k; j < cols; ++j) w[(size_t)j * n + (size_t)j] = 0.0;
            break;
        }
        x0 = ck[kk];
        alpha = x0 >= 0.0 ? -sigma : sigma; /* no cancellation in v0 = x0 - alpha */
        ck[kk] = x0 - alpha;                /* v = (x0 - alpha, x1, ...) */
        vtv = 2.0 * sigma * (sigma + fabs(x0));
        for (j = k + 1; j <= cols; ++j) {
            double *c = w + (size_t)j * n, s = 0.0, f;
            for (r = kk; r < n; ++r) s += ck[r] * c[r];
            f = 2.0 * s / vtv;
            for (r = kk; r < n; ++r) c[r] -= f * ck[r];
        }
        ck[kk] = alpha;
    }
    for (k = 0; k < cols; ++k) {
        double d = fabs(w[(size_t)k * n + (size_t)k]);
        rmax = REFL__MAX(rmax, d);
        rmin = REFL__MIN(rmin, d);
    }
    cond = rmin > 0.0 ? rmax / rmin : INFINITY;
    if (condition) *condition = cond;
    if (!(cond <= 1e12)) {
        refl__free(NULL, w);
        return REFL_ERROR_SINGULAR;
    }
    for (i = cols - 1; i >= 0; --i) {
        double s = w[(size_t)cols * n + (size_t)i];
        for (j = i + 1; j < cols; ++j) s -= w[(size_t)j * n + (size_t)i] * z[j];
        z[i] = s / w[(size_t)i * n + (size_t)i];
    }
    for (i = 0; i < cols; ++i) x[perm[i]] = ldexp(z[i], -scale[perm[i]]);
    refl__free(NULL, w);
    return REFL_OK;
}

/* ---- random numbers ---------------------------------------------------------- */

REFL_API refl_rng refl_rng_seed(uint64_t seed) {
    refl_rng r;
    r.state = seed ? seed : 0x9E3779B97F4A7C15ull; /* xorshift never leaves 0 */
    return r;
}

/* xorshift64*, the high half of the product (the better bits). */
REFL_API uint32_t refl_rng_u32(refl_rng *rng) {
    uint64_t s = rng->state;
    s ^= s >> 12;
    s ^= s << 25;
    s ^= s >> 27;
    rng->state = s;
    return (uint32_t)((s * 0x2545F4914F6CDD1Dull) >> 32);
}

REFL_API float refl_rng_float(refl_rng *rng) {
    return (float)(refl_rng_u32(rng) >> 8) * (1.0f / 16777216.0f);
}
