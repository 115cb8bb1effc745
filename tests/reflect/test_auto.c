/* AUTO (m_auto.c, auto_model.c): per reflector, the cheapest method whose
   predicted error meets the budget; its models' text format. */
#define _POSIX_C_SOURCE 200809L /* mkstemp, fdopen */
#include <criterion/criterion.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "../../reflect.h"
#include "refl_test_util.h"

/* Models from text, asserting they parse. */
static refl_auto_models models_of(const char *text) {
    refl_auto_models m;
    char msg[200];
    refl_result r = refl_auto_models_parse(text, strlen(text), &m, msg, sizeof msg);
    cr_assert_eq(r, REFL_OK, "%s", msg);
    return m;
}

/* AUTO's choice for scene object `object` in frame f (asserting it made one). */
static const refl_auto_choice *choice_of(const refl_frame *f, int object) {
    int k;
    for (k = 0; k < f->stats.automatic.count && k < REFL_AUTO_MAX_CHOICES; ++k)
        if (f->stats.automatic.choices[k].object == object) return &f->stats.automatic.choices[k];
    cr_assert_fail("AUTO made no choice for object %d", object);
    return NULL;
}

static int first_reflector(const refl_scene *s) {
    int i;
    for (i = 0; i < s->object_count; ++i)
        if (s->materials[s->objects[i].material].type != REFL_DIFFUSE) return i;
    return -1;
}

Test(refl_auto, planar_mirrors_go_to_planar_by_the_built_in_models) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("mirror-room", &v, 96, 72);
    refl_render_desc d = tu_refl_one_bounce(REFL_AUTO, 2);
    refl_frame *f;
    int i, seen = 0;
    d.depth = 0;
    f = tu_refl_render(s, &v, &d);
    cr_assert_eq(f->stats.automatic.count, 4);
    for (i = 0; i < f->stats.automatic.count; ++i) {
        const refl_auto_choice *c = &f->stats.automatic.choices[i];
        cr_assert_eq(c->features.reflector_class, REFL_AUTO_PLANAR);
        if (!c->features.pixels) continue;
        seen++;
        cr_expect_eq(c->method, REFL_PLANAR, "wall %d (%lld px) went to %s", c->object, c->features.pixels,
                     refl_method_name(c->method));
        cr_expect(!c->over_budget);
    }
    cr_assert_geq(seen, 2);
    cr_expect_eq(f->stats.handed_over, 0);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* A mirror sphere with everything else far off has a nearness near 0 and
   no path past its bounce; a mirror wall in a room facing another, a
   nearness near 1/2 and about half its paths meeting a mirror again (as
   RAYTRACE's tracer counts them past ENVMAP's one bounce), none at depth 1. */
Test(refl_auto, nearness_and_beyond_tell_a_far_environment_from_a_room) {
    refl_scene *s = NULL, *room;
    refl_mesh *m = NULL;
    refl_material mirror = refl_material_mirror(0.9f), box = refl_material_diffuse(0.6f, 0.4f, 0.2f);
    refl_render_desc d = tu_refl_one_bounce(REFL_AUTO, 2);
    refl_view v = tu_refl_view(refl_v3(0.0f, 1.4f, 2.6f), refl_v3(0.0f, 1.0f, 0.0f), 64, 48);
    refl_frame *f, *one;
    const refl_auto_choice *c;
    long long pixels = 0;
    float share = 0.0f;
    int k;
    d.depth = 0;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(0.5f, 48, 24, NULL, &m), REFL_OK);
    cr_assert_geq(refl_scene_add(s, m, &mirror, refl_mat4_translate(refl_v3(0.0f, 1.0f, 0.0f))), 0);
    for (k = 0; k < 4; ++k) {
        cr_assert_eq(refl_mesh_box(refl_v3(2.0f, 2.0f, 2.0f), NULL, &m), REFL_OK);
        cr_assert_geq(refl_scene_add(s, m, &box, refl_mat4_translate(refl_v3(k & 1 ? 12.0f : -12.0f, 1.0f,
                                                                            k & 2 ? 12.0f : -12.0f))), 0);
    }
    refl_scene_complete(s);
    f = tu_refl_render(s, &v, &d);
    c = choice_of(f, 0);
    cr_expect_eq(c->features.reflector_class, REFL_AUTO_CONVEX);
    cr_expect_lt(c->features.nearness, 0.05f);
    cr_expect_gt(c->features.pixels, 100);
    cr_expect_eq(c->features.beyond, 0.0f);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    room = tu_refl_builtin("mirror-room", &v, 64, 48);
    f = tu_refl_render(room, &v, &d);
    cr_expect(f->stats.automatic.choices[0].features.nearness > 0.3f &&
                  f->stats.automatic.choices[0].features.nearness < 0.7f,
              "%g", (double)f->stats.automatic.choices[0].features.nearness);
    for (k = 0; k < f->stats.automatic.count; ++k) {
        c = &f->stats.automatic.choices[k];
        pixels += c->features.pixels;
        share += c->features.beyond * (float)c->features.pixels;
    }
    d.method = REFL_ENVMAP;
    one = tu_refl_render(room, &v, &d);
    cr_assert_gt(pixels, 0);
    cr_expect(fabsf(share / (float)pixels - (float)one->stats.traced_beyond / (float)pixels) < 0.15f,
              "beyond %g, traced past ENVMAP's bounce %g", (double)(share / (float)pixels),
              (double)one->stats.traced_beyond / (double)pixels);
    refl_frame_destroy(one);
    refl_frame_destroy(f);
    d.method = REFL_AUTO;
    d.depth = 1;
    f = tu_refl_render(room, &v, &d);
    for (k = 0; k < f->stats.automatic.count; ++k) cr_expect_eq(f->stats.automatic.choices[k].features.beyond, 0.0f);
    refl_frame_destroy(f);
    refl_scene_destroy(room);
}

