/* Running the queue: a flush cuts the queued commands into passes of
   bounded memory. Each pass runs three parallel phases:
     1. vertex jobs for indexed draws (each vertex once),
     2. setup jobs, one per fixed range of primitives, each writing its own
        chunk of records and binning them into tiles,
     3. tile jobs, each walking every chunk in submission order.
   Job boundaries depend only on the input, never on the thread count. */
#include "internal.h"

/* A setup job writes about this many bytes of records: 2048 triangles
   with a few varyings, 21845 splats. Every tile walks every chunk of a
   pass, so small records want many to a job. */
enum { RAST__JOB_BYTES = 256 * 1024, RAST__MAX_PRIMS_PER_JOB = 32768 };

typedef struct rast__job {
    rast__cmd *cmd;
    int p0, p1;
} rast__job;

typedef struct rast__pass {
    rast_context *ctx;
    rast__job *jobs;
    rast__chunk *chunks;
    int count;
    rast__cmd **vertex_cmds;  /* vertex job i: command and job index within it */
    int *vertex_jobs;
} rast__pass;

static void rast__parallel(rast_context *ctx, int count, rast_job_fn fn, void *arg) {
    int i;
    if (count <= 0) return;
    if (ctx->parallel_for) {
        ctx->parallel_for(ctx->parallel_for_user, count, fn, arg);
        return;
    }
#ifndef RAST_NO_THREADS
    if (ctx->pool && count > 1) {
        rast__pool_run(ctx->pool, count, fn, arg);
        return;
    }
#endif
    for (i = 0; i < count; ++i) fn(arg, i);
}

RAST_API void rast_run_jobs(rast_context *ctx, int count, rast_job_fn job, void *job_arg) {
    if (!ctx || !job) return;
    rast__parallel(ctx, count, job, job_arg);
}

static void rast__vertex_job_fn(void *arg, int i) {
    rast__pass *ps = (rast__pass *)arg;
    rast__vertex_job(ps->vertex_cmds[i], ps->vertex_jobs[i]);
}

/* Rectangle of a whole-target command: clears and accumulation ignore the
   viewport and honour the scissor (GL); rectangles cover the viewport. */
static void rast__command_rect(const rast_context *ctx, const rast__cmd *cmd, rast__rec *h) {
    const rast__pipe *p = cmd->pipe;
    int r[4];
    if (cmd->kind == RAST__CMD_RECT) {
        memcpy(r, p->clip, sizeof(r));
    } else {
        r[0] = 0; r[1] = 0; r[2] = ctx->fb.width; r[3] = ctx->fb.height;
        if (p->s.scissor_test) {
            r[0] = RAST__MAX(r[0], p->s.scissor[0]);
            r[1] = RAST__MAX(r[1], p->s.scissor[1]);
            r[2] = (int)RAST__MIN((int64_t)r[2], (int64_t)p->s.scissor[0] + p->s.scissor[2]);
            r[3] = (int)RAST__MIN((int64_t)r[3], (int64_t)p->s.scissor[1] + p->s.scissor[3]);
        }
    }
    if (r[0] >= r[2] || r[1] >= r[3]) r[0] = r[1] = r[2] = r[3] = 0;
    h->x0 = (int16_t)r[0]; h->y0 = (int16_t)r[1]; h->x1 = (int16_t)r[2]; h->y1 = (int16_t)r[3];
}

static void rast__setup_command(const rast_context *ctx, rast__chunk *ch) {
    const rast__cmd *cmd = ch->cmd;
    rast__rec *h;
    if (cmd->kind == RAST__CMD_CLEAR) {
        rast__clear_rec *r = (rast__clear_rec *)rast__chunk_push(ch, rast__rec_size(RAST__REC_CLEAR, 0));
        if (!r) return;
        r->h.kind = RAST__REC_CLEAR;
        r->c = cmd->clear;
        h = &r->h;
    } else if (cmd->kind == RAST__CMD_RECT) {
        rast__rect *r = (rast__rect *)rast__chunk_push(ch, rast__rec_size(RAST__REC_RECT, 0));
        if (!r) return;
        r->h.kind = RAST__REC_RECT;
        r->z = cmd->rect_z;
        memcpy(r->rgba, cmd->rect_rgba, sizeof(r->rgba));
        h = &r->h;
    } else {
        rast__accum_rec *r = (rast__accum_rec *)rast__chunk_push(ch, rast__rec_size(RAST__REC_ACCUM, 0));
        if (!r) return;
        r->h.kind = RAST__REC_ACCUM;
        r->op = cmd->accum_op;
        r->value = cmd->accum_value;
        h = &r->h;
    }
    h->front = 1;
    h->pad = 0;
    rast__command_rect(ctx, cmd, h);
    if (h->x0 >= h->x1 || h->y0 >= h->y1) { /* empty scissor: nothing to do */
        ch->used = 0;
        ch->nrec = 0;
    }
}

