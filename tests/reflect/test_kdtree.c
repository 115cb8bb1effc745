/* The kd-tree over points (paper 000, section 4): the tree's invariants
   (a permutation of the input, tight boxes, children partitioning their
   parent, the eight-way median split, the leaf criteria, the statistics)
   on random, flat, clustered and duplicate points; queries against brute
   force; shuffled leaves; determinism; the depth on teapot samples; bad
   input and allocation failure at every allocation. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

static float rnd(refl_rng *r, float lo, float hi) { return lo + (hi - lo) * refl_rng_float(r); }

/* n points uniform in [-1, 1]^3 scaled by (sx, sy, sz). */
static float *random_points(int n, uint64_t seed, float sx, float sy, float sz) {
    refl_rng r = refl_rng_seed(seed);
    float *p = (float *)malloc(sizeof(float) * 3 * (size_t)(n ? n : 1));
    int i;
    cr_assert_not_null(p);
    for (i = 0; i < n; ++i) {
        p[3 * i] = sx * rnd(&r, -1, 1);
        p[3 * i + 1] = sy * rnd(&r, -1, 1);
        p[3 * i + 2] = sz * rnd(&r, -1, 1);
    }
    return p;
}

static refl_kdtree *build(const float *p, int n, int leaf_points, float min_size) {
    refl_kdtree_desc d;
    refl_kdtree *t = NULL;
    memset(&d, 0, sizeof d);
    d.leaf_points = leaf_points;
    d.min_size = min_size;
    cr_assert_eq(refl_kdtree_build(p, n, &d, &t), REFL_OK);
    cr_assert_not_null(t);
    return t;
}

/* Largest side of the tight box of tree points [first, first + count),
   checking the node's box is exactly that box. */
static float check_box(const refl_kdtree *t, const refl_kdtree_node *nd) {
    float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0}, size = 0;
    int i, k;
    for (i = 0; i < nd->count; ++i)
        for (k = 0; k < 3; ++k) {
            float v = t->positions[3 * (nd->first + i) + k];
            if (i == 0 || v < lo[k]) lo[k] = v;
            if (i == 0 || v > hi[k]) hi[k] = v;
        }
    for (k = 0; k < 3; ++k) {
        cr_assert(nd->lo[k] == lo[k] && nd->hi[k] == hi[k], "node box axis %d: [%g, %g], points [%g, %g]", k,
                  nd->lo[k], nd->hi[k], lo[k], hi[k]);
        size = fmaxf(size, hi[k] - lo[k]);
    }
    return size;
}

/* max of axis over tree points [b, e) <= min over [e, f) */
static void check_separated(const refl_kdtree *t, int b, int e, int f, int axis) {
    float mx = -INFINITY, mn = INFINITY;
    int i;
    for (i = b; i < e; ++i) mx = fmaxf(mx, t->positions[3 * i + axis]);
    for (i = e; i < f; ++i) mn = fminf(mn, t->positions[3 * i + axis]);
    cr_assert(mx <= mn, "median split along %d: lower part up to %g, upper from %g", axis, mx, mn);
}

