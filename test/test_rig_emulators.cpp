// The rig drivers (AuroraClient, FlowSensor, ValveLoop + SerialValveBoard) against the PTY
// emulators of test/emulators/ (Python, standard library only), which speak each device's protocol
// byte for byte: nominal sessions, CRC errors, partial and garbage frames, out-of-volume sensors,
// device errors, unplug and replug, silence. ROS-free. Every emulator is a child process, killed and
// reaped by its guard; every test works in its own temporary directory.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>
#include <vector>

#include "hydrojet_control/devices/aurora_client.h"
#include "hydrojet_control/devices/crc16.h"
#include "hydrojet_control/devices/flow_sensors.h"
#include "hydrojet_control/devices/valve_board.h"
#include "emulator_process.h"

using namespace hydrojet::devices;
using hydrojet::test::Emulator;
using hydrojet::test::eventually;

namespace {

void sleep_s(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

std::string text_of(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// A temporary directory, removed with everything in it.
struct TempDir {
  std::string path;
  TempDir() {
    char tmpl[] = "/tmp/hj_rig_test_XXXXXX";
    path = mkdtemp(tmpl);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  std::string operator/(const std::string& name) const { return path + "/" + name; }
};

/// Samples delivered by an AuroraClient.
struct Collector {
  std::mutex mu;
  std::vector<AuroraSample> samples;
  void add(const AuroraSample& s) {
    std::lock_guard<std::mutex> l(mu);
    samples.push_back(s);
  }
  std::vector<AuroraSample> get() {
    std::lock_guard<std::mutex> l(mu);
    return samples;
  }
  size_t count_valid_tip() {
    std::lock_guard<std::mutex> l(mu);
    size_t n = 0;
    for (const auto& s : samples) n += s.tip_new && s.tip.status == HandlePose::kValid;
    return n;
  }
};

AuroraOptions aurora_options(const TempDir& d) {
  AuroraOptions c;
  c.port = d / "aurora";
  c.rate = 40.0;
  c.reconnect_period = 0.2;
  c.reset_timeout = 0.5;
  c.command_timeout = 0.5;
  c.timeout = 0.25;
  return c;
}

/// The emulator's tip: circle of radius 20 mm at z = -150 mm, yawing with the motion (no tilt);
/// the base: fixed at (0, 0, -50) mm, identity. Checks every delivered valid pose against it, so a
/// corrupted frame that slipped through would show. `tx`: the TX reply's resolution (0.01 mm,
/// 1e-4 per quaternion component) instead of float32's.
void expect_consistent(const std::vector<AuroraSample>& v, bool tx = false) {
  const double pos_tol = tx ? 1.2e-5 : 2e-6, q_tol = tx ? 6e-5 : 1e-6, yaw_tol = tx ? 6e-4 : 1e-4;
  uint32_t last_tip_frame = 0;
  bool first = true;
  SteadyTime last_received{};
  for (const AuroraSample& s : v) {
    if (!first && seconds_between(last_received, s.received) > 0.3) first = true;  // a new session
    last_received = s.received;
    if (s.tip_new && s.tip.status == HandlePose::kValid) {
      const HandlePose& t = s.tip;
      EXPECT_NEAR(std::hypot(t.t[0], t.t[1]), 0.020, pos_tol);
      EXPECT_NEAR(t.t[2], -0.150, pos_tol);
      EXPECT_NEAR(t.q[1], 0.0, q_tol);
      EXPECT_NEAR(t.q[2], 0.0, q_tol);
      const double yaw = 2.0 * std::atan2(t.q[3], t.q[0]);
      const double az = std::atan2(t.t[1], t.t[0]);
      EXPECT_NEAR(std::remainder(yaw - az, 2 * M_PI), 0.0, yaw_tol);
      EXPECT_NEAR(t.rms_m, 0.30e-3, 1e-8);
      if (!first) {
        EXPECT_GT(t.frame, last_tip_frame);
      }
      last_tip_frame = t.frame;
      first = false;
    }
    if (s.base_new && s.base.status == HandlePose::kValid) {
      EXPECT_NEAR(s.base.t[2], -0.050, pos_tol);
      EXPECT_NEAR(s.base.q[0], 1.0, q_tol);
      EXPECT_NEAR(s.base.rms_m, 0.20e-3, 1e-8);
    }
    if (s.tip.status != HandlePose::kValid) {
      EXPECT_TRUE(s.tip.status == HandlePose::kOutOfVolume || s.tip.status == HandlePose::kMissing);
    }
  }
}

/// Stamps strictly increase and trail the receive time by the latency (a bump of 1 us per sample
/// at most when two replies arrived closer than the clock's jitter).
void expect_stamps(const std::vector<AuroraSample>& v, double latency) {
  for (size_t i = 0; i < v.size(); ++i) {
    const double lag = seconds_between(v[i].stamp, v[i].received);
    EXPECT_LE(lag, latency + 1e-9);
    EXPECT_GE(lag, latency - 1e-4);
    if (i > 0) {
      EXPECT_LT(v[i - 1].stamp, v[i].stamp) << "sample " << i;
    }
  }
}

/// Position of the first occurrence of `what` in the events file text (npos when absent).
size_t at(const std::string& ev, const std::string& what) { return ev.find(what); }

/// An AuroraClient that has delivered at least `n` valid tip poses, or the reason it has not.
::testing::AssertionResult tracks(AuroraClient& client, Collector& c, size_t n, double timeout = 8.0) {
  if (eventually([&] { return c.count_valid_tip() >= n; }, timeout)) return ::testing::AssertionSuccess();
  const AuroraStatus st = client.status();
  return ::testing::AssertionFailure() << "no " << n << " valid tip poses: " << st.message << " / " << st.last_error;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// NDI Aurora
// ---------------------------------------------------------------------------------------------

TEST(AuroraEmulator, NominalSession) {
  TempDir d;
  Emulator emu("aurora_emulator.py", {"--symlink", d / "aurora", "--strict-baud", "--events-file", d / "events"},
               d / "aurora");
  ASSERT_TRUE(emu.started());
  Collector c;
  AuroraOptions cfg = aurora_options(d);
  cfg.latency = 0.015;
  AuroraClient client(cfg, [&](const AuroraSample& s) { c.add(s); });
  client.start();
  ASSERT_TRUE(eventually([&] { return c.count_valid_tip() >= 20; }, 8.0)) << client.status().message;
  const AuroraStatus st = client.status();
  EXPECT_TRUE(st.healthy(SteadyClock::now(), 1.0));
  EXPECT_EQ(st.state, LinkState::kRunning);
  EXPECT_EQ(st.sessions, 1u);
  EXPECT_EQ(st.crc_errors, 0u);
  EXPECT_EQ(st.garbage_bytes, 0u);
  EXPECT_EQ(st.connected_by, AuroraStatus::Connect::kBreak);  // the NUL stand-in for the BREAK on a pty
  EXPECT_FALSE(st.tx_mode);
  EXPECT_TRUE(AuroraStatus::handle_ok(st.tip, SteadyClock::now(), 1.0));
  EXPECT_TRUE(AuroraStatus::handle_ok(st.base, SteadyClock::now(), 1.0));
  expect_consistent(c.get());
  expect_stamps(c.get(), cfg.latency);
  client.stop();
  EXPECT_EQ(client.status().state, LinkState::kStopped);
  // The session as the device saw it (--strict-baud: INIT onwards only answered at 115200).
  EXPECT_TRUE(eventually([&] { return text_of(d / "events").find("TSTOP: OKAY") != std::string::npos; }, 1.0));
  const std::string ev = text_of(d / "events");
  for (const char* want : {"RESET (NUL byte)", "COMM:50000 OKAY", "INIT: OKAY", "PINIT:0A OKAY", "PINIT:0B OKAY",
                           "PENA:0AD OKAY", "PENA:0BD OKAY", "TSTART: OKAY", "TSTOP: OKAY"})
    EXPECT_NE(ev.find(want), std::string::npos) << want << " not in:\n" << ev;
  // Shutdown: TSTOP, then back to 9600 (the OKAY was still sent at 115200: --strict-baud answered).
  EXPECT_TRUE(eventually([&] { return text_of(d / "events").find("COMM:00000 OKAY") != std::string::npos; }, 1.0));
  EXPECT_LT(at(text_of(d / "events"), "TSTOP: OKAY"), at(text_of(d / "events"), "COMM:00000 OKAY"));
}

// A USB-serial adapter that drops the BREAK: the emulator neither resets on the NUL stand-in (it
// stays in its input as garbage) nor on a RESET line. The INIT probe at 9600 finds it (the first
// INIT is garbled by the NUL: a CRC-valid ERROR, so TSTOP and INIT again). Shutdown leaves it at
// 9600, not tracking; a second driver start then finds it at 9600 at once.
TEST(AuroraEmulator, BreakIgnoredInitProbeAt9600AndShutdownBackTo9600) {
  TempDir d;
  Emulator emu("aurora_emulator.py",
               {"--symlink", d / "aurora", "--strict-baud", "--ignore-break", "--events-file", d / "events"},
               d / "aurora");
  {
    Collector c;
    AuroraClient client(aurora_options(d), [&](const AuroraSample& s) { c.add(s); });
    client.start();
    ASSERT_TRUE(tracks(client, c, 20));
    const AuroraStatus st = client.status();
    EXPECT_EQ(st.connected_by, AuroraStatus::Connect::kInitProbe9600);
    EXPECT_EQ(st.sessions, 1u);
    EXPECT_EQ(st.connect_failures, 0u);
    expect_consistent(c.get());
    client.stop();
  }
  std::string ev = text_of(d / "events");
  EXPECT_EQ(ev.find("RESET"), std::string::npos) << ev;  // never reset: the probe did it
  EXPECT_NE(at(ev, "COMM:50000 OKAY"), std::string::npos) << ev;
  ASSERT_NE(at(ev, "TSTOP: OKAY"), std::string::npos) << ev;
  ASSERT_NE(at(ev, "COMM:00000 OKAY"), std::string::npos) << ev;
  EXPECT_LT(at(ev, "TSTOP: OKAY"), at(ev, "COMM:00000 OKAY"));
  EXPECT_LT(at(ev, "COMM:50000 OKAY"), at(ev, "TSTOP: OKAY"));

  // Second start: the device is where ndicapi and this driver look first.
  const size_t before = ev.size();
  Collector c2;
  AuroraClient again(aurora_options(d), [&](const AuroraSample& s) { c2.add(s); });
  const SteadyTime t0 = SteadyClock::now();
  again.start();
  ASSERT_TRUE(tracks(again, c2, 1, 5.0));
  EXPECT_LT(seconds_between(t0, SteadyClock::now()), 3.0);
  EXPECT_EQ(again.status().connected_by, AuroraStatus::Connect::kInitProbe9600);
  EXPECT_EQ(again.status().connect_failures, 0u);
  again.stop();
  ev = text_of(d / "events").substr(before);
  EXPECT_NE(at(ev, "INIT: OKAY"), std::string::npos) << ev;
}

// A device left at 115200 by a run that crashed, the BREAK lost: no answer at 9600 (--strict-baud),
// INIT answered at the configured 115200; COMM skipped. Shutdown brings it back to 9600.
TEST(AuroraEmulator, LeftAt115200FoundByProbeAtConfiguredBaud) {
  TempDir d;
  Emulator emu("aurora_emulator.py",
               {"--symlink", d / "aurora", "--strict-baud", "--ignore-break", "--start-baud", "115200", "--events-file",
                d / "events"},
               d / "aurora");
  Collector c;
  AuroraClient client(aurora_options(d), [&](const AuroraSample& s) { c.add(s); });
  client.start();
  ASSERT_TRUE(tracks(client, c, 20));
  EXPECT_EQ(client.status().connected_by, AuroraStatus::Connect::kInitProbeConfigured);
  EXPECT_EQ(client.status().connect_failures, 0u);
  expect_consistent(c.get());
  client.stop();
  const std::string ev = text_of(d / "events");
  EXPECT_EQ(ev.find("COMM:50000"), std::string::npos) << ev;  // already at 115200
  ASSERT_NE(at(ev, "COMM:00000 OKAY"), std::string::npos) << ev;
  EXPECT_LT(at(ev, "TSTOP: OKAY"), at(ev, "COMM:00000 OKAY"));
  // Now at 9600: a new start finds it by the first probe.
  Collector c2;
  AuroraClient again(aurora_options(d), [&](const AuroraSample& s) { c2.add(s); });
  again.start();
  ASSERT_TRUE(tracks(again, c2, 1, 5.0));
  EXPECT_EQ(again.status().connected_by, AuroraStatus::Connect::kInitProbe9600);
}

// Left at 115200 and still tracking: INIT is refused (ERROR0C), TSTOP, INIT again.
TEST(AuroraEmulator, LeftAt115200AndTrackingStoppedThenInitialised) {
  TempDir d;
  Emulator emu("aurora_emulator.py",
               {"--symlink", d / "aurora", "--strict-baud", "--ignore-break", "--start-baud", "115200",
                "--start-tracking", "--events-file", d / "events"},
               d / "aurora");
  Collector c;
  AuroraClient client(aurora_options(d), [&](const AuroraSample& s) { c.add(s); });
  client.start();
  ASSERT_TRUE(tracks(client, c, 20));
  EXPECT_EQ(client.status().connected_by, AuroraStatus::Connect::kInitProbeConfigured);
  expect_consistent(c.get());
  client.stop();
  const std::string ev = text_of(d / "events");
  ASSERT_NE(at(ev, "INIT: ERROR0C"), std::string::npos) << ev;
  ASSERT_NE(at(ev, "TSTOP: OKAY"), std::string::npos) << ev;
  ASSERT_NE(at(ev, "INIT: OKAY"), std::string::npos) << ev;
  EXPECT_LT(at(ev, "INIT: ERROR0C"), at(ev, "TSTOP: OKAY"));
  EXPECT_LT(at(ev, "TSTOP: OKAY"), at(ev, "INIT: OKAY"));
}

// A tool without a programmed ROM: PINIT fails until its tool definition was written with PVWR.
TEST(AuroraEmulator, UnprogrammedToolNeedsItsSromFile) {
  TempDir d;
  // 150 bytes: three PVWR chunks, the last padded with zeros to 64 bytes.
  std::vector<uint8_t> rom(150);
  for (size_t i = 0; i < rom.size(); ++i) rom[i] = static_cast<uint8_t>(i * 37 + 11);
  {
    std::ofstream f(d / "tip.rom", std::ios::binary);
    f.write(reinterpret_cast<const char*>(rom.data()), static_cast<std::streamsize>(rom.size()));
  }
  std::vector<uint8_t> padded = rom;
  padded.resize(192, 0);
  char want[64];
  std::snprintf(want, sizeof want, "SROM 0A: 192 bytes, CRC %04X", crc16_arc(padded.data(), padded.size()));

  Emulator emu("aurora_emulator.py", {"--symlink", d / "aurora", "--unprogrammed", "0A", "--events-file", d / "events"},
               d / "aurora");
  {
    AuroraClient client(aurora_options(d), nullptr);  // no srom_files: refused, and told why
    client.start();
    ASSERT_TRUE(eventually([&] { return client.status().connect_failures >= 1; }, 5.0));
    const std::string e = client.status().last_error;
    EXPECT_NE(e.find("PINIT 0A: ERROR13"), std::string::npos) << e;
    EXPECT_NE(e.find("tracker/srom_files/0A"), std::string::npos) << e;
    EXPECT_EQ(client.status().sessions, 0u);
  }
  AuroraOptions cfg = aurora_options(d);
  cfg.srom_files[0x0A] = d / "tip.rom";
  Collector c;
  AuroraClient client(cfg, [&](const AuroraSample& s) { c.add(s); });
  client.start();
  ASSERT_TRUE(tracks(client, c, 20));
  expect_consistent(c.get());
  client.stop();
  const std::string ev = text_of(d / "events");
  EXPECT_NE(ev.find(want), std::string::npos) << want << " not in:\n" << ev;
  EXPECT_NE(ev.find("PVWR:0A0080"), std::string::npos) << ev;
  EXPECT_EQ(ev.find("PVWR:0A00C0"), std::string::npos) << ev;
  EXPECT_EQ(ev.find("PVWR:0B"), std::string::npos) << ev;  // the base has its ROM
}

// Firmware that refuses BX: with tx_fallback the session switches to TX and tracks; without it the
// error is a fault naming the reply.
TEST(AuroraEmulator, BxErrorFallsBackToTx) {
  TempDir d;
  Emulator emu("aurora_emulator.py", {"--symlink", d / "aurora", "--strict-baud", "--bx-error", "01"}, d / "aurora");
  {
    Collector c;
    AuroraOptions cfg = aurora_options(d);
    cfg.latency = 0.01;
    std::mutex log_mu;
    std::string logs;
    AuroraClient client(
        cfg, [&](const AuroraSample& s) { c.add(s); },
        [&](LogLevel, const std::string& m) {
          std::lock_guard<std::mutex> l(log_mu);
          logs += m + "\n";
        });
    client.start();
    ASSERT_TRUE(tracks(client, c, 20));
    const AuroraStatus st = client.status();
    EXPECT_TRUE(st.tx_mode);
    EXPECT_EQ(st.tx_fallbacks, 1u);
    EXPECT_EQ(st.sessions, 1u);
    EXPECT_EQ(st.crc_errors, 0u);
    EXPECT_EQ(st.format_errors, 0u);
    expect_consistent(c.get(), true);
    expect_stamps(c.get(), cfg.latency);
    client.stop();
    std::lock_guard<std::mutex> l(log_mu);
    EXPECT_NE(logs.find("BX: ERROR01: invalid command"), std::string::npos) << logs;
    EXPECT_NE(logs.find("TX:0001"), std::string::npos) << logs;
  }
  {
    AuroraOptions cfg = aurora_options(d);
    cfg.tx_fallback = false;
    Collector c;
    AuroraClient client(cfg, [&](const AuroraSample& s) { c.add(s); });
    client.start();
    ASSERT_TRUE(eventually([&] { return client.status().last_error.find("BX") != std::string::npos; }, 5.0));
    EXPECT_NE(client.status().last_error.find("BX: ERROR01: invalid command"), std::string::npos)
        << client.status().last_error;
    EXPECT_FALSE(client.status().tx_mode);
    EXPECT_EQ(c.count_valid_tip(), 0u);
  }
}

// reply_format tx from the start, with CRC errors injected: TX replies are CRC-checked too.
TEST(AuroraEmulator, TxRepliesAreCrcChecked) {
  TempDir d;
  Emulator emu("aurora_emulator.py", {"--symlink", d / "aurora", "--tx-crc-error-every", "4"}, d / "aurora");
  AuroraOptions cfg = aurora_options(d);
  cfg.reply_format = AuroraOptions::ReplyFormat::kTx;
  Collector c;
  AuroraClient client(cfg, [&](const AuroraSample& s) { c.add(s); });
  client.start();
  ASSERT_TRUE(eventually([&] { return c.count_valid_tip() >= 20 && client.status().crc_errors >= 3; }, 8.0))
      << client.status().message;
  EXPECT_TRUE(client.status().tx_mode);
  EXPECT_EQ(client.status().tx_fallbacks, 0u);
  EXPECT_EQ(client.status().sessions, 1u);
  expect_consistent(c.get(), true);
}

TEST(AuroraEmulator, CrcErrorsCountedNeverDelivered) {
  TempDir d;
  Emulator emu("aurora_emulator.py", {"--symlink", d / "aurora", "--crc-error-every", "3", "--seed", "7"},
               d / "aurora");
  Collector c;
  AuroraClient client(aurora_options(d), [&](const AuroraSample& s) { c.add(s); });
  client.start();
  ASSERT_TRUE(eventually([&] { return c.count_valid_tip() >= 30 && client.status().crc_errors >= 5; }, 8.0))
      << client.status().message;
  const AuroraStatus st = client.status();
  EXPECT_TRUE(st.healthy(SteadyClock::now(), 1.0));  // one frame in three lost: still tracking
  EXPECT_EQ(st.sessions, 1u);
  expect_consistent(c.get());
}

TEST(AuroraEmulator, PartialAndGarbageFrames) {
  TempDir d;
  // Replies come in 7-byte pieces; every 3rd is preceded by random bytes, every 5th is cut short.
  Emulator emu("aurora_emulator.py",
               {"--symlink", d / "aurora", "--garbage-every", "3", "--truncate-every", "5", "--chunk-bytes", "7",
                "--chunk-delay", "0.0005", "--seed", "3"},
               d / "aurora");
  Collector c;
  AuroraClient client(aurora_options(d), [&](const AuroraSample& s) { c.add(s); });
  client.start();
  ASSERT_TRUE(eventually([&] { return c.count_valid_tip() >= 30; }, 8.0)) << client.status().message;
  const AuroraStatus st = client.status();
  EXPECT_GT(st.garbage_bytes, 0u);
  EXPECT_GT(st.truncated_frames + st.reply_timeouts, 0u);
  EXPECT_EQ(st.sessions, 1u);  // no reconnect needed
  expect_consistent(c.get());
}

TEST(AuroraEmulator, OutOfVolumeNeverValid) {
  TempDir d;
  // The tip leaves the volume from 1.0 s to 2.0 s after the emulator started, still sending its
  // (meaningless) transform but with the out-of-volume port-status bit.
  Emulator emu(
      "aurora_emulator.py",
      {"--symlink", d / "aurora", "--out-of-volume-after", "1.0", "--out-of-volume-for", "1.0", "--oov-keep-transform"},
      d / "aurora");
  Collector c;
  AuroraOptions cfg = aurora_options(d);
  AuroraClient client(cfg, [&](const AuroraSample& s) { c.add(s); });
  client.start();
  bool saw_unhealthy_tip = false;
  ASSERT_TRUE(eventually(
      [&] {
        const AuroraStatus s = client.status();
        if (s.tip.out_of_volume > 0 && !AuroraStatus::handle_ok(s.tip, SteadyClock::now(), cfg.timeout))
          saw_unhealthy_tip = true;
        return saw_unhealthy_tip && s.tip.last_status == HandlePose::kValid && s.tip.out_of_volume > 5;
      },
      8.0))
      << "tip out_of_volume " << client.status().tip.out_of_volume;
  const std::vector<AuroraSample> v = c.get();
  size_t oov = 0, valid_after = 0;
  for (const auto& s : v) {
    if (s.tip_new && s.tip.status == HandlePose::kOutOfVolume) {
      ++oov;
      EXPECT_TRUE(s.tip.has_transform());  // sent, flagged, never kValid
      valid_after = 0;
    } else if (s.tip_new && s.tip.status == HandlePose::kValid && oov > 0) {
      ++valid_after;
    }
    if (s.base_new) {
      EXPECT_EQ(s.base.status, HandlePose::kValid);  // the base stays in the volume
    }
  }
  EXPECT_GT(oov, 20u);
  EXPECT_GE(valid_after, 1u);                                     // back in the volume: valid again
  EXPECT_TRUE(client.status().healthy(SteadyClock::now(), 1.0));  // the tracker itself was fine
  expect_consistent(v);
}

TEST(AuroraEmulator, UnplugAndReplug) {
  TempDir d;
  Collector c;
  AuroraOptions cfg = aurora_options(d);
  std::mutex log_mu;
  std::vector<std::string> logs;
  AuroraClient client(
      cfg, [&](const AuroraSample& s) { c.add(s); },
      [&](LogLevel, const std::string& m) {
        std::lock_guard<std::mutex> l(log_mu);
        logs.push_back(m);
      });
  {
    Emulator first("aurora_emulator.py", {"--symlink", d / "aurora", "--die-after", "1.0"}, d / "aurora");
    client.start();
    ASSERT_TRUE(eventually([&] { return c.count_valid_tip() >= 5; }, 8.0)) << client.status().message;
    ASSERT_TRUE(eventually([&] { return first.exited(); }, 5.0));
    ASSERT_TRUE(eventually([&] { return !client.status().healthy(SteadyClock::now(), cfg.timeout); }, 1.0));
  }
  EXPECT_NE(client.status().state, LinkState::kRunning);
  {
    std::lock_guard<std::mutex> l(log_mu);
    bool hung_up = false;
    for (const auto& m : logs) hung_up |= m.find("hung up") != std::string::npos;
    EXPECT_TRUE(hung_up);
  }
  // The reconnect loop now fails to open the port (the link is gone).
  EXPECT_TRUE(eventually([&] { return client.status().last_error.find("No such file") != std::string::npos; }, 2.0))
      << client.status().last_error;
  EXPECT_GT(client.status().connect_failures, 0u);

  const size_t before = c.count_valid_tip();
  Emulator second("aurora_emulator.py", {"--symlink", d / "aurora"}, d / "aurora");
  ASSERT_TRUE(eventually(
      [&] { return client.status().healthy(SteadyClock::now(), cfg.timeout) && c.count_valid_tip() >= before + 5; },
      8.0))
      << client.status().message;
  EXPECT_EQ(client.status().sessions, 2u);
  expect_consistent(c.get());
}

TEST(AuroraEmulator, SilenceDetectedAndReconnectRetried) {
  TempDir d;
  Emulator emu("aurora_emulator.py", {"--symlink", d / "aurora", "--silence-after", "0.8"}, d / "aurora");
  Collector c;
  AuroraOptions cfg = aurora_options(d);
  cfg.reset_timeout = 0.2;
  AuroraClient client(cfg, [&](const AuroraSample& s) { c.add(s); });
  client.start();
  ASSERT_TRUE(eventually([&] { return c.count_valid_tip() >= 3; }, 8.0)) << client.status().message;
  ASSERT_TRUE(eventually([&] { return !client.status().healthy(SteadyClock::now(), cfg.timeout); }, 3.0));
  ASSERT_TRUE(eventually([&] { return client.status().connect_failures >= 1; }, 3.0));
  const AuroraStatus st = client.status();
  EXPECT_EQ(st.sessions, 1u);
  EXPECT_NE(st.last_error.find("no RESET reply"), std::string::npos) << st.last_error;
  EXPECT_NE(st.last_error.find("no reply to INIT at 9600 nor at 115200 baud"), std::string::npos) << st.last_error;
  // Nothing was delivered after the silence began: the last sample is older than the timeout.
  const auto v = c.get();
  ASSERT_FALSE(v.empty());
  EXPECT_GT(seconds_between(v.back().received, SteadyClock::now()), cfg.timeout);
}

TEST(AuroraEmulator, DeviceErrorsDecodedAndMissingHandleNamed) {
  TempDir d;
  {
    Emulator emu("aurora_emulator.py", {"--symlink", d / "aurora", "--error-on", "PINIT=13"}, d / "aurora");
    AuroraClient client(aurora_options(d), nullptr);
    client.start();
    ASSERT_TRUE(eventually([&] { return client.status().connect_failures >= 1; }, 5.0));
    const AuroraStatus st = client.status();
    EXPECT_NE(st.last_error.find("PINIT 0A: ERROR13: unable to initialize tool (port handle)"), std::string::npos)
        << st.last_error;
    EXPECT_GE(st.device_errors, 1u);
    EXPECT_FALSE(st.tracking);
  }
  {
    Emulator emu("aurora_emulator.py", {"--symlink", d / "aurora"}, d / "aurora");
    AuroraOptions cfg = aurora_options(d);
    cfg.base_handle = 0x0C;
    AuroraClient client(cfg, nullptr);
    client.start();
    ASSERT_TRUE(eventually([&] { return client.status().connect_failures >= 1; }, 5.0));
    EXPECT_NE(
        client.status().last_error.find("base sensor: port handle 0C not reported by the tracker (handles: 0A 0B)"),
        std::string::npos)
        << client.status().last_error;
  }
}

// ---------------------------------------------------------------------------------------------
// Flow sensors
// ---------------------------------------------------------------------------------------------

namespace {

FlowSensorOptions flow_options(const std::string& port) {
  FlowSensorOptions c;
  c.name = "flow sensor 1";
  c.port = port;
  c.format.field_index = 0;
  c.format.separator = ',';
  c.format.scale_to_m3_per_s = kMlPerMinToM3PerS;
  c.timeout = 0.25;
  c.reconnect_period = 0.2;
  return c;
}

struct Readings {
  std::mutex mu;
  std::vector<FlowReading> v;
  void add(const FlowReading& r) {
    std::lock_guard<std::mutex> l(mu);
    v.push_back(r);
  }
  std::vector<FlowReading> get() {
    std::lock_guard<std::mutex> l(mu);
    return v;
  }
  size_t accepted() {
    std::lock_guard<std::mutex> l(mu);
    size_t n = 0;
    for (const auto& r : v) n += r.accepted;
    return n;
  }
};

}  // namespace

TEST(FlowEmulator, ReadingsInSiAndBadLinesRejected) {
  TempDir d;
  // Duty 0.5 and 0.25: 480 and 240 mL/min. Every 4th line invalid (nan, -12.5, ERR), every 7th
  // random bytes, every 11th over-long; every line arrives in two pieces.
  Emulator emu("flow_emulator.py",
               {"--sensor", d / "flow1", "--sensor", d / "flow2", "--duty", "0.5,0.25", "--bad-every", "4",
                "--garbage-every", "7", "--long-every", "11", "--split", "--tau", "0"},
               d / "flow2");
  Readings r1, r2;
  FlowSensor s1(flow_options(d / "flow1"), [&](const FlowReading& r) { r1.add(r); });
  FlowSensorOptions c2 = flow_options(d / "flow2");
  c2.name = "flow sensor 2";
  FlowSensor s2(c2, [&](const FlowReading& r) { r2.add(r); });
  s1.start();
  s2.start();
  ASSERT_TRUE(eventually([&] { return r1.accepted() >= 30 && r2.accepted() >= 30 && s1.status().discarded > 0; }, 8.0))
      << s1.status().message << " / " << s1.status().last_error;
  bool nan_seen = false, negative_seen = false, text_seen = false;
  for (const FlowReading& r : r1.get()) {
    if (r.accepted) {
      EXPECT_NEAR(r.flow, 480.0 * kMlPerMinToM3PerS, 3.0 * kMlPerMinToM3PerS);
    } else {
      EXPECT_TRUE(std::isnan(r.flow));
      nan_seen |= r.error.find("non-finite") != std::string::npos;
      negative_seen |= r.error.find("negative flow") != std::string::npos;
      text_seen |= r.error.find("not a number") != std::string::npos;
    }
  }
  for (const FlowReading& r : r2.get()) {
    if (r.accepted) {
      EXPECT_NEAR(r.flow, 240.0 * kMlPerMinToM3PerS, 3.0 * kMlPerMinToM3PerS);
    }
  }
  EXPECT_TRUE(nan_seen && negative_seen && text_seen);
  const FlowSensorStatus st = s1.status();
  EXPECT_GT(st.rejected, 0u);
  EXPECT_GT(st.discarded, 0u);
  EXPECT_TRUE(st.healthy(SteadyClock::now(), 1.0));
  EXPECT_NEAR(st.last_flow, 8e-6, 5e-8);
}

TEST(FlowEmulator, SilenceAndUnplugThenRecovery) {
  TempDir d;
  Readings r;
  FlowSensorOptions cfg = flow_options(d / "flow1");
  FlowSensor s(cfg, [&](const FlowReading& x) { r.add(x); });
  {
    // Silent from 0.6 s to 1.4 s, then streaming again, then unplugged at 2.0 s.
    Emulator emu("flow_emulator.py",
                 {"--sensor", d / "flow1", "--duty", "0.5", "--silence-after", "0.6", "--silence-for", "0.8",
                  "--die-after", "2.0"},
                 d / "flow1");
    s.start();
    ASSERT_TRUE(eventually([&] { return s.status().healthy(SteadyClock::now(), cfg.timeout); }, 5.0));
    ASSERT_TRUE(eventually([&] { return !s.status().healthy(SteadyClock::now(), cfg.timeout); }, 3.0));
    EXPECT_TRUE(eventually([&] { return s.status().last_error.find("no valid reading") != std::string::npos; }, 1.0))
        << s.status().last_error;
    ASSERT_TRUE(eventually([&] { return s.status().healthy(SteadyClock::now(), cfg.timeout); }, 3.0))
        << s.status().message;
    EXPECT_GE(s.status().connects, 2u);  // reconnected after the silence
    ASSERT_TRUE(eventually([&] { return emu.exited(); }, 3.0));
    ASSERT_TRUE(eventually([&] { return !s.status().healthy(SteadyClock::now(), cfg.timeout); }, 1.0));
  }
  EXPECT_TRUE(eventually([&] { return s.status().state == LinkState::kDisconnected; }, 1.0));
  const uint64_t connects = s.status().connects;
  Emulator again("flow_emulator.py", {"--sensor", d / "flow1", "--duty", "0.25"}, d / "flow1");
  ASSERT_TRUE(eventually(
      [&] { return s.status().healthy(SteadyClock::now(), cfg.timeout) && s.status().connects > connects; }, 5.0))
      << s.status().message;
  EXPECT_TRUE(eventually([&] { return std::fabs(s.status().last_flow - 4e-6) < 5e-8; }, 1.0));
}

// ---------------------------------------------------------------------------------------------
// Valve board
// ---------------------------------------------------------------------------------------------

namespace {

/// "duty": [a, b, c] of the valve emulator's state file (NaNs when unreadable).
Duty board_duty(const std::string& state_file) {
  const std::string s = text_of(state_file);
  Duty d{std::nan(""), std::nan(""), std::nan("")};
  const size_t k = s.find("\"duty\": [");
  if (k == std::string::npos) return d;
  std::sscanf(s.c_str() + k + 9, "%lf, %lf, %lf", &d[0], &d[1], &d[2]);
  return d;
}

bool near(const Duty& a, const Duty& b) {
  for (int i = 0; i < 3; ++i)
    if (!(std::fabs(a[i] - b[i]) < 1e-4)) return false;
  return true;
}

std::unique_ptr<ValveLoop> make_loop(const std::string& port, std::atomic<bool>* ok, double reconnect = 0.2) {
  SerialValveBoardOptions b;
  b.port = port;
  b.ack_timeout = 0.05;
  ValveLoopOptions l;
  l.rate = 50.0;
  l.command_timeout = 0.1;
  l.max_failures = 3;
  l.reconnect_period = reconnect;
  return std::unique_ptr<ValveLoop>(
      new ValveLoop(std::unique_ptr<ValveDriver>(new SerialValveBoard(b)), l, [ok](std::string* why) {
        if (!ok->load()) *why = "tracker: silent";
        return ok->load();
      }));
}

}  // namespace

TEST(ValveEmulator, CommandsReachTheBoardAndAreGated) {
  TempDir d;
  Emulator emu("valve_emulator.py", {"--symlink", d / "valves", "--state-file", d / "valves.json"}, d / "valves");
  std::atomic<bool> ok{true};
  auto loop = make_loop(d / "valves", &ok);
  loop->start();
  ASSERT_TRUE(eventually([&] { return loop->status().healthy; }, 5.0)) << loop->status().message;
  const Duty want{0.25, 0.5, 1.0};
  ASSERT_TRUE(eventually(
      [&] {
        loop->command(want);
        return near(board_duty(d / "valves.json"), want) && near(loop->status().acknowledged, want);
      },
      2.0));
  // Commands stop: the driver closes the valves (command timeout).
  ASSERT_TRUE(eventually([&] { return near(board_duty(d / "valves.json"), Duty{}); }, 1.0));
  EXPECT_TRUE(eventually([&] { return near(loop->status().acknowledged, Duty{}); }, 0.5));
  EXPECT_NE(loop->status().gate_reason.find("command timeout"), std::string::npos) << loop->status().gate_reason;
  // Another device unhealthy: closed although commands come.
  ok = false;
  for (int k = 0; k < 20; ++k) {
    loop->command(want);
    sleep_s(0.01);
  }
  EXPECT_TRUE(near(board_duty(d / "valves.json"), Duty{}));
  EXPECT_EQ(loop->status().gate_reason, "tracker: silent");
  ok = true;
  ASSERT_TRUE(eventually(
      [&] {
        loop->command({0.1, 0.2, 0.3});
        return near(board_duty(d / "valves.json"), {0.1, 0.2, 0.3});
      },
      2.0));
  // Stop closes them (the emulator writes its state file just after acknowledging).
  loop->stop();
  EXPECT_TRUE(eventually([&] { return near(board_duty(d / "valves.json"), Duty{}); }, 1.0));
  EXPECT_EQ(loop->status().no_reply + loop->status().rejected, 0u);
}

TEST(ValveEmulator, SilenceMakesBoardUnhealthyUntilItAnswersAgain) {
  TempDir d;
  Emulator emu(
      "valve_emulator.py",
      {"--symlink", d / "valves", "--state-file", d / "valves.json", "--silence-after", "0.6", "--silence-for", "1.0"},
      d / "valves");
  std::atomic<bool> ok{true};
  auto loop = make_loop(d / "valves", &ok);
  loop->start();
  ASSERT_TRUE(eventually([&] { return loop->status().healthy; }, 5.0));
  ASSERT_TRUE(eventually([&] { return !loop->status().healthy; }, 3.0));
  const ValveStatus st = loop->status();
  EXPECT_NE(st.last_error.find("acknowledg"), std::string::npos) << st.last_error;
  EXPECT_GE(st.no_reply, 3u);
  ASSERT_TRUE(eventually([&] { return loop->status().healthy; }, 3.0)) << loop->status().message;
  EXPECT_GE(loop->status().connects, 2u);
}

TEST(ValveEmulator, NacksAndCorruptAcksCountedUnplugDetected) {
  TempDir d;
  std::atomic<bool> ok{true};
  auto loop = make_loop(d / "valves", &ok);
  {
    Emulator emu("valve_emulator.py",
                 {"--symlink", d / "valves", "--nack-every", "5", "--bad-checksum-every", "7", "--die-after", "1.5"},
                 d / "valves");
    loop->start();
    ASSERT_TRUE(eventually([&] { return loop->status().healthy; }, 5.0));
    ASSERT_TRUE(eventually(
        [&] {
          loop->command({0.2, 0.2, 0.2});
          return loop->status().rejected >= 3;
        },
        3.0));
    EXPECT_TRUE(loop->status().healthy);  // isolated failures: still healthy
    EXPECT_NE(loop->status().last_error.find("valve"), std::string::npos) << loop->status().last_error;
    ASSERT_TRUE(eventually([&] { return emu.exited(); }, 3.0));
    ASSERT_TRUE(eventually([&] { return !loop->status().healthy; }, 1.0));
    EXPECT_GE(loop->status().hangups, 1u);
  }
  Emulator again("valve_emulator.py", {"--symlink", d / "valves"}, d / "valves");
  ASSERT_TRUE(eventually([&] { return loop->status().healthy; }, 5.0)) << loop->status().message;
}
