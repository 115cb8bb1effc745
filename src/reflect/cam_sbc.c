/* cam_sbc: the sample-based camera (SBC) of paper 003, section IV.
   One reflection group's projection function, built from a ray map: each
   reflected ray has a tail (where it leaves the last reflector), a head
   (where it leaves the scene box) and the first reflector point the
   desired view sees along it. The rays are decomposed into a BSP tree
   (BuildBSP, the paper's Fig. 10) whose leaves hold planar pinhole cameras
   fitted to their rays, or, where no camera fits, the rays themselves.

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
   it is below error_px.
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
   along any line the drift is linear in s. Without the term a 4 x 4
   patch of a 4,000-triangle teapot's rays errs by 1.35 px at 320 x 240,
   with it 0.49 px. The error is also checked half-way along each ray (in
   s), so the bound holds between a ray's ends, not only at them.

   Beyond runtime mode: desc.widen grows each accepted camera's rectangle
   (paper 003 VI, "extends the field of view of the BSP leaf cameras"), so
   a morphing grid's node projects points just outside its ray map; off by
   default, leaving runtime mode's projections unchanged.

   Split (the paper's heuristic, with the changes said at
   refl__sbc_split): the plane through the tails' centroid,
   parallel to the mean ray direction, perpendicular to the tails' principal
   axis (made orthogonal to the mean direction). A ray goes left when any
   tail or head of its unit frustum (itself and its ray-map neighbours
   u +- 1, v +- 1 in the set) lies on the plane's positive side (or on it),
   right when any lies on the negative side; rays near the plane go both
   ways, so a point of either half space that lies among the set's rays
   lies among the rays of that side's subset. Splitting fails when a subset
   is the whole set (the paper), when half the set would go both ways (a
   few unit frustums across, every cut keeps nearly all rays on both sides
   and the cells would multiply without end) and at max_depth: the rays
   are then stored as a ray list. Cutting on until three quarters go both
   ways keeps ray lists shorter (default scene, 640x480: 26% faster) but
   put a strongly curved sphere's points up to 16 px off (2 px now; tests/
   reflect/test_sbc_stability.c).

   Projection: down the tree by the side of each plane (s >= 0: left). A
   pinhole leaf projects as above (z: p's height over the image plane). A
   ray-list leaf searches its unit frustums, the 2 x 2 quads of its rays:
   p lies in one at (s, t) in [0, 1]^2 when it lies on the bilinearly
   interpolated ray (s, t). Each quad is sliced across its mean direction
   m: at p's slice tau = (p - o) . m each ray is one point of the slice,
   so (s, t) is an inverse bilinear interpolation in 2D, and the answer is
   the four first points blended at (s, t) (z: the blended distance along
   the rays from their tails); the nearest such quad wins. Adjacent quads
   share their edge rays, so the blend is continuous to within the
   rays' skewness. Where no quad holds p, the one p lies nearest outside
   (within REFL__SBC_NEAR of its diagonal) answers at its clamped (s, t):
   at a fold the quads around a ray cover only some sides of it, and a
   point a hair off the ray fell in none (default scene, 640x480 factor
   2: 1.3% of the ray-list samples did not project through their own
   group, 0.1% now; refl_sbc_measure_camera_error).
   Sheets (beyond the paper, its section VII-C's proposal): where rays
   cross (a focusing mirror, a crease) a point lies in several quads, and
   one image per group (the nearest, as refl_sbc_project keeps) shows it
   in one place only. Each quad knows the slices where its four rays fold
   (its signed area, a quadratic along m, is zero; folds behind the tails
   do not count) and a point past k of them lies in the quad's sheet k:
   refl_sbc_project_sheets returns the nearest image per sheet, in one
   search. Default scene, 640x480, factor 2, ray-list samples through
   their own group: p95 1.44 -> 0.08 px; the concave bowl 2.80 -> 0.14 px.

   Deterministic: lists keep ray-map order, nothing is sorted or drawn at
   random, every sum runs in a fixed order. */
#include "internal.h"

/* zero: an empty ray list, what a fresh node is until it is built */
enum { REFL__SBC_RAYS = 0, REFL__SBC_PINHOLE = 1, REFL__SBC_INNER = 2 };

typedef struct refl__sbc_node {
    double plane[4];         /* inner: n . p + plane[3] >= 0 goes left */
    int child;               /* inner: left child, the right one follows; leaf: -1 */
    int kind;
    int first, count;        /* pinhole: camera index; rays: quads [first, first + count) */
    float box[6];            /* rays: the box its quads lie in (lows, then highs); what lies outside
                                is no quad's, and a point not projecting is found so at once */
    int grid;                /* rays: its index (refl__sbc_index) + 1; 0: none, every quad is tried */
} refl__sbc_node;

/* A ray-list leaf's index: slabs across the leaf's mean ray direction m,
   each cut in cells across it, each cell listing the quads whose region
   (the hull of its lateral boxes at both ends) meets it. A point then
   tries the quads of its cell only: the concave bowl's leaves hold about
   1,000 quads each, and its 640x480 frame took 3.1 s with every quad
   tried, 1.6 s with the index; the teapot's leaves are short (80 quads)
   and their quads' world boxes already stop most, so it gains 4%. */
#define REFL__SBC_INDEX_MIN 16 /* quads in a leaf, at least, for an index */
typedef struct refl__sbc_index {
    double o[3], m[3], a[3], b[3]; /* the leaf's frame: t along m, x along a, y along b */
    double t0, t_scale;      /* slab = (t - t0) t_scale */
    double x0, x_scale, y0, y_scale; /* cell = (x - x0) x_scale, (y - y0) y_scale */
    int slabs, cells;        /* slabs, and cells per side of one */
    int start;               /* cell_start[start + (slab * cells + y) * cells + x]: its list */
} refl__sbc_index;

typedef struct refl__sbc_cam {
    double o[3], c[3], n[3], eu[3], ev[3];
    double ho;               /* (o - c) . n: < 0 diverging, > 0 converging */
    double hmin;             /* the lowest (p - c) . n that projects */
    double ocu, ocv;         /* (o - c) in the plane's basis */
    double rect[4];          /* frustum: umin, umax, vmin, vmax */
    double norm[4];          /* u, v centre and inverse half size: to [-1, 1] */
    double coef[3][12];       /* f per coordinate over 1, u, v, u^2, uv, v^2, s, s u, s v */
} refl__sbc_cam;

/* A unit frustum of a ray list: rays (u, v), (u + 1, v), (u, v + 1),
   (u + 1, v + 1), sliced across its mean direction m: at tau = (p - o) . m
   each ray is one point of the lateral plane (a, b), and p lies on the
   bilinearly interpolated ray (s, t) when its lateral position is the
   bilinear blend of the four at (s, t). */
typedef struct refl__sbc_quad {
    int idx;                 /* ray-map index of its (u, v) corner */
    float o[3], m[3], a[3], b[3];
    float tau[2];            /* its tails' lowest and (a quarter past) heads' highest tau */
    float box[2][4];         /* lateral xmin, xmax, ymin, ymax at tau[0] and tau[1], padded:
                                between them the lerp bounds the rays (min of lines is concave) */
    float inv_span;          /* 1 / (tau[1] - tau[0]), for the float pre-test */
    float o_size;            /* |o.x| + |o.y| + |o.z|: the pre-test's rounding scale */
    float aabb[6];           /* its region's world box (lows, highs), padded: the first pre-test */
    float fold[2];           /* the slices where its rays fold (ascending; FLT_MAX: none) */
    float ray[4][6];         /* per ray in its frame: tail - o along m, a, b, then head - tail along m, a, b */
    float len[4];            /* per ray: |head - tail| */
} refl__sbc_quad;

/* A point nearer its interpolated ray's tail than this (0 tail, 1 head)
   lies on the reflector: heads are twice as far as what the rays meet, so
   what they reflect lies near 0.5. */
#define REFL__SBC_ON_SURFACE 0.02

/* The exact test's (s, t) tolerance, and the fallback's reach for a point
   no quad holds: its lateral distance to a quad (at clamped (s, t)), in
   the quad's diagonals. Near a fold (a caustic: a neighbour ray crossing
   the sample's) the quads around a ray do not cover all sides of it, and
   a point a hair off the ray (a pixel's own reflected ray, not the
   sample's) lies in none of them. */
#define REFL__SBC_TOL 1e-4
#define REFL__SBC_NEAR 0.01

/* A quad's frame in double: what build and projection both compute with. */
typedef struct refl__sbc_frame {
    double o[3], m[3], a[3], b[3];
} refl__sbc_frame;

