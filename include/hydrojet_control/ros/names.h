// Topic and service names of the ROS interface, one constant each, used by every node and test.
// docs/ros_api.md lists exactly these (checked by test/test_docs.cpp). Names are relative: they
// resolve in the node's namespace (launch files may push the whole graph into one).
// Plain C++ (no ROS include), so that ROS-free tools and tests can use them too.
#pragma once

namespace hydrojet {
namespace names {

// Topics
constexpr char kTipPose[] = "tracker/tip_pose";                 ///< geometry_msgs/PoseStamped, tracker frame
constexpr char kBasePose[] = "tracker/base_pose";               ///< geometry_msgs/PoseStamped, tracker frame
constexpr char kTipRms[] = "tracker/tip_rms";                   ///< std_msgs/Float64 [m] (rig only)
constexpr char kBaseRms[] = "tracker/base_rms";                 ///< std_msgs/Float64 [m] (rig only)
constexpr char kTipFrameNumber[] = "tracker/tip_frame_number";  ///< std_msgs/Header: seq = frame no. (rig)
constexpr char kJetState[] = "jets/state";                      ///< hydrojet_control/JetState
constexpr char kJetCommand[] = "jets/command";                  ///< hydrojet_control/JetCommand
constexpr char kControllerStatus[] = "controller/status";       ///< hydrojet_control/ControllerStatus
constexpr char kControllerTarget[] = "controller/target";       ///< hydrojet_control/TipTarget
constexpr char kRodState[] = "rod/state";                       ///< hydrojet_control/RodState (controller's model)
constexpr char kPlantRodState[] = "plant/rod_state";            ///< hydrojet_control/RodState (simulated truth)
constexpr char kPlantFault[] = "plant/fault";                   ///< hydrojet_control/PlantFault: inject (sim only)
constexpr char kPlantFaultApplied[] = "plant/fault_applied";    ///< hydrojet_control/PlantFault: when it took effect
constexpr char kPlantEnvironment[] = "plant/environment";       ///< hydrojet_control/Environment, latched (sim only)
constexpr char kViewMarkers[] = "view/markers";                 ///< visualization_msgs/MarkerArray
constexpr char kCalibrationResult[] = "calibration/result";     ///< std_msgs/String (JSON), latched
constexpr char kClock[] = "/clock";                             ///< rosgraph_msgs/Clock (plant_node in lockstep)
constexpr char kTargetDirection[] = "controller/target_direction";  ///< geometry_msgs/Vector3Stamped: aim the tip
constexpr char kLookAt[] = "controller/look_at";              ///< geometry_msgs/PointStamped: aim the camera at a point
constexpr char kClickedPoint[] = "/clicked_point";            ///< geometry_msgs/PointStamped (rviz Publish Point)
constexpr char kViewRate[] = "controller/view_rate";          ///< geometry_msgs/TwistStamped: keyboard rates, tip frame
constexpr char kReachableSet[] = "controller/reachable_set";  ///< hydrojet_control/ReachableSet, latched
constexpr char kExternalForce[] = "controller/external_force";  ///< geometry_msgs/WrenchStamped, base frame
constexpr char kContact[] = "controller/contact";               ///< hydrojet_control/Contact: the detector
constexpr char kKeepOut[] = "controller/keep_out";              ///< hydrojet_control/KeepOut, latched: regions in force
constexpr char kJoy[] = "joy";                                  ///< sensor_msgs/Joy (joystick_node)
constexpr char kDiagnostics[] = "/diagnostics";                 ///< diagnostic_msgs/DiagnosticArray

// Actions (actionlib: the goal, cancel, status, feedback and result topics under this name)
constexpr char kFollowPathAction[] = "controller/follow_path";  ///< hydrojet_control/FollowPath

// Services
constexpr char kStartService[] = "controller/start";               ///< std_srvs/Trigger
constexpr char kStopService[] = "controller/stop";                 ///< std_srvs/Trigger
constexpr char kClosedLoopService[] = "controller/closed_loop";    ///< std_srvs/SetBool
constexpr char kReloadSceneService[] = "controller/reload_scene";  ///< std_srvs/Trigger
constexpr char kSetKeepOutService[] = "controller/set_keep_out";   ///< hydrojet_control/SetKeepOut

/// Every topic and every service above (docs/ros_api.md lists exactly these; test/test_docs.cpp).
constexpr const char* kTopics[] = {kTipPose,
                                   kBasePose,
                                   kTipRms,
                                   kBaseRms,
                                   kTipFrameNumber,
                                   kJetState,
                                   kJetCommand,
                                   kControllerStatus,
                                   kControllerTarget,
                                   kRodState,
                                   kPlantRodState,
                                   kViewMarkers,
                                   kCalibrationResult,
                                   kClock,
                                   kJoy,
                                   kDiagnostics,
                                   kTargetDirection,
                                   kLookAt,
                                   kClickedPoint,
                                   kViewRate,
                                   kReachableSet,
                                   kExternalForce,
                                   kContact,
                                   kPlantFault,
                                   kPlantFaultApplied,
                                   kKeepOut,
                                   kPlantEnvironment};
constexpr const char* kServices[] = {kStartService, kStopService, kClosedLoopService, kReloadSceneService,
                                     kSetKeepOutService};

}  // namespace names
}  // namespace hydrojet
