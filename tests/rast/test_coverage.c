/* Coverage: watertightness and the top-left fill rule.

   The stencil buffer is used as a per-pixel hit counter (stencil test ALWAYS,
   pass op INCR, no colour target at all), so a crack shows up as a 0 and a
   double hit on a shared edge or vertex as a 2. Every expectation is computed
   from geometry in the test (point-in-polygon, an independent reference of
   the top-left rule), never from captured output. */
#include "../test_util.h"

/* ---- meshes ------------------------------------------------------------- */

typedef struct mesh {
    int nv, nt;
    double *xy;  /* 2 per vertex, image coordinates */
    double *w;   /* clip w per vertex (1 for all when NULL) */
    int *tri;    /* 3 per triangle */
} mesh;

static void mesh_free(mesh *m) {
    free(m->xy);
    free(m->w);
    free(m->tri);
    memset(m, 0, sizeof *m);
}

/* Randomly reverses the winding of about half of the triangles: the fill
   rule and watertightness must not depend on orientation (with culling off
   both orientations are drawn). Also rotates the vertex order. */
static void mesh_scramble(mesh *m, tu_rng *rng) {
    int t;
    for (t = 0; t < m->nt; t++) {
        int *v = m->tri + 3 * t, k;
        if (tu_rng_u32(rng) & 1) {
            int s = v[1];
            v[1] = v[2];
            v[2] = s;
        }
        for (k = tu_rng_int(rng, 0, 2); k > 0; k--) {
            int s = v[0];
            v[0] = v[1];
            v[1] = v[2];
            v[2] = s;
        }
    }
}

/* Sum of |area| of all triangles; for a valid subdivision of a polygon it
   equals the polygon's area (no overlaps, no folds). Used as a sanity check
   of the generators, so a broken generator cannot make a test vacuous. */
static double mesh_abs_area(const mesh *m) {
    double s = 0;
    int t;
    for (t = 0; t < m->nt; t++) {
        const int *v = m->tri + 3 * t;
        s += fabs(tu_area_img(m->xy[2 * v[0]], m->xy[2 * v[0] + 1], m->xy[2 * v[1]],
                              m->xy[2 * v[1] + 1], m->xy[2 * v[2]], m->xy[2 * v[2] + 1]));
    }
    return 0.5 * s;
}

/* Jittered grid over the rectangle [x0, x1] x [y0, y1] with nx x ny cells.
   Boundary vertices only slide along the boundary (so the outer boundary
   stays exactly the rectangle); interior vertices jitter in both axes by at
   most 0.2 cell, which keeps every triangle non-inverted. half_grid: all
   positions are multiples of 0.5 pixel, so many edges and vertices pass
   exactly through pixel centres (the fill rule must then break the tie);
   otherwise positions are arbitrary floats (the rasteriser snaps them, the
   same way for both triangles sharing an edge). Each cell is split along a
   random diagonal. */
