// Linux joystick reader (see joystick.h).
#include "hydrojet_control/devices/joystick.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/joystick.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace hydrojet {
namespace devices {
namespace {

static_assert(sizeof(js_event) == 8, "a js_event record is 8 bytes");

constexpr double kFullScale = 32767.0;  ///< the kernel's full deflection
constexpr double kMaxWait = 0.05;       ///< longest poll [s]: how soon stop() is noticed

using Publish = JoystickDecoder::Publish;

/// When the next state is due (ROS joy's rules): at once for a button, coalesce_interval after
/// the first of a burst of axis events, and every 1 / autorepeat_rate after the last report (once
/// a first state went out).
class PublishSchedule {
 public:
  PublishSchedule(double coalesce_interval, double autorepeat_rate)
      : coalesce_(seconds(coalesce_interval)),
        repeat_(autorepeat_rate > 0.0 ? seconds(1.0 / autorepeat_rate) : SteadyClock::duration::zero()) {}

  void request(Publish p, SteadyTime now) {
    if (p == Publish::kNone) return;
    const SteadyTime when = p == Publish::kNow ? now : now + coalesce_;
    if (!pending_ || when < due_) due_ = when;
    pending_ = true;
  }
  bool due(SteadyTime now) const { return has_next() && now >= next(); }
  void reported(SteadyTime now) {
    pending_ = false;
    last_ = now;
    reported_ = true;
  }
  /// Seconds until the next state is due, at most `cap`.
  double wait(SteadyTime now, double cap) const {
    if (!has_next()) return cap;
    return std::clamp(seconds_between(now, next()), 0.0, cap);
  }

 private:
  bool has_next() const { return pending_ || (reported_ && repeat_ > SteadyClock::duration::zero()); }
  SteadyTime next() const { return pending_ ? due_ : last_ + repeat_; }

