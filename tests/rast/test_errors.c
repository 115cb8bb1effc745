/* Errors and robustness: non-finite vertices, invalid arguments and sizes,
   the documented rast_result codes, and allocation failure at every
   allocation of a small frame (no crash, no leak). Where api.h does not pin
   down which of two codes applies, the test accepts both and says so. */
#include "../test_util.h"

static int is_known_result(rast_result r) {
    return r == RAST_OK || r == RAST_ERROR_INVALID_ARGUMENT || r == RAST_ERROR_INVALID_SIZE ||
           r == RAST_ERROR_OUT_OF_MEMORY || r == RAST_ERROR_TARGET_MISMATCH ||
           r == RAST_ERROR_NO_TARGET || r == RAST_ERROR_INDEX_RANGE || r == RAST_ERROR_THREADS;
}

/* ---- non-finite input --------------------------------------------------- */

/* Triangles, points and lines with NaN or infinite position components are
   dropped without crashing, and the finite primitives of the same draw
   still draw exactly their pixels. */
Test(errors, nan_and_inf_vertices_are_dropped) {
    enum { W = 32, H = 32 };
    const float nan = NAN, inf = INFINITY;
    const float bad[6][4] = {{nan, 0, 0, 1}, {0, nan, 0, 1}, {0, 0, nan, 1},
                             {0, 0, 0, nan}, {inf, 0, 0, 1}, {0, -inf, 0, 1}};
    /* good triangles: (2,2)-(12,2)-(2,12) and (20,20)-(30,20)-(20,30) */
    const double good[2][6] = {{2, 2, 12, 2, 2, 12}, {20, 20, 30, 20, 20, 30}};
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    float v[(2 + 6) * 3 * 4];
    int b, k, x, y, n = 0;
    rast_state s;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    /* good, then six triangles each with one bad vertex (in varying
       positions), then good */
    for (k = 0; k < 3; k++) tu_clip_from_window(v + 4 * n++, good[0][2 * k], good[0][2 * k + 1], 0, 1, W, H);
    for (b = 0; b < 6; b++)
        for (k = 0; k < 3; k++) {
            if (k == b % 3) memcpy(v + 4 * n, bad[b], sizeof bad[b]);
            else tu_clip_from_window(v + 4 * n, 8 + 10 * k, 16 + b, 0, 1, W, H);
            n++;
        }
    for (k = 0; k < 3; k++) tu_clip_from_window(v + 4 * n++, good[1][2 * k], good[1][2 * k + 1], 0, 1, W, H);
    tu_state_count(&s);
    tu_set_state(ctx, &s);
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, n, 0), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int ex = tu_ref_covers(good[0], x + 0.5, y + 0.5) + tu_ref_covers(good[1], x + 0.5, y + 0.5);
            TU_CHECK(&chk, *tu_sten(&fb, x, y) == ex, "(%d,%d) = %d expected %d", x, y,
                     *tu_sten(&fb, x, y), ex);
        }
    TU_CHECK_DONE(&chk);
    /* the same vertex array as points and lines: only finite points draw */
    memset(fb.stencil, 0, W * H);
    tu_state_count(&s);
    s.point_size = 3;
    tu_set_state(ctx, &s);
    cr_assert_eq(tu_draw(ctx, RAST_POINTS, v, n, 0), RAST_OK);
    cr_assert_eq(tu_draw(ctx, RAST_LINES, v, n - 1, 0), RAST_OK);
    tu_finish(ctx);
    /* huge but finite values must not crash either */
    {
        const float huge[12] = {1e38f, 1e38f, 0, 1, -1e38f, 3e38f, 0, 1, 0, -3e38f, 0, 1e-38f};
        cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, huge, 3, 0), RAST_OK);
        cr_assert_eq(tu_draw(ctx, RAST_LINES, huge, 2, 0), RAST_OK);
        cr_assert_eq(tu_draw(ctx, RAST_POINTS, huge, 3, 0), RAST_OK);
        tu_finish(ctx);
    }
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* A vertex callback producing NaN positions: its primitives are dropped. */
static int nan_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out) {
    (void)user;
    (void)max_out;
    memcpy(out[0].position, vertex, 4 * sizeof(float));
    if (index == 1) out[0].position[3] = NAN;
    return 1;
}

