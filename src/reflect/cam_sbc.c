/* cam_sbc: the sample-based camera (SBC) of paper 003, section IV: one
   reflection group's projection function, built from a ray map. Each
   reflected ray has a tail (where it leaves the last reflector), a head
   (where it leaves the scene box) and the first reflector point the
   desired view sees along it. The rays are decomposed into a BSP tree
   (BuildBSP, the paper's Fig. 10) whose leaves hold planar pinhole cameras
   fitted to their rays (cam_sbc_fit.c), or, where no camera fits, the rays
   themselves (cam_sbc_raylist.c). This file builds the tree, descends it
   and holds the public API; docs/methods/sbc.md, "The sample-based
   camera", tells the whole algorithm.

   Split (the paper's heuristic, with the changes said at
   refl__sbc_split): the plane through the tails' centroid,
   parallel to the mean ray direction, perpendicular to the tails' principal
   axis (made orthogonal to the mean direction). A ray goes left when any
   tail or head of its unit frustum (itself and its ray-map neighbours
   u +- 1, v +- 1 in the set) lies on the plane's positive side (or on it),
   right when any lies on the negative side; rays near the plane go both
   ways, so a point of either half space that lies among the set's rays
   lies among the rays of that side's subset. Splitting fails when a subset
   is the whole set (the paper), when half the set would go both ways (a
   few unit frustums across, every cut keeps nearly all rays on both sides
   and the cells would multiply without end) and at max_depth: the rays
   are then stored as a ray list. Cutting on until three quarters go both
   ways would keep ray lists shorter, but puts a strongly curved sphere's
   points pixels off (tests/reflect/test_sbc_stability.c).

   Projection: down the tree by the side of each plane (s >= 0: left), then
   the leaf's camera or ray list.

   Beyond runtime mode: desc.widen grows each accepted camera's rectangle
   (paper 003 VI, "extends the field of view of the BSP leaf cameras"), so
   a morphing grid's node projects points just outside its ray map; off by
   default, leaving runtime mode's projections unchanged.

   Deterministic: lists keep ray-map order, nothing is sorted or drawn at
   random, every sum runs in a fixed order. */
#include "cam_sbc_internal.h"

/* ---- reflected rays, shared by the SBC method (sbc_raymap.c) and the
   morphing grids (cam_sbc_morph.c): one head rule for both -------------------- */

#define REFL__SBC_REACH 2.0f /* a ray's head: this many times as far as what it hits */

/* Where a ray from inside box [lo, hi] along d leaves it. */
static float refl__sbc_box_exit(refl_vec3 lo, refl_vec3 hi, refl_vec3 o, refl_vec3 d) {
    float t_out;
    refl_ray_box(o, d, lo, hi, NULL, &t_out);
    return REFL__MAX(t_out, 0.0f);
}

/* The ray from q along unit r in a scene (its BVH, its box [lo, hi], grown,
   and that box's diagonal): tail = first = q, head REFL__SBC_REACH times as
   far as what it meets plus 1% of the diagonal, or a tenth of the diagonal
   when it meets nothing, within the box; what it meets in *met. With no
   BVH (SBC-paper, no search of the scene) the head is where the ray leaves
   the box, the paper's rule, and it meets nothing. 0 for a ray of zero
   length. */
static int refl__sbc_scene_ray(const refl_bvh *bvh, refl_vec3 lo, refl_vec3 hi, float diagonal, refl_vec3 q,
                               refl_vec3 r, refl_sbc_ray *ray, refl__sbc_hit *met) {
    refl_hit hit;
    float reach = refl__sbc_box_exit(lo, hi, q, r);
    met->object = -1;
    ray->tail = q;
    ray->first = q;
    if (bvh && refl_bvh_intersect(bvh, q, r, 1e-4f * diagonal, reach, &hit)) {
        met->object = hit.object;
        met->triangle = hit.triangle;
        met->point = refl_v3_add(q, refl_v3_scale(r, hit.t));
        reach = REFL__MIN(reach, REFL__SBC_REACH * hit.t + 0.01f * diagonal);
    } else if (bvh) {
        reach = REFL__MIN(reach, 0.1f * diagonal);
    }
    ray->head = refl_v3_add(q, refl_v3_scale(r, reach));
    return refl_v3_length(refl_v3_sub(ray->head, q)) > 0.0f;
}

