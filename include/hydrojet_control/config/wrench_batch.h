// The line format of `rod_fk --batch`: one tip wrench per line, six numbers "fx fy fz mx my mz"
// ([N], [N m], tip body frame) separated by spaces, commas or tabs; blank lines and lines starting
// with '#' are skipped. ROS-free; shared by rod_fk and its fuzz harness (test/fuzz/).
#pragma once

#include <istream>
#include <string>
#include <vector>

#include "hydrojet_control/config/yaml_tree.h"
#include "hydrojet_control/rod/rod_model.h"

namespace hydrojet {
namespace config {

/// A batch line that cannot be used; key() is "--batch line <n>".
class BatchError : public KeyError {
 public:
  using KeyError::KeyError;
};

/// The number in `text`, all of it, finite. @throws BatchError(key, ...) otherwise.
double parse_finite_number(const std::string& text, const std::string& key);

/// Every wrench of `in` in line order. @throws BatchError naming the line on a malformed one.
std::vector<rod::TipWrench> parse_wrench_batch(std::istream& in);

}  // namespace config
}  // namespace hydrojet