struct refl_sbc {
    refl_allocator allocator;
    int width, height;
    refl__sbc_node *nodes;
    int node_count, node_cap;
    refl__sbc_cam *cams;
    int cam_count, cam_cap;
    refl__sbc_quad *quads;
    int quad_count, quad_cap;
    refl__sbc_index *indexes; /* the ray-list leaves' */
    int index_count, index_cap;
    int *cell_start;         /* per index cell, then one past the last: where its list starts */
    int cell_start_count, cell_start_cap;
    int *cell_quads;         /* the lists: quads, from their leaf's first */
    int cell_quad_count, cell_quad_cap;
    refl_sbc_ray *rays;      /* a copy of the map, only when there are ray lists */
    refl_sbc_stats stats;
};

/* ---- reflected rays, shared by the SBC method (m_sbc.c) and the morphing
   grids (cam_sbc_morph.c): one head rule for both ------------------------------ */

/* What a reflected ray meets first: a scene triangle and the point; object
   -1 for nothing. */
typedef struct refl__sbc_hit {
    int object, triangle;
    refl_vec3 point;
} refl__sbc_hit;

#define REFL__SBC_REACH 2.0f /* a ray's head: this many times as far as what it hits */

/* Where a ray from inside box [lo, hi] along d leaves it. */
static float refl__sbc_box_exit(refl_vec3 lo, refl_vec3 hi, refl_vec3 o, refl_vec3 d) {
    float t = INFINITY, s;
    if (d.x != 0.0f) { s = ((d.x > 0.0f ? hi.x : lo.x) - o.x) / d.x; t = REFL__MIN(t, s); }
    if (d.y != 0.0f) { s = ((d.y > 0.0f ? hi.y : lo.y) - o.y) / d.y; t = REFL__MIN(t, s); }
    if (d.z != 0.0f) { s = ((d.z > 0.0f ? hi.z : lo.z) - o.z) / d.z; t = REFL__MIN(t, s); }
    return REFL__MAX(t, 0.0f);
}

/* The ray from q along unit r in a scene (its BVH, its box [lo, hi], grown,
   and that box's diagonal): tail = first = q, head REFL__SBC_REACH times as
   far as what it meets plus 1% of the diagonal, or a tenth of the diagonal
   when it meets nothing, within the box; what it meets in *met. 0 for a
   ray of zero length. */
static int refl__sbc_scene_ray(const refl_bvh *bvh, refl_vec3 lo, refl_vec3 hi, float diagonal, refl_vec3 q,
                               refl_vec3 r, refl_sbc_ray *ray, refl__sbc_hit *met) {
    refl_hit hit;
    float reach = refl__sbc_box_exit(lo, hi, q, r);
    met->object = -1;
    ray->tail = q;
    ray->first = q;
    if (refl_bvh_intersect(bvh, q, r, 1e-4f * diagonal, reach, &hit)) {
        met->object = hit.object;
        met->triangle = hit.triangle;
        met->point = refl_v3_add(q, refl_v3_scale(r, hit.t));
        reach = REFL__MIN(reach, REFL__SBC_REACH * hit.t + 0.01f * diagonal);
    } else {
        reach = REFL__MIN(reach, 0.1f * diagonal);
    }
    ray->head = refl_v3_add(q, refl_v3_scale(r, reach));
    return refl_v3_length(refl_v3_sub(ray->head, q)) > 0.0f;
}

/* A union-find root, halving the path on the way: how the method and the
   grids join samples and triangles into smooth pieces. */
static int refl__sbc_root(int *parent, int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
}

/* ---- small double helpers ---------------------------------------------------- */

static int refl__sbc_finite(double v) { return v - v == 0.0; }
static double refl__sbc_dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void refl__sbc_cross(const double *a, const double *b, double *o) {
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}
static double refl__sbc_normalize(double *a) {
    double l = sqrt(refl__sbc_dot(a, a));
    if (l > 0.0) { a[0] /= l; a[1] /= l; a[2] /= l; }
    return l;
}
static void refl__sbc_load(refl_vec3 v, double *o) { o[0] = v.x; o[1] = v.y; o[2] = v.z; }
static int refl__sbc_finite3(refl_vec3 v) { return refl__isfinite(v.x) && refl__isfinite(v.y) && refl__isfinite(v.z); }

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

/* ---- building ---------------------------------------------------------------- */

#define REFL__SBC_SMOOTH_SIN 0.5f    /* a chord leaving a tangent plane by more (30 degrees) crosses a gap */
#define REFL__SBC_SMOOTH_COS 0.7071f /* normals turning by more (45 degrees) meet at a crease */

/* Whether neighbouring samples with surface points t1, t2 and unit normals
   n1, n2 lie on one smooth piece of surface: normals turning by less than
   REFL__SBC_SMOOTH_COS (not a crease: the knob on the lid, the spout's
   joint, a silhouette turning them fast) and no gap, where the chord
   between the points leaves a tangent plane by more than
   REFL__SBC_SMOOTH_SIN (one surface passing in front of another: the knob
   before the lid, the handle before the body; the chord runs along the
   view ray). */
static int refl__sbc_smooth(refl_vec3 t1, refl_vec3 n1, refl_vec3 t2, refl_vec3 n2) {
    refl_vec3 e;
    float l;
    if (!(refl_v3_dot(n1, n2) >= REFL__SBC_SMOOTH_COS)) return 0;
    e = refl_v3_sub(t2, t1);
    l = refl_v3_length(e);
    return fabsf(refl_v3_dot(n1, e)) <= REFL__SBC_SMOOTH_SIN * l && fabsf(refl_v3_dot(n2, e)) <= REFL__SBC_SMOOTH_SIN * l;
}

typedef struct refl__sbc_task {
    int node, count, depth;
    size_t off;              /* its rays: pool[off, off + count) */
} refl__sbc_task;

typedef struct refl__sbc_builder {
    const refl_sbc_ray *rays;
    int W, H;
    double error_px;         /* INFINITY: every camera that fits is good */
    double vp[16];
    int width, height;
    int max_depth;
    double widen;            /* desc.widen: accepted cameras' rectangles grown by this */
    const uint8_t *links;    /* desc.links, or NULL */
    refl_allocator *a;
    uint8_t *valid;          /* in the group, finite, not of zero length */
    float *dir;              /* unit direction per map entry */
    double *truth;           /* desired-view pixel of each first point (NaN: behind the eye) */
    unsigned *mark;          /* stamp of the set being split */
    double *smin, *smax;     /* per set ray: lowest and highest plane side of tail and head */
    uint8_t *side;           /* per set ray: 1 left, 2 right, 3 both */
    double *uv;              /* fit scratch: 6 per ray of the set */
    int *pool;
    size_t pool_cap;
    unsigned stamp;
    refl_sbc *sbc;
} refl__sbc_builder;

/* Grows *arr (elements of size sz, capacity *cap) to hold need; 0 when out of memory. */
static int refl__sbc_grow(const refl_allocator *a, void **arr, size_t *cap, size_t need, size_t sz) {
    size_t nc;
    void *n;
    if (need <= *cap) return 1;
    nc = *cap ? *cap : 16;
    while (nc < need) {
        if (nc > ((size_t)-1) / 2 / sz) return 0;
        nc *= 2;
    }
    n = refl__alloc(a, nc * sz); /* no need to clear: every use writes first */
    if (!n) return 0;
    if (*arr) memcpy(n, *arr, *cap * sz);
    refl__free(a, *arr);
    *arr = n;
    *cap = nc;
    return 1;
}

static int refl__sbc_grow_int(const refl_allocator *a, void **arr, int *cap, int need, size_t sz) {
    size_t c = (size_t)*cap;
    if (need < 0 || need >= INT_MAX / 2) return 0;
    if (!refl__sbc_grow(a, arr, &c, (size_t)need, sz)) return 0;
    *cap = c > (size_t)(INT_MAX / 2) ? INT_MAX / 2 : (int)c;
    return 1;
}

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

/* The plane through c with normal sn, and each ray's side(s) in b->side:
   by the extent of its unit frustum's tails and heads. */
static void refl__sbc_assign(refl__sbc_builder *b, const int *list, int n, const double sn[3], const double c[3],
                             double plane[4], int *nl, int *nr) {
    int i, W = b->W, H = b->H;
    unsigned st;
    memcpy(plane, sn, 3 * sizeof(double));
    plane[3] = -refl__sbc_dot(sn, c);
    /* each ray's own extent, then its unit frustum's */
    st = ++b->stamp;
    for (i = 0; i < n; ++i) {
        const refl_sbc_ray *r = &b->rays[list[i]];
        double p[3], s0, s1;
        refl__sbc_load(r->tail, p);
        s0 = refl__sbc_dot(p, sn) + plane[3];
        refl__sbc_load(r->head, p);
        s1 = refl__sbc_dot(p, sn) + plane[3];
        b->smin[list[i]] = REFL__MIN(s0, s1);
        b->smax[list[i]] = REFL__MAX(s0, s1);
        b->mark[list[i]] = st;
    }
    *nl = *nr = 0;
    for (i = 0; i < n; ++i) {
        int idx = list[i], u = idx % W, v = idx / W, du, dv;
        int u0 = u > 0 ? -1 : 0, u1 = u + 1 < W ? 1 : 0, v0 = v > 0 ? -1 : 0, v1 = v + 1 < H ? 1 : 0;
        double lo = b->smin[idx], hi = b->smax[idx];
        for (dv = v0; dv <= v1; ++dv)
            for (du = u0; du <= u1; ++du) {
                int k = idx + dv * W + du;
                if (b->mark[k] != st) continue;
                lo = REFL__MIN(lo, b->smin[k]);
                hi = REFL__MAX(hi, b->smax[k]);
            }
        b->side[idx] = (uint8_t)((hi >= 0.0 ? 1 : 0) | (lo < 0.0 ? 2 : 0));
        if (b->side[idx] == 0) b->side[idx] = 3; /* NaN: keep it everywhere */
        *nl += b->side[idx] & 1;
        *nr += (b->side[idx] >> 1) & 1;
    }
}

