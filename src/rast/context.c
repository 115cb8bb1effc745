/* The context: creation, targets, state, and the public calls that queue
   work. Validation happens here, at the call, so the workers never see bad
   input. */
#include "internal.h"

#if !defined(RAST_NO_THREADS) && !defined(_WIN32)
#include <unistd.h>
#endif

RAST_API const char *rast_result_string(rast_result result) {
    switch (result) {
    case RAST_OK: return "ok";
    case RAST_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case RAST_ERROR_INVALID_SIZE: return "invalid size (zero, negative, or too large)";
    case RAST_ERROR_OUT_OF_MEMORY: return "out of memory";
    case RAST_ERROR_TARGET_MISMATCH: return "targets differ in size";
    case RAST_ERROR_NO_TARGET: return "no target bound";
    case RAST_ERROR_INDEX_RANGE: return "index out of range";
    case RAST_ERROR_THREADS: return "could not start worker threads";
    }
    return "unknown rast_result";
}

static int rast__default_threads(void) {
#if !defined(RAST_NO_THREADS) && !defined(_WIN32)
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : (n > RAST_MAX_THREADS ? RAST_MAX_THREADS : (int)n);
#else
    return 1;
#endif
}

RAST_API rast_result rast_context_create(const rast_context_desc *desc, rast_context **out_ctx) {
    rast_context *ctx;
    rast_allocator alloc;
    int threads, tile;
    if (!out_ctx) return RAST_ERROR_INVALID_ARGUMENT;
    *out_ctx = NULL;
    if (!desc) return RAST_ERROR_INVALID_ARGUMENT;
    if ((desc->allocator.alloc != NULL) != (desc->allocator.free != NULL))
        return RAST_ERROR_INVALID_ARGUMENT;
    if (desc->num_threads < 0 || desc->num_threads > RAST_MAX_THREADS) return RAST_ERROR_INVALID_ARGUMENT;
    tile = desc->tile_size ? desc->tile_size : 64;
    if (tile != 16 && tile != 32 && tile != 64 && tile != 128) return RAST_ERROR_INVALID_ARGUMENT;
    threads = desc->num_threads ? desc->num_threads : rast__default_threads();
    alloc = desc->allocator;
    ctx = (rast_context *)rast__calloc(&alloc, 1, sizeof(rast_context));
    if (!ctx) return RAST_ERROR_OUT_OF_MEMORY;
    ctx->alloc = alloc;
    ctx->tile_size = tile;
    while ((1 << ctx->tile_shift) < tile) ctx->tile_shift++;
    ctx->batch_bytes = desc->batch_bytes; /* 0: rast__pass_budget decides per flush */
    ctx->parallel_for = desc->parallel_for;
    ctx->parallel_for_user = desc->parallel_for_user;
    ctx->threads = threads;
#ifndef RAST_NO_THREADS
    if (threads > 1 && !ctx->parallel_for) {
        int out_of_memory = 0;
        ctx->pool = rast__pool_create(&ctx->alloc, threads - 1, &out_of_memory);
        if (!ctx->pool) {
            rast__free(&alloc, ctx);
            return out_of_memory ? RAST_ERROR_OUT_OF_MEMORY : RAST_ERROR_THREADS;
        }
    }
#else
    if (!ctx->parallel_for) ctx->threads = 1;
#endif
    *out_ctx = ctx;
    return RAST_OK;
}

static void rast__free_pipes(rast_context *ctx) {
    rast__pipe *p = ctx->pipes;
    while (p) {
        rast__pipe *n = p->next;
        rast__free(&ctx->alloc, p);
        p = n;
    }
    ctx->pipes = NULL;
    ctx->pipe = NULL;
}

RAST_API void rast_context_destroy(rast_context *ctx) {
    rast_allocator alloc;
    int i;
    if (!ctx) return;
    /* queued work is dropped, not run: its callbacks' user data may be gone */
    for (i = 0; i < ctx->cmd_count; ++i) {
        rast__free(&ctx->alloc, ctx->cmds[i].vout);
        rast__free(&ctx->alloc, ctx->cmds[i].vout_count);
        rast__free(&ctx->alloc, ctx->cmds[i].vinfo);
    }
    rast__pool_destroy(ctx->pool);
    rast__free_pipes(ctx);
    rast__free_chunks(ctx);
    alloc = ctx->alloc;
    rast__free(&alloc, ctx->cmds);
    rast__free(&alloc, ctx);
}

