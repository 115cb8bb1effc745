/* The generic non-pinhole impostor (paper 004, section 3) with SPOC
   cameras: ray-impostor hits on a plane (strength 0, a plain depth image)
   and on a sphere (strength 1) agree with the analytic intersection within
   a texel's footprint; a ray passing behind a silhouette does not stop on
   the skin between the depth layers; peeled layers hold the wall a box
   hides, and rays passing behind the box meet it there; a ray missing the
   bounding sphere takes no step; and the paper's Fig. 7: the SPOC stores more of the
   teapot's area-uniform samples than the plain depth image. */
#include <criterion/criterion.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

static refl_scene *imp_scene(void) {
    refl_scene *s = NULL;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    refl_scene_add_light(s, &(refl_light){.type = REFL_LIGHT_DIRECTIONAL, .direction = {0.3f, -1.0f, -0.2f},
                                          .color = {1, 1, 1}});
    return s;
}

static refl_impostor *imp_build_layers(refl_scene *s, const int *objects, int count, const refl_spoc *cam,
                                      int layers) {
    refl_impostor_camera ic = refl_spoc_impostor_camera(cam);
    refl_impostor_desc d;
    refl_impostor *imp = NULL;
    memset(&d, 0, sizeof d);
    d.threads = 2;
    d.layers = layers;
    cr_assert_eq(refl_impostor_build(s, objects, count, &ic, &d, &imp), REFL_OK);
    cr_assert_eq(imp->layers, layers > 0 ? layers : 1);
    return imp;
}

static refl_impostor *imp_build(refl_scene *s, const int *objects, int count, const refl_spoc *cam) {
    return imp_build_layers(s, objects, count, cam, 1);
}

/* World size of a texel at depth z (pinhole pixels; the push only
   stretches the image, so SPOC texels are no larger). */
static double texel_at(const refl_spoc *c, refl_vec3 p) {
    double z = refl_v3_dot(refl_v3_sub(p, c->eye), c->forward);
    return z / c->focal;
}

Test(impostor, plane_hits_match_analytic) {
    refl_scene *s = imp_scene();
    refl_mesh *m = NULL;
    refl_material mat = refl_material_diffuse(0.8f, 0.8f, 0.8f);
    refl_spoc cam;
    refl_impostor *imp;
    refl_rng rng = refl_rng_seed(7);
    int obj, i, hits = 0, tried = 0;
    double worst = 0.0;
    cr_assert_eq(refl_mesh_plane(1.0f, 4, NULL, &m), REFL_OK);
    obj = refl_scene_add(s, m, &mat, refl_mat4_identity());
    cr_assert_eq(refl_spoc_init(&cam, refl_v3(0.3f, 2.5f, 0.6f), refl_v3(0, 0, 0), 0.75f, 0.4f, 0.0f, 256), REFL_OK);
    imp = imp_build(s, &obj, 1, &cam);
    for (i = 0; i < 2000; ++i) {
        refl_vec3 target = refl_v3(0.9f * (refl_rng_float(&rng) - 0.5f), 0.0f, 0.9f * (refl_rng_float(&rng) - 0.5f));
        refl_vec3 origin = refl_v3(2.0f * (refl_rng_float(&rng) - 0.5f), 0.5f + refl_rng_float(&rng),
                                   2.0f * (refl_rng_float(&rng) - 0.5f));
        refl_vec3 dir = refl_v3_normalize(refl_v3_sub(target, origin));
        refl_impostor_hit h;
        double t_true = -origin.y / dir.y, err, cos_cam, foot;
        refl_vec3 truth = refl_v3_add(origin, refl_v3_scale(dir, (float)t_true));
        ++tried;
        if (!refl_impostor_intersect(imp, origin, dir, 0.0f, 100.0f, 1.0f, &h, NULL)) continue;
        ++hits;
        err = refl_v3_length(refl_v3_sub(h.point, truth));
        /* a texel's footprint on the plane: its size over the cosine of the camera ray's incidence */
        cos_cam = fabs(refl_v3_normalize(refl_v3_sub(truth, cam.eye)).y);
        foot = texel_at(&cam, truth) / cos_cam;
        if (err / foot > worst) worst = err / foot;
    }
    cr_expect(hits >= tried * 99 / 100, "%d of %d rays hit", hits, tried);
    cr_expect(worst <= 1.0, "worst error %g texel footprints", worst);
    refl_impostor_destroy(imp);
    refl_scene_destroy(s);
}

