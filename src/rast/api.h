/* rast.h - a small deterministic multithreaded software rasteriser, GL semantics.
   Part of reflect.h + rast.h. Licence: MIT No Attribution (MIT-0):

   Permission is hereby granted, free of charge, to any person obtaining a copy
   of this software and associated documentation files (the "Software"), to
   deal in the Software without restriction, including without limitation the
   rights to use, copy, modify, merge, publish, distribute, sublicense, and/or
   sell copies of the Software, and to permit persons to whom the Software is
   furnished to do so. THE SOFTWARE IS PROVIDED "AS IS", WITHOUT WARRANTY OF
   ANY KIND, EXPRESS OR IMPLIED, INCLUDING BUT NOT LIMITED TO THE WARRANTIES OF
   MERCHANTABILITY, FITNESS FOR A PARTICULAR PURPOSE AND NONINFRINGEMENT. IN NO
   EVENT SHALL THE AUTHORS OR COPYRIGHT HOLDERS BE LIABLE FOR ANY CLAIM, DAMAGES
   OR OTHER LIABILITY, WHETHER IN AN ACTION OF CONTRACT, TORT OR OTHERWISE,
   ARISING FROM, OUT OF OR IN CONNECTION WITH THE SOFTWARE OR THE USE OR OTHER
   DEALINGS IN THE SOFTWARE.

   DO THIS in *one* C or C++ file, before including this file:

       #define RAST_IMPLEMENTATION
       #include "rast.h"

   Other files include "rast.h" without the define.

   OPTIONS (define before the implementation include)
       RAST_STATIC          all functions static to the including file
       RAST_API             decoration of every public function (default extern)
       RAST_NO_THREADS      no worker pool and no pthreads; work still runs in
                            tiles (and through rast_context_desc.parallel_for)
       RAST_NO_SIMD         plain C where SSE2 would be used (the same bytes:
                            `make test` runs the rasteriser's tests both ways)
       RAST_ASSERT(c)       contract checks (default assert from <assert.h>)
       RAST_MALLOC(size, user) / RAST_FREE(ptr, user)
                            compile-time allocator (define both or neither);
                            rast_context_desc.allocator overrides at run time

   WHAT IT DRAWS
       Points (integer size N: the pixels whose centres lie in the N x N square
       centred on the point, [x - N/2, x + N/2) across and (y - N/2, y + N/2]
       down, which is llvmpipe's choice where GL leaves ties open; a point
       whose centre is outside the clip volume is dropped, as in GL), lines
       (1 pixel, for debugging) and
       triangles (homogeneous near/far clipping, a +-8192 pixel guard band,
       culling, 8 sub-pixel bits, the top-left fill rule, 16 perspective-correct
       varyings, flat or smooth shading). Each fragment then goes, in GL order,
       through the fragment callback or fixed texturing, fog, scissor, stencil
       (separate front/back), depth, blending and the colour mask. Full-target
       operations: clears, stencil passes, rectangles and accumulation ops.

   COORDINATES
       Image row 0 is the TOP row, as in image files. Clip space and NDC are
       GL's: NDC y = +1 is the top of the viewport, z_ndc in [-1, 1] maps to
       depth [0, 1]. Pixel centres lie at (x + 0.5, y + 0.5). Front faces are
       counter-clockwise in NDC (GL's default). The fill rule is D3D's
       top-left in image coordinates. GL leaves the rule to the implementation
       (each shared edge drawn once); Mesa's llvmpipe, read back and flipped,
       is bottom-left, so the two differ only at pixel centres lying exactly on
       horizontal edges (tests/rast/test_gl_conformance.c measures this).

   STEP BY STEP
       uint8_t rgba[W*H*4]; float depth[W*H];
       rast_context *ctx;
       rast_context_desc cd = {0};                      // zero = defaults
       if (rast_context_create(&cd, &ctx) != RAST_OK) ...
       rast_targets t = {0};
       t.color = (rast_view){ rgba, W, H, W*4 };
       t.depth = (rast_view){ depth, W, H, W*(int)sizeof(float) };
       rast_set_targets(ctx, &t);
       rast_clear_desc c = {0};
       c.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH; c.depth = 1.0f;
       rast_clear(ctx, &c);
       rast_state s = {0};                              // GL defaults
       s.depth_test = 1;
       rast_set_state(ctx, &s);
       float tri[3*8] = { x,y,z,w, r,g,b,a,  ... };     // clip position + colour
       rast_draw_desc d = {0};
       d.primitive = RAST_TRIANGLES; d.vertices = tri; d.vertex_count = 3;
       d.stride = 8; d.num_varyings = 4;
       rast_draw(ctx, &d);
       rast_finish(ctx);                                // now rgba is final
       rast_context_destroy(ctx);

   LIFETIMES
       Draws are queued and run at rast_finish() or rast_set_targets();
       rast_context_destroy() drops what is still queued. Vertex and index
       arrays, textures and callback user data must stay valid until then.
       State is copied at each draw. Target memory holds undefined contents
       between the first draw and rast_finish(). Memory for setup stays
       bounded (rast_context_desc.batch_bytes): a long queue runs in passes.

   DETERMINISM AND THREADS
       Work is split into fixed chunks of primitives and binned into square
       tiles; a tile is owned by one worker, which runs its commands in
       submission order. Every value a pixel sees is computed from
       per-primitive plane equations at absolute pixel coordinates, so the
       same inputs give the same bytes for any thread count and tile size.
       Vertex and fragment callbacks run on worker threads, concurrently:
       they must be pure functions of their inputs (and thread-safe).
*/
#ifndef RAST_H_INCLUDED
#define RAST_H_INCLUDED