Test(errors, nan_from_vertex_callback_is_dropped) {
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    rast_state s;
    float v[6 * 4];
    const double xy[12] = {1, 1, 15, 1, 1, 15, 1, 1, 15, 1, 15, 15};
    int i, x, y;
    long sum = 0;
    tu_fb_init(&fb, 16, 16, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (i = 0; i < 6; i++) tu_clip_from_window(v + 4 * i, xy[2 * i], xy[2 * i + 1], 0, 1, 16, 16);
    tu_state_count(&s);
    s.vertex_fn = nan_vertex;
    tu_set_state(ctx, &s);
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 6, 0), RAST_OK);
    tu_finish(ctx);
    /* the second triangle (vertices 3..5) is finite */
    for (y = 0; y < 16; y++)
        for (x = 0; x < 16; x++) {
            cr_assert_eq(*tu_sten(&fb, x, y), tu_ref_covers(xy + 6, x + 0.5, y + 0.5),
                         "(%d,%d)", x, y);
            sum += *tu_sten(&fb, x, y);
        }
    cr_assert(sum > 50);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- contexts ---------------------------------------------------------------- */

Test(errors, context_create_arguments) {
    rast_context_desc cd;
    rast_context *ctx = NULL;
    static const int bad_tiles[] = {-16, 8, 17, 48, 256};
    size_t i;
    memset(&cd, 0, sizeof cd);
    cr_assert_eq(rast_context_create(&cd, NULL), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_context_create(NULL, &ctx), RAST_ERROR_INVALID_ARGUMENT);
    cd.num_threads = -1;
    cr_assert_eq(rast_context_create(&cd, &ctx), RAST_ERROR_INVALID_ARGUMENT, "negative threads");
    cd.num_threads = 1;
    for (i = 0; i < sizeof bad_tiles / sizeof bad_tiles[0]; i++) {
        rast_result r;
        cd.tile_size = bad_tiles[i];
        r = rast_context_create(&cd, &ctx);
        /* a tile size is a count/size: either code is defensible */
        cr_assert(r == RAST_ERROR_INVALID_ARGUMENT || r == RAST_ERROR_INVALID_SIZE,
                  "tile_size %d gave %d", bad_tiles[i], (int)r);
    }
    cd.tile_size = 0;
    cd.allocator.alloc = tu_count_alloc; /* alloc without free */
    cr_assert_eq(rast_context_create(&cd, &ctx), RAST_ERROR_INVALID_ARGUMENT,
                 "an allocator needs both functions");
    cd.allocator.alloc = NULL;
    for (i = 0; i < 4; i++) {
        static const int good_tiles[] = {0, 16, 32, 128};
        cd.tile_size = good_tiles[i];
        cr_assert_eq(rast_context_create(&cd, &ctx), RAST_OK, "tile %d", good_tiles[i]);
        rast_context_destroy(ctx);
    }
    rast_context_destroy(NULL); /* must be a no-op */
}

/* ---- targets -------------------------------------------------------------------- */

