/* Rasterisation of one record inside one tile: which pixels a triangle,
   point, line or rectangle covers, and the values it carries there.
   Coverage is decided in integer fixed point (RAST_SUBPIXEL_BITS) with the
   top-left rule; every interpolated value is evaluated from its plane at the
   absolute pixel centre, never stepped across tiles (determinism). */
#include "internal.h"

enum { RAST__ONE = 1 << RAST_SUBPIXEL_BITS, RAST__HALF = RAST__ONE / 2 };

/* What a tile worker needs of the draw a record came from. */
typedef struct rast__draw_info {
    const rast__pipe *pipe;
    int nvar;
    const float *color;       /* the draw colour (num_varyings < 4) */
} rast__draw_info;

/* The fragment stage common to every primitive: shading (callback or fixed),
   then the tests, then colour. `var` holds the varyings when known; for
   triangles the caller computes them lazily through `tri`. */
static void rast__fragment(const rast__draw_info *di, rast__tile *tl, int x, int y, float z,
                           float w, int front, const float *var, const float *ddx,
                           const float *ddy) {
    const rast__pipe *p = di->pipe;
    const rast__fb *fb = tl->fb;
    float rgba[4];
    int want_color = fb->color && p->color_write;
    z += p->s.depth_offset;
    z = RAST__CLAMP(z, 0.0f, 1.0f);
    if (p->s.fragment_fn) {
        rast_fragment_in in;
        in.x = x; in.y = y; in.z = z; in.w = w; in.front_facing = front;
        in.varyings = var;
        in.ddx = p->s.fragment_derivatives ? ddx : NULL;
        in.ddy = p->s.fragment_derivatives ? ddy : NULL;
        rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0.0f;
        if (!p->s.fragment_fn(p->s.fragment_user, &in, rgba)) return;
        if (p->fog) {
            int fv = p->s.fog_varying;
            rast__apply_fog(p, fv > 0 && fv <= di->nvar ? var[fv - 1] : w, rgba);
        }
        if (!rast__depth_stencil(p, fb, x, y, z, !front)) return;
    } else {
        if (!rast__depth_stencil(p, fb, x, y, z, !front)) return;
        if (!want_color) return;
        rast__shade_fixed(p, var, di->nvar, di->color, ddx, ddy, w, rgba);
    }
    if (want_color) rast__color_out(p, fb, x, y, rgba);
}

/* Writes a fragment colour on a simple pipe: straight in when there is
   no blending or masking, else through blending and the mask. */
static void rast__store_color(const rast__pipe *p, const rast__fb *fb, uint8_t *crow, int x, int y,
                              const float c[4]) {
    if (!p->plain_color) {
        rast__color_out(p, fb, x, y, c);
    } else if (fb->color_f32) {
        float *px = (float *)crow + 4 * x;
        px[0] = c[0]; px[1] = c[1]; px[2] = c[2]; px[3] = c[3];
    } else {
        uint32_t v = rast__pack_rgba8(c);
        memcpy(crow + 4 * x, &v, 4);
    }
}

/* Depth test and write for the simple path; nonzero when the pixel passes. */
static int rast__depth_simple(const rast__pipe *p, float *drow, int x, float z) {
    int pass;
    if (!drow) return 1;
    pass = p->depth_func == RAST_LESS ? z < drow[x] : rast__compare_f(p->depth_func, z, drow[x]);
    if (!pass) return 0;
    if (p->depth_write) drow[x] = z;
    return 1;
}

/* Where a span starts: the edge functions of edges 0 and 2 at its first
   pixel and their steps, which give the barycentrics of vertices 2 and 1. */
typedef struct rast__span {
    int y, xs, xe;
    int64_t e0, e2, s0, s2;
} rast__span;

/* Clamp to [0, 1] as max then min, NaN to 0: the same on the scalar and
   the SSE2 paths (which must agree to the bit). */
static float rast__clamp01(float v) {
    v = v > 0.0f ? v : 0.0f;
    return v < 1.0f ? v : 1.0f;
}

/* What every span of one triangle on a simple pipe shares: worked out
   once per triangle and tile, not once per span (small triangles have
   spans of a few pixels). */
typedef struct rast__simple_tri {
    int flat;                 /* one colour over the whole triangle */
#ifdef RAST__SSE2
    __m128 inv_area, z0, dz1, dz2, iw0, diw1, diw2, iw1, iw2;
    __m128 cv0[4], cd1[4], cd2[4]; /* the colour's channels, each broadcast */
    __m128 v0, d1, d2;        /* the colour's channels as one vector */
#endif
} rast__simple_tri;

