/* SBC: Popescu, Sacks and Mei's sample-based camera reflections (paper
   003; docs/methods/sbc.md tells the algorithm, step by step). Per frame,
   after the base pass:
     1. ray maps (sbc_raymap.c): a reflected ray per factor x factor pixels
        of every reflector side seen, from the reflectors' G-buffer; past
        the first order, the reflection histories traced through the
        mirrors and glass;
     2. reflection groups (sbc_groups.c): each ray map cut into smooth
        pieces, the curved ones into tiles, each group a BSP tree of
        sample-based cameras (cam_sbc.c) built to the requested error, each
        pixel given a group;
     3. projection and 4. rasterisation, in batches of groups: every scene
        vertex in a group's box projected into it, its triangles emitted and
        subdivided (sbc_project.c), then drawn, stencilled to the group's
        pixels (sbc_draw.c);
     5. composite (sbc_resolve.c): what was drawn times the reflectance,
        cracks filled, holes and contradicted pixels traced with
        desc.sbc.trace_fallback.
   The rays meet the scene's BVH (SBC-traced, the default) or its box
   alone (SBC-paper, desc.sbc.mode: no search of the scene).
   This file: the options, the frame's setup (steps 1 and 2), the memory
   bound (desc.sbc.memory_mb) and its orchestration. Diffuse shading needs
   no eye vector (Lambert), so the paper's true eye vector for point lights
   has nothing to change here.
   Deterministic: work is split into jobs whose outputs are drawn in job
   order. */
#include "sbc_internal.h"

#define REFL__SB_FACTOR 2           /* default ray map down-sampling */

static const char *refl__options_sbc(refl_render_desc *d) {
    const refl_sbc_options *o = &d->sbc;
    if (!(o->error_px >= 0.0f) || !refl__isfinite(o->error_px)) return "sbc.error_px: finite, 0 (1) or more";
    if (o->ray_factor < 0 || o->ray_factor > 64) return "sbc.ray_factor: 0 (2) to 64";
    if (o->batch_groups < 0 || o->batch_groups > 254) return "sbc.batch_groups: 0 (254) to 254";
    if (o->trace_fallback < 0 || o->trace_fallback > 1) return "sbc.trace_fallback: 0 or 1";
    if (o->mixed_levels > 6) return "sbc.mixed_levels: negative (never), 0 (the default) or 1 to 6";
    if (o->morph_count < 0 || (o->morph_count > 0 && !o->morphs))
        return "sbc.morphs: morph_count 0, or the array of that many grids";
    if (o->mode != REFL_SBC_TRACED && o->mode != REFL_SBC_PAPER) return "sbc.mode: REFL_SBC_TRACED or REFL_SBC_PAPER";
    if (o->mode == REFL_SBC_PAPER && o->trace_fallback)
        return "sbc.mode: REFL_SBC_PAPER searches no scene, so trace_fallback must be 0";
    if (o->memory_mb < 0) return "sbc.memory_mb: 0 (2048) or more";
    return NULL;
}

/* A frame past desc.sbc.memory_mb: OUT_OF_MEMORY, `why` in frame->message. */
static refl_result refl__sb_over_memory(refl__sb *sb, const char *why) {
    refl__frame_say(sb->p->frame, "%s (%.0f MiB, more than sbc.memory_mb %.0f)", why,
                    (double)sb->memory_fixed / 1048576.0, (double)sb->memory_limit / 1048576.0);
    return REFL_ERROR_OUT_OF_MEMORY;
}