/* Split: the plane and each ray's side(s) in b->side; 0 when it fails. */
static int refl__sbc_split(refl__sbc_builder *b, const int *list, int n, double plane[4], int *nl, int *nr) {
    double c[3] = {0.0, 0.0, 0.0}, m[3] = {0.0, 0.0, 0.0}, a1[3], a2[3], ax[3] = {0.0, 0.0, 0.0};
    double cAA = 0.0, cAB = 0.0, cBB = 0.0, lam, e1, e2, sn[3], sn2[3], plane2[4];
    int i, j, best = 0, nl2, nr2;
    refl__sbc_centroid(b, list, n, c, m);
    if (!(refl__sbc_normalize(m) > 0.0)) return 0;
    /* Beyond the paper, whose plane is parallel to the mean direction: the
       plane is parallel to the central ray, from the least-squares centre
       of projection o through c. Rays spreading from about o then stay on
       their side, where a plane off o is crossed by every ray whose tail
       lies between the plane and o's side of it (the heads lie at the
       scene's box, far beyond the tails: most of a set, at every level). */
    {
        double o[3], oc[3];
        if (refl__sbc_centre(b, list, n, c, o, NULL)) {
            for (j = 0; j < 3; ++j) oc[j] = c[j] - o[j];
            if (refl__sbc_dot(oc, m) < 0.0)
                for (j = 0; j < 3; ++j) oc[j] = -oc[j];
            if (refl__sbc_normalize(oc) > 0.0 && refl__sbc_dot(oc, m) > 0.5) memcpy(m, oc, sizeof m);
        }
    }
    /* the tails' scatter within the plane perpendicular to that direction */
    for (j = 1; j < 3; ++j)
        if (fabs(m[j]) < fabs(m[best])) best = j;
    ax[best] = 1.0;
    refl__sbc_cross(m, ax, a1);
    refl__sbc_normalize(a1);
    refl__sbc_cross(m, a1, a2);
    for (i = 0; i < n; ++i) {
        const refl_sbc_ray *r = &b->rays[list[i]];
        double t[3], x, y;
        t[0] = r->tail.x - c[0]; t[1] = r->tail.y - c[1]; t[2] = r->tail.z - c[2];
        x = refl__sbc_dot(t, a1);
        y = refl__sbc_dot(t, a2);
        cAA += x * x; cAB += x * y; cBB += y * y;
    }
    if (!(cAA + cBB > 0.0)) return 0;
    /* the principal axis: the diameter's direction, orthogonal to m; the
       larger eigenvector of the 2 x 2 scatter in closed form (sqrt only:
       correctly rounded, the same everywhere, unlike atan2 or cos) */
    lam = 0.5 * (cAA + cBB) + sqrt(0.25 * (cAA - cBB) * (cAA - cBB) + cAB * cAB);
    if (lam - cBB >= lam - cAA) { e1 = lam - cBB; e2 = cAB; }
    else { e1 = cAB; e2 = lam - cAA; }
    for (j = 0; j < 3; ++j) sn[j] = e1 * a1[j] + e2 * a2[j];
    if (!(refl__sbc_normalize(sn) > 0.0)) memcpy(sn, a1, sizeof sn); /* round: any axis */
    /* Beyond the paper: the plane across the other axis too, kept when
       fewer rays cross it. Where the reflector curves the rays together
       along the diameter (a saddle, a concave patch) they cross every
       plane across it, the cut gains nothing and the set ends up as a ray
       list; across the axis along which they spread, the cut is clean. */
    refl__sbc_cross(m, sn, sn2);
    refl__sbc_normalize(sn2);
    refl__sbc_assign(b, list, n, sn2, c, plane2, &nl2, &nr2);
    refl__sbc_assign(b, list, n, sn, c, plane, nl, nr);
    if ((long long)nl2 + nr2 < (long long)*nl + *nr && 4 * ((long long)*nl + *nr) > 5 * (long long)n) {
        refl__sbc_assign(b, list, n, sn2, c, plane, nl, nr);
    }
    /* the paper fails only when a subset is the whole set; below a few
       unit frustums across, though, every cut keeps nearly all rays on both
       sides and the cells would multiply without end: fail when half the
       set would go both ways */
    return *nl < n && *nr < n && 2 * ((long long)*nl + *nr) < 3 * (long long)n;
}

static void refl__sbc_frame_load(const refl__sbc_quad *q, refl__sbc_frame *f) {
    int j;
    for (j = 0; j < 3; ++j) {
        f->o[j] = q->o[j]; f->m[j] = q->m[j]; f->a[j] = q->a[j]; f->b[j] = q->b[j];
    }
}

/* The four rays' lateral positions (x, y) at slice tau of a quad's frame,
   how far along each ray (0 tail, 1 head) that slice is, and their
   lengths; 0 when a ray runs almost across the slices. */
static int refl__sbc_quad_slice(const refl__sbc_frame *q, const refl_sbc_ray *rays, int idx, int W, double tau,
                                double x[4], double y[4], double lam[4], double len[4]) {
    int c, j;
    for (c = 0; c < 4; ++c) {
        const refl_sbc_ray *r = &rays[idx + (c & 1) + (c >> 1) * W];
        double t[3], d[3], dm, l, pt[3];
        refl__sbc_load(r->tail, t);
        d[0] = (double)r->head.x - t[0]; d[1] = (double)r->head.y - t[1]; d[2] = (double)r->head.z - t[2];
        for (j = 0; j < 3; ++j) t[j] -= q->o[j];
        dm = refl__sbc_dot(d, q->m);
        len[c] = sqrt(refl__sbc_dot(d, d));
        if (!(dm > 0.05 * len[c])) return 0;
        l = (tau - refl__sbc_dot(t, q->m)) / dm;
        for (j = 0; j < 3; ++j) pt[j] = t[j] + l * d[j];
        x[c] = refl__sbc_dot(pt, q->a);
        y[c] = refl__sbc_dot(pt, q->b);
        lam[c] = l;
    }
    return 1;
}

/* A ray-list leaf's box and each of its quads': every corner of a quad's
   lateral boxes at both ends (between them the quad's region is their
   blend), padded past float rounding. */
static void refl__sbc_leaf_box(refl_sbc *s, refl__sbc_node *node) {
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, pad = 0.0;
    int i, e, c, j;
    for (i = 0; i < node->count; ++i) {
        refl__sbc_quad *q = &s->quads[node->first + i];
        double qlo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, qhi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, qpad = 0.0;
        refl__sbc_frame fr;
        refl__sbc_frame_load(q, &fr);
        for (e = 0; e < 2; ++e)
            for (c = 0; c < 4; ++c) {
                double x = q->box[e][c & 1], y = q->box[e][2 + (c >> 1)];
                for (j = 0; j < 3; ++j) {
                    double v = fr.o[j] + (double)q->tau[e] * fr.m[j] + x * fr.a[j] + y * fr.b[j];
                    qlo[j] = REFL__MIN(qlo[j], v);
                    qhi[j] = REFL__MAX(qhi[j], v);
                }
            }
        for (j = 0; j < 3; ++j) qpad = REFL__MAX(qpad, qhi[j] - qlo[j] + fabs(qlo[j]) + fabs(qhi[j]));
        for (j = 0; j < 3; ++j) {
            q->aabb[j] = (float)(qlo[j] - 1e-5 * qpad);
            q->aabb[3 + j] = (float)(qhi[j] + 1e-5 * qpad);
            lo[j] = REFL__MIN(lo[j], qlo[j]);
            hi[j] = REFL__MAX(hi[j], qhi[j]);
        }
    }
    for (j = 0; j < 3 && node->count; ++j) pad = REFL__MAX(pad, hi[j] - lo[j] + fabs(lo[j]) + fabs(hi[j]));
    for (j = 0; j < 3; ++j) { /* empty: lows above highs, nothing inside */
        node->box[j] = node->count ? (float)(lo[j] - 1e-5 * pad) : 1.0f;
        node->box[3 + j] = node->count ? (float)(hi[j] + 1e-5 * pad) : 0.0f;
    }
}

