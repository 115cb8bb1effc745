/* Image I/O (tools/image_io.h): PNG and EXR round trips of known patterns,
   the HDR environment maps of ../shared/assets/env, six-face cube maps,
   errors on missing and corrupt files, and the image comparison. */
#define _XOPEN_SOURCE 700
#include <criterion/criterion.h>

#include <dirent.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../../reflect.h"
#include "../../tools/image_io.h"

#define ENV_DIR "../shared/assets/env" /* tests run from the repository root */

static void ti_mkdtemp(char *dir, size_t n) {
    snprintf(dir, n, "/tmp/refl_image_XXXXXX");
    cr_assert(mkdtemp(dir), "mkdtemp failed");
}

static void ti_rmdir(const char *dir) {
    DIR *d = opendir(dir);
    struct dirent *e;
    char path[1024];
    if (!d) return;
    while ((e = readdir(d)) != NULL) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        unlink(path);
    }
    closedir(d);
    rmdir(dir);
}

static void ti_write_bytes(const char *path, const void *data, size_t size) {
    FILE *f = fopen(path, "wb");
    cr_assert(f, "cannot create %s", path);
    cr_assert_eq(fwrite(data, 1, size, f), size);
    fclose(f);
}

static unsigned char *ti_read_bytes(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    unsigned char *d;
    long n;
    cr_assert(f, "cannot open %s", path);
    fseek(f, 0, SEEK_END);
    n = ftell(f);
    fseek(f, 0, SEEK_SET);
    d = malloc((size_t)n + 1);
    *size = fread(d, 1, (size_t)n, f);
    fclose(f);
    return d;
}

static double ti_srgb_to_linear(double c) { return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4); }
static double ti_linear_to_srgb(double c) { return c <= 0.0031308 ? c * 12.92 : 1.055 * pow(c, 1 / 2.4) - 0.055; }

/* A W x H RGBA8 pattern where every channel value and position differ. */
enum { W = 37, H = 23 };
static void ti_pattern8(uint8_t *p) {
    int i;
    for (i = 0; i < W * H * 4; i++) p[i] = (uint8_t)((i * 7 + i / 13) & 255);
}

/* ---- PNG ------------------------------------------------------------------------ */

Test(image_io, png_round_trip) {
    char dir[64], path[128], err[512];
    uint8_t src[W * H * 4], *back = NULL;
    refl_image img;
    int w, h, i, bad = -1;
    ti_mkdtemp(dir, sizeof dir);
    ti_pattern8(src);
    snprintf(path, sizeof path, "%s/pattern.png", dir);
    cr_assert_eq(refl_image_write(path, W, H, 4, src, NULL, err, sizeof err), REFL_OK, "%s", err);

    /* as stored: exact, alpha not premultiplied */
    cr_assert_eq(refl_image_read_rgba8(path, &w, &h, &back, NULL, err, sizeof err), REFL_OK, "%s", err);
    cr_assert(w == W && h == H);
    cr_expect(memcmp(back, src, sizeof src) == 0, "8-bit PNG round trip is exact");
    free(back);

    /* as linear floats: sRGB decoded, alpha as stored */
    cr_assert_eq(refl_image_read(path, &img, NULL, err, sizeof err), REFL_OK, "%s", err);
    cr_assert(img.width == W && img.height == H);
    for (i = 0; i < W * H * 4 && bad < 0; i++) {
        double want = i % 4 == 3 ? src[i] / 255.0 : ti_srgb_to_linear(src[i] / 255.0);
        if (fabs(img.pixels[i] - want) > 1e-5) bad = i;
    }
    cr_expect(bad < 0, "value %d: %g, want sRGB-decoded %d", bad, bad < 0 ? 0 : img.pixels[bad],
              bad < 0 ? 0 : src[bad]);

    /* linear floats written to PNG and read back: within 1/255 after the
       sRGB round trip */
    snprintf(path, sizeof path, "%s/linear.png", dir);
    cr_assert_eq(refl_image_write(path, W, H, 4, NULL, img.pixels, err, sizeof err), REFL_OK, "%s", err);
    {
        refl_image again;
        cr_assert_eq(refl_image_read(path, &again, NULL, err, sizeof err), REFL_OK, "%s", err);
        for (i = 0, bad = -1; i < W * H * 4 && bad < 0; i++) {
            double a = img.pixels[i], b = again.pixels[i];
            if (i % 4 != 3) a = ti_linear_to_srgb(a), b = ti_linear_to_srgb(b);
            if (fabs(a - b) > 1.0 / 255 + 1e-6) bad = i;
        }
        cr_expect(bad < 0, "value %d differs by more than 1/255 after the round trip", bad);
        refl_image_free(&again, NULL);
    }
    refl_image_free(&img, NULL);
    cr_expect_null(img.pixels);
    ti_rmdir(dir);
}

