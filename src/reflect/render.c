/* render: being written. */
#include "internal.h"
