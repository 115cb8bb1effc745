/* The contract every method in the method table keeps, present and
   future: each refl_method value either renders or says UNSUPPORTED, and
   a method that renders gives the same bytes for every thread count,
   survives the failure of every allocation without a leak, refuses every
   bad option by name, and writes no NaN depth, no half-NaN point and no
   transparent pixel. */
#include <criterion/criterion.h>
#include <stdint.h>
#include <stdio.h>

#include "../../reflect.h"
#include "refl_test_util.h"

static int renders(refl_method m) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 8, 6);
    refl_frame *f = NULL;
    refl_render_desc d = tu_refl_one_bounce(m, 1);
    refl_result r;
    cr_assert_eq(refl_frame_create(8, 6, NULL, &f), REFL_OK);
    r = refl_render(s, &v, &d, f);
    cr_assert(r == REFL_OK || r == REFL_ERROR_UNSUPPORTED, "%s: %s", refl_method_name(m), refl_result_string(r));
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    return r == REFL_OK;
}

Test(refl_contract, every_method_renders_or_is_unsupported) {
    int m, built = 0;
    for (m = REFL_DIRECT; m < REFL_METHOD_COUNT; ++m) built += renders((refl_method)m);
    cr_assert_geq(built, 6, "%d methods render", built);
}

/* The same bytes on 1, 2, 3 and 7 threads, with shadows and two bounces;
   no NaN depth, points NaN in all three coordinates or none; every pixel
   opaque. */
Test(refl_contract, same_bytes_for_every_thread_count_and_a_well_formed_frame, .timeout = 240) {
    static const char *const scenes[] = {"default", "glass", "mirror-room"};
    static const int plain_threads[] = {1, 2, 3, 7}, sanitized_threads[] = {1, 7}; /* the plain runs compare 2 and 3 too */
    const int *threads = tu_sanitized() ? sanitized_threads : plain_threads;
    const int thread_counts = tu_sanitized() ? 2 : 4;
    int m, k, t;
    for (m = REFL_DIRECT; m < REFL_METHOD_COUNT; ++m) {
        if (!renders((refl_method)m)) continue;
        for (k = 0; k < 3; ++k) {
            refl_view v;
            refl_scene *s = tu_refl_builtin(scenes[k], &v, 48, 36);
            uint64_t first = 0;
            for (t = 0; t < thread_counts; ++t) {
                refl_render_desc d = tu_refl_one_bounce((refl_method)m, threads[t]);
                refl_frame *f;
                int i;
                d.depth = 2;
                d.lighting.shadows = 1;
                f = tu_refl_render(s, &v, &d);
                if (t == 0) first = tu_refl_digest(f);
                cr_assert_eq(tu_refl_digest(f), first, "%s on %s: %d threads give other bytes than 1",
                             refl_method_name((refl_method)m), scenes[k], threads[t]);
                for (i = 0; t == 0 && i < v.width * v.height; ++i) {
                    const float *p = f->points + 3 * i;
                    int nan_count = isnan(p[0]) + isnan(p[1]) + isnan(p[2]);
                    cr_assert(f->depth[i] >= 0.0f && f->depth[i] <= 1.0f, "pixel %d: depth %g", i, f->depth[i]);
                    cr_assert(nan_count == 0 || nan_count == 3, "pixel %d: partly NaN point", i);
                    cr_assert(nan_count == 3 || (isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2])));
                    cr_assert_eq(tu_unorm8(f->rgba[4 * i + 3]), 255, "%s on %s: pixel %d is not opaque",
                                 refl_method_name((refl_method)m), scenes[k], i);
                }
                refl_frame_destroy(f);
            }
            refl_scene_destroy(s);
        }
    }
}

/* A renderer's two frames (the second reusing what the first built), each
   allocation failing in turn: every call fails with OUT_OF_MEMORY or
   succeeds, and nothing leaks. The scene is built once, on the same
   counting allocator, which the methods allocate from. */
