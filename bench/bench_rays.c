/* bench_rays - rays per second of refl_bvh against Embree 3 (single-ray
   and stream API), on a built-in scene ("default" unless --scene) or a
   glTF file (--asset) from its own camera (else refl_scene_complete's); the
   build times of both; and whole RAYTRACE frames with refl_bvh and with
   Embree as the ray caster.

   Usage: bench_rays [--csv FILE] [--runs N] [--size WxH] [--scene NAME | --asset FILE.glb]
                     [--frame WxH] [--frame-depth N] [--shadows] [--only primary|mirror|frames|build]
                     [--cpu-time] [--subdivide N] [--packets]

   Ray sets:
     primary   one ray through each pixel centre (1920x1080 unless --size):
               coherent
     mirror    the mirror ray of every primary hit on a reflector (material
               not diffuse: the default scene's teapot; in a scene without
               one, of every primary hit), about the interpolated normal,
               starting just off the surface: incoherent
   Tracers, closest hit for every ray, written to a hit array:
     refl_bvh       refl_bvh_intersect per ray
     embree_single  rtcIntersect1 per ray (robust scene, high build quality)
     embree_stream  rtcIntersect1M on chunks of REFL_EMBREE_CHUNK rays
   for 1 and 2 threads; every tracer splits the rays into the same
   contiguous slices, one pthread each (refl_embree_split). Each of N runs
   (default 5, after one warm-up) times the three in turn. Reported:
   million rays per second from each tracer's median time, and ours /
   Embree in speed (above 1: refl_bvh is faster) as the median of the
   per-run ratios, which a shared, noisy machine disturbs less.

   The hits are checked too: all three must find the same number, and rays
   where refl_bvh and Embree name different triangles are counted (only
   rays grazing an edge may differ; tests/tools/test_embree.c classifies them).
   Exit status 1 when the hit counts differ by more than 1 in 10^4.
   --only times one ray set (the other is still traced once, for its hits),
   or (frames) the frames alone, no ray sets nor builds, or (build) the
   builds alone;
   --cpu-time times the ray sets, the builds and the frames in process CPU
   time (Mrays/s then per CPU second of all threads together) instead of
   wall time;
   --subdivide N splits every triangle of the scene into four, N times
   (the 100k-triangle dragon with N 2: 1.6 million), for a larger mesh.
   --packets times, instead of all the above, refl_bvh's single rays
   against its packets of four (refl_bvh_intersect4, refl_bvh_occluded4;
   four consecutive rays of a set, which is in pixel order) on one
   thread, taking turns within each run: the mirror rays, and shadow rays
   from every primary hit to the scene's first point light (occlusion);
   the hits must be the same, bit for bit (exit status 1 otherwise).

   Builds: refl_bvh_build_threads and Embree's scene (high quality,
   robust), each with 1 thread and with all, taking turns, median of N
   each, and ours / Embree at the same thread count in time (above 1:
   ours is slower) as the median of the per-run ratios.

   Frames (--frame, default 640x480; 0x0: none): RAYTRACE (--frame-depth
   bounces, default 1; shadows with --shadows) four ways: refl_render
   with its own BVH built inside the frame; a refl_renderer's frame, its
   BVH kept from the frame before (what an application rendering frame
   after frame gets); a refl_bvh built beforehand as a caller's caster;
   and Embree's scene built beforehand as the caster, primary and
   secondary rays all through Embree (what a CPU user without this library
   would trace with). 1 and 2 threads, taking
   turns within each of N runs; medians, and Embree's time / ours as the
   median of per-run ratios (above 1: ours is faster). */
#define _POSIX_C_SOURCE 200809L
/* The implementations come from tests/reflect_impl.c and tests/rast_impl.c
   (linked in by the Makefile). */
#include "../reflect.h"
#include "../tools/gltf_load.h"
#include "embree_peer.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

enum { TRACER_OURS, TRACER_EMBREE_SINGLE, TRACER_EMBREE_STREAM, TRACER_COUNT };
static const char *tracer_names[TRACER_COUNT] = {"refl_bvh", "embree_single", "embree_stream"};

enum { SET_PRIMARY, SET_MIRROR, SET_COUNT };
static const char *set_names[SET_COUNT] = {"primary", "mirror"};

static const int thread_counts[] = {1, 2};
#define THREAD_ROWS ((int)(sizeof thread_counts / sizeof thread_counts[0]))

typedef struct ray_set {
    refl_vec3 *origins, *dirs;
    long long count;
} ray_set;

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* --cpu-time: the ray sets are timed in CPU seconds of the whole process
   (all its threads), which time spent waiting for a shared machine's
   cores does not inflate. */
static int use_cpu_time;

