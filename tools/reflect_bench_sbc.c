/* `reflect bench`, SBC part (paper 003): its Fig. 19 reproduced on this
   machine beside the paper's numbers, and its vertex projection rate for
   pinhole and ray-list leaves.

   Four scenes, each the default stage (floor, torus, sphere, box) with
   the teapot replaced by the paper's reflectors: the teapot's body (its
   8 body patches: no rim, handle, spout or lid), a spherical cap facing
   the viewer, two spheres, and a car-like compound reflector of four
   mirror pieces (body, cabin, two bumpers: scaled spheres; the paper cut
   its automobile into seven). The view is the paper's size, 720x480,
   looking from the default view's direction but nearer, so the
   reflectors cover about the share of it the paper's did; the ray maps
   are its quarter and half resolution ones (factors 4 and 2: 180x120 and
   360x240).

   The ray maps are SBC's own (refl_render_desc.debug.sbc_ray_map hands over
   each reflector side's map as the method makes it); each becomes one
   reflection group, as in the paper (the teapot body's inside, seen over
   its top, is a group of its own), built with refl_sbc_build at the
   method's default 1 px error. Columns:
     rays      the rays the SBCs are built from: every ray map sample on a
               reflector plus the ring extrapolated beyond its silhouette
               (the paper's extended reflectors);
     coverage  the fraction of the ray map's samples that fall on a
               reflector (the paper's Cov.: its rays over its 360x240 and
               180x120 maps give its 19/33/40/20%), counted independently
               from the rendered frame's stencil;
     KB        the trees' memory (refl_sbc_stats.bytes), summed;
     build ms  refl_sbc_build over all reflectors, one thread, median;
     the renderer's own trees (REFL_SBC cuts each side into tiles of 16
     samples, see sbc_groups.c) are reported beside them.
   Projection: points spread uniformly in the scene's box are sent through
   every reflector's SBC on one thread; each is timed with the others of
   its leaf kind (refl_sbc_leaf_at), so the rate is per kind, in million
   vertices per second, whether the point then projects or not. The paper
   projected on the GPU (20 Mv/s pinhole, 2.5 Mv/s ray list) and says its
   CPU was 5 times slower.
   Reflection morphing (the paper's section VI): for the teapot body and
   two spheres scenes (the paper's morphing scenes), a one-cell grid of
   panoramic SBCs (refl_sbc_morph_build, 2 x 2 x 2 nodes, 128-sample cube
   faces) around the view's eye, a tenth of the eye's distance to its
   target on every side, per mirror; every scene vertex projected into
   every piece on one thread, dynamic (the four nodes' SBCs, then the
   blend) and static (projections kept for the tetrahedron, re-blended for
   ten eyes within it), in million vertex projections per second (the
   paper: 1 and 12.5 Mv/s on its CPU); then a frame at half the table's
   size drawn with the grids (SBC with refl_render_desc.sbc.morphs) and
   per frame (SBC), each timed (median) and measured against RAYTRACE.
   SBC-paper and SBC-traced (refl_sbc_options.mode) against Embree's
   RAYTRACE on the built-in scenes: modes_table. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "../bench/embree_peer.h"
#include "reflect_bench.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SBC_VIEW_W 720
#define SBC_VIEW_H 480
#define SBC_MAPS_MAX 16

/* The paper's Fig. 19 (Pentium 4 Xeon 3.4 GHz): quarter / half. */
typedef struct fig19_paper {
    double krays[2], coverage, kb[2], ms[2];
} fig19_paper;

/* The ray maps one render handed over. */
typedef struct sbc_maps {
    int count, width, height, failed;
    int object[SBC_MAPS_MAX];
    refl_sbc_ray *rays[SBC_MAPS_MAX];
    uint8_t *valid[SBC_MAPS_MAX];
} sbc_maps;

static void keep_ray_map(void *user, int object, const refl_sbc_ray *rays, const uint8_t *valid, int w, int h) {
    sbc_maps *m = (sbc_maps *)user;
    size_t n = (size_t)w * (size_t)h;
    if (m->count == SBC_MAPS_MAX) {
        m->failed = 1;
        return;
    }
    m->rays[m->count] = (refl_sbc_ray *)malloc(n * sizeof(refl_sbc_ray));
    m->valid[m->count] = (uint8_t *)malloc(n);
    if (!m->rays[m->count] || !m->valid[m->count]) {
        free(m->rays[m->count]);
        free(m->valid[m->count]);
        m->failed = 1;
        return;
    }
    memcpy(m->rays[m->count], rays, n * sizeof(refl_sbc_ray));
    memcpy(m->valid[m->count], valid, n);
    m->object[m->count++] = object;
    m->width = w;
    m->height = h;
}

static void free_maps(sbc_maps *m) {
    int i;
    for (i = 0; i < m->count; ++i) {
        free(m->rays[i]);
        free(m->valid[i]);
    }
    memset(m, 0, sizeof *m);
}

