/* embree_peer.c - Embree 3 behind refl_bvh's interface (embree_peer.h). */
#define _POSIX_C_SOURCE 200809L
#include "embree_peer.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct refl_embree {
    RTCDevice device;
    RTCScene scene;
    int object_count;
    int **prim_triangle;     /* per object: primID -> triangle in its mesh; NULL: no geometry */
    char error[256];         /* the device's first error, "" while none */
};

/* Embree reports errors through a callback; keep the first, since later
   ones are usually its consequences. */
static void refl_embree__on_error(void *user, enum RTCError code, const char *message) {
    refl_embree *e = (refl_embree *)user;
    if (e->error[0]) return;
    snprintf(e->error, sizeof e->error, "embree error %d: %s", (int)code, message ? message : "(no message)");
}

static void refl_embree__set_error(char *err, size_t err_size, const char *message) {
    if (err && err_size > 0) snprintf(err, err_size, "%s", message);
}

/* refl_bvh's rule, so both trace the same triangles: finite, and a
   nonzero cross product in double. */
static int refl_embree__triangle_ok(const float *a, const float *b, const float *c) {
    double e1[3], e2[3], n[3];
    int k;
    for (k = 0; k < 3; ++k)
        if (!isfinite(a[k]) || !isfinite(b[k]) || !isfinite(c[k])) return 0;
    for (k = 0; k < 3; ++k) {
        e1[k] = (double)b[k] - a[k];
        e2[k] = (double)c[k] - a[k];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    return n[0] != 0 || n[1] != 0 || n[2] != 0;
}

void refl_embree_destroy(refl_embree *e) {
    int i;
    if (!e) return;
    if (e->scene) rtcReleaseScene(e->scene);
    if (e->device) rtcReleaseDevice(e->device);
    if (e->prim_triangle)
        for (i = 0; i < e->object_count; ++i) free(e->prim_triangle[i]);
    free(e->prim_triangle);
    free(e);
}

/* One object as one triangle geometry with geomID = object; a failure
   leaves its message in e->error. */
static void refl_embree__add_object(refl_embree *e, const refl_scene *scene, int object) {
    const refl_object *o = &scene->objects[object];
    const refl_mesh *mesh = scene->meshes[o->mesh];
    float *world, *vb;
    unsigned *ib;
    int *map;
    int v, t, n = 0;
    RTCGeometry g;

    if (mesh->triangle_count == 0) return;
    if (mesh->vertex_count <= 0) {
        snprintf(e->error, sizeof e->error, "object %d: triangles without vertices", object);
        return;
    }
    /* Each vertex once, so triangles sharing it share its exact floats
       (watertightness depends on it, as in refl_bvh). */
    world = (float *)malloc(sizeof(float) * 3 * (size_t)mesh->vertex_count);
    map = (int *)malloc(sizeof(int) * (size_t)mesh->triangle_count);
    if (!world || !map) {
        free(world);
        free(map);
        snprintf(e->error, sizeof e->error, "object %d: out of memory", object);
        return;
    }
    for (v = 0; v < mesh->vertex_count; ++v) {
        const float *p = mesh->positions + 3 * (size_t)v;
        refl_vec3 w = refl_mat4_point(o->transform, refl_v3(p[0], p[1], p[2]));
        world[3 * v] = w.x;
        world[3 * v + 1] = w.y;
        world[3 * v + 2] = w.z;
    }
    for (t = 0; t < mesh->triangle_count; ++t) {
        const uint32_t *tri = mesh->indices + 3 * (size_t)t;
        if (tri[0] >= (uint32_t)mesh->vertex_count || tri[1] >= (uint32_t)mesh->vertex_count ||
            tri[2] >= (uint32_t)mesh->vertex_count) {
            free(world);
            free(map);
            snprintf(e->error, sizeof e->error, "object %d: triangle %d indexes past its %d vertices", object, t,
                     mesh->vertex_count);
            return;
        }
        if (refl_embree__triangle_ok(world + 3 * tri[0], world + 3 * tri[1], world + 3 * tri[2])) map[n++] = t;
    }
    if (n == 0) { /* nothing hittable: no geometry, its ID stays free */
        free(world);
        free(map);
        return;
    }
    e->prim_triangle[object] = map;

    g = rtcNewGeometry(e->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!g) {
        free(world);
        if (!e->error[0]) snprintf(e->error, sizeof e->error, "object %d: rtcNewGeometry failed", object);
        return;
    }
    rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
    /* Embree's own buffers carry the padding its vector loads need. */
    vb = (float *)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                          (size_t)mesh->vertex_count);
    ib = (unsigned *)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                             (size_t)n);
    if (!vb || !ib) {
        free(world);
        rtcReleaseGeometry(g);
        if (!e->error[0]) snprintf(e->error, sizeof e->error, "object %d: no memory for Embree's buffers", object);
        return;
    }
    memcpy(vb, world, sizeof(float) * 3 * (size_t)mesh->vertex_count);
    free(world);
    for (t = 0; t < n; ++t) {
        const uint32_t *tri = mesh->indices + 3 * (size_t)map[t];
        ib[3 * t] = tri[0];
        ib[3 * t + 1] = tri[1];
        ib[3 * t + 2] = tri[2];
    }
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(e->scene, g, (unsigned)object);
    rtcReleaseGeometry(g); /* the scene holds it now */
}