static double ray_clock_s(void) {
    struct timespec ts;
    if (!use_cpu_time) return now_s();
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void *xmalloc(size_t n) {
    void *p = malloc(n ? n : 1);
    if (!p) {
        fprintf(stderr, "bench_rays: out of memory (%zu bytes)\n", n);
        exit(2);
    }
    return p;
}

static int compare_doubles(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *t, int n) {
    qsort(t, (size_t)n, sizeof *t, compare_doubles);
    return n % 2 ? t[n / 2] : 0.5 * (t[n / 2 - 1] + t[n / 2]);
}

/* ---- refl_bvh in the same slices as Embree ------------------------------------- */

typedef struct bvh_batch {
    const refl_bvh *bvh;
    const ray_set *rays;
    refl_hit *hits;
} bvh_batch;

static void bvh_trace_slice(void *user, long long begin, long long end) {
    const bvh_batch *b = (const bvh_batch *)user;
    long long i;
    for (i = begin; i < end; ++i)
        if (!refl_bvh_intersect(b->bvh, b->rays->origins[i], b->rays->dirs[i], 0, INFINITY, &b->hits[i]))
            b->hits[i].object = -1;
}

static void trace(int tracer, const refl_bvh *bvh, const refl_embree *emb, int coherent, const ray_set *rays,
                  int threads, refl_hit *hits) {
    if (tracer == TRACER_OURS) {
        bvh_batch b;
        b.bvh = bvh;
        b.rays = rays;
        b.hits = hits;
        refl_embree_split(rays->count, threads, bvh_trace_slice, &b);
    } else {
        refl_embree_trace(emb, tracer == TRACER_EMBREE_SINGLE ? REFL_EMBREE_SINGLE : REFL_EMBREE_STREAM, coherent,
                          rays->origins, rays->dirs, rays->count, 0, INFINITY, threads, hits);
    }
}

/* ---- rays ---------------------------------------------------------------------- */

/* Through pixel centres, in the frustum the rasteriser uses. */
static ray_set primary_rays(const refl_scene *s, const refl_view *view) {
    ray_set r;
    refl_mat4 view_m, proj_m;
    refl_vec3 right, up, forward;
    int x, y;
    refl_view_matrices(view, s, &view_m, &proj_m);
    right = refl_v3(view_m.m[0], view_m.m[4], view_m.m[8]);
    up = refl_v3(view_m.m[1], view_m.m[5], view_m.m[9]);
    forward = refl_v3(-view_m.m[2], -view_m.m[6], -view_m.m[10]);
    r.count = (long long)view->width * view->height;
    r.origins = (refl_vec3 *)xmalloc(sizeof(refl_vec3) * (size_t)r.count);
    r.dirs = (refl_vec3 *)xmalloc(sizeof(refl_vec3) * (size_t)r.count);
    for (y = 0; y < view->height; ++y)
        for (x = 0; x < view->width; ++x) {
            long long i = (long long)y * view->width + x;
            float ndc_x = 2.0f * (x + 0.5f) / view->width - 1, ndc_y = 1 - 2.0f * (y + 0.5f) / view->height;
            r.origins[i] = view->eye;
            r.dirs[i] = refl_v3_add(forward, refl_v3_add(refl_v3_scale(right, ndc_x / proj_m.m[0]),
                                                         refl_v3_scale(up, ndc_y / proj_m.m[5])));
        }
    return r;
}

/* The mirror rays of the primary hits on reflectors: about the interpolated
   normal turned towards the viewer, from just off the surface. */
static ray_set mirror_rays(const refl_scene *s, const ray_set *primary, const refl_hit *hits) {
    ray_set r;
    refl_vec3 lo, hi;
    float offset;
    long long i;
    int any_reflector = 0;
    for (i = 0; i < primary->count && !any_reflector; ++i)
        any_reflector = hits[i].object >= 0 &&
                        s->materials[s->objects[hits[i].object].material].type != REFL_DIFFUSE;
    refl_scene_bounds(s, &lo, &hi);
    offset = 1e-5f * refl_v3_length(refl_v3_sub(hi, lo));
    r.count = 0;
    r.origins = (refl_vec3 *)xmalloc(sizeof(refl_vec3) * (size_t)primary->count);
    r.dirs = (refl_vec3 *)xmalloc(sizeof(refl_vec3) * (size_t)primary->count);
    for (i = 0; i < primary->count; ++i) {
        const refl_hit *h = &hits[i];
        const refl_object *o;
        const refl_mesh *m;
        const uint32_t *tri;
        refl_vec3 v[3], n, ng, d, p;
        refl_mat4 inverse;
        int k;
        if (h->object < 0) continue;
        o = &s->objects[h->object];
        if (any_reflector && s->materials[o->material].type == REFL_DIFFUSE) continue;
        m = s->meshes[o->mesh];
        tri = m->indices + 3 * (size_t)h->triangle;
        n = refl_v3(0, 0, 0);
        for (k = 0; k < 3; ++k) {
            const float *pk = m->positions + 3 * (size_t)tri[k], *nk = m->normals + 3 * (size_t)tri[k];
            float w = k == 0 ? 1 - h->u - h->v : k == 1 ? h->u : h->v;
            v[k] = refl_mat4_point(o->transform, refl_v3(pk[0], pk[1], pk[2]));
            n = refl_v3_add(n, refl_v3_scale(refl_v3(nk[0], nk[1], nk[2]), w));
        }
        if (!refl_mat4_invert(o->transform, &inverse)) continue;
        n = refl_v3_normalize(refl_mat4_dir(refl_mat4_transpose(inverse), n));
        ng = refl_v3_normalize(refl_v3_cross(refl_v3_sub(v[1], v[0]), refl_v3_sub(v[2], v[0])));
        d = refl_v3_normalize(primary->dirs[i]);
        if (refl_v3_length(n) == 0 || refl_v3_length(ng) == 0) continue;
        if (refl_v3_dot(n, d) > 0) n = refl_v3_scale(n, -1);
        if (refl_v3_dot(ng, d) > 0) ng = refl_v3_scale(ng, -1);
        p = refl_v3_add(primary->origins[i], refl_v3_scale(primary->dirs[i], h->t));
        r.origins[r.count] = refl_v3_add(p, refl_v3_scale(ng, offset));
        r.dirs[r.count] = refl_v3_reflect(d, n);
        ++r.count;
    }
    return r;
}

static long long count_hits(const refl_hit *hits, long long n) {
    long long i, k = 0;
    for (i = 0; i < n; ++i) k += hits[i].object >= 0;
    return k;
}

static long long count_different(const refl_hit *a, const refl_hit *b, long long n) {
    long long i, k = 0;
    for (i = 0; i < n; ++i)
        k += a[i].object != b[i].object || (a[i].object >= 0 && a[i].triangle != b[i].triangle);
    return k;
}

/* ---- packets of four rays against single rays ----------------------------------- */

/* From each primary hit towards the scene's first point light (the
   origin where it has none), occlusion up to it, from just off the
   surface. */
static ray_set shadow_rays(const refl_scene *s, const ray_set *primary, const refl_hit *hits, float **tmax_out) {
    ray_set r;
    refl_vec3 lo, hi, light = refl_v3(0, 0, 0);
    float offset, *tmax;
    long long i;
    int k;
    for (k = 0; k < s->light_count; ++k)
        if (s->lights[k].type == REFL_LIGHT_POINT) {
            light = s->lights[k].position;
            break;
        }
    refl_scene_bounds(s, &lo, &hi);
    offset = 1e-4f * refl_v3_length(refl_v3_sub(hi, lo));
    r.count = 0;
    r.origins = (refl_vec3 *)xmalloc(sizeof(refl_vec3) * (size_t)primary->count);
    r.dirs = (refl_vec3 *)xmalloc(sizeof(refl_vec3) * (size_t)primary->count);
    tmax = (float *)xmalloc(sizeof(float) * (size_t)primary->count);
    for (i = 0; i < primary->count; ++i) {
        refl_vec3 p, d;
        if (hits[i].object < 0) continue;
        p = refl_v3_add(primary->origins[i], refl_v3_scale(primary->dirs[i], hits[i].t));
        d = refl_v3_sub(light, p);
        p = refl_v3_add(p, refl_v3_scale(refl_v3_normalize(d), offset));
        r.origins[r.count] = p;
        r.dirs[r.count] = refl_v3_sub(light, p);
        tmax[r.count++] = 1.0f;
    }
    *tmax_out = tmax;
    return r;
}

/* One thread: single rays, then packets of four consecutive rays (the
   sets are in pixel order), closest hits (mirror) or occlusion (shadow),
   taking turns; the hits must be the same, bit for bit. */
static int packets_experiment(const refl_bvh *bvh, const ray_set *mirror, const ray_set *shadow,
                              const float *shadow_tmax, int runs) {
    const ray_set *sets[2] = {mirror, shadow};
    const char *names[2] = {"mirror", "shadow"};
    int set, run, status = 0;
    for (set = 0; set < 2; ++set) {
        const ray_set *rs = sets[set];
        long long n = rs->count - rs->count % 4, i, differ = 0;
        refl_hit *a = (refl_hit *)xmalloc(sizeof(refl_hit) * (size_t)(n + 1));
        refl_hit *b = (refl_hit *)xmalloc(sizeof(refl_hit) * (size_t)(n + 1));
        double *t = (double *)xmalloc(sizeof(double) * (size_t)runs * 3);
        int any = set == 1;
        memset(a, 0, sizeof(refl_hit) * (size_t)(n + 1));
        memset(b, 0, sizeof(refl_hit) * (size_t)(n + 1));
        for (run = -1; run < runs; ++run) {
            double t0 = ray_clock_s(), t1, t2;
            for (i = 0; i < n; ++i) {
                float tmax = any ? shadow_tmax[i] : INFINITY;
                int h = any ? refl_bvh_occluded(bvh, rs->origins[i], rs->dirs[i], 0, tmax)
                            : refl_bvh_intersect(bvh, rs->origins[i], rs->dirs[i], 0, tmax, &a[i]);
                if (!h) a[i].object = -1;
                else if (any) a[i].object = 1;
            }
            t1 = ray_clock_s();
            for (i = 0; i < n; i += 4) {
                float tmin[4] = {0, 0, 0, 0}, tmax[4];
                unsigned h;
                int k;
                for (k = 0; k < 4; ++k) tmax[k] = any ? shadow_tmax[i + k] : INFINITY;
                h = any ? refl_bvh_occluded4(bvh, rs->origins + i, rs->dirs + i, tmin, tmax)
                        : refl_bvh_intersect4(bvh, rs->origins + i, rs->dirs + i, tmin, tmax, &b[i]);
                for (k = 0; k < 4; ++k) {
                    if (!(h >> k & 1)) b[i + k].object = -1;
                    else if (any) b[i + k].object = 1;
                }
            }
            t2 = ray_clock_s();
            if (run < 0) continue;
            t[run] = t1 - t0;
            t[runs + run] = t2 - t1;
            t[2 * runs + run] = (t1 - t0) / (t2 - t1);
        }
        for (i = 0; i < n; ++i)
            differ += any ? a[i].object != b[i].object
                          : (a[i].object != b[i].object || (a[i].object >= 0 && memcmp(&a[i], &b[i], sizeof a[i])));
        printf("packets %-6s %9lld rays, 1 thread: single %.2f Mrays/s, packets of 4 %.2f Mrays/s, packets / single "
               "%.2f (median of per-run ratios); rays whose hit differs: %lld\n",
               names[set], n, n / median(t, runs) * 1e-6, n / median(t + runs, runs) * 1e-6,
               median(t + 2 * runs, runs), differ);
        if (differ) status = 1;
        free(a);
        free(b);
        free(t);
    }
    return status;
}

/* ---- a larger mesh: every triangle split into four ----------------------------- */

typedef struct edge_key {
    uint32_t a, b;                /* a < b: the edge's vertices */
    long long slot;               /* 3 * triangle + edge */
} edge_key;

static int compare_edges(const void *x, const void *y) {
    const edge_key *p = (const edge_key *)x, *q = (const edge_key *)y;
    if (p->a != q->a) return p->a < q->a ? -1 : 1;
    if (p->b != q->b) return p->b < q->b ? -1 : 1;
    return (p->slot > q->slot) - (p->slot < q->slot);
}

/* Each triangle into four at its edges' midpoints, a midpoint shared by
   the edge's two triangles (no cracks); positions and normals
   interpolated. Deterministic: --subdivide N gives the same mesh every time. */
static refl_mesh *split_in_four(const refl_mesh *m) {
    long long nt = m->triangle_count, e, i, nv = m->vertex_count;
    edge_key *edges = (edge_key *)xmalloc(sizeof(edge_key) * (size_t)(3 * nt));
    uint32_t *mid = (uint32_t *)xmalloc(sizeof(uint32_t) * (size_t)(3 * nt));
    uint32_t *idx = (uint32_t *)xmalloc(sizeof(uint32_t) * (size_t)(12 * nt));
    /* positions, normals, texcoords and colours: each vertex attribute, its
       midpoints after the mesh's vertices */
    const float *src[4];
    float *dst[4];
    const int dims[4] = {3, 3, 2, 4};
    int a;
    refl_mesh_desc d;
    refl_mesh *out = NULL;
    for (i = 0; i < nt; ++i)
        for (e = 0; e < 3; ++e) {
            uint32_t a = m->indices[3 * i + e], b = m->indices[3 * i + (e + 1) % 3];
            edges[3 * i + e].a = a < b ? a : b;
            edges[3 * i + e].b = a < b ? b : a;
            edges[3 * i + e].slot = 3 * i + e;
        }
    qsort(edges, (size_t)(3 * nt), sizeof *edges, compare_edges);
    src[0] = m->positions;
    src[1] = m->normals;
    src[2] = m->texcoords;
    src[3] = m->colors;
    for (a = 0; a < 4; ++a) {
        dst[a] = src[a] ? (float *)xmalloc(sizeof(float) * (size_t)dims[a] * (size_t)(nv + 3 * nt)) : NULL;
        if (src[a]) memcpy(dst[a], src[a], sizeof(float) * (size_t)dims[a] * (size_t)nv);
    }
    for (e = 0; e < 3 * nt; ++e) {
        int k;
        if (e == 0 || edges[e].a != edges[e - 1].a || edges[e].b != edges[e - 1].b) {
            for (a = 0; a < 4; ++a)
                for (k = 0; src[a] && k < dims[a]; ++k)
                    dst[a][dims[a] * nv + k] =
                        0.5f * (src[a][dims[a] * edges[e].a + k] + src[a][dims[a] * edges[e].b + k]);
            ++nv;
        }
        mid[edges[e].slot] = (uint32_t)(nv - 1);
    }
    for (i = 0; i < nt; ++i) {
        const uint32_t *v = m->indices + 3 * i, *c = mid + 3 * i; /* c[e]: midpoint of edge v[e] v[e + 1] */
        uint32_t *q = idx + 12 * i;
        q[0] = v[0]; q[1] = c[0]; q[2] = c[2];
        q[3] = c[0]; q[4] = v[1]; q[5] = c[1];
        q[6] = c[2]; q[7] = c[1]; q[8] = v[2];
        q[9] = c[0]; q[10] = c[1]; q[11] = c[2];
    }
    memset(&d, 0, sizeof d);
    d.positions = dst[0];
    d.normals = dst[1];
    d.texcoords = dst[2];
    d.colors = dst[3];
    d.indices = idx;
    d.vertex_count = (int)nv;
    d.index_count = (int)(12 * nt);
    if (refl_mesh_create(&d, &out) != REFL_OK) {
        fprintf(stderr, "bench_rays: --subdivide: refl_mesh_create failed\n");
        exit(2);
    }
    free(edges);
    free(mid);
    free(idx);
    for (a = 0; a < 4; ++a) free(dst[a]);
    return out;
}

/* --subdivide N: every mesh of the scene split N times (4^N triangles
   each). */
static void subdivide_scene(refl_scene *s, int times) {
    int i, k;
    for (i = 0; i < s->mesh_count; ++i)
        for (k = 0; k < times; ++k) {
            refl_mesh *m = split_in_four(s->meshes[i]);
            refl_mesh_destroy(s->meshes[i]);
            s->meshes[i] = m;
        }
    refl_scene_touch(s);
}

/* ---- builds and whole frames ---------------------------------------------------- */

/* Build times: wall, or process CPU time with --cpu-time (ray_clock_s). */
static double build_ours_ms(const refl_scene *s, int threads) {
    refl_bvh *b = NULL;
    double t0 = ray_clock_s(), ms;
    if (refl_bvh_build_threads(s, NULL, threads, &b) != REFL_OK) {
        fprintf(stderr, "bench_rays: refl_bvh_build_threads failed\n");
        exit(2);
    }
    ms = (ray_clock_s() - t0) * 1e3;
    refl_bvh_destroy(b);
    return ms;
}

static double build_embree_ms(const refl_scene *s, int threads) {
    char err[256];
    double t0 = ray_clock_s(), ms;
    refl_embree *e = refl_embree_create(s, threads, err, sizeof err);
    if (!e) {
        fprintf(stderr, "bench_rays: %s\n", err);
        exit(2);
    }
    ms = (ray_clock_s() - t0) * 1e3;
    refl_embree_destroy(e);
    return ms;
}

static int bvh_caster_intersect(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax, refl_hit *hit) {
    return refl_bvh_intersect((const refl_bvh *)user, o, d, tmin, tmax, hit);
}

static int bvh_caster_occluded(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    return refl_bvh_occluded((const refl_bvh *)user, o, d, tmin, tmax);
}

enum { FRAME_OURS_BUILT_IN, FRAME_OURS_KEPT, FRAME_OURS_PREBUILT, FRAME_EMBREE, FRAME_COUNT };
static const char *frame_names[FRAME_COUNT] = {"ours (BVH built in frame)", "ours (renderer, BVH kept)",
                                               "refl_bvh as caster", "Embree as caster"};
static int frame_depth = 1, frame_shadows;

/* The frames' RAYTRACE desc on `threads` threads. */
static refl_render_desc frame_desc(int threads) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = REFL_RAYTRACE;
    d.threads = threads;
    d.depth = frame_depth;
    d.lighting.shadows = frame_shadows;
    return d;
}

