/* bvh: a bounding volume hierarchy over the scene's world-space triangles,
   for the RAYTRACE reference and every method that needs exact rays.
   Build: binned SAH (Wald 2007), iterative, deterministic, into a binary
   tree (the triangles' boxes move with the partitions, so that every
   pass reads memory in order; SSE2 where built). On several threads the
   tree's top is split one node at a time, each node's passes over its
   triangles cut into pieces whose results merge in order, and the
   subtrees below are built in one piece each, in parallel, then put
   where the serial build puts them: the same tree, bit for bit, for any
   number of threads. Then collapsed into an 8-wide tree (Wald, Benthin and Boulos
   2008) whose eight child boxes one AVX2 slab test checks at once where
   the CPU has it (chosen at run time), else two SSE2 ones (RAST_NO_SIMD:
   the same arithmetic lane by lane, the same bits). Traversal: explicit
   stack, nearest child next, the others' memory prefetched as they are
   stacked. A ray's work is mostly a chain of dependent loads and tests,
   so the wider node, which halves the chain's length, pays more than it
   costs in box tests. Triangles: the watertight test of Woop,
   Benthin and Wald 2013, so rays never slip through shared edges. The
   closest hit is the least (t, object, triangle), whatever order the
   boxes are visited in, so the binary and the wide tree, scalar or SIMD,
   name the same hit; and boxes are culled with an allowance for the
   triangle test's rounding (refl__bvh_ray_slack), so that a bound tmax
   keeps, grazing hits aside, every hit the triangle test finds before it. */
#include "internal.h"

#if (defined(__SSE2__) || defined(_M_X64)) && !defined(RAST_NO_SIMD)
#include <emmintrin.h>
#define REFL__BVH_SSE2 1
/* AVX2 where the CPU has it, chosen per trace at run time (GCC and
   clang's target attribute), whatever the flags the user compiles with. */
#if (defined(__GNUC__) || defined(__clang__)) && (defined(__x86_64__) || defined(__i386__))
#include <immintrin.h>
#define REFL__BVH_AVX2 1
#endif
#endif

/* Inlined into each traversal, the AVX2 one included, so that the ray's
   values stay in registers. */
#if defined(__GNUC__) || defined(__clang__)
#define REFL__BVH_INLINE __attribute__((always_inline)) inline
#else
#define REFL__BVH_INLINE
#endif

#define REFL__BVH_BINS 16
#define REFL__BVH_TWO_SETS 128   /* a node of this many triangles bins into two sets of bins (refl__bvh_bin_range) */
#define REFL__BVH_LEAF 4          /* always a leaf at or below this many */
#define REFL__BVH_MAX_LEAF 32     /* never a leaf above this, unless too deep */
#define REFL__BVH_MAX_DEPTH 60    /* keeps traversal within its stacks */
#define REFL__BVH_STACK 64
/* SAH cost of a leaf of n triangles, against 1 for a box: they are
   tested four at a time (refl__bvh_leaf); on the 100k-triangle dragon
   anything between 0.5 and 1 per block of four measured about the same. */
#define REFL__BVH_LEAF_COST(n) (0.75f * (float)(((n) + 3) / 4))
/* Children of a wide node: the AVX2 box test's lanes, two SSE2 tests'. */
#define REFL__BVH_W 8
/* A wide node pushes up to W - 1 of its children and is no deeper than
   the binary node it was collapsed from. */
#define REFL__BVHW_STACK ((REFL__BVH_W - 1) * REFL__BVH_MAX_DEPTH + 8)

/* 32 bytes: children are adjacent, so one index names both. */
typedef struct refl__bvh_node {
    float lo[3], hi[3];
    int32_t index;                /* interior: first child; leaf: first of the build's triangles, then in blocks[] */
    int32_t count;                /* 0: interior; else triangles in the leaf */
} refl__bvh_node;

/* 256 bytes, four cache lines: eight children's boxes, one SIMD lane per
   child. An unused lane has an empty box (lo +inf, hi -inf), which no ray
   enters. */
typedef struct refl__bvhw_node {
    float box[6][REFL__BVH_W];    /* lo x, y, z, then hi x, y, z */
    int32_t child[REFL__BVH_W];   /* interior: node index; leaf: first in blocks[] */
    int32_t count[REFL__BVH_W];   /* 0: interior (or unused, child -1); else triangles in the leaf */
} refl__bvhw_node;

typedef struct refl__bvh_tri {
    float v[9];                   /* world-space vertices 0, 1, 2 */
    int32_t object, triangle;
} refl__bvh_tri;

/* 192 bytes, three cache lines: four triangles of a leaf, one SIMD lane
   each. A leaf of n triangles is ceil(n / 4) consecutive blocks, the last
   one's spare lanes unused (object -1). */
typedef struct refl__bvh_tri4 {
    float v[9][4];                /* row 3 j + k: coordinate k of vertex j */
    int32_t object[4], triangle[4];
    int32_t pad[4];               /* to a whole number of cache lines */
} refl__bvh_tri4;

struct refl_bvh {
    refl_allocator allocator;
    refl__bvh_node *nodes;        /* the binary tree: kept only for the tests (refl__bvh_build_ex) */
    int node_count;
    refl__bvhw_node *wide;        /* the tree every trace walks (cache-line aligned in wide_mem) */
    void *wide_mem;
    int wide_count;
    refl__bvh_tri *tris;          /* while building: the triangles, named by the build's ids */
    int tri_count;
    refl__bvh_tri4 *blocks;       /* leaves' triangles: a leaf is a range of blocks (aligned in blocks_mem) */
    void *blocks_mem;
    int block_count;
    int *object_tris;             /* per object of the scene built from: its triangle count (refit) */
    int object_count;
    float lo[3], hi[3];           /* the root's box: a ray's slack comes from it (refl__bvh_ray_slack) */
};

/* ---- build ------------------------------------------------------------------ */

/* Four floats a side, the fourth unused, so that one SIMD min and max
   merge two boxes. */
typedef struct refl__bvh_box { float lo[4], hi[4]; } refl__bvh_box;

/* Four floats the build computes on at once: SSE2's, or lane by lane with
   the same operations (min and max as MINPS and MAXPS: a < b ? a : b and
   a > b ? a : b), so that either builds the same tree. */
#ifdef REFL__BVH_SSE2
typedef __m128 refl__v4;
#define refl__v4_load _mm_loadu_ps
#define refl__v4_store _mm_storeu_ps
#define refl__v4_set1 _mm_set1_ps
#define refl__v4_add _mm_add_ps
#define refl__v4_sub _mm_sub_ps
#define refl__v4_mul _mm_mul_ps
#define refl__v4_min _mm_min_ps
#define refl__v4_max _mm_max_ps
/* Lanes 0 to 2 truncated to integers, each in [0, 2^15). */
REFL__BVH_INLINE static void refl__v4_to_small_int3(refl__v4 a, int out[3]) {
    __m128i i = _mm_cvttps_epi32(a);
    out[0] = _mm_extract_epi16(i, 0);
    out[1] = _mm_extract_epi16(i, 2);
    out[2] = _mm_extract_epi16(i, 4);
}
/* which ? a : b, which 0 or 1 */
REFL__BVH_INLINE static refl__v4 refl__v4_select(int which, refl__v4 a, refl__v4 b) {
    __m128 m = _mm_castsi128_ps(_mm_set1_epi32(-which));
    return _mm_or_ps(_mm_and_ps(m, a), _mm_andnot_ps(m, b));
}
#else
typedef struct refl__v4 { float v[4]; } refl__v4;
#define REFL__V4_LANES(expr)                                                                                        \
    refl__v4 r;                                                                                                     \
    int k;                                                                                                          \
    for (k = 0; k < 4; ++k) r.v[k] = (expr);                                                                        \
    return r
static refl__v4 refl__v4_load(const float *p) { REFL__V4_LANES(p[k]); }
static void refl__v4_store(float *p, refl__v4 a) { memcpy(p, a.v, sizeof a.v); }
static refl__v4 refl__v4_set1(float x) { REFL__V4_LANES(x); }
static refl__v4 refl__v4_add(refl__v4 a, refl__v4 b) { REFL__V4_LANES(a.v[k] + b.v[k]); }
static refl__v4 refl__v4_sub(refl__v4 a, refl__v4 b) { REFL__V4_LANES(a.v[k] - b.v[k]); }
static refl__v4 refl__v4_mul(refl__v4 a, refl__v4 b) { REFL__V4_LANES(a.v[k] * b.v[k]); }
static refl__v4 refl__v4_min(refl__v4 a, refl__v4 b) { REFL__V4_LANES(a.v[k] < b.v[k] ? a.v[k] : b.v[k]); }
static refl__v4 refl__v4_max(refl__v4 a, refl__v4 b) { REFL__V4_LANES(a.v[k] > b.v[k] ? a.v[k] : b.v[k]); }
static refl__v4 refl__v4_select(int which, refl__v4 a, refl__v4 b) { return which ? a : b; }
static void refl__v4_to_small_int3(refl__v4 a, int out[3]) {
    int k;
    for (k = 0; k < 3; ++k) out[k] = (int)a.v[k];
}
#undef REFL__V4_LANES
#endif

static void refl__box_empty(refl__bvh_box *b) {
    int k;
    for (k = 0; k < 4; ++k) { b->lo[k] = FLT_MAX; b->hi[k] = -FLT_MAX; }
}

static void refl__box_grow(refl__bvh_box *b, const float *p) {
    int k;
    for (k = 0; k < 3; ++k) {
        b->lo[k] = REFL__MIN(b->lo[k], p[k]);
        b->hi[k] = REFL__MAX(b->hi[k], p[k]);
    }
}

REFL__BVH_INLINE
static void refl__box_merge(refl__bvh_box *b, const refl__bvh_box *o) {
    refl__v4_store(b->lo, refl__v4_min(refl__v4_load(b->lo), refl__v4_load(o->lo)));
    refl__v4_store(b->hi, refl__v4_max(refl__v4_load(b->hi), refl__v4_load(o->hi)));
}

/* Half the surface area of a box that holds something (an empty one's is
   meaningless), without a branch. */
static float refl__box_area_full(const refl__bvh_box *b) {
    float dx = b->hi[0] - b->lo[0], dy = b->hi[1] - b->lo[1], dz = b->hi[2] - b->lo[2];
    return dx * dy + dy * dz + dz * dx;
}

/* Half the surface area; an empty box (lo > hi) has none. */
static float refl__box_area(const refl__bvh_box *b) {
    float dx = b->hi[0] - b->lo[0], dy = b->hi[1] - b->lo[1], dz = b->hi[2] - b->lo[2];
    if (dx < 0 || dy < 0 || dz < 0) return 0;
    return refl__box_area_full(b);
}

static void refl__tri_box(const refl__bvh_tri *t, refl__bvh_box *b) {
    refl__box_empty(b);
    refl__box_grow(b, t->v);
    refl__box_grow(b, t->v + 3);
    refl__box_grow(b, t->v + 6);
}

/* The build's triangles: each one's box and its index in tris[], which
   the partitions move together, so that every pass reads them in memory
   order. A centroid is 0.5 (lo + hi), computed where needed. */
typedef struct refl__bvh_prims {
    refl__bvh_box *box;
    int32_t *id;
} refl__bvh_prims;

REFL__BVH_INLINE
static refl__v4 refl__bvh_centroid(const refl__bvh_box *b) {
    return refl__v4_mul(refl__v4_set1(0.5f), refl__v4_add(refl__v4_load(b->lo), refl__v4_load(b->hi)));
}

/* A centroid's bin on each axis, (c - cmin) scale clamped to the bins in
   float (converting a huge value is undefined; a NaN goes to bin 0, as
   MAXPS gives its second operand). Binning and partitioning both go
   through here, so they agree. */
REFL__BVH_INLINE
static void refl__bvh_bins_of(refl__v4 c, refl__v4 cmin, refl__v4 scale, int bin[3]) {
    refl__v4 f = refl__v4_mul(refl__v4_sub(c, cmin), scale);
    refl__v4_to_small_int3(
        refl__v4_min(refl__v4_max(f, refl__v4_set1(0.0f)), refl__v4_set1((float)(REFL__BVH_BINS - 1))), bin);
}

/* A node's bins on each axis: the box and count of the triangles whose
   centroids fall in each. */
typedef struct refl__bvh_bins {
    refl__bvh_box box[3][REFL__BVH_BINS];
    int count[3][REFL__BVH_BINS];
} refl__bvh_bins;

/* Bins triangles [begin, end) into `sets` sets of bins taken in turns
   (triangle i into set (i - begin) % sets), so that consecutive triangles
   falling into one bin do not wait on each other's stores. */
/* One triangle (lo, hi) into d's bin bin[k] on axis k: a macro, so that
   the three axes' loads and stores interleave freely. */
#define REFL__BVH_BIN_INTO(k)                                                                                       \
    do {                                                                                                            \
        refl__bvh_box *to = &d->box[k][bin[k]];                                                                     \
        refl__v4_store(to->lo, refl__v4_min(refl__v4_load(to->lo), lo));                                            \
        refl__v4_store(to->hi, refl__v4_max(refl__v4_load(to->hi), hi));                                            \
        d->count[k][bin[k]]++;                                                                                      \
    } while (0)

REFL__BVH_INLINE
static void refl__bvh_bin_sets(const refl__bvh_prims *pr, int begin, int end, int sets, refl__v4 cmin,
                               refl__v4 scale, refl__bvh_bins *bins) {
    int s, i, k, b;
    for (s = 0; s < sets; ++s)
        for (k = 0; k < 3; ++k)
            for (b = 0; b < REFL__BVH_BINS; ++b) {
                refl__box_empty(&bins[s].box[k][b]);
                bins[s].count[k][b] = 0;
            }
    for (i = begin; i < end; ++i) {
        /* the box in registers: the stores into the bins might alias it */
        const refl__v4 lo = refl__v4_load(pr->box[i].lo), hi = refl__v4_load(pr->box[i].hi);
        refl__bvh_bins *d = &bins[(i - begin) & (sets - 1)];
        int bin[3];
        refl__bvh_bins_of(refl__v4_mul(refl__v4_set1(0.5f), refl__v4_add(lo, hi)), cmin, scale, bin);
        REFL__BVH_BIN_INTO(0);
        REFL__BVH_BIN_INTO(1);
        REFL__BVH_BIN_INTO(2);
    }
}
#undef REFL__BVH_BIN_INTO

/* Adds bins o into bins b. MINPS and MAXPS keep their second operand
   between equals (+0 and -0 are equal), so merging in the order the
   triangles come in gives the bits one pass over them in that order
   gives: the parallel build's pieces, merged in order, make the serial
   build's bins. */
