#include "hydrojet_control/control/robot_model.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hydrojet {
namespace control {

namespace {

/// The uniform rod of a one-segment body (the inverse of rod::general_model).
rod::RodModel uniform_rod(const rod::GeneralRodModel& g) {
  const rod::RodSegment& s = g.segments.front();
  rod::RodModel m;
  m.rod.length = s.length;
  m.rod.stiffness = s.stiffness;
  m.rod.precurvature = s.precurvature;
  m.rod.linear_density = s.linear_density;
  m.rod.kind = g.kind;
  m.rod.shear_stiffness = s.shear_stiffness;
  m.rod.axial_stiffness = s.axial_stiffness;
  m.tip_mass = g.tip_mass;
  m.gravity = g.gravity;
  return m;
}

/// One uniform rod, no point loads, every actuator at the tip: the tip wrench W q says it all.
bool tip_actuated_uniform_rod(const rod::GeneralRodModel& g) {
  if (g.segments.size() != 1 || !g.loads.empty()) return false;
  for (const rod::Actuator& a : g.actuators)
    if (a.at < g.length()) return false;
  return true;
}

}  // namespace

std::vector<rod::Actuator> jet_actuators(const actuation::JetGeometry& jets, const JetVector& max_force,
                                         double length) {
  const actuation::JetMap map(jets);
  if (max_force.size() != 3)
    throw std::invalid_argument("max_jet_force: " + std::to_string(max_force.size()) + " entries for 3 jets");
  std::vector<rod::Actuator> out;
  for (int i = 0; i < 3; ++i) {
    rod::Actuator a;
    a.name = "jet" + std::to_string(i + 1);
    a.at = length;
    a.direction = map.wrench_matrix().col(i).head<3>();
    a.position = rod::Vec3(0.0, 0.0, jets.nozzle_offset);
    a.max_force = max_force[i];
    a.type = rod::ActuatorType::kJet;
    out.push_back(a);
  }
  return out;
}

rod::GeneralRodModel actuated_body(const RobotModel& m) {
  if (!m.body.segments.empty()) return m.body;
  rod::GeneralRodModel g = rod::general_model(m.rod);
  g.actuators = jet_actuators(m.jets, m.max_jet_force, m.rod.rod.length);
  return g;
}

ActuatedModel::ActuatedModel(const RobotModel& model) : model_(model), body_(actuated_body(model)) { build(); }

ActuatedModel::ActuatedModel(const ActuatedModel& other) : model_(other.model_), body_(other.body_) { build(); }

ActuatedModel& ActuatedModel::operator=(const ActuatedModel& other) {
  if (this == &other) return *this;
  model_ = other.model_;
  body_ = other.body_;
  fast_.reset();
  general_.reset();
  build();
  return *this;
}

ActuatedModel::~ActuatedModel() = default;

void ActuatedModel::build() {
  if (std::string why = body_.validate(); !why.empty()) throw std::invalid_argument("robot model: " + why);
  const int n = input_count();
  if (n < 1) throw std::invalid_argument("actuators: the robot needs at least one actuator");
  lower_.resize(n);
  upper_.resize(n);
  tip_wrenches_.setZero(6, n);
  const double L = body_.length();
  for (int i = 0; i < n; ++i) {
    const rod::Actuator& a = body_.actuators[i];
    lower_[i] = a.min_force;  // ≥ 0 for a jet (GeneralRodModel::validate)
    upper_[i] = a.max_force;
    if (a.at >= L) tip_wrenches_.col(i) = a.unit_wrench();
  }
  if (tip_actuated_uniform_rod(body_)) {
    // The HydroJet description keeps its own RodModel (its ρA, tip mass and gravity as given).
    const rod::RodModel rod = model_.body.segments.empty() ? model_.rod : uniform_rod(body_);
    fast_ = std::make_unique<rod::ShootingSolver>(rod, model_.solver);
  } else {
    general_ = std::make_unique<rod::GeneralRodSolver>(body_, model_.solver);
  }
}

rod::RodSolution ActuatedModel::solve(const JetVector& q, const rod::TipWrench& extra) {
  if (q.size() != input_count()) {
    rod::RodSolution bad;
    bad.residual = std::nan("");
    bad.message = "expected " + std::to_string(input_count()) + " actuator input(s), got " + std::to_string(q.size());
    return bad;
  }
  if (fast_) {
    const rod::Vec6 w = tip_wrench(q);
    rod::TipWrench tip;
    tip.force = w.head<3>() + extra.force;
    tip.moment = w.tail<3>() + extra.moment;
    return fast_->solve(tip);
  }
  return general_->solve(q, extra);
}

ActuatedModel::Linearisation ActuatedModel::linearise() {
  Linearisation lin;
  if (fast_) {
    const rod::Compliance C = fast_->compliance();
    lin.ok = C.ok;
    lin.body_compliance = C.body;
    lin.actuation = C.body * tip_wrenches_;
    lin.wrenches = tip_wrenches_;
  } else {
    const rod::GeneralCompliance C = general_->compliance();
    lin.ok = C.ok;
    lin.body_compliance = C.body;
    lin.actuation = C.actuation;
    lin.wrenches = rod::equivalent_tip_wrenches(C.body, C.actuation);
  }
  lin.ok = lin.ok && lin.body_compliance.allFinite() && lin.actuation.allFinite() && lin.wrenches.allFinite();
  return lin;
}

rod::StabilityReport ActuatedModel::stability(const Linearisation& lin) const {
  if (model_.body.segments.empty()) return rod::stability(lin.body_compliance, model_.actuated);
  return rod::stability(lin.body_compliance, lin.wrenches, body_.length());
}

std::vector<Vec3> ActuatedModel::shape(int segments) const {
  return fast_ ? fast_->shape(segments) : general_->shape(segments);
}

void ActuatedModel::reset() {
  if (fast_) fast_->reset();
  if (general_) general_->reset();
}

}  // namespace control
}  // namespace hydrojet
