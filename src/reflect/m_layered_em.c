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
   3. the frame: the lens tessellated for the eye, drawn once per map with
      per-vertex F G and that map's shell indices of both terms, each
      fragment the map's weight times T F_T G_T + R F_R G_R, the draws
      added over the base pass where the lens shows; lens pixels no
      triangle covered are ray traced.

   Every stage runs in a fixed order or per pixel, and a map depends only on
   what keys it, so any thread count, and a kept map or a fresh one, gives
   the same bytes. Left out (see the issue): several layers by LBG, quads,
   continued rays, direct images. */
#include "internal.h"

/* per term: shell index (3), F G (3); then both terms' presence, and 1 at a
   vertex where a term has an exit ray the shell cannot look up */
enum { REFL__LEM_VARYINGS = 15 };

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
    return NULL;
}

/* The shell's index of an exit ray: its far hit on the sphere minus the
   centre (0: none). An exit ray that starts outside the shell has none: its
   path left the lens through another lens object beyond the shell, where
   the map knows nothing of what the ray meets (the frame hands such pixels
   to the tracer). */
static int refl__lem_index(const refl_lem_shell *sh, refl_vec3 o, refl_vec3 d, refl_vec3 *index) {
    refl_vec3 oc = refl_v3_sub(o, sh->center);
    float b = refl_v3_dot(oc, d), c = refl_v3_dot(oc, oc) - sh->radius * sh->radius, dd = refl_v3_dot(d, d);
    float disc = b * b - c * dd, t;
    if (!(c <= 0.0f) || !(disc >= 0.0f) || !(dd > 0.0f)) return 0;
    t = (-b + sqrtf(disc)) / dd;
    *index = refl_v3_add(oc, refl_v3_scale(d, t));
    return refl__v3_finite(*index) && t >= 0.0f;
}

/* What one draw of the lens shares: the shell, the map it looks up and
   the map's blend weight, and the term drawn in record mode. */
typedef struct refl__lem_draw {
    refl_lem_shell shell;
    const float *map;
    float weight;
    int record_term;             /* 0, 1: write that term's index; -1: shade */
} refl__lem_draw;

static float refl__lem_sample(const refl__lem_draw *dr, refl_vec3 index, int c) {
    uint32_t tex[4];
    float w[4], l = 0.0f;
    int k;
    if (!refl_lem_shell_lookup(&dr->shell, dr->shell.center, index, tex, w)) return 0.0f;
    for (k = 0; k < 4; ++k) l += w[k] * dr->map[4 * tex[k] + (uint32_t)c];
    return l;
}

static int refl__lem_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__lem_draw *dr = (const refl__lem_draw *)user;
    const float *v = in->varyings;
    int term, c;
    if (dr->record_term >= 0) {
        const float *t = v + 6 * dr->record_term;
        rgba[0] = t[0];
        rgba[1] = t[1];
        rgba[2] = t[2];
        rgba[3] = v[12 + dr->record_term];
        return 1;
    }
    rgba[0] = rgba[1] = rgba[2] = 0.0f;
    rgba[3] = v[14] > 0.0f ? 2.0f : 1.0f; /* 2: a vertex's term had no lookup, the pixel is traced */
    for (term = 0; term < 2; ++term) {
        const float *t = v + 6 * term;
        refl_vec3 index = refl_v3(t[0], t[1], t[2]);
        for (c = 0; c < 3; ++c)
            if (t[3 + c] > 0.0f) rgba[c] += t[3 + c] * (dr->weight * refl__lem_sample(dr, index, c));
    }
    return 1;
}

/* Draws tessellation t seen through vp into the w x h RGBA32F colour and
   depth buffers (cleared here), with stencil (may be NULL) tested equal
   to ref. */
