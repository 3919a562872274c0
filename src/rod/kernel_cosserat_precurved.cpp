// Single-shooting kernels for RodTerms<true, false, true> (cosserat + precurved); see kernel_impl.h.
#include "kernel_impl.h"

HYDROJET_ROD_KERNELS(true, false, true)
