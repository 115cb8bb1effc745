/* Paper 001's adaptive tessellation (Hakura and Snyder, section 5): ray
   paths are traced at a lens object's vertices only, and a triangle is
   split where the paths at its vertices differ, so rays follow the places
   where the lens maps incoming rays very differently (high curvature, more
   interfaces, total internal reflection) and nowhere else.

   Stages: mark the mesh's front-facing triangles and trace their vertices
   (a seam's twin vertices, at one position with one normal, welded so
   both sides share their edges);
   then, one level at a time, decide for every pending triangle whether it
   splits and which of its edges (those projected at least edge_px long),
   creating each edge midpoint once through the edge table, trace the
   level's new vertices in parallel, and queue the children; finally every
   leaf collects the vertices its neighbours put on its edges (recursive
   queries of the edge table) and is re-triangulated around them: a fan
   from a corner whose two edges are whole, else from a new, traced centre
   vertex. Decisions are made in a fixed order and tracing only fills in
   vertices already placed, so any thread count gives the same mesh. */
#include "internal.h"

/* What a vertex keeps besides its public record: the surface it lies on
   (for tracing from it). */
typedef struct refl__lt_vertex {
    refl_vec3 face_normal;       /* of a front-facing triangle it lies on (world, unit) */
    float magnitude;             /* largest |coordinate| of that triangle */
    int triangle;                /* that triangle, in the mesh */
} refl__lt_vertex;

typedef struct refl__lt_tri {
    uint32_t v[3];
    int level;
    refl__lt_vertex surface;     /* the mesh triangle it is part of */
} refl__lt_tri;

typedef struct refl__lt {
    const refl_scene *scene;
    refl__gp_casters casters;
    const refl_material *material;
    int object;
    refl_vec3 eye, forward;
    refl_mat4 view_proj;
    int width, height;
    float cos_angle, edge_px;
    int max_level, max_interfaces;
    long long max_vertices;      /* past this no triangle splits (refl__lt_vertex_budget) */
    const refl_allocator *al;
    refl_lens_vertex *v;
    refl__lt_vertex *vx;
    int vcount, vcap;
    refl__lt_tri *tris;          /* pending, then leaves, grown as needed */
    int tcount, tcap;
    uint64_t *keys;              /* edge table: (min << 32 | max) + 1, 0 empty */
    uint32_t *mids;
    size_t hcap, hcount;
    long long *chunk_rays;
    int trace_first;             /* the vertices a tracing job covers start here */
} refl__lt;

enum { REFL__LT_CHUNK = 32 };

/* The vertices past which no triangle splits: the mesh's and 16 per
   pixel of the view (the default t, 1 pixel, makes one or two per lens
   pixel), so that a t or angle near 0, which would split every triangle
   to max_level, stays bounded in memory and time (the leaves' centre
   vertices come on top, at most one each). */
enum { REFL__LT_VERTICES_PER_PIXEL = 16 };
static long long refl__lt_vertex_budget(int width, int height, int mesh_vertices) {
    long long px = (long long)width * (long long)height;
    return REFL__MIN(REFL__LT_VERTICES_PER_PIXEL * px, 1LL << 28) + mesh_vertices;
}

static int refl__lt_grow(const refl_allocator *al, void **arr, int *cap, int need, size_t size) {
    void *n;
    int c = *cap ? *cap : 64;
    if (need <= *cap) return 1;
    while (c < need) {
        if (c > (1 << 28)) return 0;
        c *= 2;
    }
    n = refl__calloc(al, (size_t)c, size);
    if (!n) return 0;
    if (*arr) memcpy(n, *arr, (size_t)*cap * size);
    refl__free(al, *arr);
    *arr = n;
    *cap = c;
    return 1;
}

