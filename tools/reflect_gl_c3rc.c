/* reflect_gl_c3rc.c - a frame of C3RC through GL (reflect_gl.h, docs/gl.md),
   the paper's split: the CPU culls, GL projects and rasterises.
     1. the base pass (reflect_gl_frame.c): each reflector marks its pixels
        with its object number; per reflector pixel the CPU turns the
        read-back into its reflected ray and how fast it turns (textures
        for the fragment shader);
     2. the scene's surfaces sampled with points (refl_mesh_sample_points at
        the CPU path's default density: a point per 2 x 2 pixels at the
        reflectors' distance), each shaded once as DIRECT shows it, in a
        kd-tree (leaves of 128 points, the paper's size);
     3. the CPU path's cameras (refl_c3rc_view_cameras: every reflector
        triangle facing the eye, split as C3RC splits it); per camera the
        kd-tree's leaves its box test (refl_c3rc_box_visible) keeps are
        drawn as GL_POINTS through the C3RC hook (refl_c3rc_project in the
        vertex shader, after a test against the planes of its volume's
        hull; one instance per projection, three where the camera folds):
        each projection a square splat at its reflector point, sized by the
        point spacing the camera shows there as the CPU path sizes it; per
        fragment its depth pushed back to where the pixel's own ray meets
        the point's tangent plane, and, where the pixel's ray turns fast,
        only a surfel the ray meets shown; stencilled to the reflector's
        pixels; the reflector's own points within one edge left out;
     4. the CPU composites: pixels whose splats all missed take their
        neighbours' nearest point; a pixel in a gap of a nearer surface's
        points (refl_c3rc_in_gap, the CPU path's test) is traced on the
        CPU, as the CPU path hands it to its tracer; the others show
        reflectance times the point's colour, the environment along the
        reflected ray where no point landed.
   One bounce, as the paper; glass is drawn as DIRECT draws it. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "reflect_gl.h"

#include <EGL/egl.h>
#include <GL/gl.h>

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "reflect_gl_funcs.h"
#include "reflect_gl_frame.h"

#ifndef GL_PROGRAM_POINT_SIZE
#define GL_PROGRAM_POINT_SIZE 0x8642
#endif

#define RGL_C3_AUTO_POINTS 2e6    /* the most points the default density samples */
#define RGL_C3_MAX_SPLAT 8        /* pixels: the CPU path's default max_splat */
#define RGL_C3_STR(x) #x
#define RGL_C3_GLSL_INT(x) RGL_C3_STR(x)
#define RGL_C3_TURN_TEST "0.05"  /* radians: the CPU path's REFL__C3_TURN_TEST */
#define RGL_C3_LEAF_POINTS 128    /* kd-tree leaf size: the box test culls per leaf (the paper: 122) */
enum { RGL_C3_POINT_FLOATS = 9 }; /* position, tree index; normal, object (+ 0.5 on a diffuse one); density */

static const char rgl__c3_vs_head[] =
    "#version 330 core\n"
    "layout(location = 0) in vec4 a_p;\n" /* position, tree index */
    "layout(location = 1) in vec4 a_n;\n" /* normal, object (+ 0.5 when diffuse) */
    "layout(location = 2) in float a_density;\n" /* its object's points per unit area */
    "uniform samplerBuffer u_data;\n"
    "uniform int u_cam;\n"
    "uniform mat4 u_vp;\n"
    "uniform float u_tmax, u_screen_area, u_near_self, u_fold, u_fold_splat;\n"
    "uniform int u_object;\n"
    "uniform int u_hull_count;\n"
    "uniform float u_edge, u_pixel_angle;\n" /* the camera's longest edge (world); a pixel's size per unit of distance */
    "uniform vec3 u_eye;\n"
    "uniform vec4 u_hull[20];\n"
    "flat out float v_index; flat out float v_t; flat out float v_side; flat out float v_pix_sweep;\n"
    "flat out vec3 v_pt; flat out vec3 v_np; flat out float v_reach; flat out float v_self; flat out float v_disc;\n"
    "flat out vec3 v_q; flat out float v_tol;\n";

