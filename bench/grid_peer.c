/* grid_peer.c - a uniform grid ray caster, refl_bvh's peer (grid_peer.h). */
#include "grid_peer.h"

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Triangles' bounds are widened by this share of a cell before they are
   binned, so a hit on a cell's face is in the cells on both sides of it
   whatever the rounding: the walk may then stop at the first cell past
   which nothing can come closer. */
#define GRID_PAD_CELLS 1e-3f
/* Cells at most in all (memory: a start index each). */
#define GRID_MAX_CELLS (1LL << 26)

typedef struct grid_tri {
    float v[9];              /* world space, as refl_bvh takes them */
    int object, triangle;
    int lo[3], hi[3];        /* the cells its (widened) bounds overlap, inclusive */
} grid_tri;

struct refl_grid {
    unsigned char *objects;  /* per scene object, 1: in the grid */
    int object_count;
    grid_tri *tris;
    int tri_count;
    int res[3];
    float lo[3], cell[3], inv_cell[3];
    unsigned *start;         /* per cell, its first reference; res product + 1 */
    unsigned *items;         /* triangle indices, cell by cell */
    long long references;
    long long rays, tests;   /* counted with atomic adds */
};

/* The chosen objects' world triangles into g->tris; 0 on failure. */
static int grid_gather(refl_grid *g, const refl_scene *s, const unsigned char *objects) {
    long long n = 0;
    int i, t, j, pass;
    for (pass = 0; pass < 2; ++pass) {
        for (i = 0; i < s->object_count; ++i) {
            const refl_object *o = &s->objects[i];
            const refl_mesh *m = s->meshes[o->mesh];
            if (objects && !objects[i]) continue;
            for (t = 0; t < m->triangle_count; ++t) {
                grid_tri tri;
                for (j = 0; j < 3; ++j) {
                    uint32_t vi = m->indices[3 * (size_t)t + (size_t)j];
                    refl_vec3 w;
                    if (vi >= (uint32_t)m->vertex_count) return 0;
                    w = refl_mat4_point(o->transform, refl_v3(m->positions[3 * (size_t)vi], m->positions[3 * (size_t)vi + 1],
                                                              m->positions[3 * (size_t)vi + 2]));
                    tri.v[3 * j] = w.x;
                    tri.v[3 * j + 1] = w.y;
                    tri.v[3 * j + 2] = w.z;
                }
                for (j = 0; j < 9 && isfinite(tri.v[j]); ++j) {}
                if (j < 9) continue; /* as refl_bvh: a degenerate one stays, refl_ray_triangle never hits it */
                if (pass == 1) {
                    tri.object = i;
                    tri.triangle = t;
                    g->tris[g->tri_count++] = tri;
                }
                ++n;
            }
        }
        if (pass == 0) {
            if (n > INT_MAX) return 0;
            g->tris = (grid_tri *)malloc((size_t)(n > 0 ? n : 1) * sizeof *g->tris);
            if (!g->tris) return 0;
        }
    }
    return 1;
}

/* The grid's bounds, widened a little (a flat set of triangles gets some
   depth), and its cells (PBRT's GridAccel's resolution). */
static int grid_shape(refl_grid *g, float per_side, int max_side) {
    float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX}, ext = 0.0f, pad;
    int i, k;
    for (i = 0; i < g->tri_count; ++i)
        for (k = 0; k < 9; ++k) {
            lo[k % 3] = fminf(lo[k % 3], g->tris[i].v[k]);
            hi[k % 3] = fmaxf(hi[k % 3], g->tris[i].v[k]);
        }
    if (!g->tri_count)
        for (k = 0; k < 3; ++k) lo[k] = hi[k] = 0.0f;
    for (k = 0; k < 3; ++k) ext = fmaxf(ext, hi[k] - lo[k]);
    pad = 1e-4f * ext + 1e-6f;
    ext = 0.0f;
    for (k = 0; k < 3; ++k) {
        lo[k] -= pad;
        hi[k] += pad;
        ext = fmaxf(ext, hi[k] - lo[k]);
    }
    for (k = 0; k < 3; ++k) {
        float side = hi[k] - lo[k];
        long r = lroundf(side / ext * per_side * cbrtf((float)g->tri_count));
        g->res[k] = (int)(r < 1 ? 1 : r > max_side ? max_side : r);
        g->lo[k] = lo[k];
        g->cell[k] = side / (float)g->res[k];
        g->inv_cell[k] = (float)g->res[k] / side;
    }
    return (long long)g->res[0] * g->res[1] * g->res[2] <= GRID_MAX_CELLS;
}

