/* LAYERED_EM: Hakura and Snyder's hybrid rendering (paper 001) with one
   environment layer. Per lens object (a reflector of this pass):

   1. the viewpoint samples: points on a circle around the lens's centre
      through the eye, at its height, `samples` of them evenly; the two
      bracketing the eye's azimuth are used, blended by angular distance;
   2. each sample's map (per scene and sample, not per frame: a renderer
      keeps them in its models, keyed by the object, the sample's view, the
      options and the depth; refl_renderer_prebuild infers them all):
      a. the records (section 4.1: greedy paths of every lens pixel, the
         radiance where their exit rays meet the scene) give the targets;
         the shell's radius is the mean distance of those hits from the
         centre (LBG with one cluster);
      b. the lens is tessellated (lens_tess.c) and drawn with rast.h at
         the sample's views, interpolating each vertex's shell index (exit
         ray's hit on the shell minus the centre) as the runtime does: each
         pixel's lookup of that index is its row of the rendering matrix,
         so the matrix is exactly how the runtime samples the map;
         C A x = C b is solved by CGLS (lem_infer.c);
   3. the frame: the lens tessellated for the eye (its vertex paths cast
      at a BVH of the lens objects alone, refl__lem_split), drawn once
      per map with per-vertex F G and that map's shell indices of both
      terms, each fragment the map's weight times T F_T G_T + R F_R G_R,
      the draws added over the base pass where the lens shows; lens
      pixels no triangle covered are ray traced.

   Every stage runs in a fixed order or per pixel, and a map depends only on
   what keys it, so any thread count, and a kept map or a fresh one, gives
   the same bytes. Left out (see the issue): several layers by LBG, quads,
   continued rays, direct images. */
#include "internal.h"

/* One draw is one term: per layer its shell index (3; a partial layer's,
   a quad or an inner sphere (refl_lem_shell_partial), (0, 0, 0) where the
   exit ray misses it, so that a quad's third component, or an inner
   sphere's length over its radius, interpolates to the share of the
   layer present), then shading F G (3) and 1 at a vertex whose term has
   an exit ray a closed shell cannot look up, or recording the term's
   presence and the recorded layer's: 3 layers + 4 varyings (16 at
   REFL_LEM_MAX_LAYERS, rast.h's most). */
static int refl__lem_varyings(int layers) { return 3 * layers + 4; }

static int refl__lem_bvh_intersect(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax, refl_hit *hit) {
    return refl_bvh_intersect((const refl_bvh *)user, o, d, tmin, tmax, hit);
}

static int refl__lem_bvh_occluded(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    return refl_bvh_occluded((const refl_bvh *)user, o, d, tmin, tmax);
}

static const char *refl__options_layered_em(refl_render_desc *d) {
    const refl_layered_em_options *o = &d->layered_em;
    if (o->samples < 0 || o->samples > 3600) return "layered_em.samples: 0 (45) to 3600";
    if (o->face_size < 0 || o->face_size > 1024) return "layered_em.face_size: 0 (from the lens's size) to 1024";
    if (o->supersample < 0 || o->supersample > 8) return "layered_em.supersample: 0 (1) to 8";
    if (!(o->edge_px >= 0.0f) || !refl__isfinite(o->edge_px)) return "layered_em.edge_px: finite, 0 or more";
    if (!(o->angle_degrees >= 0.0f && o->angle_degrees <= 180.0f)) return "layered_em.angle_degrees: 0 (3) to 180";
    if (!(o->theta_c_degrees >= 0.0f && o->theta_c_degrees <= 180.0f))
        return "layered_em.theta_c_degrees: 0 (5) to 180";
    if (o->iterations < 0 || o->iterations > 100000) return "layered_em.iterations: 0 (200) to 100000";
    if (o->single_view < 0 || o->single_view > 1) return "layered_em.single_view: 0 or 1";
    if (o->layers < 0 || o->layers > REFL_LEM_MAX_LAYERS) return "layered_em.layers: 0 (1) to 4";
    if (o->shell < REFL_LEM_SHELL_AUTO || o->shell > REFL_LEM_SHELL_QUAD)
        return "layered_em.shell: AUTO, SPHERE, CYLINDER, BOX or QUAD";
    if (o->shell_frame < REFL_LEM_FRAME_AUTO || o->shell_frame > REFL_LEM_FRAME_FITTED)
        return "layered_em.shell_frame: AUTO, WORLD or FITTED";
    if (o->direct_images < -1 || o->direct_images > 1) return "layered_em.direct_images: -1 (off), 0 or 1 (on)";
    if (o->lens_layers < -1 || o->lens_layers > 1) return "layered_em.lens_layers: -1 (traced), 0 or 1 (layers)";
    if (o->continue_incoming < -1 || o->continue_incoming > 1)
        return "layered_em.continue_incoming: -1 (off), 0 or 1 (on)";
    if (o->direct_from < 0 || o->direct_from > REFL_LEM_DIRECT_FROM_MATERIAL)
        return "layered_em.direct_from: 0 (default), CENTRE, VIEWPOINT or MATERIAL";
    if (o->direct_confidence < 0 || o->direct_confidence > REFL_LEM_DIRECT_DISTANCE)
        return "layered_em.direct_confidence: 0 (default), COVERAGE or DISTANCE";
    if (o->keep_stale_maps < 0 || o->keep_stale_maps > 1) return "layered_em.keep_stale_maps: 0 or 1";
    if (o->kept_mib < 0 || o->kept_mib > (1 << 20)) return "layered_em.kept_mib: 0 (512) to 1048576";
    if (o->share_outer_layer < -1 || o->share_outer_layer > 1)
        return "layered_em.share_outer_layer: -1 (off), 0 or 1 (on)";
    if (o->share_outer_layer > 0 || (o->share_outer_layer == 0 && REFL_LEM_SHARE_DEFAULT > 0)) {
        /* a lens that is a layer of another lies inside the shared shell, not on it */
        if (o->lens_layers > 0 || (o->lens_layers == 0 && REFL_LEM_LENS_LAYERS_DEFAULT > 0))
            return "layered_em.share_outer_layer: not with lens_layers on";
        /* its hits are each lens's and gone by the time the shared layer is solved */
        if ((o->direct_confidence ? o->direct_confidence : REFL_LEM_DIRECT_CONFIDENCE_DEFAULT) ==
            REFL_LEM_DIRECT_DISTANCE)
            return "layered_em.share_outer_layer: not with direct_confidence DISTANCE";
    }
    return NULL;
}

/* The lens whose paths end where they leave it (lens_layers on: i, the
   other lenses layers of its environment), else -1. */
static int refl__lem_own(const refl__pass *p, int i) {
    int on = p->desc.layered_em.lens_layers;
    return on > 0 || (on == 0 && REFL_LEM_LENS_LAYERS_DEFAULT > 0) ? i : -1;
}

/* Whether the samples' eye rays are continued to the lens through what
   hides it (refl_layered_em_options.continue_incoming). */
static int refl__lem_continued(const refl__pass *p) {
    int on = p->desc.layered_em.continue_incoming;
    return on > 0 || (on == 0 && REFL_LEM_CONTINUE_DEFAULT > 0);
}

/* Whether the pass's lenses share their outermost layer
   (refl_layered_em_options.share_outer_layer): asked, and two lenses or
   more to share it. */
static int refl__lem_share(const refl__pass *p) {
    int on = p->desc.layered_em.share_outer_layer, i, lenses = 0;
    if (!(on > 0 || (on == 0 && REFL_LEM_SHARE_DEFAULT > 0))) return 0;
    for (i = 0; i < p->scene->object_count && lenses < 2; ++i) lenses += refl__pass_draws(p, i);
    return lenses > 1;
}

/* The casters of lens i's vertex paths (refl__lem_own). */
static refl__gp_casters refl__lem_vertex_casters(const refl__pass *p, const refl__gp_casters *c, int i) {
    refl__gp_casters own = *c;
    own.own = refl__lem_own(p, i);
    return own;
}

/* What one draw of the lens shares: the layers' shells, the maps it looks
   up and the blend weight, the term drawn, and in record mode the layer
   whose index it writes. */
typedef struct refl__lem_draw {
    int layers;
    refl_lem_shell shell[REFL_LEM_MAX_LAYERS];
    int partial[REFL_LEM_MAX_LAYERS]; /* refl_lem_shell_partial, set by refl__lem_raster */
    const float *map[REFL_LEM_MAX_LAYERS];
    float weight;
    int term;                    /* 0 reflection, 1 refraction */
    int record_layer;            /* -1: shade; else write that layer's index and the presence */
    int points;                  /* shading's vertices, refl__lem_point_fragment's output */
    long long quad_misses;       /* out: vertices whose exit ray missed a quad layer */
    refl_vec3 lens_box[2];       /* the lens's bounds, a little wider: an exit ray from
                                    outside them left through another lens */
} refl__lem_draw;

/* dr's lens box: object i's bounds box[2], widened by a thousandth of
   their diagonal. */
static void refl__lem_draw_box(refl__lem_draw *dr, const refl_vec3 box[2]) {
    float pad = 1e-3f * refl_v3_length(refl_v3_sub(box[1], box[0])) + 1e-6f;
    dr->lens_box[0] = refl_v3_sub(box[0], refl_v3(pad, pad, pad));
    dr->lens_box[1] = refl_v3_add(box[1], refl_v3(pad, pad, pad));
}

/* The share of partial layer l present at interpolated index t (a quad's
   third component, an inner sphere's length over its radius); 1 on a
   closed shell. */
static float refl__lem_present(const refl__lem_draw *dr, int l, const float *t) {
    if (!dr->partial[l]) return 1.0f;
    if (dr->shell[l].kind == REFL_LEM_SHELL_QUAD) return REFL__CLAMP(t[2], 0.0f, 1.0f);
    return REFL__CLAMP(sqrtf(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]) / dr->shell[l].radius, 0.0f, 1.0f);
}

/* Layer l's bilinear RGBA at a shell index. */
static void refl__lem_sample(const refl__lem_draw *dr, int l, refl_vec3 index, float rgba[4]) {
    uint32_t tex[4];
    float w[4];
    int k, c;
    rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0.0f;
    if (!refl_lem_shell_texels(&dr->shell[l], index, tex, w)) return;
    for (k = 0; k < 4; ++k)
        for (c = 0; c < 4; ++c) rgba[c] += w[k] * dr->map[l][4 * tex[k] + (uint32_t)c];
}

/* The term's colour: the layers composited front to back, L1 over L2 over
   ... (the outermost opaque), times F G, times the map's weight. Alpha 1,
   or 2 where a vertex had no lookup (the pixel goes to the tracer). */
static int refl__lem_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__lem_draw *dr = (const refl__lem_draw *)user;
    const float *v = in->varyings, *fg = v + 3 * dr->layers;
    float through = 1.0f, layer[4];
    int l, c;
    if (dr->record_layer >= 0) {
        const float *t = v + 3 * dr->record_layer;
        rgba[0] = t[0];
        rgba[1] = t[1];
        rgba[2] = t[2];
        rgba[3] = fg[0] * fg[1]; /* the term's lookup, times the share of the layer met */
        return 1;
    }
    rgba[0] = rgba[1] = rgba[2] = 0.0f;
    rgba[3] = fg[3] > 0.0f ? 2.0f : 1.0f;
    if (!(fg[0] > 0.0f || fg[1] > 0.0f || fg[2] > 0.0f)) return 1;
    for (l = 0; l < dr->layers && through > 0.0f; ++l) {
        const float *t = v + 3 * l;
        float a, present = refl__lem_present(dr, l, t);
        if (!(present > 0.0f)) continue; /* a partial layer the exit rays miss here */
        refl__lem_sample(dr, l, refl_v3(t[0], t[1], t[2]), layer);
        for (c = 0; c < 4; ++c) layer[c] *= present;
        a = l == dr->layers - 1 ? 1.0f : REFL__CLAMP(layer[3], 0.0f, 1.0f);
        for (c = 0; c < 3; ++c) rgba[c] += through * layer[c]; /* premultiplied */
        through *= 1.0f - a;
    }
    for (c = 0; c < 3; ++c) rgba[c] *= REFL__MAX(fg[c], 0.0f) * dr->weight;
    return 1;
}

