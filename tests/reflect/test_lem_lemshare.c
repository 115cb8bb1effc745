/* Paper 001 section 4.3: the lenses share their outermost layer
   (layered_em.share_outer_layer), one map per viewpoint sample solved
   from the rows of every lens at once. Two lenses, a glass sphere and a
   mirror sphere side by side at the centre of a ringed sphere: shared,
   each sample has one map for both, the maps take fewer bytes, and the
   lenses match greedy RAYTRACE more closely than with their own maps
   (the shared sphere is the ringed one). The
   GL host (tools/reflect_gl_lem.c) draws the shared layer as the CPU
   does: each lens's plan names the shared texels and shell. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "../../tools/reflect_gl.h"
#include "refl_test_util.h"
#include "test_gl_context.h"

static const float DEG = 3.14159265f / 180.0f;

/* A ringed sphere of radius 6 (object 0) around a glass sphere (object
   1) at x = -1.3 and a mirror sphere (object 2) at x = 1.3, radius 1
   each. Ambient light alone. */
static refl_scene *two_lens_scene(void) {
    refl_scene *s = NULL;
    refl_mesh *shell = NULL, *lens[2] = {NULL, NULL};
    refl_material paper = refl_material_diffuse(1, 1, 1), glass = refl_material_glass(1.5f);
    refl_material mirror = refl_material_mirror(0.9f);
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    paper.texture = tu_refl_add_rings(s);
    cr_assert_gt(paper.texture, 0);
    cr_assert_eq(refl_mesh_sphere(6.0f, 96, 48, NULL, &shell), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(1.0f, 48, 24, NULL, &lens[0]), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(1.0f, 48, 24, NULL, &lens[1]), REFL_OK); /* the scene takes each */
    cr_assert_eq(refl_scene_add(s, shell, &paper, refl_mat4_identity()), 0);
    glass.tint[0] = 1.0f, glass.tint[1] = 0.9f, glass.tint[2] = 0.8f;
    cr_assert_eq(refl_scene_add(s, lens[0], &glass, refl_mat4_translate(refl_v3(-1.3f, 0.0f, 0.0f))), 1);
    cr_assert_eq(refl_scene_add(s, lens[1], &mirror, refl_mat4_translate(refl_v3(1.3f, 0.0f, 0.0f))), 2);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 1.0f;
    return s;
}

/* The eye at azimuth 4 degrees (between the samples at 0 and 8) on the
   circle of radius 4.5 around the origin, a little above the lenses. */
static refl_view eye_between_samples(int w, int h) {
    float a = 4.0f * DEG;
    return tu_refl_view(refl_v3(4.5f * sinf(a), 0.6f, 4.5f * cosf(a)), refl_v3(0, 0, 0), w, h);
}

static refl_render_desc lem_desc(int share) {
    refl_render_desc d = tu_refl_desc(REFL_LAYERED_EM, 2);
    d.layered_em.share_outer_layer = share;
    return d;
}

/* PSNR of f against truth over lens object `object`'s pixels (-1: both). */
static double lens_psnr(const refl_frame *f, const refl_frame *truth, int object) {
    double se = 0.0;
    size_t i, n = (size_t)f->width * (size_t)f->height, px = 0;
    int c;
    for (i = 0; i < n; ++i) {
        if (!truth->stencil[i] || (object >= 0 && truth->stencil[i] != object + 1)) continue;
        ++px;
        for (c = 0; c < 3; ++c) {
            double d = fmin(fmax(f->rgba[4 * i + c], 0.0), 1.0) - fmin(fmax(truth->rgba[4 * i + c], 0.0), 1.0);
            se += d * d;
        }
    }
    cr_assert_gt(px, 300, "%zu lens pixels", px);
    return se > 0.0 ? 10.0 * log10(3.0 * (double)px / se) : 99.0;
}

