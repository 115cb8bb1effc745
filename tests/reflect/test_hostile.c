/* Hostile input to the newer API: LAYERED_EM's options at and past their
   limits, lenses that are degenerate or change under a renderer, and a
   prebuild asked for more maps than its memory budget. Each case: a clear
   error, or a finished opaque frame without NaN, in bounded memory. Small
   frames and few samples: these run in the sanitized binary too. */
#include <criterion/criterion.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>
#include "../../reflect.h"
#include "refl_test_util.h"

/* A floor, a box and (lens not NULL) a lens at the origin, seen from
   (0, 1, 5) at 40 x 30. */
static refl_scene *hostile_scene(refl_mesh *lens, int glass, refl_view *v) {
    refl_scene *s = NULL;
    refl_mesh *floor = NULL, *box = NULL;
    refl_material lm = glass ? refl_material_glass(1.5f) : refl_material_mirror(1.0f);
    refl_material d = refl_material_diffuse(0.7f, 0.5f, 0.3f);
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(20.0f, 4, NULL, &floor), REFL_OK);
    cr_assert_geq(refl_scene_add(s, floor, &d, refl_mat4_translate(refl_v3(0, -1.5f, 0))), 0);
    cr_assert_eq(refl_mesh_box(refl_v3(1, 1, 1), NULL, &box), REFL_OK);
    cr_assert_geq(refl_scene_add(s, box, &d, refl_mat4_translate(refl_v3(3, 0, 0))), 0);
    if (lens) cr_assert_geq(refl_scene_add(s, lens, &lm, refl_mat4_identity()), 0);
    refl_scene_complete(s);
    *v = tu_refl_view(refl_v3(0, 1, 5), refl_v3(0, 0, 0), 40, 30);
    return s;
}

static refl_mesh *hostile_sphere(void) {
    refl_mesh *m = NULL;
    cr_assert_eq(refl_mesh_sphere(1.0f, 16, 8, NULL, &m), REFL_OK);
    return m;
}

/* LAYERED_EM, one bounce, `samples` single-view samples. */
static refl_render_desc hostile_lem_desc(int samples) {
    refl_render_desc d = tu_refl_one_bounce(REFL_LAYERED_EM, 2);
    d.layered_em.samples = samples;
    d.layered_em.single_view = 1;
    return d;
}

/* Every pixel finite and opaque. */
static void assert_finished(const refl_frame *f, const char *what) {
    size_t n = (size_t)f->width * (size_t)f->height, i;
    int c;
    for (i = 0; i < n; ++i) {
        for (c = 0; c < 4; ++c) cr_assert(isfinite(f->rgba[4 * i + (size_t)c]), "%s: pixel %zu not finite", what, i);
        cr_assert_eq(f->rgba[4 * i + 3], 1.0f, "%s: pixel %zu not opaque", what, i);
    }
}

Test(hostile, layered_em_options_out_of_range_are_named) {
    static const struct {
        int field;
        int value;
        const char *message;
    } cases[] = {
        {0, 2, "layered_em.keep_stale_maps: 0 or 1"},
        {0, -1, "layered_em.keep_stale_maps: 0 or 1"},
        {1, -1, "layered_em.kept_mib: 0 (512) to 1048576"},
        {1, (1 << 20) + 1, "layered_em.kept_mib: 0 (512) to 1048576"},
    };
    size_t k;
    const char *why = NULL;
    for (k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        refl_render_desc d = hostile_lem_desc(4);
        if (cases[k].field == 0) d.layered_em.keep_stale_maps = cases[k].value;
        else d.layered_em.kept_mib = cases[k].value;
        cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT, "case %zu", k);
        cr_assert_str_eq(why, cases[k].message);
    }
    {
        refl_render_desc d = hostile_lem_desc(4);
        d.layered_em.keep_stale_maps = 1;
        d.layered_em.kept_mib = 1 << 20;
        cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_OK, "%s", why);
    }
}

/* A lens of one triangle, of collinear vertices, and with NaN normals: a
   frame either way. */
