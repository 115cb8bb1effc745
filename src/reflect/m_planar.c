/* PLANAR: Diefenbach and Badler's pipeline rendering (paper 002) for
   planar mirrors. A mirror's visible pixels are marked in the stencil, the
   scene is drawn again from the mirrored viewpoint into them, clipped by
   an oblique near plane at the mirror (Lengyel 2005), and the procedure
   recurses (a hall of mirrors) with one stencil level per bounce, as the
   paper's Figure 4: level L's region has stencil L; marking a mirror
   raises its pixels to L + 1; returning lowers them again.

   Planar reflectors are found per object: its triangles grouped by plane
   (within a tolerance; planar_faces.c). An object whose triangles fall into more than
   REFL__PLANAR_MAX_FACES planes is not planar (a teapot) and is left as
   DIRECT draws it.

   Colour is kept in a float buffer while the recursion runs, so the
   reflectance of each bounce weighs unrounded colour, as RAYTRACE's does;
   each surface is clamped to [0, 1] before a reflectance weighs it (the
   shared model), and the frame gets 8-bit colour once at the end. The
   environment in a mirror is looked up along the mirrored ray; the point a
   first-bounce pixel shows (frame->points) is unprojected from the
   mirrored view's depth. It draws with the base pass's programs (base_pass.c).
   Opt-in: the light mirrors reflect (light_volume.c) at every unwarped
   level, and translucent glass (desc.lighting.translucency: rast.h's fog over the
   image behind a glass face, refl__planar_fog). */
#include "internal.h"

typedef struct refl__planar {
    refl__pass *p;
    const refl_scene *scene;
    refl__planar_face *faces;
    int face_count;
    float *color;                 /* the frame's colour (frame->rgba) */
    float *saved;                 /* glass: the refracted image of a region */
    float *unfogged;              /* translucency: a region's colour before its fog */
    float *saved_points;          /* and, at the first bounce, the points it shows */
    uint8_t *lit;                 /* shadows: the lights each pixel of a region sees */
    uint16_t *counts;             /* soft shadows: per light, the samples each pixel sees */
    rast_targets targets;         /* what PLANAR draws into */
    uint8_t *stencil;             /* recursion levels */
    int no_culling;
    long long culled;
    uint8_t *cut;                 /* pixels of mirrors past desc.planar.max_renderings (NULL: none) */
    refl__lv lv;                  /* light volumes: the virtual lights (none when off) */
} refl__planar;

/* ---- mirrored cameras ----------------------------------------------------------- */

/* Lengyel's oblique near plane: the projection's near plane becomes the
   eye-space plane c (points with c . (x, y, z, 1) >= 0 are kept; the eye
   must lie on the other side). 0 when c cannot serve (edge-on). */
static int refl__planar_oblique(refl_mat4 *proj, double c[4]) {
    float *m = proj->m;
    double q[4], dot, k;
    int i;
    q[0] = ((c[0] > 0) - (c[0] < 0) + (double)m[8]) / m[0];
    q[1] = ((c[1] > 0) - (c[1] < 0) + (double)m[9]) / m[5];
    q[2] = -1.0;
    q[3] = (1.0 + (double)m[10]) / m[14];
    dot = c[0] * q[0] + c[1] * q[1] + c[2] * q[2] + c[3] * q[3];
    if (!(dot > 0.0) || c[3] >= 0.0) return 0;
    k = 2.0 / dot;
    for (i = 0; i < 4; ++i) c[i] *= k; /* the caller keeps the scaled plane: row 3 + row 4 */
    m[2] = (float)c[0];
    m[6] = (float)c[1];
    m[10] = (float)(c[2] + 1.0);
    m[14] = (float)c[3];
    return 1;
}

/* ---- drawing ---------------------------------------------------------------------- */

/* One level of the recursion: the camera sees w * x through vp. */
typedef struct refl__planar_level {
    int level;                    /* the stencil value of its region */
    int bounces;                  /* taken to get here: one per mirror, two per slab */
    refl_mat4 w, w_inv;           /* the virtual world and back */
    refl_mat4 vp;                 /* projection (oblique at level > 0) * view * w */
    double clip[4];               /* the eye-space near plane (level > 0) */
    int parent;                   /* the face it reflects in; -1 at level 0 */
    /* a refracted camera's image warped onto the face (paper 002's
       appendix): h maps its normalised device x, y, w to the viewer's */
    int warped;
    double h[9], h_inv[9];        /* 3 x 3, row vectors: [x y w] h */
    refl_mat4 vp_inv;             /* the refracted camera's clip to world */
    /* seen through a slab (in-out refraction): light has left the slab,
       its faces are not met again */
    int left_slab;
    /* translucency: seen through a glass face from outside, fogged by
       the distance fog . (x, 1) behind it towards fog_rgb */
    int fogged;
    double fog[4];
    float fog_rgb[3];
} refl__planar_level;

/* A draw context of a level's scene, with the level's warp (or NULL). */
typedef struct refl__planar_dc {
    refl__draw_ctx dc;
    const double *h;
} refl__planar_dc;

/* The base pass's vertex program, then the level's warp: x, y, w through
   h, z scaled with w so the depth a vertex gets is unchanged. */
static int refl__planar_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out) {
    const refl__planar_dc *d = (const refl__planar_dc *)user;
    int n = refl__base_vertex((void *)&d->dc, vertex, index, out, max_out);
    if (d->h) {
        const double *h = d->h;
        double x = out->position[0], y = out->position[1], w = out->position[3];
        double xw = x * h[0] + y * h[3] + w * h[6], yw = x * h[1] + y * h[4] + w * h[7];
        double ww = x * h[2] + y * h[5] + w * h[8];
        out->position[0] = (float)xw;
        out->position[1] = (float)yw;
        out->position[2] = w != 0.0 ? (float)(out->position[2] * ww / w) : out->position[2];
        out->position[3] = (float)ww;
    }
    return n;
}

/* The composite of a face: its diffuse share plus reflectance times what
   the region now holds (blend ONE, SRC_ALPHA; the reflectance in alpha). */
typedef struct refl__planar_comp {
    refl__draw_ctx dc;
    refl_vec3 eye;                /* the viewer in the face's world */
} refl__planar_comp;

