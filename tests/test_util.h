/* Shared helpers for the rast.h core test suite (Criterion).

   Everything here is static inline so that every test_*.c under tests/ can include
   it and all of them link into one binary.

   Conventions used throughout the tests:
   - "window" / "pixel" coordinates are image coordinates: x to the right,
     y DOWN, row 0 is the top row, pixel (x, y) has its centre at
     (x + 0.5, y + 0.5).
   - tu_clip_from_window() turns a window position into clip coordinates for
     a viewport of size vw x vh at (0, 0) with the given clip w:
         ndc_x = 2 x / vw - 1,  ndc_y = 1 - 2 y / vh   (NDC y = +1 is the top)
     For power-of-two viewports and positions on the 1/256 grid this is exact
     in float, so the rasteriser sees exactly the positions the test intends.
   - Per-pixel checks accumulate failures in a tu_check and assert once at
     the end, printing the first failing pixel, so a broken pixel pipeline
     produces one readable message instead of thousands. */
#ifndef RAST_TEST_UTIL_H
#define RAST_TEST_UTIL_H

#include <criterion/criterion.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../rast.h"

/* tu_sanitized(): whether this binary runs under AddressSanitizer, that is
   whether the sanitizer's runtime is linked (its __asan_init, a weak
   reference that stays null elsewhere). That run looks for memory errors; the plain and portable runs check the
   same bytes, so a test whose size only adds time under the sanitizers may
   do less there. */
extern void __asan_init(void) __attribute__((weak));
static inline int tu_sanitized(void) { return __asan_init != NULL; }

/* ---- failure accumulation ------------------------------------------------ */

typedef struct tu_check {
    long fails;
    char first[1024];
} tu_check;

#define TU_CHECK(chk, cond, ...)                                              \
    do {                                                                      \
        if (!(cond)) {                                                        \
            if ((chk)->fails++ == 0)                                          \
                snprintf((chk)->first, sizeof (chk)->first, __VA_ARGS__);     \
        }                                                                     \
    } while (0)

#define TU_CHECK_DONE(chk)                                                    \
    cr_assert((chk)->fails == 0, "%ld failure(s); first: %s", (chk)->fails,   \
              (chk)->first)

/* ---- deterministic RNG (xorshift64*) ------------------------------------- */

typedef struct tu_rng {
    uint64_t s;
} tu_rng;

static inline tu_rng tu_rng_make(uint64_t seed) {
    tu_rng r;
    r.s = seed * 0x9E3779B97F4A7C15ull + 0x2545F4914F6CDD1Dull;
    if (r.s == 0) r.s = 1;
    return r;
}

static inline uint32_t tu_rng_u32(tu_rng *r) {
    uint64_t x = r->s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    r->s = x;
    return (uint32_t)((x * 0x2545F4914F6CDD1Dull) >> 32);
}

/* uniform in [0, 1) with 24 random bits (exact in float) */
static inline float tu_rng_float(tu_rng *r) {
    return (float)(tu_rng_u32(r) >> 8) * (1.0f / 16777216.0f);
}

static inline double tu_rng_range(tu_rng *r, double lo, double hi) {
    return lo + (hi - lo) * (double)tu_rng_float(r);
}

/* uniform integer in [lo, hi] */
static inline int tu_rng_int(tu_rng *r, int lo, int hi) {
    return lo + (int)(tu_rng_u32(r) % (uint32_t)(hi - lo + 1));
}

/* a value on the 1/256 sub-pixel grid in [lo, hi] */
static inline double tu_rng_grid(tu_rng *r, double lo, double hi) {
    long a = (long)ceil(lo * 256.0), b = (long)floor(hi * 256.0);
    long k = a + (long)(tu_rng_u32(r) % (uint32_t)(b - a + 1));
    return (double)k / 256.0;
}

static inline double tu_snap(double v) { return floor(v * 256.0 + 0.5) / 256.0; }

/* ---- contexts -------------------------------------------------------------- */

static inline rast_context *tu_ctx(int threads, int tile) {
    rast_context_desc cd;
    rast_context *ctx = NULL;
    rast_result r;
    memset(&cd, 0, sizeof cd);
    cd.num_threads = threads;
    cd.tile_size = tile;
    r = rast_context_create(&cd, &ctx);
    cr_assert_eq(r, RAST_OK, "rast_context_create(threads=%d, tile=%d) = %d",
                 threads, tile, (int)r);
    cr_assert_not_null(ctx);
    return ctx;
}