static void refl__bvh_bins_merge(refl__bvh_bins *b, const refl__bvh_bins *o) {
    int k, j;
    for (k = 0; k < 3; ++k)
        for (j = 0; j < REFL__BVH_BINS; ++j) {
            refl__box_merge(&b->box[k][j], &o->box[k][j]);
            b->count[k][j] += o->count[k][j];
        }
}

/* Bins triangles [begin, end) into bins[0]: a large range into two sets,
   then merged. */
static void refl__bvh_bin_range(const refl__bvh_prims *pr, int begin, int end, refl__v4 cmin, refl__v4 scale,
                                refl__bvh_bins bins[2]) {
    int sets = end - begin >= REFL__BVH_TWO_SETS ? 2 : 1;
    refl__bvh_bin_sets(pr, begin, end, sets, cmin, scale, bins);
    if (sets == 2) refl__bvh_bins_merge(&bins[0], &bins[1]);
}

/* Moves triangles [begin, end) whose bin on `axis` is at most split_bin
   before the others, each side in its order; each side's centroid box
   into lcbox and rcbox. Returns where the second side starts. Every
   triangle is written both to its place on the left (which the reading
   has passed) and to the right side's place in `spare` (its same range),
   and only its side's count moves on: no branch on the side, which no
   predictor guesses. The right side then follows the left. */
static int refl__bvh_partition(refl__bvh_prims *pr, refl__bvh_prims *spare, int begin, int end, int axis,
                               int split_bin, refl__v4 cmin, refl__v4 scale, refl__bvh_box *lcbox,
                               refl__bvh_box *rcbox) {
    const refl__v4 big = refl__v4_set1(FLT_MAX), small = refl__v4_set1(-FLT_MAX);
    refl__v4 llo = big, lhi = small, rlo = big, rhi = small;
    int i, left = begin, right = begin;
    for (i = begin; i < end; ++i) {
        refl__v4 blo = refl__v4_load(pr->box[i].lo), bhi = refl__v4_load(pr->box[i].hi);
        refl__v4 c = refl__v4_mul(refl__v4_set1(0.5f), refl__v4_add(blo, bhi));
        int32_t id = pr->id[i];
        int bin[3], r;
        refl__bvh_bins_of(c, cmin, scale, bin);
        r = bin[axis] > split_bin;
        /* the other side's box grows by an empty box's corner: not at all */
        llo = refl__v4_min(llo, refl__v4_select(r, big, c));
        lhi = refl__v4_max(lhi, refl__v4_select(r, small, c));
        rlo = refl__v4_min(rlo, refl__v4_select(r, c, big));
        rhi = refl__v4_max(rhi, refl__v4_select(r, c, small));
        refl__v4_store(pr->box[left].lo, blo);
        refl__v4_store(pr->box[left].hi, bhi);
        pr->id[left] = id;
        refl__v4_store(spare->box[right].lo, blo);
        refl__v4_store(spare->box[right].hi, bhi);
        spare->id[right] = id;
        left += 1 - r;
        right += r;
    }
    memcpy(&pr->box[left], &spare->box[begin], sizeof *pr->box * (size_t)(right - begin));
    memcpy(&pr->id[left], &spare->id[begin], sizeof *pr->id * (size_t)(right - begin));
    refl__v4_store(lcbox->lo, llo);
    refl__v4_store(lcbox->hi, lhi);
    refl__v4_store(rcbox->lo, rlo);
    refl__v4_store(rcbox->hi, rhi);
    return left;
}

/* A node to build: its range of the triangles, and when `bounded` its box
   and its centroids' box, which the parent's split found already. */
typedef struct refl__bvh_task {
    int node, begin, end, depth, bounded;
    refl__bvh_box box, cbox;
} refl__bvh_task;

/* A node's three passes over its triangles (its boxes, its bins, its
   partition), the parallel build's (refl__bvh_par_*) or the serial ones. */
typedef struct refl__bvh_passes refl__bvh_passes;
static void refl__bvh_par_bound(refl__bvh_passes *ps, int begin, int end, refl__bvh_box *box, refl__bvh_box *cbox);
static void refl__bvh_par_bin(refl__bvh_passes *ps, int begin, int end, refl__v4 cmin, refl__v4 scale,
                              refl__bvh_bins *bins);
static int refl__bvh_par_partition(refl__bvh_passes *ps, int begin, int end, int axis, int split_bin, refl__v4 cmin,
                                   refl__v4 scale, const refl__bvh_bins *bins, refl__bvh_box *lcbox,
                                   refl__bvh_box *rcbox);

/* The boxes of triangles [begin, end) and of their centroids. */
static void refl__bvh_bound(const refl__bvh_prims *pr, int begin, int end, refl__bvh_box *box, refl__bvh_box *cbox) {
    refl__v4 blo = refl__v4_set1(FLT_MAX), bhi = refl__v4_set1(-FLT_MAX), clo = blo, chi = bhi;
    int i;
    for (i = begin; i < end; ++i) {
        refl__v4 c = refl__bvh_centroid(&pr->box[i]);
        blo = refl__v4_min(blo, refl__v4_load(pr->box[i].lo));
        bhi = refl__v4_max(bhi, refl__v4_load(pr->box[i].hi));
        clo = refl__v4_min(clo, c);
        chi = refl__v4_max(chi, c);
    }
    refl__v4_store(box->lo, blo);
    refl__v4_store(box->hi, bhi);
    refl__v4_store(cbox->lo, clo);
    refl__v4_store(cbox->hi, chi);
}

/* Builds one node: its box into *node (a leaf of the task's range until
   split), and when it is split (returns 1) its two children's tasks,
   left first, into child (their node fields for the caller). Serial
   passes when ps is NULL; the same bits either way. */
REFL__BVH_INLINE
static int refl__bvh_split(refl__bvh_passes *ps, refl__bvh_prims *pr, refl__bvh_prims *spare,
                           const refl__bvh_task *task, refl__bvh_node *node, refl__bvh_task child[2]) {
    refl__bvh_bins bins[2];
    int n = task->end - task->begin, j, k, axis = -1, split_bin = 0, mid, split_bounded = 0;
    refl__bvh_box box = task->box, cbox = task->cbox, lcbox, rcbox;
    float best_cost = FLT_MAX, leaf_cost, s3[4], parea;
    refl__v4 cmin, scale;

    if (!task->bounded) {
        if (ps) refl__bvh_par_bound(ps, task->begin, task->end, &box, &cbox);
        else refl__bvh_bound(pr, task->begin, task->end, &box, &cbox);
    }
    for (k = 0; k < 3; ++k) { node->lo[k] = box.lo[k]; node->hi[k] = box.hi[k]; }
    node->index = task->begin;
    node->count = n;
    if (n <= REFL__BVH_LEAF || task->depth >= REFL__BVH_MAX_DEPTH) return 0;

    /* SAH with traversal cost 1 and REFL__BVH_LEAF_COST, relative to
       the parent's area. One pass bins the three axes (an axis
       without extent: scale 0, not split). */
    leaf_cost = REFL__BVH_LEAF_COST(n);
    for (k = 0; k < 3; ++k) {
        float extent = cbox.hi[k] - cbox.lo[k];
        s3[k] = extent > 0 ? (float)REFL__BVH_BINS * (1.0f - 1e-6f) / extent : 0.0f;
        if (!refl__isfinite(s3[k])) s3[k] = 0.0f; /* denormal extent */
    }
    s3[3] = 0.0f;
    cmin = refl__v4_load(cbox.lo);
    scale = refl__v4_load(s3);
    if (ps) refl__bvh_par_bin(ps, task->begin, task->end, cmin, scale, bins);
    else refl__bvh_bin_range(pr, task->begin, task->end, cmin, scale, bins);
    parea = refl__box_area(&box);
    for (k = 0; k < 3; ++k) {
        const refl__bvh_box *b = bins[0].box[k];
        const int *counts = bins[0].count[k];
        int full[REFL__BVH_BINS], m = 0, left_n[REFL__BVH_BINS], right_n[REFL__BVH_BINS];
        float left_area[REFL__BVH_BINS], right_area[REFL__BVH_BINS], cost[REFL__BVH_BINS];
        refl__bvh_box acc;
        if (s3[k] == 0.0f) continue;
        /* The bins holding triangles: a split after an empty bin
           costs what the split before it does, and the first of equal
           costs wins, so only splits after these are costed. */
        for (j = 0; j < REFL__BVH_BINS; ++j) {
            full[m] = j;
            m += counts[j] > 0;
        }
        /* Sweep from the right, then from the left: split i is after
           bin full[i]. Then each split's cost, apart from the sweeps'
           chains of dependent merges, so that they overlap. */
        refl__box_empty(&acc);
        for (j = m - 1; j > 0; --j) {
            refl__box_merge(&acc, &b[full[j]]);
            right_n[j - 1] = counts[full[j]] + (j < m - 1 ? right_n[j] : 0);
            right_area[j - 1] = refl__box_area_full(&acc);
        }
        refl__box_empty(&acc);
        for (j = 0; j < m - 1; ++j) {
            refl__box_merge(&acc, &b[full[j]]);
            left_n[j] = counts[full[j]] + (j > 0 ? left_n[j - 1] : 0);
            left_area[j] = refl__box_area_full(&acc);
        }
        for (j = 0; j < m - 1; ++j)
            cost[j] = parea > 0 ? 1.0f + (left_area[j] * REFL__BVH_LEAF_COST(left_n[j]) +
                                          right_area[j] * REFL__BVH_LEAF_COST(right_n[j])) / parea
                                : 1.0f + REFL__BVH_LEAF_COST(n); /* flat cluster: any split is as good */
        for (j = 0; j < m - 1; ++j)
            if (cost[j] < best_cost) {
                best_cost = cost[j];
                axis = k;
                split_bin = full[j];
            }
    }
    if (axis >= 0 && best_cost >= leaf_cost && n <= REFL__BVH_MAX_LEAF) return 0;

    if (axis >= 0) {
        /* Both sides are non-empty by construction. */
        if (ps)
            mid = refl__bvh_par_partition(ps, task->begin, task->end, axis, split_bin, cmin, scale, bins, &lcbox,
                                          &rcbox);
        else
            mid = refl__bvh_partition(pr, spare, task->begin, task->end, axis, split_bin, cmin, scale, &lcbox,
                                      &rcbox);
        split_bounded = 1;
        if (mid == task->begin || mid == task->end) {
            mid = task->begin + n / 2;
            split_bounded = 0;
        }
    } else {
        /* Every centroid coincides: no axis separates them, so halve the range. */
        mid = task->begin + n / 2;
    }
    child[0].begin = task->begin; child[0].end = mid;
    child[1].begin = mid; child[1].end = task->end;
    for (k = 0; k < 2; ++k) {
        child[k].depth = task->depth + 1;
        child[k].bounded = split_bounded;
    }
    if (split_bounded) {
        /* the sides' boxes are their bins' (min and max are exact:
           the same floats as a pass over the triangles) */
        refl__box_empty(&child[0].box);
        refl__box_empty(&child[1].box);
        for (j = 0; j < REFL__BVH_BINS; ++j)
            refl__box_merge(j <= split_bin ? &child[0].box : &child[1].box, &bins[0].box[axis][j]);
        child[0].cbox = lcbox;
        child[1].cbox = rcbox;
    }
    return 1;
}

/* Builds the subtree of task `root` into nodes[], depth first, left
   child first: the root at nodes[0], the rest from nodes[1] on, each
   interior node's children adjacent. Returns the number of nodes. The
   whole tree built in one piece is refl_bvh_build's, node for node. */
static int refl__bvh_build_subtree(refl__bvh_node *nodes, const refl__bvh_task *root, refl__bvh_prims *pr,
                                   refl__bvh_prims *spare) {
    refl__bvh_task stack[2 * REFL__BVH_MAX_DEPTH + 8];
    int sp = 1, count = 1;
    stack[0] = *root;
    stack[0].node = 0;
    while (sp > 0) {
        refl__bvh_task task = stack[--sp], child[2];
        refl__bvh_node *node = &nodes[task.node];
        if (!refl__bvh_split(NULL, pr, spare, &task, node, child)) continue;
        node->index = count;
        node->count = 0;
        count += 2;
        /* Left on top, so it is built first: nodes land in depth-first order. */
        child[0].node = node->index;
        child[1].node = node->index + 1;
        stack[sp] = child[1];
        stack[sp + 1] = child[0];
        sp += 2;
    }
    return count;
}

static int refl__tri_ok(const float *v) {
    int k;
    double e1[3], e2[3], c[3];
    for (k = 0; k < 9; ++k)
        if (!refl__isfinite(v[k])) return 0;
    for (k = 0; k < 3; ++k) { e1[k] = (double)v[3 + k] - v[k]; e2[k] = (double)v[6 + k] - v[k]; }
    c[0] = e1[1] * e2[2] - e1[2] * e2[1];
    c[1] = e1[2] * e2[0] - e1[0] * e2[2];
    c[2] = e1[0] * e2[1] - e1[1] * e2[0];
    return c[0] != 0 || c[1] != 0 || c[2] != 0;
}

REFL_API void refl_bvh_destroy(refl_bvh *bvh) {
    refl_allocator a;
    if (!bvh) return;
    a = bvh->allocator;
    refl__free(&a, bvh->nodes);
    refl__free(&a, bvh->wide_mem);
    refl__free(&a, bvh->tris);
    refl__free(&a, bvh->blocks_mem);
    refl__free(&a, bvh->object_tris);
    refl__free(&a, bvh);
}

/* ---- collapse into the wide tree ------------------------------------------------ */

static float refl__bvh_node_area(const refl__bvh_node *n) {
    refl__bvh_box b;
    int k;
    for (k = 0; k < 3; ++k) { b.lo[k] = n->lo[k]; b.hi[k] = n->hi[k]; }
    return refl__box_area(&b);
}

/* Each wide node starts from a binary interior node's two children and
   opens the interior one with the largest box until it has eight (or
   only leaves): the larger a box, the more rays enter it (SAH), so those
   are the levels most worth skipping. A wide node is thus no deeper than
   the binary node it starts from. */
