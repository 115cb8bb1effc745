/* gl_hooks: the camera models handed to a GL vertex program (DESIGN.md
   section 2, "GL hooks"; docs/gl.md). Each camera packs into plain floats
   that a GLSL 3.30 program reads as a buffer texture of vec4 (GL_RGBA32F,
   texelFetch on a samplerBuffer), and refl_gl_glsl gives the source of the
   function that projects a world point with them. Nothing here calls GL:
   the host (tools/reflect_gl.c) uploads the floats and compiles the source.

   Every block starts with a header texel (kind, REFL_GL_LAYOUT_VERSION,
   then two kind-specific counts) and carries every number its projection
   reads (thresholds included), so a shader needs nothing else. Integers
   (counts, indices, offsets) are stored as floats, exact below 2^24; a
   packer refuses anything larger. Offsets inside a block count texels
   from the block's header. The GLSL mirrors the C projection in float
   where the C computes in double, so the two agree to float rounding
   except where the C's own decisions (a BSP side, a root's existence) sit
   within that rounding. */
#include "cam_sbc_internal.h"

#define REFL__GL_INT_MAX 16777216.0 /* 2^24: integers stored as floats are exact below */

/* (refl__gl_out, refl__gl_put and refl__gl_put4: cam_sbc_internal.h) */

/* A double[3] and a fourth value: one texel. */
static void refl__gl_put3d(refl__gl_out *o, const double *v, double w) { refl__gl_put4(o, v[0], v[1], v[2], w); }

static void refl__gl_put3f(refl__gl_out *o, const float *v, double w) { refl__gl_put4(o, v[0], v[1], v[2], w); }

static void refl__gl_put_v3(refl__gl_out *o, refl_vec3 v, double w) { refl__gl_put4(o, v.x, v.y, v.z, w); }

/* What a packer returns: the floats needed (written when they fit). */
static long long refl__gl_done(const refl__gl_out *o) { return o->n; }

/* ---- PLANAR: the mirrored pinhole -------------------------------------------- */

static long long refl__gl_mirror(refl__gl_out *op, refl_mat4 view_proj, refl_vec3 normal, float d) {
    refl__gl_out o = *op;
    double n[3] = {normal.x, normal.y, normal.z}, len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    refl_mat4 m;
    int i;
    if (!(len > 0.0) || !refl__isfinite(d)) return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < 3; ++i) n[i] /= len;
    /* the same reflection PLANAR draws its mirrored levels with */
    m = refl_mat4_mul(view_proj, refl__planar_reflection(n, d / len));
    refl__gl_put4(&o, REFL_GL_MIRROR, REFL_GL_LAYOUT_VERSION, 0, 0);
    for (i = 0; i < 16; ++i) refl__gl_put(&o, m.m[i]);
    refl__gl_put4(&o, n[0], n[1], n[2], -(double)d / len);
    return refl__gl_done(&o);
}

REFL_API long long refl_gl_pack_mirror(refl_mat4 view_proj, refl_vec3 normal, float d, float *out, long long cap) {
    refl__gl_out o = {NULL, 0, 0};
    long long need = refl__gl_mirror(&o, view_proj, normal, d);
    return refl__gl_fill(&o, need, out, cap) ? refl__gl_mirror(&o, view_proj, normal, d) : need;
}

/* ---- C3RC -------------------------------------------------------------------- */

/* The indices of cam->pre[] (cam_c3rc.c's layout) the GLSL reads. */
enum {
    REFL__GL_C3RC_N0 = 0, REFL__GL_C3RC_N1 = 3, REFL__GL_C3RC_N2 = 6, REFL__GL_C3RC_M = 9, REFL__GL_C3RC_CTR = 13,
    REFL__GL_C3RC_R = 16, REFL__GL_C3RC_INVM = 17, REFL__GL_C3RC_L = 18, REFL__GL_C3RC_E1 = 21,
    REFL__GL_C3RC_E2 = 24, REFL__GL_C3RC_F1 = 27, REFL__GL_C3RC_F2 = 30, REFL__GL_C3RC_D1 = 33,
    REFL__GL_C3RC_U = 36, REFL__GL_C3RC_ULEN = 39
};

static long long refl__gl_c3rc(refl__gl_out *op, const refl_c3rc *cams, int count) {
    refl__gl_out o = *op;
    int i;
    if (count < 0 || (count > 0 && !cams) || count >= REFL__GL_INT_MAX) return REFL_ERROR_INVALID_ARGUMENT;
    refl__gl_put4(&o, REFL_GL_C3RC, REFL_GL_LAYOUT_VERSION, count, REFL_GL_C3RC_TEXELS);
    for (i = 0; i < count; ++i) {
        const double *q = cams[i].pre;
        refl__gl_put_v3(&o, cams[i].v[0], q[REFL__GL_C3RC_R]);
        refl__gl_put_v3(&o, cams[i].v[1], q[REFL__GL_C3RC_INVM]);
        refl__gl_put_v3(&o, cams[i].v[2], q[REFL__GL_C3RC_ULEN]);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_N0, q[REFL__GL_C3RC_M + 0]);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_N1, q[REFL__GL_C3RC_M + 1]);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_N2, q[REFL__GL_C3RC_M + 2]);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_CTR, q[REFL__GL_C3RC_M + 3]);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_E1, q[REFL__GL_C3RC_L + 0]);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_E2, q[REFL__GL_C3RC_L + 1]);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_F1, q[REFL__GL_C3RC_L + 2]);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_F2, 0.0);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_D1, 0.0);
        refl__gl_put3d(&o, q + REFL__GL_C3RC_U, 0.0);
        refl__gl_put4(&o, 0, 0, 0, 0);
        refl__gl_put4(&o, 0, 0, 0, 0);
        refl__gl_put4(&o, 0, 0, 0, 0);
    }
    return refl__gl_done(&o);
}

REFL_API long long refl_gl_pack_c3rc(const refl_c3rc *cams, int count, float *out, long long cap) {
    refl__gl_out o = {NULL, 0, 0};
    long long need = refl__gl_c3rc(&o, cams, count);
    return refl__gl_fill(&o, need, out, cap) ? refl__gl_c3rc(&o, cams, count) : need;
}

/* ---- SBC --------------------------------------------------------------------- */

static long long refl__gl_sbc(refl__gl_out *op, const refl_sbc *sbc) {
    refl__gl_out o = *op;
    long long node_off, cam_off, quad_off, index_off, start_off, list_off, end;
    int i, j;
    if (!sbc || !sbc->nodes) return REFL_ERROR_INVALID_ARGUMENT;
    node_off = REFL_GL_SBC_HEADER_TEXELS;
    cam_off = node_off + (long long)sbc->node_count * REFL_GL_SBC_NODE_TEXELS;
    quad_off = cam_off + (long long)sbc->cam_count * REFL_GL_SBC_CAM_TEXELS;
    index_off = quad_off + (long long)sbc->quad_count * REFL_GL_SBC_QUAD_TEXELS;
    start_off = index_off + (long long)sbc->index_count * REFL_GL_SBC_INDEX_TEXELS;
    list_off = start_off + (sbc->cell_start_count + 3) / 4;
    end = list_off + (sbc->cell_quad_count + 3) / 4;
    if (end >= REFL__GL_INT_MAX) return REFL_ERROR_INVALID_ARGUMENT;
    refl__gl_put4(&o, REFL_GL_SBC, REFL_GL_LAYOUT_VERSION, sbc->node_count, end);
    refl__gl_put4(&o, node_off, cam_off, quad_off, index_off);
    refl__gl_put4(&o, start_off, list_off, 0, 0);
    refl__gl_put4(&o, REFL__SBC_TOL, REFL__SBC_NEAR, REFL__SBC_ON_SURFACE, 0);
    for (i = 0; i < sbc->node_count; ++i) {
        const refl__sbc_node *n = &sbc->nodes[i];
        refl__gl_put3d(&o, n->plane, n->plane[3]);
        refl__gl_put4(&o, n->child, n->kind, n->first, n->count);
        refl__gl_put3f(&o, n->box, n->grid);
        refl__gl_put3f(&o, n->box + 3, 0);
    }
    for (i = 0; i < sbc->cam_count; ++i) {
        const refl__sbc_cam *k = &sbc->cams[i];
        refl__gl_put3d(&o, k->o, k->ho);
        refl__gl_put3d(&o, k->c, k->hmin);
        refl__gl_put3d(&o, k->n, k->ocu);
        refl__gl_put3d(&o, k->eu, k->ocv);
        refl__gl_put3d(&o, k->ev, 0);
        refl__gl_put4(&o, k->rect[0], k->rect[1], k->rect[2], k->rect[3]);
        refl__gl_put4(&o, k->norm[0], k->norm[1], k->norm[2], k->norm[3]);
        for (j = 0; j < 36; ++j) refl__gl_put(&o, k->coef[j / 12][j % 12]);
    }
    for (i = 0; i < sbc->quad_count; ++i) {
        const refl__sbc_quad *q = &sbc->quads[i];
        int c, W = sbc->width;
        refl__gl_put3f(&o, q->o, 0);
        refl__gl_put3f(&o, q->m, 0);
        refl__gl_put3f(&o, q->a, 0);
        refl__gl_put3f(&o, q->b, 0);
        refl__gl_put4(&o, q->tau[0], q->tau[1], q->fold[0], q->fold[1]);
        refl__gl_put4(&o, q->box[0][0], q->box[0][1], q->box[0][2], q->box[0][3]);
        refl__gl_put4(&o, q->box[1][0], q->box[1][1], q->box[1][2], q->box[1][3]);
        refl__gl_put3f(&o, q->aabb, 0);
        refl__gl_put3f(&o, q->aabb + 3, 0);
        refl__gl_put4(&o, q->len[0], q->len[1], q->len[2], q->len[3]);
        for (c = 0; c < 4; ++c)
            for (j = 0; j < 6; ++j) refl__gl_put(&o, q->ray[c][j]);
        /* the four rays' first reflector points, what the blend returns */
        for (c = 0; c < 4; ++c) refl__gl_put_v3(&o, sbc->rays[q->idx + (c & 1) + (c >> 1) * W].first, 0);
    }
    for (i = 0; i < sbc->index_count; ++i) {
        const refl__sbc_index *ix = &sbc->indexes[i];
        refl__gl_put3d(&o, ix->o, ix->t0);
        refl__gl_put3d(&o, ix->m, ix->t_scale);
        refl__gl_put3d(&o, ix->a, ix->x0);
        refl__gl_put3d(&o, ix->b, ix->x_scale);
        refl__gl_put4(&o, ix->y0, ix->y_scale, ix->slabs, ix->cells);
        refl__gl_put4(&o, ix->start, 0, 0, 0);
    }
    for (i = 0; i < (sbc->cell_start_count + 3) / 4 * 4; ++i)
        refl__gl_put(&o, i < sbc->cell_start_count ? sbc->cell_start[i] : 0);
    for (i = 0; i < (sbc->cell_quad_count + 3) / 4 * 4; ++i)
        refl__gl_put(&o, i < sbc->cell_quad_count ? sbc->cell_quads[i] : 0);
    return refl__gl_done(&o);
}