static double refl__sbc_cross2(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

/* The real roots of a t^2 + b t + c, ascending (the linear one where a is
   negligible): the textbook's cancellation-free form, without
   refl_solve_quadratic's exact scaling, which costs a tenth of a ray-list
   projection and buys nothing here (the roots are checked against [0, 1]
   with a tolerance). NaN coefficients give NaN roots, which fail that. */
static int refl__sbc_quadratic(double a, double b, double c, double r[2]) {
    double disc, q;
    if (fabs(a) <= 1e-12 * (fabs(b) + fabs(c))) {
        if (b == 0.0) return 0;
        r[0] = -c / b;
        return 1;
    }
    disc = b * b - 4.0 * a * c;
    if (disc < 0.0) return 0;
    q = -0.5 * (b + (b >= 0.0 ? sqrt(disc) : -sqrt(disc)));
    if (q == 0.0) { /* b = c = 0: a double root at 0 */
        r[0] = 0.0;
        return 1;
    }
    r[0] = REFL__MIN(q / a, c / q);
    r[1] = REFL__MAX(q / a, c / q);
    return 2;
}

/* Where a quad's rays fold between slices tau[0] and tau[1]: its four
   rays' lateral positions move linearly with the slice, so the signed area
   of their quadrilateral (half the cross product of its diagonals) is a
   quadratic in tau, exact from three slices, and it turns over at its
   roots. Returns the folds found (0 to 2). */
static int refl__sbc_quad_folds(const refl__sbc_frame *fr, const refl_sbc_ray *rays, int idx, int W,
                                const double tau[2], double fold[2]) {
    double ts[3], area[3], x[4], y[4], lam[4], len[4], a, b, roots[2];
    int i, n, found = 0;
    ts[0] = tau[0];
    ts[1] = 0.5 * (tau[0] + tau[1]);
    ts[2] = tau[1];
    for (i = 0; i < 3; ++i) {
        if (!refl__sbc_quad_slice(fr, rays, idx, W, ts[i], x, y, lam, len)) return 0;
        area[i] = refl__sbc_cross2(x[3] - x[0], y[3] - y[0], x[2] - x[1], y[2] - y[1]);
    }
    /* area(f) = a f^2 + b f + area[0] over f = (tau - tau[0]) / (tau[1] - tau[0]) in [0, 1] */
    a = 2.0 * (area[2] - 2.0 * area[1] + area[0]);
    b = area[2] - area[0] - a;
    n = refl__sbc_quadratic(a, b, area[0], roots);
    for (i = 0; i < n; ++i) {
        double t = tau[0] + roots[i] * (tau[1] - tau[0]), ahead = 0.0;
        int c;
        if (!(roots[i] > 0.0 && roots[i] < 1.0) || !refl__sbc_quad_slice(fr, rays, idx, W, t, x, y, lam, len)) continue;
        for (c = 0; c < 4; ++c) ahead += lam[c];
        /* behind the tails the rays are lines, not rays: nothing there reflects */
        if (ahead > 0.0) fold[found++] = t;
    }
    return found;
}

/* Unit a and b across unit m (m, a, b right-handed): a from m and the
   axis m leans on least. */
static void refl__sbc_across(const double *m, double *a, double *b) {
    double ax[3] = {0.0, 0.0, 0.0};
    int j, best = 0;
    for (j = 1; j < 3; ++j)
        if (fabs(m[j]) < fabs(m[best])) best = j;
    ax[best] = 1.0;
    refl__sbc_cross(m, ax, a);
    refl__sbc_normalize(a);
    refl__sbc_cross(m, a, b);
}

/* Quad q's region in index frame ix: its 8 corners (its lateral boxes'
   at both ends) as (t, x, y). */
static void refl__sbc_index_corners(const refl__sbc_index *ix, const refl__sbc_quad *q, double v[8][3]) {
    refl__sbc_frame fr;
    int e, c, j;
    refl__sbc_frame_load(q, &fr);
    for (e = 0; e < 2; ++e)
        for (c = 0; c < 4; ++c) {
            double w[3], x = q->box[e][c & 1], y = q->box[e][2 + (c >> 1)];
            for (j = 0; j < 3; ++j) w[j] = fr.o[j] + (double)q->tau[e] * fr.m[j] + x * fr.a[j] + y * fr.b[j] - ix->o[j];
            v[4 * e + c][0] = refl__sbc_dot(w, ix->m);
            v[4 * e + c][1] = refl__sbc_dot(w, ix->a);
            v[4 * e + c][2] = refl__sbc_dot(w, ix->b);
        }
}

/* The lateral box (x lo, x hi, y lo, y hi) of the part of a quad's region
   (its corners v) with t in [t0, t1]: the corners in the slab and where
   the region's 12 edges cross its planes; 0 when none (it misses the slab). */
static int refl__sbc_slab_box(const double v[8][3], double t0, double t1, double box[4]) {
    static const int edge[12][2] = {{0, 1}, {1, 3}, {3, 2}, {2, 0}, {4, 5}, {5, 7}, {7, 6}, {6, 4},
                                    {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    int k, e, any = 0;
    box[0] = box[2] = DBL_MAX;
    box[1] = box[3] = -DBL_MAX;
    for (k = 0; k < 8; ++k)
        if (v[k][0] >= t0 && v[k][0] <= t1) {
            box[0] = REFL__MIN(box[0], v[k][1]); box[1] = REFL__MAX(box[1], v[k][1]);
            box[2] = REFL__MIN(box[2], v[k][2]); box[3] = REFL__MAX(box[3], v[k][2]);
            any = 1;
        }
    for (k = 0; k < 12; ++k) {
        const double *p = v[edge[k][0]], *q = v[edge[k][1]];
        for (e = 0; e < 2; ++e) {
            double t = e ? t1 : t0, f;
            if (!((p[0] - t) * (q[0] - t) <= 0.0) || p[0] == q[0]) continue;
            f = (t - p[0]) / (q[0] - p[0]);
            box[0] = REFL__MIN(box[0], p[1] + f * (q[1] - p[1])); box[1] = REFL__MAX(box[1], p[1] + f * (q[1] - p[1]));
            box[2] = REFL__MIN(box[2], p[2] + f * (q[2] - p[2])); box[3] = REFL__MAX(box[3], p[2] + f * (q[2] - p[2]));
            any = 1;
        }
    }
    return any;
}

/* A ray-list leaf's index (see refl__sbc_index), built when it has
   REFL__SBC_INDEX_MIN quads or more. Conservative: a point a quad's exact
   test takes lies in its region, so in a cell listing it (boxes padded
   past rounding). */
static refl_result refl__sbc_leaf_index(refl_sbc *s, refl__sbc_node *node) {
    refl__sbc_index ix;
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, pad = 0.0;
    double (*v)[8][3], box[4];
    int ncells, i, j, k, pass, total, *start, *last;
    node->grid = 0;
    if (node->count < REFL__SBC_INDEX_MIN) return REFL_OK;
    memset(&ix, 0, sizeof ix);
    /* finer for longer lists: a few quads per cell where they lie side by side */
    ix.cells = REFL__CLAMP((int)sqrt((double)node->count), 4, 32);
    ix.slabs = REFL__CLAMP((int)(0.5 * sqrt((double)node->count)), 4, 16);
    ncells = ix.slabs * ix.cells * ix.cells;
    for (i = 0; i < node->count; ++i)
        for (j = 0; j < 3; ++j) {
            ix.o[j] += (double)s->quads[node->first + i].o[j] / node->count;
            ix.m[j] += s->quads[node->first + i].m[j];
        }
    if (!(refl__sbc_normalize(ix.m) > 0.0)) return REFL_OK;
    refl__sbc_across(ix.m, ix.a, ix.b);
    v = (double(*)[8][3])refl__alloc(&s->allocator, (size_t)node->count * sizeof *v); /* per quad: its corners */
    if (!v) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < node->count; ++i) { /* the leaf's extent in its frame */
        refl__sbc_index_corners(&ix, &s->quads[node->first + i], v[i]);
        for (k = 0; k < 8; ++k)
            for (j = 0; j < 3; ++j) {
                lo[j] = REFL__MIN(lo[j], v[i][k][j]);
                hi[j] = REFL__MAX(hi[j], v[i][k][j]);
            }
    }
    for (j = 0; j < 3; ++j) pad = REFL__MAX(pad, hi[j] - lo[j] + fabs(lo[j]) + fabs(hi[j]));
    pad = 1e-5 * (pad + fabs(ix.o[0]) + fabs(ix.o[1]) + fabs(ix.o[2]));
    ix.t0 = lo[0] - pad;
    ix.t_scale = ix.slabs / (hi[0] - lo[0] + 2.0 * pad);
    ix.x0 = lo[1] - pad;
    ix.x_scale = ix.cells / (hi[1] - lo[1] + 2.0 * pad);
    ix.y0 = lo[2] - pad;
    ix.y_scale = ix.cells / (hi[2] - lo[2] + 2.0 * pad);
    ix.start = s->cell_start_count;
    if (!refl__sbc_grow_int(&s->allocator, (void **)&s->cell_start, &s->cell_start_cap, ix.start + ncells + 1,
                            sizeof(int)) ||
        !refl__sbc_grow_int(&s->allocator, (void **)&s->indexes, &s->index_cap, s->index_count + 1,
                            sizeof(refl__sbc_index)) ||
        !(last = (int *)refl__alloc(&s->allocator, (size_t)ncells * sizeof(int)))) { /* per cell: its last quad */
        refl__free(&s->allocator, v);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    start = s->cell_start + ix.start;
    memset(start, 0, (size_t)(ncells + 1) * sizeof(int));
    total = s->cell_quad_count;
    for (pass = 0; pass < 2; ++pass) { /* count each cell's list, then fill it */
        for (k = 0; k < ncells; ++k) last[k] = -1;
        if (pass) {
            for (k = 0; k <= ncells; ++k) {
                int count = start[k];
                start[k] = total;
                total += count;
            }
            if (!refl__sbc_grow_int(&s->allocator, (void **)&s->cell_quads, &s->cell_quad_cap, total, sizeof(int))) {
                refl__free(&s->allocator, last);
                refl__free(&s->allocator, v);
                return REFL_ERROR_OUT_OF_MEMORY;
            }
        }
        for (i = 0; i < node->count; ++i) {
            int slab;
            for (slab = 0; slab < ix.slabs; ++slab) {
                double t0 = ix.t0 + slab / ix.t_scale, t1 = ix.t0 + (slab + 1) / ix.t_scale;
                int x, y, r[4];
                if (!refl__sbc_slab_box((const double(*)[3])v[i], t0 - pad, t1 + pad, box)) continue;
                r[0] = (int)REFL__CLAMP((box[0] - pad - ix.x0) * ix.x_scale, 0.0, ix.cells - 1.0);
                r[1] = (int)REFL__CLAMP((box[1] + pad - ix.x0) * ix.x_scale, 0.0, ix.cells - 1.0);
                r[2] = (int)REFL__CLAMP((box[2] - pad - ix.y0) * ix.y_scale, 0.0, ix.cells - 1.0);
                r[3] = (int)REFL__CLAMP((box[3] + pad - ix.y0) * ix.y_scale, 0.0, ix.cells - 1.0);
                for (y = r[2]; y <= r[3]; ++y)
                    for (x = r[0]; x <= r[1]; ++x) {
                        int c = (slab * ix.cells + y) * ix.cells + x;
                        if (last[c] == i) continue;
                        last[c] = i;
                        if (!pass) start[c]++;
                        else s->cell_quads[start[c]++] = i;
                    }
            }
        }
        if (pass) { /* the fill moved every start to the next cell's */
            for (k = ncells; k > 0; --k) start[k] = start[k - 1];
            start[0] = s->cell_quad_count;
        }
    }
    refl__free(&s->allocator, last);
    refl__free(&s->allocator, v);
    s->cell_quad_count = total;
    s->cell_start_count += ncells + 1;
    s->indexes[s->index_count++] = ix;
    node->grid = s->index_count;
    return REFL_OK;
}

/* A ray-list leaf: the set's 2 x 2 quads of rays, each with its frame. */
static refl_result refl__sbc_ray_leaf(refl__sbc_builder *b, const int *list, int n, refl__sbc_node *node) {
    refl_sbc *s = b->sbc;
    unsigned st = ++b->stamp;
    int i, W = b->W, H = b->H;
    for (i = 0; i < n; ++i) b->mark[list[i]] = st;
    node->kind = REFL__SBC_RAYS;
    node->first = s->quad_count;
    node->count = 0;
    for (i = 0; i < n; ++i) {
        int idx = list[i], u = idx % W, v = idx / W, c, j, e, ok = 1;
        refl__sbc_quad q;
        refl__sbc_frame fr;
        double lo = DBL_MAX, hi = -DBL_MAX, scale = 0.0, tau[2];
        if (u + 1 >= W || v + 1 >= H) continue;
        if (b->mark[idx + 1] != st || b->mark[idx + W] != st || b->mark[idx + W + 1] != st) continue;
        /* one smooth piece: a frustum across a gap or crease holds points no ray reflects */
        if (b->links && !((b->links[idx] & 3) == 3 && (b->links[idx + W] & 1) && (b->links[idx + 1] & 2))) continue;
        memset(&q, 0, sizeof q);
        memset(&fr, 0, sizeof fr);
        q.idx = idx;
        for (c = 0; c < 4; ++c) {
            int k = idx + (c & 1) + (c >> 1) * W;
            const refl_sbc_ray *r = &b->rays[k];
            fr.o[0] += 0.25 * r->tail.x; fr.o[1] += 0.25 * r->tail.y; fr.o[2] += 0.25 * r->tail.z;
            for (j = 0; j < 3; ++j) fr.m[j] += b->dir[3 * (size_t)k + (size_t)j];
        }
        if (!(refl__sbc_normalize(fr.m) > 0.0)) continue;
        refl__sbc_across(fr.m, fr.a, fr.b);
        /* stored in float; everything below from the stored values */
        for (j = 0; j < 3; ++j) {
            q.o[j] = (float)fr.o[j]; q.m[j] = (float)fr.m[j]; q.a[j] = (float)fr.a[j]; q.b[j] = (float)fr.b[j];
        }
        refl__sbc_frame_load(&q, &fr);
        for (c = 0; c < 4; ++c) {
            const refl_sbc_ray *r = &b->rays[idx + (c & 1) + (c >> 1) * W];
            for (e = 0; e < 2; ++e) {
                double p[3], t;
                refl__sbc_load(e ? r->head : r->tail, p);
                for (j = 0; j < 3; ++j) p[j] -= fr.o[j];
                t = refl__sbc_dot(p, fr.m);
                lo = REFL__MIN(lo, t);
                hi = REFL__MAX(hi, t);
                scale = REFL__MAX(scale, sqrt(refl__sbc_dot(p, p)));
            }
        }
        /* the pads outgrow float rounding (relative 6e-8 of scale) */
        scale += fabs(fr.o[0]) + fabs(fr.o[1]) + fabs(fr.o[2]);
        tau[0] = lo - 1e-4 * (hi - lo) - 1e-6 * scale;
        /* beyond the heads too: where heads leave the box through different
           faces, their blend lies inside it, short of the box */
        tau[1] = hi + 0.25 * (hi - lo) + 1e-6 * scale;
        for (e = 0; e < 2 && ok; ++e) {
            double x[4], y[4], lam[4], len[4], pad, bx[4];
            if (!refl__sbc_quad_slice(&fr, b->rays, idx, W, tau[e], x, y, lam, len)) ok = 0;
            bx[0] = bx[2] = DBL_MAX;
            bx[1] = bx[3] = -DBL_MAX;
            for (c = 0; c < 4; ++c) {
                bx[0] = REFL__MIN(bx[0], x[c]); bx[1] = REFL__MAX(bx[1], x[c]);
                bx[2] = REFL__MIN(bx[2], y[c]); bx[3] = REFL__MAX(bx[3], y[c]);
            }
            /* room for the exact test's tolerance in (s, t), and for the
               fallback's reach (a diagonal is at most width plus height) */
            pad = (1e-3 + REFL__SBC_NEAR) * (bx[1] - bx[0] + bx[3] - bx[2]) + 1e-6 * scale;
            q.box[e][0] = (float)(bx[0] - pad); q.box[e][1] = (float)(bx[1] + pad);
            q.box[e][2] = (float)(bx[2] - pad); q.box[e][3] = (float)(bx[3] + pad);
            q.tau[e] = (float)tau[e];
        }
        if (!ok) continue; /* rays a quarter turn apart: no slicing; nothing projects there */
        for (c = 0; c < 4; ++c) { /* what projection slices, once */
            const refl_sbc_ray *r = &b->rays[idx + (c & 1) + (c >> 1) * W];
            double t[3], d[3];
            refl__sbc_load(r->tail, t);
            d[0] = (double)r->head.x - t[0]; d[1] = (double)r->head.y - t[1]; d[2] = (double)r->head.z - t[2];
            for (j = 0; j < 3; ++j) t[j] -= fr.o[j];
            q.ray[c][0] = (float)refl__sbc_dot(t, fr.m);
            q.ray[c][1] = (float)refl__sbc_dot(t, fr.a);
            q.ray[c][2] = (float)refl__sbc_dot(t, fr.b);
            q.ray[c][3] = (float)refl__sbc_dot(d, fr.m);
            q.ray[c][4] = (float)refl__sbc_dot(d, fr.a);
            q.ray[c][5] = (float)refl__sbc_dot(d, fr.b);
            q.len[c] = (float)sqrt(refl__sbc_dot(d, d));
        }
        {
            double fold[2];
            int folds = refl__sbc_quad_folds(&fr, b->rays, idx, W, tau, fold);
            q.fold[0] = folds > 0 ? (float)fold[0] : FLT_MAX;
            q.fold[1] = folds > 1 ? (float)fold[1] : FLT_MAX;
            s->stats.sheets = REFL__MAX(s->stats.sheets, folds + 1);
        }
        q.inv_span = 1.0f / (q.tau[1] - q.tau[0]); /* tau[1] > tau[0]: the pads grow them apart */
        q.o_size = fabsf(q.o[0]) + fabsf(q.o[1]) + fabsf(q.o[2]);
        if (!refl__sbc_grow_int(&s->allocator, (void **)&s->quads, &s->quad_cap, s->quad_count + 1,
                                sizeof(refl__sbc_quad)))
            return REFL_ERROR_OUT_OF_MEMORY;
        s->quads[s->quad_count++] = q;
        node->count++;
    }
    refl__sbc_leaf_box(s, node);
    return refl__sbc_leaf_index(s, node);
}

static void refl__sbc_free_builder(refl__sbc_builder *b) {
    refl__free(b->a, b->valid);
    refl__free(b->a, b->dir);
    refl__free(b->a, b->truth);
    refl__free(b->a, b->mark);
    refl__free(b->a, b->smin);
    refl__free(b->a, b->smax);
    refl__free(b->a, b->side);
    refl__free(b->a, b->pool);
    refl__free(b->a, b->uv);
}

REFL_API void refl_sbc_destroy(refl_sbc *sbc) {
    refl_allocator a;
    if (!sbc) return;
    a = sbc->allocator;
    refl__free(&a, sbc->nodes);
    refl__free(&a, sbc->cams);
    refl__free(&a, sbc->quads);
    refl__free(&a, sbc->indexes);
    refl__free(&a, sbc->cell_start);
    refl__free(&a, sbc->cell_quads);
    refl__free(&a, sbc->rays);
    refl__free(&a, sbc);
}

static refl_result refl__sbc_run(refl__sbc_builder *b, int nvalid) {
    refl_sbc *s = b->sbc;
    refl__sbc_task *tasks;
    int ntask = 0, i;
    refl_result res = REFL_OK;
    /* the DFS holds at most one pending right sibling per level */
    tasks = (refl__sbc_task *)refl__calloc(b->a, (size_t)REFL__MIN(b->max_depth, nvalid) + 2, sizeof(refl__sbc_task));
    if (!tasks) return REFL_ERROR_OUT_OF_MEMORY;
    if (!refl__sbc_grow_int(b->a, (void **)&s->nodes, &s->node_cap, 1, sizeof(refl__sbc_node))) {
        refl__free(b->a, tasks);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    s->node_count = 1;
    s->nodes[0].child = -1;
    tasks[0].node = 0;
    tasks[0].off = 0;
    tasks[0].count = nvalid;
    tasks[0].depth = 0;
    ntask = 1;
    while (ntask > 0) {
        refl__sbc_task t = tasks[--ntask];
        size_t top = t.off + (size_t)t.count; /* everything above belongs to finished tasks */
        refl__sbc_cam cam;
        double plane[4];
        int nl = 0, nr = 0;
        s->stats.depth = REFL__MAX(s->stats.depth, t.depth);
        if (refl__sbc_fit_ok(b, b->pool + t.off, t.count, &cam)) {
            if (!refl__sbc_grow_int(b->a, (void **)&s->cams, &s->cam_cap, s->cam_count + 1, sizeof(refl__sbc_cam))) {
                res = REFL_ERROR_OUT_OF_MEMORY;
                break;
            }
            if (b->widen > 0.0) { /* after the fit: its normalisation (norm) stays the fitted one */
                double wu = b->widen * (cam.rect[1] - cam.rect[0]), wv = b->widen * (cam.rect[3] - cam.rect[2]);
                cam.rect[0] -= wu; cam.rect[1] += wu; cam.rect[2] -= wv; cam.rect[3] += wv;
            }
            s->cams[s->cam_count] = cam;
            s->nodes[t.node].kind = REFL__SBC_PINHOLE;
            s->nodes[t.node].first = s->cam_count++;
            s->nodes[t.node].count = 1;
            s->stats.pinhole_leaves++;
            continue;
        }
        if (t.depth < b->max_depth && refl__sbc_split(b, b->pool + t.off, t.count, plane, &nl, &nr)) {
            int *list, *wr, *wl, left;
            if (!refl__sbc_grow(b->a, (void **)&b->pool, &b->pool_cap, top + (size_t)nl + (size_t)nr, sizeof(int)) ||
                !refl__sbc_grow_int(b->a, (void **)&s->nodes, &s->node_cap, s->node_count + 2,
                                    sizeof(refl__sbc_node))) {
                res = REFL_ERROR_OUT_OF_MEMORY;
                break;
            }
            list = b->pool + t.off;
            wr = b->pool + top;          /* right below left: left is popped first */
            wl = wr + nr;
            for (i = 0; i < t.count; ++i) {
                int idx = list[i];
                if (b->side[idx] & 1) *wl++ = idx;
                if (b->side[idx] & 2) *wr++ = idx;
            }
            left = s->node_count;
            s->node_count += 2;
            memset(&s->nodes[left], 0, 2 * sizeof(refl__sbc_node));
            s->nodes[left].child = s->nodes[left + 1].child = -1;
            memcpy(s->nodes[t.node].plane, plane, sizeof plane);
            s->nodes[t.node].kind = REFL__SBC_INNER;
            s->nodes[t.node].child = left;
            tasks[ntask].node = left + 1;
            tasks[ntask].off = top;
            tasks[ntask].count = nr;
            tasks[ntask].depth = t.depth + 1;
            ++ntask;
            tasks[ntask].node = left;
            tasks[ntask].off = top + (size_t)nr;
            tasks[ntask].count = nl;
            tasks[ntask].depth = t.depth + 1;
            ++ntask;
            continue;
        }
        res = refl__sbc_ray_leaf(b, b->pool + t.off, t.count, &s->nodes[t.node]);
        if (res != REFL_OK) break;
        s->stats.ray_leaves++;
    }
    refl__free(b->a, tasks);
    return res;
}

REFL_API refl_result refl_sbc_build(const refl_sbc_ray *rays, const uint8_t *valid, int map_width, int map_height,
                                    const refl_sbc_desc *desc, refl_sbc **out_sbc) {
    refl__sbc_builder b;
    refl_sbc *s;
    refl_allocator alloc;
    refl_result res;
    size_t count, i;
    int nvalid = 0, j;
    double err;
    if (out_sbc) *out_sbc = NULL;
    if (!rays || !desc || !out_sbc || map_width < 1 || map_height < 1) return REFL_ERROR_INVALID_ARGUMENT;
    if ((size_t)map_width > (size_t)(INT_MAX / 4) / (size_t)map_height) return REFL_ERROR_INVALID_SIZE;
    err = desc->error_px == 0.0f ? 1.0 : (double)desc->error_px;
    if (!(err > 0.0)) return REFL_ERROR_INVALID_ARGUMENT; /* negative or NaN */
    if (desc->max_depth < 0 || !(desc->widen >= 0.0f && desc->widen <= 1e6f)) return REFL_ERROR_INVALID_ARGUMENT;
    if (err <= DBL_MAX) {
        if (desc->width < 1 || desc->height < 1) return REFL_ERROR_INVALID_ARGUMENT;
        for (j = 0; j < 16; ++j)
            if (!refl__isfinite(desc->view_proj.m[j])) return REFL_ERROR_INVALID_ARGUMENT;
    }
    count = (size_t)map_width * (size_t)map_height;
    for (i = 0; i < count; ++i) {
        const refl_sbc_ray *r = &rays[i];
        if (valid && !valid[i]) continue;
        if (!refl__sbc_finite3(r->tail) || !refl__sbc_finite3(r->head) || !refl__sbc_finite3(r->first))
            return REFL_ERROR_INVALID_ARGUMENT;
    }
    alloc = desc->allocator;
    memset(&b, 0, sizeof b);
    b.rays = rays;
    b.W = map_width;
    b.H = map_height;
    b.error_px = err;
    for (j = 0; j < 16; ++j) b.vp[j] = desc->view_proj.m[j];
    b.width = desc->width;
    b.height = desc->height;
    b.max_depth = desc->max_depth ? desc->max_depth : 40;
    b.widen = desc->widen;
    b.links = desc->links;
    s = (refl_sbc *)refl__calloc(&alloc, 1, sizeof(refl_sbc));
    if (!s) return REFL_ERROR_OUT_OF_MEMORY;
    s->allocator = alloc;
    s->width = map_width;
    s->height = map_height;
    b.sbc = s;
    b.a = &s->allocator;
    b.valid = (uint8_t *)refl__calloc(b.a, count, 1);
    b.dir = (float *)refl__calloc(b.a, count, 3 * sizeof(float));
    b.truth = (double *)refl__calloc(b.a, count, 2 * sizeof(double));
    b.mark = (unsigned *)refl__calloc(b.a, count, sizeof(unsigned));
    b.smin = (double *)refl__calloc(b.a, count, sizeof(double));
    b.smax = (double *)refl__calloc(b.a, count, sizeof(double));
    b.side = (uint8_t *)refl__calloc(b.a, count, 1);
    if (!b.valid || !b.dir || !b.truth || !b.mark || !b.smin || !b.smax || !b.side) {
        res = REFL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    /* rays of zero length have no direction: left out of the group */
    for (i = 0; i < count; ++i) {
        const refl_sbc_ray *r = &rays[i];
        double d[3], l;
        if (valid && !valid[i]) continue;
        d[0] = (double)r->head.x - r->tail.x;
        d[1] = (double)r->head.y - r->tail.y;
        d[2] = (double)r->head.z - r->tail.z;
        l = refl__sbc_normalize(d);
        if (!(l > 0.0) || !refl__sbc_finite(l)) continue;
        b.valid[i] = 1;
        for (j = 0; j < 3; ++j) b.dir[3 * i + (size_t)j] = (float)d[j];
        ++nvalid;
        if (err <= DBL_MAX) {
            double q[3];
            refl__sbc_load(r->first, q);
            if (!refl__sbc_pixel(&b, q, &b.truth[2 * i], &b.truth[2 * i + 1]))
                b.truth[2 * i] = b.truth[2 * i + 1] = NAN; /* behind the eye: no camera fits it */
        }
    }
    b.uv = (double *)refl__calloc(b.a, (size_t)nvalid + 1, 6 * sizeof(double));
    if (!b.uv || !refl__sbc_grow(b.a, (void **)&b.pool, &b.pool_cap, (size_t)nvalid * 4 + 16, sizeof(int))) {
        res = REFL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    {
        int k = 0;
        for (i = 0; i < count; ++i)
            if (b.valid[i]) b.pool[k++] = (int)i;
    }
    s->stats.rays = nvalid;
    s->stats.sheets = 1;
    res = refl__sbc_run(&b, nvalid);
    if (res == REFL_OK && s->stats.ray_leaves > 0) {
        /* ray lists read the map at projection time; invalid entries are never read */
        s->rays = (refl_sbc_ray *)refl__calloc(b.a, count, sizeof(refl_sbc_ray));
        if (!s->rays) res = REFL_ERROR_OUT_OF_MEMORY;
        else
            for (i = 0; i < count; ++i)
                if (b.valid[i]) s->rays[i] = rays[i];
    }
done:
    refl__sbc_free_builder(&b);
    if (res != REFL_OK) {
        refl_sbc_destroy(s);
        return res;
    }
    s->stats.nodes = s->node_count;
    s->stats.bytes = (long long)sizeof(refl_sbc) + (long long)s->node_cap * (long long)sizeof(refl__sbc_node) +
                     (long long)s->cam_cap * (long long)sizeof(refl__sbc_cam) +
                     (long long)s->quad_cap * (long long)sizeof(refl__sbc_quad) +
                     (long long)s->index_cap * (long long)sizeof(refl__sbc_index) +
                     ((long long)s->cell_start_cap + (long long)s->cell_quad_cap) * (long long)sizeof(int) +
                     (s->rays ? (long long)count * (long long)sizeof(refl_sbc_ray) : 0);
    *out_sbc = s;
    return REFL_OK;
}

REFL_API void refl_sbc_get_stats(const refl_sbc *sbc, refl_sbc_stats *out) {
    if (!out) return;
    if (!sbc) {
        memset(out, 0, sizeof *out);
        return;
    }
    *out = sbc->stats;
}

/* Inverse bilinear interpolation: (s, t) in [0, 1]^2 (within tol, then
   clamped) with (x, y) = the blend of corners 0 (0, 0), 1 (1, 0), 2 (0, 1),
   3 (1, 1), the root least outside the square (*out: how far); 0 when there
   is none. */
static int refl__sbc_inv_bilinear(const double *cx, const double *cy, double x, double y, double tol, double *s,
                                  double *t, double *out) {
    double ex = cx[1] - cx[0], ey = cy[1] - cy[0], fx = cx[2] - cx[0], fy = cy[2] - cy[0];
    double gx = cx[0] - cx[1] - cx[2] + cx[3], gy = cy[0] - cy[1] - cy[2] + cy[3], hx = x - cx[0], hy = y - cy[0];
    double roots[2], best = DBL_MAX;
    int nr, i;
    /* h - t f = s (e + t g): crossing both sides with e + t g leaves a quadratic in t */
    nr = refl__sbc_quadratic(refl__sbc_cross2(gx, gy, fx, fy),
                             refl__sbc_cross2(ex, ey, fx, fy) + refl__sbc_cross2(hx, hy, gx, gy),
                             refl__sbc_cross2(hx, hy, ex, ey), roots);
    for (i = 0; i < nr; ++i) {
        double tt = roots[i], dx = ex + gx * tt, dy = ey + gy * tt, ss, o;
        if (!(tt >= -tol && tt <= 1.0 + tol)) continue;
        if (fabs(dx) >= fabs(dy)) {
            if (dx == 0.0) continue;
            ss = (hx - fx * tt) / dx;
        } else {
            ss = (hy - fy * tt) / dy;
        }
        if (!(ss >= -tol && ss <= 1.0 + tol)) continue;
        o = REFL__MAX(REFL__MAX(-ss, ss - 1.0), REFL__MAX(-tt, tt - 1.0));
        o = REFL__MAX(o, 0.0);
        if (!(o < best)) continue;
        best = o;
        *s = REFL__CLAMP(ss, 0.0, 1.0);
        *t = REFL__CLAMP(tt, 0.0, 1.0);
        if (o == 0.0) break; /* inside: the first such root, as ever */
    }
    *out = best;
    return best < DBL_MAX;
}

/* A ray-list image candidate: its rank (off the reflector, how far off
   its quad, depth) and its answer. */
typedef struct refl__sbc_pick {
    int off;
    double out, zz;
    refl_vec3 first;
} refl__sbc_pick;

/* A ray-list leaf, per sheet (sheets 0: one for all, as if no ray
   folded): the unit frustum holding p nearest the reflector; where none
   does, the one p lies nearest outside, within REFL__SBC_NEAR. Returns the
   mask of sheets p projects in. */
static int refl__sbc_rays_project(const refl_sbc *sb, const refl__sbc_node *node, const double *p, int sheets,
                                  refl_vec3 *first, float *z) {
    refl__sbc_pick picks[REFL_SBC_SHEETS][2]; /* per sheet: inside a quad, near one */
    const float pf[3] = {(float)p[0], (float)p[1], (float)p[2]};
    const float pn = fabsf(pf[0]) + fabsf(pf[1]) + fabsf(pf[2]);
    int i, c, j, k, W = sb->width, mask = 0, from = 0, to = node->count, at;
    const int *list = NULL;
    for (j = 0; j < 3; ++j)
        if (!(p[j] >= node->box[j] && p[j] <= node->box[3 + j])) return 0;
    for (i = 0; i < REFL_SBC_SHEETS; ++i) {
        picks[i][0].zz = picks[i][1].zz = DBL_MAX;
        picks[i][0].out = picks[i][1].out = DBL_MAX;
        picks[i][0].off = picks[i][1].off = 0;
    }
    if (node->grid) { /* only the quads listed in p's cell */
        const refl__sbc_index *ix = &sb->indexes[node->grid - 1];
        double w[3], t, x, y;
        int slab, cx, cy;
        for (j = 0; j < 3; ++j) w[j] = p[j] - ix->o[j];
        t = (refl__sbc_dot(w, ix->m) - ix->t0) * ix->t_scale;
        x = (refl__sbc_dot(w, ix->a) - ix->x0) * ix->x_scale;
        y = (refl__sbc_dot(w, ix->b) - ix->y0) * ix->y_scale;
        if (!(t >= 0.0 && t < ix->slabs && x >= 0.0 && x < ix->cells && y >= 0.0 && y < ix->cells))
            return 0;
        slab = (int)t;
        cx = (int)x;
        cy = (int)y;
        at = ix->start + (slab * ix->cells + cy) * ix->cells + cx;
        from = sb->cell_start[at];
        to = sb->cell_start[at + 1];
        list = sb->cell_quads;
    }
    for (at = from; at < to; ++at) {
        const refl__sbc_quad *q = &sb->quads[node->first + (list ? list[at] : at)];
        refl__sbc_frame fr;
        double w[3], tau, x, y, f, x4[4], y4[4], lam[4], len[4], ss = 0.0, tt = 0.0, wt[4], zz = 0.0, lm = 0.0, o;
        refl__sbc_pick *pk, *pick;
        double t0 = q->tau[0], t1 = q->tau[1];
        int sheet;
        /* most quads miss p: its box first, then a float test of its
           region, looser than its rounding (about 1e-6 of the coordinates'
           size), so neither drops a quad the exact test below would take */
        if (!(pf[0] >= q->aabb[0] && pf[0] <= q->aabb[3] && pf[1] >= q->aabb[1] && pf[1] <= q->aabb[4] &&
              pf[2] >= q->aabb[2] && pf[2] <= q->aabb[5]))
            continue;
        {
            float eps = 1e-5f * (pn + q->o_size);
            float wx = pf[0] - q->o[0], wy = pf[1] - q->o[1], wz = pf[2] - q->o[2], tf, ff, v;
            tf = wx * q->m[0] + wy * q->m[1] + wz * q->m[2];
            if (!(tf >= q->tau[0] - eps && tf <= q->tau[1] + eps)) continue;
            ff = REFL__CLAMP((tf - q->tau[0]) * q->inv_span, 0.0f, 1.0f);
            v = wx * q->a[0] + wy * q->a[1] + wz * q->a[2];
            if (!(v >= q->box[0][0] + ff * (q->box[1][0] - q->box[0][0]) - eps &&
                  v <= q->box[0][1] + ff * (q->box[1][1] - q->box[0][1]) + eps))
                continue;
            v = wx * q->b[0] + wy * q->b[1] + wz * q->b[2];
            if (!(v >= q->box[0][2] + ff * (q->box[1][2] - q->box[0][2]) - eps &&
                  v <= q->box[0][3] + ff * (q->box[1][3] - q->box[0][3]) + eps))
                continue;
        }
        refl__sbc_frame_load(q, &fr);
        for (j = 0; j < 3; ++j) w[j] = p[j] - fr.o[j];
        tau = refl__sbc_dot(w, fr.m);
        if (!(tau >= t0 && tau <= t1)) continue;
        sheet = sheets ? (tau > q->fold[0]) + (tau > q->fold[1]) : 0;
        if (sheets && sheet >= sheets) continue;
        pick = picks[sheet];
        f = (tau - t0) / (t1 - t0);
        x = refl__sbc_dot(w, fr.a);
        if (!(x >= q->box[0][0] + f * ((double)q->box[1][0] - q->box[0][0]) &&
              x <= q->box[0][1] + f * ((double)q->box[1][1] - q->box[0][1])))
            continue;
        y = refl__sbc_dot(w, fr.b);
        if (!(y >= q->box[0][2] + f * ((double)q->box[1][2] - q->box[0][2]) &&
              y <= q->box[0][3] + f * ((double)q->box[1][3] - q->box[0][3])))
            continue;
        for (c = 0; c < 4; ++c) { /* its rays at p's slice (each crosses the slices: the build checked) */
            double l = (tau - q->ray[c][0]) / q->ray[c][3];
            x4[c] = q->ray[c][1] + l * q->ray[c][4];
            y4[c] = q->ray[c][2] + l * q->ray[c][5];
            lam[c] = l;
            len[c] = q->len[c];
        }
        /* the root least outside: inside within the exact tolerance, else
           near when its clamped point lies within REFL__SBC_NEAR diagonals */
        if (!refl__sbc_inv_bilinear(x4, y4, x, y, pick[0].zz < DBL_MAX ? REFL__SBC_TOL : 0.5, &ss, &tt, &o)) continue;
        wt[0] = (1.0 - ss) * (1.0 - tt); wt[1] = ss * (1.0 - tt); wt[2] = (1.0 - ss) * tt; wt[3] = ss * tt;
        k = o > REFL__SBC_TOL;
        o = 0.0;
        if (k && pick[0].zz < DBL_MAX) continue; /* one inside wins */
        if (k) {
            double dx = x, dy = y, d1, d2;
            for (c = 0; c < 4; ++c) {
                dx -= wt[c] * x4[c];
                dy -= wt[c] * y4[c];
            }
            d1 = (x4[3] - x4[0]) * (x4[3] - x4[0]) + (y4[3] - y4[0]) * (y4[3] - y4[0]);
            d2 = (x4[2] - x4[1]) * (x4[2] - x4[1]) + (y4[2] - y4[1]) * (y4[2] - y4[1]);
            o = (dx * dx + dy * dy) / REFL__MAX(d1, d2); /* squared: ranks alike */
            if (!(o <= REFL__SBC_NEAR * REFL__SBC_NEAR)) continue;
        }
        for (c = 0; c < 4; ++c) {
            zz += wt[c] * lam[c] * len[c];
            lm += wt[c] * lam[c];
        }
        /* past the interpolated ray's tail; where rays fold, the nearest
           image off the reflector: one at the tails is the reflector's own
           surface (a knob on a lid lies at its own rays' tails, and also
           ahead of the lid's rays that meet it) */
        if (!(lm >= -1e-4)) continue;
        pk = &pick[k];
        if (pk->off && lm < REFL__SBC_ON_SURFACE) continue;
        if (!(!pk->off && lm >= REFL__SBC_ON_SURFACE)) {
            if (o > pk->out) continue;
            if (o == pk->out && !(zz < pk->zz)) continue;
        }
        pk->off = lm >= REFL__SBC_ON_SURFACE;
        pk->zz = zz;
        pk->out = o;
        {
            double fp[3] = {0.0, 0.0, 0.0};
            for (c = 0; c < 4; ++c) {
                refl_vec3 r = sb->rays[q->idx + (c & 1) + (c >> 1) * W].first;
                fp[0] += wt[c] * r.x; fp[1] += wt[c] * r.y; fp[2] += wt[c] * r.z;
            }
            pk->first = refl_v3((float)fp[0], (float)fp[1], (float)fp[2]);
        }
    }
    for (i = 0; i < REFL__MAX(sheets, 1); ++i) {
        k = picks[i][0].zz < DBL_MAX ? 0 : 1;
        if (!(picks[i][k].zz < DBL_MAX)) continue;
        first[i] = picks[i][k].first;
        z[i] = (float)REFL__MAX(picks[i][k].zz, 0.0);
        mask |= 1 << i;
    }
    return mask;
}

/* The leaf whose cell holds pd: down the tree by the side of each plane. */
static const refl__sbc_node *refl__sbc_leaf(const refl_sbc *sbc, const double *pd) {
    const refl__sbc_node *node = &sbc->nodes[0];
    while (node->kind == REFL__SBC_INNER) {
        double sd = node->plane[0] * pd[0] + node->plane[1] * pd[1] + node->plane[2] * pd[2] + node->plane[3];
        node = &sbc->nodes[sd >= 0.0 ? node->child : node->child + 1];
    }
    return node;
}

REFL_API refl_sbc_leaf_kind refl_sbc_leaf_at(const refl_sbc *sbc, refl_vec3 p) {
    double pd[3];
    if (!sbc || !sbc->nodes || !sbc->stats.rays || !refl__sbc_finite3(p)) return REFL_SBC_LEAF_NONE;
    refl__sbc_load(p, pd);
    return refl__sbc_leaf(sbc, pd)->kind == REFL__SBC_PINHOLE ? REFL_SBC_LEAF_PINHOLE : REFL_SBC_LEAF_RAY_LIST;
}

/* The leaf holding p and its projection per sheet (sheets 0: one for
   all); the mask of those p projects in. */
static int refl__sbc_project(const refl_sbc *sbc, refl_vec3 p, int sheets, refl_vec3 *first, float *z) {
    const refl__sbc_node *node;
    double pd[3];
    if (!sbc || !sbc->nodes || !refl__sbc_finite3(p)) return 0;
    refl__sbc_load(p, pd);
    node = refl__sbc_leaf(sbc, pd);
    if (node->kind == REFL__SBC_PINHOLE) return refl__sbc_cam_project(&sbc->cams[node->first], pd, first, z);
    return refl__sbc_rays_project(sbc, node, pd, sheets, first, z);
}

REFL_API int refl_sbc_project(const refl_sbc *sbc, refl_vec3 p, refl_vec3 *first, float *z) {
    refl_vec3 f;
    float zz;
    if (!refl__sbc_project(sbc, p, 0, &f, &zz)) return 0;
    if (first) *first = f;
    if (z) *z = zz;
    return 1;
}

REFL_API int refl_sbc_project_sheets(const refl_sbc *sbc, refl_vec3 p, int sheets, refl_vec3 *first, float *z) {
    if (!first || !z || sheets < 1) return 0;
    return refl__sbc_project(sbc, p, REFL__MIN(sheets, REFL_SBC_SHEETS), first, z);
}

/* The image sheet `sheet` draws of a point with images `mask`: its own,
   else one a fold away (*across): a triangle straddling a fold draws in
   the sheets on both sides, its vertices past the fold at their images
   there, which meet this sheet's at the fold. -1: none. */
static int refl__sbc_sheet_image(int mask, int sheet, int *across) {
    *across = !(mask >> sheet & 1);
    if (!*across) return sheet;
    if (sheet > 0 && (mask >> (sheet - 1) & 1)) return sheet - 1;
    if (mask >> (sheet + 1) & 1) return sheet + 1;
    return -1;
}
