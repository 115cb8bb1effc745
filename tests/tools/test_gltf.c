/* glTF loading (tools/gltf_load.h): every asset in ../shared/assets loads
   with the triangle counts and scene-space bounds of its README, materials
   are classified (mirror, glass), textures decoded, cameras found; malformed
   input (missing, truncated, byte-flipped, hand-written bad files) gives an
   error naming the file, never a crash (this suite also runs under
   ASan/UBSan in `make test`, which catches leaks and overruns). */
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
#include "../../tools/gltf_load.h"

/* Tests run from the repository root. */
#define ASSETS "../shared/assets"

static void need_assets(void) {
    struct stat st;
    if (stat(ASSETS, &st) != 0 || !S_ISDIR(st.st_mode))
        cr_skip_test("%s is absent: the asset tests need the shared assets next to the repository", ASSETS);
}

/* ---- small helpers ---------------------------------------------------------- */

typedef struct tg_bytes {
    unsigned char *data;
    size_t size;
} tg_bytes;

static tg_bytes tg_read(const char *path) {
    tg_bytes b = {NULL, 0};
    FILE *f = fopen(path, "rb");
    long n;
    cr_assert(f, "cannot open %s", path);
    fseek(f, 0, SEEK_END);
    n = ftell(f);
    fseek(f, 0, SEEK_SET);
    b.data = malloc((size_t)n + 1);
    cr_assert(b.data);
    b.size = fread(b.data, 1, (size_t)n, f);
    fclose(f);
    cr_assert_eq(b.size, (size_t)n);
    return b;
}

static void tg_write(const char *path, const void *data, size_t size) {
    FILE *f = fopen(path, "wb");
    cr_assert(f, "cannot create %s", path);
    cr_assert_eq(fwrite(data, 1, size, f), size);
    fclose(f);
}

/* A fresh directory under /tmp, removed with its files by tg_rmdir. */
static void tg_mkdtemp(char *dir, size_t n) {
    snprintf(dir, n, "/tmp/refl_gltf_XXXXXX");
    cr_assert(mkdtemp(dir), "mkdtemp failed");
}