static void rast__simple_tri_init(const rast__draw_info *di, const rast__tri *t, rast__simple_tri *st) {
    const float *vd = (const float *)(t + 1);
    int k;
    st->flat = 1;
    for (k = 0; k < 4 && di->nvar >= 4; ++k)
        if (vd[3 * k + 1] != 0.0f || vd[3 * k + 2] != 0.0f) st->flat = 0;
#ifdef RAST__SSE2
    st->inv_area = _mm_set1_ps(t->inv_area);
    st->z0 = _mm_set1_ps(t->z[0]);
    st->dz1 = _mm_set1_ps(t->z[1] - t->z[0]);
    st->dz2 = _mm_set1_ps(t->z[2] - t->z[0]);
    st->iw0 = _mm_set1_ps(t->iw[0]);
    st->diw1 = _mm_set1_ps(t->iw[1] - t->iw[0]);
    st->diw2 = _mm_set1_ps(t->iw[2] - t->iw[0]);
    st->iw1 = _mm_set1_ps(t->iw[1]);
    st->iw2 = _mm_set1_ps(t->iw[2]);
    if (di->nvar >= 4) {
        for (k = 0; k < 4; ++k) {
            st->cv0[k] = _mm_set1_ps(vd[3 * k]);
            st->cd1[k] = _mm_set1_ps(vd[3 * k + 1]);
            st->cd2[k] = _mm_set1_ps(vd[3 * k + 2]);
        }
        st->v0 = _mm_setr_ps(vd[0], vd[3], vd[6], vd[9]);
        st->d1 = _mm_setr_ps(vd[1], vd[4], vd[7], vd[10]);
        st->d2 = _mm_setr_ps(vd[2], vd[5], vd[8], vd[11]);
    }
#endif
}

#ifdef RAST__SSE2
/* Whole groups of four pixels of a simple span, RGBA8, interpolated colour,
   depth LESS or LEQUAL (or none); advances *x, *e0, *e2 past them. */
static void rast__tri_quad_simple(const rast__pipe *p, const rast__simple_tri *st, float *drow, uint8_t *crow,
                                  int *x, int xe, int64_t *e0, int64_t *e2, int64_t s0, int64_t s2) {
    const __m128 inv_area = st->inv_area, zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
    const __m128 z0 = st->z0, dz1 = st->dz1, dz2 = st->dz2;
    const __m128 iw0 = st->iw0, diw1 = st->diw1, diw2 = st->diw2, iw1 = st->iw1, iw2 = st->iw2;
    const __m128 k255 = _mm_set1_ps(255.0f), half = _mm_set1_ps(0.5f), top = _mm_set1_ps(255.5f);
    const __m128 *cv0 = st->cv0, *cd1 = st->cd1, *cd2 = st->cd2;
    int c, less = p->depth_func == RAST_LESS, write = p->depth_write;
    for (; *x + 4 <= xe; *x += 4, *e0 += 4 * s0, *e2 += 4 * s2) {
        __m128 l1 = _mm_mul_ps(_mm_setr_ps((float)*e2, (float)(*e2 + s2), (float)(*e2 + 2 * s2), (float)(*e2 + 3 * s2)), inv_area);
        __m128 l2 = _mm_mul_ps(_mm_setr_ps((float)*e0, (float)(*e0 + s0), (float)(*e0 + 2 * s0), (float)(*e0 + 3 * s0)), inv_area);
        __m128 z = _mm_add_ps(_mm_add_ps(z0, _mm_mul_ps(l1, dz1)), _mm_mul_ps(l2, dz2));
        __m128 pass, w, b1, b2;
        __m128i px, ch[4], old;
        z = _mm_min_ps(_mm_max_ps(z, zero), one);
        if (drow) {
            __m128 d = _mm_loadu_ps(drow + *x);
            pass = less ? _mm_cmplt_ps(z, d) : _mm_cmple_ps(z, d);
            if (_mm_movemask_ps(pass) == 0) continue;
            if (write) _mm_storeu_ps(drow + *x, _mm_or_ps(_mm_and_ps(pass, z), _mm_andnot_ps(pass, d)));
        } else {
            pass = _mm_castsi128_ps(_mm_set1_epi32(-1));
        }
        w = _mm_div_ps(one, _mm_add_ps(_mm_add_ps(iw0, _mm_mul_ps(l1, diw1)), _mm_mul_ps(l2, diw2)));
        b1 = _mm_mul_ps(_mm_mul_ps(l1, iw1), w);
        b2 = _mm_mul_ps(_mm_mul_ps(l2, iw2), w);
        for (c = 0; c < 4; ++c) { /* channel c of four pixels, as rast__pack_rgba8_v */
            __m128 v = _mm_add_ps(_mm_add_ps(cv0[c], _mm_mul_ps(b1, cd1[c])), _mm_mul_ps(b2, cd2[c]));
            v = _mm_add_ps(_mm_mul_ps(v, k255), half);
            ch[c] = _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(v, zero), top));
        }
        px = _mm_or_si128(_mm_or_si128(ch[0], _mm_slli_epi32(ch[1], 8)),
                          _mm_or_si128(_mm_slli_epi32(ch[2], 16), _mm_slli_epi32(ch[3], 24)));
        old = _mm_loadu_si128((const __m128i *)(crow + 4 * *x));
        px = _mm_or_si128(_mm_and_si128(_mm_castps_si128(pass), px), _mm_andnot_si128(_mm_castps_si128(pass), old));
        _mm_storeu_si128((__m128i *)(crow + 4 * *x), px);
    }
}
#endif

