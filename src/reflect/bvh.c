/* bvh: a bounding volume hierarchy over the scene's world-space triangles,
   for the RAYTRACE reference and every method that needs exact rays.
   Build: binned SAH (Wald 2007), iterative, deterministic. Traversal:
   explicit stack, nearer child first. Triangles: the watertight test of
   Woop, Benthin and Wald 2013, so rays never slip through shared edges. */
#include "internal.h"

#define REFL__BVH_BINS 16
#define REFL__BVH_LEAF 4          /* always a leaf at or below this many */
#define REFL__BVH_MAX_LEAF 32     /* never a leaf above this, unless too deep */
#define REFL__BVH_MAX_DEPTH 60    /* keeps traversal within its 64-entry stack */
#define REFL__BVH_STACK 64

/* 32 bytes: children are adjacent, so one index names both. */
typedef struct refl__bvh_node {
    float lo[3], hi[3];
    int32_t index;                /* interior: first child; leaf: first in order[] */
    int32_t count;                /* 0: interior; else triangles in the leaf */
} refl__bvh_node;

typedef struct refl__bvh_tri {
    float v[9];                   /* world-space vertices 0, 1, 2 */
    int32_t object, triangle;
} refl__bvh_tri;

struct refl_bvh {
    refl_allocator allocator;
    refl__bvh_node *nodes;
    int node_count;
    refl__bvh_tri *tris;
    int32_t *order;               /* leaf ranges index this; entries index tris */
    int tri_count;
};

/* ---- build ------------------------------------------------------------------ */

typedef struct refl__bvh_box { float lo[3], hi[3]; } refl__bvh_box;

static void refl__box_empty(refl__bvh_box *b) {
    int k;
    for (k = 0; k < 3; ++k) { b->lo[k] = FLT_MAX; b->hi[k] = -FLT_MAX; }
}

static void refl__box_grow(refl__bvh_box *b, const float *p) {
    int k;
    for (k = 0; k < 3; ++k) {
        b->lo[k] = REFL__MIN(b->lo[k], p[k]);
        b->hi[k] = REFL__MAX(b->hi[k], p[k]);
    }
}

static void refl__box_merge(refl__bvh_box *b, const refl__bvh_box *o) {
    int k;
    for (k = 0; k < 3; ++k) {
        b->lo[k] = REFL__MIN(b->lo[k], o->lo[k]);
        b->hi[k] = REFL__MAX(b->hi[k], o->hi[k]);
    }
}

/* Half the surface area; an empty box (lo > hi) has none. */
static float refl__box_area(const refl__bvh_box *b) {
    float dx = b->hi[0] - b->lo[0], dy = b->hi[1] - b->lo[1], dz = b->hi[2] - b->lo[2];
    if (dx < 0 || dy < 0 || dz < 0) return 0;
    return dx * dy + dy * dz + dz * dx;
}

static void refl__tri_box(const refl__bvh_tri *t, refl__bvh_box *b) {
    refl__box_empty(b);
    refl__box_grow(b, t->v);
    refl__box_grow(b, t->v + 3);
    refl__box_grow(b, t->v + 6);
}

/* The bin of a centroid coordinate; binning and partitioning must agree,
   so both go through here. */
static int refl__bvh_bin(float c, float cmin, float scale) {
    float f = (c - cmin) * scale;
    if (!(f > 0)) return 0;       /* clamp in float: converting a huge value is undefined */
    if (f >= (float)(REFL__BVH_BINS - 1)) return REFL__BVH_BINS - 1;
    return (int)f;
}

typedef struct refl__bvh_task { int node, begin, end, depth; } refl__bvh_task;

