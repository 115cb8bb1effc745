/* reflect.h meshes: creation and its errors, allocation failure at every
   allocation (no leak), computed normals, bounds, subdivision (surface,
   edge bound, area, no T-junctions, attributes, determinism) and
   area-uniform point sampling (count, uniformity, determinism, points on
   their triangles). Every mesh is built here by hand. */
#include <criterion/criterion.h>

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../reflect.h"

/* ---- a counting allocator that can fail the k-th allocation ---------------- */

typedef struct counting {
    long calls, live, fail_at; /* fail_at: 1-based; 0 never */
} counting;

static void *counting_alloc(size_t size, void *user) {
    counting *c = (counting *)user;
    if (++c->calls == c->fail_at) return NULL;
    ++c->live;
    return malloc(size);
}

static void counting_free(void *ptr, void *user) {
    counting *c = (counting *)user;
    if (ptr) --c->live;
    free(ptr);
}

static refl_allocator counting_allocator(counting *c) {
    refl_allocator a;
    a.alloc = counting_alloc;
    a.free = counting_free;
    a.user = c;
    return a;
}

/* ---- hand-built meshes ------------------------------------------------------ */

typedef struct hmesh {
    float p[64 * 3];
    uint32_t t[128 * 3];
    int nv, nt;
} hmesh;

/* Flips triangles whose normal points towards the centroid (convex solids). */
static void orient_outward(hmesh *h) {
    double c[3] = {0, 0, 0};
    int i, k;
    for (i = 0; i < h->nv; ++i)
        for (k = 0; k < 3; ++k) c[k] += h->p[3 * i + k] / h->nv;
    for (i = 0; i < h->nt; ++i) {
        uint32_t *t = h->t + 3 * i;
        const float *a = h->p + 3 * t[0], *b = h->p + 3 * t[1], *d = h->p + 3 * t[2];
        double e1[3], e2[3], n[3], m[3], dot = 0;
        for (k = 0; k < 3; ++k) {
            e1[k] = b[k] - a[k];
            e2[k] = d[k] - a[k];
            m[k] = (a[k] + b[k] + d[k]) / 3.0 - c[k];
        }
        n[0] = e1[1] * e2[2] - e1[2] * e2[1];
        n[1] = e1[2] * e2[0] - e1[0] * e2[2];
        n[2] = e1[0] * e2[1] - e1[1] * e2[0];
        for (k = 0; k < 3; ++k) dot += n[k] * m[k];
        if (dot < 0) {
            uint32_t s = t[1];
            t[1] = t[2];
            t[2] = s;
        }
    }
}

static void h_vertex(hmesh *h, double x, double y, double z) {
    h->p[3 * h->nv] = (float)x;
    h->p[3 * h->nv + 1] = (float)y;
    h->p[3 * h->nv + 2] = (float)z;
    ++h->nv;
}

static void h_tri(hmesh *h, uint32_t a, uint32_t b, uint32_t c) {
    h->t[3 * h->nt] = a;
    h->t[3 * h->nt + 1] = b;
    h->t[3 * h->nt + 2] = c;
    ++h->nt;
}

static hmesh octahedron(double r) {
    hmesh h;
    memset(&h, 0, sizeof h);
    h_vertex(&h, r, 0, 0); h_vertex(&h, -r, 0, 0);
    h_vertex(&h, 0, r, 0); h_vertex(&h, 0, -r, 0);
    h_vertex(&h, 0, 0, r); h_vertex(&h, 0, 0, -r);
    h_tri(&h, 0, 2, 4); h_tri(&h, 2, 1, 4); h_tri(&h, 1, 3, 4); h_tri(&h, 3, 0, 4);
    h_tri(&h, 2, 0, 5); h_tri(&h, 1, 2, 5); h_tri(&h, 3, 1, 5); h_tri(&h, 0, 3, 5);
    orient_outward(&h);
    return h;
}

static hmesh tetrahedron(void) {
    hmesh h;
    memset(&h, 0, sizeof h);
    h_vertex(&h, 1, 1, 1); h_vertex(&h, 1, -1, -1); h_vertex(&h, -1, 1, -1); h_vertex(&h, -1, -1, 1);
    h_tri(&h, 0, 1, 2); h_tri(&h, 0, 1, 3); h_tri(&h, 0, 2, 3); h_tri(&h, 1, 2, 3);
    orient_outward(&h);
    return h;
}

/* The unit cube [0,1]^3: 8 shared corners, 12 triangles. */
static hmesh cube(void) {
    static const int q[6][4] = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    hmesh h;
    int i;
    memset(&h, 0, sizeof h);
    for (i = 0; i < 8; ++i) h_vertex(&h, i & 1, (i >> 1) & 1, (i >> 2) & 1);
    for (i = 0; i < 6; ++i) {
        h_tri(&h, (uint32_t)q[i][0], (uint32_t)q[i][1], (uint32_t)q[i][2]);
        h_tri(&h, (uint32_t)q[i][0], (uint32_t)q[i][2], (uint32_t)q[i][3]);
    }
    orient_outward(&h);
    return h;
}

/* An n x n grid of quads on y = 0 over [0, size]^2, facing +y. */
static hmesh grid(int n, double size) {
    hmesh h;
    int i, j;
    memset(&h, 0, sizeof h);
    for (j = 0; j <= n; ++j)
        for (i = 0; i <= n; ++i) h_vertex(&h, size * i / n, 0, size * j / n);
    for (j = 0; j < n; ++j)
        for (i = 0; i < n; ++i) {
            uint32_t a = (uint32_t)(j * (n + 1) + i), b = a + 1, c = a + (uint32_t)(n + 1), d = c + 1;
            h_tri(&h, a, c, b); /* (x,z) -> (x,z+1) -> (x+1,z): +y by the right hand */
            h_tri(&h, b, c, d);
        }
    return h;
}

