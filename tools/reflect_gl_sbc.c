/* reflect_gl_sbc.c - a frame of SBC through GL (reflect_gl.h, docs/gl.md).
     1. the base pass (reflect_gl_frame.c): each reflector marks its pixels
        with its object number;
     2. per reflector, a ray map from the read-back G-buffer (one reflected
        ray per 2 x 2 pixels, the CPU path's default factor; its head where
        it leaves the scene's box, as SBC-paper has it) cut at creases
        (neighbours linked where their normals are within 45 degrees) and
        its sample-based camera built (refl_sbc_build, 1 px error);
     3. the scene's other objects, their triangles split to at most 1/64 of
        the scene's diagonal (the CPU path splits projected triangles; a
        vertex program cannot), drawn through the SBC hook
        (refl_sbc_project in the vertex shader: the reflector point each
        vertex shows, the visibility offset as depth), stencilled to the
        reflector's pixels; a triangle with a vertex no leaf projects is
        dropped;
     4. the CPU composites as the CPU path's resolve does with
        trace_fallback (SBC-traced): reflectance times what was drawn, and
        each reflector pixel nothing was drawn on, whose nearest fragment
        lies off the pixel's reflected ray, or whose drawn point the ray
        meets something before (one occlusion ray), traced (refl_bvh)
        after the read-back, the environment where the trace leaves the
        scene.
   One bounce; glass is drawn as DIRECT draws it. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "reflect_gl.h"

#include <EGL/egl.h>
#include <GL/gl.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "reflect_gl_funcs.h"
#include "reflect_gl_frame.h"

#define RGL_SB_FACTOR 2          /* ray map samples per pixel side, as the CPU path's default */
#define RGL_SB_SPLIT 64.0f       /* triangles split to at most the scene's diagonal over this */
#define RGL_SB_RAY_TOL "3.0"     /* a fragment's distance from its pixel's ray, in the ray's spread */
#define RGL_SB_TILE 16           /* a tile's side in ray map samples, as the CPU path's groups */
#define RGL_SB_OWN_NEAR 0.25f    /* the reflector's own vertex this near (in edges) its image: its surface */
#define RGL_SB_CREASE 0.70710678f /* cos 45 degrees: neighbours on one smooth piece */

static const char rgl__sb_vs_main[] =
    "uniform mat4 u_vp;\n"
    "uniform float u_zscale;\n"
    "uniform vec3 u_box_lo, u_box_hi, u_first_lo, u_first_hi;\n"
    "uniform int u_object;\n"
    "uniform float u_own_near;\n"
    "out float v_ok;\n"
    "void main() {\n"
    "    vec3 first; float z; int kind;\n"
    "    v_p = a_p; v_n = a_n; v_uv = a_uv_id.xy; v_id = a_uv_id.z;\n"
    "    v_ok = 0.0;\n"
    "    gl_Position = vec4(0.0, 0.0, 2.0, 1.0);\n"
    /* as the CPU path: a vertex inside the rays' box, its image on the reflector's
       (a leaf's map far outside its rays sends points anywhere) */
    "    if (any(lessThan(a_p, u_box_lo)) || any(greaterThan(a_p, u_box_hi))) return;\n"
    "    if (!refl_sbc_project(u_data, u_base, a_p, first, z, kind)) return;\n"
    "    if (any(lessThan(first, u_first_lo)) || any(greaterThan(first, u_first_hi))) return;\n"
    /* the reflector's own surface the rays leave (near its own image) is not drawn;
       farther parts of it are (the knob seen in the lid) */
    "    if (int(a_uv_id.z) == u_object + 1 && distance(a_p, first) < u_own_near) return;\n"
    "    vec4 clip = u_vp * vec4(first, 1.0);\n"
    "    v_ok = 1.0;\n"
    "    gl_Position = vec4(clip.xy, (2.0 * clamp(z * u_zscale, 0.0, 1.0) - 1.0) * clip.w, clip.w);\n"
    "}\n";

