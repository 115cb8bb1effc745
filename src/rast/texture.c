#include "internal.h"

/* ---- textures ------------------------------------------------------------

   STORAGE
       Every level of every face is float RGBA, rows top first, in the same
       block as the rast_texture header (one allocation, so nothing can leak
       half-built). RGBA8 texels become v / 255 once, at creation: sampling
       has one code path, mip levels are not rounded back to 8 bits, and
       RGBA32F keeps its values exactly, outside [0, 1] included. The price
       is 16 bytes per texel.

   MIPMAPS
       Level l is max(1, size >> l) on each axis (GL's floor(size / 2)), down
       to 1x1, each built from the level above. A texel is the area-weighted
       average of the texels its footprint covers: the 2x2 box for even
       sizes; for odd sizes the footprint is 2 + 1/n texels wide and edge
       texels count by the fraction covered, so none is dropped or doubled.

   SAMPLING (GL 4.6 section 8.14)
       Wrap modes act on integer texel coordinates; NEAREST takes
       floor(s * w), LINEAR the four texels around s * w - 1/2. lod <= 0
       magnifies with mag_filter on level 0; lod > 0 minifies with GL's level
       choice. Coordinates are widened to double, where s * w is exact for
       every float s, so far-away and negative coordinates wrap exactly.
       NaN coordinates read as 0, infinities as +-FLT_MAX, a NaN lod as 0.
       A NULL texture, or one of the other type, samples as GL's incomplete
       texture: (0, 0, 0, 1).

   CUBE MAPS
       Face selection is GL's table (4.6 table 8.19). GL leaves ties between
       |x|, |y| and |z| open; they go to z, then y, then x, as in Mesa's
       llvmpipe (the tests' GL reference), D3D10 and AMD's cube instruction.
       (softpipe and swrast prefer x, then y.) The zero vector reads the
       centre of +Z; NaN components count as 0; a direction with infinite
       components is its limit, those components as +-1 and the rest 0.
       Faces are sampled apart, with CLAMP_TO_EDGE (GL without
       TEXTURE_CUBE_MAP_SEAMLESS); face row 0 is at t = 0, as in 2D.
*/

struct rast_texture {
    rast_allocator allocator;  /* frees this block */
    rast_texture_type type;
    int width, height;         /* level 0 */
    int num_levels;            /* 1 without mipmaps */
    int num_faces;             /* 1 or 6 */
    rast_filter min_filter;    /* resolved: never DEFAULT */
    rast_filter mag_filter;    /* NEAREST or LINEAR */
    rast_wrap wrap_s, wrap_t;  /* resolved: never DEFAULT */
    int level_width[RAST_MAX_MIP_LEVELS];
    int level_height[RAST_MAX_MIP_LEVELS];
    float *texels[6][RAST_MAX_MIP_LEVELS]; /* RGBA rows, top first */
};

/* Weights of the source texels under destination texel i when an axis
   shrinks from n to m texels. Measured in 1/m of a source texel, texel i
   covers [i*n, (i+1)*n) and source texel j covers [j*m, (j+1)*m); the
   overlaps are integers summing to n, so the weights sum to 1. n / m <= 3,
   so at most 4 texels are touched. */
static int rast__box_taps(int i, int n, int m, int *first, float weight[4])
{
    int lo = i * n, hi = lo + n, j = lo / m, k = 0;
    *first = j;
    for (; j * m < hi; ++j) {
        int a = RAST__MAX(lo, j * m), b = RAST__MIN(hi, (j + 1) * m);
        RAST_ASSERT(k < 4);
        weight[k++] = (float)(b - a) / (float)n;
    }
    return k;
}