Test(hostile, degenerate_lenses_render_finished_frames, .timeout = 60) {
    static const float tri[9] = {-1, 0, 0, 1, 0, 0, 0, 1.5f, 0};
    static const float line[9] = {-1, 0, 0, 0, 0, 0, 1, 0, 0};
    static const float nan_normals[9] = {NAN, NAN, NAN, NAN, 0, 1, 0, 0, 1};
    const float *positions[3] = {tri, line, tri}, *normals[3] = {NULL, NULL, nan_normals};
    int k, glass;
    for (k = 0; k < 3; ++k)
        for (glass = 0; glass < 2; ++glass) {
            refl_mesh_desc md;
            refl_mesh *m = NULL;
            refl_render_desc d = hostile_lem_desc(4);
            refl_view v;
            refl_scene *s;
            refl_frame *f;
            memset(&md, 0, sizeof md);
            md.positions = positions[k];
            md.normals = normals[k];
            md.vertex_count = 3;
            cr_assert_eq(refl_mesh_create(&md, &m), REFL_OK);
            s = hostile_scene(m, glass, &v);
            f = tu_refl_render(s, &v, &d);
            assert_finished(f, "degenerate lens");
            refl_frame_destroy(f);
            refl_scene_destroy(s);
        }
}

/* t and the angle near 0 would split every triangle to max_level (4^12
   children each): the tessellation stops splitting at 16 vertices a pixel
   (the leaves' centre vertices on top: at most one each, two leaves a
   vertex or so). */
Test(hostile, a_tessellation_asked_for_everything_stays_bounded, .timeout = 60) {
    refl_view v;
    refl_scene *s = hostile_scene(hostile_sphere(), 1, &v);
    refl_render_desc d = hostile_lem_desc(1);
    refl_frame *f;
    d.layered_em.edge_px = 1e-6f;
    d.layered_em.angle_degrees = 1e-6f;
    f = tu_refl_render(s, &v, &d);
    cr_assert_gt(f->stats.layered_em.vertices, 0);
    cr_assert_leq(f->stats.layered_em.vertices, 3 * (16LL * v.width * v.height + s->meshes[2]->vertex_count), "%lld",
                  f->stats.layered_em.vertices);
    assert_finished(f, "the finest tessellation");
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* One renderer through lenses added and removed (kept stale maps too) and
   frames of other sizes. */
Test(hostile, a_renderer_follows_lenses_added_and_removed, .timeout = 60) {
    refl_view v, small;
    refl_scene *s = hostile_scene(hostile_sphere(), 0, &v);
    refl_material mirror = refl_material_mirror(1.0f);
    refl_mesh *second = NULL;
    refl_frame *f = NULL, *g = NULL;
    int stale;
    small = v;
    small.width = 17;
    small.height = 5;
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &f), REFL_OK);
    cr_assert_eq(refl_frame_create(small.width, small.height, NULL, &g), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(0.5f, 12, 6, NULL, &second), REFL_OK);
    cr_assert_geq(refl_scene_add(s, second, &mirror, refl_mat4_translate(refl_v3(-2, 0, 0))), 0);
    s->object_count--; /* the second lens held back: added and removed below */
    refl_scene_touch(s);
    for (stale = 0; stale < 2; ++stale) {
        refl_render_desc d = hostile_lem_desc(4);
        refl_renderer *rr = NULL;
        d.layered_em.keep_stale_maps = stale;
        cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
        cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK);
        s->object_count++;
        refl_scene_touch(s);
        cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK, "%s", f->message);
        assert_finished(f, "a lens added");
        cr_assert_eq(refl_renderer_render(rr, &small, g), REFL_OK, "%s", g->message);
        assert_finished(g, "a smaller frame");
        s->object_count -= 2; /* both lenses gone */
        refl_scene_touch(s);
        cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK, "%s", f->message);
        assert_finished(f, "the lenses removed");
        s->object_count++;
        refl_scene_touch(s);
        cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK, "%s", f->message);
        assert_finished(f, "a lens back");
        refl_renderer_destroy(rr);
    }
    refl_renderer_destroy(NULL);
    refl_frame_destroy(g);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* Prebuild stops short of layered_em.kept_mib however many samples are
   asked for, holding the samples nearest the eye: the frame there then
   infers nothing. */
