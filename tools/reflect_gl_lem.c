/* reflect_gl_lem.c - a frame of LAYERED_EM through GL (reflect_gl.h,
   docs/gl.md): the CPU traces the lens's tessellation's vertex paths, GL
   looks the layers up and composites them.
     1. the CPU: a renderer's LAYERED_EM plan of each lens
        (refl_renderer_lem_lenses: the maps of the viewpoint samples the
        eye lies between, inferred as a frame infers them, their blend
        weights, and the eye's tessellation with both greedy paths per
        vertex);
     2. GL: the base pass (reflect_gl_frame.c), each lens marking its
        pixels; per lens, map and term one draw of the tessellation into
        the lens's pixels (depth cleared, as the CPU path's rast.h draw),
        the vertex shader finding each layer's index of the vertex's exit
        ray (refl_lem_shell_index through the packed shells and maps,
        refl_gl_pack_lem_shells), the fragment shader compositing the
        layers front to back (refl_lem_shell_sample, the outermost opaque)
        times the path's F G and the map's weight; alpha 2 where a vertex
        whose path left has no lookup;
     3. the CPU adds the draws over the base pass as the CPU path does; a
        lens pixel no triangle covered, or marked 2, takes RAYTRACE's
        colour (the CPU path's tracer: a RAYTRACE frame of the same desc,
        rendered only when such a pixel exists). */
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

#ifndef GL_ELEMENT_ARRAY_BUFFER
#define GL_ELEMENT_ARRAY_BUFFER 0x8893
#endif

/* per vertex: position, exit origin, exit direction, F G and whether the
   path has a lookup (exited with F > 0 from inside the lens's box), and
   whether it exited with F > 0 at all */
enum { RGL_LEM_VERTEX_FLOATS = 14 };
static const int rgl__lem_sizes[5] = {3, 3, 3, 4, 1};

static const char rgl__lem_vs_head[] =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_p;\n"
    "layout(location = 1) in vec3 a_origin;\n"
    "layout(location = 2) in vec3 a_dir;\n"
    "layout(location = 3) in vec4 a_fg;\n"   /* F G, and 1 where the path has a lookup */
    "layout(location = 4) in float a_exits;\n"
    "uniform samplerBuffer u_data;\n"
    "uniform mat4 u_vp;\n"
    "uniform int u_layers;\n"
    "uniform int u_partial;\n"  /* bit l: refl_lem_shell_partial of layer l */
    "out vec3 v_index[4];\n"
    "out vec4 v_fg;\n";

/* As the CPU path's vertices (m_layered_em.c): layer by layer, a closed
   shell without a lookup takes the vertex's lookup away; a partial layer
   (a quad, an inner sphere) missed leaves its layer out there (index 0,
   interpolated: the share present). */
static const char rgl__lem_vs_main[] =
    "void main() {\n"
    "    bool has = a_fg.w > 0.5;\n"
    "    gl_Position = u_vp * vec4(a_p, 1.0);\n"
    "    for (int l = 0; l < 4; ++l) v_index[l] = vec3(0.0);\n"
    "    for (int l = 0; l < u_layers; ++l) {\n"
    "        bool may_miss = ((u_partial >> l) & 1) != 0;\n"
    "        vec3 index = vec3(0.0, 0.0, may_miss ? 0.0 : 1.0), found;\n"
    "        bool got = has && refl_lem_shell_index(u_data, 0, l, a_origin, a_dir, found);\n"
    "        if (got) index = found;\n"
    "        if (!may_miss) has = has && got;\n"
    "        v_index[l] = index;\n"
    "    }\n"
    "    v_fg = vec4(has ? a_fg.xyz : vec3(0.0), a_exits > 0.5 && !has ? 1.0 : 0.0);\n"
    "}\n";

static const char rgl__lem_fs_head[] =
    "#version 330 core\n"
    "in vec3 v_index[4];\n"
    "in vec4 v_fg;\n"
    "uniform samplerBuffer u_data;\n"
    "uniform int u_layers;\n"
    "uniform int u_partial;\n"
    "uniform float u_weight;\n"
    "layout(location = 0) out vec4 o_colour;\n";

/* The CPU path's fragment (refl__lem_fragment): L1 over L2 over ...,
   premultiplied (an inner sphere's scaled by the share present: its
   index's length over its radius), the outermost opaque, times F G and
   the map's weight; alpha 2 where a vertex's path left with no lookup. */
