// Single-shooting kernels for RodTerms<false, true, false> (kirchhoff + weight); see kernel_impl.h.
#include "kernel_impl.h"

HYDROJET_ROD_KERNELS(false, true, false)
