/* SBC past the first bounce (paper 003's reflection histories, section
   IV, and Fig. 20b's refraction through a bi-convex lens): two mirror
   spheres facing each other over a floor with diffuse boxes, a mirror
   sphere beside a large curved mirror, and a glass lens before a row of
   coloured boxes, against RAYTRACE at the same depth. Both record the last
   point along each reflector pixel's path (desc.debug.points_last), so the error
   measures where a higher-order reflection lands, not where the second
   mirror is. Depth 1 must be what SBC drew before histories existed. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

enum { W = 320, H = 240 };

static refl_render_desc desc_of(refl_method m, int depth, int threads) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = m;
    d.threads = threads;
    d.depth = depth;
    d.debug.points_last = 1;
    return d;
}

static const float grey[3] = {0.6f, 0.6f, 0.6f}, red[3] = {0.9f, 0.2f, 0.1f}, green[3] = {0.2f, 0.8f, 0.3f},
                   blue[3] = {0.2f, 0.3f, 0.9f}, yellow[3] = {0.9f, 0.8f, 0.2f}, silver[3] = {0.9f, 0.9f, 0.9f};

/* A checkered floor (16 x 16 squares over 12 x 12), the scene takes it. */
static void add_floor(refl_scene *s) {
    static float texels[16 * 16 * 4];
    refl_mesh *floor = NULL;
    int k, o;
    for (k = 0; k < 16 * 16; ++k) {
        float c = ((k % 16) + (k / 16)) % 2 ? 1.0f : 0.35f;
        texels[4 * k] = texels[4 * k + 1] = texels[4 * k + 2] = c;
        texels[4 * k + 3] = 1.0f;
    }
    cr_assert_eq(refl_mesh_plane(12.0f, 8, NULL, &floor), REFL_OK);
    o = tu_refl_add_object(s, floor, REFL_DIFFUSE, grey, refl_mat4_translate(refl_v3(0, -1.0f, 0)));
    s->materials[s->objects[o].material].texture = refl_scene_add_texture(s, 16, 16, texels);
    cr_assert(s->materials[s->objects[o].material].texture > 0);
}

/* A floor, three boxes and a light: what the mirrors reflect. */
static refl_scene *boxes_scene(void) {
    refl_scene *s = NULL;
    refl_mesh *box[3] = {NULL, NULL, NULL};
    int k;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    for (k = 0; k < 3; ++k) cr_assert_eq(refl_mesh_box(refl_v3(0.7f, 1.0f + 0.4f * k, 0.7f), NULL, &box[k]), REFL_OK);
    add_floor(s);
    tu_refl_add_object(s, box[0], REFL_DIFFUSE, red, refl_mat4_translate(refl_v3(-0.2f, -0.5f, -2.2f)));
    tu_refl_add_object(s, box[1], REFL_DIFFUSE, green, refl_mat4_translate(refl_v3(-2.6f, -0.3f, -0.8f)));
    tu_refl_add_object(s, box[2], REFL_DIFFUSE, blue, refl_mat4_translate(refl_v3(2.6f, -0.1f, -1.0f)));
    tu_refl_add_point_light(s, refl_v3(3.0f, 5.0f, 4.0f), 1.0f, 0.0f);
    s->environment.color[0] = 0.3f;
    s->environment.color[1] = 0.5f;
    s->environment.color[2] = 0.8f;
    return s;
}

/* Two mirror spheres (radius 0.8) facing each other across a gap of 1,
   a low yellow block in the gap: each sphere shows the other, which shows
   the first again (histories A, B, AB, BA, ABA, BAB ...), and the block
   hides from each the other's lower half, whose reflection of the floor
   lies nearer that sphere than the block does to this one: only the
   visibility offset between orders keeps the block in front. */
static refl_scene *facing_mirrors(void) {
    refl_scene *s = boxes_scene();
    refl_mesh *a = NULL, *b = NULL, *block = NULL;
    cr_assert_eq(refl_mesh_sphere(0.8f, 48, 24, NULL, &a), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(0.8f, 48, 24, NULL, &b), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(0.15f, 0.5f, 0.8f), NULL, &block), REFL_OK);
    tu_refl_add_object(s, a, REFL_MIRROR, silver, refl_mat4_translate(refl_v3(-1.3f, 0.0f, 0.0f)));
    tu_refl_add_object(s, b, REFL_MIRROR, silver, refl_mat4_translate(refl_v3(1.3f, 0.0f, 0.0f)));
    tu_refl_add_object(s, block, REFL_DIFFUSE, yellow, refl_mat4_translate(refl_v3(0.45f, -0.5f, 0.0f)));
    return s;
}

/* The fraction of the pixels showing a point in `truth` (refl_frame.points
   finite) whose colour in f differs from truth's by more than 32 in some
   channel: where a wrong surface shows, or a right one wrongly weighed;
   *mean (may be NULL) the mean absolute difference over their channels. */
