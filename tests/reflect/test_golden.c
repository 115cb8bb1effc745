/* Every method on every built-in scene, and a few settings of each, render
   the bytes recorded in the table below (a 64-bit FNV-1a digest of the
   frame's colour, depth, stencil and points). A change that alters any image
   must say so by updating the table; REFL_GOLDEN_PRINT=1 prints it anew. */
#include <criterion/criterion.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "../../reflect.h"
#include "refl_test_util.h"

typedef struct golden_case {
    const char *scene;
    const char *setting;     /* a method name, or one of the variants below */
    uint64_t digest;
} golden_case;

/* The render desc of a setting. */
static refl_render_desc golden_desc(const char *setting) {
    refl_render_desc d;
    memset(&d, 0, sizeof d);
    d.threads = 2;
    if (!strcmp(setting, "sbc-fallback")) {
        d.method = REFL_SBC;
        d.sbc.trace_fallback = 1;
    } else if (!strcmp(setting, "sbc-f4-depth2")) {
        d.method = REFL_SBC;
        d.sbc.ray_factor = 4;
        d.depth = 2;
        d.debug.points_last = 1;
    } else if (!strcmp(setting, "c3rc-one-camera")) {
        d.method = REFL_C3RC;
        d.c3rc.camera_split_px = -1.0f;
        d.c3rc.max_splat = 4;
        d.c3rc.kd_leaf_points = 200;
    } else if (!strcmp(setting, "planar-shadows")) {
        d.method = REFL_PLANAR;
        d.lighting.shadows = 1;
        d.lighting.soft_shadow_samples = 3;
        d.lighting.light_volumes = 1;
    } else if (!strcmp(setting, "planar-no-culling")) {
        d.method = REFL_PLANAR;
        d.planar.no_culling = 1;
        d.depth = 3;
        d.lighting.translucency = 0.5f;
    } else if (!strcmp(setting, "raytrace-volumes")) {
        d.method = REFL_RAYTRACE;
        d.lighting.shadows = 1;
        d.lighting.light_volumes = 1;
        d.lighting.caustic_samples = 2;
        d.debug.points_last = 1;
    } else if (!strcmp(setting, "envmap-64")) {
        d.method = REFL_ENVMAP;
        d.envmap.size = 64;
        d.lighting.shadows = 1;
    } else {
        d.method = refl_method_from_name(setting);
        cr_assert(d.method != REFL_METHOD_DEFAULT || !strcmp(setting, "direct"), "unknown setting %s", setting);
    }
    return d;
}

static const golden_case golden_cases[] = {
    {"default", "direct", 0x25d9a4b808333eafull},
    {"default", "raytrace", 0x8e1ba9c7e3ee052cull},
    {"default", "envmap", 0x44b0284d5d58e212ull},
    {"default", "planar", 0x28ea7f0353c87c97ull},
    {"default", "c3rc", 0xf31ae19cb5c195feull},
    {"default", "sbc", 0x1d028ba3a375e6e2ull},
    {"default", "sbc-fallback", 0xfda6070dd1321464ull},
    {"default", "c3rc-one-camera", 0x7329c2a004fc291dull},
    {"default", "envmap-64", 0x2474464aa37f43c4ull},
    {"mirror-room", "direct", 0xd6b636c1996fb175ull},
    {"mirror-room", "raytrace", 0x3aca03dadd14677bull},
    {"mirror-room", "envmap", 0x1fd44ac3100c8d7eull},
    {"mirror-room", "planar", 0xafb9a409d2f57b85ull},
    {"mirror-room", "c3rc", 0x2e28558ffe1c42d0ull},
    {"mirror-room", "sbc", 0x28c813ceeefaceb0ull},
    {"mirror-room", "sbc-f4-depth2", 0xdc80205ab000c3a4ull},
    {"mirror-room", "planar-shadows", 0x7a7c0e3423b28982ull},
    {"mirror-room", "planar-no-culling", 0x6018fdfe164daf14ull},
    {"mirror-room", "raytrace-volumes", 0x657adb07c7207175ull},
    {"concave", "direct", 0xe57075333d040a3full},
    {"concave", "raytrace", 0x0aa69e24c679f72cull},
    {"concave", "envmap", 0x73e9d6dd35cc0fa5ull},
    {"concave", "planar", 0x2ecce22de74556c8ull},
    {"concave", "c3rc", 0xc08b4b2acd6397f9ull},
    {"concave", "sbc", 0xbb080c9db445a659ull},
    {"concave", "sbc-fallback", 0xc32369faad7ef671ull},
    {"glass", "direct", 0x2e3444e9a05d8becull},
    {"glass", "raytrace", 0xd1b1041013739232ull},
    {"glass", "envmap", 0x5f414e741f187642ull},
    {"glass", "planar", 0x270ac25a5c70b376ull},
    {"glass", "c3rc", 0x438f2d79075f216aull},
    {"glass", "sbc", 0xaab0146a4d249803ull},
    {"glass", "planar-no-culling", 0xe290c3052db7429cull},
    {"glass", "raytrace-volumes", 0x2a58249256381a9cull},
};

Test(refl_golden, every_method_on_every_builtin_scene_renders_the_recorded_bytes, .timeout = 300) {
    size_t i, n = sizeof golden_cases / sizeof golden_cases[0];
    int print = getenv("REFL_GOLDEN_PRINT") != NULL, bad = 0;
    for (i = 0; i < n; ++i) {
        const golden_case *c = &golden_cases[i];
        refl_view v;
        refl_scene *s = tu_refl_builtin(c->scene, &v, 96, 72);
        refl_render_desc d = golden_desc(c->setting);
        refl_frame *f = tu_refl_render(s, &v, &d);
        uint64_t h = tu_refl_digest(f);
        if (print) printf("    {\"%s\", \"%s\", 0x%016llxull},\n", c->scene, c->setting, (unsigned long long)h);
        if (h != c->digest) {
            fprintf(stderr, "%s %s: digest 0x%016llx, recorded 0x%016llx\n", c->scene, c->setting,
                    (unsigned long long)h, (unsigned long long)c->digest);
            bad++;
        }
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
    cr_assert_eq(bad, 0, "%d of %zu settings render other bytes than recorded", bad, n);
}
