/* reflect.h shapes: Newell's teapot, sphere, torus, box and plane.

   Properties, not snapshots: bounds against the data's known extremes,
   triangle counts, unit and finite normals that agree with the winding,
   outward orientation, closed shapes with every edge shared by exactly two
   oppositely wound triangles (after welding by position), volumes by the
   divergence theorem, areas converging under refinement, texcoords, every
   invalid argument, and allocation failure at every allocation without a
   leak. */
#include <criterion/criterion.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../../reflect.h"

#define PI 3.14159265358979323846

/* ---- counting allocator ------------------------------------------------------ */

typedef struct counting {
    long calls;   /* allocations attempted */
    long fail_at; /* the attempt that fails (0-based), or -1 */
    long live;    /* allocations not yet freed */
} counting;

static void *counting_alloc(size_t size, void *user) {
    counting *c = (counting *)user;
    if (c->calls++ == c->fail_at) return NULL;
    c->live++;
    return malloc(size);
}

static void counting_free(void *ptr, void *user) {
    counting *c = (counting *)user;
    if (!ptr) return;
    c->live--;
    free(ptr);
}

static refl_allocator counting_allocator(counting *c, long fail_at) {
    refl_allocator a;
    memset(c, 0, sizeof *c);
    c->fail_at = fail_at;
    a.alloc = counting_alloc;
    a.free = counting_free;
    a.user = c;
    return a;
}

/* ---- geometry helpers ------------------------------------------------------------- */

static void vsub(const float *a, const float *b, double r[3]) {
    r[0] = (double)a[0] - b[0];
    r[1] = (double)a[1] - b[1];
    r[2] = (double)a[2] - b[2];
}

