/* Per-fragment operations in GL order: (shading, fog), stencil, depth,
   blending, colour mask; plus the whole-target operations that run per tile:
   clears, accumulation ops. Scissor and viewport are applied by the
   rasteriser, which only visits pixels inside pipe->clip. */
#include "internal.h"

static int rast__compare_u8(int func, unsigned a, unsigned b) {
    switch (func) {
    case RAST_NEVER: return 0;
    case RAST_LESS: return a < b;
    case RAST_EQUAL: return a == b;
    case RAST_LEQUAL: return a <= b;
    case RAST_GREATER: return a > b;
    case RAST_NOTEQUAL: return a != b;
    case RAST_GEQUAL: return a >= b;
    default: return 1; /* ALWAYS */
    }
}

static int rast__compare_f(int func, float a, float b) {
    switch (func) {
    case RAST_NEVER: return 0;
    case RAST_LESS: return a < b;
    case RAST_EQUAL: return a == b;
    case RAST_LEQUAL: return a <= b;
    case RAST_GREATER: return a > b;
    case RAST_NOTEQUAL: return a != b;
    case RAST_GEQUAL: return a >= b;
    default: return 1;
    }
}

static unsigned rast__stencil_op(int op, unsigned s, unsigned ref) {
    switch (op) {
    case RAST_ZERO: return 0;
    case RAST_REPLACE: return ref;
    case RAST_INCR: return s < 255 ? s + 1 : 255;
    case RAST_DECR: return s > 0 ? s - 1 : 0;
    case RAST_INVERT: return ~s & 0xFFu;
    case RAST_INCR_WRAP: return (s + 1) & 0xFFu;
    case RAST_DECR_WRAP: return (s - 1) & 0xFFu;
    default: return s; /* KEEP */
    }
}

/* Stencil and depth tests with their side effects on one pixel.
   face: 0 front, 1 back. Returns nonzero when the fragment survives. */
static int rast__depth_stencil(const rast__pipe *p, const rast__fb *fb, int x, int y,
                               float z, int face) {
    uint8_t *sp = NULL;
    float *dp = NULL;
    unsigned s = 0;
    int zpass = 1;
    if (p->stencil_on) {
        sp = fb->stencil + (size_t)y * (size_t)fb->stencil_stride + (size_t)x;
        s = *sp;
        if (!rast__compare_u8(p->st_func[face], p->st_ref[face] & p->st_rmask[face],
                              s & p->st_rmask[face])) {
            unsigned n = rast__stencil_op(p->st_fail[face], s, p->st_ref[face]);
            *sp = (uint8_t)((s & ~(unsigned)p->st_wmask[face]) | (n & p->st_wmask[face]));
            return 0;
        }
    }
    if (p->depth_on) {
        dp = (float *)((uint8_t *)fb->depth + (size_t)y * (size_t)fb->depth_stride) + x;
        zpass = rast__compare_f(p->depth_func, z, *dp);
    }
    if (sp) {
        unsigned n = rast__stencil_op(zpass ? p->st_pass[face] : p->st_zfail[face], s,
                                      p->st_ref[face]);
        *sp = (uint8_t)((s & ~(unsigned)p->st_wmask[face]) | (n & p->st_wmask[face]));
    }
    if (!zpass) return 0;
    if (dp && p->depth_write) *dp = z;
    return 1;
}

static float rast__blend_factor(int f, int alpha_channel, const float src[4],
                                const float dst[4], const float k[4], int c) {
    switch (f) {
    case RAST_ZERO_FACTOR: return 0.0f;
    case RAST_ONE: return 1.0f;
    case RAST_SRC_COLOR: return src[c];
    case RAST_ONE_MINUS_SRC_COLOR: return 1.0f - src[c];
    case RAST_DST_COLOR: return dst[c];
    case RAST_ONE_MINUS_DST_COLOR: return 1.0f - dst[c];
    case RAST_SRC_ALPHA: return src[3];
    case RAST_ONE_MINUS_SRC_ALPHA: return 1.0f - src[3];
    case RAST_DST_ALPHA: return dst[3];
    case RAST_ONE_MINUS_DST_ALPHA: return 1.0f - dst[3];
    case RAST_CONSTANT_COLOR: return k[c];
    case RAST_ONE_MINUS_CONSTANT_COLOR: return 1.0f - k[c];
    case RAST_CONSTANT_ALPHA: return k[3];
    case RAST_ONE_MINUS_CONSTANT_ALPHA: return 1.0f - k[3];
    case RAST_SRC_ALPHA_SATURATE: {
        float m = RAST__MIN(src[3], 1.0f - dst[3]);
        return alpha_channel ? 1.0f : m;
    }
    default: return 1.0f;
    }
}

