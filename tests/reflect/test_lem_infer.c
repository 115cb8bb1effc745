/* Paper 001's inferred environment maps, one sphere shell: the shell
   lookup (the far root, bilinear weights), the confidence formula, the
   least-squares solver recovering a known texture from images rendered
   with it (and weighing rows by confidence exactly), and the whole chain
   on an exact-shell scene (a glass lens at the centre of a textured
   sphere): records of a view, inference, and the two-term hybrid pixel
   T F_T G_T + R F_R G_R with the inferred shell against greedy RAYTRACE. */
#include <criterion/criterion.h>
#include <criterion/parameterized.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "refl_test_util.h"

static const float DEG = 3.14159265f / 180.0f;

Test(lem_infer, shell_lookup_far_root) {
    refl_lem_shell sh;
    uint32_t tex[4], tc[4];
    float w[4], wc[4];
    refl_vec3 o = refl_v3(0.4f, -0.3f, 0.2f), d = refl_v3_normalize(refl_v3(0.3f, 0.5f, -0.8f)), hit, oc;
    float b, c, t;
    int k;
    memset(&sh, 0, sizeof sh); /* kind 0: a sphere */
    sh.center = refl_v3(1.0f, 2.0f, 3.0f);
    sh.radius = 2.5f;
    sh.face_size = 16;
    o = refl_v3_add(o, sh.center);
    cr_assert(refl_lem_shell_lookup(&sh, o, d, tex, w));
    /* the same texels and weights as the ray from the centre to the far hit */
    oc = refl_v3_sub(o, sh.center);
    b = refl_v3_dot(oc, d);
    c = refl_v3_dot(oc, oc) - sh.radius * sh.radius;
    t = -b + sqrtf(b * b - c);
    hit = refl_v3_add(oc, refl_v3_scale(d, t));
    cr_assert(refl_lem_shell_lookup(&sh, sh.center, refl_v3_normalize(hit), tc, wc));
    for (k = 0; k < 4; ++k) {
        cr_assert_eq(tex[k], tc[k]);
        cr_assert_float_eq(w[k], wc[k], 1e-4f);
        cr_assert_geq(w[k], 0.0f);
        cr_assert_lt(tex[k], 6u * 16u * 16u);
    }
    cr_assert_float_eq(w[0] + w[1] + w[2] + w[3], 1.0f, 1e-6f);
    /* from outside, away from it: no hit; bad shells and rays: none */
    cr_assert_not(refl_lem_shell_lookup(&sh, refl_v3(10, 2, 3), refl_v3(1, 0, 0), tex, w));
    cr_assert_not(refl_lem_shell_lookup(&sh, o, refl_v3(NAN, 0, 0), tex, w));
    sh.face_size = 0;
    cr_assert_not(refl_lem_shell_lookup(&sh, o, d, tex, w));
}

Test(lem_infer, confidence_formula) {
    refl_vec3 dirs[3];
    dirs[0] = refl_v3(0, 0, -1);
    cr_assert_eq(refl_lem_confidence(dirs, 1, 0.0f), 1.0f);
    dirs[1] = dirs[0];
    cr_assert_float_eq(refl_lem_confidence(dirs, 2, 0.0f), 1.0f, 1e-6f);
    /* theta_m = 2.5 degrees of theta_c = 5: 1 - 0.25 */
    dirs[1] = refl_v3(sinf(2.5f * DEG), 0, -cosf(2.5f * DEG));
    cr_assert_float_eq(refl_lem_confidence(dirs, 2, 0.0f), 0.75f, 1e-5f);
    cr_assert_float_eq(refl_lem_confidence(dirs, 2, 10.0f), 1.0f - 0.0625f, 1e-5f);
    /* the largest pair counts: 1 degree to one side, 3 to the other (4 apart) */
    dirs[1] = refl_v3(sinf(-1.0f * DEG), 0, -cosf(1.0f * DEG));
    dirs[2] = refl_v3(sinf(3.0f * DEG), 0, -cosf(3.0f * DEG));
    cr_assert_float_eq(refl_lem_confidence(dirs, 3, 5.0f), 1.0f - 16.0f / 25.0f, 1e-4f);
    /* theta_c and beyond: 0 */
    dirs[1] = refl_v3(sinf(7.0f * DEG), 0, -cosf(7.0f * DEG));
    cr_assert_eq(refl_lem_confidence(dirs, 2, 5.0f), 0.0f);
}

Test(lem_infer, least_squares_recovers_known_texture) {
    const int n = 4, texels = 6 * 4 * 4, rays = 4000;
    refl_lem_shell sh;
    refl_lem_system *sys = NULL;
    refl_lem_solve_stats st;
    refl_rng rng = refl_rng_seed(7);
    float *truth = (float *)malloc(sizeof(float) * 4 * (size_t)texels);
    float *x = (float *)malloc(sizeof(float) * 4 * (size_t)texels), *x2 = (float *)malloc(sizeof(float) * 4 * (size_t)texels);
    int i, k, c;
    double worst = 0.0;
    memset(&sh, 0, sizeof sh);
    sh.center = refl_v3(0, 0, 0);
    sh.radius = 3.0f;
    sh.face_size = n;
    for (i = 0; i < 4 * texels; ++i) truth[i] = refl_rng_float(&rng);
    cr_assert_eq(refl_lem_system_create(texels, NULL, &sys), REFL_OK);
    /* images rendered with the texture: rows from exit rays leaving points
       inside the shell in every direction, their pixels A x_true */
    for (i = 0; i < rays; ++i) {
        refl_vec3 o = refl_v3(refl_rng_float(&rng) - 0.5f, refl_rng_float(&rng) - 0.5f, refl_rng_float(&rng) - 0.5f);
        refl_vec3 d = refl_v3_normalize(refl_v3(2.0f * refl_rng_float(&rng) - 1.0f, 2.0f * refl_rng_float(&rng) - 1.0f,
                                                2.0f * refl_rng_float(&rng) - 1.0f));
        uint32_t tex[4];
        float w[4], b[4] = {0, 0, 0, 0};
        cr_assert(refl_lem_shell_lookup(&sh, o, d, tex, w));
        for (k = 0; k < 4; ++k)
            for (c = 0; c < 4; ++c) b[c] += w[k] * truth[4 * tex[k] + (uint32_t)c];
        cr_assert_eq(refl_lem_system_add_row(sys, tex, w, 4, b, 1.0f), REFL_OK);
    }
    cr_assert_eq(refl_lem_system_rows(sys), rays);
    cr_assert_eq(refl_lem_solve(sys, NULL, x, &st), REFL_OK);
    for (i = 0; i < 4 * texels; ++i) worst = fmax(worst, fabs((double)x[i] - truth[i]));
    cr_assert_lt(worst, 1e-3, "largest texel error %g after %d iterations", worst, st.iterations);
    for (c = 0; c < 4; ++c) cr_assert_lt(st.residual[c], 1e-4 * st.initial[c]);
    /* the same texels again */
    cr_assert_eq(refl_lem_solve(sys, NULL, x2, NULL), REFL_OK);
    cr_assert_eq(memcmp(x, x2, sizeof(float) * 4 * (size_t)texels), 0);
    refl_lem_system_destroy(sys);
    free(truth);
    free(x);
    free(x2);
}

Test(lem_infer, least_squares_converges_where_texels_are_unevenly_seen) {
    /* a strip of texels looked up bilinearly, the pixels' confidence
       falling a thousandfold along it (a shell seen head-on at one end and
       at grazing angles at the other): the texels' columns differ by 10^3
       in length, and plain CGLS leaves a texel 0.99 off after 60
       iterations; with every column scaled to unit length the solve
       converges within them */
    const int texels = 256, rows = 4 * 256;
    refl_lem_system *sys = NULL;
    refl_lem_solve_stats st;
    refl_lem_solve_desc d;
    refl_rng rng = refl_rng_seed(11);
    float truth[4 * 256], x[4 * 256];
    double worst = 0.0;
    int i, c;
    for (i = 0; i < 4 * texels; ++i) truth[i] = refl_rng_float(&rng);
    cr_assert_eq(refl_lem_system_create(texels, NULL, &sys), REFL_OK);
    for (i = 0; i < rows; ++i) {
        float u = (float)(texels - 1) * ((float)i + 0.5f) / (float)rows, f = u - floorf(u), b[4];
        uint32_t tex[2] = {(uint32_t)u, (uint32_t)u + 1u};
        float w[2] = {1.0f - f, f}, confidence = powf(10.0f, -3.0f * u / (float)(texels - 1));
        for (c = 0; c < 4; ++c) b[c] = w[0] * truth[4 * tex[0] + (uint32_t)c] + w[1] * truth[4 * tex[1] + (uint32_t)c];
        cr_assert_eq(refl_lem_system_add_row(sys, tex, w, 2, b, confidence), REFL_OK);
    }
    memset(&d, 0, sizeof d);
    d.iterations = 60;
    cr_assert_eq(refl_lem_solve(sys, &d, x, &st), REFL_OK);
    for (i = 0; i < 4 * texels; ++i) worst = fmax(worst, fabs((double)x[i] - truth[i]));
    cr_assert_lt(worst, 1e-3, "largest texel error %g after %d iterations", worst, st.iterations);
    cr_assert_lt(st.iterations, 60, "not converged in %d iterations", st.iterations);
    refl_lem_system_destroy(sys);
}

