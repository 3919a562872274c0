// Multiple shooting's node sweeps (9 directions) of every variant (see sweep_impl.h).
#include "sweep_impl.h"

namespace hydrojet {
namespace rod {
namespace internal {

template struct Sweep<9, RodTerms<false, false, false>>;
template struct Sweep<9, RodTerms<false, false, true>>;
template struct Sweep<9, RodTerms<false, true, false>>;
template struct Sweep<9, RodTerms<false, true, true>>;
template struct Sweep<9, RodTerms<true, false, false>>;
template struct Sweep<9, RodTerms<true, false, true>>;
template struct Sweep<9, RodTerms<true, true, false>>;
template struct Sweep<9, RodTerms<true, true, true>>;

}  // namespace internal
}  // namespace rod
}  // namespace hydrojet