static const char rgl__c3_vs_main[] =
    "void main() {\n"
    "    vec4 pr[3];\n"
    "    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);\n" /* outside: culled */
    "    gl_PointSize = 1.0;\n"
    "    v_index = a_p.w; v_t = 0.0; v_side = 1.0; v_pix_sweep = 0.0;\n"
    "    v_pt = a_p.xyz; v_np = a_n.xyz; v_reach = 0.0; v_self = 0.0; v_q = vec3(0.0); v_tol = 0.0;\n"
    "    v_disc = a_density > 0.0 ? inversesqrt(a_density) : 1e30;\n"
    /* outside the truncated volume's hull: no projection (the CPU path's test) */
    "    for (int i = 0; i < u_hull_count; ++i)\n"
    "        if (dot(u_hull[i].xyz, a_p.xyz) > u_hull[i].w) return;\n"
    "    int k = refl_c3rc_project(u_data, 0, u_cam, a_p.xyz, pr);\n"
    "    if (gl_InstanceID >= k) return;\n"
    "    vec4 r = pr[gl_InstanceID];\n"
    "    int object = int(a_n.w);\n"
    "    bool diffuse = fract(a_n.w) > 0.25;\n"
    "    if (!(r.w > 0.0) || (object == u_object && r.w < u_near_self)) return;\n"
    "    vec3 q = refl_c3rc_image(u_data, 0, u_cam, r);\n"
    "    vec4 clip = u_vp * vec4(q, 1.0);\n"
    "    if (!(clip.w > 0.0)) return;\n"
    /* the sweeping triangle at t (texels 7-10: e1, e2, f1, f2) */
    "    int o = 1 + u_cam * 16;\n"
    "    vec3 E1 = texelFetch(u_data, o + 7).xyz + r.w * texelFetch(u_data, o + 9).xyz;\n"
    "    vec3 E2 = texelFetch(u_data, o + 8).xyz + r.w * texelFetch(u_data, o + 10).xyz;\n"
    "    vec3 ns = cross(E1, E2);\n"
    "    float sweep = 0.5 * length(ns);\n"
    "    vec3 dir = normalize(a_p.xyz - q);\n"
    "    float cs = sweep > 0.0 ? abs(dot(ns, dir)) / (2.0 * sweep) : 1.0, cp = dot(a_n.xyz, dir);\n"
    "    if (cp > 0.0 && diffuse) return;\n" /* a diffuse surface's back */
    "    float spacing = sweep > 0.0 && a_density > 0.0 ?\n"
    "        sqrt(abs(cp) / max(cs, 0.05) * u_screen_area / (sweep * a_density)) : 0.0;\n"
    /* the CPU path's splat: 1.5 per point spacing, at most its default max_splat 8,
       from the camera's first fold interval on its size on screen */
    "    float side = clamp(ceil(1.5 * min(spacing, 1e4)), 1.0,\n"
    "                       r.w >= u_fold ? u_fold_splat : float(" RGL_C3_GLSL_INT(RGL_C3_MAX_SPLAT) "));\n"
    "    v_t = r.w; v_side = side;\n"
    "    v_pix_sweep = u_screen_area > 0.0 ? sqrt(sweep / u_screen_area) : 0.0;\n"
    "    v_reach = side * v_pix_sweep / max(abs(cp), 0.2);\n"
    "    v_self = object == u_object ? 1.0 : 0.0;\n"
    "    v_q = q; v_tol = u_edge + side * u_pixel_angle * length(q - u_eye);\n"
    "    gl_Position = vec4(clip.xy / clip.w, 0.0, 1.0);\n"
    "    gl_PointSize = side;\n"
    "}\n";

/* Per pixel (textures of the base pass, rows bottom first): the reflector
   point and how far its reflected ray turns to its neighbours' (u_surf),
   the reflected ray (u_ray). As the CPU path: a splat's depth is where the
   pixel's ray meets the point's tangent plane (within its reach of the
   point's t), plus the same-surface slope off the splat's centre; where
   the ray turns fast, another object's point shows only where the ray
   meets its surfel (a disc of one point spacing of its object's); a pixel all of
   whose splats missed is marked (-1), and shows its neighbours' nearest
   point (rgl__c3_resolve). */
static const char rgl__c3_fs[] =
    "#version 330 core\n"
    "flat in float v_index; flat in float v_t; flat in float v_side; flat in float v_pix_sweep;\n"
    "flat in vec3 v_pt; flat in vec3 v_np; flat in float v_reach; flat in float v_self; flat in float v_disc;\n"
    "flat in vec3 v_q; flat in float v_tol;\n"
    "uniform vec3 u_plane_n, u_eye;\n" /* the camera's reflector plane's unit normal */
    "uniform float u_pixel_angle;\n"
    "uniform float u_tmax, u_side;\n"
    "uniform sampler2D u_surf, u_ray;\n"
    "layout(location = 0) out vec4 o_point;\n"
    "void main() {\n"
    "    ivec2 px = ivec2(gl_FragCoord.xy);\n"
    "    vec4 r = texelFetch(u_surf, px, 0);\n"
    "    vec4 ray = texelFetch(u_ray, px, 0);\n"
    "    vec3 u = ray.xyz;\n"
    "    if (ray.w != u_side) discard;\n" /* the other side of the reflector (an open mesh) */
    /* the surface seen there must be this camera's triangle's: within two
       pixels of its plane and of the splat's size from its centre (the
       CPU path's test; another part of the reflector in front is not) */
    "    vec3 dq = v_q - r.xyz;\n"
    "    if (length(dq) > v_tol || abs(dot(dq, u_plane_n)) > 2.0 * u_pixel_angle * length(v_q - u_eye)) discard;\n"
    "    vec3 w = v_pt - r.xyz;\n"
    "    float un = dot(u, v_np);\n"
    "    if (r.w >= " RGL_C3_TURN_TEST " && v_self < 0.5) {\n"
    "        float s = abs(un) > 0.2 ? dot(w, v_np) / un : dot(w, u);\n"
    "        if (!(s > 0.0) || length(w - s * u) > v_disc) {\n"
    /* missed: marks the pixel touched, behind every splat that shows */
    "            gl_FragDepth = 0.999999;\n"
    "            o_point = vec4(0.0, 0.0, 0.0, -1.0);\n"
    "            return;\n"
    "        }\n"
    "    }\n"
    "    float depth = abs(un) > 0.2 ? clamp(dot(w, v_np) / un, v_t - v_reach, v_t + v_reach) : v_t;\n"
    "    vec2 off = (gl_PointCoord - 0.5) * v_side;\n"
    /* the CPU path's same-surface slope: 4 pixel sweeps per pixel off the centre */
    "    depth += 4.0 * v_pix_sweep * length(off);\n"
    "    gl_FragDepth = clamp(depth / u_tmax, 0.0, 0.99999);\n"
    "    o_point = vec4(depth, 0.0, 0.0, v_index + 1.0);\n"
    "}\n";