/* The triangles of src that keep() takes, as a mesh (src is destroyed). */
static refl_mesh *triangle_subset(refl_mesh *src, int (*keep)(const refl_mesh *m, int t, float arg), float arg) {
    refl_mesh *out = NULL;
    refl_mesh_desc d;
    uint32_t *idx;
    int t, n = 0;
    if (!src) return NULL;
    idx = (uint32_t *)malloc((size_t)src->triangle_count * 3 * sizeof(uint32_t));
    for (t = 0; idx && t < src->triangle_count; ++t)
        if (keep(src, t, arg)) memcpy(idx + 3 * n++, src->indices + 3 * t, 3 * sizeof(uint32_t));
    memset(&d, 0, sizeof d);
    d.positions = src->positions;
    d.normals = src->normals;
    d.vertex_count = src->vertex_count;
    d.indices = idx;
    d.index_count = 3 * n;
    if (!idx || refl_mesh_create(&d, &out) != REFL_OK) out = NULL;
    free(idx);
    refl_mesh_destroy(src);
    return out;
}

/* A triangle whose centroid lies above z = arg. */
static int above_z(const refl_mesh *m, int t, float arg) {
    float z = 0.0f;
    int k;
    for (k = 0; k < 3; ++k) z += m->positions[3 * m->indices[3 * t + k] + 2] / 3.0f;
    return z >= arg;
}

/* A triangle of [arg, 3 arg). */
static int in_body(const refl_mesh *m, int t, float arg) {
    (void)m;
    return (float)t >= arg && (float)t < 3.0f * arg;
}

/* A sphere's triangles within half_angle of +z: a cap facing +z. */
static refl_mesh *cap_mesh(float radius, float half_angle) {
    refl_mesh *sphere = NULL;
    if (refl_mesh_sphere(radius, 96, 48, NULL, &sphere) != REFL_OK) return NULL;
    return triangle_subset(sphere, above_z, radius * cosf(half_angle));
}

/* The teapot's body: refl_mesh_teapot lays its 32 patches out in the
   data's order (rim 4, body 8, handle 4, spout 4, lid 8, bottom 4), each
   2 tess^2 triangles (only the lid's and bottom's poles lose some), so
   the body is triangles [8 tess^2, 24 tess^2). Checked: without handle
   and spout it is symmetric about x = 0. */
static refl_mesh *teapot_body_mesh(void) {
    const int tess = 8;
    refl_mesh *teapot = NULL, *body;
    float lo = 0.0f, hi = 0.0f;
    int i;
    if (refl_mesh_teapot(tess, NULL, &teapot) != REFL_OK) return NULL;
    body = triangle_subset(teapot, in_body, (float)(8 * tess * tess));
    if (!body) return NULL;
    for (i = 0; i < 3 * body->triangle_count; ++i) { /* the vertices in use (all are kept) */
        float x = body->positions[3 * body->indices[i]];
        lo = x < lo ? x : lo;
        hi = x > hi ? x : hi;
    }
    if (fabsf(hi + lo) > 0.01f * (hi - lo)) {
        refl_mesh_destroy(body);
        return NULL;
    }
    return body;
}

/* Adds a mirror object (the teapot's material) with mesh m; 0 on failure. */
static int add_mirror(refl_scene *s, int material, refl_mesh *m, refl_mat4 transform, const char *name) {
    refl_object o;
    memset(&o, 0, sizeof o);
    if (!m) return 0;
    o.mesh = refl_scene_add_mesh(s, m);
    if (o.mesh < 0) return 0;
    o.material = material;
    o.transform = transform;
    snprintf(o.name, sizeof o.name, "%s", name);
    return refl_scene_add_object(s, &o) >= 0;
}

static refl_mesh *sphere_mesh(float radius) {
    refl_mesh *m = NULL;
    return refl_mesh_sphere(radius, 64, 32, NULL, &m) == REFL_OK ? m : NULL;
}

static refl_mat4 at_scaled(float x, float y, float z, float sx, float sy, float sz) {
    return refl_mat4_mul(refl_mat4_translate(refl_v3(x, y, z)), refl_mat4_scale(refl_v3(sx, sy, sz)));
}

/* Puts mesh m (the scene takes it) in object o's place, moved by t; 0 on
   failure. */
static int reshape(refl_scene *s, int o, refl_mesh *m, refl_mat4 t) {
    int mi = m ? refl_scene_add_mesh(s, m) : -1;
    if (mi < 0) return 0;
    s->objects[o].mesh = mi;
    s->objects[o].transform = t;
    return 1;
}

/* The default scene with its teapot replaced by the named reflector(s),
   the first of them in the teapot's place. */
