/* Per-fragment operations in GL order: (shading, fog), stencil, depth,
   blending, colour mask; plus the whole-target operations that run per tile:
   clears, accumulation ops. Scissor and viewport are applied by the
   rasteriser, which only visits pixels inside pipe->clip. */
#include "internal.h"

/* Stencil and depth tests with their side effects on one pixel.
   face: 0 front, 1 back. Returns nonzero when the fragment survives. The
   stencil test and ops are table lookups prepared with the pipe. */
static int rast__depth_stencil(const rast__pipe *p, const rast__fb *fb, int x, int y,
                               float z, int face) {
    uint8_t *sp = NULL;
    float *dp = NULL;
    unsigned s = 0;
    int zpass = 1;
    if (p->stencil_on) {
        sp = fb->stencil + (size_t)y * (size_t)fb->stencil_stride + (size_t)x;
        s = *sp;
        if (!p->st_test[face][s]) {
            *sp = p->st_next[face][RAST__ST_FAIL][s];
            return 0;
        }
    }
    if (p->depth_on) {
        dp = (float *)((uint8_t *)fb->depth + (size_t)y * (size_t)fb->depth_stride) + x;
        zpass = rast__compare_f(p->depth_func, z, *dp);
    }
    if (sp) *sp = p->st_next[face][zpass ? RAST__ST_PASS : RAST__ST_ZFAIL][s];
    if (!zpass) return 0;
    if (dp && p->depth_write) *dp = z;
    return 1;
}

/* Blending and the colour mask; writes one pixel of the colour target. */
static void rast__color_out(const rast__pipe *p, const rast__fb *fb, int x, int y,
                            const float frag[4]) {
    float src[4], dst[4], out[4];
    int c;
    uint8_t *row = fb->color + (size_t)y * (size_t)fb->color_stride;
    if (fb->color_f32) {
        float *px = (float *)row + 4 * x;
        for (c = 0; c < 4; ++c) { src[c] = frag[c]; dst[c] = px[c]; }
    } else {
        uint8_t *px = row + 4 * x;
        /* fixed-point buffers clamp the incoming colour (GL 4.6 §17.3.6);
           NaN fails both comparisons and becomes 0 */
        for (c = 0; c < 4; ++c) {
            float v = frag[c] > 0.0f ? frag[c] : 0.0f;
            src[c] = v < 1.0f ? v : 1.0f;
            dst[c] = px[c] * (1.0f / 255.0f);
        }
    }
    if (p->blend) {
        const rast__blend *b = &p->bl;
        for (c = 0; c < 4; ++c) {
            float sf = b->s_base[c] + b->s_sc[c] * src[c] + b->s_sa[c] * src[3] + b->s_dc[c] * dst[c] +
                       b->s_da[c] * dst[3];
            float df = b->d_base[c] + b->d_sc[c] * src[c] + b->d_sa[c] * src[3] + b->d_dc[c] * dst[c] +
                       b->d_da[c] * dst[3];
            out[c] = b->term_s[c] * src[c] * sf + b->term_d[c] * dst[c] * df;
        }
        if (b->general)
            for (c = 0; c < 4; ++c) {
                float sat = c == 3 ? 1.0f : RAST__MIN(src[3], 1.0f - dst[3]);
                float sf = b->saturate_s[c] ? sat : b->s_base[c] + b->s_sc[c] * src[c] + b->s_sa[c] * src[3] +
                                                    b->s_dc[c] * dst[c] + b->s_da[c] * dst[3];
                float df = b->saturate_d[c] ? sat : b->d_base[c] + b->d_sc[c] * src[c] + b->d_sa[c] * src[3] +
                                                    b->d_dc[c] * dst[c] + b->d_da[c] * dst[3];
                out[c] = b->minmax[c] == 1   ? RAST__MIN(src[c], dst[c])
                         : b->minmax[c] == 2 ? RAST__MAX(src[c], dst[c])
                                             : b->term_s[c] * src[c] * sf + b->term_d[c] * dst[c] * df;
            }
    } else {
        for (c = 0; c < 4; ++c) out[c] = src[c];
    }
    if (fb->color_f32) {
        float *px = (float *)row + 4 * x;
        for (c = 0; c < 4; ++c)
            if (p->color_write & (1u << c)) px[c] = out[c];
    } else if (p->color_write == RAST_WRITE_RGBA) {
        uint8_t *px = row + 4 * x;
        for (c = 0; c < 4; ++c) px[c] = rast__to_unorm8(out[c]);
    } else {
        uint8_t *px = row + 4 * x;
        for (c = 0; c < 4; ++c)
            if (p->color_write & (1u << c)) px[c] = rast__to_unorm8(out[c]);
    }
}