/* A fragment shows only what lies near its pixel's own reflected ray
   (rgl_pass_ray_textures): within RGL_SB_RAY_TOL times the larger of the
   pixel's angle and its ray's turn to its neighbours', per unit of
   distance along it. Where the nearest fragment lies farther off (a
   reflected triangle spanning leaves that send its vertices far apart,
   or interpolated across a strongly bent image) the pixel is marked
   contradicted (-1) and traced, as the CPU path traces contradicted
   pixels; the mark keeps its depth, so nothing behind it shows. */
static const char rgl__sb_fs[] =
    "#version 330 core\n"
    "in vec3 v_p; in vec3 v_n; in vec2 v_uv; flat in float v_id; in float v_ok;\n"
    "uniform sampler2D u_surf, u_ray;\n"
    "uniform float u_pixel_angle, u_own_near;\n"
    "uniform int u_object;\n"
    "layout(location = 0) out vec4 o_point;\n"
    "layout(location = 1) out vec4 o_normal;\n"
    "layout(location = 2) out vec4 o_uv;\n"
    "void main() {\n"
    "    if (v_ok < 0.999) discard;\n" /* a vertex no leaf projects */
    "    ivec2 px = ivec2(gl_FragCoord.xy);\n"
    "    vec4 r = texelFetch(u_surf, px, 0);\n"
    "    vec3 u = texelFetch(u_ray, px, 0).xyz, w = v_p - r.xyz;\n"
    "    float s = dot(w, u);\n"
    /* the reflector's own surface where the ray leaves it (grazing at a silhouette) */
    "    if (int(v_id) == u_object + 1 && s < u_own_near) discard;\n"
    "    if (!(s > 0.0) || length(w - s * u) > " RGL_SB_RAY_TOL " * max(r.w, u_pixel_angle) * s) {\n"
    "        o_point = vec4(0.0, 0.0, 0.0, -1.0);\n" /* contradicted: traced, and hides what lies behind */
    "        o_normal = vec4(0.0); o_uv = vec4(0.0);\n"
    "        return;\n"
    "    }\n"
    "    o_point = vec4(v_p, v_id); o_normal = vec4(v_n, 0.0); o_uv = vec4(v_uv, 0.0, 0.0);\n"
    "}\n";

/* The scene's triangles split to edges of at most `len`: each triangle into
   k x k, k from its longest edge (RGL_VERTEX_FLOATS per vertex, the
   attributes interpolated). first: per object, and one past the last. */
static float *rgl__sb_split(const rgl_geometry *geo, int objects, float len, long long *first) {
    long long total = 0, at = 0, i;
    float *out = NULL;
    int o, pass;
    for (pass = 0; pass < 2; ++pass) {
        if (pass == 1 && !(out = (float *)malloc((size_t)(total ? total : 1) * RGL_VERTEX_FLOATS * sizeof(float))))
            return NULL;
        for (o = 0; o < objects; ++o) {
            if (pass) first[o] = at;
            for (i = geo->first[o]; i + 2 < geo->first[o + 1]; i += 3) {
                const float *a = geo->v + i * RGL_VERTEX_FLOATS, *c[3];
                float e = 0.0f;
                int k, j, r, s, q;
                c[0] = a;
                c[1] = a + RGL_VERTEX_FLOATS;
                c[2] = a + 2 * RGL_VERTEX_FLOATS;
                for (j = 0; j < 3; ++j) {
                    const float *p0 = c[j], *p1 = c[(j + 1) % 3];
                    e = fmaxf(e, sqrtf((p1[0] - p0[0]) * (p1[0] - p0[0]) + (p1[1] - p0[1]) * (p1[1] - p0[1]) +
                                       (p1[2] - p0[2]) * (p1[2] - p0[2])));
                }
                k = (int)fminf(ceilf(e / len), 64.0f);
                k = k < 1 ? 1 : k;
                if (!pass) {
                    total += 3LL * k * k;
                    continue;
                }
                /* sub-triangles of the k x k grid in barycentrics (r, s) / k */
                for (r = 0; r < k; ++r)
                    for (s = 0; s < k - r; ++s)
                        for (q = 0; q < (s + r + 1 < k ? 2 : 1); ++q) {
                            int tri[3][2];
                            if (!q) {
                                tri[0][0] = r; tri[0][1] = s; tri[1][0] = r + 1; tri[1][1] = s;
                                tri[2][0] = r; tri[2][1] = s + 1;
                            } else {
                                tri[0][0] = r + 1; tri[0][1] = s; tri[1][0] = r + 1; tri[1][1] = s + 1;
                                tri[2][0] = r; tri[2][1] = s + 1;
                            }
                            for (j = 0; j < 3; ++j) {
                                float b1 = (float)tri[j][0] / (float)k, b2 = (float)tri[j][1] / (float)k, b0 = 1.0f - b1 - b2;
                                float *v = out + at * RGL_VERTEX_FLOATS;
                                int f;
                                for (f = 0; f < RGL_VERTEX_FLOATS - 1; ++f) v[f] = b0 * c[0][f] + b1 * c[1][f] + b2 * c[2][f];
                                v[RGL_VERTEX_FLOATS - 1] = c[0][RGL_VERTEX_FLOATS - 1];
                                ++at;
                            }
                        }
            }
        }
    }
    first[objects] = at;
    return out;
}