static double colour_off(const refl_frame *f, const refl_frame *truth, double *mean) {
    long n = 0, off = 0;
    double sum = 0.0;
    int i, c;
    for (i = 0; i < f->width * f->height; ++i) {
        int worst = 0;
        if (!(truth->points[3 * i] == truth->points[3 * i])) continue;
        for (c = 0; c < 3; ++c) {
            int d = abs((int)tu_unorm8(f->rgba[4 * i + c]) - (int)tu_unorm8(truth->rgba[4 * i + c]));
            worst = d > worst ? d : worst;
            sum += d;
        }
        ++n;
        off += worst > 32;
    }
    if (mean) *mean = n ? sum / (3.0 * (double)n) : 0.0;
    return n ? (double)off / (double)n : 0.0;
}


/* The mirror spheres of a scene: where a first reflection meets a mirror. */
typedef struct mirror_sphere {
    refl_vec3 c;
    float r;
} mirror_sphere;

/* Leaves in f (and truth) only the points of pixels whose first reflected
   ray meets one of the n mirror spheres (as RAYTRACE at depth 1 records
   it, in `first`): the higher-order reflections alone; their count. */
static long keep_higher(refl_frame *f, refl_frame *truth, const refl_frame *first, const mirror_sphere *m, int n) {
    long kept = 0;
    int i, k;
    for (i = 0; i < f->width * f->height; ++i) {
        const float *p = first->points + 3 * i;
        int on = 0;
        for (k = 0; k < n && p[0] == p[0]; ++k) {
            float dx = p[0] - m[k].c.x, dy = p[1] - m[k].c.y, dz = p[2] - m[k].c.z;
            on |= fabsf(sqrtf(dx * dx + dy * dy + dz * dz) - m[k].r) < 0.01f * m[k].r;
        }
        if (on) {
            ++kept;
            continue;
        }
        for (k = 0; k < 3; ++k) f->points[3 * i + k] = truth->points[3 * i + k] = NAN;
    }
    return kept;
}

/* What a case measures: SBC's error against RAYTRACE over every
   reflector pixel and over the higher-order ones (keep_higher), the
   fraction of each whose colour is off (colour_off), and SBC's stats. */
typedef struct sbc_case {
    refl_reflection_error all, higher;
    double colour, higher_colour, mean_diff, higher_mean_diff; /* mean_diff: colour_off's mean */
    long higher_pixels;
    refl_stats stats;
} sbc_case;

/* Renders SBC, RAYTRACE and DIRECT at `depth` (desc.debug.points_last =
   `last`); checks SBC's frame is well formed (DIRECT's bytes off the
   reflectors, points NaN in all three coordinates or none) and measures
   it; with mirrors (n > 0), the higher-order pixels too. */
static sbc_case run_case(const refl_scene *s, const refl_view *v, int depth, int last, const char *what,
                         const mirror_sphere *m, int n) {
    refl_render_desc d = desc_of(REFL_SBC, depth, 2), t = desc_of(REFL_RAYTRACE, depth, 2);
    refl_render_desc dd = desc_of(REFL_DIRECT, depth, 2);
    refl_frame *f, *truth, *direct;
    sbc_case c;
    memset(&c, 0, sizeof c);
    d.debug.points_last = t.debug.points_last = last;
    f = tu_refl_render(s, v, &d);
    truth = tu_refl_render(s, v, &t);
    direct = tu_refl_render(s, v, &dd);
    tu_assert_reflector_frame(f, direct);
    cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &c.all), REFL_OK);
    c.colour = colour_off(f, truth, &c.mean_diff);
    c.stats = f->stats;
    cr_log_info("SBC %s depth %d%s %dx%d: mean %.2f p95 %.2f max %.1f px, wrong %.3f, holes %.3f over %lld pixels, "
                "colour off %.3f (mean difference %.2f); %d histories, %d groups, %lld pinhole and %lld ray-list "
                "leaves", what, depth, last ? "" : " (first points)", v->width, v->height, c.all.mean, c.all.p95,
                c.all.max, c.all.wrong, c.all.empty, c.all.pixels, c.colour, c.mean_diff, f->stats.sbc.histories,
                f->stats.sbc.groups, f->stats.sbc.pinhole_leaves, f->stats.sbc.ray_leaves);
    if (n) {
        refl_render_desc t1 = desc_of(REFL_RAYTRACE, 1, 2);
        refl_frame *first = tu_refl_render(s, v, &t1);
        c.higher_pixels = keep_higher(f, truth, first, m, n);
        cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &c.higher), REFL_OK);
        c.higher_colour = colour_off(f, truth, &c.higher_mean_diff);
        cr_log_info("  of those, the %ld whose first reflection meets a mirror: mean %.2f p95 %.2f max %.1f px, "
                    "wrong %.3f, holes %.3f, colour off %.3f (mean difference %.2f)", c.higher_pixels,
                    c.higher.mean, c.higher.p95, c.higher.max, c.higher.wrong, c.higher.empty, c.higher_colour,
                    c.higher_mean_diff);
        refl_frame_destroy(first);
    }
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_frame_destroy(direct);
    return c;
}