/* A span of a triangle on a simple pipe: depth test, then the interpolated
   colour (or the draw colour) straight into the target. */
static void rast__tri_span_simple(const rast__draw_info *di, rast__tile *tl, const rast__tri *t,
                                  const rast__simple_tri *st, const rast__span *sp) {
    const rast__pipe *p = di->pipe;
    const rast__fb *fb = tl->fb;
    const float *vd = (const float *)(t + 1);
    float *drow = p->depth_on ? (float *)((uint8_t *)fb->depth + (size_t)sp->y * (size_t)fb->depth_stride) : NULL;
    uint8_t *crow = fb->color ? fb->color + (size_t)sp->y * (size_t)fb->color_stride : NULL;
    float dz1 = t->z[1] - t->z[0], dz2 = t->z[2] - t->z[0];
    float diw1 = t->iw[1] - t->iw[0], diw2 = t->iw[2] - t->iw[0];
    int64_t e0 = sp->e0, e2 = sp->e2;
    int x, k;
    float k1[4], k2[4];
    const uint8_t (*lut)[256] = NULL;
    if (st->flat && crow && !fb->color_f32) {
        /* one colour over the whole triangle: pack or blend it once */
        const float *c = di->nvar < 4 ? di->color : (const float *)vd;
        float cc[4];
        uint32_t packed;
        int blend_k;
        for (k = 0; k < 4; ++k) cc[k] = di->nvar < 4 ? c[k] : c[3 * k];
        packed = rast__pack_rgba8(cc);
        blend_k = rast__const_blend(p, cc, k1, k2);
        if (blend_k && !drow) {
            rast__const_blend_run(crow + 4 * sp->xs, sp->xe - sp->xs, k1, k2);
            return;
        }
        /* a table costs 1024 conversions: worth it for long spans only */
        if (blend_k && sp->xe - sp->xs >= 64) lut = rast__const_blend_lut(tl, k1, k2);
        if (p->plain_color || blend_k) {
            for (x = sp->xs; x < sp->xe; ++x, e0 += sp->s0, e2 += sp->s2) {
                if (drow) {
                    float l1 = (float)e2 * t->inv_area, l2 = (float)e0 * t->inv_area;
                    float z = t->z[0] + l1 * dz1 + l2 * dz2;
                    z = RAST__CLAMP(z, 0.0f, 1.0f);
                    if (!rast__depth_simple(p, drow, x, z)) continue;
                }
                if (lut) {
                    uint8_t *px = crow + 4 * x;
                    px[0] = lut[0][px[0]]; px[1] = lut[1][px[1]]; px[2] = lut[2][px[2]]; px[3] = lut[3][px[3]];
                } else if (blend_k) {
                    for (k = 0; k < 4; ++k) crow[4 * x + k] = rast__to_unorm8(k1[k] + k2[k] * (float)crow[4 * x + k]);
                } else {
                    memcpy(crow + 4 * x, &packed, 4);
                }
            }
            return;
        }
    }
#ifdef RAST__SSE2
    if (crow && p->plain_color && !fb->color_f32 && di->nvar >= 4) {
        /* the colour as one vector: no per-channel stores to reload */
        const __m128 v0 = st->v0, d1 = st->d1, d2 = st->d2;
        if (!drow || p->depth_func == RAST_LESS || p->depth_func == RAST_LEQUAL) {
            /* four pixels at a time; every lane does exactly the scalar
               arithmetic, so which pixels share a group (it depends on the
               tile) never changes a bit */
            x = sp->xs;
            rast__tri_quad_simple(p, st, drow, crow, &x, sp->xe, &e0, &e2, sp->s0, sp->s2);
        } else {
            x = sp->xs;
        }
        for (; x < sp->xe; ++x, e0 += sp->s0, e2 += sp->s2) {
            float l1 = (float)e2 * t->inv_area, l2 = (float)e0 * t->inv_area, w, z;
            uint32_t packed;
            z = t->z[0] + l1 * dz1 + l2 * dz2;
            z = rast__clamp01(z);
            if (!rast__depth_simple(p, drow, x, z)) continue;
            w = 1.0f / (t->iw[0] + l1 * diw1 + l2 * diw2);
            /* (v0 + b1 d1) + b2 d2: the scalar paths' order, same bits */
            packed = rast__pack_rgba8_v(_mm_add_ps(_mm_add_ps(v0, _mm_mul_ps(_mm_set1_ps(l1 * t->iw[1] * w), d1)),
                                                   _mm_mul_ps(_mm_set1_ps(l2 * t->iw[2] * w), d2)));
            memcpy(crow + 4 * x, &packed, 4);
        }
        return;
    }
#endif
    for (x = sp->xs; x < sp->xe; ++x, e0 += sp->s0, e2 += sp->s2) {
        float l1 = (float)e2 * t->inv_area, l2 = (float)e0 * t->inv_area;
        float z = t->z[0] + l1 * dz1 + l2 * dz2, c[4];
        z = rast__clamp01(z);
        if (!rast__depth_simple(p, drow, x, z) || !crow) continue;
        if (di->nvar >= 4) {
            float w = 1.0f / (t->iw[0] + l1 * diw1 + l2 * diw2);
            float b1 = l1 * t->iw[1] * w, b2 = l2 * t->iw[2] * w;
            for (k = 0; k < 4; ++k) c[k] = vd[3 * k] + b1 * vd[3 * k + 1] + b2 * vd[3 * k + 2];
            rast__store_color(p, fb, crow, x, sp->y, c);
        } else {
            rast__store_color(p, fb, crow, x, sp->y, di->color);
        }
    }
}

