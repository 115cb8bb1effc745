/* Paper 001's inferred environment maps (Hakura and Snyder, section 4.3),
   one layer: a sphere shell around the lens object, cube-map textured,
   whose texels are found by least squares so that hybrid rendering with
   it matches ray-traced images. Rendering is linear in the texels: a
   pixel's term is the bilinear lookup of its exit ray on the shell
   (refl_lem_shell_lookup), one row of the rendering matrix A, recorded
   with exactly the weights the runtime samples with. The records of a
   viewpoint sample (section 4.1) give the targets b: the mean radiance
   where the pixel's subsamples' exit rays meet the scene, weighed by the
   paper's confidence, which distrusts pixels whose exit rays diverge.
   C A x = C b is solved by conjugate gradients on the normal equations,
   over x >= 0 where asked (radiance is never negative), sequentially in
   double, so the texels are the same on every run. */
#include "internal.h"

/* ---- shells: where an exit ray leaves one, and its texels -------------------------- */

static int refl__lem_sphere_kind(const refl_lem_shell *sh) {
    return sh->kind == REFL_LEM_SHELL_AUTO || sh->kind == REFL_LEM_SHELL_SPHERE;
}

REFL_API int refl_lem_shell_index(const refl_lem_shell *sh, refl_vec3 origin, refl_vec3 dir, refl_vec3 *index) {
    refl_vec3 oc;
    float dd, p[3], v[3], e[3], t = FLT_MAX;
    int i;
    if (!sh || !index || !refl__v3_finite(origin) || !refl__v3_finite(dir)) return 0;
    dd = refl_v3_dot(dir, dir);
    oc = refl_v3_sub(origin, sh->center);
    if (!(dd > 0.0f)) return 0;
    if (refl__lem_sphere_kind(sh)) {
        /* |o + t d - c| = r: from inside, where the ray leaves (the larger
           root); from outside (an inner layer's sphere within the lens's
           bounds), where it enters (the smaller) */
        float b = refl_v3_dot(oc, dir), c = refl_v3_dot(oc, oc) - sh->radius * sh->radius, disc = b * b - c * dd;
        if (!(sh->radius > 0.0f) || !(disc >= 0.0f)) return 0;
        t = (-b + (c <= 0.0f ? sqrtf(disc) : -sqrtf(disc))) / dd;
        *index = refl_v3_add(oc, refl_v3_scale(dir, t));
        return refl__v3_finite(*index) && t >= 0.0f;
    }
    for (i = 0; i < 3; ++i) {
        p[i] = refl_v3_dot(oc, sh->axis[i]);
        v[i] = refl_v3_dot(dir, sh->axis[i]);
        e[i] = sh->extent[i];
    }
    switch (sh->kind) {
    case REFL_LEM_SHELL_BOX:
        /* from inside: the nearest of the three slabs' exits */
        for (i = 0; i < 3; ++i)
            if (!(e[i] > 0.0f) || !(fabsf(p[i]) <= e[i])) return 0;
        for (i = 0; i < 3; ++i)
            if (v[i] != 0.0f) t = REFL__MIN(t, ((v[i] > 0.0f ? e[i] : -e[i]) - p[i]) / v[i]);
        break;
    case REFL_LEM_SHELL_CYLINDER: {
        /* from inside: the side's larger root or a cap, the nearer */
        float a = v[0] * v[0] + v[2] * v[2], b = p[0] * v[0] + p[2] * v[2];
        float c = p[0] * p[0] + p[2] * p[2] - e[0] * e[0];
        if (!(e[0] > 0.0f) || !(e[1] > 0.0f) || !(c <= 0.0f) || !(fabsf(p[1]) <= e[1])) return 0;
        if (a > 0.0f) t = (-b + sqrtf(REFL__MAX(b * b - a * c, 0.0f))) / a;
        if (v[1] != 0.0f) t = REFL__MIN(t, ((v[1] > 0.0f ? e[1] : -e[1]) - p[1]) / v[1]);
        e[2] = e[0];
        break;
    }
    case REFL_LEM_SHELL_QUAD: {
        /* the plane ahead, inside the rectangle */
        float x, y;
        if (!(e[0] > 0.0f) || !(e[1] > 0.0f) || v[2] == 0.0f) return 0;
        t = -p[2] / v[2];
        if (!(t > 0.0f)) return 0;
        x = (p[0] + t * v[0]) / e[0];
        y = (p[1] + t * v[1]) / e[1];
        if (!(fabsf(x) <= 1.0f && fabsf(y) <= 1.0f)) return 0;
        *index = refl_v3(x, y, 1.0f);
        return 1;
    }
    default: return 0;
    }
    if (!(t >= 0.0f) || !(t < FLT_MAX)) return 0;
    *index = refl_v3((p[0] + t * v[0]) / e[0], (p[1] + t * v[1]) / e[1], (p[2] + t * v[2]) / e[2]);
    return refl__v3_finite(*index);
}

REFL_API int refl_lem_shell_partial(const refl_lem_shell *sh, const refl_vec3 box[2]) {
    int k;
    if (!sh || !box) return 0;
    if (sh->kind == REFL_LEM_SHELL_QUAD) return 1;
    if (!refl__lem_sphere_kind(sh)) return 0;
    for (k = 0; k < 8; ++k) {
        refl_vec3 d = refl_v3_sub(refl_v3(box[k & 1].x, box[(k >> 1) & 1].y, box[(k >> 2) & 1].z), sh->center);
        if (!(refl_v3_dot(d, d) <= sh->radius * sh->radius)) return 1;
    }
    return 0;
}

REFL_API int refl_lem_shell_texels(const refl_lem_shell *shell, refl_vec3 index, uint32_t texel[4], float weight[4]) {
    float dv[3], s, tt, x, y, fx, fy;
    int face, n, x0, y0, x1, y1;
    if (!shell || shell->face_size <= 0 || shell->face_size > REFL__LEM_MAX_FACE || !refl__v3_finite(index)) return 0;
    if (shell->kind == REFL_LEM_SHELL_QUAD) { /* (x, y, presence): the point is (x, y) over the presence */
        if (!(index.z > 0.0f)) return 0;
        index = refl_v3(index.x / index.z, index.y / index.z, 1.0f);
    }
    n = shell->face_size;
    dv[0] = index.x;
    dv[1] = index.y;
    dv[2] = index.z;
    if (dv[0] == 0.0f && dv[1] == 0.0f && dv[2] == 0.0f) return 0;
    face = rast_cube_face(dv, &s, &tt);
    /* bilinear, taps clamped to the face (as refl_environment_lookup) */
    x = REFL__CLAMP(s, 0.0f, 1.0f) * (float)n - 0.5f;
    y = REFL__CLAMP(tt, 0.0f, 1.0f) * (float)n - 0.5f;
    fx = x - floorf(x);
    fy = y - floorf(y);
    x0 = (int)floorf(x);
    y0 = (int)floorf(y);
    x1 = REFL__MIN(x0 + 1, n - 1);
    y1 = REFL__MIN(y0 + 1, n - 1);
    x0 = REFL__CLAMP(x0, 0, n - 1);
    y0 = REFL__CLAMP(y0, 0, n - 1);
    {
        uint32_t base = (uint32_t)face * (uint32_t)n * (uint32_t)n;
        texel[0] = base + (uint32_t)(y0 * n + x0);
        texel[1] = base + (uint32_t)(y0 * n + x1);
        texel[2] = base + (uint32_t)(y1 * n + x0);
        texel[3] = base + (uint32_t)(y1 * n + x1);
    }
    weight[0] = (1.0f - fx) * (1.0f - fy);
    weight[1] = fx * (1.0f - fy);
    weight[2] = (1.0f - fx) * fy;
    weight[3] = fx * fy;
    return 1;
}

REFL_API int refl_lem_shell_lookup(const refl_lem_shell *shell, refl_vec3 origin, refl_vec3 dir, uint32_t texel[4],
                                   float weight[4]) {
    refl_vec3 index;
    return refl_lem_shell_index(shell, origin, dir, &index) && refl_lem_shell_texels(shell, index, texel, weight);
}

/* ---- fitting a layer's shell to its hits --------------------------------------------- */

/* Distance from local point p (in the shell's frame) to the shell's surface. */
static double refl__lem_surface_distance(const refl_lem_shell *sh, const double p[3]) {
    int i;
    switch (sh->kind) {
    case REFL_LEM_SHELL_BOX: {
        double out = 0.0, in = DBL_MAX;
        for (i = 0; i < 3; ++i) {
            double d = fabs(p[i]) - sh->extent[i];
            if (d > 0.0) out += d * d;
            in = REFL__MIN(in, -d);
        }
        return out > 0.0 ? sqrt(out) : in;
    }
    case REFL_LEM_SHELL_CYLINDER: {
        double rho = sqrt(p[0] * p[0] + p[2] * p[2]), dr = rho - sh->extent[0], dy = fabs(p[1]) - sh->extent[1];
        if (dr <= 0.0 && dy <= 0.0) return REFL__MIN(-dr, -dy);
        return sqrt(REFL__MAX(dr, 0.0) * REFL__MAX(dr, 0.0) + REFL__MAX(dy, 0.0) * REFL__MAX(dy, 0.0));
    }
    case REFL_LEM_SHELL_QUAD: {
        double dx = REFL__MAX(fabs(p[0]) - sh->extent[0], 0.0), dy = REFL__MAX(fabs(p[1]) - sh->extent[1], 0.0);
        return sqrt(dx * dx + dy * dy + p[2] * p[2]);
    }
    default: return fabs(sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - sh->radius);
    }
}

/* The mean distance of the hits pos[3 n] from the shell's surface. */
static double refl__lem_fit_error(const refl_lem_shell *sh, const float *pos, int n) {
    double acc = 0.0;
    int k, i;
    for (k = 0; k < n; ++k) {
        refl_vec3 d = refl_v3_sub(refl_v3(pos[3 * k], pos[3 * k + 1], pos[3 * k + 2]), sh->center);
        double p[3];
        for (i = 0; i < 3; ++i) p[i] = refl__lem_sphere_kind(sh) ? (&d.x)[i] : refl_v3_dot(d, sh->axis[i]);
        acc += refl__lem_surface_distance(sh, p);
    }
    return n ? acc / n : 0.0;
}

/* Eigenvectors of the symmetric 3x3 m (cyclic Jacobi), as rows of v,
   ordered by descending eigenvalue. */
static void refl__lem_eigen3(double m[3][3], double v[3][3]) {
    int sweep, p, q, k, i, j;
    double ev[3];
    for (i = 0; i < 3; ++i)
        for (j = 0; j < 3; ++j) v[i][j] = i == j;
    for (sweep = 0; sweep < 50; ++sweep) {
        double off = fabs(m[0][1]) + fabs(m[0][2]) + fabs(m[1][2]);
        if (off <= 1e-30) break;
        for (p = 0; p < 2; ++p)
            for (q = p + 1; q < 3; ++q) {
                double theta, t, c, sn;
                if (m[p][q] == 0.0) continue;
                theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
                t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                c = 1.0 / sqrt(t * t + 1.0);
                sn = t * c;
                for (k = 0; k < 3; ++k) { /* columns p, q of m, then rows */
                    double a = m[k][p], b = m[k][q];
                    m[k][p] = c * a - sn * b;
                    m[k][q] = sn * a + c * b;
                }
                for (k = 0; k < 3; ++k) {
                    double a = m[p][k], b = m[q][k];
                    m[p][k] = c * a - sn * b;
                    m[q][k] = sn * a + c * b;
                }
                for (k = 0; k < 3; ++k) { /* eigenvectors as rows */
                    double a = v[p][k], b = v[q][k];
                    v[p][k] = c * a - sn * b;
                    v[q][k] = sn * a + c * b;
                }
            }
    }
    for (i = 0; i < 3; ++i) ev[i] = m[i][i];
    for (i = 0; i < 3; ++i) /* selection sort, descending */
        for (j = i + 1; j < 3; ++j)
            if (ev[j] > ev[i]) {
                double t = ev[i];
                ev[i] = ev[j], ev[j] = t;
                for (k = 0; k < 3; ++k) t = v[i][k], v[i][k] = v[j][k], v[j][k] = t;
            }
}

/* The box of the hits and the lens's box (lo, hi) together, in the
   orthonormal frame axis[3] (on the world axes, exactly the world box). */