static void rast__downsample(const float *src, int sw, int sh, float *dst, int dw, int dh)
{
    int x, y, i, j, c, x0, y0, nx, ny;
    float wx[4], wy[4];
    for (y = 0; y < dh; ++y) {
        ny = rast__box_taps(y, sh, dh, &y0, wy);
        for (x = 0; x < dw; ++x) {
            float sum[4] = { 0.0f, 0.0f, 0.0f, 0.0f };
            nx = rast__box_taps(x, sw, dw, &x0, wx);
            for (j = 0; j < ny; ++j) {
                for (i = 0; i < nx; ++i) {
                    const float *p = src + ((size_t)(y0 + j) * (size_t)sw + (size_t)(x0 + i)) * 4;
                    float w = wx[i] * wy[j];
                    for (c = 0; c < 4; ++c) sum[c] += w * p[c];
                }
            }
            memcpy(dst + ((size_t)y * (size_t)dw + (size_t)x) * 4, sum, sizeof sum);
        }
    }
}

static int rast__valid_filter(rast_filter f, int mag)
{
    int v = (int)f;
    return v >= 0 && v <= (mag ? (int)RAST_FILTER_LINEAR : (int)RAST_FILTER_LINEAR_MIPMAP_LINEAR);
}

static int rast__valid_wrap(rast_wrap w)
{
    return (int)w >= 0 && (int)w <= (int)RAST_WRAP_MIRRORED_REPEAT;
}

RAST_API rast_result rast_texture_create(const rast_texture_desc *desc, rast_texture **out_tex)
{
    rast_texture *tex;
    unsigned char *block;
    size_t header, count = 0, offset;
    int cube, faces, levels, w, h, f, l, x, y, texel_bytes, stride;

    if (out_tex) *out_tex = NULL;
    if (!desc || !out_tex) return RAST_ERROR_INVALID_ARGUMENT;
    if (desc->type != RAST_TEXTURE_2D && desc->type != RAST_TEXTURE_CUBE)
        return RAST_ERROR_INVALID_ARGUMENT;
    if ((int)desc->format < 0 || (int)desc->format > (int)RAST_TEXTURE_RGBA32F)
        return RAST_ERROR_INVALID_ARGUMENT;
    cube = desc->type == RAST_TEXTURE_CUBE;
    if (!rast__valid_filter(desc->min_filter, 0) || !rast__valid_filter(desc->mag_filter, 1))
        return RAST_ERROR_INVALID_ARGUMENT;
    /* cube maps ignore the wrap modes, so they are not checked there */
    if (!cube && (!rast__valid_wrap(desc->wrap_s) || !rast__valid_wrap(desc->wrap_t)))
        return RAST_ERROR_INVALID_ARGUMENT;
    /* memory from one allocator must not go back to another */
    if (!desc->allocator.alloc != !desc->allocator.free) return RAST_ERROR_INVALID_ARGUMENT;

    w = desc->width;
    h = desc->height;
    if (w <= 0 || h <= 0 || w > RAST_MAX_TARGET_SIZE || h > RAST_MAX_TARGET_SIZE)
        return RAST_ERROR_INVALID_SIZE;
    if (cube && w != h) return RAST_ERROR_INVALID_SIZE;
    texel_bytes = desc->format == RAST_TEXTURE_RGBA32F ? 16 : 4;
    stride = desc->stride ? desc->stride : w * texel_bytes;
    if (stride < w * texel_bytes) return RAST_ERROR_INVALID_SIZE;

    faces = cube ? 6 : 1;
    for (f = 0; f < faces; ++f)
        if (!desc->pixels[f]) return RAST_ERROR_INVALID_ARGUMENT;

    levels = 1;
    if (desc->mipmaps)
        for (x = RAST__MAX(w, h); x > 1; x >>= 1) ++levels;
    RAST_ASSERT(levels <= RAST_MAX_MIP_LEVELS);
    for (l = 0; l < levels; ++l)
        count += (size_t)RAST__MAX(w >> l, 1) * (size_t)RAST__MAX(h >> l, 1);
    count *= (size_t)faces; /* < 2^31 texels: no overflow yet */

    /* the header rounded up to 16 bytes keeps the texels vector-aligned */
    header = (sizeof(rast_texture) + 15) & ~(size_t)15;
    if (count > ((size_t)-1 - header) / (4 * sizeof(float))) return RAST_ERROR_OUT_OF_MEMORY;
    block = (unsigned char *)rast__alloc(&desc->allocator, header + count * 4 * sizeof(float));
    if (!block) return RAST_ERROR_OUT_OF_MEMORY;

    tex = (rast_texture *)(void *)block;
    memset(tex, 0, sizeof *tex);
    tex->allocator = desc->allocator;
    tex->type = desc->type;
    tex->width = w;
    tex->height = h;
    tex->num_levels = levels;
    tex->num_faces = faces;
    tex->min_filter = desc->min_filter != RAST_FILTER_DEFAULT ? desc->min_filter
                    : desc->mipmaps ? RAST_FILTER_LINEAR_MIPMAP_LINEAR : RAST_FILTER_LINEAR;
    tex->mag_filter = desc->mag_filter != RAST_FILTER_DEFAULT ? desc->mag_filter : RAST_FILTER_LINEAR;
    tex->wrap_s = cube ? RAST_WRAP_CLAMP_TO_EDGE
                : desc->wrap_s != RAST_WRAP_DEFAULT ? desc->wrap_s : RAST_WRAP_REPEAT;
    tex->wrap_t = cube ? RAST_WRAP_CLAMP_TO_EDGE
                : desc->wrap_t != RAST_WRAP_DEFAULT ? desc->wrap_t : RAST_WRAP_REPEAT;
    for (l = 0; l < levels; ++l) {
        tex->level_width[l] = RAST__MAX(w >> l, 1);
        tex->level_height[l] = RAST__MAX(h >> l, 1);
    }

    offset = header;
    for (f = 0; f < faces; ++f) {
        for (l = 0; l < levels; ++l) {
            tex->texels[f][l] = (float *)(void *)(block + offset);
            offset += (size_t)tex->level_width[l] * (size_t)tex->level_height[l] * 4 * sizeof(float);
        }
    }

    for (f = 0; f < faces; ++f) {
        for (y = 0; y < h; ++y) {
            const unsigned char *row = (const unsigned char *)desc->pixels[f] + (size_t)y * (size_t)stride;
            float *dst = tex->texels[f][0] + (size_t)y * (size_t)w * 4;
            if (texel_bytes == 16) {
                memcpy(dst, row, (size_t)w * 16); /* the caller's rows need no alignment */
            } else {
                for (x = 0; x < w * 4; ++x) dst[x] = (float)row[x] / 255.0f;
            }
        }
        for (l = 1; l < levels; ++l)
            rast__downsample(tex->texels[f][l - 1], tex->level_width[l - 1], tex->level_height[l - 1],
                             tex->texels[f][l], tex->level_width[l], tex->level_height[l]);
    }

    *out_tex = tex;
    return RAST_OK;
}

