/* SBC past the first bounce (paper 003's reflection histories, section
   IV, and Fig. 20b's refraction through a bi-convex lens): two mirror
   spheres facing each other over a floor with diffuse boxes, a mirror
   sphere beside a large curved mirror, and a glass lens before a row of
   coloured boxes, against RAYTRACE at the same depth. Both record the last
   point along each reflector pixel's path (desc.points_last), so the error
   measures where a higher-order reflection lands, not where the second
   mirror is. Depth 1 must be what SBC drew before histories existed. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>
#include "../reflect.h"
#include "test_util.h"
#include "refl_test_util.h"

enum { W = 320, H = 240 };

static refl_render_desc desc_of(refl_method m, int depth, int threads) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.method = m;
    d.threads = threads;
    d.depth = depth;
    d.points_last = 1;
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
    s->materials[s->objects[o].material].texture = refl_scene_add_texture(s, 16, 16, texels) + 1;
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

/* Two mirror spheres (radius 0.8) facing each other across a gap of 0.5,
   a small yellow ball between them, above the boxes: each sphere shows
   the other, which shows the first again (histories A, B, AB, BA, ABA,
   BAB ...), and the ball hides parts of the second order behind it. */
static refl_scene *facing_mirrors(void) {
    refl_scene *s = boxes_scene();
    refl_mesh *a = NULL, *b = NULL, *ball = NULL;
    cr_assert_eq(refl_mesh_sphere(0.8f, 48, 24, NULL, &a), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(0.8f, 48, 24, NULL, &b), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(0.15f, 16, 8, NULL, &ball), REFL_OK);
    tu_refl_add_object(s, a, REFL_MIRROR, silver, refl_mat4_translate(refl_v3(-1.05f, 0.0f, 0.0f)));
    tu_refl_add_object(s, b, REFL_MIRROR, silver, refl_mat4_translate(refl_v3(1.05f, 0.0f, 0.0f)));
    tu_refl_add_object(s, ball, REFL_DIFFUSE, yellow, refl_mat4_translate(refl_v3(0.0f, 0.1f, 0.3f)));
    return s;
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

/* Renders SBC and RAYTRACE at `depth`; checks SBC's frame is well formed
   (DIRECT's bytes off the reflectors, no NaN colour) and returns its error
   and stats; with mirrors (n > 0), *higher gets the error over the pixels
   whose first reflected ray meets a mirror (keep_higher). */
static refl_reflection_error sbc_error(const refl_scene *s, const refl_view *v, int depth, const char *what,
                                       refl_stats *stats, const mirror_sphere *m, int n,
                                       refl_reflection_error *higher) {
    refl_render_desc d = desc_of(REFL_SBC, getenv("SBC_DEPTH") ? atoi(getenv("SBC_DEPTH")) : depth, 2), t = desc_of(REFL_RAYTRACE, depth, 2);
    refl_render_desc dd = desc_of(REFL_DIRECT, depth, 2);
    refl_frame *f = tu_refl_render(s, v, &d), *truth = tu_refl_render(s, v, &t), *direct = tu_refl_render(s, v, &dd);
    refl_reflection_error e;
    if (getenv("SBC_DUMP")) { /* DEBUG */
        char fn[256]; int k, i; refl_frame *fs[2]; fs[0] = f; fs[1] = truth;
        for (k = 0; k < 2; ++k) { FILE *fp; snprintf(fn, sizeof fn, "/tmp/hx/%s_%d_%s.ppm", what, depth, k ? "rt" : "sbc");
          fp = fopen(fn, "wb"); fprintf(fp, "P6 %d %d 255\n", v->width, v->height);
          for (i = 0; i < v->width * v->height; ++i) fwrite(fs[k]->color + 4 * i, 1, 3, fp);
          fclose(fp); }
    }
    tu_assert_reflector_frame(f, direct);
    cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, &e), REFL_OK);
    cr_log_info("SBC %s depth %d %dx%d: mean %.2f p95 %.2f max %.1f px, wrong %.3f, holes %.3f over %lld pixels; "
                "%d histories, %d groups, %lld pinhole and %lld ray-list leaves",
                what, depth, v->width, v->height, e.mean, e.p95, e.max, e.wrong, e.empty, e.pixels,
                f->stats.histories, f->stats.groups, f->stats.cameras, f->stats.leaves);
    if (n) {
        refl_render_desc t1 = desc_of(REFL_RAYTRACE, 1, 2);
        refl_frame *first = tu_refl_render(s, v, &t1);
        long kept = keep_higher(f, truth, first, m, n);
        cr_assert_eq(refl_measure_reflection_error(f, truth, NULL, higher), REFL_OK);
        cr_log_info("  of those, the %ld pixels whose first reflection meets a mirror: mean %.2f p95 %.2f max %.1f px, "
                    "wrong %.3f, holes %.3f", kept, higher->mean, higher->p95, higher->max, higher->wrong, higher->empty);
        cr_assert(kept > 100, "%s: %ld higher-order pixels", what, kept);
        refl_frame_destroy(first);
    }
    if (stats) *stats = f->stats;
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_frame_destroy(direct);
    return e;
}

