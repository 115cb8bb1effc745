/* sbc_resolve: SBC's composite (paper 003 V-D; docs/methods/sbc.md, "5.
   Composite" and "The ray-traced fallback"). The reflected colour, or the
   environment along the pixel's reflected ray where nothing was drawn,
   times the material's reflectance (Schlick's Fresnel, or V-D's Fresnel
   blend and distance fade, when the material asks), as ENVMAP composites;
   glass adds the environment refracted once. A pixel of a group (of the
   first layer) that nothing was drawn on, between two drawn pixels of its
   group on opposite sides, is a crack (reflected triangles subdivided to
   different depths meet at a T-junction) and takes the nearer one's
   reflection (past the first order, the order with it). With
   desc.sbc.trace_fallback (beyond the paper) a pixel still without a
   reflection, or whose first-order point the samples around it contradict
   (refl__sb_fallback), is rendered as RAYTRACE renders it (refl__rt_pixel)
   when its reflected ray meets anything; mixed triangles are then not
   split (sbc_project.c), their pixels traced. SBC-traced checks the
   pixels of groups whose rays fold so even without the option
   (refl__sb_checked), and renders so every pixel whose last order drawn
   shows a mirror while the depth goes on (refl__sb_goes_past), and every
   hole past the first order whose path's last ray meets a mirror or glass,
   or another surface a hair away (refl__sb_hole_goes_on).

   Past the first order (refl__sb_resolve_row_deep): the nearest order's
   colour (its order read off the offset), or the environment along the
   last reflected ray, times the product of the reflectances along the
   pixel's own history (each bounce as RAYTRACE weighs it, faded by its
   reflected ray's length when the material asks); glass adds (1 - F) tint
   times what the refraction layer drew (or the environment beyond the
   glass), times (1 - F) at the exit and the absorption inside; reflections
   inside the glass short of total are left out. frame->points: the first
   point past the first reflector, as RAYTRACE's, or with
   desc.debug.points_last the last. */
#include "sbc_internal.h"

#define REFL__SB_HOLE_NEAR_PX 2.0f  /* a hole's last ray meeting a surface this near (pixels' footprint): traced */

/* Where pixel (x, y) of a group, with nothing drawn on it, takes its
   reflection from (past the first order, its order too): the nearer of two drawn pixels of its
   group on opposite sides of it (left and right, above and below, or
   diagonally). Reflected triangles subdivided to different depths meet
   at edges bent differently (a T-junction), and the crack between them
   is a pixel wide; a hole wider than that stays one. Itself when none. */
