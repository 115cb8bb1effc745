/* reflect.h - accurate reflections and refractions on the CPU: the camera
   models and methods of five research papers, drawn with rast.h.
   Part of reflect.h + rast.h. Licence: MIT No Attribution (MIT-0), as in rast.h.

   DO THIS in *one* C or C++ file, before including this file:

       #define RAST_IMPLEMENTATION
       #define REFL_IMPLEMENTATION
       #include "reflect.h"          (it includes "rast.h" itself)

   Other files include "reflect.h" without the defines.

   OPTIONS (define before the implementation include)
       REFL_STATIC          all functions static to the including file
       REFL_API             decoration of every public function (default extern)
       REFL_ASSERT(c)       contract checks (default assert)
       REFL_NOW_MS()        wall-clock milliseconds for stats (default:
                            clock_gettime, which needs _POSIX_C_SOURCE
                            200809L before the first include in strict C)
       REFL_MALLOC(size, user) / REFL_FREE(ptr, user)
                            compile-time allocator (both or neither); every
                            desc's allocator overrides at run time

   WHAT IS HERE
       math      vectors, 4x4 matrices (column-major, GL), quaternions, robust
                 quadratic / cubic solvers, small dense least squares (QR)
       meshes    indexed triangles, normals, subdivision, area-uniform points
       shapes    the Utah teapot (Newell's 32 patches), sphere, torus, box, plane
       scenes    objects, materials (diffuse, mirror, glass, partial), lights,
                 environment; the built-in named scenes
       views     pinhole camera
       render    refl_render(scene, view, desc, frame) with one of the methods

   STEP BY STEP
       refl_scene *scene;
       refl_builtin_desc bd = {0};
       refl_scene_builtin("default", &bd, &scene);
       refl_view view = scene->camera;             // or fill one in
       view.width = 640; view.height = 480;
       refl_frame *frame;
       refl_frame_create(view.width, view.height, NULL, &frame);
       refl_render_desc rd = {0};                   // method 0: DIRECT
       refl_render(scene, &view, &rd, frame);       // frame->rgba: linear floats
       refl_frame_destroy(frame);
       refl_scene_destroy(scene);

   DETERMINISM
       Same inputs, same build: same bytes, whatever the thread count. Random
       sampling uses refl_rng (xorshift64*), seeded by the caller.
*/
#ifndef REFLECT_H_INCLUDED
#define REFLECT_H_INCLUDED

#include "rast.h"

#define REFL_VERSION_MAJOR 0
#define REFL_VERSION_MINOR 1
#define REFL_VERSION_PATCH 0

#ifndef REFL_API
#ifdef REFL_STATIC
#define REFL_API static
#else
#define REFL_API extern
#endif
#endif

