/* Shadows in the rasterised methods (shadow.c): stencil shadow volumes
   against RAYTRACE's shadow rays, pixel by pixel per light, on the default
   scene and a box over a floor (point and directional light); z-pass and
   z-fail agreeing where both are right, z-fail alone right with the eye
   inside a volume; mirrored and oblique projections, as PLANAR's mirrored
   cameras use; thread counts, allocation failures and degenerate lights.

   The internals it calls (refl__shadow_mask_mode, with the counting
   forced, and a few more) come from tests/reflect_testing.h. */
#define _POSIX_C_SOURCE 200809L
#include "../../reflect.h"
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../test_util.h"
#include "../reflect_testing.h"
#include "refl_test_util.h"

/* ---- scenes and renders --------------------------------------------------------- */

static refl_frame *render(const refl_scene *s, const refl_view *v, refl_method method, int shadows, int threads) {
    refl_frame *f = NULL;
    refl_render_desc d;
    refl_result r;
    memset(&d, 0, sizeof d);
    d.method = method;
    d.depth = 1;
    d.lighting.shadows = shadows;
    d.threads = threads;
    cr_assert_eq(refl_frame_create(v->width, v->height, NULL, &f), REFL_OK);
    r = refl_render(s, v, &d, f);
    cr_assert_eq(r, REFL_OK, "refl_render: %s", refl_result_string(r));
    return f;
}

static refl_mat4 view_proj(const refl_scene *s, const refl_view *v) {
    refl_mat4 vm, pm;
    refl_view_matrices(v, s, &vm, &pm);
    return refl_mat4_mul(pm, vm);
}

static rast_targets frame_targets(refl_frame *f) {
    rast_targets t;
    memset(&t, 0, sizeof t);
    t.color.ptr = f->rgba; t.color.width = f->width; t.color.height = f->height;
    t.color.stride = 4 * (int)sizeof(float) * f->width;
    t.color_format = RAST_COLOR_RGBA32F;
    t.depth.ptr = f->depth; t.depth.width = f->width; t.depth.height = f->height;
    t.depth.stride = (int)sizeof(float) * f->width;
    t.stencil.ptr = f->stencil; t.stencil.width = f->width; t.stencil.height = f->height;
    t.stencil.stride = f->width;
    return t;
}

static rast_context *context(int threads) {
    rast_context_desc cd;
    rast_context *rc = NULL;
    memset(&cd, 0, sizeof cd);
    cd.num_threads = threads;
    cr_assert_eq(rast_context_create(&cd, &rc), RAST_OK);
    return rc;
}

/* DIRECT's base pass, then the mask with the counting forced and the
   shadowed pixels shaded again: DIRECT with shadows, by hand. */
static refl_frame *direct_masked(const refl_scene *s, const refl_view *v, refl__shadow_mode mode, unsigned *zfail,
                                 uint8_t **lit_out) {
    refl_frame *f = render(s, v, REFL_DIRECT, 0, 2);
    rast_context *rc = context(2);
    rast_targets t = frame_targets(f);
    refl_mat4 vp = view_proj(s, v);
    uint8_t *lit = (uint8_t *)malloc((size_t)f->width * (size_t)f->height);
    cr_assert_not_null(lit);
    cr_assert_eq(rast_set_targets(rc, &t), RAST_OK);
    refl__shadow_job job = {
        .rc = rc, .scene = s, .vp = vp, .eye = v->eye, .depth = f->depth, .width = f->width, .height = f->height,
        .restore = &t};
    cr_assert_eq(refl__shadow_mask_mode(&job, lit, mode, zfail), REFL_OK);
    cr_assert_eq(refl__shade_lit(&job, -1, lit, 0), REFL_OK);
    rast_context_destroy(rc);
    if (lit_out) *lit_out = lit;
    else free(lit);
    return f;
}

static void add_light(refl_scene *s, refl_light_type type, refl_vec3 v, float k) {
    refl_light l;
    memset(&l, 0, sizeof l);
    l.type = type;
    if (type == REFL_LIGHT_POINT) l.position = v;
    else l.direction = v;
    l.color[0] = l.color[1] = l.color[2] = k;
    cr_assert(refl_scene_add_light(s, &l) >= 0);
}

/* A box (turned by `turn` radians about y) over a floor and a ball on it,
   lit by one light; allocator may be NULL. */
static refl_scene *box_scene_ex(refl_light_type type, refl_vec3 light, float box_y, float turn,
                                const refl_allocator *allocator) {
    static const float grey[3] = {0.8f, 0.8f, 0.75f}, blue[3] = {0.2f, 0.3f, 0.9f}, red[3] = {0.9f, 0.2f, 0.1f};
    refl_scene *s;
    refl_mesh *floor_mesh, *box, *ball;
    cr_assert_eq(refl_scene_create(allocator, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(12.0f, 8, NULL, &floor_mesh), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(1.5f, 1.0f, 1.2f), NULL, &box), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(0.5f, 24, 12, NULL, &ball), REFL_OK);
    tu_refl_add_object(s, floor_mesh, REFL_DIFFUSE, grey, refl_mat4_identity());
    tu_refl_add_object(s, box, REFL_DIFFUSE, blue,
               refl_mat4_mul(refl_mat4_translate(refl_v3(0.3f, box_y, -0.2f)),
                             refl_mat4_rotate(refl_v3(0, 1, 0), turn)));
    tu_refl_add_object(s, ball, REFL_DIFFUSE, red, refl_mat4_translate(refl_v3(-1.8f, 0.5f, 1.0f)));
    add_light(s, type, light, 0.7f);
    s->ambient[0] = s->ambient[1] = s->ambient[2] = 0.15f;
    s->environment.color[0] = 0.3f; s->environment.color[1] = 0.5f; s->environment.color[2] = 0.8f;
    return s;
}