static void tg_rmdir(const char *dir) {
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

/* Exact scene-space bounds: every vertex through its object's transform. */
static void tg_bounds(const refl_scene *s, double lo[3], double hi[3]) {
    int o, v, c;
    for (c = 0; c < 3; c++) lo[c] = INFINITY, hi[c] = -INFINITY;
    for (o = 0; o < s->object_count; o++) {
        const refl_mesh *m = s->meshes[s->objects[o].mesh];
        const float *t = s->objects[o].transform.m;
        for (v = 0; v < m->vertex_count; v++) {
            const float *p = m->positions + 3 * v;
            for (c = 0; c < 3; c++) {
                double x = (double)t[c] * p[0] + (double)t[4 + c] * p[1] + (double)t[8 + c] * p[2] + t[12 + c];
                if (x < lo[c]) lo[c] = x;
                if (x > hi[c]) hi[c] = x;
            }
        }
    }
}

static long long tg_triangles(const refl_scene *s) {
    long long n = 0;
    int o;
    for (o = 0; o < s->object_count; o++) n += s->meshes[s->objects[o].mesh]->triangle_count;
    return n;
}

static const refl_material *tg_material(const refl_scene *s, const char *name) {
    int i;
    for (i = 0; i < s->material_count; i++)
        if (!strcmp(s->materials[i].name, name)) return &s->materials[i];
    return NULL;
}

static int tg_count_type(const refl_scene *s, refl_material_type t) {
    int i, n = 0;
    for (i = 0; i < s->material_count; i++) n += s->materials[i].type == t;
    return n;
}

/* Whether every warning line is one of the loader's "not drawn: FEATURE"
   notes (the assets use glTF features the renderer ignores). */
static int only_not_drawn_lines(const char *err) {
    while (*err) {
        const char *end = strchr(err, '\n');
        const char *hit = strstr(err, ": not drawn: ");
        if (!end || !hit || hit > end) return 0;
        err = end + 1;
    }
    return 1;
}

static refl_scene *tg_load(const char *file, float normalize) {
    char path[512], err[1024];
    refl_scene *s = NULL;
    refl_gltf_options opt;
    refl_result r;
    memset(&opt, 0, sizeof opt);
    opt.normalize_size = normalize;
    snprintf(path, sizeof path, "%s/%s", ASSETS, file);
    r = refl_gltf_load(path, &opt, &s, err, sizeof err);
    cr_assert_eq(r, REFL_OK, "%s: %d (%s)", path, r, err);
    cr_assert(s);
    cr_expect(only_not_drawn_lines(err), "warnings for %s: %s", path, err);
    return s;
}

/* ---- every asset: counts and bounds from the assets README ------------------ */

typedef struct tg_asset {
    const char *file;
    long long triangles; /* in the scene, instances counted */
    double lo[3], hi[3]; /* scene space */
} tg_asset;

static const tg_asset tg_assets[] = {
    {"teapot.glb", 4032, {-3, 0, -2}, {3.433, 3.15, 2}},
    {"bunny.glb", 69451, {-0.09469, 0.03299, -0.06187}, {0.06101, 0.1873, 0.0588}},
    {"bunny_10k.glb", 9999, {-0.09459, 0.03299, -0.06181}, {0.06092, 0.1873, 0.05879}},
    {"xyzrgb_dragon_100k.glb", 100000, {-98.67, -41.3, -57.25}, {103.1, 49.26, 76.86}},
    {"Box.glb", 12, {-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}},
    {"Duck.glb", 4212, {-0.693, 0.09929, -0.6133}, {0.9618, 1.64, 0.5393}},
    {"Suzanne.glb", 3936, {-1.337, -0.9746, -0.8008}, {1.337, 0.9502, 0.8257}},
    {"MetalRoughSpheresNoTextures.glb", 1040409, {-0.0009243, -0.00101, -0.00335}, {0.006477, 0.006494, 0.00035}},
    {"WaterBottle.glb", 4510, {-0.05445, -0.1302, -0.05445}, {0.05445, 0.1302, 0.05445}},
    {"TransmissionTest.glb", 128775, {-0.9764, -0.4, -0.521}, {0.8262, 0.6205, 1.368}},
    {"AttenuationTest.glb", 292, {-10, -10, -2}, {10, 10, 2}},
    {"ToyCar.glb", 108936, {-0.035, -0.01621, -0.03698}, {0.03845, 0.01262, 0.03698}},
};

Test(gltf, every_asset_loads_with_readme_counts_and_bounds) {
    size_t i;
    int c;
    need_assets();
    for (i = 0; i < sizeof tg_assets / sizeof tg_assets[0]; i++) {
        const tg_asset *a = &tg_assets[i];
        refl_scene *s = tg_load(a->file, 0);
        double lo[3], hi[3], diag = 0;
        tg_bounds(s, lo, hi);
        cr_expect_eq(tg_triangles(s), a->triangles, "%s: %lld triangles, README %lld", a->file, tg_triangles(s),
                     a->triangles);
        cr_expect_eq(refl_scene_triangles(s), a->triangles, "%s: refl_scene_triangles", a->file);
        for (c = 0; c < 3; c++) diag += (a->hi[c] - a->lo[c]) * (a->hi[c] - a->lo[c]);
        diag = sqrt(diag);
        for (c = 0; c < 3; c++) {
            /* the README rounds to 4 significant digits */
            cr_expect(fabs(lo[c] - a->lo[c]) <= 1e-3 * fabs(a->lo[c]) + 1e-6 * diag,
                      "%s: min[%d] = %.7g, README %.7g", a->file, c, lo[c], a->lo[c]);
            cr_expect(fabs(hi[c] - a->hi[c]) <= 1e-3 * fabs(a->hi[c]) + 1e-6 * diag,
                      "%s: max[%d] = %.7g, README %.7g", a->file, c, hi[c], a->hi[c]);
        }
        cr_expect_eq(s->light_count, 0, "%s has no lights", a->file);
        refl_scene_destroy(s);
    }
}

/* 98 nodes instance one sphere: one scene mesh, many objects (glTF repeats the
   accessors in one mesh per material; the loader shares them). Metallic 1,
   roughness 0 is a mirror; smooth enough spheres in between are partial. */
Test(gltf, metal_rough_spheres_instance_one_mesh_and_find_the_mirror) {
    refl_scene *s;
    int i, *uses, most = 0, mirror_objects = 0;
    const refl_material *m;
    need_assets();
    s = tg_load("MetalRoughSpheresNoTextures.glb", 0);
    uses = calloc((size_t)s->mesh_count, sizeof *uses);
    for (i = 0; i < s->object_count; i++) {
        if (++uses[s->objects[i].mesh] > most) most = uses[s->objects[i].mesh];
        mirror_objects += s->materials[s->objects[i].material].type == REFL_MIRROR;
    }
    free(uses);
    cr_expect_eq(most, 98, "the sphere mesh has %d instances", most);
    cr_expect(s->mesh_count < s->object_count);
    /* metallic 1, roughness 0: mat_42 (grey) and mat_91 (gold) */
    m = tg_material(s, "mat_42");
    cr_assert(m);
    cr_expect_eq(m->type, REFL_MIRROR);
    cr_expect_float_eq(m->reflectance, 0.6038f, 1e-3f);
    cr_expect_eq(tg_material(s, "mat_91")->type, REFL_MIRROR);
    cr_expect_eq(tg_count_type(s, REFL_MIRROR), 2);
    cr_expect_eq(mirror_objects, 2);
    /* in between: PARTIAL, mirror_weight = (1 - roughness)^2 (0.04 (1 - metallic) + metallic) */
    m = tg_material(s, "mat_43"); /* metallic 1, roughness 1/6 */
    cr_expect_eq(m->type, REFL_PARTIAL);
    cr_expect_float_eq(m->mirror_weight, 25.0f / 36.0f, 1e-5f);
    cr_expect_float_eq(m->reflectance, 0.6038f, 1e-3f, "a metal reflects its base colour's luminance");
    m = tg_material(s, "mat_7"); /* metallic 1/6, roughness 0: 0.04 5/6 + 1/6 = 0.2 */
    cr_expect_eq(m->type, REFL_PARTIAL);
    cr_expect_float_eq(m->mirror_weight, 0.2f, 1e-6f);
    cr_expect_float_eq(m->reflectance, (0.04f * 5 / 6 + 0.6038f / 6) / 0.2f, 1e-3f);
    cr_expect_eq(tg_material(s, "mat_0")->type, REFL_DIFFUSE, "a smooth dielectric: 0.04, below 0.05");
    /* 27 of each colour; metallic 1/6 (0.16666667 in the file), roughness 1/2
       gives 0.0500000012, just in */
    cr_expect_eq(tg_count_type(s, REFL_PARTIAL), 54, "%d partial", tg_count_type(s, REFL_PARTIAL));
    refl_scene_destroy(s);
}

Test(gltf, teapot_is_a_mirror) {
    refl_scene *s;
    need_assets();
    s = tg_load("teapot.glb", 0);
    cr_assert_eq(s->object_count, 1);
    cr_expect_eq(s->materials[s->objects[0].material].type, REFL_MIRROR);
    cr_expect_float_eq(s->materials[s->objects[0].material].reflectance, 0.9f, 1e-5f);
    refl_scene_destroy(s);
}

Test(gltf, transmission_materials_are_glass) {
    refl_scene *s;
    const refl_material *m;
    need_assets();
    s = tg_load("TransmissionTest.glb", 0);
    /* 12 transmissive materials: 8 dielectric (glass), 4 metallic 1 and
       roughness 0 (a metal is opaque: mirror) */
    cr_expect_eq(tg_count_type(s, REFL_GLASS), 8);
    cr_expect_eq(tg_count_type(s, REFL_MIRROR), 4);
    m = tg_material(s, "YellowTrans");
    cr_assert(m);
    cr_expect_eq(m->type, REFL_GLASS);
    cr_expect_float_eq(m->ior, 1.5f, 1e-6f);
    cr_expect_float_eq(m->tint[0], 0.8468738f, 1e-5f);
    cr_expect_float_eq(m->tint[2], 0.0930590f, 1e-5f);
    cr_expect_eq(m->attenuation, 0.0f);
    cr_expect_eq(tg_material(s, "YellowTransMetal")->type, REFL_MIRROR);
    cr_expect_eq(tg_material(s, "Cloth Backdrop")->type, REFL_DIFFUSE);
    cr_expect_gt(tg_material(s, "Cloth Backdrop")->texture, 0);
    cr_expect(s->has_camera);
    refl_scene_destroy(s);

    s = tg_load("ToyCar.glb", 0);
    m = tg_material(s, "Glass");
    cr_assert(m);
    cr_expect_eq(m->type, REFL_GLASS);
    cr_expect_float_eq(m->tint[1], 0.8f, 1e-6f);
    cr_expect_eq(tg_material(s, "ToyCar")->type, REFL_DIFFUSE);
    cr_expect(s->has_camera);
    refl_scene_destroy(s);
}

/* KHR_materials_volume: the colour through the volume's nominal thickness
   (thicknessFactor) is attenuationColor^(thickness / attenuationDistance),
   which is what the test's row of reference samples (R1_Sample_*: plain
   transmission with that base colour) shows: the loader's tint and
   attenuation (the least absorbed channel's, per unit length) must give
   each R2 (thickness) and R5 (distance) cube its sample's colour. */
Test(gltf, attenuation_from_materials_volume) {
    static const char *suffix[] = {"1.0", "1.5", "2.0", "0.50", "0.25"};
    refl_scene *s;
    const refl_material *m, *ref;
    char name[64];
    int i, c, row;
    need_assets();
    s = tg_load("AttenuationTest.glb", 0);
    cr_expect_eq(tg_count_type(s, REFL_GLASS), 16);
    for (i = 0; i < 5; i++) {
        snprintf(name, sizeof name, "R1_Sample_%s", suffix[i]);
        ref = tg_material(s, name);
        cr_assert(ref);
        cr_expect_eq(ref->type, REFL_GLASS);
        cr_expect_eq(ref->attenuation, 0.0f, "no volume: no absorption");
        for (row = 0; row < 2; row++) {
            float thickness;
            if (row == 0) snprintf(name, sizeof name, "R2_ThicknessFac_%s", suffix[i]);
            else snprintf(name, sizeof name, "R5_Attenuation_%s", suffix[i]);
            m = tg_material(s, i == 0 && row == 0 ? "R2_and_R4_ThicknessFac_1.0" : name);
            cr_assert(m, "%s", name);
            cr_expect_eq(m->type, REFL_GLASS);
            thickness = row == 0 ? (float)atof(suffix[i]) : 1.0f;
            for (c = 0; c < 3; c++) {
                float through = m->tint[c] * expf(-m->attenuation * thickness);
                cr_expect(fabsf(through - ref->tint[c]) < 1e-3f, "%s channel %d: %g through the cube, sample %g",
                          name, c, through, ref->tint[c]);
            }
        }
    }
    m = tg_material(s, "R5_Attenuation_2.0"); /* attenuationDistance 0.5: blue absorbs least */
    cr_expect_float_eq(m->attenuation, (float)(-log(0.9) / 0.5), 1e-5f);
    cr_expect_float_eq(m->tint[2], 1.0f, 1e-6f);
    refl_scene_destroy(s);

    /* normalising rescales the attenuation with the scene (diagonal 20*sqrt(2.04) -> 2) */
    s = tg_load("AttenuationTest.glb", 2.0f);
    m = tg_material(s, "R5_Attenuation_2.0");
    cr_expect_float_eq(m->attenuation, (float)(-log(0.9) / 0.5 * sqrt(20.0 * 20 + 20 * 20 + 4 * 4) / 2.0), 1e-3f);
    refl_scene_destroy(s);
}

Test(gltf, duck_texture_and_camera) {
    refl_scene *s;
    const refl_image *t;
    const refl_mesh *mesh;
    int i, nonzero = 0, in_range = 1;
    need_assets();
    s = tg_load("Duck.glb", 0);
    cr_assert_eq(s->texture_count, 1);
    t = &s->textures[0];
    cr_expect_eq(t->width, 512);
    cr_expect_eq(t->height, 512);
    for (i = 0; i < t->width * t->height * 4; i++) {
        nonzero += t->pixels[i] > 0.01f;
        in_range &= t->pixels[i] >= 0 && t->pixels[i] <= 1;
    }
    cr_expect(in_range, "linear texels in [0, 1]");
    cr_expect_gt(nonzero, t->width * t->height, "the texture is not blank");
    cr_assert_eq(s->object_count, 1);
    cr_expect_eq(s->materials[s->objects[0].material].texture, 1);
    mesh = s->meshes[s->objects[0].mesh];
    cr_expect(mesh->texcoords != NULL);
    cr_expect(mesh->normals != NULL);
    cr_expect(s->has_camera);
    cr_expect_gt(s->camera.fovy_degrees, 1.0f);
    cr_expect_lt(s->camera.fovy_degrees, 179.0f);
    refl_scene_destroy(s);
}

Test(gltf, normalize_option) {
    refl_scene *s;
    double lo[3], hi[3], d = 0;
    int c;
    need_assets();
    s = tg_load("Duck.glb", 2.0f);
    tg_bounds(s, lo, hi);
    for (c = 0; c < 3; c++) {
        d += (hi[c] - lo[c]) * (hi[c] - lo[c]);
        cr_expect(fabs(lo[c] + hi[c]) < 1e-4, "centred on the origin (axis %d: %g..%g)", c, lo[c], hi[c]);
    }
    cr_expect(fabs(sqrt(d) - 2.0) < 1e-3, "diagonal %g", sqrt(d));
    refl_scene_destroy(s);
}

/* ---- malformed input ------------------------------------------------------------ */

/* Criterion reports every assertion to its runner, which costs about a
   millisecond each: the loops below check by hand and assert once. */
typedef struct tg_check {
    long fails;
    char first[1200];
} tg_check;

/* path (or, with data, those bytes named path) must fail to load, with a
   message naming `name`. */
static void check_error(tg_check *chk, const char *path, const void *data, size_t size, const char *name,
                        const char *what) {
    char err[1024] = "";
    refl_scene *s = (refl_scene *)1;
    refl_result r = data ? refl_gltf_load_memory(data, size, path, NULL, &s, err, sizeof err)
                         : refl_gltf_load(path, NULL, &s, err, sizeof err);
    if (r == REFL_OK || s != NULL || !strstr(err, name)) {
        if (chk->fails++ == 0)
            snprintf(chk->first, sizeof chk->first, "%s (%s, %zu bytes): result %d, scene %p, message '%s'", path,
                     what, size, r, (void *)s, err);
        if (r == REFL_OK && s) refl_scene_destroy(s);
    }
}

#define TG_CHECK_DONE(chk) cr_assert((chk)->fails == 0, "%ld failure(s); first: %s", (chk)->fails, (chk)->first)

static void expect_error(const char *path, const char *name, const char *what) {
    tg_check chk = {0, ""};
    check_error(&chk, path, NULL, 0, name, what);
    TG_CHECK_DONE(&chk);
}

Test(gltf, missing_file_and_bad_arguments) {
    char err[256];
    refl_scene *s;
    expect_error("/nonexistent/dir/no_such_model.glb", "no_such_model.glb", "missing file");
    cr_expect_eq(refl_gltf_load("/nonexistent/x.glb", NULL, &s, err, sizeof err), REFL_ERROR_UNKNOWN_NAME);
    cr_expect_eq(refl_gltf_load(NULL, NULL, &s, err, sizeof err), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_gltf_load("x.glb", NULL, NULL, err, sizeof err), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_eq(refl_gltf_load("/nonexistent/x.glb", NULL, &s, NULL, 0), REFL_ERROR_UNKNOWN_NAME);
    /* a directory is not a file */
    expect_error("/tmp", "/tmp", "a directory");
}

/* Truncated copies written to a temporary directory (Box.glb and Duck.glb
   at chosen lengths), and every truncation of Box.glb from memory (files
   are slow to write here, about 2 ms each). */
Test(gltf, truncated_glb) {
    char dir[64], path[128];
    tg_bytes box, duck;
    size_t n, i;
    tg_check chk = {0, ""};
    need_assets();
    box = tg_read(ASSETS "/Box.glb");
    duck = tg_read(ASSETS "/Duck.glb");
    tg_mkdtemp(dir, sizeof dir);
    {
        const size_t box_cuts[] = {0, 1, 11, 12, 19, 20, 21, 100, 800, box.size - 4, box.size - 1};
        const size_t duck_cuts[] = {24, 1000, 4096, 50000, duck.size / 2, duck.size - 1000, duck.size - 1};
        snprintf(path, sizeof path, "%s/cut_box.glb", dir);
        for (i = 0; i < sizeof box_cuts / sizeof box_cuts[0]; i++) {
            tg_write(path, box.data, box_cuts[i]);
            check_error(&chk, path, NULL, 0, "cut_box.glb", "truncated Box.glb");
        }
        snprintf(path, sizeof path, "%s/cut_duck.glb", dir);
        for (i = 0; i < sizeof duck_cuts / sizeof duck_cuts[0]; i++) {
            tg_write(path, duck.data, duck_cuts[i]);
            check_error(&chk, path, NULL, 0, "cut_duck.glb", "truncated Duck.glb");
        }
    }
    for (n = 1; n < box.size; n++) check_error(&chk, "mem/cut_box.glb", box.data, n, "cut_box.glb", "truncated in memory");
    TG_CHECK_DONE(&chk);
    tg_rmdir(dir);
    free(box.data);
    free(duck.data);
}

/* Loads a mutated copy: it may load (the change was harmless) or fail with
   a message naming the file; it must not crash, hang or leak. 1: rejected. */
static int load_mutant(tg_check *chk, const tg_bytes *b, const char *name, size_t at) {
    char err[1024] = "";
    refl_scene *s = NULL;
    refl_result r = refl_gltf_load_memory(b->data, b->size, name, NULL, &s, err, sizeof err);
    if (r == REFL_OK) {
        if (!s && chk->fails++ == 0) snprintf(chk->first, sizeof chk->first, "byte %zu: no scene", at);
        refl_scene_destroy(s);
        return 0;
    }
    if ((s || !strstr(err, name)) && chk->fails++ == 0)
        snprintf(chk->first, sizeof chk->first, "byte %zu: scene %p, message '%s'", at, (void *)s, err);
    return 1;
}

/* Box.glb with every byte changed in turn, three ways: the low bit flipped
   (digits in the JSON become other digits: counts, offsets and indices go
   out of range), all bits flipped, and set to '9' (numbers grow). The
   copies are loaded from memory; one is also written and loaded as a file. */
Test(gltf, byte_flipped_box) {
    char dir[64], path[128];
    tg_bytes box;
    size_t i;
    int k, failed = 0, runs = 0;
    tg_check chk = {0, ""};
    need_assets();
    box = tg_read(ASSETS "/Box.glb");
    for (i = 0; i < box.size; i++) {
        unsigned char orig = box.data[i];
        for (k = 0; k < 3; k++) {
            unsigned char v = k == 0 ? orig ^ 0x01 : k == 1 ? orig ^ 0xFF : '9';
            if (v == orig) continue;
            box.data[i] = v;
            failed += load_mutant(&chk, &box, "flip_box.glb", i);
            runs++;
        }
        box.data[i] = orig;
    }
    TG_CHECK_DONE(&chk);
    cr_log_info("byte_flipped_box: %d of %d mutants rejected", failed, runs);
    cr_expect_gt(failed, runs / 10, "most header and JSON damage is detected");
    /* byte 8 is the GLB length: as a file */
    tg_mkdtemp(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/flip_box.glb", dir);
    box.data[8] ^= 0x01;
    tg_write(path, box.data, box.size);
    expect_error(path, "flip_box.glb", "corrupt GLB length");
    tg_rmdir(dir);
    free(box.data);
}

/* Larger assets: every 997th byte (JSON, accessors, vertex data) changed in
   turn. Loads that cost more are sampled more sparsely, to keep the
   sanitized run short: the Duck (its PNG is decoded on every load, 30 ms
   under ASan) every 2999th byte, MetalRoughSpheres (98 materials, 119
   nodes) only in its first 64 KiB: the 49,700-byte JSON and the start of
   the vertex data. */
Test(gltf, byte_flipped_assets) {
    static const char *files[] = {"Duck.glb", "teapot.glb", "MetalRoughSpheresNoTextures.glb"};
    static const size_t limit[] = {(size_t)-1, (size_t)-1, 65536}, stride[] = {2999, 997, 997};
    char src[256];
    size_t f, i;
    int failed = 0, runs = 0;
    tg_check chk = {0, ""};
    need_assets();
    for (f = 0; f < sizeof files / sizeof files[0]; f++) {
        tg_bytes b;
        snprintf(src, sizeof src, "%s/%s", ASSETS, files[f]);
        b = tg_read(src);
        for (i = 5; i < b.size && i < limit[f]; i += stride[f]) {
            unsigned char orig = b.data[i];
            b.data[i] = (unsigned char)(orig ^ (i % 2 ? 0x01 : 0xFF));
            failed += load_mutant(&chk, &b, files[f], i);
            runs++;
            b.data[i] = orig;
        }
        free(b.data);
    }
    TG_CHECK_DONE(&chk);
    cr_log_info("byte_flipped_assets: %d of %d mutants rejected", failed, runs);
}

/* ---- hand-written files ------------------------------------------------------------ */

/* tiny.bin: 4 vertices (float xyz) at 0, u16 indices at 48, u8 indices at
   64, normalised u8 texcoords at 72, u8 colours at 80 (4 x rgb, padded),
   a NaN vertex set at 96. */
static void write_tiny_bin(const char *dir) {
    unsigned char bin[144];
    const float pos[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    const uint16_t idx16[6] = {0, 1, 2, 2, 1, 5}; /* the 5 is out of range */
    const uint8_t idx8[6] = {0, 1, 2, 2, 1, 3};
    const uint8_t uv[8] = {0, 0, 255, 0, 0, 255, 255, 255};
    const uint8_t rgb[12] = {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255};
    float nan_pos[12];
    char path[256];
    memcpy(nan_pos, pos, sizeof pos);
    nan_pos[4] = NAN;
    memset(bin, 0, sizeof bin);
    memcpy(bin, pos, 48);
    memcpy(bin + 48, idx16, 12);
    memcpy(bin + 64, idx8, 6);
    memcpy(bin + 72, uv, 8);
    memcpy(bin + 80, rgb, 12);
    memcpy(bin + 96, nan_pos, 48);
    snprintf(path, sizeof path, "%s/tiny.bin", dir);
    tg_write(path, bin, sizeof bin);
}

/* A .gltf around tiny.bin; `accessors` and `meshes` are JSON arrays, `extra`
   more top-level members (or ""). Nodes: 0 is the root (translated by
   (10, 0, 0), scaled by 2) with children 1 (mesh 0) and 2 (camera at z = 5,
   a point light). */
#define TINY_NODES                                                                                      \
    "[{\"translation\":[10,0,0],\"scale\":[2,2,2],\"children\":[1,2]},{\"mesh\":0},"                   \
    "{\"camera\":0,\"translation\":[0,0,5],\"extensions\":{\"KHR_lights_punctual\":{\"light\":0}}}]"
#define TINY_LIGHTS "[{\"type\":\"point\",\"color\":[1,0.5,0.25],\"intensity\":2}]"

/* write_gltf with other nodes (a JSON array like TINY_NODES) and lights. */
static void write_gltf_nodes(const char *dir, const char *name, const char *nodes, const char *lights,
                             const char *accessors, const char *meshes, const char *extra) {
    char path[256];
    static char json[8192];
    int n = snprintf(json, sizeof json,
        "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
        "\"nodes\":%s,"
        "\"cameras\":[{\"type\":\"perspective\",\"perspective\":{\"yfov\":0.5,\"znear\":0.1}}],"
        "\"extensionsUsed\":[\"KHR_lights_punctual\"],"
        "\"extensions\":{\"KHR_lights_punctual\":{\"lights\":%s}},"
        "\"buffers\":[{\"uri\":\"tiny.bin\",\"byteLength\":144}],"
        "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":48},"
        "{\"buffer\":0,\"byteOffset\":48,\"byteLength\":12},"
        "{\"buffer\":0,\"byteOffset\":64,\"byteLength\":6},"
        "{\"buffer\":0,\"byteOffset\":72,\"byteLength\":8},"
        "{\"buffer\":0,\"byteOffset\":80,\"byteLength\":12},"
        "{\"buffer\":0,\"byteOffset\":96,\"byteLength\":48}],"
        "\"accessors\":%s,\"meshes\":%s%s}",
        nodes, lights, accessors, meshes, extra);
    cr_assert(n > 0 && n < (int)sizeof json);
    snprintf(path, sizeof path, "%s/%s", dir, name);
    tg_write(path, json, (size_t)n);
}

static void write_gltf(const char *dir, const char *name, const char *accessors, const char *meshes,
                       const char *extra) {
    write_gltf_nodes(dir, name, TINY_NODES, TINY_LIGHTS, accessors, meshes, extra);
}

/* accessors: 0 positions, 1 u16 indices (one out of range), 2 u8 indices,
   3 u8n texcoords, 4 u8n rgb colours, 5 positions with a NaN */
#define TINY_ACCESSORS                                                                                  \
    "[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"},"                         \
    "{\"bufferView\":1,\"componentType\":5123,\"count\":6,\"type\":\"SCALAR\"},"                        \
    "{\"bufferView\":2,\"componentType\":5121,\"count\":6,\"type\":\"SCALAR\"},"                        \
    "{\"bufferView\":3,\"componentType\":5121,\"normalized\":true,\"count\":4,\"type\":\"VEC2\"},"      \
    "{\"bufferView\":4,\"componentType\":5121,\"normalized\":true,\"count\":4,\"type\":\"VEC3\"},"      \
    "{\"bufferView\":5,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"}]"

static void expect_tiny_error(const char *dir, const char *name, refl_result code, const char *needle) {
    char path[256], err[1024] = "";
    refl_scene *s = (refl_scene *)1;
    refl_result r;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    r = refl_gltf_load(path, NULL, &s, err, sizeof err);
    cr_expect_eq(r, code, "%s: result %d, expected %d (%s)", name, r, code, err);
    cr_expect_null(s);
    cr_expect(strstr(err, name) != NULL, "%s: message '%s' does not name the file", name, err);
    cr_expect(strstr(err, needle) != NULL, "%s: message '%s' does not say '%s'", name, err, needle);
    if (r == REFL_OK && s) refl_scene_destroy(s);
}

Test(gltf, hand_written_good_file) {
    char dir[64], path[256], err[1024];
    refl_scene *s;
    const refl_mesh *m;
    const refl_object *o;
    tg_mkdtemp(dir, sizeof dir);
    write_tiny_bin(dir);
    write_gltf(dir, "good.gltf", TINY_ACCESSORS,
               "[{\"name\":\"quad\",\"primitives\":[{\"attributes\":{\"POSITION\":0,\"TEXCOORD_0\":3,"
               "\"COLOR_0\":4},\"indices\":2}]}]", "");
    snprintf(path, sizeof path, "%s/good.gltf", dir);
    cr_assert_eq(refl_gltf_load(path, NULL, &s, err, sizeof err), REFL_OK, "%s", err);
    cr_expect_eq(err[0], '\0', "no warnings: %s", err);
    cr_assert_eq(s->object_count, 1);
    o = &s->objects[0];
    m = s->meshes[o->mesh];
    cr_expect_eq(m->triangle_count, 2);
    cr_expect_eq(m->vertex_count, 4);
    cr_expect_eq(m->indices[5], 3u);
    cr_assert(m->texcoords && m->colors && m->normals);
    cr_expect_float_eq(m->texcoords[2], 1.0f, 1e-6f);
    cr_expect_float_eq(m->colors[4 * 1 + 1], 1.0f, 1e-6f);
    cr_expect_float_eq(m->colors[4 * 1 + 3], 1.0f, 1e-6f, "vec3 colours get alpha 1");
    /* the world transform: translate (10,0,0) * scale 2 */
    cr_expect_float_eq(o->transform.m[0], 2.0f, 1e-6f);
    cr_expect_float_eq(o->transform.m[12], 10.0f, 1e-6f);
    cr_expect_eq(s->materials[o->material].type, REFL_DIFFUSE, "the default material");
    /* the camera's node sits at (0,0,5) under the root: (10, 0, 10) */
    cr_expect(s->has_camera);
    cr_expect_float_eq(s->camera.eye.x, 10.0f, 1e-5f);
    cr_expect_float_eq(s->camera.eye.z, 10.0f, 1e-5f);
    cr_expect_float_eq(s->camera.target.z, 9.0f, 1e-5f, "looks down -z");
    cr_expect_float_eq(s->camera.up.y, 1.0f, 1e-5f);
    cr_expect_float_eq(s->camera.fovy_degrees, (float)(0.5 * 180 / M_PI), 1e-3f);
    cr_assert_eq(s->light_count, 1);
    cr_expect_eq(s->lights[0].type, REFL_LIGHT_POINT);
    cr_expect_float_eq(s->lights[0].position.x, 10.0f, 1e-5f);
    cr_expect_float_eq(s->lights[0].color[1], 1.0f, 1e-6f);
    refl_scene_destroy(s);

    /* strips and fans become lists; a POINTS primitive next to triangles is
       skipped with a warning */
    write_gltf(dir, "modes.gltf", TINY_ACCESSORS,
               "[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"mode\":5},"
               "{\"attributes\":{\"POSITION\":0},\"mode\":6},"
               "{\"attributes\":{\"POSITION\":0},\"mode\":0}]}]", "");
    snprintf(path, sizeof path, "%s/modes.gltf", dir);
    cr_assert_eq(refl_gltf_load(path, NULL, &s, err, sizeof err), REFL_OK, "%s", err);
    cr_expect(strstr(err, "POINTS") && strstr(err, "modes.gltf"), "warning: %s", err);
    cr_assert_eq(s->object_count, 2);
    m = s->meshes[s->objects[0].mesh]; /* strip 0 1 2 3: (0 1 2) (1 3 2), the spec's order */
    cr_expect_eq(m->triangle_count, 2);
    cr_expect(m->indices[3] == 1 && m->indices[4] == 3 && m->indices[5] == 2);
    m = s->meshes[s->objects[1].mesh]; /* fan: (1 2 0) (2 3 0) */
    cr_expect_eq(m->triangle_count, 2);
    cr_expect(m->indices[0] == 1 && m->indices[1] == 2 && m->indices[2] == 0);
    refl_scene_destroy(s);
    tg_rmdir(dir);
}

Test(gltf, hand_written_bad_files) {
    char dir[64];
    tg_mkdtemp(dir, sizeof dir);
    write_tiny_bin(dir);
    write_gltf(dir, "bad_index.gltf", TINY_ACCESSORS,
               "[{\"name\":\"x\",\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}]", "");
    expect_tiny_error(dir, "bad_index.gltf", REFL_ERROR_BAD_MESH, "primitive 0 of mesh 0 'x': index 5 out of range (4 vertices)");
    write_gltf(dir, "nan.gltf", TINY_ACCESSORS, "[{\"primitives\":[{\"attributes\":{\"POSITION\":5}}]}]", "");
    expect_tiny_error(dir, "nan.gltf", REFL_ERROR_BAD_MESH, "vertex 1 has a non-finite position");
    write_gltf(dir, "points.gltf", TINY_ACCESSORS,
               "[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"mode\":0}]}]", "");
    expect_tiny_error(dir, "points.gltf", REFL_ERROR_UNSUPPORTED, "POINTS");
    write_gltf(dir, "lines.gltf", TINY_ACCESSORS,
               "[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"mode\":1}]}]", "");
    expect_tiny_error(dir, "lines.gltf", REFL_ERROR_UNSUPPORTED, "LINES");
    /* 5 elements of 12 bytes do not fit the 48-byte view */
    write_gltf(dir, "overrun.gltf",
               "[{\"bufferView\":0,\"componentType\":5126,\"count\":5,\"type\":\"VEC3\"}]",
               "[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}]", "");
    expect_tiny_error(dir, "overrun.gltf", REFL_ERROR_BAD_MESH, "overruns bufferView 0");
    write_gltf(dir, "offset.gltf",
               "[{\"bufferView\":0,\"byteOffset\":4,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"}]",
               "[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}]", "");
    expect_tiny_error(dir, "offset.gltf", REFL_ERROR_BAD_MESH, "overruns");
    write_gltf(dir, "sparse.gltf",
               "[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\",\"sparse\":{\"count\":1,"
               "\"indices\":{\"bufferView\":2,\"componentType\":5121},\"values\":{\"bufferView\":0}}}]",
               "[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}]", "");
    expect_tiny_error(dir, "sparse.gltf", REFL_ERROR_UNSUPPORTED, "sparse");
    write_gltf(dir, "wrong_type.gltf", TINY_ACCESSORS,
               "[{\"primitives\":[{\"attributes\":{\"POSITION\":3}}]}]", "");
    expect_tiny_error(dir, "wrong_type.gltf", REFL_ERROR_BAD_MESH, "wrong type");
    write_gltf(dir, "no_accessor.gltf", TINY_ACCESSORS,
               "[{\"primitives\":[{\"attributes\":{\"POSITION\":42}}]}]", "");
    expect_tiny_error(dir, "no_accessor.gltf", REFL_ERROR_BAD_MESH, "accessor 42 does not exist");
    write_gltf(dir, "no_triangles.gltf", TINY_ACCESSORS, "[]", "");
    expect_tiny_error(dir, "no_triangles.gltf", REFL_ERROR_BAD_MESH, "node 1: mesh 0 does not exist");
    write_gltf(dir, "required_ext.gltf", TINY_ACCESSORS, "[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}]",
               ",\"extensionsRequired\":[\"KHR_draco_mesh_compression\"]");
    expect_tiny_error(dir, "required_ext.gltf", REFL_ERROR_UNSUPPORTED, "KHR_draco_mesh_compression");
    {
        char path[256];
        snprintf(path, sizeof path, "%s/not_json.gltf", dir);
        tg_write(path, "{\"asset\": [1, 2", 15);
        expect_tiny_error(dir, "not_json.gltf", REFL_ERROR_BAD_MESH, "tinygltf");
        snprintf(path, sizeof path, "%s/empty.glb", dir);
        tg_write(path, "", 0);
        expect_tiny_error(dir, "empty.glb", REFL_ERROR_BAD_MESH, "empty file");
    }
    tg_rmdir(dir);
}

