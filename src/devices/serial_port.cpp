// POSIX serial port and line splitter (see serial_port.h).
#include "hydrojet_control/devices/serial_port.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace hydrojet {
namespace devices {
namespace {

speed_t speed_constant(int baud) {
  switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 921600: return B921600;
    default: return 0;
  }
}

void set_err(std::string* err, const std::string& msg) {
  if (err) *err = msg;
}

std::string sys_error(const std::string& what, int e) { return what + ": " + std::strerror(e); }

timespec to_timespec(double s) {
  if (!(s > 0.0)) return timespec{0, 0};
  timespec ts;
  ts.tv_sec = static_cast<time_t>(std::floor(s));
  ts.tv_nsec = static_cast<long>((s - std::floor(s)) * 1e9);
  if (ts.tv_nsec >= 1000000000L) ts.tv_nsec = 999999999L;
  return ts;
}

/// Unix98 pty slaves have majors 136..143 (UNIX98_PTY_SLAVE_MAJOR and the following 7).
bool fd_is_pty_slave(int fd) {
  struct stat st;
  if (fstat(fd, &st) != 0 || !S_ISCHR(st.st_mode)) return false;
  const unsigned maj = major(st.st_rdev);
  return maj >= 136 && maj <= 143;
}

}  // namespace

bool is_supported_baud(int baud) { return speed_constant(baud) != 0; }

SerialPort::~SerialPort() { close(); }

bool SerialPort::open(const std::string& path, int baud, std::string* err) {
  close();
  if (!is_supported_baud(baud)) {
    set_err(err, "unsupported baud rate " + std::to_string(baud));
    return false;
  }
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    set_err(err, sys_error("open " + path, errno));
    return false;
  }
  if (!isatty(fd)) {
    ::close(fd);
    set_err(err, "open " + path + ": not a terminal (serial port)");
    return false;
  }
  fd_ = fd;
  path_ = path;
  is_pty_ = fd_is_pty_slave(fd);
  if (!configure(baud, err)) {
    close();
    return false;
  }
  tcflush(fd_, TCIOFLUSH);
  return true;
}

void SerialPort::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  is_pty_ = false;
}

bool SerialPort::configure(int baud, std::string* err) {
  termios tio;
  if (tcgetattr(fd_, &tio) != 0) {
    set_err(err, sys_error("tcgetattr " + path_, errno));
    return false;
  }
  cfmakeraw(&tio);  // no echo, no line editing, no CR/NL translation, BREAK reads as NUL
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~(CSTOPB | PARENB | CRTSCTS | CSIZE);
  tio.c_cflag |= CS8;
  tio.c_iflag &= ~(IXON | IXOFF | IXANY);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  const speed_t sp = speed_constant(baud);
  cfsetispeed(&tio, sp);
  cfsetospeed(&tio, sp);
  if (tcsetattr(fd_, TCSANOW, &tio) != 0) {
    set_err(err, sys_error("tcsetattr " + path_, errno));
    return false;
  }
  baud_ = baud;
  return true;
}

bool SerialPort::set_baud(int baud, std::string* err) {
  if (fd_ < 0) {
    set_err(err, "port not open");
    return false;
  }
  if (!is_supported_baud(baud)) {
    set_err(err, "unsupported baud rate " + std::to_string(baud));
    return false;
  }
  return configure(baud, err);
}

bool SerialPort::write_all(const void* data, size_t n, double timeout_s, std::string* err) {
  if (fd_ < 0) {
    set_err(err, "port not open");
    return false;
  }
  const SteadyTime until = SteadyClock::now() + seconds(timeout_s);
  const auto* p = static_cast<const uint8_t*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd_, p, n);
    if (w > 0) {
      p += w;
      n -= static_cast<size_t>(w);
      continue;
    }
    if (w < 0 && errno == EINTR) continue;
    if (w < 0 && (errno == EIO || errno == ENODEV || errno == ENXIO)) {
      set_err(err, "write " + path_ + ": device hung up (unplugged?)");
      return false;
    }
    if (w < 0 && errno != EAGAIN) {
      set_err(err, sys_error("write " + path_, errno));
      return false;
    }
    const double left = seconds_between(SteadyClock::now(), until);
    if (left <= 0.0) {
      set_err(err, "write " + path_ + ": time-out (output not draining)");
      return false;
    }
    pollfd pfd{fd_, POLLOUT, 0};
    const timespec ts = to_timespec(left);
    const int r = ppoll(&pfd, 1, &ts, nullptr);
    if (r < 0 && errno != EINTR) {
      set_err(err, sys_error("poll " + path_, errno));
      return false;
    }
    if (r > 0 && (pfd.revents & (POLLHUP | POLLERR | POLLNVAL))) {
      set_err(err, "write " + path_ + ": device hung up");
      return false;
    }
  }
  return true;
}

