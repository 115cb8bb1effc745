/* Metrics: the reflection error in pixels against a synthetic true
   reflection with known answers (identical frames, shifted frames, points
   found nowhere, points of another reflector, holes, the tolerance), the
   image error's exact numbers, bad input, allocation failure, and RAYTRACE
   measured against itself on the default scene. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "../../tools/image_io.h"
#include "../test_util.h"

enum { W = 64, H = 48 };

/* Reflector 1 covers x in [8, 56), y in [6, 38); reflector 2 the rows
   [40, 46) of the same columns. */
static int region(int x, int y) {
    if (x < 8 || x >= 56) return 0;
    if (y >= 6 && y < 38) return 1;
    if (y >= 40 && y < 46) return 2;
    return 0;
}

/* The "true reflection": reflector 1 shows a ground plane y = -1 through a
   perspective mapping (farther rows are wider apart, so the spacing of the
   points changes across the reflector), reflector 2 a wall far from it. */
static void true_point(int x, int y, float p[3]) {
    if (region(x, y) == 1) {
        double depth = 4.0 / (0.25 + 0.02 * y);
        p[0] = (float)((x - 31.5) * 0.05 * depth);
        p[1] = -1.0f;
        p[2] = (float)depth;
    } else {
        p[0] = (float)((x - 31.5) * 0.1);
        p[1] = (float)(3.0 + 0.1 * y);
        p[2] = 20.0f;
    }
}

static float *pt(refl_frame *f, int x, int y) { return f->points + 3 * ((size_t)y * (size_t)f->width + (size_t)x); }
static uint8_t *st(refl_frame *f, int x, int y) { return f->stencil + (size_t)y * (size_t)f->width + (size_t)x; }

static void set_none(float *p) { p[0] = p[1] = p[2] = NAN; }

static refl_frame *truth_frame(void) {
    refl_frame *f = NULL;
    int x, y;
    cr_assert_eq(refl_frame_create(W, H, NULL, &f), REFL_OK);
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            *st(f, x, y) = (uint8_t)region(x, y);
            if (region(x, y)) true_point(x, y, pt(f, x, y));
            else set_none(pt(f, x, y));
        }
    return f;
}

/* A copy of the truth whose pixel x shows what the truth shows at x + (dx,
   dy) when that pixel lies on the same reflector, else nothing. */
static refl_frame *shifted(refl_frame *truth, int dx, int dy) {
    refl_frame *f = NULL;
    int x, y;
    cr_assert_eq(refl_frame_create(truth->width, truth->height, NULL, &f), REFL_OK);
    memcpy(f->stencil, truth->stencil, (size_t)truth->width * (size_t)truth->height);
    for (y = 0; y < truth->height; ++y)
        for (x = 0; x < truth->width; ++x) {
            int xs = x + dx, ys = y + dy;
            if (xs >= 0 && ys >= 0 && xs < truth->width && ys < truth->height && *st(truth, x, y) &&
                *st(truth, xs, ys) == *st(truth, x, y))
                memcpy(pt(f, x, y), pt(truth, xs, ys), 3 * sizeof(float));
            else
                set_none(pt(f, x, y));
        }
    return f;
}

static refl_frame *copy_frame(refl_frame *truth) { return shifted(truth, 0, 0); }

static refl_reflection_error measure(refl_frame *test, refl_frame *truth, float tolerance) {
    refl_error_desc d;
    refl_reflection_error e;
    refl_result r;
    memset(&d, 0, sizeof d);
    d.tolerance = tolerance;
    r = refl_measure_reflection_error(test, truth, &d, &e);
    cr_assert_eq(r, REFL_OK, "%s", refl_result_string(r));
    return e;
}

/* The largest distance from the truth's point at (x, y) to those of its
   4-neighbours on the same reflector: the metric's local spacing. */