static int refl__planar_comp_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__planar_comp *c = (const refl__planar_comp *)user;
    const refl_material *m = c->dc.material;
    const float *v = in->varyings;
    refl_vec3 p = refl_v3(v[0], v[1], v[2]), n = refl_v3_normalize(refl_v3(v[3], v[4], v[5]));
    refl_vec3 d = refl_v3_normalize(refl_v3_sub(p, c->eye));
    float cos_i = fabsf(refl_v3_dot(d, n));
    rgba[0] = rgba[1] = rgba[2] = 0.0f;
    if (m->type == REFL_PARTIAL) {
        float rgb[3];
        refl_shade_diffuse(c->dc.scene, m, p, refl_v3(v[3], v[4], v[5]), v + 6, rgb);
        refl__surface_rgba(m, rgb, rgba);
    }
    rgba[3] = refl_material_reflectance(m, cos_i);
    return 1;
}


/* A state's scissor on a region's box (an empty box draws nothing). */
static void refl__planar_scissor(rast_state *s, const int box[4]) {
    s->scissor_test = 1;
    s->scissor[0] = box[0];
    s->scissor[1] = box[1];
    s->scissor[2] = box[2] - box[0];
    s->scissor[3] = box[3] - box[1];
}

/* A state testing the stencil against `ref` with `pass` on success. */
static rast_state refl__planar_state(uint8_t ref, rast_stencil_op pass) {
    rast_state s;
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = RAST_EQUAL;
    s.stencil_front.ref = ref;
    s.stencil_front.pass = pass;
    s.stencil_back = s.stencil_front;
    s.depth_test = 1;
    s.vertex_fn = refl__base_vertex;
    return s;
}

/* The scene as the level sees it, into its region (depth cleared there):
   every object but the face's own, diffuse ones shaded, reflectors as
   DIRECT draws them. */
static rast_result refl__planar_draw_scene(refl__planar *pl, const refl__planar_level *lv, const int box[4],
                                           refl__planar_dc *dc) {
    const refl_scene *s = pl->scene;
    rast_result rr = RAST_OK;
    int i, skip = lv->parent >= 0 ? pl->faces[lv->parent].object : -1; /* the mirror, or the slab seen through */
    for (i = 0; i < s->object_count && rr == RAST_OK; ++i) {
        rast_state st = refl__planar_state((uint8_t)lv->level, RAST_KEEP);
        if (i == skip) continue;
        refl__planar_scissor(&st, box);
        refl__draw_ctx_init(&dc[i].dc, s, i, lv->vp);
        dc[i].h = lv->warped ? lv->h : NULL;
        st.vertex_fn = refl__planar_vertex;
        st.vertex_user = &dc[i];
        st.fragment_fn = dc[i].dc.material->type == REFL_DIFFUSE || dc[i].dc.material->type == REFL_PARTIAL
                             ? refl__base_fragment : refl__clear_fragment;
        st.fragment_user = &dc[i].dc;
        rr = rast_set_state(pl->p->rc, &st);
        if (rr == RAST_OK) rr = refl__draw_mesh(pl->p->rc, dc[i].dc.mesh, NULL, 0, REFL__BASE_VARYINGS);
        pl->p->frame->stats.triangles += dc[i].dc.mesh->triangle_count;
    }
    return rr;
}

/* After a level's scene: the environment where nothing was drawn (looked
   up along the real, unmirrored ray), and at the first bounce the points
   the region shows, unprojected from the depth along the pixel's ray. */
static void refl__planar_fill_region(refl__planar *pl, const refl__planar_level *lv, const int box[4]) {
    refl_frame *f = pl->p->frame;
    const refl__view_rays *vr = &pl->p->rays;
    double right_len = refl_v3_length(vr->right), up_len = refl_v3_length(vr->up);
    int x, y;
    for (y = box[1]; y < box[3]; ++y)
        for (x = box[0]; x < box[2]; ++x) {
            size_t i = (size_t)y * (size_t)f->width + (size_t)x;
            float nx, ny;
            refl_vec3 dir;
            if (pl->stencil[i] != lv->level) continue;
            nx = 2.0f * ((float)x + 0.5f) / (float)f->width - 1.0f;
            ny = 1.0f - 2.0f * ((float)y + 0.5f) / (float)f->height;
            dir = refl_v3_add(vr->forward, refl_v3_add(refl_v3_scale(vr->right, nx), refl_v3_scale(vr->up, ny)));
            if (lv->warped) {
                /* back through the warp into the refracted camera */
                const double *h = lv->h_inv;
                double w = nx * h[2] + ny * h[5] + h[8], rx, ry;
                refl_vec3 a, b;
                if (w == 0.0) continue;
                rx = (nx * h[0] + ny * h[3] + h[6]) / w;
                ry = (nx * h[1] + ny * h[4] + h[7]) / w;
                a = refl_mat4_point(lv->vp_inv, refl_v3((float)rx, (float)ry, -1.0f));
                b = refl_mat4_point(lv->vp_inv, refl_v3((float)rx, (float)ry, 1.0f));
                if (f->depth[i] >= 1.0f) {
                    float rgb[3];
                    int c;
                    refl_environment_lookup(&pl->scene->environment, refl_v3_sub(b, a), rgb);
                    for (c = 0; c < 3; ++c) pl->color[4 * i + (size_t)c] = REFL__RADIANCE(rgb[c]);
                    pl->color[4 * i + 3] = 1.0f;
                } else if (lv->level == 1) {
                    refl_vec3 world = refl_mat4_point(lv->vp_inv, refl_v3((float)rx, (float)ry, 2.0f * f->depth[i] - 1.0f));
                    f->points[3 * i] = world.x;
                    f->points[3 * i + 1] = world.y;
                    f->points[3 * i + 2] = world.z;
                }
                continue;
            }
            if (f->depth[i] >= 1.0f) {
                float rgb[3];
                int c;
                refl_environment_lookup(&pl->scene->environment, refl_mat4_dir(lv->w_inv, dir), rgb);
                for (c = 0; c < 3; ++c) pl->color[4 * i + (size_t)c] = REFL__RADIANCE(rgb[c]);
                pl->color[4 * i + 3] = 1.0f;
            } else if (lv->level == 1) {
                /* eye-space depth along the ray from the oblique projection:
                   z_ndc = c.D - 1 + c_w / t with D = (nx tx, ny ty, -1) */
                double cd = lv->clip[0] * nx * right_len + lv->clip[1] * ny * up_len - lv->clip[2];
                double zn = 2.0 * f->depth[i] - 1.0, t = lv->clip[3] / (zn + 1.0 - cd);
                refl_vec3 seen = refl_v3_add(vr->eye, refl_v3_scale(dir, (float)t));
                refl_vec3 world = refl_mat4_point(lv->w_inv, seen);
                f->points[3 * i] = world.x;
                f->points[3 * i + 1] = world.y;
                f->points[3 * i + 2] = world.z;
            }
        }
}