RAST_API void rast_texture_destroy(rast_texture *tex)
{
    rast_allocator a;
    if (!tex) return;
    a = tex->allocator; /* it lives in the block being freed */
    rast__free(&a, tex);
}

/* ---- sampling ---- */

static float rast__coord(float v)
{
    if (v != v) return 0.0f;
    return RAST__CLAMP(v, -FLT_MAX, FLT_MAX);
}

/* GL's wrap(i) (4.6 table 8.20) on an integer texel coordinate held in a
   double, which may be far outside the int range. */
static int rast__wrap(double i, int size, rast_wrap mode)
{
    double period;
    int k;
    if (mode == RAST_WRAP_CLAMP_TO_EDGE) return (int)RAST__CLAMP(i, 0.0, (double)(size - 1));
    period = mode == RAST_WRAP_MIRRORED_REPEAT ? 2.0 * size : (double)size;
    if (i < 0.0 || i >= period) i = fmod(i, period); /* exact */
    k = (int)i;
    if (k < 0) k += (int)period;
    if (mode == RAST_WRAP_MIRRORED_REPEAT) {
        /* (size - 1) - mirror(k - size), mirror(a) = a >= 0 ? a : -(1 + a) */
        k -= size;
        k = size - 1 - (k >= 0 ? k : -(1 + k));
    }
    return k;
}

