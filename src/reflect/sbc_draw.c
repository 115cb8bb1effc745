/* sbc_draw: SBC's reflected triangles drawn (paper 003 V-B;
   docs/methods/sbc.md, "4. Rasterisation"), a batch of groups at a time:
   by rast.h, twice (colour as DIRECT shades the surface, then its world
   point; each pass with its depth buffer), stencilled to each group's
   pixels. Layers are drawn in order, into one depth buffer; after order
   k < k_max, where a mirror or glass (drawn transparent black) is nearest
   the pixel is cleared: order k + 1 shows there, and nowhere an order-k
   point lies in front (the visibility offset): lower orders occlude higher
   ones. Refractions draw into targets of their own (they add to the
   reflection, never hide it). */
#include "sbc_internal.h"

static refl_result refl__sb_canvas_create(refl__sb_canvas *c, const refl_allocator *al, size_t npx) {
    c->color = (float *)refl__calloc(al, npx, 4 * sizeof(float));
    c->depth = (float *)refl__calloc(al, npx, sizeof(float));
    c->points = (float *)refl__calloc(al, npx, 4 * sizeof(float));
    c->points_depth = (float *)refl__calloc(al, npx, sizeof(float));
    return c->color && c->depth && c->points && c->points_depth ? REFL_OK : REFL_ERROR_OUT_OF_MEMORY;
}

static void refl__sb_canvas_free(refl__sb_canvas *c, const refl_allocator *al) {
    refl__free(al, c->color);
    refl__free(al, c->depth);
    refl__free(al, c->points);
    refl__free(al, c->points_depth);
    memset(c, 0, sizeof *c);
}

/* The targets of draw pass `pass` into canvas c: 0 the colour, 1 the
   points, each with its own depth buffer (the batch draws both passes). */
static rast_targets refl__sb_targets(const refl__sb *sb, const refl__sb_canvas *c, int pass) {
    const refl_frame *fr = sb->p->frame;
    rast_targets t;
    memset(&t, 0, sizeof t);
    t.color.width = t.depth.width = t.stencil.width = fr->width;
    t.color.height = t.depth.height = t.stencil.height = fr->height;
    t.depth.ptr = pass ? c->points_depth : c->depth;
    t.depth.stride = (int)sizeof(float) * fr->width;
    t.stencil.ptr = sb->stencil;
    t.stencil.stride = fr->width;
    t.color.ptr = pass ? (void *)c->points : (void *)c->color;
    t.color.stride = 4 * (int)sizeof(float) * fr->width;
    t.color_format = RAST_COLOR_RGBA32F;
    return t;
}

/* The reflections' targets, and the refraction layer's when there is one,
   and the stencil, made; both passes' colour and depth cleared, once
   before the batches. */
static refl_result refl__sb_draw_begin(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    size_t npx = (size_t)sb->p->frame->width * (size_t)sb->p->frame->height;
    refl_result r = refl__sb_canvas_create(&sb->drawn, al, npx);
    rast_result rr = RAST_OK;
    int pass;
    sb->stencil = (uint8_t *)refl__calloc(al, npx, 1);
    if (!sb->stencil) r = REFL_ERROR_OUT_OF_MEMORY;
    if (r == REFL_OK && sb->layers > sb->orders) r = refl__sb_canvas_create(&sb->refr, al, npx);
    if (r != REFL_OK) return r;
    for (pass = 0; pass < (sb->layers > sb->orders ? 4 : 2) && rr == RAST_OK; ++pass) {
        rast_targets t = refl__sb_targets(sb, pass < 2 ? &sb->drawn : &sb->refr, pass & 1);
        if ((rr = rast_set_targets(sb->p->rc, &t)) == RAST_OK)
            rr = refl__em_clear(sb->p->rc, RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH);
    }
    if (rr == RAST_OK) rr = rast_finish(sb->p->rc);
    return refl__result_from_rast(rr);
}

static void refl__sb_draw_end(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    refl__sb_canvas_free(&sb->drawn, al);
    refl__sb_canvas_free(&sb->refr, al);
    refl__free(al, sb->stencil);
    sb->stencil = NULL;
}

/* After the groups of order k < k_max: where a mirror or glass (drawn
   transparent black, alpha 0) is nearest, the reflection goes on there, so
   the order k + 1 draws may (they lie behind every order-k point, by the
   visibility offset); the mirror hid the order-k points behind it. */
