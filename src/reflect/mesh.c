/* mesh: being written. */
#include "internal.h"
