/* cam_sbc_raylist: the sample-based camera's ray-list leaves, where no
   pinhole camera fits, and their sheets (paper 003 IV and VII-C;
   docs/methods/sbc.md, "The sample-based camera").

   A ray-list leaf searches its unit frustums, the 2 x 2 quads of its rays:
   p lies in one at (s, t) in [0, 1]^2 when it lies on the bilinearly
   interpolated ray (s, t). Each quad is sliced across its mean direction
   m: at p's slice tau = (p - o) . m each ray is one point of the slice,
   so (s, t) is an inverse bilinear interpolation in 2D, and the answer is
   the four first points blended at (s, t) (z: the blended distance along
   the rays from their tails); the nearest such quad wins. Adjacent quads
   share their edge rays, so the blend is continuous to within the
   rays' skewness. Where no quad holds p, the one p lies nearest outside
   (within REFL__SBC_NEAR of its diagonal) answers at its clamped (s, t):
   at a fold the quads around a ray cover only some sides of it, and a
   point a hair off the ray would fall in none. A leaf of many quads gets
   an index (refl__sbc_index), so a point tries the quads of its cell only.

   Sheets (beyond the paper, its section VII-C's proposal): where rays
   cross (a focusing mirror, a crease) a point lies in several quads, and
   one image per group (the nearest, as refl_sbc_project keeps) shows it
   in one place only. Each quad knows the slices where its four rays fold
   (its signed area, a quadratic along m, is zero; folds behind the tails
   do not count) and a point past k of them lies in the quad's sheet k:
   refl_sbc_project_sheets returns the nearest image per sheet, in one
   search. */
#include "cam_sbc_internal.h"

/* A ray-list leaf gets an index (refl__sbc_index) from this many quads on:
   a concave bowl's leaves hold about a thousand quads each, where trying
   every quad costs most of the frame; short leaves' quads' world boxes
   already stop most points. */
#define REFL__SBC_INDEX_MIN 16

/* A quad's frame in double: what build and projection both compute with. */
typedef struct refl__sbc_frame {
    double o[3], m[3], a[3], b[3];
} refl__sbc_frame;

/* ---- building ---------------------------------------------------------------- */

static void refl__sbc_frame_load(const refl__sbc_quad *q, refl__sbc_frame *f) {
    int j;
    for (j = 0; j < 3; ++j) {
        f->o[j] = q->o[j]; f->m[j] = q->m[j]; f->a[j] = q->a[j]; f->b[j] = q->b[j];
    }
}

/* The four rays' lateral positions (x, y) at slice tau of a quad's frame,
   how far along each ray (0 tail, 1 head) that slice is, and their
   lengths; 0 when a ray runs almost across the slices. */
static int refl__sbc_quad_slice(const refl__sbc_frame *q, const refl_sbc_ray *rays, int idx, int W, double tau,
                                double x[4], double y[4], double lam[4], double len[4]) {
    int c, j;
    for (c = 0; c < 4; ++c) {
        const refl_sbc_ray *r = &rays[idx + (c & 1) + (c >> 1) * W];
        double t[3], d[3], dm, l, pt[3];
        refl__sbc_load(r->tail, t);
        d[0] = (double)r->head.x - t[0]; d[1] = (double)r->head.y - t[1]; d[2] = (double)r->head.z - t[2];
        for (j = 0; j < 3; ++j) t[j] -= q->o[j];
        dm = refl__sbc_dot(d, q->m);
        len[c] = sqrt(refl__sbc_dot(d, d));
        if (!(dm > 0.05 * len[c])) return 0;
        l = (tau - refl__sbc_dot(t, q->m)) / dm;
        for (j = 0; j < 3; ++j) pt[j] = t[j] + l * d[j];
        x[c] = refl__sbc_dot(pt, q->a);
        y[c] = refl__sbc_dot(pt, q->b);
        lam[c] = l;
    }
    return 1;
}

/* A ray-list leaf's box and each of its quads': every corner of a quad's
   lateral boxes at both ends (between them the quad's region is their
   blend), padded past float rounding. */
