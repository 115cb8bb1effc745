/* The single-pole occlusion camera (paper 004, section 4; the model is
   refl_spoc in api.h): the centre projects to the pole, the near depth is
   undistorted, the push follows the closed form, project and unproject are
   inverse, a straight segment beside the pole images to the curve the
   closed form gives, and the fold count on the teapot rises with the
   strength, few at the paper's strength. */
#include <criterion/criterion.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

static refl_vec3 spoc_point(const refl_spoc *c, double x, double y, double z) {
    return refl_v3((float)(c->eye.x + x * c->right.x + y * c->up.x + z * c->forward.x),
                   (float)(c->eye.y + x * c->right.y + y * c->up.y + z * c->forward.y),
                   (float)(c->eye.z + x * c->right.z + y * c->up.z + z * c->forward.z));
}

static refl_spoc spoc_cam(float strength) {
    refl_spoc c;
    cr_assert_eq(refl_spoc_init(&c, refl_v3(0.3f, 1.2f, 4.0f), refl_v3(-0.5f, 0.4f, -1.0f), 1.0f, 0.8f, strength,
                                512),
                 REFL_OK);
    return c;
}

Test(spoc, rejects_bad_arguments) {
    refl_spoc c;
    cr_expect_eq(refl_spoc_init(NULL, refl_v3(0, 0, 5), refl_v3(0, 0, 0), 1, 1, 1, 64), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_spoc_init(&c, refl_v3(0, 0, 1), refl_v3(0, 0, 0), 1, 1, 1, 64), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_spoc_init(&c, refl_v3(0, 0, 5), refl_v3(0, 0, 0), 0, 1, 1, 64), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_spoc_init(&c, refl_v3(0, 0, 5), refl_v3(0, 0, 0), 1, -1, 1, 64), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_spoc_init(&c, refl_v3(0, 0, 5), refl_v3(0, 0, 0), 1, 1, NAN, 64), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_spoc_init(&c, refl_v3(0, 0, 5), refl_v3(0, 0, 0), 1, 1, 1, 4), REFL_ERROR_INVALID_SIZE);
}

Test(spoc, centre_projects_to_pole) {
    refl_spoc c = spoc_cam(1.0f);
    float o[3];
    cr_assert(refl_spoc_project(&c, c.center, o));
    cr_expect(fabsf(o[0] - c.pole[0]) < 1e-3f && fabsf(o[1] - c.pole[1]) < 1e-3f, "centre at (%g, %g)", o[0], o[1]);
    {
        double d = 0.5 * ((double)c.znear + c.zfar);
        double want = (1.0 / c.znear - 1.0 / d) / (1.0 / c.znear - 1.0 / c.zfar);
        cr_expect(isfinite(o[2]) && fabs(o[2] - want) < 1e-5, "gd %g, want %g", o[2], want);
    }
    /* the eye and points behind it do not project */
    cr_expect(!refl_spoc_project(&c, c.eye, o));
    cr_expect(!refl_spoc_project(&c, spoc_point(&c, 0.1, 0.1, -1.0), o));
}

/* At zn the push is 0: the image is the plain pinhole's. Deeper, a point
   at pinhole radius r >= ramp moves out along its direction by exactly
   delta_max * gd. */