/* The sorted spare buffer (total bytes) becomes the records; the old
   records buffer becomes the spare for the next pass. */
static void rast__chunk_take_sorted(rast__chunk *ch, size_t total) {
    uint8_t *r = ch->recs;
    size_t cap = ch->cap;
    ch->recs = ch->spare;
    ch->cap = ch->spare_cap;
    ch->spare = r;
    ch->spare_cap = cap;
    ch->used = total;
}

/* The tile a splat's square lies in, or -1 when it touches several: then
   [*tx0, *tx1] x [*ty0, *ty1] are they (its square clipped by the pipe). */
RAST__FORCE_INLINE int rast__splat_tiles(const rast_context *ctx, const rast__pipe *p, const rast__splat *sp,
                                         int *tx0, int *ty0, int *tx1, int *ty1) {
    const int S = ctx->tile_shift;
    if (p->point_size == 1) return (sp->y >> S) * ctx->tiles_x + (sp->x >> S); /* within the clip */
    *tx0 = RAST__MAX(sp->x, p->clip[0]) >> S;
    *ty0 = RAST__MAX(sp->y, p->clip[1]) >> S;
    *tx1 = (RAST__MIN(sp->x + p->point_size, p->clip[2]) - 1) >> S;
    *ty1 = (RAST__MIN(sp->y + p->point_size, p->clip[3]) - 1) >> S;
    return *tx0 == *tx1 && *ty0 == *ty1 ? *ty0 * ctx->tiles_x + *tx0 : -1;
}

/* rast__bin_chunk for splats: records without headers, each copied into
   every tile its square touches. */
static void rast__bin_splats(const rast_context *ctx, rast__chunk *ch) {
    int ntiles = ctx->tiles_x * ctx->tiles_y, t, tx, ty, tx0 = 0, ty0 = 0, tx1 = -1, ty1 = -1;
    const rast__pipe *p = ch->cmd->pipe;
    const rast__splat *in = (const rast__splat *)ch->recs;
    size_t n = ch->used / sizeof(rast__splat), i, total = 0, *count = ch->bin_start + 1;
    rast__splat *out;
    for (i = 0; i < n; ++i) {
        if ((t = rast__splat_tiles(ctx, p, &in[i], &tx0, &ty0, &tx1, &ty1)) >= 0) {
            count[t] += sizeof(rast__splat);
            continue;
        }
        for (ty = ty0; ty <= ty1; ++ty)
            for (tx = tx0; tx <= tx1; ++tx) count[ty * ctx->tiles_x + tx] += sizeof(rast__splat);
    }
    for (t = 0; t < ntiles; ++t) {
        size_t c = count[t];
        count[t] = total;
        total += c;
    }
    /* count[t] is now the start of tile t; filling advances it to its end */
    if (ch->spare_cap < total) {
        rast__free(ch->alloc, ch->spare);
        ch->spare = (uint8_t *)rast__alloc(ch->alloc, total);
        ch->spare_cap = ch->spare ? total : 0;
        if (!ch->spare) { ch->failed = 1; return; }
    }
    out = (rast__splat *)ch->spare;
    for (i = 0; i < n; ++i) {
        if ((t = rast__splat_tiles(ctx, p, &in[i], &tx0, &ty0, &tx1, &ty1)) >= 0) {
            out[count[t] / sizeof(rast__splat)] = in[i];
            count[t] += sizeof(rast__splat);
            continue;
        }
        for (ty = ty0; ty <= ty1; ++ty)
            for (tx = tx0; tx <= tx1; ++tx) {
                size_t *at = &count[ty * ctx->tiles_x + tx];
                out[*at / sizeof(rast__splat)] = in[i];
                *at += sizeof(rast__splat);
            }
    }
    rast__chunk_take_sorted(ch, total);
}

