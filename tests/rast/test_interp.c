/* Interpolation: perspective-correct varyings, flat shading, depth.

   The analytic value at a pixel centre comes from first principles: for a
   clip-space triangle P0, P1, P2 and the pixel's NDC (u, v), solve
       l0 (x0,y0,w0) + l1 (x1,y1,w1) + l2 (x2,y2,w2) = (u, v, 1).
   The hit point's barycentrics are lambda = l / sum(l), its clip w is
   1 / sum(l) and its NDC depth is sum(l z). A varying is sum(lambda V): the
   3D-linear interpolation GL calls perspective correct. For a floor quad the
   tests instead intersect the pixel ray with the plane in eye space.

   Vertex window positions are put exactly on the 1/256 sub-pixel grid
   (except where clipping creates vertices), so snapping does not move the
   triangle and tight tolerances are fair. */
#include "../test_util.h"

enum { IW = 64, IH = 64, NV = RAST_MAX_VARYINGS };

/* What the fragment callback saw at each pixel. */
typedef struct frag_rec {
    int hits;
    float var[NV];
    float z, w;
    int front;
    int x, y;
} frag_rec;

typedef struct rec_buf {
    int w, h, nvar;
    frag_rec *px;
} rec_buf;

/* Records its inputs; pixels are owned by one tile worker each, and each
   test draws non-overlapping geometry, so the plain stores do not race. */
static int record_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    rec_buf *b = (rec_buf *)user;
    frag_rec *r;
    int k;
    if (in->x < 0 || in->y < 0 || in->x >= b->w || in->y >= b->h) return 0;
    r = &b->px[in->y * b->w + in->x];
    r->hits++;
    for (k = 0; k < b->nvar; k++) r->var[k] = in->varyings[k];
    r->z = in->z;
    r->w = in->w;
    r->front = in->front_facing;
    r->x = in->x;
    r->y = in->y;
    rgba[0] = rgba[1] = rgba[2] = rgba[3] = 1.0f;
    return 1;
}

/* l = M^-1 (u, v, 1) for M with columns (x_i, y_i, w_i); returns 0 when
   singular. */
static int solve_l(const float p[3][4], double u, double v, double l[3]) {
    double a = p[0][0], b = p[1][0], c = p[2][0];
    double d = p[0][1], e = p[1][1], f = p[2][1];
    double g = p[0][3], h = p[1][3], i = p[2][3];
    double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    if (det == 0.0) return 0;
    l[0] = (u * (e * i - f * h) - b * (v * i - f) + c * (v * h - e)) / det;
    l[1] = (a * (v * i - f) - u * (d * i - f * g) + c * (d - v * g)) / det;
    l[2] = (a * (e - v * h) - b * (d - v * g) + u * (d * h - e * g)) / det;
    return 1;
}

static int close_rel(double got, double exp, double rel, double abs_floor) {
    return fabs(got - exp) <= rel * fabs(exp) + abs_floor;
}

/* ---- random triangles, fragment callback ------------------------------ */

/* Random triangles with per-vertex w in [0.3, 4]: every varying within 1e-4
   (relative to max(1, |value|)) of the analytic perspective-correct value,
   the depth within 1e-6 relative of z_ndc * 0.5 + 0.5, in.w the clip w of
   the hit point, front_facing from the winding, and the callback called
   exactly once for exactly the pixels the fill rule covers. The first four
   varyings are clip x, y, z, w, so a correct interpolator also gives
   var0 / var3 == u and var1 / var3 == v (checked as a consistency test). */
