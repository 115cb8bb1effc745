/* reflect_gl_impostor.c - frames of paper 004's impostor methods, SPOC
   and GRAPHCAM, through GL (reflect_gl.h, docs/gl.md): the impostors built
   on the CPU as the CPU methods build them, packed with their GL hooks,
   and intersected in a pixel shader along each reflector pixel's
   reflected ray; what the CPU method does besides the march (its exact
   objects, the rays it hands to its tracer) on the CPU after the
   read-back. SPOC:
     1. the base pass (reflect_gl_frame.c): each mirror and partial
        reflector marks its pixels with its object number;
     2. per reflector seen, its impostors as the CPU method builds them
        (refl_spoc_set_build at spoc's defaults: every compact diffuse
        object whose bounding sphere does not hold the reflector's box
        centre gets a SPOC from there, the rest of the scene exact),
        packed with the SPOC impostor hook (colour and gd per texel of
        every depth layer, the camera, the sphere) into one buffer texture;
     3. per reflector a full-screen triangle, stencilled to its pixels,
        whose fragment shader takes the pixel's reflected ray (from the
        read-back, a hair off the surface as the CPU method starts it) and
        marches every impostor with refl_spoc_impostor_intersect (nearest
        hit kept, later impostors cut at it, as the CPU's loop);
     4. after the read-back the CPU does the rest of the CPU method's
        refl__spoc_trace and refl__spoc_row: the exact part of the scene
        (flat objects, those an SPOC cannot see from the reflector, the
        reflectors, which show as DIRECT draws them) intersected through a
        BVH up to the impostor's hit, and a ray that missed an impostored
        object the scene puts in front (refl__spoc_missed) handed to the
        tracer; then the composite.
   GRAPHCAM: one impostor through the graph camera for every reflector,
   marched with refl_graphcam_impostor_intersect (algorithm 2), then
   m_graphcam.c's billboards and hand-over on the CPU.
   One bounce; glass is drawn as DIRECT draws it, as the other GL paths.
   Also the hooks' marches against the C ray by ray (rgl_validate_*). */
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

/* refl_spoc_options' default march (refl__options_spoc), what the CPU path draws with */
#define RGL_SP_STEP_SCALE 1.0f

/* A full-screen triangle; the stencil keeps the reflector's pixels. */
static const char rgl__sp_vs[] =
    "#version 330 core\n"
    "void main() {\n"
    "    gl_Position = vec4(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0, 0.0, 1.0);\n"
    "}\n";

static const char rgl__sp_fs_head[] = "#version 330 core\n";

/* The reflector's data: texel 0 (impostors, 0, 0, 0), texel 1 + i the
   offset of impostor i's block; each block as refl_gl_pack_spoc_impostor.
   Out: the point met and 1 (0: none), its colour and t, the steps walked
   and the impostor met (-1: none). */
static const char rgl__sp_fs_main[] =
    "uniform samplerBuffer u_data;\n"
    "uniform sampler2D u_org, u_dir;\n"
    "uniform float u_step_scale;\n"
    "layout(location = 0) out vec4 o_point;\n"
    "layout(location = 1) out vec4 o_color;\n"
    "layout(location = 2) out vec4 o_steps;\n"
    "void main() {\n"
    "    ivec2 px = ivec2(gl_FragCoord.xy);\n"
    "    vec3 o = texelFetch(u_org, px, 0).xyz, d = texelFetch(u_dir, px, 0).xyz, shown = vec3(0.0);\n"
    "    int count = int(texelFetch(u_data, 0).x), steps = 0, met = -1;\n"
    "    float best = 3.4e38;\n"
    "    vec4 col = vec4(0.0);\n"
    "    for (int i = 0; i < count; ++i) {\n"
    "        float t; vec3 pt; vec4 c; int layer, n;\n"
    "        if (refl_spoc_impostor_intersect(u_data, int(texelFetch(u_data, 1 + i).x), o, d, 0.0, best, u_step_scale,\n"
    "                                         t, pt, c, layer, n) && t < best) {\n"
    "            best = t; shown = pt; col = c; met = i;\n"
    "        }\n"
    "        steps += n;\n"
    "    }\n"
    "    o_point = vec4(shown, met >= 0 ? 1.0 : 0.0);\n"
    "    o_color = vec4(col.rgb, best);\n"
    "    o_steps = vec4(float(steps), float(met), 0.0, 0.0);\n"
    "}\n";

/* A marching program (the hooks' source, then main), in use, its samplers
   on units 0 (the data), 1 and 2 (the rays' origins and directions); 0
   with the reason in err. */
static GLuint rgl__imp_program(const char *const *parts, int count, char *err, size_t n) {
    const char *vs[1] = {rgl__sp_vs}, *fs[5];
    GLuint prog;
    int i;
    fs[0] = rgl__sp_fs_head;
    for (i = 0; i < count && i < 4; ++i) fs[1 + i] = parts[i];
    if (!(prog = rgl_program(vs, 1, fs, 1 + i, NULL, 0, err, n))) return 0;
    rgl.UseProgram(prog);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_data"), 0);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_org"), 1);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_dir"), 2);
    return prog;
}

static GLuint rgl__sp_program(char *err, size_t n) {
    const char *parts[3];
    GLuint prog;
    parts[0] = refl_gl_glsl(REFL_GL_SPOC);
    parts[1] = refl_gl_glsl(REFL_GL_SPOC_IMPOSTOR);
    parts[2] = rgl__sp_fs_main;
    if ((prog = rgl__imp_program(parts, 3, err, n)))
        rgl.Uniform1f(rgl.GetUniformLocation(prog, "u_step_scale"), RGL_SP_STEP_SCALE);
    return prog;
}