/* How many pixels the region `level` has, and their bounding box
   (x0, y0, x1, y1, exclusive; empty: all zero): every later pass over the
   region, on the CPU or through rast's scissor, stays inside it. */
static long long refl__planar_region(const refl__planar *pl, int level, int box[4]) {
    int x, y, w = pl->p->frame->width, h = pl->p->frame->height;
    long long k = 0;
    box[0] = w; box[1] = h; box[2] = box[3] = 0;
    for (y = 0; y < h; ++y) {
        const uint8_t *row = pl->stencil + (size_t)y * (size_t)w;
        for (x = 0; x < w; ++x)
            if (row[x] == level) {
                ++k;
                box[0] = REFL__MIN(box[0], x); box[2] = REFL__MAX(box[2], x + 1);
                box[1] = REFL__MIN(box[1], y); box[3] = REFL__MAX(box[3], y + 1);
            }
    }
    if (!k) box[0] = box[1] = box[2] = box[3] = 0;
    return k;
}


/* Raises the face's visible pixels at this level to level + 1. */
static refl_result refl__planar_mark(refl__planar *pl, const refl__planar_level *lv, refl__planar_comp *comp,
                                     const refl__planar_face *face) {
    rast_state state = refl__planar_state((uint8_t)lv->level, RAST_INCR);
    rast_result rr;
    state.depth_func = RAST_LEQUAL;
    state.depth_write_disabled = 1;
    state.color_write = RAST_MASK(0);
    state.vertex_user = &comp->dc;
    rr = rast_set_state(pl->p->rc, &state);
    if (rr == RAST_OK) rr = refl__draw_mesh(pl->p->rc, comp->dc.mesh, face->indices, face->index_count, REFL__BASE_VARYINGS);
    if (rr == RAST_OK) rr = rast_finish(pl->p->rc);
    return refl__result_from_rast(rr);
}

/* Translucency (paper 002's fog): the level's objects drawn again over
   its region (depth EQUAL) showing the colour they left there, fogged by
   rast.h towards the glass's colour with the distance behind the face as
   the fog coordinate (a ninth varying: affine in the position, so exact
   under perspective interpolation); the environment, infinitely far,
   becomes the colour. */
typedef struct refl__planar_fog_dc {
    refl__planar_dc pdc;          /* first: refl__planar_vertex reads it */
    const double *fog;
    const float *src;
    int width;
} refl__planar_fog_dc;

static int refl__planar_fog_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out) {
    const refl__planar_fog_dc *d = (const refl__planar_fog_dc *)user;
    int n = refl__planar_vertex(user, vertex, index, out, max_out);
    const float *v = out->varyings;
    out->varyings[REFL__BASE_VARYINGS] = (float)(d->fog[0] * v[0] + d->fog[1] * v[1] + d->fog[2] * v[2] + d->fog[3]);
    return n;
}

static int refl__planar_fog_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__planar_fog_dc *d = (const refl__planar_fog_dc *)user;
    memcpy(rgba, d->src + 4 * ((size_t)in->y * (size_t)d->width + (size_t)in->x), 4 * sizeof(float));
    return 1;
}

static refl_result refl__planar_fog(refl__planar *pl, const refl__planar_level *lv, const int box[4],
                                    const refl__planar_dc *dcs) {
    const refl_scene *s = pl->scene;
    refl_frame *f = pl->p->frame;
    refl__planar_fog_dc *fd;
    rast_result rr = RAST_OK;
    int i, x, y, c, skip = pl->faces[lv->parent].object;
    fd = (refl__planar_fog_dc *)refl__calloc(&s->allocator, (size_t)REFL__MAX(s->object_count, 1), sizeof(*fd));
    if (!fd) return REFL_ERROR_OUT_OF_MEMORY;
    for (y = box[1]; y < box[3]; ++y)
        for (x = box[0]; x < box[2]; ++x) {
            size_t k = (size_t)y * (size_t)f->width + (size_t)x;
            if (pl->stencil[k] != lv->level) continue;
            memcpy(pl->unfogged + 4 * k, pl->color + 4 * k, 4 * sizeof(float));
            if (f->depth[k] >= 1.0f)
                for (c = 0; c < 3; ++c) pl->color[4 * k + (size_t)c] = lv->fog_rgb[c];
        }
    for (i = 0; i < s->object_count && rr == RAST_OK; ++i) {
        rast_state st = refl__planar_state((uint8_t)lv->level, RAST_KEEP);
        if (i == skip) continue;
        fd[i].pdc = dcs[i]; /* as refl__planar_draw_scene set them up */
        fd[i].fog = lv->fog;
        fd[i].src = pl->unfogged;
        fd[i].width = f->width;
        refl__planar_scissor(&st, box);
        st.depth_func = RAST_EQUAL;
        st.depth_write_disabled = 1;
        st.vertex_fn = refl__planar_fog_vertex;
        st.vertex_user = &fd[i];
        st.fragment_fn = refl__planar_fog_fragment;
        st.fragment_user = &fd[i];
        st.fog = RAST_FOG_EXP;
        st.fog_density = pl->p->desc.lighting.translucency;
        st.fog_varying = REFL__BASE_VARYINGS + 1;
        for (c = 0; c < 3; ++c) st.fog_color[c] = lv->fog_rgb[c];
        rr = rast_set_state(pl->p->rc, &st);
        if (rr == RAST_OK) rr = refl__draw_mesh(pl->p->rc, dcs[i].dc.mesh, NULL, 0, REFL__BASE_VARYINGS + 1);
    }
    if (rr == RAST_OK) rr = rast_finish(pl->p->rc);
    else rast_finish(pl->p->rc);
    refl__free(&s->allocator, fd);
    return refl__result_from_rast(rr);
}

/* Draws into the child's region (stencil child->level) the scene through
   child->vp (and its warp), the region's depth cleared first, then the
   environment where nothing is; finishes. */
