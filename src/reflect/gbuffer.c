/* The reflectors' G-buffer and the mirror share's composite, shared by
   ENVMAP, C3RC and SBC: the methods differ in where a reflected ray lands
   and agree on everything around it.

   Per reflector pixel, the world normal comes from a G-buffer draw of the
   reflectors (depth LEQUAL against the frame's depth, stencil EQUAL their
   id, so exactly the pixels the base pass gave them; the object index in
   alpha tells apart objects sharing stencil 255; negative where the back
   side shows), the view direction from the pixel's camera ray, and the
   point of the surface from the window depth along that ray.

   The composite weighs the colour a method found by the reflectance and
   adds it to the base pass's diffuse share. Glass is the classic
   single-interface approximation: the Fresnel share of the reflection plus
   (1 - F) times the tint of the environment along the ray refracted once
   (eta = 1 / ior); the second interface and absorption are ignored, as
   there is no path length without the back surface. */
#include "internal.h"

/* Varyings: world position, then (G-buffer) world normal. */
static int refl__em_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out) {
    const refl__em_draw *d = (const refl__em_draw *)user;
    refl_vec3 p = refl_v3(vertex[0], vertex[1], vertex[2]), w = refl_mat4_point(d->model, p);
    const float *mm = d->mvp.m;
    int k;
    (void)max_out;
    /* the same expression as refl__base_vertex: bit-identical clip positions */
    for (k = 0; k < 4; ++k) out->position[k] = mm[k] * p.x + mm[4 + k] * p.y + mm[8 + k] * p.z + mm[12 + k];
    out->varyings[0] = w.x;
    out->varyings[1] = w.y;
    out->varyings[2] = w.z;
    if (d->normals) {
        const float *n = d->mesh->normals + 3 * (size_t)index;
        w = refl_mat4_dir(d->normal_m, refl_v3(n[0], n[1], n[2]));
        out->varyings[3] = w.x;
        out->varyings[4] = w.y;
        out->varyings[5] = w.z;
    }
    return 1;
}

/* G-buffer: the normal a reflection uses, chosen as RAYTRACE chooses it:
   the shading normal, turned to the side the viewer is on (back faces
   flip it), or the geometric normal (from the screen derivatives of the
   position, which lie in the triangle's plane) where the interpolated
   normal still faces away, as it can at silhouettes. */
static int refl__em_normal_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__em_draw *d = (const refl__em_draw *)user;
    const float *v = in->varyings;
    refl_vec3 view = refl_v3_sub(refl_v3(v[0], v[1], v[2]), d->eye), n = refl_v3(v[3], v[4], v[5]);
    if (!in->front_facing) n = refl_v3_scale(n, -1.0f);
    if (refl_v3_dot(view, n) > 0.0f || refl_v3_dot(n, n) == 0.0f) {
        n = refl_v3_cross(refl_v3(in->ddx[0], in->ddx[1], in->ddx[2]), refl_v3(in->ddy[0], in->ddy[1], in->ddy[2]));
        if (refl_v3_dot(view, n) > 0.0f) n = refl_v3_scale(n, -1.0f);
    }
    n = refl_v3_normalize(n);
    rgba[0] = n.x;
    rgba[1] = n.y;
    rgba[2] = n.z;
    rgba[3] = in->front_facing ? d->id : -d->id; /* the side seen, for C3RC */
    return 1;
}

static void refl__em_setup_draw(refl__em_draw *d, const refl_scene *scene, int object, refl_mat4 vp, int normals) {
    const refl_object *o = &scene->objects[object];
    d->mesh = scene->meshes[o->mesh];
    d->model = o->transform;
    d->mvp = refl_mat4_mul(vp, o->transform);
    d->normal_m = refl__normal_matrix(o->transform);
    d->normals = normals;
    d->id = (float)(object + 1);
}

static rast_result refl__em_submit(rast_context *rc, const refl__em_draw *d) {
    return refl__draw_mesh(rc, d->mesh, NULL, 0, d->normals ? 6 : 3);
}

/* Clears with the default state: clears honour the depth mask and scissor. */
static rast_result refl__em_clear(rast_context *rc, unsigned flags) {
    rast_state s;
    rast_clear_desc c;
    rast_result r;
    memset(&s, 0, sizeof s);
    memset(&c, 0, sizeof c);
    c.flags = flags;
    c.depth = 1.0f;
    if ((r = rast_set_state(rc, &s)) != RAST_OK) return r;
    return rast_clear(rc, &c);
}