/* Largest errors a case may show. */
typedef struct sbc_bounds {
    double mean, p95, max, wrong, holes, colour;
    double mean_diff;             /* past the first order: colour_off's mean */
} sbc_bounds;

static void assert_within(const refl_reflection_error *e, double colour, sbc_bounds b, const char *what) {
    cr_assert(e->pixels > 300, "%s: %lld pixels", what, e->pixels);
    cr_assert(e->mean <= b.mean && e->p95 <= b.p95 && e->max <= b.max, "%s: mean %.2f p95 %.2f max %.1f px", what,
              e->mean, e->p95, e->max);
    cr_assert(e->wrong <= b.wrong && e->empty <= b.holes, "%s: wrong %.3f holes %.3f", what, e->wrong, e->empty);
    cr_assert(colour <= b.colour, "%s: colour off at %.3f of the pixels", what, colour);
}

/* run_case over every reflector pixel, asserted within b (b.mean_diff:
   over every reflector pixel here); destroys s. */
static void check_case(refl_scene *s, const refl_view *v, int depth, int last, const char *what, sbc_bounds b) {
    sbc_case c = run_case(s, v, depth, last, what, NULL, 0);
    assert_within(&c.all, c.colour, b, what);
    cr_assert(c.mean_diff <= b.mean_diff, "%s: colours off by %.2f on average", what, c.mean_diff);
    refl_scene_destroy(s);
}

static refl_view facing_view(void) {
    return tu_refl_view(refl_v3(0.0f, 0.35f, 3.4f), refl_v3(0.0f, -0.1f, 0.0f), W, H);
}

static const mirror_sphere facing_spheres[2] = {{{-1.3f, 0.0f, 0.0f}, 0.8f}, {{1.3f, 0.0f, 0.0f}, 0.8f}};

/* run_case with the mirror spheres m: the number of histories sampled,
   and the errors over every reflector pixel and past the first order
   within their bounds; destroys s. */
static void check_higher(refl_scene *s, const refl_view *v, int depth, const mirror_sphere *m, int histories,
                         sbc_bounds all, sbc_bounds higher, const char *what) {
    sbc_case c = run_case(s, v, depth, 1, what, m, 2);
    cr_assert_eq(c.stats.sbc.histories, histories, "%s: %d histories", what, c.stats.sbc.histories);
    assert_within(&c.all, c.colour, all, what);
    assert_within(&c.higher, c.higher_colour, higher, what);
    cr_assert(c.higher_mean_diff <= higher.mean_diff, "%s: colours past the first order off by %.2f on average", what,
              c.higher_mean_diff);
    refl_scene_destroy(s);
}

/* Histories A, B, AB, BA. Measured: mean 0.07, p95 0, max 23.4 px, wrong
   0.000, holes 0.012, colour off 0.018; past the first order (820
   pixels): mean 0.11, p95 1.0, max 4.5 px, wrong 0.009, holes 0.026,
   colour off 0.087, mean colour difference 7.72 (holes 0.049 and colour
   off 0.099 before cracks were filled). */
Test(sbc_higher, facing_mirrors_depth_2, .timeout = 120) {
    refl_view v = facing_view();
    sbc_bounds all = {0.1, 1.0, 30, 0.005, 0.03, 0.035, 0}, higher = {0.2, 1.5, 8, 0.015, 0.07, 0.13, 10};
    check_higher(facing_mirrors(), &v, 2, facing_spheres, 4, all, higher, "facing mirrors");
}

/* ABA and BAB too. Measured: mean 0.06, p95 0, max 5.1 px, wrong 0.000,
   holes 0.013, colour off 0.018; past the first order: mean 0.14, p95
   1.0, max 4.5 px, wrong 0.000, holes 0.050, colour off 0.109, mean
   colour difference 9.61. */
Test(sbc_higher, facing_mirrors_depth_3, .timeout = 120) {
    refl_view v = facing_view();
    sbc_bounds all = {0.1, 1.0, 12, 0.005, 0.03, 0.035, 0}, higher = {0.2, 1.5, 8, 0.01, 0.11, 0.16, 12.5};
    check_higher(facing_mirrors(), &v, 3, facing_spheres, 6, all, higher, "facing mirrors");
}

/* Paper 003's surface properties on both mirrors (a Fresnel interval and
   a distance fade), each bounce weighed as RAYTRACE weighs it: the fade of
   a bounce by its own reflected ray's length. Measured: colour off 0.014,
   past the first order 0.044 and a mean colour difference of 3.13 (8.06
   when the first bounce's fade was left out of an order-2 pixel). */