/* A new, untraced vertex: -1 when out of memory. */
static int refl__lt_add_vertex(refl__lt *t, refl_vec3 p, refl_vec3 n, refl__lt_vertex surface, int level) {
    int cap = t->vcap;
    refl_lens_vertex *v;
    if (t->vcount >= cap) {
        if (!refl__lt_grow(t->al, (void **)&t->v, &t->vcap, t->vcount + 1, sizeof *t->v)) return -1;
        if (!refl__lt_grow(t->al, (void **)&t->vx, &cap, t->vcount + 1, sizeof *t->vx)) return -1;
    }
    v = &t->v[t->vcount];
    memset(v, 0, sizeof *v);
    v->position = p;
    v->normal = refl_v3_normalize(n);
    v->level = level;
    t->vx[t->vcount] = surface;
    return t->vcount++;
}

/* ---- the edge table ---------------------------------------------------------- */

static uint64_t refl__lt_key(uint32_t a, uint32_t b) {
    return a < b ? ((uint64_t)a << 32 | b) + 1 : ((uint64_t)b << 32 | a) + 1;
}

static size_t refl__lt_slot(const refl__lt *t, uint64_t key) {
    size_t h = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 17) & (t->hcap - 1);
    while (t->keys[h] && t->keys[h] != key) h = (h + 1) & (t->hcap - 1);
    return h;
}

/* The midpoint recorded for edge (a, b), or -1. */
static int refl__lt_mid_get(const refl__lt *t, uint32_t a, uint32_t b) {
    size_t h;
    if (!t->hcap) return -1;
    h = refl__lt_slot(t, refl__lt_key(a, b));
    return t->keys[h] ? (int)t->mids[h] : -1;
}

static int refl__lt_mid_put(refl__lt *t, uint32_t a, uint32_t b, uint32_t m) {
    size_t h, i;
    if (2 * (t->hcount + 1) > t->hcap) { /* grow to keep it half empty */
        uint64_t *ok = t->keys;
        uint32_t *om = t->mids;
        size_t oc = t->hcap;
        t->hcap = oc ? 2 * oc : 1024;
        t->keys = (uint64_t *)refl__calloc(t->al, t->hcap, sizeof *t->keys);
        t->mids = (uint32_t *)refl__calloc(t->al, t->hcap, sizeof *t->mids);
        if (!t->keys || !t->mids) {
            refl__free(t->al, ok);
            refl__free(t->al, om);
            return 0;
        }
        for (i = 0; i < oc; ++i)
            if (ok[i]) {
                h = refl__lt_slot(t, ok[i]);
                t->keys[h] = ok[i];
                t->mids[h] = om[i];
            }
        refl__free(t->al, ok);
        refl__free(t->al, om);
    }
    h = refl__lt_slot(t, refl__lt_key(a, b));
    t->keys[h] = refl__lt_key(a, b);
    t->mids[h] = m;
    ++t->hcount;
    return 1;
}

/* Edge (a, b)'s midpoint, made (untraced) on first use: -1 out of memory. */
static int refl__lt_midpoint(refl__lt *t, uint32_t a, uint32_t b, int level, refl__lt_vertex surface) {
    int m = refl__lt_mid_get(t, a, b);
    if (m >= 0) return m;
    m = refl__lt_add_vertex(t, refl_v3_scale(refl_v3_add(t->v[a].position, t->v[b].position), 0.5f),
                            refl_v3_add(t->v[a].normal, t->v[b].normal), surface, level);
    if (m < 0 || !refl__lt_mid_put(t, a, b, (uint32_t)m)) return -1;
    return m;
}

/* ---- tracing ----------------------------------------------------------------- */

/* Vertex i: its window position, visibility and both greedy paths, from
   the vertex itself as the first interface. */
