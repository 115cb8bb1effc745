/* ENVMAP, the classic baseline: a cube map from each reflector's centre,
   looked up along the mirror (and refracted) direction. With nothing but
   the environment around a reflector the cube shows only the environment,
   so the method must agree with the environment looked up along the true
   reflected direction up to the cube's resolution; with scenery, each
   reflector pixel's point must be what the cube shows along its direction.
   Also: determinism across thread counts, the default scene, edge sizes,
   shared stencil ids and allocation failure. */
#include <criterion/criterion.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"


static const double PI = 3.14159265358979323846;

static int is_nan(float v) { return v != v; }

static refl_frame *render_with(const refl_scene *s, const refl_view *view, refl_method method, int threads,
                               int envmap_size) {
    refl_frame *f = NULL;
    refl_render_desc d;
    refl_result r;
    memset(&d, 0, sizeof d);
    d.method = method;
    d.threads = threads;
    d.envmap.size = envmap_size;
    d.depth = 1; /* ENVMAP's own pixels: past one bounce RAYTRACE's tracer colours them */
    cr_assert_eq(refl_frame_create(view->width, view->height, NULL, &f), REFL_OK);
    r = refl_render(s, view, &d, f);
    cr_assert_eq(r, REFL_OK, "refl_render: %s", refl_result_string(r));
    return f;
}

/* ---- environments ---------------------------------------------------------- */

/* Six constant faces of distinct colours, exact in 8 bits. */
static const float face_rgb[6][3] = {{1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}, {0.0f, 0.0f, 1.0f},
                                     {1.0f, 1.0f, 0.0f}, {0.0f, 1.0f, 1.0f}, {1.0f, 0.0f, 1.0f}};

static void set_face_env(refl_scene *s) {
    float px[6][4];
    refl_environment env;
    int f, c;
    memset(&env, 0, sizeof env);
    env.type = REFL_ENV_CUBE;
    for (f = 0; f < 6; ++f) {
        for (c = 0; c < 3; ++c) px[f][c] = face_rgb[f][c];
        px[f][3] = 1.0f;
        env.faces[f].width = env.faces[f].height = 1;
        env.faces[f].pixels = px[f];
    }
    cr_assert_eq(refl_scene_set_environment(s, &env), REFL_OK);
}

/* An equirectangular map whose colour varies smoothly with direction. */
static void set_smooth_env(refl_scene *s) {
    enum { W = 64, H = 32 };
    static float px[W * H * 4];
    refl_environment env;
    int i, j;
    for (j = 0; j < H; ++j)
        for (i = 0; i < W; ++i) {
            double lon = ((i + 0.5) / W - 0.5) * 2.0 * PI, lat = (j + 0.5) / H * PI;
            double x = sin(lat) * sin(lon), y = cos(lat), z = -sin(lat) * cos(lon);
            float *p = px + 4 * (j * W + i);
            p[0] = (float)(0.5 + 0.45 * x);
            p[1] = (float)(0.5 + 0.45 * y);
            p[2] = (float)(0.5 + 0.45 * z);
            p[3] = 1.0f;
        }
    memset(&env, 0, sizeof env);
    env.type = REFL_ENV_EQUIRECT;
    env.image.width = W;
    env.image.height = H;
    env.image.pixels = px;
    cr_assert_eq(refl_scene_set_environment(s, &env), REFL_OK);
}

/* A scene of one sphere of material m at the origin (and, when floor is
   set, a diffuse floor below it and a box beside it). */