Test(sbc_higher, facing_mirrors_surface_properties, .timeout = 120) {
    refl_scene *s = facing_mirrors();
    refl_view v = facing_view();
    sbc_bounds all = {0.1, 1.0, 30, 0.005, 0.03, 0.035, 0}, higher = {0.2, 1.5, 8, 0.015, 0.07, 0.06, 4.5};
    int k;
    for (k = 0; k < s->object_count; ++k) {
        refl_material *m = &s->materials[s->objects[k].material];
        if (m->type != REFL_MIRROR) continue;
        m->fresnel_min = 0.6f;
        m->fresnel_max = 1.0f;
        m->fade_distance = 3.0f;
        m->fade_min = 0.3f;
        m->fade_max = 1.0f;
    }
    check_higher(s, &v, 2, facing_spheres, 4, all, higher, "facing mirrors, surface properties");
}

/* The points as RAYTRACE records them by default: the first past the
   first reflector (on an order-2 path, the second mirror's surface), which
   tells apart the block (order 1) from the floor it hides (order 2).
   Measured: mean 0.06, p95 0, max 5.1 px, wrong 0.000, holes 0.011, colour
   off 0.017, mean colour difference 1.78. With the orders' offset (k - 1) g
   dropped from m_sbc.c's window depth: mean 0.39, max 104.4 px, wrong
   0.005, colour off 0.032. */
Test(sbc_higher, facing_mirrors_first_points, .timeout = 120) {
    refl_view v = facing_view();
    sbc_bounds all = {0.1, 1.0, 10, 0.003, 0.03, 0.03, 3};
    check_case(facing_mirrors(), &v, 2, 0, "facing mirrors, first points", all);
}

/* A small mirror sphere beside a large one: each shows the other (AB and
   BA), the large one much magnified in the small. */
Test(sbc_higher, sphere_beside_curved_mirror, .timeout = 120) {
    refl_scene *s = boxes_scene();
    refl_mesh *a = NULL, *big = NULL;
    refl_view v = tu_refl_view(refl_v3(0.6f, 0.6f, 4.2f), refl_v3(0.0f, 0.0f, -0.6f), W, H);
    static const mirror_sphere spheres[2] = {{{1.0f, -0.4f, 0.0f}, 0.6f}, {{-0.9f, 0.5f, -1.6f}, 1.5f}};
    /* measured: mean 0.07, p95 0, max 11.4 px, wrong 0.001, holes 0.013,
       colour off 0.022; past the first order (885 pixels): mean 0.22, p95
       1.41, max 8.0 px (5.7 before cracks were filled: a crack there takes
       a neighbour's point 8 px away), wrong 0.017, holes 0.049, colour off
       0.081, mean colour difference 8.36 */
    sbc_bounds all = {0.1, 1.0, 16, 0.005, 0.03, 0.04, 0}, higher = {0.25, 2.0, 8, 0.02, 0.1, 0.13, 11};
    cr_assert_eq(refl_mesh_sphere(spheres[0].r, 48, 24, NULL, &a), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(spheres[1].r, 96, 48, NULL, &big), REFL_OK);
    tu_refl_add_object(s, a, REFL_MIRROR, silver, refl_mat4_translate(spheres[0].c));
    tu_refl_add_object(s, big, REFL_MIRROR, silver, refl_mat4_translate(spheres[1].c));
    check_higher(s, &v, 2, spheres, 4, all, higher, "sphere beside a curved mirror");
}

/* A bi-convex lens: two caps of spheres of radius 1.6 meeting at a rim of
   radius 0.75 (0.38 thick), built here from its two caps (the rim's
   vertices repeated, so each cap keeps its own normals). */