static void vcross(const double a[3], const double b[3], double r[3]) {
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

static double vlen(const double a[3]) { return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

/* Twice the area vector of triangle t (CCW winding: along its normal). */
static void face_normal(const refl_mesh *m, int t, double n[3]) {
    const uint32_t *ix = m->indices + 3 * t;
    double e1[3], e2[3];
    vsub(m->positions + 3 * ix[1], m->positions + 3 * ix[0], e1);
    vsub(m->positions + 3 * ix[2], m->positions + 3 * ix[0], e2);
    vcross(e1, e2, n);
}

static double mesh_area(const refl_mesh *m) {
    double a = 0.0, n[3];
    int t;
    for (t = 0; t < m->triangle_count; ++t) {
        face_normal(m, t, n);
        a += 0.5 * vlen(n);
    }
    return a;
}

/* Divergence theorem: sum over triangles of p0 . (p1 x p2) / 6. Positive
   and equal to the volume only for a closed surface wound CCW outside. */
static double mesh_volume(const refl_mesh *m) {
    double v = 0.0;
    int t;
    for (t = 0; t < m->triangle_count; ++t) {
        const float *p0 = m->positions + 3 * m->indices[3 * t];
        const float *p1 = m->positions + 3 * m->indices[3 * t + 1];
        const float *p2 = m->positions + 3 * m->indices[3 * t + 2];
        double a[3] = {p0[0], p0[1], p0[2]}, b[3] = {p1[0], p1[1], p1[2]}, c[3] = {p2[0], p2[1], p2[2]}, x[3];
        vcross(b, c, x);
        v += (a[0] * x[0] + a[1] * x[1] + a[2] * x[2]) / 6.0;
    }
    return v;
}

/* Finite everything, unit normals, indices in range. */
static void check_basic(const refl_mesh *m, const char *what) {
    int i, c, bad_nan = 0, bad_len = 0, bad_idx = 0;
    double worst = 0.0;
    cr_assert_not_null(m, "%s: no mesh", what);
    cr_assert(m->vertex_count > 0 && m->triangle_count > 0, "%s: empty", what);
    for (i = 0; i < m->vertex_count; ++i) {
        double l = 0.0;
        for (c = 0; c < 3; ++c) {
            if (!isfinite(m->positions[3 * i + c]) || !isfinite(m->normals[3 * i + c])) bad_nan++;
            l += (double)m->normals[3 * i + c] * m->normals[3 * i + c];
        }
        if (m->texcoords)
            for (c = 0; c < 2; ++c)
                if (!isfinite(m->texcoords[2 * i + c])) bad_nan++;
        l = sqrt(l);
        if (fabs(l - 1.0) > worst) worst = fabs(l - 1.0);
        if (fabs(l - 1.0) > 1e-5) bad_len++;
    }
    for (i = 0; i < 3 * m->triangle_count; ++i)
        if (m->indices[i] >= (uint32_t)m->vertex_count) bad_idx++;
    cr_expect_eq(bad_nan, 0, "%s: %d non-finite values", what, bad_nan);
    cr_expect_eq(bad_len, 0, "%s: %d normals not unit (worst |len - 1| = %g)", what, bad_len, worst);
    cr_expect_eq(bad_idx, 0, "%s: %d indices out of range", what, bad_idx);
}

/* Triangles whose CCW face normal has a non-positive dot with one of its
   vertex normals (zero-area triangles count as bad). */
static int winding_disagreements(const refl_mesh *m) {
    int t, k, bad = 0;
    for (t = 0; t < m->triangle_count; ++t) {
        double n[3];
        int ok = 1;
        face_normal(m, t, n);
        if (!(vlen(n) > 0.0)) ok = 0;
        for (k = 0; k < 3 && ok; ++k) {
            const float *vn = m->normals + 3 * m->indices[3 * t + k];
            if (n[0] * vn[0] + n[1] * vn[1] + n[2] * vn[2] <= 0.0) ok = 0;
        }
        bad += !ok;
    }
    return bad;
}

/* ---- edges after welding by position ------------------------------------------------ */

static const float *sort_positions;

static int cmp_position(const void *a, const void *b) {
    const float *p = sort_positions + 3 * *(const int *)a, *q = sort_positions + 3 * *(const int *)b;
    int c;
    for (c = 0; c < 3; ++c)
        if (p[c] != q[c]) return p[c] < q[c] ? -1 : 1;
    return *(const int *)a - *(const int *)b;
}

typedef struct edge_rec {
    uint64_t key; /* lower id << 32 | higher id */
    int dir;      /* +1 when wound from lower to higher */
} edge_rec;

static int cmp_edge(const void *a, const void *b) {
    const edge_rec *x = (const edge_rec *)a, *y = (const edge_rec *)b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->dir - y->dir;
}

typedef struct edge_stats {
    int boundary;     /* used by one triangle */
    int interior;     /* two triangles, opposite directions */
    int inconsistent; /* two triangles, same direction */
    int nonmanifold;  /* more than two */
    int collapsed;    /* triangles with two corners welded together */
} edge_stats;

static edge_stats edge_analysis(const refl_mesh *m) {
    int nv = m->vertex_count, nt = m->triangle_count, i, t, k, ne = 0;
    int *order = (int *)malloc(sizeof(int) * (size_t)nv), *id = (int *)malloc(sizeof(int) * (size_t)nv);
    edge_rec *e = (edge_rec *)malloc(sizeof(edge_rec) * 3 * (size_t)nt);
    edge_stats s;
    memset(&s, 0, sizeof s);
    cr_assert(order && id && e);
    for (i = 0; i < nv; ++i) order[i] = i;
    sort_positions = m->positions;
    qsort(order, (size_t)nv, sizeof(int), cmp_position);
    for (i = 0; i < nv; ++i) {
        const float *p = m->positions + 3 * order[i];
        const float *q = i > 0 ? m->positions + 3 * order[i - 1] : NULL;
        int same = q && p[0] == q[0] && p[1] == q[1] && p[2] == q[2];
        id[order[i]] = same ? id[order[i - 1]] : order[i];
    }
    for (t = 0; t < nt; ++t) {
        int w[3], collapsed = 0;
        for (k = 0; k < 3; ++k) w[k] = id[m->indices[3 * t + k]];
        for (k = 0; k < 3; ++k)
            if (w[k] == w[(k + 1) % 3]) collapsed = 1;
        if (collapsed) {
            s.collapsed++;
            continue;
        }
        for (k = 0; k < 3; ++k) {
            uint32_t a = (uint32_t)w[k], b = (uint32_t)w[(k + 1) % 3];
            e[ne].key = a < b ? ((uint64_t)a << 32 | b) : ((uint64_t)b << 32 | a);
            e[ne].dir = a < b ? 1 : -1;
            ne++;
        }
    }
    qsort(e, (size_t)ne, sizeof(edge_rec), cmp_edge);
    for (i = 0; i < ne;) {
        int j = i;
        while (j < ne && e[j].key == e[i].key) j++;
        if (j - i == 1) s.boundary++;
        else if (j - i == 2) {
            if (e[i].dir != e[i + 1].dir) s.interior++;
            else s.inconsistent++;
        } else s.nonmanifold++;
        i = j;
    }
    free(order);
    free(id);
    free(e);
    return s;
}

static void expect_closed(const refl_mesh *m, const char *what) {
    edge_stats s = edge_analysis(m);
    cr_expect(s.boundary == 0 && s.inconsistent == 0 && s.nonmanifold == 0 && s.collapsed == 0,
              "%s: %d boundary, %d inconsistent, %d non-manifold edges, %d collapsed triangles (%d interior)",
              what, s.boundary, s.inconsistent, s.nonmanifold, s.collapsed, s.interior);
    cr_expect_eq(3 * m->triangle_count, 2 * s.interior, "%s: every edge in exactly two triangles", what);
}

static refl_mesh *teapot(int tess) {
    refl_mesh *m = NULL;
    refl_result r = refl_mesh_teapot(tess, NULL, &m);
    cr_assert_eq(r, REFL_OK, "refl_mesh_teapot(%d) = %d", tess, (int)r);
    check_basic(m, "teapot");
    return m;
}

/* ---- teapot -------------------------------------------------------------------------- */

/* The data's extremes: handle x = -3 and body z = +-2 are control points
   the surface interpolates at patch corners; y = 0 and 3.15 are the
   bottom's and the knob's poles. All are grid points at every tess, so
   they are exact (to float rounding, 1e-6 here). The spout lip's far edge
   is the cubic with control values 3.3, 3.525, 3.45, 3.2 (on y = 0),
   whose maximum 3.4340751 lies at t = 0.410, between grid lines: the grid
   maximum is below it by at most max|x''| h^2 / 8 with h = 1 / tess and
   |x''| <= 6 * 0.3 = 1.8. (3.434375, sometimes quoted, is not the maximum
   of this data: it is 3e-4 too high.) */
Test(refl_shapes, teapot_bounds) {
    static const int tess[] = {1, 2, 4, 8, 16, 32};
    const double xmax = 3.4340751254710957;
    int k, i;
    for (k = 0; k < (int)(sizeof tess / sizeof tess[0]); ++k) {
        refl_mesh *m = teapot(tess[k]);
        float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
        double h = 1.0 / tess[k], slack = 1.8 * h * h / 8.0;
        for (i = 0; i < 3 * m->vertex_count; ++i) {
            lo[i % 3] = fminf(lo[i % 3], m->positions[i]);
            hi[i % 3] = fmaxf(hi[i % 3], m->positions[i]);
        }
        cr_expect(fabs(lo[0] + 3.0) < 1e-6 && fabs(lo[1]) < 1e-6 && fabs(lo[2] + 2.0) < 1e-6,
                  "tess %d: min (%.7f %.7f %.7f), want (-3 0 -2)", tess[k], lo[0], lo[1], lo[2]);
        cr_expect(fabs(hi[1] - 3.15) < 1e-6 && fabs(hi[2] - 2.0) < 1e-6,
                  "tess %d: max y z (%.7f %.7f), want (3.15 2)", tess[k], hi[1], hi[2]);
        cr_expect(hi[0] <= xmax + 1e-6 && hi[0] >= xmax - slack - 1e-6,
                  "tess %d: max x %.7f, want in [%.7f, %.7f]", tess[k], hi[0], xmax - slack, xmax);
        refl_mesh_destroy(m);
    }
}

/* 32 patches x tess^2 cells x 2 triangles, less one per pole cell: the 4
   knob and 4 bottom patches have tess cells each on their pole. */
Test(refl_shapes, teapot_triangle_counts) {
    refl_mesh *m4 = teapot(4), *m8 = teapot(8), *m16 = teapot(16), *m0 = teapot(0);
    cr_expect_eq(m4->triangle_count, 64 * 16 - 8 * 4);
    cr_expect_eq(m8->triangle_count, 64 * 64 - 8 * 8);
    cr_expect_eq(m16->triangle_count, 64 * 256 - 8 * 16);
    cr_expect(m4->triangle_count >= 900 && m4->triangle_count <= 1024);
    cr_expect(m8->triangle_count >= 3900 && m8->triangle_count <= 4096);
    cr_expect(m16->triangle_count >= 15900 && m16->triangle_count <= 16384);
    /* tess 0 is the default, 8 */
    cr_expect_eq(m0->triangle_count, m8->triangle_count);
    cr_expect_eq(m0->vertex_count, m8->vertex_count);
    /* welding: fewer vertices than the 32 (tess + 1)^2 grid points */
    cr_expect_lt(m8->vertex_count, 32 * 81);
    refl_mesh_destroy(m4);
    refl_mesh_destroy(m8);
    refl_mesh_destroy(m16);
    refl_mesh_destroy(m0);
}

/* Analytic normals, CCW winding: every triangle's face normal has a
   positive dot with each of its vertex normals (pole fans included, since
   the pole's normal is the axis). The exceptions are coarse cells across
   the spout's lip, a curl of radius about 0.05 that a quarter-patch cell
   spans at more than 90 degrees: 4 triangles at tess 4 (0.4%), none from
   tess 8 up. (tess 1 and 2 cut corners everywhere and are not held to it.) */
Test(refl_shapes, teapot_normals_agree_with_winding) {
    static const int tess[] = {4, 8, 16, 64};
    int k, t;
    for (k = 0; k < (int)(sizeof tess / sizeof tess[0]); ++k) {
        refl_mesh *m = teapot(tess[k]);
        int bad = winding_disagreements(m), off_lip = 0;
        for (t = 0; t < m->triangle_count; ++t) {
            const float *p = m->positions + 3 * m->indices[3 * t];
            refl_mesh one = *m;
            one.indices += 3 * t;
            one.triangle_count = 1;
            if (winding_disagreements(&one) && !(p[0] > 2.7f && p[1] > 2.35f)) off_lip++;
        }
        cr_expect_eq(off_lip, 0, "tess %d: %d disagreeing triangles off the spout's lip", tess[k], off_lip);
        cr_expect_leq(bad, tess[k] == 4 ? 8 : 0, "tess %d: %d of %d triangles disagree with their vertex normals",
                      tess[k], bad, m->triangle_count);
        refl_mesh_destroy(m);
    }
}

/* Outward, part by part (y up; the handle is at -x, the spout at +x, both
   symmetric about z = 0). */
Test(refl_shapes, teapot_outward) {
    refl_mesh *m = teapot(16);
    int i, body = 0, rim = 0, lid = 0, side = 0, poles = 0, bad = 0;
    for (i = 0; i < m->vertex_count; ++i) {
        const float *p = m->positions + 3 * i, *n = m->normals + 3 * i;
        double r = sqrt((double)p[0] * p[0] + (double)p[2] * p[2]);
        if (p[1] > 0.2f && p[1] < 2.35f && fabsf(p[2]) > 0.7f) {
            /* the body, away from handle and spout: away from the axis */
            body++;
            bad += (p[0] * n[0] + p[2] * n[2]) <= 0.0f;
        } else if (p[1] > 2.47f && r > 1.35 && r < 1.5) {
            /* the top of the rim's curl: up */
            rim++;
            bad += n[1] <= 0.0f;
        } else if (p[1] > 2.5f && r > 0.45 && r < 1.25) {
            /* the lid: up */
            lid++;
            bad += n[1] <= 0.0f;
        } else if ((p[0] < -2.05f || (p[0] > 2.05f && p[1] < 2.39f)) && fabsf(p[2]) > 0.1f) {
            /* the sides of the handle and the spout's tube (its lip above
               y = 2.4 curls inwards): away from the middle plane */
            side++;
            bad += p[2] * n[2] <= 0.0f;
        }
        if (p[0] == 0.0f && p[2] == 0.0f) {
            /* the poles: the knob's top faces up, the bottom's centre down */
            poles++;
            cr_expect(p[1] == 0.0f || p[1] == 3.15f, "pole at y = %g", p[1]);
            cr_expect(fabsf(n[1] - (p[1] > 1.0f ? 1.0f : -1.0f)) < 1e-6f, "pole at y = %g: normal (%g %g %g)",
                      p[1], n[0], n[1], n[2]);
        }
    }
    cr_expect(body > 100 && rim > 10 && lid > 50 && side > 50, "samples: body %d rim %d lid %d side %d", body, rim,
              lid, side);
    cr_expect_eq(poles, 2, "%d vertices on the axis at the poles (one each after welding)", poles);
    cr_expect_eq(bad, 0, "%d vertices with inward normals", bad);
    refl_mesh_destroy(m);
}

/* Welded by position, every edge is used once (an open boundary) or twice
   in opposite directions: the patches are oriented consistently and the
   mesh is connected across patch boundaries. The open boundaries are the
   rim's inner edge (4 patch edges), the lid's lower edge (4), the spout's
   two ends (2 + 2) and the handle's two ends (2 + 2): 16 tess edges.
   (At tess 1 the handle and spout tubes flatten to double-sided quads.) */
Test(refl_shapes, teapot_edges_consistent) {
    static const int tess[] = {2, 4, 8, 16};
    int k;
    for (k = 0; k < (int)(sizeof tess / sizeof tess[0]); ++k) {
        refl_mesh *m = teapot(tess[k]);
        edge_stats s = edge_analysis(m);
        cr_expect_eq(s.inconsistent, 0, "tess %d: %d edges wound the same way twice", tess[k], s.inconsistent);
        cr_expect_eq(s.nonmanifold, 0, "tess %d: %d edges in more than two triangles", tess[k], s.nonmanifold);
        cr_expect_eq(s.collapsed, 0, "tess %d: %d degenerate triangles", tess[k], s.collapsed);
        cr_expect_eq(s.boundary, 16 * tess[k], "tess %d: %d boundary edges, want %d", tess[k], s.boundary,
                     16 * tess[k]);
        refl_mesh_destroy(m);
    }
}

/* The tessellation converges to the patches' area at second order: the
   differences shrink by about 4 per halving of the step (tess 8 is 0.6%
   short of tess 32, tess 16 0.15%). */
Test(refl_shapes, teapot_area_converges) {
    refl_mesh *m8 = teapot(8), *m16 = teapot(16), *m32 = teapot(32);
    double a8 = mesh_area(m8), a16 = mesh_area(m16), a32 = mesh_area(m32);
    double ratio = (a32 - a16) / (a16 - a8);
    cr_expect(a8 < a16 && a16 < a32, "inscribed areas grow: %.6f %.6f %.6f", a8, a16, a32);
    cr_expect(fabs(a8 - a32) / a32 < 1e-2, "tess 8 vs 32: %.6f vs %.6f", a8, a32);
    cr_expect(fabs(a16 - a32) / a32 < 2.5e-3, "tess 16 vs 32: %.6f vs %.6f", a16, a32);
    cr_expect(ratio > 0.15 && ratio < 0.35, "convergence ratio %.3f, want about 1/4", ratio);
    refl_mesh_destroy(m8);
    refl_mesh_destroy(m16);
    refl_mesh_destroy(m32);
}

Test(refl_shapes, teapot_deterministic) {
    refl_mesh *a = teapot(8), *b = teapot(8);
    cr_assert_eq(a->vertex_count, b->vertex_count);
    cr_assert_eq(a->triangle_count, b->triangle_count);
    cr_expect(!memcmp(a->positions, b->positions, 12 * (size_t)a->vertex_count));
    cr_expect(!memcmp(a->normals, b->normals, 12 * (size_t)a->vertex_count));
    cr_expect(!memcmp(a->indices, b->indices, 12 * (size_t)a->triangle_count));
    refl_mesh_destroy(a);
    refl_mesh_destroy(b);
}

/* ---- sphere ------------------------------------------------------------------------------ */

Test(refl_shapes, sphere_geometry) {
    const float r = 2.5f;
    const int slices = 24, stacks = 12;
    refl_mesh *m = NULL;
    int i, c, far = 0, bad_n = 0;
    cr_assert_eq(refl_mesh_sphere(r, slices, stacks, NULL, &m), REFL_OK);
    check_basic(m, "sphere");
    cr_expect_eq(m->vertex_count, 2 * slices + (stacks - 1) * (slices + 1));
    cr_expect_eq(m->triangle_count, 2 * slices * (stacks - 1));
    for (i = 0; i < m->vertex_count; ++i) {
        const float *p = m->positions + 3 * i, *n = m->normals + 3 * i;
        double d = sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]);
        if (fabs(d - r) > 1e-6 * r) far++;
        /* outward: the normal is the direction from the centre */
        for (c = 0; c < 3; ++c)
            if (fabs(n[c] - p[c] / d) > 1e-6) bad_n++;
    }
    cr_expect_eq(far, 0, "%d vertices off the sphere", far);
    cr_expect_eq(bad_n, 0, "%d normals not radial", bad_n);
    cr_expect_eq(winding_disagreements(m), 0);
    refl_mesh_destroy(m);
}