Test(refl_contract, allocation_failure_at_every_allocation, .timeout = 600) {
    const long stride = tu_sanitized() ? 5 : 1; /* every fifth allocation: the plain runs fail each one, counting leaks */
    int m;
    for (m = REFL_DIRECT; m < REFL_METHOD_COUNT; ++m) {
        tu_alloc_counter c;
        refl_builtin_desc bd;
        refl_scene *s = NULL;
        long k, failures = 0;
        int done = 0;
        if (!renders((refl_method)m)) continue;
        memset(&c, 0, sizeof c);
        memset(&bd, 0, sizeof bd);
        bd.teapot_tess = 2;
        bd.allocator = tu_refl_counting(&c);
        cr_assert_eq(refl_scene_builtin("default", &bd, &s), REFL_OK);
        for (k = 1; !done; k += stride) {
            refl_renderer *rr = NULL;
            refl_frame *f = NULL;
            refl_render_desc d = tu_refl_one_bounce((refl_method)m, 2);
            long live = c.allocs - c.frees;
            refl_result r;
            int frame;
            c.attempts = c.failed = 0;
            c.fail_at = k;
            d.depth = 2;
            d.envmap.size = 16;
            d.sbc.trace_fallback = 1;
            /* models sized to the 24x18 frame: every allocation fails in turn,
               each a frame and a renderer's worth of work */
            d.spoc.size = 32;
            d.graphcam.size = 48;
            d.layered_em.face_size = 8;
            d.layered_em.iterations = 20;
            r = refl_frame_create(24, 18, &bd.allocator, &f);
            if (r == REFL_OK) r = refl_renderer_create(s, &d, &rr);
            for (frame = 0; r == REFL_OK && frame < 2; ++frame) {
                refl_view v = s->camera;
                v.width = 24;
                v.height = 18;
                v.eye.x += 0.2f * (float)frame;
                r = refl_renderer_render(rr, &v, f);
            }
            cr_assert(r == REFL_OK || r == REFL_ERROR_OUT_OF_MEMORY, "%s, allocation %ld: %s",
                      refl_method_name((refl_method)m), k, refl_result_string(r));
            refl_renderer_destroy(rr);
            refl_frame_destroy(f);
            cr_assert_eq(c.allocs - c.frees, live, "%s, allocation %ld failed: %ld blocks leaked",
                         refl_method_name((refl_method)m), k, c.allocs - c.frees - live);
            failures += r != REFL_OK;
            done = c.failed == 0;
        }
        c.fail_at = 0;
        refl_scene_destroy(s);
        cr_assert_eq(c.allocs, c.frees);
        cr_assert(failures * stride > 20, "%s: only %ld failures", refl_method_name((refl_method)m), failures);
        cr_log_info("%s: %ld allocations failed in turn", refl_method_name((refl_method)m), failures);
    }
}

typedef struct bad_option {
    const char *rule;        /* what frame->message starts with */
    void (*set)(refl_render_desc *d);
} bad_option;

static void bad_method(refl_render_desc *d) { d->method = (refl_method)99; }
static void bad_threads(refl_render_desc *d) { d->threads = -1; }
static void too_many_threads(refl_render_desc *d) { d->threads = RAST_MAX_THREADS + 1; }
static void bad_depth(refl_render_desc *d) { d->depth = -2; }
static void bad_shadows(refl_render_desc *d) { d->lighting.shadows = 2; }
static void bad_soft(refl_render_desc *d) { d->lighting.soft_shadow_samples = 1025; }
static void bad_volumes(refl_render_desc *d) { d->lighting.light_volumes = -1; }
static void bad_caustics(refl_render_desc *d) { d->lighting.caustic_samples = 5000; }
static void bad_translucency(refl_render_desc *d) { d->lighting.translucency = NAN; }
static void bad_object_methods(refl_render_desc *d) { d->object_method_count = 3; }
static void bad_object_method(refl_render_desc *d) {
    static const refl_method m[2] = {REFL_SBC, (refl_method)-4};
    d->object_methods = m;
    d->object_method_count = 2;
}
static void bad_object_raytrace(refl_render_desc *d) {
    static const refl_method m[1] = {REFL_SBC};
    d->method = REFL_RAYTRACE;
    d->object_methods = m;
    d->object_method_count = 1;
}
static int never_occluded(void *user, refl_vec3 o, refl_vec3 dir, float tmin, float tmax) {
    (void)user; (void)o; (void)dir; (void)tmin; (void)tmax;
    return 0;
}
static void bad_caster(refl_render_desc *d) { d->raytrace.caster.occluded = never_occluded; }
static void bad_envmap(refl_render_desc *d) { d->envmap.size = 2049; }
static void bad_culling(refl_render_desc *d) { d->planar.no_culling = 7; }
static void bad_density(refl_render_desc *d) { d->c3rc.point_density = -1.0f; }
static void bad_leaf(refl_render_desc *d) { d->c3rc.kd_leaf_points = -5; }
static void bad_splat(refl_render_desc *d) { d->c3rc.max_splat = 65; }
static void bad_split(refl_render_desc *d) { d->c3rc.camera_split_px = INFINITY; }
static void bad_error(refl_render_desc *d) { d->sbc.error_px = -0.5f; }
static void bad_factor(refl_render_desc *d) { d->sbc.ray_factor = 65; }
static void bad_batch(refl_render_desc *d) { d->sbc.batch_groups = 255; }
static void bad_fallback(refl_render_desc *d) { d->sbc.trace_fallback = 2; }
static void bad_mixed(refl_render_desc *d) { d->sbc.mixed_levels = 7; }
static void bad_morphs(refl_render_desc *d) { d->sbc.morph_count = 1; }
static void bad_points_last(refl_render_desc *d) { d->debug.points_last = 3; }