REFL_API long long refl_gl_pack_sbc(const refl_sbc *sbc, float *out, long long cap) {
    refl__gl_out o = {NULL, 0, 0};
    long long need = refl__gl_sbc(&o, sbc);
    return refl__gl_fill(&o, need, out, cap) ? refl__gl_sbc(&o, sbc) : need;
}

/* ---- the graph camera ------------------------------------------------------------ */

static long long refl__gl_graphcam(refl__gl_out *op, const refl_graphcam *cam) {
    refl__gl_out o = *op;
    int f, k;
    if (!cam || cam->count <= 0 || cam->count > REFL_GRAPHCAM_MAX_FRUSTA) return REFL_ERROR_INVALID_ARGUMENT;
    refl__gl_put4(&o, REFL_GL_GRAPHCAM, REFL_GL_LAYOUT_VERSION, cam->count, cam->levels);
    refl__gl_put4(&o, cam->width, cam->height, 0, 0);
    for (f = 0; f < cam->count; ++f) {
        const refl_graphcam_frustum *fr = &cam->frusta[f];
        refl_mat4 m = refl__gc_draw_matrix(cam, f); /* what the impostor is drawn with */
        refl__gl_put4(&o, fr->plane_count, fr->level, fr->parent, 0);
        for (k = 0; k < 16; ++k) refl__gl_put(&o, m.m[k]);
        for (k = 0; k < REFL_GRAPHCAM_MAX_PLANES; ++k) {
            if (k < fr->plane_count) refl__gl_put3d(&o, fr->planes[k], fr->planes[k][3]);
            else refl__gl_put4(&o, 0, 0, 0, 1);
        }
    }
    return refl__gl_done(&o);
}

REFL_API long long refl_gl_pack_graphcam(const refl_graphcam *cam, float *out, long long cap) {
    refl__gl_out o = {NULL, 0, 0};
    long long need = refl__gl_graphcam(&o, cam);
    return refl__gl_fill(&o, need, out, cap) ? refl__gl_graphcam(&o, cam) : need;
}

/* ---- LAYERED_EM: every layer's shell ------------------------------------------ */

/* Header (kind, version, layers, maps or 0), per layer 5 texels (face
   size, shell kind, its map's offset from the header or 0, 0; centre and
   radius; the frame's three axes, each with its half size), then the maps. */
static long long refl__gl_lem_shells(refl__gl_out *op, const refl_lem_shell *shells, const float *const *maps,
                                     int layers) {
    refl__gl_out o = *op;
    long long texels, at;
    int l, k;
    if (!shells || layers <= 0 || layers > REFL_LEM_MAX_LAYERS) return REFL_ERROR_INVALID_ARGUMENT;
    at = 1 + 5LL * layers;
    for (l = 0; l < layers; ++l) {
        const refl_lem_shell *sh = &shells[l];
        int sphere = sh->kind == REFL_LEM_SHELL_AUTO || sh->kind == REFL_LEM_SHELL_SPHERE;
        if (sh->face_size <= 0 || sh->face_size > REFL__LEM_MAX_FACE || !refl__v3_finite(sh->center) || sh->kind < 0 || sh->kind > REFL_LEM_SHELL_QUAD ||
            (sphere && !(sh->radius > 0.0f)))
            return REFL_ERROR_INVALID_ARGUMENT;
        for (k = 0; k < 3 && !sphere; ++k)
            if (!refl__v3_finite(sh->axis[k]) || !refl__isfinite(sh->extent[k])) return REFL_ERROR_INVALID_ARGUMENT;
        texels = 6LL * sh->face_size * sh->face_size;
        if (maps && !maps[l]) return REFL_ERROR_INVALID_ARGUMENT;
        if (at + (maps ? texels : 0) >= REFL__GL_INT_MAX) return REFL_ERROR_INVALID_ARGUMENT;
        at += maps ? texels : 0;
    }
    refl__gl_put4(&o, REFL_GL_LEM_SHELL, REFL_GL_LAYOUT_VERSION, layers, maps ? 1 : 0);
    at = 1 + 5LL * layers;
    for (l = 0; l < layers; ++l) {
        const refl_lem_shell *sh = &shells[l];
        refl__gl_put4(&o, sh->face_size, sh->kind == REFL_LEM_SHELL_AUTO ? REFL_LEM_SHELL_SPHERE : sh->kind,
                      maps ? (double)at : 0.0, 0);
        refl__gl_put_v3(&o, sh->center, sh->radius);
        for (k = 0; k < 3; ++k) refl__gl_put_v3(&o, sh->axis[k], sh->extent[k]);
        at += maps ? 6LL * sh->face_size * sh->face_size : 0;
    }
    for (l = 0; maps && l < layers; ++l) {
        long long i, n = 4 * 6LL * shells[l].face_size * shells[l].face_size;
        for (i = 0; i < n; ++i) refl__gl_put(&o, maps[l][i]);
    }
    return refl__gl_done(&o);
}

REFL_API long long refl_gl_pack_lem_shells(const refl_lem_shell *shells, const float *const *maps, int layers,
                                           float *out, long long cap) {
    refl__gl_out o = {NULL, 0, 0};
    long long need = refl__gl_lem_shells(&o, shells, maps, layers);
    return refl__gl_fill(&o, need, out, cap) ? refl__gl_lem_shells(&o, shells, maps, layers) : need;
}

REFL_API long long refl_gl_pack_lem_shell(const refl_lem_shell *shell, const float *map, float *out, long long cap) {
    return refl_gl_pack_lem_shells(shell, map ? &map : NULL, 1, out, cap);
}

/* ---- the SPOC ------------------------------------------------------------------- */

static long long refl__gl_spoc(refl__gl_out *op, const refl_spoc *cam) {
    refl__gl_out o = *op;
    if (!cam || !(cam->focal > 0.0f) || !(cam->znear > 0.0f) || !(cam->zfar > cam->znear))
        return REFL_ERROR_INVALID_ARGUMENT;
    refl__gl_put4(&o, REFL_GL_SPOC, REFL_GL_LAYOUT_VERSION, 0, 0);
    refl__gl_put_v3(&o, cam->eye, cam->focal);
    refl__gl_put_v3(&o, cam->right, cam->ramp);
    refl__gl_put_v3(&o, cam->up, cam->delta_max);
    refl__gl_put_v3(&o, cam->forward, 0.0);
    refl__gl_put4(&o, 1.0 / cam->znear, 1.0 / cam->zfar, cam->pole[0], cam->pole[1]);
    return refl__gl_done(&o);
}

REFL_API long long refl_gl_pack_spoc(const refl_spoc *cam, float *out, long long cap) {
    refl__gl_out o = {NULL, 0, 0};
    long long need = refl__gl_spoc(&o, cam);
    return refl__gl_fill(&o, need, out, cap) ? refl__gl_spoc(&o, cam) : need;
}

/* ---- the SPOC impostor ---------------------------------------------------------- */

/* Everything refl_impostor_intersect reads of an impostor whose camera is
   the SPOC cam: its sphere, tolerance, the camera's block, and per texel
   colour and gd together (-1: nothing stored, where the C reads alpha 0). */
static long long refl__gl_spoc_impostor(refl__gl_out *op, const refl_impostor *imp, const refl_spoc *cam) {
    refl__gl_out o = *op;
    long long nn, i, spoc;
    if (!imp || !cam || imp->camera.cam != (const void *)cam || imp->width != cam->size || imp->height != cam->size ||
        imp->layers < 1 || imp->layers > REFL_IMPOSTOR_MAX_LAYERS || !imp->color || !imp->depth)
        return REFL_ERROR_INVALID_ARGUMENT;
    nn = (long long)imp->width * imp->height * imp->layers;
    if ((double)(REFL_GL_SPOC_IMPOSTOR_TEXELS + nn) >= REFL__GL_INT_MAX) return REFL_ERROR_INVALID_ARGUMENT;
    refl__gl_put4(&o, REFL_GL_SPOC_IMPOSTOR, REFL_GL_LAYOUT_VERSION, imp->width, imp->layers);
    refl__gl_put_v3(&o, imp->camera.center, imp->camera.radius);
    refl__gl_put4(&o, imp->depth_tolerance, imp->height, REFL_GL_SPOC_IMPOSTOR_TEXELS, 0.0);
    spoc = refl__gl_spoc(&o, cam);
    if (spoc < 0) return spoc;
    o.n = spoc;
    for (i = 0; i < nn; ++i) {
        const float *c = imp->color + 4 * i;
        refl__gl_put4(&o, c[0], c[1], c[2], c[3] > 0.0f ? imp->depth[i] : -1.0);
    }
    return refl__gl_done(&o);
}

REFL_API long long refl_gl_pack_spoc_impostor(const refl_impostor *imp, const refl_spoc *cam, float *out,
                                              long long cap) {
    refl__gl_out o = {NULL, 0, 0};
    long long need = refl__gl_spoc_impostor(&o, imp, cam);
    return refl__gl_fill(&o, need, out, cap) ? refl__gl_spoc_impostor(&o, imp, cam) : need;
}

/* ---- the graph camera's impostor ------------------------------------------------ */

/* Everything refl_graphcam_intersect's algorithm 2 reads: the camera's
   bounds (the ray's slab clip), its block, and per pixel colour, frustum
   id and gd. */