static refl_scene *box_scene(refl_light_type type, refl_vec3 light, float box_y) {
    return box_scene_ex(type, light, box_y, 0.5f, NULL);
}

/* ---- agreement with RAYTRACE ------------------------------------------------------ */

typedef struct agreement {
    long pixels;        /* diffuse pixels classified in both, off shadow edges */
    long edges;         /* left out: a RAYTRACE 8-neighbour classified otherwise */
    long agree;
    long shadowed;      /* RAYTRACE's shadowed pixels among `pixels` */
    long colour_checked, colour_ok;
} agreement;

static int channel_diff(const float *a, const float *b) {
    int c, m = 0;
    for (c = 0; c < 3; ++c) m = REFL__MAX(m, abs(tu_unorm8(a[c]) - tu_unorm8(b[c])));
    return m;
}

/* Pixel classes from colours: a shadow changes a diffuse pixel's colour
   exactly where the light would have added something visible, so
   "shadowed" is shadowed-and-visible in both methods alike. -1: not a
   diffuse surface. */
static void classify(const refl_frame *unshadowed, const refl_frame *shadowed, signed char *cls) {
    size_t i, n = (size_t)unshadowed->width * (size_t)unshadowed->height;
    for (i = 0; i < n; ++i) {
        if (shadowed->stencil[i] || !(shadowed->depth[i] < 1.0f)) cls[i] = -1;
        else cls[i] = (signed char)(channel_diff(unshadowed->rgba + 4 * i, shadowed->rgba + 4 * i) != 0);
    }
}

static void agree_frames(const refl_frame *d0, const refl_frame *d1, const refl_frame *r0, const refl_frame *r1,
                         agreement *a) {
    int w = d0->width, h = d0->height, x, y, dx, dy;
    size_t n = (size_t)w * (size_t)h;
    signed char *cd = (signed char *)malloc(n), *cr = (signed char *)malloc(n);
    cr_assert(cd && cr);
    classify(d0, d1, cd);
    classify(r0, r1, cr);
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            int edge = 0;
            if (cd[i] < 0 || cr[i] < 0) continue;
            for (dy = -1; dy <= 1; ++dy)
                for (dx = -1; dx <= 1; ++dx) {
                    int nx = x + dx, ny = y + dy;
                    size_t j = (size_t)ny * (size_t)w + (size_t)nx;
                    if (nx < 0 || ny < 0 || nx >= w || ny >= h || cr[j] < 0) continue;
                    edge |= cr[j] != cr[i];
                }
            if (edge) { ++a->edges; continue; }
            ++a->pixels;
            a->shadowed += cr[i];
            if (cd[i] != cr[i]) continue;
            ++a->agree;
            /* where the unshadowed colours agree, the shadowed ones must too */
            if (channel_diff(d0->rgba + 4 * i, r0->rgba + 4 * i) <= 2) {
                ++a->colour_checked;
                a->colour_ok += channel_diff(d1->rgba + 4 * i, r1->rgba + 4 * i) <= 2;
            }
        }
    free(cd);
    free(cr);
}

/* Per light (the others dark): DIRECT (with `mode`) against RAYTRACE, with
   and without shadows. */
static agreement against_raytrace(refl_scene *s, const refl_view *v, refl__shadow_mode mode, const char *what,
                                  unsigned *zfail) {
    static const float dark[3] = {0, 0, 0};
    agreement a;
    int li, k;
    float saved[64][3];
    memset(&a, 0, sizeof a);
    if (zfail) *zfail = 0;
    cr_assert(s->light_count <= 64);
    for (li = 0; li < s->light_count; ++li) memcpy(saved[li], s->lights[li].color, sizeof saved[li]);
    for (li = 0; li < s->light_count; ++li) {
        refl_frame *d0, *d1, *r0, *r1;
        agreement one;
        unsigned used = 0;
        memset(&one, 0, sizeof one);
        for (k = 0; k < s->light_count; ++k)
            memcpy(s->lights[k].color, k == li ? saved[k] : dark, sizeof saved[k]);
        d0 = render(s, v, REFL_DIRECT, 0, 2);
        d1 = direct_masked(s, v, mode, &used, NULL);
        if (zfail) *zfail |= used & (1u << li);
        r0 = render(s, v, REFL_RAYTRACE, 0, 2);
        r1 = render(s, v, REFL_RAYTRACE, 1, 2);
        agree_frames(d0, d1, r0, r1, &one);
        cr_log_info("%s, light %d: %ld of %ld pixels agree (%.3f%%), %ld shadowed, %ld shadow-edge pixels left out; "
                    "colours within 2/255: %ld of %ld",
                    what, li, one.agree, one.pixels, 100.0 * (double)one.agree / (double)REFL__MAX(one.pixels, 1),
                    one.shadowed, one.edges, one.colour_ok, one.colour_checked);
        a.pixels += one.pixels;
        a.edges += one.edges;
        a.agree += one.agree;
        a.shadowed += one.shadowed;
        a.colour_checked += one.colour_checked;
        a.colour_ok += one.colour_ok;
        refl_frame_destroy(d0);
        refl_frame_destroy(d1);
        refl_frame_destroy(r0);
        refl_frame_destroy(r1);
    }
    for (li = 0; li < s->light_count; ++li) memcpy(s->lights[li].color, saved[li], sizeof saved[li]);
    return a;
}

static double ratio(long a, long b) { return (double)a / (double)REFL__MAX(b, 1); }

