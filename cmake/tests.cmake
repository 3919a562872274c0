# Tests of hydrojet_control (included from CMakeLists.txt). gtests of the ROS-free core build in both
# configurations; rostests, and gtests that need ROS (rosbag), only with HYDROJET_WITH_ROS.
if(HYDROJET_WITH_ROS AND NOT CATKIN_ENABLE_TESTING)
  return()
endif()
find_package(GTest REQUIRED)
set(HJ_TEST_DEFS
  HYDROJET_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
  HYDROJET_ROD_FK="${HJ_BIN_DIR}/rod_fk"
  HYDROJET_BIN_DIR="${HJ_BIN_DIR}")

# hydrojet_gtest(name [ROS] LIBS lib...): test/<name>.cpp linked with the libraries and gtest_main;
# ROS-free (poisoned in every build) unless ROS.
function(hydrojet_gtest name)
  cmake_parse_arguments(T "ROS" "" "LIBS" ${ARGN})
  if(HYDROJET_WITH_ROS)
    catkin_add_gtest(${name} test/${name}.cpp)
  else()
    add_executable(${name} test/${name}.cpp)
    add_test(NAME ${name} COMMAND ${name} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
  endif()
  if(NOT T_ROS)
    hydrojet_ros_free(${name})
  endif()
  target_link_libraries(${name} ${T_LIBS} GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE ${HJ_TEST_DEFS})
endfunction()

foreach(t test_rod_closed_form test_rod_compliance test_scene test_rod_fk_cli test_actuation test_controller test_util
          test_dynamic_rod test_numerics_models test_numerics_extreme test_rod_solver test_integrators
          test_bounded_allocation test_resolved_rates test_reference test_approach test_task_space
          test_modal_model test_modal_law test_identification test_contact test_keep_out
          test_safety_monitor)
  hydrojet_gtest(${t} LIBS hydrojet_config)
endforeach()
add_dependencies(test_rod_fk_cli rod_fk)
# Operator control's core pieces: paths, reachable set, look-at solver.
hydrojet_gtest(test_operator_core LIBS hydrojet_config)
# The simulated plant's parts, its valve model, and closed-loop runs.
foreach(t test_plant test_hydraulics test_environment test_closed_loop_run)
  hydrojet_gtest(${t} LIBS hydrojet_sim hydrojet_config)
endforeach()
add_dependencies(test_closed_loop_run identify)
hydrojet_gtest(test_devices LIBS hydrojet_devices hydrojet_config)
# Rig core (line splitter, serial port on a pty pair, gate, aggregator, valve loop, rig.yaml) and the
# drivers against the PTY emulators in test/emulators/ (Python, standard library only).
hydrojet_gtest(test_rig_core LIBS hydrojet_devices)
hydrojet_gtest(test_rig_emulators LIBS hydrojet_devices)
# Joystick reader on a FIFO fed with js_event records.
hydrojet_gtest(test_joystick LIBS hydrojet_devices)
# Calibration core: the parameter vector zeta; synthetic data, data checks, covariance, scene round trip.
hydrojet_gtest(test_zeta LIBS hydrojet_calibration)
hydrojet_gtest(test_calibration LIBS hydrojet_calibration)

if(NOT HYDROJET_WITH_ROS)
  return()
endif()

# The documentation against the code (docs/rod_model.md symbols, docs/ros_api.md names, links).
hydrojet_gtest(test_docs ROS)
target_include_directories(test_docs PRIVATE include)

# The calibrate tool as a user runs it (CSV and bag input, exit codes, JSON line, --out read back).
hydrojet_gtest(test_calibration_cli ROS LIBS hydrojet_calibration_ros)
target_include_directories(test_calibration_cli PRIVATE ${catkin_INCLUDE_DIRS})
target_compile_definitions(test_calibration_cli PRIVATE HYDROJET_CALIBRATE="${HJ_BIN_DIR}/calibrate")
add_dependencies(test_calibration_cli calibrate)

# rostests: each .test file starts its own master; the test binaries talk to the real nodes.
find_package(rostest REQUIRED)
function(hydrojet_rostest_binary name)
  cmake_parse_arguments(T "" "" "DEPENDS;LIBS" ${ARGN})
  add_executable(rostest_${name} EXCLUDE_FROM_ALL test/rostest/${name}.cpp)
  target_include_directories(rostest_${name} PRIVATE include ${catkin_INCLUDE_DIRS})
  target_link_libraries(rostest_${name} ${T_LIBS} ${catkin_LIBRARIES} GTest::gtest)
  target_compile_definitions(rostest_${name} PRIVATE ${HJ_TEST_DEFS})
  add_dependencies(rostest_${name} ${T_DEPENDS} ${PROJECT_NAME}_generate_messages_cpp)
  set_target_properties(rostest_${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${HJ_BIN_DIR})
  add_dependencies(tests rostest_${name})
endfunction()
foreach(t controller_params controller_stale sim_graph sim_controller_killed)
  hydrojet_rostest_binary(${t} DEPENDS controller_node plant_node)
endforeach()
hydrojet_rostest_binary(operator_control DEPENDS controller_node plant_node LIBS Eigen3::Eigen)
hydrojet_rostest_binary(rig_emulated DEPENDS rig_node controller_node)
hydrojet_rostest_binary(shutdown_signals DEPENDS rig_node controller_node plant_node)
hydrojet_rostest_binary(view_markers DEPENDS view_node)
hydrojet_rostest_binary(joystick_fifo DEPENDS joystick_node)
hydrojet_rostest_binary(calibration_plant DEPENDS plant_node calibration_recorder_node calibrate
  LIBS hydrojet_calibration)
foreach(f controller_params controller_stale sim_closed_loop sim_tracker_dropout sim_flow_fault sim_stuck_jet sim_wall sim_keep_out
          sim_controller_killed rig_emulated shutdown_signals_sim shutdown_signals_rig view_markers calibration_plant joystick_fifo
          teleop_keyboard operator_target_direction operator_look_at operator_joy operator_follow_path
          operator_clipped operator_rejected operator_reload_scene hostile_inputs)
  add_rostest(test/rostest/${f}.test)
endforeach()
