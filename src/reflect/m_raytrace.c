/* RAYTRACE: the reference (in progress). */
#include "internal.h"

static refl_result refl__method_raytrace(refl__pass *p) {
    (void)p;
    return REFL_ERROR_UNSUPPORTED;
}
