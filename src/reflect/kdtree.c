/* kd-tree over points: paper 000, section 4 (see api.h). The hybrid
   method's scene subdivision for the diffuse point samples.
   Build: iterative, one task per node on an explicit stack. An inner node
   splits its points in eight with three rounds of median selection (x over
   the node, y over each half, z over each quarter): quickselect with a
   sampled pivot and branch-free partitions, falling back to heapsort when
   it stalls, so the build is O(n log n) and deterministic (1M points in
   about 0.15 s on one core). The points move as 16-byte records (position
   and caller index) and are written out at the end.
   Leaves are shuffled (Fisher-Yates from the leaf's first index) so every
   prefix is an even subsample. Query: explicit stack, children in order. */
#include "internal.h"

#define REFL__KDT_DEFAULT_LEAF 1000
/* Every split leaves at most ceil(n / 8) points per child, so a tree over
   INT_MAX points is 11 levels deep; the cap is a safety net only. */
#define REFL__KDT_MAX_DEPTH 48
#define REFL__KDT_STACK (8 * REFL__KDT_MAX_DEPTH + 8)
#define REFL__KDT_SAMPLE 9

typedef struct refl__kdt_rec {
    float p[3];
    uint32_t index;               /* the caller's index */
} refl__kdt_rec;

typedef struct refl__kdt_task { int node, depth; } refl__kdt_task;

/* ---- median selection ------------------------------------------------------- */

static void refl__kdt_swap(refl__kdt_rec *a, refl__kdt_rec *b) {
    refl__kdt_rec t = *a;
    *a = *b;
    *b = t;
}

static void refl__kdt_sift(refl__kdt_rec *a, int root, int n, int axis) {
    for (;;) {
        int c = 2 * root + 1;
        if (c >= n) return;
        if (c + 1 < n && a[c + 1].p[axis] > a[c].p[axis]) ++c;
        if (!(a[c].p[axis] > a[root].p[axis])) return;
        refl__kdt_swap(&a[c], &a[root]);
        root = c;
    }
}

/* The fallback when quickselect stalls: O(n log n) whatever the input. */
static void refl__kdt_heapsort(refl__kdt_rec *a, int n, int axis) {
    int i;
    for (i = n / 2 - 1; i >= 0; --i) refl__kdt_sift(a, i, n, axis);
    for (i = n - 1; i > 0; --i) {
        refl__kdt_swap(&a[0], &a[i]);
        refl__kdt_sift(a, 0, i, axis);
    }
}

/* Reorders a[0, n) so that a[k] holds the value a sort along axis would put
   there, nothing after it is smaller and nothing before it larger (C++'s
   nth_element). Pivot: drawn from a few keys at deterministic
   pseudo-random places (fixed places meet patterns in structured input).
   Branch-free Lomuto partitions (random keys mispredict a branching one
   at every other element): the keys below the pivot to the front; when
   there are none, the pivot is the least key and the keys equal to it go
   to the front instead, so runs of equal keys end the search rather than
   stall it. */
static void refl__kdt_select(refl__kdt_rec *a, int n, int k, int axis) {
    int lo = 0, hi = n - 1, budget = 8, m;
    refl_rng rng = refl_rng_seed((uint64_t)n * 0x9E3779B97F4A7C15ull + (uint64_t)k);
    for (m = n; m > 1; m >>= 1) budget += 2;
    while (lo < hi) {
        float x;
        int i, s = lo;
        if (--budget < 0) {
            refl__kdt_heapsort(a + lo, hi - lo + 1, axis);
            return;
        }
        {
            /* pivot: of a few keys drawn at deterministic pseudo-random
               places, the one whose rank among them matches k's */
            float sample[REFL__KDT_SAMPLE];
            int count = hi - lo + 1 < 64 ? 3 : REFL__KDT_SAMPLE, j;
            for (i = 0; i < count; ++i) {
                float v = a[lo + (int)(((uint64_t)refl_rng_u32(&rng) * (uint64_t)(hi - lo + 1)) >> 32)].p[axis];
                for (j = i; j > 0 && sample[j - 1] > v; --j) sample[j] = sample[j - 1];
                sample[j] = v;
            }
            x = sample[(int)((int64_t)(k - lo) * count / (hi - lo + 1))];
        }
        /* [lo, s) < x <= [s, i): swapping a[i] with a[s] keeps that either way */
        for (i = lo; i <= hi; ++i) {
            refl__kdt_rec r = a[i];
            a[i] = a[s];
            a[s] = r;
            s += r.p[axis] < x;
        }
        if (k < s) {
            hi = s - 1;
            continue;
        }
        if (s > lo) {
            lo = s;
            continue;
        }
        /* x is the least key left: [lo, m) == x < [m, i), m > lo */
        m = s;
        for (i = s; i <= hi; ++i) {
            refl__kdt_rec r = a[i];
            a[i] = a[m];
            a[m] = r;
            m += r.p[axis] == x;
        }
        if (k < m) return;
        lo = m;
    }
}

