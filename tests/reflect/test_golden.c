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
    {"default", "direct", 0x690a87ee85247ae1ull},
    {"default", "raytrace", 0xb0ec8838296e366dull},
    {"default", "envmap", 0x51bbbf64f3699c41ull},
    {"default", "planar", 0xefc4107abc7623deull},
    {"default", "c3rc", 0xb2a61dd49cee2f3dull},
    {"default", "sbc", 0x65fa30ccc4f7ff3bull},
    {"default", "sbc-fallback", 0x2fe60dd42f2d6947ull},
    {"default", "c3rc-one-camera", 0x7bd479b3cf982ca8ull},
    {"default", "envmap-64", 0x435afa0765c65382ull},
    {"mirror-room", "direct", 0x13fb59e17f2d8748ull},
    {"mirror-room", "raytrace", 0xb9929847f790cf11ull},
    {"mirror-room", "envmap", 0x7ea697260cb8bce9ull},
    {"mirror-room", "planar", 0x7fd21c38b918dd97ull},
    {"mirror-room", "c3rc", 0x0f9cbb40154522c7ull},
    {"mirror-room", "sbc", 0x1b20144537024df6ull},
    {"mirror-room", "sbc-f4-depth2", 0x715fb71dd3272b6aull},
    {"mirror-room", "planar-shadows", 0xe1dd50de7376eb33ull},
    {"mirror-room", "planar-no-culling", 0xd2a6936952991b2cull},
    {"mirror-room", "raytrace-volumes", 0x9e5bf8e54baf152dull},
    {"concave", "direct", 0x1279b06a45b5598eull},
    {"concave", "raytrace", 0x2bf52809a1bb281bull},
    {"concave", "envmap", 0x1c29dd7f8107e08eull},
    {"concave", "planar", 0x90b8193994750485ull},
    {"concave", "c3rc", 0x933b4f427cf23363ull},
    {"concave", "sbc", 0x7dca1e01af3e379aull},
    {"concave", "sbc-fallback", 0x1affeedba5b541b9ull},
    {"glass", "direct", 0x0ebe79c8a2045c18ull},
    {"glass", "raytrace", 0x6f87c7ac0f40daf3ull},
    {"glass", "envmap", 0x40bd20800e314724ull},
    {"glass", "planar", 0x016d0d8ee8e0f9a5ull},
    {"glass", "c3rc", 0x5a2f0adc188cb550ull},
    {"glass", "sbc", 0x998fe96c8eb94398ull},
    {"glass", "planar-no-culling", 0x8b477bff0cff4c60ull},
    {"glass", "raytrace-volumes", 0x62066197db78627aull},
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