static void mesh_grid(mesh *m, tu_rng *rng, int nx, int ny, double x0, double y0, double x1,
                      double y1, int half_grid, int perspective) {
    int i, j, t = 0;
    double cw = (x1 - x0) / nx, ch = (y1 - y0) / ny;
    memset(m, 0, sizeof *m);
    m->nv = (nx + 1) * (ny + 1);
    m->nt = 2 * nx * ny;
    m->xy = (double *)malloc(sizeof(double) * 2 * (size_t)m->nv);
    m->tri = (int *)malloc(sizeof(int) * 3 * (size_t)m->nt);
    cr_assert(m->xy && m->tri);
    if (perspective) {
        m->w = (double *)malloc(sizeof(double) * (size_t)m->nv);
        cr_assert_not_null(m->w);
    }
    for (j = 0; j <= ny; j++)
        for (i = 0; i <= nx; i++) {
            double x = x0 + i * cw, y = y0 + j * ch;
            double jx, jy;
            if (half_grid) {
                jx = 0.5 * tu_rng_int(rng, -1, 1);
                jy = 0.5 * tu_rng_int(rng, -1, 1);
            } else {
                jx = tu_rng_range(rng, -0.2, 0.2) * cw;
                jy = tu_rng_range(rng, -0.2, 0.2) * ch;
            }
            if (i > 0 && i < nx) x += jx;
            if (j > 0 && j < ny) y += jy;
            m->xy[2 * (j * (nx + 1) + i)] = x;
            m->xy[2 * (j * (nx + 1) + i) + 1] = y;
            if (m->w) m->w[j * (nx + 1) + i] = tu_rng_range(rng, 0.5, 3.0);
        }
    for (j = 0; j < ny; j++)
        for (i = 0; i < nx; i++) {
            int a = j * (nx + 1) + i, b = a + 1, d = a + nx + 1, c = d + 1;
            int *v = m->tri + 3 * t;
            if (tu_rng_u32(rng) & 1) {
                v[0] = a; v[1] = b; v[2] = c;
                v[3] = a; v[4] = c; v[5] = d;
            } else {
                v[0] = a; v[1] = b; v[2] = d;
                v[3] = b; v[4] = c; v[5] = d;
            }
            t += 2;
        }
    /* generator sanity: no inverted triangles, total area = rectangle */
    for (t = 0; t < m->nt; t++) {
        const int *v = m->tri + 3 * t;
        double a = tu_area_img(m->xy[2 * v[0]], m->xy[2 * v[0] + 1], m->xy[2 * v[1]],
                               m->xy[2 * v[1] + 1], m->xy[2 * v[2]], m->xy[2 * v[2] + 1]);
        cr_assert(a > 0.0, "generator produced an inverted triangle");
    }
    cr_assert(fabs(mesh_abs_area(m) - (x1 - x0) * (y1 - y0)) < 1e-6 * (x1 - x0) * (y1 - y0));
    mesh_scramble(m, rng);
}

/* Two concentric rings around (ox, oy): a fan of n1 triangles around the
   apex (cx, cy) (inside the inner ring; the tests put it exactly on a pixel
   centre so that n1 triangles meet at a sampled point), then the annulus
   between the inner ring (n1 vertices, radius r1) and the outer ring (n2,
   radius r2) zipped by angle. snap: vertex positions are rounded to this
   grid (1/256 for sub-pixel, 0.5 for "through pixel centres"). The outer
   ring is the mesh boundary, m->xy[2*first_outer...]. */
static void mesh_rings(mesh *m, tu_rng *rng, double ox, double oy, double cx, double cy,
                       int n1, double r1, int n2, double r2, double snap, int *first_outer) {
    int k, i, j, t = 0;
    const double two_pi = 6.283185307179586;
    double *ang = (double *)malloc(sizeof(double) * (size_t)(n1 + n2));
    cr_assert_not_null(ang);
    memset(m, 0, sizeof *m);
    m->nv = 1 + n1 + n2;
    m->nt = n1 + n1 + n2;
    m->xy = (double *)malloc(sizeof(double) * 2 * (size_t)m->nv);
    m->tri = (int *)malloc(sizeof(int) * 3 * (size_t)m->nt);
    cr_assert(m->xy && m->tri);
    m->xy[0] = cx;
    m->xy[1] = cy;
    for (k = 0; k < n1 + n2; k++) {
        int inner = k < n1;
        int n = inner ? n1 : n2, idx = inner ? k : k - n1;
        double r = inner ? r1 : r2;
        double a = two_pi * (idx + tu_rng_range(rng, 0.0, 0.45)) / n;
        double x = ox + r * cos(a), y = oy + r * sin(a);
        ang[k] = a;
        m->xy[2 * (1 + k)] = floor(x / snap + 0.5) * snap;
        m->xy[2 * (1 + k) + 1] = floor(y / snap + 0.5) * snap;
    }
    /* fan around the apex */
    for (k = 0; k < n1; k++) {
        m->tri[3 * t] = 0;
        m->tri[3 * t + 1] = 1 + k;
        m->tri[3 * t + 2] = 1 + (k + 1) % n1;
        t++;
    }
    /* zip inner and outer rings by (generation) angle */
    i = 0;
    j = 0;
    while (i < n1 || j < n2) {
        int ii = 1 + i % n1, in = 1 + (i + 1) % n1;
        int jj = 1 + n1 + j % n2, jn = 1 + n1 + (j + 1) % n2;
        double ai = ang[(i + 1) % n1] + (i + 1 >= n1 ? two_pi : 0.0);
        double aj = ang[n1 + (j + 1) % n2] + (j + 1 >= n2 ? two_pi : 0.0);
        if (j >= n2 || (i < n1 && ai <= aj)) {
            m->tri[3 * t] = ii;
            m->tri[3 * t + 1] = jj;
            m->tri[3 * t + 2] = in;
            i++;
        } else {
            m->tri[3 * t] = ii;
            m->tri[3 * t + 1] = jj;
            m->tri[3 * t + 2] = jn;
            j++;
        }
        t++;
    }
    cr_assert_eq(t, m->nt);
    free(ang);
    *first_outer = 1 + n1;
    mesh_scramble(m, rng);
}

