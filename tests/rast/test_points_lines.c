/* Points (integer size N, GL rules) and 1-pixel lines.

   Points, GL 2.1 section 3.4 (non-antialiased): with window position
   (xw, yw), an odd-size point covers the N x N square centred at
   (floor(xw) + 0.5, floor(yw) + 0.5), an even-size one the square centred
   at (floor(xw + 0.5), floor(yw + 0.5)). GL's window y points up; rast.h
   promises images equal to a GL framebuffer read back and flipped, so rows
   are computed in GL's y (yw_gl = H - y_image) and flipped back. Away from
   exact .0/.5 positions this equals the rule applied to the top-down image
   y, and equals "pixel centres inside the square" (what llvmpipe and GL 3+
   point sprites do). At exact ties these rules differ; the random tests
   avoid ties, and the tie tests are separate (see tie_first below for the
   rule they assert).

   Lines: GL's diamond-exit rule, with the latitude GL 2.1 section 3.5
   explicitly grants (fragments within one unit of the diamond-exit ones,
   at most one fragment more or less, never two fragments in one column of
   an x-major line). So every major-axis column strictly between the end
   points has exactly one fragment, and each end column at most one. */
#include "../test_util.h"

/* first pixel of the GL 2.1 span of size n around coordinate c (any axis,
   in GL's orientation) */
static int gl_point_first(double c, int n) {
    if (n & 1) return (int)floor(c) - (n - 1) / 2;
    return (int)floor(c + 0.5) - n / 2;
}

/* The rule asserted at exact ties. Default: the rule src/rast/setup.c
   documents, "pixel centres in the square [c - N/2, c + N/2) in GL's
   orientation: ties go left and down, as in llvmpipe", i.e. the first
   pixel is ceil(c - N/2 - 0.5). Define RAST_TEST_POINT_TIES_GL21 to assert
   GL 2.1 section 3.4 literally instead (floor-based, see gl_point_first),
   which differs exactly at ties: e.g. a size-1 point at x = 10.0 is column
   10 under GL 2.1 and column 9 under the square rule. Away from ties both
   equal gl_point_first. */
static int tie_first(double c, int n) {
#ifdef RAST_TEST_POINT_TIES_GL21
    return gl_point_first(c, n);
#else
    return (int)ceil(c - n * 0.5 - 0.5);
#endif
}

/* pixel columns [*x0, *x0 + n) and image rows [*y0, *y0 + n) of a point at
   image position (x, y) in a viewport of height H at the origin, using the
   span rule `first` (in GL orientation) on both axes */
static void point_rect_rule(int (*first)(double, int), double x, double y, int n, int H, int *x0,
                            int *y0) {
    int gl_first_row = first(H - y, n); /* GL rows [r, r + n) */
    *x0 = first(x, n);
    *y0 = H - (gl_first_row + n); /* image row of GL row r + n - 1 */
}

static void point_rect(double x, double y, int n, int H, int *x0, int *y0) {
    point_rect_rule(gl_point_first, x, y, n, H, x0, y0);
}

static void draw_points(rast_context *ctx, const float *v, int n, float size) {
    rast_state s;
    tu_state_count(&s);
    s.point_size = size;
    tu_set_state(ctx, &s);
    cr_assert_eq(tu_draw(ctx, RAST_POINTS, v, n, 0), RAST_OK);
    tu_finish(ctx);
}

/* on the 1/256 grid but at least 1/256 away from multiples of 0.5 */
static double no_tie(tu_rng *r, double lo, double hi) {
    double v;
    do v = tu_rng_grid(r, lo, hi);
    while (fmod(v * 256.0, 128.0) == 0.0);
    return v;
}

/* Sizes 1..8 at random positions (including near and over the target
   edges, so partially visible points are clipped to the target without
   wrapping into neighbouring rows), random clip w: per-pixel hit counts
   equal the sum of the GL squares. */