RAST_API int rast_context_threads(const rast_context *ctx) { return ctx ? ctx->threads : 0; }

/* Checks one view; *size takes the first present view's size. */
static rast_result rast__check_view(const rast_view *v, int bytes_per_pixel, int is_float,
                                    int size[2]) {
    if (!v->ptr) return RAST_OK;
    if (v->width <= 0 || v->height <= 0 || v->width > RAST_MAX_TARGET_SIZE ||
        v->height > RAST_MAX_TARGET_SIZE)
        return RAST_ERROR_INVALID_SIZE;
    if (v->stride < v->width * bytes_per_pixel) return RAST_ERROR_INVALID_SIZE;
    if (is_float && v->stride % 4) return RAST_ERROR_INVALID_SIZE; /* float alignment */
    if (size[0] == 0) { size[0] = v->width; size[1] = v->height; }
    else if (size[0] != v->width || size[1] != v->height) return RAST_ERROR_TARGET_MISMATCH;
    return RAST_OK;
}

RAST_API rast_result rast_set_targets(rast_context *ctx, const rast_targets *t) {
    int size[2] = {0, 0};
    rast_result r;
    rast__fb *fb;
    if (!ctx || !t) return RAST_ERROR_INVALID_ARGUMENT;
    if (t->color_format < RAST_COLOR_DEFAULT || t->color_format > RAST_COLOR_RGBA32F)
        return RAST_ERROR_INVALID_ARGUMENT;
    int f32 = t->color_format == RAST_COLOR_RGBA32F;
    if ((r = rast__check_view(&t->color, f32 ? 16 : 4, f32, size)) ||
        (r = rast__check_view(&t->depth, 4, 1, size)) || (r = rast__check_view(&t->stencil, 1, 0, size)) ||
        (r = rast__check_view(&t->accum, 16, 1, size)))
        return r;
    r = rast__flush(ctx);
    ctx->targets = *t;
    fb = &ctx->fb;
    memset(fb, 0, sizeof(*fb));
    fb->width = size[0];
    fb->height = size[1];
    fb->color = (uint8_t *)t->color.ptr;
    fb->color_stride = t->color.stride;
    fb->color_f32 = t->color_format == RAST_COLOR_RGBA32F;
    fb->depth = (float *)t->depth.ptr;
    fb->depth_stride = t->depth.stride;
    fb->stencil = (uint8_t *)t->stencil.ptr;
    fb->stencil_stride = t->stencil.stride;
    fb->accum = (float *)t->accum.ptr;
    fb->accum_stride = t->accum.stride;
    ctx->has_target = size[0] > 0;
    ctx->tiles_x = (size[0] + ctx->tile_size - 1) / ctx->tile_size;
    ctx->tiles_y = (size[1] + ctx->tile_size - 1) / ctx->tile_size;
    ctx->pipe = NULL; /* the clip rectangle depends on the target size */
    return r;
}

#define RAST__ENUM_OK(v, hi) ((int)(v) >= 0 && (int)(v) <= (int)(hi))

static int rast__stencil_face_ok(const rast_stencil_face *f) {
    return RAST__ENUM_OK(f->func, RAST_ALWAYS) && RAST__ENUM_OK(f->fail, RAST_DECR_WRAP) &&
           RAST__ENUM_OK(f->depth_fail, RAST_DECR_WRAP) && RAST__ENUM_OK(f->pass, RAST_DECR_WRAP) &&
           f->read_mask <= 0x1FFu && f->write_mask <= 0x1FFu;
}