/* Blending a constant colour into RGBA8 when no factor reads the
   destination (alpha blending, additive, constant factors ...) is, per
   channel, out = k1 + k2 * dst. Fills k1, k2 and returns 1 when that holds
   and every channel is written; spans and rectangles then skip the general
   per-pixel blend. */
static int rast__const_blend(const rast__pipe *p, const float frag[4], float k1[4], float k2[4]) {
    const rast__blend *b = &p->bl;
    float src[4];
    int c;
    if (!p->blend || b->general || p->color_write != RAST_WRITE_RGBA) return 0;
    for (c = 0; c < 4; ++c) {
        float v = frag[c] > 0.0f ? frag[c] : 0.0f;
        src[c] = v < 1.0f ? v : 1.0f;
        if (b->s_dc[c] != 0.0f || b->s_da[c] != 0.0f || b->d_dc[c] != 0.0f || b->d_da[c] != 0.0f) return 0;
    }
    for (c = 0; c < 4; ++c) {
        float sf = b->s_base[c] + b->s_sc[c] * src[c] + b->s_sa[c] * src[3];
        float df = b->d_base[c] + b->d_sc[c] * src[c] + b->d_sa[c] * src[3];
        k1[c] = b->term_s[c] * src[c] * sf;
        k2[c] = b->term_d[c] * df * (1.0f / 255.0f);
    }
    return 1;
}

/* out = k1 + k2 * dst over n consecutive RGBA8 pixels: four at a time with
   SSE2, each lane the scalar arithmetic of rast__to_unorm8 (same bits as
   the table and the scalar path, whichever pixels share a group). */
static void rast__const_blend_run(uint8_t *px, int n, const float k1[4], const float k2[4]) {
    int i = 0, c;
#ifdef RAST__SSE2
    const __m128 a = _mm_loadu_ps(k1), b = _mm_loadu_ps(k2), zero = _mm_setzero_ps();
    const __m128 k255 = _mm_set1_ps(255.0f), half = _mm_set1_ps(0.5f), top = _mm_set1_ps(255.5f);
    const __m128i z8 = _mm_setzero_si128();
    for (; i + 4 <= n; i += 4) {
        __m128i d = _mm_loadu_si128((const __m128i *)(px + 4 * i));
        __m128i lo = _mm_unpacklo_epi8(d, z8), hi = _mm_unpackhi_epi8(d, z8);
        __m128i q[4], r;
        q[0] = _mm_unpacklo_epi16(lo, z8); q[1] = _mm_unpackhi_epi16(lo, z8); /* pixels 0, 1 */
        q[2] = _mm_unpacklo_epi16(hi, z8); q[3] = _mm_unpackhi_epi16(hi, z8); /* pixels 2, 3 */
        for (c = 0; c < 4; ++c) { /* one pixel's R, G, B, A per vector */
            __m128 v = _mm_add_ps(a, _mm_mul_ps(b, _mm_cvtepi32_ps(q[c])));
            v = _mm_add_ps(_mm_mul_ps(v, k255), half);
            q[c] = _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(v, zero), top));
        }
        r = _mm_packus_epi16(_mm_packs_epi32(q[0], q[1]), _mm_packs_epi32(q[2], q[3]));
        _mm_storeu_si128((__m128i *)(px + 4 * i), r);
    }
#endif
    for (; i < n; ++i)
        for (c = 0; c < 4; ++c) px[4 * i + c] = rast__to_unorm8(k1[c] + k2[c] * (float)px[4 * i + c]);
}

/* The table of out = k1 + k2 * dst for every destination byte, rebuilt
   only when k1, k2 change: whole-screen blends then cost four lookups. */
