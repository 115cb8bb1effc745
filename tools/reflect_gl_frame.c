/* reflect_gl_frame.c - the GL path's shared frame (reflect_gl_frame.h)
   and PLANAR through GL (reflect_gl.h, docs/gl.md). GL draws, the CPU
   shades:
     1. base pass from the eye: every object's world point, normal, uv and
        id into float targets; each object marks its pixels in the stencil
        with the mark its method gives it (PLANAR: each planar mirror its
        number);
     2. per mirror: the scene again through the mirrored pinhole (the GL
        hook, refl_mirror_project in the vertex shader, its plane as
        gl_ClipDistance), stencil-tested to the mirror's pixels;
     3. the CPU shades both read-backs with reflect.h's shading
        (refl_shade_diffuse, refl_environment_lookup) and composites each
        mirror pixel as PLANAR does: reflectance times what it shows.
   One bounce; a mirror object must be planar (all its triangles in one
   plane) and seen from its front, else it is drawn as DIRECT draws it. */
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

static const char rgl__frame_vs_base[] =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_p;\n"
    "layout(location = 1) in vec3 a_n;\n"
    "layout(location = 2) in vec3 a_uv_id;\n"
    "uniform mat4 u_vp;\n"
    "out vec3 v_p; out vec3 v_n; out vec2 v_uv; flat out float v_id;\n"
    "void main() {\n"
    "    v_p = a_p; v_n = a_n; v_uv = a_uv_id.xy; v_id = a_uv_id.z;\n"
    "    gl_Position = u_vp * vec4(a_p, 1.0);\n"
    "}\n";

const int rgl_vertex_sizes[3] = {3, 3, 3};

const char rgl_frame_vs_head[] =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_p;\n"
    "layout(location = 1) in vec3 a_n;\n"
    "layout(location = 2) in vec3 a_uv_id;\n"
    "uniform samplerBuffer u_data;\n"
    "uniform int u_base;\n"
    "out vec3 v_p; out vec3 v_n; out vec2 v_uv; flat out float v_id;\n";

static const char rgl__frame_vs_mirror_main[] =
    "void main() {\n"
    "    v_p = a_p; v_n = a_n; v_uv = a_uv_id.xy; v_id = a_uv_id.z;\n"
    "    gl_Position = refl_mirror_project(u_data, u_base, a_p, gl_ClipDistance[0]);\n"
    "}\n";

const char rgl_frame_fs[] =
    "#version 330 core\n"
    "in vec3 v_p; in vec3 v_n; in vec2 v_uv; flat in float v_id;\n"
    "layout(location = 0) out vec4 o_point;\n"
    "layout(location = 1) out vec4 o_normal;\n"
    "layout(location = 2) out vec4 o_uv;\n"
    "void main() {\n"
    "    o_point = vec4(v_p, v_id);\n"
    "    o_normal = vec4(v_n, gl_FrontFacing ? 0.0 : 1.0);\n" /* the side seen: 1 a back face */
    "    o_uv = vec4(v_uv, 0.0, 0.0);\n"
    "}\n";

static void rgl__geometry_free(rgl_geometry *g) {
    free(g->v);
    free(g->first);
    free(g->mirrors);
    memset(g, 0, sizeof *g);
}

/* Whether object o's world triangles all lie in one plane; its plane. */
static int rgl__planar(const float *v, long long first, long long count, double n[3], double *d) {
    double size = 0.0, len;
    long long i;
    int k, found = 0;
    for (i = first; i + 2 < first + count && !found; i += 3) {
        const float *a = v + i * RGL_VERTEX_FLOATS, *b = a + RGL_VERTEX_FLOATS, *c = b + RGL_VERTEX_FLOATS;
        double e1[3], e2[3];
        for (k = 0; k < 3; ++k) { e1[k] = b[k] - a[k]; e2[k] = c[k] - a[k]; }
        n[0] = e1[1] * e2[2] - e1[2] * e2[1];
        n[1] = e1[2] * e2[0] - e1[0] * e2[2];
        n[2] = e1[0] * e2[1] - e1[1] * e2[0];
        len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (len > 0.0) {
            for (k = 0; k < 3; ++k) n[k] /= len;
            *d = n[0] * a[0] + n[1] * a[1] + n[2] * a[2];
            found = 1;
        }
    }
    if (!found) return 0;
    for (i = first; i < first + count; ++i)
        for (k = 0; k < 3; ++k) size = fmax(size, fabs(v[i * RGL_VERTEX_FLOATS + k]));
    for (i = first; i < first + count; ++i) {
        const float *p = v + i * RGL_VERTEX_FLOATS;
        if (fabs(n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - *d) > 1e-4 * (size + 1.0)) return 0;
    }
    return 1;
}

static int rgl__frame_fail(char *err, size_t n, const char *what) {
    snprintf(err, n, "%s", what);
    return -1;
}