static int grid_clampi(int x, int lo, int hi) { return x < lo ? lo : x > hi ? hi : x; }

/* The cells of every triangle (its widened bounds), and the cells' lists. */
static int grid_bin(refl_grid *g) {
    long long cells = (long long)g->res[0] * g->res[1] * g->res[2], refs = 0, c;
    int i, k, x, y, z;
    for (i = 0; i < g->tri_count; ++i) {
        grid_tri *t = &g->tris[i];
        long long n = 1;
        for (k = 0; k < 3; ++k) {
            float a = fminf(t->v[k], fminf(t->v[3 + k], t->v[6 + k]));
            float b = fmaxf(t->v[k], fmaxf(t->v[3 + k], t->v[6 + k]));
            t->lo[k] = grid_clampi((int)floorf((a - g->lo[k]) * g->inv_cell[k] - GRID_PAD_CELLS), 0, g->res[k] - 1);
            t->hi[k] = grid_clampi((int)floorf((b - g->lo[k]) * g->inv_cell[k] + GRID_PAD_CELLS), 0, g->res[k] - 1);
            n *= t->hi[k] - t->lo[k] + 1;
        }
        refs += n;
    }
    if (refs > (long long)UINT_MAX - 1) return 0;
    g->references = refs;
    g->start = (unsigned *)calloc((size_t)cells + 1, sizeof *g->start);
    g->items = (unsigned *)malloc((size_t)(refs > 0 ? refs : 1) * sizeof *g->items);
    if (!g->start || !g->items) return 0;
    /* count, prefix sum, fill (each cell's triangles in index order) */
    for (i = 0; i < g->tri_count; ++i)
        for (z = g->tris[i].lo[2]; z <= g->tris[i].hi[2]; ++z)
            for (y = g->tris[i].lo[1]; y <= g->tris[i].hi[1]; ++y)
                for (x = g->tris[i].lo[0]; x <= g->tris[i].hi[0]; ++x)
                    ++g->start[((long long)z * g->res[1] + y) * g->res[0] + x + 1];
    for (c = 0; c < cells; ++c) g->start[c + 1] += g->start[c];
    for (i = 0; i < g->tri_count; ++i)
        for (z = g->tris[i].lo[2]; z <= g->tris[i].hi[2]; ++z)
            for (y = g->tris[i].lo[1]; y <= g->tris[i].hi[1]; ++y)
                for (x = g->tris[i].lo[0]; x <= g->tris[i].hi[0]; ++x)
                    g->items[g->start[((long long)z * g->res[1] + y) * g->res[0] + x]++] = (unsigned)i;
    for (c = cells; c > 0; --c) g->start[c] = g->start[c - 1]; /* the fill moved each start to its end */
    g->start[0] = 0;
    return 1;
}

refl_grid *refl_grid_create(const refl_scene *scene, const refl_grid_desc *desc) {
    refl_grid_desc d;
    refl_grid *g;
    int k;
    if (!scene) return NULL;
    memset(&d, 0, sizeof d);
    if (desc) d = *desc;
    if (!(d.per_side > 0.0f)) d.per_side = 3.0f;
    if (d.max_side <= 0) d.max_side = 64;
    g = (refl_grid *)calloc(1, sizeof *g);
    if (!g) return NULL;
    g->object_count = scene->object_count;
    g->objects = (unsigned char *)malloc((size_t)(scene->object_count > 0 ? scene->object_count : 1));
    if (g->objects)
        for (k = 0; k < scene->object_count; ++k) g->objects[k] = !d.objects || d.objects[k];
    if (!g->objects || !grid_gather(g, scene, d.objects) || !grid_shape(g, d.per_side, d.max_side) || !grid_bin(g)) {
        refl_grid_destroy(g);
        return NULL;
    }
    return g;
}

void refl_grid_destroy(refl_grid *g) {
    if (!g) return;
    free(g->objects);
    free(g->tris);
    free(g->start);
    free(g->items);
    free(g);
}

/* ---- tracing --------------------------------------------------------------------- */

/* A ray as the walk needs it. */
typedef struct grid_ray {
    refl_vec3 o, d;
    float org[3], dir[3];
} grid_ray;

