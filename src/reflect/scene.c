/* Scenes: growable arrays of meshes, materials, objects, lights and
   textures, the environment and the scene's own camera. The scene owns
   everything added to it. */
#include "internal.h"

REFL_API refl_result refl_scene_create(const refl_allocator *a, refl_scene **out_scene) {
    refl_scene *s;
    if (!out_scene) return REFL_ERROR_INVALID_ARGUMENT;
    *out_scene = NULL;
    if (a && ((a->alloc != NULL) != (a->free != NULL))) return REFL_ERROR_INVALID_ARGUMENT;
    s = (refl_scene *)refl__calloc(a, 1, sizeof(refl_scene));
    if (!s) return REFL_ERROR_OUT_OF_MEMORY;
    s->allocator = refl__allocator(a);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 0.1f;
    *out_scene = s;
    return REFL_OK;
}

static void refl__image_free(const refl_allocator *a, refl_image *img) {
    refl__free(a, img->pixels);
    memset(img, 0, sizeof(*img));
}

static void refl__environment_free(const refl_allocator *a, refl_environment *env) {
    int i;
    refl__image_free(a, &env->image);
    for (i = 0; i < 6; ++i) refl__image_free(a, &env->faces[i]);
}

REFL_API void refl_scene_destroy(refl_scene *s) {
    refl_allocator a;
    int i;
    if (!s) return;
    a = s->allocator;
    for (i = 0; i < s->mesh_count; ++i) refl_mesh_destroy(s->meshes[i]);
    for (i = 0; i < s->texture_count; ++i) refl__image_free(&a, &s->textures[i]);
    refl__environment_free(&a, &s->environment);
    refl__free(&a, s->meshes);
    refl__free(&a, s->materials);
    refl__free(&a, s->objects);
    refl__free(&a, s->lights);
    refl__free(&a, s->textures);
    refl__free(&a, s);
}

/* Appends one element of `size` bytes to *array (count *count), growing by
   doubling when the count reaches a power of two. Index or -1. */
static int refl__push(const refl_allocator *a, void **array, int *count, size_t size, const void *elem) {
    int n = *count;
    if (n >= INT_MAX / 2) return -1;
    if ((n & (n - 1)) == 0) { /* 0, 1, 2, 4 ...: full, grow */
        size_t cap = n ? (size_t)n * 2 : 4;
        void *grown = refl__alloc(a, cap * size);
        if (!grown) return -1;
        if (n) memcpy(grown, *array, (size_t)n * size);
        refl__free(a, *array);
        *array = grown;
    }
    memcpy((char *)*array + (size_t)n * size, elem, size);
    *count = n + 1;
    return n;
}