static refl_lem_shell refl__lem_fit_box(const float *pos, int n, refl_vec3 lo, refl_vec3 hi, const refl_vec3 axis[3]) {
    refl_lem_shell sh;
    float a[3], b[3], pad;
    int k, i;
    memset(&sh, 0, sizeof sh);
    pad = 0.01f * refl_v3_length(refl_v3_sub(hi, lo)) + 1e-6f;
    for (i = 0; i < 3; ++i) {
        a[i] = FLT_MAX, b[i] = -FLT_MAX;
        for (k = 0; k < 8; ++k) {
            float d = refl_v3_dot(refl_v3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z), axis[i]);
            a[i] = REFL__MIN(a[i], d), b[i] = REFL__MAX(b[i], d);
        }
        a[i] -= pad, b[i] += pad;
    }
    for (k = 0; k < n; ++k)
        for (i = 0; i < 3; ++i) {
            float d = refl_v3_dot(refl_v3(pos[3 * k], pos[3 * k + 1], pos[3 * k + 2]), axis[i]);
            a[i] = REFL__MIN(a[i], d), b[i] = REFL__MAX(b[i], d);
        }
    sh.kind = REFL_LEM_SHELL_BOX;
    for (i = 0; i < 3; ++i) {
        sh.center = refl_v3_add(sh.center, refl_v3_scale(axis[i], 0.5f * (a[i] + b[i])));
        sh.axis[i] = axis[i];
        sh.extent[i] = 0.5f * (b[i] - a[i]);
    }
    return sh;
}

/* Ascending with NaN last: a total order, so the selection below ends
   on any input. */
static int refl__lem_less(float a, float b) { return a < b || (a == a && b != b); }

/* Reorders v[0 .. n) so that v[k] is what an ascending sort would put
   there, those before it no greater and those after no less (a
   quickselect, three-way so that runs of equal values, a floor's hits
   at one height, cost no more than others): the fits take quantiles in
   linear time, for every frame the frame search tries. Returns v[k]. */
static float refl__lem_select(float *v, int n, int k) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        float a = v[lo], b = v[lo + (hi - lo) / 2], c = v[hi], pivot, t;
        int lt = lo, i = lo, gt = hi;
        /* the median of three */
        pivot = refl__lem_less(a, b) ? (refl__lem_less(b, c) ? b : refl__lem_less(a, c) ? c : a)
                                     : (refl__lem_less(a, c) ? a : refl__lem_less(b, c) ? c : b);
        while (i <= gt) { /* v[lo, lt) < pivot, v[lt, i) equal, v(gt, hi] > pivot */
            if (refl__lem_less(v[i], pivot))
                t = v[i], v[i++] = v[lt], v[lt++] = t;
            else if (refl__lem_less(pivot, v[i]))
                t = v[i], v[i] = v[gt], v[gt--] = t;
            else
                ++i;
        }
        if (k < lt)
            hi = lt - 1;
        else if (k > gt)
            lo = gt + 1;
        else
            break;
    }
    return v[k];
}

/* The share of a cylinder's cap hits that its cap holds: the radius is
   where nine in ten of them lie (the floor a lens stands on spreads to the
   horizon; its farthest hits would make a cap too wide for its texels,
   their mean a cap that leaves most of the floor to the side). */
#define REFL__LEM_CAP_SHARE 0.9

/* The share of a layer's hits a cylinder's caps hold beyond the lens's
   box: the highest and lowest hundredth are left out, so that three
   hits of columns beside a small lens do not stretch its cylinder up the
   columns (the floor seen past the cap then gets a sliver of the side). */
#define REFL__LEM_CAP_HOLD 0.99

/* The share of a layer's hits off a cylinder's caps from which they set
   its radius (their mean distance from the axis, section 4.2's shell at
   the layer's mean distance: the walls of a room, the columns around a
   teapot on a floor); under it the caps do (REFL__LEM_CAP_SHARE). */
#define REFL__LEM_SIDE_SHARE 0.05

/* A cylinder around the line through the lens's centre c along axis[1]
   (axis[0] and axis[2] span its cross-section). Its caps hold the lens's
   box, padded, and the hits (REFL__LEM_CAP_HOLD of them); where the hits'
   lowest (highest) lies within that padding, a plane the lens stands on
   (`hybrid`'s floor, 0.005 under the teapot), the cap lies on it, so that
   those hits count as on it.
   Its radius is the mean of what each hit says: one off the caps its
   distance from the axis, one on a cap the radius holding
   REFL__LEM_CAP_SHARE of the cap hits (at least the lens's), so a few
   hits of a column beside a lens on a floor do not set it. scratch holds
   n floats. On the world axes: around the vertical. */
static refl_lem_shell refl__lem_fit_cylinder(const float *pos, int n, refl_vec3 c, refl_vec3 lo, refl_vec3 hi,
                                             const refl_vec3 axis[3], float *scratch) {
    refl_lem_shell sh;
    refl_vec3 up = axis[1], q = refl_v3_sub(hi, lo);
    float y0 = FLT_MAX, y1 = -FLT_MAX, h0 = FLT_MAX, h1 = -FLT_MAX, pad = 0.01f * refl_v3_length(q) + 1e-6f;
    float rmin = 0.0f, keep = 1e-3f * pad; /* the caps' clearance of the lens's box */
    double acc = 0.0, u[3] = {up.x, up.y, up.z};
    int k, i, side = 0, capped = 0;
    memset(&sh, 0, sizeof sh);
    for (k = 0; k < 8; ++k) {
        refl_vec3 corner = refl_v3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z);
        refl_vec3 diag = refl_v3(k & 1 ? q.x : -q.x, k & 2 ? q.y : -q.y, q.z), r;
        float d = refl_v3_dot(corner, up);
        y0 = REFL__MIN(y0, d), y1 = REFL__MAX(y1, d);
        r = refl_v3_sub(diag, refl_v3_scale(up, refl_v3_dot(diag, up))); /* the lens's diagonal across the axis */
        rmin = REFL__MAX(rmin, refl_v3_dot(r, r));
    }
    for (k = 0; k < n; ++k) scratch[k] = refl_v3_dot(refl_v3(pos[3 * k], pos[3 * k + 1], pos[3 * k + 2]), up);
    if (n) {
        int k0 = (int)((1.0 - REFL__LEM_CAP_HOLD) * (n - 1)), k1 = (int)(REFL__LEM_CAP_HOLD * (n - 1));
        h0 = refl__lem_select(scratch, n, k0);
        h1 = refl__lem_select(scratch + k0, n - k0, k1 - k0); /* past k0 nothing is less */
    }
    /* the padded box, out to the hits; a cap on the hits' plane where that
       lies within the padding */
    y0 = h0 >= y0 - pad && h0 < y0 + keep ? REFL__MIN(h0, y0 - keep) : REFL__MIN(y0 - pad, h0);
    y1 = h1 <= y1 + pad && h1 > y1 - keep ? REFL__MAX(h1, y1 + keep) : REFL__MAX(y1 + pad, h1);
    for (k = 0; k < n; ++k) {
        double d[3] = {pos[3 * k] - c.x, pos[3 * k + 1] - c.y, pos[3 * k + 2] - c.z}, h, rho = 0.0;
        float y = refl_v3_dot(refl_v3(pos[3 * k], pos[3 * k + 1], pos[3 * k + 2]), up);
        h = d[0] * u[0] + d[1] * u[1] + d[2] * u[2];
        for (i = 0; i < 3; ++i) rho += (d[i] - h * u[i]) * (d[i] - h * u[i]);
        rho = sqrt(rho);
        if (y > y0 + 0.02f * (y1 - y0) && y < y1 - 0.02f * (y1 - y0))
            acc += rho, ++side;
        else
            scratch[capped++] = (float)rho;
    }
    if (side < REFL__LEM_SIDE_SHARE * n && capped) { /* the caps hold most of the layer: they set the radius */
        acc = refl__lem_select(scratch, capped, REFL__MIN((int)(REFL__LEM_CAP_SHARE * capped), capped - 1));
        side = 1;
    }
    rmin = pad + 0.5f * sqrtf(rmin);
    sh.kind = REFL_LEM_SHELL_CYLINDER;
    sh.center = refl_v3_add(refl_v3_sub(c, refl_v3_scale(up, refl_v3_dot(c, up))), refl_v3_scale(up, 0.5f * (y0 + y1)));
    for (i = 0; i < 3; ++i) sh.axis[i] = axis[i];
    sh.extent[0] = sh.extent[2] = REFL__MAX((float)(side ? acc / side : 0.0), rmin);
    sh.extent[1] = 0.5f * (y1 - y0);
    return sh;
}

/* ---- oriented frames: a box's or cylinder's frame fitted to the hits --- */

/* The frame rows f[3][3] turned by `radians` about its own axis i. */
static void refl__lem_turn(const double f[3][3], int i, double radians, double out[3][3]) {
    int j = (i + 1) % 3, k = (i + 2) % 3, c;
    double cs = cos(radians), sn = sin(radians);
    for (c = 0; c < 3; ++c) {
        out[i][c] = f[i][c];
        out[j][c] = cs * f[j][c] + sn * f[k][c];
        out[k][c] = cs * f[k][c] - sn * f[j][c];
    }
}

/* What a frame search fits: a box or cylinder (kind) to hits pos[3 n]
   (a subsample of the layer's), around the lens (c, lo, hi); scratch
   for the cylinder's fit, as many floats as the layer's hits. */
typedef struct refl__lem_frame_fit {
    int kind;
    const float *pos;
    int n;
    refl_vec3 c, lo, hi;
    float *scratch;
} refl__lem_frame_fit;

static refl_lem_shell refl__lem_fit_in_frame(const refl__lem_frame_fit *x, const float *pos, int n,
                                             const double f[3][3]) {
    refl_vec3 axis[3];
    int i;
    for (i = 0; i < 3; ++i) axis[i] = refl_v3_normalize(refl_v3((float)f[i][0], (float)f[i][1], (float)f[i][2]));
    return x->kind == REFL_LEM_SHELL_BOX ? refl__lem_fit_box(pos, n, x->lo, x->hi, axis)
                                         : refl__lem_fit_cylinder(pos, n, x->c, x->lo, x->hi, axis, x->scratch);
}

static double refl__lem_frame_error(const refl__lem_frame_fit *x, const double f[3][3]) {
    refl_lem_shell sh = refl__lem_fit_in_frame(x, x->pos, x->n, f);
    return refl__lem_fit_error(&sh, x->pos, x->n);
}

static const double refl__lem_world_frame[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};

/* Rows of Ry(yaw) Rx(pitch) Rz(roll)'s columns: a frame by its angles. */
static void refl__lem_frame_of_angles(double yaw, double pitch, double roll, double f[3][3]) {
    double a[3][3], b[3][3];
    refl__lem_turn(refl__lem_world_frame, 2, roll, a);
    refl__lem_turn(a, 0, pitch, b);
    refl__lem_turn(b, 1, yaw, f);
}

/* The frame whose fitted box or cylinder lies nearest the hits (mean
   distance, refl__lem_fit_error): a grid over the frames a box or a
   cylinder's axis tells apart (7.5 degrees apart; a cylinder's axis over
   the upper hemisphere), then turns about the frame's own axes halving
   from 4 degrees to 1/16. */
static void refl__lem_search_frame(const refl__lem_frame_fit *x, double best[3][3]) {
    const double deg = REFL__PI / 180.0;
    double err = DBL_MAX, f[3][3], step;
    int i, j, k;
    if (x->kind == REFL_LEM_SHELL_BOX) {
        for (i = 0; i < 12; ++i)
            for (j = 0; j < 12; ++j)
                for (k = 0; k < 12; ++k) {
                    double e;
                    refl__lem_frame_of_angles(7.5 * deg * i, 7.5 * deg * (j - 6), 7.5 * deg * (k - 6), f);
                    if ((e = refl__lem_frame_error(x, f)) < err) err = e, memcpy(best, f, sizeof f);
                }
    } else {
        for (i = 0; i <= 12; ++i) /* the axis (row 1) tilted i steps off the vertical towards azimuth j */
            for (j = 0; j < (i ? 48 : 1); ++j) {
                double e;
                refl__lem_frame_of_angles(7.5 * deg * j, 7.5 * deg * i, 0.0, f);
                if ((e = refl__lem_frame_error(x, f)) < err) err = e, memcpy(best, f, sizeof f);
            }
    }
    for (step = 4.0 * deg; step >= deg / 16.0; step *= 0.5) {
        int moved = 1, rounds;
        for (rounds = 0; moved && rounds < 16; ++rounds)
            for (moved = 0, i = 0; i < 3; ++i) {
                if (i == 1 && x->kind == REFL_LEM_SHELL_CYLINDER) continue; /* a turn about its own axis */
                for (k = -1; k <= 1; k += 2) {
                    double e;
                    refl__lem_turn(best, i, k * step, f);
                    if ((e = refl__lem_frame_error(x, f)) < err) err = e, memcpy(best, f, sizeof f), moved = 1;
                }
            }
    }
}

