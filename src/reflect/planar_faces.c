/* Planar reflector faces, shared by PLANAR (paper 002's mirrors and
   refractors) and by the light volumes of both PLANAR and RAYTRACE: each
   mirror, partial reflector or glass object's triangles grouped by world
   plane. An object whose triangles fall into more than
   REFL__PLANAR_MAX_FACES planes is not planar (a teapot): it has no faces. */
#include "internal.h"

enum { REFL__PLANAR_MAX_FACES = 16 };

static void refl__planar_free_faces(const refl_scene *s, refl__planar_face *faces, int count) {
    int i;
    for (i = 0; i < count; ++i) refl__free(&s->allocator, faces[i].indices);
    refl__free(&s->allocator, faces);
}

/* Unit world plane of triangle t of object o (n . x = d); 0 when degenerate. */
static int refl__planar_tri_plane(const refl_object *o, const refl_mesh *mesh, int t, double n[3], double *d) {
    refl_vec3 v[3];
    double e1[3], e2[3], len;
    int k;
    for (k = 0; k < 3; ++k) {
        const float *pp = mesh->positions + 3 * (size_t)mesh->indices[3 * t + k];
        v[k] = refl_mat4_point(o->transform, refl_v3(pp[0], pp[1], pp[2]));
    }
    e1[0] = (double)v[1].x - v[0].x; e1[1] = (double)v[1].y - v[0].y; e1[2] = (double)v[1].z - v[0].z;
    e2[0] = (double)v[2].x - v[0].x; e2[1] = (double)v[2].y - v[0].y; e2[2] = (double)v[2].z - v[0].z;
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0.0) || len > DBL_MAX) return 0;
    for (k = 0; k < 3; ++k) n[k] /= len;
    *d = n[0] * v[0].x + n[1] * v[0].y + n[2] * v[0].z;
    return *d == *d;
}

/* The face among faces[first, count) in the plane (n, d), or count. */
static int refl__planar_match(const refl__planar_face *faces, int first, int count, const double n[3], double d,
                              double tol_d) {
    int f;
    for (f = first; f < count; ++f)
        if (faces[f].n[0] * n[0] + faces[f].n[1] * n[1] + faces[f].n[2] * n[2] > 1.0 - 1e-6 &&
            fabs(faces[f].d - d) <= tol_d)
            return f;
    return count;
}

/* Groups each mirror or partial reflector's triangles by world plane
   (normals within 0.08 degrees, offsets within 1e-5 of the scene's size).
   Degenerate triangles join no face (they draw nothing anyway). only:
   NULL, or per object whether to look at it at all. */
static refl_result refl__planar_find_faces(const refl_scene *s, const uint8_t *only, refl__planar_face **out,
                                           int *out_count) {
    refl__planar_face *faces;
    int i, count = 0, cap = 0;
    refl_vec3 lo, hi;
    double tol_d;
    refl_scene_bounds(s, &lo, &hi);
    tol_d = 1e-5 * REFL__MAX((double)refl_v3_length(refl_v3_sub(hi, lo)), 1e-6);
    for (i = 0; i < s->object_count; ++i) {
        const refl_material *m = &s->materials[s->objects[i].material];
        if (m->type != REFL_DIFFUSE && (!only || only[i])) cap += REFL__PLANAR_MAX_FACES;
    }
    faces = (refl__planar_face *)refl__calloc(&s->allocator, (size_t)REFL__MAX(cap, 1), sizeof(*faces));
    if (!faces) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < s->object_count; ++i) {
        const refl_object *o = &s->objects[i];
        const refl_mesh *mesh = s->meshes[o->mesh];
        const refl_material *m = &s->materials[o->material];
        int first = count, t, f, k, planar = 1;
        double n[3], d;
        if (m->type == REFL_DIFFUSE || (only && !only[i])) continue;
        /* the planes and how many indices each gets */
        for (t = 0; t < mesh->triangle_count && planar; ++t) {
            if (!refl__planar_tri_plane(o, mesh, t, n, &d)) continue;
            f = refl__planar_match(faces, first, count, n, d, tol_d);
            if (f == count) {
                if (count - first == REFL__PLANAR_MAX_FACES) { planar = 0; break; }
                faces[f].object = i;
                for (k = 0; k < 3; ++k) faces[f].n[k] = n[k];
                faces[f].d = d;
                faces[f].glass = m->type == REFL_GLASS;
                faces[f].opposite = -1;
                ++count;
            }
            faces[f].index_count += 3;
        }
        if (!planar) { /* curved: not PLANAR's (refl__planar_handles) */
            memset(&faces[first], 0, (size_t)(count - first) * sizeof(*faces));
            count = first;
            continue;
        }
        for (f = first; f < count; ++f) {
            faces[f].indices = (uint32_t *)refl__calloc(&s->allocator, (size_t)faces[f].index_count, sizeof(uint32_t));
            if (!faces[f].indices) {
                refl__planar_free_faces(s, faces, count);
                return REFL_ERROR_OUT_OF_MEMORY;
            }
            faces[f].index_count = 0;
        }
        for (t = 0; t < mesh->triangle_count; ++t) {
            if (!refl__planar_tri_plane(o, mesh, t, n, &d)) continue;
            f = refl__planar_match(faces, first, count, n, d, tol_d);
            for (k = 0; k < 3; ++k) faces[f].indices[faces[f].index_count++] = mesh->indices[3 * t + k];
        }
        /* a glass face with a parallel face opposite is one side of a slab */
        for (f = first; f < count; ++f) {
            int g;
            for (g = first; g < count && faces[f].glass; ++g)
                if (faces[f].n[0] * faces[g].n[0] + faces[f].n[1] * faces[g].n[1] + faces[f].n[2] * faces[g].n[2] <
                        -1.0 + 1e-6 && faces[f].d + faces[g].d > tol_d) {
                    faces[f].opposite = g;
                    faces[f].thickness = faces[f].d + faces[g].d;
                }
        }
    }
    *out = faces;
    *out_count = count;
    return REFL_OK;
}

/* Reflection about the plane n . x = d: x - 2 (n . x - d) n. */
static refl_mat4 refl__planar_reflection(const double n[3], double d) {
    refl_mat4 r = refl_mat4_identity();
    int i, j;
    for (j = 0; j < 3; ++j) {
        for (i = 0; i < 3; ++i) r.m[j * 4 + i] = (float)((i == j) - 2.0 * n[i] * n[j]);
        r.m[12 + j] = (float)(2.0 * d * n[j]);
    }
    return r;
}