/* Uploads w x h RGBA32F rows (bottom first) as the 2-D texture on unit `unit`. */
static void rgl__sp_texture(GLuint tex, int unit, int w, int h, const float *rgba) {
    rgl.ActiveTexture(GL_TEXTURE0 + unit);
    rgl.BindTexture(GL_TEXTURE_2D, tex);
    rgl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    rgl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    rgl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, w, h, 0, GL_RGBA, GL_FLOAT, rgba);
    rgl.ActiveTexture(GL_TEXTURE0);
}

/* The BVH of the objects keep[] marks (*bvh NULL: none) and its object
   index -> scene object (*map, the caller frees it). Nonzero on failure. */
static int rgl__imp_sub_bvh(const refl_scene *s, const uint8_t *keep, refl_bvh **bvh, int **map) {
    size_t n_obj = (size_t)(s->object_count > 0 ? s->object_count : 1);
    refl_object *objs = (refl_object *)calloc(n_obj, sizeof *objs);
    int i, n = 0, rc = -1;
    *bvh = NULL;
    *map = (int *)calloc(n_obj, sizeof **map);
    if (objs && *map) {
        refl_scene sub = *s;
        for (i = 0; i < s->object_count; ++i)
            if (keep[i]) {
                (*map)[n] = i;
                objs[n++] = s->objects[i];
            }
        sub.objects = objs;
        sub.object_count = n;
        rc = n && refl_bvh_build(&sub, NULL, bvh) != REFL_OK ? -1 : 0;
    }
    free(objs);
    return rc;
}

/* The set's impostors packed for the fragment shader (rgl__sp_fs_main's
   layout); NULL when out of memory or refused. */
static float *rgl__sp_pack(const refl_spoc_set *set, long long *floats) {
    long long at = 4LL * (1 + set->imp_count), need = at, k;
    float *data;
    int i;
    for (i = 0; i < set->imp_count; ++i) {
        if ((k = refl_gl_pack_spoc_impostor(set->imps[i], &set->cams[i], NULL, 0)) < 0) return NULL;
        need += k;
    }
    if (!(data = (float *)calloc((size_t)need, sizeof(float)))) return NULL;
    data[0] = (float)set->imp_count;
    for (i = 0; i < set->imp_count; ++i) {
        data[4 * (1 + i)] = (float)(at / 4);
        k = refl_gl_pack_spoc_impostor(set->imps[i], &set->cams[i], data + at, need - at);
        at += k;
    }
    *floats = need;
    return data;
}

/* Reflector pixel i's reflected ray as the CPU methods take it: from its
   G-buffer point s, the normal n turned towards the eye, direction r. */
static void rgl__imp_pixel_ray(const rgl_pass *p, size_t i, refl_vec3 *s, refl_vec3 *n, refl_vec3 *r) {
    const float *bp = p->base[0] + 4 * i, *bn = p->base[1] + 4 * i;
    refl_vec3 d = rgl_pass_ray(p, (int)i);
    *n = refl_v3_normalize(refl_v3(bn[0], bn[1], bn[2]));
    if (refl_v3_dot(*n, *n) == 0.0f) *n = refl_v3_scale(d, -1.0f);
    if (refl_v3_dot(d, *n) > 0.0f) *n = refl_v3_scale(*n, -1.0f);
    *s = refl_v3(bp[0], bp[1], bp[2]);
    *r = refl_v3_reflect(d, *n);
}

/* Per reflector pixel, as 2-D RGBA32F textures on units 1 and 2 (rows
   bottom first): its reflected ray's origin, `offset` off the surface on
   the eye's side, and unit direction; the same rays into org and dir
   (rows top first) for the CPU's share. */
static int rgl__sp_rays(const rgl_pass *p, float offset, GLuint tex[2], float *org, float *dir) {
    int w = p->w, h = p->h, x, y, k;
    float *up[2];
    up[0] = (float *)calloc((size_t)w * h, 4 * sizeof(float));
    up[1] = (float *)calloc((size_t)w * h, 4 * sizeof(float));
    if (!up[0] || !up[1]) {
        free(up[0]);
        free(up[1]);
        return -1;
    }
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            size_t i = (size_t)y * w + x, g = (size_t)(h - 1 - y) * w + x;
            refl_vec3 n, o, r;
            if (!p->marks[i]) continue;
            rgl__imp_pixel_ray(p, i, &o, &n, &r);
            o = refl_v3_add(o, refl_v3_scale(n, offset));
            org[3 * i] = up[0][4 * g] = o.x;
            org[3 * i + 1] = up[0][4 * g + 1] = o.y;
            org[3 * i + 2] = up[0][4 * g + 2] = o.z;
            dir[3 * i] = up[1][4 * g] = r.x;
            dir[3 * i + 1] = up[1][4 * g + 1] = r.y;
            dir[3 * i + 2] = up[1][4 * g + 2] = r.z;
        }
    rgl.GenTextures(2, tex);
    for (k = 0; k < 2; ++k) rgl__sp_texture(tex[k], 1 + k, w, h, up[k]);
    free(up[0]);
    free(up[1]);
    return 0;
}

/* Hit h on scene object `object` as the G-buffer holds a surface (point +
   id, normal, uv: interpolated from the GL geometry's vertices). */
static void rgl__sp_hit_surface(const rgl_pass *p, int object, const refl_hit *h, float pt[4], float nrm[4],
                                float uv[4]) {
    const float *a = p->geo.v + (p->geo.first[object] + 3 * (long long)h->triangle) * RGL_VERTEX_FLOATS;
    const float *b = a + RGL_VERTEX_FLOATS, *c = b + RGL_VERTEX_FLOATS;
    float w0 = 1.0f - h->u - h->v;
    int f;
    memset(uv, 0, 4 * sizeof(float));
    for (f = 0; f < 3; ++f) {
        pt[f] = w0 * a[f] + h->u * b[f] + h->v * c[f];
        nrm[f] = w0 * a[3 + f] + h->u * b[3 + f] + h->v * c[3 + f];
    }
    nrm[3] = 0.0f;
    for (f = 0; f < 2; ++f) uv[f] = w0 * a[6 + f] + h->u * b[6 + f] + h->v * c[6 + f];
    pt[3] = (float)(object + 1);
}