static refl_scene *fig19_scene(const char *name) {
    refl_builtin_desc bd;
    refl_scene *s = NULL;
    int i, teapot = -1, material = 0, ok;
    memset(&bd, 0, sizeof bd);
    if (refl_scene_builtin("default", &bd, &s) != REFL_OK) return NULL;
    for (i = 0; i < s->object_count; ++i)
        if (!strcmp(s->objects[i].name, "teapot")) teapot = i;
    ok = teapot >= 0;
    if (ok) material = s->objects[teapot].material;
    if (ok && !strcmp(name, "spherical cap")) {
        /* a 60-degree cap of radius 1.6 facing the viewer */
        refl_vec3 axis = refl_v3_normalize(refl_v3_sub(s->camera.eye, s->camera.target));
        ok = reshape(s, teapot, cap_mesh(1.6f, 1.0471976f),
                     refl_mat4_mul(refl_mat4_translate(refl_v3(0.0f, 0.6f, -1.6f)),
                                   refl_mat4_rotate(refl_v3(1, 0, 0), -asinf(axis.y))));
    } else if (ok && !strcmp(name, "two spheres")) {
        ok = reshape(s, teapot, sphere_mesh(1.0f), refl_mat4_translate(refl_v3(-1.3f, 1.0f, -0.4f))) &&
             add_mirror(s, material, sphere_mesh(1.0f), refl_mat4_translate(refl_v3(1.3f, 1.0f, -0.4f)), "sphere 2");
    } else if (ok && !strcmp(name, "car")) {
        /* body, cabin, front and rear bumper: separate reflectors, so
           separate reflection groups (the paper's pieces whose rays do
           not cross) */
        ok = reshape(s, teapot, sphere_mesh(1.0f), at_scaled(0.0f, 0.75f, 0.0f, 2.2f, 0.5f, 1.0f)) &&
             add_mirror(s, material, sphere_mesh(1.0f), at_scaled(-0.3f, 1.2f, 0.0f, 1.2f, 0.5f, 0.8f), "cabin") &&
             add_mirror(s, material, sphere_mesh(1.0f), at_scaled(2.1f, 0.55f, 0.0f, 0.3f, 0.3f, 0.9f),
                        "front bumper") &&
             add_mirror(s, material, sphere_mesh(1.0f), at_scaled(-2.1f, 0.55f, 0.0f, 0.3f, 0.3f, 0.9f),
                        "rear bumper");
    } else if (ok && !strcmp(name, "teapot body")) {
        ok = reshape(s, teapot, teapot_body_mesh(), s->objects[teapot].transform);
    } else {
        ok = 0;
    }
    if (!ok) {
        refl_scene_destroy(s);
        return NULL;
    }
    return s;
}

/* One row of the table: a scene at one ray map factor. */
typedef struct fig19_row {
    int width, height, reflectors;
    long long rays, on_reflector, kb_bytes;
    double coverage, build_ms;
    int nodes, pinhole_leaves, ray_leaves, depth;
    long long render_bytes, render_pinhole, render_rays;
    long long points[2], projected[2]; /* by leaf kind: pinhole, ray list */
    double project_ms[2];
} fig19_row;

/* Map samples whose pixel (as sbc_raymap.c places it: the middle of its
   factor x factor block) shows a reflector in the frame's stencil. */
static long long samples_on_reflectors(const refl_frame *f, int factor, int mw, int mh) {
    long long n = 0;
    int u, v;
    for (v = 0; v < mh; ++v)
        for (u = 0; u < mw; ++u) {
            int x = u * factor + factor / 2, y = v * factor + factor / 2;
            if (x > f->width - 1) x = f->width - 1;
            if (y > f->height - 1) y = f->height - 1;
            n += f->stencil[(size_t)y * (size_t)f->width + (size_t)x] != 0;
        }
    return n;
}

/* Projects every point of `list` through sbc on this thread; returns the
   wall time in ms and adds the projections found. */
static double timed_projection(const refl_sbc *sbc, const refl_vec3 *pts, const int *list, int n,
                               long long *projected) {
    double t0 = refl_bench_now_ms();
    long long found = 0;
    int i;
    for (i = 0; i < n; ++i) {
        refl_vec3 first;
        float z;
        found += refl_sbc_project(sbc, pts[list[i]], &first, &z);
    }
    *projected += found;
    return refl_bench_now_ms() - t0;
}