/* The point the term shows, with its strength: the point on the shell
   of the layer that gives most of the composite (front to back, as
   refl__lem_fragment), and the sum of the interpolated F G; strength 0
   where the term has no lookup. */
static int refl__lem_point_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__lem_draw *dr = (const refl__lem_draw *)user;
    const float *v = in->varyings, *fg = v + 3 * dr->layers, *t;
    float through = 1.0f, layer[4], most = 0.0f, strength = fg[0] + fg[1] + fg[2];
    int l, shown = -1;
    refl_vec3 at;
    rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0.0f;
    if (fg[3] > 0.0f || !(strength > 0.0f)) return 1;
    for (l = 0; l < dr->layers && through > 0.0f; ++l) {
        float a, present;
        t = v + 3 * l;
        present = refl__lem_present(dr, l, t);
        if (!(present > 0.0f)) continue;
        refl__lem_sample(dr, l, refl_v3(t[0], t[1], t[2]), layer);
        a = l == dr->layers - 1 ? 1.0f : REFL__CLAMP(present * layer[3], 0.0f, 1.0f);
        if (through * a > most) most = through * a, shown = l;
        through *= 1.0f - a;
    }
    t = v + 3 * (shown >= 0 ? shown : 0);
    if (shown < 0 || !refl__lem_shell_point(&dr->shell[shown], refl_v3(t[0], t[1], t[2]), &at)) return 1;
    rgba[0] = at.x;
    rgba[1] = at.y;
    rgba[2] = at.z;
    rgba[3] = strength;
    return 1;
}

/* Draws tessellation t seen through vp into the w x h RGBA32F colour and
   depth buffers (cleared here), with stencil (may be NULL) tested equal
   to ref. */
static refl_result refl__lem_raster(rast_context *rc, const refl_lens_tess *t, refl_mat4 vp, refl__lem_draw *dr,
                                    float *color, float *depth, uint8_t *stencil, uint8_t ref, int w, int h,
                                    const refl_allocator *al) {
    const int nv = refl__lem_varyings(dr->layers), stride = 4 + nv;
    float *verts = (float *)refl__calloc(al, (size_t)REFL__MAX(t->vertex_count, 1) * (size_t)stride, sizeof(float));
    rast_targets tg;
    rast_state s;
    rast_draw_desc d;
    rast_clear_desc clear;
    rast_result rr;
    const float *m = vp.m;
    int i, k, l;
    if (!verts) return REFL_ERROR_OUT_OF_MEMORY;
    for (l = 0; l < dr->layers; ++l) dr->partial[l] = refl_lem_shell_partial(&dr->shell[l], dr->lens_box);
    for (i = 0; i < t->vertex_count; ++i) {
        const refl_lens_vertex *v = &t->vertices[i];
        const refl_greedy_path *path = dr->term ? &v->paths.refract : &v->paths.reflect;
        float *o = verts + (size_t)i * (size_t)stride, *fg = o + 4 + 3 * dr->layers;
        refl_vec3 p = v->position;
        refl_vec3 eo = path->exit_origin;
        int exits = path->fresnel > 0.0f && path->exited;
        int has = exits && eo.x >= dr->lens_box[0].x && eo.y >= dr->lens_box[0].y && eo.z >= dr->lens_box[0].z &&
                  eo.x <= dr->lens_box[1].x && eo.y <= dr->lens_box[1].y && eo.z <= dr->lens_box[1].z;
        float met = 1.0f;        /* whether the exit ray meets the recorded layer's shell */
        for (k = 0; k < 4; ++k) o[k] = m[k] * p.x + m[4 + k] * p.y + m[8 + k] * p.z + m[12 + k];
        for (l = 0; l < dr->layers; ++l) {
            /* a closed shell without a lookup: the path left the lens through
               another lens object beyond the shell, where the map knows
               nothing of what the ray meets (the pixels go to the tracer); a
               partial layer missed: the layer is left out at this vertex */
            int quad = dr->shell[l].kind == REFL_LEM_SHELL_QUAD;
            refl_vec3 index = refl_v3(0.0f, 0.0f, quad ? 0.0f : 1.0f);
            int got = has && refl_lem_shell_index(&dr->shell[l], path->exit_origin, path->exit_direction, &index);
            if (quad) dr->quad_misses += has && !got;
            if (!dr->partial[l]) has = has && got;
            if (dr->partial[l] && !got) index = refl_v3(0.0f, 0.0f, 0.0f);
            if (l == dr->record_layer && dr->partial[l]) met = (float)got;
            o[4 + 3 * l] = index.x;
            o[4 + 3 * l + 1] = index.y;
            o[4 + 3 * l + 2] = index.z;
        }
        if (dr->record_layer >= 0) {
            fg[0] = (float)has;
            fg[1] = met;
        } else {
            for (k = 0; k < 3; ++k) fg[k] = has ? path->fresnel * path->attenuation[k] : 0.0f;
            fg[3] = (float)(exits && !has);
        }
    }
    tg = refl__float_targets(color, depth, stencil, w, h);
    memset(&s, 0, sizeof s);
    memset(&clear, 0, sizeof clear);
    clear.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH;
    clear.depth = 1.0f;
    rr = rast_set_targets(rc, &tg);
    if (rr == RAST_OK) rr = rast_set_state(rc, &s);
    if (rr == RAST_OK) rr = rast_clear(rc, &clear);
    s.depth_test = 1;
    s.fragment_fn = dr->points ? refl__lem_point_fragment : refl__lem_fragment;
    s.fragment_user = dr;
    if (stencil) {
        s.stencil_test = 1;
        s.stencil_front.func = s.stencil_back.func = RAST_EQUAL;
        s.stencil_front.ref = s.stencil_back.ref = ref;
    }
    memset(&d, 0, sizeof d);
    d.primitive = RAST_TRIANGLES;
    d.vertices = verts;
    d.vertex_count = t->vertex_count;
    d.stride = stride;
    d.num_varyings = nv;
    d.indices = t->indices;
    d.index_count = 3 * t->triangle_count;
    if (rr == RAST_OK) rr = rast_set_state(rc, &s);
    if (rr == RAST_OK && t->triangle_count > 0) rr = rast_draw(rc, &d);
    if (rr == RAST_OK) rr = rast_finish(rc);
    refl__free(al, verts);
    return refl__result_from_rast(rr);
}

/* ---- records of a sample, on the pass's threads --------------------------------- */

typedef struct refl__lem_records {
    const refl_scene *scene;
    const refl_ray_caster *caster;
    refl__view_rays rays;
    int object, ss, max_interfaces;
    float theta_c;
    const refl__lem_layering *lay;
    int rect[4];                 /* x0, y0, x1, y1: the pixels the lens's bounds may cover */
    float *rec;                  /* 10 layers per pixel; confidence -1 where none */
    float *points;               /* NULL, or 6 layers per pixel: refl__lem_pixel_records' points */
    long long *row_rays;
    int *row_continued;          /* per row, the pixels whose eye ray was continued to the lens */
} refl__lem_records;

/* Whether a pixel's records (10 floats a layer, refl__lem_pixel_records)
   hold a term of the innermost layer: a lens pixel. */
static int refl__lem_has_record(const float *rec, int layers) { return rec[4] >= 0.0f || rec[5 * layers + 4] >= 0.0f; }

static void refl__lem_records_row(void *arg, int y) {
    refl__lem_records *r = (refl__lem_records *)arg;
    int x, w = r->rays.width, n = 10 * r->lay->layers, k;
    for (x = 0; x < w; ++x) {
        float *out = r->rec + (size_t)n * ((size_t)y * (size_t)w + (size_t)x);
        float *pts = r->points ? r->points + (size_t)6 * r->lay->layers * ((size_t)y * (size_t)w + (size_t)x) : NULL;
        refl_greedy_paths_result centre;
        int met = x >= r->rect[0] && x < r->rect[2] && y >= r->rect[1] && y < r->rect[3]
                      ? refl__lem_pixel_records(r->scene, r->caster, &r->rays, x, y, r->object, r->ss, r->theta_c,
                                                r->max_interfaces, r->lay, out, pts, &centre, &r->row_rays[y])
                      : 0;
        if (!met) {
            for (k = 4; k < n; k += 5) out[k] = -1.0f;
            for (k = 0; pts && k < 6 * r->lay->layers; ++k) pts[k] = NAN;
        }
        /* counted as the lens pixels are (refl__lem_record_views), so that
           the continued ones aside never leave fewer than none */
        r->row_continued[y] += met == 2 && refl__lem_has_record(out, r->lay->layers);
    }
}

/* The pixel rectangle [x0, x1) x [y0, y1) of view vp (w x h) that the box
   of corners lo, hi may cover: its corners' projections and a pixel more;
   the whole view when a corner lies behind the eye. */
static void refl__lem_screen_rect(refl_mat4 vp, refl_vec3 lo, refl_vec3 hi, int w, int h, int rect[4]) {
    const float *m = vp.m;
    float x0 = FLT_MAX, y0 = FLT_MAX, x1 = -FLT_MAX, y1 = -FLT_MAX;
    int k, c;
    for (k = 0; k < 8; ++k) {
        refl_vec3 p = refl_v3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z);
        float clip[4], sx, sy;
        for (c = 0; c < 4; ++c) clip[c] = m[c] * p.x + m[4 + c] * p.y + m[8 + c] * p.z + m[12 + c];
        if (!(clip[3] > 1e-6f)) {
            rect[0] = rect[1] = 0;
            rect[2] = w;
            rect[3] = h;
            return;
        }
        sx = (clip[0] / clip[3] * 0.5f + 0.5f) * (float)w;
        sy = (0.5f - clip[1] / clip[3] * 0.5f) * (float)h;
        x0 = REFL__MIN(x0, sx), x1 = REFL__MAX(x1, sx), y0 = REFL__MIN(y0, sy), y1 = REFL__MAX(y1, sy);
    }
    rect[0] = (int)REFL__CLAMP(floorf(x0) - 1.0f, 0.0f, (float)w);
    rect[1] = (int)REFL__CLAMP(floorf(y0) - 1.0f, 0.0f, (float)h);
    rect[2] = (int)REFL__CLAMP(ceilf(x1) + 1.0f, 0.0f, (float)w);
    rect[3] = (int)REFL__CLAMP(ceilf(y1) + 1.0f, 0.0f, (float)h);
}

/* One view whose records a map is inferred from. */
typedef struct refl__lem_sample_view {
    refl_mat4 vp;
    refl_lens_tess tess;
    float *rec, *points;         /* points: for the direct images' distance confidence */
    int lens_pixels;
} refl__lem_sample_view;

static void refl__lem_sample_free(const refl_allocator *al, refl__lem_sample_view *s) {
    refl__free(al, s->tess.vertices);
    refl__free(al, s->tess.indices);
    refl__free(al, s->rec);
    refl__free(al, s->points);
    memset(s, 0, sizeof *s);
}

/* The world bounds' centre and half diagonal of object i: the box of the
   vertices its triangles use (the paper's lens centre: the concave
   scene's bowl's, at its focus, not that of the sphere its mesh keeps). */
static void refl__lem_bounds(const refl_scene *scene, int i, refl_vec3 *centre, float *radius, refl_vec3 box[2]) {
    const refl_object *o = &scene->objects[i];
    refl_vec3 lo, hi, wlo = refl_v3(FLT_MAX, FLT_MAX, FLT_MAX), whi = refl_v3(-FLT_MAX, -FLT_MAX, -FLT_MAX);
    int k;
    refl__mesh_used_bounds(scene->meshes[o->mesh], &lo, &hi);
    for (k = 0; k < 8; ++k) {
        refl_vec3 c = refl_mat4_point(o->transform, refl_v3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z));
        wlo = refl_v3(REFL__MIN(wlo.x, c.x), REFL__MIN(wlo.y, c.y), REFL__MIN(wlo.z, c.z));
        whi = refl_v3(REFL__MAX(whi.x, c.x), REFL__MAX(whi.y, c.y), REFL__MAX(whi.z, c.z));
    }
    box[0] = wlo;
    box[1] = whi;
    *centre = refl_v3_scale(refl_v3_add(wlo, whi), 0.5f);
    *radius = 0.5f * refl_v3_length(refl_v3_sub(whi, wlo));
}

