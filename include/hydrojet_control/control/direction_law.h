// The law of a control cycle: what turns the direction error into x_cntr, the rotation the tip
// direction should make this step (Algorithm 1, line 5), which the allocation then resolves into
// actuator inputs (lines 7, 9/12). Two laws: the paper's (eqs. 17–18, papers_law.h) and the modal law
// (modal_law.h); `control_law` in the controller file chooses (make_direction_law). ROS-free.
#pragma once

#include <memory>
#include <string>

#include "hydrojet_control/control/controller_io.h"
#include "hydrojet_control/control/plant_identification.h"
#include "hydrojet_control/control/reference.h"
#include "hydrojet_control/control/resolved_rates.h"
#include "hydrojet_control/control/robot_model.h"

namespace hydrojet {
namespace control {

/// Which law acts: the paper's, or the modal law on a path whose clock runs (the paper's for every
/// other source).
enum class ControlLaw { kPapers, kModal };
const char* to_string(ControlLaw l);

/// What a law sees of one cycle (every reference valid for the call only).
struct LawCycle {
  double t = 0.0;                              ///< [s]
  double dt = 0.0;                             ///< since the last cycle [s]
  bool closed_loop = true;                     ///< x_obs is the tracker's (else the model's, §7.3)
  Vec3 observed = Vec3::UnitZ();               ///< x_obs (unit, base frame)
  Vec3 desired = Vec3::UnitZ();                ///< x_des
  Vec3 measured = Vec3::UnitZ();               ///< the tracker's tip direction (unit, base frame)
  double measured_stamp = 0.0;                 ///< [s] when the tracker measured it (t minus its latency)
  const ActuatedModel* model = nullptr;        ///< solved at q_obs this cycle (line 6)
  const rod::RodSolution* solution = nullptr;  ///< that solve
  const ActuatedModel::Linearisation* linearisation = nullptr;  ///< its C^b and J_q
  const InputVector* observed_inputs = nullptr;                 ///< q_obs [N]
  const Reference* reference = nullptr;                         ///< the reference, advanced to x_des
  bool saturated = false;   ///< a jet's last command was at its bound (Controller::at_bound)
  bool near_bound = false;  ///< ... or within kNearBound of it: the law's authority is not handed back yet
};

/// A law: eq. (17)'s PD (DirectionPd, each law's own gains from the PD's) and what the law adds.
class DirectionLaw {
 public:
  virtual ~DirectionLaw() = default;
  /// Starts afresh (controller start).
  virtual void reset() { pd_.reset(); }
  /// A cycle without a correction (the controller held its inputs) of dt [s].
  void skip(double dt) { pd_.skip(dt); }
  /// x_cntr [rad, base frame] for this cycle.
  virtual Vec3 correction(const LawCycle& cycle) = 0;
  /// The fast-path weight of the reference's speed over the last correction (PdOptions::fast_path_rate).
  double fast_path_weight() const;
  /// [N] the allocation's rounding acts as if the tip force were at least this (0: as it is).
  virtual double rounding_force() const { return 0.0; }
  /// The PD's gains (the live ones dynamic_reconfigure sets), validated (std::invalid_argument).
  void set_pd(const PdOptions& pd);
  const PdOptions& pd() const { return pd_options_; }
  virtual ControlLaw kind() const = 0;
  /// What has been measured of the plant (the controller, every cycle), and the flow regulators
  /// that close the loop on the valves (flow_regulator/*). The paper's law assumes nothing of it.
  virtual void adopt(const PlantIdentity& /*identity*/, const actuation::FlowRegulatorOptions& /*flow*/) {}
  /// The flow regulators invert the valves' identified play under this law now (the paper's: as
  /// published, they do not).
  virtual bool inverts_play() const { return false; }
  /// The supervisor's share of the law's own terms in [0, 1] (0: the paper's law acts), and the mode's
  /// swing it watches [rad]; the paper's law has neither.
  virtual double supervisor_weight() const { return 1.0; }
  virtual double swing() const { return 0.0; }
  /// The mode goes on growing after the supervisor fell back to the paper's law: the plant itself
  /// rings at these forces (the controller closes the reach in, LearnedReach::ring).
  virtual bool plant_rings() const { return false; }
  /// The step's inputs lost `lost` [rad, base frame] of the tip direction's change to their bounds
  /// and the force limits (InputStep::lost) at the model's tip direction `d`. The paper's law
  /// (control_law: papers), as published, ignores it.
  virtual void bounded(const Vec3& /*lost*/, const Vec3& /*d*/) {}

 protected:
  /// std::invalid_argument naming the field when `pd` is not valid.
  explicit DirectionLaw(const PdOptions& pd) { set_pd(pd); }
  PdOptions pd_options_;
  DirectionPd pd_;
};

struct ModalLawOptions;
/// The law `law` names with its options (std::invalid_argument naming the field when invalid);
/// sample_period [s] is the tracker's.
std::unique_ptr<DirectionLaw> make_direction_law(ControlLaw law, const PdOptions& pd, const ModalLawOptions& modal,
                                                 double sample_period);

}  // namespace control
}  // namespace hydrojet
