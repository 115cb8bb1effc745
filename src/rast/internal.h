/* Private declarations shared by the implementation modules (rast__ prefix).
   The amalgamator puts this first inside the RAST_IMPLEMENTATION section. */
#include "api.h"

#include <math.h>
#include <string.h>
#include <float.h>
#include <limits.h>
#if (defined(__SSE2__) || defined(_M_X64)) && !defined(RAST_NO_SIMD)
#include <emmintrin.h>
#endif

/* For the few per-pixel helpers whose call would cost more than their body. */
#if defined(__GNUC__) || defined(__clang__)
#define RAST__FORCE_INLINE static inline __attribute__((always_inline))
#elif defined(_MSC_VER)
#define RAST__FORCE_INLINE static __forceinline
#else
#define RAST__FORCE_INLINE static
#endif

#ifndef RAST_ASSERT
#include <assert.h>
#define RAST_ASSERT(c) assert(c)
#endif

#if defined(RAST_MALLOC) != defined(RAST_FREE)
#error "define both RAST_MALLOC and RAST_FREE, or neither"
#endif
#ifndef RAST_MALLOC
#include <stdlib.h>
#define RAST_MALLOC(size, user) ((void)(user), malloc(size))
#define RAST_FREE(ptr, user) ((void)(user), free(ptr))
#endif

#define RAST__MIN(a, b) ((a) < (b) ? (a) : (b))
#define RAST__MAX(a, b) ((a) > (b) ? (a) : (b))
#define RAST__CLAMP(v, lo, hi) ((v) < (lo) ? (lo) : ((v) > (hi) ? (hi) : (v)))

/* ---- allocation: the desc's allocator when set, else RAST_MALLOC ---- */

static void *rast__alloc(const rast_allocator *a, size_t size) {
    if (size == 0) size = 1;
    if (a && a->alloc) return a->alloc(size, a->user);
    return RAST_MALLOC(size, a ? a->user : NULL);
}

static void rast__free(const rast_allocator *a, void *ptr) {
    if (!ptr) return;
    if (a && a->free) a->free(ptr, a->user);
    else RAST_FREE(ptr, a ? a->user : NULL);
}

static void *rast__calloc(const rast_allocator *a, size_t count, size_t size) {
    void *p;
    if (size && count > (size_t)-1 / size) return NULL;
    p = rast__alloc(a, count * size);
    if (p) memset(p, 0, count * size);
    return p;
}

static int rast__isfinite(float v) { return v - v == 0.0f; }

/* Round to nearest, ties to even, for |v| < 2^51: the double magic-number
   trick, exact in IEEE arithmetic and much cheaper than a libm call. */
static int64_t rast__round(float v) {
    double d = (double)v + 6755399441055744.0;
    return (int64_t)(d - 6755399441055744.0);
}

/* Clamp and round to 8 bits; written so compilers emit min/max, not
   branches. NaN fails both comparisons and lands on 0. */
static uint8_t rast__to_unorm8(float v) {
    v = v * 255.0f + 0.5f;
    v = v > 0.0f ? v : 0.0f;
    v = v < 255.5f ? v : 255.5f;
    return (uint8_t)(int)v;
}

/* Packs a colour as the 4 bytes R, G, B, A in memory order (so a memcpy of
   the result writes an RGBA8 pixel on any byte order). With SSE2 the same
   arithmetic (max, min, truncation) runs on all four channels at once;
   max(v, 0) returns 0 for NaN exactly like the scalar comparison. */
#if (defined(__SSE2__) || defined(_M_X64)) && !defined(RAST_NO_SIMD)
#define RAST__SSE2 1
static uint32_t rast__pack_rgba8_v(__m128 c) {
    __m128 v = _mm_add_ps(_mm_mul_ps(c, _mm_set1_ps(255.0f)), _mm_set1_ps(0.5f));
    __m128i i;
    uint32_t out;
    v = _mm_min_ps(_mm_max_ps(v, _mm_setzero_ps()), _mm_set1_ps(255.5f));
    i = _mm_cvttps_epi32(v);
    i = _mm_packs_epi32(i, i);
    i = _mm_packus_epi16(i, i);
    out = (uint32_t)_mm_cvtsi128_si32(i);
    {   /* memory order: on little-endian x86 the low byte is R already */
        uint8_t b[4];
        b[0] = (uint8_t)out; b[1] = (uint8_t)(out >> 8); b[2] = (uint8_t)(out >> 16); b[3] = (uint8_t)(out >> 24);
        memcpy(&out, b, 4);
    }
    return out;
}
#endif