static void rast__sample_level(const rast_texture *tex, int face, int level, int linear,
                               rast_wrap ws, rast_wrap wt, float s, float t, float rgba[4])
{
    const float *img = tex->texels[face][level];
    int w = tex->level_width[level], h = tex->level_height[level], c;
    double u = (double)s * w, v = (double)t * h;

    if (!linear) {
        int i = rast__wrap(floor(u), w, ws), j = rast__wrap(floor(v), h, wt);
        memcpy(rgba, img + ((size_t)j * (size_t)w + (size_t)i) * 4, 4 * sizeof(float));
    } else {
        double fu = floor(u - 0.5), fv = floor(v - 0.5);
        float a = (float)(u - 0.5 - fu), b = (float)(v - 0.5 - fv);
        size_t i0 = (size_t)rast__wrap(fu, w, ws), i1 = (size_t)rast__wrap(fu + 1.0, w, ws);
        size_t j0 = (size_t)rast__wrap(fv, h, wt), j1 = (size_t)rast__wrap(fv + 1.0, h, wt);
        const float *t00 = img + (j0 * (size_t)w + i0) * 4, *t10 = img + (j0 * (size_t)w + i1) * 4;
        const float *t01 = img + (j1 * (size_t)w + i0) * 4, *t11 = img + (j1 * (size_t)w + i1) * 4;
        float w00 = (1.0f - a) * (1.0f - b), w10 = a * (1.0f - b);
        float w01 = (1.0f - a) * b, w11 = a * b;
        for (c = 0; c < 4; ++c)
            rgba[c] = w00 * t00[c] + w10 * t10[c] + w01 * t01[c] + w11 * t11[c];
    }
}

static void rast__sample(const rast_texture *tex, int face, rast_wrap ws, rast_wrap wt,
                         float s, float t, float lod, float rgba[4])
{
    rast_filter f = tex->min_filter;
    int q = tex->num_levels - 1, d, c, linear;
    float frac, hi[4];

    s = rast__coord(s);
    t = rast__coord(t);
    if (!(lod > 0.0f)) { /* magnification; a NaN lod lands here too */
        rast__sample_level(tex, face, 0, tex->mag_filter == RAST_FILTER_LINEAR, ws, wt, s, t, rgba);
        return;
    }
    switch (f) {
    case RAST_FILTER_NEAREST_MIPMAP_NEAREST:
    case RAST_FILTER_LINEAR_MIPMAP_NEAREST:
        /* GL: d = ceil(lod + 1/2) - 1, the nearest level, halves going down */
        if (lod <= 0.5f) d = 0;
        else if ((double)lod > q + 0.5) d = q;
        else d = (int)ceil((double)lod + 0.5) - 1;
        rast__sample_level(tex, face, d, f == RAST_FILTER_LINEAR_MIPMAP_NEAREST, ws, wt, s, t, rgba);
        break;
    case RAST_FILTER_NEAREST_MIPMAP_LINEAR:
    case RAST_FILTER_LINEAR_MIPMAP_LINEAR:
        linear = f == RAST_FILTER_LINEAR_MIPMAP_LINEAR;
        if (lod >= (float)q) {
            rast__sample_level(tex, face, q, linear, ws, wt, s, t, rgba);
            break;
        }
        d = (int)lod;
        frac = lod - (float)d; /* exact */
        rast__sample_level(tex, face, d, linear, ws, wt, s, t, rgba);
        if (frac > 0.0f) {
            rast__sample_level(tex, face, d + 1, linear, ws, wt, s, t, hi);
            for (c = 0; c < 4; ++c) rgba[c] = (1.0f - frac) * rgba[c] + frac * hi[c];
        }
        break;
    default: /* NEAREST, LINEAR: level 0 only */
        rast__sample_level(tex, face, 0, f == RAST_FILTER_LINEAR, ws, wt, s, t, rgba);
        break;
    }
}

