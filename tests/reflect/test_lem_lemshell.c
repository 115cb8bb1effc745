/* LAYERED_EM's cylinder shell fitted to a layer's hits (lem_infer.c,
   refl__lem_fit_cylinder), on synthetic hits shaped as `hybrid`'s: a
   floor a lens stands on, seen out to the horizon, and a few hits of
   columns beside a small lens. The floor's hits belong on the bottom cap,
   which must lie on the floor and hold most of them without spreading
   its texels over the whole disk; a handful of other hits must not set
   the shell. */
#include <criterion/criterion.h>
#include <math.h>
#include "../../reflect.h"
#include "../reflect_testing.h"

/* n hits on the floor y = 0 around (cx, cz), at distances from rho0 out
   to far, denser near (as a lens sees a floor: the k-th of n at
   rho0 / (1 - s u), u = (k + 0.5) / n), turned by the golden angle. */
static void floor_hits(float *pos, int n, float cx, float cz, float rho0, float far) {
    const float s = 1.0f - rho0 / far;
    int k;
    for (k = 0; k < n; ++k) {
        float u = ((float)k + 0.5f) / (float)n, rho = rho0 / (1.0f - s * u), a = 2.39996323f * (float)k;
        pos[3 * k] = cx + rho * cosf(a);
        pos[3 * k + 1] = 0.0f;
        pos[3 * k + 2] = cz + rho * sinf(a);
    }
}

/* The share of the hits whose distance from the vertical through c lies
   within radius r. */
static double share_within(const float *pos, int n, refl_vec3 c, float r) {
    int k, in = 0;
    for (k = 0; k < n; ++k) in += hypotf(pos[3 * k] - c.x, pos[3 * k + 2] - c.z) <= r;
    return (double)in / n;
}

Test(lem_lemshell, a_floor_layer_lies_on_the_bottom_cap) {
    /* hybrid's teapot with three layers: the floor alone is its outermost
       layer, the teapot's box 0.005 above it; its hits from 0.6 out to 20
       (a quarter within 0.8, half within 1.2) */
    enum { N = 400 };
    static float pos[3 * N];
    const refl_vec3 lo = {-1.1f, 0.005f, -1.0f}, hi = {0.9f, 1.58f, 1.0f}, c = {-0.1f, 0.7925f, 0.0f};
    refl_lem_shell sh;
    float bottom, farthest = 20.0f;
    double within;
    floor_hits(pos, N, c.x, c.z, 0.6f, farthest);
    sh = refl__testing_lem_fit_cylinder(pos, N, c, lo, hi);
    cr_assert_eq(sh.kind, REFL_LEM_SHELL_CYLINDER);
    bottom = sh.center.y - sh.extent[1];
    within = share_within(pos, N, c, sh.extent[0]);
    cr_log_info("floor layer: bottom cap at y = %.4f, radius %.2f holding %.0f%% of the hits", bottom, sh.extent[0],
                100.0 * within);
    /* on the floor (the lens's box padded would put it 0.035 under, every
       floor hit off the cap), and under the lens */
    cr_assert(fabsf(bottom) <= 1e-3f && bottom < lo.y, "bottom cap at y = %g, the floor at 0", bottom);
    /* most of the floor on the cap: not the hits' mean distance, which
       leaves a quarter of them to the side, where each viewpoint sees a
       floor point in other texels */
    cr_assert_geq(within, 0.85, "the radius %.2f holds %.0f%% of the floor hits", sh.extent[0], 100.0 * within);
    /* nor the whole disk: its texels too wide near the lens */
    cr_assert_leq(sh.extent[0], 0.5f * farthest, "radius %.2f", sh.extent[0]);
}

Test(lem_lemshell, a_few_column_hits_do_not_set_a_small_lens_shell) {
    /* hybrid's mirror cup with two layers, its eye rays continued: the near
       layer holds the floor's 272 hits (0.3 to 1.6 from the cup's axis)
       and three hits of two columns 5 and 6 away, up to 2.6 high */
    enum { FLOOR = 272, N = FLOOR + 3 };
    static float pos[3 * N];
    static const float column[3][3] = {{1.2f + 5.05f, 0.8f, 0.7f}, {1.2f, 1.9f, 0.7f + 6.18f}, {1.2f - 6.18f, 2.6f, 0.7f}};
    const refl_vec3 lo = {0.7f, 0.005f, 0.2f}, hi = {1.7f, 0.555f, 1.2f}, c = {1.2f, 0.28f, 0.7f};
    refl_lem_shell sh;
    float lens = 0.5f * hypotf(hi.x - lo.x, hi.z - lo.z), top;
    double within;
    int k;
    floor_hits(pos, FLOOR, c.x, c.z, 0.3f, 1.6f);
    for (k = 0; k < 3; ++k) memcpy(pos + 3 * (FLOOR + k), column[k], sizeof column[k]);
    sh = refl__testing_lem_fit_cylinder(pos, N, c, lo, hi);
    cr_assert_eq(sh.kind, REFL_LEM_SHELL_CYLINDER);
    top = sh.center.y + sh.extent[1];
    within = share_within(pos, FLOOR, c, sh.extent[0]);
    cr_log_info("cup's near layer: radius %.2f holding %.0f%% of the floor hits, caps at %.3f and %.3f", sh.extent[0],
                100.0 * within, sh.center.y - sh.extent[1], top);
    /* the floor's radius (the three column hits, the only ones off the
       caps, made it 5.8: the floor a fifth of the cap's texels across) */
    cr_assert_leq(sh.extent[0], 2.0f, "radius %.2f (the floor's farthest hit 1.6 away)", sh.extent[0]);
    cr_assert_geq(sh.extent[0], lens, "radius %.2f, the lens %.2f", sh.extent[0], lens);
    cr_assert_geq(within, 0.85, "the radius %.2f holds %.0f%% of the floor hits", sh.extent[0], 100.0 * within);
    /* the top cap where the lens's box is: three hits of 275 do not raise
       it to 2.6, which would leave the floor seen past the cap a fifth of
       the side's height */
    cr_assert_leq(top, hi.y + 0.05f, "top cap at y = %.3f, the lens's top at %.3f", top, hi.y);
}

Test(lem_lemshell, a_ring_of_columns_keeps_its_mean_distance) {
    /* a layer all off the caps (hybrid's ring of columns, 5.7 to 6.1 from
       the teapot's axis, 0.2 to 3 high): the radius is their mean distance,
       section 4.2's shell at the layer's average distance (the
       topmost few, on the top cap, counted at its radius) */
    enum { N = 120 };
    static float pos[3 * N];
    const refl_vec3 lo = {-1.1f, 0.005f, -1.0f}, hi = {0.9f, 1.58f, 1.0f}, c = {-0.1f, 0.7925f, 0.0f};
    refl_lem_shell sh;
    double mean = 0.0;
    int k;
    for (k = 0; k < N; ++k) {
        float a = 2.39996323f * (float)k, rho = 5.7f + 0.4f * (float)(k % 5) / 4.0f;
        pos[3 * k] = c.x + rho * cosf(a);
        pos[3 * k + 1] = 0.2f + 2.8f * (float)k / (N - 1);
        pos[3 * k + 2] = c.z + rho * sinf(a);
        mean += rho / N;
    }
    sh = refl__testing_lem_fit_cylinder(pos, N, c, lo, hi);
    cr_assert_eq(sh.kind, REFL_LEM_SHELL_CYLINDER);
    cr_assert_float_eq(sh.extent[0], (float)mean, 0.02f * (float)mean, "radius %.4f, the mean distance %.4f", sh.extent[0], mean);
}