/* A scene surface's colour as a reflection shows it (refl__exact_hit_shade,
   one bounce: the diffuse share, a mirror black), clamped to [0, 1]. */
static void rgl__sp_shade_hit(const rgl_pass *p, int object, const refl_hit *h, refl_vec3 dir, float rgb[3],
                              float at[3]) {
    float pt[4], nrm[4], uv[4];
    int c;
    rgl__sp_hit_surface(p, object, h, pt, nrm, uv);
    rgl_shade(p->scene, pt, nrm, uv, dir, rgb);
    for (c = 0; c < 3; ++c) {
        rgb[c] = fminf(rgb[c], 1.0f);
        at[c] = pt[c];
    }
}

/* Whether the ray o + t d, which the reflector's SPOC answered with the
   point `shown` (met: 0, nothing), missed an impostored object the scene
   puts in front (refl__spoc_missed); *h the scene's own first hit. */
static int rgl__sp_missed(const refl_spoc_set *set, const refl_bvh *scene_bvh, refl_vec3 o, refl_vec3 d, int met,
                          const float shown[3], refl_hit *h, int *hit) {
    int i;
    *hit = refl_bvh_intersect(scene_bvh, o, d, 0.0f, 1e30f, h);
    if (!*hit) return 0;
    if (!met) return 1;
    for (i = 0; i < set->imp_count; ++i)
        if (set->imp_object[i] == h->object)
            return h->t * refl_v3_length(d) <
                   refl_v3_length(refl_v3_sub(refl_v3(shown[0], shown[1], shown[2]), o)) -
                       4.0f * set->cams[i].radius / (float)set->cams[i].size;
    return 0;
}

/* The CPU's share for reflector o's pixels: the exact part up to the
   impostor's hit, the missed rays traced, the composite. */
static void rgl__sp_finish(const rgl_pass *p, int o, const refl_spoc_set *set, const refl_bvh *scene_bvh,
                           float *const drawn[3], const float *org, const float *dir, refl_frame *frame, float *rgb,
                           rgl_frame_stats *st) {
    size_t i, np = (size_t)p->w * (size_t)p->h;
    for (i = 0; i < np; ++i) {
        const float *gp = drawn[0] + 4 * i, *gc = drawn[1] + 4 * i;
        refl_vec3 ro = refl_v3(org[3 * i], org[3 * i + 1], org[3 * i + 2]);
        refl_vec3 rd = refl_v3(dir[3 * i], dir[3 * i + 1], dir[3 * i + 2]);
        float col[3] = {0.0f, 0.0f, 0.0f}, at[3] = {0.0f, 0.0f, 0.0f}, best = FLT_MAX;
        int met = gp[3] > 0.5f, c, hit;
        refl_hit h;
        if (p->marks[i] != o + 1) continue;
        if (met) {
            best = gc[3];
            for (c = 0; c < 3; ++c) {
                col[c] = fminf(fmaxf(gc[c], 0.0f), 1.0f);
                at[c] = gp[c];
            }
        }
        st->projections += (long long)drawn[2][4 * i];
        if (set->exact && refl_bvh_intersect(set->exact, ro, rd, 0.0f, best, &h)) {
            rgl__sp_shade_hit(p, set->exact_object[h.object], &h, rd, col, at);
            met = 1;
        }
        if (rgl__sp_missed(set, scene_bvh, ro, rd, met, at, &h, &hit)) {
            /* the tracer's: the scene's first hit along the ray */
            rgl__sp_shade_hit(p, h.object, &h, rd, col, at);
            met = 1;
            st->traced++;
        }
        rgl_composite(p, (int)i, met ? col : NULL, at, frame, rgb);
    }
}