static void refl__bvh_build_tree(refl_bvh *bvh, const float *centroid) {
    refl__bvh_task stack[2 * REFL__BVH_MAX_DEPTH + 8];
    int sp = 0;
    bvh->node_count = 1;
    stack[sp].node = 0; stack[sp].begin = 0; stack[sp].end = bvh->tri_count; stack[sp].depth = 0;
    ++sp;
    while (sp > 0) {
        refl__bvh_task task = stack[--sp];
        refl__bvh_node *node = &bvh->nodes[task.node];
        int n = task.end - task.begin, i, k, axis = -1, split_bin = 0, mid;
        refl__bvh_box box, cbox;
        float best_cost = FLT_MAX, leaf_cost, scale = 0;

        refl__box_empty(&box);
        refl__box_empty(&cbox);
        for (i = task.begin; i < task.end; ++i) {
            refl__bvh_box tb;
            int t = bvh->order[i];
            refl__tri_box(&bvh->tris[t], &tb);
            refl__box_merge(&box, &tb);
            refl__box_grow(&cbox, centroid + 3 * t);
        }
        for (k = 0; k < 3; ++k) { node->lo[k] = box.lo[k]; node->hi[k] = box.hi[k]; }
        node->index = task.begin;
        node->count = n;
        if (n <= REFL__BVH_LEAF || task.depth >= REFL__BVH_MAX_DEPTH) continue;

        /* SAH with traversal cost 1 and intersection cost 1, relative to
           the parent's area: a leaf costs n. */
        leaf_cost = (float)n;
        for (k = 0; k < 3; ++k) {
            refl__bvh_box bins[REFL__BVH_BINS], acc;
            int counts[REFL__BVH_BINS], b, left_n;
            float right_area[REFL__BVH_BINS], extent = cbox.hi[k] - cbox.lo[k], s, parea;
            int right_n[REFL__BVH_BINS];
            if (!(extent > 0)) continue;
            s = (float)REFL__BVH_BINS * (1.0f - 1e-6f) / extent;
            if (!refl__isfinite(s)) continue; /* denormal extent */
            for (b = 0; b < REFL__BVH_BINS; ++b) { refl__box_empty(&bins[b]); counts[b] = 0; }
            for (i = task.begin; i < task.end; ++i) {
                refl__bvh_box tb;
                int t = bvh->order[i];
                b = refl__bvh_bin(centroid[3 * t + k], cbox.lo[k], s);
                refl__tri_box(&bvh->tris[t], &tb);
                refl__box_merge(&bins[b], &tb);
                counts[b]++;
            }
            /* Sweep from the right, then from the left: split after bin b. */
            refl__box_empty(&acc);
            right_n[REFL__BVH_BINS - 1] = 0;
            right_area[REFL__BVH_BINS - 1] = 0;
            {
                int rn = 0;
                for (b = REFL__BVH_BINS - 1; b > 0; --b) {
                    refl__box_merge(&acc, &bins[b]);
                    rn += counts[b];
                    right_n[b - 1] = rn;
                    right_area[b - 1] = refl__box_area(&acc);
                }
            }
            parea = refl__box_area(&box);
            refl__box_empty(&acc);
            left_n = 0;
            for (b = 0; b < REFL__BVH_BINS - 1; ++b) {
                float cost;
                refl__box_merge(&acc, &bins[b]);
                left_n += counts[b];
                if (left_n == 0 || right_n[b] == 0) continue;
                cost = parea > 0
                           ? 1.0f + (refl__box_area(&acc) * (float)left_n + right_area[b] * (float)right_n[b]) / parea
                           : 1.0f + (float)n; /* flat cluster: any split is as good */
                if (cost < best_cost) { best_cost = cost; axis = k; split_bin = b; scale = s; }
            }
        }
        if (axis >= 0 && best_cost >= leaf_cost && n <= REFL__BVH_MAX_LEAF) continue;

        if (axis >= 0) {
            /* In-place partition by bin; both sides are non-empty by construction. */
            int lo = task.begin, hi = task.end - 1;
            while (lo <= hi) {
                int t = bvh->order[lo];
                if (refl__bvh_bin(centroid[3 * t + axis], cbox.lo[axis], scale) <= split_bin) {
                    ++lo;
                } else {
                    bvh->order[lo] = bvh->order[hi];
                    bvh->order[hi] = t;
                    --hi;
                }
            }
            mid = lo;
            if (mid == task.begin || mid == task.end) mid = task.begin + n / 2;
        } else {
            /* Every centroid coincides: no axis separates them, so halve the range. */
            mid = task.begin + n / 2;
        }

        node->index = bvh->node_count;
        node->count = 0;
        bvh->node_count += 2;
        /* Left on top, so it is built first: nodes land in depth-first order. */
        stack[sp].node = node->index + 1; stack[sp].begin = mid; stack[sp].end = task.end;
        stack[sp].depth = task.depth + 1;
        ++sp;
        stack[sp].node = node->index; stack[sp].begin = task.begin; stack[sp].end = mid;
        stack[sp].depth = task.depth + 1;
        ++sp;
    }
}