REFL_API int refl_scene_add_mesh(refl_scene *s, refl_mesh *mesh) {
    int i;
    if (!s || !mesh) {
        refl_mesh_destroy(mesh);
        return REFL_ERROR_INVALID_ARGUMENT;
    }
    i = refl__push(&s->allocator, (void **)&s->meshes, &s->mesh_count, sizeof(refl_mesh *), &mesh);
    if (i < 0) {
        refl_mesh_destroy(mesh);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    s->version++;
    return i;
}

static const char *refl__material_rule(const refl_material *m, int texture_count) {
    if ((int)m->type < REFL_DIFFUSE || (int)m->type > REFL_PARTIAL) return "material.type: a refl_material_type";
    if (m->texture < 0 || m->texture > texture_count) return "material.texture: 0 or a texture id";
    if (!refl__all_finite(m->color, 4) || !refl__all_finite(m->tint, 3) || !refl__isfinite(m->reflectance) ||
        !refl__isfinite(m->ior) || !refl__isfinite(m->attenuation) || !refl__isfinite(m->mirror_weight) ||
        !refl__isfinite(m->fresnel_min) || !refl__isfinite(m->fresnel_max) || !refl__isfinite(m->fade_distance) ||
        !refl__isfinite(m->fade_min) || !refl__isfinite(m->fade_max) || !refl__all_finite(m->emissive, 3))
        return "material: every number finite";
    if (m->emissive[0] < 0.0f || m->emissive[1] < 0.0f || m->emissive[2] < 0.0f) return "material.emissive: >= 0";
    return NULL;
}

REFL_API int refl_scene_add_material(refl_scene *s, const refl_material *m) {
    int i;
    if (!s || !m || refl__material_rule(m, s->texture_count)) return REFL_ERROR_INVALID_ARGUMENT;
    i = refl__push(&s->allocator, (void **)&s->materials, &s->material_count, sizeof(refl_material), m);
    if (i >= 0) s->version++;
    return i < 0 ? REFL_ERROR_OUT_OF_MEMORY : i;
}

REFL_API int refl_scene_add_object(refl_scene *s, const refl_object *o) {
    int i, k;
    if (!s || !o || o->mesh < 0 || o->mesh >= s->mesh_count || o->material < 0 ||
        o->material >= s->material_count)
        return REFL_ERROR_INVALID_ARGUMENT;
    for (k = 0; k < 16; ++k)
        if (!refl__isfinite(o->transform.m[k])) return REFL_ERROR_INVALID_ARGUMENT;
    i = refl__push(&s->allocator, (void **)&s->objects, &s->object_count, sizeof(refl_object), o);
    if (i >= 0) s->version++;
    return i < 0 ? REFL_ERROR_OUT_OF_MEMORY : i;
}

static const char *refl__light_rule(const refl_light *l) {
    if ((int)l->type < REFL_LIGHT_POINT || (int)l->type > REFL_LIGHT_DIRECTIONAL) return "light.type: a refl_light_type";
    if (!refl__v3_finite(l->position) || !refl__v3_finite(l->direction) || !refl__all_finite(l->color, 3) ||
        !refl__isfinite(l->radius))
        return "light: every number finite";
    return NULL;
}

REFL_API int refl_scene_add_light(refl_scene *s, const refl_light *l) {
    int i;
    if (!s || !l || refl__light_rule(l)) return REFL_ERROR_INVALID_ARGUMENT;
    i = refl__push(&s->allocator, (void **)&s->lights, &s->light_count, sizeof(refl_light), l);
    if (i >= 0) s->version++;
    return i < 0 ? REFL_ERROR_OUT_OF_MEMORY : i;
}

/* A copy of w x h RGBA floats, or an error. */
static refl_result refl__image_copy(const refl_allocator *a, int w, int h, const float *rgba, refl_image *out) {
    memset(out, 0, sizeof(*out));
    if (w <= 0 || h <= 0 || w > 65536 || h > 65536) return REFL_ERROR_INVALID_SIZE;
    if (!rgba || !refl__all_finite(rgba, (size_t)w * (size_t)h * 4)) return REFL_ERROR_INVALID_ARGUMENT;
    out->pixels = (float *)refl__calloc(a, (size_t)w * (size_t)h, 4 * sizeof(float));
    if (!out->pixels) return REFL_ERROR_OUT_OF_MEMORY;
    memcpy(out->pixels, rgba, (size_t)w * (size_t)h * 4 * sizeof(float));
    out->width = w;
    out->height = h;
    return REFL_OK;
}

REFL_API int refl_scene_add_texture(refl_scene *s, int width, int height, const float *rgba) {
    refl_image img;
    refl_result r;
    int i;
    if (!s) return REFL_ERROR_INVALID_ARGUMENT;
    if ((r = refl__image_copy(&s->allocator, width, height, rgba, &img)) != REFL_OK) return r;
    i = refl__push(&s->allocator, (void **)&s->textures, &s->texture_count, sizeof(refl_image), &img);
    if (i < 0) {
        refl__image_free(&s->allocator, &img);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    s->version++;
    return i + 1;
}

REFL_API refl_result refl_scene_set_environment(refl_scene *s, const refl_environment *env) {
    refl_environment e;
    refl_result r = REFL_OK;
    int i;
    if (!s || !env || (int)env->type < REFL_ENV_COLOR || (int)env->type > REFL_ENV_CUBE ||
        !refl__all_finite(env->color, 3) || !refl__isfinite(env->intensity))
        return REFL_ERROR_INVALID_ARGUMENT;
    e = *env;
    memset(&e.image, 0, sizeof(e.image));
    memset(e.faces, 0, sizeof(e.faces));
    if (env->type == REFL_ENV_EQUIRECT)
        r = refl__image_copy(&s->allocator, env->image.width, env->image.height, env->image.pixels, &e.image);
    for (i = 0; env->type == REFL_ENV_CUBE && i < 6 && r == REFL_OK; ++i) {
        if (env->faces[i].width != env->faces[0].width || env->faces[i].height != env->faces[i].width)
            r = REFL_ERROR_INVALID_SIZE;
        else
            r = refl__image_copy(&s->allocator, env->faces[i].width, env->faces[i].height,
                                 env->faces[i].pixels, &e.faces[i]);
    }
    if (r != REFL_OK) {
        refl__environment_free(&s->allocator, &e);
        return r;
    }
    refl__environment_free(&s->allocator, &s->environment);
    s->environment = e;
    s->version++;
    return REFL_OK;
}

REFL_API void refl_scene_bounds(const refl_scene *s, refl_vec3 *lo, refl_vec3 *hi) {
    refl_vec3 l = refl_v3(FLT_MAX, FLT_MAX, FLT_MAX), h = refl_v3(-FLT_MAX, -FLT_MAX, -FLT_MAX);
    int i, c;
    for (i = 0; s && i < s->object_count; ++i) {
        const refl_object *o = &s->objects[i];
        refl_vec3 ml, mh;
        refl_mesh_bounds(s->meshes[o->mesh], &ml, &mh);
        for (c = 0; c < 8; ++c) { /* the corners of the mesh box, transformed */
            refl_vec3 p = refl_v3(c & 1 ? mh.x : ml.x, c & 2 ? mh.y : ml.y, c & 4 ? mh.z : ml.z);
            p = refl_mat4_point(o->transform, p);
            l = refl_v3(REFL__MIN(l.x, p.x), REFL__MIN(l.y, p.y), REFL__MIN(l.z, p.z));
            h = refl_v3(REFL__MAX(h.x, p.x), REFL__MAX(h.y, p.y), REFL__MAX(h.z, p.z));
        }
    }
    if (l.x > h.x) l = h = refl_v3(0, 0, 0); /* empty scene */
    if (lo) *lo = l;
    if (hi) *hi = h;
}

REFL_API void refl_object_world_bounds(const refl_scene *scene, int i, refl_vec3 *lo, refl_vec3 *hi) {
    const refl_object *o = &scene->objects[i];
    const refl_mesh *m = scene->meshes[o->mesh];
    int v;
    *lo = refl_v3(FLT_MAX, FLT_MAX, FLT_MAX);
    *hi = refl_v3(-FLT_MAX, -FLT_MAX, -FLT_MAX);
    for (v = 0; v < m->vertex_count; ++v) {
        const float *q = m->positions + 3 * (size_t)v;
        refl_vec3 w = refl_mat4_point(o->transform, refl_v3(q[0], q[1], q[2]));
        *lo = refl__v3_min(*lo, w);
        *hi = refl__v3_max(*hi, w);
    }
    if (!m->vertex_count) *lo = *hi = refl_mat4_point(o->transform, refl_v3(0.0f, 0.0f, 0.0f));
}

REFL_API int refl_object_is_flat(const refl_scene *scene, int i) {
    refl_vec3 lo, hi, size;
    float small, large;
    refl_object_world_bounds(scene, i, &lo, &hi);
    size = refl_v3_sub(hi, lo);
    small = REFL__MIN(size.x, REFL__MIN(size.y, size.z));
    large = REFL__MAX(size.x, REFL__MAX(size.y, size.z));
    return !(small >= 0.01f * large) || !(large > 0.0f);
}

REFL_API int refl_object_world_positions(const refl_scene *s, int object, float *out) {
    const refl_mesh *m;
    int i;
    if (!s || object < 0 || object >= s->object_count || s->objects[object].mesh < 0 ||
        s->objects[object].mesh >= s->mesh_count)
        return REFL_ERROR_INVALID_ARGUMENT;
    m = s->meshes[s->objects[object].mesh];
    for (i = 0; out && i < m->vertex_count; ++i) {
        const float *q = m->positions + 3 * (size_t)i;
        refl_vec3 w = refl_mat4_point(s->objects[object].transform, refl_v3(q[0], q[1], q[2]));
        out[3 * (size_t)i] = w.x;
        out[3 * (size_t)i + 1] = w.y;
        out[3 * (size_t)i + 2] = w.z;
    }
    return m->vertex_count;
}

REFL_API void refl_scene_normalize(refl_scene *s, float size) {
    refl_vec3 lo, hi, c;
    float diag, k;
    refl_mat4 m;
    int i;
    if (!s || !(size > 0.0f) || !s->object_count) return;
    s->version++;
    refl_scene_bounds(s, &lo, &hi);
    diag = refl_v3_length(refl_v3_sub(hi, lo));
    if (!(diag > 0.0f)) return;
    k = size / diag;
    c = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    m = refl_mat4_mul(refl_mat4_scale(refl_v3(k, k, k)), refl_mat4_translate(refl_v3_scale(c, -1.0f)));
    for (i = 0; i < s->object_count; ++i) s->objects[i].transform = refl_mat4_mul(m, s->objects[i].transform);
    for (i = 0; i < s->light_count; ++i)
        if (s->lights[i].type == REFL_LIGHT_POINT) s->lights[i].position = refl_mat4_point(m, s->lights[i].position);
    if (s->has_camera) {
        s->camera.eye = refl_mat4_point(m, s->camera.eye);
        s->camera.target = refl_mat4_point(m, s->camera.target);
        s->camera.znear *= k;
        s->camera.zfar *= k;
    }
}

REFL_API refl_material refl_material_diffuse(float r, float g, float b) {
    refl_material m;
    memset(&m, 0, sizeof m);
    m.type = REFL_DIFFUSE;
    m.color[0] = r;
    m.color[1] = g;
    m.color[2] = b;
    m.color[3] = 1.0f;
    return m;
}

REFL_API refl_material refl_material_mirror(float reflectance) {
    refl_material m = refl_material_diffuse(1.0f, 1.0f, 1.0f);
    m.type = REFL_MIRROR;
    m.reflectance = reflectance;
    return m;
}

REFL_API refl_material refl_material_glass(float ior) {
    refl_material m = refl_material_diffuse(1.0f, 1.0f, 1.0f);
    m.type = REFL_GLASS;
    m.ior = ior;
    return m;
}

REFL_API refl_light refl_light_point(refl_vec3 position, float intensity) {
    refl_light l;
    memset(&l, 0, sizeof l);
    l.type = REFL_LIGHT_POINT;
    l.position = position;
    l.color[0] = l.color[1] = l.color[2] = intensity;
    return l;
}

REFL_API refl_light refl_light_directional(refl_vec3 direction, float intensity) {
    refl_light l = refl_light_point(refl_v3(0.0f, 0.0f, 0.0f), intensity);
    l.type = REFL_LIGHT_DIRECTIONAL;
    l.direction = refl_v3_normalize(direction);
    return l;
}

REFL_API int refl_scene_add(refl_scene *s, refl_mesh *mesh, const refl_material *material, refl_mat4 transform) {
    refl_object o;
    if (!s || !material) {
        refl_mesh_destroy(mesh);
        return REFL_ERROR_INVALID_ARGUMENT;
    }
    memset(&o, 0, sizeof o);
    o.transform = transform;
    if ((o.mesh = refl_scene_add_mesh(s, mesh)) < 0) return o.mesh;
    if ((o.material = refl_scene_add_material(s, material)) < 0) return o.material;
    return refl_scene_add_object(s, &o);
}

REFL_API void refl_scene_complete(refl_scene *s) {
    refl_vec3 lo, hi, c;
    float diag;
    if (!s) return;
    refl_scene_bounds(s, &lo, &hi);
    c = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    diag = refl_v3_length(refl_v3_sub(hi, lo));
    if (!(diag > 0.0f) || !refl__isfinite(diag)) diag = 1.0f;
    if (!s->has_camera) {
        memset(&s->camera, 0, sizeof s->camera);
        s->camera.eye = refl_v3_add(c, refl_v3(0.35f * diag, 0.45f * diag, 1.1f * diag));
        s->camera.target = c;
        s->camera.up = refl_v3(0, 1, 0);
        s->camera.fovy_degrees = 45.0f;
        s->has_camera = 1;
    }
    if (refl_v3_length(s->camera.up) == 0.0f) s->camera.up = refl_v3(0, 1, 0);
    if (!s->light_count) {
        refl_light key = refl_light_directional(refl_v3(-0.4f, -1.0f, -0.6f), 0.9f);
        refl_scene_add_light(s, &key);
    }
    if (s->environment.type == REFL_ENV_COLOR && s->environment.color[0] == 0.0f &&
        s->environment.color[1] == 0.0f && s->environment.color[2] == 0.0f) {
        s->environment.color[0] = 0.45f; /* a sky, so mirrors have something to show */
        s->environment.color[1] = 0.6f;
        s->environment.color[2] = 0.85f;
    }
    s->version++;
}

REFL_API void refl_scene_touch(refl_scene *s) {
    if (s) s->version++;
}

REFL_API long long refl_scene_triangles(const refl_scene *s) {
    long long n = 0;
    int i;
    for (i = 0; s && i < s->object_count; ++i) n += s->meshes[s->objects[i].mesh]->triangle_count;
    return n;
}

/* ---- built-in scenes ------------------------------------------------------ */

static const char *const refl__builtin_names[] = {"default", "mirror-room", "concave", "glass", "maze", "teapots",
                                                   "hybrid", NULL};

REFL_API const char *const *refl_builtin_names(void) { return refl__builtin_names; }

/* Adds the mesh a shape function just made (`made` is its result, *mesh
   its output: read here, after the call, since argument evaluation order
   is unspecified) with a material and transform. Returns the object index
   or a negative refl_result; the scene owns the mesh either way. */
static int refl__add(refl_scene *s, refl_result made, refl_mesh **mesh, const refl_material *m,
                     refl_mat4 transform, const char *name) {
    refl_object o;
    int mi, mat;
    if (made != REFL_OK) return made;
    mi = refl_scene_add_mesh(s, *mesh);
    *mesh = NULL;
    if (mi < 0) return mi;
    mat = refl_scene_add_material(s, m);
    if (mat < 0) return mat;
    memset(&o, 0, sizeof o);
    o.mesh = mi;
    o.material = mat;
    o.transform = transform;
    strncpy(o.name, name, sizeof(o.name) - 1);
    return refl_scene_add_object(s, &o);
}

static refl_material refl__material(refl_material_type type, float r, float g, float b, const char *name) {
    refl_material m;
    memset(&m, 0, sizeof m);
    m.type = type;
    m.color[0] = r; m.color[1] = g; m.color[2] = b; m.color[3] = 1.0f;
    strncpy(m.name, name, sizeof(m.name) - 1);
    return m;
}

static refl_mat4 refl__at(float x, float y, float z) { return refl_mat4_translate(refl_v3(x, y, z)); }

/* A floor, a key and a fill light, a sky-coloured environment and a camera. */
static refl_result refl__stage(refl_scene *s, const refl_allocator *a, float floor_size, refl_vec3 eye,
                               refl_vec3 target) {
    refl_material floor_m = refl__material(REFL_DIFFUSE, 0.55f, 0.55f, 0.5f, "floor");
    refl_light key, fill;
    refl_environment env;
    refl_mesh *m = NULL;
    int r = refl__add(s, refl_mesh_plane(floor_size, 16, a, &m), &m, &floor_m, refl_mat4_identity(), "floor");
    if (r < 0) return (refl_result)r;
    memset(&key, 0, sizeof key);
    key.type = REFL_LIGHT_POINT;
    key.position = refl_v3(4.0f, 8.0f, 6.0f);
    key.color[0] = key.color[1] = key.color[2] = 0.9f;
    memset(&fill, 0, sizeof fill);
    fill.type = REFL_LIGHT_DIRECTIONAL;
    fill.direction = refl_v3_normalize(refl_v3(0.5f, -1.0f, -0.3f));
    fill.color[0] = 0.25f; fill.color[1] = 0.27f; fill.color[2] = 0.3f;
    if ((r = refl_scene_add_light(s, &key)) < 0 || (r = refl_scene_add_light(s, &fill)) < 0) return (refl_result)r;
    memset(&env, 0, sizeof env);
    env.type = REFL_ENV_COLOR;
    env.color[0] = 0.45f; env.color[1] = 0.6f; env.color[2] = 0.85f;
    if ((r = refl_scene_set_environment(s, &env)) != REFL_OK) return (refl_result)r;
    s->camera.eye = eye;
    s->camera.target = target;
    s->camera.up = refl_v3(0, 1, 0);
    s->camera.fovy_degrees = 45.0f;
    s->camera.width = 640;
    s->camera.height = 480;
    s->has_camera = 1;
    return REFL_OK;
}

/* How far the mesh reaches along +z near height y in the x = 0 plane: the
   teapot's front, found from its vertices so objects can touch it. */
static float refl__front_extent(const refl_mesh *m, float y) {
    float best = 0.0f;
    int v;
    for (v = 0; v < m->vertex_count; ++v) {
        const float *p = m->positions + 3 * v;
        if (fabsf(p[0]) < 0.2f && fabsf(p[1] - y) < 0.2f && p[2] > best) best = p[2];
    }
    return best;
}

/* default: a mirror teapot on a floor with diffuse objects close to it,
   the sphere touching it (overlapping by 3% of its radius). */
static refl_result refl__scene_default(refl_scene *s, const refl_allocator *a, int tess) {
    refl_material mirror = refl__material(REFL_MIRROR, 0.9f, 0.9f, 0.9f, "mirror");
    refl_material red = refl__material(REFL_DIFFUSE, 0.8f, 0.15f, 0.1f, "red");
    refl_material green = refl__material(REFL_DIFFUSE, 0.15f, 0.7f, 0.2f, "green");
    refl_material blue = refl__material(REFL_DIFFUSE, 0.15f, 0.25f, 0.8f, "blue");
    refl_mesh *m = NULL;
    refl_result r;
    int k, teapot;
    if ((r = refl__stage(s, a, 20.0f, refl_v3(0.0f, 4.5f, 9.0f), refl_v3(0.0f, 1.2f, 0.0f))) != REFL_OK) return r;
    mirror.reflectance = 0.9f;
    if ((teapot = refl__add(s, refl_mesh_teapot(tess, a, &m), &m, &mirror, refl_mat4_identity(), "teapot")) < 0)
        return (refl_result)teapot;
    if ((k = refl__add(s, refl_mesh_torus(0.6f, 0.25f, 32, 16, a, &m), &m, &red, refl__at(2.6f, 0.25f, 1.6f),
                       "torus")) < 0)
        return (refl_result)k;
    {
        float front = refl__front_extent(s->meshes[s->objects[teapot].mesh], 0.7f);
        if ((k = refl__add(s, refl_mesh_sphere(0.7f, 32, 16, a, &m), &m, &green,
                           refl__at(0.0f, 0.7f, front + 0.7f * 0.97f), "sphere")) < 0)
            return (refl_result)k;
    }
    if ((k = refl__add(s, refl_mesh_box(refl_v3(1.2f, 1.2f, 1.2f), a, &m), &m, &blue,
                       refl_mat4_mul(refl__at(0.6f, 0.6f, -3.0f), refl_mat4_rotate(refl_v3(0, 1, 0), 0.6f)),
                       "box")) < 0)
        return (refl_result)k;
    return REFL_OK;
}

/* mirror-room: four facing planar mirrors around a few objects. */
static refl_result refl__scene_mirror_room(refl_scene *s, const refl_allocator *a, int tess) {
    refl_material mirror = refl__material(REFL_MIRROR, 0.92f, 0.92f, 0.95f, "mirror");
    refl_material orange = refl__material(REFL_DIFFUSE, 0.9f, 0.5f, 0.1f, "orange");
    refl_material teal = refl__material(REFL_DIFFUSE, 0.1f, 0.6f, 0.6f, "teal");
    refl_mesh *m = NULL;
    refl_result r;
    int k, w;
    if ((r = refl__stage(s, a, 12.0f, refl_v3(1.8f, 2.2f, 2.4f), refl_v3(-1.0f, 1.0f, -1.5f))) != REFL_OK) return r;
    mirror.reflectance = 0.9f;
    for (w = 0; w < 4; ++w) { /* a wall mirror 6 wide, 3 high, facing the centre */
        refl_mat4 t = refl_mat4_mul(refl_mat4_rotate(refl_v3(0, 1, 0), (float)(w * REFL__PI / 2)),
                                    refl_mat4_mul(refl__at(0.0f, 1.5f, -3.0f),
                                                  refl_mat4_mul(refl_mat4_rotate(refl_v3(1, 0, 0), (float)(REFL__PI / 2)),
                                                                refl_mat4_scale(refl_v3(1.0f, 1.0f, 0.5f)))));
        if ((k = refl__add(s, refl_mesh_plane(6.0f, 1, a, &m), &m, &mirror, t, "wall mirror")) < 0)
            return (refl_result)k;
    }
    if ((k = refl__add(s, refl_mesh_teapot(tess, a, &m), &m, &orange,
                       refl_mat4_scale(refl_v3(0.4f, 0.4f, 0.4f)), "teapot")) < 0)
        return (refl_result)k;
    if ((k = refl__add(s, refl_mesh_sphere(0.4f, 24, 12, a, &m), &m, &teal, refl__at(1.2f, 0.4f, 0.8f), "sphere")) < 0)
        return (refl_result)k;
    return REFL_OK;
}

/* The back half (z < 0) of a sphere seen from inside: normals inward and
   winding flipped, a concave bowl opening towards +z. */
static refl_result refl__bowl(float radius, const refl_allocator *a, refl_mesh **out) {
    refl_mesh *sphere = NULL;
    refl_mesh_desc d;
    uint32_t *idx;
    float *nrm;
    int t, n = 0, v;
    refl_result r = refl_mesh_sphere(radius, 64, 32, a, &sphere);
    if (r != REFL_OK) return r;
    idx = (uint32_t *)refl__alloc(a, (size_t)sphere->triangle_count * 3 * sizeof(uint32_t));
    nrm = (float *)refl__alloc(a, (size_t)sphere->vertex_count * 3 * sizeof(float));
    if (!idx || !nrm) {
        refl__free(a, idx);
        refl__free(a, nrm);
        refl_mesh_destroy(sphere);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (t = 0; t < sphere->triangle_count; ++t) {
        const uint32_t *tri = sphere->indices + 3 * t;
        float z = sphere->positions[3 * tri[0] + 2] + sphere->positions[3 * tri[1] + 2] +
                  sphere->positions[3 * tri[2] + 2];
        if (z >= 0.0f) continue;
        idx[3 * n] = tri[0];
        idx[3 * n + 1] = tri[2];
        idx[3 * n + 2] = tri[1];
        ++n;
    }
    for (v = 0; v < 3 * sphere->vertex_count; ++v) nrm[v] = -sphere->normals[v];
    memset(&d, 0, sizeof d);
    d.positions = sphere->positions;
    d.normals = nrm;
    d.texcoords = sphere->texcoords;
    d.indices = idx;
    d.vertex_count = sphere->vertex_count;
    d.index_count = 3 * n;
    d.allocator = refl__allocator(a);
    r = refl_mesh_create(&d, out);
    refl__free(a, idx);
    refl__free(a, nrm);
    refl_mesh_destroy(sphere);
    return r;
}

/* concave: the inside of a hemispherical mirror with an object near its
   focus (half the radius from the mirror), where reflections converge. */
static refl_result refl__scene_concave(refl_scene *s, const refl_allocator *a, int tess) {
    refl_material mirror = refl__material(REFL_MIRROR, 0.9f, 0.9f, 0.9f, "concave mirror");
    refl_material yellow = refl__material(REFL_DIFFUSE, 0.9f, 0.8f, 0.2f, "yellow");
    refl_mesh *m = NULL;
    refl_result r;
    int k;
    (void)tess;
    if ((r = refl__stage(s, a, 20.0f, refl_v3(0.0f, 3.5f, 6.0f), refl_v3(0.0f, 3.0f, -1.5f))) != REFL_OK) return r;
    mirror.reflectance = 0.9f;
    if ((k = refl__add(s, refl__bowl(3.0f, a, &m), &m, &mirror, refl__at(0.0f, 3.0f, 0.0f), "concave mirror")) < 0)
        return (refl_result)k;
    if ((k = refl__add(s, refl_mesh_sphere(0.3f, 24, 12, a, &m), &m, &yellow, refl__at(0.0f, 3.0f, -1.5f),
                       "ball at focus")) < 0)
        return (refl_result)k;
    return REFL_OK;
}

/* glass: a glass teapot and a glass slab over a checker of diffuse boxes.
   The slab stands a hair above the floor: a face in the floor's plane
   would make every tracer's answer there depend on traversal order. */
static refl_result refl__scene_glass(refl_scene *s, const refl_allocator *a, int tess) {
    refl_material glass = refl__material(REFL_GLASS, 0.95f, 0.97f, 1.0f, "glass");
    refl_material slab = refl__material(REFL_GLASS, 0.9f, 1.0f, 0.95f, "glass slab");
    refl_material dark = refl__material(REFL_DIFFUSE, 0.1f, 0.1f, 0.12f, "dark");
    refl_material light = refl__material(REFL_DIFFUSE, 0.85f, 0.85f, 0.8f, "light");
    refl_mesh *m = NULL;
    refl_result r;
    int k, i, j;
    if ((r = refl__stage(s, a, 20.0f, refl_v3(0.0f, 4.0f, 8.5f), refl_v3(0.0f, 1.2f, 0.0f))) != REFL_OK) return r;
    glass.ior = 1.5f;
    glass.fresnel = 1;
    slab.ior = 1.5f;
    slab.fresnel = 1;
    slab.attenuation = 0.2f;
    if ((k = refl__add(s, refl_mesh_teapot(tess, a, &m), &m, &glass, refl__at(-1.2f, 0.0f, 0.0f), "glass teapot")) < 0)
        return (refl_result)k;
    if ((k = refl__add(s, refl_mesh_box(refl_v3(2.0f, 1.5f, 0.3f), a, &m), &m, &slab, refl__at(2.2f, 0.76f, 1.0f),
                       "glass slab")) < 0)
        return (refl_result)k;
    for (j = 0; j < 4; ++j) /* tiles behind the glass, so refraction shows */
        for (i = 0; i < 8; ++i)
            if ((k = refl__add(s, refl_mesh_box(refl_v3(1.0f, 0.05f, 1.0f), a, &m), &m, (i + j) & 1 ? &dark : &light,
                               refl__at(-3.5f + (float)i, 0.025f, -1.5f - (float)j), "tile")) < 0)
                return (refl_result)k;
    return REFL_OK;
}

/* A 256 x 256 checker of cells x cells tiles (light and dark grey) as the
   texture of object 0's material (the stage's floor), its colour white. */
static refl_result refl__checker_floor(refl_scene *s, const refl_allocator *a, int cells) {
    float *checker = (float *)refl__calloc(a, 256 * 256, 4 * sizeof(float));
    int x, y, tex, side = 256 / cells;
    refl_material *floor_m = &s->materials[s->objects[0].material];
    if (!checker) return REFL_ERROR_OUT_OF_MEMORY;
    for (y = 0; y < 256; ++y)
        for (x = 0; x < 256; ++x) {
            float v = ((x / side) + (y / side)) & 1 ? 0.95f : 0.15f;
            float *px = checker + 4 * (256 * y + x);
            px[0] = px[1] = px[2] = v;
            px[3] = 1.0f;
        }
    tex = refl_scene_add_texture(s, 256, 256, checker);
    refl__free(a, checker);
    if (tex < 0) return (refl_result)tex;
    floor_m->texture = tex;
    floor_m->color[0] = floor_m->color[1] = floor_m->color[2] = 1.0f;
    return REFL_OK;
}

/* A cup without a handle standing on y = 0 around the y axis: outer and
   inner walls (wall thick), the rim, the inside floor and the bottom, each
   part its own vertices with its own normals so the edges stay sharp. */
static refl_result refl__mesh_cup(float radius, float height, float wall, int slices, const refl_allocator *a,
                                  refl_mesh **out) {
    int nv = 8 * (slices + 1) + 2, ni = 3 * 8 * slices, v = 0, t = 0, i, part;
    float *pos = (float *)refl__calloc(a, (size_t)nv * 6, sizeof(float)), *nrm = pos ? pos + 3 * nv : NULL;
    uint32_t *idx = (uint32_t *)refl__calloc(a, (size_t)ni, sizeof(uint32_t));
    const float ri = radius - wall;
    refl_mesh_desc d;
    refl_result r;
    if (!pos || !idx) {
        refl__free(a, pos);
        refl__free(a, idx);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
#define REFL__CUP_VERTEX(px, py, pz, nx, ny, nz)                                                                      \
    (pos[3 * v] = (px), pos[3 * v + 1] = (py), pos[3 * v + 2] = (pz), nrm[3 * v] = (nx), nrm[3 * v + 1] = (ny),        \
     nrm[3 * v + 2] = (nz), v++)
#define REFL__CUP_TRI(i0, i1, i2) (idx[t] = (uint32_t)(i0), idx[t + 1] = (uint32_t)(i1), idx[t + 2] = (uint32_t)(i2), t += 3)
    /* the walls and the rim: two rings each, (lower or inner, upper or outer) per angle */
    for (part = 0; part < 3; ++part) {
        int base = v;
        for (i = 0; i <= slices; ++i) {
            float an = 2.0f * (float)REFL__PI * (float)i / (float)slices, c = cosf(an), sn = sinf(an);
            if (part == 0) { /* outer wall, bottom then top */
                REFL__CUP_VERTEX(radius * c, 0.0f, radius * sn, c, 0.0f, sn);
                REFL__CUP_VERTEX(radius * c, height, radius * sn, c, 0.0f, sn);
            } else if (part == 1) { /* inner wall, its floor then top */
                REFL__CUP_VERTEX(ri * c, wall, ri * sn, -c, 0.0f, -sn);
                REFL__CUP_VERTEX(ri * c, height, ri * sn, -c, 0.0f, -sn);
            } else { /* rim, inner then outer */
                REFL__CUP_VERTEX(ri * c, height, ri * sn, 0.0f, 1.0f, 0.0f);
                REFL__CUP_VERTEX(radius * c, height, radius * sn, 0.0f, 1.0f, 0.0f);
            }
        }
        for (i = 0; i < slices; ++i) {
            int b0 = base + 2 * i, t0 = b0 + 1, b1 = b0 + 2, t1 = b0 + 3;
            if (part == 0) REFL__CUP_TRI(b0, t0, t1), REFL__CUP_TRI(b0, t1, b1);
            else if (part == 1) REFL__CUP_TRI(b0, t1, t0), REFL__CUP_TRI(b0, b1, t1);
            else REFL__CUP_TRI(t0, b0, b1), REFL__CUP_TRI(t0, b1, t1);
        }
    }
    /* the inside floor (up) and the bottom (down): a centre and a ring each */
    for (part = 0; part < 2; ++part) {
        float y = part ? 0.0f : wall, rr = part ? radius : ri, ny = part ? -1.0f : 1.0f;
        int centre = v;
        REFL__CUP_VERTEX(0.0f, y, 0.0f, 0.0f, ny, 0.0f);
        for (i = 0; i <= slices; ++i) {
            float an = 2.0f * (float)REFL__PI * (float)i / (float)slices;
            REFL__CUP_VERTEX(rr * cosf(an), y, rr * sinf(an), 0.0f, ny, 0.0f);
        }
        for (i = 0; i < slices; ++i) {
            if (part) REFL__CUP_TRI(centre, centre + 1 + i, centre + 2 + i);
            else REFL__CUP_TRI(centre, centre + 2 + i, centre + 1 + i);
        }
    }
#undef REFL__CUP_VERTEX
#undef REFL__CUP_TRI
    memset(&d, 0, sizeof d);
    d.positions = pos;
    d.normals = nrm;
    d.indices = idx;
    d.vertex_count = v;
    d.index_count = t;
    if (a) d.allocator = *a;
    r = refl_mesh_create(&d, out);
    refl__free(a, pos);
    refl__free(a, idx);
    return r;
}

/* hybrid: paper 001's scene (section 6): a glass teapot and a mirror cup
   inside a ring of ten columns, walls far around them, on a checker floor.
   The teapot and the cup float 0.005 above the floor: bottoms in its plane
   would make rays seen through the glass choose between coincident
   triangles, which two ray casters may break differently. */
static refl_result refl__scene_hybrid(refl_scene *s, const refl_allocator *a, int tess) {
    static const float column_rgb[2][3] = {{0.85f, 0.75f, 0.55f}, {0.45f, 0.55f, 0.8f}};
    static const float wall_rgb[4][3] = {{0.8f, 0.35f, 0.3f}, {0.35f, 0.7f, 0.4f}, {0.85f, 0.8f, 0.45f},
                                         {0.55f, 0.45f, 0.75f}};
    refl_material glass = refl__material(REFL_GLASS, 0.95f, 0.97f, 1.0f, "glass teapot");
    refl_material mirror = refl__material(REFL_MIRROR, 0.9f, 0.9f, 0.9f, "mirror cup");
    refl_mesh *m = NULL;
    refl_result r;
    int k, i;
    if ((r = refl__stage(s, a, 34.0f, refl_v3(0.9f, 1.9f, 4.8f), refl_v3(0.4f, 0.45f, 0.0f))) != REFL_OK) return r;
    if ((r = refl__checker_floor(s, a, 16)) != REFL_OK) return r;
    glass.ior = 1.5f;
    glass.fresnel = 1;
    mirror.reflectance = 0.9f;
    if ((k = refl__add(s, refl_mesh_teapot(tess, a, &m), &m, &glass,
                       refl_mat4_mul(refl__at(-0.2f, 0.005f, 0.0f), refl_mat4_scale(refl_v3(0.5f, 0.5f, 0.5f))),
                       "glass teapot")) < 0)
        return (refl_result)k;
    if ((k = refl__add(s, refl__mesh_cup(0.3f, 0.55f, 0.03f, 48, a, &m), &m, &mirror, refl__at(1.2f, 0.005f, 0.7f),
                       "mirror cup")) < 0)
        return (refl_result)k;
    for (i = 0; i < 10; ++i) {
        float an = 2.0f * (float)REFL__PI * ((float)i + 0.5f) / 10.0f;
        refl_material col = refl__material(REFL_DIFFUSE, column_rgb[i & 1][0], column_rgb[i & 1][1],
                                           column_rgb[i & 1][2], "column");
        if ((k = refl__add(s, refl_mesh_box(refl_v3(0.35f, 2.8f, 0.35f), a, &m), &m, &col,
                           refl__at(6.0f * sinf(an), 1.4f, 6.0f * cosf(an)), "column")) < 0)
            return (refl_result)k;
    }
    for (i = 0; i < 4; ++i) {
        float an = 0.5f * (float)REFL__PI * (float)i;
        refl_material wall = refl__material(REFL_DIFFUSE, wall_rgb[i][0], wall_rgb[i][1], wall_rgb[i][2], "wall");
        if ((k = refl__add(s, refl_mesh_box(refl_v3(30.0f, 5.0f, 0.3f), a, &m), &m, &wall,
                           refl_mat4_mul(refl_mat4_rotate(refl_v3(0, 1, 0), an), refl__at(0.0f, 2.5f, -15.0f)),
                           "wall")) < 0)
            return (refl_result)k;
    }
    return REFL_OK;
}

/* teapots: paper 004's two-teapot scene (Fig. 1): a mirror teapot and a
   diffuse teapot beside it, turned, both at half size, on a checker floor
   (a 256 x 256 texture of 16 x 16 tiles over the floor). */
static refl_result refl__scene_teapots(refl_scene *s, const refl_allocator *a, int tess) {
    refl_material mirror = refl__material(REFL_MIRROR, 0.9f, 0.9f, 0.9f, "mirror teapot");
    refl_material orange = refl__material(REFL_DIFFUSE, 0.9f, 0.45f, 0.12f, "diffuse teapot");
    refl_mat4 half = refl_mat4_scale(refl_v3(0.5f, 0.5f, 0.5f));
    refl_mesh *m = NULL;
    refl_result r;
    int k;
    if ((r = refl__stage(s, a, 12.0f, refl_v3(-0.6f, 2.8f, 6.0f), refl_v3(-0.3f, 0.5f, 0.2f))) != REFL_OK) return r;
    if ((r = refl__checker_floor(s, a, 16)) != REFL_OK) return r;
    mirror.reflectance = 0.9f;
    if ((k = refl__add(s, refl_mesh_teapot(tess, a, &m), &m, &mirror, refl_mat4_mul(refl__at(-1.2f, 0.0f, -0.2f), half), "mirror teapot")) < 0)
        return (refl_result)k;
    if ((k = refl__add(s, refl_mesh_teapot(tess, a, &m), &m, &orange,
                       refl_mat4_mul(refl__at(1.1f, 0.0f, 1.5f),
                                     refl_mat4_mul(refl_mat4_rotate(refl_v3(0, 1, 0), 2.2f), half)),
                       "diffuse teapot")) < 0)
        return (refl_result)k;
    return REFL_OK;
}

/* maze: paper 004's maze (docs/graphcam.md): the corridors of
   refl__maze_layout walled with boxes 0.15 thick and REFL__MAZE_WALL_H
   high, no ceiling, on a checker floor; a teapot, a sphere, a torus and a
   box in the corridors; a mirror sphere near the entrance, where the
   view looks. refl_graphcam_maze is its graph camera. */
static refl_result refl__scene_maze(refl_scene *s, const refl_allocator *a, int tess) {
    static const float wall_rgb[4][3] = {{0.85f, 0.8f, 0.7f}, {0.6f, 0.7f, 0.85f}, {0.6f, 0.82f, 0.6f}, {0.85f, 0.65f, 0.7f}};
    refl_material mirror = refl__material(REFL_MIRROR, 0.9f, 0.9f, 0.9f, "mirror");
    refl_material red = refl__material(REFL_DIFFUSE, 0.8f, 0.15f, 0.1f, "red");
    refl_material green = refl__material(REFL_DIFFUSE, 0.15f, 0.7f, 0.2f, "green");
    refl_material blue = refl__material(REFL_DIFFUSE, 0.15f, 0.25f, 0.8f, "blue");
    refl_material orange = refl__material(REFL_DIFFUSE, 0.9f, 0.5f, 0.1f, "orange");
    refl__maze_corridor c[REFL__MAZE_CORRIDORS];
    refl_mesh *m = NULL;
    refl_result r;
    float *checker;
    int k, i, tex, n = 340;
    const float thick = 0.15f, h = REFL__MAZE_WALL_H;
    if ((r = refl__stage(s, a, 40.0f, refl_v3(0.7f, 1.3f, 2.2f), refl_v3(0.2f, 0.6f, -1.6f))) != REFL_OK) return r;
    /* the floor: a 1 x 1 checker (the plane spans 40, its texture 40 x 40 cells of 8 texels) */
    n = 320;
    checker = (float *)refl__alloc(a, (size_t)n * (size_t)n * 4 * sizeof(float));
    if (!checker) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < n * n; ++i) {
        float v = ((i % n) / 8 + (i / n) / 8) & 1 ? 0.75f : 0.25f;
        checker[4 * i] = checker[4 * i + 1] = checker[4 * i + 2] = v;
        checker[4 * i + 3] = 1.0f;
    }
    tex = refl_scene_add_texture(s, n, n, checker);
    refl__free(a, checker);
    if (tex < 0) return (refl_result)tex;
    s->materials[s->objects[0].material].texture = tex;
    s->materials[s->objects[0].material].color[0] = s->materials[s->objects[0].material].color[1] =
        s->materials[s->objects[0].material].color[2] = 1.0f;
    refl__maze_layout(c);
    for (i = 0; i < REFL__MAZE_CORRIDORS; ++i) {
        const refl__maze_corridor *k0 = &c[i];
        refl_material wall = refl__material(REFL_DIFFUSE, wall_rgb[k0->level][0], wall_rgb[k0->level][1],
                                            wall_rgb[k0->level][2], "wall");
        float along = i < 7 ? k0->length - 2.0f : k0->length; /* the side walls stop at a junction */
        float lx = -k0->d[1], lz = k0->d[0];
        int side;
        for (side = -1; side <= 1; ++side) {
            /* side = 0: the end wall across the corridor's far end */
            float len = side ? along + thick : 2.0f + thick;
            float t = side ? 0.5f * along : k0->length;
            float x = k0->s[0] + k0->d[0] * t + (float)side * lx, z = k0->s[1] + k0->d[1] * t + (float)side * lz;
            int across = side == 0;
            float sx = (k0->d[0] != 0.0f) != across ? len : thick, sz = (k0->d[0] != 0.0f) != across ? thick : len;
            if ((k = refl__add(s, refl_mesh_box(refl_v3(sx, h, sz), a, &m), &m, &wall, refl__at(x, 0.5f * h, z), "wall")) < 0)
                return (refl_result)k;
        }
    }
    mirror.reflectance = 0.9f;
    if ((k = refl__add(s, refl_mesh_sphere(0.5f, 48, 24, a, &m), &m, &mirror, refl__at(0.3f, 0.5f, -1.6f),
                       "mirror sphere")) < 0)
        return (refl_result)k;
    if ((k = refl__add(s, refl_mesh_teapot(tess, a, &m), &m, &orange,
                       refl_mat4_mul(refl__at(-0.45f, 0.0f, -4.0f),
                                     refl_mat4_mul(refl_mat4_rotate(refl_v3(0, 1, 0), 2.2f), refl_mat4_scale(refl_v3(0.3f, 0.3f, 0.3f)))),
                       "teapot")) < 0)
        return (refl_result)k;
    if ((k = refl__add(s, refl_mesh_sphere(0.45f, 32, 16, a, &m), &m, &green, refl__at(4.0f, 0.45f, -9.0f),
                       "sphere")) < 0)
        return (refl_result)k;
    if ((k = refl__add(s, refl_mesh_torus(0.45f, 0.18f, 32, 16, a, &m), &m, &red,
                       refl_mat4_mul(refl__at(-4.5f, 0.6f, -9.0f), refl_mat4_rotate(refl_v3(0, 1, 0), 1.2f)), "torus")) < 0)
        return (refl_result)k;
    if ((k = refl__add(s, refl_mesh_box(refl_v3(0.7f, 0.7f, 0.7f), a, &m), &m, &blue,
                       refl_mat4_mul(refl__at(8.0f, 0.35f, -5.0f), refl_mat4_rotate(refl_v3(0, 1, 0), 0.5f)), "box")) < 0)
        return (refl_result)k;
    return REFL_OK;
}

REFL_API refl_result refl_scene_builtin(const char *name, const refl_builtin_desc *desc, refl_scene **out_scene) {
    refl_builtin_desc d;
    refl_scene *s;
    refl_result r;
    if (!out_scene) return REFL_ERROR_INVALID_ARGUMENT;
    *out_scene = NULL;
    if (!name) return REFL_ERROR_INVALID_ARGUMENT;
    if (desc) d = *desc;
    else memset(&d, 0, sizeof d);
    if (strcmp(name, "default") && strcmp(name, "mirror-room") && strcmp(name, "concave") && strcmp(name, "glass") &&
        strcmp(name, "maze") && strcmp(name, "teapots") && strcmp(name, "hybrid"))
        return REFL_ERROR_UNKNOWN_NAME;
    if ((r = refl_scene_create(&d.allocator, &s)) != REFL_OK) return r;
    if (!strcmp(name, "default")) r = refl__scene_default(s, &d.allocator, d.teapot_tess);
    else if (!strcmp(name, "mirror-room")) r = refl__scene_mirror_room(s, &d.allocator, d.teapot_tess);
    else if (!strcmp(name, "concave")) r = refl__scene_concave(s, &d.allocator, d.teapot_tess);
    else if (!strcmp(name, "maze")) r = refl__scene_maze(s, &d.allocator, d.teapot_tess);
    else if (!strcmp(name, "teapots")) r = refl__scene_teapots(s, &d.allocator, d.teapot_tess);
    else if (!strcmp(name, "hybrid")) r = refl__scene_hybrid(s, &d.allocator, d.teapot_tess);
    else r = refl__scene_glass(s, &d.allocator, d.teapot_tess);
    if (r != REFL_OK) {
        refl_scene_destroy(s);
        return r;
    }
    *out_scene = s;
    return REFL_OK;
}