/* The fitted frame lies on the world axes (within 2 degrees): a box's
   three axes each along one, a cylinder's axis along the vertical. A
   turn that small is within what the hits tell (a cylinder tilted a
   degree moves a wall's far floor hits off its cap and into its radius). */
static int refl__lem_frame_is_world(int kind, const double f[3][3]) {
    const double c = cos(2.0 * REFL__PI / 180.0);
    int i;
    if (kind == REFL_LEM_SHELL_CYLINDER) return fabs(f[1][1]) >= c;
    for (i = 0; i < 3; ++i)
        if (!(REFL__MAX(fabs(f[i][0]), REFL__MAX(fabs(f[i][1]), fabs(f[i][2]))) >= c)) return 0;
    return 1;
}

/* Hits a frame search looks at: every hit up to this many, else evenly strided. */
#define REFL__LEM_FRAME_HITS 2048

/* A fitted frame's shell must lie this much nearer the hits than the
   world-axis one's to be a candidate: else the hits do not tell its
   frame (a floor's hits lie on a box turned about the vertical as well). */
#define REFL__LEM_FRAME_NEARER 0.9

/* The box or cylinder (kind) of the hits on its fitted frame
   (refl__lem_search_frame over a subsample) in *out: 1; 0 where that
   frame is the world's or its shell lies not clearly nearer the hits
   (REFL__LEM_FRAME_NEARER); -1 when out of memory. scratch: n floats. */
static int refl__lem_fit_oriented(int kind, const float *pos, int n, refl_vec3 c, refl_vec3 lo, refl_vec3 hi,
                                  const refl_allocator *al, float *scratch, refl_lem_shell *out) {
    refl__lem_frame_fit x;
    int m = REFL__MIN(n, REFL__LEM_FRAME_HITS), k;
    float *sub = m ? (float *)refl__calloc(al, 3 * (size_t)m, sizeof(float)) : NULL;
    double f[3][3];
    int nearer;
    if (!m) return 0;
    if (!sub) return -1;
    for (k = 0; k < m; ++k) memcpy(sub + 3 * (size_t)k, pos + 3 * ((long long)k * n / m), 3 * sizeof(float));
    x.kind = kind, x.pos = sub, x.n = m, x.c = c, x.lo = lo, x.hi = hi, x.scratch = scratch;
    refl__lem_search_frame(&x, f);
    nearer = refl__lem_frame_error(&x, f) < REFL__LEM_FRAME_NEARER * refl__lem_frame_error(&x, refl__lem_world_frame);
    refl__free(al, sub);
    if (!nearer || refl__lem_frame_is_world(kind, f)) return 0;
    *out = refl__lem_fit_in_frame(&x, pos, n, f);
    return 1;
}

/* The least-squares plane of the hits (the normal the covariance's least
   eigenvector), bounded by the rectangle of their extents in it. A quad
   with no area, or one passing within the lens's bounding sphere (c,
   lens_radius), is returned with extent 0 (not a candidate). */
static refl_lem_shell refl__lem_fit_quad(const float *pos, int n, refl_vec3 c, float lens_radius) {
    refl_lem_shell sh;
    double mean[3] = {0, 0, 0}, cov[3][3], ev[3][3], lo[2] = {DBL_MAX, DBL_MAX}, hi[2] = {-DBL_MAX, -DBL_MAX};
    int k, i, j;
    memset(&sh, 0, sizeof sh);
    sh.kind = REFL_LEM_SHELL_QUAD;
    if (n < 3) return sh;
    for (k = 0; k < n; ++k)
        for (i = 0; i < 3; ++i) mean[i] += pos[3 * k + i] / (double)n;
    memset(cov, 0, sizeof cov);
    for (k = 0; k < n; ++k)
        for (i = 0; i < 3; ++i)
            for (j = 0; j < 3; ++j) cov[i][j] += (pos[3 * k + i] - mean[i]) * (pos[3 * k + j] - mean[j]);
    refl__lem_eigen3(cov, ev);
    for (i = 0; i < 3; ++i) sh.axis[i] = refl_v3_normalize(refl_v3((float)ev[i][0], (float)ev[i][1], (float)ev[i][2]));
    for (k = 0; k < n; ++k)
        for (i = 0; i < 2; ++i) {
            double d = 0.0;
            for (j = 0; j < 3; ++j) d += (pos[3 * k + j] - mean[j]) * ev[i][j];
            lo[i] = REFL__MIN(lo[i], d), hi[i] = REFL__MAX(hi[i], d);
        }
    sh.center = refl_v3((float)mean[0], (float)mean[1], (float)mean[2]);
    for (i = 0; i < 2; ++i) {
        sh.center = refl_v3_add(sh.center, refl_v3_scale(sh.axis[i], (float)(0.5 * (lo[i] + hi[i]))));
        sh.extent[i] = (float)(0.5 * (hi[i] - lo[i]));
    }
    if (!(fabsf(refl_v3_dot(refl_v3_sub(c, sh.center), sh.axis[2])) > lens_radius) || !refl__v3_finite(sh.center))
        sh.extent[0] = sh.extent[1] = 0.0f;
    return sh;
}

/* How far the hits' directions from c spread: 1 minus the length of
   their mean unit direction (0: all one way; near 1: all round). */
static double refl__lem_spread(const float *pos, int n, refl_vec3 c) {
    double m[3] = {0, 0, 0};
    int k;
    for (k = 0; k < n; ++k) {
        refl_vec3 d = refl_v3_normalize(refl_v3_sub(refl_v3(pos[3 * k], pos[3 * k + 1], pos[3 * k + 2]), c));
        m[0] += d.x / n, m[1] += d.y / n, m[2] += d.z / n;
    }
    return n ? 1.0 - sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]) : 1.0;
}

/* The records of a layer as the clustering met them: each exit ray's
   first hit in the layer, its colour and the exit ray. */
typedef struct refl__lem_front {
    float *data;                 /* 10 per hit: rgb, exit origin, exit direction, view */
    int count;
} refl__lem_front;

static int refl__lem_cmp_key(const void *a, const void *b) {
    const uint32_t *x = (const uint32_t *)a, *y = (const uint32_t *)b;
    int i;
    for (i = 0; i < 3; ++i)
        if (x[i] != y[i]) return (x[i] > y[i]) - (x[i] < y[i]);
    return 0;
}

/* The conflicts of a layer's records on candidate shell sh at face size
   n: each front hit predicted by the mean colour of the other views' hits
   in the texel its exit ray looks up most (the layer's mean where there
   are none, or the ray has no lookup); the mean squared error per hit. A
   shell on which one scene point lands in different texels from
   different views (parallax off its surface), or several points share a
   texel, predicts badly: what no map inferred from some views can show
   at others. -1 when out of memory. */
static double refl__lem_conflicts(const refl_lem_shell *candidate, const refl__lem_front *f, int n,
                                  const refl_allocator *al) {
    refl_lem_shell sh = *candidate;
    uint32_t *key = (uint32_t *)refl__calloc(al, 3 * (size_t)REFL__MAX(f->count, 1), sizeof(uint32_t));
    double mean[3] = {0, 0, 0}, acc = 0.0;
    int k, j, c, m = 0;
    if (!key) return -1.0;
    sh.face_size = n;
    for (k = 0; k < f->count; ++k)
        for (c = 0; c < 3; ++c) mean[c] += f->data[10 * (size_t)k + (size_t)c] / f->count;
    /* (texel, view, hit) of every hit with a lookup, sorted: a texel's hits
       in a row, each view's within them */
    for (k = 0; k < f->count; ++k) {
        const float *e = f->data + 10 * (size_t)k;
        uint32_t tex[4];
        float w[4];
        int best = 0;
        if (!refl_lem_shell_lookup(&sh, refl_v3(e[3], e[4], e[5]), refl_v3(e[6], e[7], e[8]), tex, w)) {
            for (c = 0; c < 3; ++c) acc += (e[c] - mean[c]) * (e[c] - mean[c]);
            continue;
        }
        for (j = 1; j < 4; ++j)
            if (w[j] > w[best]) best = j;
        key[3 * m] = tex[best];
        key[3 * m + 1] = (uint32_t)e[9];
        key[3 * m + 2] = (uint32_t)k;
        ++m;
    }
    qsort(key, (size_t)m, 3 * sizeof(uint32_t), refl__lem_cmp_key);
    for (k = 0; k < m;) {
        double all[4] = {0, 0, 0, 0};
        int end, v, i;
        for (end = k; end < m && key[3 * end] == key[3 * k]; ++end) {
            for (c = 0; c < 3; ++c) all[c] += f->data[10 * (size_t)key[3 * end + 2] + (size_t)c];
            all[3] += 1.0;
        }
        for (v = k; v < end; v = i) { /* one view's hits, predicted by the others' */
            double own[4] = {0, 0, 0, 0};
            for (i = v; i < end && key[3 * i + 1] == key[3 * v + 1]; ++i) {
                for (c = 0; c < 3; ++c) own[c] += f->data[10 * (size_t)key[3 * i + 2] + (size_t)c];
                own[3] += 1.0;
            }
            for (j = v; j < i; ++j)
                for (c = 0; c < 3; ++c) {
                    double pred = all[3] > own[3] ? (all[c] - own[c]) / (all[3] - own[3]) : mean[c];
                    double d = f->data[10 * (size_t)key[3 * j + 2] + (size_t)c] - pred;
                    acc += d * d;
                }
        }
        k = end;
    }
    refl__free(al, key);
    return f->count ? acc / f->count : 0.0;
}

/* A layer's hits at most half spread (their mean direction at least half
   long) are "sparse in direction": a quad may hold them. */
#define REFL__LEM_QUAD_SPREAD 0.5

/* Kinds whose conflicts are within this factor of the fewest are not told
   apart by them (below what the binning resolves). */
#define REFL__LEM_SHELL_MARGIN 0.95

/* A layer's conflicts on sh summed over three face sizes (1, 2 and 4
   front hits a texel, were they spread evenly over the six faces): no one
   resolution decides. -1 when out of memory. */
static double refl__lem_shell_conflicts(const refl_lem_shell *sh, const refl__lem_front *front,
                                        const refl_allocator *al) {
    double per, sum = 0.0;
    for (per = 1.0; per <= 4.0; per *= 2.0) {
        int n = REFL__CLAMP((int)(sqrt(front->count / (6.0 * per)) + 0.5), 4, 64);
        double e = refl__lem_conflicts(sh, front, n, al);
        if (e < 0.0) return -1.0;
        sum += e;
    }
    return sum;
}

/* Layer shell *out of the kind asked, AUTO choosing among the candidates
   by the conflicts of the layer's records on their texels
   (refl__lem_shell_conflicts), then by nearness to the hits among those
   the conflicts do not tell apart. A box or cylinder is a candidate on
   the world axes and on the frame fitted to the hits (frame, a
   refl_lem_shell_frame), the conflicts choosing between them too. 0 when
   out of memory. */
