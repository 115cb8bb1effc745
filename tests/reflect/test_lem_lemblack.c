/* LAYERED_EM's direct images from the viewpoint reach only what lies past
   the lens from the sample's views: a mirror's texels that its reflected
   exit rays alone look up (the sky above the rim of `hybrid`'s mirror
   cup) may hold no row of them, nor of the lens images where the samples
   see no such exit ray. Such a texel must still be solved (from the
   centre's direct image), not left at 0 and drawn black. */
#include <criterion/criterion.h>
#include "../../reflect.h"
#include "refl_test_util.h"

/* Method m on `hybrid`: one desc for both, each method reading its own
   options (RAYTRACE greedy, LAYERED_EM's direct images from the
   viewpoint). */
static refl_frame *render(const refl_scene *s, const refl_view *v, refl_method m) {
    refl_render_desc d = tu_refl_desc(m, 2);
    d.raytrace.greedy = 1;
    d.layered_em.direct_from = REFL_LEM_DIRECT_FROM_VIEWPOINT;
    return tu_refl_render(s, v, &d);
}

Test(lem_lemblack, viewpoint_direct_images_leave_no_texel_black) {
    /* `hybrid` at 128 x 96: the mirror cup's pixels LAYERED_EM draws black
       where greedy RAYTRACE is bright (a channel over 0.2: the sky above
       the rim is 0.45 in blue; one dark grey floor pixel, 0.14, is black
       with the centre's direct images too, left out) */
    refl_view v;
    refl_scene *s = tu_refl_builtin("hybrid", &v, 128, 96);
    refl_frame *truth, *lem;
    size_t n = (size_t)v.width * (size_t)v.height, px;
    int i, cup = -1, pixels = 0, black = 0;
    for (i = 0; i < s->object_count; ++i)
        if (s->materials[s->objects[i].material].type == REFL_MIRROR) cup = i;
    cr_assert_geq(cup, 0, "hybrid has a mirror");
    truth = render(s, &v, REFL_RAYTRACE);
    lem = render(s, &v, REFL_LAYERED_EM);
    for (px = 0; px < n; ++px) {
        const float *a = lem->rgba + 4 * px, *t = truth->rgba + 4 * px;
        if (truth->stencil[px] != cup + 1) continue;
        ++pixels;
        black += a[0] <= 0.0f && a[1] <= 0.0f && a[2] <= 0.0f && (t[0] > 0.2f || t[1] > 0.2f || t[2] > 0.2f);
    }
    cr_log_info("hybrid 128x96, direct images from the viewpoint: %d of the cup's %d pixels black", black, pixels);
    cr_assert_gt(pixels, 100);
    cr_assert_eq(black, 0, "%d of the cup's %d pixels black where greedy RAYTRACE is bright", black, pixels);
    refl_frame_destroy(truth);
    refl_frame_destroy(lem);
    refl_scene_destroy(s);
}
