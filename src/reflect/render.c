/* Frames and the one entry point, refl_render: the base pass every method
   shares (diffuse geometry shaded per pixel, reflectors into the stencil),
   the environment behind everything, and the per-method middle step.
   DIRECT is the base pass alone; RAYTRACE renders the whole frame itself. */
#include "internal.h"

#include <time.h>

static const char *const refl__method_names[REFL_METHOD_COUNT] = {
    "direct", "direct", "raytrace", "envmap", "planar", "sbc", "c3rc", "spoc", "graphcam", "layered-em", "auto"};

REFL_API const char *refl_method_name(refl_method m) {
    return (int)m >= 0 && m < REFL_METHOD_COUNT ? refl__method_names[m] : "unknown";
}

REFL_API refl_method refl_method_from_name(const char *name) {
    int i;
    for (i = 1; name && i < REFL_METHOD_COUNT; ++i)
        if (!strcmp(name, refl__method_names[i])) return (refl_method)i;
    return REFL_METHOD_DEFAULT;
}

REFL_API refl_result refl_frame_create(int width, int height, const refl_allocator *a, refl_frame **out_frame) {
    refl_frame *f;
    size_t n;
    if (!out_frame) return REFL_ERROR_INVALID_ARGUMENT;
    *out_frame = NULL;
    if (width <= 0 || height <= 0 || width > RAST_MAX_TARGET_SIZE || height > RAST_MAX_TARGET_SIZE)
        return REFL_ERROR_INVALID_SIZE;
    if (a && ((a->alloc != NULL) != (a->free != NULL))) return REFL_ERROR_INVALID_ARGUMENT;
    n = (size_t)width * (size_t)height;
    f = (refl_frame *)refl__calloc(a, 1, sizeof(refl_frame));
    if (!f) return REFL_ERROR_OUT_OF_MEMORY;
    f->allocator = refl__allocator(a);
    f->width = width;
    f->height = height;
    f->color = (uint8_t *)refl__calloc(a, n, 4);
    f->depth = (float *)refl__calloc(a, n, sizeof(float));
    f->stencil = (uint8_t *)refl__calloc(a, n, 1);
    f->points = (float *)refl__calloc(a, n, 3 * sizeof(float));
    if (!f->color || !f->depth || !f->stencil || !f->points) {
        refl_frame_destroy(f);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    *out_frame = f;
    return REFL_OK;
}

REFL_API void refl_frame_destroy(refl_frame *f) {
    refl_allocator a;
    if (!f) return;
    a = f->allocator;
    refl__free(&a, f->color);
    refl__free(&a, f->depth);
    refl__free(&a, f->stencil);
    refl__free(&a, f->points);
    refl__free(&a, f);
}

/* Milliseconds from a monotonic clock. Timings go into stats only, never
   into images. Strict C99 has no such clock: define _POSIX_C_SOURCE
   200809L before the implementation's includes, or REFL_NOW_MS(). */
#ifdef REFL_NOW_MS
static double refl__now_ms(void) { return REFL_NOW_MS(); }
#else
static double refl__now_ms(void) {
#if defined(CLOCK_MONOTONIC)
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
#else
    return 0.0;
#endif
}
#endif

/* Near and far planes: the view's, or from the scene's bounds. */
static void refl__view_planes(const refl_view *v, const refl_scene *scene, float *out_near, float *out_far) {
    float znear = v->znear, zfar = v->zfar;
    if (!(znear > 0.0f) || !(zfar > znear)) {
        /* from the scene's bounding sphere: far just beyond it, near a
           fraction of far (24 bits of depth keep plenty of precision) */
        refl_vec3 lo, hi, c;
        float radius, dist;
        refl_scene_bounds(scene, &lo, &hi);
        c = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
        radius = 0.5f * refl_v3_length(refl_v3_sub(hi, lo));
        dist = refl_v3_length(refl_v3_sub(v->eye, c));
        zfar = REFL__MAX(dist + radius, 1e-3f) * 1.01f;
        znear = REFL__MAX(dist - radius, zfar * 1e-3f);
        znear = REFL__MAX(znear * 0.5f, zfar * 1e-4f);
    }
    *out_near = znear;
    *out_far = zfar;
}

REFL_API void refl_view_matrices(const refl_view *v, const refl_scene *scene, refl_mat4 *view_m,
                                 refl_mat4 *proj_m) {
    float znear, zfar;
    float fovy = v->fovy_degrees > 0.0f ? v->fovy_degrees : 45.0f;
    float aspect = v->height > 0 ? (float)v->width / (float)v->height : 1.0f;
    refl__view_planes(v, scene, &znear, &zfar);
    if (view_m) *view_m = refl_mat4_look_at(v->eye, v->target, v->up);
    if (proj_m) *proj_m = refl_mat4_perspective(fovy * (float)(REFL__PI / 180.0), aspect, znear, zfar);
}

static void refl__view_rays_init(refl__view_rays *r, const refl_view *v, const refl_scene *scene) {
    float fovy = v->fovy_degrees > 0.0f ? v->fovy_degrees : 45.0f;
    float aspect = v->height > 0 ? (float)v->width / (float)v->height : 1.0f;
    float t = tanf(0.5f * fovy * (float)(REFL__PI / 180.0));
    r->eye = v->eye;
    /* the basis of refl_mat4_look_at */
    r->forward = refl_v3_normalize(refl_v3_sub(v->target, v->eye));
    r->right = refl_v3_normalize(refl_v3_cross(r->forward, v->up));
    r->up = refl_v3_scale(refl_v3_cross(r->right, r->forward), t);
    r->right = refl_v3_scale(r->right, t * aspect);
    refl__view_planes(v, scene, &r->znear, &r->zfar);
    r->width = v->width;
    r->height = v->height;
}

static void refl__view_rays_get(const refl__view_rays *r, float px, float py, refl_vec3 *origin, refl_vec3 *dir,
                                float *tmax) {
    float nx = 2.0f * px / (float)r->width - 1.0f, ny = 1.0f - 2.0f * py / (float)r->height;
    refl_vec3 d = refl_v3_add(r->forward, refl_v3_add(refl_v3_scale(r->right, nx), refl_v3_scale(r->up, ny)));
    float len = refl_v3_length(d); /* d . forward = 1: len is 1 / cos of the angle off axis */
    *origin = refl_v3_add(r->eye, refl_v3_scale(d, r->znear));
    *dir = refl_v3_scale(d, 1.0f / len);
    *tmax = (r->zfar - r->znear) * len;
}

REFL_API void refl_view_ray(const refl_view *view, const refl_scene *scene, float px, float py, refl_vec3 *origin,
                            refl_vec3 *dir, float *tmax) {
    refl__view_rays r;
    refl_vec3 o, d;
    float t;
    refl__view_rays_init(&r, view, scene);
    refl__view_rays_get(&r, px, py, &o, &d, &t);
    if (origin) *origin = o;
    if (dir) *dir = d;
    if (tmax) *tmax = t;
}

/* ---- the base pass ---------------------------------------------------------- */

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
static void refl__draw_background(uint8_t *color, const float *depth, int width, int height, int stride_px,
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
            for (c = 0; c < 3; ++c) {
                float v = REFL__CLAMP(rgb[c], 0.0f, 1.0f);
                color[4 * i + (size_t)c] = (uint8_t)(v * 255.0f + 0.5f);
            }
            color[4 * i + 3] = 255;
        }
}