static void refl__bvh_collapse(refl_bvh *bvh) {
    struct { int binary, wide; } stack[REFL__BVHW_STACK];
    const refl__bvh_node *nodes = bvh->nodes;
    int sp = 1;
    stack[0].binary = 0;
    stack[0].wide = 0;
    bvh->wide_count = 1;
    while (sp > 0) {
        int b, w, slot[REFL__BVH_W], n = 0, k, lane;
        refl__bvhw_node *node;
        --sp;
        b = stack[sp].binary;
        w = stack[sp].wide;
        node = &bvh->wide[w];
        if (nodes[b].count > 0) {
            slot[n++] = b; /* the root alone is a leaf */
        } else {
            slot[n++] = nodes[b].index;
            slot[n++] = nodes[b].index + 1;
        }
        while (n < REFL__BVH_W) {
            int best = -1;
            float best_area = -1.0f;
            for (k = 0; k < n; ++k)
                if (nodes[slot[k]].count == 0 && refl__bvh_node_area(&nodes[slot[k]]) > best_area) {
                    best = k;
                    best_area = refl__bvh_node_area(&nodes[slot[k]]);
                }
            if (best < 0) break;
            k = nodes[slot[best]].index;
            slot[best] = k;
            slot[n++] = k + 1;
        }
        for (lane = 0; lane < REFL__BVH_W; ++lane) {
            const refl__bvh_node *c = lane < n ? &nodes[slot[lane]] : NULL;
            for (k = 0; k < 3; ++k) {
                node->box[k][lane] = c ? c->lo[k] : INFINITY;
                node->box[3 + k][lane] = c ? c->hi[k] : -INFINITY;
            }
            if (!c) {
                node->child[lane] = -1;
                node->count[lane] = 0;
            } else if (c->count > 0) {
                node->child[lane] = c->index;
                node->count[lane] = c->count;
            } else {
                REFL_ASSERT(sp < REFL__BVHW_STACK);
                node->child[lane] = bvh->wide_count++;
                node->count[lane] = 0;
                stack[sp].binary = slot[lane];
                stack[sp].wide = node->child[lane];
                ++sp;
            }
        }
    }
}

/* The root's box, the union of its children's, into bvh->lo, hi. */
static void refl__bvh_root_box(refl_bvh *bvh) {
    int lane, k;
    for (k = 0; k < 3; ++k) { bvh->lo[k] = INFINITY; bvh->hi[k] = -INFINITY; }
    for (lane = 0; bvh->wide_count > 0 && lane < REFL__BVH_W; ++lane)
        for (k = 0; k < 3; ++k) {
            bvh->lo[k] = REFL__MIN(bvh->lo[k], bvh->wide[0].box[k][lane]);
            bvh->hi[k] = REFL__MAX(bvh->hi[k], bvh->wide[0].box[3 + k][lane]);
        }
}

/* An array of count * size bytes, not zeroed (the build fills what it
   reads); NULL on overflow or failure. */
static void *refl__bvh_alloc(const refl_allocator *a, size_t count, size_t size) {
    if (size && count > (size_t)-1 / size) return NULL;
    return refl__alloc(a, count * size);
}

/* An array (not zeroed: its writer fills every byte) starting on a
   64-byte cache line, so that each node and block, a whole number of
   lines, touches no line more than it must; *mem receives what to free. */
static void *refl__bvh_alloc_lines(const refl_allocator *a, size_t count, size_t size, void **mem) {
    uintptr_t p;
    if (size && count > ((size_t)-1 - 64) / size) return NULL;
    *mem = refl__alloc(a, count * size + 64);
    if (!*mem) return NULL;
    p = (uintptr_t)*mem;
    return (void *)(p + (64 - p % 64) % 64);
}

/* ---- the build on several threads ------------------------------------------------ */

/* The fewest triangles a job of a parallel pass takes. */
#define REFL__BVH_GRAIN 8192

/* Jobs on the pool, or on the calling thread when there is none. */
static void refl__bvh_run(rast_context *rc, int count, rast_job_fn job, void *arg) {
    int i;
    if (rc) rast_run_jobs(rc, count, job, arg);
    else
        for (i = 0; i < count; ++i) job(arg, i);
}

/* A node's pass over its range [begin, end), in `jobs` pieces of `piece`
   triangles (an even number, so that a piece's two sets of bins take
   the triangles the whole range's would), whose results are merged in
   the pieces' order: the serial pass's bits. */
struct refl__bvh_passes {
    rast_context *rc;
    int most_jobs, grain;
    refl__bvh_prims *pr, *spare;
    int begin, end, piece, jobs, axis, split_bin;
    float cmin[4], scale[4];
    refl__bvh_bins *bins;         /* two sets a job */
    refl__bvh_box *boxes;         /* two a job: box and centroids' box, or the left and right centroids' boxes */
    int *left_at, *right_at;      /* a job's first place on each side of a partition */
};

static void refl__bvh_pieces(refl__bvh_passes *ps, int begin, int end) {
    int n = end - begin, piece = (n + ps->most_jobs - 1) / ps->most_jobs;
    piece = REFL__MAX(piece, ps->grain);
    piece += piece & 1;
    ps->begin = begin;
    ps->end = end;
    ps->piece = piece;
    ps->jobs = (n + piece - 1) / piece;
}

static void refl__bvh_piece(const refl__bvh_passes *ps, int job, int *begin, int *end) {
    *begin = ps->begin + job * ps->piece;
    *end = REFL__MIN(*begin + ps->piece, ps->end);
}

static void refl__bvh_bound_job(void *arg, int job) {
    refl__bvh_passes *ps = (refl__bvh_passes *)arg;
    int a, b;
    refl__bvh_piece(ps, job, &a, &b);
    refl__bvh_bound(ps->pr, a, b, &ps->boxes[2 * job], &ps->boxes[2 * job + 1]);
}

static void refl__bvh_par_bound(refl__bvh_passes *ps, int begin, int end, refl__bvh_box *box, refl__bvh_box *cbox) {
    int j;
    refl__bvh_pieces(ps, begin, end);
    refl__bvh_run(ps->rc, ps->jobs, refl__bvh_bound_job, ps);
    refl__box_empty(box);
    refl__box_empty(cbox);
    for (j = 0; j < ps->jobs; ++j) {
        refl__box_merge(box, &ps->boxes[2 * j]);
        refl__box_merge(cbox, &ps->boxes[2 * j + 1]);
    }
}

static void refl__bvh_bin_job(void *arg, int job) {
    refl__bvh_passes *ps = (refl__bvh_passes *)arg;
    int a, b;
    refl__bvh_piece(ps, job, &a, &b);
    refl__bvh_bin_sets(ps->pr, a, b, 2, refl__v4_load(ps->cmin), refl__v4_load(ps->scale), &ps->bins[2 * job]);
}

/* refl__bvh_bin_range's bins (a range this long takes two sets). */
static void refl__bvh_par_bin(refl__bvh_passes *ps, int begin, int end, refl__v4 cmin, refl__v4 scale,
                              refl__bvh_bins *bins) {
    int j;
    REFL_ASSERT(end - begin >= REFL__BVH_TWO_SETS);
    refl__bvh_pieces(ps, begin, end);
    refl__v4_store(ps->cmin, cmin);
    refl__v4_store(ps->scale, scale);
    refl__bvh_run(ps->rc, ps->jobs, refl__bvh_bin_job, ps);
    bins[0] = ps->bins[0];
    bins[1] = ps->bins[1];
    for (j = 1; j < ps->jobs; ++j) {
        refl__bvh_bins_merge(&bins[0], &ps->bins[2 * j]);
        refl__bvh_bins_merge(&bins[1], &ps->bins[2 * j + 1]);
    }
    refl__bvh_bins_merge(&bins[0], &bins[1]);
}

/* A piece's triangles to their sides' places in spare, each side in its
   order, and each side's centroid box as refl__bvh_partition grows it. */
static void refl__bvh_partition_job(void *arg, int job) {
    refl__bvh_passes *ps = (refl__bvh_passes *)arg;
    const refl__v4 big = refl__v4_set1(FLT_MAX), small = refl__v4_set1(-FLT_MAX);
    const refl__v4 cmin = refl__v4_load(ps->cmin), scale = refl__v4_load(ps->scale);
    refl__v4 llo = big, lhi = small, rlo = big, rhi = small;
    int i, a, b, left = ps->left_at[job], right = ps->right_at[job];
    refl__bvh_piece(ps, job, &a, &b);
    for (i = a; i < b; ++i) {
        refl__v4 blo = refl__v4_load(ps->pr->box[i].lo), bhi = refl__v4_load(ps->pr->box[i].hi);
        refl__v4 c = refl__v4_mul(refl__v4_set1(0.5f), refl__v4_add(blo, bhi));
        int bin[3], r, to;
        refl__bvh_bins_of(c, cmin, scale, bin);
        r = bin[ps->axis] > ps->split_bin;
        llo = refl__v4_min(llo, refl__v4_select(r, big, c));
        lhi = refl__v4_max(lhi, refl__v4_select(r, small, c));
        rlo = refl__v4_min(rlo, refl__v4_select(r, c, big));
        rhi = refl__v4_max(rhi, refl__v4_select(r, c, small));
        to = r ? right++ : left++;
        ps->spare->box[to] = ps->pr->box[i];
        ps->spare->id[to] = ps->pr->id[i];
    }
    refl__v4_store(ps->boxes[2 * job].lo, llo);
    refl__v4_store(ps->boxes[2 * job].hi, lhi);
    refl__v4_store(ps->boxes[2 * job + 1].lo, rlo);
    refl__v4_store(ps->boxes[2 * job + 1].hi, rhi);
}

static void refl__bvh_copy_back_job(void *arg, int job) {
    refl__bvh_passes *ps = (refl__bvh_passes *)arg;
    int a, b;
    refl__bvh_piece(ps, job, &a, &b);
    memcpy(&ps->pr->box[a], &ps->spare->box[a], sizeof *ps->pr->box * (size_t)(b - a));
    memcpy(&ps->pr->id[a], &ps->spare->id[a], sizeof *ps->pr->id * (size_t)(b - a));
}

/* refl__bvh_partition's result. The pieces are those refl__bvh_par_bin
   binned (the same range): each piece's count on each side is in its
   bins, which place every piece's triangles at once. */
static int refl__bvh_par_partition(refl__bvh_passes *ps, int begin, int end, int axis, int split_bin, refl__v4 cmin,
                                   refl__v4 scale, const refl__bvh_bins *bins, refl__bvh_box *lcbox,
                                   refl__bvh_box *rcbox) {
    int j, b, left = begin, right, total_left = 0;
    (void)cmin;
    (void)scale;
    REFL_ASSERT(ps->begin == begin && ps->end == end);
    for (b = 0; b <= split_bin; ++b) total_left += bins[0].count[axis][b];
    right = begin + total_left;
    for (j = 0; j < ps->jobs; ++j) {
        int a0, a1, n_left = 0;
        refl__bvh_piece(ps, j, &a0, &a1);
        for (b = 0; b <= split_bin; ++b) n_left += ps->bins[2 * j].count[axis][b] + ps->bins[2 * j + 1].count[axis][b];
        ps->left_at[j] = left;
        ps->right_at[j] = right;
        left += n_left;
        right += a1 - a0 - n_left;
    }
    ps->axis = axis;
    ps->split_bin = split_bin;
    refl__bvh_run(ps->rc, ps->jobs, refl__bvh_partition_job, ps);
    refl__bvh_run(ps->rc, ps->jobs, refl__bvh_copy_back_job, ps);
    refl__box_empty(lcbox);
    refl__box_empty(rcbox);
    for (j = 0; j < ps->jobs; ++j) {
        refl__box_merge(lcbox, &ps->boxes[2 * j]);
        refl__box_merge(rcbox, &ps->boxes[2 * j + 1]);
    }
    return begin + total_left;
}

/* A node of the tree's top, which the parallel build splits one at a time
   with parallel passes, down to nodes small enough to build each as one
   piece (deferred), on its own thread. */
typedef struct refl__bvh_top {
    refl__bvh_task task;
    refl__bvh_node node;          /* as in the tree, but an interior node's index names its children in the tops */
    int deferred;                 /* its subtree built in one piece (refl__bvh_build_subtree) */
    int count;                    /* deferred: its subtree's nodes */
    int at, first;                /* its node in the tree; deferred: where its subtree's other nodes start */
} refl__bvh_top;

typedef struct refl__bvh_subtrees {
    refl__bvh_top *tops;
    int *deferred;                /* the deferred tops, largest first */
    refl__bvh_node *built;        /* a deferred top's subtree at 2 task.begin (room for its 2 n - 1 nodes) */
    refl__bvh_node *nodes;        /* the tree */
    refl__bvh_prims *pr, *spare;
} refl__bvh_subtrees;

static void refl__bvh_subtree_job(void *arg, int job) {
    refl__bvh_subtrees *st = (refl__bvh_subtrees *)arg;
    refl__bvh_top *t = &st->tops[st->deferred[job]];
    t->count = refl__bvh_build_subtree(st->built + 2 * (size_t)t->task.begin, &t->task, st->pr, st->spare);
}

/* A subtree into its place: its root at `at`, its node k > 0 at
   first + k - 1, where the whole tree built in one piece puts them. */
static void refl__bvh_place_job(void *arg, int job) {
    refl__bvh_subtrees *st = (refl__bvh_subtrees *)arg;
    const refl__bvh_top *t = &st->tops[st->deferred[job]];
    const refl__bvh_node *from = st->built + 2 * (size_t)t->task.begin;
    int k;
    for (k = 0; k < t->count; ++k) {
        refl__bvh_node n = from[k];
        if (n.count == 0) n.index += t->first - 1;
        st->nodes[k ? t->first + k - 1 : t->at] = n;
    }
}

/* The tree's nodes in refl__bvh_build_subtree's order: depth first, left
   first, children numbered when their parent is reached. */
static int refl__bvh_number_tops(refl__bvh_top *tops, refl__bvh_node *nodes) {
    struct { int top, at; } stack[2 * REFL__BVH_MAX_DEPTH + 8];
    int sp = 1, count = 1;
    stack[0].top = 0;
    stack[0].at = 0;
    while (sp > 0) {
        refl__bvh_top *t;
        --sp;
        t = &tops[stack[sp].top];
        t->at = stack[sp].at;
        if (t->deferred) {
            t->first = count;
            count += t->count - 1;
        } else if (t->node.count > 0) {
            nodes[t->at] = t->node;
        } else {
            nodes[t->at] = t->node;
            nodes[t->at].index = count;
            stack[sp].top = t->node.index + 1;
            stack[sp].at = count + 1;
            stack[sp + 1].top = t->node.index;
            stack[sp + 1].at = count;
            sp += 2;
            count += 2;
        }
    }
    return count;
}

typedef struct refl__bvh_sized { int size, top; } refl__bvh_sized;

static int refl__bvh_larger_first(const void *a, const void *b) {
    const refl__bvh_sized *x = (const refl__bvh_sized *)a, *y = (const refl__bvh_sized *)b;
    if (x->size != y->size) return x->size > y->size ? -1 : 1;
    return (x->top > y->top) - (x->top < y->top);
}

/* The binary tree over pr's n triangles into bvh->nodes (room for 2 n - 1),
   on rc's threads: the tree's top split with parallel passes, the
   subtrees below built in one piece each, in parallel, then put where
   the serial build puts their nodes. The same nodes, bit for bit, as
   refl__bvh_build_subtree's of the whole (`threads` 1). */