static int refl__tri_ok(const float *v) {
    int k;
    double e1[3], e2[3], c[3];
    for (k = 0; k < 9; ++k)
        if (!refl__isfinite(v[k])) return 0;
    for (k = 0; k < 3; ++k) { e1[k] = (double)v[3 + k] - v[k]; e2[k] = (double)v[6 + k] - v[k]; }
    c[0] = e1[1] * e2[2] - e1[2] * e2[1];
    c[1] = e1[2] * e2[0] - e1[0] * e2[2];
    c[2] = e1[0] * e2[1] - e1[1] * e2[0];
    return c[0] != 0 || c[1] != 0 || c[2] != 0;
}

REFL_API void refl_bvh_destroy(refl_bvh *bvh) {
    refl_allocator a;
    if (!bvh) return;
    a = bvh->allocator;
    refl__free(&a, bvh->nodes);
    refl__free(&a, bvh->tris);
    refl__free(&a, bvh->order);
    refl__free(&a, bvh);
}

REFL_API refl_result refl_bvh_build(const refl_scene *scene, const refl_allocator *a, refl_bvh **out_bvh) {
    refl_bvh *bvh;
    float *centroid = NULL;
    long long total = 0;
    int i, n = 0;

    if (out_bvh) *out_bvh = NULL;
    if (!scene || !out_bvh) return REFL_ERROR_INVALID_ARGUMENT;
    if (scene->object_count < 0 || (scene->object_count > 0 && !scene->objects))
        return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < scene->object_count; ++i) {
        int m = scene->objects[i].mesh;
        const refl_mesh *mesh;
        if (m < 0 || m >= scene->mesh_count || !scene->meshes || !scene->meshes[m]) return REFL_ERROR_BAD_MESH;
        mesh = scene->meshes[m];
        if (mesh->triangle_count < 0 || (mesh->triangle_count > 0 && (!mesh->positions || !mesh->indices)))
            return REFL_ERROR_BAD_MESH;
        total += mesh->triangle_count;
    }
    /* 2n - 1 nodes must fit an int32 index. */
    if (total > INT_MAX / 4) return REFL_ERROR_INVALID_SIZE;

    bvh = (refl_bvh *)refl__calloc(a, 1, sizeof *bvh);
    if (!bvh) return REFL_ERROR_OUT_OF_MEMORY;
    bvh->allocator = refl__allocator(a);
    if (total == 0) { *out_bvh = bvh; return REFL_OK; }

    bvh->tris = (refl__bvh_tri *)refl__calloc(a, (size_t)total, sizeof *bvh->tris);
    if (!bvh->tris) { refl_bvh_destroy(bvh); return REFL_ERROR_OUT_OF_MEMORY; }

    /* World space once, so triangles sharing a vertex share its exact
       floats: the watertight test relies on that. */
    for (i = 0; i < scene->object_count; ++i) {
        const refl_object *o = &scene->objects[i];
        const refl_mesh *mesh = scene->meshes[o->mesh];
        int t, j;
        for (t = 0; t < mesh->triangle_count; ++t) {
            refl__bvh_tri *dst = &bvh->tris[n];
            int bad = 0;
            for (j = 0; j < 3; ++j) {
                uint32_t vi = mesh->indices[3 * t + j];
                const float *p;
                refl_vec3 w;
                if (vi >= (uint32_t)mesh->vertex_count) { bad = 1; break; }
                p = mesh->positions + 3 * (size_t)vi;
                w = refl_mat4_point(o->transform, refl_v3(p[0], p[1], p[2]));
                dst->v[3 * j] = w.x; dst->v[3 * j + 1] = w.y; dst->v[3 * j + 2] = w.z;
            }
            if (bad) { refl_bvh_destroy(bvh); return REFL_ERROR_BAD_MESH; }
            if (!refl__tri_ok(dst->v)) continue;
            dst->object = i;
            dst->triangle = t;
            ++n;
        }
    }
    bvh->tri_count = n;
    if (n == 0) { *out_bvh = bvh; return REFL_OK; }

    bvh->order = (int32_t *)refl__calloc(a, (size_t)n, sizeof *bvh->order);
    bvh->nodes = (refl__bvh_node *)refl__calloc(a, (size_t)(2 * n - 1), sizeof *bvh->nodes);
    centroid = (float *)refl__calloc(a, (size_t)n * 3, sizeof *centroid);
    if (!bvh->order || !bvh->nodes || !centroid) {
        refl__free(a, centroid);
        refl_bvh_destroy(bvh);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < n; ++i) {
        refl__bvh_box b;
        int k;
        refl__tri_box(&bvh->tris[i], &b);
        for (k = 0; k < 3; ++k) centroid[3 * i + k] = 0.5f * (b.lo[k] + b.hi[k]);
        bvh->order[i] = i;
    }
    refl__bvh_build_tree(bvh, centroid);
    refl__free(a, centroid);
    *out_bvh = bvh;
    return REFL_OK;
}

