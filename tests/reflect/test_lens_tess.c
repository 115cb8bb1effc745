/* Paper 001's adaptive tessellation (refl_lens_tessellate): the mesh
   conforms (every edge inside the front-facing region shared by exactly
   two triangles, wound opposite ways, the region's border by one, the area
   kept), every vertex is placed and traced once, splits follow the
   criteria (smaller t or angle: more vertices; a mirror plane splits only
   by angle, a glass sphere also by topology), and the mesh is the same
   for any thread count. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "refl_test_util.h"

/* One lens object, its BVH and a 160 x 120 view of it from eye. */
typedef struct lens_scene {
    tu_refl_traced t;
    refl_scene *scene;
    refl_ray_caster caster;
    refl_view view;
} lens_scene;

static lens_scene lens(refl_mesh *mesh, const refl_material *m, refl_mat4 transform, refl_vec3 eye) {
    lens_scene l;
    l.t = tu_refl_traced_object(mesh, m, transform);
    l.scene = l.t.scene;
    l.caster = l.t.caster;
    l.view = tu_refl_view(eye, refl_v3(0, 0, 0), 160, 120);
    return l;
}

static void lens_free(lens_scene *l) { tu_refl_traced_free(&l->t); }

static refl_lens_tess *tessellate(const lens_scene *l, float edge_px, float angle, int threads) {
    refl_lens_tess_desc d;
    refl_lens_tess *t = NULL;
    memset(&d, 0, sizeof d);
    d.edge_px = edge_px;
    d.angle_degrees = angle;
    d.threads = threads;
    cr_assert_eq(refl_lens_tessellate(l->scene, &l->caster, 0, &l->view, &d, &t), REFL_OK);
    cr_assert_not_null(t);
    return t;
}

static float tri_area(refl_vec3 a, refl_vec3 b, refl_vec3 c) {
    return 0.5f * refl_v3_length(refl_v3_cross(refl_v3_sub(b, a), refl_v3_sub(c, a)));
}

static refl_vec3 mesh_pos(const refl_mesh *m, uint32_t i) {
    return refl_v3(m->positions[3 * i], m->positions[3 * i + 1], m->positions[3 * i + 2]);
}

static int same_pos(refl_vec3 a, refl_vec3 b) { return a.x == b.x && a.y == b.y && a.z == b.z; }

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static int cmp_pos(const void *a, const void *b) {
    const float *p = (const float *)a, *q = (const float *)b;
    int k;
    for (k = 0; k < 3; ++k)
        if (p[k] != q[k]) return p[k] < q[k] ? -1 : 1;
    return 0;
}

/* Whether p lies on segment (a, b). */
static int on_segment(refl_vec3 p, refl_vec3 a, refl_vec3 b) {
    refl_vec3 ab = refl_v3_sub(b, a), ap = refl_v3_sub(p, a);
    float l2 = refl_v3_dot(ab, ab), s = refl_v3_dot(ap, ab);
    return refl_v3_length(refl_v3_cross(ab, ap)) <= 1e-5f * l2 && s >= -1e-6f * l2 && s <= l2 * (1.0f + 1e-6f);
}

/* The conformity of t against the front-facing triangles of mesh m (model
   identity) seen from eye: directed edges once each, an undirected edge
   used twice unless it lies on the border of the front-facing region (an
   edge of the mesh with one front-facing triangle), and the area the
   front-facing triangles cover. */