static int rgl__geometry(const refl_scene *s, refl_vec3 eye, rgl_geometry *g) {
    long long total = 0, at = 0;
    int o;
    memset(g, 0, sizeof *g);
    for (o = 0; o < s->object_count; ++o) total += 3LL * s->meshes[s->objects[o].mesh]->triangle_count;
    g->v = (float *)malloc((size_t)(total ? total : 1) * RGL_VERTEX_FLOATS * sizeof(float));
    g->first = (long long *)malloc((size_t)(s->object_count + 1) * sizeof(long long));
    g->mirrors = (rgl_mirror *)malloc((size_t)(s->object_count > 0 ? s->object_count : 1) * sizeof(rgl_mirror));
    if (!g->v || !g->first || !g->mirrors) return -1;
    for (o = 0; o < s->object_count; ++o) {
        const refl_object *ob = &s->objects[o];
        const refl_mesh *m = s->meshes[ob->mesh];
        const refl_material *mat = &s->materials[ob->material];
        refl_mat4 inv, nm;
        int t, c;
        g->first[o] = at;
        nm = refl_mat4_invert(ob->transform, &inv) ? refl_mat4_transpose(inv) : ob->transform;
        for (t = 0; t < m->triangle_count; ++t) {
            for (c = 0; c < 3; ++c) {
                uint32_t i = m->indices[3 * t + c];
                float *out = g->v + at * RGL_VERTEX_FLOATS;
                refl_vec3 p = refl_mat4_point(ob->transform, refl_v3(m->positions[3 * i], m->positions[3 * i + 1],
                                                                     m->positions[3 * i + 2]));
                refl_vec3 n = refl_v3_normalize(refl_mat4_dir(nm, refl_v3(m->normals[3 * i], m->normals[3 * i + 1],
                                                                          m->normals[3 * i + 2])));
                out[0] = p.x; out[1] = p.y; out[2] = p.z;
                out[3] = n.x; out[4] = n.y; out[5] = n.z;
                out[6] = m->texcoords ? m->texcoords[2 * i] : 0.0f;
                out[7] = m->texcoords ? m->texcoords[2 * i + 1] : 0.0f;
                out[8] = (float)(o + 1);
                ++at;
            }
        }
        if (mat->type == REFL_MIRROR || mat->type == REFL_PARTIAL) {
            rgl_mirror *mr = &g->mirrors[g->mirror_count];
            if (rgl__planar(g->v, g->first[o], at - g->first[o], mr->n, &mr->d)) {
                double side = mr->n[0] * eye.x + mr->n[1] * eye.y + mr->n[2] * eye.z - mr->d;
                int k;
                if (side < 0.0) { /* facing the eye: its front */
                    for (k = 0; k < 3; ++k) mr->n[k] = -mr->n[k];
                    mr->d = -mr->d;
                }
                mr->object = o;
                if (side != 0.0 && g->mirror_count < 254) g->mirror_count++;
            }
        }
    }
    g->first[s->object_count] = at;
    g->vertex_count = at;
    return 0;
}

void rgl_pass_read(const rgl_pass *p, int a, float *out) {
    int y, w = p->w, h = p->h;
    rgl.ReadBuffer(GL_COLOR_ATTACHMENT0 + a);
    rgl.ReadPixels(0, 0, w, h, GL_RGBA, GL_FLOAT, out);
    for (y = 0; y < h / 2; ++y) { /* GL's row 0 is the bottom one */
        float *r0 = out + (size_t)y * w * 4, *r1 = out + (size_t)(h - 1 - y) * w * 4, t;
        int x;
        for (x = 0; x < w * 4; ++x) { t = r0[x]; r0[x] = r1[x]; r1[x] = t; }
    }
}

static void rgl__read_stencil(int w, int h, uint8_t *out) {
    int y;
    rgl.ReadPixels(0, 0, w, h, GL_STENCIL_INDEX, GL_UNSIGNED_BYTE, out);
    for (y = 0; y < h / 2; ++y) {
        uint8_t *r0 = out + (size_t)y * w, *r1 = out + (size_t)(h - 1 - y) * w, t;
        int x;
        for (x = 0; x < w; ++x) { t = r0[x]; r0[x] = r1[x]; r1[x] = t; }
    }
}

void rgl_shade(const refl_scene *s, const float *pt, const float *nrm, const float *uv, refl_vec3 dir, float rgb[3]) {
    int id = (int)pt[3], c;
    if (id >= 1 && id <= s->object_count) {
        const refl_material *m = &s->materials[s->objects[id - 1].material];
        /* a reflector's diffuse share only (the bounce ends here), as DIRECT */
        float share = m->type == REFL_DIFFUSE ? 1.0f : m->type == REFL_PARTIAL ? 1.0f - m->mirror_weight : 0.0f;
        refl_shade_diffuse(s, m, refl_v3(pt[0], pt[1], pt[2]), refl_v3(nrm[0], nrm[1], nrm[2]), uv, rgb);
        for (c = 0; c < 3; ++c) rgb[c] *= share;
    } else {
        refl_environment_lookup(&s->environment, dir, rgb);
    }
    for (c = 0; c < 3; ++c) rgb[c] = rgb[c] > 0.0f ? rgb[c] : 0.0f; /* as the CPU path keeps colour */
}