static size_t refl__sb_crack_source(const refl__sb *sb, int x, int y) {
    static const int dir[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    const refl_frame *fr = sb->p->frame;
    size_t i = (size_t)y * (size_t)fr->width + (size_t)x, best = i;
    int k, e;
    for (k = 0; k < 4; ++k) {
        size_t side[2];
        int ok = 1;
        for (e = 0; e < 2 && ok; ++e) {
            int sx = x + (e ? -dir[k][0] : dir[k][0]), sy = y + (e ? -dir[k][1] : dir[k][1]);
            if (sx < 0 || sy < 0 || sx >= fr->width || sy >= fr->height) ok = 0;
            else side[e] = (size_t)sy * (size_t)fr->width + (size_t)sx;
            ok = ok && sb->group_of[side[e]] == sb->group_of[i] && sb->drawn.depth[side[e]] < 1.0f;
        }
        for (e = 0; e < 2 && ok; ++e)
            if (best == i || sb->drawn.depth[side[e]] < sb->drawn.depth[best]) best = side[e];
    }
    return best;
}

/* Pixel (x, y) under desc.sbc.trace_fallback (refl__sb_fallback): where
   its reflected ray (taken as the ray map's samples take it) meets
   anything, the pixel is rendered as RAYTRACE renders it, colour and
   point, and 1 is returned; else 0, and it keeps what SBC made of it (a
   hole: the environment, as without the option; most holes are the sky
   seen in the mirror, one ray each). */
static void refl__sb_render_pixel(const refl__sb *sb, int x, int y);
static int refl__sb_trace_pixel(const refl__sb *sb, int x, int y) {
    size_t i = (size_t)y * (size_t)sb->p->frame->width + (size_t)x;
    refl_vec3 d, q, n;
    refl_sbc_ray ray;
    refl__sbc_hit met;
    refl__sb_pixel_view(sb, i, &d, &q, &n);
    sb->tracer.rays[y]++;
    if (!refl__sb_ray(sb, q, n, d, &ray, &met) || met.object < 0) return 0;
    refl__sb_render_pixel(sb, x, y);
    return 1;
}

/* Pixel (x, y) rendered as RAYTRACE renders it, colour and point. */
static void refl__sb_render_pixel(const refl__sb *sb, int x, int y) {
    refl_frame *fr = sb->p->frame;
    size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
    refl_vec3 shown;
    float rgb[3], depth;
    uint8_t stencil;
    int c;
    refl__rt_pixel(sb->tracer.rt, x, y, &sb->tracer.rays[y], rgb, &shown, &depth, &stencil);
    sb->tracer.pixels[y]++;
    for (c = 0; c < 3; ++c) fr->rgba[4 * i + (size_t)c] = rgb[c];
    fr->rgba[4 * i + 3] = 1.0f;
    fr->points[3 * i] = shown.x;
    fr->points[3 * i + 1] = shown.y;
    fr->points[3 * i + 2] = shown.z;
}

/* Whether pixel i, of a group or not, shows nothing drawn (src: where
   its reflection comes from, itself or a crack's neighbour). */
static int refl__sb_hole(const refl__sb *sb, size_t i, size_t src) {
    return !(sb->group_of[i] && sb->drawn.depth[src] < 1.0f);
}

/* Whether what is drawn at pixel src is a mirror or glass (transparent
   black) while the frame's depth allows another bounce. Lower orders pass
   such pixels on (refl__sb_pass_through), so it lies in the last order
   the ray map's samples reached (sb->orders, the longest history
   sampled), and its path goes on past every group (the concave bowl's
   outer rim, seen through more bounces than any sample took). It is not
   black there: RAYTRACE's tracer renders the pixel (SBC-traced; SBC-paper
   searches no scene). */
static int refl__sb_goes_past(const refl__sb *sb, size_t src) {
    return sb->bvh && sb->orders < sb->budget && sb->drawn.depth[src] < 1.0f && sb->drawn.color[4 * src + 3] == 0.0f;
}

/* Whether a hole's path (pa, traced through the mirrors and glass)
   goes on: its last reflected ray meets a mirror or glass, or another
   surface within REFL__SB_HOLE_NEAR_PX pixels' footprint (at the path's
   length) of the point it leaves. No layer drew what it meets there (the
   seams between mirror-room's wall mirrors, high up, through six bounces;
   the floor where a wall mirror meets it, whose reflection near the seam
   is a sliver thinner than a pixel), and the environment along that ray is
   not what the path shows: RAYTRACE's tracer renders the pixel
   (SBC-traced; its black where the depth runs out, its reflection where it
   goes on). The search starts at the point of the triangle the path
   leaves (refl__sb_path_start), as RAYTRACE's does, and skips the surface
   it leaves. */
static int refl__sb_hole_goes_on(const refl__sb *sb, const refl__sb_path *pa) {
    const refl_view *v = sb->p->view;
    float fovy = (v->fovy_degrees > 0.0f ? v->fovy_degrees : 45.0f) * (float)REFL__PI / 180.0f, length, reach;
    int last = (int)fabsf(pa->id[pa->count - 1]) - 1, k;
    refl_vec3 o = pa->q[pa->count - 1], near;
    refl_hit h;
    if (!sb->bvh) return 0;
    near = pa->count > 1 ? o : refl__sb_path_start(sb, o, pa->d[0], last);
    if (refl__sb_mirror_hit(sb, o, near, pa->out, last, &h)) return 1;
    length = refl_v3_length(refl_v3_sub(pa->q[0], v->eye));
    for (k = 1; k < pa->count; ++k) length += refl_v3_length(refl_v3_sub(pa->q[k], pa->q[k - 1]));
    reach = REFL__SB_HOLE_NEAR_PX * length * 2.0f * tanf(0.5f * fovy) / (float)v->height;
    if (!refl_bvh_intersect(sb->bvh, near, pa->out, 1e-6f * sb->diagonal, reach, &h)) return 0;
    return h.object != last || refl_bvh_intersect(sb->bvh, near, pa->out, 1e-4f * sb->diagonal + h.t, reach, &h);
}

/* Whether side sd's four ray map samples around pixel i contradict the
   point drawn there (shown: world point, object + 1), seen from `from`
   (where the pixel's ray leaves the last reflector): on an object none of
   their rays meets, or nearer than the nearest of what they meet or
   farther than the farthest. 0 where a sample does not show the side. */
static int refl__sb_samples_contradict(const refl__sb *sb, const refl__sb_side *sd, size_t i, const float *shown,
                                       refl_vec3 from) {
    const refl_frame *fr = sb->p->frame;
    int x = (int)(i % (size_t)fr->width), y = (int)(i / (size_t)fr->width), f = sb->factor, k;
    int u0 = (x - f / 2 + f) / f - 1, v0 = (y - f / 2 + f) / f - 1; /* the samples around it: u0, u0 + 1 */
    float lo = INFINITY, hi = 0.0f, d;
    int met_shown = 0, object = (int)shown[3] - 1;
    for (k = 0; k < 4; ++k) {
        int u = u0 + (k & 1), v = v0 + (k >> 1);
        size_t at = (size_t)v * (size_t)sb->map_w + (size_t)u;
        if (u < 0 || v < 0 || u >= sb->map_w || v >= sb->map_h || sd->valid[at] != 1) return 0;
        d = sd->hits[at].object < 0 ? INFINITY : refl_v3_length(refl_v3_sub(sd->hits[at].point, sd->rays[at].tail));
        lo = REFL__MIN(lo, d);
        hi = REFL__MAX(hi, d);
        met_shown |= sd->hits[at].object == object;
    }
    d = refl_v3_length(refl_v3_sub(refl_v3(shown[0], shown[1], shown[2]), from));
    return !met_shown || d < lo || d > hi;
}

/* Whether desc.sbc.trace_fallback traces pixel i (src as above; first:
   what it shows is a first-order reflection): a hole, or a first-order
   point the ray map's samples around the pixel contradict, seen from the
   reflector's point (refl__sb_samples_contradict). Where the reflection is continuous
   between the samples, the distance to what it shows is too, and lies
   between theirs; a point outside is a surface the samples do not see:
   the floor drawn below the lid's rim where the truth sees the teapot's
   own surface. A thin object between the samples is traced too: exact, at
   a ray's cost. */
static int refl__sb_fallback(const refl__sb *sb, size_t i, size_t src, int first) {
    refl_vec3 q = refl_v3(sb->em->surface[3 * i], sb->em->surface[3 * i + 1], sb->em->surface[3 * i + 2]);
    if (refl__sb_hole(sb, i, src)) return 1;
    if (!first || sb->groups[sb->group_of[i] - 1].morph) return 0; /* a morph group has no samples here */
    return refl__sb_samples_contradict(sb, &sb->sides[sb->groups[sb->group_of[i] - 1].side], i,
                                       sb->drawn.points + 4 * src, q);
}

/* Whether glass pixel i's refraction (view direction d, point q, normal
   n, side id `id`) is one that SBC-traced traces, with or without
   desc.sbc.trace_fallback: it leaves the glass, or meets a surface inside
   it, with nothing drawn on the refraction layer there; or it meets
   another mirror or glass first, or stays inside (reflected within), which
   no refraction group models. A thick glass's refracted rays cross: its
   refraction groups are mostly ray lists whose triangles across a fold are
   dropped, and the environment beyond the glass in their place is flat
   light patches with straight edges across the teapot. Where such a
   triangle was the nearest surface, the depth test shows what lies behind
   it (a floor tile's side face behind the next tile's top): in a group
   whose rays fold (every group with the fallback), a point the refraction
   side's samples around the pixel contradict, seen from the pixel's exit,
   is traced too (refl__sb_samples_contradict). Past one bounce only: at
   depth 1 SBC-paper's glass shows the environment refracted once, as
   ENVMAP's (SBC-traced hands glass to the tracer there). */
static int refl__sb_refraction_traced(const refl__sb *sb, size_t i, refl_vec3 d, refl_vec3 q, refl_vec3 n, float id) {
    size_t npx = (size_t)sb->p->frame->width * (size_t)sb->p->frame->height;
    const refl__sb_group *g;
    refl__sb_refr rp;
    if (refl__sb_material(sb, id)->type != REFL_GLASS || sb->budget < 2) return 0;
    if (refl__sb_refract_path(sb, q, n, d, id, &rp) <= 0 ||
        !(sb->layers > sb->orders && sb->group_of[(size_t)sb->orders * npx + i] && sb->refr.depth[i] < 1.0f))
        return 1;
    g = &sb->groups[sb->group_of[(size_t)sb->orders * npx + i] - 1];
    return (!sb->tracer.folds_only || g->sheets > 1) && !g->morph &&
           refl__sb_samples_contradict(sb, &sb->sides[g->side], i, sb->refr.points + 4 * i, rp.tail);
}

/* Whether pixel i goes through the fallback's checks (refl__sb_fallback):
   every pixel with desc.sbc.trace_fallback; by default (SBC-traced) those
   of a first-layer group of the frame's ray map (not a morphing grid's)
   whose rays fold. A reflected triangle that
   straddles a fold wider than REFL__SB_FOLD_SAMPLES is not drawn (its
   images part at the caustic), and where it was the nearest surface the
   depth test shows what lies behind it (the far side of the ball at the
   concave bowl's focus, smeared into a ring) or nothing: the samples
   contradict such a point, and RAYTRACE's tracer renders the pixel. */
static int refl__sb_checked(const refl__sb *sb, size_t i) {
    if (!sb->tracer.rt) return 0;
    if (!sb->tracer.folds_only) return 1;
    return sb->group_of[i] && !sb->groups[sb->group_of[i] - 1].morph && sb->groups[sb->group_of[i] - 1].sheets > 1;
}

static void refl__sb_resolve_row(void *arg, int y) {
    const refl__sb *sb = (const refl__sb *)arg;
    const refl_frame *fr = sb->p->frame;
    int x, c;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x, src = i;
        float sub[3];
        if (sb->em->gbuf[4 * i + 3] == 0.0f) continue;
        if (sb->group_of[i] && !(sb->drawn.depth[i] < 1.0f)) src = refl__sb_crack_source(sb, x, y);
        if (refl__sb_checked(sb, i) && refl__sb_fallback(sb, i, src, 1) && refl__sb_trace_pixel(sb, x, y)) continue;
        if (sb->group_of[i] && refl__sb_goes_past(sb, src)) {
            refl__sb_render_pixel(sb, x, y);
            continue;
        }
        /* a pixel of no group (its tile's samples lie on other surfaces)
           shows the environment, as one nothing reflects in */
        if (!refl__sb_hole(sb, i, src)) {
            const float *q = sb->drawn.points + 4 * src;
            for (c = 0; c < 3; ++c) sub[c] = sb->drawn.color[4 * src + (size_t)c];
            refl__em_composite(sb->p, sb->em->gbuf + 4 * i, x, y, sub, refl_v3(q[0], q[1], q[2]));
        } else {
            refl__em_composite(sb->p, sb->em->gbuf + 4 * i, x, y, NULL, refl_v3(NAN, NAN, NAN));
        }
    }
}