static long long refl__gl_graphcam_impostor(refl__gl_out *op, const refl_graphcam *cam,
                                           const refl_graphcam_impostor *imp) {
    refl__gl_out o = *op;
    long long npx, i, cam_texels, color, depth;
    refl_vec3 lo, hi;
    if (!cam || !imp || imp->width != cam->width || imp->height != cam->height || !imp->rgba || !imp->depth ||
        !imp->frustum)
        return REFL_ERROR_INVALID_ARGUMENT;
    if (cam->count <= 0 || cam->count > REFL_GRAPHCAM_MAX_FRUSTA) return REFL_ERROR_INVALID_ARGUMENT;
    cam_texels = 2 + (long long)REFL_GL_GRAPHCAM_TEXELS * cam->count; /* refl__gl_graphcam's block */
    npx = (long long)imp->width * imp->height;
    color = REFL_GL_GRAPHCAM_IMPOSTOR_CAMERA + cam_texels;
    depth = color + npx;
    if ((double)(depth + (npx + 3) / 4) >= REFL__GL_INT_MAX) return REFL_ERROR_INVALID_ARGUMENT;
    refl_graphcam_bounds(cam, &lo, &hi);
    refl__gl_put4(&o, REFL_GL_GRAPHCAM_IMPOSTOR, REFL_GL_LAYOUT_VERSION, imp->width, imp->height);
    refl__gl_put_v3(&o, lo, (double)color);
    refl__gl_put_v3(&o, hi, (double)depth);
    o.n = refl__gl_graphcam(&o, cam);
    for (i = 0; i < npx; ++i) {
        const float *c = imp->rgba + 4 * i;
        refl__gl_put4(&o, c[0], c[1], c[2], imp->frustum[i]);
    }
    for (i = 0; i < (npx + 3) / 4 * 4; ++i) refl__gl_put(&o, i < npx ? imp->depth[i] : 1.0);
    return refl__gl_done(&o);
}

REFL_API long long refl_gl_pack_graphcam_impostor(const refl_graphcam *cam, const refl_graphcam_impostor *imp,
                                                  float *out, long long cap) {
    refl__gl_out o = {NULL, 0, 0};
    long long need = refl__gl_graphcam_impostor(&o, cam, imp);
    return refl__gl_fill(&o, need, out, cap) ? refl__gl_graphcam_impostor(&o, cam, imp) : need;
}

/* ---- GLSL -------------------------------------------------------------------- */

static const char refl__gl_glsl_mirror[] =
    "/* reflect.h GL hook: PLANAR's mirrored pinhole (layout version 1). */\n"
    "vec4 refl_mirror_project(samplerBuffer data, int base, vec3 p, out float clip_distance) {\n"
    "    mat4 m = mat4(texelFetch(data, base + 1), texelFetch(data, base + 2),\n"
    "                  texelFetch(data, base + 3), texelFetch(data, base + 4));\n"
    "    vec4 plane = texelFetch(data, base + 5);\n"
    "    clip_distance = dot(plane.xyz, p) + plane.w;\n"
    "    return m * vec4(p, 1.0);\n"
    "}\n";

static const char refl__gl_glsl_c3rc[] =
    "/* reflect.h GL hook: C3RC (layout version 1); cam_c3rc.c's projection in float, with\n"
    "   the cubic F(t) evaluated in the sweeping triangle's own frame. */\n"
    "struct refl_c3rc_frame { vec3 e1, e2, f1, f2, d1, wu; };\n"
    "/* F(t) = (E1(t) x E2(t)) . (P - V1(t)): the cubic cam_c3rc.c expands into\n"
    "   coefficients, here from the triangle's edges and P's offset at t, whose\n"
    "   rounding is relative to the triangle and not to P's distance from it\n"
    "   (in float the expanded form decides a fold's double root wrongly). */\n"
    "float refl_c3rc_F(refl_c3rc_frame k, float t) {\n"
    "    return dot(cross(k.e1 + t * k.f1, k.e2 + t * k.f2), k.wu - t * k.d1);\n"
    "}\n"
    "/* the root in (lo, hi) where the cubic c is monotone and F changes sign:\n"
    "   Newton steps kept inside the bracket, bisection otherwise */\n"
    "float refl_c3rc_root(refl_c3rc_frame k, vec4 c, float lo, float hi, float flo) {\n"
    "    float x = 0.5 * (lo + hi);\n"
    "    for (int it = 0; it < 80; ++it) {\n"
    "        float f = refl_c3rc_F(k, x);\n"
    "        if (f == 0.0) return x;\n"
    "        if ((f < 0.0) == (flo < 0.0)) lo = x; else hi = x;\n"
    "        float df = (3.0 * c.w * x + 2.0 * c.z) * x + c.y;\n"
    "        float xn = df != 0.0 ? x - f / df : lo;\n"
    "        if (!(xn > lo && xn < hi)) xn = 0.5 * (lo + hi);\n"
    "        if (xn == x || hi - lo <= 1e-7 * max(abs(lo), abs(hi))) return xn;\n"
    "        x = xn;\n"
    "    }\n"
    "    return x;\n"
    "}\n"
    "bool refl_c3rc_bary(refl_c3rc_frame k, float t, out vec3 abc) {\n"
    "    vec3 E1 = k.e1 + t * k.f1, E2 = k.e2 + t * k.f2, W = k.wu - t * k.d1;\n"
    "    vec3 n = cross(E1, E2);\n"
    "    float n2 = dot(n, n);\n"
    "    if (!(n2 > 1e-14 * dot(E1, E1) * dot(E2, E2))) return false;\n"
    "    float b = dot(cross(W, E2), n) / n2, c = dot(cross(E1, W), n) / n2, a = 1.0 - b - c;\n"
    "    if (!(a >= -1e-6 && b >= -1e-6 && c >= -1e-6)) return false;\n"
    "    abc = clamp(vec3(a, b, c), 0.0, 1.0);\n"
    "    abc /= abc.x + abc.y + abc.z;\n"
    "    return true;\n"
    "}\n"
    "/* Every projection (a, b, c, t) of p through camera `cam` of the block at\n"
    "   `base`, ascending in t, into proj; returns how many (0..3). The C decides\n"
    "   a root at a fold (F's extremum near 0) in double with a rounding bound;\n"
    "   here F's float sign alone decides: a bound in float would only widen the\n"
    "   band of points where the two disagree. */\n"
    "int refl_c3rc_project(samplerBuffer data, int base, int cam, vec3 p, out vec4 proj[3]) {\n"
    "    int o = base + 1 + cam * 16;\n"
    "    vec4 t0 = texelFetch(data, o), t1 = texelFetch(data, o + 1);\n"
    "    vec4 n0 = texelFetch(data, o + 3), n1 = texelFetch(data, o + 4), n2 = texelFetch(data, o + 5);\n"
    "    vec4 ct = texelFetch(data, o + 6);\n"
    "    vec3 w = p - ct.xyz;\n"
    "    float r = length(w);\n"
    "    refl_c3rc_frame k;\n"
    "    k.e1 = texelFetch(data, o + 7).xyz;\n"
    "    k.e2 = texelFetch(data, o + 8).xyz;\n"
    "    k.f1 = texelFetch(data, o + 9).xyz;\n"
    "    k.f2 = texelFetch(data, o + 10).xyz;\n"
    "    k.d1 = texelFetch(data, o + 11).xyz;\n"
    "    k.wu = w + texelFetch(data, o + 12).xyz;\n"
    "    vec4 c = vec4(dot(n0.xyz, w) + n0.w, dot(n1.xyz, w) + n1.w, dot(n2.xyz, w) + n2.w, ct.w);\n"
    "    float T = (r + t0.w) * t1.w * 1.001;\n"
    "    float x[4], f[4], cand[4];\n"
    "    int nx = 1, nc = 0, n = 0;\n"
    "    x[0] = -2e-6 * t0.w;\n"
    "    f[0] = refl_c3rc_F(k, x[0]);\n"
    "    float disc = c.z * c.z - 3.0 * c.w * c.y;\n"
    "    if (disc >= 0.0) {\n"
    "        float s = sqrt(disc), qq = -(c.z + (c.z >= 0.0 ? s : -s));\n"
    "        if (qq != 0.0) {\n"
    "            float r1 = c.w != 0.0 ? qq / (3.0 * c.w) : T, r2 = c.y / qq;\n"
    "            if (r1 > r2) { s = r1; r1 = r2; r2 = s; }\n"
    "            if (r1 > x[0] && r1 < T) x[nx++] = r1;\n"
    "            if (r2 > x[0] && r2 < T && r2 != r1) x[nx++] = r2;\n"
    "        }\n"
    "    }\n"
    "    for (int i = 1; i < nx; ++i) f[i] = refl_c3rc_F(k, x[i]);\n"
    "    x[nx] = T;\n"
    "    f[nx] = refl_c3rc_F(k, T);\n"
    "    for (int i = 0; i < nx; ++i) {\n"
    "        if (f[i] == 0.0) cand[nc++] = x[i];\n"
    "        else if ((f[i] < 0.0 && f[i + 1] > 0.0) || (f[i] > 0.0 && f[i + 1] < 0.0))\n"
    "            cand[nc++] = refl_c3rc_root(k, c, x[i], x[i + 1], f[i]);\n"
    "    }\n"
    "    if (f[nx] == 0.0) cand[nc++] = T;\n"
    "    for (int i = 0; i < nc && n < 3; ++i) {\n"
    "        vec3 abc;\n"
    "        if (!refl_c3rc_bary(k, cand[i], abc)) continue;\n"
    "        proj[n++] = vec4(abc, max(cand[i], 0.0));\n"
    "    }\n"
    "    return n;\n"
    "}\n"
    "/* The image point of a projection: its reflector point a v1 + b v2 + c v3. */\n"
    "vec3 refl_c3rc_image(samplerBuffer data, int base, int cam, vec4 proj) {\n"
    "    int o = base + 1 + cam * 16;\n"
    "    return proj.x * texelFetch(data, o).xyz + proj.y * texelFetch(data, o + 1).xyz +\n"
    "           proj.z * texelFetch(data, o + 2).xyz;\n"
    "}\n";

