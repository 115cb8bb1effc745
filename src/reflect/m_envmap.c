/* ENVMAP: the classic baseline (in progress). */
#include "internal.h"

static refl_result refl__method_envmap(refl__pass *p) {
    (void)p;
    return REFL_ERROR_UNSUPPORTED;
}