/* The sampled points: tree order, with colour and attributes for GL. */
typedef struct rgl_c3_points {
    refl_kdtree *tree;
    float *gl;               /* RGL_C3_POINT_FLOATS per tree point */
    float *rgb;              /* per tree point */
} rgl_c3_points;

static void rgl__c3_points_free(rgl_c3_points *s) {
    refl_kdtree_destroy(s->tree);
    free(s->gl);
    free(s->rgb);
    memset(s, 0, sizeof *s);
}

static int rgl__c3_is_reflector(const refl_scene *s, int o) {
    int t = s->materials[s->objects[o].material].type;
    return t == REFL_MIRROR || t == REFL_PARTIAL;
}

/* The CPU path's default density: a point per 2 x 2 pixels at the nearest
   box corner or centre of the reflectors the base pass shows, at most
   RGL_C3_AUTO_POINTS over the scene's area; *wanted the density before
   that cap. */
static float rgl__c3_density(const rgl_pass *p, float *wanted) {
    const refl_scene *s = p->scene;
    double area = 0.0;
    float nearest = FLT_MAX, size, zn, pixel_angle = rgl_pass_pixel_angle(p);
    long long i;
    size_t k, np = (size_t)p->w * (size_t)p->h;
    int o, corner;
    uint8_t *seen = (uint8_t *)calloc((size_t)(s->object_count > 0 ? s->object_count : 1), 1);
    *wanted = 0.0f;
    if (!seen) return 0.0f;
    for (k = 0; k < np; ++k)
        if (p->marks[k] >= 1 && p->marks[k] <= s->object_count) seen[p->marks[k] - 1] = 1;
    for (o = 0; o < s->object_count; ++o) {
        refl_vec3 lo, hi;
        if (!seen[o] || !rgl__c3_is_reflector(s, o)) continue;
        refl_mesh_bounds(s->meshes[s->objects[o].mesh], &lo, &hi);
        for (corner = 0; corner < 9; ++corner) {
            refl_vec3 q = corner == 8 ? refl_v3_scale(refl_v3_add(lo, hi), 0.5f)
                                      : refl_v3(corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y, corner & 4 ? hi.z : lo.z);
            float d = refl_v3_length(refl_v3_sub(refl_mat4_point(s->objects[o].transform, q), p->view->eye));
            nearest = d < nearest ? d : nearest;
        }
    }
    for (i = 0; i + 2 < p->geo.vertex_count; i += 3) {
        const float *a = p->geo.v + i * RGL_VERTEX_FLOATS, *b = a + RGL_VERTEX_FLOATS, *c = b + RGL_VERTEX_FLOATS;
        refl_vec3 e1 = refl_v3(b[0] - a[0], b[1] - a[1], b[2] - a[2]), e2 = refl_v3(c[0] - a[0], c[1] - a[1], c[2] - a[2]);
        area += 0.5 * refl_v3_length(refl_v3_cross(e1, e2));
    }
    zn = p->proj_m.m[14] / (p->proj_m.m[10] - 1.0f);
    free(seen);
    size = 2.0f * (nearest > zn ? nearest : zn) * pixel_angle;
    if (!(size > 0.0f) || nearest == FLT_MAX) return 0.0f;
    *wanted = (float)(1.0 / ((double)size * size));
    return (float)fmin(1.0 / ((double)size * size), area > 0.0 ? RGL_C3_AUTO_POINTS / area : 0.0);
}

/* Barycentric uv of world point q on object o's triangle t (geometry's
   world vertices). */
static void rgl__c3_uv(const rgl_pass *p, int o, uint32_t t, const float *q, float uv[2]) {
    const float *a = p->geo.v + (p->geo.first[o] + 3 * (long long)t) * RGL_VERTEX_FLOATS, *b = a + RGL_VERTEX_FLOATS,
                *c = b + RGL_VERTEX_FLOATS;
    refl_vec3 e1 = refl_v3(b[0] - a[0], b[1] - a[1], b[2] - a[2]), e2 = refl_v3(c[0] - a[0], c[1] - a[1], c[2] - a[2]);
    refl_vec3 w = refl_v3(q[0] - a[0], q[1] - a[1], q[2] - a[2]);
    float d00 = refl_v3_dot(e1, e1), d01 = refl_v3_dot(e1, e2), d11 = refl_v3_dot(e2, e2);
    float d20 = refl_v3_dot(w, e1), d21 = refl_v3_dot(w, e2), det = d00 * d11 - d01 * d01;
    float v = det != 0.0f ? (d11 * d20 - d01 * d21) / det : 0.0f, u = det != 0.0f ? (d00 * d21 - d01 * d20) / det : 0.0f;
    uv[0] = (1.0f - v - u) * a[6] + v * b[6] + u * c[6];
    uv[1] = (1.0f - v - u) * a[7] + v * b[7] + u * c[7];
}