/* A union-find root, halving the path on the way: how the method and the
   grids join samples and triangles into smooth pieces. */
static int refl__sbc_root(int *parent, int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
}

/* Whether neighbouring samples with surface points t1, t2 and unit normals
   n1, n2 lie on one smooth piece of surface: normals turning by less than
   REFL__SBC_SMOOTH_COS (not a crease: the knob on the lid, the spout's
   joint, a silhouette turning them fast) and no gap, where the chord
   between the points leaves a tangent plane by more than
   REFL__SBC_SMOOTH_SIN (one surface passing in front of another: the knob
   before the lid, the handle before the body; the chord runs along the
   view ray). */
static int refl__sbc_smooth(refl_vec3 t1, refl_vec3 n1, refl_vec3 t2, refl_vec3 n2) {
    refl_vec3 e;
    float l;
    if (!(refl_v3_dot(n1, n2) >= REFL__SBC_SMOOTH_COS)) return 0;
    e = refl_v3_sub(t2, t1);
    l = refl_v3_length(e);
    return fabsf(refl_v3_dot(n1, e)) <= REFL__SBC_SMOOTH_SIN * l && fabsf(refl_v3_dot(n2, e)) <= REFL__SBC_SMOOTH_SIN * l;
}

/* ---- building ---------------------------------------------------------------- */

typedef struct refl__sbc_task {
    int node, count, depth;
    size_t off;              /* its rays: pool[off, off + count) */
} refl__sbc_task;

/* Grows *arr (elements of size sz, capacity *cap) to hold need; 0 when out of memory. */
static int refl__sbc_grow(const refl_allocator *a, void **arr, size_t *cap, size_t need, size_t sz) {
    size_t nc;
    void *n;
    if (need <= *cap) return 1;
    nc = *cap ? *cap : 16;
    while (nc < need) {
        if (nc > ((size_t)-1) / 2 / sz) return 0;
        nc *= 2;
    }
    n = refl__alloc(a, nc * sz); /* no need to clear: every use writes first */
    if (!n) return 0;
    if (*arr) memcpy(n, *arr, *cap * sz);
    refl__free(a, *arr);
    *arr = n;
    *cap = nc;
    return 1;
}

static int refl__sbc_grow_int(const refl_allocator *a, void **arr, int *cap, int need, size_t sz) {
    size_t c = (size_t)*cap;
    if (need < 0 || need >= INT_MAX / 2) return 0;
    if (!refl__sbc_grow(a, arr, &c, (size_t)need, sz)) return 0;
    *cap = c > (size_t)(INT_MAX / 2) ? INT_MAX / 2 : (int)c;
    return 1;
}

/* The plane through c with normal sn, and each ray's side(s) in b->side:
   by the extent of its unit frustum's tails and heads. */
