/* sbc_measure: refl_sbc_measure_camera_error, SBC's cameras alone
   (docs/metrics.md, "The cameras alone"): every point a truth frame shows
   on a reflector, projected into the groups a frame's setup builds, lands
   some distance from the pixel the truth sees it at; the distances are
   summarised by the kind of leaf that projected them. */
#include "sbc_internal.h"

/* refl_sbc_measure_camera_error's state: per truth pixel, the distance to
   the nearest image of its point and the kind of leaf its own group holds
   the point in (the nearest image's when it has no group). */
typedef struct refl__sb_measure {
    const refl_frame *truth;
    const refl__sb *sb;
    double *error;                /* INFINITY: no image within REFL__SB_MEASURE_REACH */
    uint8_t *kind;                /* refl_sbc_leaf_kind */
    double *own_error;            /* at sample pixels: through the pixel's own group, INFINITY: none */
    uint8_t *own_kind;            /* ... and its leaf there; NONE off the samples */
    int cells_x, cells_y;         /* REFL__SB_MEASURE_CELL pixel cells, each listing the groups */
    int *cell_start, *cell_list;  /* whose images can land within reach of its pixels */
    refl_sbc_camera_error *out;
} refl__sb_measure;

#define REFL__SB_MEASURE_REACH 8.0 /* pixels: an image further off shows another point */
#define REFL__SB_MEASURE_CELL 32   /* pixels per side of the measure's cells */

/* Group g's pixels that an image of it can reach: an image lands on the
   group's first reflector points (its tile, guard band and ring), and one further off
   than the reach does not count. */
static void refl__sb_measure_rect(const refl__sb *sb, const refl__sb_group *g, int r[4]) {
    const int reach = (int)REFL__SB_MEASURE_REACH + 1;
    r[0] = (g->u0 - REFL__SB_GUARD - 1) * sb->factor - reach;
    r[1] = (g->v0 - REFL__SB_GUARD - 1) * sb->factor - reach;
    r[2] = (g->u1 + REFL__SB_GUARD + 1) * sb->factor + reach;
    r[3] = (g->v1 + REFL__SB_GUARD + 1) * sb->factor + reach;
}

/* The cells' group lists (counted, then filled), groups in index order. */
static refl_result refl__sb_measure_cells(refl__sb_measure *ms) {
    const refl__sb *sb = ms->sb;
    const refl_allocator *al = &sb->p->scene->allocator;
    const int cell = REFL__SB_MEASURE_CELL;
    int pass, g, cx, cy, cells;
    ms->cells_x = (ms->truth->width + cell - 1) / cell;
    ms->cells_y = (ms->truth->height + cell - 1) / cell;
    cells = ms->cells_x * ms->cells_y;
    ms->cell_start = (int *)refl__calloc(al, (size_t)cells + 1, sizeof(int));
    if (!ms->cell_start) return REFL_ERROR_OUT_OF_MEMORY;
    for (pass = 0; pass < 2; ++pass) {
        for (g = 0; g < sb->group_count; ++g) {
            int r[4];
            if (!sb->groups[g].sbc) continue;
            refl__sb_measure_rect(sb, &sb->groups[g], r);
            for (cy = REFL__MAX(r[1], 0) / cell; cy <= REFL__MIN(r[3] / cell, ms->cells_y - 1); ++cy)
                for (cx = REFL__MAX(r[0], 0) / cell; cx <= REFL__MIN(r[2] / cell, ms->cells_x - 1); ++cx) {
                    if (!pass) ms->cell_start[cy * ms->cells_x + cx + 1]++;
                    else ms->cell_list[ms->cell_start[cy * ms->cells_x + cx]++] = g;
                }
        }
        if (!pass) {
            for (cx = 0; cx < cells; ++cx) ms->cell_start[cx + 1] += ms->cell_start[cx];
            ms->cell_list = (int *)refl__calloc(al, (size_t)REFL__MAX(ms->cell_start[cells], 1), sizeof(int));
            if (!ms->cell_list) return REFL_ERROR_OUT_OF_MEMORY;
        } else { /* the fill moved every start to the next cell's */
            for (cx = cells; cx > 0; --cx) ms->cell_start[cx] = ms->cell_start[cx - 1];
            ms->cell_start[0] = 0;
        }
    }
    return REFL_OK;
}

/* Row y of the truth: each point projected into every group of its
   reflector, as the method projects a vertex. */
