/* scene: being written. */
#include "internal.h"
