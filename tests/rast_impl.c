/* The rast.h implementation, compiled once for the tests and the benchmarks. */
#define RAST_IMPLEMENTATION
#include "../rast.h"
