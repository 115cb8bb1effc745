/* The renderer that lives across frames, options validation that names
   the rule broken, and per-reflector dispatch. */
#include <criterion/criterion.h>
#include <stdint.h>
#include <stdio.h>

#include "../../reflect.h"
#include "refl_test_util.h"

/* Frame k of a camera path orbiting the scene's camera around its target. */
static refl_view path_view(const refl_scene *s, int k, int w, int h) {
    refl_view v = s->camera;
    refl_vec3 off = refl_v3_sub(v.eye, v.target);
    float a = 0.04f * (float)k, c = cosf(a), sn = sinf(a);
    v.eye = refl_v3_add(v.target, refl_v3(c * off.x + sn * off.z, off.y, -sn * off.x + c * off.z));
    v.width = w;
    v.height = h;
    return v;
}

/* Each frame of a camera path through one renderer renders refl_render's
   bytes, and the scene-wide models (BVH, C3RC's points and kd-tree) are
   built at the first frame only. */
#define PATH_FRAMES (tu_sanitized() ? 3 : 6) /* the plain runs take the whole path */
static void check_path(const char *scene, refl_render_desc d, int builds_first) {
    refl_view v;
    refl_scene *s = tu_refl_builtin(scene, &v, 64, 48);
    refl_renderer *rr = NULL;
    refl_frame *kept = NULL;
    int k;
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_frame_create(64, 48, NULL, &kept), REFL_OK);
    for (k = 0; k < PATH_FRAMES; ++k) {
        refl_view vk = path_view(s, k, 64, 48);
        refl_frame *fresh = tu_refl_render(s, &vk, &d);
        cr_assert_eq(refl_renderer_render(rr, &vk, kept), REFL_OK);
        cr_assert_eq(tu_refl_digest(kept), tu_refl_digest(fresh), "%s, %s, frame %d: the renderer's bytes differ from refl_render's",
                     scene, refl_method_name(d.method), k);
        cr_assert_eq(fresh->stats.scene_models_built, builds_first, "%s: refl_render builds %d models",
                     refl_method_name(d.method), fresh->stats.scene_models_built);
        cr_assert_eq(kept->stats.scene_models_built, k == 0 ? builds_first : 0, "%s, frame %d: %d models rebuilt",
                     refl_method_name(d.method), k, kept->stats.scene_models_built);
        refl_frame_destroy(fresh);
    }
    /* a new object rebuilds them (objects that only moved have the BVH
       refit: tests/reflect/test_bvh.c) */
    {
        refl_mesh *box;
        refl_material m = refl_material_diffuse(0.5f, 0.5f, 0.5f);
        cr_assert_eq(refl_mesh_box(refl_v3(0.1f, 0.1f, 0.1f), NULL, &box), REFL_OK);
        cr_assert(refl_scene_add(s, box, &m, refl_mat4_translate(refl_v3(0, -100, 0))) >= 0);
    }
    cr_assert_eq(refl_renderer_render(rr, &v, kept), REFL_OK);
    cr_assert_eq(kept->stats.scene_models_built, builds_first);
    refl_frame_destroy(kept);
    refl_renderer_destroy(rr);
    refl_scene_destroy(s);
}

Test(refl_renderer, a_camera_path_keeps_the_bvh_and_the_kd_tree, .timeout = 120) {
    refl_render_desc d = tu_refl_one_bounce(REFL_RAYTRACE, 2);
    d.depth = 0;
    check_path("default", d, 1);
    check_path("glass", d, 1);
    d.method = REFL_SBC;
    check_path("default", d, 1);
    d.sbc.trace_fallback = 1;
    check_path("concave", d, 1);
    d = tu_refl_one_bounce(REFL_C3RC, 2);
    d.c3rc.point_density = 25.0f; /* sparse and quick: what is kept is tested here, not accuracy */
    check_path("default", d, 2); /* the points, and the BVH that traces the gaps in them */
    d = tu_refl_one_bounce(REFL_ENVMAP, 2);
    check_path("default", d, 0);
    d.method = REFL_PLANAR;
    check_path("mirror-room", d, 0);
}

/* C3RC's view-dependent default density is fixed at the renderer's first
   frame: its first frame is refl_render's, and a later view keeps the
   first frame's points (refl_render would sample that view anew). */