Test(errors, target_sizes_strides_and_mismatch) {
    static uint8_t mem[64 * 64 * 16];
    static const int bad_sizes[][2] = {{0, 8}, {8, 0}, {-1, 8}, {8, -5},
                                       {RAST_MAX_TARGET_SIZE + 1, 1}, {1, RAST_MAX_TARGET_SIZE + 1},
                                       {-2147483647 - 1, 4}};
    rast_context *ctx = tu_ctx(1, 16);
    rast_targets t;
    size_t i;
    rast_result r;
    for (i = 0; i < sizeof bad_sizes / sizeof bad_sizes[0]; i++) {
        int w = bad_sizes[i][0], h = bad_sizes[i][1];
        memset(&t, 0, sizeof t);
        t.stencil = (rast_view){mem, w, h, w > 0 ? w : 1};
        cr_assert_eq(rast_set_targets(ctx, &t), RAST_ERROR_INVALID_SIZE, "stencil %dx%d", w, h);
        memset(&t, 0, sizeof t);
        t.color = (rast_view){mem, w, h, w > 0 ? 4 * w : 4};
        cr_assert_eq(rast_set_targets(ctx, &t), RAST_ERROR_INVALID_SIZE, "colour %dx%d", w, h);
    }
    /* mismatched sizes between present views */
    memset(&t, 0, sizeof t);
    t.color = (rast_view){mem, 16, 16, 64};
    t.depth = (rast_view){mem, 16, 15, 64};
    cr_assert_eq(rast_set_targets(ctx, &t), RAST_ERROR_TARGET_MISMATCH);
    t.depth = (rast_view){NULL, 16, 15, 64}; /* absent views do not count */
    t.stencil = (rast_view){mem, 17, 16, 17};
    cr_assert_eq(rast_set_targets(ctx, &t), RAST_ERROR_TARGET_MISMATCH);
    t.stencil = (rast_view){NULL, 0, 0, 0};
    t.accum = (rast_view){mem, 16, 16, 16 * 16};
    cr_assert_eq(rast_set_targets(ctx, &t), RAST_OK);
    t.accum = (rast_view){mem, 8, 16, 8 * 16};
    cr_assert_eq(rast_set_targets(ctx, &t), RAST_ERROR_TARGET_MISMATCH);
    /* positive strides smaller than a row (api.h gives no meaning to zero or
       negative strides, so they are not tested): accept INVALID_SIZE or
       INVALID_ARGUMENT, api.h does not say which */
    {
        static const struct { int which, stride; } bad[] = {
            {0, 63}, {0, 1}, {1, 63}, {1, 4}, {2, 15}, {3, 255}, {4, 16 * 4 - 1}};
        for (i = 0; i < sizeof bad / sizeof bad[0]; i++) {
            memset(&t, 0, sizeof t);
            switch (bad[i].which) {
            case 0: t.color = (rast_view){mem, 16, 16, bad[i].stride}; break;
            case 1: t.depth = (rast_view){mem, 16, 16, bad[i].stride}; break;
            case 2: t.stencil = (rast_view){mem, 16, 16, bad[i].stride}; break;
            case 3: t.accum = (rast_view){mem, 16, 16, bad[i].stride}; break;
            case 4:
                t.color = (rast_view){mem, 16, 16, bad[i].stride};
                t.color_format = RAST_COLOR_RGBA32F; /* 16 bytes per pixel */
                break;
            }
            r = rast_set_targets(ctx, &t);
            cr_assert(r == RAST_ERROR_INVALID_SIZE || r == RAST_ERROR_INVALID_ARGUMENT,
                      "view %d stride %d gave %d", bad[i].which, bad[i].stride, (int)r);
        }
    }
    /* bad colour format, NULL targets, NULL context */
    memset(&t, 0, sizeof t);
    t.color = (rast_view){mem, 16, 16, 64};
    t.color_format = (rast_color_format)7;
    cr_assert_eq(rast_set_targets(ctx, &t), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_set_targets(ctx, NULL), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_set_targets(NULL, &t), RAST_ERROR_INVALID_ARGUMENT);
    /* the largest allowed side works (16384 x 1 stencil) and draws */
    {
        uint8_t *big = calloc(RAST_MAX_TARGET_SIZE, 1);
        rast_state s;
        static const float c[4] = {1, 1, 1, 1};
        long sum = 0;
        int x;
        cr_assert_not_null(big);
        memset(&t, 0, sizeof t);
        t.stencil = (rast_view){big, RAST_MAX_TARGET_SIZE, 1, RAST_MAX_TARGET_SIZE};
        cr_assert_eq(rast_set_targets(ctx, &t), RAST_OK);
        tu_state_count(&s);
        tu_set_state(ctx, &s);
        cr_assert_eq(rast_draw_fullscreen(ctx, 0.5f, c), RAST_OK);
        tu_finish(ctx);
        for (x = 0; x < RAST_MAX_TARGET_SIZE; x++) sum += big[x];
        cr_assert_eq(sum, RAST_MAX_TARGET_SIZE);
        free(big);
    }
    rast_context_destroy(ctx);
}