static int measure(const refl_scene *s, const refl_view *v, int factor, int threads, int repeats, int npoints,
                   fig19_row *row) {
    refl_frame *f = NULL;
    refl_render_desc d;
    refl_sbc_desc sd;
    refl_sbc *sbc[SBC_MAPS_MAX];
    refl_mat4 view_m, proj_m;
    refl_vec3 lo, hi, *pts = NULL;
    int *list[2] = {NULL, NULL}, count[2];
    double times[32];
    sbc_maps maps;
    refl_rng rng = refl_rng_seed(0x5bc19);
    int i, k, c, ok, n = repeats < 1 ? 1 : repeats > 32 ? 32 : repeats;
    memset(row, 0, sizeof *row);
    memset(&maps, 0, sizeof maps);
    memset(sbc, 0, sizeof sbc);
    memset(&d, 0, sizeof d);
    d.method = REFL_SBC;
    d.threads = threads;
    d.depth = 1;
    d.sbc.ray_factor = factor;
    d.debug.sbc_ray_map = keep_ray_map;
    d.debug.sbc_ray_map_user = &maps;
    ok = refl_frame_create(v->width, v->height, NULL, &f) == REFL_OK && refl_render(s, v, &d, f) == REFL_OK &&
         !maps.failed && maps.count > 0;
    if (ok) {
        row->width = maps.width;
        row->height = maps.height;
        row->reflectors = maps.count;
        row->on_reflector = samples_on_reflectors(f, factor, maps.width, maps.height);
        row->coverage = (double)row->on_reflector / ((double)maps.width * maps.height);
        row->render_bytes = f->stats.model_bytes;
        row->render_pinhole = f->stats.sbc.pinhole_leaves;
        row->render_rays = f->stats.sbc.ray_leaves;
    }
    memset(&sd, 0, sizeof sd);
    refl_view_matrices(v, s, &view_m, &proj_m);
    sd.view_proj = refl_mat4_mul(proj_m, view_m);
    sd.width = v->width;
    sd.height = v->height;
    for (k = 0; ok && k < n; ++k) {
        double t0;
        for (i = 0; i < maps.count; ++i) { /* the last run's trees are kept */
            refl_sbc_destroy(sbc[i]);
            sbc[i] = NULL;
        }
        t0 = refl_bench_now_ms();
        for (i = 0; ok && i < maps.count; ++i)
            ok = refl_sbc_build(maps.rays[i], maps.valid[i], maps.width, maps.height, &sd, &sbc[i]) == REFL_OK;
        times[k] = refl_bench_now_ms() - t0;
    }
    if (ok) row->build_ms = refl_bench_median(times, n);
    for (i = 0; ok && i < maps.count; ++i) {
        refl_sbc_stats st;
        refl_sbc_get_stats(sbc[i], &st);
        row->rays += st.rays;
        row->kb_bytes += st.bytes;
        row->nodes += st.nodes;
        row->pinhole_leaves += st.pinhole_leaves;
        row->ray_leaves += st.ray_leaves;
        if (st.depth > row->depth) row->depth = st.depth;
    }
    /* the points, then per reflector: sorted by leaf kind, each kind timed */
    refl_scene_bounds(s, &lo, &hi);
    pts = (refl_vec3 *)malloc((size_t)npoints * sizeof(refl_vec3));
    list[0] = (int *)malloc((size_t)npoints * sizeof(int));
    list[1] = (int *)malloc((size_t)npoints * sizeof(int));
    if (!pts || !list[0] || !list[1]) ok = 0;
    for (i = 0; ok && i < npoints; ++i) {
        float x = refl_rng_float(&rng), y = refl_rng_float(&rng), z = refl_rng_float(&rng);
        pts[i] = refl_v3(lo.x + x * (hi.x - lo.x), lo.y + y * (hi.y - lo.y), lo.z + z * (hi.z - lo.z));
    }
    for (k = 0; ok && k < maps.count; ++k) {
        count[0] = count[1] = 0;
        for (i = 0; i < npoints; ++i) {
            refl_sbc_leaf_kind kind = refl_sbc_leaf_at(sbc[k], pts[i]);
            if (kind == REFL_SBC_LEAF_PINHOLE) list[0][count[0]++] = i;
            else if (kind == REFL_SBC_LEAF_RAY_LIST) list[1][count[1]++] = i;
        }
        for (c = 0; c < 2; ++c) {
            row->points[c] += count[c];
            row->project_ms[c] += timed_projection(sbc[k], pts, list[c], count[c], &row->projected[c]);
        }
    }
    for (i = 0; i < maps.count; ++i) refl_sbc_destroy(sbc[i]);
    free(pts);
    free(list[0]);
    free(list[1]);
    free_maps(&maps);
    refl_frame_destroy(f);
    return ok;
}

static double mvps(long long points, double ms) { return ms > 0.0 ? (double)points / ms * 1e-3 : 0.0; }

/* One morphing row: grids, rates, and the frame with and without them. */
typedef struct morph_row {
    int grids, pieces, sbcs;
    long long bytes, vertices, dynamic_calls, static_calls;
    double build_ms, dynamic_ms, static_ms;
    double morph_ms, runtime_ms, morph_mean, morph_p95, morph_holes, runtime_mean, runtime_p95, runtime_holes;
    long long ambiguous;
} morph_row;

#define MORPH_GRIDS_MAX 4