static void refl__lt_trace_vertex(const refl__lt *t, int i, long long *rays) {
    refl_lens_vertex *v = &t->v[i];
    const refl__lt_vertex *x = &t->vx[i];
    const refl__gp_casters *c = &t->casters;
    refl_vec3 to = refl_v3_sub(v->position, t->eye), d, w;
    float dist = refl_v3_length(to), near = dist * (1.0f - 1e-4f);
    refl__gp_hit h;
    d = dist > 0.0f ? refl_v3_scale(to, 1.0f / dist) : t->forward;
    v->window[0] = v->window[1] = NAN;
    if (refl_v3_dot(to, t->forward) > 0.0f) {
        w = refl_mat4_point(t->view_proj, v->position);
        v->window[0] = (w.x * 0.5f + 0.5f) * (float)t->width;
        v->window[1] = (0.5f - w.y * 0.5f) * (float)t->height;
    }
    ++*rays;
    /* split: the same triangles in two BVHs, each asked */
    v->visible = c->lenses && c->others ? !refl__caster_blocked(c->others, t->eye, d, near) &&
                                              !refl__caster_blocked(c->lenses, t->eye, d, near)
                                        : !refl__caster_blocked(c->scene, t->eye, d, near);
    refl__greedy_paths_none(t->eye, d, &v->paths);
    h.p = v->position;
    h.ng = x->face_normal;
    h.ns = v->normal;
    h.magnitude = x->magnitude;
    h.material = t->material;
    h.object = t->object;
    h.triangle = x->triangle;
    h.t = dist;
    refl__greedy_paths_from(t->scene, &t->casters, d, &h, t->max_interfaces, &v->paths, rays);
}

static void refl__lt_trace_job(void *arg, int job) {
    refl__lt *t = (refl__lt *)arg;
    int i = t->trace_first + job * REFL__LT_CHUNK, end = REFL__MIN(i + REFL__LT_CHUNK, t->vcount);
    long long rays = 0;
    for (; i < end; ++i) refl__lt_trace_vertex(t, i, &rays);
    t->chunk_rays[job] = rays;
}

/* Traces vertices [first, vcount) on rc's threads; the rays and the time
   go into out's counts. */
static int refl__lt_trace(refl__lt *t, rast_context *rc, int first, refl_lens_tess *out) {
    int jobs = (t->vcount - first + REFL__LT_CHUNK - 1) / REFL__LT_CHUNK, j;
    double t0 = refl__now_ms();
    if (jobs <= 0) return 1;
    t->chunk_rays = (long long *)refl__calloc(t->al, (size_t)jobs, sizeof(long long));
    if (!t->chunk_rays) return 0;
    t->trace_first = first;
    rast_run_jobs(rc, jobs, refl__lt_trace_job, t);
    for (j = 0; j < jobs; ++j) out->rays += t->chunk_rays[j];
    refl__free(t->al, t->chunk_rays);
    t->chunk_rays = NULL;
    out->ms_trace += refl__now_ms() - t0;
    return 1;
}

/* ---- the split criterion ----------------------------------------------------- */

/* Whether two vertices' paths differ: 2 in topology, 1 only by the angle
   between exit rays, 0 not. */
static int refl__lt_path_differs(const refl__lt *t, const refl_greedy_path *a, const refl_greedy_path *b,
                                 int a_has, int b_has) {
    if (a_has != b_has) return 2;
    if (!a_has) return 0;
    if (a->exited != b->exited || a->length != b->length || a->reflected != b->reflected) return 2;
    return refl_v3_dot(a->exit_direction, b->exit_direction) < t->cos_angle ? 1 : 0;
}

static int refl__lt_differs(const refl__lt *t, const refl_lens_vertex *a, const refl_lens_vertex *b) {
    const refl_greedy_paths_result *p = &a->paths, *q = &b->paths;
    int r, tt;
    if (p->terms != q->terms) return 2;
    r = refl__lt_path_differs(t, &p->reflect, &q->reflect, p->terms > 0, q->terms > 0);
    tt = refl__lt_path_differs(t, &p->refract, &q->refract, p->refract.fresnel > 0.0f, q->refract.fresnel > 0.0f);
    return REFL__MAX(r, tt);
}

static float refl__lt_edge_px(const refl__lt *t, uint32_t a, uint32_t b) {
    float dx = t->v[a].window[0] - t->v[b].window[0], dy = t->v[a].window[1] - t->v[b].window[1];
    float len = sqrtf(dx * dx + dy * dy);
    return len == len ? len : 0.0f; /* behind the eye: never split for size */
}

/* ---- T-junctions ------------------------------------------------------------- */