static refl_result refl__bvh_build_tree(refl_bvh *bvh, const refl_allocator *a, rast_context *rc, int threads,
                                        int grain, refl__bvh_prims *pr, refl__bvh_prims *spare) {
    refl__bvh_task root;
    refl__bvh_passes ps;
    refl__bvh_subtrees st;
    struct { int top; } stack[2 * REFL__BVH_MAX_DEPTH + 8];
    int n = bvh->tri_count, cutoff, top_count = 1, capacity, sp = 1, deferred = 0, i, j;
    refl__bvh_sized *order = NULL;
    refl_result r = REFL_OK;

    memset(&root, 0, sizeof root);
    root.begin = 0;
    root.end = n;
    /* below this, a subtree is one job; above it, a node's passes are */
    cutoff = REFL__MAX(REFL__MAX(2 * grain, REFL__BVH_TWO_SETS), n / (8 * threads));
    if (threads <= 1 || n < cutoff) {
        bvh->node_count = refl__bvh_build_subtree(bvh->nodes, &root, pr, spare);
        return REFL_OK;
    }
    memset(&ps, 0, sizeof ps);
    memset(&st, 0, sizeof st);
    ps.rc = rc;
    ps.most_jobs = 4 * threads;
    ps.grain = grain;
    ps.pr = pr;
    ps.spare = spare;
    capacity = 64;
    ps.bins = (refl__bvh_bins *)refl__bvh_alloc(a, (size_t)ps.most_jobs * 2, sizeof *ps.bins);
    ps.boxes = (refl__bvh_box *)refl__bvh_alloc(a, (size_t)ps.most_jobs * 2, sizeof *ps.boxes);
    ps.left_at = (int *)refl__bvh_alloc(a, (size_t)ps.most_jobs * 2, sizeof *ps.left_at);
    st.tops = (refl__bvh_top *)refl__bvh_alloc(a, (size_t)capacity, sizeof *st.tops);
    st.built = (refl__bvh_node *)refl__bvh_alloc(a, (size_t)(2 * n - 1), sizeof *st.built);
    if (!ps.bins || !ps.boxes || !ps.left_at || !st.tops || !st.built) {
        r = REFL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    ps.right_at = ps.left_at + ps.most_jobs;

    memset(&st.tops[0], 0, sizeof st.tops[0]);
    st.tops[0].task = root;
    stack[0].top = 0;
    while (sp > 0) {
        refl__bvh_task child[2];
        refl__bvh_top *t;
        int e = stack[--sp].top;
        if (st.tops[e].task.end - st.tops[e].task.begin < cutoff) {
            st.tops[e].deferred = 1;
            ++deferred;
            continue;
        }
        if (top_count + 2 > capacity) {
            refl__bvh_top *more = (refl__bvh_top *)refl__bvh_alloc(a, (size_t)capacity * 2, sizeof *more);
            if (!more) {
                r = REFL_ERROR_OUT_OF_MEMORY;
                goto done;
            }
            memcpy(more, st.tops, sizeof *more * (size_t)top_count);
            refl__free(a, st.tops);
            st.tops = more;
            capacity *= 2;
        }
        t = &st.tops[e];
        if (!refl__bvh_split(&ps, pr, spare, &t->task, &t->node, child)) continue;
        t->node.index = top_count;
        t->node.count = 0;
        for (j = 0; j < 2; ++j) {
            memset(&st.tops[top_count + j], 0, sizeof st.tops[0]);
            st.tops[top_count + j].task = child[j];
        }
        stack[sp].top = top_count + 1;
        stack[sp + 1].top = top_count;
        sp += 2;
        top_count += 2;
    }

    /* the subtrees, largest first, so that the last to start are short */
    st.deferred = (int *)refl__bvh_alloc(a, (size_t)deferred, sizeof *st.deferred);
    order = (refl__bvh_sized *)refl__bvh_alloc(a, (size_t)deferred, sizeof *order);
    if (!st.deferred || !order) {
        r = REFL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    for (i = 0, j = 0; i < top_count; ++i)
        if (st.tops[i].deferred) {
            order[j].size = st.tops[i].task.end - st.tops[i].task.begin;
            order[j++].top = i;
        }
    qsort(order, (size_t)deferred, sizeof *order, refl__bvh_larger_first);
    for (i = 0; i < deferred; ++i) st.deferred[i] = order[i].top;
    st.nodes = bvh->nodes;
    st.pr = pr;
    st.spare = spare;
    refl__bvh_run(rc, deferred, refl__bvh_subtree_job, &st);
    bvh->node_count = refl__bvh_number_tops(st.tops, bvh->nodes);
    refl__bvh_run(rc, deferred, refl__bvh_place_job, &st);
done:
    refl__free(a, ps.bins);
    refl__free(a, ps.boxes);
    refl__free(a, ps.left_at);
    refl__free(a, st.tops);
    refl__free(a, st.built);
    refl__free(a, st.deferred);
    refl__free(a, order);
    return r;
}

/* The build's input on several threads: every object's vertices in world
   space, then its triangles, each at its place among all objects'
   (tris[], `object` -1 for one left out as degenerate), then the kept
   ones' boxes and places in order into pr. */
typedef struct refl__bvh_input {
    const refl_scene *scene;
    refl__bvh_tri *tris;
    refl_vec3 *world;
    const size_t *first_vertex;   /* an object's first in world[] (one more: the total) */
    const int *first_tri;         /* an object's first in tris[] (one more: the total) */
    int jobs;
    size_t vertex_piece;
    int tri_piece;
    int *kept;                    /* a job's triangles kept, then the first of its places in pr */
    int *bad;                     /* a job's: a vertex index out of range */
    refl__bvh_prims *pr;
} refl__bvh_input;

/* The object whose range of first[] holds `at`. */
static int refl__bvh_object_at_tri(const refl__bvh_input *in, int at) {
    int lo = 0, hi = in->scene->object_count - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if (in->first_tri[mid] <= at) lo = mid;
        else hi = mid - 1;
    }
    return lo;
}

static void refl__bvh_world_job(void *arg, int job) {
    refl__bvh_input *in = (refl__bvh_input *)arg;
    size_t total = in->first_vertex[in->scene->object_count];
    size_t at = (size_t)job * in->vertex_piece, end = REFL__MIN(at + in->vertex_piece, total);
    int lo = 0, hi = in->scene->object_count - 1;
    if (at >= end) return;
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if (in->first_vertex[mid] <= at) lo = mid;
        else hi = mid - 1;
    }
    for (; at < end; ++at) {
        const refl_object *o;
        const float *p;
        while (in->first_vertex[lo + 1] <= at) ++lo;
        o = &in->scene->objects[lo];
        p = in->scene->meshes[o->mesh]->positions + 3 * (at - in->first_vertex[lo]);
        in->world[at] = refl_mat4_point(o->transform, refl_v3(p[0], p[1], p[2]));
    }
}

static void refl__bvh_tris_job(void *arg, int job) {
    refl__bvh_input *in = (refl__bvh_input *)arg;
    int total = in->first_tri[in->scene->object_count], at = job * in->tri_piece;
    int end = REFL__MIN(at + in->tri_piece, total), i, kept = 0;
    in->bad[job] = 0;
    if (at < end) {
        for (i = refl__bvh_object_at_tri(in, at); at < end; ++at) {
            const refl_mesh *mesh;
            const refl_vec3 *world;
            refl__bvh_tri *dst = &in->tris[at];
            int t, j;
            while (in->first_tri[i + 1] <= at) ++i;
            mesh = in->scene->meshes[in->scene->objects[i].mesh];
            world = in->world + in->first_vertex[i];
            t = at - in->first_tri[i];
            for (j = 0; j < 3; ++j) {
                uint32_t vi = mesh->indices[3 * (size_t)t + j];
                if (vi >= (uint32_t)mesh->vertex_count) {
                    in->bad[job] = 1;
                    return;
                }
                dst->v[3 * j] = world[vi].x;
                dst->v[3 * j + 1] = world[vi].y;
                dst->v[3 * j + 2] = world[vi].z;
            }
            dst->object = refl__tri_ok(dst->v) ? i : -1;
            dst->triangle = t;
            kept += dst->object >= 0;
        }
    }
    in->kept[job] = kept;
}

static void refl__bvh_prims_job(void *arg, int job) {
    refl__bvh_input *in = (refl__bvh_input *)arg;
    int total = in->first_tri[in->scene->object_count], at = job * in->tri_piece;
    int end = REFL__MIN(at + in->tri_piece, total), k = in->kept[job];
    for (; at < end; ++at) {
        if (in->tris[at].object < 0) continue;
        refl__tri_box(&in->tris[at], &in->pr->box[k]);
        in->pr->id[k++] = at;
    }
}

/* Each leaf's triangles into its blocks, in the order the build left
   them in (id[]); the leaf then names its first block. A job takes
   nodes [at[job], at[job + 1]) and its leaves' blocks from first[job]. */
typedef struct refl__bvh_filling {
    refl_bvh *bvh;
    const int32_t *id;
    int jobs, piece;
    int *first;
} refl__bvh_filling;

static void refl__bvh_count_blocks_job(void *arg, int job) {
    refl__bvh_filling *f = (refl__bvh_filling *)arg;
    int i = job * f->piece, end = REFL__MIN(i + f->piece, f->bvh->node_count), blocks = 0;
    for (; i < end; ++i) blocks += (f->bvh->nodes[i].count + 3) / 4;
    f->first[job] = blocks;
}

static void refl__bvh_fill_blocks_job(void *arg, int job) {
    refl__bvh_filling *f = (refl__bvh_filling *)arg;
    refl_bvh *bvh = f->bvh;
    int i = job * f->piece, end = REFL__MIN(i + f->piece, bvh->node_count), b = f->first[job], j, k;
    for (; i < end; ++i) {
        refl__bvh_node *leaf = &bvh->nodes[i];
        if (leaf->count == 0) continue;
        memset(&bvh->blocks[b], 0, sizeof *bvh->blocks * (size_t)((leaf->count + 3) / 4));
        for (j = 0; j < leaf->count; ++j) {
            const refl__bvh_tri *t = &bvh->tris[f->id[leaf->index + j]];
#ifdef REFL__BVH_SSE2
            /* the triangles are scattered over tris[]: ask for those a few leaves on */
            if (leaf->index + j + 16 < bvh->tri_count) _mm_prefetch((const char *)&bvh->tris[f->id[leaf->index + j + 16]], _MM_HINT_T0);
#endif
            refl__bvh_tri4 *q = &bvh->blocks[b + j / 4];
            for (k = 0; k < 9; ++k) q->v[k][j % 4] = t->v[k];
            q->object[j % 4] = t->object;
            q->triangle[j % 4] = t->triangle;
        }
        for (; j % 4; ++j) bvh->blocks[b + j / 4].object[j % 4] = -1;
        leaf->index = b;
        b += (leaf->count + 3) / 4;
    }
}

/* Triangle t of object i in world space into v (0: an index out of range). */
static int refl__bvh_world_tri(const refl_scene *scene, int i, int t, float v[9]) {
    const refl_object *o = &scene->objects[i];
    const refl_mesh *mesh = scene->meshes[o->mesh];
    int j;
    for (j = 0; j < 3; ++j) {
        uint32_t vi = mesh->indices[3 * t + j];
        const float *p;
        refl_vec3 w;
        if (vi >= (uint32_t)mesh->vertex_count) return 0;
        p = mesh->positions + 3 * (size_t)vi;
        w = refl_mat4_point(o->transform, refl_v3(p[0], p[1], p[2]));
        v[3 * j] = w.x; v[3 * j + 1] = w.y; v[3 * j + 2] = w.z;
    }
    return 1;
}

/* keep_binary: keep the binary tree too, for the tests that compare the
   two (refl__bvh_intersect_binary). rc: the threads to build on (NULL:
   the calling thread); grain: the fewest triangles a parallel job takes.
   The same tree, bit for bit, whatever the threads and grain. */
