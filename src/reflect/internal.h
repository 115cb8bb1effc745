/* Private declarations shared by the reflect.h modules (refl__ prefix).
   The amalgamator puts this first inside the REFL_IMPLEMENTATION section.
   Whatever one module takes from another is declared here, grouped by the
   module that defines it, so the modules may follow in any order; only the
   SBC family still shares privates among itself (cam_sbc.c before
   cam_sbc_morph.c and m_sbc.c). */
#include "api.h"

#include <math.h>
#include <string.h>
#include <float.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>  /* vsnprintf: messages with numbers (refl__frame_say) */

#ifndef REFL_ASSERT
#include <assert.h>
#define REFL_ASSERT(c) assert(c)
#endif

#if defined(REFL_MALLOC) != defined(REFL_FREE)
#error "define both REFL_MALLOC and REFL_FREE, or neither"
#endif
#ifndef REFL_MALLOC
#include <stdlib.h>
#define REFL_MALLOC(size, user) ((void)(user), malloc(size))
#define REFL_FREE(ptr, user) ((void)(user), free(ptr))
#endif

#define REFL__MIN(a, b) ((a) < (b) ? (a) : (b))
#define REFL__MAX(a, b) ((a) > (b) ? (a) : (b))
#define REFL__CLAMP(v, lo, hi) ((v) < (lo) ? (lo) : ((v) > (hi) ? (hi) : (v)))
/* A channel in [0, 1] as 8 bits, rounded; below 0 and NaN: 0, above 1: 255. */
static inline uint8_t refl__unorm8(float v) { return (uint8_t)(v > 0.0f ? (v < 1.0f ? v * 255.0f + 0.5f : 255.0f) : 0.0f); }
/* A colour channel as the frame keeps it: unclamped above, 0 for negative and NaN. */
#define REFL__RADIANCE(v) ((v) > 0.0f ? (v) : 0.0f)
#define REFL__PI 3.14159265358979323846

/* ---- allocation: the given allocator when set, else REFL_MALLOC ---- */

static inline void *refl__alloc(const refl_allocator *a, size_t size) {
    if (size == 0) size = 1;
    if (a && a->alloc) return a->alloc(size, a->user);
    return REFL_MALLOC(size, a ? a->user : NULL);
}

static inline void refl__free(const refl_allocator *a, void *ptr) {
    if (!ptr) return;
    if (a && a->free) a->free(ptr, a->user);
    else REFL_FREE(ptr, a ? a->user : NULL);
}

/* Zeroed array of count * size bytes, NULL on overflow or failure. */
static inline void *refl__calloc(const refl_allocator *a, size_t count, size_t size) {
    void *p;
    if (size && count > (size_t)-1 / size) return NULL;
    p = refl__alloc(a, count * size);
    if (p) memset(p, 0, count * size);
    return p;
}

/* A copy of an allocator pointer's contents (zero when NULL). */
static inline refl_allocator refl__allocator(const refl_allocator *a) {
    refl_allocator r;
    if (a) return *a;
    memset(&r, 0, sizeof r);
    return r;
}

static inline int refl__isfinite(float v) { return v - v == 0.0f; }
static inline int refl__all_finite(const float *v, size_t n) {
    size_t i;
    for (i = 0; i < n; ++i)
        if (!refl__isfinite(v[i])) return 0;
    return 1;
}
static inline int refl__v3_finite(refl_vec3 v) { return refl__isfinite(v.x) && refl__isfinite(v.y) && refl__isfinite(v.z); }
/* The rules refl_scene_add_material and _add_light enforce (scene.c), also
   checked per frame since the scene's arrays are the caller's to edit:
   the rule a value breaks, or NULL. */
static const char *refl__material_rule(const refl_material *m, int texture_count);
static const char *refl__light_rule(const refl_light *l);

/* Per-axis minimum and maximum: bounding boxes. */
static inline refl_vec3 refl__v3_min(refl_vec3 a, refl_vec3 b) {
    return refl_v3(REFL__MIN(a.x, b.x), REFL__MIN(a.y, b.y), REFL__MIN(a.z, b.z));
}
static inline refl_vec3 refl__v3_max(refl_vec3 a, refl_vec3 b) {
    return refl_v3(REFL__MAX(a.x, b.x), REFL__MAX(a.y, b.y), REFL__MAX(a.z, b.z));
}

/* The matrix that carries normals under transform m: its inverse
   transpose (m itself when it has no inverse). */
static inline refl_mat4 refl__normal_matrix(refl_mat4 m) {
    refl_mat4 inv;
    return refl_mat4_invert(m, &inv) ? refl_mat4_transpose(inv) : m;
}

static inline int refl__is_reflector(const refl_material *m) { return m->type != REFL_DIFFUSE; }

/* rast.h targets of w x h pixels: linear float RGBA colour, float depth,
   and a stencil unless it is NULL. */
static inline rast_targets refl__float_targets(float *rgba, float *depth, uint8_t *stencil, int w, int h) {
    rast_targets t;
    memset(&t, 0, sizeof t);
    t.color.ptr = rgba; t.color.width = w; t.color.height = h;
    t.color.stride = 4 * (int)sizeof(float) * w;
    t.color_format = RAST_COLOR_RGBA32F;
    t.depth.ptr = depth; t.depth.width = w; t.depth.height = h;
    t.depth.stride = (int)sizeof(float) * w;
    if (stencil) {
        t.stencil.ptr = stencil; t.stencil.width = w; t.stencil.height = h;
        t.stencil.stride = w;
    }
    return t;
}

