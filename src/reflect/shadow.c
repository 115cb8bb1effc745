/* Hard shadows for the rasterised methods: stencil shadow volumes, counted
   in and out as Heidmann does and Diefenbach and Badler use them (paper
   002), so that a pixel is lit by a light exactly when RAYTRACE's shadow
   ray from the surface it shows reaches that light.

   THE VOLUMES
       RAYTRACE blocks a shadow ray on any triangle, either side. Here each
       occluding triangle, turned to face the light, owns the prism behind
       it (the triangle, its three edges pushed to infinity away from the
       light, and the triangle itself at infinity), and a point is in
       shadow when it lies inside at least one prism. Counting is additive,
       so the prisms of one mesh are drawn as one volume: the side faces of
       an edge two occluders share with opposite directions cancel, and
       only edges with a nonzero net count (the sum of +1 or -1 over the
       occluders using the edge, by direction) are extruded, |net| times.
       On a closed mesh these are its silhouette edges; on an open one, its
       boundary too. Vertices are welded by exact position first (the sphere's seam,
       the box's corners, the teapot's patches). No adjacency is assumed:
       open meshes, non-manifold edges and inconsistent winding all give
       the counts of the per-triangle prisms.
       Which triangles occlude: on a closed mesh (after welding every edge
       has one use each way) those facing the light, or, when the light is
       inside the mesh (its winding number), those facing away, turned
       round: the first surface a ray from the light crosses. On an open
       mesh (the floor, the mirror room's walls, the concave bowl, the
       teapot with its open rim, lid and spout) a ray may cross back faces
       only, so every triangle counts, from either side: a wall facing away
       from a light still shadows the room. Drawn naively that doubles
       every silhouette; instead an open mesh is counted twice, cheaply:
       T1 with the light-facing triangles (their silhouette once), T2 with
       every triangle as it is wound (whose side faces are only the mesh's
       boundary edges: their prisms cancel elsewhere), which is (facing
       ones crossed) - (the others crossed). T1 - T2 counts the back faces
       crossed, so a light is blocked exactly where T1 != 0 or T1 != T2
       (T1 summing the closed meshes' counts too). Triangles edge-on to the
       light occlude nothing (zero measure). Lights at infinity extrude
       every edge to one point; point lights close the prisms with caps at
       infinity.

   COUNTING
       Into a scratch stencil, per light, against the caller's depth buffer
       (read only, LESS, no colour), with INCR_WRAP / DECR_WRAP by face
       side, so the stencil holds the number of prisms (mod 256) around the
       point just in front of the surface. z-pass (Heidmann) counts the
       faces in front of the surface and is right only when the near-plane
       rectangle lies outside every volume; z-fail (Carmack's reverse)
       counts those behind it and is right always, at the price of the
       caps. REFL__SHADOW_AUTO takes z-pass per light when no object's
       bounding box meets the convex hull of the light, the eye and the
       near rectangle (conservative), else z-fail. Mirrored projections
       (PLANAR's) flip every winding: the front face is then clockwise.
       rast.h clips at the far plane and has no depth clamp, yet z-fail
       must count faces beyond it: every volume polygon is split at the far
       plane here, in homogeneous clip space, and the part beyond is
       flattened onto it (z = w: window depth 1, behind every surface),
       which is what GL's depth clamping does. z-pass instead drops what
       lies beyond the farthest surface of the frame, which can never
       count (on the default scene, 30% of the counting's time).

   THE SURFACE THAT CASTS
       RAYTRACE starts its shadow ray on the light's side of the surface,
       and a surface facing away from a light gets no Lambert term anyway.
       Counting gives the point just in front of the surface (towards the
       eye); the only volume face through the surface point itself is its
       own triangle's cap, drawn here with the base pass's vertex
       expression so its depth equals the depth buffer's bit for bit. Seen
       from the light's side that cap must count as behind the point (LESS
       fails at equality); seen from the other side (the inside of an open
       mesh, lit through it) as in front (LEQUAL passes): so caps facing
       the eye are drawn with LESS and the others with LEQUAL. Side faces
       touch the surface only along its edges. The result agrees with the
       shadow rays away from shadow edges, where a pixel centre and the
       prism's edge fall within rounding of each other.

   LIMITS
       Lights beyond REFL__SHADOW_MAX_LIGHTS (8: bits of the lit byte) are
       treated as lit, as are lights with no valid position or direction.
       A count of exactly 256 volumes reads as lit. */
#include "internal.h"

enum { REFL__SV_NONE = 0xFFFFFFFFu };

typedef struct refl__sv_object {
    const refl_mesh *mesh;
    refl_mat4 mvp;            /* vp * transform, formed as refl__draw_scene forms it */
    double *world;            /* 3 per vertex */
    float *clip;              /* 4 per vertex: mvp * position, the base pass's expression */
    float *ext;               /* 4 per vertex: the vertex at infinity, away from the light */
    uint32_t *weld;           /* per vertex: the lowest index at the same position */
    uint32_t *edges;          /* 2 per edge, welded ids u < v */
    uint32_t *tri_edges;      /* 3 per triangle: edge << 1 | (1: the triangle runs v -> u); NONE: degenerate */
    uint32_t *caps[2];        /* exact caps in their original vertex order (refl__sv_object_light) */
    int cap_count[2];
    int cap_turned;           /* list 1 occludes turned round (else as wound, facing away from the light) */
    int *net;                 /* per edge */
    signed char *sign;        /* per triangle: +1, -1 (turned round) or 0 (not occluding) */
    int edge_count;
    int closed;
    double volume;            /* signed (> 0: wound outwards) */
    double lo[3], hi[3];      /* world bounds */
    void *block;
} refl__sv_object;

/* A growing array of clip-space triangle vertices (4 floats each). */
typedef struct refl__sv_buf {
    float *v;
    size_t count, cap;        /* in floats */
    const refl_allocator *a;
    int failed;
    float kfar;               /* refl__sv_poly's plane, z = kfar w */
    int drop_beyond;          /* z-pass: drop what lies beyond it */
} refl__sv_buf;

static float *refl__sv_push(refl__sv_buf *b, size_t floats) {
    float *p;
    if (b->failed) return NULL;
    if (b->count + floats > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        float *n;
        while (cap < b->count + floats) {
            if (cap > (size_t)-1 / (2 * sizeof(float))) { b->failed = 1; return NULL; }
            cap *= 2;
        }
        n = (float *)refl__alloc(b->a, cap * sizeof(float));
        if (!n) { b->failed = 1; return NULL; }
        if (b->count) memcpy(n, b->v, b->count * sizeof(float));
        refl__free(b->a, b->v);
        b->v = n;
        b->cap = cap;
    }
    p = b->v + b->count;
    b->count += floats;
    return p;
}

static void refl__sv_fan(refl__sv_buf *b, float (*v)[4], int n) {
    int i;
    for (i = 1; i + 1 < n; ++i) {
        float *o = refl__sv_push(b, 12);
        if (!o) return;
        memcpy(o, v[0], 4 * sizeof(float));
        memcpy(o + 4, v[i], 4 * sizeof(float));
        memcpy(o + 8, v[i + 1], 4 * sizeof(float));
    }
}