/* 1 and 2 channels: grey to R, G, B; alpha 1 when absent. */
Test(image_io, grey_and_grey_alpha) {
    char dir[64], path[128], err[512];
    uint8_t g[W * H * 2], *back;
    int w, h, i, bad = -1;
    ti_mkdtemp(dir, sizeof dir);
    for (i = 0; i < W * H * 2; i++) g[i] = (uint8_t)(i * 5);
    snprintf(path, sizeof path, "%s/grey.png", dir);
    cr_assert_eq(refl_image_write(path, W, H, 1, g, NULL, err, sizeof err), REFL_OK, "%s", err);
    cr_assert_eq(refl_image_read_rgba8(path, &w, &h, &back, NULL, err, sizeof err), REFL_OK, "%s", err);
    for (i = 0; i < W * H && bad < 0; i++)
        if (back[4 * i] != g[i] || back[4 * i + 1] != g[i] || back[4 * i + 2] != g[i] || back[4 * i + 3] != 255) bad = i;
    cr_expect(bad < 0, "grey pixel %d", bad);
    free(back);
    snprintf(path, sizeof path, "%s/grey_alpha.png", dir);
    cr_assert_eq(refl_image_write(path, W, H, 2, g, NULL, err, sizeof err), REFL_OK, "%s", err);
    cr_assert_eq(refl_image_read_rgba8(path, &w, &h, &back, NULL, err, sizeof err), REFL_OK, "%s", err);
    for (i = 0, bad = -1; i < W * H && bad < 0; i++)
        if (back[4 * i] != g[2 * i] || back[4 * i + 2] != g[2 * i] || back[4 * i + 3] != g[2 * i + 1]) bad = i;
    cr_expect(bad < 0, "grey+alpha pixel %d", bad);
    free(back);
    ti_rmdir(dir);
}

/* ---- EXR ------------------------------------------------------------------------ */

Test(image_io, exr_float_round_trip_is_exact) {
    char dir[64], path[128], err[512];
    static float src[W * H * 4];
    refl_image img;
    int i;
    ti_mkdtemp(dir, sizeof dir);
    for (i = 0; i < W * H * 4; i++) src[i] = (float)(sin(i * 0.37) * 3.0 + (i % 4 == 3 ? 3.0 : 0.0)) * 1.2345f;
    src[5] = 1e-30f;
    src[6] = 65504.0f * 4;
    snprintf(path, sizeof path, "%s/pattern.exr", dir);
    cr_assert_eq(refl_image_write(path, W, H, 4, NULL, src, err, sizeof err), REFL_OK, "%s", err);
    cr_assert_eq(refl_image_read(path, &img, NULL, err, sizeof err), REFL_OK, "%s", err);
    cr_assert(img.width == W && img.height == H);
    cr_expect(memcmp(img.pixels, src, sizeof src) == 0, "float EXR round trip is bit exact");
    refl_image_free(&img, NULL);

    /* three channels: alpha 1 */
    {
        static float rgb[W * H * 3];
        int bad = -1;
        for (i = 0; i < W * H * 3; i++) rgb[i] = (float)i * 0.25f;
        snprintf(path, sizeof path, "%s/rgb.exr", dir);
        cr_assert_eq(refl_image_write(path, W, H, 3, NULL, rgb, err, sizeof err), REFL_OK, "%s", err);
        cr_assert_eq(refl_image_read(path, &img, NULL, err, sizeof err), REFL_OK, "%s", err);
        for (i = 0; i < W * H && bad < 0; i++)
            if (img.pixels[4 * i] != rgb[3 * i] || img.pixels[4 * i + 2] != rgb[3 * i + 2] || img.pixels[4 * i + 3] != 1.0f)
                bad = i;
        cr_expect(bad < 0, "rgb EXR pixel %d", bad);
        refl_image_free(&img, NULL);
    }
    /* 8-bit data written as EXR is decoded to linear */
    {
        uint8_t p8[W * H * 4];
        ti_pattern8(p8);
        snprintf(path, sizeof path, "%s/from8.exr", dir);
        cr_assert_eq(refl_image_write(path, W, H, 4, p8, NULL, err, sizeof err), REFL_OK, "%s", err);
        cr_assert_eq(refl_image_read(path, &img, NULL, err, sizeof err), REFL_OK, "%s", err);
        cr_expect_float_eq(img.pixels[1], (float)ti_srgb_to_linear(p8[1] / 255.0), 1e-6f);
        cr_expect_float_eq(img.pixels[3], p8[3] / 255.0f, 1e-6f);
        refl_image_free(&img, NULL);
    }
    ti_rmdir(dir);
}