/* The frame's colour, depth and stencil as rast.h targets. */
static inline rast_targets refl__frame_targets(const refl_frame *f) {
    return refl__float_targets(f->rgba, f->depth, f->stencil, f->width, f->height);
}

/* A pinhole view's rays, set up once (render.c): through window point
   (px, py), pixel centres at + 0.5, the unit direction is
   normalize(forward + right * nx + up * ny) with nx, ny in [-1, 1]; rays
   start on the near plane and end on the far plane, as the rasteriser
   clips. Built from the camera's basis, not by inverting the
   view-projection matrix, which loses all precision far from the origin. */
typedef struct refl__view_rays {
    refl_vec3 eye, forward, right, up; /* right and up scaled by tan(half fov) */
    float znear, zfar;
    int width, height;
} refl__view_rays;
static void refl__view_rays_init(refl__view_rays *r, const refl_view *v, const refl_scene *scene);
static void refl__view_rays_get(const refl__view_rays *r, float px, float py, refl_vec3 *origin, refl_vec3 *dir,
                                float *tmax);

/* ---- what refl_render hands a method (render.c) ---- */

/* What a renderer keeps across frames: models that depend on the scene and
   the desc but not on the view, built on a frame's first need and dropped
   when scene->version moves. */
typedef struct refl__models {
    unsigned scene_version;
    refl_bvh *bvh;                /* RAYTRACE (without a caster of its own) and SBC */
    struct refl__c3_samples *c3;   /* C3RC's samples, kd-tree and shading (m_c3rc.c) */
    float c3_density;             /* the density they were sampled at; 0: none yet */
    struct refl__lem_maps *lem;   /* LAYERED_EM's inferred maps, per viewpoint sample (m_layered_em.c) */
    refl_bvh *split[2];           /* LAYERED_EM's BVHs of the lens objects alone and of the rest
                                     (refl__lem_split) */
    unsigned split_version;       /* the scene version they were built or refit at */
} refl__models;

/* A method either renders the whole frame itself (RAYTRACE) or fills the
   reflector pixels after the base pass: diffuse geometry shaded, mirrors
   and glass transparent black (opaque once every method has run),
   partial reflectors at their diffuse share,
   reflector object id + 1 in the stencil, the environment behind, and
   frame->points NaN everywhere. Methods add their mirror share on top. */
typedef struct refl__pass {
    const refl_scene *scene;
    const refl_view *view;
    refl_render_desc desc;        /* validated, defaults resolved: depth, envmap.size */
    refl_frame *frame;
    rast_context *rc;             /* the frame bound as its targets */
    refl_mat4 view_m, proj_m, vp; /* vp = proj_m * view_m */
    refl__view_rays rays;
    const uint8_t *mine;          /* per object: 1 where this method draws the reflector;
                                     NULL: every reflector is the method's */
    refl__models *models;         /* NULL: nothing kept (a metric's own frame) */
    uint8_t *trace;               /* per pixel, when some reflector's method models fewer
                                     bounces than desc.depth (else NULL): REFL__TRACE_COLOUR
                                     where a method's own path met a reflector it cannot
                                     follow; refl__trace_beyond traces them after every
                                     method drew */
} refl__pass;

/* Writes a message with numbers into frame->message_text and points
   frame->message at it. */
static void refl__frame_say(refl_frame *frame, const char *fmt, ...);

/* Reports done (0..1) to the progress callback; nonzero when it asks to stop. */
static inline int refl__progress(const refl__pass *p, float done) {
    return p->desc.progress && p->desc.progress(p->desc.progress_user, done) != 0;
}

/* Whether the running method draws object i (a reflector it was given). */
static inline int refl__pass_draws(const refl__pass *p, int i) {
    return refl__is_reflector(&p->scene->materials[p->scene->objects[i].material]) && (!p->mine || p->mine[i]);
}

/* The scene's BVH, built on first use and kept with the renderer's models
   (owned by them; with no models, the caller frees *owned). */
static refl_result refl__models_bvh(refl__pass *p, refl_bvh **out, refl_bvh **owned);

/* Sets up p for a frame of scene from view into frame (desc validated and
   resolved, rc any rast context) and runs the base pass: diffuse geometry
   shaded, shadows, reflectors into the stencil, the environment behind. */
static refl_result refl__base_pass(refl__pass *p, const refl_scene *scene, const refl_view *view,
                                   const refl_render_desc *desc, refl_frame *frame, rast_context *rc,
                                   refl__models *models);
/* The rule a view, its frame or the scene breaks for rendering; NULL when none. */
static const char *refl__frame_rule(const refl_scene *scene, const refl_view *v, const refl_frame *frame);
/* A rast context (the thread pool) on the scene's allocator. */
static refl_result refl__context_create(const refl_scene *scene, int threads, rast_context **out);
/* desc validated (NULL: the defaults) into *out with the renderer-wide
   defaults resolved; the broken rule into *message. */