/* A node hierarchy with a cycle (0 -> 1 -> 0) loads each node once. */
Test(gltf, node_cycle_does_not_hang) {
    char dir[64], path[256], err[1024];
    static const char json[] =
        "{\"asset\":{\"version\":\"2.0\"},\"scenes\":[{\"nodes\":[0]}],"
        "\"nodes\":[{\"mesh\":0,\"children\":[1]},{\"mesh\":0,\"children\":[0]}],"
        "\"buffers\":[{\"uri\":\"tiny.bin\",\"byteLength\":144}],"
        "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":48}],"
        "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}],"
        "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}]}";
    refl_scene *s;
    tg_mkdtemp(dir, sizeof dir);
    write_tiny_bin(dir);
    snprintf(path, sizeof path, "%s/cycle.gltf", dir);
    tg_write(path, json, sizeof json - 1);
    cr_assert_eq(refl_gltf_load(path, NULL, &s, err, sizeof err), REFL_OK, "%s", err);
    cr_expect_eq(s->object_count, 2);
    cr_expect_eq(s->mesh_count, 1);
    cr_expect(strstr(err, "reached twice") != NULL, "warning: %s", err);
    refl_scene_destroy(s);
    tg_rmdir(dir);
}

/* ---- hostile files ------------------------------------------------------------------ */