/* A span of a triangle through the full fragment pipeline. */
static void rast__tri_span(const rast__draw_info *di, rast__tile *tl, const rast__tri *t,
                           const rast__span *sp) {
    const rast__pipe *p = di->pipe;
    const float *vd = (const float *)(t + 1); /* v0, v1 - v0, v2 - v0 per varying */
    int nvar = di->nvar, k, x;
    int derivs = (p->s.fragment_fn && p->s.fragment_derivatives) || p->fixed_texture;
    int need_var = p->s.fragment_fn || (tl->fb->color && p->color_write);
    float dz1 = t->z[1] - t->z[0], dz2 = t->z[2] - t->z[0];
    float diw1 = t->iw[1] - t->iw[0], diw2 = t->iw[2] - t->iw[0];
    /* screen derivatives of the linear barycentrics: one pixel steps the
       edge functions by s in x and by the edge's dx in y */
    float l1x = (float)sp->s2 * t->inv_area, l2x = (float)sp->s0 * t->inv_area;
    float l1y = (float)(t->fx[0] - t->fx[2]) * (float)(1 << RAST_SUBPIXEL_BITS) * t->inv_area;
    float l2y = (float)(t->fx[1] - t->fx[0]) * (float)(1 << RAST_SUBPIXEL_BITS) * t->inv_area;
    int64_t e0 = sp->e0, e2 = sp->e2;
    for (x = sp->xs; x < sp->xe; ++x, e0 += sp->s0, e2 += sp->s2) {
        float l1 = (float)e2 * t->inv_area, l2 = (float)e0 * t->inv_area;
        float z = t->z[0] + l1 * dz1 + l2 * dz2;
        float iw = t->iw[0] + l1 * diw1 + l2 * diw2, w = 1.0f / iw;
        if (need_var) {
            float b1 = l1 * t->iw[1] * w, b2 = l2 * t->iw[2] * w;
            for (k = 0; k < nvar; ++k) tl->var[k] = vd[3 * k] + b1 * vd[3 * k + 1] + b2 * vd[3 * k + 2];
            if (derivs) { /* derivatives of b = l * iw_vertex / iw, exact */
                float iwx = l1x * diw1 + l2x * diw2, iwy = l1y * diw1 + l2y * diw2;
                float b1x = (l1x * t->iw[1] - b1 * iwx) * w, b1y = (l1y * t->iw[1] - b1 * iwy) * w;
                float b2x = (l2x * t->iw[2] - b2 * iwx) * w, b2y = (l2y * t->iw[2] - b2 * iwy) * w;
                for (k = 0; k < nvar; ++k) {
                    tl->ddx[k] = b1x * vd[3 * k + 1] + b2x * vd[3 * k + 2];
                    tl->ddy[k] = b1y * vd[3 * k + 1] + b2y * vd[3 * k + 2];
                }
            }
        }
        rast__fragment(di, tl, x, sp->y, z, w, t->h.front, tl->var, derivs ? tl->ddx : NULL,
                       derivs ? tl->ddy : NULL);
    }
}