/* Sorts the chunk's records by tile: a counting sort by bytes that copies
   each record into every tile it touches, keeping submission order within
   a tile. Tile workers then read their records contiguously instead of
   chasing them across the chunk (a cache miss per record). */
static void rast__bin_chunk(const rast_context *ctx, rast__chunk *ch) {
    int ntiles = ctx->tiles_x * ctx->tiles_y, S = ctx->tile_shift, nvar;
    size_t off, total = 0, size;
    uint8_t *sorted;
    int t;
    if (ch->bin_tiles < ntiles) {
        rast__free(ch->alloc, ch->bin_start);
        ch->bin_start = (size_t *)rast__alloc(ch->alloc, ((size_t)ntiles + 1) * sizeof(size_t));
        ch->bin_tiles = ch->bin_start ? ntiles : 0;
        if (!ch->bin_start) { ch->failed = 1; return; }
    }
    memset(ch->bin_start, 0, ((size_t)ntiles + 1) * sizeof(size_t));
    if (!ch->nrec) return;
    if (ch->splat) {
        rast__bin_splats(ctx, ch);
        return;
    }
    /* a chunk holds one kind of record (one draw or one command) */
    nvar = ch->cmd->kind == RAST__CMD_DRAW ? ch->cmd->d.num_varyings : 0;
    size = rast__rec_size(((const rast__rec *)ch->recs)->kind, nvar);
    for (off = 0; off < ch->used; off += size) {
        const rast__rec *h = (const rast__rec *)(ch->recs + off);
        int tx, ty;
        for (ty = h->y0 >> S; ty <= (h->y1 - 1) >> S; ++ty)
            for (tx = h->x0 >> S; tx <= (h->x1 - 1) >> S; ++tx) ch->bin_start[ty * ctx->tiles_x + tx + 1] += size;
    }
    for (t = 0; t < ntiles; ++t) {
        size_t n = ch->bin_start[t + 1];
        ch->bin_start[t + 1] = total;
        total += n;
    }
    /* bin_start[t + 1] is now the start of tile t; filling advances it to
       the end of tile t, which is the start of tile t + 1 */
    if (ch->spare_cap < total) {
        rast__free(ch->alloc, ch->spare);
        ch->spare = (uint8_t *)rast__alloc(ch->alloc, total);
        ch->spare_cap = ch->spare ? total : 0;
        if (!ch->spare) { ch->failed = 1; return; }
    }
    sorted = ch->spare;
    for (off = 0; off < ch->used; off += size) {
        const rast__rec *h = (const rast__rec *)(ch->recs + off);
        int tx, ty;
        for (ty = h->y0 >> S; ty <= (h->y1 - 1) >> S; ++ty)
            for (tx = h->x0 >> S; tx <= (h->x1 - 1) >> S; ++tx) {
                size_t *at = &ch->bin_start[ty * ctx->tiles_x + tx + 1], k;
                uint8_t *dst = sorted + *at;
                /* records are whole 4-byte words: copy by 8 and a tail, fixed
                   sizes the compiler turns into plain moves (not a memcpy call) */
                for (k = 0; k + 8 <= size; k += 8) memcpy(dst + k, (const uint8_t *)h + k, 8);
                if (k < size) memcpy(dst + k, (const uint8_t *)h + k, 4);
                *at += size;
            }
    }
    rast__chunk_take_sorted(ch, total);
}

static void rast__setup_job_fn(void *arg, int i) {
    rast__pass *ps = (rast__pass *)arg;
    rast__chunk *ch = &ps->chunks[i];
    const rast__job *job = &ps->jobs[i];
    if (job->cmd->kind == RAST__CMD_DRAW) rast__setup_range(ch, job->p0, job->p1);
    else rast__setup_command(ps->ctx, ch);
    if (!ch->failed) rast__bin_chunk(ps->ctx, ch);
}

/* Records land on random pixels of a tile; asking for the tile's depth and
   colour lines up front turns a cache miss per fragment into a stream. */
