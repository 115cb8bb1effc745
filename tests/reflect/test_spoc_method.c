/* Method SPOC (paper 004) on the built-in "teapots" scene, against RAYTRACE
   with one bounce: the impostor the method builds holds the points of the
   diffuse teapot that RAYTRACE's reflected rays meet (the paper's claim
   that an SPOC impostor is "sufficient to intercept all reflected rays":
   with its three depth layers, at least 99%); the reflection error and PSNR
   over the mirror; the same bytes for any thread count. */
#include <criterion/criterion.h>

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

static int object_named(const refl_scene *s, const char *name) {
    int i;
    for (i = 0; i < s->object_count; ++i)
        if (!strcmp(s->objects[i].name, name)) return i;
    cr_assert_fail("no object %s", name);
    return -1;
}

static void world_box(const refl_scene *s, int object, refl_vec3 *lo, refl_vec3 *hi) {
    int n = refl_object_world_positions(s, object, NULL), k;
    float *p = (float *)malloc(3 * sizeof(float) * (size_t)n);
    cr_assert(n > 0 && p);
    refl_object_world_positions(s, object, p);
    *lo = refl_v3(FLT_MAX, FLT_MAX, FLT_MAX);
    *hi = refl_v3(-FLT_MAX, -FLT_MAX, -FLT_MAX);
    for (k = 0; k < n; ++k) {
        lo->x = fminf(lo->x, p[3 * k]); lo->y = fminf(lo->y, p[3 * k + 1]); lo->z = fminf(lo->z, p[3 * k + 2]);
        hi->x = fmaxf(hi->x, p[3 * k]); hi->y = fmaxf(hi->y, p[3 * k + 1]); hi->z = fmaxf(hi->z, p[3 * k + 2]);
    }
    free(p);
}

/* The fraction of the truth's reflected points on the diffuse teapot that
   an impostor built as the method builds it (strength K, `layers` depth
   layers) stores: the point's texel, or one of its 8 neighbours, holds its
   depth within the impostor's depth tolerance in some layer. */
static double held_fraction(const refl_scene *s, const refl_frame *truth, float strength, int layers,
                            long long *counted) {
    int mirror = object_named(s, "mirror teapot"), diffuse = object_named(s, "diffuse teapot");
    refl_vec3 mlo, mhi, dlo, dhi;
    refl_spoc cam;
    refl_impostor_camera ic;
    refl_impostor *imp = NULL;
    refl_impostor_desc d;
    long long held = 0, n = 0;
    size_t i, npx = (size_t)truth->width * (size_t)truth->height;
    world_box(s, mirror, &mlo, &mhi);
    world_box(s, diffuse, &dlo, &dhi);
    cr_assert_eq(refl_spoc_init(&cam, refl_v3_scale(refl_v3_add(mlo, mhi), 0.5f), refl_v3_scale(refl_v3_add(dlo, dhi), 0.5f),
                                0.5f * refl_v3_length(refl_v3_sub(dhi, dlo)),
                                0.5f * refl_v3_length(refl_v3_sub(mhi, mlo)), strength, 512),
                 REFL_OK);
    ic = refl_spoc_impostor_camera(&cam);
    memset(&d, 0, sizeof d);
    d.threads = 2;
    d.layers = layers;
    cr_assert_eq(refl_impostor_build(s, &diffuse, 1, &ic, &d, &imp), REFL_OK);
    for (i = 0; i < npx; ++i) {
        const float *q = truth->points + 3 * i;
        float o[3];
        int du, dv, layer, ok = 0;
        if (truth->stencil[i] != mirror + 1 || !isfinite(q[0])) continue;
        /* on the diffuse teapot: inside its box, above the floor */
        if (q[0] < dlo.x - 1e-3f || q[0] > dhi.x + 1e-3f || q[2] < dlo.z - 1e-3f || q[2] > dhi.z + 1e-3f ||
            q[1] < 1e-3f || q[1] > dhi.y + 1e-3f)
            continue;
        ++n;
        cr_assert(refl_spoc_project(&cam, refl_v3(q[0], q[1], q[2]), o));
        for (layer = 0; layer < layers && !ok; ++layer)
            for (dv = -1; dv <= 1 && !ok; ++dv)
                for (du = -1; du <= 1 && !ok; ++du) {
                    int u = (int)floorf(o[0]) + du, v = (int)floorf(o[1]) + dv;
                    size_t t;
                    if (u < 0 || v < 0 || u >= imp->width || v >= imp->height) continue;
                    t = ((size_t)layer * imp->height + v) * imp->width + u;
                    ok = imp->color[4 * t + 3] > 0.0f && fabsf(imp->depth[t] - o[2]) <= imp->depth_tolerance;
                }
        held += ok;
    }
    refl_impostor_destroy(imp);
    *counted = n;
    return n ? (double)held / (double)n : 0.0;
}