static uint32_t rast__pack_rgba8(const float c[4]) {
#ifdef RAST__SSE2
    return rast__pack_rgba8_v(_mm_loadu_ps(c));
#else
    uint8_t b[4];
    uint32_t v;
    b[0] = rast__to_unorm8(c[0]);
    b[1] = rast__to_unorm8(c[1]);
    b[2] = rast__to_unorm8(c[2]);
    b[3] = rast__to_unorm8(c[3]);
    memcpy(&v, b, 4);
    return v;
#endif
}

/* ---- comparisons and stencil ops, GL semantics ---- */

static int rast__compare_u8(int func, unsigned a, unsigned b) {
    switch (func) {
    case RAST_NEVER: return 0;
    case RAST_LESS: return a < b;
    case RAST_EQUAL: return a == b;
    case RAST_LEQUAL: return a <= b;
    case RAST_GREATER: return a > b;
    case RAST_NOTEQUAL: return a != b;
    case RAST_GEQUAL: return a >= b;
    default: return 1; /* ALWAYS */
    }
}

static int rast__compare_f(int func, float a, float b) {
    switch (func) {
    case RAST_NEVER: return 0;
    case RAST_LESS: return a < b;
    case RAST_EQUAL: return a == b;
    case RAST_LEQUAL: return a <= b;
    case RAST_GREATER: return a > b;
    case RAST_NOTEQUAL: return a != b;
    case RAST_GEQUAL: return a >= b;
    default: return 1;
    }
}

static unsigned rast__stencil_op(int op, unsigned s, unsigned ref) {
    switch (op) {
    case RAST_ZERO: return 0;
    case RAST_REPLACE: return ref;
    case RAST_INCR: return s < 255 ? s + 1 : 255;
    case RAST_DECR: return s > 0 ? s - 1 : 0;
    case RAST_INVERT: return ~s & 0xFFu;
    case RAST_INCR_WRAP: return (s + 1) & 0xFFu;
    case RAST_DECR_WRAP: return (s - 1) & 0xFFu;
    default: return s; /* KEEP */
    }
}

/* Blending, resolved: every GL factor but SRC_ALPHA_SATURATE is linear in
   the source and destination colours, factor[c] = base[c] + sc[c] * src[c]
   + sa[c] * src[3] + dc[c] * dst[c] + da[c] * dst[3] (the constant colour
   folded into base), and the equation is term_s[c] * src * sf + term_d[c] *
   dst * df. Straight-line arithmetic over four channels, no branches. */
typedef struct rast__blend {
    float s_base[4], s_sc[4], s_sa[4], s_dc[4], s_da[4];
    float d_base[4], d_sc[4], d_sa[4], d_dc[4], d_da[4];
    float term_s[4], term_d[4];
    int minmax[4];            /* 0 equation above, 1 min, 2 max */
    int saturate_s[4], saturate_d[4];
    int general;              /* min/max or saturate somewhere */
} rast__blend;

enum { RAST__ST_FAIL = 0, RAST__ST_ZFAIL = 1, RAST__ST_PASS = 2 };

/* ---- resolved pipeline state: one per rast_set_state, shared by draws ---- */

/* What a stencil table does to every value, when it is one of the
   whole-byte operations SIMD has (else TABLE). */
enum { RAST__SOP_TABLE, RAST__SOP_KEEP, RAST__SOP_SET, RAST__SOP_ADD_SAT, RAST__SOP_SUB_SAT,
       RAST__SOP_ADD_WRAP, RAST__SOP_SUB_WRAP, RAST__SOP_INVERT };

typedef struct rast__pipe {
    rast_state s;             /* the caller's state, copied */
    struct rast__pipe *next;  /* every pipe of the frame, for freeing */
    /* viewport transform: window = ndc * scale + offset (image y is down) */
    float vp_sx, vp_tx, vp_sy, vp_ty;
    float guard_x, guard_y;   /* clip-space |x| <= guard_x * w keeps the guard band */
    int clip[4];              /* x0, y0, x1, y1: viewport & scissor & target */
    int point_size;
    int cull_front, cull_back, front_is_ccw;
    int stencil_on, depth_on, depth_write;
    int depth_func;
    uint8_t st_ref[2], st_rmask[2], st_wmask[2]; /* [0] front, [1] back */
    uint8_t st_func[2], st_fail[2], st_zfail[2], st_pass[2];
    uint8_t st_test[2][256];      /* stencil test result per stored value */
    uint8_t st_next[2][3][256];   /* value after FAIL / ZFAIL / PASS, masks applied */
    uint8_t st_pure[2][256];      /* value after a fragment with no depth test (the
                                     papers' full-screen stencil passes) */
    int st_pure_op[2];            /* what st_pure does to every value (RAST__SOP_) */
    int blend;
    rast__blend bl;
    int plain_color;          /* no blending, every channel written */
    unsigned color_write;     /* RAST_WRITE_ bits actually written */
    int fog;
    int fixed_texture;        /* no fragment callback and a texture bound */
    int simple;               /* only depth test and colour writes: fast spans */
} rast__pipe;