static refl_result refl__resolve_desc(const refl_render_desc *desc, refl_render_desc *out, const char **message);
/* Milliseconds from a monotonic clock, for the stats only. */
static double refl__now_ms(void);

/* ---- small services of other modules ---- */

/* The object-space box of the vertices a triangle of mesh uses (mesh.c;
   a mesh may keep others, as the concave scene's bowl keeps its whole
   sphere's); refl_mesh_bounds' without triangles. */
static void refl__mesh_used_bounds(const refl_mesh *mesh, refl_vec3 *lo, refl_vec3 *hi);
/* rast.h's result as a refl_result (result.c). */
static refl_result refl__result_from_rast(rast_result r);
/* Appends one element of `size` bytes to *array (count *count), growing by
   doubling (scene.c). Its index, or -1. */
static int refl__push(const refl_allocator *a, void **array, int *count, size_t size, const void *elem);
/* Fills out from the matched errors (sorted here) and the counts (metrics.c). */
static void refl__metric_summary(double *errors, long long matched, double sum, long long counted, long long wrong,
                                 long long empty, refl_reflection_error *out);
/* A hit's surface (bvh.c): triangle corners, weights, point, normals. */
typedef struct refl__hit_geom {
    refl_vec3 v[3];
    float w[3];
    refl_vec3 p, ng, ns;
} refl__hit_geom;
static void refl__hit_surface(const refl_mesh *m, const refl_mat4 *model, const refl_mat4 *normal_m, const refl_hit *h,
                              refl__hit_geom *g);
/* refl_bvh_build on rc's threads (bvh.c): the same tree. */
static refl_result refl__bvh_build_on(const refl_scene *scene, const refl_allocator *a, rast_context *rc,
                                      refl_bvh **out_bvh);
/* What a BVH holds in bytes (bvh.c): its nodes, triangles and leaf order. */
static long long refl__bvh_bytes(const refl_bvh *bvh);
/* Triangle tests of every BVH trace of the process so far (bvh.c): a
   frame's are the difference across it (stats.triangle_tests). */
static long long refl__bvh_tests_counted(void);

/* ---- the base pass's drawing (base_pass.c), shared by every rasterising method ---- */

/* The base pass's programs: refl__base_vertex reads a refl__draw_ctx and
   writes REFL__BASE_VARYINGS varyings; refl__base_fragment shades them
   with the shared diffuse model (refl__surface_rgba); refl__clear_fragment
   writes transparent black (mirrors and glass until a method fills them).
   A program with a context of its own puts the refl__draw_ctx first. */
enum { REFL__BASE_VARYINGS = 8 }; /* world position, world normal, uv */

/* One object seen through a view-projection. */
typedef struct refl__draw_ctx {
    const refl_scene *scene;
    const refl_mesh *mesh;
    const refl_material *material;
    refl_mat4 mvp, model, normal_m;  /* normal_m: inverse transpose of model */
} refl__draw_ctx;

static void refl__draw_ctx_init(refl__draw_ctx *dc, const refl_scene *s, int object, refl_mat4 vp);
static int refl__base_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out);
static int refl__base_fragment(void *user, const rast_fragment_in *in, float rgba[4]);
static int refl__clear_fragment(void *user, const rast_fragment_in *in, float rgba[4]);
/* What a diffuse surface shows of its shaded colour rgb: clamped, times
   1 - mirror_weight on a partial reflector; opaque. */
static void refl__surface_rgba(const refl_material *m, const float rgb[3], float rgba[4]);
/* Draws a mesh's triangles (indices NULL: all of them) with the bound
   state, num_varyings from the vertex program. */
static rast_result refl__draw_mesh(rast_context *rc, const refl_mesh *m, const uint32_t *indices, int index_count,
                                   int num_varyings);
/* Draws every object but `skip` (-1: none) as the base pass does, into
   whatever targets rc has bound, and finishes. */
static refl_result refl__draw_scene(rast_context *rc, const refl_scene *scene, refl_mat4 vp, int skip,
                                    refl_stats *st);
/* Fills every pixel whose depth is still 1 with the environment seen
   through it (inv_vp: clip to world). */
static void refl__draw_background(float *color, const float *depth, int width, int height, int stride_px,
                                  const refl_scene *scene, refl_mat4 inv_vp);


/* ---- the reflectors' G-buffer and composite (gbuffer.c): ENVMAP, C3RC, SBC ---- */

/* One object in a G-buffer or cube-face draw: clip position exactly as the
   base pass computes it (so depth tests against the base pass's depth are
   exact), world position and (G-buffer) world normal as varyings. */
typedef struct refl__em_draw {
    const refl_mesh *mesh;
    refl_mat4 mvp, model, normal_m;
    int normals;                  /* varyings 3..5: world normal too (G-buffer) */
    refl_vec3 eye;                /* G-buffer: the viewer */
    float id;                     /* written to alpha: object index + 1 */
} refl__em_draw;

/* The G-buffer of the reflectors the running method draws. */
typedef struct refl__em {
    refl__pass *p;
    refl__em_draw *draws;         /* one per object */
    float *gbuf;                  /* frame-sized RGBA32F: world normal, object + 1 (negative: the back side) */
    float *surface;               /* C3RC, SBC: per reflector pixel, the world point seen there */
} refl__em;

/* Vertex program of those draws: varyings world position, then (with
   d->normals) world normal. */