static const char refl__gl_glsl_sbc[] =
    "/* reflect.h GL hook: SBC (layout version 1); cam_sbc.c's BSP descent, cam_sbc_fit.c's\n"
    "   pinhole leaves and cam_sbc_raylist.c's ray-list leaves (one sheet for all, or\n"
    "   per sheet) in float. */\n"
    "float refl_sbc_cross2(vec2 a, vec2 b) { return a.x * b.y - a.y * b.x; }\n"
    "int refl_sbc_quadratic(float a, float b, float c, out vec2 r) {\n"
    "    if (abs(a) <= 1e-6 * (abs(b) + abs(c))) {\n"
    "        if (b == 0.0) return 0;\n"
    "        r = vec2(-c / b);\n"
    "        return 1;\n"
    "    }\n"
    "    float disc = b * b - 4.0 * a * c;\n"
    "    if (disc < 0.0) return 0;\n"
    "    float q = -0.5 * (b + (b >= 0.0 ? sqrt(disc) : -sqrt(disc)));\n"
    "    if (q == 0.0) { r = vec2(0.0); return 1; }\n"
    "    r = vec2(min(q / a, c / q), max(q / a, c / q));\n"
    "    return 2;\n"
    "}\n"
    "/* inverse bilinear interpolation of corners (0,0) (1,0) (0,1) (1,1) */\n"
    "bool refl_sbc_inv_bilinear(vec2 c0, vec2 c1, vec2 c2, vec2 c3, vec2 p, float tol, out vec2 st, out float outside) {\n"
    "    vec2 e = c1 - c0, f = c2 - c0, g = c0 - c1 - c2 + c3, h = p - c0, r;\n"
    "    float best = 3.0e38;\n"
    "    int nr = refl_sbc_quadratic(refl_sbc_cross2(g, f), refl_sbc_cross2(e, f) + refl_sbc_cross2(h, g),\n"
    "                                refl_sbc_cross2(h, e), r);\n"
    "    for (int i = 0; i < nr; ++i) {\n"
    "        float tt = r[i], ss;\n"
    "        vec2 d = e + g * tt;\n"
    "        if (!(tt >= -tol && tt <= 1.0 + tol)) continue;\n"
    "        if (abs(d.x) >= abs(d.y)) { if (d.x == 0.0) continue; ss = (h.x - f.x * tt) / d.x; }\n"
    "        else ss = (h.y - f.y * tt) / d.y;\n"
    "        if (!(ss >= -tol && ss <= 1.0 + tol)) continue;\n"
    "        float o = max(max(max(-ss, ss - 1.0), max(-tt, tt - 1.0)), 0.0);\n"
    "        if (!(o < best)) continue;\n"
    "        best = o;\n"
    "        st = clamp(vec2(ss, tt), 0.0, 1.0);\n"
    "        if (o == 0.0) break;\n"
    "    }\n"
    "    outside = best;\n"
    "    return best < 3.0e38;\n"
    "}\n"
    "bool refl_sbc_pinhole(samplerBuffer data, int k, vec3 p, out vec3 first, out float z) {\n"
    "    vec4 o = texelFetch(data, k), c = texelFetch(data, k + 1), n = texelFetch(data, k + 2);\n"
    "    vec4 eu = texelFetch(data, k + 3), ev = texelFetch(data, k + 4);\n"
    "    vec4 rect = texelFetch(data, k + 5), norm = texelFetch(data, k + 6);\n"
    "    float hp = dot(p - c.xyz, n.xyz), den = o.w - hp;\n"
    "    if (!(hp >= c.w) || !(o.w * den > 0.0)) return false;\n"
    "    float s = o.w / den;\n"
    "    vec3 w = p - o.xyz;\n"
    "    float u = n.w + s * dot(w, eu.xyz), v = eu.w + s * dot(w, ev.xyz);\n"
    "    if (!(u >= rect.x && u <= rect.y && v >= rect.z && v <= rect.w)) return false;\n"
    "    float x = (u - norm.x) * norm.z, y = (v - norm.y) * norm.w, sd = hp / (hp - o.w);\n"
    "    float b[12] = float[12](1.0, x, y, x * x, x * y, y * y, sd, sd * x, sd * y, sd * x * x, sd * x * y, sd * y * y);\n"
    "    for (int i = 0; i < 3; ++i) {\n"
    "        float acc = 0.0;\n"
    "        for (int j = 0; j < 12; ++j) acc += texelFetch(data, k + 7 + (i * 12 + j) / 4)[(i * 12 + j) % 4] * b[j];\n"
    "        first[i] = acc;\n"
    "    }\n"
    "    z = max(hp, 0.0);\n"
    "    return true;\n"
    "}\n"
    "float refl_sbc_int(samplerBuffer data, int at, int i) { return texelFetch(data, at + i / 4)[i % 4]; }\n"
    "/* a ray-list leaf per sheet (sheets 0: one for all, as if no ray folded;\n"
    "   cam_sbc_raylist.c's refl__sbc_rays_project): the mask of the sheets p\n"
    "   projects in, first[i] and z[i] sheet i's answer */\n"
    "int refl_sbc_rays_sheets(samplerBuffer data, int base, vec4 nd1, vec4 nd2, vec4 nd3, vec3 p, int sheets,\n"
    "                         out vec3 first[3], out float z[3]) {\n"
    "    first = vec3[3](vec3(0.0), vec3(0.0), vec3(0.0));\n"
    "    z = float[3](0.0, 0.0, 0.0);\n"
    "    if (any(lessThan(p, nd2.xyz)) || any(greaterThan(p, nd3.xyz))) return 0;\n"
    "    vec4 h1 = texelFetch(data, base + 1), h2 = texelFetch(data, base + 2), th = texelFetch(data, base + 3);\n"
    "    int from = 0, to = int(nd1.w), grid = int(nd2.w), quads = base + int(h1.z);\n"
    "    int list = -1;\n"
    "    if (grid > 0) {\n"
    "        int ix = base + int(h1.w) + (grid - 1) * 6;\n"
    "        vec4 i0 = texelFetch(data, ix), i1 = texelFetch(data, ix + 1), i2 = texelFetch(data, ix + 2);\n"
    "        vec4 i3 = texelFetch(data, ix + 3), i4 = texelFetch(data, ix + 4), i5 = texelFetch(data, ix + 5);\n"
    "        vec3 w = p - i0.xyz;\n"
    "        float t = (dot(w, i1.xyz) - i0.w) * i1.w, x = (dot(w, i2.xyz) - i2.w) * i3.w;\n"
    "        float y = (dot(w, i3.xyz) - i4.x) * i4.y;\n"
    "        if (!(t >= 0.0 && t < i4.z && x >= 0.0 && x < i4.w && y >= 0.0 && y < i4.w)) return 0;\n"
    "        int cells = int(i4.w);\n"
    "        int at = int(i5.x) + (int(t) * cells + int(y)) * cells + int(x);\n"
    "        from = int(refl_sbc_int(data, base + int(h2.x), at));\n"
    "        to = int(refl_sbc_int(data, base + int(h2.x), at + 1));\n"
    "        list = base + int(h2.y);\n"
    "    }\n"
    "    /* per sheet and rank (2 sheet + 0 inside a quad, + 1 near one): off the\n"
    "       surface, how far outside, depth */\n"
    "    bool off[6] = bool[6](false, false, false, false, false, false);\n"
    "    float outv[6] = float[6](3.0e38, 3.0e38, 3.0e38, 3.0e38, 3.0e38, 3.0e38);\n"
    "    float zz[6] = float[6](3.0e38, 3.0e38, 3.0e38, 3.0e38, 3.0e38, 3.0e38);\n"
    "    vec3 fp[6];\n"
    "    for (int at = from; at < to; ++at) {\n"
    "        int q = quads + (int(nd1.z) + (list >= 0 ? int(refl_sbc_int(data, list, at)) : at)) * 20;\n"
    "        vec4 lo = texelFetch(data, q + 7), hi = texelFetch(data, q + 8);\n"
    "        if (any(lessThan(p, lo.xyz)) || any(greaterThan(p, hi.xyz))) continue;\n"
    "        vec3 w = p - texelFetch(data, q).xyz;\n"
    "        vec4 tf = texelFetch(data, q + 4), b0 = texelFetch(data, q + 5), b1 = texelFetch(data, q + 6);\n"
    "        float tau = dot(w, texelFetch(data, q + 1).xyz);\n"
    "        if (!(tau >= tf.x && tau <= tf.y)) continue;\n"
    "        int sheet = sheets > 0 ? int(tau > tf.z) + int(tau > tf.w) : 0;\n" /* past its folds */
    "        if (sheets > 0 && sheet >= sheets) continue;\n"
    "        int b = 2 * sheet;\n"
    "        float fr = (tau - tf.x) / (tf.y - tf.x);\n"
    "        float x = dot(w, texelFetch(data, q + 2).xyz);\n"
    "        if (!(x >= b0.x + fr * (b1.x - b0.x) && x <= b0.y + fr * (b1.y - b0.y))) continue;\n"
    "        float y = dot(w, texelFetch(data, q + 3).xyz);\n"
    "        if (!(y >= b0.z + fr * (b1.z - b0.z) && y <= b0.w + fr * (b1.w - b0.w))) continue;\n"
    "        vec2 c4[4];\n"
    "        vec4 lam, len = texelFetch(data, q + 9);\n"
    "        for (int c = 0; c < 4; ++c) {\n"
    "            vec4 ra = texelFetch(data, q + 10 + (c * 6) / 4), rb = texelFetch(data, q + 10 + (c * 6) / 4 + 1);\n"
    "            float r6[6];\n"
    "            int s0 = (c * 6) % 4;\n"
    "            for (int j = 0; j < 6; ++j) r6[j] = s0 + j < 4 ? ra[s0 + j] : rb[s0 + j - 4];\n"
    "            float l = (tau - r6[0]) / r6[3];\n"
    "            c4[c] = vec2(r6[1] + l * r6[4], r6[2] + l * r6[5]);\n"
    "            lam[c] = l;\n"
    "        }\n"
    "        vec2 st;\n"
    "        float o;\n"
    "        if (!refl_sbc_inv_bilinear(c4[0], c4[1], c4[2], c4[3], vec2(x, y), zz[b] < 3.0e38 ? th.x : 0.5, st, o))\n"
    "            continue;\n"
    "        vec4 wt = vec4((1.0 - st.x) * (1.0 - st.y), st.x * (1.0 - st.y), (1.0 - st.x) * st.y, st.x * st.y);\n"
    "        int k = b + (o > th.x ? 1 : 0);\n"
    "        o = 0.0;\n"
    "        if (k > b && zz[b] < 3.0e38) continue;\n"
    "        if (k > b) {\n"
    "            vec2 d = vec2(x, y) - (wt.x * c4[0] + wt.y * c4[1] + wt.z * c4[2] + wt.w * c4[3]);\n"
    "            vec2 d1 = c4[3] - c4[0], d2 = c4[2] - c4[1];\n"
    "            o = dot(d, d) / max(dot(d1, d1), dot(d2, d2));\n"
    "            if (!(o <= th.y * th.y)) continue;\n"
    "        }\n"
    "        float zq = dot(wt, lam * len), lm = dot(wt, lam);\n"
    "        if (!(lm >= -1e-4)) continue;\n"
    "        if (off[k] && lm < th.z) continue;\n"
    "        if (!(!off[k] && lm >= th.z)) {\n"
    "            if (o > outv[k]) continue;\n"
    "            if (o == outv[k] && !(zq < zz[k])) continue;\n"
    "        }\n"
    "        off[k] = lm >= th.z;\n"
    "        zz[k] = zq;\n"
    "        outv[k] = o;\n"
    "        fp[k] = wt.x * texelFetch(data, q + 16).xyz + wt.y * texelFetch(data, q + 17).xyz +\n"
    "                wt.z * texelFetch(data, q + 18).xyz + wt.w * texelFetch(data, q + 19).xyz;\n"
    "    }\n"
    "    int mask = 0;\n"
    "    for (int i = 0; i < max(sheets, 1); ++i) {\n"
    "        int k = zz[2 * i] < 3.0e38 ? 2 * i : 2 * i + 1;\n"
    "        if (!(zz[k] < 3.0e38)) continue;\n"
    "        first[i] = fp[k];\n"
    "        z[i] = max(zz[k], 0.0);\n"
    "        mask |= 1 << i;\n"
    "    }\n"
    "    return mask;\n"
    "}\n"
    "/* the BSP descent: the node index of the leaf holding p */\n"
    "int refl_sbc_leaf(samplerBuffer data, int base, vec3 p) {\n"
    "    int nodes = base + int(texelFetch(data, base + 1).x), node = 0;\n"
    "    vec4 nd1 = texelFetch(data, nodes + 1);\n"
    "    while (int(nd1.y) == 2) {\n"
    "        vec4 pl = texelFetch(data, nodes + node * 4);\n"
    "        node = int(nd1.x) + (dot(pl.xyz, p) + pl.w >= 0.0 ? 0 : 1);\n"
    "        nd1 = texelFetch(data, nodes + node * 4 + 1);\n"
    "    }\n"
    "    return node;\n"
    "}\n"
    "/* p's projection through the SBC block at `base`: true with the first\n"
    "   reflector point and the visibility offset z, false when p lies in no\n"
    "   leaf's frustum. leaf_kind: 1 pinhole, 0 ray list. */\n"
    "bool refl_sbc_project(samplerBuffer data, int base, vec3 p, out vec3 first, out float z, out int leaf_kind) {\n"
    "    vec4 h1 = texelFetch(data, base + 1);\n"
    "    int nodes = base + int(h1.x), node = refl_sbc_leaf(data, base, p);\n"
    "    vec4 nd1 = texelFetch(data, nodes + node * 4 + 1);\n"
    "    vec3 fs[3];\n"
    "    float zs[3];\n"
    "    first = vec3(0.0);\n"
    "    z = 0.0;\n"
    "    leaf_kind = int(nd1.y);\n"
    "    if (leaf_kind == 1) return refl_sbc_pinhole(data, base + int(h1.y) + int(nd1.z) * 16, p, first, z);\n"
    "    if (refl_sbc_rays_sheets(data, base, nd1, texelFetch(data, nodes + node * 4 + 2),\n"
    "                             texelFetch(data, nodes + node * 4 + 3), p, 0, fs, zs) == 0)\n"
    "        return false;\n"
    "    first = fs[0];\n"
    "    z = zs[0];\n"
    "    return true;\n"
    "}\n"
    "/* p's projection in each of `sheets` sheets (1 .. 3; refl_sbc_project_sheets):\n"
    "   the mask of the sheets it projects in (a pinhole leaf: sheet 0 alone) */\n"
    "int refl_sbc_project_sheets(samplerBuffer data, int base, vec3 p, int sheets, out vec3 first[3], out float z[3]) {\n"
    "    vec4 h1 = texelFetch(data, base + 1);\n"
    "    int nodes = base + int(h1.x), node = refl_sbc_leaf(data, base, p);\n"
    "    vec4 nd1 = texelFetch(data, nodes + node * 4 + 1);\n"
    "    first = vec3[3](vec3(0.0), vec3(0.0), vec3(0.0));\n"
    "    z = float[3](0.0, 0.0, 0.0);\n"
    "    if (int(nd1.y) == 1) return refl_sbc_pinhole(data, base + int(h1.y) + int(nd1.z) * 16, p, first[0], z[0]) ? 1 : 0;\n"
    "    return refl_sbc_rays_sheets(data, base, nd1, texelFetch(data, nodes + node * 4 + 2),\n"
    "                                texelFetch(data, nodes + node * 4 + 3), p, clamp(sheets, 1, 3), first, z);\n"
    "}\n";