static uint32_t tg_le32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void tg_put_le32(unsigned char *p, uint32_t v) {
    p[0] = (unsigned char)v; p[1] = (unsigned char)(v >> 8); p[2] = (unsigned char)(v >> 16); p[3] = (unsigned char)(v >> 24);
}

/* A GLB with its JSON chunk edited: the first `find` replaced by `repl`,
   the chunk padded with spaces and the lengths rewritten. Free .data. */
static tg_bytes tg_glb_patch(const tg_bytes *glb, const char *find, const char *repl) {
    size_t json_len = tg_le32(glb->data + 12), rest = glb->size - 20 - json_len, at, n;
    char *json = malloc(json_len + 1);
    const char *hit;
    tg_bytes out;
    cr_assert(json);
    memcpy(json, glb->data + 20, json_len);
    json[json_len] = '\0';
    hit = strstr(json, find);
    cr_assert(hit, "'%s' is not in the JSON", find);
    at = (size_t)(hit - json);
    n = json_len - strlen(find) + strlen(repl);
    n += (4 - n % 4) % 4;
    out.size = 20 + n + rest;
    out.data = malloc(out.size);
    cr_assert(out.data);
    memcpy(out.data, glb->data, 12);
    tg_put_le32(out.data + 8, (uint32_t)out.size);
    tg_put_le32(out.data + 12, (uint32_t)n);
    memcpy(out.data + 16, "JSON", 4);
    memset(out.data + 20, ' ', n);
    memcpy(out.data + 20, json, at);
    memcpy(out.data + 20 + at, repl, strlen(repl));
    memcpy(out.data + 20 + at + strlen(repl), hit + strlen(find), json_len - at - strlen(find));
    memcpy(out.data + 20 + n, glb->data + 20 + json_len, rest);
    free(json);
    return out;
}

