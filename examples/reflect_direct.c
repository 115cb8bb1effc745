/* reflect_direct: one frame of a built-in scene through reflect.h, written
   as a binary PPM. The smallest complete use of refl_render.

     build/examples/reflect_direct [SCENE [OUT.ppm]]   (SCENE: default) */
#define RAST_IMPLEMENTATION
#define REFL_IMPLEMENTATION
#include "../reflect.h"

#include <stdio.h>

int main(int argc, char **argv) {
    const char *name = argc > 1 ? argv[1] : "default";
    const char *out = argc > 2 ? argv[2] : "out/reflect_direct.ppm";
    refl_scene *scene = NULL;
    refl_frame *frame = NULL;
    refl_render_desc rd = {0}; /* method 0: DIRECT; threads 0: one per CPU */
    refl_view view;
    refl_result r;
    FILE *f;
    int i;
    if ((r = refl_scene_builtin(name, NULL, &scene)) != REFL_OK) {
        fprintf(stderr, "reflect_direct: scene '%s': %s\n", name, refl_result_string(r));
        return 1;
    }
    view = scene->camera; /* every built-in scene has one */
    view.width = 640;
    view.height = 480;
    if ((r = refl_frame_create(view.width, view.height, NULL, &frame)) != REFL_OK ||
        (r = refl_render(scene, &view, &rd, frame)) != REFL_OK) {
        fprintf(stderr, "reflect_direct: %s\n", refl_result_string(r));
        refl_frame_destroy(frame);
        refl_scene_destroy(scene);
        return 1;
    }
    /* colour is linear: sRGB-encoded to 8 bits, top row first, as PPM wants it */
    if (!(f = fopen(out, "wb"))) {
        perror(out);
    } else {
        fprintf(f, "P6\n%d %d\n255\n", frame->width, frame->height);
        for (i = 0; i < frame->width * frame->height; ++i) {
            uint8_t px[3];
            int c;
            for (c = 0; c < 3; ++c) px[c] = refl_display_channel(frame->rgba[4 * i + c], NULL);
            fwrite(px, 1, 3, f);
        }
        fclose(f);
        printf("reflect_direct: %s, %d reflector(s) left for the methods to fill, %lld triangles -> %s\n", name,
               frame->stats.reflectors, frame->stats.triangles, out);
    }
    refl_frame_destroy(frame);
    refl_scene_destroy(scene);
    return f ? 0 : 1;
}