Test(lem_infer, damping_draws_faintly_seen_texels_towards_zero) {
    /* min (w x - w t)^2 + lambda^2 x^2 per texel gives x = w^2 t / (w^2 +
       lambda^2): at lambda 0.05 a texel seen with weight 1 keeps 1/1.0025
       of its value, one seen with weight 0.05 (a faint row) half of it */
    refl_lem_system *sys = NULL;
    refl_lem_solve_desc d;
    uint32_t t[2] = {0, 1};
    float one = 1.0f, faint = 0.05f, x[8], target[4] = {0.8f, 0.8f, 0.8f, 0.8f}, faint_target[4];
    int c;
    for (c = 0; c < 4; ++c) faint_target[c] = faint * target[c];
    cr_assert_eq(refl_lem_system_create(2, NULL, &sys), REFL_OK);
    cr_assert_eq(refl_lem_system_add_row(sys, &t[0], &one, 1, target, 1.0f), REFL_OK);
    cr_assert_eq(refl_lem_system_add_row(sys, &t[1], &faint, 1, faint_target, 1.0f), REFL_OK);
    memset(&d, 0, sizeof d);
    d.damping = 0.05f;
    d.nonnegative = 1;
    cr_assert_eq(refl_lem_solve(sys, &d, x, NULL), REFL_OK);
    for (c = 0; c < 4; ++c) {
        cr_assert_float_eq(x[c], 0.8f / 1.0025f, 1e-5f);
        cr_assert_float_eq(x[4 + c], 0.4f, 1e-5f);
    }
    /* undamped, both fit their rows exactly */
    d.damping = 0.0f;
    cr_assert_eq(refl_lem_solve(sys, &d, x, NULL), REFL_OK);
    cr_assert_float_eq(x[0], 0.8f, 1e-5f);
    cr_assert_float_eq(x[4], 0.8f, 1e-5f);
    d.damping = -0.1f;
    cr_assert_eq(refl_lem_solve(sys, &d, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
    d.damping = NAN;
    cr_assert_eq(refl_lem_solve(sys, &d, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
    d.damping = INFINITY;
    cr_assert_eq(refl_lem_solve(sys, &d, x, NULL), REFL_ERROR_INVALID_ARGUMENT);
    refl_lem_system_destroy(sys);
}

Test(lem_infer, confidence_weighs_rows) {
    /* one texel told 1 with confidence 1 and 0 with confidence 0.5:
       least squares of (x - 1)^2 + 0.25 x^2 gives 0.8; confidence 0 adds nothing */
    refl_lem_system *sys = NULL;
    uint32_t t = 0;
    float w = 1.0f, one[4] = {1, 1, 1, 1}, zero[4] = {0, 0, 0, 0}, x[4];
    cr_assert_eq(refl_lem_system_create(1, NULL, &sys), REFL_OK);
    cr_assert_eq(refl_lem_system_add_row(sys, &t, &w, 1, one, 1.0f), REFL_OK);
    cr_assert_eq(refl_lem_system_add_row(sys, &t, &w, 1, zero, 0.5f), REFL_OK);
    cr_assert_eq(refl_lem_system_add_row(sys, &t, &w, 1, zero, 0.0f), REFL_OK);
    cr_assert_eq(refl_lem_system_rows(sys), 2);
    cr_assert_eq(refl_lem_solve(sys, NULL, x, NULL), REFL_OK);
    cr_assert_float_eq(x[0], 0.8f, 1e-6f);
    /* bad rows refused */
    t = 1;
    cr_assert_eq(refl_lem_system_add_row(sys, &t, &w, 1, one, 1.0f), REFL_ERROR_INVALID_ARGUMENT);
    t = 0;
    w = NAN;
    cr_assert_eq(refl_lem_system_add_row(sys, &t, &w, 1, one, 1.0f), REFL_ERROR_INVALID_ARGUMENT);
    refl_lem_system_destroy(sys);
}

/* ---- the exact-shell scene ------------------------------------------------------ */

/* A texture of 4-texel checks on a colour ramp (every texel different), added to s. */
static int add_checker(refl_scene *s, float *tex, int w, int h) {
    int x, y;
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            float *p = tex + 4 * (y * w + x);
            int odd = ((x / 4) + (y / 4)) & 1;
            p[0] = odd ? 0.9f : 0.2f;
            p[1] = 0.2f + 0.6f * (float)x / w;
            p[2] = 0.2f + 0.6f * (float)y / h;
            p[3] = 1.0f;
        }
    return refl_scene_add_texture(s, w, h, tex);
}

/* A glass sphere of radius 1 (object 1) at the centre of a checkered
   sphere of radius 5 (object 0) lit by ambient light alone. */
static refl_scene *exact_shell_scene(void) {
    enum { W = 64, H = 32 };
    refl_scene *s = NULL;
    refl_mesh *shell = NULL, *lens = NULL;
    refl_material paper = refl_material_diffuse(1, 1, 1), glass = refl_material_glass(1.5f);
    static float tex[W * H * 4];
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    paper.texture = add_checker(s, tex, W, H);
    cr_assert_gt(paper.texture, 0);
    cr_assert_eq(refl_mesh_sphere(5.0f, 96, 48, NULL, &shell), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(1.0f, 48, 24, NULL, &lens), REFL_OK);
    cr_assert_eq(refl_scene_add(s, shell, &paper, refl_mat4_identity()), 0);
    glass.tint[0] = 1.0f, glass.tint[1] = 0.9f, glass.tint[2] = 0.8f;
    glass.attenuation = 0.1f;
    cr_assert_eq(refl_scene_add(s, lens, &glass, refl_mat4_identity()), 1);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 1.0f;
    return s;
}

/* Greedy RAYTRACE of v. */
static refl_frame *greedy_truth(const refl_scene *s, const refl_view *v) {
    refl_render_desc d = tu_refl_greedy_raytrace(2);
    return tu_refl_render(s, v, &d);
}

/* PSNR over the lens pixels of view v of the hybrid frame against greedy
   RAYTRACE: the truth's frame with every lens pixel made of the two
   terms, each its path's F G times the inferred shell's lookup. */
static double hybrid_psnr(const refl_scene *s, const refl_ray_caster *caster, const refl_view *v,
                          const refl_lem_shell *sh, const float *x) {
    refl_frame *truth, *hybrid;
    refl_image_error err;
    int px, py, k, c;
    truth = greedy_truth(s, v);
    hybrid = greedy_truth(s, v); /* overwritten pixel by pixel below */
    for (py = 0; py < v->height; ++py)
        for (px = 0; px < v->width; ++px) {
            size_t i = (size_t)py * (size_t)v->width + (size_t)px;
            refl_greedy_paths_result g;
            refl_vec3 o, dir;
            float rgb[3] = {0, 0, 0};
            int term;
            if (truth->stencil[i] != 2) continue;
            refl_view_ray(v, s, (float)px + 0.5f, (float)py + 0.5f, &o, &dir, NULL);
            refl_greedy_paths(s, caster, o, dir, 0, &g, NULL);
            for (term = 0; term < 2; ++term) {
                const refl_greedy_path *p = term ? &g.refract : &g.reflect;
                uint32_t tex[4];
                float w[4];
                if (!(p->fresnel > 0.0f) || !refl_lem_shell_lookup(sh, p->exit_origin, p->exit_direction, tex, w))
                    continue;
                for (c = 0; c < 3; ++c) {
                    float l = 0.0f;
                    for (k = 0; k < 4; ++k) l += w[k] * x[4 * tex[k] + (uint32_t)c];
                    rgb[c] += p->fresnel * p->attenuation[c] * l;
                }
            }
            for (c = 0; c < 3; ++c) hybrid->rgba[4 * i + (size_t)c] = rgb[c];
        }
    cr_assert_eq(refl_measure_image_error(hybrid, truth, 1, 0.0f, &err), REFL_OK);
    cr_assert_gt(err.pixels, 500);
    refl_frame_destroy(truth);
    refl_frame_destroy(hybrid);
    return err.psnr;
}

/* The w x h view at azimuth `degrees` on a circle of radius 3 around the lens. */
static refl_view orbit_view_sized(float degrees, int w, int h) {
    float a = degrees * DEG;
    return tu_refl_view(refl_v3(3.0f * sinf(a), 0.6f, 3.0f * cosf(a)), refl_v3(0, 0, 0), w, h);
}

static refl_view orbit_view(float degrees) { return orbit_view_sized(degrees, 96, 72); }

Test(lem_infer, exact_shell_one_layer_matches_greedy_raytrace) {
    tu_refl_traced tr = tu_refl_traced_scene(exact_shell_scene());
    refl_scene *s = tr.scene;
    refl_ray_caster caster = tr.caster;
    refl_lem_shell sh;
    refl_lem_system *sys = NULL;
    refl_lem_record_desc rd;
    refl_lem_record_stats rs;
    refl_lem_solve_stats st;
    refl_view v = orbit_view(0.0f);
    float *x;
    double at_sample, between;
    int k;
    memset(&sh, 0, sizeof sh);
    sh.center = refl_v3(0, 0, 0);
    sh.radius = 5.0f;
    sh.face_size = 24; /* about a texel per pixel of the lens's view: finer is underdetermined between samples */
    cr_assert_eq(refl_lem_system_create(6 * 24 * 24, NULL, &sys), REFL_OK);
    memset(&rd, 0, sizeof rd);
    rd.object = 1;
    rd.supersample = 1;
    cr_assert_eq(refl_lem_record_view(sys, s, &caster, &v, &sh, &rd, &rs), REFL_OK);
    cr_assert_gt(rs.pixels, 500);
    cr_assert_gt(rs.rows, 19 * rs.pixels / 10, "%d rows of %d pixels: nearly every lens pixel has both terms", rs.rows,
                 rs.pixels);
    /* simultaneous inference over views 8 degrees either side */
    for (k = -1; k <= 1; k += 2) {
        refl_view w = orbit_view(8.0f * (float)k);
        cr_assert_eq(refl_lem_record_view(sys, s, &caster, &w, &sh, &rd, NULL), REFL_OK);
    }
    x = (float *)malloc(sizeof(float) * 4 * 6 * 24 * 24);
    cr_assert_eq(refl_lem_solve(sys, NULL, x, &st), REFL_OK);
    at_sample = hybrid_psnr(s, &caster, &v, &sh, x);
    cr_assert_geq(at_sample, 35.0, "at the sample: PSNR %.2f dB (CG: %d iterations)", at_sample, st.iterations);
    /* midway between samples: a viewpoint no record was made from */
    v = orbit_view(4.0f);
    between = hybrid_psnr(s, &caster, &v, &sh, x);
    cr_assert_geq(between, 35.0, "between samples: PSNR %.2f dB", between);
    free(x);
    refl_lem_system_destroy(sys);
    tu_refl_traced_free(&tr);
}

/* ---- the method ------------------------------------------------------------------ */

static refl_frame *render_lem(const refl_scene *s, const refl_view *v, int threads) {
    refl_render_desc d = tu_refl_desc(REFL_LAYERED_EM, threads);
    return tu_refl_render(s, v, &d);
}

Test(layered_em, exact_shell_off_sample_matches_greedy_raytrace) {
    /* 45 samples 8 degrees apart, each inferred from its view and those 4
       degrees either side: at 3 degrees, between two samples and no view
       any map was inferred from */
    refl_scene *s = exact_shell_scene();
    refl_view v = orbit_view_sized(3.0f, 128, 96);
    refl_frame *truth, *lem;
    refl_image_error err;
    size_t i, n = (size_t)v.width * (size_t)v.height;
    truth = greedy_truth(s, &v);
    lem = render_lem(s, &v, 2);
    cr_assert_eq(refl_measure_image_error(lem, truth, 1, 0.0f, &err), REFL_OK);
    cr_assert_gt(err.pixels, 4000);
    cr_assert_geq(err.psnr, 35.0, "between samples: PSNR %.2f dB over %lld lens pixels", err.psnr, err.pixels);
    for (i = 0; i < 4 * n; ++i) cr_assert(lem->rgba[i] == lem->rgba[i], "no NaN");
    cr_assert_gt(lem->stats.rays, 0);
    refl_frame_destroy(truth);
    refl_frame_destroy(lem);
    refl_scene_destroy(s);
}

Test(layered_em, same_bytes_any_threads) {
    refl_scene *s = exact_shell_scene();
    refl_view v = orbit_view_sized(5.0f, 40, 30);
    refl_frame *a = render_lem(s, &v, 1), *b = render_lem(s, &v, 3);
    cr_assert_eq(tu_refl_digest(a), tu_refl_digest(b));
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    refl_scene_destroy(s);
}

Test(layered_em, options_validated) {
    refl_render_desc d;
    const char *why = NULL;
    memset(&d, 0, sizeof d);
    d.method = REFL_LAYERED_EM;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_OK);
    cr_assert(refl_method_is_built(REFL_LAYERED_EM));
    d.layered_em.samples = -1;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_str_eq(why, "layered_em.samples: 0 (45) to 3600");
    d.layered_em.samples = 0;
    d.layered_em.edge_px = NAN;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    d.layered_em.edge_px = 0.0f;
    d.layered_em.supersample = 9;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    d.layered_em.supersample = 0;
    d.layered_em.layers = REFL_LEM_MAX_LAYERS + 1;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_str_eq(why, "layered_em.layers: 0 (1) to 4");
    d.layered_em.layers = REFL_LEM_MAX_LAYERS;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_OK);
    d.layered_em.layers = -1;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    d.layered_em.layers = 0;
    d.layered_em.shell = REFL_LEM_SHELL_QUAD + 1;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    d.layered_em.shell = 0;
    d.layered_em.shell_frame = REFL_LEM_FRAME_FITTED + 1;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
    d.layered_em.shell_frame = 0;
    d.layered_em.direct_images = 2;
    cr_assert_eq(refl_validate_render_desc(&d, &why), REFL_ERROR_INVALID_ARGUMENT);
}

/* ---- maps kept by a renderer -------------------------------------------------------- */

static refl_render_desc lem_desc(int samples) {
    refl_render_desc d = tu_refl_desc(REFL_LAYERED_EM, 2);
    d.layered_em.samples = samples;
    return d;
}

Test(layered_em, a_kept_renderer_reuses_its_maps_with_a_fresh_ones_bytes) {
    /* 8 samples 45 degrees apart: views at 10 and 30 degrees share the
       samples at 0 and 45 */
    refl_scene *s = exact_shell_scene();
    refl_render_desc d = lem_desc(8);
    refl_renderer *rr = NULL;
    refl_view v10 = orbit_view_sized(10.0f, 48, 36), v30 = orbit_view_sized(30.0f, 48, 36);
    refl_frame *f = NULL, *fresh;
    unsigned long long first;
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_frame_create(48, 36, NULL, &f), REFL_OK);
    cr_assert_eq(refl_renderer_render(rr, &v10, f), REFL_OK);
    cr_assert_eq(f->stats.layered_em.maps_inferred, 2);
    cr_assert_eq(f->stats.layered_em.maps_kept, 0);
    cr_assert_eq(f->stats.layered_em.maps_held, 2);
    first = tu_refl_digest(f);
    cr_assert_eq(refl_renderer_render(rr, &v10, f), REFL_OK);
    cr_assert_eq(f->stats.layered_em.maps_inferred, 0, "the second frame infers nothing");
    cr_assert_eq(f->stats.layered_em.maps_kept, 2);
    cr_assert_eq(tu_refl_digest(f), first);
    cr_assert_eq(refl_renderer_render(rr, &v30, f), REFL_OK);
    cr_assert_eq(f->stats.layered_em.maps_inferred, 0, "another view between the same samples");
    fresh = tu_refl_render(s, &v30, &d);
    cr_assert_eq(tu_refl_digest(f), tu_refl_digest(fresh), "kept maps give a fresh renderer's bytes");
    cr_assert_eq(fresh->stats.layered_em.maps_inferred, 2);
    {
        /* nearer the lens and higher: the first frame's circle of samples still serves */
        refl_view near = tu_refl_view(refl_v3(2.5f * sinf(20.0f * DEG), 1.0f, 2.5f * cosf(20.0f * DEG)),
                                      refl_v3(0, 0, 0), 48, 36);
        cr_assert_eq(refl_renderer_render(rr, &near, f), REFL_OK);
        cr_assert_eq(f->stats.layered_em.maps_inferred, 0, "an eye off the circle takes its samples");
        cr_assert_eq(f->stats.layered_em.maps_kept, 2);
    }
    refl_scene_touch(s);
    cr_assert_eq(refl_renderer_render(rr, &v30, f), REFL_OK);
    cr_assert_eq(f->stats.layered_em.maps_inferred, 2, "a changed scene drops the maps");
    cr_assert_eq(f->stats.layered_em.maps_held, 2);
    refl_frame_destroy(fresh);
    refl_frame_destroy(f);
    refl_renderer_destroy(rr);
    refl_scene_destroy(s);
}