/* bytes named `name` must fail with `code` and a message naming the file
   and saying `needle`. */
static void expect_memory_error(const tg_bytes *b, const char *name, refl_result code, const char *needle) {
    char err[1024] = "";
    refl_scene *s = (refl_scene *)1;
    refl_result r = refl_gltf_load_memory(b->data, b->size, name, NULL, &s, err, sizeof err);
    cr_expect_eq(r, code, "%s: result %d, expected %d (%s)", name, r, code, err);
    cr_expect_null(s);
    cr_expect(strncmp(err, name, strlen(name)) == 0, "%s: message '%s' does not start with the file", name, err);
    cr_expect(strstr(err, needle) != NULL, "%s: message '%s' does not say '%s'", name, err, needle);
    cr_expect(strchr(err, '\n') == NULL, "%s: message '%s' spans lines", name, err);
    if (r == REFL_OK && s) refl_scene_destroy(s);
}

/* Duck.glb's PNG lies in bufferView 3 (offset 102040, 16302 bytes) of its
   118342-byte buffer: a view that reaches past the buffer, starts far
   outside it, or a buffer declared shorter than its views is refused
   before a byte of the image is read. */
Test(gltf, image_bytes_outside_their_buffer) {
    static const struct { const char *find, *repl, *needle; } cases[] = {
        {"\"byteOffset\":102040,\"byteLength\":16302", "\"byteOffset\":102040,\"byteLength\":99999999",
         "image 0: bufferView 3 (byteOffset 102040, byteLength 99999999) lies outside buffer 0 (118342 bytes)"},
        {"\"byteOffset\":102040,\"byteLength\":16302", "\"byteOffset\":2000000000,\"byteLength\":16302",
         "image 0: bufferView 3 (byteOffset 2000000000"},
        {"\"buffers\":[{\"byteLength\":118342}]", "\"buffers\":[{\"byteLength\":110000}]",
         "lies outside buffer 0 (110000 bytes)"},
    };
    tg_bytes duck;
    size_t i;
    need_assets();
    duck = tg_read(ASSETS "/Duck.glb");
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        tg_bytes b = tg_glb_patch(&duck, cases[i].find, cases[i].repl);
        expect_memory_error(&b, "hostile_duck.glb", REFL_ERROR_BAD_MESH, cases[i].needle);
        free(b.data);
    }
    free(duck.data);
}