static refl_result refl__planar_render_level(refl__planar *pl, refl__planar_level *child, const int box[4],
                                             refl__planar_dc *dcs) {
    rast_context *rc = pl->p->rc;
    rast_state state = refl__planar_state((uint8_t)child->level, RAST_KEEP);
    rast_result rr;
    float far_rgba[4] = {0, 0, 0, 0};
    state.depth_func = RAST_ALWAYS;
    state.color_write = RAST_MASK(0);
    state.vertex_fn = NULL;
    refl__planar_scissor(&state, box);
    rr = rast_set_state(rc, &state);
    if (rr == RAST_OK) rr = rast_draw_fullscreen(rc, 1.0f, far_rgba); /* the region's depth cleared */
    if (rr == RAST_OK) rr = refl__planar_draw_scene(pl, child, box, dcs);
    if (rr == RAST_OK) rr = rast_finish(rc);
    if (rr != RAST_OK) return refl__result_from_rast(rr);
    if (!child->warped) {
        /* the region as the mirrored camera sees it (a warped refraction's
           depth is not its camera's: left unshadowed and unlit by mirrors) */
        refl__shadow_job job = refl__shadow_job_of(pl->p, child->vp, refl_mat4_point(child->w_inv, pl->p->view->eye));
        int skip = child->parent >= 0 ? pl->faces[child->parent].object : -1;
        refl_result r = REFL_OK;
        job.region = pl->stencil;
        job.region_value = (uint8_t)child->level;
        job.restore = &pl->targets;
        if (pl->p->desc.lighting.shadows && pl->scene->light_count > 0) {
            if (pl->counts) { /* soft: a mask per jittered light, summed */
                int ns = pl->p->desc.lighting.soft_shadow_samples;
                r = refl__shadow_mask_soft(&job, ns, pl->counts, pl->lit);
                if (r == REFL_OK) r = refl__shade_soft(&job, skip, pl->counts, ns, 0);
            } else {
                r = refl__shadow_mask(&job, pl->lit);
                if (r == REFL_OK) r = refl__shade_lit(&job, skip, pl->lit, 0);
            }
        }
        /* the light the mirrors reflect onto what the mirrored camera sees */
        if (r == REFL_OK && pl->lv.count > 0) r = refl__lv_pass(&job, &pl->lv, &pl->p->desc, skip);
        if (r != REFL_OK) return r;
    }
    pl->p->frame->stats.planar.renderings++;
    if (child->bounces >= pl->p->desc.depth) pl->p->frame->stats.planar.deepest++;
    refl__planar_fill_region(pl, child, box);
    return child->fogged ? refl__planar_fog(pl, child, box, dcs) : REFL_OK;
}

/* The child's camera: the viewer's through child->w, clipped to the world
   half-space n . x >= d (what lies beyond the face); then its scene. */
static refl_result refl__planar_render_child(refl__planar *pl, refl__planar_level *child, const double n[3], double d,
                                             const int box[4], refl__planar_dc *dcs) {
    refl_mat4 proj, view_inv, plane_to_eye;
    float fovy = pl->p->view->fovy_degrees > 0.0f ? pl->p->view->fovy_degrees : 45.0f;
    float aspect = (float)pl->p->frame->width / (float)pl->p->frame->height;
    int k;
    /* the kept half-space as a plane of eye space: through w_inv, then the view */
    if (!refl_mat4_invert(pl->p->view_m, &view_inv)) return REFL_ERROR_INVALID_ARGUMENT;
    plane_to_eye = refl_mat4_mul(child->w_inv, view_inv);
    for (k = 0; k < 4; ++k) {
        const float *col = plane_to_eye.m + 4 * k;
        child->clip[k] = n[0] * col[0] + n[1] * col[1] + n[2] * col[2] - d * col[3];
    }
    /* room for the virtual scene, further away at every bounce */
    proj = refl_mat4_perspective(fovy * (float)(REFL__PI / 180.0), aspect, pl->p->rays.znear,
                                 pl->p->rays.zfar * 2.0f * (float)(child->level + 1));
    if (!refl__planar_oblique(&proj, child->clip)) memset(child->clip, 0, sizeof child->clip);
    child->vp = refl_mat4_mul(refl_mat4_mul(proj, pl->p->view_m), child->w);
    return refl__planar_render_level(pl, child, box, dcs);
}

/* Draws the face over its region (stencil level + 1) with the composite
   fragment (NULL: colour untouched), restoring the face's depth there,
   then lowers the region back to `level`. */
static refl_result refl__planar_restore(refl__planar *pl, int level, refl__planar_comp *comp,
                                        const refl__planar_face *face, rast_fragment_fn composite, const int box[4]) {
    rast_context *rc = pl->p->rc;
    rast_state state = refl__planar_state((uint8_t)(level + 1), RAST_KEEP);
    rast_result rr;
    float far_rgba[4] = {0, 0, 0, 0};
    state.depth_func = RAST_ALWAYS;
    state.vertex_user = &comp->dc;
    refl__planar_scissor(&state, box);
    if (composite) {
        state.blend = 1;
        state.blend_src_rgb = RAST_ONE;
        state.blend_dst_rgb = RAST_SRC_ALPHA;
        state.blend_src_alpha = RAST_ZERO_FACTOR; /* alpha: the region's (opaque) */
        state.blend_dst_alpha = RAST_ONE;
        state.fragment_fn = composite;
        state.fragment_user = comp;
    } else {
        state.color_write = RAST_MASK(0);
    }
    rr = rast_set_state(rc, &state);
    if (rr == RAST_OK) rr = refl__draw_mesh(rc, comp->dc.mesh, face->indices, face->index_count, REFL__BASE_VARYINGS);
    if (rr == RAST_OK) {
        state = refl__planar_state((uint8_t)(level + 1), RAST_DECR);
        state.depth_test = 0;
        state.color_write = RAST_MASK(0);
        state.vertex_fn = NULL;
        refl__planar_scissor(&state, box);
        rr = rast_set_state(rc, &state);
    }
    if (rr == RAST_OK) rr = rast_draw_fullscreen(rc, 0.0f, far_rgba);
    if (rr == RAST_OK) rr = rast_finish(rc);
    if (rr != RAST_OK) return refl__result_from_rast(rr);
    return REFL_OK;
}

static refl_result refl__planar_level_draw(refl__planar *pl, const refl__planar_level *lv, refl__planar_dc *dcs);

/* The mirror image in the face: the child level through the reflection,
   and the levels below it. */
