/* SBC (paper 003) where sample-based cameras are known to struggle, and
   where they must be exact: one reflector at a time, of curvature from none
   to strong to concave, in a small scene of diffuse boxes on a floor, and
   the default scene along a camera path that sweeps across the teapot's
   curvature discontinuities (body to spout and handle). Every frame must be
   well formed (no NaN, DIRECT's bytes off the reflectors) and its error
   against the one-bounce ray-traced reference bounded; a planar reflector
   needs only pinhole leaves and shows no error beyond a pixel's worth. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

enum { SW = 96, SH = 72 };

static refl_render_desc method_desc(refl_method m) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = m;
    d.threads = 2;
    d.depth = 1;
    return d;
}

/* A floor, three diffuse boxes around the origin and one light; the
   reflector (scene takes `reflector`) at the origin with transform xf. */
static refl_scene *reflector_scene(refl_mesh *reflector, refl_mat4 xf) {
    static const float grey[3] = {0.6f, 0.6f, 0.6f}, red[3] = {0.9f, 0.2f, 0.1f}, green[3] = {0.2f, 0.8f, 0.3f},
                       blue[3] = {0.2f, 0.3f, 0.9f}, silver[3] = {0.9f, 0.9f, 0.9f};
    refl_scene *s = NULL;
    refl_mesh *floor = NULL, *box[3] = {NULL, NULL, NULL};
    int k;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(12.0f, 8, NULL, &floor), REFL_OK);
    for (k = 0; k < 3; ++k) cr_assert_eq(refl_mesh_box(refl_v3(0.8f, 1.2f + 0.4f * k, 0.8f), NULL, &box[k]), REFL_OK);
    tu_refl_add_object(s, floor, REFL_DIFFUSE, grey, refl_mat4_translate(refl_v3(0, -1.0f, 0)));
    tu_refl_add_object(s, box[0], REFL_DIFFUSE, red, refl_mat4_translate(refl_v3(-2.2f, -0.4f, -1.5f)));
    tu_refl_add_object(s, box[1], REFL_DIFFUSE, green, refl_mat4_translate(refl_v3(2.0f, -0.2f, -1.8f)));
    tu_refl_add_object(s, box[2], REFL_DIFFUSE, blue, refl_mat4_translate(refl_v3(0.3f, 0.0f, -3.0f)));
    tu_refl_add_object(s, reflector, REFL_MIRROR, silver, xf);
    tu_refl_add_point_light(s, refl_v3(3.0f, 5.0f, 4.0f), 1.0f, 0.0f);
    return s;
}

/* Largest errors a case may show (refl_reflection_error's fields). */
typedef struct sbc_bounds {
    double mean, p95, wrong, holes;
} sbc_bounds;

/* Renders SBC, checks the frame is well formed and its error within b. */
static void check_sbc_frame(const refl_scene *s, const refl_view *v, const char *what, sbc_bounds b,
                            refl_stats *stats) {
    refl_render_desc d = method_desc(REFL_SBC), t = method_desc(REFL_RAYTRACE), dd = method_desc(REFL_DIRECT);
    refl_frame *f = tu_refl_render(s, v, &d), *truth = tu_refl_render(s, v, &t), *direct = tu_refl_render(s, v, &dd);
    refl_reflection_error e;
    tu_assert_reflector_frame(f, direct);
    cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &e), REFL_OK);
    cr_log_info("SBC %s %dx%d: mean %.2f p95 %.2f max %.1f px, wrong %.3f, holes %.3f, %lld pinhole and %lld "
                "ray-list leaves", what, v->width, v->height, e.mean, e.p95, e.max, e.wrong, e.empty,
                f->stats.sbc.pinhole_leaves, f->stats.sbc.ray_leaves);
    cr_assert(e.pixels > 200, "%s: %lld reflector pixels", what, e.pixels);
    cr_assert(e.mean <= b.mean && e.p95 <= b.p95, "%s: mean %.2f p95 %.2f px", what, e.mean, e.p95);
    cr_assert(e.wrong <= b.wrong && e.empty <= b.holes, "%s: wrong %.3f holes %.3f", what, e.wrong, e.empty);
    if (stats) *stats = f->stats;
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_frame_destroy(direct);
}

/* One reflector in the boxes scene, seen from eye at width x height. */
static void check_reflector(refl_mesh *m, refl_mat4 xf, refl_vec3 eye, int width, int height, const char *what,
                            sbc_bounds b, refl_stats *stats) {
    refl_scene *s = reflector_scene(m, xf);
    refl_view v = tu_refl_view(eye, refl_v3(0, -0.2f, -0.5f), width, height);
    check_sbc_frame(s, &v, what, b, stats);
    refl_scene_destroy(s);
}

/* The bounds below are what this build measured (in the comments) with
   some room; the goal is 1 px everywhere. 96x72 unless said. */

