/* The base pass's drawing, shared by every rasterising method: each object
   drawn with the shared diffuse model per pixel (shade.c), reflectors with
   their diffuse share (partial) or transparent black (mirror, glass) and
   their object id + 1 in the stencil, then the environment behind
   everything. Methods draw with these programs again (a mirrored camera, a
   cube face, the shadowed pixels shaded once more), so their clip
   positions and colours match the base pass's bit for bit. */
#include "internal.h"

/* The draw context of object `object` seen through vp. */
static void refl__draw_ctx_init(refl__draw_ctx *dc, const refl_scene *s, int object, refl_mat4 vp) {
    const refl_object *o = &s->objects[object];
    dc->scene = s;
    dc->mesh = s->meshes[o->mesh];
    dc->material = &s->materials[o->material];
    dc->model = o->transform;
    dc->mvp = refl_mat4_mul(vp, o->transform);
    dc->normal_m = refl__normal_matrix(o->transform);
}

/* Draws a mesh's triangles (indices NULL: all of them) with the bound
   state: positions read three floats at a time, num_varyings from the
   vertex program. */
static rast_result refl__draw_mesh(rast_context *rc, const refl_mesh *m, const uint32_t *indices, int index_count,
                                   int num_varyings) {
    rast_draw_desc d;
    memset(&d, 0, sizeof d);
    d.primitive = RAST_TRIANGLES;
    d.vertices = m->positions;
    d.vertex_count = m->vertex_count;
    d.stride = 3;
    d.position_size = 3;
    d.num_varyings = num_varyings;
    d.indices = indices ? indices : m->indices;
    d.index_count = indices ? index_count : 3 * m->triangle_count;
    return rast_draw(rc, &d);
}

/* The vertex program of the base pass: clip position and world-space
   varyings, read from the mesh by index. */
static int refl__base_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out) {
    const refl__draw_ctx *d = (const refl__draw_ctx *)user;
    const refl_mesh *m = d->mesh;
    refl_vec3 p = refl_v3(vertex[0], vertex[1], vertex[2]);
    refl_vec3 n = refl_v3(m->normals[3 * index], m->normals[3 * index + 1], m->normals[3 * index + 2]);
    refl_vec3 wp = refl_mat4_point(d->model, p), wn = refl_mat4_dir(d->normal_m, n);
    const float *mm = d->mvp.m;
    int k;
    (void)max_out;
    for (k = 0; k < 4; ++k) out->position[k] = mm[k] * p.x + mm[4 + k] * p.y + mm[8 + k] * p.z + mm[12 + k];
    out->varyings[0] = wp.x; out->varyings[1] = wp.y; out->varyings[2] = wp.z;
    out->varyings[3] = wn.x; out->varyings[4] = wn.y; out->varyings[5] = wn.z;
    out->varyings[6] = m->texcoords ? m->texcoords[2 * index] : 0.0f;
    out->varyings[7] = m->texcoords ? m->texcoords[2 * index + 1] : 0.0f;
    return 1;
}

/* What a diffuse surface shows of its shaded colour: never negative
   (REFL__RADIANCE, as the shared model keeps every surface), times 1 - mirror_weight on a partial reflector (its
   diffuse share; the methods add the mirror share); opaque. */
static void refl__surface_rgba(const refl_material *m, const float rgb[3], float rgba[4]) {
    float k = m->type == REFL_PARTIAL ? 1.0f - REFL__CLAMP(m->mirror_weight, 0.0f, 1.0f) : 1.0f;
    int c;
    for (c = 0; c < 3; ++c) rgba[c] = REFL__RADIANCE(rgb[c]) * k;
    rgba[3] = 1.0f;
}

/* The fragment program of the base pass: the shared diffuse model. */
static int refl__base_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__draw_ctx *d = (const refl__draw_ctx *)user;
    const float *v = in->varyings;
    float rgb[3];
    refl_shade_diffuse(d->scene, d->material, refl_v3(v[0], v[1], v[2]), refl_v3(v[3], v[4], v[5]), v + 6, rgb);
    refl__surface_rgba(d->material, rgb, rgba);
    return 1;
}