typedef struct lem_progress {
    int calls, stop_after;
    float last;
    int decreased;
} lem_progress;

static int lem_progress_fn(void *user, float done) {
    lem_progress *p = (lem_progress *)user;
    p->decreased |= done < p->last;
    p->last = done;
    return p->stop_after > 0 && ++p->calls >= p->stop_after;
}

Test(layered_em, prebuild_infers_every_sample_once_and_cancels) {
    refl_scene *s = exact_shell_scene();
    refl_render_desc d = lem_desc(6);
    refl_renderer *rr = NULL;
    refl_view v = orbit_view_sized(0.0f, 40, 30), w = orbit_view_sized(200.0f, 40, 30);
    refl_frame *f = NULL;
    lem_progress pr;
    memset(&pr, 0, sizeof pr);
    d.layered_em.single_view = 1;
    d.progress = lem_progress_fn;
    d.progress_user = &pr;
    cr_assert_eq(refl_frame_create(40, 30, NULL, &f), REFL_OK);
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_renderer_prebuild(rr, &v, f), REFL_OK);
    cr_assert_eq(f->stats.layered_em.maps_inferred, 6);
    cr_assert_eq(f->stats.layered_em.maps_held, 6);
    cr_assert_gt(f->stats.model_bytes, 0);
    cr_assert_eq(pr.last, 1.0f);
    cr_assert(!pr.decreased, "progress only grows");
    cr_assert_eq(refl_renderer_render(rr, &w, f), REFL_OK);
    cr_assert_eq(f->stats.layered_em.maps_inferred, 0, "any view on the circle finds its maps built");
    cr_assert_eq(f->stats.layered_em.maps_kept, 2);
    refl_renderer_destroy(rr);
    /* a callback that stops it after the second map */
    memset(&pr, 0, sizeof pr);
    pr.stop_after = 2;
    cr_assert_eq(refl_renderer_create(s, &d, &rr), REFL_OK);
    cr_assert_eq(refl_renderer_prebuild(rr, &v, f), REFL_ERROR_CANCELLED);
    cr_assert_str_eq(f->message, "cancelled by the progress callback");
    cr_assert_eq(f->stats.layered_em.maps_held, 2, "the maps finished stay kept");
    refl_renderer_destroy(rr);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* ---- a path leaving through another lens ------------------------------------------- */

Test(layered_em, a_path_leaving_through_another_lens_is_traced) {
    /* the hybrid scene's mirror cup (object 2) reflects the glass teapot
       (object 1): those greedy paths leave the lens system from the
       teapot, beyond the cup's shell, where its map knows nothing; the
       frame hands their pixels to the tracer instead of showing black */
    refl_builtin_desc bd;
    refl_scene *s0 = NULL;
    tu_refl_traced tr;
    refl_render_desc d;
    refl_view v;
    refl_frame *truth, *lem;
    refl_vec3 cup = refl_v3(1.2f, 0.28f, 0.7f);
    int x, y, beyond = 0, dark = 0;
    double err = 0.0;
    memset(&bd, 0, sizeof bd);
    cr_assert_eq(refl_scene_builtin("hybrid", &bd, &s0), REFL_OK);
    tr = tu_refl_traced_scene(s0);
    v = tr.scene->camera;
    v.width = 120;
    v.height = 90;
    d = tu_refl_desc(REFL_RAYTRACE, 2);
    truth = tu_refl_render(tr.scene, &v, &d);
    d = lem_desc(0);
    d.layered_em.single_view = 1;
    d.layered_em.face_size = 16;
    lem = tu_refl_render(tr.scene, &v, &d);
    for (y = 0; y < v.height; ++y)
        for (x = 0; x < v.width; ++x) {
            size_t i = (size_t)y * (size_t)v.width + (size_t)x;
            refl_greedy_paths_result g;
            refl_vec3 o, dir;
            float t = 0.0f, l = 0.0f;
            int c;
            refl_view_ray(&v, tr.scene, (float)x + 0.5f, (float)y + 0.5f, &o, &dir, NULL);
            refl_greedy_paths(tr.scene, &tr.caster, o, dir, d.depth, &g, NULL);
            if (g.object != 2 || !g.reflect.exited || refl_v3_length(refl_v3_sub(g.reflect.exit_origin, cup)) < 0.6f)
                continue;
            ++beyond;
            for (c = 0; c < 3; ++c) {
                t += truth->rgba[4 * i + (size_t)c] / 3.0f;
                l += lem->rgba[4 * i + (size_t)c] / 3.0f;
            }
            err += fabs((double)t - (double)l);
            dark += t > 0.1f && l < 0.02f;
        }
    cr_assert_gt(beyond, 10, "%d cup pixels show the teapot", beyond);
    cr_assert_eq(dark, 0, "%d of %d pixels black where the truth is not", dark, beyond);
    cr_assert_lt(err / beyond, 0.15, "mean error %.3f over %d pixels", err / beyond, beyond);
    cr_assert_gt(lem->stats.layered_em.traced_pixels, 0);
    refl_frame_destroy(truth);
    refl_frame_destroy(lem);
    tu_refl_traced_free(&tr);
}