/* u = slice fraction (angle from +x towards -z over 2 pi), v = stack
   fraction from the top (polar angle over pi). */
Test(refl_shapes, sphere_texcoords) {
    refl_mesh *m = NULL;
    int i, bad = 0, seam = 0;
    cr_assert_eq(refl_mesh_sphere(1.0f, 16, 8, NULL, &m), REFL_OK);
    cr_assert_not_null(m->texcoords);
    for (i = 0; i < m->vertex_count; ++i) {
        const float *p = m->positions + 3 * i, *uv = m->texcoords + 2 * i;
        double v = acos(fmax(-1.0, fmin(1.0, (double)p[1]))) / PI, u;
        if (fabs(uv[1] - v) > 1e-5) bad++;
        if (fabs(p[1]) > 0.999f) continue; /* poles: u is the middle of the slice */
        u = atan2(-(double)p[2], (double)p[0]) / (2.0 * PI);
        if (u < -1e-6) u += 1.0;
        if (fabs(u) < 1e-6 && uv[0] > 0.5f) {
            u = 1.0; /* the seam column repeats u = 0 as u = 1 */
            seam++;
        }
        if (fabs(uv[0] - u) > 1e-5) bad++;
    }
    cr_expect_eq(bad, 0, "%d vertices with texcoords off", bad);
    cr_expect_eq(seam, 7, "seam vertices: %d", seam);
    refl_mesh_destroy(m);
}

