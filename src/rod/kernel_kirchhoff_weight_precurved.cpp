// Single-shooting kernels for RodTerms<false, true, true> (kirchhoff + weight + precurved); see kernel_impl.h.
#include "kernel_impl.h"

HYDROJET_ROD_KERNELS(false, true, true)