/* The scene's points, object o sampled at density[o] points per unit area. */
static int rgl__c3_points(const rgl_pass *p, const float *density, rgl_c3_points *out) {
    const refl_scene *s = p->scene;
    refl_points **pts = (refl_points **)calloc((size_t)(s->object_count > 0 ? s->object_count : 1), sizeof *pts);
    float *pos = NULL, *col = NULL, *nrm = NULL, *obj = NULL;
    long long total = 0, at = 0, i;
    int o, rc = -1;
    memset(out, 0, sizeof *out);
    if (!pts) return -1;
    for (o = 0; o < s->object_count; ++o) {
        const refl_object *ob = &s->objects[o];
        if (refl_mesh_sample_points(s->meshes[ob->mesh], &ob->transform, density[o], 0x5eed + (uint64_t)o, NULL,
                                    &pts[o]) != REFL_OK)
            goto done;
        total += pts[o]->count;
    }
    if (total >= 16777216) goto done; /* tree indices pass through GL as floats */
    pos = (float *)malloc((size_t)(total ? total : 1) * 3 * sizeof(float));
    nrm = (float *)malloc((size_t)(total ? total : 1) * 3 * sizeof(float));
    col = (float *)malloc((size_t)(total ? total : 1) * 3 * sizeof(float));
    obj = (float *)malloc((size_t)(total ? total : 1) * sizeof(float));
    if (!pos || !nrm || !col || !obj) goto done;
    for (o = 0; o < s->object_count; ++o) {
        const refl_material *m = &s->materials[s->objects[o].material];
        for (i = 0; i < pts[o]->count; ++i, ++at) {
            const float *q = pts[o]->positions + 3 * i, *n = pts[o]->normals + 3 * i;
            float pt[4] = {q[0], q[1], q[2], (float)(o + 1)}, uv[2];
            memcpy(pos + 3 * at, q, 3 * sizeof(float));
            memcpy(nrm + 3 * at, n, 3 * sizeof(float));
            rgl__c3_uv(p, o, pts[o]->triangles[i], q, uv);
            rgl_shade(s, pt, n, uv, refl_v3(0.0f, 0.0f, 1.0f), col + 3 * at);
            obj[at] = (float)o + (m->type == REFL_DIFFUSE ? 0.5f : 0.0f);
        }
    }
    {
        refl_kdtree_desc kd;
        memset(&kd, 0, sizeof kd);
        kd.leaf_points = RGL_C3_LEAF_POINTS;
        if (refl_kdtree_build(pos, (int)total, &kd, &out->tree) != REFL_OK) goto done;
    }
    out->gl = (float *)malloc((size_t)(total ? total : 1) * RGL_C3_POINT_FLOATS * sizeof(float));
    out->rgb = (float *)malloc((size_t)(total ? total : 1) * 3 * sizeof(float));
    if (!out->gl || !out->rgb) goto done;
    for (i = 0; i < total; ++i) {
        uint32_t src = out->tree->order[i];
        float *g = out->gl + i * RGL_C3_POINT_FLOATS;
        memcpy(g, out->tree->positions + 3 * i, 3 * sizeof(float));
        g[3] = (float)i;
        memcpy(g + 4, nrm + 3 * (size_t)src, 3 * sizeof(float));
        g[7] = obj[src];
        g[8] = density[(int)obj[src]];
        memcpy(out->rgb + 3 * i, col + 3 * (size_t)src, 3 * sizeof(float));
    }
    rc = 0;
done:
    for (o = 0; o < s->object_count; ++o) refl_points_destroy(pts[o]);
    free(pts);
    free(pos);
    free(nrm);
    free(col);
    free(obj);
    return rc;
}

/* The splats read back as the CPU path's keys (refl_c3rc_splats), and
   per pixel the key it shows: its own, or where every splat missed its
   surfel (marked -1) the nearest of its 4-neighbours' on the same
   reflector side, as the CPU path's. */
typedef struct rgl_c3_keys {
    refl_c3rc_splats splats;
    uint64_t *key, *shown;
    float *side;             /* per pixel: mark, negated on a back face; 0 off the reflectors */
    int32_t *object;         /* per tree point */
} rgl_c3_keys;

static void rgl__c3_keys_free(rgl_c3_keys *k) {
    free(k->key);
    free(k->shown);
    free(k->side);
    free(k->object);
    memset(k, 0, sizeof *k);
}

static uint64_t rgl__c3_key(float depth, long long index) {
    uint32_t bits;
    depth = depth > 0.0f ? depth : 0.0f; /* (a positive float's bits order as the float) */
    memcpy(&bits, &depth, sizeof bits);
    return (uint64_t)bits << 32 | (uint64_t)(uint32_t)index;
}