RAST_API rast_result rast_set_state(rast_context *ctx, const rast_state *s) {
    if (!ctx || !s) return RAST_ERROR_INVALID_ARGUMENT;
    if (!RAST__ENUM_OK(s->cull, RAST_CULL_FRONT_AND_BACK) || !RAST__ENUM_OK(s->front_face, RAST_CW) ||
        !RAST__ENUM_OK(s->shading, RAST_FLAT) || !RAST__ENUM_OK(s->depth_func, RAST_ALWAYS) ||
        !RAST__ENUM_OK(s->blend_src_rgb, RAST_SRC_ALPHA_SATURATE) ||
        !RAST__ENUM_OK(s->blend_dst_rgb, RAST_SRC_ALPHA_SATURATE) ||
        !RAST__ENUM_OK(s->blend_src_alpha, RAST_SRC_ALPHA_SATURATE) ||
        !RAST__ENUM_OK(s->blend_dst_alpha, RAST_SRC_ALPHA_SATURATE) ||
        !RAST__ENUM_OK(s->blend_eq_rgb, RAST_FUNC_MAX) || !RAST__ENUM_OK(s->blend_eq_alpha, RAST_FUNC_MAX) ||
        !RAST__ENUM_OK(s->fog, RAST_FOG_EXP2) || !RAST__ENUM_OK(s->tex_env, RAST_REPLACE_COLOR) ||
        !rast__stencil_face_ok(&s->stencil_front) || !rast__stencil_face_ok(&s->stencil_back) ||
        s->color_write > 0x1FFu || s->viewport[2] < 0 || s->viewport[3] < 0 ||
        (s->scissor_test && (s->scissor[2] < 0 || s->scissor[3] < 0)) ||
        s->max_vertex_outputs < 0 || s->max_vertex_outputs > RAST_MAX_VERTEX_OUTPUTS ||
        !(s->point_size >= 0.0f) || /* NaN too; sizes above the maximum clamp */
        !rast__isfinite(s->depth_offset) || s->fog_varying < 0 || s->fog_varying > RAST_MAX_VARYINGS ||
        s->texcoord_varying < 0 || s->texcoord_varying >= RAST_MAX_VARYINGS)
        return RAST_ERROR_INVALID_ARGUMENT;
    ctx->state = *s;
    ctx->pipe = NULL;
    return RAST_OK;
}

static uint8_t rast__mask(unsigned m) { return m ? (uint8_t)(m & 0xFFu) : 0xFFu; }

/* The RAST__SOP_ a stencil table amounts to, found by comparing the whole
   table: SIMD then gives the same bytes as the lookup, 16 at a time. */
static int rast__stencil_table_op(const uint8_t next[256]) {
    int op, v;
    for (op = RAST__SOP_KEEP; op <= RAST__SOP_INVERT; ++op) {
        for (v = 0; v < 256; ++v) {
            int want = op == RAST__SOP_KEEP ? v : op == RAST__SOP_SET ? next[0]
                     : op == RAST__SOP_ADD_SAT ? RAST__MIN(v + 1, 255) : op == RAST__SOP_SUB_SAT ? RAST__MAX(v - 1, 0)
                     : op == RAST__SOP_ADD_WRAP ? (v + 1) & 255 : op == RAST__SOP_SUB_WRAP ? (v - 1) & 255 : 255 - v;
            if (next[v] != want) break;
        }
        if (v == 256) return op;
    }
    return RAST__SOP_TABLE;
}

static void rast__resolve_face(rast__pipe *p, int i, const rast_stencil_face *f) {
    unsigned v, w;
    int k;
    p->st_func[i] = (uint8_t)(f->func ? f->func : RAST_ALWAYS);
    p->st_ref[i] = f->ref;
    p->st_rmask[i] = rast__mask(f->read_mask);
    p->st_wmask[i] = rast__mask(f->write_mask);
    p->st_fail[i] = (uint8_t)f->fail;
    p->st_zfail[i] = (uint8_t)f->depth_fail;
    p->st_pass[i] = (uint8_t)f->pass;
    /* every stencil outcome depends only on the stored value: tabulate */
    w = p->st_wmask[i];
    for (v = 0; v < 256; ++v) {
        const uint8_t ops[3] = {p->st_fail[i], p->st_zfail[i], p->st_pass[i]};
        p->st_test[i][v] = (uint8_t)rast__compare_u8(p->st_func[i], p->st_ref[i] & p->st_rmask[i],
                                                     v & p->st_rmask[i]);
        for (k = 0; k < 3; ++k)
            p->st_next[i][k][v] = (uint8_t)((v & ~w) | (rast__stencil_op(ops[k], v, p->st_ref[i]) & w));
    }
    for (v = 0; v < 256; ++v)
        p->st_pure[i][v] = p->st_test[i][v] ? p->st_next[i][RAST__ST_PASS][v] : p->st_next[i][RAST__ST_FAIL][v];
    p->st_pure_op[i] = rast__stencil_table_op(p->st_pure[i]);
}

