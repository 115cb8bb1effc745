/* The GL hooks (src/reflect/gl_hooks.c): the packers' layouts (no GL
   needed), and every camera's GLSL projection against its C projection by
   transform feedback on 10^5 random points (tools/reflect_gl.c; docs/gl.md),
   skipped, saying why, where no EGL device exists (test_gl_context.h). */
#include <criterion/criterion.h>
#include "../../reflect.h"
#include "../../tools/reflect_gl.h"
#include "refl_test_util.h"
#include "test_gl_context.h"


Test(refl_gl_hooks, mirror_layout) {
    float buf[64];
    refl_mat4 vp = refl_mat4_identity();
    long long n = refl_gl_pack_mirror(vp, refl_v3(0, 2, 0), 1.0f, NULL, 0);
    cr_assert_eq(n, 24);
    cr_assert_eq(refl_gl_pack_mirror(vp, refl_v3(0, 2, 0), 1.0f, buf, 64), 24);
    cr_assert_eq(buf[0], (float)REFL_GL_MIRROR);
    cr_assert_eq(buf[1], (float)REFL_GL_LAYOUT_VERSION);
    /* y reflected about y = 0.5: the matrix maps (0, 0, 0) to (0, 1, 0) */
    cr_assert_float_eq(buf[4 + 13], 1.0f, 1e-6f);
    cr_assert_float_eq(buf[4 + 5], -1.0f, 1e-6f);
    /* the clip plane, unit: y - 0.5 */
    cr_assert_float_eq(buf[21], 1.0f, 1e-6f);
    cr_assert_float_eq(buf[23], -0.5f, 1e-6f);
    cr_assert_lt(refl_gl_pack_mirror(vp, refl_v3(0, 0, 0), 1.0f, buf, 64), 0);
}