/* The exact-shell scene with a mirror sphere of radius 0.5 (object 2)
   beside the glass one, reflecting it towards an eye at +z. */
static refl_scene *mirror_sees_glass_scene(void) {
    refl_scene *s = exact_shell_scene();
    refl_mesh *ball = NULL;
    refl_material mirror = refl_material_mirror(0.9f);
    cr_assert_eq(refl_mesh_sphere(0.5f, 48, 24, NULL, &ball), REFL_OK);
    cr_assert_eq(refl_scene_add(s, ball, &mirror, refl_mat4_translate(refl_v3(1.4f, 0.0f, 1.0f))), 2);
    return s;
}

Test(layered_em, another_lens_as_a_layer_needs_no_tracer) {
    /* the mirror's paths that meet the glass sphere leave the lens system
       from the glass: traced (lens_layers -1; the full ray tree, 20.0 dB
       against greedy RAYTRACE over those pixels), or with the glass a
       layer of the mirror's environment (1) looked up like the rest (19.9
       dB with two layers; asserted at most 0.5 dB under the tracer) */
    tu_refl_traced tr = tu_refl_traced_scene(mirror_sees_glass_scene());
    refl_view v = tu_refl_view(refl_v3(0.0f, 0.6f, 3.5f), refl_v3(0.7f, 0.0f, 0.5f), 96, 72);
    refl_render_desc d;
    refl_frame *truth = greedy_truth(tr.scene, &v), *lem[2];
    double se[2] = {0.0, 0.0}, psnr[2];
    long long traced[2];
    int mode, through = 0, x, y, c;
    for (mode = 0; mode < 2; ++mode) {
        d = lem_desc(8);
        d.layered_em.lens_layers = mode ? 1 : -1;
        d.layered_em.layers = 2; /* the glass a layer of its own (one: merged with the shell) */
        lem[mode] = tu_refl_render(tr.scene, &v, &d);
        traced[mode] = lem[mode]->stats.layered_em.traced_pixels;
    }
    for (y = 0; y < v.height; ++y)
        for (x = 0; x < v.width; ++x) {
            size_t i = (size_t)y * (size_t)v.width + (size_t)x;
            refl_greedy_paths_result g;
            refl_vec3 o, dir;
            refl_view_ray(&v, tr.scene, (float)x + 0.5f, (float)y + 0.5f, &o, &dir, NULL);
            refl_greedy_paths(tr.scene, &tr.caster, o, dir, d.depth, &g, NULL);
            if (g.object != 2 || !g.reflect.exited ||
                refl_v3_length(refl_v3_sub(g.reflect.exit_origin, refl_v3(1.4f, 0.0f, 1.0f))) < 0.6f)
                continue;
            ++through;
            for (mode = 0; mode < 2; ++mode)
                for (c = 0; c < 3; ++c) {
                    double e = fmin(fmax(lem[mode]->rgba[4 * i + (size_t)c], 0.0), 1.0) -
                               fmin(fmax(truth->rgba[4 * i + (size_t)c], 0.0), 1.0);
                    se[mode] += e * e;
                }
        }
    for (mode = 0; mode < 2; ++mode) psnr[mode] = 10.0 * log10(3.0 * through / fmax(se[mode], 1e-12));
    cr_log_info("mirror sees glass: %d pixels; traced %.2f dB (%lld traced), a layer %.2f dB (%lld traced)", through,
                psnr[0], traced[0], psnr[1], traced[1]);
    cr_assert_gt(through, 30, "%d mirror pixels show the glass", through);
    cr_assert_geq(traced[0], through / 2, "traced: %lld of %d", traced[0], through);
    cr_assert_lt(traced[1], through / 10, "a layer: %lld of %d still traced", traced[1], through);
    cr_assert_geq(psnr[1], psnr[0] - 0.5, "a layer %.2f dB, traced %.2f dB", psnr[1], psnr[0]);
    refl_frame_destroy(truth);
    refl_frame_destroy(lem[0]);
    refl_frame_destroy(lem[1]);
    tu_refl_traced_free(&tr);
}

/* ---- several layers ------------------------------------------------------------------ */

Test(lem_infer, lbg_separates_two_distance_groups_keeping_objects_whole) {
    /* object 0 near 2, object 1 near 10; object 2 mostly near 10 with a
       few hits near 3, which the whole-object rule keeps with the rest;
       ray 7 meets layer 1 twice (10 then 14): only the front one counts */
    float dist[24], radius[REFL_LEM_MAX_LAYERS];
    int obj[24], ray[24], layer[24], n = 0, i, k;
    for (i = 0; i < 8; ++i) dist[n] = 1.9f + 0.025f * (float)i, obj[n] = 0, ray[n] = i, ++n;
    for (i = 0; i < 6; ++i) dist[n] = 9.5f + 0.2f * (float)i, obj[n] = 1, ray[n] = 8 + i, ++n;
    for (i = 0; i < 5; ++i) dist[n] = 10.0f, obj[n] = 2, ray[n] = 14 + i, ++n;
    for (i = 0; i < 2; ++i) dist[n] = 3.0f, obj[n] = 2, ray[n] = 19 + i, ++n;
    /* ray 7 (object 0 at 2.075) continues to object 1 at 10 and 14 */
    dist[n] = 10.0f, obj[n] = 1, ray[n] = 7, ++n;
    dist[n] = 14.0f, obj[n] = 1, ray[n] = 7, ++n;
    /* put ray 7's continued hits right after its first (hits of a ray come together) */
    {
        float d7[3] = {dist[7], dist[n - 2], dist[n - 1]};
        int o7[3] = {obj[7], obj[n - 2], obj[n - 1]};
        for (k = n - 1; k > 9; --k) dist[k] = dist[k - 2], obj[k] = obj[k - 2], ray[k] = ray[k - 2];
        for (k = 0; k < 3; ++k) dist[7 + k] = d7[k], obj[7 + k] = o7[k], ray[7 + k] = 7;
    }
    cr_assert_eq(refl_lem_cluster_layers(dist, obj, ray, n, 2, NULL, radius, layer), 2);
    for (i = 0; i < n; ++i)
        cr_assert_eq(layer[i], obj[i] == 0 ? 0 : 1, "hit %d (object %d at %.2f) in layer %d", i, obj[i], dist[i],
                     layer[i]);
    {
        /* layer 1's front-most hits: object 1's six, ray 7's 10, object 2's five at 10 and two at 3 */
        double want = 0.0;
        for (i = 0; i < 6; ++i) want += 9.5 + 0.2 * i;
        want = (want + 10.0 + 5 * 10.0 + 2 * 3.0) / 14.0;
        cr_assert_float_eq(radius[0], 1.9f + 0.025f * 3.5f, 1e-4f);
        cr_assert_float_eq(radius[1], (float)want, 1e-4f, "%f against %f", radius[1], want);
    }
    /* one layer: the mean of every ray's front-most hit */
    cr_assert_eq(refl_lem_cluster_layers(dist, obj, ray, n, 1, NULL, radius, layer), 1);
    for (i = 0; i < n; ++i) cr_assert_eq(layer[i], 0);
    /* more layers asked than there are distances apart: none left empty */
    cr_assert_eq(refl_lem_cluster_layers(dist, NULL, NULL, 3, 3, NULL, radius, NULL), 3);
    cr_assert_eq(refl_lem_cluster_layers(dist, NULL, NULL, 0, 2, NULL, radius, NULL), 0);
}

Test(lem_infer, lbg_orders_layers_front_to_back_along_the_rays) {
    /* a teapot (object 1, six hits at 4) standing on a floor (object 0):
       ten rays meet the floor alone at 1 to 2, six meet the teapot and,
       continued, the floor behind it at 5 to 6. The floor's front-most
       hits lie nearer on average (3.0) than the teapot's (4.0), but the
       rays meet the teapot first: its layer composites first */
    float dist[22], radius[REFL_LEM_MAX_LAYERS];
    int obj[22], ray[22], layer[22], n = 0, i;
    for (i = 0; i < 10; ++i) dist[n] = 1.0f + 0.1f * (float)i, obj[n] = 0, ray[n] = i, ++n;
    for (i = 0; i < 6; ++i) {
        dist[n] = 4.0f, obj[n] = 1, ray[n] = 10 + i, ++n;
        dist[n] = 5.0f + 0.2f * (float)i, obj[n] = 0, ray[n] = 10 + i, ++n;
    }
    cr_assert_eq(refl_lem_cluster_layers(dist, obj, ray, n, 2, NULL, radius, layer), 2);
    for (i = 0; i < n; ++i)
        cr_assert_eq(layer[i], obj[i] == 1 ? 0 : 1, "hit %d (object %d at %.2f) in layer %d", i, obj[i], dist[i],
                     layer[i]);
    cr_assert_float_eq(radius[0], 4.0f, 1e-4f);
    cr_assert_float_eq(radius[1], (14.5f + 33.0f) / 16.0f, 1e-4f, "%f", radius[1]);
    /* without the rays, by distance */
    cr_assert_eq(refl_lem_cluster_layers(dist, obj, NULL, n, 2, NULL, radius, layer), 2);
    cr_assert_eq(layer[0], 0);
    cr_assert_eq(layer[10], 1);
}