static const char rgl__lem_fs_main[] =
    "void main() {\n"
    "    float through = 1.0;\n"
    "    o_colour = vec4(0.0, 0.0, 0.0, v_fg.w > 0.0 ? 2.0 : 1.0);\n"
    "    if (!(v_fg.x > 0.0 || v_fg.y > 0.0 || v_fg.z > 0.0)) return;\n"
    "    for (int l = 0; l < u_layers && through > 0.0; ++l) {\n"
    "        bool quad = int(texelFetch(u_data, 1 + 5 * l).y) == 4, may_miss = ((u_partial >> l) & 1) != 0;\n"
    "        float present = !may_miss ? 1.0 : quad ? clamp(v_index[l].z, 0.0, 1.0) :\n"
    "                        clamp(length(v_index[l]) / texelFetch(u_data, 2 + 5 * l).w, 0.0, 1.0);\n"
    "        if (!(present > 0.0)) continue;\n"
    "        vec4 layer = refl_lem_shell_sample(u_data, 0, l, v_index[l]) * (quad ? 1.0 : present);\n"
    "        float a = l == u_layers - 1 ? 1.0 : clamp(layer.w, 0.0, 1.0);\n"
    "        o_colour.xyz += through * layer.xyz;\n"
    "        through *= 1.0 - a;\n"
    "    }\n"
    "    o_colour.xyz *= max(v_fg.xyz, vec3(0.0)) * u_weight;\n"
    "}\n";

void rgl_lem_desc(refl_render_desc *d) {
    memset(d, 0, sizeof *d);
    d->method = REFL_LAYERED_EM;
}

/* Term `term`'s vertices of lens ln (RGL_LEM_VERTEX_FLOATS each). */
static void rgl__lem_vertices(const refl_lem_lens *ln, int term, float *out) {
    int i, k;
    for (i = 0; i < ln->tess.vertex_count; ++i) {
        const refl_lens_vertex *v = &ln->tess.vertices[i];
        const refl_greedy_path *path = term ? &v->paths.refract : &v->paths.reflect;
        refl_vec3 eo = path->exit_origin, ed = path->exit_direction;
        float *o = out + (size_t)i * RGL_LEM_VERTEX_FLOATS;
        int exits = path->fresnel > 0.0f && path->exited;
        int has = exits && eo.x >= ln->box[0].x && eo.y >= ln->box[0].y && eo.z >= ln->box[0].z &&
                  eo.x <= ln->box[1].x && eo.y <= ln->box[1].y && eo.z <= ln->box[1].z;
        o[0] = v->position.x, o[1] = v->position.y, o[2] = v->position.z;
        o[3] = eo.x, o[4] = eo.y, o[5] = eo.z;
        o[6] = ed.x, o[7] = ed.y, o[8] = ed.z;
        for (k = 0; k < 3; ++k) o[9 + k] = path->fresnel * path->attenuation[k];
        o[12] = (float)has;
        o[13] = (float)exits;
    }
}

/* Draws lens ln's map s, term `term`, into its pixels (stencil `mark`),
   reads it back and adds it into sum; seen: 1 covered, 2 a path off the
   maps (the CPU path's). */