static void refl__sb_pass_through(refl__sb *sb) {
    refl__sb_canvas *c = &sb->drawn;
    size_t k, npx = (size_t)sb->p->frame->width * (size_t)sb->p->frame->height;
    for (k = 0; k < npx; ++k)
        if (c->depth[k] < 1.0f && c->color[4 * k + 3] == 0.0f) c->depth[k] = c->points_depth[k] = 1.0f;
}

/* The points pass's fragments: the world position and the object drawn
   (user: the object's index + 1, as a float), which the fallback checks
   against what the ray map's samples meet. */
static int refl__sb_point_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    rgba[0] = in->varyings[0];
    rgba[1] = in->varyings[1];
    rgba[2] = in->varyings[2];
    rgba[3] = *(const float *)user;
    return 1;
}

/* Draws the batch's jobs into the scratch targets: colour, then the points
   with the same depth test, each job stencilled to its group's pixels. */
static refl_result refl__sb_draw(refl__sb *sb) {
    refl__pass *p = sb->p;
    const refl_scene *scene = p->scene;
    refl_frame *fr = p->frame;
    refl__draw_ctx *dc = (refl__draw_ctx *)refl__calloc(&scene->allocator, (size_t)scene->object_count,
                                                        sizeof(refl__draw_ctx));
    float *ids = (float *)refl__calloc(&scene->allocator, (size_t)scene->object_count, sizeof(float));
    rast_result rr = RAST_OK;
    int pass, i;
    size_t k, npx = (size_t)fr->width * (size_t)fr->height;
    if (!dc || !ids) {
        refl__free(&scene->allocator, dc);
        refl__free(&scene->allocator, ids);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < scene->object_count; ++i) {
        refl__draw_ctx_init(&dc[i], scene, i, p->vp);
        ids[i] = (float)(i + 1);
    }
    for (k = 0; k < npx; ++k) {
        int g = sb->group_of[(size_t)sb->batch.layer * npx + k] - 1;
        sb->stencil[k] = (uint8_t)(g >= sb->batch.first && g < sb->batch.end ? g - sb->batch.first + 1 : 0);
    }
    for (pass = 0; pass < 2 && rr == RAST_OK; ++pass) {
        rast_targets t = refl__sb_targets(sb, sb->batch.layer >= sb->orders ? &sb->refr : &sb->drawn, pass);
        if ((rr = rast_set_targets(p->rc, &t)) != RAST_OK) break;
        for (i = 0; i < sb->batch.job_count && rr == RAST_OK; ++i) {
            const refl__sb_job *j = &sb->batch.jobs[i];
            const refl__draw_ctx *d = &dc[j->object];
            rast_state s;
            rast_draw_desc dd;
            if (!j->out_count) continue;
            memset(&s, 0, sizeof s);
            s.depth_test = 1;
            s.stencil_test = 1;
            s.stencil_front.func = RAST_EQUAL;
            s.stencil_front.ref = (uint8_t)(j->group - sb->batch.first + 1);
            s.stencil_back = s.stencil_front;
            if (pass == 1) {
                s.fragment_fn = refl__sb_point_fragment;
                s.fragment_user = &ids[j->object];
            } else {
                s.fragment_fn = d->material->type == REFL_DIFFUSE || d->material->type == REFL_PARTIAL
                                    ? refl__base_fragment
                                    : refl__clear_fragment;
                s.fragment_user = (void *)d;
            }
            memset(&dd, 0, sizeof dd);
            dd.primitive = RAST_TRIANGLES;
            dd.vertices = j->out;
            dd.vertex_count = (int)j->out_count;
            dd.stride = REFL__SB_FLOATS;
            dd.position_size = 4;
            dd.num_varyings = REFL__SB_FLOATS - 4;
            if ((rr = rast_set_state(p->rc, &s)) == RAST_OK) rr = rast_draw(p->rc, &dd);
            if (pass == 0) fr->stats.triangles += (long long)(j->out_count / 3);
        }
        if (rr == RAST_OK) rr = rast_finish(p->rc);
    }
    refl__free(&scene->allocator, dc);
    refl__free(&scene->allocator, ids);
    return refl__result_from_rast(rr);
}