/* Appends a clip-space polygon (n <= 4) as triangles, split at the plane
   z = kfar w (window depth zmax): the part in front as it is; the part
   beyond either dropped (z-pass: it lies behind every surface, so it never
   counts) or flattened onto the plane (z-fail: it always counts, and with
   kfar = 1 rast.h's far clipping would have dropped it; flattened, it
   stays behind every surface, as GL's depth clamping keeps it). A crossing
   edge is interpolated from its inside end, so polygons sharing the edge
   share the new vertex. */
static void refl__sv_poly(refl__sv_buf *b, const float *const *v, int n) {
    float in[8][4], out[8][4], d[4];
    int i, k, ni = 0, no = 0;
    for (i = 0; i < n; ++i) d[i] = b->kfar * v[i][3] - v[i][2];
    for (i = 0; i < n; ++i) {
        int j = i + 1 == n ? 0 : i + 1;
        if (d[i] >= 0.0f) memcpy(in[ni++], v[i], 4 * sizeof(float));
        if (d[i] <= 0.0f) {
            memcpy(out[no], v[i], 4 * sizeof(float));
            out[no][2] = b->kfar * out[no][3];
            ++no;
        }
        if ((d[i] > 0.0f && d[j] < 0.0f) || (d[i] < 0.0f && d[j] > 0.0f)) {
            const float *a = d[i] > 0.0f ? v[i] : v[j], *c = d[i] > 0.0f ? v[j] : v[i];
            float da = d[i] > 0.0f ? d[i] : d[j], dc = d[i] > 0.0f ? d[j] : d[i], t = da / (da - dc);
            for (k = 0; k < 4; ++k) in[ni][k] = a[k] + t * (c[k] - a[k]);
            in[ni][2] = b->kfar * in[ni][3];
            memcpy(out[no++], in[ni++], 4 * sizeof(float));
        }
    }
    if (ni >= 3) refl__sv_fan(b, in, ni);
    if (no >= 3 && !b->drop_beyond) refl__sv_fan(b, out, no);
}

/* ---- occluders ------------------------------------------------------------------ */

static uint32_t refl__sv_hash(const float *p) {
    uint32_t h = 2166136261u, w;
    int k;
    for (k = 0; k < 3; ++k) {
        float f = p[k] + 0.0f; /* -0 and +0 weld */
        memcpy(&w, &f, sizeof w);
        h = (h ^ w) * 16777619u;
        h ^= h >> 15;
    }
    return h;
}

static size_t refl__sv_pow2(size_t n) {
    size_t s = 16;
    while (s < 2 * n) s *= 2;
    return s;
}

/* Sizes of the object block's arrays, each rounded to 8 bytes. */
static size_t refl__sv_round8(size_t n) { return (n + 7) & ~(size_t)7; }

static refl_result refl__sv_object_init(refl__sv_object *o, const refl_scene *scene, int object, refl_mat4 vp) {
    const refl_allocator *al = &scene->allocator;
    const refl_object *ob = &scene->objects[object];
    const refl_mesh *m = scene->meshes[ob->mesh];
    size_t nv = (size_t)m->vertex_count, nt = (size_t)m->triangle_count, ne = 3 * nt, sz[10], total = 0, k;
    size_t wmask, emask;
    uint32_t *wtab, *evals;
    uint64_t *ekeys;
    unsigned char *fwd, *rev, *bp, *tmp;
    size_t t, v;
    int c;
    memset(o, 0, sizeof *o);
    o->mesh = m;
    o->mvp = refl_mat4_mul(vp, ob->transform);
    if (nv > ((size_t)1 << 28) || nt > ((size_t)1 << 28)) return REFL_ERROR_INVALID_SIZE;
    sz[0] = 3 * nv * sizeof(double);
    sz[1] = 4 * nv * sizeof(float);
    sz[2] = 4 * nv * sizeof(float);
    sz[3] = nv * sizeof(uint32_t);
    sz[4] = 2 * ne * sizeof(uint32_t);
    sz[5] = 3 * nt * sizeof(uint32_t);
    sz[6] = 3 * nt * sizeof(uint32_t);
    sz[7] = 3 * nt * sizeof(uint32_t);
    sz[8] = ne * sizeof(int);
    sz[9] = nt;
    for (k = 0; k < 10; ++k) total += refl__sv_round8(sz[k]);
    o->block = refl__alloc(al, total);
    if (!o->block) return REFL_ERROR_OUT_OF_MEMORY;
    bp = (unsigned char *)o->block;
    o->world = (double *)(void *)bp; bp += refl__sv_round8(sz[0]);
    o->clip = (float *)(void *)bp; bp += refl__sv_round8(sz[1]);
    o->ext = (float *)(void *)bp; bp += refl__sv_round8(sz[2]);
    o->weld = (uint32_t *)(void *)bp; bp += refl__sv_round8(sz[3]);
    o->edges = (uint32_t *)(void *)bp; bp += refl__sv_round8(sz[4]);
    o->tri_edges = (uint32_t *)(void *)bp; bp += refl__sv_round8(sz[5]);
    o->caps[0] = (uint32_t *)(void *)bp; bp += refl__sv_round8(sz[6]);
    o->caps[1] = (uint32_t *)(void *)bp; bp += refl__sv_round8(sz[7]);
    o->net = (int *)(void *)bp; bp += refl__sv_round8(sz[8]);
    o->sign = (signed char *)bp;

    /* world positions (double) and the clip positions the base pass computes */
    for (c = 0; c < 3; ++c) { o->lo[c] = DBL_MAX; o->hi[c] = -DBL_MAX; }
    for (v = 0; v < nv; ++v) {
        const float *p = m->positions + 3 * v;
        const float *tm = ob->transform.m, *mm = o->mvp.m;
        refl_vec3 q = refl_v3(p[0], p[1], p[2]);
        double w[4];
        for (c = 0; c < 4; ++c)
            w[c] = (double)tm[c] * p[0] + (double)tm[4 + c] * p[1] + (double)tm[8 + c] * p[2] + (double)tm[12 + c];
        if (w[3] == 0.0) w[3] = 1.0;
        for (c = 0; c < 3; ++c) {
            o->world[3 * v + c] = w[c] / w[3];
            o->lo[c] = REFL__MIN(o->lo[c], o->world[3 * v + c]);
            o->hi[c] = REFL__MAX(o->hi[c], o->world[3 * v + c]);
        }
        for (c = 0; c < 4; ++c)
            o->clip[4 * v + c] = mm[c] * q.x + mm[4 + c] * q.y + mm[8 + c] * q.z + mm[12 + c];
    }

    /* temporaries: the weld table, the edge table, per-edge use counts */
    wmask = refl__sv_pow2(nv) - 1;
    emask = refl__sv_pow2(ne) - 1;
    tmp = (unsigned char *)refl__alloc(al, (wmask + 1) * sizeof(uint32_t) + (emask + 1) * (sizeof(uint64_t) +
                                                                                           sizeof(uint32_t)) +
                                               2 * ne);
    if (!tmp) {
        refl__free(al, o->block);
        o->block = NULL;
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    ekeys = (uint64_t *)(void *)tmp;
    evals = (uint32_t *)(void *)(tmp + (emask + 1) * sizeof(uint64_t));
    wtab = evals + (emask + 1);
    fwd = (unsigned char *)(wtab + (wmask + 1));
    rev = fwd + ne;
    memset(ekeys, 0, (emask + 1) * sizeof(uint64_t));
    memset(wtab, 0xFF, (wmask + 1) * sizeof(uint32_t));
    memset(fwd, 0, 2 * ne);

    for (v = 0; v < nv; ++v) { /* weld: first index at each position */
        const float *p = m->positions + 3 * v;
        size_t s = refl__sv_hash(p) & wmask;
        for (;;) {
            uint32_t u = wtab[s];
            const float *q;
            if (u == REFL__SV_NONE) { wtab[s] = (uint32_t)v; o->weld[v] = (uint32_t)v; break; }
            q = m->positions + 3 * (size_t)u;
            if (q[0] == p[0] && q[1] == p[1] && q[2] == p[2]) { o->weld[v] = u; break; }
            s = (s + 1) & wmask;
        }
    }
    o->closed = 1;
    for (t = 0; t < nt; ++t) {
        uint32_t w3[3];
        for (c = 0; c < 3; ++c) w3[c] = o->weld[m->indices[3 * t + (size_t)c]];
        if (w3[0] == w3[1] || w3[1] == w3[2] || w3[2] == w3[0]) { /* no area: occludes nothing */
            o->tri_edges[3 * t] = o->tri_edges[3 * t + 1] = o->tri_edges[3 * t + 2] = REFL__SV_NONE;
            continue;
        }
        for (c = 0; c < 3; ++c) {
            uint32_t a = w3[c], b = w3[(c + 1) % 3], u = REFL__MIN(a, b), w = REFL__MAX(a, b);
            uint64_t key = ((uint64_t)u << 32 | w) + 1;
            size_t s = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 20) & emask;
            while (ekeys[s] != 0 && ekeys[s] != key) s = (s + 1) & emask;
            if (ekeys[s] == 0) {
                ekeys[s] = key;
                evals[s] = (uint32_t)o->edge_count;
                o->edges[2 * (size_t)o->edge_count] = u;
                o->edges[2 * (size_t)o->edge_count + 1] = w;
                ++o->edge_count;
            }
            o->tri_edges[3 * t + (size_t)c] = evals[s] << 1 | (uint32_t)(a > b);
            if (a > b) rev[evals[s]] = (unsigned char)REFL__MIN(rev[evals[s]] + 1, 2);
            else fwd[evals[s]] = (unsigned char)REFL__MIN(fwd[evals[s]] + 1, 2);
        }
    }
    for (k = 0; k < (size_t)o->edge_count; ++k)
        if (fwd[k] != 1 || rev[k] != 1) o->closed = 0;
    refl__free(al, tmp);

    /* closed: which way it is wound (the signed volume) */
    o->volume = 0.0;
    if (o->closed && nv) {
        const double *r = o->world;
        for (t = 0; t < nt; ++t) {
            const double *a = o->world + 3 * (size_t)m->indices[3 * t], *b = o->world + 3 * (size_t)m->indices[3 * t + 1],
                         *cc = o->world + 3 * (size_t)m->indices[3 * t + 2];
            double x[3], y[3], z[3];
            for (c = 0; c < 3; ++c) { x[c] = a[c] - r[c]; y[c] = b[c] - r[c]; z[c] = cc[c] - r[c]; }
            o->volume += x[0] * (y[1] * z[2] - y[2] * z[1]) + x[1] * (y[2] * z[0] - y[0] * z[2]) +
                         x[2] * (y[0] * z[1] - y[1] * z[0]);
        }
    }
    return REFL_OK;
}

