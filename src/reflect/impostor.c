/* impostor: the generic non-pinhole impostor of paper 004, section 3 (api.h,
   refl_impostor). Construction (3.1): each object's mesh, subdivided in
   object space until its edges are about max_edge_px texels long (a texel
   measured as the bounding sphere's diameter over the image width), is
   drawn with a vertex program that projects world points through the
   camera and writes w = 1, so colour, depth and normals interpolate
   affinely in the image; a second pass with depth EQUAL stores normals.
   With several layers, each further layer is peeled: the nearest surface
   behind the layer before it, texel by texel. Intersection (3.2) walks the
   ray in 3-D and compares in (t, gd) with every layer, with the skin test
   the paper leaves out (refl_impostor_intersect in api.h). */
#include "internal.h"

/* One object's draw: the base pass's context (mesh: the subdivided one),
   then the camera, and the depth layer being peeled behind (NULL: none). */
typedef struct refl__imp_draw {
    refl__draw_ctx dc;
    const refl_impostor_camera *cam;
    const float *peel;
} refl__imp_draw;

static int refl__imp_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out) {
    const refl__imp_draw *d = (const refl__imp_draw *)user;
    const refl_mesh *m = d->dc.mesh;
    refl_vec3 p = refl_v3(vertex[0], vertex[1], vertex[2]);
    refl_vec3 n = refl_v3(m->normals[3 * index], m->normals[3 * index + 1], m->normals[3 * index + 2]);
    refl_vec3 wp = refl_mat4_point(d->dc.model, p), wn = refl_mat4_dir(d->dc.normal_m, n);
    float uvd[3];
    (void)max_out;
    if (!d->cam->project(d->cam->cam, wp, uvd)) return 0;
    out->position[0] = 2.0f * uvd[0] / (float)d->cam->width - 1.0f;
    out->position[1] = 1.0f - 2.0f * uvd[1] / (float)d->cam->height;
    out->position[2] = 2.0f * uvd[2] - 1.0f;
    out->position[3] = 1.0f;
    out->varyings[0] = wp.x; out->varyings[1] = wp.y; out->varyings[2] = wp.z;
    out->varyings[3] = wn.x; out->varyings[4] = wn.y; out->varyings[5] = wn.z;
    out->varyings[6] = m->texcoords ? m->texcoords[2 * index] : 0.0f;
    out->varyings[7] = m->texcoords ? m->texcoords[2 * index + 1] : 0.0f;
    return 1;
}

/* The colour pass shades with the shared diffuse model; alpha 1 marks a
   stored texel. */
static int refl__imp_color_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__draw_ctx *d = (const refl__draw_ctx *)user;
    const float *v = in->varyings;
    float rgb[3];
    int c;
    refl_shade_diffuse(d->scene, d->material, refl_v3(v[0], v[1], v[2]), refl_v3(v[3], v[4], v[5]), v + 6, rgb);
    for (c = 0; c < 3; ++c) rgba[c] = REFL__RADIANCE(rgb[c]);
    rgba[3] = 1.0f;
    return 1;
}

/* A peeled layer keeps only what lies behind the layer before it (which
   has a surface there: nothing lies behind an empty texel). */
static int refl__imp_peel_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__imp_draw *d = (const refl__imp_draw *)user;
    float before = d->peel[(size_t)in->y * (size_t)d->cam->width + (size_t)in->x];
    if (!(in->z > before) || before >= 1.0f) return 0;
    return refl__imp_color_fragment(user, in, rgba);
}

static int refl__imp_normal_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    refl_vec3 n = refl_v3_normalize(refl_v3(in->varyings[3], in->varyings[4], in->varyings[5]));
    (void)user;
    rgba[0] = n.x;
    rgba[1] = n.y;
    rgba[2] = n.z;
    rgba[3] = 1.0f;
    return 1;
}

static int refl__imp_spoc_project(const void *cam, refl_vec3 p, float out[3]) {
    return refl_spoc_project((const refl_spoc *)cam, p, out);
}
static int refl__imp_spoc_unproject(const void *cam, const float uvd[3], refl_vec3 *out) {
    return refl_spoc_unproject((const refl_spoc *)cam, uvd, out);
}