static int refl__em_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out);
/* d for object `object` seen through vp, with normals or without. */
static void refl__em_setup_draw(refl__em_draw *d, const refl_scene *scene, int object, refl_mat4 vp, int normals);
static rast_result refl__em_submit(rast_context *rc, const refl__em_draw *d);
/* Clears `flags` (RAST_CLEAR_*) with the default state: clears honour the
   depth mask and scissor. */
static rast_result refl__em_clear(rast_context *rc, unsigned flags);
/* The reflectors' world normals into em->gbuf where the base pass showed
   them; seen[i] set for every reflector i with a pixel, *any when one has. */
static refl_result refl__em_gbuffer(refl__em *em, unsigned char *seen, int *any);
/* Allocates em->gbuf, em->draws and *seen (one flag per object; the
   caller frees all three, also on failure) and draws the G-buffer. */
static refl_result refl__em_gbuffer_new(refl__em *em, unsigned char **seen, int *any);
/* A row job (arg: the refl__em): per reflector pixel, the world point of
   the surface seen into em->surface. */
static void refl__em_surface_row(void *arg, int y);
/* The distance fade (paper 003 V-D) of material m's mirror share at pixel
   (x, y) showing `shown` (NaN: the environment). */
static float refl__em_fade(const refl__pass *p, const refl_material *m, int x, int y, refl_vec3 shown);
/* Adds rgb to frame pixel i (opaque now) and sets the point it shows. */
static void refl__em_put(refl_frame *fr, size_t i, const float rgb[3], refl_vec3 shown);
/* Adds reflector pixel (x, y)'s mirror share (g: its G-buffer texel), as
   ENVMAP composites: sub (NULL: the environment along the reflected ray)
   times the reflectance; glass adds the refracted environment. */
static void refl__em_composite(const refl__pass *p, const float *g, int x, int y, const float *sub_in,
                               refl_vec3 shown);

/* ---- shadows (shadow.c): stencil shadow volumes for the rasterised methods ---- */

/* What a shadow or light-volume pass works on: the pixels of a width x
   height view (region NULL, or region[pixel] == region_value) whose
   window depth `depth` (drawn with vp: any view-projection, mirrored or
   with an oblique near plane) is below 1. eye: the viewpoint vp projects
   from (it takes part in choosing z-pass or z-fail). A pass draws into rc
   and finishes; the masks draw into a scratch stencil with `depth` bound
   read-only and leave `restore` bound (NULL: no targets at all) and rast's
   state changed, also on failure (then nothing stays queued); the shading
   passes draw into the bound targets, stencil EQUAL region_value where a
   region is given (the bound stencil then holds it). st (may be NULL)
   counts the triangles drawn. */
typedef struct refl__shadow_job {
    rast_context *rc;
    const refl_scene *scene;
    refl_mat4 vp;
    refl_vec3 eye;
    const float *depth;
    int width, height;
    const uint8_t *region;
    uint8_t region_value;
    const rast_targets *restore;
    refl_stats *st;
} refl__shadow_job;

/* A job over pass p's frame (its context, scene, depth and stats) seen
   through vp from eye: every pixel, nothing restored. */
static refl__shadow_job refl__shadow_job_of(const refl__pass *p, refl_mat4 vp, refl_vec3 eye);

/* refl__shadow_mask: for the job's pixels, sets bit i of lit[pixel] when
   light i reaches the surface seen there and clears it when not, as
   RAYTRACE's shadow rays decide; bits of lights past
   REFL__SHADOW_MAX_LIGHTS do not exist (those lights count as lit), other
   selected pixels get 0xFF, unselected ones are untouched.
   refl__shade_lit: draws every diffuse and partial object but `skip` again
   (depth EQUAL, the base pass's vertex expression, no depth writes),
   shading with refl_shade_diffuse_lit and lit[y * width + x] (partial:
   times 1 - mirror_weight, as the base pass). lit must hold every pixel
   the draw can reach. all_pixels 0 rewrites only pixels with a light
   shadowed (the others keep the colour the base pass gave them, which is
   the same); 1 every pixel. */
enum { REFL__SHADOW_MAX_LIGHTS = 8 };
typedef enum refl__shadow_mode {
    REFL__SHADOW_AUTO = 0,    /* z-pass where provably safe, else z-fail, per light */
    REFL__SHADOW_ZPASS,       /* Heidmann: wrong where the near plane is in a volume */
    REFL__SHADOW_ZFAIL        /* Carmack's reverse, with caps: always right */
} refl__shadow_mode;
static refl_result refl__shadow_mask(const refl__shadow_job *job, uint8_t *lit);
/* The same with the counting forced; *used_zfail (may be NULL) gets bit i
   set when light i was counted with z-fail. */
static refl_result refl__shadow_mask_mode(const refl__shadow_job *job, uint8_t *lit, refl__shadow_mode mode,
                                          unsigned *used_zfail);