static refl_result refl__planar_mirror_image(refl__planar *pl, const refl__planar_level *lv, int f, double side,
                                             const int box[4], refl__planar_dc *dcs) {
    const refl__planar_face *face = &pl->faces[f];
    refl__planar_level child;
    refl_mat4 r = refl__planar_reflection(face->n, face->d);
    double kept[3];
    refl_result res;
    int k;
    memset(&child, 0, sizeof child);
    child.level = lv->level + 1;
    child.bounces = lv->bounces + 1;
    child.parent = f;
    child.w = refl_mat4_mul(lv->w, r);
    child.w_inv = refl_mat4_mul(r, lv->w_inv);
    /* what lies on the viewer's side of the face (side: +1 the front) */
    for (k = 0; k < 3; ++k) kept[k] = side * face->n[k];
    res = refl__planar_render_child(pl, &child, kept, side * face->d, box, dcs);
    if (res == REFL_OK && child.bounces < pl->p->desc.depth)
        res = refl__planar_level_draw(pl, &child, dcs);
    return res;
}

/* The level's mirrors, each: mark its visible pixels (stencil L -> L + 1),
   draw the mirrored scene there (depth cleared), recurse, then composite
   the face over what its region shows and restore its depth and the
   stencil. Glass faces go through refl__planar_glass. */
static refl_result refl__planar_glass(refl__planar *pl, const refl__planar_level *lv, int f, refl__planar_comp *comp,
                                      const int box[4], refl__planar_dc *dcs);

/* Past the rendering budget: the region `level` goes to RAYTRACE's tracer
   once the recursion is done. */
static refl_result refl__planar_cut(refl__planar *pl, int level, const int box[4]) {
    const refl_frame *fr = pl->p->frame;
    int x, y;
    if (!pl->cut && !(pl->cut = (uint8_t *)refl__calloc(&pl->scene->allocator,
                                                        (size_t)fr->width * (size_t)fr->height, 1)))
        return REFL_ERROR_OUT_OF_MEMORY;
    for (y = box[1]; y < box[3]; ++y)
        for (x = box[0]; x < box[2]; ++x) {
            size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
            pl->cut[i] |= pl->stencil[i] == level;
        }
    return REFL_OK;
}

static refl_result refl__planar_level_draw(refl__planar *pl, const refl__planar_level *lv, refl__planar_dc *dcs) {
    refl_vec3 eye = refl_mat4_point(lv->w_inv, pl->p->view->eye); /* the viewer in this level's world */
    refl__planar_dc *next = dcs + pl->scene->object_count;
    int f;
    for (f = 0; f < pl->face_count; ++f) {
        const refl__planar_face *face = &pl->faces[f];
        refl__planar_comp comp;
        refl_result r;
        int box[4], front = face->n[0] * eye.x + face->n[1] * eye.y + face->n[2] * eye.z - face->d > 0.0;
        if (f == lv->parent) continue;
        /* through a slab, or translucent glass, light has left the glass
           (the slab's far faces are in its in-out refraction): its other
           faces are not met again */
        if ((lv->left_slab || lv->fogged) && face->object == pl->faces[lv->parent].object) continue;
        /* glass is seen from inside too (its far faces from outside fail
           the depth test and mark nothing) */
        if (!front && !face->glass && !pl->no_culling) { ++pl->culled; continue; }
        memset(&comp, 0, sizeof comp);
        refl__draw_ctx_init(&comp.dc, pl->scene, face->object, lv->vp);
        comp.eye = eye;
        /* a mirror seen from behind marks nothing; unculled, it still
           costs its renderings, as formula 5 counts them */
        if ((front || face->glass) && (r = refl__planar_mark(pl, lv, &comp, face)) != REFL_OK) return r;
        if (refl__planar_region(pl, lv->level + 1, box) == 0 && !pl->no_culling) { ++pl->culled; continue; }
        if (pl->p->frame->stats.planar.renderings >= pl->p->desc.planar.max_renderings) {
            r = refl__planar_cut(pl, lv->level + 1, box);
            if (r == REFL_OK) r = refl__planar_restore(pl, lv->level, &comp, face, NULL, box);
            if (r != REFL_OK) return r;
            continue;
        }
        if (face->glass) {
            r = refl__planar_glass(pl, lv, f, &comp, box, next);
        } else {
            r = refl__planar_mirror_image(pl, lv, f, 1.0, box, next);
            if (r == REFL_OK) r = refl__planar_restore(pl, lv->level, &comp, face, refl__planar_comp_fragment, box);
        }
        if (r != REFL_OK) return r;
    }
    return REFL_OK;
}

/* ---- refraction ------------------------------------------------------------------- */

/* Paper 002's appendix: the projective map of the unit square onto the
   quadrilateral q (corners in order from (0,0) through (1,0), (1,1),
   (0,1)), as a 3 x 3 matrix acting on row vectors [u v 1]. */
static int refl__planar_square_to_quad(const double q[4][2], double m[9]) {
    double sx = q[0][0] - q[1][0] + q[2][0] - q[3][0], sy = q[0][1] - q[1][1] + q[2][1] - q[3][1];
    double dx1 = q[1][0] - q[2][0], dx2 = q[3][0] - q[2][0], dy1 = q[1][1] - q[2][1], dy2 = q[3][1] - q[2][1];
    double den = dx1 * dy2 - dx2 * dy1, g, h;
    if (den == 0.0) return 0;
    g = (sx * dy2 - dx2 * sy) / den;
    h = (dx1 * sy - sx * dy1) / den;
    m[0] = q[1][0] - q[0][0] + g * q[1][0]; m[1] = q[1][1] - q[0][1] + g * q[1][1]; m[2] = g;
    m[3] = q[3][0] - q[0][0] + h * q[3][0]; m[4] = q[3][1] - q[0][1] + h * q[3][1]; m[5] = h;
    m[6] = q[0][0];                         m[7] = q[0][1];                         m[8] = 1.0;
    return 1;
}

/* The adjoint: the inverse up to scale, all a projective map needs. */
static void refl__planar_adjoint(const double m[9], double a[9]) {
    a[0] = m[4] * m[8] - m[5] * m[7]; a[1] = m[2] * m[7] - m[1] * m[8]; a[2] = m[1] * m[5] - m[2] * m[4];
    a[3] = m[5] * m[6] - m[3] * m[8]; a[4] = m[0] * m[8] - m[2] * m[6]; a[5] = m[2] * m[3] - m[0] * m[5];
    a[6] = m[3] * m[7] - m[4] * m[6]; a[7] = m[1] * m[6] - m[0] * m[7]; a[8] = m[0] * m[4] - m[1] * m[3];
}

