/* PLANAR (paper 002): planar mirrors through the stencil equal the
   ray-traced reference with the same shading at recursion depths 1 to 4,
   in the mirror room and from random cameras inside it; the renderings
   follow the paper's count (formula 5) without culling; mirrors seen
   edge-on, partly behind the camera or through another mirror's edge
   neither crash, nor give NaN, nor leak outside the mirrors. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

static int g_shadows; /* render() with shadows */

static refl_frame *render(const refl_scene *s, const refl_view *v, refl_method m, int depth, int no_culling,
                          int threads) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.lighting.shadows = g_shadows;
    d.method = m;
    d.depth = depth;
    d.planar.no_culling = no_culling;
    d.threads = threads;
    return tu_refl_render(s, v, &d);
}

/* The bar: PSNR >= 40 dB and >= 99.5% of mirror pixels within
   2/255 of RAYTRACE at the same depth; the points the mirrors show land
   where the reference shows them. */
static void expect_matches_reference(const refl_scene *s, const refl_view *v, int depth, const char *what) {
    refl_frame *planar = render(s, v, REFL_PLANAR, depth, 0, 2), *truth = render(s, v, REFL_RAYTRACE, depth, 0, 2);
    refl_image_error ie;
    refl_reflection_error re;
    cr_assert_eq(refl_measure_image_error(planar, truth, 1, 2.0f / 255.0f, &ie), REFL_OK);
    cr_assert_eq(refl_measure_reflection_error(planar, truth, NULL, &re), REFL_OK);
    cr_log_info("%s, depth %d: %lld mirror pixels, PSNR %.2f dB, %.4f%% over 2/255; reflection error mean %.3f px, "
                "max %.2f, wrong %.4f, holes %.4f; %lld renderings",
                what, depth, ie.pixels, ie.psnr, 100.0 * ie.over_threshold, re.mean, re.max, re.wrong, re.empty,
                planar->stats.planar.renderings);
    cr_assert(ie.pixels > 1000, "%s: the view must show mirrors", what);
    cr_assert(ie.psnr >= 40.0, "%s, depth %d: PSNR %.2f dB < 40", what, depth, ie.psnr);
    cr_assert(ie.over_threshold <= 0.005, "%s, depth %d: %.3f%% of mirror pixels over 2/255", what, depth,
              100.0 * ie.over_threshold);
    cr_assert(re.mean < 0.05 && re.wrong < 0.001 && re.empty < 0.001, "%s, depth %d: reflection error %.3f px", what,
              depth, re.mean);
    refl_frame_destroy(planar);
    refl_frame_destroy(truth);
}

Test(refl_planar, mirror_room_equals_the_reference_at_depths_1_to_4) {
    refl_scene *s;
    refl_view v;
    int depth;
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 200; v.height = 150;
    for (depth = 1; depth <= 4; ++depth) expect_matches_reference(s, &v, depth, "mirror-room");
    refl_scene_destroy(s);
}

/* Cameras the scene's author did not choose: anywhere inside the room,
   looking anywhere level-ish. */
Test(refl_planar, random_cameras_in_the_room_equal_the_reference) {
    refl_scene *s;
    refl_rng rng = refl_rng_seed(20261121);
    int k;
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    for (k = 0; k < 3; ++k) {
        refl_view v = s->camera;
        float a = 6.2831853f * refl_rng_float(&rng);
        char what[96];
        v.eye = refl_v3(-2.4f + 4.8f * refl_rng_float(&rng), 0.5f + 2.0f * refl_rng_float(&rng),
                        -2.4f + 4.8f * refl_rng_float(&rng));
        v.target = refl_v3_add(v.eye, refl_v3(cosf(a), -0.6f + 0.9f * refl_rng_float(&rng), sinf(a)));
        v.width = 160; v.height = 120;
        snprintf(what, sizeof what, "camera %d at %.2f,%.2f,%.2f", k, v.eye.x, v.eye.y, v.eye.z);
        expect_matches_reference(s, &v, 1 + k, what);
    }
    refl_scene_destroy(s);
}

/* Without culling every mirror is drawn at every level from every mirror
   but itself: num-ref-faces (num-ref-faces - 1)^(depth - 1) renderings at
   the deepest level (the paper's formula 5); culling mirrors not seen
   brings it down and changes no pixel. */