static int refl__lem_fit_shell(int kind, int frame, int inner, const float *pos, int n, const refl__lem_front *front,
                               const refl_allocator *al, refl_vec3 c, float sphere_radius, refl_vec3 lo,
                               refl_vec3 hi, float lens_radius, refl_lem_shell *out) {
    static const refl_vec3 world[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    refl_lem_shell cand[6];
    double err[6], least = DBL_MAX, best_near = DBL_MAX;
    int k, m = 0, best = -1, shape, twin[6] = {-1, -1, -1, -1, -1, -1}; /* a fitted one's world-axis twin */
    float *scratch = (float *)refl__calloc(al, (size_t)REFL__MAX(n, 1), sizeof(float)); /* the cylinder's */
    if (!scratch) return 0;
    memset(cand, 0, sizeof cand);
    if (n == 0) kind = REFL_LEM_SHELL_SPHERE; /* nothing met: the environment, on the sphere */
    /* candidates in order of preference on a tie: quad, box, cylinder
       (each on the world axes, then fitted), sphere */
    if ((kind == REFL_LEM_SHELL_AUTO && inner && refl__lem_spread(pos, n, c) <= REFL__LEM_QUAD_SPREAD) ||
        (kind == REFL_LEM_SHELL_QUAD && inner)) {
        cand[m] = refl__lem_fit_quad(pos, n, c, lens_radius);
        if (cand[m].extent[0] > 0.0f && cand[m].extent[1] > 0.0f) ++m;
    }
    for (shape = REFL_LEM_SHELL_BOX; shape >= REFL_LEM_SHELL_CYLINDER; --shape) {
        refl_lem_shell oriented;
        int fitted;
        if (kind != REFL_LEM_SHELL_AUTO && kind != REFL_LEM_SHELL_QUAD && kind != shape) continue;
        fitted = frame == REFL_LEM_FRAME_WORLD ? 0
                                               : refl__lem_fit_oriented(shape, pos, n, c, lo, hi, al, scratch, &oriented);
        if (fitted < 0) {
            refl__free(al, scratch);
            return 0;
        }
        if (!fitted || frame != REFL_LEM_FRAME_FITTED)
            cand[m++] = shape == REFL_LEM_SHELL_BOX ? refl__lem_fit_box(pos, n, lo, hi, world)
                                                    : refl__lem_fit_cylinder(pos, n, c, lo, hi, world, scratch);
        if (fitted) {
            if (frame != REFL_LEM_FRAME_FITTED) twin[m] = m - 1;
            cand[m++] = oriented;
        }
    }
    refl__free(al, scratch);
    if (kind == REFL_LEM_SHELL_AUTO || kind == REFL_LEM_SHELL_QUAD || kind == REFL_LEM_SHELL_SPHERE) {
        memset(&cand[m], 0, sizeof cand[m]);
        cand[m].kind = REFL_LEM_SHELL_SPHERE;
        cand[m].center = c;
        cand[m++].radius = sphere_radius;
    }
    if (kind == REFL_LEM_SHELL_QUAD && cand[0].kind == REFL_LEM_SHELL_QUAD) m = 1; /* forced */
    for (k = 0; k < m && m > 1; ++k)
        if ((err[k] = refl__lem_shell_conflicts(&cand[k], front, al)) < 0.0) return 0;
    /* of a kind's two frames, the fitted one only where it has clearly
       fewer conflicts (past the margin the binning resolves) */
    for (k = 0; k < m && m > 1; ++k)
        if (twin[k] >= 0) err[err[k] < REFL__LEM_SHELL_MARGIN * err[twin[k]] ? twin[k] : k] = DBL_MAX;
    for (k = 0; k < m && m > 1; ++k) least = REFL__MIN(least, err[k]);
    /* of the kinds within the margin of the fewest conflicts, the one whose
       surface lies nearest the hits (a later one must be clearly nearer) */
    for (k = 0; k < m && m > 1; ++k) {
        double nearness;
        if (!(REFL__LEM_SHELL_MARGIN * err[k] <= least)) continue;
        nearness = refl__lem_fit_error(&cand[k], pos, n);
        if (best < 0 || nearness < 0.99 * best_near) best = k, best_near = nearness;
    }
    if (best < 0) best = 0;
    *out = cand[best];
    out->radius = sphere_radius; /* every kind keeps the layer's mean distance (the hits' fallback layer) */
    return 1;
}

REFL_API float refl_lem_confidence(const refl_vec3 *dirs, int count, float theta_c_degrees) {
    double tc = (theta_c_degrees > 0.0f ? theta_c_degrees : 5.0f) * REFL__PI / 180.0, tm = 0.0;
    int i, j;
    if (!dirs || count < 2) return 1.0f;
    for (i = 0; i < count; ++i)
        for (j = i + 1; j < count; ++j) {
            /* the angle from the chord: accurate for small angles, where acos is not */
            double dx = (double)dirs[i].x - dirs[j].x, dy = (double)dirs[i].y - dirs[j].y,
                   dz = (double)dirs[i].z - dirs[j].z, chord = sqrt(dx * dx + dy * dy + dz * dz);
            double a = 2.0 * asin(REFL__MIN(chord * 0.5, 1.0));
            if (a > tm) tm = a;
        }
    tm = REFL__MIN(tm, tc);
    return (float)(1.0 - tm * tm / (tc * tc));
}

static int refl__lem_fit_layers(refl__lem_layering *lay, const refl__lem_hits *h, const int *layer_of, int kind,
                                int frame, refl_vec3 lo, refl_vec3 hi, float lens_radius) {
    float *pos = h->count ? (float *)refl__calloc(h->al, 3 * (size_t)h->count, sizeof(float)) : NULL;
    refl__lem_front front;
    int l, k, n;
    memset(&front, 0, sizeof front);
    front.data = h->count ? (float *)refl__calloc(h->al, 10 * (size_t)h->count, sizeof(float)) : NULL;
    if (h->count && (!pos || !front.data)) {
        refl__free(h->al, pos);
        refl__free(h->al, front.data);
        return 0;
    }
    for (l = 0; l < lay->layers; ++l) {
        int counted = -1;
        for (k = n = front.count = 0; k < h->count; ++k) {
            if (!layer_of || layer_of[k] != l) continue;
            memcpy(pos + 3 * (size_t)n++, h->pos + 3 * (size_t)k, 3 * sizeof(float));
            /* a ray's hits are in a row, nearest first: its first in the layer */
            if (h->ray[k] == counted) continue;
            counted = h->ray[k];
            memcpy(front.data + 10 * (size_t)front.count, h->rgb + 3 * (size_t)k, 3 * sizeof(float));
            memcpy(front.data + 10 * (size_t)front.count + 3, h->exit + 6 * (size_t)k, 6 * sizeof(float));
            front.data[10 * (size_t)front.count + 9] = (float)h->view[k];
            ++front.count;
        }
        if (!refl__lem_fit_shell(kind, frame, l < lay->layers - 1, pos, n, &front, h->al, lay->centre,
                                 lay->radius[l], lo, hi, lens_radius, &lay->shell[l]))
            break;
    }
    refl__free(h->al, pos);
    refl__free(h->al, front.data);
    return l == lay->layers;
}

/* ---- the sparse system ------------------------------------------------------- */

struct refl_lem_system {
    refl_allocator allocator;
    int texels, rows, row_cap;
    long long entries, entry_cap;
    long long *row_start;        /* rows + 1 */
    uint32_t *col;
    float *w;                    /* confidence included */
    float *b;                    /* 4 per row, confidence included */
};

REFL_API refl_result refl_lem_system_create(int texels, const refl_allocator *a, refl_lem_system **out) {
    refl_lem_system *s;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    if (texels <= 0 || texels > (1 << 28)) return REFL_ERROR_INVALID_SIZE;
    s = (refl_lem_system *)refl__calloc(a, 1, sizeof *s);
    if (!s) return REFL_ERROR_OUT_OF_MEMORY;
    if (a) s->allocator = *a;
    s->texels = texels;
    s->row_start = (long long *)refl__calloc(a, 1, sizeof(long long));
    if (!s->row_start) {
        refl__free(a, s);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    *out = s;
    return REFL_OK;
}

REFL_API void refl_lem_system_destroy(refl_lem_system *s) {
    refl_allocator a;
    if (!s) return;
    a = s->allocator;
    refl__free(&a, s->row_start);
    refl__free(&a, s->col);
    refl__free(&a, s->w);
    refl__free(&a, s->b);
    refl__free(&a, s);
}

REFL_API int refl_lem_system_rows(const refl_lem_system *s) { return s ? s->rows : 0; }

/* Grows an array of `size`-byte items from cap to at least need. */
static int refl__lem_grow(const refl_allocator *a, void **arr, long long cap, long long need, size_t size,
                          long long *new_cap) {
    long long c = cap ? cap : 256;
    void *n;
    while (c < need) c *= 2;
    if (c == cap) return 1;
    n = refl__calloc(a, (size_t)c, size);
    if (!n) return 0;
    if (*arr) memcpy(n, *arr, (size_t)cap * size);
    refl__free(a, *arr);
    *arr = n;
    *new_cap = c;
    return 1;
}

REFL_API refl_result refl_lem_system_add_row(refl_lem_system *s, const uint32_t *texels, const float *weights,
                                             int count, const float target[4], float confidence) {
    const refl_allocator *a;
    int i;
    if (!s || !texels || !weights || !target || count <= 0) return REFL_ERROR_INVALID_ARGUMENT;
    if (!refl__isfinite(confidence) || confidence < 0.0f) return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < count; ++i)
        if (texels[i] >= (uint32_t)s->texels || !refl__isfinite(weights[i])) return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < 4; ++i)
        if (!refl__isfinite(target[i])) return REFL_ERROR_INVALID_ARGUMENT;
    if (confidence == 0.0f) return REFL_OK;
    a = &s->allocator;
    if (s->rows + 1 > s->row_cap) {
        long long nc = s->row_cap ? 2LL * s->row_cap : 256, got;
        if (!refl__lem_grow(a, (void **)&s->row_start, s->row_cap + 1LL, nc + 1, sizeof(long long), &got) ||
            !refl__lem_grow(a, (void **)&s->b, 4LL * s->row_cap, 4 * nc, sizeof(float), &got))
            return REFL_ERROR_OUT_OF_MEMORY;
        s->row_cap = (int)nc;
    }
    if (s->entries + count > s->entry_cap) {
        long long got = s->entry_cap;
        if (!refl__lem_grow(a, (void **)&s->col, s->entry_cap, s->entries + count, sizeof(uint32_t), &got) ||
            !refl__lem_grow(a, (void **)&s->w, s->entry_cap, s->entries + count, sizeof(float), &got))
            return REFL_ERROR_OUT_OF_MEMORY;
        s->entry_cap = got;
    }
    for (i = 0; i < count; ++i) {
        s->col[s->entries + i] = texels[i];
        s->w[s->entries + i] = weights[i] * confidence;
    }
    for (i = 0; i < 4; ++i) s->b[4 * (size_t)s->rows + (size_t)i] = target[i] * confidence;
    s->entries += count;
    ++s->rows;
    s->row_start[s->rows] = s->entries;
    return REFL_OK;
}

/* The solve's column scaling (Jacobi preconditioning of the normal
   equations): each texel's 1 / |its column of A stacked on lambda I|, 0
   for a texel no row reaches. A texel seen by many pixels has a column
   hundreds of times longer than one at a grazing edge seen by a few, and
   plain CGLS over such columns needs iterations that grow with the face
   size; over unit columns it does not. Sums in row order. */
static void refl__lem_column_scale(const refl_lem_system *s, double lambda2, double *scale) {
    long long e;
    int k;
    memset(scale, 0, sizeof(double) * (size_t)s->texels);
    for (e = 0; e < s->entries; ++e) scale[s->col[e]] += (double)s->w[e] * (double)s->w[e];
    for (k = 0; k < s->texels; ++k) scale[k] = scale[k] > 0.0 ? 1.0 / sqrt(scale[k] + lambda2) : 0.0;
}

/* q = A S p (rows x 4) with S the column scaling, and qq the squared
   norm per channel of the stacked operator's product: |q|^2 (summed in
   row order, as refl__lem_norm2 sums: one pass over q instead of two)
   plus lambda^2 |S p|^2 */
static void refl__lem_mul(const refl_lem_system *s, const double *scale, double lambda2, const double *p, double *q,
                          double qq[4]) {
    int r, c;
    long long e;
    size_t k;
    for (c = 0; c < 4; ++c) qq[c] = 0.0;
    for (r = 0; r < s->rows; ++r) {
        double acc[4] = {0, 0, 0, 0};
        for (e = s->row_start[r]; e < s->row_start[r + 1]; ++e) {
            double w = (double)s->w[e] * scale[s->col[e]];
            for (c = 0; c < 4; ++c) acc[c] += w * p[4 * (size_t)s->col[e] + (size_t)c];
        }
        for (c = 0; c < 4; ++c) q[4 * (size_t)r + (size_t)c] = acc[c], qq[c] += acc[c] * acc[c];
    }
    for (k = 0; lambda2 > 0.0 && k < 4 * (size_t)s->texels; ++k) qq[k % 4] += lambda2 * (scale[k / 4] * p[k]) * (scale[k / 4] * p[k]);
}

/* g = S A^T r - lambda^2 S^2 y (texels x 4), the stacked operator's
   transpose times its residual (the damping's, -lambda S y, implicit), in
   row order */
static void refl__lem_mul_t(const refl_lem_system *s, const double *scale, double lambda2, const double *y,
                            const double *r, double *g) {
    int row, c;
    long long e;
    size_t k;
    memset(g, 0, sizeof(double) * 4 * (size_t)s->texels);
    for (row = 0; row < s->rows; ++row)
        for (e = s->row_start[row]; e < s->row_start[row + 1]; ++e) {
            double w = (double)s->w[e] * scale[s->col[e]];
            for (c = 0; c < 4; ++c) g[4 * (size_t)s->col[e] + (size_t)c] += w * r[4 * (size_t)row + (size_t)c];
        }
    for (k = 0; lambda2 > 0.0 && k < 4 * (size_t)s->texels; ++k) g[k] -= lambda2 * scale[k / 4] * scale[k / 4] * y[k];
}

static void refl__lem_norm2(const double *v, size_t n, double out[4]) {
    size_t i;
    int c;
    for (c = 0; c < 4; ++c) out[c] = 0.0;
    for (i = 0; i < n; ++i)
        for (c = 0; c < 4; ++c) out[c] += v[4 * i + (size_t)c] * v[4 * i + (size_t)c];
}