/* Appends the vertices strictly inside edge (a, b), in order from a. */
static int refl__lt_collect(const refl__lt *t, uint32_t a, uint32_t b, uint32_t *out, int n, int cap) {
    int m = refl__lt_mid_get(t, a, b);
    if (m < 0 || n >= cap) return n;
    n = refl__lt_collect(t, a, (uint32_t)m, out, n, cap);
    if (n < cap) out[n++] = (uint32_t)m;
    return refl__lt_collect(t, (uint32_t)m, b, out, n, cap);
}

static int refl__lt_emit(const refl__lt *t, uint32_t **idx, int *count, int *cap, uint32_t a, uint32_t b,
                         uint32_t c) {
    if (!refl__lt_grow(t->al, (void **)idx, cap, 3 * (*count + 1), sizeof(uint32_t))) return 0;
    (*idx)[3 * *count] = a;
    (*idx)[3 * *count + 1] = b;
    (*idx)[3 * *count + 2] = c;
    ++*count;
    return 1;
}

/* ---- the whole ---------------------------------------------------------------- */

static void refl__lt_free(refl__lt *t) {
    refl__free(t->al, t->vx);
    refl__free(t->al, t->tris);
    refl__free(t->al, t->keys);
    refl__free(t->al, t->mids);
    refl__free(t->al, t->chunk_rays);
}

/* Splits the pending triangles [first, end) of t->tris one level: appends
   their children and moves the leaves to leaves[]. */
static int refl__lt_level(refl__lt *t, refl_lens_tess *out, int first, int end, refl__lt_tri **leaves, int *nleaves,
                          int *leaf_cap) {
    int i, k;
    for (i = first; i < end; ++i) {
        refl__lt_tri tri = t->tris[i];
        uint32_t *v = tri.v;
        int differ = 0, hidden = !t->v[v[0]].visible && !t->v[v[1]].visible && !t->v[v[2]].visible;
        int longe[3], nlong = 0, m[3] = {-1, -1, -1}, r;
        for (k = 0; k < 3; ++k) differ = REFL__MAX(differ, refl__lt_differs(t, &t->v[v[k]], &t->v[v[(k + 1) % 3]]));
        for (k = 0; k < 3; ++k) nlong += longe[k] = refl__lt_edge_px(t, v[k], v[(k + 1) % 3]) >= t->edge_px;
        if (!differ || hidden || tri.level >= t->max_level || nlong == 0 || t->vcount >= t->max_vertices) {
            if (!refl__lt_grow(t->al, (void **)leaves, leaf_cap, *nleaves + 1, sizeof **leaves)) return 0;
            (*leaves)[(*nleaves)++] = tri;
            continue;
        }
        ++out->splits;
        if (differ == 2) ++out->topology_splits;
        for (k = 0; k < 3; ++k)
            if (longe[k]) {
                m[k] = refl__lt_midpoint(t, v[k], v[(k + 1) % 3], tri.level + 1, tri.surface);
                if (m[k] < 0) return 0;
            }
        /* children, wound as the parent: rotate so the split edges come first
           (one: edge 0; two: edges 0 and 1) */
        for (r = 0; r < 3 && nlong < 3; ++r) {
            int ok = nlong == 1 ? m[0] >= 0 : (m[0] >= 0 && m[1] >= 0);
            if (ok) break;
            {
                uint32_t sv = v[0];
                int sm = m[0];
                v[0] = v[1], v[1] = v[2], v[2] = sv;
                m[0] = m[1], m[1] = m[2], m[2] = sm;
            }
        }
        if (!refl__lt_grow(t->al, (void **)&t->tris, &t->tcap, t->tcount + 4, sizeof *t->tris)) return 0;
        {
            refl__lt_tri *c = t->tris + t->tcount;
            uint32_t a = v[0], b = v[1], cc = v[2];
            int lv = tri.level + 1;
            uint32_t m0 = (uint32_t)m[0], m1 = (uint32_t)m[1], m2 = (uint32_t)m[2];
            int n = 0;
#define REFL__LT_CHILD(x, y, z) \
    (c[n].v[0] = (x), c[n].v[1] = (y), c[n].v[2] = (z), c[n].level = lv, c[n].surface = tri.surface, ++n)
            if (nlong == 3) {
                REFL__LT_CHILD(a, m0, m2);
                REFL__LT_CHILD(m0, b, m1);
                REFL__LT_CHILD(m2, m1, cc);
                REFL__LT_CHILD(m0, m1, m2);
            } else if (nlong == 2) { /* edges ab and bc split, ca whole */
                REFL__LT_CHILD(m0, b, m1);
                REFL__LT_CHILD(a, m0, m1);
                REFL__LT_CHILD(a, m1, cc);
            } else {
                REFL__LT_CHILD(a, m0, cc);
                REFL__LT_CHILD(m0, b, cc);
            }
#undef REFL__LT_CHILD
            t->tcount += n;
        }
    }
    return 1;
}