static int grid_ray_setup(grid_ray *r, refl_vec3 o, refl_vec3 d) {
    int k;
    r->o = o;
    r->d = d;
    r->org[0] = o.x; r->org[1] = o.y; r->org[2] = o.z;
    r->dir[0] = d.x; r->dir[1] = d.y; r->dir[2] = d.z;
    for (k = 0; k < 3; ++k)
        if (!isfinite(r->org[k]) || !isfinite(r->dir[k])) return 0;
    return r->dir[0] != 0.0f || r->dir[1] != 0.0f || r->dir[2] != 0.0f;
}

/* Whether cell c lies in triangle t's cells. */
static int grid_tri_holds(const grid_tri *t, const int c[3]) {
    return c[0] >= t->lo[0] && c[0] <= t->hi[0] && c[1] >= t->lo[1] && c[1] <= t->hi[1] && c[2] >= t->lo[2] &&
           c[2] <= t->hi[2];
}

/* The distance along the ray to the face of cell c on axis k it leaves by. */
static float grid_face(const refl_grid *g, const grid_ray *r, const int c[3], int k) {
    float face = g->lo[k] + (float)(c[k] + (r->dir[k] > 0.0f)) * g->cell[k];
    return r->dir[k] != 0.0f ? (face - r->org[k]) / r->dir[k] : INFINITY;
}

/* The walk: the closest hit in (tmin, tmax) (any_hit: any), each triangle
   tested once; the tests made into *tests. */
static int grid_trace(const refl_grid *g, refl_vec3 o, refl_vec3 d, float tmin, float tmax, int any_hit,
                      refl_hit *hit, long long *tests) {
    grid_ray r;
    float t0 = tmin, t1 = tmax, next[3];
    int cell[3], prev[3] = {0, 0, 0}, have_prev = 0, found = 0, k;
    refl_hit best;
    memset(&best, 0, sizeof best);
    if (!g->tri_count || !grid_ray_setup(&r, o, d)) return 0;
    for (k = 0; k < 3; ++k) { /* clip to the grid's box */
        float lo = g->lo[k], hi = g->lo[k] + (float)g->res[k] * g->cell[k], a, b;
        if (r.dir[k] == 0.0f) {
            if (r.org[k] < lo || r.org[k] > hi) return 0;
            continue;
        }
        a = (lo - r.org[k]) / r.dir[k];
        b = (hi - r.org[k]) / r.dir[k];
        if (a > b) { float s = a; a = b; b = s; }
        t0 = fmaxf(t0, a);
        t1 = fminf(t1, b);
    }
    if (!(t0 <= t1)) return 0;
    for (k = 0; k < 3; ++k) {
        cell[k] = grid_clampi((int)floorf((r.org[k] + t0 * r.dir[k] - g->lo[k]) * g->inv_cell[k]), 0, g->res[k] - 1);
        next[k] = grid_face(g, &r, cell, k);
    }
    for (;;) {
        long long c = ((long long)cell[2] * g->res[1] + cell[1]) * g->res[0] + cell[0];
        unsigned j;
        float texit = fminf(next[0], fminf(next[1], next[2]));
        for (j = g->start[c]; j < g->start[c + 1]; ++j) {
            const grid_tri *t = &g->tris[g->items[j]];
            float bound = found ? best.t : tmax;
            refl_hit th;
            if (have_prev && grid_tri_holds(t, prev)) continue; /* tested in an earlier cell */
            ++*tests;
            if (!refl_ray_triangle(r.o, r.d, t->v, tmin, bound, &th)) continue;
            /* refl_bvh's order: closer first; a tie to the lower object, then triangle;
               tmax itself excluded */
            if (!(th.t < bound) && !(th.t == bound && found && (t->object < best.object ||
                                                               (t->object == best.object && t->triangle < best.triangle))))
                continue;
            found = 1;
            best = th;
            best.object = t->object;
            best.triangle = t->triangle;
            if (any_hit) return 1;
        }
        if (found && best.t < texit) break; /* nothing past this cell comes closer */
        if (!(texit < t1)) break;
        k = next[0] <= next[1] ? (next[0] <= next[2] ? 0 : 2) : (next[1] <= next[2] ? 1 : 2);
        memcpy(prev, cell, sizeof prev);
        have_prev = 1;
        cell[k] += r.dir[k] > 0.0f ? 1 : -1;
        if (cell[k] < 0 || cell[k] >= g->res[k]) break;
        next[k] = grid_face(g, &r, cell, k);
    }
    if (found && hit) *hit = best;
    return found;
}

static void grid_count(refl_grid *g, long long tests) {
    __atomic_fetch_add(&g->rays, 1, __ATOMIC_RELAXED);
    __atomic_fetch_add(&g->tests, tests, __ATOMIC_RELAXED);
}

