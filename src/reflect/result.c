/* What the calls return: refl_result's strings, and rast.h's results as
   refl_result. */
#include "internal.h"

REFL_API const char *refl_result_string(refl_result result) {
    switch (result) {
    case REFL_OK: return "ok";
    case REFL_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case REFL_ERROR_INVALID_SIZE: return "invalid size (zero, negative, or too large)";
    case REFL_ERROR_OUT_OF_MEMORY: return "out of memory";
    case REFL_ERROR_BAD_MESH: return "bad mesh (indices out of range, non-finite positions or no triangles)";
    case REFL_ERROR_UNKNOWN_NAME: return "unknown name";
    case REFL_ERROR_SINGULAR: return "singular or ill-conditioned system";
    case REFL_ERROR_UNSUPPORTED: return "method not available";
    case REFL_ERROR_RASTER: return "rasteriser error";
    case REFL_ERROR_CANCELLED: return "cancelled";
    }
    return "unknown refl_result";
}

static refl_result refl__result_from_rast(rast_result r) {
    return r == RAST_OK ? REFL_OK : r == RAST_ERROR_OUT_OF_MEMORY ? REFL_ERROR_OUT_OF_MEMORY : REFL_ERROR_RASTER;
}
