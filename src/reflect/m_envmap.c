/* ENVMAP: the classic baseline. Per reflector, a cube map is rendered with
   rast.h from the centre of the reflector's world bounding box (six 90
   degree faces, GL's layout +X -X +Y -Y +Z -Z, the reflector itself left
   out), and each reflector pixel looks it up along its mirror direction, as
   if everything the cube shows were infinitely far away. That assumption
   is the method's known error: it is small for distant surroundings and
   large for objects close to the reflector.

   One bounce: other reflectors appear in a cube as DIRECT draws them
   (black, or a partial reflector's diffuse share).

   Per reflector pixel: the world normal comes from a G-buffer draw of the
   reflectors (depth LEQUAL against the frame's depth, stencil EQUAL their
   id, so exactly the pixels the base pass gave them; the object index in
   alpha tells apart objects sharing stencil 255; negative where the back
   side shows), the view direction from
   the pixel's camera ray. Colour is looked up bilinearly within a face;
   the world point a texel shows (drawn in a second pass per face) nearest,
   into frame->points.

   Glass is the classic single-interface approximation: the Fresnel share
   of the reflected lookup plus (1 - F) times the tint of the lookup along
   the ray refracted once into the glass (eta = 1 / ior). The second
   interface and absorption (attenuation) are ignored: there is no path
   length without the back surface. The point shown follows the stronger
   branch, as RAYTRACE's does.

   Cube texels are RGBA8, so every surface's colour is clamped to [0, 1]
   before the reflectance weighs it, as in RAYTRACE. One set of cube
   buffers is reused across reflectors; model_bytes counts a cube per
   reflector, what a renderer keeping them between frames would hold. */
#include "internal.h"

/* One object in a draw of ours: clip position exactly as the base pass
   computes it (so depth tests against the base pass's depth are exact),
   world position and (G-buffer) world normal as varyings. */
typedef struct refl__em_draw {
    const refl_mesh *mesh;
    refl_mat4 mvp, model, normal_m;
    int normals;                  /* varyings 3..5: world normal too (G-buffer) */
    refl_vec3 eye;                /* G-buffer: the viewer */
    float id;                     /* written to alpha: object index + 1 */
} refl__em_draw;

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

/* Cube faces: the world position a texel shows. */
static int refl__em_position_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    (void)user;
    rgba[0] = in->varyings[0];
    rgba[1] = in->varyings[1];
    rgba[2] = in->varyings[2];
    rgba[3] = 1.0f;
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

/* View matrix of cube face f from centre c: eye coordinates chosen so that
   a 90 degree projection puts direction v at NDC (sc / ma, -tc / ma), which
   is where rast_cube_face finds it: face texel (i, j) is pixel (i, j). */
static refl_mat4 refl__em_face_view(int f, refl_vec3 c) {
    /* rows x_e, y_e, z_e of the rotation, per face (GL table 8.19 inverted) */
    static const float rows[6][9] = {
        {0, 0, -1, 0, 1, 0, -1, 0, 0},  /* +X: sc = -z, tc = -y, ma = x */
        {0, 0, 1, 0, 1, 0, 1, 0, 0},    /* -X: sc = z, tc = -y, ma = -x */
        {1, 0, 0, 0, 0, -1, 0, -1, 0},  /* +Y: sc = x, tc = z, ma = y */
        {1, 0, 0, 0, 0, 1, 0, 1, 0},    /* -Y: sc = x, tc = -z, ma = -y */
        {1, 0, 0, 0, 1, 0, 0, 0, -1},   /* +Z: sc = x, tc = -y, ma = z */
        {-1, 0, 0, 0, 1, 0, 0, 0, 1}};  /* -Z: sc = -x, tc = -y, ma = -z */
    refl_mat4 m = refl_mat4_identity();
    int r;
    for (r = 0; r < 3; ++r) {
        const float *v = rows[f] + 3 * r;
        m.m[0 + r] = v[0];
        m.m[4 + r] = v[1];
        m.m[8 + r] = v[2];
        m.m[12 + r] = -(v[0] * c.x + v[1] * c.y + v[2] * c.z);
    }
    return m;
}

/* Centre of the object's world-space bounding box: the box of its
   vertices after the transform, counting only vertices a triangle uses
   (a mesh may keep others, as the concave scene's bowl keeps its whole
   sphere's). */
