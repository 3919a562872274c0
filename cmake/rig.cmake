# ---------------------------------------------------------------------------------------------
# Rig driver (issue 6): the HydroJet testbed's serial devices (NDI Aurora, three flow sensors,
# valve board) behind rig_node. Included at the end of CMakeLists.txt. README "Rig driver".
# ---------------------------------------------------------------------------------------------
find_package(Threads REQUIRED)

# ROS-free device core: serial port, Aurora session, flow sensors, valve loop (one thread each).
target_sources(hydrojet_devices PRIVATE
  src/devices/serial_port.cpp
  src/devices/aurora_client.cpp
  src/devices/flow_sensors.cpp
  src/devices/valve_board.cpp
)
target_link_libraries(hydrojet_devices PUBLIC Threads::Threads)

# The thin ROS layer (topics, tf, diagnostics).
hydrojet_node(rig_node src/ros/rig_node.cpp)
target_link_libraries(rig_node hydrojet_devices)

if(CATKIN_ENABLE_TESTING)
  # Pure logic (no I/O but a pty pair): line splitter, serial port, gate, aggregator, valve loop with
  # an in-memory backend, rig.yaml validation.
  catkin_add_gtest(test_rig_core test/test_rig_core.cpp)
  target_link_libraries(test_rig_core hydrojet_devices yaml-cpp GTest::gtest_main)
  target_compile_definitions(test_rig_core PRIVATE ${HJ_TEST_DEFS})

  # The drivers against the PTY emulators in test/emulators/ (Python, standard library only).
  catkin_add_gtest(test_rig_emulators test/test_rig_emulators.cpp)
  target_link_libraries(test_rig_emulators hydrojet_devices GTest::gtest_main)
  target_compile_definitions(test_rig_emulators PRIVATE ${HJ_TEST_DEFS})

  # rig.launch (driver + controller) against the emulators.
  find_package(rostest REQUIRED)
  add_executable(rostest_rig_emulated EXCLUDE_FROM_ALL test/rostest/rig_emulated.cpp)
  target_include_directories(rostest_rig_emulated PRIVATE ${catkin_INCLUDE_DIRS})
  target_link_libraries(rostest_rig_emulated ${catkin_LIBRARIES} GTest::gtest)
  target_compile_definitions(rostest_rig_emulated PRIVATE ${HJ_TEST_DEFS})
  add_dependencies(rostest_rig_emulated rig_node controller_node ${PROJECT_NAME}_generate_messages_cpp)
  set_target_properties(rostest_rig_emulated PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})
  add_dependencies(tests rostest_rig_emulated)
  add_rostest(test/rostest/rig_emulated.test)
endif()