Test(lem_share, one_map_for_both_lenses_fewer_bytes_nearer_the_truth) {
    enum { W = 96, H = 72 };
    refl_scene *s = two_lens_scene();
    refl_view v = eye_between_samples(W, H);
    refl_render_desc gd = tu_refl_greedy_raytrace(2), d;
    refl_frame *truth, *f[2];
    double all[2], glass[2], mirror[2];
    int share;
    truth = tu_refl_render(s, &v, &gd);
    for (share = 0; share < 2; ++share) {
        d = lem_desc(share ? 1 : -1);
        f[share] = tu_refl_render(s, &v, &d);
        all[share] = lens_psnr(f[share], truth, -1);
        glass[share] = lens_psnr(f[share], truth, 1);
        mirror[share] = lens_psnr(f[share], truth, 2);
    }
    cr_log_info("own maps: %lld bytes, %d maps, %.2f dB (glass %.2f, mirror %.2f); shared: %lld bytes, %d maps, "
                "%.2f dB (glass %.2f, mirror %.2f)",
                f[0]->stats.model_bytes, f[0]->stats.layered_em.maps_held, all[0], glass[0], mirror[0],
                f[1]->stats.model_bytes, f[1]->stats.layered_em.maps_held, all[1], glass[1], mirror[1]);
    /* two samples: each lens's map of each (4); shared, the lenses' maps
       hold no texels of their one layer and each sample has the shared
       one (6) */
    cr_assert_eq(f[0]->stats.layered_em.maps_held, 4);
    cr_assert_eq(f[1]->stats.layered_em.maps_held, 6);
    cr_assert_lt(f[1]->stats.model_bytes, f[0]->stats.model_bytes);
    /* the shared sphere is centred where the ringed sphere is (the
       lenses' joint box's centre), at its radius: exact for both lenses,
       where each lens's own shell, around its centre 1.3 off, is not */
    cr_assert_geq(all[1], all[0] + 3.0, "own %.2f dB, shared %.2f dB", all[0], all[1]);
    cr_assert_geq(glass[1], glass[0] + 2.0, "glass: own %.2f dB, shared %.2f dB", glass[0], glass[1]);
    cr_assert_geq(mirror[1], mirror[0] + 2.0, "mirror: own %.2f dB, shared %.2f dB", mirror[0], mirror[1]);
    refl_frame_destroy(f[0]);
    refl_frame_destroy(f[1]);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* Through the GL host's entry: each sample's one layer is the same texels
   and shell for both lenses. */
Test(lem_share, the_gl_plan_looks_both_lenses_up_in_one_map) {
    refl_scene *s = two_lens_scene();
    refl_view v = eye_between_samples(64, 48);
    refl_render_desc d = lem_desc(1);
    refl_renderer *rr = NULL;
    refl_frame *f = NULL;
    refl_lem_lens *lenses = NULL;
    int count = 0, m;
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_frame_create(64, 48, NULL, &f), REFL_OK);
    cr_assert_eq(refl_renderer_lem_lenses(rr, &v, f, &lenses, &count), REFL_OK);
    cr_assert_eq(count, 2);
    cr_assert_eq(lenses[0].maps, 2);
    cr_assert_eq(lenses[1].maps, 2);
    for (m = 0; m < 2; ++m) {
        cr_assert_eq(lenses[0].layers, 1);
        cr_assert_not_null(lenses[0].texels[m][0]);
        cr_assert_eq(lenses[0].texels[m][0], lenses[1].texels[m][0], "sample %d: one map", m);
        cr_assert_eq(memcmp(&lenses[0].shell[m][0], &lenses[1].shell[m][0], sizeof(refl_lem_shell)), 0);
        cr_assert_eq(lenses[0].weight[m], lenses[1].weight[m]);
    }
    cr_assert_neq(lenses[0].texels[0][0], lenses[0].texels[1][0], "the two samples' maps differ");
    refl_renderer_lem_lenses_free(rr, lenses, count);
    refl_frame_destroy(f);
    refl_renderer_destroy(rr);
    refl_scene_destroy(s);
}

