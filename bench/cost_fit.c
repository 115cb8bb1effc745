/* cost_fit.c - straight lines through measured costs (cost_fit.h). */
#include "cost_fit.h"

#include <math.h>

int refl_cost_fit(const double *x, const double *y, int n, refl_cost_line *out) {
    double mx = 0.0, my = 0.0, sxx = 0.0, sxy = 0.0;
    int i;
    if (n < 2) return 0;
    for (i = 0; i < n; ++i) {
        if (!isfinite(x[i]) || !isfinite(y[i])) return 0;
        mx += x[i] / n;
        my += y[i] / n;
    }
    /* centred sums: pixel counts in the millions would square to 1e13
       and swamp the differences otherwise */
    for (i = 0; i < n; ++i) {
        sxx += (x[i] - mx) * (x[i] - mx);
        sxy += (x[i] - mx) * (y[i] - my);
    }
    if (!(sxx > 0.0)) return 0;
    out->per_unit = sxy / sxx;
    out->fixed = my - out->per_unit * mx;
    return 1;
}

int refl_cost_crossover(refl_cost_line a, refl_cost_line b, double *x) {
    double slope = a.per_unit - b.per_unit, at;
    if (slope == 0.0) return 0;
    at = (b.fixed - a.fixed) / slope;
    if (!(at > 0.0) || !isfinite(at)) return 0;
    *x = at;
    return 1;
}