Test(refl_renderer, c3rc_default_density_is_the_first_frames, .timeout = 120) {
    refl_view v0, v3;
    refl_scene *s = tu_refl_builtin("default", &v0, 64, 48);
    refl_render_desc d = tu_refl_one_bounce(REFL_C3RC, 2);
    refl_renderer *rr = NULL;
    refl_frame *first, *kept = NULL;
    v0 = path_view(s, 0, 64, 48);
    v3 = path_view(s, 3, 64, 48);
    first = tu_refl_render(s, &v0, &d);
    cr_assert(first->stats.c3rc.points > 1000);
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_frame_create(64, 48, NULL, &kept), REFL_OK);
    cr_assert_eq(refl_renderer_render(rr, &v0, kept), REFL_OK);
    cr_assert_eq(tu_refl_digest(kept), tu_refl_digest(first));
    cr_assert_eq(refl_renderer_render(rr, &v3, kept), REFL_OK);
    cr_assert_eq(kept->stats.c3rc.points, first->stats.c3rc.points, "the points were sampled again");
    cr_assert_eq(kept->stats.scene_models_built, 0);
    refl_frame_destroy(first);
    refl_frame_destroy(kept);
    refl_renderer_destroy(rr);
    refl_scene_destroy(s);
}

/* A planar mirror, a mirror sphere and a few diffuse objects. */
static refl_scene *two_mirrors(refl_view *v, int *plane, int *sphere) {
    refl_scene *s = NULL;
    refl_mesh *m = NULL;
    const float grey[3] = {0.9f, 0.9f, 0.9f}, red[3] = {0.8f, 0.2f, 0.1f}, blue[3] = {0.2f, 0.3f, 0.8f};
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(6.0f, 1, NULL, &m), REFL_OK);
    *plane = tu_refl_add_object(s, m, REFL_MIRROR, grey, refl_mat4_identity());
    cr_assert_eq(refl_mesh_sphere(0.8f, 32, 16, NULL, &m), REFL_OK);
    *sphere = tu_refl_add_object(s, m, REFL_MIRROR, grey, refl_mat4_translate(refl_v3(0.0f, 0.8f, 0.0f)));
    cr_assert_eq(refl_mesh_box(refl_v3(0.8f, 0.8f, 0.8f), NULL, &m), REFL_OK);
    tu_refl_add_object(s, m, REFL_DIFFUSE, red, refl_mat4_translate(refl_v3(1.6f, 0.4f, -0.8f)));
    cr_assert_eq(refl_mesh_torus(0.5f, 0.2f, 24, 12, NULL, &m), REFL_OK);
    tu_refl_add_object(s, m, REFL_DIFFUSE, blue, refl_mat4_translate(refl_v3(-1.5f, 0.3f, 0.9f)));
    tu_refl_add_point_light(s, refl_v3(2.0f, 5.0f, 3.0f), 1.0f, 0.0f);
    *v = tu_refl_view(refl_v3(0.5f, 2.6f, 5.0f), refl_v3(0.0f, 0.5f, 0.0f), 96, 72);
    return s;
}

/* One frame, each reflector its own method: each reflector's pixels are
   those a frame of its method alone gives it (one bounce), the rest
   DIRECT's (the base pass). (C3RC's density is set: its default follows the
   reflectors it draws.) */
Test(refl_renderer, each_reflector_with_its_own_method, .timeout = 60) {
    static const refl_method pairs[][2] = {{REFL_PLANAR, REFL_SBC}, {REFL_PLANAR, REFL_ENVMAP},
                                           {REFL_ENVMAP, REFL_C3RC}, {REFL_DIRECT, REFL_SBC},
                                           {REFL_PLANAR, REFL_RAYTRACE}};
    refl_view v;
    int plane, sphere, k;
    refl_scene *s = two_mirrors(&v, &plane, &sphere);
    refl_render_desc direct = tu_refl_one_bounce(REFL_DIRECT, 2);
    refl_frame *base = tu_refl_render(s, &v, &direct);
    for (k = 0; k < (int)(sizeof pairs / sizeof pairs[0]); ++k) {
        refl_method per_object[2];
        refl_render_desc d = tu_refl_one_bounce(pairs[k][0], 2);
        refl_frame *alone0, *alone1, *mixed;
        d.c3rc.point_density = 300.0f;
        alone0 = tu_refl_render(s, &v, &d);
        long long on[2] = {0, 0};
        int i;
        d.method = pairs[k][1];
        alone1 = tu_refl_render(s, &v, &d);
        per_object[plane] = pairs[k][0];
        per_object[sphere] = pairs[k][1];
        d.method = REFL_DIRECT;
        d.object_methods = per_object;
        d.object_method_count = 2;
        mixed = tu_refl_render(s, &v, &d);
        for (i = 0; i < v.width * v.height; ++i) {
            const refl_frame *want = !mixed->stencil[i] ? base : mixed->stencil[i] == plane + 1 ? alone0 : alone1;
            cr_assert_eq(mixed->stencil[i], alone0->stencil[i]);
            on[mixed->stencil[i] == plane + 1] += mixed->stencil[i] != 0;
            cr_assert_eq(memcmp(mixed->rgba + 4 * i, want->rgba + 4 * i, 4 * sizeof(float)), 0,
                         "%s + %s: pixel %d (stencil %d) differs from its method's own frame",
                         refl_method_name(pairs[k][0]), refl_method_name(pairs[k][1]), i, mixed->stencil[i]);
            cr_assert(tu_refl_same_point(mixed->points + 3 * i, want->points + 3 * i),
                      "%s + %s: pixel %d (stencil %d): point (%g %g %g), its method's own (%g %g %g)",
                      refl_method_name(pairs[k][0]), refl_method_name(pairs[k][1]), i, mixed->stencil[i],
                      mixed->points[3 * i], mixed->points[3 * i + 1], mixed->points[3 * i + 2], want->points[3 * i],
                      want->points[3 * i + 1], want->points[3 * i + 2]);
        }
        cr_assert(on[0] > 200 && on[1] > 200, "the view shows %lld sphere and %lld plane pixels", on[0], on[1]);
        refl_frame_destroy(alone0);
        refl_frame_destroy(alone1);
        refl_frame_destroy(mixed);
    }
    refl_frame_destroy(base);
    refl_scene_destroy(s);
}

