// NDI Aurora session over a serial port: reset, baud change, port-handle set-up, BX tracking loop,
// reconnect. ROS-free; one thread per client. The wire format lives in aurora_protocol.h.
//
// Session (NDI Combined API):
//   open the port at 9600 8N1
//   reset:   BREAK (tcsendbreak) and wait for "RESET"+CRC. A pseudo-terminal, and some USB
//            adapters, drop a BREAK; then the client sends a NUL byte, which a UART delivers for a
//            BREAK and which the test emulator (test/emulators/aurora_emulator.py) treats as one.
//   COMM:<b>0000  (8N1, no handshake; b = 5 for 115200) -> OKAY, then switch the port speed
//   INIT:         -> OKAY
//   PHSR:00       all port handles: the configured tip and base handles must be listed
//   PHSR:01       handles to free -> PHF:hh each
//   PHSR:02       handles to initialise -> PINIT:hh for the tip and base handles
//   PHSR:03       handles to enable -> PENA:hh<priority> for the tip and base handles
//   PHSR:04       enabled handles: the tip and base handles must be listed
//   TSTART:       -> OKAY
//   loop at `rate`: BX:<options> -> binary reply (BxParser), until stop or a fault
//   TSTOP:        on stop (shutdown)
// Every ASCII reply's CRC is checked; ERRORxx replies are decoded (describe_error) into the status
// message. A fault (hang-up, silence, device error) closes the port; the client's DeviceWorker
// (device_worker.h) retries every `reconnect_period` seconds with the whole session.
//
// Data rules: each BX reply is CRC-checked by BxParser (CRC errors, garbage, truncated frames are
// counted and skipped). A handle's pose is delivered only when its frame number changed since the
// last delivered one (a BX poll between two device frames repeats the previous frame: counted as
// duplicate, never re-delivered). Out-of-volume and missing handles are delivered with their
// status and no usable transform; the caller publishes kValid poses only.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>

#include "hydrojet_control/devices/aurora_protocol.h"
#include "hydrojet_control/devices/device_status.h"
#include "hydrojet_control/devices/device_worker.h"
#include "hydrojet_control/devices/serial_port.h"

namespace hydrojet {
namespace devices {

struct AuroraOptions {
  std::string port;               ///< serial device path (e.g. /dev/serial/by-id/...)
  int baud = 115200;              ///< tracking baud rate, set by COMM (9600 ... 921600)
  uint8_t tip_handle = 0x0A;      ///< port handle of the tip (capsule) sensor
  uint8_t base_handle = 0x0B;     ///< port handle of the base (holder) sensor
  double rate = 40.0;             ///< BX requests per second [Hz] (the Aurora measures at 40 Hz)
  double reply_timeout = 0.05;    ///< BX reply [s]
  double command_timeout = 3.0;   ///< ASCII replies during set-up (INIT, PINIT are slow) [s]
  double reset_timeout = 5.0;     ///< RESET reply after a BREAK on a real port [s]
  double timeout = 0.25;          ///< no valid BX frame (device silent) / no valid pose of a
                                  ///< handle (sensor unhealthy) for this long [s]
  double reconnect_period = 1.0;  ///< wait between connection attempts [s]
  uint32_t out_of_volume_mask = kDefaultOutOfVolumeMask;  ///< port-status bits meaning "out of volume"
  char tracking_priority = 'D';                           ///< PENA priority: S static, D dynamic, B button box
  std::string bx_options = "0001";                        ///< BX reply option (0001: transformation data)