REFL_API void refl_bvh_stats(const refl_bvh *bvh, long long *nodes, long long *triangles) {
    if (nodes) *nodes = bvh ? bvh->node_count : 0;
    if (triangles) *triangles = bvh ? bvh->tri_count : 0;
}

static long long refl__bvh_bytes(const refl_bvh *bvh) {
    long long nodes = 0, tris = 0;
    refl_bvh_stats(bvh, &nodes, &tris);
    return nodes * (long long)sizeof(refl__bvh_node) + tris * (long long)(sizeof(refl__bvh_tri) + sizeof(int32_t));
}

/* ---- traversal ---------------------------------------------------------------- */

typedef struct refl__bvh_ray {
    float org[3], dir[3];
    float inv[3];
    int near_lo[3];               /* 1: the ray enters a slab through its lo plane */
    int kx, ky, kz;               /* Woop's ray-space axes: kz the dominant one */
    float sx, sy, sz;             /* shear and scale to ray space */
} refl__bvh_ray;

static int refl__bvh_ray_setup(refl__bvh_ray *r, refl_vec3 o, refl_vec3 d) {
    float ad[3];
    int k, t;
    r->org[0] = o.x; r->org[1] = o.y; r->org[2] = o.z;
    r->dir[0] = d.x; r->dir[1] = d.y; r->dir[2] = d.z;
    for (k = 0; k < 3; ++k) {
        if (!refl__isfinite(r->org[k]) || !refl__isfinite(r->dir[k])) return 0;
        ad[k] = fabsf(r->dir[k]);
        /* A zero component gives an infinite inverse; the slab test skips
           the NaN that 0 * inf makes. */
        r->inv[k] = 1.0f / r->dir[k];
        r->near_lo[k] = !(r->inv[k] < 0);
    }
    r->kz = ad[0] >= ad[1] ? (ad[0] >= ad[2] ? 0 : 2) : (ad[1] >= ad[2] ? 1 : 2);
    if (ad[r->kz] == 0) return 0;
    r->kx = (r->kz + 1) % 3;
    r->ky = (r->kx + 1) % 3;
    /* Keep the winding (edge function signs) of the paper; no culling
       here, but it costs nothing. */
    if (r->dir[r->kz] < 0) { t = r->kx; r->kx = r->ky; r->ky = t; }
    r->sx = r->dir[r->kx] / r->dir[r->kz];
    r->sy = r->dir[r->ky] / r->dir[r->kz];
    r->sz = 1.0f / r->dir[r->kz];
    return 1;
}