/* Milliseconds (wall, or CPU with --cpu-time) of one RAYTRACE frame
   through tracer `which`; FRAME_OURS_KEPT renders with rr. */
static double frame_ms(const refl_scene *s, const refl_view *v, int which, int threads, refl_bvh *bvh,
                       refl_embree *emb, refl_renderer *rr, refl_frame *f) {
    refl_render_desc d = frame_desc(threads);
    refl_result r;
    double t0;
    if (which == FRAME_OURS_PREBUILT) {
        d.raytrace.caster.intersect = bvh_caster_intersect;
        d.raytrace.caster.occluded = bvh_caster_occluded;
        d.raytrace.caster.user = bvh;
    } else if (which == FRAME_EMBREE) {
        d.raytrace.caster.intersect = refl_embree_intersect;
        d.raytrace.caster.occluded = refl_embree_occluded;
        d.raytrace.caster.user = emb;
    }
    t0 = ray_clock_s();
    r = which == FRAME_OURS_KEPT ? refl_renderer_render(rr, v, f) : refl_render(s, v, &d, f);
    if (r != REFL_OK) {
        fprintf(stderr, "bench_rays: RAYTRACE: %s\n", refl_result_string(r));
        exit(2);
    }
    return (ray_clock_s() - t0) * 1e3;
}