static float rast__blend_equation(int eq, float s, float sf, float d, float df) {
    switch (eq) {
    case RAST_FUNC_SUBTRACT: return s * sf - d * df;
    case RAST_FUNC_REVERSE_SUBTRACT: return d * df - s * sf;
    case RAST_FUNC_MIN: return RAST__MIN(s, d);
    case RAST_FUNC_MAX: return RAST__MAX(s, d);
    default: return s * sf + d * df;
    }
}

/* Clamp and round to 8 bits; written so compilers emit min/max, not
   branches. NaN fails both comparisons and lands on 0. */
static uint8_t rast__to_unorm8(float v) {
    v = v > 0.0f ? v : 0.0f;
    v = v < 1.0f ? v : 1.0f;
    return (uint8_t)(int)(v * 255.0f + 0.5f);
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
        /* fixed-point buffers clamp the incoming colour (GL 4.6 §17.3.6) */
        for (c = 0; c < 4; ++c) {
            src[c] = RAST__CLAMP(frag[c], 0.0f, 1.0f);
            if (src[c] != src[c]) src[c] = 0.0f;
            dst[c] = px[c] * (1.0f / 255.0f);
        }
    }
    if (p->blend) {
        const rast_state *s = &p->s;
        int srgb = s->blend_src_rgb ? (int)s->blend_src_rgb : RAST_ONE;
        int drgb = s->blend_dst_rgb ? (int)s->blend_dst_rgb : RAST_ZERO_FACTOR;
        int sa = s->blend_src_alpha ? (int)s->blend_src_alpha : RAST_ONE;
        int da = s->blend_dst_alpha ? (int)s->blend_dst_alpha : RAST_ZERO_FACTOR;
        for (c = 0; c < 4; ++c) {
            int a = c == 3;
            int eq = a ? (int)s->blend_eq_alpha : (int)s->blend_eq_rgb;
            float sf = rast__blend_factor(a ? sa : srgb, a, src, dst, s->blend_color, c);
            float df = rast__blend_factor(a ? da : drgb, a, src, dst, s->blend_color, c);
            out[c] = rast__blend_equation(eq, src[c], sf, dst[c], df);
        }
    } else {
        for (c = 0; c < 4; ++c) out[c] = src[c];
    }
    if (fb->color_f32) {
        float *px = (float *)row + 4 * x;
        for (c = 0; c < 4; ++c)
            if (p->color_write & (1u << c)) px[c] = out[c];
    } else {
        uint8_t *px = row + 4 * x;
        for (c = 0; c < 4; ++c)
            if (p->color_write & (1u << c)) px[c] = rast__to_unorm8(out[c]);
    }
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

static void rast__run_clear(const rast__pipe *p, const rast__fb *fb, const rast__clear_rec *r,
                            int x0, int y0, int x1, int y1) {
    int x, y, c;
    const rast_clear_desc *d = &r->c;
    unsigned smask = p->st_wmask[0];
    uint8_t v8[4];
    uint32_t v32;
    float z = RAST__CLAMP(d->depth, 0.0f, 1.0f);
    for (c = 0; c < 4; ++c) v8[c] = rast__to_unorm8(d->color[c]);
    memcpy(&v32, v8, 4);
    for (y = y0; y < y1; ++y) {
        if ((d->flags & RAST_CLEAR_COLOR) && fb->color && p->color_write) {
            uint8_t *row = fb->color + (size_t)y * (size_t)fb->color_stride;
            if (fb->color_f32) {
                float *px = (float *)row;
                for (x = x0; x < x1; ++x)
                    for (c = 0; c < 4; ++c)
                        if (p->color_write & (1u << c)) px[4 * x + c] = d->color[c];
            } else if (p->color_write == RAST_WRITE_RGBA) {
                for (x = x0; x < x1; ++x) memcpy(row + 4 * x, &v32, 4);
            } else {
                for (x = x0; x < x1; ++x)
                    for (c = 0; c < 4; ++c)
                        if (p->color_write & (1u << c)) row[4 * x + c] = v8[c];
            }
        }
        if ((d->flags & RAST_CLEAR_DEPTH) && fb->depth && !p->s.depth_write_disabled) {
            float *row = (float *)((uint8_t *)fb->depth + (size_t)y * (size_t)fb->depth_stride);
            for (x = x0; x < x1; ++x) row[x] = z;
        }
        if ((d->flags & RAST_CLEAR_STENCIL) && fb->stencil) {
            uint8_t *row = fb->stencil + (size_t)y * (size_t)fb->stencil_stride;
            if (smask == 0xFFu) memset(row + x0, d->stencil, (size_t)(x1 - x0));
            else
                for (x = x0; x < x1; ++x) row[x] = (uint8_t)((row[x] & ~smask) | (d->stencil & smask));
        }
        if ((d->flags & RAST_CLEAR_ACCUM) && fb->accum) {
            float *row = (float *)((uint8_t *)fb->accum + (size_t)y * (size_t)fb->accum_stride);
            for (x = x0; x < x1; ++x)
                for (c = 0; c < 4; ++c) row[4 * x + c] = d->accum[c];
        }
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