static unsigned expect_agreement(refl_scene *s, const refl_view *v, refl__shadow_mode mode, const char *what,
                                 long min_shadowed) {
    unsigned zfail;
    agreement a = against_raytrace(s, v, mode, what, &zfail);
    cr_log_info("%s: %.3f%% agree over all lights, colours %.3f%% within 2/255", what,
                100.0 * ratio(a.agree, a.pixels), 100.0 * ratio(a.colour_ok, a.colour_checked));
    cr_assert(a.shadowed >= min_shadowed, "%s: the view must show shadows (%ld)", what, a.shadowed);
    cr_assert(ratio(a.agree, a.pixels) >= 0.99, "%s: %ld of %ld pixels agree with RAYTRACE", what, a.agree,
              a.pixels);
    cr_assert(a.colour_ok == a.colour_checked, "%s: %ld of %ld agreeing pixels within 2/255 of RAYTRACE", what,
              a.colour_ok, a.colour_checked);
    return zfail;
}

Test(refl_shadow, default_scene_agrees_with_raytrace) {
    refl_scene *s;
    refl_view v;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 240; v.height = 180;
    cr_assert_eq(expect_agreement(s, &v, REFL__SHADOW_AUTO, "default", 2000), 0u, "the eye is in no volume: z-pass");
    {
        /* both lights at once, through refl_render: the final images */
        refl_frame *d = render(s, &v, REFL_DIRECT, 1, 2), *r = render(s, &v, REFL_RAYTRACE, 1, 2);
        size_t i, n = (size_t)v.width * (size_t)v.height;
        long diffuse = 0, close = 0;
        for (i = 0; i < n; ++i) {
            if (d->stencil[i] || r->stencil[i] || !(d->depth[i] < 1.0f) || !(r->depth[i] < 1.0f)) continue;
            ++diffuse;
            close += channel_diff(d->rgba + 4 * i, r->rgba + 4 * i) <= 2;
        }
        cr_log_info("default, both lights: DIRECT within 2/255 of RAYTRACE on %ld of %ld diffuse pixels (%.3f%%)",
                    close, diffuse, 100.0 * ratio(close, diffuse));
        cr_assert(ratio(close, diffuse) >= 0.98);
        refl_frame_destroy(d);
        refl_frame_destroy(r);
    }
    refl_scene_destroy(s);
}

Test(refl_shadow, box_over_floor_point_light_agrees_with_raytrace) {
    refl_scene *s = box_scene(REFL_LIGHT_POINT, refl_v3(2.0f, 6.0f, 1.5f), 1.8f);
    refl_view v = tu_refl_view(refl_v3(4.0f, 5.0f, 7.0f), refl_v3(0, 0.5f, 0), 200, 150);
    expect_agreement(s, &v, REFL__SHADOW_AUTO, "box, point light", 300);
    refl_scene_destroy(s);
}

Test(refl_shadow, box_over_floor_directional_light_agrees_with_raytrace) {
    refl_scene *s = box_scene(REFL_LIGHT_DIRECTIONAL, refl_v3(-0.4f, -1.0f, -0.5f), 1.8f);
    refl_view v = tu_refl_view(refl_v3(4.0f, 5.0f, 7.0f), refl_v3(0, 0.5f, 0), 200, 150);
    expect_agreement(s, &v, REFL__SHADOW_AUTO, "box, directional light", 200);
    refl_scene_destroy(s);
}

/* ---- z-pass and z-fail ------------------------------------------------------------- */

/* The lit masks of both countings: equal but for shadow-edge pixels (a
   differently lit 8-neighbour), where depth rounding decides. */
static void expect_same_masks(const refl_scene *s, const refl_view *v, const char *what) {
    refl_frame *f = render(s, v, REFL_DIRECT, 0, 2);
    rast_context *rc = context(2);
    refl_mat4 vp = view_proj(s, v);
    size_t n = (size_t)v->width * (size_t)v->height;
    uint8_t *a = (uint8_t *)malloc(n), *b = (uint8_t *)malloc(n);
    unsigned za = 0, zb = 0, bits = (1u << REFL__MIN(s->light_count, 8)) - 1u;
    long differ = 0, inner = 0, surface = 0;
    int x, y, dx, dy;
    refl__shadow_job job = {
        .rc = rc, .scene = s, .vp = vp, .eye = v->eye, .depth = f->depth, .width = v->width, .height = v->height};
    cr_assert(a && b);
    cr_assert_eq(refl__shadow_mask_mode(&job, a, REFL__SHADOW_ZPASS, &za), REFL_OK);
    cr_assert_eq(refl__shadow_mask_mode(&job, b, REFL__SHADOW_ZFAIL, &zb), REFL_OK);
    cr_assert_eq(za, 0u);
    cr_assert_eq(zb, bits);
    for (y = 0; y < v->height; ++y)
        for (x = 0; x < v->width; ++x) {
            size_t i = (size_t)y * (size_t)v->width + (size_t)x;
            int edge = 0;
            if (!(f->depth[i] < 1.0f)) continue;
            ++surface;
            if (((a[i] ^ b[i]) & bits) == 0) continue;
            ++differ;
            for (dy = -1; dy <= 1; ++dy)
                for (dx = -1; dx <= 1; ++dx) {
                    int nx = x + dx, ny = y + dy;
                    size_t j = (size_t)ny * (size_t)v->width + (size_t)nx;
                    if (nx >= 0 && ny >= 0 && nx < v->width && ny < v->height && f->depth[j] < 1.0f)
                        edge |= ((b[j] ^ b[i]) & bits) != 0;
                }
            inner += !edge;
        }
    cr_log_info("%s: z-pass and z-fail masks differ on %ld of %ld surface pixels, %ld of them off shadow edges",
                what, differ, surface, inner);
    cr_assert_eq(inner, 0, "%s: %ld pixels differ off shadow edges", what, inner);
    cr_assert(differ * 1000 <= surface, "%s: %ld of %ld pixels differ", what, differ, surface);
    free(a);
    free(b);
    rast_context_destroy(rc);
    refl_frame_destroy(f);
}

