"""The keyboard side of scripts/teleop, without ROS or a terminal: which bytes are which key, which key
does what, how long a key stays active, and the help screen. scripts/teleop owns the terminal and
the topics.

A terminal sends no key-release events, only the repeats of a held key. So a tilt key stays active
for a short window after its last byte: FIRST_PRESS_WINDOW after a fresh press (it bridges the
keyboard's auto-repeat delay, typically 250-600 ms, so that holding a key moves smoothly) and
REPEAT_WINDOW after a repeat. When the window runs out, the view holds.
"""
import math

FIRST_PRESS_WINDOW = 0.6  # [s]
REPEAT_WINDOW = 0.3  # [s]
SPEEDS = (0.02, 0.05, 0.1, 0.2, 0.3, 0.5)  # [rad/s] selectable with + and -
DEFAULT_SPEED_INDEX = 2

# Tilt keys: (up rate sign, right rate sign), in the camera (tip) frame: up = about tip +x, right =
# about tip +y.
TILTS = {"up": (1, 0), "down": (-1, 0), "left": (0, -1), "right": (0, 1)}

_ARROWS = {b"A": "up", b"B": "down", b"C": "right", b"D": "left"}
_PLAIN = {"w": "up", "s": "down", "a": "left", "d": "right", "+": "faster", "=": "faster", "-": "slower",
          "_": "slower", " ": "hold", "h": "home", "q": "quit", "\x03": "quit", "\x04": "quit"}


def _escape(buf, i):
    """(key name or None, length) of the escape sequence at buf[i]; length 0 when it is incomplete.
    Arrows come as ESC [ A or ESC O A, with modifiers as ESC [ 1 ; 5 A (taken as the plain arrow)."""
    if i + 1 >= len(buf):
        return None, 0
    if buf[i + 1:i + 2] not in (b"[", b"O"):
        return None, 1  # ESC then something else: drop the ESC
    j = i + 2
    while j < len(buf) and buf[j:j + 1] in b"0123456789;":
        j += 1
    if j >= len(buf):
        return None, 0
    return _ARROWS.get(buf[j:j + 1]), j + 1 - i


def parse_keys(buf):
    """Splits the bytes read from the terminal into key names. Returns (keys, rest): rest is an
    incomplete escape sequence to prepend to the next read (the caller drops it when nothing follows
    soon: a lone Esc key). Unknown bytes and sequences are dropped."""
    keys = []
    i = 0
    while i < len(buf):
        if buf[i:i + 1] == b"\x1b":
            name, length = _escape(buf, i)
            if length == 0:
                return keys, buf[i:]
        else:
            name, length = _PLAIN.get(chr(buf[i]).lower()), 1
        if name:
            keys.append(name)
        i += length
    return keys, b""


class KeyboardTeleop:
    """State of the keyboard: the active tilt key and until when, the speed, the last command."""

    def __init__(self, speed_index=DEFAULT_SPEED_INDEX):
        self.speed_index = speed_index
        self.active = None  # tilt key name
        self.active_until = 0.0  # [s], monotonic
        self.last_command = "none yet"
        self.quit = False

    @property
    def speed(self):
        """[rad/s]"""
        return SPEEDS[self.speed_index]

    def press(self, key, now):
        """Applies one key at time `now` [s]. Returns the one-shot action for the caller: "hold" (send a
        zero rate now), "home" (send the straight direction), "quit", or None."""
        if key in TILTS:
            window = REPEAT_WINDOW if key == self.active and now <= self.active_until else FIRST_PRESS_WINDOW
            self.active = key
            self.active_until = now + window
            self.last_command = "tilt %s at %.2f rad/s" % (key, self.speed)
            return None
        if key in ("faster", "slower"):
            step = 1 if key == "faster" else -1
            self.speed_index = max(0, min(len(SPEEDS) - 1, self.speed_index + step))
            self.last_command = "speed %.2f rad/s" % self.speed
            return None
        self.active = None
        self.last_command = {"hold": "hold", "home": "home (straight, base z-axis)", "quit": "quit"}[key]
        if key == "quit":
            self.quit = True
        return key

    def rates(self, now):
        """(up, right) [rad/s] of the active key, or None when no key is active."""
        if self.active is None:
            return None
        if now > self.active_until:
            self.active = None
            return None
        up, right = TILTS[self.active]
        return up * self.speed, right * self.speed


HELP = """HydroJet keyboard teleoperation (camera view)
  arrows or W A S D   tilt the view up / left / down / right (hold the key)
  + / -               faster / slower
  space               hold here
  h                   home: back to the straight pose
  q                   quit
"""


def render(teleop, rates, controller, connected, max_rate=None):
    """The screen: help, speed, the current rates, the last command and the controller's status line.
    max_rate [rad/s]: the controller's cap on the rates (None: unknown)."""
    moving = "holding" if rates is None else "up %+.2f  right %+.2f rad/s" % rates
    capped = "  (the controller caps it at %.2f)" % max_rate if max_rate is not None and teleop.speed > max_rate else ""
    lines = HELP.splitlines() + [
        "",
        "speed    %.2f rad/s%s" % (teleop.speed, capped),
        "now      %s" % moving,
        "last     %s" % teleop.last_command,
        "robot    %s" % controller,
    ]
    if not connected:
        lines.append("waiting  nobody subscribes to controller/view_rate: is controller_node running?")
    return "\x1b[H" + "".join(line + "\x1b[K\r\n" for line in lines) + "\x1b[J"


def describe_status(m):
    """One line from a hydrojet_control/ControllerStatus: state, source, error, clipping, message."""
    d = m.desired_direction
    theta = math.degrees(math.acos(max(-1.0, min(1.0, d.z)))) if (d.x or d.y or d.z) else float("nan")
    phi = math.degrees(math.atan2(d.y, d.x))
    text = "%s  source %s  target theta %.1f deg phi %.0f deg  error %.3f rad" % (
        m.state, getattr(m, "source", "?") or "-", theta, phi, m.error_geodesic)
    if getattr(m, "clipped", False):
        text += "  CLIPPED by %.3f rad" % m.clip_angle
    if m.reason:
        text += "  (%s)" % m.reason
    elif getattr(m, "message", ""):
        text += "  (%s)" % m.message
    return text