refl_embree *refl_embree_create(const refl_scene *scene, int threads, char *err, size_t err_size) {
    refl_embree *e;
    char config[64];
    int i;

    refl_embree__set_error(err, err_size, "");
    if (!scene || scene->object_count < 0 || (scene->object_count > 0 && !scene->objects)) {
        refl_embree__set_error(err, err_size, "refl_embree_create: no scene");
        return NULL;
    }
    for (i = 0; i < scene->object_count; ++i) {
        int m = scene->objects[i].mesh;
        const refl_mesh *mesh;
        if (m < 0 || m >= scene->mesh_count || !scene->meshes || !scene->meshes[m]) {
            refl_embree__set_error(err, err_size, "refl_embree_create: an object names a missing mesh");
            return NULL;
        }
        mesh = scene->meshes[m];
        if (mesh->triangle_count < 0 || (mesh->triangle_count > 0 && (!mesh->positions || !mesh->indices))) {
            refl_embree__set_error(err, err_size, "refl_embree_create: a mesh without positions or indices");
            return NULL;
        }
    }

    e = (refl_embree *)calloc(1, sizeof *e);
    if (!e) {
        refl_embree__set_error(err, err_size, "refl_embree_create: out of memory");
        return NULL;
    }
    e->object_count = scene->object_count;
    e->prim_triangle = (int **)calloc((size_t)(scene->object_count > 0 ? scene->object_count : 1), sizeof(int *));
    if (threads > 0)
        snprintf(config, sizeof config, "threads=%d", threads);
    else
        config[0] = 0;
    if (!e->prim_triangle) {
        refl_embree__set_error(err, err_size, "refl_embree_create: out of memory");
        refl_embree_destroy(e);
        return NULL;
    }
    e->device = rtcNewDevice(config);
    if (!e->device) {
        if (err && err_size > 0)
            snprintf(err, err_size, "refl_embree_create: rtcNewDevice failed (error %d)",
                     (int)rtcGetDeviceError(NULL));
        refl_embree_destroy(e);
        return NULL;
    }
    rtcSetDeviceErrorFunction(e->device, refl_embree__on_error, e);
    e->scene = rtcNewScene(e->device);
    if (e->scene) {
        /* Robust: no traversal shortcuts that lose hits at shared edges,
           the fair comparison with refl_bvh's watertight test. */
        rtcSetSceneFlags(e->scene, RTC_SCENE_FLAG_ROBUST);
        rtcSetSceneBuildQuality(e->scene, RTC_BUILD_QUALITY_HIGH);
        for (i = 0; i < scene->object_count && !e->error[0]; ++i)
            refl_embree__add_object(e, scene, i);
        if (!e->error[0]) rtcCommitScene(e->scene);
    }
    if (!e->scene || e->error[0]) {
        refl_embree__set_error(err, err_size, e->error[0] ? e->error : "refl_embree_create: rtcNewScene failed");
        refl_embree_destroy(e);
        return NULL;
    }
    return e;
}