static void refl__planar_mul3(const double a[9], const double b[9], double r[9]) {
    int i, j;
    for (i = 0; i < 3; ++i)
        for (j = 0; j < 3; ++j) r[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
}

/* Normalised device x, y of a world point through vp; 0 behind the eye. */
static int refl__planar_ndc(refl_mat4 vp, refl_vec3 p, double out[2]) {
    const float *m = vp.m;
    double x = m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12], y = m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13];
    double w = m[3] * p.x + m[7] * p.y + m[11] * p.z + m[15];
    if (!(w > 1e-9)) return 0;
    out[0] = x / w;
    out[1] = y / w;
    return 1;
}

/* Translucency for a child seen through glass face f from eye: fogged
   behind the face when desc asks and the eye is outside. */
static void refl__planar_fog_setup(const refl__planar *pl, refl__planar_level *child, int f, const refl_material *m,
                                   refl_vec3 eye) {
    const refl__planar_face *face = &pl->faces[f];
    int c;
    if (!(pl->p->desc.lighting.translucency > 0.0f) ||
        face->n[0] * eye.x + face->n[1] * eye.y + face->n[2] * eye.z - face->d <= 0.0)
        return;
    child->fogged = 1;
    for (c = 0; c < 3; ++c) {
        child->fog[c] = -face->n[c];
        child->fog_rgb[c] = REFL__CLAMP(m->color[c], 0.0f, 1.0f);
    }
    child->fog[3] = face->d;
}

/* A single interface (a face with nothing parallel behind it, or any face
   seen from inside the glass): the paper's refracted camera, bent by
   Snell's law where the view axis meets the face, its image mapped onto
   the face's image by the quad-to-quad map between two projections of the
   face's plane. Any four points of the plane fix that map; a square about
   the axis's point is in front of both cameras, where the face's own
   corners may not be. */
static refl_result refl__planar_single_interface(refl__planar *pl, const refl__planar_level *lv, int f, const int box[4],
                                                 const refl__planar_comp *comp, refl_vec3 axis, refl_vec3 nf,
                                                 double df, float eta, refl__planar_dc *dcs) {
    refl__planar_level child;
    refl_vec3 t, p0, eye_r, u, v, up;
    double quad_v[4][2], quad_r[4][2], m_v[9], m_r[9], adj[9], kept[3], dist;
    float fovy = pl->p->view->fovy_degrees > 0.0f ? pl->p->view->fovy_degrees : 45.0f;
    float aspect = (float)pl->p->frame->width / (float)pl->p->frame->height, tn;
    refl_mat4 proj, view_r;
    int k;
    if (!refl_v3_refract(axis, nf, eta, &t)) return REFL_OK; /* wholly reflective: nothing refracted */
    tn = refl_v3_dot(axis, nf);
    if (tn > -1e-4f) return REFL_OK;
    /* where the axis meets the plane, and the camera bent there */
    dist = ((double)df - (nf.x * comp->eye.x + nf.y * comp->eye.y + nf.z * comp->eye.z)) / tn;
    p0 = refl_v3_add(comp->eye, refl_v3_scale(axis, (float)dist));
    eye_r = refl_v3_sub(p0, refl_v3_scale(t, (float)dist));
    up = refl_mat4_dir(lv->w_inv, pl->p->rays.up);
    if (refl_v3_length(refl_v3_cross(t, up)) < 1e-6f) up = refl_v3(up.z, up.x, up.y);
    view_r = refl_mat4_look_at(eye_r, refl_v3_add(eye_r, t), up);
    /* a square in the plane about the axis's point */
    u = refl_v3_normalize(refl_v3_cross(nf, fabsf(nf.x) < 0.9f ? refl_v3(1, 0, 0) : refl_v3(0, 1, 0)));
    v = refl_v3_cross(nf, u);
    u = refl_v3_scale(u, 0.25f * (float)dist);
    v = refl_v3_scale(v, 0.25f * (float)dist);
    memset(&child, 0, sizeof child);
    child.level = lv->level + 1;
    child.bounces = lv->bounces + 1;
    child.parent = f;
    child.w = child.w_inv = refl_mat4_identity();
    refl__planar_fog_setup(pl, &child, f, comp->dc.material, comp->eye);
    /* behind the face, from the viewer */
    for (k = 0; k < 3; ++k) kept[k] = -(&nf.x)[k];
    {
        /* the refracted camera's projection, clipped at the face */
        refl_mat4 view_inv;
        double c[4];
        proj = refl_mat4_perspective(fovy * (float)(REFL__PI / 180.0), aspect, pl->p->rays.znear,
                                     pl->p->rays.zfar * 2.0f * (float)(child.level + 1));
        if (!refl_mat4_invert(view_r, &view_inv)) return REFL_OK;
        for (k = 0; k < 4; ++k) {
            const float *col = view_inv.m + 4 * k;
            c[k] = kept[0] * col[0] + kept[1] * col[1] + kept[2] * col[2] + df * col[3];
        }
        if (refl__planar_oblique(&proj, c)) memcpy(child.clip, c, sizeof c);
        child.vp = refl_mat4_mul(proj, view_r);
    }
    for (k = 0; k < 4; ++k) {
        float a = k == 1 || k == 2 ? 1.0f : -1.0f, b = k >= 2 ? 1.0f : -1.0f;
        refl_vec3 corner = refl_v3_add(p0, refl_v3_add(refl_v3_scale(u, a), refl_v3_scale(v, b)));
        if (!refl__planar_ndc(lv->vp, corner, quad_v[k]) || !refl__planar_ndc(child.vp, corner, quad_r[k]))
            return REFL_OK; /* grazing: the square reaches behind a camera */
    }
    /* refracted image -> unit square -> the viewer's image */
    if (!refl__planar_square_to_quad(quad_r, m_r) || !refl__planar_square_to_quad(quad_v, m_v)) return REFL_OK;
    refl__planar_adjoint(m_r, adj);
    refl__planar_mul3(adj, m_v, child.h);
    refl__planar_adjoint(child.h, child.h_inv);
    if (!refl_mat4_invert(child.vp, &child.vp_inv)) return REFL_OK;
    child.warped = 1;
    return refl__planar_render_level(pl, &child, box, dcs);
}