/* The exact-shell scene with an inner partial shell: the cap (z < -1.2,
   behind the lens from the orbit's views, where the refraction looks) of
   a sphere of radius 2.5 (object 2), checkered as the outer one. */
static refl_scene *inner_shell_scene(void) {
    refl_scene *s = exact_shell_scene();
    refl_mesh *sphere = NULL, *half = NULL;
    refl_mesh_desc md;
    refl_material inner = s->materials[s->objects[0].material];
    uint32_t *idx;
    int t, n = 0;
    cr_assert_eq(refl_mesh_sphere(2.5f, 64, 32, NULL, &sphere), REFL_OK);
    idx = (uint32_t *)malloc(sizeof(uint32_t) * 3 * (size_t)sphere->triangle_count);
    for (t = 0; t < sphere->triangle_count; ++t) {
        const uint32_t *tri = sphere->indices + 3 * t;
        float cx = sphere->positions[3 * tri[0]] + sphere->positions[3 * tri[1]] + sphere->positions[3 * tri[2]];
        float cz = sphere->positions[3 * tri[0] + 2] + sphere->positions[3 * tri[1] + 2] +
                   sphere->positions[3 * tri[2] + 2];
        (void)cx;
        if (cz >= -3.6f) continue;
        memcpy(idx + 3 * n++, tri, 3 * sizeof(uint32_t));
    }
    memset(&md, 0, sizeof md);
    md.positions = sphere->positions;
    md.vertex_count = sphere->vertex_count;
    md.texcoords = sphere->texcoords;
    md.indices = idx;
    md.index_count = 3 * n;
    cr_assert_eq(refl_mesh_create(&md, &half), REFL_OK);
    cr_assert_eq(refl_scene_add(s, half, &inner, refl_mat4_identity()), 2);
    free(idx);
    refl_mesh_destroy(sphere);
    return s;
}

