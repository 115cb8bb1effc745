/* Clipping: near/far planes, w <= 0, the guard band.

   Expectations come from an analytic classification of each pixel centre
   against the clip-space triangle (see clip_classify). Pixels whose
   classification changes within a small distance delta of the centre are
   "unstable" (the centre is essentially on the boundary): there the exact
   answer legitimately depends on sub-pixel snapping and float clipping, so
   they are only required to be hit at most once. Every other pixel must be
   hit exactly as predicted. The stencil buffer counts hits (INCR), which
   also catches double hits on edges created by clipping. */
#include "../test_util.h"

/* Pixel (u, v) in NDC is covered by the clip-space triangle p[3][4] iff the
   ray {(u w, v w, ., w) : w > 0} meets it inside the clip volume. Solving
       l0 (x0,y0,w0) + l1 (x1,y1,w1) + l2 (x2,y2,w2) = (u, v, 1)
   gives l = lambda / w for the barycentrics lambda of the hit point, so the
   point is inside the triangle with w > 0 iff all l > 0 (all l < 0 is the
   "external" triangle through w < 0, which GL never draws), and since the
   w row reads sum(l w) = 1, its NDC depth is z/w = sum(l z), which must lie
   in [-1, 1]. */
static int clip_classify(const double p[3][4], double u, double v) {
    double a = p[0][0], b = p[1][0], c = p[2][0];
    double d = p[0][1], e = p[1][1], f = p[2][1];
    double g = p[0][3], h = p[1][3], i = p[2][3];
    double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    double l0, l1, l2, z;
    if (det == 0.0) return 0;
    /* Cramer's rule with the right-hand side (u, v, 1) */
    l0 = (u * (e * i - f * h) - b * (v * i - f * 1.0) + c * (v * h - e * 1.0)) / det;
    l1 = (a * (v * i - f * 1.0) - u * (d * i - f * g) + c * (d * 1.0 - v * g)) / det;
    l2 = (a * (e * 1.0 - v * h) - b * (d * 1.0 - v * g) + u * (d * h - e * g)) / det;
    if (!(l0 > 0 && l1 > 0 && l2 > 0)) return 0;
    /* the w row of the system says sum(l w) = 1, so sum(l z) = z / w */
    z = l0 * p[0][2] + l1 * p[1][2] + l2 * p[2][2];
    return z >= -1.0 && z <= 1.0;
}

/* Classification of pixel (x, y) of a W x H viewport, stable under moving the
   sample point by +-delta pixels: returns 0/1, or -1 when unstable. */