static refl_result refl__lem_raster(rast_context *rc, const refl_lens_tess *t, refl_mat4 vp, refl__lem_draw *dr,
                                    float *color, float *depth, uint8_t *stencil, uint8_t ref, int w, int h,
                                    const refl_allocator *al) {
    const int stride = 4 + REFL__LEM_VARYINGS;
    float *verts = (float *)refl__calloc(al, (size_t)REFL__MAX(t->vertex_count, 1) * (size_t)stride, sizeof(float));
    rast_targets tg;
    rast_state s;
    rast_draw_desc d;
    rast_clear_desc clear;
    rast_result rr;
    const float *m = vp.m;
    int i, k, term;
    if (!verts) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < t->vertex_count; ++i) {
        const refl_lens_vertex *v = &t->vertices[i];
        float *o = verts + (size_t)i * (size_t)stride;
        refl_vec3 p = v->position;
        for (k = 0; k < 4; ++k) o[k] = m[k] * p.x + m[4 + k] * p.y + m[8 + k] * p.z + m[12 + k];
        o[4 + 14] = 0.0f;
        for (term = 0; term < 2; ++term) {
            const refl_greedy_path *path = term ? &v->paths.refract : &v->paths.reflect;
            float *q = o + 4 + 6 * term;
            refl_vec3 index = refl_v3(0.0f, 0.0f, 1.0f);
            int exits = path->fresnel > 0.0f && path->exited;
            int has = exits && refl__lem_index(&dr->shell, path->exit_origin, path->exit_direction, &index);
            q[0] = index.x;
            q[1] = index.y;
            q[2] = index.z;
            for (k = 0; k < 3; ++k) q[3 + k] = has ? path->fresnel * path->attenuation[k] : 0.0f;
            o[4 + 12 + term] = (float)has;
            if (exits && !has) o[4 + 14] = 1.0f;
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
    s.fragment_fn = refl__lem_fragment;
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
    d.num_varyings = REFL__LEM_VARYINGS;
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
    refl_vec3 centre;
    int rect[4];                 /* x0, y0, x1, y1: the pixels the lens's bounds may cover */
    float *rec;                  /* 10 per pixel; confidence -1 where none */
    double *row_dist;
    long long *row_hits, *row_rays;
} refl__lem_records;

static void refl__lem_records_row(void *arg, int y) {
    refl__lem_records *r = (refl__lem_records *)arg;
    int x, w = r->rays.width;
    for (x = 0; x < w; ++x) {
        float *out = r->rec + 10 * ((size_t)y * (size_t)w + (size_t)x);
        refl_greedy_paths_result centre;
        if (x < r->rect[0] || x >= r->rect[2] || y < r->rect[1] || y >= r->rect[3] ||
            !refl__lem_pixel_records(r->scene, r->caster, &r->rays, x, y, r->object, r->ss, r->theta_c,
                                     r->max_interfaces, r->centre, out, &centre, &r->row_dist[y], &r->row_hits[y],
                                     &r->row_rays[y]))
            out[4] = out[9] = -1.0f;
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
    float *rec;
    int lens_pixels;
} refl__lem_sample_view;

static void refl__lem_sample_free(const refl_allocator *al, refl__lem_sample_view *s) {
    refl__free(al, s->tess.vertices);
    refl__free(al, s->tess.indices);
    refl__free(al, s->rec);
    memset(s, 0, sizeof *s);
}

/* The world bounds' centre and half diagonal of object i. */
static void refl__lem_bounds(const refl_scene *scene, int i, refl_vec3 *centre, float *radius, refl_vec3 box[2]) {
    const refl_object *o = &scene->objects[i];
    refl_vec3 lo, hi, wlo = refl_v3(FLT_MAX, FLT_MAX, FLT_MAX), whi = refl_v3(-FLT_MAX, -FLT_MAX, -FLT_MAX);
    int k;
    refl_mesh_bounds(scene->meshes[o->mesh], &lo, &hi);
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

/* ---- the maps a renderer keeps ---------------------------------------------------- */

/* One viewpoint sample's inferred map and what shaped it: the lens
   object, the sample's view, the options and the bounces. A map depends on
   nothing else (the scene's version aside, which drops them all), so a
   frame that needs it again takes it as it is. */
typedef struct refl__lem_map {
    int object, depth;
    refl_view view;
    refl_layered_em_options options;
    refl_lem_shell shell;
    float *texels;               /* 4 floats per texel of the shell */
} refl__lem_map;

/* A lens's circle of viewpoint samples as a renderer fixed it. */
typedef struct refl__lem_ring {
    int object;
    float rho, height;
} refl__lem_ring;

struct refl__lem_maps {
    refl__lem_map *maps;
    int count;
    refl__lem_ring *rings;       /* a renderer's: the circle of each lens, from its first frame */
    int ring_count;
};

static void refl__lem_maps_free(const refl_allocator *al, struct refl__lem_maps *m) {
    int k;
    if (!m) return;
    for (k = 0; k < m->count; ++k) refl__free(al, m->maps[k].texels);
    refl__free(al, m->maps);
    refl__free(al, m->rings);
    refl__free(al, m);
}

/* RGBA floats on six faces. */
static long long refl__lem_map_bytes(const refl__lem_map *m) { return 96LL * m->shell.face_size * m->shell.face_size; }

static long long refl__lem_maps_bytes(const struct refl__lem_maps *m) {
    long long b = 0;
    int k;
    for (k = 0; m && k < m->count; ++k) b += refl__lem_map_bytes(&m->maps[k]);
    return b;
}

/* What a renderer keeps of maps at the start of a frame: the oldest go
   first past this (a dolly or a crane makes new samples every frame; a
   dropped map is inferred again, the same bytes, when a frame needs it). */
#define REFL__LEM_KEPT_BYTES (512LL << 20)

static void refl__lem_trim(const refl_allocator *al, struct refl__lem_maps *m) {
    int drop = 0, k;
    long long bytes = refl__lem_maps_bytes(m);
    while (drop < m->count && bytes > REFL__LEM_KEPT_BYTES) {
        bytes -= refl__lem_map_bytes(&m->maps[drop]);
        refl__free(al, m->maps[drop++].texels);
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

/* ---- inferring one sample's map ----------------------------------------------------- */

/* Infers object i's map for the sample whose views are views[0 .. per)
   (the sample's own first): the records and tessellation of each view, the
   shell at the mean distance of their hits, rows from the runtime's own
   lookups at those views, solved by CGLS. out->texels is allocated. */
static refl_result refl__lem_infer(refl__pass *p, const refl_ray_caster *caster, int i, const refl_view *views, int per,
                                   refl__lem_map *out) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    const refl_layered_em_options *o = &p->desc.layered_em;
    refl_stats *st = &p->frame->stats;
    int w = views[0].width, h = views[0].height, s, y, term, face;
    size_t np = (size_t)w * (size_t)h, px;
    refl__lem_sample_view sv[3];
    refl_lens_tess_desc td;
    refl__lem_draw dr;
    refl_lem_system *sys = NULL;
    refl_lem_solve_desc sd;
    refl_vec3 box[2];
    float lens_radius, *depth = NULL, *index[2] = {NULL, NULL};
    double dist = 0.0;
    long long hits = 0;
    refl_result r = REFL_OK;
    memset(sv, 0, sizeof sv);
    memset(&td, 0, sizeof td);
    memset(&dr, 0, sizeof dr);
    td.edge_px = o->edge_px;
    td.angle_degrees = o->angle_degrees;
    td.max_interfaces = p->desc.depth;
    refl__lem_bounds(scene, i, &dr.shell.center, &lens_radius, box);
    /* the records and tessellation of each view, in rows on the pass's threads */
    for (s = 0; s < per && r == REFL_OK; ++s) {
        refl__lem_records rec;
        refl_mat4 vm, pm;
        refl_view_matrices(&views[s], scene, &vm, &pm);
        sv[s].vp = refl_mat4_mul(pm, vm);
        memset(&rec, 0, sizeof rec);
        rec.scene = scene;
        rec.caster = caster;
        refl__view_rays_init(&rec.rays, &views[s], scene);
        rec.object = i;
        rec.ss = o->supersample > 0 ? o->supersample : 1;
        rec.theta_c = o->theta_c_degrees;
        rec.max_interfaces = p->desc.depth;
        rec.centre = dr.shell.center;
        refl__lem_screen_rect(sv[s].vp, box[0], box[1], w, h, rec.rect);
        sv[s].rec = rec.rec = (float *)refl__calloc(al, 10 * np, sizeof(float));
        rec.row_dist = (double *)refl__calloc(al, (size_t)h, sizeof(double));
        rec.row_hits = (long long *)refl__calloc(al, (size_t)h, sizeof(long long));
        rec.row_rays = (long long *)refl__calloc(al, (size_t)h, sizeof(long long));
        if (!rec.rec || !rec.row_dist || !rec.row_hits || !rec.row_rays) r = REFL_ERROR_OUT_OF_MEMORY;
        if (r == REFL_OK) {
            rast_run_jobs(p->rc, h, refl__lem_records_row, &rec);
            for (y = 0; y < h; ++y) {
                dist += rec.row_dist[y];
                hits += rec.row_hits[y];
                st->rays += rec.row_rays[y];
            }
            for (px = 0; px < np; ++px) sv[s].lens_pixels += rec.rec[10 * px + 4] >= 0.0f || rec.rec[10 * px + 9] >= 0.0f;
        }
        refl__free(al, rec.row_dist);
        refl__free(al, rec.row_hits);
        refl__free(al, rec.row_rays);
        if (r == REFL_OK) {
            sv[s].tess.allocator = *al;
            r = refl__lens_tessellate(scene, caster, i, &views[s], &td, p->rc, &sv[s].tess);
            st->rays += sv[s].tess.rays;
        }
    }
    /* the shell: at the mean distance of the records' hits */
    dr.shell.radius = hits > 0 ? (float)(dist / (double)hits) : 0.0f;
    if (!(dr.shell.radius > lens_radius)) dr.shell.radius = REFL__MAX(10.0f * lens_radius, 1e-3f);
    face = o->face_size > 0 ? o->face_size
                            : REFL__CLAMP((int)floor(0.5 * sqrt((double)sv[0].lens_pixels) + 0.5), 8, 256);
    dr.shell.face_size = face;
    out->shell = dr.shell;
    /* rows from the runtime's own lookups at the views */
    if (r == REFL_OK) r = refl_lem_system_create(6 * face * face, al, &sys);
    depth = r == REFL_OK ? (float *)refl__calloc(al, np, sizeof(float)) : NULL;
    for (term = 0; term < 2 && r == REFL_OK; ++term) {
        index[term] = (float *)refl__calloc(al, 4 * np, sizeof(float));
        if (!index[term] || !depth) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    for (s = 0; s < per && r == REFL_OK; ++s) {
        for (term = 0; term < 2 && r == REFL_OK; ++term) {
            dr.record_term = term;
            r = refl__lem_raster(p->rc, &sv[s].tess, sv[s].vp, &dr, index[term], depth, NULL, 0, w, h, al);
        }
        for (px = 0; px < np && r == REFL_OK; ++px)
            for (term = 0; term < 2 && r == REFL_OK; ++term) {
                const float *rec = sv[s].rec + 10 * px + 5 * term, *ix = index[term] + 4 * px;
                uint32_t tex[4];
                float wt[4];
                /* a row where the records have the term and all three vertices gave it an index */
                if (rec[4] < 0.0f || !(ix[3] >= 0.999f) ||
                    !refl_lem_shell_lookup(&dr.shell, dr.shell.center, refl_v3(ix[0], ix[1], ix[2]), tex, wt))
                    continue;
                r = refl_lem_system_add_row(sys, tex, wt, 4, rec, rec[4]);
            }
    }
    out->texels = r == REFL_OK ? (float *)refl__calloc(al, 4 * (size_t)(6 * face * face), sizeof(float)) : NULL;
    if (r == REFL_OK && !out->texels) r = REFL_ERROR_OUT_OF_MEMORY;
    memset(&sd, 0, sizeof sd);
    sd.iterations = o->iterations;
    if (r == REFL_OK) r = refl_lem_solve(sys, &sd, out->texels, NULL);
    refl_lem_system_destroy(sys);
    refl__free(al, index[0]);
    refl__free(al, index[1]);
    refl__free(al, depth);
    for (s = 0; s < 3; ++s) refl__lem_sample_free(al, &sv[s]);
    if (r != REFL_OK) {
        refl__free(al, out->texels);
        out->texels = NULL;
    }
    return r;
}

/* The index in *maps of object i's map for the sample of views[0 .. per):
   the one kept when pass p's renderer has it, else inferred and added. */
static refl_result refl__lem_map_of(refl__pass *p, const refl_ray_caster *caster, int i, const refl_view *views,
                                    int per, struct refl__lem_maps *maps, int *at) {
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
    r = refl__lem_infer(p, caster, i, views, per, &m);
    if (r == REFL_OK && (*at = refl__push(al, (void **)&maps->maps, &maps->count, sizeof m, &m)) < 0) {
        refl__free(al, m.texels);
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
   them, puts the samples at exactly the same views. A renderer fixes each
   lens's circle at the first frame (or prebuild) that draws it (rings),
   as the paper parameterises its maps by one circle: later eyes off it
   take the samples of their azimuth on it. 0 when the eye is on the
   circle's axis (its azimuth undefined). */
typedef struct refl__lem_circle {
    refl_vec3 c;
    float rho, height;
    double step, phi;            /* spacing; the eye's azimuth in [0, 2 pi) */
    int samples, per;            /* per: views a map is inferred from (1, or 3 multi-view) */
} refl__lem_circle;

static int refl__lem_circle_of(const refl__pass *p, int object, refl_vec3 c, float lens_radius,
                               struct refl__lem_maps *rings, refl__lem_circle *out) {
    const refl_view *v = p->view;
    float dx = v->eye.x - c.x, dz = v->eye.z - c.z, rho = sqrtf(dx * dx + dz * dz);
    float grid = REFL__MAX(lens_radius, 1e-6f) / 1024.0f;
    refl__lem_ring ring;
    int k;
    out->c = c;
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
    for (k = 0; rings && k < rings->ring_count; ++k)
        if (rings->rings[k].object == object) {
            out->rho = rings->rings[k].rho;
            out->height = rings->rings[k].height;
            return 1;
        }
    ring.object = object;
    ring.rho = out->rho;
    ring.height = out->height;
    if (rings) refl__push(&p->scene->allocator, (void **)&rings->rings, &rings->ring_count, sizeof ring, &ring);
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

/* Lens object i: the maps of the two samples bracketing the eye (kept or
   inferred), the eye's tessellation drawn once per map, weighed by the
   blend, added over the base pass. marked: lens pixels left to the tracer. */
static refl_result refl__lem_object(refl__pass *p, const refl_ray_caster *caster, int i, struct refl__lem_maps *maps,
                                    uint8_t *marked) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    const refl_layered_em_options *o = &p->desc.layered_em;
    refl_frame *f = p->frame;
    int w = f->width, h = f->height, n = 1, s, k, at[2] = {-1, -1};
    size_t np = (size_t)w * (size_t)h, px;
    refl__lem_circle cc;
    refl__lem_draw dr;
    refl_lens_tess_desc td;
    refl_lens_tess frame_tess;
    refl_vec3 box[2], centre;
    refl_view views[3];
    float weight[2] = {1.0f, 0.0f}, lens_radius, *color[2] = {NULL, NULL}, *depth = NULL;
    uint8_t ref = (uint8_t)(i + 1 < 255 ? i + 1 : 255);
    refl_result r = REFL_OK;
    double t0, t1;
    memset(&frame_tess, 0, sizeof frame_tess);
    memset(&td, 0, sizeof td);
    td.edge_px = o->edge_px;
    td.angle_degrees = o->angle_degrees;
    td.max_interfaces = p->desc.depth;
    refl__lem_bounds(scene, i, &centre, &lens_radius, box);
    if (!refl__lem_circle_of(p, i, centre, lens_radius, p->models ? maps : NULL, &cc)) {
        /* on the axis: the eye's own view, one map */
        views[0] = *p->view;
        r = refl__lem_map_of(p, caster, i, views, 1, maps, &at[0]);
    } else {
        double fk = cc.phi / cc.step;
        int k0 = (int)floor(fk);
        weight[1] = (float)(fk - k0);
        weight[0] = 1.0f - weight[1];
        n = weight[1] > 0.0f ? 2 : 1;
        for (s = 0; s < n && r == REFL_OK; ++s) {
            refl__lem_sample_views(p, &cc, k0 + s, views);
            r = refl__lem_map_of(p, caster, i, views, cc.per, maps, &at[s]);
        }
    }
    t0 = refl__now_ms();
    for (s = 0; s < n && r == REFL_OK; ++s)
        if (!(color[s] = (float *)refl__calloc(al, 4 * np, sizeof(float)))) r = REFL_ERROR_OUT_OF_MEMORY;
    depth = (float *)refl__calloc(al, np, sizeof(float));
    if (!depth) r = REFL_ERROR_OUT_OF_MEMORY;
    /* the frame: tessellated for the eye, both terms from each map */
    if (r == REFL_OK) {
        t1 = refl__now_ms();
        frame_tess.allocator = *al;
        r = refl__lens_tessellate(scene, caster, i, p->view, &td, p->rc, &frame_tess);
        f->stats.rays += frame_tess.rays;
        f->stats.triangles += frame_tess.triangle_count;
        f->stats.layered_em.vertices += frame_tess.vertex_count;
        f->stats.layered_em.ms_trace += frame_tess.ms_trace;
        f->stats.layered_em.ms_tessellate += refl__now_ms() - t1 - frame_tess.ms_trace;
    }
    t1 = refl__now_ms();
    for (s = 0; s < n && r == REFL_OK; ++s) {
        const refl__lem_map *m = &maps->maps[at[s]];
        memset(&dr, 0, sizeof dr);
        dr.shell = m->shell;
        dr.map = m->texels;
        dr.weight = weight[s];
        dr.record_term = -1;
        r = refl__lem_raster(p->rc, &frame_tess, p->vp, &dr, color[s], depth, f->stencil, ref, w, h, al);
    }
    for (px = 0; px < np && r == REFL_OK; ++px) {
        if (f->stencil[px] != ref) continue;
        if (!(color[0][4 * px + 3] > 0.0f) || color[0][4 * px + 3] > 1.0f || (n > 1 && color[1][4 * px + 3] > 1.0f)) {
            marked[px] = 1; /* no triangle here, or an exit ray off the maps: traced */
            f->stats.layered_em.traced_pixels++;
            continue;
        }
        for (s = 0; s < n; ++s)
            for (k = 0; k < 3; ++k) f->rgba[4 * px + (size_t)k] += color[s][4 * px + (size_t)k];
    }
    f->stats.layered_em.ms_draw += refl__now_ms() - t1;
    f->stats.ms_reflect += refl__now_ms() - t0;
    refl__free(al, frame_tess.vertices);
    refl__free(al, frame_tess.indices);
    refl__free(al, color[0]);
    refl__free(al, color[1]);
    refl__free(al, depth);
    return r;
}

/* The ray caster over the scene's BVH (kept by the renderer, else *owned). */
static refl_result refl__lem_caster(refl__pass *p, refl_ray_caster *caster, refl_bvh **owned) {
    refl_bvh *bvh = NULL;
    refl_result r = refl__models_bvh(p, &bvh, owned);
    memset(caster, 0, sizeof *caster);
    caster->intersect = refl__lem_bvh_intersect;
    caster->occluded = refl__lem_bvh_occluded;
    caster->user = bvh;
    return r;
}

static refl_result refl__method_layered_em(refl__pass *p) {
    const refl_scene *scene = p->scene;
    refl_frame *f = p->frame;
    refl_bvh *owned = NULL;
    refl_ray_caster caster;
    struct refl__lem_maps own, *maps = NULL;
    uint8_t *marked = NULL;
    size_t np = (size_t)f->width * (size_t)f->height, k;
    int i, any = 0;
    rast_targets t = refl__frame_targets(f);
    refl_result r = refl__lem_caster(p, &caster, &owned);
    memset(&own, 0, sizeof own);
    if (r == REFL_OK) r = refl__lem_store(p, &own, &maps);
    if (r == REFL_OK) refl__lem_trim(&scene->allocator, maps);
    marked = r == REFL_OK ? (uint8_t *)refl__calloc(&scene->allocator, np, 1) : NULL;
    if (r == REFL_OK && !marked) r = REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i)
        if (refl__pass_draws(p, i)) r = refl__lem_object(p, &caster, i, maps, marked);
    if (r == REFL_OK) r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    for (k = 0; k < np && r == REFL_OK; ++k) any |= marked[k];
    if (r == REFL_OK && any) r = refl__trace_marked(p, marked);
    f->stats.layered_em.maps_held = maps ? maps->count : 0;
    f->stats.model_bytes += refl__lem_maps_bytes(maps);
    for (k = 0; k < (size_t)own.count; ++k) refl__free(&scene->allocator, own.maps[k].texels);
    refl__free(&scene->allocator, own.maps);
    refl__free(&scene->allocator, marked);
    refl_bvh_destroy(owned);
    return r;
}

/* Every viewpoint sample's map of every lens object the pass draws, on
   the circle through the pass's eye, into the renderer's models; progress
   after each map, cancelled when the callback asks. */
static refl_result refl__prebuild_layered_em(refl__pass *p) {
    const refl_scene *scene = p->scene;
    refl_bvh *owned = NULL;
    refl_ray_caster caster;
    struct refl__lem_maps *maps = NULL, none;
    refl_view views[3];
    int i, k, at, lenses = 0, done = 0;
    refl_result r = refl__lem_caster(p, &caster, &owned);
    memset(&none, 0, sizeof none);
    if (r == REFL_OK) r = refl__lem_store(p, &none, &maps);
    if (r == REFL_OK && maps == &none) r = REFL_ERROR_INVALID_ARGUMENT; /* nowhere to keep them */
    for (i = 0; i < scene->object_count; ++i) lenses += refl__pass_draws(p, i);
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i) {
        refl__lem_circle cc;
        refl_vec3 box[2], centre;
        float lens_radius;
        if (!refl__pass_draws(p, i)) continue;
        refl__lem_bounds(scene, i, &centre, &lens_radius, box);
        if (!refl__lem_circle_of(p, i, centre, lens_radius, maps, &cc)) {
            views[0] = *p->view;
            r = refl__lem_map_of(p, &caster, i, views, 1, maps, &at);
            ++done;
            continue;
        }
        for (k = 0; k < cc.samples && r == REFL_OK; ++k) {
            refl__lem_sample_views(p, &cc, k, views);
            r = refl__lem_map_of(p, &caster, i, views, cc.per, maps, &at);
            if (r == REFL_OK && refl__progress(p, ((float)done + (float)(k + 1) / (float)cc.samples) / (float)lenses))
                r = REFL_ERROR_CANCELLED;
        }
        ++done;
    }
    p->frame->stats.layered_em.maps_held = maps && maps != &none ? maps->count : 0;
    p->frame->stats.model_bytes += maps && maps != &none ? refl__lem_maps_bytes(maps) : 0;
    refl_bvh_destroy(owned);
    return r;
}
