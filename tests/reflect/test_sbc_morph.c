/* SBC reflection morphing (paper 003, section VI): a grid of panoramic
   SBCs around one reflector, blended for the eye's tetrahedron. Small
   grids (one cell: 8 nodes, 6 tetrahedra) in the eye's neighbourhood and
   small images keep this fast; the bounds are what this build measured
   (in the comments) with some room, and the paper's 5 px for the
   blending error where it holds (the sphere; the teapot's knob seen in
   its lid is further off). */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

enum { MW = 96, MH = 72 };

static refl_render_desc method_desc(refl_method m, int threads) { return tu_refl_one_bounce(m, threads); }

/* A one-cell grid spanning [lo, hi] at face samples per cube face. */
static refl_sbc_morph_desc cell_desc(refl_vec3 lo, refl_vec3 hi, int face) {
    refl_sbc_morph_desc d;
    memset(&d, 0, sizeof d);
    d.nodes[0] = d.nodes[1] = d.nodes[2] = 2;
    d.region_lo = lo;
    d.region_hi = hi;
    d.face_size = face;
    d.threads = 2;
    return d;
}

static refl_sbc_morph *build(const refl_scene *s, int object, const refl_sbc_morph_desc *d) {
    refl_sbc_morph *m = NULL;
    refl_result r = refl_sbc_morph_build(s, object, d, &m);
    cr_assert_eq(r, REFL_OK, "refl_sbc_morph_build: %s", refl_result_string(r));
    cr_assert_not_null(m);
    return m;
}

/* The default scene's teapot (object 1) and a one-cell grid on the side
   of the default view. */
static const refl_vec3 teapot_lo = {-1.0f, 3.8f, 7.4f}, teapot_hi = {1.0f, 5.3f, 9.4f};

static refl_scene *teapot_scene(void) {
    refl_scene *s = NULL;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    cr_assert_eq(s->materials[s->objects[1].material].type, REFL_MIRROR);
    return s;
}

/* A floor, two diffuse boxes and a mirror sphere of radius 0.6 at the origin. */
static refl_scene *sphere_scene(void) {
    static const float grey[3] = {0.6f, 0.6f, 0.6f}, red[3] = {0.9f, 0.2f, 0.1f}, blue[3] = {0.2f, 0.3f, 0.9f},
                       silver[3] = {0.9f, 0.9f, 0.9f};
    refl_scene *s = NULL;
    refl_mesh *floor = NULL, *b0 = NULL, *b1 = NULL, *ball = NULL;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(12.0f, 8, NULL, &floor), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(0.8f, 1.2f, 0.8f), NULL, &b0), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(0.8f, 1.6f, 0.8f), NULL, &b1), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(0.6f, 48, 24, NULL, &ball), REFL_OK);
    tu_refl_add_object(s, floor, REFL_DIFFUSE, grey, refl_mat4_translate(refl_v3(0, -1.0f, 0)));
    tu_refl_add_object(s, b0, REFL_DIFFUSE, red, refl_mat4_translate(refl_v3(-2.2f, -0.4f, -1.5f)));
    tu_refl_add_object(s, b1, REFL_DIFFUSE, blue, refl_mat4_translate(refl_v3(2.0f, -0.2f, -1.8f)));
    tu_refl_add_object(s, ball, REFL_MIRROR, silver, refl_mat4_identity());
    tu_refl_add_point_light(s, refl_v3(3.0f, 5.0f, 4.0f), 1.0f, 0.0f);
    return s;
}

typedef struct morph_bounds {
    double mean, p95, max, wrong, holes;
} morph_bounds;

/* Renders SBC with the grid from eye, checks the frame is well formed, that
   the grid was used (its memory counts in the frame's model) and the error
   against RAYTRACE is within b. */
static void check_morph_view(const refl_scene *s, const refl_sbc_morph *m, refl_vec3 eye, refl_vec3 target,
                             const char *what, morph_bounds b) {
    const refl_sbc_morph *ms[1];
    refl_render_desc d = method_desc(REFL_SBC, 2), t = method_desc(REFL_RAYTRACE, 2), dd = method_desc(REFL_DIRECT, 2);
    refl_view v = tu_refl_view(eye, target, MW, MH);
    refl_frame *f, *truth, *direct;
    refl_reflection_error e;
    refl_sbc_morph_stats st;
    ms[0] = m;
    d.sbc.morphs = ms;
    d.sbc.morph_count = 1;
    f = tu_refl_render(s, &v, &d);
    truth = tu_refl_render(s, &v, &t);
    direct = tu_refl_render(s, &v, &dd);
    tu_assert_reflector_frame(f, direct);
    cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &e), REFL_OK);
    cr_log_info("morph %s: mean %.2f p95 %.2f max %.1f px, wrong %.3f, holes %.3f, %lld of %lld projected, %lld "
                "ambiguous", what, e.mean, e.p95, e.max, e.wrong, e.empty, f->stats.sbc.projected, f->stats.sbc.projections,
                f->stats.sbc.ambiguous);
    refl_sbc_morph_get_stats(m, &st);
    cr_assert(f->stats.model_bytes >= st.bytes, "%s: the grid was not used", what);
    cr_assert(f->stats.sbc.projected > 0, "%s: nothing projected", what);
    cr_assert(e.pixels > 200, "%s: %lld reflector pixels", what, e.pixels);
    cr_assert(e.mean <= b.mean && e.p95 <= b.p95 && e.max <= b.max, "%s: mean %.2f p95 %.2f max %.1f px", what, e.mean,
              e.p95, e.max);
    cr_assert(e.wrong <= b.wrong && e.empty <= b.holes, "%s: wrong %.3f holes %.3f", what, e.wrong, e.empty);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_frame_destroy(direct);
}

