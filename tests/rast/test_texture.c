/* Texture module: creation, validation, mipmaps, 2D sampling and cube maps.
   Every expected value is worked out by hand from the GL 4.6 rules (section
   8.14 and table 8.19); the comments show the arithmetic. */
#include <criterion/criterion.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../../rast.h"

#define EPS 1e-5f

static void expect_rgba(const float got[4], float r, float g, float b, float a)
{
    cr_expect(fabsf(got[0] - r) <= EPS && fabsf(got[1] - g) <= EPS &&
              fabsf(got[2] - b) <= EPS && fabsf(got[3] - a) <= EPS,
              "got (%g %g %g %g), want (%g %g %g %g)",
              (double)got[0], (double)got[1], (double)got[2], (double)got[3],
              (double)r, (double)g, (double)b, (double)a);
}

static float red_at(const rast_texture *tex, float s, float t, float lod)
{
    float c[4];
    rast_texture_sample_2d(tex, s, t, lod, c);
    return c[0];
}

#define expect_red(tex, s, t, lod, want)                                          \
    do {                                                                          \
        float got_ = red_at(tex, s, t, lod);                                      \
        cr_expect(fabsf(got_ - (want)) <= EPS, "at s=%g t=%g lod=%g: red %g, want %g", \
                  (double)(s), (double)(t), (double)(lod), (double)got_, (double)(want)); \
    } while (0)

/* 4x4 RGBA32F, texel (x, y) = (x, y, 10y + x, 1): red tells the column,
   green the row (row 0 is the top row, t = 0). */
static float ramp4[4 * 4 * 4];

static void fill_ramp(void)
{
    int x, y;
    for (y = 0; y < 4; ++y)
        for (x = 0; x < 4; ++x) {
            float *p = ramp4 + (y * 4 + x) * 4;
            p[0] = (float)x; p[1] = (float)y; p[2] = (float)(10 * y + x); p[3] = 1.0f;
        }
}

static rast_texture *make_ramp(rast_filter min, rast_filter mag, rast_wrap ws, rast_wrap wt)
{
    rast_texture_desc d;
    rast_texture *tex = NULL;
    fill_ramp();
    memset(&d, 0, sizeof d);
    d.format = RAST_TEXTURE_RGBA32F;
    d.width = d.height = 4;
    d.pixels[0] = ramp4;
    d.min_filter = min;
    d.mag_filter = mag;
    d.wrap_s = ws;
    d.wrap_t = wt;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    cr_assert_not_null(tex);
    return tex;
}

/* 4x4 RGBA32F with red = x + 4y, mipmapped. By hand:
   level 1 (2x2): (0+1+4+5)/4 = 2.5, (2+3+6+7)/4 = 4.5,
                  (8+9+12+13)/4 = 10.5, (10+11+14+15)/4 = 12.5
   level 2 (1x1): (2.5+4.5+10.5+12.5)/4 = 7.5 */
static float seq4[4 * 4 * 4];

static rast_texture *make_seq_mipmapped(rast_filter min, rast_filter mag)
{
    rast_texture_desc d;
    rast_texture *tex = NULL;
    int i;
    for (i = 0; i < 16; ++i) {
        seq4[i * 4 + 0] = (float)i;
        seq4[i * 4 + 1] = 0.0f;
        seq4[i * 4 + 2] = 0.0f;
        seq4[i * 4 + 3] = 1.0f;
    }
    memset(&d, 0, sizeof d);
    d.format = RAST_TEXTURE_RGBA32F;
    d.width = d.height = 4;
    d.pixels[0] = seq4;
    d.mipmaps = 1;
    d.min_filter = min;
    d.mag_filter = mag;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    return tex;
}

/* ---- 2D filtering ---- */

Test(texture, nearest_picks_texel_under_coordinate)
{
    rast_texture *tex = make_ramp(RAST_FILTER_NEAREST, RAST_FILTER_NEAREST,
                                  RAST_WRAP_REPEAT, RAST_WRAP_REPEAT);
    float c[4];
    int x, y;
    for (y = 0; y < 4; ++y)
        for (x = 0; x < 4; ++x) {
            /* texel centres ((x + 0.5) / 4, (y + 0.5) / 4) */
            rast_texture_sample_2d(tex, ((float)x + 0.5f) / 4.0f, ((float)y + 0.5f) / 4.0f, 0.0f, c);
            expect_rgba(c, (float)x, (float)y, (float)(10 * y + x), 1.0f);
        }
    /* s = 0.49 -> u = 1.96 -> texel 1; t = 0 -> the top row, row 0 */
    rast_texture_sample_2d(tex, 0.49f, 0.0f, 0.0f, c);
    expect_rgba(c, 1.0f, 0.0f, 1.0f, 1.0f);
    /* s = 0.5 -> u = 2 exactly -> texel 2; t = 0.99 -> row 3 */
    rast_texture_sample_2d(tex, 0.5f, 0.99f, 0.0f, c);
    expect_rgba(c, 2.0f, 3.0f, 32.0f, 1.0f);
    rast_texture_destroy(tex);
}

Test(texture, bilinear_weights_at_known_positions)
{
    rast_texture *tex = make_ramp(RAST_FILTER_LINEAR, RAST_FILTER_LINEAR,
                                  RAST_WRAP_CLAMP_TO_EDGE, RAST_WRAP_CLAMP_TO_EDGE);
    float c[4];
    /* at a texel centre bilinear is that texel: s = 0.375 -> u - 0.5 = 1 */
    rast_texture_sample_2d(tex, 0.375f, 0.625f, 0.0f, c);
    expect_rgba(c, 1.0f, 2.0f, 21.0f, 1.0f);
    /* s = 0.3125: u - 0.5 = 0.75 -> 0.25 * texel 0 + 0.75 * texel 1 = 0.75;
       t = 0.625: v - 0.5 = 2 -> row 2; blue = 10 * 2 + 0.75 */
    rast_texture_sample_2d(tex, 0.3125f, 0.625f, 0.0f, c);
    expect_rgba(c, 0.75f, 2.0f, 20.75f, 1.0f);
    /* s = t = 0.5: halfway between texels 1 and 2 on both axes */
    rast_texture_sample_2d(tex, 0.5f, 0.5f, 0.0f, c);
    expect_rgba(c, 1.5f, 1.5f, 16.5f, 1.0f);
    /* s = 0.1875, t = 0.4375: u - 0.5 = 0.25 -> 0.25; v - 0.5 = 1.25 -> 1.25 */
    rast_texture_sample_2d(tex, 0.1875f, 0.4375f, 0.0f, c);
    expect_rgba(c, 0.25f, 1.25f, 12.75f, 1.0f);
    rast_texture_destroy(tex);
}

