// The self-test's gtest probe (scripts/ci_selftest through scripts/test --only selftest_gtest): it
// checks a closed form like any test, and fails in the way HYDROJET_SELFTEST_INJECT names.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "injection.h"

namespace {

using hydrojet::selftest::injected;

TEST(SelfTestProbe, SumOfOddNumbersIsASquare) {
  long sum = 0;
  for (long k = 1; k <= 999; k += 2) sum += k;
  EXPECT_EQ(sum, 500L * 500L);
  // gtest_failure: an assertion that does not hold.
  if (injected("gtest_failure")) EXPECT_EQ(sum, 0L) << "injected failure";
}

TEST(SelfTestProbe, InjectedAfterTheResults) {
  // crash_after_xml: every test passes and the XML is written, then the process aborts at exit.
  if (injected("crash_after_xml")) std::atexit([] { std::abort(); });
  // sanitizer_test_binary: a leak, reported by LeakSanitizer when the process exits.
  if (injected("sanitizer_test_binary")) hydrojet::selftest::leak(64);
  EXPECT_NEAR(std::sqrt(2.0) * std::sqrt(2.0), 2.0, 1e-15);
}

}  // namespace