Test(spoc, near_depth_undistorted_and_push_closed_form) {
    refl_spoc c = spoc_cam(1.0f);
    int i;
    for (i = 0; i < 200; ++i) {
        double ang = 0.0314 * i, r = 2.0 + 1.3 * i, z = c.znear;
        double x = r * cos(ang) * z / c.focal, y = r * sin(ang) * z / c.focal;
        float o[3];
        cr_assert(refl_spoc_project(&c, spoc_point(&c, x, y, z), o));
        cr_expect(fabs(o[0] - (c.pole[0] + r * cos(ang))) < 2e-3 && fabs(o[1] - (c.pole[1] - r * sin(ang))) < 2e-3,
                  "at zn: (%g, %g) for r %g", o[0], o[1], r);
        cr_expect(fabsf(o[2]) < 1e-5f);
        if (r >= c.ramp) {
            double zd = c.znear + (c.zfar - c.znear) * (i % 10) / 9.0, gd;
            double want;
            x = r * cos(ang) * zd / c.focal;
            y = r * sin(ang) * zd / c.focal;
            cr_assert(refl_spoc_project(&c, spoc_point(&c, x, y, zd), o));
            gd = (1.0 / c.znear - 1.0 / zd) / (1.0 / c.znear - 1.0 / c.zfar);
            want = r + c.delta_max * gd;
            cr_expect(fabs(hypot(o[0] - c.pole[0], o[1] - c.pole[1]) - want) < 5e-3, "r' %g want %g",
                      hypot(o[0] - c.pole[0], o[1] - c.pole[1]), want);
            cr_expect(fabs(atan2(c.pole[1] - o[1], o[0] - c.pole[0]) - atan2(sin(ang), cos(ang))) < 1e-4);
        }
    }
    /* the push at zf is the parallax of a sideways move of the baseline */
    cr_expect(fabs(c.delta_max - c.strength * c.focal * c.baseline * (1.0 / c.znear - 1.0 / c.zfar)) <
              1e-3 * c.delta_max);
}

Test(spoc, round_trip) {
    float strengths[3] = {0.0f, 1.0f, 4.0f};
    int s, i;
    for (s = 0; s < 3; ++s) {
        refl_spoc c = spoc_cam(strengths[s]);
        refl_rng rng = refl_rng_seed(19 + s);
        double worst = 0.0;
        for (i = 0; i < 20000; ++i) {
            /* random points in the bounding sphere (and some near the pole) */
            refl_vec3 d, p, back;
            float o[3];
            double err;
            do {
                d = refl_v3(2 * refl_rng_float(&rng) - 1, 2 * refl_rng_float(&rng) - 1, 2 * refl_rng_float(&rng) - 1);
            } while (refl_v3_dot(d, d) > 1.0f);
            if (i % 10 == 0) d = refl_v3_scale(d, 0.01f);
            p = refl_v3_add(c.center, refl_v3_scale(d, c.radius));
            cr_assert(refl_spoc_project(&c, p, o));
            cr_assert(o[0] >= 0 && o[0] <= c.size && o[1] >= 0 && o[1] <= c.size, "(%g, %g) off the image", o[0],
                      o[1]);
            cr_assert(refl_spoc_unproject(&c, o, &back));
            err = refl_v3_length(refl_v3_sub(back, p)) / refl_v3_length(refl_v3_sub(p, c.eye));
            if (err > worst) worst = err;
        }
        cr_expect(worst < 1e-5, "strength %g: worst relative round-trip error %g", strengths[s], worst);
    }
}

/* A segment at constant depth z (>= zn) beside the pole, from pinhole
   (-a, h) to (a, h) (all radii >= ramp): its pinhole image is straight;
   pushed by D = delta_max gd(z) it bends away from the pole: the middle
   lies D (1 - h / sqrt(a^2 + h^2)) beyond the chord of the ends. */