/* Adds rgb to frame pixel i (opaque now) and sets the point it shows. */
static void refl__em_put(refl_frame *fr, size_t i, const float rgb[3], refl_vec3 shown) {
    float *px = fr->rgba + 4 * i;
    int c;
    for (c = 0; c < 3; ++c) px[c] += rgb[c];
    px[3] = 1.0f;
    fr->points[3 * i] = shown.x;
    fr->points[3 * i + 1] = shown.y;
    fr->points[3 * i + 2] = shown.z;
}

/* The world point of the surface pixel (x, y) shows, from its window
   depth along its ray. */
static refl_vec3 refl__em_surface_at(const refl__pass *p, int x, int y) {
    const refl__view_rays *r = &p->rays;
    const refl_frame *fr = p->frame;
    float n = r->znear, f = r->zfar, nx, ny, ndc, dist;
    refl_vec3 d;
    nx = 2.0f * ((float)x + 0.5f) / (float)fr->width - 1.0f;
    ny = 1.0f - 2.0f * ((float)y + 0.5f) / (float)fr->height;
    ndc = 2.0f * fr->depth[(size_t)y * (size_t)fr->width + (size_t)x] - 1.0f;
    dist = 2.0f * f * n / ((f + n) - ndc * (f - n)); /* eye depth along forward */
    d = refl_v3_add(r->forward, refl_v3_add(refl_v3_scale(r->right, nx), refl_v3_scale(r->up, ny)));
    return refl_v3_add(r->eye, refl_v3_scale(d, dist));
}

/* The distance fade (paper 003 V-D) of material m's mirror share at pixel
   (x, y) showing `shown` (NaN: the environment). */
static float refl__em_fade(const refl__pass *p, const refl_material *m, int x, int y, refl_vec3 shown) {
    if (!(m->fade_distance > 0.0f)) return 1.0f; /* the common case: no depth read */
    return refl_material_fade(m, refl_v3_length(refl_v3_sub(shown, refl__em_surface_at(p, x, y))));
}

/* Per reflector pixel (G-buffer id nonzero): the world point of the
   surface seen into em->surface. Rows are independent. */
static void refl__em_surface_row(void *arg, int y) {
    refl__em *em = (refl__em *)arg;
    const refl_frame *fr = em->p->frame;
    int x;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
        refl_vec3 q;
        if (fabsf(em->gbuf[4 * i + 3]) < 1.0f) continue;
        q = refl__em_surface_at(em->p, x, y);
        em->surface[3 * i] = q.x;
        em->surface[3 * i + 1] = q.y;
        em->surface[3 * i + 2] = q.z;
    }
}

/* Adds reflector pixel i's mirror share to the frame, as ENVMAP
   composites: `sub` (the colour reflected there, each channel in [0, 1];
   NULL: the environment along the reflected ray) times the reflectance;
   glass adds (1 - F) times the tinted environment along the ray refracted
   once (wholly reflective past the critical angle). The pixel's point
   becomes `shown` (NaN: none), or none where the refraction dominates. */
static void refl__em_composite(const refl__pass *p, const float *g, int x, int y, const float *sub_in,
                               refl_vec3 shown) {
    const refl_scene *scene = p->scene;
    refl_frame *fr = p->frame;
    size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
    int object = (int)fabsf(g[3]) - 1, c;
    const refl_material *m;
    float rgb[3], sub[3], cos_i, w, tmax;
    refl_vec3 o, d, n;
    if (object < 0 || object >= scene->object_count) return;
    m = &scene->materials[scene->objects[object].material];
    refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
    n = refl_v3_normalize(refl_v3(g[0], g[1], g[2]));
    if (refl_v3_dot(n, n) == 0.0f) n = refl_v3_scale(d, -1.0f);
    if (refl_v3_dot(d, n) > 0.0f) n = refl_v3_scale(n, -1.0f);
    cos_i = REFL__CLAMP(-refl_v3_dot(d, n), 0.0f, 1.0f);
    w = refl_material_reflectance(m, cos_i);
    if (sub_in) {
        memcpy(sub, sub_in, sizeof sub);
    } else {
        refl_environment_lookup(&scene->environment, refl_v3_reflect(d, n), sub);
        for (c = 0; c < 3; ++c) sub[c] = REFL__RADIANCE(sub[c]);
    }
    if (m->type != REFL_GLASS) w *= refl__em_fade(p, m, x, y, shown);
    for (c = 0; c < 3; ++c) rgb[c] = w * sub[c];
    if (m->type == REFL_GLASS) {
        float ior = m->ior > 0.0f ? m->ior : 1.5f, tsub[3];
        int tinted = m->tint[0] + m->tint[1] + m->tint[2] > 0.0f;
        refl_vec3 t;
        if (refl_v3_refract(d, n, 1.0f / ior, &t)) {
            refl_environment_lookup(&scene->environment, t, tsub);
            for (c = 0; c < 3; ++c)
                rgb[c] += (1.0f - w) * (tinted ? m->tint[c] : 1.0f) * REFL__RADIANCE(tsub[c]);
            if (w < 0.5f) shown = refl_v3(NAN, NAN, NAN);
        } else {
            for (c = 0; c < 3; ++c) rgb[c] = sub[c]; /* total internal reflection */
        }
    }
    refl__em_put(fr, i, rgb, shown);
}

