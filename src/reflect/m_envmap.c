/* ENVMAP: the classic baseline. Per reflector, a cube map is rendered with
   rast.h from the centre of the reflector's world bounding box (six 90
   degree faces, GL's layout +X -X +Y -Y +Z -Z, the reflector itself left
   out), and each reflector pixel looks it up along its mirror direction, as
   if everything the cube shows were infinitely far away. That assumption
   is the method's known error: it is small for distant surroundings and
   large for objects close to the reflector.

   One bounce: other reflectors appear in a cube as DIRECT draws them
   (black, or a partial reflector's diffuse share). With depth > 1, a pixel
   whose lookup lands on another reflector's texel goes to RAYTRACE's
   tracer for its colour (refl__trace_beyond), as the cube cannot follow
   the path further; its point stays the cube's.

   Per reflector pixel, the normal comes from the reflectors' G-buffer
   (gbuffer.c), the view direction from the pixel's camera ray. Colour is
   looked up bilinearly within a face; the world point a texel shows
   (drawn in a second pass per face) nearest, into frame->points.

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

/* Cube faces: the world position a texel shows. */
static int refl__em_position_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    rgba[0] = in->varyings[0];
    rgba[1] = in->varyings[1];
    rgba[2] = in->varyings[2];
    rgba[3] = ((const refl__em_draw *)user)->id; /* object index + 1 */
    return 1;
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

/* ENVMAP's frame: the G-buffer, and one set of cube buffers that every
   reflector's cube reuses in turn. */
typedef struct refl__em_cube {
    refl__em em;                  /* the reflectors' G-buffer (gbuffer.c) */
    int n;                        /* face size */
    float *cube_color;            /* 6 faces of n x n linear RGBA */
    float *cube_points;           /* 6 faces of n x n world points (NaN: environment) */
    uint8_t *cube_reflector;      /* 6 faces of n x n: 1 where a texel shows a reflector */
    float *face_depth;            /* n x n */
    float *face_pos;              /* n x n RGBA32F */
    int object;                   /* the reflector being looked up */
} refl__em_cube;

/* Renders the cube of reflector `object` around centre c: colour with the
   shared shading and the environment behind, then world points. */
static refl_result refl__em_build_cube(refl__em_cube *cb, int object, refl_vec3 c) {
    refl__pass *p = cb->em.p;
    const refl_scene *scene = p->scene;
    size_t nn = (size_t)cb->n * (size_t)cb->n, k;
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
        float *color = cb->cube_color + 4 * nn * (size_t)f;
        float *points = cb->cube_points + 3 * nn * (size_t)f;
        uint8_t *reflector = cb->cube_reflector + nn * (size_t)f;
        rast_targets t;
        rast_state s;
        t = refl__float_targets(color, cb->face_depth, NULL, cb->n, cb->n);
        if ((rr = rast_set_targets(p->rc, &t)) != RAST_OK ||
            (rr = refl__em_clear(p->rc, RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH)) != RAST_OK)
            return refl__result_from_rast(rr);
        if ((r = refl__draw_scene(p->rc, scene, vp, object, &p->frame->stats)) != REFL_OK) return r;
        if (refl_mat4_invert(vp, &inv)) refl__draw_background(color, cb->face_depth, cb->n, cb->n, cb->n, scene, inv);
        /* the world points: the same objects, order and depth test, so the
           same surface wins every texel */
        t.color.ptr = cb->face_pos;
        if ((rr = rast_set_targets(p->rc, &t)) != RAST_OK || (rr = refl__em_clear(p->rc, RAST_CLEAR_DEPTH)) != RAST_OK)
            return refl__result_from_rast(rr);
        memset(&s, 0, sizeof s);
        s.depth_test = 1;
        s.vertex_fn = refl__em_vertex;
        s.fragment_fn = refl__em_position_fragment;
        for (i = 0; i < scene->object_count; ++i) {
            if (i == object) continue;
            refl__em_setup_draw(&cb->em.draws[i], scene, i, vp, 0);
            s.vertex_user = s.fragment_user = &cb->em.draws[i];
            if ((rr = rast_set_state(p->rc, &s)) != RAST_OK ||
                (rr = refl__em_submit(p->rc, &cb->em.draws[i])) != RAST_OK)
                return refl__result_from_rast(rr);
            p->frame->stats.triangles += cb->em.draws[i].mesh->triangle_count;
        }
        if ((rr = rast_finish(p->rc)) != RAST_OK) return refl__result_from_rast(rr);
        for (k = 0; k < nn; ++k) {
            int shown = cb->face_depth[k] < 1.0f;
            points[3 * k] = shown ? cb->face_pos[4 * k] : NAN;
            points[3 * k + 1] = shown ? cb->face_pos[4 * k + 1] : NAN;
            points[3 * k + 2] = shown ? cb->face_pos[4 * k + 2] : NAN;
            reflector[k] = 0;
            if (shown) {
                int o = (int)cb->face_pos[4 * k + 3] - 1;
                reflector[k] = (uint8_t)(o >= 0 && o < scene->object_count &&
                                         refl__is_reflector(&scene->materials[scene->objects[o].material]));
            }
        }
    }
    return REFL_OK;
}