Test(refl_shadow, zpass_and_zfail_agree_when_the_eye_is_outside_every_volume) {
    refl_scene *s;
    refl_view v;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 320; v.height = 240;
    expect_same_masks(s, &v, "default");
    refl_scene_destroy(s);
    s = box_scene(REFL_LIGHT_POINT, refl_v3(2.0f, 6.0f, 1.5f), 1.8f);
    v = tu_refl_view(refl_v3(4.0f, 5.0f, 7.0f), refl_v3(0, 0.5f, 0), 200, 150);
    expect_same_masks(s, &v, "box, point light");
    refl_scene_destroy(s);
    s = box_scene(REFL_LIGHT_DIRECTIONAL, refl_v3(-0.4f, -1.0f, -0.5f), 1.8f);
    expect_same_masks(s, &v, "box, directional light");
    refl_scene_destroy(s);
}

/* The eye under a raised box, in its shadow, looking out over the floor:
   z-fail (which AUTO must pick) agrees with RAYTRACE; z-pass, which counts
   from the eye as if it were lit, inverts the box's shadow: it is known to
   be wrong there, which is why it is only taken when provably safe. */
Test(refl_shadow, eye_inside_a_shadow_volume_needs_zfail) {
    refl_scene *s;
    refl_view v = tu_refl_view(refl_v3(0.5f, 0.7f, -0.3f), refl_v3(1.5f, 0.0f, 0.9f), 200, 150);
    agreement wrong;
    int k;
    for (k = 0; k < 2; ++k) {
        s = k == 0 ? box_scene(REFL_LIGHT_POINT, refl_v3(0.4f, 9.0f, -0.3f), 3.0f)
                   : box_scene(REFL_LIGHT_DIRECTIONAL, refl_v3(0.02f, -1.0f, 0.01f), 3.0f);
        cr_assert_eq(expect_agreement(s, &v, REFL__SHADOW_AUTO, k ? "eye in a volume, auto, directional"
                                                                   : "eye in a volume, auto, point", 500),
                     1u, "AUTO must count the light with z-fail");
        expect_agreement(s, &v, REFL__SHADOW_ZFAIL, k ? "eye in a volume, z-fail, directional"
                                                       : "eye in a volume, z-fail, point", 500);
        wrong = against_raytrace(s, &v, REFL__SHADOW_ZPASS, "eye in a volume, z-pass (known wrong)", NULL);
        cr_log_info("eye in a volume, z-pass: %.3f%% agree (z-pass misses the volume the eye is in)",
                    100.0 * ratio(wrong.agree, wrong.pixels));
        cr_assert(ratio(wrong.agree, wrong.pixels) < 0.9, "z-pass was expected to fail here");
        refl_scene_destroy(s);
    }
}

/* ---- other projections: mirrored and oblique (PLANAR's mirrored cameras) ------------- */

/* The depth of the scene drawn with any view-projection. */
static float *depth_with(const refl_scene *s, refl_mat4 vp, int w, int h) {
    float *depth = (float *)malloc((size_t)w * (size_t)h * sizeof(float));
    uint8_t *color = (uint8_t *)malloc((size_t)w * (size_t)h * 4), *stencil = (uint8_t *)malloc((size_t)w * (size_t)h);
    rast_context *rc = context(2);
    rast_targets t;
    rast_clear_desc c;
    refl_stats st;
    cr_assert(depth && color && stencil);
    memset(&t, 0, sizeof t);
    t.color.ptr = color; t.color.width = w; t.color.height = h; t.color.stride = 4 * w;
    t.depth.ptr = depth; t.depth.width = w; t.depth.height = h; t.depth.stride = w * (int)sizeof(float);
    t.stencil.ptr = stencil; t.stencil.width = w; t.stencil.height = h; t.stencil.stride = w;
    memset(&c, 0, sizeof c);
    c.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL;
    c.depth = 1.0f;
    memset(&st, 0, sizeof st);
    cr_assert_eq(rast_set_targets(rc, &t), RAST_OK);
    cr_assert_eq(rast_clear(rc, &c), RAST_OK);
    cr_assert_eq(refl__draw_scene(rc, s, vp, -1, &st), REFL_OK);
    rast_context_destroy(rc);
    free(color);
    free(stencil);
    return depth;
}

static uint8_t *mask_with(const refl_scene *s, refl_mat4 vp, refl_vec3 eye, const float *depth, int w, int h,
                          refl__shadow_mode mode, unsigned *zfail) {
    uint8_t *lit = (uint8_t *)malloc((size_t)w * (size_t)h);
    rast_context *rc = context(3);
    cr_assert_not_null(lit);
    refl__shadow_job job = {.rc = rc, .scene = s, .vp = vp, .eye = eye, .depth = depth, .width = w, .height = h};
    cr_assert_eq(refl__shadow_mask_mode(&job, lit, mode, zfail), REFL_OK);
    rast_context_destroy(rc);
    return lit;
}

/* A camera on the scene's plane of symmetry x = 0 seen through the mirror
   x -> -x: vp * M is the screen flipped, and every triangle's winding with
   it, so the masks must be each other's mirror image. */