#include <stddef.h>
#include <stdint.h>

#define RAST_VERSION_MAJOR 0
#define RAST_VERSION_MINOR 1
#define RAST_VERSION_PATCH 0

#ifndef RAST_API
#ifdef RAST_STATIC
#define RAST_API static
#else
#define RAST_API extern
#endif
#endif

#ifdef __cplusplus
extern "C" {
#endif

enum {
    RAST_MAX_VARYINGS = 16,       /* floats interpolated per vertex */
    RAST_MAX_VERTEX_OUTPUTS = 4,  /* projections a vertex callback may emit */
    RAST_MAX_POINT_SIZE = 256,    /* pixels */
    RAST_MAX_TARGET_SIZE = 16384, /* pixels per side */
    RAST_GUARD_BAND = 8192,       /* pixels beyond each viewport edge */
    RAST_SUBPIXEL_BITS = 8,
    RAST_MAX_THREADS = 64,
    RAST_MAX_MIP_LEVELS = 15
};

typedef enum rast_result {
    RAST_OK = 0,
    RAST_ERROR_INVALID_ARGUMENT = -1, /* NULL pointer, bad enum, bad count */
    RAST_ERROR_INVALID_SIZE = -2,     /* zero, negative or absurd sizes */
    RAST_ERROR_OUT_OF_MEMORY = -3,
    RAST_ERROR_TARGET_MISMATCH = -4,  /* targets of different sizes */
    RAST_ERROR_NO_TARGET = -5,        /* drawing with no target bound */
    RAST_ERROR_INDEX_RANGE = -6,      /* an index >= vertex_count */
    RAST_ERROR_THREADS = -7           /* the worker pool could not start */
} rast_result;

RAST_API const char *rast_result_string(rast_result result);

/* ---- allocation ------------------------------------------------------- */

typedef struct rast_allocator {
    void *(*alloc)(size_t size, void *user); /* NULL on failure */
    void (*free)(void *ptr, void *user);
    void *user;
} rast_allocator;

/* ---- contexts and threads --------------------------------------------- */

typedef struct rast_context rast_context;

/* Runs job(job_arg, i) for every i in [0, count), in any order and on any
   threads, and returns when all have finished. */
typedef void (*rast_job_fn)(void *job_arg, int index);
typedef void (*rast_parallel_for_fn)(void *user, int count, rast_job_fn job, void *job_arg);

typedef struct rast_context_desc {
    int num_threads;     /* 0: one per online CPU; 1: no workers */
    int tile_size;       /* 0: 64; else 16, 32, 64 or 128 */
    rast_allocator allocator;            /* zero: RAST_MALLOC / malloc */
    rast_parallel_for_fn parallel_for;   /* caller-driven jobs instead of the pool */
    void *parallel_for_user;
    size_t batch_bytes;  /* setup memory per pass of a flush; 0: 4 MiB, or 16 bytes
                            per queued vertex of non-indexed draws when more */
} rast_context_desc;

/* On failure *out_ctx is NULL (as is *out_tex of rast_texture_create). */
RAST_API rast_result rast_context_create(const rast_context_desc *desc, rast_context **out_ctx);
/* Drops queued work (call rast_finish first to keep it). */
RAST_API void rast_context_destroy(rast_context *ctx);
RAST_API int rast_context_threads(const rast_context *ctx);
/* Runs job(job_arg, i) for every i in [0, count) on the context's workers
   (or its parallel_for) and returns when all have finished: the caller's
   own parallel work on the same threads, e.g. reflect.h's ray tracer. Call
   it between draws, never from inside a job or a callback. */
RAST_API void rast_run_jobs(rast_context *ctx, int count, rast_job_fn job, void *job_arg);

/* ---- targets ----------------------------------------------------------- */

typedef struct rast_view {
    void *ptr;   /* first byte of row 0 (the top row) */
    int width, height;
    int stride;  /* bytes from one row to the next */
} rast_view;

typedef enum rast_color_format {
    RAST_COLOR_DEFAULT = 0, /* RGBA8 */
    RAST_COLOR_RGBA8,       /* 4 x uint8, unorm */
    RAST_COLOR_RGBA32F      /* 4 x float */
} rast_color_format;

/* Any view with a NULL ptr is absent. Present views must share one size.
   depth: float per pixel; stencil: uint8 per pixel; accum: 4 floats.
   Strides of float views are multiples of 4 bytes (RAST_ERROR_INVALID_SIZE
   otherwise). Float targets are never clamped; RGBA8 ones clamp to [0, 1]. */
typedef struct rast_targets {
    rast_view color;
    rast_color_format color_format;
    rast_view depth;
    rast_view stencil;
    rast_view accum;
} rast_targets;

/* Finishes pending work, then binds. */
RAST_API rast_result rast_set_targets(rast_context *ctx, const rast_targets *targets);

/* ---- textures ---------------------------------------------------------- */

typedef enum rast_texture_format {
    RAST_TEXTURE_DEFAULT = 0, /* RGBA8 */
    RAST_TEXTURE_RGBA8,
    RAST_TEXTURE_RGBA32F
} rast_texture_format;

typedef enum rast_filter {
    RAST_FILTER_DEFAULT = 0, /* LINEAR_MIPMAP_LINEAR when mipmapped, else LINEAR */
    RAST_FILTER_NEAREST,
    RAST_FILTER_LINEAR,
    RAST_FILTER_NEAREST_MIPMAP_NEAREST,
    RAST_FILTER_LINEAR_MIPMAP_NEAREST,
    RAST_FILTER_NEAREST_MIPMAP_LINEAR,
    RAST_FILTER_LINEAR_MIPMAP_LINEAR
} rast_filter;

typedef enum rast_wrap {
    RAST_WRAP_DEFAULT = 0, /* REPEAT */
    RAST_WRAP_REPEAT,
    RAST_WRAP_CLAMP_TO_EDGE,
    RAST_WRAP_MIRRORED_REPEAT
} rast_wrap;

typedef enum rast_texture_type {
    RAST_TEXTURE_2D = 0,
    RAST_TEXTURE_CUBE      /* six square faces, order +X -X +Y -Y +Z -Z */
} rast_texture_type;

typedef struct rast_texture_desc {
    rast_texture_type type;
    rast_texture_format format;
    int width, height;          /* of level 0; cube faces: width == height */
    const void *pixels[6];      /* level-0 rows, top row first; [0] for 2D */
    int stride;                 /* bytes per row; 0: tightly packed */
    int mipmaps;                /* nonzero: build the full chain (2x2 box) */
    rast_filter min_filter;     /* default as above */
    rast_filter mag_filter;     /* NEAREST or LINEAR; default LINEAR */
    rast_wrap wrap_s, wrap_t;   /* ignored for cube maps (clamped) */
    rast_allocator allocator;
} rast_texture_desc;

typedef struct rast_texture rast_texture;

/* Copies the pixels; the texture is immutable afterwards. */
RAST_API rast_result rast_texture_create(const rast_texture_desc *desc, rast_texture **out_tex);
RAST_API void rast_texture_destroy(rast_texture *tex);
/* Samples at (s, t) with t = 0 at the top row, at level of detail lod
   (log2 of texels per pixel; ignored without mipmaps except to pick
   min/mag filter). */
RAST_API void rast_texture_sample_2d(const rast_texture *tex, float s, float t, float lod, float rgba[4]);
/* GL cube-map face selection on direction (x, y, z). */
RAST_API void rast_texture_sample_cube(const rast_texture *tex, const float dir[3], float lod, float rgba[4]);
/* Which face (0..5 = +X -X +Y -Y +Z -Z) and face coordinates GL picks. */
RAST_API int rast_cube_face(const float dir[3], float *s, float *t);

/* ---- state ------------------------------------------------------------- */

typedef enum rast_primitive {
    RAST_PRIMITIVE_DEFAULT = 0, /* TRIANGLES */
    RAST_TRIANGLES,
    RAST_POINTS,
    RAST_LINES
} rast_primitive;

typedef enum rast_compare {
    RAST_COMPARE_DEFAULT = 0, /* LESS for depth, ALWAYS for stencil */
    RAST_NEVER, RAST_LESS, RAST_EQUAL, RAST_LEQUAL,
    RAST_GREATER, RAST_NOTEQUAL, RAST_GEQUAL, RAST_ALWAYS
} rast_compare;

typedef enum rast_stencil_op {
    RAST_STENCIL_OP_DEFAULT = 0, /* KEEP */
    RAST_KEEP, RAST_ZERO, RAST_REPLACE, RAST_INCR, RAST_DECR,
    RAST_INVERT, RAST_INCR_WRAP, RAST_DECR_WRAP
} rast_stencil_op;

typedef enum rast_blend_factor {
    RAST_BLEND_FACTOR_DEFAULT = 0, /* ONE for src, ZERO for dst */
    RAST_ZERO_FACTOR, RAST_ONE,
    RAST_SRC_COLOR, RAST_ONE_MINUS_SRC_COLOR,
    RAST_DST_COLOR, RAST_ONE_MINUS_DST_COLOR,
    RAST_SRC_ALPHA, RAST_ONE_MINUS_SRC_ALPHA,
    RAST_DST_ALPHA, RAST_ONE_MINUS_DST_ALPHA,
    RAST_CONSTANT_COLOR, RAST_ONE_MINUS_CONSTANT_COLOR,
    RAST_CONSTANT_ALPHA, RAST_ONE_MINUS_CONSTANT_ALPHA,
    RAST_SRC_ALPHA_SATURATE
} rast_blend_factor;

typedef enum rast_blend_equation {
    RAST_BLEND_EQUATION_DEFAULT = 0, /* ADD */
    RAST_FUNC_ADD, RAST_FUNC_SUBTRACT, RAST_FUNC_REVERSE_SUBTRACT,
    RAST_FUNC_MIN, RAST_FUNC_MAX
} rast_blend_equation;

typedef enum rast_cull {
    RAST_CULL_DEFAULT = 0, /* NONE (GL's default: culling disabled) */
    RAST_CULL_NONE, RAST_CULL_BACK, RAST_CULL_FRONT, RAST_CULL_FRONT_AND_BACK
} rast_cull;

typedef enum rast_front_face {
    RAST_FRONT_FACE_DEFAULT = 0, /* CCW */
    RAST_CCW, RAST_CW
} rast_front_face;

typedef enum rast_fog_mode {
    RAST_FOG_NONE = 0, RAST_FOG_LINEAR, RAST_FOG_EXP, RAST_FOG_EXP2
} rast_fog_mode;

typedef enum rast_shading {
    RAST_SHADING_DEFAULT = 0, /* SMOOTH */
    RAST_SMOOTH,
    RAST_FLAT                 /* varyings of the last vertex (GL's provoking vertex) */
} rast_shading;

typedef enum rast_tex_env {
    RAST_TEX_ENV_DEFAULT = 0, /* MODULATE */
    RAST_MODULATE, RAST_REPLACE_COLOR
} rast_tex_env;

/* Masks: 0 means GL's default (all 8 bits). Write RAST_MASK(m) for any
   explicit mask, including RAST_MASK(0). */
#define RAST_MASK(m) (0x100u | ((unsigned)(m) & 0xFFu))

typedef struct rast_stencil_face {
    rast_compare func;          /* default ALWAYS */
    uint8_t ref;
    unsigned read_mask;         /* RAST_MASK(); 0: 0xFF */
    unsigned write_mask;        /* RAST_MASK(); 0: 0xFF */
    rast_stencil_op fail;       /* stencil test failed */
    rast_stencil_op depth_fail; /* stencil passed, depth failed */
    rast_stencil_op pass;       /* both passed (or no depth test) */
} rast_stencil_face;

enum {
    RAST_WRITE_R = 1, RAST_WRITE_G = 2, RAST_WRITE_B = 4, RAST_WRITE_A = 8,
    RAST_WRITE_RGBA = 15
};

/* What one fragment callback sees. */
typedef struct rast_fragment_in {
    int x, y;                  /* pixel */
    float z;                   /* window depth in [0, 1] */
    float w;                   /* clip w (eye depth for perspective) */
    int front_facing;
    const float *varyings;     /* num_varyings perspective-correct values */
    const float *ddx, *ddy;    /* their derivatives per pixel rightwards and per
                                  image row downwards, when the state asks
                                  (fragment_derivatives), else NULL */
} rast_fragment_in;

/* Vertex program: reads vertex `index` (its floats at `vertex`), writes up to
   max_out outputs and returns how many (0 drops every primitive that uses
   the vertex). Points: each output is a point. Lines and triangles: the
   primitive is drawn once per output layer k < the smallest count of its
   vertices, from output k of each vertex. */
typedef struct rast_vertex_out {
    float position[4];                 /* clip space */
    float varyings[RAST_MAX_VARYINGS];
} rast_vertex_out;
typedef int (*rast_vertex_fn)(void *user, const float *vertex, int index,
                              rast_vertex_out *out, int max_out);
/* Fragment program: writes rgba and returns nonzero, or returns 0 to discard. */
typedef int (*rast_fragment_fn)(void *user, const rast_fragment_in *in, float rgba[4]);

typedef struct rast_state {
    /* viewport x, y (top-left), width, height in pixels; zero: whole target */
    int viewport[4];
    int scissor_test;
    int scissor[4];            /* x, y (top-left), width, height */

    rast_cull cull;
    rast_front_face front_face;
    rast_shading shading;
    float point_size;          /* rounded, clamped to [1, 256]; 0: 1; < 0 is an error */

    int stencil_test;
    rast_stencil_face stencil_front, stencil_back;

    int depth_test;
    rast_compare depth_func;   /* default LESS */
    int depth_write_disabled;  /* GL's glDepthMask(GL_FALSE) */
    float depth_offset;        /* added to window z of every fragment */

    int blend;
    rast_blend_factor blend_src_rgb, blend_dst_rgb, blend_src_alpha, blend_dst_alpha;
    rast_blend_equation blend_eq_rgb, blend_eq_alpha;
    float blend_color[4];
    unsigned color_write;      /* RAST_WRITE_ bits; 0: RGBA. RAST_MASK(0): none */

    rast_fog_mode fog;
    float fog_color[4];
    float fog_start, fog_end, fog_density;
    int fog_varying;           /* 0: fog coordinate is clip w; k: varying k-1 */

    const rast_texture *texture; /* fixed texturing when no fragment callback */
    int texcoord_varying;        /* s, t are varyings [k], [k+1] */
    rast_tex_env tex_env;

    rast_vertex_fn vertex_fn;
    void *vertex_user;
    int max_vertex_outputs;    /* 0: 1; at most RAST_MAX_VERTEX_OUTPUTS */
    rast_fragment_fn fragment_fn;
    void *fragment_user;
    int fragment_derivatives;  /* fill rast_fragment_in.ddx/ddy */
} rast_state;

RAST_API rast_result rast_set_state(rast_context *ctx, const rast_state *state);

/* ---- drawing ----------------------------------------------------------- */

typedef struct rast_draw_desc {
    rast_primitive primitive;
    const float *vertices;     /* vertex_count vertices of `stride` floats */
    int vertex_count;
    int stride;                /* floats per vertex; 0: position_size + num_varyings */
    int position_size;         /* 0: 4 (clip x, y, z, w); 3: x, y, z with w = 1 */
    int num_varyings;          /* floats after the position (or from the
                                  vertex callback); varyings 0..3 are the
                                  colour when num_varyings >= 4 */
    const uint32_t *indices;   /* NULL: vertices in order */
    int index_count;
    const float *matrix;       /* optional 4x4 column-major, applied to positions */
    float color[4];            /* colour when num_varyings < 4 */
} rast_draw_desc;

RAST_API rast_result rast_draw(rast_context *ctx, const rast_draw_desc *desc);

enum {
    RAST_CLEAR_COLOR = 1, RAST_CLEAR_DEPTH = 2, RAST_CLEAR_STENCIL = 4,
    RAST_CLEAR_ACCUM = 8
};

/* Clears honour the current scissor and write masks, as GL's do. */
typedef struct rast_clear_desc {
    unsigned flags;
    float color[4];
    float depth;
    uint8_t stencil;
    float accum[4];
} rast_clear_desc;

RAST_API rast_result rast_clear(rast_context *ctx, const rast_clear_desc *desc);

/* A full-viewport rectangle at window depth z with a constant colour, through
   the whole fragment pipeline (stencil, depth, blend, masks) with the current
   state; the papers' "apply the stencil to every pixel". */
RAST_API rast_result rast_draw_fullscreen(rast_context *ctx, float z, const float rgba[4]);

typedef enum rast_accum_op {
    RAST_ACCUM = 1,  /* accum += value * colour */
    RAST_LOAD,       /* accum  = value * colour */
    RAST_RETURN,     /* colour = value * accum (colour mask applies) */
    RAST_MULT,       /* accum *= value */
    RAST_ADD         /* accum += value */
} rast_accum_op;

/* GL's glAccum, within the scissor. */
RAST_API rast_result rast_accum(rast_context *ctx, rast_accum_op op, float value);

/* Runs everything queued; target memory is final when it returns. */
RAST_API rast_result rast_finish(rast_context *ctx);

#ifdef __cplusplus
}
#endif
#endif /* RAST_H_INCLUDED */
