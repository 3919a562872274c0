# libFuzzer harnesses of test/fuzz/ (included from CMakeLists.txt when HYDROJET_FUZZ is ON).
# scripts/fuzz builds them in .build-asan (clang-14, HYDROJET_SANITIZE: ASan + UBSan on everything);
# the harnesses link -fsanitize=fuzzer.
# One executable per test/fuzz/fuzz_<name>.cpp, all built by the target `fuzzers`.
if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  message(FATAL_ERROR "HYDROJET_FUZZ needs clang (libFuzzer): configure with -DCMAKE_CXX_COMPILER=clang++-14")
endif()
file(GLOB HJ_FUZZ_SOURCES CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/test/fuzz/fuzz_*.cpp)
add_custom_target(fuzzers)
# Coverage feedback from the code under test: the parsers' libraries (not the rod solver, whose
# numerics the harnesses do not explore and which the sanitized tests would run far slower).
foreach(lib hydrojet_config hydrojet_devices hydrojet_calibration)
  target_compile_options(${lib} PRIVATE -fsanitize=fuzzer-no-link)
endforeach()
foreach(src ${HJ_FUZZ_SOURCES})
  get_filename_component(name ${src} NAME_WE)
  add_executable(${name} EXCLUDE_FROM_ALL ${src})
  hydrojet_ros_free(${name})
  target_link_libraries(${name} hydrojet_config hydrojet_devices hydrojet_calibration)
  target_link_options(${name} PRIVATE -fsanitize=fuzzer)
  target_compile_definitions(${name} PRIVATE HYDROJET_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/fuzz)
  add_dependencies(fuzzers ${name})
endforeach()
# The self-test's probe harness (scripts/ci_selftest; not fuzz_*, so scripts/fuzz runs it only by name).
add_executable(selftest_fuzz EXCLUDE_FROM_ALL ${PROJECT_SOURCE_DIR}/test/selftest/selftest_fuzz.cpp)
hydrojet_ros_free(selftest_fuzz)
target_compile_options(selftest_fuzz PRIVATE -fsanitize=fuzzer-no-link)  # its own coverage: it calls no library
target_link_options(selftest_fuzz PRIVATE -fsanitize=fuzzer)
set_target_properties(selftest_fuzz PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/fuzz)
add_dependencies(fuzzers selftest_fuzz)