/* Adds factor f of channel c (alpha when c == 3) to the linear form. */
static void rast__resolve_factor(int f, int c, const float k[4], float *base, float *sc, float *sa,
                                 float *dc, float *da, int *saturate) {
    float one_minus = 0.0f, sign = 1.0f;
    int a = c == 3;
    *base = *sc = *sa = *dc = *da = 0.0f;
    *saturate = f == RAST_SRC_ALPHA_SATURATE;
    switch (f) {
    case RAST_ZERO_FACTOR: case RAST_SRC_ALPHA_SATURATE: return;
    case RAST_ONE: *base = 1.0f; return;
    case RAST_ONE_MINUS_SRC_COLOR: case RAST_ONE_MINUS_DST_COLOR: case RAST_ONE_MINUS_SRC_ALPHA:
    case RAST_ONE_MINUS_DST_ALPHA: case RAST_ONE_MINUS_CONSTANT_COLOR: case RAST_ONE_MINUS_CONSTANT_ALPHA:
        one_minus = 1.0f;
        sign = -1.0f;
        break;
    default: break;
    }
    *base = one_minus;
    switch (f) {
    case RAST_SRC_COLOR: case RAST_ONE_MINUS_SRC_COLOR: if (a) *sa = sign; else *sc = sign; break;
    case RAST_DST_COLOR: case RAST_ONE_MINUS_DST_COLOR: if (a) *da = sign; else *dc = sign; break;
    case RAST_SRC_ALPHA: case RAST_ONE_MINUS_SRC_ALPHA: *sa = sign; break;
    case RAST_DST_ALPHA: case RAST_ONE_MINUS_DST_ALPHA: *da = sign; break;
    case RAST_CONSTANT_COLOR: case RAST_ONE_MINUS_CONSTANT_COLOR: *base += sign * k[c]; break;
    case RAST_CONSTANT_ALPHA: case RAST_ONE_MINUS_CONSTANT_ALPHA: *base += sign * k[3]; break;
    default: break;
    }
}

static void rast__resolve_blend(rast__pipe *p, const rast_state *s) {
    rast__blend *b = &p->bl;
    int c;
    b->general = 0;
    for (c = 0; c < 4; ++c) {
        int a = c == 3;
        int sf = a ? (s->blend_src_alpha ? (int)s->blend_src_alpha : RAST_ONE)
                   : (s->blend_src_rgb ? (int)s->blend_src_rgb : RAST_ONE);
        int df = a ? (s->blend_dst_alpha ? (int)s->blend_dst_alpha : RAST_ZERO_FACTOR)
                   : (s->blend_dst_rgb ? (int)s->blend_dst_rgb : RAST_ZERO_FACTOR);
        int eq = a ? (int)s->blend_eq_alpha : (int)s->blend_eq_rgb;
        rast__resolve_factor(sf, c, s->blend_color, &b->s_base[c], &b->s_sc[c], &b->s_sa[c], &b->s_dc[c],
                             &b->s_da[c], &b->saturate_s[c]);
        rast__resolve_factor(df, c, s->blend_color, &b->d_base[c], &b->d_sc[c], &b->d_sa[c], &b->d_dc[c],
                             &b->d_da[c], &b->saturate_d[c]);
        b->term_s[c] = eq == RAST_FUNC_REVERSE_SUBTRACT ? -1.0f : 1.0f;
        b->term_d[c] = eq == RAST_FUNC_SUBTRACT ? -1.0f : 1.0f;
        b->minmax[c] = eq == RAST_FUNC_MIN ? 1 : eq == RAST_FUNC_MAX ? 2 : 0;
        b->general |= b->minmax[c] || b->saturate_s[c] || b->saturate_d[c];
    }
}