/* ---- single rays ---------------------------------------------------------------- */

/* refl_bvh takes hits with tmin < t < tmax, Embree with tnear <= t <= tfar:
   one float step inwards at each end makes them the same. RAYTRACE
   relies on the open end: it skips the triangle a ray leaves by casting
   again from tmin = that hit's t. */
/* nextafterf(x, INFINITY), inline: libm's call is a fair share of a
   ray's time in the benchmark, which is Embree's time, not ours. */
static float refl_embree__next_up(float x) {
    uint32_t u;
    if (x != x || x == INFINITY) return x;
    if (x == 0.0f) return 1.40129846e-45f; /* the least subnormal */
    memcpy(&u, &x, sizeof u);
    u = x > 0.0f ? u + 1 : u - 1;
    memcpy(&x, &u, sizeof u);
    return x;
}

static void refl_embree__ray(struct RTCRay *r, refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    r->org_x = o.x; r->org_y = o.y; r->org_z = o.z;
    r->dir_x = d.x; r->dir_y = d.y; r->dir_z = d.z;
    r->tnear = refl_embree__next_up(tmin);
    r->tfar = -refl_embree__next_up(-tmax);
    r->time = 0;
    r->mask = 0xFFFFFFFFu;
    r->id = 0;
    r->flags = 0;
}

static void refl_embree__rayhit(struct RTCRayHit *rh, refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    refl_embree__ray(&rh->ray, o, d, tmin, tmax);
    rh->hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh->hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh->hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
}

/* refl_bvh's contract: nothing for empty intervals, non-finite input or a
   zero direction (Embree's result there is unspecified). */
static int refl_embree__ray_ok(refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    return tmin < tmax && isfinite(o.x) && isfinite(o.y) && isfinite(o.z) && isfinite(d.x) && isfinite(d.y) &&
           isfinite(d.z) && (d.x != 0 || d.y != 0 || d.z != 0);
}

static int refl_embree__hit(const refl_embree *e, const struct RTCRayHit *rh, refl_hit *hit) {
    if (rh->hit.geomID == RTC_INVALID_GEOMETRY_ID) {
        if (hit) hit->object = -1;
        return 0;
    }
    if (hit) {
        hit->t = rh->ray.tfar;
        hit->object = (int)rh->hit.geomID;
        hit->triangle = e->prim_triangle[rh->hit.geomID][rh->hit.primID];
        hit->u = rh->hit.u;
        hit->v = rh->hit.v;
    }
    return 1;
}

