// NDI Aurora session over a serial port: wake-up (BREAK, then INIT probes: ndicapi probes INIT
// before it sends a BREAK, this driver after one; with an adapter that drops the BREAK each connect
// costs reset_timeout more, and a device that did reset is found at 9600 at once),
// baud change, tool definitions, port-handle set-up, BX (or TX) tracking loop, orderly shutdown,
// reconnect. ROS-free; one thread per client. The wire format lives in aurora_protocol.h.
//
// Session (NDI Combined API):
//   open the port at 9600 8N1
//   wake-up, first that answers wins (AuroraStatus::connected_by):
//     kBreak:               BREAK (tcsendbreak), "RESET"+CRC within reset_timeout (0.5 s at most on
//                           a pseudo-terminal). A pty cannot carry a BREAK, so on a pty only the
//                           client follows it with a NUL byte, the stand-in the test emulator
//                           resets on; a real serial port never gets the NUL. (On a pty bridged to
//                           a real device the NUL is one garbage byte: the INIT probe below absorbs
//                           the ERROR reply it causes.)
//     kInitProbe9600:       no RESET (many USB-serial adapters drop a BREAK): INIT at 9600
//     kInitProbeConfigured: no answer at 9600: the host switches to `baud` and INIT there (a device
//                           left at that rate by a run that crashed); COMM is skipped then
//     A CRC-valid ERROR to a probe INIT (ERROR0C: still tracking; ERROR01: garbage before it)
//     shows a live device: TSTOP, then INIT once more. Nothing answered: "reset: ..." names what
//     was tried, and the tracker counts as absent.
//   COMM:<b>0000  (after kBreak / kInitProbe9600, b = 5 for 115200) -> OKAY, host switches 0.1 s later
//   INIT:         -> OKAY (after kBreak; the probes already did it)
//   PHSR:00       all port handles: the configured tip and base handles must be listed
//   PHSR:01       handles to free -> PHF:hh each
//   PHSR:02       handles to initialise: for a handle in `srom_files`, PVWR:<hh><AAAA><64 bytes hex>
//                 per 64-byte chunk of its tool-definition file, then PINIT:hh (tip and base)
//   PHSR:03       handles to enable -> PENA:hh<priority> for the tip and base handles
//   PHSR:04       enabled handles: the tip and base handles must be listed
//   TSTART:       -> OKAY
//   loop at `rate`: BX:<options> (binary, BxParser) or TX:0001 (ASCII, parse_tx_reply), until stop
//                 or a fault. `reply_format` chooses; with `tx_fallback`, a CRC-valid ERROR reply to
//                 BX switches the session to TX (some Aurora firmware rejects BX with several tools).
//   on stop, whenever the device answered INIT on this port: TSTOP (when tracking), COMM:00000 and
//                 the host back to 9600, so the next start finds the device at 9600, not tracking.
// Input is flushed before every ASCII command (and before TX). BX is not flushed: a late BX frame is
// CRC-checked and dropped by its frame number if not new. Every ASCII reply's CRC is checked;
// ERRORxx replies are decoded (describe_error) into the status message. A fault (hang-up, silence,
// device error) closes the port; the client's DeviceWorker (device_worker.h) retries every
// `reconnect_period` seconds with the whole session.
//
// Data rules: each BX reply is CRC-checked by BxParser (header and body CRCs; CRC errors, garbage,
// truncated frames are counted and skipped), each TX reply by its ASCII CRC. A handle's pose is
// delivered only when its frame number changed since the last delivered one (a poll between two
// device frames repeats the previous frame: counted as duplicate, never re-delivered). Out-of-volume
// and missing handles are delivered with their status and no usable transform; the caller publishes
// kValid poses only. Each delivered sample has a stamp: host receive time minus `latency`, strictly
// increasing (when that would not advance, the previous stamp + 1 us).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

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
  enum class ReplyFormat { kBx, kTx };
  ReplyFormat reply_format = ReplyFormat::kBx;  ///< tracking replies: BX (binary) or TX:0001 (ASCII)
  bool tx_fallback = true;                      ///< BX answered with ERRORxx -> TX for the session
  double latency = 0.0;  ///< [s] subtracted from the host receive time for the sample stamp, [0, 1]
  /// Tool-definition (SROM) file per port handle, written with PVWR before PINIT (tools without a
  /// programmed ROM); at most kMaxSromBytes bytes each. Empty: none.
  std::map<uint8_t, std::string> srom_files;

  /// Empty when usable, else "<field>: <what>". Checks the srom_files' handles, not their files.
  std::string validate() const;
};

/// Reads a tool-definition file (a regular file of at most kMaxSromBytes, util::read_regular_file):
/// false with *err ("'<path>': not a regular file", "'<path>' is empty", "'<path>': N bytes, more
/// than the limit of 1024", ...) when it cannot be written with PVWR.
bool load_srom(const std::string& path, std::vector<uint8_t>* data, std::string* err);

/// "bx" / "tx".
const char* to_string(AuroraOptions::ReplyFormat f);

