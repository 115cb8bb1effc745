/* Soft shadows (paper 002's jittered lights): refl_render_desc's
   soft_shadow_samples with lights of nonzero radius. The rasterised
   methods (DIRECT's base pass, PLANAR's mirrored levels) draw a stencil
   shadow mask per light sample and weigh each light by its visible
   fraction; RAYTRACE casts a shadow ray per sample and weighs alike
   (refl_shade_diffuse_weighted), so the images compare pixel for pixel. */
#define _POSIX_C_SOURCE 200809L
#include "../../reflect.h"
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "refl_test_util.h"

static refl_frame *render_soft(const refl_scene *s, const refl_view *v, refl_method method, int depth, int shadows,
                               int samples, int threads) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = method;
    d.depth = depth;
    d.lighting.shadows = shadows;
    d.lighting.soft_shadow_samples = samples;
    d.threads = threads;
    return tu_refl_render(s, v, &d);
}

/* A box held over a floor (object 0), one point light of the given radius. */
static refl_scene *box_scene(float radius) {
    static const float grey[3] = {0.8f, 0.8f, 0.75f}, blue[3] = {0.2f, 0.3f, 0.9f};
    refl_scene *s;
    refl_mesh *floor_mesh, *box;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(12.0f, 8, NULL, &floor_mesh), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(1.5f, 1.0f, 1.2f), NULL, &box), REFL_OK);
    tu_refl_add_object(s, floor_mesh, REFL_DIFFUSE, grey, refl_mat4_identity());
    tu_refl_add_object(s, box, REFL_DIFFUSE, blue,
               refl_mat4_mul(refl_mat4_translate(refl_v3(0.3f, 1.8f, -0.2f)), refl_mat4_rotate(refl_v3(0, 1, 0), 0.5f)));
    tu_refl_add_point_light(s, refl_v3(2.0f, 6.0f, 1.5f), 0.7f, radius);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 0.15f;
    s->environment.color[0] = 0.3f; s->environment.color[1] = 0.5f; s->environment.color[2] = 0.8f;
    return s;
}

static refl_view box_view(void) {
    refl_view v;
    memset(&v, 0, sizeof v);
    v.eye = refl_v3(4.0f, 5.0f, 7.0f);
    v.target = refl_v3(0, 0.5f, 0);
    v.up = refl_v3(0, 1, 0);
    v.width = 200;
    v.height = 150;
    return v;
}