static void rast__prefetch_tile(const rast_context *ctx, const rast__pass *ps, int t,
                                const rast__tile *tl) {
#if defined(__GNUC__) || defined(__clang__)
    size_t bytes = 0;
    int i, y, x;
    for (i = 0; i < ps->count; ++i)
        if (ps->chunks[i].nrec) bytes += ps->chunks[i].bin_start[t + 1] - ps->chunks[i].bin_start[t];
    if (bytes < 4096) return; /* a few records: not worth it */
    for (y = tl->y0; y < tl->y1; ++y) {
        const rast__fb *fb = &ctx->fb;
        if (fb->depth)
            for (x = tl->x0; x < tl->x1; x += 16)
                __builtin_prefetch((const uint8_t *)fb->depth + (size_t)y * (size_t)fb->depth_stride + 4 * (size_t)x, 1);
        if (fb->color)
            for (x = tl->x0; x < tl->x1; x += fb->color_f32 ? 4 : 16)
                __builtin_prefetch(fb->color + (size_t)y * (size_t)fb->color_stride +
                                   (size_t)x * (fb->color_f32 ? 16u : 4u), 1);
    }
#else
    (void)ctx; (void)ps; (void)t; (void)tl;
#endif
}

static void rast__tile_job_fn(void *arg, int t) {
    rast__pass *ps = (rast__pass *)arg;
    const rast_context *ctx = ps->ctx;
    int T = ctx->tile_size, i;
    rast__tile tl;
    tl.lut_valid = 0;
    tl.fb = &ctx->fb;
    tl.x0 = (t % ctx->tiles_x) * T;
    tl.y0 = (t / ctx->tiles_x) * T;
    tl.x1 = RAST__MIN(tl.x0 + T, ctx->fb.width);
    tl.y1 = RAST__MIN(tl.y0 + T, ctx->fb.height);
    rast__prefetch_tile(ctx, ps, t, &tl);
    for (i = 0; i < ps->count; ++i) {
        const rast__chunk *ch = &ps->chunks[i];
        size_t b, e, size;
        rast__draw_info di;
        if (!ch->nrec) continue;
        b = ch->bin_start[t];
        e = ch->bin_start[t + 1];
        if (b == e) continue;
        di.pipe = ch->cmd->pipe;
        di.nvar = ch->cmd->kind == RAST__CMD_DRAW ? ch->cmd->d.num_varyings : 0;
        di.color = ch->cmd->d.color;
        if (ch->splat) {
            rast__raster_splats(&di, &tl, (const rast__splat *)(ch->recs + b), (const rast__splat *)(ch->recs + e));
            continue;
        }
        size = rast__rec_size(((const rast__rec *)(ch->recs + b))->kind, di.nvar);
        for (; b < e; b += size) rast__raster_record(&di, &tl, (const rast__rec *)(ch->recs + b));
    }
}

/* Whether a command's points become rast__splat records. */
static int rast__is_splat(const rast_context *ctx, const rast__cmd *cmd) {
    return cmd->kind == RAST__CMD_DRAW && cmd->verts_per_prim == 1 && cmd->pipe->simple &&
           cmd->pipe->plain_color && ctx->fb.color && !ctx->fb.color_f32;
}

/* Setup memory a primitive of the command may take (records, twice for
   the tile sort), for planning passes. */
static size_t rast__prim_bytes(const rast_context *ctx, const rast__cmd *cmd) {
    size_t rec = rast__is_splat(ctx, cmd) ? sizeof(rast__splat)
                 : rast__rec_size(cmd->verts_per_prim == 3 ? RAST__REC_TRI
                                  : cmd->verts_per_prim == 2 ? RAST__REC_LINE : RAST__REC_POINT,
                                  cmd->d.num_varyings);
    return 2 * rec * (size_t)cmd->max_out;
}

/* Primitives per setup job of a command (a function of the command only,
   so job boundaries never depend on the thread count). */
static int rast__prims_per_job(const rast_context *ctx, const rast__cmd *cmd) {
    size_t per_prim = rast__prim_bytes(ctx, cmd) / 2;
    return (int)RAST__CLAMP(RAST__JOB_BYTES / RAST__MAX(per_prim, (size_t)1), (size_t)1,
                            (size_t)RAST__MAX_PRIMS_PER_JOB);
}