/* A glass face. Seen from outside a slab (a parallel face behind it): the
   paper's in-out refraction, light leaving parallel to how it came,
   shifted sideways, one shift for the whole face, taken at the incidence
   of the view axis where it meets the face (of the ray to the face's
   centre when the axis misses it). Otherwise a single interface through
   refl__planar_single_interface; seen from inside beyond the critical
   angle (at the face's centre, the paper's rule), wholly reflective.
   Besides, the mirror image; per pixel
       F_in mirror + (1 - F_in)(1 - F_out) tint e^(-attenuation path) refracted
   (a single interface: F_out = 0, no path). A slab takes two bounces, as
   in RAYTRACE, an interface one. */
static refl_result refl__planar_glass(refl__planar *pl, const refl__planar_level *lv, int f, refl__planar_comp *comp,
                                      const int box[4], refl__planar_dc *dcs) {
    const refl__planar_face *face = &pl->faces[f];
    const refl_material *m = comp->dc.material;
    const refl__view_rays *vr = &pl->p->rays;
    refl_frame *fr = pl->p->frame;
    float ior = m->ior > 0.0f ? m->ior : 1.5f, tint[3], n1, n2;
    size_t i, npx = (size_t)fr->width * (size_t)fr->height;
    int inside, slab, refracts = 0, c, x, y, k;
    double side;
    refl_vec3 nv, axis, centre = refl_v3(0, 0, 0);
    float df;
    refl_result r = REFL_OK;
    inside = face->n[0] * comp->eye.x + face->n[1] * comp->eye.y + face->n[2] * comp->eye.z - face->d <= 0.0;
    side = inside ? -1.0 : 1.0;
    nv = refl_v3((float)(side * face->n[0]), (float)(side * face->n[1]), (float)(side * face->n[2]));
    df = (float)(side * face->d);
    n1 = inside ? ior : 1.0f;
    n2 = inside ? 1.0f : ior;
    slab = !inside && face->opposite >= 0;
    for (c = 0; c < 3; ++c) tint[c] = inside ? 1.0f : m->tint[0] + m->tint[1] + m->tint[2] > 0.0f ? m->tint[c] : 1.0f;
    for (k = 0; k < face->index_count; ++k) {
        const float *pp = comp->dc.mesh->positions + 3 * (size_t)face->indices[k];
        centre = refl_v3_add(centre, refl_mat4_point(comp->dc.model, refl_v3(pp[0], pp[1], pp[2])));
    }
    centre = refl_v3_scale(centre, 1.0f / (float)REFL__MAX(face->index_count, 1));
    axis = refl_v3_normalize(refl_mat4_dir(lv->w_inv, vr->forward));
    if (refl_v3_dot(axis, nv) > -1e-3f) axis = refl_v3_normalize(refl_v3_sub(centre, comp->eye)); /* misses */
    if (lv->bounces + (slab ? 2 : 1) <= pl->p->desc.depth) {
        /* the paper's critical-angle rule, at the face's centre */
        refl_vec3 to_centre = refl_v3_normalize(refl_v3_sub(centre, comp->eye));
        float cc = -refl_v3_dot(to_centre, nv);
        refracts = refl_fresnel_dielectric(cc, n1, n2) < 1.0f;
    }
    if (refracts && slab) {
        refl__planar_level child;
        double behind[3];
        refl_vec3 t, shift;
        float cos_i = -refl_v3_dot(axis, nv), cos_t;
        refracts = cos_i > 1e-4f && refl_v3_refract(axis, nv, 1.0f / ior, &t);
        if (refracts) {
            cos_t = -refl_v3_dot(t, nv);
            /* where the refracted ray leaves the slab, less where the
               straight one would: the shift of every exiting ray */
            shift = refl_v3_sub(refl_v3_scale(t, (float)face->thickness / cos_t),
                                refl_v3_scale(axis, (float)face->thickness / cos_i));
            memset(&child, 0, sizeof child);
            child.level = lv->level + 1;
            child.bounces = lv->bounces + 2;
            child.parent = f;
            child.left_slab = 1;
            refl__planar_fog_setup(pl, &child, f, m, comp->eye);
            child.w = refl_mat4_mul(lv->w, refl_mat4_translate(refl_v3_scale(shift, -1.0f)));
            child.w_inv = refl_mat4_mul(refl_mat4_translate(shift), lv->w_inv);
            /* what lies behind the face: light may also leave by another
               face (the floor under a slab), so not only beyond the back */
            for (c = 0; c < 3; ++c) behind[c] = -face->n[c];
            r = refl__planar_render_child(pl, &child, behind, -face->d, box, dcs);
            /* mirrors seen through the slab, with the bounces left */
            if (r == REFL_OK && child.bounces < pl->p->desc.depth) r = refl__planar_level_draw(pl, &child, dcs);
            if (r != REFL_OK) return r;
        }
    } else if (refracts) {
        /* the region starts black: where the map leaves it, nothing shows */
        for (i = 0; i < npx; ++i)
            if (pl->stencil[i] == lv->level + 1) memset(pl->color + 4 * i, 0, 3 * sizeof(float));
        r = refl__planar_single_interface(pl, lv, f, box, comp, axis, nv, df, n1 / n2, dcs);
        if (r != REFL_OK) return r;
    }
    if (refracts)
        for (i = 0; i < npx; ++i)
            if (pl->stencil[i] == lv->level + 1) {
                memcpy(pl->saved + 4 * i, pl->color + 4 * i, 4 * sizeof(float));
                if (lv->level == 0) memcpy(pl->saved_points + 3 * i, fr->points + 3 * i, 3 * sizeof(float));
            }
    r = refl__planar_mirror_image(pl, lv, f, side, box, dcs);
    if (r != REFL_OK) return r;
    for (y = box[1]; y < box[3]; ++y)
        for (x = box[0]; x < box[2]; ++x) {
            float nx = 2.0f * ((float)x + 0.5f) / (float)fr->width - 1.0f;
            float ny = 1.0f - 2.0f * ((float)y + 0.5f) / (float)fr->height;
            refl_vec3 d;
            float cos_i, sin_t, cos_t, f_in, through = 0.0f;
            i = (size_t)y * (size_t)fr->width + (size_t)x;
            if (pl->stencil[i] != lv->level + 1) continue;
            d = refl_v3_add(vr->forward, refl_v3_add(refl_v3_scale(vr->right, nx), refl_v3_scale(vr->up, ny)));
            d = refl_v3_normalize(refl_mat4_dir(lv->w_inv, d));
            cos_i = REFL__CLAMP(-refl_v3_dot(d, nv), 0.0f, 1.0f);
            f_in = refl_fresnel_dielectric(cos_i, n1, n2);
            if (refracts && f_in < 1.0f) {
                sin_t = sqrtf(1.0f - cos_i * cos_i) * n1 / n2;
                cos_t = sqrtf(REFL__MAX(1.0f - sin_t * sin_t, 1e-12f));
                through = 1.0f - f_in;
                if (slab)
                    through *= (1.0f - refl_fresnel_dielectric(cos_t, ior, 1.0f)) *
                               expf(-REFL__MAX(m->attenuation, 0.0f) * (float)face->thickness / cos_t);
            }
            for (c = 0; c < 3; ++c)
                pl->color[4 * i + (size_t)c] =
                    f_in * pl->color[4 * i + (size_t)c] + through * tint[c] * pl->saved[4 * i + (size_t)c];
            /* the point shown follows the stronger branch, as RAYTRACE's:
               the mirror image wrote its points last */
            if (lv->level == 0 && f_in < 0.5f)
                for (c = 0; c < 3; ++c) fr->points[3 * i + (size_t)c] = refracts ? pl->saved_points[3 * i + (size_t)c] : NAN;
        }
    return refl__planar_restore(pl, lv->level, comp, face, NULL, box);
}