/* CGLS over the scaled texels y = x / scale (the operator A S, stacked on
   lambda S with target 0 where damped: that part's residual -lambda S y
   is kept implicit in y), the four channels at once, from y = 0 with
   r = b; y >= 0 exactly where x >= 0. With held, over x >= 0 (projected
   CGLS with restarts): conjugate gradients over each channel's free
   texels, those not held at 0 by a gradient pushing them below it. A
   step that takes a free texel below 0 is clamped there and the channel
   restarts from its gradient with its free set found again; a channel
   converged on its free texels restarts where a held texel's gradient
   now points above 0, and is done where none does. Without held (NULL)
   nothing is ever held, clamped or restarted: plain CGLS, whose first
   beta is 0 as gamma starts at 0. r, g, p (0 on entry), q and held are
   the solver's work vectors. Returns the iterations run. */
static int refl__lem_cgls(const refl_lem_system *s, const double *scale, double lambda2, double *xd, double *r, double *g,
                          double *p, double *q, unsigned char *held, int max_it, double tol) {
    const size_t nt = (size_t)s->texels, nr = (size_t)s->rows;
    const int bounded = held != NULL;
    double gamma[4] = {0, 0, 0, 0}, gamma0[4] = {0, 0, 0, 0}, qq[4];
    int restart[4] = {bounded, bounded, bounded, bounded}, done[4], first = 1, it, c;
    size_t k;
    for (it = 0; it < max_it; ++it) {
        double gn[4] = {0, 0, 0, 0}, beta[4], alpha[4];
        int all_done = 1;
        if (restart[0] | restart[1] | restart[2] | restart[3]) { /* r = b - A x on the clamped x */
            for (k = 0; k < 4 * nt; ++k) xd[k] = REFL__MAX(xd[k], 0.0);
            refl__lem_mul(s, scale, lambda2, xd, q, qq);
            for (k = 0; k < 4 * nr; ++k) r[k] = (double)s->b[k] - q[k];
        }
        refl__lem_mul_t(s, scale, lambda2, xd, r, g);
        for (k = 0; k < nt; ++k)
            for (c = 0; c < 4; ++c) {
                size_t e = 4 * k + (size_t)c;
                if (restart[c]) held[e] = xd[e] <= 0.0 && g[e] <= 0.0;
                if (!bounded || !held[e]) gn[c] += g[e] * g[e];
            }
        for (c = 0; c < 4; ++c) {
            if (first) gamma0[c] = gn[c];
            beta[c] = restart[c] || !(gamma[c] > 0.0) ? 0.0 : gn[c] / gamma[c];
            gamma[c] = gn[c];
            restart[c] = 0;
        }
        first = 0;
        for (k = 0; k < nt; ++k)
            for (c = 0; c < 4; ++c) {
                size_t e = 4 * k + (size_t)c;
                p[e] = bounded && held[e] ? 0.0 : g[e] + beta[c] * p[e];
            }
        for (c = 0; c < 4; ++c) { /* a channel done stands still (alpha 0) while others go on */
            done[c] = !(gamma[c] > tol * tol * gamma0[c]);
            for (k = 0; bounded && done[c] && k < nt && !restart[c]; ++k) /* a held texel pulled back above 0 */
                restart[c] = held[4 * k + (size_t)c] && g[4 * k + (size_t)c] > 0.0;
            done[c] &= !restart[c];
            /* plain CGLS goes on past a NaN gamma (from weights past float's range) */
            all_done &= bounded ? done[c] : gamma[c] <= tol * tol * gamma0[c];
        }
        if (all_done) break;
        if (restart[0] | restart[1] | restart[2] | restart[3]) continue;
        refl__lem_mul(s, scale, lambda2, p, q, qq);
        for (c = 0; c < 4; ++c) alpha[c] = qq[c] > 0.0 && !done[c] ? gamma[c] / qq[c] : 0.0;
        for (k = 0; k < nt; ++k)
            for (c = 0; c < 4; ++c) {
                size_t e = 4 * k + (size_t)c;
                xd[e] += alpha[c] * p[e];
                restart[c] |= bounded && xd[e] < 0.0;
            }
        for (k = 0; k < nr; ++k)
            for (c = 0; c < 4; ++c) r[4 * k + (size_t)c] -= alpha[c] * q[4 * k + (size_t)c];
    }
    for (k = 0; bounded && k < 4 * nt; ++k) xd[k] = REFL__MAX(xd[k], 0.0);
    return it;
}

REFL_API refl_result refl_lem_solve(const refl_lem_system *s, const refl_lem_solve_desc *desc, float *x,
                                    refl_lem_solve_stats *stats) {
    const refl_allocator *a;
    size_t nt, nr;
    double *xd, *r, *g, *p, *q, *scale, rr[4];
    unsigned char *held = NULL;
    int it, max_it = desc && desc->iterations > 0 ? desc->iterations : 200, c, i;
    double tol = desc && desc->tolerance > 0.0f ? desc->tolerance : 1e-6;
    double lambda2 = desc ? (double)desc->damping * (double)desc->damping : 0.0;
    refl_result res = REFL_ERROR_OUT_OF_MEMORY;
    if (!s || !x || (desc && !(desc->damping >= 0.0f && desc->damping <= FLT_MAX))) return REFL_ERROR_INVALID_ARGUMENT;
    a = &s->allocator;
    nt = (size_t)s->texels;
    nr = (size_t)REFL__MAX(s->rows, 1);
    xd = (double *)refl__calloc(a, 4 * nt, sizeof(double));
    g = (double *)refl__calloc(a, 4 * nt, sizeof(double));
    p = (double *)refl__calloc(a, 4 * nt, sizeof(double));
    r = (double *)refl__calloc(a, 4 * nr, sizeof(double));
    q = (double *)refl__calloc(a, 4 * nr, sizeof(double));
    scale = (double *)refl__calloc(a, nt, sizeof(double));
    if (!xd || !g || !p || !r || !q || !scale) goto out;
    refl__lem_column_scale(s, lambda2, scale);
    for (i = 0; i < 4 * s->rows; ++i) r[i] = s->b[i]; /* r = b - A 0 */
    refl__lem_norm2(r, (size_t)s->rows, rr);
    if (stats)
        for (c = 0; c < 4; ++c) stats->initial[c] = sqrt(rr[c]);
    if (desc && desc->nonnegative && !(held = (unsigned char *)refl__calloc(a, 4 * nt, 1))) goto out;
    it = refl__lem_cgls(s, scale, lambda2, xd, r, g, p, q, held, max_it, tol);
    for (i = 0; i < 4 * s->texels; ++i) x[i] = (float)(xd[i] * scale[i / 4]);
    if (stats) {
        stats->iterations = it;
        stats->converged = it < max_it;
        refl__lem_norm2(r, (size_t)s->rows, rr);
        for (c = 0; c < 4; ++c) stats->residual[c] = sqrt(rr[c]);
    }
    res = REFL_OK;
out:
    refl__free(a, held);
    refl__free(a, xd), refl__free(a, g), refl__free(a, p), refl__free(a, r), refl__free(a, q), refl__free(a, scale);
    return res;
}

/* ---- records of a viewpoint sample --------------------------------------------- */


static int refl__lem_exit_hits(const refl_scene *scene, const refl_ray_caster *caster, refl_vec3 o, refl_vec3 d,
                               refl_vec3 centre, int own, int depth, refl__lem_hit *hits, int max, long long *rays);

/* The interfaces a greedy path may still meet past path (NULL: none yet)
   under the pass's depth (0: REFL_GREEDY_MAX_INTERFACES). */
static int refl__lem_depth_left(int depth, const refl_greedy_path *path) {
    int all = depth > 0 ? REFL__MIN(depth, REFL_GREEDY_MAX_INTERFACES) : REFL_GREEDY_MAX_INTERFACES;
    return all - (path ? path->length : 0);
}

/* The colour of lens `hit` (another lens than the one whose environment
   it is) seen along unit d, as the greedy tracer shows it: its one
   greedy path on (depth interfaces at most; black where it ends inside),
   F G times what its exit ray meets first, shaded as the records shade
   (refl__lem_exit_hits). */
static void refl__lem_lens_colour(const refl_scene *scene, const refl_ray_caster *caster, refl_vec3 d,
                                  const refl_hit *hit, int depth, float rgb[3], long long *rays) {
    refl_greedy_path path;
    refl__lem_hit end;
    float seen[3];
    int c;
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    refl__greedy_path_on(scene, caster, d, hit, depth, &path, rays);
    if (!path.exited) return;
    if (refl__lem_exit_hits(scene, caster, path.exit_origin, path.exit_direction, path.exit_origin, -1, 0, &end, 1,
                            rays) == 1) {
        memcpy(seen, end.rgb, sizeof seen);
    } else {
        refl_environment_lookup(&scene->environment, path.exit_direction, seen);
        for (c = 0; c < 3; ++c) seen[c] = REFL__RADIANCE(seen[c]);
    }
    for (c = 0; c < 3; ++c) rgb[c] = REFL__RADIANCE(path.fresnel * path.attenuation[c] * seen[c]);
}

/* Every surface an exit ray meets past the lens, continued through them
   (section 4.1, Figure 4c; the back of an object the ray entered is not
   one, an open shell's inside is): up to max (at most
   REFL__LEM_MAX_HITS), nearest first, each shaded as RAYTRACE shades a
   diffuse surface without shadows. Lens objects are passed through where
   own < 0 (the ray's own lens met again, or a mirror or glass beyond,
   whose own paths the tracer would follow); with own >= 0 only own is,
   and another lens is a surface of own's environment like any other,
   its colour what the greedy tracer sees of it along the ray
   (refl__lem_lens_colour, depth interfaces on). Returns the count. */
static int refl__lem_exit_hits(const refl_scene *scene, const refl_ray_caster *caster, refl_vec3 o, refl_vec3 d,
                               refl_vec3 centre, int own, int depth, refl__lem_hit *hits, int max, long long *rays) {
    refl_hit h;
    float tmin = 0.0f;
    int tries, k, n = 0;
    ++*rays;
    max = REFL__MIN(max, REFL__LEM_MAX_HITS);
    for (tries = 0; tries < 4 * REFL__LEM_MAX_HITS && n < max; ++tries) {
        const refl_object *obj;
        const refl_mesh *m;
        const refl_material *mat;
        refl_mat4 nm;
        refl__hit_geom g;
        float uv[2] = {0.0f, 0.0f};
        int lens;
        if (!caster->intersect(caster->user, o, d, tmin, FLT_MAX, &h) || h.object < 0 || h.object >= scene->object_count)
            break;
        tmin = h.t;
        obj = &scene->objects[h.object];
        mat = &scene->materials[obj->material];
        lens = refl__is_reflector(mat);
        if (lens && (own < 0 || h.object == own)) continue;
        m = scene->meshes[obj->mesh];
        nm = refl__normal_matrix(obj->transform);
        refl__hit_surface(m, &obj->transform, &nm, &h, &g);
        if (refl_v3_dot(g.ng, d) >= 0.0f) { /* leaving an object the ray entered: its inside, not seen */
            for (k = 0; k < n && hits[k].object != h.object; ++k) {
            }
            if (k < n) continue;
        }
        if (lens) {
            refl__lem_lens_colour(scene, caster, d, &h, depth, hits[n].rgb, rays);
        } else {
            if (m->texcoords) {
                const uint32_t *tri = m->indices + 3 * (size_t)h.triangle;
                for (k = 0; k < 3; ++k) {
                    uv[0] += g.w[k] * m->texcoords[2 * (size_t)tri[k]];
                    uv[1] += g.w[k] * m->texcoords[2 * (size_t)tri[k] + 1];
                }
            }
            refl_shade_diffuse(scene, mat, g.p, g.ns, m->texcoords ? uv : NULL, hits[n].rgb);
            for (k = 0; k < 3; ++k) hits[n].rgb[k] = REFL__RADIANCE(hits[n].rgb[k]);
        }
        hits[n].distance = refl_v3_length(refl_v3_sub(g.p, centre));
        hits[n].position = g.p;
        hits[n].object = h.object;
        ++n;
    }
    return n;
}

/* The layer of a hit: its object's, else the shell nearest its distance. */
static int refl__lem_hit_layer(const refl__lem_layering *lay, const refl__lem_hit *h) {
    int l, best = 0;
    if (lay->object_layer && h->object >= 0 && h->object < lay->object_count && lay->object_layer[h->object] >= 0)
        return lay->object_layer[h->object];
    for (l = 1; l < lay->layers; ++l)
        if (fabsf(h->distance - lay->radius[l]) < fabsf(h->distance - lay->radius[best])) best = l;
    return best;
}

/* Surfaces an eye ray is continued through on its way to the lens at most. */
enum { REFL__LEM_MAX_CONTINUED = 32 };