static void refl__sbc_assign(refl__sbc_builder *b, const int *list, int n, const double sn[3], const double c[3],
                             double plane[4], int *nl, int *nr) {
    int i, W = b->W, H = b->H;
    unsigned st;
    memcpy(plane, sn, 3 * sizeof(double));
    plane[3] = -refl__sbc_dot(sn, c);
    /* each ray's own extent, then its unit frustum's */
    st = ++b->stamp;
    for (i = 0; i < n; ++i) {
        const refl_sbc_ray *r = &b->rays[list[i]];
        double p[3], s0, s1;
        refl__sbc_load(r->tail, p);
        s0 = refl__sbc_dot(p, sn) + plane[3];
        refl__sbc_load(r->head, p);
        s1 = refl__sbc_dot(p, sn) + plane[3];
        b->smin[list[i]] = REFL__MIN(s0, s1);
        b->smax[list[i]] = REFL__MAX(s0, s1);
        b->mark[list[i]] = st;
    }
    *nl = *nr = 0;
    for (i = 0; i < n; ++i) {
        int idx = list[i], u = idx % W, v = idx / W, du, dv;
        int u0 = u > 0 ? -1 : 0, u1 = u + 1 < W ? 1 : 0, v0 = v > 0 ? -1 : 0, v1 = v + 1 < H ? 1 : 0;
        double lo = b->smin[idx], hi = b->smax[idx];
        for (dv = v0; dv <= v1; ++dv)
            for (du = u0; du <= u1; ++du) {
                int k = idx + dv * W + du;
                if (b->mark[k] != st) continue;
                lo = REFL__MIN(lo, b->smin[k]);
                hi = REFL__MAX(hi, b->smax[k]);
            }
        b->side[idx] = (uint8_t)((hi >= 0.0 ? 1 : 0) | (lo < 0.0 ? 2 : 0));
        if (b->side[idx] == 0) b->side[idx] = 3; /* NaN: keep it everywhere */
        *nl += b->side[idx] & 1;
        *nr += (b->side[idx] >> 1) & 1;
    }
}

/* Split: the plane and each ray's side(s) in b->side; 0 when it fails. */
static int refl__sbc_split(refl__sbc_builder *b, const int *list, int n, double plane[4], int *nl, int *nr) {
    double c[3] = {0.0, 0.0, 0.0}, m[3] = {0.0, 0.0, 0.0}, a1[3], a2[3];
    double cAA = 0.0, cAB = 0.0, cBB = 0.0, lam, e1, e2, sn[3], sn2[3], plane2[4];
    int i, j, nl2, nr2;
    refl__sbc_centroid(b, list, n, c, m);
    if (!(refl__sbc_normalize(m) > 0.0)) return 0;
    /* Beyond the paper, whose plane is parallel to the mean direction: the
       plane is parallel to the central ray, from the least-squares centre
       of projection o through c. Rays spreading from about o then stay on
       their side, where a plane off o is crossed by every ray whose tail
       lies between the plane and o's side of it (the heads lie at the
       scene's box, far beyond the tails: most of a set, at every level). */
    {
        double o[3], oc[3];
        if (refl__sbc_centre(b, list, n, c, o, NULL)) {
            for (j = 0; j < 3; ++j) oc[j] = c[j] - o[j];
            if (refl__sbc_dot(oc, m) < 0.0)
                for (j = 0; j < 3; ++j) oc[j] = -oc[j];
            if (refl__sbc_normalize(oc) > 0.0 && refl__sbc_dot(oc, m) > 0.5) memcpy(m, oc, sizeof m);
        }
    }
    /* the tails' scatter within the plane perpendicular to that direction */
    refl__sbc_across(m, a1, a2);
    for (i = 0; i < n; ++i) {
        const refl_sbc_ray *r = &b->rays[list[i]];
        double t[3], x, y;
        t[0] = r->tail.x - c[0]; t[1] = r->tail.y - c[1]; t[2] = r->tail.z - c[2];
        x = refl__sbc_dot(t, a1);
        y = refl__sbc_dot(t, a2);
        cAA += x * x; cAB += x * y; cBB += y * y;
    }
    if (!(cAA + cBB > 0.0)) return 0;
    /* the principal axis: the diameter's direction, orthogonal to m; the
       larger eigenvector of the 2 x 2 scatter in closed form (sqrt only:
       correctly rounded, the same everywhere, unlike atan2 or cos) */
    lam = 0.5 * (cAA + cBB) + sqrt(0.25 * (cAA - cBB) * (cAA - cBB) + cAB * cAB);
    if (lam - cBB >= lam - cAA) { e1 = lam - cBB; e2 = cAB; }
    else { e1 = cAB; e2 = lam - cAA; }
    for (j = 0; j < 3; ++j) sn[j] = e1 * a1[j] + e2 * a2[j];
    if (!(refl__sbc_normalize(sn) > 0.0)) memcpy(sn, a1, sizeof sn); /* round: any axis */
    /* Beyond the paper: the plane across the other axis too, kept when
       fewer rays cross it. Where the reflector curves the rays together
       along the diameter (a saddle, a concave patch) they cross every
       plane across it, the cut gains nothing and the set ends up as a ray
       list; across the axis along which they spread, the cut is clean. */
    refl__sbc_cross(m, sn, sn2);
    refl__sbc_normalize(sn2);
    refl__sbc_assign(b, list, n, sn2, c, plane2, &nl2, &nr2);
    refl__sbc_assign(b, list, n, sn, c, plane, nl, nr);
    if ((long long)nl2 + nr2 < (long long)*nl + *nr && 4 * ((long long)*nl + *nr) > 5 * (long long)n) {
        refl__sbc_assign(b, list, n, sn2, c, plane, nl, nr);
    }
    /* the paper fails only when a subset is the whole set; below a few
       unit frustums across, though, every cut keeps nearly all rays on both
       sides and the cells would multiply without end: fail when half the
       set would go both ways */
    return *nl < n && *nr < n && 2 * ((long long)*nl + *nr) < 3 * (long long)n;
}