Test(impostor, sphere_hits_match_analytic) {
    refl_scene *s = imp_scene();
    refl_mesh *m = NULL;
    refl_material mat = refl_material_diffuse(0.8f, 0.3f, 0.3f);
    refl_spoc cam;
    refl_impostor *imp;
    refl_rng rng = refl_rng_seed(11);
    const float R = 0.5f;
    int obj, i, agree = 0, tried = 0;
    cr_assert_eq(refl_mesh_sphere(R, 96, 48, NULL, &m), REFL_OK);
    obj = refl_scene_add(s, m, &mat, refl_mat4_identity());
    cr_assert_eq(refl_spoc_init(&cam, refl_v3(0.2f, 0.4f, 2.0f), refl_v3(0, 0, 0), 1.01f * R, 0.5f, 1.0f, 256),
                 REFL_OK);
    imp = imp_build(s, &obj, 1, &cam);
    for (i = 0; i < 2000; ++i) {
        /* query rays from within the baseline of the reference viewpoint */
        refl_vec3 origin = refl_v3_add(cam.eye, refl_v3((refl_rng_float(&rng) - 0.5f) * 0.8f,
                                                        (refl_rng_float(&rng) - 0.5f) * 0.8f,
                                                        (refl_rng_float(&rng) - 0.5f) * 0.8f));
        refl_vec3 target = refl_v3(0.9f * R * (refl_rng_float(&rng) - 0.5f) * 2.0f,
                                   0.9f * R * (refl_rng_float(&rng) - 0.5f) * 2.0f, 0.0f);
        refl_vec3 dir = refl_v3_normalize(refl_v3_sub(target, origin)), truth;
        double b = refl_v3_dot(origin, dir), c = refl_v3_dot(origin, origin) - R * R, t_true;
        refl_impostor_hit h;
        if (b * b - c <= 0.0) continue;
        t_true = -b - sqrt(b * b - c);
        truth = refl_v3_add(origin, refl_v3_scale(dir, (float)t_true));
        ++tried;
        if (!refl_impostor_intersect(imp, origin, dir, 0.0f, 100.0f, 1.0f, &h, NULL)) continue;
        {
            /* footprint: a texel over the cosine of the camera ray's incidence, capped at 4 texels */
            refl_vec3 n = refl_v3_normalize(truth);
            double cos_cam = fabs(refl_v3_dot(n, refl_v3_normalize(refl_v3_sub(truth, cam.eye))));
            double foot = texel_at(&cam, truth) / fmax(cos_cam, 0.25);
            if (refl_v3_length(refl_v3_sub(h.point, truth)) <= foot) ++agree;
        }
    }
    cr_expect(tried > 1500);
    cr_expect(agree >= tried * 99 / 100, "%d of %d rays agree within a texel footprint", agree, tried);
    refl_impostor_destroy(imp);
    refl_scene_destroy(s);
}

/* A box in front of a back wall (the objects of s), seen from (0, 0, 4)
   by a plain depth image. */
static void box_and_wall(refl_scene *s, int objs[2], refl_spoc *cam) {
    refl_mesh *box = NULL, *wall = NULL;
    refl_material mat = refl_material_diffuse(0.5f, 0.5f, 0.5f);
    cr_assert_eq(refl_mesh_box(refl_v3(0.4f, 0.4f, 0.4f), NULL, &box), REFL_OK);
    cr_assert_eq(refl_mesh_plane(1.6f, 4, NULL, &wall), REFL_OK);
    objs[0] = refl_scene_add(s, box, &mat, refl_mat4_translate(refl_v3(0, 0, 0.3f)));
    /* the plane faces +y; turned to face +z at z = -0.5 */
    objs[1] = refl_scene_add(s, wall, &mat,
                             refl_mat4_mul(refl_mat4_translate(refl_v3(0, 0, -0.5f)),
                                           refl_mat4_rotate(refl_v3(1, 0, 0), 1.5707963f)));
    cr_assert_eq(refl_spoc_init(cam, refl_v3(0, 0, 4.0f), refl_v3(0, 0, 0), 1.2f, 0.5f, 0.0f, 256), REFL_OK);
}