/* ---- records: what setup leaves for the tile workers ---- */

enum {
    RAST__REC_TRI = 1, RAST__REC_POINT, RAST__REC_LINE,
    RAST__REC_RECT, RAST__REC_CLEAR, RAST__REC_ACCUM
};

typedef struct rast__rec {
    uint8_t kind;
    uint8_t front;            /* front facing */
    uint16_t pad;
    int16_t x0, y0, x1, y1;   /* pixel bounds, x1/y1 exclusive, within clip
                                 (targets are at most 16384 pixels wide) */
} rast__rec;

/* A triangle, oriented so the edge functions are positive inside. The tile
   worker gets its barycentrics from the integer edge functions at each pixel
   centre, so a pixel gets the same values whichever tile computes it, and
   setup computes no planes at all. */
typedef struct rast__tri {
    rast__rec h;
    int32_t fx[3], fy[3];     /* window position, RAST_SUBPIXEL_BITS fraction */
    float inv_area;           /* 1 / the edge function of edge 0 at vertex 2 */
    float z[3];               /* window depth */
    float iw[3];              /* 1 / w */
    /* then num_varyings * 3 floats: v0, v1 - v0, v2 - v0 */
} rast__tri;

typedef struct rast__point {
    rast__rec h;
    float z, w;
    /* then num_varyings floats */
} rast__point;

/* A point of a simple pipe drawn into RGBA8: only where, how deep and
   what colour travel to the tile (the C3RC method splats millions). Its
   square is the pipe's point size from (x, y), clipped by the pipe's clip
   rectangle where drawn. No record header: a chunk holds splats only. */
typedef struct rast__splat {
    int16_t x, y;             /* top-left pixel of the unclipped square */
    float z;                  /* clamped window depth */
    uint32_t rgba;            /* bytes R, G, B, A in memory order */
} rast__splat;

typedef struct rast__line {
    rast__rec h;
    float x[2], y[2];         /* window position */
    float z[2], iw[2];
    /* then num_varyings * 2 floats: v0, v1 - v0 */
} rast__line;

typedef struct rast__rect {
    rast__rec h;
    float z;
    float rgba[4];
} rast__rect;

typedef struct rast__clear_rec {
    rast__rec h;
    rast_clear_desc c;
} rast__clear_rec;

typedef struct rast__accum_rec {
    rast__rec h;
    int op;
    float value;
} rast__accum_rec;

/* The bound targets, resolved. */
typedef struct rast__fb {
    int width, height;
    uint8_t *color; int color_stride; int color_f32;
    float *depth; int depth_stride;     /* strides in bytes */
    uint8_t *stencil; int stencil_stride;
    float *accum; int accum_stride;
} rast__fb;

/* Scratch of one tile worker. */
typedef struct rast__tile {
    const rast__fb *fb;
    int x0, y0, x1, y1;       /* the tile's pixels */
    float var[RAST_MAX_VARYINGS];
    float ddx[RAST_MAX_VARYINGS], ddy[RAST_MAX_VARYINGS];
    /* constant-colour blending as a table of every destination byte,
       kept while the same k1, k2 come back (see rast__const_blend) */
    float lut_key[8];
    int lut_valid;
    uint8_t lut[4][256];
} rast__tile;

/* Records are whole 4-byte words (every field is 4-byte aligned). */
static size_t rast__align(size_t n) { return (n + 3u) & ~(size_t)3u; }

/* ---- the queue: draws and whole-target commands, run at flush ---- */

enum { RAST__CMD_DRAW = 1, RAST__CMD_CLEAR, RAST__CMD_RECT, RAST__CMD_ACCUM };