REFL_API refl_impostor_camera refl_spoc_impostor_camera(const refl_spoc *cam) {
    refl_impostor_camera c;
    memset(&c, 0, sizeof c);
    if (!cam) return c;
    c.project = refl__imp_spoc_project;
    c.unproject = refl__imp_spoc_unproject;
    c.cam = cam;
    c.width = c.height = cam->size;
    c.center = cam->center;
    c.radius = cam->radius;
    return c;
}

/* The largest factor by which the transform stretches lengths (its
   columns' lengths bound it for the rigid and scaled transforms scenes use). */
static float refl__imp_scale(refl_mat4 m) {
    float s = 0.0f;
    int c;
    for (c = 0; c < 3; ++c)
        s = REFL__MAX(s, sqrtf(m.m[4 * c] * m.m[4 * c] + m.m[4 * c + 1] * m.m[4 * c + 1] + m.m[4 * c + 2] * m.m[4 * c + 2]));
    return s > 0.0f ? s : 1.0f;
}

/* Draws the objects into the impostor's buffers with rc: per layer, the
   colour pass (layers after the first peeled behind the one before), then
   with normals the normal pass (depth EQUAL). */
static refl_result refl__imp_draw_all(rast_context *rc, const refl_scene *scene, const int *objects, int count,
                                      refl_impostor *imp, float max_edge_px, int normals) {
    const refl_allocator *al = &scene->allocator;
    refl_mesh **sub = (refl_mesh **)refl__calloc(al, (size_t)REFL__MAX(count, 1), sizeof(refl_mesh *));
    refl__imp_draw *draws = (refl__imp_draw *)refl__calloc(al, (size_t)REFL__MAX(count, 1), sizeof(refl__imp_draw));
    float *scratch = NULL;
    float texel = 2.0f * imp->camera.radius / (float)imp->camera.width;
    size_t nn = (size_t)imp->width * (size_t)imp->height;
    refl_result r = REFL_OK;
    rast_result rr = RAST_OK;
    rast_targets t;
    rast_state s;
    rast_clear_desc cl;
    int i, pass, layer;
    if (!sub || !draws) r = REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; r == REFL_OK && i < count; ++i) {
        const refl_object *o = &scene->objects[objects[i]];
        float edge = max_edge_px * texel / refl__imp_scale(o->transform);
        r = refl_mesh_subdivide(scene->meshes[o->mesh], edge, &sub[i]);
        if (r != REFL_OK) break;
        refl__draw_ctx_init(&draws[i].dc, scene, objects[i], refl_mat4_identity());
        draws[i].dc.mesh = sub[i];
        draws[i].cam = &imp->camera;
        imp->triangles += sub[i]->triangle_count;
    }
    if (r == REFL_OK && normals) {
        scratch = (float *)refl__calloc(al, nn, 4 * sizeof(float));
        if (!scratch) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    for (layer = 0; r == REFL_OK && rr == RAST_OK && layer < imp->layers; ++layer) {
        float *color = imp->color + 4 * nn * (size_t)layer, *depth = imp->depth + nn * (size_t)layer;
        for (i = 0; i < count; ++i) draws[i].peel = layer ? depth - nn : NULL;
        for (pass = 0; pass < (normals ? 2 : 1); ++pass) {
            t = refl__float_targets(pass ? scratch : color, depth, NULL, imp->width, imp->height);
            if ((rr = rast_set_targets(rc, &t)) != RAST_OK) break;
            memset(&s, 0, sizeof s);
            if ((rr = rast_set_state(rc, &s)) != RAST_OK) break;
            memset(&cl, 0, sizeof cl);
            cl.flags = pass ? RAST_CLEAR_COLOR : RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH;
            cl.depth = 1.0f;
            if ((rr = rast_clear(rc, &cl)) != RAST_OK) break;
            s.depth_test = 1;
            s.depth_func = pass ? RAST_EQUAL : RAST_LESS;
            s.depth_write_disabled = pass;
            s.vertex_fn = refl__imp_vertex;
            s.fragment_fn = pass ? refl__imp_normal_fragment : layer ? refl__imp_peel_fragment : refl__imp_color_fragment;
            for (i = 0; i < count; ++i) {
                s.vertex_user = s.fragment_user = &draws[i];
                if ((rr = rast_set_state(rc, &s)) != RAST_OK ||
                    (rr = refl__draw_mesh(rc, sub[i], NULL, 0, REFL__BASE_VARYINGS)) != RAST_OK)
                    break;
            }
            if (rr == RAST_OK) rr = rast_finish(rc);
            if (rr != RAST_OK) break;
            if (pass) {
                float *normal = imp->normal + 3 * nn * (size_t)layer;
                size_t k;
                for (k = 0; k < nn; ++k) {
                    normal[3 * k] = scratch[4 * k];
                    normal[3 * k + 1] = scratch[4 * k + 1];
                    normal[3 * k + 2] = scratch[4 * k + 2];
                }
            }
        }
    }
    if (r == REFL_OK && rr != RAST_OK) r = refl__result_from_rast(rr);
    /* unbind: nothing queued may point at the buffers freed here */
    memset(&t, 0, sizeof t);
    rast_set_targets(rc, &t);
    for (i = 0; sub && i < count; ++i) refl_mesh_destroy(sub[i]);
    refl__free(al, sub);
    refl__free(al, draws);
    refl__free(al, scratch);
    return r;
}

