// Rig driver core without devices: line splitter, serial port on a pty pair, the device worker,
// command gate, flow aggregation, the valve loop with an in-memory backend (what a DAQ backend
// would implement), and the validation of config/rig.yaml. ROS-free.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

#include "hydrojet_control/devices/device_worker.h"
#include "hydrojet_control/devices/rig_config.h"
#include "emulator_process.h"

using namespace hydrojet::devices;
using hydrojet::test::eventually;

namespace {

/// A pty pair: master fd and slave path.
struct Pty {
  int master = -1;
  std::string slave;
  Pty() {
    master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0) return;
    slave = ptsname(master);
  }
  ~Pty() {
    if (master >= 0) close(master);
  }
  void close_master() {
    if (master >= 0) close(master);
    master = -1;
  }
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// LineSplitter
// ---------------------------------------------------------------------------------------------

TEST(LineSplitter, SplitsOnCrLfAnyChunking) {
  LineSplitter s(16);
  const std::string in = "12.5,1\r\n13.0,2\n\r14,3\r";
  for (char c : in) s.feed(reinterpret_cast<const uint8_t*>(&c), 1);
  std::string l;
  ASSERT_TRUE(s.next(&l));
  EXPECT_EQ(l, "12.5,1");
  ASSERT_TRUE(s.next(&l));
  EXPECT_EQ(l, "13.0,2");
  ASSERT_TRUE(s.next(&l));
  EXPECT_EQ(l, "14,3");
  EXPECT_FALSE(s.next(&l));
  s.feed(reinterpret_cast<const uint8_t*>("15"), 2);
  EXPECT_FALSE(s.next(&l));  // incomplete
  s.feed(reinterpret_cast<const uint8_t*>("\n"), 1);
  ASSERT_TRUE(s.next(&l));
  EXPECT_EQ(l, "15");
}

TEST(LineSplitter, DiscardsOverlongAndNulLinesAndSkipsFirst) {
  LineSplitter s(8);
  const std::string in = std::string("123456789012\n") + "ok1\n" + std::string("a\0b\n", 4) + "ok2\n";
  s.feed(reinterpret_cast<const uint8_t*>(in.data()), in.size());
  std::string l;
  ASSERT_TRUE(s.next(&l));
  EXPECT_EQ(l, "ok1");
  ASSERT_TRUE(s.next(&l));
  EXPECT_EQ(l, "ok2");
  EXPECT_FALSE(s.next(&l));
  EXPECT_EQ(s.discarded(), 2u);

  // Opened mid-stream: the tail "3.4" of "123.4" must not become a reading.
  LineSplitter t(32);
  t.skip_first_line();
  const std::string mid = "3.4\n125.0\n";
  t.feed(reinterpret_cast<const uint8_t*>(mid.data()), mid.size());
  ASSERT_TRUE(t.next(&l));
  EXPECT_EQ(l, "125.0");
  EXPECT_EQ(t.skipped_partial(), 1u);
}

// ---------------------------------------------------------------------------------------------
// SerialPort on a pseudo-terminal
// ---------------------------------------------------------------------------------------------

TEST(SerialPort, OpenErrorsNameThePath) {
  SerialPort p;
  std::string err;
  EXPECT_FALSE(p.open("/nonexistent/ttyX", 115200, &err));
  EXPECT_NE(err.find("/nonexistent/ttyX"), std::string::npos) << err;
  EXPECT_FALSE(p.open("/dev/null", 115200, &err));
  EXPECT_NE(err.find("not a terminal"), std::string::npos) << err;
  EXPECT_FALSE(p.is_open());
  EXPECT_FALSE(is_supported_baud(14400));
  EXPECT_TRUE(is_supported_baud(115200));
}

TEST(SerialPort, ReadWriteTimeoutAndHangup) {
  Pty pty;
  ASSERT_FALSE(pty.slave.empty());
  SerialPort p;
  std::string err;
  ASSERT_TRUE(p.open(pty.slave, 9600, &err)) << err;
  EXPECT_TRUE(p.is_pseudo_terminal());
  ASSERT_TRUE(p.set_baud(115200, &err)) << err;
  EXPECT_EQ(p.baud(), 115200);
  EXPECT_TRUE(p.send_break(&err)) << err;  // succeeds, nothing arrives on a pty

  ASSERT_TRUE(p.write_all("INIT:E3A5\r", 0.1, &err)) << err;
  char buf[64] = {0};
  ASSERT_EQ(read(pty.master, buf, sizeof buf), 10);
  EXPECT_EQ(std::string(buf, 10), "INIT:E3A5\r");  // raw: no CR/NL translation

  uint8_t rb[64];
  size_t n = 0;
  const auto t0 = SteadyClock::now();
  EXPECT_EQ(p.read_some(rb, sizeof rb, 0.05, &n, &err), SerialPort::ReadStatus::kTimeout);
  EXPECT_GE(seconds_between(t0, SteadyClock::now()), 0.045);
  ASSERT_EQ(write(pty.master, "OKAYA896\r", 9), 9);
  ASSERT_EQ(p.read_some(rb, sizeof rb, 0.5, &n, &err), SerialPort::ReadStatus::kData);
  EXPECT_EQ(std::string(reinterpret_cast<char*>(rb), n), "OKAYA896\r");

  pty.close_master();  // the device goes away
  EXPECT_EQ(p.read_some(rb, sizeof rb, 0.5, &n, &err), SerialPort::ReadStatus::kHangup);
  EXPECT_NE(err.find("hung up"), std::string::npos) << err;
}

// ---------------------------------------------------------------------------------------------
// DeviceWorker with in-memory sessions
// ---------------------------------------------------------------------------------------------

namespace {

/// A device that never connects: the same fault every time.
class UnreachableDevice : public DeviceSession {
 public:
  std::atomic<int> sessions{0}, closes{0}, shutdowns{0};
  bool run_session(std::string* fault) override {
    ++sessions;
    *fault = "open failed";
    return false;
  }
  void close_port() override { ++closes; }
  void shut_down() override { ++shutdowns; }
};

/// A device that connects and then waits for wake-ups (as the valve loop waits for commands).
class WakeableDevice : public DeviceSession {
 public:
  DeviceWorker* worker = nullptr;
  std::atomic<int> wakes{0};
  bool run_session(std::string*) override {
    while (worker->wait_for_wake(10.0)) ++wakes;
    return true;
  }
  void close_port() override {}
  void shut_down() override {}
};

}  // namespace

TEST(DeviceWorker, RetriesEveryPeriodLogsARepeatedFaultOnceAndStops) {
  UnreachableDevice device;
  std::mutex mu;
  LinkStatus link;
  std::mutex log_mu;
  std::vector<std::string> logs;
  DeviceWorker worker(device, mu, link, "fake device", 0.1, [&](LogLevel level, const std::string& m) {
    std::lock_guard<std::mutex> l(log_mu);
    logs.push_back(std::string(level == LogLevel::kWarn ? "W " : "I ") + m);
  });
  worker.start();
  ASSERT_TRUE(eventually([&] { return device.sessions >= 3; }, 2.0));
  {
    std::lock_guard<std::mutex> l(mu);
    EXPECT_EQ(link.state, LinkState::kDisconnected);
    EXPECT_EQ(link.last_error, "open failed");
    EXPECT_EQ(link.message, "open failed; retrying every 0.1 s");
  }
  worker.stop();
  EXPECT_EQ(device.shutdowns, 1);
  EXPECT_GE(device.closes, device.sessions - 1);
  EXPECT_EQ(link.state, LinkState::kStopped);
  EXPECT_EQ(link.message, "stopped");
  EXPECT_EQ(link.last_error, "open failed");
  std::lock_guard<std::mutex> l(log_mu);
  EXPECT_EQ(logs, std::vector<std::string>{"W fake device: open failed"});
}

TEST(DeviceWorker, StopInterruptsTheReconnectWait) {
  UnreachableDevice device;
  std::mutex mu;
  LinkStatus link;
  DeviceWorker worker(device, mu, link, "fake device", 30.0, nullptr);
  worker.start();
  ASSERT_TRUE(eventually(
      [&] {
        std::lock_guard<std::mutex> l(mu);
        return link.state == LinkState::kDisconnected && !link.last_error.empty();
      },
      2.0));
  {
    std::lock_guard<std::mutex> l(mu);
    EXPECT_EQ(link.message, "open failed; retrying every 30.0 s");
  }
  const SteadyTime t0 = SteadyClock::now();
  worker.stop();
  EXPECT_LT(seconds_between(t0, SteadyClock::now()), 1.0);
  EXPECT_EQ(device.sessions, 1);
  EXPECT_EQ(link.state, LinkState::kStopped);
}

TEST(DeviceWorker, WakeEndsAWaitAtOnceAndStopEndsTheSession) {
  WakeableDevice device;
  std::mutex mu;
  LinkStatus link;
  DeviceWorker worker(device, mu, link, "fake device", 1.0, nullptr);
  device.worker = &worker;
  worker.start();
  worker.wake();
  ASSERT_TRUE(eventually([&] { return device.wakes >= 1; }, 1.0));
  worker.wake();
  ASSERT_TRUE(eventually([&] { return device.wakes >= 2; }, 1.0));
  const SteadyTime t0 = SteadyClock::now();
  worker.stop();
  EXPECT_LT(seconds_between(t0, SteadyClock::now()), 0.5);
  EXPECT_EQ(link.state, LinkState::kStopped);
  EXPECT_TRUE(link.last_error.empty());  // stopping is no fault
}

// ---------------------------------------------------------------------------------------------
// CommandGate
// ---------------------------------------------------------------------------------------------

TEST(CommandGate, ZeroUnlessFreshCommandAndHealthyDevices) {
  CommandGate g(0.1);
  const SteadyTime t0 = SteadyClock::now();
  std::string why;
  Duty d = g.duty(t0, true, "", &why);
  EXPECT_EQ(d, Duty({0, 0, 0}));
  EXPECT_EQ(why, "no command received yet");

  EXPECT_TRUE(g.set_command({0.2, 1.5, -0.1}, t0));
  d = g.duty(t0 + seconds(0.05), true, "", &why);
  EXPECT_EQ(d, Duty({0.2, 1.0, 0.0}));  // clamped
  EXPECT_TRUE(why.empty());

  d = g.duty(t0 + seconds(0.05), false, "tracker (NDI Aurora, /dev/x): silent", &why);
  EXPECT_EQ(d, Duty({0, 0, 0}));
  EXPECT_EQ(why, "tracker (NDI Aurora, /dev/x): silent");

  d = g.duty(t0 + seconds(0.15), true, "", &why);
  EXPECT_EQ(d, Duty({0, 0, 0}));
  EXPECT_NE(why.find("command timeout"), std::string::npos);

  EXPECT_FALSE(g.set_command({0.5, std::nan(""), 0.5}, t0 + seconds(0.2)));  // broken: zero command
  d = g.duty(t0 + seconds(0.21), true, "", &why);
  EXPECT_EQ(d, Duty({0, 0, 0}));
}

// ---------------------------------------------------------------------------------------------
// FlowAggregator
// ---------------------------------------------------------------------------------------------

namespace {
FlowReading reading(SteadyTime t, double q) {
  FlowReading r;
  r.time = t;
  r.accepted = std::isfinite(q) && q >= 0;
  r.flow = r.accepted ? q : std::nan("");
  if (!r.accepted) r.error = "bad";
  return r;
}
}  // namespace

TEST(FlowAggregator, ValidityStalenessAndNoRepublish) {
  FlowAggregator agg(0.2, true);
  const SteadyTime t0 = SteadyClock::now();
  FlowAggregator::Sample s;
  EXPECT_FALSE(agg.take(t0, &s));  // nothing yet

  agg.add(0, reading(t0, 1e-6));
  agg.add(1, reading(t0 + seconds(0.01), 2e-6));
  agg.add(2, reading(t0 + seconds(0.02), 3e-6));
  ASSERT_TRUE(agg.take(t0 + seconds(0.03), &s));
  EXPECT_EQ(s.valid, (std::array<bool, 3>{true, true, true}));
  EXPECT_DOUBLE_EQ(s.flow[2], 3e-6);
  EXPECT_EQ(s.stamp, t0);                          // the oldest reading used
  EXPECT_FALSE(agg.take(t0 + seconds(0.04), &s));  // nothing new: not republished

  // Jet 2's next line is rejected: invalid (NaN) until its next good line.
  agg.add(1, reading(t0 + seconds(0.05), std::nan("")));
  ASSERT_TRUE(agg.take(t0 + seconds(0.05), &s));
  EXPECT_TRUE(s.valid[0]);
  EXPECT_FALSE(s.valid[1]);
  EXPECT_TRUE(std::isnan(s.flow[1]));
  agg.add(1, reading(t0 + seconds(0.06), 2.5e-6));
  ASSERT_TRUE(agg.take(t0 + seconds(0.06), &s));
  EXPECT_TRUE(s.valid[1]);

  // Jet 1 goes silent: stale after 0.2 s although the others keep streaming.
  agg.add(1, reading(t0 + seconds(0.25), 2.5e-6));
  agg.add(2, reading(t0 + seconds(0.25), 3e-6));
  ASSERT_TRUE(agg.take(t0 + seconds(0.25), &s));
  EXPECT_FALSE(s.valid[0]);
  EXPECT_TRUE(std::isnan(s.flow[0]));
  EXPECT_TRUE(s.valid[1] && s.valid[2]);

  // Without invalidate_on_reject the last good reading holds until it is stale.
  FlowAggregator hold(0.2, false);
  hold.add(0, reading(t0, 1e-6));
  hold.add(0, reading(t0 + seconds(0.01), -1.0));
  ASSERT_TRUE(hold.take(t0 + seconds(0.02), &s));
  EXPECT_TRUE(s.valid[0]);
  EXPECT_DOUBLE_EQ(s.flow[0], 1e-6);
}

// ---------------------------------------------------------------------------------------------
// ValveLoop with an in-memory backend
// ---------------------------------------------------------------------------------------------

namespace {

/// A valve backend in memory, as a DAQ backend would be: records what it applied; can fail.
class FakeValves : public ValveDriver {
 public:
  struct Shared {
    std::mutex mu;
    Duty applied{};
    int applies = 0;
    bool fail_open = false;
    bool silent = false;  ///< apply() returns kNoReply
    bool open = false;
  };
  explicit FakeValves(std::shared_ptr<Shared> s) : s_(std::move(s)) {}
  std::string describe() const override { return "fake valves"; }
  bool open(std::string* err) override {
    std::lock_guard<std::mutex> l(s_->mu);
    if (s_->fail_open) {
      *err = "open failed";
      return false;
    }
    s_->open = true;
    return true;
  }
  void close() override {
    std::lock_guard<std::mutex> l(s_->mu);
    s_->open = false;
  }
  bool is_open() const override {
    std::lock_guard<std::mutex> l(s_->mu);
    return s_->open;
  }
  Result apply(const Duty& d, Duty* applied, std::string* err) override {
    std::lock_guard<std::mutex> l(s_->mu);
    if (s_->silent) {
      *err = "no acknowledgement";
      return Result::kNoReply;
    }
    s_->applied = d;
    ++s_->applies;
    *applied = d;
    return Result::kApplied;
  }

