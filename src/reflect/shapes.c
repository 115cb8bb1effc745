/* shapes: being written. */
#include "internal.h"