static void refl__sv_object_free(const refl_scene *scene, refl__sv_object *o) {
    refl__free(&scene->allocator, o->block);
    o->block = NULL;
}

/* Winding number of a closed mesh around the point l: the sum of its
   triangles' signed solid angles over 4 pi (Van Oosterom and Strackee). */
static double refl__sv_winding(const refl__sv_object *o, const double l[3]) {
    const refl_mesh *m = o->mesh;
    double sum = 0.0;
    int t, c;
    for (t = 0; t < m->triangle_count; ++t) {
        double a[3], b[3], e[3], la, lb, le, num, den;
        if (o->tri_edges[3 * (size_t)t] == REFL__SV_NONE) continue;
        for (c = 0; c < 3; ++c) {
            a[c] = o->world[3 * (size_t)m->indices[3 * (size_t)t] + (size_t)c] - l[c];
            b[c] = o->world[3 * (size_t)m->indices[3 * (size_t)t + 1] + (size_t)c] - l[c];
            e[c] = o->world[3 * (size_t)m->indices[3 * (size_t)t + 2] + (size_t)c] - l[c];
        }
        la = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        le = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
        if (la == 0.0 || lb == 0.0 || le == 0.0) return 0.5; /* on the surface: either */
        num = a[0] * (b[1] * e[2] - b[2] * e[1]) + a[1] * (b[2] * e[0] - b[0] * e[2]) + a[2] * (b[0] * e[1] - b[1] * e[0]);
        den = la * lb * le + (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) * le +
              (a[0] * e[0] + a[1] * e[1] + a[2] * e[2]) * lb + (b[0] * e[0] + b[1] * e[1] + b[2] * e[2]) * la;
        sum += 2.0 * atan2(num, den);
    }
    return sum / (4.0 * REFL__PI);
}

/* A light in double: point (w = 1) or direction of travel (w = 0); 0 when
   it has no usable position or direction (it then counts as lit). */
static int refl__sv_light(const refl_light *l, double out[4]) {
    if (l->type == REFL_LIGHT_DIRECTIONAL) {
        double len;
        out[0] = l->direction.x; out[1] = l->direction.y; out[2] = l->direction.z; out[3] = 0.0;
        len = sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
        if (!(len > 0.0) || !(len <= DBL_MAX)) return 0;
        out[0] /= len; out[1] /= len; out[2] /= len;
        return 1;
    }
    out[0] = l->position.x; out[1] = l->position.y; out[2] = l->position.z; out[3] = 1.0;
    return refl__isfinite(l->position.x) && refl__isfinite(l->position.y) && refl__isfinite(l->position.z);
}

/* Which triangles make an object's volume for one light (see the top):
   ONE_SIDED, per triangle the prism of the first surface a ray from the
   light crosses (closed meshes), or of those facing the light (open
   meshes); ALL_AS_WOUND (open meshes only), every triangle with
   coefficient +1 as it is wound: the count is then (light-facing
   triangles crossed) - (the others crossed), and its side faces are only
   the mesh's boundary edges. With T1 the ONE_SIDED count over every object
   and T2 the ALL_AS_WOUND count over the open ones, T1 - T2 counts the
   back-facing triangles of open meshes crossed (and the closed meshes'),
   so a point sees the light exactly when T1 = 0 and T1 = T2. This counts
   open meshes from both sides, as RAYTRACE does, without drawing their
   silhouettes twice. */
enum { REFL__SV_ONE_SIDED = 0, REFL__SV_ALL_AS_WOUND = 1 };

/* One object's volume for one light: the caps drawn exactly go to
   o->caps (list 0: the prism's own triangle as wound; list 1: the other
   triangles, see cap_turned), everything else (side faces, caps beyond the
   far plane, caps at infinity) into b as clip-space triangles, wound
   outwards. */