Test(errors, drawing_without_targets) {
    rast_context *ctx = tu_ctx(1, 16);
    float v[12] = {0, 0, 0, 1, 1, 0, 0, 1, 0, 1, 0, 1};
    static const float c[4] = {1, 1, 1, 1};
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 3, 0), RAST_ERROR_NO_TARGET);
    cr_assert_eq(rast_draw_fullscreen(ctx, 0.5f, c), RAST_ERROR_NO_TARGET);
    cr_assert_eq(rast_finish(ctx), RAST_OK);
    rast_context_destroy(ctx);
}

/* ---- state -------------------------------------------------------------------------- */

/* Every enum field with an out-of-range value is rejected with
   INVALID_ARGUMENT, and a rejected state leaves the previous state in
   effect (GL: an erroneous command has no effect). */
Test(errors, bad_state_enums_rejected_and_ignored) {
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    rast_state good, bad;
    int field;
    static const float c[4] = {1, 1, 1, 1};
    tu_fb_init(&fb, 8, 8, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    memset(&good, 0, sizeof good);
    good.stencil_test = 1;
    good.stencil_front.func = good.stencil_back.func = RAST_ALWAYS;
    good.stencil_front.pass = good.stencil_back.pass = RAST_REPLACE;
    good.stencil_front.ref = good.stencil_back.ref = 42;
    tu_set_state(ctx, &good);
    for (field = 0; field < 20; field++) {
        bad = good;
        switch (field) {
        case 0: bad.cull = (rast_cull)9; break;
        case 1: bad.front_face = (rast_front_face)3; break;
        case 2: bad.shading = (rast_shading)3; break;
        case 3: bad.stencil_front.func = (rast_compare)9; break;
        case 4: bad.stencil_back.fail = (rast_stencil_op)9; break;
        case 5: bad.stencil_front.depth_fail = (rast_stencil_op)-1; break;
        case 6: bad.stencil_back.pass = (rast_stencil_op)100; break;
        case 7: bad.depth_func = (rast_compare)-3; break;
        case 8: bad.blend_src_rgb = (rast_blend_factor)16; break;
        case 9: bad.blend_dst_alpha = (rast_blend_factor)99; break;
        case 10: bad.blend_eq_rgb = (rast_blend_equation)6; break;
        case 11: bad.blend_eq_alpha = (rast_blend_equation)-1; break;
        case 12: bad.fog = (rast_fog_mode)4; break;
        case 13: bad.tex_env = (rast_tex_env)3; break;
        case 14: bad.max_vertex_outputs = RAST_MAX_VERTEX_OUTPUTS + 1; break;
        case 15: bad.max_vertex_outputs = -1; break;
        case 16: bad.stencil_front.fail = (rast_stencil_op)9; break;
        case 17: bad.blend_src_alpha = (rast_blend_factor)-7; break;
        case 18: bad.stencil_back.func = (rast_compare)100; break;
        case 19: bad.blend_dst_rgb = (rast_blend_factor)16; break;
        }
        cr_assert_eq(rast_set_state(ctx, &bad), RAST_ERROR_INVALID_ARGUMENT, "field case %d",
                     field);
    }
    cr_assert_eq(rast_set_state(ctx, NULL), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_set_state(NULL, &good), RAST_ERROR_INVALID_ARGUMENT);
    /* the good state is still the current one */
    cr_assert_eq(rast_draw_fullscreen(ctx, 0.5f, c), RAST_OK);
    tu_finish(ctx);
    cr_assert_eq(*tu_sten(&fb, 3, 3), 42, "a rejected state replaced the current one");
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- draws ----------------------------------------------------------------------- */

Test(errors, bad_draw_descs) {
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    float v[3 * 8] = {0};
    const uint32_t idx_bad[3] = {0, 1, 3};
    const uint32_t idx_huge[3] = {0, 0xFFFFFFFFu, 1};
    rast_draw_desc d, base;
    static const float c[4] = {1, 1, 1, 1};
    int i;
    tu_fb_init(&fb, 8, 8, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    {
        rast_state s;
        tu_state_count(&s);
        tu_set_state(ctx, &s);
    }
    /* a triangle covering the target, for the cases that must draw nothing */
    tu_clip_from_window(v, -10, -10, 0, 1, 8, 8);
    tu_clip_from_window(v + 8, 40, -10, 0, 1, 8, 8);
    tu_clip_from_window(v + 16, -10, 40, 0, 1, 8, 8);
    memset(&base, 0, sizeof base);
    base.vertices = v;
    base.vertex_count = 3;
    base.stride = 8;
    for (i = 0; i < 12; i++) {
        rast_result want = RAST_ERROR_INVALID_ARGUMENT;
        d = base;
        switch (i) {
        case 0: d.primitive = (rast_primitive)4; break;
        case 1: d.primitive = (rast_primitive)-1; break;
        case 2: d.vertex_count = -3; break;
        case 3: d.num_varyings = RAST_MAX_VARYINGS + 1; break;
        case 4: d.num_varyings = -1; break;
        case 5: d.position_size = 2; break;
        case 6: d.position_size = 5; break;
        case 7: d.stride = 3; break;             /* < position_size */
        case 8: d.stride = 6; d.num_varyings = 4; break; /* < 4 + 4 */
        case 9: d.vertices = NULL; break;
        case 10: d.indices = idx_bad; d.index_count = 3; want = RAST_ERROR_INDEX_RANGE; break;
        case 11: d.indices = idx_huge; d.index_count = 3; want = RAST_ERROR_INDEX_RANGE; break;
        }
        cr_assert_eq(rast_draw(ctx, &d), want, "case %d", i);
    }
    d = base;
    d.index_count = -1;
    d.indices = idx_bad;
    cr_assert_eq(rast_draw(ctx, &d), RAST_ERROR_INVALID_ARGUMENT, "negative index_count");
    cr_assert_eq(rast_draw(ctx, NULL), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_draw(NULL, &base), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_draw_fullscreen(ctx, 0.5f, NULL), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_draw_fullscreen(NULL, 0.5f, c), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_clear(ctx, NULL), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_accum(ctx, (rast_accum_op)0, 1.0f), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_accum(ctx, (rast_accum_op)6, 1.0f), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_finish(NULL), RAST_ERROR_INVALID_ARGUMENT);
    tu_finish(ctx);
    {
        int x, y;
        for (y = 0; y < 8; y++)
            for (x = 0; x < 8; x++)
                cr_assert_eq(*tu_sten(&fb, x, y), 0, "a rejected draw drew (%d,%d)", x, y);
    }
    /* empty draws are fine */
    d = base;
    d.vertex_count = 0;
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
    d.vertices = NULL;
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK, "no vertices and a count of 0 is not an error");
    d = base;
    d.indices = idx_bad;
    d.index_count = 0;
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
    /* and the valid draw still works */
    cr_assert_eq(rast_draw(ctx, &base), RAST_OK);
    tu_finish(ctx);
    cr_assert_eq(*tu_sten(&fb, 4, 4), 1);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

Test(errors, result_strings) {
    static const rast_result codes[] = {
        RAST_OK, RAST_ERROR_INVALID_ARGUMENT, RAST_ERROR_INVALID_SIZE,
        RAST_ERROR_OUT_OF_MEMORY, RAST_ERROR_TARGET_MISMATCH, RAST_ERROR_NO_TARGET,
        RAST_ERROR_INDEX_RANGE, RAST_ERROR_THREADS};
    size_t i, j;
    for (i = 0; i < sizeof codes / sizeof codes[0]; i++) {
        const char *s = rast_result_string(codes[i]);
        cr_assert(s != NULL && s[0] != '\0', "code %d", (int)codes[i]);
        for (j = 0; j < i; j++)
            cr_assert(strcmp(s, rast_result_string(codes[j])) != 0, "codes %d and %d share \"%s\"",
                      (int)codes[i], (int)codes[j], s);
    }
    cr_assert_not_null(rast_result_string((rast_result)42));
    cr_assert_not_null(rast_result_string((rast_result)-1000));
}

/* ---- allocation failure ------------------------------------------------------------- */

static int twice_vertex(void *user, const float *vertex, int index, rast_vertex_out *out,
                        int max_out) {
    int k;
    (void)user;
    (void)index;
    for (k = 0; k < max_out && k < 2; k++) {
        memcpy(out[k].position, vertex, 4 * sizeof(float));
        out[k].position[0] += 0.1f * k;
    }
    return k;
}

/* A small frame with everything that may allocate: context (with worker
   threads), targets, state, clears, triangles (some clipped), many points
   (several chunks with a small batch), lines, a vertex callback with two
   outputs, accumulation, two finishes. Every call must return a known
   code; calls after a failure must keep working or fail cleanly. */
static void small_frame(tu_alloc_counter *c, int threads, int *completed) {
    rast_context_desc cd;
    rast_context *ctx = NULL;
    tu_fb fb;
    rast_state s;
    rast_result r;
    float *v = malloc(sizeof(float) * 4 * 3000);
    int i;
    static const float col[4] = {0.5f, 0.5f, 0.5f, 1};
    cr_assert_not_null(v);
    *completed = 0;
    for (i = 0; i < 3000; i++)
        tu_clip_from_window(v + 4 * i, (i * 37) % 70 - 3, (i * 53) % 50 - 3, (i % 5) * 0.3 - 0.6,
                            i % 7 == 3 ? -0.5 : 1.0, 64, 48);
    memset(&cd, 0, sizeof cd);
    cd.num_threads = threads;
    cd.tile_size = 16;
    cd.batch_bytes = 16384;
    cd.allocator = tu_counting_allocator(c);
    r = rast_context_create(&cd, &ctx);
    cr_assert(is_known_result(r), "create returned %d", (int)r);
    if (r != RAST_OK) {
        cr_assert_null(ctx, "a failed create must not return a context");
        free(v);
        return;
    }
    tu_fb_init(&fb, 64, 48, TU_COLOR8 | TU_DEPTH | TU_STENCIL | TU_ACCUM);
#define CALL(expr)                                                                             \
    do {                                                                                       \
        r = (expr);                                                                            \
        cr_assert(is_known_result(r), "%s returned %d", #expr, (int)r);                        \
    } while (0)
    CALL(rast_set_targets(ctx, &fb.t));
    memset(&s, 0, sizeof s);
    s.depth_test = 1;
    s.blend = 1;
    s.blend_dst_rgb = RAST_ONE;
    CALL(rast_set_state(ctx, &s));
    {
        rast_clear_desc cl;
        memset(&cl, 0, sizeof cl);
        cl.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL | RAST_CLEAR_ACCUM;
        cl.depth = 1;
        CALL(rast_clear(ctx, &cl));
    }
    CALL(tu_draw(ctx, RAST_TRIANGLES, v, 900, 0));
    s.point_size = 3;
    CALL(rast_set_state(ctx, &s));
    CALL(tu_draw(ctx, RAST_POINTS, v, 3000, 0));
    CALL(tu_draw(ctx, RAST_LINES, v, 400, 0));
    CALL(rast_accum(ctx, RAST_LOAD, 0.5f));
    CALL(rast_finish(ctx));
    s.vertex_fn = twice_vertex;
    s.max_vertex_outputs = 2;
    CALL(rast_set_state(ctx, &s));
    CALL(tu_draw(ctx, RAST_TRIANGLES, v, 600, 0));
    CALL(rast_draw_fullscreen(ctx, 0.25f, col));
    CALL(rast_accum(ctx, RAST_RETURN, 1.0f));
    CALL(rast_finish(ctx));
#undef CALL
    *completed = 1;
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
    free(v);
}

/* Counts the allocations of the frame (single-threaded, deterministic),
   then fails allocation k for every k: no crash, a known code from every
   call, and as many frees as allocations afterwards. */
Test(errors, allocation_failure_at_every_allocation, .timeout = 120) {
    tu_alloc_counter c;
    long n, k;
    int completed;
    memset(&c, 0, sizeof c);
    small_frame(&c, 1, &completed);
    cr_assert(completed);
    n = c.attempts;
    cr_assert(n >= 5, "the frame should allocate through the allocator (%ld)", n);
    cr_assert_eq(c.allocs, c.frees, "leak without failures: %ld allocs, %ld frees", c.allocs,
                 c.frees);
    for (k = 1; k <= n; k++) {
        memset(&c, 0, sizeof c);
        c.fail_at = k;
        small_frame(&c, 1, &completed);
        cr_assert_eq(c.failed, 1, "allocation %ld of %ld was never attempted", k, n);
        cr_assert_eq(c.allocs, c.frees, "failing allocation %ld of %ld leaks: %ld allocs, %ld "
                     "frees", k, n, c.allocs, c.frees);
    }
}

/* The same with worker threads (allocation order may vary, so a handful of
   failure points spread over the run): still no leak, no crash. */
Test(errors, allocation_failure_with_threads, .timeout = 120) {
    tu_alloc_counter c;
    long n, k;
    int completed;
    memset(&c, 0, sizeof c);
    small_frame(&c, 3, &completed);
    cr_assert(completed);
    n = c.attempts;
    cr_assert_eq(c.allocs, c.frees);
    for (k = 1; k <= n; k += (n + 15) / 16) {
        memset(&c, 0, sizeof c);
        c.fail_at = k;
        small_frame(&c, 3, &completed);
        cr_assert_eq(c.allocs, c.frees, "failing allocation %ld leaks: %ld allocs, %ld frees", k,
                     c.allocs, c.frees);
    }
}

/* Textures take their own allocator: fail each allocation of a mipmapped
   texture's creation; a failure returns OUT_OF_MEMORY and a NULL texture,
   and nothing leaks. */
Test(errors, texture_allocation_failure) {
    static uint8_t px[32 * 16 * 4];
    rast_texture_desc td;
    rast_texture *tex;
    tu_alloc_counter c;
    long n, k;
    memset(&td, 0, sizeof td);
    td.width = 32;
    td.height = 16;
    td.pixels[0] = px;
    td.mipmaps = 1;
    memset(&c, 0, sizeof c);
    td.allocator = tu_counting_allocator(&c);
    cr_assert_eq(rast_texture_create(&td, &tex), RAST_OK);
    rast_texture_destroy(tex);
    n = c.attempts;
    cr_assert_eq(c.allocs, c.frees);
    for (k = 1; k <= n; k++) {
        rast_result r;
        memset(&c, 0, sizeof c);
        c.fail_at = k;
        tex = (rast_texture *)&c; /* must be overwritten */
        r = rast_texture_create(&td, &tex);
        cr_assert_eq(r, RAST_ERROR_OUT_OF_MEMORY, "failing allocation %ld of %ld gave %d", k, n,
                     (int)r);
        cr_assert_null(tex);
        cr_assert_eq(c.allocs, c.frees, "leak when allocation %ld fails", k);
    }
    cr_assert_eq(rast_texture_create(NULL, &tex), RAST_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(rast_texture_create(&td, NULL), RAST_ERROR_INVALID_ARGUMENT);
    rast_texture_destroy(NULL);
}