/* `depth` nested arrays: "[[...]]". Free the result. */
static char *tg_nested_arrays(int depth) {
    char *s = malloc((size_t)depth * 2 + 1);
    cr_assert(s);
    memset(s, '[', (size_t)depth);
    memset(s + depth, ']', (size_t)depth);
    s[depth * 2] = '\0';
    return s;
}

/* tinygltf's JSON parser recurses per level: 100,000 nested arrays in an
   `extras` (200 KB) overflowed the stack. The loader scans the JSON first
   and refuses more than 512 levels, in .glb and .gltf alike. */
Test(gltf, deeply_nested_json_is_refused) {
    static const int depths[] = {510, 511, 100000};
    char *nest, *text;
    tg_bytes box, b;
    size_t i;
    need_assets();
    box = tg_read(ASSETS "/Box.glb");
    for (i = 0; i < 3; i++) {
        /* "{" and "asset":{ are two levels: 510 arrays make 512 */
        char *repl;
        nest = tg_nested_arrays(depths[i]);
        repl = malloc(strlen(nest) + 32);
        cr_assert(repl);
        sprintf(repl, "\"asset\":{\"extras\":%s,", nest);
        b = tg_glb_patch(&box, "\"asset\":{", repl);
        if (depths[i] == 510) {
            char err[1024];
            refl_scene *s;
            cr_expect_eq(refl_gltf_load_memory(b.data, b.size, "nested.glb", NULL, &s, err, sizeof err), REFL_OK,
                         "512 levels load: %s", err);
            if (s) refl_scene_destroy(s);
        } else {
            expect_memory_error(&b, "nested.glb", REFL_ERROR_INVALID_SIZE, "JSON nested deeper than 512");
        }
        free(b.data);
        free(repl);
        free(nest);
    }
    free(box.data);

    nest = tg_nested_arrays(100000);
    text = malloc(strlen(nest) + 64);
    cr_assert(text);
    sprintf(text, "{\"asset\":{\"version\":\"2.0\",\"extras\":%s}}", nest);
    b.data = (unsigned char *)text;
    b.size = strlen(text);
    expect_memory_error(&b, "nested.gltf", REFL_ERROR_INVALID_SIZE, "JSON nested deeper than 512");
    /* brackets inside strings do not count */
    sprintf(text, "{\"asset\":{\"version\":\"2.0\",\"generator\":\"%.*s\"}}", 1000, nest);
    b.size = strlen(text);
    expect_memory_error(&b, "strings.gltf", REFL_ERROR_BAD_MESH, "no triangles");
    free(text);
    free(nest);
}

