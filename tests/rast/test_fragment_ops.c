/* Per-fragment operations against a small CPU model of GL 2.1 semantics:
   stencil (every func x op x masks x path, two-sided), depth (every func,
   write mask, offset), blending (every factor and equation), colour mask,
   scissor, clears, fog, accumulation, full-screen passes, target strides.

   Buffers are filled directly in memory between rast_finish() calls (the
   API allows that: target memory is ours outside draw..finish) so that one
   full-screen draw exercises hundreds of different stored values at once.
   Float targets use values that are multiples of 1/16, so every product
   and sum in the model is exact and float results can be compared with ==. */
#include "../test_util.h"

/* ---- the model ---------------------------------------------------------- */

static const rast_compare all_funcs[9] = {RAST_COMPARE_DEFAULT, RAST_NEVER, RAST_LESS,
                                          RAST_EQUAL, RAST_LEQUAL, RAST_GREATER,
                                          RAST_NOTEQUAL, RAST_GEQUAL, RAST_ALWAYS};

/* GL: the test passes if  incoming FUNC stored  (for stencil: (ref & mask)
   FUNC (stencil & mask); for depth: fragment z FUNC buffer z). */
static int model_compare(rast_compare f, double a, double b, rast_compare dflt) {
    if (f == RAST_COMPARE_DEFAULT) f = dflt;
    switch (f) {
    case RAST_NEVER: return 0;
    case RAST_LESS: return a < b;
    case RAST_EQUAL: return a == b;
    case RAST_LEQUAL: return a <= b;
    case RAST_GREATER: return a > b;
    case RAST_NOTEQUAL: return a != b;
    case RAST_GEQUAL: return a >= b;
    case RAST_ALWAYS: return 1;
    default: cr_assert_fail("bad func"); return 0;
    }
}

static const rast_stencil_op all_ops[9] = {RAST_STENCIL_OP_DEFAULT, RAST_KEEP, RAST_ZERO,
                                           RAST_REPLACE, RAST_INCR, RAST_DECR,
                                           RAST_INVERT, RAST_INCR_WRAP, RAST_DECR_WRAP};

static unsigned model_mask(unsigned m) { return m == 0 ? 0xFFu : (m & 0xFFu); }

static uint8_t model_stencil_op(rast_stencil_op op, uint8_t s, uint8_t ref, unsigned wmask) {
    unsigned v;
    switch (op) {
    case RAST_STENCIL_OP_DEFAULT:
    case RAST_KEEP: v = s; break;
    case RAST_ZERO: v = 0; break;
    case RAST_REPLACE: v = ref; break;
    case RAST_INCR: v = s == 255 ? 255 : s + 1u; break; /* saturates */
    case RAST_DECR: v = s == 0 ? 0 : s - 1u; break;
    case RAST_INVERT: v = ~(unsigned)s & 0xFFu; break;
    case RAST_INCR_WRAP: v = (s + 1u) & 0xFFu; break;
    case RAST_DECR_WRAP: v = (s + 255u) & 0xFFu; break;
    default: cr_assert_fail("bad op"); v = s;
    }
    wmask = model_mask(wmask);
    return (uint8_t)((s & ~wmask) | (v & wmask));
}

/* stencil stage + depth stage for one fragment; returns whether the colour
   is written; updates *s and *d */
static int model_fragment(const rast_state *st, int front, float z, uint8_t *s, float *d,
                          int have_depth, int have_stencil) {
    const rast_stencil_face *f = front ? &st->stencil_front : &st->stencil_back;
    int spass = 1, dpass = 1;
    if (st->stencil_test && have_stencil) {
        unsigned rm = model_mask(f->read_mask);
        spass = model_compare(f->func, f->ref & rm, *s & rm, RAST_ALWAYS);
        if (!spass) {
            *s = model_stencil_op(f->fail, *s, f->ref, f->write_mask);
            return 0;
        }
    }
    if (st->depth_test && have_depth) {
        dpass = model_compare(st->depth_func, z, *d, RAST_LESS);
        if (!dpass) {
            if (st->stencil_test && have_stencil)
                *s = model_stencil_op(f->depth_fail, *s, f->ref, f->write_mask);
            return 0;
        }
        if (!st->depth_write_disabled) *d = z;
    }
    if (st->stencil_test && have_stencil)
        *s = model_stencil_op(f->pass, *s, f->ref, f->write_mask);
    return 1;
}

static void fullscreen(rast_context *ctx, float z, float r, float g, float b, float a) {
    const float c[4] = {r, g, b, a};
    rast_result res = rast_draw_fullscreen(ctx, z, c);
    cr_assert_eq(res, RAST_OK, "rast_draw_fullscreen = %d", (int)res);
}

static void fill_f(float *p, size_t n, float v) {
    size_t i;
    for (i = 0; i < n; i++) p[i] = v;
}

/* ---- stencil --------------------------------------------------------------- */

/* A stencil test with both faces alike: func, ref, read/write masks, and
   the ops rotated by `o` through all_ops (fail, depth_fail, pass). */
static rast_state stencil_state(rast_compare func, uint8_t ref, const unsigned masks[2], int o) {
    rast_state s;
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = func;
    s.stencil_front.ref = ref;
    s.stencil_front.read_mask = masks[0];
    s.stencil_front.write_mask = masks[1];
    s.stencil_front.fail = all_ops[o];
    s.stencil_front.depth_fail = all_ops[(o + 3) % 9];
    s.stencil_front.pass = all_ops[(o + 5) % 9];
    s.stencil_back = s.stencil_front;
    return s;
}

/* Every func (incl. the default ALWAYS) x ref x read/write mask pairs x
   every op on every path. A 32x16 target holds all 256 stencil values in
   its left half, where the depth test passes (buffer 1.0 vs z 0.5), and
   again in its right half, where it fails (buffer 0.25): so fail,
   depth_fail and pass paths, saturation at 0/255 and wrapping are all hit
   in each draw. The ops rotate so every op appears on every path. Colour
   and depth must change exactly where both tests pass. */