Test(texture, nearest_vs_bilinear_same_point)
{
    rast_texture *n = make_ramp(RAST_FILTER_NEAREST, RAST_FILTER_NEAREST,
                                RAST_WRAP_REPEAT, RAST_WRAP_REPEAT);
    rast_texture *l = make_ramp(RAST_FILTER_LINEAR, RAST_FILTER_LINEAR,
                                RAST_WRAP_REPEAT, RAST_WRAP_REPEAT);
    /* s = 0.4375: u = 1.75 -> nearest texel 1; bilinear 0.75*1 + 0.25*2 = 1.25 */
    expect_red(n, 0.4375f, 0.375f, 0.0f, 1.0f);
    expect_red(l, 0.4375f, 0.375f, 0.0f, 1.25f);
    rast_texture_destroy(n);
    rast_texture_destroy(l);
}

/* ---- wrap modes (NEAREST on the 4-wide ramp: red = wrapped column) ---- */

Test(texture, wrap_repeat)
{
    rast_texture *tex = make_ramp(RAST_FILTER_NEAREST, RAST_FILTER_NEAREST,
                                  RAST_WRAP_REPEAT, RAST_WRAP_REPEAT);
    expect_red(tex, -0.125f, 0.5f, 0.0f, 3.0f);  /* u = -0.5 -> -1 mod 4 = 3 */
    expect_red(tex, -0.375f, 0.5f, 0.0f, 2.0f);  /* u = -1.5 -> -2 -> 2 */
    expect_red(tex, 1.125f, 0.5f, 0.0f, 0.0f);   /* u = 4.5 -> 4 -> 0 */
    expect_red(tex, 1.875f, 0.5f, 0.0f, 3.0f);   /* u = 7.5 -> 7 -> 3 */
    expect_red(tex, -1.875f, 0.5f, 0.0f, 0.0f);  /* u = -7.5 -> -8 -> 0 */
    expect_red(tex, 1000.375f, 0.5f, 0.0f, 1.0f);/* u = 4001.5 -> 4001 -> 1 */
    rast_texture_destroy(tex);
}

Test(texture, wrap_clamp_to_edge)
{
    rast_texture *tex = make_ramp(RAST_FILTER_NEAREST, RAST_FILTER_NEAREST,
                                  RAST_WRAP_CLAMP_TO_EDGE, RAST_WRAP_CLAMP_TO_EDGE);
    expect_red(tex, -0.125f, 0.5f, 0.0f, 0.0f);
    expect_red(tex, -5.0f, 0.5f, 0.0f, 0.0f);
    expect_red(tex, 1.0f, 0.5f, 0.0f, 3.0f);     /* u = 4 -> clamped to 3 */
    expect_red(tex, 1.125f, 0.5f, 0.0f, 3.0f);
    expect_red(tex, 7.0f, 0.5f, 0.0f, 3.0f);
    rast_texture_destroy(tex);
}

Test(texture, wrap_mirrored_repeat)
{
    rast_texture *tex = make_ramp(RAST_FILTER_NEAREST, RAST_FILTER_NEAREST,
                                  RAST_WRAP_MIRRORED_REPEAT, RAST_WRAP_MIRRORED_REPEAT);
    /* GL: wrap(i) = (size-1) - mirror((i mod 2size) - size); columns run
       ... 1 0 | 0 1 2 3 | 3 2 1 0 | 0 1 ... */
    expect_red(tex, -0.125f, 0.5f, 0.0f, 0.0f);  /* i = -1 -> 0 */
    expect_red(tex, -0.375f, 0.5f, 0.0f, 1.0f);  /* i = -2 -> 1 */
    expect_red(tex, -0.875f, 0.5f, 0.0f, 3.0f);  /* i = -4 -> 3 */
    expect_red(tex, 1.125f, 0.5f, 0.0f, 3.0f);   /* i = 4 -> 3 */
    expect_red(tex, 1.375f, 0.5f, 0.0f, 2.0f);   /* i = 5 -> 2 */
    expect_red(tex, 1.875f, 0.5f, 0.0f, 0.0f);   /* i = 7 -> 0 */
    expect_red(tex, 2.125f, 0.5f, 0.0f, 0.0f);   /* i = 8 -> 0 */
    expect_red(tex, 2.375f, 0.5f, 0.0f, 1.0f);   /* i = 9 -> 1 */
    rast_texture_destroy(tex);
}

Test(texture, wrap_modes_under_bilinear_at_edges)
{
    rast_texture *r = make_ramp(RAST_FILTER_LINEAR, RAST_FILTER_LINEAR, RAST_WRAP_REPEAT, RAST_WRAP_REPEAT);
    rast_texture *c = make_ramp(RAST_FILTER_LINEAR, RAST_FILTER_LINEAR, RAST_WRAP_CLAMP_TO_EDGE, RAST_WRAP_CLAMP_TO_EDGE);
    rast_texture *m = make_ramp(RAST_FILTER_LINEAR, RAST_FILTER_LINEAR, RAST_WRAP_MIRRORED_REPEAT, RAST_WRAP_MIRRORED_REPEAT);
    /* s = 0: u - 0.5 = -0.5 -> texels -1 and 0 at weight 1/2 each */
    expect_red(r, 0.0f, 0.375f, 0.0f, 1.5f);  /* 3 and 0 */
    expect_red(c, 0.0f, 0.375f, 0.0f, 0.0f);  /* 0 and 0 */
    expect_red(m, 0.0f, 0.375f, 0.0f, 0.0f);  /* 0 and 0 */
    /* s = 1: u - 0.5 = 3.5 -> texels 3 and 4 */
    expect_red(r, 1.0f, 0.375f, 0.0f, 1.5f);  /* 3 and 0 */
    expect_red(c, 1.0f, 0.375f, 0.0f, 3.0f);  /* 3 and 3 */
    expect_red(m, 1.0f, 0.375f, 0.0f, 3.0f);  /* 3 and 3 */
    /* s = -0.25: u - 0.5 = -1.5 -> texels -2, -1 */
    expect_red(r, -0.25f, 0.375f, 0.0f, 2.5f); /* 2 and 3 */
    expect_red(c, -0.25f, 0.375f, 0.0f, 0.0f);
    expect_red(m, -0.25f, 0.375f, 0.0f, 0.5f); /* 1 and 0 */
    rast_texture_destroy(r);
    rast_texture_destroy(c);
    rast_texture_destroy(m);
}

Test(texture, wrap_s_and_t_are_independent)
{
    rast_texture *tex = make_ramp(RAST_FILTER_NEAREST, RAST_FILTER_NEAREST,
                                  RAST_WRAP_CLAMP_TO_EDGE, RAST_WRAP_REPEAT);
    float c[4];
    /* s = 1.125 clamps to column 3; t = 1.125 repeats to row 0;
       t = -0.125 repeats to row 3 */
    rast_texture_sample_2d(tex, 1.125f, 1.125f, 0.0f, c);
    expect_rgba(c, 3.0f, 0.0f, 3.0f, 1.0f);
    rast_texture_sample_2d(tex, -3.0f, -0.125f, 0.0f, c);
    expect_rgba(c, 0.0f, 3.0f, 30.0f, 1.0f);
    rast_texture_destroy(tex);
}