/* Per pixel: 1 where the view ray's first hit is the floor (object 0). */
static unsigned char *floor_pixels(const refl_scene *s, const refl_view *v, long *count) {
    refl_bvh *bvh = NULL;
    unsigned char *fl = (unsigned char *)calloc((size_t)v->width * (size_t)v->height, 1);
    int x, y;
    cr_assert_not_null(fl);
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    *count = 0;
    for (y = 0; y < v->height; ++y)
        for (x = 0; x < v->width; ++x) {
            refl_vec3 o, d;
            float tmax;
            refl_hit h;
            refl_view_ray(v, s, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
            if (refl_bvh_intersect(bvh, o, d, 0.0f, tmax, &h) && h.object == 0) {
                fl[(size_t)y * (size_t)v->width + (size_t)x] = 1;
                ++*count;
            }
        }
    refl_bvh_destroy(bvh);
    return fl;
}

static int channel_diff(const float *a, const float *b) {
    int c, m = 0;
    for (c = 0; c < 3; ++c) {
        int d = abs(tu_unorm8(a[c]) - tu_unorm8(b[c]));
        if (d > m) m = d;
    }
    return m;
}

static void expect_same_bytes(const refl_frame *a, const refl_frame *b, const char *what) {
    size_t n = (size_t)a->width * (size_t)a->height;
    cr_assert_eq(memcmp(a->rgba, b->rgba, (4 * n) * sizeof(float)), 0, "%s: colours differ", what);
}

/* Penumbra pixels of the floor: strictly between the umbra (ambient only:
   the hard shadow's value) and the lit value (no shadows), by more than
   2/255 from each, in the green channel. */
static long penumbra(const refl_frame *soft, const refl_frame *hard, const refl_frame *lit, const unsigned char *fl,
                     int *umbra_out) {
    size_t i, n = (size_t)soft->width * (size_t)soft->height;
    long count = 0;
    int umbra = -1;
    for (i = 0; i < n; ++i) /* the hard shadow's colour on the floor: the umbra */
        if (fl[i] && tu_unorm8(hard->rgba[4 * i + 1]) + 8 < tu_unorm8(lit->rgba[4 * i + 1])) {
            umbra = tu_unorm8(hard->rgba[4 * i + 1]);
            break;
        }
    cr_assert(umbra >= 0, "the box must shadow the floor");
    for (i = 0; i < n; ++i) {
        int g = tu_unorm8(soft->rgba[4 * i + 1]);
        if (fl[i] && g > umbra + 2 && g < (int)tu_unorm8(lit->rgba[4 * i + 1]) - 2) ++count;
    }
    if (umbra_out) *umbra_out = umbra;
    return count;
}

Test(refl_soft_shadow, direct_equals_raytrace_on_a_box_over_a_floor) {
    refl_scene *s = box_scene(0.6f);
    refl_view v = box_view();
    long floor_count, close = 0, exact = 0;
    unsigned char *fl = floor_pixels(s, &v, &floor_count);
    refl_frame *d = render_soft(s, &v, REFL_DIRECT, 1, 1, 16, 2), *r = render_soft(s, &v, REFL_RAYTRACE, 1, 1, 16, 2);
    size_t i, n = (size_t)v.width * (size_t)v.height;
    int worst = 0;
    for (i = 0; i < n; ++i) {
        int df;
        if (!fl[i]) continue;
        df = channel_diff(d->rgba + 4 * i, r->rgba + 4 * i);
        close += df <= 2;
        exact += df == 0;
        if (df > worst) worst = df;
    }
    cr_log_info("soft box, 16 samples: DIRECT within 2/255 of RAYTRACE on %ld of %ld floor pixels (%.3f%%), "
                "%ld exact, worst %d/255",
                close, floor_count, 100.0 * (double)close / (double)floor_count, exact, worst);
    cr_assert(floor_count > 5000);
    cr_assert((double)close >= 0.99 * (double)floor_count, "%ld of %ld", close, floor_count);
    refl_frame_destroy(d);
    refl_frame_destroy(r);
    free(fl);
    refl_scene_destroy(s);
}

Test(refl_soft_shadow, the_penumbra_shrinks_to_the_hard_shadow) {
    static const float radii[4] = {0.9f, 0.45f, 0.15f, 0.0f};
    refl_scene *s = box_scene(0.0f);
    refl_view v = box_view();
    long floor_count, last = -1;
    unsigned char *fl = floor_pixels(s, &v, &floor_count);
    refl_frame *hard = render_soft(s, &v, REFL_DIRECT, 1, 1, 0, 2), *lit = render_soft(s, &v, REFL_DIRECT, 1, 0, 0, 2);
    refl_frame *hard_rt = render_soft(s, &v, REFL_RAYTRACE, 1, 1, 0, 2);
    int k, umbra = 0;
    cr_assert_eq(penumbra(hard, hard, lit, fl, &umbra), 0, "hard shadows have no penumbra");
    for (k = 0; k < 4; ++k) {
        refl_frame *d, *r;
        long pd, pr;
        s->lights[0].radius = radii[k];
        d = render_soft(s, &v, REFL_DIRECT, 1, 1, 16, 2);
        r = render_soft(s, &v, REFL_RAYTRACE, 1, 1, 16, 2);
        pd = penumbra(d, hard, lit, fl, NULL);
        pr = penumbra(r, hard_rt, lit, fl, NULL);
        cr_log_info("radius %.2f: penumbra %ld pixels (DIRECT), %ld (RAYTRACE); umbra %d/255", (double)radii[k], pd,
                    pr, umbra);
        if (k == 0) cr_assert(pd > 300 && pr > 300, "a wide light casts a penumbra (%ld, %ld)", pd, pr);
        if (last >= 0) cr_assert(pd < last, "radius %.2f: the penumbra must shrink (%ld after %ld)", (double)radii[k], pd, last);
        last = pd;
        if (radii[k] == 0.0f) {
            cr_assert_eq(pd, 0);
            expect_same_bytes(d, hard, "radius 0, 16 samples: DIRECT as hard shadows");
            expect_same_bytes(r, hard_rt, "radius 0, 16 samples: RAYTRACE as hard shadows");
        }
        refl_frame_destroy(d);
        refl_frame_destroy(r);
    }
    {
        /* one sample, whatever the radius: hard shadows */
        refl_frame *d, *r;
        s->lights[0].radius = 0.9f;
        d = render_soft(s, &v, REFL_DIRECT, 1, 1, 1, 2);
        r = render_soft(s, &v, REFL_RAYTRACE, 1, 1, 1, 2);
        expect_same_bytes(d, hard, "one sample: DIRECT as hard shadows");
        expect_same_bytes(r, hard_rt, "one sample: RAYTRACE as hard shadows");
        refl_frame_destroy(d);
        refl_frame_destroy(r);
    }
    refl_frame_destroy(hard);
    refl_frame_destroy(hard_rt);
    refl_frame_destroy(lit);
    free(fl);
    refl_scene_destroy(s);
}

Test(refl_soft_shadow, same_bytes_for_every_thread_count) {
    static const refl_method methods[3] = {REFL_DIRECT, REFL_RAYTRACE, REFL_PLANAR};
    refl_scene *s;
    refl_view v;
    int m, t;
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    s->lights[0].radius = 0.5f;
    s->lights[1].radius = 0.05f;
    v = s->camera;
    v.width = 120; v.height = 90;
    for (m = 0; m < 3; ++m) {
        refl_frame *one = render_soft(s, &v, methods[m], 2, 1, 8, 1);
        for (t = 3; t <= 8; t += 5) {
            refl_frame *f = render_soft(s, &v, methods[m], 2, 1, 8, t);
            expect_same_bytes(f, one, refl_method_name(methods[m]));
            refl_frame_destroy(f);
        }
        refl_frame_destroy(one);
    }
    refl_scene_destroy(s);
}

Test(refl_soft_shadow, planar_equals_raytrace_in_the_mirror_room) {
    refl_scene *s;
    refl_view v;
    int depth;
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    s->lights[0].radius = 0.8f;
    s->lights[1].radius = 0.08f; /* the directional fill: radians */
    v = s->camera;
    v.width = 200; v.height = 150;
    for (depth = 1; depth <= 2; ++depth) {
        refl_frame *planar = render_soft(s, &v, REFL_PLANAR, depth, 1, 12, 2);
        refl_frame *truth = render_soft(s, &v, REFL_RAYTRACE, depth, 1, 12, 2);
        refl_frame *hard = render_soft(s, &v, REFL_RAYTRACE, depth, 1, 0, 2);
        refl_image_error ie;
        size_t i, n = (size_t)v.width * (size_t)v.height;
        long long mirror = 0, soft_differs = 0;
        for (i = 0; i < n; ++i) {
            if (!truth->stencil[i]) continue;
            ++mirror;
            soft_differs += memcmp(truth->rgba + 4 * i, hard->rgba + 4 * i, 3 * sizeof(float)) != 0;
        }
        cr_assert_eq(refl_measure_image_error(planar, truth, 1, 2.0f / 255.0f, &ie), REFL_OK);
        cr_log_info("soft, depth %d: %lld of %lld mirror pixels differ from hard shadows; PLANAR vs RAYTRACE PSNR "
                    "%.2f dB, %.3f%% over 2/255",
                    depth, soft_differs, mirror, ie.psnr, 100.0 * ie.over_threshold);
        cr_assert(soft_differs > mirror / 50, "the mirrors must show soft shadows (%lld of %lld)", soft_differs, mirror);
        cr_assert(ie.over_threshold <= 0.01, "depth %d: %.3f%% of mirror pixels over 2/255", depth,
                  100.0 * ie.over_threshold);
        refl_frame_destroy(planar);
        refl_frame_destroy(truth);
        refl_frame_destroy(hard);
    }
    refl_scene_destroy(s);
}

Test(refl_soft_shadow, light_samples_and_arguments) {
    refl_light p, d, q;
    refl_scene *s = box_scene(0.5f);
    refl_view v = box_view();
    refl_frame *f;
    refl_render_desc rd;
    int k;
    memset(&p, 0, sizeof p);
    p.type = REFL_LIGHT_POINT;
    p.position = refl_v3(1, 2, 3);
    p.radius = 0.5f;
    q = refl_light_sample(&p, 0, 1);
    cr_assert(q.position.x == 1.0f && q.position.y == 2.0f && q.position.z == 3.0f, "one sample: the centre");
    for (k = 0; k < 16; ++k) {
        float r;
        q = refl_light_sample(&p, k, 16);
        r = refl_v3_length(refl_v3_sub(q.position, p.position));
        cr_assert(fabsf(r - 0.5f) < 1e-5f, "sample %d lies on the sphere (%g)", k, (double)r);
    }
    memset(&d, 0, sizeof d);
    d.type = REFL_LIGHT_DIRECTIONAL;
    d.direction = refl_v3(0, -1, 0);
    d.radius = 0.1f;
    for (k = 0; k < 16; ++k) {
        float c;
        q = refl_light_sample(&d, k, 16);
        c = refl_v3_dot(q.direction, refl_v3(0, -1, 0));
        cr_assert(fabsf(refl_v3_length(q.direction) - 1.0f) < 1e-5f && c >= cosf(0.1f) - 1e-6f,
                  "sample %d within the cone", k);
    }
    cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &f), REFL_OK);
    memset(&rd, 0, sizeof rd);
    rd.lighting.shadows = 1;
    rd.lighting.soft_shadow_samples = -1;
    cr_assert_eq(refl_render(s, &v, &rd, f), REFL_ERROR_INVALID_ARGUMENT);
    rd.lighting.soft_shadow_samples = 1025;
    cr_assert_eq(refl_render(s, &v, &rd, f), REFL_ERROR_INVALID_ARGUMENT);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