/* Entry distance of the ray into the node's box within [tmin, tmax], or
   -1 (as a miss flag via the return value). */
static int refl__bvh_slab(const refl__bvh_ray *r, const refl__bvh_node *n, float tmin, float tmax,
                          float *tentry) {
    int k;
    for (k = 0; k < 3; ++k) {
        float nearp = r->near_lo[k] ? n->lo[k] : n->hi[k];
        float farp = r->near_lo[k] ? n->hi[k] : n->lo[k];
        float t0 = (nearp - r->org[k]) * r->inv[k];
        float t1 = (farp - r->org[k]) * r->inv[k];
        /* Comparisons written so a NaN (ray inside a slab's plane) leaves
           the interval alone. */
        if (t0 > tmin) tmin = t0;
        /* Widen the exit by 2 gamma(3) (Ize 2013), so rounding in the slab
           test never culls a box the exact ray touches. */
        t1 *= 1.0000004f;
        if (t1 < tmax) tmax = t1;
    }
    *tentry = tmin;
    return tmin <= tmax;
}

/* Watertight ray/triangle test. Returns 1 with t, u, v when the ray hits
   within (tmin, tmax). */
static int refl__bvh_tri_hit(const refl__bvh_ray *r, const refl__bvh_tri *tri, float tmin, float tmax,
                             float *t_out, float *u_out, float *v_out) {
    const float *v = tri->v;
    int kx = r->kx, ky = r->ky, kz = r->kz;
    float ax, ay, bx, by, cx, cy, az, bz, cz, e0, e1, e2, det, tt;
    float a[3], b[3], c[3];
    int k;
    for (k = 0; k < 3; ++k) {
        a[k] = v[k] - r->org[k];
        b[k] = v[3 + k] - r->org[k];
        c[k] = v[6 + k] - r->org[k];
    }
    ax = a[kx] - r->sx * a[kz]; ay = a[ky] - r->sy * a[kz];
    bx = b[kx] - r->sx * b[kz]; by = b[ky] - r->sy * b[kz];
    cx = c[kx] - r->sx * c[kz]; cy = c[ky] - r->sy * c[kz];
    e0 = cx * by - cy * bx;
    e1 = ax * cy - ay * cx;
    e2 = bx * ay - by * ax;
    /* An exact zero may be a rounding artefact on a shared edge: decide it
       in double, where these products are exact. */
    if (e0 == 0.0f || e1 == 0.0f || e2 == 0.0f) {
        e0 = (float)((double)cx * by - (double)cy * bx);
        e1 = (float)((double)ax * cy - (double)ay * cx);
        e2 = (float)((double)bx * ay - (double)by * ax);
    }
    if ((e0 < 0 || e1 < 0 || e2 < 0) && (e0 > 0 || e1 > 0 || e2 > 0)) return 0;
    det = e0 + e1 + e2;
    if (det == 0.0f) return 0;
    az = r->sz * a[kz]; bz = r->sz * b[kz]; cz = r->sz * c[kz];
    tt = e0 * az + e1 * bz + e2 * cz;
    /* Either sign of det: back faces count. */
    {
        float inv = 1.0f / det;
        float t = tt * inv;
        if (!(t > tmin) || !(t < tmax)) return 0;
        *t_out = t;
        *u_out = e1 * inv;
        *v_out = e2 * inv;
    }
    return 1;
}