Test(interp, perspective_correct_varyings_random_triangles) {
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    rec_buf rb;
    tu_rng rng = tu_rng_make(31337);
    tu_check chk = {0, {0}};
    long checked = 0;
    int t;
    rb.w = IW;
    rb.h = IH;
    rb.nvar = NV;
    rb.px = (frag_rec *)calloc(IW * IH, sizeof(frag_rec));
    cr_assert_not_null(rb.px);
    tu_fb_init(&fb, IW, IH, TU_COLOR8);
    tu_fb_bind(ctx, &fb);
    for (t = 0; t < 60; t++) {
        float v[3 * (4 + NV)];
        float p[3][4];
        double win[6], V[3][NV];
        int k, j, x, y;
        rast_state s;
        double area;
        do {
            for (k = 0; k < 3; k++) {
                win[2 * k] = tu_rng_grid(&rng, -6, IW + 6);
                win[2 * k + 1] = tu_rng_grid(&rng, -6, IH + 6);
            }
            area = tu_area_img(win[0], win[1], win[2], win[3], win[4], win[5]);
        } while (fabs(area) < 300.0); /* reasonably well shaped */
        for (k = 0; k < 3; k++) {
            double w = tu_rng_range(&rng, 0.3, 4.0);
            double z = tu_rng_range(&rng, -0.9, 0.9);
            tu_clip_from_window(p[k], win[2 * k], win[2 * k + 1], z, w, IW, IH);
            for (j = 0; j < 4; j++) V[k][j] = p[k][j];
            for (j = 4; j < NV; j++) V[k][j] = (float)tu_rng_range(&rng, -3.0, 3.0);
            for (j = 0; j < 4; j++) v[k * (4 + NV) + j] = p[k][j];
            for (j = 0; j < NV; j++) v[k * (4 + NV) + 4 + j] = (float)V[k][j];
        }
        memset(rb.px, 0, sizeof(frag_rec) * IW * IH);
        memset(&s, 0, sizeof s);
        s.fragment_fn = record_fragment;
        s.fragment_user = &rb;
        tu_set_state(ctx, &s);
        cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 3, NV), RAST_OK);
        tu_finish(ctx);
        for (y = 0; y < IH; y++)
            for (x = 0; x < IW; x++) {
                const frag_rec *r = &rb.px[y * IW + x];
                int cov = tu_ref_covers(win, x + 0.5, y + 0.5);
                double u, vv, l[3], sl, lam[3];
                TU_CHECK(&chk, r->hits == cov, "tri %d pixel (%d,%d): callback ran %d times, "
                         "coverage %d", t, x, y, r->hits, cov);
                if (!cov || r->hits != 1) continue;
                TU_CHECK(&chk, r->x == x && r->y == y, "in->x/y");
                tu_ndc_of_pixel(x + 0.5, y + 0.5, IW, IH, &u, &vv);
                cr_assert(solve_l((const float(*)[4])p, u, vv, l));
                sl = l[0] + l[1] + l[2];
                for (k = 0; k < 3; k++) lam[k] = l[k] / sl;
                for (j = 0; j < NV; j++) {
                    double e = lam[0] * V[0][j] + lam[1] * V[1][j] + lam[2] * V[2][j];
                    TU_CHECK(&chk, fabs(r->var[j] - e) <= 1e-4 * fmax(1.0, fabs(e)),
                             "tri %d pixel (%d,%d) varying %d = %.7g, analytic %.7g", t, x, y, j,
                             r->var[j], e);
                }
                {
                    double zd = (l[0] * p[0][2] + l[1] * p[1][2] + l[2] * p[2][2]) * 0.5 + 0.5;
                    TU_CHECK(&chk, close_rel(r->z, zd, 1e-6, 1e-7),
                             "tri %d pixel (%d,%d) depth %.9g, analytic %.9g", t, x, y, r->z, zd);
                    TU_CHECK(&chk, close_rel(r->w, 1.0 / sl, 1e-5, 0),
                             "tri %d pixel (%d,%d) w %.7g, analytic %.7g", t, x, y, r->w,
                             1.0 / sl);
                    TU_CHECK(&chk, fabs(r->var[0] / r->var[3] - u) < 1e-4 &&
                                       fabs(r->var[1] / r->var[3] - vv) < 1e-4,
                             "tri %d pixel (%d,%d): interpolated clip position does not "
                             "project onto the pixel", t, x, y);
                }
                TU_CHECK(&chk, (r->front != 0) == (area < 0), "tri %d pixel (%d,%d): "
                         "front_facing %d, image area %g", t, x, y, r->front, area);
                checked++;
            }
    }
    TU_CHECK_DONE(&chk);
    cr_assert(checked > 10000, "only %ld pixels checked", checked);
    free(rb.px);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- floor quad in eye space ------------------------------------------ */