/* The box of every lens object pass p draws (refl__lem_bounds of each):
   its centre and half diagonal, and the box (may be NULL). */
static void refl__lem_joint_bounds(const refl__pass *p, refl_vec3 *centre, float *radius, refl_vec3 *joint_box) {
    refl_vec3 lo = refl_v3(FLT_MAX, FLT_MAX, FLT_MAX), hi = refl_v3(-FLT_MAX, -FLT_MAX, -FLT_MAX), c, box[2];
    float r;
    int i;
    for (i = 0; i < p->scene->object_count; ++i) {
        if (!refl__pass_draws(p, i)) continue;
        refl__lem_bounds(p->scene, i, &c, &r, box);
        lo = refl_v3(REFL__MIN(lo.x, box[0].x), REFL__MIN(lo.y, box[0].y), REFL__MIN(lo.z, box[0].z));
        hi = refl_v3(REFL__MAX(hi.x, box[1].x), REFL__MAX(hi.y, box[1].y), REFL__MAX(hi.z, box[1].z));
    }
    *centre = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    *radius = 0.5f * refl_v3_length(refl_v3_sub(hi, lo));
    if (joint_box) joint_box[0] = lo, joint_box[1] = hi;
}

/* ---- the maps a renderer keeps ---------------------------------------------------- */

/* One viewpoint sample's inferred maps (one per layer) and what shaped
   them: the lens object, the sample's view, the options and the bounces
   (the layers' shells come from the lens's ring). They depend on nothing
   else (the scene's version aside, which drops them all), so a frame that
   needs them again takes them as they are. With a shared outer layer
   (refl__lem_share) a lens's outermost texels are NULL: they are those of
   the sample's shared map, object -1, one layer. */
typedef struct refl__lem_map {
    int object, depth;
    refl_view view;
    refl_layered_em_options options;
    int layers;
    refl_lem_shell shell[REFL_LEM_MAX_LAYERS];
    float *texels[REFL_LEM_MAX_LAYERS]; /* 4 floats per texel of each shell */
} refl__lem_map;

/* A lens's circle of viewpoint samples as a renderer fixed it, and the
   layers clustered over every sample on it. */
typedef struct refl__lem_ring {
    int object;
    float rho, height;
    refl__lem_layering lay;
    signed char *object_layer;   /* lay's, owned */
    int joint;                   /* the circle is around every lens (refl__lem_share) */
    int joint_fitted;            /* joint_shell set: the shared layer's (refl__lem_joint_shell) */
    refl_lem_shell joint_shell;
} refl__lem_ring;

struct refl__lem_maps {
    refl__lem_map *maps;
    int count;
    refl__lem_ring *rings;       /* a renderer's: the circle of each lens, from its first frame */
    int ring_count;
};

static void refl__lem_map_free(const refl_allocator *al, refl__lem_map *m) {
    int l;
    for (l = 0; l < REFL_LEM_MAX_LAYERS; ++l) refl__free(al, m->texels[l]), m->texels[l] = NULL;
}

/* Frees what m holds (not m). */
static void refl__lem_maps_clear(const refl_allocator *al, struct refl__lem_maps *m) {
    int k;
    for (k = 0; k < m->count; ++k) refl__lem_map_free(al, &m->maps[k]);
    for (k = 0; k < m->ring_count; ++k) refl__free(al, m->rings[k].object_layer);
    refl__free(al, m->maps);
    refl__free(al, m->rings);
    memset(m, 0, sizeof *m);
}

static void refl__lem_maps_free(const refl_allocator *al, struct refl__lem_maps *m) {
    if (!m) return;
    refl__lem_maps_clear(al, m);
    refl__free(al, m);
}

/* RGBA floats on six faces, per layer. */
static long long refl__lem_map_bytes(const refl__lem_map *m) {
    long long b = 0;
    int l;
    for (l = 0; l < m->layers; ++l)
        if (m->texels[l]) b += 96LL * m->shell[l].face_size * m->shell[l].face_size;
    return b;
}

static long long refl__lem_maps_bytes(const struct refl__lem_maps *m) {
    long long b = 0;
    int k;
    for (k = 0; m && k < m->count; ++k) b += refl__lem_map_bytes(&m->maps[k]);
    return b;
}

/* What a renderer keeps of maps at the start of a frame
   (layered_em.kept_mib): the oldest go first past this (a dolly or a crane
   makes new samples every frame; a dropped map is inferred again, the same
   bytes, when a frame needs it). */
static long long refl__lem_kept_bytes(const refl_layered_em_options *o) {
    return (long long)(o->kept_mib > 0 ? o->kept_mib : 512) << 20;
}

static void refl__lem_trim(const refl_allocator *al, struct refl__lem_maps *m, long long kept) {
    int drop = 0, k;
    long long bytes = refl__lem_maps_bytes(m);
    while (drop < m->count && bytes > kept) {
        bytes -= refl__lem_map_bytes(&m->maps[drop]);
        refl__lem_map_free(al, &m->maps[drop++]);
    }
    for (k = drop; k < m->count; ++k) m->maps[k - drop] = m->maps[k];
    m->count -= drop;
}

static int refl__lem_same_view(const refl_view *a, const refl_view *b) {
    return a->eye.x == b->eye.x && a->eye.y == b->eye.y && a->eye.z == b->eye.z && a->target.x == b->target.x &&
           a->target.y == b->target.y && a->target.z == b->target.z && a->up.x == b->up.x && a->up.y == b->up.y &&
           a->up.z == b->up.z && a->fovy_degrees == b->fovy_degrees && a->width == b->width &&
           a->height == b->height && a->znear == b->znear && a->zfar == b->zfar;
}

/* The map of object i at sample view v under pass p's options in m, or -1. */
static int refl__lem_find(const struct refl__lem_maps *m, const refl__pass *p, int i, const refl_view *v) {
    int k;
    for (k = 0; m && k < m->count; ++k) {
        const refl__lem_map *e = &m->maps[k];
        if (e->object == i && e->depth == p->desc.depth && refl__lem_same_view(&e->view, v) &&
            !memcmp(&e->options, &p->desc.layered_em, sizeof e->options))
            return k;
    }
    return -1;
}

/* ---- inferring one sample's maps ---------------------------------------------------- */

/* How lens i's direct images are taken (refl_layered_em_options'
   direct_from and direct_confidence), from the sample's views[0 .. per)
   where from the viewpoint (stride 1 and the rectangles set later). */
static void refl__lem_direct_how(const refl__pass *p, int i, const refl_view *views, int per, refl__lem_direct *out) {
    const refl_layered_em_options *o = &p->desc.layered_em;
    int from = o->direct_from ? o->direct_from : REFL_LEM_DIRECT_FROM_DEFAULT;
    int conf = o->direct_confidence ? o->direct_confidence : REFL_LEM_DIRECT_CONFIDENCE_DEFAULT;
    int glass = p->scene->materials[p->scene->objects[i].material].type == REFL_GLASS;
    memset(out, 0, sizeof *out);
    out->viewpoint = from == REFL_LEM_DIRECT_FROM_VIEWPOINT || (from == REFL_LEM_DIRECT_FROM_MATERIAL && glass);
    out->distance = conf == REFL_LEM_DIRECT_DISTANCE;
    out->views = views;
    out->per = per;
    out->stride = 1;
}

/* A shared outer layer's rows as the lenses' records give them
   (refl__lem_infer): kept as shell indices, since the shared map's face
   size is the largest the lenses ask for, known once every lens is
   recorded; and how the last lens recorded takes its direct images. */
typedef struct refl__lem_joint {
    refl_lem_shell shell;        /* the shared shell; face_size the largest asked so far */
    float *rows;                 /* 8 per row: the index (3), the target (4), its confidence */
    long long count, cap;
    refl__lem_direct direct;     /* the last lens's (refl__lem_infer sets it) */
    int direct_on;
} refl__lem_joint;

static refl_result refl__lem_joint_row(const refl_allocator *al, refl__lem_joint *jr, const float *index,
                                       const float *target) {
    float *row;
    if (jr->count == jr->cap) {
        long long cap = REFL__MAX(2 * jr->cap, 4096);
        float *grown = (float *)refl__calloc(al, 8 * (size_t)cap, sizeof(float));
        if (!grown) return REFL_ERROR_OUT_OF_MEMORY;
        if (jr->count) memcpy(grown, jr->rows, 8 * (size_t)jr->count * sizeof(float));
        refl__free(al, jr->rows);
        jr->rows = grown;
        jr->cap = cap;
    }
    row = jr->rows + 8 * (size_t)jr->count++;
    memcpy(row, index, 3 * sizeof(float));
    memcpy(row + 3, target, 5 * sizeof(float));
    return REFL_OK;
}

/* Whether layer l of `layers` is the one the pass's lenses share (jr):
   the outermost, looked up on jr's shell, its rows gathered into jr for
   refl__lem_joint_solve instead of solved with the lens's own layers. */
static int refl__lem_shared_layer(const refl__lem_joint *jr, int l, int layers) { return jr && l == layers - 1; }

/* One sample's inference (refl__lem_infer), as its stages hand it on. */
typedef struct refl__lem_inference {
    refl__pass *p;
    const refl__gp_casters *casters;
    int object;
    const refl_view *views;      /* the sample's, views[0 .. per) */
    int per, w, h;
    const refl__lem_layering *lay;
    refl__lem_joint *jr;         /* NULL: no shared layer */
    refl_vec3 box[2];            /* the lens's bounds */
    refl__lem_sample_view sv[3];
    refl__lem_draw dr;           /* the layers' shells as the lookups draw them */
    int face;
    refl_lem_system *sys[REFL_LEM_MAX_LAYERS]; /* NULL at the shared layer */
    refl__lem_direct direct;
    int direct_on;
} refl__lem_inference;

/* The records and tessellation of each view, the records in rows on the
   pass's threads. */