Test(refl_planar, renderings_follow_formula_5_without_culling) {
    refl_scene *s;
    refl_view v;
    int depth;
    long long expected = 4; /* the four wall mirrors */
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 64; v.height = 48;
    for (depth = 1; depth <= 4; ++depth) {
        refl_frame *all = render(s, &v, REFL_PLANAR, depth, 1, 2), *seen = render(s, &v, REFL_PLANAR, depth, 0, 2);
        long long total = 0, level = 4;
        int d;
        for (d = 1; d <= depth; ++d, level *= 3) total += level;
        cr_assert_eq(all->stats.planar.deepest, expected, "depth %d: %lld renderings at the deepest level, formula 5 says %lld",
                     depth, all->stats.planar.deepest, expected);
        cr_assert_eq(all->stats.planar.renderings, total, "depth %d: %lld renderings in all, want %lld", depth,
                     all->stats.planar.renderings, total);
        cr_log_info("depth %d: %lld renderings at the deepest level (formula 5), %lld with culling (%lld culled)",
                    depth, all->stats.planar.deepest, seen->stats.planar.deepest, seen->stats.planar.culled);
        cr_assert(seen->stats.planar.deepest < all->stats.planar.deepest || depth == 1);
        cr_assert_eq(tu_first_diff(all->rgba, seen->rgba, 4 * sizeof(float) * (size_t)v.width * (size_t)v.height), -1,
                     "depth %d: culling changed the image", depth);
        refl_frame_destroy(all);
        refl_frame_destroy(seen);
        expected *= 3;
    }
    refl_scene_destroy(s);
}

/* Past desc.planar.max_renderings the mirrors still to render are ray
   traced: the frame stays the reference's, with at most the budget of
   renderings (and the last one begun). */