/* ---- build ------------------------------------------------------------------ */

static void refl__kdt_free_tree(refl_kdtree *t) {
    refl_allocator a = t->allocator;
    refl__free(&a, t->positions);
    refl__free(&a, t->order);
    refl__free(&a, t->nodes);
    refl__free(&a, t);
}

/* Appends n nodes; their index, or -1 when out of memory. */
static int refl__kdt_push_nodes(refl_kdtree *t, int *capacity, int n) {
    int first = t->node_count;
    if (first + n > *capacity) {
        int cap = (int)REFL__MAX(REFL__MIN(2LL * *capacity, (long long)INT_MAX), (long long)first + n);
        refl_kdtree_node *nodes = (refl_kdtree_node *)refl__alloc(&t->allocator, sizeof *nodes * (size_t)cap);
        if (!nodes) return -1;
        memcpy(nodes, t->nodes, sizeof *nodes * (size_t)first);
        refl__free(&t->allocator, t->nodes);
        t->nodes = nodes;
        *capacity = cap;
    }
    t->node_count += n;
    return first;
}

/* A node's box, and whether it can be split: a leaf when small enough
   (either criterion of the paper), or when its points all coincide, which
   no split separates. */
static int refl__kdt_bound(refl_kdtree_node *node, const refl__kdt_rec *r, int leaf_points, float min_size) {
    int i, k;
    float size = 0;
    if (node->count == 0) {
        for (k = 0; k < 3; ++k) node->lo[k] = node->hi[k] = 0;
        return 0;
    }
    for (k = 0; k < 3; ++k) node->lo[k] = node->hi[k] = r[node->first].p[k];
    for (i = node->first + 1; i < node->first + node->count; ++i)
        for (k = 0; k < 3; ++k) {
            float v = r[i].p[k];
            if (v < node->lo[k]) node->lo[k] = v;
            if (v > node->hi[k]) node->hi[k] = v;
        }
    for (k = 0; k < 3; ++k) size = REFL__MAX(size, node->hi[k] - node->lo[k]);
    if (node->count <= leaf_points || size < min_size || !(size > 0)) return 0;
    return 1;
}

/* Fisher-Yates, seeded from the leaf's first index: the same on every
   machine, and different leaves are shuffled differently. */
static void refl__kdt_shuffle(refl__kdt_rec *r, int n, uint64_t seed) {
    refl_rng rng = refl_rng_seed(seed * 0x9E3779B97F4A7C15ull + 1);
    int i;
    for (i = n - 1; i > 0; --i) {
        int j = (int)(((uint64_t)refl_rng_u32(&rng) * (uint64_t)(i + 1)) >> 32);
        refl__kdt_swap(&r[i], &r[j]);
    }
}

/* Splits [first, first + n) at medians: x over it, y over each half, z over
   each quarter. bounds[0..8] are the eight ranges' boundaries. */
static void refl__kdt_split8(refl__kdt_rec *r, int first, int n, int bounds[9]) {
    int axis, step, s;
    bounds[0] = first;
    bounds[8] = first + n;
    for (axis = 0, step = 8; axis < 3; ++axis, step >>= 1)
        for (s = 0; s < 8; s += step) {
            int b = bounds[s], e = bounds[s + step], m = (e - b) / 2;
            if (e - b > 1) refl__kdt_select(r + b, e - b, m, axis);
            bounds[s + step / 2] = b + m;
        }
}

