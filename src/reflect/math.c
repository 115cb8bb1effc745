/* math: being written. */
#include "internal.h"
