/* Vertex processing, primitive assembly, homogeneous clipping and setup:
   turns a range of a draw's primitives into records (rast__tri, rast__point,
   rast__line) in a chunk. Runs on workers, one chunk per job. */
#include "internal.h"

/* A clip-space vertex is a float array: x, y, z, w, then the varyings,
   the layout of rast_vertex_out and of the vertex outputs of indexed draws,
   so setup reads them in place. */
enum { RAST__VTX_FLOATS = 4 + RAST_MAX_VARYINGS };
typedef float rast__vtx;
typedef char rast__vertex_out_is_packed[offsetof(rast_vertex_out, varyings) == 4 * sizeof(float) ? 1 : -1];

enum { RAST__MAX_POLY = 16 };

/* The default vertex program: the position (w = 1 when it has three
   floats) through the optional matrix, then the varyings copied; writes
   4 + num_varyings floats. */
static void rast__default_vertex(const rast_draw_desc *d, const float *src, float *out) {
    float in[4];
    int k;
    in[0] = src[0]; in[1] = src[1]; in[2] = src[2];
    in[3] = d->position_size == 4 ? src[3] : 1.0f;
    if (d->matrix) {
        const float *m = d->matrix;
        for (k = 0; k < 4; ++k) out[k] = m[k] * in[0] + m[4 + k] * in[1] + m[8 + k] * in[2] + m[12 + k] * in[3];
    } else {
        for (k = 0; k < 4; ++k) out[k] = in[k];
    }
    for (k = 0; k < d->num_varyings; ++k) out[4 + k] = src[d->position_size + k];
}

/* The vertex program: the caller's callback or the default. Returns the
   number of outputs. */
static int rast__vertex(const rast__cmd *cmd, int index, rast_vertex_out *out) {
    const rast__pipe *p = cmd->pipe;
    const rast_draw_desc *d = &cmd->d;
    const float *v = d->vertices + (size_t)index * (size_t)d->stride;
    int n;
    if (p->s.vertex_fn) {
        n = p->s.vertex_fn(p->s.vertex_user, v, index, out, cmd->max_out);
        return RAST__CLAMP(n, 0, cmd->max_out);
    }
    /* position and varyings are contiguous in rast_vertex_out (asserted above) */
    rast__default_vertex(d, v, out->position);
    return 1;
}

/* Indexed draws run the vertex program once per vertex, in jobs of this many. */
enum { RAST__VERTEX_JOB = 4096 };

static size_t rast__vout_floats(const rast__cmd *cmd) { return 4 + (size_t)cmd->d.num_varyings; }

static unsigned rast__outcode(const rast__pipe *p, const float *c);
static int rast__vtx_finite(const rast__vtx *v, int nvar);
static int rast__vertex_window(const rast__pipe *p, const rast__vtx *v, rast__vinfo *o);

static void rast__vertex_job(rast__cmd *cmd, int job) {
    int v0 = job * RAST__VERTEX_JOB, v1 = RAST__MIN(cmd->d.vertex_count, v0 + RAST__VERTEX_JOB);
    size_t nf = rast__vout_floats(cmd);
    int v, k;
    for (v = v0; v < v1; ++v) {
        rast_vertex_out out[RAST_MAX_VERTEX_OUTPUTS];
        int n = rast__vertex(cmd, v, out);
        cmd->vout_count[v] = (uint8_t)n;
        for (k = 0; k < n; ++k) {
            size_t at = (size_t)v * (size_t)cmd->max_out + (size_t)k;
            float *dst = cmd->vout + at * nf;
            rast__vinfo *wi = &cmd->vinfo[at];
            memcpy(dst, out[k].position, 4 * sizeof(float));
            memcpy(dst + 4, out[k].varyings, (size_t)cmd->d.num_varyings * sizeof(float));
            /* what every triangle using this vertex would compute again:
               where it is, and whether clipping is needed */
            if (!rast__vtx_finite(dst, cmd->d.num_varyings)) wi->code = RAST__VINFO_BAD;
            else wi->code = rast__outcode(cmd->pipe, dst);
            if (!wi->code && !rast__vertex_window(cmd->pipe, dst, wi)) wi->code = RAST__VINFO_CLIP;
        }
    }
}