static const char refl__gl_glsl_graphcam[] =
    "/* reflect.h GL hook: the graph camera (layout version 1): the first frustum\n"
    "   whose region holds p (cam_graph.c's locate), then its matrix. */\n"
    "vec4 refl_graphcam_project(samplerBuffer data, int base, vec3 p, out int frustum) {\n"
    "    int count = int(texelFetch(data, base).z);\n"
    "    frustum = -1;\n"
    "    for (int f = 0; f < count; ++f) {\n"
    "        int b = base + 2 + f * 21;\n"
    "        int planes = int(texelFetch(data, b).x);\n"
    "        bool inside = true;\n"
    "        for (int k = 0; k < planes && inside; ++k) {\n"
    "            vec4 pl = texelFetch(data, b + 5 + k);\n"
    "            inside = dot(pl.xyz, p) + pl.w >= 0.0;\n"
    "        }\n"
    "        if (inside) {\n"
    "            frustum = f;\n"
    "            mat4 m = mat4(texelFetch(data, b + 1), texelFetch(data, b + 2),\n"
    "                          texelFetch(data, b + 3), texelFetch(data, b + 4));\n"
    "            return m * vec4(p, 1.0);\n"
    "        }\n"
    "    }\n"
    "    return vec4(0.0);\n"
    "}\n";

static const char refl__gl_glsl_sbc_morph[] =
    "/* reflect.h GL hook: an SBC morph grid (layout version 1), cam_sbc_morph.c's\n"
    "   refl_sbc_morph_project in float: the eye's tetrahedron of nodes, each node's\n"
    "   face SBCs (refl_sbc_project, REFL_GL_SBC's source), the blend. */\n"
    "int refl_sbm_face_of(vec3 v) {\n"
    "    vec3 a = abs(v);\n"
    "    if (a.x >= a.y && a.x >= a.z) return v.x >= 0.0 ? 0 : 1;\n"
    "    if (a.y >= a.z) return v.y >= 0.0 ? 2 : 3;\n"
    "    return v.z >= 0.0 ? 4 : 5;\n"
    "}\n"
    "/* whether p lies ahead of first point q along the unextended ray of the\n"
    "   node's face sample q lands on (cam_sbc_morph.c's refl__sbm_ahead) */\n"
    "bool refl_sbm_ahead(samplerBuffer data, int base, int nb, vec3 pos, int face, vec3 p, vec3 q) {\n"
    "    const vec3 fws[6] = vec3[6](vec3(1, 0, 0), vec3(-1, 0, 0), vec3(0, 1, 0), vec3(0, -1, 0), vec3(0, 0, 1), vec3(0, 0, -1));\n"
    "    const vec3 ups[6] = vec3[6](vec3(0, 1, 0), vec3(0, 1, 0), vec3(0, 0, -1), vec3(0, 0, 1), vec3(0, 1, 0), vec3(0, 1, 0));\n"
    "    vec3 v = q - pos;\n"
    "    int f = refl_sbm_face_of(v), W = face + 2;\n"
    "    float dm = texelFetch(data, nb + 5 + f / 4)[f % 4];\n"
    "    if (dm < 0.0) return true;\n"
    "    vec3 fw = fws[f], rt = normalize(cross(fw, ups[f])), up = cross(rt, fw);\n"
    "    float w = dot(v, fw);\n"
    "    if (!(w > 0.0)) return true;\n"
    "    float x = dot(v, rt) / w, y = dot(v, up) / w;\n"
    "    int i = int(clamp(floor((x + 1.0) * 0.5 * float(face)) + 1.0, 0.0, float(W - 1)));\n"
    "    int j = int(clamp(floor((1.0 - y) * 0.5 * float(face)) + 1.0, 0.0, float(W - 1)));\n"
    "    vec3 dr = texelFetch(data, base + int(dm) + j * W + i).xyz;\n"
    "    if (dr == vec3(0.0)) return true;\n"
    "    return dot(p - q, dr) > 0.0;\n"
    "}\n"
    "/* p at one node (its block at nb): the face owning the answer first */\n"
    "bool refl_sbm_node_project(samplerBuffer data, int base, int nb, vec3 p, out vec3 first) {\n"
    "    vec4 pos = texelFetch(data, nb);\n"
    "    first = vec3(0.0);\n"
    "    if (any(lessThan(p, texelFetch(data, nb + 1).xyz)) || any(greaterThan(p, texelFetch(data, nb + 2).xyz)))\n"
    "        return false;\n"
    "    bool got = false;\n"
    "    vec3 keep = vec3(0.0);\n"
    "    for (int f = 0; f < 6; ++f) {\n"
    "        float so = texelFetch(data, nb + 3 + f / 4)[f % 4];\n"
    "        vec3 q;\n"
    "        float z;\n"
    "        int kind;\n"
    "        if (so < 0.0 || !refl_sbc_project(data, base + int(so), p, q, z, kind)) continue;\n"
    "        if (!refl_sbm_ahead(data, base, nb, pos.xyz, int(pos.w), p, q)) continue;\n"
    "        if (refl_sbm_face_of(q - pos.xyz) == f) { first = q; return true; }\n"
    "        if (!got) keep = q;\n"
    "        got = true;\n"
    "    }\n"
    "    first = keep;\n"
    "    return got;\n"
    "}\n"
    "/* p at one node in each of `sheets` sheets of its face SBCs, a sheet\n"
    "   choosing among the faces as refl_sbm_node_project does\n"
    "   (refl__sbm_node_sheets): the mask of the sheets with an image */\n"
    "int refl_sbm_node_sheets(samplerBuffer data, int base, int nb, vec3 p, int sheets, out vec3 first[3]) {\n"
    "    vec4 pos = texelFetch(data, nb);\n"
    "    int mask = 0, own = 0;\n"
    "    first = vec3[3](vec3(0.0), vec3(0.0), vec3(0.0));\n"
    "    if (any(lessThan(p, texelFetch(data, nb + 1).xyz)) || any(greaterThan(p, texelFetch(data, nb + 2).xyz)))\n"
    "        return 0;\n"
    "    for (int f = 0; f < 6; ++f) {\n"
    "        float so = texelFetch(data, nb + 3 + f / 4)[f % 4];\n"
    "        vec3 q[3];\n"
    "        float z[3];\n"
    "        if (so < 0.0) continue;\n"
    "        int got = refl_sbc_project_sheets(data, base + int(so), p, sheets, q, z);\n"
    "        for (int k = 0; k < sheets; ++k) {\n"
    "            if (((got >> k) & 1) == 0 || ((own >> k) & 1) != 0 ||\n"
    "                !refl_sbm_ahead(data, base, nb, pos.xyz, int(pos.w), p, q[k]))\n"
    "                continue;\n"
    "            if (refl_sbm_face_of(q[k] - pos.xyz) == f) {\n"
    "                own |= 1 << k;\n"
    "                first[k] = q[k];\n"
    "            } else if (((mask >> k) & 1) == 0) {\n"
    "                first[k] = q[k];\n"
    "            }\n"
    "            mask |= 1 << k;\n"
    "        }\n"
    "    }\n"
    "    return mask;\n"
    "}\n"
    "/* the image sheet `sheet` draws of a point with images `mask`: its own,\n"
    "   else one a fold away (across), -1 none (refl__sbc_sheet_image) */\n"
    "int refl_sbc_sheet_image(int mask, int sheet, out bool across) {\n"
    "    across = ((mask >> sheet) & 1) == 0;\n"
    "    if (!across) return sheet;\n"
    "    if (sheet > 0 && ((mask >> (sheet - 1)) & 1) != 0) return sheet - 1;\n"
    "    if (((mask >> (sheet + 1)) & 1) != 0) return sheet + 1;\n"
    "    return -1;\n"
    "}\n"
    "/* the blend over the nodes of positive weight of each one's image of p:\n"
    "   sheet < 0 one per node (refl_sbm_node_project), else its image in that\n"
    "   sheet, or one a fold away (across); false where a node has none, or\n"
    "   past the piece's sheets */\n"
    "bool refl_sbm_blend(samplerBuffer data, int base, vec3 p, int sheet, out vec3 first, out float dist, out bool across) {\n"
    "    vec4 w = texelFetch(data, base + 1);\n"
    "    int sheets = int(texelFetch(data, base + 2).y);\n"
    "    vec3 f = vec3(0.0);\n"
    "    float dd = 0.0;\n"
    "    bool any_node = false;\n"
    "    first = vec3(0.0);\n"
    "    dist = 0.0;\n"
    "    across = false;\n"
    "    if (sheet >= sheets) return false;\n"
    "    for (int k = 0; k < 4; ++k) {\n"
    "        if (!(w[k] > 0.0)) continue;\n"
    "        float nb = texelFetch(data, base + 2 + k).x;\n"
    "        vec3 q;\n"
    "        if (nb < 0.0) return false;\n"
    "        if (sheet < 0) {\n"
    "            if (!refl_sbm_node_project(data, base, base + int(nb), p, q)) return false;\n"
    "        } else {\n"
    "            vec3 qs[3];\n"
    "            bool a;\n"
    "            int image = refl_sbc_sheet_image(refl_sbm_node_sheets(data, base, base + int(nb), p, sheets, qs), sheet, a);\n"
    "            if (image < 0) return false;\n"
    "            q = qs[image];\n"
    "            across = across || a;\n"
    "        }\n"
    "        f += w[k] * q;\n"
    "        dd += w[k] * length(p - q);\n"
    "        any_node = true;\n"
    "    }\n"
    "    if (!any_node) return false;\n"
    "    first = f;\n"
    "    dist = dd;\n"
    "    return true;\n"
    "}\n"
    "/* p's blended first reflector point and distance for the packed eye and\n"
    "   piece (one image per node: refl_sbc_morph_project); false where a node\n"
    "   of positive weight does not project it */\n"
    "bool refl_sbc_morph_project(samplerBuffer data, int base, vec3 p, out vec3 first, out float dist) {\n"
    "    bool across;\n"
    "    return refl_sbm_blend(data, base, p, -1, first, dist, across);\n"
    "}\n"
    "/* p in sheet `sheet` of the piece's face SBCs, blended as refl_render blends\n"
    "   a morph grid's sheets (refl_sbc_morph_project_sheet): each node of\n"
    "   positive weight its image in that sheet, else one a fold away\n"
    "   (across); false where one has neither, or past the piece's sheets */\n"
    "bool refl_sbc_morph_project_sheet(samplerBuffer data, int base, vec3 p, int sheet, out vec3 first, out float dist,\n"
    "                                  out bool across) {\n"
    "    return refl_sbm_blend(data, base, p, sheet < 0 ? 3 : sheet, first, dist, across);\n" /* (3: past every piece's sheets) */
    "}\n";