/* Measured (face 128, defaults: one ring extrapolated past the
   silhouettes, leaves widened by 0.1): mean 0.08 / 0.07 / 0.12, p95 1.0
   px, max 1.4 / 1.4 / 3.6 px (the paper's 5 px, asserted), wrong up to
   0.3%, holes 40 / 40 / 36%. History of this test's numbers:
   - one image per node and piece, every quad of a piece's map a unit
     frustum: mean 0.33 / 0.40 / 0.33, p95 1.4 / 2.2 / 1.4, max 4.2 / 7.0
     / 3.6 px, holes 31 / 27 / 26%; 7 px where the knob is seen in the lid;
   - each sheet blended apart: mean 0.22 / 0.30 / 0.25, p95 1.4, max 2.2
     / 7.0 / 4.5 px, holes 33 / 30 / 27%;
   - no unit frustum across a gap or crease (refl_sbc_desc.links; the
     knob before the lid is one mesh piece with it): the numbers above.
     The frustums between the knob's silhouette and the lid behind it held
     points neither reflects; without them the lid behind the knob, which
     the nodes do not see, is a hole where the eye sees it.
   Runtime mode at these eyes: mean 0.3-0.5, p95 1.4, holes 12-20%: the
   nodes' face maps are coarser than its ray maps and end at the pieces'
   creases and gaps, where runtime mode extends each group by a ring. */
Test(refl_sbc_morph, teapot_error_within_5px, .timeout = 120) {
    refl_scene *s = teapot_scene();
    refl_sbc_morph_desc md = cell_desc(teapot_lo, teapot_hi, 128);
    refl_sbc_morph *m = build(s, 1, &md);
    static const refl_vec3 eyes[3] = {{0.3f, 4.5f, 8.9f}, {-0.7f, 3.9f, 7.6f}, {0.8f, 5.1f, 8.2f}};
    morph_bounds b = {0.2, 1.0, 5.0, 0.02, 0.45};
    refl_sbc_morph_stats st;
    int k;
    refl_sbc_morph_get_stats(m, &st);
    cr_log_info("teapot grid: %d nodes, %d pieces, %d SBCs, %lld rays, %lld/%lld leaves, %lld KB, %.0f ms",
                st.nodes_built, st.pieces, st.sbcs, st.rays, st.pinhole_leaves, st.ray_leaves, st.bytes / 1024,
                st.ms_build);
    cr_assert_eq(st.nodes, 8);
    cr_assert_eq(st.nodes_built, 8);
    cr_assert_eq(st.tetrahedra, 6);
    cr_assert(st.pieces >= 2, "%d pieces: the teapot's parts come apart at its creases", st.pieces);
    for (k = 0; k < 3; ++k) {
        char what[32];
        snprintf(what, sizeof what, "teapot eye %d", k);
        check_morph_view(s, m, eyes[k], s->camera.target, what, b);
    }
    refl_sbc_morph_destroy(m);
    refl_scene_destroy(s);
}

/* The concave bowl folds its rays: seen from a node a point lies before
   and past the caustic, and the grid blends each sheet of the nodes'
   cameras apart. Measured (face 64): mean 3.7 / 3.8 / 3.3, p95 9.2 / 8.5
   / 7.1 px, wrong 11-15%, holes 2-3%. With one image per node and piece
   (the paper's projection) the mean was 30 / 37 / 25 px, p95 63-71 px.
   The max is not bounded here: 14 / 75 / 68 px, in the magnified image by
   the caustic, where many pixels show nearly one point (before: 69-77).
   Runtime mode at these eyes: mean 0.3 px; the nodes' own frames are
   1.6-2.8 px off at their eyes already (no check against the frame's ray
   map, whole pieces rather than tiles). */
Test(refl_sbc_morph, concave_bowl_blends_each_sheet, .timeout = 120) {
    refl_scene *s = NULL;
    refl_sbc_morph_desc md = cell_desc(refl_v3(-0.5f, 3.0f, 5.5f), refl_v3(0.5f, 4.0f, 6.5f), 64);
    refl_sbc_morph *m;
    static const refl_vec3 eyes[3] = {{0.0f, 3.5f, 6.0f}, {-0.3f, 3.2f, 5.7f}, {0.3f, 3.8f, 6.3f}};
    morph_bounds b = {4.5, 11.0, HUGE_VAL, 0.17, 0.05};
    int k;
    cr_assert_eq(refl_scene_builtin("concave", NULL, &s), REFL_OK);
    cr_assert_eq(s->materials[s->objects[1].material].type, REFL_MIRROR);
    m = build(s, 1, &md);
    for (k = 0; k < 3; ++k) {
        char what[32];
        snprintf(what, sizeof what, "concave eye %d", k);
        check_morph_view(s, m, eyes[k], s->camera.target, what, b);
    }
    refl_sbc_morph_destroy(m);
    refl_scene_destroy(s);
}