static refl_mesh *make(const hmesh *h, const float *normals) {
    refl_mesh_desc d;
    refl_mesh *m = NULL;
    memset(&d, 0, sizeof d);
    d.positions = h->p;
    d.normals = normals;
    d.indices = h->t;
    d.vertex_count = h->nv;
    d.index_count = 3 * h->nt;
    cr_assert_eq(refl_mesh_create(&d, &m), REFL_OK);
    cr_assert_not_null(m);
    return m;
}

/* ---- geometry helpers (double) -------------------------------------------------- */

static void vsub(double *o, const float *a, const float *b) {
    o[0] = (double)a[0] - b[0];
    o[1] = (double)a[1] - b[1];
    o[2] = (double)a[2] - b[2];
}

static double tri_area(const float *a, const float *b, const float *c) {
    double e1[3], e2[3], n[3];
    vsub(e1, b, a);
    vsub(e2, c, a);
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    return 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

static double mesh_area(const refl_mesh *m) {
    double s = 0;
    int t;
    for (t = 0; t < m->triangle_count; ++t) {
        const uint32_t *i = m->indices + 3 * t;
        s += tri_area(m->positions + 3 * i[0], m->positions + 3 * i[1], m->positions + 3 * i[2]);
    }
    return s;
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5). */
static double point_triangle_distance(const float *pf, const float *af, const float *bf, const float *cf) {
    double p[3], a[3], b[3], c[3], ab[3], ac[3], ap[3], bp[3], cp[3], q[3], d1, d2, d3, d4, d5, d6, va, vb, vc, v, w,
        den;
    int k;
    for (k = 0; k < 3; ++k) {
        p[k] = pf[k]; a[k] = af[k]; b[k] = bf[k]; c[k] = cf[k];
        ab[k] = b[k] - a[k]; ac[k] = c[k] - a[k]; ap[k] = p[k] - a[k];
        bp[k] = p[k] - b[k]; cp[k] = p[k] - c[k];
    }
    d1 = dot3(ab, ap); d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) { memcpy(q, a, sizeof q); goto out; }
    d3 = dot3(ab, bp); d4 = dot3(ac, bp);
    if (d3 >= 0 && d4 <= d3) { memcpy(q, b, sizeof q); goto out; }
    vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        v = d1 / (d1 - d3);
        for (k = 0; k < 3; ++k) q[k] = a[k] + v * ab[k];
        goto out;
    }
    d5 = dot3(ab, cp); d6 = dot3(ac, cp);
    if (d6 >= 0 && d5 <= d6) { memcpy(q, c, sizeof q); goto out; }
    vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        w = d2 / (d2 - d6);
        for (k = 0; k < 3; ++k) q[k] = a[k] + w * ac[k];
        goto out;
    }
    va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (k = 0; k < 3; ++k) q[k] = b[k] + w * (c[k] - b[k]);
        goto out;
    }
    den = 1.0 / (va + vb + vc);
    v = vb * den;
    w = vc * den;
    for (k = 0; k < 3; ++k) q[k] = a[k] + ab[k] * v + ac[k] * w;
out:
    for (k = 0; k < 3; ++k) q[k] -= p[k];
    return sqrt(dot3(q, q));
}

/* ---- creation ---------------------------------------------------------------------- */

Test(refl_mesh, create_copies_and_computes) {
    hmesh h = cube();
    refl_mesh *m = make(&h, NULL);
    cr_assert_eq(m->vertex_count, 8);
    cr_assert_eq(m->triangle_count, 12);
    cr_assert(m->positions != h.p && memcmp(m->positions, h.p, 8 * 3 * sizeof(float)) == 0);
    cr_assert(memcmp(m->indices, h.t, 36 * sizeof(uint32_t)) == 0);
    cr_assert_null(m->texcoords);
    cr_assert_null(m->colors);
    refl_mesh_destroy(m);
    refl_mesh_destroy(NULL); /* harmless */
}