Test(texture, default_wrap_is_repeat_and_default_filters)
{
    rast_texture *tex = make_ramp(RAST_FILTER_DEFAULT, RAST_FILTER_DEFAULT,
                                  RAST_WRAP_DEFAULT, RAST_WRAP_DEFAULT);
    /* default mag LINEAR, wrap REPEAT: s = 0 blends texels 3 and 0 */
    expect_red(tex, 0.0f, 0.375f, 0.0f, 1.5f);
    /* without mipmaps the default min is LINEAR on level 0, for any lod */
    expect_red(tex, 0.3125f, 0.375f, 3.0f, 0.75f);
    rast_texture_destroy(tex);
}

Test(texture, lod_picks_min_or_mag_filter)
{
    /* min NEAREST, mag LINEAR, no mipmaps: s = 0.4375 gives 1 or 1.25 */
    rast_texture *tex = make_ramp(RAST_FILTER_NEAREST, RAST_FILTER_LINEAR,
                                  RAST_WRAP_REPEAT, RAST_WRAP_REPEAT);
    expect_red(tex, 0.4375f, 0.375f, 0.0f, 1.25f);   /* lod <= 0: mag */
    expect_red(tex, 0.4375f, 0.375f, -2.0f, 1.25f);
    expect_red(tex, 0.4375f, 0.375f, 0.001f, 1.0f);  /* lod > 0: min */
    expect_red(tex, 0.4375f, 0.375f, 5.0f, 1.0f);
    rast_texture_destroy(tex);
    /* a mipmap min filter without mipmaps uses its base filter on level 0 */
    tex = make_ramp(RAST_FILTER_LINEAR_MIPMAP_LINEAR, RAST_FILTER_NEAREST,
                    RAST_WRAP_REPEAT, RAST_WRAP_REPEAT);
    expect_red(tex, 0.4375f, 0.375f, 0.0f, 1.0f);
    expect_red(tex, 0.4375f, 0.375f, 1.5f, 1.25f);
    rast_texture_destroy(tex);
}

/* ---- formats and strides ---- */

Test(texture, rgba32f_values_outside_unit_range_preserved)
{
    float px[2 * 1 * 4] = { 1000.5f, -3.0f, 2.5f, 65504.0f, -0.25f, 1e-30f, 7.0f, 1.0f };
    rast_texture_desc d;
    rast_texture *tex;
    float c[4];
    memset(&d, 0, sizeof d);
    d.format = RAST_TEXTURE_RGBA32F;
    d.width = 2; d.height = 1;
    d.pixels[0] = px;
    d.min_filter = d.mag_filter = RAST_FILTER_NEAREST;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    rast_texture_sample_2d(tex, 0.25f, 0.5f, 0.0f, c);
    cr_expect(c[0] == 1000.5f && c[1] == -3.0f && c[2] == 2.5f && c[3] == 65504.0f);
    rast_texture_sample_2d(tex, 0.75f, 0.5f, 0.0f, c);
    cr_expect(c[0] == -0.25f && c[1] == 1e-30f && c[2] == 7.0f && c[3] == 1.0f);
    /* bilinear halfway: (1000.5 + -0.25) / 2 = 500.125 */
    rast_texture_destroy(tex);
    d.mag_filter = RAST_FILTER_LINEAR;
    d.wrap_s = RAST_WRAP_CLAMP_TO_EDGE;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    rast_texture_sample_2d(tex, 0.5f, 0.5f, 0.0f, c);
    cr_expect_float_eq(c[0], 500.125f, 1e-3f);
    rast_texture_destroy(tex);
}

Test(texture, rgba8_converts_to_unit_floats)
{
    const uint8_t px[4] = { 0, 51, 255, 128 };
    rast_texture_desc d;
    rast_texture *tex;
    float c[4];
    memset(&d, 0, sizeof d); /* format DEFAULT = RGBA8 */
    d.width = d.height = 1;
    d.pixels[0] = px;
    d.mag_filter = RAST_FILTER_NEAREST; /* exact: no weights */
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    rast_texture_sample_2d(tex, 0.3f, 0.7f, 0.0f, c);
    cr_expect(c[0] == 0.0f && c[1] == 51.0f / 255.0f && c[2] == 1.0f && c[3] == 128.0f / 255.0f);
    rast_texture_destroy(tex);
}

Test(texture, stride_skips_row_padding)
{
    /* 2x2 RGBA8, rows 12 bytes apart; the padding is poison */
    const uint8_t px[24] = {
        10, 0, 0, 255,   20, 0, 0, 255,   99, 99, 99, 99,
        30, 0, 0, 255,   40, 0, 0, 255,   99, 99, 99, 99,
    };
    rast_texture_desc d;
    rast_texture *tex;
    memset(&d, 0, sizeof d);
    d.format = RAST_TEXTURE_RGBA8;
    d.width = d.height = 2;
    d.stride = 12;
    d.pixels[0] = px;
    d.min_filter = d.mag_filter = RAST_FILTER_NEAREST;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    expect_red(tex, 0.25f, 0.25f, 0.0f, 10.0f / 255.0f);
    expect_red(tex, 0.75f, 0.25f, 0.0f, 20.0f / 255.0f);
    expect_red(tex, 0.25f, 0.75f, 0.0f, 30.0f / 255.0f);
    expect_red(tex, 0.75f, 0.75f, 0.0f, 40.0f / 255.0f);
    rast_texture_destroy(tex);
}

Test(texture, rgba32f_unaligned_rows_with_stride)
{
    /* 1x2 RGBA32F whose rows start 1 byte into a buffer, 20 bytes apart */
    unsigned char buf[1 + 40];
    float a[4] = { 1.5f, 2.5f, 3.5f, 4.5f }, b[4] = { -1.0f, -2.0f, -3.0f, -4.0f }, c[4];
    rast_texture_desc d;
    rast_texture *tex;
    memset(buf, 0xFF, sizeof buf);
    memcpy(buf + 1, a, 16);
    memcpy(buf + 21, b, 16);
    memset(&d, 0, sizeof d);
    d.format = RAST_TEXTURE_RGBA32F;
    d.width = 1; d.height = 2;
    d.stride = 20;
    d.pixels[0] = buf + 1;
    d.mag_filter = RAST_FILTER_NEAREST;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    rast_texture_sample_2d(tex, 0.5f, 0.25f, 0.0f, c);
    expect_rgba(c, 1.5f, 2.5f, 3.5f, 4.5f);
    rast_texture_sample_2d(tex, 0.5f, 0.75f, 0.0f, c);
    expect_rgba(c, -1.0f, -2.0f, -3.0f, -4.0f);
    rast_texture_destroy(tex);
}