static void rast__free_pass(rast_context *ctx, rast__pass *ps) {
    rast__free(&ctx->alloc, ps->jobs);
    rast__free(&ctx->alloc, ps->vertex_cmds);
    rast__free(&ctx->alloc, ps->vertex_jobs);
    memset(ps, 0, sizeof(*ps));
}

/* Makes room for n chunks; their buffers persist across passes. */
static int rast__reserve_chunks(rast_context *ctx, int n) {
    rast__chunk *c;
    if (n <= ctx->chunk_cap) return 1;
    c = (rast__chunk *)rast__calloc(&ctx->alloc, (size_t)n, sizeof(rast__chunk));
    if (!c) return 0;
    if (ctx->chunk_cap) memcpy(c, ctx->chunks, (size_t)ctx->chunk_cap * sizeof(rast__chunk));
    rast__free(&ctx->alloc, ctx->chunks);
    ctx->chunks = c;
    ctx->chunk_cap = n;
    return 1;
}

static void rast__free_chunks(rast_context *ctx) {
    int i;
    for (i = 0; i < ctx->chunk_cap; ++i) {
        rast__free(&ctx->alloc, ctx->chunks[i].recs);
        rast__free(&ctx->alloc, ctx->chunks[i].spare);
        rast__free(&ctx->alloc, ctx->chunks[i].bin_start);
    }
    rast__free(&ctx->alloc, ctx->chunks);
    ctx->chunks = NULL;
    ctx->chunk_cap = 0;
}

static void rast__free_vertex_outputs(rast_context *ctx, rast__cmd *cmd) {
    rast__free(&ctx->alloc, cmd->vout);
    rast__free(&ctx->alloc, cmd->vout_count);
    rast__free(&ctx->alloc, cmd->vinfo);
    cmd->vout = NULL;
    cmd->vout_count = NULL;
    cmd->vinfo = NULL;
}

/* Setup memory a pass may take: the caller's, or by default 4 MiB or 16
   bytes per queued vertex of non-indexed draws, whichever is more. Every
   pass sweeps the tiles it touches once more, so a million splats want
   one pass, not six; indexed draws already hold about 50 bytes of vertex
   outputs per vertex, so theirs do not raise it. */
static size_t rast__pass_budget(const rast_context *ctx) {
    size_t vertices = 0;
    int i;
    if (ctx->batch_bytes) return ctx->batch_bytes;
    for (i = 0; i < ctx->cmd_count; ++i)
        if (ctx->cmds[i].kind == RAST__CMD_DRAW && !ctx->cmds[i].d.indices)
            vertices += (size_t)ctx->cmds[i].d.vertex_count;
    return RAST__MAX((size_t)4 << 20, 16 * vertices);
}

