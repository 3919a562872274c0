// Strings that go out in messages (a status, an action result, a service reply) carry text only:
// they are built from what came in (a goal's type, a frame id, a line of a path file) and a client
// that decodes them as UTF-8 fails on raw bytes.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <string>

namespace hydrojet {
namespace util {

/// `s` as text: valid UTF-8 kept, tab and newline kept, every other control byte and every byte that
/// is not part of valid UTF-8 written as \xNN; at most `max_bytes` of the result (then "...").
inline std::string printable(const std::string& s, std::size_t max_bytes = 1024) {
  std::string out;
  const auto byte = [&s](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  std::size_t i = 0;
  while (i < s.size() && out.size() <= max_bytes) {
    const unsigned char c = byte(i);
    // The length of a well-formed UTF-8 sequence starting at i (RFC 3629: no overlong forms, no
    // surrogates, nothing above U+10FFFF), 0 when there is none.
    std::size_t n = 0;
    if (c >= 0x20 && c < 0x7f)
      n = 1;
    else if (c == '\n' || c == '\t')
      n = 1;
    else if (c >= 0xc2 && c <= 0xdf)
      n = 2;
    else if (c >= 0xe0 && c <= 0xef)
      n = 3;
    else if (c >= 0xf0 && c <= 0xf4)
      n = 4;
    if (n > 1) {
      if (i + n > s.size()) n = 0;
      for (std::size_t k = 1; n && k < n; ++k)
        if ((byte(i + k) & 0xc0) != 0x80) n = 0;
      const unsigned char c1 = n ? byte(i + 1) : 0;
      if (n && ((c == 0xe0 && c1 < 0xa0) || (c == 0xed && c1 > 0x9f) || (c == 0xf0 && c1 < 0x90) ||
                (c == 0xf4 && c1 > 0x8f)))
        n = 0;
    }
    if (n == 0) {
      char hex[5];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
      ++i;
    } else {
      out.append(s, i, n);
      i += n;
    }
  }
  if (out.size() > max_bytes || i < s.size()) {
    // Cut at a character boundary, never inside a UTF-8 sequence or an escape.
    std::size_t cut = std::min(max_bytes, out.size());
    while (cut > 0 && (static_cast<unsigned char>(out[cut]) & 0xc0) == 0x80) --cut;
    const std::size_t escape = out.rfind("\\x", cut);
    if (escape != std::string::npos && cut - escape < 4) cut = escape;
    out = out.substr(0, cut) + "...";
  }
  return out;
}

}  // namespace util
}  // namespace hydrojet