static void refl__sv_object_light(refl__sv_object *o, const double l[4], refl_mat4 vp, int zfail, int chain,
                                  refl__sv_buf *b) {
    const refl_mesh *m = o->mesh;
    const float *vm = vp.m;
    size_t nv = (size_t)m->vertex_count, v;
    int t, e, c, flip = 0;
    float dir_clip[4];
    o->cap_count[0] = o->cap_count[1] = 0;
    /* the vertices at infinity: vp * (direction, 0) */
    if (l[3] == 0.0) {
        for (c = 0; c < 4; ++c)
            dir_clip[c] = (float)((double)vm[c] * l[0] + (double)vm[4 + c] * l[1] + (double)vm[8 + c] * l[2]);
    } else {
        for (v = 0; v < nv; ++v) {
            const double *p = o->world + 3 * v;
            double d[3];
            d[0] = p[0] - l[0]; d[1] = p[1] - l[1]; d[2] = p[2] - l[2];
            for (c = 0; c < 4; ++c)
                o->ext[4 * v + c] = (float)((double)vm[c] * d[0] + (double)vm[4 + c] * d[1] + (double)vm[8 + c] * d[2]);
        }
    }
    /* closed meshes: the first surface a ray from the light crosses */
    if (o->closed && l[3] != 0.0) {
        int inside = fabs(refl__sv_winding(o, l)) > 0.5;
        flip = (o->volume > 0.0) == inside;
    } else if (o->closed) {
        flip = o->volume < 0.0;
    }
    /* list 1 holds turned-round triangles (ONE_SIDED) or back-facing ones
       as wound (ALL_AS_WOUND): their prism's own triangle is turned round */
    o->cap_turned = chain == REFL__SV_ONE_SIDED;
    for (t = 0; t < m->triangle_count; ++t) {
        const uint32_t *ix = m->indices + 3 * (size_t)t;
        const double *a = o->world + 3 * (size_t)ix[0], *bb = o->world + 3 * (size_t)ix[1],
                     *cc = o->world + 3 * (size_t)ix[2];
        double u[3], w[3], n[3], f;
        int s, list;
        o->sign[t] = 0;
        if (o->tri_edges[3 * (size_t)t] == REFL__SV_NONE) continue;
        for (c = 0; c < 3; ++c) { u[c] = bb[c] - a[c]; w[c] = cc[c] - a[c]; }
        n[0] = u[1] * w[2] - u[2] * w[1];
        n[1] = u[2] * w[0] - u[0] * w[2];
        n[2] = u[0] * w[1] - u[1] * w[0];
        f = l[3] != 0.0 ? n[0] * (l[0] - a[0]) + n[1] * (l[1] - a[1]) + n[2] * (l[2] - a[2])
                        : -(n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
        if (chain == REFL__SV_ALL_AS_WOUND) s = 1; /* edge-on ones too: their prisms are flat */
        else if (o->closed && flip) s = f < 0.0 ? -1 : 0;
        else s = f > 0.0 ? 1 : 0;
        o->sign[t] = (signed char)s;
        if (!s) continue;
        list = s < 0 || f < 0.0;
        {
            /* the corners in the volume's winding: turned round when s < 0 */
            uint32_t k0 = ix[0], k1 = s > 0 ? ix[1] : ix[2], k2 = s > 0 ? ix[2] : ix[1];
            const float *q[3];
            int beyond = 0;
            q[0] = o->clip + 4 * (size_t)k0; q[1] = o->clip + 4 * (size_t)k1; q[2] = o->clip + 4 * (size_t)k2;
            for (c = 0; c < 3; ++c) beyond |= q[c][3] - q[c][2] < 0.0f;
            if (zfail && beyond) {
                refl__sv_poly(b, q, 3); /* cut by the far plane: drawn here, not exactly */
            } else if (zfail || !o->closed) {
                uint32_t *dst = o->caps[list] + 3 * (size_t)o->cap_count[list]++;
                dst[0] = ix[0]; dst[1] = ix[1]; dst[2] = ix[2];
            }
            if (zfail && l[3] != 0.0) { /* the cap at infinity, facing away from the light */
                q[0] = o->ext + 4 * (size_t)k0; q[1] = o->ext + 4 * (size_t)k2; q[2] = o->ext + 4 * (size_t)k1;
                refl__sv_poly(b, q, 3);
            }
        }
    }
    /* net use of each edge by the occluders, by direction */
    for (e = 0; e < o->edge_count; ++e) o->net[e] = 0;
    for (t = 0; t < m->triangle_count; ++t) {
        if (!o->sign[t]) continue;
        for (c = 0; c < 3; ++c) {
            uint32_t te = o->tri_edges[3 * (size_t)t + (size_t)c];
            o->net[te >> 1] += (te & 1u) ? -o->sign[t] : o->sign[t];
        }
    }
    for (e = 0; e < o->edge_count; ++e) {
        int k = o->net[e], r;
        uint32_t x = o->edges[2 * (size_t)e], y = o->edges[2 * (size_t)e + 1];
        const float *q[4];
        if (!k) continue;
        if (k < 0) { uint32_t tmp = x; x = y; y = tmp; k = -k; }
        /* occluders run x -> y: the side face is y, x, x at infinity, y at infinity */
        q[0] = o->clip + 4 * (size_t)y;
        q[1] = o->clip + 4 * (size_t)x;
        q[2] = l[3] != 0.0 ? o->ext + 4 * (size_t)x : dir_clip;
        q[3] = l[3] != 0.0 ? o->ext + 4 * (size_t)y : dir_clip;
        for (r = 0; r < k; ++r) refl__sv_poly(b, q, l[3] != 0.0 ? 4 : 3);
    }
}

/* ---- choosing z-pass ------------------------------------------------------------- */

/* Supporting planes of the convex hull of pts (and, with a direction u,
   of the points swept along u to infinity), found by brute force over
   triples (pairs and u): n . x <= d + tol holds on the hull. */
typedef struct refl__sv_plane { double n[3], d; } refl__sv_plane;

static int refl__sv_add_plane(refl__sv_plane *out, int count, const double n_in[3], const double p[3],
                              const double (*pts)[3], int np, const double *u, double tol) {
    double n[3], len = sqrt(n_in[0] * n_in[0] + n_in[1] * n_in[1] + n_in[2] * n_in[2]), d, lo = 0.0, hi = 0.0;
    int i, c;
    if (!(len > 0.0) || !(len <= DBL_MAX)) return count;
    for (c = 0; c < 3; ++c) n[c] = n_in[c] / len;
    d = n[0] * p[0] + n[1] * p[1] + n[2] * p[2];
    for (i = 0; i < np; ++i) {
        double s = n[0] * pts[i][0] + n[1] * pts[i][1] + n[2] * pts[i][2] - d;
        lo = REFL__MIN(lo, s);
        hi = REFL__MAX(hi, s);
    }
    if (hi > tol && lo < -tol) return count; /* points on both sides: not a face */
    if (hi > tol) { for (c = 0; c < 3; ++c) n[c] = -n[c]; d = -d; }
    if (u && n[0] * u[0] + n[1] * u[1] + n[2] * u[2] > 1e-9) return count; /* the sweep leaves it */
    for (c = 0; c < 3; ++c) out[count].n[c] = n[c];
    out[count].d = d;
    return count + 1;
}

/* Nonzero when z-pass is safe for light l: no object's bounding box meets
   the hull of the light, the eye and the near rectangle (so neither the
   eye nor any point of the near plane lies in a shadow volume). */
static int refl__sv_zpass_safe(const refl__sv_object *objs, int count, const double l[4], refl_vec3 eye,
                               refl_mat4 vp) {
    double pts[6][3], u[3], scale = 0.0, tol;
    refl__sv_plane planes[48]; /* at most 20 triples and 15 pairs */
    refl_mat4 inv;
    int np = 0, npl = 0, i, j, k, c, ob;
    const int directional = l[3] == 0.0;
    if (!refl_mat4_invert(vp, &inv)) return 0;
    for (k = 0; k < 4; ++k) { /* near corners, in order around the rectangle */
        double ndc[4], w[4];
        ndc[0] = (k == 1 || k == 2) ? 1.0 : -1.0;
        ndc[1] = k >= 2 ? 1.0 : -1.0;
        ndc[2] = -1.0;
        ndc[3] = 1.0;
        for (c = 0; c < 4; ++c)
            w[c] = inv.m[c] * ndc[0] + inv.m[4 + c] * ndc[1] + inv.m[8 + c] * ndc[2] + inv.m[12 + c] * ndc[3];
        if (w[3] == 0.0) return 0;
        for (c = 0; c < 3; ++c) pts[np][c] = w[c] / w[3];
        ++np;
    }
    pts[np][0] = eye.x; pts[np][1] = eye.y; pts[np][2] = eye.z; ++np;
    if (!directional) { for (c = 0; c < 3; ++c) pts[np][c] = l[c]; ++np; }
    for (c = 0; c < 3; ++c) u[c] = -l[c]; /* towards the light */
    for (i = 0; i < np; ++i)
        for (c = 0; c < 3; ++c) {
            if (!(fabs(pts[i][c]) <= 1e30)) return 0;
            scale = REFL__MAX(scale, fabs(pts[i][c]));
        }
    for (ob = 0; ob < count; ++ob)
        for (c = 0; c < 3; ++c) scale = REFL__MAX(scale, REFL__MAX(fabs(objs[ob].lo[c]), fabs(objs[ob].hi[c])));
    tol = 1e-5 * (scale + 1.0);
    for (i = 0; i < np; ++i)
        for (j = i + 1; j < np; ++j) {
            double e1[3], n[3];
            for (c = 0; c < 3; ++c) e1[c] = pts[j][c] - pts[i][c];
            if (directional) {
                n[0] = e1[1] * u[2] - e1[2] * u[1];
                n[1] = e1[2] * u[0] - e1[0] * u[2];
                n[2] = e1[0] * u[1] - e1[1] * u[0];
                npl = refl__sv_add_plane(planes, npl, n, pts[i], (const double(*)[3])pts, np, u, tol);
            }
            for (k = j + 1; k < np; ++k) {
                double e2[3];
                for (c = 0; c < 3; ++c) e2[c] = pts[k][c] - pts[i][c];
                n[0] = e1[1] * e2[2] - e1[2] * e2[1];
                n[1] = e1[2] * e2[0] - e1[0] * e2[2];
                n[2] = e1[0] * e2[1] - e1[1] * e2[0];
                npl = refl__sv_add_plane(planes, npl, n, pts[i], (const double(*)[3])pts, np,
                                         directional ? u : NULL, tol);
            }
        }
    for (ob = 0; ob < count; ++ob) {
        const refl__sv_object *o = &objs[ob];
        int separated = 0;
        for (i = 0; i < npl && !separated; ++i) { /* all 8 corners beyond one face of the hull */
            int out = 1;
            for (k = 0; k < 8 && out; ++k) {
                double x = k & 1 ? o->hi[0] : o->lo[0], y = k & 2 ? o->hi[1] : o->lo[1], z = k & 4 ? o->hi[2] : o->lo[2];
                out = planes[i].n[0] * x + planes[i].n[1] * y + planes[i].n[2] * z - planes[i].d > tol;
            }
            separated = out;
        }
        for (c = 0; c < 3 && !separated; ++c) { /* the hull beyond one face of the box */
            int above = 1, below = 1;
            for (i = 0; i < np; ++i) {
                above &= pts[i][c] > o->hi[c] + tol;
                below &= pts[i][c] < o->lo[c] - tol;
            }
            if (directional) {
                above &= u[c] >= 0.0;
                below &= u[c] <= 0.0;
            }
            separated = above || below;
        }
        if (!separated) return 0;
    }
    return 1;
}

/* ---- drawing the volumes ------------------------------------------------------- */

/* The cap's clip position: refl__base_vertex's expression, so caps meet the
   depth buffer bit for bit. */
static int refl__sv_cap_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out) {
    const float *mm = ((const refl_mat4 *)user)->m;
    refl_vec3 p = refl_v3(vertex[0], vertex[1], vertex[2]);
    int k;
    (void)index;
    (void)max_out;
    for (k = 0; k < 4; ++k) out->position[k] = mm[k] * p.x + mm[4 + k] * p.y + mm[8 + k] * p.z + mm[12 + k];
    return 1;
}