/* Nonzero when every float is finite (exponent bits not all ones); the
   checks are independent, so this vectorises. */
static int rast__vtx_finite(const rast__vtx *v, int nvar) {
    uint32_t bad = 0, bits;
    int k;
    for (k = 0; k < 4 + nvar; ++k) {
        memcpy(&bits, &v[k], 4);
        bad |= (uint32_t)((bits & 0x7F800000u) == 0x7F800000u);
    }
    return !bad;
}

/* Signed distance to clip plane `plane` (inside >= 0). */
static float rast__plane_dist(const rast__pipe *p, int plane, const float *c) {
    switch (plane) {
    case 0: return c[2] + c[3];                 /* near */
    case 1: return c[3] - c[2];                 /* far */
    case 2: return p->guard_x * c[3] - c[0];    /* guard band */
    case 3: return p->guard_x * c[3] + c[0];
    case 4: return p->guard_y * c[3] - c[1];
    default: return p->guard_y * c[3] + c[1];
    }
}

/* Bit `plane` set when the point is outside that plane. */
static unsigned rast__outcode(const rast__pipe *p, const float *c) {
    float gx = p->guard_x * c[3], gy = p->guard_y * c[3];
    return (unsigned)(c[2] + c[3] < 0.0f) | (unsigned)(c[3] - c[2] < 0.0f) << 1 |
           (unsigned)(gx - c[0] < 0.0f) << 2 | (unsigned)(gx + c[0] < 0.0f) << 3 |
           (unsigned)(gy - c[1] < 0.0f) << 4 | (unsigned)(gy + c[1] < 0.0f) << 5;
}

static void rast__vtx_lerp(rast__vtx *o, const rast__vtx *a, const rast__vtx *b, float t, int nvar) {
    int k;
    for (k = 0; k < 4; ++k) o[k] = a[k] + t * (b[k] - a[k]);
    for (k = 0; k < nvar; ++k) o[4 + k] = a[4 + k] + t * (b[4 + k] - a[4 + k]);
}

/* Window position of a clip-space point. */
static void rast__to_window(const rast__pipe *p, const float *c, float *x, float *y, float *z, float *iw) {
    float i = 1.0f / c[3];
    *x = c[0] * i * p->vp_sx + p->vp_tx;
    *y = c[1] * i * p->vp_sy + p->vp_ty;
    *z = c[2] * i * 0.5f + 0.5f;
    *iw = i;
}

/* Setup of a triangle that lies within the clip volume and the guard band. */
/* Window position of one clip-space vertex in fixed point, or 0 when it
   is unusable (w <= 0, or off any plausible window). Shared by triangle
   setup and the per-vertex pass of indexed draws, so both paths give the
   same bits. */
static int rast__vertex_window(const rast__pipe *p, const rast__vtx *v, rast__vinfo *o) {
    float wx, wy;
    if (!(v[3] > 0.0f)) return 0;
    rast__to_window(p, v, &wx, &wy, &o->z, &o->iw);
    if (!(fabsf(wx) < 1e6f && fabsf(wy) < 1e6f)) return 0;
    o->fx = (int32_t)rast__round(wx * (float)(1 << RAST_SUBPIXEL_BITS));
    o->fy = (int32_t)rast__round(wy * (float)(1 << RAST_SUBPIXEL_BITS));
    return 1;
}

static void rast__emit_tri_window(rast__chunk *ch, const rast__vtx *va, const rast__vtx *vb, const rast__vtx *vc,
                                  const rast__vinfo *wa, const rast__vinfo *wb, const rast__vinfo *wc,
                                  const float *flat);