Test(layered_em, an_inner_partial_shell_needs_two_layers) {
    /* at a sample: one sphere shell must stand for both the inner cap and
       the outer sphere, two fit them exactly */
    refl_scene *s = inner_shell_scene();
    refl_view v = orbit_view_sized(0.0f, 96, 72);
    refl_render_desc d;
    refl_frame *truth, *lem;
    refl_image_error err[2];
    int layers;
    truth = greedy_truth(s, &v);
    for (layers = 1; layers <= 2; ++layers) {
        d = lem_desc(0);
        d.layered_em.layers = layers;
        lem = tu_refl_render(s, &v, &d);
        cr_assert_eq(refl_measure_image_error(lem, truth, 1, 0.0f, &err[layers - 1]), REFL_OK);
        refl_frame_destroy(lem);
    }
    cr_assert_gt(err[1].pixels, 2000);
    cr_assert_lt(err[0].psnr, 35.0, "one layer: PSNR %.2f dB", err[0].psnr);
    cr_assert_geq(err[1].psnr, 35.0, "two layers: PSNR %.2f dB (one: %.2f dB)", err[1].psnr, err[0].psnr);
    /* the most layers: LBG splits the two groups further, still exact */
    d = lem_desc(0);
    d.layered_em.layers = REFL_LEM_MAX_LAYERS;
    lem = tu_refl_render(s, &v, &d);
    cr_assert_eq(refl_measure_image_error(lem, truth, 1, 0.0f, &err[0]), REFL_OK);
    cr_assert_geq(err[0].psnr, 35.0, "%d layers: PSNR %.2f dB", REFL_LEM_MAX_LAYERS, err[0].psnr);
    refl_frame_destroy(lem);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* ---- shells of other kinds ------------------------------------------------------------ */

static refl_lem_shell framed_shell(int kind, refl_vec3 centre, float e0, float e1, float e2) {
    refl_lem_shell sh;
    memset(&sh, 0, sizeof sh);
    sh.kind = kind;
    sh.center = centre;
    sh.axis[0] = refl_v3(1, 0, 0);
    sh.axis[1] = refl_v3(0, 1, 0);
    sh.axis[2] = refl_v3(0, 0, 1);
    sh.extent[0] = e0, sh.extent[1] = e1, sh.extent[2] = e2;
    sh.face_size = 8;
    return sh;
}

static void assert_index(const refl_lem_shell *sh, refl_vec3 o, refl_vec3 d, float x, float y, float z) {
    refl_vec3 ix;
    cr_assert(refl_lem_shell_index(sh, o, refl_v3_normalize(d), &ix), "kind %d: a lookup", sh->kind);
    cr_assert(fabsf(ix.x - x) < 1e-5f && fabsf(ix.y - y) < 1e-5f && fabsf(ix.z - z) < 1e-5f,
              "kind %d: index (%g %g %g), expected (%g %g %g)", sh->kind, ix.x, ix.y, ix.z, x, y, z);
}

Test(lem_infer, shell_index_of_every_kind) {
    refl_lem_shell sh;
    refl_vec3 ix, c = refl_v3(1, 2, 3);
    uint32_t tex[4];
    float w[4];
    /* a sphere of radius 2: the hit minus the centre, where the ray leaves
       it from inside and enters it from outside (an inner layer's sphere);
       none past it or away from it */
    memset(&sh, 0, sizeof sh);
    sh.kind = REFL_LEM_SHELL_SPHERE, sh.center = c, sh.radius = 2.0f, sh.face_size = 8;
    assert_index(&sh, c, refl_v3(1, 0, 0), 2, 0, 0);
    assert_index(&sh, refl_v3(1, 2, 4), refl_v3(0, 0, 1), 0, 0, 2);
    assert_index(&sh, refl_v3(5, 2, 3), refl_v3(-1, 0, 0), 2, 0, 0);
    cr_assert_not(refl_lem_shell_index(&sh, refl_v3(5, 2, 3), refl_v3(1, 0, 0), &ix));
    cr_assert_not(refl_lem_shell_index(&sh, refl_v3(5, 4.5f, 3), refl_v3(-1, 0, 0), &ix));
    {
        /* a sphere that does not hold a lens's box may miss its exit rays */
        refl_vec3 inside[2] = {refl_v3(0, 1, 2), refl_v3(2, 3, 4)}, wider[2] = {refl_v3(0, 1, 0), refl_v3(2, 3, 4)};
        cr_assert_not(refl_lem_shell_partial(&sh, inside));
        cr_assert(refl_lem_shell_partial(&sh, wider));
    }
    /* a box of half sides 2, 3, 4: the nearest slab's exit, over the half sides */
    sh = framed_shell(REFL_LEM_SHELL_BOX, c, 2, 3, 4);
    assert_index(&sh, refl_v3(1.5f, 2, 3), refl_v3(1, 0, 0), 1, 0, 0);
    assert_index(&sh, c, refl_v3(1, 1, 0), 1, 2.0f / 3.0f, 0);
    assert_index(&sh, c, refl_v3(0, -1, -2), 0, -2.0f / 3.0f, -1); /* z first: at 2, y is -2 of 3 */
    cr_assert_not(refl_lem_shell_index(&sh, refl_v3(4, 2, 3), refl_v3(-1, 0, 0), &ix));
    /* a cylinder of radius 2 and half height 1 around y: side or cap, the nearer */
    sh = framed_shell(REFL_LEM_SHELL_CYLINDER, c, 2, 1, 2);
    assert_index(&sh, c, refl_v3(1, 0, 0), 1, 0, 0);
    assert_index(&sh, c, refl_v3(0, 1, 0), 0, 1, 0);
    assert_index(&sh, c, refl_v3(1, 1, 0), 0.5f, 1, 0);    /* the cap first: t = 1.41 < 2.83 */
    assert_index(&sh, c, refl_v3(0, 0.25f, -1), 0, 0.5f, -1); /* the side first */
    assert_index(&sh, refl_v3(2, 2, 3), refl_v3(0, 0, 1), 0.5f, 0, sqrtf(3.0f) / 2.0f);
    cr_assert_not(refl_lem_shell_index(&sh, refl_v3(1, 3.5f, 3), refl_v3(0, -1, 0), &ix)); /* above it */
    /* a quad 2 x 1 either side of (1, 2, 8), facing z: ahead and inside only */
    sh = framed_shell(REFL_LEM_SHELL_QUAD, refl_v3(1, 2, 8), 2, 1, 0);
    assert_index(&sh, c, refl_v3(0, 0, 1), 0, 0, 1);
    assert_index(&sh, c, refl_v3(0.2f, 0.1f, 1), 0.5f, 0.5f, 1);
    cr_assert_not(refl_lem_shell_index(&sh, c, refl_v3(0, 0, -1), &ix)); /* away from it */
    cr_assert_not(refl_lem_shell_index(&sh, c, refl_v3(1, 0, 1), &ix));  /* past its side */
    cr_assert_not(refl_lem_shell_index(&sh, c, refl_v3(1, 0, 0), &ix));  /* along it */
    /* a quad's lookups all land on the +z face */
    cr_assert(refl_lem_shell_lookup(&sh, c, refl_v3_normalize(refl_v3(-0.3f, 0.15f, 1)), tex, w));
    cr_assert_geq(tex[0], 4u * 64u);
    cr_assert_lt(tex[3], 5u * 64u);
}

/* A room (object 0: mesh `room`, checkered, placed by `place`) around a
   glass sphere of radius 1 at the origin; ambient light. */
static refl_scene *room_scene(refl_mesh *room, refl_mat4 place) {
    enum { W = 32, H = 32 };
    refl_scene *s = NULL;
    refl_mesh *lens = NULL;
    refl_material paper = refl_material_diffuse(1, 1, 1), glass = refl_material_glass(1.5f);
    static float tex[W * H * 4];
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    paper.texture = add_checker(s, tex, W, H);
    cr_assert_eq(refl_mesh_sphere(1.0f, 48, 24, NULL, &lens), REFL_OK);
    cr_assert_eq(refl_scene_add(s, room, &paper, place), 0);
    glass.tint[0] = 1.0f, glass.tint[1] = 0.9f, glass.tint[2] = 0.8f;
    glass.attenuation = 0.1f;
    cr_assert_eq(refl_scene_add(s, lens, &glass, refl_mat4_identity()), 1);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 1.0f;
    return s;
}

/* A box room 10 x 6 x 8 placed by `place` around the lens. */
static refl_scene *placed_box_room_scene(refl_mat4 place) {
    refl_mesh *room = NULL;
    cr_assert_eq(refl_mesh_box(refl_v3(10.0f, 6.0f, 8.0f), NULL, &room), REFL_OK);
    return room_scene(room, place);
}

/* The room centred at (1.5, 1, -0.5), on the world axes: the lens off its centre. */
static refl_scene *box_room_scene(void) {
    return placed_box_room_scene(refl_mat4_translate(refl_v3(1.5f, 1.0f, -0.5f)));
}

/* PSNR over the lens of LAYERED_EM (shell kind on frames `frame`, face
   size, layers) against truth, greedy RAYTRACE's frame of the same view
   (one for the shells a test compares). */
static double lem_psnr_framed(const refl_scene *s, const refl_view *v, const refl_frame *truth, int kind, int frame,
                              int face, int layers, long long *quad_misses) {
    refl_render_desc d;
    refl_frame *lem;
    refl_image_error err;
    d = lem_desc(0);
    d.layered_em.shell = kind;
    d.layered_em.shell_frame = frame;
    d.layered_em.face_size = face;
    d.layered_em.layers = layers;
    lem = tu_refl_render(s, v, &d);
    cr_assert_eq(refl_measure_image_error(lem, truth, 1, 0.0f, &err), REFL_OK);
    cr_assert_gt(err.pixels, 1000);
    if (quad_misses) *quad_misses = lem->stats.layered_em.quad_misses;
    refl_frame_destroy(lem);
    return err.psnr;
}

static double lem_psnr(const refl_scene *s, const refl_view *v, const refl_frame *truth, int kind, int layers,
                       long long *quad_misses) {
    return lem_psnr_framed(s, v, truth, kind, REFL_LEM_FRAME_AUTO, 0, layers, quad_misses);
}

Test(layered_em, a_box_shell_fits_a_box_room_better_than_a_sphere) {
    refl_scene *s = box_room_scene();
    refl_view v = orbit_view_sized(3.0f, 96, 72);
    refl_frame *truth = greedy_truth(s, &v);
    double sphere = lem_psnr(s, &v, truth, REFL_LEM_SHELL_SPHERE, 1, NULL);
    double box = lem_psnr(s, &v, truth, REFL_LEM_SHELL_BOX, 1, NULL);
    double automatic = lem_psnr(s, &v, truth, REFL_LEM_SHELL_AUTO, 1, NULL);
    cr_log_info("box room: sphere %.2f dB, box %.2f dB, auto %.2f dB", sphere, box, automatic);
    cr_assert_geq(box, sphere + 1.5, "box %.2f dB, sphere %.2f dB", box, sphere);
    cr_assert_eq(automatic, box, "AUTO takes the box: %.2f dB against %.2f", automatic, box);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* A closed cylinder around the y axis (radius r, half height h, 48
   slices), its side's texture once around, its caps' a disc. */
static refl_mesh *cylinder_mesh(float r, float h) {
    enum { S = 48, V = 2 * (S + 1) + 2 * (S + 2) };
    static float pos[3 * V], uv[2 * V];
    static uint32_t idx[3 * 4 * S];
    refl_mesh_desc md;
    refl_mesh *m = NULL;
    int i, v = 0, t = 0, cap;
    for (i = 0; i <= S; ++i) { /* the side: bottom and top rings */
        float a = 2.0f * 3.14159265f * (float)i / S;
        int k;
        for (k = 0; k < 2; ++k, ++v) {
            pos[3 * v] = r * cosf(a), pos[3 * v + 1] = k ? h : -h, pos[3 * v + 2] = r * sinf(a);
            uv[2 * v] = (float)i / S, uv[2 * v + 1] = (float)k;
        }
        if (i < S) {
            uint32_t b = (uint32_t)(2 * i);
            idx[t++] = b, idx[t++] = b + 3, idx[t++] = b + 2; /* counter-clockwise from outside */
            idx[t++] = b, idx[t++] = b + 1, idx[t++] = b + 3;
        }
    }
    for (cap = 0; cap < 2; ++cap) { /* a centre and a ring each */
        uint32_t c = (uint32_t)v;
        float y = cap ? h : -h;
        pos[3 * v] = 0.0f, pos[3 * v + 1] = y, pos[3 * v + 2] = 0.0f, uv[2 * v] = uv[2 * v + 1] = 0.5f, ++v;
        for (i = 0; i <= S; ++i, ++v) {
            float a = 2.0f * 3.14159265f * (float)i / S;
            pos[3 * v] = r * cosf(a), pos[3 * v + 1] = y, pos[3 * v + 2] = r * sinf(a);
            uv[2 * v] = 0.5f + 0.5f * cosf(a), uv[2 * v + 1] = 0.5f + 0.5f * sinf(a);
            if (i < S) {
                idx[t++] = c;
                idx[t++] = c + 1 + (uint32_t)(cap ? i + 1 : i);
                idx[t++] = c + 1 + (uint32_t)(cap ? i : i + 1);
            }
        }
    }
    memset(&md, 0, sizeof md);
    md.positions = pos, md.texcoords = uv, md.indices = idx;
    md.vertex_count = v, md.index_count = t;
    cr_assert_eq(refl_mesh_create(&md, &m), REFL_OK);
    return m;
}

/* A room turned off the world axes needs a box or cylinder shell off
   them: the box room turned 30 degrees about the vertical and 20 about
   its own x axis, and a cylinder room (radius 4.5, height 7) tilted 25
   degrees off the vertical, each around the glass sphere off its centre,
   seen between two samples (4 degrees) with 48-texel faces (fine enough
   that the shell's place, not its texels, sets the error). The shell on
   the frame fitted to the hits shows the room as the world-axis one
   cannot, and AUTO takes it (on the cylinder room the box of the
   cylinder's fitted frame or the cylinder, their conflicts within the
   margin). Each room is a test of its own (run in parallel under --jobs),
   its three shells measured against one truth. */
ParameterizedTestParameters(layered_em, oriented_shells_fit_turned_rooms) {
    static int kinds[] = {REFL_LEM_SHELL_BOX, REFL_LEM_SHELL_CYLINDER};
    return cr_make_param_array(int, kinds, sizeof kinds / sizeof *kinds);
}

ParameterizedTest(int *kind, layered_em, oriented_shells_fit_turned_rooms, .timeout = 120) {
    refl_mat4 turn = refl_mat4_mul(refl_mat4_rotate(refl_v3(0, 1, 0), 30.0f * DEG),
                                   refl_mat4_rotate(refl_v3(1, 0, 0), 20.0f * DEG));
    refl_mat4 tilt = refl_mat4_mul(refl_mat4_rotate(refl_v3(0, 1, 0), 40.0f * DEG),
                                   refl_mat4_rotate(refl_v3(0, 0, 1), 25.0f * DEG));
    int box = *kind == REFL_LEM_SHELL_BOX;
    refl_scene *s = box ? placed_box_room_scene(refl_mat4_mul(refl_mat4_translate(refl_v3(1.5f, 1.0f, -0.5f)), turn))
                        : room_scene(cylinder_mesh(4.5f, 3.5f),
                                     refl_mat4_mul(refl_mat4_translate(refl_v3(0.8f, 0.5f, -0.6f)), tilt));
    refl_view v = orbit_view_sized(4.0f, 96, 72);
    refl_frame *truth = greedy_truth(s, &v);
    double world = lem_psnr_framed(s, &v, truth, *kind, REFL_LEM_FRAME_WORLD, 48, 1, NULL);
    double fitted = lem_psnr_framed(s, &v, truth, *kind, REFL_LEM_FRAME_FITTED, 48, 1, NULL);
    double automatic = lem_psnr_framed(s, &v, truth, REFL_LEM_SHELL_AUTO, REFL_LEM_FRAME_AUTO, 48, 1, NULL);
    if (box) {
        cr_log_info("turned box room: world-axis box %.2f dB, fitted %.2f, AUTO %.2f", world, fitted, automatic);
        cr_assert_geq(fitted, 34.0, "fitted box %.2f dB", fitted);
        cr_assert_geq(fitted, world + 2.5, "fitted box %.2f dB, world-axis %.2f", fitted, world);
        cr_assert_eq(automatic, fitted, "AUTO takes the fitted box: %.2f dB against %.2f", automatic, fitted);
    } else {
        cr_log_info("tilted cylinder room: world-axis cylinder %.2f dB, fitted %.2f, AUTO %.2f", world, fitted,
                    automatic);
        cr_assert_geq(fitted, 35.0, "fitted cylinder %.2f dB", fitted);
        cr_assert_geq(fitted, world + 4.0, "fitted cylinder %.2f dB, world-axis %.2f", fitted, world);
        cr_assert_geq(automatic, fitted - 0.5, "AUTO %.2f dB, fitted cylinder %.2f", automatic, fitted);
    }
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* A checkered wall 3 x 3 (object 2) at z = -2.5 behind the exact-shell
   scene's glass sphere, facing it: a sparse inner layer. */
static refl_scene *wall_scene(void) {
    enum { W = 16, H = 16 };
    refl_scene *s = exact_shell_scene();
    refl_mesh *wall = NULL;
    refl_material paint = refl_material_diffuse(1, 1, 1);
    static float tex[W * H * 4];
    int x, y;
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            float *p = tex + 4 * (y * W + x);
            int odd = ((x / 4) + (y / 4)) & 1;
            p[0] = 0.1f + 0.8f * (float)y / H;
            p[1] = odd ? 0.1f : 0.8f;
            p[2] = 0.1f + 0.8f * (float)x / W;
            p[3] = 1.0f;
        }
    paint.texture = refl_scene_add_texture(s, W, H, tex);
    cr_assert_eq(refl_mesh_plane(3.0f, 4, NULL, &wall), REFL_OK);
    cr_assert_eq(refl_scene_add(s, wall, &paint,
                                refl_mat4_mul(refl_mat4_translate(refl_v3(0, 0, -2.5f)),
                                              refl_mat4_rotate(refl_v3(1, 0, 0), 1.5707963f))),
                 2);
    return s;
}

Test(layered_em, a_quad_layer_recovers_a_wall_behind_the_lens) {
    /* two layers, between samples: the wall on a sphere shell smears it
       over directions it does not cover; on its quad it is exact, and the
       exit rays past the quad see the outer sphere */
    refl_scene *s = wall_scene();
    refl_view v = orbit_view_sized(3.0f, 96, 72);
    refl_frame *truth = greedy_truth(s, &v);
    long long misses = 0;
    double spheres = lem_psnr(s, &v, truth, REFL_LEM_SHELL_SPHERE, 2, NULL);
    double quad = lem_psnr(s, &v, truth, REFL_LEM_SHELL_QUAD, 2, &misses);
    double automatic = lem_psnr(s, &v, truth, REFL_LEM_SHELL_AUTO, 2, NULL);
    cr_log_info("wall: two spheres %.2f dB, quad + sphere %.2f dB (%lld misses), auto %.2f dB", spheres, quad, misses,
                automatic);
    cr_assert_geq(quad, spheres + 2.0, "quad %.2f dB, spheres %.2f dB", quad, spheres);
    cr_assert_geq(quad, 33.0, "quad %.2f dB", quad);
    cr_assert_gt(misses, 0, "exit rays past the quad are counted");
    /* AUTO may take the box of the wall's hits and the lens (its back face
       the wall's plane) instead: as exact on the wall, and its lookup is
       defined past the wall's edges, where the quad leaves the layer out */
    cr_assert_geq(automatic, quad, "AUTO recovers the wall as well as the quad: %.2f dB against %.2f", automatic, quad);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* ---- direct images against disocclusion ------------------------------------------------- */

/* LAYERED_EM on a built-in scene at 80 x 60 with layers[0], then
   layers[1] layers, against one greedy RAYTRACE frame: PSNR over the lens
   pixels, and the reflection errors when err is not NULL. */
static void builtin_lem_psnrs(const char *name, const int layers[2], double psnr[2], refl_reflection_error *err) {
    refl_view v;
    refl_scene *s = tu_refl_builtin(name, &v, 80, 60);
    refl_render_desc d;
    refl_frame *truth, *lem;
    refl_image_error img;
    int k;
    truth = greedy_truth(s, &v);
    for (k = 0; k < 2; ++k) {
        d = lem_desc(0);
        d.layered_em.layers = layers[k];
        lem = tu_refl_render(s, &v, &d);
        cr_assert_eq(refl_measure_image_error(lem, truth, 1, 0.0f, &img), REFL_OK);
        cr_assert_gt(img.pixels, 1000);
        if (err) cr_assert_eq(refl_measure_reflection_error(lem, truth, NULL, &err[k]), REFL_OK);
        psnr[k] = img.psnr;
        refl_frame_destroy(lem);
    }
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

Test(layered_em, a_ball_at_a_concave_mirrors_focus_is_an_inner_layer) {
    /* `concave`: the ball sits at the bowl's focus, inside the lens's own
       bounds, where the reflected rays converge. Three layers asked: LBG
       gives the ball a layer of its own, a sphere around the bowl's centre
       at the ball's distance that the exit rays enter from outside (left
       out where they miss it), the floor and sky the outer one. One layer
       cannot show it (a limit of a shell around the lens: the rays through
       the focus cross the same texels whether they meet the ball or pass
       it, and the map breaks into rings) */
    static const int layers[2] = {1, 3};
    refl_reflection_error err[2];
    double psnr[2], one, three;
    builtin_lem_psnrs("concave", layers, psnr, err);
    one = psnr[0], three = psnr[1];
    cr_log_info("concave 80x60: one layer %.2f dB, %.2f px; three %.2f dB, %.2f px", one, err[0].mean, three,
                err[1].mean);
    cr_assert_geq(three, 28.0, "three layers %.2f dB", three);
    cr_assert_lt(err[1].mean, 1.5, "three layers %.2f px", err[1].mean);
    cr_assert_lt(one, 22.0, "one layer %.2f dB: the rings are this method's limit, documented", one);
}

Test(layered_em, a_teapot_seen_in_a_mirror_stays_whole_on_three_layers) {
    /* `mirror-room`: with three layers the back mirror's floor and the
       teapot on it get layers of their own. The teapot's rays meet it
       before the floor behind it, so its layer composites first, though
       the floor's hits lie nearer on average: three layers show the scene
       as well as one (by mean distance the floor came first, its holes
       behind the teapot let a streaked teapot through, 5 dB under) */
    static const int layers[2] = {1, 3};
    double psnr[2], one, three;
    builtin_lem_psnrs("mirror-room", layers, psnr, NULL);
    one = psnr[0], three = psnr[1];
    cr_log_info("mirror-room 80x60: one layer %.2f dB, three %.2f dB", one, three);
    cr_assert_geq(three, one - 1.0, "three layers %.2f dB, one %.2f dB", three, one);
}

/* Pixels of the lens (stencil 2) under half as bright as a bright truth. */
static int dark_lens_pixels(const refl_frame *truth, const refl_frame *f) {
    size_t i, n = (size_t)f->width * (size_t)f->height;
    int dark = 0;
    for (i = 0; i < n; ++i) {
        const float *t = truth->rgba + 4 * i, *l = f->rgba + 4 * i;
        dark += truth->stencil[i] == 2 && t[0] + t[1] + t[2] > 0.3f && l[0] + l[1] + l[2] < 0.5f * (t[0] + t[1] + t[2]);
    }
    return dark;
}

/* Lens pixels drawn more than twice as bright as the truth and a quarter over it. */
static int bright_lens_pixels(const refl_frame *truth, const refl_frame *f) {
    size_t i, n = (size_t)f->width * (size_t)f->height;
    int bright = 0, c;
    for (i = 0; i < n; ++i)
        for (c = 0; c < 3 && truth->stencil[i] == 2; ++c)
            if (f->rgba[4 * i + c] > 2.0f * truth->rgba[4 * i + c] + 0.25f) {
                ++bright;
                break;
            }
    return bright;
}

Test(layered_em, direct_images_fill_what_the_samples_never_saw) {
    /* 4 samples 90 degrees apart, each from its own view alone: at 45
       degrees the lens shows parts of the sphere no sample's records met
       (their texels stay empty); the direct images from the lens's centre
       fill them. Without them, the texels that only a few faint rows reach
       are damped towards 0 (dark), not set to whatever fits those rows
       (bright specks) */
    refl_scene *s = exact_shell_scene();
    refl_view v = orbit_view_sized(45.0f, 96, 72);
    refl_render_desc d;
    refl_frame *truth = greedy_truth(s, &v), *lem[2];
    refl_image_error err[2];
    int dark[2] = {0, 0}, bright[2] = {0, 0}, on, lens = 0;
    size_t i, n = (size_t)v.width * (size_t)v.height;
    for (on = 0; on < 2; ++on) {
        d = lem_desc(4);
        d.layered_em.single_view = 1;
        d.layered_em.direct_images = on ? 1 : -1;
        lem[on] = tu_refl_render(s, &v, &d);
        cr_assert_eq(refl_measure_image_error(lem[on], truth, 1, 0.0f, &err[on]), REFL_OK);
        cr_assert_eq(lem[on]->stats.layered_em.direct_rows > 0, on);
        dark[on] = dark_lens_pixels(truth, lem[on]);
        bright[on] = bright_lens_pixels(truth, lem[on]);
    }
    for (i = 0; i < n; ++i) lens += truth->stencil[i] == 2;
    cr_log_info("disocclusion: without %.2f dB (%d dark, %d bright), with %.2f dB (%d dark, %d bright) of %d lens pixels",
                err[0].psnr, dark[0], bright[0], err[1].psnr, dark[1], bright[1], lens);
    cr_assert_geq(dark[0], 50, "without: %d dark pixels", dark[0]);
    cr_assert_lt(err[0].psnr, 25.0, "without: %.2f dB", err[0].psnr);
    cr_assert_eq(bright[0], 0, "without: %d bright pixels", bright[0]);
    cr_assert_eq(dark[1], 0, "with: %d dark pixels", dark[1]);
    cr_assert_eq(bright[1], 0, "with: %d bright pixels", bright[1]);
    cr_assert_geq(err[1].psnr, 33.0, "with: %.2f dB", err[1].psnr);
    refl_frame_destroy(truth);
    refl_frame_destroy(lem[0]);
    refl_frame_destroy(lem[1]);
    refl_scene_destroy(s);
}

Test(layered_em, direct_images_from_the_viewpoint_and_by_distance) {
    /* the scene above with the paper's other direct images: by the
       distance of their hits from the lens images' (from the centre:
       35.7 dB, none dark, above the coverage's 35.4), and from the
       samples' viewpoints, the lens left out (35.8 dB by distance, 35.6
       by coverage): they see what lies behind the glass, where its
       refracted exit rays look, and none of what the reflected ones look
       at beside it, which the samples never saw either; the centre's
       rows fill those texels (without them 22.8 dB by coverage, 22.9 by
       distance; without direct images 18.7 dB) */
    refl_scene *s = exact_shell_scene();
    refl_view v = orbit_view_sized(45.0f, 96, 72);
    refl_render_desc d;
    refl_frame *truth = greedy_truth(s, &v), *lem;
    refl_image_error err[3];
    long long rows[3];
    int k, dark = 0;
    for (k = 0; k < 3; ++k) {
        d = lem_desc(4);
        d.layered_em.single_view = 1;
        d.layered_em.direct_from = k == 0 ? REFL_LEM_DIRECT_FROM_CENTRE : REFL_LEM_DIRECT_FROM_VIEWPOINT;
        d.layered_em.direct_confidence = k == 2 ? REFL_LEM_DIRECT_COVERAGE : REFL_LEM_DIRECT_DISTANCE;
        lem = tu_refl_render(s, &v, &d);
        cr_assert_eq(refl_measure_image_error(lem, truth, 1, 0.0f, &err[k]), REFL_OK);
        rows[k] = lem->stats.layered_em.direct_rows;
        if (k == 0) dark = dark_lens_pixels(truth, lem);
        refl_frame_destroy(lem);
    }
    cr_log_info("direct images: centre by distance %.2f dB (%lld rows, %d dark), viewpoint by distance %.2f dB (%lld), "
                "by coverage %.2f dB (%lld)",
                err[0].psnr, rows[0], dark, err[1].psnr, rows[1], err[2].psnr, rows[2]);
    cr_assert_eq(dark, 0, "centre by distance: %d dark pixels", dark);
    cr_assert_geq(err[0].psnr, 35.0, "centre by distance: %.2f dB", err[0].psnr);
    for (k = 1; k < 3; ++k) {
        cr_assert_gt(rows[k], 0);
        cr_assert_geq(err[k].psnr, 35.0, "viewpoint: %.2f dB, near the centre's %.2f", err[k].psnr, err[0].psnr);
    }
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* ---- the points the maps show: the reflection error ----------------------------------- */

Test(layered_em, shows_the_glass_scene_nearer_its_true_places_than_envmap) {
    /* the built-in `glass` at 80x60 against greedy RAYTRACE: LAYERED_EM
       exports the point on the shell its maps show at every lens pixel, so
       the reflection error measures it; its refracted floor and boxes land
       nearer their true places than ENVMAP's lookups from the centre */
    refl_scene *s = NULL;
    refl_view v;
    refl_render_desc d;
    refl_frame *truth, *lem, *envmap;
    refl_reflection_error lem_err, env_err;
    refl_image_error lem_img, env_img;
    cr_assert_eq(refl_scene_builtin("glass", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 80;
    v.height = 60;
    truth = greedy_truth(s, &v);
    d = lem_desc(0);
    lem = tu_refl_render(s, &v, &d);
    d = tu_refl_desc(REFL_ENVMAP, 2);
    envmap = tu_refl_render(s, &v, &d);
    cr_assert_eq(refl_measure_reflection_error(lem, truth, NULL, &lem_err), REFL_OK);
    cr_assert_eq(refl_measure_reflection_error(envmap, truth, NULL, &env_err), REFL_OK);
    cr_assert_eq(refl_measure_image_error(lem, truth, 1, 0.0f, &lem_img), REFL_OK);
    cr_assert_eq(refl_measure_image_error(envmap, truth, 1, 0.0f, &env_img), REFL_OK);
    cr_log_info("glass 80x60: LAYERED_EM %.2f px (wrong %.3f, empty %.3f), %.2f dB; ENVMAP %.2f px (wrong %.3f, "
                "empty %.3f), %.2f dB",
                lem_err.mean, lem_err.wrong, lem_err.empty, lem_img.psnr, env_err.mean, env_err.wrong, env_err.empty,
                env_img.psnr);
    /* a point at every lens pixel, most of them matched: the mean is over
       most of the lens, not a few pixels */
    cr_assert_gt(lem_err.pixels, 800);
    cr_assert_lt(lem_err.empty, 0.01, "LAYERED_EM exports a point at every lens pixel: %.3f empty", lem_err.empty);
    cr_assert_lt(lem_err.wrong, 0.2, "%.3f wrong", lem_err.wrong);
    cr_assert_lt(lem_err.mean, env_err.mean, "LAYERED_EM %.2f px, ENVMAP %.2f px", lem_err.mean, env_err.mean);
    cr_assert_gt(lem_img.psnr, env_img.psnr, "LAYERED_EM %.2f dB, ENVMAP %.2f dB", lem_img.psnr, env_img.psnr);
    refl_frame_destroy(truth);
    refl_frame_destroy(lem);
    refl_frame_destroy(envmap);
    refl_scene_destroy(s);
}

/* ---- the vertex paths trace the lenses alone ------------------------------------------- */

/* A glass sphere of radius 1 (object 0) alone, or (cloud 1) inside a
   cloud of 20000 small diffuse triangles between radii 4 and 8 around it:
   every path leaving the sphere crosses the cloud, while the eye, 3 from
   the centre, sees the sphere past none of it. */
static refl_scene *clouded_lens_scene(int cloud) {
    enum { N = 20000 };
    refl_scene *s = NULL;
    refl_mesh *lens = NULL, *bits = NULL;
    refl_material glass = refl_material_glass(1.5f), grey = refl_material_diffuse(0.6f, 0.6f, 0.6f);
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(1.0f, 24, 12, NULL, &lens), REFL_OK);
    cr_assert_eq(refl_scene_add(s, lens, &glass, refl_mat4_identity()), 0);
    if (cloud) {
        float *pos = (float *)malloc(9 * N * sizeof(float));
        uint32_t seed = 12345u;
        refl_mesh_desc md;
        int i, k;
        cr_assert(pos);
        for (i = 0; i < N; ++i) { /* a random centre in the layer, corners within 0.15 of it */
            float u[12], z, phi, r, c[3];
            for (k = 0; k < 12; ++k) {
                seed = seed * 1664525u + 1013904223u;
                u[k] = (float)(seed >> 8) / 16777216.0f;
            }
            z = 2.0f * u[0] - 1.0f, phi = 6.2831853f * u[1], r = 4.0f + 4.0f * u[2];
            c[0] = r * sqrtf(1.0f - z * z) * cosf(phi), c[1] = r * z, c[2] = r * sqrtf(1.0f - z * z) * sinf(phi);
            for (k = 0; k < 9; ++k) pos[9 * i + k] = c[k % 3] + 0.3f * (u[3 + k] - 0.5f);
        }
        memset(&md, 0, sizeof md);
        md.positions = pos;
        md.vertex_count = 3 * N;
        cr_assert_eq(refl_mesh_create(&md, &bits), REFL_OK);
        free(pos);
        cr_assert_eq(refl_scene_add(s, bits, &grey, refl_mat4_identity()), 1);
    }
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 1.0f;
    return s;
}

Test(layered_em, vertex_paths_test_the_lens_triangles_alone, .timeout = 120) {
    /* the frame's vertices trace the same paths with the cloud or
       without: through the lens's triangles alone, the rest of the scene
       asked only whether it lies between two lens surfaces, so the cloud
       every exit ray crosses costs them no triangle tests (traced through
       the whole scene, each exit ray would test the cloud's) */
    refl_view v;
    refl_render_desc d = lem_desc(8);
    refl_scene *plain = clouded_lens_scene(0), *clouded = clouded_lens_scene(1);
    refl_frame *a, *b;
    memset(&v, 0, sizeof v);
    v.eye = refl_v3(0.0f, 0.5f, 3.0f);
    v.up = refl_v3(0.0f, 1.0f, 0.0f);
    v.fovy_degrees = 45.0f;
    v.width = 64;
    v.height = 48;
    d.layered_em.single_view = 1;
    d.layered_em.face_size = 16;
    a = tu_refl_render(plain, &v, &d);
    b = tu_refl_render(clouded, &v, &d);
    cr_assert_gt(a->stats.layered_em.vertices, 100);
    cr_assert_eq(b->stats.layered_em.vertices, a->stats.layered_em.vertices, "the cloud changed the paths");
    cr_assert_gt(a->stats.layered_em.vertex_tests, 0);
    cr_assert_leq(b->stats.layered_em.vertex_tests, a->stats.layered_em.vertex_tests + a->stats.layered_em.vertices,
                  "the cloud cost the vertices %lld triangle tests (%lld without it, %lld vertices)",
                  b->stats.layered_em.vertex_tests - a->stats.layered_em.vertex_tests,
                  a->stats.layered_em.vertex_tests, a->stats.layered_em.vertices);
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    refl_scene_destroy(plain);
    refl_scene_destroy(clouded);
}

Test(layered_em, default_iterations_reach_the_least_squares) {
    /* hybrid's maps at the default iterations: every solve stops at the
       tolerance, none at the cap (whose maps would be short of the least
       squares); the frame's stats say which stopped where */
    refl_view v;
    refl_scene *s = tu_refl_builtin("hybrid", &v, 64, 48);
    refl_render_desc d = tu_refl_desc(REFL_LAYERED_EM, 2);
    refl_frame *f = tu_refl_render(s, &v, &d);
    const refl_layered_em_frame_stats *st = &f->stats.layered_em;
    cr_assert_geq(st->solves, 2, "a map of each lens");
    cr_assert_eq(st->solves_capped, 0, "%d of %d solves stopped at the cap (%d iterations)", st->solves_capped,
                 st->solves, st->solve_iterations);
    cr_assert(st->solve_iterations > 0 && st->solve_iterations < 200);
    refl_frame_destroy(f);
    d.layered_em.iterations = 3;
    f = tu_refl_render(s, &v, &d);
    cr_assert_eq(f->stats.layered_em.solves_capped, f->stats.layered_em.solves);
    cr_assert_eq(f->stats.layered_em.solve_iterations, 3);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

Test(layered_em, split_tracing_keeps_the_whole_scenes_images, .timeout = 120) {
    /* the vertex paths through the lenses' BVH, the rest asked for
       occluders between lens surfaces, find what tracing them through the
       whole scene found: the frames of mirror-room (mirrors seeing each
       other past the room's furniture) and hybrid (glass, a mirror cup and
       columns) are the bytes recorded from whole-scene tracing */
    static const struct {
        const char *scene;
        uint64_t digest;
    } cases[] = {{"mirror-room", 0x8b3bef63f1e1779full}, {"hybrid", 0xef23ed865ff87790ull}};
    uint64_t digest[2];
    int k;
    for (k = 0; k < 2; ++k) {
        refl_view v;
        refl_scene *s = tu_refl_builtin(cases[k].scene, &v, 64, 48);
        refl_frame *f = render_lem(s, &v, 2);
        digest[k] = tu_refl_digest(f);
        if (getenv("REFL_GOLDEN_PRINT")) printf("%s 0x%016llxull\n", cases[k].scene, (unsigned long long)digest[k]);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
    for (k = 0; k < 2; ++k)
        cr_assert_eq(digest[k], cases[k].digest, "%s: LAYERED_EM's bytes changed", cases[k].scene);
}
