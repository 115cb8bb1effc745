/* RAYTRACE: the reference every other method is measured against. Every
   pixel is rendered by the per-pixel tracer (trace.c), in tiles of
   REFL__RT_TILE pixels square run on the thread pool, a band of tile rows
   at a time so progress is reported from the calling thread. Pixels are
   independent, so any thread count gives the same bytes. */
#include "internal.h"

enum { REFL__RT_TILE = 16 };

/* A frame's tracing: the tracer, and the rays each tile cast (summed
   after: no shared counter). */
typedef struct refl__rt_frame {
    refl__rt rt;
    int tiles_x, tiles_y, first_tile;
    long long *tile_rays;
} refl__rt_frame;

/* One tile of pixels. */
/* Whether a pixel of base-pass stencil value `stencil` shows a reflector
   this pass draws (objects past 254 share 255: any of them). */
static int refl__rt_mine(const refl__pass *p, uint8_t stencil) {
    int i;
    if (!stencil) return 0;
    if (stencil < 255) return refl__pass_draws(p, stencil - 1);
    for (i = 254; i < p->scene->object_count; ++i)
        if (refl__pass_draws(p, i)) return 1;
    return 0;
}

/* RAYTRACE's tiles: every pixel of the frame, or (p->mine, a frame of
   several methods) the pixels of its own reflectors, on the base pass. */
static void refl__rt_tile(void *arg, int job) {
    const refl__rt_frame *tf = (const refl__rt_frame *)arg;
    refl_frame *f = tf->rt.p->frame;
    int tile = tf->first_tile + job;
    int x0 = (tile % tf->tiles_x) * REFL__RT_TILE, y0 = (tile / tf->tiles_x) * REFL__RT_TILE;
    int x1 = REFL__MIN(x0 + REFL__RT_TILE, f->width), y1 = REFL__MIN(y0 + REFL__RT_TILE, f->height), x, y;
    long long rays = 0;
    for (y = y0; y < y1; ++y)
        for (x = x0; x < x1; ++x) {
            size_t i = (size_t)y * (size_t)f->width + (size_t)x;
            float rgb[3], depth;
            uint8_t stencil;
            refl_vec3 shown;
            if (tf->rt.p->mine && !refl__rt_mine(tf->rt.p, f->stencil[i])) continue;
            refl__rt_pixel(&tf->rt, x, y, &rays, rgb, &shown, &depth, &stencil);
            if (!tf->rt.p->mine) { /* the whole frame: no base pass under it */
                f->depth[i] = depth;
                f->stencil[i] = stencil;
            }
            if (f->stencil[i]) {
                f->points[3 * i] = shown.x;
                f->points[3 * i + 1] = shown.y;
                f->points[3 * i + 2] = shown.z;
            }
            f->rgba[4 * i] = rgb[0];
            f->rgba[4 * i + 1] = rgb[1];
            f->rgba[4 * i + 2] = rgb[2];
            f->rgba[4 * i + 3] = 1.0f;
        }
    tf->tile_rays[tile] = rays;
}

static const char *refl__options_raytrace(refl_render_desc *d) {
    if (d->raytrace.caster.occluded && !d->raytrace.caster.intersect)
        return "raytrace.caster: occluded without intersect";
    return NULL;
}

static refl_result refl__method_raytrace(refl__pass *p) {
    const refl_scene *scene = p->scene;
    refl_frame *f = p->frame;
    refl__rt_frame tf;
    double t0 = refl__now_ms(), t1;
    int i, tiles, rows_done;
    refl_bvh *bvh = NULL, *owned = NULL;
    refl_result r = p->desc.raytrace.caster.intersect ? REFL_OK : refl__models_bvh(p, &bvh, &owned);
    if (r != REFL_OK) return r;
    r = refl__rt_begin(&tf.rt, p, bvh);
    tf.rt.bvh = owned; /* freed with rt */
    if (r != REFL_OK) {
        refl__rt_end(&tf.rt);
        return r;
    }
    tf.tiles_x = (f->width + REFL__RT_TILE - 1) / REFL__RT_TILE;
    tf.tiles_y = (f->height + REFL__RT_TILE - 1) / REFL__RT_TILE;
    tiles = tf.tiles_x * tf.tiles_y;
    tf.tile_rays = (long long *)refl__calloc(&scene->allocator, (size_t)tiles, sizeof(long long));
    if (!tf.tile_rays) {
        refl__rt_end(&tf.rt);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < scene->object_count && !p->mine; ++i)
        f->stats.triangles += scene->meshes[scene->objects[i].mesh]->triangle_count;
    if (bvh) f->stats.model_bytes += refl__bvh_bytes(bvh);
    t1 = refl__now_ms();
    f->stats.ms_build += t1 - t0;
    /* bands of tile rows, so progress is reported from this thread */
    for (rows_done = 0; rows_done < tf.tiles_y;) {
        int band = REFL__MAX(1, tf.tiles_y / 16), rows = REFL__MIN(band, tf.tiles_y - rows_done);
        tf.first_tile = rows_done * tf.tiles_x;
        rast_run_jobs(p->rc, rows * tf.tiles_x, refl__rt_tile, &tf);
        rows_done += rows;
        if (!p->mine && rows_done < tf.tiles_y && refl__progress(p, (float)rows_done / (float)tf.tiles_y)) {
            r = REFL_ERROR_CANCELLED;
            break;
        }
    }
    for (i = 0; i < tiles; ++i) f->stats.rays += tf.tile_rays[i];
    f->stats.ms_reflect += refl__now_ms() - t1;
    refl__free(&scene->allocator, tf.tile_rays);
    refl__rt_end(&tf.rt);
    return r;
}