/* The greedy paths of a sample's eye ray (o, unit d) at lens `object`
   (section 4.1): where the ray meets the lens first, its paths from there
   (1); where it meets something else first (a diffuse occluder, another
   lens: the cup before the teapot) and continue_box is the lens's world
   box (NULL: not continued; Figure 4b), its paths from the lens's first
   surface behind it, the occluders passed through as if absent (2), so
   the lens's hidden parts give records as the runtime's rasterised lens
   shows them to an eye that sees them; else 0 (*out then unset). A ray
   is not continued past the box, where no lens surface can lie. */
static int refl__lem_eye_paths(const refl_scene *scene, const refl__gp_casters *paths, refl_vec3 o, refl_vec3 d,
                               int object, int max_interfaces, const refl_vec3 *continue_box,
                               refl_greedy_paths_result *out, long long *rays) {
    refl_hit hit;
    refl__gp_hit h;
    float tmin = 0.0f, tbox = -1.0f;
    int tries;
    for (tries = 0; tries < REFL__LEM_MAX_CONTINUED; ++tries) {
        ++*rays;
        if (!paths->scene->intersect(paths->scene->user, o, d, tmin, FLT_MAX, &hit)) return 0;
        if (hit.object == object) break;
        if (!continue_box) return 0;
        if (!tries && !refl_ray_box(o, d, continue_box[0], continue_box[1], NULL, &tbox)) tbox = -1.0f;
        if (!(hit.t <= tbox * (1.0f + 1e-4f) + 1e-6f)) return 0; /* past the lens's box: no lens behind */
        tmin = hit.t;
    }
    if (tries == REFL__LEM_MAX_CONTINUED || !refl__gp_hit_of(scene, &hit, &h)) return 0;
    refl__greedy_paths_none(o, d, out);
    refl__greedy_paths_from(scene, paths, d, &h, max_interfaces, out, rays);
    return tries ? 2 : 1;
}