static int rgl__c3_resolve(const rgl_pass *p, const rgl_c3_points *pts, const float *drawn, float spacing_scale,
                           rgl_c3_keys *k) {
    int w = p->w, h = p->h, x, y, n;
    size_t np = (size_t)w * (size_t)h, i;
    long long count = pts->tree->point_count, j;
    memset(k, 0, sizeof *k);
    k->key = (uint64_t *)malloc(np * sizeof(uint64_t));
    k->shown = (uint64_t *)malloc(np * sizeof(uint64_t));
    k->side = (float *)malloc(np * sizeof(float));
    k->object = (int32_t *)malloc((size_t)(count ? count : 1) * sizeof(int32_t));
    if (!k->key || !k->shown || !k->side || !k->object) return -1;
    for (j = 0; j < count; ++j) k->object[j] = (int32_t)pts->gl[j * RGL_C3_POINT_FLOATS + 7];
    for (i = 0; i < np; ++i) {
        long long at = p->marks[i] ? (long long)drawn[4 * i + 3] - 1 : -1;
        k->key[i] = at >= 0 && at < count ? rgl__c3_key(drawn[4 * i], at) : ~(uint64_t)0;
        k->side[i] = p->marks[i] ? (p->base[1][4 * i + 3] > 0.5f ? -(float)p->marks[i] : (float)p->marks[i]) : 0.0f;
    }
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            i = (size_t)y * w + x;
            k->shown[i] = k->key[i];
            if (!p->marks[i] || drawn[4 * i + 3] != -1.0f) continue;
            for (n = 0; n < 4; ++n) {
                int xs = x + (n == 0) - (n == 1), ys = y + (n == 2) - (n == 3);
                size_t js = (size_t)ys * w + xs;
                if (xs < 0 || ys < 0 || xs >= w || ys >= h || k->side[js] != k->side[i]) continue;
                if (k->key[js] < k->shown[i]) k->shown[i] = k->key[js];
            }
        }
    k->splats.width = w;
    k->splats.height = h;
    k->splats.side = k->side;
    k->splats.side_stride = 1;
    k->splats.key = k->key;
    k->splats.point_object = k->object;
    k->splats.reach = refl_c3rc_gap_reach(RGL_C3_MAX_SPLAT, spacing_scale);
    return 0;
}

/* One camera of the CPU path's (refl_c3rc_view_cameras), the largest t
   a scene point can have, the start of its first fold interval, and the
   planes bounding its volume up to that t (n . p <= d inside; none where
   it is unbounded). */
typedef struct rgl_c3_cam {
    refl_c3rc_view_camera view; /* the CPU path's camera, for its level of detail */
    refl_c3rc cam;
    int object, back, folds, hull_count;
    float screen_area, screen_edge, near_self, sweep, fold, edge;
    refl_vec3 plane_n;       /* its reflector plane's unit normal */
    float hull[20][4];
} rgl_c3_cam;

/* The volume up to tmax is the convex hull of the tails and vi + tmax di:
   every plane through three of those six points with all six on one side
   bounds it (a margin keeps rounding on the inside). */
static void rgl__c3_hull(rgl_c3_cam *k, float tmax) {
    refl_vec3 q[6];
    float scale = 0.0f;
    int i, j, l, m;
    for (i = 0; i < 3; ++i) {
        q[i] = k->cam.v[i];
        q[i + 3] = refl_v3_add(k->cam.v[i], refl_v3_scale(k->cam.d[i], tmax));
    }
    for (i = 0; i < 6; ++i) scale = fmaxf(scale, refl_v3_length(refl_v3_sub(q[i], q[0])));
    k->hull_count = 0;
    for (i = 0; i < 6; ++i)
        for (j = i + 1; j < 6; ++j)
            for (l = j + 1; l < 6; ++l) {
                refl_vec3 nn = refl_v3_cross(refl_v3_sub(q[j], q[i]), refl_v3_sub(q[l], q[i]));
                float len = refl_v3_length(nn), d, lo = 0.0f, hi = 0.0f, tol;
                if (!(len > 1e-6f * scale * scale)) continue;
                nn = refl_v3_scale(nn, 1.0f / len);
                d = refl_v3_dot(nn, q[i]);
                for (m = 0; m < 6; ++m) {
                    float s = refl_v3_dot(nn, q[m]) - d;
                    lo = fminf(lo, s);
                    hi = fmaxf(hi, s);
                }
                tol = 1e-4f * scale;
                if (hi > tol && lo < -tol) continue; /* points on both sides */
                if (hi > tol) { /* all on the positive side: face the other way */
                    nn = refl_v3_scale(nn, -1.0f);
                    d = -d;
                }
                k->hull[k->hull_count][0] = nn.x;
                k->hull[k->hull_count][1] = nn.y;
                k->hull[k->hull_count][2] = nn.z;
                k->hull[k->hull_count][3] = d + 1e-3f * scale;
                k->hull_count++;
            }
}

/* Whether the base pass shows a back face of object o (an open mesh's
   inside) in the screen box (x0, y0)-(x1, y1), as the CPU path's
   refl__c3_back_seen asks; boxes over 4096 pixels are not scanned. */