/* GL perspective projection, fovy 90 degrees, aspect 1, near 0.5, far 8. */
static const double FN = 0.5, FF = 8.0;
static void project(const double e[3], float out[4]) {
    out[0] = (float)e[0];
    out[1] = (float)e[1];
    out[2] = (float)((FF + FN) / (FN - FF) * e[2] + 2.0 * FF * FN / (FN - FF));
    out[3] = (float)-e[2];
}

/* The floor y_eye = -1 between z_eye = -1 and -4, x_eye in [-0.75, 0.75] near
   and [-1.5, 1.5] far: its corners project to the dyadic window positions
   (8,64) (56,64) (44,40) (20,40). Varyings: eye x, y, z, then s, t style
   texture coordinates (affine in eye space). */
static const double floor_eye[4][3] = {
    {-0.75, -1, -1}, {0.75, -1, -1}, {1.5, -1, -4}, {-1.5, -1, -4}};
static const double floor_win[4][2] = {{8, 64}, {56, 64}, {44, 40}, {20, 40}};
static const int floor_idx[6] = {0, 1, 2, 0, 2, 3};

static void floor_varyings(const double e[3], float out[6]) {
    out[0] = (float)e[0];
    out[1] = (float)e[1];
    out[2] = (float)e[2];
    out[3] = 1.0f;
    out[4] = (float)((e[0] + 1.5) / 3.0);
    out[5] = (float)((e[2] + 4.0) / 3.0);
}

/* Analytic: the ray through pixel centre (u, v) is t (u, v, -1) in eye space
   (f = 1); it meets the plane y = height (-1 for the floor) at t = height/v. */
static void floor_analytic_h(int x, int y, double height, double out[6], double *depth,
                             double *w) {
    double u, v, t, e[3];
    tu_ndc_of_pixel(x + 0.5, y + 0.5, IW, IH, &u, &v);
    t = height / v;
    e[0] = u * t;
    e[1] = height;
    e[2] = -t;
    out[0] = e[0];
    out[1] = e[1];
    out[2] = e[2];
    out[3] = 1.0;
    out[4] = (e[0] + 1.5) / 3.0;
    out[5] = (e[2] + 4.0) / 3.0;
    *w = t;
    *depth = ((FF + FN) / (FN - FF) * e[2] + 2.0 * FF * FN / (FN - FF)) / t * 0.5 + 0.5;
}

static void floor_analytic(int x, int y, double out[6], double *depth, double *w) {
    floor_analytic_h(x, y, -1.0, out, depth, w);
}

static int floor_covers(int x, int y) {
    double a[6], b[6];
    int k;
    for (k = 0; k < 3; k++) {
        a[2 * k] = floor_win[floor_idx[k]][0];
        a[2 * k + 1] = floor_win[floor_idx[k]][1];
        b[2 * k] = floor_win[floor_idx[3 + k]][0];
        b[2 * k + 1] = floor_win[floor_idx[3 + k]][1];
    }
    return tu_ref_covers(a, x + 0.5, y + 0.5) + tu_ref_covers(b, x + 0.5, y + 0.5);
}

/* Draws the floor either with CPU-projected clip positions, or with eye
   positions (position_size 3) and the projection as rast_draw_desc.matrix. */