/* ---- mipmaps ---- */

static rast_texture *make_checker(int size, rast_filter min)
{
    uint8_t *px = (uint8_t *)malloc((size_t)size * (size_t)size * 4);
    rast_texture_desc d;
    rast_texture *tex = NULL;
    int x, y, k;
    cr_assert_not_null(px);
    for (y = 0; y < size; ++y)
        for (x = 0; x < size; ++x)
            for (k = 0; k < 4; ++k)
                px[(y * size + x) * 4 + k] = ((x + y) & 1) ? 0 : 255; /* (0,0) white */
    memset(&d, 0, sizeof d);
    d.width = d.height = size;
    d.pixels[0] = px;
    d.mipmaps = 1;
    d.min_filter = min;
    d.mag_filter = RAST_FILTER_NEAREST;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    free(px);
    return tex;
}

Test(texture, checkerboard_mip_levels_are_uniform_grey)
{
    rast_texture *tex = make_checker(8, RAST_FILTER_NEAREST_MIPMAP_NEAREST);
    float c[4];
    int level, x, y;
    /* level 0 is the checkerboard itself */
    expect_red(tex, 0.0625f, 0.0625f, 0.0f, 1.0f);
    expect_red(tex, 0.1875f, 0.0625f, 0.0f, 0.0f);
    /* levels 1 (4x4), 2 (2x2) and 3 (1x1): every 2x2 box holds two white and
       two black texels, so every texel is (1 + 0 + 1 + 0) / 4 = 0.5 */
    for (level = 1; level <= 3; ++level) {
        int n = 8 >> level;
        for (y = 0; y < n; ++y)
            for (x = 0; x < n; ++x) {
                rast_texture_sample_2d(tex, ((float)x + 0.5f) / (float)n,
                                       ((float)y + 0.5f) / (float)n, (float)level, c);
                expect_rgba(c, 0.5f, 0.5f, 0.5f, 0.5f);
            }
    }
    rast_texture_destroy(tex);
}

Test(texture, mipmap_nearest_level_selection)
{
    rast_texture *tex = make_seq_mipmapped(RAST_FILTER_NEAREST_MIPMAP_NEAREST, RAST_FILTER_NEAREST);
    /* s = t = 0.25: level 0 texel (1, 1) = 5, level 1 texel (0, 0) = 2.5,
       level 2 = 7.5. GL: d = 0 for lod <= 1/2, else ceil(lod + 1/2) - 1 */
    expect_red(tex, 0.25f, 0.25f, 0.0f, 5.0f);   /* magnification */
    expect_red(tex, 0.25f, 0.25f, 0.25f, 5.0f);
    expect_red(tex, 0.25f, 0.25f, 0.5f, 5.0f);
    expect_red(tex, 0.25f, 0.25f, 0.51f, 2.5f);
    expect_red(tex, 0.25f, 0.25f, 1.0f, 2.5f);
    expect_red(tex, 0.25f, 0.25f, 1.5f, 2.5f);   /* halves go down */
    expect_red(tex, 0.25f, 0.25f, 1.51f, 7.5f);
    expect_red(tex, 0.25f, 0.25f, 2.0f, 7.5f);
    expect_red(tex, 0.25f, 0.25f, 40.0f, 7.5f);  /* clamped to the last level */
    expect_red(tex, 0.25f, 0.25f, INFINITY, 7.5f);
    /* the other level-1 texels */
    expect_red(tex, 0.75f, 0.25f, 1.0f, 4.5f);
    expect_red(tex, 0.25f, 0.75f, 1.0f, 10.5f);
    expect_red(tex, 0.75f, 0.75f, 1.0f, 12.5f);
    rast_texture_destroy(tex);
}

Test(texture, mipmap_linear_blends_two_levels)
{
    rast_texture *tex = make_seq_mipmapped(RAST_FILTER_NEAREST_MIPMAP_LINEAR, RAST_FILTER_NEAREST);
    /* s = t = 0.125: level 0 texel (0, 0) = 0, level 1 = 2.5, level 2 = 7.5 */
    expect_red(tex, 0.125f, 0.125f, 0.5f, 1.25f);   /* 0.5 * 0 + 0.5 * 2.5 */
    expect_red(tex, 0.125f, 0.125f, 0.25f, 0.625f); /* 0.75 * 0 + 0.25 * 2.5 */
    expect_red(tex, 0.125f, 0.125f, 1.0f, 2.5f);
    expect_red(tex, 0.125f, 0.125f, 1.25f, 3.75f);  /* 0.75 * 2.5 + 0.25 * 7.5 */
    expect_red(tex, 0.125f, 0.125f, 2.0f, 7.5f);
    expect_red(tex, 0.125f, 0.125f, 9.0f, 7.5f);
    rast_texture_destroy(tex);
}

Test(texture, trilinear_halfway_between_levels)
{
    /* checkerboard, (0,0) white: at the centre of texel (0, 0) bilinear on
       level 0 is exactly 1; level 1 is 0.5 everywhere; lod 0.5 -> 0.75 */
    rast_texture *tex = make_checker(4, RAST_FILTER_LINEAR_MIPMAP_LINEAR);
    float c[4];
    rast_texture_sample_2d(tex, 0.125f, 0.125f, 0.5f, c);
    expect_rgba(c, 0.75f, 0.75f, 0.75f, 0.75f);
    /* the black texel (1, 0): 0.5 * 0 + 0.5 * 0.5 */
    rast_texture_sample_2d(tex, 0.375f, 0.125f, 0.5f, c);
    expect_rgba(c, 0.25f, 0.25f, 0.25f, 0.25f);
    /* lod 1.5 lies between levels 1 and 2, both 0.5 */
    rast_texture_sample_2d(tex, 0.375f, 0.125f, 1.5f, c);
    expect_rgba(c, 0.5f, 0.5f, 0.5f, 0.5f);
    rast_texture_destroy(tex);
}

Test(texture, default_min_filter_with_mipmaps_is_trilinear)
{
    rast_texture *a = make_seq_mipmapped(RAST_FILTER_DEFAULT, RAST_FILTER_DEFAULT);
    rast_texture *b = make_seq_mipmapped(RAST_FILTER_LINEAR_MIPMAP_LINEAR, RAST_FILTER_LINEAR);
    float ca[4], cb[4];
    float lods[] = { -1.0f, 0.0f, 0.3f, 0.5f, 1.2f, 1.7f, 3.0f };
    unsigned i;
    for (i = 0; i < sizeof lods / sizeof lods[0]; ++i) {
        rast_texture_sample_2d(a, 0.3f, 0.6f, lods[i], ca);
        rast_texture_sample_2d(b, 0.3f, 0.6f, lods[i], cb);
        cr_expect(memcmp(ca, cb, sizeof ca) == 0, "lod %g", (double)lods[i]);
    }
    /* by hand at lod 0.5, s = t = 0.125: level 0 bilinear at texel (0,0) = 0;
       level 1 at u - 0.5 = -0.25 with REPEAT: 0.75 * texel 0 + 0.25 * texel 1
       on both axes: 0.5625*2.5 + 0.1875*4.5 + 0.1875*10.5 + 0.0625*12.5 = 5;
       blend 0.5 * 0 + 0.5 * 5 */
    expect_red(a, 0.125f, 0.125f, 0.5f, 2.5f);
    rast_texture_destroy(a);
    rast_texture_destroy(b);
}