static void refl__sbc_leaf_box(refl_sbc *s, refl__sbc_node *node) {
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, pad = 0.0;
    int i, e, c, j;
    for (i = 0; i < node->count; ++i) {
        refl__sbc_quad *q = &s->quads[node->first + i];
        double qlo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, qhi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, qpad = 0.0;
        refl__sbc_frame fr;
        refl__sbc_frame_load(q, &fr);
        for (e = 0; e < 2; ++e)
            for (c = 0; c < 4; ++c) {
                double x = q->box[e][c & 1], y = q->box[e][2 + (c >> 1)];
                for (j = 0; j < 3; ++j) {
                    double v = fr.o[j] + (double)q->tau[e] * fr.m[j] + x * fr.a[j] + y * fr.b[j];
                    qlo[j] = REFL__MIN(qlo[j], v);
                    qhi[j] = REFL__MAX(qhi[j], v);
                }
            }
        for (j = 0; j < 3; ++j) qpad = REFL__MAX(qpad, qhi[j] - qlo[j] + fabs(qlo[j]) + fabs(qhi[j]));
        for (j = 0; j < 3; ++j) {
            q->aabb[j] = (float)(qlo[j] - 1e-5 * qpad);
            q->aabb[3 + j] = (float)(qhi[j] + 1e-5 * qpad);
            lo[j] = REFL__MIN(lo[j], qlo[j]);
            hi[j] = REFL__MAX(hi[j], qhi[j]);
        }
    }
    for (j = 0; j < 3 && node->count; ++j) pad = REFL__MAX(pad, hi[j] - lo[j] + fabs(lo[j]) + fabs(hi[j]));
    for (j = 0; j < 3; ++j) { /* empty: lows above highs, nothing inside */
        node->box[j] = node->count ? (float)(lo[j] - 1e-5 * pad) : 1.0f;
        node->box[3 + j] = node->count ? (float)(hi[j] + 1e-5 * pad) : 0.0f;
    }
}