Test(refl_shadow, a_mirrored_projection_gives_the_mirrored_mask) {
    refl_scene *s;
    refl_view v;
    refl_mat4 vp, vpm;
    int w = 240, h = 180, x, y, mode;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = w; v.height = h;
    cr_assert(v.eye.x == 0.0f && v.target.x == 0.0f);
    vp = view_proj(s, &v);
    vpm = refl_mat4_mul(vp, refl_mat4_scale(refl_v3(-1, 1, 1)));
    for (mode = REFL__SHADOW_ZPASS; mode <= REFL__SHADOW_ZFAIL; ++mode) {
        float *d = depth_with(s, vp, w, h), *dm = depth_with(s, vpm, w, h);
        uint8_t *a = mask_with(s, vp, v.eye, d, w, h, (refl__shadow_mode)mode, NULL);
        uint8_t *b = mask_with(s, vpm, v.eye, dm, w, h, (refl__shadow_mode)mode, NULL);
        long surface = 0, same = 0, shadowed = 0;
        for (y = 0; y < h; ++y)
            for (x = 0; x < w; ++x) {
                size_t i = (size_t)y * (size_t)w + (size_t)x, j = (size_t)y * (size_t)w + (size_t)(w - 1 - x);
                if (!(d[i] < 1.0f) || !(dm[j] < 1.0f)) continue;
                ++surface;
                same += (a[i] & 3) == (b[j] & 3);
                shadowed += (a[i] & 3) != 3;
            }
        cr_log_info("mirrored projection, %s: %ld of %ld pixels the same (%ld shadowed)",
                    mode == REFL__SHADOW_ZPASS ? "z-pass" : "z-fail", same, surface, shadowed);
        cr_assert(shadowed > 1000);
        cr_assert(ratio(same, surface) >= 0.998, "mirrored: %ld of %ld the same", same, surface);
        free(d); free(dm); free(a); free(b);
    }
    refl_scene_destroy(s);
}

/* Lengyel's oblique near plane: the projection's near plane replaced by a
   world plane (kept side: n . x > k), as PLANAR clips a mirrored view at
   its mirror. */
static refl_mat4 oblique(refl_mat4 view_m, refl_mat4 proj, refl_vec3 n, float k) {
    refl_mat4 inv, p = proj;
    double c[4], q[4], dot, sc;
    int i;
    cr_assert(refl_mat4_invert(view_m, &inv));
    /* the plane in eye space: (n, -k) times the inverse view */
    for (i = 0; i < 4; ++i)
        c[i] = (double)n.x * inv.m[4 * i] + (double)n.y * inv.m[4 * i + 1] + (double)n.z * inv.m[4 * i + 2] -
               (double)k * inv.m[4 * i + 3];
    q[0] = ((c[0] > 0 ? 1.0 : -1.0) + proj.m[8]) / proj.m[0];
    q[1] = ((c[1] > 0 ? 1.0 : -1.0) + proj.m[9]) / proj.m[5];
    q[2] = -1.0;
    q[3] = (1.0 + proj.m[10]) / proj.m[14];
    dot = c[0] * q[0] + c[1] * q[1] + c[2] * q[2] + c[3] * q[3];
    sc = 2.0 / dot;
    for (i = 0; i < 4; ++i) p.m[4 * i + 2] = (float)(c[i] * sc - proj.m[4 * i + 3]);
    return refl_mat4_mul(p, view_m);
}

/* The window depth a world point gets from vp. */
static double window_depth(refl_mat4 vp, const double p[3]) {
    double z = 0.0, w = 0.0;
    int k;
    for (k = 0; k < 3; ++k) {
        z += (double)vp.m[4 * k + 2] * p[k];
        w += (double)vp.m[4 * k + 3] * p[k];
    }
    z += vp.m[14];
    w += vp.m[15];
    return 0.5 * z / w + 0.5;
}

/* An oblique near plane through the occluding box (y = 1.8, keeping what
   lies below): the box's top is cut away in view and its shadow volume is
   clipped by the near plane, yet the floor's shadows stay where they are
   with z-fail (and with AUTO, which must choose it). */
Test(refl_shadow, an_oblique_near_plane_through_the_occluder_keeps_its_shadow) {
    refl_scene *s = box_scene(REFL_LIGHT_POINT, refl_v3(2.0f, 6.0f, 1.5f), 1.8f);
    refl_view v = tu_refl_view(refl_v3(4.0f, 5.0f, 7.0f), refl_v3(0, 0.5f, 0), 240, 180);
    refl_mat4 view_m, proj_m, vp, vpo;
    refl__view_rays rays;
    float *d, *dobl;
    uint8_t *ref, *obl, *auto_mask, *zpass;
    unsigned zf = 0;
    long floor_px = 0, same = 0, same_auto = 0, same_zpass = 0, shadowed = 0, revealed = 0;
    int x, y, w = v.width, h = v.height;
    refl_view_matrices(&v, s, &view_m, &proj_m);
    vp = refl_mat4_mul(proj_m, view_m);
    vpo = oblique(view_m, proj_m, refl_v3(0, -1, 0), -1.8f);
    refl__view_rays_init(&rays, &v, s);
    d = depth_with(s, vp, w, h);
    dobl = depth_with(s, vpo, w, h);
    ref = mask_with(s, vp, v.eye, d, w, h, REFL__SHADOW_ZFAIL, NULL);
    obl = mask_with(s, vpo, v.eye, dobl, w, h, REFL__SHADOW_ZFAIL, NULL);
    auto_mask = mask_with(s, vpo, v.eye, dobl, w, h, REFL__SHADOW_AUTO, &zf);
    zpass = mask_with(s, vpo, v.eye, dobl, w, h, REFL__SHADOW_ZPASS, NULL);
    cr_assert_eq(zf, 1u, "the near plane cuts the box: AUTO must count with z-fail");
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            refl_vec3 o, dir;
            float tmax;
            double t, p[3];
            int in_std, in_obl;
            refl__view_rays_get(&rays, (float)x + 0.5f, (float)y + 0.5f, &o, &dir, &tmax);
            if (!(dir.y < 0.0f)) continue;
            t = -(double)o.y / dir.y;
            p[0] = o.x + t * dir.x; p[1] = 0.0; p[2] = o.z + t * dir.z;
            if (fabs(p[0]) > 5.9 || fabs(p[2]) > 5.9) continue;
            /* the floor, seen in both views */
            in_std = fabs(d[i] - window_depth(vp, p)) < 2e-6;
            in_obl = fabs(dobl[i] - window_depth(vpo, p)) < 2e-6;
            revealed += in_obl && !in_std;
            if (!in_std || !in_obl) continue;
            ++floor_px;
            shadowed += !(ref[i] & 1);
            same += (ref[i] & 1) == (obl[i] & 1);
            same_auto += (ref[i] & 1) == (auto_mask[i] & 1);
            same_zpass += (ref[i] & 1) == (zpass[i] & 1);
        }
    cr_log_info("oblique near plane: %ld floor pixels in both views (%ld shadowed), the same with z-fail %ld, "
                "auto %ld, z-pass %ld (known wrong: the volume is cut by the near plane); %ld floor pixels revealed "
                "by the cut",
                floor_px, shadowed, same, same_auto, same_zpass, revealed);
    cr_assert(floor_px > 10000 && shadowed > 300 && revealed > 50);
    cr_assert(ratio(same, floor_px) >= 0.998, "oblique, z-fail: %ld of %ld", same, floor_px);
    cr_assert_eq(same_auto, same);
    free(d); free(dobl); free(ref); free(obl); free(auto_mask); free(zpass);
    refl_scene_destroy(s);
}