refl_vec3 rgl_reflect(refl_vec3 d, refl_vec3 normal) {
    refl_vec3 nrm = refl_v3_normalize(normal);
    if (refl_v3_dot(nrm, d) > 0.0f) nrm = refl_v3_scale(nrm, -1.0f);
    return refl_v3_reflect(d, nrm);
}

void rgl_trace(const rgl_pass *p, const refl_bvh *bvh, refl_vec3 q, refl_vec3 dir, float pt[4], float nrm[4],
               float uv[4]) {
    refl_hit hit;
    int f;
    memset(pt, 0, 4 * sizeof(float));
    if (!refl_bvh_intersect(bvh, q, dir, 1e-4f, INFINITY, &hit)) return;
    {
        const float *a = p->geo.v + (p->geo.first[hit.object] + 3 * (long long)hit.triangle) * RGL_VERTEX_FLOATS;
        const float *b = a + RGL_VERTEX_FLOATS, *c = b + RGL_VERTEX_FLOATS;
        float w0 = 1.0f - hit.u - hit.v;
        for (f = 0; f < 3; ++f) {
            pt[f] = w0 * a[f] + hit.u * b[f] + hit.v * c[f];
            nrm[f] = w0 * a[3 + f] + hit.u * b[3 + f] + hit.v * c[3 + f];
        }
        uv[0] = w0 * a[6] + hit.u * b[6] + hit.v * c[6];
        uv[1] = w0 * a[7] + hit.u * b[7] + hit.v * c[7];
        pt[3] = (float)(hit.object + 1);
    }
}

void rgl_composite(const rgl_pass *p, int i, const float *shown, const float *at, refl_frame *frame, float *rgb) {
    const float *bp = p->base[0] + 4 * (size_t)i, *bn = p->base[1] + 4 * (size_t)i;
    refl_vec3 d = rgl_pass_ray(p, i), nrm = refl_v3(bn[0], bn[1], bn[2]);
    float col[3], env[3];
    int m_at = p->marks[i], c;
    frame->stencil[i] = 0;
    for (c = 0; c < 3; ++c) frame->points[3 * (size_t)i + c] = NAN;
    rgl_shade(p->scene, bp, bn, p->base[2] + 4 * (size_t)i, d, col);
    if (m_at) {
        const refl_material *m = &p->scene->materials[p->scene->objects[m_at - 1].material];
        float wgt = refl_material_reflectance(m, fabsf(refl_v3_dot(d, refl_v3_normalize(nrm))));
        if (!shown) {
            refl_environment_lookup(&p->scene->environment, rgl_reflect(d, nrm), env);
            for (c = 0; c < 3; ++c) env[c] = env[c] > 0.0f ? env[c] : 0.0f;
            shown = env;
        } else {
            for (c = 0; c < 3; ++c) frame->points[3 * (size_t)i + c] = at[c];
        }
        for (c = 0; c < 3; ++c) col[c] += wgt * shown[c]; /* col: the reflector's diffuse share */
        frame->stencil[i] = (uint8_t)m_at;
    }
    for (c = 0; c < 3; ++c) rgb[3 * (size_t)i + c] = col[c];
}

int rgl_pass_ray_textures(const rgl_pass *p, GLuint tex[2]) {
    int w = p->w, h = p->h, x, y, k, t;
    float *surf = (float *)calloc((size_t)w * h, 4 * sizeof(float)), *ray = (float *)calloc((size_t)w * h, 4 * sizeof(float));
    if (!surf || !ray) {
        free(surf);
        free(ray);
        return -1;
    }
    for (y = 0; y < h; ++y) /* rays first (GL's rows: bottom first) */
        for (x = 0; x < w; ++x) {
            int i = y * w + x;
            float *o = ray + 4 * ((size_t)(h - 1 - y) * w + x);
            const float *n = p->base[1] + 4 * (size_t)i;
            refl_vec3 u;
            if (!p->marks[i]) continue;
            u = refl_v3_normalize(rgl_reflect(rgl_pass_ray(p, i), refl_v3(n[0], n[1], n[2])));
            o[0] = u.x; o[1] = u.y; o[2] = u.z; o[3] = n[3] > 0.5f ? -1.0f : 1.0f;
        }
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            int i = y * w + x;
            size_t g = (size_t)(h - 1 - y) * w + x;
            float *s = surf + 4 * g, turn = 0.0f;
            const float *u = ray + 4 * g;
            if (!p->marks[i]) continue;
            for (k = 0; k < 4; ++k) {
                int xs = x + (k == 0) - (k == 1), ys = y + (k == 2) - (k == 3);
                const float *v;
                if (xs < 0 || ys < 0 || xs >= w || ys >= h || p->base[0][4 * ((size_t)ys * w + xs) + 3] != p->base[0][4 * (size_t)i + 3])
                    continue;
                v = ray + 4 * ((size_t)(h - 1 - ys) * w + xs);
                if (v[3] == 0.0f) continue;
                turn = fmaxf(turn, sqrtf((u[0] - v[0]) * (u[0] - v[0]) + (u[1] - v[1]) * (u[1] - v[1]) + (u[2] - v[2]) * (u[2] - v[2])));
            }
            for (t = 0; t < 3; ++t) s[t] = p->base[0][4 * (size_t)i + t];
            s[3] = turn;
        }
    rgl.GenTextures(2, tex);
    for (k = 0; k < 2; ++k) {
        rgl.ActiveTexture(GL_TEXTURE1 + k);
        rgl.BindTexture(GL_TEXTURE_2D, tex[k]);
        rgl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        rgl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        rgl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, w, h, 0, GL_RGBA, GL_FLOAT, k ? ray : surf);
    }
    rgl.ActiveTexture(GL_TEXTURE0);
    free(surf);
    free(ray);
    return 0;
}