/* The pipe for the current state and targets, made on first use. */
static rast__pipe *rast__current_pipe(rast_context *ctx) {
    const rast_state *s = &ctx->state;
    const rast__fb *fb = &ctx->fb;
    rast__pipe *p;
    int vx, vy, vw, vh;
    if (ctx->pipe) return ctx->pipe;
    p = (rast__pipe *)rast__calloc(&ctx->alloc, 1, sizeof(rast__pipe));
    if (!p) return NULL;
    p->s = *s;
    vw = s->viewport[2] ? s->viewport[2] : fb->width;
    vh = s->viewport[3] ? s->viewport[3] : fb->height;
    vx = s->viewport[2] ? s->viewport[0] : 0;
    vy = s->viewport[3] ? s->viewport[1] : 0;
    p->vp_sx = 0.5f * (float)vw;
    p->vp_tx = (float)vx + 0.5f * (float)vw;
    p->vp_sy = -0.5f * (float)vh;
    p->vp_ty = (float)vy + 0.5f * (float)vh;
    p->guard_x = 1.0f + 2.0f * (float)RAST_GUARD_BAND / (float)vw;
    p->guard_y = 1.0f + 2.0f * (float)RAST_GUARD_BAND / (float)vh;
    {   /* 64-bit: viewport and scissor may be anywhere, even near INT_MAX */
        int64_t c[4];
        c[0] = RAST__MAX((int64_t)vx, 0);
        c[1] = RAST__MAX((int64_t)vy, 0);
        c[2] = RAST__MIN((int64_t)vx + vw, (int64_t)fb->width);
        c[3] = RAST__MIN((int64_t)vy + vh, (int64_t)fb->height);
        if (s->scissor_test) {
            c[0] = RAST__MAX(c[0], (int64_t)s->scissor[0]);
            c[1] = RAST__MAX(c[1], (int64_t)s->scissor[1]);
            c[2] = RAST__MIN(c[2], (int64_t)s->scissor[0] + s->scissor[2]);
            c[3] = RAST__MIN(c[3], (int64_t)s->scissor[1] + s->scissor[3]);
        }
        if (c[0] >= c[2] || c[1] >= c[3]) c[0] = c[1] = c[2] = c[3] = 0;
        p->clip[0] = (int)c[0]; p->clip[1] = (int)c[1]; p->clip[2] = (int)c[2]; p->clip[3] = (int)c[3];
    }
    p->point_size = s->point_size > 0.0f
                        ? (int)floorf(RAST__MIN(s->point_size, (float)RAST_MAX_POINT_SIZE) + 0.5f)
                        : 1;
    p->point_size = RAST__CLAMP(p->point_size, 1, (int)RAST_MAX_POINT_SIZE);
    p->cull_back = s->cull == RAST_CULL_BACK || s->cull == RAST_CULL_FRONT_AND_BACK;
    p->cull_front = s->cull == RAST_CULL_FRONT || s->cull == RAST_CULL_FRONT_AND_BACK;
    p->front_is_ccw = s->front_face != RAST_CW;
    p->stencil_on = s->stencil_test && fb->stencil;
    p->depth_on = s->depth_test && fb->depth;
    p->depth_write = p->depth_on && !s->depth_write_disabled;
    p->depth_func = s->depth_func ? (int)s->depth_func : RAST_LESS;
    rast__resolve_face(p, 0, &s->stencil_front);
    rast__resolve_face(p, 1, &s->stencil_back);
    p->blend = s->blend != 0;
    rast__resolve_blend(p, s);
    p->color_write = s->color_write ? (s->color_write & 0xFu) : (unsigned)RAST_WRITE_RGBA;
    p->plain_color = !p->blend && p->color_write == RAST_WRITE_RGBA;
    p->fog = s->fog != RAST_FOG_NONE;
    p->fixed_texture = !s->fragment_fn && s->texture;
    p->simple = !p->stencil_on && !s->fragment_fn && !p->fixed_texture && !p->fog &&
                s->depth_offset == 0.0f;
    p->next = ctx->pipes;
    ctx->pipes = p;
    ctx->pipe = p;
    return p;
}

static rast__cmd *rast__push_cmd(rast_context *ctx, int kind) {
    rast__cmd *c;
    if (!(ctx->pipe = rast__current_pipe(ctx))) return NULL;
    if (ctx->cmd_count == ctx->cmd_cap) {
        int cap = ctx->cmd_cap ? ctx->cmd_cap * 2 : 64;
        rast__cmd *n = (rast__cmd *)rast__alloc(&ctx->alloc, (size_t)cap * sizeof(rast__cmd));
        if (!n) return NULL;
        if (ctx->cmd_count) memcpy(n, ctx->cmds, (size_t)ctx->cmd_count * sizeof(rast__cmd));
        rast__free(&ctx->alloc, ctx->cmds);
        ctx->cmds = n;
        ctx->cmd_cap = cap;
    }
    c = &ctx->cmds[ctx->cmd_count++];
    memset(c, 0, sizeof(*c));
    c->kind = kind;
    c->pipe = ctx->pipe;
    return c;
}