static int rgl__c3_back_seen(const rgl_pass *p, int o, float x0, float y0, float x1, float y1) {
    int xa = (int)fmaxf(floorf(x0), 0.0f), ya = (int)fmaxf(floorf(y0), 0.0f);
    int xb = (int)fminf(floorf(x1) + 1.0f, (float)p->w), yb = (int)fminf(floorf(y1) + 1.0f, (float)p->h), x, y;
    if ((long long)(xb - xa) * (yb - ya) > 4096) return 1;
    for (y = ya; y < yb; ++y)
        for (x = xa; x < xb; ++x) {
            size_t i = (size_t)y * p->w + x;
            if (p->marks[i] == o + 1 && p->base[1][4 * i + 3] > 0.5f) return 1;
        }
    return 0;
}

/* View camera vc for drawing: 0 where it lies off the screen, or its side
   seen is the back and the base pass shows none of its object's back
   faces about it (the CPU path draws an open mesh's inside so). */
static int rgl__c3_camera(const rgl_pass *p, const refl_c3rc_view_camera *vc, float tmax, rgl_c3_cam *k) {
    float sx[3], sy[3], intervals[4][2];
    int i;
    if (!(vc->screen_area > 0.0f)) return 0; /* (an area: its corners lie before the eye) */
    for (i = 0; i < 3; ++i) {
        refl_vec3 q = refl_mat4_point(p->vp, vc->cam.v[i]);
        sx[i] = (q.x + 1.0f) * 0.5f * (float)p->w;
        sy[i] = (1.0f - q.y) * 0.5f * (float)p->h;
    }
    if ((sx[0] < 0 && sx[1] < 0 && sx[2] < 0) || (sy[0] < 0 && sy[1] < 0 && sy[2] < 0) ||
        (sx[0] > p->w && sx[1] > p->w && sx[2] > p->w) || (sy[0] > p->h && sy[1] > p->h && sy[2] > p->h))
        return 0;
    if (vc->back && !rgl__c3_back_seen(p, vc->object, fminf(sx[0], fminf(sx[1], sx[2])), fminf(sy[0], fminf(sy[1], sy[2])),
                                       fmaxf(sx[0], fmaxf(sx[1], sx[2])), fmaxf(sy[0], fmaxf(sy[1], sy[2]))))
        return 0;
    k->view = *vc;
    k->cam = vc->cam;
    k->object = vc->object;
    k->back = vc->back;
    k->near_self = vc->near_self;
    k->screen_area = vc->screen_area;
    k->screen_edge = vc->screen_edge;
    k->sweep = vc->sweep;
    k->folds = refl_c3rc_multiple_intervals(&k->cam, fminf(k->sweep, 4.0f * tmax), intervals);
    k->fold = k->folds > 0 ? intervals[0][0] : INFINITY;
    k->hull_count = 0;
    if (k->sweep < FLT_MAX) rgl__c3_hull(k, k->sweep);
    k->plane_n = refl_v3_normalize(refl_v3_cross(refl_v3_sub(k->cam.v[1], k->cam.v[0]), refl_v3_sub(k->cam.v[2], k->cam.v[0])));
    k->edge = 0.0f;
    for (i = 0; i < 3; ++i) k->edge = fmaxf(k->edge, refl_v3_length(refl_v3_sub(k->cam.v[(i + 1) % 3], k->cam.v[i])));
    return 1;
}

/* The leaves a camera's box test keeps, each thinned as the CPU path
   thins it (refl_c3rc_view_camera_lod at the frame's density: a prefix of
   its shuffled points where the camera minifies it), as runs of the
   tree's order (leaves next to each other go in one draw call), appended
   to a list. */
typedef struct rgl_c3_runs {
    const rgl_c3_cam *k;
    float density;           /* the frame's, before the magnified objects' raise */
    int *run;                /* first, count pairs */
    long long count, cap;
    int failed;
} rgl_c3_runs;

static int rgl__c3_box(void *user, const float lo[3], const float hi[3]) {
    const rgl_c3_runs *q = (const rgl_c3_runs *)user;
    return refl_c3rc_box_visible(&q->k->cam, refl_v3(lo[0], lo[1], lo[2]), refl_v3(hi[0], hi[1], hi[2]), q->k->sweep);
}

static void rgl__c3_leaf(void *user, const refl_kdtree *tree, const refl_kdtree_node *leaf) {
    rgl_c3_runs *q = (rgl_c3_runs *)user;
    int count = refl_c3rc_view_camera_lod(&q->k->view, leaf->lo, leaf->hi, leaf->count, q->density);
    (void)tree;
    if (count <= 0 || q->failed) return;
    if (q->count > 0 && q->run[2 * q->count - 2] + q->run[2 * q->count - 1] == leaf->first) {
        q->run[2 * q->count - 1] += count;
        return;
    }
    if (q->count == q->cap) {
        int *nr = (int *)realloc(q->run, (size_t)(q->cap ? 2 * q->cap : 1024) * 2 * sizeof(int));
        if (!nr) {
            q->failed = 1;
            return;
        }
        q->run = nr;
        q->cap = q->cap ? 2 * q->cap : 1024;
    }
    q->run[2 * q->count] = leaf->first;
    q->run[2 * q->count + 1] = count;
    q->count++;
}