REFL_API refl_result refl_kdtree_build(const float *positions, int count, const refl_kdtree_desc *desc,
                                       refl_kdtree **out_tree) {
    refl_allocator alloc = refl__allocator(desc ? &desc->allocator : NULL);
    refl_kdtree *t;
    refl__kdt_rec *rec;
    refl__kdt_task stack[REFL__KDT_STACK];
    int leaf_points = desc && desc->leaf_points ? desc->leaf_points : REFL__KDT_DEFAULT_LEAF;
    float min_size = desc ? desc->min_size : 0.0f;
    int capacity, sp = 0, i, k;
    size_t j;
    double depth_sum = 0;

    if (out_tree) *out_tree = NULL;
    if (!out_tree || count < 0 || (!positions && count > 0) || leaf_points < 0 || !(min_size >= 0))
        return REFL_ERROR_INVALID_ARGUMENT;
    for (j = 0; j < 3 * (size_t)count; ++j)
        if (!refl__isfinite(positions[j])) return REFL_ERROR_INVALID_ARGUMENT;

    t = (refl_kdtree *)refl__calloc(&alloc, 1, sizeof *t);
    if (!t) return REFL_ERROR_OUT_OF_MEMORY;
    t->allocator = alloc;
    t->point_count = count;
    /* Eight nodes per leaf_points points: usually enough; it grows when not. */
    capacity = 1 + (int)REFL__MIN(8LL * (count / ((long long)leaf_points + 1)), (long long)INT_MAX / 2);
    t->positions = (float *)refl__calloc(&alloc, (size_t)count, 3 * sizeof(float));
    t->order = (uint32_t *)refl__calloc(&alloc, (size_t)count, sizeof(uint32_t));
    t->nodes = (refl_kdtree_node *)refl__calloc(&alloc, (size_t)capacity, sizeof(refl_kdtree_node));
    rec = (refl__kdt_rec *)refl__calloc(&alloc, (size_t)count, sizeof *rec);
    if (!t->positions || !t->order || !t->nodes || !rec) {
        refl__free(&alloc, rec);
        refl__kdt_free_tree(t);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < count; ++i) {
        for (k = 0; k < 3; ++k) rec[i].p[k] = positions[3 * (size_t)i + k];
        rec[i].index = (uint32_t)i;
    }

    t->node_count = 1;
    t->nodes[0].first = 0;
    t->nodes[0].count = count;
    t->nodes[0].depth = 0;
    stack[sp].node = 0; stack[sp].depth = 0;
    ++sp;
    while (sp > 0) {
        refl__kdt_task task = stack[--sp];
        refl_kdtree_node *node = &t->nodes[task.node];
        int bounds[9], children = 0, c, s;
        node->child = -1;
        node->child_count = 0;
        node->depth = task.depth;
        if (!refl__kdt_bound(node, rec, leaf_points, min_size) || task.depth >= REFL__KDT_MAX_DEPTH) {
            refl__kdt_shuffle(rec + node->first, node->count, (uint64_t)node->first);
            t->leaf_count += 1;
            t->max_depth = REFL__MAX(t->max_depth, task.depth);
            depth_sum += task.depth;
            continue;
        }
        refl__kdt_split8(rec, node->first, node->count, bounds);
        for (s = 0; s < 8; ++s) children += bounds[s + 1] > bounds[s];
        c = refl__kdt_push_nodes(t, &capacity, children);
        if (c < 0) {
            refl__free(&alloc, rec);
            refl__kdt_free_tree(t);
            return REFL_ERROR_OUT_OF_MEMORY;
        }
        node = &t->nodes[task.node]; /* the push may have moved it */
        node->child = c;
        node->child_count = children;
        for (s = 0; s < 8; ++s) {
            if (bounds[s + 1] == bounds[s]) continue;
            t->nodes[c].first = bounds[s];
            t->nodes[c].count = bounds[s + 1] - bounds[s];
            ++c;
        }
        /* reversed, so the children are built in order */
        for (s = children - 1; s >= 0; --s) {
            REFL_ASSERT(sp < REFL__KDT_STACK);
            stack[sp].node = node->child + s;
            stack[sp].depth = task.depth + 1;
            ++sp;
        }
    }

    for (i = 0; i < count; ++i) {
        for (k = 0; k < 3; ++k) t->positions[3 * (size_t)i + k] = rec[i].p[k];
        t->order[i] = rec[i].index;
    }
    refl__free(&alloc, rec);
    t->average_leaf_depth = depth_sum / t->leaf_count;
    t->average_leaf_points = (double)count / t->leaf_count;
    *out_tree = t;
    return REFL_OK;
}

REFL_API void refl_kdtree_destroy(refl_kdtree *tree) {
    if (tree) refl__kdt_free_tree(tree);
}

/* ---- query ------------------------------------------------------------------ */

REFL_API long long refl_kdtree_query(const refl_kdtree *tree, refl_kdtree_box_fn box_test, refl_kdtree_leaf_fn leaf,
                                     void *user) {
    int stack[REFL__KDT_STACK];
    int sp = 0;
    long long tests = 0;
    if (!tree || !tree->nodes || tree->node_count <= 0) return 0;
    stack[sp++] = 0;
    while (sp > 0) {
        const refl_kdtree_node *node = &tree->nodes[stack[--sp]];
        int c;
        if (box_test) {
            ++tests;
            if (!box_test(user, node->lo, node->hi)) continue;
        }
        if (node->child_count == 0) {
            if (leaf) leaf(user, tree, node);
            continue;
        }
        for (c = node->child_count - 1; c >= 0; --c) {
            REFL_ASSERT(sp < REFL__KDT_STACK);
            stack[sp++] = node->child + c;
        }
    }
    return tests;
}