/* The inscribed polyhedron's area rises to 4 pi r^2. */
Test(refl_shapes, sphere_area_converges) {
    static const int res[] = {8, 32, 128};
    const float r = 1.5f;
    double want = 4.0 * PI * r * r, prev = 1.0;
    int k;
    for (k = 0; k < 3; ++k) {
        refl_mesh *m = NULL;
        double err;
        cr_assert_eq(refl_mesh_sphere(r, 2 * res[k], res[k], NULL, &m), REFL_OK);
        err = (want - mesh_area(m)) / want;
        cr_expect(err > 0.0 && err < prev / 10.0, "slices %d: relative area error %g (previous %g)", 2 * res[k], err,
                  prev);
        prev = err;
        refl_mesh_destroy(m);
    }
    cr_expect_lt(prev, 2e-4);
}

Test(refl_shapes, sphere_closed_and_volume) {
    static const int shape[][2] = {{3, 2}, {4, 3}, {17, 9}, {64, 32}};
    int k;
    for (k = 0; k < 4; ++k) {
        refl_mesh *m = NULL;
        double v;
        cr_assert_eq(refl_mesh_sphere(1.0f, shape[k][0], shape[k][1], NULL, &m), REFL_OK);
        check_basic(m, "sphere");
        expect_closed(m, "sphere");
        cr_expect_eq(winding_disagreements(m), 0, "sphere %d x %d", shape[k][0], shape[k][1]);
        v = mesh_volume(m);
        cr_expect(v > 0.0 && v < 4.0 / 3.0 * PI, "sphere %d x %d: volume %g", shape[k][0], shape[k][1], v);
        if (k == 3) cr_expect(fabs(v - 4.0 / 3.0 * PI) / (4.0 / 3.0 * PI) < 5e-3, "volume %g", v);
        refl_mesh_destroy(m);
    }
}

