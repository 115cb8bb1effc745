/* LAYERED_EM's layers (paper 001 section 4.2): LBG keeps a small object
   whose distances lie apart from a dense object's in a layer of its own
   when as many layers are asked as there are such groups (the ball at the
   concave bowl's focus with two layers). */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>
#include "../../reflect.h"
#include "refl_test_util.h"

Test(lem_infer, lbg_keeps_a_small_distinct_object_apart_from_a_dense_one) {
    /* object 0, a floor: 400 hits at 3 to 15, most of them near 3; object
       1, a ball: 60 hits at 0.3. Lloyd's iterations over the hits from
       their quantiles put the ball with the near floor, and the whole-object
       rule then moves the whole floor there too: one layer. Two layers
       asked give the ball one and the floor the other */
    enum { FLOOR = 400, BALL = 60, N = FLOOR + BALL };
    float dist[N], radius[REFL_LEM_MAX_LAYERS];
    int obj[N], ray[N], layer[N], i;
    double floor_mean = 0.0, ball_mean = 0.0;
    for (i = 0; i < FLOOR; ++i) {
        float u = (float)i / FLOOR;
        dist[i] = 3.0f + 12.0f * u * u, obj[i] = 0, ray[i] = i;
        floor_mean += dist[i] / FLOOR;
    }
    for (i = FLOOR; i < N; ++i) {
        dist[i] = 0.298f + 0.0001f * (float)(i - FLOOR), obj[i] = 1, ray[i] = i;
        ball_mean += dist[i] / BALL;
    }
    cr_assert_eq(refl_lem_cluster_layers(dist, obj, ray, N, 2, NULL, radius, layer), 2);
    for (i = 0; i < N; ++i)
        cr_assert_eq(layer[i], obj[i] == 1 ? 0 : 1, "hit %d (object %d at %.3f) in layer %d", i, obj[i], dist[i],
                     layer[i]);
    cr_assert_float_eq(radius[0], (float)ball_mean, 1e-4f, "%f", radius[0]);
    cr_assert_float_eq(radius[1], (float)floor_mean, 1e-3f, "%f", radius[1]);
    /* three asked: still the two groups, the third layer left empty */
    cr_assert_eq(refl_lem_cluster_layers(dist, obj, ray, N, 3, NULL, radius, layer), 2);
    /* without object ids the hits alone decide (the near floor joins the ball) */
    cr_assert_eq(refl_lem_cluster_layers(dist, NULL, ray, N, 2, NULL, radius, layer), 2);
    cr_assert_gt(radius[0], 1.0f, "%f", radius[0]);
}

Test(layered_em, two_layers_show_the_ball_at_a_concave_mirrors_focus) {
    /* `concave` at 80x60 against greedy RAYTRACE: two layers give the ball
       its layer as three do (the bounds of
       a_ball_at_a_concave_mirrors_focus_is_an_inner_layer), where one
       layer shows rings (under 22 dB there) */
    refl_view v;
    refl_scene *s = tu_refl_builtin("concave", &v, 80, 60);
    refl_render_desc d;
    refl_frame *truth, *lem;
    refl_image_error img;
    refl_reflection_error err;
    d = tu_refl_greedy_raytrace(2); /* the default bounces, as the LAYERED_EM frame */
    truth = tu_refl_render(s, &v, &d);
    d = tu_refl_desc(REFL_LAYERED_EM, 2);
    d.layered_em.layers = 2;
    lem = tu_refl_render(s, &v, &d);
    cr_assert_eq(refl_measure_image_error(lem, truth, 1, 0.0f, &img), REFL_OK);
    cr_assert_eq(refl_measure_reflection_error(lem, truth, NULL, &err), REFL_OK);
    cr_log_info("concave 80x60, two layers: %.2f dB, %.2f px", img.psnr, err.mean);
    cr_assert_geq(img.psnr, 28.0, "two layers %.2f dB", img.psnr);
    cr_assert_lt(err.mean, 1.5, "two layers %.2f px", err.mean);
    refl_frame_destroy(truth);
    refl_frame_destroy(lem);
    refl_scene_destroy(s);
}
