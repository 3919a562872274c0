// A POSIX serial port (termios) for the rig's devices: raw 8N1, no flow control, reads with
// time-outs, hang-up detection (unplugged USB adapter, closed pseudo-terminal), BREAK. ROS-free.
//
// Also used on the slave side of a pseudo-terminal (the device emulators in test/emulators/): a
// pty accepts every termios setting, makes the line speed visible to the master side, but silently
// drops a BREAK (see is_pseudo_terminal()).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace hydrojet {
namespace devices {

using SteadyClock = std::chrono::steady_clock;
using SteadyTime = SteadyClock::time_point;

/// Seconds as a steady-clock duration.
inline SteadyClock::duration seconds(double s) {
  return std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(s));
}
/// Seconds between two steady-clock instants (b - a).
inline double seconds_between(SteadyTime a, SteadyTime b) { return std::chrono::duration<double>(b - a).count(); }

/// True for the line speeds a termios port can be set to here (9600 ... 921600, and 1228739, the
/// NDI rate that only exists on some adapters, is not one of them).
bool is_supported_baud(int baud);

class SerialPort {
 public:
  /// Result of read_some().
  enum class ReadStatus {
    kData,     ///< at least one byte read
    kTimeout,  ///< nothing arrived within the time-out (the port is still fine)
    kHangup,   ///< the device went away (EOF, EIO, POLLHUP/POLLERR): close and reconnect
    kError,    ///< another read error (see the message)
  };

  SerialPort() = default;
  ~SerialPort();
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  /// Opens `path` (symbolic links are followed, e.g. /dev/serial/by-id/...) non-blocking, without
  /// becoming its controlling terminal, and configures raw 8N1 at `baud` without flow control;
  /// discards anything buffered. Closes a previously open port first.
  /// @return false with `*err` ("open /dev/ttyUSB0: No such file or directory") on failure.
  bool open(const std::string& path, int baud, std::string* err);
  void close();
  bool is_open() const { return fd_ >= 0; }
  const std::string& path() const { return path_; }
  int baud() const { return baud_; }

  /// Changes the line speed (after the output queue drained). Validates is_supported_baud().
  bool set_baud(int baud, std::string* err);

  /// Writes all `n` bytes, waiting at most `timeout_s` for the output queue to accept them.
  bool write_all(const void* data, size_t n, double timeout_s, std::string* err);
  bool write_all(const std::string& s, double timeout_s, std::string* err) {
    return write_all(s.data(), s.size(), timeout_s, err);
  }

  /// Waits up to `timeout_s` for data and reads what is available (at most `cap` bytes).
  /// `*n` is the number of bytes read (0 unless kData).
  ReadStatus read_some(uint8_t* buf, size_t cap, double timeout_s, size_t* n, std::string* err);

  /// Sends a serial BREAK (tcsendbreak, 0.25 to 0.5 s of zero bits). On a pseudo-terminal this
  /// succeeds but nothing reaches the other side.
  bool send_break(std::string* err);

  /// Discards received but unread bytes.
  void flush_input();

  /// True when the open port is the slave side of a Unix98 pseudo-terminal (/dev/pts/N), where a
  /// BREAK cannot be transmitted.
  bool is_pseudo_terminal() const { return is_pty_; }

 private:
  bool configure(int baud, std::string* err);

  int fd_ = -1;
  int baud_ = 0;
  bool is_pty_ = false;
  std::string path_;
};

/// Splits a byte stream into lines. A line ends at '\n' or '\r' (so "\r\n" ends one line and
/// leaves an empty one, which is skipped). Lines longer than `max_length` and lines containing a
/// NUL byte are discarded whole (counted in discarded()).
class LineSplitter {
 public:
  explicit LineSplitter(size_t max_length = 256) : max_length_(max_length) {}

  void feed(const uint8_t* data, size_t n);
  /// The next complete, non-empty line (terminator removed); false when none is buffered.
  bool next(std::string* line);
  /// Drops the partial line and all complete lines not yet taken.
  void reset();
  /// When set, the first line completed after this call is discarded: after opening a port that was
  /// already streaming, the first line is likely to be the tail of a line (e.g. "3.4" of "123.4"),
  /// which could parse as a valid but wrong number.
  void skip_first_line() { skip_next_ = true; }

  /// Lines dropped for length or a NUL byte.
  uint64_t discarded() const { return discarded_; }
  /// Lines dropped by skip_first_line().
  uint64_t skipped_partial() const { return skipped_partial_; }

 private:
  size_t max_length_;
  std::string partial_;
  std::vector<std::string> lines_;
  size_t head_ = 0;
  bool overflowing_ = false;
  bool bad_byte_ = false;
  bool skip_next_ = false;
  uint64_t discarded_ = 0;
  uint64_t skipped_partial_ = 0;
};

}  // namespace devices
}  // namespace hydrojet