Test(refl_gl_hooks, c3rc_layout) {
    refl_c3rc cams[2];
    refl_vec3 v[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, d[3] = {{0, 0, 1}, {0.1f, 0, 1}, {0, 0.1f, 1}};
    float buf[200];
    cr_assert_eq(refl_c3rc_init(&cams[0], v, d), REFL_OK);
    cams[1] = cams[0];
    cr_assert_eq(refl_gl_pack_c3rc(cams, 2, NULL, 0), 4 * (1 + 2 * REFL_GL_C3RC_TEXELS));
    /* too small: nothing written */
    buf[0] = -7.0f;
    cr_assert_eq(refl_gl_pack_c3rc(cams, 2, buf, 10), 4 * (1 + 2 * REFL_GL_C3RC_TEXELS));
    cr_assert_eq(buf[0], -7.0f);
    cr_assert_eq(refl_gl_pack_c3rc(cams, 2, buf, 200), 4 * (1 + 2 * REFL_GL_C3RC_TEXELS));
    cr_assert_eq(buf[0], (float)REFL_GL_C3RC);
    cr_assert_eq(buf[2], 2.0f);
    /* camera 1's tails at texels 0..2 of its block */
    cr_assert_eq(buf[4 * (1 + REFL_GL_C3RC_TEXELS) + 4], 1.0f);
    cr_assert_lt(refl_gl_pack_c3rc(NULL, 1, buf, 200), 0);
    cr_assert_not_null(refl_gl_glsl(REFL_GL_C3RC));
    cr_assert_null(refl_gl_glsl((refl_gl_camera)0));
}

static void validate(int which) {
    rgl_context *g = tu_gl_context("test_gl_hooks");
    rgl_validation v;
    char err[1024];
    int r;
    LSAN_OFF();
    r = rgl_validate(g, which, 100000, 1, &v, err, sizeof err);
    rgl_destroy(g);
    LSAN_ON();
    cr_assert_eq(r, 0, "%s", err);
    cr_log_info("%s on %s: %lld points, %lld project, %lld disagree, max rel %.2e, p99.9 %.2e [%s]", v.camera,
                "GL", v.points, v.projected, v.disagree, v.max_rel, v.p999_rel, v.note);
    /* most points project (the fixtures aim 80% of them into the volume) */
    cr_assert_gt(v.projected, v.points / 2, "%s: %lld of %lld project", v.camera, v.projected, v.points);
    cr_assert(rgl_validation_ok(&v), "%s: %lld of %lld disagree, max rel %.2e, p99.9 %.2e", v.camera, v.disagree,
              v.points, v.max_rel, v.p999_rel);
    if (which == 7) /* SPOC: float rounding of the pinhole, the push and gd */
        cr_assert(v.max_rel <= 1e-4, "spoc: max rel %.2e", v.max_rel);
    if (which == 1) { /* C3RC, its cubic in the triangle's frame (docs/gl.md): float rounding, no more */
        cr_assert(v.max_rel <= 1e-4, "c3rc: max rel %.2e", v.max_rel);
        cr_assert((double)v.disagree <= 1e-5 * (double)v.points, "c3rc: %lld of %lld disagree", v.disagree, v.points);
    }
    if (which == 2 || which == 3) { /* SBC: both leaf kinds carry points */
        cr_assert_gt(v.pinhole_points, 1000);
        if (which == 2) cr_assert_gt(v.raylist_points, 1000);
    }
}

Test(refl_gl_hooks, mirror_glsl_matches_c, .timeout = 120) { validate(0); }
Test(refl_gl_hooks, c3rc_glsl_matches_c, .timeout = 120) { validate(1); }
Test(refl_gl_hooks, sbc_glsl_matches_c, .timeout = 120) { validate(2); }
Test(refl_gl_hooks, sbc_bowl_glsl_matches_c, .timeout = 120) { validate(3); }

/* The SBC morph grid's hook (cam_sbc_morph.c): the layout's header and
   refusals, then its GLSL blend against refl_sbc_morph_project on 10^5
   points of the default scene's teapot (tools/reflect_gl.c's fixture 5). */
Test(refl_gl_hooks, sbc_morph_layout, .timeout = 60) {
    refl_scene *s = NULL;
    refl_sbc_morph *m = NULL;
    refl_sbc_morph_desc md;
    refl_vec3 eye = {0.3f, 4.5f, 8.9f};
    int nodes[4];
    float w[4], *buf;
    long long need, k;
    memset(&md, 0, sizeof md);
    md.nodes[0] = md.nodes[1] = md.nodes[2] = 2;
    md.region_lo = refl_v3(-1.0f, 3.8f, 7.4f);
    md.region_hi = refl_v3(1.0f, 5.3f, 9.4f);
    md.face_size = 16;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    cr_assert_eq(refl_sbc_morph_build(s, 1, &md, &m), REFL_OK);
    need = refl_gl_pack_sbc_morph(m, eye, 0, NULL, 0);
    cr_assert_gt(need, 24);
    cr_assert_eq(need % 4, 0);
    buf = malloc((size_t)need * sizeof(float));
    cr_assert_not_null(buf);
    cr_assert_eq(refl_gl_pack_sbc_morph(m, eye, 0, buf, need), need);
    cr_assert_eq(buf[0], (float)REFL_GL_SBC_MORPH);
    cr_assert_eq(buf[1], (float)REFL_GL_LAYOUT_VERSION);
    cr_assert_eq(buf[3], (float)(need / 4), "texel count in the header");
    /* the eye's weights, and each node of weight a block of its own */
    cr_assert_geq(refl_sbc_morph_locate(m, eye, nodes, w), 0);
    for (k = 0; k < 4; ++k) {
        cr_assert_float_eq(buf[4 + k], w[k] > 0.0f ? w[k] : 0.0f, 1e-6f);
        if (w[k] > 0.0f) cr_assert_geq(buf[4 * (2 + k)], 6.0f);
    }
    cr_assert_eq(buf[9], (float)refl_sbc_morph_sheets(m, eye, 0), "the piece's sheets in texel 2");
    cr_assert_geq(buf[9], 1.0f);
    cr_assert_lt(refl_gl_pack_sbc_morph(m, eye, -1, NULL, 0), 0);
    cr_assert_lt(refl_gl_pack_sbc_morph(m, refl_v3(0, 100, 0), 0, NULL, 0), 0);
    cr_assert_lt(refl_gl_pack_sbc_morph(NULL, eye, 0, NULL, 0), 0);
    cr_assert_not_null(refl_gl_glsl(REFL_GL_SBC_MORPH));
    free(buf);
    refl_sbc_morph_destroy(m);
    refl_scene_destroy(s);
}

Test(refl_gl_hooks, sbc_morph_glsl_matches_c, .timeout = 120) { validate(5); }

/* The blend per sheet, as refl_render draws a morph grid
   (refl_sbc_morph_project_sheet), on the concave bowl's grid (its rays
   fold: three sheets; fixture 8): each point in one of the sheets, its
   image, distance and whether it came from across a fold. */
Test(refl_gl_hooks, sbc_morph_sheets_glsl_matches_c, .timeout = 120) { validate(8); }

/* LAYERED_EM's shells (gl_hooks.c): the layout, then the GLSL lookup's
   texels and weights against refl_lem_shell_lookup on 10^5 exit rays, a
   quarter on each kind of shell (no lookup from outside a closed shell or
   past the quad, on both sides). */
Test(refl_gl_hooks, lem_shell_layout) {
    refl_lem_shell sh[2];
    float map[4 * 24], buf[44 + 8 * 24];
    const float *maps[2] = {map, map};
    int i;
    memset(sh, 0, sizeof sh);
    sh[0].center = refl_v3(1.0f, 2.0f, 3.0f);
    sh[0].radius = 4.0f;
    sh[0].face_size = 2;
    sh[1] = sh[0];
    sh[1].kind = REFL_LEM_SHELL_BOX;
    sh[1].axis[0] = refl_v3(1, 0, 0), sh[1].axis[1] = refl_v3(0, 1, 0), sh[1].axis[2] = refl_v3(0, 0, 1);
    sh[1].extent[0] = 5.0f, sh[1].extent[1] = 6.0f, sh[1].extent[2] = 7.0f;
    for (i = 0; i < 4 * 24; ++i) map[i] = (float)i;
    /* a header texel, 5 a layer, then the maps */
    cr_assert_eq(refl_gl_pack_lem_shell(&sh[0], NULL, NULL, 0), 24);
    cr_assert_eq(refl_gl_pack_lem_shell(&sh[0], map, NULL, 0), 24 + 4 * 24);
    cr_assert_eq(refl_gl_pack_lem_shells(sh, maps, 2, NULL, 0), 44 + 8 * 24);
    cr_assert_eq(refl_gl_pack_lem_shells(sh, maps, 2, buf, 44 + 8 * 24), 44 + 8 * 24);
    cr_assert_eq(buf[0], (float)REFL_GL_LEM_SHELL);
    cr_assert_eq(buf[2], 2.0f);                   /* layers */
    cr_assert_eq(buf[3], 1.0f);                   /* maps */
    cr_assert_eq(buf[4], 2.0f);                   /* layer 0: face size */
    cr_assert_eq(buf[5], (float)REFL_LEM_SHELL_SPHERE);
    cr_assert_eq(buf[6], 11.0f);                  /* its map at texel 11 */
    cr_assert_eq(buf[11], 4.0f);                  /* radius */
    cr_assert_eq(buf[24 + 1], (float)REFL_LEM_SHELL_BOX);
    cr_assert_eq(buf[24 + 2], 11.0f + 24.0f);     /* layer 1's map after layer 0's */
    cr_assert_eq(buf[24 + 4 * 4 + 3], 7.0f);      /* its third half size */
    cr_assert_eq(buf[44 + 4 * 5 + 2], 22.0f);     /* layer 0's texel 5's blue */
    sh[0].radius = 0.0f;
    cr_assert_lt(refl_gl_pack_lem_shell(&sh[0], NULL, NULL, 0), 0);
    cr_assert_lt(refl_gl_pack_lem_shells(sh, NULL, REFL_LEM_MAX_LAYERS + 1, NULL, 0), 0);
    cr_assert_not_null(refl_gl_glsl(REFL_GL_LEM_SHELL));
}

/* (the shells' error: the largest weight difference; another texel disagrees) */
Test(refl_gl_hooks, lem_shell_glsl_matches_c, .timeout = 120) { validate(6); }

Test(refl_gl_hooks, spoc_layout) {
    refl_spoc cam;
    float buf[32];
    cr_assert_eq(refl_spoc_init(&cam, refl_v3(0, 0.5f, 4), refl_v3(0, 0, 0), 1.0f, 1.0f, 1.0f, 256), REFL_OK);
    cr_assert_eq(refl_gl_pack_spoc(&cam, NULL, 0), 24);
    cr_assert_eq(refl_gl_pack_spoc(&cam, buf, 32), 24);
    cr_assert_eq(buf[0], (float)REFL_GL_SPOC);
    cr_assert_eq(buf[1], (float)REFL_GL_LAYOUT_VERSION);
    cr_assert_eq(buf[7], cam.focal);
    cr_assert_eq(buf[15], cam.delta_max);
    cr_assert_eq(buf[22], cam.pole[0]);
    cr_assert_lt(refl_gl_pack_spoc(NULL, buf, 32), 0);
    cr_assert_not_null(refl_gl_glsl(REFL_GL_SPOC));
}

/* the SPOC's projection in float against the C's in double */
Test(refl_gl_hooks, spoc_glsl_matches_c, .timeout = 120) { validate(7); }

/* C3RC's level of detail as the GL path draws it
   (refl_c3rc_view_camera_lod, the CPU path's rule): a leaf's prefix
   shrinks as the density grows, never below one point; small leaves and
   cameras whose rays fold keep every point. */
Test(refl_gl_hooks, c3rc_level_of_detail) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("default", &v, 160, 120);
    refl_c3rc_view_camera *cams = NULL, folded;
    refl_vec3 lo3, hi3;
    float lo[3], hi[3], density;
    int count = 0, i, found = -1, last = 1000, k;
    cr_assert_eq(refl_c3rc_view_cameras(s, &v, 0.0f, &cams, &count), REFL_OK);
    for (i = 0; i < count && found < 0; ++i)
        if (cams[i].lod && cams[i].screen_area > 1.0f) found = i;
    cr_assert_geq(found, 0, "a camera of the teapot that does not fold");
    refl_scene_bounds(s, &lo3, &hi3);
    lo[0] = lo3.x; lo[1] = lo3.y; lo[2] = lo3.z;
    hi[0] = hi3.x; hi[1] = hi3.y; hi[2] = hi3.z;
    for (density = 1.0f; density <= 1e6f; density *= 10.0f) {
        k = refl_c3rc_view_camera_lod(&cams[found], lo, hi, 1000, density);
        cr_assert(k >= 1 && k <= last, "density %g: %d points of 1000 (before: %d)", density, k, last);
        last = k;
    }
    cr_assert_lt(last, 1000, "a dense leaf is thinned");
    cr_assert_eq(refl_c3rc_view_camera_lod(&cams[found], lo, hi, 15, 1e6f), 15);
    folded = cams[found];
    folded.lod = 0;
    cr_assert_eq(refl_c3rc_view_camera_lod(&folded, lo, hi, 1000, 1e6f), 1000);
    refl_c3rc_view_cameras_free(s, cams);
    refl_scene_destroy(s);
}