static void draw_floor(rast_context *ctx, int use_matrix) {
    float v[4 * (4 + 6)];
    rast_draw_desc d;
    /* column-major projection matrix */
    float M[16] = {0};
    uint32_t idx[6];
    int k;
    M[0] = 1;
    M[5] = 1;
    M[10] = (float)((FF + FN) / (FN - FF));
    M[11] = -1;
    M[14] = (float)(2.0 * FF * FN / (FN - FF));
    for (k = 0; k < 4; k++) {
        float *o = v + k * (use_matrix ? 9 : 10);
        if (use_matrix) {
            o[0] = (float)floor_eye[k][0];
            o[1] = (float)floor_eye[k][1];
            o[2] = (float)floor_eye[k][2];
            floor_varyings(floor_eye[k], o + 3);
        } else {
            project(floor_eye[k], o);
            floor_varyings(floor_eye[k], o + 4);
        }
    }
    for (k = 0; k < 6; k++) idx[k] = (uint32_t)floor_idx[k];
    memset(&d, 0, sizeof d);
    d.primitive = RAST_TRIANGLES;
    d.vertices = v;
    d.vertex_count = 4;
    d.indices = idx;
    d.index_count = 6;
    d.num_varyings = 6;
    if (use_matrix) {
        d.position_size = 3;
        d.stride = 9;
        d.matrix = M;
    } else {
        d.stride = 10;
    }
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
    tu_finish(ctx);
}

/* The floor through the fragment callback: world coordinates, texture-like
   coordinates, depth and w against the analytic ray/plane intersection;
   both with CPU projection and with desc.matrix. */
Test(interp, perspective_floor_world_coordinates_callback) {
    int use_matrix;
    for (use_matrix = 0; use_matrix < 2; use_matrix++) {
        rast_context *ctx = tu_ctx(3, 16);
        tu_fb fb;
        rec_buf rb;
        rast_state s;
        tu_check chk = {0, {0}};
        long n = 0;
        int x, y, j;
        /* sanity: the corners really project to the dyadic window positions */
        for (j = 0; j < 4; j++) {
            float c[4];
            project(floor_eye[j], c);
            cr_assert_float_eq((c[0] / c[3] + 1) * 32, floor_win[j][0], 1e-9);
            cr_assert_float_eq((1 - c[1] / c[3]) * 32, floor_win[j][1], 1e-9);
        }
        rb.w = IW;
        rb.h = IH;
        rb.nvar = 6;
        rb.px = (frag_rec *)calloc(IW * IH, sizeof(frag_rec));
        cr_assert_not_null(rb.px);
        tu_fb_init(&fb, IW, IH, TU_COLOR32F);
        tu_fb_bind(ctx, &fb);
        memset(&s, 0, sizeof s);
        s.fragment_fn = record_fragment;
        s.fragment_user = &rb;
        tu_set_state(ctx, &s);
        draw_floor(ctx, use_matrix);
        for (y = 0; y < IH; y++)
            for (x = 0; x < IW; x++) {
                const frag_rec *r = &rb.px[y * IW + x];
                double e[6], depth, w;
                int cov = floor_covers(x, y);
                TU_CHECK(&chk, r->hits == cov, "matrix %d (%d,%d): %d calls, coverage %d",
                         use_matrix, x, y, r->hits, cov);
                if (!cov || r->hits != 1) continue;
                floor_analytic(x, y, e, &depth, &w);
                for (j = 0; j < 6; j++)
                    TU_CHECK(&chk, fabs(r->var[j] - e[j]) <= 1e-4 * fmax(1.0, fabs(e[j])),
                             "matrix %d (%d,%d) varying %d = %.7g, analytic %.7g", use_matrix, x,
                             y, j, r->var[j], e[j]);
                TU_CHECK(&chk, close_rel(r->z, depth, 1e-6, 1e-7),
                         "matrix %d (%d,%d) depth %.9g, analytic %.9g", use_matrix, x, y, r->z,
                         depth);
                TU_CHECK(&chk, close_rel(r->w, w, 1e-5, 0), "matrix %d (%d,%d) w %.7g vs %.7g",
                         use_matrix, x, y, r->w, w);
                n++;
            }
        TU_CHECK_DONE(&chk);
        cr_assert(n > 700, "only %ld pixels", n);
        free(rb.px);
        rast_context_destroy(ctx);
        tu_fb_free(&fb);
    }
}

/* The default path: varyings 0..3 are the colour, written to an RGBA32F
   target; the depth buffer receives z_ndc * 0.5 + 0.5. Colour = (s, t, -z/4,
   1) style values in [0, 1], so no clamping question arises. */