refl_vec3 rgl_pass_ray(const rgl_pass *p, int i) {
    int x = i % p->w, y = i / p->w;
    float nx = (2.0f * ((float)x + 0.5f)) / (float)p->w - 1.0f, ny = 1.0f - (2.0f * ((float)y + 0.5f)) / (float)p->h;
    refl_vec3 o = refl_mat4_point(p->vp_inv, refl_v3(nx, ny, -1.0f));
    return refl_v3_normalize(refl_v3_sub(refl_mat4_point(p->vp_inv, refl_v3(nx, ny, 1.0f)), o));
}

int rgl_pass_check(const char *what, char *err, size_t n) {
    GLenum e = rgl.GetError();
    if (e == GL_NO_ERROR) return 0;
    snprintf(err, n, "GL error 0x%x while %s", (unsigned)e, what);
    return -1;
}

int rgl_pass_begin(rgl_pass *p, const refl_scene *scene, const refl_view *view, const uint8_t *mark, char *err,
                   size_t n) {
    static const GLenum bufs[3] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};
    const char *base_vs[1] = {rgl__frame_vs_base}, *fs[1] = {rgl_frame_fs};
    size_t np;
    int i;
    memset(p, 0, sizeof *p);
    p->scene = scene;
    p->view = view;
    p->w = view->width;
    p->h = view->height;
    np = (size_t)p->w * (size_t)p->h;
    if (p->w < 1 || p->h < 1) return rgl__frame_fail(err, n, "bad frame size");
    if (rgl__geometry(scene, view->eye, &p->geo) != 0) return rgl__frame_fail(err, n, "out of memory");
    for (i = 0; i < 3; ++i)
        if (!(p->base[i] = (float *)malloc(np * 4 * sizeof(float)))) return rgl__frame_fail(err, n, "out of memory");
    if (!(p->marks = (uint8_t *)malloc(np))) return rgl__frame_fail(err, n, "out of memory");
    if (!(p->base_prog = rgl_program(base_vs, 1, fs, 1, NULL, 0, err, n))) return -1;
    refl_view_matrices(view, scene, &p->view_m, &p->proj_m);
    p->vp = refl_mat4_mul(p->proj_m, p->view_m);
    if (!refl_mat4_invert(p->vp, &p->vp_inv)) return rgl__frame_fail(err, n, "singular view");
    rgl.GenFramebuffers(1, &p->fbo);
    rgl.BindFramebuffer(GL_FRAMEBUFFER, p->fbo);
    rgl.GenRenderbuffers(4, p->rb);
    for (i = 0; i < 4; ++i) {
        rgl.BindRenderbuffer(GL_RENDERBUFFER, p->rb[i]);
        rgl.RenderbufferStorage(GL_RENDERBUFFER, i < 3 ? GL_RGBA32F : GL_DEPTH24_STENCIL8, p->w, p->h);
        rgl.FramebufferRenderbuffer(GL_FRAMEBUFFER, i < 3 ? GL_COLOR_ATTACHMENT0 + i : GL_DEPTH_STENCIL_ATTACHMENT,
                                    GL_RENDERBUFFER, p->rb[i]);
    }
    if (rgl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        return rgl__frame_fail(err, n, "float G-buffer framebuffer incomplete");
    rgl.DrawBuffers(3, bufs);
    rgl.Viewport(0, 0, p->w, p->h);
    rgl_pass_vertices(p->geo.v, p->geo.vertex_count, RGL_VERTEX_FLOATS, rgl_vertex_sizes, 3, &p->vao, &p->vbo);
    rgl.ClearColor(0, 0, 0, 0);
    rgl.ClearDepth(1.0);
    rgl.ClearStencil(0);
    rgl.StencilMask(0xFF);
    rgl.DepthMask(GL_TRUE);
    rgl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
    rgl.Enable(GL_DEPTH_TEST);
    rgl.DepthFunc(GL_LESS);
    rgl.Enable(GL_STENCIL_TEST);
    rgl.StencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
    rgl.UseProgram(p->base_prog);
    rgl.UniformMatrix4fv(rgl.GetUniformLocation(p->base_prog, "u_vp"), 1, GL_FALSE, p->vp.m);
    for (i = 0; i < scene->object_count; ++i) {
        rgl.StencilFunc(GL_ALWAYS, mark ? mark[i] : 0, 0xFF);
        rgl.DrawArrays(GL_TRIANGLES, (GLint)p->geo.first[i], (GLsizei)(p->geo.first[i + 1] - p->geo.first[i]));
    }
    for (i = 0; i < 3; ++i) rgl_pass_read(p, i, p->base[i]);
    rgl__read_stencil(p->w, p->h, p->marks);
    return rgl_pass_check("drawing the base pass", err, n);
}