static refl_result refl__lem_record_views(refl__lem_inference *x) {
    refl__pass *p = x->p;
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    const refl_layered_em_options *o = &p->desc.layered_em;
    refl_stats *st = &p->frame->stats;
    refl__lem_sample_view *sv = x->sv;
    int w = x->w, h = x->h, L = x->lay->layers, s, y;
    size_t np = (size_t)w * (size_t)h, px, nrec = 10 * (size_t)L;
    refl_lens_tess_desc td;
    refl_result r = REFL_OK;
    memset(&td, 0, sizeof td);
    td.edge_px = o->edge_px;
    td.angle_degrees = o->angle_degrees;
    td.max_interfaces = p->desc.depth;
    for (s = 0; s < x->per && r == REFL_OK; ++s) {
        refl__lem_records rec;
        refl_mat4 vm, pm;
        refl_view_matrices(&x->views[s], scene, &vm, &pm);
        sv[s].vp = refl_mat4_mul(pm, vm);
        memset(&rec, 0, sizeof rec);
        rec.scene = scene;
        rec.caster = x->casters->scene;
        refl__view_rays_init(&rec.rays, &x->views[s], scene);
        rec.object = x->object;
        rec.ss = o->supersample > 0 ? o->supersample : 1;
        rec.theta_c = o->theta_c_degrees;
        rec.max_interfaces = p->desc.depth;
        rec.lay = x->lay;
        refl__lem_screen_rect(sv[s].vp, x->box[0], x->box[1], w, h, rec.rect);
        sv[s].rec = rec.rec = (float *)refl__calloc(al, nrec * np, sizeof(float));
        if (x->direct.distance)
            sv[s].points = rec.points = (float *)refl__calloc(al, 6 * (size_t)L * np, sizeof(float));
        rec.row_rays = (long long *)refl__calloc(al, (size_t)h, sizeof(long long));
        rec.row_continued = (int *)refl__calloc(al, (size_t)h, sizeof(int));
        if (!rec.rec || !rec.row_rays || !rec.row_continued || (x->direct.distance && !rec.points))
            r = REFL_ERROR_OUT_OF_MEMORY;
        if (r == REFL_OK) {
            rast_run_jobs(p->rc, h, refl__lem_records_row, &rec);
            for (y = 0; y < h; ++y) st->rays += rec.row_rays[y];
            for (px = 0; px < np; ++px)
                sv[s].lens_pixels += refl__lem_has_record(rec.rec + nrec * px, L);
            /* the face size follows the lens pixels the view sees: the
               continued ones aside, so continuing leaves it as it was */
            for (y = 0; y < h; ++y) sv[s].lens_pixels -= rec.row_continued[y];
            for (y = 0; y < h; ++y) st->layered_em.continued_pixels += rec.row_continued[y];
        }
        refl__free(al, rec.row_rays);
        refl__free(al, rec.row_continued);
        if (r == REFL_OK) {
            refl__gp_casters vc = refl__lem_vertex_casters(p, x->casters, x->object);
            sv[s].tess.allocator = *al;
            r = refl__lens_tessellate(scene, &vc, x->object, &x->views[s], &td, p->rc, &sv[s].tess);
            st->rays += sv[s].tess.rays;
        }
    }
    return r;
}

/* The layers' shells (out's and the lookups'), at the face size the first
   view's lens pixels ask for, and a system for each layer solved here;
   the shared shell's face size is the largest any lens asks for. */
static refl_result refl__lem_layer_systems(refl__lem_inference *x, refl__lem_map *out) {
    const refl_layered_em_options *o = &x->p->desc.layered_em;
    int l, L = x->lay->layers;
    refl_result r = REFL_OK;
    x->face = o->face_size > 0 ? o->face_size
                               : REFL__CLAMP((int)floor(0.5 * sqrt((double)x->sv[0].lens_pixels) + 0.5), 8, 256);
    out->layers = x->dr.layers = L;
    for (l = 0; l < L; ++l) {
        int shared = refl__lem_shared_layer(x->jr, l, L);
        x->dr.shell[l] = shared ? x->jr->shell : x->lay->shell[l];
        x->dr.shell[l].face_size = x->face;
        out->shell[l] = x->dr.shell[l];
        if (r == REFL_OK && !shared)
            r = refl_lem_system_create(6 * x->face * x->face, &x->p->scene->allocator, &x->sys[l]);
    }
    if (x->jr) x->jr->shell.face_size = REFL__MAX(x->jr->shell.face_size, x->face), x->jr->direct_on = x->direct_on;
    return r;
}

/* Rows from the runtime's own lookups at the views: per view and layer
   both terms drawn, each pixel a row where its records have the term. */