/* A frame of s from v with desc d (median time of n); its error against truth. */
static int morph_frame(const refl_scene *s, const refl_view *v, const refl_render_desc *d, int n,
                       const refl_frame *truth, double *ms, refl_reflection_error *e, long long *ambiguous) {
    refl_frame *f = NULL;
    double times[32];
    int k, ok = refl_frame_create(v->width, v->height, NULL, &f) == REFL_OK;
    for (k = 0; ok && k < n; ++k) {
        ok = refl_render(s, v, d, f) == REFL_OK;
        times[k] = f->stats.ms_total;
    }
    if (ok) {
        *ms = refl_bench_median(times, n);
        *ambiguous = f->stats.sbc.ambiguous;
        ok = refl_measure_reflection_error(f, truth, NULL, e) == REFL_OK;
    }
    refl_frame_destroy(f);
    return ok;
}

static int measure_morph(const refl_scene *s, const refl_view *v, int threads, int repeats, morph_row *row) {
    refl_sbc_morph *grids[MORPH_GRIDS_MAX];
    const refl_sbc_morph *use[MORPH_GRIDS_MAX];
    refl_sbc_morph_desc md;
    refl_render_desc d;
    refl_view hv = *v;
    refl_frame *truth = NULL;
    refl_reflection_error e;
    float *pts = NULL, *dist = NULL;
    refl_vec3 *first = NULL;
    uint8_t *status = NULL;
    float reach = 0.1f * refl_v3_length(refl_v3_sub(v->eye, v->target));
    int o, i, k, g, piece, n = repeats < 1 ? 1 : repeats > 32 ? 32 : repeats, ok = 1, nv = 0;
    memset(row, 0, sizeof *row);
    memset(&md, 0, sizeof md);
    md.nodes[0] = md.nodes[1] = md.nodes[2] = 2;
    md.region_lo = refl_v3_sub(v->eye, refl_v3(reach, reach, reach));
    md.region_hi = refl_v3_add(v->eye, refl_v3(reach, reach, reach));
    md.face_size = 128;
    md.threads = threads;
    for (o = 0; ok && o < s->object_count; ++o) {
        refl_sbc_morph_stats st;
        if (s->materials[s->objects[o].material].type != REFL_MIRROR) continue;
        if (row->grids == MORPH_GRIDS_MAX) { ok = 0; break; }
        ok = refl_sbc_morph_build(s, o, &md, &grids[row->grids]) == REFL_OK;
        if (!ok) break;
        use[row->grids] = grids[row->grids];
        refl_sbc_morph_get_stats(grids[row->grids++], &st);
        row->build_ms += st.ms_build;
        row->bytes += st.bytes;
        row->pieces += st.pieces;
        row->sbcs += st.sbcs;
    }
    /* every vertex of the scene, world space */
    for (o = 0; o < s->object_count; ++o) nv += refl_object_world_positions(s, o, NULL);
    row->vertices = nv;
    pts = (float *)malloc((size_t)nv * 3 * sizeof(float));
    dist = (float *)malloc((size_t)nv * sizeof(float));
    first = (refl_vec3 *)malloc((size_t)nv * sizeof(refl_vec3));
    status = (uint8_t *)malloc((size_t)nv);
    if (!pts || !dist || !first || !status) ok = 0;
    for (o = 0, i = 0; ok && o < s->object_count; ++o) i += refl_object_world_positions(s, o, pts + 3 * (size_t)i);
    for (g = 0; ok && g < row->grids; ++g) {
        refl_sbc_morph_stats st;
        refl_sbc_morph_get_stats(grids[g], &st);
        for (piece = 0; ok && piece < st.pieces; ++piece) {
            refl_sbc_morph_cache *cache = NULL;
            long long amb;
            double t0 = refl_bench_now_ms();
            ok = refl_sbc_morph_project_points(grids[g], v->eye, piece, pts, nv, NULL, first, dist, status, &amb) ==
                 REFL_OK;
            row->dynamic_ms += refl_bench_now_ms() - t0;
            row->dynamic_calls += nv;
            /* the cache filled once (not timed), then ten eyes in the tetrahedron */
            ok = ok && refl_sbc_morph_cache_create(NULL, &cache) == REFL_OK &&
                 refl_sbc_morph_project_points(grids[g], v->eye, piece, pts, nv, cache, first, dist, status, &amb) ==
                     REFL_OK;
            t0 = refl_bench_now_ms();
            for (k = 0; ok && k < 10; ++k) {
                refl_vec3 eye = refl_v3_add(v->eye, refl_v3(1e-4f * reach * (float)k, 0.0f, 0.0f));
                ok = refl_sbc_morph_project_points(grids[g], eye, piece, pts, nv, cache, first, dist, status, &amb) ==
                     REFL_OK;
                row->static_calls += nv;
            }
            row->static_ms += refl_bench_now_ms() - t0;
            refl_sbc_morph_cache_destroy(cache);
        }
    }
    /* the frame at half size: with the grids, per frame, and the truth */
    hv.width = v->width / 2;
    hv.height = v->height / 2;
    memset(&d, 0, sizeof d);
    d.method = REFL_RAYTRACE;
    d.threads = threads;
    d.depth = 1;
    ok = ok && refl_frame_create(hv.width, hv.height, NULL, &truth) == REFL_OK && refl_render(s, &hv, &d, truth) == REFL_OK;
    d.method = REFL_SBC;
    if (ok && morph_frame(s, &hv, &d, n, truth, &row->runtime_ms, &e, &row->ambiguous)) {
        row->runtime_mean = e.mean;
        row->runtime_p95 = e.p95;
        row->runtime_holes = e.empty;
    } else {
        ok = 0;
    }
    d.sbc.morphs = use;
    d.sbc.morph_count = row->grids;
    if (ok && morph_frame(s, &hv, &d, n, truth, &row->morph_ms, &e, &row->ambiguous)) {
        row->morph_mean = e.mean;
        row->morph_p95 = e.p95;
        row->morph_holes = e.empty;
    } else {
        ok = 0;
    }
    for (g = 0; g < row->grids; ++g) refl_sbc_morph_destroy(grids[g]);
    refl_frame_destroy(truth);
    free(pts);
    free(dist);
    free(first);
    free(status);
    return ok;
}