Test(fragment_ops, stencil_every_func_op_mask_and_path) {
    static const uint8_t refs[] = {0x00, 0x5A, 0x80, 0xFF};
    static const unsigned masks[][2] = {
        {0, 0}, {RAST_MASK(0xFF), RAST_MASK(0xFF)}, {RAST_MASK(0x0F), RAST_MASK(0xF0)},
        {RAST_MASK(0xF0), RAST_MASK(0x0F)}, {RAST_MASK(0), RAST_MASK(0)},
        {RAST_MASK(0x3C), 0}, {0, RAST_MASK(0x81)}};
    enum { W = 32, H = 16 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    size_t fi, ri, mi;
    int o, x, y;
    tu_fb_init(&fb, W, H, TU_COLOR32F | TU_DEPTH | TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (fi = 0; fi < 9; fi++)
        for (ri = 0; ri < sizeof refs; ri++)
            for (mi = 0; mi < sizeof masks / sizeof masks[0]; mi++)
                for (o = 0; o < 9; o++) {
                    rast_state s = stencil_state(all_funcs[fi], refs[ri], masks[mi], o);
                    s.depth_test = 1; /* default func LESS */
                    for (y = 0; y < H; y++)
                        for (x = 0; x < W; x++) {
                            *tu_sten(&fb, x, y) = (uint8_t)(y * 16 + (x & 15));
                            *tu_depth(&fb, x, y) = x < 16 ? 1.0f : 0.25f;
                        }
                    fill_f(fb.rgba32f, 4 * W * H, 0.125f);
                    tu_set_state(ctx, &s);
                    fullscreen(ctx, 0.5f, 1.0f, 0.5f, 0.25f, 0.75f);
                    tu_finish(ctx);
                    for (y = 0; y < H; y++)
                        for (x = 0; x < W; x++) {
                            uint8_t es = (uint8_t)(y * 16 + (x & 15));
                            float ed = x < 16 ? 1.0f : 0.25f;
                            int wr = model_fragment(&s, 1, 0.5f, &es, &ed, 1, 1);
                            const float *c = tu_pxf(&fb, x, y);
                            TU_CHECK(&chk, *tu_sten(&fb, x, y) == es,
                                     "func %d ref 0x%02x masks %03x/%03x ops %d/%d/%d: stored "
                                     "0x%02x depth %s -> 0x%02x, expected 0x%02x",
                                     (int)all_funcs[fi], refs[ri], masks[mi][0], masks[mi][1],
                                     (int)s.stencil_front.fail, (int)s.stencil_front.depth_fail,
                                     (int)s.stencil_front.pass, y * 16 + (x & 15),
                                     x < 16 ? "pass" : "fail", *tu_sten(&fb, x, y), es);
                            TU_CHECK(&chk, *tu_depth(&fb, x, y) == ed,
                                     "func %d: depth at (%d,%d) = %g expected %g",
                                     (int)all_funcs[fi], x, y, *tu_depth(&fb, x, y), ed);
                            TU_CHECK(&chk, (c[0] == 1.0f) == wr && (wr || c[0] == 0.125f),
                                     "func %d ref 0x%02x: colour at (%d,%d) written=%d, "
                                     "expected %d", (int)all_funcs[fi], refs[ri], x, y,
                                     c[0] == 1.0f, wr);
                        }
                }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Pure stencil passes (no depth test, colour masked off: the papers'
   "apply stencil to every pixel"), which rast.h runs as a table or, for
   the common ops, 16 values at a time: every func x ref x mask pair x op
   on rows of 37 values (a SIMD run and a tail; with 16-pixel tiles, runs
   split by tiles) holding all 256 values, 0 and 255 within SIMD runs,
   against the GL model. */
Test(fragment_ops, pure_stencil_passes_every_func_op_and_mask) {
    static const uint8_t refs[] = {0x00, 0x5A, 0xFF};
    static const unsigned masks[][2] = {
        {0, 0}, {RAST_MASK(0x0F), RAST_MASK(0xF0)}, {RAST_MASK(0xF0), RAST_MASK(0x0F)},
        {RAST_MASK(0), RAST_MASK(0)}, {0, RAST_MASK(0x81)}};
    enum { W = 37, H = 8 };
    tu_check chk = {0, {0}};
    int tile;
    for (tile = 16; tile <= 64; tile *= 4) {
        rast_context *ctx = tu_ctx(2, tile);
        tu_fb fb;
        size_t fi, ri, mi;
        int o, x, y;
        tu_fb_init(&fb, W, H, TU_STENCIL);
        tu_fb_bind(ctx, &fb);
        for (fi = 0; fi < 9; fi++)
            for (ri = 0; ri < sizeof refs; ri++)
                for (mi = 0; mi < sizeof masks / sizeof masks[0]; mi++)
                    for (o = 0; o < 9; o++) {
                        rast_state s = stencil_state(all_funcs[fi], refs[ri], masks[mi], o);
                        s.color_write = RAST_MASK(0);
                        for (y = 0; y < H; y++)
                            for (x = 0; x < W; x++) *tu_sten(&fb, x, y) = (uint8_t)(y * W + x + 7);
                        tu_set_state(ctx, &s);
                        fullscreen(ctx, 0.5f, 1, 1, 1, 1);
                        tu_finish(ctx);
                        for (y = 0; y < H; y++)
                            for (x = 0; x < W; x++) {
                                uint8_t es = (uint8_t)(y * W + x + 7);
                                float ed = 1.0f;
                                model_fragment(&s, 1, 0.5f, &es, &ed, 0, 1);
                                TU_CHECK(&chk, *tu_sten(&fb, x, y) == es,
                                         "tile %d func %d ref 0x%02x masks %03x/%03x ops %d/%d: 0x%02x -> 0x%02x, "
                                         "expected 0x%02x", tile, (int)all_funcs[fi], refs[ri], masks[mi][0],
                                         masks[mi][1], (int)s.stencil_front.fail, (int)s.stencil_front.pass,
                                         (y * W + x + 7) & 255, *tu_sten(&fb, x, y), es);
                            }
                    }
        rast_context_destroy(ctx);
        tu_fb_free(&fb);
    }
    TU_CHECK_DONE(&chk);
}

/* Without the depth test, stencil uses the pass op (never depth_fail) and
   the depth buffer is not written (GL: depth writes need the test
   enabled). With the stencil test disabled the stencil buffer is never
   written whatever the ops say. */
Test(fragment_ops, stencil_and_depth_disabled_paths) {
    enum { W = 16, H = 16 };
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    rast_state s;
    int x, y;
    tu_fb_init(&fb, W, H, TU_COLOR32F | TU_DEPTH | TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    /* 1: stencil on, depth off */
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            *tu_sten(&fb, x, y) = (uint8_t)(y * 16 + x);
            *tu_depth(&fb, x, y) = 0.0f; /* would fail LESS */
        }
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = RAST_ALWAYS;
    s.stencil_front.depth_fail = RAST_ZERO;
    s.stencil_front.pass = RAST_INCR_WRAP;
    s.stencil_back = s.stencil_front;
    tu_set_state(ctx, &s);
    fullscreen(ctx, 0.5f, 1, 1, 1, 1);
    tu_finish(ctx);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            TU_CHECK(&chk, *tu_sten(&fb, x, y) == (uint8_t)(y * 16 + x + 1),
                     "depth off: stencil (%d,%d) = %d, expected pass op", x, y,
                     *tu_sten(&fb, x, y));
            TU_CHECK(&chk, *tu_depth(&fb, x, y) == 0.0f, "depth off: depth written at (%d,%d)", x,
                     y);
            TU_CHECK(&chk, tu_pxf(&fb, x, y)[0] == 1.0f, "depth off: colour not written");
        }
    /* 2: stencil off, depth on (passes): ops configured but inactive */
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            *tu_sten(&fb, x, y) = (uint8_t)(y * 16 + x);
            *tu_depth(&fb, x, y) = 1.0f;
        }
    s.stencil_test = 0;
    s.stencil_front.fail = s.stencil_front.pass = s.stencil_front.depth_fail = RAST_INVERT;
    s.stencil_back = s.stencil_front;
    s.depth_test = 1;
    tu_set_state(ctx, &s);
    fullscreen(ctx, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f);
    tu_finish(ctx);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            TU_CHECK(&chk, *tu_sten(&fb, x, y) == (uint8_t)(y * 16 + x),
                     "stencil off: stencil (%d,%d) changed", x, y);
            TU_CHECK(&chk, *tu_depth(&fb, x, y) == 0.5f, "depth on: depth (%d,%d) = %g", x, y,
                     *tu_depth(&fb, x, y));
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* GL: with no depth buffer the depth test always passes; with no stencil
   buffer the stencil test always passes. */
Test(fragment_ops, missing_depth_or_stencil_buffer_passes) {
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    rast_state s;
    tu_fb_init(&fb, 8, 8, TU_COLOR32F);
    tu_fb_bind(ctx, &fb);
    memset(&s, 0, sizeof s);
    s.depth_test = 1;
    s.depth_func = RAST_NEVER;
    tu_set_state(ctx, &s);
    fullscreen(ctx, 0.5f, 1, 1, 1, 1);
    tu_finish(ctx);
    cr_assert_eq(tu_pxf(&fb, 3, 3)[0], 1.0f, "no depth buffer: the depth test must pass");
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = s.stencil_back.func = RAST_NEVER;
    tu_set_state(ctx, &s);
    fullscreen(ctx, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f);
    tu_finish(ctx);
    cr_assert_eq(tu_pxf(&fb, 3, 3)[0], 0.5f, "no stencil buffer: the stencil test must pass");
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Two-sided stencil: front faces (CCW in NDC, i.e. negative image-space
   area) use stencil_front, back faces stencil_back, with different funcs,
   refs, masks and ops; front_face = CW swaps which triangles are front. */
Test(fragment_ops, stencil_two_sided) {
    enum { W = 32, H = 16 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    /* left square: image-space area < 0 (CCW in NDC); right square: > 0 */
    const double quads[24] = {0, 0, 0, 16, 16, 16, 0, 0, 16, 16, 16, 0,
                              16, 0, 32, 0, 32, 16, 16, 0, 32, 16, 16, 16};
    int ff, x, y;
    cr_assert(tu_area_img(0, 0, 0, 16, 16, 16) < 0 && tu_area_img(16, 0, 32, 0, 32, 16) > 0);
    tu_fb_init(&fb, W, H, TU_COLOR32F | TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (ff = 0; ff < 2; ff++) {
        rast_state s;
        memset(&s, 0, sizeof s);
        s.front_face = ff ? RAST_CW : RAST_CCW;
        s.stencil_test = 1;
        s.stencil_front.func = RAST_GEQUAL;
        s.stencil_front.ref = 0x80;
        s.stencil_front.fail = RAST_DECR;
        s.stencil_front.pass = RAST_INCR;
        s.stencil_back.func = RAST_EQUAL;
        s.stencil_back.ref = 0x05;
        s.stencil_back.read_mask = RAST_MASK(0x0F);
        s.stencil_back.write_mask = RAST_MASK(0x3F);
        s.stencil_back.fail = RAST_INVERT;
        s.stencil_back.pass = RAST_REPLACE;
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) *tu_sten(&fb, x, y) = (uint8_t)(y * 16 + (x & 15));
        tu_set_state(ctx, &s);
        tu_draw_tris_px(ctx, W, H, quads, 4, 0.0);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                uint8_t es = (uint8_t)(y * 16 + (x & 15));
                float ed = 0;
                int left = x < 16, front = ff ? !left : left;
                model_fragment(&s, front, 0.5f, &es, &ed, 0, 1);
                TU_CHECK(&chk, *tu_sten(&fb, x, y) == es,
                         "front_face %s: (%d,%d) %s face: stencil 0x%02x, expected 0x%02x",
                         ff ? "CW" : "CCW", x, y, front ? "front" : "back", *tu_sten(&fb, x, y),
                         es);
            }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- depth ---------------------------------------------------------------- */

/* Every func x fragment z in {0, .25, .5, .75, 1} against buffers holding
   the same five values, with and without depth writes. */
Test(fragment_ops, depth_every_func_and_write_mask) {
    static const float zs[5] = {0.0f, 0.25f, 0.5f, 0.75f, 1.0f};
    enum { W = 5, H = 4 };
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int fi, zi, wd, x, y;
    tu_fb_init(&fb, W, H, TU_COLOR32F | TU_DEPTH);
    tu_fb_bind(ctx, &fb);
    for (fi = 0; fi < 9; fi++)
        for (zi = 0; zi < 5; zi++)
            for (wd = 0; wd < 2; wd++) {
                rast_state s;
                memset(&s, 0, sizeof s);
                s.depth_test = 1;
                s.depth_func = all_funcs[fi];
                s.depth_write_disabled = wd;
                for (y = 0; y < H; y++)
                    for (x = 0; x < W; x++) *tu_depth(&fb, x, y) = zs[x];
                fill_f(fb.rgba32f, 4 * W * H, 0.0f);
                tu_set_state(ctx, &s);
                fullscreen(ctx, zs[zi], 1, 1, 1, 1);
                tu_finish(ctx);
                for (y = 0; y < H; y++)
                    for (x = 0; x < W; x++) {
                        int pass = model_compare(all_funcs[fi], zs[zi], zs[x], RAST_LESS);
                        float ed = pass && !wd ? zs[zi] : zs[x];
                        TU_CHECK(&chk, (tu_pxf(&fb, x, y)[0] == 1.0f) == pass,
                                 "func %d: z %g vs buffer %g: colour written %d, expected %d",
                                 (int)all_funcs[fi], zs[zi], zs[x], tu_pxf(&fb, x, y)[0] == 1.0f,
                                 pass);
                        TU_CHECK(&chk, *tu_depth(&fb, x, y) == ed,
                                 "func %d write_disabled %d: z %g vs %g: depth %g expected %g",
                                 (int)all_funcs[fi], wd, zs[zi], zs[x], *tu_depth(&fb, x, y), ed);
                    }
            }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* depth_offset is added to the window z of every fragment, before the test
   and for the written value: full-screen at 0.25 + 0.25 passes EQUAL
   against 0.5; a triangle at z_ndc = -0.5 (depth 0.25) with offset 0.5
   writes 0.75 and then fails LESS against 0.625 where without the offset it
   would pass. */
Test(fragment_ops, depth_offset) {
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    rast_state s;
    const double tri[6] = {-20, -20, 60, -20, -20, 60}; /* covers the 8x8 target */
    tu_fb_init(&fb, 8, 8, TU_COLOR32F | TU_DEPTH);
    tu_fb_bind(ctx, &fb);
    fill_f(fb.depth, 64, 0.5f);
    memset(&s, 0, sizeof s);
    s.depth_test = 1;
    s.depth_func = RAST_EQUAL;
    s.depth_offset = 0.25f;
    tu_set_state(ctx, &s);
    fullscreen(ctx, 0.25f, 1, 1, 1, 1);
    tu_finish(ctx);
    cr_assert_eq(tu_pxf(&fb, 4, 4)[0], 1.0f, "0.25 + offset 0.25 must EQUAL 0.5");
    /* negative offset, LESS, written value includes the offset */
    fill_f(fb.depth, 64, 0.625f);
    s.depth_func = RAST_LESS;
    s.depth_offset = -0.25f;
    tu_set_state(ctx, &s);
    fullscreen(ctx, 0.75f, 0.5f, 0.5f, 0.5f, 0.5f);
    tu_finish(ctx);
    cr_assert_eq(tu_pxf(&fb, 4, 4)[0], 0.5f, "0.75 - 0.25 < 0.625 must pass");
    cr_assert_eq(*tu_depth(&fb, 4, 4), 0.5f, "written depth includes the offset");
    /* triangles */
    fill_f(fb.depth, 64, 1.0f);
    fill_f(fb.rgba32f, 256, 0.0f);
    s.depth_func = RAST_ALWAYS;
    s.depth_offset = 0.5f;
    tu_set_state(ctx, &s);
    tu_draw_tris_px(ctx, 8, 8, tri, 1, -0.5);
    cr_assert_eq(*tu_depth(&fb, 2, 5), 0.75f, "triangle depth 0.25 + 0.5");
    fill_f(fb.depth, 64, 0.625f);
    fill_f(fb.rgba32f, 256, 0.0f);
    s.depth_func = RAST_LESS;
    tu_set_state(ctx, &s);
    tu_draw_tris_px(ctx, 8, 8, tri, 1, -0.5);
    cr_assert_eq(tu_pxf(&fb, 2, 5)[0], 0.0f, "0.75 is not LESS than 0.625");
    s.depth_offset = 0.0f;
    tu_set_state(ctx, &s);
    tu_draw_tris_px(ctx, 8, 8, tri, 1, -0.5);
    cr_assert_eq(tu_pxf(&fb, 2, 5)[0], 1.0f, "without offset 0.25 < 0.625 passes");
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- blending -------------------------------------------------------------- */

static const rast_blend_factor all_factors[16] = {
    RAST_BLEND_FACTOR_DEFAULT, RAST_ZERO_FACTOR, RAST_ONE, RAST_SRC_COLOR,
    RAST_ONE_MINUS_SRC_COLOR, RAST_DST_COLOR, RAST_ONE_MINUS_DST_COLOR, RAST_SRC_ALPHA,
    RAST_ONE_MINUS_SRC_ALPHA, RAST_DST_ALPHA, RAST_ONE_MINUS_DST_ALPHA, RAST_CONSTANT_COLOR,
    RAST_ONE_MINUS_CONSTANT_COLOR, RAST_CONSTANT_ALPHA, RAST_ONE_MINUS_CONSTANT_ALPHA,
    RAST_SRC_ALPHA_SATURATE};
static const rast_blend_equation all_eqs[6] = {RAST_BLEND_EQUATION_DEFAULT, RAST_FUNC_ADD,
                                               RAST_FUNC_SUBTRACT, RAST_FUNC_REVERSE_SUBTRACT,
                                               RAST_FUNC_MIN, RAST_FUNC_MAX};

/* GL 2.1 table 4.1, for channel c (3 = alpha) */
static double model_factor(rast_blend_factor f, int c, const double s[4], const double d[4],
                           const double k[4], int is_src) {
    if (f == RAST_BLEND_FACTOR_DEFAULT) f = is_src ? RAST_ONE : RAST_ZERO_FACTOR;
    switch (f) {
    case RAST_ZERO_FACTOR: return 0;
    case RAST_ONE: return 1;
    case RAST_SRC_COLOR: return s[c];
    case RAST_ONE_MINUS_SRC_COLOR: return 1 - s[c];
    case RAST_DST_COLOR: return d[c];
    case RAST_ONE_MINUS_DST_COLOR: return 1 - d[c];
    case RAST_SRC_ALPHA: return s[3];
    case RAST_ONE_MINUS_SRC_ALPHA: return 1 - s[3];
    case RAST_DST_ALPHA: return d[3];
    case RAST_ONE_MINUS_DST_ALPHA: return 1 - d[3];
    case RAST_CONSTANT_COLOR: return k[c];
    case RAST_ONE_MINUS_CONSTANT_COLOR: return 1 - k[c];
    case RAST_CONSTANT_ALPHA: return k[3];
    case RAST_ONE_MINUS_CONSTANT_ALPHA: return 1 - k[3];
    case RAST_SRC_ALPHA_SATURATE: return c < 3 ? fmin(s[3], 1 - d[3]) : 1.0;
    default: cr_assert_fail("bad factor"); return 0;
    }
}

static double model_blend(const rast_state *st, int c, const double s[4], const double d[4]) {
    const double k[4] = {st->blend_color[0], st->blend_color[1], st->blend_color[2],
                         st->blend_color[3]};
    rast_blend_equation eq = c < 3 ? st->blend_eq_rgb : st->blend_eq_alpha;
    rast_blend_factor sf = c < 3 ? st->blend_src_rgb : st->blend_src_alpha;
    rast_blend_factor df = c < 3 ? st->blend_dst_rgb : st->blend_dst_alpha;
    double a = s[c] * model_factor(sf, c, s, d, k, 1), b = d[c] * model_factor(df, c, s, d, k, 0);
    switch (eq) {
    case RAST_BLEND_EQUATION_DEFAULT:
    case RAST_FUNC_ADD: return a + b;
    case RAST_FUNC_SUBTRACT: return a - b;
    case RAST_FUNC_REVERSE_SUBTRACT: return b - a;
    case RAST_FUNC_MIN: return fmin(s[c], d[c]); /* factors ignored */
    case RAST_FUNC_MAX: return fmax(s[c], d[c]);
    default: cr_assert_fail("bad equation"); return 0;
    }
}

static double sixteenth(tu_rng *r) { return tu_rng_int(r, 0, 16) / 16.0; }

/* Every src factor x dst factor x equation for RGB, with the alpha factors
   and equation rotated independently (so separate alpha state is tested
   too), over 16 destination colours, against the model. Values are
   multiples of 1/16, so on RGBA32F the result is exact. Where the exact
   result leaves [0, 1] (ADD of ONE+ONE, SUBTRACT...), the API does not say
   whether float targets clamp (GL's ARB_color_buffer_float does not for
   float buffers by default), so either the exact or the clamped value is
   accepted there. */
Test(fragment_ops, blend_every_factor_and_equation_rgba32f) {
    enum { W = 4, H = 4 };
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_rng rng = tu_rng_make(8);
    tu_check chk = {0, {0}};
    double dst[W * H][4];
    int i, j, e, p, c;
    long exact = 0;
    tu_fb_init(&fb, W, H, TU_COLOR32F);
    tu_fb_bind(ctx, &fb);
    for (p = 0; p < W * H; p++)
        for (c = 0; c < 4; c++) dst[p][c] = sixteenth(&rng);
    dst[0][3] = 0.0; /* make SRC_ALPHA_SATURATE pick both branches */
    dst[1][3] = 1.0;
    for (i = 0; i < 16; i++)
        for (j = 0; j < 16; j++)
            for (e = 0; e < 6; e++) {
                rast_state s;
                double src[4];
                float srcf[4];
                memset(&s, 0, sizeof s);
                s.blend = 1;
                s.blend_src_rgb = all_factors[i];
                s.blend_dst_rgb = all_factors[j];
                s.blend_eq_rgb = all_eqs[e];
                s.blend_src_alpha = all_factors[(i + 5) % 16];
                s.blend_dst_alpha = all_factors[(j + 11) % 16];
                s.blend_eq_alpha = all_eqs[(e + 2) % 6];
                for (c = 0; c < 4; c++) {
                    s.blend_color[c] = (float)sixteenth(&rng);
                    src[c] = sixteenth(&rng);
                    srcf[c] = (float)src[c];
                }
                for (p = 0; p < W * H; p++)
                    for (c = 0; c < 4; c++) fb.rgba32f[4 * p + c] = (float)dst[p][c];
                tu_set_state(ctx, &s);
                fullscreen(ctx, 0.5f, srcf[0], srcf[1], srcf[2], srcf[3]);
                tu_finish(ctx);
                for (p = 0; p < W * H; p++)
                    for (c = 0; c < 4; c++) {
                        double ex = model_blend(&s, c, src, dst[p]);
                        double cl = fmin(1.0, fmax(0.0, ex));
                        float got = fb.rgba32f[4 * p + c];
                        exact += got == ex;
                        TU_CHECK(&chk, got == ex || (ex != cl && got == cl),
                                 "src %d dst %d eq %d | alpha src %d dst %d eq %d | channel %d: "
                                 "src %g dst %g const %g -> %.9g, expected %.9g",
                                 (int)s.blend_src_rgb, (int)s.blend_dst_rgb, (int)s.blend_eq_rgb,
                                 (int)s.blend_src_alpha, (int)s.blend_dst_alpha,
                                 (int)s.blend_eq_alpha, c, src[c], dst[p][c], s.blend_color[c],
                                 got, ex);
                    }
            }
    TU_CHECK_DONE(&chk);
    cr_assert(exact > 16 * 16 * 6 * 16 * 4 / 2);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* The same on RGBA8 with arbitrary source colours: the destination is read
   as byte/255, the result clamped to [0, 1] and stored rounded; within one
   step of the model. */
Test(fragment_ops, blend_every_factor_and_equation_rgba8) {
    enum { W = 4, H = 4 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_rng rng = tu_rng_make(9);
    tu_check chk = {0, {0}};
    uint8_t dst[W * H][4];
    int i, j, e, p, c;
    tu_fb_init(&fb, W, H, TU_COLOR8);
    tu_fb_bind(ctx, &fb);
    for (p = 0; p < W * H; p++)
        for (c = 0; c < 4; c++) dst[p][c] = (uint8_t)tu_rng_int(&rng, 0, 255);
    dst[0][3] = 0;
    dst[1][3] = 255;
    for (i = 0; i < 16; i++)
        for (j = 0; j < 16; j++)
            for (e = 0; e < 6; e++) {
                rast_state s;
                double src[4];
                float srcf[4];
                memset(&s, 0, sizeof s);
                s.blend = 1;
                s.blend_src_rgb = all_factors[i];
                s.blend_dst_rgb = all_factors[j];
                s.blend_eq_rgb = all_eqs[e];
                s.blend_src_alpha = all_factors[(i + 7) % 16];
                s.blend_dst_alpha = all_factors[(j + 3) % 16];
                s.blend_eq_alpha = all_eqs[(e + 4) % 6];
                for (c = 0; c < 4; c++) {
                    s.blend_color[c] = tu_rng_float(&rng);
                    srcf[c] = tu_rng_float(&rng);
                    src[c] = srcf[c];
                }
                memcpy(fb.rgba8, dst, sizeof dst);
                tu_set_state(ctx, &s);
                fullscreen(ctx, 0.5f, srcf[0], srcf[1], srcf[2], srcf[3]);
                tu_finish(ctx);
                for (p = 0; p < W * H; p++) {
                    double d[4];
                    for (c = 0; c < 4; c++) d[c] = dst[p][c] / 255.0;
                    for (c = 0; c < 4; c++) {
                        int ex = tu_unorm8(model_blend(&s, c, src, d));
                        int got = fb.rgba8[4 * p + c];
                        TU_CHECK(&chk, abs(got - ex) <= 1,
                                 "src %d dst %d eq %d | alpha src %d dst %d eq %d | channel %d: "
                                 "src %g dst %d -> %d, expected %d", (int)s.blend_src_rgb,
                                 (int)s.blend_dst_rgb, (int)s.blend_eq_rgb,
                                 (int)s.blend_src_alpha, (int)s.blend_dst_alpha,
                                 (int)s.blend_eq_alpha, c, src[c], dst[p][c], got, ex);
                    }
                }
            }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Blending through triangles with a per-vertex colour (not only the
   full-screen path), and the order of overlapping triangles in one draw is
   the submission order (blending is not commutative). */
Test(fragment_ops, blend_order_of_overlapping_triangles) {
    rast_context *ctx = tu_ctx(3, 16);
    tu_fb fb;
    rast_state s;
    tu_check chk = {0, {0}};
    float v[3 * 3 * 8];
    int t, k, x, y;
    tu_fb_init(&fb, 48, 48, TU_COLOR32F);
    tu_fb_bind(ctx, &fb);
    memset(&s, 0, sizeof s);
    s.blend = 1;
    s.blend_src_rgb = s.blend_src_alpha = RAST_SRC_ALPHA;
    s.blend_dst_rgb = s.blend_dst_alpha = RAST_ONE_MINUS_SRC_ALPHA;
    tu_set_state(ctx, &s);
    for (t = 0; t < 3; t++)
        for (k = 0; k < 3; k++) {
            static const double xy[3][2] = {{-100, -100}, {300, -100}, {-100, 300}};
            float *o = v + 8 * (3 * t + k);
            tu_clip_from_window(o, xy[k][0], xy[k][1], 0.0, 1.0, 48, 48);
            o[4] = t == 0 ? 1.0f : 0.0f;
            o[5] = t == 1 ? 1.0f : 0.0f;
            o[6] = t == 2 ? 1.0f : 0.0f;
            o[7] = 0.5f;
        }
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 9, 4), RAST_OK);
    tu_finish(ctx);
    /* ((0 * .5 + R * .5) * .5 + G * .5) * .5 + B * .5 = (.125, .25, .5) */
    for (y = 0; y < 48; y++)
        for (x = 0; x < 48; x++) {
            const float *c = tu_pxf(&fb, x, y);
            TU_CHECK(&chk, c[0] == 0.125f && c[1] == 0.25f && c[2] == 0.5f && c[3] == 0.4375f,
                     "(%d,%d) = %g %g %g %g", x, y, c[0], c[1], c[2], c[3]);
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- colour mask, scissor, clears ----------------------------------------- */

/* All 16 channel masks (RAST_MASK(m), and plain bits for m != 0 which the
   state comment also allows), 0 = all channels, on both formats and with
   blending on (the mask applies after blending). */
Test(fragment_ops, color_write_mask_every_combination) {
    int fmt, m, form, x, y, c;
    tu_check chk = {0, {0}};
    for (fmt = 0; fmt < 2; fmt++) {
        rast_context *ctx = tu_ctx(1, 16);
        tu_fb fb;
        tu_fb_init(&fb, 8, 8, fmt ? TU_COLOR32F : TU_COLOR8);
        tu_fb_bind(ctx, &fb);
        for (m = 0; m < 16; m++)
            for (form = 0; form < 3; form++) {
                rast_state s;
                unsigned eff;
                if (form == 1 && m == 0) continue; /* plain 0 means "all", tested below */
                memset(&s, 0, sizeof s);
                s.color_write = form == 0 ? RAST_MASK(m) : form == 1 ? (unsigned)m : 0u;
                eff = form == 2 ? 15u : (unsigned)m;
                s.blend = m & 1;
                s.blend_src_rgb = s.blend_src_alpha = RAST_ONE;
                s.blend_dst_rgb = s.blend_dst_alpha = RAST_ONE;
                if (fmt) fill_f(fb.rgba32f, 256, 0.25f);
                else memset(fb.rgba8, 64, 256);
                tu_set_state(ctx, &s);
                fullscreen(ctx, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f);
                tu_finish(ctx);
                for (y = 0; y < 8; y++)
                    for (x = 0; x < 8; x++)
                        for (c = 0; c < 4; c++) {
                            int on = (eff >> c) & 1;
                            if (fmt) {
                                float ex = on ? (s.blend ? 0.75f : 0.5f) : 0.25f;
                                TU_CHECK(&chk, tu_pxf(&fb, x, y)[c] == ex,
                                         "float mask 0x%x form %d channel %d = %g expected %g",
                                         s.color_write, form, c, tu_pxf(&fb, x, y)[c], ex);
                            } else {
                                int ex = on ? tu_unorm8(s.blend ? 64 / 255.0 + 0.5 : 0.5) : 64;
                                TU_CHECK(&chk, abs(tu_px8(&fb, x, y)[c] - ex) <= 1,
                                         "rgba8 mask 0x%x form %d channel %d = %d expected %d",
                                         s.color_write, form, c, tu_px8(&fb, x, y)[c], ex);
                            }
                        }
            }
        rast_context_destroy(ctx);
        tu_fb_free(&fb);
    }
    TU_CHECK_DONE(&chk);
}

/* The scissor rectangle (x, y from the top-left) limits full-screen passes
   and triangles, also when it extends past the target or is empty; with
   scissor_test = 0 the rectangle is ignored. */
Test(fragment_ops, scissor_rectangles) {
    static const int rects[][4] = {{3, 2, 5, 7}, {-4, -3, 10, 8}, {20, 10, 100, 100},
                                   {0, 0, 0, 5}, {5, 5, 3, 0}, {-100, -100, 1000, 1000},
                                   {40, 0, 5, 5}};
    enum { W = 32, H = 24 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    const double tri[6] = {-50, -50, 200, -50, -50, 200};
    size_t r;
    int path, on, x, y;
    tu_fb_init(&fb, W, H, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (r = 0; r < sizeof rects / sizeof rects[0]; r++)
        for (path = 0; path < 2; path++)
            for (on = 0; on < 2; on++) {
                rast_state s;
                const int *R = rects[r];
                memset(fb.stencil, 0, W * H);
                tu_state_count(&s);
                s.scissor_test = on;
                memcpy(s.scissor, R, sizeof s.scissor);
                tu_set_state(ctx, &s);
                if (path) tu_draw_tris_px(ctx, W, H, tri, 1, 0.0);
                else {
                    fullscreen(ctx, 0.5f, 1, 1, 1, 1);
                    tu_finish(ctx);
                }
                for (y = 0; y < H; y++)
                    for (x = 0; x < W; x++) {
                        int in = !on || (x >= R[0] && x < R[0] + R[2] && y >= R[1] &&
                                         y < R[1] + R[3]);
                        TU_CHECK(&chk, *tu_sten(&fb, x, y) == in,
                                 "scissor (%d,%d,%d,%d) on %d %s: (%d,%d) = %d expected %d",
                                 R[0], R[1], R[2], R[3], on, path ? "triangle" : "fullscreen", x,
                                 y, *tu_sten(&fb, x, y), in);
                    }
            }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Clears honour the scissor, the colour mask, the depth write mask and the
   stencil write mask (GL uses the front mask; both are set equal here);
   the accumulation clear honours only the scissor. The viewport does not
   limit clears (GL). On RGBA32F and RGBA8 colour targets. */
static void check_clears(int rgba8) {
    enum { W = 16, H = 12 };
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    rast_state s;
    rast_clear_desc cd;
    int x, y, c, sc;
    tu_fb_init(&fb, W, H, (rgba8 ? TU_COLOR8 : TU_COLOR32F) | TU_DEPTH | TU_STENCIL | TU_ACCUM);
    tu_fb_bind(ctx, &fb);
    for (sc = 0; sc < 2; sc++) {
        if (rgba8) memset(fb.rgba8, 64, 4 * W * H);
        else fill_f(fb.rgba32f, 4 * W * H, 0.25f);
        fill_f(fb.depth, W * H, 0.25f);
        memset(fb.stencil, 0xA5, W * H);
        fill_f(fb.accum, 4 * W * H, 0.25f);
        memset(&s, 0, sizeof s);
        s.viewport[0] = 1;
        s.viewport[1] = 1;
        s.viewport[2] = 2;
        s.viewport[3] = 2;
        s.scissor_test = sc;
        s.scissor[0] = 4;
        s.scissor[1] = 3;
        s.scissor[2] = 6;
        s.scissor[3] = 5;
        s.color_write = RAST_MASK(RAST_WRITE_R | RAST_WRITE_A);
        s.depth_write_disabled = 1;
        s.stencil_front.write_mask = s.stencil_back.write_mask = RAST_MASK(0x0F);
        tu_set_state(ctx, &s);
        memset(&cd, 0, sizeof cd);
        cd.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL | RAST_CLEAR_ACCUM;
        cd.color[0] = 0.5f;
        cd.color[1] = 0.5f;
        cd.color[2] = 0.5f;
        cd.color[3] = 0.75f;
        cd.depth = 1.0f;
        cd.stencil = 0x3C;
        cd.accum[0] = -0.5f;
        cd.accum[1] = 0.5f;
        cd.accum[2] = 0.75f;
        cd.accum[3] = 1.0f;
        cr_assert_eq(rast_clear(ctx, &cd), RAST_OK);
        tu_finish(ctx);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                int in = !sc || (x >= 4 && x < 10 && y >= 3 && y < 8);
                const float *acc = tu_accum(&fb, x, y);
                uint8_t es = in ? (uint8_t)((0xA5 & 0xF0) | (0x3C & 0x0F)) : 0xA5;
                for (c = 0; c < 4; c++) {
                    int on = in && (c == 0 || c == 3);
                    if (rgba8) {
                        /* 0.5 -> 127 or 128 (a tie), 0.75 -> 191 */
                        int got = tu_px8(&fb, x, y)[c];
                        int ok = !on ? got == 64 : c == 0 ? (got == 127 || got == 128) : got == 191;
                        TU_CHECK(&chk, ok, "rgba8 scissor %d (%d,%d) colour[%d] = %d", sc, x, y,
                                 c, got);
                    } else {
                        float ec = on ? (c == 0 ? 0.5f : 0.75f) : 0.25f;
                        TU_CHECK(&chk, tu_pxf(&fb, x, y)[c] == ec,
                                 "scissor %d (%d,%d) colour[%d] = %g exp %g", sc, x, y, c,
                                 tu_pxf(&fb, x, y)[c], ec);
                    }
                    TU_CHECK(&chk, acc[c] == (in ? cd.accum[c] : 0.25f),
                             "scissor %d (%d,%d) accum[%d] = %g", sc, x, y, c, acc[c]);
                }
                TU_CHECK(&chk, *tu_depth(&fb, x, y) == 0.25f,
                         "depth written despite depth_write_disabled at (%d,%d)", x, y);
                TU_CHECK(&chk, *tu_sten(&fb, x, y) == es, "scissor %d (%d,%d) stencil 0x%02x exp "
                         "0x%02x", sc, x, y, *tu_sten(&fb, x, y), es);
            }
    }
    /* and with default masks the clears write everything, everywhere */
    memset(&s, 0, sizeof s);
    tu_set_state(ctx, &s);
    tu_clear(ctx, RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL, 0.25f, 0.5f, 0.75f,
             1.0f, 0.75f, 7);
    tu_finish(ctx);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            TU_CHECK(&chk, *tu_depth(&fb, x, y) == 0.75f && *tu_sten(&fb, x, y) == 7,
                     "default-mask clear at (%d,%d)", x, y);
            if (rgba8)
                TU_CHECK(&chk, tu_px8(&fb, x, y)[2] == 191 && tu_px8(&fb, x, y)[3] == 255,
                         "default-mask colour clear at (%d,%d)", x, y);
            else
                TU_CHECK(&chk, tu_pxf(&fb, x, y)[2] == 0.75f && tu_pxf(&fb, x, y)[3] == 1.0f,
                         "default-mask colour clear at (%d,%d)", x, y);
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

Test(fragment_ops, clears_honour_scissor_and_masks_rgba32f) { check_clears(0); }
Test(fragment_ops, clears_honour_scissor_and_masks_rgba8) { check_clears(1); }

/* RGBA8 stores round(c * 255) (GL's conversion to the nearest
   representable value), clamped: (k + 0.75)/255 gives k + 1 and
   (k + 0.25)/255 gives k, exactly; out-of-range colours clamp. */
Test(fragment_ops, rgba8_conversion_rounds_to_nearest) {
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    int k;
    tu_fb_init(&fb, 4, 4, TU_COLOR8);
    tu_fb_bind(ctx, &fb);
    for (k = 0; k < 255; k += 7) {
        float c[4] = {(k + 0.75f) / 255.0f, (k + 0.25f) / 255.0f, -0.5f, 1.5f};
        cr_assert_eq(rast_draw_fullscreen(ctx, 0.5f, c), RAST_OK);
        tu_finish(ctx);
        cr_assert_eq(tu_px8(&fb, 1, 2)[0], k + 1, "%g*255 must round up", c[0]);
        cr_assert_eq(tu_px8(&fb, 1, 2)[1], k, "%g*255 must round down", c[1]);
        cr_assert_eq(tu_px8(&fb, 1, 2)[2], 0);
        cr_assert_eq(tu_px8(&fb, 1, 2)[3], 255);
    }
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Targets with padded rows: draws, clears and accumulation write only the
   pixels of each row, never the padding (an implementation that assumes
   stride == width * bytes-per-pixel smears into it). Byte targets get an
   odd padding; float targets keep 4-byte alignment. */
Test(fragment_ops, padded_strides_untouched) {
    enum { W = 13, H = 7, PB = 11, PF = 12 };
    enum { CS = W * 4 + PB, SS = W + PB, DS = W * 4 + PF, AS = W * 16 + PF };
    rast_context *ctx = tu_ctx(2, 16);
    rast_targets t;
    rast_state s;
    uint8_t *col = malloc(CS * H), *sten = malloc(SS * H);
    float *dep = malloc(DS * H), *acc = malloc(AS * H);
    const double tri[6] = {-50, -50, 200, -50, -50, 200};
    int x, y, k;
    cr_assert(col && sten && dep && acc);
    memset(col, 0xAB, CS * H);
    memset(sten, 0xAB, SS * H);
    memset(dep, 0xAB, DS * H);
    memset(acc, 0xAB, AS * H);
    memset(&t, 0, sizeof t);
    t.color = (rast_view){col, W, H, CS};
    t.depth = (rast_view){dep, W, H, DS};
    t.stencil = (rast_view){sten, W, H, SS};
    t.accum = (rast_view){acc, W, H, AS};
    cr_assert_eq(rast_set_targets(ctx, &t), RAST_OK);
    tu_clear(ctx, RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL | RAST_CLEAR_ACCUM, 1, 0,
             1, 0, 1.0f, 3);
    tu_state_count(&s);
    s.depth_test = 1;
    tu_set_state(ctx, &s);
    tu_draw_tris_px(ctx, W, H, tri, 1, 0.0);
    cr_assert_eq(rast_accum(ctx, RAST_LOAD, 1.0f), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < H; y++) {
        const uint8_t *dr = (const uint8_t *)dep + y * DS, *ar = (const uint8_t *)acc + y * AS;
        for (k = 0; k < PB; k++) {
            cr_assert_eq(col[y * CS + W * 4 + k], 0xAB, "colour padding row %d", y);
            cr_assert_eq(sten[y * SS + W + k], 0xAB, "stencil padding row %d", y);
        }
        for (k = 0; k < PF; k++) {
            cr_assert_eq(dr[W * 4 + k], 0xAB, "depth padding row %d", y);
            cr_assert_eq(ar[W * 16 + k], 0xAB, "accum padding row %d", y);
        }
        for (x = 0; x < W; x++) {
            float d, a0;
            memcpy(&d, dr + 4 * x, 4);
            memcpy(&a0, ar + 16 * x, 4);
            cr_assert_eq(sten[y * SS + x], 4, "stencil (%d,%d)", x, y);
            cr_assert_eq(d, 0.5f, "depth (%d,%d)", x, y);
            cr_assert_eq(col[y * CS + 4 * x], 255, "colour (%d,%d)", x, y);
            cr_assert_eq(a0, 1.0f, "accum (%d,%d)", x, y);
        }
    }
    rast_context_destroy(ctx);
    free(col);
    free(sten);
    free(dep);
    free(acc);
}

/* ---- fog ---------------------------------------------------------------------- */

/* Fog blends RGB towards the fog colour by f (alpha unchanged), with
   linear f = (end - c) / (end - start), exp f = e^(-density c), exp2
   f = e^(-(density c)^2), f clamped to [0, 1]; c is clip w by default. A
   triangle drawn with the same w = 4 at every vertex has c = 4 everywhere. */
Test(fragment_ops, fog_modes_with_clip_w) {
    static const struct {
        rast_fog_mode mode;
        float start, end, density;
        double f;
    } cases[] = {
        {RAST_FOG_LINEAR, 2, 10, 0, 0.75},  {RAST_FOG_LINEAR, 6, 10, 0, 1.0},
        {RAST_FOG_LINEAR, 0, 3, 0, 0.0},    {RAST_FOG_EXP, 0, 0, 0.25f, 0.36787944117144233},
        {RAST_FOG_EXP2, 0, 0, 0.125f, 0.77880078307140488}, {RAST_FOG_NONE, 2, 10, 1, 1.0},
    };
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    size_t i;
    int k, x, y;
    tu_fb_init(&fb, 16, 16, TU_COLOR32F);
    tu_fb_bind(ctx, &fb);
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        rast_state s;
        float v[3 * 8];
        const double xy[3][2] = {{-40, -40}, {100, -40}, {-40, 100}};
        const float col[4] = {0.5f, 0.25f, 1.0f, 0.625f}, fogc[4] = {0.0f, 1.0f, 0.5f, 0.25f};
        for (k = 0; k < 3; k++) {
            tu_clip_from_window(v + 8 * k, xy[k][0], xy[k][1], 0.0, 4.0, 16, 16);
            memcpy(v + 8 * k + 4, col, sizeof col);
        }
        memset(&s, 0, sizeof s);
        s.fog = cases[i].mode;
        s.fog_start = cases[i].start;
        s.fog_end = cases[i].end;
        s.fog_density = cases[i].density;
        memcpy(s.fog_color, fogc, sizeof fogc);
        tu_set_state(ctx, &s);
        cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 3, 4), RAST_OK);
        tu_finish(ctx);
        for (y = 0; y < 16; y++)
            for (x = 0; x < 16; x++) {
                const float *c = tu_pxf(&fb, x, y);
                for (k = 0; k < 3; k++) {
                    double ex = cases[i].f * col[k] + (1 - cases[i].f) * fogc[k];
                    TU_CHECK(&chk, fabs(c[k] - ex) < 1e-5, "case %d (%d,%d) channel %d = %.7g "
                             "expected %.7g", (int)i, x, y, k, c[k], ex);
                }
                TU_CHECK(&chk, c[3] == col[3], "case %d: fog changed alpha to %g", (int)i, c[3]);
            }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* fog_varying = k takes the fog coordinate from varying k - 1: varying 4
   holds window x / 8 (w = 1, so it is affine), c = (x + 0.5) / 8 at pixel
   x, linear fog from 0 to 4. Also the clip-w coordinate on a perspective
   floor, where c = w of the hit point (analytic, per pixel). */
Test(fragment_ops, fog_varying_and_perspective_w) {
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    rast_state s;
    float v[3 * 9];
    const double xy[3][2] = {{-32, -32}, {96, -32}, {-32, 96}};
    int k, x, y;
    long n = 0;
    tu_fb_init(&fb, 32, 32, TU_COLOR32F);
    tu_fb_bind(ctx, &fb);
    for (k = 0; k < 3; k++) {
        float *o = v + 9 * k;
        tu_clip_from_window(o, xy[k][0], xy[k][1], 0.0, 1.0, 32, 32);
        o[4] = 1.0f;
        o[5] = 1.0f;
        o[6] = 1.0f;
        o[7] = 1.0f;
        o[8] = (float)(xy[k][0] / 8.0);
    }
    memset(&s, 0, sizeof s);
    s.fog = RAST_FOG_LINEAR;
    s.fog_start = 0.0f;
    s.fog_end = 4.0f;
    s.fog_varying = 5; /* varying index 4 */
    tu_set_state(ctx, &s);
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 3, 5), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < 32; y++)
        for (x = 0; x < 32; x++) {
            double c = (x + 0.5) / 8.0, f = fmin(1.0, fmax(0.0, (4.0 - c) / 4.0));
            TU_CHECK(&chk, fabs(tu_pxf(&fb, x, y)[0] - f) < 1e-5,
                     "fog_varying: (%d,%d) = %.7g expected %.7g", x, y, tu_pxf(&fb, x, y)[0], f);
        }
    /* perspective floor y_eye = -1, z_eye in [-1, -4], fog coordinate = w */
    {
        const double eye[4][3] = {{-0.75, -1, -1}, {0.75, -1, -1}, {1.5, -1, -4}, {-1.5, -1, -4}};
        const int idx[6] = {0, 1, 2, 0, 2, 3};
        float q[6 * 8];
        for (k = 0; k < 6; k++) {
            const double *e = eye[idx[k]];
            float *o = q + 8 * k;
            o[0] = (float)e[0];
            o[1] = (float)e[1];
            o[2] = (float)(-e[2] * 0.25); /* any z inside [-w, w] */
            o[3] = (float)-e[2];
            o[4] = o[5] = o[6] = o[7] = 1.0f;
        }
        fill_f(fb.rgba32f, 4 * 32 * 32, -1.0f);
        s.fog_varying = 0;
        s.fog_start = 0.0f;
        s.fog_end = 8.0f;
        tu_set_state(ctx, &s);
        cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, q, 6, 4), RAST_OK);
        tu_finish(ctx);
        for (y = 0; y < 32; y++)
            for (x = 0; x < 32; x++) {
                double u, vv, t, f;
                float got = tu_pxf(&fb, x, y)[0];
                if (got == -1.0f) continue;
                tu_ndc_of_pixel(x + 0.5, y + 0.5, 32, 32, &u, &vv);
                t = -1.0 / vv; /* = clip w of the hit point on y_eye = -1 */
                f = (8.0 - t) / 8.0;
                TU_CHECK(&chk, fabs(got - f) < 1e-4, "floor (%d,%d): %.7g expected %.7g (w %g)",
                         x, y, got, f, t);
                n++;
            }
    }
    TU_CHECK_DONE(&chk);
    cr_assert(n > 150, "floor drew %ld pixels", n);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- accumulation -------------------------------------------------------------- */

/* Each op from a fresh known state: colour and accum hold multiples of 1/16
   (exact), RGBA32F colour. ACCUM: a += v c; LOAD: a = v c; MULT: a *= v;
   ADD: a += v; RETURN: c = v a (colour mask applies). All limited to the
   scissor. */
Test(fragment_ops, accum_ops_rgba32f) {
    enum { W = 8, H = 8 };
    static const struct { rast_accum_op op; float v; } ops[] = {
        {RAST_ACCUM, 0.5f}, {RAST_ACCUM, -0.25f}, {RAST_LOAD, 0.25f}, {RAST_LOAD, 2.0f},
        {RAST_MULT, 0.5f}, {RAST_MULT, -2.0f}, {RAST_ADD, 0.25f}, {RAST_ADD, -0.5f},
        {RAST_RETURN, 0.5f}, {RAST_RETURN, 1.0f}};
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_rng rng = tu_rng_make(3);
    tu_check chk = {0, {0}};
    float col0[W * H * 4], acc0[W * H * 4];
    size_t i;
    int p, c, sc;
    tu_fb_init(&fb, W, H, TU_COLOR32F | TU_ACCUM);
    tu_fb_bind(ctx, &fb);
    for (p = 0; p < W * H * 4; p++) {
        col0[p] = (float)sixteenth(&rng);
        acc0[p] = (float)(tu_rng_int(&rng, -16, 32) / 16.0); /* includes negatives */
    }
    for (sc = 0; sc < 2; sc++)
        for (i = 0; i < sizeof ops / sizeof ops[0]; i++) {
            rast_state s;
            memset(&s, 0, sizeof s);
            s.scissor_test = sc;
            s.scissor[0] = 2;
            s.scissor[1] = 1;
            s.scissor[2] = 4;
            s.scissor[3] = 5;
            if (ops[i].op == RAST_RETURN && sc)
                s.color_write = RAST_MASK(RAST_WRITE_G | RAST_WRITE_A);
            memcpy(fb.rgba32f, col0, sizeof col0);
            memcpy(fb.accum, acc0, sizeof acc0);
            tu_set_state(ctx, &s);
            cr_assert_eq(rast_accum(ctx, ops[i].op, ops[i].v), RAST_OK);
            tu_finish(ctx);
            for (p = 0; p < W * H; p++) {
                int x = p % W, y = p / W;
                int in = !sc || (x >= 2 && x < 6 && y >= 1 && y < 6);
                for (c = 0; c < 4; c++) {
                    double a = acc0[4 * p + c], col = col0[4 * p + c], v = ops[i].v;
                    double ea = a, ec = col;
                    if (in) switch (ops[i].op) {
                        case RAST_ACCUM: ea = a + v * col; break;
                        case RAST_LOAD: ea = v * col; break;
                        case RAST_MULT: ea = a * v; break;
                        case RAST_ADD: ea = a + v; break;
                        case RAST_RETURN:
                            if (!sc || c == 1 || c == 3) ec = v * a;
                            break;
                        }
                    TU_CHECK(&chk, fb.accum[4 * p + c] == ea,
                             "op %d value %g scissor %d (%d,%d)[%d]: accum %g expected %g",
                             (int)ops[i].op, v, sc, x, y, c, fb.accum[4 * p + c], ea);
                    /* RETURN of a negative accum into a float target: clamping
                       is not specified for float targets, accept either */
                    TU_CHECK(&chk, fb.rgba32f[4 * p + c] == ec ||
                                       (ec < 0 && fb.rgba32f[4 * p + c] == 0.0f) ||
                                       (ec > 1 && fb.rgba32f[4 * p + c] == 1.0f),
                             "op %d value %g scissor %d (%d,%d)[%d]: colour %g expected %g",
                             (int)ops[i].op, v, sc, x, y, c, fb.rgba32f[4 * p + c], ec);
                }
            }
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* RGBA8 colour: ACCUM/LOAD read the colour as byte/255; RETURN clamps
   v * accum to [0, 1] and rounds (within one step). */
Test(fragment_ops, accum_ops_rgba8_clamp_and_scale) {
    enum { W = 8, H = 4 };
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_rng rng = tu_rng_make(4);
    tu_check chk = {0, {0}};
    uint8_t col0[W * H * 4];
    float acc0[W * H * 4];
    int p, op;
    tu_fb_init(&fb, W, H, TU_COLOR8 | TU_ACCUM);
    tu_fb_bind(ctx, &fb);
    for (p = 0; p < W * H * 4; p++) {
        col0[p] = (uint8_t)tu_rng_int(&rng, 0, 255);
        acc0[p] = (float)tu_rng_range(&rng, -0.5, 1.5); /* RETURN must clamp both ends */
    }
    for (op = 0; op < 3; op++) {
        memcpy(fb.rgba8, col0, sizeof col0);
        memcpy(fb.accum, acc0, sizeof acc0);
        if (op == 0) cr_assert_eq(rast_accum(ctx, RAST_ACCUM, 0.5f), RAST_OK);
        if (op == 1) cr_assert_eq(rast_accum(ctx, RAST_LOAD, 1.0f), RAST_OK);
        if (op == 2) cr_assert_eq(rast_accum(ctx, RAST_RETURN, 1.25f), RAST_OK);
        tu_finish(ctx);
        for (p = 0; p < W * H * 4; p++) {
            double cv = col0[p] / 255.0;
            if (op == 0)
                TU_CHECK(&chk, fabs(fb.accum[p] - (acc0[p] + 0.5 * cv)) < 1e-6,
                         "ACCUM [%d]: %g expected %g", p, fb.accum[p], acc0[p] + 0.5 * cv);
            if (op == 1)
                TU_CHECK(&chk, fabs(fb.accum[p] - cv) < 1e-6, "LOAD [%d]: %g expected %g", p,
                         fb.accum[p], cv);
            if (op == 2) {
                int ex = tu_unorm8(1.25 * acc0[p]);
                TU_CHECK(&chk, abs(fb.rgba8[p] - ex) <= 1, "RETURN [%d]: 1.25 * %g -> %d, "
                         "expected %d", p, acc0[p], fb.rgba8[p], ex);
                TU_CHECK(&chk, fb.accum[p] == acc0[p], "RETURN changed accum");
            }
        }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- full-screen passes ------------------------------------------------------ */

/* The papers' stencil passes: a full-screen rectangle colours exactly the
   pixels whose stencil passes EQUAL 1; a colourless pass with INVERT flips
   stencil everywhere without touching colour; with a viewport the pass
   covers only the viewport; depth at z goes through the depth test. */
Test(fragment_ops, fullscreen_stencil_passes) {
    enum { W = 24, H = 16 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    rast_state s;
    int x, y;
    tu_fb_init(&fb, W, H, TU_COLOR32F | TU_DEPTH | TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            *tu_sten(&fb, x, y) = (uint8_t)((x * 7 + y * 3) % 3); /* 0, 1, 2 pattern */
            *tu_depth(&fb, x, y) = (x & 1) ? 0.25f : 0.75f;
        }
    fill_f(fb.rgba32f, 4 * W * H, 0.0f);
    /* pass 1: colour where stencil == 1 and z 0.5 < depth */
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = s.stencil_back.func = RAST_EQUAL;
    s.stencil_front.ref = s.stencil_back.ref = 1;
    s.depth_test = 1;
    s.depth_write_disabled = 1;
    tu_set_state(ctx, &s);
    fullscreen(ctx, 0.5f, 1.0f, 0.5f, 0.25f, 1.0f);
    tu_finish(ctx);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int ex = (x * 7 + y * 3) % 3 == 1 && !(x & 1);
            const float *c = tu_pxf(&fb, x, y);
            TU_CHECK(&chk, (c[0] == 1.0f && c[1] == 0.5f && c[2] == 0.25f) == ex &&
                               (ex || c[0] == 0.0f),
                     "pass 1 (%d,%d): colour %g, expected written=%d", x, y, c[0], ex);
        }
    /* pass 2: INVERT stencil everywhere, no colour written, viewport limits */
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = s.stencil_back.func = RAST_ALWAYS;
    s.stencil_front.pass = s.stencil_back.pass = RAST_INVERT;
    s.color_write = RAST_MASK(0);
    s.viewport[0] = 4;
    s.viewport[1] = 2;
    s.viewport[2] = 10;
    s.viewport[3] = 9;
    tu_set_state(ctx, &s);
    fullscreen(ctx, 0.5f, 0.0f, 1.0f, 1.0f, 1.0f);
    tu_finish(ctx);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int in = x >= 4 && x < 14 && y >= 2 && y < 11;
            uint8_t s0 = (uint8_t)((x * 7 + y * 3) % 3);
            TU_CHECK(&chk, *tu_sten(&fb, x, y) == (in ? (uint8_t)~s0 : s0),
                     "pass 2 (%d,%d): stencil %d", x, y, *tu_sten(&fb, x, y));
            TU_CHECK(&chk, tu_pxf(&fb, x, y)[1] != 1.0f, "pass 2 wrote colour at (%d,%d)", x, y);
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Fast paths must not assume a colour target: blended rectangles and
   constant-colour triangles over depth + stencil only still run their
   stencil ops (GL: the blend state is irrelevant without colour). */
Test(fragment_ops, blending_without_colour_target) {
    rast_context *ctx = tu_ctx(2, 32);
    tu_fb fb;
    rast_state s;
    static const float rgba[4] = {0.5f, 0.25f, 1.0f, 0.5f};
    const float tri[3 * 8] = {-1, -1, 0, 1, 1, 0, 0, 1, 3, -1, 0, 1, 1, 0, 0, 1, -1, 3, 0, 1, 1, 0, 0, 1};
    int x, y;
    tu_fb_init(&fb, 48, 40, TU_DEPTH | TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    memset(&s, 0, sizeof s);
    s.blend = 1;
    s.blend_src_rgb = s.blend_src_alpha = RAST_SRC_ALPHA;
    s.blend_dst_rgb = s.blend_dst_alpha = RAST_ONE_MINUS_SRC_ALPHA;
    s.stencil_test = 1;
    s.stencil_front.pass = s.stencil_back.pass = RAST_INCR;
    s.depth_test = 1; /* with depth, not the pure-stencil rectangle loop */
    s.depth_func = RAST_ALWAYS;
    tu_set_state(ctx, &s);
    cr_assert_eq(rast_draw_fullscreen(ctx, 0.5f, rgba), RAST_OK);
    cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, tri, 3, 4), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < 40; y++)
        for (x = 0; x < 48; x++) cr_assert_eq(*tu_sten(&fb, x, y), 2, "(%d,%d)", x, y);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}