/* ---- torus -------------------------------------------------------------------------------- */

Test(refl_shapes, torus_geometry) {
    const float R = 2.0f, r = 0.5f;
    refl_mesh *m = NULL;
    int i, c, bad_d = 0, bad_n = 0, bad_uv = 0;
    cr_assert_eq(refl_mesh_torus(R, r, 32, 16, NULL, &m), REFL_OK);
    check_basic(m, "torus");
    cr_expect_eq(m->triangle_count, 2 * 32 * 16);
    cr_assert_not_null(m->texcoords);
    for (i = 0; i < m->vertex_count; ++i) {
        const float *p = m->positions + 3 * i, *n = m->normals + 3 * i;
        double rho = sqrt((double)p[0] * p[0] + (double)p[2] * p[2]);
        double cc[3] = {R * p[0] / rho, 0.0, R * p[2] / rho}, d[3], l; /* nearest point of the core circle */
        for (c = 0; c < 3; ++c) d[c] = p[c] - cc[c];
        l = vlen(d);
        if (fabs(l - r) > 1e-6) bad_d++;
        /* outward: away from the core circle */
        for (c = 0; c < 3; ++c)
            if (fabs(n[c] - d[c] / l) > 1e-5) bad_n++;
        if (m->texcoords[2 * i] < 0.0f || m->texcoords[2 * i] > 1.0f || m->texcoords[2 * i + 1] < 0.0f ||
            m->texcoords[2 * i + 1] > 1.0f)
            bad_uv++;
    }
    cr_expect_eq(bad_d, 0, "%d vertices off the tube", bad_d);
    cr_expect_eq(bad_n, 0, "%d normals not pointing away from the core circle", bad_n);
    cr_expect_eq(bad_uv, 0);
    cr_expect_eq(winding_disagreements(m), 0);
    refl_mesh_destroy(m);
}