static const bad_option bad_options[] = {
    {"method:", bad_method},
    {"threads:", bad_threads},
    {"threads:", too_many_threads},
    {"depth:", bad_depth},
    {"lighting.shadows:", bad_shadows},
    {"lighting.soft_shadow_samples:", bad_soft},
    {"lighting.light_volumes:", bad_volumes},
    {"lighting.caustic_samples:", bad_caustics},
    {"lighting.translucency:", bad_translucency},
    {"object_methods:", bad_object_methods},
    {"object_methods:", bad_object_method},
    {"object_methods:", bad_object_raytrace},
    {"raytrace.caster:", bad_caster},
    {"envmap.size:", bad_envmap},
    {"planar.no_culling:", bad_culling},
    {"c3rc.point_density:", bad_density},
    {"c3rc.kd_leaf_points:", bad_leaf},
    {"c3rc.max_splat:", bad_splat},
    {"c3rc.camera_split_px:", bad_split},
    {"sbc.error_px:", bad_error},
    {"sbc.ray_factor:", bad_factor},
    {"sbc.batch_groups:", bad_batch},
    {"sbc.trace_fallback:", bad_fallback},
    {"sbc.mixed_levels:", bad_mixed},
    {"sbc.morphs:", bad_morphs},
    {"debug.points_last:", bad_points_last},
};

/* Every bad option value makes refl_render, refl_renderer_create and
   refl_validate_render_desc refuse the desc, naming the option, whatever
   the method (options of methods not used are checked too). */