static refl_result refl__lem_lookup_rows(refl__lem_inference *x) {
    const refl_allocator *al = &x->p->scene->allocator;
    refl__lem_draw *dr = &x->dr;
    const refl__lem_sample_view *sv = x->sv;
    int w = x->w, h = x->h, L = x->lay->layers, s, l, term;
    size_t np = (size_t)w * (size_t)h, px, nrec = 10 * (size_t)L;
    float *depth = (float *)refl__calloc(al, np, sizeof(float)), *index[2] = {NULL, NULL};
    refl_result r = REFL_OK;
    for (term = 0; term < 2 && r == REFL_OK; ++term) {
        index[term] = (float *)refl__calloc(al, 4 * np, sizeof(float));
        if (!index[term] || !depth) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    for (s = 0; s < x->per && r == REFL_OK; ++s)
        for (l = 0; l < L && r == REFL_OK; ++l) {
            int shared = refl__lem_shared_layer(x->jr, l, L);
            for (term = 0; term < 2 && r == REFL_OK; ++term) {
                dr->term = term;
                dr->record_layer = l;
                r = refl__lem_raster(x->p->rc, &sv[s].tess, sv[s].vp, dr, index[term], depth, NULL, 0, w, h, al);
            }
            for (px = 0; px < np && r == REFL_OK; ++px)
                for (term = 0; term < 2 && r == REFL_OK; ++term) {
                    const float *rec = sv[s].rec + nrec * px + 5 * (size_t)(term * L + l), *ix = index[term] + 4 * px;
                    uint32_t tex[4];
                    float wt[4];
                    /* a row where the records have the term and all three vertices gave it an index;
                       the lens is drawn alone, so a pixel whose eye ray was continued
                       to it through an occluder (refl__lem_eye_paths) gets the row of
                       the lens surface its record is of: the tessellation leaves a
                       hidden triangle whole but traces its vertices (section 5) */
                    if (rec[4] < 0.0f || !(ix[3] >= 0.999f) ||
                        !refl_lem_shell_texels(&dr->shell[l], refl_v3(ix[0], ix[1], ix[2]), tex, wt))
                        continue;
                    r = shared ? refl__lem_joint_row(al, x->jr, ix, rec)
                               : refl_lem_system_add_row(x->sys[l], tex, wt, 4, rec, rec[4]);
                }
        }
    refl__free(al, index[0]);
    refl__free(al, index[1]);
    refl__free(al, depth);
    return r;
}

/* Where the lens images leave texels unheld, the direct images: from the
   viewpoint, each view's rectangle and the stride (x->direct, jr's copy
   for the shared layer, whose rows refl__lem_joint_solve adds), then the
   rows of each layer solved here. */
static refl_result refl__lem_direct_images(refl__lem_inference *x) {
    refl__pass *p = x->p;
    const refl_allocator *al = &p->scene->allocator;
    refl_stats *st = &p->frame->stats;
    refl__lem_direct *direct = &x->direct;
    int w = x->w, h = x->h, L = x->lay->layers, per = x->per, s, l, term;
    size_t np = (size_t)w * (size_t)h, px;
    refl_result r = REFL_OK;
    for (s = 0; s < per && direct->viewpoint; ++s) {
        int *rc = direct->rect[s], cx, cy;
        long long area;
        refl__lem_screen_rect(x->sv[s].vp, x->box[0], x->box[1], w, h, rc);
        /* twice the lens's rectangle: what its exit rays see past its outline */
        cx = (rc[0] + rc[2]) / 2, cy = (rc[1] + rc[3]) / 2;
        rc[0] = REFL__MAX(2 * rc[0] - cx, 0), rc[2] = REFL__MIN(2 * rc[2] - cx, w);
        rc[1] = REFL__MAX(2 * rc[1] - cy, 0), rc[3] = REFL__MIN(2 * rc[3] - cy, h);
        /* at most about a ray per texel from each view */
        area = (long long)(rc[2] - rc[0]) * (rc[3] - rc[1]);
        direct->stride = REFL__MAX(direct->stride, (int)ceil(sqrt((double)area / (6.0 * x->face * x->face))));
    }
    if (x->jr) x->jr->direct = *direct;
    for (l = 0; l < L && r == REFL_OK && x->direct_on; ++l) {
        int added = 0;
        float *pts = NULL;
        long long n = 0;
        if (refl__lem_shared_layer(x->jr, l, L)) continue;
        if (direct->distance) { /* the lens images' hits in the layer, both terms */
            pts = (float *)refl__calloc(al, 6 * (size_t)per * np + 1, sizeof(float));
            if (!pts) r = REFL_ERROR_OUT_OF_MEMORY;
            for (s = 0; s < per && pts; ++s)
                for (px = 0; px < np; ++px)
                    for (term = 0; term < 2; ++term) {
                        const float *q = x->sv[s].points + 6 * (size_t)L * px + 3 * (size_t)(term * L + l);
                        if (!isnan(q[0])) memcpy(pts + 3 * n++, q, 3 * sizeof(float));
                    }
        }
        direct->points = pts;
        direct->count = n;
        if (r == REFL_OK)
            r = refl__lem_direct_rows(p->scene, x->casters->scene, x->lay, &x->dr.shell[l], l, direct, x->sys[l],
                                      &st->rays, &added);
        st->layered_em.direct_rows += added;
        refl__free(al, pts);
        direct->points = NULL;
    }
    return r;
}

/* The maps' damping (refl_lem_solve_desc.damping). A row's weights are
   bilinear (summing to 1) times a confidence of at most 1, so a texel one
   pixel sees fully has a column of length near 1; one that only a few
   faint rows reach (the grazing edge of a face, a texel beside what the
   samples saw, with the direct images off) is barely determined, and the
   least squares solved to its tolerance sets it to whatever fits those
   rows: bright and off-colour specks. 0.05 leaves a texel with squared
   weights summing to 1 within 0.25% of its undamped value. */
#define REFL__LEM_DAMPING 0.05f

/* Solves one layer's system into texels as every map is solved, counting
   the solve in the frame's stats. Radiance and coverage are never
   negative, but unconstrained least squares is: where rows that share
   texels disagree (one shell point seen as a black and a white checker),
   it swings texels below 0 and their neighbours past every target
   (ringing), and a lookup there is drawn dark. Every layer is solved
   over x >= 0, damped. */
static refl_result refl__lem_solve_counted(refl__pass *p, const refl_lem_system *sys, float *texels) {
    refl_layered_em_frame_stats *st = &p->frame->stats.layered_em;
    refl_lem_solve_desc sd;
    refl_lem_solve_stats ss;
    refl_result r;
    memset(&sd, 0, sizeof sd);
    sd.iterations = p->desc.layered_em.iterations;
    sd.nonnegative = 1;
    sd.damping = REFL__LEM_DAMPING;
    r = refl_lem_solve(sys, &sd, texels, &ss);
    if (r != REFL_OK) return r;
    st->solves += 1;
    st->solves_capped += !ss.converged;
    st->solve_iterations = REFL__MAX(st->solve_iterations, ss.iterations);
    return r;
}

/* The texels of each layer solved here (out's, allocated). */
static refl_result refl__lem_solve_layers(refl__lem_inference *x, refl__lem_map *out) {
    const refl_allocator *al = &x->p->scene->allocator;
    int l, L = x->lay->layers;
    refl_result r = REFL_OK;
    for (l = 0; l < L && r == REFL_OK; ++l) {
        if (refl__lem_shared_layer(x->jr, l, L)) continue;
        out->texels[l] = (float *)refl__calloc(al, 4 * (size_t)(6 * x->face * x->face), sizeof(float));
        if (!out->texels[l]) r = REFL_ERROR_OUT_OF_MEMORY;
        if (r == REFL_OK) r = refl__lem_solve_counted(x->p, x->sys[l], out->texels[l]);
    }
    return r;
}

/* Infers object i's maps for the sample whose views are views[0 .. per)
   (the sample's own first) on the layers' shells: the records and
   tessellation of each view, then per layer rows from the runtime's own
   lookups at those views (both terms) and the direct images', solved by
   CGLS. out->texels are allocated. With jr (a shared outer layer), the
   outermost layer is looked up on jr's shell and its rows go to jr,
   unsolved (its texels NULL). */
static refl_result refl__lem_infer(refl__pass *p, const refl__gp_casters *casters, int i, const refl_view *views, int per,
                                   const refl__lem_layering *lay, refl__lem_joint *jr, refl__lem_map *out) {
    const refl_allocator *al = &p->scene->allocator;
    const refl_layered_em_options *o = &p->desc.layered_em;
    refl__lem_inference x;
    refl_vec3 centre;
    float lens_radius;
    int s, l;
    refl_result r;
    memset(&x, 0, sizeof x);
    x.p = p;
    x.casters = casters;
    x.object = i;
    x.views = views;
    x.per = per;
    x.w = views[0].width;
    x.h = views[0].height;
    x.lay = lay;
    x.jr = jr;
    x.direct_on = o->direct_images > 0 || (o->direct_images == 0 && REFL_LEM_DIRECT_DEFAULT > 0);
    refl__lem_direct_how(p, i, views, per, &x.direct);
    x.direct.distance &= x.direct_on;
    refl__lem_bounds(p->scene, i, &centre, &lens_radius, x.box);
    refl__lem_draw_box(&x.dr, x.box);
    r = refl__lem_record_views(&x);
    if (r == REFL_OK) r = refl__lem_layer_systems(&x, out);
    if (r == REFL_OK) r = refl__lem_lookup_rows(&x);
    if (r == REFL_OK) r = refl__lem_direct_images(&x);
    if (r == REFL_OK) r = refl__lem_solve_layers(&x, out);
    for (l = 0; l < lay->layers; ++l) refl_lem_system_destroy(x.sys[l]);
    for (s = 0; s < 3; ++s) refl__lem_sample_free(al, &x.sv[s]);
    if (r != REFL_OK) refl__lem_map_free(al, out);
    return r;
}

/* The index in *maps of object i's map for the sample of views[0 .. per):
   the one kept when pass p's renderer has it, else inferred and added. */
static refl_result refl__lem_map_of(refl__pass *p, const refl__gp_casters *casters, int i, const refl_view *views,
                                    int per, const refl__lem_layering *lay, struct refl__lem_maps *maps, int *at) {
    const refl_allocator *al = &p->scene->allocator;
    refl__lem_map m;
    refl_result r;
    double t0 = refl__now_ms();
    *at = refl__lem_find(maps, p, i, &views[0]);
    if (*at >= 0) {
        p->frame->stats.layered_em.maps_kept++;
        return REFL_OK;
    }
    memset(&m, 0, sizeof m);
    m.object = i;
    m.depth = p->desc.depth;
    m.view = views[0];
    m.options = p->desc.layered_em;
    r = refl__lem_infer(p, casters, i, views, per, lay, NULL, &m);
    if (r == REFL_OK && (*at = refl__push(al, (void **)&maps->maps, &maps->count, sizeof m, &m)) < 0) {
        refl__lem_map_free(al, &m);
        r = REFL_ERROR_OUT_OF_MEMORY;
    }
    if (r == REFL_OK) p->frame->stats.layered_em.maps_inferred++;
    p->frame->stats.ms_build += refl__now_ms() - t0;
    return r;
}

/* ---- viewpoint samples ------------------------------------------------------------- */

/* The circle of viewpoint samples around c, level with the eye and
   through it: its radius and height snapped to 1/1024 of the lens's
   radius, so that every frame of an orbit, and a fresh renderer at any of
   them, puts the samples at exactly the same views. The maps' store fixes
   each lens's circle at the first frame (or prebuild) that draws it
   (rings), as the paper parameterises its maps by one circle: later eyes
   off it take the samples of their azimuth on it. 0 when the eye is on
   the circle's axis (its azimuth undefined). */
typedef struct refl__lem_circle {
    refl_vec3 c;
    float rho, height;
    double step, phi;            /* spacing; the eye's azimuth in [0, 2 pi) */
    int samples, per;            /* per: views a map is inferred from (1, or 3 multi-view) */
    int ring;                    /* in the store's rings, -1: none (no memory) */
} refl__lem_circle;

static int refl__lem_circle_of(const refl__pass *p, int object, refl_vec3 c, float lens_radius, int joint,
                               struct refl__lem_maps *rings, refl__lem_circle *out) {
    const refl_view *v = p->view;
    float dx = v->eye.x - c.x, dz = v->eye.z - c.z, rho = sqrtf(dx * dx + dz * dz);
    float grid = REFL__MAX(lens_radius, 1e-6f) / 1024.0f;
    refl__lem_ring ring;
    int k;
    out->c = c;
    out->ring = -1;
    out->samples = p->desc.layered_em.samples > 0 ? p->desc.layered_em.samples : 45;
    out->per = p->desc.layered_em.single_view ? 1 : 3;
    out->step = 2.0 * REFL__PI / out->samples;
    out->phi = atan2((double)dx, (double)dz);
    if (out->phi < 0.0) out->phi += 2.0 * REFL__PI;
    out->rho = roundf(rho / grid) * grid;
    out->height = roundf(v->eye.y / grid) * grid;
    if (!(rho > 1e-6f * (1.0f + refl_v3_length(refl_v3_sub(v->eye, c))) && out->rho > 0.0f &&
          refl__isfinite(out->height)))
        return 0;
    for (k = 0; k < rings->ring_count; ++k)
        if (rings->rings[k].object == object && rings->rings[k].joint == joint) {
            out->rho = rings->rings[k].rho;
            out->height = rings->rings[k].height;
            out->ring = k;
            return 1;
        }
    memset(&ring, 0, sizeof ring);
    ring.object = object;
    ring.joint = joint;
    ring.rho = out->rho;
    ring.height = out->height;
    out->ring = refl__push(&p->scene->allocator, (void **)&rings->rings, &rings->ring_count, sizeof ring, &ring);
    return 1; /* a ring not kept (no memory) only costs later frames their reuse */
}

/* The views sample k's map is inferred from: the sample's own (at azimuth
   k step) and, multi-view, the views half a spacing either side (the
   paper's simultaneous inference, against disocclusions between samples). */
static void refl__lem_sample_views(const refl__pass *p, const refl__lem_circle *cc, int k, refl_view out[3]) {
    int j;
    k %= cc->samples; /* past the last: the first again, at exactly its view */
    for (j = 0; j < cc->per; ++j) {
        double a = k * cc->step + (j == 0 ? 0.0 : j == 1 ? -0.5 * cc->step : 0.5 * cc->step);
        out[j] = *p->view;
        out[j].eye = refl_v3(cc->c.x + cc->rho * (float)sin(a), cc->height, cc->c.z + cc->rho * (float)cos(a));
        out[j].target = cc->c;
    }
}

/* Views of the circle the layers are clustered over. */
enum { REFL__LEM_CLUSTER_VIEWS = 16 };

/* View k of the n the layers are clustered over (refl__lem_cluster): the
   sample k samples / n of circle cc (NULL: the pass's eye), a quarter of
   its size, 16 to 64 pixels wide (the clustering needs distances, not
   detail). */
static refl_view refl__lem_cluster_view(const refl__pass *p, const refl__lem_circle *cc, int k, int n) {
    refl_view v[3];
    int w;
    if (cc) refl__lem_sample_views(p, cc, (int)((long long)k * cc->samples / n), v);
    else v[0] = *p->view;
    w = REFL__MIN(v[0].width, REFL__CLAMP(v[0].width / 4, 16, 64));
    v[0].height = REFL__MAX(1, (int)((long long)v[0].height * w / v[0].width));
    v[0].width = w;
    return v[0];
}

/* Section 4.2's layers of lens object i (centre c, half diagonal
   lens_radius) over its viewpoint samples at once: the hits of the views
   of up to REFL__LEM_CLUSTER_VIEWS samples evenly around the circle (each
   a quarter of its size, 16 to 64 pixels wide: the clustering needs
   distances, not detail) clustered by
   refl_lem_cluster_layers, each object's layer kept. No hits (only the
   environment): one shell at 10 lens radii. Each layer's sphere lies at
   its hits' mean distance, the outermost outside the lens; then each
   layer's shell is fitted to its hits (refl__lem_fit_layers): boxes and
   cylinders around the lens's box, an inner layer's sphere where its
   hits lie. */
static refl_result refl__lem_cluster(refl__pass *p, const refl_ray_caster *caster, int i, refl_vec3 c,
                                     float lens_radius, const refl__lem_circle *cc, refl__lem_ring *ring) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl__lem_hits h;
    refl__lem_layering *lay = &ring->lay;
    int n = cc ? REFL__MIN(cc->samples, REFL__LEM_CLUSTER_VIEWS) : 1, k, l, top;
    int want = p->desc.layered_em.layers > 0 ? p->desc.layered_em.layers : 1;
    int *layer_of = NULL;
    refl_vec3 box[2], bc;
    float br;
    refl_result r = REFL_OK;
    refl__lem_bounds(scene, i, &bc, &br, box);
    memset(&h, 0, sizeof h);
    h.al = al;
    for (k = 0; k < n && r == REFL_OK; ++k) {
        refl_view v[1];
        v[0] = refl__lem_cluster_view(p, cc, k, n);
        if (!refl__lem_gather_hits(scene, caster, &v[0], i, p->desc.depth, refl__lem_own(p, i),
                                   refl__lem_continued(p) ? box : NULL, c, &h, &p->frame->stats.rays))
            r = REFL_ERROR_OUT_OF_MEMORY;
    }
    memset(lay, 0, sizeof *lay);
    lay->own = refl__lem_own(p, i);
    lay->continued = refl__lem_continued(p);
    lay->box[0] = box[0];
    lay->box[1] = box[1];
    lay->centre = c;
    lay->object_count = scene->object_count;
    ring->object_layer = r == REFL_OK ? (signed char *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), 1)
                                      : NULL;
    if (r == REFL_OK && !ring->object_layer) r = REFL_ERROR_OUT_OF_MEMORY;
    if (r == REFL_OK) {
        memset(ring->object_layer, -1, (size_t)scene->object_count);
        lay->object_layer = ring->object_layer;
        lay->layers = 1;
        lay->radius[0] = 0.0f;
    }
    if (r == REFL_OK && h.count > 0) {
        layer_of = (int *)refl__calloc(al, (size_t)h.count, sizeof(int));
        lay->layers = layer_of ? refl_lem_cluster_layers(h.distance, h.object, h.ray, h.count, want, al, lay->radius,
                                                         layer_of)
                               : 0;
        if (!lay->layers) r = REFL_ERROR_OUT_OF_MEMORY;
        for (k = 0; k < h.count && r == REFL_OK; ++k)
            if (h.object[k] >= 0 && h.object[k] < scene->object_count)
                ring->object_layer[h.object[k]] = (signed char)layer_of[k];
    }
    /* every layer at its hits' mean distance, in whatever order the
       layers composite (along the rays: `hybrid`'s floor comes after the
       columns and walls its rays meet first, though it lies nearer the
       teapot than they do; a sphere moved out beyond them puts the floor
       far from where it is, and every viewpoint sees it in other texels);
       an inner one within the lens's bounds too (the paper's shells: a
       ball at a concave mirror's focus is an inner sphere the exit rays
       enter); the outermost, opaque and closed around the lens, beyond
       it */
    for (l = 0; l < lay->layers; ++l)
        if (!(lay->radius[l] > 0.0f)) lay->radius[l] = REFL__MAX(1e-3f * lens_radius, 1e-6f);
    top = REFL__MAX(lay->layers, 1) - 1;
    if (!(lay->radius[top] > lens_radius))
        lay->radius[top] = REFL__MAX(REFL__MAX(10.0f * lens_radius, 1e-3f), 1.05f * lay->radius[REFL__MAX(top - 1, 0)]);
    if (r == REFL_OK &&
        !refl__lem_fit_layers(lay, &h, layer_of, p->desc.layered_em.shell, p->desc.layered_em.shell_frame, box[0], box[1], lens_radius))
        r = REFL_ERROR_OUT_OF_MEMORY;
    refl__free(al, layer_of);
    refl__lem_hits_free(&h);
    return r;
}

/* Where the pass keeps maps: its renderer's, else `own` (this frame's). */
static refl_result refl__lem_store(refl__pass *p, struct refl__lem_maps *own, struct refl__lem_maps **out) {
    *out = own;
    if (!p->models) return REFL_OK;
    if (!p->models->lem) p->models->lem = (struct refl__lem_maps *)refl__calloc(&p->scene->allocator, 1, sizeof *own);
    if (!p->models->lem) return REFL_ERROR_OUT_OF_MEMORY;
    *out = p->models->lem;
    return REFL_OK;
}

/* ---- the frame ------------------------------------------------------------------------ */