/* The longest edge of the triangles from vertex first to end. */
static float rgl__sb_longest_edge(const float *v, long long first, long long end) {
    float e = 0.0f;
    long long i;
    int j;
    for (i = first; i + 2 < end; i += 3)
        for (j = 0; j < 3; ++j) {
            const float *a = v + (i + j) * RGL_VERTEX_FLOATS, *b = v + (i + (j + 1) % 3) * RGL_VERTEX_FLOATS;
            e = fmaxf(e, sqrtf((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2])));
        }
    return e;
}

/* Reflector object o's SBC over the ray map samples tile[0] <= u <
   tile[2], tile[1] <= v < tile[3], from the G-buffer: 0 and *out, or
   nonzero (*out NULL when none of its samples there is seen). */
/* box[0..1]: the rays' tails and heads, grown by a quarter; box[2..3]: the
   tails, grown by a hundredth of that (the CPU path's group boxes). */
static int rgl__sb_build(const rgl_pass *p, int o, const int tile[4], refl_vec3 lo, refl_vec3 hi, refl_sbc **out,
                         refl_vec3 box[4]) {
    int mw = tile[2] - tile[0], mh = tile[3] - tile[1], u, v, any = 0;
    size_t nm = (size_t)mw * (size_t)mh;
    refl_sbc_ray *rays = (refl_sbc_ray *)calloc(nm, sizeof *rays);
    uint8_t *valid = (uint8_t *)calloc(nm, 1), *links = (uint8_t *)calloc(nm, 1);
    float *nrm = (float *)calloc(nm, 3 * sizeof(float));
    refl_sbc_desc d;
    int rc = -1;
    *out = NULL;
    if (!rays || !valid || !links || !nrm) goto done;
    for (v = 0; v < mh; ++v)
        for (u = 0; u < mw; ++u) {
            int x = (tile[0] + u) * RGL_SB_FACTOR + RGL_SB_FACTOR / 2, y = (tile[1] + v) * RGL_SB_FACTOR + RGL_SB_FACTOR / 2;
            int i, k;
            size_t m = (size_t)v * mw + u;
            const float *bp, *bn;
            refl_vec3 q, dir, inv;
            float t_far = INFINITY;
            x = x < p->w - 1 ? x : p->w - 1;
            y = y < p->h - 1 ? y : p->h - 1;
            i = y * p->w + x;
            bp = p->base[0] + 4 * (size_t)i;
            bn = p->base[1] + 4 * (size_t)i;
            if (p->marks[i] != o + 1 || (int)bp[3] != o + 1) continue;
            q = refl_v3(bp[0], bp[1], bp[2]);
            dir = rgl_reflect(rgl_pass_ray(p, i), refl_v3(bn[0], bn[1], bn[2]));
            inv = refl_v3(1.0f / dir.x, 1.0f / dir.y, 1.0f / dir.z);
            for (k = 0; k < 3; ++k) { /* where the ray leaves the box */
                float qa = (&q.x)[k], ia = (&inv.x)[k], lo_k = (&lo.x)[k], hi_k = (&hi.x)[k];
                float t = ia > 0.0f ? (hi_k - qa) * ia : (lo_k - qa) * ia;
                if (t == t && t < t_far) t_far = t;
            }
            if (!(t_far > 0.0f) || !isfinite(t_far)) continue;
            rays[m].tail = rays[m].first = q;
            rays[m].head = refl_v3_add(q, refl_v3_scale(dir, t_far));
            valid[m] = 1;
            memcpy(nrm + 3 * m, bn, 3 * sizeof(float));
            any = 1;
        }
    if (!any) {
        rc = 0;
        goto done;
    }
    box[0] = box[2] = refl_v3(INFINITY, INFINITY, INFINITY);
    box[1] = box[3] = refl_v3(-INFINITY, -INFINITY, -INFINITY);
    for (u = 0; u < (int)nm; ++u) {
        int k;
        if (!valid[u]) continue;
        for (k = 0; k < 3; ++k) {
            float ta = (&rays[u].tail.x)[k], he = (&rays[u].head.x)[k];
            (&box[0].x)[k] = fminf((&box[0].x)[k], fminf(ta, he));
            (&box[1].x)[k] = fmaxf((&box[1].x)[k], fmaxf(ta, he));
            (&box[2].x)[k] = fminf((&box[2].x)[k], ta);
            (&box[3].x)[k] = fmaxf((&box[3].x)[k], ta);
        }
    }
    {
        refl_vec3 g0 = refl_v3_scale(refl_v3_sub(box[1], box[0]), 0.25f), g1 = refl_v3_scale(g0, 0.04f);
        box[0] = refl_v3_sub(box[0], g0);
        box[1] = refl_v3_add(box[1], g0);
        box[2] = refl_v3_sub(box[2], g1);
        box[3] = refl_v3_add(box[3], g1);
    }
    for (v = 0; v < mh; ++v) /* neighbours on one smooth piece */
        for (u = 0; u < mw; ++u) {
            size_t m = (size_t)v * mw + u, nb[2] = {m + 1, m + (size_t)mw};
            int k;
            for (k = 0; k < 2; ++k) {
                const float *a = nrm + 3 * m, *b;
                if ((k == 0 && u + 1 >= mw) || (k == 1 && v + 1 >= mh) || !valid[m] || !valid[nb[k]]) continue;
                b = nrm + 3 * nb[k];
                if (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] >=
                    RGL_SB_CREASE * sqrtf((a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) * (b[0] * b[0] + b[1] * b[1] + b[2] * b[2])))
                    links[m] |= (uint8_t)(1 << k);
            }
        }
    memset(&d, 0, sizeof d);
    d.error_px = 1.0f;
    d.view_proj = p->vp;
    d.width = p->w;
    d.height = p->h;
    d.links = links;
    rc = refl_sbc_build(rays, valid, mw, mh, &d, out) == REFL_OK ? 0 : -1;