/* Every invariant of a tree built from p[0, n) with these parameters. */
static void check_tree(const refl_kdtree *t, const float *p, int n, int leaf_points, float min_size) {
    int i, leaves = 0, maxd = 0;
    double depth_sum = 0;
    char *seen = (char *)calloc((size_t)n + 1, 1);
    int *parents = (int *)calloc((size_t)t->node_count, sizeof(int));
    if (leaf_points == 0) leaf_points = 1000;
    cr_assert(seen && parents);
    cr_assert_eq(t->point_count, n);
    cr_assert(t->node_count >= 1 && t->nodes && t->positions && t->order);

    /* a permutation, and the caller's points */
    for (i = 0; i < n; ++i) {
        cr_assert_lt(t->order[i], (uint32_t)n);
        cr_assert_eq(seen[t->order[i]], 0, "caller point %u twice", t->order[i]);
        seen[t->order[i]] = 1;
        cr_assert(memcmp(t->positions + 3 * i, p + 3 * (size_t)t->order[i], 3 * sizeof(float)) == 0);
    }

    cr_assert(t->nodes[0].first == 0 && t->nodes[0].count == n && t->nodes[0].depth == 0);
    for (i = 0; i < t->node_count; ++i) {
        const refl_kdtree_node *nd = &t->nodes[i];
        float size;
        cr_assert(nd->first >= 0 && nd->count >= 0 && nd->first + nd->count <= n);
        size = check_box(t, nd);
        if (nd->child_count == 0) {
            cr_assert_eq(nd->child, -1);
            cr_assert(nd->count <= leaf_points || size < min_size || size == 0,
                      "leaf of %d points, size %g", nd->count, size);
            ++leaves;
            depth_sum += nd->depth;
            if (nd->depth > maxd) maxd = nd->depth;
        } else {
            int c, at = nd->first, b[9], s, axis, step, group = 0;
            cr_assert(nd->count > leaf_points && size >= min_size && size > 0, "inner node of %d points, size %g",
                      nd->count, size);
            cr_assert(nd->child_count >= 2 && nd->child_count <= 8);
            cr_assert(nd->child > i && nd->child + nd->child_count <= t->node_count);
            for (c = 0; c < nd->child_count; ++c) {
                const refl_kdtree_node *ch = &t->nodes[nd->child + c];
                cr_assert_eq(ch->first, at, "children must be consecutive ranges");
                cr_assert_gt(ch->count, 0, "empty children are left out");
                cr_assert_eq(ch->depth, nd->depth + 1);
                at += ch->count;
                parents[nd->child + c] += 1;
            }
            cr_assert_eq(at, nd->first + nd->count, "children cover the parent");

            /* The eight parts: x median over the node, y medians over the
               halves, z medians over the quarters; the children are the
               non-empty ones, in order, each separated from its sibling
               part along the axis of that round. */
            b[0] = nd->first;
            b[8] = nd->first + nd->count;
            for (axis = 0, step = 8; axis < 3; ++axis, step >>= 1)
                for (s = 0; s < 8; s += step) {
                    b[s + step / 2] = b[s] + (b[s + step] - b[s]) / 2;
                    check_separated(t, b[s], b[s + step / 2], b[s + step], axis);
                }
            for (s = 0; s < 8; ++s) {
                if (b[s + 1] == b[s]) continue;
                cr_assert_lt(group, nd->child_count);
                cr_assert(t->nodes[nd->child + group].first == b[s] &&
                          t->nodes[nd->child + group].count == b[s + 1] - b[s]);
                ++group;
            }
            cr_assert_eq(group, nd->child_count);
        }
    }
    /* a tree: every node but the root is exactly one node's child */
    cr_assert_eq(parents[0], 0);
    for (i = 1; i < t->node_count; ++i) cr_assert_eq(parents[i], 1, "node %d has %d parents", i, parents[i]);

    cr_assert_eq(t->leaf_count, leaves);
    cr_assert_eq(t->max_depth, maxd);
    cr_assert(fabs(t->average_leaf_depth - depth_sum / leaves) < 1e-9);
    cr_assert(fabs(t->average_leaf_points - (double)n / leaves) < 1e-9);
    free(seen);
    free(parents);
}

Test(refl_kdtree, invariants_on_random_flat_and_clustered_points) {
    static const struct { int n, leaf_points; float min_size, sx, sy, sz; } cases[] = {
        {20000, 0, 0, 1, 1, 1},        /* the defaults */
        {20000, 50, 0, 1, 1, 1},
        {3000, 1, 0, 1, 1, 1},         /* down to single points: empty children */
        {20000, 8, 0.4f, 1, 1, 1},     /* the size criterion stops first */
        {20000, 30, 0, 10, 0.01f, 1},  /* anisotropic */
        {20000, 30, 0, 1, 1, 0},       /* flat: z all equal */
        {9001, 1000, 0, 1, 1, 1},
    };
    int c;
    for (c = 0; c < (int)(sizeof cases / sizeof cases[0]); ++c) {
        float *p = random_points(cases[c].n, 100 + (uint64_t)c, cases[c].sx, cases[c].sy, cases[c].sz);
        refl_kdtree *t = build(p, cases[c].n, cases[c].leaf_points, cases[c].min_size);
        check_tree(t, p, cases[c].n, cases[c].leaf_points, cases[c].min_size);
        cr_assert_gt(t->node_count, 1);
        if (cases[c].min_size > 0) { /* it did stop some nodes with many points */
            int i, big = 0;
            for (i = 0; i < t->node_count; ++i) big += t->nodes[i].child_count == 0 && t->nodes[i].count > cases[c].leaf_points;
            cr_assert_gt(big, 0);
        }
        refl_kdtree_destroy(t);
        free(p);
    }
    /* clustered: a few tight blobs (many points sharing coordinates) */
    {
        int n = 12000, i, k;
        float *p = random_points(n, 7, 1, 1, 1);
        refl_kdtree *t;
        for (i = 0; i < n; ++i)
            for (k = 0; k < 3; ++k) p[3 * i + k] = roundf(p[3 * i + k] * 2) * 5 + p[3 * i + k] * 1e-3f * (i % 3);
        t = build(p, n, 20, 0);
        check_tree(t, p, n, 20, 0);
        refl_kdtree_destroy(t);
        free(p);
    }
}