/* The leaves, re-triangulated around the vertices on their edges. */
static int refl__lt_conform(refl__lt *t, rast_context *rc, refl_lens_tess *out, const refl__lt_tri *leaves,
                            int nleaves) {
    enum { CAP = 3 * 4096 };
    uint32_t *poly = (uint32_t *)refl__calloc(t->al, CAP + 3, sizeof(uint32_t));
    uint32_t *idx = NULL;
    int count = 0, cap = 0, i, k, first_centre = t->vcount, ok = 1;
    if (!poly) return 0;
    for (i = 0; i < nleaves && ok; ++i) {
        const uint32_t *v = leaves[i].v;
        int n = 0, corner[3], inner[3], j, fan = -1;
        for (k = 0; k < 3; ++k) {
            int before = n;
            corner[k] = n;
            poly[n++] = v[k];
            n = refl__lt_collect(t, v[k], v[(k + 1) % 3], poly, n, CAP);
            inner[k] = n - before - 1;
        }
        if (!inner[0] && !inner[1] && !inner[2]) {
            ok = refl__lt_emit(t, &idx, &count, &cap, v[0], v[1], v[2]);
            continue;
        }
        ++out->junction_fixes;
        for (k = 0; k < 3 && fan < 0; ++k)
            if (!inner[k] && !inner[(k + 2) % 3]) fan = corner[k]; /* both edges at corner k whole */
        if (fan >= 0) {
            for (j = 1; j + 1 < n && ok; ++j)
                ok = refl__lt_emit(t, &idx, &count, &cap, poly[fan], poly[(fan + j) % n], poly[(fan + j + 1) % n]);
        } else {
            refl_vec3 p = refl_v3_scale(
                refl_v3_add(refl_v3_add(t->v[v[0]].position, t->v[v[1]].position), t->v[v[2]].position), 1.0f / 3.0f);
            refl_vec3 nn = refl_v3_add(refl_v3_add(t->v[v[0]].normal, t->v[v[1]].normal), t->v[v[2]].normal);
            int c = refl__lt_add_vertex(t, p, nn, leaves[i].surface, leaves[i].level + 1);
            if (c < 0) ok = 0;
            for (j = 0; j < n && ok; ++j)
                ok = refl__lt_emit(t, &idx, &count, &cap, (uint32_t)c, poly[j], poly[(j + 1) % n]);
        }
    }
    refl__free(t->al, poly);
    if (ok) ok = refl__lt_trace(t, rc, first_centre, out);
    out->indices = idx;
    out->triangle_count = count;
    return ok;
}

/* The tessellation's vertex for mesh vertex (p, n): one already made at
   exactly p with a normal within 25 degrees (a seam's twin), else a new
   one; -1 out of memory. weld: 2^k slots of vertex ids (-1 empty). */