static refl_result refl__bvh_build_ex(const refl_scene *scene, const refl_allocator *a, int keep_binary,
                                      rast_context *rc, int grain, refl_bvh **out_bvh) {
    refl_bvh *bvh;
    refl__bvh_prims pr, spare;
    refl__bvh_input in;
    refl__bvh_filling fill;
    size_t *first_vertex = NULL;
    int *first_tri = NULL, *job_ints = NULL;
    long long total = 0, vertices = 0;
    int i, n = 0, threads = rc ? rast_context_threads(rc) : 1;
    refl_result r = REFL_ERROR_OUT_OF_MEMORY;

    if (out_bvh) *out_bvh = NULL;
    if (!scene || !out_bvh) return REFL_ERROR_INVALID_ARGUMENT;
    if (scene->object_count < 0 || (scene->object_count > 0 && !scene->objects))
        return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < scene->object_count; ++i) {
        int m = scene->objects[i].mesh;
        const refl_mesh *mesh;
        if (m < 0 || m >= scene->mesh_count || !scene->meshes || !scene->meshes[m]) return REFL_ERROR_BAD_MESH;
        mesh = scene->meshes[m];
        if (mesh->triangle_count < 0 || (mesh->triangle_count > 0 && (!mesh->positions || !mesh->indices)))
            return REFL_ERROR_BAD_MESH;
        total += mesh->triangle_count;
        if (mesh->triangle_count > 0) vertices += REFL__MAX(mesh->vertex_count, 0);
    }
    /* 2n - 1 nodes must fit an int32 index. */
    if (total > INT_MAX / 4) return REFL_ERROR_INVALID_SIZE;

    bvh = (refl_bvh *)refl__calloc(a, 1, sizeof *bvh);
    if (!bvh) return REFL_ERROR_OUT_OF_MEMORY;
    bvh->allocator = refl__allocator(a);
    if (total == 0) { *out_bvh = bvh; return REFL_OK; }
    memset(&pr, 0, sizeof pr);
    memset(&spare, 0, sizeof spare);
    memset(&in, 0, sizeof in);

    bvh->object_count = scene->object_count;
    bvh->object_tris = (int *)refl__calloc(a, (size_t)REFL__MAX(scene->object_count, 1), sizeof(int));
    bvh->tris = (refl__bvh_tri *)refl__bvh_alloc(a, (size_t)total, sizeof *bvh->tris);
    in.world = (refl_vec3 *)refl__bvh_alloc(a, (size_t)REFL__MAX(vertices, 1), sizeof *in.world);
    first_vertex = (size_t *)refl__bvh_alloc(a, (size_t)scene->object_count + 1, sizeof *first_vertex);
    first_tri = (int *)refl__bvh_alloc(a, (size_t)scene->object_count + 1, sizeof *first_tri);
    in.jobs = threads <= 1 ? 1 : (int)REFL__MIN((long long)4 * threads, (total + grain - 1) / grain);
    job_ints = (int *)refl__bvh_alloc(a, (size_t)in.jobs * 2, sizeof *job_ints);
    if (!bvh->object_tris || !bvh->tris || !in.world || !first_vertex || !first_tri || !job_ints) goto fail;
    first_vertex[0] = 0;
    first_tri[0] = 0;
    for (i = 0; i < scene->object_count; ++i) {
        const refl_mesh *mesh = scene->meshes[scene->objects[i].mesh];
        bvh->object_tris[i] = mesh->triangle_count;
        first_vertex[i + 1] = first_vertex[i] + (mesh->triangle_count > 0 ? (size_t)REFL__MAX(mesh->vertex_count, 0) : 0);
        first_tri[i + 1] = first_tri[i] + mesh->triangle_count;
    }
    /* World space once per vertex, so triangles sharing a vertex share
       its exact floats: the watertight test relies on that. */
    in.scene = scene;
    in.tris = bvh->tris;
    in.first_vertex = first_vertex;
    in.first_tri = first_tri;
    in.vertex_piece = (size_t)((vertices + in.jobs - 1) / in.jobs);
    in.tri_piece = (int)((total + in.jobs - 1) / in.jobs);
    in.kept = job_ints;
    in.bad = job_ints + in.jobs;
    in.pr = &pr;
    refl__bvh_run(rc, in.jobs, refl__bvh_world_job, &in);
    refl__bvh_run(rc, in.jobs, refl__bvh_tris_job, &in);
    for (i = 0; i < in.jobs; ++i) {
        int kept = in.kept[i];
        if (in.bad[i]) {
            r = REFL_ERROR_BAD_MESH;
            goto fail;
        }
        in.kept[i] = n;
        n += kept;
    }
    refl__free(a, in.world);
    in.world = NULL;
    bvh->tri_count = n;
    if (n == 0) goto done;

    bvh->nodes = (refl__bvh_node *)refl__bvh_alloc(a, (size_t)(2 * n - 1), sizeof *bvh->nodes);
    pr.box = (refl__bvh_box *)refl__bvh_alloc(a, (size_t)n, sizeof *pr.box);
    pr.id = (int32_t *)refl__bvh_alloc(a, (size_t)n, sizeof *pr.id);
    spare.box = (refl__bvh_box *)refl__bvh_alloc(a, (size_t)n, sizeof *spare.box);
    spare.id = (int32_t *)refl__bvh_alloc(a, (size_t)n, sizeof *spare.id);
    if (!bvh->nodes || !pr.box || !pr.id || !spare.box || !spare.id) goto fail;
    refl__bvh_run(rc, in.jobs, refl__bvh_prims_job, &in);
    r = refl__bvh_build_tree(bvh, a, rc, threads, grain, &pr, &spare);
    if (r != REFL_OK) goto fail;
    r = REFL_ERROR_OUT_OF_MEMORY;
    refl__free(a, pr.box);
    refl__free(a, spare.box);
    refl__free(a, spare.id);
    pr.box = spare.box = NULL;
    spare.id = NULL;

    /* each job's share of the blocks, in node order */
    fill.bvh = bvh;
    fill.id = pr.id;
    fill.jobs = in.jobs;
    fill.piece = (bvh->node_count + in.jobs - 1) / in.jobs;
    fill.first = job_ints;
    refl__bvh_run(rc, fill.jobs, refl__bvh_count_blocks_job, &fill);
    for (i = 0; i < fill.jobs; ++i) {
        int blocks = fill.first[i];
        fill.first[i] = bvh->block_count;
        bvh->block_count += blocks;
    }
    bvh->blocks = (refl__bvh_tri4 *)refl__bvh_alloc_lines(a, (size_t)bvh->block_count, sizeof *bvh->blocks,
                                                           &bvh->blocks_mem);
    /* A full binary tree of L leaves has L - 1 interior nodes, and each
       wide node starts from a different one (one node for a lone leaf). */
    bvh->wide = (refl__bvhw_node *)refl__bvh_alloc_lines(a, (size_t)REFL__MAX((bvh->node_count - 1) / 2, 1),
                                                          sizeof *bvh->wide, &bvh->wide_mem);
    if (!bvh->blocks || !bvh->wide) goto fail;
    refl__bvh_run(rc, fill.jobs, refl__bvh_fill_blocks_job, &fill);
    refl__free(a, bvh->tris);
    bvh->tris = NULL;

    refl__bvh_collapse(bvh);
    refl__bvh_root_box(bvh);
    if (!keep_binary) {
        refl__free(a, bvh->nodes);
        bvh->nodes = NULL;
        bvh->node_count = 0;
    }
done:
    r = REFL_OK;
fail:
    refl__free(a, in.world);
    refl__free(a, pr.box);
    refl__free(a, pr.id);
    refl__free(a, spare.box);
    refl__free(a, spare.id);
    refl__free(a, first_vertex);
    refl__free(a, first_tri);
    refl__free(a, job_ints);
    if (r != REFL_OK) {
        refl_bvh_destroy(bvh);
        return r;
    }
    *out_bvh = bvh;
    return REFL_OK;
}

REFL_API refl_result refl_bvh_build(const refl_scene *scene, const refl_allocator *a, refl_bvh **out_bvh) {
    return refl__bvh_build_ex(scene, a, 0, NULL, REFL__BVH_GRAIN, out_bvh);
}

static refl_result refl__bvh_build_on(const refl_scene *scene, const refl_allocator *a, rast_context *rc,
                                      refl_bvh **out_bvh) {
    return refl__bvh_build_ex(scene, a, 0, rc, REFL__BVH_GRAIN, out_bvh);
}

/* refl_bvh_build_threads with the tests' choices: the binary tree kept
   too, and the grain of the parallel passes. */
static refl_result refl__bvh_build_threads_ex(const refl_scene *scene, const refl_allocator *a, int threads,
                                              int keep_binary, int grain, refl_bvh **out_bvh) {
    rast_context_desc cd;
    rast_context *rc = NULL;
    refl_result r;
    if (out_bvh) *out_bvh = NULL;
    if (threads < 0 || threads > RAST_MAX_THREADS || grain < 1) return REFL_ERROR_INVALID_ARGUMENT;
    if (threads == 1) return refl__bvh_build_ex(scene, a, keep_binary, NULL, grain, out_bvh);
    memset(&cd, 0, sizeof cd);
    cd.num_threads = threads;
    if (a) {
        cd.allocator.alloc = a->alloc;
        cd.allocator.free = a->free;
        cd.allocator.user = a->user;
    }
    if ((r = refl__result_from_rast(rast_context_create(&cd, &rc))) != REFL_OK) return r;
    r = refl__bvh_build_ex(scene, a, keep_binary, rc, grain, out_bvh);
    rast_context_destroy(rc);
    return r;
}

REFL_API refl_result refl_bvh_build_threads(const refl_scene *scene, const refl_allocator *a, int threads,
                                            refl_bvh **out_bvh) {
    return refl__bvh_build_threads_ex(scene, a, threads, 0, REFL__BVH_GRAIN, out_bvh);
}

/* ---- refit ------------------------------------------------------------------- */

/* Whether the scene has the objects and triangle counts the BVH was built
   over, with the same triangles left out as degenerate. */
static int refl__bvh_refit_fits(const refl_bvh *bvh, const refl_scene *scene) {
    int i, t, ok = 0;
    float v[9];
    if (!bvh->object_tris || scene->object_count != bvh->object_count) return 0;
    for (i = 0; i < scene->object_count; ++i) {
        int m = scene->objects[i].mesh;
        const refl_mesh *mesh = m >= 0 && m < scene->mesh_count && scene->meshes ? scene->meshes[m] : NULL;
        if (!mesh || mesh->triangle_count != bvh->object_tris[i] ||
            (mesh->triangle_count > 0 && (!mesh->positions || !mesh->indices)))
            return 0;
    }
    for (i = 0; i < scene->object_count; ++i)
        for (t = 0; t < bvh->object_tris[i]; ++t) {
            if (!refl__bvh_world_tri(scene, i, t, v)) return 0;
            ok += refl__tri_ok(v);
        }
    return ok == bvh->tri_count;
}

/* Box of the `count` triangles of the leaf at blocks[first] into lo, hi. */
static void refl__bvh_leaf_box(const refl_bvh *bvh, int first, int count, float lo[3], float hi[3]) {
    int j, k;
    for (k = 0; k < 3; ++k) { lo[k] = INFINITY; hi[k] = -INFINITY; }
    for (j = 0; j < count; ++j) {
        const refl__bvh_tri4 *q = &bvh->blocks[first + j / 4];
        for (k = 0; k < 9; ++k) {
            lo[k % 3] = REFL__MIN(lo[k % 3], q->v[k][j % 4]);
            hi[k % 3] = REFL__MAX(hi[k % 3], q->v[k][j % 4]);
        }
    }
}

REFL_API refl_result refl_bvh_refit(refl_bvh *bvh, const refl_scene *scene) {
    int b, lane, w, k;
    if (!bvh || !scene) return REFL_ERROR_INVALID_ARGUMENT;
    if (!refl__bvh_refit_fits(bvh, scene)) return REFL_ERROR_UNSUPPORTED;
    for (b = 0; b < bvh->block_count; ++b) {
        refl__bvh_tri4 *q = &bvh->blocks[b];
        for (lane = 0; lane < 4; ++lane) {
            float v[9];
            if (q->object[lane] < 0) continue;
            refl__bvh_world_tri(scene, q->object[lane], q->triangle[lane], v);
            if (!refl__tri_ok(v)) return REFL_ERROR_UNSUPPORTED; /* left half refit: the caller rebuilds */
            for (k = 0; k < 9; ++k) q->v[k][lane] = v[k];
        }
    }
    /* children come after their parent (refl__bvh_collapse): bottom-up is backwards */
    for (w = bvh->wide_count - 1; w >= 0; --w) {
        refl__bvhw_node *n = &bvh->wide[w];
        for (lane = 0; lane < REFL__BVH_W; ++lane) {
            float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            if (n->count[lane] > 0) {
                refl__bvh_leaf_box(bvh, n->child[lane], n->count[lane], lo, hi);
            } else if (n->child[lane] >= 0) {
                const refl__bvhw_node *c = &bvh->wide[n->child[lane]];
                int cl;
                for (cl = 0; cl < REFL__BVH_W; ++cl)
                    for (k = 0; k < 3; ++k) {
                        lo[k] = REFL__MIN(lo[k], c->box[k][cl]);
                        hi[k] = REFL__MAX(hi[k], c->box[3 + k][cl]);
                    }
            }
            for (k = 0; k < 3; ++k) {
                n->box[k][lane] = lo[k];
                n->box[3 + k][lane] = hi[k];
            }
        }
    }
    refl__bvh_root_box(bvh);
    /* the binary tree (tests only) no longer matches: dropped */
    refl__free(&bvh->allocator, bvh->nodes);
    bvh->nodes = NULL;
    bvh->node_count = 0;
    return REFL_OK;
}

REFL_API void refl_bvh_stats(const refl_bvh *bvh, long long *nodes, long long *triangles) {
    if (nodes) *nodes = bvh ? bvh->wide_count : 0;
    if (triangles) *triangles = bvh ? bvh->tri_count : 0;
}

static long long refl__bvh_bytes(const refl_bvh *bvh) {
    if (!bvh) return 0;
    return (long long)bvh->wide_count * (long long)sizeof(refl__bvhw_node) +
           (long long)bvh->node_count * (long long)sizeof(refl__bvh_node) +
           (long long)bvh->block_count * (long long)sizeof(refl__bvh_tri4);
}

/* ---- traversal ---------------------------------------------------------------- */

typedef struct refl__bvh_ray {
    float org[3], dir[3];
    float inv[3];
    int near_lo[3];               /* 1: the ray enters a slab through its lo plane */
    int kx, ky, kz;               /* Woop's ray-space axes: kz the dominant one */
    float sx, sy, sz;             /* shear and scale to ray space */
    float slack;                  /* refl__bvh_ray_slack */
} refl__bvh_ray;

static int refl__bvh_ray_setup(refl__bvh_ray *r, refl_vec3 o, refl_vec3 d) {
    float ad[3];
    int k, t;
    r->org[0] = o.x; r->org[1] = o.y; r->org[2] = o.z;
    r->dir[0] = d.x; r->dir[1] = d.y; r->dir[2] = d.z;
    for (k = 0; k < 3; ++k) {
        if (!refl__isfinite(r->org[k]) || !refl__isfinite(r->dir[k])) return 0;
        ad[k] = fabsf(r->dir[k]);
    }
    r->kz = ad[0] >= ad[1] ? (ad[0] >= ad[2] ? 0 : 2) : (ad[1] >= ad[2] ? 1 : 2);
    if (ad[r->kz] == 0) return 0;
    r->kx = (r->kz + 1) % 3;
    r->ky = (r->kx + 1) % 3;
    /* Keep the winding (edge function signs) of the paper; no culling
       here, but it costs nothing. */
    if (r->dir[r->kz] < 0) { t = r->kx; r->kx = r->ky; r->ky = t; }
    /* A zero component gives an infinite inverse; the slab test skips
       the NaN that 0 * inf makes. Divisions round exactly, so doing them
       four at a time gives the same bits. */
#ifdef REFL__BVH_SSE2
    {
        float q[4], s[4];
        _mm_storeu_ps(q, _mm_div_ps(_mm_set1_ps(1.0f), _mm_setr_ps(r->dir[0], r->dir[1], r->dir[2], r->dir[r->kz])));
        _mm_storeu_ps(s, _mm_div_ps(_mm_setr_ps(r->dir[r->kx], r->dir[r->ky], 0.0f, 0.0f), _mm_set1_ps(r->dir[r->kz])));
        for (k = 0; k < 3; ++k) r->inv[k] = q[k];
        r->sz = q[3];
        r->sx = s[0];
        r->sy = s[1];
    }
#else
    for (k = 0; k < 3; ++k) r->inv[k] = 1.0f / r->dir[k];
    r->sx = r->dir[r->kx] / r->dir[r->kz];
    r->sy = r->dir[r->ky] / r->dir[r->kz];
    r->sz = 1.0f / r->dir[r->kz];
#endif
    for (k = 0; k < 3; ++k) r->near_lo[k] = !(r->inv[k] < 0);
    r->slack = 0.0f;
    return 1;
}