int rgl_method_begin(rgl_method_pass *m, const refl_scene *scene, const refl_view *view, const refl_frame *frame,
                     rgl_frame_stats *st, char *err, size_t n) {
    int o;
    memset(m, 0, sizeof *m);
    memset(st, 0, sizeof *st);
    m->t0 = rgl_now();
    if (view->width < 1 || view->height < 1 || frame->width != view->width || frame->height != view->height)
        return rgl__frame_fail(err, n, "bad frame size");
    if (!(m->mark = (uint8_t *)calloc((size_t)(scene->object_count > 0 ? scene->object_count : 1), 1)))
        return rgl__frame_fail(err, n, "out of memory");
    for (o = 0; o < scene->object_count && o < 254; ++o) {
        int type = scene->materials[scene->objects[o].material].type;
        if (type == REFL_MIRROR || type == REFL_PARTIAL) m->mark[o] = (uint8_t)(o + 1);
    }
    return rgl_pass_begin(&m->ps, scene, view, m->mark, err, n);
}

int rgl_method_data(rgl_method_pass *m, const float *data, long long floats, char *err, size_t n) {
    if (m->tex) rgl.DeleteTextures(1, &m->tex);
    if (m->tbuf) rgl.DeleteBuffers(1, &m->tbuf);
    m->tex = m->tbuf = 0;
    if (!(m->tex = rgl_buffer_texture(data, floats, &m->tbuf, err, n))) return -1;
    rgl.ActiveTexture(GL_TEXTURE0);
    rgl.BindTexture(GL_TEXTURE_BUFFER, m->tex);
    return 0;
}

int rgl_method_read(rgl_method_pass *m, int count, const char *what, char *err, size_t n) {
    size_t np = (size_t)m->ps.w * (size_t)m->ps.h;
    int c;
    for (c = 0; c < count && c < 3; ++c) {
        if (!m->drawn[c] && !(m->drawn[c] = (float *)malloc(np * 4 * sizeof(float))))
            return rgl__frame_fail(err, n, "out of memory");
        rgl_pass_read(&m->ps, c, m->drawn[c]);
    }
    return rgl_pass_check(what, err, n);
}

int rgl_method_finish(const rgl_method_pass *m, refl_frame *frame, float *rgb, rgl_frame_stats *st, double t1,
                      char *err, size_t n) {
    if (rgl_hand_over_glass(&m->ps, frame, rgb, st, err, n) != 0) return -1;
    st->shade_seconds = rgl_now() - t1 + m->t_cpu;
    return 0;
}

int rgl_method_end(rgl_context *g, rgl_method_pass *m, int rc) {
    int c;
    rgl_pass_delete(m->prog, m->vao, m->vbo, m->tex, m->tbuf, m->ray_tex);
    rgl_pass_end(g, &m->ps);
    for (c = 0; c < 3; ++c) free(m->drawn[c]);
    free(m->mark);
    memset(m, 0, sizeof *m);
    return rc;
}

void rgl_pass_vertices(const float *v, long long count, int stride, const int *sizes, int attribs, GLuint *vao,
                       GLuint *vbo) {
    int i, at = 0;
    rgl.GenVertexArrays(1, vao);
    rgl.BindVertexArray(*vao);
    rgl.GenBuffers(1, vbo);
    rgl.BindBuffer(GL_ARRAY_BUFFER, *vbo);
    rgl.BufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(count * stride * (long long)sizeof(float)), v, GL_STATIC_DRAW);
    for (i = 0; i < attribs; ++i) {
        rgl.EnableVertexAttribArray((GLuint)i);
        rgl.VertexAttribPointer((GLuint)i, sizes[i], GL_FLOAT, GL_FALSE, stride * (GLsizei)sizeof(float),
                                (const void *)(size_t)(at * sizeof(float)));
        at += sizes[i];
    }
}