/* ---- queries -------------------------------------------------------------- */

typedef struct query_ctx {
    float lo[3], hi[3];
    int nodes_seen;                /* leaves seen */
    int last_first;
    int *leaf_hit;                 /* per node: times handed to leaf */
    char *found;                   /* per caller point: found in the query box */
    const refl_kdtree *tree;
} query_ctx;

static int overlaps(const float alo[3], const float ahi[3], const float blo[3], const float bhi[3]) {
    int k;
    for (k = 0; k < 3; ++k)
        if (ahi[k] < blo[k] || bhi[k] < alo[k]) return 0;
    return 1;
}

static int inside(const float *p, const float lo[3], const float hi[3]) {
    return p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1] && p[2] >= lo[2] && p[2] <= hi[2];
}

static int box_overlaps(void *user, const float lo[3], const float hi[3]) {
    query_ctx *q = (query_ctx *)user;
    return overlaps(lo, hi, q->lo, q->hi);
}

static void collect(void *user, const refl_kdtree *tree, const refl_kdtree_node *leaf) {
    query_ctx *q = (query_ctx *)user;
    int i;
    cr_assert_eq(tree, q->tree);
    cr_assert_eq(leaf->child_count, 0);
    /* depth first, children in order: leaves come in point order */
    cr_assert_gt(leaf->first, q->last_first);
    q->last_first = leaf->first;
    q->leaf_hit[leaf - tree->nodes] += 1;
    q->nodes_seen += 1;
    for (i = leaf->first; i < leaf->first + leaf->count; ++i)
        if (inside(tree->positions + 3 * i, q->lo, q->hi)) q->found[tree->order[i]] += 1;
}

