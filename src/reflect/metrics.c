/* Metrics: the reflection error in pixels (test frame's reflected points
   against the ray-traced ones, matched through a kd-tree per reflector) and
   the image error of the colours. Single-threaded and in pixel order, so
   the numbers are the same on every machine and thread count. */
#include "internal.h"

#include <stdlib.h>

/* A pixel shows a point only when all three coordinates are finite: NaN is
   the frames' "none", and an infinite coordinate is no place in the scene. */
static int refl__metric_point(const float *p) {
    return refl__isfinite(p[0]) && refl__isfinite(p[1]) && refl__isfinite(p[2]);
}

static double refl__metric_d2(const float *a, const float *b) {
    double dx = (double)a[0] - b[0], dy = (double)a[1] - b[1], dz = (double)a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

/* ---- kd-tree ------------------------------------------------------------------
   Implicit and balanced over copies of the points (searches then read
   contiguous memory, not the frame at random): a node range [lo, hi) keeps
   its splitting point at the middle, m = lo + (hi - lo) / 2, with the
   smaller keys before it and the larger after; axis[m] says which
   coordinate. Keys tie-break on the pixel index, so the order is total and
   the tree depends on nothing but the points. Ranges this small are
   scanned instead of split. */

enum { REFL__KD_LEAF = 8, REFL__KD_STACK = 128 };
enum { REFL__METRIC_REACH = 16 }; /* pixels searched for a nearer image of a point */

typedef struct refl__kd_point {
    float p[3];
    uint32_t pixel;
} refl__kd_point;

static int refl__kd_less(const refl__kd_point *a, const refl__kd_point *b, int axis) {
    return a->p[axis] < b->p[axis] || (a->p[axis] == b->p[axis] && a->pixel < b->pixel);
}

static void refl__kd_swap(refl__kd_point *a, refl__kd_point *b) {
    refl__kd_point t = *a;
    *a = *b;
    *b = t;
}

/* Puts the k-th smallest (by axis) of v[lo, hi) at k, smaller ones before,
   larger after (quickselect, median-of-three pivots). */
static void refl__kd_select(refl__kd_point *v, size_t lo, size_t hi, size_t k, int axis) {
    while (hi - lo > 2) {
        size_t mid = lo + (hi - lo) / 2, i, store;
        /* order v[lo], v[mid], v[hi - 1]; the median becomes the pivot at hi - 1 */
        if (refl__kd_less(&v[mid], &v[lo], axis)) refl__kd_swap(&v[mid], &v[lo]);
        if (refl__kd_less(&v[hi - 1], &v[lo], axis)) refl__kd_swap(&v[hi - 1], &v[lo]);
        if (refl__kd_less(&v[mid], &v[hi - 1], axis)) refl__kd_swap(&v[mid], &v[hi - 1]);
        for (store = lo, i = lo; i + 1 < hi; ++i)
            if (refl__kd_less(&v[i], &v[hi - 1], axis)) refl__kd_swap(&v[i], &v[store++]);
        refl__kd_swap(&v[store], &v[hi - 1]);
        if (k == store) return;
        if (k < store) hi = store;
        else lo = store + 1;
    }
    if (hi - lo == 2 && refl__kd_less(&v[lo + 1], &v[lo], axis)) refl__kd_swap(&v[lo], &v[lo + 1]);
}

/* Builds the tree over v[lo, hi) in place, with an explicit stack: each
   range splits in halves, so at most one pending range per level. */
static void refl__kd_build(refl__kd_point *v, uint8_t *axes, size_t lo, size_t hi) {
    size_t stack[2 * REFL__KD_STACK];
    int top = 0;
    stack[top++] = lo;
    stack[top++] = hi;
    while (top > 0) {
        size_t h = stack[--top], l = stack[--top], m, i;
        float mn[3], mx[3], ext = -1.0f;
        int axis = 0, c;
        if (h - l <= REFL__KD_LEAF) continue;
        /* split across the widest extent of the range's box */
        for (c = 0; c < 3; ++c) mn[c] = mx[c] = v[l].p[c];
        for (i = l + 1; i < h; ++i)
            for (c = 0; c < 3; ++c) {
                mn[c] = REFL__MIN(mn[c], v[i].p[c]);
                mx[c] = REFL__MAX(mx[c], v[i].p[c]);
            }
        for (c = 0; c < 3; ++c)
            if (mx[c] - mn[c] > ext) {
                ext = mx[c] - mn[c];
                axis = c;
            }
        m = l + (h - l) / 2;
        refl__kd_select(v, l, h, m, axis);
        axes[m] = (uint8_t)axis;
        REFL_ASSERT(top + 4 <= 2 * REFL__KD_STACK);
        stack[top++] = l;
        stack[top++] = m;
        stack[top++] = m + 1;
        stack[top++] = h;
    }
}

/* Offers point e as the nearest to q: nearer wins, ties go to the lower
   pixel index, so the answer does not depend on the tree's shape. */
static void refl__kd_offer(const refl__kd_point *e, const float *q, uint32_t skip, uint32_t *best,
                           double *best_d2) {
    double d2;
    if (e->pixel == skip) return;
    d2 = refl__metric_d2(e->p, q);
    if (d2 < *best_d2 || (d2 == *best_d2 && e->pixel < *best)) {
        *best_d2 = d2;
        *best = e->pixel;
    }
}

/* The pixel in v[lo, hi) whose point lies nearest q, skipping pixel `skip`
   (UINT32_MAX: none), or UINT32_MAX when there is no other. *best and
   *best_d2 come in as a candidate already known (UINT32_MAX, INFINITY:
   none), which prunes the search from the start. */
static void refl__kd_nearest(const refl__kd_point *v, const uint8_t *axes, size_t lo, size_t hi, const float *q,
                             uint32_t skip, uint32_t *best, double *best_d2) {
    struct refl__kd_todo { size_t lo, hi; double bound; } stack[REFL__KD_STACK];
    int top = 1;
    stack[0].lo = lo;
    stack[0].hi = hi;
    stack[0].bound = 0.0;
    while (top > 0) {
        size_t l, h, m;
        double diff;
        --top;
        l = stack[top].lo;
        h = stack[top].hi;
        /* strictly beyond: an equal distance may still win the tie */
        if (stack[top].bound > *best_d2 || l >= h) continue;
        if (h - l <= REFL__KD_LEAF) {
            for (; l < h; ++l) refl__kd_offer(&v[l], q, skip, best, best_d2);
            continue;
        }
        m = l + (h - l) / 2;
        refl__kd_offer(&v[m], q, skip, best, best_d2);
        diff = (double)q[axes[m]] - v[m].p[axes[m]];
        /* the far side first on the stack, so the near side is searched
           first; the stack gains at most one entry per level */
        REFL_ASSERT(top + 2 <= REFL__KD_STACK);
        stack[top].lo = diff < 0.0 ? m + 1 : l;
        stack[top].hi = diff < 0.0 ? h : m;
        stack[top].bound = diff * diff;
        ++top;
        stack[top].lo = diff < 0.0 ? l : m + 1;
        stack[top].hi = diff < 0.0 ? m : h;
        stack[top].bound = 0.0;
        ++top;
    }
}

/* ---- reflection error ------------------------------------------------------------ */

static int refl__metric_cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Fills out from the matched errors (sorted here) and the counts. */
static void refl__metric_summary(double *errors, long long matched, double sum, long long counted, long long wrong,
                                 long long empty, refl_reflection_error *out) {
    out->pixels = counted;
    out->matched = matched;
    if (matched) {
        size_t rank;
        qsort(errors, (size_t)matched, sizeof(double), refl__metric_cmp_double);
        out->mean = sum / (double)matched;
        /* nearest rank: the smallest error that 95% of the matches do not exceed */
        rank = (size_t)ceil(0.95 * (double)matched);
        out->p95 = errors[rank > 0 ? rank - 1 : 0];
        out->max = errors[matched - 1];
    }
    if (counted) {
        out->wrong = (double)wrong / (double)counted;
        out->empty = (double)empty / (double)counted;
    }
}

/* Whether truth pixel (x, y) of reflector id is where an image of p lies:
   its true point matches p (within tolerance times its spacing, as for
   x*), and no 8-neighbour of it on the reflector shows a point nearer p
   (ties to the lower pixel index): the middle of an image of p, not the
   edge of one. */
static int refl__metric_image_of(const refl_frame *truth, const double *spacing, int id, int x, int y, const float *p,
                                 double tolerance) {
    int w = truth->width, h = truth->height, dx, dy;
    size_t i = (size_t)y * (size_t)w + (size_t)x;
    double d2;
    if (x < 0 || y < 0 || x >= w || y >= h || truth->stencil[i] != id || !refl__metric_point(truth->points + 3 * i) ||
        spacing[i] < 0.0)
        return 0;
    d2 = refl__metric_d2(truth->points + 3 * i, p);
    if (sqrt(d2) > tolerance * spacing[i]) return 0;
    for (dy = -1; dy <= 1; ++dy)
        for (dx = -1; dx <= 1; ++dx) {
            int xs = x + dx, ys = y + dy;
            size_t j;
            double dj;
            if ((!dx && !dy) || xs < 0 || ys < 0 || xs >= w || ys >= h) continue;
            j = (size_t)ys * (size_t)w + (size_t)xs;
            if (truth->stencil[j] != id || !refl__metric_point(truth->points + 3 * j)) continue;
            dj = refl__metric_d2(truth->points + 3 * j, p);
            if (dj < d2 || (dj == d2 && j < i)) return 0;
        }
    return 1;
}


static refl_result refl__metric_frames(const refl_frame *test, const refl_frame *truth) {
    if (!test || !truth) return REFL_ERROR_INVALID_ARGUMENT;
    if (test->width <= 0 || test->height <= 0 || test->width != truth->width || test->height != truth->height ||
        (size_t)test->width * (size_t)test->height > (size_t)UINT32_MAX / 4)
        return REFL_ERROR_INVALID_SIZE;
    return REFL_OK;
}

REFL_API refl_result refl_measure_reflection_error(const refl_frame *test, const refl_frame *truth,
                                                   const refl_error_desc *desc, refl_reflection_error *out) {
    refl_allocator a;
    refl__kd_point *kd = NULL;
    uint8_t *axes = NULL;
    double *errors = NULL, tolerance = 1.5, sum = 0.0;
    double *spacing = NULL;
    size_t n, i, start[257], fill[256];
    long long counted = 0, matched = 0, wrong = 0, empty = 0;
    uint32_t last = UINT32_MAX;
    int w;
    refl_result r;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    memset(out, 0, sizeof *out);
    if ((r = refl__metric_frames(test, truth)) != REFL_OK) return r;
    if (!test->points || !truth->points || !truth->stencil) return REFL_ERROR_INVALID_ARGUMENT;
    a = refl__allocator(desc ? &desc->allocator : NULL);
    if ((a.alloc != NULL) != (a.free != NULL)) return REFL_ERROR_INVALID_ARGUMENT;
    if (desc && desc->tolerance != 0.0f) {
        if (!(desc->tolerance > 0.0f) || !refl__isfinite(desc->tolerance)) return REFL_ERROR_INVALID_ARGUMENT;
        tolerance = desc->tolerance;
    }
    w = truth->width;
    n = (size_t)w * (size_t)truth->height;

    /* the truth's points, grouped by reflector id (a counting sort, so each
       group starts in pixel order), then one tree per group */
    memset(start, 0, sizeof start);
    for (i = 0; i < n; ++i)
        if (truth->stencil[i] && refl__metric_point(truth->points + 3 * i)) ++start[truth->stencil[i] + 1];
    for (i = 1; i < 257; ++i) start[i] += start[i - 1];
    kd = (refl__kd_point *)refl__calloc(&a, start[256], sizeof(refl__kd_point));
    axes = (uint8_t *)refl__calloc(&a, start[256], 1);
    errors = (double *)refl__calloc(&a, n, sizeof(double));
    spacing = (double *)refl__calloc(&a, n, sizeof(double));
    if (!kd || !axes || !errors || !spacing) {
        r = REFL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    memcpy(fill, start, sizeof fill);
    for (i = 0; i < n; ++i)
        if (truth->stencil[i] && refl__metric_point(truth->points + 3 * i)) {
            refl__kd_point *e = &kd[fill[truth->stencil[i]]++];
            memcpy(e->p, truth->points + 3 * i, sizeof e->p);
            e->pixel = (uint32_t)i;
        }
    for (i = 1; i < 256; ++i) refl__kd_build(kd, axes, start[i], start[i + 1]);
    /* each true point's spacing to its 4-neighbours (-1: none of them) */
    for (i = 0; i < n; ++i) {
        int id = truth->stencil[i], x = (int)(i % (size_t)w), y = (int)(i / (size_t)w), k;
        double s2 = -1.0;
        if (!id || !refl__metric_point(truth->points + 3 * i)) continue;
        for (k = 0; k < 4; ++k) {
            int xs = x + (k == 0) - (k == 1), ys = y + (k == 2) - (k == 3);
            size_t j;
            if (xs < 0 || ys < 0 || xs >= w || ys >= truth->height) continue;
            j = (size_t)ys * (size_t)w + (size_t)xs;
            if (truth->stencil[j] != id || !refl__metric_point(truth->points + 3 * j)) continue;
            s2 = REFL__MAX(s2, refl__metric_d2(truth->points + 3 * i, truth->points + 3 * j));
        }
        spacing[i] = s2 < 0.0 ? -1.0 : sqrt(s2);
    }

    for (i = 0; i < n; ++i) {
        int id = truth->stencil[i], x, y;
        const float *p = test->points + 3 * i, *tp;
        uint32_t best = UINT32_MAX, other = UINT32_MAX;
        double d2 = INFINITY, spacing2 = -1.0;
        if (!id) continue;
        if (!refl__metric_point(p)) {
            if (refl__metric_point(truth->points + 3 * i)) {
                ++counted;
                ++empty;
            }
            continue;
        }
        ++counted;
        /* a first candidate bounds the search: the truth at this pixel, else
           the previous match (neighbouring pixels show neighbouring points) */
        if (refl__metric_point(truth->points + 3 * i)) best = (uint32_t)i;
        else if (last != UINT32_MAX && truth->stencil[last] == id) best = last;
        if (best != UINT32_MAX) d2 = refl__metric_d2(truth->points + 3 * (size_t)best, p);
        refl__kd_nearest(kd, axes, start[id], start[id + 1], p, UINT32_MAX, &best, &d2);
        if (best == UINT32_MAX) { /* this reflector shows nothing in the truth */
            ++wrong;
            continue;
        }
        last = best;
        /* the spacing of the true points around x*: the farthest of its
           4-neighbours on the same reflector, else the nearest other point */
        x = (int)(best % (uint32_t)w);
        y = (int)(best / (uint32_t)w);
        tp = truth->points + 3 * (size_t)best;
        if (spacing[best] >= 0.0) spacing2 = spacing[best] * spacing[best];
        if (spacing2 < 0.0) {
            spacing2 = INFINITY;
            refl__kd_nearest(kd, axes, start[id], start[id + 1], tp, best, &other, &spacing2);
            if (other == UINT32_MAX) spacing2 = 0.0; /* the only point: only itself matches */
        }
        if (sqrt(d2) <= tolerance * sqrt(spacing2)) {
            int xi = (int)(i % (size_t)w), yi = (int)(i / (size_t)w), dx, dy, reach;
            double e = sqrt((double)(xi - x) * (xi - x) + (double)(yi - y) * (yi - y));
            /* the same point may show in more than one place on a reflector
               (a minified image beside a magnified one, where the nearest
               true point is likelier): the error is the distance to the
               nearest place within REFL__METRIC_REACH pixels where the
               truth shows P too (refl__metric_image_of) */
            reach = (int)REFL__MIN(ceil(e) - 1.0, (double)REFL__METRIC_REACH);
            for (dy = -reach; dy <= reach; ++dy)
                for (dx = -reach; dx <= reach; ++dx) {
                    int xs = xi + dx, ys = yi + dy;
                    double ej = sqrt((double)(dx * dx + dy * dy));
                    if (ej < e && ej <= (double)REFL__METRIC_REACH &&
                        refl__metric_image_of(truth, spacing, id, xs, ys, p, tolerance))
                        e = ej;
                }
            errors[matched++] = e;
            sum += e;
        } else {
            ++wrong;
        }
    }

    refl__metric_summary(errors, matched, sum, counted, wrong, empty, out);
    r = REFL_OK;
done:
    refl__free(&a, errors);
    refl__free(&a, spacing);
    refl__free(&a, axes);
    refl__free(&a, kd);
    return r;
}

/* ---- image error ------------------------------------------------------------------ */

REFL_API refl_result refl_measure_image_error(const refl_frame *test, const refl_frame *truth, int reflectors_only,
                                             float threshold, refl_image_error *out) {
    unsigned long long sum = 0; /* squared 8-bit differences: exact */
    long long count = 0, over = 0;
    int max_diff = 0;
    double level;
    size_t n, i;
    refl_result r;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    memset(out, 0, sizeof *out);
    out->psnr = INFINITY;
    if ((r = refl__metric_frames(test, truth)) != REFL_OK) return r;
    if (!test->rgba || !truth->rgba || (reflectors_only && !truth->stencil)) return REFL_ERROR_INVALID_ARGUMENT;
    if (!(threshold >= 0.0f) || !refl__isfinite(threshold)) return REFL_ERROR_INVALID_ARGUMENT;
    /* over when a difference of d levels has d / 255 > threshold; the small
       margin keeps a difference of exactly the threshold under it */
    level = (threshold == 0.0f ? 2.0 / 255.0 : (double)threshold) * 255.0 + 1e-6;
    n = (size_t)truth->width * (size_t)truth->height;
    for (i = 0; i < n; ++i) {
        int c, worst = 0;
        if (reflectors_only && !truth->stencil[i]) continue;
        for (c = 0; c < 3; ++c) {
            int d = (int)refl__unorm8(test->rgba[4 * i + (size_t)c]) - (int)refl__unorm8(truth->rgba[4 * i + (size_t)c]);
            d = d < 0 ? -d : d;
            sum += (unsigned long long)(d * d);
            worst = REFL__MAX(worst, d);
        }
        max_diff = REFL__MAX(max_diff, worst);
        over += (double)worst > level;
        ++count;
    }
    out->pixels = count;
    if (count) {
        out->rmse = sqrt((double)sum / (3.0 * (double)count)) / 255.0;
        out->psnr = out->rmse > 0.0 ? 20.0 * log10(1.0 / out->rmse) : INFINITY;
        out->max_diff = max_diff / 255.0;
        out->over_threshold = (double)over / (double)count;
    }
    return REFL_OK;
}

/* The largest RGB channel difference of pixel i between two frames, in
   8-bit levels. */
static int refl__level_change(const refl_frame *a, const refl_frame *b, size_t i) {
    int c, worst = 0;
    for (c = 0; c < 3; ++c) {
        int d = (int)refl__unorm8(a->rgba[4 * i + (size_t)c]) - (int)refl__unorm8(b->rgba[4 * i + (size_t)c]);
        worst = REFL__MAX(worst, d < 0 ? -d : d);
    }
    return worst;
}

REFL_API refl_result refl_measure_flicker(const refl_frame *test_prev, const refl_frame *test,
                                          const refl_frame *truth_prev, const refl_frame *truth, refl_flicker *out) {
    long long histogram[256], count = 0, rank, seen = 0;
    double excess = 0.0, test_sum = 0.0, truth_sum = 0.0;
    size_t n, i;
    int level;
    refl_result r;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    memset(out, 0, sizeof *out);
    if ((r = refl__metric_frames(test, truth)) != REFL_OK || (r = refl__metric_frames(test_prev, truth)) != REFL_OK ||
        (r = refl__metric_frames(truth_prev, truth)) != REFL_OK)
        return r;
    if (!test->rgba || !test_prev->rgba || !truth->rgba || !truth_prev->rgba || !truth->stencil || !truth_prev->stencil)
        return REFL_ERROR_INVALID_ARGUMENT;
    memset(histogram, 0, sizeof histogram);
    n = (size_t)truth->width * (size_t)truth->height;
    for (i = 0; i < n; ++i) {
        int dt, dr;
        if (!truth->stencil[i] || !truth_prev->stencil[i]) continue;
        dt = refl__level_change(test, test_prev, i);
        dr = refl__level_change(truth, truth_prev, i);
        histogram[REFL__MAX(dt - dr, 0)]++;
        excess += REFL__MAX(dt - dr, 0);
        test_sum += dt;
        truth_sum += dr;
        ++count;
    }
    out->pixels = count;
    if (!count) return REFL_OK;
    out->mean = excess / (double)count;
    out->test_change = test_sum / (double)count;
    out->truth_change = truth_sum / (double)count;
    rank = (long long)ceil(0.95 * (double)count); /* nearest rank */
    for (level = 0; level < 256; ++level) {
        seen += histogram[level];
        if (seen >= rank) break;
    }
    out->p95 = level;
    return REFL_OK;
}