/* A transformed vertex of an indexed draw, as setup needs it. */
typedef struct rast__vinfo {
    int32_t fx, fy;           /* window position, fixed point (when code is 0) */
    float z, iw;              /* window depth, 1 / w */
    unsigned code;            /* clip planes outside (bits 0-5), or: */
} rast__vinfo;
enum { RAST__VINFO_CLIP = 0x40, /* needs clipping for another reason */
       RAST__VINFO_BAD = 0x80 }; /* non-finite: drops its triangles */

typedef struct rast__cmd {
    int kind;
    rast__pipe *pipe;
    rast_draw_desc d;         /* DRAW: the caller's desc, with defaults resolved */
    int prim_count, verts_per_prim, max_out;
    float *vout;              /* indexed draws: vertex outputs, [vertex][layer] */
    rast__vinfo *vinfo;       /* and their window positions, [vertex][layer] */
    uint8_t *vout_count;      /* outputs per vertex */
    rast_clear_desc clear;
    float rect_z, rect_rgba[4];
    int accum_op;
    float accum_value;
} rast__cmd;

/* One setup job's output: records and, per tile, which of them touch it. */
typedef struct rast__chunk {
    const rast__cmd *cmd;
    const rast_allocator *alloc;
    uint8_t *recs;
    size_t used, cap;
    uint32_t nrec;
    size_t *bin_start;        /* tiles + 1 byte offsets: tile t's records
                                 are recs[bin_start[t] .. bin_start[t + 1]) */
    int bin_tiles;            /* tiles bin_start has room for */
    int splat;                /* points become rast__splat records */
    uint8_t *spare;           /* the other buffer of the tile sort */
    size_t spare_cap;
    int failed;
    /* neighbouring chunks are written by different workers record by
       record: keep their counters on different cache lines */
    char pad[64];
} rast__chunk;

static size_t rast__rec_size(int kind, int nvar) {
    switch (kind) {
    case RAST__REC_TRI: return rast__align(sizeof(rast__tri) + (size_t)nvar * 3 * sizeof(float));
    case RAST__REC_POINT: return rast__align(sizeof(rast__point) + (size_t)nvar * sizeof(float));
    case RAST__REC_LINE: return rast__align(sizeof(rast__line) + (size_t)nvar * 2 * sizeof(float));
    case RAST__REC_RECT: return rast__align(sizeof(rast__rect));
    case RAST__REC_CLEAR: return rast__align(sizeof(rast__clear_rec));
    default: return rast__align(sizeof(rast__accum_rec));
    }
}

/* Room for one record of `size` bytes at the end of the chunk, or NULL. */
static void *rast__chunk_push(rast__chunk *c, size_t size) {
    void *p;
    if (c->failed) return NULL;
    if (c->used + size > c->cap) {
        size_t cap = c->cap ? c->cap * 2 : 4096;
        uint8_t *n;
        while (cap < c->used + size) cap *= 2;
        n = (uint8_t *)rast__alloc(c->alloc, cap);
        if (!n) { c->failed = 1; return NULL; }
        if (c->used) memcpy(n, c->recs, c->used);
        rast__free(c->alloc, c->recs);
        c->recs = n;
        c->cap = cap;
    }
    p = c->recs + c->used;
    c->used += size;
    c->nrec++;
    return p;
}

/* floor(a / 2^RAST_SUBPIXEL_BITS): pixel index of a fixed-point coordinate,
   without a division or an implementation-defined shift of a negative. */
static int64_t rast__floor_px(int64_t a) {
    const int64_t mask = ((int64_t)1 << RAST_SUBPIXEL_BITS) - 1;
    return a >= 0 ? a >> RAST_SUBPIXEL_BITS : -((-a + mask) >> RAST_SUBPIXEL_BITS);
}

struct rast__pool;

struct rast_context {
    rast_allocator alloc;
    int threads, tile_size, tile_shift;
    size_t batch_bytes;
    rast_parallel_for_fn parallel_for;
    void *parallel_for_user;
    struct rast__pool *pool;

    rast_targets targets;
    rast__fb fb;
    int has_target;
    int tiles_x, tiles_y;

    rast_state state;
    rast__pipe *pipe;         /* for state, NULL when it changed since */
    rast__pipe *pipes;        /* every pipe the queue refers to */

    rast__cmd *cmds;
    int cmd_count, cmd_cap;

    /* one chunk per setup job of a pass; buffers are kept between passes
       so that steady-state frames do not allocate */
    rast__chunk *chunks;
    int chunk_cap;
};

static rast_result rast__flush(rast_context *ctx);
static void rast__free_chunks(rast_context *ctx);