/* Shared traversal: closest hit, or the first one when any_hit. */
static int refl__bvh_trace(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax,
                           int any_hit, refl_hit *hit) {
    refl__bvh_ray r;
    int stack[REFL__BVH_STACK];
    float stack_t[REFL__BVH_STACK]; /* entry distances, to skip boxes behind a closer hit */
    int sp = 0, node = 0, found = 0;
    float tentry;
    if (!bvh || bvh->node_count == 0) return 0;
    if (!(tmin < tmax) || tmin != tmin) return 0;
    if (!refl__bvh_ray_setup(&r, origin, dir)) return 0;
    if (!refl__bvh_slab(&r, &bvh->nodes[0], tmin, tmax, &tentry)) return 0;
    for (;;) {
        const refl__bvh_node *n = &bvh->nodes[node];
        if (n->count > 0) {
            int i;
            for (i = n->index; i < n->index + n->count; ++i) {
                const refl__bvh_tri *tri = &bvh->tris[bvh->order[i]];
                float t, u, v;
                if (refl__bvh_tri_hit(&r, tri, tmin, tmax, &t, &u, &v)) {
                    found = 1;
                    tmax = t;
                    if (hit) {
                        hit->t = t;
                        hit->object = tri->object;
                        hit->triangle = tri->triangle;
                        hit->u = u;
                        hit->v = v;
                    }
                    if (any_hit) return 1;
                }
            }
        } else {
            float t0, t1;
            int c0 = n->index, c1 = n->index + 1;
            int h0 = refl__bvh_slab(&r, &bvh->nodes[c0], tmin, tmax, &t0);
            int h1 = refl__bvh_slab(&r, &bvh->nodes[c1], tmin, tmax, &t1);
            if (h0 && h1) {
                /* Nearer first, so the far one is often culled by tmax;
                   the build's depth limit keeps the stack within bounds. */
                if (t1 < t0) { int s = c0; c0 = c1; c1 = s; }
                REFL_ASSERT(sp < REFL__BVH_STACK);
                stack_t[sp] = t0 < t1 ? t1 : t0;
                stack[sp++] = c1;
                node = c0;
                continue;
            }
            if (h0) { node = c0; continue; }
            if (h1) { node = c1; continue; }
        }
        do {
            if (sp == 0) return found;
            --sp;
        } while (stack_t[sp] > tmax);
        node = stack[sp];
    }
}

REFL_API int refl_bvh_intersect(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax,
                                refl_hit *hit) {
    refl_hit h;
    int r = refl__bvh_trace(bvh, origin, dir, tmin, tmax, 0, &h);
    if (r && hit) *hit = h;
    return r;
}

REFL_API int refl_bvh_occluded(const refl_bvh *bvh, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax) {
    return refl__bvh_trace(bvh, origin, dir, tmin, tmax, 1, NULL);
}

/* The surface at hit h on mesh m placed by `model` (normals by
   `normal_m`): its triangle's corners in the world, the barycentric
   weights, the point (interpolated: more exact than origin + t dir), the
   geometric normal and the interpolated shading normal (the geometric one
   where that vanishes). The ray tracer and SBC's higher orders share it. */
static void refl__hit_surface(const refl_mesh *m, const refl_mat4 *model, const refl_mat4 *normal_m, const refl_hit *h,
                              refl__hit_geom *g) {
    const uint32_t *tri = m->indices + 3 * (size_t)h->triangle;
    refl_vec3 n = refl_v3(0.0f, 0.0f, 0.0f);
    int k;
    g->w[0] = 1.0f - h->u - h->v;
    g->w[1] = h->u;
    g->w[2] = h->v;
    for (k = 0; k < 3; ++k) {
        const float *pp = m->positions + 3 * (size_t)tri[k], *nn = m->normals + 3 * (size_t)tri[k];
        g->v[k] = refl_mat4_point(*model, refl_v3(pp[0], pp[1], pp[2]));
        n = refl_v3_add(n, refl_v3_scale(refl_v3(nn[0], nn[1], nn[2]), g->w[k]));
    }
    g->p = refl_v3_add(refl_v3_add(refl_v3_scale(g->v[0], g->w[0]), refl_v3_scale(g->v[1], g->w[1])),
                       refl_v3_scale(g->v[2], g->w[2]));
    g->ng = refl_v3_normalize(refl_v3_cross(refl_v3_sub(g->v[1], g->v[0]), refl_v3_sub(g->v[2], g->v[0])));
    g->ns = refl_v3_normalize(refl_mat4_dir(*normal_m, n));
    if (refl_v3_dot(g->ns, g->ns) == 0.0f) g->ns = g->ng;
}