static refl_vec3 refl__em_centre(const refl_scene *scene, int object) {
    const refl_object *o = &scene->objects[object];
    const refl_mesh *m = scene->meshes[o->mesh];
    refl_vec3 lo = refl_v3(FLT_MAX, FLT_MAX, FLT_MAX), hi = refl_v3(-FLT_MAX, -FLT_MAX, -FLT_MAX);
    size_t k, count = 3 * (size_t)m->triangle_count;
    for (k = 0; k < count; ++k) {
        const float *q = m->positions + 3 * (size_t)m->indices[k];
        refl_vec3 w = refl_mat4_point(o->transform, refl_v3(q[0], q[1], q[2]));
        lo = refl__v3_min(lo, w);
        hi = refl__v3_max(hi, w);
    }
    if (!count) return refl_mat4_point(o->transform, refl_v3(0.0f, 0.0f, 0.0f));
    return refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
}

typedef struct refl__em {
    refl__pass *p;
    int n;                        /* face size */
    uint8_t *cube_color;          /* 6 faces of n x n RGBA8 */
    float *cube_points;           /* 6 faces of n x n world points (NaN: environment) */
    float *face_depth;            /* n x n */
    float *face_pos;              /* n x n RGBA32F */
    refl__em_draw *draws;         /* one per object */
    float *gbuf;                  /* frame-sized RGBA32F: world normal, object + 1 */
    float *surface;               /* C3RC, SBC: per reflector pixel, the world point seen there */
    int object;                   /* the reflector being looked up */
} refl__em;

/* Renders the cube of reflector `object` around centre c: colour with the
   shared shading and the environment behind, then world points. */
static refl_result refl__em_build_cube(refl__em *em, int object, refl_vec3 c) {
    refl__pass *p = em->p;
    const refl_scene *scene = p->scene;
    size_t nn = (size_t)em->n * (size_t)em->n, k;
    refl_vec3 lo, hi;
    float far_d = 0.0f, near_d;
    refl_mat4 proj;
    int f, i, corner;
    rast_result rr;
    refl_result r;
    /* far: the farthest corner of the scene's box; near: a small fraction */
    refl_scene_bounds(scene, &lo, &hi);
    for (corner = 0; corner < 8; ++corner) {
        refl_vec3 q = refl_v3(corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y, corner & 4 ? hi.z : lo.z);
        far_d = REFL__MAX(far_d, refl_v3_length(refl_v3_sub(q, c)));
    }
    if (!(far_d > 1e-6f) || !refl__isfinite(far_d)) far_d = 1.0f;
    far_d *= 1.01f;
    near_d = far_d * 1e-3f;
    proj = refl_mat4_perspective((float)(REFL__PI / 2.0), 1.0f, near_d, far_d);
    for (f = 0; f < 6; ++f) {
        refl_mat4 vp = refl_mat4_mul(proj, refl__em_face_view(f, c)), inv;
        uint8_t *color = em->cube_color + 4 * nn * (size_t)f;
        float *points = em->cube_points + 3 * nn * (size_t)f;
        rast_targets t;
        rast_state s;
        memset(&t, 0, sizeof t);
        t.color.ptr = color;
        t.color.width = t.color.height = em->n;
        t.color.stride = 4 * em->n;
        t.depth.ptr = em->face_depth;
        t.depth.width = t.depth.height = em->n;
        t.depth.stride = (int)sizeof(float) * em->n;
        if ((rr = rast_set_targets(p->rc, &t)) != RAST_OK ||
            (rr = refl__em_clear(p->rc, RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH)) != RAST_OK)
            return refl__result_from_rast(rr);
        if ((r = refl__draw_scene(p->rc, scene, vp, object, &p->frame->stats)) != REFL_OK) return r;
        if (refl_mat4_invert(vp, &inv)) refl__draw_background(color, em->face_depth, em->n, em->n, em->n, scene, inv);
        /* the world points: the same objects, order and depth test, so the
           same surface wins every texel */
        t.color.ptr = em->face_pos;
        t.color.stride = 4 * (int)sizeof(float) * em->n;
        t.color_format = RAST_COLOR_RGBA32F;
        if ((rr = rast_set_targets(p->rc, &t)) != RAST_OK || (rr = refl__em_clear(p->rc, RAST_CLEAR_DEPTH)) != RAST_OK)
            return refl__result_from_rast(rr);
        memset(&s, 0, sizeof s);
        s.depth_test = 1;
        s.vertex_fn = refl__em_vertex;
        s.fragment_fn = refl__em_position_fragment;
        for (i = 0; i < scene->object_count; ++i) {
            if (i == object) continue;
            refl__em_setup_draw(&em->draws[i], scene, i, vp, 0);
            s.vertex_user = s.fragment_user = &em->draws[i];
            if ((rr = rast_set_state(p->rc, &s)) != RAST_OK || (rr = refl__em_submit(p->rc, &em->draws[i])) != RAST_OK)
                return refl__result_from_rast(rr);
            p->frame->stats.triangles += em->draws[i].mesh->triangle_count;
        }
        if ((rr = rast_finish(p->rc)) != RAST_OK) return refl__result_from_rast(rr);
        for (k = 0; k < nn; ++k) {
            int shown = em->face_depth[k] < 1.0f;
            points[3 * k] = shown ? em->face_pos[4 * k] : NAN;
            points[3 * k + 1] = shown ? em->face_pos[4 * k + 1] : NAN;
            points[3 * k + 2] = shown ? em->face_pos[4 * k + 2] : NAN;
        }
    }
    return REFL_OK;
}