static int classify_stable(int (*fn)(const void *, double, double), const void *arg, int x,
                           int y, int W, int H, double delta) {
    static const double off[5][2] = {{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    int k, r0 = -1;
    for (k = 0; k < 5; k++) {
        double u, v;
        int r;
        tu_ndc_of_pixel(x + 0.5 + off[k][0] * delta, y + 0.5 + off[k][1] * delta, W, H, &u, &v);
        r = fn(arg, u, v);
        if (k == 0) r0 = r;
        else if (r != r0) return -1;
    }
    return r0;
}

typedef struct tri_list {
    int n;
    const double (*p)[3][4];
} tri_list;

/* union of triangles that do not overlap */
static int classify_list(const void *arg, double u, double v) {
    const tri_list *l = (const tri_list *)arg;
    int i;
    for (i = 0; i < l->n; i++)
        if (clip_classify(l->p[i], u, v)) return 1;
    return 0;
}

/* Planar parallelogram P1 + s (P0 - P1) + t (P2 - P1), 0 < s, t < 1, in clip
   space (the union of a quad mesh, independent of its inner edges). */
static int classify_quad(const void *arg, double u, double v) {
    const double(*p)[4] = (const double(*)[4])arg;
    double a = p[0][0], b = p[1][0], c = p[2][0];
    double d = p[0][1], e = p[1][1], f = p[2][1];
    double g = p[0][3], h = p[1][3], i = p[2][3];
    double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    double l0, l1, l2, s, z;
    if (det == 0.0) return 0;
    l0 = (u * (e * i - f * h) - b * (v * i - f) + c * (v * h - e)) / det;
    l1 = (a * (v * i - f) - u * (d * i - f * g) + c * (d - v * g)) / det;
    l2 = (a * (e - v * h) - b * (d - v * g) + u * (d * h - e * g)) / det;
    s = l0 + l1 + l2; /* = 1 / w of the hit point */
    if (!(s > 0)) return 0;
    if (!(l0 / s > 0 && l0 / s < 1 && l2 / s > 0 && l2 / s < 1)) return 0;
    z = l0 * p[0][2] + l1 * p[1][2] + l2 * p[2][2]; /* z / w, as above */
    return z >= -1.0 && z <= 1.0;
}

/* Compares the stencil hit counts with the stable classification; returns
   the number of stable covered pixels (to prove the test is not vacuous). */
static long compare_counts(const tu_fb *fb, int (*fn)(const void *, double, double),
                           const void *arg, double delta, tu_check *chk, const char *what) {
    int x, y;
    long covered = 0;
    for (y = 0; y < fb->h; y++)
        for (x = 0; x < fb->w; x++) {
            int exp = classify_stable(fn, arg, x, y, fb->w, fb->h, delta);
            int got = *tu_sten(fb, x, y);
            if (exp < 0) {
                TU_CHECK(chk, got <= 1, "%s: boundary pixel (%d,%d) hit %d times", what, x, y,
                         got);
            } else {
                covered += exp;
                TU_CHECK(chk, got == exp, "%s: pixel (%d,%d) hit %d times, expected %d", what, x,
                         y, got, exp);
            }
        }
    return covered;
}

/* Draws clip-space triangles (as given, converted to float) with the
   counting state into a cleared stencil target. The double copies are
   rounded to float first so that expectation and draw see the same input. */
static void draw_clip_tris(rast_context *ctx, tu_fb *fb, double (*p)[3][4], int n) {
    float *v = (float *)malloc(sizeof(float) * 12 * (size_t)n);
    rast_state s;
    int i, k, c;
    cr_assert_not_null(v);
    for (i = 0; i < n; i++)
        for (k = 0; k < 3; k++)
            for (c = 0; c < 4; c++) {
                v[12 * i + 4 * k + c] = (float)p[i][k][c];
                p[i][k][c] = (double)v[12 * i + 4 * k + c];
            }
    memset(fb->stencil, 0, (size_t)fb->w * fb->h);
    tu_state_count(&s);
    tu_set_state(ctx, &s);
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 3 * n, 0), RAST_OK);
    tu_finish(ctx);
    free(v);
}

/* GL perspective projection, fovy 90 degrees, aspect 1. */
static void project(const double eye[3], double n, double f, double out[4]) {
    out[0] = eye[0];
    out[1] = eye[1];
    out[2] = (f + n) / (n - f) * eye[2] + 2.0 * f * n / (n - f);
    out[3] = -eye[2];
}

/* ---- near plane and w <= 0 -------------------------------------------- */

/* A floor quad y_eye = -0.25 reaching from behind the eye (z_eye = +5, clip
   w = -5) to z_eye = -50, drawn as two triangles. The near plane (0.5) cuts
   it along window row y = 48 exactly; without homogeneous clipping the part
   behind the eye would be projected (mirrored) into the upper half. */