/* Bilinear colour of the cube along dir (within its face, clamped at the
   face's edges as GL samples cube maps), and the world point of the
   nearest texel; nonzero when a texel the colour mixes shows a reflector. */
static int refl__em_lookup(const refl__em_cube *cb, refl_vec3 dir, float rgb[3], refl_vec3 *point) {
    float v[3], s, t, x, y, fx, fy;
    int face, x0, y0, x1, y1, c, n = cb->n, ix, iy;
    size_t base;
    const uint8_t *mirror;
    const float *px;
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
    px = cb->cube_color + 4 * base;
    for (c = 0; c < 3; ++c) {
        float a = px[4 * ((size_t)y0 * (size_t)n + (size_t)x0) + (size_t)c];
        float b = px[4 * ((size_t)y0 * (size_t)n + (size_t)x1) + (size_t)c];
        float d = px[4 * ((size_t)y1 * (size_t)n + (size_t)x0) + (size_t)c];
        float e = px[4 * ((size_t)y1 * (size_t)n + (size_t)x1) + (size_t)c];
        rgb[c] = (a * (1.0f - fx) + b * fx) * (1.0f - fy) + (d * (1.0f - fx) + e * fx) * fy;
    }
    ix = REFL__CLAMP((int)(s * (float)n), 0, n - 1);
    iy = REFL__CLAMP((int)(t * (float)n), 0, n - 1);
    pt = cb->cube_points + 3 * (base + (size_t)iy * (size_t)n + (size_t)ix);
    *point = refl_v3(pt[0], pt[1], pt[2]);
    mirror = cb->cube_reflector + base;
    return (fx < 1.0f && fy < 1.0f && mirror[(size_t)y0 * (size_t)n + (size_t)x0]) ||
           (fx > 0.0f && fy < 1.0f && mirror[(size_t)y0 * (size_t)n + (size_t)x1]) ||
           (fx < 1.0f && fy > 0.0f && mirror[(size_t)y1 * (size_t)n + (size_t)x0]) ||
           (fx > 0.0f && fy > 0.0f && mirror[(size_t)y1 * (size_t)n + (size_t)x1]);
}

/* One frame row: every pixel of the current reflector gets its reflection
   (and refraction) added and its point. Pixels are independent, so rows
   may run on any thread in any order. */