int refl_grid_intersect(void *grid, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax, refl_hit *hit) {
    refl_grid *g = (refl_grid *)grid;
    long long tests = 0;
    int h = grid_trace(g, origin, dir, tmin, tmax, 0, hit, &tests);
    grid_count(g, tests);
    return h;
}

int refl_grid_occluded(void *grid, refl_vec3 origin, refl_vec3 dir, float tmin, float tmax) {
    refl_grid *g = (refl_grid *)grid;
    long long tests = 0;
    int h = grid_trace(g, origin, dir, tmin, tmax, 1, NULL, &tests);
    grid_count(g, tests);
    return h;
}

refl_ray_caster refl_grid_caster(refl_grid *grid) {
    refl_ray_caster c;
    c.intersect = refl_grid_intersect;
    c.occluded = refl_grid_occluded;
    c.user = grid;
    return c;
}

void refl_grid_counts(const refl_grid *g, long long *rays, long long *tests) {
    if (rays) *rays = __atomic_load_n(&g->rays, __ATOMIC_RELAXED);
    if (tests) *tests = __atomic_load_n(&g->tests, __ATOMIC_RELAXED);
}

void refl_grid_shape(const refl_grid *g, int cells[3], long long *triangles, long long *references) {
    if (cells) memcpy(cells, g->res, sizeof g->res);
    if (triangles) *triangles = g->tri_count;
    if (references) *references = g->references;
}

/* ---- the resolution for a target cost ------------------------------------------------ */

/* cost(per_side) into fit; 0 on its failure or when no evaluation is left. */
static int grid_fit_eval(refl_grid_cost cost, void *user, float per_side, int max_evaluations, refl_grid_fit *fit,
                         double *c) {
    if (fit->evaluations >= max_evaluations) return 0;
    ++fit->evaluations;
    *c = cost(user, per_side);
    fit->per_side = per_side;
    fit->cost = *c;
    return *c > 0.0;
}

int refl_grid_fit_per_side(refl_grid_cost cost, void *user, double target, double tolerance, float lo, float hi,
                           int max_evaluations, refl_grid_fit *fit) {
    double clo, chi, c;
    memset(fit, 0, sizeof *fit);
    if (max_evaluations <= 0) max_evaluations = 40;
    if (!cost || !(target > 0.0) || !(tolerance >= 0.0) || !(lo > 0.0f) || !(hi > lo)) return 0;
#define GRID_FIT_DONE(x) (fabs((x) / target - 1.0) <= tolerance)
    if (!grid_fit_eval(cost, user, lo, max_evaluations, fit, &clo)) return 0;
    if (GRID_FIT_DONE(clo)) return fit->converged = 1;
    if (clo < target) {
        do { /* already finer than the target: coarser */
            hi = lo;
            chi = clo;
            lo *= 0.5f;
            if (!grid_fit_eval(cost, user, lo, max_evaluations, fit, &clo)) return 0;
            if (GRID_FIT_DONE(clo)) return fit->converged = 1;
        } while (clo < target);
    } else {
        if (!grid_fit_eval(cost, user, hi, max_evaluations, fit, &chi)) return 0;
        if (GRID_FIT_DONE(chi)) return fit->converged = 1;
        while (chi > target) { /* still coarser than the target: finer */
            lo = hi;
            clo = chi;
            hi *= 2.0f;
            if (!grid_fit_eval(cost, user, hi, max_evaluations, fit, &chi)) return 0;
            if (GRID_FIT_DONE(chi)) return fit->converged = 1;
        }
    }
    /* clo > target > chi */
    while (hi - lo > 1e-4f * hi) {
        double xl = log((double)lo), xh = log((double)hi), yl = log(clo), yh = log(chi);
        double x = xl + (log(target) - yl) * (xh - xl) / (yh - yl), w = xh - xl;
        float p;
        if (!(x >= xl + 0.1 * w)) x = xl + 0.1 * w;
        if (!(x <= xh - 0.1 * w)) x = xh - 0.1 * w;
        p = (float)exp(x);
        if (!(p > lo && p < hi)) break;
        if (!grid_fit_eval(cost, user, p, max_evaluations, fit, &c)) return 0;
        if (GRID_FIT_DONE(c)) return fit->converged = 1;
        if (c > target) {
            lo = p;
            clo = c;
        } else {
            hi = p;
            chi = c;
        }
    }
#undef GRID_FIT_DONE
    return 0;
}