static refl_result refl__shade_lit(const refl__shadow_job *job, int skip, const uint8_t *lit, int all_pixels);
/* Soft shadows (paper 002: the scene rendered once per jittered light, summed
   in the accumulation buffer; here the per-sample shadow masks are summed
   exactly on the CPU instead, which rast's RAST_ACCUM would give up to
   rounding): refl__soft_shadows says whether desc asks for them (shadows,
   soft_shadow_samples > 1, at most 64 lights). refl__shadow_mask_soft: as
   refl__shadow_mask, once at the lights' centres for the lights without a
   radius and once per sample (refl_light_sample) for those with one, counts
   (REFL__SHADOW_MAX_LIGHTS planes of width x height) receiving per light
   and selected pixel the samples that reach it; lit is scratch.
   refl__shade_soft: refl__shade_lit with those counts, each light's Lambert
   term weighed by count / samples (refl_shade_diffuse_weighted); all_pixels
   0 rewrites only pixels with a light not wholly visible. */
static int refl__soft_shadows(const refl_render_desc *desc, const refl_scene *scene);
static refl_result refl__shadow_mask_soft(const refl__shadow_job *job, int samples, uint16_t *counts, uint8_t *lit);
static refl_result refl__shade_soft(const refl__shadow_job *job, int skip, const uint16_t *counts, int samples,
                                    int all_pixels);
/* The base pass's shadows: mask and re-shade over the whole frame (bound on
   entry and on return). */
static refl_result refl__shadow_base_pass(refl__pass *p);

/* ---- planar reflector faces (planar_faces.c): PLANAR and the light volumes ---- */

/* A mirror, partial reflector or glass object's triangles in one world
   plane. */
typedef struct refl__planar_face {
    int object;
    double n[3], d;               /* world plane n . x = d, n facing the mirror's front */
    int glass;                    /* a refractor's face */
    int opposite;                 /* glass: the parallel face behind it (a slab), or -1 */
    double thickness;             /* glass: the distance to that face */
    uint32_t *indices;            /* the face's triangles, into the object's mesh */
    int index_count;
} refl__planar_face;

/* Each mirror or partial reflector's (and glass's) faces into *out (only:
   NULL, or per object whether to look at it); none for an object that is
   not planar. Free with refl__planar_free_faces. */
static refl_result refl__planar_find_faces(const refl_scene *s, const uint8_t *only, refl__planar_face **out,
                                           int *out_count);
static void refl__planar_free_faces(const refl_scene *s, refl__planar_face *faces, int count);
/* Reflection about the plane n . x = d. */
static refl_mat4 refl__planar_reflection(const double n[3], double d);

/* ---- light volumes (light_volume.c): light planar mirrors reflect ---- */

/* Lights the shading sums at most (the soft shadows' limit). */
enum { REFL__LV_MAX_LIGHTS = 64 };

typedef struct refl__vlight {
    int source;                   /* the scene light */
    int face;                     /* index into the faces */
    double side;                  /* +1, -1: the side of the face's plane the light is on */
} refl__vlight;

typedef struct refl__lv {
    const refl__planar_face *faces; /* not owned */
    refl__vlight v[REFL__LV_MAX_LIGHTS];
    int count;
    refl_scene shade;             /* the scene with its lights then the virtual lights' centres */
    refl_light lights[REFL__LV_MAX_LIGHTS];
    int samples;                  /* per light with a radius; 1: the centres */
} refl__lv;

/* The virtual lights of the scene's lights in the mirror faces; lv->shade
   sums them after the scene's own. */
static void refl__lv_init(refl__lv *lv, const refl_scene *s, const refl__planar_face *faces, int face_count,
                          int samples);
/* Samples of virtual light k: 1 for lights without a radius. */
static int refl__lv_samples(const refl__lv *lv, const refl_scene *s, int k);
/* Sample j of virtual light k's source (*src) and its mirror image (*virt);
   0 when the sample is not on the light's side of the face. */
static int refl__lv_sample(const refl__lv *lv, const refl_scene *s, int k, int j, refl_light *src, refl_light *virt);
/* The face's reflectance weighing virtual light k at point p of object
   `object`; 0 off the light's side or on the face's own object. */
static float refl__lv_reflectance(const refl__lv *lv, const refl_scene *s, int k, int object, refl_vec3 p);
/* Where the segment from p towards virt meets face k, *m, when it does. */
static int refl__lv_through_face(const refl__lv *lv, const refl_scene *s, int k, const refl_light *virt, refl_vec3 p,
                                 refl_vec3 *m);
/* PLANAR's virtual lights on the job's pixels: every diffuse or partial
   object but `skip` shaded again where a virtual light reaches, with the
   scene's own lights shadowed as desc asks. */
static refl_result refl__lv_pass(const refl__shadow_job *job, const refl__lv *lv, const refl_render_desc *desc,
                                 int skip);

/* ---- the per-pixel tracer (trace.c): RAYTRACE, and SBC's fallback ---- */

typedef struct refl__rt_object {
    const refl_mesh *mesh;
    const refl_material *material;
    refl_mat4 model, normal_m;    /* normal_m: inverse transpose of model */
} refl__rt_object;

/* A tracer set up for one pass (refl__rt_begin). */
typedef struct refl__rt {
    const refl__pass *p;
    const refl_scene *scene;
    refl__rt_object *objects;
    refl_ray_caster caster;
    refl_bvh *bvh;                /* built by refl__rt_begin when the pass brings no caster, nor its caller a BVH */
    refl__planar_face *faces;     /* light_volumes: the planar mirror faces */
    int face_count;
    refl__lv lv;                  /* and their virtual lights (none when off) */
} refl__rt;