static const char refl__gl_glsl_lem_shell[] =
    "/* reflect.h GL hook: a LAYERED_EM lens's layers' shells (layout version 1),\n"
    "   lem_infer.c's refl_lem_shell_index and refl_lem_shell_texels in float\n"
    "   (rast.h's cube faces). Kinds: 1 sphere, 2 cylinder, 3 box, 4 quad. */\n"
    "int refl_lem_layers(samplerBuffer data, int base) { return int(texelFetch(data, base).z); }\n"
    "/* the exit ray's index on layer `layer`'s shell (interpolate it per\n"
    "   vertex; a sphere from outside: where the ray enters it); false (no\n"
    "   lookup) from outside a box or cylinder, past or away from a sphere\n"
    "   from outside, or away from or past a quad */\n"
    "bool refl_lem_shell_index(samplerBuffer data, int base, int layer, vec3 origin, vec3 dir, out vec3 index) {\n"
    "    int b = base + 1 + 5 * layer, kind = int(texelFetch(data, b).y);\n"
    "    vec4 sh = texelFetch(data, b + 1);\n"
    "    vec4 a0 = texelFetch(data, b + 2), a1 = texelFetch(data, b + 3), a2 = texelFetch(data, b + 4);\n"
    "    vec3 oc = origin - sh.xyz;\n"
    "    float dd = dot(dir, dir), t = 3.402823e38;\n"
    "    index = vec3(0.0);\n"
    "    if (!(dd > 0.0)) return false;\n"
    "    if (kind == 1) {\n"
    "        float b1 = dot(oc, dir), c = dot(oc, oc) - sh.w * sh.w, disc = b1 * b1 - c * dd;\n"
    "        if (!(sh.w > 0.0) || !(disc >= 0.0)) return false;\n"
    "        t = (-b1 + (c <= 0.0 ? sqrt(disc) : -sqrt(disc))) / dd;\n"
    "        index = oc + dir * t;\n"
    "        return t >= 0.0;\n"
    "    }\n"
    "    vec3 p = vec3(dot(oc, a0.xyz), dot(oc, a1.xyz), dot(oc, a2.xyz));\n"
    "    vec3 v = vec3(dot(dir, a0.xyz), dot(dir, a1.xyz), dot(dir, a2.xyz));\n"
    "    vec3 e = vec3(a0.w, a1.w, a2.w);\n"
    "    if (kind == 3) {\n"
    "        for (int i = 0; i < 3; ++i)\n"
    "            if (!(e[i] > 0.0) || !(abs(p[i]) <= e[i])) return false;\n"
    "        for (int i = 0; i < 3; ++i)\n"
    "            if (v[i] != 0.0) t = min(t, ((v[i] > 0.0 ? e[i] : -e[i]) - p[i]) / v[i]);\n"
    "    } else if (kind == 2) {\n"
    "        float a = v.x * v.x + v.z * v.z, b1 = p.x * v.x + p.z * v.z, c = p.x * p.x + p.z * p.z - e.x * e.x;\n"
    "        if (!(e.x > 0.0) || !(e.y > 0.0) || !(c <= 0.0) || !(abs(p.y) <= e.y)) return false;\n"
    "        if (a > 0.0) t = (-b1 + sqrt(max(b1 * b1 - a * c, 0.0))) / a;\n"
    "        if (v.y != 0.0) t = min(t, ((v.y > 0.0 ? e.y : -e.y) - p.y) / v.y);\n"
    "        e.z = e.x;\n"
    "    } else if (kind == 4) {\n"
    "        if (!(e.x > 0.0) || !(e.y > 0.0) || v.z == 0.0) return false;\n"
    "        t = -p.z / v.z;\n"
    "        if (!(t > 0.0)) return false;\n"
    "        vec2 q = (p.xy + t * v.xy) / e.xy;\n"
    "        if (!(abs(q.x) <= 1.0 && abs(q.y) <= 1.0)) return false;\n"
    "        index = vec3(q, 1.0);\n"
    "        return true;\n"
    "    } else return false;\n"
    "    if (!(t >= 0.0) || !(t < 3.402823e38)) return false;\n"
    "    index = (p + t * v) / e;\n"
    "    return true;\n"
    "}\n"
    "/* rast_cube_face: GL's table 8.19, ties to z, then y */\n"
    "int refl_lem_cube_face(vec3 v, out vec2 st) {\n"
    "    vec3 a = abs(v);\n"
    "    float sc, tc, ma;\n"
    "    int face;\n"
    "    if (a.z >= a.x && a.z >= a.y) { face = v.z >= 0.0 ? 4 : 5; sc = v.z >= 0.0 ? v.x : -v.x; tc = -v.y; ma = a.z; }\n"
    "    else if (a.y >= a.x) { face = v.y >= 0.0 ? 2 : 3; sc = v.x; tc = v.y >= 0.0 ? v.z : -v.z; ma = a.y; }\n"
    "    else { face = v.x >= 0.0 ? 0 : 1; sc = v.x >= 0.0 ? -v.z : v.z; tc = -v.y; ma = a.x; }\n"
    "    st = ma > 0.0 ? (vec2(sc, tc) / ma + 1.0) * 0.5 : vec2(0.5);\n"
    "    return face;\n"
    "}\n"
    "/* the four texels (face-major, rows top first; within the layer's map)\n"
    "   and bilinear weights of an index (a quad's (x, y, presence): the\n"
    "   point (x, y) over its presence) */\n"
    "bool refl_lem_shell_texels(samplerBuffer data, int base, int layer, vec3 index, out ivec4 texel, out vec4 weight) {\n"
    "    vec4 h = texelFetch(data, base + 1 + 5 * layer);\n"
    "    int n = int(h.x);\n"
    "    vec2 st;\n"
    "    texel = ivec4(-1);\n"
    "    weight = vec4(0.0);\n"
    "    if (int(h.y) == 4) {\n"
    "        if (!(index.z > 0.0)) return false;\n"
    "        index = vec3(index.xy / index.z, 1.0);\n"
    "    }\n"
    "    if (index == vec3(0.0)) return false;\n"
    "    int face = refl_lem_cube_face(index, st);\n"
    "    vec2 xy = clamp(st, 0.0, 1.0) * float(n) - 0.5, f = xy - floor(xy);\n"
    "    ivec2 p0 = ivec2(floor(xy)), p1 = min(p0 + 1, n - 1);\n"
    "    p0 = clamp(p0, 0, n - 1);\n"
    "    int b = face * n * n;\n"
    "    texel = ivec4(b + p0.y * n + p0.x, b + p0.y * n + p1.x, b + p1.y * n + p0.x, b + p1.y * n + p1.x);\n"
    "    weight = vec4((1.0 - f.x) * (1.0 - f.y), f.x * (1.0 - f.y), (1.0 - f.x) * f.y, f.x * f.y);\n"
    "    return true;\n"
    "}\n"
    "/* refl_lem_shell_lookup: the index, then its texels */\n"
    "bool refl_lem_shell_lookup(samplerBuffer data, int base, int layer, vec3 origin, vec3 dir, out ivec4 texel,\n"
    "                           out vec4 weight) {\n"
    "    vec3 index;\n"
    "    texel = ivec4(-1);\n"
    "    weight = vec4(0.0);\n"
    "    return refl_lem_shell_index(data, base, layer, origin, dir, index) &&\n"
    "           refl_lem_shell_texels(data, base, layer, index, texel, weight);\n"
    "}\n"
    "/* per fragment: layer `layer`'s packed map at an interpolated index\n"
    "   (premultiplied RGBA; a quad's scaled by its presence); 0 without maps */\n"
    "vec4 refl_lem_shell_sample(samplerBuffer data, int base, int layer, vec3 index) {\n"
    "    vec4 h = texelFetch(data, base + 1 + 5 * layer);\n"
    "    ivec4 t;\n"
    "    vec4 w;\n"
    "    if (texelFetch(data, base).w < 0.5 || !refl_lem_shell_texels(data, base, layer, index, t, w)) return vec4(0.0);\n"
    "    int m = base + int(h.z);\n"
    "    vec4 c = w.x * texelFetch(data, m + t.x) + w.y * texelFetch(data, m + t.y) + w.z * texelFetch(data, m + t.z) +\n"
    "             w.w * texelFetch(data, m + t.w);\n"
    "    return int(h.y) == 4 ? c * clamp(index.z, 0.0, 1.0) : c;\n"
    "}\n";