static const uint8_t (*rast__const_blend_lut(rast__tile *tl, const float k1[4], const float k2[4]))[256] {
    int c, v;
    if (!tl->lut_valid || memcmp(tl->lut_key, k1, 4 * sizeof(float)) ||
        memcmp(tl->lut_key + 4, k2, 4 * sizeof(float))) {
        for (c = 0; c < 4; ++c)
            for (v = 0; v < 256; ++v) tl->lut[c][v] = rast__to_unorm8(k1[c] + k2[c] * (float)v);
        memcpy(tl->lut_key, k1, 4 * sizeof(float));
        memcpy(tl->lut_key + 4, k2, 4 * sizeof(float));
        tl->lut_valid = 1;
    }
    return (const uint8_t (*)[256])tl->lut;
}

/* GL fixed-function fog on the fragment colour (alpha unchanged). */
static void rast__apply_fog(const rast__pipe *p, float coord, float rgba[4]) {
    const rast_state *s = &p->s;
    float f, c = fabsf(coord);
    int i;
    switch (s->fog) {
    case RAST_FOG_LINEAR:
        f = s->fog_end != s->fog_start ? (s->fog_end - c) / (s->fog_end - s->fog_start) : 1.0f;
        break;
    case RAST_FOG_EXP: f = expf(-s->fog_density * c); break;
    case RAST_FOG_EXP2: f = expf(-(s->fog_density * c) * (s->fog_density * c)); break;
    default: return;
    }
    f = RAST__CLAMP(f, 0.0f, 1.0f);
    if (f != f) f = 0.0f;
    for (i = 0; i < 3; ++i) rgba[i] = f * rgba[i] + (1.0f - f) * s->fog_color[i];
}

/* Fixed-function colour: varyings 0..3 (or the draw colour), the texture
   (modulate or replace) and fog. */
static void rast__shade_fixed(const rast__pipe *p, const float *var, int nvar,
                              const float *draw_color, const float *ddx, const float *ddy,
                              float w, float rgba[4]) {
    int i;
    const float *c = nvar >= 4 ? var : draw_color;
    for (i = 0; i < 4; ++i) rgba[i] = c[i];
    if (p->fixed_texture) {
        float t[4];
        int k = p->s.texcoord_varying;
        if (k >= 0 && k + 1 < nvar) {
            if (ddx && ddy)
                rast__texture_sample_2d_grad(p->s.texture, var[k], var[k + 1], ddx[k], ddx[k + 1],
                                             ddy[k], ddy[k + 1], t);
            else
                rast_texture_sample_2d(p->s.texture, var[k], var[k + 1], 0.0f, t);
            if (p->s.tex_env == RAST_REPLACE_COLOR)
                for (i = 0; i < 4; ++i) rgba[i] = t[i];
            else
                for (i = 0; i < 4; ++i) rgba[i] *= t[i];
        }
    }
    if (p->fog) {
        int fv = p->s.fog_varying;
        rast__apply_fog(p, fv > 0 && fv <= nvar ? var[fv - 1] : w, rgba);
    }
}

/* ---- whole-target operations, one tile at a time ---- */

/* Clears: the first row of the rectangle is filled value by value, every
   other row is a memcpy of it (a fill loop per row is most of a frame's
   clear time otherwise). Masked channels go the slow way. */
static void rast__fill_rows(uint8_t *base, size_t stride, int y0, int y1, size_t offset, size_t bytes) {
    int y;
    for (y = y0 + 1; y < y1; ++y)
        memcpy(base + (size_t)y * stride + offset, base + (size_t)y0 * stride + offset, bytes);
}