static int refl__lt_weld(refl__lt *t, int *weld, size_t cap, refl_vec3 p, refl_vec3 n, refl__lt_vertex surface) {
    uint32_t b[3];
    size_t h;
    memcpy(&b[0], &p.x, 4);
    memcpy(&b[1], &p.y, 4);
    memcpy(&b[2], &p.z, 4);
    h = (size_t)(((uint64_t)b[0] * 0x9E3779B97F4A7C15ull ^ (uint64_t)b[1] * 0xC2B2AE3D27D4EB4Full ^
                  (uint64_t)b[2] * 0x165667B19E3779F9ull) >> 20) & (cap - 1);
    for (; weld[h] >= 0; h = (h + 1) & (cap - 1)) {
        const refl_lens_vertex *v = &t->v[weld[h]];
        if (v->position.x == p.x && v->position.y == p.y && v->position.z == p.z &&
            refl_v3_dot(v->normal, refl_v3_normalize(n)) >= 0.9f)
            return weld[h];
    }
    weld[h] = refl__lt_add_vertex(t, p, n, surface, 0);
    return weld[h];
}

static refl_result refl__lens_tessellate(const refl_scene *scene, const refl__gp_casters *casters, int object,
                                         const refl_view *view, const refl_lens_tess_desc *desc, rast_context *rc,
                                         refl_lens_tess *out) {
    const refl_object *obj = &scene->objects[object];
    const refl_mesh *mesh = scene->meshes[obj->mesh];
    refl_mat4 nm = refl__normal_matrix(obj->transform), vm, pm;
    refl__lt t;
    int *map = NULL, *weld = NULL, i, k, first = 0, nleaves = 0, leaf_cap = 0;
    size_t weld_cap = 16;
    refl__lt_tri *leaves = NULL;
    refl_result r = REFL_ERROR_OUT_OF_MEMORY;
    float angle = desc && desc->angle_degrees > 0.0f ? desc->angle_degrees : 3.0f;
    memset(&t, 0, sizeof t);
    t.scene = scene;
    t.casters = *casters;
    t.material = &scene->materials[obj->material];
    t.object = object;
    t.eye = view->eye;
    t.forward = refl_v3_normalize(refl_v3_sub(view->target, view->eye));
    refl_view_matrices(view, scene, &vm, &pm);
    t.view_proj = refl_mat4_mul(pm, vm);
    t.width = view->width;
    t.height = view->height;
    t.cos_angle = cosf(REFL__MIN(angle, 180.0f) * (float)(REFL__PI / 180.0));
    t.edge_px = desc && desc->edge_px > 0.0f ? desc->edge_px : 1.0f;
    t.max_level = desc && desc->max_level > 0 ? REFL__MIN(desc->max_level, 30) : 12;
    t.max_interfaces = desc ? desc->max_interfaces : 0;
    t.max_vertices = refl__lt_vertex_budget(view->width, view->height, mesh->vertex_count);
    t.al = &out->allocator;
    map = (int *)refl__calloc(t.al, (size_t)REFL__MAX(mesh->vertex_count, 1), sizeof(int));
    if (!map) goto done;
    while (weld_cap < 2 * (size_t)mesh->vertex_count) weld_cap *= 2;
    weld = (int *)refl__calloc(t.al, weld_cap, sizeof(int));
    if (!weld) goto done;
    for (i = 0; i < mesh->vertex_count; ++i) map[i] = -1;
    for (i = 0; i < (int)weld_cap; ++i) weld[i] = -1;
    /* the front-facing triangles and their vertices, each once */
    for (i = 0; i < mesh->triangle_count; ++i) {
        const uint32_t *tri = mesh->indices + 3 * (size_t)i;
        refl_vec3 p[3], n;
        refl__lt_vertex x;
        refl__lt_tri lt;
        for (k = 0; k < 3; ++k)
            p[k] = refl_mat4_point(obj->transform, refl_v3(mesh->positions[3 * (size_t)tri[k]],
                                                          mesh->positions[3 * (size_t)tri[k] + 1],
                                                          mesh->positions[3 * (size_t)tri[k] + 2]));
        n = refl_v3_cross(refl_v3_sub(p[1], p[0]), refl_v3_sub(p[2], p[0]));
        if (!(refl_v3_dot(n, n) > 0.0f) || refl_v3_dot(n, refl_v3_sub(t.eye, p[0])) <= 0.0f) continue;
        x.face_normal = refl_v3_normalize(n);
        x.triangle = i;
        x.magnitude = 0.0f;
        for (k = 0; k < 3; ++k)
            x.magnitude = REFL__MAX(x.magnitude, REFL__MAX(fabsf(p[k].x), REFL__MAX(fabsf(p[k].y), fabsf(p[k].z))));
        for (k = 0; k < 3; ++k) {
            if (map[tri[k]] < 0) {
                const float *mn = mesh->normals + 3 * (size_t)tri[k];
                map[tri[k]] = refl__lt_weld(&t, weld, weld_cap, p[k], refl_mat4_dir(nm, refl_v3(mn[0], mn[1], mn[2])), x);
                if (map[tri[k]] < 0) goto done;
            }
            lt.v[k] = (uint32_t)map[tri[k]];
        }
        lt.level = 0;
        lt.surface = x;
        if (!refl__lt_grow(t.al, (void **)&t.tris, &t.tcap, t.tcount + 1, sizeof *t.tris)) goto done;
        t.tris[t.tcount++] = lt;
        ++out->front_triangles;
    }
    if (!refl__lt_trace(&t, rc, 0, out)) goto done;
    /* level by level: decide in order, then trace the level's new vertices */
    while (first < t.tcount) {
        int end = t.tcount, traced = t.vcount;
        if (!refl__lt_level(&t, out, first, end, &leaves, &nleaves, &leaf_cap)) goto done;
        if (!refl__lt_trace(&t, rc, traced, out)) goto done;
        first = end;
    }
    if (!refl__lt_conform(&t, rc, out, leaves, nleaves)) goto done;
    r = REFL_OK;
done:
    out->vertices = t.v;
    out->vertex_count = t.vcount;
    refl__free(t.al, map);
    refl__free(t.al, weld);
    refl__free(t.al, leaves);
    refl__lt_free(&t);
    return r;
}