Test(texture, odd_sizes_average_covered_texels)
{
    /* 5x1 RGBA32F, red = 0 10 20 30 40. Level 1 is 2x1: texel 0 covers
       source [0, 2.5), texel 1 covers [2.5, 5):
           (0*1 + 10*1 + 20*0.5) / 2.5 = 8,  (20*0.5 + 30 + 40) / 2.5 = 32
       level 2 is 1x1: (8 + 32) / 2 = 20 (also the mean of the five) */
    float px[5 * 4];
    rast_texture_desc d;
    rast_texture *tex;
    int i;
    for (i = 0; i < 5; ++i) {
        px[i * 4 + 0] = (float)(10 * i);
        px[i * 4 + 1] = 1.0f; px[i * 4 + 2] = 2.0f; px[i * 4 + 3] = 3.0f;
    }
    memset(&d, 0, sizeof d);
    d.format = RAST_TEXTURE_RGBA32F;
    d.width = 5; d.height = 1;
    d.pixels[0] = px;
    d.mipmaps = 1;
    d.min_filter = RAST_FILTER_NEAREST_MIPMAP_NEAREST;
    d.mag_filter = RAST_FILTER_NEAREST;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    expect_red(tex, 0.25f, 0.5f, 1.0f, 8.0f);
    expect_red(tex, 0.75f, 0.5f, 1.0f, 32.0f);
    expect_red(tex, 0.5f, 0.5f, 2.0f, 20.0f);
    expect_red(tex, 0.5f, 0.5f, 9.0f, 20.0f);   /* 3 levels only: 5, 2, 1 */
    {   /* constant channels stay exactly constant through odd filtering */
        float c[4];
        rast_texture_sample_2d(tex, 0.75f, 0.5f, 1.0f, c);
        expect_rgba(c, 32.0f, 1.0f, 2.0f, 3.0f);
    }
    rast_texture_destroy(tex);

    /* 3x3 -> 1x1: each axis weighs its 3 texels 1/3: the mean, 4 for 0..8 */
    {
        float p9[9 * 4];
        for (i = 0; i < 9; ++i) {
            p9[i * 4 + 0] = (float)i; p9[i * 4 + 1] = 0.0f; p9[i * 4 + 2] = 0.0f; p9[i * 4 + 3] = 1.0f;
        }
        d.width = d.height = 3;
        d.pixels[0] = p9;
        cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
        expect_red(tex, 0.5f, 0.5f, 0.0f, 4.0f);    /* level 0 centre */
        expect_red(tex, 0.1f, 0.9f, 1.0f, 4.0f);    /* level 1 = 1x1 */
        rast_texture_destroy(tex);
    }
}

Test(texture, non_square_chain_and_largest_size)
{
    /* 16384x1 white: 15 levels (16384 .. 1), all 1.0 */
    uint8_t *px = (uint8_t *)malloc(16384 * 4);
    rast_texture_desc d;
    rast_texture *tex;
    float c[4];
    cr_assert_not_null(px);
    memset(px, 255, 16384 * 4);
    memset(&d, 0, sizeof d);
    d.width = RAST_MAX_TARGET_SIZE; d.height = 1;
    d.pixels[0] = px;
    d.mipmaps = 1;
    d.min_filter = RAST_FILTER_NEAREST_MIPMAP_NEAREST;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    rast_texture_sample_2d(tex, 0.3f, 0.5f, 14.0f, c);
    expect_rgba(c, 1.0f, 1.0f, 1.0f, 1.0f);
    rast_texture_sample_2d(tex, 0.3f, 0.5f, 100.0f, c);
    expect_rgba(c, 1.0f, 1.0f, 1.0f, 1.0f);
    rast_texture_destroy(tex);
    free(px);
}

/* ---- robustness of sampling ---- */

Test(texture, nan_and_inf_coordinates_are_defined)
{
    const rast_filter filters[] = { RAST_FILTER_NEAREST, RAST_FILTER_LINEAR,
                                    RAST_FILTER_LINEAR_MIPMAP_LINEAR, RAST_FILTER_NEAREST_MIPMAP_NEAREST };
    const rast_wrap wraps[] = { RAST_WRAP_REPEAT, RAST_WRAP_CLAMP_TO_EDGE, RAST_WRAP_MIRRORED_REPEAT };
    const float odd[] = { NAN, INFINITY, -INFINITY, FLT_MAX, -FLT_MAX, 1e30f, -1e30f, 0.5f };
    unsigned f, w, i, j, k;
    for (f = 0; f < 4; ++f)
        for (w = 0; w < 3; ++w) {
            rast_texture_desc d;
            rast_texture *tex;
            float c[4];
            fill_ramp();
            memset(&d, 0, sizeof d);
            d.format = RAST_TEXTURE_RGBA32F;
            d.width = d.height = 4;
            d.pixels[0] = ramp4;
            d.mipmaps = 1;
            d.min_filter = filters[f];
            d.mag_filter = RAST_FILTER_LINEAR;
            d.wrap_s = d.wrap_t = wraps[w];
            cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
            for (i = 0; i < 8; ++i)
                for (j = 0; j < 8; ++j)
                    for (k = 0; k < 8; ++k) {
                        rast_texture_sample_2d(tex, odd[i], odd[j], odd[k], c);
                        /* a blend of texels: red and green within [0, 3] */
                        cr_expect(c[0] >= -EPS && c[0] <= 3.0f + EPS && c[1] >= -EPS &&
                                  c[1] <= 3.0f + EPS && fabsf(c[3] - 1.0f) <= EPS, "f%u w%u (%g %g %g) -> %g %g", f, w,
                                  (double)odd[i], (double)odd[j], (double)odd[k],
                                  (double)c[0], (double)c[1]);
                    }
            rast_texture_destroy(tex);
        }
}

Test(texture, nan_coordinate_reads_as_zero)
{
    rast_texture *tex = make_ramp(RAST_FILTER_NEAREST, RAST_FILTER_NEAREST,
                                  RAST_WRAP_CLAMP_TO_EDGE, RAST_WRAP_CLAMP_TO_EDGE);
    float c[4];
    rast_texture_sample_2d(tex, NAN, 0.99f, NAN, c);   /* s = 0, lod = 0 */
    expect_rgba(c, 0.0f, 3.0f, 30.0f, 1.0f);
    rast_texture_sample_2d(tex, INFINITY, -INFINITY, 0.0f, c); /* clamp: right, top */
    expect_rgba(c, 3.0f, 0.0f, 3.0f, 1.0f);
    rast_texture_destroy(tex);
}