/* Closed, CCW outside: the volume tends to 2 pi^2 R r^2, the area to
   4 pi^2 R r, both from below for the inscribed polyhedron, short by
   about (2 pi / sides)^2 / 6 = 1.6e-3 for the tube's 64-gon plus less for
   the 128 slices. */
Test(refl_shapes, torus_closed_and_volume) {
    const double R = 3.0, r = 1.0, vol = 2.0 * PI * PI * R * r * r, area = 4.0 * PI * PI * R * r;
    refl_mesh *m = NULL;
    double v, a;
    cr_assert_eq(refl_mesh_torus(3.0f, 1.0f, 3, 3, NULL, &m), REFL_OK);
    expect_closed(m, "torus 3 x 3");
    cr_expect_gt(mesh_volume(m), 0.0);
    refl_mesh_destroy(m);
    cr_assert_eq(refl_mesh_torus(3.0f, 1.0f, 128, 64, NULL, &m), REFL_OK);
    expect_closed(m, "torus");
    v = mesh_volume(m);
    a = mesh_area(m);
    cr_expect(v < vol && (vol - v) / vol < 3e-3, "volume %g, want %g", v, vol);
    cr_expect(a < area && (area - a) / area < 3e-3, "area %g, want %g", a, area);
    refl_mesh_destroy(m);
}

/* ---- box ---------------------------------------------------------------------------------- */

Test(refl_shapes, box_faces) {
    refl_mesh *m = NULL;
    const float s[3] = {1.0f, 2.0f, 3.0f};
    int i, t, k, c, corners[6] = {0};
    cr_assert_eq(refl_mesh_box(refl_v3(s[0], s[1], s[2]), NULL, &m), REFL_OK);
    check_basic(m, "box");
    cr_expect_eq(m->vertex_count, 24);
    cr_expect_eq(m->triangle_count, 12);
    cr_assert_not_null(m->texcoords);
    for (i = 0; i < 24; ++i) {
        const float *p = m->positions + 3 * i, *n = m->normals + 3 * i, *uv = m->texcoords + 2 * i;
        int axes = 0;
        for (c = 0; c < 3; ++c) {
            cr_expect(fabsf(fabsf(p[c]) - 0.5f * s[c]) == 0.0f, "corner %d off the box", i);
            axes += n[c] != 0.0f;
        }
        /* flat: the normal is an axis, pointing away from the centre */
        cr_expect_eq(axes, 1, "vertex %d normal (%g %g %g)", i, n[0], n[1], n[2]);
        cr_expect_gt(p[0] * n[0] + p[1] * n[1] + p[2] * n[2], 0.0f);
        cr_expect((uv[0] == 0.0f || uv[0] == 1.0f) && (uv[1] == 0.0f || uv[1] == 1.0f));
        corners[i / 4] |= 1 << (int)(2 * uv[0] + uv[1]);
    }
    /* each face: the four texcoord corners, all its vertices sharing one
       normal, and its triangles' face normals along it */
    for (i = 0; i < 6; ++i) cr_expect_eq(corners[i], 15, "face %d texcoords", i);
    for (t = 0; t < 12; ++t) {
        double fn[3], l;
        face_normal(m, t, fn);
        l = vlen(fn);
        for (k = 0; k < 3; ++k) {
            const float *n = m->normals + 3 * m->indices[3 * t + k];
            cr_expect(fabs((fn[0] * n[0] + fn[1] * n[1] + fn[2] * n[2]) / l - 1.0) < 1e-6, "triangle %d", t);
        }
    }
    refl_mesh_destroy(m);
}

/* Divergence theorem: the volume is the product of the sides exactly
   when every face is wound counter-clockwise from outside. */
Test(refl_shapes, box_volume_and_closed) {
    static const float sizes[][3] = {{1, 1, 1}, {1, 2, 3}, {0.25f, 10, 0.5f}};
    int k;
    for (k = 0; k < 3; ++k) {
        refl_mesh *m = NULL;
        double want = (double)sizes[k][0] * sizes[k][1] * sizes[k][2], area;
        cr_assert_eq(refl_mesh_box(refl_v3(sizes[k][0], sizes[k][1], sizes[k][2]), NULL, &m), REFL_OK);
        cr_expect(fabs(mesh_volume(m) - want) <= 1e-6 * want, "volume %g, want %g", mesh_volume(m), want);
        area = 2.0 * ((double)sizes[k][0] * sizes[k][1] + (double)sizes[k][1] * sizes[k][2] +
                      (double)sizes[k][0] * sizes[k][2]);
        cr_expect(fabs(mesh_area(m) - area) <= 1e-6 * area);
        expect_closed(m, "box");
        refl_mesh_destroy(m);
    }
}

/* ---- plane -------------------------------------------------------------------------------- */