/* What tracing pass p needs: the objects' transforms and materials, the
   caster (p's, else bvh when the caller has one of the scene, else a BVH
   built here) and, with light volumes, the mirror faces and their virtual
   lights. refl__rt_end frees it (also after a failed begin). */
static refl_result refl__rt_begin(refl__rt *rt, const refl__pass *p, refl_bvh *bvh);
/* Every scene object's mesh, material and transforms for shading hits
   (refl__exact_hit_shade and the tracer); NULL when out of memory. */
static refl__rt_object *refl__rt_objects_new(const refl_scene *scene);
static void refl__rt_end(refl__rt *rt);
/* Where a secondary ray leaving point p (on a triangle of largest
   |coordinate| magnitude) along the side n starts: off its surface by the
   rounding of the hit (trace.c; greedy_path.c's rays start the same way). */
static refl_vec3 refl__rt_offset(refl_vec3 p, refl_vec3 n, float magnitude);
/* Pixel (x, y) as RAYTRACE renders it: colour, the point its reflector
   shows (NaN: none), window depth and stencil as the base pass writes
   them; *rays counts the rays cast. */
static void refl__rt_pixel(const refl__rt *rt, int x, int y, long long *rays, float rgb[3], refl_vec3 *shown,
                           float *depth, uint8_t *stencil);
/* Whether pixel (x, y)'s exact path, after the modelled[object] mirror
   reflections of the method of the reflector it shows, meets a reflector
   again; *rays counts the rays cast. */
static int refl__rt_goes_beyond(const refl__rt *rt, int x, int y, const int *modelled, long long *rays);
/* RAYTRACE's colour and point for the pixels of pass p that `marked` is
   REFL__TRACE_ALL on, its colour alone where REFL__TRACE_COLOUR (the point
   the method found stays, so the metrics measure the method)
   (m_raytrace.c): what a method hands over pixel by pixel. */
enum { REFL__TRACE_ALL = 1, REFL__TRACE_COLOUR = 2 };
static refl_result refl__trace_marked(refl__pass *p, const uint8_t *marked);
/* The bounces past a method's own: every reflector pixel p->trace marks,
   and every one whose exact path, after the modelled[object] mirror
   reflections its method models, meets a reflector again, gets RAYTRACE's
   colour (m_raytrace.c). modelled[i] 0 (DIRECT) or desc.depth or more:
   left alone. */
static refl_result refl__trace_beyond(refl__pass *p, const int *modelled);

/* ---- the graph camera (cam_graph.c) and the maze built on it (scene.c) ---- */

/* The maze's layout: REFL__MAZE_CORRIDORS corridors, breadth first, the
   entrance first; corridor i < 7 ends in a T whose branches are 2i + 1 and
   2i + 2. s: the middle of its entry edge (x, z); d: its unit direction
   (x, z); length: along d, its 2 x 2 junction square included. */
enum { REFL__MAZE_CORRIDORS = 15 };
#define REFL__MAZE_WALL_H 2.5f
typedef struct refl__maze_corridor {
    float s[2], d[2], length;
    int level, parent;
} refl__maze_corridor;
static void refl__maze_layout(refl__maze_corridor out[REFL__MAZE_CORRIDORS]);
/* Frustum f's matrix with its level folded into z (what the impostor is
   drawn with; window depth = gd), p in its clip space with that level,
   and a 4x4's inverse in double (0 when singular). */
static refl_mat4 refl__gc_draw_matrix(const refl_graphcam *cam, int f);
static void refl__gc_clip(const refl_graphcam *cam, int f, refl_vec3 p, double c[4]);
static int refl__gc_invert(const refl_mat4 *m, double inv[16]);
/* ---- paper 001's greedy ray paths (greedy_path.c) ---- */

/* The lens surface a path meets: its point, geometric and shading normals
   (unit), the largest |coordinate| of its triangle (ray offsets), material,
   object, triangle and the ray's distance to it. */
typedef struct refl__gp_hit {
    refl_vec3 p, ng, ns;
    float magnitude;
    const refl_material *material;
    int object, triangle;
    float t;
} refl__gp_hit;
/* Where greedy paths are cast: scene, a caster over every object; and,
   split (both or neither; refl__lem_split), lenses over the scene's lens
   objects alone and others over the rest (the scene's object indices):
   then a path's rays are cast at the lenses, and the rest asked only
   whether it blocks the way to the lens surface met (any hit). own >= 0:
   a path ends where it leaves lens object own, another lens met next
   being part of own's environment (paper 001's "other lens as a layer",
   refl_layered_em_options.lens_layers); -1: paths cross the whole lens
   system. */
typedef struct refl__gp_casters {
    const refl_ray_caster *scene, *lenses, *others;
    int own;
} refl__gp_casters;
/* Whether caster c has anything on o + t d, 0 < t < tmax (any hit). */
static int refl__caster_blocked(const refl_ray_caster *c, refl_vec3 o, refl_vec3 d, float tmax);
/* Both greedy paths of a ray along unit dir whose first lens interface is
   h (as refl_greedy_paths after its eye ray), e.g. a lens vertex. */
static void refl__greedy_paths_from(const refl_scene *scene, const refl__gp_casters *casters, refl_vec3 dir,
                                    const refl__gp_hit *h, int max_interfaces, refl_greedy_paths_result *out,
                                    long long *rays);