static void rast__raster_tri(const rast__draw_info *di, rast__tile *tl, const rast__tri *t) {
    int x0 = RAST__MAX(t->h.x0, tl->x0), x1 = RAST__MIN(t->h.x1, tl->x1);
    int y0 = RAST__MAX(t->h.y0, tl->y0), y1 = RAST__MIN(t->h.y1, tl->y1);
    int64_t ea[3], eb[3], ec[3];
    int i, have_st = 0;
    rast__span sp;
    rast__simple_tri st;
    if (x0 >= x1 || y0 >= y1) return;
    /* Edge i runs from vertex i to vertex i+1; E = ea*px + eb*py + ec is
       positive inside. Top-left edges keep E == 0, others need E > 0. */
    for (i = 0; i < 3; ++i) {
        int j = i == 2 ? 0 : i + 1;
        int64_t dx = (int64_t)t->fx[j] - t->fx[i], dy = (int64_t)t->fy[j] - t->fy[i];
        int top_left = dy < 0 || (dy == 0 && dx > 0);
        ea[i] = -dy;
        eb[i] = dx;
        ec[i] = dy * t->fx[i] - dx * t->fy[i] - (top_left ? 0 : 1);
    }
    sp.s0 = ea[0] * RAST__ONE;
    sp.s2 = ea[2] * RAST__ONE;
    for (sp.y = y0; sp.y < y1; ++sp.y) {
        int64_t py = (int64_t)sp.y * RAST__ONE + RAST__HALF;
        int64_t px = (int64_t)x0 * RAST__ONE + RAST__HALF;
        int64_t e0 = ea[0] * px + eb[0] * py + ec[0];
        int64_t e1 = ea[1] * px + eb[1] * py + ec[1];
        int64_t e2 = ea[2] * px + eb[2] * py + ec[2];
        int64_t s1 = ea[1] * RAST__ONE, last = (int64_t)(x1 - 1 - x0);
        int64_t lo = 0, hi = x1 - x0; /* the span, as offsets from x0 (hi exclusive) */
        /* The triangle is convex: its pixels on a row form one span. Both
           ends inside: the whole row (big triangles). Wide rows: the ends
           from each edge by division. Narrow rows: a short search. */
        if ((e0 | e1 | e2) >= 0 && ((e0 + last * sp.s0) | (e1 + last * s1) | (e2 + last * sp.s2)) >= 0) {
            /* lo = 0, hi = x1 - x0 */
        } else if (x1 - x0 > 16) {
            const int64_t e[3] = {e0, e1, e2}, st[3] = {sp.s0, s1, sp.s2};
            for (i = 0; i < 3 && lo < hi; ++i) {
                if (st[i] > 0) {
                    if (e[i] < 0) lo = RAST__MAX(lo, (-e[i] + st[i] - 1) / st[i]);
                } else if (st[i] < 0) {
                    hi = e[i] < 0 ? 0 : RAST__MIN(hi, e[i] / -st[i] + 1);
                } else if (e[i] < 0) {
                    hi = 0;
                }
            }
        } else {
            int64_t a = e0, b = e1, c = e2;
            while (lo < hi && (a | b | c) < 0) { a += sp.s0; b += s1; c += sp.s2; ++lo; }
            hi = lo;
            while (hi < x1 - x0 && (a | b | c) >= 0) { a += sp.s0; b += s1; c += sp.s2; ++hi; }
        }
        if (lo >= hi) continue;
        sp.xs = x0 + (int)lo;
        sp.xe = x0 + (int)hi;
        sp.e0 = e0 + lo * sp.s0;
        sp.e2 = e2 + lo * sp.s2;
        if (!di->pipe->simple) {
            rast__tri_span(di, tl, t, &sp);
            continue;
        }
        if (!have_st) rast__simple_tri_init(di, t, &st);
        have_st = 1;
        rast__tri_span_simple(di, tl, t, &st, &sp);
    }
}