/// COMM parameter for a baud rate ("50000" for 115200), or "" when the Aurora has no code for it.
std::string aurora_comm_params(int baud);

/// One delivered tracker measurement (a BX reply with at least one handle whose frame changed).
struct AuroraSample {
  SteadyTime received;   ///< when the reply was complete
  SteadyTime stamp;      ///< received - latency, strictly increasing over the client's samples
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
  /// How the last successful wake-up reached the device (see the header comment).
  enum class Connect { kNone, kBreak, kInitProbe9600, kInitProbeConfigured };
  Connect connected_by = Connect::kNone;
  bool tx_mode = false;       ///< this session polls with TX (reply_format tx, or the BX fallback)
  uint64_t tx_fallbacks = 0;  ///< sessions switched from BX to TX after an ERROR reply to BX

  /// True when tracking and a valid frame arrived within `timeout` of `now`.
  bool healthy(SteadyTime now, double timeout) const;
  /// True when the handle's last valid pose is within `timeout` of `now`.
  static bool handle_ok(const HandleStats& h, SteadyTime now, double timeout);
};

/// "BREAK", "INIT probe at 9600 baud", "INIT probe at the configured baud", "none".
const char* to_string(AuroraStatus::Connect c);

class AuroraClient : private DeviceSession {
 public:
  using SampleCallback = std::function<void(const AuroraSample&)>;

  /// Reads the `srom_files` (once; validate() does not open them).
  /// @throws std::invalid_argument when `config.validate()` fails or a tool-definition file cannot be
  /// read (the message names srom_files/<handle>).
  AuroraClient(const AuroraOptions& config, SampleCallback on_sample, LogCallback log = nullptr);
  ~AuroraClient() override;
  AuroraClient(const AuroraClient&) = delete;
  AuroraClient& operator=(const AuroraClient&) = delete;

  /// Starts the driver thread (connect, track, reconnect).
  void start() { worker_.start(); }
  /// Stops tracking (TSTOP when the session is up), closes the port, joins the thread.
  void stop() { worker_.stop(); }

  AuroraStatus status() const;
  const AuroraOptions& options() const { return cfg_; }

 private:
  // DeviceSession: one session is connect() then track().
  bool run_session(std::string* fault) override;
  void close_port() override { port_.close(); }
  void shut_down() override;  ///< TSTOP when tracking, COMM:00000, host at 9600, then closes the port
  void mark_link_down() override { status_.tracking = false; }

  bool connect(std::string* err);
  /// BREAK, else INIT probes (header comment); *how says which answered.
  bool wake_device(AuroraStatus::Connect* how, std::string* err);
  bool reset_by_break();
  /// INIT at `baud` (host switched first); a CRC-valid ERROR gets TSTOP and one more INIT.
  bool probe_init(int baud);
  bool switch_host_baud(int baud, std::string* err);
  /// COMM to the configured baud and the host after it.
  bool change_baud(std::string* err);
  bool setup_handles(std::string* err);
  bool write_srom(uint8_t handle, std::string* err);
  /// Sends NAME:params and reads the ASCII reply (CRC checked; ERRORxx decoded into *err and its
  /// text kept in last_error_code_).
  bool command(const std::string& name, const std::string& params, std::string* reply, std::string* err,
               double timeout);
  /// One CR-terminated line; *hangup (if given) tells a hang-up from a time-out.
  bool read_ascii_line(std::string* line, double timeout, std::string* err, bool* hangup = nullptr);
  bool handle_list(const std::string& option, std::vector<std::pair<uint8_t, uint16_t>>* out, std::string* err);
  /// Tracking loop; returns with *err set on a fault, or when stopping.
  void track(std::string* err);
  enum class BxResult { kFrame, kNoFrame, kDeviceError, kHangup };
  BxResult request_bx(BxFrame* frame, std::string* err);
  BxResult request_tx(BxFrame* frame, std::string* err);
  /// After an ERRORxx reply to BX: switches to TX when allowed; false when the error is a fault.
  bool fall_back_to_tx(const std::string& bx_error);
  void count_reply(BxResult r, SteadyTime now);
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
  uint64_t tx_format_errors_ = 0;
  bool closing_ = false;                          ///< stopping, but waiting for the TSTOP / COMM replies
  std::map<uint8_t, std::vector<uint8_t>> srom_;  ///< tool definitions read from srom_files
  bool device_up_ = false;                        ///< the device answered INIT on the open port
  int host_baud_ = 9600;                          ///< the host port's rate
  bool use_tx_ = false;                           ///< this session polls with TX
  std::string last_error_code_;                   ///< "ERRORxx" of the last command's device error, else ""
  std::string bx_error_code_;                     ///< "ERRORxx" seen in the BX stream by the last request_bx
  SteadyTime last_stamp_{};
  bool have_stamp_ = false;

  mutable std::mutex mu_;  ///< guards status_
  AuroraStatus status_;
  DeviceWorker worker_;  ///< last: its thread uses the members above
};

}  // namespace devices
}  // namespace hydrojet