int rgl_render_spoc(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame, float *rgb,
                    rgl_frame_stats *st, char *err, size_t n) {
    int o, rc = -1;
    size_t np = (size_t)view->width * (size_t)view->height, i;
    uint8_t *seen = NULL;
    float *org = NULL, *dir = NULL, *data = NULL, offset;
    refl_bvh *scene_bvh = NULL;
    refl_spoc_set *set = NULL;
    rgl_method_pass m;
    const rgl_pass *ps = &m.ps;
    refl_vec3 lo, hi;
    double t1;
    if (rgl_method_begin(&m, scene, view, frame, st, err, n) != 0) goto done;
    t1 = rgl_now();
    refl_scene_bounds(scene, &lo, &hi);
    offset = 1e-4f * refl_v3_length(refl_v3_sub(hi, lo)); /* m_spoc.c's */
    if (!(org = (float *)calloc(np, 3 * sizeof(float))) || !(dir = (float *)calloc(np, 3 * sizeof(float))) ||
        !(seen = (uint8_t *)calloc((size_t)(scene->object_count > 0 ? scene->object_count : 1), 1)))
        goto oom;
    for (i = 0; i < np; ++i)
        if (ps->marks[i]) seen[ps->marks[i] - 1] = 1;
    if (refl_bvh_build(scene, NULL, &scene_bvh) != REFL_OK) goto oom;
    m.t_cpu += rgl_now() - t1;
    if (!(m.prog = rgl__sp_program(err, n))) goto done;
    if (rgl__sp_rays(ps, offset, m.ray_tex, org, dir) != 0) goto oom;
    rgl.ClearColor(0, 0, 0, 0);
    rgl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    rgl.Disable(GL_DEPTH_TEST);
    rgl.StencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
    for (o = 0; o < scene->object_count; ++o) {
        long long floats = 0;
        if (!m.mark[o] || !seen[o]) continue;
        t1 = rgl_now();
        /* the CPU method's set at spoc's defaults */
        if (refl_spoc_set_build(scene, o, NULL, &set) != REFL_OK) {
            snprintf(err, n, "building object %d's impostors failed", o);
            goto done;
        }
        free(data);
        if (!(data = rgl__sp_pack(set, &floats))) {
            snprintf(err, n, "refl_gl_pack_spoc_impostor refused object %d's impostors", o);
            goto done;
        }
        st->mirrors += set->imp_count;
        m.t_cpu += rgl_now() - t1;
        if (set->imp_count) {
            if (rgl_method_data(&m, data, floats, err, n) != 0) goto done;
            rgl.StencilFunc(GL_EQUAL, m.mark[o], 0xFF);
            rgl.DrawArrays(GL_TRIANGLES, 0, 3);
            st->vertices += 3;
        }
        /* this reflector's pixels only: the later ones redraw theirs */
        if (rgl_method_read(&m, 3, "marching the SPOC impostors", err, n) != 0) goto done;
        t1 = rgl_now();
        rgl__sp_finish(ps, o, set, scene_bvh, m.drawn, org, dir, frame, rgb, st);
        refl_spoc_set_destroy(set);
        set = NULL;
        m.t_cpu += rgl_now() - t1;
    }
    /* every other pixel: the base pass shaded */
    t1 = rgl_now();
    for (i = 0; i < np; ++i)
        if (!ps->marks[i]) rgl_composite(ps, (int)i, NULL, NULL, frame, rgb);
    st->gl_seconds = t1 - m.t0 - m.t_cpu;
    rc = rgl_method_finish(&m, frame, rgb, st, t1, err, n);
    goto done;
oom:
    snprintf(err, n, "out of memory");
done:
    refl_spoc_set_destroy(set);
    refl_bvh_destroy(scene_bvh);
    free(org);
    free(dir);
    free(data);
    free(seen);
    return rgl_method_end(g, &m, rc);
}

/* ---- GRAPHCAM through GL ----------------------------------------------------------- */

/* One impostor for the frame: its block at texel 0. Out: the point met
   and 1 (0: none), its colour and t, the steps walked, the frustum met
   and `behind` (refl_graphcam_impostor_intersect's). */
static const char rgl__gc_fs_main[] =
    "uniform samplerBuffer u_data;\n"
    "uniform sampler2D u_org, u_dir;\n"
    "uniform float u_step, u_tmin;\n"
    "layout(location = 0) out vec4 o_point;\n"
    "layout(location = 1) out vec4 o_color;\n"
    "layout(location = 2) out vec4 o_steps;\n"
    "void main() {\n"
    "    ivec2 px = ivec2(gl_FragCoord.xy);\n"
    "    vec3 o = texelFetch(u_org, px, 0).xyz, d = texelFetch(u_dir, px, 0).xyz, pt, c;\n"
    "    float t, behind;\n"
    "    int f, steps;\n"
    "    bool met = refl_graphcam_impostor_intersect(u_data, 0, o, d, u_tmin, 1e30, u_step, t, pt, c, f, behind, steps);\n"
    "    o_point = vec4(pt, met ? 1.0 : 0.0);\n"
    "    o_color = vec4(c, t);\n"
    "    o_steps = vec4(float(steps), float(f), behind, 0.0);\n"
    "}\n";

/* The graph camera's marching program, in use: 1 px a step (graphcam.step's
   default), from tmin on. */
static GLuint rgl__gc_program(float tmin, char *err, size_t n) {
    const char *parts[2];
    GLuint prog;
    parts[0] = refl_gl_glsl(REFL_GL_GRAPHCAM_IMPOSTOR);
    parts[1] = rgl__gc_fs_main;
    if (!(prog = rgl__imp_program(parts, 2, err, n))) return 0;
    rgl.Uniform1f(rgl.GetUniformLocation(prog, "u_step"), 1.0f);
    rgl.Uniform1f(rgl.GetUniformLocation(prog, "u_tmin"), tmin);
    return prog;
}

/* The view's near and far planes as the renderer takes them (render.c's
   refl__view_planes): GRAPHCAM's default camera is the view's pinhole. */
static void rgl__gc_view_planes(const refl_view *v, const refl_scene *s, float *znear, float *zfar) {
    refl_vec3 lo, hi, c;
    float radius, dist;
    *znear = v->znear;
    *zfar = v->zfar;
    if (*znear > 0.0f && *zfar > *znear) return;
    refl_scene_bounds(s, &lo, &hi);
    c = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    radius = 0.5f * refl_v3_length(refl_v3_sub(hi, lo));
    dist = refl_v3_length(refl_v3_sub(v->eye, c));
    *zfar = fmaxf(dist + radius, 1e-3f) * 1.01f;
    *znear = fmaxf(dist - radius, *zfar * 1e-3f);
    *znear = fmaxf(*znear * 0.5f, *zfar * 1e-4f);
}

/* What the reflected rays meet besides the impostor (m_graphcam.c's
   refl__gcm_exact): the flat diffuse objects (billboards, for their parts
   outside every frustum), the reflectors (which the impostor leaves out),
   the whole scene. */
typedef struct rgl_gc_exact {
    refl_bvh *flat, *unheld, *scene;
    int *flat_object, *unheld_object;
} rgl_gc_exact;

static void rgl__gc_exact_free(rgl_gc_exact *x) {
    refl_bvh_destroy(x->flat);
    refl_bvh_destroy(x->unheld);
    refl_bvh_destroy(x->scene);
    free(x->flat_object);
    free(x->unheld_object);
    memset(x, 0, sizeof *x);
}