  /// Empty when usable, else "<field>: <what>".
  std::string validate() const;
};

/// COMM parameter for a baud rate ("50000" for 115200), or "" when the Aurora has no code for it.
std::string aurora_comm_params(int baud);

/// One delivered tracker measurement (a BX reply with at least one handle whose frame changed).
struct AuroraSample {
  SteadyTime received;   ///< when the reply was complete
  HandlePose tip, base;  ///< kMissing with frame 0 when the handle was not in the reply
  bool tip_new = false;  ///< tip frame number changed since the last delivered tip
  bool base_new = false;
  uint16_t system_status = 0;
};

/// Per-handle counters (new frames only).
struct HandleStats {
  HandlePose::Status last_status = HandlePose::kMissing;
  uint64_t valid = 0, missing = 0, out_of_volume = 0, disabled = 0;
  double last_rms_m = 0.0;  ///< RMS error of the last valid pose [m]
  SteadyTime last_valid{};  ///< epoch when never
  bool ever_valid = false;
};

/// Link state, message and last fault (LinkStatus), and the tracking counters.
struct AuroraStatus : LinkStatus {
  bool tracking = false;    ///< TSTART acknowledged and BX loop running
  SteadyTime last_frame{};  ///< last CRC-valid BX frame
  bool ever_frame = false;
  HandleStats tip, base;
  uint64_t frames = 0;            ///< CRC-valid BX frames
  uint64_t duplicate_frames = 0;  ///< frames with no new frame number (not delivered)
  uint64_t crc_errors = 0;        ///< BX header/body CRC errors + ASCII reply CRC errors
  uint64_t garbage_bytes = 0;
  uint64_t format_errors = 0;
  uint64_t truncated_frames = 0;
  uint64_t reply_timeouts = 0;  ///< BX requests without a valid reply in time
  uint64_t device_errors = 0;   ///< ERRORxx replies
  uint64_t sessions = 0;        ///< successful TSTARTs
  uint64_t connect_failures = 0;
  bool reset_by_break = false;  ///< last reset answered the BREAK (false: NUL fallback)

  /// True when tracking and a valid frame arrived within `timeout` of `now`.
  bool healthy(SteadyTime now, double timeout) const;
  /// True when the handle's last valid pose is within `timeout` of `now`.
  static bool handle_ok(const HandleStats& h, SteadyTime now, double timeout);
};

class AuroraClient : private DeviceSession {
 public:
  using SampleCallback = std::function<void(const AuroraSample&)>;

  /// @throws std::invalid_argument when `config.validate()` fails.
  AuroraClient(const AuroraOptions& config, SampleCallback on_sample, LogCallback log = nullptr);
  ~AuroraClient() override;
  AuroraClient(const AuroraClient&) = delete;
  AuroraClient& operator=(const AuroraClient&) = delete;

  /// Starts the driver thread (connect, track, reconnect).
  void start() { worker_.start(); }
  /// Stops tracking (TSTOP when the session is up), closes the port, joins the thread.
  void stop() { worker_.stop(); }

  AuroraStatus status() const;
  const AuroraOptions& config() const { return cfg_; }

 private:
  // DeviceSession: one session is connect() then track().
  bool run_session(std::string* fault) override;
  void close_port() override { port_.close(); }
  void shut_down() override;  ///< TSTOP when tracking, then closes the port
  void mark_link_down() override { status_.tracking = false; }

  bool connect(std::string* err);
  bool reset_device(std::string* err);
  /// Sends NAME:params and reads the ASCII reply (CRC checked; ERRORxx decoded into *err).
  bool command(const std::string& name, const std::string& params, std::string* reply, std::string* err,
               double timeout);
  bool read_ascii_line(std::string* line, double timeout, std::string* err);
  bool handle_list(const std::string& option, std::vector<std::pair<uint8_t, uint16_t>>* out, std::string* err);
  /// Tracking loop; returns with *err set on a fault, or when stopping.
  void track(std::string* err);
  enum class BxResult { kFrame, kNoFrame, kDeviceError, kHangup };
  BxResult request_bx(BxFrame* frame, std::string* err);
  void deliver(const BxFrame& frame, SteadyTime received);

  bool stopping() const { return worker_.stopping(); }

  const AuroraOptions cfg_;
  SampleCallback on_sample_;
  SerialPort port_;
  BxParser parser_;
  std::string ascii_tail_;  ///< recent non-BX bytes (ERROR replies inside the BX stream)
  uint32_t last_tip_frame_ = 0, last_base_frame_ = 0;
  bool have_tip_frame_ = false, have_base_frame_ = false;
  uint64_t ascii_crc_errors_ = 0;
  bool closing_ = false;  ///< stopping, but waiting for the TSTOP reply

  mutable std::mutex mu_;  ///< guards status_
  AuroraStatus status_;
  DeviceWorker worker_;  ///< last: its thread uses the members above
};

}  // namespace devices
}  // namespace hydrojet