/* Crossing-number point-in-polygon, exact for dyadic inputs. Returns 1
   strictly inside, 0 strictly outside, -1 exactly on the boundary. */
static int point_in_polygon(const double *xy, int n, double px, double py) {
    int i, c = 0;
    for (i = 0; i < n; i++) {
        double ax = xy[2 * i], ay = xy[2 * i + 1];
        double bx = xy[2 * ((i + 1) % n)], by = xy[2 * ((i + 1) % n) + 1];
        double cr = (bx - ax) * (py - ay) - (by - ay) * (px - ax);
        if (cr == 0.0 && px >= fmin(ax, bx) && px <= fmax(ax, bx) && py >= fmin(ay, by) &&
            py <= fmax(ay, by))
            return -1;
        if ((ay > py) != (by > py)) {
            double xi = ax + (py - ay) * (bx - ax) / (by - ay);
            if (px < xi) c ^= 1;
        }
    }
    return c;
}

/* Draws the mesh (indexed or as a plain triangle list) with the counting
   stencil state into a stencil-only target. */
static void draw_mesh(rast_context *ctx, int vw, int vh, const mesh *m, int indexed) {
    rast_state s;
    rast_draw_desc d;
    rast_result r;
    int n = indexed ? m->nv : 3 * m->nt, i;
    float *v = (float *)malloc(sizeof(float) * 4 * (size_t)n);
    uint32_t *idx = NULL;
    cr_assert_not_null(v);
    tu_state_count(&s);
    tu_set_state(ctx, &s);
    for (i = 0; i < n; i++) {
        int src = indexed ? i : m->tri[i];
        tu_clip_from_window(v + 4 * i, m->xy[2 * src], m->xy[2 * src + 1], 0.0,
                            m->w ? m->w[src] : 1.0, vw, vh);
    }
    memset(&d, 0, sizeof d);
    d.primitive = RAST_TRIANGLES;
    d.vertices = v;
    d.vertex_count = n;
    d.stride = 4;
    if (indexed) {
        idx = (uint32_t *)malloc(sizeof(uint32_t) * 3 * (size_t)m->nt);
        cr_assert_not_null(idx);
        for (i = 0; i < 3 * m->nt; i++) idx[i] = (uint32_t)m->tri[i];
        d.indices = idx;
        d.index_count = 3 * m->nt;
    }
    r = rast_draw(ctx, &d);
    cr_assert_eq(r, RAST_OK, "rast_draw = %d", (int)r);
    tu_finish(ctx);
    free(v);
    free(idx);
}

/* ---- watertightness ---------------------------------------------------- */

/* Grid meshes: inside the rectangle every pixel centre must be hit exactly
   once, outside never. Runs several thread/tile configurations because tile
   borders are where per-tile edge stepping typically goes wrong. */