  const SteadyClock::duration coalesce_, repeat_;
  bool pending_ = false;   ///< a change waits to be reported at due_
  bool reported_ = false;  ///< a state went out (autorepeat armed)
  SteadyTime due_{}, last_{};
};

template <class T>
void grow_to(std::vector<T>* v, size_t index) {
  if (v->size() <= index) v->resize(index + 1, T(0));
}

}  // namespace

std::string JoystickOptions::validate() const {
  if (device.empty()) return "device: must not be empty";
  if (!(deadzone >= 0.0 && deadzone < 1.0)) return "deadzone: must lie in [0, 1)";
  if (!(autorepeat_rate >= 0.0 && autorepeat_rate <= 1000.0))
    return "autorepeat_rate: must lie in [0, 1000] Hz (0 = publish on change only)";
  if (!(coalesce_interval >= 0.0 && coalesce_interval <= 1.0)) return "coalesce_interval: must lie in [0, 1] s";
  if (!(std::isfinite(reconnect_period) && reconnect_period > 0.0)) return "reconnect_period: must be finite and > 0";
  return "";
}

// ---------------------------------------------------------------------------------------------
// JoystickDecoder
// ---------------------------------------------------------------------------------------------

Publish JoystickDecoder::feed(const uint8_t* data, size_t n) {
  Publish out = Publish::kNone;
  for (size_t i = 0; i < n; ++i) {
    partial_[partial_size_++] = data[i];
    if (partial_size_ < sizeof partial_) continue;
    out = std::max(out, apply(partial_));
    partial_size_ = 0;
  }
  return out;
}

void JoystickDecoder::zero() {
  std::fill(axes_.begin(), axes_.end(), 0.0);
  std::fill(buttons_.begin(), buttons_.end(), 0);
}

void JoystickDecoder::reset() {
  axes_.clear();
  buttons_.clear();
  partial_size_ = 0;
  events_ = 0;
}

double JoystickDecoder::scale_axis(int16_t value, double deadzone) {
  const double dz = kFullScale * deadzone;
  double v = 0.0;
  if (value > dz)
    v = value - dz;
  else if (value < -dz)
    v = value + dz;
  if (v == 0.0) return 0.0;
  // kFullScale - dz, not kFullScale * (1 - deadzone): full deflection gives exactly ±1.
  return std::clamp(-v / (kFullScale - dz), -1.0, 1.0);
}

Publish JoystickDecoder::apply(const uint8_t* record) {
  js_event e;
  std::memcpy(&e, record, sizeof e);
  ++events_;
  const bool initial = (e.type & JS_EVENT_INIT) != 0;
  switch (e.type & ~JS_EVENT_INIT) {
    case JS_EVENT_BUTTON:
      grow_to(&buttons_, e.number);
      buttons_[e.number] = e.value != 0 ? 1 : 0;
      return initial ? Publish::kSoon : Publish::kNow;
    case JS_EVENT_AXIS:
      grow_to(&axes_, e.number);
      if (!initial) axes_[e.number] = scale_axis(e.value, deadzone_);
      return Publish::kSoon;
    default: return Publish::kNone;
  }
}

// ---------------------------------------------------------------------------------------------
// JoystickReader
// ---------------------------------------------------------------------------------------------

JoystickReader::JoystickReader(const JoystickOptions& options, StateCallback on_state, LogCallback log)
    : opt_(options),
      on_state_(std::move(on_state)),
      decoder_(options.deadzone),
      worker_(*this, mu_, status_, "joystick", options.reconnect_period, std::move(log)) {
  const std::string err = opt_.validate();
  if (!err.empty()) throw std::invalid_argument("joystick: " + err);
}

JoystickReader::~JoystickReader() { stop(); }

JoystickState JoystickReader::state() const {
  std::lock_guard<std::mutex> l(mu_);
  return state_;
}

JoystickStatus JoystickReader::status() const {
  std::lock_guard<std::mutex> l(mu_);
  return status_;
}

bool JoystickReader::run_session(std::string* fault) {
  worker_.set_link(LinkState::kConnecting, "opening " + opt_.device);
  if (!open_device(fault)) {
    std::lock_guard<std::mutex> l(mu_);
    ++status_.connect_failures;
    return false;
  }
  std::string name;
  {
    std::lock_guard<std::mutex> l(mu_);
    ++status_.connects;
    status_.message = "open, waiting for the first event";
    name = status_.name;
  }
  worker_.log(LogLevel::kInfo, "opened " + opt_.device + (name.empty() ? "" : " (" + name + ")"));
  decoder_.reset();
  *fault = stream();
  // Closed before the report: whoever reacts to it finds the device free (a FIFO's writer then
  // waits for the next open instead of writing into a pipe nobody reads).
  close_device();
  if (decoder_.events() > 0) {
    decoder_.zero();
    report(false);
  }
  return true;
}

bool JoystickReader::open_device(std::string* err) {
  fd_ = ::open(opt_.device.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    *err = "open " + opt_.device + ": " + std::strerror(errno);
    return false;
  }
  char name[128] = {};
  const bool named = ::ioctl(fd_, JSIOCGNAME(sizeof name - 1), name) >= 0;  // fails on a FIFO
  std::lock_guard<std::mutex> l(mu_);
  status_.name = named ? name : "";
  return true;
}

void JoystickReader::close_device() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

std::string JoystickReader::stream() {
  PublishSchedule schedule(opt_.coalesce_interval, opt_.autorepeat_rate);
  while (!worker_.stopping()) {
    Publish publish = Publish::kNone;
    const std::string fault = read_events(schedule.wait(SteadyClock::now(), kMaxWait), &publish);
    if (!fault.empty()) return fault;
    const SteadyTime now = SteadyClock::now();
    schedule.request(publish, now);
    if (!schedule.due(now)) continue;
    report(true);
    schedule.reported(now);
  }
  return "stopped";
}

std::string JoystickReader::read_events(double timeout_s, Publish* publish) {
  pollfd p{fd_, POLLIN, 0};
  const int ready = ::poll(&p, 1, static_cast<int>(std::ceil(timeout_s * 1000.0)));
  if (ready < 0) return errno == EINTR ? "" : std::string("poll: ") + std::strerror(errno);
  if (ready == 0) return "";
  uint8_t buf[256];
  const ssize_t n = ::read(fd_, buf, sizeof buf);
  if (n == 0) return "end of file on " + opt_.device + " (device gone)";
  if (n < 0) {
    if (errno == EAGAIN || errno == EINTR) return "";
    return "read " + opt_.device + ": " + std::strerror(errno);  // ENODEV: unplugged
  }
  const uint64_t before = decoder_.events();
  *publish = decoder_.feed(buf, static_cast<size_t>(n));
  if (decoder_.events() != before) note_events(decoder_.events() - before);
  return "";
}

void JoystickReader::note_events(uint64_t count) {
  std::lock_guard<std::mutex> l(mu_);
  status_.events += count;
  status_.axes = decoder_.axes().size();
  status_.buttons = decoder_.buttons().size();
  if (status_.state == LinkState::kRunning) return;
  status_.state = LinkState::kRunning;  // the session's first event: a joystick is there
  status_.message = "connected";
}

void JoystickReader::report(bool connected) {
  JoystickState s;
  s.axes = decoder_.axes();
  s.buttons = decoder_.buttons();
  s.stamp = SteadyClock::now();
  s.connected = connected;
  {
    std::lock_guard<std::mutex> l(mu_);
    state_ = s;
    ++status_.reports;
  }
  if (on_state_) on_state_(s);
}

}  // namespace devices
}  // namespace hydrojet