static void rast__raster_point(const rast__draw_info *di, rast__tile *tl, const rast__point *pt) {
    const float *var = (const float *)(pt + 1);
    int x0 = RAST__MAX(pt->h.x0, tl->x0), x1 = RAST__MIN(pt->h.x1, tl->x1);
    int y0 = RAST__MAX(pt->h.y0, tl->y0), y1 = RAST__MIN(pt->h.y1, tl->y1);
    int x, y;
    const rast__pipe *p = di->pipe;
    const rast__fb *fb = tl->fb;
    if (p->simple) {
        float z = RAST__CLAMP(pt->z, 0.0f, 1.0f);
        const float *c = di->nvar >= 4 ? var : di->color;
        for (y = y0; y < y1; ++y) {
            float *drow = p->depth_on ? (float *)((uint8_t *)fb->depth + (size_t)y * (size_t)fb->depth_stride) : NULL;
            uint8_t *crow = fb->color ? fb->color + (size_t)y * (size_t)fb->color_stride : NULL;
            for (x = x0; x < x1; ++x)
                if (rast__depth_simple(p, drow, x, z) && crow) rast__store_color(p, fb, crow, x, y, c);
        }
        return;
    }
    for (y = y0; y < y1; ++y)
        for (x = x0; x < x1; ++x)
            rast__fragment(di, tl, x, y, pt->z, pt->w, 1, var, NULL, NULL);
}

/* A 1-pixel line: one pixel per step along the major axis, from the pixel
   holding the start to the one before the pixel holding the end (GL's
   diamond-exit rule, simplified: the last pixel is left to the next line of
   a strip). Values are interpolated perspective-correctly. */
static void rast__raster_line(const rast__draw_info *di, rast__tile *tl, const rast__line *ln) {
    const float *vd = (const float *)(ln + 1); /* v0, v1 - v0 */
    float dx = ln->x[1] - ln->x[0], dy = ln->y[1] - ln->y[0];
    int xmajor = fabsf(dx) >= fabsf(dy);
    float a0 = xmajor ? ln->x[0] : ln->y[0], a1 = xmajor ? ln->x[1] : ln->y[1];
    float len = a1 - a0;
    int s0 = (int)floorf(a0), s1 = (int)floorf(a1), step = s1 >= s0 ? 1 : -1, i, k;
    for (i = s0;; i += step) {
        float c = (float)i + 0.5f, u, o, z, iw, w, up;
        int x, y;
        if (i == s1 && s1 != s0) break;
        u = len != 0.0f ? (c - a0) / len : 0.0f;
        u = RAST__CLAMP(u, 0.0f, 1.0f);
        o = xmajor ? ln->y[0] + u * dy : ln->x[0] + u * dx;
        x = xmajor ? i : (int)floorf(o);
        y = xmajor ? (int)floorf(o) : i;
        if (x >= tl->x0 && x < tl->x1 && y >= tl->y0 && y < tl->y1 && x >= ln->h.x0 &&
            x < ln->h.x1 && y >= ln->h.y0 && y < ln->h.y1) {
            z = ln->z[0] + u * (ln->z[1] - ln->z[0]);
            iw = ln->iw[0] + u * (ln->iw[1] - ln->iw[0]);
            w = 1.0f / iw;
            up = u * ln->iw[1] * w; /* the perspective-correct parameter */
            for (k = 0; k < di->nvar; ++k) tl->var[k] = vd[2 * k] + up * vd[2 * k + 1];
            rast__fragment(di, tl, x, y, z, w, 1, tl->var, NULL, NULL);
        }
        if (i == s1) break;
    }
}

/* Applies a pure stencil pass's table to one row of n values. */
static void rast__stencil_table_run(uint8_t *s, int n, const uint8_t next[256], int op) {
    int x = 0;
    if (op == RAST__SOP_KEEP) return;
    if (op == RAST__SOP_SET) {
        memset(s, next[0], (size_t)n);
        return;
    }
#ifdef RAST__SSE2
    if (op != RAST__SOP_TABLE) {
        const __m128i one = _mm_set1_epi8(1), ones = _mm_set1_epi8(-1);
        for (; x + 16 <= n; x += 16) {
            __m128i v = _mm_loadu_si128((const __m128i *)(const void *)(s + x));
            v = op == RAST__SOP_ADD_SAT ? _mm_adds_epu8(v, one) : op == RAST__SOP_SUB_SAT ? _mm_subs_epu8(v, one)
              : op == RAST__SOP_ADD_WRAP ? _mm_add_epi8(v, one) : op == RAST__SOP_SUB_WRAP ? _mm_sub_epi8(v, one)
              : _mm_xor_si128(v, ones);
            _mm_storeu_si128((__m128i *)(void *)(s + x), v);
        }
    }
#endif
    for (; x < n; ++x) s[x] = next[s[x]];
}

