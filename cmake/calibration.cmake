# ---------------------------------------------------------------------------------------------
# Calibration (issue 7): offline Ceres fit of zeta = [ux, uy, E, G, da, db, dg] (paper §6.2, eq. 27).
# Included at the end of CMakeLists.txt. README "Calibration".
# ---------------------------------------------------------------------------------------------
find_package(Ceres 2.1 REQUIRED)
find_package(rosbag REQUIRED)

# ROS-free core: data, fit (Ceres), quasistatic extraction, scene writer, synthetic data.
add_library(hydrojet_calibration
  src/calibration/zeta.cpp
  src/calibration/samples.cpp
  src/calibration/calibrator.cpp
  src/calibration/quasistatic.cpp
  src/calibration/scene_writer.cpp
  src/calibration/synthetic.cpp
)
target_include_directories(hydrojet_calibration PUBLIC include)
target_link_libraries(hydrojet_calibration PUBLIC hydrojet_config Ceres::ceres)

# ROS side: rosbag reader and the command line (shared by the tool and the recorder node).
add_library(hydrojet_calibration_ros
  src/calibration/bag_reader.cpp
  src/calibration/app.cpp
)
target_include_directories(hydrojet_calibration_ros PUBLIC include ${catkin_INCLUDE_DIRS} ${rosbag_INCLUDE_DIRS})
target_link_libraries(hydrojet_calibration_ros PUBLIC hydrojet_calibration ${rosbag_LIBRARIES} ${catkin_LIBRARIES})
add_dependencies(hydrojet_calibration_ros ${PROJECT_NAME}_generate_messages_cpp)

add_executable(calibrate src/tools/calibrate.cpp)
target_link_libraries(calibrate hydrojet_calibration_ros)
set_target_properties(calibrate PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})

# Drives the rig / simulated plant through random jet-force combinations, records a bag, fits.
add_executable(calibration_recorder_node src/ros/calibration_recorder_node.cpp)
target_include_directories(calibration_recorder_node PRIVATE ${catkin_INCLUDE_DIRS} ${rosbag_INCLUDE_DIRS})
target_link_libraries(calibration_recorder_node hydrojet_calibration_ros hydrojet_ros_bridge ${rosbag_LIBRARIES} ${catkin_LIBRARIES})
add_dependencies(calibration_recorder_node ${PROJECT_NAME}_generate_messages_cpp)
set_target_properties(calibration_recorder_node PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})

if(CATKIN_ENABLE_TESTING)
  # Core (synthetic data, data checks, covariance, scene round trip): ROS-free.
  catkin_add_gtest(test_calibration test/test_calibration.cpp)
  target_link_libraries(test_calibration hydrojet_calibration GTest::gtest_main)
  target_compile_definitions(test_calibration PRIVATE ${HJ_TEST_DEFS})

  # The tool as a user runs it (CSV and bag input, exit codes, JSON line, --out read back).
  catkin_add_gtest(test_calibration_cli test/test_calibration_cli.cpp)
  target_include_directories(test_calibration_cli PRIVATE ${catkin_INCLUDE_DIRS} ${rosbag_INCLUDE_DIRS})
  target_link_libraries(test_calibration_cli hydrojet_calibration_ros GTest::gtest_main)
  target_compile_definitions(test_calibration_cli PRIVATE ${HJ_TEST_DEFS}
    HYDROJET_CALIBRATE="${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION}/calibrate")
  add_dependencies(test_calibration_cli calibrate)

  # Simulated plant → recorder node → bag → calibrate, against the plant's true zeta.
  find_package(rostest REQUIRED)
  add_executable(rostest_calibration_plant EXCLUDE_FROM_ALL test/rostest/calibration_plant.cpp)
  target_include_directories(rostest_calibration_plant PRIVATE ${catkin_INCLUDE_DIRS})
  target_link_libraries(rostest_calibration_plant hydrojet_calibration ${catkin_LIBRARIES} GTest::gtest)
  target_compile_definitions(rostest_calibration_plant PRIVATE ${HJ_TEST_DEFS})
  add_dependencies(rostest_calibration_plant plant_node calibration_recorder_node calibrate
    ${PROJECT_NAME}_generate_messages_cpp)
  set_target_properties(rostest_calibration_plant PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/${CATKIN_PACKAGE_BIN_DESTINATION})
  add_dependencies(tests rostest_calibration_plant)
  add_rostest(test/rostest/calibration_plant.test)
endif()
