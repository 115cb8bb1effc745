/* LAYERED_EM: Hakura and Snyder's hybrid rendering (paper 001) with one
   environment layer. Per lens object (a reflector of this pass) and frame:

   1. the viewpoint samples: points on a circle around the lens's centre
      through the eye, at its height, `samples` of them evenly; the two
      bracketing the eye's azimuth are used, blended by angular distance;
   2. per sample, the records (section 4.1: greedy paths of every lens
      pixel, the radiance where their exit rays meet the scene) give the
      targets; the shell's radius is the mean distance of those hits from
      the centre (LBG with one cluster);
   3. per sample, the lens is tessellated (lens_tess.c) and drawn with
      rast.h at the sample's view, interpolating each vertex's shell index
      (exit ray's hit on the shell minus the centre) as the runtime does:
      each pixel's lookup of that index is its row of the rendering matrix,
      so the matrix is exactly how the runtime samples the map; C A x = C b
      is solved by CGLS (lem_infer.c);
   4. the frame: the lens tessellated for the eye, drawn with per-vertex
      F G and shell indices of both terms, each fragment T F_T G_T + R F_R
      G_R from the blended maps, added over the base pass where the lens
      shows; lens pixels no triangle covered are ray traced.

   Every stage runs in a fixed order or per pixel, so any thread count
   gives the same bytes. Left out (see the issue): several layers by LBG,
   quads, continued rays, multi-view and direct images, maps kept across
   frames. */
#include "internal.h"

enum { REFL__LEM_VARYINGS = 14 }; /* per term: shell index (3), F G (3); then both terms' presence */

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
   centre (0: none). */
static int refl__lem_index(const refl_lem_shell *sh, refl_vec3 o, refl_vec3 d, refl_vec3 *index) {
    refl_vec3 oc = refl_v3_sub(o, sh->center);
    float b = refl_v3_dot(oc, d), c = refl_v3_dot(oc, oc) - sh->radius * sh->radius, dd = refl_v3_dot(d, d);
    float disc = b * b - c * dd, t;
    if (!(disc >= 0.0f) || !(dd > 0.0f)) return 0;
    t = (-b + sqrtf(disc)) / dd;
    *index = refl_v3_add(oc, refl_v3_scale(d, t));
    return refl__v3_finite(*index) && t >= 0.0f;
}

/* What the lens's draws share: the shell, the maps of the samples and
   their blend weights, and the term drawn in record mode. */
typedef struct refl__lem_draw {
    refl_lem_shell shell;
    const float *maps[2];
    float weight[2];
    int record_term;             /* 0, 1: write that term's index; -1: shade */
} refl__lem_draw;

static float refl__lem_sample(const refl__lem_draw *dr, const float *map, refl_vec3 index, int c) {
    uint32_t tex[4];
    float w[4], l = 0.0f;
    int k;
    if (!refl_lem_shell_lookup(&dr->shell, dr->shell.center, index, tex, w)) return 0.0f;
    for (k = 0; k < 4; ++k) l += w[k] * map[4 * tex[k] + (uint32_t)c];
    return l;
}