/* Bilinear colour of the cube along dir (within its face, clamped at the
   face's edges as GL samples cube maps), and the world point of the
   nearest texel. */
static void refl__em_lookup(const refl__em *em, refl_vec3 dir, float rgb[3], refl_vec3 *point) {
    float v[3], s, t, x, y, fx, fy;
    int face, x0, y0, x1, y1, c, n = em->n, ix, iy;
    size_t base;
    const uint8_t *px;
    const float *pt;
    v[0] = dir.x; v[1] = dir.y; v[2] = dir.z;
    face = rast_cube_face(v, &s, &t);
    base = (size_t)face * (size_t)n * (size_t)n;
    x = s * (float)n - 0.5f;
    y = t * (float)n - 0.5f;
    x0 = (int)floorf(x);
    y0 = (int)floorf(y);
    fx = x - (float)x0;
    fy = y - (float)y0;
    x1 = REFL__CLAMP(x0 + 1, 0, n - 1);
    y1 = REFL__CLAMP(y0 + 1, 0, n - 1);
    x0 = REFL__CLAMP(x0, 0, n - 1);
    y0 = REFL__CLAMP(y0, 0, n - 1);
    px = em->cube_color + 4 * base;
    for (c = 0; c < 3; ++c) {
        float a = px[4 * ((size_t)y0 * (size_t)n + (size_t)x0) + (size_t)c];
        float b = px[4 * ((size_t)y0 * (size_t)n + (size_t)x1) + (size_t)c];
        float d = px[4 * ((size_t)y1 * (size_t)n + (size_t)x0) + (size_t)c];
        float e = px[4 * ((size_t)y1 * (size_t)n + (size_t)x1) + (size_t)c];
        rgb[c] = ((a * (1.0f - fx) + b * fx) * (1.0f - fy) + (d * (1.0f - fx) + e * fx) * fy) * (1.0f / 255.0f);
    }
    ix = REFL__CLAMP((int)(s * (float)n), 0, n - 1);
    iy = REFL__CLAMP((int)(t * (float)n), 0, n - 1);
    pt = em->cube_points + 3 * (base + (size_t)iy * (size_t)n + (size_t)ix);
    *point = refl_v3(pt[0], pt[1], pt[2]);
}