/* Builds with a caller's rast context (the methods', with their threads). */
static refl_result refl__impostor_build(rast_context *rc, const refl_scene *scene, const int *objects, int count,
                                        const refl_impostor_camera *camera, const refl_impostor_desc *desc,
                                        refl_impostor **out) {
    const refl_allocator *al = desc && (desc->allocator.alloc || desc->allocator.free) ? &desc->allocator
                                                                                        : &scene->allocator;
    refl_impostor *imp;
    size_t nn;
    float max_edge = desc && desc->max_edge_px > 0.0f ? desc->max_edge_px : 4.0f;
    int i, normals = desc && desc->normals, layers = desc && desc->layers > 0 ? desc->layers : 1;
    refl_result r;
    *out = NULL;
    if (layers > REFL_IMPOSTOR_MAX_LAYERS) return REFL_ERROR_INVALID_ARGUMENT;
    if (!camera->project || !camera->unproject || camera->width < 1 || camera->height < 1 ||
        camera->width > 16384 || camera->height > 16384 || !(camera->radius > 0.0f))
        return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < count; ++i)
        if (objects[i] < 0 || objects[i] >= scene->object_count) return REFL_ERROR_INVALID_ARGUMENT;
    imp = (refl_impostor *)refl__calloc(al, 1, sizeof *imp);
    if (!imp) return REFL_ERROR_OUT_OF_MEMORY;
    imp->allocator = *al;
    imp->width = camera->width;
    imp->height = camera->height;
    imp->layers = layers;
    imp->camera = *camera;
    imp->depth_tolerance = 4.0f / (float)camera->width;
    nn = (size_t)imp->width * (size_t)imp->height * (size_t)layers;
    imp->color = (float *)refl__calloc(al, nn, 4 * sizeof(float));
    imp->depth = (float *)refl__calloc(al, nn, sizeof(float));
    if (normals) imp->normal = (float *)refl__calloc(al, nn, 3 * sizeof(float));
    if (!imp->color || !imp->depth || (normals && !imp->normal)) r = REFL_ERROR_OUT_OF_MEMORY;
    else r = refl__imp_draw_all(rc, scene, objects, count, imp, max_edge, normals);
    if (r != REFL_OK) {
        refl_impostor_destroy(imp);
        return r;
    }
    *out = imp;
    return REFL_OK;
}

REFL_API refl_result refl_impostor_build(const refl_scene *scene, const int *objects, int count,
                                         const refl_impostor_camera *camera, const refl_impostor_desc *desc,
                                         refl_impostor **out) {
    rast_context *rc = NULL;
    refl_result r;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    if (!scene || !camera || count < 0 || (count > 0 && !objects)) return REFL_ERROR_INVALID_ARGUMENT;
    if ((r = refl__context_create(scene, desc ? desc->threads : 0, &rc)) != REFL_OK) return r;
    r = refl__impostor_build(rc, scene, objects, count, camera, desc, out);
    rast_context_destroy(rc);
    return r;
}

REFL_API void refl_impostor_destroy(refl_impostor *imp) {
    refl_allocator al;
    if (!imp) return;
    al = imp->allocator;
    refl__free(&al, imp->color);
    refl__free(&al, imp->depth);
    refl__free(&al, imp->normal);
    refl__free(&al, imp);
}