/* A constant rectangle through the tests and colour stages (no callbacks):
   the stencil passes of the papers, so the loop is kept tight. */
static void rast__raster_rect(const rast__draw_info *di, rast__tile *tl, const rast__rect *r) {
    const rast__pipe *p = di->pipe;
    const rast__fb *fb = tl->fb;
    int x0 = RAST__MAX(r->h.x0, tl->x0), x1 = RAST__MIN(r->h.x1, tl->x1);
    int y0 = RAST__MAX(r->h.y0, tl->y0), y1 = RAST__MIN(r->h.y1, tl->y1);
    int x, y, want_color = fb->color && p->color_write;
    float z = RAST__CLAMP(r->z + p->s.depth_offset, 0.0f, 1.0f), rgba[4];
    const uint8_t *test = p->st_test[0], *fail = p->st_next[0][RAST__ST_FAIL];
    const uint8_t *zfail = p->st_next[0][RAST__ST_ZFAIL], *pass = p->st_next[0][RAST__ST_PASS];
    float k1[4], k2[4];
    const uint8_t (*lut)[256] = NULL;
    int blend_k;
    memcpy(rgba, r->rgba, sizeof(rgba));
    if (p->fog) rast__apply_fog(p, 1.0f, rgba);
    blend_k = want_color && !fb->color_f32 && rast__const_blend(p, rgba, k1, k2);
    if (blend_k && !p->stencil_on && !p->depth_on) {
        for (y = y0; y < y1; ++y)
            rast__const_blend_run(fb->color + (size_t)y * (size_t)fb->color_stride + 4 * (size_t)x0, x1 - x0, k1, k2);
        return;
    }
    if (blend_k) lut = rast__const_blend_lut(tl, k1, k2);
    if (p->stencil_on && !p->depth_on && !want_color) { /* a pure stencil pass */
        for (y = y0; y < y1; ++y)
            rast__stencil_table_run(fb->stencil + (size_t)y * (size_t)fb->stencil_stride + x0, x1 - x0,
                                    p->st_pure[0], p->st_pure_op[0]);
        return;
    }
    for (y = y0; y < y1; ++y) {
        uint8_t *srow = p->stencil_on ? fb->stencil + (size_t)y * (size_t)fb->stencil_stride : NULL;
        float *drow = p->depth_on ? (float *)((uint8_t *)fb->depth + (size_t)y * (size_t)fb->depth_stride) : NULL;
        uint8_t *crow = want_color ? fb->color + (size_t)y * (size_t)fb->color_stride : NULL;
        for (x = x0; x < x1; ++x) {
            int zpass = drow ? rast__compare_f(p->depth_func, z, drow[x]) : 1;
            if (srow) {
                unsigned s = srow[x];
                if (!test[s]) {
                    srow[x] = fail[s];
                    continue;
                }
                srow[x] = zpass ? pass[s] : zfail[s];
            }
            if (!zpass) continue;
            if (drow && p->depth_write) drow[x] = z;
            if (lut) {
                uint8_t *px = crow + 4 * x;
                px[0] = lut[0][px[0]]; px[1] = lut[1][px[1]]; px[2] = lut[2][px[2]]; px[3] = lut[3][px[3]];
            } else if (crow) {
                rast__store_color(p, fb, crow, x, y, rgba);
            }
        }
    }
}

/* What splat loops need of the pipe and targets, in locals: a colour store
   may alias anything, so fields read through pointers would be reloaded
   for every pixel. */
typedef struct rast__splat_target {
    uint8_t *color, *depth;
    size_t color_stride, depth_stride;
    int depth_on, depth_func, depth_write;
} rast__splat_target;

static rast__splat_target rast__splat_target_of(const rast__pipe *p, const rast__fb *fb) {
    rast__splat_target t;
    t.color = fb->color;
    t.depth = (uint8_t *)fb->depth;
    t.color_stride = (size_t)fb->color_stride;
    t.depth_stride = (size_t)fb->depth_stride;
    t.depth_on = p->depth_on;
    t.depth_func = p->depth_func;
    t.depth_write = p->depth_write;
    return t;
}

/* A run of n splatted pixels of one row: depth test and write, then the
   packed colour. Branchless per pixel (random depths would mispredict
   half the time); the usual depth functions inline. */