static void refl__sbc_free_builder(refl__sbc_builder *b) {
    refl__free(b->a, b->valid);
    refl__free(b->a, b->dir);
    refl__free(b->a, b->truth);
    refl__free(b->a, b->mark);
    refl__free(b->a, b->smin);
    refl__free(b->a, b->smax);
    refl__free(b->a, b->side);
    refl__free(b->a, b->pool);
    refl__free(b->a, b->uv);
}

REFL_API void refl_sbc_destroy(refl_sbc *sbc) {
    refl_allocator a;
    if (!sbc) return;
    a = sbc->allocator;
    refl__free(&a, sbc->nodes);
    refl__free(&a, sbc->cams);
    refl__free(&a, sbc->quads);
    refl__free(&a, sbc->indexes);
    refl__free(&a, sbc->cell_start);
    refl__free(&a, sbc->cell_quads);
    refl__free(&a, sbc->rays);
    refl__free(&a, sbc);
}

static refl_result refl__sbc_run(refl__sbc_builder *b, int nvalid) {
    refl_sbc *s = b->sbc;
    refl__sbc_task *tasks;
    int ntask = 0, i;
    refl_result res = REFL_OK;
    /* the DFS holds at most one pending right sibling per level */
    tasks = (refl__sbc_task *)refl__calloc(b->a, (size_t)REFL__MIN(b->max_depth, nvalid) + 2, sizeof(refl__sbc_task));
    if (!tasks) return REFL_ERROR_OUT_OF_MEMORY;
    if (!refl__sbc_grow_int(b->a, (void **)&s->nodes, &s->node_cap, 1, sizeof(refl__sbc_node))) {
        refl__free(b->a, tasks);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    s->node_count = 1;
    s->nodes[0].child = -1;
    tasks[0].node = 0;
    tasks[0].off = 0;
    tasks[0].count = nvalid;
    tasks[0].depth = 0;
    ntask = 1;
    while (ntask > 0) {
        refl__sbc_task t = tasks[--ntask];
        size_t top = t.off + (size_t)t.count; /* everything above belongs to finished tasks */
        refl__sbc_cam cam;
        double plane[4];
        int nl = 0, nr = 0;
        s->stats.depth = REFL__MAX(s->stats.depth, t.depth);
        if (refl__sbc_fit_ok(b, b->pool + t.off, t.count, &cam)) {
            if (!refl__sbc_grow_int(b->a, (void **)&s->cams, &s->cam_cap, s->cam_count + 1, sizeof(refl__sbc_cam))) {
                res = REFL_ERROR_OUT_OF_MEMORY;
                break;
            }
            if (b->widen > 0.0) { /* after the fit: its normalisation (norm) stays the fitted one */
                double wu = b->widen * (cam.rect[1] - cam.rect[0]), wv = b->widen * (cam.rect[3] - cam.rect[2]);
                cam.rect[0] -= wu; cam.rect[1] += wu; cam.rect[2] -= wv; cam.rect[3] += wv;
            }
            s->cams[s->cam_count] = cam;
            s->nodes[t.node].kind = REFL__SBC_PINHOLE;
            s->nodes[t.node].first = s->cam_count++;
            s->nodes[t.node].count = 1;
            s->stats.pinhole_leaves++;
            continue;
        }
        if (t.depth < b->max_depth && refl__sbc_split(b, b->pool + t.off, t.count, plane, &nl, &nr)) {
            int *list, *wr, *wl, left;
            if (!refl__sbc_grow(b->a, (void **)&b->pool, &b->pool_cap, top + (size_t)nl + (size_t)nr, sizeof(int)) ||
                !refl__sbc_grow_int(b->a, (void **)&s->nodes, &s->node_cap, s->node_count + 2,
                                    sizeof(refl__sbc_node))) {
                res = REFL_ERROR_OUT_OF_MEMORY;
                break;
            }
            list = b->pool + t.off;
            wr = b->pool + top;          /* right below left: left is popped first */
            wl = wr + nr;
            for (i = 0; i < t.count; ++i) {
                int idx = list[i];
                if (b->side[idx] & 1) *wl++ = idx;
                if (b->side[idx] & 2) *wr++ = idx;
            }
            left = s->node_count;
            s->node_count += 2;
            memset(&s->nodes[left], 0, 2 * sizeof(refl__sbc_node));
            s->nodes[left].child = s->nodes[left + 1].child = -1;
            memcpy(s->nodes[t.node].plane, plane, sizeof plane);
            s->nodes[t.node].kind = REFL__SBC_INNER;
            s->nodes[t.node].child = left;
            tasks[ntask].node = left + 1;
            tasks[ntask].off = top;
            tasks[ntask].count = nr;
            tasks[ntask].depth = t.depth + 1;
            ++ntask;
            tasks[ntask].node = left;
            tasks[ntask].off = top + (size_t)nr;
            tasks[ntask].count = nl;
            tasks[ntask].depth = t.depth + 1;
            ++ntask;
            continue;
        }
        res = refl__sbc_ray_leaf(b, b->pool + t.off, t.count, &s->nodes[t.node]);
        if (res != REFL_OK) break;
        s->stats.ray_leaves++;
    }
    refl__free(b->a, tasks);
    return res;
}

REFL_API refl_result refl_sbc_build(const refl_sbc_ray *rays, const uint8_t *valid, int map_width, int map_height,
                                    const refl_sbc_desc *desc, refl_sbc **out_sbc) {
    refl__sbc_builder b;
    refl_sbc *s;
    refl_allocator alloc;
    refl_result res;
    size_t count, i;
    int nvalid = 0, j;
    double err;
    if (out_sbc) *out_sbc = NULL;
    if (!rays || !desc || !out_sbc || map_width < 1 || map_height < 1) return REFL_ERROR_INVALID_ARGUMENT;
    if ((size_t)map_width > (size_t)(INT_MAX / 4) / (size_t)map_height) return REFL_ERROR_INVALID_SIZE;
    err = desc->error_px == 0.0f ? 1.0 : (double)desc->error_px;
    if (!(err > 0.0)) return REFL_ERROR_INVALID_ARGUMENT; /* negative or NaN */
    if (desc->max_depth < 0 || !(desc->widen >= 0.0f && desc->widen <= 1e6f)) return REFL_ERROR_INVALID_ARGUMENT;
    if (err <= DBL_MAX) {
        if (desc->width < 1 || desc->height < 1) return REFL_ERROR_INVALID_ARGUMENT;
        for (j = 0; j < 16; ++j)
            if (!refl__isfinite(desc->view_proj.m[j])) return REFL_ERROR_INVALID_ARGUMENT;
    }
    count = (size_t)map_width * (size_t)map_height;
    for (i = 0; i < count; ++i) {
        const refl_sbc_ray *r = &rays[i];
        if (valid && !valid[i]) continue;
        if (!refl__sbc_finite3(r->tail) || !refl__sbc_finite3(r->head) || !refl__sbc_finite3(r->first))
            return REFL_ERROR_INVALID_ARGUMENT;
    }
    alloc = desc->allocator;
    memset(&b, 0, sizeof b);
    b.rays = rays;
    b.W = map_width;
    b.H = map_height;
    b.error_px = err;
    for (j = 0; j < 16; ++j) b.vp[j] = desc->view_proj.m[j];
    b.width = desc->width;
    b.height = desc->height;
    b.max_depth = desc->max_depth ? desc->max_depth : 40;
    b.widen = desc->widen;
    b.links = desc->links;
    s = (refl_sbc *)refl__calloc(&alloc, 1, sizeof(refl_sbc));
    if (!s) return REFL_ERROR_OUT_OF_MEMORY;
    s->allocator = alloc;
    s->width = map_width;
    s->height = map_height;
    b.sbc = s;
    b.a = &s->allocator;
    b.valid = (uint8_t *)refl__calloc(b.a, count, 1);
    b.dir = (float *)refl__calloc(b.a, count, 3 * sizeof(float));
    b.truth = (double *)refl__calloc(b.a, count, 2 * sizeof(double));
    b.mark = (unsigned *)refl__calloc(b.a, count, sizeof(unsigned));
    b.smin = (double *)refl__calloc(b.a, count, sizeof(double));
    b.smax = (double *)refl__calloc(b.a, count, sizeof(double));
    b.side = (uint8_t *)refl__calloc(b.a, count, 1);
    if (!b.valid || !b.dir || !b.truth || !b.mark || !b.smin || !b.smax || !b.side) {
        res = REFL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    /* rays of zero length have no direction: left out of the group */
    for (i = 0; i < count; ++i) {
        const refl_sbc_ray *r = &rays[i];
        double d[3], l;
        if (valid && !valid[i]) continue;
        d[0] = (double)r->head.x - r->tail.x;
        d[1] = (double)r->head.y - r->tail.y;
        d[2] = (double)r->head.z - r->tail.z;
        l = refl__sbc_normalize(d);
        if (!(l > 0.0) || !refl__sbc_finite(l)) continue;
        b.valid[i] = 1;
        for (j = 0; j < 3; ++j) b.dir[3 * i + (size_t)j] = (float)d[j];
        ++nvalid;
        if (err <= DBL_MAX) {
            double q[3];
            refl__sbc_load(r->first, q);
            if (!refl__sbc_pixel(&b, q, &b.truth[2 * i], &b.truth[2 * i + 1]))
                b.truth[2 * i] = b.truth[2 * i + 1] = NAN; /* behind the eye: no camera fits it */
        }
    }
    b.uv = (double *)refl__calloc(b.a, (size_t)nvalid + 1, 6 * sizeof(double));
    if (!b.uv || !refl__sbc_grow(b.a, (void **)&b.pool, &b.pool_cap, (size_t)nvalid * 4 + 16, sizeof(int))) {
        res = REFL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    {
        int k = 0;
        for (i = 0; i < count; ++i)
            if (b.valid[i]) b.pool[k++] = (int)i;
    }
    s->stats.rays = nvalid;
    s->stats.sheets = 1;
    res = refl__sbc_run(&b, nvalid);
    if (res == REFL_OK && s->stats.ray_leaves > 0) {
        /* ray lists read the map at projection time; invalid entries are never read */
        s->rays = (refl_sbc_ray *)refl__calloc(b.a, count, sizeof(refl_sbc_ray));
        if (!s->rays) res = REFL_ERROR_OUT_OF_MEMORY;
        else
            for (i = 0; i < count; ++i)
                if (b.valid[i]) s->rays[i] = rays[i];
    }
done:
    refl__sbc_free_builder(&b);
    if (res != REFL_OK) {
        refl_sbc_destroy(s);
        return res;
    }
    s->stats.nodes = s->node_count;
    s->stats.bytes = (long long)sizeof(refl_sbc) + (long long)s->node_cap * (long long)sizeof(refl__sbc_node) +
                     (long long)s->cam_cap * (long long)sizeof(refl__sbc_cam) +
                     (long long)s->quad_cap * (long long)sizeof(refl__sbc_quad) +
                     (long long)s->index_cap * (long long)sizeof(refl__sbc_index) +
                     ((long long)s->cell_start_cap + (long long)s->cell_quad_cap) * (long long)sizeof(int) +
                     (s->rays ? (long long)count * (long long)sizeof(refl_sbc_ray) : 0);
    *out_sbc = s;
    return REFL_OK;
}

REFL_API void refl_sbc_get_stats(const refl_sbc *sbc, refl_sbc_stats *out) {
    if (!out) return;
    if (!sbc) {
        memset(out, 0, sizeof *out);
        return;
    }
    *out = sbc->stats;
}

/* ---- projecting -------------------------------------------------------------- */

/* The leaf whose cell holds pd: down the tree by the side of each plane. */
static const refl__sbc_node *refl__sbc_leaf(const refl_sbc *sbc, const double *pd) {
    const refl__sbc_node *node = &sbc->nodes[0];
    while (node->kind == REFL__SBC_INNER) {
        double sd = node->plane[0] * pd[0] + node->plane[1] * pd[1] + node->plane[2] * pd[2] + node->plane[3];
        node = &sbc->nodes[sd >= 0.0 ? node->child : node->child + 1];
    }
    return node;
}

REFL_API refl_sbc_leaf_kind refl_sbc_leaf_at(const refl_sbc *sbc, refl_vec3 p) {
    double pd[3];
    if (!sbc || !sbc->nodes || !sbc->stats.rays || !refl__sbc_finite3(p)) return REFL_SBC_LEAF_NONE;
    refl__sbc_load(p, pd);
    return refl__sbc_leaf(sbc, pd)->kind == REFL__SBC_PINHOLE ? REFL_SBC_LEAF_PINHOLE : REFL_SBC_LEAF_RAY_LIST;
}

/* The leaf holding p and its projection per sheet (sheets 0: one for
   all); the mask of those p projects in. */
static int refl__sbc_project(const refl_sbc *sbc, refl_vec3 p, int sheets, refl_vec3 *first, float *z) {
    const refl__sbc_node *node;
    double pd[3];
    if (!sbc || !sbc->nodes || !refl__sbc_finite3(p)) return 0;
    refl__sbc_load(p, pd);
    node = refl__sbc_leaf(sbc, pd);
    if (node->kind == REFL__SBC_PINHOLE) return refl__sbc_cam_project(&sbc->cams[node->first], pd, first, z);
    return refl__sbc_rays_project(sbc, node, pd, sheets, first, z);
}

REFL_API int refl_sbc_project(const refl_sbc *sbc, refl_vec3 p, refl_vec3 *first, float *z) {
    refl_vec3 f;
    float zz;
    if (!refl__sbc_project(sbc, p, 0, &f, &zz)) return 0;
    if (first) *first = f;
    if (z) *z = zz;
    return 1;
}

REFL_API int refl_sbc_project_sheets(const refl_sbc *sbc, refl_vec3 p, int sheets, refl_vec3 *first, float *z) {
    if (!first || !z || sheets < 1) return 0;
    return refl__sbc_project(sbc, p, REFL__MIN(sheets, REFL_SBC_SHEETS), first, z);
}
