// Joystick reader (devices/joystick.h): the js_event decoder (axis scaling, deadzone, buttons,
// initial-state events, array growth, records split anywhere), and the reader thread on a FIFO
// fed with js_event records: states, coalescing, autorepeat, disconnect (all zero) and reconnect.
// ROS-free.
#include <errno.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/joystick.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "emulator_process.h"
#include "js_records.h"
#include "hydrojet_control/devices/joystick.h"

using namespace hydrojet::devices;
using hydrojet::test::eventually;
using namespace hydrojet::test;  // js_record, axis, button, initial_axis, initial_button
using Publish = JoystickDecoder::Publish;

namespace {

constexpr double kWait = 5.0;  ///< bound of every wait for the reader [s]

Publish feed(JoystickDecoder& d, const std::string& bytes) {
  return d.feed(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
}

/// A temporary directory with a FIFO, and the FIFO's write end (what a joystick would be).
class Fifo {
 public:
  Fifo() {
    char tmpl[] = "/tmp/hj_joystick_XXXXXX";
    dir_ = mkdtemp(tmpl) ? tmpl : "";
    path_ = dir_ + "/js0";
  }
  ~Fifo() {
    close_writer();
    unlink(path_.c_str());
    rmdir(dir_.c_str());
  }
  bool make() const { return !dir_.empty() && mkfifo(path_.c_str(), 0600) == 0; }
  const std::string& path() const { return path_; }

  /// Opens the write end; waits (bounded) for the reader to open the read end (ENXIO until then).
  bool open_writer() {
    return eventually(
        [this] {
          fd_ = ::open(path_.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
          return fd_ >= 0;
        },
        kWait);
  }
  bool write(const std::string& bytes) {
    return fd_ >= 0 && ::write(fd_, bytes.data(), bytes.size()) == static_cast<ssize_t>(bytes.size());
  }
  void close_writer() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  std::string dir_, path_;
  int fd_ = -1;
};

/// Every state the reader reported.
class Recorder {
 public:
  JoystickReader::StateCallback callback() {
    return [this](const JoystickState& s) {
      std::lock_guard<std::mutex> l(mu_);
      states_.push_back(s);
    };
  }
  size_t count() {
    std::lock_guard<std::mutex> l(mu_);
    return states_.size();
  }
  size_t disconnects() {
    std::lock_guard<std::mutex> l(mu_);
    size_t n = 0;
    for (const auto& s : states_) n += s.connected ? 0 : 1;
    return n;
  }
  JoystickState last() {
    std::lock_guard<std::mutex> l(mu_);
    return states_.empty() ? JoystickState() : states_.back();
  }

 private:
  std::mutex mu_;
  std::vector<JoystickState> states_;
};

JoystickOptions fifo_options(const std::string& path) {
  JoystickOptions o;
  o.device = path;
  o.autorepeat_rate = 0.0;  // reports on change only, unless a test wants autorepeat
  o.reconnect_period = 0.05;
  return o;
}

bool all_zero(const JoystickState& s) {
  for (double a : s.axes)
    if (a != 0.0) return false;
  for (int b : s.buttons)
    if (b != 0) return false;
  return true;
}

class JoystickFifo : public ::testing::Test {
 protected:
  void SetUp() override {
    signal(SIGPIPE, SIG_IGN);  // a write after the reader closed fails with EPIPE instead
    ASSERT_TRUE(fifo.make()) << std::strerror(errno);
  }
  /// Waits until the last reported state satisfies `pred` (the reader's state() is that state).
  template <class P>
  bool state_becomes(P pred) {
    return eventually([&] { return rec.count() > 0 && pred(rec.last()); }, kWait);
  }
  Fifo fifo;
  Recorder rec;
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Options
// ---------------------------------------------------------------------------------------------

TEST(JoystickOptions, ValidateNamesTheField) {
  EXPECT_EQ(JoystickOptions().validate(), "");
  auto first_word = [](const JoystickOptions& o) { return o.validate().substr(0, o.validate().find(':')); };
  JoystickOptions o;
  o.device = "";
  EXPECT_EQ(first_word(o), "device");
  o = JoystickOptions();
  o.deadzone = 1.0;
  EXPECT_EQ(first_word(o), "deadzone");
  o.deadzone = -0.1;
  EXPECT_EQ(first_word(o), "deadzone");
  o = JoystickOptions();
  o.autorepeat_rate = -1.0;
  EXPECT_EQ(first_word(o), "autorepeat_rate");
  o = JoystickOptions();
  o.coalesce_interval = std::nan("");
  EXPECT_EQ(first_word(o), "coalesce_interval");
  o = JoystickOptions();
  o.reconnect_period = 0.0;
  EXPECT_EQ(first_word(o), "reconnect_period");
  EXPECT_THROW(JoystickReader(o, nullptr), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Decoder
// ---------------------------------------------------------------------------------------------

TEST(JoystickDecoder, AxisScalingAndDeadzone) {
  // Without a deadzone: value / 32767, negated (ROS joy: stick up or left is +), clamped.
  EXPECT_EQ(JoystickDecoder::scale_axis(0, 0.0), 0.0);
  EXPECT_DOUBLE_EQ(JoystickDecoder::scale_axis(32767, 0.0), -1.0);
  EXPECT_DOUBLE_EQ(JoystickDecoder::scale_axis(-32767, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(JoystickDecoder::scale_axis(-32768, 0.0), 1.0);  // clamped
  EXPECT_DOUBLE_EQ(JoystickDecoder::scale_axis(16384, 0.0), -16384.0 / 32767.0);
  // Deadzone 0.1: |value| <= 3276.7 reads 0; outside, rescaled so full deflection stays ±1.
  const double dz = 0.1;
  EXPECT_EQ(JoystickDecoder::scale_axis(3276, dz), 0.0);
  EXPECT_EQ(JoystickDecoder::scale_axis(-3276, dz), 0.0);
  EXPECT_DOUBLE_EQ(JoystickDecoder::scale_axis(32767, dz), -1.0);
  EXPECT_DOUBLE_EQ(JoystickDecoder::scale_axis(-32767, dz), 1.0);
  EXPECT_NEAR(JoystickDecoder::scale_axis(3277, dz), -(3277 - 3276.7) / (0.9 * 32767), 1e-12);
  EXPECT_NEAR(JoystickDecoder::scale_axis(-18021, dz), (18021 - 3276.7) / (0.9 * 32767), 1e-12);
  EXPECT_NEAR(JoystickDecoder::scale_axis(-18021, dz), 0.5, 1e-4);  // halfway between deadzone and full
}

TEST(JoystickDecoder, InitialStateButtonsAndGrowth) {
  JoystickDecoder d(0.05);
  // Initial state: buttons take the value, axes are created at 0 (their value is ignored).
  EXPECT_EQ(feed(d, initial_button(0, 0) + initial_button(1, 1) + initial_axis(0, 20000) + initial_axis(1, -5)),
            Publish::kSoon);
  EXPECT_EQ(d.axes(), (std::vector<double>{0.0, 0.0}));
  EXPECT_EQ(d.buttons(), (std::vector<int>{0, 1}));
  EXPECT_EQ(d.events(), 4u);
  // A button change asks for a report at once, an axis for a coalesced one.
  EXPECT_EQ(feed(d, button(0, 1)), Publish::kNow);
  EXPECT_EQ(feed(d, axis(0, 32767)), Publish::kSoon);
  EXPECT_EQ(feed(d, axis(1, 100) + button(1, 0)), Publish::kNow);
  EXPECT_EQ(d.axes(), (std::vector<double>{-1.0, 0.0}));  // axis 1 inside the deadzone
  EXPECT_EQ(d.buttons(), (std::vector<int>{1, 0}));
  // Higher numbers grow the arrays; the new entries in between are 0.
  feed(d, axis(4, -32767) + button(6, 7));
  EXPECT_EQ(d.axes(), (std::vector<double>{-1.0, 0.0, 0.0, 0.0, 1.0}));
  EXPECT_EQ(d.buttons(), (std::vector<int>{1, 0, 0, 0, 0, 0, 1}));
  // Unknown event types are counted and ignored.
  EXPECT_EQ(feed(d, js_record(0x40, 2, 1)), Publish::kNone);
  EXPECT_EQ(d.buttons().size(), 7u);
  // zero() keeps the sizes; reset() forgets everything.
  d.zero();
  EXPECT_EQ(d.axes(), std::vector<double>(5, 0.0));
  EXPECT_EQ(d.buttons(), std::vector<int>(7, 0));
  d.reset();
  EXPECT_TRUE(d.axes().empty());
  EXPECT_TRUE(d.buttons().empty());
}

TEST(JoystickDecoder, RecordsSplitAnywhere) {
  const std::string bytes = axis(0, -32767) + button(2, 1) + axis(1, 32767);
  for (size_t cut = 0; cut <= bytes.size(); ++cut) {
    JoystickDecoder d(0.0);
    feed(d, bytes.substr(0, cut));
    EXPECT_EQ(d.events(), cut / 8) << "cut at " << cut;
    feed(d, bytes.substr(cut));
    EXPECT_EQ(d.axes(), (std::vector<double>{1.0, -1.0})) << "cut at " << cut;
    EXPECT_EQ(d.buttons(), (std::vector<int>{0, 0, 1})) << "cut at " << cut;
  }
  JoystickDecoder one_byte(0.0);
  for (char c : bytes) feed(one_byte, std::string(1, c));
  EXPECT_EQ(one_byte.events(), 3u);
  EXPECT_EQ(one_byte.axes(), (std::vector<double>{1.0, -1.0}));
}

// ---------------------------------------------------------------------------------------------
// Reader on a FIFO
// ---------------------------------------------------------------------------------------------

TEST_F(JoystickFifo, StatesDisconnectAndReconnect) {
  JoystickOptions o = fifo_options(fifo.path());
  o.deadzone = 0.1;
  JoystickReader reader(o, rec.callback());
  reader.start();
  ASSERT_TRUE(fifo.open_writer());
  // The kernel's burst of initial-state events: one coalesced report.
  ASSERT_TRUE(fifo.write(initial_axis(0, 12000) + initial_axis(1, 0) + initial_button(0, 0) + initial_button(1, 1)));
  ASSERT_TRUE(state_becomes([](const JoystickState& s) { return s.connected && s.buttons.size() == 2; }));
  JoystickState s = reader.state();
  EXPECT_EQ(s.axes, (std::vector<double>{0.0, 0.0}));
  EXPECT_EQ(s.buttons, (std::vector<int>{0, 1}));
  EXPECT_EQ(rec.count(), 1u);
  EXPECT_EQ(reader.status().state, LinkState::kRunning);

  // Axis changes (scaled, deadzone) and a button on a higher number (growth).
  ASSERT_TRUE(fifo.write(axis(0, -32767) + axis(1, 3000) + axis(3, 18021)));
  ASSERT_TRUE(state_becomes([](const JoystickState& s) { return s.axes.size() == 4; }));
  s = reader.state();
  EXPECT_DOUBLE_EQ(s.axes[0], 1.0);
  EXPECT_EQ(s.axes[1], 0.0);  // inside the deadzone
  EXPECT_EQ(s.axes[2], 0.0);
  EXPECT_NEAR(s.axes[3], -0.5, 1e-4);
  ASSERT_TRUE(fifo.write(button(4, 1)));
  ASSERT_TRUE(state_becomes([](const JoystickState& s) { return s.buttons.size() == 5; }));
  EXPECT_EQ(reader.state().buttons, (std::vector<int>{0, 1, 0, 0, 1}));

  // One record in two writes: nothing before the second part arrives, then the whole event.
  const std::string split = axis(1, 32767);
  const uint64_t events = reader.status().events;
  ASSERT_TRUE(fifo.write(split.substr(0, 3)));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // let the reader see the first part alone
  EXPECT_EQ(reader.status().events, events);
  ASSERT_TRUE(fifo.write(split.substr(3)));
  ASSERT_TRUE(state_becomes([](const JoystickState& s) { return s.axes[1] == -1.0; }));
  EXPECT_EQ(reader.status().events, events + 1);

  // The writer goes away: one disconnected report, every axis and button 0, sizes kept.
  fifo.close_writer();
  ASSERT_TRUE(state_becomes([](const JoystickState& s) { return !s.connected; }));
  s = reader.state();
  EXPECT_TRUE(all_zero(s));
  EXPECT_EQ(s.axes.size(), 4u);
  EXPECT_EQ(s.buttons.size(), 5u);
  EXPECT_EQ(rec.disconnects(), 1u);
  EXPECT_NE(reader.status().state, LinkState::kRunning);
  EXPECT_NE(reader.status().last_error.find("end of file"), std::string::npos) << reader.status().last_error;

  // A new writer (the device is back): connected again with the new state.
  ASSERT_TRUE(fifo.open_writer());
  ASSERT_TRUE(fifo.write(initial_button(0, 1) + initial_axis(0, 0) + axis(0, 32767)));
  ASSERT_TRUE(state_becomes([](const JoystickState& s) { return s.connected; }));
  s = reader.state();
  EXPECT_EQ(s.axes, (std::vector<double>{-1.0}));  // a new session starts with fresh arrays
  EXPECT_EQ(s.buttons, (std::vector<int>{1}));
  EXPECT_EQ(reader.status().connects, 2u);
  EXPECT_EQ(rec.disconnects(), 1u);
}

TEST_F(JoystickFifo, CoalescesAxisBurstsAndReportsButtonsAtOnce) {
  JoystickOptions o = fifo_options(fifo.path());
  // The longest allowed, against a loaded machine's scheduling: "at once" below means within half of it.
  o.coalesce_interval = 1.0;
  JoystickReader reader(o, rec.callback());
  reader.start();
  ASSERT_TRUE(fifo.open_writer());
  // Three axis events in separate writes within the coalesce interval: one report with all three.
  ASSERT_TRUE(fifo.write(axis(0, 32767)));
  ASSERT_TRUE(fifo.write(axis(1, 32767)));
  ASSERT_TRUE(fifo.write(axis(2, 32767)));
  ASSERT_TRUE(eventually([&] { return rec.count() >= 1; }, kWait));
  EXPECT_EQ(rec.last().axes, (std::vector<double>{-1.0, -1.0, -1.0}));
  EXPECT_EQ(rec.count(), 1u);
  // A button goes out without waiting for the coalesce interval: within half of it.
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(fifo.write(button(0, 1)));
  ASSERT_TRUE(eventually([&] { return rec.count() >= 2; }, kWait));
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0.5 * o.coalesce_interval);
  EXPECT_EQ(rec.last().buttons, (std::vector<int>{1}));
}

TEST_F(JoystickFifo, AutorepeatsTheLastStateWhileConnected) {
  JoystickOptions o = fifo_options(fifo.path());
  o.autorepeat_rate = 100.0;
  JoystickReader reader(o, rec.callback());
  reader.start();
  ASSERT_TRUE(fifo.open_writer());
  // Nothing is reported before the first event.
  EXPECT_FALSE(eventually([&] { return rec.count() > 0; }, 0.05));
  ASSERT_TRUE(fifo.write(initial_button(0, 1) + axis(0, -32767)));
  ASSERT_TRUE(eventually([&] { return rec.count() >= 5; }, kWait));
  const JoystickState s = rec.last();
  EXPECT_TRUE(s.connected);
  EXPECT_EQ(s.axes, (std::vector<double>{1.0}));
  EXPECT_EQ(s.buttons, (std::vector<int>{1}));
  // Stopping reports the stick as gone (all zero): nothing stays held after the reader stops.
  reader.stop();
  EXPECT_FALSE(rec.last().connected);
  EXPECT_TRUE(all_zero(rec.last()));
  EXPECT_EQ(reader.status().state, LinkState::kStopped);
}

TEST_F(JoystickFifo, MissingDeviceIsRetriedUntilItAppears) {
  const std::string later = fifo.path() + "_later";
  JoystickReader reader(fifo_options(later), rec.callback());
  reader.start();
  ASSERT_TRUE(eventually([&] { return reader.status().connect_failures >= 2; }, kWait));
  EXPECT_EQ(reader.status().state, LinkState::kDisconnected);
  EXPECT_NE(reader.status().last_error.find("No such file"), std::string::npos) << reader.status().last_error;
  EXPECT_FALSE(reader.state().connected);
  EXPECT_EQ(rec.count(), 0u);  // never connected: nothing to release
  // The device appears: the reader opens it at its next attempt.
  ASSERT_EQ(mkfifo(later.c_str(), 0600), 0);
  const int fd = [&] {
    int f = -1;
    eventually([&] { return (f = ::open(later.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC)) >= 0; }, kWait);
    return f;
  }();
  ASSERT_GE(fd, 0);
  const std::string b = button(0, 1);
  ASSERT_EQ(::write(fd, b.data(), b.size()), 8);
  EXPECT_TRUE(state_becomes([](const JoystickState& s) { return s.connected && s.buttons.size() == 1; }));
  reader.stop();
  ::close(fd);
  unlink(later.c_str());
}
