/* reflect_scene: a scene built in code (a mirror sphere and a glass cube on
   a floor), completed with a camera, a key light and a sky, rendered with
   SBC and its ray-traced fallback along a short camera path by one
   renderer, each frame written as an sRGB PPM. Needs nothing but the two
   headers.

     build/examples/reflect_scene [OUTDIR]   (OUTDIR: out; writes scene-0.ppm ...) */
#define RAST_IMPLEMENTATION
#define REFL_IMPLEMENTATION
#include "../reflect.h"

#include <stdio.h>
#include <stdlib.h>

/* Binary PPM of RGBA8 pixels, top row first. */
static int write_ppm(const char *path, const uint8_t *rgba, int width, int height) {
    FILE *f = fopen(path, "wb");
    int i, ok;
    if (!f) return 0;
    fprintf(f, "P6\n%d %d\n255\n", width, height);
    for (i = 0; i < width * height; ++i) fwrite(rgba + 4 * i, 1, 3, f);
    ok = !ferror(f);
    return fclose(f) == 0 && ok;
}

/* The scene: every refl_scene_add returns the object's index or an error. */
static refl_result build(refl_scene **out) {
    refl_scene *s = NULL;
    refl_mesh *m = NULL;
    refl_material floor_m = refl_material_diffuse(0.7f, 0.7f, 0.65f), mirror = refl_material_mirror(0.9f),
                  glass = refl_material_glass(1.5f), red = refl_material_diffuse(0.8f, 0.15f, 0.1f);
    refl_light lamp = refl_light_point(refl_v3(3.0f, 6.0f, 4.0f), 1.0f);
    refl_result r = refl_scene_create(NULL, &s);
    int k = 0;
    if (r == REFL_OK && (r = refl_mesh_plane(6.0f, 1, NULL, &m)) == REFL_OK)
        k = refl_scene_add(s, m, &floor_m, refl_mat4_identity());
    if (r == REFL_OK && k >= 0 && (r = refl_mesh_sphere(1.0f, 48, 24, NULL, &m)) == REFL_OK)
        k = refl_scene_add(s, m, &mirror, refl_mat4_translate(refl_v3(0.0f, 1.0f, 0.0f)));
    if (r == REFL_OK && k >= 0 && (r = refl_mesh_box(refl_v3(1.0f, 1.0f, 1.0f), NULL, &m)) == REFL_OK)
        k = refl_scene_add(s, m, &glass, refl_mat4_translate(refl_v3(1.8f, 0.5f, 1.0f)));
    if (r == REFL_OK && k >= 0 && (r = refl_mesh_torus(0.6f, 0.25f, 32, 16, NULL, &m)) == REFL_OK)
        k = refl_scene_add(s, m, &red, refl_mat4_translate(refl_v3(-1.8f, 0.25f, 0.8f)));
    if (r == REFL_OK && k >= 0) k = refl_scene_add_light(s, &lamp);
    if (r == REFL_OK && k < 0) r = (refl_result)k;
    if (r == REFL_OK) refl_scene_complete(s); /* a camera framing it, and a sky */
    if (r != REFL_OK) refl_scene_destroy(s);
    *out = r == REFL_OK ? s : NULL;
    return r;
}

int main(int argc, char **argv) {
    const char *dir = argc > 1 ? argv[1] : "out";
    refl_scene *scene = NULL;
    refl_renderer *renderer = NULL;
    refl_frame *frame = NULL;
    refl_render_desc rd = {0};
    uint8_t *srgb = NULL;
    refl_result r;
    int k, ok = 1;
    rd.method = REFL_SBC;
    rd.sbc.trace_fallback = 1;   /* the pixels SBC leaves are ray traced */
    rd.lighting.shadows = 1;
    if ((r = build(&scene)) != REFL_OK) {
        fprintf(stderr, "reflect_scene: %s\n", refl_result_string(r));
        return 1;
    }
    r = refl_frame_create(480, 360, NULL, &frame);
    if (r == REFL_OK) r = refl_renderer_create(scene, &rd, &renderer);
    if (r == REFL_OK && !(srgb = (uint8_t *)malloc((size_t)480 * 360 * 4))) r = REFL_ERROR_OUT_OF_MEMORY;
    for (k = 0; r == REFL_OK && ok && k < 3; ++k) {
        refl_view view = scene->camera;
        char path[512];
        view.width = 480;
        view.height = 360;
        view.eye.x += 0.6f * (float)k; /* a short dolly sideways: the BVH is built once */
        if ((r = refl_renderer_render(renderer, &view, frame)) != REFL_OK) break;
        refl_frame_to_srgb8(frame, NULL, srgb);
        snprintf(path, sizeof path, "%s/scene-%d.ppm", dir, k);
        ok = write_ppm(path, srgb, frame->width, frame->height);
        printf("reflect_scene: %s%s, %.1f ms, %lld rays traced\n", path, ok ? "" : " (not written)",
               frame->stats.ms_total, frame->stats.rays);
    }
    if (r != REFL_OK)
        fprintf(stderr, "reflect_scene: %s%s%s\n", refl_result_string(r), frame && frame->message[0] ? ": " : "",
                frame ? frame->message : "");
    free(srgb);
    refl_renderer_destroy(renderer);
    refl_frame_destroy(frame);
    refl_scene_destroy(scene);
    return r == REFL_OK && ok ? 0 : 1;
}