/* Whether PLANAR can draw reflector `object` (*can): a planar mirror or
   glass (a few planes at most, refl__planar_find_faces); a curved one it
   cannot. */
static refl_result refl__planar_handles(const refl__pass *p, int object, int *can) {
    const refl_scene *s = p->scene;
    refl__planar_face *faces = NULL;
    uint8_t *only = (uint8_t *)refl__calloc(&s->allocator, (size_t)s->object_count, 1);
    int count = 0;
    refl_result r;
    if (!only) return REFL_ERROR_OUT_OF_MEMORY;
    only[object] = 1;
    r = refl__planar_find_faces(s, only, &faces, &count);
    if (r == REFL_OK) refl__planar_free_faces(s, faces, count);
    refl__free(&s->allocator, only);
    *can = count > 0;
    return r;
}

static const char *refl__options_planar(refl_render_desc *d) {
    if (d->planar.no_culling < 0 || d->planar.no_culling > 1) return "planar.no_culling: 0 or 1";
    if (d->planar.max_renderings < 0) return "planar.max_renderings: 0 (256) or more";
    if (d->planar.max_renderings == 0) d->planar.max_renderings = 256;
    return NULL;
}

static refl_result refl__method_planar(refl__pass *p) {
    const refl_scene *s = p->scene;
    refl_frame *f = p->frame;
    refl__planar pl;
    refl__planar_level top;
    refl__planar_dc *dcs;
    rast_targets t;
    refl_result r;
    size_t i, n = (size_t)f->width * (size_t)f->height;
    double t0 = refl__now_ms();
    memset(&pl, 0, sizeof pl);
    pl.p = p;
    pl.scene = s;
    pl.no_culling = p->desc.planar.no_culling;
    r = refl__planar_find_faces(s, p->mine, &pl.faces, &pl.face_count);
    if (r != REFL_OK) return r;
    f->stats.ms_build = refl__now_ms() - t0;
    if (pl.face_count == 0) {
        refl__planar_free_faces(s, pl.faces, 0);
        return REFL_OK; /* no planar mirror: what DIRECT shows */
    }
    pl.color = f->rgba;
    pl.stencil = (uint8_t *)refl__calloc(&s->allocator, n, 1);
    pl.saved = (float *)refl__calloc(&s->allocator, n, 4 * sizeof(float));
    pl.saved_points = (float *)refl__calloc(&s->allocator, n, 3 * sizeof(float));
    pl.lit = (uint8_t *)refl__calloc(&s->allocator, n, 1);
    if (p->desc.lighting.translucency > 0.0f) pl.unfogged = (float *)refl__calloc(&s->allocator, n, 4 * sizeof(float));
    dcs = (refl__planar_dc *)refl__calloc(&s->allocator, (size_t)(p->desc.depth + 1) * (size_t)s->object_count,
                                          sizeof(refl__planar_dc));
    if (refl__soft_shadows(&p->desc, s))
        pl.counts = (uint16_t *)refl__calloc(&s->allocator, n * REFL__SHADOW_MAX_LIGHTS, sizeof(uint16_t));
    if (!pl.stencil || !pl.saved || !pl.saved_points || !pl.lit || !dcs ||
        (p->desc.lighting.translucency > 0.0f && !pl.unfogged) ||
        (refl__soft_shadows(&p->desc, s) && !pl.counts)) {
        r = REFL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    t = refl__float_targets(pl.color, f->depth, pl.stencil, f->width, f->height);
    pl.targets = t;
    r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    if (r != REFL_OK) goto done;
    memset(&top, 0, sizeof top);
    top.w = top.w_inv = refl_mat4_identity();
    top.vp = p->vp;
    top.parent = -1;
    if (p->desc.lighting.light_volumes) {
        /* the reflected light on what the viewer sees directly */
        refl__shadow_job job = refl__shadow_job_of(p, p->vp, p->view->eye);
        job.region = pl.stencil;
        job.region_value = 0;
        job.restore = &pl.targets;
        refl__lv_init(&pl.lv, s, pl.faces, pl.face_count, p->desc.lighting.caustic_samples);
        r = refl__lv_pass(&job, &pl.lv, &p->desc, -1);
        if (r != REFL_OK) goto done;
    }
    r = refl__planar_level_draw(&pl, &top, dcs);
    if (r == REFL_OK && pl.cut) {
        for (i = 0; i < n; ++i) f->stats.planar.traced += pl.cut[i];
        r = refl__trace_marked(p, pl.cut);
    }
    if (r != REFL_OK) goto done;
    f->stats.planar.culled = pl.culled;
    f->stats.ms_reflect = refl__now_ms() - t0 - f->stats.ms_build;
done:
    /* the frame's own targets back: rc's queue is empty or dropped */
    refl__free(&s->allocator, dcs);
    refl__free(&s->allocator, pl.stencil);
    refl__free(&s->allocator, pl.cut);
    refl__free(&s->allocator, pl.saved);
    refl__free(&s->allocator, pl.saved_points);
    refl__free(&s->allocator, pl.lit);
    refl__free(&s->allocator, pl.unfogged);
    refl__free(&s->allocator, pl.counts);
    refl__planar_free_faces(s, pl.faces, pl.face_count);
    return r;
}
