/* metrics: reflection error in pixels and image error (in progress). */
#include "internal.h"

REFL_API refl_result refl_measure_reflection_error(const refl_frame *test, const refl_frame *truth,
                                           const refl_error_desc *desc, refl_reflection_error *out) {
    (void)test; (void)truth; (void)desc; (void)out;
    return REFL_ERROR_UNSUPPORTED;
}

REFL_API refl_result refl_measure_image_error(const refl_frame *test, const refl_frame *truth, int reflectors_only,
                                             float threshold, refl_image_error *out) {
    (void)test; (void)truth; (void)reflectors_only; (void)threshold; (void)out;
    return REFL_ERROR_UNSUPPORTED;
}