/* ---- the API's promises --------------------------------------------------------------- */

/* Only the region's pixels change; the restore targets end up bound; lit
   bits past the lights read as lit. */
Test(refl_shadow, region_restore_and_bits) {
    refl_scene *s;
    refl_view v;
    refl_frame *f;
    rast_context *rc = context(2);
    rast_targets t;
    refl_mat4 vp;
    uint8_t *full, *part, *region;
    size_t i, n;
    const float red[4] = {1, 0, 0, 1};
    rast_state st;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 160; v.height = 120;
    n = (size_t)v.width * (size_t)v.height;
    f = render(s, &v, REFL_DIRECT, 0, 2);
    t = frame_targets(f);
    vp = view_proj(s, &v);
    full = (uint8_t *)malloc(n);
    part = (uint8_t *)malloc(n);
    region = (uint8_t *)malloc(n);
    cr_assert(full && part && region);
    for (i = 0; i < n; ++i) region[i] = (uint8_t)(((i % 7) < 3) ? 5 : 1);
    memset(part, 0x5A, n);
    refl__shadow_job job = {
        .rc = rc, .scene = s, .vp = vp, .eye = v.eye, .depth = f->depth, .width = v.width, .height = v.height};
    cr_assert_eq(refl__shadow_mask(&job, full), REFL_OK);
    job.region = region;
    job.region_value = 5;
    job.restore = &t;
    cr_assert_eq(refl__shadow_mask(&job, part), REFL_OK);
    for (i = 0; i < n; ++i) {
        cr_assert_eq(part[i], region[i] == 5 ? full[i] : 0x5A, "pixel %zu", i);
        cr_assert_eq(full[i] & 0xFC, 0xFC, "bits past the two lights are set");
        if (!(f->depth[i] < 1.0f)) cr_assert_eq(full[i], 0xFF);
    }
    /* the frame is bound again: a rectangle lands in its colour */
    memset(&st, 0, sizeof st);
    cr_assert_eq(rast_set_state(rc, &st), RAST_OK);
    cr_assert_eq(rast_draw_fullscreen(rc, 0.0f, red), RAST_OK);
    cr_assert_eq(rast_finish(rc), RAST_OK);
    cr_assert(tu_unorm8(f->rgba[0]) == 255 && tu_unorm8(f->rgba[1]) == 0 && tu_unorm8(f->rgba[4 * n - 3]) == 0);
    free(full); free(part); free(region);
    rast_context_destroy(rc);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* DIRECT with shadows is the base pass plus refl__shadow_mask and
   refl__shade_lit; with no light blocked (nothing but a floor) it is the
   base pass byte for byte. */
Test(refl_shadow, direct_is_mask_plus_shade_and_unblocked_light_changes_nothing) {
    static const float grey[3] = {0.6f, 0.6f, 0.6f};
    refl_scene *s;
    refl_view v;
    refl_frame *a, *b;
    refl_mesh *plane;
    size_t n;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 160; v.height = 120;
    n = (size_t)v.width * (size_t)v.height;
    a = render(s, &v, REFL_DIRECT, 1, 2);
    b = direct_masked(s, &v, REFL__SHADOW_AUTO, NULL, NULL);
    cr_assert_eq(tu_first_diff(a->rgba, b->rgba, (4 * n) * sizeof(float)), -1);
    cr_assert_eq(tu_first_diff(a->depth, b->depth, sizeof(float) * n), -1);
    cr_assert_eq(tu_first_diff(a->stencil, b->stencil, n), -1);
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    refl_scene_destroy(s);
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_plane(10.0f, 4, NULL, &plane), REFL_OK);
    tu_refl_add_object(s, plane, REFL_DIFFUSE, grey, refl_mat4_identity());
    add_light(s, REFL_LIGHT_POINT, refl_v3(1, 5, 2), 0.8f);
    add_light(s, REFL_LIGHT_DIRECTIONAL, refl_v3(0.3f, -1, 0.2f), 0.3f);
    v = tu_refl_view(refl_v3(0, 4, 8), refl_v3(0, 0, 0), 160, 120);
    a = render(s, &v, REFL_DIRECT, 0, 2);
    b = render(s, &v, REFL_DIRECT, 1, 2);
    cr_assert_eq(tu_first_diff(a->rgba, b->rgba, (4 * n) * sizeof(float)), -1, "an unblocked light must change nothing");
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    refl_scene_destroy(s);
}

/* A partial reflector's diffuse share is shadowed as the base pass draws
   it: (1 - mirror_weight) times the shadowed diffuse colour, here against
   a diffuse floor of that much darker colour. */