Test(spoc, straight_segment_images_to_curve) {
    refl_spoc c = spoc_cam(1.0f);
    double z = 0.5 * (c.znear + c.zfar), h = 2.0 * c.ramp, a = 3.0 * c.ramp;
    double gd = (1.0 / c.znear - 1.0 / z) / (1.0 / c.znear - 1.0 / c.zfar), D = c.delta_max * gd;
    double want = D * (1.0 - h / sqrt(a * a + h * h)), dev_max = 0.0;
    float e0[3], e1[3], m[3];
    int i;
    cr_assert(D > 1.0);
    cr_assert(refl_spoc_project(&c, spoc_point(&c, -a * z / c.focal, h * z / c.focal, z), e0));
    cr_assert(refl_spoc_project(&c, spoc_point(&c, a * z / c.focal, h * z / c.focal, z), e1));
    cr_assert(refl_spoc_project(&c, spoc_point(&c, 0.0, h * z / c.focal, z), m));
    /* the chord is horizontal (both ends at one height); image rows grow down */
    cr_expect(fabs(e0[1] - e1[1]) < 1e-3);
    cr_expect(fabs((e0[1] - m[1]) - want) < 1e-2, "deviation %g, closed form %g", e0[1] - m[1], want);
    /* and every point between bulges the same side, the middle most */
    for (i = 1; i < 64; ++i) {
        double s = -a + 2.0 * a * i / 64.0, dev;
        float o[3];
        cr_assert(refl_spoc_project(&c, spoc_point(&c, s * z / c.focal, h * z / c.focal, z), o));
        dev = e0[1] - o[1];
        cr_expect(dev > 0.0);
        if (dev > dev_max) dev_max = dev;
    }
    cr_expect(fabs(dev_max - want) < 1e-2);
    /* with strength 0 (the plain depth image) the segment stays straight */
    {
        refl_spoc p = spoc_cam(0.0f);
        float o0[3], o1[3], om[3];
        double zz = 0.5 * (p.znear + p.zfar);
        refl_spoc_project(&p, spoc_point(&p, -a * zz / p.focal, h * zz / p.focal, zz), o0);
        refl_spoc_project(&p, spoc_point(&p, a * zz / p.focal, h * zz / p.focal, zz), o1);
        refl_spoc_project(&p, spoc_point(&p, 0.0, h * zz / p.focal, zz), om);
        cr_expect(fabs(o0[1] - om[1]) < 1e-3);
    }
}

/* The image of the bounding sphere fits the image for any strength, and
   bounds() says where. */
Test(spoc, bounds_hold_sphere) {
    refl_spoc c = spoc_cam(2.0f);
    float rect[4];
    refl_rng rng = refl_rng_seed(5);
    int i;
    refl_spoc_bounds(&c, rect);
    cr_expect(rect[0] >= 0.0f && rect[1] >= 0.0f && rect[2] <= c.size && rect[3] <= c.size);
    for (i = 0; i < 5000; ++i) {
        float th = 6.2831853f * refl_rng_float(&rng), zz = 2 * refl_rng_float(&rng) - 1, o[3];
        float s = sqrtf(1 - zz * zz);
        refl_vec3 p = refl_v3_add(c.center, refl_v3_scale(refl_v3(s * cosf(th), s * sinf(th), zz), c.radius));
        cr_assert(refl_spoc_project(&c, p, o));
        cr_expect(o[0] >= rect[0] - 1e-3f && o[0] <= rect[2] + 1e-3f && o[1] >= rect[1] - 1e-3f &&
                  o[1] <= rect[3] + 1e-3f && o[2] >= -1e-5f && o[2] <= 1.0f + 1e-5f);
    }
}

/* The teapot's eye-facing triangles: none folds with strength 0; at the
   paper's strength few do (beside silhouettes that face the pole, where
   the surface turns away from the eye: |dz/dr| is unbounded there); folds
   grow as the strength rises. */
Test(spoc, folds_detected_as_strength_rises) {
    refl_mesh *m = NULL;
    float strengths[5] = {0.0f, 1.0f, 4.0f, 16.0f, 64.0f};
    long long folds[5], facing = 0;
    refl_vec3 lo, hi, ctr;
    float radius;
    int i;
    cr_assert_eq(refl_mesh_teapot(8, NULL, &m), REFL_OK);
    refl_mesh_bounds(m, &lo, &hi);
    ctr = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    radius = 0.5f * refl_v3_length(refl_v3_sub(hi, lo));
    for (i = 0; i < 5; ++i) {
        refl_spoc c;
        cr_assert_eq(refl_spoc_init(&c, refl_v3_add(ctr, refl_v3(4.0f * radius, 0.5f * radius, 1.0f * radius)), ctr,
                                    radius, radius, strengths[i], 512),
                     REFL_OK);
        folds[i] = refl_spoc_count_folds(&c, m, NULL, &facing);
        cr_expect(facing > m->triangle_count / 4);
    }
    cr_expect_eq(folds[0], 0);
    cr_expect(folds[1] < facing / 25, "folds at strength 1: %lld of %lld", folds[1], facing);
    for (i = 1; i < 5; ++i) cr_expect(folds[i] >= folds[i - 1]);
    cr_expect(folds[2] > 2 * folds[1] && folds[4] > facing / 10, "folds do not grow with the strength");
    refl_mesh_destroy(m);
}
