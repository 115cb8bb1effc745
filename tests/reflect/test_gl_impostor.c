/* The SPOC impostor's GL hook (tools/reflect_gl_impostor.c): its packed
   layout, and its fragment-side march (refl_spoc_impostor_intersect)
   against refl_impostor_intersect ray by ray (the frame through GL:
   test_gl_frame.c). The march is skipped, saying why, where no EGL device
   exists (test_gl_context.h). */
#include <criterion/criterion.h>
#include "../../reflect.h"
#include "../../tools/reflect_gl.h"
#include "refl_test_util.h"
#include "test_gl_context.h"

/* An impostor hook's march against its C on 20000 rays: none hit on one
   side only, the hit distances within float rounding. */
static void march_matches_c(int (*validate)(rgl_context *, long long, rgl_validation *, char *, size_t)) {
    rgl_context *g = tu_gl_context("test_gl_impostor");
    rgl_validation v;
    char err[1024];
    int r;
    LSAN_OFF();
    r = validate(g, 20000, &v, err, sizeof err);
    rgl_destroy(g);
    LSAN_ON();
    cr_assert_eq(r, 0, "%s", err);
    cr_log_info("%s march, GLSL vs C: %lld rays, %lld hit both, %lld disagree, max %.2e, p99.9 %.2e (%s)", v.camera,
                v.points, v.projected, v.disagree, v.max_rel, v.p999_rel, v.note);
    cr_assert_gt(v.projected, 3000, "%lld rays hit", v.projected);
    cr_assert_leq(v.disagree, 0, "%lld rays disagree", v.disagree);
    cr_assert_leq(v.p999_rel, 1e-4, "p99.9 %.2e", v.p999_rel);
}

Test(refl_gl_impostor, spoc_march_matches_c, .timeout = 120) { march_matches_c(rgl_validate_spoc_impostor); }

Test(refl_gl_impostor, graphcam_march_matches_c, .timeout = 120) { march_matches_c(rgl_validate_graphcam_impostor); }

/* The packed layout (no GL needed): the header, the sphere, the SPOC's own
   block, and per texel of every layer its colour and gd, -1 where nothing
   is stored; another camera's impostor is refused. */
Test(refl_gl_impostor, spoc_impostor_layout) {
    refl_scene *s = NULL;
    refl_spoc cam, other;
    refl_impostor_camera ic;
    refl_impostor_desc d;
    refl_impostor *imp = NULL;
    float *data, spoc[24];
    long long need, nn, i, stored = 0;
    int diffuse = -1, k;
    cr_assert_eq(refl_scene_builtin("teapots", NULL, &s), REFL_OK);
    for (k = 0; k < s->object_count; ++k)
        if (s->materials[s->objects[k].material].type == REFL_DIFFUSE && s->meshes[s->objects[k].mesh]->triangle_count > 100)
            diffuse = k;
    cr_assert_geq(diffuse, 0);
    cr_assert_eq(refl_spoc_init(&cam, refl_v3(-1.2f, 0.4f, -0.2f), refl_v3(1.1f, 0.4f, 1.5f), 1.0f, 0.5f, 1.0f, 32),
                 REFL_OK);
    other = cam;
    ic = refl_spoc_impostor_camera(&cam);
    memset(&d, 0, sizeof d);
    d.layers = 2;
    d.threads = 1;
    cr_assert_eq(refl_impostor_build(s, &diffuse, 1, &ic, &d, &imp), REFL_OK);
    cr_assert_eq(refl_gl_pack_spoc_impostor(imp, &other, NULL, 0), REFL_ERROR_INVALID_ARGUMENT);
    nn = 32LL * 32 * 2;
    need = refl_gl_pack_spoc_impostor(imp, &cam, NULL, 0);
    cr_assert_eq(need, 4 * (REFL_GL_SPOC_IMPOSTOR_TEXELS + nn));
    data = malloc((size_t)need * sizeof(float));
    cr_assert_not_null(data);
    cr_assert_eq(refl_gl_pack_spoc_impostor(imp, &cam, data, need), need);
    cr_assert_eq(data[0], (float)REFL_GL_SPOC_IMPOSTOR);
    cr_assert_eq(data[1], (float)REFL_GL_LAYOUT_VERSION);
    cr_assert_eq(data[2], 32.0f);
    cr_assert_eq(data[3], 2.0f);
    cr_assert_eq(data[7], imp->camera.radius);
    cr_assert_eq(data[8], imp->depth_tolerance);
    cr_assert_eq(data[9], 32.0f);
    cr_assert_eq(data[10], (float)REFL_GL_SPOC_IMPOSTOR_TEXELS);
    cr_assert_eq(refl_gl_pack_spoc(&cam, spoc, 24), 24);
    cr_assert_eq(memcmp(data + 12, spoc, sizeof spoc), 0, "the SPOC's block at texel 3");
    for (i = 0; i < nn; ++i) {
        const float *t = data + 4 * (REFL_GL_SPOC_IMPOSTOR_TEXELS + i);
        int is = imp->color[4 * i + 3] > 0.0f;
        stored += is;
        cr_assert_eq(memcmp(t, imp->color + 4 * i, 3 * sizeof(float)), 0);
        cr_assert_eq(t[3], is ? imp->depth[i] : -1.0f);
    }
    cr_assert_gt(stored, 100, "%lld texels stored", stored);
    free(data);
    refl_impostor_destroy(imp);
    refl_scene_destroy(s);
}