/* Setup of a triangle that lies within the clip volume and the guard band. */
static void rast__emit_tri(rast__chunk *ch, const rast__vtx *va, const rast__vtx *vb, const rast__vtx *vc,
                           const float *flat) {
    const rast__pipe *p = ch->cmd->pipe;
    rast__vinfo w[3];
    if (!rast__vertex_window(p, va, &w[0]) || !rast__vertex_window(p, vb, &w[1]) ||
        !rast__vertex_window(p, vc, &w[2]))
        return;
    rast__emit_tri_window(ch, va, vb, vc, &w[0], &w[1], &w[2], flat);
}

/* The rest of triangle setup, from window positions: area, culling,
   orientation, bounds and the record. */
static void rast__emit_tri_window(rast__chunk *ch, const rast__vtx *va, const rast__vtx *vb, const rast__vtx *vc,
                                  const rast__vinfo *wa, const rast__vinfo *wb, const rast__vinfo *wc,
                                  const float *flat) {
    const rast__cmd *cmd = ch->cmd;
    const rast__pipe *p = cmd->pipe;
    int nvar = cmd->d.num_varyings, i, k;
    const rast__vtx *v[3];
    float wz[3], iw[3];
    int32_t fx[3], fy[3];
    int64_t area, minx, maxx, miny, maxy;
    int front, x0, y0, x1, y1;
    rast__tri *t;
    float *vd;
    v[0] = va; v[1] = vb; v[2] = vc;
    fx[0] = wa->fx; fy[0] = wa->fy; wz[0] = wa->z; iw[0] = wa->iw;
    fx[1] = wb->fx; fy[1] = wb->fy; wz[1] = wb->z; iw[1] = wb->iw;
    fx[2] = wc->fx; fy[2] = wc->fy; wz[2] = wc->z; iw[2] = wc->iw;
    area = ((int64_t)fx[1] - fx[0]) * ((int64_t)fy[2] - fy[0]) -
           ((int64_t)fx[2] - fx[0]) * ((int64_t)fy[1] - fy[0]);
    if (area == 0) return;
    /* image y points down, so counter-clockwise in NDC has negative area */
    front = p->front_is_ccw ? area < 0 : area > 0;
    if ((front && p->cull_front) || (!front && p->cull_back)) return;
    if (area < 0) { /* orient so that edge functions are positive inside */
        const rast__vtx *tv = v[1]; float tf; int32_t ti;
        v[1] = v[2]; v[2] = tv;
        ti = fx[1]; fx[1] = fx[2]; fx[2] = ti;
        ti = fy[1]; fy[1] = fy[2]; fy[2] = ti;
        tf = wz[1]; wz[1] = wz[2]; wz[2] = tf;
        tf = iw[1]; iw[1] = iw[2]; iw[2] = tf;
        area = -area;
    }
    minx = RAST__MIN(fx[0], RAST__MIN(fx[1], fx[2]));
    maxx = RAST__MAX(fx[0], RAST__MAX(fx[1], fx[2]));
    miny = RAST__MIN(fy[0], RAST__MIN(fy[1], fy[2]));
    maxy = RAST__MAX(fy[0], RAST__MAX(fy[1], fy[2]));
    /* pixels whose centre (i + 1/2) can lie inside */
    x0 = (int)rast__floor_px(minx + ((1 << RAST_SUBPIXEL_BITS) / 2 - 1));
    y0 = (int)rast__floor_px(miny + ((1 << RAST_SUBPIXEL_BITS) / 2 - 1));
    x1 = (int)rast__floor_px(maxx - (1 << RAST_SUBPIXEL_BITS) / 2) + 1;
    y1 = (int)rast__floor_px(maxy - (1 << RAST_SUBPIXEL_BITS) / 2) + 1;
    x0 = RAST__MAX(x0, p->clip[0]); y0 = RAST__MAX(y0, p->clip[1]);
    x1 = RAST__MIN(x1, p->clip[2]); y1 = RAST__MIN(y1, p->clip[3]);
    if (x0 >= x1 || y0 >= y1) return;

    t = (rast__tri *)rast__chunk_push(ch, rast__rec_size(RAST__REC_TRI, nvar));
    if (!t) return;
    t->h.kind = RAST__REC_TRI;
    t->h.front = (uint8_t)front;
    t->h.pad = 0;
    t->h.x0 = (int16_t)x0; t->h.y0 = (int16_t)y0; t->h.x1 = (int16_t)x1; t->h.y1 = (int16_t)y1;
    for (i = 0; i < 3; ++i) {
        t->fx[i] = fx[i];
        t->fy[i] = fy[i];
        t->z[i] = wz[i];
        t->iw[i] = iw[i];
    }
    t->inv_area = (float)(1.0 / (double)area);
    vd = (float *)(t + 1);
    for (k = 0; k < nvar; ++k) {
        if (flat) {
            vd[3 * k] = flat[k]; vd[3 * k + 1] = 0.0f; vd[3 * k + 2] = 0.0f;
        } else {
            vd[3 * k] = v[0][4 + k];
            vd[3 * k + 1] = v[1][4 + k] - v[0][4 + k];
            vd[3 * k + 2] = v[2][4 + k] - v[0][4 + k];
        }
    }
}