/* Counting state: faces wound outwards; `turned` draws turned-round
   triangles in their original order (its faces are the other way). */
static rast_state refl__sv_state(int zfail, int turned, int mirrored, rast_cull cull, rast_compare func,
                                 const int scissor[4]) {
    rast_state s;
    memset(&s, 0, sizeof s);
    s.scissor_test = 1;
    memcpy(s.scissor, scissor, sizeof s.scissor);
    s.front_face = (mirrored != turned) ? RAST_CW : RAST_CCW;
    s.cull = cull;
    s.depth_test = 1;
    s.depth_func = func;
    s.depth_write_disabled = 1;
    s.color_write = RAST_MASK(0);
    s.stencil_test = 1;
    s.stencil_front.func = s.stencil_back.func = RAST_ALWAYS;
    if (zfail) { /* behind the surface: leaving a volume counts up */
        s.stencil_front.depth_fail = RAST_DECR_WRAP;
        s.stencil_back.depth_fail = RAST_INCR_WRAP;
    } else { /* in front of it: entering counts up */
        s.stencil_front.pass = RAST_INCR_WRAP;
        s.stencil_back.pass = RAST_DECR_WRAP;
    }
    return s;
}

/* One object's exact caps of list k. A cap's depth test depends on which
   side of its prism's own triangle the eye is (see THE SURFACE THAT
   CASTS): LESS where that triangle faces the eye, LEQUAL where it faces
   away; z-pass needs only the latter (a cap in front of a surface hides
   it). */
static rast_result refl__sv_draw_caps(rast_context *rc, const refl__sv_object *o, int k, int zfail, int mirrored,
                                      const int scissor[4], long long *tris) {
    int turned = k == 1 && o->cap_turned, less_on_front = !(k == 1 && !o->cap_turned), pass;
    rast_result r = RAST_OK;
    if (!o->cap_count[k]) return RAST_OK;
    for (pass = zfail ? 0 : 1; pass < 2 && r == RAST_OK; ++pass) {
        int cull_back = (pass == 0) == less_on_front; /* pass 0: LESS, pass 1: LEQUAL */
        rast_state s = refl__sv_state(zfail, turned, mirrored, cull_back ? RAST_CULL_BACK : RAST_CULL_FRONT,
                                      pass == 0 ? RAST_LESS : RAST_LEQUAL, scissor);
        s.vertex_fn = refl__sv_cap_vertex;
        s.vertex_user = (void *)&o->mvp;
        if ((r = rast_set_state(rc, &s)) == RAST_OK) r = refl__draw_mesh(rc, o->mesh, o->caps[k], 3 * o->cap_count[k], 0);
        *tris += o->cap_count[k];
    }
    return r;
}

