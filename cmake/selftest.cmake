# Probes of scripts/ci_selftest (included from CMakeLists.txt): a gtest, a rostest with a node of its
# own and (cmake/fuzz.cmake) a fuzz harness. Each fails only in the way the environment variable
# HYDROJET_SELFTEST_INJECT names (test/selftest/injection.h), which no normal build or run sets. The
# tests carry the ctest label `selftest`: scripts/test leaves them out unless named with --only.
if(HYDROJET_WITH_ROS AND CATKIN_ENABLE_TESTING)
  catkin_add_gtest(selftest_gtest test/selftest/selftest_gtest.cpp)
  target_link_libraries(selftest_gtest GTest::gtest_main)
  hydrojet_ros_free(selftest_gtest)
  set_tests_properties(_ctest_hydrojet_control_gtest_selftest_gtest PROPERTIES LABELS selftest)

  add_executable(selftest_node EXCLUDE_FROM_ALL test/selftest/selftest_node.cpp)
  target_include_directories(selftest_node PRIVATE ${catkin_INCLUDE_DIRS})
  target_link_libraries(selftest_node hydrojet_ros_bridge ${catkin_LIBRARIES})
  set_target_properties(selftest_node PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${HJ_BIN_DIR})
  add_dependencies(tests selftest_node)
  add_rostest(test/selftest/selftest_rostest.test)
  set_tests_properties(_ctest_hydrojet_control_rostest_test_selftest_selftest_rostest.test PROPERTIES LABELS selftest)
endif()

# A broken install rule, on demand: `cmake --install` fails as it would on a missing file.
install(CODE "if(\"\$ENV{HYDROJET_SELFTEST_INJECT}\" STREQUAL \"broken_install_rule\")
  message(FATAL_ERROR \"injected broken install rule (HYDROJET_SELFTEST_INJECT)\")
endif()")
