// Reading a file a user or a program names (a scene, a plant, a path, calibration data): only a
// regular file, and only up to a bound. Opened without blocking, so that a FIFO with no writer does
// not wait; refused unless fstat says regular, so that /dev/zero or /dev/urandom is not read for ever
// into memory (a scene reload of /dev/zero once filled 24 GB); read up to the bound, so that a file
// that grows while it is read is cut off.
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstring>
#include <string>

namespace hydrojet {
namespace util {

constexpr std::size_t kMaxFileBytes = 16u << 20;  ///< 16 MiB: far beyond any scene, plant, path or data file

/// The whole of `path` into *text; "" on success, else why not ("not a regular file", "N bytes, more
/// than the limit of M", the system's error).
inline std::string read_regular_file(const std::string& path, std::string* text,
                                     std::size_t max_bytes = kMaxFileBytes) {
  text->clear();
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return std::string("cannot be read (") + std::strerror(errno) + ")";
  struct stat st {};
  std::string error;
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    error = "not a regular file";
  } else if (static_cast<std::size_t>(st.st_size) > max_bytes) {
    error = std::to_string(st.st_size) + " bytes, more than the limit of " + std::to_string(max_bytes);
  } else {
    char buffer[65536];
    for (ssize_t n; text->size() <= max_bytes && (n = ::read(fd, buffer, sizeof buffer)) != 0;) {
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        error = std::string("read failed (") + std::strerror(errno) + ")";
        break;
      }
      text->append(buffer, static_cast<std::size_t>(n));
    }
    if (error.empty() && text->size() > max_bytes)
      error = "grew past the limit of " + std::to_string(max_bytes) + " bytes";
  }
  ::close(fd);
  if (!error.empty()) text->clear();
  return error;
}

}  // namespace util
}  // namespace hydrojet