/* The reflectors' world normals into em->gbuf where the base pass showed
   them; seen[i] set for every reflector i with a pixel. */
static refl_result refl__em_gbuffer(refl__em *em, unsigned char *seen, int *any) {
    refl__pass *p = em->p;
    const refl_scene *scene = p->scene;
    refl_frame *fr = p->frame;
    rast_targets t;
    rast_state s;
    rast_result rr;
    size_t k, npx = (size_t)fr->width * (size_t)fr->height;
    int i;
    t = refl__float_targets(em->gbuf, fr->depth, fr->stencil, fr->width, fr->height);
    if ((rr = rast_set_targets(p->rc, &t)) != RAST_OK || (rr = refl__em_clear(p->rc, RAST_CLEAR_COLOR)) != RAST_OK)
        return refl__result_from_rast(rr);
    /* the frame's depth and stencil are only read */
    memset(&s, 0, sizeof s);
    s.depth_test = 1;
    s.depth_func = RAST_LEQUAL;
    s.depth_write_disabled = 1;
    s.stencil_test = 1;
    s.stencil_front.func = RAST_EQUAL;
    s.stencil_back = s.stencil_front;
    s.vertex_fn = refl__em_vertex;
    s.fragment_fn = refl__em_normal_fragment;
    s.fragment_derivatives = 1;
    for (i = 0; i < scene->object_count; ++i) {
        if (!refl__pass_draws(p, i)) continue;
        refl__em_setup_draw(&em->draws[i], scene, i, p->vp, 1);
        em->draws[i].eye = p->view->eye;
        s.stencil_front.ref = s.stencil_back.ref = (uint8_t)(i + 1 < 255 ? i + 1 : 255);
        s.vertex_user = s.fragment_user = &em->draws[i];
        if ((rr = rast_set_state(p->rc, &s)) != RAST_OK || (rr = refl__em_submit(p->rc, &em->draws[i])) != RAST_OK)
            return refl__result_from_rast(rr);
        fr->stats.triangles += em->draws[i].mesh->triangle_count;
    }
    if ((rr = rast_finish(p->rc)) != RAST_OK) return refl__result_from_rast(rr);
    *any = 0;
    for (k = 0; k < npx; ++k) {
        float id = fabsf(em->gbuf[4 * k + 3]);
        if (id >= 1.0f && id <= (float)scene->object_count) {
            seen[(int)id - 1] = 1;
            *any = 1;
        }
    }
    return REFL_OK;
}

/* Allocates em->gbuf, em->draws and *seen (one flag per object; the
   caller frees all three, also on failure) and draws the G-buffer. */
static refl_result refl__em_gbuffer_new(refl__em *em, unsigned char **seen, int *any) {
    const refl_scene *scene = em->p->scene;
    const refl_allocator *al = &scene->allocator;
    size_t npx = (size_t)em->p->frame->width * (size_t)em->p->frame->height;
    size_t objects = (size_t)REFL__MAX(scene->object_count, 1);
    em->gbuf = (float *)refl__calloc(al, npx, 4 * sizeof(float));
    em->draws = (refl__em_draw *)refl__calloc(al, objects, sizeof(refl__em_draw));
    *seen = (unsigned char *)refl__calloc(al, objects, 1);
    *any = 0;
    if (!em->gbuf || !em->draws || !*seen) return REFL_ERROR_OUT_OF_MEMORY;
    return refl__em_gbuffer(em, *seen, any);
}