Test(refl_soft_shadow, weighted_shading_with_whole_weights_is_the_lit_shading) {
    refl_scene *s = box_scene(0.0f);
    const refl_material *m = &s->materials[0];
    float a[3], b[3], w1 = 1.0f, w0 = 0.0f, wh = 0.5f, h[3];
    unsigned char l1 = 1, l0 = 0;
    int c;
    refl_vec3 p = refl_v3(0.3f, 0.0f, 0.7f), n = refl_v3(0, 1, 0);
    refl_shade_diffuse_lit(s, m, p, n, NULL, &l1, a);
    refl_shade_diffuse_weighted(s, m, p, n, NULL, &w1, b);
    cr_assert_eq(memcmp(a, b, sizeof a), 0);
    refl_shade_diffuse_lit(s, m, p, n, NULL, &l0, a);
    refl_shade_diffuse_weighted(s, m, p, n, NULL, &w0, b);
    cr_assert_eq(memcmp(a, b, sizeof a), 0);
    refl_shade_diffuse_weighted(s, m, p, n, NULL, &wh, h);
    refl_shade_diffuse_lit(s, m, p, n, NULL, &l1, b);
    for (c = 0; c < 3; ++c) cr_assert(fabsf(h[c] - 0.5f * (a[c] + b[c])) < 1e-6f, "half a light: halfway");
    refl_scene_destroy(s);
}