static void refl__sb_measure_row(void *arg, int y) {
    refl__sb_measure *ms = (refl__sb_measure *)arg;
    const refl__sb *sb = ms->sb;
    const refl_frame *t = ms->truth;
    int x, c;
    for (x = 0; x < t->width; ++x) {
        size_t i = (size_t)y * (size_t)t->width + (size_t)x;
        const float *q = t->points + 3 * i;
        int object = t->stencil[i] - 1, own = sb->group_of[i] - 1;
        int cell = (y / REFL__SB_MEASURE_CELL) * ms->cells_x + x / REFL__SB_MEASURE_CELL;
        double best = INFINITY;
        refl_sbc_leaf_kind kind = REFL_SBC_LEAF_NONE;
        refl__sb_pv v;
        int sx, sy;
        ms->error[i] = ms->own_error[i] = INFINITY;
        ms->kind[i] = ms->own_kind[i] = REFL_SBC_LEAF_NONE;
        if (object < 0 || !refl__isfinite(q[0]) || !refl__isfinite(q[1]) || !refl__isfinite(q[2])) continue;
        memset(&v, 0, sizeof v);
        v.world = refl_v3(q[0], q[1], q[2]);
        refl__sb_sample_pixel(sb, x / sb->factor, y / sb->factor, &sx, &sy);
        if (sx == x && sy == y) { /* a sample: its own group's camera, where the build checked the fit */
            refl_sbc_leaf_kind k = own >= 0 && sb->groups[own].sbc ? refl_sbc_leaf_at(sb->groups[own].sbc, v.world)
                                                                   : REFL_SBC_LEAF_NONE;
            ms->own_kind[i] = (uint8_t)(k == REFL_SBC_LEAF_RAY_LIST ? REFL_SBC_LEAF_RAY_LIST : REFL_SBC_LEAF_PINHOLE);
            for (v.sheet = 0; k != REFL_SBC_LEAF_NONE && v.sheet < sb->groups[own].sheets; ++v.sheet) {
                refl__sb_project(sb, &sb->groups[own], &v);
                if (v.ok)
                    ms->own_error[i] = REFL__MIN(ms->own_error[i], hypot((double)v.sx - ((double)x + 0.5),
                                                                          (double)v.sy - ((double)y + 0.5)));
            }
        }
        for (c = ms->cell_start[cell]; c < ms->cell_start[cell + 1]; ++c) {
            const refl__sb_group *gr = &sb->groups[ms->cell_list[c]];
            double dx, dy, e;
            int rect[4];
            if (gr->object != object && !(object == 254 && gr->object >= 254)) continue;
            refl__sb_measure_rect(sb, gr, rect);
            if (x < rect[0] || x > rect[2] || y < rect[1] || y > rect[3]) continue;
            for (v.sheet = 0; v.sheet < gr->sheets; ++v.sheet) {
                refl__sb_project(sb, gr, &v);
                if (!v.ok) continue;
                dx = (double)v.sx - ((double)x + 0.5);
                dy = (double)v.sy - ((double)y + 0.5);
                e = sqrt(dx * dx + dy * dy);
                if (e < best) {
                    best = e;
                    kind = refl_sbc_leaf_at(gr->sbc, v.world);
                }
            }
        }
        if (best <= REFL__SB_MEASURE_REACH) ms->error[i] = best;
        /* charged to the leaf its own group holds it in (the groups'
           guard bands overlap: the nearest image may be a neighbour's) */
        if (own >= 0 && sb->groups[own].sbc) kind = refl_sbc_leaf_at(sb->groups[own].sbc, v.world);
        ms->kind[i] = (uint8_t)(kind == REFL_SBC_LEAF_RAY_LIST ? REFL_SBC_LEAF_RAY_LIST : REFL_SBC_LEAF_PINHOLE);
    }
}

/* The summaries of the pixels the measure left, by leaf kind: over every
   pixel the nearest image, over the ray map's sample pixels the image
   through the pixel's own group. */
