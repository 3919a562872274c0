// dynamic_reconfigure's protocol (~parameter_descriptions, ~parameter_updates, ~set_parameters) for
// a configuration generated from a .cfg, served so that what it reports is always the configuration
// in force. dynamic_reconfigure::Server clamps a value outside the .cfg's bounds without a word before
// its callback sees it, and keeps and advertises a value its callback refused; here a request with a
// value outside the bounds (or not finite), or one the node refuses, changes nothing: it is refused
// with a warning naming the field, and the reply is the configuration in force. rqt_reconfigure and
// `rosrun dynamic_reconfigure dynparam` work with it unchanged. Runs on the node's spinner thread.
#pragma once

#include <dynamic_reconfigure/Config.h>
#include <dynamic_reconfigure/ConfigDescription.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <ros/ros.h>

#include <boost/any.hpp>
#include <cmath>
#include <functional>
#include <sstream>
#include <string>

namespace hydrojet {
namespace ros_bridge {

template <class Config>
class ReconfigureServer {
 public:
  /// `apply`: puts a configuration in force, or returns why not ("" when applied).
  using Apply = std::function<std::string(const Config&)>;

  ReconfigureServer(ros::NodeHandle& pnh, const Config& initial, Apply apply)
      : nh_(pnh), config_(initial), apply_(std::move(apply)) {
    descriptions_ = nh_.advertise<dynamic_reconfigure::ConfigDescription>("parameter_descriptions", 1, true);
    descriptions_.publish(Config::__getDescriptionMessage__());
    updates_ = nh_.advertise<dynamic_reconfigure::Config>("parameter_updates", 1, true);
    publish();
    set_ = nh_.advertiseService("set_parameters", &ReconfigureServer::on_set, this);
  }

  const Config& config() const { return config_; }

  /// Why `c` is outside the .cfg's bounds ("" when every value is finite and within them).
  static std::string out_of_bounds(const Config& c) {
    for (const auto& d : Config::__getParamDescriptions__()) {
      boost::any v, lo, hi;
      d->getValue(c, v);
      d->getValue(Config::__getMin__(), lo);
      d->getValue(Config::__getMax__(), hi);
      const double* x = boost::any_cast<double>(&v);
      if (!x) continue;  // the generated configurations here are all double
      const double a = boost::any_cast<double>(lo), b = boost::any_cast<double>(hi);
      if (!std::isfinite(*x) || *x < a || *x > b) {
        std::ostringstream os;
        os << d->name << " = " << *x << " is outside its safe range [" << a << ", " << b << "]";
        return os.str();
      }
    }
    return "";
  }

 private:
  bool on_set(dynamic_reconfigure::Reconfigure::Request& req, dynamic_reconfigure::Reconfigure::Response& res) {
    Config next = config_;
    std::string why;
    if (!next.__fromMessage__(req.config))
      why = "a parameter this node does not have, or of the wrong type";
    else if ((why = out_of_bounds(next)).empty())
      why = apply_(next);
    if (why.empty()) {
      config_ = next;
      publish();
    } else {
      ROS_WARN("%s: reconfiguration refused, nothing changed: %s", ros::this_node::getName().c_str(), why.c_str());
    }
    config_.__toMessage__(res.config);
    return true;
  }

  /// The configuration in force: on the parameter server (as dynamic_reconfigure::Server keeps it)
  /// and on ~parameter_updates.
  void publish() {
    config_.__toServer__(nh_);
    dynamic_reconfigure::Config msg;
    config_.__toMessage__(msg);
    updates_.publish(msg);
  }

  ros::NodeHandle nh_;
  Config config_;
  Apply apply_;
  ros::Publisher descriptions_, updates_;
  ros::ServiceServer set_;
};

}  // namespace ros_bridge
}  // namespace hydrojet