int refl_embree_intersect(void *peer, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax, refl_hit *hit) {
    const refl_embree *e = (const refl_embree *)peer;
    struct RTCIntersectContext ctx;
    struct RTCRayHit rh;
    if (!refl_embree__ray_ok(origin, dir, tmin, tmax)) return 0;
    refl_embree__rayhit(&rh, origin, dir, tmin, tmax);
    rtcInitIntersectContext(&ctx);
    rtcIntersect1(e->scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return 0;
    return refl_embree__hit(e, &rh, hit);
}

int refl_embree_occluded(void *peer, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax) {
    const refl_embree *e = (const refl_embree *)peer;
    struct RTCIntersectContext ctx;
    struct RTCRay r;
    if (!refl_embree__ray_ok(origin, dir, tmin, tmax)) return 0;
    refl_embree__ray(&r, origin, dir, tmin, tmax);
    rtcInitIntersectContext(&ctx);
    rtcOccluded1(e->scene, &ctx, &r);
    return r.tfar == -INFINITY; /* Embree's mark for "occluded" */
}

/* ---- batches ------------------------------------------------------------------------ */

typedef struct refl_embree__slice {
    void (*fn)(void *user, long long begin, long long end);
    void *user;
    long long begin, end;
} refl_embree__slice;

static void *refl_embree__run_slice(void *arg) {
    refl_embree__slice *s = (refl_embree__slice *)arg;
    s->fn(s->user, s->begin, s->end);
    return NULL;
}

void refl_embree_split(long long count, int threads, void (*fn)(void *user, long long begin, long long end),
                       void *user) {
    enum { MAX_THREADS = 256 };
    refl_embree__slice slices[MAX_THREADS];
    pthread_t ids[MAX_THREADS];
    int started[MAX_THREADS];
    int k;
    if (threads < 1) threads = 1;
    if (threads > MAX_THREADS) threads = MAX_THREADS;
    for (k = 0; k < threads; ++k) {
        slices[k].fn = fn;
        slices[k].user = user;
        slices[k].begin = count * k / threads;
        slices[k].end = count * (k + 1) / threads;
        started[k] = 0;
    }
    for (k = 1; k < threads; ++k)
        started[k] = pthread_create(&ids[k], NULL, refl_embree__run_slice, &slices[k]) == 0;
    refl_embree__run_slice(&slices[0]);
    for (k = 1; k < threads; ++k) {
        if (started[k])
            pthread_join(ids[k], NULL);
        else /* no thread to spare: this one does the slice */
            refl_embree__run_slice(&slices[k]);
    }
}

typedef struct refl_embree__batch {
    const refl_embree *e;
    refl_embree_api api;
    int coherent;
    const refl_vec3 *origins, *dirs;
    float tmin, tmax;
    refl_hit *hits;
} refl_embree__batch;

static void refl_embree__trace_slice(void *user, long long begin, long long end) {
    const refl_embree__batch *b = (const refl_embree__batch *)user;
    struct RTCIntersectContext ctx;
    long long i;
    rtcInitIntersectContext(&ctx);
    ctx.flags = b->coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    if (b->api == REFL_EMBREE_SINGLE) {
        for (i = begin; i < end; ++i) {
            struct RTCRayHit rh;
            refl_embree__rayhit(&rh, b->origins[i], b->dirs[i], b->tmin, b->tmax);
            rtcIntersect1(b->e->scene, &ctx, &rh);
            refl_embree__hit(b->e, &rh, &b->hits[i]);
        }
        return;
    }
    for (i = begin; i < end; i += REFL_EMBREE_CHUNK) {
        struct RTCRayHit rays[REFL_EMBREE_CHUNK];
        int k, n = (int)(end - i < REFL_EMBREE_CHUNK ? end - i : REFL_EMBREE_CHUNK);
        for (k = 0; k < n; ++k) refl_embree__rayhit(&rays[k], b->origins[i + k], b->dirs[i + k], b->tmin, b->tmax);
        rtcIntersect1M(b->e->scene, &ctx, rays, (unsigned)n, sizeof rays[0]);
        for (k = 0; k < n; ++k) refl_embree__hit(b->e, &rays[k], &b->hits[i + k]);
    }
}

void refl_embree_trace(const refl_embree *embree, refl_embree_api api, int coherent, const refl_vec3 *origins,
                       const refl_vec3 *dirs, long long count, float tmin, float tmax, int threads, refl_hit *hits) {
    refl_embree__batch b;
    b.e = embree;
    b.api = api;
    b.coherent = coherent;
    b.origins = origins;
    b.dirs = dirs;
    b.tmin = tmin;
    b.tmax = tmax;
    b.hits = hits;
    refl_embree_split(count, threads, refl_embree__trace_slice, &b);
}