done:
    free(rays);
    free(valid);
    free(links);
    free(nrm);
    return rc;
}

/* Whether the point drawn at a reflector pixel (q its surface point, dir
   its reflected ray) lies behind something the ray meets first: the
   SBC-traced check of the CPU path (a self-reflection the projection
   missed, the knob in the lid, lets what lies behind it through). */
static int rgl__sb_hidden(const refl_bvh *bvh, refl_vec3 q, refl_vec3 dir, const float *drawn) {
    float s = refl_v3_dot(refl_v3_sub(refl_v3(drawn[0], drawn[1], drawn[2]), q), dir);
    return s > 0.0f && refl_bvh_occluded(bvh, q, dir, 1e-4f, 0.99f * s);
}

/* One tile of reflector o: its camera built and packed, the scene's other
   objects drawn through it into the tile's pixels of the reflector. */
static int rgl__sb_draw_tile(rgl_method_pass *m, int o, float own_near, const int tile[4], int tu, int tv, refl_vec3 lo,
                             refl_vec3 hi, const long long *first, float **data, rgl_frame_stats *st, char *err,
                             size_t n) {
    const rgl_pass *p = &m->ps;
    GLuint prog = m->prog;
    refl_sbc *sbc = NULL;
    refl_vec3 box[4];
    long long floats;
    double t1 = rgl_now();
    int k, x0 = tu * RGL_SB_FACTOR, y0 = tv * RGL_SB_FACTOR, side = RGL_SB_TILE * RGL_SB_FACTOR;
    if (rgl__sb_build(p, o, tile, lo, hi, &sbc, box) != 0) {
        snprintf(err, n, "refl_sbc_build failed for object %d", o);
        return -1;
    }
    if (!sbc) {
        m->t_cpu += rgl_now() - t1;
        return 0;
    }
    floats = refl_gl_pack_sbc(sbc, NULL, 0);
    free(*data);
    *data = floats > 0 ? (float *)malloc((size_t)floats * sizeof(float)) : NULL;
    if (!*data || refl_gl_pack_sbc(sbc, *data, floats) != floats) {
        refl_sbc_destroy(sbc);
        snprintf(err, n, "refl_gl_pack_sbc refused object %d's camera", o);
        return -1;
    }
    refl_sbc_destroy(sbc);
    m->t_cpu += rgl_now() - t1;
    if (rgl_method_data(m, *data, floats, err, n) != 0) return -1;
    rgl.Uniform3f(rgl.GetUniformLocation(prog, "u_box_lo"), box[0].x, box[0].y, box[0].z);
    rgl.Uniform3f(rgl.GetUniformLocation(prog, "u_box_hi"), box[1].x, box[1].y, box[1].z);
    rgl.Uniform3f(rgl.GetUniformLocation(prog, "u_first_lo"), box[2].x, box[2].y, box[2].z);
    rgl.Uniform3f(rgl.GetUniformLocation(prog, "u_first_hi"), box[3].x, box[3].y, box[3].z);
    rgl.StencilFunc(GL_EQUAL, m->mark[o], 0xFF);
    /* GL's rows count from the bottom */
    rgl.Scissor(x0, p->h - (y0 + side), side, side);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_object"), o);
    rgl.Uniform1f(rgl.GetUniformLocation(prog, "u_own_near"), own_near);
    for (k = 0; k < p->scene->object_count; ++k) {
        rgl.DrawArrays(GL_TRIANGLES, (GLint)first[k], (GLsizei)(first[k + 1] - first[k]));
        st->vertices += first[k + 1] - first[k];
    }
    return 0;
}