Test(points, gl_rule_random_positions_sizes_1_to_8) {
    enum { W = 64, H = 48, N = 150 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_rng rng = tu_rng_make(4242);
    tu_check chk = {0, {0}};
    static int expect[W * H];
    float v[N * 4];
    int size, i, x, y;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (size = 1; size <= 8; size++) {
        memset(expect, 0, sizeof expect);
        memset(fb.stencil, 0, W * H);
        for (i = 0; i < N; i++) {
            double px = no_tie(&rng, 0.0, W - 1.0 / 256), py = no_tie(&rng, 0.0, H - 1.0 / 256);
            int x0, y0;
            tu_clip_from_window(v + 4 * i, px, py, tu_rng_range(&rng, -0.9, 0.9),
                                tu_rng_range(&rng, 0.5, 2.0), W, H);
            point_rect(px, py, size, H, &x0, &y0);
            for (y = y0; y < y0 + size; y++)
                for (x = x0; x < x0 + size; x++)
                    if (x >= 0 && y >= 0 && x < W && y < H) expect[y * W + x]++;
        }
        draw_points(ctx, v, N, (float)size);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++)
                TU_CHECK(&chk, *tu_sten(&fb, x, y) == expect[y * W + x],
                         "size %d: pixel (%d,%d) hit %d times, expected %d", size, x, y,
                         *tu_sten(&fb, x, y), expect[y * W + x]);
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* One point per corner and edge with size 7 and 8, centre just inside the
   target: exactly the visible part of each square, nothing elsewhere. */
Test(points, partially_off_target_points_clip) {
    enum { W = 32, H = 32 };
    static const double pos[][2] = {{0.3, 0.2},   {31.7, 0.4},  {0.1, 31.9},
                                    {31.8, 31.6}, {15.3, 0.1},  {31.9, 16.2}};
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int size, i, x, y;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (size = 7; size <= 8; size++)
        for (i = 0; i < 6; i++) {
            float v[4];
            int x0, y0;
            tu_clip_from_window(v, pos[i][0], pos[i][1], 0.0, 1.0, W, H);
            memset(fb.stencil, 0, W * H);
            draw_points(ctx, v, 1, (float)size);
            point_rect(pos[i][0], pos[i][1], size, H, &x0, &y0);
            for (y = 0; y < H; y++)
                for (x = 0; x < W; x++) {
                    int ex = x >= x0 && x < x0 + size && y >= y0 && y < y0 + size;
                    TU_CHECK(&chk, *tu_sten(&fb, x, y) == ex,
                             "size %d at (%g,%g): (%d,%d) = %d expected %d", size, pos[i][0],
                             pos[i][1], x, y, *tu_sten(&fb, x, y), ex);
                }
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Ties: a point exactly on a pixel boundary (x or y = k.0) or on a pixel
   centre (k.5), sizes 1..4, in x and in y separately, compared with
   tie_first (see above for the rule). Hand-computed first column/row under
   the default (square, llvmpipe) rule, which the model must reproduce:
     x = 10.0: size 1 -> 9, 2 -> 9, 3 -> 8, 4 -> 8
     x = 10.5: size 1 -> 10, 2 -> 9, 3 -> 9, 4 -> 8
   (GL 2.1 literal: x = 10.0 -> 10, 9, 9, 8; x = 10.5 -> 10, 10, 9, 9.)
   In y the square rule is applied in GL's upward y, i.e. ties go DOWN in the
   image as well: image y = 10.0, size 1 lights row 10; size 2 at 10.5 lights
   rows 10..11. A real bug caught here: tie handling that differs between
   axes, between odd and even sizes, or from the triangle-like coverage of
   the square. */
static void check_ties(int axis_y) {
    static const double pos[2] = {10.0, 10.5};
#ifndef RAST_TEST_POINT_TIES_GL21
    static const int hand_x[2][4] = {{9, 9, 8, 8}, {10, 9, 9, 8}};
#endif
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int i, n, x, y;
    tu_fb_init(&fb, 32, 32, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (i = 0; i < 2; i++)
        for (n = 1; n <= 4; n++) {
            float v[4];
            int x0, y0;
            double px = axis_y ? 10.25 : pos[i], py = axis_y ? pos[i] : 10.25;
            tu_clip_from_window(v, px, py, 0.0, 1.0, 32, 32);
            memset(fb.stencil, 0, 32 * 32);
            draw_points(ctx, v, 1, (float)n);
            point_rect_rule(tie_first, px, py, n, 32, &x0, &y0);
#ifndef RAST_TEST_POINT_TIES_GL21
            if (!axis_y) cr_assert_eq(x0, hand_x[i][n - 1], "model self-check");
#endif
            for (y = 0; y < 32; y++)
                for (x = 0; x < 32; x++) {
                    int ex = x >= x0 && x < x0 + n && y >= y0 && y < y0 + n;
                    TU_CHECK(&chk, *tu_sten(&fb, x, y) == ex,
                             "size %d at (%g,%g): column %d row %d = %d, expected %d (square "
                             "%d..%d x %d..%d)", n, px, py, x, y, *tu_sten(&fb, x, y), ex, x0,
                             x0 + n - 1, y0, y0 + n - 1);
                }
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

Test(points, ties_in_x) { check_ties(0); }
Test(points, ties_in_y) { check_ties(1); }

/* Points whose vertex is outside the clip volume are discarded: behind the
   eye (w < 0, even though x/w, y/w land on screen), w == 0, z beyond far or
   before near. The same point with positive w draws (sanity). */
Test(points, points_outside_clip_volume_dropped) {
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    int c, x, y;
    tu_fb_init(&fb, 32, 32, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (c = 0; c < 6; c++) {
        float v[4] = {0.25f, -0.25f, 0.0f, 1.0f};
        long sum = 0;
        if (c == 1) { v[0] = -0.5f; v[1] = 0.5f; v[2] = 0.0f; v[3] = -2.0f; } /* w < 0 */
        if (c == 2) { v[0] = 0.0f; v[1] = 0.0f; v[3] = 0.0f; }                /* w == 0 */
        if (c == 3) v[2] = 1.01f;                                             /* beyond far */
        if (c == 4) v[2] = -1.01f;                                            /* before near */
        if (c == 5) { v[0] = -0.5f; v[1] = 0.5f; v[2] = -0.5f; v[3] = -2.0f; } /* w<0, z/w ok */
        memset(fb.stencil, 0, 32 * 32);
        draw_points(ctx, v, 1, 5.0f);
        for (y = 0; y < 32; y++)
            for (x = 0; x < 32; x++) sum += *tu_sten(&fb, x, y);
        if (c == 0) cr_assert_eq(sum, 25, "visible size-5 point: %ld pixels", sum);
        else cr_assert_eq(sum, 0, "case %d must be dropped, drew %ld pixels", c, sum);
    }
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* point_size: 0 means 1, non-integers round to the nearest integer (0.2
   rounds to 0 and becomes 1). */
static void check_point_size(float size, int n) {
    enum { W = 320, H = 320 };
    rast_context *ctx = tu_ctx(2, 64);
    tu_fb fb;
    float v[4];
    long sum = 0, bad = 0;
    int x0, y0, x, y;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    tu_clip_from_window(v, 160.3, 150.7, 0.0, 1.0, W, H);
    draw_points(ctx, v, 1, size);
    point_rect(160.3, 150.7, n, H, &x0, &y0);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int ex = x >= x0 && x < x0 + n && y >= y0 && y < y0 + n;
            sum += *tu_sten(&fb, x, y);
            bad += *tu_sten(&fb, x, y) != ex;
        }
    cr_assert(sum == (long)n * n && bad == 0,
              "point_size %g: %ld pixels (%ld misplaced), expected a %dx%d square", size, sum,
              bad, n, n);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

Test(points, point_size_rounding) {
    static const struct { float size; int n; } cases[] = {
        {0.0f, 1}, {0.2f, 1}, {1.0f, 1}, {2.4f, 2}, {2.6f, 3}, {7.51f, 8}, {256.0f, 256}};
    size_t i;
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) check_point_size(cases[i].size, cases[i].n);
}

/* "rounded to an integer in [1, 256]": like GL, which clamps glPointSize to
   the implementation maximum at rasterisation instead of failing, a size of
   300 draws a 256 x 256 point (just as 0.2 is raised to 1). */
Test(points, point_size_clamped_to_max) { check_point_size(300.0f, 256); }

/* The default colour path for points: varyings 0..3 are the colour. */
Test(points, point_colour_from_varyings) {
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    float v[2 * 8];
    rast_state s;
    int x, y;
    tu_fb_init(&fb, 16, 16, TU_COLOR32F);
    tu_fb_bind(ctx, &fb);
    tu_clip_from_window(v, 4.3, 4.3, 0, 1, 16, 16);
    tu_clip_from_window(v + 8, 11.6, 11.2, 0, 2, 16, 16);
    v[4] = 0.25f; v[5] = 0.5f; v[6] = 0.75f; v[7] = 1.0f;
    v[12] = 1.0f; v[13] = 0.5f; v[14] = 0.0f; v[15] = 0.5f;
    memset(&s, 0, sizeof s);
    s.point_size = 3;
    tu_set_state(ctx, &s);
    cr_assert_eq(tu_draw(ctx, RAST_POINTS, v, 2, 4), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < 16; y++)
        for (x = 0; x < 16; x++) {
            const float *c = tu_pxf(&fb, x, y);
            int a = x >= 3 && x <= 5 && y >= 3 && y <= 5;
            int b = x >= 10 && x <= 12 && y >= 10 && y <= 12;
            if (a) cr_assert(c[0] == 0.25f && c[1] == 0.5f && c[2] == 0.75f && c[3] == 1.0f);
            else if (b) cr_assert(c[0] == 1.0f && c[1] == 0.5f && c[2] == 0.0f && c[3] == 0.5f);
            else cr_assert(c[3] == 0.0f, "(%d,%d) written", x, y);
        }
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- lines ------------------------------------------------------------------ */

/* Checks one drawn line from (x0, y0) to (x1, y1) (window coordinates)
   whose end pixels (sx, sy), (ex, ey) are inside the target: every
   major-axis column strictly between the end columns has exactly one
   fragment, one of the two nearest to the ideal line; each end column has
   at most one; nothing is drawn outside the major range or twice;
   consecutive fragments are 8-connected. With at_centres (both end points
   exactly on pixel centres) at least one end pixel must be drawn: the
   diamond-exit rule draws the start pixel, Bresenham both, an
   implementation that orders the end points canonically one of them. */
static void check_line(const tu_fb *fb, double x0, double y0, double x1, double y1, int at_centres,
                       tu_check *chk, const char *what) {
    int sx = (int)floor(x0), sy = (int)floor(y0), ex = (int)floor(x1), ey = (int)floor(y1);
    int xmajor = fabs(x1 - x0) >= fabs(y1 - y0);
    int s0 = xmajor ? sx : sy, s1 = xmajor ? ex : ey, step = s1 >= s0 ? 1 : -1;
    int M = xmajor ? fb->w : fb->h, m = xmajor ? fb->h : fb->w;
    int i, j, prev = -1000;
    if (at_centres)
        TU_CHECK(chk, *tu_sten(fb, sx, sy) == 1 || *tu_sten(fb, ex, ey) == 1,
                 "%s: neither end pixel (%d,%d) nor (%d,%d) drawn", what, sx, sy, ex, ey);
    for (i = step > 0 ? 0 : M - 1; i >= 0 && i < M; i += step) {
        int count = 0, at = -1, in_range = step > 0 ? (i >= s0 && i <= s1) : (i <= s0 && i >= s1);
        for (j = 0; j < m; j++) {
            int v = xmajor ? *tu_sten(fb, i, j) : *tu_sten(fb, j, i);
            TU_CHECK(chk, v <= 1, "%s: pixel drawn %d times", what, v);
            if (v) {
                count++;
                at = j;
            }
        }
        if (!in_range) {
            TU_CHECK(chk, count == 0, "%s: %d pixels drawn at major %d outside [%d,%d]", what,
                     count, i, s0, s1);
            continue;
        }
        if (i == s1 || i == s0) {
            TU_CHECK(chk, count <= 1, "%s: %d pixels at end column %d", what, count, i);
        } else {
            TU_CHECK(chk, count == 1, "%s: %d pixels at major %d (expected 1)", what, count, i);
        }
        if (count == 1) {
            /* ideal minor coordinate at this major pixel centre */
            double t = xmajor ? (i + 0.5 - x0) / (x1 - x0) : (i + 0.5 - y0) / (y1 - y0);
            double ideal = xmajor ? y0 + t * (y1 - y0) : x0 + t * (x1 - x0);
            TU_CHECK(chk, fabs(at + 0.5 - ideal) < 1.0, "%s: major %d minor %d, ideal %.3f",
                     what, i, at, ideal);
            if (prev != -1000)
                TU_CHECK(chk, abs(at - prev) <= 1, "%s: gap between steps at major %d", what, i);
            prev = at;
        }
    }
}

/* Random lines in all octants (random clip w per end point): half with end
   points exactly on pixel centres, half anywhere inside their pixels. */
Test(lines, random_lines_are_connected_one_pixel_paths) {
    enum { W = 64, H = 64 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_rng rng = tu_rng_make(11);
    tu_check chk = {0, {0}};
    int l;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (l = 0; l < 400; l++) {
        int sx, sy, ex, ey, centres = l & 1;
        double p[4];
        float v[8];
        char what[96];
        rast_state s;
        do {
            sx = tu_rng_int(&rng, 1, W - 2);
            sy = tu_rng_int(&rng, 1, H - 2);
            ex = tu_rng_int(&rng, 1, W - 2);
            ey = tu_rng_int(&rng, 1, H - 2);
        } while (abs(abs(ex - sx) - abs(ey - sy)) < 2); /* clear major axis */
        p[0] = sx + (centres ? 0.5 : tu_rng_grid(&rng, 0.01, 0.99));
        p[1] = sy + (centres ? 0.5 : tu_rng_grid(&rng, 0.01, 0.99));
        p[2] = ex + (centres ? 0.5 : tu_rng_grid(&rng, 0.01, 0.99));
        p[3] = ey + (centres ? 0.5 : tu_rng_grid(&rng, 0.01, 0.99));
        tu_clip_from_window(v, p[0], p[1], 0, tu_rng_range(&rng, 0.5, 2), W, H);
        tu_clip_from_window(v + 4, p[2], p[3], 0, tu_rng_range(&rng, 0.5, 2), W, H);
        memset(fb.stencil, 0, W * H);
        tu_state_count(&s);
        tu_set_state(ctx, &s);
        cr_assert_eq(tu_draw(ctx, RAST_LINES, v, 2, 0), RAST_OK);
        tu_finish(ctx);
        snprintf(what, sizeof what, "line %d (%.3f,%.3f)-(%.3f,%.3f)", l, p[0], p[1], p[2], p[3]);
        check_line(&fb, p[0], p[1], p[2], p[3], centres, &chk, what);
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Lines leaving the target: the visible columns after the start column
   still get exactly one pixel each (the start column at most one), and
   nothing wraps around into other rows or columns. */
Test(lines, lines_leaving_the_target) {
    enum { W = 48, H = 40 };
    static const double seg[][4] = {{10.5, 10.5, -30.3, 20.2},
                                    {40.5, 5.5, 90.2, -12.7},
                                    {20.4, 30.6, 25.3, 95.1}};
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int i, x, y;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (i = 0; i < 3; i++) {
        float v[8];
        rast_state s;
        const double *q = seg[i];
        int xmajor = fabs(q[2] - q[0]) >= fabs(q[3] - q[1]);
        int lo, hi, M;
        tu_clip_from_window(v, q[0], q[1], 0, 1, W, H);
        tu_clip_from_window(v + 4, q[2], q[3], 0, 1, W, H);
        memset(fb.stencil, 0, W * H);
        tu_state_count(&s);
        tu_set_state(ctx, &s);
        cr_assert_eq(tu_draw(ctx, RAST_LINES, v, 2, 0), RAST_OK);
        tu_finish(ctx);
        /* visible major range: from the start pixel to the target edge */
        M = xmajor ? W : H;
        if ((xmajor ? q[2] - q[0] : q[3] - q[1]) < 0) {
            lo = 0;
            hi = (int)floor(xmajor ? q[0] : q[1]);
        } else {
            lo = (int)floor(xmajor ? q[0] : q[1]);
            hi = M - 1;
        }
        for (x = 0; x < M; x++) {
            int count = 0;
            for (y = 0; y < (xmajor ? H : W); y++) count += xmajor ? *tu_sten(&fb, x, y) : *tu_sten(&fb, y, x);
            if (x == (int)floor(xmajor ? q[0] : q[1]))
                TU_CHECK(&chk, count <= 1, "segment %d: %d pixels at start column %d", i, count,
                         x);
            else if (x >= lo && x <= hi)
                TU_CHECK(&chk, count == 1, "segment %d: %d pixels at major %d", i, count, x);
            else
                TU_CHECK(&chk, count == 0, "segment %d: %d pixels at major %d (outside)", i,
                         count, x);
        }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* A line from a visible point to a point in front of the near plane (z < -w,
   w > 0) and another to a point behind the eye (w < 0): only the part from
   P0 to the near-plane intersection Pc may be drawn: all pixels within one
   pixel of the projected segment P0..Pc, reaching both of its ends (within
   2.5 px: the last column may be omitted), with about one pixel per major
   step. Both vertex orders, so both clipping branches are used. (Without clipping the w < 0
   case projects the wrong way.) */
Test(lines, near_clipped_lines) {
    enum { W = 64, H = 64 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int c, x, y;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (c = 0; c < 4; c++) {
        /* P0 at window (8.5, 8.5), w = 1, z = 0; c & 2: drawn from P1 to P0 */
        double P0[4] = {8.5 / 32 - 1, 1 - 8.5 / 32, 0.0, 1.0};
        double P1[4];
        double t, Pc[4], a[2], b[2], len;
        float v[8];
        rast_state s;
        long count = 0;
        int k;
        if (!(c & 1)) { P1[0] = 0.9 * 2; P1[1] = -0.7 * 2; P1[2] = -3.0; P1[3] = 2.0; }
        else { P1[0] = 8.13; P1[1] = -7.54; P1[2] = -6.0; P1[3] = -1.0; } /* behind the eye;
            its naive projection (-8.13, 7.54) lies up-left, the visible part runs
            down-right to NDC (0.5, -0.4) */
        /* near plane: z + w = 0 along P0 + t (P1 - P0) */
        t = (P0[2] + P0[3]) / ((P0[2] + P0[3]) - (P1[2] + P1[3]));
        for (k = 0; k < 4; k++) Pc[k] = P0[k] + t * (P1[k] - P0[k]);
        cr_assert(t > 0 && t < 1 && Pc[3] > 0);
        a[0] = (P0[0] / P0[3] + 1) * 32;
        a[1] = (1 - P0[1] / P0[3]) * 32;
        b[0] = (Pc[0] / Pc[3] + 1) * 32;
        b[1] = (1 - Pc[1] / Pc[3]) * 32;
        len = fmax(fabs(b[0] - a[0]), fabs(b[1] - a[1]));
        cr_assert(len > 10, "test geometry: visible part %g px", len);
        for (k = 0; k < 4; k++) {
            v[(c & 2 ? 4 : 0) + k] = (float)P0[k];
            v[(c & 2 ? 0 : 4) + k] = (float)P1[k];
        }
        memset(fb.stencil, 0, W * H);
        tu_state_count(&s);
        tu_set_state(ctx, &s);
        cr_assert_eq(tu_draw(ctx, RAST_LINES, v, 2, 0), RAST_OK);
        tu_finish(ctx);
        {
            double da = 1e9, db = 1e9;
            for (y = 0; y < H; y++)
                for (x = 0; x < W; x++)
                    if (*tu_sten(&fb, x, y)) {
                        da = fmin(da, hypot(x + 0.5 - a[0], y + 0.5 - a[1]));
                        db = fmin(db, hypot(x + 0.5 - b[0], y + 0.5 - b[1]));
                    }
            /* 2.5: the last column may be omitted (GL's one-fragment latitude) */
            TU_CHECK(&chk, da <= 2.5 && db <= 2.5, "case %d: the drawn part does not reach its "
                     "ends: %.2f px from P0 (%.2f,%.2f), %.2f px from Pc (%.2f,%.2f)", c, da, a[0],
                     a[1], db, b[0], b[1]);
        }
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                double px = x + 0.5, py = y + 0.5, dx = b[0] - a[0], dy = b[1] - a[1];
                double u = ((px - a[0]) * dx + (py - a[1]) * dy) / (dx * dx + dy * dy);
                double qx, qy, dist;
                if (!*tu_sten(&fb, x, y)) continue;
                count++;
                u = fmin(1.0, fmax(0.0, u));
                qx = a[0] + u * dx;
                qy = a[1] + u * dy;
                dist = hypot(px - qx, py - qy);
                TU_CHECK(&chk, dist <= 1.0, "case %d: pixel (%d,%d) is %.2f px from the visible "
                         "segment (%.2f,%.2f)-(%.2f,%.2f)", c, x, y, dist, a[0], a[1], b[0], b[1]);
            }
        TU_CHECK(&chk, count >= len - 2 && count <= len + 2,
                 "case %d: %ld pixels for a %.1f px long visible segment", c, count, len);
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}