Test(texture, null_and_wrong_type_sample_incomplete_black)
{
    rast_texture *tex = make_ramp(RAST_FILTER_NEAREST, RAST_FILTER_NEAREST,
                                  RAST_WRAP_REPEAT, RAST_WRAP_REPEAT);
    float dir[3] = { 1.0f, 0.0f, 0.0f }, c[4] = { 9.0f, 9.0f, 9.0f, 9.0f };
    rast_texture_sample_2d(NULL, 0.5f, 0.5f, 0.0f, c);
    expect_rgba(c, 0.0f, 0.0f, 0.0f, 1.0f);
    c[0] = 9.0f;
    rast_texture_sample_cube(tex, dir, 0.0f, c);   /* a 2D texture */
    expect_rgba(c, 0.0f, 0.0f, 0.0f, 1.0f);
    rast_texture_sample_cube(NULL, dir, 0.0f, c);
    expect_rgba(c, 0.0f, 0.0f, 0.0f, 1.0f);
    rast_texture_destroy(tex);
    rast_texture_destroy(NULL);
}

/* ---- cube maps ---- */

static void expect_face(float x, float y, float z, int face, float s, float t)
{
    float dir[3], gs = -1.0f, gt = -1.0f;
    int got;
    dir[0] = x; dir[1] = y; dir[2] = z;
    got = rast_cube_face(dir, &gs, &gt);
    cr_expect(got == face && fabsf(gs - s) <= EPS && fabsf(gt - t) <= EPS,
              "(%g %g %g): face %d s %g t %g, want face %d s %g t %g",
              (double)x, (double)y, (double)z, got, (double)gs, (double)gt,
              face, (double)s, (double)t);
}

Test(texture_cube, axis_directions)
{
    expect_face(1.0f, 0.0f, 0.0f, 0, 0.5f, 0.5f);
    expect_face(-1.0f, 0.0f, 0.0f, 1, 0.5f, 0.5f);
    expect_face(0.0f, 1.0f, 0.0f, 2, 0.5f, 0.5f);
    expect_face(0.0f, -1.0f, 0.0f, 3, 0.5f, 0.5f);
    expect_face(0.0f, 0.0f, 1.0f, 4, 0.5f, 0.5f);
    expect_face(0.0f, 0.0f, -1.0f, 5, 0.5f, 0.5f);
    expect_face(0.0f, 0.0f, -1e-20f, 5, 0.5f, 0.5f);
    expect_face(3e20f, 0.0f, 0.0f, 0, 0.5f, 0.5f);
}

Test(texture_cube, table_8_19_off_axis)
{
    /* s = (sc/|ma| + 1) / 2, t = (tc/|ma| + 1) / 2 with, from the table:
       +X: sc = -z, tc = -y   -X: sc = +z, tc = -y
       +Y: sc = +x, tc = +z   -Y: sc = +x, tc = -z
       +Z: sc = +x, tc = -y   -Z: sc = -x, tc = -y */
    expect_face(2.0f, 0.5f, -1.0f, 0, 0.75f, 0.375f);   /* sc 1, tc -0.5, ma 2 */
    expect_face(-2.0f, 0.5f, -1.0f, 1, 0.25f, 0.375f);  /* sc -1, tc -0.5 */
    expect_face(0.5f, 2.0f, -1.0f, 2, 0.625f, 0.25f);   /* sc 0.5, tc -1 */
    expect_face(0.5f, -2.0f, -1.0f, 3, 0.625f, 0.75f);  /* sc 0.5, tc 1 */
    expect_face(0.5f, -1.0f, 2.0f, 4, 0.625f, 0.75f);   /* sc 0.5, tc 1 */
    expect_face(0.5f, -1.0f, -2.0f, 5, 0.375f, 0.75f);  /* sc -0.5, tc 1 */
    /* diagonal-ish: -Y with sc = 0.3, tc = -0.6, ma = 0.9: s = 2/3, t = 1/6 */
    expect_face(0.3f, -0.9f, 0.6f, 3, 2.0f / 3.0f, 1.0f / 6.0f);
    /* +X nearly on the +X/+Y edge: sc = -0.1, tc = -0.99, ma = 1 */
    expect_face(1.0f, 0.99f, 0.1f, 0, 0.45f, 0.005f);
    /* -Z corner region: sc = 0.7, tc = 0.8, ma = 0.9 */
    expect_face(-0.7f, -0.8f, -0.9f, 5, (0.7f / 0.9f + 1.0f) / 2.0f, (0.8f / 0.9f + 1.0f) / 2.0f);
    /* scale does not matter */
    expect_face(200.0f, 50.0f, -100.0f, 0, 0.75f, 0.375f);
}

Test(texture_cube, ties_prefer_z_then_y)
{
    /* llvmpipe's rule (GL leaves it open): z if |z| >= max(|x|, |y|),
       else y if |y| >= |x|, else x */
    expect_face(1.0f, 1.0f, 1.0f, 4, 1.0f, 0.0f);    /* +Z: sc = 1, tc = -1 */
    expect_face(1.0f, 1.0f, 0.0f, 2, 1.0f, 0.5f);    /* +Y: sc = 1, tc = 0 */
    expect_face(-1.0f, 0.0f, -1.0f, 5, 1.0f, 0.5f);  /* -Z: sc = 1, tc = 0 */
    expect_face(0.5f, -1.0f, 1.0f, 4, 0.75f, 1.0f);  /* +Z: sc = 0.5, tc = 1 */
    expect_face(-1.0f, -1.0f, 0.5f, 3, 0.0f, 0.25f); /* -Y: sc = -1, tc = -0.5 */
}

Test(texture_cube, degenerate_directions_are_defined)
{
    float dir[3], s, t;
    int face;
    expect_face(0.0f, 0.0f, 0.0f, 4, 0.5f, 0.5f);     /* zero: centre of +Z */
    expect_face(-0.0f, -0.0f, -0.0f, 4, 0.5f, 0.5f);
    expect_face(NAN, 1.0f, 0.0f, 2, 0.5f, 0.5f);      /* NaN counts as 0 */
    expect_face(INFINITY, 1.0f, 0.0f, 0, 0.5f, 0.5f); /* limit: (1, 0, 0) */
    expect_face(INFINITY, -INFINITY, 5.0f, 3, 1.0f, 0.5f); /* (1, -1, 0) -> -Y */
    dir[0] = NAN; dir[1] = NAN; dir[2] = NAN;
    face = rast_cube_face(dir, &s, &t);
    cr_expect(face == 4 && s == 0.5f && t == 0.5f);
    face = rast_cube_face(NULL, &s, &t);
    cr_expect(face == 4 && s == 0.5f && t == 0.5f);
    dir[0] = 1.0f; dir[1] = 0.0f; dir[2] = 0.0f;
    cr_expect_eq(rast_cube_face(dir, NULL, NULL), 0);
}