/* With a model that makes ENVMAP cheap and exact, AUTO takes it, and its
   frame is the frame of ENVMAP given that reflector by hand. */
Test(refl_auto, a_cheap_model_picks_the_cheap_method_and_draws_as_it_would) {
    refl_auto_models m = models_of("reflect-auto-models 1\n"
                                   "model raytrace convex samples 1 cost 50 0 0 error 0 0 0\n"
                                   "model envmap convex samples 1 cost 1 0 0 error 0.1 0 0\n"
                                   "model planar convex samples 1 cost 0.5 0 0 error 0 0 0\n");
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 80, 60);
    refl_render_desc d = tu_refl_one_bounce(REFL_AUTO, 2);
    refl_method per[64];
    refl_frame *f, *g;
    const refl_auto_choice *c;
    int teapot = first_reflector(s), i;
    d.automatic.models = &m;
    f = tu_refl_render(s, &v, &d);
    cr_assert_eq(f->stats.automatic.count, 1);
    c = choice_of(f, teapot);
    cr_expect_eq(c->method, REFL_ENVMAP);
    cr_expect_float_eq(c->cost_ms[REFL_ENVMAP], 1.0f, 1e-6f);
    cr_expect_float_eq(c->error_px[REFL_ENVMAP], 0.1f, 1e-6f);
    cr_expect_eq(c->candidate[REFL_RAYTRACE], 1);
    cr_expect_eq(c->candidate[REFL_PLANAR], -1, "PLANAR cannot draw a teapot, cheap as it is");
    cr_expect_eq(c->candidate[REFL_C3RC], 0, "no model, no candidate");
    cr_expect_eq(f->stats.handed_over, 0);
    cr_expect_eq(f->stats.depth, 1);
    for (i = 0; i < s->object_count; ++i) per[i] = REFL_DIRECT;
    per[teapot] = REFL_ENVMAP;
    d.method = REFL_DIRECT;
    d.object_methods = per;
    d.object_method_count = s->object_count;
    g = tu_refl_render(s, &v, &d);
    cr_expect_eq(tu_refl_digest(f), tu_refl_digest(g));
    refl_frame_destroy(f);
    refl_frame_destroy(g);
    refl_scene_destroy(s);
}

Test(refl_auto, over_budget_takes_the_least_error_and_no_model_ray_traces) {
    refl_auto_models m = models_of("reflect-auto-models 1\n"
                                   "model envmap convex samples 1 cost 1 0 0 error 5 0 0\n"
                                   "model c3rc convex samples 1 cost 9 0 0 error 3 0 0\n"
                                   "model sbc convex samples 1 cost 4 0 0 error 3 0 0\n");
    refl_auto_models none;
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 64, 48);
    refl_render_desc d = tu_refl_one_bounce(REFL_AUTO, 2);
    refl_frame *f;
    const refl_auto_choice *c;
    d.automatic.models = &m;
    d.automatic.error_budget_px = 1.0f;
    f = tu_refl_render(s, &v, &d);
    c = choice_of(f, first_reflector(s));
    cr_expect_eq(c->method, REFL_SBC, "the least error (3 px), the cheaper of the two: %s", refl_method_name(c->method));
    cr_expect_eq(c->over_budget, 1);
    refl_frame_destroy(f);
    d.automatic.error_budget_px = 6.0f; /* now everything meets it: the cheapest */
    f = tu_refl_render(s, &v, &d);
    cr_expect_eq(choice_of(f, first_reflector(s))->method, REFL_ENVMAP);
    cr_expect_eq(choice_of(f, first_reflector(s))->over_budget, 0);
    refl_frame_destroy(f);
    memset(&none, 0, sizeof none);
    d.automatic.models = &none;
    f = tu_refl_render(s, &v, &d);
    cr_expect_eq(choice_of(f, first_reflector(s))->method, REFL_RAYTRACE);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