Test(refl_shadow, partial_reflectors_keep_their_diffuse_share) {
    refl_scene *s;
    refl_view v = tu_refl_view(refl_v3(4.0f, 5.0f, 7.0f), refl_v3(0, 0.5f, 0), 160, 120);
    refl_frame *a, *b;
    size_t i, n = 160 * 120;
    long floor_px = 0, shadowed = 0;
    s = box_scene(REFL_LIGHT_POINT, refl_v3(2.0f, 6.0f, 1.5f), 1.8f);
    s->materials[0].type = REFL_PARTIAL;
    s->materials[0].mirror_weight = 0.5f;
    a = render(s, &v, REFL_DIRECT, 1, 2);
    b = render(s, &v, REFL_DIRECT, 0, 2);
    s->materials[0].type = REFL_DIFFUSE;
    s->materials[0].color[0] *= 0.5f; s->materials[0].color[1] *= 0.5f; s->materials[0].color[2] *= 0.5f;
    {
        refl_frame *c = render(s, &v, REFL_DIRECT, 1, 2);
        for (i = 0; i < n; ++i) {
            if (a->stencil[i] != 1) continue; /* the partial floor */
            ++floor_px;
            shadowed += channel_diff(a->rgba + 4 * i, b->rgba + 4 * i) > 0;
            cr_assert(channel_diff(a->rgba + 4 * i, c->rgba + 4 * i) <= 1, "pixel %zu", i);
        }
        refl_frame_destroy(c);
    }
    cr_assert(floor_px > 5000 && shadowed > 200, "%ld %ld", floor_px, shadowed);
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    refl_scene_destroy(s);
}

/* ---- threads, allocation, degenerate input --------------------------------------------- */

static void expect_same_frames(const refl_frame *a, const refl_frame *b, const char *what) {
    size_t n = (size_t)a->width * (size_t)a->height;
    cr_assert_eq(tu_first_diff(a->rgba, b->rgba, (4 * n) * sizeof(float)), -1, "%s: colour differs", what);
    cr_assert_eq(tu_first_diff(a->depth, b->depth, sizeof(float) * n), -1, "%s: depth differs", what);
    cr_assert_eq(tu_first_diff(a->stencil, b->stencil, n), -1, "%s: stencil differs", what);
}

Test(refl_shadow, same_bytes_for_every_thread_count) {
    int k, t, threads[] = {2, 3, 8};
    for (k = 0; k < 2; ++k) {
        refl_scene *s;
        refl_view v;
        refl_frame *one;
        if (k == 0) {
            cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
            v = s->camera;
        } else { /* z-fail */
            s = box_scene(REFL_LIGHT_POINT, refl_v3(0.4f, 9.0f, -0.3f), 3.0f);
            v = tu_refl_view(refl_v3(0.5f, 1.0f, -0.3f), refl_v3(1.5f, 0.0f, 0.9f), 0, 0);
        }
        v.width = 197; v.height = 131; /* tiles cut at odd places */
        one = render(s, &v, REFL_DIRECT, 1, 1);
        for (t = 0; t < 3; ++t) {
            refl_frame *other = render(s, &v, REFL_DIRECT, 1, threads[t]);
            char what[64];
            snprintf(what, sizeof what, "%s, %d threads", k ? "z-fail" : "default", threads[t]);
            expect_same_frames(one, other, what);
            refl_frame_destroy(other);
        }
        refl_frame_destroy(one);
        refl_scene_destroy(s);
    }
}

/* Every allocation DIRECT with shadows makes (occluder tables, volume
   arrays, the scratch stencil, the mask, rast's) can fail: each failure is
   OUT_OF_MEMORY and leaks nothing. Both countings. */