static void assert_conforms(const refl_lens_tess *t, const refl_mesh *m, refl_vec3 eye) {
    int i, j, k, n = t->triangle_count, nb = 0;
    refl_vec3 *border = (refl_vec3 *)malloc(sizeof(refl_vec3) * 6 * (size_t)m->triangle_count);
    int *front = (int *)calloc((size_t)m->triangle_count, sizeof(int));
    uint64_t *edges = (uint64_t *)malloc(sizeof(uint64_t) * 3 * (size_t)(n ? n : 1));
    double area = 0.0, front_area = 0.0;
    for (i = 0; i < m->triangle_count; ++i) {
        refl_vec3 a = mesh_pos(m, m->indices[3 * i]), b = mesh_pos(m, m->indices[3 * i + 1]),
                  c = mesh_pos(m, m->indices[3 * i + 2]);
        refl_vec3 nn = refl_v3_cross(refl_v3_sub(b, a), refl_v3_sub(c, a));
        front[i] = refl_v3_dot(nn, nn) > 0.0f && refl_v3_dot(nn, refl_v3_sub(eye, a)) > 0.0f;
        if (front[i]) front_area += tri_area(a, b, c);
    }
    /* the border: front-facing edges whose other side (by position) is not front-facing */
    for (i = 0; i < m->triangle_count; ++i) {
        if (!front[i]) continue;
        for (k = 0; k < 3; ++k) {
            refl_vec3 a = mesh_pos(m, m->indices[3 * i + k]), b = mesh_pos(m, m->indices[3 * i + (k + 1) % 3]);
            int shared = 0;
            for (j = 0; j < m->triangle_count && !shared; ++j) {
                int q;
                if (j == i || !front[j]) continue;
                for (q = 0; q < 3; ++q)
                    if (same_pos(mesh_pos(m, m->indices[3 * j + q]), b) &&
                        same_pos(mesh_pos(m, m->indices[3 * j + (q + 1) % 3]), a))
                        shared = 1;
            }
            if (!shared) {
                border[2 * nb] = a;
                border[2 * nb + 1] = b;
                ++nb;
            }
        }
    }
    /* every directed edge, sorted: each once, its opposite at most once */
    for (i = 0; i < n; ++i) {
        const uint32_t *x = t->indices + 3 * i;
        area += tri_area(t->vertices[x[0]].position, t->vertices[x[1]].position, t->vertices[x[2]].position);
        for (k = 0; k < 3; ++k) {
            cr_assert_neq(x[k], x[(k + 1) % 3], "triangle %d degenerate", i);
            edges[3 * i + k] = (uint64_t)x[k] << 32 | x[(k + 1) % 3];
        }
    }
    qsort(edges, 3 * (size_t)n, sizeof *edges, cmp_u64);
    for (i = 0; i < 3 * n; ++i) {
        uint32_t a = (uint32_t)(edges[i] >> 32), b = (uint32_t)edges[i];
        uint64_t opposite = (uint64_t)b << 32 | a;
        cr_assert(i == 0 || edges[i] != edges[i - 1], "directed edge %u-%u used twice", a, b);
        if (!bsearch(&opposite, edges, 3 * (size_t)n, sizeof *edges, cmp_u64)) { /* on the border */
            int found = 0;
            for (j = 0; j < nb && !found; ++j)
                found = on_segment(t->vertices[a].position, border[2 * j], border[2 * j + 1]) &&
                        on_segment(t->vertices[b].position, border[2 * j], border[2 * j + 1]);
            cr_assert(found, "edge %u-%u has one triangle but is inside the region (a T-junction)", a, b);
        }
    }
    cr_assert_float_eq(area, front_area, 1e-4 * front_area, "area %g, front-facing %g", area, front_area);
    free(border);
    free(front);
    free(edges);
}

/* Every vertex is used, traced (a term) and placed once (no two share a
   position), and the rays cover at least one visibility ray and one path
   ray per vertex. */
static void assert_traced_once(const refl_lens_tess *t) {
    int i;
    char *used = (char *)calloc((size_t)t->vertex_count, 1);
    float *pos = (float *)malloc(sizeof(float) * 3 * (size_t)t->vertex_count);
    for (i = 0; i < 3 * t->triangle_count; ++i) used[t->indices[i]] = 1;
    for (i = 0; i < t->vertex_count; ++i) {
        cr_assert(used[i], "vertex %d unused", i);
        cr_assert_gt(t->vertices[i].paths.terms, 0, "vertex %d untraced", i);
        pos[3 * i] = t->vertices[i].position.x;
        pos[3 * i + 1] = t->vertices[i].position.y;
        pos[3 * i + 2] = t->vertices[i].position.z;
    }
    qsort(pos, (size_t)t->vertex_count, 3 * sizeof(float), cmp_pos);
    for (i = 1; i < t->vertex_count; ++i)
        cr_assert_neq(cmp_pos(pos + 3 * (i - 1), pos + 3 * i), 0, "two vertices at one position");
    cr_assert_geq(t->rays, 2LL * t->vertex_count);
    free(used);
    free(pos);
}