static inline void tu_set_state(rast_context *ctx, const rast_state *s) {
    rast_result r = rast_set_state(ctx, s);
    cr_assert_eq(r, RAST_OK, "rast_set_state = %d", (int)r);
}

static inline void tu_finish(rast_context *ctx) {
    rast_result r = rast_finish(ctx);
    cr_assert_eq(r, RAST_OK, "rast_finish = %d", (int)r);
}

/* ---- framebuffers ---------------------------------------------------------- */

enum {
    TU_COLOR8 = 1,   /* RGBA8 colour */
    TU_COLOR32F = 2, /* RGBA32F colour */
    TU_DEPTH = 4,
    TU_STENCIL = 8,
    TU_ACCUM = 16
};

typedef struct tu_fb {
    int w, h;
    unsigned what;
    uint8_t *rgba8;
    float *rgba32f;
    float *depth;
    uint8_t *stencil;
    float *accum;
    rast_targets t;
} tu_fb;

/* Tightly packed targets of w x h, zero-filled (calloc). */
static inline void tu_fb_init(tu_fb *fb, int w, int h, unsigned what) {
    size_t n = (size_t)w * (size_t)h;
    memset(fb, 0, sizeof *fb);
    fb->w = w;
    fb->h = h;
    fb->what = what;
    if (what & TU_COLOR8) {
        fb->rgba8 = (uint8_t *)calloc(n, 4);
        cr_assert_not_null(fb->rgba8);
        fb->t.color.ptr = fb->rgba8;
        fb->t.color.stride = w * 4;
        fb->t.color_format = RAST_COLOR_RGBA8;
    } else if (what & TU_COLOR32F) {
        fb->rgba32f = (float *)calloc(n, 4 * sizeof(float));
        cr_assert_not_null(fb->rgba32f);
        fb->t.color.ptr = fb->rgba32f;
        fb->t.color.stride = w * 4 * (int)sizeof(float);
        fb->t.color_format = RAST_COLOR_RGBA32F;
    }
    if (fb->t.color.ptr) {
        fb->t.color.width = w;
        fb->t.color.height = h;
    }
    if (what & TU_DEPTH) {
        fb->depth = (float *)calloc(n, sizeof(float));
        cr_assert_not_null(fb->depth);
        fb->t.depth.ptr = fb->depth;
        fb->t.depth.width = w;
        fb->t.depth.height = h;
        fb->t.depth.stride = w * (int)sizeof(float);
    }
    if (what & TU_STENCIL) {
        fb->stencil = (uint8_t *)calloc(n, 1);
        cr_assert_not_null(fb->stencil);
        fb->t.stencil.ptr = fb->stencil;
        fb->t.stencil.width = w;
        fb->t.stencil.height = h;
        fb->t.stencil.stride = w;
    }
    if (what & TU_ACCUM) {
        fb->accum = (float *)calloc(n, 4 * sizeof(float));
        cr_assert_not_null(fb->accum);
        fb->t.accum.ptr = fb->accum;
        fb->t.accum.width = w;
        fb->t.accum.height = h;
        fb->t.accum.stride = w * 4 * (int)sizeof(float);
    }
}

static inline void tu_fb_bind(rast_context *ctx, tu_fb *fb) {
    rast_result r = rast_set_targets(ctx, &fb->t);
    cr_assert_eq(r, RAST_OK, "rast_set_targets = %d", (int)r);
}

static inline void tu_fb_free(tu_fb *fb) {
    free(fb->rgba8);
    free(fb->rgba32f);
    free(fb->depth);
    free(fb->stencil);
    free(fb->accum);
    memset(fb, 0, sizeof *fb);
}

static inline uint8_t *tu_px8(const tu_fb *fb, int x, int y) {
    return fb->rgba8 + ((size_t)y * (size_t)fb->w + (size_t)x) * 4;
}
static inline float *tu_pxf(const tu_fb *fb, int x, int y) {
    return fb->rgba32f + ((size_t)y * (size_t)fb->w + (size_t)x) * 4;
}
static inline float *tu_depth(const tu_fb *fb, int x, int y) {
    return fb->depth + (size_t)y * (size_t)fb->w + (size_t)x;
}
static inline uint8_t *tu_sten(const tu_fb *fb, int x, int y) {
    return fb->stencil + (size_t)y * (size_t)fb->w + (size_t)x;
}
static inline float *tu_accum(const tu_fb *fb, int x, int y) {
    return fb->accum + ((size_t)y * (size_t)fb->w + (size_t)x) * 4;
}