static int rgl__gc_exact_build(const refl_scene *s, rgl_gc_exact *x) {
    uint8_t *keep = (uint8_t *)calloc((size_t)(s->object_count > 0 ? s->object_count : 1), 2);
    int i, rc = -1;
    memset(x, 0, sizeof *x);
    if (!keep) return -1;
    for (i = 0; i < s->object_count; ++i) {
        int reflector = s->materials[s->objects[i].material].type != REFL_DIFFUSE;
        keep[i] = !reflector && refl_object_is_flat(s, i);
        keep[s->object_count + i] = (uint8_t)reflector;
    }
    if (rgl__imp_sub_bvh(s, keep, &x->flat, &x->flat_object) == 0 &&
        rgl__imp_sub_bvh(s, keep + s->object_count, &x->unheld, &x->unheld_object) == 0 &&
        refl_bvh_build(s, NULL, &x->scene) == REFL_OK)
        rc = 0;
    free(keep);
    return rc;
}

/* The CPU's share of reflector pixel i (m_graphcam.c's refl__gcm_row after
   the march): the first flat surface where no frustum holds it, the rays
   the impostor cannot answer traced (none met where the scene has
   something, passed behind a surface first, or a reflector met first),
   the composite. */
static void rgl__gc_finish(const rgl_pass *p, size_t i, const refl_graphcam *cam, const rgl_gc_exact *x, float eps,
                           float *const drawn[3], refl_frame *frame, float *rgb, rgl_frame_stats *st) {
    const float *gp = drawn[0] + 4 * i, *gc = drawn[1] + 4 * i;
    float col[3], at[3], t = gc[3], behind = drawn[2][4 * i + 2];
    int found = gp[3] > 0.5f, hand = 0, c;
    refl_vec3 s, n, d, off;
    refl_hit h;
    rgl__imp_pixel_ray(p, i, &s, &n, &d);
    st->projections += (long long)drawn[2][4 * i];
    for (c = 0; c < 3; ++c) {
        col[c] = gc[c];
        at[c] = gp[c];
    }
    if (x->flat && refl_bvh_intersect(x->flat, s, d, eps, found ? t : 1e30f, &h)) {
        float frgb[3], fat[3];
        rgl__sp_shade_hit(p, x->flat_object[h.object], &h, d, frgb, fat);
        if (refl_graphcam_locate(cam, refl_v3(fat[0], fat[1], fat[2])) < 0) {
            memcpy(col, frgb, sizeof col);
            memcpy(at, fat, sizeof at);
            t = h.t;
            found = 1;
        }
    }
    off = refl_v3_add(s, refl_v3_scale(n, eps));
    if ((!found || behind < t) && refl_bvh_intersect(x->scene, off, d, 0.0f, 1e30f, &h)) hand = 1;
    if (!hand && found && x->unheld && refl_bvh_occluded(x->unheld, off, d, 0.0f, t))
        hand = refl_bvh_intersect(x->scene, off, d, 0.0f, 1e30f, &h);
    if (hand) {
        /* the tracer's: the scene's first hit along the ray */
        rgl__sp_shade_hit(p, h.object, &h, d, col, at);
        found = 1;
        st->traced++;
    }
    rgl_composite(p, (int)i, found ? col : NULL, at, frame, rgb);
}

int rgl_render_graphcam(rgl_context *g, const refl_scene *scene, const refl_view *view, const refl_graphcam *camera,
                        refl_frame *frame, float *rgb, rgl_frame_stats *st, char *err, size_t n) {
    int rc = -1, any = 0;
    size_t np = (size_t)view->width * (size_t)view->height, i;
    float *org = NULL, *dir = NULL, *data = NULL, eps;
    refl_graphcam *own = NULL;
    refl_graphcam_impostor *imp = NULL;
    rgl_gc_exact x;
    rgl_method_pass m;
    const rgl_pass *ps = &m.ps;
    refl_vec3 lo, hi;
    long long floats = 0;
    double t1;
    memset(&x, 0, sizeof x);
    if (rgl_method_begin(&m, scene, view, frame, st, err, n) != 0) goto done;
    for (i = 0; i < np && !any; ++i) any = ps->marks[i] != 0;
    t1 = rgl_now();
    if (!camera) { /* the view's pinhole at twice the frame's width, as the CPU method's default */
        refl_view v = *view;
        int w = 2 * view->width, h = (int)((long long)w * view->height / view->width);
        if (!(own = (refl_graphcam *)malloc(sizeof *own))) goto oom;
        rgl__gc_view_planes(view, scene, &v.znear, &v.zfar);
        if (refl_graphcam_init(own, &v, w, h > 1 ? h : 1) != REFL_OK) {
            snprintf(err, n, "the view's graph camera failed");
            goto done;
        }
        camera = own;
    }
    if (!(org = (float *)calloc(np, 3 * sizeof(float))) || !(dir = (float *)calloc(np, 3 * sizeof(float)))) goto oom;
    if (any) {
        if (refl_graphcam_impostor_build(scene, camera, NULL, 0, &imp) != REFL_OK) {
            snprintf(err, n, "the graph camera's impostor failed");
            goto done;
        }
        floats = refl_gl_pack_graphcam_impostor(camera, imp, NULL, 0);
        if (floats < 0 || !(data = (float *)malloc((size_t)floats * sizeof(float))) ||
            refl_gl_pack_graphcam_impostor(camera, imp, data, floats) != floats) {
            snprintf(err, n, "refl_gl_pack_graphcam_impostor refused the impostor");
            goto done;
        }
        if (rgl__gc_exact_build(scene, &x) != 0) goto oom;
    }
    st->mirrors = camera->count;
    refl_graphcam_bounds(camera, &lo, &hi);
    eps = 1e-4f * (refl_v3_length(refl_v3_sub(hi, lo)) + 1.0f); /* m_graphcam.c's */
    m.t_cpu += rgl_now() - t1;
    if (!(m.prog = rgl__gc_program(eps, err, n))) goto done;
    if (rgl__sp_rays(ps, 0.0f, m.ray_tex, org, dir) != 0) goto oom;
    rgl.ClearColor(0, 0, 0, 0);
    rgl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    rgl.Disable(GL_DEPTH_TEST);
    rgl.StencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
    if (any) {
        if (rgl_method_data(&m, data, floats, err, n) != 0) goto done;
        rgl.StencilFunc(GL_NOTEQUAL, 0, 0xFF); /* every reflector's pixels: one impostor */
        rgl.DrawArrays(GL_TRIANGLES, 0, 3);
        st->vertices += 3;
    }
    if (rgl_method_read(&m, 3, "marching the graph camera's impostor", err, n) != 0) goto done;
    st->gl_seconds = rgl_now() - m.t0 - m.t_cpu;
    t1 = rgl_now();
    for (i = 0; i < np; ++i) {
        if (ps->marks[i]) rgl__gc_finish(ps, i, camera, &x, eps, m.drawn, frame, rgb, st);
        else rgl_composite(ps, (int)i, NULL, NULL, frame, rgb);
    }
    rc = rgl_method_finish(&m, frame, rgb, st, t1, err, n);
    goto done;
oom:
    snprintf(err, n, "out of memory");
done:
    rgl__gc_exact_free(&x);
    refl_graphcam_impostor_destroy(imp);
    free(org);
    free(dir);
    free(data);
    free(own);
    return rgl_method_end(g, &m, rc);
}

