// The simulated HydroJet: dynamic rod + jets + hydraulics + sensors, described by its own "true"
// PlantModel (which differs from the controller's nominal scene: model mismatch). It speaks the
// same signals as the rig: valve duties in, tracker poses (tip and base sensors, tracker frame) and
// flows out. ROS-free (Eigen + the rod/actuation/plant libraries). Time is passed in.
//
// Defaults: every default below that a plant file can set equals config/plant.yaml (the test
// PlantConfig.DefaultsMatchYaml compares them field by field).
#pragma once

#include <array>
#include <memory>
#include <string>

#include "hydrojet_control/actuation/jet_map.h"
#include "hydrojet_control/actuation/thrust.h"
#include "hydrojet_control/rod/dynamic_rod.h"
#include "hydrojet_control/plant/environment.h"
#include "hydrojet_control/plant/hydraulics.h"
#include "hydrojet_control/plant/sensors.h"

namespace hydrojet {
namespace plant {

/// How the simulated HydroJet differs from the nominal (calibrated) scene it is built from: what
/// the calibrated model does not capture (config::make_plant applies it).
struct ModelMismatch {
  Eigen::Vector3d precurvature_offset = Eigen::Vector3d(1.5, -1.0, 0.0);  ///< added to ũ [1/m]
  double bending_stiffness_scale = 0.8;    ///< EI_x, EI_y × this (the bellows is softer than calibrated)
  double torsional_stiffness_scale = 1.0;  ///< GJ × this
  Eigen::Vector3d misalignment_offset = Eigen::Vector3d(0.12, -0.12, 0.10);  ///< added to (δα, δβ, δγ) [rad]
  double tip_mass_scale = 3.0;    ///< m_t × this (water in the capsule and lines)
  double base_tilt_offset = 0.2;  ///< added to the scene's base tilt [rad] (the holder sits 11° further round)
};

/// The simulated HydroJet (or any robot a scene describes) as it truly is.
struct PlantModel {
  /// The true robot (its rod.gravity is set from base_tilt): segments, point loads and actuators;
  /// its jets each have a valve (valves in turn), its force actuators a drive.
  rod::DynamicRodModel rod;
  actuation::Nozzle nozzle;
  std::vector<ValveModel> valves = hydrojet_valves();  ///< jet i's is valves[i], in turn when fewer
  TrackerNoise tracker;
  FlowNoise flow;
  bool sensor_noise = true;  ///< false: exact sensors (no noise, quantisation, latency)
  /// Force actuators (type force): first-order lag of the force behind its drive [s].
  double thruster_time_constant = 0.02;
  /// An external follower wrench at the tip, tip frame [N] and [N m] (a disturbance: tissue contact,
  /// a tether). Zero by default.
  Eigen::Vector3d external_tip_force = Eigen::Vector3d::Zero();
  Eigen::Vector3d external_tip_moment = Eigen::Vector3d::Zero();
  /// What the tip meets: surfaces it presses, loads that act for a while (none by default).
  Environment environment;
  double base_tilt = 0.0;  ///< base turned about its own x-axis [rad] (§7: 0 or 30°)
  double gravity = 9.81;   ///< [m/s^2]
  Eigen::Vector3d base_position = Eigen::Vector3d(0.0, 0.0, 0.25);  ///< base origin in the tracker frame [m]
  double internal_dt = 0.002;                                       ///< rod time step [s]
  double command_timeout = 0.05;  ///< valves close when no command arrives for this long [s]
  std::string validate() const;
};

/// Orientation of the base frame in the tracker frame (z up): the 0° set-up hangs the rod down,
/// R = Rx(π + tilt), so that gravity in the base frame is g·[0, sin tilt, cos tilt].
Eigen::Matrix3d base_orientation(double tilt);

class Plant {
 public:
  Plant(const PlantModel& p, unsigned seed);

  /// At rest, jets off, time 0. False (with error()) if the rod could not be initialised.
  bool reset();
  /// One entry per actuator of the robot.

