/* The cost lines behind `reflect bench`'s SBC resolution sweep
   (bench/cost_fit.c, tools/reflect_bench_sbc_sweep.c): a least-squares
   line of ms against pixels, exact on points on a line at the sweep's
   pixel counts, and the crossover of two lines where it exists (and none
   where the lines are parallel or meet only at x <= 0). No timing. */
#include <criterion/criterion.h>
#include <math.h>
#include "../../bench/cost_fit.h"

/* 640x480, 1920x1080, 3840x2160 */
static const double sweep_px[3] = {307200.0, 2073600.0, 8294400.0};

Test(refl_sbc_sweep, fit_recovers_a_line_at_the_sweeps_pixel_counts) {
    double ms[3];
    refl_cost_line l;
    int i;
    for (i = 0; i < 3; ++i) ms[i] = 4500.0 + 0.9e-3 * sweep_px[i];
    cr_assert(refl_cost_fit(sweep_px, ms, 3, &l));
    cr_assert_float_eq(l.fixed, 4500.0, 1e-6);
    cr_assert_float_eq(l.per_unit, 0.9e-3, 1e-12);
}

Test(refl_sbc_sweep, fit_is_the_least_squares_line) {
    /* (0,0), (1,1), (2,1): slope 1/2, intercept 1/6 */
    const double x[3] = {0.0, 1.0, 2.0}, y[3] = {0.0, 1.0, 1.0};
    refl_cost_line l;
    cr_assert(refl_cost_fit(x, y, 3, &l));
    cr_assert_float_eq(l.per_unit, 0.5, 1e-12);
    cr_assert_float_eq(l.fixed, 1.0 / 6.0, 1e-12);
}

Test(refl_sbc_sweep, fit_refuses_what_has_no_line) {
    const double same[3] = {5.0, 5.0, 5.0}, y[3] = {1.0, 2.0, 3.0}, bad[3] = {1.0, NAN, 3.0};
    refl_cost_line l = {7.0, 7.0};
    cr_assert_not(refl_cost_fit(same, y, 3, &l));
    cr_assert_not(refl_cost_fit(sweep_px, y, 1, &l));
    cr_assert_not(refl_cost_fit(sweep_px, bad, 3, &l));
    cr_assert_not(refl_cost_fit(bad, y, 3, &l));
    cr_assert(l.fixed == 7.0 && l.per_unit == 7.0); /* untouched */
}

Test(refl_sbc_sweep, crossover_where_the_lines_meet) {
    /* slow to start but growing slowly, against fast to start and growing
       fast: they meet at (4500 - 10) / (0.06e-3 - 0.01e-3) = 89.8 Mpx */
    refl_cost_line sbc = {4500.0, 0.01e-3}, tracer = {10.0, 0.06e-3};
    double x = 0.0;
    cr_assert(refl_cost_crossover(sbc, tracer, &x));
    cr_assert_float_eq(x, 4490.0 / 0.05e-3, 1e-3);
    cr_assert(refl_cost_crossover(tracer, sbc, &x)); /* symmetric */
    cr_assert_float_eq(x, 4490.0 / 0.05e-3, 1e-3);
}

Test(refl_sbc_sweep, no_crossover_when_parallel_or_behind) {
    refl_cost_line a = {100.0, 1e-3}, parallel = {10.0, 1e-3}, behind = {10.0, 2e-3};
    double x = -1.0;
    cr_assert_not(refl_cost_crossover(a, parallel, &x));
    /* behind: slower to start and growing faster, met only at x < 0 */
    cr_assert_not(refl_cost_crossover(behind, (refl_cost_line){5.0, 1e-3}, &x));
    cr_assert(x == -1.0);
    cr_assert(refl_cost_crossover(a, behind, &x)); /* 90 / 1e-3 */
    cr_assert_float_eq(x, 90000.0, 1e-6);
}