static int rgl__lem_draw(const rgl_pass *ps, GLuint prog, const refl_lem_lens *ln, int s, int term, int mark,
                         float *colour, float *sum, uint8_t *seen, rgl_frame_stats *st, char *err, size_t n) {
    GLuint vao = 0, vbo = 0, ibo = 0, tex = 0, tbuf = 0, no_rays[2] = {0, 0};
    long long floats = refl_gl_pack_lem_shells(ln->shell[s], ln->texels[s], ln->layers, NULL, 0);
    float *data = floats > 0 ? (float *)malloc((size_t)floats * sizeof(float)) : NULL;
    float *v = (float *)malloc((size_t)(ln->tess.vertex_count > 0 ? ln->tess.vertex_count : 1) * RGL_LEM_VERTEX_FLOATS *
                               sizeof(float));
    size_t np = (size_t)ps->w * (size_t)ps->h, i;
    int k, rc = -1, partial;
    if (!data || !v || refl_gl_pack_lem_shells(ln->shell[s], ln->texels[s], ln->layers, data, floats) != floats) {
        snprintf(err, n, "refl_gl_pack_lem_shells refused object %d's maps", ln->object);
        goto done;
    }
    if (!(tex = rgl_buffer_texture(data, floats, &tbuf, err, n))) goto done;
    rgl__lem_vertices(ln, term, v);
    rgl_pass_vertices(v, ln->tess.vertex_count, RGL_LEM_VERTEX_FLOATS, rgl__lem_sizes, 5, &vao, &vbo);
    rgl.GenBuffers(1, &ibo);
    rgl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, ibo);
    rgl.BufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr_rgl)(3 * (size_t)ln->tess.triangle_count * sizeof(uint32_t)),
                   ln->tess.indices, GL_STATIC_DRAW);
    rgl.ActiveTexture(GL_TEXTURE0);
    rgl.BindTexture(GL_TEXTURE_BUFFER, tex);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_layers"), ln->layers);
    for (k = partial = 0; k < ln->layers; ++k) partial |= refl_lem_shell_partial(&ln->shell[s][k], ln->box) << k;
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_partial"), partial);
    rgl.Uniform1f(rgl.GetUniformLocation(prog, "u_weight"), ln->weight[s]);
    rgl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    rgl.StencilFunc(GL_EQUAL, mark, 0xFF);
    if (ln->tess.triangle_count > 0)
        rgl.DrawElements(GL_TRIANGLES, 3 * ln->tess.triangle_count, GL_UNSIGNED_INT, (const void *)0);
    st->vertices += 3LL * ln->tess.triangle_count;
    rgl_pass_read(ps, 0, colour);
    if (rgl_pass_check("drawing a LAYERED_EM lens", err, n) != 0) goto done;
    for (i = 0; i < np; ++i) {
        float a = colour[4 * i + 3];
        if (ps->marks[i] != mark || !(a > 0.0f)) continue;
        seen[i] = (uint8_t)(seen[i] > (a > 1.0f ? 2 : 1) ? seen[i] : (a > 1.0f ? 2 : 1));
        for (k = 0; k < 3; ++k) sum[3 * i + k] += colour[4 * i + k];
    }
    rc = 0;
done:
    if (ibo) rgl.DeleteBuffers(1, &ibo);
    rgl_pass_delete(0, vao, vbo, tex, tbuf, no_rays);
    free(data);
    free(v);
    return rc;
}

/* The lens pixels the draws left to the tracer take the CPU path's
   tracer's colour: a RAYTRACE frame of desc d, whole pixels. */
static int rgl__lem_trace(const refl_scene *scene, const refl_view *view, const refl_render_desc *d,
                          const uint8_t *traced, refl_frame *frame, float *rgb, rgl_frame_stats *st, char *err,
                          size_t n) {
    refl_render_desc rt = *d;
    refl_frame *f = NULL;
    size_t np = (size_t)view->width * (size_t)view->height, i;
    int c;
    rt.method = REFL_RAYTRACE;
    if (refl_frame_create(view->width, view->height, NULL, &f) != REFL_OK || refl_render(scene, view, &rt, f) != REFL_OK) {
        refl_frame_destroy(f);
        snprintf(err, n, "the CPU's RAYTRACE frame for the traced lens pixels failed");
        return -1;
    }
    for (i = 0; i < np; ++i) {
        if (!traced[i]) continue;
        for (c = 0; c < 3; ++c) {
            rgb[3 * i + c] = f->rgba[4 * i + c];
            frame->points[3 * i + c] = f->points[3 * i + c];
        }
        st->traced++;
    }
    refl_frame_destroy(f);
    return 0;
}

int rgl_render_layered_em(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame,
                          float *rgb, rgl_frame_stats *st, char *err, size_t n) {
    return rgl_render_layered_em_desc(g, scene, view, NULL, frame, rgb, st, err, n);
}