Test(clip, near_plane_floor_quad) {
    static const int cfg[][2] = {{1, 16}, {2, 32}, {3, 64}};
    const double n = 0.5, f = 100.0;
    const double corners[4][3] = {{-20, -0.25, 5}, {20, -0.25, 5}, {20, -0.25, -50}, {-20, -0.25, -50}};
    double q[4][4];
    int i, c;
    for (i = 0; i < 4; i++) project(corners[i], n, f, q[i]);
    for (c = 0; c < 3; c++) {
        rast_context *ctx = tu_ctx(cfg[c][0], cfg[c][1]);
        tu_fb fb;
        tu_check chk = {0, {0}};
        double tris[2][3][4];
        long covered;
        int x;
        memcpy(tris[0][0], q[0], sizeof q[0]);
        memcpy(tris[0][1], q[1], sizeof q[0]);
        memcpy(tris[0][2], q[2], sizeof q[0]);
        memcpy(tris[1][0], q[0], sizeof q[0]);
        memcpy(tris[1][1], q[2], sizeof q[0]);
        memcpy(tris[1][2], q[3], sizeof q[0]);
        tu_fb_init(&fb, 64, 64, TU_STENCIL);
        tu_fb_bind(ctx, &fb);
        draw_clip_tris(ctx, &fb, tris, 2);
        /* the two triangles of a quad: classify the quad as a whole so the
           shared diagonal (interior) is not treated as a boundary */
        {
            double par[3][4];
            memcpy(par[0], tris[0][0], sizeof par[0]); /* corner 0 */
            memcpy(par[1], tris[0][1], sizeof par[0]); /* corner 1 */
            memcpy(par[2], tris[0][2], sizeof par[0]); /* corner 2; corner 3 = 0 + 2 - 1 */
            covered = compare_counts(&fb, classify_quad, par, 1.0 / 32, &chk, "floor quad");
        }
        TU_CHECK_DONE(&chk);
        cr_assert(covered > 800, "visible area too small (%ld): test geometry broken", covered);
        /* hand check: rows 48.. are in front of the near plane, rows above
           the horizon (y < 32) are sky */
        for (x = 0; x < 64; x++) {
            cr_assert_eq(*tu_sten(&fb, x, 50), 0, "pixel (%d,50) is closer than near", x);
            cr_assert_eq(*tu_sten(&fb, x, 10), 0, "pixel (%d,10) is sky", x);
        }
        cr_assert_eq(*tu_sten(&fb, 32, 46), 1, "pixel (32,46) sees the floor");
        rast_context_destroy(ctx);
        tu_fb_free(&fb);
    }
}

/* The same floor as a 12x12 grid of quads crossing w = 0 and the far plane
   (far = 30): every visible pixel exactly once, so clipped shared edges stay
   watertight. */