static double refl__sbc_cross2(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

/* The real roots of a t^2 + b t + c, ascending (the linear one where a is
   negligible): the textbook's cancellation-free form, without
   refl_solve_quadratic's exact scaling, which costs a tenth of a ray-list
   projection and buys nothing here (the roots are checked against [0, 1]
   with a tolerance). NaN coefficients give NaN roots, which fail that. */
static int refl__sbc_quadratic(double a, double b, double c, double r[2]) {
    double disc, q;
    if (fabs(a) <= 1e-12 * (fabs(b) + fabs(c))) {
        if (b == 0.0) return 0;
        r[0] = -c / b;
        return 1;
    }
    disc = b * b - 4.0 * a * c;
    if (disc < 0.0) return 0;
    q = -0.5 * (b + (b >= 0.0 ? sqrt(disc) : -sqrt(disc)));
    if (q == 0.0) { /* b = c = 0: a double root at 0 */
        r[0] = 0.0;
        return 1;
    }
    r[0] = REFL__MIN(q / a, c / q);
    r[1] = REFL__MAX(q / a, c / q);
    return 2;
}

/* Where a quad's rays fold between slices tau[0] and tau[1]: its four
   rays' lateral positions move linearly with the slice, so the signed area
   of their quadrilateral (half the cross product of its diagonals) is a
   quadratic in tau, exact from three slices, and it turns over at its
   roots. Returns the folds found (0 to 2). */
static int refl__sbc_quad_folds(const refl__sbc_frame *fr, const refl_sbc_ray *rays, int idx, int W,
                                const double tau[2], double fold[2]) {
    double ts[3], area[3], x[4], y[4], lam[4], len[4], a, b, roots[2];
    int i, n, found = 0;
    ts[0] = tau[0];
    ts[1] = 0.5 * (tau[0] + tau[1]);
    ts[2] = tau[1];
    for (i = 0; i < 3; ++i) {
        if (!refl__sbc_quad_slice(fr, rays, idx, W, ts[i], x, y, lam, len)) return 0;
        area[i] = refl__sbc_cross2(x[3] - x[0], y[3] - y[0], x[2] - x[1], y[2] - y[1]);
    }
    /* area(f) = a f^2 + b f + area[0] over f = (tau - tau[0]) / (tau[1] - tau[0]) in [0, 1] */
    a = 2.0 * (area[2] - 2.0 * area[1] + area[0]);
    b = area[2] - area[0] - a;
    n = refl__sbc_quadratic(a, b, area[0], roots);
    for (i = 0; i < n; ++i) {
        double t = tau[0] + roots[i] * (tau[1] - tau[0]), ahead = 0.0;
        int c;
        if (!(roots[i] > 0.0 && roots[i] < 1.0) || !refl__sbc_quad_slice(fr, rays, idx, W, t, x, y, lam, len)) continue;
        for (c = 0; c < 4; ++c) ahead += lam[c];
        /* behind the tails the rays are lines, not rays: nothing there reflects */
        if (ahead > 0.0) fold[found++] = t;
    }
    return found;
}

/* Unit a and b across unit m (m, a, b right-handed): a from m and the
   axis m leans on least. */
static void refl__sbc_across(const double *m, double *a, double *b) {
    double ax[3] = {0.0, 0.0, 0.0};
    int j, best = 0;
    for (j = 1; j < 3; ++j)
        if (fabs(m[j]) < fabs(m[best])) best = j;
    ax[best] = 1.0;
    refl__sbc_cross(m, ax, a);
    refl__sbc_normalize(a);
    refl__sbc_cross(m, a, b);
}

/* Quad q's region in index frame ix: its 8 corners (its lateral boxes'
   at both ends) as (t, x, y). */
static void refl__sbc_index_corners(const refl__sbc_index *ix, const refl__sbc_quad *q, double v[8][3]) {
    refl__sbc_frame fr;
    int e, c, j;
    refl__sbc_frame_load(q, &fr);
    for (e = 0; e < 2; ++e)
        for (c = 0; c < 4; ++c) {
            double w[3], x = q->box[e][c & 1], y = q->box[e][2 + (c >> 1)];
            for (j = 0; j < 3; ++j) w[j] = fr.o[j] + (double)q->tau[e] * fr.m[j] + x * fr.a[j] + y * fr.b[j] - ix->o[j];
            v[4 * e + c][0] = refl__sbc_dot(w, ix->m);
            v[4 * e + c][1] = refl__sbc_dot(w, ix->a);
            v[4 * e + c][2] = refl__sbc_dot(w, ix->b);
        }
}

/* The lateral box (x lo, x hi, y lo, y hi) of the part of a quad's region
   (its corners v) with t in [t0, t1]: the corners in the slab and where
   the region's 12 edges cross its planes; 0 when none (it misses the slab). */
static int refl__sbc_slab_box(const double v[8][3], double t0, double t1, double box[4]) {
    static const int edge[12][2] = {{0, 1}, {1, 3}, {3, 2}, {2, 0}, {4, 5}, {5, 7}, {7, 6}, {6, 4},
                                    {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    int k, e, any = 0;
    box[0] = box[2] = DBL_MAX;
    box[1] = box[3] = -DBL_MAX;
    for (k = 0; k < 8; ++k)
        if (v[k][0] >= t0 && v[k][0] <= t1) {
            box[0] = REFL__MIN(box[0], v[k][1]); box[1] = REFL__MAX(box[1], v[k][1]);
            box[2] = REFL__MIN(box[2], v[k][2]); box[3] = REFL__MAX(box[3], v[k][2]);
            any = 1;
        }
    for (k = 0; k < 12; ++k) {
        const double *p = v[edge[k][0]], *q = v[edge[k][1]];
        for (e = 0; e < 2; ++e) {
            double t = e ? t1 : t0, f;
            if (!((p[0] - t) * (q[0] - t) <= 0.0) || p[0] == q[0]) continue;
            f = (t - p[0]) / (q[0] - p[0]);
            box[0] = REFL__MIN(box[0], p[1] + f * (q[1] - p[1])); box[1] = REFL__MAX(box[1], p[1] + f * (q[1] - p[1]));
            box[2] = REFL__MIN(box[2], p[2] + f * (q[2] - p[2])); box[3] = REFL__MAX(box[3], p[2] + f * (q[2] - p[2]));
            any = 1;
        }
    }
    return any;
}

/* A ray-list leaf's index (see refl__sbc_index), built when it has
   REFL__SBC_INDEX_MIN quads or more. Conservative: a point a quad's exact
   test takes lies in its region, so in a cell listing it (boxes padded
   past rounding). */
static refl_result refl__sbc_leaf_index(refl_sbc *s, refl__sbc_node *node) {
    refl__sbc_index ix;
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, pad = 0.0;
    double (*v)[8][3], box[4];
    int ncells, i, j, k, pass, total, *start, *last;
    node->grid = 0;
    if (node->count < REFL__SBC_INDEX_MIN) return REFL_OK;
    memset(&ix, 0, sizeof ix);
    /* finer for longer lists: a few quads per cell where they lie side by side */
    ix.cells = REFL__CLAMP((int)sqrt((double)node->count), 4, 32);
    ix.slabs = REFL__CLAMP((int)(0.5 * sqrt((double)node->count)), 4, 16);
    ncells = ix.slabs * ix.cells * ix.cells;
    for (i = 0; i < node->count; ++i)
        for (j = 0; j < 3; ++j) {
            ix.o[j] += (double)s->quads[node->first + i].o[j] / node->count;
            ix.m[j] += s->quads[node->first + i].m[j];
        }
    if (!(refl__sbc_normalize(ix.m) > 0.0)) return REFL_OK;
    refl__sbc_across(ix.m, ix.a, ix.b);
    v = (double(*)[8][3])refl__alloc(&s->allocator, (size_t)node->count * sizeof *v); /* per quad: its corners */
    if (!v) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < node->count; ++i) { /* the leaf's extent in its frame */
        refl__sbc_index_corners(&ix, &s->quads[node->first + i], v[i]);
        for (k = 0; k < 8; ++k)
            for (j = 0; j < 3; ++j) {
                lo[j] = REFL__MIN(lo[j], v[i][k][j]);
                hi[j] = REFL__MAX(hi[j], v[i][k][j]);
            }
    }
    for (j = 0; j < 3; ++j) pad = REFL__MAX(pad, hi[j] - lo[j] + fabs(lo[j]) + fabs(hi[j]));
    pad = 1e-5 * (pad + fabs(ix.o[0]) + fabs(ix.o[1]) + fabs(ix.o[2]));
    ix.t0 = lo[0] - pad;
    ix.t_scale = ix.slabs / (hi[0] - lo[0] + 2.0 * pad);
    ix.x0 = lo[1] - pad;
    ix.x_scale = ix.cells / (hi[1] - lo[1] + 2.0 * pad);
    ix.y0 = lo[2] - pad;
    ix.y_scale = ix.cells / (hi[2] - lo[2] + 2.0 * pad);
    ix.start = s->cell_start_count;
    if (!refl__sbc_grow_int(&s->allocator, (void **)&s->cell_start, &s->cell_start_cap, ix.start + ncells + 1,
                            sizeof(int)) ||
        !refl__sbc_grow_int(&s->allocator, (void **)&s->indexes, &s->index_cap, s->index_count + 1,
                            sizeof(refl__sbc_index)) ||
        !(last = (int *)refl__alloc(&s->allocator, (size_t)ncells * sizeof(int)))) { /* per cell: its last quad */
        refl__free(&s->allocator, v);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    start = s->cell_start + ix.start;
    memset(start, 0, (size_t)(ncells + 1) * sizeof(int));
    total = s->cell_quad_count;
    for (pass = 0; pass < 2; ++pass) { /* count each cell's list, then fill it */
        for (k = 0; k < ncells; ++k) last[k] = -1;
        if (pass) {
            for (k = 0; k <= ncells; ++k) {
                int count = start[k];
                start[k] = total;
                total += count;
            }
            if (!refl__sbc_grow_int(&s->allocator, (void **)&s->cell_quads, &s->cell_quad_cap, total, sizeof(int))) {
                refl__free(&s->allocator, last);
                refl__free(&s->allocator, v);
                return REFL_ERROR_OUT_OF_MEMORY;
            }
        }
        for (i = 0; i < node->count; ++i) {
            int slab;
            for (slab = 0; slab < ix.slabs; ++slab) {
                double t0 = ix.t0 + slab / ix.t_scale, t1 = ix.t0 + (slab + 1) / ix.t_scale;
                int x, y, r[4];
                if (!refl__sbc_slab_box((const double(*)[3])v[i], t0 - pad, t1 + pad, box)) continue;
                r[0] = (int)REFL__CLAMP((box[0] - pad - ix.x0) * ix.x_scale, 0.0, ix.cells - 1.0);
                r[1] = (int)REFL__CLAMP((box[1] + pad - ix.x0) * ix.x_scale, 0.0, ix.cells - 1.0);
                r[2] = (int)REFL__CLAMP((box[2] - pad - ix.y0) * ix.y_scale, 0.0, ix.cells - 1.0);
                r[3] = (int)REFL__CLAMP((box[3] + pad - ix.y0) * ix.y_scale, 0.0, ix.cells - 1.0);
                for (y = r[2]; y <= r[3]; ++y)
                    for (x = r[0]; x <= r[1]; ++x) {
                        int c = (slab * ix.cells + y) * ix.cells + x;
                        if (last[c] == i) continue;
                        last[c] = i;
                        if (!pass) start[c]++;
                        else s->cell_quads[start[c]++] = i;
                    }
            }
        }
        if (pass) { /* the fill moved every start to the next cell's */
            for (k = ncells; k > 0; --k) start[k] = start[k - 1];
            start[0] = s->cell_quad_count;
        }
    }
    refl__free(&s->allocator, last);
    refl__free(&s->allocator, v);
    s->cell_quad_count = total;
    s->cell_start_count += ncells + 1;
    s->indexes[s->index_count++] = ix;
    node->grid = s->index_count;
    return REFL_OK;
}

/* A ray-list leaf: the set's 2 x 2 quads of rays, each with its frame. */
static refl_result refl__sbc_ray_leaf(refl__sbc_builder *b, const int *list, int n, refl__sbc_node *node) {
    refl_sbc *s = b->sbc;
    unsigned st = ++b->stamp;
    int i, W = b->W, H = b->H;
    for (i = 0; i < n; ++i) b->mark[list[i]] = st;
    node->kind = REFL__SBC_RAYS;
    node->first = s->quad_count;
    node->count = 0;
    for (i = 0; i < n; ++i) {
        int idx = list[i], u = idx % W, v = idx / W, c, j, e, ok = 1;
        refl__sbc_quad q;
        refl__sbc_frame fr;
        double lo = DBL_MAX, hi = -DBL_MAX, scale = 0.0, tau[2];
        if (u + 1 >= W || v + 1 >= H) continue;
        if (b->mark[idx + 1] != st || b->mark[idx + W] != st || b->mark[idx + W + 1] != st) continue;
        /* one smooth piece: a frustum across a gap or crease holds points no ray reflects */
        if (b->links && !((b->links[idx] & 3) == 3 && (b->links[idx + W] & 1) && (b->links[idx + 1] & 2))) continue;
        memset(&q, 0, sizeof q);
        memset(&fr, 0, sizeof fr);
        q.idx = idx;
        for (c = 0; c < 4; ++c) {
            int k = idx + (c & 1) + (c >> 1) * W;
            const refl_sbc_ray *r = &b->rays[k];
            fr.o[0] += 0.25 * r->tail.x; fr.o[1] += 0.25 * r->tail.y; fr.o[2] += 0.25 * r->tail.z;
            for (j = 0; j < 3; ++j) fr.m[j] += b->dir[3 * (size_t)k + (size_t)j];
        }
        if (!(refl__sbc_normalize(fr.m) > 0.0)) continue;
        refl__sbc_across(fr.m, fr.a, fr.b);
        /* stored in float; everything below from the stored values */
        for (j = 0; j < 3; ++j) {
            q.o[j] = (float)fr.o[j]; q.m[j] = (float)fr.m[j]; q.a[j] = (float)fr.a[j]; q.b[j] = (float)fr.b[j];
        }
        refl__sbc_frame_load(&q, &fr);
        for (c = 0; c < 4; ++c) {
            const refl_sbc_ray *r = &b->rays[idx + (c & 1) + (c >> 1) * W];
            for (e = 0; e < 2; ++e) {
                double p[3], t;
                refl__sbc_load(e ? r->head : r->tail, p);
                for (j = 0; j < 3; ++j) p[j] -= fr.o[j];
                t = refl__sbc_dot(p, fr.m);
                lo = REFL__MIN(lo, t);
                hi = REFL__MAX(hi, t);
                scale = REFL__MAX(scale, sqrt(refl__sbc_dot(p, p)));
            }
        }
        /* the pads outgrow float rounding (relative 6e-8 of scale) */
        scale += fabs(fr.o[0]) + fabs(fr.o[1]) + fabs(fr.o[2]);
        tau[0] = lo - 1e-4 * (hi - lo) - 1e-6 * scale;
        /* beyond the heads too: where heads leave the box through different
           faces, their blend lies inside it, short of the box */
        tau[1] = hi + 0.25 * (hi - lo) + 1e-6 * scale;
        for (e = 0; e < 2 && ok; ++e) {
            double x[4], y[4], lam[4], len[4], pad, bx[4];
            if (!refl__sbc_quad_slice(&fr, b->rays, idx, W, tau[e], x, y, lam, len)) ok = 0;
            bx[0] = bx[2] = DBL_MAX;
            bx[1] = bx[3] = -DBL_MAX;
            for (c = 0; c < 4; ++c) {
                bx[0] = REFL__MIN(bx[0], x[c]); bx[1] = REFL__MAX(bx[1], x[c]);
                bx[2] = REFL__MIN(bx[2], y[c]); bx[3] = REFL__MAX(bx[3], y[c]);
            }
            /* room for the exact test's tolerance in (s, t), and for the
               fallback's reach (a diagonal is at most width plus height) */
            pad = (1e-3 + REFL__SBC_NEAR) * (bx[1] - bx[0] + bx[3] - bx[2]) + 1e-6 * scale;
            q.box[e][0] = (float)(bx[0] - pad); q.box[e][1] = (float)(bx[1] + pad);
            q.box[e][2] = (float)(bx[2] - pad); q.box[e][3] = (float)(bx[3] + pad);
            q.tau[e] = (float)tau[e];
        }
        if (!ok) continue; /* rays a quarter turn apart: no slicing; nothing projects there */
        for (c = 0; c < 4; ++c) { /* what projection slices, once */
            const refl_sbc_ray *r = &b->rays[idx + (c & 1) + (c >> 1) * W];
            double t[3], d[3];
            refl__sbc_load(r->tail, t);
            d[0] = (double)r->head.x - t[0]; d[1] = (double)r->head.y - t[1]; d[2] = (double)r->head.z - t[2];
            for (j = 0; j < 3; ++j) t[j] -= fr.o[j];
            q.ray[c][0] = (float)refl__sbc_dot(t, fr.m);
            q.ray[c][1] = (float)refl__sbc_dot(t, fr.a);
            q.ray[c][2] = (float)refl__sbc_dot(t, fr.b);
            q.ray[c][3] = (float)refl__sbc_dot(d, fr.m);
            q.ray[c][4] = (float)refl__sbc_dot(d, fr.a);
            q.ray[c][5] = (float)refl__sbc_dot(d, fr.b);
            q.len[c] = (float)sqrt(refl__sbc_dot(d, d));
        }
        {
            double fold[2];
            int folds = refl__sbc_quad_folds(&fr, b->rays, idx, W, tau, fold);
            q.fold[0] = folds > 0 ? (float)fold[0] : FLT_MAX;
            q.fold[1] = folds > 1 ? (float)fold[1] : FLT_MAX;
            s->stats.sheets = REFL__MAX(s->stats.sheets, folds + 1);
        }
        q.inv_span = 1.0f / (q.tau[1] - q.tau[0]); /* tau[1] > tau[0]: the pads grow them apart */
        q.o_size = fabsf(q.o[0]) + fabsf(q.o[1]) + fabsf(q.o[2]);
        if (!refl__sbc_grow_int(&s->allocator, (void **)&s->quads, &s->quad_cap, s->quad_count + 1,
                                sizeof(refl__sbc_quad)))
            return REFL_ERROR_OUT_OF_MEMORY;
        s->quads[s->quad_count++] = q;
        node->count++;
    }
    refl__sbc_leaf_box(s, node);
    return refl__sbc_leaf_index(s, node);
}

/* ---- projecting -------------------------------------------------------------- */

/* Inverse bilinear interpolation: (s, t) in [0, 1]^2 (within tol, then
   clamped) with (x, y) = the blend of corners 0 (0, 0), 1 (1, 0), 2 (0, 1),
   3 (1, 1), the root least outside the square (*out: how far); 0 when there
   is none. */
static int refl__sbc_inv_bilinear(const double *cx, const double *cy, double x, double y, double tol, double *s,
                                  double *t, double *out) {
    double ex = cx[1] - cx[0], ey = cy[1] - cy[0], fx = cx[2] - cx[0], fy = cy[2] - cy[0];
    double gx = cx[0] - cx[1] - cx[2] + cx[3], gy = cy[0] - cy[1] - cy[2] + cy[3], hx = x - cx[0], hy = y - cy[0];
    double roots[2], best = DBL_MAX;
    int nr, i;
    /* h - t f = s (e + t g): crossing both sides with e + t g leaves a quadratic in t */
    nr = refl__sbc_quadratic(refl__sbc_cross2(gx, gy, fx, fy),
                             refl__sbc_cross2(ex, ey, fx, fy) + refl__sbc_cross2(hx, hy, gx, gy),
                             refl__sbc_cross2(hx, hy, ex, ey), roots);
    for (i = 0; i < nr; ++i) {
        double tt = roots[i], dx = ex + gx * tt, dy = ey + gy * tt, ss, o;
        if (!(tt >= -tol && tt <= 1.0 + tol)) continue;
        if (fabs(dx) >= fabs(dy)) {
            if (dx == 0.0) continue;
            ss = (hx - fx * tt) / dx;
        } else {
            ss = (hy - fy * tt) / dy;
        }
        if (!(ss >= -tol && ss <= 1.0 + tol)) continue;
        o = REFL__MAX(REFL__MAX(-ss, ss - 1.0), REFL__MAX(-tt, tt - 1.0));
        o = REFL__MAX(o, 0.0);
        if (!(o < best)) continue;
        best = o;
        *s = REFL__CLAMP(ss, 0.0, 1.0);
        *t = REFL__CLAMP(tt, 0.0, 1.0);
        if (o == 0.0) break; /* inside: the first such root, as ever */
    }
    *out = best;
    return best < DBL_MAX;
}

/* A ray-list image candidate: its rank (off the reflector, how far off
   its quad, depth) and its answer. */
typedef struct refl__sbc_pick {
    int off;
    double out, zz;
    refl_vec3 first;
} refl__sbc_pick;

/* A ray-list leaf, per sheet (sheets 0: one for all, as if no ray
   folded): the unit frustum holding p nearest the reflector; where none
   does, the one p lies nearest outside, within REFL__SBC_NEAR. Returns the
   mask of sheets p projects in. */
static int refl__sbc_rays_project(const refl_sbc *sb, const refl__sbc_node *node, const double *p, int sheets,
                                  refl_vec3 *first, float *z) {
    refl__sbc_pick picks[REFL_SBC_SHEETS][2]; /* per sheet: inside a quad, near one */
    const float pf[3] = {(float)p[0], (float)p[1], (float)p[2]};
    const float pn = fabsf(pf[0]) + fabsf(pf[1]) + fabsf(pf[2]);
    int i, c, j, k, W = sb->width, mask = 0, from = 0, to = node->count, at;
    const int *list = NULL;
    for (j = 0; j < 3; ++j)
        if (!(p[j] >= node->box[j] && p[j] <= node->box[3 + j])) return 0;
    for (i = 0; i < REFL_SBC_SHEETS; ++i) {
        picks[i][0].zz = picks[i][1].zz = DBL_MAX;
        picks[i][0].out = picks[i][1].out = DBL_MAX;
        picks[i][0].off = picks[i][1].off = 0;
    }
    if (node->grid) { /* only the quads listed in p's cell */
        const refl__sbc_index *ix = &sb->indexes[node->grid - 1];
        double w[3], t, x, y;
        int slab, cx, cy;
        for (j = 0; j < 3; ++j) w[j] = p[j] - ix->o[j];
        t = (refl__sbc_dot(w, ix->m) - ix->t0) * ix->t_scale;
        x = (refl__sbc_dot(w, ix->a) - ix->x0) * ix->x_scale;
        y = (refl__sbc_dot(w, ix->b) - ix->y0) * ix->y_scale;
        if (!(t >= 0.0 && t < ix->slabs && x >= 0.0 && x < ix->cells && y >= 0.0 && y < ix->cells))
            return 0;
        slab = (int)t;
        cx = (int)x;
        cy = (int)y;
        at = ix->start + (slab * ix->cells + cy) * ix->cells + cx;
        from = sb->cell_start[at];
        to = sb->cell_start[at + 1];
        list = sb->cell_quads;
    }
    for (at = from; at < to; ++at) {
        const refl__sbc_quad *q = &sb->quads[node->first + (list ? list[at] : at)];
        refl__sbc_frame fr;
        double w[3], tau, x, y, f, x4[4], y4[4], lam[4], len[4], ss = 0.0, tt = 0.0, wt[4], zz = 0.0, lm = 0.0, o;
        refl__sbc_pick *pk, *pick;
        double t0 = q->tau[0], t1 = q->tau[1];
        int sheet;
        /* most quads miss p: its box first, then a float test of its
           region, looser than its rounding (about 1e-6 of the coordinates'
           size), so neither drops a quad the exact test below would take */
        if (!(pf[0] >= q->aabb[0] && pf[0] <= q->aabb[3] && pf[1] >= q->aabb[1] && pf[1] <= q->aabb[4] &&
              pf[2] >= q->aabb[2] && pf[2] <= q->aabb[5]))
            continue;
        {
            float eps = 1e-5f * (pn + q->o_size);
            float wx = pf[0] - q->o[0], wy = pf[1] - q->o[1], wz = pf[2] - q->o[2], tf, ff, v;
            tf = wx * q->m[0] + wy * q->m[1] + wz * q->m[2];
            if (!(tf >= q->tau[0] - eps && tf <= q->tau[1] + eps)) continue;
            ff = REFL__CLAMP((tf - q->tau[0]) * q->inv_span, 0.0f, 1.0f);
            v = wx * q->a[0] + wy * q->a[1] + wz * q->a[2];
            if (!(v >= q->box[0][0] + ff * (q->box[1][0] - q->box[0][0]) - eps &&
                  v <= q->box[0][1] + ff * (q->box[1][1] - q->box[0][1]) + eps))
                continue;
            v = wx * q->b[0] + wy * q->b[1] + wz * q->b[2];
            if (!(v >= q->box[0][2] + ff * (q->box[1][2] - q->box[0][2]) - eps &&
                  v <= q->box[0][3] + ff * (q->box[1][3] - q->box[0][3]) + eps))
                continue;
        }
        refl__sbc_frame_load(q, &fr);
        for (j = 0; j < 3; ++j) w[j] = p[j] - fr.o[j];
        tau = refl__sbc_dot(w, fr.m);
        if (!(tau >= t0 && tau <= t1)) continue;
        sheet = sheets ? (tau > q->fold[0]) + (tau > q->fold[1]) : 0;
        if (sheets && sheet >= sheets) continue;
        pick = picks[sheet];
        f = (tau - t0) / (t1 - t0);
        x = refl__sbc_dot(w, fr.a);
        if (!(x >= q->box[0][0] + f * ((double)q->box[1][0] - q->box[0][0]) &&
              x <= q->box[0][1] + f * ((double)q->box[1][1] - q->box[0][1])))
            continue;
        y = refl__sbc_dot(w, fr.b);
        if (!(y >= q->box[0][2] + f * ((double)q->box[1][2] - q->box[0][2]) &&
              y <= q->box[0][3] + f * ((double)q->box[1][3] - q->box[0][3])))
            continue;
        for (c = 0; c < 4; ++c) { /* its rays at p's slice (each crosses the slices: the build checked) */
            double l = (tau - q->ray[c][0]) / q->ray[c][3];
            x4[c] = q->ray[c][1] + l * q->ray[c][4];
            y4[c] = q->ray[c][2] + l * q->ray[c][5];
            lam[c] = l;
            len[c] = q->len[c];
        }
        /* the root least outside: inside within the exact tolerance, else
           near when its clamped point lies within REFL__SBC_NEAR diagonals */
        if (!refl__sbc_inv_bilinear(x4, y4, x, y, pick[0].zz < DBL_MAX ? REFL__SBC_TOL : 0.5, &ss, &tt, &o)) continue;
        wt[0] = (1.0 - ss) * (1.0 - tt); wt[1] = ss * (1.0 - tt); wt[2] = (1.0 - ss) * tt; wt[3] = ss * tt;
        k = o > REFL__SBC_TOL;
        o = 0.0;
        if (k && pick[0].zz < DBL_MAX) continue; /* one inside wins */
        if (k) {
            double dx = x, dy = y, d1, d2;
            for (c = 0; c < 4; ++c) {
                dx -= wt[c] * x4[c];
                dy -= wt[c] * y4[c];
            }
            d1 = (x4[3] - x4[0]) * (x4[3] - x4[0]) + (y4[3] - y4[0]) * (y4[3] - y4[0]);
            d2 = (x4[2] - x4[1]) * (x4[2] - x4[1]) + (y4[2] - y4[1]) * (y4[2] - y4[1]);
            o = (dx * dx + dy * dy) / REFL__MAX(d1, d2); /* squared: ranks alike */
            if (!(o <= REFL__SBC_NEAR * REFL__SBC_NEAR)) continue;
        }
        for (c = 0; c < 4; ++c) {
            zz += wt[c] * lam[c] * len[c];
            lm += wt[c] * lam[c];
        }
        /* past the interpolated ray's tail; where rays fold, the nearest
           image off the reflector: one at the tails is the reflector's own
           surface (a knob on a lid lies at its own rays' tails, and also
           ahead of the lid's rays that meet it) */
        if (!(lm >= -1e-4)) continue;
        pk = &pick[k];
        if (pk->off && lm < REFL__SBC_ON_SURFACE) continue;
        if (!(!pk->off && lm >= REFL__SBC_ON_SURFACE)) {
            if (o > pk->out) continue;
            if (o == pk->out && !(zz < pk->zz)) continue;
        }
        pk->off = lm >= REFL__SBC_ON_SURFACE;
        pk->zz = zz;
        pk->out = o;
        {
            double fp[3] = {0.0, 0.0, 0.0};
            for (c = 0; c < 4; ++c) {
                refl_vec3 r = sb->rays[q->idx + (c & 1) + (c >> 1) * W].first;
                fp[0] += wt[c] * r.x; fp[1] += wt[c] * r.y; fp[2] += wt[c] * r.z;
            }
            pk->first = refl_v3((float)fp[0], (float)fp[1], (float)fp[2]);
        }
    }
    for (i = 0; i < REFL__MAX(sheets, 1); ++i) {
        k = picks[i][0].zz < DBL_MAX ? 0 : 1;
        if (!(picks[i][k].zz < DBL_MAX)) continue;
        first[i] = picks[i][k].first;
        z[i] = (float)REFL__MAX(picks[i][k].zz, 0.0);
        mask |= 1 << i;
    }
    return mask;
}

/* The image sheet `sheet` draws of a point with images `mask`: its own,
   else one a fold away (*across): a triangle straddling a fold draws in
   the sheets on both sides, its vertices past the fold at their images
   there, which meet this sheet's at the fold. -1: none. */
static int refl__sbc_sheet_image(int mask, int sheet, int *across) {
    *across = !(mask >> sheet & 1);
    if (!*across) return sheet;
    if (sheet > 0 && (mask >> (sheet - 1) & 1)) return sheet - 1;
    if (mask >> (sheet + 1) & 1) return sheet + 1;
    return -1;
}