static void refl__greedy_paths_none(refl_vec3 origin, refl_vec3 dir, refl_greedy_paths_result *out);
/* The lens surface of caster hit `hit` in *h; 0 where it is no lens's. */
static int refl__gp_hit_of(const refl_scene *scene, const refl_hit *hit, refl__gp_hit *h);
/* refl_greedy_paths through casters: the eye ray's first lens, then its
   paths as casters->own says. */
static void refl__greedy_paths_cast(const refl_scene *scene, const refl__gp_casters *casters, refl_vec3 origin,
                                    refl_vec3 dir, int max_interfaces, refl_greedy_paths_result *out,
                                    long long *rays);
/* The one greedy path (the child of the larger coefficient at every
   interface, the first included) of a ray along unit dir whose closest
   hit `hit` is on a lens object, through the whole lens system of
   casters->scene, at most max_interfaces interfaces: what the greedy
   tracer follows past a lens met beyond another lens's exit. */
static void refl__greedy_path_on(const refl_scene *scene, const refl_ray_caster *caster, refl_vec3 dir,
                                 const refl_hit *hit, int max_interfaces, refl_greedy_path *path, long long *rays);

/* ---- paper 001's tessellation and inferred maps (lens_tess.c, lem_infer.c) ---- */

/* refl_lens_tessellate on the pass's threads (rc), into *out (its
   allocator set; its arrays freed by the caller, also on failure). */
static refl_result refl__lens_tessellate(const refl_scene *scene, const refl__gp_casters *casters, int object,
                                         const refl_view *view, const refl_lens_tess_desc *desc, rast_context *rc,
                                         refl_lens_tess *out);
/* The layers of a lens's maps: the shells' radii (ascending) around
   centre, and the layer each scene object's hits belong to (-1: the
   shell nearest the hit's distance). */
typedef struct refl__lem_layering {
    int layers;
    float radius[REFL_LEM_MAX_LAYERS];
    refl_lem_shell shell[REFL_LEM_MAX_LAYERS]; /* each layer's, face_size aside (refl__lem_fit_layers) */
    refl_vec3 centre;
    const signed char *object_layer;
    int object_count;
    /* the lens object whose environment this is where the other lenses
       are layers of it (refl_layered_em_options.lens_layers; a pass's,
       refl__lem_ring_of), else -1; and the pass's depth (greedy paths
       beyond it) */
    int own, depth;
    /* whether a sample's eye ray meeting something else before the lens is
       continued to it (refl_layered_em_options.continue_incoming), and
       the lens's world box, past which it is not */
    int continued;
    refl_vec3 box[2];
} refl__lem_layering;
enum { REFL__LEM_MAX_SS = 8, REFL__LEM_MAX_HITS = 8 };
/* A shell's face side at most: its texels 6 side^2 numbered in uint32 */
enum { REFL__LEM_MAX_FACE = 16384 };
/* One front-facing surface an exit ray meets, continued through the others. */
typedef struct refl__lem_hit {
    float rgb[3], distance;      /* distance from the layering's centre */
    refl_vec3 position;
    int object;
} refl__lem_hit;
/* Hits gathered for the clustering: distance, object and exit ray of each;
   its colour and the exit ray itself for choosing the shells. */
typedef struct refl__lem_hits {
    const refl_allocator *al;
    float *distance, *pos;       /* pos: 3 per hit */
    float *rgb, *exit;           /* 3 per hit; 6 per hit: the exit ray's origin and direction */
    int *object, *ray, *view;    /* view: which refl__lem_gather_hits call met it, 0 first */
    int count, cap, rays, views;
} refl__lem_hits;
/* Frees the arrays of h (not h). */
static void refl__lem_hits_free(refl__lem_hits *h);
/* Each layer's shell (lay->shell) from the hits h of it (layer_of[k]):
   the kind asked (refl_layered_em_options.shell), AUTO choosing per layer,
   boxes and cylinders on the frames asked (shell_frame);
   closed shells hold the lens's box (lo, hi; half diagonal lens_radius),
   a sphere at lay->radius. 0 when out of memory. */
static int refl__lem_fit_layers(refl__lem_layering *lay, const refl__lem_hits *h, const int *layer_of, int kind,
                                int frame, refl_vec3 lo, refl_vec3 hi, float lens_radius);
/* Section 4.1's records of one pixel (lem_infer.c): 0 when its centre ray
   does not meet `object` first (with lay->continued: does not reach it
   through what it meets first, Figure 4b), 2 when it reaches it so, 1
   when it meets it first; with 1 or 2 per term and layer l the target
   (rgba: the mean colour of the subsamples' first hits in the layer, alpha
   their share; the outermost layer opaque, the environment where nothing
   of it was met) and the term's confidence (-1: no subsample has the term)
   in out[5 (term layers + l) ...]; points (may be NULL): per term and
   layer the first subsample's hit in the layer (NaN: none) in
   points[3 (term layers + l) ...], for the direct images' distance
   confidence. */
static int refl__lem_pixel_records(const refl_scene *scene, const refl_ray_caster *caster, const refl__view_rays *view,
                                   int x, int y, int object, int ss, float theta_c, int max_interfaces,
                                   const refl__lem_layering *lay, float *out, float *points,
                                   refl_greedy_paths_result *centre_paths, long long *rays);