Test(refl_kdtree, query_matches_brute_force) {
    int n = 20000, i, qn;
    float *p = random_points(n, 5, 1, 1, 1);
    refl_kdtree *t = build(p, n, 64, 0);
    refl_rng r = refl_rng_seed(9);
    query_ctx q;
    memset(&q, 0, sizeof q);
    q.tree = t;
    q.leaf_hit = (int *)calloc((size_t)t->node_count, sizeof(int));
    q.found = (char *)calloc((size_t)n, 1);
    for (qn = 0; qn < 60; ++qn) {
        long long tests, expected_tests = 1;
        int k, expected_leaves = 0;
        for (k = 0; k < 3; ++k) {
            float c = rnd(&r, -1.2f, 1.2f), h = rnd(&r, 0, qn % 10 == 0 ? 1.5f : 0.3f);
            q.lo[k] = c - h;
            q.hi[k] = c + h;
        }
        if (qn == 1) /* a box that is a point: exactly one tree point */
            for (k = 0; k < 3; ++k) q.lo[k] = q.hi[k] = p[3 * 1234 + k];
        memset(q.leaf_hit, 0, sizeof(int) * (size_t)t->node_count);
        memset(q.found, 0, (size_t)n);
        q.nodes_seen = 0;
        q.last_first = -1;
        tests = refl_kdtree_query(t, box_overlaps, collect, &q);

        /* parents' boxes hold their children's, so the accepted leaves are
           exactly those overlapping the query; a box is tested when its
           parent was accepted */
        for (i = 0; i < t->node_count; ++i) {
            const refl_kdtree_node *nd = &t->nodes[i];
            int ov = overlaps(nd->lo, nd->hi, q.lo, q.hi);
            if (nd->child_count == 0) {
                cr_assert_eq(q.leaf_hit[i], ov, "query %d leaf %d: visited %d, overlaps %d", qn, i, q.leaf_hit[i], ov);
                expected_leaves += ov;
            } else if (ov) {
                expected_tests += nd->child_count;
            }
        }
        cr_assert_eq(q.nodes_seen, expected_leaves);
        cr_assert_eq(tests, expected_tests);
        for (i = 0; i < n; ++i)
            cr_assert_eq(q.found[i], inside(p + 3 * i, q.lo, q.hi), "query %d point %d", qn, i);
        if (qn == 1) cr_assert_geq(q.nodes_seen, 1);
    }

    /* no box test: every leaf, no tests counted */
    memset(q.leaf_hit, 0, sizeof(int) * (size_t)t->node_count);
    q.nodes_seen = 0;
    q.last_first = -1;
    q.lo[0] = q.lo[1] = q.lo[2] = -INFINITY;
    q.hi[0] = q.hi[1] = q.hi[2] = INFINITY;
    cr_assert_eq(refl_kdtree_query(t, NULL, collect, &q), 0);
    cr_assert_eq(q.nodes_seen, t->leaf_count);
    /* rejecting everything: one test, no leaves */
    q.lo[0] = q.hi[0] = 100;
    q.nodes_seen = 0;
    cr_assert_eq(refl_kdtree_query(t, box_overlaps, collect, &q), 1);
    cr_assert_eq(q.nodes_seen, 0);
    cr_assert_eq(refl_kdtree_query(NULL, box_overlaps, collect, &q), 0);
    cr_assert_gt(refl_kdtree_query(t, box_overlaps, NULL, &q), 0);

    free(q.leaf_hit);
    free(q.found);
    refl_kdtree_destroy(t);
    free(p);
}

/* Level of detail: any prefix of a leaf is spread over the whole leaf, not
   bunched in one corner as the median selection would leave it. */
Test(refl_kdtree, leaf_prefixes_are_even_subsamples) {
    int n = 40000, i, k, checked = 0;
    float *p = random_points(n, 11, 1, 1, 1);
    refl_kdtree *t = build(p, n, 1000, 0);
    for (i = 0; i < t->node_count; ++i) {
        const refl_kdtree_node *nd = &t->nodes[i];
        int m = nd->count / 8, j;
        if (nd->child_count || nd->count < 200) continue;
        for (k = 0; k < 3; ++k) {
            double side = nd->hi[k] - nd->lo[k], mean = 0, lo = INFINITY, hi = -INFINITY;
            for (j = 0; j < m; ++j) {
                double v = t->positions[3 * (nd->first + j) + k];
                mean += v / m;
                lo = fmin(lo, v);
                hi = fmax(hi, v);
            }
            /* uniform points: the mean of m is within a few sd (side / sqrt(12 m)) of the centre */
            cr_assert(fabs(mean - 0.5 * (nd->lo[k] + nd->hi[k])) < 0.25 * side, "leaf %d axis %d", i, k);
            cr_assert(hi - lo > 0.7 * side, "leaf %d axis %d: first %d points span %g of %g", i, k, m, hi - lo, side);
        }
        ++checked;
    }
    cr_assert_gt(checked, 8);
    refl_kdtree_destroy(t);
    free(p);
}

Test(refl_kdtree, deterministic) {
    int n = 30000;
    float *p = random_points(n, 21, 2, 1, 3);
    refl_kdtree *a = build(p, n, 100, 0), *b = build(p, n, 100, 0);
    cr_assert(a->point_count == b->point_count && a->node_count == b->node_count && a->leaf_count == b->leaf_count &&
              a->max_depth == b->max_depth && a->average_leaf_depth == b->average_leaf_depth &&
              a->average_leaf_points == b->average_leaf_points);
    cr_assert(memcmp(a->positions, b->positions, sizeof(float) * 3 * (size_t)n) == 0);
    cr_assert(memcmp(a->order, b->order, sizeof(uint32_t) * (size_t)n) == 0);
    cr_assert(memcmp(a->nodes, b->nodes, sizeof(refl_kdtree_node) * (size_t)a->node_count) == 0);
    refl_kdtree_destroy(a);
    refl_kdtree_destroy(b);
    free(p);
}