/* The morphing rows (the module comment), into sbc_morph.csv. */
static int morph_table(const char *dir, int threads, int repeats, const float *closer) {
    static const char *const scenes[] = {"teapot body", "two spheres"};
    static const int which[] = {1, 2}; /* their places in refl_bench_sbc's list, for `closer` */
    char path[1024];
    FILE *csv;
    int i, ok = 1;
    snprintf(path, sizeof path, "%s/sbc_morph.csv", dir);
    if (!(csv = fopen(path, "w"))) return 0;
    fprintf(csv, "scene,grids,nodes_per_grid,face_size,pieces,sbcs,kb,build_ms,vertices,dynamic_mvps,static_mvps,"
                 "paper_dynamic_mvps,paper_static_mvps,view_width,view_height,morph_ms,morph_mean_px,morph_p95_px,"
                 "morph_holes,ambiguous,runtime_ms,runtime_mean_px,runtime_p95_px,runtime_holes\n");
    printf("SBC reflection morphing: one-cell grids (8 nodes, 128-sample faces) around the eye per mirror; "
           "projection on one thread\n(paper, CPU: 1 Mv/s dynamic, 12.5 static); frames at %dx%d with the grids "
           "and per frame, median of %d, error against RAYTRACE\n", SBC_VIEW_W / 2, SBC_VIEW_H / 2, repeats);
    printf("%-12s %6s %8s %9s | %9s %9s | %21s | %21s\n", "scene", "KB", "build ms", "vertices", "dyn Mv/s",
           "stat Mv/s", "morph ms mean/p95/holes", "runtime ms mean/p95/holes");
    for (i = 0; ok && i < 2; ++i) {
        refl_scene *s = fig19_scene(scenes[i]);
        refl_view v;
        morph_row r;
        if (!s) { ok = 0; break; }
        v = s->camera;
        v.width = SBC_VIEW_W;
        v.height = SBC_VIEW_H;
        v.eye = refl_v3_add(v.target, refl_v3_scale(refl_v3_sub(v.eye, v.target), closer[which[i]]));
        ok = measure_morph(s, &v, threads, repeats, &r);
        refl_scene_destroy(s);
        if (!ok) break;
        fprintf(csv, "%s,%d,8,128,%d,%d,%.1f,%.1f,%lld,%.3f,%.3f,1,12.5,%d,%d,%.1f,%.2f,%.2f,%.3f,%lld,%.1f,%.2f,%.2f,%.3f\n",
                scenes[i], r.grids, r.pieces, r.sbcs, r.bytes / 1024.0, r.build_ms, r.vertices,
                mvps(r.dynamic_calls, r.dynamic_ms), mvps(r.static_calls, r.static_ms), v.width / 2, v.height / 2,
                r.morph_ms, r.morph_mean, r.morph_p95, r.morph_holes, r.ambiguous, r.runtime_ms, r.runtime_mean,
                r.runtime_p95, r.runtime_holes);
        printf("%-12s %6.0f %8.0f %9lld | %9.2f %9.2f | %7.0f %4.2f/%4.1f/%3.0f%% | %7.0f %4.2f/%4.1f/%3.0f%%\n",
               scenes[i], r.bytes / 1024.0, r.build_ms, r.vertices, mvps(r.dynamic_calls, r.dynamic_ms),
               mvps(r.static_calls, r.static_ms), r.morph_ms, r.morph_mean, r.morph_p95, 100.0 * r.morph_holes,
               r.runtime_ms, r.runtime_mean, r.runtime_p95, 100.0 * r.runtime_holes);
    }
    fclose(csv);
    if (ok) fprintf(stderr, "wrote %s\n", path);
    return ok;
}