  /// The latest command received at time t [s]: per actuator the valve duty [0, 1] (jets) or the
  /// drive [−1, 1] (force actuators: force = drive · max(|min_force|, |max_force|)). A wrong count or
  /// a non-finite entry closes the valves.
  void command(const rod::InputVector& duty, double t);
  /// Integrates up to time t [s] (internal steps of internal_dt). False with error() if the rod
  /// solver failed, or t is not finite or lies more than kMaxAdvance ahead; the plant then holds
  /// its last state.
  bool advance_to(double t);
  static constexpr double kMaxAdvance = 3600.0;  ///< [s] the longest one call integrates

  /// What the tracker reports now (tip and base sensors in the tracker frame).
  TrackerSample tracker_sample();
  /// What the flow sensors report now [m^3/s] (0 for force actuators).
  rod::InputVector flow_sample();
  /// The actuators' forces as an exact force sensor reports them [N] (the controller reads it for
  /// force actuators; a jet's force it computes from the flow).
  rod::InputVector force_sample();
  int input_count() const { return static_cast<int>(duty_.size()); }
  /// Actuator i is a water jet (valve and flow); else a force actuator.
  bool is_jet(int i) const { return jet_[i]; }
  /// The index in hydraulics() of actuator i's valve, or −1 for a force actuator.
  int valve_of(int i) const { return valve_of_[i]; }

  double time() const { return t_; }
  Eigen::Matrix3d tip_rotation() const { return rod_->tip_rotation(); }  ///< truth, base frame
  Eigen::Vector3d tip_position() const { return rod_->tip_position(); }  ///< truth, base frame [m]
  std::vector<Eigen::Vector3d> backbone() const { return rod_->backbone(); }
  rod::InputVector flows() const;       ///< truth [m^3/s] (0 for force actuators)
  rod::InputVector jet_forces() const;  ///< truth [N], per actuator
  rod::InputVector valve_command() const { return duty_; }
  bool valves_closed_by_timeout() const { return timed_out_; }
  const std::string& error() const { return error_; }
  /// The capsule against the environment's surfaces at the last step (truth, base frame).
  const Contact& contact() const { return contact_; }
  /// The whole external force on the tip at the last step: contact, loads and the constant
  /// external_tip_force (truth, base frame) [N].
  const Eigen::Vector3d& external_force() const { return external_force_; }
  Hydraulics& hydraulics() { return hydraulics_; }
  TrackerModel& tracker() { return tracker_; }
  const PlantModel& model() const { return model_; }

 private:
  /// Advances the actuators by dt under the current command (or closed valves).
  void step_actuators(const rod::InputVector& duty, double dt);
  /// Steps the rod by dt, in substeps short enough for the stiffest surface it is near.
  bool step_rod(double dt);
  /// The tip wrench (tip frame) at time t: the constant one, the loads, the contact at this state.
  rod::TipWrench tip_wrench(double t);
  double contact_mass() const;

  PlantModel model_;
  std::unique_ptr<rod::DynamicRod> rod_;
  std::vector<bool> jet_;         ///< per actuator: a jet (else a force actuator)
  std::vector<int> valve_of_;     ///< per actuator: its valve in hydraulics_ (jets), or −1
  rod::InputVector drive_scale_;  ///< force actuators: force per unit drive [N]
  rod::InputVector thrust_;       ///< force actuators: their force now [N]
  Hydraulics hydraulics_;
  TrackerModel tracker_;
  FlowSensorModel flow_sensors_;
  Eigen::Matrix3d R_tracker_base_;
  rod::InputVector duty_;
  double t_ = 0.0, t_command_ = -1e300;
  bool timed_out_ = true;
  std::string error_;
  Contact contact_;
  Eigen::Vector3d external_force_ = Eigen::Vector3d::Zero();
};

}  // namespace plant
}  // namespace hydrojet