/* Lens object i's circle (0 on its axis: cc unset) and its layers, in
   *lay: the ring's (clustered at its first use), else clustered into
   *spare (its object_layer freed by the caller). */
static int refl__lem_ring_of(refl__pass *p, const refl_ray_caster *caster, int i, refl_vec3 centre, float lens_radius,
                             struct refl__lem_maps *maps, refl__lem_circle *cc, refl__lem_layering *lay,
                             refl__lem_ring *spare, refl_result *r) {
    refl_vec3 around = centre;
    float around_radius = lens_radius;
    int joint = refl__lem_share(p), on;
    refl__lem_ring *ring;
    /* a shared outer layer: one circle around every lens, so that a
       sample is the same views for each */
    if (joint) refl__lem_joint_bounds(p, &around, &around_radius, NULL);
    on = refl__lem_circle_of(p, i, around, around_radius, joint, maps, cc);
    ring = on && cc->ring >= 0 ? &maps->rings[cc->ring] : spare;
    *r = REFL_OK;
    /* a ring clustered with the other lenses' hits in or out (lens_layers)
       does not serve the other way */
    if (ring->lay.layers && (ring->lay.own != refl__lem_own(p, i) || ring->lay.continued != refl__lem_continued(p)))
        ring = spare;
    if (!ring->lay.layers) *r = refl__lem_cluster(p, caster, i, centre, lens_radius, on ? cc : NULL, ring);
    *lay = ring->lay;
    lay->depth = p->desc.depth;
    return on;
}

/* ---- a shared outer layer (section 4.3) ------------------------------------------------ */

/* The shared outer layer's shell, fitted as a lens's outermost is
   (refl__lem_fit_layers: the kind and frame asked, AUTO choosing by the
   conflicts) to the hits in each lens's outermost layer (lays[k] of
   objs[k]) seen from the clustering's views of their shared circle cc
   (NULL: the eye's), distances from the centre of the lenses' joint box:
   a sphere at their mean (a ray's front-most hit in the layer counted),
   at 10 half diagonals of the box where that lies within them; a box or
   cylinder holds the joint box. */
static refl_result refl__lem_joint_shell(refl__pass *p, const refl_ray_caster *caster, const int *objs,
                                         const refl__lem_layering *lays, int n, const refl__lem_circle *cc,
                                         refl_lem_shell *out) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    int nv = cc ? REFL__MIN(cc->samples, REFL__LEM_CLUSTER_VIEWS) : 1, j, k, v, counted = -1, kept = 0;
    int *end = (int *)refl__calloc(al, (size_t)n, sizeof(int)), *layer_of = NULL;
    refl__lem_hits h;
    refl__lem_layering jl;
    refl_vec3 box[2];
    float joint_radius;
    double sum = 0.0;
    refl_result r = end ? REFL_OK : REFL_ERROR_OUT_OF_MEMORY;
    memset(&h, 0, sizeof h);
    memset(&jl, 0, sizeof jl);
    h.al = al;
    refl__lem_joint_bounds(p, &jl.centre, &joint_radius, box);
    for (j = 0; j < n && r == REFL_OK; ++j) {
        for (v = 0; v < nv && r == REFL_OK; ++v) {
            refl_view view = refl__lem_cluster_view(p, cc, v, nv);
            if (!refl__lem_gather_hits(scene, caster, &view, objs[j], p->desc.depth, lays[j].own,
                                       lays[j].continued ? lays[j].box : NULL, jl.centre, &h, &p->frame->stats.rays))
                r = REFL_ERROR_OUT_OF_MEMORY;
        }
        end[j] = h.count;
    }
    layer_of = r == REFL_OK && h.count ? (int *)refl__calloc(al, (size_t)h.count, sizeof(int)) : NULL;
    if (r == REFL_OK && h.count && !layer_of) r = REFL_ERROR_OUT_OF_MEMORY;
    for (j = k = 0; k < h.count && r == REFL_OK; ++k) {
        refl__lem_hit hit;
        while (k >= end[j]) ++j;
        /* the hit's layer at its own lens: the layers are each lens's */
        memset(&hit, 0, sizeof hit);
        hit.object = h.object[k];
        hit.distance = refl_v3_length(refl_v3_sub(refl_v3(h.pos[3 * k], h.pos[3 * k + 1], h.pos[3 * k + 2]),
                                                  lays[j].centre));
        layer_of[k] = refl__lem_hit_layer(&lays[j], &hit) == lays[j].layers - 1 ? 0 : -1;
        if (layer_of[k] < 0 || h.ray[k] == counted) continue;
        counted = h.ray[k];
        sum += h.distance[k];
        ++kept;
    }
    jl.layers = 1;
    jl.radius[0] = kept ? (float)(sum / kept) : 0.0f;
    if (!(jl.radius[0] > joint_radius)) jl.radius[0] = 10.0f * REFL__MAX(joint_radius, 1e-4f);
    if (r == REFL_OK && !refl__lem_fit_layers(&jl, &h, layer_of, p->desc.layered_em.shell,
                                              p->desc.layered_em.shell_frame, box[0], box[1], joint_radius))
        r = REFL_ERROR_OUT_OF_MEMORY;
    *out = jl.shell[0];
    refl__free(al, layer_of);
    refl__free(al, end);
    refl__lem_hits_free(&h);
    return r;
}

/* The shared layer's map from jr's rows (every lens's) and each lens's
   direct images (directs[k] with layering lays[k], their outermost
   layer), solved as one system: out is the shared map (one layer). */
static refl_result refl__lem_joint_solve(refl__pass *p, const refl__gp_casters *casters, const refl__lem_joint *jr,
                                         const refl__lem_layering *lays, const refl__lem_direct *directs, int n,
                                         refl__lem_map *out) {
    const refl_allocator *al = &p->scene->allocator;
    refl_stats *st = &p->frame->stats;
    int texels = 6 * jr->shell.face_size * jr->shell.face_size, k;
    long long row;
    refl_lem_system *sys = NULL;
    refl_result r = refl_lem_system_create(texels, al, &sys);
    out->layers = 1;
    out->shell[0] = jr->shell;
    for (row = 0; row < jr->count && r == REFL_OK; ++row) {
        const float *q = jr->rows + 8 * (size_t)row;
        uint32_t tex[4];
        float wt[4];
        if (refl_lem_shell_texels(&jr->shell, refl_v3(q[0], q[1], q[2]), tex, wt))
            r = refl_lem_system_add_row(sys, tex, wt, 4, q + 3, q[7]);
    }
    /* after every lens's rows: the coverage the direct images fill around */
    for (k = 0; k < n && r == REFL_OK && jr->direct_on; ++k) {
        int added = 0;
        r = refl__lem_direct_rows(p->scene, casters->scene, &lays[k], &jr->shell, lays[k].layers - 1, &directs[k], sys,
                                  &st->rays, &added);
        st->layered_em.direct_rows += added;
    }
    out->texels[0] = r == REFL_OK ? (float *)refl__calloc(al, 4 * (size_t)texels, sizeof(float)) : NULL;
    if (r == REFL_OK && !out->texels[0]) r = REFL_ERROR_OUT_OF_MEMORY;
    if (r == REFL_OK) r = refl__lem_solve_counted(p, sys, out->texels[0]);
    refl_lem_system_destroy(sys);
    return r;
}

/* Puts map m into the store, in place of the one of its key there (a
   sample inferred again because a part of it was dropped). */
static refl_result refl__lem_put(refl__pass *p, struct refl__lem_maps *maps, refl__lem_map *m) {
    const refl_allocator *al = &p->scene->allocator;
    int at = refl__lem_find(maps, p, m->object, &m->view);
    if (at >= 0) {
        refl__lem_map_free(al, &maps->maps[at]);
        maps->maps[at] = *m;
        return REFL_OK;
    }
    if (refl__push(al, (void **)&maps->maps, &maps->count, sizeof *m, m) >= 0) return REFL_OK;
    refl__lem_map_free(al, m);
    return REFL_ERROR_OUT_OF_MEMORY;
}

/* The sample of views[0 .. per) for every lens pass p draws, their
   outermost layer shared: kept when the store has every lens's map and
   the shared one, else all inferred. The shared shell
   (refl__lem_joint_shell) is fitted once for the lenses' rings and kept
   with them. *at: lens i's map, *joint_at: the shared one. */
static refl_result refl__lem_joint_map_of(refl__pass *p, const refl__gp_casters *casters, int i, const refl_view *views,
                                          int per, struct refl__lem_maps *maps, int *at, int *joint_at) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    int n = 0, k, j, all;
    int *objs = (int *)refl__calloc(al, (size_t)scene->object_count, sizeof(int));
    refl__lem_layering *lays = (refl__lem_layering *)refl__calloc(al, (size_t)scene->object_count, sizeof *lays);
    refl__lem_ring *spares = (refl__lem_ring *)refl__calloc(al, (size_t)scene->object_count, sizeof *spares);
    refl__lem_direct *directs = (refl__lem_direct *)refl__calloc(al, (size_t)scene->object_count, sizeof *directs);
    refl__lem_map *ms = (refl__lem_map *)refl__calloc(al, (size_t)scene->object_count + 1, sizeof *ms);
    int *ring = (int *)refl__calloc(al, (size_t)scene->object_count, sizeof(int)), on = 0, fitted = 0;
    refl__lem_joint jr;
    refl__lem_circle cc;
    refl_result r = objs && lays && spares && directs && ms && ring ? REFL_OK : REFL_ERROR_OUT_OF_MEMORY;
    double t0 = refl__now_ms();
    memset(&jr, 0, sizeof jr);
    for (j = 0; j < scene->object_count; ++j)
        if (refl__pass_draws(p, j) && objs) objs[n++] = j;
    *joint_at = refl__lem_find(maps, p, -1, &views[0]);
    for (k = 0, all = *joint_at >= 0; k < n && all; ++k) all = refl__lem_find(maps, p, objs[k], &views[0]) >= 0;
    if (r == REFL_OK && all) {
        *at = refl__lem_find(maps, p, i, &views[0]);
        p->frame->stats.layered_em.maps_kept++;
        n = 0; /* nothing to free but the arrays */
    }
    /* every lens's layers, its ring clustered where this is its first
       sample, and the shared shell, fitted at the first */
    for (k = 0; k < n && r == REFL_OK && !all; ++k) {
        refl_vec3 centre, box[2];
        float lens_radius;
        refl__lem_bounds(scene, objs[k], &centre, &lens_radius, box);
        on = refl__lem_ring_of(p, casters->scene, objs[k], centre, lens_radius, maps, &cc, &lays[k], &spares[k], &r);
        ring[k] = on && cc.ring >= 0 && maps->rings[cc.ring].lay.layers ? cc.ring : -1;
        if (ring[k] >= 0 && maps->rings[ring[k]].joint_fitted) jr.shell = maps->rings[ring[k]].joint_shell, fitted = 1;
    }
    if (r == REFL_OK && !all && !fitted)
        r = refl__lem_joint_shell(p, casters->scene, objs, lays, n, on ? &cc : NULL, &jr.shell);
    for (k = 0; k < n && r == REFL_OK && !all && !fitted; ++k)
        if (ring[k] >= 0) maps->rings[ring[k]].joint_shell = jr.shell, maps->rings[ring[k]].joint_fitted = 1;
    jr.shell.face_size = 0;
    for (k = 0; k < n && r == REFL_OK && !all; ++k) {
        ms[k].object = objs[k];
        ms[k].depth = p->desc.depth;
        ms[k].view = views[0];
        ms[k].options = p->desc.layered_em;
        r = refl__lem_infer(p, casters, objs[k], views, per, &lays[k], &jr, &ms[k]);
        directs[k] = jr.direct;
    }
    if (r == REFL_OK && !all) {
        ms[n].object = -1;
        ms[n].depth = p->desc.depth;
        ms[n].view = views[0];
        ms[n].options = p->desc.layered_em;
        r = refl__lem_joint_solve(p, casters, &jr, lays, directs, n, &ms[n]);
    }
    for (k = 0; k < n && r == REFL_OK && !all; ++k) ms[k].shell[ms[k].layers - 1] = jr.shell;
    for (k = 0; k <= n && !all && ms; ++k) {
        if (r == REFL_OK) r = refl__lem_put(p, maps, &ms[k]);
        else refl__lem_map_free(al, &ms[k]);
    }
    if (r == REFL_OK && !all) {
        p->frame->stats.layered_em.maps_inferred += n + 1;
        p->frame->stats.ms_build += refl__now_ms() - t0;
        *at = refl__lem_find(maps, p, i, &views[0]);
        *joint_at = refl__lem_find(maps, p, -1, &views[0]);
    }
    for (k = 0; k < n && spares; ++k) refl__free(al, spares[k].object_layer);
    refl__free(al, jr.rows);
    refl__free(al, objs);
    refl__free(al, lays);
    refl__free(al, spares);
    refl__free(al, directs);
    refl__free(al, ms);
    refl__free(al, ring);
    return r;
}