int rgl_pass_reflect_begin(const rgl_pass *p, GLuint prog, GLuint ray_tex[2]) {
    rgl.ClearColor(0, 0, 0, 0);
    rgl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    rgl.StencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
    rgl.UseProgram(prog);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_data"), 0);
    rgl.UniformMatrix4fv(rgl.GetUniformLocation(prog, "u_vp"), 1, GL_FALSE, p->vp.m);
    if (rgl_pass_ray_textures(p, ray_tex) != 0) return -1;
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_surf"), 1);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_ray"), 2);
    return 0;
}

float rgl_pass_pixel_angle(const rgl_pass *p) {
    float fovy = p->view->fovy_degrees > 0.0f ? p->view->fovy_degrees : 45.0f;
    return 2.0f * tanf(0.5f * fovy * 3.14159265f / 180.0f) / (float)p->h;
}

void rgl_pass_delete(GLuint prog, GLuint vao, GLuint vbo, GLuint tex, GLuint tbuf, const GLuint ray_tex[2]) {
    if (tex) rgl.DeleteTextures(1, &tex);
    if (ray_tex[0]) rgl.DeleteTextures(2, ray_tex);
    if (tbuf) rgl.DeleteBuffers(1, &tbuf);
    if (vbo) rgl.DeleteBuffers(1, &vbo);
    if (vao) rgl.DeleteVertexArrays(1, &vao);
    if (prog) rgl.DeleteProgram(prog);
}

void rgl_pass_end(rgl_context *g, rgl_pass *p) {
    int i;
    rgl.Disable(GL_STENCIL_TEST);
    rgl.Disable(GL_DEPTH_TEST);
    if (p->vbo) rgl.DeleteBuffers(1, &p->vbo);
    if (p->vao) rgl.DeleteVertexArrays(1, &p->vao);
    if (p->base_prog) rgl.DeleteProgram(p->base_prog);
    if (p->fbo) {
        rgl.BindFramebuffer(GL_FRAMEBUFFER, rgl_default_framebuffer(g));
        rgl.DeleteFramebuffers(1, &p->fbo);
    }
    if (p->rb[0]) rgl.DeleteRenderbuffers(4, p->rb);
    for (i = 0; i < 3; ++i) free(p->base[i]);
    free(p->marks);
    rgl__geometry_free(&p->geo);
    memset(p, 0, sizeof *p);
}

/* Pixels of the reflectors `handed` marks (one flag per object) drawn by
   the CPU: a one-bounce refl_render of `cpu_method` with every other
   object DIRECT (object_methods), whose pixels of those objects (as its
   stencil or GL's base pass has them) replace GL's: colour, stencil and
   point. Nothing is drawn when none of them is in view. */
static int rgl__hand_over(const rgl_pass *ps, const uint8_t *handed, refl_method cpu_method, refl_frame *frame,
                          float *rgb, rgl_frame_stats *st, long long *pixels, char *err, size_t n) {
    const refl_scene *s = ps->scene;
    int o, c, any = 0;
    size_t i, np = (size_t)ps->w * (size_t)ps->h;
    refl_method *methods;
    refl_render_desc d;
    refl_frame *cpu = NULL;
    int rc = -1;
    for (i = 0; i < np && !any; ++i) {
        int id = (int)ps->base[0][4 * i + 3];
        any = id >= 1 && id <= s->object_count && handed[id - 1];
    }
    if (!any) return 0;
    methods = (refl_method *)calloc((size_t)s->object_count, sizeof *methods);
    if (!methods) goto oom;
    for (o = 0; o < s->object_count; ++o) methods[o] = handed[o] ? cpu_method : REFL_DIRECT;
    memset(&d, 0, sizeof d);
    d.method = cpu_method == REFL_RAYTRACE ? REFL_DIRECT : cpu_method; /* RAYTRACE takes whole frames only */
    d.depth = 1; /* one bounce, as the GL frame */
    d.object_methods = methods;
    d.object_method_count = s->object_count;
    if (refl_frame_create(ps->w, ps->h, NULL, &cpu) != REFL_OK) goto oom;
    if (refl_render(s, ps->view, &d, cpu) != REFL_OK) {
        snprintf(err, n, "the CPU's frame of the reflectors GL leaves to it failed: %s", cpu->message);
        goto done;
    }
    st->handed_over += cpu->stats.handed_over;
    for (i = 0; i < np; ++i) {
        int id = (int)ps->base[0][4 * i + 3], sid = cpu->stencil[i];
        if (!(id >= 1 && id <= s->object_count && handed[id - 1]) && !(sid >= 1 && sid <= s->object_count && handed[sid - 1]))
            continue;
        for (c = 0; c < 3; ++c) {
            rgb[3 * i + c] = cpu->rgba[4 * i + c];
            frame->points[3 * i + c] = cpu->points[3 * i + c];
        }
        frame->stencil[i] = cpu->stencil[i];
        ++*pixels;
    }
    rc = 0;
    goto done;
oom:
    snprintf(err, n, "out of memory");
done:
    refl_frame_destroy(cpu);
    free(methods);
    return rc;
}

