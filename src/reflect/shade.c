/* shade: being written. */
#include "internal.h"