static int refl__clear_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    (void)user;
    (void)in;
    rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0.0f;
    return 1;
}

/* Draws every object but `skip`: diffuse ones shaded, reflectors with their
   diffuse share (partial) or black (mirror, glass), each writing its object
   id + 1 into the stencil. */
static refl_result refl__draw_scene(rast_context *rc, const refl_scene *scene, refl_mat4 vp, int skip,
                                    refl_stats *st) {
    refl__draw_ctx *dc;
    int i;
    rast_result rr = RAST_OK;
    /* one draw context per object: rast runs the callbacks at rast_finish */
    dc = (refl__draw_ctx *)refl__calloc(&scene->allocator, (size_t)REFL__MAX(scene->object_count, 1),
                                        sizeof(refl__draw_ctx));
    if (!dc) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < scene->object_count && rr == RAST_OK; ++i) {
        const refl_object *o = &scene->objects[i];
        const refl_mesh *m = scene->meshes[o->mesh];
        rast_state s;
        if (i == skip) continue;
        refl__draw_ctx_init(&dc[i], scene, i, vp);
        memset(&s, 0, sizeof s);
        s.depth_test = 1;
        s.stencil_test = 1;
        s.stencil_front.func = RAST_ALWAYS;
        s.stencil_front.pass = RAST_REPLACE;
        s.stencil_front.ref = (uint8_t)(i + 1 < 255 ? i + 1 : 255);
        s.stencil_back = s.stencil_front;
        s.vertex_fn = refl__base_vertex;
        s.vertex_user = &dc[i];
        if (dc[i].material->type == REFL_DIFFUSE || dc[i].material->type == REFL_PARTIAL) {
            s.fragment_fn = refl__base_fragment;
            s.fragment_user = &dc[i];
        }
        if (!refl__is_reflector(dc[i].material)) s.stencil_front.pass = s.stencil_back.pass = RAST_ZERO;
        /* mirrors and glass: transparent black until a method fills them */
        if (dc[i].material->type == REFL_MIRROR || dc[i].material->type == REFL_GLASS)
            s.fragment_fn = refl__clear_fragment;
        rr = rast_set_state(rc, &s);
        if (rr == RAST_OK) rr = refl__draw_mesh(rc, m, NULL, 0, REFL__BASE_VARYINGS);
        st->triangles += m->triangle_count;
    }
    if (rr == RAST_OK) rr = rast_finish(rc);
    refl__free(&scene->allocator, dc);
    return refl__result_from_rast(rr);
}

/* The environment behind the geometry: every pixel the scene left at the
   far plane shows the environment along its view ray. */
static void refl__draw_background(float *color, const float *depth, int width, int height, int stride_px,
                                  const refl_scene *scene, refl_mat4 inv_vp) {
    int x, y;
    for (y = 0; y < height; ++y)
        for (x = 0; x < width; ++x) {
            size_t i = (size_t)y * (size_t)stride_px + (size_t)x;
            float nx, ny, rgb[3];
            refl_vec3 a, b;
            int c;
            if (depth[i] < 1.0f) continue;
            nx = 2.0f * ((float)x + 0.5f) / (float)width - 1.0f;
            ny = 1.0f - 2.0f * ((float)y + 0.5f) / (float)height;
            a = refl_mat4_point(inv_vp, refl_v3(nx, ny, -1.0f));
            b = refl_mat4_point(inv_vp, refl_v3(nx, ny, 1.0f));
            refl_environment_lookup(&scene->environment, refl_v3_sub(b, a), rgb);
            for (c = 0; c < 3; ++c) color[4 * i + (size_t)c] = REFL__RADIANCE(rgb[c]);
            color[4 * i + 3] = 1.0f;
        }
}