Test(refl_mesh, create_errors) {
    hmesh h = cube();
    refl_mesh_desc d;
    refl_mesh *m = (refl_mesh *)&h; /* must be reset to NULL on failure */
    uint32_t bad[36];
    float p[8 * 3];
#define BASE()                          \
    do {                                \
        memset(&d, 0, sizeof d);        \
        d.positions = h.p;              \
        d.indices = h.t;                \
        d.vertex_count = 8;             \
        d.index_count = 36;             \
    } while (0)
#define EXPECT(code)                                                                        \
    do {                                                                                    \
        m = (refl_mesh *)&h;                                                                \
        cr_assert_eq(refl_mesh_create(&d, &m), code, "line %d: want %d", __LINE__, code);  \
        cr_assert_null(m);                                                                  \
    } while (0)
    BASE();
    cr_assert_eq(refl_mesh_create(&d, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_mesh_create(NULL, &m), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(m);
    BASE(); d.positions = NULL; EXPECT(REFL_ERROR_INVALID_ARGUMENT);
    BASE(); d.vertex_count = 0; EXPECT(REFL_ERROR_BAD_MESH);           /* no vertices */
    BASE(); d.index_count = 0; EXPECT(REFL_ERROR_BAD_MESH);            /* no triangles */
    BASE(); d.vertex_count = -1; EXPECT(REFL_ERROR_INVALID_SIZE);
    BASE(); d.index_count = -3; EXPECT(REFL_ERROR_INVALID_SIZE);
    BASE(); d.index_count = 35; EXPECT(REFL_ERROR_INVALID_SIZE);       /* not a multiple of 3 */
    BASE(); d.indices = NULL; EXPECT(REFL_ERROR_INVALID_ARGUMENT);     /* a count without its array */
    BASE(); d.indices = NULL; d.index_count = 0; EXPECT(REFL_ERROR_INVALID_SIZE); /* 8 vertices, not 3k */
    BASE(); d.allocator.alloc = counting_alloc; EXPECT(REFL_ERROR_INVALID_ARGUMENT); /* alloc without free */
    memcpy(bad, h.t, sizeof bad);
    bad[17] = 8; /* one past the end */
    BASE(); d.indices = bad; EXPECT(REFL_ERROR_BAD_MESH);
    bad[17] = 0xFFFFFFFFu;
    BASE(); d.indices = bad; EXPECT(REFL_ERROR_BAD_MESH);
    memcpy(p, h.p, sizeof p);
    p[13] = NAN;
    BASE(); d.positions = p; EXPECT(REFL_ERROR_BAD_MESH);
    p[13] = INFINITY;
    BASE(); d.positions = p; EXPECT(REFL_ERROR_BAD_MESH);
    p[13] = -INFINITY;
    BASE(); d.positions = p; EXPECT(REFL_ERROR_BAD_MESH);
#undef BASE
#undef EXPECT
}

/* Without indices, vertices are taken three at a time. */
Test(refl_mesh, create_without_indices) {
    const float p[18] = {0, 0, 0, 1, 0, 0, 0, 0, -1, 5, 5, 5, 6, 5, 5, 5, 5, 4};
    refl_mesh_desc d;
    refl_mesh *m;
    int i;
    memset(&d, 0, sizeof d);
    d.positions = p;
    d.vertex_count = 6;
    cr_assert_eq(refl_mesh_create(&d, &m), REFL_OK);
    cr_assert_eq(m->triangle_count, 2);
    for (i = 0; i < 6; ++i) cr_assert_eq(m->indices[i], (uint32_t)i);
    for (i = 0; i < 6; ++i) cr_assert(m->normals[3 * i] == 0 && m->normals[3 * i + 1] == 1 && m->normals[3 * i + 2] == 0);
    refl_mesh_destroy(m);
}

/* Every allocation of create (with computed normals, texcoords and
   colours), subdivide and sample fails in turn: the call reports
   OUT_OF_MEMORY, leaves NULL, and nothing leaks. */
Test(refl_mesh, allocation_failure_at_every_allocation) {
    hmesh h = octahedron(1);
    float uv[6 * 2], col[6 * 4];
    refl_mesh_desc d;
    counting c;
    refl_mesh *m, *base, *sub;
    refl_points *pts;
    refl_result r;
    long k;
    int i, ok = 0;
    for (i = 0; i < 12; ++i) uv[i] = (float)i;
    for (i = 0; i < 24; ++i) col[i] = (float)i / 24;
    for (k = 1; !ok; ++k) { /* create */
        memset(&c, 0, sizeof c);
        c.fail_at = k;
        memset(&d, 0, sizeof d);
        d.positions = h.p; d.texcoords = uv; d.colors = col; d.indices = h.t;
        d.vertex_count = h.nv; d.index_count = 3 * h.nt;
        d.allocator = counting_allocator(&c);
        m = (refl_mesh *)&c;
        r = refl_mesh_create(&d, &m);
        if (r == REFL_OK) {
            ok = 1;
            cr_assert_eq(c.calls, k - 1, "the successful run made %ld allocations", c.calls);
            refl_mesh_destroy(m);
        } else {
            cr_assert_eq(r, REFL_ERROR_OUT_OF_MEMORY, "fail at %ld: %d", k, r);
            cr_assert_null(m);
        }
        cr_assert_eq(c.live, 0, "create, fail at %ld: %ld leaked", k, c.live);
    }
    cr_assert_gt(k, 6); /* struct, 5 arrays, the normal accumulator */
    /* subdivide and sample through a mesh that owns a counting allocator */
    memset(&c, 0, sizeof c);
    memset(&d, 0, sizeof d);
    d.positions = h.p; d.texcoords = uv; d.colors = col; d.indices = h.t;
    d.vertex_count = h.nv; d.index_count = 3 * h.nt;
    d.allocator = counting_allocator(&c);
    cr_assert_eq(refl_mesh_create(&d, &base), REFL_OK);
    for (ok = 0, k = 1; !ok; ++k) {
        long live0 = c.live;
        c.calls = 0;
        c.fail_at = k;
        sub = (refl_mesh *)&c;
        r = refl_mesh_subdivide(base, 0.3f, &sub);
        c.fail_at = 0;
        if (r == REFL_OK) {
            ok = 1;
            refl_mesh_destroy(sub);
        } else {
            cr_assert_eq(r, REFL_ERROR_OUT_OF_MEMORY, "fail at %ld: %d", k, r);
            cr_assert_null(sub);
        }
        cr_assert_eq(c.live, live0, "subdivide, fail at %ld: %ld leaked", k, c.live - live0);
    }
    cr_assert_gt(k, 20); /* several rounds of map + mesh */
    for (ok = 0, k = 1; !ok; ++k) {
        counting c2;
        refl_allocator a2;
        memset(&c2, 0, sizeof c2);
        c2.fail_at = k;
        a2 = counting_allocator(&c2);
        pts = (refl_points *)&c2;
        r = refl_mesh_sample_points(base, NULL, 50.0f, 7, &a2, &pts);
        if (r == REFL_OK) {
            ok = 1;
            cr_assert_gt(pts->count, 0);
            refl_points_destroy(pts);
        } else {
            cr_assert_eq(r, REFL_ERROR_OUT_OF_MEMORY, "fail at %ld: %d", k, r);
            cr_assert_null(pts);
        }
        cr_assert_eq(c2.live, 0, "sample, fail at %ld: %ld leaked", k, c2.live);
    }
    refl_mesh_destroy(base);
    cr_assert_eq(c.live, 0);
}

/* ---- normals ---------------------------------------------------------------------- */

/* Each cube corner touches three faces, each with a right angle there
   (split as 90 or 45 + 45 by the diagonals): angle weighting gives exactly
   the diagonal direction, whatever the triangulation. */
Test(refl_mesh, normals_of_a_cube) {
    hmesh h = cube();
    refl_mesh *m = make(&h, NULL);
    int v, k;
    for (v = 0; v < 8; ++v)
        for (k = 0; k < 3; ++k) {
            float want = (float)((h.p[3 * v + k] - 0.5) * 2 / sqrt(3.0));
            cr_assert(fabsf(m->normals[3 * v + k] - want) < 1e-6f, "vertex %d: %g, want %g", v, m->normals[3 * v + k], want);
        }
    refl_mesh_destroy(m);
}

Test(refl_mesh, normals_of_a_plane) {
    hmesh h = grid(4, 2.0);
    refl_mesh *m = make(&h, NULL);
    int v;
    for (v = 0; v < m->vertex_count; ++v)
        cr_assert(m->normals[3 * v] == 0 && m->normals[3 * v + 1] == 1 && m->normals[3 * v + 2] == 0, "vertex %d", v);
    refl_mesh_destroy(m);
}

/* Given normals are normalised; zero and NaN ones are replaced by the
   computed ones; degenerate triangles add nothing; a vertex without a
   proper triangle gets (0, 1, 0). */
Test(refl_mesh, normals_given_degenerate_and_lonely) {
    hmesh h = grid(1, 1.0); /* 4 vertices, 2 triangles, +y */
    float n[7 * 3];
    refl_mesh *m;
    int v;
    /* vertex 4, 5: a collinear triangle with vertex 0; vertex 6 unused */
    h_vertex(&h, 2, 1, 0);
    h_vertex(&h, 4, 2, 0);
    h_vertex(&h, 9, 9, 9);
    h_tri(&h, 0, 4, 5);
    h_tri(&h, 1, 1, 2); /* repeated index */
    for (v = 0; v < 7; ++v) {
        n[3 * v] = 0; n[3 * v + 1] = 0; n[3 * v + 2] = 3; /* not unit */
    }
    n[3 * 0 + 2] = 0;   /* zero: computed */
    n[3 * 2 + 1] = NAN; /* NaN: computed */
    n[3 * 4 + 2] = 0;   /* zero on a degenerate-only vertex: (0, 1, 0) */
    m = make(&h, n);
    cr_assert(m->normals[0] == 0 && m->normals[1] == 1 && m->normals[2] == 0, "vertex 0 from its proper faces only");
    cr_assert(m->normals[3] == 0 && m->normals[4] == 0 && m->normals[5] == 1, "vertex 1 given, normalised");
    cr_assert(m->normals[6] == 0 && m->normals[7] == 1 && m->normals[8] == 0, "vertex 2 NaN replaced");
    cr_assert(m->normals[12] == 0 && m->normals[13] == 1 && m->normals[14] == 0, "vertex 4 lonely");
    cr_assert(m->normals[20] == 1, "vertex 6 given");
    refl_mesh_destroy(m);
    m = make(&h, NULL);
    for (v = 4; v < 7; ++v)
        cr_assert(m->normals[3 * v] == 0 && m->normals[3 * v + 1] == 1 && m->normals[3 * v + 2] == 0, "vertex %d", v);
    cr_assert(m->normals[1] == 1);
    refl_mesh_destroy(m);
}

/* A vertex where a big and a small face meet at equal angles gets their
   bisector; area weighting would lean towards the big face. */
Test(refl_mesh, normals_are_angle_weighted) {
    hmesh h;
    refl_mesh *m;
    const float *n;
    memset(&h, 0, sizeof h);
    /* apex at the origin, two faces with right angles there: A (normal
       (1,1,0)/sqrt 2) reaches z = 10, B (normal (-1,1,0)/sqrt 2) z = 1 */
    h_vertex(&h, 0, 0, 0);
    h_vertex(&h, 1, -1, 0);
    h_vertex(&h, 0, 0, 10);
    h_vertex(&h, -1, -1, 0);
    h_vertex(&h, 0, 0, 1);
    h_tri(&h, 0, 2, 1);
    h_tri(&h, 0, 3, 4);
    m = make(&h, NULL);
    n = m->normals;
    cr_assert(fabsf(n[0]) < 1e-6f && fabsf(n[1] - 1) < 1e-6f && fabsf(n[2]) < 1e-6f, "apex normal (%g %g %g)", n[0], n[1],
              n[2]);
    cr_assert(fabsf(n[3] - (float)sqrt(0.5)) < 1e-6f && fabsf(n[4] - (float)sqrt(0.5)) < 1e-6f, "face A");
    cr_assert(fabsf(n[9] + (float)sqrt(0.5)) < 1e-6f && fabsf(n[10] - (float)sqrt(0.5)) < 1e-6f, "face B");
    refl_mesh_destroy(m);
}

Test(refl_mesh, bounds) {
    hmesh h = octahedron(2);
    refl_mesh *m;
    refl_vec3 lo, hi;
    h.p[0] = 3; /* +x vertex moved */
    m = make(&h, NULL);
    refl_mesh_bounds(m, &lo, &hi);
    cr_assert(lo.x == -2 && lo.y == -2 && lo.z == -2 && hi.x == 3 && hi.y == 2 && hi.z == 2);
    refl_mesh_bounds(m, NULL, &hi); /* either output may be NULL */
    refl_mesh_bounds(NULL, &lo, &hi);
    cr_assert(lo.x == 0 && hi.z == 0);
    refl_mesh_destroy(m);
}

/* ---- subdivision ---------------------------------------------------------------------- */

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Every directed edge exactly once and its reverse exactly once: a closed,
   consistently oriented manifold without T-junctions. Returns the number
   of undirected edges. */
static long check_closed(const refl_mesh *m) {
    long n = 3L * m->triangle_count, i;
    uint64_t *e = (uint64_t *)malloc((size_t)n * sizeof(uint64_t));
    int t, k;
    for (t = 0; t < m->triangle_count; ++t)
        for (k = 0; k < 3; ++k) {
            uint64_t u = m->indices[3 * t + k], v = m->indices[3 * t + (k + 1) % 3];
            cr_assert_neq(u, v);
            e[3 * t + k] = u << 32 | v;
        }
    qsort(e, (size_t)n, sizeof(uint64_t), cmp_u64);
    for (i = 0; i < n; ++i) {
        uint64_t rev = (e[i] & 0xFFFFFFFFu) << 32 | e[i] >> 32;
        cr_assert(i == 0 || e[i] != e[i - 1], "directed edge %lu-%lu twice", (unsigned long)(e[i] >> 32),
                  (unsigned long)(e[i] & 0xFFFFFFFFu));
        cr_assert_not_null(bsearch(&rev, e, (size_t)n, sizeof(uint64_t), cmp_u64), "edge %lu-%lu has one side only",
                           (unsigned long)(e[i] >> 32), (unsigned long)(e[i] & 0xFFFFFFFFu));
    }
    free(e);
    return n / 2;
}

/* Subdivides and checks: edges <= max_edge, vertices on the original
   surface, area kept, original vertices kept in place, normals unit. */
static refl_mesh *subdivide_checked(const refl_mesh *m, float max_edge) {
    refl_mesh *s = NULL;
    refl_vec3 lo, hi;
    double size, a0 = mesh_area(m), a1;
    int t, k, v;
    refl_mesh_bounds(m, &lo, &hi);
    size = sqrt((double)(hi.x - lo.x) * (hi.x - lo.x) + (double)(hi.y - lo.y) * (hi.y - lo.y) +
                (double)(hi.z - lo.z) * (hi.z - lo.z));
    cr_assert_eq(refl_mesh_subdivide(m, max_edge, &s), REFL_OK);
    cr_assert_geq(s->vertex_count, m->vertex_count);
    cr_assert(memcmp(s->positions, m->positions, (size_t)m->vertex_count * 3 * sizeof(float)) == 0,
              "original vertices move");
    for (t = 0; t < s->triangle_count; ++t)
        for (k = 0; k < 3; ++k) {
            uint32_t u = s->indices[3 * t + k], w = s->indices[3 * t + (k + 1) % 3];
            double e[3];
            cr_assert_lt(u, (uint32_t)s->vertex_count);
            vsub(e, s->positions + 3 * u, s->positions + 3 * w);
            cr_assert(sqrt(dot3(e, e)) <= max_edge * (1 + 1e-6), "edge %g > %g", sqrt(dot3(e, e)), max_edge);
        }
    for (v = m->vertex_count; v < s->vertex_count; ++v) {
        double best = DBL_MAX, l;
        const float *n = s->normals + 3 * v;
        for (t = 0; t < m->triangle_count; ++t) {
            const uint32_t *i = m->indices + 3 * t;
            double d = point_triangle_distance(s->positions + 3 * v, m->positions + 3 * i[0], m->positions + 3 * i[1],
                                               m->positions + 3 * i[2]);
            best = d < best ? d : best;
        }
        cr_assert(best < 1e-6 * size, "vertex %d is %g off the surface", v, best);
        l = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        cr_assert(fabs(l - 1) < 1e-6, "normal %d has length %g", v, l);
    }
    a1 = mesh_area(s);
    cr_assert(fabs(a1 - a0) <= 1e-5 * a0, "area %.9g -> %.9g", a0, a1);
    return s;
}

Test(refl_mesh, subdivide_closed_meshes_stay_closed) {
    hmesh shapes[3];
    static const float max_edges[4] = {1.0f, 0.3f, 0.11f, 0.05f};
    int i, j;
    shapes[0] = tetrahedron();
    shapes[1] = octahedron(1);
    shapes[2] = octahedron(1);
    /* an irregular octahedron: edges of many lengths, so triangles split
       on 1, 2 or 3 edges in the same round */
    for (j = 0; j < 6; ++j) {
        float f = 0.6f + 0.37f * (float)j;
        shapes[2].p[3 * j] *= f;
        shapes[2].p[3 * j + 1] *= 1.9f - 0.23f * (float)j;
        shapes[2].p[3 * j + 2] *= f * 0.5f + 0.2f;
    }
    for (i = 0; i < 3; ++i)
        for (j = 0; j < 4; ++j) {
            refl_mesh *m = make(&shapes[i], NULL), *s = subdivide_checked(m, max_edges[j]);
            long edges = check_closed(s);
            cr_assert_eq(s->vertex_count - edges + s->triangle_count, 2, "Euler characteristic, shape %d", i);
            refl_mesh_destroy(s);
            refl_mesh_destroy(m);
        }
}

/* Texture coordinates and colours that are linear in position stay so;
   a sliver triangle terminates; the result is the same every time. */
Test(refl_mesh, subdivide_attributes_and_determinism) {
    hmesh h = grid(2, 3.0);
    float uv[9 * 2], col[9 * 4];
    refl_mesh_desc d;
    refl_mesh *m, *s, *s2;
    int v;
    h.p[3 * 4] += 0.4f; /* move the centre: uneven triangles */
    for (v = 0; v < h.nv; ++v) {
        float x = h.p[3 * v], z = h.p[3 * v + 2];
        uv[2 * v] = x; uv[2 * v + 1] = z;
        col[4 * v] = x; col[4 * v + 1] = z; col[4 * v + 2] = x + z; col[4 * v + 3] = 1;
    }
    memset(&d, 0, sizeof d);
    d.positions = h.p; d.texcoords = uv; d.colors = col; d.indices = h.t;
    d.vertex_count = h.nv; d.index_count = 3 * h.nt;
    cr_assert_eq(refl_mesh_create(&d, &m), REFL_OK);
    s = subdivide_checked(m, 0.2f);
    s2 = subdivide_checked(m, 0.2f);
    cr_assert_not_null(s->texcoords);
    cr_assert_not_null(s->colors);
    for (v = 0; v < s->vertex_count; ++v) {
        const float *p = s->positions + 3 * v, *t = s->texcoords + 2 * v, *c = s->colors + 4 * v;
        cr_assert(fabsf(t[0] - p[0]) < 1e-5f && fabsf(t[1] - p[2]) < 1e-5f, "uv at vertex %d", v);
        cr_assert(fabsf(c[0] - p[0]) < 1e-5f && fabsf(c[2] - p[0] - p[2]) < 1e-5f && c[3] == 1, "colour at vertex %d", v);
        cr_assert(s->normals[3 * v + 1] == 1.0f);
    }
    cr_assert_eq(s->vertex_count, s2->vertex_count);
    cr_assert_eq(s->triangle_count, s2->triangle_count);
    cr_assert(memcmp(s->positions, s2->positions, (size_t)s->vertex_count * 3 * sizeof(float)) == 0);
    cr_assert(memcmp(s->indices, s2->indices, (size_t)s->triangle_count * 3 * sizeof(uint32_t)) == 0);
    refl_mesh_destroy(s);
    refl_mesh_destroy(s2);
    refl_mesh_destroy(m);
    { /* a sliver: 10 long, 0.001 high */
        hmesh sl;
        memset(&sl, 0, sizeof sl);
        h_vertex(&sl, 0, 0, 0); h_vertex(&sl, 10, 0, 0); h_vertex(&sl, 4, 0.001, 0);
        h_tri(&sl, 0, 1, 2);
        m = make(&sl, NULL);
        s = subdivide_checked(m, 0.1f);
        refl_mesh_destroy(s);
        refl_mesh_destroy(m);
    }
}

Test(refl_mesh, subdivide_arguments) {
    hmesh h = octahedron(1);
    refl_mesh *m = make(&h, NULL), *s = (refl_mesh *)&h;
    cr_assert_eq(refl_mesh_subdivide(m, 0.0f, &s), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(s);
    cr_assert_eq(refl_mesh_subdivide(m, -1.0f, &s), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_mesh_subdivide(m, NAN, &s), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_mesh_subdivide(NULL, 1.0f, &s), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_mesh_subdivide(m, 1.0f, NULL), REFL_ERROR_INVALID_ARGUMENT);
    /* absurd growth fails up front (about 2^40 triangles) */
    cr_assert_eq(refl_mesh_subdivide(m, 1e-6f, &s), REFL_ERROR_INVALID_SIZE);
    cr_assert_null(s);
    /* nothing to split: an equal copy */
    cr_assert_eq(refl_mesh_subdivide(m, INFINITY, &s), REFL_OK);
    cr_assert(s != m && s->vertex_count == 6 && s->triangle_count == 8);
    cr_assert(memcmp(s->indices, m->indices, 24 * sizeof(uint32_t)) == 0);
    refl_mesh_destroy(s);
    cr_assert_eq(refl_mesh_subdivide(m, 2.0f, &s), REFL_OK); /* edges are sqrt 2 */
    cr_assert(memcmp(s->positions, m->positions, 18 * sizeof(float)) == 0 && s->triangle_count == 8);
    refl_mesh_destroy(s);
    refl_mesh_destroy(m);
}

/* ---- sampling ---------------------------------------------------------------------------- */

/* Barycentric coordinates of p in triangle abc and its distance to the plane. */
static void barycentric(const float *pf, const float *af, const float *bf, const float *cf, double bc[3], double *plane) {
    double v0[3], v1[3], v2[3], d00, d01, d11, d20, d21, den, n[3], ln;
    vsub(v0, bf, af);
    vsub(v1, cf, af);
    vsub(v2, pf, af);
    d00 = dot3(v0, v0); d01 = dot3(v0, v1); d11 = dot3(v1, v1);
    d20 = dot3(v2, v0); d21 = dot3(v2, v1);
    den = d00 * d11 - d01 * d01;
    bc[1] = (d11 * d20 - d01 * d21) / den;
    bc[2] = (d00 * d21 - d01 * d20) / den;
    bc[0] = 1 - bc[1] - bc[2];
    n[0] = v0[1] * v1[2] - v0[2] * v1[1];
    n[1] = v0[2] * v1[0] - v0[0] * v1[2];
    n[2] = v0[0] * v1[1] - v0[1] * v1[0];
    ln = sqrt(dot3(n, n));
    *plane = fabs(dot3(v2, n)) / ln;
}

/* Four separate right triangles of areas 1, 2, 3, 4 (legs sqrt(2k)). */
static hmesh four_triangles(void) {
    hmesh h;
    int k;
    memset(&h, 0, sizeof h);
    for (k = 0; k < 4; ++k) {
        double l = sqrt(2.0 * (k + 1)), x = 10.0 * k;
        h_vertex(&h, x, 0, 0);
        h_vertex(&h, x + l, 0, 0);
        h_vertex(&h, x, 0, -l);
        h_tri(&h, (uint32_t)(3 * k), (uint32_t)(3 * k + 1), (uint32_t)(3 * k + 2));
    }
    return h;
}

Test(refl_mesh, sample_count) {
    hmesh h = grid(1, 2.0); /* area 4 */
    refl_mesh *m = make(&h, NULL);
    refl_points *p;
    double sum = 0;
    int seed, lo = 1 << 30, hi = 0;
    cr_assert_eq(refl_mesh_sample_points(m, NULL, 1000.0f, 1, NULL, &p), REFL_OK);
    cr_assert(abs(p->count - 4000) <= 1, "count %d", p->count);
    refl_points_destroy(p);
    /* scaled by 3: area 36 */
    {
        refl_mat4 s = refl_mat4_scale(refl_v3(3, 1, 3));
        cr_assert_eq(refl_mesh_sample_points(m, &s, 100.0f, 1, NULL, &p), REFL_OK);
        cr_assert(abs(p->count - 3600) <= 1, "count %d", p->count);
        refl_points_destroy(p);
    }
    /* expected 10.5: 10 or 11, 10.5 on average (Bernoulli sd 0.5) */
    for (seed = 1; seed <= 4000; ++seed) {
        cr_assert_eq(refl_mesh_sample_points(m, NULL, 2.625f, (uint64_t)seed, NULL, &p), REFL_OK);
        sum += p->count;
        lo = p->count < lo ? p->count : lo;
        hi = p->count > hi ? p->count : hi;
        refl_points_destroy(p);
    }
    cr_assert(lo == 10 && hi == 11, "counts %d..%d", lo, hi);
    cr_assert(fabs(sum / 4000 - 10.5) < 4 * 0.5 / sqrt(4000.0), "mean count %g", sum / 4000);
    /* density 0: no points, still a valid (empty) result */
    cr_assert_eq(refl_mesh_sample_points(m, NULL, 0.0f, 1, NULL, &p), REFL_OK);
    cr_assert_eq(p->count, 0);
    refl_points_destroy(p);
    refl_points_destroy(NULL);
    refl_mesh_destroy(m);
}

/* Triangles of areas 1..4 get points in proportion (chi-square, 3 dof), and
   within a triangle the four midpoint sub-triangles get a quarter each. */
Test(refl_mesh, sample_uniform) {
    hmesh h = four_triangles();
    refl_mesh *m = make(&h, NULL);
    refl_points *p;
    long per_tri[4] = {0}, sub[4][4];
    double chi = 0;
    int i, k;
    memset(sub, 0, sizeof sub);
    cr_assert_eq(refl_mesh_sample_points(m, NULL, 10000.0f, 99, NULL, &p), REFL_OK);
    cr_assert(abs(p->count - 100000) <= 1);
    for (i = 0; i < p->count; ++i) {
        uint32_t t = p->triangles[i];
        const uint32_t *ix = m->indices + 3 * t;
        double bc[3], d;
        cr_assert_lt(t, 4u);
        ++per_tri[t];
        barycentric(p->positions + 3 * i, m->positions + 3 * ix[0], m->positions + 3 * ix[1], m->positions + 3 * ix[2], bc,
                    &d);
        /* the midpoint sub-triangle: a corner one when its coordinate > 1/2 */
        k = bc[0] > 0.5 ? 0 : bc[1] > 0.5 ? 1 : bc[2] > 0.5 ? 2 : 3;
        ++sub[t][k];
    }
    for (k = 0; k < 4; ++k) {
        double e = p->count * (k + 1) / 10.0;
        chi += (per_tri[k] - e) * (per_tri[k] - e) / e;
    }
    cr_assert(chi < 16.27, "triangles: chi-square %g (3 dof, p = 0.001 at 16.27): %ld %ld %ld %ld", chi, per_tri[0],
              per_tri[1], per_tri[2], per_tri[3]);
    for (i = 0; i < 4; ++i) {
        chi = 0;
        for (k = 0; k < 4; ++k) {
            double e = per_tri[i] / 4.0;
            chi += (sub[i][k] - e) * (sub[i][k] - e) / e;
        }
        cr_assert(chi < 16.27, "inside triangle %d: chi-square %g", i, chi);
    }
    refl_points_destroy(p);
    refl_mesh_destroy(m);
}

static uint64_t fnv(const void *data, size_t n, uint64_t h) {
    const unsigned char *b = (const unsigned char *)data;
    size_t i;
    for (i = 0; i < n; ++i) h = (h ^ b[i]) * 0x100000001B3ull;
    return h;
}

/* Same seed: the same bytes; another seed: other points. Points lie on
   the triangle they name, with the (transformed) surface normal. */
Test(refl_mesh, sample_determinism_and_placement) {
    hmesh h = octahedron(1.5);
    refl_mesh *m = make(&h, NULL);
    refl_mat4 tr = refl_mat4_mul(refl_mat4_translate(refl_v3(1, -2, 3)),
                                 refl_mat4_mul(refl_mat4_rotate(refl_v3(1, 2, 3), 0.7f), refl_mat4_scale(refl_v3(2, 1, 0.5f))));
    refl_mat4 nmat;
    refl_points *a, *b, *c;
    int i;
    cr_assert_eq(refl_mat4_invert(tr, &nmat), 1);
    nmat = refl_mat4_transpose(nmat);
    cr_assert_eq(refl_mesh_sample_points(m, &tr, 300.0f, 42, NULL, &a), REFL_OK);
    cr_assert_eq(refl_mesh_sample_points(m, &tr, 300.0f, 42, NULL, &b), REFL_OK);
    cr_assert_eq(refl_mesh_sample_points(m, &tr, 300.0f, 43, NULL, &c), REFL_OK);
    cr_assert_eq(a->count, b->count);
    cr_assert_gt(a->count, 1000);
    cr_assert(memcmp(a->positions, b->positions, (size_t)a->count * 3 * sizeof(float)) == 0);
    cr_assert(memcmp(a->normals, b->normals, (size_t)a->count * 3 * sizeof(float)) == 0);
    cr_assert(memcmp(a->triangles, b->triangles, (size_t)a->count * sizeof(uint32_t)) == 0);
    cr_assert(c->count != a->count ||
              memcmp(a->positions, c->positions, (size_t)a->count * 3 * sizeof(float)) != 0);
    for (i = 0; i < a->count; ++i) {
        const uint32_t *ix = m->indices + 3 * a->triangles[i];
        float w[3][3];
        double bc[3], d, fn[3], e1[3], e2[3], l, dd;
        const float *n = a->normals + 3 * i;
        int k;
        for (k = 0; k < 3; ++k) {
            refl_vec3 q = refl_mat4_point(tr, refl_v3(m->positions[3 * ix[k]], m->positions[3 * ix[k] + 1],
                                                      m->positions[3 * ix[k] + 2]));
            w[k][0] = q.x; w[k][1] = q.y; w[k][2] = q.z;
        }
        barycentric(a->positions + 3 * i, w[0], w[1], w[2], bc, &d);
        cr_assert(d < 1e-5 && bc[0] > -1e-5 && bc[1] > -1e-5 && bc[2] > -1e-5, "point %d: off its triangle (%g; %g %g %g)",
                  i, d, bc[0], bc[1], bc[2]);
        /* the normal: the vertex normals interpolated, through the inverse
           transpose, normalised; and outward */
        vsub(e1, w[1], w[0]);
        vsub(e2, w[2], w[0]);
        fn[0] = e1[1] * e2[2] - e1[2] * e2[1];
        fn[1] = e1[2] * e2[0] - e1[0] * e2[2];
        fn[2] = e1[0] * e2[1] - e1[1] * e2[0];
        l = sqrt(dot3(fn, fn));
        dd = (n[0] * fn[0] + n[1] * fn[1] + n[2] * fn[2]) / l;
        cr_assert(dd > 0, "point %d: normal points inward", i);
        {
            refl_vec3 on = refl_v3(0, 0, 0), want;
            for (k = 0; k < 3; ++k)
                on = refl_v3_add(on, refl_v3_scale(refl_v3(m->normals[3 * ix[k]], m->normals[3 * ix[k] + 1],
                                                           m->normals[3 * ix[k] + 2]),
                                                   (float)bc[k]));
            want = refl_v3_normalize(refl_mat4_dir(nmat, on));
            cr_assert(fabsf(n[0] - want.x) < 1e-4f && fabsf(n[1] - want.y) < 1e-4f && fabsf(n[2] - want.z) < 1e-4f,
                      "point %d: normal (%g %g %g), want (%g %g %g)", i, n[0], n[1], n[2], want.x, want.y, want.z);
        }
        cr_assert(fabs(sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]) - 1) < 1e-6);
    }
    refl_points_destroy(a);
    refl_points_destroy(b);
    refl_points_destroy(c);
    refl_mesh_destroy(m);
}

/* The stream is pinned: these bytes on every machine (the hash would only
   change with a deliberate change of the sampling recipe). */
Test(refl_mesh, sample_golden) {
    hmesh h = four_triangles();
    refl_mesh *m = make(&h, NULL);
    refl_points *p;
    uint64_t hash = 0xcbf29ce484222325ull;
    cr_assert_eq(refl_mesh_sample_points(m, NULL, 50.0f, 2024, NULL, &p), REFL_OK);
    cr_assert_eq(p->count, 500);
    hash = fnv(p->positions, (size_t)p->count * 3 * sizeof(float), hash);
    hash = fnv(p->normals, (size_t)p->count * 3 * sizeof(float), hash);
    hash = fnv(p->triangles, (size_t)p->count * sizeof(uint32_t), hash);
    cr_assert_eq(hash, 0x953131974067e286ull, "hash %016llx", (unsigned long long)hash);
    refl_points_destroy(p);
    refl_mesh_destroy(m);
}

/* Normals go through the inverse transpose: a shear x -> (x, x + y, z)
   tilts the y = 0 plane to y = x, with normal (-1, 1, 0) / sqrt 2; a mirror
   keeps normals outward. */
Test(refl_mesh, sample_transformed_normals) {
    hmesh h = grid(2, 1.0);
    refl_mesh *m = make(&h, NULL);
    refl_mat4 shear = refl_mat4_identity(), mirror = refl_mat4_scale(refl_v3(1, -1, 1));
    refl_points *p;
    int i;
    shear.m[1] = 1; /* row y, column x */
    cr_assert_eq(refl_mesh_sample_points(m, &shear, 500.0f, 3, NULL, &p), REFL_OK);
    cr_assert_gt(p->count, 0);
    cr_assert(abs(p->count - (int)lround(500 * sqrt(2.0))) <= 1, "count %d (area sqrt 2)", p->count);
    for (i = 0; i < p->count; ++i) {
        const float *q = p->positions + 3 * i, *n = p->normals + 3 * i;
        cr_assert(fabsf(q[1] - q[0]) < 1e-6f);
        cr_assert(fabsf(n[0] + (float)sqrt(0.5)) < 1e-6f && fabsf(n[1] - (float)sqrt(0.5)) < 1e-6f && n[2] == 0,
                  "normal (%g %g %g)", n[0], n[1], n[2]);
    }
    refl_points_destroy(p);
    cr_assert_eq(refl_mesh_sample_points(m, &mirror, 100.0f, 3, NULL, &p), REFL_OK);
    for (i = 0; i < p->count; ++i) cr_assert(p->normals[3 * i + 1] == -1.0f);
    refl_points_destroy(p);
    refl_mesh_destroy(m);
}

Test(refl_mesh, sample_arguments) {
    hmesh h = grid(1, 1.0);
    refl_mesh *m = make(&h, NULL);
    refl_points *p = (refl_points *)&h;
    refl_mat4 bad = refl_mat4_identity();
    cr_assert_eq(refl_mesh_sample_points(NULL, NULL, 1.0f, 1, NULL, &p), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(p);
    cr_assert_eq(refl_mesh_sample_points(m, NULL, 1.0f, 1, NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_mesh_sample_points(m, NULL, -1.0f, 1, NULL, &p), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_mesh_sample_points(m, NULL, NAN, 1, NULL, &p), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_mesh_sample_points(m, NULL, INFINITY, 1, NULL, &p), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_mesh_sample_points(m, NULL, 1e30f, 1, NULL, &p), REFL_ERROR_INVALID_SIZE);
    cr_assert_null(p);
    bad.m[0] = NAN;
    cr_assert_eq(refl_mesh_sample_points(m, &bad, 1.0f, 1, NULL, &p), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(p);
    refl_mesh_destroy(m);
}