/* 2^24 values: refused before the parser builds millions of nodes. */
Test(gltf, json_with_too_many_values_is_refused) {
    const size_t count = ((size_t)1 << 24) + 8;
    size_t i, n = 0;
    char *text = malloc(count * 2 + 64);
    tg_bytes b;
    cr_assert(text);
    n += (size_t)sprintf(text, "{\"asset\":{\"version\":\"2.0\",\"extras\":[");
    for (i = 0; i < count; i++) { text[n++] = '0'; text[n++] = ','; }
    n += (size_t)sprintf(text + n - 1, "0]}}") - 1;
    b.data = (unsigned char *)text;
    b.size = n;
    expect_memory_error(&b, "values.gltf", REFL_ERROR_INVALID_SIZE, "JSON with more than 16777216 values");
    free(text);
}

/* Doubles the renderer would get as inf, or as coordinates whose squares
   overflow float: refused, naming the node or material and the field. */
Test(gltf, large_doubles_are_refused) {
    static const char mesh[] = "[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":2,\"material\":0}]}]";
    static const char glass[] =
        ",\"materials\":[{\"name\":\"g\",\"extensions\":{\"KHR_materials_transmission\":{\"transmissionFactor\":1}%s}}]";
    static const struct { const char *name, *nodes, *lights, *ext, *needle; } cases[] = {
        {"light_far.gltf", "[{\"children\":[1,2]},{\"mesh\":0},{\"translation\":[1e300,0,0],"
         "\"extensions\":{\"KHR_lights_punctual\":{\"light\":0}}}]", TINY_LIGHTS, "",
         "node 2 '': light position (1e+300, 0, 0) is beyond +-1e+18"},
        {"scale_1e30.gltf", "[{\"children\":[1]},{\"name\":\"big\",\"mesh\":0,\"scale\":[1e30,1e30,1e30]}]",
         TINY_LIGHTS, "", "node 1 'big': its transform puts mesh 0's vertices at 1e+30, beyond +-1e+18"},
        {"translate_1e300.gltf", "[{\"children\":[1]},{\"mesh\":0,\"translation\":[0,1e300,0]}]", TINY_LIGHTS, "",
         "node 1 '': transform entry 1e+300 does not fit a float"},
        {"camera_far.gltf", "[{\"children\":[1,2]},{\"mesh\":0},{\"camera\":0,\"translation\":[0,0,1e20]}]",
         TINY_LIGHTS, "", "node 2 '': camera position (0, 0, 1e+20) is beyond"},
        {"intensity.gltf", TINY_NODES, "[{\"type\":\"point\",\"intensity\":1e300}]", "",
         "node 2: light 0: color x intensity 1e+300 does not fit a float"},
        {"ior.gltf", TINY_NODES, TINY_LIGHTS, ",\"KHR_materials_ior\":{\"ior\":1e300}",
         "material 0 'g': KHR_materials_ior.ior 1e+300 does not fit a float"},
        {"attenuation.gltf", TINY_NODES, TINY_LIGHTS,
         ",\"KHR_materials_volume\":{\"thicknessFactor\":1,\"attenuationDistance\":1e-300,"
         "\"attenuationColor\":[0.5,0.5,0.5]}",
         "material 0 'g': KHR_materials_volume: attenuation 6.93147e+299"},
    };
    char dir[64], extra[512];
    size_t i;
    tg_mkdtemp(dir, sizeof dir);
    write_tiny_bin(dir);
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        snprintf(extra, sizeof extra, glass, cases[i].ext);
        if (!cases[i].ext[0]) snprintf(extra, sizeof extra, ",\"materials\":[{}]");
        write_gltf_nodes(dir, cases[i].name, cases[i].nodes, cases[i].lights, TINY_ACCESSORS, mesh, extra);
        expect_tiny_error(dir, cases[i].name, REFL_ERROR_BAD_MESH, cases[i].needle);
    }
    tg_rmdir(dir);
}