Test(interp, perspective_floor_default_path_colour_and_depth) {
    rast_context *ctx = tu_ctx(2, 32);
    tu_fb fb;
    rast_state s;
    tu_check chk = {0, {0}};
    float v[4 * 8];
    rast_draw_desc d;
    uint32_t idx[6];
    int k, x, y;
    long n = 0;
    tu_fb_init(&fb, IW, IH, TU_COLOR32F | TU_DEPTH);
    tu_fb_bind(ctx, &fb);
    tu_clear(ctx, RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH, 0, 0, 0, 0, 1.0f, 0);
    memset(&s, 0, sizeof s);
    s.depth_test = 1;
    s.depth_func = RAST_ALWAYS;
    tu_set_state(ctx, &s);
    for (k = 0; k < 4; k++) {
        float var[6];
        project(floor_eye[k], v + 8 * k);
        floor_varyings(floor_eye[k], var);
        v[8 * k + 4] = var[4];                           /* s */
        v[8 * k + 5] = var[5];                           /* t */
        v[8 * k + 6] = (float)(-floor_eye[k][2] / 4.0); /* -z/4 */
        v[8 * k + 7] = 1.0f;
    }
    for (k = 0; k < 6; k++) idx[k] = (uint32_t)floor_idx[k];
    memset(&d, 0, sizeof d);
    d.vertices = v;
    d.vertex_count = 4;
    d.stride = 8;
    d.num_varyings = 4;
    d.indices = idx;
    d.index_count = 6;
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < IH; y++)
        for (x = 0; x < IW; x++) {
            const float *c = tu_pxf(&fb, x, y);
            float dep = *tu_depth(&fb, x, y);
            double e[6], depth, w;
            if (!floor_covers(x, y)) {
                TU_CHECK(&chk, c[3] == 0 && dep == 1.0f, "(%d,%d) outside was written", x, y);
                continue;
            }
            floor_analytic(x, y, e, &depth, &w);
            TU_CHECK(&chk, fabs(c[0] - e[4]) <= 1e-4 && fabs(c[1] - e[5]) <= 1e-4 &&
                               fabs(c[2] - (-e[2] / 4)) <= 1e-4 && c[3] == 1.0f,
                     "(%d,%d) colour %.6g %.6g %.6g %.6g, analytic %.6g %.6g %.6g 1", x, y, c[0],
                     c[1], c[2], c[3], e[4], e[5], -e[2] / 4);
            TU_CHECK(&chk, close_rel(dep, depth, 1e-6, 1e-7), "(%d,%d) depth %.9g analytic %.9g",
                     x, y, dep, depth);
            n++;
        }
    TU_CHECK_DONE(&chk);
    cr_assert(n > 700);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Smooth colour into RGBA8: the perspective-correct barycentrics as colour,
   stored as round(c * 255) within one step. */