static int refl__lem_pixel_records(const refl_scene *scene, const refl_ray_caster *caster, const refl__view_rays *view,
                                   int x, int y, int object, int ss, float theta_c, int max_interfaces,
                                   const refl__lem_layering *lay, float *out, float *points,
                                   refl_greedy_paths_result *centre_paths, long long *rays) {
    refl_vec3 dirs[2][REFL__LEM_MAX_SS * REFL__LEM_MAX_SS], o, d;
    refl_greedy_paths_result sub;
    refl__lem_hit hits[REFL__LEM_MAX_HITS];
    float sum[2][REFL_LEM_MAX_LAYERS][3], tmax;
    int n[2] = {0, 0}, seen[2][REFL_LEM_MAX_LAYERS], i, j, k, l, c, term, L = lay->layers, met;
    const refl_vec3 *continue_box = lay->continued ? lay->box : NULL;
    refl__gp_casters paths;
    paths.scene = caster;
    paths.lenses = paths.others = NULL;
    paths.own = lay->own;
    refl__view_rays_get(view, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
    met = refl__lem_eye_paths(scene, &paths, o, d, object, max_interfaces, continue_box, centre_paths, rays);
    if (!met) return 0;
    for (k = 0; points && k < 6 * L; ++k) points[k] = NAN;
    memset(sum, 0, sizeof sum);
    memset(seen, 0, sizeof seen);
    for (j = 0; j < ss; ++j)
        for (i = 0; i < ss; ++i) {
            refl__view_rays_get(view, (float)x + ((float)i + 0.5f) / (float)ss,
                                (float)y + ((float)j + 0.5f) / (float)ss, &o, &d, &tmax);
            if (!refl__lem_eye_paths(scene, &paths, o, d, object, max_interfaces, continue_box, &sub, rays))
                continue;
            for (term = 0; term < 2; ++term) {
                const refl_greedy_path *sp = term ? &sub.refract : &sub.reflect;
                int nh, got[REFL_LEM_MAX_LAYERS], deepest = 0;
                if (!(sp->fresnel > 0.0f) || !sp->exited) continue;
                nh = refl__lem_exit_hits(scene, caster, sp->exit_origin, sp->exit_direction, lay->centre, lay->own,
                                         refl__lem_depth_left(max_interfaces, sp), hits, REFL__LEM_MAX_HITS, rays);
                memset(got, 0, sizeof got);
                /* each layer takes the ray's first hit in it (section 4.3)
                   that no nearer hit of a later layer hides: the runtime
                   composites the layers in their order, so a hit behind a
                   later layer's (an object kept whole in an earlier layer,
                   the floor behind a teapot) would cover it */
                for (k = 0; k < nh; ++k) {
                    l = refl__lem_hit_layer(lay, &hits[k]);
                    if (l < deepest) continue;
                    deepest = l;
                    if (got[l]) continue;
                    got[l] = 1;
                    if (points && isnan(points[3 * (term * L + l)]))
                        memcpy(points + 3 * (term * L + l), &hits[k].position, 3 * sizeof(float));
                    ++seen[term][l];
                    for (c = 0; c < 3; ++c) sum[term][l][c] += hits[k].rgb[c];
                }
                if (!got[L - 1]) { /* the outermost layer is opaque: the environment past everything */
                    float rgb[3];
                    refl_environment_lookup(&scene->environment, sp->exit_direction, rgb);
                    for (k = 0; k < 3; ++k) sum[term][L - 1][k] += REFL__RADIANCE(rgb[k]);
                    ++seen[term][L - 1];
                }
                dirs[term][n[term]++] = sp->exit_direction;
            }
        }
    for (term = 0; term < 2; ++term) {
        float conf = n[term] ? refl_lem_confidence(dirs[term], n[term], theta_c) : -1.0f;
        /* radiance past float's range (a caller's huge light or emission)
           gives the term no record: least squares needs finite targets */
        for (l = 0; l < L && n[term]; ++l)
            for (k = 0; k < 3; ++k)
                if (!refl__isfinite(sum[term][l][k])) conf = -1.0f;
        for (l = 0; l < L; ++l) {
            float *t = out + 5 * (term * L + l);
            t[0] = t[1] = t[2] = t[3] = 0.0f;
            t[4] = conf;
            if (!n[term]) continue;
            /* premultiplied: what the layer adds where it covers, so texels
               interpolate across its edges as "over" composites them */
            for (k = 0; k < 3; ++k) t[k] = sum[term][l][k] / (float)n[term];
            t[3] = (float)seen[term][l] / (float)n[term];
        }
    }
    return met;
}

/* ---- direct images against disocclusion (section 4.3) ----------------------------------- */

/* The unit-cube point of texel (face, x, y)'s centre (rast_cube_face's inverse). */
static refl_vec3 refl__lem_texel_direction(int face, int x, int y, int n) {
    float sc = 2.0f * ((float)x + 0.5f) / (float)n - 1.0f, tc = 2.0f * ((float)y + 0.5f) / (float)n - 1.0f;
    switch (face) {
    case 0: return refl_v3(1.0f, -tc, -sc);
    case 1: return refl_v3(-1.0f, -tc, sc);
    case 2: return refl_v3(sc, 1.0f, tc);
    case 3: return refl_v3(sc, -1.0f, -tc);
    case 4: return refl_v3(sc, -tc, 1.0f);
    default: return refl_v3(-sc, -tc, -1.0f);
    }
}

/* The world point on the shell whose index points along q (a texel's
   direction), 0 where none (a quad's other faces). */
static int refl__lem_shell_point(const refl_lem_shell *sh, refl_vec3 q, refl_vec3 *p) {
    float k;
    if (refl__lem_sphere_kind(sh)) {
        *p = refl_v3_add(sh->center, refl_v3_scale(refl_v3_normalize(q), sh->radius));
        return 1;
    }
    switch (sh->kind) {
    case REFL_LEM_SHELL_BOX: k = REFL__MAX(fabsf(q.x), REFL__MAX(fabsf(q.y), fabsf(q.z))); break;
    case REFL_LEM_SHELL_CYLINDER: k = REFL__MAX(sqrtf(q.x * q.x + q.z * q.z), fabsf(q.y)); break;
    case REFL_LEM_SHELL_QUAD:
        if (!(q.z > 0.0f) || fabsf(q.x) > q.z || fabsf(q.y) > q.z) return 0;
        k = q.z, q.z = 0.0f;
        break;
    default: return 0;
    }
    if (!(k > 0.0f)) return 0;
    *p = refl_v3_add(sh->center,
                     refl_v3_add(refl_v3_scale(sh->axis[0], sh->extent[0] * q.x / k),
                                 refl_v3_add(refl_v3_scale(sh->axis[1], sh->extent[1] * q.y / k),
                                             refl_v3_scale(sh->axis[2], sh->extent[2] * q.z / k))));
    return 1;
}

/* The nearest of a layer's record hits, for the distance confidence:
   the hits in a kd-tree (refl_kdtree_build), searched within cell. */
typedef struct refl__lem_near {
    float cell;
    refl_kdtree *tree;           /* NULL: no hits */
} refl__lem_near;

/* 0 when out of memory. */
static int refl__lem_near_build(refl__lem_near *g, const float *pos, long long count, float cell,
                                const refl_allocator *al) {
    refl_kdtree_desc kd;
    memset(g, 0, sizeof *g);
    g->cell = cell;
    if (count <= 0 || !(cell > 0.0f)) return 1;
    memset(&kd, 0, sizeof kd);
    kd.leaf_points = 16;
    kd.allocator = *al;
    return refl_kdtree_build(pos, (int)REFL__MIN(count, (long long)INT_MAX), &kd, &g->tree) == REFL_OK;
}

/* A search for the hit nearest p: the least squared distance so far. */
typedef struct refl__lem_near_query {
    const float *p;
    double best;
} refl__lem_near_query;

static int refl__lem_near_box(void *user, const float lo[3], const float hi[3]) {
    const refl__lem_near_query *q = (const refl__lem_near_query *)user;
    double d2 = 0.0;
    int k;
    for (k = 0; k < 3; ++k) {
        double e = q->p[k] < lo[k] ? (double)lo[k] - q->p[k] : q->p[k] > hi[k] ? (double)q->p[k] - hi[k] : 0.0;
        d2 += e * e;
    }
    return d2 < q->best;
}

static void refl__lem_near_leaf(void *user, const refl_kdtree *tree, const refl_kdtree_node *leaf) {
    refl__lem_near_query *q = (refl__lem_near_query *)user;
    int i;
    for (i = leaf->first; i < leaf->first + leaf->count; ++i) {
        const float *h = tree->positions + 3 * (size_t)i;
        double ex = (double)q->p[0] - h[0], ey = (double)q->p[1] - h[1], ez = (double)q->p[2] - h[2];
        q->best = REFL__MIN(q->best, ex * ex + ey * ey + ez * ez);
    }
}

/* The distance from p to the nearest hit, at most g->cell. */
static float refl__lem_near_distance(const refl__lem_near *g, const float *p) {
    refl__lem_near_query q;
    q.p = p;
    q.best = (double)g->cell * g->cell;
    refl_kdtree_query(g->tree, refl__lem_near_box, refl__lem_near_leaf, &q);
    return (float)sqrt(q.best);
}

/* Layer `layer`'s direct-image target along the ray (o, d), continued as
   the records' exit rays are: its first hit in the layer that no nearer
   hit of a later layer hides, at *at; 0 where none (target alpha 0; the
   environment on the outermost layer, *at unset). */
static int refl__lem_direct_target(const refl_scene *scene, const refl_ray_caster *caster,
                                   const refl__lem_layering *lay, int layer, refl_vec3 o, refl_vec3 d,
                                   float target[4], refl_vec3 *at, long long *rays) {
    refl__lem_hit hits[REFL__LEM_MAX_HITS];
    int nh, k, deepest, hl;
    target[0] = target[1] = target[2] = target[3] = 0.0f;
    nh = refl__lem_exit_hits(scene, caster, o, d, lay->centre, lay->own, refl__lem_depth_left(lay->depth, NULL), hits,
                             REFL__LEM_MAX_HITS, rays);
    for (k = 0, deepest = 0; k < nh && deepest <= layer; ++k) {
        hl = refl__lem_hit_layer(lay, &hits[k]);
        deepest = REFL__MAX(deepest, hl);
        if (hl == layer && deepest == layer) {
            memcpy(target, hits[k].rgb, 3 * sizeof(float));
            target[3] = 1.0f;
            *at = hits[k].position;
            return 1;
        }
    }
    if (layer == lay->layers - 1) { /* the outermost layer is opaque: the environment past everything */
        float rgb[3];
        refl_environment_lookup(&scene->environment, d, rgb);
        for (k = 0; k < 3; ++k) target[k] = REFL__RADIANCE(rgb[k]);
        target[3] = 1.0f;
    }
    return 0;
}

/* One direct-image row: the ray (o, d)'s lookup on the shell, its target
   (refl__lem_direct_target) weighed by how likely the lens images miss
   it: 1 minus the texels' coverage by their rows (cov), or by the
   distance of its hit from the nearest of their hits in the layer
   (near: (distance / cell)^2, 1 from a cell on; a ray that meets nothing
   in an inner layer adds nothing, one on the outermost layer is measured
   from its point on the shell). */
static refl_result refl__lem_direct_row(const refl_scene *scene, const refl_ray_caster *caster,
                                        const refl__lem_layering *lay, const refl_lem_shell *shell, int layer,
                                        const float *cov, const refl__lem_near *near, refl_vec3 o, refl_vec3 d,
                                        refl_lem_system *sys, long long *rays, int *added) {
    refl_vec3 index, at;
    uint32_t tex[4];
    float w[4], target[4], held = 0.0f, conf = 1.0f;
    int k, got;
    refl_result r;
    if (!refl_lem_shell_index(shell, o, d, &index) || !refl_lem_shell_texels(shell, index, tex, w)) return REFL_OK;
    if (!near) {
        for (k = 0; k < 4; ++k) held += w[k] * cov[tex[k]];
        conf = 1.0f - REFL__MIN(held, 1.0f);
        if (!(conf > 0.0f)) return REFL_OK; /* the lens images hold it */
    }
    got = refl__lem_direct_target(scene, caster, lay, layer, o, d, target, &at, rays);
    if (near) {
        float f;
        if (!got && (layer < lay->layers - 1 || !refl__lem_shell_point(shell, index, &at))) return REFL_OK;
        f = near->tree ? refl__lem_near_distance(near, &at.x) / near->cell : 1.0f;
        conf = f * f;
    }
    if (!refl__all_finite(target, 3)) return REFL_OK; /* radiance past float's range: as a record's, no row */
    r = refl_lem_system_add_row(sys, tex, w, 4, target, conf);
    if (r == REFL_OK && conf > 0.0f) ++*added;
    return r;
}

static refl_result refl__lem_direct_rows(const refl_scene *scene, const refl_ray_caster *caster,
                                         const refl__lem_layering *lay, const refl_lem_shell *shell, int layer,
                                         const refl__lem_direct *how, refl_lem_system *sys, long long *rays,
                                         int *added) {
    const refl_allocator *a = &sys->allocator;
    int n = shell->face_size, face, x, y, s;
    float *cov = NULL;
    refl__lem_near near;
    long long e;
    refl_result r = REFL_OK;
    memset(&near, 0, sizeof near);
    if (how->distance) {
        /* a quarter of a texel's side at the layer's mean distance (2 r / n
           at a face's centre): no farther than that from a lens image's
           hit, a point is held by less (of two texels: worse than the
           coverage on `hybrid` and `glass`, docs/methods/layered_em.md) */
        float cell = 0.5f * REFL__MAX(shell->radius, 1e-6f) / (float)REFL__MAX(n, 1);
        if (!refl__lem_near_build(&near, how->points, how->count, cell, a)) return REFL_ERROR_OUT_OF_MEMORY;
    } else {
        /* how much of each texel the lens images' rows already hold */
        cov = (float *)refl__calloc(a, (size_t)sys->texels, sizeof(float));
        if (!cov) return REFL_ERROR_OUT_OF_MEMORY;
        for (e = 0; e < sys->entries; ++e) cov[sys->col[e]] += sys->w[e];
    }
    for (s = 0; how->viewpoint && s < how->per && r == REFL_OK; ++s) {
        /* from the sample's views, the lens left out: each pixel's ray
           from its point nearest the lens's centre on */
        const int *rect = how->rect[s];
        refl__view_rays vr;
        refl__view_rays_init(&vr, &how->views[s], scene);
        for (y = rect[1]; y < rect[3] && r == REFL_OK; y += how->stride)
            for (x = rect[0]; x < rect[2] && r == REFL_OK; x += how->stride) {
                refl_vec3 o, d;
                float tmax, t;
                refl__view_rays_get(&vr, (float)x + 0.5f * how->stride, (float)y + 0.5f * how->stride, &o, &d, &tmax);
                t = refl_v3_dot(refl_v3_sub(lay->centre, o), d) / refl_v3_dot(d, d);
                if (!(t > 0.0f)) continue;
                r = refl__lem_direct_row(scene, caster, lay, shell, layer, cov, how->distance ? &near : NULL,
                                         refl_v3_add(o, refl_v3_scale(d, t)), d, sys, rays, added);
            }
    }
    if (how->viewpoint && r == REFL_OK) {
        /* the viewpoint's rays reach only what lies past the lens from the
           views: the texels its reflected exit rays alone look up (the sky
           above a mirror cup's rim) would be solved to 0, or to what CGLS
           carries over from a neighbour's faint row, and drawn black; the
           centre's rows below, weighed by the coverage, hold what the
           lens images and the viewpoint's rows leave unheld */
        if (!cov) cov = (float *)refl__calloc(a, (size_t)sys->texels, sizeof(float));
        if (!cov) r = REFL_ERROR_OUT_OF_MEMORY;
        else memset(cov, 0, (size_t)sys->texels * sizeof(float));
        for (e = 0; r == REFL_OK && e < sys->entries; ++e) cov[sys->col[e]] += sys->w[e];
    }
    /* from the lens's centre towards every texel's point on the shell */
    for (face = 0; face < 6 && r == REFL_OK; ++face)
        for (y = 0; y < n && r == REFL_OK; ++y)
            for (x = 0; x < n && r == REFL_OK; ++x) {
                refl_vec3 p;
                if (!refl__lem_shell_point(shell, refl__lem_texel_direction(face, x, y, n), &p)) continue;
                r = refl__lem_direct_row(scene, caster, lay, shell, layer, cov,
                                         how->distance && !how->viewpoint ? &near : NULL, lay->centre,
                                         refl_v3_normalize(refl_v3_sub(p, lay->centre)), sys, rays, added);
            }
    refl__free(a, cov);
    refl_kdtree_destroy(near.tree);
    return r;
}

/* ---- layers: LBG over hit distances ------------------------------------------------ */

static int refl__lem_cmp_float(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y;
}

static int refl__lem_cmp_i64(const void *a, const void *b) {
    long long x = *(const long long *)a, y = *(const long long *)b;
    return x < y ? -1 : x > y;
}

/* Each hit's object as a dense number (0 .. distinct objects - 1, in the
   order of the objects' own numbers; -1 where object[i] < 0) into dense[]:
   the hits sorted by object, so the time and memory are count log count
   whatever the object numbers. The number of distinct objects, or -1 for
   no memory. */
static int refl__lem_dense_objects(const int *object, int count, const refl_allocator *a, int *dense) {
    long long *key = (long long *)refl__calloc(a, (size_t)count, sizeof(long long));
    int n = 0, i, objects = 0;
    if (!key) return -1;
    for (i = 0; i < count; ++i) {
        dense[i] = -1;
        if (object[i] >= 0) key[n++] = (long long)object[i] << 32 | i;
    }
    qsort(key, (size_t)n, sizeof *key, refl__lem_cmp_i64);
    for (i = 0; i < n; ++i) {
        if (i > 0 && key[i] >> 32 != key[i - 1] >> 32) ++objects;
        dense[key[i] & 0xffffffff] = objects;
    }
    refl__free(a, key);
    return n > 0 ? objects + 1 : 0;
}

/* LBG's clustering state over the hits' distances: per layer the mean
   distance and the count of hits; own[] each hit's layer. With objects
   (numbered densely: refl__lem_dense_objects), votes (objects x layers)
   is scratch for the whole-object rule. */
typedef struct refl__lem_lbg {
    const float *distance;
    const int *object;
    int count, layers, objects;
    long long *votes;
} refl__lem_lbg;

/* The layer of the mean nearest distance d (the lower layer on a tie). */
static int refl__lem_lbg_nearest(const refl__lem_lbg *g, const double *mean, float d) {
    int l, best = 0;
    for (l = 1; l < g->layers; ++l)
        if (fabs(d - mean[l]) < fabs(d - mean[best])) best = l;
    return best;
}

/* Each object's hits counted by layer: their layers own[], or with own
   NULL the layers of their nearest means. */
static void refl__lem_lbg_votes(const refl__lem_lbg *g, const int *own, const double *mean) {
    int i;
    memset(g->votes, 0, sizeof(long long) * (size_t)g->objects * (size_t)g->layers);
    for (i = 0; i < g->count; ++i)
        if (g->object[i] >= 0)
            ++g->votes[(size_t)g->object[i] * (size_t)g->layers +
                       (size_t)(own ? own[i] : refl__lem_lbg_nearest(g, mean, g->distance[i]))];
}

/* The paper's whole-object rule: the layer holding most of object o's
   hits (the lower layer on a tie). */
static int refl__lem_lbg_majority(const refl__lem_lbg *g, int o) {
    const long long *v = g->votes + (size_t)o * (size_t)g->layers;
    int l, best = 0;
    for (l = 1; l < g->layers; ++l)
        if (v[l] > v[best]) best = l;
    return best;
}

/* Each layer's mean distance over its hits (an empty layer keeps its
   mean); the distortion, the squared distances from them summed. */
static double refl__lem_lbg_means(const refl__lem_lbg *g, const int *own, double *mean) {
    double acc[REFL_LEM_MAX_LAYERS] = {0.0}, sum = 0.0;
    long long cnt[REFL_LEM_MAX_LAYERS] = {0};
    int i, l;
    for (i = 0; i < g->count; ++i) acc[own[i]] += g->distance[i], ++cnt[own[i]];
    for (l = 0; l < g->layers; ++l)
        if (cnt[l]) mean[l] = acc[l] / (double)cnt[l];
    for (i = 0; i < g->count; ++i) sum += (g->distance[i] - mean[own[i]]) * (g->distance[i] - mean[own[i]]);
    return sum;
}

/* How many layers own[] leaves with hits. */
static int refl__lem_lbg_used(const refl__lem_lbg *g, const int *own) {
    int i, l, used = 0, mask = 0;
    for (i = 0; i < g->count; ++i) mask |= 1 << own[i];
    for (l = 0; l < g->layers; ++l) used += (mask >> l) & 1;
    return used;
}

/* Lloyd's iterations from mean[]: each hit to its nearest mean, the means
   recomputed, until no hit moves (at most 200). The whole-object rule
   (with object ids) after every assignment when whole_each_step, else
   once at the end. The distortion of the final layers own[]. */
static double refl__lem_lbg_run(const refl__lem_lbg *g, double *mean, int whole_each_step, int *own) {
    int i, it, changed = 1, whole = whole_each_step && g->objects;
    for (i = 0; i < g->count; ++i) own[i] = -1;
    for (it = 0; it < 200 && changed; ++it) {
        changed = 0;
        if (whole) refl__lem_lbg_votes(g, NULL, mean);
        for (i = 0; i < g->count; ++i) {
            int best = whole && g->object[i] >= 0 ? refl__lem_lbg_majority(g, g->object[i])
                                                  : refl__lem_lbg_nearest(g, mean, g->distance[i]);
            changed |= own[i] != best;
            own[i] = best;
        }
        refl__lem_lbg_means(g, own, mean);
    }
    if (!whole && g->objects) {
        refl__lem_lbg_votes(g, own, NULL);
        for (i = 0; i < g->count; ++i)
            if (g->object[i] >= 0) own[i] = refl__lem_lbg_majority(g, g->object[i]);
    }
    return refl__lem_lbg_means(g, own, mean);
}

/* The starts for `layers` means from sorted values v[0..n): their
   quantiles (deterministic where the paper draws at random). */
static void refl__lem_lbg_quantiles(const float *v, int n, int layers, double *mean) {
    int l;
    for (l = 0; l < layers; ++l) mean[l] = v[(size_t)(((double)l + 0.5) / layers * n)];
}

REFL_API int refl_lem_cluster_layers(const float *distance, const int *object, const int *ray, int count, int layers,
                                     const refl_allocator *a, float *radius, int *layer_of) {
    double mean[REFL_LEM_MAX_LAYERS], acc[REFL_LEM_MAX_LAYERS];
    long long cnt[REFL_LEM_MAX_LAYERS];
    long long ahead[REFL_LEM_MAX_LAYERS][REFL_LEM_MAX_LAYERS]; /* [a][b]: rays meeting a's hits before b's */
    int *own = NULL, *other = NULL, *dense = NULL, i, l, k = 0, ok, met = 0, remap[REFL_LEM_MAX_LAYERS],
        order[REFL_LEM_MAX_LAYERS];
    float *sorted = NULL;
    double *object_acc = NULL;
    refl__lem_lbg g;
    if (!distance || count <= 0 || layers <= 0 || !radius) return 0;
    for (i = 0; i < count; ++i)
        if (!refl__isfinite(distance[i])) return 0;
    memset(&g, 0, sizeof g);
    g.distance = distance;
    g.count = count;
    g.layers = layers = REFL__MIN(layers, REFL_LEM_MAX_LAYERS);
    own = layer_of ? layer_of : (int *)refl__calloc(a, (size_t)count, sizeof(int));
    sorted = (float *)refl__calloc(a, (size_t)count, sizeof(float));
    ok = own && sorted;
    if (ok && object) { /* objects numbered densely: votes are objects x layers */
        dense = (int *)refl__calloc(a, (size_t)count, sizeof(int));
        ok = dense && (g.objects = refl__lem_dense_objects(object, count, a, dense)) >= 0;
        g.object = dense;
    }
    if (ok && g.objects) {
        other = (int *)refl__calloc(a, (size_t)count, sizeof(int));
        g.votes = (long long *)refl__calloc(a, (size_t)g.objects * (size_t)layers, sizeof(long long));
        object_acc = (double *)refl__calloc(a, 2 * (size_t)g.objects, sizeof(double));
        ok = other && g.votes && object_acc;
    }
    if (ok) {
        /* the paper's LBG: from the quantiles of the hits' distances, each
           hit to its nearest layer until none moves, then every object whole
           in the layer holding most of its hits */
        double distortion;
        memcpy(sorted, distance, sizeof(float) * (size_t)count);
        qsort(sorted, (size_t)count, sizeof(float), refl__lem_cmp_float);
        refl__lem_lbg_quantiles(sorted, count, layers, mean);
        distortion = refl__lem_lbg_run(&g, mean, 0, own);
        if (g.objects) {
            /* A dense object's spread of distances holds those quantiles, and
               Lloyd's iterations over its hits drag a small object's few hits
               into one of its layers (a ball at a concave mirror's focus with
               the near floor), where the whole-object rule then moves the
               dense object too: a layer lost. A second start, from the
               quantiles of the objects' mean distances (each object once),
               the whole-object rule applied at every step so that objects,
               not hits, move: kept where it leaves more layers than the
               paper's start at a lower distortion */
            double other_mean[REFL_LEM_MAX_LAYERS];
            int m = 0;
            for (i = 0; i < count; ++i)
                if (dense[i] >= 0) object_acc[2 * dense[i]] += distance[i], object_acc[2 * dense[i] + 1] += 1.0;
            for (i = 0; i < g.objects; ++i)
                if (object_acc[2 * i + 1] > 0.0) sorted[m++] = (float)(object_acc[2 * i] / object_acc[2 * i + 1]);
            qsort(sorted, (size_t)m, sizeof(float), refl__lem_cmp_float);
            if (m > 0) {
                refl__lem_lbg_quantiles(sorted, m, layers, other_mean);
                if (refl__lem_lbg_run(&g, other_mean, 1, other) < distortion &&
                    refl__lem_lbg_used(&g, other) > refl__lem_lbg_used(&g, own))
                    memcpy(own, other, sizeof(int) * (size_t)count);
            }
        }
    }
    refl__free(a, other);
    refl__free(a, dense);
    refl__free(a, g.votes);
    refl__free(a, object_acc);
    if (!ok) {
        if (own != layer_of) refl__free(a, own);
        refl__free(a, sorted);
        return 0;
    }
    /* the shells: the mean distance of each layer's hits, a continued ray
       counted by its front-most hit in the layer (hits of a ray come
       together, nearest first: the layers its run has met so far) */
    for (l = 0; l < layers; ++l) acc[l] = 0.0, cnt[l] = 0;
    for (i = 0; i < count; ++i) {
        if (!ray || i == 0 || ray[i] != ray[i - 1]) met = 0;
        if (!(met & 1 << own[i])) acc[own[i]] += distance[i], ++cnt[own[i]];
        met |= 1 << own[i];
    }
    /* empty layers dropped */
    k = 0;
    for (l = 0; l < layers; ++l)
        if (cnt[l]) mean[k] = acc[l] / (double)cnt[l], remap[l] = k++;
        else remap[l] = -1;
    for (i = 0; i < count; ++i) own[i] = remap[own[i]];
    /* the order they composite in (L1 over L2 ...): front to back along
       the continued rays, a layer before another when more rays meet its
       hits first than the other's (a teapot standing on a floor hides the
       floor behind it, the floor never the teapot, though the floor's hits
       may lie nearer on average); by distance where the rays do not tell */
    memset(ahead, 0, sizeof ahead);
    for (i = 0; ray && i < count;) {
        int end, seen = 0;
        for (end = i; end < count && ray[end] == ray[i]; ++end) {
            if (seen & (1 << own[end])) continue;
            for (l = 0; l < k; ++l)
                if (seen & (1 << l)) ++ahead[l][own[end]];
            seen |= 1 << own[end];
        }
        i = end;
    }
    for (l = 0; l < k; ++l) radius[l] = (float)mean[l], order[l] = l;
    for (l = 1; l < k; ++l) /* insertion sort */
        for (i = l; i > 0; --i) {
            int a = order[i], b = order[i - 1], t;
            if (!(ahead[a][b] > ahead[b][a] || (ahead[a][b] == ahead[b][a] && mean[a] < mean[b]))) break;
            t = order[i], order[i] = order[i - 1], order[i - 1] = t;
        }
    for (l = 0; l < k; ++l) radius[l] = (float)mean[order[l]], remap[order[l]] = l;
    for (i = 0; i < count; ++i) own[i] = remap[own[i]];
    if (own != layer_of) refl__free(a, own);
    refl__free(a, sorted);
    return k;
}

/* A copy of n elements of `size` bytes of *arr in a new array of cap
   (freeing the old); 0 when out of memory (*arr kept). */
static int refl__lem_hits_array(const refl_allocator *al, void **arr, int n, int cap, size_t size) {
    void *fresh = refl__calloc(al, (size_t)cap, size);
    if (!fresh) return 0;
    if (n) memcpy(fresh, *arr, (size_t)n * size);
    refl__free(al, *arr);
    *arr = fresh;
    return 1;
}

/* h's arrays twice as long (1024 at first); 0 when out of memory. */
static int refl__lem_hits_grow(refl__lem_hits *h) {
    int cap = h->cap ? 2 * h->cap : 1024;
    if (!refl__lem_hits_array(h->al, (void **)&h->distance, h->count, cap, sizeof(float)) ||
        !refl__lem_hits_array(h->al, (void **)&h->pos, h->count, cap, 3 * sizeof(float)) ||
        !refl__lem_hits_array(h->al, (void **)&h->rgb, h->count, cap, 3 * sizeof(float)) ||
        !refl__lem_hits_array(h->al, (void **)&h->exit, h->count, cap, 6 * sizeof(float)) ||
        !refl__lem_hits_array(h->al, (void **)&h->object, h->count, cap, sizeof(int)) ||
        !refl__lem_hits_array(h->al, (void **)&h->ray, h->count, cap, sizeof(int)) ||
        !refl__lem_hits_array(h->al, (void **)&h->view, h->count, cap, sizeof(int)))
        return 0; /* the arrays grown so far are longer: harmless, cap stays */
    h->cap = cap;
    return 1;
}

static void refl__lem_hits_free(refl__lem_hits *h) {
    refl__free(h->al, h->distance), refl__free(h->al, h->pos), refl__free(h->al, h->rgb);
    refl__free(h->al, h->exit), refl__free(h->al, h->object), refl__free(h->al, h->ray);
    refl__free(h->al, h->view);
    h->distance = h->pos = h->rgb = h->exit = NULL;
    h->object = h->ray = h->view = NULL;
}

/* The hits of the centre rays of a view's lens pixels, in pixel order, for
   the clustering (with continue_box, the lens's world box, the pixels
   whose eye ray reaches the lens through what hides it too:
   refl__lem_eye_paths): appended to the arrays of *h. 0 when out of
   memory. */
static int refl__lem_gather_hits(const refl_scene *scene, const refl_ray_caster *caster, const refl_view *view,
                                 int object, int max_interfaces, int own, const refl_vec3 *continue_box,
                                 refl_vec3 centre, refl__lem_hits *h, long long *rays) {
    refl__view_rays vr;
    refl__gp_casters paths;
    int x, y, term, k;
    paths.scene = caster;
    paths.lenses = paths.others = NULL;
    paths.own = own;
    refl__view_rays_init(&vr, view, scene);
    for (y = 0; y < view->height; ++y)
        for (x = 0; x < view->width; ++x) {
            refl_greedy_paths_result g;
            refl_vec3 o, d;
            float tmax;
            refl__view_rays_get(&vr, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
            if (!refl__lem_eye_paths(scene, &paths, o, d, object, max_interfaces, continue_box, &g, rays)) continue;
            for (term = 0; term < 2; ++term) {
                const refl_greedy_path *p = term ? &g.refract : &g.reflect;
                refl__lem_hit hits[REFL__LEM_MAX_HITS];
                int n;
                if (!(p->fresnel > 0.0f) || !p->exited) continue;
                n = refl__lem_exit_hits(scene, caster, p->exit_origin, p->exit_direction, centre, own,
                                        refl__lem_depth_left(max_interfaces, p), hits, REFL__LEM_MAX_HITS, rays);
                for (k = 0; k < n; ++k) {
                    if (h->count == h->cap && !refl__lem_hits_grow(h)) return 0;
                    h->distance[h->count] = hits[k].distance;
                    h->pos[3 * (size_t)h->count] = hits[k].position.x;
                    h->pos[3 * (size_t)h->count + 1] = hits[k].position.y;
                    h->pos[3 * (size_t)h->count + 2] = hits[k].position.z;
                    memcpy(h->rgb + 3 * (size_t)h->count, hits[k].rgb, 3 * sizeof(float));
                    memcpy(h->exit + 6 * (size_t)h->count, &p->exit_origin, sizeof p->exit_origin);
                    memcpy(h->exit + 6 * (size_t)h->count + 3, &p->exit_direction, sizeof p->exit_direction);
                    h->object[h->count] = hits[k].object;
                    h->ray[h->count] = h->rays;
                    h->view[h->count] = h->views;
                    ++h->count;
                }
                ++h->rays;
            }
        }
    ++h->views;
    return 1;
}

REFL_API refl_result refl_lem_record_view(refl_lem_system *system, const refl_scene *scene,
                                          const refl_ray_caster *caster, const refl_view *view,
                                          const refl_lem_shell *shell, const refl_lem_record_desc *desc,
                                          refl_lem_record_stats *stats) {
    refl_lem_record_stats st;
    refl__view_rays rays;
    refl__lem_layering one;
    int ss, x, y, term;
    refl_result r = REFL_OK;
    memset(&st, 0, sizeof st);
    if (stats) *stats = st;
    if (!system || !scene || !caster || !caster->intersect || !view || !shell || !desc) return REFL_ERROR_INVALID_ARGUMENT;
    if (desc->object < 0 || desc->object >= scene->object_count) return REFL_ERROR_INVALID_ARGUMENT;
    if (view->width <= 0 || view->height <= 0) return REFL_ERROR_INVALID_SIZE;
    if (6LL * shell->face_size * shell->face_size != system->texels) return REFL_ERROR_INVALID_ARGUMENT;
    ss = desc->supersample > 0 ? REFL__MIN(desc->supersample, REFL__LEM_MAX_SS) : 3;
    refl__view_rays_init(&rays, view, scene);
    memset(&one, 0, sizeof one);
    one.own = -1;
    one.layers = 1;
    one.radius[0] = shell->radius;
    one.shell[0] = *shell;
    one.centre = shell->center;
    for (y = 0; y < view->height && r == REFL_OK; ++y)
        for (x = 0; x < view->width && r == REFL_OK; ++x) {
            refl_greedy_paths_result centre;
            float rec[10];
            if (!refl__lem_pixel_records(scene, caster, &rays, x, y, desc->object, ss, desc->theta_c_degrees,
                                         desc->max_interfaces, &one, rec, NULL, &centre, &st.rays))
                continue;
            ++st.pixels;
            for (term = 0; term < 2 && r == REFL_OK; ++term) {
                const refl_greedy_path *cp = term ? &centre.refract : &centre.reflect;
                uint32_t tex[4];
                float w[4];
                if (!(cp->fresnel > 0.0f) || !cp->exited || rec[5 * term + 4] < 0.0f ||
                    !refl_lem_shell_lookup(shell, cp->exit_origin, cp->exit_direction, tex, w))
                    continue;
                r = refl_lem_system_add_row(system, tex, w, 4, rec + 5 * term, rec[5 * term + 4]);
                if (r == REFL_OK) ++st.rows;
            }
        }
    if (stats) *stats = st;
    return r;
}