/* refl__sb_resolve_row past the first order: a pixel's reflected colour
   is the nearest order's drawn colour (its order read off the visibility
   offset) times the reflectances along the pixel's own history to that
   order, or the environment along its last reflected ray times them all;
   glass adds what its refraction layer drew (else the environment beyond
   the glass) times (1 - F) tint at the entry and the refraction path's
   weight. The point shown: the first past the first reflector, as RAYTRACE
   records it (the second reflector's surface on an order-2 path), or with
   desc.debug.points_last the last one drawn (NaN where none). */
static void refl__sb_resolve_row_deep(void *arg, int y) {
    const refl__sb *sb = (const refl__sb *)arg;
    const refl__pass *p = sb->p;
    const refl_scene *scene = p->scene;
    refl_frame *fr = p->frame;
    size_t npx = (size_t)fr->width * (size_t)fr->height;
    int x, c, last = p->desc.debug.points_last;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x, src = i;
        const float *g = sb->em->gbuf + 4 * i;
        int object = (int)fabsf(g[3]) - 1, k;
        const refl_material *m;
        float rgb[3], sub[3], w;
        refl_vec3 d, q, n, shown = refl_v3(NAN, NAN, NAN), t;
        refl__sb_path pa;
        if (g[3] == 0.0f || object < 0 || object >= scene->object_count) continue;
        if (sb->group_of[i] && !(sb->drawn.depth[i] < 1.0f)) src = refl__sb_crack_source(sb, x, y);
        refl__sb_pixel_view(sb, i, &d, &q, &n);
        if (sb->tracer.rt && refl__sb_refraction_traced(sb, i, d, q, n, g[3])) {
            refl__sb_render_pixel(sb, x, y);
            continue;
        }
        if (refl__sb_checked(sb, i) && refl__sb_fallback(sb, i, src, (int)(sb->drawn.depth[src] * (float)sb->orders) == 0) &&
            refl__sb_trace_pixel(sb, x, y))
            continue;
        m = &scene->materials[scene->objects[object].material];
        refl__sb_trace_path(sb, q, n, d, g[3], &pa);
        if (refl__sb_hole(sb, i, src) && sb->tracer.rt && refl__sb_hole_goes_on(sb, &pa)) {
            refl__sb_render_pixel(sb, x, y);
            continue;
        }
        if (!refl__sb_hole(sb, i, src)) {
            const float *pt = sb->drawn.points + 4 * src;
            k = REFL__CLAMP((int)(sb->drawn.depth[src] * (float)sb->orders), 0, pa.count - 1);
            if (refl__sb_goes_past(sb, src)) {
                refl__sb_render_pixel(sb, x, y);
                continue;
            }
            for (c = 0; c < 3; ++c) sub[c] = sb->drawn.color[4 * src + (size_t)c];
            shown = refl_v3(pt[0], pt[1], pt[2]);
        } else {
            k = pa.count - 1;
            refl_environment_lookup(&scene->environment, pa.out, sub);
            for (c = 0; c < 3; ++c) sub[c] = REFL__CLAMP(sub[c], 0.0f, 1.0f);
        }
        /* order k's bounce fades by the distance to what it shows (none: wholly) */
        w = pa.weight[k] * refl_material_fade(refl__sb_material(sb, pa.id[k]),
                                              shown.x == shown.x ? refl_v3_length(refl_v3_sub(shown, pa.q[k])) : INFINITY);
        if (!last && pa.count > 1 && (k > 0 || !(shown.x == shown.x))) shown = pa.q[1];
        for (c = 0; c < 3; ++c) rgb[c] = w * sub[c];
        if (m->type == REFL_GLASS) {
            float ior = m->ior > 0.0f ? m->ior : 1.5f, tsub[3], f = pa.weight[0], tw = 1.0f;
            int tinted = m->tint[0] + m->tint[1] + m->tint[2] > 0.0f;
            refl_vec3 tshown = refl_v3(NAN, NAN, NAN);
            if (refl_v3_refract(d, n, 1.0f / ior, &t)) {
                refl__sb_refr rp;
                int through = sb->layers > sb->orders ? refl__sb_refract_path(sb, q, n, d, g[3], &rp) : -1;
                if (through < 0) { /* no refraction sampled, or off the glass: refracted once, as ENVMAP */
                    refl_environment_lookup(&scene->environment, t, tsub);
                } else if (!through) {
                    tsub[0] = tsub[1] = tsub[2] = 0.0f; /* still inside when the bounces run out */
                } else if (sb->group_of[(size_t)sb->orders * npx + i] && sb->refr.depth[i] < 1.0f) {
                    const float *pt = sb->refr.points + 4 * i;
                    for (c = 0; c < 3; ++c) tsub[c] = sb->refr.color[4 * i + (size_t)c];
                    if (through == 1) tshown = refl_v3(pt[0], pt[1], pt[2]); /* inside glass: none, as RAYTRACE */
                    tw = rp.weight;
                } else {
                    refl_environment_lookup(&scene->environment, rp.out, tsub);
                    tw = rp.weight;
                }
                for (c = 0; c < 3; ++c)
                    rgb[c] += (1.0f - f) * (tinted ? m->tint[c] : 1.0f) * tw * REFL__CLAMP(tsub[c], 0.0f, 1.0f);
                if (f < 0.5f) shown = tshown;
            } else {
                for (c = 0; c < 3; ++c) rgb[c] = sub[c]; /* total internal reflection */
            }
        }
        refl__em_put(fr, i, rgb, shown);
    }
}