/* The two SBC variants against Embree's RAYTRACE in one run, per built-in
   scene at 640x480: SBC-paper (refl_sbc_options.mode REFL_SBC_PAPER: no
   search of the scene, what the paper times against ray tracing) and
   SBC-traced (REFL_SBC_TRACED, the default: every ray map sample traced
   against the scene's BVH), each timed (median) and measured against
   RAYTRACE of the same depth (glass at depth 2: one bounce leaves it
   black). A table on stdout and dir/sbc_modes.csv. */
static int modes_table(const char *dir, int threads, int repeats) {
    static const char *const scenes[] = {"default", "mirror-room", "concave", "glass"};
    static const char *const series[] = {"embree", "sbc-paper", "sbc-traced"};
    char path[1024], err[256];
    FILE *csv;
    int i, k, ok = 1;
    snprintf(path, sizeof path, "%s/sbc_modes.csv", dir);
    if (!(csv = fopen(path, "w"))) return 0;
    fprintf(csv, "scene,series,depth,width,height,threads,ms_median,ms_min,ratio_to_embree,rays,model_bytes,"
                 "error_mean_px,error_p95_px,wrong,empty,psnr_db\n");
    printf("SBC-paper (no scene search) and SBC-traced (ray map samples traced) against Embree's RAYTRACE, "
           "640x480, %d threads, median of %d\n", threads, repeats);
    printf("%-12s %-11s %5s %9s %7s %9s %8s %8s %7s %7s\n", "scene", "series", "depth", "ms", "x embree", "rays",
           "mean px", "p95 px", "holes", "PSNR");
    for (i = 0; ok && i < 4; ++i) {
        refl_scene *s = NULL;
        refl_embree *e = NULL;
        refl_frame *truth = NULL, *f = NULL;
        refl_render_desc d;
        refl_view v;
        double embree_ms = 0.0;
        if (refl_scene_builtin(scenes[i], NULL, &s) != REFL_OK) {
            ok = 0;
            break;
        }
        v = s->camera;
        v.width = 640;
        v.height = 480;
        if (!(e = refl_embree_create(s, threads, err, sizeof err)) ||
            refl_frame_create(v.width, v.height, NULL, &truth) != REFL_OK ||
            refl_frame_create(v.width, v.height, NULL, &f) != REFL_OK)
            ok = 0;
        memset(&d, 0, sizeof d);
        d.method = REFL_RAYTRACE;
        d.threads = threads;
        d.depth = strcmp(scenes[i], "glass") ? 1 : 2;
        if (ok && refl_render(s, &v, &d, truth) != REFL_OK) ok = 0;
        for (k = 0; ok && k < 3; ++k) {
            refl_reflection_error re;
            refl_image_error ie;
            double ms, fastest;
            d.method = k ? REFL_SBC : REFL_RAYTRACE;
            d.sbc.mode = k == 1 ? REFL_SBC_PAPER : REFL_SBC_TRACED;
            d.raytrace.caster.intersect = k ? NULL : refl_embree_intersect;
            d.raytrace.caster.occluded = k ? NULL : refl_embree_occluded;
            d.raytrace.caster.user = k ? NULL : e;
            if (refl_bench_timed_render(s, &v, &d, repeats, f, &ms, &fastest) != REFL_OK ||
                refl_measure_reflection_error(f, truth, NULL, &re) != REFL_OK ||
                refl_measure_image_error(f, truth, 1, 0.0f, &ie) != REFL_OK) {
                ok = 0;
                break;
            }
            if (!k) embree_ms = ms;
            fprintf(csv, "%s,%s,%d,%d,%d,%d,%.2f,%.2f,%.3f,%lld,%lld,%.4f,%.4f,%.6f,%.6f,%.3f\n", scenes[i], series[k],
                    d.depth, v.width, v.height, threads, ms, fastest, embree_ms > 0.0 ? ms / embree_ms : 0.0,
                    f->stats.rays, f->stats.model_bytes, re.mean, re.p95, re.wrong, re.empty, ie.psnr);
            printf("%-12s %-11s %5d %9.1f %8.2f %9lld %8.3f %8.2f %6.2f%% %7.2f\n", scenes[i], series[k], d.depth, ms,
                   embree_ms > 0.0 ? ms / embree_ms : 0.0, f->stats.rays, re.mean, re.p95, 100.0 * re.empty, ie.psnr);
        }
        refl_frame_destroy(truth);
        refl_frame_destroy(f);
        refl_embree_destroy(e);
        refl_scene_destroy(s);
    }
    fclose(csv);
    if (ok) fprintf(stderr, "wrote %s\n", path);
    return ok;
}