Test(lem_share, invalid_combinations_are_refused) {
    static const struct {
        int share, lens_layers, direct_confidence;
        const char *message;
    } cases[] = {
        {2, 0, 0, "layered_em.share_outer_layer: -1 (off), 0 or 1 (on)"},
        {-2, 0, 0, "layered_em.share_outer_layer: -1 (off), 0 or 1 (on)"},
        /* the other lens would lie inside the shell it is a layer of */
        {1, 1, 0, "layered_em.share_outer_layer: not with lens_layers on"},
        {1, 0, REFL_LEM_DIRECT_DISTANCE, "layered_em.share_outer_layer: not with direct_confidence DISTANCE"},
    };
    refl_scene *s = two_lens_scene();
    refl_view v = eye_between_samples(16, 12);
    refl_frame *f = NULL;
    refl_render_desc d;
    const char *why = NULL;
    size_t k;
    cr_assert_eq(refl_frame_create(16, 12, NULL, &f), REFL_OK);
    for (k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        d = lem_desc(cases[k].share);
        d.layered_em.lens_layers = cases[k].lens_layers;
        d.layered_em.direct_confidence = cases[k].direct_confidence;
        cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT, "case %zu", k);
        cr_assert_str_eq(why, cases[k].message);
        cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT, "case %zu", k);
    }
    /* off, those combinations stand; on, the others */
    d = lem_desc(-1);
    d.layered_em.lens_layers = 1;
    d.layered_em.direct_confidence = REFL_LEM_DIRECT_DISTANCE;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_OK, "%s", why);
    d = lem_desc(1);
    d.layered_em.lens_layers = -1;
    d.layered_em.direct_confidence = REFL_LEM_DIRECT_COVERAGE;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_OK);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* The GL host with a shared outer layer against the CPU, as
   refl_gl_frame::layered_em_matches_cpu with the defaults: `hybrid`'s
   teapot and cup, two layers (the shared one the outer). */
Test(refl_gl_frame, layered_em_shared_layer_matches_cpu, .timeout = 120) {
    refl_render_desc d;
    tu_gl_lem_vs_cpu m;
    rgl_lem_desc(&d);
    d.layered_em.share_outer_layer = 1;
    d.layered_em.layers = 2;
    m = tu_gl_layered_em_vs_cpu("test_lem_lemshare", &d);
    cr_log_info("LAYERED_EM shared, GL vs CPU: PSNR %.1f dB; traced GL %lld, CPU %lld", m.psnr, m.gl.traced,
                m.cpu_traced);
    cr_assert_gt(m.psnr, 38.0);
}

/* A renderer keeps the shared sample (every lens's map and the shared
   one): its second frame infers nothing and is the first's bytes, and
   the frame is the same for any thread count. */
Test(lem_share, kept_and_any_threads_same_bytes) {
    refl_scene *s = two_lens_scene();
    refl_view v = eye_between_samples(48, 36);
    refl_render_desc d = lem_desc(1);
    refl_renderer *rr = NULL;
    refl_frame *f[3];
    int k;
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    for (k = 0; k < 2; ++k) {
        cr_assert_eq(refl_frame_create(48, 36, NULL, &f[k]), REFL_OK);
        cr_assert_eq(refl_renderer_render(rr, &v, f[k]), REFL_OK);
    }
    cr_assert_eq(f[0]->stats.layered_em.maps_inferred, 6);
    cr_assert_eq(f[1]->stats.layered_em.maps_inferred, 0);
    cr_assert_eq(tu_refl_digest(f[0]), tu_refl_digest(f[1]));
    d.threads = 3;
    f[2] = tu_refl_render(s, &v, &d);
    cr_assert_eq(tu_refl_digest(f[0]), tu_refl_digest(f[2]));
    for (k = 0; k < 3; ++k) refl_frame_destroy(f[k]);
    refl_renderer_destroy(rr);
    refl_scene_destroy(s);
}
