// Single-shooting kernels for RodTerms<true, false, false> (cosserat); see kernel_impl.h.
#include "kernel_impl.h"

HYDROJET_ROD_KERNELS(true, false, false)