/* Measured: mean 0.00, p95 0, max 1.4 px, nothing wrong or missing. One
   pinhole camera per group: the mirrored eye. */
Test(refl_sbc_stability, planar_mirror, .timeout = 120) {
    refl_mesh *m = NULL;
    refl_stats st;
    sbc_bounds b = {0.05, 1.0, 0.005, 0.005};
    cr_assert_eq(refl_mesh_plane(3.0f, 4, NULL, &m), REFL_OK);
    check_reflector(m, refl_mat4_translate(refl_v3(0, -0.9f, 0)), refl_v3(0, 1.5f, 4.0f), SW, SH, "planar", b, &st);
    cr_assert_eq(st.sbc.ray_leaves, 0, "%lld ray-list leaves on a plane", st.sbc.ray_leaves);
}

/* A cap of a sphere of radius 20: within the view, a mirror bent by about
   four degrees, at 384x288, where each group's rays are a nearly parallel
   bundle narrower than the boxes' faces. Before triangles were subdivided
   towards where a group's rays meet them (m_sbc.c), 27% of the mirror
   showed what the truth shows nowhere and 33% nothing; before projections
   behind the mirror were refused, 2.6% (99.7% at 96x72 with tile groups).
   Measured: mean 0.09, p95 1.0 px, wrong 0.1%, holes 0.4%. */
Test(refl_sbc_stability, nearly_planar_mirror, .timeout = 120) {
    refl_mesh *m = NULL;
    refl_stats st;
    sbc_bounds b = {0.25, 1.5, 0.005, 0.01};
    cr_assert_eq(refl_mesh_sphere(20.0f, 256, 128, NULL, &m), REFL_OK);
    check_reflector(m, refl_mat4_translate(refl_v3(0, -20.9f, 0)), refl_v3(0, 1.5f, 4.0f), 384, 288, "nearly planar",
                    b, &st);
    cr_assert_eq(st.sbc.ray_leaves, 0, "%lld ray-list leaves on a nearly flat mirror", st.sbc.ray_leaves);
}

/* Measured: mean 0.10, p95 1.0, max 2.0 px, wrong 1.0%, holes 1.2%.
   (Letting BSP splits go on until three quarters of a set's rays straddle
   the plane made this mean 0.53, max 15.8 px: cam_sbc.c.) */
Test(refl_sbc_stability, strongly_curved_mirror, .timeout = 120) {
    refl_mesh *m = NULL;
    sbc_bounds b = {0.25, 1.5, 0.02, 0.025};
    cr_assert_eq(refl_mesh_sphere(0.6f, 48, 24, NULL, &m), REFL_OK);
    check_reflector(m, refl_mat4_identity(), refl_v3(0, 0.5f, 2.5f), SW, SH, "strongly curved", b, NULL);
}

/* The built-in concave mirror: all its leaves are ray lists (its rays
   cross). Measured: mean 0.27, p95 1.4, max 4.2 px, wrong 3.8%, holes
   3.1% (4.8% before cracks were filled); with one image per group (no
   sheets) mean 0.96, p95 6.3, max 13.4 px, wrong 4.7%, holes 5.5%. */
Test(refl_sbc_stability, concave_mirror, .timeout = 120) {
    refl_scene *s = NULL;
    refl_view v;
    sbc_bounds b = {0.4, 2.0, 0.05, 0.045};
    cr_assert_eq(refl_scene_builtin("concave", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = SW;
    v.height = SH;
    check_sbc_frame(s, &v, "concave", b, NULL);
    refl_scene_destroy(s);
}

/* The default scene's camera swung around the teapot in eight steps of
   0.4 radians. Measured: worst mean 1.28 and p95 7.1 px (step 0, where
   the spout's reflection crosses the body's), wrong up to 1.5%, holes up
   to 20.6% (step 7): ray-list leaves near the silhouettes, and the teapot
   reflecting itself next to its own surface. */
Test(refl_sbc_stability, camera_path_across_the_teapot, .timeout = 300) {
    refl_scene *s = NULL;
    refl_vec3 eye, target;
    float r, a0;
    int k;
    sbc_bounds b = {1.6, 9.0, 0.03, 0.27};
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    eye = s->camera.eye;
    target = s->camera.target;
    r = sqrtf((eye.x - target.x) * (eye.x - target.x) + (eye.z - target.z) * (eye.z - target.z));
    a0 = atan2f(eye.z - target.z, eye.x - target.x);
    for (k = 0; k < 8; ++k) {
        float a = a0 + (float)k * 0.4f;
        char what[32];
        refl_view v = s->camera;
        v.eye = refl_v3(target.x + r * cosf(a), eye.y, target.z + r * sinf(a));
        v.width = SW;
        v.height = SH;
        snprintf(what, sizeof what, "path step %d", k);
        check_sbc_frame(s, &v, what, b, NULL);
    }
    refl_scene_destroy(s);
}