REFL_API void refl_lens_tess_destroy(refl_lens_tess *tess) {
    refl_allocator al;
    if (!tess) return;
    al = tess->allocator;
    refl__free(&al, tess->vertices);
    refl__free(&al, tess->indices);
    refl__free(&al, tess);
}

REFL_API refl_result refl_lens_tessellate(const refl_scene *scene, const refl_ray_caster *caster, int object,
                                          const refl_view *view, const refl_lens_tess_desc *desc,
                                          refl_lens_tess **out) {
    rast_context_desc cd;
    rast_context *rc = NULL;
    refl_lens_tess *t;
    refl__gp_casters casters;
    refl_result r;
    if (out) *out = NULL;
    if (!scene || !caster || !caster->intersect || !view || !out || object < 0 || object >= scene->object_count)
        return REFL_ERROR_INVALID_ARGUMENT;
    if (view->width <= 0 || view->height <= 0) return REFL_ERROR_INVALID_SIZE;
    if (!refl__v3_finite(view->eye) || !refl__v3_finite(view->target)) return REFL_ERROR_INVALID_ARGUMENT;
    if (!refl__is_reflector(&scene->materials[scene->objects[object].material])) return REFL_ERROR_INVALID_ARGUMENT;
    t = (refl_lens_tess *)refl__calloc(&scene->allocator, 1, sizeof *t);
    if (!t) return REFL_ERROR_OUT_OF_MEMORY;
    t->allocator = scene->allocator;
    memset(&cd, 0, sizeof cd);
    cd.num_threads = desc ? desc->threads : 0;
    if (rast_context_create(&cd, &rc) != RAST_OK) {
        refl_lens_tess_destroy(t);
        return REFL_ERROR_RASTER;
    }
    casters.scene = caster;
    casters.lenses = NULL;
    casters.own = -1;
    r = refl__lens_tessellate(scene, &casters, object, view, desc, rc, t);
    rast_context_destroy(rc);
    if (r != REFL_OK) {
        refl_lens_tess_destroy(t);
        return r;
    }
    *out = t;
    return REFL_OK;
}