/* The composite, a job per row; with desc.sbc.trace_fallback, or where a
   group's rays fold (refl__sb_checked), RAYTRACE's tracer for the pixels
   it traces, begun and ended here. */
static refl_result refl__sb_resolve(refl__sb *sb) {
    refl__pass *p = sb->p;
    refl_frame *fr = p->frame;
    const refl_allocator *al = &p->scene->allocator;
    refl_result r = REFL_OK;
    int i, traces;
    size_t k, npx = (size_t)fr->width * (size_t)fr->height;
    /* a refraction layer's holes are traced (refl__sb_refraction_traced) */
    traces = sb->layers > sb->orders;
    for (i = 0; i < sb->group_count; ++i) traces |= sb->groups[i].sheets > 1;
    for (k = 0; k < npx && !traces; ++k)
        traces |= refl__sb_goes_past(sb, k) || (sb->layers > 1 && sb->group_of[k] && !(sb->drawn.depth[k] < 1.0f));
    sb->tracer.folds_only = !p->desc.sbc.trace_fallback;
    if (p->desc.sbc.trace_fallback || (traces && sb->bvh)) {
        sb->tracer.rt = (refl__rt *)refl__calloc(al, 1, sizeof(refl__rt));
        sb->tracer.rays = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
        sb->tracer.pixels = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
        if (!sb->tracer.rt || !sb->tracer.rays || !sb->tracer.pixels) r = REFL_ERROR_OUT_OF_MEMORY;
        if (r == REFL_OK) r = refl__rt_begin(sb->tracer.rt, p, sb->bvh);
    }
    if (r == REFL_OK)
        rast_run_jobs(p->rc, fr->height, sb->layers > 1 ? refl__sb_resolve_row_deep : refl__sb_resolve_row, sb);
    for (i = 0; sb->tracer.rays && i < fr->height; ++i) fr->stats.rays += sb->tracer.rays[i];
    for (i = 0; sb->tracer.pixels && i < fr->height; ++i) fr->stats.sbc.traced += sb->tracer.pixels[i];
    if (sb->tracer.rt) refl__rt_end(sb->tracer.rt);
    refl__free(al, sb->tracer.rt);
    refl__free(al, sb->tracer.rays);
    refl__free(al, sb->tracer.pixels);
    memset(&sb->tracer, 0, sizeof sb->tracer);
    return r;
}