Test(interp, smooth_colour_rgba8_within_one_step) {
    rast_context *ctx = tu_ctx(1, 64);
    tu_fb fb;
    tu_check chk = {0, {0}};
    const double win[6] = {3.25, 60.5, 61.0, 50.75, 20.5, 2.0};
    const double wv[3] = {0.5, 3.0, 1.25};
    float v[3 * 8], p[3][4];
    int k, x, y;
    tu_fb_init(&fb, IW, IH, TU_COLOR8);
    tu_fb_bind(ctx, &fb);
    for (k = 0; k < 3; k++) {
        tu_clip_from_window(p[k], win[2 * k], win[2 * k + 1], 0.0, wv[k], IW, IH);
        memcpy(v + 8 * k, p[k], sizeof p[k]);
        v[8 * k + 4] = k == 0;
        v[8 * k + 5] = k == 1;
        v[8 * k + 6] = k == 2;
        v[8 * k + 7] = 1.0f;
    }
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 3, 4), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < IH; y++)
        for (x = 0; x < IW; x++) {
            const uint8_t *c = tu_px8(&fb, x, y);
            double u, vv, l[3], sl;
            if (!tu_ref_covers(win, x + 0.5, y + 0.5)) {
                TU_CHECK(&chk, c[3] == 0, "(%d,%d) outside written", x, y);
                continue;
            }
            tu_ndc_of_pixel(x + 0.5, y + 0.5, IW, IH, &u, &vv);
            solve_l((const float(*)[4])p, u, vv, l);
            sl = l[0] + l[1] + l[2];
            for (k = 0; k < 3; k++) {
                int e = tu_unorm8(l[k] / sl);
                TU_CHECK(&chk, abs((int)c[k] - e) <= 1, "(%d,%d) channel %d = %d, expected %d",
                         x, y, k, c[k], e);
            }
            TU_CHECK(&chk, c[3] == 255, "(%d,%d) alpha %d", x, y, c[3]);
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Near-clipped geometry: a floor at y_eye = -0.25 from z_eye = +2 (behind
   the eye) to -4 is cut by the near plane along window row 48; the clipper
   creates vertices whose snapped positions are not on our grid, so the
   tolerance is the interpolation error of a 1/256 pixel displacement: 1e-3
   relative here. */
Test(interp, near_clipped_varyings_stay_perspective_correct) {
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    rec_buf rb;
    rast_state s;
    tu_check chk = {0, {0}};
    const double eye[4][3] = {{-1.5, -0.25, 2}, {1.5, -0.25, 2}, {1.5, -0.25, -4}, {-1.5, -0.25, -4}};
    float v[6 * 10];
    int k, j, x, y;
    long n = 0;
    rb.w = IW;
    rb.h = IH;
    rb.nvar = 6;
    rb.px = (frag_rec *)calloc(IW * IH, sizeof(frag_rec));
    cr_assert_not_null(rb.px);
    tu_fb_init(&fb, IW, IH, TU_COLOR8);
    tu_fb_bind(ctx, &fb);
    for (k = 0; k < 6; k++) {
        project(eye[floor_idx[k]], v + 10 * k);
        floor_varyings(eye[floor_idx[k]], v + 10 * k + 4);
    }
    memset(&s, 0, sizeof s);
    s.fragment_fn = record_fragment;
    s.fragment_user = &rb;
    tu_set_state(ctx, &s);
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 6, 6), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < IH; y++)
        for (x = 0; x < IW; x++) {
            const frag_rec *r = &rb.px[y * IW + x];
            double e[6], depth, w;
            TU_CHECK(&chk, r->hits <= 1, "(%d,%d) shaded %d times", x, y, r->hits);
            if (r->hits != 1) continue;
            floor_analytic_h(x, y, -0.25, e, &depth, &w);
            /* the hit must be on the visible part of the floor */
            TU_CHECK(&chk, e[2] <= -FN * (1 - 1e-3) && e[2] >= -4.01 && fabs(e[0]) <= 1.51,
                     "(%d,%d) shaded but its ray hits the floor at z %g x %g", x, y, e[2], e[0]);
            for (j = 0; j < 6; j++)
                TU_CHECK(&chk, fabs(r->var[j] - e[j]) <= 1e-3 * fmax(1.0, fabs(e[j])),
                         "(%d,%d) varying %d = %.7g, analytic %.7g", x, y, j, r->var[j], e[j]);
            TU_CHECK(&chk, close_rel(r->z, depth, 1e-4, 1e-6), "(%d,%d) depth %.9g vs %.9g", x, y,
                     r->z, depth);
            n++;
        }
    TU_CHECK_DONE(&chk);
    cr_assert(n > 700, "only %ld pixels", n);
    /* row 47 is just beyond the near plane, row 48 just in front of it */
    cr_assert_eq(rb.px[47 * IW + 32].hits, 1);
    cr_assert_eq(rb.px[48 * IW + 32].hits, 0);
    free(rb.px);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- flat shading ------------------------------------------------------ */