Test(refl_planar, renderings_past_the_budget_are_ray_traced) {
    refl_scene *s;
    refl_view v;
    refl_render_desc d;
    refl_frame *budgeted, *truth;
    refl_image_error ie;
    refl_reflection_error re;
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 200; v.height = 150;
    memset(&d, 0, sizeof d);
    d.method = REFL_PLANAR;
    d.depth = 6;
    d.threads = 2;
    d.planar.no_culling = 1; /* 1456 renderings unbudgeted */
    d.planar.max_renderings = 12;
    budgeted = tu_refl_render(s, &v, &d);
    d.method = REFL_RAYTRACE;
    truth = tu_refl_render(s, &v, &d);
    cr_assert_leq(budgeted->stats.planar.renderings, 13, "%lld renderings", budgeted->stats.planar.renderings);
    cr_assert_gt(budgeted->stats.planar.traced, 1000, "%lld pixels traced", budgeted->stats.planar.traced);
    cr_assert_gt(budgeted->stats.rays, budgeted->stats.planar.traced);
    cr_assert_eq(refl_measure_image_error(budgeted, truth, 1, 2.0f / 255.0f, &ie), REFL_OK);
    cr_assert_eq(refl_measure_reflection_error(budgeted, truth, NULL, &re), REFL_OK);
    cr_assert(ie.psnr >= 40.0 && ie.over_threshold <= 0.005, "PSNR %.2f dB, %.3f%% over 2/255", ie.psnr,
              100.0 * ie.over_threshold);
    cr_assert(re.mean < 0.05 && re.wrong < 0.001 && re.empty < 0.001, "reflection error %.3f px", re.mean);
    refl_frame_destroy(budgeted);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

Test(refl_planar, same_bytes_for_every_thread_count) {
    refl_scene *s;
    refl_view v;
    refl_frame *one;
    int t, threads[] = {2, 3, 8};
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 97; v.height = 61;
    one = render(s, &v, REFL_PLANAR, 3, 0, 1);
    for (t = 0; t < 3; ++t) {
        refl_frame *other = render(s, &v, REFL_PLANAR, 3, 0, threads[t]);
        size_t n = (size_t)v.width * (size_t)v.height;
        cr_assert_eq(tu_first_diff(one->rgba, other->rgba, (4 * n) * sizeof(float)), -1, "%d threads: colour differs", threads[t]);
        cr_assert_eq(tu_first_diff(one->points, other->points, 12 * n), -1, "%d threads: points differ", threads[t]);
        refl_frame_destroy(other);
    }
    refl_frame_destroy(one);
    refl_scene_destroy(s);
}

/* Outside the planar mirrors PLANAR is DIRECT, byte for byte; nothing is
   NaN; a scene without planar mirrors (the default scene's teapot is
   curved) renders as DIRECT does. */
static void expect_confined(const refl_scene *s, const refl_view *v, int depth, const char *what) {
    refl_frame *direct = render(s, v, REFL_DIRECT, 0, 0, 2), *planar = render(s, v, REFL_PLANAR, depth, 0, 2);
    size_t i, n = (size_t)v->width * (size_t)v->height;
    long long leaks = 0;
    for (i = 0; i < n; ++i) {
        int mirror = direct->stencil[i] && s->materials[s->objects[direct->stencil[i] - 1].material].type == REFL_MIRROR;
        if (!mirror) leaks += memcmp(direct->rgba + 4 * i, planar->rgba + 4 * i, 4 * sizeof(float)) != 0;
        cr_assert(!isinf(planar->points[3 * i]), "%s: infinite point", what);
    }
    cr_assert_eq(leaks, 0, "%s: %lld pixels outside the mirrors changed", what, leaks);
    refl_frame_destroy(direct);
    refl_frame_destroy(planar);
}

Test(refl_planar, hard_views_stay_confined_to_the_mirrors) {
    refl_scene *s;
    refl_view v;
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 96; v.height = 72;
    /* edge-on: the eye in the plane of the back mirror (z = -3) */
    v.eye = refl_v3(0.0f, 1.5f, -3.0f);
    v.target = refl_v3(2.0f, 1.4f, -3.0f);
    expect_confined(s, &v, 3, "edge-on");
    /* a mirror partly behind the camera, seen at a grazing angle */
    v.eye = refl_v3(-2.9f, 1.0f, 0.5f);
    v.target = refl_v3(-2.9f, 1.0f, -2.0f);
    expect_confined(s, &v, 3, "partly behind");
    /* a corner: one mirror seen through another's edge */
    v.eye = refl_v3(1.0f, 1.2f, 1.0f);
    v.target = refl_v3(-3.0f, 1.2f, -3.0f);
    expect_confined(s, &v, 4, "corner");
    /* the eye just in front of a mirror, looking into it */
    v.eye = refl_v3(0.0f, 1.5f, -2.999f);
    v.target = refl_v3(0.0f, 1.5f, -4.0f);
    expect_confined(s, &v, 2, "nose on the glass");
    refl_scene_destroy(s);
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 64; v.height = 48;
    {
        /* a curved mirror is not planar: PLANAR hands it to the tracer
           (tests/reflect/test_renderer.c checks its pixels) */
        refl_frame *planar = render(s, &v, REFL_PLANAR, 2, 0, 2);
        cr_assert_eq(planar->stats.planar.renderings, 0);
        cr_assert_eq(planar->stats.handed_over, 1);
        refl_frame_destroy(planar);
    }
    refl_scene_destroy(s);
}

Test(refl_planar, allocation_failure_at_every_allocation_leaks_nothing) {
    tu_alloc_counter c;
    refl_builtin_desc bd;
    refl_scene *s;
    refl_view v;
    refl_frame *f;
    refl_render_desc d = tu_refl_desc(REFL_PLANAR, 2);
    memset(&c, 0, sizeof c);
    memset(&bd, 0, sizeof bd);
    bd.allocator = tu_refl_counting(&c);
    bd.teapot_tess = 4;
    cr_assert_eq(refl_scene_builtin("mirror-room", &bd, &s), REFL_OK);
    v = s->camera;
    v.width = 24; v.height = 16;
    cr_assert_eq(refl_frame_create(24, 16, NULL, &f), REFL_OK);
    d.depth = 2;
    tu_refl_fail_each_render_allocation(s, &v, &d, f, &c);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    cr_assert_eq(c.allocs, c.frees);
}

/* A glass slab before a striped wall: head on, the paper's parallel
   offset is nearly right (the axis's shift is zero, the pixels' own are
   small), and its error grows with the incidence angle, one shift standing
   in for every pixel's own; the log gives the curve. */
static refl_scene *slab_scene(void) {
    refl_scene *s;
    refl_mesh *m;
    refl_material mat;
    refl_object o;
    refl_light l;
    int k;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    memset(&l, 0, sizeof l);
    l.type = REFL_LIGHT_DIRECTIONAL;
    l.direction = refl_v3(0.3f, -0.5f, -1.0f);
    l.color[0] = l.color[1] = l.color[2] = 0.8f;
    refl_scene_add_light(s, &l);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 0.2f;
    s->environment.color[0] = 0.4f; s->environment.color[1] = 0.6f; s->environment.color[2] = 0.9f;
    for (k = 0; k < 12; ++k) { /* stripes 0.5 wide in z = -2 */
        memset(&mat, 0, sizeof mat);
        memset(&o, 0, sizeof o);
        mat.color[0] = k % 2 ? 0.9f : 0.1f; mat.color[1] = k % 3 ? 0.8f : 0.2f; mat.color[2] = k % 2 ? 0.2f : 0.7f;
        mat.color[3] = 1.0f;
        cr_assert_eq(refl_mesh_box(refl_v3(0.5f, 4.0f, 0.1f), NULL, &m), REFL_OK);
        o.mesh = refl_scene_add_mesh(s, m);
        o.material = refl_scene_add_material(s, &mat);
        o.transform = refl_mat4_translate(refl_v3(-2.75f + 0.5f * (float)k, 0.0f, -2.0f));
        refl_scene_add_object(s, &o);
    }
    memset(&mat, 0, sizeof mat);
    memset(&o, 0, sizeof o);
    mat.type = REFL_GLASS;
    mat.ior = 1.5f;
    cr_assert_eq(refl_mesh_box(refl_v3(2.0f, 2.0f, 0.4f), NULL, &m), REFL_OK);
    o.mesh = refl_scene_add_mesh(s, m);
    o.material = refl_scene_add_material(s, &mat);
    o.transform = refl_mat4_identity();
    refl_scene_add_object(s, &o);
    return s;
}

Test(refl_planar, slab_refraction_is_close_head_on_and_degrades_with_incidence) {
    refl_scene *s = slab_scene();
    int k, glass = s->object_count;
    double first = 0.0, last = 0.0;
    for (k = 0; k <= 6; ++k) {
        float a = (float)k * 10.0f * 3.14159265f / 180.0f;
        refl_view v;
        refl_frame *planar, *truth;
        refl_reflection_error re;
        size_t i, n;
        long long bad = 0, slab = 0;
        memset(&v, 0, sizeof v);
        v.eye = refl_v3(5.0f * sinf(a), 0.0f, 5.0f * cosf(a));
        v.target = refl_v3(0, 0, 0);
        v.up = refl_v3(0, 1, 0);
        v.width = 160; v.height = 120;
        planar = render(s, &v, REFL_PLANAR, 2, 0, 2);
        truth = render(s, &v, REFL_RAYTRACE, 2, 0, 2);
        cr_assert_eq(refl_measure_reflection_error(planar, truth, NULL, &re), REFL_OK);
        n = (size_t)v.width * (size_t)v.height;
        for (i = 0; i < n; ++i) {
            int c;
            cr_assert(!isinf(planar->points[3 * i]));
            if (truth->stencil[i] != glass) continue;
            ++slab;
            for (c = 0; c < 3; ++c) bad += abs((int)tu_unorm8(planar->rgba[4 * i + c]) - (int)tu_unorm8(truth->rgba[4 * i + c])) > 2;
        }
        cr_log_info("incidence %2d degrees: reflection error mean %.3f px, p95 %.3f, wrong %.4f, holes %.4f; "
                    "%.2f%% of slab channels over 2/255",
                    k * 10, re.mean, re.p95, re.wrong, re.empty, 100.0 * (double)bad / (double)(3 * slab));
        if (k == 0) first = re.mean;
        last = re.mean;
        refl_frame_destroy(planar);
        refl_frame_destroy(truth);
    }
    cr_assert(first < 0.5, "head on, the shift is zero: error %.3f px", first);
    cr_assert(last > first, "one shift for every pixel must cost something at 60 degrees (%.3f vs %.3f)", last, first);
    refl_scene_destroy(s);
}

/* A water surface (one glass plane, ior 1.33, nothing parallel beneath)
   over a floor, a box above it: the paper's refracted camera and
   quad-to-quad map. From below, the camera moving away from under the
   surface's centre crosses the critical angle (48.8 degrees, the paper's
   rule at the face's centre): refracted inside the cone (two renderings:
   refraction and reflection), wholly reflective beyond (one). No crash,
   no NaN, nothing changed outside the water. */
Test(refl_planar, water_surface_refracts_and_turns_to_a_mirror_past_the_critical_angle) {
    static const float grey[3] = {0.6f, 0.6f, 0.55f}, red[3] = {0.9f, 0.2f, 0.1f};
    refl_scene *s;
    refl_mesh *m;
    refl_light l;
    int k, water, refracted = 0, mirrored = 0;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(12.0f, 2, NULL, &m), REFL_OK);
    {
        refl_material mat;
        refl_object o;
        memset(&mat, 0, sizeof mat);
        memset(&o, 0, sizeof o);
        mat.color[0] = grey[0]; mat.color[1] = grey[1]; mat.color[2] = grey[2]; mat.color[3] = 1.0f;
        o.mesh = refl_scene_add_mesh(s, m);
        o.material = refl_scene_add_material(s, &mat);
        o.transform = refl_mat4_identity();
        refl_scene_add_object(s, &o);
        cr_assert_eq(refl_mesh_box(refl_v3(1, 1, 1), NULL, &m), REFL_OK);
        mat.color[0] = red[0]; mat.color[1] = red[1]; mat.color[2] = red[2];
        o.mesh = refl_scene_add_mesh(s, m);
        o.material = refl_scene_add_material(s, &mat);
        o.transform = refl_mat4_translate(refl_v3(0.5f, 3.5f, -0.5f));
        refl_scene_add_object(s, &o);
        memset(&mat, 0, sizeof mat);
        mat.type = REFL_GLASS;
        mat.ior = 1.33f;
        cr_assert_eq(refl_mesh_plane(6.0f, 1, NULL, &m), REFL_OK);
        o.mesh = refl_scene_add_mesh(s, m);
        o.material = refl_scene_add_material(s, &mat);
        o.transform = refl_mat4_translate(refl_v3(0, 2.0f, 0));
        water = refl_scene_add_object(s, &o);
    }
    memset(&l, 0, sizeof l);
    l.type = REFL_LIGHT_DIRECTIONAL;
    l.direction = refl_v3(0.2f, -1.0f, 0.3f);
    l.color[0] = l.color[1] = l.color[2] = 0.8f;
    refl_scene_add_light(s, &l);
    s->environment.color[0] = 0.4f; s->environment.color[1] = 0.6f; s->environment.color[2] = 0.9f;
    for (k = 0; k < 6; ++k) {
        refl_view v;
        refl_frame *f, *direct;
        size_t i, n;
        float x = 0.5f * (float)k; /* 0 to 68 degrees off the centre's vertical */
        memset(&v, 0, sizeof v);
        v.width = 64; v.height = 48;
        v.eye = refl_v3(x, 1.0f, 0.0f);
        v.target = refl_v3(0.0f, 2.0f, 0.0f);
        v.up = refl_v3(0, 0, -1);
        f = render(s, &v, REFL_PLANAR, 2, 0, 2);
        direct = render(s, &v, REFL_DIRECT, 0, 0, 2);
        n = (size_t)v.width * (size_t)v.height;
        for (i = 0; i < n; ++i) {
            cr_assert(!isinf(f->points[3 * i]), "view %d", k);
            if (direct->stencil[i] != water + 1)
                cr_assert_eq(memcmp(f->rgba + 4 * i, direct->rgba + 4 * i, 4 * sizeof(float)), 0, "view %d: outside the water", k);
        }
        refracted += f->stats.planar.renderings == 2;
        mirrored += f->stats.planar.renderings == 1;
        cr_log_info("%.1f from under the centre (%.0f degrees): %lld renderings", x,
                    atanf(x) * 180.0f / 3.14159265f, f->stats.planar.renderings);
        cr_assert_eq(f->stats.planar.renderings, atanf(x) < asinf(1.0f / 1.33f) ? 2 : 1, "view %d", k);
        refl_frame_destroy(f);
        refl_frame_destroy(direct);
    }
    cr_assert(refracted > 0 && mirrored > 0);
    refl_scene_destroy(s);
}