static refl_scene *sphere_scene(const refl_material *m, int floor) {
    refl_scene *s;
    refl_mesh *mesh = NULL;
    refl_object o;
    int mi;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_sphere(1.0f, 64, 32, NULL, &mesh), REFL_OK);
    mi = refl_scene_add_mesh(s, mesh);
    memset(&o, 0, sizeof o);
    o.mesh = mi;
    o.material = refl_scene_add_material(s, m);
    o.transform = refl_mat4_identity();
    cr_assert_eq(refl_scene_add_object(s, &o), 0);
    if (floor) {
        refl_material d;
        memset(&d, 0, sizeof d);
        d.type = REFL_DIFFUSE;
        d.color[0] = 0.6f; d.color[1] = 0.5f; d.color[2] = 0.4f; d.color[3] = 1.0f;
        cr_assert_eq(refl_mesh_plane(12.0f, 8, NULL, &mesh), REFL_OK);
        o.mesh = refl_scene_add_mesh(s, mesh);
        o.material = refl_scene_add_material(s, &d);
        o.transform = refl_mat4_translate(refl_v3(0.0f, -1.5f, 0.0f));
        cr_assert_eq(refl_scene_add_object(s, &o), 1);
        cr_assert_eq(refl_mesh_box(refl_v3(1.0f, 2.0f, 1.0f), NULL, &mesh), REFL_OK);
        o.mesh = refl_scene_add_mesh(s, mesh);
        o.transform = refl_mat4_translate(refl_v3(2.2f, -0.5f, 0.5f));
        cr_assert_eq(refl_scene_add_object(s, &o), 2);
        tu_refl_add_point_light(s, refl_v3(3.0f, 5.0f, 4.0f), 0.9f, 0.0f);
    }
    return s;
}

static refl_material material(refl_material_type type) {
    refl_material m;
    memset(&m, 0, sizeof m);
    m.type = type;
    m.color[0] = 0.3f; m.color[1] = 0.6f; m.color[2] = 0.9f; m.color[3] = 1.0f;
    return m;
}

/* ---- the true directions, traced ------------------------------------------- */

typedef struct traced {
    refl_vec3 d, n;   /* unit view direction; normal facing the viewer */
    int ok;
} traced;

/* The view ray through pixel (x, y), its hit on object 0 and the
   interpolated normal there, chosen as the method documents (the shading
   normal, or the geometric one where the shading normal faces away). */
static traced trace_pixel(const refl_bvh *bvh, const refl_scene *s, const refl_view *v, int x, int y) {
    traced t;
    refl_vec3 o;
    float tmax;
    refl_hit hit;
    memset(&t, 0, sizeof t);
    refl_view_ray(v, s, (float)x + 0.5f, (float)y + 0.5f, &o, &t.d, &tmax);
    if (refl_bvh_intersect(bvh, o, t.d, 0.0f, tmax, &hit) && hit.object == 0) {
        const refl_mesh *m = s->meshes[s->objects[0].mesh];
        const uint32_t *tri = m->indices + 3 * hit.triangle;
        float wt[3];
        refl_vec3 v[3], ng, n = refl_v3(0, 0, 0);
        int k;
        wt[0] = 1.0f - hit.u - hit.v; wt[1] = hit.u; wt[2] = hit.v;
        for (k = 0; k < 3; ++k) {
            const float *p = m->positions + 3 * tri[k], *q = m->normals + 3 * tri[k];
            v[k] = refl_v3(p[0], p[1], p[2]);
            n = refl_v3_add(n, refl_v3_scale(refl_v3(q[0], q[1], q[2]), wt[k]));
        }
        ng = refl_v3_normalize(refl_v3_cross(refl_v3_sub(v[1], v[0]), refl_v3_sub(v[2], v[0])));
        if (refl_v3_dot(t.d, ng) > 0.0f) {
            ng = refl_v3_scale(ng, -1.0f);
            n = refl_v3_scale(n, -1.0f);
        }
        n = refl_v3_normalize(n);
        t.n = refl_v3_dot(t.d, n) > 0.0f ? ng : n;
        t.ok = 1;
    }
    return t;
}

/* What the method documents for a reflector pixel that sees only the
   environment: the DIRECT byte plus the reflectance share of the lookup
   along r (and for glass, 1 - F of the lookup along the refracted ray,
   tinted), clamped. */
static void expected_color(const refl_scene *s, const refl_material *m, const traced *t, const float *direct,
                           float out[3]) {
    float cos_i = -refl_v3_dot(t->d, t->n), w = refl_material_reflectance(m, cos_i), e[3], tr[3];
    int c;
    refl_environment_lookup(&s->environment, refl_v3_reflect(t->d, t->n), e);
    for (c = 0; c < 3; ++c) out[c] = direct[c] + w * fmaxf(e[c], 0.0f);
    if (m->type == REFL_GLASS) {
        refl_vec3 dir;
        cr_assert(refl_v3_refract(t->d, t->n, 1.0f / (m->ior > 0.0f ? m->ior : 1.5f), &dir));
        refl_environment_lookup(&s->environment, dir, tr);
        for (c = 0; c < 3; ++c) {
            float tint = m->tint[0] + m->tint[1] + m->tint[2] > 0.0f ? m->tint[c] : 1.0f;
            out[c] += (1.0f - w) * tint * fmaxf(tr[c], 0.0f);
        }
    }
    for (c = 0; c < 3; ++c) out[c] = fminf(fmaxf(out[c], 0.0f), 1.0f);
}