/* Clips a triangle against near, far and the guard band (Sutherland-Hodgman),
   then emits the fan. An edge crossing a plane is always interpolated from
   its inside end, so neighbours sharing the edge get the same new vertex. */
static void rast__setup_tri(rast__chunk *ch, const rast__vtx *a, const rast__vtx *b,
                            const rast__vtx *c) {
    const rast__cmd *cmd = ch->cmd;
    const rast__pipe *p = cmd->pipe;
    int nvar = cmd->d.num_varyings, plane, i, n = 3, outside_any = 0;
    const float *flat = p->s.shading == RAST_FLAT ? c + 4 : NULL;
    float buf[2][RAST__MAX_POLY][RAST__VTX_FLOATS];
    float (*in)[RAST__VTX_FLOATS] = buf[0], (*out)[RAST__VTX_FLOATS] = buf[1];
    if (!rast__vtx_finite(a, nvar) || !rast__vtx_finite(b, nvar) || !rast__vtx_finite(c, nvar))
        return;
    {
        unsigned oa = rast__outcode(p, a), ob = rast__outcode(p, b), oc = rast__outcode(p, c);
        if (oa & ob & oc) return; /* wholly outside one plane */
        outside_any = (oa | ob | oc) != 0;
    }
    if (!outside_any) {
        rast__emit_tri(ch, a, b, c, flat);
        return;
    }
    memcpy(in[0], a, (size_t)(4 + nvar) * sizeof(float));
    memcpy(in[1], b, (size_t)(4 + nvar) * sizeof(float));
    memcpy(in[2], c, (size_t)(4 + nvar) * sizeof(float));
    for (plane = 0; plane < 6 && n >= 3; ++plane) {
        int m = 0;
        for (i = 0; i < n; ++i) {
            const rast__vtx *u = in[i], *w = in[i + 1 == n ? 0 : i + 1];
            float du = rast__plane_dist(p, plane, u), dw = rast__plane_dist(p, plane, w);
            if (du >= 0.0f) memcpy(out[m++], u, (size_t)(4 + nvar) * sizeof(float));
            if ((du >= 0.0f) != (dw >= 0.0f) && m < RAST__MAX_POLY) {
                if (du >= 0.0f) rast__vtx_lerp(out[m++], u, w, du / (du - dw), nvar);
                else rast__vtx_lerp(out[m++], w, u, dw / (dw - du), nvar);
            }
        }
        n = m;
        { float (*t)[RAST__VTX_FLOATS] = in; in = out; out = t; }
    }
    for (i = 1; i + 1 < n; ++i) rast__emit_tri(ch, in[0], in[i], in[i + 1], flat);
}

