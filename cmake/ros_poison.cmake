# Keeping ROS out of the core: Debian installs ROS headers in /usr/include, where any compiler finds
# them, so leaving catkin's include folders out is not enough. Here every header of the installed ROS
# packages gets a stand-in that stops the build, in a folder searched before the system's: a core
# library (in every build) or a core tool or test (in the HYDROJET_WITH_ROS=OFF build) that includes
# <ros/...> (or a message header) fails.
set(HJ_ROS_POISON_DIR ${CMAKE_BINARY_DIR}/ros_poison)
set(_hj_ros_roots ros roscpp rosconsole xmlrpcpp std_msgs std_srvs geometry_msgs sensor_msgs diagnostic_msgs
    diagnostic_updater visualization_msgs rosgraph_msgs actionlib actionlib_msgs tf2 tf2_ros tf2_msgs
    tf2_eigen dynamic_reconfigure rosbag rosbag_storage message_filters nodelet hydrojet_control/ros)
file(REMOVE_RECURSE ${HJ_ROS_POISON_DIR})
set(_hj_poisoned 0)
foreach(root ${_hj_ros_roots})
  file(GLOB_RECURSE _hj_headers RELATIVE /usr/include LIST_DIRECTORIES false /usr/include/${root}/*.h)
  foreach(h ${_hj_headers})
    file(WRITE ${HJ_ROS_POISON_DIR}/${h}
      "#error \"ROS header <${h}> in the ROS-free core: move this include to src/ros/\"\n")
    math(EXPR _hj_poisoned "${_hj_poisoned} + 1")
  endforeach()
endforeach()
# The package's own ROS layer headers (include/hydrojet_control/ros/) are off limits too.
file(GLOB _hj_own RELATIVE ${PROJECT_SOURCE_DIR}/include ${PROJECT_SOURCE_DIR}/include/hydrojet_control/ros/*.h)
foreach(h ${_hj_own})
  file(WRITE ${HJ_ROS_POISON_DIR}/${h} "#error \"ROS layer header <${h}> in the ROS-free core\"\n")
  math(EXPR _hj_poisoned "${_hj_poisoned} + 1")
endforeach()
message(STATUS "ROS-free build: ${_hj_poisoned} ROS headers poisoned in ${HJ_ROS_POISON_DIR}")