/* Every perspective camera node is reachable by its number, depth first;
   one past the last is refused naming the count; a negative picks none. */
Test(gltf, camera_option_picks_each_perspective_camera) {
    refl_gltf_options opt;
    refl_scene *s;
    char err[1024];
    refl_vec3 eyes[8];
    int i, j, count = -1;
    need_assets();
    memset(&opt, 0, sizeof opt);
    opt.camera_count = &count;
    for (i = 0; i < 8; i++) {
        opt.camera = i;
        cr_assert_eq(refl_gltf_load(ASSETS "/ToyCar.glb", &opt, &s, err, sizeof err), REFL_OK, "%s", err);
        cr_expect_eq(count, 8, "ToyCar has 8 perspective cameras");
        cr_expect(s->has_camera);
        eyes[i] = s->camera.eye;
        for (j = 0; j < i; j++)
            cr_expect(eyes[j].x != eyes[i].x || eyes[j].y != eyes[i].y || eyes[j].z != eyes[i].z,
                      "cameras %d and %d sit at one point", j, i);
        refl_scene_destroy(s);
    }
    opt.camera = 8;
    s = (refl_scene *)1;
    cr_expect_eq(refl_gltf_load(ASSETS "/ToyCar.glb", &opt, &s, err, sizeof err), REFL_ERROR_INVALID_ARGUMENT);
    cr_expect_null(s);
    cr_expect(strstr(err, "camera 8 does not exist: the scene has 8 perspective cameras"), "%s", err);
    opt.camera = -1;
    cr_assert_eq(refl_gltf_load(ASSETS "/ToyCar.glb", &opt, &s, err, sizeof err), REFL_OK, "%s", err);
    cr_expect_not(s->has_camera);
    refl_scene_destroy(s);
}

/* emissiveFactor times KHR_materials_emissive_strength on a diffuse
   material; nothing where an emissiveTexture (not drawn) scales it, and a
   warning on a mirror. */
Test(gltf, emission_and_its_strength) {
    char dir[64], path[256], err[1024];
    refl_scene *s;
    tg_mkdtemp(dir, sizeof dir);
    write_tiny_bin(dir);
    write_gltf(dir, "emissive.gltf", TINY_ACCESSORS,
               "[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":2,\"material\":0},"
               "{\"attributes\":{\"POSITION\":0},\"indices\":2,\"material\":1},"
               "{\"attributes\":{\"POSITION\":0},\"indices\":2,\"material\":2}]}]",
               ",\"materials\":[{\"emissiveFactor\":[0.5,0.25,0],"
               "\"extensions\":{\"KHR_materials_emissive_strength\":{\"emissiveStrength\":4}}},"
               "{\"emissiveFactor\":[1,1,1],\"emissiveTexture\":{\"index\":0}},"
               "{\"emissiveFactor\":[1,0,0],\"pbrMetallicRoughness\":{\"metallicFactor\":1,\"roughnessFactor\":0}}],"
               "\"textures\":[{\"source\":0}],\"images\":[{\"uri\":\"missing.png\"}]");
    snprintf(path, sizeof path, "%s/emissive.gltf", dir);
    cr_assert_eq(refl_gltf_load(path, NULL, &s, err, sizeof err), REFL_OK, "%s", err);
    cr_assert_geq(s->material_count, 3);
    cr_expect(s->materials[0].emissive[0] == 2.0f && s->materials[0].emissive[1] == 1.0f &&
              s->materials[0].emissive[2] == 0.0f);
    cr_expect(s->materials[1].emissive[0] == 0.0f, "the factor of a texture not drawn is not drawn either");
    cr_expect_eq(s->materials[2].type, REFL_MIRROR);
    cr_expect(s->materials[2].emissive[0] == 0.0f);
    cr_expect(strstr(err, "emission on a mirror is not drawn"), "%s", err);
    cr_expect(strstr(err, "not drawn: emissiveTexture (1 use)"), "%s", err);
    refl_scene_destroy(s);
    tg_rmdir(dir);
}

/* One warning line per feature the renderer ignores, with its count. */
Test(gltf, ignored_features_are_named) {
    refl_scene *s;
    char err[4096];
    need_assets();
    cr_assert_eq(refl_gltf_load(ASSETS "/ToyCar.glb", NULL, &s, err, sizeof err), REFL_OK, "%s", err);
    cr_expect(strstr(err, "ToyCar.glb: not drawn: normalTexture (2 uses)\n"), "%s", err);
    cr_expect(strstr(err, "not drawn: KHR_materials_sheen (1 use)"), "%s", err);
    cr_expect(strstr(err, "not drawn: KHR_materials_clearcoat (1 use)"), "%s", err);
    cr_expect(strstr(err, "not drawn: KHR_texture_transform (1 use)"), "%s", err);
    refl_scene_destroy(s);
    cr_assert_eq(refl_gltf_load(ASSETS "/MetalRoughSpheresNoTextures.glb", NULL, &s, err, sizeof err), REFL_OK);
    cr_expect_null(strstr(err, "not drawn"), "nothing ignored: %s", err);
    refl_scene_destroy(s);
}

/* A base colour image larger than the limit is refused from its header,
   before it is decoded (Duck's texture is a 512 x 512 PNG). */
Test(gltf, texture_over_the_limit_is_refused_before_decoding) {
    refl_gltf_options opt;
    refl_scene *s;
    char err[1024];
    need_assets();
    memset(&opt, 0, sizeof opt);
    opt.max_texture_pixels = 512 * 512;
    cr_assert_eq(refl_gltf_load(ASSETS "/Duck.glb", &opt, &s, err, sizeof err), REFL_OK, "%s", err);
    cr_expect_eq(s->texture_count, 1);
    refl_scene_destroy(s);
    opt.max_texture_pixels = 512 * 512 - 1;
    cr_expect_eq(refl_gltf_load(ASSETS "/Duck.glb", &opt, &s, err, sizeof err), REFL_ERROR_INVALID_SIZE);
    cr_expect(strstr(err, "image 0 is 512x512, more than the texture limit of 262143 pixels"), "%s", err);
}

/* A device streams without end: refused before a byte is read. */
Test(gltf, not_a_regular_file) {
    refl_scene *s;
    char err[1024];
    cr_expect_eq(refl_gltf_load("/dev/zero", NULL, &s, err, sizeof err), REFL_ERROR_INVALID_SIZE);
    cr_expect(strstr(err, "/dev/zero: not a regular file"), "%s", err);
}