static double spacing(refl_frame *truth, int x, int y) {
    static const int d[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    double s = 0.0;
    int k, c;
    for (k = 0; k < 4; ++k) {
        int xs = x + d[k][0], ys = y + d[k][1];
        double d2 = 0.0;
        if (region(xs, ys) != region(x, y)) continue;
        for (c = 0; c < 3; ++c) {
            double v = (double)pt(truth, x, y)[c] - pt(truth, xs, ys)[c];
            d2 += v * v;
        }
        s = fmax(s, sqrt(d2));
    }
    return s;
}

static const long long REFLECTOR_PIXELS = 48 * 32 + 48 * 6;

Test(refl_metrics, identical_frames_match_everything_with_no_error) {
    refl_frame *truth = truth_frame(), *test = copy_frame(truth);
    refl_reflection_error e = measure(test, truth, 0.0f);
    cr_assert_eq(e.pixels, REFLECTOR_PIXELS);
    cr_assert_eq(e.matched, REFLECTOR_PIXELS);
    cr_assert(e.mean == 0.0 && e.p95 == 0.0 && e.max == 0.0, "mean %g p95 %g max %g", e.mean, e.p95, e.max);
    cr_assert(e.wrong == 0.0 && e.empty == 0.0);
    /* the truth against itself, and NULL desc (the defaults) */
    cr_assert_eq(refl_measure_reflection_error(truth, truth, NULL, &e), REFL_OK);
    cr_assert_eq(e.matched, REFLECTOR_PIXELS);
    cr_assert(e.max == 0.0);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

/* Test pixel x shows the truth's point at x + k: every matched pixel is off
   by exactly |k|, and the k columns whose source lies off the reflector are
   holes. */
Test(refl_metrics, shifted_frames_are_off_by_the_shift) {
    refl_frame *truth = truth_frame();
    static const int shifts[4][3] = {{3, 0, 3}, {-2, 0, 2}, {0, 1, 1}, {3, 4, 5}};
    int s;
    for (s = 0; s < 4; ++s) {
        int dx = shifts[s][0], dy = shifts[s][1], x, y;
        refl_frame *test = shifted(truth, dx, dy);
        refl_reflection_error e = measure(test, truth, 0.0f);
        long long holes = 0;
        for (y = 0; y < H; ++y)
            for (x = 0; x < W; ++x)
                if (region(x, y) && region(x + dx, y + dy) != region(x, y)) ++holes;
        cr_assert_eq(e.pixels, REFLECTOR_PIXELS, "shift %d,%d", dx, dy);
        cr_assert_eq(e.matched, REFLECTOR_PIXELS - holes, "shift %d,%d", dx, dy);
        cr_assert(fabs(e.mean - shifts[s][2]) < 1e-9, "shift %d,%d: mean %.12g", dx, dy, e.mean);
        cr_assert(e.p95 == shifts[s][2] && e.max == shifts[s][2], "p95 %g max %g", e.p95, e.max);
        cr_assert_eq(e.wrong, 0.0);
        cr_assert(fabs(e.empty - (double)holes / (double)REFLECTOR_PIXELS) < 1e-15, "empty %g", e.empty);
        refl_frame_destroy(test);
    }
    refl_frame_destroy(truth);
}

/* p95 is a nearest rank over the matched errors (the smallest error that
   95% of them do not exceed), max their largest. */
Test(refl_metrics, p95_and_max_of_a_mixed_shift) {
    refl_frame *truth = truth_frame(), *test = copy_frame(truth);
    int x, y, k = 0;
    refl_reflection_error e;
    /* 100 pixels of reflector 1 off by 2 columns, one by 7; the rest exact */
    for (y = 10; y < 36 && k < 101; ++y)
        for (x = 20; x < 40 && k < 101; x += 4, ++k)
            memcpy(pt(test, x, y), pt(truth, x + (k == 100 ? 7 : 2), y), 3 * sizeof(float));
    e = measure(test, truth, 0.0f);
    cr_assert_eq(e.matched, REFLECTOR_PIXELS);
    cr_assert(fabs(e.mean - (100 * 2.0 + 7.0) / (double)REFLECTOR_PIXELS) < 1e-12, "mean %g", e.mean);
    cr_assert_eq(e.p95, 2.0); /* 1723 exact, 100 off by 2, 1 by 7: rank 1733 is a 2 */
    cr_assert_eq(e.max, 7.0);
    /* with 15 fewer off by 2, 95% are exact */
    for (y = 10, k = 0; k < 15; y += 1, ++k) memcpy(pt(test, 20, y), pt(truth, 20, y), 3 * sizeof(float));
    e = measure(test, truth, 0.0f);
    cr_assert(fabs(e.mean - (85 * 2.0 + 7.0) / (double)REFLECTOR_PIXELS) < 1e-12, "mean %g", e.mean);
    cr_assert_eq(e.p95, 0.0);
    cr_assert_eq(e.max, 7.0);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

Test(refl_metrics, points_found_nowhere_are_wrong) {
    refl_frame *truth = truth_frame(), *test = copy_frame(truth);
    refl_reflection_error e;
    int i;
    for (i = 0; i < 10; ++i) {
        float *p = pt(test, 10 + i, 20);
        p[0] = 1000.0f; p[1] = 1000.0f + (float)i; p[2] = -1000.0f;
    }
    e = measure(test, truth, 0.0f);
    cr_assert_eq(e.pixels, REFLECTOR_PIXELS);
    cr_assert_eq(e.matched, REFLECTOR_PIXELS - 10);
    cr_assert(fabs(e.wrong - 10.0 / (double)REFLECTOR_PIXELS) < 1e-15, "wrong %g", e.wrong);
    cr_assert_eq(e.empty, 0.0);
    cr_assert_eq(e.max, 0.0);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

/* A point off the true surface by a fraction of the local spacing matches
   its nearest true pixel; beyond tolerance times the spacing it is wrong,
   and a larger tolerance takes it back. */
Test(refl_metrics, tolerance_is_relative_to_the_local_spacing) {
    refl_frame *truth = truth_frame(), *test = copy_frame(truth);
    refl_reflection_error e;
    int i;
    static const int at[4][2] = {{12, 8}, {30, 20}, {50, 35}, {20, 42}};
    for (i = 0; i < 4; ++i) {
        int x = at[i][0], y = at[i][1];
        double s = spacing(truth, x, y);
        /* along the surface normal (y for reflector 1, z for 2), so the
           nearest true point is still the pixel's own */
        pt(test, x, y)[region(x, y) == 1 ? 1 : 2] += (float)(s * (i < 2 ? 0.5 : 3.0));
    }
    e = measure(test, truth, 0.0f);
    cr_assert_eq(e.matched, REFLECTOR_PIXELS - 2);
    cr_assert(fabs(e.wrong - 2.0 / (double)REFLECTOR_PIXELS) < 1e-15);
    cr_assert_eq(e.max, 0.0);
    e = measure(test, truth, 4.0f);
    cr_assert_eq(e.matched, REFLECTOR_PIXELS);
    cr_assert_eq(e.max, 0.0);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

/* Reflector 1 showing what reflector 2 shows is wrong, although those
   points are exactly true points: matching never crosses reflector ids. */
Test(refl_metrics, points_of_another_reflector_do_not_match) {
    refl_frame *truth = truth_frame(), *test = copy_frame(truth);
    refl_reflection_error e;
    int x, y;
    for (y = 6; y < 12; ++y)
        for (x = 8; x < 56; ++x) memcpy(pt(test, x, y), pt(truth, x, y + 34), 3 * sizeof(float));
    e = measure(test, truth, 0.0f);
    cr_assert_eq(e.pixels, REFLECTOR_PIXELS);
    cr_assert_eq(e.matched, REFLECTOR_PIXELS - 48 * 6);
    cr_assert(fabs(e.wrong - 48.0 * 6.0 / (double)REFLECTOR_PIXELS) < 1e-15, "wrong %g", e.wrong);
    /* relabelled as reflector 2 in the truth too, the same points match */
    for (y = 6; y < 12; ++y)
        for (x = 8; x < 56; ++x) *st(truth, x, y) = 2;
    e = measure(test, truth, 0.0f);
    cr_assert_eq(e.wrong, 0.0);
    cr_assert_eq(e.max, 34.0);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

/* Holes: the truth shows a point, the test none (NaN, or any non-finite
   coordinate). Where neither shows one the pixel is not counted; where only
   the test does, it is matched or wrong like any other. */
Test(refl_metrics, holes_and_pixels_neither_shows) {
    refl_frame *truth = truth_frame(), *test = copy_frame(truth);
    refl_reflection_error e;
    int x, y;
    for (y = 10; y < 14; ++y) /* 16 pixels where the truth shows the environment */
        for (x = 20; x < 24; ++x) {
            set_none(pt(truth, x, y));
            set_none(pt(test, x, y));
        }
    for (x = 30; x < 40; ++x) set_none(pt(test, x, 25)); /* 10 holes */
    pt(test, 41, 25)[0] = INFINITY;                       /* 2 more */
    pt(test, 42, 25)[2] = -INFINITY;
    pt(test, 43, 26)[1] = NAN;                             /* 1 more */
    memcpy(pt(test, 20, 30), pt(truth, 21, 30), 3 * sizeof(float));
    memcpy(pt(test, 10, 10), pt(truth, 10, 9), 3 * sizeof(float));
    /* a point where the truth shows none: matched to its nearest neighbour */
    memcpy(pt(test, 20, 10), pt(truth, 19, 10), 3 * sizeof(float));
    /* and an inf in the truth is none too: (50, 30) is then a test point
       matched one pixel away */
    pt(truth, 50, 30)[1] = INFINITY;
    e = measure(test, truth, 0.0f);
    cr_assert_eq(e.pixels, REFLECTOR_PIXELS - 16 + 1);
    cr_assert_eq(e.matched, e.pixels - 13);
    cr_assert(fabs(e.empty - 13.0 / (double)e.pixels) < 1e-15, "empty %g", e.empty);
    cr_assert_eq(e.wrong, 0.0);
    cr_assert_eq(e.max, 1.0);
    cr_assert(fabs(e.mean - 4.0 / (double)e.matched) < 1e-15, "mean %g", e.mean);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

/* The definition, by brute force: a linear scan over the truth's pixels
   instead of the kd-tree, ties to the lowest pixel index. */
static int shows(const float *p) { return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]); }

static double dist2(const float *a, const float *b) {
    double dx = (double)a[0] - b[0], dy = (double)a[1] - b[1], dz = (double)a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static refl_reflection_error brute_force(refl_frame *test, refl_frame *truth, double tolerance) {
    int w = truth->width, n = truth->width * truth->height, i, j;
    double *err = (double *)calloc((size_t)n, sizeof(double)), sum = 0.0;
    long long wrong = 0, empty = 0;
    refl_reflection_error e;
    memset(&e, 0, sizeof e);
    cr_assert_not_null(err);
    for (i = 0; i < n; ++i) {
        int id = truth->stencil[i], best = -1, k;
        double bd = INFINITY, s2 = -1.0;
        if (!id) continue;
        if (!shows(test->points + 3 * i)) {
            if (shows(truth->points + 3 * i)) ++e.pixels, ++empty;
            continue;
        }
        ++e.pixels;
        for (j = 0; j < n; ++j) {
            double d;
            if (truth->stencil[j] != id || !shows(truth->points + 3 * j)) continue;
            d = dist2(truth->points + 3 * j, test->points + 3 * i);
            if (d < bd) bd = d, best = j;
        }
        if (best < 0) { ++wrong; continue; }
        for (k = 0; k < 4; ++k) {
            int x = best % w + (k == 0) - (k == 1), y = best / w + (k == 2) - (k == 3);
            if (x < 0 || y < 0 || x >= w || y >= truth->height) continue;
            j = y * w + x;
            if (truth->stencil[j] == id && shows(truth->points + 3 * j))
                s2 = fmax(s2, dist2(truth->points + 3 * best, truth->points + 3 * j));
        }
        if (s2 < 0.0) {
            double nd = INFINITY;
            for (j = 0; j < n; ++j)
                if (j != best && truth->stencil[j] == id && shows(truth->points + 3 * j))
                    nd = fmin(nd, dist2(truth->points + 3 * best, truth->points + 3 * j));
            s2 = isinf(nd) ? 0.0 : nd;
        }
        if (sqrt(bd) <= tolerance * sqrt(s2)) {
            double dx = i % w - best % w, dy = i / w - best / w, ex = sqrt(dx * dx + dy * dy);
            /* a nearer image of the point: a pixel within 16 (and nearer
               than x*) matching it within its own spacing, nearer it than
               its 8 neighbours are */
            for (j = 0; j < n; ++j) {
                double ej = sqrt((double)(i % w - j % w) * (i % w - j % w) + (double)(i / w - j / w) * (i / w - j / w));
                double dj, sj = -1.0;
                int ok = 1, m;
                if (ej >= ex || ej > 16.0 || abs(i % w - j % w) > 16 || abs(i / w - j / w) > 16) continue;
                if (truth->stencil[j] != id || !shows(truth->points + 3 * j)) continue;
                for (k = 0; k < 4; ++k) {
                    int x = j % w + (k == 0) - (k == 1), y = j / w + (k == 2) - (k == 3);
                    if (x < 0 || y < 0 || x >= w || y >= truth->height) continue;
                    m = y * w + x;
                    if (truth->stencil[m] == id && shows(truth->points + 3 * m))
                        sj = fmax(sj, sqrt(dist2(truth->points + 3 * j, truth->points + 3 * m)));
                }
                dj = dist2(truth->points + 3 * j, test->points + 3 * i);
                if (sj < 0.0 || sqrt(dj) > tolerance * sj) continue;
                for (k = 0; k < 9 && ok; ++k) {
                    int x = j % w + k % 3 - 1, y = j / w + k / 3 - 1;
                    double dm;
                    if (k == 4 || x < 0 || y < 0 || x >= w || y >= truth->height) continue;
                    m = y * w + x;
                    if (truth->stencil[m] != id || !shows(truth->points + 3 * m)) continue;
                    dm = dist2(truth->points + 3 * m, test->points + 3 * i);
                    if (dm < dj || (dm == dj && m < j)) ok = 0;
                }
                if (ok) ex = ej;
            }
            err[e.matched] = ex;
            sum += err[e.matched++];
        } else {
            ++wrong;
        }
    }
    if (e.matched) {
        qsort(err, (size_t)e.matched, sizeof(double), cmp_double);
        e.mean = sum / (double)e.matched;
        e.p95 = err[(size_t)ceil(0.95 * (double)e.matched) - 1];
        e.max = err[e.matched - 1];
    }
    if (e.pixels) {
        e.wrong = (double)wrong / (double)e.pixels;
        e.empty = (double)empty / (double)e.pixels;
    }
    free(err);
    return e;
}

/* Random truths and tests, among them coarse grids full of duplicate points
   and ties, and reflectors that all show one point: the kd-tree search
   agrees with the linear scan exactly. */
Test(refl_metrics, kd_tree_agrees_with_a_linear_scan) {
    tu_rng rng = tu_rng_make(7);
    int round;
    for (round = 0; round < 12; ++round) {
        int w = 20 + tu_rng_int(&rng, 0, 80), h = 10 + tu_rng_int(&rng, 0, 60), i, n = w * h;
        double grid = round % 3 == 0 ? 0.0 : (round % 3 == 1 ? 0.25 : 1e-6);
        refl_frame *truth = NULL, *test = NULL;
        refl_reflection_error got, want;
        float tol = round % 4 == 3 ? 0.5f : 1.5f;
        cr_assert_eq(refl_frame_create(w, h, NULL, &truth), REFL_OK);
        cr_assert_eq(refl_frame_create(w, h, NULL, &test), REFL_OK);
        for (i = 0; i < n; ++i) {
            float *p = truth->points + 3 * i, *q = test->points + 3 * i;
            int c, kind = tu_rng_int(&rng, 0, 9);
            truth->stencil[i] = (uint8_t)(round == 5 ? 255 : tu_rng_int(&rng, 0, 3));
            for (c = 0; c < 3; ++c) {
                double v = tu_rng_range(&rng, -2.0, 2.0);
                if (grid > 0.0) v = floor(v / grid) * grid;
                if (round == 8) v = 0.5; /* every point the same */
                p[c] = (float)v;
            }
            if (tu_rng_int(&rng, 0, 9) == 0) set_none(p);
            if (kind < 4) { /* a true point of a random pixel */
                memcpy(q, truth->points + 3 * tu_rng_int(&rng, 0, i), 3 * sizeof(float));
            } else if (kind < 8) {
                for (c = 0; c < 3; ++c) q[c] = (float)tu_rng_range(&rng, -2.5, 2.5);
            } else if (kind < 9) {
                set_none(q);
                if (i % 2) q[0] = q[1] = 1e30f, q[2] = INFINITY;
            } else { /* far from everything */
                q[0] = 100.0f; q[1] = (float)tu_rng_range(&rng, 100.0, 101.0); q[2] = -100.0f;
            }
        }
        memset(&got, 0, sizeof got);
        got = measure(test, truth, tol);
        want = brute_force(test, truth, tol);
        cr_assert(got.pixels == want.pixels && got.matched == want.matched, "round %d: %lld/%lld vs %lld/%lld", round,
                  got.matched, got.pixels, want.matched, want.pixels);
        cr_assert(got.mean == want.mean && got.p95 == want.p95 && got.max == want.max, "round %d: %g %g %g vs %g %g %g",
                  round, got.mean, got.p95, got.max, want.mean, want.p95, want.max);
        cr_assert(got.wrong == want.wrong && got.empty == want.empty, "round %d", round);
        cr_assert(got.matched > 0 && got.wrong > 0 && got.empty > 0, "round %d: a weak case", round);
        refl_frame_destroy(test);
        refl_frame_destroy(truth);
    }
}

Test(refl_metrics, frames_without_reflectors_give_zeros) {
    refl_frame *truth = NULL, *test = NULL;
    refl_reflection_error e;
    refl_image_error ie;
    cr_assert_eq(refl_frame_create(17, 9, NULL, &truth), REFL_OK);
    cr_assert_eq(refl_frame_create(17, 9, NULL, &test), REFL_OK);
    test->stencil[5] = 3; /* the test's stencil does not choose the pixels */
    memset(&e, 0xff, sizeof e);
    cr_assert_eq(refl_measure_reflection_error(test, truth, NULL, &e), REFL_OK);
    cr_assert(e.pixels == 0 && e.matched == 0 && e.mean == 0.0 && e.p95 == 0.0 && e.max == 0.0 &&
              e.wrong == 0.0 && e.empty == 0.0);
    cr_assert_eq(refl_measure_image_error(test, truth, 1, 0.0f, &ie), REFL_OK);
    cr_assert(ie.pixels == 0 && ie.rmse == 0.0 && isinf(ie.psnr) && ie.max_diff == 0.0 && ie.over_threshold == 0.0);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

/* A reflector whose true reflection is all environment: every test point on
   it is wrong; a reflector with one true point matches only that point. */
Test(refl_metrics, reflectors_with_few_true_points) {
    refl_frame *truth = truth_frame(), *test = copy_frame(truth);
    refl_reflection_error e;
    int x, y;
    for (y = 40; y < 46; ++y)
        for (x = 8; x < 56; ++x) set_none(pt(truth, x, y));
    e = measure(test, truth, 0.0f);
    cr_assert_eq(e.pixels, REFLECTOR_PIXELS);
    cr_assert_eq(e.matched, REFLECTOR_PIXELS - 48 * 6);
    true_point(30, 42, pt(truth, 30, 42)); /* the one true point of reflector 2 */
    e = measure(test, truth, 0.0f);
    cr_assert_eq(e.matched, REFLECTOR_PIXELS - 48 * 6 + 1);
    cr_assert_eq(e.max, 0.0);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

Test(refl_metrics, bad_input_is_refused) {
    refl_frame *truth = truth_frame(), *test = copy_frame(truth), *small = NULL;
    refl_error_desc d;
    refl_reflection_error e;
    refl_image_error ie;
    cr_assert_eq(refl_frame_create(W, H - 1, NULL, &small), REFL_OK);
    memset(&d, 0, sizeof d);
    cr_assert_eq(refl_measure_reflection_error(NULL, truth, &d, &e), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_measure_reflection_error(test, NULL, &d, &e), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_measure_reflection_error(test, truth, &d, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_measure_reflection_error(small, truth, &d, &e), REFL_ERROR_INVALID_SIZE);
    cr_assert_eq(refl_measure_reflection_error(test, small, &d, &e), REFL_ERROR_INVALID_SIZE);
    d.tolerance = -1.0f;
    cr_assert_eq(refl_measure_reflection_error(test, truth, &d, &e), REFL_ERROR_INVALID_ARGUMENT);
    d.tolerance = NAN;
    cr_assert_eq(refl_measure_reflection_error(test, truth, &d, &e), REFL_ERROR_INVALID_ARGUMENT);
    d.tolerance = INFINITY;
    cr_assert_eq(refl_measure_reflection_error(test, truth, &d, &e), REFL_ERROR_INVALID_ARGUMENT);
    d.tolerance = 0.0f;
    d.allocator.alloc = tu_count_alloc; /* alloc without free */
    cr_assert_eq(refl_measure_reflection_error(test, truth, &d, &e), REFL_ERROR_INVALID_ARGUMENT);

    cr_assert_eq(refl_measure_image_error(NULL, truth, 0, 0.0f, &ie), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_measure_image_error(test, NULL, 0, 0.0f, &ie), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_measure_image_error(test, truth, 0, 0.0f, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_measure_image_error(small, truth, 0, 0.0f, &ie), REFL_ERROR_INVALID_SIZE);
    cr_assert_eq(refl_measure_image_error(test, truth, 0, -0.1f, &ie), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_measure_image_error(test, truth, 0, NAN, &ie), REFL_ERROR_INVALID_ARGUMENT);
    refl_frame_destroy(small);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

/* Every allocation may fail: each run returns OUT_OF_MEMORY or the full
   answer, and frees what it took. */
Test(refl_metrics, allocation_failure_leaks_nothing) {
    refl_frame *truth = truth_frame(), *test = shifted(truth, 3, 1);
    refl_reflection_error want = measure(test, truth, 0.0f);
    long k;
    int saw_failure = 0;
    for (k = 1; k < 100; ++k) {
        tu_alloc_counter c;
        refl_error_desc d;
        refl_reflection_error e;
        refl_result r;
        memset(&c, 0, sizeof c);
        c.fail_at = k;
        memset(&d, 0, sizeof d);
        d.allocator.alloc = tu_count_alloc;
        d.allocator.free = tu_count_free;
        d.allocator.user = &c;
        r = refl_measure_reflection_error(test, truth, &d, &e);
        cr_assert_eq(c.allocs, c.frees, "k=%ld: %ld allocations, %ld frees", k, c.allocs, c.frees);
        if (!c.failed) {
            cr_assert_eq(r, REFL_OK);
            cr_assert(!memcmp(&e, &want, sizeof e), "k=%ld: a different answer", k);
            break;
        }
        cr_assert_eq(r, REFL_ERROR_OUT_OF_MEMORY, "k=%ld: %s", k, refl_result_string(r));
        cr_assert_eq(e.pixels, 0);
        saw_failure = 1;
    }
    cr_assert(saw_failure && k > 1 && k < 100, "k=%ld", k);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

/* ---- image error ---- */

static void fill_color(refl_frame *f, uint8_t r, uint8_t g, uint8_t b) {
    size_t i, n = (size_t)f->width * (size_t)f->height;
    for (i = 0; i < n; ++i) {
        f->rgba[4 * i] = (float)r / 255.0f;
        f->rgba[4 * i + 1] = (float)g / 255.0f;
        f->rgba[4 * i + 2] = (float)b / 255.0f;
        f->rgba[4 * i + 3] = (float)255 / 255.0f;
    }
}

Test(refl_metrics, image_error_known_answers) {
    refl_frame *truth = truth_frame(), *test = copy_frame(truth);
    refl_image_error ie;
    refl_image_diff cmp;
    const double n = W * H;
    static uint8_t test8[4 * W * H], truth8[4 * W * H];
    double rmse;
    int i, on_reflector = 0;
    fill_color(truth, 10, 20, 30);
    fill_color(test, 10, 20, 30);
    cr_assert_eq(refl_measure_image_error(test, truth, 0, 0.0f, &ie), REFL_OK);
    cr_assert(ie.pixels == W * H && ie.rmse == 0.0 && isinf(ie.psnr) && ie.psnr > 0 && ie.max_diff == 0.0 &&
              ie.over_threshold == 0.0);
    /* green 10 levels up on 100 pixels (alpha differences are ignored) */
    for (i = 0; i < 100; ++i) {
        int p = i * 29 % (W * H);
        test->rgba[4 * p + 1] = (float)30 / 255.0f;
        test->rgba[4 * p + 3] = (float)0 / 255.0f;
        on_reflector += truth->stencil[p] != 0;
    }
    rmse = sqrt(100.0 * 100.0 / (3.0 * n)) / 255.0;
    cr_assert_eq(refl_measure_image_error(test, truth, 0, 0.0f, &ie), REFL_OK);
    cr_assert_eq(ie.pixels, W * H);
    cr_assert(fabs(ie.rmse - rmse) < 1e-15, "rmse %.17g, want %.17g", ie.rmse, rmse);
    cr_assert(fabs(ie.psnr - 20.0 * log10(1.0 / rmse)) < 1e-12, "psnr %g", ie.psnr);
    cr_assert(fabs(ie.max_diff - 10.0 / 255.0) < 1e-15);
    cr_assert(fabs(ie.over_threshold - 100.0 / n) < 1e-15);
    /* a difference equal to the threshold is not over it */
    cr_assert_eq(refl_measure_image_error(test, truth, 0, 10.0f / 255.0f, &ie), REFL_OK);
    cr_assert_eq(ie.over_threshold, 0.0);
    cr_assert_eq(refl_measure_image_error(test, truth, 0, 9.0f / 255.0f, &ie), REFL_OK);
    cr_assert(fabs(ie.over_threshold - 100.0 / n) < 1e-15);
    /* the same numbers as the tools' comparison (reflect compare) of the
       frames' 8-bit levels */
    for (i = 0; i < 4 * W * H; ++i) {
        test8[i] = (uint8_t)tu_unorm8(test->rgba[i]);
        truth8[i] = (uint8_t)tu_unorm8(truth->rgba[i]);
    }
    cr_assert_eq(refl_image_compare(test8, truth8, W, H, 2.0 / 255.0, &cmp), REFL_OK);
    cr_assert(fabs(cmp.rmse - rmse) < 1e-15 && cmp.psnr == 20.0 * log10(1.0 / cmp.rmse) &&
              cmp.fraction_over == 100.0 / n);
    /* over the truth's reflector pixels only */
    cr_assert(on_reflector > 10 && on_reflector < 100, "%d", on_reflector);
    cr_assert_eq(refl_measure_image_error(test, truth, 1, 0.0f, &ie), REFL_OK);
    cr_assert_eq(ie.pixels, REFLECTOR_PIXELS);
    rmse = sqrt(100.0 * on_reflector / (3.0 * (double)REFLECTOR_PIXELS)) / 255.0;
    cr_assert(fabs(ie.rmse - rmse) < 1e-15);
    cr_assert(fabs(ie.over_threshold - on_reflector / (double)REFLECTOR_PIXELS) < 1e-15);
    /* a pixel 255 off in every channel */
    test->rgba[0] = (float)255 / 255.0f; test->rgba[1] = (float)255 / 255.0f; test->rgba[2] = (float)0 / 255.0f;
    truth->rgba[0] = (float)0 / 255.0f; truth->rgba[1] = (float)0 / 255.0f; truth->rgba[2] = (float)255 / 255.0f;
    cr_assert_eq(refl_measure_image_error(test, truth, 0, 0.5f, &ie), REFL_OK);
    cr_assert_eq(ie.max_diff, 1.0);
    cr_assert(fabs(ie.over_threshold - 1.0 / n) < 1e-15);
    refl_frame_destroy(test);
    refl_frame_destroy(truth);
}

/* ---- against the ray-traced reference ---- */

static refl_frame *render_default(const refl_scene *s, refl_method method) {
    refl_frame *f = NULL;
    refl_view v = s->camera;
    refl_render_desc d;
    refl_result r;
    v.width = 160;
    v.height = 120;
    memset(&d, 0, sizeof d);
    d.method = method;
    d.threads = 2;
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &f), REFL_OK);
    r = refl_render(s, &v, &d, f);
    cr_assert_eq(r, REFL_OK, "render with %s: %s", refl_method_name(method), refl_result_string(r));
    return f;
}

/* RAYTRACE against itself is exact; shifted 3 pixels across, every point
   still found on its own reflector lands 3 pixels from where it is. */
Test(refl_metrics, raytrace_against_itself, .timeout = 120) {
    refl_scene *s = NULL;
    refl_frame *a, *b, *moved;
    refl_reflection_error e;
    refl_image_error ie;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    a = render_default(s, REFL_RAYTRACE);
    b = render_default(s, REFL_RAYTRACE);
    cr_assert_eq(refl_measure_reflection_error(b, a, NULL, &e), REFL_OK);
    cr_assert(e.pixels > 500, "only %lld reflector pixels show a point", e.pixels);
    cr_assert_eq(e.matched, e.pixels);
    cr_assert(e.mean == 0.0 && e.p95 == 0.0 && e.max == 0.0 && e.wrong == 0.0 && e.empty == 0.0);
    cr_assert_eq(refl_measure_image_error(b, a, 0, 0.0f, &ie), REFL_OK);
    cr_assert(ie.rmse == 0.0 && isinf(ie.psnr));

    moved = shifted(a, 3, 0);
    cr_assert_eq(refl_measure_reflection_error(moved, a, NULL, &e), REFL_OK);
    cr_assert(e.matched > 400, "%lld matched", e.matched);
    /* at 160x120 the teapot shrinks the scenery to a few pixels, where a
       point shows more than once within 3 pixels (the handle, the spout,
       the silhouettes): those pixels measure the nearer image */
    cr_assert(e.mean > 2.5 && e.mean <= 3.0, "mean %.12g", e.mean);
    cr_assert_eq(e.max, 3.0);
    cr_assert_eq(e.wrong, 0.0);
    cr_assert(e.empty > 0.0);
    refl_frame_destroy(moved);
    refl_frame_destroy(b);
    refl_frame_destroy(a);
    refl_scene_destroy(s);
}

/* A w x 1 frame of one grey level per pixel (levels[i] / 255), reflector
   pixels where stencil[i]. */
static refl_frame *grey_frame(int w, const int *levels, const uint8_t *stencil) {
    refl_frame *f;
    int i, c;
    cr_assert_eq(refl_frame_create(w, 1, NULL, &f), REFL_OK);
    for (i = 0; i < w; ++i) {
        for (c = 0; c < 3; ++c) f->rgba[4 * i + c] = (float)levels[i] / 255.0f;
        f->rgba[4 * i + 3] = 1.0f;
        f->stencil[i] = stencil[i];
    }
    return f;
}

/* Known answers: a method that changes as the truth does flickers 0; one
   pixel of two jumping 10 levels where the truth moves 4 is an excess of 6
   there (mean 3, p95 6); pixels outside the truth's reflectors, in either
   frame, do not count. */
Test(refl_metrics, flicker_known_answers) {
    static const uint8_t stencil[4] = {1, 1, 1, 0}, stencil_prev[4] = {1, 1, 0, 0};
    static const int zero[4] = {0, 0, 0, 0}, truth_now[4] = {4, 0, 0, 0}, test_now[4] = {10, 0, 200, 90};
    refl_frame *truth_prev = grey_frame(4, zero, stencil_prev), *truth = grey_frame(4, truth_now, stencil);
    refl_frame *test_prev = grey_frame(4, zero, stencil_prev), *test = grey_frame(4, test_now, stencil);
    refl_flicker fl;
    cr_assert_eq(refl_measure_flicker(truth_prev, truth, truth_prev, truth, &fl), REFL_OK);
    cr_assert(fl.pixels == 2 && fl.mean == 0.0 && fl.p95 == 0.0 && fl.test_change == 2.0 && fl.truth_change == 2.0);
    cr_assert_eq(refl_measure_flicker(test_prev, test, truth_prev, truth, &fl), REFL_OK);
    cr_assert_eq(fl.pixels, 2, "pixel 2 is no reflector in the previous truth, pixel 3 in neither");
    cr_assert(fl.mean == 3.0 && fl.p95 == 6.0, "mean %g p95 %g", fl.mean, fl.p95);
    cr_assert(fl.test_change == 5.0 && fl.truth_change == 2.0);
    cr_assert_eq(refl_measure_flicker(test_prev, test, truth_prev, NULL, &fl), REFL_ERROR_INVALID_ARGUMENT);
    refl_frame_destroy(truth_prev);
    refl_frame_destroy(truth);
    refl_frame_destroy(test_prev);
    refl_frame_destroy(test);
}