/* Measured: mean 0.29 / 0.10 / 0.10, p95 1.4 / 1.0 / 1.0 px, max 3 / 3 /
   2.2 px (the paper's 5 px bounds it), wrong up to 0.5%, holes 3 / 5 / 3%. */
Test(refl_sbc_morph, sphere_error_within_5px, .timeout = 120) {
    refl_scene *s = sphere_scene();
    refl_sbc_morph_desc md = cell_desc(refl_v3(-0.4f, 0.2f, 2.1f), refl_v3(0.4f, 0.8f, 2.9f), 128);
    refl_sbc_morph *m = build(s, 3, &md);
    static const refl_vec3 eyes[3] = {{0.0f, 0.5f, 2.5f}, {-0.25f, 0.3f, 2.2f}, {0.3f, 0.7f, 2.8f}};
    morph_bounds b = {0.5, 2.0, 5.0, 0.02, 0.1};
    refl_sbc_morph_stats st;
    int k;
    refl_sbc_morph_get_stats(m, &st);
    cr_assert_eq(st.pieces, 1);
    for (k = 0; k < 3; ++k) {
        char what[32];
        snprintf(what, sizeof what, "sphere eye %d", k);
        check_morph_view(s, m, eyes[k], refl_v3(0, -0.2f, -0.5f), what, b);
    }
    refl_sbc_morph_destroy(m);
    refl_scene_destroy(s);
}

/* Every vertex of every object of the scene, in world space (3 floats each). */
static float *scene_points(const refl_scene *s, int *count) {
    int o, n = 0;
    float *p;
    for (o = 0; o < s->object_count; ++o) n += refl_object_world_positions(s, o, NULL);
    p = (float *)malloc((size_t)n * 3 * sizeof(float));
    cr_assert_not_null(p);
    for (o = 0, n = 0; o < s->object_count; ++o) n += refl_object_world_positions(s, o, p + 3 * (size_t)n);
    cr_assert_eq(refl_object_world_positions(s, s->object_count, p), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_object_world_positions(NULL, 0, p), REFL_ERROR_INVALID_ARGUMENT);
    *count = n;
    return p;
}

/* An eye exactly at a node weighs it 1 and the others 0, and projects as
   that node's SBCs do, to the bit. */
Test(refl_sbc_morph, eye_at_a_node_is_that_node, .timeout = 60) {
    refl_scene *s = teapot_scene();
    refl_sbc_morph_desc md = cell_desc(teapot_lo, teapot_hi, 32);
    refl_sbc_morph *m = build(s, 1, &md);
    refl_sbc_morph_stats st;
    int n, i, piece, node[4], k, same = 0, corner;
    float *pts = scene_points(s, &n), w[4];
    refl_sbc_morph_get_stats(m, &st);
    for (corner = 0; corner < 8; ++corner) {
        int ci = corner & 1, cj = corner >> 1 & 1, ck = corner >> 2, at = -1;
        refl_vec3 eye;
        cr_assert(refl_sbc_morph_node(m, ci, cj, ck, &eye));
        cr_assert_geq(refl_sbc_morph_locate(m, eye, node, w), 0);
        for (k = 0; k < 4; ++k) {
            if (w[k] == 1.0f) at = node[k];
            else cr_assert_eq(w[k], 0.0f, "corner %d: weight %d is %g", corner, k, w[k]);
        }
        cr_assert_eq(at, (ck * 2 + cj) * 2 + ci, "corner %d: weight 1 on node %d", corner, at);
        for (piece = 0; piece < st.pieces; ++piece)
            for (i = 0; i < n; i += 7) {
                refl_vec3 p = refl_v3(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]), f1, f2;
                float d1 = 0.0f, d2 = 0.0f;
                int amb = -1, a = refl_sbc_morph_project(m, eye, piece, p, &f1, &d1, &amb);
                int b = refl_sbc_morph_project_node(m, ci, cj, ck, piece, p, &f2, &d2);
                cr_assert_eq(a, b, "corner %d piece %d vertex %d", corner, piece, i);
                cr_assert_eq(amb, 0, "one node of weight: nothing is ambiguous");
                if (!a) continue;
                cr_assert(f1.x == f2.x && f1.y == f2.y && f1.z == f2.z && d1 == d2, "corner %d vertex %d", corner, i);
                ++same;
            }
    }
    cr_log_info("%d projections at nodes equal their node's", same);
    cr_assert(same > 1000, "only %d vertices project at the nodes", same);
    /* just off the node, the blend moves off it continuously */
    {
        refl_vec3 eye;
        refl_sbc_morph_node(m, 0, 0, 0, &eye);
        eye.x += 1e-3f;
        cr_assert_geq(refl_sbc_morph_locate(m, eye, node, w), 0);
        cr_assert(w[0] < 1.0f && w[0] > 0.99f);
    }
    free(pts);
    refl_sbc_morph_destroy(m);
    refl_scene_destroy(s);
}