static refl_mesh *lens_mesh(float radius, float rim, int rings, int slices) {
    int nv = 2 * (1 + rings * slices), nt = 2 * (slices + 2 * slices * (rings - 1)), cap, r, k, v = 0, t = 0;
    float *pos = (float *)malloc((size_t)nv * 3 * sizeof(float)), *nrm = (float *)malloc((size_t)nv * 3 * sizeof(float));
    uint32_t *idx = (uint32_t *)malloc((size_t)nt * 3 * sizeof(uint32_t));
    float half = asinf(rim / radius), sag = radius - sqrtf(radius * radius - rim * rim);
    refl_mesh_desc d;
    refl_mesh *m = NULL;
    cr_assert(pos && nrm && idx);
    for (cap = 0; cap < 2; ++cap) {
        float sz = cap ? -1.0f : 1.0f; /* the front cap bulges to +z, the back to -z */
        int base = v;
        /* its centre lies behind the rim plane by radius - sag */
        float cz = -sz * (radius - sag);
        pos[3 * v] = 0.0f; pos[3 * v + 1] = 0.0f; pos[3 * v + 2] = cz + sz * radius;
        nrm[3 * v] = 0.0f; nrm[3 * v + 1] = 0.0f; nrm[3 * v + 2] = sz;
        ++v;
        for (r = 1; r <= rings; ++r) {
            float a = half * (float)r / (float)rings;
            for (k = 0; k < slices; ++k) {
                float phi = 6.2831853f * (float)k / (float)slices;
                float nx = sinf(a) * cosf(phi), ny = sinf(a) * sinf(phi), nz = sz * cosf(a);
                pos[3 * v] = radius * nx; pos[3 * v + 1] = radius * ny; pos[3 * v + 2] = cz + radius * nz;
                nrm[3 * v] = nx; nrm[3 * v + 1] = ny; nrm[3 * v + 2] = nz;
                ++v;
            }
        }
        /* counter-clockwise seen from outside: along +z for the front cap */
        for (k = 0; k < slices; ++k) {
            uint32_t a0 = (uint32_t)(base + 1 + k), a1 = (uint32_t)(base + 1 + (k + 1) % slices);
            idx[3 * t] = (uint32_t)base;
            idx[3 * t + 1] = cap ? a1 : a0;
            idx[3 * t + 2] = cap ? a0 : a1;
            ++t;
        }
        for (r = 1; r < rings; ++r)
            for (k = 0; k < slices; ++k) {
                uint32_t i0 = (uint32_t)(base + 1 + (r - 1) * slices + k);
                uint32_t i1 = (uint32_t)(base + 1 + (r - 1) * slices + (k + 1) % slices);
                uint32_t j0 = i0 + (uint32_t)slices, j1 = i1 + (uint32_t)slices;
                uint32_t q[6];
                int e;
                q[0] = i0; q[1] = j0; q[2] = j1; q[3] = i0; q[4] = j1; q[5] = i1;
                if (cap) { q[1] = j1; q[2] = j0; q[4] = i1; q[5] = j1; }
                for (e = 0; e < 6; ++e) idx[3 * t + e] = q[e];
                t += 2;
            }
    }
    cr_assert_eq(v, nv);
    cr_assert_eq(t, nt);
    memset(&d, 0, sizeof d);
    d.positions = pos;
    d.normals = nrm;
    d.indices = idx;
    d.vertex_count = nv;
    d.index_count = 3 * nt;
    cr_assert_eq(refl_mesh_create(&d, &m), REFL_OK);
    free(pos);
    free(nrm);
    free(idx);
    return m;
}

/* The lens before a row of coloured boxes on a floor. */
static refl_scene *lens_scene(void) {
    refl_scene *s = NULL;
    refl_mesh *box[4] = {NULL, NULL, NULL, NULL};
    refl_material glass;
    refl_object o;
    const float *colors[4] = {red, green, blue, yellow};
    int k;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    add_floor(s);
    for (k = 0; k < 4; ++k) {
        cr_assert_eq(refl_mesh_box(refl_v3(0.35f, 0.9f + 0.3f * (float)k, 0.35f), NULL, &box[k]), REFL_OK);
        tu_refl_add_object(s, box[k], REFL_DIFFUSE, colors[k],
                           refl_mat4_translate(refl_v3(-0.75f + 0.5f * (float)k, -0.5f, -1.6f)));
    }
    memset(&glass, 0, sizeof glass);
    glass.type = REFL_GLASS;
    glass.color[0] = glass.color[1] = glass.color[2] = glass.color[3] = 1.0f;
    glass.ior = 1.5f;
    memset(&o, 0, sizeof o);
    o.mesh = refl_scene_add_mesh(s, lens_mesh(2.5f, 0.8f, 12, 48));
    o.material = refl_scene_add_material(s, &glass);
    o.transform = refl_mat4_translate(refl_v3(0.0f, 0.0f, 0.0f));
    cr_assert(refl_scene_add_object(s, &o) >= 0);
    tu_refl_add_point_light(s, refl_v3(2.0f, 4.0f, 4.0f), 1.0f, 0.0f);
    s->environment.color[0] = 0.3f;
    s->environment.color[1] = 0.5f;
    s->environment.color[2] = 0.8f;
    return s;
}

static refl_view lens_view(void) {
    return tu_refl_view(refl_v3(0.2f, 0.3f, 3.6f), refl_v3(0.0f, -0.1f, 0.0f), W, H);
}

/* RAYTRACE's points_last: the same colours and, where the first reflection
   meets no mirror, the same points as the first points; where it meets
   one, a point off that mirror (the last along the path) or none. */