Test(refl_shapes, plane_geometry) {
    static const int divs[] = {1, 3, 10};
    int k, i, t;
    for (k = 0; k < 3; ++k) {
        const float size = 4.0f;
        int d = divs[k];
        refl_mesh *m = NULL;
        float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
        edge_stats s;
        cr_assert_eq(refl_mesh_plane(size, d, NULL, &m), REFL_OK);
        check_basic(m, "plane");
        cr_expect_eq(m->vertex_count, (d + 1) * (d + 1));
        cr_expect_eq(m->triangle_count, 2 * d * d);
        cr_assert_not_null(m->texcoords);
        for (i = 0; i < m->vertex_count; ++i) {
            const float *p = m->positions + 3 * i, *n = m->normals + 3 * i, *uv = m->texcoords + 2 * i;
            int c;
            for (c = 0; c < 3; ++c) {
                lo[c] = fminf(lo[c], p[c]);
                hi[c] = fmaxf(hi[c], p[c]);
            }
            cr_expect(n[0] == 0.0f && n[1] == 1.0f && n[2] == 0.0f);
            /* texcoords run 0..1 with x and z */
            cr_expect(fabsf(uv[0] - (p[0] / size + 0.5f)) < 1e-6f && fabsf(uv[1] - (p[2] / size + 0.5f)) < 1e-6f,
                      "vertex %d: uv (%g %g) at (%g %g)", i, uv[0], uv[1], p[0], p[2]);
        }
        cr_expect(lo[0] == -2.0f && lo[1] == 0.0f && lo[2] == -2.0f && hi[0] == 2.0f && hi[1] == 0.0f && hi[2] == 2.0f);
        for (t = 0; t < m->triangle_count; ++t) {
            double fn[3];
            face_normal(m, t, fn);
            cr_expect(fn[1] > 0.0 && fn[0] == 0.0 && fn[2] == 0.0, "triangle %d faces -y or sideways", t);
        }
        cr_expect(fabs(mesh_area(m) - 16.0) < 1e-5);
        s = edge_analysis(m);
        cr_expect(s.boundary == 4 * d && s.inconsistent == 0 && s.nonmanifold == 0);
        refl_mesh_destroy(m);
    }
}

/* ---- errors -------------------------------------------------------------------------------- */