static void assert_error(refl_reflection_error e, double mean, double p95, double max, double wrong, double holes,
                         const char *what) {
    cr_assert(e.pixels > 500, "%s: %lld reflector pixels", what, e.pixels);
    cr_assert(e.mean <= mean && e.p95 <= p95 && e.max <= max, "%s: mean %.2f p95 %.2f max %.1f px", what, e.mean,
              e.p95, e.max);
    cr_assert(e.wrong <= wrong && e.empty <= holes, "%s: wrong %.3f holes %.3f", what, e.wrong, e.empty);
}

static refl_view facing_view(void) {
    return tu_refl_view(refl_v3(0.0f, 0.35f, 3.0f), refl_v3(0.0f, 0.0f, 0.0f), W, H);
}

static const mirror_sphere facing_spheres[2] = {{{-1.05f, 0.0f, 0.0f}, 0.8f}, {{1.05f, 0.0f, 0.0f}, 0.8f}};

Test(sbc_higher, facing_mirrors_depth_2, .timeout = 120) {
    refl_scene *s = facing_mirrors();
    refl_view v = facing_view();
    refl_stats st;
    refl_reflection_error h, e = sbc_error(s, &v, 2, "facing mirrors", &st, facing_spheres, 2, &h);
    cr_assert_eq(st.histories, 4, "A, B, AB, BA: %d", st.histories);
    assert_error(e, 100, 100, 1000, 1, 1, "facing mirrors, depth 2");
    assert_error(h, 100, 100, 1000, 1, 1, "facing mirrors, depth 2, higher orders");
    refl_scene_destroy(s);
}

Test(sbc_higher, facing_mirrors_depth_3, .timeout = 120) {
    refl_scene *s = facing_mirrors();
    refl_view v = facing_view();
    refl_stats st;
    refl_reflection_error h, e = sbc_error(s, &v, 3, "facing mirrors", &st, facing_spheres, 2, &h);
    cr_assert_eq(st.histories, 6, "A, B, AB, BA, ABA, BAB: %d", st.histories);
    assert_error(e, 100, 100, 1000, 1, 1, "facing mirrors, depth 3");
    assert_error(h, 100, 100, 1000, 1, 1, "facing mirrors, depth 3, higher orders");
    refl_scene_destroy(s);
}

/* A small mirror sphere beside a large one: each shows the other (AB and
   BA), the large one much magnified in the small. */
Test(sbc_higher, sphere_beside_curved_mirror, .timeout = 120) {
    refl_scene *s = boxes_scene();
    refl_mesh *a = NULL, *big = NULL;
    refl_view v = tu_refl_view(refl_v3(0.6f, 0.6f, 4.2f), refl_v3(0.0f, 0.0f, -0.6f), W, H);
    refl_stats st;
    refl_reflection_error e, h;
    static const mirror_sphere spheres[2] = {{{1.0f, -0.4f, 0.0f}, 0.6f}, {{-0.9f, 0.5f, -1.6f}, 1.5f}};
    cr_assert_eq(refl_mesh_sphere(spheres[0].r, 48, 24, NULL, &a), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(spheres[1].r, 96, 48, NULL, &big), REFL_OK);
    tu_refl_add_object(s, a, REFL_MIRROR, silver, refl_mat4_translate(spheres[0].c));
    tu_refl_add_object(s, big, REFL_MIRROR, silver, refl_mat4_translate(spheres[1].c));
    e = sbc_error(s, &v, 2, "sphere beside a curved mirror", &st, spheres, 2, &h);
    cr_assert_eq(st.histories, 4, "A, B, AB, BA: %d", st.histories);
    assert_error(e, 100, 100, 1000, 1, 1, "sphere beside a curved mirror");
    assert_error(h, 100, 100, 1000, 1, 1, "sphere beside a curved mirror, higher orders");
    refl_scene_destroy(s);
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

Test(sbc_higher, glass_lens, .timeout = 120) {
    refl_scene *s = lens_scene();
    refl_view v = lens_view();
    refl_stats st;
    refl_reflection_error e = sbc_error(s, &v, 2, "lens", &st, NULL, 0, NULL);
    cr_assert_eq(st.histories, 2, "the lens's front and its refraction: %d", st.histories);
    assert_error(e, 100, 100, 1000, 1, 1, "lens");
    refl_scene_destroy(s);
}