int rgl_render_layered_em_desc(rgl_context *g, const refl_scene *scene, const refl_view *view,
                               const refl_render_desc *desc, refl_frame *frame, float *rgb, rgl_frame_stats *st,
                               char *err, size_t n) {
    static const char *const vs_parts[3] = {rgl__lem_vs_head, NULL, rgl__lem_vs_main};
    static const char *const fs_parts[3] = {rgl__lem_fs_head, NULL, rgl__lem_fs_main};
    const char *vs[3], *fs[3];
    int w = view->width, h = view->height, rc = -1, count = 0, o, s, term, c, any = 0;
    size_t np = (size_t)w * (size_t)h, i;
    GLuint prog;
    uint8_t *mark, *seen = NULL, *traced = NULL;
    float *colour = NULL, *sum = NULL;
    refl_render_desc d;
    refl_renderer *rr = NULL;
    refl_frame *stats = NULL;
    refl_lem_lens *lenses = NULL;
    rgl_method_pass m;
    const rgl_pass *ps = &m.ps;
    double t0 = rgl_now(), t_cpu, t1;
    memset(st, 0, sizeof *st);
    memset(&m, 0, sizeof m);
    if (w < 1 || h < 1 || frame->width != w || frame->height != h) {
        snprintf(err, n, "bad frame size");
        return -1;
    }
    /* the CPU: the maps and the eye's tessellation (a shared outer layer
       needs nothing here: each lens's plan names the shared map's texels
       and shell as its own outermost layer's) */
    if (desc) d = *desc;
    else rgl_lem_desc(&d);
    if (refl_renderer_create(scene, &d, &rr) != REFL_OK || refl_frame_create(w, h, NULL, &stats) != REFL_OK ||
        refl_renderer_lem_lenses(rr, view, stats, &lenses, &count) != REFL_OK) {
        snprintf(err, n, "LAYERED_EM's lenses failed");
        goto done;
    }
    t_cpu = rgl_now() - t0;
    if (!(mark = m.mark = (uint8_t *)calloc((size_t)(scene->object_count > 0 ? scene->object_count : 1), 1)) ||
        !(seen = (uint8_t *)calloc(np, 1)) || !(traced = (uint8_t *)calloc(np, 1)) ||
        !(colour = (float *)malloc(np * 4 * sizeof(float))) || !(sum = (float *)calloc(np * 3, sizeof(float))))
        goto oom;
    for (o = 0; o < count; ++o)
        if (lenses[o].object < 254) mark[lenses[o].object] = (uint8_t)(lenses[o].object + 1);
    if (rgl_pass_begin(&m.ps, scene, view, mark, err, n) != 0) goto done;
    vs[0] = vs_parts[0], vs[1] = refl_gl_glsl(REFL_GL_LEM_SHELL), vs[2] = vs_parts[2];
    fs[0] = fs_parts[0], fs[1] = vs[1], fs[2] = fs_parts[2];
    if (!(m.prog = prog = rgl_program(vs, 3, fs, 3, NULL, 0, err, n))) goto done;
    rgl.UseProgram(prog);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_data"), 0);
    rgl.UniformMatrix4fv(rgl.GetUniformLocation(prog, "u_vp"), 1, GL_FALSE, ps->vp.m);
    rgl.StencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
    rgl.ClearColor(0, 0, 0, 0);
    for (o = 0; o < count; ++o) {
        const refl_lem_lens *ln = &lenses[o];
        if (!mark[ln->object]) continue;
        st->mirrors++;
        for (s = 0; s < ln->maps; ++s)
            for (term = 0; term < ln->terms; ++term)
                if (rgl__lem_draw(ps, prog, ln, s, term, mark[ln->object], colour, sum, seen, st, err, n) != 0)
                    goto done;
    }
    st->gl_seconds = rgl_now() - t0 - t_cpu;

    /* composite on the CPU: the base pass, the draws added on the lenses */
    t1 = rgl_now();
    for (i = 0; i < np; ++i) {
        const float *bp = ps->base[0] + 4 * i, *bn = ps->base[1] + 4 * i;
        float col[3];
        if (!ps->marks[i]) {
            rgl_composite(ps, (int)i, NULL, NULL, frame, rgb);
            continue;
        }
        rgl_shade(scene, bp, bn, ps->base[2] + 4 * i, rgl_pass_ray(ps, (int)i), col);
        for (c = 0; c < 3; ++c) {
            rgb[3 * i + c] = col[c] + sum[3 * i + c];
            frame->points[3 * i + c] = NAN;
        }
        frame->stencil[i] = ps->marks[i];
        traced[i] = seen[i] != 1;
        any |= traced[i];
    }
    if (any && rgl__lem_trace(scene, view, &d, traced, frame, rgb, st, err, n) != 0) goto done;
    st->shade_seconds = rgl_now() - t1 + t_cpu;
    rc = 0;
    goto done;
oom:
    snprintf(err, n, "out of memory");
done:
    refl_renderer_lem_lenses_free(rr, lenses, count);
    refl_renderer_destroy(rr);
    refl_frame_destroy(stats);
    free(seen);
    free(traced);
    free(colour);
    free(sum);
    return rgl_method_end(g, &m, rc);
}