/* Clears through the API (honours the current state's scissor and masks). */
static inline void tu_clear(rast_context *ctx, unsigned flags, float r, float g, float b,
                            float a, float depth, uint8_t stencil) {
    rast_clear_desc c;
    rast_result res;
    memset(&c, 0, sizeof c);
    c.flags = flags;
    c.color[0] = r; c.color[1] = g; c.color[2] = b; c.color[3] = a;
    c.depth = depth;
    c.stencil = stencil;
    res = rast_clear(ctx, &c);
    cr_assert_eq(res, RAST_OK, "rast_clear = %d", (int)res);
}

/* ---- coordinates ------------------------------------------------------------ */

/* Window (image) position -> clip coordinates for a viewport of vw x vh at
   the origin; z_ndc is the NDC depth, w the clip w (positions are
   multiplied by w, so the perspective divide recovers them). */
static inline void tu_clip_from_window(float out[4], double x, double y, double z_ndc,
                                       double w, int vw, int vh) {
    double nx = 2.0 * x / vw - 1.0;
    double ny = 1.0 - 2.0 * y / vh;
    out[0] = (float)(nx * w);
    out[1] = (float)(ny * w);
    out[2] = (float)(z_ndc * w);
    out[3] = (float)w;
}

/* NDC of the centre of pixel (x, y) in a vw x vh viewport at the origin. */
static inline void tu_ndc_of_pixel(double px, double py, int vw, int vh, double *u, double *v) {
    *u = 2.0 * px / vw - 1.0;
    *v = 1.0 - 2.0 * py / vh;
}

/* Signed area in image coordinates (y down). A triangle is front facing
   (CCW in NDC, GL default) exactly when this is NEGATIVE, because the
   window y axis is flipped relative to NDC. */
static inline double tu_area_img(double x0, double y0, double x1, double y1, double x2,
                                 double y2) {
    return (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0);
}

/* ---- reference fill rule -------------------------------------------------- */

/* Does the triangle (image coordinates) cover the point (px, py) under the
   top-left rule in image coordinates?  A top edge is horizontal with the
   interior below it (larger y); a left edge is non-horizontal with the
   interior to its right.  Points strictly inside are covered; points exactly
   on an edge are covered only for top and left edges.  Degenerate triangles
   cover nothing.  Exact for inputs on a dyadic grid (computed in double). */
static inline int tu_ref_covers(const double v[6], double px, double py) {
    double area = tu_area_img(v[0], v[1], v[2], v[3], v[4], v[5]);
    int e;
    if (area == 0.0) return 0;
    for (e = 0; e < 3; e++) {
        double ax = v[2 * e], ay = v[2 * e + 1];
        double bx = v[2 * ((e + 1) % 3)], by = v[2 * ((e + 1) % 3) + 1];
        double cx = v[2 * ((e + 2) % 3)], cy = v[2 * ((e + 2) % 3) + 1];
        /* side of p and of the opposite vertex c relative to line ab */
        double sp = (bx - ax) * (py - ay) - (by - ay) * (px - ax);
        double sc = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
        if (sp * sc > 0.0) continue; /* strictly on the interior side */
        if (sp != 0.0) return 0;     /* strictly outside */
        /* on the edge line: top or left edge? */
        if (ay == by) {
            if (!(cy > ay)) return 0; /* horizontal: top iff interior below */
        } else {
            /* horizontal offset of c from the line, signed by (by - ay) */
            double hx = ((cx - ax) * (by - ay) - (cy - ay) * (bx - ax)) * (by - ay);
            if (!(hx > 0.0)) return 0; /* left iff interior to the right */
        }
    }
    return 1;
}

/* ---- drawing ----------------------------------------------------------------- */

static inline rast_result tu_draw(rast_context *ctx, rast_primitive prim, const float *verts,
                                  int count, int num_varyings) {
    rast_draw_desc d;
    memset(&d, 0, sizeof d);
    d.primitive = prim;
    d.vertices = verts;
    d.vertex_count = count;
    d.stride = 4 + num_varyings;
    d.num_varyings = num_varyings;
    d.color[0] = d.color[1] = d.color[2] = d.color[3] = 1.0f;
    return rast_draw(ctx, &d);
}

