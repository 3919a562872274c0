// The self-test's libFuzzer probe (scripts/ci_selftest through scripts/fuzz SECONDS
// selftest_fuzz): sums the bytes like a harmless parser; HYDROJET_SELFTEST_INJECT=fuzz_crash
// reads past its buffer (ASan), =fuzz_leak leaks on every input (LeakSanitizer in libFuzzer).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "injection.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool crash = hydrojet::selftest::injected("fuzz_crash");
  static const bool leak = hydrojet::selftest::injected("fuzz_leak");
  std::vector<uint8_t> copy(data, data + size);
  unsigned sum = 0;
  for (size_t i = 0; i < copy.size() + (crash && size > 0 ? 1 : 0); ++i) sum += copy.data()[i];
  if (leak) hydrojet::selftest::leak(16 + size);
  return sum == 0xdeadbeef ? -1 : 0;
}