/* The texel holding image point (u, v): its index, or -1 off the image. */
static long refl__imp_texel(const refl_impostor *imp, float u, float v) {
    float fu = floorf(u), fv = floorf(v);
    if (!(fu >= 0.0f && fv >= 0.0f && fu < (float)imp->width && fv < (float)imp->height)) return -1;
    return (long)fv * imp->width + (long)fu;
}

/* The texel of layer `base` / (width * height) holding (u, v) if it stores
   a surface, else -1; base is the layer's first texel. */
static long refl__imp_stored(const refl_impostor *imp, long base, float u, float v) {
    long t = refl__imp_texel(imp, u, v);
    return t >= 0 && imp->color[4 * (base + t) + 3] > 0.0f ? base + t : -1;
}

/* How much the stored depth changes over one texel beyond image point cur,
   continuing from prev (0 where that texel is empty or the points meet):
   the slope of the surface stored at cur in the layer at base, along the
   ray's projection. */
static float refl__imp_slope(const refl_impostor *imp, long base, const float prev[3], const float cur[3],
                             float gd_cur) {
    float du = cur[0] - prev[0], dv = cur[1] - prev[1], len = sqrtf(du * du + dv * dv);
    long t;
    if (!(len > 1e-6f)) return 0.0f;
    t = refl__imp_stored(imp, base, cur[0] + du / len, cur[1] + dv / len);
    return t < 0 ? 0.0f : fabsf(imp->depth[t] - gd_cur);
}

/* One layer's side of the walk: the texel the last end fell in (-1: none
   stored) and the ray's gd minus the stored depth there. */
typedef struct refl__imp_walk {
    long tex;
    float d;
} refl__imp_walk;

/* Where on the piece from prev to cur the ray crosses behind the surface
   layer `base` stores at cur, as a fraction of the piece, or -1 (no
   crossing, or a skin); w is the layer's state at prev, updated to cur. */
static float refl__imp_cross(const refl_impostor *imp, long base, refl__imp_walk *w, const float prev[3],
                             const float cur[3], int first) {
    long tex = refl__imp_stored(imp, base, cur[0], cur[1]);
    float gd_stored = tex >= 0 ? imp->depth[tex] : 1.0f, d = cur[2] - gd_stored, f = -1.0f;
    if (!first && tex >= 0 && d >= 0.0f && (w->tex < 0 || w->d < 0.0f)) {
        /* the ray went from in front of what texel k-1 stores (or from
           an empty texel) to behind what texel k stores. A hit, unless
           texel k's surface is nearer and the ray was already behind
           it extended back by its own slope: a skin */
        float d0 = prev[2] - gd_stored;
        int farther = w->tex >= 0 && gd_stored >= imp->depth[w->tex];
        if (farther || d0 <= refl__imp_slope(imp, base, prev, cur, gd_stored) + imp->depth_tolerance)
            f = w->tex >= 0 ? w->d / (w->d - d) : d0 < 0.0f ? d0 / (d0 - d) : 0.0f;
    }
    w->tex = tex;
    w->d = d;
    return f;
}