static void rast__setup_point(rast__chunk *ch, const rast__vtx *v) {
    const rast__cmd *cmd = ch->cmd;
    const rast__pipe *p = cmd->pipe;
    int nvar = cmd->d.num_varyings, size = p->point_size;
    float wx, wy, wz, iw;
    int64_t fx, fy, left, top;
    int x0, y0, x1, y1;
    rast__point *pt;
    if (!rast__vtx_finite(v, nvar)) return;
    /* GL clips a point by its centre: outside the clip volume it is gone,
       inside it draws whole (clipped to the viewport by pixels) */
    if (!(v[3] > 0.0f) || v[2] < -v[3] || v[2] > v[3] ||
        v[0] < -v[3] || v[0] > v[3] || v[1] < -v[3] ||
        v[1] > v[3])
        return;
    rast__to_window(p, v, &wx, &wy, &wz, &iw);
    if (!(fabsf(wx) < 1e7f && fabsf(wy) < 1e7f)) return;
    fx = rast__round(wx * (float)(1 << RAST_SUBPIXEL_BITS));
    fy = rast__round(wy * (float)(1 << RAST_SUBPIXEL_BITS));
    /* the N x N square centred on the point covers the pixels whose centres
       lie in [left, left + N) x (top, top + N]: ties go left and down, as
       in llvmpipe (GL leaves them to the implementation) */
    left = fx - (int64_t)size * ((1 << RAST_SUBPIXEL_BITS) / 2);
    top = fy - (int64_t)size * ((1 << RAST_SUBPIXEL_BITS) / 2);
    x0 = (int)rast__floor_px(left + ((1 << RAST_SUBPIXEL_BITS) / 2 - 1));
    y0 = (int)rast__floor_px(top - (1 << RAST_SUBPIXEL_BITS) / 2) + 1;
    x1 = x0 + size;
    y1 = y0 + size;
    if (ch->splat) { /* clipped where drawn */
        rast__splat *sp;
        if (x1 <= p->clip[0] || x0 >= p->clip[2] || y1 <= p->clip[1] || y0 >= p->clip[3]) return;
        sp = (rast__splat *)rast__chunk_push(ch, sizeof(rast__splat));
        if (!sp) return;
        sp->x = (int16_t)x0;
        sp->y = (int16_t)y0;
        sp->z = RAST__CLAMP(wz, 0.0f, 1.0f);
        sp->rgba = rast__pack_rgba8(nvar >= 4 ? v + 4 : cmd->d.color);
        return;
    }
    x0 = RAST__MAX(x0, p->clip[0]); y0 = RAST__MAX(y0, p->clip[1]);
    x1 = RAST__MIN(x1, p->clip[2]); y1 = RAST__MIN(y1, p->clip[3]);
    if (x0 >= x1 || y0 >= y1) return;
    pt = (rast__point *)rast__chunk_push(ch, rast__rec_size(RAST__REC_POINT, nvar));
    if (!pt) return;
    pt->h.kind = RAST__REC_POINT;
    pt->h.front = 1;
    pt->h.pad = 0;
    pt->h.x0 = (int16_t)x0; pt->h.y0 = (int16_t)y0; pt->h.x1 = (int16_t)x1; pt->h.y1 = (int16_t)y1;
    pt->z = wz;
    pt->w = v[3];
    memcpy(pt + 1, (v + 4), (size_t)nvar * sizeof(float));
}