/* Shadows seen in the mirrors: stencil shadow volumes drawn through each
   mirrored camera agree with RAYTRACE's shadow rays. A mirror pixel whose
   colour is within 2/255 of the reference got both its light and its
   shadow right; the mirrors must show shadows for this to mean anything. */
Test(refl_planar, shadows_seen_in_the_mirrors_agree_with_the_reference) {
    refl_scene *s;
    refl_view v;
    int depth;
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 200; v.height = 150;
    for (depth = 1; depth <= 2; ++depth) {
        refl_frame *planar, *truth, *unshadowed;
        refl_image_error ie;
        size_t i, n = (size_t)v.width * (size_t)v.height;
        long long mirror = 0, in_shadow = 0;
        g_shadows = 1;
        planar = render(s, &v, REFL_PLANAR, depth, 0, 2);
        truth = render(s, &v, REFL_RAYTRACE, depth, 0, 2);
        g_shadows = 0;
        unshadowed = render(s, &v, REFL_RAYTRACE, depth, 0, 2);
        for (i = 0; i < n; ++i) {
            if (!truth->stencil[i]) continue;
            ++mirror;
            in_shadow += memcmp(truth->rgba + 4 * i, unshadowed->rgba + 4 * i, 3 * sizeof(float)) != 0;
        }
        cr_assert_eq(refl_measure_image_error(planar, truth, 1, 2.0f / 255.0f, &ie), REFL_OK);
        cr_log_info("shadows, depth %d: %lld of %lld mirror pixels show a shadow; PSNR %.2f dB, %.3f%% over 2/255",
                    depth, in_shadow, mirror, ie.psnr, 100.0 * ie.over_threshold);
        cr_assert(in_shadow > mirror / 20, "the mirrors must show shadows (%lld of %lld)", in_shadow, mirror);
        cr_assert(ie.over_threshold <= 0.01 && ie.psnr >= 40.0, "depth %d: %.3f%% of mirror pixels off, %.2f dB",
                  depth, 100.0 * ie.over_threshold, ie.psnr);
        refl_frame_destroy(planar);
        refl_frame_destroy(truth);
        refl_frame_destroy(unshadowed);
    }
    refl_scene_destroy(s);
}

