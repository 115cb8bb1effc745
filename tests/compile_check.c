/* Compile check: the whole of rast.h and reflect.h, implementations included, as C99 with
   -Wall -Wextra -Werror. Built (never run) by `make` and `make test`. */
#define RAST_IMPLEMENTATION
#define REFL_IMPLEMENTATION
#include "../reflect.h" /* includes rast.h */

/* Touches the public API the way the README's example does. */
int rast_compile_check_c(void);
int rast_compile_check_c(void) {
    rast_context *ctx;
    rast_context_desc cd = {0};
    rast_state s = {0};
    rast_draw_desc d = {0};
    static const float tri[3 * 8] = {
        -1, -1, 0, 1,  1, 0, 0, 1,
         1, -1, 0, 1,  0, 1, 0, 1,
         0,  1, 0, 1,  0, 0, 1, 1,
    };
    if (rast_context_create(&cd, &ctx) != RAST_OK) return 1;
    s.depth_test = 1;
    rast_set_state(ctx, &s);
    d.primitive = RAST_TRIANGLES;
    d.vertices = tri;
    d.vertex_count = 3;
    d.num_varyings = 4;
    rast_draw(ctx, &d);
    rast_finish(ctx);
    rast_context_destroy(ctx);
    return rast_result_string(RAST_OK) != NULL;
}