/* 2x2 cube, RGBA32F: red = face, green = texel index x + 2y */
static float cube_px[6][2 * 2 * 4];

static rast_texture *make_cube(int size, const float *const faces[6], rast_filter min, rast_filter mag, int mipmaps)
{
    rast_texture_desc d;
    rast_texture *tex = NULL;
    int f;
    memset(&d, 0, sizeof d);
    d.type = RAST_TEXTURE_CUBE;
    d.format = RAST_TEXTURE_RGBA32F;
    d.width = d.height = size;
    for (f = 0; f < 6; ++f) d.pixels[f] = faces[f];
    d.min_filter = min;
    d.mag_filter = mag;
    d.mipmaps = mipmaps;
    d.wrap_s = d.wrap_t = RAST_WRAP_REPEAT; /* ignored: cube maps clamp */
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    return tex;
}

static rast_texture *make_cube2(rast_filter filter)
{
    const float *faces[6];
    int f, i;
    for (f = 0; f < 6; ++f) {
        for (i = 0; i < 4; ++i) {
            cube_px[f][i * 4 + 0] = (float)f;
            cube_px[f][i * 4 + 1] = (float)i;
            cube_px[f][i * 4 + 2] = 0.0f;
            cube_px[f][i * 4 + 3] = 1.0f;
        }
        faces[f] = cube_px[f];
    }
    return make_cube(2, faces, filter, filter, 0);
}

static void expect_cube(const rast_texture *tex, float x, float y, float z, float face, float texel)
{
    float dir[3], c[4];
    dir[0] = x; dir[1] = y; dir[2] = z;
    rast_texture_sample_cube(tex, dir, 0.0f, c);
    cr_expect(fabsf(c[0] - face) <= EPS && fabsf(c[1] - texel) <= EPS,
              "(%g %g %g): face %g texel %g, want %g %g", (double)x, (double)y, (double)z,
              (double)c[0], (double)c[1], (double)face, (double)texel);
}

Test(texture_cube, sample_reads_face_rows_top_first)
{
    rast_texture *tex = make_cube2(RAST_FILTER_NEAREST);
    /* +X, (1, -0.5, 0.5): sc = -0.5, tc = 0.5 -> s 0.25, t 0.75 -> texel (0, 1) = 2 */
    expect_cube(tex, 1.0f, -0.5f, 0.5f, 0.0f, 2.0f);
    /* +X, (1, 0.5, -0.5): s 0.75, t 0.25 -> texel (1, 0) = 1 */
    expect_cube(tex, 1.0f, 0.5f, -0.5f, 0.0f, 1.0f);
    /* -X, (-1, 0.5, -0.5): sc = z = -0.5 -> s 0.25; tc = -0.5 -> t 0.25 -> 0 */
    expect_cube(tex, -1.0f, 0.5f, -0.5f, 1.0f, 0.0f);
    /* +Y, (0.5, 1, 0.5): sc 0.5 tc 0.5 -> (1, 1) = 3 */
    expect_cube(tex, 0.5f, 1.0f, 0.5f, 2.0f, 3.0f);
    /* -Y, (-0.5, -1, 0.5): sc -0.5, tc = -z = -0.5 -> (0, 0) = 0 */
    expect_cube(tex, -0.5f, -1.0f, 0.5f, 3.0f, 0.0f);
    /* +Z, (0.5, 0.5, 1): sc 0.5, tc -0.5 -> (1, 0) = 1 */
    expect_cube(tex, 0.5f, 0.5f, 1.0f, 4.0f, 1.0f);
    /* -Z, (0.5, -0.5, -1): sc = -x = -0.5, tc 0.5 -> (0, 1) = 2 */
    expect_cube(tex, 0.5f, -0.5f, -1.0f, 5.0f, 2.0f);
    rast_texture_destroy(tex);
}

Test(texture_cube, linear_filtering_clamps_to_face_edge)
{
    rast_texture *tex = make_cube2(RAST_FILTER_LINEAR);
    /* +X, (1, -0.5, 0.99): s = 0.005, t = 0.75. u - 0.5 = -0.49 -> texels
       -1 and 0 clamp to column 0; v - 0.5 = 1 -> row 1: texel (0, 1) = 2
       exactly (REPEAT would have mixed in column 1) */
    expect_cube(tex, 1.0f, -0.5f, 0.99f, 0.0f, 2.0f);
    /* +X centre: the four texels equally: (0 + 1 + 2 + 3) / 4 */
    expect_cube(tex, 1.0f, 0.0f, 0.0f, 0.0f, 1.5f);
    rast_texture_destroy(tex);
}

Test(texture_cube, mipmapped_faces_average_per_face)
{
    /* 4x4 faces, face f texel i: red = f * 16 + i; level 2 = mean = 16f + 7.5 */
    static float px[6][16 * 4];
    const float *faces[6];
    rast_texture *tex;
    float dir[3], c[4];
    int f, i;
    static const float dirs[6][3] = { { 1, 0.2f, 0.1f }, { -1, 0.2f, 0.1f }, { 0.2f, 1, 0.1f },
                                      { 0.2f, -1, 0.1f }, { 0.2f, 0.1f, 1 }, { 0.2f, 0.1f, -1 } };
    for (f = 0; f < 6; ++f) {
        for (i = 0; i < 16; ++i) {
            px[f][i * 4 + 0] = (float)(f * 16 + i);
            px[f][i * 4 + 1] = px[f][i * 4 + 2] = 0.0f;
            px[f][i * 4 + 3] = 1.0f;
        }
        faces[f] = px[f];
    }
    tex = make_cube(4, faces, RAST_FILTER_LINEAR_MIPMAP_LINEAR, RAST_FILTER_LINEAR, 1);
    for (f = 0; f < 6; ++f) {
        dir[0] = dirs[f][0]; dir[1] = dirs[f][1]; dir[2] = dirs[f][2];
        rast_texture_sample_cube(tex, dir, 2.0f, c);
        expect_rgba(c, (float)(f * 16) + 7.5f, 0.0f, 0.0f, 1.0f);
    }
    rast_texture_destroy(tex);
}

/* ---- validation ---- */

static void count_free(void *ptr, void *user);

static const uint8_t px_white[16 * 16 * 4] = { 255 };

static rast_texture_desc good_desc(void)
{
    rast_texture_desc d;
    memset(&d, 0, sizeof d);
    d.width = d.height = 4;
    d.pixels[0] = px_white;
    return d;
}

static void expect_create_fails(const rast_texture_desc *d, rast_result want)
{
    rast_texture *tex = (rast_texture *)(uintptr_t)1; /* must be reset to NULL */
    rast_result r = rast_texture_create(d, &tex);
    cr_expect_eq(r, want, "result %d, want %d", (int)r, (int)want);
    cr_expect_null(tex);
}