static void rast__texture_incomplete(float rgba[4])
{
    rgba[0] = rgba[1] = rgba[2] = 0.0f;
    rgba[3] = 1.0f;
}

RAST_API void rast_texture_sample_2d(const rast_texture *tex, float s, float t, float lod, float rgba[4])
{
    if (!rgba) return;
    if (!tex || tex->type != RAST_TEXTURE_2D) {
        rast__texture_incomplete(rgba);
        return;
    }
    rast__sample(tex, 0, tex->wrap_s, tex->wrap_t, s, t, lod, rgba);
}

RAST_API int rast_cube_face(const float dir[3], float *out_s, float *out_t)
{
    float v[3] = { 0.0f, 0.0f, 0.0f }, x, y, z, ax, ay, az, sc, tc, ma, s = 0.5f, t = 0.5f;
    int face, k, infinite = 0;

    if (dir) {
        for (k = 0; k < 3; ++k) {
            v[k] = dir[k] != dir[k] ? 0.0f : dir[k]; /* NaN counts as 0 */
            if (!rast__isfinite(v[k])) infinite = 1;
        }
    }
    if (infinite) /* the limit direction: only the infinite components, as +-1 */
        for (k = 0; k < 3; ++k) v[k] = rast__isfinite(v[k]) ? 0.0f : v[k] > 0.0f ? 1.0f : -1.0f;
    x = v[0]; y = v[1]; z = v[2];
    ax = fabsf(x); ay = fabsf(y); az = fabsf(z);

    /* GL 4.6 table 8.19; ties prefer z, then y (llvmpipe) */
    if (az >= ax && az >= ay) {
        face = z >= 0.0f ? 4 : 5;
        sc = z >= 0.0f ? x : -x;
        tc = -y;
        ma = az;
    } else if (ay >= ax) {
        face = y >= 0.0f ? 2 : 3;
        sc = x;
        tc = y >= 0.0f ? z : -z;
        ma = ay;
    } else {
        face = x >= 0.0f ? 0 : 1;
        sc = x >= 0.0f ? -z : z;
        tc = -y;
        ma = ax;
    }
    if (ma > 0.0f) { /* else the zero vector: the centre of +Z */
        s = (sc / ma + 1.0f) * 0.5f;
        t = (tc / ma + 1.0f) * 0.5f;
    }
    if (out_s) *out_s = s;
    if (out_t) *out_t = t;
    return face;
}

RAST_API void rast_texture_sample_cube(const rast_texture *tex, const float dir[3], float lod, float rgba[4])
{
    float s, t;
    int face;
    if (!rgba) return;
    if (!tex || tex->type != RAST_TEXTURE_CUBE) {
        rast__texture_incomplete(rgba);
        return;
    }
    face = rast_cube_face(dir, &s, &t);
    rast__sample(tex, face, RAST_WRAP_CLAMP_TO_EDGE, RAST_WRAP_CLAMP_TO_EDGE, s, t, lod, rgba);
}

/* For the fragment stage: GL's scale factor from the screen derivatives of
   (s, t), rho = max(|d(s*w, t*h)/dx|, |d(s*w, t*h)/dy|) on level 0, and
   lod = log2(rho). rho = 0 gives -inf, which magnifies. */
static void rast__texture_sample_2d_grad(const rast_texture *tex, float s, float t,
                                         float dsdx, float dtdx, float dsdy, float dtdy,
                                         float rgba[4])
{
    float lod = 0.0f;
    if (tex) {
        float w = (float)tex->width, h = (float)tex->height;
        float ux = dsdx * w, vx = dtdx * h, uy = dsdy * w, vy = dtdy * h;
        float rx = sqrtf(ux * ux + vx * vx), ry = sqrtf(uy * uy + vy * vy);
        lod = log2f(RAST__MAX(rx, ry));
    }
    rast_texture_sample_2d(tex, s, t, lod, rgba);
}