static const char refl__gl_glsl_spoc[] =
    "/* reflect.h GL hook: the SPOC (layout version 1; cam_spoc.c): the pinhole,\n"
    "   then the push delta_max * gd away from the pole, faded in over ramp. */\n"
    "vec4 refl_spoc_project(samplerBuffer data, int base, vec3 p) {\n"
    "    vec4 eye = texelFetch(data, base + 1), right = texelFetch(data, base + 2);\n"
    "    vec4 up = texelFetch(data, base + 3), fwd = texelFetch(data, base + 4);\n"
    "    vec4 k = texelFetch(data, base + 5);\n"
    "    vec3 q = p - eye.xyz;\n"
    "    float z = dot(q, fwd.xyz);\n"
    "    if (!(z > 0.0)) return vec4(0.0);\n"
    "    vec2 rho = eye.w * vec2(dot(q, right.xyz), -dot(q, up.xyz)) / z;\n"
    "    float r = length(rho), gd = (k.x - 1.0 / z) / (k.x - k.y);\n"
    "    float push = gd > 0.0 ? up.w * gd : 0.0;\n"
    "    float scale = r < right.w ? 1.0 + push / right.w : 1.0 + push / r;\n"
    "    return vec4(k.zw + rho * scale, gd, 1.0);\n"
    "}\n";

static const char refl__gl_glsl_spoc_impostor[] =
    "/* reflect.h GL hook: a SPOC impostor (layout version 1; impostor.c's\n"
    "   refl_impostor_intersect step for step, in float; needs refl_spoc_project). */\n"
    "/* The texel of `layer` holding image point uv if it stores a surface, else -1;\n"
    "   its (r, g, b, gd) in texel. size: width, height, layers. */\n"
    "int refl_spi_stored(samplerBuffer data, int img, ivec3 size, int layer, vec2 uv, out vec4 texel) {\n"
    "    vec2 f = floor(uv);\n"
    "    texel = vec4(0.0, 0.0, 0.0, -1.0);\n"
    "    if (!(f.x >= 0.0 && f.y >= 0.0 && f.x < float(size.x) && f.y < float(size.y))) return -1;\n"
    "    int t = (layer * size.y + int(f.y)) * size.x + int(f.x);\n"
    "    texel = texelFetch(data, img + t);\n"
    "    return texel.w >= 0.0 ? t : -1;\n"
    "}\n"
    "/* The stored depth's change over one texel beyond cur, continuing from prev. */\n"
    "float refl_spi_slope(samplerBuffer data, int img, ivec3 size, int layer, vec3 prev, vec3 cur, float gd_cur) {\n"
    "    vec2 duv = cur.xy - prev.xy;\n"
    "    float len = length(duv);\n"
    "    vec4 texel;\n"
    "    if (!(len > 1e-6)) return 0.0;\n"
    "    return refl_spi_stored(data, img, size, layer, cur.xy + duv / len, texel) < 0 ? 0.0 : abs(texel.w - gd_cur);\n"
    "}\n"
    "bool refl_spoc_impostor_intersect(samplerBuffer data, int base, vec3 o, vec3 dir, float tmin, float tmax,\n"
    "                                  float step_scale, out float t_hit, out vec3 point, out vec4 color,\n"
    "                                  out int layer_hit, out int steps) {\n"
    "    vec4 h = texelFetch(data, base), sph = texelFetch(data, base + 1), k = texelFetch(data, base + 2);\n"
    "    ivec3 size = ivec3(int(h.z), int(k.y), int(h.w));\n"
    "    int img = base + int(k.z), cam = base + 3, wtex[4];\n"
    "    float wd[4], wgd[4];\n"
    "    t_hit = 0.0; point = vec3(0.0); color = vec4(0.0); layer_hit = -1; steps = 0;\n"
    /* 1. clip to the bounding sphere */
    "    vec3 oc = o - sph.xyz;\n"
    "    float a = dot(dir, dir), b = dot(oc, dir), c = dot(oc, oc) - sph.w * sph.w, disc = b * b - a * c;\n"
    "    if (!(a > 0.0) || !(disc > 0.0)) return false;\n"
    "    float sq = sqrt(disc), t0 = max((-b - sq) / a, tmin), t1 = min((-b + sq) / a, tmax);\n"
    "    if (!(t0 < t1)) return false;\n"
    /* 2. the projection's length along 4 pieces sets the pieces walked */
    "    vec3 prev = vec3(0.0), cur;\n"
    "    float len = 0.0;\n"
    "    for (int i = 0; i <= 4; ++i) {\n"
    "        vec4 q = refl_spoc_project(data, cam, o + dir * (t0 + (t1 - t0) * float(i) / 4.0));\n"
    "        if (q.w == 0.0) return false;\n"
    "        if (i > 0) len += length(q.xy - prev.xy);\n"
    "        prev = q.xyz;\n"
    "    }\n"
    "    len *= step_scale > 0.0 ? step_scale : 1.0;\n"
    "    int most = 4 * (size.x + size.y);\n"
    "    int n = len < 2.0 ? 2 : len > float(most) ? most : int(ceil(len));\n"
    "    for (int l = 0; l < 4; ++l) { wtex[l] = -1; wd[l] = 0.0; wgd[l] = 1.0; }\n"
    /* 3. near to far, every layer on the same ends: the first piece that
          crosses behind a layer (skins excepted), its nearest crossing */
    "    for (int i = 0; i <= n; ++i) {\n"
    "        vec4 q = refl_spoc_project(data, cam, o + dir * (t0 + (t1 - t0) * float(i) / float(n)));\n"
    "        if (q.w == 0.0) return false;\n"
    "        cur = q.xyz;\n"
    "        float best = 2.0;\n"
    "        int best_layer = -1;\n"
    "        for (int l = 0; l < size.z; ++l) {\n"
    "            vec4 texel;\n"
    "            int tex = refl_spi_stored(data, img, size, l, cur.xy, texel);\n"
    "            float gd = tex >= 0 ? texel.w : 1.0, d = cur.z - gd, f = -1.0;\n"
    "            if (i > 0 && tex >= 0 && d >= 0.0 && (wtex[l] < 0 || wd[l] < 0.0)) {\n"
    "                float d0 = prev.z - gd;\n"
    "                bool farther = wtex[l] >= 0 && gd >= wgd[l];\n"
    "                if (farther || d0 <= refl_spi_slope(data, img, size, l, prev, cur, gd) + k.x)\n"
    "                    f = wtex[l] >= 0 ? wd[l] / (wd[l] - d) : d0 < 0.0 ? d0 / (d0 - d) : 0.0;\n"
    "            }\n"
    "            wtex[l] = tex; wd[l] = d; wgd[l] = gd;\n"
    "            if (f >= 0.0 && f < best) { best = f; best_layer = l; }\n"
    "        }\n"
    "        if (i > 0) steps = i;\n"
    "        if (best_layer >= 0) {\n"
    "            vec4 texel;\n"
    "            t_hit = t0 + (t1 - t0) * (float(i - 1) + best) / float(n);\n"
    "            point = o + dir * t_hit;\n"
    "            vec4 at = refl_spoc_project(data, cam, point);\n"
    "            if (refl_spi_stored(data, img, size, best_layer, at.w != 0.0 ? at.xy : cur.xy, texel) < 0)\n"
    "                texel = texelFetch(data, img + wtex[best_layer]);\n"
    "            color = vec4(texel.rgb, 1.0);\n"
    "            layer_hit = best_layer;\n"
    "            return true;\n"
    "        }\n"
    "        prev = cur;\n"
    "    }\n"
    "    return false;\n"
    "}\n";