/* The paper's construction check (check_ambiguous): each node's unextended
   rays' heads and near-tail points, projected at the nodes sharing a
   tetrahedron. Measured at face 64: none 5723 of 17116, one ring past the
   silhouettes 4984, leaves widened by 0.5: 5703, both 4983. Widening helps
   little: most leaves of the teapot's face maps are ray lists, which it
   does not widen. The ring helped more (4285 of 5680) while unit frustums
   spanned creases: ring rays whose extrapolated normals turn more than 45
   degrees from their neighbours' covered points with frustums no ray
   reflects (at 288x216, 256-sample faces, eye 2: mean 2.8 px with them,
   0.6 without). (With the ring also past the pieces' other edges, where a
   fictional surface lies beside a real one, the count fell to 3512 but the
   teapot's p95 error at a node rose from 2 to 7 px.) */
static long long ambiguous_ends(const refl_scene *s, int rings, float widen, long long *checked) {
    refl_sbc_morph_desc md = cell_desc(teapot_lo, teapot_hi, 64);
    refl_sbc_morph *m;
    refl_sbc_morph_stats st;
    md.extend_rings = rings;
    md.widen = widen;
    md.check_ambiguous = 1;
    m = build(s, 1, &md);
    refl_sbc_morph_get_stats(m, &st);
    refl_sbc_morph_destroy(m);
    cr_log_info("rings %d widen %.2f: %lld of %lld ends ambiguous", rings, widen, st.ambiguous_ends, st.ends_checked);
    *checked = st.ends_checked;
    return st.ambiguous_ends;
}

Test(refl_sbc_morph, remedies_reduce_ambiguity, .timeout = 120) {
    refl_scene *s = teapot_scene();
    long long c0, c1, c2, c3, none = ambiguous_ends(s, -1, -1.0f, &c0), ring = ambiguous_ends(s, 1, -1.0f, &c1);
    long long wide = ambiguous_ends(s, -1, 0.5f, &c2), both = ambiguous_ends(s, 1, 0.5f, &c3);
    /* the same unextended rays are checked every time */
    cr_assert(c0 == c1 && c1 == c2 && c2 == c3 && c0 > 10000, "%lld %lld %lld %lld", c0, c1, c2, c3);
    cr_assert(none > c0 / 5, "without remedies %lld of %lld", none, c0);
    cr_assert(ring < none * 9 / 10, "extended reflectors: %lld against %lld", ring, none);
    cr_assert(wide < none, "widened leaves: %lld against %lld", wide, none);
    /* with a ring nearly every leaf is a ray list: widening them adds nothing */
    cr_assert(both <= ring, "both: %lld against one ring's %lld", both, ring);
    refl_scene_destroy(s);
}

/* Vertex ambiguity at render time is counted too, and static points'
   projections reused within the tetrahedron give the uncached bytes. */
Test(refl_sbc_morph, static_points_reuse_matches, .timeout = 60) {
    refl_scene *s = teapot_scene();
    refl_sbc_morph_desc md = cell_desc(teapot_lo, teapot_hi, 32);
    refl_sbc_morph *m = build(s, 1, &md);
    refl_sbc_morph_cache *cache = NULL;
    refl_vec3 *f0, *f1, eyes[2] = {{0.3f, 4.5f, 8.9f}, {0.35f, 4.45f, 8.85f}};
    float *d0, *d1, w[4];
    uint8_t *s0, *s1;
    int n, k, piece, t0, t1, node[4], projected = 0;
    float *pts = scene_points(s, &n);
    long long a0, a1, amb = 0;
    refl_sbc_morph_stats st;
    refl_sbc_morph_get_stats(m, &st);
    t0 = refl_sbc_morph_locate(m, eyes[0], node, w);
    t1 = refl_sbc_morph_locate(m, eyes[1], node, w);
    cr_assert(t0 >= 0 && t0 == t1, "one tetrahedron: %d %d", t0, t1);
    f0 = (refl_vec3 *)malloc((size_t)n * sizeof *f0);
    f1 = (refl_vec3 *)malloc((size_t)n * sizeof *f1);
    d0 = (float *)malloc((size_t)n * sizeof *d0);
    d1 = (float *)malloc((size_t)n * sizeof *d1);
    s0 = (uint8_t *)malloc((size_t)n);
    s1 = (uint8_t *)malloc((size_t)n);
    cr_assert(f0 && f1 && d0 && d1 && s0 && s1);
    cr_assert_eq(refl_sbc_morph_cache_create(NULL, &cache), REFL_OK);
    for (piece = 0; piece < st.pieces; ++piece)
        for (k = 0; k < 2; ++k) {
            int i;
            cr_assert_eq(refl_sbc_morph_project_points(m, eyes[k], piece, pts, n, cache, f0, d0, s0, &a0), REFL_OK);
            cr_assert_eq(refl_sbc_morph_project_points(m, eyes[k], piece, pts, n, NULL, f1, d1, s1, &a1), REFL_OK);
            cr_assert_eq(a0, a1);
            amb += a0;
            for (i = 0; i < n; ++i) {
                cr_assert_eq(s0[i], s1[i], "piece %d eye %d point %d", piece, k, i);
                if (s0[i] != 1) continue;
                ++projected;
                cr_assert(memcmp(&f0[i], &f1[i], sizeof f0[i]) == 0 && d0[i] == d1[i], "point %d", i);
            }
        }
    cr_log_info("%d projected, %lld ambiguous", projected, amb);
    cr_assert(projected > 1000 && amb > 0);
    refl_sbc_morph_cache_destroy(cache);
    refl_sbc_morph_cache_destroy(NULL);
    free(f0); free(f1); free(d0); free(d1); free(s0); free(s1); free(pts);
    refl_sbc_morph_destroy(m);
    refl_scene_destroy(s);
}