/* The reflectors GL does not draw through a mirrored pinhole (curved
   mirrors and partial reflectors, glass) go to the CPU exactly as CPU
   PLANAR hands them over: PLANAR's own `handles` sends each curved
   reflector to RAYTRACE's tracer (stats.handed_over) and draws the planar
   glass itself. */
static int rgl__planar_hand_over(const rgl_pass *ps, refl_frame *frame, float *rgb, rgl_frame_stats *st, char *err,
                                 size_t n) {
    const refl_scene *s = ps->scene;
    int o, k, rc;
    uint8_t *handed = (uint8_t *)calloc((size_t)(s->object_count > 0 ? s->object_count : 1), 1);
    if (!handed) return rgl__frame_fail(err, n, "out of memory");
    for (o = 0; o < s->object_count; ++o) {
        handed[o] = s->materials[s->objects[o].material].type != REFL_DIFFUSE;
        st->handed += handed[o];
    }
    for (k = 0; k < ps->geo.mirror_count; ++k) {
        st->handed -= handed[ps->geo.mirrors[k].object];
        handed[ps->geo.mirrors[k].object] = 0;
    }
    rc = rgl__hand_over(ps, handed, REFL_PLANAR, frame, rgb, st, &st->traced, err, n);
    free(handed);
    return rc;
}

int rgl_hand_over_glass(const rgl_pass *ps, refl_frame *frame, float *rgb, rgl_frame_stats *st, char *err, size_t n) {
    const refl_scene *s = ps->scene;
    int o, rc;
    uint8_t *handed = (uint8_t *)calloc((size_t)(s->object_count > 0 ? s->object_count : 1), 1);
    if (!handed) return rgl__frame_fail(err, n, "out of memory");
    for (o = 0; o < s->object_count; ++o) {
        handed[o] = s->materials[s->objects[o].material].type == REFL_GLASS;
        st->handed += handed[o];
    }
    rc = st->handed ? rgl__hand_over(ps, handed, REFL_RAYTRACE, frame, rgb, st, &st->handed_pixels, err, n) : 0;
    free(handed);
    return rc;
}