static void assert_same_tess(const refl_lens_tess *a, const refl_lens_tess *b) {
    int i;
    cr_assert_eq(a->vertex_count, b->vertex_count);
    cr_assert_eq(a->triangle_count, b->triangle_count);
    cr_assert_eq(a->rays, b->rays);
    cr_assert_eq(memcmp(a->indices, b->indices, 3 * sizeof(uint32_t) * (size_t)a->triangle_count), 0);
    for (i = 0; i < a->vertex_count; ++i)
        cr_assert_eq(memcmp(&a->vertices[i], &b->vertices[i], sizeof a->vertices[i]), 0, "vertex %d", i);
}

Test(lens_tess, glass_sphere_conforms_traced_once_any_threads) {
    refl_mesh *mesh = NULL;
    refl_material glass = refl_material_glass(1.5f);
    lens_scene l;
    refl_lens_tess *t1, *t3;
    refl_vec3 eye = refl_v3(0.3f, 0.5f, 4.0f);
    cr_assert_eq(refl_mesh_sphere(1.0f, 16, 8, NULL, &mesh), REFL_OK);
    l = lens(mesh, &glass, refl_mat4_identity(), eye);
    t1 = tessellate(&l, 2.0f, 0.0f, 1);
    t3 = tessellate(&l, 2.0f, 0.0f, 3);
    cr_assert_gt(t1->splits, 0);
    cr_assert_gt(t1->topology_splits, 0, "total internal reflection near the rim changes the paths");
    cr_assert_gt(t1->triangle_count, t1->front_triangles);
    assert_conforms(t1, l.scene->meshes[0], eye);
    assert_traced_once(t1);
    assert_same_tess(t1, t3);
    refl_lens_tess_destroy(t1);
    refl_lens_tess_destroy(t3);
    lens_free(&l);
}

Test(lens_tess, mirror_plane_splits_by_angle_down_to_t) {
    refl_mesh *mesh = NULL;
    refl_material mirror = refl_material_mirror(0.9f);
    lens_scene l;
    refl_lens_tess *coarse, *fine, *strict;
    refl_vec3 eye = refl_v3(0.0f, 2.5f, 2.5f);
    cr_assert_eq(refl_mesh_plane(2.0f, 4, NULL, &mesh), REFL_OK);
    l = lens(mesh, &mirror, refl_mat4_identity(), eye);
    coarse = tessellate(&l, 8.0f, 3.0f, 2);
    fine = tessellate(&l, 2.0f, 3.0f, 2);
    strict = tessellate(&l, 2.0f, 1.0f, 2);
    cr_assert_eq(coarse->topology_splits, 0, "a flat mirror's paths all reflect once");
    cr_assert_gt(coarse->splits, 0);
    cr_assert_lt(coarse->vertex_count, fine->vertex_count);
    cr_assert_lt(fine->vertex_count, strict->vertex_count);
    assert_conforms(fine, l.scene->meshes[0], eye);
    assert_conforms(strict, l.scene->meshes[0], eye);
    assert_traced_once(strict);
    refl_lens_tess_destroy(coarse);
    refl_lens_tess_destroy(fine);
    refl_lens_tess_destroy(strict);
    lens_free(&l);
}

Test(lens_tess, bad_input) {
    refl_mesh *mesh = NULL;
    refl_material red = refl_material_diffuse(1, 0, 0);
    lens_scene l;
    refl_lens_tess *t = (refl_lens_tess *)1;
    cr_assert_eq(refl_mesh_plane(2.0f, 2, NULL, &mesh), REFL_OK);
    l = lens(mesh, &red, refl_mat4_identity(), refl_v3(0, 2, 2));
    cr_assert_eq(refl_lens_tessellate(l.scene, &l.caster, 0, &l.view, NULL, &t), REFL_ERROR_INVALID_ARGUMENT,
                 "a diffuse object is no lens");
    cr_assert_null(t);
    cr_assert_eq(refl_lens_tessellate(l.scene, &l.caster, 1, &l.view, NULL, &t), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_lens_tessellate(NULL, &l.caster, 0, &l.view, NULL, &t), REFL_ERROR_INVALID_ARGUMENT);
    l.view.eye.x = NAN;
    l.scene->materials[0] = refl_material_mirror(1.0f);
    cr_assert_eq(refl_lens_tessellate(l.scene, &l.caster, 0, &l.view, NULL, &t), REFL_ERROR_INVALID_ARGUMENT);
    refl_lens_tess_destroy(NULL);
    lens_free(&l);
}
