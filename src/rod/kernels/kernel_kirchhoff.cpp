#include "sweep_impl.h"

HYDROJET_ROD_KERNELS(false, false, false)