/* A ray that enters the box's image behind the box (the box hides where
   it goes) and then meets the wall must not stop at the box's silhouette. */
Test(impostor, no_hit_on_skins) {
    refl_scene *s = imp_scene();
    refl_spoc cam;
    refl_impostor *imp;
    int objs[2], i, false_hits = 0, wall_hits = 0;
    box_and_wall(s, objs, &cam);
    imp = imp_build(s, objs, 2, &cam);
    for (i = 0; i < 200; ++i) {
        /* from beside the box, slanting behind it (z from 0.05 down to -0.5) towards the wall */
        float y = -0.15f + 0.3f * (float)i / 199.0f;
        refl_vec3 origin = refl_v3(0.6f, y, 0.05f), target = refl_v3(-0.35f, y, -0.5f);
        refl_vec3 dir = refl_v3_normalize(refl_v3_sub(target, origin));
        refl_impostor_hit h;
        if (!refl_impostor_intersect(imp, origin, dir, 0.0f, 100.0f, 1.0f, &h, NULL)) continue;
        if (fabsf(h.point.z + 0.5f) < 0.02f) ++wall_hits;
        else ++false_hits;
    }
    cr_expect_eq(false_hits, 0, "%d rays stopped on a skin (%d on the wall)", false_hits, wall_hits);
    cr_expect(wall_hits > 150, "%d of 200 rays met the wall", wall_hits);
    refl_impostor_destroy(imp);
    refl_scene_destroy(s);
}

/* Depth peeling: layer 1 holds the box's far side, layer 2 the wall the
   box hides. Rays from beside the box that pass behind it and meet the
   hidden wall miss a one-layer impostor and meet the wall in a three-layer
   one, within a texel's footprint, stopping on no skin between the
   layers. */
Test(impostor, peeled_layers_hold_the_hidden_wall) {
    refl_scene *s = imp_scene();
    refl_spoc cam;
    refl_impostor *one, *three;
    int objs[2], i, one_wall = 0, wall_hits = 0, false_hits = 0, layer2 = 0;
    long long centre;
    box_and_wall(s, objs, &cam);
    one = imp_build(s, objs, 2, &cam);
    three = imp_build_layers(s, objs, 2, &cam, 3);
    /* the image centre: the box's near face, its far face, the wall */
    centre = (long long)(cam.size / 2) * cam.size + cam.size / 2;
    cr_expect(three->depth[centre] < three->depth[centre + (long long)cam.size * cam.size] &&
              three->depth[centre + (long long)cam.size * cam.size] <
                  three->depth[centre + 2LL * cam.size * cam.size] &&
              three->color[4 * (centre + 2LL * cam.size * cam.size) + 3] > 0.0f);
    for (i = 0; i < 100; ++i) {
        /* from beside the box, below its far face (z < 0.1), to the wall where the box hides it */
        float y = -0.12f + 0.24f * (float)i / 99.0f;
        refl_vec3 origin = refl_v3(0.8f, y, -0.1f), target = refl_v3(-0.1f + 0.002f * (float)i, y, -0.5f);
        refl_vec3 dir = refl_v3_normalize(refl_v3_sub(target, origin));
        refl_impostor_hit h;
        double foot = 2.0 * texel_at(&cam, target) / fabs(dir.z);
        if (refl_impostor_intersect(one, origin, dir, 0.0f, 100.0f, 1.0f, &h, NULL) && fabsf(h.point.z + 0.5f) < 0.02f)
            ++one_wall;
        if (!refl_impostor_intersect(three, origin, dir, 0.0f, 100.0f, 1.0f, &h, NULL)) continue;
        if (refl_v3_length(refl_v3_sub(h.point, target)) <= foot) ++wall_hits;
        else ++false_hits;
        layer2 += h.layer == 2;
    }
    cr_expect(one_wall < 5, "%d rays met the hidden wall in one layer", one_wall);
    cr_expect(wall_hits >= 98 && false_hits == 0, "%d rays met the wall, %d elsewhere", wall_hits, false_hits);
    cr_expect(layer2 >= 98, "%d hits on layer 2", layer2);
    refl_impostor_destroy(one);
    refl_impostor_destroy(three);
    refl_scene_destroy(s);
}