/* ---- the hook's march against refl_impostor_intersect ------------------------------ */

static double rgl__sp_rand(uint64_t *s) {
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) * (1.0 / 9007199254740992.0);
}

static int rgl__sp_cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* One fragment per ray: prog (in use, rgl__imp_program's) over the rays
   (org, dir: 4 floats each, w rays a row, h rows) with data on unit 0;
   its three outputs read back into back[0..2] (4 floats per ray, rows
   bottom first, as the rays). *secs: the draw and read-back. */
static int rgl__imp_march_rays(rgl_context *g, GLuint prog, const float *data, long long floats, const float *org,
                               const float *dir, int w, int h, float *const back[3], double *secs, char *err,
                               size_t n) {
    static const GLenum bufs[3] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};
    GLuint fbo = 0, rb[3] = {0, 0, 0}, tex[2] = {0, 0}, dtex = 0, tbuf = 0, vao = 0;
    int k, rc = -1;
    double t0;
    rgl.UseProgram(prog);
    rgl.GenFramebuffers(1, &fbo);
    rgl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
    rgl.GenRenderbuffers(3, rb);
    for (k = 0; k < 3; ++k) {
        rgl.BindRenderbuffer(GL_RENDERBUFFER, rb[k]);
        rgl.RenderbufferStorage(GL_RENDERBUFFER, GL_RGBA32F, w, h);
        rgl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + k, GL_RENDERBUFFER, rb[k]);
    }
    if (rgl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
        snprintf(err, n, "the rays' framebuffer is incomplete");
        goto done;
    }
    rgl.DrawBuffers(3, bufs);
    rgl.Viewport(0, 0, w, h);
    rgl.Disable(GL_DEPTH_TEST);
    rgl.Disable(GL_STENCIL_TEST);
    rgl.GenTextures(2, tex);
    rgl__sp_texture(tex[0], 1, w, h, org);
    rgl__sp_texture(tex[1], 2, w, h, dir);
    if (!(dtex = rgl_buffer_texture(data, floats, &tbuf, err, n))) goto done;
    rgl.ActiveTexture(GL_TEXTURE0);
    rgl.BindTexture(GL_TEXTURE_BUFFER, dtex);
    rgl.GenVertexArrays(1, &vao);
    rgl.BindVertexArray(vao);
    t0 = rgl_now();
    rgl.DrawArrays(GL_TRIANGLES, 0, 3);
    for (k = 0; k < 3; ++k) {
        rgl.ReadBuffer(GL_COLOR_ATTACHMENT0 + k);
        rgl.ReadPixels(0, 0, w, h, GL_RGBA, GL_FLOAT, back[k]);
    }
    *secs = rgl_now() - t0;
    rc = rgl_pass_check("marching the rays", err, n);
done:
    if (vao) rgl.DeleteVertexArrays(1, &vao);
    if (fbo) {
        rgl.BindFramebuffer(GL_FRAMEBUFFER, rgl_default_framebuffer(g));
        rgl.DeleteFramebuffers(1, &fbo);
    }
    if (rb[0]) rgl.DeleteRenderbuffers(3, rb);
    rgl_pass_delete(0, 0, 0, dtex, tbuf, tex);
    return rc;
}

/* A hook's march against its C intersector: the fixture's scene, the
   hook's data and marching program, the rays (org and dir, 4 floats a
   ray, w rays a row), GL's read-back of them (back[3], rows as the rays)
   and the agreeing rays' errors; rgl__imp_check_free releases it all. */
typedef struct rgl_imp_check {
    refl_scene *scene;
    float *data;
    long long floats;
    GLuint prog;
    long long count;
    float *org, *dir, *back[3];
    double *errs;
    int w, h;
} rgl_imp_check;

static void rgl__imp_check_free(rgl_imp_check *c) {
    int k;
    if (c->prog) rgl.DeleteProgram(c->prog);
    refl_scene_destroy(c->scene);
    free(c->data);
    free(c->org);
    free(c->dir);
    for (k = 0; k < 3; ++k) free(c->back[k]);
    free(c->errs);
    memset(c, 0, sizeof *c);
}