RAST_API rast_result rast_draw(rast_context *ctx, const rast_draw_desc *desc) {
    rast_draw_desc d;
    rast__cmd *c;
    int vpp, count, i, has_fn;
    if (!ctx || !desc) return RAST_ERROR_INVALID_ARGUMENT;
    if (!ctx->has_target) return RAST_ERROR_NO_TARGET;
    d = *desc;
    has_fn = ctx->state.vertex_fn != NULL;
    if (!RAST__ENUM_OK(d.primitive, RAST_LINES) || d.vertex_count < 0 || d.index_count < 0 ||
        d.num_varyings < 0 || d.num_varyings > RAST_MAX_VARYINGS || d.stride < 0)
        return RAST_ERROR_INVALID_ARGUMENT;
    if (!d.position_size) d.position_size = 4;
    if (d.position_size != 3 && d.position_size != 4) return RAST_ERROR_INVALID_ARGUMENT;
    if (!d.stride) d.stride = d.position_size + d.num_varyings;
    if (!has_fn && (d.stride < d.position_size + d.num_varyings || (!d.vertices && d.vertex_count)))
        return RAST_ERROR_INVALID_ARGUMENT;
    if (d.indices) {
        for (i = 0; i < d.index_count; ++i)
            if (d.indices[i] >= (uint32_t)d.vertex_count) return RAST_ERROR_INDEX_RANGE;
    } else if (d.index_count) {
        return RAST_ERROR_INVALID_ARGUMENT;
    }
    vpp = d.primitive == RAST_POINTS ? 1 : d.primitive == RAST_LINES ? 2 : 3;
    count = d.indices ? d.index_count : d.vertex_count;
    if (count / vpp == 0) return RAST_OK;
    if (!(c = rast__push_cmd(ctx, RAST__CMD_DRAW))) return RAST_ERROR_OUT_OF_MEMORY;
    c->d = d;
    c->verts_per_prim = vpp;
    c->prim_count = count / vpp;
    c->max_out = ctx->state.max_vertex_outputs ? ctx->state.max_vertex_outputs : 1;
    return RAST_OK;
}

RAST_API rast_result rast_clear(rast_context *ctx, const rast_clear_desc *desc) {
    rast__cmd *c;
    if (!ctx || !desc || (desc->flags & ~15u)) return RAST_ERROR_INVALID_ARGUMENT;
    if (!ctx->has_target) return RAST_ERROR_NO_TARGET;
    if (!(c = rast__push_cmd(ctx, RAST__CMD_CLEAR))) return RAST_ERROR_OUT_OF_MEMORY;
    c->clear = *desc;
    return RAST_OK;
}

RAST_API rast_result rast_draw_fullscreen(rast_context *ctx, float z, const float rgba[4]) {
    rast__cmd *c;
    if (!ctx || !rgba || !rast__isfinite(z)) return RAST_ERROR_INVALID_ARGUMENT;
    if (!ctx->has_target) return RAST_ERROR_NO_TARGET;
    if (!(c = rast__push_cmd(ctx, RAST__CMD_RECT))) return RAST_ERROR_OUT_OF_MEMORY;
    c->rect_z = z;
    memcpy(c->rect_rgba, rgba, sizeof(c->rect_rgba));
    return RAST_OK;
}

RAST_API rast_result rast_accum(rast_context *ctx, rast_accum_op op, float value) {
    rast__cmd *c;
    if (!ctx || op < RAST_ACCUM || op > RAST_ADD || !rast__isfinite(value))
        return RAST_ERROR_INVALID_ARGUMENT;
    if (!ctx->has_target) return RAST_ERROR_NO_TARGET;
    if (!(c = rast__push_cmd(ctx, RAST__CMD_ACCUM))) return RAST_ERROR_OUT_OF_MEMORY;
    c->accum_op = op;
    c->accum_value = value;
    return RAST_OK;
}

RAST_API rast_result rast_finish(rast_context *ctx) {
    if (!ctx) return RAST_ERROR_INVALID_ARGUMENT;
    return rast__flush(ctx);
}