static void rast__run_clear(const rast__pipe *p, const rast__fb *fb, const rast__clear_rec *r,
                            int x0, int y0, int x1, int y1) {
    int x, y, c;
    const rast_clear_desc *d = &r->c;
    unsigned smask = p->st_wmask[0];
    size_t n = (size_t)(x1 - x0);
    if ((d->flags & RAST_CLEAR_COLOR) && fb->color && p->color_write) {
        if (p->color_write == RAST_WRITE_RGBA) {
            uint8_t *row = fb->color + (size_t)y0 * (size_t)fb->color_stride;
            if (fb->color_f32) {
                for (x = x0; x < x1; ++x) memcpy(row + 16 * (size_t)x, d->color, 16);
                rast__fill_rows(fb->color, (size_t)fb->color_stride, y0, y1, 16 * (size_t)x0, 16 * n);
            } else {
                uint32_t v32 = rast__pack_rgba8(d->color);
                for (x = x0; x < x1; ++x) memcpy(row + 4 * (size_t)x, &v32, 4);
                rast__fill_rows(fb->color, (size_t)fb->color_stride, y0, y1, 4 * (size_t)x0, 4 * n);
            }
        } else {
            uint8_t v8[4];
            for (c = 0; c < 4; ++c) v8[c] = rast__to_unorm8(d->color[c]);
            for (y = y0; y < y1; ++y) {
                uint8_t *row = fb->color + (size_t)y * (size_t)fb->color_stride;
                for (x = x0; x < x1; ++x)
                    for (c = 0; c < 4; ++c) {
                        if (!(p->color_write & (1u << c))) continue;
                        if (fb->color_f32) ((float *)row)[4 * x + c] = d->color[c];
                        else row[4 * x + c] = v8[c];
                    }
            }
        }
    }
    if ((d->flags & RAST_CLEAR_DEPTH) && fb->depth && !p->s.depth_write_disabled) {
        float *row = (float *)((uint8_t *)fb->depth + (size_t)y0 * (size_t)fb->depth_stride);
        float z = RAST__CLAMP(d->depth, 0.0f, 1.0f);
        for (x = x0; x < x1; ++x) row[x] = z;
        rast__fill_rows((uint8_t *)fb->depth, (size_t)fb->depth_stride, y0, y1, 4 * (size_t)x0, 4 * n);
    }
    if ((d->flags & RAST_CLEAR_STENCIL) && fb->stencil) {
        for (y = y0; y < y1; ++y) {
            uint8_t *row = fb->stencil + (size_t)y * (size_t)fb->stencil_stride;
            if (smask == 0xFFu) memset(row + x0, d->stencil, n);
            else
                for (x = x0; x < x1; ++x) row[x] = (uint8_t)((row[x] & ~smask) | (d->stencil & smask));
        }
    }
    if ((d->flags & RAST_CLEAR_ACCUM) && fb->accum) {
        float *row = (float *)((uint8_t *)fb->accum + (size_t)y0 * (size_t)fb->accum_stride);
        for (x = x0; x < x1; ++x) memcpy(row + 4 * x, d->accum, 16);
        rast__fill_rows((uint8_t *)fb->accum, (size_t)fb->accum_stride, y0, y1, 16 * (size_t)x0, 16 * n);
    }
}

static void rast__run_accum(const rast__pipe *p, const rast__fb *fb, const rast__accum_rec *r,
                            int x0, int y0, int x1, int y1) {
    int x, y, c;
    float v = r->value;
    if (!fb->accum) return;
    for (y = y0; y < y1; ++y) {
        float *acc = (float *)((uint8_t *)fb->accum + (size_t)y * (size_t)fb->accum_stride);
        uint8_t *row = fb->color ? fb->color + (size_t)y * (size_t)fb->color_stride : NULL;
        for (x = x0; x < x1; ++x) {
            float *a = acc + 4 * x;
            float col[4] = {0, 0, 0, 0};
            if (row) {
                if (fb->color_f32)
                    for (c = 0; c < 4; ++c) col[c] = ((float *)row)[4 * x + c];
                else
                    for (c = 0; c < 4; ++c) col[c] = row[4 * x + c] * (1.0f / 255.0f);
            }
            switch (r->op) {
            case RAST_ACCUM: for (c = 0; c < 4; ++c) a[c] += v * col[c]; break;
            case RAST_LOAD: for (c = 0; c < 4; ++c) a[c] = v * col[c]; break;
            case RAST_MULT: for (c = 0; c < 4; ++c) a[c] *= v; break;
            case RAST_ADD: for (c = 0; c < 4; ++c) a[c] += v; break;
            case RAST_RETURN:
                if (!row) break;
                for (c = 0; c < 4; ++c) {
                    if (!(p->color_write & (1u << c))) continue;
                    if (fb->color_f32) ((float *)row)[4 * x + c] = v * a[c];
                    else row[4 * x + c] = rast__to_unorm8(v * a[c]);
                }
                break;
            default: break;
            }
        }
    }
}
