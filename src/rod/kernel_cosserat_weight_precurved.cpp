// Single-shooting kernels for RodTerms<true, true, true> (cosserat + weight + precurved); see kernel_impl.h.
#include "kernel_impl.h"

HYDROJET_ROD_KERNELS(true, true, true)