/* Whether vp mirrors: screen winding follows the sign of the determinant
   of its x, y and w rows (negative for gluPerspective * gluLookAt). */
static int refl__sv_mirrored(refl_mat4 vp) {
    const float *m = vp.m;
    double a = m[0], b = m[4], c = m[8], d = m[1], e = m[5], f = m[9], g = m[3], h = m[7], i = m[11];
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) > 0.0;
}

static refl_result refl__shadow_mask_mode(const refl__shadow_job *job, uint8_t *lit, refl__shadow_mode mode,
                                          unsigned *used_zfail) {
    rast_context *rc = job->rc;
    const refl_scene *scene = job->scene;
    const refl_mat4 vp = job->vp;
    const float *depth = job->depth;
    const uint8_t *region = job->region;
    const uint8_t region_value = job->region_value;
    const int width = job->width, height = job->height;
    const refl_allocator *al;
    refl__sv_object *objs = NULL;
    refl__sv_buf buf;
    uint8_t *scratch = NULL;
    rast_targets t;
    rast_result rr = RAST_OK;
    refl_result r = REFL_OK;
    size_t npx, i;
    int x0, y0, x1, y1, x, y, li, ob, inited = 0, lights, mirrored, scissor[4], queued = 0;
    long long tris = 0;
    float zmax = 0.0f;
    if (used_zfail) *used_zfail = 0;
    if (!rc || !scene || !depth || !lit || width <= 0 || height <= 0 || width > RAST_MAX_TARGET_SIZE ||
        height > RAST_MAX_TARGET_SIZE)
        return REFL_ERROR_INVALID_ARGUMENT;
    al = &scene->allocator;
    npx = (size_t)width * (size_t)height;
    memset(&buf, 0, sizeof buf);
    buf.a = al;
    /* the pixels to compute: start lit, and their bounds as the scissor */
    x0 = width; y0 = height; x1 = y1 = 0;
    for (y = 0; y < height; ++y)
        for (x = 0; x < width; ++x) {
            i = (size_t)y * (size_t)width + (size_t)x;
            if (region && region[i] != region_value) continue;
            lit[i] = 0xFF;
            if (!(depth[i] < 1.0f)) continue;
            zmax = REFL__MAX(zmax, depth[i]);
            x0 = REFL__MIN(x0, x); y0 = REFL__MIN(y0, y);
            x1 = REFL__MAX(x1, x + 1); y1 = REFL__MAX(y1, y + 1);
        }
    lights = REFL__MIN(scene->light_count, REFL__SHADOW_MAX_LIGHTS);
    if (x0 >= x1 || lights <= 0 || scene->object_count <= 0) goto done;
    scissor[0] = x0; scissor[1] = y0; scissor[2] = x1 - x0; scissor[3] = y1 - y0;
    mirrored = refl__sv_mirrored(vp);

    scratch = (uint8_t *)refl__alloc(al, 2 * npx); /* T1, then T2 */
    objs = (refl__sv_object *)refl__calloc(al, (size_t)scene->object_count, sizeof(refl__sv_object));
    if (!scratch || !objs) { r = REFL_ERROR_OUT_OF_MEMORY; goto done; }
    for (ob = 0; ob < scene->object_count && r == REFL_OK; ++ob, ++inited)
        r = refl__sv_object_init(&objs[ob], scene, ob, vp);
    if (r != REFL_OK) goto done;

    memset(&t, 0, sizeof t);
    t.depth.ptr = (void *)depth; /* read only: depth writes are off */
    t.depth.width = width; t.depth.height = height; t.depth.stride = width * (int)sizeof(float);
    t.stencil.width = width; t.stencil.height = height; t.stencil.stride = width;

    for (li = 0; li < lights; ++li) {
        double l[4];
        int zfail, chain;
        if (!refl__sv_light(&scene->lights[li], l)) continue;
        zfail = mode == REFL__SHADOW_ZFAIL ||
                (mode == REFL__SHADOW_AUTO && !refl__sv_zpass_safe(objs, scene->object_count, l, job->eye, vp));
        if (zfail && used_zfail) *used_zfail |= 1u << li;
        /* z-pass: what lies beyond the farthest surface never counts (a
           margin for the rounding of window depth); z-fail: the far plane */
        buf.kfar = zfail ? 1.0f : REFL__MIN(2.0f * zmax - 1.0f + 1e-5f, 1.0f);
        buf.drop_beyond = !zfail;
        for (chain = REFL__SV_ONE_SIDED; chain <= REFL__SV_ALL_AS_WOUND; ++chain) {
            uint8_t *counts = scratch + (size_t)chain * npx;
            rast_state s;
            rast_clear_desc clear;
            rast_draw_desc d;
            int any = 0;
            buf.count = 0;
            for (ob = 0; ob < scene->object_count; ++ob) {
                objs[ob].cap_count[0] = objs[ob].cap_count[1] = 0;
                if (chain == REFL__SV_ALL_AS_WOUND && objs[ob].closed) continue;
                refl__sv_object_light(&objs[ob], l, vp, zfail, chain, &buf);
                any = 1;
            }
            if (buf.failed) { r = REFL_ERROR_OUT_OF_MEMORY; goto done; }
            if (!any) { /* no open mesh: T2 = 0 */
                for (y = y0; y < y1; ++y) memset(counts + (size_t)y * (size_t)width + (size_t)x0, 0, (size_t)(x1 - x0));
                break;
            }
            if (buf.count / 4 > (size_t)INT_MAX) { r = REFL_ERROR_INVALID_SIZE; goto done; }
            t.stencil.ptr = counts;
            if ((rr = rast_set_targets(rc, &t)) != RAST_OK) goto done;
            /* clear the counts within the scissor, then count */
            s = refl__sv_state(zfail, 0, mirrored, RAST_CULL_NONE, RAST_LESS, scissor);
            memset(&clear, 0, sizeof clear);
            clear.flags = RAST_CLEAR_STENCIL;
            queued = 1;
            if ((rr = rast_set_state(rc, &s)) != RAST_OK || (rr = rast_clear(rc, &clear)) != RAST_OK) goto done;
            memset(&d, 0, sizeof d);
            d.primitive = RAST_TRIANGLES;
            d.vertices = buf.v;
            d.vertex_count = (int)(buf.count / 4);
            d.stride = 4;
            d.position_size = 4;
            if ((rr = rast_draw(rc, &d)) != RAST_OK) goto done;
            tris += (long long)(buf.count / 12);
            for (ob = 0; ob < scene->object_count; ++ob) {
                int k;
                for (k = 0; k < 2; ++k)
                    if ((rr = refl__sv_draw_caps(rc, &objs[ob], k, zfail, mirrored, scissor, &tris)) != RAST_OK)
                        goto done;
            }
            queued = 0;
            if ((rr = rast_finish(rc)) != RAST_OK) goto done;
        }
        for (y = y0; y < y1; ++y)
            for (x = x0; x < x1; ++x) {
                i = (size_t)y * (size_t)width + (size_t)x;
                if ((region && region[i] != region_value) || !(depth[i] < 1.0f)) continue;
                if (scratch[i] || scratch[i] != scratch[npx + i]) lit[i] = (uint8_t)(lit[i] & ~(1u << li));
            }
    }

done:
    /* nothing queued may outlive the arrays it reads */
    if (queued || rr != RAST_OK) rast_finish(rc);
    if (r == REFL_OK && rr != RAST_OK) r = refl__result_from_rast(rr);
    if (objs)
        for (ob = 0; ob < inited; ++ob) refl__sv_object_free(scene, &objs[ob]);
    refl__free(al, objs);
    refl__free(al, scratch);
    refl__free(al, buf.v);
    {
        /* never leave the freed scratch bound: the caller's targets, or none */
        rast_targets none;
        rast_result rb;
        memset(&none, 0, sizeof none);
        rb = rast_set_targets(rc, job->restore ? job->restore : &none);
        if (r == REFL_OK && rb != RAST_OK) r = refl__result_from_rast(rb);
    }
    if (job->st) job->st->triangles += tris;
    return r;
}