RAST__FORCE_INLINE void rast__splat_run(const rast__splat_target *t, int x, int y, int n, float z, uint32_t rgba) {
    uint8_t *cp = t->color + (size_t)y * t->color_stride + 4 * (size_t)x;
    int i;
    if (!t->depth_on) {
        for (i = 0; i < n; ++i) memcpy(cp + 4 * i, &rgba, 4);
        return;
    }
    {
        float *dp = (float *)(t->depth + (size_t)y * t->depth_stride) + x;
        const int func = t->depth_func, write = t->depth_write;
        i = 0;
#ifdef RAST__SSE2
        /* two pixels at a time for the usual functions: the same compares
           (false for NaN, as above), selected by mask */
        if (func == RAST_LESS || func == RAST_LEQUAL) {
            const __m128 zz = _mm_set1_ps(z);
            const __m128i col = _mm_set1_epi32((int)rgba);
            for (; i + 2 <= n; i += 2) {
                /* 8-byte moves that allow any alignment (depth rows need only 4) */
                __m128 old = _mm_castsi128_ps(_mm_loadl_epi64((const __m128i *)(const void *)(dp + i)));
                __m128 pass = func == RAST_LESS ? _mm_cmplt_ps(zz, old) : _mm_cmple_ps(zz, old);
                __m128i pm = _mm_castps_si128(pass);
                __m128i now = _mm_loadl_epi64((const __m128i *)(const void *)(cp + 4 * i));
                if (write)
                    _mm_storel_epi64((__m128i *)(void *)(dp + i),
                                     _mm_castps_si128(_mm_or_ps(_mm_and_ps(pass, zz), _mm_andnot_ps(pass, old))));
                now = _mm_or_si128(_mm_and_si128(pm, col), _mm_andnot_si128(pm, now));
                _mm_storel_epi64((__m128i *)(void *)(cp + 4 * i), now);
            }
        }
#endif
        for (; i < n; ++i) {
            float old = dp[i];
            uint32_t now;
            int pass = func == RAST_LESS ? z < old : func == RAST_LEQUAL ? z <= old : rast__compare_f(func, z, old);
            dp[i] = pass && write ? z : old;
            memcpy(&now, cp + 4 * i, 4);
            now = pass ? rgba : now;
            memcpy(cp + 4 * i, &now, 4);
        }
    }
}

/* Splats of a tile: their squares clipped by the tile and the pipe. */
static void rast__raster_splats(const rast__draw_info *di, rast__tile *tl, const rast__splat *b,
                                const rast__splat *e) {
    const rast__pipe *p = di->pipe;
    const rast__splat_target t = rast__splat_target_of(p, tl->fb);
    const int cx0 = RAST__MAX(tl->x0, p->clip[0]), cy0 = RAST__MAX(tl->y0, p->clip[1]);
    const int cx1 = RAST__MIN(tl->x1, p->clip[2]), cy1 = RAST__MIN(tl->y1, p->clip[3]), size = p->point_size;
    if (size == 1) { /* binning put each in this tile, within the clip */
        for (; b < e; ++b) rast__splat_run(&t, b->x, b->y, 1, b->z, b->rgba);
        return;
    }
    for (; b < e; ++b) {
        int x0 = RAST__MAX(b->x, cx0), x1 = RAST__MIN(b->x + size, cx1);
        int y0 = RAST__MAX(b->y, cy0), y1 = RAST__MIN(b->y + size, cy1), y;
        for (y = y0; y < y1; ++y) rast__splat_run(&t, x0, y, x1 - x0, b->z, b->rgba);
    }
}

static void rast__raster_record(const rast__draw_info *di, rast__tile *tl, const rast__rec *h) {
    int x0 = RAST__MAX(h->x0, tl->x0), x1 = RAST__MIN(h->x1, tl->x1);
    int y0 = RAST__MAX(h->y0, tl->y0), y1 = RAST__MIN(h->y1, tl->y1);
    switch (h->kind) {
    case RAST__REC_TRI: rast__raster_tri(di, tl, (const rast__tri *)h); break;
    case RAST__REC_POINT: rast__raster_point(di, tl, (const rast__point *)h); break;
    case RAST__REC_LINE: rast__raster_line(di, tl, (const rast__line *)h); break;
    case RAST__REC_RECT: rast__raster_rect(di, tl, (const rast__rect *)h); break;
    case RAST__REC_CLEAR:
        if (x0 < x1 && y0 < y1)
            rast__run_clear(di->pipe, tl->fb, (const rast__clear_rec *)h, x0, y0, x1, y1);
        break;
    case RAST__REC_ACCUM:
        if (x0 < x1 && y0 < y1)
            rast__run_accum(di->pipe, tl->fb, (const rast__accum_rec *)h, x0, y0, x1, y1);
        break;
    default: break;
    }
}