static void refl__em_row(void *arg, int y) {
    const refl__em_cube *cb = (const refl__em_cube *)arg;
    const refl__pass *p = cb->em.p;
    refl_frame *fr = p->frame;
    const refl_material *m = &p->scene->materials[p->scene->objects[cb->object].material];
    float id = (float)(cb->object + 1);
    int x, c;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
        const float *g = cb->em.gbuf + 4 * i;
        float rgb[3], sub[3], cos_i, w, tmax;
        int beyond;                   /* the lookup met a reflector the cube cannot follow */
        refl_vec3 o, d, n, shown;
        if (fabsf(g[3]) != id) continue;
        refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
        n = refl_v3_normalize(refl_v3(g[0], g[1], g[2]));
        if (refl_v3_dot(n, n) == 0.0f) n = refl_v3_scale(d, -1.0f); /* degenerate normal: face the eye */
        if (refl_v3_dot(d, n) > 0.0f) n = refl_v3_scale(n, -1.0f);  /* the side the viewer sees */
        cos_i = REFL__CLAMP(-refl_v3_dot(d, n), 0.0f, 1.0f);
        w = refl_material_reflectance(m, cos_i);
        beyond = refl__em_lookup(cb, refl_v3_reflect(d, n), sub, &shown) && w > 0.0f;
        if (m->type == REFL_GLASS) {
            float ior = m->ior > 0.0f ? m->ior : 1.5f, tint[3], tsub[3];
            int tinted = m->tint[0] + m->tint[1] + m->tint[2] > 0.0f;
            refl_vec3 t, tshown;
            if (!refl_v3_refract(d, n, 1.0f / ior, &t)) w = 1.0f; /* total internal reflection */
            for (c = 0; c < 3; ++c) rgb[c] = w * sub[c];
            if (w < 1.0f) {
                beyond |= refl__em_lookup(cb, t, tsub, &tshown);
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
        if (beyond && p->trace) p->trace[i] = REFL__TRACE_COLOUR;
    }
}

static const char *refl__options_envmap(refl_render_desc *d) {
    /* six faces of float colour and points, a reflector flag, depth and positions: 49 bytes a texel */
    if (d->envmap.size < 0 || d->envmap.size > 2048) return "envmap.size: 0 (256) to 2048 (1.2 GB of cube buffers)";
    if (d->envmap.size == 0) d->envmap.size = 256;
    return NULL;
}

static refl_result refl__method_envmap(refl__pass *p) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl_frame *fr = p->frame;
    refl__em_cube cb;
    unsigned char *seen = NULL;
    size_t nn;
    double t0 = refl__now_ms(), t1;
    refl_result r = REFL_OK;
    int i, any = 0, reflectors = 0;
    for (i = 0; i < scene->object_count; ++i)
        reflectors += refl__is_reflector(&scene->materials[scene->objects[i].material]);
    if (!reflectors) return REFL_OK;
    memset(&cb, 0, sizeof cb);
    cb.em.p = p;
    cb.n = p->desc.envmap.size > 0 ? p->desc.envmap.size : 256;
    nn = (size_t)cb.n * (size_t)cb.n;
    r = refl__em_gbuffer_new(&cb.em, &seen, &any);
    if (r == REFL_OK && any) {
        cb.cube_color = (float *)refl__calloc(al, 6 * nn, 4 * sizeof(float));
        cb.cube_points = (float *)refl__calloc(al, 6 * nn, 3 * sizeof(float));
        cb.cube_reflector = (uint8_t *)refl__calloc(al, 6 * nn, 1);
        cb.face_depth = (float *)refl__calloc(al, nn, sizeof(float));
        cb.face_pos = (float *)refl__calloc(al, nn, 4 * sizeof(float));
        if (!cb.cube_color || !cb.cube_points || !cb.cube_reflector || !cb.face_depth || !cb.face_pos) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    t1 = refl__now_ms();
    fr->stats.ms_reflect += t1 - t0;
    for (i = 0; r == REFL_OK && i < scene->object_count; ++i) {
        if (!seen[i]) continue;
        r = refl__em_build_cube(&cb, i, refl__em_centre(scene, i));
        t0 = refl__now_ms();
        fr->stats.ms_build += t0 - t1;
        if (r != REFL_OK) break;
        fr->stats.envmap.cube_faces += 6;
        fr->stats.model_bytes += (long long)(6 * nn * (4 + 3 * sizeof(float) + 1));
        cb.object = i;
        rast_run_jobs(p->rc, fr->height, refl__em_row, &cb);
        t1 = refl__now_ms();
        fr->stats.ms_reflect += t1 - t0;
    }
    /* leave the frame bound, as the method found it; never after a failed
       draw, whose queued work may point at freed memory */
    if (r == REFL_OK) {
        rast_targets t = refl__frame_targets(fr);
        r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    }
    refl__free(al, cb.em.gbuf);
    refl__free(al, cb.em.draws);
    refl__free(al, seen);
    refl__free(al, cb.cube_color);
    refl__free(al, cb.cube_points);
    refl__free(al, cb.cube_reflector);
    refl__free(al, cb.face_depth);
    refl__free(al, cb.face_pos);
    return r;
}