static refl_result refl__shadow_mask(const refl__shadow_job *job, uint8_t *lit) {
    return refl__shadow_mask_mode(job, lit, REFL__SHADOW_AUTO, NULL);
}

/* ---- shading with the mask ---------------------------------------------------------- */

typedef struct refl__sv_shade {
    refl__draw_ctx dc;            /* first: the base pass's vertex program reads it */
    const uint8_t *lit;
    const unsigned char *table;   /* 256 rows of light_count flags: row b is lit byte b unpacked */
    int width, height, light_count, all_pixels;
    unsigned all_lit;             /* the bits of a pixel every light reaches */
    const uint16_t *counts;       /* soft: per light (< REFL__SHADOW_MAX_LIGHTS) a plane of
                                     width x height visible-sample counts; NULL: lit bytes */
    const int *samples;           /* soft: samples per light */
} refl__sv_shade;

/* Soft shadows' fragment: each light's Lambert term weighed by its visible
   fraction at the pixel, (float)count / (float)samples, as RAYTRACE's
   refl__rt_diffuse weighs it. light_count <= REFL__SV_SOFT_MAX_LIGHTS. */
enum { REFL__SV_SOFT_MAX_LIGHTS = 64 };
static int refl__sv_shade_soft_fragment(const refl__sv_shade *d, const rast_fragment_in *in, float rgba[4]) {
    const float *v = in->varyings;
    float rgb[3], weight[REFL__SV_SOFT_MAX_LIGHTS];
    int li, lights = REFL__MIN(d->light_count, REFL__SHADOW_MAX_LIGHTS), all_lit = 1;
    size_t i, npx = (size_t)d->width * (size_t)d->height;
    for (li = 0; li < d->light_count && li < REFL__SV_SOFT_MAX_LIGHTS; ++li) weight[li] = 1.0f;
    if (in->x >= 0 && in->y >= 0 && in->x < d->width && in->y < d->height) {
        i = (size_t)in->y * (size_t)d->width + (size_t)in->x;
        for (li = 0; li < lights; ++li) {
            int c = d->counts[(size_t)li * npx + i];
            if (c >= d->samples[li]) continue;
            weight[li] = (float)c / (float)d->samples[li];
            all_lit = 0;
        }
    }
    if (!d->all_pixels && all_lit) return 0; /* keeps the base pass's identical colour */
    refl_shade_diffuse_weighted(d->dc.scene, d->dc.material, refl_v3(v[0], v[1], v[2]), refl_v3(v[3], v[4], v[5]),
                                v + 6, weight, rgb);
    refl__surface_rgba(d->dc.material, rgb, rgba);
    return 1;
}

/* The base pass's fragment program with the pixel's lights. */
static int refl__sv_shade_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__sv_shade *d = (const refl__sv_shade *)user;
    const float *v = in->varyings;
    float rgb[3];
    unsigned b = 0xFFu;
    if (d->counts) return refl__sv_shade_soft_fragment(d, in, rgba);
    if (in->x >= 0 && in->y >= 0 && in->x < d->width && in->y < d->height)
        b = d->lit[(size_t)in->y * (size_t)d->width + (size_t)in->x];
    if (!d->all_pixels && (b & d->all_lit) == d->all_lit) return 0; /* keeps the base pass's identical colour */
    refl_shade_diffuse_lit(d->dc.scene, d->dc.material, refl_v3(v[0], v[1], v[2]), refl_v3(v[3], v[4], v[5]), v + 6,
                           d->table + (size_t)b * (size_t)d->light_count, rgb);
    refl__surface_rgba(d->dc.material, rgb, rgba);
    return 1;
}

/* refl__shade_lit, or with counts (refl__shadow_mask_soft's) the soft
   shadows' fractional visibility. */
static refl_result refl__shade_lit_ex(const refl__shadow_job *job, int skip, const uint8_t *lit,
                                      const uint16_t *counts, int samples, int all_pixels) {
    rast_context *rc = job->rc;
    const refl_scene *scene = job->scene;
    const refl_allocator *al;
    refl__sv_shade *dc = NULL;
    unsigned char *table = NULL;
    rast_result rr = RAST_OK;
    int i, b, lc, queued = 0, ns[REFL__SHADOW_MAX_LIGHTS];
    if (!rc || !scene || (!lit && !counts) || job->width <= 0 || job->height <= 0) return REFL_ERROR_INVALID_ARGUMENT;
    if (counts && scene->light_count > REFL__SV_SOFT_MAX_LIGHTS) return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < REFL__SHADOW_MAX_LIGHTS; ++i)
        ns[i] = i < scene->light_count && scene->lights[i].radius > 0.0f ? REFL__MAX(samples, 1) : 1;
    if (scene->object_count <= 0 || (scene->light_count <= 0 && !all_pixels)) return REFL_OK;
    al = &scene->allocator;
    lc = REFL__MAX(scene->light_count, 1);
    table = (unsigned char *)refl__alloc(al, 256 * (size_t)lc);
    dc = (refl__sv_shade *)refl__calloc(al, (size_t)scene->object_count, sizeof(refl__sv_shade));
    if (!table || !dc) {
        refl__free(al, table);
        refl__free(al, dc);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (b = 0; b < 256; ++b) /* lights beyond the byte's bits are lit */
        for (i = 0; i < lc; ++i)
            table[(size_t)b * (size_t)lc + (size_t)i] = (unsigned char)(i >= REFL__SHADOW_MAX_LIGHTS || ((b >> i) & 1));
    for (i = 0; i < scene->object_count && rr == RAST_OK; ++i) {
        const refl_object *o = &scene->objects[i];
        const refl_material *mat = &scene->materials[o->material];
        rast_state s;
        if (i == skip || (mat->type != REFL_DIFFUSE && mat->type != REFL_PARTIAL)) continue;
        refl__draw_ctx_init(&dc[i].dc, scene, i, job->vp);
        dc[i].lit = lit;
        dc[i].table = table;
        dc[i].width = job->width;
        dc[i].height = job->height;
        dc[i].light_count = lc;
        dc[i].all_pixels = all_pixels;
        dc[i].counts = counts;
        dc[i].samples = ns;
        dc[i].all_lit = (1u << REFL__MIN(scene->light_count, REFL__SHADOW_MAX_LIGHTS)) - 1u;
        memset(&s, 0, sizeof s);
        s.depth_test = 1;
        s.depth_func = RAST_EQUAL;
        s.depth_write_disabled = 1;
        if (job->region) { /* the bound stencil is the region */
            s.stencil_test = 1;
            s.stencil_front.func = RAST_EQUAL;
            s.stencil_front.ref = job->region_value;
            s.stencil_back = s.stencil_front;
        }
        s.vertex_fn = refl__base_vertex;
        s.vertex_user = &dc[i].dc;
        s.fragment_fn = refl__sv_shade_fragment;
        s.fragment_user = &dc[i];
        queued = 1;
        if ((rr = rast_set_state(rc, &s)) == RAST_OK) rr = refl__draw_mesh(rc, dc[i].dc.mesh, NULL, 0, REFL__BASE_VARYINGS);
        if (job->st) job->st->triangles += dc[i].dc.mesh->triangle_count;
    }
    /* finishing also drops what a failed draw left queued, before the
       contexts it reads are freed */
    if (queued) {
        rast_result rf = rast_finish(rc);
        if (rr == RAST_OK) rr = rf;
    }
    refl__free(al, table);
    refl__free(al, dc);
    return refl__result_from_rast(rr);
}