/* A reflector PLANAR cannot draw (the default scene's curved teapot) is
   handed to RAYTRACE's tracer: its pixels are RAYTRACE's, colour and
   point, and the frame says one reflector was handed over. */
Test(refl_renderer, a_reflector_its_method_cannot_draw_is_ray_traced, .timeout = 60) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 96, 72);
    refl_render_desc d = tu_refl_one_bounce(REFL_PLANAR, 2);
    refl_frame *planar = tu_refl_render(s, &v, &d), *traced;
    long long on = 0;
    int i;
    d.method = REFL_RAYTRACE;
    traced = tu_refl_render(s, &v, &d);
    cr_assert_eq(planar->stats.handed_over, 1);
    cr_assert_eq(traced->stats.handed_over, 0);
    for (i = 0; i < v.width * v.height; ++i) {
        if (!planar->stencil[i]) continue;
        on++;
        cr_assert_eq(memcmp(planar->rgba + 4 * i, traced->rgba + 4 * i, 4 * sizeof(float)), 0, "pixel %d", i);
        cr_assert(tu_refl_same_point(planar->points + 3 * i, traced->points + 3 * i), "pixel %d: point", i);
    }
    cr_assert(on > 500, "%lld teapot pixels", on);
    refl_frame_destroy(planar);
    refl_frame_destroy(traced);
    refl_scene_destroy(s);
}

/* The progress callback: what it was told, and when to stop. */
typedef struct progress_log {
    int calls, stop_at; /* stop_at: the call that returns nonzero; 0: never */
    float last;
    int rising;         /* every report at least the one before */
} progress_log;

static int log_progress(void *user, float done) {
    progress_log *l = (progress_log *)user;
    if (done < l->last || !(done >= 0.0f && done <= 1.0f)) l->rising = 0;
    l->last = done;
    return ++l->calls == l->stop_at;
}

/* Every method reports progress from 0 to 1, rising, and renders the same
   bytes with a callback that never stops; a callback that stops at its
   first or its last-but-one report ends the render with
   REFL_ERROR_CANCELLED, saying so, and the renderer renders again after. */