static void rast__setup_line(rast__chunk *ch, const rast__vtx *a, const rast__vtx *b) {
    const rast__cmd *cmd = ch->cmd;
    const rast__pipe *p = cmd->pipe;
    int nvar = cmd->d.num_varyings, plane, k;
    float e[2][RAST__VTX_FLOATS];
    float *vw;
    rast__line *ln;
    float lo_x, hi_x, lo_y, hi_y;
    if (!rast__vtx_finite(a, nvar) || !rast__vtx_finite(b, nvar)) return;
    memcpy(e[0], a, (size_t)(4 + nvar) * sizeof(float));
    memcpy(e[1], b, (size_t)(4 + nvar) * sizeof(float));
    if (p->s.shading == RAST_FLAT) memcpy(e[0] + 4, b + 4, (size_t)nvar * sizeof(float));
    for (plane = 0; plane < 6; ++plane) {
        float d0 = rast__plane_dist(p, plane, e[0]), d1 = rast__plane_dist(p, plane, e[1]);
        if (d0 < 0.0f && d1 < 0.0f) return;
        if (d0 < 0.0f) rast__vtx_lerp(e[0], e[1], e[0], d1 / (d1 - d0), nvar);
        else if (d1 < 0.0f) rast__vtx_lerp(e[1], e[0], e[1], d0 / (d0 - d1), nvar);
    }
    if (!(e[0][3] > 0.0f) || !(e[1][3] > 0.0f)) return;
    ln = (rast__line *)rast__chunk_push(ch, rast__rec_size(RAST__REC_LINE, nvar));
    if (!ln) return;
    for (k = 0; k < 2; ++k) rast__to_window(p, e[k], &ln->x[k], &ln->y[k], &ln->z[k], &ln->iw[k]);
    vw = (float *)(ln + 1);
    for (k = 0; k < nvar; ++k) {
        vw[2 * k] = e[0][4 + k];
        vw[2 * k + 1] = e[1][4 + k] - e[0][4 + k];
    }
    lo_x = RAST__MIN(ln->x[0], ln->x[1]); hi_x = RAST__MAX(ln->x[0], ln->x[1]);
    lo_y = RAST__MIN(ln->y[0], ln->y[1]); hi_y = RAST__MAX(ln->y[0], ln->y[1]);
    ln->h.kind = RAST__REC_LINE;
    ln->h.front = 1;
    ln->h.pad = 0;
    ln->h.x0 = (int16_t)RAST__MAX((int)floorf(lo_x) - 1, p->clip[0]);
    ln->h.y0 = (int16_t)RAST__MAX((int)floorf(lo_y) - 1, p->clip[1]);
    ln->h.x1 = (int16_t)RAST__MIN((int)floorf(hi_x) + 2, p->clip[2]);
    ln->h.y1 = (int16_t)RAST__MIN((int)floorf(hi_y) + 2, p->clip[3]);
    if (ln->h.x0 >= ln->h.x1 || ln->h.y0 >= ln->h.y1) { /* nothing visible: take it back */
        ch->used -= rast__rec_size(RAST__REC_LINE, nvar);
        ch->nrec--;
    }
}

/* Output `layer` of the vertex at position `i` of the draw, read in place,
   or NULL when the vertex has no such output. */
static const rast__vtx *rast__fetch(const rast__cmd *cmd, int i, int layer,
                                    rast_vertex_out *scratch, int *scratch_n, int *scratch_index) {
    int index = cmd->d.indices ? (int)cmd->d.indices[i] : i;
    if (cmd->vout) {
        if (layer >= cmd->vout_count[index]) return NULL;
        return cmd->vout + ((size_t)index * (size_t)cmd->max_out + (size_t)layer) * rast__vout_floats(cmd);
    }
    if (*scratch_index != index) {
        *scratch_n = rast__vertex(cmd, index, scratch);
        *scratch_index = index;
    }
    return layer < *scratch_n ? scratch[layer].position : NULL;
}

/* Triangles of an indexed draw, whose vertices were transformed once with
   their window positions and clip codes: a triangle inside the guard band
   goes straight to setup, only the others through clipping. */
