#include "hydrojet_control/control/controller_options.h"

#include <cmath>

#include "hydrojet_control/util/format.h"

namespace hydrojet {
namespace control {

const char* to_string(LoopMode m) { return m == LoopMode::kClosed ? "closed" : "open"; }
const char* to_string(PathType t) { return t == PathType::kSpiral ? "spiral" : "none"; }

std::string LimitOptions::validate() const {
  if (std::string err = util::check_range("max_force", max_force, 0.01, 1.0); !err.empty()) return err;
  if (std::string err = util::check_range("max_force_rate", max_force_rate, 0.01, 20.0); !err.empty()) return err;
  if (!(std::isfinite(max_angular_rate) && max_angular_rate > 0.0))
    return util::bad("max_angular_rate", max_angular_rate, "must be finite and > 0");
  if (std::string err = util::check_range("max_path_rate", max_path_rate, 0.01, 10.0); !err.empty()) return err;
  if (!(reachable_force_fraction > 0.0 && reachable_force_fraction <= 1.0))
    return util::bad("reachable_force_fraction", reachable_force_fraction, "must lie in (0, 1]");
  return "";
}

std::string PathOptions::validate() const {
  if (!(std::isfinite(duration) && duration > 0.0)) return util::bad("duration", duration, "must be finite and > 0");
  for (const auto& [field, v] : {std::pair<const char*, double>{"theta_start", theta_start}, {"theta_end", theta_end}})
    if (!(v >= 0 && v <= M_PI / 2)) return util::bad(field, v, "must lie in [0, pi/2]");
  for (const auto& [field, v] : {std::pair<const char*, double>{"phi_start", phi_start}, {"phi_end", phi_end}})
    if (!std::isfinite(v)) return util::bad(field, v, "must be finite");
  return "";
}

std::string ControllerOptions::validate() const {
  const std::pair<const char*, std::string> groups[] = {
      {"pd", pd.validate()},          {"modal", modal.validate()},
      {"limits", limits.validate()},  {"allocation", allocation.validate()},
      {"safety", safety.validate()},  {"approach", approach.validate()},
      {"path", path.validate()},      {"identification", identification.validate()},
      {"contact", contact.validate()}};
  for (const auto& [group, err] : groups)
    if (!err.empty()) return util::in_group(group, err);
  for (size_t i = 0; i < keep_out.size(); ++i)
    if (std::string err = keep_out[i].validate(); !err.empty()) return "keep_out[" + std::to_string(i) + "]/" + err;
  return "";
}

}  // namespace control
}  // namespace hydrojet