int refl_bench_sbc(const char *dir, int threads, int repeats, int full) {
    static const char *const scenes[] = {"spherical cap", "teapot body", "two spheres", "car"};
    static const fig19_paper paper[] = {{{4, 16}, 19, {153, 597}, {21, 33}},
                                        {{7, 28}, 33, {191, 703}, {93, 295}},
                                        {{9, 35}, 40, {549, 2331}, {65, 328}},
                                        {{5, 18}, 20, {315, 1256}, {62, 463}}};
    static const int factors[] = {4, 2};
    /* the default view's distance to its target, scaled per scene */
    static const float closer[] = {0.5f, 0.575f, 0.38f, 0.52f};
    const int npoints = full ? 1000000 : 200000;
    char path[1024];
    FILE *csv;
    long long all_points[2] = {0, 0};
    double all_ms[2] = {0.0, 0.0};
    int i, q, ok = 1;
    snprintf(path, sizeof path, "%s/sbc_fig19.csv", dir);
    if (!(csv = fopen(path, "w"))) return 0;
    fprintf(csv, "scene,ray_factor,view_width,view_height,map_width,map_height,reflectors,rays,reflector_samples,"
                 "coverage_pct,sbc_kb,build_ms,nodes,pinhole_leaves,ray_list_leaves,depth,render_tiles_kb,"
                 "render_pinhole_leaves,render_ray_list_leaves,points,pinhole_points,pinhole_projected,pinhole_mvps,"
                 "ray_list_points,ray_list_projected,ray_list_mvps,paper_krays,paper_coverage_pct,paper_kb,paper_ms\n");
    printf("SBC: paper 003's Fig. 19 at %dx%d, quarter (Q, factor 4) and half (H, factor 2) resolution ray maps,\n"
           "one SBC per reflector at 1 px; build on one thread (median of %d); coverage: ray map samples on a\n"
           "reflector; rays: those plus the ring extrapolated beyond the silhouettes; paper's numbers in ()\n",
           SBC_VIEW_W, SBC_VIEW_H, repeats);
    printf("%-14s %2s %8s %13s %12s %18s %16s %12s | %9s %9s\n", "scene", "", "map", "rays (k)", "coverage",
           "size KB", "build ms", "leaves p/r", "pin Mv/s", "list Mv/s");
    for (i = 0; ok && i < 4; ++i) {
        refl_scene *s = fig19_scene(scenes[i]);
        refl_view v;
        if (!s) { ok = 0; break; }
        v = s->camera;
        v.width = SBC_VIEW_W;
        v.height = SBC_VIEW_H;
        /* nearer the target, so the reflectors fill about the paper's share of the view */
        v.eye = refl_v3_add(v.target, refl_v3_scale(refl_v3_sub(v.eye, v.target), closer[i]));
        for (q = 0; ok && q < 2; ++q) {
            fig19_row r;
            const fig19_paper *p = &paper[i];
            ok = measure(s, &v, factors[q], threads, repeats, npoints, &r);
            if (!ok) break;
            fprintf(csv, "%s,%d,%d,%d,%d,%d,%d,%lld,%lld,%.1f,%.1f,%.2f,%d,%d,%d,%d,%.1f,%lld,%lld,%d,%lld,%lld,%.3f,"
                         "%lld,%lld,%.3f,%.0f,%.0f,%.0f,%.0f\n",
                    scenes[i], factors[q], v.width, v.height, r.width, r.height, r.reflectors, r.rays,
                    r.on_reflector, 100.0 * r.coverage, r.kb_bytes / 1024.0, r.build_ms, r.nodes, r.pinhole_leaves,
                    r.ray_leaves, r.depth, r.render_bytes / 1024.0, r.render_pinhole, r.render_rays, npoints,
                    r.points[0], r.projected[0], mvps(r.points[0], r.project_ms[0]), r.points[1], r.projected[1],
                    mvps(r.points[1], r.project_ms[1]), p->krays[q], p->coverage, p->kb[q], p->ms[q]);
            printf("%-14s %2s %3dx%-4d %6.1f (%4.0f) %5.1f%% (%2.0f%%) %8.0f (%6.0f) %7.1f (%5.0f) %5d/%-5d | %9.2f %9.2f\n",
                   scenes[i], q ? "H" : "Q", r.width, r.height, r.rays * 1e-3, p->krays[q], 100.0 * r.coverage,
                   p->coverage, r.kb_bytes / 1024.0, p->kb[q], r.build_ms, p->ms[q], r.pinhole_leaves, r.ray_leaves,
                   mvps(r.points[0], r.project_ms[0]), mvps(r.points[1], r.project_ms[1]));
            all_points[0] += r.points[0];
            all_points[1] += r.points[1];
            all_ms[0] += r.project_ms[0];
            all_ms[1] += r.project_ms[1];
        }
        refl_scene_destroy(s);
    }
    fclose(csv);
    if (!ok) return 0;
    printf("projection, one thread, %d points in each scene's box per row: pinhole leaves %.2f Mv/s, "
           "ray-list leaves %.2f Mv/s (paper, GPU: 20 and 2.5; its CPU 5 times slower)\n",
           npoints, mvps(all_points[0], all_ms[0]), mvps(all_points[1], all_ms[1]));
    fprintf(stderr, "wrote %s\n", path);
    return modes_table(dir, threads, repeats) && morph_table(dir, threads, repeats, closer);
}
