/* reflect.h math: vectors, a ray against a box, GL matrices, quaternions,
   the robust quadratic and cubic solvers, least squares and the random
   numbers. Expected values are worked out by hand (or, for the
   near-degenerate roots, to 25 digits with mpmath from the exact double
   coefficients; quoted in comments). */
#include <criterion/criterion.h>

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "../../reflect.h"

#define PI 3.14159265358979323846

/* |got - want| <= tol * max(1, |want|) style checks, with a message */
#define NEAR_REL(got, want, rel)                                                                        \
    cr_assert(fabs((double)(got) - (double)(want)) <= (rel) * fabs((double)(want)),                     \
              "%s = %.17g, want %.17g (rel %g)", #got, (double)(got), (double)(want), (double)(rel))
#define NEAR_ABS(got, want, tol)                                                                        \
    cr_assert(fabs((double)(got) - (double)(want)) <= (tol), "%s = %.17g, want %.17g (abs %g)", #got,   \
              (double)(got), (double)(want), (double)(tol))

/* Test-local generator (splitmix64), independent of refl_rng. */
static uint64_t sm_state;
static uint64_t sm_next(void) {
    uint64_t z = (sm_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static double sm_uniform(double lo, double hi) { return lo + (hi - lo) * ((double)(sm_next() >> 11) * 0x1.0p-53); }

/* ---- quadratic ---------------------------------------------------------- */

Test(refl_math, quadratic_known_answers) {
    double r[2] = {0, 0};
    cr_assert_eq(refl_solve_quadratic(1, -3, 2, r), 2);
    cr_assert(r[0] == 1.0 && r[1] == 2.0, "%g %g", r[0], r[1]);
    cr_assert_eq(refl_solve_quadratic(2, 0, -8, r), 2); /* b = 0 */
    cr_assert(r[0] == -2.0 && r[1] == 2.0, "%g %g", r[0], r[1]);
    cr_assert_eq(refl_solve_quadratic(1, 0, -2, r), 2);
    NEAR_REL(r[0], -sqrt(2.0), 2.3e-16);
    NEAR_REL(r[1], sqrt(2.0), 2.3e-16);
    cr_assert_eq(refl_solve_quadratic(1, 0, 4, r), 0); /* complex */
    cr_assert_eq(refl_solve_quadratic(1, 5, 0, r), 2); /* c = 0 */
    cr_assert(r[0] == -5.0 && r[1] == 0.0, "%g %g", r[0], r[1]);
    cr_assert_eq(refl_solve_quadratic(3, 0, 0, r), 2); /* double root at 0 */
    cr_assert(r[0] == 0.0 && r[1] == 0.0);
    cr_assert_eq(refl_solve_quadratic(1, -2, 1, r), 2); /* double root, reported twice */
    cr_assert(r[0] == 1.0 && r[1] == 1.0, "%g %g", r[0], r[1]);
    cr_assert_eq(refl_solve_quadratic(4, 4, 1, r), 2);
    cr_assert(r[0] == -0.5 && r[1] == -0.5, "%g %g", r[0], r[1]);
    cr_assert_eq(refl_solve_quadratic(-1, 3, -2, r), 2); /* negative a */
    cr_assert(r[0] == 1.0 && r[1] == 2.0, "%g %g", r[0], r[1]);
}

Test(refl_math, quadratic_lower_degree) {
    double r[2] = {0, 0};
    cr_assert_eq(refl_solve_quadratic(0, 0, 0, r), -1);
    cr_assert_eq(refl_solve_quadratic(0, 0, 1, r), 0);
    cr_assert_eq(refl_solve_quadratic(0, 2, 1, r), 1);
    cr_assert_eq(r[0], -0.5);
    cr_assert_eq(refl_solve_quadratic(0, 2, 0, r), 1);
    cr_assert_eq(r[0], 0.0);
    /* non-finite coefficients: no roots, no crash */
    cr_assert_eq(refl_solve_quadratic(NAN, 1, 1, r), 0);
    cr_assert_eq(refl_solve_quadratic(1, INFINITY, 1, r), 0);
}

/* a -> 0: the near root stays accurate (the textbook formula loses half the
   digits here); the far root is returned while it is representable. */
Test(refl_math, quadratic_vanishing_leading_coefficient) {
    double r[2] = {0, 0};
    /* 1e-12 x^2 + x + 1: -999999999999.0000201133514, -1.000000000001000000000002 */
    cr_assert_eq(refl_solve_quadratic(1e-12, 1, 1, r), 2);
    NEAR_REL(r[0], -999999999999.0000201133514, 1e-15);
    NEAR_REL(r[1], -1.000000000001, 1e-15);
    /* a = 1e-300: roots -1 (to 1e-300) and -1e300 */
    cr_assert_eq(refl_solve_quadratic(1e-300, 1, 1, r), 2);
    NEAR_REL(r[0], -1e300, 1e-15);
    NEAR_REL(r[1], -1.0, 1e-16);
    /* subnormal a: the far root -1e320 overflows and is dropped */
    cr_assert_eq(refl_solve_quadratic(1e-320, 1, -2, r), 1);
    NEAR_REL(r[0], 2.0, 1e-16);
    /* tiny a and c against b: -c/b and -b/a, both far outside each other */
    cr_assert_eq(refl_solve_quadratic(1, -1e200, 1, r), 2);
    NEAR_REL(r[0], 1e-200, 1e-15);
    NEAR_REL(r[1], 1e200, 1e-15);
}

Test(refl_math, quadratic_huge_and_tiny_coefficients) {
    double r[2] = {0, 0};
    /* (x - 1)(x - 2) times 1e150 and 1e-150: b*b would overflow/underflow */
    cr_assert_eq(refl_solve_quadratic(1e150, -3e150, 2e150, r), 2);
    NEAR_REL(r[0], 1.0, 1e-15);
    NEAR_REL(r[1], 2.0, 1e-15);
    cr_assert_eq(refl_solve_quadratic(1e-150, -3e-150, 2e-150, r), 2);
    NEAR_REL(r[0], 1.0, 1e-15);
    NEAR_REL(r[1], 2.0, 1e-15);
    /* roots 1e150 and 2e150: c = 2e300 */
    cr_assert_eq(refl_solve_quadratic(1, -3e150, 2e300, r), 2);
    NEAR_REL(r[0], 1e150, 1e-15);
    NEAR_REL(r[1], 2e150, 1e-15);
    /* roots 1e-150 and 2e-150: c = 2e-300 */
    cr_assert_eq(refl_solve_quadratic(1, -3e-150, 2e-300, r), 2);
    NEAR_REL(r[0], 1e-150, 1e-15);
    NEAR_REL(r[1], 2e-150, 1e-15);
    /* 1e-200 x^2 + x - 1e200: roots (-1 +- sqrt 5) / 2 * 1e200 */
    cr_assert_eq(refl_solve_quadratic(1e-200, 1, -1e200, r), 2);
    NEAR_REL(r[0], -1.6180339887498949e200, 1e-15);
    NEAR_REL(r[1], 0.6180339887498949e200, 1e-15);
}

Test(refl_math, quadratic_close_and_double_roots) {
    double r[2] = {0, 0}, e = ldexp(1.0, -27);
    static const double v[] = {0.1, 0.3, 1.0 / 3.0, 0.7, 1.1, 12.345, 1e-5, 1e5, -2.2};
    int i;
    /* (x - 1)(x - 1 - 2^-27): exact coefficients, exactly separable roots;
       b^2 needs 56 bits, the exact discriminant gets them */
    cr_assert_eq(refl_solve_quadratic(1, -(2 + e), 1 + e, r), 2);
    cr_assert(r[0] == 1.0 && r[1] == 1.0 + e, "%.17g %.17g", r[0], r[1]);
    /* (x - 1)(x - 1 - 1e-8) with rounded coefficients: a coefficient error
       of 1 ulp moves these roots by up to 2e-8, so that is the bar */
    cr_assert_eq(refl_solve_quadratic(1, -(2 + 1e-8), 1 + 1e-8, r), 2);
    NEAR_ABS(r[0], 1.0, 3e-8);
    NEAR_ABS(r[1], 1.0 + 1e-8, 3e-8);
    cr_assert(r[0] <= r[1]);
    /* (x - v)^2 with rounded coefficients: a discriminant a little below 0
       from rounding is still a double root, never "no roots" */
    for (i = 0; i < (int)(sizeof v / sizeof v[0]); ++i) {
        int n = refl_solve_quadratic(1.0, -2.0 * v[i], v[i] * v[i], r);
        cr_assert_eq(n, 2, "(x - %g)^2: %d roots", v[i], n);
        NEAR_REL(r[0], v[i], 1e-7);
        NEAR_REL(r[1], v[i], 1e-7);
    }
}

/* Random quadratics from known, well separated roots of random magnitude:
   root error and residual. */
Test(refl_math, quadratic_random_known_roots) {
    double r[2];
    int it;
    sm_state = 12345;
    for (it = 0; it < 20000; ++it) {
        double scale = ldexp(1.0, (int)sm_uniform(-300, 300));
        double x1 = sm_uniform(-1, 1) * scale, x2 = sm_uniform(-1, 1) * scale * ldexp(1.0, (int)sm_uniform(-20, 20));
        double a = sm_uniform(0.5, 2) * ldexp(1.0, (int)sm_uniform(-200, 200)), lo, hi, big;
        int n;
        if (fabs(x1 - x2) < 0.1 * fmax(fabs(x1), fabs(x2))) continue;
        lo = x1 < x2 ? x1 : x2;
        hi = x1 < x2 ? x2 : x1;
        big = fabs(lo) > fabs(hi) ? fabs(lo) : fabs(hi);
        n = refl_solve_quadratic(a, -a * (x1 + x2), a * x1 * x2, r);
        cr_assert_eq(n, 2, "roots %g %g: %d", x1, x2, n);
        /* the coefficients carry rounding; each root is good to a few ulp
           of the larger (and the small one to a few ulp of itself) */
        cr_assert(fabs(r[0] - lo) <= 1e-14 * big && fabs(r[1] - hi) <= 1e-14 * big, "roots %.17g %.17g: %.17g %.17g",
                  lo, hi, r[0], r[1]);
        cr_assert(fabs(r[0] - lo) <= 1e-13 * fabs(lo) && fabs(r[1] - hi) <= 1e-13 * fabs(hi),
                  "roots %.17g %.17g: %.17g %.17g", lo, hi, r[0], r[1]);
    }
}

/* ---- cubic ---------------------------------------------------------------- */

static double cubic_residual(double a, double b, double c, double d, double x) {
    double v = ((a * x + b) * x + c) * x + d;
    double s = fabs(a * x * x * x) + fabs(b * x * x) + fabs(c * x) + fabs(d);
    return s > 0 ? fabs(v) / s : fabs(v);
}

Test(refl_math, cubic_known_answers) {
    double r[3] = {0, 0, 0};
    cr_assert_eq(refl_solve_cubic(1, -6, 11, -6, r), 3); /* 1 2 3 */
    NEAR_REL(r[0], 1.0, 1e-15);
    NEAR_REL(r[1], 2.0, 1e-15);
    NEAR_REL(r[2], 3.0, 1e-15);
    cr_assert_eq(refl_solve_cubic(2, 0, 0, -16, r), 1); /* 2 x^3 = 16 */
    NEAR_REL(r[0], 2.0, 1e-15);
    cr_assert_eq(refl_solve_cubic(1, 0, 1, 0, r), 1); /* x (x^2 + 1) */
    cr_assert_eq(r[0], 0.0);
    cr_assert_eq(refl_solve_cubic(1, -1, 0, 0, r), 3); /* x^2 (x - 1) */
    cr_assert(r[0] == 0.0 && r[1] == 0.0 && r[2] == 1.0, "%g %g %g", r[0], r[1], r[2]);
    cr_assert_eq(refl_solve_cubic(1, 0, 0, 0, r), 3); /* x^3 */
    cr_assert(r[0] == 0.0 && r[1] == 0.0 && r[2] == 0.0);
    cr_assert_eq(refl_solve_cubic(-1, 0, 7, -6, r), 3); /* -(x - 1)(x - 2)(x + 3) */
    NEAR_REL(r[0], -3.0, 1e-15);
    NEAR_REL(r[1], 1.0, 1e-15);
    NEAR_REL(r[2], 2.0, 1e-15);
    /* one real root and a complex pair: (x - 2)(x^2 + x + 1) */
    cr_assert_eq(refl_solve_cubic(1, -1, -1, -2, r), 1);
    NEAR_REL(r[0], 2.0, 1e-15);
    /* lower degree */
    cr_assert_eq(refl_solve_cubic(0, 1, -3, 2, r), 2);
    cr_assert(r[0] == 1.0 && r[1] == 2.0);
    cr_assert_eq(refl_solve_cubic(0, 0, 2, 1, r), 1);
    cr_assert_eq(r[0], -0.5);
    cr_assert_eq(refl_solve_cubic(0, 0, 0, 0, r), -1);
    cr_assert_eq(refl_solve_cubic(0, 0, 0, 3, r), 0);
    cr_assert_eq(refl_solve_cubic(NAN, 0, 0, 3, r), 0);
}

Test(refl_math, cubic_double_and_triple_roots) {
    double r[3] = {0, 0, 0};
    static const double v[] = {0.1, 0.3, 0.7, 1.1, 12.345, -2.2, 1e-4, 1e4};
    int i, n;
    /* exact coefficients: exact roots */
    cr_assert_eq(refl_solve_cubic(1, -3, 3, -1, r), 3); /* (x - 1)^3 */
    cr_assert(r[0] == 1.0 && r[1] == 1.0 && r[2] == 1.0, "%.17g %.17g %.17g", r[0], r[1], r[2]);
    cr_assert_eq(refl_solve_cubic(1, -6, 12, -8, r), 3); /* (x - 2)^3 */
    cr_assert(r[0] == 2.0 && r[1] == 2.0 && r[2] == 2.0, "%.17g %.17g %.17g", r[0], r[1], r[2]);
    cr_assert_eq(refl_solve_cubic(1, -5, 7, -3, r), 3); /* (x - 1)^2 (x - 3) */
    cr_assert(r[0] == 1.0 && r[1] == 1.0 && r[2] == 3.0, "%.17g %.17g %.17g", r[0], r[1], r[2]);
    cr_assert_eq(refl_solve_cubic(1, 0, -3, 2, r), 3); /* (x - 1)^2 (x + 2) */
    cr_assert(r[0] == -2.0 && r[1] == 1.0 && r[2] == 1.0, "%.17g %.17g %.17g", r[0], r[1], r[2]);
    /* rounded coefficients: a double root stays a (near) double root and
       the simple root stays accurate */
    for (i = 0; i < (int)(sizeof v / sizeof v[0]); ++i) {
        double s = 3.0 * v[i] + 1.0; /* (x - v)^2 (x - s) */
        n = refl_solve_cubic(1, -(2 * v[i] + s), v[i] * v[i] + 2 * v[i] * s, -v[i] * v[i] * s, r);
        cr_assert_eq(n, 3, "(x - %g)^2 (x - %g): %d roots", v[i], s, n);
        {
            double lo[3], want[3];
            want[0] = v[i] < s ? v[i] : s;
            want[1] = v[i];
            want[2] = v[i] < s ? s : v[i];
            memcpy(lo, r, sizeof lo);
            NEAR_ABS(lo[0], want[0], 1e-7 * fabs(s));
            NEAR_ABS(lo[1], want[1], 1e-7 * fabs(s));
            NEAR_ABS(lo[2], want[2], 1e-7 * fabs(s));
        }
        /* triple root with rounded coefficients: may split into a complex
           pair; every real root within eps^(1/3) of v */
        n = refl_solve_cubic(1, -3 * v[i], 3 * v[i] * v[i], -v[i] * v[i] * v[i], r);
        cr_assert(n == 1 || n == 3, "(x - %g)^3: %d roots", v[i], n);
        while (n-- > 0) NEAR_REL(r[n], v[i], 2e-5);
    }
}

Test(refl_math, cubic_vanishing_leading_coefficient) {
    double r[3] = {0, 0, 0};
    /* 1e-12 x^3 + x^2 - 3x + 2 (mpmath, from the double coefficients):
       -1000000000003.000020113345, 1.000000000001000000000004,
       1.999999999992000000000032 */
    cr_assert_eq(refl_solve_cubic(1e-12, 1, -3, 2, r), 3);
    NEAR_REL(r[0], -1000000000003.000020113345, 1e-15);
    NEAR_REL(r[1], 1.000000000001, 1e-15);
    NEAR_REL(r[2], 1.999999999992, 1e-15);
    /* a = 1e-100 and 1e-300: near roots 1, 2 (to 1e-100), far -b/a */
    cr_assert_eq(refl_solve_cubic(1e-100, 1, -3, 2, r), 3);
    NEAR_REL(r[0], -1e100, 1e-15);
    NEAR_REL(r[1], 1.0, 1e-15);
    NEAR_REL(r[2], 2.0, 1e-15);
    cr_assert_eq(refl_solve_cubic(1e-300, 1, -3, 2, r), 3);
    NEAR_REL(r[0], -1e300, 1e-15);
    NEAR_REL(r[1], 1.0, 1e-15);
    NEAR_REL(r[2], 2.0, 1e-15);
    /* far roots +-sqrt(1/a) when b = 0: 1e-300 x^3 - x + 0.5 */
    cr_assert_eq(refl_solve_cubic(1e-300, 0, -1, 0.5, r), 3);
    NEAR_REL(r[0], -1e150, 1e-15);
    NEAR_REL(r[1], 0.5, 1e-15);
    NEAR_REL(r[2], 1e150, 1e-15);
    /* subnormal a: the far root overflows and is dropped */
    cr_assert_eq(refl_solve_cubic(1e-320, 1, -3, 2, r), 2);
    NEAR_REL(r[0], 1.0, 1e-15);
    NEAR_REL(r[1], 2.0, 1e-15);
}

Test(refl_math, cubic_huge_and_tiny_magnitudes) {
    double r[3] = {0, 0, 0};
    /* (x - 1)(x - 2)(x - 3) times 1e150 and 1e-150; the coefficients are
       rounded, and root 2 has condition ~1e1 there */
    cr_assert_eq(refl_solve_cubic(1e150, -6e150, 11e150, -6e150, r), 3);
    NEAR_REL(r[0], 1.0, 1e-14);
    NEAR_REL(r[1], 2.0, 1e-14);
    NEAR_REL(r[2], 3.0, 1e-14);
    cr_assert_eq(refl_solve_cubic(1e-150, -6e-150, 11e-150, -6e-150, r), 3);
    NEAR_REL(r[0], 1.0, 1e-14);
    NEAR_REL(r[1], 2.0, 1e-14);
    NEAR_REL(r[2], 3.0, 1e-14);
    /* roots 1e100, 2e100, 3e100: d = -6e300 */
    cr_assert_eq(refl_solve_cubic(1, -6e100, 11e200, -6e300, r), 3);
    NEAR_REL(r[0], 1e100, 1e-14);
    NEAR_REL(r[1], 2e100, 1e-14);
    NEAR_REL(r[2], 3e100, 1e-14);
    /* roots 1e-100, 2e-100, 3e-100 */
    cr_assert_eq(refl_solve_cubic(1, -6e-100, 11e-200, -6e-300, r), 3);
    NEAR_REL(r[0], 1e-100, 1e-14);
    NEAR_REL(r[1], 2e-100, 1e-14);
    NEAR_REL(r[2], 3e-100, 1e-14);
    /* roots spread over 600 decades: 1e-300, 1, 1e300 (approximately:
       x^3 - 1e300 x^2 + 1e300 x - 1) */
    cr_assert_eq(refl_solve_cubic(1, -1e300, 1e300, -1, r), 3);
    NEAR_REL(r[0], 1e-300, 1e-15);
    NEAR_REL(r[1], 1.0, 1e-15);
    NEAR_REL(r[2], 1e300, 1e-15);
}

/* Random cubics from known roots (three real, or one real and a complex
   pair): root error against the separation, and residual. */
Test(refl_math, cubic_random_known_roots) {
    double r[3];
    int it, checked = 0;
    sm_state = 777;
    for (it = 0; it < 20000; ++it) {
        double scale = ldexp(1.0, (int)sm_uniform(-100, 100));
        double a = sm_uniform(0.5, 2) * ldexp(1.0, (int)sm_uniform(-100, 100));
        double x[3], t, big = 0, sep = DBL_MAX, b, c, d;
        int i, j, n;
        for (i = 0; i < 3; ++i) x[i] = sm_uniform(-1, 1) * scale;
        for (i = 0; i < 3; ++i)
            for (j = i + 1; j < 3; ++j)
                if (x[j] < x[i]) { t = x[i]; x[i] = x[j]; x[j] = t; }
        for (i = 0; i < 3; ++i) big = fabs(x[i]) > big ? fabs(x[i]) : big;
        for (i = 0; i < 2; ++i) sep = x[i + 1] - x[i] < sep ? x[i + 1] - x[i] : sep;
        if (sep < 0.05 * big) continue;
        b = -a * (x[0] + x[1] + x[2]);
        c = a * (x[0] * x[1] + x[0] * x[2] + x[1] * x[2]);
        d = -a * x[0] * x[1] * x[2];
        n = refl_solve_cubic(a, b, c, d, r);
        cr_assert_eq(n, 3, "roots %g %g %g: %d", x[0], x[1], x[2], n);
        for (i = 0; i < 3; ++i) {
            cr_assert(fabs(r[i] - x[i]) <= 1e-12 * big, "roots %.17g %.17g %.17g: root %d = %.17g", x[0], x[1], x[2], i,
                      r[i]);
            cr_assert(cubic_residual(a, b, c, d, r[i]) <= 1e-13, "residual %g", cubic_residual(a, b, c, d, r[i]));
        }
        ++checked;
    }
    cr_assert_gt(checked, 5000);
    sm_state = 778;
    for (it = 0; it < 5000; ++it) { /* (x - x0)(x^2 + p x + q), p^2 < 4q */
        double x0 = sm_uniform(-10, 10), re = sm_uniform(-10, 10), im = sm_uniform(0.5, 10);
        double p = -2 * re, q = re * re + im * im;
        int n = refl_solve_cubic(1, p - x0, q - x0 * p, -x0 * q, r);
        cr_assert_eq(n, 1, "x0 %g, %g +- %gi: %d roots", x0, re, im, n);
        NEAR_ABS(r[0], x0, 1e-12 * (fabs(x0) + fabs(re) + im));
    }
}

/* ---- least squares ------------------------------------------------------------ */

Test(refl_math, least_squares_exact_recovery) {
    enum { R = 12, C = 5 };
    double A[R * C], b[R], x[C], want[C], cond = 0;
    int i, j, trial;
    sm_state = 99;
    for (trial = 0; trial < 50; ++trial) {
        int rows = trial % 2 ? R : C; /* overdetermined consistent, and square */
        for (j = 0; j < C; ++j) want[j] = sm_uniform(-10, 10);
        for (i = 0; i < rows; ++i) {
            b[i] = 0;
            for (j = 0; j < C; ++j) {
                A[i * C + j] = sm_uniform(-1, 1);
                b[i] += A[i * C + j] * want[j];
            }
        }
        cr_assert_eq(refl_least_squares(A, b, rows, C, x, &cond), REFL_OK);
        cr_assert(cond >= 1.0 && cond < 1e6, "cond %g", cond);
        for (j = 0; j < C; ++j) NEAR_ABS(x[j], want[j], 1e-10 * (1 + cond));
    }
}

Test(refl_math, least_squares_line_fit) {
    /* y = m x + c through (0,1) (1,2) (2,2) (3,4): normal equations
       [14 6; 6 4] [m c] = [18 9] give m = 0.9, c = 0.9 */
    const double A[8] = {0, 1, 1, 1, 2, 1, 3, 1}, b[4] = {1, 2, 2, 4};
    double x[2] = {0, 0};
    cr_assert_eq(refl_least_squares(A, b, 4, 2, x, NULL), REFL_OK);
    NEAR_ABS(x[0], 0.9, 1e-14);
    NEAR_ABS(x[1], 0.9, 1e-14);
}

/* Columns of wildly different scale are not ill-conditioned once
   equilibrated: x is recovered and the estimate stays small. */
Test(refl_math, least_squares_column_scaling) {
    const double A[6] = {1e10, 1e-10, 2e10, 3e-10, 3e10, -1e-10};
    double b[3], x[2] = {0, 0}, cond = 0;
    int i;
    for (i = 0; i < 3; ++i) b[i] = A[2 * i] * 2e-10 + A[2 * i + 1] * -5e10;
    cr_assert_eq(refl_least_squares(A, b, 3, 2, x, &cond), REFL_OK);
    NEAR_REL(x[0], 2e-10, 1e-13);
    NEAR_REL(x[1], -5e10, 1e-13);
    cr_assert(cond < 10, "cond %g", cond);
}

Test(refl_math, least_squares_singular) {
    /* second column twice the first; a zero column; a near-dependent one */
    const double dup[8] = {1, 2, 2, 4, 3, 6, 4, 8};
    const double zero[8] = {1, 0, 2, 0, 3, 0, 4, 0};
    double near[8], b[4] = {1, 2, 3, 5}, x[2] = {42, 42}, cond = 0;
    int i;
    cr_assert_eq(refl_least_squares(dup, b, 4, 2, x, &cond), REFL_ERROR_SINGULAR);
    cr_assert(cond > 1e12, "cond %g", cond);
    cr_assert(x[0] == 42 && x[1] == 42, "x touched");
    cr_assert_eq(refl_least_squares(zero, b, 4, 2, x, &cond), REFL_ERROR_SINGULAR);
    cr_assert(x[0] == 42 && x[1] == 42, "x touched");
    for (i = 0; i < 4; ++i) {
        near[2 * i] = i + 1;
        near[2 * i + 1] = (i + 1) * (1 + 1e-15 * (i == 2));
    }
    cr_assert_eq(refl_least_squares(near, b, 4, 2, x, &cond), REFL_ERROR_SINGULAR);
    /* moderately ill-conditioned is fine, and the estimate says so:
       [1 1; 1 1 + 1e-6] has 2-norm condition ~4e6 */
    {
        const double A[4] = {1, 1, 1, 1 + 1e-6}, bb[2] = {2, 2 + 1e-6};
        cr_assert_eq(refl_least_squares(A, bb, 2, 2, x, &cond), REFL_OK);
        cr_assert(cond > 1e5 && cond < 1e8, "cond %g", cond);
        NEAR_ABS(x[0], 1.0, 1e-8);
        NEAR_ABS(x[1], 1.0, 1e-8);
    }
}

Test(refl_math, least_squares_invalid_arguments) {
    double A[33 * 33] = {0}, b[33] = {0}, x[33];
    cr_assert_eq(refl_least_squares(NULL, b, 2, 2, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_least_squares(A, NULL, 2, 2, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_least_squares(A, b, 2, 2, NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_least_squares(A, b, 1, 2, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_least_squares(A, b, 2, 0, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_least_squares(A, b, 33, 33, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_least_squares(A, b, -1, 2, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
    A[0] = NAN;
    cr_assert_eq(refl_least_squares(A, b, 2, 1, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
}

/* A tall system (thousands of rows) at the 32-column limit. */
Test(refl_math, least_squares_tall) {
    enum { R = 3000, C = 32 };
    static double A[R * C], b[R];
    double x[C], want[C], cond = 0;
    int i, j;
    sm_state = 5;
    for (j = 0; j < C; ++j) want[j] = sm_uniform(-1, 1);
    for (i = 0; i < R; ++i) {
        b[i] = 0;
        for (j = 0; j < C; ++j) {
            A[i * C + j] = sm_uniform(-1, 1);
            b[i] += A[i * C + j] * want[j];
        }
    }
    cr_assert_eq(refl_least_squares(A, b, R, C, x, &cond), REFL_OK);
    for (j = 0; j < C; ++j) NEAR_ABS(x[j], want[j], 1e-12);
}

/* ---- vectors ------------------------------------------------------------------- */

Test(refl_math, vectors) {
    refl_vec3 a = refl_v3(1, 2, 3), b = refl_v3(-2, 0, 5), c, out = refl_v3(7, 7, 7);
    c = refl_v3_cross(a, b);
    cr_assert(c.x == 10 && c.y == -11 && c.z == 4);
    cr_assert_eq(refl_v3_dot(a, b), 13.0f);
    cr_assert_eq(refl_v3_length(refl_v3(3, 4, 12)), 13.0f);
    c = refl_v3_normalize(refl_v3(0, 0, 0));
    cr_assert(c.x == 0 && c.y == 0 && c.z == 0);
    c = refl_v3_normalize(refl_v3(0, 3, 4));
    cr_assert(c.x == 0 && fabsf(c.y - 0.6f) < 1e-7f && fabsf(c.z - 0.8f) < 1e-7f);
    c = refl_v3_normalize(refl_v3(1e30f, 0, 0)); /* no overflow */
    cr_assert_eq(c.x, 1.0f);
    /* reflect: mirror about the normal */
    c = refl_v3_reflect(refl_v3(1, -1, 0), refl_v3(0, 1, 0));
    cr_assert(c.x == 1 && c.y == 1 && c.z == 0);
    /* refract (GLSL): normal incidence passes straight */
    cr_assert_eq(refl_v3_refract(refl_v3(0, -1, 0), refl_v3(0, 1, 0), 1.0f / 1.5f, &out), 1);
    cr_assert(fabsf(out.x) < 1e-7f && fabsf(out.y + 1) < 1e-7f);
    /* 45 degrees into glass: Snell, sin t = sin 45 / 1.5 */
    {
        float s = (float)sqrt(0.5);
        cr_assert_eq(refl_v3_refract(refl_v3(s, -s, 0), refl_v3(0, 1, 0), 1.0f / 1.5f, &out), 1);
        NEAR_ABS(out.x, sqrt(0.5) / 1.5, 1e-6);
        NEAR_ABS(out.y, -sqrt(1 - 0.5 / 2.25), 1e-6);
        NEAR_ABS(refl_v3_length(out), 1.0, 1e-6);
        /* 60 degrees out of glass: total internal reflection, out unchanged */
        out = refl_v3(7, 7, 7);
        cr_assert_eq(refl_v3_refract(refl_v3((float)sin(PI / 3), (float)-cos(PI / 3), 0), refl_v3(0, 1, 0), 1.5f, &out),
                     0);
        cr_assert(out.x == 7 && out.y == 7 && out.z == 7);
    }
}

/* ---- rays and boxes ------------------------------------------------------------- */

/* refl_ray_box(o, d, [lo, hi]) gives hit with span [t_in, t_out], exactly
   (every answer below is a quotient of small binary fractions, or one the
   test computes with the same single division). */
static void ray_box_is(const char *what, refl_vec3 o, refl_vec3 d, refl_vec3 lo, refl_vec3 hi, int hit, float t_in,
                       float t_out) {
    float got_in = -7.0f, got_out = -7.0f;
    int got = refl_ray_box(o, d, lo, hi, &got_in, &got_out);
    cr_assert(got == hit && got_in == t_in && got_out == t_out, "%s: %d [%.9g, %.9g], want %d [%.9g, %.9g]", what,
              got, got_in, got_out, hit, t_in, t_out);
}

Test(refl_math, ray_box_known_answers) {
    refl_vec3 lo = refl_v3(-1, -1, -1), hi = refl_v3(1, 1, 1), big = refl_v3(2, 4, 8), zero = refl_v3(0, 0, 0);
    float t_out = -7.0f;
    /* axis-aligned, either way along the axis; a longer d shortens t */
    ray_box_is("+x", refl_v3(-5, 0, 0), refl_v3(1, 0, 0), lo, hi, 1, 4, 6);
    ray_box_is("-x", refl_v3(5, 0, 0), refl_v3(-1, 0, 0), lo, hi, 1, 4, 6);
    ray_box_is("+x, |d| 2", refl_v3(-5, 0, 0), refl_v3(2, 0, 0), lo, hi, 1, 2, 3);
    ray_box_is("-z, box [0, (2,4,8)]", refl_v3(1, 1, 10), refl_v3(0, 0, -1), zero, big, 1, 2, 10);
    /* oblique: enters through x = -1 at t 1, leaves through y = 1 at t 2 */
    ray_box_is("oblique", refl_v3(-2, 0, 0), refl_v3(1, 0.5f, 0), lo, hi, 1, 1, 2);
    ray_box_is("diagonal", refl_v3(-3, -3, -3), refl_v3(1, 1, 1), lo, hi, 1, 2, 4);
    /* oblique miss: it leaves the y slab (t 0.5) before it enters the x slab (t 2) */
    ray_box_is("oblique miss", refl_v3(-3, 0.5f, 0), refl_v3(1, 1, 0), lo, hi, 0, 2, 0.5f);
    /* parallel to the y and z slabs: inside them, on a face (faces count),
       outside; the span is the x slab's either way */
    ray_box_is("parallel inside", refl_v3(-5, 0.5f, -0.5f), refl_v3(1, 0, 0), lo, hi, 1, 4, 6);
    ray_box_is("parallel on a face", refl_v3(-5, 1, 0), refl_v3(1, 0, 0), lo, hi, 1, 4, 6);
    ray_box_is("parallel outside", refl_v3(-5, 2, 0), refl_v3(1, 0, 0), lo, hi, 0, 4, 6);
    ray_box_is("parallel, -0", refl_v3(-5, 0, 0), refl_v3(1, -0.0f, 0), lo, hi, 1, 4, 6);
    /* origin inside: from t 0 to where it leaves */
    ray_box_is("inside", refl_v3(0.5f, 0, 0), refl_v3(1, 0, 0), lo, hi, 1, 0, 0.5f);
    ray_box_is("inside, oblique", zero, refl_v3(0.6f, 0.8f, 0), lo, hi, 1, 0, 1.0f / 0.8f);
    ray_box_is("on the far face", refl_v3(1, 0, 0), refl_v3(1, 0, 0), lo, hi, 1, 0, 0);
    /* box behind: no hit, and t_out < 0 is where the ray left it */
    ray_box_is("behind", refl_v3(5, 0, 0), refl_v3(1, 0, 0), lo, hi, 0, 0, -4);
    ray_box_is("behind, oblique", refl_v3(3, 3, 0), refl_v3(1, 1, 0), lo, hi, 0, 0, -2);
    /* d zero: only the origin counts */
    ray_box_is("d zero, inside", zero, zero, lo, hi, 1, 0, INFINITY);
    ray_box_is("d zero, outside", refl_v3(0, 0, 3), zero, lo, hi, 0, 0, INFINITY);
    /* either output may be NULL */
    cr_assert_eq(refl_ray_box(refl_v3(0.5f, 0, 0), refl_v3(1, 0, 0), lo, hi, NULL, &t_out), 1);
    cr_assert_eq(t_out, 0.5f);
    cr_assert_eq(refl_ray_box(refl_v3(5, 0, 0), refl_v3(1, 0, 0), lo, hi, NULL, NULL), 0);
}

/* ---- matrices -------------------------------------------------------------------- */

static void mat_near(refl_mat4 a, const float *want, float tol) {
    int i;
    for (i = 0; i < 16; ++i) cr_assert(fabsf(a.m[i] - want[i]) <= tol, "m[%d] = %.9g, want %.9g", i, a.m[i], want[i]);
}

Test(refl_math, matrix_basics) {
    refl_mat4 t = refl_mat4_translate(refl_v3(1, 2, 3)), s = refl_mat4_scale(refl_v3(2, 3, 4)), m;
    refl_vec3 p;
    m = refl_mat4_mul(t, s); /* scale, then translate */
    p = refl_mat4_point(m, refl_v3(1, 1, 1));
    cr_assert(p.x == 3 && p.y == 5 && p.z == 7);
    p = refl_mat4_dir(m, refl_v3(1, 1, 1));
    cr_assert(p.x == 2 && p.y == 3 && p.z == 4);
    cr_assert(m.m[12] == 1 && m.m[13] == 2 && m.m[14] == 3); /* column-major */
    m = refl_mat4_transpose(m);
    cr_assert(m.m[3] == 1 && m.m[7] == 2 && m.m[11] == 3);
    /* glRotate: 90 degrees about z takes x to y */
    m = refl_mat4_rotate(refl_v3(0, 0, 2), (float)(PI / 2));
    p = refl_mat4_dir(m, refl_v3(1, 0, 0));
    cr_assert(fabsf(p.x) < 1e-7f && fabsf(p.y - 1) < 1e-7f && p.z == 0);
    /* about (1,1,1) by 120 degrees: x -> y -> z */
    m = refl_mat4_rotate(refl_v3(1, 1, 1), (float)(2 * PI / 3));
    p = refl_mat4_dir(m, refl_v3(1, 0, 0));
    cr_assert(fabsf(p.x) < 1e-6f && fabsf(p.y - 1) < 1e-6f && fabsf(p.z) < 1e-6f);
}

Test(refl_math, matrix_inverse_round_trip) {
    int it, i, j;
    sm_state = 4242;
    for (it = 0; it < 200; ++it) {
        refl_mat4 m = refl_mat4_mul(
            refl_mat4_translate(refl_v3((float)sm_uniform(-50, 50), (float)sm_uniform(-50, 50), (float)sm_uniform(-50, 50))),
            refl_mat4_mul(refl_mat4_rotate(refl_v3((float)sm_uniform(-1, 1), (float)sm_uniform(-1, 1), (float)sm_uniform(-1, 1)),
                                           (float)sm_uniform(-7, 7)),
                          refl_mat4_scale(refl_v3((float)sm_uniform(0.01, 10), (float)sm_uniform(0.01, 10),
                                                  (float)sm_uniform(0.01, 10)))));
        refl_mat4 inv, p;
        cr_assert_eq(refl_mat4_invert(m, &inv), 1);
        p = refl_mat4_mul(inv, m);
        for (i = 0; i < 4; ++i)
            for (j = 0; j < 4; ++j)
                cr_assert(fabsf(p.m[j * 4 + i] - (float)(i == j)) < 1e-4f, "(inv m)[%d][%d] = %g", i, j, p.m[j * 4 + i]);
    }
    {
        /* a projection inverts too, and tiny uniform scales are not "singular" */
        refl_mat4 pr = refl_mat4_perspective((float)(PI / 3), 1.5f, 0.01f, 1000.0f), inv;
        refl_vec3 q = refl_mat4_point(pr, refl_v3(1, 2, -5)), back;
        cr_assert_eq(refl_mat4_invert(pr, &inv), 1);
        back = refl_mat4_point(inv, q);
        cr_assert(fabsf(back.x - 1) < 1e-4f && fabsf(back.y - 2) < 1e-4f && fabsf(back.z + 5) < 1e-3f, "%g %g %g", back.x,
                  back.y, back.z);
        cr_assert_eq(refl_mat4_invert(refl_mat4_scale(refl_v3(1e-6f, 1e-6f, 1e-6f)), &inv), 1);
        NEAR_REL(inv.m[0], 1e6, 1e-6);
    }
}

Test(refl_math, matrix_inverse_singular) {
    refl_mat4 m = refl_mat4_scale(refl_v3(1, 0, 1)), out = refl_mat4_translate(refl_v3(9, 9, 9)), keep = out;
    cr_assert_eq(refl_mat4_invert(m, &out), 0);
    cr_assert(memcmp(&out, &keep, sizeof out) == 0, "out touched");
    m = refl_mat4_identity(); /* two equal rows */
    m.m[1] = 1; m.m[5] = 0;   /* row 1 = (1, 0, 0, 0) = row 0 */
    cr_assert_eq(refl_mat4_invert(m, &out), 0);
    /* nearly dependent rows (1, 1e4) and (1, 1e4 + 2^-10): |det| / (product
       of the row norms) ~ 1e-11, condition ~ 1e11: singular */
    m = refl_mat4_identity();
    m.m[0] = 1; m.m[4] = 1e4f; m.m[1] = 1; m.m[5] = 1e4f + 0.0009765625f;
    cr_assert_eq(refl_mat4_invert(m, &out), 0);
    /* while 2^-4 instead (condition ~ 2e9) still inverts */
    m.m[5] = 1e4f + 0.0625f;
    cr_assert_eq(refl_mat4_invert(m, &out), 1);
    cr_assert(memcmp(&out, &keep, sizeof out) != 0);
    m = refl_mat4_identity();
    m.m[6] = NAN;
    cr_assert_eq(refl_mat4_invert(m, &out), 0);
}

/* gluPerspective(90, 2, 1, 3): f = cot 45 = 1; m[0] = f / 2, m[5] = f,
   m[10] = (3 + 1) / (1 - 3) = -2, m[11] = -1, m[14] = 2*3*1 / (1 - 3) = -3. */
Test(refl_math, matrix_perspective) {
    const float want[16] = {0.5f, 0, 0, 0, 0, 1, 0, 0, 0, 0, -2, -1, 0, 0, -3, 0};
    refl_mat4 p = refl_mat4_perspective((float)(PI / 2), 2.0f, 1.0f, 3.0f);
    refl_vec3 n, f;
    mat_near(p, want, 1e-6f);
    n = refl_mat4_point(p, refl_v3(0, 0, -1)); /* near plane -> z = -1 */
    f = refl_mat4_point(p, refl_v3(0, 0, -3)); /* far plane -> z = +1 */
    NEAR_ABS(n.z, -1, 1e-6);
    NEAR_ABS(f.z, 1, 1e-6);
    /* gluPerspective(60, 1, 0.5, 100): f = cot 30 = sqrt 3 */
    p = refl_mat4_perspective((float)(PI / 3), 1.0f, 0.5f, 100.0f);
    NEAR_REL(p.m[0], sqrt(3.0), 1e-6);
    NEAR_REL(p.m[5], sqrt(3.0), 1e-6);
    NEAR_REL(p.m[10], -100.5 / 99.5, 1e-6);
    NEAR_REL(p.m[14], -100.0 / 99.5, 1e-6);
}

/* gluLookAt(eye (2,3,4), centre (3,3,4), up y): f = +x, s = f x up = +z,
   u = s x f = +y; rows s, u, -f: m[8] = 1, m[5] = 1, m[2] = -1, and the
   translation (-s.eye, -u.eye, f.eye) = (-4, -3, 2). */
Test(refl_math, matrix_look_at) {
    const float want[16] = {0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, -4, -3, 2, 1};
    refl_mat4 v = refl_mat4_look_at(refl_v3(2, 3, 4), refl_v3(3, 3, 4), refl_v3(0, 1, 0));
    refl_vec3 p;
    mat_near(v, want, 1e-6f);
    p = refl_mat4_point(v, refl_v3(3, 3, 4)); /* the target straight ahead, 1 away */
    NEAR_ABS(p.x, 0, 1e-6);
    NEAR_ABS(p.y, 0, 1e-6);
    NEAR_ABS(p.z, -1, 1e-6);
    /* the classic default: eye (0,0,5) looking at the origin is a translation;
       an unnormalised, non-orthogonal up is fine */
    v = refl_mat4_look_at(refl_v3(0, 0, 5), refl_v3(0, 0, 0), refl_v3(0, 3, 1));
    {
        const float w2[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -5, 1};
        mat_near(v, w2, 1e-6f);
    }
}

/* ---- quaternions ------------------------------------------------------------------ */

static void v3_near(refl_vec3 a, refl_vec3 b, float tol) {
    cr_assert(fabsf(a.x - b.x) <= tol && fabsf(a.y - b.y) <= tol && fabsf(a.z - b.z) <= tol,
              "(%g %g %g) vs (%g %g %g)", a.x, a.y, a.z, b.x, b.y, b.z);
}

Test(refl_math, quaternion_matches_matrix) {
    int it;
    sm_state = 31;
    for (it = 0; it < 500; ++it) {
        refl_vec3 axis = refl_v3((float)sm_uniform(-1, 1), (float)sm_uniform(-1, 1), (float)sm_uniform(-1, 1));
        refl_vec3 v = refl_v3((float)sm_uniform(-5, 5), (float)sm_uniform(-5, 5), (float)sm_uniform(-5, 5));
        float ang = (float)sm_uniform(-7, 7);
        refl_quat q = refl_quat_axis_angle(axis, ang), q2;
        refl_mat4 m = refl_mat4_rotate(axis, ang);
        v3_near(refl_quat_rotate(q, v), refl_mat4_dir(m, v), 1e-5f);
        v3_near(refl_mat4_dir(refl_mat4_from_quat(q), v), refl_mat4_dir(m, v), 1e-5f);
        /* composition: rotating by a * b is rotating by b, then a */
        q2 = refl_quat_axis_angle(refl_v3(v.z, v.x, v.y), ang * 0.7f);
        v3_near(refl_quat_rotate(refl_quat_mul(q, q2), v), refl_quat_rotate(q, refl_quat_rotate(q2, v)), 1e-4f);
        /* a non-unit quaternion is its normalised rotation */
        q2 = q;
        q2.x *= 3; q2.y *= 3; q2.z *= 3; q2.w *= 3;
        v3_near(refl_quat_rotate(q2, v), refl_quat_rotate(q, v), 1e-5f);
        v3_near(refl_mat4_dir(refl_mat4_from_quat(q2), v), refl_quat_rotate(q, v), 1e-5f);
    }
    {
        refl_quat q = refl_quat_normalize(refl_quat_axis_angle(refl_v3(0, 0, 0), 1)); /* zero axis: identity */
        cr_assert(q.x == 0 && q.y == 0 && q.z == 0 && q.w == 1);
    }
}

Test(refl_math, quaternion_slerp) {
    refl_vec3 z = refl_v3(0, 0, 1), x = refl_v3(1, 0, 0);
    refl_quat a = refl_quat_axis_angle(z, 0), b = refl_quat_axis_angle(z, (float)(PI / 2)), m, nb;
    /* endpoints */
    m = refl_quat_slerp(a, b, 0);
    v3_near(refl_quat_rotate(m, x), x, 1e-6f);
    m = refl_quat_slerp(a, b, 1);
    v3_near(refl_quat_rotate(m, x), refl_v3(0, 1, 0), 1e-6f);
    /* midpoint: 45 degrees, a unit quaternion */
    m = refl_quat_slerp(a, b, 0.5f);
    v3_near(refl_quat_rotate(m, x), refl_v3((float)sqrt(0.5), (float)sqrt(0.5), 0), 1e-6f);
    NEAR_ABS(sqrt((double)m.x * m.x + (double)m.y * m.y + (double)m.z * m.z + (double)m.w * m.w), 1, 1e-6);
    /* a quarter: 22.5 degrees (constant angular speed, unlike nlerp) */
    m = refl_quat_slerp(a, b, 0.25f);
    v3_near(refl_quat_rotate(m, x), refl_v3((float)cos(PI / 8), (float)sin(PI / 8), 0), 1e-6f);
    /* the short way: -b is the same rotation, the result is the same */
    nb = b;
    nb.x = -nb.x; nb.y = -nb.y; nb.z = -nb.z; nb.w = -nb.w;
    v3_near(refl_quat_rotate(refl_quat_slerp(a, nb, 0.5f), x), refl_v3((float)sqrt(0.5), (float)sqrt(0.5), 0), 1e-6f);
    /* 350 degrees apart one way is 10 the other: halfway is -5 degrees */
    b = refl_quat_axis_angle(z, (float)(-10 * PI / 180));
    m = refl_quat_slerp(a, b, 0.5f);
    v3_near(refl_quat_rotate(m, x), refl_v3((float)cos(-5 * PI / 180), (float)sin(-5 * PI / 180), 0), 1e-6f);
    /* nearly equal quaternions: finite, unit, in between */
    b = refl_quat_axis_angle(z, 1e-6f);
    m = refl_quat_slerp(a, b, 0.5f);
    cr_assert(isfinite(m.x) && isfinite(m.y) && isfinite(m.z) && isfinite(m.w));
    NEAR_ABS(m.z, sin(0.25e-6), 1e-9);
    NEAR_ABS(m.w, 1, 1e-7);
    m = refl_quat_slerp(b, b, 0.3f);
    NEAR_ABS(m.z, b.z, 1e-9);
}

/* ---- random numbers --------------------------------------------------------------- */

/* xorshift64* from seed 1 (values from a Python reference implementation) */
Test(refl_math, rng_known_sequence) {
    const uint32_t want[4] = {0x47e4ce4bu, 0xabcfa6a8u, 0xb9d10d8fu, 0x4db418a0u};
    refl_rng r = refl_rng_seed(1), r2;
    int i;
    for (i = 0; i < 4; ++i) cr_assert_eq(refl_rng_u32(&r), want[i], "draw %d", i);
    r = refl_rng_seed(1);
    r2 = refl_rng_seed(1);
    for (i = 0; i < 1000; ++i) {
        uint32_t u = refl_rng_u32(&r2);
        float f = refl_rng_float(&r);
        cr_assert_eq(f, (float)(u >> 8) * (1.0f / 16777216.0f));
        cr_assert(f >= 0.0f && f < 1.0f);
    }
    /* seed 0 is replaced: not stuck at zero */
    r = refl_rng_seed(0);
    cr_assert(refl_rng_u32(&r) != 0 || refl_rng_u32(&r) != 0);
    cr_assert_neq(r.state, 0);
}

Test(refl_math, rng_uniform) {
    refl_rng r = refl_rng_seed(2024);
    int bins[16] = {0}, i;
    double chi = 0, e = 160000.0 / 16;
    for (i = 0; i < 160000; ++i) ++bins[(int)(refl_rng_float(&r) * 16)];
    for (i = 0; i < 16; ++i) chi += (bins[i] - e) * (bins[i] - e) / e;
    cr_assert(chi < 37.7, "chi-square %g (15 dof, p = 0.001 at 37.7)", chi);
}