/* ---- environment maps ------------------------------------------------------------ */

static void need_env(void) {
    struct stat st;
    if (stat(ENV_DIR, &st) != 0 || !S_ISDIR(st.st_mode))
        cr_skip_test("%s is absent: the environment map tests need the shared assets", ENV_DIR);
}

Test(image_io, hdr_environment_maps) {
    static const char *files[] = {ENV_DIR "/dresden_square_1k.hdr", ENV_DIR "/studio_small_03_1k.hdr"};
    static const double max_readme[] = {59, 3568}, mean_readme[] = {1.39, 1.88};
    size_t f;
    need_env();
    for (f = 0; f < 2; f++) {
        refl_image img;
        refl_environment env;
        char err[512];
        double sum = 0, max = 0;
        int i, finite = 1;
        cr_assert_eq(refl_image_read(files[f], &img, NULL, err, sizeof err), REFL_OK, "%s", err);
        cr_expect_eq(img.width, 1024);
        cr_expect_eq(img.height, 512);
        for (i = 0; i < img.width * img.height * 4; i++) {
            float v = img.pixels[i];
            finite &= isfinite(v) && v >= 0;
            if (i % 4 == 3) {
                finite &= v == 1.0f;
                continue;
            }
            sum += v;
            if (v > max) max = v;
        }
        cr_expect(finite, "%s: finite, non-negative, alpha 1", files[f]);
        /* the README's max and mean (over R, G, B), as HDR linear values */
        cr_expect(fabs(max - max_readme[f]) < 0.02 * max_readme[f], "%s: max %g", files[f], max);
        cr_expect(fabs(sum / (img.width * img.height * 3.0) - mean_readme[f]) < 0.02 * mean_readme[f],
                  "%s: mean %g", files[f], sum / (img.width * img.height * 3.0));
        refl_image_free(&img, NULL);

        cr_assert_eq(refl_env_load(files[f], &env, NULL, err, sizeof err), REFL_OK, "%s", err);
        cr_expect_eq(env.type, REFL_ENV_EQUIRECT);
        cr_expect(env.image.width == 1024 && env.image.height == 512 && env.image.pixels);
        refl_env_free(&env, NULL);
        cr_expect_null(env.image.pixels);
    }
}

static int ti_allocs;
static void *ti_alloc(size_t n, void *user) { (void)user; ti_allocs++; return malloc(n); }
static void ti_free(void *p, void *user) { (void)user; ti_allocs--; free(p); }

Test(image_io, cube_faces_from_a_pattern) {
    static const char *faces[6] = {"px", "nx", "py", "ny", "pz", "nz"};
    char dir[64], path[160], pattern[160], err[512];
    float face[8 * 8 * 3];
    refl_environment env;
    refl_allocator a = {ti_alloc, ti_free, NULL};
    int f, i;
    ti_mkdtemp(dir, sizeof dir);
    for (f = 0; f < 6; f++) {
        for (i = 0; i < 8 * 8 * 3; i++) face[i] = (float)f + (float)i / 256.0f;
        snprintf(path, sizeof path, "%s/sky_%s.exr", dir, faces[f]);
        cr_assert_eq(refl_image_write(path, 8, 8, 3, NULL, face, err, sizeof err), REFL_OK, "%s", err);
    }
    snprintf(pattern, sizeof pattern, "%s/sky_%%s.exr", dir);
    cr_assert_eq(refl_env_load(pattern, &env, &a, err, sizeof err), REFL_OK, "%s", err);
    cr_expect_eq(env.type, REFL_ENV_CUBE);
    cr_expect_eq(ti_allocs, 6);
    for (f = 0; f < 6; f++) {
        cr_expect(env.faces[f].width == 8 && env.faces[f].height == 8);
        cr_expect_float_eq(env.faces[f].pixels[0], (float)f, 1e-6f, "face %s in GL order", faces[f]);
        cr_expect_float_eq(env.faces[f].pixels[4 * 63 + 2], (float)f + 191.0f / 256.0f, 1e-6f);
    }
    refl_env_free(&env, &a);
    cr_expect_eq(ti_allocs, 0);

    /* one face of another size, then one missing: errors naming that face */
    snprintf(path, sizeof path, "%s/sky_pz.exr", dir);
    cr_assert_eq(refl_image_write(path, 4, 4, 3, NULL, face, err, sizeof err), REFL_OK, "%s", err);
    cr_expect_eq(refl_env_load(pattern, &env, &a, err, sizeof err), REFL_ERROR_INVALID_SIZE);
    cr_expect(strstr(err, "sky_pz.exr") != NULL, "message: %s", err);
    cr_expect_eq(ti_allocs, 0, "nothing allocated on error");
    unlink(path);
    cr_expect_eq(refl_env_load(pattern, &env, &a, err, sizeof err), REFL_ERROR_UNKNOWN_NAME);
    cr_expect(strstr(err, "sky_pz.exr") != NULL, "message: %s", err);
    cr_expect_eq(env.type, REFL_ENV_COLOR, "zeroed on error");

    /* an equirectangular map must be 2:1 */
    snprintf(path, sizeof path, "%s/square.exr", dir);
    cr_assert_eq(refl_image_write(path, 8, 8, 3, NULL, face, err, sizeof err), REFL_OK, "%s", err);
    cr_expect_eq(refl_env_load(path, &env, NULL, err, sizeof err), REFL_ERROR_INVALID_SIZE);
    cr_expect(strstr(err, "square.exr") && strstr(err, "8x8"), "message: %s", err);
    ti_rmdir(dir);
}