/* How far beyond the bound a box is still entered, in units of t: the
   watertight test computes t from the corners' coordinates relative to
   the origin, so it rounds with the farthest corner's distance, not with
   t, where a box's entry rounds by a few ulps of t: a ray starting 1e-5
   from a wall whose far corner is 25 away gets a t some percent short of
   the wall's box entry, and a bound just past that t culled the box.
   Boxes are culled against tmax + slack (and the best t so far plus
   slack), the triangles tested against tmax itself. The slack is 2^-16 of
   the ray's reach, the largest |t| at which it can be inside the root box
   (the box's farthest coordinate from the origin over the direction's
   largest component; no point of the box is farther along that axis):
   16 times the least power of two that lost no hit of 100,000 random rays
   and rays leaving the surfaces of each builtin scene (2^-21 lost some on
   hybrid; tests/reflect/test_bvh.c), and 128 ulps or more of any t within
   reach, so it covers the boxes' and triangles' rounding relative to t
   as well. A hit at a grazing angle can round further than any slack of
   the ray's alone covers. tmin gets none: a ray leaving a surface with
   tmin just past it would then enter every box that touches its origin
   (a fifth to a third more triangle tests a ray on the builtin scenes'
   camera rays and rays leaving their hits), so a hit the triangle test
   puts just past tmin, in a box whose exit rounds before tmin, can be
   missed. */
static void refl__bvh_ray_slack(const refl_bvh *bvh, refl__bvh_ray *r) {
    float far = 0.0f;
    int k;
    for (k = 0; k < 3; ++k) {
        far = REFL__MAX(far, fabsf(bvh->lo[k] - r->org[k]));
        far = REFL__MAX(far, fabsf(bvh->hi[k] - r->org[k]));
    }
    r->slack = far * fabsf(r->sz) * 1.52587890625e-05f; /* 2^-16 */
}

/* Entry distance of the ray into the node's box within [tmin, tmax], or
   -1 (as a miss flag via the return value). */
static int refl__bvh_slab(const refl__bvh_ray *r, const refl__bvh_node *n, float tmin, float tmax,
                          float *tentry) {
    int k;
    for (k = 0; k < 3; ++k) {
        float nearp = r->near_lo[k] ? n->lo[k] : n->hi[k];
        float farp = r->near_lo[k] ? n->hi[k] : n->lo[k];
        float t0 = (nearp - r->org[k]) * r->inv[k];
        float t1 = (farp - r->org[k]) * r->inv[k];
        /* Comparisons written so a NaN (ray inside a slab's plane) leaves
           the interval alone. */
        if (t0 > tmin) tmin = t0;
        /* Widen the exit by 2 gamma(3) (Ize 2013), so rounding in the slab
           test never culls a box the exact ray touches. */
        t1 *= 1.0000004f;
        if (t1 < tmax) tmax = t1;
    }
    *tentry = tmin;
    return tmin <= tmax;
}

/* Watertight ray/triangle test. Returns 1 with t, u, v when the ray hits
   with tmin < t <= tmax (a tie at tmax is for the caller: refl__bvh_leaf). */
static int refl__bvh_tri_hit(const refl__bvh_ray *r, const float v[9], float tmin, float tmax, float *t_out,
                             float *u_out, float *v_out) {
    int kx = r->kx, ky = r->ky, kz = r->kz;
    float ax, ay, bx, by, cx, cy, az, bz, cz, e0, e1, e2, det, tt;
    float a[3], b[3], c[3];
    int k;
    for (k = 0; k < 3; ++k) {
        a[k] = v[k] - r->org[k];
        b[k] = v[3 + k] - r->org[k];
        c[k] = v[6 + k] - r->org[k];
    }
    ax = a[kx] - r->sx * a[kz]; ay = a[ky] - r->sy * a[kz];
    bx = b[kx] - r->sx * b[kz]; by = b[ky] - r->sy * b[kz];
    cx = c[kx] - r->sx * c[kz]; cy = c[ky] - r->sy * c[kz];
    e0 = cx * by - cy * bx;
    e1 = ax * cy - ay * cx;
    e2 = bx * ay - by * ax;
    /* An exact zero may be a rounding artefact on a shared edge: decide it
       in double, where these products are exact. */
    if (e0 == 0.0f || e1 == 0.0f || e2 == 0.0f) {
        e0 = (float)((double)cx * by - (double)cy * bx);
        e1 = (float)((double)ax * cy - (double)ay * cx);
        e2 = (float)((double)bx * ay - (double)by * ax);
    }
    if ((e0 < 0 || e1 < 0 || e2 < 0) && (e0 > 0 || e1 > 0 || e2 > 0)) return 0;
    det = e0 + e1 + e2;
    if (det == 0.0f) return 0;
    az = r->sz * a[kz]; bz = r->sz * b[kz]; cz = r->sz * c[kz];
    tt = e0 * az + e1 * bz + e2 * cz;
    /* Either sign of det: back faces count. */
    {
        float inv = 1.0f / det;
        float t = tt * inv;
        if (!(t > tmin) || !(t <= tmax)) return 0;
        *t_out = t;
        *u_out = e1 * inv;
        *v_out = e2 * inv;
    }
    return 1;
}

/* A ray as the wide traversal and the four-triangle test need it: which
   of a node's box rows is the near and which the far plane on each axis,
   and with SSE2 the origin, inverse direction and shear in every lane. */
typedef struct refl__bvhw_ray {
    int near_row[3], far_row[3];
#ifdef REFL__BVH_SSE2
    __m128 org4[3], inv4[3], sx4, sy4, sz4;
#endif
} refl__bvhw_ray;

static void refl__bvhw_ray_setup(refl__bvhw_ray *w, const refl__bvh_ray *r) {
    int k;
    for (k = 0; k < 3; ++k) {
        w->near_row[k] = r->near_lo[k] ? k : 3 + k;
        w->far_row[k] = r->near_lo[k] ? 3 + k : k;
#ifdef REFL__BVH_SSE2
        w->org4[k] = _mm_set1_ps(r->org[k]);
        w->inv4[k] = _mm_set1_ps(r->inv[k]);
#endif
    }
#ifdef REFL__BVH_SSE2
    w->sx4 = _mm_set1_ps(r->sx);
    w->sy4 = _mm_set1_ps(r->sy);
    w->sz4 = _mm_set1_ps(r->sz);
#endif
}

/* refl__bvh_tri_hit on the first `lanes` triangles of block q: bit k of
   the result set when triangle k is hit, with t[k], u[k], v[k]. */
static int refl__bvh_tri4_hit_scalar(const refl__bvh_ray *r, const refl__bvh_tri4 *q, int lanes, float tmin,
                                     float tmax, float t[4], float u[4], float v[4]) {
    int lane, k, mask = 0;
    for (lane = 0; lane < lanes; ++lane) {
        float tri[9];
        for (k = 0; k < 9; ++k) tri[k] = q->v[k][lane];
        if (refl__bvh_tri_hit(r, tri, tmin, tmax, &t[lane], &u[lane], &v[lane])) mask |= 1 << lane;
    }
    return mask;
}

#ifdef REFL__BVH_SSE2
/* The same in SSE2, bit for bit: each lane does refl__bvh_tri_hit's
   operations in its order, and a lane with an edge function of exactly
   zero has all three redone in double as there. */
REFL__BVH_INLINE
static int refl__bvh_tri4_hit_sse2(const refl__bvh_ray *r, const refl__bvhw_ray *w, const refl__bvh_tri4 *q,
                                   int lanes, float tmin, float tmax, float t[4], float u[4], float v[4]) {
    const int kx = r->kx, ky = r->ky, kz = r->kz;
    const __m128 zero = _mm_setzero_ps();
    __m128 az = _mm_sub_ps(_mm_loadu_ps(q->v[kz]), w->org4[kz]);
    __m128 bz = _mm_sub_ps(_mm_loadu_ps(q->v[3 + kz]), w->org4[kz]);
    __m128 cz = _mm_sub_ps(_mm_loadu_ps(q->v[6 + kz]), w->org4[kz]);
    __m128 ax = _mm_sub_ps(_mm_sub_ps(_mm_loadu_ps(q->v[kx]), w->org4[kx]), _mm_mul_ps(w->sx4, az));
    __m128 ay = _mm_sub_ps(_mm_sub_ps(_mm_loadu_ps(q->v[ky]), w->org4[ky]), _mm_mul_ps(w->sy4, az));
    __m128 bx = _mm_sub_ps(_mm_sub_ps(_mm_loadu_ps(q->v[3 + kx]), w->org4[kx]), _mm_mul_ps(w->sx4, bz));
    __m128 by = _mm_sub_ps(_mm_sub_ps(_mm_loadu_ps(q->v[3 + ky]), w->org4[ky]), _mm_mul_ps(w->sy4, bz));
    __m128 cx = _mm_sub_ps(_mm_sub_ps(_mm_loadu_ps(q->v[6 + kx]), w->org4[kx]), _mm_mul_ps(w->sx4, cz));
    __m128 cy = _mm_sub_ps(_mm_sub_ps(_mm_loadu_ps(q->v[6 + ky]), w->org4[ky]), _mm_mul_ps(w->sy4, cz));
    __m128 e0 = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
    __m128 e1 = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
    __m128 e2 = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
    __m128 det, tt, inv, tv, ok;
    int valid = (1 << lanes) - 1, exact;
    exact = _mm_movemask_ps(_mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(e0, zero), _mm_cmpeq_ps(e1, zero)),
                                      _mm_cmpeq_ps(e2, zero))) & valid;
    if (exact) {
        float fax[4], fay[4], fbx[4], fby[4], fcx[4], fcy[4], f0[4], f1[4], f2[4];
        int lane;
        _mm_storeu_ps(fax, ax); _mm_storeu_ps(fay, ay);
        _mm_storeu_ps(fbx, bx); _mm_storeu_ps(fby, by);
        _mm_storeu_ps(fcx, cx); _mm_storeu_ps(fcy, cy);
        _mm_storeu_ps(f0, e0); _mm_storeu_ps(f1, e1); _mm_storeu_ps(f2, e2);
        for (lane = 0; lane < 4; ++lane)
            if (exact >> lane & 1) {
                f0[lane] = (float)((double)fcx[lane] * fby[lane] - (double)fcy[lane] * fbx[lane]);
                f1[lane] = (float)((double)fax[lane] * fcy[lane] - (double)fay[lane] * fcx[lane]);
                f2[lane] = (float)((double)fbx[lane] * fay[lane] - (double)fby[lane] * fax[lane]);
            }
        e0 = _mm_loadu_ps(f0);
        e1 = _mm_loadu_ps(f1);
        e2 = _mm_loadu_ps(f2);
    }
    /* rejected: edge functions of both signs, or det == 0 */
    ok = _mm_andnot_ps(
        _mm_and_ps(_mm_or_ps(_mm_or_ps(_mm_cmplt_ps(e0, zero), _mm_cmplt_ps(e1, zero)), _mm_cmplt_ps(e2, zero)),
                   _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(e0, zero), _mm_cmpgt_ps(e1, zero)), _mm_cmpgt_ps(e2, zero))),
        _mm_cmpneq_ps(det = _mm_add_ps(_mm_add_ps(e0, e1), e2), zero));
    if (!(_mm_movemask_ps(ok) & valid)) return 0;
    tt = _mm_add_ps(_mm_add_ps(_mm_mul_ps(e0, _mm_mul_ps(w->sz4, az)), _mm_mul_ps(e1, _mm_mul_ps(w->sz4, bz))),
                    _mm_mul_ps(e2, _mm_mul_ps(w->sz4, cz)));
    inv = _mm_div_ps(_mm_set1_ps(1.0f), det);
    tv = _mm_mul_ps(tt, inv);
    ok = _mm_and_ps(ok, _mm_and_ps(_mm_cmpgt_ps(tv, _mm_set1_ps(tmin)), _mm_cmple_ps(tv, _mm_set1_ps(tmax))));
    _mm_storeu_ps(t, tv);
    _mm_storeu_ps(u, _mm_mul_ps(e1, inv));
    _mm_storeu_ps(v, _mm_mul_ps(e2, inv));
    return _mm_movemask_ps(ok) & valid;
}
#endif

/* The closest hit so far. */
typedef struct refl__bvh_best {
    int found;
    float t, u, v;
    int32_t object, triangle;
    long long tests;              /* triangles tested: those of the leaves visited, not their spare lanes */
} refl__bvh_best;

/* Triangle tests counted for the frame's stats (stats.triangle_tests):
   a ray adds its count once, to a counter its thread owns (one cache line
   each, so threads share no line, and its owner's alone to write: a
   plain add, where a locked one per ray costs a measurable share of a
   ray), and a frame sums the counters before and after
   (refl__bvh_tests_counted). A thread claims a free counter at its first
   ray and frees it at its exit (a pthread key's destructor), the next
   owner adding on; past REFL__BVH_TEST_SLOTS live threads, or without
   pthreads, threads share the last counter with atomic adds. Sums of
   integers, so the same for any thread count; a frame rendered at the
   same time in another thread of the process counts into the same sum.
   Compilers without GCC's atomics and thread-local storage count
   nothing. */
#if defined(__GNUC__) || defined(__clang__)
#define REFL__BVH_TEST_SLOTS 64
typedef struct refl__bvh_test_slot {
    long long n;
    int owned;
    char pad[64 - sizeof(long long) - sizeof(int)];
} refl__bvh_test_slot;
static refl__bvh_test_slot refl__bvh_test_slots[REFL__BVH_TEST_SLOTS + 1]; /* the last: shared */
static __thread refl__bvh_test_slot *refl__bvh_test_mine;

#ifndef RAST_NO_THREADS
#include <pthread.h>
static pthread_key_t refl__bvh_test_key;
static pthread_once_t refl__bvh_test_once = PTHREAD_ONCE_INIT;
static int refl__bvh_test_key_made;

static void refl__bvh_test_release(void *slot) {
    __atomic_store_n(&((refl__bvh_test_slot *)slot)->owned, 0, __ATOMIC_RELEASE);
}

static void refl__bvh_test_make_key(void) {
    refl__bvh_test_key_made = pthread_key_create(&refl__bvh_test_key, refl__bvh_test_release) == 0;
}
#endif

static refl__bvh_test_slot *refl__bvh_test_claim(void) {
#ifndef RAST_NO_THREADS
    int k;
    pthread_once(&refl__bvh_test_once, refl__bvh_test_make_key);
    for (k = 0; refl__bvh_test_key_made && k < REFL__BVH_TEST_SLOTS; ++k) {
        int free_slot = 0;
        if (!__atomic_compare_exchange_n(&refl__bvh_test_slots[k].owned, &free_slot, 1, 0, __ATOMIC_ACQUIRE,
                                         __ATOMIC_RELAXED))
            continue;
        if (pthread_setspecific(refl__bvh_test_key, &refl__bvh_test_slots[k]) == 0) return &refl__bvh_test_slots[k];
        refl__bvh_test_release(&refl__bvh_test_slots[k]);
        break;
    }
#endif
    return &refl__bvh_test_slots[REFL__BVH_TEST_SLOTS];
}