/* The map of lens i for the sample of views[0 .. per) (refl__lem_map_of),
   and with a shared outer layer the shared map (else -1). */
static refl_result refl__lem_sample_maps(refl__pass *p, const refl__gp_casters *casters, int i, const refl_view *views,
                                         int per, const refl__lem_layering *lay, struct refl__lem_maps *maps, int *at,
                                         int *joint_at) {
    *joint_at = -1;
    if (refl__lem_share(p)) return refl__lem_joint_map_of(p, casters, i, views, per, maps, at, joint_at);
    return refl__lem_map_of(p, casters, i, views, per, lay, maps, at);
}

/* Layer l's texels of map m: its own, else (shared) the shared map's. */
static const float *refl__lem_layer_texels(const struct refl__lem_maps *maps, const refl__lem_map *m, int joint_at,
                                           int l) {
    return m->texels[l] || joint_at < 0 ? m->texels[l] : maps->maps[joint_at].texels[0];
}

/* ---- the points the maps show (frame->points) ------------------------------------------ */

/* frame->points at the lens pixels the maps drew (seen 1; the traced ones
   get the tracer's): per pixel the point refl__lem_point_fragment gives
   for the term of the larger F G, from map m (the blend's heavier
   sample; its layers' texels[], refl__lem_layer_texels), so the reflection error measures where the model puts what
   it shows. color and depth: scratch buffers of the frame's size. */
static refl_result refl__lem_points(refl__pass *p, const refl_lens_tess *t, const refl__lem_map *m,
                                    const float *const *texels, int terms, const refl_vec3 box[2], uint8_t ref,
                                    const uint8_t *seen, float *color, float *depth) {
    refl_frame *f = p->frame;
    const refl_allocator *al = &p->scene->allocator;
    size_t np = (size_t)f->width * (size_t)f->height, px;
    float *strength = (float *)refl__calloc(al, np, sizeof(float));
    refl__lem_draw dr;
    refl_result r = strength ? REFL_OK : REFL_ERROR_OUT_OF_MEMORY;
    int term, l;
    memset(&dr, 0, sizeof dr);
    dr.layers = m->layers;
    for (l = 0; l < m->layers; ++l) dr.shell[l] = m->shell[l], dr.map[l] = texels[l];
    dr.weight = 1.0f;
    dr.record_layer = -1;
    dr.points = 1;
    refl__lem_draw_box(&dr, box);
    for (term = 0; term < terms && r == REFL_OK; ++term) {
        dr.term = term;
        r = refl__lem_raster(p->rc, t, p->vp, &dr, color, depth, f->stencil, ref, f->width, f->height, al);
        for (px = 0; px < np && r == REFL_OK; ++px) {
            const float *c = color + 4 * px;
            if (f->stencil[px] != ref || seen[px] != 1 || !(c[3] > strength[px])) continue;
            strength[px] = c[3];
            memcpy(f->points + 3 * px, c, 3 * sizeof(float));
        }
    }
    refl__free(al, strength);
    return r;
}

/* What a frame draws of lens object i: the maps of the one or two
   samples bracketing the eye (kept or inferred; indices into the store)
   with their blend weights, the terms, the lens's bounds and the eye's
   tessellation (frame_tess, allocated with the scene's allocator). */
typedef struct refl__lem_plan {
    int n, at[2], terms;
    int joint_at[2];         /* the shared outer layer's map of each sample, -1: none */
    float weight[2];
    refl_vec3 box[2];
    refl_lens_tess frame_tess;
    double ms_tessellate;    /* its time (the frame's reflection time; the maps' is build time) */
} refl__lem_plan;

static refl_result refl__lem_plan_of(refl__pass *p, const refl__gp_casters *casters, int i, struct refl__lem_maps *maps,
                                     refl__lem_plan *pl) {
    const refl_scene *scene = p->scene;
    const refl_layered_em_options *o = &p->desc.layered_em;
    refl_frame *f = p->frame;
    int s;
    refl__lem_circle cc;
    refl__lem_ring spare;
    refl__lem_layering lay;
    refl_lens_tess_desc td;
    refl_vec3 centre;
    refl_view views[3];
    float lens_radius;
    refl_result r = REFL_OK;
    double t1;
    memset(pl, 0, sizeof *pl);
    memset(&td, 0, sizeof td);
    memset(&spare, 0, sizeof spare);
    pl->n = 1;
    pl->at[0] = pl->at[1] = -1;
    pl->joint_at[0] = pl->joint_at[1] = -1;
    pl->weight[0] = 1.0f;
    td.edge_px = o->edge_px;
    td.angle_degrees = o->angle_degrees;
    td.max_interfaces = p->desc.depth;
    pl->terms = scene->materials[scene->objects[i].material].type == REFL_GLASS ? 2 : 1;
    refl__lem_bounds(scene, i, &centre, &lens_radius, pl->box);
    if (!refl__lem_ring_of(p, casters->scene, i, centre, lens_radius, maps, &cc, &lay, &spare, &r)) {
        /* on the axis: the eye's own view, one map */
        views[0] = *p->view;
        if (r == REFL_OK) r = refl__lem_sample_maps(p, casters, i, views, 1, &lay, maps, &pl->at[0], &pl->joint_at[0]);
    } else {
        double fk = cc.phi / cc.step;
        int k0 = (int)floor(fk);
        pl->weight[1] = (float)(fk - k0);
        pl->weight[0] = 1.0f - pl->weight[1];
        pl->n = pl->weight[1] > 0.0f ? 2 : 1;
        for (s = 0; s < pl->n && r == REFL_OK; ++s) {
            refl__lem_sample_views(p, &cc, k0 + s, views);
            r = refl__lem_sample_maps(p, casters, i, views, cc.per, &lay, maps, &pl->at[s], &pl->joint_at[s]);
        }
    }
    refl__free(&scene->allocator, spare.object_layer);
    /* the frame: tessellated for the eye */
    if (r == REFL_OK) {
        long long tests0 = refl__bvh_tests_counted();
        refl__gp_casters vc = refl__lem_vertex_casters(p, casters, i);
        t1 = refl__now_ms();
        pl->frame_tess.allocator = scene->allocator;
        r = refl__lens_tessellate(scene, &vc, i, p->view, &td, p->rc, &pl->frame_tess);
        f->stats.layered_em.vertex_tests += refl__bvh_tests_counted() - tests0;
        f->stats.rays += pl->frame_tess.rays;
        f->stats.triangles += pl->frame_tess.triangle_count;
        f->stats.layered_em.vertices += pl->frame_tess.vertex_count;
        f->stats.layered_em.ms_trace += pl->frame_tess.ms_trace;
        pl->ms_tessellate = refl__now_ms() - t1;
        f->stats.layered_em.ms_tessellate += pl->ms_tessellate - pl->frame_tess.ms_trace;
    }
    return r;
}

/* Lens object i: its plan (refl__lem_plan_of), the eye's tessellation
   drawn once per map and term, weighed by the blend, added over the base
   pass. marked: lens pixels left to the tracer (no triangle there, or a
   path off the maps). */
static refl_result refl__lem_object(refl__pass *p, const refl__gp_casters *casters, int i, struct refl__lem_maps *maps,
                                    uint8_t *marked) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl_frame *f = p->frame;
    int w = f->width, h = f->height, s, k, term;
    size_t np = (size_t)w * (size_t)h, px;
    refl__lem_plan pl;
    refl__lem_draw dr;
    float *color = NULL, *sum = NULL, *depth = NULL;
    uint8_t ref = (uint8_t)(i + 1 < 255 ? i + 1 : 255), *seen = NULL;
    refl_result r = refl__lem_plan_of(p, casters, i, maps, &pl);
    double t0 = refl__now_ms() - pl.ms_tessellate, t1;
    color = (float *)refl__calloc(al, 4 * np, sizeof(float));
    sum = (float *)refl__calloc(al, 4 * np, sizeof(float));
    depth = (float *)refl__calloc(al, np, sizeof(float));
    seen = (uint8_t *)refl__calloc(al, np, 1);
    if (r == REFL_OK && (!color || !sum || !depth || !seen)) r = REFL_ERROR_OUT_OF_MEMORY;
    t1 = refl__now_ms();
    /* seen: 1 a triangle covers the pixel, 2 some vertex's path was off the maps */
    for (s = 0; s < pl.n && r == REFL_OK; ++s)
        for (term = 0; term < pl.terms && r == REFL_OK; ++term) {
            const refl__lem_map *m = &maps->maps[pl.at[s]];
            memset(&dr, 0, sizeof dr);
            dr.layers = m->layers;
            for (k = 0; k < m->layers; ++k) {
                dr.shell[k] = m->shell[k];
                dr.map[k] = refl__lem_layer_texels(maps, m, pl.joint_at[s], k);
            }
            dr.weight = pl.weight[s];
            dr.term = term;
            dr.record_layer = -1;
            refl__lem_draw_box(&dr, pl.box);
            r = refl__lem_raster(p->rc, &pl.frame_tess, p->vp, &dr, color, depth, f->stencil, ref, w, h, al);
            if (s == 0) f->stats.layered_em.quad_misses += dr.quad_misses;
            for (px = 0; px < np && r == REFL_OK; ++px) {
                float a = color[4 * px + 3];
                if (f->stencil[px] != ref || !(a > 0.0f)) continue;
                seen[px] = (uint8_t)REFL__MAX(seen[px], a > 1.0f ? 2 : 1);
                for (k = 0; k < 3; ++k) sum[4 * px + (size_t)k] += color[4 * px + (size_t)k];
            }
        }
    for (px = 0; px < np && r == REFL_OK; ++px) {
        if (f->stencil[px] != ref) continue;
        if (seen[px] != 1) {
            marked[px] = 1; /* no triangle here, or an exit ray off the maps: traced */
            f->stats.layered_em.traced_pixels++;
            continue;
        }
        for (k = 0; k < 3; ++k) f->rgba[4 * px + (size_t)k] += sum[4 * px + (size_t)k];
    }
    f->stats.layered_em.ms_draw += refl__now_ms() - t1;
    if (r == REFL_OK) {
        int heavier = pl.n > 1 && pl.weight[1] > pl.weight[0];
        const refl__lem_map *m = &maps->maps[pl.at[heavier]];
        const float *texels[REFL_LEM_MAX_LAYERS];
        for (k = 0; k < m->layers; ++k) texels[k] = refl__lem_layer_texels(maps, m, pl.joint_at[heavier], k);
        r = refl__lem_points(p, &pl.frame_tess, m, texels, pl.terms, pl.box, ref, seen, color, depth);
    }
    f->stats.ms_reflect += refl__now_ms() - t0;
    refl__free(al, pl.frame_tess.vertices);
    refl__free(al, pl.frame_tess.indices);
    refl__free(al, color);
    refl__free(al, sum);
    refl__free(al, depth);
    refl__free(al, seen);
    return r;
}