/* ---- errors ----------------------------------------------------------------------- */

static void expect_read_error(const char *path, const char *name) {
    char err[512] = "";
    refl_image img;
    uint8_t *p8 = (uint8_t *)1;
    int w, h;
    refl_result r = refl_image_read(path, &img, NULL, err, sizeof err);
    cr_expect_neq(r, REFL_OK, "%s read", path);
    cr_expect_null(img.pixels);
    cr_expect(strstr(err, name) != NULL, "message '%s' does not name %s", err, name);
    r = refl_image_read_rgba8(path, &w, &h, &p8, NULL, err, sizeof err);
    cr_expect_neq(r, REFL_OK, "%s read as rgba8", path);
    cr_expect_null(p8);
    cr_expect(strstr(err, name) != NULL, "message '%s' does not name %s", err, name);
}

Test(image_io, missing_corrupt_and_truncated_files) {
    char dir[64], path[160], err[512];
    uint8_t p8[W * H * 4];
    static float pf[W * H * 4];
    static const char *exts[] = {"png", "exr", "hdr"};
    refl_image img;
    size_t e;
    ti_mkdtemp(dir, sizeof dir);
    cr_expect_eq(refl_image_read("/nonexistent/no_such_image.png", &img, NULL, err, sizeof err), REFL_ERROR_UNKNOWN_NAME);
    cr_expect(strstr(err, "no_such_image.png") != NULL, "%s", err);
    expect_read_error("/nonexistent/no_such_image.exr", "no_such_image.exr");

    snprintf(path, sizeof path, "%s/garbage.png", dir);
    ti_write_bytes(path, "this is not a PNG file at all, just text\n", 41);
    expect_read_error(path, "garbage.png");
    snprintf(path, sizeof path, "%s/empty.exr", dir);
    ti_write_bytes(path, "", 0);
    expect_read_error(path, "empty.exr");

    /* valid files cut in half, and with a byte in the middle changed */
    ti_pattern8(p8);
    for (e = 0; e < W * H * 4; e++) pf[e] = (float)e;
    for (e = 0; e < 3; e++) {
        char cut[160];
        unsigned char *bytes;
        size_t size;
        snprintf(path, sizeof path, "%s/whole.%s", dir, exts[e]);
        cr_assert_eq(refl_image_write(path, W, H, 4, e == 0 ? p8 : NULL, e == 0 ? NULL : pf, err, sizeof err), REFL_OK,
                     "%s", err);
        bytes = ti_read_bytes(path, &size);
        snprintf(cut, sizeof cut, "%s/cut.%s", dir, exts[e]);
        ti_write_bytes(cut, bytes, size / 2);
        expect_read_error(cut, cut + strlen(dir) + 1);
        /* a byte in the middle changed: a PNG's CRC catches it; EXR and HDR
           pixel data may just read differently, but must not crash */
        bytes[size / 2] ^= 0x5A;
        snprintf(cut, sizeof cut, "%s/flip.%s", dir, exts[e]);
        ti_write_bytes(cut, bytes, size);
        if (e == 0) {
            expect_read_error(cut, "flip.png");
            cr_expect_eq(refl_image_read(cut, &img, NULL, err, sizeof err), REFL_ERROR_BAD_MESH);
            cr_expect(strstr(err, "bad CRC") != NULL, "%s", err);
        } else if (refl_image_read(cut, &img, NULL, err, sizeof err) == REFL_OK) {
            refl_image_free(&img, NULL);
        } else {
            cr_expect(strstr(err, "flip.") != NULL, "%s", err);
        }
        free(bytes);
    }
    /* writing: unknown format, bad arguments */
    snprintf(path, sizeof path, "%s/x.nosuchformat", dir);
    cr_expect_eq(refl_image_write(path, W, H, 4, p8, NULL, err, sizeof err), REFL_ERROR_UNKNOWN_NAME);
    cr_expect(strstr(err, "x.nosuchformat") != NULL, "%s", err);
    cr_expect_eq(refl_image_write("/nonexistent/dir/out.png", W, H, 4, p8, NULL, err, sizeof err), REFL_ERROR_UNKNOWN_NAME);
    cr_expect(strstr(err, "out.png") != NULL, "%s", err);
    cr_expect_eq(refl_image_write(path, W, H, 4, NULL, NULL, err, sizeof err), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_image_write(path, W, H, 4, p8, pf, err, sizeof err), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_image_write(path, W, H, 5, p8, NULL, err, sizeof err), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_image_write(path, 0, H, 4, p8, NULL, err, sizeof err), REFL_ERROR_INVALID_SIZE);
    cr_expect_eq(refl_image_read(NULL, &img, NULL, err, sizeof err), REFL_ERROR_INVALID_ARGUMENT);
    ti_rmdir(dir);
}