/* The renderer of FRAME_OURS_KEPT. */
static refl_renderer *frame_renderer(const refl_scene *s, int threads) {
    refl_render_desc d = frame_desc(threads);
    refl_renderer *rr = NULL;
    if (refl_renderer_create(s, &d, &rr) != REFL_OK) {
        fprintf(stderr, "bench_rays: refl_renderer_create failed\n");
        exit(2);
    }
    return rr;
}

static int parse_size(const char *s, int *w, int *h) {
    return sscanf(s, "%dx%d", w, h) == 2 && *w > 0 && *h > 0 && *w <= 16384 && *h <= 16384;
}

int main(int argc, char **argv) {
    const char *csv = NULL, *scene_name = "default", *asset = NULL, *only = NULL;
    int runs = 5, width = 1920, height = 1080, frame_w = 640, frame_h = 480, i, set, ti, tracer, status = 0;
    refl_scene *scene = NULL;
    refl_bvh *bvh = NULL;
    refl_embree *emb;
    refl_view view;
    refl_result res;
    ray_set rays[SET_COUNT];
    refl_hit *hits[TRACER_COUNT];
    double mrays[SET_COUNT][THREAD_ROWS][TRACER_COUNT], ratio[SET_COUNT][THREAD_ROWS][TRACER_COUNT];
    double t0, bvh_ms, embree_ms, *times, *ratios;
    long long nodes, tris;
    char err[256];
    int frames_only, build_only, subdivide = 0, packets = 0;

    for (i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--csv") && i + 1 < argc)
            csv = argv[++i];
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc && (runs = atoi(argv[++i])) > 0 && runs <= 1000)
            ;
        else if (!strcmp(argv[i], "--size") && i + 1 < argc && parse_size(argv[++i], &width, &height))
            ;
        else if (!strcmp(argv[i], "--scene") && i + 1 < argc)
            scene_name = argv[++i];
        else if (!strcmp(argv[i], "--asset") && i + 1 < argc)
            scene_name = asset = argv[++i];
        else if (!strcmp(argv[i], "--cpu-time"))
            use_cpu_time = 1;
        else if (!strcmp(argv[i], "--only") && i + 1 < argc &&
                 (!strcmp(argv[i + 1], set_names[SET_PRIMARY]) || !strcmp(argv[i + 1], set_names[SET_MIRROR]) ||
                  !strcmp(argv[i + 1], "frames") || !strcmp(argv[i + 1], "build")))
            only = argv[++i];
        else if (!strcmp(argv[i], "--subdivide") && i + 1 < argc && (subdivide = atoi(argv[++i])) >= 0 &&
                 subdivide <= 4)
            ;
        else if (!strcmp(argv[i], "--frame-depth") && i + 1 < argc && (frame_depth = atoi(argv[++i])) >= 0 &&
                 frame_depth <= 16)
            ;
        else if (!strcmp(argv[i], "--shadows"))
            frame_shadows = 1;
        else if (!strcmp(argv[i], "--packets"))
            packets = 1;
        else if (!strcmp(argv[i], "--frame") && i + 1 < argc &&
                 (!strcmp(argv[i + 1], "0x0") ? (frame_w = frame_h = 0, ++i, 1)
                                               : parse_size(argv[++i], &frame_w, &frame_h)))
            ;
        else {
            fprintf(stderr,
                    "usage: %s [--csv FILE] [--runs N] [--size WxH] [--scene NAME | --asset FILE.glb] [--frame WxH] "
                    "[--frame-depth N] [--shadows] [--only primary|mirror|frames|build] [--cpu-time] [--subdivide N] "
                    "[--packets]\n",
                    argv[0]);
            return 2;
        }
    }

    frames_only = only && !strcmp(only, "frames");
    build_only = only && !strcmp(only, "build");
    if (asset) {
        char gerr[1024];
        res = refl_gltf_load(asset, NULL, &scene, gerr, sizeof gerr);
        if (res != REFL_OK) {
            fprintf(stderr, "bench_rays: %s\n", gerr);
            return 2;
        }
        refl_scene_complete(scene); /* a camera framing it, where the file has none */
    } else {
        res = refl_scene_builtin(scene_name, NULL, &scene);
        if (res != REFL_OK) {
            fprintf(stderr, "bench_rays: refl_scene_builtin(\"%s\"): %s\n", scene_name, refl_result_string(res));
            return 2;
        }
    }
    if (subdivide > 0) subdivide_scene(scene, subdivide);
    view = scene->camera;
    view.width = width;
    view.height = height;

    t0 = now_s();
    res = refl_bvh_build(scene, NULL, &bvh);
    bvh_ms = (now_s() - t0) * 1e3;
    if (res != REFL_OK) {
        fprintf(stderr, "bench_rays: refl_bvh_build: %s\n", refl_result_string(res));
        return 2;
    }
    t0 = now_s();
    emb = refl_embree_create(scene, 0, err, sizeof err);
    embree_ms = (now_s() - t0) * 1e3;
    if (!emb) {
        fprintf(stderr, "bench_rays: %s\n", err);
        return 2;
    }
    refl_bvh_stats(bvh, &nodes, &tris);

    memset(rays, 0, sizeof rays);
    memset(hits, 0, sizeof hits);
    if (build_only)
        printf("bench_rays: scene \"%s\" (%lld triangles); builds only, median of %d\n", scene_name, tris, runs);
    if (!frames_only && !build_only) {
        rays[SET_PRIMARY] = primary_rays(scene, &view);
        for (tracer = 0; tracer < TRACER_COUNT; ++tracer)
            hits[tracer] = (refl_hit *)xmalloc(sizeof(refl_hit) * (size_t)rays[SET_PRIMARY].count);
        trace(TRACER_OURS, bvh, emb, 1, &rays[SET_PRIMARY], 2, hits[TRACER_OURS]);
        rays[SET_MIRROR] = mirror_rays(scene, &rays[SET_PRIMARY], hits[TRACER_OURS]);
        if (packets) {
            float *shadow_tmax;
            ray_set shadow = shadow_rays(scene, &rays[SET_PRIMARY], hits[TRACER_OURS], &shadow_tmax);
            printf("bench_rays: scene \"%s\" (%lld triangles), %dx%d from its camera; median of %d runs after 1 "
                   "warm-up\n", scene_name, tris, width, height, runs);
            return packets_experiment(bvh, &rays[SET_MIRROR], &shadow, shadow_tmax, runs);
        }

        printf("bench_rays: scene \"%s\" (%lld triangles), %dx%d from its camera; median of %d runs after 1 "
               "warm-up\n",
               scene_name, tris, width, height, runs);
        printf("machine: nproc %ld; builds: refl_bvh %.1f ms (1 thread, %lld nodes), Embree %.1f ms (all threads, "
               "high quality, robust)\n\n",
               sysconf(_SC_NPROCESSORS_ONLN), bvh_ms, nodes, embree_ms);

        /* Hits: the three must agree before their speeds mean anything. */
        for (set = 0; set < SET_COUNT; ++set) {
            long long n = rays[set].count, h[TRACER_COUNT];
            for (tracer = 0; tracer < TRACER_COUNT; ++tracer) {
                trace(tracer, bvh, emb, set == SET_PRIMARY, &rays[set], 2, hits[tracer]);
                h[tracer] = count_hits(hits[tracer], n);
            }
            printf("%-8s %9lld rays: hits refl_bvh %lld, embree_single %lld, embree_stream %lld; rays where "
                   "refl_bvh and Embree differ: %lld (single), %lld (stream)\n",
                   set_names[set], n, h[0], h[1], h[2], count_different(hits[0], hits[1], n),
                   count_different(hits[0], hits[2], n));
            for (tracer = 1; tracer < TRACER_COUNT; ++tracer)
                if (llabs(h[tracer] - h[0]) * 10000 > n) {
                    fprintf(stderr, "bench_rays: %s: %s finds %lld hits, refl_bvh %lld\n", set_names[set],
                            tracer_names[tracer], h[tracer], h[0]);
                    status = 1;
                }
        }
        printf("\n");

        /* The tracers take turns within each run, so a busy moment of a shared
           machine falls on all three alike; the ratios are medians of the
           per-run ratios. */
        times = (double *)xmalloc(sizeof(double) * (size_t)runs * TRACER_COUNT);
        ratios = (double *)xmalloc(sizeof(double) * (size_t)runs);
        memset(mrays, 0, sizeof mrays);
        memset(ratio, 0, sizeof ratio);
        for (set = 0; set < SET_COUNT; ++set)
            for (ti = 0; ti < THREAD_ROWS; ++ti) {
                int run;
                if (only && strcmp(only, set_names[set])) continue;
                for (tracer = 0; tracer < TRACER_COUNT; ++tracer) /* warm-up */
                    trace(tracer, bvh, emb, set == SET_PRIMARY, &rays[set], thread_counts[ti], hits[tracer]);
                for (run = 0; run < runs; ++run)
                    for (tracer = 0; tracer < TRACER_COUNT; ++tracer) {
                        t0 = ray_clock_s();
                        trace(tracer, bvh, emb, set == SET_PRIMARY, &rays[set], thread_counts[ti], hits[tracer]);
                        times[tracer * runs + run] = ray_clock_s() - t0;
                    }
                for (tracer = 1; tracer < TRACER_COUNT; ++tracer) {
                    for (run = 0; run < runs; ++run) ratios[run] = times[tracer * runs + run] / times[run];
                    ratio[set][ti][tracer] = median(ratios, runs);
                }
                for (tracer = 0; tracer < TRACER_COUNT; ++tracer)
                    mrays[set][ti][tracer] = (double)rays[set].count / median(times + tracer * runs, runs) * 1e-6;
            }
        free(times);
        free(ratios);

        printf("Mrays/s%s (higher is faster); ratio = refl_bvh speed / Embree speed, median of per-run ratios\n",
               use_cpu_time ? " per CPU second" : "");
        printf("%-8s %7s %9s %9s %14s %14s %13s %13s\n", "rays", "threads", "count", "refl_bvh", "embree_single",
               "embree_stream", "ratio_single", "ratio_stream");
        for (set = 0; set < SET_COUNT; ++set)
            for (ti = 0; ti < THREAD_ROWS; ++ti) {
                const double *m = mrays[set][ti], *q = ratio[set][ti];
                if (only && strcmp(only, set_names[set])) continue;
                printf("%-8s %7d %9lld %9.2f %14.2f %14.2f %13.2f %13.2f\n", set_names[set], thread_counts[ti],
                       rays[set].count, m[0], m[1], m[2], q[1], q[2]);
            }
    }

    /* Builds, taking turns within each run (after one warm-up each): ours
       and Embree's with 1 thread and with all, ratios at the same count. */
    if (!frames_only) {
        double *bt = (double *)xmalloc(sizeof(double) * (size_t)runs * 6);
        int run;
        build_ours_ms(scene, 1);
        build_embree_ms(scene, 1);
        for (run = 0; run < runs; ++run) {
            bt[run] = build_ours_ms(scene, 1);
            bt[runs + run] = build_embree_ms(scene, 1);
            bt[2 * runs + run] = build_ours_ms(scene, 0);
            bt[3 * runs + run] = build_embree_ms(scene, 0);
            bt[4 * runs + run] = bt[run] / bt[runs + run];
            bt[5 * runs + run] = bt[2 * runs + run] / bt[3 * runs + run];
        }
        printf("\nbuild %s ms (median of %d): 1 thread: refl_bvh %.1f, Embree %.1f, refl_bvh / Embree %.2f; all %ld "
               "threads: refl_bvh %.1f, Embree %.1f, refl_bvh / Embree %.2f (ratios: medians of per-run ratios)\n",
               use_cpu_time ? "CPU" : "wall", runs, median(bt, runs), median(bt + runs, runs),
               median(bt + 4 * runs, runs), sysconf(_SC_NPROCESSORS_ONLN), median(bt + 2 * runs, runs),
               median(bt + 3 * runs, runs), median(bt + 5 * runs, runs));
        free(bt);
    }

    /* Whole RAYTRACE frames, the four taking turns within each run. */
    if (frame_w > 0 && !build_only) {
        refl_view fv = view;
        refl_frame *f = NULL;
        double *ft = (double *)xmalloc(sizeof(double) * (size_t)runs * FRAME_COUNT);
        double *fr = (double *)xmalloc(sizeof(double) * (size_t)runs);
        int which, run;
        fv.width = frame_w;
        fv.height = frame_h;
        if (refl_frame_create(frame_w, frame_h, NULL, &f) != REFL_OK) return 2;
        printf("\nRAYTRACE %dx%d of \"%s\", %d bounce(s), %s; %s ms, median of %d after 1 warm-up; ratio = "
               "Embree's time / ours (above 1: ours faster), median of per-run ratios\n",
               frame_w, frame_h, scene_name, frame_depth, frame_shadows ? "shadows" : "no shadows",
               use_cpu_time ? "CPU" : "wall", runs);
        printf("%-7s %26s %26s %19s %17s %12s %12s %12s\n", "threads", frame_names[0], frame_names[1], frame_names[2],
               frame_names[3], "ratio_built", "ratio_kept", "ratio_caster");
        for (ti = 0; ti < THREAD_ROWS; ++ti) {
            double med[FRAME_COUNT], q[FRAME_EMBREE];
            refl_renderer *rr = frame_renderer(scene, thread_counts[ti]);
            for (which = 0; which < FRAME_COUNT; ++which) /* warm-up; the renderer builds its BVH */
                frame_ms(scene, &fv, which, thread_counts[ti], bvh, emb, rr, f);
            for (run = 0; run < runs; ++run)
                for (which = 0; which < FRAME_COUNT; ++which)
                    ft[which * runs + run] = frame_ms(scene, &fv, which, thread_counts[ti], bvh, emb, rr, f);
            for (which = 0; which < FRAME_EMBREE; ++which) {
                for (run = 0; run < runs; ++run) fr[run] = ft[FRAME_EMBREE * runs + run] / ft[which * runs + run];
                q[which] = median(fr, runs);
            }
            for (which = 0; which < FRAME_COUNT; ++which) med[which] = median(ft + which * runs, runs);
            printf("%-7d %26.1f %26.1f %19.1f %17.1f %12.2f %12.2f %12.2f\n", thread_counts[ti], med[0], med[1],
                   med[2], med[3], q[0], q[1], q[2]);
            refl_renderer_destroy(rr);
        }
        refl_frame_destroy(f);
        free(ft);
        free(fr);
    }

    if (csv && !frames_only && !build_only) {
        FILE *f;
        char dir[1024], *slash;
        snprintf(dir, sizeof dir, "%s", csv);
        slash = strrchr(dir, '/');
        if (slash) {
            *slash = 0;
            mkdir(dir, 0777); /* one level, as in out/bench_rays.csv */
        }
        f = fopen(csv, "w");
        if (!f) {
            fprintf(stderr, "bench_rays: cannot write %s: %s\n", csv, strerror(errno));
            return 2;
        }
        fprintf(f, "rays,threads,count,refl_bvh_mrays_s,embree_single_mrays_s,embree_stream_mrays_s,"
                   "ratio_single,ratio_stream\n");
        for (set = 0; set < SET_COUNT; ++set)
            for (ti = 0; ti < THREAD_ROWS; ++ti) {
                const double *m = mrays[set][ti], *q = ratio[set][ti];
                if (only && strcmp(only, set_names[set])) continue;
                fprintf(f, "%s,%d,%lld,%.3f,%.3f,%.3f,%.3f,%.3f\n", set_names[set], thread_counts[ti],
                        rays[set].count, m[0], m[1], m[2], q[1], q[2]);
            }
        fclose(f);
        printf("\nwrote %s\n", csv);
    }

    for (set = 0; set < SET_COUNT; ++set) {
        free(rays[set].origins);
        free(rays[set].dirs);
    }
    for (tracer = 0; tracer < TRACER_COUNT; ++tracer) free(hits[tracer]);
    refl_embree_destroy(emb);
    refl_bvh_destroy(bvh);
    refl_scene_destroy(scene);
    return status;
}
