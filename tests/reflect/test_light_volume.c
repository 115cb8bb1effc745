/* Paper 002's light volumes, caustics and translucency in PLANAR
   (refl_render_desc.lighting.light_volumes, caustic_samples, translucency), against
   RAYTRACE, which traces the same light paths, and against answers worked
   out here by hand: the square of floor a ceiling mirror lights, the
   paths two boxes block, the fog's exp(-density h). */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

/* The scene: a grey floor (object 0, y = 0); a square mirror of side
   MIRROR_SIDE facing down at y = MIRROR_Y, centred over (MX, MZ) (object 1);
   a point light at LIGHT below it. Optional boxes: one standing on the
   floor inside the reflected light (object 2) and one between the light
   and the mirror (object 3). */
#define MIRROR_Y 3.0f
#define MIRROR_SIDE 1.2f
#define MX 0.2f
#define MZ -0.3f
static const float LIGHT[3] = {0.5f, 1.5f, -1.5f};
static const float FLOOR_RGB[3] = {0.6f, 0.6f, 0.6f};
#define LIGHT_K 0.5f
#define AMBIENT 0.1f
#define REFLECTANCE 0.8f
static const float BOX_OUT[2][3] = {{-0.5f, 0.0f, 0.9f}, {0.1f, 0.9f, 1.3f}}; /* lo, hi */
static const float BOX_IN[2][3] = {{0.3f, 2.1f, -1.1f}, {0.6f, 2.3f, -0.9f}};

static void add_box(refl_scene *s, const float b[2][3], const float rgb[3]) {
    refl_mesh *m;
    cr_assert_eq(refl_mesh_box(refl_v3(b[1][0] - b[0][0], b[1][1] - b[0][1], b[1][2] - b[0][2]), NULL, &m), REFL_OK);
    tu_refl_add_object(s, m, REFL_DIFFUSE, rgb,
                       refl_mat4_translate(refl_v3(0.5f * (b[0][0] + b[1][0]), 0.5f * (b[0][1] + b[1][1]),
                                                   0.5f * (b[0][2] + b[1][2]))));
}

static refl_scene *mirror_scene(int boxes, float radius) {
    static const float blue[3] = {0.2f, 0.3f, 0.8f}, white[3] = {1, 1, 1};
    refl_scene *s;
    refl_mesh *floor_mesh, *mirror;
    int mi;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(12.0f, 8, NULL, &floor_mesh), REFL_OK);
    cr_assert_eq(refl_mesh_plane(MIRROR_SIDE, 1, NULL, &mirror), REFL_OK);
    tu_refl_add_object(s, floor_mesh, REFL_DIFFUSE, FLOOR_RGB, refl_mat4_identity());
    /* turned over about x: facing -y */
    mi = tu_refl_add_object(s, mirror, REFL_MIRROR, white,
                            refl_mat4_mul(refl_mat4_translate(refl_v3(MX, MIRROR_Y, MZ)),
                                          refl_mat4_rotate(refl_v3(1, 0, 0), 3.14159265f)));
    s->materials[s->objects[mi].material].reflectance = REFLECTANCE;
    if (boxes) {
        add_box(s, BOX_OUT, blue);
        add_box(s, BOX_IN, blue);
    }
    tu_refl_add_point_light(s, refl_v3(LIGHT[0], LIGHT[1], LIGHT[2]), LIGHT_K, radius);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = AMBIENT;
    s->environment.color[0] = 0.3f; s->environment.color[1] = 0.4f; s->environment.color[2] = 0.5f;
    return s;
}

static refl_view mirror_view(void) {
    refl_view v;
    memset(&v, 0, sizeof v);
    v.eye = refl_v3(0.3f, 2.4f, 6.0f);
    v.target = refl_v3(0.0f, 0.2f, 1.0f);
    v.up = refl_v3(0, 1, 0);
    v.fovy_degrees = 50.0f;
    v.width = 200;
    v.height = 150;
    return v;
}

static refl_frame *render_lv(const refl_scene *s, const refl_view *v, refl_method m, int light_volumes, int shadows,
                             int caustic_samples, int threads) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = m;
    d.depth = 2;
    d.lighting.shadows = shadows;
    d.lighting.light_volumes = light_volumes;
    d.lighting.caustic_samples = caustic_samples;
    d.threads = threads;
    return tu_refl_render(s, v, &d);
}