Test(impostor, miss_takes_no_step) {
    refl_scene *s = imp_scene();
    refl_mesh *m = NULL;
    refl_material mat = refl_material_diffuse(0.5f, 0.5f, 0.5f);
    refl_spoc cam;
    refl_impostor *imp;
    refl_impostor_hit h;
    int obj, steps = -1;
    cr_assert_eq(refl_mesh_sphere(0.5f, 32, 16, NULL, &m), REFL_OK);
    obj = refl_scene_add(s, m, &mat, refl_mat4_identity());
    cr_assert_eq(refl_spoc_init(&cam, refl_v3(0, 0, 3.0f), refl_v3(0, 0, 0), 0.55f, 0.5f, 1.0f, 64), REFL_OK);
    imp = imp_build(s, &obj, 1, &cam);
    cr_expect(!refl_impostor_intersect(imp, refl_v3(2, 2, 2), refl_v3(1, 0, 0), 0.0f, 100.0f, 1.0f, &h, &steps));
    cr_expect_eq(steps, 0);
    cr_expect(refl_impostor_intersect(imp, refl_v3(0, 0, 3), refl_v3(0, 0, -1), 0.0f, 100.0f, 1.0f, &h, &steps));
    cr_expect(steps > 0 && fabsf(h.point.z - 0.5f) < 0.02f, "hit z %g after %d steps", h.point.z, steps);
    refl_impostor_destroy(imp);
    refl_scene_destroy(s);
}

/* The fraction of area-uniform samples of the teapot that an impostor
   stores (its texel's depth matches the sample's within the depth
   tolerance). */
static double stored_fraction(refl_scene *s, int obj, const refl_mesh *m, float strength) {
    refl_vec3 lo, hi, ctr;
    refl_spoc cam;
    refl_impostor *imp;
    refl_points *pts = NULL;
    float radius;
    int i, stored = 0;
    refl_mesh_bounds(m, &lo, &hi);
    ctr = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    radius = 0.5f * refl_v3_length(refl_v3_sub(hi, lo));
    cr_assert_eq(refl_spoc_init(&cam, refl_v3_add(ctr, refl_v3(3.5f * radius, 1.2f * radius, 1.0f * radius)), ctr,
                                radius, radius, strength, 512),
                 REFL_OK);
    imp = imp_build(s, &obj, 1, &cam);
    cr_assert_eq(refl_mesh_sample_points(m, NULL, 2000.0f / (radius * radius), 3, NULL, &pts), REFL_OK);
    for (i = 0; i < pts->count; ++i) {
        float o[3];
        int u, v;
        refl_vec3 p = refl_v3(pts->positions[3 * i], pts->positions[3 * i + 1], pts->positions[3 * i + 2]);
        if (!refl_spoc_project(&cam, p, o)) continue;
        u = (int)floorf(o[0]);
        v = (int)floorf(o[1]);
        if (u < 0 || v < 0 || u >= imp->width || v >= imp->height) continue;
        if (imp->color[4 * ((size_t)v * imp->width + u) + 3] > 0.0f &&
            fabsf(imp->depth[(size_t)v * imp->width + u] - o[2]) <= imp->depth_tolerance)
            ++stored;
    }
    {
        double f = (double)stored / pts->count;
        refl_points_destroy(pts);
        refl_impostor_destroy(imp);
        return f;
    }
}

Test(impostor, fig7_spoc_stores_more_of_the_teapot) {
    refl_scene *s = imp_scene();
    refl_mesh *m = NULL, *copy;
    refl_material mat = refl_material_diffuse(0.7f, 0.7f, 0.7f);
    double plain, spoc;
    int obj;
    cr_assert_eq(refl_mesh_teapot(8, NULL, &m), REFL_OK);
    cr_assert_eq(refl_mesh_subdivide(m, 1e9f, &copy), REFL_OK);
    obj = refl_scene_add(s, m, &mat, refl_mat4_identity());
    plain = stored_fraction(s, obj, copy, 0.0f);
    spoc = stored_fraction(s, obj, copy, 1.0f);
    cr_log_info("Fig. 7: teapot samples stored: plain depth image %.3f, SPOC %.3f\n", plain, spoc);
    cr_expect(plain > 0.3 && plain < 0.5, "plain depth image stores %g", plain);
    cr_expect(spoc > plain + 0.05, "SPOC stores %g, the plain depth image %g", spoc, plain);
    refl_mesh_destroy(copy);
    refl_scene_destroy(s);
}
