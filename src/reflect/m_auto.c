/* AUTO: per reflector, after the base pass, the cheapest method whose
   predicted error meets desc.automatic.error_budget_px, by the models of
   auto_model.c; the reflector is then drawn by that method's row like any
   other (render.c). The choice depends only on the scene, the view and the
   base pass's stencil, so it is the same for every thread count. */
#include "internal.h"

static const char *refl__options_auto(refl_render_desc *d) {
    if (!(d->automatic.error_budget_px >= 0.0f) || !refl__isfinite(d->automatic.error_budget_px))
        return "automatic.error_budget_px: finite, 0 (1 px) or more";
    if (d->automatic.error_budget_px == 0.0f) d->automatic.error_budget_px = 1.0f;
    return NULL;
}

/* AUTO's method for reflector `object` into *out, the reason in the
   frame's stats: the cheapest candidate predicted within the budget (with
   no pixels on screen, the cheapest); with none, the least error. Ties go to the method first in refl_method order; with no
   candidate at all, RAYTRACE (it draws anything exactly). */
static refl_result refl__auto_choose(refl__pass *p, int object, refl_method *out) {
    refl_auto_frame_stats *st = &p->frame->stats.automatic;
    refl_auto_models builtin;
    const refl_auto_models *models = p->desc.automatic.models;
    refl_auto_choice ch;
    float budget = p->desc.automatic.error_budget_px;
    int m, best = -1, least = -1;
    refl_result r;
    memset(&ch, 0, sizeof ch);
    if (!models) {
        refl_auto_models_builtin(&builtin);
        models = &builtin;
    }
    r = refl__auto_features(p->scene, object, &p->rays, p->frame,
                            refl__auto_pixels(p->frame->stencil,
                                              (size_t)p->frame->width * (size_t)p->frame->height, object),
                            &ch.features);
    if (r != REFL_OK) return r;
    if (p->desc.depth < 2) ch.features.beyond = 0.0f; /* no bounce past the first is followed */
    ch.object = object;
    for (m = 0; m < REFL_METHOD_COUNT; ++m) {
        const refl_auto_model *model = &models->model[m][ch.features.reflector_class];
        int can = 0;
        if (!model->fitted || !refl__auto_modelled((refl_method)m)) continue;
        if ((r = refl__method_can_draw(p, (refl_method)m, object, &can)) != REFL_OK) return r;
        ch.candidate[m] = (signed char)(can ? 1 : -1);
        if (!can) continue;
        refl_auto_predict(model, &ch.features, &ch.error_px[m], &ch.cost_ms[m]);
        /* off screen (seen only in other reflectors, if at all): no error of its own shows */
        if ((ch.error_px[m] <= budget || !ch.features.pixels) && (best < 0 || ch.cost_ms[m] < ch.cost_ms[best]))
            best = m;
        if (least < 0 || ch.error_px[m] < ch.error_px[least] ||
            (ch.error_px[m] == ch.error_px[least] && ch.cost_ms[m] < ch.cost_ms[least]))
            least = m;
    }
    ch.over_budget = best < 0;
    ch.method = best >= 0 ? (refl_method)best : least >= 0 ? (refl_method)least : REFL_RAYTRACE;
    st->budget_px = budget;
    if (st->count < REFL_AUTO_MAX_CHOICES) st->choices[st->count] = ch;
    st->count++;
    *out = ch.method;
    return REFL_OK;
}