/* ---- agreement with refl_bvh ------------------------------------------------------- */

static unsigned grid_rand(unsigned *state) {
    *state = *state * 1664525u + 1013904223u;
    return *state >> 8;
}

static float grid_uniform(unsigned *state, float lo, float hi) {
    return lo + (hi - lo) * (float)grid_rand(state) / 16777216.0f;
}

/* refl_bvh's first hit on the grid's objects in (0, tmax): past the others. */
static int grid_bvh_first(const refl_grid *g, const refl_bvh *bvh, refl_vec3 o, refl_vec3 d, float tmax, refl_hit *h) {
    float tmin = 0.0f;
    int k;
    for (k = 0; k < 256 && refl_bvh_intersect(bvh, o, d, tmin, tmax, h); ++k) {
        if (h->object >= 0 && h->object < g->object_count && g->objects[h->object]) return 1;
        tmin = h->t;
    }
    return 0;
}

long long refl_grid_agreement(refl_grid *g, const refl_scene *s, const refl_bvh *bvh, int rays, unsigned seed,
                              char *first, size_t first_size) {
    refl_vec3 lo = refl_v3(FLT_MAX, FLT_MAX, FLT_MAX), hi = refl_v3(-FLT_MAX, -FLT_MAX, -FLT_MAX);
    long long bad = 0;
    unsigned state = seed;
    int i, k;
    for (i = 0; i < s->object_count; ++i) {
        refl_vec3 a, b;
        refl_object_world_bounds(s, i, &a, &b);
        lo = refl_v3(fminf(lo.x, a.x), fminf(lo.y, a.y), fminf(lo.z, a.z));
        hi = refl_v3(fmaxf(hi.x, b.x), fmaxf(hi.y, b.y), fmaxf(hi.z, b.z));
    }
    if (first && first_size) first[0] = 0;
    for (i = 0; i < rays; ++i) {
        refl_vec3 o = refl_v3(grid_uniform(&state, lo.x, hi.x), grid_uniform(&state, lo.y, hi.y),
                              grid_uniform(&state, lo.z, hi.z)),
                  d;
        refl_hit a, b;
        float tmax;
        int ha, hb, oa, ob;
        if (g->tri_count && grid_rand(&state) % 2) {
            const grid_tri *t = &g->tris[grid_rand(&state) % (unsigned)g->tri_count];
            float u = grid_uniform(&state, 0.0f, 1.0f), v = grid_uniform(&state, 0.0f, 1.0f - u), w = 1.0f - u - v;
            d = refl_v3_sub(refl_v3(w * t->v[0] + u * t->v[3] + v * t->v[6], w * t->v[1] + u * t->v[4] + v * t->v[7],
                                    w * t->v[2] + u * t->v[5] + v * t->v[8]),
                            o);
        } else {
            do d = refl_v3(grid_uniform(&state, -1, 1), grid_uniform(&state, -1, 1), grid_uniform(&state, -1, 1));
            while (refl_v3_dot(d, d) > 1.0f || refl_v3_dot(d, d) < 1e-4f);
        }
        ha = refl_grid_intersect(g, o, d, 0.0f, FLT_MAX, &a);
        hb = grid_bvh_first(g, bvh, o, d, FLT_MAX, &b);
        tmax = grid_uniform(&state, 0.0f, 1.2f) * (hb ? b.t : 10.0f);
        oa = refl_grid_occluded(g, o, d, 0.0f, tmax);
        /* whether refl_bvh's first hit on the grid's objects lies before
           tmax (refl_bvh_occluded would take the other objects too) */
        ob = hb && b.t < tmax;
        k = ha == hb && oa == ob &&
            (!ha || (a.object == b.object && a.triangle == b.triangle && a.t == b.t && a.u == b.u && a.v == b.v));
        if (k) continue;
        if (!bad++ && first && first_size)
            snprintf(first, first_size,
                     "ray %d (%g %g %g) + t (%g %g %g): grid %d (object %d triangle %d t %.9g), bvh %d (object %d "
                     "triangle %d t %.9g); any hit before %g: grid %d bvh %d",
                     i, o.x, o.y, o.z, d.x, d.y, d.z, ha, ha ? a.object : -1, ha ? a.triangle : -1, ha ? a.t : 0.0f, hb,
                     hb ? b.object : -1, hb ? b.triangle : -1, hb ? b.t : 0.0f, tmax, oa, ob);
    }
    return bad;
}
