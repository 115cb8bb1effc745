/* Private declarations of the sample-based camera (refl_sbc, paper 003
   section IV; docs/methods/sbc.md, "The sample-based camera"), shared by
   its modules: cam_sbc.c (the BSP build, the descent, the public API),
   cam_sbc_fit.c (pinhole leaves) and cam_sbc_raylist.c (ray-list leaves
   and their sheets); and what the SBC method (m_sbc.c, sbc_*.c) and the
   morphing grids (cam_sbc_morph.c) take from it: the reflected-ray rule,
   the smoothness test, the sheets. Needs internal.h only. */
#include "internal.h"

/* ---- the tree ---------------------------------------------------------------- */

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

/* A pinhole leaf (cam_sbc_fit.c). */
typedef struct refl__sbc_cam {
    double o[3], c[3], n[3], eu[3], ev[3];
    double ho;               /* (o - c) . n: < 0 diverging, > 0 converging */
    double hmin;             /* the lowest (p - c) . n that projects */
    double ocu, ocv;         /* (o - c) in the plane's basis */
    double rect[4];          /* frustum: umin, umax, vmin, vmax */
    double norm[4];          /* u, v centre and inverse half size: to [-1, 1] */
    double coef[3][12];       /* f per coordinate over 1, u, v, u^2, uv, v^2, s, s u, s v */
} refl__sbc_cam;

/* A unit frustum of a ray list (cam_sbc_raylist.c): rays (u, v), (u + 1,
   v), (u, v + 1), (u + 1, v + 1), sliced across its mean direction m: at
   tau = (p - o) . m each ray is one point of the lateral plane (a, b), and
   p lies on the bilinearly interpolated ray (s, t) when its lateral
   position is the bilinear blend of the four at (s, t). */
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

/* A ray-list leaf's index (cam_sbc_raylist.c): slabs across the leaf's
   mean ray direction m, each cut in cells across it, each cell listing the
   quads whose region (the hull of its lateral boxes at both ends) meets
   it. */
typedef struct refl__sbc_index {
    double o[3], m[3], a[3], b[3]; /* the leaf's frame: t along m, x along a, y along b */
    double t0, t_scale;      /* slab = (t - t0) t_scale */
    double x0, x_scale, y0, y_scale; /* cell = (x - x0) x_scale, (y - y0) y_scale */
    int slabs, cells;        /* slabs, and cells per side of one */
    int start;               /* cell_start[start + (slab * cells + y) * cells + x]: its list */
} refl__sbc_index;

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

/* ---- building (cam_sbc.c drives it) ------------------------------------------ */

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

/* Grows *arr (elements of size sz, capacity *cap) to hold need; 0 when out
   of memory. The _int form for int capacities. */
static int refl__sbc_grow(const refl_allocator *a, void **arr, size_t *cap, size_t need, size_t sz);
static int refl__sbc_grow_int(const refl_allocator *a, void **arr, int *cap, int need, size_t sz);

/* cam_sbc_fit.c: the desired-view pixel of a world point (0 behind the
   eye); the tails' centroid c and the summed directions m of a set of rays
   (list, n); the least-squares centre of projection o (C, may be NULL: the
   tails' scatter about c; 0 when the rays are nearly parallel); whether a
   pinhole camera fits the set within error_px (into *k); and a pinhole
   leaf's projection of p. */
static int refl__sbc_pixel(const refl__sbc_builder *b, const double *p, double *x, double *y);
static void refl__sbc_centroid(const refl__sbc_builder *b, const int *list, int n, double c[3], double m[3]);
static int refl__sbc_centre(const refl__sbc_builder *b, const int *list, int n, const double c[3], double o[3],
                            double C[3][3]);
static int refl__sbc_fit_ok(refl__sbc_builder *b, const int *list, int n, refl__sbc_cam *k);
static int refl__sbc_cam_project(const refl__sbc_cam *k, const double *p, refl_vec3 *first, float *z);

/* Ray-list leaves' thresholds (cam_sbc_raylist.c; the GL hooks pack them). */
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

/* cam_sbc_raylist.c: a ray-list leaf of the set (its quads, box and
   index), and its projection of p per sheet (sheets 0: one for all): the
   mask of the sheets p projects in. */
