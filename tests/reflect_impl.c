/* The reflect.h implementation (rast.h is implemented in rast_impl.c). */
#define REFL_IMPLEMENTATION
#include "../reflect.h"
