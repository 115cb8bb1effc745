/* The reflect.h implementation (rast.h is implemented in rast_impl.c).
   POSIX for clock_gettime: the stats carry wall-clock timings. */
#define _POSIX_C_SOURCE 200809L
#define REFL_IMPLEMENTATION
#include "../reflect.h"