static refl_result refl__shade_lit(const refl__shadow_job *job, int skip, const uint8_t *lit, int all_pixels) {
    if (!lit) return REFL_ERROR_INVALID_ARGUMENT;
    return refl__shade_lit_ex(job, skip, lit, NULL, 0, all_pixels);
}

/* ---- soft shadows: the mask once per jittered light ----------------------------------- */

static int refl__soft_shadows(const refl_render_desc *desc, const refl_scene *scene) {
    return desc->lighting.shadows && desc->lighting.soft_shadow_samples > 1 && scene->light_count <= REFL__SV_SOFT_MAX_LIGHTS;
}

static refl_result refl__shadow_mask_soft(const refl__shadow_job *job, int samples, uint16_t *counts, uint8_t *lit) {
    const refl_scene *scene = job->scene;
    const uint8_t *region = job->region;
    const uint8_t region_value = job->region_value;
    const refl_allocator *al;
    refl_light *jit = NULL;
    refl_scene sc;
    refl__shadow_job jittered;
    refl_result r = REFL_OK;
    size_t npx, i;
    int idx[REFL__SHADOW_MAX_LIGHTS], li, j, k, lights, soft = 0, hard = 0;
    if (!job->rc || !scene || !job->depth || !counts || !lit || job->width <= 0 || job->height <= 0 || samples < 1)
        return REFL_ERROR_INVALID_ARGUMENT;
    al = &scene->allocator;
    npx = (size_t)job->width * (size_t)job->height;
    lights = REFL__MIN(scene->light_count, REFL__SHADOW_MAX_LIGHTS);
    for (li = 0; li < lights; ++li) {
        if (scene->lights[li].radius > 0.0f && samples > 1) idx[soft++] = li;
        else hard = 1;
    }
    for (li = 0; li < lights; ++li)
        for (i = 0; i < npx; ++i)
            if (!region || region[i] == region_value) counts[(size_t)li * npx + i] = 0;
    if (hard || lights == 0) { /* the lights without a radius: one mask, at their centres */
        r = refl__shadow_mask(job, lit);
        if (r != REFL_OK) return r;
        for (li = 0; li < lights; ++li) {
            if (scene->lights[li].radius > 0.0f && samples > 1) continue;
            for (i = 0; i < npx; ++i)
                if (!region || region[i] == region_value) counts[(size_t)li * npx + i] = (uint16_t)((lit[i] >> li) & 1);
        }
    }
    if (!soft) return REFL_OK;
    jit = (refl_light *)refl__alloc(al, (size_t)soft * sizeof(refl_light));
    if (!jit) return REFL_ERROR_OUT_OF_MEMORY;
    sc = *scene;
    sc.lights = jit;
    sc.light_count = soft;
    jittered = *job;
    jittered.scene = &sc;
    for (k = 0; k < samples && r == REFL_OK; ++k) {
        for (j = 0; j < soft; ++j) jit[j] = refl_light_sample(&scene->lights[idx[j]], k, samples);
        r = refl__shadow_mask(&jittered, lit);
        if (r != REFL_OK) break;
        for (j = 0; j < soft; ++j) {
            uint16_t *plane = counts + (size_t)idx[j] * npx;
            for (i = 0; i < npx; ++i)
                if ((!region || region[i] == region_value) && ((lit[i] >> j) & 1)) ++plane[i];
        }
    }
    refl__free(al, jit);
    return r;
}

static refl_result refl__shade_soft(const refl__shadow_job *job, int skip, const uint16_t *counts, int samples,
                                    int all_pixels) {
    if (!counts) return REFL_ERROR_INVALID_ARGUMENT;
    return refl__shade_lit_ex(job, skip, NULL, counts, samples, all_pixels);
}

static refl__shadow_job refl__shadow_job_of(const refl__pass *p, refl_mat4 vp, refl_vec3 eye) {
    refl__shadow_job job;
    memset(&job, 0, sizeof job);
    job.rc = p->rc;
    job.scene = p->scene;
    job.vp = vp;
    job.eye = eye;
    job.depth = p->frame->depth;
    job.width = p->frame->width;
    job.height = p->frame->height;
    job.st = &p->frame->stats;
    return job;
}

/* DIRECT's (and every method's) base pass with shadows: the mask over the
   whole frame, then the shadowed pixels shaded again. The frame stays bound. */
static refl_result refl__shadow_base_pass(refl__pass *p) {
    refl_frame *f = p->frame;
    const refl_scene *scene = p->scene;
    uint8_t *lit;
    rast_targets t;
    refl_result r;
    size_t npx = (size_t)f->width * (size_t)f->height;
    uint16_t *counts = NULL;
    refl__shadow_job job;
    int soft = refl__soft_shadows(&p->desc, scene);
    lit = (uint8_t *)refl__alloc(&scene->allocator, npx);
    if (soft) counts = (uint16_t *)refl__calloc(&scene->allocator, npx * REFL__SHADOW_MAX_LIGHTS, sizeof(uint16_t));
    if (!lit || (soft && !counts)) {
        refl__free(&scene->allocator, lit);
        refl__free(&scene->allocator, counts);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    t = refl__frame_targets(f);
    job = refl__shadow_job_of(p, p->vp, p->view->eye);
    job.restore = &t;
    if (soft) {
        r = refl__shadow_mask_soft(&job, p->desc.lighting.soft_shadow_samples, counts, lit);
        if (r == REFL_OK) r = refl__shade_soft(&job, -1, counts, p->desc.lighting.soft_shadow_samples, 0);
    } else {
        r = refl__shadow_mask(&job, lit);
        if (r == REFL_OK) r = refl__shade_lit(&job, -1, lit, 0);
    }
    refl__free(&scene->allocator, lit);
    refl__free(&scene->allocator, counts);
    return r;
}