REFL_API int refl_impostor_intersect(const refl_impostor *imp, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax,
                                     float step_scale, refl_impostor_hit *hit, int *steps) {
    const refl_impostor_camera *cam;
    refl_vec3 oc;
    double a, b, c, disc, sq, t0, t1, len = 0.0;
    float prev[3], cur[3];
    refl__imp_walk walk[REFL_IMPOSTOR_MAX_LAYERS];
    long nn;
    int n, k, layer, found = 0;
    if (steps) *steps = 0;
    if (!imp || !hit) return 0;
    cam = &imp->camera;
    nn = (long)imp->width * imp->height;
    /* 1. clip to the bounding sphere */
    oc = refl_v3_sub(origin, cam->center);
    a = refl_v3_dot(dir, dir);
    b = refl_v3_dot(oc, dir);
    c = refl_v3_dot(oc, oc) - (double)cam->radius * cam->radius;
    disc = b * b - a * c;
    if (!(a > 0.0) || !(disc > 0.0)) return 0;
    sq = sqrt(disc);
    t0 = REFL__MAX((-b - sq) / a, (double)tmin);
    t1 = REFL__MIN((-b + sq) / a, (double)tmax);
    if (!(t0 < t1)) return 0;
    /* 2. the length of the projection, along 4 pieces, sets n */
    for (k = 0; k <= 4; ++k) {
        double t = t0 + (t1 - t0) * k / 4.0;
        if (!cam->project(cam->cam, refl_v3_add(origin, refl_v3_scale(dir, (float)t)), cur)) return 0;
        if (k) len += sqrt((double)(cur[0] - prev[0]) * (cur[0] - prev[0]) + (double)(cur[1] - prev[1]) * (cur[1] - prev[1]));
        memcpy(prev, cur, sizeof prev);
    }
    len *= step_scale > 0.0f ? step_scale : 1.0f;
    n = len < 2.0 ? 2 : len > 4.0 * (imp->width + imp->height) ? 4 * (imp->width + imp->height) : (int)ceil(len);
    /* 3. walk from near to far, every layer on the same ends: the first
       piece where the ray crosses behind a layer's surface, at the
       nearest crossing on it */
    for (k = 0; k <= n && !found; ++k) {
        double t = t0 + (t1 - t0) * k / n;
        float best = 2.0f;
        int best_layer = -1;
        if (!cam->project(cam->cam, refl_v3_add(origin, refl_v3_scale(dir, (float)t)), cur)) return 0;
        for (layer = 0; layer < imp->layers; ++layer) {
            float f = refl__imp_cross(imp, layer * nn, &walk[layer], prev, cur, k == 0);
            if (f >= 0.0f && f < best) {
                best = f;
                best_layer = layer;
            }
        }
        if (best_layer >= 0) {
            double th = t0 + (t1 - t0) * ((k - 1) + (double)best) / n;
            long at;
            hit->t = (float)th;
            hit->point = refl_v3_add(origin, refl_v3_scale(dir, hit->t));
            if (!cam->project(cam->cam, hit->point, hit->uvd)) memcpy(hit->uvd, cur, sizeof cur);
            at = refl__imp_stored(imp, best_layer * nn, hit->uvd[0], hit->uvd[1]);
            if (at < 0) at = walk[best_layer].tex;
            memcpy(hit->color, imp->color + 4 * at, 4 * sizeof(float));
            hit->normal = imp->normal ? refl_v3(imp->normal[3 * at], imp->normal[3 * at + 1], imp->normal[3 * at + 2])
                                      : refl_v3(0.0f, 0.0f, 0.0f);
            hit->layer = best_layer;
            found = 1;
        }
        memcpy(prev, cur, sizeof prev);
        if (steps && k > 0) ++*steps;
    }
    return found;
}

/* ---- billboard impostors: flat objects, intersected exactly ------------------------
   Paper 004 models the floor under its SPOC-impostored objects as a
   billboard impostor, "which captures it perfectly": a flat object's
   impostor is the object itself. Both impostor methods intersect such
   objects exactly through a BVH of their own and shade the hit here. */

/* The colour (clamped to [0, 1], as RAYTRACE clamps), point and shading
   normal (may be NULL) of an exact hit h on object ro: the shared diffuse
   shading without shadows; a mirror or glass shows black (one bounce, as
   DIRECT draws them). */
static void refl__exact_hit_shade(const refl_scene *scene, const refl__rt_object *ro, const refl_hit *h, float rgb[3],
                                  refl_vec3 *point, refl_vec3 *normal) {
    const refl_material *m = ro->material;
    const uint32_t *tri = ro->mesh->indices + 3 * (size_t)h->triangle;
    refl__hit_geom g;
    float uv[2] = {0.0f, 0.0f}, col[3], rgba[4];
    int k;
    refl__hit_surface(ro->mesh, &ro->model, &ro->normal_m, h, &g);
    if (ro->mesh->texcoords)
        for (k = 0; k < 3; ++k) {
            uv[0] += g.w[k] * ro->mesh->texcoords[2 * (size_t)tri[k]];
            uv[1] += g.w[k] * ro->mesh->texcoords[2 * (size_t)tri[k] + 1];
        }
    if (m->type == REFL_MIRROR || m->type == REFL_GLASS) {
        rgba[0] = rgba[1] = rgba[2] = 0.0f;
    } else {
        refl_shade_diffuse(scene, m, g.p, g.ns, uv, col);
        refl__surface_rgba(m, col, rgba);
    }
    for (k = 0; k < 3; ++k) rgb[k] = REFL__CLAMP(rgba[k], 0.0f, 1.0f);
    *point = g.p;
    if (normal) *normal = g.ns;
}