static int refl__lem_gather_hits(const refl_scene *scene, const refl_ray_caster *caster, const refl_view *view,
                                 int object, int max_interfaces, int own, const refl_vec3 *continue_box,
                                 refl_vec3 centre, refl__lem_hits *h, long long *rays);
/* Section 4.3's direct images of the environment without the lens: how
   a map's are taken. From the lens's centre (lay->centre) one ray towards
   every texel's point on the shell; from the viewpoint, each pixel (every
   stride-th) of rect[s] (x0, y0, x1, y1) of the sample's views[s], the
   lens left out, its ray taken from its point nearest the centre on (it
   looks the shell up as an exit ray through the lens would). The
   confidence: 1 minus the texels' coverage by the lens images' rows
   (already in the system), or (distance) by the distance of the ray's
   hit from the nearest of the lens images' hits in the layer (points,
   3 per hit), the paper's. */
typedef struct refl__lem_direct {
    int viewpoint, distance;
    const refl_view *views;
    int per, stride, rect[3][4];
    const float *points;
    long long count;
} refl__lem_direct;
/* Layer `layer`'s direct images (how) as rows of its system: per ray its
   lookup on the shell, its target the ray's first hit in the layer
   (continued through the rest; alpha 0 where none, the environment on
   the outermost layer). *added counts the rows. */
static refl_result refl__lem_direct_rows(const refl_scene *scene, const refl_ray_caster *caster,
                                         const refl__lem_layering *lay, const refl_lem_shell *shell, int layer,
                                         const refl__lem_direct *how, refl_lem_system *sys, long long *rays,
                                         int *added);
/* The world point on the shell whose index points along q (lem_infer.c),
   0 where none (a quad's other faces). */
static int refl__lem_shell_point(const refl_lem_shell *sh, refl_vec3 q, refl_vec3 *p);
/* ---- impostors (impostor.c) ---- */

/* refl_impostor_build with the caller's rast context (left with no
   targets bound). */
static refl_result refl__impostor_build(rast_context *rc, const refl_scene *scene, const int *objects, int count,
                                        const refl_impostor_camera *camera, const refl_impostor_desc *desc,
                                        refl_impostor **out);

/* ---- the methods (m_*.c) ---- */

/* The methods, one module each, and their rows in the method table
   (render.c). A row's options function checks the method's sub-struct of
   the desc and resolves its defaults in place: NULL, or the rule broken. */
static refl_result refl__method_raytrace(refl__pass *p);
static refl_result refl__method_envmap(refl__pass *p);
static refl_result refl__method_c3rc(refl__pass *p);
static refl_result refl__method_sbc(refl__pass *p);
static refl_result refl__sbc_handles(const refl__pass *p, int object, int *can);
static refl_result refl__method_planar(refl__pass *p);
static refl_result refl__method_graphcam(refl__pass *p);
static const char *refl__options_graphcam(refl_render_desc *d);
static refl_result refl__method_spoc(refl__pass *p);
static const char *refl__options_raytrace(refl_render_desc *d);
static const char *refl__options_envmap(refl_render_desc *d);
static const char *refl__options_planar(refl_render_desc *d);
static const char *refl__options_c3rc(refl_render_desc *d);
static const char *refl__options_sbc(refl_render_desc *d);
static refl_result refl__method_layered_em(refl__pass *p);
/* LAYERED_EM's maps of every viewpoint sample around the pass's eye, for
   the lenses the pass draws, into p->models (refl_renderer_prebuild). */
static refl_result refl__prebuild_layered_em(refl__pass *p);
static refl_result refl__lem_lenses(refl__pass *p, refl_lem_lens **out, int *count);
/* Frees what refl__models keeps of LAYERED_EM (m_layered_em.c). */
static void refl__lem_maps_free(const refl_allocator *al, struct refl__lem_maps *m);
static const char *refl__options_layered_em(refl_render_desc *d);
static const char *refl__options_spoc(refl_render_desc *d);
static refl_result refl__spoc_handles(const refl__pass *p, int object, int *can);
static refl_result refl__planar_handles(const refl__pass *p, int object, int *can);
/* AUTO (m_auto.c): the method it picks for reflector `object`, its reason
   appended to the frame's stats; and whether method m has a row that
   draws reflectors and can draw that one (render.c). */
static const char *refl__options_auto(refl_render_desc *d);
static refl_result refl__auto_choose(refl__pass *p, int object, refl_method *out);
static refl_result refl__method_can_draw(const refl__pass *p, refl_method m, int object, int *can);
/* AUTO's models (auto_model.c): object i's features with `pixels` on
   screen in frame f (its stencil and depth), seen along rays; the pixels
   of object i in a stencil; whether a model may name m. */
static refl_result refl__auto_features(const refl_scene *s, int i, const refl__view_rays *rays, const refl_frame *f,
                                       long long pixels, refl_auto_features *out);
static long long refl__auto_pixels(const uint8_t *stencil, size_t n, int object);
static int refl__auto_modelled(refl_method m);
/* Frees what refl__models keeps of C3RC (m_c3rc.c). */
static void refl__c3_samples_free(const refl_allocator *al, struct refl__c3_samples *pts);