Test(sbc_higher, raytrace_points_last, .timeout = 120) {
    refl_scene *s = facing_mirrors();
    refl_view v = facing_view();
    refl_render_desc first = desc_of(REFL_RAYTRACE, 2, 2), last = desc_of(REFL_RAYTRACE, 2, 2);
    refl_frame *a, *b;
    long on = 0, moved = 0;
    int i, k;
    first.debug.points_last = 0;
    a = tu_refl_render(s, &v, &first);
    b = tu_refl_render(s, &v, &last);
    cr_assert_eq(memcmp(a->rgba, b->rgba, 4 * sizeof(float) * (size_t)W * H), 0);
    for (i = 0; i < W * H; ++i) {
        const float *p = a->points + 3 * i, *q = b->points + 3 * i;
        int on_mirror = 0;
        for (k = 0; k < 2 && p[0] == p[0]; ++k) {
            float dx = p[0] - facing_spheres[k].c.x, dy = p[1] - facing_spheres[k].c.y, dz = p[2] - facing_spheres[k].c.z;
            on_mirror |= fabsf(sqrtf(dx * dx + dy * dy + dz * dz) - facing_spheres[k].r) < 0.01f * facing_spheres[k].r;
        }
        if (!on_mirror) {
            cr_assert(memcmp(p, q, 3 * sizeof(float)) == 0 || (p[0] != p[0] && q[0] != q[0]), "pixel %d", i);
            continue;
        }
        ++on;
        moved += memcmp(p, q, 3 * sizeof(float)) != 0;
    }
    cr_assert(on > 100 && moved == on, "%ld of %ld second-mirror points moved on", moved, on);
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    refl_scene_destroy(s);
}

/* Counts the first-order sides SBC reports (refl_render_desc.debug.sbc_ray_map). */
static void count_side(void *user, int object, const refl_sbc_ray *rays, const uint8_t *valid, int w, int h) {
    (void)object;
    (void)rays;
    (void)valid;
    (void)w;
    (void)h;
    ++*(int *)user;
}

/* Depth 2: in at the front cap, out at the back (Snell with ior 1.5),
   every sample's path one refraction history; the boxes seen through the
   lens (upright, magnified: inside the focal length) drawn as a group of
   their own and weighed by (1 - F) at both faces. */