Test(refl_auto, the_frame_is_the_same_for_any_thread_count) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("glass", &v, 96, 72);
    refl_render_desc d = tu_refl_one_bounce(REFL_AUTO, 1);
    refl_frame *one, *more;
    int t;
    d.depth = 0;
    d.automatic.error_budget_px = 2.0f;
    one = tu_refl_render(s, &v, &d);
    cr_assert_eq(one->stats.automatic.count, 2);
    for (t = 0; t < 2; ++t) { /* glass goes to a method that draws glass */
        const refl_auto_choice *c = &one->stats.automatic.choices[t];
        cr_expect_eq(c->features.reflector_class, REFL_AUTO_GLASS);
        cr_expect_eq(c->candidate[c->method], 1, "%s", refl_method_name(c->method));
        cr_expect_leq(c->candidate[REFL_C3RC], 0, "C3RC declines glass");
    }
    cr_expect_eq(one->stats.handed_over, 0);
    for (t = 2; t <= 3; ++t) {
        d.threads = t;
        more = tu_refl_render(s, &v, &d);
        cr_expect_eq(tu_refl_digest(one), tu_refl_digest(more), "%d threads", t);
        cr_expect_eq(more->stats.automatic.count, one->stats.automatic.count);
        refl_frame_destroy(more);
    }
    refl_frame_destroy(one);
    refl_scene_destroy(s);
}