/* Everything up to the groups' trees (shared with refl_sbc_measure_camera_error). */
static refl_result refl__sb_setup(refl__sb *sb, refl__pass *p) {
    const refl_allocator *al = &p->scene->allocator;
    size_t npx = (size_t)p->frame->width * (size_t)p->frame->height;
    unsigned char *seen = NULL;
    refl_vec3 lo, hi, grow;
    refl_result r;
    int any = 0, g;
    memset(sb, 0, sizeof *sb);
    sb->p = p;
    sb->factor = p->desc.sbc.ray_factor > 0 ? p->desc.sbc.ray_factor : REFL__SB_FACTOR;
    sb->map_w = (p->frame->width + sb->factor - 1) / sb->factor;
    sb->map_h = (p->frame->height + sb->factor - 1) / sb->factor;
    sb->error_px = p->desc.sbc.error_px > 0.0f ? p->desc.sbc.error_px : 1.0f;
    /* with the fallback, the pixels a group's edge leaves uncovered are
       traced: splitting mixed triangles costs more than it buys */
    sb->mixed_levels = p->desc.sbc.mixed_levels > 0   ? p->desc.sbc.mixed_levels
                       : p->desc.sbc.mixed_levels < 0 ? 0
                       : p->desc.sbc.trace_fallback   ? 0
                                                      : -1;
    sb->batch.size = p->desc.sbc.batch_groups > 0 ? p->desc.sbc.batch_groups : REFL__SB_BATCH;
    sb->memory_limit = (size_t)(p->desc.sbc.memory_mb > 0 ? p->desc.sbc.memory_mb : REFL__SB_MEMORY_MB) << 20;
    for (g = 0; g < p->scene->object_count; ++g)
        sb->vertices += p->scene->meshes[p->scene->objects[g].mesh]->vertex_count;
    sb->budget = REFL__CLAMP(p->desc.depth, 1, REFL__SB_ORDERS);
    sb->orders = sb->layers = 1;
    refl_scene_bounds(p->scene, &lo, &hi);
    grow = refl_v3_scale(refl_v3_sub(hi, lo), 0.01f);
    grow = refl_v3_add(grow, refl_v3(1e-4f, 1e-4f, 1e-4f));
    sb->box_lo = refl_v3_sub(lo, grow);
    sb->box_hi = refl_v3_add(hi, grow);
    sb->diagonal = refl_v3_length(refl_v3_sub(sb->box_hi, sb->box_lo));
    /* the reflectors' G-buffer (ENVMAP's) and the point seen at each pixel */
    sb->em = (refl__em *)refl__calloc(al, 1, sizeof(refl__em));
    if (!sb->em) return REFL_ERROR_OUT_OF_MEMORY;
    sb->em->p = p;
    r = refl__em_gbuffer_new(sb->em, &seen, &any);
    refl__free(al, seen);
    if (r != REFL_OK || !any) return r;
    /* SBC-traced's rays meet the scene's BVH; SBC-paper's meet its box alone */
    if (p->desc.sbc.mode != REFL_SBC_PAPER && (r = refl__models_bvh(p, &sb->bvh, &sb->own_bvh)) != REFL_OK) return r;
    sb->em->surface = (float *)refl__calloc(al, npx, 3 * sizeof(float));
    if (!sb->em->surface) return REFL_ERROR_OUT_OF_MEMORY;
    rast_run_jobs(p->rc, p->frame->height, refl__em_surface_row, sb->em);
    if ((r = refl__sb_ray_maps(sb)) != REFL_OK) return r;
    sb->memory_fixed = (size_t)sb->side_count * (size_t)sb->map_w * (size_t)sb->map_h * REFL__SB_SAMPLE_BYTES;
    if (sb->memory_fixed > sb->memory_limit) return refl__sb_over_memory(sb, "sbc.memory_mb: the ray maps alone exceed it");
    if ((r = refl__sb_groups(sb)) != REFL_OK) return r;
    p->frame->stats.sbc.histories += sb->side_count;
    p->frame->stats.sbc.groups += sb->group_count;
    for (g = 0; p->desc.debug.sbc_ray_map && g < sb->side_count && !sb->sides[g].layer; ++g)
        p->desc.debug.sbc_ray_map(p->desc.debug.sbc_ray_map_user, sb->sides[g].object, sb->sides[g].rays,
                                  sb->sides[g].valid, sb->map_w, sb->map_h);
    rast_run_jobs(p->rc, sb->group_count, refl__sb_build_group, sb);
    if ((r = refl__sb_morph_groups(sb)) != REFL_OK) return r;
    for (g = 0; g < sb->group_count; ++g) {
        refl_sbc_stats st;
        if (sb->groups[g].result != REFL_OK) return sb->groups[g].result;
        refl_sbc_get_stats(sb->groups[g].sbc, &st);
        p->frame->stats.sbc.pinhole_leaves += st.pinhole_leaves;
        p->frame->stats.sbc.ray_leaves += st.ray_leaves;
        p->frame->stats.rays += st.rays;
        p->frame->stats.model_bytes += st.bytes;
        sb->memory_fixed += (size_t)st.bytes;
    }
    if (sb->memory_fixed > sb->memory_limit)
        return refl__sb_over_memory(sb, "sbc.memory_mb: the ray maps and the groups' trees exceed it");
    return REFL_OK;
}