static refl_result refl__sb_measure_summary(const refl__sb_measure *ms) {
    const refl__sb *sb = ms->sb;
    const refl_allocator *al = &sb->p->scene->allocator;
    int w = ms->truth->width, h = ms->truth->height, k, x, y;
    double *errors = (double *)refl__calloc(al, (size_t)w * (size_t)h, sizeof(double));
    refl_reflection_error *out[4];
    if (!errors) return REFL_ERROR_OUT_OF_MEMORY;
    out[0] = &ms->out->pinhole;
    out[1] = &ms->out->ray_list;
    out[2] = &ms->out->pinhole_samples;
    out[3] = &ms->out->ray_list_samples;
    for (k = 0; k < 4; ++k) {
        uint8_t want = (uint8_t)(k & 1 ? REFL_SBC_LEAF_RAY_LIST : REFL_SBC_LEAF_PINHOLE);
        const uint8_t *kind = k < 2 ? ms->kind : ms->own_kind;
        const double *error = k < 2 ? ms->error : ms->own_error;
        long long counted = 0, matched = 0;
        double sum = 0.0;
        for (y = 0; y < h; ++y)
            for (x = 0; x < w; ++x) {
                size_t i = (size_t)y * (size_t)w + (size_t)x;
                if (kind[i] != want) continue;
                ++counted;
                if (error[i] == INFINITY) continue;
                errors[matched++] = error[i];
                sum += error[i];
            }
        refl__metric_summary(errors, matched, sum, counted, counted - matched, 0, out[k]);
    }
    refl__free(al, errors);
    return REFL_OK;
}

/* SBC's cameras set up for pass p (a frame's base pass done) and measured
   against ms->truth into ms->out. */
static refl_result refl__sb_measure_cameras(refl__pass *p, refl__sb_measure *ms) {
    const refl_allocator *al = &p->scene->allocator;
    const refl_frame *fr = p->frame;
    size_t n = (size_t)fr->width * (size_t)fr->height;
    refl__sb sb;
    refl_result r = refl__sb_setup(&sb, p);
    ms->sb = &sb;
    ms->error = (double *)refl__calloc(al, n, sizeof(double));
    ms->kind = (uint8_t *)refl__calloc(al, n, 1);
    ms->own_error = (double *)refl__calloc(al, n, sizeof(double));
    ms->own_kind = (uint8_t *)refl__calloc(al, n, 1);
    if (r == REFL_OK && (!ms->error || !ms->kind || !ms->own_error || !ms->own_kind)) r = REFL_ERROR_OUT_OF_MEMORY;
    /* no reflector in view: nothing to measure (the truth shows none either) */
    if (r == REFL_OK && sb.group_of && (r = refl__sb_measure_cells(ms)) == REFL_OK) {
        rast_run_jobs(p->rc, fr->height, refl__sb_measure_row, ms);
        r = refl__sb_measure_summary(ms);
    }
    refl__free(al, ms->error);
    refl__free(al, ms->kind);
    refl__free(al, ms->own_error);
    refl__free(al, ms->own_kind);
    refl__free(al, ms->cell_start);
    refl__free(al, ms->cell_list);
    refl__sb_free(&sb);
    return r;
}

REFL_API refl_result refl_sbc_measure_camera_error(const refl_scene *scene, const refl_view *view,
                                                  const refl_render_desc *desc, const refl_frame *truth,
                                                  refl_sbc_camera_error *out) {
    refl__sb_measure ms;
    refl_render_desc given, d;
    refl_frame *frame = NULL;
    rast_context *rc = NULL;
    refl__pass p;
    const char *why;
    refl_result r;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    memset(out, 0, sizeof *out);
    if (!scene || !view || !truth || !truth->points || !truth->stencil) return REFL_ERROR_INVALID_ARGUMENT;
    if (view->width != truth->width || view->height != truth->height) return REFL_ERROR_INVALID_SIZE;
    memset(&given, 0, sizeof given);
    if (desc) given = *desc;
    given.method = REFL_SBC;
    given.depth = 1; /* the first order's cameras, as the truth's points are first bounces */
    given.object_methods = NULL;
    given.object_method_count = 0;
    if ((r = refl__resolve_desc(&given, &d, &why)) != REFL_OK) return r;
    memset(&ms, 0, sizeof ms);
    ms.truth = truth;
    ms.out = out;
    r = refl_frame_create(truth->width, truth->height, &scene->allocator, &frame);
    if (r == REFL_OK && refl__frame_rule(scene, view, frame)) r = REFL_ERROR_INVALID_ARGUMENT;
    if (r == REFL_OK) r = refl__context_create(scene, d.threads, &rc);
    if (r == REFL_OK) r = refl__base_pass(&p, scene, view, &d, frame, rc, NULL);
    if (r == REFL_OK) r = refl__sb_measure_cameras(&p, &ms);
    rast_context_destroy(rc);
    refl_frame_destroy(frame);
    return r;
}
