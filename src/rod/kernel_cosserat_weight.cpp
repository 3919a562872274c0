// Single-shooting kernels for RodTerms<true, true, false> (cosserat + weight); see kernel_impl.h.
#include "kernel_impl.h"

HYDROJET_ROD_KERNELS(true, true, false)