/* The floor point each pixel shows (the view ray's first hit, object 0),
   or none. */
static int *floor_points(const refl_scene *s, const refl_view *v, float *pts) {
    refl_bvh *bvh = NULL;
    int *is_floor = (int *)calloc((size_t)v->width * (size_t)v->height, sizeof(int));
    int x, y;
    cr_assert_not_null(is_floor);
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    for (y = 0; y < v->height; ++y)
        for (x = 0; x < v->width; ++x) {
            size_t i = (size_t)y * (size_t)v->width + (size_t)x;
            refl_vec3 o, d;
            float tmax;
            refl_hit h;
            refl_view_ray(v, s, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
            if (refl_bvh_intersect(bvh, o, d, 0.0f, tmax, &h) && h.object == 0) {
                is_floor[i] = 1;
                pts[3 * i] = o.x + h.t * d.x;
                pts[3 * i + 1] = o.y + h.t * d.y;
                pts[3 * i + 2] = o.z + h.t * d.z;
            }
        }
    refl_bvh_destroy(bvh);
    return is_floor;
}

/* The virtual light: the light mirrored in y = MIRROR_Y. */
static void virtual_light(double out[3]) {
    out[0] = LIGHT[0];
    out[1] = 2.0 * MIRROR_Y - LIGHT[1];
    out[2] = LIGHT[2];
}

/* Where the path from floor point p to the virtual light meets the
   mirror's plane, and how far inside the mirror's square it is (negative:
   outside), in world units. */
static double through_mirror(const float *p, double m[3]) {
    double vl[3], t;
    virtual_light(vl);
    t = (MIRROR_Y - p[1]) / (vl[1] - p[1]);
    m[0] = p[0] + t * (vl[0] - p[0]);
    m[1] = MIRROR_Y;
    m[2] = p[2] + t * (vl[2] - p[2]);
    return fmin(0.5 * MIRROR_SIDE - fabs(m[0] - MX), 0.5 * MIRROR_SIDE - fabs(m[2] - MZ));
}

/* The segment a -> b against the box grown by g on every side (slabs). */
static int segment_hits_box(const double a[3], const double b[3], const float box[2][3], double g) {
    double t0 = 0.0, t1 = 1.0;
    int c;
    for (c = 0; c < 3; ++c) {
        double d = b[c] - a[c], lo = box[0][c] - g, hi = box[1][c] + g;
        if (fabs(d) < 1e-12) {
            if (a[c] < lo || a[c] > hi) return 0;
        } else {
            double u = (lo - a[c]) / d, w = (hi - a[c]) / d;
            if (u > w) { double tmp = u; u = w; w = tmp; }
            t0 = fmax(t0, u);
            t1 = fmin(t1, w);
        }
    }
    return t0 <= t1;
}

/* The green the virtual light adds at floor point p, in [0, 1]: base times
   reflectance times Lambert towards the virtual light times the light. */
static double added_green(const float *p) {
    double vl[3], d[3], len;
    virtual_light(vl);
    d[0] = vl[0] - p[0]; d[1] = vl[1] - p[1]; d[2] = vl[2] - p[2];
    len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    return FLOOR_RGB[1] * REFLECTANCE * (d[1] / len) * LIGHT_K;
}

/* No blockers, no shadows: the floor brightens by exactly the virtual
   light's Lambert term inside the mirror's footprint (the light volume's
   cross-section, a square three times the mirror's side here) and not a
   level anywhere else. */
Test(refl_light_volume, the_lit_floor_is_the_mirrored_frustums_footprint) {
    refl_scene *s = mirror_scene(0, 0.0f);
    refl_view v = mirror_view();
    size_t n = (size_t)v.width * (size_t)v.height, i;
    float *pts = (float *)calloc(3 * n, sizeof(float));
    int *fl = floor_points(s, &v, pts);
    refl_frame *off = render_lv(s, &v, REFL_PLANAR, 0, 0, 0, 2), *on = render_lv(s, &v, REFL_PLANAR, 1, 0, 0, 2);
    long inside = 0, outside = 0, bad_in = 0, bad_out = 0;
    int worst = 0;
    for (i = 0; i < n; ++i) {
        double m[3], margin;
        int diff;
        if (!fl[i]) continue;
        margin = through_mirror(pts + 3 * i, m);
        diff = (int)tu_unorm8(on->rgba[4 * i + 1]) - (int)tu_unorm8(off->rgba[4 * i + 1]);
        if (margin > 0.02) {
            int e = abs(diff - (int)lround(255.0 * added_green(pts + 3 * i)));
            ++inside;
            bad_in += e > 1;
            if (e > worst) worst = e;
        } else if (margin < -0.02) {
            ++outside;
            bad_out += memcmp(on->rgba + 4 * i, off->rgba + 4 * i, 4 * sizeof(float)) != 0;
        }
    }
    cr_log_info("footprint: %ld floor pixels inside (%ld off by more than 1/255, worst %d), %ld outside (%ld changed)",
                inside, bad_in, worst, outside, bad_out);
    cr_assert(inside > 2000, "the footprint must be on screen: %ld pixels", inside);
    cr_assert(outside > 2000);
    cr_assert_eq(bad_in, 0, "%ld footprint pixels not lit by the analytic amount (worst %d/255)", bad_in, worst);
    cr_assert_eq(bad_out, 0, "%ld pixels lit outside the footprint", bad_out);
    refl_frame_destroy(off);
    refl_frame_destroy(on);
    free(fl);
    free(pts);
    refl_scene_destroy(s);
}

/* With shadows and two boxes: one in the reflected light (it blocks the
   way from the mirror to the floor), one between the light and the
   mirror (it blocks the way in, the paper's refracted-into shadows). A
   footprint pixel is lit by the analytic amount exactly when neither
   path crosses a box (classified with boxes grown and shrunk by 0.02,
   pixels in between skipped); both kinds of blocked pixels must exist. */
Test(refl_light_volume, boxes_cast_shadows_in_the_reflected_light_both_ways) {
    refl_scene *s = mirror_scene(1, 0.0f);
    refl_view v = mirror_view();
    size_t n = (size_t)v.width * (size_t)v.height, i;
    float *pts = (float *)calloc(3 * n, sizeof(float));
    int *fl = floor_points(s, &v, pts);
    refl_frame *off = render_lv(s, &v, REFL_PLANAR, 0, 1, 0, 2), *on = render_lv(s, &v, REFL_PLANAR, 1, 1, 0, 2);
    long lit = 0, blocked_out = 0, blocked_in = 0, bad = 0;
    double lt[3] = {LIGHT[0], LIGHT[1], LIGHT[2]};
    for (i = 0; i < n; ++i) {
        double m[3], p[3];
        int diff, grown_out, grown_in, shrunk_out, shrunk_in;
        if (!fl[i] || through_mirror(pts + 3 * i, m) <= 0.02) continue;
        p[0] = pts[3 * i]; p[1] = pts[3 * i + 1]; p[2] = pts[3 * i + 2];
        grown_out = segment_hits_box(p, m, BOX_OUT, 0.02) || segment_hits_box(p, m, BOX_IN, 0.02);
        shrunk_out = segment_hits_box(p, m, BOX_OUT, -0.02) || segment_hits_box(p, m, BOX_IN, -0.02);
        grown_in = segment_hits_box(m, lt, BOX_OUT, 0.02) || segment_hits_box(m, lt, BOX_IN, 0.02);
        shrunk_in = segment_hits_box(m, lt, BOX_OUT, -0.02) || segment_hits_box(m, lt, BOX_IN, -0.02);
        if (grown_out != shrunk_out || grown_in != shrunk_in) continue; /* near a shadow's edge */
        diff = (int)tu_unorm8(on->rgba[4 * i + 1]) - (int)tu_unorm8(off->rgba[4 * i + 1]);
        if (shrunk_out || shrunk_in) {
            blocked_out += shrunk_out;
            blocked_in += shrunk_in && !shrunk_out;
            bad += diff != 0;
        } else {
            ++lit;
            bad += abs(diff - (int)lround(255.0 * added_green(pts + 3 * i))) > 1;
        }
    }
    cr_log_info("reflected shadows: %ld footprint pixels lit, %ld blocked on the way out, %ld only on the way in; "
                "%ld wrong",
                lit, blocked_out, blocked_in, bad);
    cr_assert(lit > 1000 && blocked_out > 200 && blocked_in > 50, "%ld %ld %ld", lit, blocked_out, blocked_in);
    cr_assert_eq(bad, 0, "%ld footprint pixels lit wrongly", bad);
    refl_frame_destroy(off);
    refl_frame_destroy(on);
    free(fl);
    free(pts);
    refl_scene_destroy(s);
}

static void expect_close_to_raytrace(const refl_frame *planar, const refl_frame *truth, double min_close,
                                     const char *what) {
    size_t i, n = (size_t)planar->width * (size_t)planar->height;
    long close = 0;
    int worst = 0;
    refl_image_error ie;
    for (i = 0; i < n; ++i) {
        int c, m = 0;
        for (c = 0; c < 3; ++c) {
            int e = abs((int)tu_unorm8(planar->rgba[4 * i + c]) - (int)tu_unorm8(truth->rgba[4 * i + c]));
            if (e > m) m = e;
        }
        close += m <= 2;
        if (m > worst) worst = m;
    }
    cr_assert_eq(refl_measure_image_error(planar, truth, 0, 2.0f / 255.0f, &ie), REFL_OK);
    cr_log_info("%s: %.3f%% of pixels within 2/255 of RAYTRACE, PSNR %.2f dB, worst %d/255", what,
                100.0 * (double)close / (double)n, ie.psnr, worst);
    cr_assert((double)close >= min_close * (double)n, "%s: %ld of %zu within 2/255", what, close, n);
}

/* The whole frame (floor, boxes, and the reflected light seen again in the
   mirror at the second level) against the traced paths. */
Test(refl_light_volume, planar_equals_raytrace_with_shadows_and_blockers) {
    refl_scene *s = mirror_scene(1, 0.0f);
    refl_view v = mirror_view();
    refl_frame *p = render_lv(s, &v, REFL_PLANAR, 1, 1, 0, 2), *r = render_lv(s, &v, REFL_RAYTRACE, 1, 1, 0, 2);
    refl_frame *r_off = render_lv(s, &v, REFL_RAYTRACE, 0, 1, 0, 2);
    size_t i, n = (size_t)v.width * (size_t)v.height;
    long changed = 0;
    for (i = 0; i < n; ++i) changed += tu_unorm8(r->rgba[4 * i + 1]) > tu_unorm8(r_off->rgba[4 * i + 1]) + 8;
    cr_log_info("RAYTRACE: %ld pixels brighter by the reflected light", changed);
    cr_assert(changed > 3000, "the traced reflected light must show: %ld pixels", changed);
    expect_close_to_raytrace(p, r, 0.995, "light volumes, shadows");
    refl_frame_destroy(p);
    refl_frame_destroy(r);
    refl_frame_destroy(r_off);
    refl_scene_destroy(s);
}

/* Caustics: a light with a radius, 16 samples: the footprint's edge is a
   gradient (pixels partly lit) that matches the traced samples; one
   sample is the hard light volume. */
Test(refl_light_volume, caustic_samples_soften_the_footprint_as_traced) {
    refl_scene *s = mirror_scene(1, 0.25f);
    refl_view v = mirror_view();
    refl_frame *p = render_lv(s, &v, REFL_PLANAR, 1, 1, 16, 2), *r = render_lv(s, &v, REFL_RAYTRACE, 1, 1, 16, 2);
    refl_frame *hard = render_lv(s, &v, REFL_PLANAR, 1, 0, 0, 2), *one = render_lv(s, &v, REFL_PLANAR, 1, 0, 1, 2);
    refl_frame *off = render_lv(s, &v, REFL_PLANAR, 0, 0, 0, 2), *soft = render_lv(s, &v, REFL_PLANAR, 1, 0, 16, 2);
    size_t i, n = (size_t)v.width * (size_t)v.height;
    long partial = 0, hard_partial = 0;
    cr_assert_eq(memcmp(hard->rgba, one->rgba, (4 * n) * sizeof(float)), 0, "one caustic sample is the light's centre");
    for (i = 0; i < n; ++i) {
        int full = tu_unorm8(hard->rgba[4 * i + 1]) - tu_unorm8(off->rgba[4 * i + 1]), got = tu_unorm8(soft->rgba[4 * i + 1]) - tu_unorm8(off->rgba[4 * i + 1]);
        /* strictly between unlit and the hard footprint's level nearby */
        partial += got > 2 && (full == 0 || got < full - 2);
        hard_partial += full > 0 && full < 3;
    }
    cr_log_info("caustics: %ld partly lit pixels (hard: %ld)", partial, hard_partial);
    cr_assert(partial > 300, "a light of radius 0.25 must blur the footprint's edge: %ld", partial);
    expect_close_to_raytrace(p, r, 0.99, "caustics, 16 samples, shadows");
    refl_frame_destroy(p);
    refl_frame_destroy(r);
    refl_frame_destroy(hard);
    refl_frame_destroy(one);
    refl_frame_destroy(off);
    refl_frame_destroy(soft);
    refl_scene_destroy(s);
}

Test(refl_light_volume, same_bytes_for_every_thread_count_and_nothing_without_mirrors) {
    refl_scene *s = mirror_scene(1, 0.25f), *plain;
    refl_view v = mirror_view();
    refl_frame *a = render_lv(s, &v, REFL_PLANAR, 1, 1, 8, 1), *b = render_lv(s, &v, REFL_PLANAR, 1, 1, 8, 3);
    refl_frame *c, *d;
    size_t n = (size_t)v.width * (size_t)v.height;
    cr_assert_eq(memcmp(a->rgba, b->rgba, (4 * n) * sizeof(float)), 0);
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    /* the mirror made diffuse: no virtual light, the same bytes as off */
    cr_assert_eq(refl_scene_builtin("default", NULL, &plain), REFL_OK);
    s->materials[s->objects[1].material].type = REFL_DIFFUSE;
    c = render_lv(s, &v, REFL_PLANAR, 1, 1, 0, 2);
    d = render_lv(s, &v, REFL_PLANAR, 0, 1, 0, 2);
    cr_assert_eq(memcmp(c->rgba, d->rgba, (4 * n) * sizeof(float)), 0);
    refl_frame_destroy(c);
    refl_frame_destroy(d);
    refl_scene_destroy(plain);
    refl_scene_destroy(s);
}

/* ---- translucency ------------------------------------------------------------------ */

/* A glass slab (z in [1.8, 2.2]) before a floor and a box, seen head on. */
#define SLAB_FRONT 2.2f
static refl_scene *slab_scene(const float glass_rgb[3]) {
    static const float red[3] = {0.9f, 0.3f, 0.2f}, box_b[2][3] = {{-0.6f, 0.0f, -1.5f}, {0.4f, 1.2f, -0.5f}};
    refl_scene *s = mirror_scene(0, 0.0f);
    refl_mesh *m;
    int g;
    s->materials[s->objects[1].material].type = REFL_DIFFUSE; /* no mirror here */
    add_box(s, box_b, red);
    cr_assert_eq(refl_mesh_box(refl_v3(3.0f, 2.0f, 0.4f), NULL, &m), REFL_OK);
    g = tu_refl_add_object(s, m, REFL_GLASS, glass_rgb, refl_mat4_translate(refl_v3(0.0f, 1.0f, 2.0f)));
    s->materials[s->objects[g].material].ior = 1.5f;
    return s;
}

static refl_frame *render_fog(const refl_scene *s, const refl_view *v, refl_method m, float translucency) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = m; /* the default depth: the slab's faces seen again inside must not undo the fog */
    d.lighting.translucency = translucency;
    d.threads = 2;
    return tu_refl_render(s, v, &d);
}