#ifdef __cplusplus
extern "C" {
#endif

typedef enum refl_result {
    REFL_OK = 0,
    REFL_ERROR_INVALID_ARGUMENT = -1, /* NULL pointer, bad enum, bad count */
    REFL_ERROR_INVALID_SIZE = -2,     /* zero, negative or absurd sizes */
    REFL_ERROR_OUT_OF_MEMORY = -3,
    REFL_ERROR_BAD_MESH = -4,         /* indices out of range, NaN positions, no triangles */
    REFL_ERROR_UNKNOWN_NAME = -5,     /* no built-in scene of that name */
    REFL_ERROR_SINGULAR = -6,         /* ill-conditioned least squares, singular matrix */
    REFL_ERROR_UNSUPPORTED = -7,      /* a method not built (yet) */
    REFL_ERROR_RASTER = -8,           /* rast.h failed; see the message */
    REFL_ERROR_CANCELLED = -9         /* the progress callback asked to stop */
} refl_result;

REFL_API const char *refl_result_string(refl_result result);

typedef struct refl_allocator {
    void *(*alloc)(size_t size, void *user);
    void (*free)(void *ptr, void *user);
    void *user;
} refl_allocator;

/* ---- math --------------------------------------------------------------- */

typedef struct refl_vec3 { float x, y, z; } refl_vec3;
typedef struct refl_mat4 { float m[16]; } refl_mat4; /* column-major: m[col * 4 + row] */
typedef struct refl_quat { float x, y, z, w; } refl_quat;

REFL_API refl_vec3 refl_v3(float x, float y, float z);
REFL_API refl_vec3 refl_v3_add(refl_vec3 a, refl_vec3 b);
REFL_API refl_vec3 refl_v3_sub(refl_vec3 a, refl_vec3 b);
REFL_API refl_vec3 refl_v3_scale(refl_vec3 a, float s);
REFL_API float refl_v3_dot(refl_vec3 a, refl_vec3 b);
REFL_API refl_vec3 refl_v3_cross(refl_vec3 a, refl_vec3 b);
REFL_API float refl_v3_length(refl_vec3 a);
REFL_API refl_vec3 refl_v3_normalize(refl_vec3 a);   /* zero stays zero */
/* Mirror direction d about unit normal n: d - 2 (d.n) n. */
REFL_API refl_vec3 refl_v3_reflect(refl_vec3 d, refl_vec3 n);
/* Refracts unit d through unit n (facing against d) with eta = n1 / n2;
   returns 0 on total internal reflection (then *out is unchanged). */
REFL_API int refl_v3_refract(refl_vec3 d, refl_vec3 n, float eta, refl_vec3 *out);
/* The ray origin + t dir (finite) against the box [lo, hi], faces
   included: 1 when it meets the box at some t >= 0, from *t_in to *t_out;
   an origin inside gives *t_in = 0 and *t_out where the ray leaves. A dir
   parallel to a slab (a zero component) meets the box only with the
   origin within that slab. On a miss too, *t_out is where the ray leaves
   the slabs of the axes dir moves along (negative for a box behind;
   INFINITY when dir is zero) and *t_in the latest entry, at least 0.
   Either pointer may be NULL. */
REFL_API int refl_ray_box(refl_vec3 origin, refl_vec3 dir, refl_vec3 lo, refl_vec3 hi, float *t_in, float *t_out);

REFL_API refl_mat4 refl_mat4_identity(void);
REFL_API refl_mat4 refl_mat4_mul(refl_mat4 a, refl_mat4 b);         /* a * b */
REFL_API refl_mat4 refl_mat4_translate(refl_vec3 t);
REFL_API refl_mat4 refl_mat4_scale(refl_vec3 s);
REFL_API refl_mat4 refl_mat4_rotate(refl_vec3 axis, float radians);
REFL_API refl_mat4 refl_mat4_from_quat(refl_quat q);
/* 0 when singular (|det| tiny relative to the matrix scale); *out unchanged. */
REFL_API int refl_mat4_invert(refl_mat4 a, refl_mat4 *out);
REFL_API refl_mat4 refl_mat4_transpose(refl_mat4 a);
REFL_API refl_vec3 refl_mat4_point(refl_mat4 a, refl_vec3 p);      /* w = 1, divided */
REFL_API refl_vec3 refl_mat4_dir(refl_mat4 a, refl_vec3 d);        /* w = 0 */
/* GL's gluPerspective and gluLookAt. */
REFL_API refl_mat4 refl_mat4_perspective(float fovy_radians, float aspect, float znear, float zfar);
REFL_API refl_mat4 refl_mat4_look_at(refl_vec3 eye, refl_vec3 target, refl_vec3 up);

REFL_API refl_quat refl_quat_axis_angle(refl_vec3 axis, float radians);
REFL_API refl_quat refl_quat_mul(refl_quat a, refl_quat b);
REFL_API refl_quat refl_quat_normalize(refl_quat q);
REFL_API refl_vec3 refl_quat_rotate(refl_quat q, refl_vec3 v);
REFL_API refl_quat refl_quat_slerp(refl_quat a, refl_quat b, float t);

/* Real roots of a x^2 + b x + c, ascending, a double root twice. Stable
   (no cancellation), degrades to lower degree as leading coefficients
   vanish. Returns the count, or -1 when every x is a root (all zero). */
REFL_API int refl_solve_quadratic(double a, double b, double c, double roots[2]);
/* Real roots of a x^3 + b x^2 + c x + d, ascending, with multiplicity. */
REFL_API int refl_solve_cubic(double a, double b, double c, double d, double roots[3]);
/* Least squares: x minimising |A x - b| for A rows x cols (row-major),
   rows >= cols, cols <= 32, by Householder QR. REFL_ERROR_SINGULAR when
   the estimated condition number exceeds 1e12 (x is then untouched).
   *condition (optional) receives the estimate. */
REFL_API refl_result refl_least_squares(const double *A, const double *b, int rows, int cols,
                                        double *x, double *condition);

/* Deterministic random numbers (xorshift64*): same sequence on every machine. */
typedef struct refl_rng { uint64_t state; } refl_rng;
REFL_API refl_rng refl_rng_seed(uint64_t seed);
REFL_API uint32_t refl_rng_u32(refl_rng *rng);
REFL_API float refl_rng_float(refl_rng *rng); /* [0, 1), 24 bits */

/* ---- meshes ------------------------------------------------------------- */

typedef struct refl_mesh {
    int vertex_count, triangle_count;
    float *positions;        /* 3 per vertex */
    float *normals;          /* 3 per vertex, unit length */
    float *texcoords;        /* 2 per vertex, or NULL */
    float *colors;           /* 4 per vertex, or NULL */
    uint32_t *indices;       /* 3 per triangle, counter-clockwise seen from outside */
    refl_allocator allocator;
} refl_mesh;

typedef struct refl_mesh_desc {
    const float *positions;  /* required */
    const float *normals;    /* NULL: computed (angle-weighted face normals) */
    const float *texcoords;
    const float *colors;
    const uint32_t *indices; /* NULL: vertices taken three at a time */
    int vertex_count;
    int index_count;         /* multiple of 3 */
    refl_allocator allocator;
} refl_mesh_desc;

/* Copies the arrays. REFL_ERROR_BAD_MESH for out-of-range indices,
   non-finite positions or no triangles; degenerate triangles are kept
   (they draw nothing) but do not spoil normals. */
REFL_API refl_result refl_mesh_create(const refl_mesh_desc *desc, refl_mesh **out_mesh);
REFL_API void refl_mesh_destroy(refl_mesh *mesh);
REFL_API void refl_mesh_bounds(const refl_mesh *mesh, refl_vec3 *lo, refl_vec3 *hi);
/* Splits every edge longer than max_edge at its midpoint until none is,
   interpolating attributes: the surface is unchanged. Shared edges split
   the same way on both sides (no T-junctions). */
REFL_API refl_result refl_mesh_subdivide(const refl_mesh *mesh, float max_edge, refl_mesh **out_mesh);

/* Points spread uniformly by area over a mesh (after `transform`, may be
   NULL): on average `density` points per unit area, from `seed`; the same
   points for the same inputs on every machine. */
typedef struct refl_points {
    int count;
    float *positions;        /* 3 per point */
    float *normals;          /* 3 per point */
    uint32_t *triangles;     /* the triangle each point lies on */
    refl_allocator allocator;
} refl_points;
REFL_API refl_result refl_mesh_sample_points(const refl_mesh *mesh, const refl_mat4 *transform,
                                             float density, uint64_t seed,
                                             const refl_allocator *allocator,
                                             refl_points **out_points);
REFL_API void refl_points_destroy(refl_points *points);

/* ---- shapes (allocator may be NULL) --------------------------------------- */

/* Newell's teapot: 32 bicubic patches, each a tess x tess grid (0: 8, giving
   about 4k triangles; 4 about 1k, 16 about 16k); y up, base on y = 0. */
REFL_API refl_result refl_mesh_teapot(int tess, const refl_allocator *a, refl_mesh **out);
REFL_API refl_result refl_mesh_sphere(float radius, int slices, int stacks, const refl_allocator *a,
                                      refl_mesh **out);
REFL_API refl_result refl_mesh_torus(float major_radius, float minor_radius, int slices, int sides,
                                     const refl_allocator *a, refl_mesh **out);
REFL_API refl_result refl_mesh_box(refl_vec3 size, const refl_allocator *a, refl_mesh **out);
/* A square in y = 0 of side `size`, facing +y, divisions x divisions quads. */
REFL_API refl_result refl_mesh_plane(float size, int divisions, const refl_allocator *a, refl_mesh **out);

/* ---- images ------------------------------------------------------------- */

typedef struct refl_image {
    int width, height;
    float *pixels;           /* RGBA, linear, rows top first */
} refl_image;

/* ---- scenes ------------------------------------------------------------- */

typedef enum refl_material_type {
    REFL_DIFFUSE = 0,
    REFL_MIRROR,             /* reflects: reflectance, optional Fresnel */
    REFL_GLASS,              /* refracts and reflects: ior, tint, attenuation */
    REFL_PARTIAL             /* diffuse blended with mirror by mirror_weight */
} refl_material_type;

typedef struct refl_material {
    refl_material_type type;
    float color[4];          /* diffuse colour (linear RGBA) */
    int texture;             /* 0: none; else the texture id refl_scene_add_texture
                                returned, modulating color */
    float reflectance;       /* mirror colour scale at normal incidence; 0: 1 */
    int fresnel;             /* Schlick's Fresnel term on reflections */
    float ior;               /* glass; 0: 1.5 */
    float tint[3];           /* glass transmission colour; zero: white */
    float attenuation;       /* glass absorption per unit length (Beer's law) */
    float mirror_weight;     /* partial: 0 diffuse .. 1 mirror */
    /* paper 003's reflector surface properties (section V-D) on the mirror
       share of mirrors and partial reflectors; zero: off */
    float fresnel_min, fresnel_max; /* fresnel_max > 0: the mirror share times
                                       fresnel_max - (fresnel_max - fresnel_min) cos^2, cos the
                                       incidence's: fresnel_min facing the eye, fresnel_max grazing */
    float fade_distance;     /* > 0 (the paper's d_M): the mirror share times
                                fade_max - (fade_max - fade_min) min(d / fade_distance, 1)^2,
                                d from the reflector to what it reflects (the environment:
                                infinitely far); refl_material_fade */
    float fade_min, fade_max;
    float emissive[3];       /* light the surface gives off itself (linear RGB, >= 0), added to
                                its diffuse shading: diffuse and partial materials; zero: none */
    char name[32];
} refl_material;

typedef struct refl_object {
    int mesh;                /* index into scene meshes */
    int material;            /* index into scene materials */
    refl_mat4 transform;     /* object to world */
    char name[32];
} refl_object;

typedef enum refl_light_type { REFL_LIGHT_POINT = 0, REFL_LIGHT_DIRECTIONAL } refl_light_type;

typedef struct refl_light {
    refl_light_type type;
    refl_vec3 position;      /* point lights */
    refl_vec3 direction;     /* directional: the direction light travels */
    float color[3];          /* intensity per channel */
    float radius;            /* soft shadows (refl_render_desc.soft_shadow_samples):
                                point: the radius of a spherical light; directional:
                                the angular radius of its disc, in radians; 0: a
                                point (hard shadows whatever the samples) */
} refl_light;

/* Sample `index` of `count` of a light with a radius, as every method's soft
   shadows place it (paper 002: the scene drawn once per jittered light): a
   point light's position moved onto its sphere at the Fibonacci point
       z = 1 - (2 index + 1) / count, phi = index * 2.39996323 (golden angle),
       position + radius (sqrt(1 - z^2) cos phi, sqrt(1 - z^2) sin phi, z);
   a directional light's direction tilted within its cone to the Fibonacci
   disc point r = sqrt((index + 0.5) / count), same phi, times tan(radius),
   across two axes perpendicular to it. count <= 1 or radius <= 0: the light
   unchanged; light NULL: a zeroed light. Deterministic: the same lights
   on every machine. */
REFL_API refl_light refl_light_sample(const refl_light *light, int index, int count);

typedef enum refl_env_type {
    REFL_ENV_COLOR = 0,      /* a constant colour */
    REFL_ENV_EQUIRECT,       /* image: longitude across, +y at the top row */
    REFL_ENV_CUBE            /* faces +X -X +Y -Y +Z -Z (GL's layout) */
} refl_env_type;

typedef struct refl_environment {
    refl_env_type type;
    float color[3];
    refl_image image;        /* EQUIRECT */
    refl_image faces[6];     /* CUBE */
    float intensity;         /* 0: 1 */
} refl_environment;

/* A pinhole view. */
typedef struct refl_view {
    refl_vec3 eye, target, up;
    float fovy_degrees;      /* vertical; 0: 45 */
    int width, height;
    float znear, zfar;       /* 0: from the scene's bounds */
} refl_view;

typedef struct refl_scene {
    refl_mesh **meshes; int mesh_count;
    refl_material *materials; int material_count;
    refl_object *objects; int object_count;
    refl_light *lights; int light_count;
    refl_image *textures; int texture_count;
    refl_environment environment;
    refl_view camera;        /* the scene's own view */
    int has_camera;
    float ambient[3];        /* ambient light on diffuse surfaces */
    unsigned version;        /* bumped by every change through refl_scene_* (renderers
                                rebuild their models when it moves) */
    refl_allocator allocator;
} refl_scene;

REFL_API refl_result refl_scene_create(const refl_allocator *a, refl_scene **out_scene);
/* Frees the scene with its meshes, textures and environment images. */
REFL_API void refl_scene_destroy(refl_scene *scene);
/* The scene takes ownership of the mesh (also on failure). Index or error. */
REFL_API int refl_scene_add_mesh(refl_scene *scene, refl_mesh *mesh);
REFL_API int refl_scene_add_material(refl_scene *scene, const refl_material *m);
REFL_API int refl_scene_add_object(refl_scene *scene, const refl_object *o);
REFL_API int refl_scene_add_light(refl_scene *scene, const refl_light *l);
/* Copies width x height RGBA floats (linear); the texture's id for
   refl_material.texture (1, 2, ...: scene->textures[id - 1]), or an error. */
REFL_API int refl_scene_add_texture(refl_scene *scene, int width, int height, const float *rgba);
/* Copies the images. */
REFL_API refl_result refl_scene_set_environment(refl_scene *scene, const refl_environment *env);
/* Building a scene in code: materials and lights with the usual fields
   set (the rest zero: adjust them after), and an object in one call. */
REFL_API refl_material refl_material_diffuse(float r, float g, float b);
REFL_API refl_material refl_material_mirror(float reflectance);   /* grey mirror; 0: 1 */
REFL_API refl_material refl_material_glass(float ior);            /* clear glass; 0: 1.5 */
REFL_API refl_light refl_light_point(refl_vec3 position, float intensity);
REFL_API refl_light refl_light_directional(refl_vec3 direction, float intensity);
/* Adds the mesh (the scene takes it, also on failure), a copy of the
   material and an object of both at transform: the object's index, or an
   error. */
REFL_API int refl_scene_add(refl_scene *scene, refl_mesh *mesh, const refl_material *material, refl_mat4 transform);
/* What a scene without them needs to show something: a camera framing its
   bounds (when it has none), a directional key light from above and behind
   the viewer (when it has no light), and a sky colour (when its
   environment is black). */
REFL_API void refl_scene_complete(refl_scene *scene);
/* Marks the scene changed (bumps version), after writing its arrays
   directly: a renderer rebuilds its models at its next frame. */
REFL_API void refl_scene_touch(refl_scene *scene);
/* World-space bounds of every object. */
REFL_API void refl_scene_bounds(const refl_scene *scene, refl_vec3 *lo, refl_vec3 *hi);
/* Object `object`'s vertices in world space, 3 floats each, into out (may
   be NULL: only counted); the count, or REFL_ERROR_INVALID_ARGUMENT for a
   NULL scene or an object or mesh index out of range. (The static points
   refl_sbc_morph_project_points reuses projections of.) */
REFL_API int refl_object_world_positions(const refl_scene *scene, int object, float *out);
/* The tight world-space box of object i's vertices (its transform applied
   to each; an object without vertices: its origin). */
REFL_API void refl_object_world_bounds(const refl_scene *scene, int object, refl_vec3 *lo, refl_vec3 *hi);
/* Whether object i is flat: its world box's smallest side under 1% of its
   largest, or no extent. The impostor methods (SPOC, GRAPHCAM) intersect
   flat objects exactly, as billboards. */
REFL_API int refl_object_is_flat(const refl_scene *scene, int object);
/* Scales and moves every object (and the camera) so the scene's bounding
   box is centred on the origin with a diagonal of `size`. */
REFL_API void refl_scene_normalize(refl_scene *scene, float size);
/* Total triangles over all objects. */
REFL_API long long refl_scene_triangles(const refl_scene *scene);

typedef struct refl_builtin_desc {
    int teapot_tess;         /* 0: 8 */
    refl_allocator allocator;
} refl_builtin_desc;

/* "default", "mirror-room", "concave", "glass", "maze", "teapots"; NULL-terminated list. */
REFL_API const char *const *refl_builtin_names(void);
REFL_API refl_result refl_scene_builtin(const char *name, const refl_builtin_desc *desc,
                                        refl_scene **out_scene);

/* ---- shading, shared by every method ---------------------------------------- */

/* Diffuse shading of a world point: ambient + Lambert from each light (no
   shadows), times the material colour (and texture at uv, may be NULL).
   Every method shades with this, so images differ only in reflection
   geometry. */
REFL_API void refl_shade_diffuse(const refl_scene *scene, const refl_material *m, refl_vec3 p,
                                 refl_vec3 n, const float *uv, float rgb[3]);
/* The environment seen along a world direction. */
REFL_API void refl_environment_lookup(const refl_environment *env, refl_vec3 dir, float rgb[3]);
/* As refl_shade_diffuse, with light i counted only where lit[i] is nonzero
   (lit may be NULL: every light). Methods with shadows pass their
   visibility here, so shadows change nothing else. */
REFL_API void refl_shade_diffuse_lit(const refl_scene *scene, const refl_material *m, refl_vec3 p,
                                     refl_vec3 n, const float *uv, const unsigned char *lit, float rgb[3]);
/* As refl_shade_diffuse_lit with fractional visibility: light i's Lambert
   term (towards the light's centre) scaled by weight[i] in [0, 1] (weight
   may be NULL: every light 1). Soft shadows pass each light's visible
   fraction of its samples here, (float)visible / (float)samples, which
   RAYTRACE counts with shadow rays and the rasterised methods with shadow
   masks, so both shade alike. Weights 0 and 1 give refl_shade_diffuse_lit's
   bytes exactly. */
REFL_API void refl_shade_diffuse_weighted(const refl_scene *scene, const refl_material *m, refl_vec3 p,
                                          refl_vec3 n, const float *uv, const float *weight, float rgb[3]);
/* Unpolarised Fresnel reflectance of a dielectric interface for a ray
   arriving at cos_incidence (> 0) from a medium of index n1 into n2:
   1 beyond the critical angle (total internal reflection). */
REFL_API float refl_fresnel_dielectric(float cos_incidence, float n1, float n2);
/* The share of light a reflector's mirror term carries at cos_incidence:
   mirror: reflectance (0 means 1), through Schlick's Fresnel when `fresnel`
   is set, times paper 003's Fresnel blend when fresnel_max > 0; partial:
   that times mirror_weight; glass: the dielectric Fresnel term entering
   from air; diffuse: 0. Every method composites with it. */
REFL_API float refl_material_reflectance(const refl_material *m, float cos_incidence);
/* The distance fade of a reflector's mirror share (fade_distance above)
   for what it reflects `distance` away (INFINITY: the environment): 1
   when the material has none, or for glass and diffuse materials. RAYTRACE
   fades each mirror bounce by its ray's length, ENVMAP, C3RC and SBC by
   the distance to the point each pixel shows; PLANAR does not fade. */
REFL_API float refl_material_fade(const refl_material *m, float distance);

/* ---- ray tracing: a BVH over the scene's triangles ---------------------------- */

typedef struct refl_bvh refl_bvh;

typedef struct refl_hit {
    float t;                 /* distance along the (unnormalised) direction */
    int object;              /* scene object index */
    int triangle;            /* triangle index within that object's mesh */
    float u, v;              /* barycentrics of the triangle's vertices 1 and 2 */
} refl_hit;

/* Builds a bounding volume hierarchy (binned SAH, collapsed to eight
   children a node, AVX2 or SSE2 box and SSE2 triangle tests; plain C under
   RAST_NO_SIMD, with the same hits) over every object's triangles in world
   space, on the calling thread (refl_bvh_build_threads: on several).
   Deterministic: the same scene gives the same tree. Degenerate and
   non-finite triangles are left out. */
REFL_API refl_result refl_bvh_build(const refl_scene *scene, const refl_allocator *a, refl_bvh **out_bvh);
/* refl_bvh_build on `threads` threads (0: one per online CPU, 1: the
   calling thread alone, as refl_bvh_build), started and stopped within
   the call: the same tree, bit for bit, for every thread count.
   REFL_ERROR_INVALID_ARGUMENT for threads outside 0 to RAST_MAX_THREADS. */
REFL_API refl_result refl_bvh_build_threads(const refl_scene *scene, const refl_allocator *a, int threads,
                                            refl_bvh **out_bvh);
REFL_API void refl_bvh_destroy(refl_bvh *bvh);
/* Closest hit of origin + t * dir with tmin < t < tmax: 1 and *hit, or 0.
   Watertight: a ray through a shared edge or vertex hits one triangle.
   Hits at the same t go to the lower object, then triangle. */
REFL_API int refl_bvh_intersect(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax,
                                refl_hit *hit);
/* Any hit with tmin < t < tmax (shadow rays). */
REFL_API int refl_bvh_occluded(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax);
/* Four rays at once, traced together down the tree (a node fetched once
   for all the rays that enter it): what pays for coherent rays, such as
   shadow rays to one light from neighbouring pixels. Bit k of the result
   is set when ray k hits, with hit[k] (hit may be NULL), the same hit,
   bit for bit, as refl_bvh_intersect's; the occluded form as
   refl_bvh_occluded. */
REFL_API unsigned refl_bvh_intersect4(const refl_bvh *bvh, const refl_vec3 origin[4], const refl_vec3 dir[4],
                                      const float tmin[4], const float tmax[4], refl_hit hit[4]);
REFL_API unsigned refl_bvh_occluded4(const refl_bvh *bvh, const refl_vec3 origin[4], const refl_vec3 dir[4],
                                     const float tmin[4], const float tmax[4]);
/* Refits the tree to the scene's current positions (rigid or any other
   motion of the vertices) without rebuilding it: every triangle taken
   again from its mesh and transform, every box recomputed around them.
   The hits are those of a BVH built anew (the closest hit does not depend
   on the tree), only found more slowly where the motion made boxes
   overlap. REFL_ERROR_UNSUPPORTED (the tree then unusable: build anew)
   where the scene no longer has the objects and triangle counts it was
   built over, or a triangle became degenerate or stopped being one. */
REFL_API refl_result refl_bvh_refit(refl_bvh *bvh, const refl_scene *scene);
/* Nodes and triangles in the tree (stats). */
REFL_API void refl_bvh_stats(const refl_bvh *bvh, long long *nodes, long long *triangles);
/* One world-space triangle (tri: 3 vertices, 9 floats) against the ray
   origin + t dir, tmin < t <= tmax, with refl_bvh's own watertight test:
   1 with hit's t, u and v (object and triangle left alone), bit for bit
   what refl_bvh finds on that triangle; 0 on a miss, and for a triangle
   refl_bvh leaves out (degenerate or not finite). For another
   accelerator to find refl_bvh's hits (the bench's uniform grid). */
REFL_API int refl_ray_triangle(refl_vec3 origin, refl_vec3 dir, const float tri[9], float tmin, float tmax,
                               refl_hit *hit);

/* ---- kd-tree over points (paper 000, section 4) ------------------------------
   The hybrid method's scene subdivision: points (the diffuse meshes' samples)
   in a kd-tree whose every inner node splits its points in eight at once, at
   the median along x, then each half at its median along y, then each
   quarter at its median along z (the paper's eight-way recursion; empty
   children are left out). A node becomes a leaf when it holds at most
   leaf_points points or its box's largest side is below min_size (the
   paper's two termination criteria). Boxes are the tight bounds of each
   node's points. Within a leaf the points are in a deterministic shuffled
   order, so every prefix of a leaf is an even subsample of it (level of
   detail: draw the first k). Deterministic: the same input gives the same
   tree on every machine. The tree stores what it is given (object space, if
   the points are), so it stays valid under rigid motion of the object. */
typedef struct refl_kdtree_node {
    float lo[3], hi[3];      /* tight bounds of the node's points */
    int first, count;        /* its points: tree positions [first, first + count) */
    int child, child_count;  /* children: nodes [child, child + child_count); leaf: -1, 0 */
    int depth;               /* root 0 */
} refl_kdtree_node;

typedef struct refl_kdtree {
    int point_count, node_count, leaf_count, max_depth;
    double average_leaf_depth;  /* over leaves, weighted equally */
    double average_leaf_points; /* point_count / leaf_count */
    float *positions;        /* 3 per point, reordered: each node's points are contiguous */
    uint32_t *order;         /* order[i]: the caller's index of tree point i */
    refl_kdtree_node *nodes; /* nodes[0] is the root (also for no points) */
    refl_allocator allocator;
} refl_kdtree;

typedef struct refl_kdtree_desc {
    int leaf_points;         /* a node with at most this many points is a leaf; 0: 1000 */
    float min_size;          /* a node whose box's largest side is below this is a leaf; 0: none */
    refl_allocator allocator;
} refl_kdtree_desc;

/* Copies count points (3 floats each). REFL_ERROR_INVALID_ARGUMENT for a
   non-finite coordinate, a negative count or NULL positions with count > 0;
   count 0 gives an empty root leaf. desc may be NULL (defaults). */
REFL_API refl_result refl_kdtree_build(const float *positions, int count, const refl_kdtree_desc *desc,
                                       refl_kdtree **out_tree);
REFL_API void refl_kdtree_destroy(refl_kdtree *tree);
/* Depth-first from the root, children in order: a node whose box
   box_test(user, lo, hi) rejects (returns 0) is skipped with its subtree;
   leaf(user, tree, node) is called for every accepted leaf. Returns the
   number of box tests made. */
typedef int (*refl_kdtree_box_fn)(void *user, const float lo[3], const float hi[3]);
typedef void (*refl_kdtree_leaf_fn)(void *user, const refl_kdtree *tree, const refl_kdtree_node *leaf);
REFL_API long long refl_kdtree_query(const refl_kdtree *tree, refl_kdtree_box_fn box_test, refl_kdtree_leaf_fn leaf,
                                     void *user);

/* ---- continuous 3-ray camera (paper 000, section 5) ---------------------------
   A C3RC is built per reflector triangle from its three vertices v1, v2, v3
   (the tails) and the unit reflected rays there d1, d2, d3. The sweeping
   triangle at t >= 0 has vertices vi + t di; a point P projects to
   barycentrics (a, b, c), a + b + c = 1, a, b, c >= 0, and sweep t >= 0 when
       P = a (v1 + t d1) + b (v2 + t d2) + c (v3 + t d3),
   i.e. where P lies in the sweeping triangle's plane (a cubic in t) and
   inside it. Every such (a, b, c, t) is a valid projection: up to three.
   The image point is the reflector point a v1 + b v2 + c v3; t orders
   visibility (nearer the reflector wins). Adjacent C3RCs share an edge's two
   rays, so projection is continuous across it. */
typedef struct refl_c3rc {
    refl_vec3 v[3];          /* tails */
    refl_vec3 d[3];          /* unit directions */
    /* set by refl_c3rc_init, for projection (private) */
    double pre[40];
} refl_c3rc;

typedef struct refl_c3rc_projection {
    float a, b, c;           /* barycentrics on the base triangle, a + b + c = 1 */
    float t;                 /* sweep parameter: distance along the unit rays */
} refl_c3rc_projection;

/* Sets up cam from tails and directions (directions are normalised here).
   REFL_ERROR_INVALID_ARGUMENT for non-finite input or a zero direction; a
   degenerate (zero-area) base is allowed and projects nothing at t = 0. */
REFL_API refl_result refl_c3rc_init(refl_c3rc *cam, const refl_vec3 v[3], const refl_vec3 d[3]);
/* Every valid projection of p, in ascending t, into out; returns how many
   (0..3). Barycentrics within -1e-6 of the triangle count as inside (so a
   point on an edge shared by two C3RCs projects in both), then clamped. */
REFL_API int refl_c3rc_project(const refl_c3rc *cam, refl_vec3 p, refl_c3rc_projection out[3]);
/* Section 5.1: the sweep intervals of [0, tmax] where the construction rays
   are not all on one side of the sweeping triangle's plane (a ray switches
   side where the plane contains it: a quadratic in t per ray). Only there
   can a point have more than one projection. Writes up to 4 disjoint
   intervals, ascending, into out; returns how many (0: never). */
REFL_API int refl_c3rc_multiple_intervals(const refl_c3rc *cam, float tmax, float out[4][2]);
/* Section 5.2: 0 when the box [lo, hi] certainly holds no point with a valid
   projection of t <= tmax (tmax may be INFINITY), 1 when it may: no corner
   projects, no side wall of the view volume meets a box face, and (when
   tmax is finite) the box misses the bounds of the truncated volume.
   Conservative: never 0 for a box holding a point that projects. */
REFL_API int refl_c3rc_box_visible(const refl_c3rc *cam, refl_vec3 lo, refl_vec3 hi, float tmax);

/* ---- single-pole occlusion camera (paper 004, section 4) ---------------------
   A planar pinhole at `eye` looking at the object's bounding-sphere centre
   (`center`, `radius`), square image of `size` pixels, whose image point is
   then pushed radially away from the pole p0 (the centre's projection, the
   image centre) by a displacement that grows with depth, so samples just
   behind the silhouette become visible. With (x, y, z) the point in the
   pinhole's frame (z along the view axis), f the focal length in pixels,
   rho = f (x, -y) / z (pinhole pixels from the pole), r = |rho|:
       gd(z)    = (1/zn - 1/z) / (1/zn - 1/zf)     zn, zf = D -/+ radius
       delta(z) = strength * f * baseline * (1/zn - 1/z) = delta_max * gd
       image    = p0 + rho * (1 + max(delta, 0) * min(1, r / ramp) / r)
   delta is the parallax a viewpoint moved sideways by `baseline` (the radius
   of the region the query rays start from) sees between depth z and the
   near depth zn; strength 0 is the plain depth image. Within `ramp` pixels
   of the pole the push fades linearly to 0, so the image stays continuous
   there. gd is the pinhole's window depth (affine in 1/z, so delta is
   affine in gd); for a fixed gd the radial map is strictly increasing, so
   (u, v, gd) -> point is closed-form and one-to-one. f is chosen so that
   the bounding sphere, pushed, fills the image (one pixel margin). */
typedef struct refl_spoc {
    refl_vec3 eye, center;
    float radius, baseline, strength;
    int size;
    /* derived by refl_spoc_init */
    refl_vec3 right, up, forward; /* the pinhole's frame (unit) */
    float focal;             /* f, pixels */
    float znear, zfar;       /* depth range of the bounding sphere along forward */
    float delta_max;         /* the push at gd = 1, pixels */
    float ramp;              /* pixels from the pole over which the push fades in */
    float pole[2];           /* image of the centre: (size / 2, size / 2) */
} refl_spoc;

/* REFL_ERROR_INVALID_ARGUMENT for NULL, non-finite input, radius <= 0,
   baseline or strength < 0, eye within 1.001 radius of the centre;
   REFL_ERROR_INVALID_SIZE for size < 8 or > 16384. */
REFL_API refl_result refl_spoc_init(refl_spoc *cam, refl_vec3 eye, refl_vec3 center, float radius,
                                    float baseline, float strength, int size);
/* p to (u, v, gd): u, v in image pixels (row 0 at the top), gd as above (0
   at zn, 1 at zf). 0 when p is not in front of the eye (z <= 0). */
REFL_API int refl_spoc_project(const refl_spoc *cam, refl_vec3 p, float out[3]);
/* The inverse: the point projecting to (u, v, gd); 0 for gd at or beyond
   the eye plane's (1/z <= 0). */
REFL_API int refl_spoc_unproject(const refl_spoc *cam, const float uvd[3], refl_vec3 *out);
/* Image rectangle (u0, v0, u1, v1) holding the projection of the bounding
   sphere, and its gd range [0, 1]. */
REFL_API void refl_spoc_bounds(const refl_spoc *cam, float rect[4]);
/* Folds of the radial map on a mesh (after `transform`, may be NULL): the
   triangles that face the eye whose image is mirrored by the push (their
   pinhole and SPOC windings differ), where the surface comes towards the
   eye faster than the push grows (delta'(z) |dz/dr| > 1) and the SPOC
   would hide what the plain depth image shows. Returns that count and
   writes the count of eye-facing triangles to *facing (may be NULL). */
REFL_API long long refl_spoc_count_folds(const refl_spoc *cam, const refl_mesh *mesh, const refl_mat4 *transform,
                                         long long *facing);

/* ---- non-pinhole impostors (paper 004, section 3) ------------------------------
   An impostor is an image of some objects taken with a camera whose
   projection is fast and gives (u, v, gd), gd a depth linear in image
   space: colour, gd and (optionally) world normal per texel. It is built by
   projecting the objects' triangles, subdivided until their edges span
   about max_edge_px texels, with rast.h's vertex callback (clip position
   (2u/W - 1, 1 - 2v/H, 2 gd - 1, 1): affine interpolation, so gd is
   interpolated linearly in the image, as the marching assumes). A ray
   meets it by walking the ray's curved projection (refl_impostor_intersect).
   The camera is any project/unproject pair with a bounding sphere of what
   it images; the pointer `cam` must outlive the impostor. */
typedef struct refl_impostor_camera {
    int (*project)(const void *cam, refl_vec3 p, float out[3]);
    int (*unproject)(const void *cam, const float uvd[3], refl_vec3 *out);
    const void *cam;
    int width, height;       /* image size in texels */
    refl_vec3 center;        /* bounding sphere of everything imaged: the rays are */
    float radius;            /* clipped to it before walking */
} refl_impostor_camera;

/* A SPOC as an impostor camera (size x size, its bounding sphere). */
REFL_API refl_impostor_camera refl_spoc_impostor_camera(const refl_spoc *cam);

typedef struct refl_impostor_desc {
    float max_edge_px;       /* subdivision: triangle edges of about this many texels at
                                most; 0: 4 */
    int normals;             /* 1: store world normals too (reflective objects) */
    int threads;             /* rasterisation threads; 0: one per CPU */
    refl_allocator allocator;
    int layers;              /* depth layers, 1 to REFL_IMPOSTOR_MAX_LAYERS; 0: 1. Layer k
                                is peeled: per texel the nearest surface behind layer k - 1's */
} refl_impostor_desc;

enum { REFL_IMPOSTOR_MAX_LAYERS = 4 };

typedef struct refl_impostor {
    int width, height;
    float *color;            /* RGBA per texel: the shared diffuse shading (no shadows),
                                alpha 1 where a surface is stored, 0 where none */
    float *depth;            /* gd per texel (1 where none) */
    float *normal;           /* 3 per texel (world, unit), or NULL */
    refl_impostor_camera camera;
    float depth_tolerance;   /* gd a surface may change per texel and still be one surface
                                (4 / width): larger jumps are skins between layers */
    long long triangles;     /* drawn, after subdivision */
    refl_allocator allocator;
    int layers;              /* color, depth and normal hold this many images, nearest first
                                (layer k's texel i at index k * width * height + i) */
} refl_impostor;

/* Images objects[0 .. count) of the scene (any materials, drawn with the
   shared diffuse shading). desc may be NULL (defaults). */
REFL_API refl_result refl_impostor_build(const refl_scene *scene, const int *objects, int count,
                                         const refl_impostor_camera *camera, const refl_impostor_desc *desc,
                                         refl_impostor **out);
REFL_API void refl_impostor_destroy(refl_impostor *imp);

typedef struct refl_impostor_hit {
    float t;                 /* along dir (as given, unnormalised) */
    refl_vec3 point;         /* origin + t dir */
    float color[4];          /* the stored texel's colour */
    refl_vec3 normal;        /* stored normal (zero without normals) */
    float uvd[3];            /* the point's projection */
    int layer;               /* the depth layer met */
} refl_impostor_hit;

/* Section 3.2: the ray origin + t dir, tmin < t < tmax, is clipped to the
   bounding sphere, its ends projected, and the clipped segment cut in n
   equal pieces in 3-D, n = step_scale (0: 1) times the length in texels of
   its projection measured along 4 pieces, at least 2. Walking from near to
   far, each end s_k is projected to (u_k, v_k, gd_k) and compared with the
   stored depth GD at its texel (nearest, never blended): the first piece
   where the ray goes from in front of the stored surface (gd < GD) to
   behind it (gd >= GD) is a hit, at the zero of gd - GD interpolated in t,
   unless GD jumps between the two texels by more than 3 times the ray's
   own change of gd plus depth_tolerance (a skin between depth layers at a
   silhouette: the ray passes behind it). Entering a stored texel from an
   empty one counts when the ray is within its own change of gd plus the
   tolerance behind the surface. With several layers each is compared on
   the same ends, as if alone, and the walk stops at the first piece where
   any layer is crossed (the nearest crossing on it). 1 and *hit on a hit; *steps (may be NULL)
   gets the pieces walked (0 when the ray misses the sphere). */
REFL_API int refl_impostor_intersect(const refl_impostor *imp, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax,
                                     float step_scale, refl_impostor_hit *hit, int *steps);

/* ---- SPOC's impostor set (paper 004, sections 4 and 6) ---------------------------
   What the rays leaving one reflector meet, as the SPOC method builds it:
   every object that gets an impostor seen from the centre of the
   reflector's world box (the eye) - diffuse (or, with mirror_impostors, a
   mirror, whose impostor stores normals), not flat (its box's smallest
   side at least 1% of its largest), the eye outside its bounding sphere -
   gets a SPOC from the eye at the centre of its world box, of radius its
   half diagonal, the reflector's half diagonal as the baseline, imaged
   alone (refl_impostor_build); every other object (the reflector too,
   unless it is glass, whose rays leave it for good) is in one BVH,
   intersected exactly. A ray meets the nearest of the impostors
   (refl_impostor_intersect) and the exact part. */
typedef struct refl_spoc_set_desc {
    int size;                /* impostor image size (square), 8 to 4096; 0: 512 */
    float strength;          /* the SPOC's push K, at most 64; 0: 1; negative: 0 (a plain depth image) */
    int layers;              /* impostor depth layers, 1 to REFL_IMPOSTOR_MAX_LAYERS; 0: 3 */
    float max_edge_px;       /* impostor subdivision (refl_impostor_desc), 0.5 to 64; 0: 4 */
    int mirror_impostors;    /* 1: mirrors get impostors too (two bounces: rays reflect off them) */
    int threads;             /* rasterisation threads; 0: one per CPU */
    refl_allocator allocator; /* zero: the scene's */
} refl_spoc_set_desc;

typedef struct refl_spoc_set {
    refl_spoc *cams;         /* per impostor: its SPOC */
    refl_impostor **imps;    /* per impostor, imaged through cams[i] (refl_spoc_impostor_camera) */
    int *imp_object;         /* per impostor: the scene object */
    int imp_count;
    refl_bvh *exact;         /* the objects intersected exactly (NULL: none) */
    int *exact_object;       /* exact's object index -> scene object */
    int exact_count;
    refl_allocator allocator;
} refl_spoc_set;

/* Reflector `reflector`'s set; desc may be NULL (defaults).
   REFL_ERROR_INVALID_ARGUMENT for NULL scene or out, reflector not one of
   the scene's objects, desc's fields out of their ranges. */
REFL_API refl_result refl_spoc_set_build(const refl_scene *scene, int reflector, const refl_spoc_set_desc *desc,
                                         refl_spoc_set **out);
REFL_API void refl_spoc_set_destroy(refl_spoc_set *set);

/* ---- sample-based camera (paper 003) -----------------------------------------
   One reflection group's projection function: a BSP tree whose leaves hold
   planar pinhole cameras fitted to the group's reflected rays (or, where no
   camera fits, the rays themselves), built from a ray map (BuildBSP, the
   paper's Fig. 10). A scene point projects to the first reflector point
   whose reflected ray passes through it, within error_px pixels of the
   desired view for pinhole leaves, within the ray map's spacing for
   ray-list leaves; a point in no leaf's frustum does not project. */
typedef struct refl_sbc_ray {
    refl_vec3 tail;          /* where the reflected ray leaves the last reflector */
    refl_vec3 head;          /* where it leaves the scene's bounding box */
    refl_vec3 first;         /* the first reflector point: what the desired view sees */
} refl_sbc_ray;

typedef struct refl_sbc_desc {
    float error_px;          /* largest projection error in desired-view pixels; 0: 1 */
    refl_mat4 view_proj;     /* the desired view, whose pixels measure the error */
    int width, height;       /* the desired view's size in pixels */
    int max_depth;           /* BSP depth limit; 0: 40 */
    float widen;             /* pinhole leaves also project points this fraction of their
                                image rectangle's width and height beyond each of its sides
                                (paper 003 VI's widened fields of view, for morphing, where
                                points fall just outside one node's ray map); 0: exactly the
                                rectangle, as runtime mode wants */
    const uint8_t *links;    /* optional, per map entry: bit 0 set when it and its right
                                neighbour lie on one smooth piece of surface, bit 1 the same
                                with the entry below (what SBC and morphing take: normals
                                within 45 degrees, the chord between the tails within 30
                                degrees of both tangent planes); no unit frustum spans a link
                                that is not set. NULL: every neighbour is linked (a map
                                already cut into smooth pieces) */
    refl_allocator allocator;
} refl_sbc_desc;

typedef struct refl_sbc refl_sbc;

typedef struct refl_sbc_stats {
    int nodes, pinhole_leaves, ray_leaves, depth;
    long long rays;          /* rays in the group */
    long long bytes;         /* memory the tree holds */
    int sheets;              /* 1 + the most times a ray-list leaf's neighbouring rays cross (fold) between
                                their tails and heads: the sheets refl_sbc_project_sheets can fill */
} refl_sbc_stats;

/* Builds the tree of one reflection group from a map_width x map_height
   ray map (rays[v * map_width + u]); valid (may be NULL: every entry) marks
   the entries that belong to the group. REFL_ERROR_INVALID_ARGUMENT for
   NULL pointers, sizes < 1, non-finite rays or a bad desc. */
REFL_API refl_result refl_sbc_build(const refl_sbc_ray *rays, const uint8_t *valid, int map_width, int map_height,
                                    const refl_sbc_desc *desc, refl_sbc **out_sbc);
REFL_API void refl_sbc_destroy(refl_sbc *sbc);
REFL_API void refl_sbc_get_stats(const refl_sbc *sbc, refl_sbc_stats *out);
/* Projects p: 1 with *first (the first reflector point) and *z (p's
   distance to the leaf camera's image plane, the paper's visibility
   offset z), or 0 when p lies in no leaf's frustum. Thread-safe. */
REFL_API int refl_sbc_project(const refl_sbc *sbc, refl_vec3 p, refl_vec3 *first, float *z);
/* p's projection per sheet: first[k], z[k] for sheets k < `sheets` (at
   most REFL_SBC_SHEETS); returns the mask of the sheets p projects in (bit
   k). Where a group's rays cross (a focusing mirror, a crease), a point
   can lie in the frustums of several rays: before their crossing and past
   it. refl_sbc_project keeps one image per group, the nearest, as the
   paper does (its section VII-C restriction: one reflection per group);
   the paper names splitting rays as the way past it, and a sheet is that:
   the rays of the ray-list leaves cut where they fold (sheet k: past k
   folds of the frustum's four rays), and within one sheet a point has one
   image. Pinhole leaves have sheet 0 only. */
#define REFL_SBC_SHEETS 3 /* a frustum's signed area is quadratic along it: two folds at most */
REFL_API int refl_sbc_project_sheets(const refl_sbc *sbc, refl_vec3 p, int sheets, refl_vec3 *first, float *z);

/* Which kind of leaf refl_sbc_project hands p to (the BSP cell holding p),
   whether or not p then projects: the two cost very differently (a
   pinhole camera's map against a search of the leaf's unit frustums), so
   a benchmark or a profile can tell them apart. NONE for an empty tree,
   a NULL sbc or a non-finite p. */
typedef enum refl_sbc_leaf_kind {
    REFL_SBC_LEAF_NONE = 0,
    REFL_SBC_LEAF_PINHOLE,
    REFL_SBC_LEAF_RAY_LIST
} refl_sbc_leaf_kind;
REFL_API refl_sbc_leaf_kind refl_sbc_leaf_at(const refl_sbc *sbc, refl_vec3 p);

/* ---- reflection morphing (paper 003, section VI) -------------------------------
   A precomputed grid of panoramic SBCs around one reflector object: nodes on
   a regular 3-D grid, each grid cell cut into 6 tetrahedra (all sharing the
   cell's main diagonal). At every node the reflector is seen through a cube
   ray map (6 faces) with the node as the eye, and each smooth piece of the
   reflector (triangles joined through shared vertices; the mesh splits its
   vertices at creases) on each face is an SBC built to error_px face pixels.
   A piece is traced on its own, so no other piece hides it. For an eye in
   the grid, a point p projects with the four SBCs (of p's piece) at the
   nodes of the eye's tetrahedron and their first reflector points (and
   distances to p) are blended barycentrically. Cells that overlap the
   reflector's box hold no eye. A point that projects at some of the four
   nodes but not all is ambiguous and does not project; two remedies (the
   paper's) shrink their number: rays extrapolated in rings past the
   reflector's silhouette (extended reflectors) and leaf cameras that project a little
   beyond their frustums (refl_sbc_desc.widen). The grid assumes a static
   scene: rays' heads are clipped against what the scene held. The
   projections below keep one image per node and piece (the nearest, the
   paper's); refl_render (method SBC, refl_render_desc.sbc_morphs) blends
   each sheet of the nodes' SBCs apart (refl_sbc_project_sheets), so a
   point seen twice in a piece shows twice. It projects every vertex
   afresh; the reuse of static vertices' projections is
   refl_sbc_morph_project_points with a cache. */
typedef struct refl_sbc_morph_desc {
    int nodes[3];            /* grid nodes along x, y, z, each 2..64; 0: 4 */
    float margin;            /* the grid reaches this fraction of the reflector's box diagonal
                                beyond its box on every side; 0: 0.5 */
    refl_vec3 region_lo, region_hi; /* both zero: the grid above; else the grid spans this box
                                (a part of a larger grid, as the paper loads layers) */
    int face_size;           /* cube face ray map side in samples, 4..1024; 0: 128 */
    float error_px;          /* leaf camera error bound in face pixels; 0: 1 */
    int extend_rings;        /* remedy (a): rings of rays extrapolated past the reflector's
                                silhouette on each face map, into samples whose ray meets no
                                piece (the tangent plane of a neighbour, its normal continued
                                linearly); 0: 1; negative: none */
    float widen;             /* remedy (b): refl_sbc_desc.widen of every leaf; 0: 0.1;
                                negative: none */
    int threads;             /* build threads; 0: one per CPU */
    int check_ambiguous;     /* 1: count the paper's construction-time ambiguities into the
                                stats (ambiguous_ends): slow, every unextended ray's tail and
                                head projected at the nodes sharing a tetrahedron */
    refl_allocator allocator;
} refl_sbc_morph_desc;

typedef struct refl_sbc_morph refl_sbc_morph;

typedef struct refl_sbc_morph_stats {
    int nodes;               /* grid nodes */
    int nodes_built;         /* those some eye cell uses (the others lie in the reflector's box) */
    int tetrahedra;          /* 6 per cell, those of cells clear of the reflector's box */
    int pieces;              /* smooth pieces of the reflector */
    int sbcs;                /* SBCs built (node x piece x face with rays) */
    long long rays, pinhole_leaves, ray_leaves;
    long long bytes;         /* memory the grid holds */
    double ms_build;         /* wall-clock construction time */
    long long ends_checked;  /* with check_ambiguous: tails and heads tested (per cell and node pair) */
    long long ambiguous_ends; /* of those, not projecting at the other node: ambiguous */
} refl_sbc_morph_stats;

/* Builds the grid of scene object `object` (desc may be NULL: defaults).
   REFL_ERROR_INVALID_ARGUMENT for a NULL scene or out pointer, an object
   out of range or of an empty mesh, node counts outside 2..64, face sizes
   outside 4..1024, a negative or non-finite margin or error, a region
   with lo not below hi or not finite; REFL_ERROR_UNSUPPORTED for a mesh
   of more than 1024 pieces (a triangle soup: nothing shares a vertex);
   then *out_morph is NULL. */
REFL_API refl_result refl_sbc_morph_build(const refl_scene *scene, int object, const refl_sbc_morph_desc *desc,
                                          refl_sbc_morph **out_morph);
REFL_API void refl_sbc_morph_destroy(refl_sbc_morph *morph);
REFL_API void refl_sbc_morph_get_stats(const refl_sbc_morph *morph, refl_sbc_morph_stats *out);
/* The object the grid was built for (-1 for NULL). */
REFL_API int refl_sbc_morph_object(const refl_sbc_morph *morph);
/* Node (i, j, k)'s position: 1, or 0 when out of range (or morph is NULL). */
REFL_API int refl_sbc_morph_node(const refl_sbc_morph *morph, int i, int j, int k, refl_vec3 *position);
/* The eye's tetrahedron (a key: cell * 6 + which of its six) and its four
   nodes' barycentric weights; -1 when the eye lies outside the grid, in a
   cell overlapping the reflector's box, or is not finite. Eyes within 1e-5
   cells of a node's plane count as on it, so an eye at a node weighs it 1. */
REFL_API int refl_sbc_morph_locate(const refl_sbc_morph *morph, refl_vec3 eye, int nodes[4], float weights[4]);
/* The piece the ray meets first on the reflector's outside (-1: none):
   which piece's reflection a desired-view pixel shows. */
REFL_API int refl_sbc_morph_piece_at(const refl_sbc_morph *morph, refl_vec3 origin, refl_vec3 dir);
/* Projects p into piece `piece` for the eye: 1 with *first (blended first
   reflector point) and *dist (blended distance from p to it), 0 when p
   does not project at every node of positive weight (*ambiguous, may be
   NULL, 1 when it projects at some of them), the eye locates nowhere or
   an argument is bad. Thread-safe. */
REFL_API int refl_sbc_morph_project(const refl_sbc_morph *morph, refl_vec3 eye, int piece, refl_vec3 p,
                                    refl_vec3 *first, float *dist, int *ambiguous);
/* The sheets the piece's face SBCs have at the eye's nodes (1 where no
   ray folds, at most REFL_SBC_SHEETS; 0 when the eye locates nowhere or an
   argument is bad), and p projected into sheet `sheet` of them as
   refl_render's SBC blends a morph grid (one image per node and sheet,
   refl_sbc_project_sheets, blended sheet by sheet): 1 with *first, *dist
   and *across (may be NULL; 1 where a node's image came from a sheet a
   fold away, where the sheets meet), 0 where a node of positive weight
   has no image in it or beside it. Thread-safe. */
REFL_API int refl_sbc_morph_sheets(const refl_sbc_morph *morph, refl_vec3 eye, int piece);
REFL_API int refl_sbc_morph_project_sheet(const refl_sbc_morph *morph, refl_vec3 eye, int piece, int sheet, refl_vec3 p,
                                          refl_vec3 *first, float *dist, int *across);
/* p projected by node (i, j, k)'s SBCs alone (what the blend weighs): 1
   with *first and *dist, 0 when it does not project there, the node is
   out of range or not built (its cells overlap the reflector's box). */
REFL_API int refl_sbc_morph_project_node(const refl_sbc_morph *morph, int i, int j, int k, int piece, refl_vec3 p,
                                         refl_vec3 *first, float *dist);
/* Static points' projections kept while the eye stays in one tetrahedron
   (the paper's reuse): refl_sbc_morph_project_points with a cache projects
   each point at the four nodes only when the tetrahedron, the piece, the
   count or the points pointer changed, and otherwise only re-blends. The
   caller keeps the points unchanged while they are cached. */
typedef struct refl_sbc_morph_cache refl_sbc_morph_cache;
REFL_API refl_result refl_sbc_morph_cache_create(const refl_allocator *a, refl_sbc_morph_cache **out_cache);
REFL_API void refl_sbc_morph_cache_destroy(refl_sbc_morph_cache *cache);
/* count points (3 floats each) into first[i], dist[i] and status[i] (1:
   projects, 2: ambiguous, 0: neither); cache may be NULL (every point
   projected at the four nodes). *ambiguous (may be NULL): how many have
   status 2. REFL_ERROR_INVALID_ARGUMENT for NULL arrays with count > 0,
   a negative count, a bad piece or an eye that locates nowhere. */
REFL_API refl_result refl_sbc_morph_project_points(const refl_sbc_morph *morph, refl_vec3 eye, int piece,
                                                   const float *points, int count, refl_sbc_morph_cache *cache,
                                                   refl_vec3 *first, float *dist, uint8_t *status,
                                                   long long *ambiguous);

/* ---- graph camera (paper 004, section 5; docs/graphcam.md) --------------------
   A tree of planar pinhole frusta grown from a root pinhole by bending: a
   bend's child frustum starts at a planar portal quad inside its parent and
   holds the points P beyond the portal (seen from the child's eye C) whose
   line from C crosses the portal; P is imaged where that line meets the
   portal, as the parent images that point. Every frustum is one 4x4 matrix
   to the root's image (the concatenated projections). A mirror bend's
   child eye is the parent's eye mirrored in the portal's plane: the
   frustum is then PLANAR's mirrored camera (matrix parent * reflection).
   A split is several bends of one parent. A merge joins two frusta into
   one (two corridors meeting): one eye, a portal in each parent, the two
   portals sharing an edge; stored as its two halves (each a bend of its
   parent), both at the level after the deeper parent's.

   A frustum's region is convex: its entry plane (the root's near plane, a
   child's portal plane), four side planes, a far plane and any bounds added
   with refl_graphcam_bound. A bend does not cut its parent's region: where
   regions overlap (a parent reaching past its portal; a mirror bend's
   child, which lies on its parent's side of the mirror) a point belongs to
   the first frustum, in creation order, that holds it, and the impostor
   shows it in both; bounds make the regions disjoint (the maze's
   corridors). Depth: frustum f at level k (bends from the root)
   of L levels takes window depth gd in [k / L, (k + 1) / L), so depth
   rises along every camera ray from frustum to frustum. */
#define REFL_GRAPHCAM_MAX_FRUSTA 64
#define REFL_GRAPHCAM_MAX_PLANES 16

typedef struct refl_graphcam_frustum {
    int parent;              /* -1: the root */
    int level;               /* bends from the root */
    int mirror;              /* made by a mirror bend */
    int merged_with;         /* a merge's half: the other half's index + 1; else 0 */
    refl_vec3 eye;           /* its centre of projection */
    refl_vec3 portal[4];     /* its entry quad (the root: the near plane's corners) */
    refl_mat4 m;             /* world to the root image's clip space; z / w is -1 on the
                                entry plane, rising along the frustum's rays (no level) */
    double planes[REFL_GRAPHCAM_MAX_PLANES][4]; /* inside: n . x + d >= 0; [0] the entry,
                                [1..4] the sides, [5] the far plane, then the bounds */
    int plane_count;
    int rast_clipped;        /* planes [0..rast_clipped) are the rasteriser's own clip
                                (the root's near and side planes), not clipped again */
    refl_vec3 lo, hi;        /* the region's bounding box */
} refl_graphcam_frustum;

typedef struct refl_graphcam {
    int width, height;       /* the image in pixels */
    int levels;              /* L: the deepest level + 1 */
    int count;
    refl_graphcam_frustum frusta[REFL_GRAPHCAM_MAX_FRUSTA];
    /* point location (the paper's floor map): a grid over the frusta's x, z
       bounds, per cell the frusta whose box reaches it (bit f) */
    int map_w, map_h;
    float map_lo[2], map_cell[2];
    unsigned long long map[64 * 64];
} refl_graphcam;

/* The root: the view's pinhole (fovy 0: 45; znear and zfar must be set,
   0 < znear < zfar) seen at width x height pixels. */
REFL_API refl_result refl_graphcam_init(refl_graphcam *cam, const refl_view *view, int width, int height);
/* A child of `parent` entering at the planar quad portal (corners in order
   around it, every one inside the parent's region up to 1e-3 of its size)
   with centre of projection eye (off the portal's plane), reaching `far`
   beyond the portal's plane; its index into *out. */
REFL_API refl_result refl_graphcam_bend(refl_graphcam *cam, int parent, const refl_vec3 portal[4], refl_vec3 eye,
                                        float far, int *out);
/* A bend whose eye is the parent's mirrored in the portal's plane. */
REFL_API refl_result refl_graphcam_bend_mirror(refl_graphcam *cam, int parent, const refl_vec3 portal[4], float far,
                                               int *out);
/* count bends of one parent (portals[i], eyes[i]): indices *first .. + count - 1. */
REFL_API refl_result refl_graphcam_split(refl_graphcam *cam, int parent, const refl_vec3 (*portals)[4],
                                         const refl_vec3 *eyes, int count, float far, int *first);
/* A merge of frusta a and b into one frustum with centre of projection
   eye: its halves enter at portal_a (inside a) and portal_b (inside b),
   which share an edge (two corners each, equal within 1e-4 of their size)
   and lie on either side of the plane through eye and that edge. The
   halves are indices *first and *first + 1, both at the level after the
   deeper parent's; a and b each end at their half's portal plane. */
REFL_API refl_result refl_graphcam_merge(refl_graphcam *cam, int a, int b, const refl_vec3 portal_a[4],
                                         const refl_vec3 portal_b[4], refl_vec3 eye, float far, int *first);
/* Restricts a frustum's region to n . x + d >= 0. */
REFL_API refl_result refl_graphcam_bound(refl_graphcam *cam, int frustum, refl_vec3 n, float d);
/* The frustum that holds p (the floor map, then plane tests), or -1. */
REFL_API int refl_graphcam_locate(const refl_graphcam *cam, refl_vec3 p);
/* Whether frustum f's region holds p. */
REFL_API int refl_graphcam_contains(const refl_graphcam *cam, int f, refl_vec3 p);
/* p through frustum f (whether or not it holds p): out = (u, v, gd), u, v in
   pixels (0, 0 the top left corner), gd the window depth with f's level;
   0 behind the frustum's eye. */
REFL_API int refl_graphcam_project_in(const refl_graphcam *cam, int f, refl_vec3 p, float out[3]);
/* p through the frustum that holds it (*frustum, may be NULL); 0 when none does. */
REFL_API int refl_graphcam_project(const refl_graphcam *cam, refl_vec3 p, float out[3], int *frustum);
/* The point of frustum f at image (u, v) and window depth gd; 0 when singular. */
REFL_API int refl_graphcam_unproject(const refl_graphcam *cam, int f, float u, float v, float gd, refl_vec3 *p);
/* The part [*t0, *t1] of a + t (b - a), t in [0, 1], in frustum f's region; 0: none. */
REFL_API int refl_graphcam_clip_segment(const refl_graphcam *cam, int f, refl_vec3 a, refl_vec3 b, float *t0,
                                        float *t1);
/* The box around every frustum's region. */
REFL_API void refl_graphcam_bounds(const refl_graphcam *cam, refl_vec3 *lo, refl_vec3 *hi);
/* A graph-camera impostor (paper 004, section 3): the scene's diffuse
   objects (reflectors and glass left out, and objects with skip[i] set)
   drawn through the graph camera, each triangle clipped to each frustum's
   region and rasterised with that frustum's matrix: colour (the shared
   diffuse shading), window depth gd and the frustum each pixel shows. */
typedef struct refl_graphcam_impostor {
    int width, height;
    float *rgba;             /* linear colour, 4 floats a pixel, rows top first */
    float *depth;            /* gd; 1 where nothing was drawn */
    uint8_t *frustum;        /* frustum + 1; 0 where nothing was drawn */
    long long triangles;     /* triangles drawn (clipped pieces counted) */
    refl_allocator allocator;
} refl_graphcam_impostor;

REFL_API refl_result refl_graphcam_impostor_build(const refl_scene *scene, const refl_graphcam *cam,
                                                  const uint8_t *skip, int threads, refl_graphcam_impostor **out);
REFL_API void refl_graphcam_impostor_destroy(refl_graphcam_impostor *imp);

typedef enum refl_graphcam_algorithm {
    REFL_GRAPHCAM_SEGMENTS = 0, /* the paper's algorithm 2: the ray clipped to each frustum,
                                   each piece walked along its straight image segment */
    REFL_GRAPHCAM_UNIFORM = 1   /* algorithm 1: uniform steps in 3-D, each point located and
                                   projected */
} refl_graphcam_algorithm;

typedef struct refl_graphcam_hit {
    refl_vec3 point;         /* on the ray, where it crosses the impostor's depth */
    float t;                 /* along the ray (direction as given) */
    float rgb[3];            /* the impostor's colour there */
    int frustum;
    long long steps;         /* samples taken */
} refl_graphcam_hit;

/* The first crossing of the ray o + t dir, t in (tmin, tmax], with the
   impostor's depth (the ray in front of the stored depth at one sample,
   behind it at the next, both in pixels of the sample's own frustum),
   except where the stored depth jumps between the two samples' pixels by
   more than three times the ray's own depth change plus twice the
   surface's local slope: the "skins" between depth layers. step: REFL_GRAPHCAM_SEGMENTS: pixels a step (0: 1);
   REFL_GRAPHCAM_UNIFORM: world units a step (0: the camera's bounds'
   diagonal / 2048). 1 when hit; hit->steps counts either way. */
REFL_API int refl_graphcam_intersect(const refl_graphcam *cam, const refl_graphcam_impostor *imp, refl_vec3 o,
                                     refl_vec3 dir, float tmin, float tmax, refl_graphcam_algorithm algorithm,
                                     float step, refl_graphcam_hit *hit);

/* The built-in scene "maze"'s graph camera: 15 frusta, one per corridor,
   each bounded by its corridor; the image width x height (0: 1920 x 1176). */
REFL_API refl_result refl_graphcam_maze(refl_graphcam *cam, int width, int height);

/* ---- GL hooks: the cameras in a GL vertex program (docs/gl.md) ---------------
   Each camera packs into plain floats, read in GLSL 3.30 as a buffer texture
   of vec4 (GL_RGBA32F, texelFetch on a samplerBuffer), and refl_gl_glsl
   gives the source (no #version line) of the function projecting a world
   point with them; the functions of every camera may share one program.
   No GL here: a host (tools/reflect_gl.c) uploads and draws. A block starts
   with a header texel (camera, REFL_GL_LAYOUT_VERSION, two counts) and
   carries every number its projection reads; integers are stored as
   floats (exact below 2^24). The layouts are in docs/gl.md. Packers return
   the floats the block needs and write them only when cap holds them all
   (out may be NULL to size), or a negative refl_result. */
#define REFL_GL_LAYOUT_VERSION 1
#define REFL_GL_C3RC_TEXELS 16        /* per camera, after the header texel */
#define REFL_GL_SBC_HEADER_TEXELS 4
#define REFL_GL_SBC_NODE_TEXELS 4
#define REFL_GL_SBC_CAM_TEXELS 16
#define REFL_GL_SBC_QUAD_TEXELS 20
#define REFL_GL_SBC_INDEX_TEXELS 6
#define REFL_GL_GRAPHCAM_TEXELS (5 + REFL_GRAPHCAM_MAX_PLANES) /* per frustum, after 2 header texels */
typedef enum refl_gl_camera {
    REFL_GL_MIRROR = 1,      /* PLANAR's mirrored pinhole */
    REFL_GL_C3RC,            /* an array of C3RCs */
    REFL_GL_SBC,             /* one SBC: its BSP tree, pinhole and ray-list leaves */
    REFL_GL_GRAPHCAM,        /* a graph camera: per frustum its region's planes and matrix */
    REFL_GL_SPOC = 5,        /* one SPOC: its pinhole frame, focal length, push and ramp */
    REFL_GL_SBC_MORPH = 6,   /* an SBC morph grid's tetrahedron for one eye and piece: its four
                                nodes' face SBCs, blended (needs REFL_GL_SBC's source too) */
    REFL_GL_LEM_SHELL = 7,   /* a LAYERED_EM lens's layers' shells (sphere, cylinder, box,
                                quad): the lookup of an exit ray, and optionally the maps */
    REFL_GL_SPOC_IMPOSTOR = 8, /* a SPOC impostor: its SPOC, bounding sphere and depth layers
                                (colour and gd), marched per fragment (needs REFL_GL_SPOC's
                                source too) */
    REFL_GL_GRAPHCAM_IMPOSTOR = 9 /* a graph camera's impostor: the camera, its bounds, colour,
                                frustum id and gd per pixel, marched per fragment (algorithm 2) */
} refl_gl_camera;
/* GLSL: vec4 refl_mirror_project(samplerBuffer, int base, vec3 p, out float clip_distance)
         int refl_c3rc_project(samplerBuffer, int base, int cam, vec3 p, out vec4 proj[3])
             (a, b, c, t) ascending in t; vec3 refl_c3rc_image(samplerBuffer, int base, int cam, vec4 proj)
         bool refl_sbc_project(samplerBuffer, int base, vec3 p, out vec3 first, out float z, out int leaf_kind)
         vec4 refl_graphcam_project(samplerBuffer, int base, vec3 p, out int frustum)
             the clip position (window depth = gd), frustum -1 (and 0) where no frustum holds p
         bool refl_sbc_morph_project(samplerBuffer, int base, vec3 p, out vec3 first, out float dist)
             refl_sbc_morph_project's blend (one image per node and piece)
         bool refl_lem_shell_index(samplerBuffer, int base, int layer, vec3 origin, vec3 dir,
             out vec3 index) per vertex: refl_lem_shell_index (interpolate it); false (no
             lookup) from outside a box or cylinder, past or away from a sphere from
             outside, or away from or past a quad
         bool refl_lem_shell_lookup(samplerBuffer, int base, int layer, vec3 origin, vec3 dir,
             out ivec4 texel, out vec4 weight): refl_lem_shell_lookup; vec4
             refl_lem_shell_sample(samplerBuffer, int base, int layer, vec3 index): per fragment,
             the layer's packed map at an interpolated index; int refl_lem_layers(...)
         vec4 refl_spoc_project(samplerBuffer, int base, vec3 p)
             (u, v, gd, 1) as refl_spoc_project, u, v in pixels; 0 where p is not in front
         bool refl_spoc_impostor_intersect(samplerBuffer, int base, vec3 origin, vec3 dir,
             float tmin, float tmax, float step_scale, out float t, out vec3 point,
             out vec4 color, out int layer, out int steps): refl_impostor_intersect's
             march, per fragment
         bool refl_graphcam_impostor_intersect(samplerBuffer, int base, vec3 origin, vec3 dir,
             float tmin, float tmax, float step, out float t, out vec3 point, out vec3 color,
             out int frustum, out float behind, out int steps): refl_graphcam_intersect with
             REFL_GRAPHCAM_SEGMENTS per fragment; behind: the smallest t before the hit (any,
             without one) where the ray passed behind a surface by more than its thickness
             estimate (what the method hands to its tracer), 3.4e38 where none
   NULL for an unknown camera. */
REFL_API const char *refl_gl_glsl(refl_gl_camera camera);
/* The mirror plane n . x = d (n towards the mirror's front; need not be
   unit) and the viewer's view-projection: clip = vp * R * p, with the
   plane as the clip distance n . p - d (>= 0: in front of the mirror). */
REFL_API long long refl_gl_pack_mirror(refl_mat4 view_proj, refl_vec3 normal, float d, float *out, long long cap);
REFL_API long long refl_gl_pack_c3rc(const refl_c3rc *cams, int count, float *out, long long cap);
REFL_API long long refl_gl_pack_sbc(const refl_sbc *sbc, float *out, long long cap);
REFL_API long long refl_gl_pack_graphcam(const refl_graphcam *cam, float *out, long long cap);
/* The tetrahedron of the grid that holds eye, for piece `piece`: what
   refl_sbc_morph_project reads (REFL_ERROR_INVALID_ARGUMENT where the eye
   locates nowhere or the piece is out of range). */
REFL_API long long refl_gl_pack_sbc_morph(const refl_sbc_morph *morph, refl_vec3 eye, int piece, float *out,
                                          long long cap);
/* 6 texels: the header, (eye, focal), (right, ramp), (up, delta_max),
   (forward, 0), (1/znear, 1/zfar, pole u, pole v). */
REFL_API long long refl_gl_pack_spoc(const refl_spoc *cam, float *out, long long cap);
/* A SPOC impostor (imp built with refl_spoc_impostor_camera(cam), so
   imp->camera.cam == cam): the header (8, version, width, layers),
   (centre, radius), (depth_tolerance, height, REFL_GL_SPOC_IMPOSTOR_TEXELS,
   0), cam's 6-texel block, then per layer, nearest first, width x height
   texels (r, g, b, gd) in rows top first; gd -1 where nothing is stored. */
#define REFL_GL_SPOC_IMPOSTOR_TEXELS 9 /* the texels before the images */
REFL_API long long refl_gl_pack_spoc_impostor(const refl_impostor *imp, const refl_spoc *cam, float *out,
                                              long long cap);
/* A graph camera's impostor (imp built with refl_graphcam_impostor_build
   from cam): the header (9, version, width, height), (bounds' low corner,
   the colour plane's offset), (bounds' high corner, the depth plane's
   offset), cam's block (refl_gl_pack_graphcam) at texel
   REFL_GL_GRAPHCAM_IMPOSTOR_CAMERA, the colour plane: per pixel (r, g, b,
   frustum + 1, 0 where none) in rows top first, then the depth plane: gd
   per pixel, 4 pixels a texel. */
#define REFL_GL_GRAPHCAM_IMPOSTOR_CAMERA 3
REFL_API long long refl_gl_pack_graphcam_impostor(const refl_graphcam *cam, const refl_graphcam_impostor *imp,
                                                  float *out, long long cap);

/* ---- rendering -------------------------------------------------------------- */

typedef enum refl_method {
    REFL_METHOD_DEFAULT = 0, /* DIRECT */
    REFL_DIRECT,             /* scene rasterised, reflectors only in the stencil */
    REFL_RAYTRACE,           /* the reference */
    REFL_ENVMAP,
    REFL_PLANAR,             /* paper 002 */
    REFL_SBC,                /* paper 003 */
    REFL_C3RC,               /* paper 000 */
    REFL_SPOC,               /* paper 004 */
    REFL_GRAPHCAM,           /* paper 004 */
    REFL_LAYERED_EM,         /* paper 001 */
    REFL_AUTO,               /* per reflector, the cheapest method predicted to meet
                                desc.automatic's error budget */
    REFL_METHOD_COUNT
} refl_method;

REFL_API const char *refl_method_name(refl_method m);          /* "direct", ... */
REFL_API refl_method refl_method_from_name(const char *name);  /* any case; 0 when unknown */
REFL_API int refl_method_is_built(refl_method m);             /* 1: refl_render draws with it */

/* ---- AUTO: per reflector, the cheapest method whose predicted error meets
   a budget (docs/methods/auto.md) ---------------------------------------------
   Each reflector is described by its features: its class, its pixels on
   screen (the base pass's stencil), and how near what it reflects is. Per
   (method, class), a model predicts the method's frame cost and reflection
   error from them:
       cost_ms  = cost[0] + cost[1] * pixels / 1000 + cost[2] * triangles / 1000
                + cost[3] * pixels * beyond / 1000
       error_px = error[0] + error[1] * s + error[2] * s * nearness
   with s = sqrt(pixels) and triangles the scene's. `reflect bench
   --fit-auto FILE` fits them from its own measurements; the library has a
   fit built in. A method without a model for a class is never chosen. */
typedef enum refl_auto_class {
    REFL_AUTO_PLANAR = 0,    /* a reflector of a few planes that PLANAR draws, the eye in front
                                of one of its mirror faces (or it has glass ones) */
    REFL_AUTO_CONVEX,        /* curved, its normals mostly away from its centre */
    REFL_AUTO_CONCAVE,       /* curved, its normals mostly towards its centre */
    REFL_AUTO_GLASS,         /* glass (any shape) */
    REFL_AUTO_PARTIAL,       /* a curved partial reflector */
    REFL_AUTO_CLASS_COUNT
} refl_auto_class;
REFL_API const char *refl_auto_class_name(int reflector_class); /* "planar", ...; "unknown" */

typedef struct refl_auto_features {
    int reflector_class;     /* refl_auto_class */
    long long pixels;        /* its pixels in the frame (the stencil's) */
    float nearness;          /* how near what it reflects is, in [0, 1]: the mean over 26
                                directions from its bounding sphere's centre of min(1, r / D),
                                r the sphere's radius, D the distance to the first other
                                object's bounding box that way (none: 0) */
    float scene_triangles;   /* the scene's, in all */
    float beyond;            /* the share of its pixels whose path meets another reflector after
                                its first bounce (what a one-bounce method hands the tracer at
                                depth 2 and more), in [0, 1]: over at most 32 of its pixels, the
                                mirror ray from the point and normal the depth buffer gives,
                                against the reflectors' triangles (a concave one's own
                                too); 0 for glass (its paths are the tracer's) and, in
                                AUTO, at depth 1 */
} refl_auto_features;

typedef struct refl_auto_model {
    int fitted;              /* 0: no model (the method is no candidate for the class) */
    int samples;             /* measurements it was fitted to */
    float cost[4];           /* the formulas above */
    float error[3];
} refl_auto_model;
typedef struct refl_auto_models {
    refl_auto_model model[REFL_METHOD_COUNT][REFL_AUTO_CLASS_COUNT];
} refl_auto_models;

/* The predictions of one model (cost at least 0.001 ms, error at least 0). */
REFL_API void refl_auto_predict(const refl_auto_model *model, const refl_auto_features *f, float *error_px,
                                float *cost_ms);
/* The models built into the library (a fit by `reflect bench --fit-auto`). */
REFL_API void refl_auto_models_builtin(refl_auto_models *out);
/* The text format (docs/methods/auto.md): '#' comments and blank lines,
   a first line "reflect-auto-models 1", then one line per model:
       model METHOD CLASS samples N cost C0 C1 C2 [C3] error E0 E1 E2
   (C3 absent: 0)
   REFL_ERROR_INVALID_ARGUMENT on anything else, with the line and the
   rule it broke in message (may be NULL; message_size bytes, cut). */
REFL_API refl_result refl_auto_models_parse(const char *text, size_t length, refl_auto_models *out, char *message,
                                            size_t message_size);
/* The same from a file; a file that cannot be read is named in message. */
REFL_API refl_result refl_auto_models_load(const char *path, refl_auto_models *out, char *message,
                                           size_t message_size);
/* The models as text into out (cap bytes, NUL-terminated when it fits; out
   may be NULL): the length of the whole text. Parsing it gives the same
   floats back. */
REFL_API size_t refl_auto_models_format(const refl_auto_models *models, char *out, size_t cap);

/* What a frame cost and what it drew. The first fields mean the same for
   every method; each method's own figures are in its sub-struct (zero for
   the others). */
typedef struct refl_envmap_frame_stats {
    long long cube_faces;    /* cube faces rendered (6 per reflector) */
} refl_envmap_frame_stats;

typedef struct refl_planar_frame_stats {
    long long renderings;    /* mirror renderings at every level */
    long long deepest;       /* of those, renderings at the deepest level */
    long long culled;        /* mirror renderings skipped as not visible */
    long long traced;        /* pixels of mirrors past options.max_renderings, drawn by
                                RAYTRACE's tracer */
} refl_planar_frame_stats;

typedef struct refl_c3rc_frame_stats {
    long long points;        /* scene samples in the kd-tree */
    long long cameras;       /* 3-ray cameras (reflector triangles and their splits) */
    long long leaves;        /* kd-tree leaves whose points were projected */
    long long culled;        /* kd-tree boxes the view-volume test rejected */
    long long box_tests;     /* kd-tree boxes tested against a camera's view volume */
    long long projections;   /* points of the leaves the box test accepted (the paper's
                                count; those a cheaper per-point hull test then skips
                                included), after level-of-detail thinning */
    long long projected;     /* valid projections found (a point may have several) */
    long long multiple;      /* projections beyond a point's first in one camera
                                (section 5.1's multiple projections, all drawn) */
    long long traced;        /* reflector pixels in a gap of a nearer surface's points (or
                                empty inside them), handed to RAYTRACE's tracer */
    double ms_cull, ms_project; /* thread time in the box tests and in projection and
                                   splatting, summed over threads */
} refl_c3rc_frame_stats;

typedef struct refl_sbc_frame_stats {
    long long pinhole_leaves, ray_leaves; /* BSP leaves of every group's camera */
    long long projections;   /* vertex projections made */
    long long projected;     /* vertices in some leaf's frustum */
    long long ambiguous;     /* with morphs: scene vertices that project at some but not all
                                of the eye tetrahedron's nodes (paper 003 VI) */
    int histories;           /* reflection histories sampled (paper 003's A, B, AB, BA, ...;
                                a refraction through glass counts as one) */
    int groups;              /* reflection groups (a history's pieces within tiles) */
    long long traced;        /* reflector pixels rendered by RAYTRACE's tracer: the fallback's,
                                and those showing a mirror at the last order sampled while
                                the frame's depth goes on */
} refl_sbc_frame_stats;

typedef struct refl_graphcam_frame_stats {
    int frusta;              /* the graph camera's */
    long long triangles;     /* drawn into the impostor (clipped pieces counted) */
    long long rays;          /* reflected rays intersected with it */
    long long hits;          /* of those, the ones that met it */
    long long traced;        /* reflector pixels whose ray the impostor could not answer (it
                                met the scene past what the impostor holds, or a mirror or
                                glass first), drawn by RAYTRACE's tracer */
    long long steps;         /* march samples in all */
    long long max_steps;     /* the most one ray took */
} refl_graphcam_frame_stats;
typedef struct refl_spoc_frame_stats {
    long long impostors;     /* SPOC impostors built (one per reflector and compact diffuse object) */
    long long steps;         /* ray-marching pieces walked over all impostors (paper 004's n) */
    long long max_steps;     /* the most one ray walked in one impostor */
    long long traced;        /* mirror pixels whose reflected ray's march missed an impostored
                                object in front (meeting nothing, or what lies behind it),
                                drawn by RAYTRACE's tracer */
} refl_spoc_frame_stats;

typedef struct refl_layered_em_frame_stats {
    int maps_inferred;       /* viewpoint samples' maps inferred by this frame (or prebuild) */
    int maps_kept;           /* maps this frame took as its renderer kept them */
    int maps_held;           /* maps the renderer (or this frame, alone) holds after it */
    /* the frame's own work, the maps' inference aside (that is ms_build):
       paper 001's section 6 phases */
    double ms_trace;         /* tracing the tessellation's vertices (both greedy paths) */
    double ms_tessellate;    /* the rest of the adaptive tessellation */
    double ms_draw;          /* per-vertex shell coordinates, drawing, compositing */
    long long vertices;      /* vertices traced */
    long long vertex_tests;  /* triangle tests of tracing them (as stats.triangle_tests):
                                their visibility rays through the scene, their greedy paths
                                through the lens objects alone */
    long long traced_pixels; /* lens pixels ray traced: no triangle covered them, or a
                                vertex's path left through another lens beyond the shells */
    long long direct_rows;   /* rows the direct images added to the maps inferred */
    long long continued_pixels; /* sample pixels of the maps inferred whose eye ray met something
                                   else first and was continued to the lens, giving records
                                   (layered_em.continue_incoming) */
    long long quad_misses;   /* vertex terms whose exit ray missed a quad layer (travelling
                                away from it or past its rectangle): that layer is left out
                                there, the next layer shows */
    int solves;              /* least-squares solves of the maps inferred (a layer of a map each) */
    int solves_capped;       /* of them, those stopped by layered_em.iterations before the
                                tolerance: maps short of the least squares */
    int solve_iterations;    /* the most iterations one solve ran */
} refl_layered_em_frame_stats;
/* AUTO's choice for one reflector, and why. */
typedef struct refl_auto_choice {
    int object;
    refl_method method;      /* the chosen */
    int over_budget;         /* 1: no candidate's predicted error met the budget: the least
                                predicted error was chosen */
    refl_auto_features features;
    /* per method: 1 a candidate (predicted below), 0 no model for the class, -1 a
       model but it cannot draw this reflector (PLANAR: curved; C3RC: glass) */
    signed char candidate[REFL_METHOD_COUNT];
    float error_px[REFL_METHOD_COUNT], cost_ms[REFL_METHOD_COUNT];
} refl_auto_choice;
#define REFL_AUTO_MAX_CHOICES 16
typedef struct refl_auto_frame_stats {
    float budget_px;
    int count;               /* reflectors AUTO chose for; the first REFL_AUTO_MAX_CHOICES below */
    refl_auto_choice choices[REFL_AUTO_MAX_CHOICES];
} refl_auto_frame_stats;

typedef struct refl_stats {
    double ms_total, ms_build, ms_base, ms_reflect, ms_composite;
    long long triangles;     /* scene triangles drawn or put in a BVH */
    long long rays;          /* rays traced (primary, secondary and shadow) */
    long long triangle_tests; /* ray-triangle tests of the refl_bvh traces during the frame (one
                                 per ray and triangle of each leaf it visits, hit or missed; a
                                 leaf's spare block lanes not counted), any thread's: a caller's
                                 caster over refl_bvh_intersect counts, Embree does not */
    long long model_bytes;   /* memory of the models a method built (BVH, cube maps, trees) */
    int reflectors;          /* reflector objects in the scene */
    int handed_over;         /* reflectors the method cannot draw (PLANAR: curved ones; C3RC: glass),
                                drawn by RAYTRACE's tracer instead */
    int depth;               /* bounces the frame shows: desc.depth, or 0 where DIRECT
                                draws a reflector. Compare a frame with truth of this
                                depth */
    long long traced_beyond; /* reflector pixels whose path goes past the bounces their
                                method models (ENVMAP, C3RC, SPOC, GRAPHCAM: 1; SBC: 8)
                                and meets a reflector there: drawn by RAYTRACE's tracer */
    int scene_models_built;  /* the scene-wide models built for this frame (the BVH, C3RC's
                                points and kd-tree); 0 when a renderer kept them all from
                                an earlier frame */
    refl_envmap_frame_stats envmap;
    refl_planar_frame_stats planar;
    refl_c3rc_frame_stats c3rc;
    refl_sbc_frame_stats sbc;
    refl_graphcam_frame_stats graphcam;
    refl_spoc_frame_stats spoc;
    refl_layered_em_frame_stats layered_em;
    refl_auto_frame_stats automatic;
} refl_stats;

typedef struct refl_frame {
    int width, height;
    float *rgba;             /* linear RGBA, 4 floats per pixel, rows top first: colour as
                                rendered, unclamped (an HDR sky brighter than 1 stays so) but
                                for radiance past float's range, FLT_MAX; alpha 1 once a
                                render returned */
    float *depth;            /* window depth in [0, 1] */
    uint8_t *stencil;        /* 0: no reflector; k: object k - 1 (objects >= 255 share 255) */
    float *points;           /* 3 per pixel: on reflector pixels, the scene point the pixel
                                shows through its first reflection or refraction; NaN where
                                it shows none (the environment) and on other pixels. The
                                reflection-error metric compares these. */
    refl_stats stats;
    const char *message;     /* after a refl_render that failed with INVALID_ARGUMENT: the
                                rule the desc or view broke (refl_validate_render_desc's
                                words), with OUT_OF_MEMORY past sbc.memory_mb or
                                INVALID_SIZE past C3RC's points (the estimate), or
                                CANCELLED; "" otherwise. A static string or message_text */
    char message_text[160];  /* where a message with numbers is written */
    refl_allocator allocator;
} refl_frame;

REFL_API refl_result refl_frame_create(int width, int height, const refl_allocator *a,
                                       refl_frame **out_frame);
REFL_API void refl_frame_destroy(refl_frame *frame);
/* AUTO's features of scene object `object` in a frame of the scene
   rendered from view (its stencil gives the pixels). */
REFL_API refl_result refl_auto_reflector_features(const refl_scene *scene, const refl_view *view,
                                                  const refl_frame *frame, int object, refl_auto_features *out);
/* How linear colour becomes display colour: scaled by 2^exposure, tone
   mapped, clamped to [0, 1], sRGB-encoded. {0}: exposure 0, no tone map. */
typedef enum refl_tonemap {
    REFL_TONEMAP_CLAMP = 0,  /* none: values over 1 clip to white */
    REFL_TONEMAP_REINHARD,   /* x / (1 + x) per channel */
    REFL_TONEMAP_ACES        /* Narkowicz's fit of the ACES filmic curve, per channel */
} refl_tonemap;
typedef struct refl_display_desc {
    float exposure;          /* stops: colours scaled by 2^exposure; finite, |exposure| <= 64 */
    refl_tonemap tonemap;
} refl_display_desc;
/* One linear colour channel to display: exposure, tone map, [0, 1] clamp,
   sRGB encoding, 8 bits (NaN: 0). d NULL: {0}. */
REFL_API uint8_t refl_display_channel(float linear, const refl_display_desc *d);
/* The frame's colours, linear as rendered, to display colour into out
   (width * height * 4 bytes; alpha as is, scaled to 255): what an 8-bit
   image file or a screen expects. d NULL: {0}. */
REFL_API void refl_frame_to_srgb8(const refl_frame *frame, const refl_display_desc *d, uint8_t *out);

/* Lighting every method shares. */
typedef struct refl_lighting_options {
    int shadows;             /* 1: hard shadows from every light */
    int soft_shadow_samples; /* with shadows: 0 or 1 hard; N (at most 1024): soft shadows,
                                every light with a radius sampled at N positions
                                (refl_light_sample), each light's visible fraction
                                weighing its Lambert term (refl_shade_diffuse_weighted);
                                RAYTRACE casts a shadow ray per sample, the rasterised
                                methods draw a shadow mask per sample. Lights with
                                radius 0 stay hard (one sample). */
    int light_volumes;       /* PLANAR and RAYTRACE: 1: light reflected by planar mirror and
                                partial faces lights diffuse surfaces (paper 002's light
                                volumes): each light (of the first 8) mirrored in each face's
                                plane is a virtual light that reaches a point on the light's
                                side when the path through the face meets the face, weighed
                                by the face's reflectance at that incidence; with shadows,
                                blocked on either leg (PLANAR: objects crossing the face's
                                plane block only the outgoing leg). At most 64 lights in all
                                (the scene's first); glass bends no light here. 0: off */
    int caustic_samples;     /* with light_volumes: 0 or 1: each reflected light from its
                                centre; N (at most 1024): every light with a radius sampled
                                at N positions (refl_light_sample), the reflected light weighed
                                by the fraction whose paths arrive: soft-edged light volumes
                                and caustics (paper 002's accumulated jittered lights) */
    float translucency;      /* PLANAR and RAYTRACE: > 0: glass is translucent (paper 002's
                                fog): what is seen through a glass face from outside is
                                blended towards the glass's colour by exp(-translucency h),
                                h the distance of the point seen from the face's plane (the
                                environment: wholly the colour). PLANAR draws it with rast.h's
                                exponential fog; mirrors seen through glass are not fogged
                                there. 0: clear glass */
} refl_lighting_options;

/* Where rays go: RAYTRACE casts through its own BVH unless given another
   caster (the bench plugs in Embree this way, so both trace one frame with
   the same shading). Both functions run concurrently on worker threads. */
typedef struct refl_ray_caster {
    int (*intersect)(void *user, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax, refl_hit *hit);
    int (*occluded)(void *user, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax); /* NULL:
                                intersect answers it */
    void *user;
} refl_ray_caster;

/* Each method's options; zero everywhere means its defaults. */
typedef struct refl_raytrace_options {
    refl_ray_caster caster;  /* zero: refl_bvh over the scene */
    int greedy;              /* paper 001's two-term greedy ray paths (refl_greedy_paths): an
                                eye ray meeting glass splits into a reflected and a refracted
                                path, and every later interface follows only its child of the
                                larger Fresnel coefficient (ties: reflection). 0: the full ray
                                tree, both children everywhere. Mirrors have one child either
                                way, so mirror-only scenes render the same bytes */
    int unpruned;            /* every branch of the ray tree to desc.depth, as paper 001 counts
                                its full tree's ray queries. 0: a branch whose weight falls
                                below 1/1024 stops, which cannot move an 8-bit pixel */
} refl_raytrace_options;

/* ---- paper 001's greedy ray paths through a lens system ----------------------- */

enum { REFL_GREEDY_MAX_INTERFACES = 32 };

/* One greedy path: the interfaces it met, the child it took at each, what
   it carries and the ray it leaves the lens system by. */
typedef struct refl_greedy_path {
    int exited;              /* 1: left the lens system (the exit ray below is valid); 0: it
                                met one more interface after max_interfaces */
    int length;              /* interfaces met, the first (where the eye ray split) included */
    unsigned int reflected;  /* bit i: 1 where interface i reflected, 0 where it refracted */
    float fresnel;           /* F: product of the coefficients of the children taken */
    float attenuation[3];    /* G: glass tint on entering times exp(-attenuation * length)
                                inside, per channel */
    refl_vec3 exit_origin;   /* the last interface's point (the eye ray's origin when none) */
    refl_vec3 exit_direction; /* unit */
    float inside_length;     /* glass traversed */
} refl_greedy_path;

/* The two terms of paper 001's shading model for one eye ray: T F_T G_T +
   R F_R G_R, T and R the radiance along the exit rays. */
typedef struct refl_greedy_paths_result {
    int terms;               /* 0: the ray met no lens (diffuse or nothing first); 1: a mirror
                                first (reflect only); 2: glass first (both) */
    int object;              /* the lens object met first, -1 when none */
    refl_vec3 first_point;   /* where, NaN when none */
    refl_greedy_path reflect, refract; /* a term that does not exist has fresnel 0 */
} refl_greedy_paths_result;

/* Traces the greedy paths of the ray origin + t dir (dir unit) through the
   scene's lens objects (mirror, partial and glass materials) with `caster`
   (one over the scene's objects; a diffuse object met, or nothing, ends a
   path: the ray leaves the lens system). At the first interface the ray
   starts a reflected path and, at glass, a refracted one; at every later
   interface each takes the child of the larger Fresnel coefficient (total
   internal reflection: reflection; a mirror: reflection, times its
   reflectance). max_interfaces: 0 means REFL_GREEDY_MAX_INTERFACES, and
   larger is clamped to it. *rays (may be NULL) counts the rays cast. */
REFL_API void refl_greedy_paths(const refl_scene *scene, const refl_ray_caster *caster, refl_vec3 origin,
                                refl_vec3 dir, int max_interfaces, refl_greedy_paths_result *out,
                                long long *rays);

/* Paper 001's adaptive tessellation (section 5) of one lens object for a
   view: only the vertices of its front-facing triangles are traced (both
   greedy paths, from the vertex with its own normal, and a visibility ray
   from the eye); a triangle is split at its edge midpoints (1 to 4, or 1
   to 3 and 1 to 2 where some edges project shorter than edge_px) while
   its vertices' paths differ in topology (terms, length, the choice at an
   interface, leaving or not) or their exit rays by more than
   angle_degrees, in either term, unless all three vertices are hidden. An
   edge table gives every midpoint once; the leaves are then
   re-triangulated around the vertices their neighbours put on their
   edges, so the mesh conforms. Levels are split one at a time and each
   level's new vertices traced in parallel: the same mesh for any thread
   count. */
typedef struct refl_lens_tess_desc {
    float angle_degrees;     /* 0: 3 */
    float edge_px;           /* t: edges projected shorter are not split, in pixels of the
                                view; 0: 1 (the paper's t = 3 subpixels at 3x3) */
    int max_level;           /* splits of a mesh triangle at most; 0: 12 */
    int max_interfaces;      /* per path; 0: REFL_GREEDY_MAX_INTERFACES */
    int threads;             /* 0: one per CPU */
} refl_lens_tess_desc;
/* Whatever the desc, a tessellation splits no triangle once it has made
   the mesh's vertices and 16 per pixel of the view (the default t makes
   one or two per lens pixel); re-triangulating the leaves adds at most a
   centre vertex to each. */

typedef struct refl_lens_vertex {
    refl_vec3 position, normal; /* world; normal unit */
    float window[2];         /* pixel coordinates in the view; NaN behind the eye */
    int visible;             /* nothing between the eye and the vertex */
    int level;               /* 0: the mesh's; k: made splitting a level k - 1 triangle */
    refl_greedy_paths_result paths;
} refl_lens_vertex;

typedef struct refl_lens_tess {
    refl_lens_vertex *vertices;
    int vertex_count;        /* each traced once */
    uint32_t *indices;       /* 3 per triangle, wound as the mesh */
    int triangle_count;
    int front_triangles;     /* the mesh's front-facing triangles it started from */
    int splits;              /* triangles split */
    int topology_splits;     /* of which because a path's topology changed */
    int junction_fixes;      /* leaves re-triangulated around a T-junction */
    long long rays;          /* visibility and path rays cast */
    double ms_trace;         /* of its time, tracing the vertices (stats only) */
    refl_allocator allocator;
} refl_lens_tess;

/* Tessellates scene object `object` (a lens: mirror or glass) for view
   through caster (one over the scene, as for refl_greedy_paths). desc NULL:
   the defaults. */
REFL_API refl_result refl_lens_tessellate(const refl_scene *scene, const refl_ray_caster *caster, int object,
                                          const refl_view *view, const refl_lens_tess_desc *desc,
                                          refl_lens_tess **out);
REFL_API void refl_lens_tess_destroy(refl_lens_tess *tess);

/* ---- paper 001's inferred environment maps (section 4) ------------------------- */

/* The kinds of shell a layer is parameterised on (section 4.3: spheres,
   cylinders, finite cubes, and quads for sparse layers). AUTO is the
   options' "choose per layer"; a shell of kind 0 is a sphere. */
typedef enum refl_lem_shell_kind {
    REFL_LEM_SHELL_AUTO = 0,
    REFL_LEM_SHELL_SPHERE,
    REFL_LEM_SHELL_CYLINDER,
    REFL_LEM_SHELL_BOX,
    REFL_LEM_SHELL_QUAD
} refl_lem_shell_kind;

/* The frames a box or cylinder shell is fitted on: AUTO both the world
   axes (a cylinder around the vertical) and the frame fitted to the
   layer's hits (the rotation whose box, or cylinder axis, lies nearest
   them), the records' conflicts choosing; WORLD or FITTED only that one. */
typedef enum refl_lem_shell_frame {
    REFL_LEM_FRAME_AUTO = 0,
    REFL_LEM_FRAME_WORLD,
    REFL_LEM_FRAME_FITTED
} refl_lem_shell_frame;

/* One environment layer: a shell around a lens object, textured as a cube
   map (faces +X -X +Y -Y +Z -Z, GL's layout, face_size texels a side,
   texel (face, x, y) at face * size^2 + y * size + x) of the shell's
   index of a point on it (refl_lem_shell_index). A sphere is center and
   radius; the other kinds are placed by center, an orthonormal frame
   axis[3] and half sizes extent[3] along it: a box its half sides; a
   cylinder around axis[1], its radius extent[0] (= extent[2]) and half
   height extent[1]; a quad in the plane of axis[0] and axis[1] (normal
   axis[2]), extent[0] x extent[1] either side of its centre. */
typedef struct refl_lem_shell {
    refl_vec3 center;
    float radius;
    int face_size;
    int kind;                /* refl_lem_shell_kind; 0 or SPHERE: a sphere */
    refl_vec3 axis[3];
    float extent[3];
} refl_lem_shell;

/* The shell's index of an exit ray: where the ray leaves the shell, as
   the vector the cube map is looked up with (a sphere: the hit minus the
   centre; a box or cylinder: the hit in the shell's frame over its half
   sizes; a quad: (x / extent[0], y / extent[1], 1) of the hit in its
   plane). The runtime interpolates it across a triangle (a quad's as
   (0, 0, 0) where an exit ray misses it: its third component then the
   share of the quad present, refl_lem_shell_texels dividing the first
   two by it). A sphere is met from where the ray starts: from inside,
   where the ray leaves it; from outside (an inner layer's sphere within
   the lens's bounds), where it enters it. 0 (no lookup) when the ray
   starts outside a box or cylinder, misses a sphere from outside or
   travels away from it, or travels away from a quad or misses its
   rectangle. */
REFL_API int refl_lem_shell_index(const refl_lem_shell *shell, refl_vec3 origin, refl_vec3 dir, refl_vec3 *index);
/* 1 where an exit ray starting in box (a lens's bounds) may miss the
   shell, which then leaves its layer out there: a quad, or a sphere that
   does not hold the box (an inner layer whose hits lie within the lens's
   bounds: the runtime interpolates its index as (0, 0, 0) where the exit
   ray misses it, so the index's length over the radius is the share of
   the sphere present). Closed shells holding the box: 0. */
REFL_API int refl_lem_shell_partial(const refl_lem_shell *shell, const refl_vec3 box[2]);
/* The four texels and bilinear weights (summing to 1) of an index: its
   cube-map face, bilinear on the face (taps clamped at its edges). 0 for a
   zero or non-finite index or a bad shell (face_size 1 to 16384). */
REFL_API int refl_lem_shell_texels(const refl_lem_shell *shell, refl_vec3 index, uint32_t texel[4], float weight[4]);
/* How the runtime samples the shell for an exit ray (dir unit): its index,
   then that index's texels. The rendering matrix is made of exactly these. */
REFL_API int refl_lem_shell_lookup(const refl_lem_shell *shell, refl_vec3 origin, refl_vec3 dir, uint32_t texel[4],
                                   float weight[4]);
/* GL hook (REFL_GL_LEM_SHELL, docs/gl.md): a lens's layers' shells (1 to
   REFL_LEM_MAX_LAYERS, any kind) and, when maps is not NULL, each layer's
   inferred map (RGBA per texel, 6 face_size^2 texels in
   refl_lem_shell_texels' order), packed as the other cameras are. */
REFL_API long long refl_gl_pack_lem_shells(const refl_lem_shell *shells, const float *const *maps, int layers,
                                           float *out, long long cap);
/* One layer's: refl_gl_pack_lem_shells of one shell (map may be NULL). */
REFL_API long long refl_gl_pack_lem_shell(const refl_lem_shell *shell, const float *map, float *out, long long cap);

/* The paper's per-pixel confidence: 1 - min(theta_m, theta_c)^2 / theta_c^2,
   theta_m the largest angle between any two of the pixel's exit rays
   (dirs unit); theta_c_degrees 0 means 5. 1 for fewer than two rays. */
REFL_API float refl_lem_confidence(const refl_vec3 *dirs, int count, float theta_c_degrees);

/* A sparse least-squares system C A x = C b over RGBA texels: each row a
   pixel of one term, its texels and weights (A), its target colour (b)
   and confidence (C). */
typedef struct refl_lem_system refl_lem_system;
REFL_API refl_result refl_lem_system_create(int texels, const refl_allocator *a, refl_lem_system **out);
REFL_API void refl_lem_system_destroy(refl_lem_system *system);
/* Appends a row; texels out of range, non-finite weights or targets are
   refused (INVALID_ARGUMENT), a confidence of 0 adds nothing. */
REFL_API refl_result refl_lem_system_add_row(refl_lem_system *system, const uint32_t *texels, const float *weights,
                                             int count, const float target[4], float confidence);
REFL_API int refl_lem_system_rows(const refl_lem_system *system);

typedef struct refl_lem_solve_desc {
    int iterations;          /* at most; 0: 200 */
    float tolerance;         /* stop when |S A^T C^2 (b - A x)| (S: the column scaling
                                below) falls below this times its start, in every
                                channel; 0: 1e-6 */
    int nonnegative;         /* 1: every texel's channels kept at 0 or above (the least
                                squares over x >= 0); 0: unconstrained */
    float damping;           /* lambda, finite and >= 0: minimises |C (A x - b)|^2 +
                                lambda^2 |x|^2, so that a texel only faint rows reach
                                (squared weights summing to well under lambda^2) is drawn
                                towards 0 instead of set to whatever fits those rows;
                                0: none */
} refl_lem_solve_desc;

typedef struct refl_lem_solve_stats {
    int iterations;
    int converged;           /* 1: stopped at the tolerance; 0: at the iterations' cap */
    double residual[4];      /* |C (A x - b)| per channel at the end */
    double initial[4];       /* and at x = 0 */
} refl_lem_solve_stats;

/* Least squares by conjugate gradients on the normal equations (CGLS),
   the four channels at once, from x = 0: texels no row reaches stay 0.
   Each texel's column of C A (with damping, of C A stacked on lambda I)
   is scaled to unit length (Jacobi preconditioning), so the iterations
   needed do not grow with how unevenly the pixels cover the texels.
   A damping that is negative or not finite: INVALID_ARGUMENT.
   With desc->nonnegative, CGLS over the texels the bound leaves free,
   restarted where a step meets it (the iterations' cap counts them all).
   Sequential sums in double: the same x on every run. x: 4 floats per
   texel. stats may be NULL. */
REFL_API refl_result refl_lem_solve(const refl_lem_system *system, const refl_lem_solve_desc *desc, float *x,
                                    refl_lem_solve_stats *stats);

/* Section 4.2's layers: LBG (1-D k-means, Lloyd's iterations from the
   quantiles until no hit moves) over the distances of `count` hits from a
   lens's centre, then every object's hits moved to the layer holding most
   of them (object may be NULL: no objects), and each layer's shell at the
   mean distance of its hits, a continued ray's (ray[i]: the exit ray of
   hit i, its hits together and nearest first; may be NULL) counted by its
   front-most hit in the layer. Returns the layers made (empty ones
   dropped; 0 on bad arguments or no memory) in the order they composite
   in, front to back along the continued rays (a layer before another when
   more rays meet its hits first; by mean distance where as many meet each
   first), their radii in radius[], and, when layer_of is not NULL, each
   hit's layer. A distance not finite is a bad argument. */
enum { REFL_LEM_MAX_LAYERS = 4 };
REFL_API int refl_lem_cluster_layers(const float *distance, const int *object, const int *ray, int count, int layers,
                                     const refl_allocator *a, float *radius, int *layer_of);

/* Section 4.1's records of one viewpoint sample, as rows for one layer:
   every pixel whose centre ray meets lens object `object` first traces
   supersample^2 subsamples' greedy paths; per term, the row is the
   runtime's lookup of the pixel centre's exit ray, the target the mean
   radiance where the subsamples' exit rays meet the scene (diffuse shading
   as RAYTRACE's without shadows, the environment past everything), alpha 1
   (the one layer is opaque), and the confidence that of the subsamples'
   exit rays. */
typedef struct refl_lem_record_desc {
    int object;              /* the lens object */
    int supersample;         /* 0: 3 */
    float theta_c_degrees;   /* 0: 5 */
    int max_interfaces;      /* per path; 0: REFL_GREEDY_MAX_INTERFACES */
} refl_lem_record_desc;

typedef struct refl_lem_record_stats {
    int pixels;              /* lens pixels recorded */
    int rows;                /* rows added (both terms) */
    long long rays;
} refl_lem_record_stats;

REFL_API refl_result refl_lem_record_view(refl_lem_system *system, const refl_scene *scene,
                                          const refl_ray_caster *caster, const refl_view *view,
                                          const refl_lem_shell *shell, const refl_lem_record_desc *desc,
                                          refl_lem_record_stats *stats);

/* LAYERED_EM (paper 001): lens objects traced at adaptively tessellated
   vertices with the two greedy paths, the environment from a sphere-shell
   map per viewpoint sample inferred by least squares to match ray-traced
   records there, the two samples nearest the eye blended. */
typedef struct refl_layered_em_options {
    int samples;             /* viewpoint samples on the circle around each lens object's centre
                                through the eye, at its height: 0: 45 (8 degrees apart) */
    int face_size;           /* shell cube-map face side in texels, at most 1024; 0: half the
                                square root of the lens's pixels at the first sample */
    int supersample;         /* records' subsamples per pixel side, 1 to 8; 0: 1 */
    float edge_px;           /* tessellation's t in pixels; 0: 1 */
    float angle_degrees;     /* tessellation's exit-ray angle; 0: 3 */
    float theta_c_degrees;   /* confidence's angle; 0: 5 */
    int iterations;          /* CG iterations at most; 0: 200 */
    int single_view;         /* 1: each sample's map from its own view alone; 0: also from the
                                views half a spacing either side (the paper's simultaneous
                                inference, against disocclusions between samples) */
    int layers;              /* environment layers (shells) per lens, 1 to
                                REFL_LEM_MAX_LAYERS: refl_lem_cluster_layers over the hits seen
                                from every sample on the circle; 0: 1 */
    int keep_stale_maps;     /* 1: a renderer keeps its maps (and circles and layers) when the
                                scene changes, for measuring the stale maps paper 001 warns of
                                (an environment object moved after the maps were built); only
                                for scenes whose objects moved (none added or removed). 0: the
                                maps are dropped and inferred again */
    int shell;               /* refl_lem_shell_kind of every layer's shell; 0 (AUTO): per layer
                                the kind (and frame) on whose texels the layer's records
                                conflict least, a quad a candidate for an inner layer whose hits
                                are sparse in direction (docs/methods/layered_em.md). QUAD:
                                every inner layer a quad, the outermost AUTO's closed kind */
    int shell_frame;         /* refl_lem_shell_frame of the box and cylinder shells: 0 (AUTO):
                                the world axes and the frame fitted to the layer's hits, the
                                conflicts choosing */
    int direct_images;       /* section 4.3's direct images against disocclusion: rows of rays
                                of the environment without the lens (direct_from), weighed by
                                how little the lens images hold what they see
                                (direct_confidence). 1: on, -1: off, 0: the default
                                (REFL_LEM_DIRECT_DEFAULT) */
    int lens_layers;         /* another lens a lens's path meets: 1 (paper 001 section 6) a surface of
                                the lens's environment like any other, its records the colour the
                                greedy tracer sees of it, so its paths end where they leave the lens
                                and look the other lens up in a layer; -1 the paths cross the whole
                                lens system and a vertex whose path leaves through the other lens
                                has no lookup (its pixels are traced); 0 the default
                                (REFL_LEM_LENS_LAYERS_DEFAULT) */
    int direct_from;         /* where the direct images look from, refl_lem_direct_from; 0: the
                                default (REFL_LEM_DIRECT_FROM_DEFAULT) */
    int direct_confidence;   /* how a direct image's pixel is weighed, refl_lem_direct_confidence;
                                0: the default (REFL_LEM_DIRECT_CONFIDENCE_DEFAULT) */
    int kept_mib;            /* MiB of maps a renderer keeps at most (refl_renderer_prebuild), 1
                                to 1048576; 0: 512 */
    int continue_incoming;   /* paper 001 section 4.1, Figure 4b: a sample's eye ray meeting
                                something else before its lens (the cup before the teapot) is
                                continued through it to the lens, so the lens's hidden parts
                                give records too. 1: on, -1: off, 0: the default
                                (REFL_LEM_CONTINUE_DEFAULT) */
    int share_outer_layer;   /* paper 001 section 4.3: the lenses of a pass share their outermost
                                layer, one map per viewpoint sample solved from every lens's rows
                                at once on one shell around the lenses' joint bounds (fitted as a
                                lens's outermost is), the samples on one circle around them. Not
                                with lens_layers on (a lens would lie inside the shell it is a
                                layer of) nor the DISTANCE direct confidence. 1: on, -1: off, 0:
                                the default (REFL_LEM_SHARE_DEFAULT); one lens: no effect */
} refl_layered_em_options;
typedef enum refl_lem_direct_from {
    REFL_LEM_DIRECT_FROM_CENTRE = 1,    /* rays from the lens's centre towards every texel */
    REFL_LEM_DIRECT_FROM_VIEWPOINT = 2, /* the sample's views without the lens (paper 001: better
                                           for refractive lenses) */
    REFL_LEM_DIRECT_FROM_MATERIAL = 3   /* the paper's rule: the viewpoint for glass, the centre
                                           for mirrors */
} refl_lem_direct_from;
typedef enum refl_lem_direct_confidence {
    REFL_LEM_DIRECT_COVERAGE = 1,       /* 1 minus the texels' coverage by the lens images' rows */
    REFL_LEM_DIRECT_DISTANCE = 2        /* paper 001: by the distance of the ray's hit from the
                                           nearest of the lens images' hits */
} refl_lem_direct_confidence;
/* the centre by coverage: they measure best (docs/methods/layered_em.md, "Direct images") */
enum { REFL_LEM_DIRECT_FROM_DEFAULT = REFL_LEM_DIRECT_FROM_CENTRE,
       REFL_LEM_DIRECT_CONFIDENCE_DEFAULT = REFL_LEM_DIRECT_COVERAGE };
enum { REFL_LEM_DIRECT_DEFAULT = 1 }; /* on by default: it measurably helps (docs/methods/layered_em.md) */
enum { REFL_LEM_LENS_LAYERS_DEFAULT = -1 }; /* traced: it measures better (docs/methods/layered_em.md, "Lens to lens") */
enum { REFL_LEM_CONTINUE_DEFAULT = 1 }; /* on, as in the paper: what the samples do not see of the lens
                                           gains several dB; from views near the samples frames move by
                                           -0.6 to +0.5 dB (docs/methods/layered_em.md, "Continued eye rays") */
enum { REFL_LEM_SHARE_DEFAULT = -1 }; /* off: each lens its own layers (docs/methods/layered_em.md,
                                         "One outer layer for every lens") */

typedef struct refl_envmap_options {
    int size;                /* cube face size in pixels, at most 2048 (48 bytes a texel of
                                each face: 1.2 GB); 0: 256 */
} refl_envmap_options;

typedef struct refl_planar_options {
    int no_culling;          /* 1: render every mirror at every level, seen or not (paper
                                002's count, formula 5) */
    int max_renderings;      /* mirror renderings a frame makes at most; 0: 256. The pixels
                                of the mirrors past it are ray traced (stats.planar.traced) */
} refl_planar_options;

typedef struct refl_c3rc_options {
    float point_density;     /* samples per unit area of every surface; 0: from the view: one
                                per 2 x 2 pixels at the reflectors' distance, raised on an
                                object a folding camera magnifies, at most 2 million in all
                                (a renderer fixes it at its first frame) */
    int kd_leaf_points;      /* kd-tree leaf size (refl_kdtree_desc); 0: 1000 (the paper: 122) */
    int max_splat;           /* largest splat side in pixels, at most 64; 0: 8; from a camera's
                                first fold interval on (section 5.1): its size on screen */
    float camera_split_px;   /* a reflector triangle's camera is split in four while its
                                estimated error exceeds this many pixels (4 levels at most);
                                0: 0.1; negative: never (one camera per triangle, the paper's) */
} refl_c3rc_options;

/* What SBC's reflected rays know of the scene (refl_sbc_options.mode). */
typedef enum refl_sbc_mode {
    REFL_SBC_TRACED = 0,     /* "SBC-traced" (beyond the paper): every ray map sample is ray
                                traced against a BVH of the whole scene (built each frame, or
                                kept by a renderer); its first hit sets the ray's head (twice
                                as far), cuts pieces, splits the reflected triangles it lies
                                in and feeds trace_fallback's checks */
    REFL_SBC_PAPER = 1       /* "SBC-paper": the paper's method, what is timed against ray
                                tracing: no search of the scene (no BVH of it); a ray's head
                                is where it leaves the scene's box; only the mirrors and glass
                                are traced (histories, refraction). trace_fallback must be 0 */
} refl_sbc_mode;

typedef struct refl_sbc_options {
    float error_px;          /* largest camera error in desired-view pixels at the ray map's
                                samples (refl_sbc_desc.error_px); 0: 1 */
    int ray_factor;          /* one reflected ray per factor x factor pixels, at most 64; 0: 2 */
    int batch_groups;        /* reflection groups projected and drawn at once, 1..254
                                (memory: that many times the scene's vertices); 0: 254.
                                The image is the same for any value */
    int trace_fallback;      /* 1: a reflector pixel nothing was drawn on (a hole: a piece
                                thinner than a sample, a scene triangle no vertex of which
                                projects), or whose first-order point the ray map's samples
                                around it contradict (on an object none of their rays meets,
                                nearer or farther than all they meet), is rendered as
                                RAYTRACE renders it when its reflected ray meets anything;
                                its rays count in stats.rays. The other pixels are SBC's
                                (see mixed_levels). 0: the paper's method alone; holes show
                                the environment */
    int mixed_levels;        /* times a mixed reflected triangle (some of its vertices
                                project, some not: the edge of a group) is split in four,
                                1..6; negative: never (it is split only towards where the
                                group's rays meet it). 0: 4, and down to the pixel along a
                                tile's border (no crack between groups); never with trace_fallback,
                                which traces the pixels the group's edge leaves uncovered:
                                most of SBC's projections are these triangles' midpoints */
    /* Prebuilt reflection morphing grids (refl_sbc_morph_build on this
       scene); the front side of each one's object is drawn from its grid
       (paper 003 VI) instead of per-frame SBCs, when the eye lies in one of
       its tetrahedra; otherwise, and for objects without one, as before.
       One grid per object at most (the first counts). */
    const refl_sbc_morph *const *morphs;
    int morph_count;
    int mode;                /* refl_sbc_mode; 0: REFL_SBC_TRACED */
    int memory_mb;           /* the frame's ray maps, groups' trees and a batch's projected
                                vertices at most, in MiB (the reflected triangles drawn are
                                not counted); a batch takes fewer groups to stay within it,
                                and a frame that cannot fails with REFL_ERROR_OUT_OF_MEMORY
                                and frame->message saying what exceeded it. 0: 2048 */
} refl_sbc_options;

/* GRAPHCAM (paper 004, section 5): mirrors reflect a graph-camera
   impostor of the scene's diffuse objects, rebuilt every frame. */
typedef struct refl_graphcam_options {
    const refl_graphcam *camera; /* NULL: one frustum, the view's own pinhole (a plain depth
                                    image, the paper's Fig. 6 baseline) at size x size * height
                                    / width pixels */
    int size;                /* with camera NULL: the impostor's width, at most 8192; 0: twice
                                the frame's */
    int algorithm;           /* refl_graphcam_algorithm; 0: REFL_GRAPHCAM_SEGMENTS */
    float step;              /* SEGMENTS: pixels a step (0: 1); UNIFORM: world units a step
                                (0: the camera's bounds' diagonal / 2048) */
} refl_graphcam_options;
/* SPOC's glass (paper 004 section 6, refraction after Wyman 2005): handed to
   RAYTRACE's tracer (stats.handed_over); or refracted in at each pixel and
   out where the ray leaves, estimated from the view's image of the glass's
   back faces (depth and normals) or found exactly on its mesh (to tell the
   impostors' error from the estimate's), the emerging ray meeting the
   impostors. Two interfaces: with depth 1 only the Fresnel reflection. */
typedef enum refl_spoc_glass {
    REFL_SPOC_GLASS_TRACED = 0,
    REFL_SPOC_GLASS_ESTIMATE,
    REFL_SPOC_GLASS_EXACT_EXIT
} refl_spoc_glass;

typedef struct refl_spoc_options {
    int size;                /* impostor image size (square), 8 to 4096; 0: 512 */
    float strength;          /* the SPOC's push K (refl_spoc), at most 64; 0: 1; negative: 0
                                (a plain depth image, the paper's Fig. 6) */
    float step_scale;        /* ray-marching pieces per texel of a ray's projection, at most
                                16; 0: 1 (the paper's n) */
    float max_edge_px;       /* impostor construction: triangles subdivided to edges of about
                                this many texels, 0.5 to 64; 0: 4 */
    int layers;              /* impostor depth layers (refl_impostor_desc), 1 to 4; 0: 3 */
    int glass;               /* refl_spoc_glass: how glass reflectors are drawn */
} refl_spoc_options;

typedef struct refl_auto_options {
    float error_budget_px;   /* the reflection error (refl_measure_reflection_error's mean, a
                                wrong point or hole counting as the reflector's linear size)
                                a method may be predicted to make; 0: 1 */
    const refl_auto_models *models; /* NULL: refl_auto_models_builtin's */
} refl_auto_options;

/* Hooks for tests and benchmarks. */
typedef struct refl_debug_options {
    int points_last;         /* RAYTRACE and SBC: 1: frame->points holds, per reflector pixel,
                                the last point along its path (past every mirror, the
                                stronger branch at glass as for the first; NaN where the
                                path ends in the environment) instead of the first: how
                                higher-order reflections are measured. Other methods: ignored */
    /* SBC: optional; called once per reflector side seen (object index; the
       back side of an open mesh is a side of its own), on the calling
       thread, with the whole frame's ray map of that side as the method
       builds it (ceil(width / factor) x ceil(height / factor) samples,
       valid 1 on the side's samples and on the ring extrapolated beyond
       its silhouette), before the side is cut into reflection groups. The
       arrays live until the callback returns; its time counts in
       stats.ms_build. For benchmarks (paper 003's Fig. 19) and tests.
       First-order sides only: the histories past them (depth > 1) are not
       reported. */
    void (*sbc_ray_map)(void *user, int object, const refl_sbc_ray *rays, const uint8_t *valid, int map_width,
                        int map_height);
    void *sbc_ray_map_user;
} refl_debug_options;

/* How to render: zero is the defaults (DIRECT): `= {0}` in C, `= {}` in
   C++ (where `{0}` compiles too, its first member being an int, but
   -Wextra warns of the members it leaves out). Options of a method the frame does not use are
   ignored but still validated. */
#define REFL_DEFAULT_DEPTH 6

typedef struct refl_render_desc {
    int threads;             /* 0: one per CPU, at most RAST_MAX_THREADS (64) */
    refl_method method;      /* every reflector's, unless object_methods says otherwise */
    int depth;               /* reflection / refraction bounces; 0: REFL_DEFAULT_DEPTH. A
                                reflector met with none left shows what DIRECT shows
                                there; a method that models fewer says so (stats.depth) */
    int spp;                 /* samples per pixel, a square: 0 or 1, 4, 9 ... 64. The frame
                                is rendered sqrt(spp) times wider and higher and each pixel
                                the mean of its samples' colours; depth, stencil and points
                                are those of its centre sample (odd sqrt: the pixel centre,
                                so the reflection error compares as at 1 spp; even: the
                                sample half a sample right of and below it) */
    refl_lighting_options lighting;
    /* Optional, per object: object_methods[i] (i < object_method_count) is
       the method that draws reflector object i; 0: `method`. Any built
       method; RAYTRACE traces the object's pixels on the base pass (and
       draws whole frames when it is `method`, with object_methods empty).
       A reflector its method cannot draw (PLANAR: a curved one) is traced
       (stats.handed_over). Ignored on objects that are not reflectors. */
    const refl_method *object_methods;
    int object_method_count;
    refl_raytrace_options raytrace;
    refl_envmap_options envmap;
    refl_planar_options planar;
    refl_c3rc_options c3rc;
    refl_sbc_options sbc;
    refl_graphcam_options graphcam;
    refl_layered_em_options layered_em;
    refl_spoc_options spoc;
    refl_auto_options automatic; /* method AUTO (named so: auto is a C keyword) */
    refl_debug_options debug;
    /* optional: called from the rendering thread with done in [0, 1], at the
       start, between the phases and reflector methods, and per band of rows
       of ray tracing; a nonzero return stops the render, which returns
       REFL_ERROR_CANCELLED (its frame's pixels are not a finished image) */
    int (*progress)(void *user, float done);
    void *progress_user;
} refl_render_desc;

/* REFL_OK, or REFL_ERROR_INVALID_ARGUMENT with *message (may be NULL)
   naming the option and the rule it broke, e.g. "sbc.ray_factor: 0 or 1
   to 64" (a static string). desc NULL: the defaults, valid. */
REFL_API refl_result refl_validate_render_desc(const refl_render_desc *desc, const char **message);

/* Renders one frame of the scene from the view into frame (its size must
   match the view's): a renderer created and destroyed around the frame.
   The same bytes as refl_renderer_render's first frame. */
REFL_API refl_result refl_render(const refl_scene *scene, const refl_view *view,
                                 const refl_render_desc *desc, refl_frame *frame);

/* A renderer lives across the frames of one scene and one desc (a camera
   path) and keeps what does not depend on the view: the thread pool, the
   BVH, C3RC's points and kd-tree, LAYERED_EM's maps of the viewpoint
   samples its frames used. What the scene's changes invalidate: every
   refl_scene_* function that changes the scene bumps scene->version,
   and a frame whose scene version differs from the one the models were
   built at rebuilds them all, but for the BVH, refit where the objects
   and their triangle counts are those it was built over (refl_bvh_refit:
   objects moved); code that writes the scene's arrays itself
   calls refl_scene_touch. A frame renders the same bytes as refl_render
   with the same desc, except that C3RC's default point density is the one
   of the renderer's first frame (the density follows the view, and the
   points would otherwise be re-sampled every frame), and LAYERED_EM's
   circle of viewpoint samples around a lens is the one through the eye of
   the first frame (or prebuild) that drew the lens (the paper's maps are
   parameterised by one circle; later eyes off it take the samples of their
   azimuth on it). The scene, and what
   the desc points to (object_methods, sbc.morphs), must outlive the
   renderer; one thread at a time renders with it. */
typedef struct refl_renderer refl_renderer;
REFL_API refl_result refl_renderer_create(const refl_scene *scene, const refl_render_desc *desc,
                                          refl_renderer **out_renderer);
REFL_API refl_result refl_renderer_render(refl_renderer *renderer, const refl_view *view, refl_frame *frame);
REFL_API void refl_renderer_destroy(refl_renderer *renderer);
/* Builds ahead what the renderer's frames around view will take as kept:
   LAYERED_EM's maps of every viewpoint sample (layered_em.samples) on the
   circle through view's eye, for every lens the desc's methods give
   LAYERED_EM (the maps are per scene and sample, not per frame; inferring
   them is most of a first frame's time). Other methods: nothing to build.
   frame (view's size) receives the stats (ms_build, rays, layered_em) and
   the message; its pixels are not an image. Reports progress through the
   desc's callback after each map; REFL_ERROR_CANCELLED when it asks to
   stop (the maps finished so far stay kept). A renderer keeps up to
   layered_em.kept_mib (512) MiB of maps: prebuild infers a lens's samples
   nearest the eye first and stops short of that (its share of it, per
   lens; stats.layered_em.maps_held says how many it holds, the rest
   inferred by the frames that need them), and past it a frame drops the
   oldest first. */
REFL_API refl_result refl_renderer_prebuild(refl_renderer *renderer, const refl_view *view, refl_frame *frame);
/* LAYERED_EM's frame for a host that draws it itself (the GL path,
   tools/reflect_gl_lem.c): per lens object the renderer's LAYERED_EM
   draws (its desc's method, or its object_methods), what the method's
   draw takes: the maps of the one or two viewpoint samples the eye lies
   between, inferred (or kept) as a frame of the renderer infers them,
   with their blend weights, and the lens tessellated for the view, both
   greedy paths per vertex. The frame draws each map and term once: per
   vertex the term's path has a lookup where it left the lens system
   (exited, fresnel > 0) from inside box and every closed layer's
   refl_lem_shell_index finds it (a partial layer missed, a quad or an
   inner sphere (refl_lem_shell_partial with box), leaves that layer out
   there, the index (0, 0, 0)); a fragment composites the layers front to
   back (refl_lem_shell_sample, an inner sphere's scaled by its index's
   length over its radius, the outermost opaque), times the path's
   F G (0 without a lookup) and the map's weight, the draws added over the
   base pass. A lens pixel no triangle covers, or where a vertex whose path
   left has no lookup, is traced. frame (view's size) takes the stats; spp
   1 only. Free with refl_renderer_lem_lenses_free; the texels are the
   renderer's, valid until its next frame. */
typedef struct refl_lem_lens {
    int object;
    int terms;               /* 1: the reflected path; 2 (glass): reflected, then refracted */
    int maps;                /* 1 or 2 */
    float weight[2];         /* each map's share */
    int layers;
    refl_lem_shell shell[2][REFL_LEM_MAX_LAYERS]; /* per map, per layer */
    const float *texels[2][REFL_LEM_MAX_LAYERS];  /* RGBA per texel, refl_lem_shell_texels' order */
    refl_vec3 box[2];        /* an exit ray starting outside left through another lens */
    refl_lens_tess tess;     /* the eye's tessellation */
} refl_lem_lens;
REFL_API refl_result refl_renderer_lem_lenses(refl_renderer *renderer, const refl_view *view, refl_frame *frame,
                                              refl_lem_lens **out, int *count);
REFL_API void refl_renderer_lem_lenses_free(refl_renderer *renderer, refl_lem_lens *lenses, int count);


/* ---- metrics: each method against the ray-traced reference ------------------ */

/* Reflection error in pixels. The reflector pixels are those with a
   nonzero stencil in `truth`; a pixel shows a point when its three
   frame->points coordinates are finite (NaN or inf: none). For a reflector
   pixel x of `test` showing scene point P, x* is the pixel of the same
   reflector (truth's stencil id at x) in `truth` whose true point lies
   nearest P (a kd-tree over the traced points; ties to the lowest pixel
   index); the error is the Euclidean |x - x*| in pixels. P counts as wrong
   when |P - truth(x*)| exceeds `tolerance` times the local spacing s(x*):
   the largest distance from truth(x*) to the true points of its
   4-neighbours on that reflector (with none, to the nearest other true
   point of it). A point may show more than once on one reflector (a
   minified image of a surface beside a magnified one, where the nearest
   true point is likelier in the magnified image): when P matches, the
   error is the distance from x to the nearest pixel y, within 16 pixels
   and nearer than x*, of the same reflector where the truth shows P too:
   |P - truth(y)| within `tolerance` times s(y), and no 8-neighbour of y
   nearer P (the middle of an image of P, not its edge).
   Pixels where the truth shows a point and the test none are holes
   (empty); where neither does, they are not counted. Deterministic;
   single-threaded, O(n log n) in the reflector pixels. */
typedef struct refl_error_desc {
    float tolerance;         /* 0: 1.5 */
    refl_allocator allocator;
} refl_error_desc;

typedef struct refl_reflection_error {
    long long pixels;        /* reflector pixels where truth or test shows a point */
    long long matched;       /* of those, test points found in the true reflection */
    double mean, p95, max;   /* |x - x*| over matched pixels, in pixels; p95 by
                                nearest rank (the smallest error 95% of them do not
                                exceed); all 0 when nothing matched */
    double wrong;            /* fraction of `pixels` showing a point found nowhere */
    double empty;            /* fraction of `pixels` showing nothing where truth shows a point */
} refl_reflection_error;

/* Frames of one size, rendered from the same view; desc may be NULL (the
   defaults, malloc). REFL_ERROR_INVALID_SIZE when the sizes differ. */
REFL_API refl_result refl_measure_reflection_error(const refl_frame *test, const refl_frame *truth,
                                                   const refl_error_desc *desc, refl_reflection_error *out);

/* C3RC's cameras alone, without points or splats (paper 000's camera
   approximation): for each reflector pixel x of `truth` (RAYTRACE of the
   same scene and view with depth 1) showing point P, every reflector
   triangle's C3RC (as C3RC builds it for the view) whose screen box comes
   within 8 pixels of x projects P; the error is the distance in pixels
   from x's centre to the nearest image of P so found (sub-pixel), and P
   with no image within 8 pixels counts as wrong. empty is 0. split_px as
   refl_render_desc.camera_split_px. Single-threaded. */
REFL_API refl_result refl_c3rc_measure_camera_error(const refl_scene *scene, const refl_view *view,
                                                    const refl_frame *truth, float split_px,
                                                    refl_reflection_error *out);

/* The cameras C3RC builds for the view, for a host that draws them itself
   (the GL path, tools/reflect_gl_c3rc.c): every piece of every reflector
   triangle, split as split_px asks (refl_render_desc.c3rc.camera_split_px:
   0 the default, negative never), whichever side the view sees; the
   method draws those of the triangles its G-buffer shows. Allocated with
   the scene's allocator: free with refl_c3rc_view_cameras_free. */
typedef struct refl_c3rc_view_camera {
    refl_c3rc cam;
    int object, triangle;
    int back;                /* the triangle's back face is the side seen */
    float screen_area;       /* the piece's area in pixels; 0 where it crosses the eye's plane */
    float screen_edge;       /* its longest edge in pixels (the splat's bound past a fold) */
    float near_self;         /* the reflector's own points nearer (in t) are not drawn */
    float sweep;             /* the largest t a scene point can have (INFINITY: unbounded): past the
                                scene's diagonal where the rays converge */
    refl_vec3 base_normal;   /* the piece's unit normal, the side its rays leave */
    int lod;                 /* 1: its rays do not fold, so a leaf it minifies is thinned
                                (refl_c3rc_view_camera_lod) */
} refl_c3rc_view_camera;
REFL_API refl_result refl_c3rc_view_cameras(const refl_scene *scene, const refl_view *view, float split_px,
                                            refl_c3rc_view_camera **out, int *count);
REFL_API void refl_c3rc_view_cameras_free(const refl_scene *scene, refl_c3rc_view_camera *cams);
/* C3RC's level of detail: how many of a kd-tree leaf's `count` points
   (shuffled, as refl_kdtree_build leaves them) the method projects with
   camera vc, the leaf's box lo-hi, at frame density `density` (points per
   unit area): all, or, where vc->lod and the camera minifies the whole
   box, a prefix at half a pixel between points. */
REFL_API int refl_c3rc_view_camera_lod(const refl_c3rc_view_camera *vc, const float lo[3], const float hi[3], int count,
                                       float density);
/* Each object's C3RC sampling density (out: scene->object_count points
   per unit area) as the method samples them at frame density `density`:
   raised on a diffuse object where one of the `count` cameras (those drawn)
   folds and shows it magnified, to a point per 4 pixels there, at most 64
   times `density`, all objects together at most 2e6 points. scaled_down
   (may be NULL): the largest factor that budget scaled a raised density
   down by (1: none). */
REFL_API refl_result refl_c3rc_object_densities(const refl_scene *scene, const refl_c3rc_view_camera *cams, int count,
                                                float density, float *out, float *scaled_down);
/* C3RC's hand-over to its tracer (refl_render's stats.c3rc.traced), for
   a host that splats the points itself: the splatted frame as the test
   reads it. */
typedef struct refl_c3rc_splats {
    int width, height;
    const float *side;           /* per pixel, side_stride floats apart (rows top first): equal on the
                                    pixels of one reflector's one side, another value elsewhere */
    int side_stride;
    const uint64_t *key;         /* per pixel the point splatted there: (the bits of its depth, a
                                    positive float) << 32 | its index; all ones: none */
    const int32_t *point_object; /* per point index its object */
    int reach;                   /* pixels the test looks each way (refl_c3rc_gap_reach) */
} refl_c3rc_splats;
/* How far the gap test looks: the gaps the splats (at most max_splat
   pixels across) leave, wider by spacing_scale where the points lie that
   much farther apart than the frame's default density wants (the sqrt of
   wanted over sampled density, times that of refl_c3rc_object_densities'
   scaled_down). */
REFL_API int refl_c3rc_gap_reach(int max_splat, float spacing_scale);
/* Whether reflector pixel (x, y), showing point `shown` (a key as above:
   its own, or what a pixel whose splats all missed shows instead), lies in
   a gap of a nearer surface's points: the method traces it. */
REFL_API int refl_c3rc_in_gap(const refl_c3rc_splats *f, int x, int y, uint64_t shown);

/* SBC's cameras alone, without rasterisation (paper 003's projection
   accuracy, section VII-A): for each reflector pixel x of `truth`
   (RAYTRACE of the same scene and view with depth 1) showing point P, P is
   projected into every reflection group of its reflector as SBC builds
   them for the view with `desc` (sbc_error_px, sbc_ray_factor, threads;
   may be NULL; depth is taken as 1); the error is the distance in pixels from x's centre to the
   nearest image of P (sub-pixel), counted by the kind of leaf that holds
   P in the group of x's pixel (else the kind that made the image). P with
   no image within 8 pixels counts as wrong, in that kind (pinhole when
   none). empty
   is 0; everything 0 when the view shows no reflector. */
typedef struct refl_sbc_camera_error {
    refl_reflection_error pinhole, ray_list;   /* every truth pixel: the nearest image */
    refl_reflection_error pinhole_samples,     /* the ray map's sample pixels only, each point */
                          ray_list_samples;    /* through its pixel's own group (the leaf there
                                                  decides the kind; no image: wrong): where the
                                                  build checks its fit (heads, tails) */
} refl_sbc_camera_error;
REFL_API refl_result refl_sbc_measure_camera_error(const refl_scene *scene, const refl_view *view,
                                                  const refl_render_desc *desc, const refl_frame *truth,
                                                  refl_sbc_camera_error *out);

/* Image error of the RGB of the colours against the truth (alpha
   ignored), each channel clamped to [0, 1] and quantised to 8 bits as
   linear values, over every pixel or (reflectors_only) over the truth's
   reflector pixels; threshold per channel in [0, 1] (0: 2/255): a pixel is
   over it when some channel differs by more (a difference of exactly the
   threshold is not). The same numbers as tools/image_io's
   refl_image_compare. No pixels: all 0, psnr INFINITY. */
typedef struct refl_image_error {
    long long pixels;
    double rmse;             /* in [0, 1] */
    double psnr;             /* dB; INFINITY when identical */
    double max_diff;         /* largest channel difference, in [0, 1] */
    double over_threshold;   /* fraction of pixels with a channel over threshold */
} refl_image_error;
REFL_API refl_result refl_measure_image_error(const refl_frame *test, const refl_frame *truth, int reflectors_only,
                                             float threshold, refl_image_error *out);

/* Flicker along a camera path: how much more a method's reflector pixels
   change from one frame to the next than the truth's do. Per pixel that is
   a reflector in both truth frames, the change of each (the largest RGB
   channel difference, in 8-bit levels of the clamped linear colour, as
   refl_measure_image_error counts) and the excess max(0, test's - truth's);
   a method that follows the truth smoothly has excess 0 however fast the
   camera moves. No pixels: all 0. */
typedef struct refl_flicker {
    long long pixels;
    double mean, p95;        /* the excess, in levels; p95 by nearest rank */
    double test_change, truth_change; /* the mean change of each, in levels */
} refl_flicker;
REFL_API refl_result refl_measure_flicker(const refl_frame *test_prev, const refl_frame *test,
                                          const refl_frame *truth_prev, const refl_frame *truth, refl_flicker *out);

/* The world ray through window point (px, py) of a view (pixel centres at
   x + 0.5, y + 0.5, row 0 at the top): unit dir, starting on the near
   plane, reaching the far plane at *tmax, as the rasteriser clips. Any
   output may be NULL; view NULL: zero outputs; scene NULL: an empty
   scene's near and far. */
REFL_API void refl_view_ray(const refl_view *view, const refl_scene *scene, float px, float py, refl_vec3 *origin,
                            refl_vec3 *dir, float *tmax);

/* View and projection matrices of a view (near/far resolved from the scene
   when zero; scene NULL: an empty scene's). view NULL: identities. */
REFL_API void refl_view_matrices(const refl_view *view, const refl_scene *scene, refl_mat4 *view_m,
                                 refl_mat4 *proj_m);

#ifdef __cplusplus
}
#endif
#endif /* REFLECT_H_INCLUDED */