/* Adds rgb to frame pixel i (opaque now) and sets the point it shows. */
static void refl__em_put(refl_frame *fr, size_t i, const float rgb[3], refl_vec3 shown) {
    uint8_t *px = fr->color + 4 * i;
    int c;
    for (c = 0; c < 3; ++c) {
        float v = REFL__CLAMP((float)px[c] * (1.0f / 255.0f) + rgb[c], 0.0f, 1.0f);
        px[c] = (uint8_t)(v * 255.0f + 0.5f);
    }
    px[3] = 255;
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

/* One frame row: every pixel of the current reflector gets its reflection
   (and refraction) added and its point. Pixels are independent, so rows
   may run on any thread in any order. */
static void refl__em_row(void *arg, int y) {
    const refl__em *em = (const refl__em *)arg;
    const refl__pass *p = em->p;
    refl_frame *fr = p->frame;
    const refl_material *m = &p->scene->materials[p->scene->objects[em->object].material];
    float id = (float)(em->object + 1);
    int x, c;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
        const float *g = em->gbuf + 4 * i;
        float rgb[3], sub[3], cos_i, w, tmax;
        refl_vec3 o, d, n, shown;
        if (fabsf(g[3]) != id) continue;
        refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
        n = refl_v3_normalize(refl_v3(g[0], g[1], g[2]));
        if (refl_v3_dot(n, n) == 0.0f) n = refl_v3_scale(d, -1.0f); /* degenerate normal: face the eye */
        if (refl_v3_dot(d, n) > 0.0f) n = refl_v3_scale(n, -1.0f);  /* the side the viewer sees */
        cos_i = REFL__CLAMP(-refl_v3_dot(d, n), 0.0f, 1.0f);
        w = refl_material_reflectance(m, cos_i);
        refl__em_lookup(em, refl_v3_reflect(d, n), sub, &shown);
        if (m->type == REFL_GLASS) {
            float ior = m->ior > 0.0f ? m->ior : 1.5f, tint[3], tsub[3];
            int tinted = m->tint[0] + m->tint[1] + m->tint[2] > 0.0f;
            refl_vec3 t, tshown;
            if (!refl_v3_refract(d, n, 1.0f / ior, &t)) w = 1.0f; /* total internal reflection */
            for (c = 0; c < 3; ++c) rgb[c] = w * sub[c];
            if (w < 1.0f) {
                refl__em_lookup(em, t, tsub, &tshown);
                for (c = 0; c < 3; ++c) {
                    tint[c] = tinted ? m->tint[c] : 1.0f;
                    rgb[c] += (1.0f - w) * tint[c] * tsub[c];
                }
                if (w < 0.5f) shown = tshown;
            }
        } else {
            w *= refl__em_fade(p, m, x, y, shown);
            for (c = 0; c < 3; ++c) rgb[c] = w * sub[c];
        }
        refl__em_put(fr, i, rgb, shown);
    }
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
        for (c = 0; c < 3; ++c) sub[c] = REFL__CLAMP(sub[c], 0.0f, 1.0f);
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
                rgb[c] += (1.0f - w) * (tinted ? m->tint[c] : 1.0f) * REFL__CLAMP(tsub[c], 0.0f, 1.0f);
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
    memset(&t, 0, sizeof t);
    t.color.ptr = em->gbuf;
    t.color.width = fr->width;
    t.color.height = fr->height;
    t.color.stride = 4 * (int)sizeof(float) * fr->width;
    t.color_format = RAST_COLOR_RGBA32F;
    t.depth.ptr = fr->depth;
    t.depth.width = fr->width;
    t.depth.height = fr->height;
    t.depth.stride = (int)sizeof(float) * fr->width;
    t.stencil.ptr = fr->stencil;
    t.stencil.width = fr->width;
    t.stencil.height = fr->height;
    t.stencil.stride = fr->width;
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

static const char *refl__options_envmap(refl_render_desc *d) {
    if (d->envmap.size < 0 || d->envmap.size > 8192) return "envmap.size: 0 (256) to 8192";
    if (d->envmap.size == 0) d->envmap.size = 256;
    return NULL;
}

static refl_result refl__method_envmap(refl__pass *p) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl_frame *fr = p->frame;
    refl__em em;
    unsigned char *seen = NULL;
    size_t nn;
    double t0 = refl__now_ms(), t1;
    refl_result r = REFL_OK;
    int i, any = 0, reflectors = 0;
    for (i = 0; i < scene->object_count; ++i)
        reflectors += refl__is_reflector(&scene->materials[scene->objects[i].material]);
    if (!reflectors) return REFL_OK;
    memset(&em, 0, sizeof em);
    em.p = p;
    em.n = p->desc.envmap.size > 0 ? p->desc.envmap.size : 256;
    nn = (size_t)em.n * (size_t)em.n;
    r = refl__em_gbuffer_new(&em, &seen, &any);
    if (r == REFL_OK && any) {
        em.cube_color = (uint8_t *)refl__calloc(al, 6 * nn, 4);
        em.cube_points = (float *)refl__calloc(al, 6 * nn, 3 * sizeof(float));
        em.face_depth = (float *)refl__calloc(al, nn, sizeof(float));
        em.face_pos = (float *)refl__calloc(al, nn, 4 * sizeof(float));
        if (!em.cube_color || !em.cube_points || !em.face_depth || !em.face_pos) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    t1 = refl__now_ms();
    fr->stats.ms_reflect += t1 - t0;
    for (i = 0; r == REFL_OK && i < scene->object_count; ++i) {
        if (!seen[i]) continue;
        r = refl__em_build_cube(&em, i, refl__em_centre(scene, i));
        t0 = refl__now_ms();
        fr->stats.ms_build += t0 - t1;
        if (r != REFL_OK) break;
        fr->stats.envmap.cube_faces += 6;
        fr->stats.model_bytes += (long long)(6 * nn * (4 + 3 * sizeof(float)));
        em.object = i;
        rast_run_jobs(p->rc, fr->height, refl__em_row, &em);
        t1 = refl__now_ms();
        fr->stats.ms_reflect += t1 - t0;
    }
    /* leave the frame bound, as the method found it; never after a failed
       draw, whose queued work may point at freed memory */
    if (r == REFL_OK) {
        rast_targets t = refl__frame_targets(fr);
        r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    }
    refl__free(al, em.gbuf);
    refl__free(al, em.draws);
    refl__free(al, seen);
    refl__free(al, em.cube_color);
    refl__free(al, em.cube_points);
    refl__free(al, em.face_depth);
    refl__free(al, em.face_pos);
    return r;
}