/* Runs commands from (*ci, *cp) until the pass budget is used; advances them. */
static rast_result rast__run_pass(rast_context *ctx, size_t pass_budget, int *ci, int *cp) {
    rast__pass ps;
    size_t budget = 0;
    int njobs = 0, nvjobs = 0, c, p, i;
    rast_result r = RAST_OK;
    memset(&ps, 0, sizeof(ps));
    ps.ctx = ctx;
    /* plan: count jobs within the budget (always at least one) */
    for (c = *ci, p = *cp; c < ctx->cmd_count && (njobs == 0 || budget < pass_budget);) {
        rast__cmd *cmd = &ctx->cmds[c];
        int per_job;
        if (cmd->kind != RAST__CMD_DRAW) {
            ++njobs; ++c; p = 0;
            continue;
        }
        if (p == 0 && cmd->d.indices && !cmd->vout)
            nvjobs += (cmd->d.vertex_count + RAST__VERTEX_JOB - 1) / RAST__VERTEX_JOB;
        ++njobs;
        per_job = rast__prims_per_job(ctx, cmd);
        budget += rast__prim_bytes(ctx, cmd) * (size_t)RAST__MIN(per_job, cmd->prim_count - p);
        p += per_job;
        if (p >= cmd->prim_count) { ++c; p = 0; }
    }
    ps.jobs = (rast__job *)rast__calloc(&ctx->alloc, (size_t)njobs, sizeof(rast__job));
    ps.chunks = rast__reserve_chunks(ctx, njobs) ? ctx->chunks : NULL;
    ps.vertex_cmds = (rast__cmd **)rast__calloc(&ctx->alloc, (size_t)nvjobs + 1, sizeof(rast__cmd *));
    ps.vertex_jobs = (int *)rast__calloc(&ctx->alloc, (size_t)nvjobs + 1, sizeof(int));
    if (!ps.jobs || !ps.chunks || !ps.vertex_cmds || !ps.vertex_jobs) {
        rast__free_pass(ctx, &ps);
        return RAST_ERROR_OUT_OF_MEMORY;
    }
    /* fill the jobs, allocating vertex outputs of indexed draws */
    nvjobs = 0;
    for (i = 0, c = *ci, p = *cp; i < njobs; ++i) {
        rast__cmd *cmd = &ctx->cmds[c];
        ps.jobs[i].cmd = cmd;
        ps.chunks[i].cmd = cmd;
        ps.chunks[i].alloc = &ctx->alloc;
        ps.chunks[i].used = 0;
        ps.chunks[i].nrec = 0;
        ps.chunks[i].failed = 0;
        ps.chunks[i].splat = rast__is_splat(ctx, cmd);
        if (cmd->kind != RAST__CMD_DRAW) { ++c; p = 0; continue; }
        if (p == 0 && cmd->d.indices && !cmd->vout) {
            int v, nv = (cmd->d.vertex_count + RAST__VERTEX_JOB - 1) / RAST__VERTEX_JOB;
            cmd->vout = (float *)rast__alloc(&ctx->alloc, (size_t)cmd->d.vertex_count *
                                                              (size_t)cmd->max_out *
                                                              rast__vout_floats(cmd) * sizeof(float));
            cmd->vout_count = (uint8_t *)rast__alloc(&ctx->alloc, (size_t)cmd->d.vertex_count);
            cmd->vinfo = (rast__vinfo *)rast__alloc(&ctx->alloc, (size_t)cmd->d.vertex_count *
                                                                     (size_t)cmd->max_out * sizeof(rast__vinfo));
            if (!cmd->vout || !cmd->vout_count || !cmd->vinfo) r = RAST_ERROR_OUT_OF_MEMORY;
            for (v = 0; v < nv; ++v) {
                ps.vertex_cmds[nvjobs] = cmd;
                ps.vertex_jobs[nvjobs++] = v;
            }
        }
        ps.jobs[i].p0 = p;
        ps.jobs[i].p1 = RAST__MIN(p + rast__prims_per_job(ctx, cmd), cmd->prim_count);
        p = ps.jobs[i].p1;
        if (p >= cmd->prim_count) { ++c; p = 0; }
    }
    ps.count = njobs;
    if (r == RAST_OK) {
        rast__parallel(ctx, nvjobs, rast__vertex_job_fn, &ps);
        rast__parallel(ctx, njobs, rast__setup_job_fn, &ps);
        for (i = 0; i < njobs; ++i)
            if (ps.chunks[i].failed) r = RAST_ERROR_OUT_OF_MEMORY;
    }
    if (r == RAST_OK) rast__parallel(ctx, ctx->tiles_x * ctx->tiles_y, rast__tile_job_fn, &ps);
    /* vertex outputs of draws that this pass finished are no longer needed */
    for (i = *ci; i < c; ++i) rast__free_vertex_outputs(ctx, &ctx->cmds[i]);
    rast__free_pass(ctx, &ps);
    *ci = c;
    *cp = p;
    return r;
}

static rast_result rast__flush(rast_context *ctx) {
    rast_result r = RAST_OK;
    int ci = 0, cp = 0, i;
    size_t pass_budget = rast__pass_budget(ctx);
    while (r == RAST_OK && ci < ctx->cmd_count) r = rast__run_pass(ctx, pass_budget, &ci, &cp);
    for (i = 0; i < ctx->cmd_count; ++i) rast__free_vertex_outputs(ctx, &ctx->cmds[i]);
    ctx->cmd_count = 0;
    /* keep the current pipe (state is unchanged); free the others */
    {
        rast__pipe *keep = ctx->pipe, *pp = ctx->pipes;
        while (pp) {
            rast__pipe *n = pp->next;
            if (pp != keep) rast__free(&ctx->alloc, pp);
            pp = n;
        }
        ctx->pipes = keep;
        if (keep) keep->next = NULL;
    }
    return r;
}