static void check_grid(int half_grid, int perspective, int indexed, uint64_t seed) {
    static const int cfg[][2] = {{1, 16}, {2, 16}, {3, 32}, {2, 64}, {1, 128}};
    const int W = 128, H = 128;
    /* boundaries at non-centre coordinates, so "strictly inside" is exact */
    const double x0 = 4.0, y0 = 3.0, x1 = 124.0, y1 = 126.0;
    mesh m;
    tu_rng rng = tu_rng_make(seed);
    size_t c;
    mesh_grid(&m, &rng, 40, 41, x0, y0, x1, y1, half_grid, perspective);
    cr_assert(m.nt >= 3000, "thousands of triangles");
    for (c = 0; c < sizeof cfg / sizeof cfg[0]; c++) {
        rast_context *ctx = tu_ctx(cfg[c][0], cfg[c][1]);
        tu_fb fb;
        tu_check chk = {0, {0}};
        int x, y;
        tu_fb_init(&fb, W, H, TU_STENCIL);
        tu_fb_bind(ctx, &fb);
        draw_mesh(ctx, W, H, &m, indexed);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                double px = x + 0.5, py = y + 0.5;
                int inside = px > x0 && px < x1 && py > y0 && py < y1;
                int got = *tu_sten(&fb, x, y);
                TU_CHECK(&chk, got == inside,
                         "threads %d tile %d: pixel (%d,%d) hit %d times, expected %d",
                         cfg[c][0], cfg[c][1], x, y, got, inside);
            }
        TU_CHECK_DONE(&chk);
        rast_context_destroy(ctx);
        tu_fb_free(&fb);
    }
    mesh_free(&m);
}

Test(coverage, watertight_grid_subpixel) { check_grid(0, 0, 0, 1); }
Test(coverage, watertight_grid_subpixel_indexed) { check_grid(0, 0, 1, 2); }
/* positions on the half-pixel grid: edges and vertices through centres */
Test(coverage, watertight_grid_through_centres) { check_grid(1, 0, 1, 3); }
/* random clip w per vertex: shared vertices are still bit-identical 4-vectors,
   so the projected mesh is still a partition */
Test(coverage, watertight_grid_perspective) { check_grid(0, 1, 0, 4); }

/* Ring meshes: a fan of many triangles meeting at an apex that lies exactly
   on a pixel centre (exactly one of them must own that centre), plus an
   annulus zipped between rings with different vertex counts. */
static void check_rings(double snap, int n1, int n2, uint64_t seed) {
    const int W = 128, H = 128;
    mesh m;
    tu_rng rng = tu_rng_make(seed);
    int first_outer, x, y, c;
    long inside_count = 0;
    static const int cfg[][2] = {{1, 16}, {3, 32}, {2, 64}};
    mesh_rings(&m, &rng, 64.0, 64.0, 60.5, 66.5, n1, 30.0, n2, 58.0, snap, &first_outer);
    /* generator sanity: the mesh exactly tiles the outer polygon */
    {
        double poly = 0;
        int i;
        for (i = 0; i < n2; i++) {
            const double *a = m.xy + 2 * (first_outer + i);
            const double *b = m.xy + 2 * (first_outer + (i + 1) % n2);
            poly += a[0] * b[1] - b[0] * a[1];
        }
        poly = fabs(poly) * 0.5;
        cr_assert(fabs(mesh_abs_area(&m) - poly) < 1e-6 * poly, "ring mesh overlaps: %g vs %g",
                  mesh_abs_area(&m), poly);
    }
    for (c = 0; c < 3; c++) {
        rast_context *ctx = tu_ctx(cfg[c][0], cfg[c][1]);
        tu_fb fb;
        tu_check chk = {0, {0}};
        tu_fb_init(&fb, W, H, TU_STENCIL);
        tu_fb_bind(ctx, &fb);
        draw_mesh(ctx, W, H, &m, c & 1);
        inside_count = 0;
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                int in = point_in_polygon(m.xy + 2 * first_outer, n2, x + 0.5, y + 0.5);
                int got = *tu_sten(&fb, x, y);
                if (in < 0) {
                    /* centre on the outer boundary: the fill rule decides,
                       but never more than one hit */
                    TU_CHECK(&chk, got <= 1, "boundary pixel (%d,%d) hit %d times", x, y, got);
                    continue;
                }
                inside_count += in;
                TU_CHECK(&chk, got == in, "pixel (%d,%d) hit %d times, expected %d", x, y,
                         got, in);
            }
        TU_CHECK_DONE(&chk);
        cr_assert_eq(*tu_sten(&fb, 60, 66), 1, "the apex centre (60.5,66.5) must be hit once");
        rast_context_destroy(ctx);
        tu_fb_free(&fb);
    }
    cr_assert(inside_count > 9000, "test must cover a substantial area");
    mesh_free(&m);
}

Test(coverage, watertight_fan_and_rings_subpixel) { check_rings(1.0 / 256.0, 509, 700, 11); }
Test(coverage, watertight_fan_and_rings_half_pixel) { check_rings(0.5, 61, 97, 12); }