static void refl__sb_free(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    refl__sb_groups_free(sb);
    refl__sb_ray_maps_free(sb);
    refl__sb_batch_free(sb);
    refl__sb_draw_end(sb);
    refl_bvh_destroy(sb->own_bvh);
    if (sb->em) {
        refl__free(al, sb->em->gbuf);
        refl__free(al, sb->em->draws);
        refl__free(al, sb->em->surface);
        refl__free(al, sb->em);
    }
}

/* The layer g draws in: its side's; a morph's piece reflects once. */
static int refl__sb_group_layer(const refl__sb *sb, const refl__sb_group *g) {
    return g->morph ? 0 : sb->sides[g->side].layer;
}

/* An SBC frame: the setup, the batches projected and drawn, the composite. */
static refl_result refl__sb_run(refl__pass *p) {
    refl_frame *fr = p->frame;
    double t0 = refl__now_ms(), t1;
    refl__sb sb;
    refl_result r = refl__sb_setup(&sb, p);
    int i;
    t1 = refl__now_ms();
    fr->stats.ms_build += t1 - t0;
    if (r == REFL_OK && sb.group_count) {
        r = refl__sb_draw_begin(&sb);
        /* groups in batches of the stencil's values, each within one layer
           (the sides, so the groups, come layer by layer); a group's pixels
           are its own in its layer, so a layer's batches' depth tests never
           meet, and the orders meet by the visibility offset */
        for (sb.batch.first = 0; r == REFL_OK && sb.batch.first < sb.group_count; sb.batch.first = sb.batch.end) {
            /* a batch's groups index every scene vertex each: as many as
               half the memory bound leaves room for */
            size_t room = (sb.memory_limit - sb.memory_fixed) / 2 / ((size_t)sb.vertices * sizeof(int) + 1);
            int end = REFL__MIN(sb.batch.first + REFL__MIN(sb.batch.size, (int)REFL__MIN(room, (size_t)INT_MAX)),
                                sb.group_count);
            if (!room) {
                r = refl__sb_over_memory(&sb, "sbc.memory_mb: one group's projected vertices exceed it");
                break;
            }
            sb.batch.layer = refl__sb_group_layer(&sb, &sb.groups[sb.batch.first]);
            sb.batch.end = sb.batch.first + 1;
            while (sb.batch.end < end && refl__sb_group_layer(&sb, &sb.groups[sb.batch.end]) == sb.batch.layer)
                ++sb.batch.end;
            r = refl__sb_project_all(&sb);
            for (i = 0; i < sb.batch.job_count; ++i) {
                fr->stats.sbc.projections += sb.batch.jobs[i].projections;
                fr->stats.sbc.projected += sb.batch.jobs[i].projected;
            }
            if (r == REFL_OK) r = refl__sb_draw(&sb);
            refl__sb_batch_clear(&sb);
            if (r == REFL_OK && sb.batch.layer + 1 < sb.orders &&
                (sb.batch.end == sb.group_count ||
                 refl__sb_group_layer(&sb, &sb.groups[sb.batch.end]) != sb.batch.layer))
                refl__sb_pass_through(&sb);
        }
        t0 = refl__now_ms();
        fr->stats.ms_reflect += t0 - t1;
        if (r == REFL_OK) r = refl__sb_resolve(&sb);
        fr->stats.ms_composite += refl__now_ms() - t0;
    }
    if (r == REFL_OK) {
        rast_targets t = refl__frame_targets(fr);
        r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    }
    refl__sb_free(&sb);
    return r;
}

static refl_result refl__method_sbc(refl__pass *p) { return refl__sb_run(p); }

/* At one bounce a ray refracted into glass cannot leave it, and no
   refraction group is drawn: SBC-traced hands glass to RAYTRACE's tracer
   there, as C3RC does, so the pixel shows what that one bounce meets
   (the glass's inside, unlit); SBC-paper keeps the environment refracted
   once. */
static refl_result refl__sbc_handles(const refl__pass *p, int object, int *can) {
    *can = p->scene->materials[p->scene->objects[object].material].type != REFL_GLASS || p->desc.depth >= 2 ||
           p->desc.sbc.mode == REFL_SBC_PAPER;
    return REFL_OK;
}