/* FLAT uses the varyings of the LAST vertex of each primitive (GL's
   provoking vertex): for triangles in list order, through indices (last
   index), for a near-clipped triangle (the clipper must not pick a new
   vertex's values), and for lines. Checked on the default colour path
   (RGBA32F) and through the callback for all 16 varyings. */
Test(interp, flat_shading_uses_last_vertex) {
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    rec_buf rb;
    tu_check chk = {0, {0}};
    int pass, x, y, j;
    rb.w = IW;
    rb.h = IH;
    rb.nvar = NV;
    rb.px = (frag_rec *)calloc(IW * IH, sizeof(frag_rec));
    cr_assert_not_null(rb.px);
    tu_fb_init(&fb, IW, IH, TU_COLOR32F);
    tu_fb_bind(ctx, &fb);
    for (pass = 0; pass < 4; pass++) {
        /* 0: list, 1: indexed, 2: near-clipped, 3: lines; each vertex k
           carries varyings (k+1)/8 + j/128, distinct per vertex, in [0,1] */
        float v[4 * (4 + NV)];
        const uint32_t idx[3] = {2, 0, 3}; /* last index: vertex 3 */
        rast_draw_desc d;
        rast_state s;
        int last, k, cb;
        const double win[4][2] = {{4, 4}, {60, 10}, {10, 60}, {58, 58}};
        for (k = 0; k < 4; k++) {
            float *o = v + k * (4 + NV);
            double w = 1.0 + k;
            tu_clip_from_window(o, win[k][0], win[k][1], 0.0, w, IW, IH);
            if (pass == 2 && k == 1) { /* behind the near plane (z < -w) */
                o[2] = -2.0f * o[3];
            }
            for (j = 0; j < NV; j++) o[4 + j] = (float)((k + 1) / 8.0 + j / 128.0);
        }
        last = pass == 1 ? 3 : (pass == 3 ? 1 : 2);
        for (cb = 0; cb < 2; cb++) {
            long shaded = 0;
            memset(rb.px, 0, sizeof(frag_rec) * IW * IH);
            memset(fb.rgba32f, 0, sizeof(float) * 4 * IW * IH);
            memset(&s, 0, sizeof s);
            s.shading = RAST_FLAT;
            if (cb) {
                s.fragment_fn = record_fragment;
                s.fragment_user = &rb;
            }
            tu_set_state(ctx, &s);
            memset(&d, 0, sizeof d);
            d.primitive = pass == 3 ? RAST_LINES : RAST_TRIANGLES;
            d.vertices = v;
            d.vertex_count = pass == 3 ? 2 : (pass == 1 ? 4 : 3);
            d.stride = 4 + NV;
            d.num_varyings = NV;
            if (pass == 1) {
                d.indices = idx;
                d.index_count = 3;
            }
            cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
            tu_finish(ctx);
            for (y = 0; y < IH; y++)
                for (x = 0; x < IW; x++) {
                    const float *ev = v + last * (4 + NV) + 4;
                    if (cb) {
                        const frag_rec *r = &rb.px[y * IW + x];
                        if (!r->hits) continue;
                        shaded++;
                        for (j = 0; j < NV; j++)
                            TU_CHECK(&chk, r->var[j] == ev[j],
                                     "pass %d (%d,%d) varying %d = %g, last vertex has %g", pass,
                                     x, y, j, r->var[j], ev[j]);
                    } else {
                        const float *c = tu_pxf(&fb, x, y);
                        if (c[3] == 0) continue;
                        shaded++;
                        TU_CHECK(&chk, c[0] == ev[0] && c[1] == ev[1] && c[2] == ev[2] &&
                                           c[3] == ev[3],
                                 "pass %d (%d,%d) colour %g %g %g %g, last vertex %g %g %g %g",
                                 pass, x, y, c[0], c[1], c[2], c[3], ev[0], ev[1], ev[2], ev[3]);
                    }
                }
            cr_assert(shaded > (pass == 3 ? 40 : 400), "pass %d callback %d drew only %ld", pass,
                      cb, shaded);
        }
    }
    TU_CHECK_DONE(&chk);
    free(rb.px);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}