static refl_result refl__sbc_ray_leaf(refl__sbc_builder *b, const int *list, int n, refl__sbc_node *node);
static int refl__sbc_rays_project(const refl_sbc *sb, const refl__sbc_node *node, const double *p, int sheets,
                                  refl_vec3 *first, float *z);
/* Unit a and b across unit m (m, a, b right-handed). */
static void refl__sbc_across(const double *m, double *a, double *b);

/* ---- small double helpers ---------------------------------------------------- */

static inline int refl__sbc_finite(double v) { return v - v == 0.0; }
static inline double refl__sbc_dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static inline void refl__sbc_cross(const double *a, const double *b, double *o) {
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}
static inline double refl__sbc_normalize(double *a) {
    double l = sqrt(refl__sbc_dot(a, a));
    if (l > 0.0) { a[0] /= l; a[1] /= l; a[2] /= l; }
    return l;
}
static inline void refl__sbc_load(refl_vec3 v, double *o) { o[0] = v.x; o[1] = v.y; o[2] = v.z; }
static inline int refl__sbc_finite3(refl_vec3 v) {
    return refl__isfinite(v.x) && refl__isfinite(v.y) && refl__isfinite(v.z);
}

/* ---- shared with the SBC method (m_sbc.c, sbc_*.c) and the morphing grids
   (cam_sbc_morph.c), defined in cam_sbc.c and cam_sbc_raylist.c ----------------- */

/* What a reflected ray meets first: a scene triangle and the point; object
   -1 for nothing. */
typedef struct refl__sbc_hit {
    int object, triangle;
    refl_vec3 point;
} refl__sbc_hit;

/* Where a ray from inside box [lo, hi] along d leaves it. */
static float refl__sbc_box_exit(refl_vec3 lo, refl_vec3 hi, refl_vec3 o, refl_vec3 d);
/* The reflected ray from q along unit r in a scene (one head rule for the
   method and the grids; cam_sbc.c). */
static int refl__sbc_scene_ray(const refl_bvh *bvh, refl_vec3 lo, refl_vec3 hi, float diagonal, refl_vec3 q,
                               refl_vec3 r, refl_sbc_ray *ray, refl__sbc_hit *met);
/* A union-find root, halving the path on the way. */
static int refl__sbc_root(int *parent, int v);

#define REFL__SBC_SMOOTH_SIN 0.5f    /* a chord leaving a tangent plane by more (30 degrees) crosses a gap */
#define REFL__SBC_SMOOTH_COS 0.7071f /* normals turning by more (45 degrees) meet at a crease */
/* Whether neighbouring samples (surface points t1, t2, unit normals n1,
   n2) lie on one smooth piece of surface (cam_sbc.c). */
static int refl__sbc_smooth(refl_vec3 t1, refl_vec3 n1, refl_vec3 t2, refl_vec3 n2);
/* The image sheet `sheet` draws of a point with images `mask`, or -1
   (cam_sbc_raylist.c). */
static int refl__sbc_sheet_image(int mask, int sheet, int *across);

/* The GL hooks' packers' output (gl_hooks.c, and cam_sbc_morph.c's grid):
   floats written while they fit, counted always; out NULL while a packer
   only sizes its block. */
typedef struct refl__gl_out {
    float *out;
    long long cap, n;
} refl__gl_out;

static inline void refl__gl_put(refl__gl_out *o, double v) {
    if (o->out && o->n < o->cap) o->out[o->n] = (float)v; /* the callers size first: it always fits */
    ++o->n;
}

static inline void refl__gl_put4(refl__gl_out *o, double a, double b, double c, double d) {
    refl__gl_put(o, a); refl__gl_put(o, b); refl__gl_put(o, c); refl__gl_put(o, d);
}

/* A packer runs twice: first counting (out NULL), then writing. After the
   count `need`, readies o for the second run and says whether there is
   one: need valid and cap holding it (else the packer returns need). */
static inline int refl__gl_fill(refl__gl_out *o, long long need, float *out, long long cap) {
    if (need < 0 || !out || cap < need) return 0;
    o->out = out;
    o->cap = cap;
    o->n = 0;
    return 1;
}