/* Room for `rays` rays. Nonzero when out of memory. */
static int rgl__imp_check_rays(rgl_imp_check *c, long long rays) {
    size_t np;
    int k;
    c->count = rays;
    c->w = 256;
    c->h = (int)((rays + c->w - 1) / c->w);
    np = (size_t)c->w * (size_t)(c->h > 0 ? c->h : 1);
    c->org = (float *)calloc(np, 4 * sizeof(float));
    c->dir = (float *)calloc(np, 4 * sizeof(float));
    c->errs = (double *)calloc(np, sizeof(double));
    for (k = 0; k < 3; ++k) c->back[k] = (float *)malloc(np * 4 * sizeof(float));
    return c->org && c->dir && c->errs && c->back[0] && c->back[1] && c->back[2] ? 0 : -1;
}

/* Ray i from o towards d (normalised). */
static void rgl__imp_check_put(rgl_imp_check *c, size_t i, refl_vec3 o, refl_vec3 d) {
    d = refl_v3_normalize(d);
    c->org[4 * i] = o.x; c->org[4 * i + 1] = o.y; c->org[4 * i + 2] = o.z;
    c->dir[4 * i] = d.x; c->dir[4 * i + 1] = d.y; c->dir[4 * i + 2] = d.z;
}

/* A random point of the box [lo, hi]. */
static refl_vec3 rgl__imp_rand_in(uint64_t *seed, refl_vec3 lo, refl_vec3 hi) {
    float x = (float)(lo.x + (hi.x - lo.x) * rgl__sp_rand(seed)), y = (float)(lo.y + (hi.y - lo.y) * rgl__sp_rand(seed));
    return refl_v3(x, y, (float)(lo.z + (hi.z - lo.z) * rgl__sp_rand(seed)));
}

/* A random direction, each coordinate in [-1, 1]. */
static refl_vec3 rgl__imp_rand_dir(uint64_t *seed) {
    float x = (float)(2.0 * rgl__sp_rand(seed) - 1.0), y = (float)(2.0 * rgl__sp_rand(seed) - 1.0);
    return refl_v3(x, y, (float)(2.0 * rgl__sp_rand(seed) - 1.0));
}

/* A C intersector: the ray o + t d's hit (nonzero) and its t; *steps
   the steps it walked, where it counts them. */
typedef int (*rgl_imp_c_ray)(const void *user, refl_vec3 o, refl_vec3 d, double *t, long long *steps);

/* The rays marched by the hook on GL (out->gl_seconds), then one by one
   through c_ray (out->cpu_seconds): a ray that hits on one side only
   disagrees, the others' error of t over `scale` goes into out's max and
   p99.9; steps[0] and steps[1] sum the steps C and GL walked. Nonzero
   with the reason in err when GL fails. */
static int rgl__imp_check_run(rgl_context *g, rgl_imp_check *c, rgl_imp_c_ray c_ray, const void *user, double scale,
                              long long steps[2], rgl_validation *out, char *err, size_t n) {
    long long agree = 0;
    size_t i;
    double t0;
    if (rgl__imp_march_rays(g, c->prog, c->data, c->floats, c->org, c->dir, c->w, c->h, c->back, &out->gl_seconds, err,
                            n) != 0)
        return -1;
    t0 = rgl_now();
    for (i = 0; i < (size_t)c->count; ++i) {
        refl_vec3 o = refl_v3(c->org[4 * i], c->org[4 * i + 1], c->org[4 * i + 2]);
        refl_vec3 d = refl_v3(c->dir[4 * i], c->dir[4 * i + 1], c->dir[4 * i + 2]);
        double t = 0.0;
        int c_hit = c_ray(user, o, d, &t, &steps[0]);
        steps[1] += (long long)c->back[2][4 * i];
        if (c_hit != (c->back[0][4 * i + 3] > 0.5f)) out->disagree++;
        else if (c_hit) c->errs[agree++] = fabs((double)c->back[1][4 * i + 3] - t) / scale;
    }
    out->cpu_seconds = rgl_now() - t0;
    out->points = c->count;
    out->projected = agree;
    if (!agree) return 0;
    qsort(c->errs, (size_t)agree, sizeof *c->errs, rgl__sp_cmp);
    out->max_rel = c->errs[agree - 1];
    out->p999_rel = c->errs[(size_t)((double)(agree - 1) * 0.999)];
    return 0;
}

/* The SPOC impostor's C march (refl_impostor_intersect); its steps not counted. */
static int rgl__sp_c_ray(const void *imp, refl_vec3 o, refl_vec3 d, double *t, long long *steps) {
    refl_impostor_hit hit;
    int c_hit = refl_impostor_intersect((const refl_impostor *)imp, o, d, 0.0f, FLT_MAX, RGL_SP_STEP_SCALE, &hit, NULL);
    (void)steps;
    if (c_hit) *t = hit.t;
    return c_hit;
}