/* ---- tests ------------------------------------------------------------------ */

/* Faces of distinct constant colours: the cube the method renders holds the
   same constant faces, and rast_cube_face picks the same face for the
   method's and the true direction, so every pixel matches to the byte but
   where r runs within a hair of a cube edge (the rasterised and the traced
   normal differ in the last bits). Every face shows somewhere. */
Test(refl_envmap, mirror_in_face_environment_matches_the_true_reflection) {
    refl_material m = material(REFL_MIRROR);
    refl_scene *s = sphere_scene(&m, 0);
    refl_view v = tu_refl_view(refl_v3(0.3f, 0.8f, 3.5f), refl_v3(0, 0, 0), 128, 128);
    refl_frame *f;
    refl_bvh *bvh;
    int x, y, c, faces_seen[6] = {0}, px = 0, off = 0, k;
    set_face_env(s);
    f = render_with(s, &v, REFL_ENVMAP, 2, 32);
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    for (y = 0; y < v.height; ++y)
        for (x = 0; x < v.width; ++x) {
            size_t i = (size_t)y * (size_t)v.width + (size_t)x;
            int p[4];
            traced t;
            float want[3];
            float zero[3] = {0, 0, 0};
            if (f->stencil[i] != 1) {
                cr_assert(is_nan(f->points[3 * i]), "points off the reflector must be NaN");
                continue;
            }
            cr_assert(is_nan(f->points[3 * i]) && is_nan(f->points[3 * i + 1]) && is_nan(f->points[3 * i + 2]),
                      "the environment shows no point");
            tu_pixel8(f, i, p);
            cr_assert_eq(p[3], 255);
            t = trace_pixel(bvh, s, &v, x, y);
            if (!t.ok) continue; /* silhouette: raster and ray disagree on coverage */
            ++px;
            expected_color(s, &m, &t, zero, want);
            for (c = 0; c < 3; ++c)
                if (p[c] != tu_unorm8(want[c])) break;
            if (c < 3) ++off;
            for (k = 0; k < 6; ++k)
                if (p[0] == tu_unorm8(face_rgb[k][0]) && p[1] == tu_unorm8(face_rgb[k][1]) &&
                    p[2] == tu_unorm8(face_rgb[k][2]))
                    faces_seen[k] = 1;
        }
    cr_assert(px > 5000, "only %d sphere pixels", px);
    cr_assert(off * 1000 <= px * 3, "%d of %d pixels differ from the true reflection", off, px);
    for (k = 0; k < 6; ++k) cr_assert(faces_seen[k], "face %d never reflected", k);
    cr_assert_eq(f->stats.envmap.cube_faces, 6);
    cr_assert_eq(f->stats.model_bytes, 6LL * 32 * 32 * (4 + 3 * (long long)sizeof(float) + 1));
    refl_bvh_destroy(bvh);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* A smooth environment: the method agrees with the true reflection within
   the cube's resolution (8-bit texels, bilinear within a face) for each
   material: a mirror, a Fresnel mirror of reflectance 0.6, a partial
   reflector (on top of its diffuse share) and tinted glass (reflection
   plus the single-interface refraction). */
Test(refl_envmap, smooth_environment_matches_within_cube_resolution) {
    refl_material mats[4];
    int which;
    mats[0] = material(REFL_MIRROR);
    mats[1] = material(REFL_MIRROR);
    mats[1].reflectance = 0.6f;
    mats[1].fresnel = 1;
    mats[2] = material(REFL_PARTIAL);
    mats[2].mirror_weight = 0.4f;
    mats[3] = material(REFL_GLASS);
    mats[3].ior = 1.45f;
    mats[3].tint[0] = 0.9f; mats[3].tint[1] = 0.95f; mats[3].tint[2] = 0.7f;
    for (which = 0; which < 4; ++which) {
        refl_scene *s = sphere_scene(&mats[which], 0);
        refl_view v = tu_refl_view(refl_v3(-0.4f, 1.0f, 3.2f), refl_v3(0, 0, 0), 128, 128);
        refl_frame *f, *direct;
        refl_bvh *bvh;
            int x, y, c, px = 0, worst = 0;
        set_smooth_env(s);
        f = render_with(s, &v, REFL_ENVMAP, 3, 128);
        direct = render_with(s, &v, REFL_DIRECT, 1, 0);
        cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
            for (y = 0; y < v.height; ++y)
            for (x = 0; x < v.width; ++x) {
                size_t i = (size_t)y * (size_t)v.width + (size_t)x;
                traced t;
                float want[3];
                int pixel_worst = 0;
                if (f->stencil[i] != 1) continue;
                t = trace_pixel(bvh, s, &v, x, y);
                if (!t.ok) continue;
                ++px;
                expected_color(s, &mats[which], &t, direct->rgba + 4 * i, want);
                for (c = 0; c < 3; ++c) {
                    int d = abs((int)tu_unorm8(f->rgba[4 * i + c]) - tu_unorm8(want[c]));
                    if (d > pixel_worst) pixel_worst = d;
                }
                if (pixel_worst > worst) worst = pixel_worst;
            }
        cr_assert(px > 5000, "material %d: only %d sphere pixels", which, px);
        /* 8-bit texels round once more than the truth: one step at most */
        cr_assert(worst <= 1, "material %d: a pixel %d/255 off the true reflection", which, worst);
        refl_bvh_destroy(bvh);
        refl_frame_destroy(direct);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
}

/* With scenery around, each reflector pixel's point is what the cube shows
   along its mirror direction: seen from the cube's centre (the sphere's,
   the origin) it lies within a texel of r, and the scenery really lies
   along r there (a ray from the centre, the sphere left out, hits it near
   the point); NaN points go with rays that escape to the environment. */
Test(refl_envmap, points_are_what_the_cube_shows_along_the_reflection) {
    enum { N = 64 };
    refl_material m = material(REFL_MIRROR);
    refl_scene *s = sphere_scene(&m, 1), *rest;
    refl_view v = tu_refl_view(refl_v3(0.5f, 1.5f, 4.0f), refl_v3(0, -0.3f, 0), 160, 160);
    refl_frame *f;
    refl_bvh *bvh, *rest_bvh;
    int x, y, px = 0, finite = 0, agree = 0;
    float max_angle = 0.0f;
    f = render_with(s, &v, REFL_ENVMAP, 2, N);
    cr_assert_eq(refl_bvh_build(s, NULL, &bvh), REFL_OK);
    /* the same scenery without the sphere, for rays from its centre */
    cr_assert_eq(refl_scene_create(NULL, &rest), REFL_OK);
    {
        int i;
        for (i = 1; i < s->object_count; ++i) {
            refl_mesh *copy = NULL;
            refl_mesh_desc d;
            refl_object o = s->objects[i];
            const refl_mesh *src = s->meshes[o.mesh];
            memset(&d, 0, sizeof d);
            d.positions = src->positions;
            d.normals = src->normals;
            d.indices = src->indices;
            d.vertex_count = src->vertex_count;
            d.index_count = 3 * src->triangle_count;
            cr_assert_eq(refl_mesh_create(&d, &copy), REFL_OK);
            o.mesh = refl_scene_add_mesh(rest, copy);
            o.material = refl_scene_add_material(rest, &s->materials[s->objects[i].material]);
            cr_assert(refl_scene_add_object(rest, &o) >= 0);
        }
    }
    cr_assert_eq(refl_bvh_build(rest, NULL, &rest_bvh), REFL_OK);
    for (y = 0; y < v.height; ++y)
        for (x = 0; x < v.width; ++x) {
            size_t i = (size_t)y * (size_t)v.width + (size_t)x;
            const float *pt = f->points + 3 * i;
            traced t;
            refl_vec3 r;
            refl_hit h;
            int hits;
            if (f->stencil[i] != 1) continue;
            t = trace_pixel(bvh, s, &v, x, y);
            if (!t.ok) continue;
            ++px;
            r = refl_v3_reflect(t.d, t.n);
            hits = refl_bvh_intersect(rest_bvh, refl_v3(0, 0, 0), r, 0.0f, FLT_MAX, &h);
            if (!is_nan(pt[0])) {
                refl_vec3 p = refl_v3(pt[0], pt[1], pt[2]);
                float a = acosf(fminf(1.0f, refl_v3_dot(refl_v3_normalize(p), refl_v3_normalize(r))));
                cr_assert(!is_nan(pt[1]) && !is_nan(pt[2]));
                if (a > max_angle) max_angle = a;
                ++finite;
                /* the hit lies by the point (a texel's footprint away at most) */
                if (hits && refl_v3_length(refl_v3_sub(refl_v3_scale(r, h.t), p)) < 0.1f * h.t + 0.05f) ++agree;
            } else {
                cr_assert(is_nan(pt[1]) && is_nan(pt[2]));
                if (!hits) ++agree;
            }
        }
    cr_assert(px > 3000 && finite > px / 4, "%d pixels, %d with points", px, finite);
    /* nearest texel: at most half a texel's diagonal, 2 / N per texel side */
    cr_assert(max_angle <= 1.5f / N, "a point %g rad off its reflected direction", max_angle);
    cr_assert(agree * 100 >= px * 97, "only %d of %d pixels show what lies along r", agree, px);
    refl_bvh_destroy(rest_bvh);
    refl_bvh_destroy(bvh);
    refl_scene_destroy(rest);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

static void assert_same(const refl_frame *a, const refl_frame *b, const char *what, int threads) {
    size_t n = (size_t)a->width * (size_t)a->height;
    cr_assert_eq(tu_first_diff(a->rgba, b->rgba, (4 * n) * sizeof(float)), -1, "%s: colour differs with %d threads", what, threads);
    cr_assert_eq(tu_first_diff(a->points, b->points, 3 * n * sizeof(float)), -1, "%s: points differ with %d threads",
                 what, threads);
}

Test(refl_envmap, identical_for_any_thread_count) {
    const char *names[2] = {"default", "glass"};
    int threads[4] = {1, 2, 3, 8}, k, i;
    for (k = 0; k < 2; ++k) {
        refl_scene *s;
        refl_view v;
        refl_frame *a;
        cr_assert_eq(refl_scene_builtin(names[k], NULL, &s), REFL_OK);
        v = s->camera;
        v.width = 200;
        v.height = 150;
        a = render_with(s, &v, REFL_ENVMAP, threads[0], 96);
        for (i = 1; i < 4; ++i) {
            refl_frame *b = render_with(s, &v, REFL_ENVMAP, threads[i], 96);
            assert_same(a, b, names[k], threads[i]);
            refl_frame_destroy(b);
        }
        refl_frame_destroy(a);
        refl_scene_destroy(s);
    }
}

/* The default scene: every teapot pixel filled (opaque, never black), the
   floor, sphere and torus reflected with finite points inside the scene,
   the sky with none, nothing on other pixels; what is not a reflector is
   DIRECT's, byte for byte. */
Test(refl_envmap, default_scene) {
    refl_scene *s;
    refl_view v;
    refl_frame *f, *direct;
    refl_vec3 lo, hi;
    int i, n, teapot = -1, px = 0, finite = 0;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    for (i = 0; i < s->object_count; ++i)
        if (!strcmp(s->objects[i].name, "teapot")) teapot = i;
    cr_assert(teapot >= 0);
    refl_scene_bounds(s, &lo, &hi);
    v = s->camera;
    v.width = 320;
    v.height = 240;
    f = render_with(s, &v, REFL_ENVMAP, 0, 0);
    direct = render_with(s, &v, REFL_DIRECT, 0, 0);
    n = v.width * v.height;
    for (i = 0; i < n; ++i) {
        const float *c = f->rgba + 4 * i;
        const float *p = f->points + 3 * i;
        cr_assert_eq(f->stencil[i], direct->stencil[i]);
        if (f->stencil[i] != teapot + 1) {
            cr_assert_eq(memcmp(c, direct->rgba + 4 * i, 4 * sizeof(float)), 0, "pixel %d differs from DIRECT", i);
            cr_assert(is_nan(p[0]) && is_nan(p[1]) && is_nan(p[2]), "pixel %d has a point", i);
            continue;
        }
        ++px;
        cr_assert_eq(c[3], 1.0f);
        cr_assert(c[0] + c[1] + c[2] > 0, "teapot pixel %d is black", i);
        if (!is_nan(p[0])) {
            ++finite;
            cr_assert(p[0] >= lo.x - 1e-3f && p[0] <= hi.x + 1e-3f && p[1] >= lo.y - 1e-3f && p[1] <= hi.y + 1e-3f &&
                          p[2] >= lo.z - 1e-3f && p[2] <= hi.z + 1e-3f,
                      "point (%g %g %g) outside the scene", p[0], p[1], p[2]);
        } else {
            cr_assert(is_nan(p[1]) && is_nan(p[2]));
        }
    }
    cr_assert(px > 2000 && finite > px / 10 && finite < px, "%d teapot pixels, %d with points", px, finite);
    cr_assert_eq(f->stats.envmap.cube_faces, 6);
    cr_assert_eq(f->stats.reflectors, 1);
    cr_assert_eq(f->stats.model_bytes, 6LL * 256 * 256 * (4 + 3 * (long long)sizeof(float) + 1));
    cr_assert(f->stats.triangles > 12 * (direct->stats.triangles - s->meshes[s->objects[teapot].mesh]->triangle_count),
              "%lld triangles", f->stats.triangles);
    cr_assert(f->stats.ms_build >= 0.0 && f->stats.ms_reflect >= 0.0);
    refl_frame_destroy(direct);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* mirror-room at depth 3: a lookup that lands on another mirror's texel
   (drawn black, as DIRECT draws mirrors) goes to the tracer, so no mirror
   pixel is black where the exact path shows something lit. */
Test(refl_envmap, a_mirror_in_the_cube_is_traced_past_one_bounce) {
    refl_view v;
    refl_scene *s = tu_refl_builtin("mirror-room", &v, 96, 72);
    refl_render_desc d = tu_refl_one_bounce(REFL_RAYTRACE, 2);
    refl_frame *truth, *f;
    size_t i, n = (size_t)v.width * (size_t)v.height;
    int black = 0, mirror = 0;
    d.depth = 3;
    truth = tu_refl_render(s, &v, &d);
    d.method = REFL_ENVMAP;
    f = tu_refl_render(s, &v, &d);
    for (i = 0; i < n; ++i) {
        const float *c = f->rgba + 4 * i, *t = truth->rgba + 4 * i;
        if (!f->stencil[i]) continue;
        ++mirror;
        black += c[0] + c[1] + c[2] < 1e-3f && t[0] + t[1] + t[2] > 0.05f;
    }
    cr_assert_gt(mirror, (int)(n / 4));
    cr_assert_eq(black, 0, "%d of %d mirror pixels black where RAYTRACE's are lit", black, mirror);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
}

/* Sizes at the edges: a 1x1 frame, a one-texel cube, the reflector off
   screen (nothing to build: DIRECT's image), the camera inside the
   reflector. None may crash, leave a mirror pixel unfilled or emit a point
   off the reflectors. */
Test(refl_envmap, edge_sizes_and_views) {
    refl_scene *s;
    refl_view v;
    refl_frame *f, *direct;
    int i;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    /* 1 x 1, looking at the teapot's body */
    v = s->camera;
    v.target = refl_v3(0.0f, 0.8f, 0.0f);
    v.width = v.height = 1;
    f = render_with(s, &v, REFL_ENVMAP, 2, 0);
    cr_assert(f->stencil[0] != 0 && tu_unorm8(f->rgba[3]) == 255);
    refl_frame_destroy(f);
    f = render_with(s, &v, REFL_ENVMAP, 2, 1);
    cr_assert(tu_unorm8(f->rgba[3]) == 255);
    refl_frame_destroy(f);
    /* a one-texel cube on a full frame */
    v = s->camera;
    v.width = 64;
    v.height = 48;
    f = render_with(s, &v, REFL_ENVMAP, 3, 1);
    for (i = 0; i < 64 * 48; ++i)
        if (f->stencil[i]) cr_assert_eq(tu_unorm8(f->rgba[4 * i + 3]), 255);
    cr_assert_eq(f->stats.model_bytes, 6LL * (4 + 3 * (long long)sizeof(float) + 1));
    refl_frame_destroy(f);
    /* the teapot behind the camera */
    v.target = refl_v3(v.eye.x, v.eye.y, v.eye.z + 1.0f);
    f = render_with(s, &v, REFL_ENVMAP, 2, 32);
    direct = render_with(s, &v, REFL_DIRECT, 2, 0);
    cr_assert_eq(f->stats.envmap.cube_faces, 0);
    cr_assert_eq(tu_first_diff(f->rgba, direct->rgba, (64 * 48 * 4) * sizeof(float)), -1);
    for (i = 0; i < 64 * 48 * 3; ++i) cr_assert(is_nan(f->points[i]));
    refl_frame_destroy(direct);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    /* inside a mirror sphere: every pixel is the sphere's inside */
    {
        refl_material m = material(REFL_MIRROR);
        s = sphere_scene(&m, 1);
        v = tu_refl_view(refl_v3(0.1f, 0.2f, 0.3f), refl_v3(0.0f, 0.0f, -1.0f), 48, 32);
        f = render_with(s, &v, REFL_ENVMAP, 2, 16);
        for (i = 0; i < 48 * 32; ++i) {
            cr_assert_eq(f->stencil[i], 1);
            cr_assert_eq(tu_unorm8(f->rgba[4 * i + 3]), 255);
        }
        cr_assert_eq(f->stats.envmap.cube_faces, 6);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
}

/* Objects past 254 share stencil value 255: two mirrors there each still
   get their own cube and every pixel of theirs is filled. */
Test(refl_envmap, reflectors_sharing_stencil_255) {
    refl_scene *s;
    refl_mesh *mesh = NULL;
    refl_material diffuse = material(REFL_DIFFUSE), mirror = material(REFL_MIRROR);
    refl_object o;
    refl_view v;
    refl_frame *f;
    int i, dm, mm, box, sphere, px = 0;
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    cr_assert_eq(refl_mesh_box(refl_v3(0.1f, 0.1f, 0.1f), NULL, &mesh), REFL_OK);
    box = refl_scene_add_mesh(s, mesh);
    cr_assert_eq(refl_mesh_sphere(0.8f, 16, 8, NULL, &mesh), REFL_OK);
    sphere = refl_scene_add_mesh(s, mesh);
    dm = refl_scene_add_material(s, &diffuse);
    mm = refl_scene_add_material(s, &mirror);
    memset(&o, 0, sizeof o);
    for (i = 0; i < 260; ++i) { /* a row of small boxes behind the mirrors */
        o.mesh = box;
        o.material = dm;
        o.transform = refl_mat4_translate(refl_v3(-4.0f + 0.03f * (float)i, 1.5f, -3.0f));
        cr_assert_eq(refl_scene_add_object(s, &o), i);
    }
    o.mesh = sphere;
    o.material = mm;
    o.transform = refl_mat4_translate(refl_v3(-1.0f, 0.0f, 0.0f));
    cr_assert_eq(refl_scene_add_object(s, &o), 260);
    o.transform = refl_mat4_translate(refl_v3(1.0f, 0.0f, 0.0f));
    cr_assert_eq(refl_scene_add_object(s, &o), 261);
    set_face_env(s);
    v = tu_refl_view(refl_v3(0.0f, 0.5f, 5.0f), refl_v3(0, 0, 0), 96, 64);
    f = render_with(s, &v, REFL_ENVMAP, 2, 16);
    for (i = 0; i < 96 * 64; ++i)
        if (f->stencil[i] == 255) {
            ++px;
            cr_assert_eq(tu_unorm8(f->rgba[4 * i + 3]), 255, "pixel %d unfilled", i);
        }
    cr_assert(px > 500, "%d mirror pixels", px);
    cr_assert_eq(f->stats.envmap.cube_faces, 12);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* Every allocation of a scene and an ENVMAP frame may fail: each run
   returns an error or succeeds, and nothing leaks. */
Test(refl_envmap, allocation_failure_leaks_nothing) {
    refl_render_desc d = tu_refl_desc(REFL_ENVMAP, 2);
    tu_refl_failed_runs runs;
    d.envmap.size = 8;
    runs = tu_refl_default_allocation_failures(&d, 5000);
    cr_assert(runs.render_failed && runs.runs > 10, "only %ld allocations seen", runs.runs);
}