Test(texture, create_rejects_bad_descs)
{
    rast_texture_desc d = good_desc();
    rast_texture *tex;
    int f;

    cr_expect_eq(rast_texture_create(NULL, &tex), RAST_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(rast_texture_create(&d, NULL), RAST_ERROR_INVALID_ARGUMENT);
    expect_create_fails(NULL, RAST_ERROR_INVALID_ARGUMENT);

    d = good_desc(); d.width = 0;                 expect_create_fails(&d, RAST_ERROR_INVALID_SIZE);
    d = good_desc(); d.height = 0;                expect_create_fails(&d, RAST_ERROR_INVALID_SIZE);
    d = good_desc(); d.width = -4;                expect_create_fails(&d, RAST_ERROR_INVALID_SIZE);
    d = good_desc(); d.height = RAST_MAX_TARGET_SIZE + 1; expect_create_fails(&d, RAST_ERROR_INVALID_SIZE);
    d = good_desc(); d.width = 1 << 30;           expect_create_fails(&d, RAST_ERROR_INVALID_SIZE);
    d = good_desc(); d.stride = 15;               expect_create_fails(&d, RAST_ERROR_INVALID_SIZE);
    d = good_desc(); d.stride = -16;              expect_create_fails(&d, RAST_ERROR_INVALID_SIZE);
    d = good_desc(); d.format = RAST_TEXTURE_RGBA32F; d.stride = 16; /* needs 64 */
    expect_create_fails(&d, RAST_ERROR_INVALID_SIZE);

    d = good_desc(); d.pixels[0] = NULL;          expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);
    d = good_desc(); d.type = (rast_texture_type)7; expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);
    d = good_desc(); d.format = (rast_texture_format)9; expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);
    d = good_desc(); d.format = (rast_texture_format)-1; expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);
    d = good_desc(); d.min_filter = (rast_filter)42; expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);
    d = good_desc(); d.mag_filter = RAST_FILTER_LINEAR_MIPMAP_LINEAR; /* GL: INVALID_ENUM */
    expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);
    d = good_desc(); d.wrap_s = (rast_wrap)9;     expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);
    d = good_desc(); d.wrap_t = (rast_wrap)-3;    expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);
    d = good_desc(); d.allocator.alloc = NULL; d.allocator.free = count_free; /* half an allocator */
    expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);

    /* cube maps: six square faces */
    d = good_desc(); d.type = RAST_TEXTURE_CUBE;
    for (f = 0; f < 6; ++f) d.pixels[f] = px_white;
    cr_expect_eq(rast_texture_create(&d, &tex), RAST_OK);
    rast_texture_destroy(tex);
    d.height = 2;                                 expect_create_fails(&d, RAST_ERROR_INVALID_SIZE);
    d.height = 4; d.pixels[5] = NULL;             expect_create_fails(&d, RAST_ERROR_INVALID_ARGUMENT);
    d.pixels[5] = px_white; d.wrap_s = (rast_wrap)9; /* ignored for cubes */
    cr_expect_eq(rast_texture_create(&d, &tex), RAST_OK);
    rast_texture_destroy(tex);

    /* the limits themselves are fine */
    d = good_desc(); d.width = 1; d.height = 1; d.stride = 1000;
    cr_expect_eq(rast_texture_create(&d, &tex), RAST_OK);
    rast_texture_destroy(tex);
}

/* ---- allocation ---- */

typedef struct counting_alloc {
    int allocs, frees, fail_at; /* fail_at: 1-based allocation to refuse; 0: never */
    size_t bytes;
} counting_alloc;

static void *count_alloc(size_t size, void *user)
{
    counting_alloc *c = (counting_alloc *)user;
    if (c->fail_at && c->allocs + 1 == c->fail_at) {
        c->fail_at = -1; /* only that one */
        return NULL;
    }
    c->allocs++;
    c->bytes += size;
    return malloc(size);
}

static void count_free(void *ptr, void *user)
{
    counting_alloc *c = (counting_alloc *)user;
    if (ptr) c->frees++;
    free(ptr);
}

Test(texture, allocation_goes_through_desc_allocator)
{
    counting_alloc c = { 0, 0, 0, 0 };
    rast_texture_desc d = good_desc();
    rast_texture *tex;
    d.mipmaps = 1;
    d.allocator.alloc = count_alloc;
    d.allocator.free = count_free;
    d.allocator.user = &c;
    cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
    cr_expect_gt(c.allocs, 0);
    /* 4x4 + 2x2 + 1x1 texels of 16 bytes at least */
    cr_expect_geq(c.bytes, (size_t)21 * 16);
    rast_texture_destroy(tex);
    cr_expect_eq(c.allocs, c.frees);
}

Test(texture, allocation_failure_at_every_step_leaks_nothing)
{
    int types, n;
    for (types = 0; types < 2; ++types) {
        for (n = 1;; ++n) {
            counting_alloc c = { 0, 0, 0, 0 };
            rast_texture_desc d = good_desc();
            rast_texture *tex = NULL;
            rast_result r;
            int f;
            if (types == 1) {
                d.type = RAST_TEXTURE_CUBE;
                for (f = 0; f < 6; ++f) d.pixels[f] = px_white;
            }
            d.mipmaps = 1;
            c.fail_at = n;
            d.allocator.alloc = count_alloc;
            d.allocator.free = count_free;
            d.allocator.user = &c;
            r = rast_texture_create(&d, &tex);
            if (c.fail_at != -1) { /* the n-th allocation never happened: done */
                cr_assert_eq(r, RAST_OK);
                rast_texture_destroy(tex);
                cr_expect_eq(c.allocs, c.frees);
                cr_expect_gt(n, 1);
                break;
            }
            cr_expect_eq(r, RAST_ERROR_OUT_OF_MEMORY, "failing allocation %d", n);
            cr_expect_null(tex);
            cr_expect_eq(c.allocs, c.frees, "failing allocation %d: %d allocs, %d frees",
                         n, c.allocs, c.frees);
            cr_assert_lt(n, 100);
        }
    }
}

Test(texture, texture_keeps_its_allocator)
{
    /* the desc (and its allocator struct) may go away before destroy */
    counting_alloc c = { 0, 0, 0, 0 };
    rast_texture *tex;
    {
        rast_texture_desc d = good_desc();
        d.allocator.alloc = count_alloc;
        d.allocator.free = count_free;
        d.allocator.user = &c;
        cr_assert_eq(rast_texture_create(&d, &tex), RAST_OK);
        memset(&d, 0, sizeof d);
    }
    rast_texture_destroy(tex);
    cr_expect_gt(c.frees, 0);
    cr_expect_eq(c.allocs, c.frees);
}