/* ---- degenerate input ----------------------------------------------------- */

static void count_leaf(void *user, const refl_kdtree *tree, const refl_kdtree_node *leaf) {
    (void)tree;
    *(int *)user += 1 + leaf->count;
}

Test(refl_kdtree, duplicates_empty_and_single) {
    int n = 10000, i, k, calls = 0;
    float *p = (float *)malloc(sizeof(float) * 3 * (size_t)n);
    refl_kdtree *t;
    for (i = 0; i < n; ++i) {
        p[3 * i] = 1.5f; p[3 * i + 1] = -2; p[3 * i + 2] = 0.25f;
    }
    /* identical points: no split separates them, one leaf */
    t = build(p, n, 10, 0);
    check_tree(t, p, n, 10, 0);
    cr_assert(t->node_count == 1 && t->leaf_count == 1 && t->max_depth == 0);
    refl_kdtree_destroy(t);

    /* two places, half the points each: they part, then stop */
    for (i = 0; i < n; i += 2) p[3 * i] = -7;
    t = build(p, n, 10, 0);
    check_tree(t, p, n, 10, 0);
    for (i = 0; i < t->node_count; ++i)
        if (t->nodes[i].child_count == 0) cr_assert(t->nodes[i].hi[0] == t->nodes[i].lo[0]);
    cr_assert_leq(t->max_depth, 2);
    refl_kdtree_destroy(t);

    /* half duplicates, half random */
    {
        float *q = random_points(n, 3, 1, 1, 1);
        for (i = 0; i < n / 2; ++i)
            for (k = 0; k < 3; ++k) q[3 * i + k] = 0.5f;
        t = build(q, n, 16, 0);
        check_tree(t, q, n, 16, 0);
        refl_kdtree_destroy(t);
        free(q);
    }

    /* no points: one empty leaf with a zero box */
    t = build(NULL, 0, 0, 0);
    check_tree(t, p, 0, 0, 0);
    cr_assert(t->node_count == 1 && t->leaf_count == 1 && t->nodes[0].count == 0 && t->nodes[0].child == -1);
    for (k = 0; k < 3; ++k) cr_assert(t->nodes[0].lo[k] == 0 && t->nodes[0].hi[k] == 0);
    cr_assert(t->average_leaf_points == 0 && t->average_leaf_depth == 0);
    cr_assert_eq(refl_kdtree_query(t, NULL, count_leaf, &calls), 0);
    cr_assert_eq(calls, 1);
    refl_kdtree_destroy(t);

    /* one point, also with leaf_points 1 */
    p[0] = 3; p[1] = 4; p[2] = 5;
    t = build(p, 1, 1, 0);
    check_tree(t, p, 1, 1, 0);
    cr_assert(t->node_count == 1 && t->nodes[0].lo[0] == 3 && t->nodes[0].hi[2] == 5 && t->order[0] == 0);
    calls = 0;
    cr_assert_eq(refl_kdtree_query(t, NULL, count_leaf, &calls), 0);
    cr_assert_eq(calls, 2);
    refl_kdtree_destroy(t);
    free(p);
}

