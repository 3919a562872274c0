# Sourced by scripts/test --sanitize and scripts/fuzz: both build in one tree, .build-asan, with
# clang-14, AddressSanitizer (LeakSanitizer included) + UndefinedBehaviorSanitizer on everything and
# libFuzzer's coverage instrumentation (HYDROJET_SANITIZE, HYDROJET_FUZZ), so that CI compiles the
# sanitized code once for the gtests, the rostests' nodes and the fuzz harnesses. scripts/build reads
# these two variables.
export HYDROJET_BUILD_DIR=.build-asan
export HYDROJET_CMAKE_ARGS="-DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 -DHYDROJET_SANITIZE=ON -DHYDROJET_FUZZ=ON"