 private:
  std::shared_ptr<Shared> s_;
};

}  // namespace

TEST(ValveLoop, GatesCommandsDetectsSilenceReconnectsAndClosesOnStop) {
  auto hw = std::make_shared<FakeValves::Shared>();
  std::atomic<bool> devices_ok{true};
  ValveLoopOptions cfg;
  cfg.rate = 100.0;
  cfg.command_timeout = 0.1;
  cfg.max_failures = 3;
  cfg.reconnect_period = 0.1;
  ValveLoop loop(std::unique_ptr<ValveDriver>(new FakeValves(hw)), cfg, [&](std::string* why) {
    if (!devices_ok) *why = "tracker: silent";
    return devices_ok.load();
  });
  auto applied = [&] {
    std::lock_guard<std::mutex> l(hw->mu);
    return hw->applied;
  };
  loop.start();
  ASSERT_TRUE(eventually([&] { return loop.status().healthy; }, 2.0));
  EXPECT_EQ(applied(), Duty({0, 0, 0}));

  // Commands pass while fresh and every device is healthy.
  ASSERT_TRUE(eventually(
      [&] {
        loop.command({0.3, 0.6, 0.9});
        return applied() == Duty({0.3, 0.6, 0.9});
      },
      1.0));
  EXPECT_EQ(loop.status().acknowledged, Duty({0.3, 0.6, 0.9}));
  EXPECT_TRUE(loop.status().gate_open);

  // Commands stop: zero within command_timeout plus a keep-alive period.
  ASSERT_TRUE(eventually([&] { return applied() == Duty({0, 0, 0}); }, 0.5));
  EXPECT_NE(loop.status().gate_reason.find("command timeout"), std::string::npos);

  // A device becomes unhealthy: zero although commands keep coming.
  devices_ok = false;
  ASSERT_TRUE(eventually(
      [&] {
        loop.command({0.3, 0.6, 0.9});
        return applied() == Duty({0, 0, 0}) && loop.status().gate_reason == "tracker: silent";
      },
      1.0));
  devices_ok = true;
  ASSERT_TRUE(eventually(
      [&] {
        loop.command({0.1, 0.1, 0.1});
        return applied() == Duty({0.1, 0.1, 0.1});
      },
      0.5));

  // The backend stops acknowledging: unhealthy after max_failures, reconnect loop, healthy again
  // only after it acknowledged zero duty.
  {
    std::lock_guard<std::mutex> l(hw->mu);
    hw->silent = true;
  }
  ASSERT_TRUE(eventually([&] { return !loop.status().healthy; }, 1.0));
  EXPECT_NE(loop.status().message.find("acknowledg"), std::string::npos) << loop.status().message;
  {
    std::lock_guard<std::mutex> l(hw->mu);
    hw->silent = false;
  }
  ASSERT_TRUE(eventually([&] { return loop.status().healthy; }, 1.0));
  EXPECT_GE(loop.status().connects, 2u);

  // Non-finite commands count and close the valves.
  loop.command({std::nan(""), 0.5, 0.5});
  ASSERT_TRUE(eventually([&] { return applied() == Duty({0, 0, 0}); }, 0.5));
  EXPECT_EQ(loop.status().bad_commands, 1u);

  // Stop closes the valves.
  loop.command({0.4, 0.4, 0.4});
  ASSERT_TRUE(eventually([&] { return applied() == Duty({0.4, 0.4, 0.4}); }, 0.5));
  loop.stop();
  EXPECT_EQ(applied(), Duty({0, 0, 0}));
  EXPECT_EQ(loop.status().state, LinkState::kStopped);
}

// ---------------------------------------------------------------------------------------------
// config/rig.yaml
// ---------------------------------------------------------------------------------------------

namespace {

YAML::Node shipped() {
  YAML::Node n = YAML::LoadFile(std::string(HYDROJET_SOURCE_DIR) + "/config/rig.yaml");
  n["scene"] = std::string(HYDROJET_SOURCE_DIR) + "/config/scenes/hydrojet_0deg.yaml";
  return n;
}

std::string error_of(const YAML::Node& n) {
  try {
    parse_rig_options(n);
  } catch (const RigOptionsError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(RigOptions, ShippedFileParses) {
  const RigOptions c = parse_rig_options(shipped());
  EXPECT_EQ(c.tracker.tip_handle, 0x0A);
  EXPECT_EQ(c.tracker.base_handle, 0x0B);
  EXPECT_EQ(c.tracker.baud, 115200);
  EXPECT_DOUBLE_EQ(c.tracker.rate, 40.0);
  EXPECT_EQ(c.tracker.out_of_volume_mask, kDefaultOutOfVolumeMask);
  EXPECT_EQ(c.tracker.bx_options, "0001");
  EXPECT_EQ(c.flow[2].port, "/dev/ttyUSB3");
  EXPECT_EQ(c.flow[0].name, "flow sensor 1");
  EXPECT_DOUBLE_EQ(c.flow[1].format.scale_to_m3_per_s, kMlPerMinToM3PerS);
  EXPECT_EQ(c.flow[0].format.separator, ',');
  EXPECT_DOUBLE_EQ(c.valve_loop.command_timeout, 0.1);
  EXPECT_EQ(c.tracker_frame, "tracker");
  // The shipped format reads the emulator's (and the documented) line.
  double q = 0;
  std::string err;
  ASSERT_TRUE(parse_flow_line("480.00,1532.5\r\n", c.flow[0].format, &q, &err)) << err;
  EXPECT_NEAR(q, 8e-6, 1e-15);
}

// config/rig.yaml is the source of the defaults: every value it sets equals the default member
// value of RigOptions (and of the device options it holds). Not compared, because they have no
// default: scene (rig.launch sets it; the file leaves it out), the five device ports (per machine:
// the file names example devices, the structs leave them empty) and the flow unit
// (flow/format/unit is required; FlowLineFormat's scale 0 is deliberately invalid).
TEST(RigOptions, ShippedFileHoldsTheDefaults) {
  const RigOptions d;
  const RigOptions y = parse_rig_options(shipped());
  EXPECT_EQ(y.tracker_frame, d.tracker_frame);
  EXPECT_EQ(y.tip_frame, d.tip_frame);
  EXPECT_EQ(y.base_frame, d.base_frame);
  EXPECT_DOUBLE_EQ(y.reconnect_period, d.reconnect_period);

  EXPECT_EQ(y.tracker.baud, d.tracker.baud);
  EXPECT_EQ(y.tracker.tip_handle, d.tracker.tip_handle);
  EXPECT_EQ(y.tracker.base_handle, d.tracker.base_handle);
  EXPECT_DOUBLE_EQ(y.tracker.rate, d.tracker.rate);
  EXPECT_DOUBLE_EQ(y.tracker.reply_timeout, d.tracker.reply_timeout);
  EXPECT_DOUBLE_EQ(y.tracker.command_timeout, d.tracker.command_timeout);
  EXPECT_DOUBLE_EQ(y.tracker.reset_timeout, d.tracker.reset_timeout);
  EXPECT_DOUBLE_EQ(y.tracker.timeout, d.tracker.timeout);
  EXPECT_DOUBLE_EQ(y.tracker.reconnect_period, d.tracker.reconnect_period);
  EXPECT_EQ(y.tracker.out_of_volume_mask, d.tracker.out_of_volume_mask);
  EXPECT_EQ(y.tracker.tracking_priority, d.tracker.tracking_priority);
  EXPECT_EQ(y.tracker.bx_options, d.tracker.bx_options);
  EXPECT_EQ(y.tracker.reply_format, d.tracker.reply_format);
  EXPECT_EQ(y.tracker.tx_fallback, d.tracker.tx_fallback);
  EXPECT_DOUBLE_EQ(y.tracker.latency, d.tracker.latency);
  EXPECT_EQ(y.tracker.srom_files, d.tracker.srom_files);

  EXPECT_DOUBLE_EQ(y.flow_rate, d.flow_rate);
  EXPECT_DOUBLE_EQ(y.flow_publish_rate, d.flow_publish_rate);
  EXPECT_EQ(y.invalidate_on_reject, d.invalidate_on_reject);
  for (size_t i = 0; i < 3; ++i) {
    SCOPED_TRACE("jet " + std::to_string(i + 1));
    EXPECT_EQ(y.flow[i].name, d.flow[i].name);
    EXPECT_EQ(y.flow[i].baud, d.flow[i].baud);
    EXPECT_EQ(y.flow[i].format.regex, d.flow[i].format.regex);
    EXPECT_EQ(y.flow[i].format.field_index, d.flow[i].format.field_index);
    EXPECT_EQ(y.flow[i].format.separator, d.flow[i].format.separator);
    EXPECT_DOUBLE_EQ(y.flow[i].timeout, d.flow[i].timeout);
    EXPECT_DOUBLE_EQ(y.flow[i].reconnect_period, d.flow[i].reconnect_period);
    EXPECT_EQ(y.flow[i].max_line_length, d.flow[i].max_line_length);
    EXPECT_EQ(y.flow[i].start_command, d.flow[i].start_command);
  }

  EXPECT_EQ(y.valves.baud, d.valves.baud);
  EXPECT_DOUBLE_EQ(y.valves.ack_timeout, d.valves.ack_timeout);
  EXPECT_DOUBLE_EQ(y.valve_loop.rate, d.valve_loop.rate);
  EXPECT_DOUBLE_EQ(y.valve_loop.command_timeout, d.valve_loop.command_timeout);
  EXPECT_EQ(y.valve_loop.max_failures, d.valve_loop.max_failures);
  EXPECT_DOUBLE_EQ(y.valve_loop.reconnect_period, d.valve_loop.reconnect_period);

  // The fields without a default.
  EXPECT_TRUE(d.scene.empty());
  EXPECT_TRUE(d.tracker.port.empty() && d.valves.port.empty());
  for (const FlowSensorOptions& f : d.flow) {
    EXPECT_TRUE(f.port.empty());
    EXPECT_EQ(f.format.scale_to_m3_per_s, 0.0);
  }
}

TEST(RigOptions, InvalidKeysAreNamed) {
  struct Case {
    std::function<void(YAML::Node&)> edit;
    std::string prefix;
  };
  const std::vector<Case> cases = {
      {[](YAML::Node& n) { n.remove("scene"); }, "scene: missing"},
      {[](YAML::Node& n) { n["tracker"]["rate"] = 0.0; }, "tracker/rate: must lie in (0, 1000] Hz"},
      {[](YAML::Node& n) { n["tracker"]["rate"] = "fast"; }, "tracker/rate: must be a number"},
      {[](YAML::Node& n) { n["tracker"]["baud"] = 14400; }, "tracker/baud: 14400 is not one of"},
      {[](YAML::Node& n) { n["tracker"]["tip_handle"] = "0B"; }, "tracker/base_handle: must differ"},
      {[](YAML::Node& n) { n["tracker"]["tip_handle"] = "zz"; }, "tracker/tip_handle: must be an integer or hex"},
      {[](YAML::Node& n) { n["tracker"]["tracking_priority"] = "X"; }, "tracker/tracking_priority: must be S, D or B"},
      {[](YAML::Node& n) { n["tracker"]["timeout"] = 0.01; }, "tracker/timeout: must be >= reply_timeout"},
      {[](YAML::Node& n) { n["tracker"]["bogus"] = 1; }, "tracker/bogus: unknown key"},
      {[](YAML::Node& n) { n["tracker"].remove("port"); }, "tracker/port: missing"},
      {[](YAML::Node& n) { n["flow"]["ports"].remove("jet2"); }, "flow/ports/jet2: missing"},
      {[](YAML::Node& n) { n["flow"]["ports"]["jet3"] = "/dev/ttyUSB1"; },
       "flow/ports/jet3: '/dev/ttyUSB1' is already flow/ports/jet1"},
      {[](YAML::Node& n) { n["valves"]["port"] = "/dev/ttyUSB0"; },
       "valves/port: '/dev/ttyUSB0' is already tracker/port"},
      {[](YAML::Node& n) { n["flow"]["format"]["unit"] = "gal/min"; }, "flow/format/unit: 'gal/min' is not one of"},
      {[](YAML::Node& n) { n["flow"]["format"].remove("unit"); }, "flow/format/unit: missing"},
      {[](YAML::Node& n) { n["flow"]["format"]["regex"] = "(unclosed"; }, "flow/format/regex: invalid regex"},
      {[](YAML::Node& n) { n["flow"]["format"]["regex"] = "\\d+"; },
       "flow/format/regex: regex '\\d+' has no capture group"},
      {[](YAML::Node& n) { n["flow"]["format"]["separator"] = ",;"; }, "flow/format/separator: must be one character"},
      {[](YAML::Node& n) { n["flow"]["baud"] = 1234; }, "flow/baud: 1234 is not a supported rate"},
      {[](YAML::Node& n) { n["flow"]["timeout"] = -1; }, "flow/timeout: must be finite and > 0"},
      {[](YAML::Node& n) { n["valves"]["ack_timeout"] = 5; }, "valves/ack_timeout: must lie in (0, 1] s"},
      {[](YAML::Node& n) { n["valves"]["max_failures"] = 0; }, "valves/max_failures: must be >= 1"},
      {[](YAML::Node& n) { n["command_timeout"] = 0; }, "command_timeout: must be finite and > 0"},
      {[](YAML::Node& n) { n["tip_frame"] = "/tip"; }, "tip_frame: must be a non-empty frame name"},
      {[](YAML::Node& n) { n["reconnect_period"] = 0; }, "reconnect_period: must lie in [0.05, 60] s"},
      {[](YAML::Node& n) { n["tracker"]["reply_format"] = "binary"; },
       "tracker/reply_format: 'binary' is not bx or tx"},
      {[](YAML::Node& n) { n["tracker"]["tx_fallback"] = "maybe"; }, "tracker/tx_fallback: must be true or false"},
      {[](YAML::Node& n) { n["tracker"]["latency"] = 2.0; }, "tracker/latency: must lie in [0, 1] s"},
      {[](YAML::Node& n) { n["tracker"]["latency"] = -0.01; }, "tracker/latency: must lie in [0, 1] s"},
      {[](YAML::Node& n) { n["tracker"]["srom_files"] = "tip.rom"; }, "tracker/srom_files: must be a mapping"},
      {[](YAML::Node& n) { n["tracker"]["srom_files"]["0A"] = "/nonexistent/tip.rom"; },
       "tracker/srom_files/0A: '/nonexistent/tip.rom': cannot be read (No such file or directory)"},
      {[](YAML::Node& n) { n["tracker"]["srom_files"]["zz"] = "/dev/null"; },
       "tracker/srom_files/zz: the key must be a port handle"},
      {[](YAML::Node& n) { n["tracker"]["srom_files"]["0A"] = "/dev/null"; },
       "tracker/srom_files/0A: '/dev/null': not a regular file"},
  };
  for (const Case& c : cases) {
    YAML::Node n = shipped();
    c.edit(n);
    const std::string err = error_of(n);
    EXPECT_EQ(err.compare(0, c.prefix.size(), c.prefix), 0) << "got: " << err << "\nwant: " << c.prefix;
  }
  // Hex handles as text (a launch-file <param> gives a string) and the diagnostic_updater's key.
  YAML::Node n = shipped();
  n["tracker"]["tip_handle"] = "0x0C";
  n["diagnostic_period"] = 0.5;
  EXPECT_EQ(parse_rig_options(n).tracker.tip_handle, 0x0C);
}

TEST(RigOptions, SromFilesAreReadAndCheckedAtStart) {
  char dir_tmpl[] = "/tmp/hj_srom_XXXXXX";
  const std::string dir = mkdtemp(dir_tmpl);
  const std::string ok = dir + "/tip.rom", big = dir + "/big.rom";
  std::ofstream(ok) << std::string(300, 'x');
  std::ofstream(big) << std::string(1025, 'x');
  YAML::Node n = shipped();
  n["tracker"]["srom_files"]["0x0A"] = ok;
  n["tracker"]["reply_format"] = "tx";
  n["tracker"]["tx_fallback"] = false;
  n["tracker"]["latency"] = 0.025;
  const RigOptions c = parse_rig_options(n);
  ASSERT_EQ(c.tracker.srom_files.size(), 1u);
  EXPECT_EQ(c.tracker.srom_files.at(0x0A), ok);
  EXPECT_EQ(c.tracker.reply_format, AuroraOptions::ReplyFormat::kTx);
  EXPECT_FALSE(c.tracker.tx_fallback);
  EXPECT_DOUBLE_EQ(c.tracker.latency, 0.025);
  // The same handle as hex text without 0x ("0A") and as an integer (11 = 0x0B).
  n["tracker"]["srom_files"] = YAML::Load("{0B: " + ok + "}");
  EXPECT_EQ(parse_rig_options(n).tracker.srom_files.count(0x0B), 1u);
  n["tracker"]["srom_files"] = YAML::Load("{11: " + ok + "}");
  EXPECT_EQ(parse_rig_options(n).tracker.srom_files.count(0x0B), 1u);
  n["tracker"]["srom_files"] = YAML::Load("{0A: " + big + "}");
  EXPECT_EQ(error_of(n), "tracker/srom_files/0A: '" + big + "': 1025 bytes, more than the limit of 1024");
  const std::string empty = dir + "/empty.rom";
  std::ofstream(empty).close();
  n["tracker"]["srom_files"] = YAML::Load("{0A: " + empty + "}");
  EXPECT_EQ(error_of(n), "tracker/srom_files/0A: '" + empty + "' is empty");
  std::remove(empty.c_str());
  // Not a regular file: a device would never end (found in review: /dev/zero hung the start).
  n["tracker"]["srom_files"] = YAML::Load("{0A: /dev/zero}");
  EXPECT_EQ(error_of(n), "tracker/srom_files/0A: '/dev/zero': not a regular file");
  std::remove(ok.c_str());
  std::remove(big.c_str());
  rmdir(dir.c_str());
}

TEST(RateCounter, SlidingMinuteWithInjectedClock) {
  using std::chrono::seconds;
  const RateCounter::Time t0{};
  RateCounter r;  // 60 s window
  EXPECT_EQ(r.per_minute(t0), 0.0);
  r.add(t0 + seconds(1), 3);
  r.add(t0 + seconds(30));
  EXPECT_EQ(r.per_minute(t0 + seconds(30)), 4.0);
  EXPECT_EQ(r.per_minute(t0 + seconds(60)), 4.0);  // 1 s event is 59 s old
  EXPECT_EQ(r.per_minute(t0 + seconds(61)), 1.0);  // ... now 60 s old: out
  EXPECT_EQ(r.per_minute(t0 + seconds(90)), 0.0);
  // A cumulative counter: only its growth counts; a restart counts from 0.
  RateCounter c(10.0);  // 10 s window: scaled to a minute
  c.track(t0, 5);
  c.track(t0 + seconds(2), 5);
  c.track(t0 + seconds(4), 7);
  EXPECT_EQ(c.in_window(t0 + seconds(5)), 7u);
  EXPECT_DOUBLE_EQ(c.per_minute(t0 + seconds(5)), 42.0);
  EXPECT_EQ(c.in_window(t0 + seconds(12)), 2u);
  c.track(t0 + seconds(13), 1);  // restarted
  EXPECT_EQ(c.in_window(t0 + seconds(13)), 3u);
}

TEST(RigOptions, DocumentedFlowFormatsReadTheirExampleLines) {
  // The three examples of docs/rig.md, "Flow sensors".
  const struct {
    const char* yaml;
    const char* line;
    double want_m3s;
  } cases[] = {
      {"{regex: \"\", field_index: 0, separator: \",\", unit: mL/min}", "480.12,1532.5\r\n", 480.12e-6 / 60},
      {"{regex: '^\\s*([0-9.]+)\\s*ml/min', unit: mL/min}", "  480.1 ml/min\r\n", 480.1e-6 / 60},
      {"{regex: \"\", field_index: 1, separator: \" \", unit: L/min}", "F 0.480 L/min\r\n", 0.480e-3 / 60},
  };
  for (const auto& c : cases) {
    YAML::Node n = shipped();
    n["flow"]["format"] = YAML::Load(c.yaml);
    const RigOptions cfg = parse_rig_options(n);
    double q = 0;
    std::string err;
    ASSERT_TRUE(parse_flow_line(c.line, cfg.flow[0].format, &q, &err)) << c.yaml << ": " << err;
    EXPECT_NEAR(q, c.want_m3s, 1e-15) << c.yaml;
  }
  // A regex that pins the whole line (leading tag, end anchor) rejects a line that lost bytes of
  // its tag or gained garbage; lost digits cannot be detected (no checksum in such lines).
  YAML::Node n = shipped();
  n["flow"]["format"] = YAML::Load("{regex: '^Q=\\s*([0-9.]+) ml/min$', unit: mL/min}");
  const FlowLineFormat f = parse_rig_options(n).flow[0].format;
  double q = 0;
  std::string err;
  EXPECT_TRUE(parse_flow_line("Q= 480.1 ml/min\r\n", f, &q, &err)) << err;
  EXPECT_FALSE(parse_flow_line("= 480.1 ml/min", f, &q, &err));
  EXPECT_FALSE(parse_flow_line("Q= 480.1 ml/min\x13x", f, &q, &err));
}

TEST(AuroraOptions, CommParamsAndValidation) {
  EXPECT_EQ(aurora_comm_params(115200), "50000");
  EXPECT_EQ(aurora_comm_params(9600), "00000");
  EXPECT_EQ(aurora_comm_params(921600), "60000");
  EXPECT_EQ(aurora_comm_params(14400), "");
  AuroraOptions a;
  a.port = "/dev/x";
  EXPECT_EQ(a.validate(), "");
  a.bx_options = "0002";
  EXPECT_EQ(a.validate(), "bx_options: must include 0001 (transformation data)");
  a.bx_options = "0001";
  a.out_of_volume_mask = 0;
  EXPECT_NE(a.validate().find("out_of_volume_mask"), std::string::npos);
  EXPECT_THROW(AuroraClient(a, nullptr), std::invalid_argument);
}
