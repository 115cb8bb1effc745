/* Frames, views and their rays, the method table, the renderer and the
   flow of a frame: the base pass every method shares (base_pass.c's
   drawing, then shadows, then the environment behind everything), then
   the per-reflector methods. DIRECT is the base pass alone; RAYTRACE
   renders the whole frame itself. */
#include "internal.h"

#include <time.h>

static const char *const refl__method_names[REFL_METHOD_COUNT] = {
    "direct", "direct", "raytrace", "envmap", "planar", "sbc", "c3rc", "spoc", "graphcam", "layered-em", "auto"};

REFL_API const char *refl_method_name(refl_method m) {
    return (int)m >= 0 && m < REFL_METHOD_COUNT ? refl__method_names[m] : "unknown";
}

/* ASCII letters compared without case, as method names are written both ways. */
static int refl__same_name(const char *a, const char *b) {
    for (; *a && *b; ++a, ++b) {
        char x = *a >= 'A' && *a <= 'Z' ? (char)(*a - 'A' + 'a') : *a;
        char y = *b >= 'A' && *b <= 'Z' ? (char)(*b - 'A' + 'a') : *b;
        if (x != y) return 0;
    }
    return *a == *b;
}

REFL_API refl_method refl_method_from_name(const char *name) {
    int i;
    for (i = 1; name && i < REFL_METHOD_COUNT; ++i)
        if (refl__same_name(name, refl__method_names[i])) return (refl_method)i;
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
    f->message = "";
    f->rgba = (float *)refl__calloc(a, n, 4 * sizeof(float));
    f->depth = (float *)refl__calloc(a, n, sizeof(float));
    f->stencil = (uint8_t *)refl__calloc(a, n, 1);
    f->points = (float *)refl__calloc(a, n, 3 * sizeof(float));
    if (!f->rgba || !f->depth || !f->stencil || !f->points) {
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
    refl__free(&a, f->rgba);
    refl__free(&a, f->depth);
    refl__free(&a, f->stencil);
    refl__free(&a, f->points);
    refl__free(&a, f);
}

REFL_API uint8_t refl_display_channel(float linear, const refl_display_desc *d) {
    float x = linear * (d ? exp2f(d->exposure) : 1.0f), e;
    if (!(x > 0.0f)) return 0; /* negative, zero and NaN */
    if (d && d->tonemap == REFL_TONEMAP_REINHARD) x = x / (1.0f + x);
    else if (d && d->tonemap == REFL_TONEMAP_ACES) x = x * (2.51f * x + 0.03f) / (x * (2.43f * x + 0.59f) + 0.14f);
    if (!(x < 1.0f)) return 255; /* +inf and the ACES quotient of two infinities */
    e = x <= 0.0031308f ? 12.92f * x : 1.055f * powf(x, 1.0f / 2.4f) - 0.055f;
    return refl__unorm8(e);
}

REFL_API void refl_frame_to_srgb8(const refl_frame *f, const refl_display_desc *d, uint8_t *out) {
    size_t i, n;
    int c;
    if (!f || !out) return;
    n = (size_t)f->width * (size_t)f->height;
    for (i = 0; i < n; ++i) {
        for (c = 0; c < 3; ++c) out[4 * i + (size_t)c] = refl_display_channel(f->rgba[4 * i + (size_t)c], d);
        out[4 * i + 3] = refl__unorm8(f->rgba[4 * i + 3]);
    }
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
    float znear, zfar, fovy, aspect;
    if (!v) {
        if (view_m) *view_m = refl_mat4_identity();
        if (proj_m) *proj_m = refl_mat4_identity();
        return;
    }
    fovy = v->fovy_degrees > 0.0f ? v->fovy_degrees : 45.0f;
    aspect = v->height > 0 ? (float)v->width / (float)v->height : 1.0f;
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
    refl_vec3 o = refl_v3(0, 0, 0), d = refl_v3(0, 0, 0);
    float t = 0.0f;
    if (view) {
        refl__view_rays_init(&r, view, scene);
        refl__view_rays_get(&r, px, py, &o, &d, &t);
    }
    if (origin) *origin = o;
    if (dir) *dir = d;
    if (tmax) *tmax = t;
}

/* ---- the method table ---------------------------------------------------------- */

enum {
    REFL__WHOLE_FRAME = 1,        /* as the frame's method: renders every pixel itself, no base pass */
    REFL__PER_REFLECTOR = 2       /* fills the reflectors it is given after the base pass */
};

typedef struct refl__method_row {
    refl_method method;
    unsigned kind;                /* REFL__WHOLE_FRAME and/or REFL__PER_REFLECTOR */
    refl_result (*draw)(refl__pass *p);       /* NULL: nothing past the base pass (DIRECT) */
    const char *(*options)(refl_render_desc *d);
    /* NULL: it draws any reflector; else whether it can draw object i
       (those it cannot go to RAYTRACE's tracer, stats.handed_over) */
    refl_result (*handles)(const refl__pass *p, int object, int *can);
    int max_depth;                /* bounces it models at most; those past it are traced
                                     (refl__trace_beyond) */
} refl__method_row;

enum { REFL__ANY_DEPTH = 1 << 30 };

/* A `handles` of the methods that draw mirrors and partial mirrors and hand
   glass to RAYTRACE's tracer (C3RC, SPOC, GRAPHCAM: one bounce cannot
   leave a glass object). */
static refl_result refl__declines_glass(const refl__pass *p, int object, int *can) {
    *can = p->scene->materials[p->scene->objects[object].material].type != REFL_GLASS;
    return REFL_OK;
}

/* The built methods, in the order a frame runs them. A method without a
   row returns REFL_ERROR_UNSUPPORTED. */
static const refl__method_row refl__methods[] = {
    {REFL_DIRECT, REFL__PER_REFLECTOR, NULL, NULL, NULL, 0},
    {REFL_RAYTRACE, REFL__WHOLE_FRAME | REFL__PER_REFLECTOR, refl__method_raytrace, refl__options_raytrace, NULL,
     REFL__ANY_DEPTH},
    {REFL_ENVMAP, REFL__PER_REFLECTOR, refl__method_envmap, refl__options_envmap, NULL, 1},
    {REFL_PLANAR, REFL__PER_REFLECTOR, refl__method_planar, refl__options_planar, refl__planar_handles,
     REFL__ANY_DEPTH},
    {REFL_C3RC, REFL__PER_REFLECTOR, refl__method_c3rc, refl__options_c3rc, refl__declines_glass, 1},
    {REFL_SBC, REFL__PER_REFLECTOR, refl__method_sbc, refl__options_sbc, refl__sbc_handles, REFL__SB_ORDERS},
    {REFL_SPOC, REFL__PER_REFLECTOR, refl__method_spoc, refl__options_spoc, refl__spoc_handles, 2},
    {REFL_GRAPHCAM, REFL__PER_REFLECTOR, refl__method_graphcam, refl__options_graphcam, refl__declines_glass, 1},
    {REFL_LAYERED_EM, REFL__PER_REFLECTOR, refl__method_layered_em, refl__options_layered_em, NULL, REFL__ANY_DEPTH},
    /* draws nothing itself: each of its reflectors goes to the method it picks (refl__drawn_by) */
    {REFL_AUTO, REFL__PER_REFLECTOR, NULL, refl__options_auto, NULL, REFL__ANY_DEPTH},
};
enum { REFL__METHOD_ROWS = (int)(sizeof refl__methods / sizeof refl__methods[0]) };

static const refl__method_row *refl__method_row_of(refl_method m) {
    int i;
    for (i = 0; i < REFL__METHOD_ROWS; ++i)
        if (refl__methods[i].method == m) return &refl__methods[i];
    return NULL;
}

/* The method that draws object i. */
static refl_method refl__object_method(const refl_render_desc *d, int i) {
    return i < d->object_method_count && d->object_methods[i] != REFL_METHOD_DEFAULT ? d->object_methods[i]
                                                                                     : d->method;
}

/* Samples along a pixel's side for desc.spp (0: 1). */
static int refl__spp_side(int spp) {
    int s = 1;
    while ((s + 1) * (s + 1) <= spp) ++s;
    return s;
}

static refl_result refl__resolve_desc(const refl_render_desc *desc, refl_render_desc *out, const char **message) {
    const char *why = NULL;
    int i;
    *message = "";
    memset(out, 0, sizeof *out);
    if (desc) *out = *desc;
    if ((int)out->method < 0 || out->method >= REFL_METHOD_COUNT) why = "method: not a refl_method";
    else if (out->threads < 0 || out->threads > RAST_MAX_THREADS) why = "threads: 0 (one per CPU) to 64";
    else if (out->depth < 0) why = "depth: 0 (REFL_DEFAULT_DEPTH) or more";
    else if (out->spp < 0 || out->spp > 64 || refl__spp_side(out->spp) * refl__spp_side(out->spp) != REFL__MAX(out->spp, 1))
        why = "spp: 0 or 1, 4, 9, 16, 25, 36, 49 or 64";
    else if (out->lighting.shadows < 0 || out->lighting.shadows > 1) why = "lighting.shadows: 0 or 1";
    else if (out->lighting.soft_shadow_samples < 0 || out->lighting.soft_shadow_samples > 1024)
        why = "lighting.soft_shadow_samples: 0 to 1024";
    else if (out->lighting.light_volumes < 0 || out->lighting.light_volumes > 1)
        why = "lighting.light_volumes: 0 or 1";
    else if (out->lighting.caustic_samples < 0 || out->lighting.caustic_samples > 1024)
        why = "lighting.caustic_samples: 0 to 1024";
    else if (!(out->lighting.translucency >= 0.0f) || !refl__isfinite(out->lighting.translucency))
        why = "lighting.translucency: finite, 0 or more";
    else if (out->object_method_count < 0 || (out->object_method_count > 0 && !out->object_methods))
        why = "object_methods: object_method_count 0, or the array of that many";
    else if (out->debug.points_last < 0 || out->debug.points_last > 1) why = "debug.points_last: 0 or 1";
    for (i = 0; !why && i < REFL__METHOD_ROWS; ++i)
        if (refl__methods[i].options) why = refl__methods[i].options(out);
    if (!why && out->method == REFL_METHOD_DEFAULT) out->method = REFL_DIRECT;
    for (i = 0; !why && i < out->object_method_count; ++i)
        if ((int)out->object_methods[i] < 0 || out->object_methods[i] >= REFL_METHOD_COUNT)
            why = "object_methods: an entry is not a refl_method";
    if (!why && out->object_method_count > 0 && refl__method_row_of(out->method) &&
        (refl__method_row_of(out->method)->kind & REFL__WHOLE_FRAME))
        why = "object_methods: must be empty when method is RAYTRACE (it renders whole frames)";
    if (why) {
        *message = why;
        return REFL_ERROR_INVALID_ARGUMENT;
    }
    if (out->depth == 0) out->depth = REFL_DEFAULT_DEPTH;
    return REFL_OK;
}

REFL_API int refl_method_is_built(refl_method m) { return m == REFL_METHOD_DEFAULT || refl__method_row_of(m) != NULL; }

REFL_API refl_result refl_validate_render_desc(const refl_render_desc *desc, const char **message) {
    refl_render_desc d;
    const char *why;
    refl_result r = refl__resolve_desc(desc, &d, &why);
    if (message) *message = why;
    return r;
}

/* ---- a frame ------------------------------------------------------------------- */

static const char *refl__frame_rule(const refl_scene *scene, const refl_view *v, const refl_frame *frame) {
    refl_vec3 fwd = refl_v3_sub(v->target, v->eye);
    int i;
    if (v->width != frame->width || v->height != frame->height) return "view: its size is not the frame's";
    if (!refl__v3_finite(v->eye)) return "view.eye: finite";
    if (!refl__v3_finite(v->target)) return "view.target: finite";
    if (!refl__v3_finite(v->up)) return "view.up: finite";
    if (!refl__isfinite(v->znear) || !refl__isfinite(v->zfar)) return "view.znear, zfar: finite";
    if (!(refl_v3_length(fwd) > 0.0f)) return "view.target: away from the eye";
    if (!(refl_v3_length(refl_v3_cross(fwd, v->up)) > 0.0f)) return "view.up: not along the line of sight";
    if (!(v->fovy_degrees >= 0.0f && v->fovy_degrees < 180.0f)) return "view.fovy_degrees: 0 (45) up to 180";
    /* the objects before the view's matrices: the scene's bounds (its near
       and far planes) read their meshes and transforms */
    for (i = 0; i < scene->object_count; ++i)
        if (scene->objects[i].mesh < 0 || scene->objects[i].mesh >= scene->mesh_count ||
            scene->objects[i].material < 0 || scene->objects[i].material >= scene->material_count)
            return "scene.objects: a mesh or material index out of range";
        else if (!refl__all_finite(scene->objects[i].transform.m, 16))
            return "scene.objects: every transform finite";
    {
        refl_mat4 vm, pm;
        refl_view_matrices(v, scene, &vm, &pm);
        if (!refl__all_finite(vm.m, 16) || !refl__all_finite(pm.m, 16))
            return "view: its matrices overflow float (eye, near or far too large)";
    }
    for (i = 0; i < scene->material_count + scene->light_count; ++i) {
        const char *why = i < scene->material_count ? refl__material_rule(&scene->materials[i], scene->texture_count)
                                                    : refl__light_rule(&scene->lights[i - scene->material_count]);
        if (why) return why;
    }
    if (!refl__all_finite(scene->ambient, 3)) return "scene.ambient: finite";
    if (!refl__all_finite(scene->environment.color, 3) || !refl__isfinite(scene->environment.intensity))
        return "scene.environment: colour and intensity finite";
    return NULL;
}

/* REFL_OK with frame->message "", or the error of the rule refl__frame_rule
   finds, named in frame->message. */
static refl_result refl__check_frame(const refl_scene *scene, const refl_view *view, refl_frame *frame) {
    const char *why = refl__frame_rule(scene, view, frame);
    frame->message = why ? why : "";
    if (!why) return REFL_OK;
    return view->width != frame->width || view->height != frame->height ? REFL_ERROR_INVALID_SIZE
                                                                        : REFL_ERROR_INVALID_ARGUMENT;
}

/* p for a frame of scene from view into frame, nothing drawn yet. */
static void refl__pass_init(refl__pass *p, const refl_scene *scene, const refl_view *view,
                            const refl_render_desc *desc, refl_frame *frame, rast_context *rc, refl__models *models) {
    memset(p, 0, sizeof *p);
    p->desc = *desc;
    p->scene = scene;
    p->view = view;
    p->frame = frame;
    p->rc = rc;
    p->models = models;
    refl_view_matrices(view, scene, &p->view_m, &p->proj_m);
    p->vp = refl_mat4_mul(p->proj_m, p->view_m);
    refl__view_rays_init(&p->rays, view, scene);
}

static refl_result refl__base_pass(refl__pass *p, const refl_scene *scene, const refl_view *view,
                                   const refl_render_desc *desc, refl_frame *frame, rast_context *rc,
                                   refl__models *models) {
    rast_targets t;
    rast_clear_desc clear;
    rast_state state;
    refl_mat4 inv_vp;
    refl_result r;
    double t0 = refl__now_ms();
    size_t n = (size_t)frame->width * (size_t)frame->height, k;
    refl__pass_init(p, scene, view, desc, frame, rc, models);
    for (k = 0; k < 3 * n; ++k) frame->points[k] = NAN;
    t = refl__frame_targets(frame);
    memset(&clear, 0, sizeof clear);
    clear.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL;
    clear.depth = 1.0f;
    memset(&state, 0, sizeof state); /* a renderer's context keeps the last frame's state: clears obey its masks */
    r = refl__result_from_rast(rast_set_targets(rc, &t));
    if (r == REFL_OK) r = refl__result_from_rast(rast_set_state(rc, &state));
    if (r == REFL_OK) r = refl__result_from_rast(rast_clear(rc, &clear));
    /* a whole-frame method writes the frame itself: the clear goes first,
       not when the context next flushes (onto this frame, kept by then) */
    if (r == REFL_OK && (refl__method_row_of(desc->method)->kind & REFL__WHOLE_FRAME))
        return refl__result_from_rast(rast_finish(rc));
    if (r != REFL_OK) return r;
    r = refl__draw_scene(rc, scene, p->vp, -1, &frame->stats);
    /* shadows: the pixels a light cannot (wholly) reach shaded again (shadow.c) */
    if (r == REFL_OK && desc->lighting.shadows) r = refl__shadow_base_pass(p);
    if (r == REFL_OK && refl_mat4_invert(p->vp, &inv_vp))
        refl__draw_background(frame->rgba, frame->depth, frame->width, frame->height, frame->width, scene, inv_vp);
    frame->stats.ms_base = refl__now_ms() - t0;
    return r;
}

/* The method that draws reflector object i (*by): its own or the frame's
   (AUTO: the one it picks), or RAYTRACE's tracer where that one cannot
   draw it (*handed_over). */
static refl_result refl__drawn_by(refl__pass *p, int i, uint8_t *by, int *handed_over) {
    refl_method m = refl__object_method(&p->desc, i);
    const refl__method_row *row;
    int can = 1;
    refl_result r = m == REFL_AUTO ? refl__auto_choose(p, i, &m) : REFL_OK;
    row = refl__method_row_of(m);
    if (r == REFL_OK && row->handles) r = row->handles(p, i, &can);
    *by = (uint8_t)(can ? m : REFL_RAYTRACE);
    *handed_over = !can;
    return r;
}

static refl_result refl__method_can_draw(const refl__pass *p, refl_method m, int object, int *can) {
    const refl__method_row *row = refl__method_row_of(m);
    *can = row && (row->kind & REFL__PER_REFLECTOR) && row->draw;
    return *can && row->handles ? row->handles(p, object, can) : REFL_OK;
}

/* The per-reflector methods of the frame, in table order, each given the
   reflectors that are its own. */
static refl_result refl__draw_reflectors(refl__pass *p) {
    const refl_scene *scene = p->scene;
    uint8_t *by = NULL;
    int *modelled = NULL;         /* per object: the bounces its method models */
    refl_result r = REFL_OK;
    int row, i, mixed = 0, depth = p->desc.depth, rows_used = 0, rows_done = 0, beyond = 0;
    by = (uint8_t *)refl__calloc(&scene->allocator, (size_t)REFL__MAX(scene->object_count, 1), 2);
    modelled = (int *)refl__calloc(&scene->allocator, (size_t)REFL__MAX(scene->object_count, 1), sizeof(int));
    if (!by || !modelled) {
        refl__free(&scene->allocator, modelled);
        refl__free(&scene->allocator, by);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i) {
        int handed_over;
        if (!refl__is_reflector(&scene->materials[scene->objects[i].material])) continue;
        r = refl__drawn_by(p, i, &by[i], &handed_over);
        mixed |= by[i] != (uint8_t)p->desc.method;
        p->frame->stats.handed_over += handed_over;
        modelled[i] = refl__method_row_of((refl_method)by[i])->max_depth;
        if (modelled[i] == 0) depth = 0;
        beyond |= modelled[i] > 0 && modelled[i] < p->desc.depth;
    }
    if (beyond && r == REFL_OK) {
        p->trace = (uint8_t *)refl__calloc(&scene->allocator, (size_t)p->frame->width * (size_t)p->frame->height, 1);
        if (!p->trace) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    for (row = 0; row < REFL__METHOD_ROWS; ++row)
        for (i = 0; i < scene->object_count; ++i)
            if (by[i] == (uint8_t)refl__methods[row].method && refl__methods[row].draw) {
                rows_used++;
                break;
            }
    for (row = 0; row < REFL__METHOD_ROWS && r == REFL_OK; ++row) {
        const refl__method_row *m = &refl__methods[row];
        uint8_t *mine = by + scene->object_count;
        int any = 0;
        if (!(m->kind & REFL__PER_REFLECTOR)) continue;
        for (i = 0; i < scene->object_count; ++i) {
            mine[i] = by[i] == (uint8_t)m->method;
            any |= mine[i];
        }
        if (!any || !m->draw) continue;
        p->mine = mixed ? mine : NULL; /* NULL: every reflector is the frame method's */
        r = m->draw(p);
        if (r == REFL_OK && ++rows_done < rows_used && refl__progress(p, (float)rows_done / (float)rows_used))
            r = REFL_ERROR_CANCELLED;
    }
    p->mine = NULL;
    if (r == REFL_OK && beyond) r = refl__trace_beyond(p, modelled);
    p->frame->stats.depth = depth;
    refl__free(&scene->allocator, p->trace);
    p->trace = NULL;
    refl__free(&scene->allocator, modelled);
    refl__free(&scene->allocator, by);
    return r;
}

/* What no method filled (DIRECT's reflectors, where a recursion ended)
   shows black, the base pass's colour for mirror and glass, opaque. */
static void refl__opaque(refl_frame *frame) {
    size_t i, n = (size_t)frame->width * (size_t)frame->height;
    for (i = 0; i < n; ++i) frame->rgba[4 * i + 3] = 1.0f;
}

/* ---- the renderer ---------------------------------------------------------------- */

struct refl_renderer {
    const refl_scene *scene;
    refl_render_desc desc;        /* validated, defaults resolved */
    rast_context *rc;             /* the thread pool */
    refl__models models;
    refl_frame *fine;             /* spp > 1: the frame of every sample, kept for the next */
};

static void refl__models_free(const refl_scene *scene, refl__models *m) {
    refl_bvh_destroy(m->bvh);
    refl_bvh_destroy(m->split[0]);
    refl_bvh_destroy(m->split[1]);
    refl__c3_samples_free(&scene->allocator, m->c3);
    refl__lem_maps_free(&scene->allocator, m->lem);
    memset(m, 0, sizeof *m);
}

static refl_result refl__models_bvh(refl__pass *p, refl_bvh **out, refl_bvh **owned) {
    refl_result r;
    *owned = NULL;
    if (p->models && p->models->bvh) {
        *out = p->models->bvh;
        return REFL_OK;
    }
    r = refl__bvh_build_on(p->scene, &p->scene->allocator, p->rc, out);
    if (r != REFL_OK) return r;
    p->frame->stats.scene_models_built++;
    if (p->models) p->models->bvh = *out;
    else *owned = *out;
    return REFL_OK;
}

static refl_result refl__context_create(const refl_scene *scene, int threads, rast_context **out) {
    rast_context_desc cd;
    memset(&cd, 0, sizeof cd);
    cd.num_threads = threads;
    cd.allocator.alloc = scene->allocator.alloc;
    cd.allocator.free = scene->allocator.free;
    cd.allocator.user = scene->allocator.user;
    return refl__result_from_rast(rast_context_create(&cd, out));
}

REFL_API refl_result refl_renderer_create(const refl_scene *scene, const refl_render_desc *desc,
                                          refl_renderer **out_renderer) {
    refl_renderer *rr;
    refl_render_desc d;
    const char *why;
    refl_result r;
    int i;
    if (!out_renderer) return REFL_ERROR_INVALID_ARGUMENT;
    *out_renderer = NULL;
    if (!scene) return REFL_ERROR_INVALID_ARGUMENT;
    if ((r = refl__resolve_desc(desc, &d, &why)) != REFL_OK) return r;
    if (!refl__method_row_of(d.method)) return REFL_ERROR_UNSUPPORTED;
    for (i = 0; i < d.object_method_count; ++i)
        if (d.object_methods[i] != REFL_METHOD_DEFAULT && !refl__method_row_of(d.object_methods[i]))
            return REFL_ERROR_UNSUPPORTED;
    rr = (refl_renderer *)refl__calloc(&scene->allocator, 1, sizeof *rr);
    if (!rr) return REFL_ERROR_OUT_OF_MEMORY;
    rr->scene = scene;
    rr->desc = d;
    rr->models.scene_version = scene->version;
    if ((r = refl__context_create(scene, d.threads, &rr->rc)) != REFL_OK) {
        refl__free(&scene->allocator, rr);
        return r;
    }
    *out_renderer = rr;
    return REFL_OK;
}

REFL_API void refl_renderer_destroy(refl_renderer *rr) {
    if (!rr) return;
    refl_frame_destroy(rr->fine);
    refl__models_free(rr->scene, &rr->models);
    rast_context_destroy(rr->rc);
    refl__free(&rr->scene->allocator, rr);
}

static void refl__frame_say(refl_frame *frame, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(frame->message_text, sizeof frame->message_text, fmt, ap);
    va_end(ap);
    frame->message = frame->message_text;
}

static refl_result refl__cancelled(refl_frame *frame) {
    frame->message = "cancelled by the progress callback";
    return REFL_ERROR_CANCELLED;
}

/* The renderer's models dropped when the scene changed since they were
   built; the BVH refit instead where only positions moved (refl_bvh_refit). */
static void refl__models_current(refl_renderer *rr) {
    refl__models kept = rr->models;
    struct refl__lem_maps *stale = rr->desc.layered_em.keep_stale_maps ? rr->models.lem : NULL;
    refl_bvh *bvh = kept.bvh;
    if (rr->models.scene_version == rr->scene->version) return;
    rr->models.bvh = rr->models.split[0] = rr->models.split[1] = NULL;
    rr->models.lem = stale ? NULL : rr->models.lem;
    refl__models_free(rr->scene, &rr->models);
    rr->models.lem = stale;
    /* refit, or rebuilt, by LAYERED_EM's next frame (refl__lem_split) */
    rr->models.split[0] = kept.split[0];
    rr->models.split[1] = kept.split[1];
    rr->models.split_version = kept.split_version;
    if (bvh && refl_bvh_refit(bvh, rr->scene) == REFL_OK) rr->models.bvh = bvh;
    else refl_bvh_destroy(bvh);
    rr->models.scene_version = rr->scene->version;
}

/* One render of view into frame, a sample per pixel. */
static refl_result refl__render_samples(refl_renderer *rr, const refl_view *view, refl_frame *frame) {
    const refl_scene *scene = rr->scene;
    const refl__method_row *row;
    refl__pass p;
    refl_result r;
    double t0 = refl__now_ms();
    long long tests0 = refl__bvh_tests_counted();
    int i;
    refl__models_current(rr);
    memset(&frame->stats, 0, sizeof(frame->stats));
    row = refl__method_row_of(rr->desc.method);
    if (rr->desc.progress && rr->desc.progress(rr->desc.progress_user, 0.0f)) return refl__cancelled(frame);
    r = refl__base_pass(&p, scene, view, &rr->desc, frame, rr->rc, &rr->models);
    frame->stats.depth = rr->desc.depth;
    if (r == REFL_OK && refl__progress(&p, 0.0f)) r = REFL_ERROR_CANCELLED;
    if (r == REFL_OK) r = (row->kind & REFL__WHOLE_FRAME) ? row->draw(&p) : refl__draw_reflectors(&p);
    if (r == REFL_OK) r = refl__result_from_rast(rast_finish(rr->rc)); /* nothing left pending on this frame */
    if (r == REFL_ERROR_CANCELLED) return refl__cancelled(frame);
    if (r != REFL_OK) return r;
    refl__opaque(frame);
    frame->stats.ms_total = refl__now_ms() - t0;
    frame->stats.triangle_tests = refl__bvh_tests_counted() - tests0;
    for (i = 0; i < scene->object_count; ++i)
        if (refl__is_reflector(&scene->materials[scene->objects[i].material])) frame->stats.reflectors++;
    if (rr->desc.progress) rr->desc.progress(rr->desc.progress_user, 1.0f);
    return REFL_OK;
}

/* Pixel by pixel, the mean colour of its side x side samples in fine, and
   the depth, stencil and point of its centre sample. */
static void refl__resolve_spp(const refl_frame *fine, refl_frame *frame, int side) {
    int x, y, sx, sy, c, centre = side / 2;
    float w = 1.0f / (float)(side * side);
    for (y = 0; y < frame->height; ++y)
        for (x = 0; x < frame->width; ++x) {
            size_t i = (size_t)y * (size_t)frame->width + (size_t)x;
            size_t k = ((size_t)(y * side + centre)) * (size_t)fine->width + (size_t)(x * side + centre);
            float sum[4] = {0, 0, 0, 0};
            for (sy = 0; sy < side; ++sy)
                for (sx = 0; sx < side; ++sx) {
                    const float *q = fine->rgba + 4 * ((size_t)(y * side + sy) * (size_t)fine->width + (size_t)(x * side + sx));
                    for (c = 0; c < 4; ++c) sum[c] += q[c];
                }
            for (c = 0; c < 4; ++c) frame->rgba[4 * i + (size_t)c] = sum[c] * w;
            frame->depth[i] = fine->depth[k];
            frame->stencil[i] = fine->stencil[k];
            memcpy(frame->points + 3 * i, fine->points + 3 * k, 3 * sizeof(float));
        }
}

/* With spp > 1: view at sqrt(spp) times its size into *fine_view, and
   rr->fine made that size. */
static refl_result refl__fine_frame(refl_renderer *rr, const refl_view *view, int side, refl_frame *frame,
                                    refl_view *fine_view) {
    *fine_view = *view;
    fine_view->width = view->width * side;
    fine_view->height = view->height * side;
    if (fine_view->width > RAST_MAX_TARGET_SIZE || fine_view->height > RAST_MAX_TARGET_SIZE) {
        frame->message = "spp: the frame's side times sqrt(spp) above RAST_MAX_TARGET_SIZE";
        return REFL_ERROR_INVALID_SIZE;
    }
    if (rr->fine && (rr->fine->width != fine_view->width || rr->fine->height != fine_view->height)) {
        refl_frame_destroy(rr->fine);
        rr->fine = NULL;
    }
    if (!rr->fine)
        return refl_frame_create(fine_view->width, fine_view->height, &rr->scene->allocator, &rr->fine);
    return REFL_OK;
}

REFL_API refl_result refl_renderer_prebuild(refl_renderer *rr, const refl_view *view, refl_frame *frame) {
    refl_view fine_view;
    refl_frame *target = frame;
    refl__pass p;
    refl_result r;
    double t0 = refl__now_ms();
    long long tests0 = refl__bvh_tests_counted();
    int side, i, lem = 0;
    uint8_t *mine;
    if (!rr || !view || !frame) return REFL_ERROR_INVALID_ARGUMENT;
    frame->message = "";
    if ((r = refl__check_frame(rr->scene, view, frame)) != REFL_OK) return r;
    side = refl__spp_side(rr->desc.spp);
    fine_view = *view;
    if (side > 1) { /* the maps of the views the frames render */
        if ((r = refl__fine_frame(rr, view, side, frame, &fine_view)) != REFL_OK) return r;
        target = rr->fine;
    }
    refl__models_current(rr);
    memset(&target->stats, 0, sizeof target->stats);
    refl__pass_init(&p, rr->scene, &fine_view, &rr->desc, target, rr->rc, &rr->models);
    mine = (uint8_t *)refl__calloc(&rr->scene->allocator, (size_t)REFL__MAX(rr->scene->object_count, 1), 1);
    if (!mine) return REFL_ERROR_OUT_OF_MEMORY;
    p.mine = mine;
    for (i = 0; i < rr->scene->object_count; ++i) {
        mine[i] = refl__object_method(&rr->desc, i) == REFL_LAYERED_EM;
        lem |= mine[i] && refl__pass_draws(&p, i);
    }
    if (lem) r = refl__prebuild_layered_em(&p);
    refl__free(&rr->scene->allocator, mine);
    if (target != frame) frame->stats = target->stats;
    frame->stats.ms_total = refl__now_ms() - t0;
    frame->stats.triangle_tests = refl__bvh_tests_counted() - tests0;
    if (r == REFL_ERROR_CANCELLED) return refl__cancelled(frame);
    if (r == REFL_OK && rr->desc.progress) rr->desc.progress(rr->desc.progress_user, 1.0f);
    return r;
}

REFL_API refl_result refl_renderer_lem_lenses(refl_renderer *rr, const refl_view *view, refl_frame *frame,
                                              refl_lem_lens **out, int *count) {
    refl__pass p;
    refl_result r;
    int i;
    uint8_t *mine;
    if (out) *out = NULL;
    if (count) *count = 0;
    if (!rr || !view || !frame || !out || !count) return REFL_ERROR_INVALID_ARGUMENT;
    frame->message = "";
    if ((r = refl__check_frame(rr->scene, view, frame)) != REFL_OK) return r;
    if (refl__spp_side(rr->desc.spp) != 1) return REFL_ERROR_INVALID_ARGUMENT;
    refl__models_current(rr);
    memset(&frame->stats, 0, sizeof frame->stats);
    refl__pass_init(&p, rr->scene, view, &rr->desc, frame, rr->rc, &rr->models);
    mine = (uint8_t *)refl__calloc(&rr->scene->allocator, (size_t)REFL__MAX(rr->scene->object_count, 1), 1);
    if (!mine) return REFL_ERROR_OUT_OF_MEMORY;
    p.mine = mine;
    for (i = 0; i < rr->scene->object_count; ++i) mine[i] = refl__object_method(&rr->desc, i) == REFL_LAYERED_EM;
    r = refl__lem_lenses(&p, out, count);
    refl__free(&rr->scene->allocator, mine);
    return r;
}

REFL_API void refl_renderer_lem_lenses_free(refl_renderer *rr, refl_lem_lens *lenses, int count) {
    int i;
    if (!rr || !lenses) return;
    for (i = 0; i < count; ++i) {
        refl__free(&rr->scene->allocator, lenses[i].tess.vertices);
        refl__free(&rr->scene->allocator, lenses[i].tess.indices);
    }
    refl__free(&rr->scene->allocator, lenses);
}

/* Radiance past float's range (finite but huge lights, emission or sky
   whose products overflow) as the largest float, so that a frame's
   colours stay finite; a NaN is left for the tests to find. */
static void refl__frame_clamp_overflow(refl_frame *frame) {
    size_t i, n = 4 * (size_t)frame->width * (size_t)frame->height;
    for (i = 0; i < n; ++i)
        if (frame->rgba[i] > FLT_MAX) frame->rgba[i] = FLT_MAX;
        else if (frame->rgba[i] < -FLT_MAX) frame->rgba[i] = -FLT_MAX;
}

REFL_API refl_result refl_renderer_render(refl_renderer *rr, const refl_view *view, refl_frame *frame) {
    refl_view fine_view;
    refl_result r;
    double t0;
    int side;
    if (!rr || !view || !frame) return REFL_ERROR_INVALID_ARGUMENT;
    if ((r = refl__check_frame(rr->scene, view, frame)) != REFL_OK) return r;
    side = refl__spp_side(rr->desc.spp);
    if (side == 1) {
        if ((r = refl__render_samples(rr, view, frame)) == REFL_OK) refl__frame_clamp_overflow(frame);
        return r;
    }
    t0 = refl__now_ms();
    if ((r = refl__fine_frame(rr, view, side, frame, &fine_view)) != REFL_OK) return r;
    if ((r = refl__render_samples(rr, &fine_view, rr->fine)) != REFL_OK) {
        if (rr->fine->message == rr->fine->message_text) refl__frame_say(frame, "%s", rr->fine->message_text);
        else frame->message = rr->fine->message;
        return r;
    }
    refl__resolve_spp(rr->fine, frame, side);
    refl__frame_clamp_overflow(frame);
    frame->stats = rr->fine->stats;
    frame->stats.ms_total = refl__now_ms() - t0;
    return REFL_OK;
}

REFL_API refl_result refl_render(const refl_scene *scene, const refl_view *view, const refl_render_desc *desc,
                                 refl_frame *frame) {
    refl_renderer *rr;
    const char *why;
    refl_render_desc d;
    refl_result r;
    if (!scene || !view || !frame) return REFL_ERROR_INVALID_ARGUMENT;
    frame->message = "";
    if ((r = refl__resolve_desc(desc, &d, &why)) != REFL_OK) {
        frame->message = why;
        return r;
    }
    if ((r = refl__check_frame(scene, view, frame)) != REFL_OK) return r; /* before any thread starts */
    if ((r = refl_renderer_create(scene, &d, &rr)) != REFL_OK) {
        if (r == REFL_ERROR_UNSUPPORTED) frame->message = "method: not built yet (no row in the method table)";
        return r;
    }
    r = refl_renderer_render(rr, view, frame);
    refl_renderer_destroy(rr);
    return r;
}
