/* cost_fit.h - a method's cost as a straight line (least squares: ms
   against pixels, say) and where two such lines cross: the benchmark's
   crossover between two methods (tools/reflect_bench_sbc_sweep.c). Plain
   arithmetic, no dependency; bench and tests only. */
#ifndef REFL_COST_FIT_H
#define REFL_COST_FIT_H

#ifdef __cplusplus
extern "C" {
#endif

/* cost(x) = fixed + per_unit x */
typedef struct refl_cost_line {
    double fixed, per_unit;
} refl_cost_line;

/* The least-squares line through (x[i], y[i]), i < n; 0 (and *out
   untouched) when fewer than two distinct x or a value is not finite. */
int refl_cost_fit(const double *x, const double *y, int n, refl_cost_line *out);

/* The x > 0 where a and b cost the same; 0 when they never do there
   (parallel, or meeting at x <= 0). */
int refl_cost_crossover(refl_cost_line a, refl_cost_line b, double *x);

#ifdef __cplusplus
}
#endif
#endif /* REFL_COST_FIT_H */
