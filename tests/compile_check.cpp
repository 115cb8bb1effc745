// Compile check: the whole of rast.h and reflect.h, implementations included, as C++11 with
// -Wall -Wextra -Werror. Built (never run) by `make` and `make test`.
#define RAST_IMPLEMENTATION
#define REFL_IMPLEMENTATION
#include "../reflect.h" /* includes rast.h */

// Touches the public API the way a C++ caller would.
int rast_compile_check_cpp();
int rast_compile_check_cpp() {
    rast_context *ctx = nullptr;
    rast_context_desc cd = {};
    rast_state s = {};
    rast_draw_desc d = {};
    static const float tri[3 * 8] = {
        -1, -1, 0, 1,  1, 0, 0, 1,
         1, -1, 0, 1,  0, 1, 0, 1,
         0,  1, 0, 1,  0, 0, 1, 1,
    };
    if (rast_context_create(&cd, &ctx) != RAST_OK) return 1;
    s.depth_test = 1;
    s.stencil_front.write_mask = RAST_MASK(0x0F);
    rast_set_state(ctx, &s);
    d.primitive = RAST_TRIANGLES;
    d.vertices = tri;
    d.vertex_count = 3;
    d.num_varyings = 4;
    rast_draw(ctx, &d);
    rast_finish(ctx);
    rast_context_destroy(ctx);
    return rast_result_string(RAST_OK) != nullptr;
}

// And reflect.h's entry points.
int refl_compile_check_cpp();
int refl_compile_check_cpp() {
    refl_scene *scene = nullptr;
    if (refl_scene_builtin("default", nullptr, &scene) != REFL_OK) return 1;
    refl_frame *frame = nullptr;
    refl_view v = scene->camera;
    v.width = 8;
    v.height = 8;
    refl_render_desc rd = {};
    refl_render_desc kept = {};
    refl_renderer *renderer = nullptr;
    kept.method = REFL_ENVMAP;
    if (refl_frame_create(8, 8, nullptr, &frame) == REFL_OK) refl_render(scene, &v, &rd, frame);
    if (refl_renderer_create(scene, &kept, &renderer) == REFL_OK) refl_renderer_render(renderer, &v, frame);
    refl_renderer_destroy(renderer);
    refl_frame_destroy(frame);
    refl_scene_destroy(scene);
    return 0;
}