SerialPort::ReadStatus SerialPort::read_some(uint8_t* buf, size_t cap, double timeout_s, size_t* n, std::string* err) {
  *n = 0;
  if (fd_ < 0) {
    set_err(err, "port not open");
    return ReadStatus::kError;
  }
  pollfd pfd{fd_, POLLIN, 0};
  const timespec ts = to_timespec(timeout_s);
  int r;
  do {
    r = ppoll(&pfd, 1, &ts, nullptr);
  } while (r < 0 && errno == EINTR);
  if (r < 0) {
    set_err(err, sys_error("poll " + path_, errno));
    return ReadStatus::kError;
  }
  if (r == 0) return ReadStatus::kTimeout;
  if (pfd.revents & POLLNVAL) {
    set_err(err, "read " + path_ + ": invalid descriptor");
    return ReadStatus::kHangup;
  }
  // POLLHUP with POLLIN may still carry the last bytes: read them first.
  const ssize_t got = ::read(fd_, buf, cap);
  if (got > 0) {
    *n = static_cast<size_t>(got);
    return ReadStatus::kData;
  }
  if (got == 0 || (got < 0 && (errno == EIO || errno == ENODEV || errno == ENXIO))) {
    set_err(err, "read " + path_ + ": device hung up (unplugged?)");
    return ReadStatus::kHangup;
  }
  if (got < 0 && (errno == EAGAIN || errno == EINTR)) {
    if (pfd.revents & (POLLHUP | POLLERR)) {
      set_err(err, "read " + path_ + ": device hung up (unplugged?)");
      return ReadStatus::kHangup;
    }
    return ReadStatus::kTimeout;
  }
  set_err(err, sys_error("read " + path_, errno));
  return ReadStatus::kError;
}

bool SerialPort::send_break(std::string* err) {
  if (fd_ < 0) {
    set_err(err, "port not open");
    return false;
  }
  if (tcsendbreak(fd_, 0) != 0) {
    set_err(err, sys_error("tcsendbreak " + path_, errno));
    return false;
  }
  return true;
}

void SerialPort::flush_input() {
  if (fd_ >= 0) tcflush(fd_, TCIFLUSH);
}

// ---------------------------------------------------------------------------------------------
// LineSplitter
// ---------------------------------------------------------------------------------------------

void LineSplitter::feed(const uint8_t* data, size_t n) {
  if (head_ > 0 && head_ == lines_.size()) {
    lines_.clear();
    head_ = 0;
  }
  for (size_t i = 0; i < n; ++i) {
    const char c = static_cast<char>(data[i]);
    if (c == '\n' || c == '\r') {
      if (overflowing_ || bad_byte_) {
        ++discarded_;
      } else if (!partial_.empty()) {
        if (skip_next_) {
          ++skipped_partial_;
        } else {
          lines_.push_back(partial_);
        }
      }
      if (!partial_.empty() || overflowing_ || bad_byte_) skip_next_ = false;
      partial_.clear();
      overflowing_ = bad_byte_ = false;
      continue;
    }
    if (overflowing_) continue;
    if (c == '\0') bad_byte_ = true;
    if (partial_.size() >= max_length_) {
      overflowing_ = true;
      partial_.clear();
      continue;
    }
    partial_.push_back(c);
  }
}

bool LineSplitter::next(std::string* line) {
  if (head_ >= lines_.size()) return false;
  *line = std::move(lines_[head_++]);
  return true;
}

void LineSplitter::reset() {
  partial_.clear();
  lines_.clear();
  head_ = 0;
  overflowing_ = bad_byte_ = false;
}

}  // namespace devices
}  // namespace hydrojet