static int refl__view_ok(const refl_view *v) {
    refl_vec3 fwd = refl_v3_sub(v->target, v->eye);
    return refl__isfinite(v->eye.x) && refl__isfinite(v->eye.y) && refl__isfinite(v->eye.z) &&
           refl_v3_length(fwd) > 0.0f && refl_v3_length(refl_v3_cross(fwd, v->up)) > 0.0f &&
           v->fovy_degrees >= 0.0f && v->fovy_degrees < 180.0f;
}

/* refl_render, or (sbc_measure) SBC's cameras measured in place of its reflections. */
static refl_result refl__render(const refl_scene *scene, const refl_view *view, const refl_render_desc *desc,
                                refl_frame *frame, struct refl__sb_measure *sbc_measure) {
    refl__pass p;
    rast_context_desc cd;
    rast_targets t;
    rast_clear_desc clear;
    refl_mat4 inv_vp;
    refl_result r;
    double t0 = refl__now_ms(), t1;
    size_t n, k;
    int i;
    if (!scene || !view || !frame) return REFL_ERROR_INVALID_ARGUMENT;
    memset(&p, 0, sizeof p);
    if (desc) p.desc = *desc;
    if ((int)p.desc.method < 0 || p.desc.method >= REFL_METHOD_COUNT || p.desc.threads < 0 || p.desc.depth < 0 ||
        p.desc.envmap_size < 0 || p.desc.envmap_size > 8192 || p.desc.soft_shadow_samples < 0 ||
        p.desc.soft_shadow_samples > 1024 || !(p.desc.point_density >= 0.0f) ||
        !refl__isfinite(p.desc.point_density) || p.desc.kd_leaf_points < 0 || p.desc.max_splat < 0 ||
        p.desc.max_splat > 64 || !refl__isfinite(p.desc.camera_split_px) || !(p.desc.sbc_error_px >= 0.0f) ||
        !refl__isfinite(p.desc.sbc_error_px) || p.desc.sbc_ray_factor < 0 || p.desc.sbc_ray_factor > 64 ||
        p.desc.sbc_batch_groups < 0 || p.desc.sbc_batch_groups > 254 ||
        p.desc.sbc_trace_fallback < 0 || p.desc.sbc_trace_fallback > 1 || p.desc.sbc_mixed_levels > 6 ||
        p.desc.light_volumes < 0 || p.desc.caustic_samples < 0 || p.desc.caustic_samples > 1024 ||
        !(p.desc.translucency >= 0.0f) || !refl__isfinite(p.desc.translucency) || p.desc.sbc_morph_count < 0 ||
        (p.desc.sbc_morph_count > 0 && !p.desc.sbc_morphs))
        return REFL_ERROR_INVALID_ARGUMENT;
    if (view->width != frame->width || view->height != frame->height) return REFL_ERROR_INVALID_SIZE;
    if (!refl__view_ok(view)) return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < scene->object_count; ++i)
        if (scene->objects[i].mesh < 0 || scene->objects[i].mesh >= scene->mesh_count ||
            scene->objects[i].material < 0 || scene->objects[i].material >= scene->material_count)
            return REFL_ERROR_INVALID_ARGUMENT;
    if (p.desc.method == REFL_METHOD_DEFAULT) p.desc.method = REFL_DIRECT;
    if (p.desc.method != REFL_DIRECT && p.desc.method != REFL_RAYTRACE && p.desc.method != REFL_ENVMAP &&
        p.desc.method != REFL_PLANAR && p.desc.method != REFL_C3RC && p.desc.method != REFL_SBC)
        return REFL_ERROR_UNSUPPORTED;
    if (p.desc.depth == 0) p.desc.depth = 6;
    if (p.desc.envmap_size == 0) p.desc.envmap_size = 256;
    p.scene = scene;
    p.view = view;
    p.frame = frame;
    p.sbc_measure = sbc_measure;
    memset(&frame->stats, 0, sizeof(frame->stats));
    n = (size_t)frame->width * (size_t)frame->height;
    for (k = 0; k < 3 * n; ++k) frame->points[k] = NAN;
    refl_view_matrices(view, scene, &p.view_m, &p.proj_m);
    p.vp = refl_mat4_mul(p.proj_m, p.view_m);
    refl__view_rays_init(&p.rays, view, scene);

    memset(&cd, 0, sizeof cd);
    cd.num_threads = p.desc.threads;
    cd.allocator.alloc = scene->allocator.alloc;
    cd.allocator.free = scene->allocator.free;
    cd.allocator.user = scene->allocator.user;
    r = refl__result_from_rast(rast_context_create(&cd, &p.rc));
    if (r != REFL_OK) return r;
    t = refl__frame_targets(frame);
    memset(&clear, 0, sizeof clear);
    clear.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL;
    clear.depth = 1.0f;
    r = refl__result_from_rast(rast_set_targets(p.rc, &t));
    if (r == REFL_OK) r = refl__result_from_rast(rast_clear(p.rc, &clear));
    if (r != REFL_OK) {
        rast_context_destroy(p.rc);
        return r;
    }
    if (p.desc.progress) p.desc.progress(p.desc.progress_user, 0.0f);
    if (p.desc.method == REFL_RAYTRACE) {
        r = refl__method_raytrace(&p);
    } else {
        r = refl__draw_scene(p.rc, scene, p.vp, -1, &frame->stats);
        /* shadows: the pixels a light cannot (wholly) reach shaded again (shadow.c) */
        if (r == REFL_OK && p.desc.shadows) r = refl__shadow_base_pass(&p);
        if (r == REFL_OK && refl_mat4_invert(p.vp, &inv_vp))
            refl__draw_background(frame->color, frame->depth, frame->width, frame->height, frame->width, scene,
                                  inv_vp);
        t1 = refl__now_ms();
        frame->stats.ms_base = t1 - t0;
        if (r == REFL_OK && p.desc.method == REFL_ENVMAP) r = refl__method_envmap(&p);
        if (r == REFL_OK && p.desc.method == REFL_PLANAR) r = refl__method_planar(&p);
        if (r == REFL_OK && p.desc.method == REFL_C3RC) r = refl__method_c3rc(&p);
        if (r == REFL_OK && p.desc.method == REFL_SBC) r = refl__method_sbc(&p);
    }
    rast_context_destroy(p.rc);
    if (r != REFL_OK) return r;
    frame->stats.ms_total = refl__now_ms() - t0;
    for (i = 0; i < scene->object_count; ++i)
        if (refl__is_reflector(&scene->materials[scene->objects[i].material])) frame->stats.reflectors++;
    if (p.desc.progress) p.desc.progress(p.desc.progress_user, 1.0f);
    return REFL_OK;
}

REFL_API refl_result refl_render(const refl_scene *scene, const refl_view *view, const refl_render_desc *desc,
                                 refl_frame *frame) {
    return refl__render(scene, view, desc, frame, NULL);
}