/* ---- the top-left rule by hand ---------------------------------------- */

/* Draws one list of image-space triangles and compares the hit counts with
   the given expectation callback. */
static void draw_counted(rast_context *ctx, tu_fb *fb, const double *xy, int ntri) {
    rast_state s;
    memset(fb->stencil, 0, (size_t)fb->w * fb->h);
    tu_state_count(&s);
    tu_set_state(ctx, &s);
    tu_draw_tris_px(ctx, fb->w, fb->h, xy, ntri, 0.0);
}

/* A right triangle with a horizontal top edge at y = 1.5 and a vertical left
   edge at x = 1.5 (both through pixel centres, both included), and the
   hypotenuse x + y = 11 through centres (interior on its left, so it is a
   RIGHT edge: excluded). Then the complementary triangle, whose hypotenuse
   is a LEFT edge (included) and whose bottom (y = 9.5) and right (x = 9.5)
   edges are excluded. Together they cover the square [1,8]^2 once. */
Test(coverage, top_left_rule_by_hand) {
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    int x, y, pass;
    tu_check chk = {0, {0}};
    /* upper-left triangle, listed in both windings */
    const double a_ccw[6] = {1.5, 1.5, 1.5, 9.5, 9.5, 1.5};
    const double a_cw[6] = {1.5, 1.5, 9.5, 1.5, 1.5, 9.5};
    const double b[6] = {9.5, 1.5, 9.5, 9.5, 1.5, 9.5};
    const double both[12] = {1.5, 1.5, 9.5, 1.5, 1.5, 9.5, 9.5, 1.5, 9.5, 9.5, 1.5, 9.5};
    tu_fb_init(&fb, 16, 16, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (pass = 0; pass < 4; pass++) {
        const double *xy = pass == 0 ? a_ccw : pass == 1 ? a_cw : pass == 2 ? b : both;
        draw_counted(ctx, &fb, xy, pass == 3 ? 2 : 1);
        for (y = 0; y < 16; y++)
            for (x = 0; x < 16; x++) {
                int in_a = x >= 1 && y >= 1 && x + y < 10; /* hypotenuse excluded */
                int in_b = x <= 8 && y <= 8 && x + y >= 10; /* hypotenuse included */
                int exp = pass <= 1 ? in_a : pass == 2 ? in_b : in_a + in_b;
                int got = *tu_sten(&fb, x, y);
                TU_CHECK(&chk, got == exp, "case %d: pixel (%d,%d) = %d, expected %d", pass, x,
                         y, got, exp);
            }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* A 6x6 square [1.5,7.5] x [2.5,8.5] split along either diagonal, where the
   diagonal passes through pixel centres: every centre of columns 1..6 and
   rows 2..7 is hit exactly once (top/left edges in, bottom/right out). */
Test(coverage, shared_diagonal_through_centres) {
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int d, x, y;
    tu_fb_init(&fb, 16, 16, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (d = 0; d < 4; d++) {
        /* d&1: which diagonal; d&2: reversed winding */
        double q[12];
        const double L = 1.5, T = 2.5, R = 7.5, B = 8.5;
        if (d & 1) {
            const double t[12] = {L, T, R, T, R, B, L, T, R, B, L, B}; /* TL-BR diagonal */
            memcpy(q, t, sizeof q);
        } else {
            const double t[12] = {L, T, R, T, L, B, R, T, R, B, L, B}; /* TR-BL diagonal */
            memcpy(q, t, sizeof q);
        }
        if (d & 2) {
            int k;
            for (k = 0; k < 2; k++) { /* swap vertices 1 and 2 of each triangle */
                double sx = q[6 * k + 2], sy = q[6 * k + 3];
                q[6 * k + 2] = q[6 * k + 4];
                q[6 * k + 3] = q[6 * k + 5];
                q[6 * k + 4] = sx;
                q[6 * k + 5] = sy;
            }
        }
        draw_counted(ctx, &fb, q, 2);
        for (y = 0; y < 16; y++)
            for (x = 0; x < 16; x++) {
                int exp = x >= 1 && x <= 6 && y >= 2 && y <= 7;
                int got = *tu_sten(&fb, x, y);
                TU_CHECK(&chk, got == exp, "case %d: pixel (%d,%d) = %d, expected %d", d, x, y,
                         got, exp);
            }
        /* and each half separately owns the diagonal centres consistently:
           for the TL-BR diagonal, the upper-right triangle has the diagonal
           as a LEFT edge (interior to its right), so it owns them. */
        if (d == 1) {
            draw_counted(ctx, &fb, q, 1);
            for (y = 0; y < 16; y++)
                for (x = 0; x < 16; x++) {
                    int exp = x >= 1 && x <= 6 && y >= 2 && y <= 7 && x - y >= -1;
                    int got = *tu_sten(&fb, x, y);
                    TU_CHECK(&chk, got == exp, "upper-right half: (%d,%d) = %d, expected %d", x,
                             y, got, exp);
                }
        }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Triangles touching centres only with a bottom or right edge draw nothing;
   with a top or left edge they draw exactly those centres. */
Test(coverage, edge_through_centres_top_vs_bottom_left_vs_right) {
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int x, y, c;
    /* centres touched: (2.5,3.5) and (3.5,3.5) on the horizontal edge, or
       (3.5,2.5) and (3.5,3.5) on the vertical edge */
    static const double tris[4][6] = {
        {2.0, 3.5, 4.0, 3.5, 3.0, 2.2}, /* apex above: edge y=3.5 is a BOTTOM edge */
        {2.0, 3.5, 4.0, 3.5, 3.0, 4.8}, /* apex below: TOP edge */
        {3.5, 2.0, 3.5, 4.0, 2.2, 3.0}, /* apex left: x=3.5 is a RIGHT edge */
        {3.5, 2.0, 3.5, 4.0, 4.8, 3.0}, /* apex right: LEFT edge */
    };
    tu_fb_init(&fb, 8, 8, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (c = 0; c < 4; c++) {
        draw_counted(ctx, &fb, tris[c], 1);
        for (y = 0; y < 8; y++)
            for (x = 0; x < 8; x++) {
                int exp = 0;
                if (c == 1) exp = y == 3 && (x == 2 || x == 3);
                if (c == 3) exp = x == 3 && (y == 2 || y == 3);
                TU_CHECK(&chk, *tu_sten(&fb, x, y) == exp, "case %d: (%d,%d) = %d, expected %d",
                         c, x, y, *tu_sten(&fb, x, y), exp);
            }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Tiny triangles between pixel centres, sub-pixel slivers and zero-area
   triangles (even ones lying along a row of centres) draw nothing. */
Test(coverage, tiny_and_degenerate_triangles_draw_nothing) {
    enum { W = 32, H = 32 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    double *xy = (double *)malloc(sizeof(double) * 6 * W * H * 3);
    int n = 0, x, y;
    tu_check chk = {0, {0}};
    cr_assert_not_null(xy);
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (y = 0; y < H - 1; y++)
        for (x = 0; x < W - 1; x++) {
            /* inside the square between four centres */
            double t1[6] = {x + 0.55, y + 0.55, x + 1.45, y + 0.55, x + 0.55, y + 1.45};
            /* a 1/256-pixel triangle right next to a centre */
            double t2[6] = {x + 0.5 + 1 / 256., y + 0.5, x + 0.5 + 2 / 256., y + 0.5,
                            x + 0.5 + 1 / 256., y + 0.5 + 1 / 256.};
            /* zero area, lying along the row of centres y + 0.5 */
            double t3[6] = {x + 0.5, y + 0.5, x + 1.5, y + 0.5, x + 3.5, y + 0.5};
            memcpy(xy + 6 * n++, t1, sizeof t1);
            memcpy(xy + 6 * n++, t2, sizeof t2);
            memcpy(xy + 6 * n++, t3, sizeof t3);
        }
    draw_counted(ctx, &fb, xy, n);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++)
            TU_CHECK(&chk, *tu_sten(&fb, x, y) == 0, "pixel (%d,%d) hit %d times", x, y,
                     *tu_sten(&fb, x, y));
    TU_CHECK_DONE(&chk);
    free(xy);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Random triangles compared pixel by pixel with an independent reference of
   the top-left rule (tu_ref_covers). Half the batches use the half-pixel
   grid (lots of exact ties on edges and vertices, plus degenerate
   triangles), half the 1/256 sub-pixel grid. Triangles overlap freely; the
   expected count is the sum of the reference coverages. */
Test(coverage, random_triangles_match_reference_fill_rule) {
    enum { W = 32, H = 32, BATCH = 40, NB = 40 };
    rast_context *ctx = tu_ctx(3, 16);
    tu_fb fb;
    tu_rng rng = tu_rng_make(77);
    int b, t, x, y;
    long covered = 0;
    tu_check chk = {0, {0}};
    static int expect[W * H];
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (b = 0; b < NB; b++) {
        double xy[BATCH * 6];
        memset(expect, 0, sizeof expect);
        for (t = 0; t < BATCH; t++) {
            int k;
            double size = (t % 3 == 0) ? 4.0 : 20.0; /* some small, some large */
            double cx = tu_rng_range(&rng, -2, W + 2), cy = tu_rng_range(&rng, -2, H + 2);
            for (k = 0; k < 3; k++) {
                double vx = cx + tu_rng_range(&rng, -size, size);
                double vy = cy + tu_rng_range(&rng, -size, size);
                if (b & 1) {
                    vx = floor(vx * 2.0 + 0.5) * 0.5;
                    vy = floor(vy * 2.0 + 0.5) * 0.5;
                } else {
                    vx = tu_snap(vx);
                    vy = tu_snap(vy);
                }
                xy[6 * t + 2 * k] = vx;
                xy[6 * t + 2 * k + 1] = vy;
            }
            for (y = 0; y < H; y++)
                for (x = 0; x < W; x++) expect[y * W + x] += tu_ref_covers(xy + 6 * t, x + 0.5, y + 0.5);
        }
        draw_counted(ctx, &fb, xy, BATCH);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                int got = *tu_sten(&fb, x, y);
                covered += expect[y * W + x];
                TU_CHECK(&chk, got == expect[y * W + x],
                         "batch %d (%s grid): pixel (%d,%d) = %d, reference %d", b,
                         (b & 1) ? "half-pixel" : "1/256", x, y, got, expect[y * W + x]);
            }
    }
    TU_CHECK_DONE(&chk);
    cr_assert(covered > 10000);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- culling, viewport, inputs ----------------------------------------- */

/* A CCW-in-NDC triangle (front by default) in the left half, a CW one in the
   right half. Note that CCW in NDC is CW in image coordinates (y flipped):
   the left triangle has NEGATIVE image-space signed area. */
Test(coverage, culling_modes_and_front_face) {
    static const rast_cull culls[] = {RAST_CULL_DEFAULT, RAST_CULL_NONE, RAST_CULL_BACK,
                                      RAST_CULL_FRONT, RAST_CULL_FRONT_AND_BACK};
    static const rast_front_face ffs[] = {RAST_FRONT_FACE_DEFAULT, RAST_CCW, RAST_CW};
    const double tris[12] = {
        1.0, 1.0, 1.0, 7.0, 7.0, 1.0,    /* image area < 0: CCW in NDC */
        9.0, 1.0, 15.0, 1.0, 9.0, 7.0,   /* image area > 0: CW in NDC */
    };
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    size_t c, f;
    cr_assert(tu_area_img(tris[0], tris[1], tris[2], tris[3], tris[4], tris[5]) < 0);
    cr_assert(tu_area_img(tris[6], tris[7], tris[8], tris[9], tris[10], tris[11]) > 0);
    tu_fb_init(&fb, 16, 8, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (c = 0; c < 5; c++)
        for (f = 0; f < 3; f++) {
            rast_state s;
            int ccw_is_front = ffs[f] != RAST_CW;
            int left_front = ccw_is_front, right_front = !ccw_is_front;
            int cull_front = culls[c] == RAST_CULL_FRONT || culls[c] == RAST_CULL_FRONT_AND_BACK;
            int cull_back = culls[c] == RAST_CULL_BACK || culls[c] == RAST_CULL_FRONT_AND_BACK;
            int exp_left = left_front ? !cull_front : !cull_back;
            int exp_right = right_front ? !cull_front : !cull_back;
            memset(fb.stencil, 0, 16 * 8);
            tu_state_count(&s);
            s.cull = culls[c];
            s.front_face = ffs[f];
            tu_set_state(ctx, &s);
            tu_draw_tris_px(ctx, 16, 8, tris, 2, 0.0);
            /* (2,2) is inside the left triangle, (10,2) inside the right one */
            cr_assert_eq(*tu_sten(&fb, 2, 2), exp_left, "cull %d front_face %d: left", (int)c,
                         (int)f);
            cr_assert_eq(*tu_sten(&fb, 10, 2), exp_right, "cull %d front_face %d: right",
                         (int)c, (int)f);
        }
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* The viewport maps NDC [-1,1]^2 onto (x, y, w, h) with y measured from the
   top: a quad covering NDC [-1,1]^2 covers exactly the viewport, and the
   quad NDC [-0.5,0.5] x [0, 0.5] covers its computed sub-rectangle. */
Test(coverage, viewport_mapping) {
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int q, x, y;
    tu_fb_init(&fb, 64, 48, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (q = 0; q < 2; q++) {
        rast_state s;
        const float l = q ? -0.5f : -1.0f, r = q ? 0.5f : 1.0f;
        const float b = q ? 0.0f : -1.0f, t = q ? 0.5f : 1.0f;
        const float v[24] = {l, t, 0, 1, l, b, 0, 1, r, b, 0, 1,
                             l, t, 0, 1, r, b, 0, 1, r, t, 0, 1};
        memset(fb.stencil, 0, 64 * 48);
        tu_state_count(&s);
        s.viewport[0] = 8;
        s.viewport[1] = 4;
        s.viewport[2] = 32;
        s.viewport[3] = 16;
        tu_set_state(ctx, &s);
        cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 6, 0), RAST_OK);
        tu_finish(ctx);
        for (y = 0; y < 48; y++)
            for (x = 0; x < 64; x++) {
                /* full quad: x in [8,40), y in [4,20). Sub-quad: window
                   x = 8 + (ndc+1)*16 in [16,32); window y = 4 + (1-ndc)*8 in
                   [8,12) for ndc y in [0,0.5] */
                int exp = q ? (x >= 16 && x < 32 && y >= 8 && y < 12)
                            : (x >= 8 && x < 40 && y >= 4 && y < 20);
                TU_CHECK(&chk, *tu_sten(&fb, x, y) == exp, "quad %d: (%d,%d) = %d expected %d",
                         q, x, y, *tu_sten(&fb, x, y), exp);
            }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* position_size = 3 (w = 1), a column-major matrix, indices and a stride
   with extra floats: the quad (0,0)-(1,1) scaled by (0.5, 0.25) and
   translated by (-0.25, 0.5) lands on NDC [-0.25,0.25] x [0.5,0.75], i.e.
   window x in [24,40) and y in [8,16) of a 64x64 target. */
Test(coverage, matrix_indices_position_size_3) {
    const float M[16] = {0.5f, 0, 0, 0, 0, 0.25f, 0, 0, 0, 0, 1, 0, -0.25f, 0.5f, 0, 1};
    /* x, y, z, then 2 junk floats that must be skipped by the stride */
    const float v[4 * 5] = {0, 0, 0, 99, 99, 1, 0, 0, 99, 99, 1, 1, 0, 99, 99, 0, 1, 0, 99, 99};
    const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
    rast_context *ctx = tu_ctx(1, 32);
    tu_fb fb;
    rast_state s;
    rast_draw_desc d;
    tu_check chk = {0, {0}};
    int x, y;
    tu_fb_init(&fb, 64, 64, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    tu_state_count(&s);
    tu_set_state(ctx, &s);
    memset(&d, 0, sizeof d);
    d.primitive = RAST_TRIANGLES;
    d.vertices = v;
    d.vertex_count = 4;
    d.stride = 5;
    d.position_size = 3;
    d.indices = idx;
    d.index_count = 6;
    d.matrix = M;
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < 64; y++)
        for (x = 0; x < 64; x++) {
            int exp = x >= 24 && x < 40 && y >= 8 && y < 16;
            TU_CHECK(&chk, *tu_sten(&fb, x, y) == exp, "(%d,%d) = %d expected %d", x, y,
                     *tu_sten(&fb, x, y), exp);
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}