static refl_view slab_view(void) {
    refl_view v;
    memset(&v, 0, sizeof v);
    v.eye = refl_v3(0.0f, 1.0f, 6.0f);
    v.target = refl_v3(0.0f, 0.8f, 0.0f);
    v.up = refl_v3(0, 1, 0);
    v.width = 160;
    v.height = 120;
    return v;
}

/* PLANAR only: A (nearly) clear, B fogged towards black, Z wholly fogged (black).
   Per channel, (A - B) / (A - Z) is 1 - f, so f = exp(-density h), h the
   distance of the point the pixel shows (frame->points) behind the
   slab's front face, at every glass pixel whose refracted share is large. */
Test(refl_light_volume, translucency_fogs_by_exp_of_the_distance_behind_the_face) {
    static const float black[3] = {0, 0, 0};
    const float density = 0.6f;
    refl_scene *s = slab_scene(black);
    refl_view v = slab_view();
    /* A: as good as clear (f = 1 - 1e-6 at most), drawn the translucent way */
    refl_frame *a = render_fog(s, &v, REFL_PLANAR, 1e-7f), *b = render_fog(s, &v, REFL_PLANAR, density);
    refl_frame *z = render_fog(s, &v, REFL_PLANAR, 1e4f);
    size_t i, n = (size_t)v.width * (size_t)v.height;
    long checked = 0, bad = 0;
    double worst = 0.0, hmin = 1e9, hmax = 0.0;
    int glass = s->object_count;
    for (i = 0; i < n; ++i) {
        const float *p = a->points + 3 * i;
        double h, f;
        int c;
        if (a->stencil[i] != glass || !isfinite(p[0])) continue;
        h = SLAB_FRONT - p[2];
        f = exp(-density * h);
        for (c = 0; c < 3; ++c) {
            int full = (int)tu_unorm8(a->rgba[4 * i + c]) - (int)tu_unorm8(z->rgba[4 * i + c]);
            double measured;
            if (full < 30) continue;
            measured = 1.0 - (double)((int)tu_unorm8(a->rgba[4 * i + c]) - (int)tu_unorm8(b->rgba[4 * i + c])) / (double)full;
            ++checked;
            worst = fmax(worst, fabs(measured - f));
            bad += fabs(measured - f) > 2.0 / full + 0.005;
            hmin = fmin(hmin, h);
            hmax = fmax(hmax, h);
        }
    }
    cr_log_info("translucency: %ld channels checked (h from %.2f to %.2f), worst |f - exp(-density h)| %.4f, %ld over "
                "the rounding bound",
                checked, hmin, hmax, worst, bad);
    cr_assert(checked > 3000 && hmax - hmin > 2.0, "%ld channels, h %.2f..%.2f", checked, hmin, hmax);
    cr_assert_eq(bad, 0, "%ld channels off exp(-density h) (worst %.4f)", bad, worst);
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    refl_frame_destroy(z);
    refl_scene_destroy(s);
}