Test(refl_auto, models_round_trip_through_text_and_a_file) {
    refl_auto_models a, b;
    char *text, path[] = "/tmp/refl_auto_modelsXXXXXX", msg[200];
    size_t n;
    FILE *fp;
    int fd;
    a = models_of("reflect-auto-models 1\nmodel envmap convex samples 1 cost 1 2 3 4 error 5 6 7\n"
                  "model c3rc convex samples 1 cost 1 2 3 error 5 6 7\n");
    cr_expect(a.model[REFL_ENVMAP][REFL_AUTO_CONVEX].cost[3] == 4.0f &&
              a.model[REFL_ENVMAP][REFL_AUTO_CONVEX].error[0] == 5.0f);
    cr_expect(a.model[REFL_C3RC][REFL_AUTO_CONVEX].cost[3] == 0.0f, "a missing fourth cost term reads as 0");
    refl_auto_models_builtin(&a);
    cr_assert(a.model[REFL_RAYTRACE][REFL_AUTO_CONVEX].fitted, "the built-in fit models RAYTRACE");
    a.model[REFL_ENVMAP][REFL_AUTO_GLASS].error[2] = 1.0f / 3.0f; /* a float that needs nine digits */
    a.model[REFL_ENVMAP][REFL_AUTO_GLASS].cost[3] = 2.0f / 3.0f;
    a.model[REFL_ENVMAP][REFL_AUTO_GLASS].fitted = 1;
    n = refl_auto_models_format(&a, NULL, 0);
    cr_assert_gt(n, 20u);
    text = (char *)malloc(n + 1);
    cr_assert_eq(refl_auto_models_format(&a, text, n + 1), n);
    cr_assert_eq(strlen(text), n);
    cr_assert_eq(refl_auto_models_parse(text, n, &b, msg, sizeof msg), REFL_OK, "%s", msg);
    cr_expect_eq(memcmp(&a, &b, sizeof a), 0, "parsed back to other numbers");
    fd = mkstemp(path);
    cr_assert_geq(fd, 0);
    fp = fdopen(fd, "w");
    fprintf(fp, "# a comment\n\n%s", text);
    fclose(fp);
    memset(&b, 0, sizeof b);
    cr_assert_eq(refl_auto_models_load(path, &b, msg, sizeof msg), REFL_OK, "%s", msg);
    cr_expect_eq(memcmp(&a, &b, sizeof a), 0);
    unlink(path);
    cr_expect_eq(refl_auto_models_load(path, &b, msg, sizeof msg), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect(strstr(msg, path) && strstr(msg, "cannot be opened"), "%s", msg);
    free(text);
}

/* The fit built into auto_model.c is the one docs/methods/auto.md shows
   (reflect bench --fit-auto writes the file; its lines are pasted in). */
Test(refl_auto, the_built_in_models_are_the_documented_fit) {
    refl_auto_models builtin, file;
    char msg[200];
    refl_auto_models_builtin(&builtin);
    cr_assert_eq(refl_auto_models_load("docs/methods/auto_models.txt", &file, msg, sizeof msg), REFL_OK, "%s", msg);
    cr_expect_eq(memcmp(&builtin, &file, sizeof file), 0,
                 "auto_model.c's built-in fit differs from docs/methods/auto_models.txt");
}

Test(refl_auto, malformed_model_text_is_refused_naming_line_and_rule) {
    static const struct {
        const char *text, *says;
    } bad[] = {
        {"", "empty"},
        {"model raytrace convex samples 1 cost 1 0 0 error 0 0 0\n", "line 1: expected the header"},
        {"reflect-auto-models 2\n", "line 1: expected the header"},
        {"reflect-auto-models 1\nmodle raytrace convex\n", "line 2: 'modle': expected 'model'"},
        {"reflect-auto-models 1\nmodel raytraced convex samples 1 cost 1 0 0 error 0 0 0\n", "'raytraced': expected not a method"},
        {"reflect-auto-models 1\nmodel auto convex samples 1 cost 1 0 0 error 0 0 0\n", "does not draw reflectors"},
        {"reflect-auto-models 1\nmodel envmap round samples 1 cost 1 0 0 error 0 0 0\n", "'round': expected not a class"},
        {"reflect-auto-models 1\nmodel envmap convex samples 1 cost 1 0 error 0 0 0\n", "line 2: 'error': expected a finite number"},
        {"reflect-auto-models 1\nmodel envmap convex samples 1 cost 1 0 nan error 0 0 0\n", "'nan': expected a finite number"},
        {"reflect-auto-models 1\nmodel envmap convex samples 1 cost 1 0 1e999 error 0 0 0\n", "'1e999'"},
        {"reflect-auto-models 1\nmodel envmap convex samples 1.5 cost 1 0 0 error 0 0 0\n", "a whole count"},
        {"reflect-auto-models 1\nmodel envmap convex samples 1 cost 1 0 0 error 0 0 0 7\n", "'7': expected the end of the line"},
        {"reflect-auto-models 1\nmodel envmap convex samples 1 cost 1 0 0 2 3 error 0 0 0\n", "'3': expected 'error' after the costs"},
        {"reflect-auto-models 1\nmodel envmap convex samples 1 cost 1 0 0 error 0 0 0\n"
         "model envmap convex samples 1 cost 1 0 0 error 0 0 0\n", "line 3: 'convex': expected a second model"},
    };
    refl_auto_models m;
    char msg[200];
    size_t i;
    for (i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        memset(&m, 0xff, sizeof m);
        cr_expect_eq(refl_auto_models_parse(bad[i].text, strlen(bad[i].text), &m, msg, sizeof msg),
                     REFL_ERROR_INVALID_ARGUMENT, "case %zu accepted", i);
        cr_expect(strstr(msg, bad[i].says) != NULL, "case %zu: '%s' does not say '%s'", i, msg, bad[i].says);
        cr_expect(!m.model[REFL_ENVMAP][REFL_AUTO_CONVEX].fitted, "case %zu: refused models left behind", i);
    }
    cr_expect_eq(refl_auto_models_parse("reflect-auto-models 1\0model", 27, &m, msg, sizeof msg),
                 REFL_ERROR_INVALID_ARGUMENT);
    cr_expect(strstr(msg, "NUL") != NULL, "%s", msg);
}

Test(refl_auto, a_bad_budget_is_refused_by_name) {
    refl_render_desc d;
    const char *why = NULL;
    memset(&d, 0, sizeof d);
    d.method = REFL_AUTO;
    d.automatic.error_budget_px = -1.0f;
    cr_expect_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect(strstr(why, "automatic.error_budget_px") != NULL, "%s", why);
    d.automatic.error_budget_px = NAN;
    cr_expect_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    d.automatic.error_budget_px = 0.0f;
    cr_expect_eq(refl_validate_render_desc(&d, &why), REFL_OK);
}