int rgl_render_c3rc(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame, float *rgb,
                    rgl_frame_stats *st, char *err, size_t n) {
    static const char *const vs_parts[3] = {rgl__c3_vs_head, NULL, rgl__c3_vs_main};
    static const int point_sizes[3] = {4, 4, 1}; /* RGL_C3_POINT_FLOATS: a_p, a_n, a_density */
    const char *vs[3], *fs[1] = {rgl__c3_fs};
    int w = view->width, h = view->height, rc = -1, x, y;
    size_t i;
    float *cam_data = NULL, *density = NULL, tmax, frame_density, wanted_density, scaled_down = 1.0f;
    rgl_c3_cam *cams = NULL;
    rgl_c3_points pts;
    rgl_c3_keys keys;
    refl_bvh *bvh = NULL;
    rgl_method_pass m;
    const rgl_pass *ps = &m.ps;
    const uint8_t *mark;
    GLuint prog;
    refl_vec3 lo, hi;
    long long cam_count = 0, t, floats;
    double t1;
    memset(&pts, 0, sizeof pts);
    memset(&keys, 0, sizeof keys);
    if (rgl_method_begin(&m, scene, view, frame, st, err, n) != 0) goto done;
    mark = m.mark;
    frame_density = rgl__c3_density(ps, &wanted_density);
    refl_scene_bounds(scene, &lo, &hi);
    tmax = refl_v3_length(refl_v3_sub(hi, lo)) * 1.01f + 1e-3f; /* the longest sweep: the scene's diagonal */
    /* the CPU's share: points, cameras (timed apart from GL) */
    t1 = rgl_now();
    {
        refl_c3rc_view_camera *vcams = NULL;
        int vcount = 0;
        if (refl_c3rc_view_cameras(scene, view, 0.0f, &vcams, &vcount) != REFL_OK) goto oom;
        cams = (rgl_c3_cam *)malloc((size_t)(vcount ? vcount : 1) * sizeof *cams);
        if (!cams) {
            refl_c3rc_view_cameras_free(scene, vcams);
            goto oom;
        }
        for (t = 0; t < vcount; ++t)
            if (vcams[t].object < 254 && mark[vcams[t].object] &&
                rgl__c3_camera(ps, &vcams[t], tmax, &cams[cam_count]))
                vcams[cam_count++] = vcams[t];
        /* the points: denser on the objects a folding camera magnifies */
        if (!(density = (float *)malloc((size_t)(scene->object_count > 0 ? scene->object_count : 1) * sizeof(float))) ||
            refl_c3rc_object_densities(scene, vcams, (int)cam_count, frame_density, density, &scaled_down) != REFL_OK ||
            rgl__c3_points(ps, density, &pts) != 0) {
            refl_c3rc_view_cameras_free(scene, vcams);
            snprintf(err, n, "sampling the scene's points failed");
            goto done;
        }
        refl_c3rc_view_cameras_free(scene, vcams);
    }
    {
        refl_c3rc *list = (refl_c3rc *)malloc((size_t)(cam_count ? cam_count : 1) * sizeof *list);
        if (!list) goto oom;
        for (t = 0; t < cam_count; ++t) list[t] = cams[t].cam;
        floats = refl_gl_pack_c3rc(list, (int)cam_count, NULL, 0);
        cam_data = floats > 0 ? (float *)malloc((size_t)floats * sizeof(float)) : NULL;
        if (!cam_data || refl_gl_pack_c3rc(list, (int)cam_count, cam_data, floats) != floats) {
            free(list);
            snprintf(err, n, "refl_gl_pack_c3rc refused %lld cameras", cam_count);
            goto done;
        }
        free(list);
    }
    m.t_cpu += rgl_now() - t1;
    vs[0] = vs_parts[0];
    vs[1] = refl_gl_glsl(REFL_GL_C3RC);
    vs[2] = vs_parts[2];
    if (!(m.prog = prog = rgl_program(vs, 3, fs, 1, NULL, 0, err, n))) goto done;
    if (rgl_method_data(&m, cam_data, floats, err, n) != 0) goto done;
    st->points = pts.tree->point_count;
    rgl_pass_vertices(pts.gl, pts.tree->point_count, RGL_C3_POINT_FLOATS, point_sizes, 3, &m.vao, &m.vbo);
    /* the splats: nearest t wins, within each reflector's own pixels */
    if (rgl_pass_reflect_begin(ps, prog, m.ray_tex) != 0) goto oom;
    rgl.Enable(GL_PROGRAM_POINT_SIZE);
    rgl.Uniform1f(rgl.GetUniformLocation(prog, "u_tmax"), tmax);
    rgl.Uniform1f(rgl.GetUniformLocation(prog, "u_pixel_angle"), rgl_pass_pixel_angle(ps));
    rgl.Uniform3f(rgl.GetUniformLocation(prog, "u_eye"), view->eye.x, view->eye.y, view->eye.z);
    {
        GLint u_cam = rgl.GetUniformLocation(prog, "u_cam"), u_area = rgl.GetUniformLocation(prog, "u_screen_area");
        GLint u_near = rgl.GetUniformLocation(prog, "u_near_self"), u_obj = rgl.GetUniformLocation(prog, "u_object");
        GLint u_hull = rgl.GetUniformLocation(prog, "u_hull"), u_hull_count = rgl.GetUniformLocation(prog, "u_hull_count");
        GLint u_fold = rgl.GetUniformLocation(prog, "u_fold"), u_fold_splat = rgl.GetUniformLocation(prog, "u_fold_splat");
        GLint u_side = rgl.GetUniformLocation(prog, "u_side"), u_plane_n = rgl.GetUniformLocation(prog, "u_plane_n");
        GLint u_edge = rgl.GetUniformLocation(prog, "u_edge");
        rgl_c3_runs q;
        long long *runs_end = (long long *)malloc((size_t)(cam_count ? cam_count : 1) * sizeof(long long)), r = 0;
        memset(&q, 0, sizeof q);
        q.density = frame_density;
        if (!runs_end) goto oom;
        /* the CPU culls: every camera's leaves */
        t1 = rgl_now();
        for (t = 0; t < cam_count; ++t) {
            q.k = &cams[t];
            refl_kdtree_query(pts.tree, rgl__c3_box, rgl__c3_leaf, &q);
            runs_end[t] = q.count;
        }
        m.t_cpu += rgl_now() - t1;
        if (q.failed) {
            free(q.run);
            free(runs_end);
            goto oom;
        }
        /* GL projects and splats */
        for (t = 0; t < cam_count; ++t) {
            int instances = cams[t].folds > 0 ? 3 : 1;
            rgl.Uniform1i(u_cam, (GLint)t);
            rgl.Uniform1f(u_area, cams[t].screen_area);
            rgl.Uniform1f(u_near, cams[t].near_self);
            rgl.Uniform1i(u_obj, cams[t].object);
            rgl.Uniform1f(u_side, cams[t].back ? -1.0f : 1.0f);
            rgl.Uniform3f(u_plane_n, cams[t].plane_n.x, cams[t].plane_n.y, cams[t].plane_n.z);
            rgl.Uniform1f(u_edge, cams[t].edge);
            rgl.Uniform1i(u_hull_count, cams[t].hull_count);
            if (cams[t].hull_count) rgl.Uniform4fv(u_hull, cams[t].hull_count, cams[t].hull[0]);
            rgl.Uniform1f(u_fold, cams[t].fold < 1e30f ? cams[t].fold : 1e30f);
            rgl.Uniform1f(u_fold_splat, fmaxf(8.0f, ceilf(2.0f * cams[t].screen_edge)));
            rgl.StencilFunc(GL_EQUAL, mark[cams[t].object], 0xFF);
            for (; r < runs_end[t]; ++r) {
                rgl.DrawArraysInstanced(GL_POINTS, q.run[2 * r], q.run[2 * r + 1], instances);
                st->vertices += (long long)q.run[2 * r + 1] * instances;
                st->projections += q.run[2 * r + 1];
            }
        }
        free(q.run);
        free(runs_end);
    }
    rgl.Disable(GL_PROGRAM_POINT_SIZE);
    if (rgl_method_read(&m, 1, "drawing the C3RC splats", err, n) != 0) goto done;
    st->gl_seconds = rgl_now() - m.t0 - m.t_cpu;
    st->mirrors = (int)cam_count;

    /* composite on the CPU; the gaps of nearer points traced, as the CPU path */
    t1 = rgl_now();
    {
        /* the points lie this much farther apart than the view wants (the
           density's cap, the budget of the raised densities): wider gaps */
        float spacing = frame_density > 0.0f && wanted_density > frame_density ? sqrtf(wanted_density / frame_density)
                                                                                : 1.0f;
        if (rgl__c3_resolve(ps, &pts, m.drawn[0], spacing * sqrtf(scaled_down), &keys) != 0) goto oom;
    }
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            uint64_t key;
            long long at;
            i = (size_t)y * w + x;
            key = keys.shown[i];
            if (ps->marks[i] && refl_c3rc_in_gap(&keys.splats, x, y, key)) {
                const float *bp = ps->base[0] + 4 * i, *bn = ps->base[1] + 4 * i;
                float tp[4], tn[4] = {0, 0, 0, 0}, tuv[4] = {0, 0, 0, 0}, col[3];
                refl_vec3 dir = rgl_reflect(rgl_pass_ray(ps, (int)i), refl_v3(bn[0], bn[1], bn[2]));
                if (!bvh && refl_bvh_build(scene, NULL, &bvh) != REFL_OK) goto oom;
                rgl_trace(ps, bvh, refl_v3(bp[0], bp[1], bp[2]), dir, tp, tn, tuv);
                rgl_shade(scene, tp, tn, tuv, dir, col);
                rgl_composite(ps, (int)i, (int)tp[3] >= 1 ? col : NULL, tp, frame, rgb);
                st->traced++;
                continue;
            }
            at = key == ~(uint64_t)0 ? -1 : (long long)(key & 0xffffffffu);
            rgl_composite(ps, (int)i, at >= 0 ? pts.rgb + 3 * at : NULL, at >= 0 ? pts.tree->positions + 3 * at : NULL,
                          frame, rgb);
        }
    rc = rgl_method_finish(&m, frame, rgb, st, t1, err, n);
    goto done;
oom:
    snprintf(err, n, "out of memory");
done:
    rgl__c3_points_free(&pts);
    rgl__c3_keys_free(&keys);
    refl_bvh_destroy(bvh);
    free(cams);
    free(cam_data);
    free(density);
    return rgl_method_end(g, &m, rc);
}