int rgl_render_sbc(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame, float *rgb,
                   rgl_frame_stats *st, char *err, size_t n) {
    const char *vs[3], *fs[1] = {rgl__sb_fs};
    int w = view->width, h = view->height, o, rc = -1;
    size_t np = (size_t)w * (size_t)h, i;
    GLuint prog;
    float *split = NULL, *data = NULL, diag;
    long long *first = NULL;
    refl_bvh *bvh = NULL;
    rgl_method_pass m;
    const rgl_pass *ps = &m.ps;
    refl_vec3 lo, hi, grow;
    double t1;
    if (rgl_method_begin(&m, scene, view, frame, st, err, n) != 0) goto done;
    refl_scene_bounds(scene, &lo, &hi);
    grow = refl_v3_add(refl_v3_scale(refl_v3_sub(hi, lo), 0.01f), refl_v3(1e-4f, 1e-4f, 1e-4f));
    lo = refl_v3_sub(lo, grow);
    hi = refl_v3_add(hi, grow);
    diag = refl_v3_length(refl_v3_sub(hi, lo));
    t1 = rgl_now();
    if (!(first = (long long *)malloc((size_t)(scene->object_count + 1) * sizeof(long long))) ||
        !(split = rgl__sb_split(&ps->geo, scene->object_count, diag / RGL_SB_SPLIT, first)))
        goto oom;
    m.t_cpu += rgl_now() - t1;
    vs[0] = rgl_frame_vs_head;
    vs[1] = refl_gl_glsl(REFL_GL_SBC);
    vs[2] = rgl__sb_vs_main;
    if (!(m.prog = prog = rgl_program(vs, 3, fs, 1, NULL, 0, err, n))) goto done;
    rgl_pass_vertices(split, first[scene->object_count], RGL_VERTEX_FLOATS, rgl_vertex_sizes, 3, &m.vao, &m.vbo);
    if (rgl_pass_reflect_begin(ps, prog, m.ray_tex) != 0) goto oom;
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_base"), 0);
    rgl.Uniform1f(rgl.GetUniformLocation(prog, "u_zscale"), 0.5f / diag);
    rgl.Uniform1f(rgl.GetUniformLocation(prog, "u_pixel_angle"), rgl_pass_pixel_angle(ps));
    rgl.Enable(GL_SCISSOR_TEST);
    for (o = 0; o < scene->object_count; ++o) {
        int mw = (w + RGL_SB_FACTOR - 1) / RGL_SB_FACTOR, mh = (h + RGL_SB_FACTOR - 1) / RGL_SB_FACTOR, tu, tv;
        float own_near;
        if (!m.mark[o]) continue;
        own_near = RGL_SB_OWN_NEAR * rgl__sb_longest_edge(split, first[o], first[o + 1]);
        st->mirrors++;
        /* tiles of RGL_SB_TILE samples, each with its own camera and boxes
           (the CPU path's groups); a tile's rays reach one sample past it
           on every side, so its pixels all lie between its samples */
        for (tv = 0; tv < mh; tv += RGL_SB_TILE)
            for (tu = 0; tu < mw; tu += RGL_SB_TILE) {
                int tile[4];
                tile[0] = tu > 0 ? tu - 1 : 0;
                tile[1] = tv > 0 ? tv - 1 : 0;
                tile[2] = tu + RGL_SB_TILE + 1 < mw ? tu + RGL_SB_TILE + 1 : mw;
                tile[3] = tv + RGL_SB_TILE + 1 < mh ? tv + RGL_SB_TILE + 1 : mh;
                if (rgl__sb_draw_tile(&m, o, own_near, tile, tu, tv, lo, hi, first, &data, st, err, n) != 0) goto done;
            }
    }
    rgl.Disable(GL_SCISSOR_TEST);
    if (rgl_method_read(&m, 3, "drawing the SBC reflections", err, n) != 0) goto done;
    st->gl_seconds = rgl_now() - m.t0 - m.t_cpu;

    /* composite on the CPU; holes traced */
    t1 = rgl_now();
    for (i = 0; i < np; ++i) {
        const float *pp = m.drawn[0] + 4 * i, *pn = m.drawn[1] + 4 * i, *puv = m.drawn[2] + 4 * i, *bp = ps->base[0] + 4 * i;
        float tp[4], tn[4] = {0, 0, 0, 0}, tuv[4] = {0, 0, 0, 0}, sub[3];
        refl_vec3 dir;
        if (!ps->marks[i]) {
            rgl_composite(ps, (int)i, NULL, NULL, frame, rgb);
            continue;
        }
        dir = rgl_reflect(rgl_pass_ray(ps, (int)i), refl_v3(ps->base[1][4 * i], ps->base[1][4 * i + 1], ps->base[1][4 * i + 2]));
        if (!bvh && refl_bvh_build(scene, NULL, &bvh) != REFL_OK) goto oom;
        if (!((int)pp[3] >= 1) || rgl__sb_hidden(bvh, refl_v3(bp[0], bp[1], bp[2]), dir, pp)) {
            /* a hole, contradicted, or hidden: the fallback traces it */
            rgl_trace(ps, bvh, refl_v3(bp[0], bp[1], bp[2]), dir, tp, tn, tuv);
            pp = tp;
            pn = tn;
            puv = tuv;
        }
        rgl_shade(scene, pp, pn, puv, dir, sub);
        rgl_composite(ps, (int)i, (int)pp[3] >= 1 ? sub : NULL, pp, frame, rgb);
    }
    rc = rgl_method_finish(&m, frame, rgb, st, t1, err, n);
    goto done;
oom:
    snprintf(err, n, "out of memory");
done:
    refl_bvh_destroy(bvh);
    free(split);
    free(first);
    free(data);
    return rgl_method_end(g, &m, rc);
}