static void refl__bvh_count_tests(long long n) {
    refl__bvh_test_slot *s = refl__bvh_test_mine;
    if (!s) s = refl__bvh_test_mine = refl__bvh_test_claim();
    if (s == &refl__bvh_test_slots[REFL__BVH_TEST_SLOTS]) __atomic_fetch_add(&s->n, n, __ATOMIC_RELAXED);
    else __atomic_store_n(&s->n, __atomic_load_n(&s->n, __ATOMIC_RELAXED) + n, __ATOMIC_RELAXED);
}

static long long refl__bvh_tests_counted(void) {
    long long sum = 0;
    int k;
    for (k = 0; k <= REFL__BVH_TEST_SLOTS; ++k) sum += __atomic_load_n(&refl__bvh_test_slots[k].n, __ATOMIC_RELAXED);
    return sum;
}
#else
static void refl__bvh_count_tests(long long n) { (void)n; }
static long long refl__bvh_tests_counted(void) { return 0; }
#endif

/* The bound boxes are culled against, the caller's tmax or the best hit's
   t: the ray's slack beyond it (refl__bvh_ray_slack), so a box
   holding a triangle whose t ties with, or by rounding beats, the bound is
   still entered, whichever tree and order the boxes come in. */
static float refl__bvh_cull_bound(const refl__bvh_ray *r, float tmax) { return tmax + r->slack; }

/* Tests a leaf's `count` triangles from block `first` (scalar: lane by
   lane) and keeps each hit that comes before the best so far in (t,
   object, triangle) order, narrowing *tmax to it: so the closest hit does
   not depend on the order leaves are visited in. Returns 1 when any_hit
   and a hit was found. */
REFL__BVH_INLINE
static int refl__bvh_leaf(const refl_bvh *bvh, const refl__bvh_ray *r, const refl__bvhw_ray *w, int first,
                          int count, float tmin, float *tmax, int any_hit, int scalar, refl__bvh_best *best) {
    const refl__bvh_tri4 *q;
    (void)w;
    (void)scalar;
    for (q = &bvh->blocks[first]; count > 0; ++q, count -= 4) {
        float t[4], u[4], v[4];
        int lanes = count < 4 ? count : 4, lane, mask;
        best->tests += lanes;
#ifdef REFL__BVH_SSE2
        mask = scalar ? refl__bvh_tri4_hit_scalar(r, q, lanes, tmin, *tmax, t, u, v)
                      : refl__bvh_tri4_hit_sse2(r, w, q, lanes, tmin, *tmax, t, u, v);
#else
        mask = refl__bvh_tri4_hit_scalar(r, q, lanes, tmin, *tmax, t, u, v);
#endif
        for (lane = 0; mask; ++lane, mask >>= 1) {
            if (!(mask & 1)) continue;
            /* the block's lanes were tested against *tmax before any of
               them narrowed it; at t == *tmax the caller's bound excludes
               it, and a tie with the best goes to the lower object, then
               triangle */
            if (!(t[lane] < *tmax) &&
                !(t[lane] == *tmax && best->found &&
                  (q->object[lane] < best->object ||
                   (q->object[lane] == best->object && q->triangle[lane] < best->triangle))))
                continue;
            best->found = 1;
            best->t = t[lane];
            best->u = u[lane];
            best->v = v[lane];
            best->object = q->object[lane];
            best->triangle = q->triangle[lane];
            *tmax = t[lane];
            if (any_hit) return 1;
        }
    }
    return 0;
}

/* The binary tree's traversal, which the tests compare the wide one with:
   nearer child first, farther one culled when a closer hit is known;
   triangles lane by lane. */
static int refl__bvh_trace_binary(const refl_bvh *bvh, const refl__bvh_ray *r, const refl__bvhw_ray *w, float tmin,
                                  float tmax, int any_hit, refl__bvh_best *best) {
    int stack[REFL__BVH_STACK];
    float stack_t[REFL__BVH_STACK]; /* entry distances, to skip boxes behind a closer hit */
    int sp = 0, node = 0;
    float tentry, tcull = refl__bvh_cull_bound(r, tmax);
    if (!refl__bvh_slab(r, &bvh->nodes[0], tmin, tcull, &tentry)) return 0;
    for (;;) {
        const refl__bvh_node *n = &bvh->nodes[node];
        if (n->count > 0) {
            if (refl__bvh_leaf(bvh, r, w, n->index, n->count, tmin, &tmax, any_hit, 1, best)) return 1;
            if (best->found) tcull = refl__bvh_cull_bound(r, tmax);
        } else {
            float t0, t1;
            int c0 = n->index, c1 = n->index + 1;
            int h0 = refl__bvh_slab(r, &bvh->nodes[c0], tmin, tcull, &t0);
            int h1 = refl__bvh_slab(r, &bvh->nodes[c1], tmin, tcull, &t1);
            if (h0 && h1) {
                /* Nearer first, so the far one is often culled by tmax;
                   the build's depth limit keeps the stack within bounds. */
                if (t1 < t0) { int s = c0; c0 = c1; c1 = s; }
                REFL_ASSERT(sp < REFL__BVH_STACK);
                stack_t[sp] = t0 < t1 ? t1 : t0;
                stack[sp++] = c1;
                node = c0;
                continue;
            }
            if (h0) { node = c0; continue; }
            if (h1) { node = c1; continue; }
        }
        do {
            if (sp == 0) return best->found;
            --sp;
        } while (stack_t[sp] > tcull);
        node = stack[sp];
    }
}

/* refl__bvh_slab on each of the node's boxes: bit k of the result
   set when the ray enters box k within [tmin, tmax], t[k] its entry. */
static int refl__bvhw_boxes_scalar(const refl__bvh_ray *r, const refl__bvhw_ray *w, const refl__bvhw_node *n,
                                   float tmin, float tmax, float t[REFL__BVH_W]) {
    int lane, k, mask = 0;
    for (lane = 0; lane < REFL__BVH_W; ++lane) {
        float lo = tmin, hi = tmax;
        for (k = 0; k < 3; ++k) {
            float t0 = (n->box[w->near_row[k]][lane] - r->org[k]) * r->inv[k];
            float t1 = (n->box[w->far_row[k]][lane] - r->org[k]) * r->inv[k];
            if (t0 > lo) lo = t0;
            t1 *= 1.0000004f;
            if (t1 < hi) hi = t1;
        }
        t[lane] = lo;
        mask |= (lo <= hi) << lane;
    }
    return mask;
}

#ifdef REFL__BVH_SSE2
/* The same in SSE2, bit for bit: max_ps(a, b) is a > b ? a : b and
   min_ps(a, b) a < b ? a : b, NaN included, as the scalar comparisons.
   tmin and tmax come broadcast, as the traversal keeps them. */
static int refl__bvhw_boxes_sse2(const refl__bvhw_ray *w, const refl__bvhw_node *n, __m128 tmin, __m128 tmax,
                                 float t[REFL__BVH_W]) {
    const __m128 widen = _mm_set1_ps(1.0000004f);
    const float *nx = n->box[w->near_row[0]], *ny = n->box[w->near_row[1]], *nz = n->box[w->near_row[2]];
    const float *fx = n->box[w->far_row[0]], *fy = n->box[w->far_row[1]], *fz = n->box[w->far_row[2]];
    int h, mask = 0;
    for (h = 0; h < REFL__BVH_W; h += 4) {
        __m128 lo = tmin, hi = tmax;
        lo = _mm_max_ps(_mm_mul_ps(_mm_sub_ps(_mm_load_ps(nx + h), w->org4[0]), w->inv4[0]), lo);
        lo = _mm_max_ps(_mm_mul_ps(_mm_sub_ps(_mm_load_ps(ny + h), w->org4[1]), w->inv4[1]), lo);
        lo = _mm_max_ps(_mm_mul_ps(_mm_sub_ps(_mm_load_ps(nz + h), w->org4[2]), w->inv4[2]), lo);
        hi = _mm_min_ps(_mm_mul_ps(_mm_mul_ps(_mm_sub_ps(_mm_load_ps(fx + h), w->org4[0]), w->inv4[0]), widen), hi);
        hi = _mm_min_ps(_mm_mul_ps(_mm_mul_ps(_mm_sub_ps(_mm_load_ps(fy + h), w->org4[1]), w->inv4[1]), widen), hi);
        hi = _mm_min_ps(_mm_mul_ps(_mm_mul_ps(_mm_sub_ps(_mm_load_ps(fz + h), w->org4[2]), w->inv4[2]), widen), hi);
        _mm_storeu_ps(t + h, lo);
        mask |= _mm_movemask_ps(_mm_cmple_ps(lo, hi)) << h;
    }
    return mask;
}
#endif

/* Asks for a stacked child's node or first triangle block ahead of its
   turn, so its cache misses overlap the work before it. */
static void refl__bvh_prefetch(const refl_bvh *bvh, int32_t child, int32_t count) {
#ifdef REFL__BVH_SSE2
    const char *p = count ? (const char *)&bvh->blocks[child] : (const char *)&bvh->wide[child];
    size_t size = count ? sizeof(refl__bvh_tri4) : sizeof(refl__bvhw_node), at;
    for (at = 0; at < size; at += 64) _mm_prefetch(p + at, _MM_HINT_T0);
#else
    (void)bvh;
    (void)child;
    (void)count;
#endif
}

#ifdef REFL__BVH_AVX2
/* The same with AVX2, all eight boxes at once: the same operations per
   lane, so the same bits (_CMP_LE_OS is cmpleps's predicate). */
typedef char refl__bvhw_avx2_takes_eight[REFL__BVH_W == 8 ? 1 : -1];
__attribute__((target("avx2"))) static int refl__bvhw_boxes_avx2(const refl__bvh_ray *r, const refl__bvhw_ray *w,
                                                                const refl__bvhw_node *n, float tmin, float tmax,
                                                                float t[REFL__BVH_W]) {
    const __m256 widen = _mm256_set1_ps(1.0000004f);
    __m256 lo = _mm256_set1_ps(tmin), hi = _mm256_set1_ps(tmax);
    int k;
    for (k = 0; k < 3; ++k) {
        __m256 o = _mm256_broadcast_ss(&r->org[k]), inv = _mm256_broadcast_ss(&r->inv[k]);
        lo = _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->box[w->near_row[k]]), o), inv), lo);
        hi = _mm256_min_ps(
            _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n->box[w->far_row[k]]), o), inv), widen), hi);
    }
    _mm256_storeu_ps(t, lo);
    return _mm256_movemask_ps(_mm256_cmp_ps(lo, hi, _CMP_LE_OS));
}
#endif

typedef struct refl__bvhw_entry {
    int32_t child, count;         /* as in refl__bvhw_node */
    float t;                      /* entry distance: skipped once a hit is closer */
} refl__bvhw_entry;

/* The lowest lane set in a nonzero mask. */
static int refl__bvh_first_lane(unsigned mask) {
#if defined(__GNUC__) || defined(__clang__)
    return __builtin_ctz(mask);
#else
    int k = 0;
    while (!(mask >> k & 1)) ++k;
    return k;
#endif
}

/* How a traversal tests a node's boxes. */
enum { REFL__BVH_BOXES_SCALAR, REFL__BVH_BOXES_SSE2, REFL__BVH_BOXES_AVX2 };

/* The wide tree's traversal: of the children a node's ray enters, the
   nearest next and the others stacked farthest first (one or two entered,
   the common cases, without sorting). `boxes` picks the box test (a
   constant in each caller below); triangles go lane by lane with the
   scalar box test, four at a time otherwise. */
REFL__BVH_INLINE
static int refl__bvhw_trace_body(const refl_bvh *bvh, const refl__bvh_ray *r, const refl__bvhw_ray *w, float tmin,
                                 float tmax, int any_hit, int boxes, refl__bvh_best *best) {
    refl__bvhw_entry stack[REFL__BVHW_STACK];
    int sp = 0;
    int32_t child = 0, count = 0;
    float tcull = refl__bvh_cull_bound(r, tmax); /* of the caller's bound, then of the best hit's */
#ifdef REFL__BVH_SSE2
    const __m128 tmin4 = _mm_set1_ps(tmin);
    __m128 tcull4 = _mm_set1_ps(tcull);
#endif
    for (;;) {
        while (count == 0) {
            const refl__bvhw_node *n = &bvh->wide[child];
            float t[REFL__BVH_W];
            int mask, k0, k1;
#ifdef REFL__BVH_AVX2
            if (boxes == REFL__BVH_BOXES_AVX2)
                mask = refl__bvhw_boxes_avx2(r, w, n, tmin, tcull, t);
            else
#endif
#ifdef REFL__BVH_SSE2
            if (boxes == REFL__BVH_BOXES_SSE2)
                mask = refl__bvhw_boxes_sse2(w, n, tmin4, tcull4, t);
            else
#endif
                mask = refl__bvhw_boxes_scalar(r, w, n, tmin, tcull, t);
            if (!mask) goto pop;
            k0 = refl__bvh_first_lane((unsigned)mask);
            mask &= mask - 1;
            if (!mask) {
                child = n->child[k0];
                count = n->count[k0];
                continue;
            }
            k1 = refl__bvh_first_lane((unsigned)mask);
            mask &= mask - 1;
            if (!mask) {
                /* two: the nearer next, the farther stacked */
                if (t[k1] < t[k0]) { int s = k0; k0 = k1; k1 = s; }
                REFL_ASSERT(sp < REFL__BVHW_STACK);
                stack[sp].child = n->child[k1];
                stack[sp].count = n->count[k1];
                stack[sp].t = t[k1];
                refl__bvh_prefetch(bvh, stack[sp].child, stack[sp].count);
                ++sp;
                child = n->child[k0];
                count = n->count[k0];
                continue;
            }
            {
                /* three or more: sorted farthest first (equal entries: lane order) */
                int lanes[REFL__BVH_W], m = 0, k, j;
                mask |= 1 << k0 | 1 << k1;
                for (k = 0; k < REFL__BVH_W; ++k)
                    if (mask >> k & 1) {
                        for (j = m++; j > 0 && t[lanes[j - 1]] < t[k]; --j) lanes[j] = lanes[j - 1];
                        lanes[j] = k;
                    }
                REFL_ASSERT(sp + m - 1 <= REFL__BVHW_STACK);
                for (j = 0; j < m - 1; ++j) {
                    stack[sp].child = n->child[lanes[j]];
                    stack[sp].count = n->count[lanes[j]];
                    stack[sp].t = t[lanes[j]];
                    refl__bvh_prefetch(bvh, stack[sp].child, stack[sp].count);
                    ++sp;
                }
                child = n->child[lanes[m - 1]];
                count = n->count[lanes[m - 1]];
            }
        }
        if (refl__bvh_leaf(bvh, r, w, child, count, tmin, &tmax, any_hit, boxes == REFL__BVH_BOXES_SCALAR, best))
            return 1;
        if (best->found) {
            tcull = refl__bvh_cull_bound(r, tmax);
#ifdef REFL__BVH_SSE2
            tcull4 = _mm_set1_ps(tcull);
#endif
        }
    pop:
        do {
            if (sp == 0) return best->found;
            --sp;
        } while (stack[sp].t > tcull);
        child = stack[sp].child;
        count = stack[sp].count;
    }
}