#define EXPECT_FAIL(call, code)                                                                   \
    do {                                                                                          \
        refl_mesh *m_ = (refl_mesh *)(uintptr_t)1;                                                \
        refl_result r_ = call(&m_);                                                               \
        cr_expect_eq(r_, code, "%s: %d, want %d", #call, (int)r_, (int)(code));                   \
        cr_expect_null(m_, "%s: output not cleared", #call);                                      \
        if (r_ == REFL_OK && m_ && m_ != (refl_mesh *)(uintptr_t)1) refl_mesh_destroy(m_);        \
    } while (0)

static refl_result teapot_m1(refl_mesh **o) { return refl_mesh_teapot(-1, NULL, o); }
static refl_result teapot_65(refl_mesh **o) { return refl_mesh_teapot(65, NULL, o); }
static refl_result teapot_big(refl_mesh **o) { return refl_mesh_teapot(1 << 20, NULL, o); }
static refl_result sphere_r0(refl_mesh **o) { return refl_mesh_sphere(0.0f, 8, 4, NULL, o); }
static refl_result sphere_rneg(refl_mesh **o) { return refl_mesh_sphere(-1.0f, 8, 4, NULL, o); }
static refl_result sphere_rnan(refl_mesh **o) { return refl_mesh_sphere(NAN, 8, 4, NULL, o); }
static refl_result sphere_rinf(refl_mesh **o) { return refl_mesh_sphere(INFINITY, 8, 4, NULL, o); }
static refl_result sphere_sl2(refl_mesh **o) { return refl_mesh_sphere(1.0f, 2, 4, NULL, o); }
static refl_result sphere_st1(refl_mesh **o) { return refl_mesh_sphere(1.0f, 8, 1, NULL, o); }
static refl_result sphere_huge(refl_mesh **o) { return refl_mesh_sphere(1.0f, 1 << 13, 1 << 12, NULL, o); }
static refl_result sphere_max(refl_mesh **o) { return refl_mesh_sphere(1.0f, INT_MAX, INT_MAX, NULL, o); }
static refl_result torus_minor0(refl_mesh **o) { return refl_mesh_torus(1.0f, 0.0f, 8, 8, NULL, o); }
static refl_result torus_major_nan(refl_mesh **o) { return refl_mesh_torus(NAN, 0.5f, 8, 8, NULL, o); }
static refl_result torus_horn(refl_mesh **o) { return refl_mesh_torus(1.0f, 1.0f, 8, 8, NULL, o); }
static refl_result torus_spindle(refl_mesh **o) { return refl_mesh_torus(1.0f, 2.0f, 8, 8, NULL, o); }
static refl_result torus_sl2(refl_mesh **o) { return refl_mesh_torus(1.0f, 0.5f, 2, 8, NULL, o); }
static refl_result torus_sd2(refl_mesh **o) { return refl_mesh_torus(1.0f, 0.5f, 8, 2, NULL, o); }
static refl_result torus_huge(refl_mesh **o) { return refl_mesh_torus(1.0f, 0.5f, 1 << 12, 1 << 12, NULL, o); }
static refl_result box_zero(refl_mesh **o) { return refl_mesh_box(refl_v3(1.0f, 0.0f, 1.0f), NULL, o); }
static refl_result box_neg(refl_mesh **o) { return refl_mesh_box(refl_v3(1.0f, 1.0f, -1.0f), NULL, o); }
static refl_result box_nan(refl_mesh **o) { return refl_mesh_box(refl_v3(NAN, 1.0f, 1.0f), NULL, o); }
static refl_result box_inf(refl_mesh **o) { return refl_mesh_box(refl_v3(1.0f, INFINITY, 1.0f), NULL, o); }
static refl_result plane_zero(refl_mesh **o) { return refl_mesh_plane(0.0f, 4, NULL, o); }
static refl_result plane_nan(refl_mesh **o) { return refl_mesh_plane(NAN, 4, NULL, o); }
static refl_result plane_d0(refl_mesh **o) { return refl_mesh_plane(1.0f, 0, NULL, o); }
static refl_result plane_dneg(refl_mesh **o) { return refl_mesh_plane(1.0f, -3, NULL, o); }
static refl_result plane_huge(refl_mesh **o) { return refl_mesh_plane(1.0f, 1 << 12, NULL, o); }
static refl_result plane_max(refl_mesh **o) { return refl_mesh_plane(1.0f, INT_MAX, NULL, o); }

Test(refl_shapes, invalid_arguments) {
    EXPECT_FAIL(teapot_m1, REFL_ERROR_INVALID_ARGUMENT);
    EXPECT_FAIL(teapot_65, REFL_ERROR_INVALID_ARGUMENT);
    EXPECT_FAIL(teapot_big, REFL_ERROR_INVALID_ARGUMENT);
    EXPECT_FAIL(sphere_r0, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(sphere_rneg, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(sphere_rnan, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(sphere_rinf, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(sphere_sl2, REFL_ERROR_INVALID_ARGUMENT);
    EXPECT_FAIL(sphere_st1, REFL_ERROR_INVALID_ARGUMENT);
    EXPECT_FAIL(sphere_huge, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(sphere_max, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(torus_minor0, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(torus_major_nan, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(torus_horn, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(torus_spindle, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(torus_sl2, REFL_ERROR_INVALID_ARGUMENT);
    EXPECT_FAIL(torus_sd2, REFL_ERROR_INVALID_ARGUMENT);
    EXPECT_FAIL(torus_huge, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(box_zero, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(box_neg, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(box_nan, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(box_inf, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(plane_zero, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(plane_nan, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(plane_d0, REFL_ERROR_INVALID_ARGUMENT);
    EXPECT_FAIL(plane_dneg, REFL_ERROR_INVALID_ARGUMENT);
    EXPECT_FAIL(plane_huge, REFL_ERROR_INVALID_SIZE);
    EXPECT_FAIL(plane_max, REFL_ERROR_INVALID_SIZE);
    /* no output pointer */
    cr_expect_eq(refl_mesh_teapot(8, NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_mesh_sphere(1.0f, 8, 4, NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_mesh_torus(1.0f, 0.5f, 8, 8, NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_mesh_box(refl_v3(1, 1, 1), NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_mesh_plane(1.0f, 1, NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
}

/* The smallest and largest accepted parameters work. */
Test(refl_shapes, limits_accepted) {
    refl_mesh *m = NULL;
    cr_expect_eq(refl_mesh_teapot(1, NULL, &m), REFL_OK);
    refl_mesh_destroy(m);
    cr_expect_eq(refl_mesh_teapot(64, NULL, &m), REFL_OK);
    cr_expect_eq(m->triangle_count, 64 * 64 * 64 - 8 * 64);
    refl_mesh_destroy(m);
    cr_expect_eq(refl_mesh_plane(1e-20f, 1, NULL, &m), REFL_OK);
    refl_mesh_destroy(m);
    cr_expect_eq(refl_mesh_box(refl_v3(1e-30f, 1e30f, 1.0f), NULL, &m), REFL_OK);
    refl_mesh_destroy(m);
}

/* ---- allocation failure ----------------------------------------------------------------------- */

static refl_result make_shape(int which, const refl_allocator *a, refl_mesh **out) {
    switch (which) {
    case 0: return refl_mesh_teapot(3, a, out);
    case 1: return refl_mesh_sphere(1.0f, 7, 5, a, out);
    case 2: return refl_mesh_torus(2.0f, 0.5f, 6, 5, a, out);
    case 3: return refl_mesh_box(refl_v3(1, 2, 3), a, out);
    default: return refl_mesh_plane(2.0f, 3, a, out);
    }
}

/* Every allocation, in turn, fails: the call reports OUT_OF_MEMORY, clears
   the output and frees what it took; the successful mesh is freed through
   the same allocator by refl_mesh_destroy. */
Test(refl_shapes, allocation_failure_every_index) {
    int which;
    for (which = 0; which < 5; ++which) {
        counting c;
        refl_allocator a = counting_allocator(&c, -1);
        refl_mesh *m = NULL;
        long total, k;
        cr_assert_eq(make_shape(which, &a, &m), REFL_OK, "shape %d", which);
        total = c.calls;
        cr_expect_gt(total, 0, "shape %d allocates through the allocator", which);
        cr_expect_gt(c.live, 0);
        refl_mesh_destroy(m);
        cr_expect_eq(c.live, 0, "shape %d: %ld allocations leaked by destroy", which, c.live);
        for (k = 0; k < total; ++k) {
            refl_result r;
            a = counting_allocator(&c, k);
            m = (refl_mesh *)(uintptr_t)1;
            r = make_shape(which, &a, &m);
            cr_expect_eq(r, REFL_ERROR_OUT_OF_MEMORY, "shape %d, failing allocation %ld: %d", which, k, (int)r);
            cr_expect_null(m, "shape %d, failing allocation %ld: output set", which, k);
            cr_expect_eq(c.live, 0, "shape %d, failing allocation %ld: %ld leaked", which, k, c.live);
            if (r == REFL_OK) refl_mesh_destroy(m);
        }
    }
}