/* ---- pixels handed over ---------------------------------------------------------- */

/* Rows of pixels through the tracer: `marked` per pixel, `modelled` per
   object (refl__trace_beyond), and the rays each row cast, summed after. */
typedef struct refl__rt_rows {
    refl__rt rt;
    uint8_t *marked;
    const int *modelled;
    long long *row_rays;
} refl__rt_rows;

/* The tracer set up for p's frame; refl__rt_rows_end frees it, also
   after a failure. */
static refl_result refl__rt_rows_begin(refl__rt_rows *rows, refl__pass *p) {
    const refl_frame *f = p->frame;
    refl_bvh *bvh = NULL, *owned = NULL;
    refl_result r = p->desc.raytrace.caster.intersect ? REFL_OK : refl__models_bvh(p, &bvh, &owned);
    memset(rows, 0, sizeof *rows);
    if (r != REFL_OK) return r;
    r = refl__rt_begin(&rows->rt, p, bvh);
    rows->rt.bvh = owned; /* freed with rt */
    if (r == REFL_OK) rows->row_rays = (long long *)refl__calloc(&p->scene->allocator, (size_t)f->height, sizeof(long long));
    return r == REFL_OK && !rows->row_rays ? REFL_ERROR_OUT_OF_MEMORY : r;
}

/* Runs row(rows, y) for every row of the frame on the thread pool. */
static void refl__rt_rows_run(refl__rt_rows *rows, void (*row)(void *, int)) {
    const refl__pass *p = rows->rt.p;
    int y;
    rast_run_jobs(p->rc, p->frame->height, row, rows);
    for (y = 0; y < p->frame->height; ++y) {
        p->frame->stats.rays += rows->row_rays[y];
        rows->row_rays[y] = 0;
    }
}

static void refl__rt_rows_end(refl__rt_rows *rows) {
    if (rows->rt.scene) refl__free(&rows->rt.scene->allocator, rows->row_rays);
    refl__rt_end(&rows->rt);
}

static void refl__rt_marked_row(void *arg, int y) {
    const refl__rt_rows *m = (const refl__rt_rows *)arg;
    refl_frame *f = m->rt.p->frame;
    int x, c;
    for (x = 0; x < f->width; ++x) {
        size_t i = (size_t)y * (size_t)f->width + (size_t)x;
        float rgb[3], depth;
        uint8_t stencil;
        refl_vec3 shown;
        if (!m->marked[i]) continue;
        refl__rt_pixel(&m->rt, x, y, &m->row_rays[y], rgb, &shown, &depth, &stencil);
        for (c = 0; c < 3; ++c) f->rgba[4 * i + (size_t)c] = rgb[c];
        f->rgba[4 * i + 3] = 1.0f;
        if (m->marked[i] == REFL__TRACE_COLOUR) continue;
        f->points[3 * i] = shown.x;
        f->points[3 * i + 1] = shown.y;
        f->points[3 * i + 2] = shown.z;
    }
}

static refl_result refl__trace_marked(refl__pass *p, const uint8_t *marked) {
    refl__rt_rows rows;
    refl_result r = refl__rt_rows_begin(&rows, p);
    rows.marked = (uint8_t *)marked;
    if (r == REFL_OK) refl__rt_rows_run(&rows, refl__rt_marked_row);
    refl__rt_rows_end(&rows);
    return r;
}

/* ---- bounces past a method's own -------------------------------------------------- */

static void refl__rt_beyond_row(void *arg, int y) {
    const refl__rt_rows *b = (const refl__rt_rows *)arg;
    const refl_frame *f = b->rt.p->frame;
    int x;
    for (x = 0; x < f->width; ++x) {
        size_t i = (size_t)y * (size_t)f->width + (size_t)x;
        if (f->stencil[i] && !b->marked[i] && refl__rt_goes_beyond(&b->rt, x, y, b->modelled, &b->row_rays[y]))
            b->marked[i] = REFL__TRACE_COLOUR;
    }
}

/* One tracer for both passes: which reflector pixels go beyond, then
   their colour (with the pixels the methods marked). */
static refl_result refl__trace_beyond(refl__pass *p, const int *modelled) {
    refl_frame *f = p->frame;
    size_t i, n = (size_t)f->width * (size_t)f->height;
    refl__rt_rows rows;
    int any = 0;
    refl_result r = refl__rt_rows_begin(&rows, p);
    rows.marked = p->trace;
    rows.modelled = modelled;
    if (r == REFL_OK) refl__rt_rows_run(&rows, refl__rt_beyond_row);
    /* (REFL__TRACE_ALL: a method's own pixels for the tracer, counted by it) */
    for (i = 0; r == REFL_OK && i < n; ++i) {
        f->stats.traced_beyond += p->trace[i] == REFL__TRACE_COLOUR;
        any |= p->trace[i] != 0;
    }
    if (r == REFL_OK && any) refl__rt_rows_run(&rows, refl__rt_marked_row);
    refl__rt_rows_end(&rows);
    return r;
}
