/* Meshes: creation (validated copies, angle-weighted normals), bounds,
   subdivision to a maximum edge length, and area-uniform point sampling.

   NORMALS
       Missing normals, and given ones that are zero or not finite, are the
       angle-weighted average of the adjacent face normals (Thurmer and
       Wuthrich), accumulated in double. Triangles whose sine of the largest
       angle is below 1e-12 (collinear or repeated vertices) add nothing; a
       vertex without any other triangle gets (0, 1, 0). The angles come
       from a series, not libm, so the normals (and the sampled normals
       after them) are the same bits on every machine.

   SUBDIVISION
       Rounds: every undirected edge longer than max_edge gets one midpoint
       vertex (an edge map keyed by (min, max) index, so both triangles of
       an edge agree and there are no T-junctions); each triangle is then
       re-cut by how many of its edges split: 1 -> 2 triangles, 2 -> 3 (the
       quad cut by its shorter diagonal), 3 -> 4. New vertices are numbered
       in order of first appearance, so the result is deterministic.
       Attributes are interpolated at midpoints (normals renormalised). More
       than 2^26 triangles is REFL_ERROR_INVALID_SIZE, checked up front by a
       lower bound (edge pieces and area) and again every round.

   SAMPLING
       Count: floor(area * density), plus one with probability equal to the
       fraction (the first draw of the stream): the expected count is exactly
       area * density. Each point then takes two draws for a 53-bit uniform
       that picks its triangle by binary search in the cumulative areas
       (double, transformed triangles), and two floats r1, r2 for the point
       (1 - sqrt r1, sqrt r1 (1 - r2), sqrt r1 r2). More than 2^28 expected
       points is REFL_ERROR_INVALID_SIZE. Only IEEE arithmetic and
       sqrt: the same points on every machine, provided the compiler does
       not fuse multiply-adds (clang is told not to here; GCC fuses only
       in GNU modes on FMA targets such as aarch64: build the
       implementation with -ffp-contract=off there). */
#include "internal.h"

#define REFL__MAX_TRIANGLES (1 << 26)

/* ---- allocation ---------------------------------------------------------- */

static void refl__mesh_free(refl_mesh *m) {
    refl_allocator a;
    if (!m) return;
    a = m->allocator;
    refl__free(&a, m->positions);
    refl__free(&a, m->normals);
    refl__free(&a, m->texcoords);
    refl__free(&a, m->colors);
    refl__free(&a, m->indices);
    refl__free(&a, m);
}