Test(refl_sbc_morph, bad_input, .timeout = 60) {
    refl_scene *s = teapot_scene();
    refl_sbc_morph_desc md = cell_desc(teapot_lo, teapot_hi, 8), bad;
    refl_sbc_morph *m = (refl_sbc_morph *)(void *)&md;
    refl_sbc_morph_cache *cache = NULL;
    refl_vec3 f, eye = {0.3f, 4.5f, 8.9f};
    float dist, w[4], pt[3] = {0, 1, 0};
    int node[4], amb = 7;
    uint8_t st8;
    long long a;
    refl_render_desc rd = method_desc(REFL_SBC, 1);
    refl_view v = tu_refl_view(eye, s->camera.target, 16, 12);
    refl_frame *fr = NULL;
    cr_assert_eq(refl_sbc_morph_build(NULL, 1, &md, &m), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(m);
    cr_assert_eq(refl_sbc_morph_build(s, 1, &md, NULL), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_sbc_morph_build(s, -1, &md, &m), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_sbc_morph_build(s, s->object_count, &md, &m), REFL_ERROR_INVALID_ARGUMENT);
    bad = md; bad.nodes[1] = 1;
    cr_assert_eq(refl_sbc_morph_build(s, 1, &bad, &m), REFL_ERROR_INVALID_ARGUMENT);
    bad = md; bad.nodes[2] = 65;
    cr_assert_eq(refl_sbc_morph_build(s, 1, &bad, &m), REFL_ERROR_INVALID_ARGUMENT);
    bad = md; bad.face_size = 3;
    cr_assert_eq(refl_sbc_morph_build(s, 1, &bad, &m), REFL_ERROR_INVALID_ARGUMENT);
    bad = md; bad.margin = -1.0f;
    cr_assert_eq(refl_sbc_morph_build(s, 1, &bad, &m), REFL_ERROR_INVALID_ARGUMENT);
    bad = md; bad.error_px = NAN;
    cr_assert_eq(refl_sbc_morph_build(s, 1, &bad, &m), REFL_ERROR_INVALID_ARGUMENT);
    bad = md; bad.widen = NAN;
    cr_assert_eq(refl_sbc_morph_build(s, 1, &bad, &m), REFL_ERROR_INVALID_ARGUMENT);
    bad = md; bad.region_hi.y = bad.region_lo.y;
    cr_assert_eq(refl_sbc_morph_build(s, 1, &bad, &m), REFL_ERROR_INVALID_ARGUMENT);
    bad = md; bad.region_lo.x = INFINITY;
    cr_assert_eq(refl_sbc_morph_build(s, 1, &bad, &m), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(m);
    {
        /* a triangle soup: every triangle a piece of its own */
        refl_scene *soup = NULL;
        refl_mesh *mesh = NULL;
        refl_mesh_desc sd;
        static const float grey[3] = {0.5f, 0.5f, 0.5f};
        float *pos = (float *)malloc(1100 * 9 * sizeof(float));
        int t;
        cr_assert_not_null(pos);
        for (t = 0; t < 1100; ++t) {
            float x = (float)(t % 40), y = (float)(t / 40), tri[9] = {0, 0, 0, 0.8f, 0, 0, 0, 0.8f, 0};
            int k;
            for (k = 0; k < 9; ++k) pos[9 * t + k] = tri[k] + (k % 3 == 0 ? x : k % 3 == 1 ? y : 0.0f);
        }
        memset(&sd, 0, sizeof sd);
        sd.positions = pos;
        sd.vertex_count = 3300;
        cr_assert_eq(refl_mesh_create(&sd, &mesh), REFL_OK);
        free(pos);
        cr_assert_eq(refl_scene_create(NULL, &soup), REFL_OK);
        tu_refl_add_object(soup, mesh, REFL_MIRROR, grey, refl_mat4_identity());
        cr_assert_eq(refl_sbc_morph_build(soup, 0, NULL, &m), REFL_ERROR_UNSUPPORTED);
        cr_assert_null(m);
        refl_scene_destroy(soup);
    }
    /* NULL-safe and harmless on NULL */
    refl_sbc_morph_destroy(NULL);
    refl_sbc_morph_get_stats(NULL, NULL);
    cr_assert_eq(refl_sbc_morph_object(NULL), -1);
    cr_assert_eq(refl_sbc_morph_node(NULL, 0, 0, 0, &f), 0);
    cr_assert_eq(refl_sbc_morph_locate(NULL, eye, node, w), -1);
    cr_assert_eq(refl_sbc_morph_piece_at(NULL, eye, refl_v3(0, 0, -1)), -1);
    cr_assert_eq(refl_sbc_morph_project(NULL, eye, 0, refl_v3(0, 1, 0), &f, &dist, &amb), 0);
    cr_assert_eq(amb, 0);
    cr_assert_eq(refl_sbc_morph_cache_create(NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
    /* a real grid, asked wrong */
    m = build(s, 1, &md);
    cr_assert_eq(refl_sbc_morph_object(m), 1);
    cr_assert_eq(refl_sbc_morph_node(m, 2, 0, 0, &f), 0);
    cr_assert_eq(refl_sbc_morph_node(m, 0, -1, 0, &f), 0);
    cr_assert_eq(refl_sbc_morph_locate(m, refl_v3(0, 0, 0), node, w), -1, "outside the grid");
    cr_assert_eq(refl_sbc_morph_locate(m, refl_v3(NAN, 4.5f, 8.0f), node, w), -1);
    cr_assert_eq(refl_sbc_morph_project(m, eye, -1, refl_v3(0, 1, 0), &f, &dist, NULL), 0);
    cr_assert_eq(refl_sbc_morph_project(m, eye, 99, refl_v3(0, 1, 0), &f, &dist, NULL), 0);
    cr_assert_eq(refl_sbc_morph_project(m, eye, 0, refl_v3(NAN, 1, 0), &f, &dist, &amb), 0);
    cr_assert_eq(refl_sbc_morph_project(m, refl_v3(0, 0, 0), 0, refl_v3(0, 1, 0), &f, &dist, &amb), 0);
    cr_assert_eq(refl_sbc_morph_project_node(m, 0, 0, 2, 0, refl_v3(0, 1, 0), &f, &dist), 0);
    cr_assert_eq(refl_sbc_morph_project_points(m, eye, 0, NULL, 1, NULL, &f, &dist, &st8, &a),
                 REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_sbc_morph_project_points(m, eye, 0, pt, -1, NULL, &f, &dist, &st8, &a),
                 REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_sbc_morph_project_points(m, eye, 5000, pt, 1, NULL, &f, &dist, &st8, &a),
                 REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_sbc_morph_project_points(m, refl_v3(0, 0, 0), 0, pt, 1, NULL, &f, &dist, &st8, &a),
                 REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_sbc_morph_project_points(m, eye, 0, pt, 0, NULL, NULL, NULL, NULL, NULL), REFL_OK);
    cr_assert_eq(refl_sbc_morph_cache_create(NULL, &cache), REFL_OK);
    cr_assert_eq(refl_sbc_morph_project_points(m, eye, 0, pt, 1, cache, &f, &dist, &st8, &a), REFL_OK);
    refl_sbc_morph_cache_destroy(cache);
    /* the render desc's grids */
    cr_assert_eq(refl_frame_create(16, 12, NULL, &fr), REFL_OK);
    rd.sbc.morph_count = 1;
    cr_assert_eq(refl_render(s, &v, &rd, fr), REFL_ERROR_INVALID_ARGUMENT);
    rd.sbc.morph_count = -1;
    cr_assert_eq(refl_render(s, &v, &rd, fr), REFL_ERROR_INVALID_ARGUMENT);
    {
        /* a NULL entry is skipped; an eye outside every tetrahedron draws per frame */
        const refl_sbc_morph *ms[2] = {NULL, m};
        rd.sbc.morphs = ms;
        rd.sbc.morph_count = 2;
        cr_assert_eq(refl_render(s, &v, &rd, fr), REFL_OK);
        cr_assert_eq(fr->stats.sbc.pinhole_leaves + fr->stats.sbc.ray_leaves, 0);
        v.eye = refl_v3(0.0f, 4.5f, 12.0f);
        cr_assert_eq(refl_render(s, &v, &rd, fr), REFL_OK);
        cr_assert(fr->stats.sbc.pinhole_leaves + fr->stats.sbc.ray_leaves > 0, "outside the grid: per-frame SBCs");
    }
    refl_frame_destroy(fr);
    refl_sbc_morph_destroy(m);
    refl_scene_destroy(s);
}

/* The same bytes for 1 and 2 threads: the grid's build and the frame. */
Test(refl_sbc_morph, same_bytes_for_thread_counts, .timeout = 120) {
    refl_scene *s = teapot_scene();
    refl_sbc_morph_desc md = cell_desc(teapot_lo, teapot_hi, 32);
    refl_sbc_morph *m1, *m2;
    refl_sbc_morph_stats a, b;
    const refl_sbc_morph *ms[1];
    refl_render_desc d1 = method_desc(REFL_SBC, 1), d2 = method_desc(REFL_SBC, 2);
    refl_view v = tu_refl_view(refl_v3(0.3f, 4.5f, 8.9f), s->camera.target, MW, MH);
    refl_frame *f1, *f2;
    size_t n = (size_t)MW * MH;
    md.threads = 1;
    m1 = build(s, 1, &md);
    md.threads = 2;
    m2 = build(s, 1, &md);
    refl_sbc_morph_get_stats(m1, &a);
    refl_sbc_morph_get_stats(m2, &b);
    cr_assert(a.rays == b.rays && a.bytes == b.bytes && a.pinhole_leaves == b.pinhole_leaves &&
              a.ray_leaves == b.ray_leaves && a.sbcs == b.sbcs);
    ms[0] = m1;
    d1.sbc.morphs = d2.sbc.morphs = ms;
    d1.sbc.morph_count = d2.sbc.morph_count = 1;
    f1 = tu_refl_render(s, &v, &d1);
    ms[0] = m2;
    f2 = tu_refl_render(s, &v, &d2);
    cr_assert_eq(memcmp(f1->rgba, f2->rgba, (4 * n) * sizeof(float)), 0, "colour differs");
    cr_assert_eq(memcmp(f1->depth, f2->depth, sizeof(float) * n), 0, "depth differs");
    cr_assert_eq(memcmp(f1->points, f2->points, 3 * sizeof(float) * n), 0, "points differ");
    cr_assert_eq(f1->stats.sbc.ambiguous, f2->stats.sbc.ambiguous);
    cr_assert(f1->stats.sbc.ambiguous > 0, "no ambiguous vertex counted");
    refl_frame_destroy(f1);
    refl_frame_destroy(f2);
    refl_sbc_morph_destroy(m1);
    refl_sbc_morph_destroy(m2);
    refl_scene_destroy(s);
}

/* refl_sbc_desc.widen (remedy (b)): a pinhole leaf projects a point a
   little beyond its frustum only when asked; 0 leaves it as runtime mode
   has it. Rays from one centre through a 5 x 5 grid of tails: one leaf. */
Test(refl_sbc_morph, widened_leaf_projects_beyond_its_frustum, .timeout = 30) {
    refl_sbc_ray rays[25];
    refl_sbc_desc d;
    refl_sbc *narrow = NULL, *wide = NULL;
    refl_vec3 c = {0.0f, 0.0f, -2.0f}, f, outside, inside;
    float z;
    int i;
    for (i = 0; i < 25; ++i) {
        refl_vec3 t = refl_v3(-1.0f + 0.5f * (float)(i % 5), -1.0f + 0.5f * (float)(i / 5), 0.0f);
        rays[i].tail = rays[i].first = t;
        rays[i].head = refl_v3_add(t, refl_v3_scale(refl_v3_normalize(refl_v3_sub(t, c)), 3.0f));
    }
    memset(&d, 0, sizeof d);
    d.width = d.height = 64;
    d.view_proj = refl_mat4_mul(refl_mat4_perspective(1.0f, 1.0f, 0.1f, 20.0f),
                                refl_mat4_look_at(refl_v3(0, 0, 5), refl_v3(0, 0, 0), refl_v3(0, 1, 0)));
    cr_assert_eq(refl_sbc_build(rays, NULL, 5, 5, &d, &narrow), REFL_OK);
    d.widen = 0.25f;
    cr_assert_eq(refl_sbc_build(rays, NULL, 5, 5, &d, &wide), REFL_OK);
    outside = refl_v3_add(refl_v3(1.2f, 0.0f, 0.0f), refl_v3_normalize(refl_v3_sub(refl_v3(1.2f, 0.0f, 0.0f), c)));
    inside = refl_v3_add(refl_v3(0.6f, 0.3f, 0.0f), refl_v3_normalize(refl_v3_sub(refl_v3(0.6f, 0.3f, 0.0f), c)));
    cr_assert_eq(refl_sbc_leaf_at(narrow, outside), REFL_SBC_LEAF_PINHOLE);
    cr_assert_eq(refl_sbc_project(narrow, outside, &f, &z), 0, "beyond the frustum");
    cr_assert_eq(refl_sbc_project(wide, outside, &f, &z), 1, "widened");
    cr_assert(fabsf(f.x - 1.2f) < 0.02f && fabsf(f.y) < 0.02f && fabsf(f.z) < 0.02f, "(%g %g %g)", f.x, f.y, f.z);
    {
        refl_vec3 f2;
        cr_assert(refl_sbc_project(narrow, inside, &f, &z) && refl_sbc_project(wide, inside, &f2, &z));
        cr_assert(f.x == f2.x && f.y == f2.y && f.z == f2.z, "inside, widening changes nothing");
    }
    refl_sbc_destroy(narrow);
    refl_sbc_destroy(wide);
    d.widen = -0.5f;
    cr_assert_eq(refl_sbc_build(rays, NULL, 5, 5, &d, &narrow), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_null(narrow);
}

/* A grid beside the higher orders (depth 2): a second mirror sphere sees
   the grid's sphere, and the grid's groups join the first layer. Every
   pixel of the second sphere, its own reflections and the grid's sphere
   seen in them, is the same with the grid as without (its groups, their
   indices moved on past the grid's, draw the same), and the frame is the
   same on 1 and 2 threads. */
Test(refl_sbc_morph, beside_higher_orders, .timeout = 120) {
    static const float silver[3] = {0.9f, 0.9f, 0.9f};
    refl_scene *s = sphere_scene();
    refl_mesh *ball = NULL;
    refl_sbc_morph_desc md = cell_desc(refl_v3(-0.4f, 0.2f, 2.1f), refl_v3(0.4f, 0.8f, 2.9f), 64);
    refl_sbc_morph *m;
    const refl_sbc_morph *ms[1];
    refl_render_desc plain = method_desc(REFL_SBC, 2), grid2, grid1;
    refl_view v = tu_refl_view(refl_v3(0.1f, 0.5f, 2.5f), refl_v3(0.4f, -0.1f, -0.5f), 160, 120);
    refl_frame *f0, *f2, *f1;
    size_t n = (size_t)v.width * (size_t)v.height, i;
    long long second = 0;
    int other;
    cr_assert_eq(refl_mesh_sphere(0.5f, 32, 16, NULL, &ball), REFL_OK);
    other = tu_refl_add_object(s, ball, REFL_MIRROR, silver, refl_mat4_translate(refl_v3(1.3f, -0.3f, 0.2f)));
    m = build(s, 3, &md);
    ms[0] = m;
    plain.depth = 2;
    grid2 = grid1 = plain;
    grid2.sbc.morphs = grid1.sbc.morphs = ms;
    grid2.sbc.morph_count = grid1.sbc.morph_count = 1;
    grid1.threads = 1;
    f0 = tu_refl_render(s, &v, &plain);
    f2 = tu_refl_render(s, &v, &grid2);
    f1 = tu_refl_render(s, &v, &grid1);
    cr_assert(f0->stats.sbc.histories > 2, "%d histories without the grid", f0->stats.sbc.histories);
    cr_assert(f2->stats.sbc.histories >= 2, "%d histories with the grid", f2->stats.sbc.histories);
    for (i = 0; i < n; ++i) {
        if (f0->stencil[i] != other + 1) continue;
        ++second;
        cr_assert_eq(memcmp(f0->rgba + 4 * i, f2->rgba + 4 * i, 4 * sizeof(float)), 0, "pixel %zu of the second sphere", i);
        cr_assert_eq(memcmp(f0->points + 3 * i, f2->points + 3 * i, 3 * sizeof(float)), 0, "pixel %zu", i);
    }
    cr_assert(second > 500, "%lld pixels of the second sphere", second);
    cr_assert_eq(memcmp(f1->rgba, f2->rgba, (4 * n) * sizeof(float)), 0, "colour differs across thread counts");
    cr_assert_eq(memcmp(f1->points, f2->points, 3 * sizeof(float) * n), 0, "points differ across thread counts");
    refl_frame_destroy(f0);
    refl_frame_destroy(f1);
    refl_frame_destroy(f2);
    refl_sbc_morph_destroy(m);
    refl_scene_destroy(s);
}

/* The ray-traced fallback (refl_render_desc.sbc.trace_fallback) fills
   morphing's holes too (36-40% of the teapot's pixels at these eyes: the
   nodes' face maps end at the pieces' creases and gaps): each pixel it
   changes is RAYTRACE's. A morph group has no ray map samples in the
   frame, so only its holes are traced. Measured: holes 40% -> 0.3%,
   mean 0.084 -> 0.050 px (126 pixels traced). */
Test(refl_sbc_morph, fallback_traces_the_holes, .timeout = 120) {
    refl_scene *s = teapot_scene();
    refl_sbc_morph_desc md = cell_desc(teapot_lo, teapot_hi, 128);
    refl_sbc_morph *m = build(s, 1, &md);
    const refl_sbc_morph *ms[1];
    refl_view v = tu_refl_view(refl_v3(0.3f, 4.5f, 8.9f), s->camera.target, MW, MH);
    refl_render_desc d = method_desc(REFL_SBC, 2), t = method_desc(REFL_RAYTRACE, 2);
    refl_frame *plain, *traced, *truth;
    refl_reflection_error ep, et;
    int i, changed = 0;
    ms[0] = m;
    d.sbc.morphs = ms;
    d.sbc.morph_count = 1;
    d.sbc.mixed_levels = 4; /* with and without the fallback: the same triangles drawn */
    plain = tu_refl_render(s, &v, &d);
    d.sbc.trace_fallback = 1;
    traced = tu_refl_render(s, &v, &d);
    truth = tu_refl_render(s, &v, &t);
    for (i = 0; i < MW * MH; ++i) {
        if (!memcmp(plain->rgba + 4 * i, traced->rgba + 4 * i, 4 * sizeof(float)) &&
            tu_refl_same_point(plain->points + 3 * i, traced->points + 3 * i))
            continue;
        ++changed;
        cr_assert(plain->points[3 * i] != plain->points[3 * i], "pixel %d showed a point, and changed", i);
        cr_assert_eq(memcmp(traced->rgba + 4 * i, truth->rgba + 4 * i, 4 * sizeof(float)), 0, "pixel %d: not RAYTRACE's colour", i);
        cr_assert(tu_refl_same_point(traced->points + 3 * i, truth->points + 3 * i), "pixel %d: not RAYTRACE's point",
                  i);
    }
    cr_assert_eq(refl_measure_reflection_error(plain, truth, NULL, &ep), REFL_OK);
    cr_assert_eq(refl_measure_reflection_error(traced, truth, NULL, &et), REFL_OK);
    cr_log_info("morph with the fallback: %d pixels traced, holes %.3f -> %.3f, mean %.3f -> %.3f px", changed, ep.empty,
                et.empty, ep.mean, et.mean);
    cr_assert(ep.empty > 0.1 && et.empty <= 0.01, "holes %.3f -> %.3f", ep.empty, et.empty);
    cr_assert(changed > 0 && et.mean <= ep.mean + 1e-9);
    refl_frame_destroy(plain);
    refl_frame_destroy(traced);
    refl_frame_destroy(truth);
    refl_sbc_morph_destroy(m);
    refl_scene_destroy(s);
}
