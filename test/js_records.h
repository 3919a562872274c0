// Linux joystick API records (struct js_event, <linux/joystick.h>) as the bytes a /dev/input/js*
// device delivers: what the joystick tests write into a FIFO or feed to the decoder.
#pragma once

#include <linux/joystick.h>

#include <cstdint>
#include <string>

namespace hydrojet {
namespace test {

inline std::string js_record(uint8_t type, uint8_t number, int16_t value, uint32_t time_ms = 1234) {
  js_event e{};
  e.time = time_ms;
  e.value = value;
  e.type = type;
  e.number = number;
  return std::string(reinterpret_cast<const char*>(&e), sizeof e);
}
inline std::string axis(uint8_t n, int16_t v) { return js_record(JS_EVENT_AXIS, n, v); }
inline std::string button(uint8_t n, int16_t v) { return js_record(JS_EVENT_BUTTON, n, v); }
/// The synthetic events the driver sends on open (the state at that moment).
inline std::string initial_axis(uint8_t n, int16_t v) { return js_record(JS_EVENT_AXIS | JS_EVENT_INIT, n, v); }
inline std::string initial_button(uint8_t n, int16_t v) { return js_record(JS_EVENT_BUTTON | JS_EVENT_INIT, n, v); }

}  // namespace test
}  // namespace hydrojet