int rgl_validate_spoc_impostor(rgl_context *g, long long rays, rgl_validation *out, char *err, size_t n) {
    int reflector = -1, k, rc = -1;
    size_t i;
    refl_spoc_set *set = NULL;
    rgl_imp_check c;
    long long steps[2] = {0, 0};
    uint64_t seed = 0x5eedULL;
    refl_vec3 lo, hi;
    const refl_impostor_camera *cam;
    memset(out, 0, sizeof *out);
    memset(&c, 0, sizeof c);
    out->camera = "spoc-impostor";
    if (rays < 1) return 0;
    if (refl_scene_builtin("teapots", NULL, &c.scene) != REFL_OK) {
        snprintf(err, n, "no teapots scene");
        return -1;
    }
    for (k = 0; k < c.scene->object_count && reflector < 0; ++k)
        if (c.scene->materials[c.scene->objects[k].material].type == REFL_MIRROR) reflector = k;
    if (reflector < 0 || refl_spoc_set_build(c.scene, reflector, NULL, &set) != REFL_OK || set->imp_count != 1) {
        snprintf(err, n, "the teapots' impostor failed");
        goto done;
    }
    if (!(c.data = rgl__sp_pack(set, &c.floats)) || rgl__imp_check_rays(&c, rays) != 0) {
        snprintf(err, n, "out of memory");
        goto done;
    }
    /* rays from the mirror teapot's box: 80% towards a point of the
       impostor's sphere, the rest anywhere */
    refl_object_world_bounds(c.scene, reflector, &lo, &hi);
    cam = &set->imps[0]->camera;
    for (i = 0; i < (size_t)rays; ++i) {
        refl_vec3 o = rgl__imp_rand_in(&seed, lo, hi);
        refl_vec3 q = rgl__imp_rand_dir(&seed);
        rgl__imp_check_put(&c, i, o, rgl__sp_rand(&seed) < 0.8
                                         ? refl_v3_sub(refl_v3_add(cam->center, refl_v3_scale(q, cam->radius)), o)
                                         : q);
    }
    /* C: refl_impostor_intersect; the error of t over the sphere's diameter */
    if (!(c.prog = rgl__sp_program(err, n)) ||
        rgl__imp_check_run(g, &c, rgl__sp_c_ray, set->imps[0], 2.0 * cam->radius, steps, out, err, n) != 0)
        goto done;
    snprintf(out->note, sizeof out->note, "the teapots' diffuse teapot from the mirror's centre, %dx%d x %d layers",
             set->imps[0]->width, set->imps[0]->height, set->imps[0]->layers);
    rc = 0;
done:
    refl_spoc_set_destroy(set);
    rgl__imp_check_free(&c);
    return rc;
}

/* The graph camera impostor's C march (refl_graphcam_intersect, segments,
   1 px a step, from eps on). */
typedef struct rgl_gc_c_march {
    const refl_graphcam *cam;
    const refl_graphcam_impostor *imp;
    float eps;
} rgl_gc_c_march;

static int rgl__gc_c_ray(const void *user, refl_vec3 o, refl_vec3 d, double *t, long long *steps) {
    const rgl_gc_c_march *q = (const rgl_gc_c_march *)user;
    refl_graphcam_hit hit;
    int c_hit = refl_graphcam_intersect(q->cam, q->imp, o, d, q->eps, 1e30f, REFL_GRAPHCAM_SEGMENTS, 1.0f, &hit);
    *steps += hit.steps;
    if (c_hit) *t = hit.t;
    return c_hit;
}

int rgl_validate_graphcam_impostor(rgl_context *g, long long rays, rgl_validation *out, char *err, size_t n) {
    int mirror = -1, k, rc = -1;
    size_t i;
    refl_graphcam *cam = (refl_graphcam *)malloc(sizeof *cam);
    refl_graphcam_impostor *imp = NULL;
    rgl_imp_check c;
    rgl_gc_c_march march;
    long long steps[2] = {0, 0};
    uint64_t seed = 0x9c0ffeeULL;
    refl_vec3 lo, hi, clo, chi, grow;
    memset(out, 0, sizeof *out);
    memset(&c, 0, sizeof c);
    out->camera = "graphcam-impostor";
    if (rays < 1 || !cam) {
        free(cam);
        return rays < 1 ? 0 : -1;
    }
    if (refl_scene_builtin("maze", NULL, &c.scene) != REFL_OK || refl_graphcam_maze(cam, 960, 588) != REFL_OK ||
        refl_graphcam_impostor_build(c.scene, cam, NULL, 0, &imp) != REFL_OK) {
        snprintf(err, n, "the maze's graph camera impostor failed");
        goto done;
    }
    for (k = 0; k < c.scene->object_count && mirror < 0; ++k)
        if (c.scene->materials[c.scene->objects[k].material].type == REFL_MIRROR) mirror = k;
    c.floats = refl_gl_pack_graphcam_impostor(cam, imp, NULL, 0);
    if (mirror < 0 || c.floats < 0) {
        snprintf(err, n, "no maze mirror, or the impostor refused");
        goto done;
    }
    if (!(c.data = (float *)malloc((size_t)c.floats * sizeof(float))) || rgl__imp_check_rays(&c, rays) != 0) {
        snprintf(err, n, "out of memory");
        goto done;
    }
    refl_gl_pack_graphcam_impostor(cam, imp, c.data, c.floats);
    /* rays from the mirror sphere's surface region (its box grown by a
       quarter), in random directions, as the method's reflected rays */
    refl_object_world_bounds(c.scene, mirror, &lo, &hi);
    grow = refl_v3_scale(refl_v3_sub(hi, lo), 0.25f);
    lo = refl_v3_sub(lo, grow);
    hi = refl_v3_add(hi, grow);
    for (i = 0; i < (size_t)rays; ++i) {
        refl_vec3 o = rgl__imp_rand_in(&seed, lo, hi);
        rgl__imp_check_put(&c, i, o, rgl__imp_rand_dir(&seed));
    }
    refl_graphcam_bounds(cam, &clo, &chi);
    march.cam = cam;
    march.imp = imp;
    march.eps = 1e-4f * (refl_v3_length(refl_v3_sub(chi, clo)) + 1.0f);
    /* C: refl_graphcam_intersect; the error of t over the camera's bounds */
    if (!(c.prog = rgl__gc_program(march.eps, err, n)) ||
        rgl__imp_check_run(g, &c, rgl__gc_c_ray, &march, refl_v3_length(refl_v3_sub(chi, clo)), steps, out, err, n) != 0)
        goto done;
    snprintf(out->note, sizeof out->note, "the maze's camera, %d frusta at %dx%d; steps: C %lld, GL %lld",
             cam->count, cam->width, cam->height, steps[0], steps[1]);
    rc = 0;
done:
    refl_graphcam_impostor_destroy(imp);
    rgl__imp_check_free(&c);
    free(cam);
    return rc;
}
