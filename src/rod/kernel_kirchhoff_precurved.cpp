// Single-shooting kernels for RodTerms<false, false, true> (kirchhoff + precurved); see kernel_impl.h.
#include "kernel_impl.h"

HYDROJET_ROD_KERNELS(false, false, true)