int rgl_render_planar(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame, float *rgb,
                      rgl_frame_stats *st, char *err, size_t n) {
    static const char *const mirror_vs[3] = {rgl_frame_vs_head, NULL, rgl__frame_vs_mirror_main};
    const char *fs[1] = {rgl_frame_fs}, *mvs[3];
    int w = view->width, h = view->height, i, k, rc = -1;
    size_t np = (size_t)w * (size_t)h;
    GLuint mirror_prog;
    float mirror_data[24];
    refl_mat4 mirror_vp;
    rgl_method_pass m;
    rgl_pass *ps = &m.ps;
    double t0;
    memset(st, 0, sizeof *st);
    memset(&m, 0, sizeof m);
    if (w < 1 || h < 1 || frame->width != w || frame->height != h) return rgl__frame_fail(err, n, "bad frame size");
    t0 = rgl_now();
    /* the mirrors are known once the geometry is: a first look finds them */
    if (rgl__geometry(scene, view->eye, &ps->geo) != 0) {
        rgl__geometry_free(&ps->geo);
        return rgl__frame_fail(err, n, "out of memory");
    }
    m.mark = (uint8_t *)calloc((size_t)(scene->object_count > 0 ? scene->object_count : 1), 1);
    if (m.mark)
        for (k = 0; k < ps->geo.mirror_count; ++k) m.mark[ps->geo.mirrors[k].object] = (uint8_t)(k + 1);
    rgl__geometry_free(&ps->geo);
    if (!m.mark) return rgl__frame_fail(err, n, "out of memory");
    if (rgl_pass_begin(ps, scene, view, m.mark, err, n) != 0) goto done;
    mvs[0] = mirror_vs[0];
    mvs[1] = refl_gl_glsl(REFL_GL_MIRROR);
    mvs[2] = mirror_vs[2];
    if (!(m.prog = mirror_prog = rgl_program(mvs, 3, fs, 1, NULL, 0, err, n))) goto done;
    {
        /* the mirrored scene lies further away: PLANAR's far plane, doubled
           (near and far read back from the perspective matrix) */
        const refl_mat4 *pm = &ps->proj_m;
        float zn = pm->m[14] / (pm->m[10] - 1.0f), zf = pm->m[14] / (pm->m[10] + 1.0f);
        float fovy = view->fovy_degrees > 0.0f ? view->fovy_degrees : 45.0f;
        mirror_vp = refl_mat4_mul(refl_mat4_perspective(fovy * 3.14159265f / 180.0f, (float)w / (float)h, zn, 2.0f * zf),
                                  ps->view_m);
    }
    st->vertices = ps->geo.vertex_count;
    /* 2. per mirror: the scene through its mirrored pinhole, in its pixels */
    rgl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    rgl.StencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
    rgl.Enable(GL_CLIP_DISTANCE0);
    rgl.UseProgram(mirror_prog);
    rgl.Uniform1i(rgl.GetUniformLocation(mirror_prog, "u_data"), 0);
    rgl.Uniform1i(rgl.GetUniformLocation(mirror_prog, "u_base"), 0);
    for (k = 0; k < ps->geo.mirror_count; ++k) {
        const rgl_mirror *mr = &ps->geo.mirrors[k];
        if (refl_gl_pack_mirror(mirror_vp, refl_v3((float)mr->n[0], (float)mr->n[1], (float)mr->n[2]), (float)mr->d,
                                mirror_data, 24) != 24) {
            rgl__frame_fail(err, n, "refl_gl_pack_mirror refused a mirror");
            goto done;
        }
        if (rgl_method_data(&m, mirror_data, 24, err, n) != 0) goto done;
        rgl.StencilFunc(GL_EQUAL, k + 1, 0xFF);
        for (i = 0; i < scene->object_count; ++i) {
            if (i == mr->object) continue;
            rgl.DrawArrays(GL_TRIANGLES, (GLint)ps->geo.first[i], (GLsizei)(ps->geo.first[i + 1] - ps->geo.first[i]));
            st->vertices += ps->geo.first[i + 1] - ps->geo.first[i];
        }
    }
    rgl.Disable(GL_CLIP_DISTANCE0);
    if (rgl_method_read(&m, 3, "drawing the frame", err, n) != 0) goto done;
    st->gl_seconds = rgl_now() - t0;
    st->mirrors = ps->geo.mirror_count;

    /* 3. shade and composite on the CPU */
    t0 = rgl_now();
    for (i = 0; i < (int)np; ++i) {
        int m_at = ps->marks[i], c;
        refl_vec3 d = rgl_pass_ray(ps, i);
        float col[3];
        frame->stencil[i] = 0;
        for (c = 0; c < 3; ++c) frame->points[3 * i + c] = NAN;
        rgl_shade(scene, ps->base[0] + 4 * i, ps->base[1] + 4 * i, ps->base[2] + 4 * i, d, col);
        if (m_at) {
            const rgl_mirror *mr = &ps->geo.mirrors[m_at - 1];
            const refl_material *mat = &scene->materials[scene->objects[mr->object].material];
            refl_vec3 nrm = refl_v3((float)mr->n[0], (float)mr->n[1], (float)mr->n[2]);
            float sub[3], wgt = refl_material_reflectance(mat, fabsf(refl_v3_dot(d, nrm)));
            const float *rp = m.drawn[0] + 4 * i;
            rgl_shade(scene, rp, m.drawn[1] + 4 * i, m.drawn[2] + 4 * i, refl_v3_reflect(d, nrm), sub);
            for (c = 0; c < 3; ++c) col[c] += wgt * sub[c]; /* col: the mirror's diffuse share */
            frame->stencil[i] = (uint8_t)(mr->object + 1 < 255 ? mr->object + 1 : 255);
            if ((int)rp[3] >= 1)
                for (c = 0; c < 3; ++c) frame->points[3 * i + c] = rp[c];
        }
        for (c = 0; c < 3; ++c) rgb[3 * i + c] = col[c];
    }
    if (rgl__planar_hand_over(ps, frame, rgb, st, err, n) != 0) goto done;
    st->shade_seconds = rgl_now() - t0;
    rc = 0;
done:
    return rgl_method_end(g, &m, rc);
}

int rgl_render(rgl_context *g, refl_method method, const refl_scene *scene, const refl_view *view, refl_frame *frame,
               float *rgb, rgl_frame_stats *st, char *err, size_t n) {
    switch (method) {
    case REFL_PLANAR: return rgl_render_planar(g, scene, view, frame, rgb, st, err, n);
    case REFL_C3RC: return rgl_render_c3rc(g, scene, view, frame, rgb, st, err, n);
    case REFL_SBC: return rgl_render_sbc(g, scene, view, frame, rgb, st, err, n);
    case REFL_SPOC: return rgl_render_spoc(g, scene, view, frame, rgb, st, err, n);
    case REFL_GRAPHCAM: return rgl_render_graphcam(g, scene, view, NULL, frame, rgb, st, err, n);
    case REFL_LAYERED_EM: return rgl_render_layered_em(g, scene, view, frame, rgb, st, err, n);
    default: break;
    }
    snprintf(err, n, "the GL path draws PLANAR, C3RC, SBC, SPOC, GRAPHCAM and LAYERED_EM only");
    return -1;
}