Test(refl_renderer, the_progress_callback_reports_and_cancels, .timeout = 120) {
    int m;
    for (m = REFL_DIRECT; m < REFL_METHOD_COUNT; ++m) {
        refl_view v;
        refl_scene *s;
        refl_render_desc d;
        refl_frame *plain, *f;
        refl_renderer *rr;
        progress_log log;
        int stop, reports;
        if (!refl_method_is_built((refl_method)m)) continue;
        s = tu_refl_builtin(m == REFL_PLANAR ? "mirror-room" : "default", &v, 48, 36);
        d = tu_refl_one_bounce((refl_method)m, 2);
        cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &plain), REFL_OK);
        cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &f), REFL_OK);
        cr_assert_eq(refl_render(s, &v, &d, plain), REFL_OK);
        memset(&log, 0, sizeof log);
        log.rising = 1;
        d.progress = log_progress;
        d.progress_user = &log;
        cr_assert_eq(refl_render(s, &v, &d, f), REFL_OK);
        cr_expect(log.rising && log.last == 1.0f, "%s: reports rise to 1", refl_method_name((refl_method)m));
        cr_expect(log.calls >= 3, "%s: %d reports", refl_method_name((refl_method)m), log.calls);
        cr_expect_eq(memcmp(plain->rgba, f->rgba, sizeof(float) * 4 * (size_t)(v.width * v.height)), 0,
                     "%s: a callback changes no pixel", refl_method_name((refl_method)m));
        reports = log.calls;
        cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
        for (stop = 1; stop <= reports - 1; stop += reports - 2) {
            memset(&log, 0, sizeof log);
            log.stop_at = stop;
            cr_expect_eq(refl_renderer_render(rr, &v, f), REFL_ERROR_CANCELLED, "%s: stop at report %d",
                         refl_method_name((refl_method)m), stop);
            cr_expect_str_eq(f->message, "cancelled by the progress callback");
            cr_expect_eq(log.calls, stop, "no report after the stop");
        }
        memset(&log, 0, sizeof log);
        cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK);
        cr_expect_eq(memcmp(plain->rgba, f->rgba, sizeof(float) * 4 * (size_t)(v.width * v.height)), 0,
                     "%s: after a cancelled frame the renderer renders the same bytes", refl_method_name((refl_method)m));
        refl_renderer_destroy(rr);
        refl_frame_destroy(plain);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
}

/* A frame a renderer finished is the caller's: rendering the next frame
   (another frame, another view) leaves every byte of it as it was, for
   every method. */
Test(refl_renderer, a_finished_frame_is_left_alone_by_the_next, .timeout = 120) {
    int m;
    for (m = REFL_DIRECT; m < REFL_METHOD_COUNT; ++m) {
        refl_view v, w;
        refl_scene *s;
        refl_render_desc d;
        refl_frame *a, *b, *copy;
        refl_renderer *rr;
        size_t n;
        if (!refl_method_is_built((refl_method)m)) continue;
        s = tu_refl_builtin("default", &v, 40, 30);
        d = tu_refl_one_bounce((refl_method)m, 2);
        w = path_view(s, 5, 40, 30);
        n = (size_t)v.width * (size_t)v.height;
        cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &a), REFL_OK);
        cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &b), REFL_OK);
        cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &copy), REFL_OK);
        cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
        cr_assert_eq(refl_renderer_render(rr, &v, a), REFL_OK);
        memcpy(copy->rgba, a->rgba, n * 4 * sizeof(float));
        memcpy(copy->depth, a->depth, n * sizeof(float));
        memcpy(copy->stencil, a->stencil, n);
        cr_assert_eq(refl_renderer_render(rr, &w, b), REFL_OK);
        cr_expect_eq(memcmp(copy->rgba, a->rgba, n * 4 * sizeof(float)), 0, "%s: colour", refl_method_name((refl_method)m));
        cr_expect_eq(memcmp(copy->depth, a->depth, n * sizeof(float)), 0, "%s: depth", refl_method_name((refl_method)m));
        cr_expect_eq(memcmp(copy->stencil, a->stencil, n), 0, "%s: stencil", refl_method_name((refl_method)m));
        refl_renderer_destroy(rr);
        refl_frame_destroy(a);
        refl_frame_destroy(b);
        refl_frame_destroy(copy);
        refl_scene_destroy(s);
    }
}

/* layered_em.keep_stale_maps: a renderer keeps LAYERED_EM's maps through
   a scene change (the stale maps `reflect bench --only lem-sweeps`
   measures), where it would otherwise infer them again. */
Test(refl_renderer, layered_em_stale_maps_are_kept_when_asked, .timeout = 60) {
    refl_scene *s = NULL;
    refl_renderer *rr = NULL;
    refl_frame *f = NULL;
    refl_render_desc d;
    refl_view v;
    int held;
    memset(&d, 0, sizeof d);
    d.method = REFL_LAYERED_EM;
    d.threads = 2;
    d.layered_em.samples = 8;
    d.layered_em.keep_stale_maps = 1;
    cr_assert_eq(refl_scene_builtin("glass", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 48;
    v.height = 36;
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &f), REFL_OK);
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK);
    held = f->stats.layered_em.maps_held;
    cr_assert(held > 0 && f->stats.layered_em.maps_inferred == held);
    refl_scene_touch(s);
    cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK);
    cr_assert_eq(f->stats.layered_em.maps_inferred, 0, "the stale maps kept");
    cr_assert_eq(f->stats.layered_em.maps_kept, held);
    refl_frame_destroy(f);
    refl_renderer_destroy(rr);
    refl_scene_destroy(s);
}