Test(hostile, prebuild_keeps_to_the_map_budget, .timeout = 60) {
    refl_view v;
    refl_scene *s = hostile_scene(hostile_sphere(), 0, &v);
    refl_render_desc d = hostile_lem_desc(24);
    refl_renderer *rr = NULL;
    refl_frame *f = NULL;
    const long long map_bytes = 96LL * 64 * 64; /* one layer's six 64 x 64 faces, RGBA floats */
    d.layered_em.face_size = 64;
    d.layered_em.kept_mib = 1;
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &f), REFL_OK);
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_renderer_prebuild(rr, &v, f), REFL_OK, "%s", f->message);
    cr_assert_eq(f->stats.layered_em.maps_held, (int)((1LL << 20) / map_bytes), "as many maps as 1 MiB holds");
    cr_assert_leq(f->stats.model_bytes, 1LL << 20);
    cr_assert_eq(refl_renderer_render(rr, &v, f), REFL_OK);
    cr_assert_eq(f->stats.layered_em.maps_inferred, 0, "the eye's samples were built first");
    assert_finished(f, "after the prebuild");
    refl_renderer_destroy(rr);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* refl_lem_cluster_layers whatever the object numbers (each object's hits
   in one layer, in time of the hits, not of the largest number) and one
   ray's run however long; a distance not finite is refused. */
Test(hostile, layer_clustering_takes_any_object_numbers, .timeout = 60) {
    enum { N = 4096 };
    static float distance[N];
    static int object[N], ray[N], layer_of[N], first[64];
    float radius[REFL_LEM_MAX_LAYERS];
    int i, layers;
    for (i = 0; i < N; ++i) {
        distance[i] = (i % 2 ? 10.0f : 1.0f) + 0.001f * (float)(i % 100);
        object[i] = (i % 64) * 30000000; /* up to 1.9e9 */
        ray[i] = 7;                      /* one run of every hit */
    }
    layers = refl_lem_cluster_layers(distance, object, ray, N, 2, NULL, radius, layer_of);
    cr_assert_eq(layers, 2);
    for (i = 0; i < 64; ++i) first[i] = layer_of[i];
    for (i = 64; i < N; ++i) cr_assert_eq(layer_of[i], first[i % 64], "an object's hits in one layer");
    distance[N / 2] = NAN;
    cr_assert_eq(refl_lem_cluster_layers(distance, object, ray, N, 2, NULL, radius, layer_of), 0);
}

/* A shell's face side past 16384 would number its texels past uint32. */
Test(hostile, a_shell_too_large_to_number_is_refused) {
    refl_lem_shell sh;
    uint32_t texel[4];
    float weight[4];
    memset(&sh, 0, sizeof sh);
    sh.radius = 1.0f;
    sh.face_size = 16385;
    cr_assert_eq(refl_lem_shell_texels(&sh, refl_v3(0, 0, -1), texel, weight), 0);
    cr_assert_lt(refl_gl_pack_lem_shell(&sh, NULL, NULL, 0), 0);
    sh.face_size = 16384;
    cr_assert_eq(refl_lem_shell_texels(&sh, refl_v3(0, 0, -1), texel, weight), 1);
    cr_assert_lt(texel[3], 6u * 16384u * 16384u);
}

/* A sky of colour 1e30 at intensity 1e30: each number finite, their
   product past float's range. Every method returns a finished frame, the
   overflow drawn as FLT_MAX; LAYERED_EM's maps take no row from it (least
   squares needs finite targets). Fails on a frame holding inf, or on
   LAYERED_EM's INVALID_ARGUMENT from a row with an infinite target. */
Test(hostile, radiance_past_float_s_range_draws_the_largest_float, .timeout = 60) {
    int m, overflowed = 0;
    for (m = REFL_DIRECT; m < REFL_METHOD_COUNT; ++m) {
        refl_view v;
        refl_scene *s = tu_refl_builtin("default", &v, 16, 12);
        refl_render_desc d = tu_refl_one_bounce((refl_method)m, 2);
        refl_frame *f = NULL;
        refl_result r;
        size_t i;
        s->environment.color[2] = 1e30f;
        s->environment.intensity = 1e30f;
        if (m == REFL_LAYERED_EM) d.layered_em.samples = 8, d.spp = 4;
        cr_assert_eq(refl_frame_create(16, 12, NULL, &f), REFL_OK);
        r = refl_render(s, &v, &d, f);
        if (r == REFL_ERROR_UNSUPPORTED) {
            refl_frame_destroy(f);
            refl_scene_destroy(s);
            continue;
        }
        cr_assert_eq(r, REFL_OK, "%s: %s (%s)", refl_method_name((refl_method)m), refl_result_string(r), f->message);
        assert_finished(f, refl_method_name((refl_method)m));
        for (i = 0; i < 16 * 12; ++i) overflowed += f->rgba[4 * i + 2] == FLT_MAX;
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
    cr_assert_gt(overflowed, 0, "no pixel shows the sky past float's range");
}