/* A mesh with uninitialised arrays of the given sizes. */
static refl_result refl__mesh_alloc(const refl_allocator *a, int vertex_count, int triangle_count, int tex,
                                    int col, refl_mesh **out) {
    refl_mesh *m;
    size_t nv = (size_t)vertex_count, nt = (size_t)triangle_count;
    *out = NULL;
    if (nv > (size_t)-1 / (4 * sizeof(float)) || nt > (size_t)-1 / (3 * sizeof(uint32_t)))
        return REFL_ERROR_INVALID_SIZE;
    m = (refl_mesh *)refl__calloc(a, 1, sizeof(refl_mesh));
    if (!m) return REFL_ERROR_OUT_OF_MEMORY;
    m->allocator = refl__allocator(a);
    m->vertex_count = vertex_count;
    m->triangle_count = triangle_count;
    m->positions = (float *)refl__alloc(a, nv * 3 * sizeof(float));
    m->normals = (float *)refl__alloc(a, nv * 3 * sizeof(float));
    m->indices = (uint32_t *)refl__alloc(a, nt * 3 * sizeof(uint32_t));
    if (tex) m->texcoords = (float *)refl__alloc(a, nv * 2 * sizeof(float));
    if (col) m->colors = (float *)refl__alloc(a, nv * 4 * sizeof(float));
    if (!m->positions || !m->normals || !m->indices || (tex && !m->texcoords) || (col && !m->colors)) {
        refl__mesh_free(m);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    *out = m;
    return REFL_OK;
}

/* ---- normals ----------------------------------------------------------------- */

/* atan t for |t| <= 1 by the series after one reduction to |t| <= tan(pi/8)
   (error below 1e-11): plain arithmetic, the same bits everywhere. */
static double refl__atan_unit(double t) {
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif
    double off = 0.0, t2, term, s;
    int k;
    if (t > 0.41421356237309503) {
        off = REFL__PI / 4;
        t = (t - 1.0) / (t + 1.0);
    } else if (t < -0.41421356237309503) {
        off = -REFL__PI / 4;
        t = (t + 1.0) / (1.0 - t);
    }
    t2 = t * t;
    term = t;
    s = 0.0;
    for (k = 0; k < 14; ++k) {
        s += (k & 1 ? -term : term) / (double)(2 * k + 1);
        term *= t2;
    }
    return off + s;
}

/* atan2(y, x) for y >= 0: an angle in [0, pi]. */
static double refl__angle(double y, double x) {
    if (x > 0.0 && x >= y) return refl__atan_unit(y / x);
    if (x < 0.0 && -x >= y) return REFL__PI - refl__atan_unit(y / -x);
    if (y == 0.0) return 0.0;
    return REFL__PI / 2 - refl__atan_unit(x / y);
}

/* Fills m->normals: the given ones normalised where usable, the
   angle-weighted ones elsewhere. */
static refl_result refl__mesh_normals(refl_mesh *m, const float *given) {
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif
    const refl_allocator *a = &m->allocator;
    double *acc;
    int v, t, k, need = given == NULL;
    if (given) {
        for (v = 0; v < m->vertex_count; ++v) {
            double x = given[3 * v], y = given[3 * v + 1], z = given[3 * v + 2], l = sqrt(x * x + y * y + z * z);
            if (l > 0.0 && l <= DBL_MAX) {
                m->normals[3 * v] = (float)(x / l);
                m->normals[3 * v + 1] = (float)(y / l);
                m->normals[3 * v + 2] = (float)(z / l);
            } else {
                m->normals[3 * v] = m->normals[3 * v + 1] = m->normals[3 * v + 2] = 0.0f;
                need = 1; /* NaN lengths land here too */
            }
        }
    }
    if (!need) return REFL_OK;
    if (!given) memset(m->normals, 0, (size_t)m->vertex_count * 3 * sizeof(float));
    acc = (double *)refl__calloc(a, (size_t)m->vertex_count * 3, sizeof(double));
    if (!acc) return REFL_ERROR_OUT_OF_MEMORY;
    for (t = 0; t < m->triangle_count; ++t) {
        const uint32_t *tri = m->indices + 3 * t;
        double p[3][3], e[3][3], n[3], l2[3], c2, lmax, cl;
        for (k = 0; k < 3; ++k) {
            p[k][0] = m->positions[3 * tri[k]];
            p[k][1] = m->positions[3 * tri[k] + 1];
            p[k][2] = m->positions[3 * tri[k] + 2];
        }
        for (k = 0; k < 3; ++k) { /* e[k] = p[k+1] - p[k] */
            int j = (k + 1) % 3;
            e[k][0] = p[j][0] - p[k][0];
            e[k][1] = p[j][1] - p[k][1];
            e[k][2] = p[j][2] - p[k][2];
            l2[k] = e[k][0] * e[k][0] + e[k][1] * e[k][1] + e[k][2] * e[k][2];
        }
        n[0] = e[0][1] * e[2][2] - e[0][2] * e[2][1];
        n[1] = e[0][2] * e[2][0] - e[0][0] * e[2][2];
        n[2] = e[0][0] * e[2][1] - e[0][1] * e[2][0];
        n[0] = -n[0]; n[1] = -n[1]; n[2] = -n[2]; /* (p1 - p0) x (p2 - p0) */
        c2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
        lmax = REFL__MAX(REFL__MAX(l2[0], l2[1]), l2[2]);
        if (!(c2 > 1e-24 * lmax * lmax)) continue; /* degenerate */
        cl = sqrt(c2);
        for (k = 0; k < 3; ++k) {
            /* the corner at p[k], between e[k] and -e[k-1]; |cross| = cl */
            const double *ea = e[k], *eb = e[(k + 2) % 3];
            double dot = -(ea[0] * eb[0] + ea[1] * eb[1] + ea[2] * eb[2]);
            double w = refl__angle(cl, dot) / cl;
            double *o = acc + 3 * (size_t)tri[k];
            o[0] += w * n[0];
            o[1] += w * n[1];
            o[2] += w * n[2];
        }
    }
    for (v = 0; v < m->vertex_count; ++v) {
        float *o = m->normals + 3 * v;
        const double *s = acc + 3 * v;
        double l = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
        if (o[0] != 0.0f || o[1] != 0.0f || o[2] != 0.0f) continue; /* a usable given one */
        if (l > 0.0 && l <= DBL_MAX) {
            o[0] = (float)(s[0] / l);
            o[1] = (float)(s[1] / l);
            o[2] = (float)(s[2] / l);
        } else {
            o[0] = 0.0f; o[1] = 1.0f; o[2] = 0.0f;
        }
    }
    refl__free(a, acc);
    return REFL_OK;
}

/* ---- creation ------------------------------------------------------------------ */

REFL_API refl_result refl_mesh_create(const refl_mesh_desc *desc, refl_mesh **out_mesh) {
    refl_mesh *m;
    refl_result r;
    int nidx, v, i;
    if (!out_mesh) return REFL_ERROR_INVALID_ARGUMENT;
    *out_mesh = NULL;
    if (!desc || !desc->positions) return REFL_ERROR_INVALID_ARGUMENT;
    if ((desc->allocator.alloc != NULL) != (desc->allocator.free != NULL)) return REFL_ERROR_INVALID_ARGUMENT;
    if (desc->vertex_count < 0 || desc->index_count < 0) return REFL_ERROR_INVALID_SIZE;
    if (!desc->indices && desc->index_count != 0) return REFL_ERROR_INVALID_ARGUMENT;
    nidx = desc->indices ? desc->index_count : desc->vertex_count;
    if (nidx % 3 != 0) return REFL_ERROR_INVALID_SIZE;
    if (desc->vertex_count == 0 || nidx == 0) return REFL_ERROR_BAD_MESH;
    for (i = 0; desc->indices && i < nidx; ++i)
        if (desc->indices[i] >= (uint32_t)desc->vertex_count) return REFL_ERROR_BAD_MESH;
    for (v = 0; v < 3 * desc->vertex_count; ++v)
        if (!refl__isfinite(desc->positions[v])) return REFL_ERROR_BAD_MESH;
    r = refl__mesh_alloc(&desc->allocator, desc->vertex_count, nidx / 3, desc->texcoords != NULL,
                         desc->colors != NULL, &m);
    if (r != REFL_OK) return r;
    memcpy(m->positions, desc->positions, (size_t)desc->vertex_count * 3 * sizeof(float));
    if (desc->texcoords) memcpy(m->texcoords, desc->texcoords, (size_t)desc->vertex_count * 2 * sizeof(float));
    if (desc->colors) memcpy(m->colors, desc->colors, (size_t)desc->vertex_count * 4 * sizeof(float));
    if (desc->indices) memcpy(m->indices, desc->indices, (size_t)nidx * sizeof(uint32_t));
    else
        for (i = 0; i < nidx; ++i) m->indices[i] = (uint32_t)i;
    if ((r = refl__mesh_normals(m, desc->normals)) != REFL_OK) {
        refl__mesh_free(m);
        return r;
    }
    *out_mesh = m;
    return REFL_OK;
}

REFL_API void refl_mesh_destroy(refl_mesh *mesh) { refl__mesh_free(mesh); }

static void refl__mesh_used_bounds(const refl_mesh *mesh, refl_vec3 *lo, refl_vec3 *hi) {
    refl_vec3 l = refl_v3(FLT_MAX, FLT_MAX, FLT_MAX), h = refl_v3(-FLT_MAX, -FLT_MAX, -FLT_MAX);
    size_t k, count = mesh && mesh->indices ? 3 * (size_t)mesh->triangle_count : 0;
    for (k = 0; k < count; ++k) {
        const float *q = mesh->positions + 3 * (size_t)mesh->indices[k];
        l = refl__v3_min(l, refl_v3(q[0], q[1], q[2]));
        h = refl__v3_max(h, refl_v3(q[0], q[1], q[2]));
    }
    if (!count) {
        refl_mesh_bounds(mesh, lo, hi);
        return;
    }
    *lo = l;
    *hi = h;
}

/* Empty or NULL meshes: both corners at the origin. */
REFL_API void refl_mesh_bounds(const refl_mesh *mesh, refl_vec3 *lo, refl_vec3 *hi) {
    refl_vec3 l = refl_v3(0.0f, 0.0f, 0.0f), h = l;
    int v;
    if (mesh && mesh->positions && mesh->vertex_count > 0) {
        const float *p = mesh->positions;
        l = h = refl_v3(p[0], p[1], p[2]);
        for (v = 1; v < mesh->vertex_count; ++v) {
            const float *q = p + 3 * v;
            l.x = REFL__MIN(l.x, q[0]); l.y = REFL__MIN(l.y, q[1]); l.z = REFL__MIN(l.z, q[2]);
            h.x = REFL__MAX(h.x, q[0]); h.y = REFL__MAX(h.y, q[1]); h.z = REFL__MAX(h.z, q[2]);
        }
    }
    if (lo) *lo = l;
    if (hi) *hi = h;
}

/* ---- subdivision ------------------------------------------------------------------ */

/* Open-addressing map from an undirected edge to its midpoint vertex. */
typedef struct refl__edge_map {
    uint64_t *keys; /* (min << 32 | max) + 1; 0: empty */
    uint32_t *values;
    size_t mask;
} refl__edge_map;

static size_t refl__edge_slot(const refl__edge_map *em, uint64_t key) {
    uint64_t h = key * 0x9E3779B97F4A7C15ull;
    size_t i = (size_t)(h >> 20) & em->mask;
    while (em->keys[i] != 0 && em->keys[i] != key) i = (i + 1) & em->mask;
    return i;
}

static uint64_t refl__edge_key(uint32_t u, uint32_t v) {
    return u < v ? ((uint64_t)u << 32 | v) + 1 : ((uint64_t)v << 32 | u) + 1;
}

static double refl__dist2(const float *p, uint32_t u, uint32_t v) {
    double dx = (double)p[3 * u] - p[3 * v], dy = (double)p[3 * u + 1] - p[3 * v + 1],
           dz = (double)p[3 * u + 2] - p[3 * v + 2];
    return dx * dx + dy * dy + dz * dz;
}

/* Midpoint vertex d of the edge (u, v), u < v. */
static void refl__midpoint(refl_mesh *o, const refl_mesh *s, uint32_t u, uint32_t v, uint32_t d) {
    double n[3], l;
    int k;
    for (k = 0; k < 3; ++k) {
        o->positions[3 * d + k] = (float)(0.5 * ((double)s->positions[3 * u + k] + s->positions[3 * v + k]));
        n[k] = (double)s->normals[3 * u + k] + s->normals[3 * v + k];
    }
    l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (k = 0; k < 3; ++k) /* opposite normals: keep u's */
        o->normals[3 * d + k] = l > 0.0 && l <= DBL_MAX ? (float)(n[k] / l) : s->normals[3 * u + k];
    if (s->texcoords)
        for (k = 0; k < 2; ++k)
            o->texcoords[2 * d + k] = (float)(0.5 * ((double)s->texcoords[2 * u + k] + s->texcoords[2 * v + k]));
    if (s->colors)
        for (k = 0; k < 4; ++k)
            o->colors[4 * d + k] = (float)(0.5 * ((double)s->colors[4 * u + k] + s->colors[4 * v + k]));
}

static uint32_t *refl__emit(uint32_t *o, uint32_t a, uint32_t b, uint32_t c) {
    o[0] = a; o[1] = b; o[2] = c;
    return o + 3;
}

/* One round: *out is NULL when no edge is longer than max_edge. */
static refl_result refl__subdivide_round(const refl_mesh *s, double max2, refl_mesh **out) {
    const refl_allocator *a = &s->allocator;
    refl__edge_map em;
    refl_mesh *o = NULL;
    refl_result r;
    size_t cap = 16, i;
    long long splits = 0, tris = 0;
    int t, k;
    *out = NULL;
    while (cap < (size_t)s->triangle_count * 6) cap *= 2;
    em.mask = cap - 1;
    em.keys = (uint64_t *)refl__calloc(a, cap, sizeof(uint64_t));
    em.values = (uint32_t *)refl__alloc(a, cap * sizeof(uint32_t));
    if (!em.keys || !em.values) {
        r = REFL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    for (t = 0; t < s->triangle_count; ++t) {
        const uint32_t *tri = s->indices + 3 * t;
        int n = 0;
        for (k = 0; k < 3; ++k) {
            uint32_t u = tri[k], v = tri[(k + 1) % 3];
            uint64_t key = refl__edge_key(u, v);
            if (u == v || !(refl__dist2(s->positions, REFL__MIN(u, v), REFL__MAX(u, v)) > max2)) continue;
            ++n;
            i = refl__edge_slot(&em, key);
            if (em.keys[i] == 0) {
                em.keys[i] = key;
                em.values[i] = (uint32_t)(s->vertex_count + splits++);
            }
        }
        tris += 1 + n;
    }
    r = REFL_OK;
    if (splits == 0) goto done;
    if (tris > REFL__MAX_TRIANGLES || s->vertex_count + splits > INT_MAX) {
        r = REFL_ERROR_INVALID_SIZE;
        goto done;
    }
    r = refl__mesh_alloc(a, (int)(s->vertex_count + splits), (int)tris, s->texcoords != NULL, s->colors != NULL, &o);
    if (r != REFL_OK) goto done;
    memcpy(o->positions, s->positions, (size_t)s->vertex_count * 3 * sizeof(float));
    memcpy(o->normals, s->normals, (size_t)s->vertex_count * 3 * sizeof(float));
    if (s->texcoords) memcpy(o->texcoords, s->texcoords, (size_t)s->vertex_count * 2 * sizeof(float));
    if (s->colors) memcpy(o->colors, s->colors, (size_t)s->vertex_count * 4 * sizeof(float));
    for (i = 0; i < cap; ++i)
        if (em.keys[i]) {
            uint64_t key = em.keys[i] - 1;
            refl__midpoint(o, s, (uint32_t)(key >> 32), (uint32_t)key, em.values[i]);
        }
    {
        uint32_t *dst = o->indices;
        for (t = 0; t < s->triangle_count; ++t) {
            const uint32_t *tri = s->indices + 3 * t;
            uint32_t v[3], mid[3] = {0, 0, 0}, ms[3];
            int split[3], n = 0, first = 0;
            for (k = 0; k < 3; ++k) {
                uint32_t u = tri[k], w = tri[(k + 1) % 3];
                split[k] = 0;
                if (u != w) {
                    i = refl__edge_slot(&em, refl__edge_key(u, w));
                    if (em.keys[i]) {
                        split[k] = 1;
                        mid[k] = em.values[i];
                        ++n;
                    }
                }
            }
            /* rotate: the split edge first (n = 1), the unsplit one last (n = 2) */
            for (k = 0; k < 3; ++k)
                if ((n == 1 && split[k]) || (n == 2 && !split[(k + 2) % 3])) first = k;
            for (k = 0; k < 3; ++k) {
                int j = (first + k) % 3;
                v[k] = tri[j];
                ms[k] = split[j] ? mid[j] : 0;
            }
            if (n == 0) {
                dst = refl__emit(dst, v[0], v[1], v[2]);
            } else if (n == 1) { /* edge v0 v1 split */
                dst = refl__emit(dst, v[0], ms[0], v[2]);
                dst = refl__emit(dst, ms[0], v[1], v[2]);
            } else if (n == 2) { /* v0 v1 and v1 v2 split; the quad v0 m0 m1 v2 */
                dst = refl__emit(dst, ms[0], v[1], ms[1]);
                if (refl__dist2(o->positions, v[0], ms[1]) <= refl__dist2(o->positions, ms[0], v[2])) {
                    dst = refl__emit(dst, v[0], ms[0], ms[1]);
                    dst = refl__emit(dst, v[0], ms[1], v[2]);
                } else {
                    dst = refl__emit(dst, v[0], ms[0], v[2]);
                    dst = refl__emit(dst, ms[0], ms[1], v[2]);
                }
            } else {
                dst = refl__emit(dst, v[0], ms[0], ms[2]);
                dst = refl__emit(dst, ms[0], v[1], ms[1]);
                dst = refl__emit(dst, ms[2], ms[1], v[2]);
                dst = refl__emit(dst, ms[0], ms[1], ms[2]);
            }
        }
    }
    *out = o;
done:
    refl__free(a, em.keys);
    refl__free(a, em.values);
    return r;
}

/* A copy of a mesh (same allocator). */
static refl_result refl__mesh_copy(const refl_mesh *s, refl_mesh **out) {
    refl_mesh *o;
    refl_result r = refl__mesh_alloc(&s->allocator, s->vertex_count, s->triangle_count, s->texcoords != NULL,
                                     s->colors != NULL, &o);
    size_t nv = (size_t)s->vertex_count;
    *out = NULL;
    if (r != REFL_OK) return r;
    memcpy(o->positions, s->positions, nv * 3 * sizeof(float));
    memcpy(o->normals, s->normals, nv * 3 * sizeof(float));
    if (s->texcoords) memcpy(o->texcoords, s->texcoords, nv * 2 * sizeof(float));
    if (s->colors) memcpy(o->colors, s->colors, nv * 4 * sizeof(float));
    memcpy(o->indices, s->indices, (size_t)s->triangle_count * 3 * sizeof(uint32_t));
    *out = o;
    return REFL_OK;
}

REFL_API refl_result refl_mesh_subdivide(const refl_mesh *mesh, float max_edge, refl_mesh **out_mesh) {
    refl_mesh *cur = NULL, *next;
    double max2 = (double)max_edge * max_edge, bound = 0.0;
    int t, round;
    if (!out_mesh) return REFL_ERROR_INVALID_ARGUMENT;
    *out_mesh = NULL;
    if (!mesh || !mesh->positions || !mesh->normals || !mesh->indices) return REFL_ERROR_INVALID_ARGUMENT;
    if (!(max_edge > 0.0f)) return REFL_ERROR_INVALID_ARGUMENT; /* NaN too */
    /* Lower bound of the result, per triangle: its longest edge ends up in
       at least 2^j pieces, each on its own triangle, where j is how often
       it halves while staying clearly above max_edge; and its area is
       covered by triangles of area at most sqrt(3)/4 max_edge^2. */
    for (t = 0; t < mesh->triangle_count && bound <= REFL__MAX_TRIANGLES; ++t) {
        const uint32_t *tri = mesh->indices + 3 * t;
        const float *p = mesh->positions;
        double e1[3], e2[3], c[3], area, pieces = 1.0;
        double l2 = REFL__MAX(REFL__MAX(refl__dist2(p, tri[0], tri[1]), refl__dist2(p, tri[1], tri[2])),
                              refl__dist2(p, tri[2], tri[0]));
        int k;
        for (k = 0; k < 3; ++k) {
            e1[k] = (double)p[3 * tri[1] + k] - p[3 * tri[0] + k];
            e2[k] = (double)p[3 * tri[2] + k] - p[3 * tri[0] + k];
        }
        c[0] = e1[1] * e2[2] - e1[2] * e2[1];
        c[1] = e1[2] * e2[0] - e1[0] * e2[2];
        c[2] = e1[0] * e2[1] - e1[1] * e2[0];
        area = 0.5 * sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        while (l2 > max2 * 1.0001 && pieces <= REFL__MAX_TRIANGLES) {
            pieces *= 2.0;
            l2 *= 0.25;
        }
        bound += REFL__MAX(pieces, 0.999 * area / (0.43301270189221935 * max2));
    }
    if (bound > REFL__MAX_TRIANGLES) return REFL_ERROR_INVALID_SIZE;
    /* Edges shrink towards max_edge geometrically; 200 rounds is far beyond
       any mesh the bound lets through. */
    for (round = 0; round < 200; ++round) {
        refl_result r = refl__subdivide_round(cur ? cur : mesh, max2, &next);
        if (r != REFL_OK) {
            refl__mesh_free(cur);
            return r;
        }
        if (!next) break;
        refl__mesh_free(cur);
        cur = next;
    }
    if (round == 200) {
        refl__mesh_free(cur);
        return REFL_ERROR_INVALID_SIZE;
    }
    if (!cur) return refl__mesh_copy(mesh, out_mesh);
    *out_mesh = cur;
    return REFL_OK;
}

/* ---- point sampling ------------------------------------------------------------------ */

/* Uniform in [0, 1) with 53 bits, from two draws. */
static double refl__rng_double(refl_rng *rng) {
    uint32_t hi = refl_rng_u32(rng) >> 5, lo = refl_rng_u32(rng) >> 6;
    return ((double)hi * 67108864.0 + (double)lo) * (1.0 / 9007199254740992.0);
}

REFL_API refl_result refl_mesh_sample_points(const refl_mesh *mesh, const refl_mat4 *transform, float density,
                                             uint64_t seed, const refl_allocator *allocator,
                                             refl_points **out_points) {
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif
    refl_allocator al = refl__allocator(allocator);
    refl_points *pts = NULL;
    refl_rng rng = refl_rng_seed(seed);
    double *tp = NULL, *cum = NULL, m[16], cof[9], det, sgn, total = 0.0, expect;
    long long count;
    int v, t, i, k;
    if (!out_points) return REFL_ERROR_INVALID_ARGUMENT;
    *out_points = NULL;
    if (!mesh || !mesh->positions || !mesh->normals || !mesh->indices || mesh->vertex_count <= 0 ||
        mesh->triangle_count <= 0)
        return REFL_ERROR_INVALID_ARGUMENT;
    if ((al.alloc != NULL) != (al.free != NULL)) return REFL_ERROR_INVALID_ARGUMENT;
    if (!(density >= 0.0f) || !refl__isfinite(density)) return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < 16; ++i) m[i] = transform ? transform->m[i] : (i % 5 == 0);
    /* normals go through the cofactor matrix (det times the inverse
       transpose) with det's sign: the inverse transpose up to scale, and
       defined when the transform flattens */
    cof[0] = m[5] * m[10] - m[6] * m[9];
    cof[1] = m[6] * m[8] - m[4] * m[10];
    cof[2] = m[4] * m[9] - m[5] * m[8];
    cof[3] = m[9] * m[2] - m[10] * m[1];
    cof[4] = m[10] * m[0] - m[8] * m[2];
    cof[5] = m[8] * m[1] - m[9] * m[0];
    cof[6] = m[1] * m[6] - m[2] * m[5];
    cof[7] = m[2] * m[4] - m[0] * m[6];
    cof[8] = m[0] * m[5] - m[1] * m[4];
    det = m[0] * cof[0] + m[1] * cof[1] + m[2] * cof[2];
    sgn = det < 0.0 ? -1.0 : 1.0;
    tp = (double *)refl__alloc(&al, (size_t)mesh->vertex_count * 3 * sizeof(double));
    cum = (double *)refl__alloc(&al, (size_t)mesh->triangle_count * sizeof(double));
    if (!tp || !cum) {
        refl__free(&al, tp);
        refl__free(&al, cum);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (v = 0; v < mesh->vertex_count; ++v) { /* as refl_mat4_point, in double */
        const float *p = mesh->positions + 3 * v;
        double w = m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15];
        for (k = 0; k < 3; ++k) {
            double c = m[k] * p[0] + m[4 + k] * p[1] + m[8 + k] * p[2] + m[12 + k];
            tp[3 * v + k] = w != 1.0 && w != 0.0 ? c / w : c;
        }
    }
    for (t = 0; t < mesh->triangle_count; ++t) {
        const uint32_t *tri = mesh->indices + 3 * t;
        const double *a = tp + 3 * tri[0], *b = tp + 3 * tri[1], *c = tp + 3 * tri[2];
        double e1[3], e2[3], n[3];
        for (k = 0; k < 3; ++k) {
            e1[k] = b[k] - a[k];
            e2[k] = c[k] - a[k];
        }
        n[0] = e1[1] * e2[2] - e1[2] * e2[1];
        n[1] = e1[2] * e2[0] - e1[0] * e2[2];
        n[2] = e1[0] * e2[1] - e1[1] * e2[0];
        total += 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        cum[t] = total;
    }
    if (!(total <= DBL_MAX)) { /* NaN or infinite: the transform */
        refl__free(&al, tp);
        refl__free(&al, cum);
        return REFL_ERROR_INVALID_ARGUMENT;
    }
    expect = total * density;
    if (!(expect <= (double)(1 << 28))) {
        refl__free(&al, tp);
        refl__free(&al, cum);
        return REFL_ERROR_INVALID_SIZE;
    }
    count = (long long)expect;
    if ((double)refl_rng_float(&rng) < expect - (double)count) ++count;
    pts = (refl_points *)refl__calloc(&al, 1, sizeof(refl_points));
    if (pts) {
        pts->allocator = al;
        pts->count = (int)count;
        pts->positions = (float *)refl__alloc(&al, (size_t)count * 3 * sizeof(float));
        pts->normals = (float *)refl__alloc(&al, (size_t)count * 3 * sizeof(float));
        pts->triangles = (uint32_t *)refl__alloc(&al, (size_t)count * sizeof(uint32_t));
    }
    if (!pts || !pts->positions || !pts->normals || !pts->triangles) {
        refl_points_destroy(pts);
        refl__free(&al, tp);
        refl__free(&al, cum);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < (int)count; ++i) {
        double target = refl__rng_double(&rng) * total, r1, r2, s, bc[3], nn[3], no[3], l;
        const uint32_t *tri;
        int lo = 0, hi = mesh->triangle_count - 1;
        while (lo < hi) { /* the first triangle with cum > target */
            int mid = lo + (hi - lo) / 2;
            if (cum[mid] > target) hi = mid;
            else lo = mid + 1;
        }
        tri = mesh->indices + 3 * lo;
        r1 = refl_rng_float(&rng);
        r2 = refl_rng_float(&rng);
        s = sqrt(r1);
        bc[0] = 1.0 - s;
        bc[1] = s * (1.0 - r2);
        bc[2] = s * r2;
        for (k = 0; k < 3; ++k) {
            pts->positions[3 * i + k] =
                (float)(bc[0] * tp[3 * tri[0] + k] + bc[1] * tp[3 * tri[1] + k] + bc[2] * tp[3 * tri[2] + k]);
            no[k] = bc[0] * mesh->normals[3 * tri[0] + k] + bc[1] * mesh->normals[3 * tri[1] + k] +
                    bc[2] * mesh->normals[3 * tri[2] + k];
        }
        for (k = 0; k < 3; ++k) nn[k] = sgn * (cof[k] * no[0] + cof[3 + k] * no[1] + cof[6 + k] * no[2]);
        l = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
        if (!(l > 0.0) || l > DBL_MAX) { /* the face normal */
            const double *a = tp + 3 * tri[0], *b = tp + 3 * tri[1], *c = tp + 3 * tri[2];
            nn[0] = sgn * ((b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]));
            nn[1] = sgn * ((b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2]));
            nn[2] = sgn * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
            l = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
            if (!(l > 0.0) || l > DBL_MAX) {
                nn[0] = 0.0; nn[1] = 1.0; nn[2] = 0.0;
                l = 1.0;
            }
        }
        for (k = 0; k < 3; ++k) pts->normals[3 * i + k] = (float)(nn[k] / l);
        pts->triangles[i] = (uint32_t)lo;
    }
    refl__free(&al, tp);
    refl__free(&al, cum);
    *out_points = pts;
    return REFL_OK;
}

REFL_API void refl_points_destroy(refl_points *points) {
    refl_allocator a;
    if (!points) return;
    a = points->allocator;
    refl__free(&a, points->positions);
    refl__free(&a, points->normals);
    refl__free(&a, points->triangles);
    refl__free(&a, points);
}