static refl_view teapots_view(const refl_scene *s) {
    refl_view v = s->camera;
    v.width = 320;
    v.height = 240;
    return v;
}

Test(spoc_method, impostor_holds_the_reflected_points) {
    refl_scene *s = NULL;
    refl_view v;
    refl_render_desc rd = tu_refl_one_bounce(REFL_RAYTRACE, 2);
    refl_frame *truth;
    long long n0, n1, n3;
    double plain, spoc, layered;
    cr_assert_eq(refl_scene_builtin("teapots", NULL, &s), REFL_OK);
    v = teapots_view(s);
    truth = tu_refl_render(s, &v, &rd);
    plain = held_fraction(s, truth, 0.0f, 1, &n0);
    spoc = held_fraction(s, truth, 1.0f, 1, &n1);
    layered = held_fraction(s, truth, 1.0f, 3, &n3);
    cr_log_info("teapots: reflected points on the diffuse teapot held: plain depth image %.4f, SPOC one layer "
                "%.4f, three layers %.4f (of %lld)\n",
                plain, spoc, layered, n1);
    cr_expect(n1 > 300, "only %lld reflected points on the diffuse teapot", n1);
    /* one layer misses points on and beside the diffuse teapot's spout,
       which points at the mirror: hidden behind other parts of the teapot
       as the SPOC sees them (the spout's near side, the spout in front of
       the body), which the peeled layers hold */
    cr_expect(spoc >= 0.94, "SPOC (one layer) holds %.4f of the reflected points", spoc);
    cr_expect(spoc > plain, "SPOC %.4f, plain depth image %.4f", spoc, plain);
    cr_expect(layered >= 0.99, "SPOC with three layers holds %.4f of the reflected points", layered);
    {
        /* no strength reaches the aim with one layer: the points missed
           are hidden from the reflector's centre, and a push away from the
           pole shows only what viewpoints moved away from it see */
        static const float strengths[] = {0.25f, 0.5f, 2.0f};
        int k;
        for (k = 0; k < 3; ++k) {
            long long nk;
            double h = held_fraction(s, truth, strengths[k], 1, &nk);
            cr_log_info("teapots: SPOC strength %.2f holds %.4f\n", strengths[k], h);
            cr_expect(h >= 0.93, "strength %g holds %.4f", strengths[k], h);
        }
    }
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

Test(spoc_method, error_against_raytrace) {
    refl_scene *s = NULL;
    refl_view v;
    refl_render_desc rt = tu_refl_one_bounce(REFL_RAYTRACE, 2), sp = tu_refl_one_bounce(REFL_SPOC, 2);
    refl_frame *truth, *test;
    refl_reflection_error e;
    refl_image_error ie;
    cr_assert_eq(refl_scene_builtin("teapots", NULL, &s), REFL_OK);
    v = teapots_view(s);
    truth = tu_refl_render(s, &v, &rt);
    test = tu_refl_render(s, &v, &sp);
    cr_expect_eq(test->stats.spoc.impostors, 1);
    cr_expect(test->stats.spoc.steps > 0 && test->stats.spoc.max_steps > 0);
    cr_assert_eq(refl_measure_reflection_error(test, truth, NULL, &e), REFL_OK);
    cr_assert_eq(refl_measure_image_error(test, truth, 1, 0.0f, &ie), REFL_OK);
    cr_log_info("teapots 320x240: reflection error mean %.3f p95 %.3f max %.3f px, wrong %.4f, empty %.4f; "
                "PSNR %.2f dB over the mirror\n",
                e.mean, e.p95, e.max, e.wrong, e.empty, ie.psnr);
    cr_expect(e.mean < 0.1 && e.p95 < 0.5, "mean %g p95 %g", e.mean, e.p95);
    cr_expect(e.wrong < 0.005 && e.empty < 0.02, "wrong %g empty %g", e.wrong, e.empty);
    /* the differences are scattered pixels: grazing reflections at the
       mirror's silhouette (the normal is the G-buffer's), and the rays the
       impostor misses (empty) */
    cr_expect(ie.psnr > 24.0, "PSNR %g", ie.psnr);
    refl_frame_destroy(truth);
    refl_frame_destroy(test);
    refl_scene_destroy(s);
}

Test(spoc_method, same_bytes_for_any_thread_count) {
    refl_scene *s = NULL;
    refl_view v;
    refl_render_desc a = tu_refl_one_bounce(REFL_SPOC, 1), b = tu_refl_one_bounce(REFL_SPOC, 3);
    refl_frame *fa, *fb;
    size_t npx;
    cr_assert_eq(refl_scene_builtin("teapots", NULL, &s), REFL_OK);
    v = teapots_view(s);
    v.width = 160;
    v.height = 120;
    a.spoc.size = b.spoc.size = 256;
    fa = tu_refl_render(s, &v, &a);
    fb = tu_refl_render(s, &v, &b);
    npx = (size_t)v.width * (size_t)v.height;
    cr_expect(!memcmp(fa->rgba, fb->rgba, 4 * sizeof(float) * npx));
    cr_expect(!memcmp(fa->points, fb->points, 3 * sizeof(float) * npx));
    cr_expect_eq(fa->stats.spoc.steps, fb->stats.spoc.steps);
    cr_expect_eq(fa->stats.spoc.max_steps, fb->stats.spoc.max_steps);
    refl_frame_destroy(fa);
    refl_frame_destroy(fb);
    refl_scene_destroy(s);
}

/* refl_spoc_set_build as documented: from the mirror teapot, the diffuse
   teapot is the one impostor (imaged alone through its SPOC: the same
   bytes as refl_impostor_build's), every other object exact; with
   mirror_impostors, from the diffuse teapot, the mirror's impostor stores
   normals. */
Test(spoc_method, impostor_set_as_documented) {
    refl_scene *s = NULL;
    refl_spoc_set *set = NULL, unset;
    refl_spoc_set_desc d;
    refl_impostor_camera ic;
    refl_impostor_desc id;
    refl_impostor *alone = NULL;
    refl_vec3 lo, hi;
    int mirror, diffuse, k, n;
    size_t texels;
    cr_assert_eq(refl_scene_builtin("teapots", NULL, &s), REFL_OK);
    mirror = object_named(s, "mirror teapot");
    diffuse = object_named(s, "diffuse teapot");
    memset(&d, 0, sizeof d);
    d.size = 64;
    d.threads = 2;
    cr_assert_eq(refl_spoc_set_build(s, mirror, &d, &set), REFL_OK);
    cr_assert_eq(set->imp_count, 1);
    cr_expect_eq(set->imp_object[0], diffuse);
    cr_expect_eq(set->imps[0]->layers, 3);
    cr_expect_null(set->imps[0]->normal);
    refl_object_world_bounds(s, mirror, &lo, &hi);
    cr_expect_lt(refl_v3_length(refl_v3_sub(set->cams[0].eye, refl_v3_scale(refl_v3_add(lo, hi), 0.5f))), 1e-6f);
    cr_expect_eq(set->cams[0].size, 64);
    cr_expect_eq(set->exact_count, s->object_count - 1);
    for (k = 0, n = 0; k < set->exact_count; ++k) n += set->exact_object[k] == diffuse;
    cr_expect_eq(n, 0, "the impostored teapot is not exact");
    ic = refl_spoc_impostor_camera(&set->cams[0]);
    memset(&id, 0, sizeof id);
    id.layers = 3;
    id.threads = 1;
    cr_assert_eq(refl_impostor_build(s, &diffuse, 1, &ic, &id, &alone), REFL_OK);
    texels = (size_t)alone->width * (size_t)alone->height * (size_t)alone->layers;
    cr_expect(!memcmp(alone->color, set->imps[0]->color, texels * 4 * sizeof(float)) &&
              !memcmp(alone->depth, set->imps[0]->depth, texels * sizeof(float)));
    refl_impostor_destroy(alone);
    refl_spoc_set_destroy(set);
    set = NULL;
    d.mirror_impostors = 1;
    cr_assert_eq(refl_spoc_set_build(s, diffuse, &d, &set), REFL_OK);
    cr_assert_eq(set->imp_count, 1);
    cr_expect_eq(set->imp_object[0], mirror);
    cr_expect_not_null(set->imps[0]->normal);
    refl_spoc_set_destroy(set);
    set = &unset; /* a refusal sets it to NULL */
    cr_expect_eq(refl_spoc_set_build(NULL, 0, &d, &set), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_null(set);
    cr_expect_eq(refl_spoc_set_build(s, -1, &d, &set), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_spoc_set_build(s, s->object_count, &d, &set), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_spoc_set_build(s, mirror, &d, NULL), REFL_ERROR_INVALID_ARGUMENT);
    d.size = 4;
    cr_expect_eq(refl_spoc_set_build(s, mirror, &d, &set), REFL_ERROR_INVALID_ARGUMENT);
    d.size = 64;
    d.layers = REFL_IMPOSTOR_MAX_LAYERS + 1;
    cr_expect_eq(refl_spoc_set_build(s, mirror, &d, &set), REFL_ERROR_INVALID_ARGUMENT);
    d.layers = 0;
    d.strength = NAN;
    cr_expect_eq(refl_spoc_set_build(s, mirror, &d, &set), REFL_ERROR_INVALID_ARGUMENT);
    d.strength = 0.0f;
    d.max_edge_px = 0.25f;
    cr_expect_eq(refl_spoc_set_build(s, mirror, &d, &set), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_null(set);
    refl_spoc_set_destroy(NULL);
    refl_scene_destroy(s);
}

Test(spoc_method, options_validated) {
    refl_render_desc d;
    const char *why = NULL;
    memset(&d, 0, sizeof d);
    d.method = REFL_SPOC;
    d.spoc.size = 4;
    cr_expect_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect(why && strstr(why, "spoc.size"));
    d.spoc.size = 0;
    d.spoc.strength = NAN;
    cr_expect_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    d.spoc.strength = -1.0f;
    d.spoc.step_scale = 32.0f;
    cr_expect_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    d.spoc.step_scale = 0.0f;
    d.spoc.layers = 5;
    cr_expect_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect(why && strstr(why, "spoc.layers"));
    d.spoc.layers = 0;
    d.spoc.glass = 7;
    cr_expect_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    d.spoc.glass = REFL_SPOC_GLASS_ESTIMATE;
    cr_expect_eq(refl_validate_render_desc(&d, &why), REFL_OK);
}

/* Where the paper says the method degrades: the push's strength (up to
   where the map folds much of the surface) and the marching step. Every
   frame stays finite; steps scale with step_scale. */
Test(spoc_method, sweeps_stay_finite, .timeout = 120) {
    static const float strengths[] = {-1.0f, 0.5f, 4.0f, 16.0f, 64.0f};
    static const float steps[] = {0.25f, 4.0f};
    refl_scene *s = NULL;
    refl_view v;
    refl_render_desc rt = tu_refl_one_bounce(REFL_RAYTRACE, 2);
    refl_frame *truth;
    long long base_steps;
    size_t k, npx;
    int i;
    cr_assert_eq(refl_scene_builtin("teapots", NULL, &s), REFL_OK);
    v = teapots_view(s);
    v.width = 160;
    v.height = 120;
    npx = (size_t)v.width * (size_t)v.height;
    truth = tu_refl_render(s, &v, &rt);
    {
        refl_render_desc d = tu_refl_one_bounce(REFL_SPOC, 2);
        refl_frame *f;
        d.spoc.size = 256;
        f = tu_refl_render(s, &v, &d);
        base_steps = f->stats.spoc.steps;
        refl_frame_destroy(f);
    }
    for (i = 0; i < 7; ++i) {
        refl_render_desc d = tu_refl_one_bounce(REFL_SPOC, 2);
        refl_reflection_error e;
        refl_frame *f;
        d.spoc.size = 256;
        if (i < 5) d.spoc.strength = strengths[i];
        else d.spoc.step_scale = steps[i - 5];
        f = tu_refl_render(s, &v, &d);
        for (k = 0; k < 4 * npx; ++k) cr_assert(isfinite(f->rgba[k]), "setting %d: pixel %zu not finite", i, k / 4);
        cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &e), REFL_OK);
        cr_expect(isfinite(e.mean) && e.wrong + e.empty < 0.2, "setting %d: mean %g wrong %g empty %g", i, e.mean,
                  e.wrong, e.empty);
        cr_log_info("teapots 160x120, impostor 256, %s %g: mean %.3f px, wrong %.4f, empty %.4f, steps %lld\n",
                    i < 5 ? "strength" : "step_scale", i < 5 ? strengths[i] : steps[i - 5], e.mean, e.wrong, e.empty,
                    f->stats.spoc.steps);
        if (i == 5) cr_expect(f->stats.spoc.steps < base_steps / 2, "%lld vs %lld", f->stats.spoc.steps, base_steps);
        if (i == 6) cr_expect(f->stats.spoc.steps > base_steps * 3, "%lld vs %lld", f->stats.spoc.steps, base_steps);
        refl_frame_destroy(f);
    }
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* A reflector touching the reflected object (the stability
   sweep; the full sweep is `reflect bench --only spoc-sweeps`): the
   diffuse teapot moved 0.84 towards the mirror (about 0.2 past where the
   two first touch), the last step of that sweep where its bounding sphere
   still leaves out the mirror's centre, so it is still an impostor, seen
   by rays up to about 150 degrees from the impostor's reference
   direction. The frame stays finite, and its points stay close to
   RAYTRACE's: at 160x120 the bench measures 1.3% wrong, 0.2% empty and a
   mean of 0.06 px; the bound allows several times that at 64x48, where
   one wrong pixel is a larger share of the mirror's few hundred. */
Test(spoc_method, touching_teapots_stay_finite, .timeout = 60) {
    refl_scene *s = NULL;
    refl_view v;
    refl_render_desc rt = tu_refl_one_bounce(REFL_RAYTRACE, 2), sp = tu_refl_one_bounce(REFL_SPOC, 2);
    refl_frame *truth, *f;
    refl_reflection_error e;
    refl_vec3 mlo, mhi, dlo, dhi, towards;
    size_t k;
    int mirror, diffuse;
    cr_assert_eq(refl_scene_builtin("teapots", NULL, &s), REFL_OK);
    mirror = object_named(s, "mirror teapot");
    diffuse = object_named(s, "diffuse teapot");
    world_box(s, mirror, &mlo, &mhi);
    world_box(s, diffuse, &dlo, &dhi);
    towards = refl_v3_sub(refl_v3_add(mlo, mhi), refl_v3_add(dlo, dhi));
    towards.y = 0.0f;
    towards = refl_v3_scale(refl_v3_normalize(towards), 0.84f);
    s->objects[diffuse].transform = refl_mat4_mul(refl_mat4_translate(towards), s->objects[diffuse].transform);
    v = teapots_view(s);
    v.width = 64;
    v.height = 48;
    truth = tu_refl_render(s, &v, &rt);
    f = tu_refl_render(s, &v, &sp);
    for (k = 0; k < 4 * (size_t)v.width * (size_t)v.height; ++k)
        cr_assert(isfinite(f->rgba[k]), "pixel %zu not finite", k / 4);
    cr_expect_eq(f->stats.spoc.impostors, 1, "the touching teapot is still an impostor");
    cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &e), REFL_OK);
    cr_log_info("touching teapots 64x48: mean %.3f px, p95 %.2f, wrong %.4f, empty %.4f, traced %lld\n", e.mean, e.p95,
                e.wrong, e.empty, f->stats.spoc.traced);
    cr_expect(e.mean < 0.5 && e.wrong < 0.05 && e.empty < 0.03, "mean %g wrong %g empty %g", e.mean, e.wrong, e.empty);
    refl_frame_destroy(truth);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* Second-order reflections (the paper's Fig. 3, "inter-reflecting
   teapots"): with both teapots mirrors, two bounces reflect each ray that
   meets the other teapot's impostor about the normal the impostor stores.
   Against two-bounce RAYTRACE over the mirrors, well ahead of one bounce;
   the same bytes on 1 and 3 threads. */
Test(spoc_method, second_order_through_impostor_normals, .timeout = 120) {
    refl_scene *s = NULL;
    refl_view v;
    refl_render_desc rt = tu_refl_one_bounce(REFL_RAYTRACE, 2), sp = tu_refl_one_bounce(REFL_SPOC, 2);
    refl_frame *truth, *one, *two, *other;
    refl_image_error ie1, ie2;
    refl_reflection_error re;
    int diffuse;
    cr_assert_eq(refl_scene_builtin("teapots", NULL, &s), REFL_OK);
    diffuse = object_named(s, "diffuse teapot");
    s->materials[s->objects[diffuse].material].type = REFL_MIRROR;
    s->materials[s->objects[diffuse].material].reflectance = 0.9f;
    v = teapots_view(s);
    v.width = 160;
    v.height = 120;
    rt.depth = 2;
    sp.spoc.size = 256;
    truth = tu_refl_render(s, &v, &rt);
    one = tu_refl_render(s, &v, &sp);
    sp.depth = 2;
    two = tu_refl_render(s, &v, &sp);
    sp.threads = 3;
    other = tu_refl_render(s, &v, &sp);
    cr_expect_eq(one->stats.depth, 1);
    cr_expect_eq(two->stats.depth, 2);
    cr_expect_eq(two->stats.spoc.impostors, 2, "each mirror's impostor of the other");
    cr_assert_eq(refl_measure_image_error(one, truth, 1, 0.0f, &ie1), REFL_OK);
    cr_assert_eq(refl_measure_image_error(two, truth, 1, 0.0f, &ie2), REFL_OK);
    cr_assert_eq(refl_measure_reflection_error(two, truth, NULL, &re), REFL_OK);
    cr_log_info("two mirror teapots 160x120 against two-bounce RAYTRACE: PSNR over the mirrors %.2f dB with two "
                "bounces, %.2f with one; first points mean %.3f px, wrong %.4f, empty %.4f\n",
                ie2.psnr, ie1.psnr, re.mean, re.wrong, re.empty);
    cr_expect(ie2.psnr > ie1.psnr + 6.0, "two bounces %.2f dB, one %.2f", ie2.psnr, ie1.psnr);
    cr_expect(re.wrong < 0.005 && re.empty < 0.02, "wrong %g empty %g", re.wrong, re.empty);
    cr_expect_eq(tu_refl_digest(two), tu_refl_digest(other), "3 threads give other bytes than 2");
    refl_frame_destroy(truth);
    refl_frame_destroy(one);
    refl_frame_destroy(two);
    refl_frame_destroy(other);
    refl_scene_destroy(s);
}

/* The teapots scene with the mirror teapot turned into a glass sphere of
   its height, where it stood. */
static refl_scene *glass_sphere_scene(void) {
    refl_scene *s = NULL;
    refl_mesh *sphere = NULL;
    refl_vec3 lo, hi;
    refl_material *m;
    int mirror;
    cr_assert_eq(refl_scene_builtin("teapots", NULL, &s), REFL_OK);
    mirror = object_named(s, "mirror teapot");
    world_box(s, mirror, &lo, &hi);
    cr_assert_eq(refl_mesh_sphere(0.5f * (hi.y - lo.y), 96, 48, NULL, &sphere), REFL_OK);
    s->objects[mirror].mesh = refl_scene_add_mesh(s, sphere);
    cr_assert_geq(s->objects[mirror].mesh, 0);
    s->objects[mirror].transform = refl_mat4_translate(refl_v3_scale(refl_v3_add(lo, hi), 0.5f));
    m = &s->materials[s->objects[mirror].material];
    m->type = REFL_GLASS;
    m->ior = 1.5f;
    m->fresnel = 1;
    return s;
}

/* Refraction through a glass sphere (the paper's Fig. 11 setting: a
   diffuse teapot seen through glass), two bounces, against RAYTRACE over
   the sphere: with the exact exit the only error left is the impostor's,
   and the frame agrees with RAYTRACE's to a fraction of a pixel; the
   paper's image-space estimate of the exit adds its own error, bounded
   here; by default the glass is RAYTRACE's own. */
Test(spoc_method, glass_sphere_refraction, .timeout = 120) {
    refl_scene *s = glass_sphere_scene();
    refl_view v = teapots_view(s);
    refl_render_desc rt = tu_refl_one_bounce(REFL_RAYTRACE, 2), sp = tu_refl_one_bounce(REFL_SPOC, 2);
    refl_frame *truth, *exact, *estimate, *traced;
    refl_reflection_error ee, es;
    refl_image_error ie_exact, ie_est;
    v.width = 160;
    v.height = 120;
    rt.depth = sp.depth = 2;
    sp.spoc.size = 256;
    truth = tu_refl_render(s, &v, &rt);
    traced = tu_refl_render(s, &v, &sp);
    sp.spoc.glass = REFL_SPOC_GLASS_EXACT_EXIT;
    exact = tu_refl_render(s, &v, &sp);
    sp.spoc.glass = REFL_SPOC_GLASS_ESTIMATE;
    estimate = tu_refl_render(s, &v, &sp);
    cr_expect_eq(traced->stats.handed_over, 1);
    cr_expect_eq(traced->stats.spoc.impostors, 0);
    cr_expect_eq(exact->stats.handed_over, 0);
    cr_expect_eq(estimate->stats.handed_over, 0);
    cr_expect_eq(exact->stats.spoc.impostors, 1, "the diffuse teapot seen through the glass");
    cr_assert_eq(refl_measure_reflection_error(exact, truth, NULL, &ee), REFL_OK);
    cr_assert_eq(refl_measure_reflection_error(estimate, truth, NULL, &es), REFL_OK);
    cr_assert_eq(refl_measure_image_error(exact, truth, 1, 0.0f, &ie_exact), REFL_OK);
    cr_assert_eq(refl_measure_image_error(estimate, truth, 1, 0.0f, &ie_est), REFL_OK);
    cr_log_info("glass sphere 160x120 against two-bounce RAYTRACE over the glass: exact exit %.2f dB, points mean "
                "%.3f px, wrong %.4f, empty %.4f; estimated exit %.2f dB, mean %.3f px, wrong %.4f, empty %.4f\n",
                ie_exact.psnr, ee.mean, ee.wrong, ee.empty, ie_est.psnr, es.mean, es.wrong, es.empty);
    cr_expect(ie_exact.psnr > 30.0 && ee.mean < 0.05 && ee.wrong + ee.empty < 0.005,
              "exact exit: %.2f dB, mean %g, wrong %g, empty %g", ie_exact.psnr, ee.mean, ee.wrong, ee.empty);
    cr_expect(ie_est.psnr > 14.0 && es.mean < 1.0 && es.wrong < 0.01 && es.empty < 0.05,
              "estimated exit: %.2f dB, mean %g, wrong %g, empty %g", ie_est.psnr, es.mean, es.wrong, es.empty);
    cr_expect(ie_exact.psnr > ie_est.psnr + 10.0, "exact %.2f dB, estimate %.2f", ie_exact.psnr, ie_est.psnr);
    {
        size_t i, n = (size_t)v.width * (size_t)v.height;
        for (i = 0; i < 4 * n; ++i) cr_assert(isfinite(estimate->rgba[i]) && isfinite(exact->rgba[i]));
    }
    sp.threads = 3;
    {
        refl_frame *other = tu_refl_render(s, &v, &sp);
        cr_expect_eq(tu_refl_digest(estimate), tu_refl_digest(other), "3 threads give other bytes than 2");
        refl_frame_destroy(other);
    }
    refl_frame_destroy(truth);
    refl_frame_destroy(traced);
    refl_frame_destroy(exact);
    refl_frame_destroy(estimate);
    refl_scene_destroy(s);
}