static const char refl__gl_glsl_graphcam_impostor[] =
    "/* reflect.h GL hook: a graph camera's impostor (layout version 1;\n"
    "   m_graphcam.c's refl_graphcam_intersect, algorithm 2, in float). */\n"
    "struct refl_gci_sample { bool valid; int f; float t, gd, GD; ivec2 px; };\n"
    "/* Pixel i's frustum + 1 (0: none) and gd; img: (colour plane, depth plane, width, height). */\n"
    "int refl_gci_frustum(samplerBuffer data, ivec4 img, int i) { return int(texelFetch(data, img.x + i).w); }\n"
    "float refl_gci_depth(samplerBuffer data, ivec4 img, int i) { return texelFetch(data, img.y + (i >> 2))[i & 3]; }\n"
    "/* Frustum f's clip position of p (its matrix with its level in z). */\n"
    "vec4 refl_gci_clip(samplerBuffer data, int cam, int f, vec3 p) {\n"
    "    int b = cam + 2 + f * 21;\n"
    "    return mat4(texelFetch(data, b + 1), texelFetch(data, b + 2), texelFetch(data, b + 3),\n"
    "                texelFetch(data, b + 4)) * vec4(p, 1.0);\n"
    "}\n"
    "/* The depth slope at pixel px of frustum f: per axis the smaller one-sided\n"
    "   difference to a pixel of the same frustum, the larger over the axes. */\n"
    "float refl_gci_slope(samplerBuffer data, ivec4 img, int f, ivec2 px) {\n"
    "    float g = refl_gci_depth(data, img, px.y * img.z + px.x), best = 0.0;\n"
    "    for (int axis = 0; axis < 2; ++axis) {\n"
    "        float side = 3.4e38;\n"
    "        bool any = false;\n"
    "        for (int k = -1; k <= 1; k += 2) {\n"
    "            ivec2 q = px + (axis == 0 ? ivec2(k, 0) : ivec2(0, k));\n"
    "            if (q.x < 0 || q.y < 0 || q.x >= img.z || q.y >= img.w) continue;\n"
    "            int i = q.y * img.z + q.x;\n"
    "            if (refl_gci_frustum(data, img, i) != f + 1) continue;\n"
    "            side = min(side, abs(refl_gci_depth(data, img, i) - g));\n"
    "            any = true;\n"
    "        }\n"
    "        if (any) best = max(best, side);\n"
    "    }\n"
    "    return best;\n"
    "}\n"
    "/* The sample at t seen through frustum f: valid where its pixel shows f. */\n"
    "refl_gci_sample refl_gci_sample_at(samplerBuffer data, int cam, ivec4 img, int f, float t, vec3 o, vec3 d) {\n"
    "    refl_gci_sample x;\n"
    "    x.valid = false; x.f = f; x.t = t; x.gd = 0.0; x.GD = 0.0; x.px = ivec2(0);\n"
    "    vec4 c = refl_gci_clip(data, cam, f, o + t * d);\n"
    "    if (!(c.w > 0.0)) return x;\n"
    "    float u = (c.x / c.w + 1.0) * 0.5 * float(img.z), v = (1.0 - c.y / c.w) * 0.5 * float(img.w);\n"
    "    if (!(u >= 0.0 && v >= 0.0 && u < float(img.z) && v < float(img.w))) return x;\n"
    "    x.px = ivec2(int(u), int(v));\n"
    "    int i = x.px.y * img.z + x.px.x;\n"
    "    if (refl_gci_frustum(data, img, i) != f + 1) return x;\n"
    "    x.gd = (c.z / c.w + 1.0) * 0.5;\n"
    "    x.GD = refl_gci_depth(data, img, i);\n"
    "    x.valid = true;\n"
    "    return x;\n"
    "}\n"
    "/* The ray crosses the stored depth from a to b (not a skin); s the fraction. */\n"
    "bool refl_gci_crossing(samplerBuffer data, ivec4 img, refl_gci_sample a, refl_gci_sample b, out float s) {\n"
    "    float da = a.gd - a.GD, db = b.gd - b.GD;\n"
    "    s = 0.0;\n"
    "    if (!a.valid || !b.valid || a.f != b.f || !(da < 0.0) || !(db >= 0.0)) return false;\n"
    "    float slope = min(refl_gci_slope(data, img, a.f, a.px), refl_gci_slope(data, img, b.f, b.px));\n"
    "    ivec2 dp = abs(b.px - a.px);\n"
    "    float px = float(max(dp.x, dp.y));\n"
    "    if (abs(b.GD - a.GD) > 3.0 * abs(b.gd - a.gd) + 2.0 * max(px, 1.0) * slope) return false;\n"
    "    s = da / (da - db);\n"
    "    return true;\n"
    "}\n"
    "/* b behind the stored surface by more than its thickness estimate. */\n"
    "bool refl_gci_behind(samplerBuffer data, ivec4 img, refl_gci_sample a, refl_gci_sample b) {\n"
    "    if (!b.valid || !(b.gd > b.GD)) return false;\n"
    "    float thickness = 2.0 * refl_gci_slope(data, img, b.f, b.px);\n"
    "    if (a.valid && a.f == b.f) thickness += abs(b.gd - a.gd);\n"
    "    return b.gd - b.GD > thickness;\n"
    "}\n"
    "/* Algorithm 2 in frustum f: the piece [t0, t1] walked step pixels at a time. */\n"
    "bool refl_gci_segment(samplerBuffer data, int cam, ivec4 img, int f, float t0, float t1, float step, vec3 o,\n"
    "                      vec3 d, inout float behind, inout int steps, out float t_hit, out vec3 color) {\n"
    "    vec4 ca = refl_gci_clip(data, cam, f, o + t0 * d), cb = refl_gci_clip(data, cam, f, o + t1 * d);\n"
    "    t_hit = 0.0; color = vec3(0.0);\n"
    "    if (!(ca.w > 0.0) || !(cb.w > 0.0)) return false;\n"
    "    float du = (cb.x / cb.w - ca.x / ca.w) * 0.5 * float(img.z), dv = (cb.y / cb.w - ca.y / ca.w) * 0.5 * float(img.w);\n"
    "    float len = ceil(sqrt(du * du + dv * dv) / step);\n"
    "    int n = len < 1.0 ? 1 : len > 1e6 ? 1000000 : int(len);\n"
    "    refl_gci_sample a;\n"
    "    a.valid = false; a.f = 0; a.t = 0.0; a.gd = 0.0; a.GD = 0.0; a.px = ivec2(0);\n"
    "    for (int k = 0; k <= n; ++k) {\n"
    "        float sf = float(k) / float(n), den = (1.0 - sf) * cb.w + sf * ca.w, s;\n"
    "        float tf = den > 0.0 ? sf * ca.w / den : sf;\n"
    "        refl_gci_sample b = refl_gci_sample_at(data, cam, img, f, t0 + (t1 - t0) * tf, o, d);\n"
    "        ++steps;\n"
    "        if (k > 0 && refl_gci_crossing(data, img, a, b, s)) {\n"
    "            t_hit = a.t + s * (b.t - a.t);\n"
    "            color = texelFetch(data, img.x + b.px.y * img.z + b.px.x).rgb;\n"
    "            return true;\n"
    "        }\n"
    "        if (b.t < behind && refl_gci_behind(data, img, a, b)) behind = b.t;\n"
    "        a = b;\n"
    "    }\n"
    "    return false;\n"
    "}\n"
    "bool refl_graphcam_impostor_intersect(samplerBuffer data, int base, vec3 o, vec3 dir, float tmin, float tmax,\n"
    "                                      float step, out float t_hit, out vec3 point, out vec3 color,\n"
    "                                      out int frustum, out float behind, out int steps) {\n"
    "    vec4 h = texelFetch(data, base), lo = texelFetch(data, base + 1), hi = texelFetch(data, base + 2);\n"
    "    int cam = base + 3, count = int(texelFetch(data, cam).z), order[64], pieces = 0;\n"
    "    ivec4 img = ivec4(base + int(lo.w), base + int(hi.w), int(h.z), int(h.w));\n"
    "    float t0 = tmin, t1 = tmax, best = 3.4e38, ta[64], tb[64];\n"
    "    bool found = false;\n"
    "    t_hit = 0.0; point = vec3(0.0); color = vec3(0.0); frustum = -1; behind = 3.4e38; steps = 0;\n"
    /* the ray inside the camera's bounds (slabs) */
    "    for (int k = 0; k < 3; ++k) {\n"
    "        if (dir[k] == 0.0) {\n"
    "            if (o[k] < lo[k] || o[k] > hi[k]) return false;\n"
    "        } else {\n"
    "            float a = (lo[k] - o[k]) / dir[k], b = (hi[k] - o[k]) / dir[k];\n"
    "            t0 = max(t0, min(a, b));\n"
    "            t1 = min(t1, max(a, b));\n"
    "        }\n"
    "    }\n"
    "    if (!(t1 > t0)) return false;\n"
    /* the ray's piece in each frustum (refl_graphcam_clip_segment), nearest first */
    "    vec3 pa = o + t0 * dir, pb = o + t1 * dir;\n"
    "    for (int f = 0; f < count; ++f) {\n"
    "        int b = cam + 2 + f * 21, planes = int(texelFetch(data, b).x);\n"
    "        float s0 = 0.0, s1 = 1.0;\n"
    "        bool in_f = true;\n"
    "        for (int k = 0; k < planes && in_f; ++k) {\n"
    "            vec4 pl = texelFetch(data, b + 5 + k);\n"
    "            float ea = dot(pl.xyz, pa) + pl.w, eb = dot(pl.xyz, pb) + pl.w;\n"
    "            if (ea < 0.0 && eb < 0.0) in_f = false;\n"
    "            else if (ea < 0.0) s0 = max(s0, ea / (ea - eb));\n"
    "            else if (eb < 0.0) s1 = min(s1, ea / (ea - eb));\n"
    "            if (s0 > s1) in_f = false;\n"
    "        }\n"
    "        if (!in_f) continue;\n"
    "        ta[f] = t0 + (t1 - t0) * s0;\n"
    "        tb[f] = t0 + (t1 - t0) * s1;\n"
    "        int j = pieces++;\n"
    "        for (; j > 0 && ta[order[j - 1]] > ta[f]; --j) order[j] = order[j - 1];\n"
    "        order[j] = f;\n"
    "    }\n"
    /* a piece starting past the best hit cannot improve it */
    "    for (int j = 0; j < pieces; ++j) {\n"
    "        int f = order[j];\n"
    "        float t; vec3 c;\n"
    "        if (ta[f] >= best) break;\n"
    "        if (refl_gci_segment(data, cam, img, f, ta[f], tb[f], step > 0.0 ? step : 1.0, o, dir, behind, steps, t, c)\n"
    "            && t < best) {\n"
    "            best = t; t_hit = t; color = c; frustum = f; found = true;\n"
    "        }\n"
    "    }\n"
    "    if (found) point = o + t_hit * dir;\n"
    "    if (found && !(behind < t_hit)) behind = 3.4e38;\n"
    "    return found;\n"
    "}\n";

REFL_API const char *refl_gl_glsl(refl_gl_camera camera) {
    switch (camera) {
    case REFL_GL_MIRROR: return refl__gl_glsl_mirror;
    case REFL_GL_C3RC: return refl__gl_glsl_c3rc;
    case REFL_GL_SBC: return refl__gl_glsl_sbc;
    case REFL_GL_GRAPHCAM: return refl__gl_glsl_graphcam;
    case REFL_GL_SBC_MORPH: return refl__gl_glsl_sbc_morph;
    case REFL_GL_LEM_SHELL: return refl__gl_glsl_lem_shell;
    case REFL_GL_SPOC: return refl__gl_glsl_spoc;
    case REFL_GL_SPOC_IMPOSTOR: return refl__gl_glsl_spoc_impostor;
    case REFL_GL_GRAPHCAM_IMPOSTOR: return refl__gl_glsl_graphcam_impostor;
    }
    return NULL;
}