/* ---- comparison -------------------------------------------------------------------- */

Test(image_io, compare_known_differences) {
    enum { N = 10 };
    uint8_t a[N * N * 4], b[N * N * 4];
    refl_image_diff d;
    char dir[64], pa[128], pb[128], err[512];
    memset(a, 100, sizeof a);
    memcpy(b, a, sizeof a);
    cr_assert_eq(refl_image_compare(a, b, N, N, 0.0, &d), REFL_OK);
    cr_expect_eq(d.rmse, 0.0);
    cr_expect(isinf(d.psnr) && d.psnr > 0);
    cr_expect_eq(d.pixels_over, 0);

    b[4 * 7 + 1] = 151; /* one channel of one pixel off by 51 = 0.2 */
    b[4 * 8 + 3] = 0;   /* alpha is ignored */
    cr_assert_eq(refl_image_compare(a, b, N, N, 0.1, &d), REFL_OK);
    cr_expect_float_eq(d.rmse, sqrt(51.0 * 51.0 / (N * N * 3)) / 255.0, 1e-12);
    cr_expect_float_eq(d.psnr, 20 * log10(1 / d.rmse), 1e-9);
    cr_expect_float_eq(d.max_error, 0.2, 1e-12);
    cr_expect_eq(d.pixels_over, 1);
    cr_expect_float_eq(d.fraction_over, 0.01, 1e-12);
    cr_assert_eq(refl_image_compare(a, b, N, N, 0.25, &d), REFL_OK);
    cr_expect_eq(d.pixels_over, 0);
    cr_expect_eq(refl_image_compare(a, NULL, N, N, 0.1, &d), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_image_compare(a, b, 0, N, 0.1, &d), REFL_ERROR_INVALID_SIZE);

    /* the same through files */
    ti_mkdtemp(dir, sizeof dir);
    snprintf(pa, sizeof pa, "%s/a.png", dir);
    snprintf(pb, sizeof pb, "%s/b.png", dir);
    cr_assert_eq(refl_image_write(pa, N, N, 4, a, NULL, err, sizeof err), REFL_OK, "%s", err);
    cr_assert_eq(refl_image_write(pb, N, N, 4, b, NULL, err, sizeof err), REFL_OK, "%s", err);
    cr_assert_eq(refl_image_compare_files(pa, pb, 0.1, &d, err, sizeof err), REFL_OK, "%s", err);
    cr_expect_eq(d.pixels_over, 1);
    cr_expect_float_eq(d.max_error, 0.2, 1e-12);
    cr_assert_eq(refl_image_write(pb, N, N / 2, 4, b, NULL, err, sizeof err), REFL_OK, "%s", err);
    cr_expect_eq(refl_image_compare_files(pa, pb, 0.1, &d, err, sizeof err), REFL_ERROR_INVALID_SIZE);
    cr_expect(strstr(err, "b.png") != NULL, "%s", err);
    snprintf(pb, sizeof pb, "%s/missing.png", dir);
    cr_expect_eq(refl_image_compare_files(pa, pb, 0.1, &d, err, sizeof err), REFL_ERROR_UNKNOWN_NAME);
    cr_expect(strstr(err, "missing.png") != NULL, "%s", err);
    ti_rmdir(dir);
}