Test(refl_contract, every_bad_option_is_refused_by_name) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 16, 12);
    refl_frame *f = NULL;
    size_t i;
    int m;
    cr_assert_eq(refl_frame_create(16, 12, NULL, &f), REFL_OK);
    for (m = REFL_DIRECT; m < REFL_METHOD_COUNT; ++m)
        for (i = 0; i < sizeof bad_options / sizeof bad_options[0]; ++i) {
            refl_render_desc d = tu_refl_one_bounce((refl_method)m, 1);
            refl_renderer *rr = NULL;
            const char *why = NULL;
            bad_options[i].set(&d);
            cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT, "%s", bad_options[i].rule);
            cr_assert(why && !strncmp(why, bad_options[i].rule, strlen(bad_options[i].rule)),
                      "%s: expected a message naming %s, got \"%s\"", refl_method_name((refl_method)m),
                      bad_options[i].rule, why);
            cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT, "%s", bad_options[i].rule);
            cr_assert_str_eq(f->message, why);
            cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_ERROR_INVALID_ARGUMENT);
            cr_assert_null(rr);
        }
    /* the defaults are valid, and a good frame clears the message */
    cr_assert_eq(refl_validate_render_desc(NULL, NULL), REFL_OK);
    cr_assert_eq(refl_render(s, &v, NULL, f), REFL_OK);
    cr_assert_str_eq(f->message, "");
    /* a bad view is named too */
    v.fovy_degrees = 180.0f;
    cr_assert_eq(refl_render(s, &v, NULL, f), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert(!strncmp(f->message, "view.fovy_degrees:", 18), "%s", f->message);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* stats.depth: the bounces asked (past a method's own, RAYTRACE's tracer
   colours the pixels), or 0 where DIRECT draws a reflector; what the bench
   compares against truth of. */
Test(refl_contract, every_frame_says_the_depth_it_shows) {
    static const struct { refl_method m; int asked, shown; } rows[] = {
        {REFL_DIRECT, 3, 0},  {REFL_RAYTRACE, 3, 3}, {REFL_RAYTRACE, 0, REFL_DEFAULT_DEPTH},
        {REFL_ENVMAP, 3, 3},  {REFL_C3RC, 3, 3},     {REFL_PLANAR, 3, 3},
        {REFL_SBC, 3, 3},     {REFL_SBC, 12, 12},
    };
    size_t k;
    for (k = 0; k < sizeof rows / sizeof rows[0]; ++k) {
        refl_view v;
        refl_scene *s = tu_refl_builtin("mirror-room", &v, 16, 12);
        refl_render_desc d = tu_refl_one_bounce(rows[k].m, 1);
        refl_frame *f;
        d.depth = rows[k].asked;
        f = tu_refl_render(s, &v, &d);
        cr_assert_eq(f->stats.depth, rows[k].shown, "%s asked %d: %d", refl_method_name(rows[k].m), rows[k].asked,
                     f->stats.depth);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
}

/* A one-bounce method asked for more: the pixels whose path meets a
   reflector past its bounce take RAYTRACE's colour (the same tracer, so
   the same floats), while every point stays the method's own, as at
   depth 1, so the metrics measure the method. */
Test(refl_contract, bounces_past_a_method_s_own_are_traced) {
    static const refl_method one_bounce[] = {REFL_ENVMAP, REFL_C3RC, REFL_SPOC, REFL_GRAPHCAM};
    refl_view v;
    refl_scene *s = tu_refl_builtin("mirror-room", &v, 48, 36);
    refl_render_desc td = tu_refl_one_bounce(REFL_RAYTRACE, 2);
    refl_frame *truth;
    size_t k, i, n = (size_t)v.width * (size_t)v.height;
    td.depth = 3;
    truth = tu_refl_render(s, &v, &td);
    for (k = 0; k < sizeof one_bounce / sizeof one_bounce[0]; ++k) {
        refl_render_desc d = tu_refl_one_bounce(one_bounce[k], 2);
        refl_frame *one = tu_refl_render(s, &v, &d), *three;
        long long same = 0, traced;
        const char *name = refl_method_name(one_bounce[k]);
        d.depth = 3;
        three = tu_refl_render(s, &v, &d);
        cr_assert_eq(one->stats.traced_beyond, 0, "%s at depth 1", name);
        /* past one bounce: RAYTRACE's pixels, by refl__trace_beyond or by the
           method's own hand-over (C3RC's gaps, what SPOC's and GRAPHCAM's
           impostors cannot answer) */
        traced = three->stats.traced_beyond + three->stats.c3rc.traced + three->stats.graphcam.traced +
                 three->stats.spoc.traced;
        cr_assert_gt(traced, (long long)(n / 10), "%s: %lld traced of %zu", name, traced, n);
        for (i = 0; i < n; ++i) {
            same += three->stencil[i] && !memcmp(three->rgba + 4 * i, truth->rgba + 4 * i, 3 * sizeof(float));
            cr_assert(!memcmp(three->points + 3 * i, one->points + 3 * i, 3 * sizeof(float)),
                      "%s: pixel %zu shows another point at depth 3", name, i);
        }
        cr_assert_geq(same, traced, "%s: %lld pixels of RAYTRACE's colour, %lld traced", name, same, traced);
        refl_frame_destroy(one);
        refl_frame_destroy(three);
    }
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* The impostor methods where their impostors cannot answer: GRAPHCAM's
   one-frustum default, whose reflected rays leave the frustum (the mirror
   room's floor reflection) or meet a mirror it leaves out (the concave
   bowl meeting itself), and SPOC, whose march misses the ball at the
   bowl's focus near its pole. Those pixels go to RAYTRACE's tracer, so no
   reflector pixel shows the environment where RAYTRACE's reflected ray
   meets the scene; the same bytes on 1 and 3 threads. */
Test(refl_contract, what_an_impostor_cannot_answer_is_traced_not_the_environment, .timeout = 120) {
    static const char *const scenes[] = {"concave", "mirror-room"};
    static const refl_method methods[] = {REFL_GRAPHCAM, REFL_SPOC};
    size_t k, m;
    for (k = 0; k < sizeof scenes / sizeof scenes[0]; ++k) {
        refl_view v;
        refl_scene *s = tu_refl_builtin(scenes[k], &v, 96, 72);
        refl_render_desc td = tu_refl_one_bounce(REFL_RAYTRACE, 2);
        refl_frame *truth = tu_refl_render(s, &v, &td);
        for (m = 0; m < sizeof methods / sizeof methods[0]; ++m) {
            refl_render_desc d = tu_refl_one_bounce(methods[m], 1);
            refl_frame *f, *f3;
            refl_reflection_error re;
            size_t i, n = (size_t)v.width * (size_t)v.height;
            long long met = 0, sky = 0, traced;
            const char *name = refl_method_name(methods[m]);
            d.spoc.size = 64; /* mirror-room: an impostor per teapot and wall */
            f = tu_refl_render(s, &v, &d);
            for (i = 0; i < n; ++i) {
                /* a reflector in both (at an edge the rasteriser and the tracer may differ) */
                if (!truth->stencil[i] || !f->stencil[i] || isnan(truth->points[3 * i])) continue;
                ++met;
                sky += isnan(f->points[3 * i]);
            }
            traced = f->stats.graphcam.traced + f->stats.spoc.traced;
            cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &re), REFL_OK);
            cr_log_info("%s, %s: %lld reflector pixels meet the scene in RAYTRACE, %lld of them show the environment; "
                        "%lld traced; reflection error mean %.3f px, wrong %.4f, empty %.4f",
                        scenes[k], name, met, sky, traced, re.mean, re.wrong, re.empty);
            cr_assert_gt(met, 1000);
            cr_assert_eq(sky, 0, "%s, %s: %lld pixels show the environment where RAYTRACE meets the scene", scenes[k],
                         name, sky);
            cr_assert_gt(traced, 0, "%s, %s", scenes[k], name);
            cr_assert_eq(f->stats.traced_beyond, 0);
            d.threads = 3;
            f3 = tu_refl_render(s, &v, &d);
            cr_assert_eq(tu_refl_digest(f3), tu_refl_digest(f), "%s, %s: 3 threads give other bytes than 1",
                         scenes[k], name);
            refl_frame_destroy(f3);
            refl_frame_destroy(f);
        }
        refl_frame_destroy(truth);
        refl_scene_destroy(s);
    }
}

/* A frame of several methods shows every bounce asked, and 0 where one of
   them is DIRECT. */
Test(refl_contract, a_mixed_frame_shows_the_bounces_asked) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("mirror-room", &v, 16, 12);
    refl_method per_object[64];
    refl_render_desc d = tu_refl_one_bounce(REFL_PLANAR, 1);
    refl_frame *f;
    int i, first = -1;
    cr_assert_leq(s->object_count, 64);
    for (i = 0; i < s->object_count; ++i) {
        per_object[i] = REFL_METHOD_DEFAULT;
        if (first < 0 && s->materials[s->objects[i].material].type != REFL_DIFFUSE) first = i;
    }
    cr_assert_geq(first, 0);
    per_object[first] = REFL_ENVMAP;
    d.depth = 4;
    d.object_methods = per_object;
    d.object_method_count = s->object_count;
    f = tu_refl_render(s, &v, &d);
    cr_assert_eq(f->stats.depth, 4);
    refl_frame_destroy(f);
    per_object[first] = REFL_DIRECT;
    f = tu_refl_render(s, &v, &d);
    cr_assert_eq(f->stats.depth, 0);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}