/* The glass scene's slab (a box standing on the floor) at the CLI's depth:
   through its front face, the checker tiles behind it as RAYTRACE shows
   them. The levels seen through a slab must not meet the slab's own faces
   again (its in-out refraction already left by the far face); meeting its
   back face as a second interface bent the view off the tiles. */
Test(refl_planar, glass_scene_shows_the_tiles_through_the_slab) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("glass", &v, 160, 120);
    refl_frame *planar, *truth;
    size_t i, n = (size_t)v.width * (size_t)v.height;
    long long pixels = 0;
    double sum = 0.0, psnr;
    int slab = -1, k;
    for (k = 0; k < s->object_count; ++k)
        if (!strcmp(s->objects[k].name, "glass slab")) slab = k;
    cr_assert(slab >= 0);
    planar = render(s, &v, REFL_PLANAR, 6, 0, 2);
    truth = render(s, &v, REFL_RAYTRACE, 6, 0, 2);
    for (i = 0; i < n; ++i) {
        int c;
        if (truth->stencil[i] != slab + 1) continue; /* the stencil's k: object k - 1 */
        ++pixels;
        for (c = 0; c < 3; ++c) {
            double d = (tu_unorm8(planar->rgba[4 * i + c]) - tu_unorm8(truth->rgba[4 * i + c])) / 255.0;
            sum += d * d;
        }
    }
    psnr = sum > 0.0 ? -10.0 * log10(sum / (3.0 * (double)pixels)) : INFINITY;
    cr_log_info("glass slab: %lld pixels, PSNR %.2f dB against RAYTRACE at depth 6", pixels, psnr);
    cr_assert(pixels > 500, "the view must show the slab (%lld pixels)", pixels);
    cr_assert(psnr >= 15.0, "slab PSNR %.2f dB < 15: the tiles do not show through the slab", psnr);
    refl_frame_destroy(planar);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}