/* The same fog traced. PLANAR's slab stands one sideways shift in for
   every pixel's own refraction, so through the slab it may show another
   point than the traced ray (the planar tests' slab curve), and the fog,
   which depends on the point, differs with it. Where both show the same
   point (within 0.01) or both the environment, the fogged colours agree. */
Test(refl_light_volume, translucency_equals_raytrace_where_both_show_the_same_point) {
    static const float milk[3] = {0.85f, 0.85f, 0.8f};
    refl_scene *s = slab_scene(milk);
    refl_view v = slab_view();
    refl_frame *p = render_fog(s, &v, REFL_PLANAR, 0.6f), *r = render_fog(s, &v, REFL_RAYTRACE, 0.6f);
    refl_frame *r0 = render_fog(s, &v, REFL_RAYTRACE, 0.0f);
    size_t i, n = (size_t)v.width * (size_t)v.height;
    long moved = 0, same = 0, close = 0, env = 0;
    int glass = s->object_count, worst = 0;
    for (i = 0; i < n; ++i) {
        const float *a = p->points + 3 * i, *b = r->points + 3 * i;
        int c, m = 0;
        moved += abs((int)tu_unorm8(r->rgba[4 * i]) - (int)tu_unorm8(r0->rgba[4 * i])) > 10;
        if (r->stencil[i] != glass || p->stencil[i] != glass) continue;
        if (isfinite(a[0]) != isfinite(b[0])) continue;
        if (isfinite(a[0]) && (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                  (a[2] - b[2]) * (a[2] - b[2]) > 1e-4)
            continue;
        env += !isfinite(a[0]);
        ++same;
        for (c = 0; c < 3; ++c) {
            int e = abs((int)tu_unorm8(p->rgba[4 * i + c]) - (int)tu_unorm8(r->rgba[4 * i + c]));
            if (e > m) m = e;
        }
        close += m <= 2;
        if (m > worst) worst = m;
    }
    cr_log_info("translucency 0.6: %ld glass pixels show the same point in both (%ld the environment), %.3f%% of them "
                "within 2/255 of RAYTRACE, worst %d/255; the fog moves %ld traced pixels",
                same, env, 100.0 * (double)close / (double)(same > 0 ? same : 1), worst, moved);
    cr_assert(moved > 3000, "the traced fog must show: %ld pixels", moved);
    cr_assert(same - env > 300 && env > 1000, "%ld, %ld", same, env);
    cr_assert((double)close >= 0.99 * (double)same, "%ld of %ld", close, same);
    refl_frame_destroy(p);
    refl_frame_destroy(r);
    refl_frame_destroy(r0);
    refl_scene_destroy(s);
}