static void rast__setup_indexed_tris(rast__chunk *ch, int p0, int p1) {
    const rast__cmd *cmd = ch->cmd;
    const uint32_t *idx = cmd->d.indices;
    size_t nf = rast__vout_floats(cmd), mo = (size_t)cmd->max_out;
    int flat = cmd->pipe->s.shading == RAST_FLAT, prim, layer, j;
    for (prim = p0; prim < p1 && !ch->failed; ++prim) {
        for (layer = 0; layer < cmd->max_out; ++layer) {
            const rast__vtx *v[3];
            const rast__vinfo *w[3];
            for (j = 0; j < 3; ++j) {
                size_t at = (size_t)idx[3 * prim + j] * mo + (size_t)layer;
                if (layer >= cmd->vout_count[idx[3 * prim + j]]) break;
                v[j] = cmd->vout + at * nf;
                w[j] = &cmd->vinfo[at];
            }
            if (j < 3) break;
            if ((w[0]->code | w[1]->code | w[2]->code) == 0)
                rast__emit_tri_window(ch, v[0], v[1], v[2], w[0], w[1], w[2], flat ? v[2] + 4 : NULL);
            else if (!((w[0]->code | w[1]->code | w[2]->code) & RAST__VINFO_BAD) &&
                     !(w[0]->code & w[1]->code & w[2]->code & 0x3Fu))
                rast__setup_tri(ch, v[0], v[1], v[2]);
        }
    }
}

/* Points straight from the caller's array: the default vertex program
   inlined, no per-vertex copies (the C3RC method splats millions). */
static void rast__setup_points_direct(rast__chunk *ch, int p0, int p1) {
    const rast__cmd *cmd = ch->cmd;
    const rast_draw_desc *d = &cmd->d;
    float v[RAST__VTX_FLOATS];
    int i;
    for (i = p0; i < p1 && !ch->failed; ++i) {
        const float *src = d->vertices + (size_t)i * (size_t)d->stride;
#if defined(__GNUC__) || defined(__clang__)
        if (i + 8 < p1) __builtin_prefetch(src + 8 * (size_t)d->stride); /* a miss per line otherwise */
#endif
        if (!d->matrix && d->position_size == 4) { /* already x, y, z, w, varyings */
            rast__setup_point(ch, src);
            continue;
        }
        rast__default_vertex(d, src, v);
        rast__setup_point(ch, v);
    }
}

/* Sets up primitives [p0, p1) of a draw into the chunk. */
static void rast__setup_range(rast__chunk *ch, int p0, int p1) {
    const rast__cmd *cmd = ch->cmd;
    int vpp = cmd->verts_per_prim, prim, layer, j;
    /* non-indexed draws run the vertex program here, once per vertex */
    rast_vertex_out scratch[3][RAST_MAX_VERTEX_OUTPUTS];
    int scratch_n[3], scratch_index[3];
    if (vpp == 1 && !cmd->pipe->s.vertex_fn && !cmd->d.indices) {
        rast__setup_points_direct(ch, p0, p1);
        return;
    }
    if (vpp == 3 && cmd->vout) {
        rast__setup_indexed_tris(ch, p0, p1);
        return;
    }
    for (prim = p0; prim < p1 && !ch->failed; ++prim) {
        const rast__vtx *v[3];
        for (j = 0; j < vpp; ++j) scratch_index[j] = -1;
        for (layer = 0; layer < cmd->max_out; ++layer) {
            int ok = 1;
            for (j = 0; j < vpp && ok; ++j)
                ok = (v[j] = rast__fetch(cmd, prim * vpp + j, layer, scratch[j], &scratch_n[j],
                                         &scratch_index[j])) != NULL;
            if (!ok) break;
            if (vpp == 3) rast__setup_tri(ch, v[0], v[1], v[2]);
            else if (vpp == 2) rast__setup_line(ch, v[0], v[1]);
            else rast__setup_point(ch, v[0]);
        }
    }
}