Test(clip, near_and_far_clipped_mesh_is_watertight) {
    enum { N = 12 };
    const double n = 0.5, f = 30.0;
    const double z0 = 4.0, z1 = -40.0, xa = -10.0, xb = 10.0, ye = -0.25;
    double (*tris)[3][4] = malloc(sizeof(double[3][4]) * 2 * N * N);
    double par[3][4];
    int i, j, t = 0;
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    long covered;
    cr_assert_not_null(tris);
    for (j = 0; j < N; j++)
        for (i = 0; i < N; i++) {
            double e[4][3], c[4][4];
            int k;
            for (k = 0; k < 4; k++) {
                int ii = i + (k == 1 || k == 2), jj = j + (k >= 2);
                e[k][0] = xa + (xb - xa) * ii / N;
                e[k][1] = ye;
                e[k][2] = z0 + (z1 - z0) * jj / N;
                project(e[k], n, f, c[k]);
            }
            memcpy(tris[t][0], c[0], sizeof c[0]);
            memcpy(tris[t][1], c[1], sizeof c[0]);
            memcpy(tris[t][2], c[2], sizeof c[0]);
            t++;
            memcpy(tris[t][0], c[0], sizeof c[0]);
            memcpy(tris[t][1], c[2], sizeof c[0]);
            memcpy(tris[t][2], c[3], sizeof c[0]);
            t++;
        }
    {
        const double e0[3] = {xa, ye, z0}, e1[3] = {xb, ye, z0}, e2[3] = {xb, ye, z1};
        project(e0, n, f, par[0]);
        project(e1, n, f, par[1]);
        project(e2, n, f, par[2]);
    }
    tu_fb_init(&fb, 64, 64, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    draw_clip_tris(ctx, &fb, tris, t);
    covered = compare_counts(&fb, classify_quad, par, 1.0 / 32, &chk, "floor mesh");
    TU_CHECK_DONE(&chk);
    cr_assert(covered > 500, "covered %ld", covered);
    free(tris);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Random clip-space triangles with w of both signs (and sometimes exactly
   0), crossing the near and far planes, each compared with the analytic
   classification. */
Test(clip, random_triangles_crossing_w0_near_far) {
    enum { W = 64, H = 64, NT = 250 };
    rast_context *ctx = tu_ctx(3, 16);
    tu_fb fb;
    tu_rng rng = tu_rng_make(2024);
    tu_check chk = {0, {0}};
    int t, k;
    long covered = 0;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (t = 0; t < NT; t++) {
        double p[1][3][4];
        tri_list l;
        char what[64];
        for (;;) {
            double det;
            for (k = 0; k < 3; k++) {
                double w = tu_rng_range(&rng, -1.5, 2.5);
                double s = fabs(w) < 0.3 ? 0.3 : fabs(w);
                if (tu_rng_int(&rng, 0, 9) == 0) w = 0.0; /* a point at infinity */
                p[0][k][0] = tu_rng_range(&rng, -2.0, 2.0) * s;
                p[0][k][1] = tu_rng_range(&rng, -2.0, 2.0) * s;
                p[0][k][2] = tu_rng_range(&rng, -1.6, 1.6) * s;
                p[0][k][3] = w;
            }
            det = p[0][0][0] * (p[0][1][1] * p[0][2][3] - p[0][2][1] * p[0][1][3]) -
                  p[0][1][0] * (p[0][0][1] * p[0][2][3] - p[0][2][1] * p[0][0][3]) +
                  p[0][2][0] * (p[0][0][1] * p[0][1][3] - p[0][1][1] * p[0][0][3]);
            if (fabs(det) > 0.05) break; /* avoid planes through the eye */
        }
        draw_clip_tris(ctx, &fb, p, 1);
        l.n = 1;
        l.p = (const double(*)[3][4])p;
        snprintf(what, sizeof what, "triangle %d", t);
        covered += compare_counts(&fb, classify_list, &l, 1.0 / 32, &chk, what);
    }
    TU_CHECK_DONE(&chk);
    cr_assert(covered > 20000, "covered %ld", covered);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* A triangle and its negation (-x,-y,-z,-w) project to the same NDC, but the
   negated one lies entirely behind the eye and must draw nothing. Triangles
   entirely beyond far (z > w) or in front of near (z < -w) are dropped too. */
Test(clip, behind_eye_and_outside_depth_range_are_dropped) {
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    double base[1][3][4] = {{{-0.8, -0.8, 0.0, 1.0}, {1.6, -1.2, 0.5, 2.0}, {0.0, 0.9, -0.3, 1.0}}};
    int k, c, x, y;
    long sum;
    tu_fb_init(&fb, 32, 32, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (c = 0; c < 4; c++) {
        double p[1][3][4];
        memcpy(p, base, sizeof p);
        for (k = 0; k < 3; k++) {
            if (c == 1) { /* negated: all w < 0 */
                p[0][k][0] = -p[0][k][0];
                p[0][k][1] = -p[0][k][1];
                p[0][k][2] = -p[0][k][2];
                p[0][k][3] = -p[0][k][3];
            }
            if (c == 2) p[0][k][2] = p[0][k][3] * 1.01 + 0.01; /* beyond far */
            if (c == 3) p[0][k][2] = -p[0][k][3] * 1.01 - 0.01; /* before near */
        }
        draw_clip_tris(ctx, &fb, p, 1);
        sum = 0;
        for (y = 0; y < 32; y++)
            for (x = 0; x < 32; x++) sum += *tu_sten(&fb, x, y);
        if (c == 0)
            cr_assert(sum > 100, "the visible original must draw (got %ld pixels)", sum);
        else
            cr_assert_eq(sum, 0, "case %d must be dropped, drew %ld pixels", c, sum);
    }
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- guard band -------------------------------------------------------- */

/* Huge triangles (vertices from 8192 px to 1e8 px away, beyond the guard
   band so they need clipping) containing the viewport cover every pixel
   exactly once; also with the vertices scaled by a random clip w (same
   projection). */
Test(clip, guard_band_huge_triangle_covers_viewport_once) {
    static const double R[] = {8192, 8193, 9000, 1e4, 3e4, 1e5, 1e6, 1e7, 1e8};
    enum { W = 64, H = 64 };
    rast_context *ctx = tu_ctx(2, 32);
    tu_fb fb;
    tu_rng rng = tu_rng_make(5);
    tu_check chk = {0, {0}};
    size_t r;
    int rep, k, x, y;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (r = 0; r < sizeof R / sizeof R[0]; r++)
        for (rep = 0; rep < 6; rep++) {
            double p[1][3][4];
            double th = tu_rng_range(&rng, 0, 6.283185307179586);
            double cx = W / 2 + tu_rng_range(&rng, -0.2, 0.2) * R[r];
            double cy = H / 2 + tu_rng_range(&rng, -0.2, 0.2) * R[r];
            for (k = 0; k < 3; k++) {
                double a = th + k * 2.0943951023931957 * (rep & 1 ? 1 : -1); /* both windings */
                float c[4];
                double w = (rep >= 3) ? tu_rng_range(&rng, 0.01, 100.0) : 1.0;
                /* circumradius 2R: inradius R contains the viewport */
                tu_clip_from_window(c, cx + 2 * R[r] * cos(a), cy + 2 * R[r] * sin(a), 0.0, w, W, H);
                p[0][k][0] = c[0];
                p[0][k][1] = c[1];
                p[0][k][2] = c[2];
                p[0][k][3] = c[3];
            }
            draw_clip_tris(ctx, &fb, p, 1);
            for (y = 0; y < H; y++)
                for (x = 0; x < W; x++)
                    TU_CHECK(&chk, *tu_sten(&fb, x, y) == 1,
                             "R %g rep %d: pixel (%d,%d) hit %d times", R[r], rep, x, y,
                             *tu_sten(&fb, x, y));
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* A quad with corners exactly at, just inside and just outside the guard
   band (+-8192 px beyond each viewport edge), split along a diagonal that
   crosses the viewport: every pixel exactly once. */
Test(clip, guard_band_quad_at_8192) {
    static const double off[] = {-1.0, -0.5, 0.0, 0.5, 1.0, 1000.0};
    enum { W = 64, H = 32 };
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    size_t o;
    int x, y, diag;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (o = 0; o < sizeof off / sizeof off[0]; o++)
        for (diag = 0; diag < 2; diag++) {
            const double G = RAST_GUARD_BAND + off[o];
            const double L = -G, T = -G, R = W + G, B = H + G;
            double xy[12];
            if (diag) {
                const double q[12] = {L, T, R, T, R, B, L, T, R, B, L, B};
                memcpy(xy, q, sizeof q);
            } else {
                const double q[12] = {L, T, R, T, L, B, R, T, R, B, L, B};
                memcpy(xy, q, sizeof q);
            }
            {
                rast_state s;
                memset(fb.stencil, 0, W * H);
                tu_state_count(&s);
                tu_set_state(ctx, &s);
                tu_draw_tris_px(ctx, W, H, xy, 2, 0.0);
            }
            for (y = 0; y < H; y++)
                for (x = 0; x < W; x++)
                    TU_CHECK(&chk, *tu_sten(&fb, x, y) == 1,
                             "offset %g diag %d: pixel (%d,%d) hit %d times", off[o], diag, x, y,
                             *tu_sten(&fb, x, y));
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

typedef struct half_plane {
    double px, py, nx, ny; /* covered: (c - p) . n > 0, window coordinates */
    int W, H;
} half_plane;

static int classify_half_plane(const void *arg, double u, double v) {
    const half_plane *h = (const half_plane *)arg;
    double x = (u + 1.0) * 0.5 * h->W, y = (1.0 - v) * 0.5 * h->H;
    return (x - h->px) * h->nx + (y - h->py) * h->ny > 0;
}

/* A triangle with two vertices R pixels away along a line through the
   viewport and the third R away on one side covers exactly the pixels on
   that side of the line. The tolerance grows with R because the clipper
   computes in float (an error of ~R * 2^-23 is the honest limit). */
Test(clip, guard_band_half_plane_edge_on_analytic_line) {
    static const double R[] = {2e3, 1e4, 1e5, 1e6};
    enum { W = 64, H = 64 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_rng rng = tu_rng_make(99);
    tu_check chk = {0, {0}};
    size_t r;
    int rep;
    long covered = 0;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (r = 0; r < sizeof R / sizeof R[0]; r++)
        for (rep = 0; rep < 12; rep++) {
            half_plane h;
            double th = tu_rng_range(&rng, 0, 6.283185307179586);
            double dx = cos(th), dy = sin(th);
            double xy[6];
            double delta = fmax(1.0 / 32, R[r] * 4e-7);
            char what[64];
            h.px = tu_rng_range(&rng, 8, W - 8);
            h.py = tu_rng_range(&rng, 8, H - 8);
            h.nx = -dy;
            h.ny = dx;
            h.W = W;
            h.H = H;
            xy[0] = h.px + R[r] * dx;
            xy[1] = h.py + R[r] * dy;
            xy[2] = h.px - R[r] * dx;
            xy[3] = h.py - R[r] * dy;
            xy[4] = h.px + R[r] * h.nx;
            xy[5] = h.py + R[r] * h.ny;
            if (rep & 1) { /* other winding */
                double sx = xy[0], sy = xy[1];
                xy[0] = xy[2];
                xy[1] = xy[3];
                xy[2] = sx;
                xy[3] = sy;
            }
            {
                rast_state s;
                memset(fb.stencil, 0, W * H);
                tu_state_count(&s);
                tu_set_state(ctx, &s);
                tu_draw_tris_px(ctx, W, H, xy, 1, 0.0);
            }
            snprintf(what, sizeof what, "R %g rep %d", R[r], rep);
            covered += compare_counts(&fb, classify_half_plane, &h, delta, &chk, what);
        }
    TU_CHECK_DONE(&chk);
    cr_assert(covered > 10000);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Edges of huge (clipped) triangles lying exactly on a row or column of
   pixel centres still follow the top-left rule: a horizontal edge at
   y = 20.5 includes row 20 when it is a top edge (interior below) and
   excludes it when it is a bottom edge; a vertical edge at x = 10.5 includes
   column 10 when it is a left edge and excludes it when it is a right edge. */
Test(clip, guard_band_edges_through_centres_keep_fill_rule) {
    enum { W = 32, H = 32 };
    const double F = 50000.0;
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int c, x, y;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (c = 0; c < 4; c++) {
        double xy[6];
        rast_state s;
        if (c == 0) { const double t[6] = {-F, 20.5, F, 20.5, 16, F}; memcpy(xy, t, sizeof t); }
        if (c == 1) { const double t[6] = {-F, 20.5, F, 20.5, 16, -F}; memcpy(xy, t, sizeof t); }
        if (c == 2) { const double t[6] = {10.5, -F, 10.5, F, F, 16}; memcpy(xy, t, sizeof t); }
        if (c == 3) { const double t[6] = {10.5, -F, 10.5, F, -F, 16}; memcpy(xy, t, sizeof t); }
        memset(fb.stencil, 0, W * H);
        tu_state_count(&s);
        tu_set_state(ctx, &s);
        tu_draw_tris_px(ctx, W, H, xy, 1, 0.0);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                int exp = c == 0 ? y >= 20 : c == 1 ? y < 20 : c == 2 ? x >= 10 : x < 10;
                TU_CHECK(&chk, *tu_sten(&fb, x, y) == exp, "case %d: (%d,%d) = %d expected %d",
                         c, x, y, *tu_sten(&fb, x, y), exp);
            }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* GL clips to the view volume, which is the viewport: with a viewport
   smaller than the target, a huge triangle covers exactly the viewport (the
   guard band must not let it spill into the rest of the target). */
Test(clip, huge_triangle_stays_inside_viewport) {
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    rast_state s;
    /* in NDC: far beyond [-1,1] on every side */
    const float v[12] = {-3000.f, -3000.f, 0, 1, 9000.f, -3000.f, 0, 1, -3000.f, 9000.f, 0, 1};
    int x, y;
    tu_fb_init(&fb, 64, 64, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    tu_state_count(&s);
    s.viewport[0] = 10;
    s.viewport[1] = 20;
    s.viewport[2] = 30;
    s.viewport[3] = 17;
    tu_set_state(ctx, &s);
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 3, 0), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < 64; y++)
        for (x = 0; x < 64; x++) {
            int exp = x >= 10 && x < 40 && y >= 20 && y < 37;
            TU_CHECK(&chk, *tu_sten(&fb, x, y) == exp, "(%d,%d) = %d expected %d", x, y,
                     *tu_sten(&fb, x, y), exp);
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}