Test(refl_kdtree, bad_input) {
    float p[6] = {0, 0, 0, 1, 1, 1};
    refl_kdtree *t = (refl_kdtree *)1;
    refl_kdtree_desc d;
    int k;
    memset(&d, 0, sizeof d);
    cr_assert_eq(refl_kdtree_build(p, 2, NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_kdtree_build(p, -1, NULL, &t), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(t);
    t = (refl_kdtree *)1;
    cr_assert_eq(refl_kdtree_build(NULL, 2, NULL, &t), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(t);
    for (k = 0; k < 6; ++k) {
        float q[6];
        memcpy(q, p, sizeof q);
        q[k] = k % 2 ? INFINITY : NAN;
        t = (refl_kdtree *)1;
        cr_assert_eq(refl_kdtree_build(q, 2, NULL, &t), REFL_ERROR_INVALID_ARGUMENT, "bad coordinate %d", k);
        cr_assert_null(t);
    }
    d.leaf_points = -1;
    cr_assert_eq(refl_kdtree_build(p, 2, &d, &t), REFL_ERROR_INVALID_ARGUMENT);
    d.leaf_points = 0;
    d.min_size = -1;
    cr_assert_eq(refl_kdtree_build(p, 2, &d, &t), REFL_ERROR_INVALID_ARGUMENT);
    d.min_size = NAN;
    cr_assert_eq(refl_kdtree_build(p, 2, &d, &t), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(t);
    refl_kdtree_destroy(NULL);
    /* NULL positions are fine without points */
    cr_assert_eq(refl_kdtree_build(NULL, 0, NULL, &t), REFL_OK);
    refl_kdtree_destroy(t);
}

/* Table 1's shape on a real point set: teapot samples (the paper's Bunny0
   has 147k points); the eight-way split makes the depth about log8 of the
   number of leaves. */
Test(refl_kdtree, teapot_samples_statistics) {
    refl_mesh *m = NULL;
    refl_points *pts = NULL;
    refl_kdtree *t;
    double area = 0, expect;
    int i;
    cr_assert_eq(refl_mesh_teapot(0, NULL, &m), REFL_OK);
    for (i = 0; i < m->triangle_count; ++i) {
        const float *a = m->positions + 3 * m->indices[3 * i], *b = m->positions + 3 * m->indices[3 * i + 1],
                    *c = m->positions + 3 * m->indices[3 * i + 2];
        refl_vec3 e1 = refl_v3(b[0] - a[0], b[1] - a[1], b[2] - a[2]), e2 = refl_v3(c[0] - a[0], c[1] - a[1], c[2] - a[2]);
        area += 0.5 * refl_v3_length(refl_v3_cross(e1, e2));
    }
    cr_assert_eq(refl_mesh_sample_points(m, NULL, (float)(147000 / area), 1, NULL, &pts), REFL_OK);
    cr_assert(pts->count > 140000 && pts->count < 154000, "%d points", pts->count);
    t = build(pts->positions, pts->count, 1000, 0);
    check_tree(t, pts->positions, pts->count, 1000, 0);
    expect = log((double)pts->count / t->average_leaf_points) / log(8.0);
    cr_assert(fabs(t->average_leaf_depth - expect) < 1.5, "average depth %g, log8(n / per leaf) %g",
              t->average_leaf_depth, expect);
    cr_assert(t->average_leaf_points <= 1000 && t->average_leaf_points > 1000 / 8 / 2, "%g per leaf",
              t->average_leaf_points);
    refl_kdtree_destroy(t);
    refl_points_destroy(pts);
    refl_mesh_destroy(m);
}

Test(refl_kdtree, allocation_failure_at_every_allocation) {
    /* 9000 points, 1000 per leaf: two levels of splits, enough nodes to
       outgrow the first guess, so the growth is failed too */
    int n = 9000;
    float *p = random_points(n, 77, 1, 1, 1);
    tu_alloc_counter c;
    refl_kdtree_desc d;
    refl_kdtree *t = NULL;
    long attempts, i;
    memset(&c, 0, sizeof c);
    memset(&d, 0, sizeof d);
    d.leaf_points = 1000;
    d.allocator = tu_refl_counting(&c);
    cr_assert_eq(refl_kdtree_build(p, n, &d, &t), REFL_OK);
    check_tree(t, p, n, 1000, 0);
    cr_assert_eq(t->max_depth, 2);
    refl_kdtree_destroy(t);
    attempts = c.attempts;
    cr_assert_geq(attempts, 2);
    cr_assert_eq(c.allocs, c.frees);
    for (i = 1; i <= attempts; ++i) {
        memset(&c, 0, sizeof c);
        c.fail_at = i;
        t = (refl_kdtree *)1;
        cr_assert_eq(refl_kdtree_build(p, n, &d, &t), REFL_ERROR_OUT_OF_MEMORY, "failing allocation %ld", i);
        cr_assert_null(t);
        cr_assert_eq(c.failed, 1);
        cr_assert_eq(c.allocs, c.frees, "leak when allocation %ld fails", i);
    }
    free(p);
}
