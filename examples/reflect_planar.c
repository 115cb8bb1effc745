/* reflect_planar: a hall of mirrors with a glass slab, through PLANAR
   (paper 002's stencil recursion) and through the ray-traced reference,
   side by side, with how far apart they are.

     build/examples/reflect_planar [DEPTH [OUT.ppm]]   (DEPTH: 4)

   OUT.ppm gets PLANAR on the left and RAYTRACE on the right. */
#define _POSIX_C_SOURCE 200809L
#define RAST_IMPLEMENTATION
#define REFL_IMPLEMENTATION
#include "../reflect.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The mirror room with a slab of glass standing in it. */
static refl_result hall_of_mirrors(refl_scene **out) {
    refl_scene *s;
    refl_mesh *slab;
    refl_material glass;
    refl_object o;
    refl_result r = refl_scene_builtin("mirror-room", NULL, &s);
    if (r != REFL_OK) return r;
    memset(&glass, 0, sizeof glass);
    glass.type = REFL_GLASS;
    glass.ior = 1.5f;
    glass.tint[0] = 0.85f; glass.tint[1] = 0.95f; glass.tint[2] = 1.0f;
    memset(&o, 0, sizeof o);
    if ((r = refl_mesh_box(refl_v3(1.6f, 1.4f, 0.25f), NULL, &slab)) != REFL_OK) {
        refl_scene_destroy(s);
        return r;
    }
    o.mesh = refl_scene_add_mesh(s, slab);
    o.material = refl_scene_add_material(s, &glass);
    o.transform = refl_mat4_mul(refl_mat4_translate(refl_v3(-0.9f, 0.71f, -1.2f)),
                                refl_mat4_rotate(refl_v3(0, 1, 0), 0.5f));
    if (o.mesh < 0 || o.material < 0 || refl_scene_add_object(s, &o) < 0) {
        refl_scene_destroy(s);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    *out = s;
    return REFL_OK;
}

int main(int argc, char **argv) {
    int depth = argc > 1 ? atoi(argv[1]) : 4;
    const char *out = argc > 2 ? argv[2] : "out/reflect_planar.ppm";
    refl_scene *scene = NULL;
    refl_frame *planar = NULL, *truth = NULL;
    refl_render_desc rd;
    refl_view view;
    refl_image_error ie;
    refl_reflection_error re;
    refl_result r;
    FILE *f;
    int x, y;
    if (depth < 1 || depth > 16) depth = 4;
    if ((r = hall_of_mirrors(&scene)) != REFL_OK) {
        fprintf(stderr, "reflect_planar: %s\n", refl_result_string(r));
        return 1;
    }
    view = scene->camera;
    view.width = 640;
    view.height = 480;
    memset(&rd, 0, sizeof rd);
    rd.depth = depth;
    if ((r = refl_frame_create(view.width, view.height, NULL, &planar)) != REFL_OK ||
        (r = refl_frame_create(view.width, view.height, NULL, &truth)) != REFL_OK)
        goto fail;
    rd.method = REFL_PLANAR;
    if ((r = refl_render(scene, &view, &rd, planar)) != REFL_OK) goto fail;
    rd.method = REFL_RAYTRACE;
    if ((r = refl_render(scene, &view, &rd, truth)) != REFL_OK) goto fail;
    refl_measure_image_error(planar, truth, 1, 0.0f, &ie);
    refl_measure_reflection_error(planar, truth, NULL, &re);
    printf("reflect_planar: depth %d: PLANAR %.1f ms (%lld renderings, %lld culled), RAYTRACE %.1f ms\n", depth,
           planar->stats.ms_total, planar->stats.planar.renderings, planar->stats.planar.culled, truth->stats.ms_total);
    printf("  over %lld reflector pixels: PSNR %.1f dB, reflection error %.2f px mean, %.2f px p95\n", ie.pixels,
           ie.psnr, re.mean, re.p95);
    if (!(f = fopen(out, "wb"))) {
        perror(out);
        refl_frame_destroy(planar);
        refl_frame_destroy(truth);
        refl_scene_destroy(scene);
        return 1;
    }
    fprintf(f, "P6\n%d %d\n255\n", 2 * view.width, view.height);
    for (y = 0; y < view.height; ++y)
        for (x = 0; x < 2 * view.width; ++x) {
            const refl_frame *src = x < view.width ? planar : truth;
            const float *p = src->rgba + 4 * ((size_t)y * (size_t)view.width + (size_t)(x % view.width));
            int c;
            for (c = 0; c < 3; ++c) fputc(refl_display_channel(p[c], NULL), f);
        }
    fclose(f);
    printf("  -> %s (PLANAR left, RAYTRACE right)\n", out);
    refl_frame_destroy(planar);
    refl_frame_destroy(truth);
    refl_scene_destroy(scene);
    return 0;
fail:
    fprintf(stderr, "reflect_planar: %s\n", refl_result_string(r));
    refl_frame_destroy(planar);
    refl_frame_destroy(truth);
    refl_scene_destroy(scene);
    return 1;
}