/* Draws triangles given as image-coordinate vertex pairs (6 doubles per
   triangle) at NDC depth z with w = 1, no varyings, constant white. The
   vertex array is allocated here and must live until rast_finish(), so this
   helper finishes before freeing it. */
static inline void tu_draw_tris_px(rast_context *ctx, int vw, int vh, const double *xy, int ntri,
                                   double z_ndc) {
    float *v = (float *)malloc(sizeof(float) * 4 * 3 * (size_t)(ntri > 0 ? ntri : 1));
    int i;
    rast_result r;
    cr_assert_not_null(v);
    for (i = 0; i < ntri * 3; i++)
        tu_clip_from_window(v + 4 * i, xy[2 * i], xy[2 * i + 1], z_ndc, 1.0, vw, vh);
    r = tu_draw(ctx, RAST_TRIANGLES, v, ntri * 3, 0);
    cr_assert_eq(r, RAST_OK, "rast_draw = %d", (int)r);
    tu_finish(ctx);
    free(v);
}

/* State with stencil test ALWAYS and pass op INCR (both faces): every
   fragment that reaches the stencil stage adds one to its pixel. This turns
   the stencil buffer into a per-pixel coverage counter. */
static inline void tu_state_count(rast_state *s) {
    memset(s, 0, sizeof *s);
    s->stencil_test = 1;
    s->stencil_front.func = RAST_ALWAYS;
    s->stencil_front.pass = RAST_INCR;
    s->stencil_back = s->stencil_front;
}

/* ---- counting allocator -------------------------------------------------- */

/* Counts allocations and frees and fails allocation number fail_at
   (1-based; 0 = never fail). Thread safe: the rasteriser may allocate on
   worker threads. Tracks the live byte total through a small header. */
typedef struct tu_alloc_counter {
    long allocs;    /* successful allocations */
    long frees;     /* frees of non-NULL pointers */
    long attempts;  /* allocation calls, including the failed one */
    long fail_at;   /* 1-based attempt number to fail; 0: never */
    long failed;    /* how many attempts were failed */
} tu_alloc_counter;

static inline void *tu_count_alloc(size_t size, void *user) {
    tu_alloc_counter *c = (tu_alloc_counter *)user;
    long n = __atomic_add_fetch(&c->attempts, 1, __ATOMIC_SEQ_CST);
    void *p;
    if (c->fail_at > 0 && n == c->fail_at) {
        __atomic_add_fetch(&c->failed, 1, __ATOMIC_SEQ_CST);
        return NULL;
    }
    p = malloc(size ? size : 1);
    if (p) __atomic_add_fetch(&c->allocs, 1, __ATOMIC_SEQ_CST);
    return p;
}

static inline void tu_count_free(void *p, void *user) {
    tu_alloc_counter *c = (tu_alloc_counter *)user;
    if (!p) return;
    __atomic_add_fetch(&c->frees, 1, __ATOMIC_SEQ_CST);
    free(p);
}

static inline rast_allocator tu_counting_allocator(tu_alloc_counter *c) {
    rast_allocator a;
    a.alloc = tu_count_alloc;
    a.free = tu_count_free;
    a.user = c;
    return a;
}

/* ---- image comparison ------------------------------------------------------ */

/* Index of the first differing byte, or -1 when equal. */
static inline long tu_first_diff(const void *a, const void *b, size_t n) {
    const unsigned char *pa = (const unsigned char *)a, *pb = (const unsigned char *)b;
    size_t i;
    for (i = 0; i < n; i++)
        if (pa[i] != pb[i]) return (long)i;
    return -1;
}

static inline long tu_count_diff_bytes(const void *a, const void *b, size_t n) {
    const unsigned char *pa = (const unsigned char *)a, *pb = (const unsigned char *)b;
    size_t i;
    long k = 0;
    for (i = 0; i < n; i++) k += pa[i] != pb[i];
    return k;
}

/* float -> unorm8 as GL specifies (clamp, round to nearest) */
static inline int tu_unorm8(double v) {
    if (!(v > 0.0)) return 0;
    if (v >= 1.0) return 255;
    return (int)floor(v * 255.0 + 0.5);
}

#endif /* RAST_TEST_UTIL_H */