Test(sbc_higher, glass_lens, .timeout = 120) {
    refl_scene *s = lens_scene();
    refl_view v = lens_view();
    refl_render_desc d = desc_of(REFL_SBC, 2, 2);
    refl_frame *f;
    /* measured: mean 0.08, p95 0, max 25.0 px, wrong 0.003, holes 0.039,
       colour off 0.050, mean colour difference 3.57 */
    sbc_bounds all = {0.15, 1.0, 35, 0.006, 0.05, 0.07, 4.5};
    sbc_case c = run_case(s, &v, 2, 1, "lens", NULL, 0);
    int sides = 0;
    d.debug.sbc_ray_map = count_side;
    d.debug.sbc_ray_map_user = &sides;
    f = tu_refl_render(s, &v, &d);
    cr_assert(sides >= 1);
    cr_assert_eq(c.stats.sbc.histories, sides + 1, "%d first-order sides and one refraction: %d histories", sides,
                 c.stats.sbc.histories);
    assert_within(&c.all, c.colour, all, "lens, depth 2");
    cr_assert(c.mean_diff <= all.mean_diff, "lens: colours off by %.2f on average", c.mean_diff);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* Depth 3: a ray totally reflected inside may still get out. */
Test(sbc_higher, glass_lens_depth_3, .timeout = 120) {
    refl_view v = lens_view();
    /* measured: the points as at depth 2 (no path here needs a third
       interface); mean colour difference 6.36: RAYTRACE now adds the
       reflections inside the lens that SBC leaves out */
    sbc_bounds all = {0.15, 1.0, 35, 0.006, 0.05, 0.07, 8};
    check_case(lens_scene(), &v, 3, 1, "lens", all);
}

static void assert_same_frames(const refl_frame *a, const refl_frame *b, const char *what) {
    size_t n = (size_t)a->width * (size_t)a->height;
    cr_assert_eq(memcmp(a->rgba, b->rgba, (4 * n) * sizeof(float)), 0, "%s: colours differ", what);
    cr_assert_eq(memcmp(a->points, b->points, 3 * n * sizeof(float)), 0, "%s: points differ", what);
}

/* The same bytes for 1 and 2 threads, past the first order and through
   glass. */
Test(sbc_higher, threads_same_bytes, .timeout = 120) {
    refl_scene *s = facing_mirrors(), *lens = lens_scene();
    refl_view v = facing_view(), lv = lens_view();
    refl_render_desc one = desc_of(REFL_SBC, 3, 1), two = desc_of(REFL_SBC, 3, 2);
    refl_frame *a = tu_refl_render(s, &v, &one), *b = tu_refl_render(s, &v, &two);
    assert_same_frames(a, b, "facing mirrors, depth 3");
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    a = tu_refl_render(lens, &lv, &one);
    b = tu_refl_render(lens, &lv, &two);
    assert_same_frames(a, b, "lens, depth 3");
    refl_frame_destroy(a);
    refl_frame_destroy(b);
    refl_scene_destroy(s);
    refl_scene_destroy(lens);
}

/* Where no path goes past its first mirror (one convex mirror, no glass),
   every depth draws what depth 1 draws, and depth 1 is the one-bounce SBC
   of before the histories (its frames' digests were compared across the
   change; see m_sbc.c). */
Test(sbc_higher, depth_1_unchanged, .timeout = 120) {
    refl_scene *s = boxes_scene();
    refl_mesh *a = NULL;
    refl_view v = facing_view();
    refl_render_desc d1 = desc_of(REFL_SBC, 1, 2), d6 = desc_of(REFL_SBC, 6, 2);
    refl_frame *f1, *f6;
    cr_assert_eq(refl_mesh_sphere(0.8f, 48, 24, NULL, &a), REFL_OK);
    tu_refl_add_object(s, a, REFL_MIRROR, silver, refl_mat4_identity());
    d1.debug.points_last = d6.debug.points_last = 0;
    f1 = tu_refl_render(s, &v, &d1);
    f6 = tu_refl_render(s, &v, &d6);
    cr_assert_eq(f6->stats.sbc.histories, 1);
    assert_same_frames(f1, f6, "one mirror, depth 1 and 6");
    refl_frame_destroy(f1);
    refl_frame_destroy(f6);
    refl_scene_destroy(s);
}

/* Built-in scene `name` at w x h rendered by SBC and by RAYTRACE at depth
   6, each recording the first point past the first reflector (as the
   frame does by default); the scene, to destroy. */
static refl_scene *sbc_and_truth_at_depth_6(const char *name, int w, int h, refl_frame **f, refl_frame **truth) {
    refl_view v;
    refl_scene *s = tu_refl_builtin(name, &v, w, h);
    refl_render_desc d = desc_of(REFL_SBC, 6, 2), t = desc_of(REFL_RAYTRACE, 6, 2);
    d.debug.points_last = t.debug.points_last = 0;
    *f = tu_refl_render(s, &v, &d);
    *truth = tu_refl_render(s, &v, &t);
    return s;
}

/* The concave bowl at depth 6: its outer rim is seen through more bounces
   than any ray map sample takes, so the last order sampled draws the bowl
   itself there (a mirror, transparent black). Its path goes on: those
   pixels go to RAYTRACE's tracer, and none is black where the truth is
   lit (they were, a dotted black arc along the rim). */
Test(sbc_higher, concave_rim_past_the_last_order_is_traced, .timeout = 120) {
    refl_frame *f, *truth;
    refl_scene *s = sbc_and_truth_at_depth_6("concave", 128, 96, &f, &truth);
    size_t i, n = (size_t)f->width * (size_t)f->height;
    long long black = 0;
    for (i = 0; i < n; ++i) {
        const float *a = f->rgba + 4 * i, *b = truth->rgba + 4 * i;
        black += truth->stencil[i] && a[0] + a[1] + a[2] < 0.01f && b[0] + b[1] + b[2] > 0.1f;
    }
    cr_assert_eq(black, 0, "%lld reflector pixels black where RAYTRACE's are lit", black);
    cr_assert(f->stats.sbc.traced > 0);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* mirror-room at depth 6: near the seams between the wall mirrors, high
   up, some pixels' last order drew nothing (holes) while their path's last
   reflected ray meets another wall, where RAYTRACE shows black (the depth
   runs out on a mirror). Such holes go to RAYTRACE's tracer instead of
   showing the sky along that ray (white specks along the seams: 88 pixels
   lit where the truth is black, PSNR 27.3 dB over the reflectors). */
Test(sbc_higher, mirror_room_seam_holes_follow_the_path, .timeout = 120) {
    refl_frame *f, *truth;
    refl_scene *s = sbc_and_truth_at_depth_6("mirror-room", 128, 96, &f, &truth);
    refl_image_error img;
    size_t i, n = (size_t)f->width * (size_t)f->height;
    long long lit = 0, reflector = 0;
    for (i = 0; i < n; ++i) {
        const float *a = f->rgba + 4 * i, *b = truth->rgba + 4 * i;
        reflector += truth->stencil[i] != 0;
        lit += truth->stencil[i] && b[0] + b[1] + b[2] < 0.01f && a[0] + a[1] + a[2] > 0.3f;
    }
    cr_assert_eq(refl_measure_image_error(f, truth, 1, 0.0f, &img), REFL_OK);
    cr_log_info("SBC mirror-room 128x96 depth 6: %lld of %lld reflector pixels lit where RAYTRACE's are black, "
                "PSNR %.2f dB, %lld traced", lit, reflector, img.psnr, f->stats.sbc.traced);
    cr_assert(lit * 500 <= reflector, "%lld of %lld reflector pixels lit where RAYTRACE's are black", lit, reflector);
    cr_assert(img.psnr >= 30.0, "PSNR %.2f dB", img.psnr);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* mirror-room at depth 6, in the corners: the neighbouring wall a hair
   away counts (the search skipped 1e-4 of the diagonal past the path's
   point), searched from the point of the triangle the pixel's view ray
   meets (the depth buffer's point lies up to ~7e-4 past the neighbouring
   wall). Without either, the path missed that wall and the pixel showed
   the environment where RAYTRACE's meets the wall. Measured at 160x120: 2
   such pixels. Where a wall mirror meets the floor, the floor a hair below
   the path's point is drawn by no group (a hole), and the hole's last
   reflected ray meets no mirror: it goes to the tracer too, as it meets a
   surface within two pixels' footprint (160x120: 4 pixels showed the
   environment there; 640x480: 16). */
Test(sbc_higher, mirror_room_corner_paths_meet_the_next_wall, .timeout = 120) {
    refl_frame *f, *truth;
    refl_scene *s = sbc_and_truth_at_depth_6("mirror-room", 160, 120, &f, &truth);
    size_t i, n = (size_t)f->width * (size_t)f->height;
    long long sky = 0, floor = 0;
    for (i = 0; i < n; ++i) { /* RAYTRACE's point on a wall or the floor, SBC's the environment */
        int env = truth->stencil[i] && f->stencil[i] && isnan(f->points[3 * i]) && !isnan(truth->points[3 * i]);
        sky += env && truth->points[3 * i + 1] > 1e-3f;
        floor += env && !(truth->points[3 * i + 1] > 1e-3f);
    }
    cr_assert_eq(sky, 0, "%lld reflector pixels show the environment where RAYTRACE meets a wall", sky);
    cr_assert_eq(floor, 0, "%lld reflector pixels show the environment where RAYTRACE meets the floor", floor);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* hybrid at depth 6: the glass teapot's refracted rays fold (its
   refraction groups have several sheets), and a reflected triangle that
   still bends by pixels at the last subdivision lies across a fold: drawn,
   its inside showed points that project elsewhere, in front of the true
   ones (the blue column behind the teapot a dark grey V of floor). Such
   triangles are left out and their pixels traced. Measured at 160x120
   over the glass's pixels: PSNR 17.4 dB drawing them, 20.6 dB without. */
Test(sbc_higher, hybrid_glass_drops_triangles_across_folds, .timeout = 120) {
    refl_frame *f, *truth;
    refl_scene *s = sbc_and_truth_at_depth_6("hybrid", 160, 120, &f, &truth);
    refl_image_error img;
    size_t i, n = (size_t)f->width * (size_t)f->height;
    long long glass = 0;
    for (i = 0; i < n; ++i) { /* the truth's stencil kept on the glass alone (object k - 1 at k) */
        int o = truth->stencil[i] - 1;
        if (o >= 0 && s->materials[s->objects[o].material].type != REFL_GLASS) truth->stencil[i] = 0;
        glass += truth->stencil[i] != 0;
    }
    cr_assert_eq(refl_measure_image_error(f, truth, 1, 0.0f, &img), REFL_OK);
    cr_log_info("SBC hybrid 160x120 depth 6: PSNR %.2f dB over %lld glass pixels", img.psnr, glass);
    cr_assert(glass > 1000);
    cr_assert(img.psnr >= 19.0, "PSNR %.2f dB over the glass", img.psnr);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* At one bounce SBC-traced hands glass to RAYTRACE's tracer (a ray
   refracted into glass cannot leave it within the depth): the glass
   pixels are RAYTRACE's at depth 1, bit for bit, not the environment
   refracted once; SBC-paper keeps drawing the glass itself. */
Test(sbc_higher, glass_at_one_bounce_goes_to_the_tracer) {
    refl_scene *s = NULL;
    refl_view v;
    refl_render_desc d = desc_of(REFL_SBC, 1, 0), t = desc_of(REFL_RAYTRACE, 1, 0), paper = desc_of(REFL_SBC, 1, 0);
    refl_frame *f, *truth, *pf;
    int i, glass = 0, shown = 0;
    cr_assert_eq(refl_scene_builtin("glass", NULL, &s), REFL_OK);
    v = s->camera;
    v.width = 96;
    v.height = 72;
    paper.sbc.mode = REFL_SBC_PAPER;
    for (i = 0; i < s->object_count; ++i) glass += s->materials[s->objects[i].material].type == REFL_GLASS;
    f = tu_refl_render(s, &v, &d);
    truth = tu_refl_render(s, &v, &t);
    pf = tu_refl_render(s, &v, &paper);
    cr_assert_eq(f->stats.handed_over, glass, "%d handed over of %d glass objects", f->stats.handed_over, glass);
    cr_assert_eq(pf->stats.handed_over, 0, "SBC-paper handed %d over", pf->stats.handed_over);
    shown = tu_assert_glass_as_truth(s, f, truth);
    cr_assert(shown > 100, "%d glass pixels", shown);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_frame_destroy(pf);
    refl_scene_destroy(s);
}