static int refl__bvhw_trace(const refl_bvh *bvh, const refl__bvh_ray *r, const refl__bvhw_ray *w, float tmin,
                            float tmax, int any_hit, int scalar, refl__bvh_best *best) {
    return refl__bvhw_trace_body(bvh, r, w, tmin, tmax, any_hit,
                                 scalar ? REFL__BVH_BOXES_SCALAR : REFL__BVH_BOXES_SSE2, best);
}

#ifdef REFL__BVH_AVX2
__attribute__((target("avx2"))) static int refl__bvhw_trace_avx2(const refl_bvh *bvh, const refl__bvh_ray *r,
                                                                const refl__bvhw_ray *w, float tmin, float tmax,
                                                                int any_hit, refl__bvh_best *best) {
    return refl__bvhw_trace_body(bvh, r, w, tmin, tmax, any_hit, REFL__BVH_BOXES_AVX2, best);
}

/* Whether this CPU (and its OS) runs AVX2. */
static int refl__bvh_has_avx2(void) { return __builtin_cpu_supports("avx2"); }
#endif

/* Which traversal a trace takes: the wide tree (AVX2 box tests where the
   CPU has them, else SSE2 where built), the wide tree lane by lane, the
   binary tree (tests only), or the wide tree without AVX2 (tests only). */
enum { REFL__BVH_WIDE = 0, REFL__BVH_WIDE_SCALAR, REFL__BVH_BINARY, REFL__BVH_WIDE_SSE2 };

/* Closest hit, or the first one found when any_hit. */
static int refl__bvh_trace(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax,
                           int any_hit, int path, refl_hit *hit) {
    refl__bvh_ray r;
    refl__bvhw_ray w;
    refl__bvh_best best;
    int found;
    if (!bvh || bvh->wide_count == 0) return 0;
    if (!(tmin < tmax) || tmin != tmin) return 0;
    if (!refl__bvh_ray_setup(&r, origin, dir)) return 0;
    refl__bvh_ray_slack(bvh, &r);
    refl__bvhw_ray_setup(&w, &r);
    memset(&best, 0, sizeof best);
    if (path == REFL__BVH_BINARY) {
        if (!bvh->nodes) return 0;
        found = refl__bvh_trace_binary(bvh, &r, &w, tmin, tmax, any_hit, &best);
    } else {
#ifdef REFL__BVH_AVX2
        if (path == REFL__BVH_WIDE && refl__bvh_has_avx2())
            found = refl__bvhw_trace_avx2(bvh, &r, &w, tmin, tmax, any_hit, &best);
        else
#endif
            found = refl__bvhw_trace(bvh, &r, &w, tmin, tmax, any_hit, path == REFL__BVH_WIDE_SCALAR, &best);
    }
    refl__bvh_count_tests(best.tests);
    if (found && hit) {
        hit->t = best.t;
        hit->object = best.object;
        hit->triangle = best.triangle;
        hit->u = best.u;
        hit->v = best.v;
    }
    return found;
}

REFL_API int refl_bvh_intersect(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax,
                                refl_hit *hit) {
    return refl__bvh_trace(bvh, origin, dir, tmin, tmax, 0, REFL__BVH_WIDE, hit);
}

REFL_API int refl_bvh_occluded(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax) {
    return refl__bvh_trace(bvh, origin, dir, tmin, tmax, 1, REFL__BVH_WIDE, NULL);
}

REFL_API int refl_ray_triangle(refl_vec3 origin, refl_vec3 dir, const float tri[9], float tmin, float tmax,
                               refl_hit *hit) {
    refl__bvh_ray r;
    return hit && refl__tri_ok(tri) && refl__bvh_ray_setup(&r, origin, dir) &&
           refl__bvh_tri_hit(&r, tri, tmin, tmax, &hit->t, &hit->u, &hit->v);
}

/* ---- packets of four rays ----------------------------------------------------- */

typedef struct refl__bvhp_entry {
    int32_t child, count;
    unsigned rays;                /* the rays that entered its box */
    float t[4];                   /* their entry distances */
} refl__bvhp_entry;

/* Four rays down the wide tree together: a node is fetched and its
   children ordered once for all the rays that entered it; each ray's
   boxes are tested by the single-ray test, each leaf's triangles by
   refl__bvh_leaf for each ray that entered it, and each ray culls with
   its own best hit. So each ray's closest hit is the single-ray trace's,
   bit for bit: the least (t, object, triangle) in the boxes it enters,
   whatever order they come in. Children go nearest first by the least
   entry of their rays. Returns the mask of the rays that hit. */
REFL__BVH_INLINE
static unsigned refl__bvhp_trace_body(const refl_bvh *bvh, const refl__bvh_ray *r, const refl__bvhw_ray *w,
                                      const float *tmin, float *tmax, unsigned active, int any_hit, int boxes,
                                      refl__bvh_best *best) {
    refl__bvhp_entry stack[REFL__BVHW_STACK];
    float tcull[4];               /* each ray's, as in refl__bvhw_trace_body */
    unsigned rays = active, found = 0;
    int sp = 0, k;
    int32_t child = 0, count = 0;
    for (k = 0; k < 4; ++k) tcull[k] = active >> k & 1 ? refl__bvh_cull_bound(&r[k], tmax[k]) : 0.0f;
    for (;;) {
        while (count == 0) {
            const refl__bvhw_node *n = &bvh->wide[child];
            float t[4][REFL__BVH_W], key[REFL__BVH_W];
            unsigned lanes = 0, rays_of[REFL__BVH_W], left;
            int m[4], lane, order[REFL__BVH_W], c = 0, j;
            for (k = 0; k < 4; ++k) {
                m[k] = 0;
                if (!(rays >> k & 1)) continue;
#ifdef REFL__BVH_AVX2
                if (boxes == REFL__BVH_BOXES_AVX2)
                    m[k] = refl__bvhw_boxes_avx2(&r[k], &w[k], n, tmin[k], tcull[k], t[k]);
                else
#endif
#ifdef REFL__BVH_SSE2
                if (boxes == REFL__BVH_BOXES_SSE2)
                    m[k] = refl__bvhw_boxes_sse2(&w[k], n, _mm_set1_ps(tmin[k]), _mm_set1_ps(tcull[k]), t[k]);
                else
#endif
                    m[k] = refl__bvhw_boxes_scalar(&r[k], &w[k], n, tmin[k], tcull[k], t[k]);
                lanes |= (unsigned)m[k];
            }
            if (!lanes) goto pop;
            for (left = lanes; left; left &= left - 1) {
                lane = refl__bvh_first_lane(left);
                rays_of[lane] = 0;
                key[lane] = INFINITY;
                for (k = 0; k < 4; ++k)
                    if (m[k] >> lane & 1) {
                        rays_of[lane] |= 1u << k;
                        if (t[k][lane] < key[lane]) key[lane] = t[k][lane];
                    }
                /* farthest first (equal entries: lane order) */
                for (j = c++; j > 0 && key[order[j - 1]] < key[lane]; --j) order[j] = order[j - 1];
                order[j] = lane;
            }
            REFL_ASSERT(sp + c - 1 <= REFL__BVHW_STACK);
            for (j = 0; j < c - 1; ++j) {
                refl__bvhp_entry *e = &stack[sp++];
                lane = order[j];
                e->child = n->child[lane];
                e->count = n->count[lane];
                e->rays = rays_of[lane];
                for (k = 0; k < 4; ++k) e->t[k] = t[k][lane];
                refl__bvh_prefetch(bvh, e->child, e->count);
            }
            lane = order[c - 1];
            child = n->child[lane];
            count = n->count[lane];
            rays = rays_of[lane];
        }
        for (k = 0; k < 4; ++k) {
            if (!(rays >> k & 1)) continue;
            if (refl__bvh_leaf(bvh, &r[k], &w[k], child, count, tmin[k], &tmax[k], any_hit,
                               boxes == REFL__BVH_BOXES_SCALAR, &best[k])) {
                active &= ~(1u << k); /* any_hit: answered */
                continue;
            }
            if (best[k].found) tcull[k] = refl__bvh_cull_bound(&r[k], tmax[k]);
        }
        if (!active) break;
    pop:
        do {
            if (sp == 0) goto out;
            --sp;
            rays = stack[sp].rays & active;
            for (k = 0; k < 4; ++k)
                if ((rays >> k & 1) && stack[sp].t[k] > tcull[k]) rays &= ~(1u << k);
        } while (!rays);
        child = stack[sp].child;
        count = stack[sp].count;
    }
out:
    for (k = 0; k < 4; ++k) found |= (unsigned)(best[k].found != 0) << k;
    return found;
}

static unsigned refl__bvhp_trace(const refl_bvh *bvh, const refl__bvh_ray *r, const refl__bvhw_ray *w,
                                 const float *tmin, float *tmax, unsigned active, int any_hit, int scalar,
                                 refl__bvh_best *best) {
    return refl__bvhp_trace_body(bvh, r, w, tmin, tmax, active, any_hit,
                                 scalar ? REFL__BVH_BOXES_SCALAR : REFL__BVH_BOXES_SSE2, best);
}

#ifdef REFL__BVH_AVX2
__attribute__((target("avx2"))) static unsigned refl__bvhp_trace_avx2(const refl_bvh *bvh, const refl__bvh_ray *r,
                                                                     const refl__bvhw_ray *w, const float *tmin,
                                                                     float *tmax, unsigned active, int any_hit,
                                                                     refl__bvh_best *best) {
    return refl__bvhp_trace_body(bvh, r, w, tmin, tmax, active, any_hit, REFL__BVH_BOXES_AVX2, best);
}
#endif

/* Four rays through one of the wide tree's traversals (path: REFL__BVH_WIDE,
   REFL__BVH_WIDE_SCALAR or REFL__BVH_WIDE_SSE2). */
static unsigned refl__bvh_trace4(const refl_bvh *bvh, const refl_vec3 origin[4], const refl_vec3 dir[4],
                                 const float tmin_in[4], const float tmax_in[4], int any_hit, int path,
                                 refl_hit hit[4]) {
    refl__bvh_ray r[4];
    refl__bvhw_ray w[4];
    refl__bvh_best best[4];
    float tmin[4], tmax[4];
    unsigned active = 0, found;
    int k;
    if (!bvh || bvh->wide_count == 0) return 0;
    for (k = 0; k < 4; ++k) {
        tmin[k] = tmin_in[k];
        tmax[k] = tmax_in[k];
        memset(&best[k], 0, sizeof best[k]);
        if (!(tmin[k] < tmax[k]) || tmin[k] != tmin[k]) continue;
        if (!refl__bvh_ray_setup(&r[k], origin[k], dir[k])) continue;
        refl__bvh_ray_slack(bvh, &r[k]);
        refl__bvhw_ray_setup(&w[k], &r[k]);
        active |= 1u << k;
    }
    if (!active) return 0;
#ifdef REFL__BVH_AVX2
    if (path == REFL__BVH_WIDE && refl__bvh_has_avx2())
        found = refl__bvhp_trace_avx2(bvh, r, w, tmin, tmax, active, any_hit, best);
    else
#endif
        found = refl__bvhp_trace(bvh, r, w, tmin, tmax, active, any_hit, path == REFL__BVH_WIDE_SCALAR, best);
    for (k = 0; k < 4; ++k) {
        if (active >> k & 1) refl__bvh_count_tests(best[k].tests);
        if (hit && (found >> k & 1)) {
            hit[k].t = best[k].t;
            hit[k].object = best[k].object;
            hit[k].triangle = best[k].triangle;
            hit[k].u = best[k].u;
            hit[k].v = best[k].v;
        }
    }
    return found;
}

REFL_API unsigned refl_bvh_intersect4(const refl_bvh *bvh, const refl_vec3 origin[4], const refl_vec3 dir[4],
                                      const float tmin[4], const float tmax[4], refl_hit hit[4]) {
    return refl__bvh_trace4(bvh, origin, dir, tmin, tmax, 0, REFL__BVH_WIDE, hit);
}

REFL_API unsigned refl_bvh_occluded4(const refl_bvh *bvh, const refl_vec3 origin[4], const refl_vec3 dir[4],
                                     const float tmin[4], const float tmax[4]) {
    return refl__bvh_trace4(bvh, origin, dir, tmin, tmax, 1, REFL__BVH_WIDE, NULL);
}

/* The surface at hit h on mesh m placed by `model` (normals by
   `normal_m`): its triangle's corners in the world, the barycentric
   weights, the point (interpolated: more exact than origin + t dir), the
   geometric normal and the interpolated shading normal (the geometric one
   where that vanishes). The ray tracer and SBC's higher orders share it. */
static void refl__hit_surface(const refl_mesh *m, const refl_mat4 *model, const refl_mat4 *normal_m, const refl_hit *h,
                              refl__hit_geom *g) {
    const uint32_t *tri = m->indices + 3 * (size_t)h->triangle;
    refl_vec3 n = refl_v3(0.0f, 0.0f, 0.0f);
    int k;
    g->w[0] = 1.0f - h->u - h->v;
    g->w[1] = h->u;
    g->w[2] = h->v;
    for (k = 0; k < 3; ++k) {
        const float *pp = m->positions + 3 * (size_t)tri[k], *nn = m->normals + 3 * (size_t)tri[k];
        g->v[k] = refl_mat4_point(*model, refl_v3(pp[0], pp[1], pp[2]));
        n = refl_v3_add(n, refl_v3_scale(refl_v3(nn[0], nn[1], nn[2]), g->w[k]));
    }
    g->p = refl_v3_add(refl_v3_add(refl_v3_scale(g->v[0], g->w[0]), refl_v3_scale(g->v[1], g->w[1])),
                       refl_v3_scale(g->v[2], g->w[2]));
    g->ng = refl_v3_normalize(refl_v3_cross(refl_v3_sub(g->v[1], g->v[0]), refl_v3_sub(g->v[2], g->v[0])));
    g->ns = refl_v3_normalize(refl_mat4_dir(*normal_m, n));
    if (refl_v3_dot(g->ns, g->ns) == 0.0f) g->ns = g->ng;
}
