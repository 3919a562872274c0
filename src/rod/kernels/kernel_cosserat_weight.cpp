#include "sweep_impl.h"

HYDROJET_ROD_KERNELS(true, true, false)