Test(refl_shadow, allocation_failure_at_every_allocation_leaks_nothing) {
    tu_alloc_counter c;
    refl_allocator al = tu_refl_counting(&c);
    int k;
    memset(&c, 0, sizeof c);
    for (k = 0; k < 2; ++k) {
        refl_scene *s;
        refl_view v;
        refl_frame *f;
        refl_render_desc d = tu_refl_desc(REFL_DIRECT, 2);
        long needed;
        if (k == 0) {
            refl_builtin_desc bd;
            memset(&bd, 0, sizeof bd);
            bd.allocator = al;
            bd.teapot_tess = 4;
            cr_assert_eq(refl_scene_builtin("default", &bd, &s), REFL_OK);
            v = s->camera;
        } else {
            s = box_scene_ex(REFL_LIGHT_POINT, refl_v3(0.4f, 9.0f, -0.3f), 3.0f, 0.5f, &al);
            v = tu_refl_view(refl_v3(0.5f, 1.0f, -0.3f), refl_v3(1.5f, 0.0f, 0.9f), 0, 0);
        }
        v.width = 24; v.height = 16;
        cr_assert_eq(refl_frame_create(24, 16, NULL, &f), REFL_OK);
        d.lighting.shadows = 1;
        needed = tu_refl_fail_each_render_allocation(s, &v, &d, f, &c);
        cr_assert(needed >= 5);
        cr_assert_eq(refl_render(s, &v, &d, f), REFL_OK);
        cr_log_info("allocation failure, %s: %ld allocations each failed once", k ? "z-fail" : "z-pass", needed);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
    cr_assert_eq(c.allocs, c.frees);
}

static void expect_sane(const refl_frame *f, const char *what) {
    size_t i, n = (size_t)f->width * (size_t)f->height;
    for (i = 0; i < n; ++i) cr_assert(f->depth[i] >= 0.0f && f->depth[i] <= 1.0f, "%s: depth %zu", what, i);
}

Test(refl_shadow, no_lights_changes_nothing) {
    refl_scene *s;
    refl_view v;
    refl_frame *a, *b;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    s->light_count = 0;
    v = s->camera;
    v.width = 120; v.height = 90;
    a = render(s, &v, REFL_DIRECT, 0, 2);
    b = render(s, &v, REFL_DIRECT, 1, 2);
    expect_same_frames(a, b, "no lights");
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    s->light_count = 2;
    refl_scene_destroy(s);
}

/* A point light inside a closed ball: everything outside it is in shadow
   (RAYTRACE's rays leave through the ball), which the volumes get from
   the ball's winding number around the light. */
Test(refl_shadow, light_inside_a_closed_object) {
    static const float white[3] = {0.9f, 0.9f, 0.9f};
    refl_scene *s = box_scene(REFL_LIGHT_POINT, refl_v3(-1.0f, 3.0f, 1.0f), 1.8f);
    refl_view v = tu_refl_view(refl_v3(4.0f, 5.0f, 7.0f), refl_v3(0, 0.5f, 0), 160, 120);
    refl_mesh *ball;
    refl_frame *f;
    refl__view_rays rays;
    uint8_t *lit;
    size_t i, n = 160 * 120;
    long surface = 0, dark = 0;
    cr_assert_eq(refl_mesh_sphere(0.6f, 16, 8, NULL, &ball), REFL_OK);
    tu_refl_add_object(s, ball, REFL_DIFFUSE, white, refl_mat4_translate(refl_v3(-1.0f, 3.0f, 1.0f)));
    expect_agreement(s, &v, REFL__SHADOW_AUTO, "light inside a ball", 5000);
    f = direct_masked(s, &v, REFL__SHADOW_AUTO, NULL, &lit);
    refl__view_rays_init(&rays, &v, s);
    for (i = 0; i < n; ++i) {
        refl_vec3 o, dir, oc;
        float tmax, b, c;
        if (!(f->depth[i] < 1.0f)) continue;
        /* the ball itself is lit from within (on its outside, Lambert is 0) */
        refl__view_rays_get(&rays, (float)(i % 160) + 0.5f, (float)(i / 160) + 0.5f, &o, &dir, &tmax);
        oc = refl_v3_sub(o, refl_v3(-1.0f, 3.0f, 1.0f));
        b = refl_v3_dot(oc, dir);
        c = refl_v3_dot(oc, oc) - 0.62f * 0.62f;
        if (b * b - c >= 0.0f) continue;
        ++surface;
        dark += !(lit[i] & 1);
    }
    cr_assert(surface > 10000);
    cr_assert_eq(dark, surface, "everything seen but the ball is in its shadow (%ld of %ld)", dark, surface);
    expect_sane(f, "light inside");
    free(lit);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* Lights along faces: a light at infinity parallel to the box's sides (and
   to the floor), a light with no direction, one with no position. No
   crash, no NaN, and where RAYTRACE can say, the same shadows. */
Test(refl_shadow, degenerate_lights) {
    refl_view v = tu_refl_view(refl_v3(4.0f, 5.0f, 7.0f), refl_v3(0, 0.5f, 0), 160, 120);
    refl_scene *s = box_scene_ex(REFL_LIGHT_DIRECTIONAL, refl_v3(1.0f, -1.0f, 0.0f), 1.8f, 0.0f, NULL);
    refl_frame *a, *b;
    expect_agreement(s, &v, REFL__SHADOW_AUTO, "light along the box's faces", 100);
    expect_agreement(s, &v, REFL__SHADOW_ZFAIL, "light along the box's faces, z-fail", 100);
    s->lights[0].direction = refl_v3(1.0f, 0.0f, 0.3f); /* along the floor */
    against_raytrace(s, &v, REFL__SHADOW_AUTO, "light along the floor", NULL);
    a = direct_masked(s, &v, REFL__SHADOW_ZFAIL, NULL, NULL);
    expect_sane(a, "along the floor");
    refl_frame_destroy(a);
    s->lights[0].direction = refl_v3(0.0f, 0.0f, 0.0f);
    a = render(s, &v, REFL_DIRECT, 0, 2);
    b = render(s, &v, REFL_DIRECT, 1, 2);
    expect_same_frames(a, b, "no direction");
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    s->lights[0].type = REFL_LIGHT_POINT;
    s->lights[0].position = refl_v3(NAN, 1.0f, 0.0f); /* refused, naming the light */
    {
        refl_render_desc d;
        memset(&d, 0, sizeof d);
        d.lighting.shadows = 1;
        cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &a), REFL_OK);
        cr_assert_eq(refl_render(s, &v, &d, a), REFL_ERROR_INVALID_ARGUMENT);
        cr_assert(strstr(a->message, "light") != NULL, "%s", a->message);
        refl_frame_destroy(a);
    }
    s->lights[0].position = refl_v3(0.3f, 2.3f, -0.2f); /* on the box's top face */
    a = render(s, &v, REFL_DIRECT, 1, 2);
    expect_sane(a, "on a face");
    refl_frame_destroy(a);
    refl_scene_destroy(s);
}

/* Every built-in scene: open meshes (the mirror room's walls, the concave
   bowl, the teapots) block light from both sides, as RAYTRACE's rays see
   them; both countings. */
Test(refl_shadow, every_builtin_scene_agrees_with_raytrace) {
    const char *const *names = refl_builtin_names();
    int k, mode;
    for (k = 0; names[k]; ++k)
        for (mode = REFL__SHADOW_AUTO; mode <= REFL__SHADOW_ZFAIL; mode += 2) {
            refl_scene *s;
            refl_view v;
            char what[64];
            cr_assert_eq(refl_scene_builtin(names[k], NULL, &s), REFL_OK);
            v = s->camera;
            v.width = 160; v.height = 120;
            snprintf(what, sizeof what, "%s, %s", names[k], mode == REFL__SHADOW_AUTO ? "auto" : "z-fail");
            expect_agreement(s, &v, (refl__shadow_mode)mode, what, 100);
            refl_scene_destroy(s);
        }
}