/* The scene with its lens objects (reflectors) alone (lenses 1) or with
   the rest alone (0): every object left out keeps its index over an empty
   mesh (out's last), so a BVH of it holds its triangles as the scene's
   BVH does (the same world-space floats, objects and triangles: the same
   hits) and nothing else. out's meshes and objects are allocated (the
   caller frees them). */
static refl_result refl__lem_part(const refl_scene *scene, int lenses, refl_mesh *empty, refl_scene *out) {
    const refl_allocator *al = &scene->allocator;
    int i;
    *out = *scene;
    memset(empty, 0, sizeof *empty);
    out->meshes = (refl_mesh **)refl__calloc(al, (size_t)scene->mesh_count + 1, sizeof *out->meshes);
    out->objects = (refl_object *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof *out->objects);
    if (!out->meshes || !out->objects) return REFL_ERROR_OUT_OF_MEMORY;
    if (scene->mesh_count > 0) memcpy(out->meshes, scene->meshes, (size_t)scene->mesh_count * sizeof *out->meshes);
    out->meshes[scene->mesh_count] = empty;
    out->mesh_count = scene->mesh_count + 1;
    for (i = 0; i < scene->object_count; ++i) {
        out->objects[i] = scene->objects[i];
        if (refl__is_reflector(&scene->materials[scene->objects[i].material]) != lenses)
            out->objects[i].mesh = scene->mesh_count;
    }
    return REFL_OK;
}

/* The vertex paths' BVHs, split[0] over the scene's lens objects and
   split[1] over the rest (refl__lem_part): a renderer keeps them in its
   models, refit when the scene changed and rebuilt only where their
   triangles no longer fit them (an object added, removed, reshaped or
   made a lens or not); without a renderer, built into owned[] for the
   frame. */
static refl_result refl__lem_split(refl__pass *p, refl_bvh *split[2], refl_bvh *owned[2]) {
    const refl_allocator *al = &p->scene->allocator;
    refl__models *m = p->models;
    refl_result r = REFL_OK;
    int k;
    for (k = 0; k < 2; ++k) {
        refl_scene part;
        refl_mesh empty;
        owned[k] = NULL;
        split[k] = m ? m->split[k] : NULL;
        if (r != REFL_OK || (split[k] && m->split_version == p->scene->version)) continue;
        r = refl__lem_part(p->scene, k == 0, &empty, &part);
        if (r == REFL_OK && split[k] && refl_bvh_refit(split[k], &part) != REFL_OK) {
            refl_bvh_destroy(split[k]);
            split[k] = m->split[k] = NULL;
        }
        if (r == REFL_OK && !split[k]) {
            r = refl_bvh_build(&part, al, &split[k]);
            if (r == REFL_OK) p->frame->stats.scene_models_built++;
            if (m) m->split[k] = split[k];
            else owned[k] = split[k];
        }
        refl__free(al, part.meshes);
        refl__free(al, part.objects);
    }
    if (r == REFL_OK && m) m->split_version = p->scene->version;
    return r;
}

static void refl__lem_bvh_caster(refl_ray_caster *caster, refl_bvh *bvh) {
    memset(caster, 0, sizeof *caster);
    caster->intersect = refl__lem_bvh_intersect;
    caster->occluded = refl__lem_bvh_occluded;
    caster->user = bvh;
}

/* What LAYERED_EM casts through: the scene's BVH (the records, the
   layers' hits, direct images, the vertices' visibility) and the split
   ones (refl__lem_split: the vertex paths), in cast[0 .. 3), c pointing at
   them; a BVH the renderer does not keep goes into owned[]. */
static refl_result refl__lem_casters(refl__pass *p, refl_ray_caster cast[3], refl__gp_casters *c, refl_bvh *owned[3]) {
    refl_bvh *bvh = NULL, *split[2] = {NULL, NULL};
    refl_result r = refl__models_bvh(p, &bvh, &owned[0]);
    owned[1] = owned[2] = NULL;
    if (r == REFL_OK) r = refl__lem_split(p, split, owned + 1);
    refl__lem_bvh_caster(&cast[0], bvh);
    refl__lem_bvh_caster(&cast[1], split[0]);
    refl__lem_bvh_caster(&cast[2], split[1]);
    c->scene = &cast[0];
    c->lenses = &cast[1];
    c->others = &cast[2];
    c->own = -1;
    return r;
}

static refl_result refl__method_layered_em(refl__pass *p) {
    const refl_scene *scene = p->scene;
    refl_frame *f = p->frame;
    refl_bvh *owned[3] = {NULL, NULL, NULL};
    refl_ray_caster cast[3];
    refl__gp_casters casters;
    struct refl__lem_maps own, *maps = NULL;
    uint8_t *marked = NULL;
    size_t np = (size_t)f->width * (size_t)f->height, k;
    int i, any = 0;
    rast_targets t = refl__frame_targets(f);
    refl_result r = refl__lem_casters(p, cast, &casters, owned);
    memset(&own, 0, sizeof own);
    if (r == REFL_OK) r = refl__lem_store(p, &own, &maps);
    if (r == REFL_OK) refl__lem_trim(&scene->allocator, maps, refl__lem_kept_bytes(&p->desc.layered_em));
    marked = r == REFL_OK ? (uint8_t *)refl__calloc(&scene->allocator, np, 1) : NULL;
    if (r == REFL_OK && !marked) r = REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i)
        if (refl__pass_draws(p, i)) r = refl__lem_object(p, &casters, i, maps, marked);
    if (r == REFL_OK) r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    for (k = 0; k < np && r == REFL_OK; ++k) any |= marked[k];
    if (r == REFL_OK && any) r = refl__trace_marked(p, marked);
    f->stats.layered_em.maps_held = maps ? maps->count : 0;
    f->stats.model_bytes += refl__lem_maps_bytes(maps);
    refl__lem_maps_clear(&scene->allocator, &own);
    refl__free(&scene->allocator, marked);
    for (i = 0; i < 3; ++i) refl_bvh_destroy(owned[i]);
    return r;
}

/* refl_renderer_lem_lenses' work (render.c sets the pass up): every lens
   object the pass draws, planned as a frame plans it (refl__lem_plan_of). */
static refl_result refl__lem_lenses(refl__pass *p, refl_lem_lens **out, int *count) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl_bvh *owned[3] = {NULL, NULL, NULL};
    refl_ray_caster cast[3];
    refl__gp_casters casters;
    struct refl__lem_maps own, *maps = NULL;
    refl_lem_lens *lenses = NULL;
    int i, s, l, n = 0, lens_count = 0;
    refl_result r = refl__lem_casters(p, cast, &casters, owned);
    *out = NULL;
    *count = 0;
    memset(&own, 0, sizeof own);
    if (r == REFL_OK) r = refl__lem_store(p, &own, &maps);
    if (r == REFL_OK && maps == &own) r = REFL_ERROR_INVALID_ARGUMENT; /* the maps must outlive this call */
    if (r == REFL_OK) refl__lem_trim(al, maps, refl__lem_kept_bytes(&p->desc.layered_em));
    for (i = 0; i < scene->object_count; ++i) lens_count += refl__pass_draws(p, i);
    if (r == REFL_OK && lens_count > 0) {
        lenses = (refl_lem_lens *)refl__calloc(al, (size_t)lens_count, sizeof *lenses);
        if (!lenses) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i) {
        refl_lem_lens *ln;
        refl__lem_plan pl;
        refl__lem_draw dr;
        if (!refl__pass_draws(p, i)) continue;
        ln = &lenses[n++];
        r = refl__lem_plan_of(p, &casters, i, maps, &pl);
        ln->tess = pl.frame_tess;
        if (r != REFL_OK) break;
        ln->object = i;
        ln->terms = pl.terms;
        ln->maps = pl.n;
        refl__lem_draw_box(&dr, pl.box);
        ln->box[0] = dr.lens_box[0];
        ln->box[1] = dr.lens_box[1];
        for (s = 0; s < pl.n; ++s) {
            const refl__lem_map *m = &maps->maps[pl.at[s]];
            ln->weight[s] = pl.weight[s];
            ln->layers = m->layers;
            for (l = 0; l < m->layers; ++l) {
                ln->shell[s][l] = m->shell[l];
                ln->texels[s][l] = refl__lem_layer_texels(maps, m, pl.joint_at[s], l);
            }
        }
    }
    p->frame->stats.layered_em.maps_held = maps && maps != &own ? maps->count : 0;
    refl__lem_maps_clear(al, &own);
    for (i = 0; i < 3; ++i) refl_bvh_destroy(owned[i]);
    if (r != REFL_OK) {
        for (i = 0; i < n; ++i) {
            refl__free(al, lenses[i].tess.vertices);
            refl__free(al, lenses[i].tess.indices);
        }
        refl__free(al, lenses);
        return r;
    }
    *out = lenses;
    *count = n;
    return REFL_OK;
}

/* Every viewpoint sample's map of every lens object the pass draws, on
   the circle through the pass's eye, into the renderer's models; progress
   after each map, cancelled when the callback asks. */
static refl_result refl__prebuild_layered_em(refl__pass *p) {
    const refl_scene *scene = p->scene;
    refl_bvh *owned[3] = {NULL, NULL, NULL};
    refl_ray_caster cast[3];
    refl__gp_casters casters;
    struct refl__lem_maps *maps = NULL, none;
    refl_view views[3];
    int i, k, at, joint_at, lenses = 0, done = 0;
    long long share, last;
    refl_result r = refl__lem_casters(p, cast, &casters, owned);
    memset(&none, 0, sizeof none);
    if (r == REFL_OK) r = refl__lem_store(p, &none, &maps);
    if (r == REFL_OK && maps == &none) r = REFL_ERROR_INVALID_ARGUMENT; /* nowhere to keep them */
    for (i = 0; i < scene->object_count; ++i) lenses += refl__pass_draws(p, i);
    share = refl__lem_kept_bytes(&p->desc.layered_em) / REFL__MAX(lenses, 1);
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i) {
        refl__lem_circle cc;
        refl__lem_ring spare;
        refl__lem_layering lay;
        refl_vec3 box[2], centre;
        float lens_radius;
        int on;
        if (!refl__pass_draws(p, i)) continue;
        refl__lem_bounds(scene, i, &centre, &lens_radius, box);
        memset(&spare, 0, sizeof spare);
        on = refl__lem_ring_of(p, casters.scene, i, centre, lens_radius, maps, &cc, &lay, &spare, &r);
        if (!on && r == REFL_OK) {
            views[0] = *p->view;
            r = refl__lem_sample_maps(p, &casters, i, views, 1, &lay, maps, &at, &joint_at);
        }
        /* nearest the eye first (k0, k0 + 1, k0 - 1, ...), while the maps
           held and one more like the last stay within this lens's share of
           the budget: memory stays bounded whatever layered_em.samples */
        for (k = 0, last = 0; on && k < cc.samples && r == REFL_OK; ++k) {
            int k0 = (int)floor(cc.phi / cc.step), j = k0 + (k % 2 ? (k + 1) / 2 : -(k / 2));
            long long held = refl__lem_maps_bytes(maps);
            if (k > 0 && held + last > share * (done + 1)) break;
            refl__lem_sample_views(p, &cc, (j % cc.samples + cc.samples) % cc.samples, views);
            r = refl__lem_sample_maps(p, &casters, i, views, cc.per, &lay, maps, &at, &joint_at);
            if (r == REFL_OK) last = refl__lem_map_bytes(&maps->maps[at]);
            if (r == REFL_OK && refl__progress(p, ((float)done + (float)(k + 1) / (float)cc.samples) / (float)lenses))
                r = REFL_ERROR_CANCELLED;
        }
        refl__free(&scene->allocator, spare.object_layer);
        ++done;
    }
    p->frame->stats.layered_em.maps_held = maps && maps != &none ? maps->count : 0;
    p->frame->stats.model_bytes += maps && maps != &none ? refl__lem_maps_bytes(maps) : 0;
    for (i = 0; i < 3; ++i) refl_bvh_destroy(owned[i]);
    return r;
}