static int refl__lem_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__lem_draw *dr = (const refl__lem_draw *)user;
    const float *v = in->varyings;
    int term, c, s;
    if (dr->record_term >= 0) {
        const float *t = v + 6 * dr->record_term;
        rgba[0] = t[0];
        rgba[1] = t[1];
        rgba[2] = t[2];
        rgba[3] = v[12 + dr->record_term];
        return 1;
    }
    rgba[0] = rgba[1] = rgba[2] = 0.0f;
    rgba[3] = 1.0f;
    for (term = 0; term < 2; ++term) {
        const float *t = v + 6 * term;
        refl_vec3 index = refl_v3(t[0], t[1], t[2]);
        for (c = 0; c < 3; ++c) {
            float l = 0.0f;
            if (!(t[3 + c] > 0.0f)) continue;
            for (s = 0; s < 2; ++s)
                if (dr->weight[s] > 0.0f) l += dr->weight[s] * refl__lem_sample(dr, dr->maps[s], index, c);
            rgba[c] += t[3 + c] * l;
        }
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
        for (term = 0; term < 2; ++term) {
            const refl_greedy_path *path = term ? &v->paths.refract : &v->paths.reflect;
            float *q = o + 4 + 6 * term;
            refl_vec3 index = refl_v3(0.0f, 0.0f, 1.0f);
            int has = path->fresnel > 0.0f && path->exited &&
                      refl__lem_index(&dr->shell, path->exit_origin, path->exit_direction, &index);
            q[0] = index.x;
            q[1] = index.y;
            q[2] = index.z;
            for (k = 0; k < 3; ++k) q[3 + k] = has ? path->fresnel * path->attenuation[k] : 0.0f;
            o[4 + 12 + term] = (float)has;
        }
    }
    memset(&tg, 0, sizeof tg);
    tg.color.ptr = color;
    tg.color.width = w;
    tg.color.height = h;
    tg.color.stride = 4 * (int)sizeof(float) * w;
    tg.color_format = RAST_COLOR_RGBA32F;
    tg.depth.ptr = depth;
    tg.depth.width = w;
    tg.depth.height = h;
    tg.depth.stride = (int)sizeof(float) * w;
    if (stencil) {
        tg.stencil.ptr = stencil;
        tg.stencil.width = w;
        tg.stencil.height = h;
        tg.stencil.stride = w;
    }
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
    const refl_view *view;
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
    int x, w = r->view->width;
    for (x = 0; x < w; ++x) {
        float *out = r->rec + 10 * ((size_t)y * (size_t)w + (size_t)x);
        refl_greedy_paths_result centre;
        if (x < r->rect[0] || x >= r->rect[2] || y < r->rect[1] || y >= r->rect[3] ||
            !refl__lem_pixel_records(r->scene, r->caster, r->view, x, y, r->object, r->ss, r->theta_c,
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

/* One viewpoint sample of a lens object. */
typedef struct refl__lem_sample_view {
    refl_view view;
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

/* The views whose records infer the maps of the two samples bracketing
   the eye's azimuth around centre c: per sample, the sample itself and,
   with multi-view inference, the views half a spacing either side (the
   paper's simultaneous inference against disocclusion), `per` views per
   sample; the samples' blend weights. One sample, the eye's own view, when
   the eye is on the circle's axis. The sample count. */
static int refl__lem_views(const refl__pass *p, refl_vec3 c, int samples, int multiview, refl_view out[6], int *per,
                           float weight[2]) {
    const refl_view *v = p->view;
    float dx = v->eye.x - c.x, dz = v->eye.z - c.z, rho = sqrtf(dx * dx + dz * dz);
    double step = 2.0 * REFL__PI / samples, phi = atan2((double)dx, (double)dz), f;
    int k0, k, j, n;
    for (k = 0; k < 6; ++k) out[k] = *v;
    weight[0] = 1.0f;
    weight[1] = 0.0f;
    *per = 1;
    if (!(rho > 1e-6f * (1.0f + refl_v3_length(refl_v3_sub(v->eye, c))))) return 1;
    if (phi < 0.0) phi += 2.0 * REFL__PI;
    f = phi / step;
    k0 = (int)floor(f);
    weight[1] = (float)(f - k0);
    weight[0] = 1.0f - weight[1];
    n = weight[1] > 0.0f ? 2 : 1;
    *per = multiview ? 3 : 1;
    for (k = 0; k < n; ++k)
        for (j = 0; j < *per; ++j) {
            refl_view *o = &out[k * *per + j];
            double a = (k0 + k) * step + (j == 0 ? 0.0 : j == 1 ? -0.5 * step : 0.5 * step);
            o->eye = refl_v3(c.x + rho * (float)sin(a), v->eye.y, c.z + rho * (float)cos(a));
            o->target = c;
        }
    return n;
}

/* Lens object i: samples, maps, the frame's draw. marked: lens pixels
   left to the tracer. */
static refl_result refl__lem_object(refl__pass *p, const refl_ray_caster *caster, int i, uint8_t *marked) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    const refl_layered_em_options *o = &p->desc.layered_em;
    refl_frame *f = p->frame;
    int w = f->width, h = f->height, n, s, k, y, term, face, per, nv, j;
    size_t np = (size_t)w * (size_t)h, px;
    refl__lem_sample_view sv[6];
    refl_view views[6];
    refl__lem_draw dr;
    refl_lens_tess_desc td;
    refl_lens_tess frame_tess;
    refl_vec3 box[2];
    float weight[2], lens_radius, *color = NULL, *depth = NULL, *maps[2] = {NULL, NULL};
    double dist = 0.0;
    long long hits = 0;
    uint8_t ref = (uint8_t)(i + 1 < 255 ? i + 1 : 255);
    refl_result r = REFL_OK;
    double t0 = refl__now_ms();
    memset(sv, 0, sizeof sv);
    memset(&frame_tess, 0, sizeof frame_tess);
    memset(&dr, 0, sizeof dr);
    memset(&td, 0, sizeof td);
    td.edge_px = o->edge_px;
    td.angle_degrees = o->angle_degrees;
    td.max_interfaces = p->desc.depth;
    refl__lem_bounds(scene, i, &dr.shell.center, &lens_radius, box);
    n = refl__lem_views(p, dr.shell.center, o->samples > 0 ? o->samples : 45, !o->single_view, views, &per, weight);
    nv = n * per;
    color = (float *)refl__calloc(al, 4 * np, sizeof(float));
    depth = (float *)refl__calloc(al, np, sizeof(float));
    if (!color || !depth) r = REFL_ERROR_OUT_OF_MEMORY;
    /* the records of each view, in rows on the pass's threads */
    for (s = 0; s < nv && r == REFL_OK; ++s) {
        refl__lem_records rec;
        refl_mat4 vm, pm;
        sv[s].view = views[s];
        refl_view_matrices(&sv[s].view, scene, &vm, &pm);
        sv[s].vp = refl_mat4_mul(pm, vm);
        memset(&rec, 0, sizeof rec);
        rec.scene = scene;
        rec.caster = caster;
        rec.view = &sv[s].view;
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
                f->stats.rays += rec.row_rays[y];
            }
            for (px = 0; px < np; ++px) sv[s].lens_pixels += rec.rec[10 * px + 4] >= 0.0f || rec.rec[10 * px + 9] >= 0.0f;
        }
        refl__free(al, rec.row_dist);
        refl__free(al, rec.row_hits);
        refl__free(al, rec.row_rays);
        if (r == REFL_OK) {
            sv[s].tess.allocator = *al;
            r = refl__lens_tessellate(scene, caster, i, &sv[s].view, &td, p->rc, &sv[s].tess);
            f->stats.rays += sv[s].tess.rays;
        }
    }
    /* the one shell: at the mean distance of the records' hits */
    dr.shell.radius = hits > 0 ? (float)(dist / (double)hits) : 0.0f;
    if (!(dr.shell.radius > lens_radius)) dr.shell.radius = REFL__MAX(10.0f * lens_radius, 1e-3f);
    face = o->face_size > 0 ? o->face_size
                            : REFL__CLAMP((int)floor(0.5 * sqrt((double)sv[0].lens_pixels) + 0.5), 8, 256);
    dr.shell.face_size = face;
    /* each sample's map: rows from the runtime's own lookups at its views */
    for (s = 0; s < n && r == REFL_OK; ++s) {
        refl_lem_system *sys = NULL;
        refl_lem_solve_desc sd;
        float *index[2] = {NULL, NULL};
        r = refl_lem_system_create(6 * face * face, al, &sys);
        for (term = 0; term < 2 && r == REFL_OK; ++term) {
            index[term] = (float *)refl__calloc(al, 4 * np, sizeof(float));
            if (!index[term]) r = REFL_ERROR_OUT_OF_MEMORY;
        }
        for (j = 0; j < per && r == REFL_OK; ++j) {
            const refl__lem_sample_view *view = &sv[s * per + j];
            for (term = 0; term < 2 && r == REFL_OK; ++term) {
                dr.record_term = term;
                r = refl__lem_raster(p->rc, &view->tess, view->vp, &dr, index[term], depth, NULL, 0, w, h, al);
            }
            for (px = 0; px < np && r == REFL_OK; ++px)
                for (term = 0; term < 2 && r == REFL_OK; ++term) {
                    const float *rec = view->rec + 10 * px + 5 * term, *ix = index[term] + 4 * px;
                    uint32_t tex[4];
                    float wt[4];
                    /* a row where the records have the term and all three vertices gave it an index */
                    if (rec[4] < 0.0f || !(ix[3] >= 0.999f) ||
                        !refl_lem_shell_lookup(&dr.shell, dr.shell.center, refl_v3(ix[0], ix[1], ix[2]), tex, wt))
                        continue;
                    r = refl_lem_system_add_row(sys, tex, wt, 4, rec, rec[4]);
                }
        }
        maps[s] = r == REFL_OK ? (float *)refl__calloc(al, 4 * (size_t)(6 * face * face), sizeof(float)) : NULL;
        if (r == REFL_OK && !maps[s]) r = REFL_ERROR_OUT_OF_MEMORY;
        memset(&sd, 0, sizeof sd);
        sd.iterations = o->iterations;
        if (r == REFL_OK) r = refl_lem_solve(sys, &sd, maps[s], NULL);
        refl_lem_system_destroy(sys);
        refl__free(al, index[0]);
        refl__free(al, index[1]);
    }
    f->stats.ms_build += refl__now_ms() - t0;
    t0 = refl__now_ms();
    /* the frame: tessellated for the eye, both terms from the blended maps */
    if (r == REFL_OK) {
        frame_tess.allocator = *al;
        r = refl__lens_tessellate(scene, caster, i, p->view, &td, p->rc, &frame_tess);
        f->stats.rays += frame_tess.rays;
        f->stats.triangles += frame_tess.triangle_count;
    }
    if (r == REFL_OK) {
        dr.record_term = -1;
        for (s = 0; s < 2; ++s) {
            dr.maps[s] = s < n ? maps[s] : NULL;
            dr.weight[s] = s < n ? weight[s] : 0.0f;
        }
        r = refl__lem_raster(p->rc, &frame_tess, p->vp, &dr, color, depth, f->stencil, ref, w, h, al);
    }
    for (px = 0; px < np && r == REFL_OK; ++px) {
        if (f->stencil[px] != ref) continue;
        if (!(color[4 * px + 3] > 0.0f)) {
            marked[px] = 1; /* no triangle here: traced */
            continue;
        }
        for (k = 0; k < 3; ++k) f->rgba[4 * px + (size_t)k] += color[4 * px + (size_t)k];
    }
    f->stats.ms_reflect += refl__now_ms() - t0;
    refl__free(al, frame_tess.vertices);
    refl__free(al, frame_tess.indices);
    for (s = 0; s < 6; ++s) refl__lem_sample_free(al, &sv[s]);
    refl__free(al, maps[0]);
    refl__free(al, maps[1]);
    refl__free(al, color);
    refl__free(al, depth);
    return r;
}

static refl_result refl__method_layered_em(refl__pass *p) {
    const refl_scene *scene = p->scene;
    refl_frame *f = p->frame;
    refl_bvh *bvh = NULL, *owned = NULL;
    refl_ray_caster caster;
    uint8_t *marked = NULL;
    size_t np = (size_t)f->width * (size_t)f->height, k;
    int i, any = 0;
    refl_result r = refl__models_bvh(p, &bvh, &owned);
    rast_targets t = refl__frame_targets(f);
    if (r != REFL_OK) return r;
    memset(&caster, 0, sizeof caster);
    caster.intersect = refl__lem_bvh_intersect;
    caster.occluded = refl__lem_bvh_occluded;
    caster.user = bvh;
    marked = (uint8_t *)refl__calloc(&scene->allocator, np, 1);
    if (!marked) r = REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i)
        if (refl__is_reflector(&scene->materials[scene->objects[i].material]) && refl__pass_draws(p, i))
            r = refl__lem_object(p, &caster, i, marked);
    if (r == REFL_OK) r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    for (k = 0; k < np && r == REFL_OK; ++k) any |= marked[k];
    if (r == REFL_OK && any) r = refl__trace_marked(p, marked);
    refl__free(&scene->allocator, marked);
    refl_bvh_destroy(owned);
    return r;
}
