#!/usr/bin/env python3
"""Pseudo-terminal emulator of an NDI Aurora electromagnetic tracker, for driver tests.

Opens a pty pair (os.openpty) and speaks the subset of the NDI Combined API that the HydroJet
driver uses on the slave side, which a driver opens like a serial port. Standard library only.

Wire format (see include/hydrojet_control/devices/aurora_protocol.h):
  command  "NAME:params" + CRC16 (4 uppercase hex) + CR     e.g. b"INIT:E3A5\\r"
           "NAME params" + CR (space form: no CRC, as the NDI API allows)
  reply    text + CRC16 of text (4 hex) + CR                 e.g. b"OKAYA896\\r"
  BX reply binary: C4 A5, u16 body length, u16 header CRC, body, u16 body CRC (little-endian);
           body = u8 handle count, per handle u8 handle, u8 status (01 valid / 02 missing /
           04 disabled), [valid: 8 x f32 q0 qx qy qz tx ty tz rms, in mm], u32 port status,
           u32 frame number [missing: no floats; disabled: nothing], then u16 system status.
  CRC16 is CRC-16/ARC (poly 0xA001 reflected, init 0).

  TX reply (TX:0001) ASCII, CRC over all of it: 2 hex handle count; per handle 2 hex handle, then
           the transform (q0 qx qy qz: sign + 5 digits, /10000; tx ty tz: sign + 6 digits, mm /100;
           rms: sign + 5 digits, mm /10000) or "MISSING", then 8 hex port status, 8 hex frame
           number, LF ("DISABLED" + LF for a disabled handle); then 4 hex system status.

Commands answered: RESET, INIT, COMM, VER, BEEP, PHSR, PINIT, PENA, PDIS, PVWR, TSTART, TSTOP,
BX, TX.
Anything else gets ERROR01. Errors follow the NDI codes: 04 bad CRC, 02 line too long, 07 bad
parameters, 06 unsupported COMM settings, 08 unknown port handle, 09 bad tracking priority,
0C command invalid in the current mode, 0E port handle not initialized, 10 not initialized.

Reset / BREAK: the real device is reset by a serial BREAK and answers b"RESETBE6F\\r" at 9600 baud.
A BREAK cannot be observed through a Linux pty (tcsendbreak() on a pty sends nothing), so the
emulator resets on (a) a NUL byte (what a real UART delivers for a BREAK with IGNBRK/BRKINT off),
and (b) a literal "RESET" line, with or without ":" and CRC (b"RESET\\r", b"RESET:\\r" or
b"RESET:" + CRC + b"\\r"). A driver under test should send its BREAK and, when talking to this
emulator, may follow it with b"RESET\\r" (a real Aurora would answer that with an ERROR reply).

--ignore-break: like a USB-serial adapter that does not pass a BREAK, neither the NUL byte nor a
RESET line resets the emulator: the NUL stays in the input as one garbage byte (so the next command
is answered with an ERROR, as a real Aurora would), and a RESET line is answered with ERROR01.

Baud rate: a pty has no line speed, but the speed a driver sets with tcsetattr() is visible
through the pty. With --strict-baud the emulator ignores (does not answer) lines received while
the slave's output speed differs from the rate the emulated device is at: 9600 after reset, the
COMM rate after the OKAY of a COMM command (COMM:50000 = 115200 8N1).
--start-baud N starts the device at N baud instead of 9600, as a device left at that rate by a run
that crashed (combine with --strict-baud, so that it answers only at that rate, and with
--ignore-break, so that the driver cannot reset it to 9600). --start-tracking starts it initialised
with both handles enabled and tracking (INIT is then answered with ERROR0C until TSTOP).

Handles: 0x0A "tip" moves on a horizontal circle (radius --radius-mm, period --circle-period,
centre (0, 0, -150) mm), yawing with the motion; 0x0B "base" is fixed at (0, 0, -50) mm with the
identity orientation. Both are reported only once PINIT/PENA-ed (BX option 0x0800 also reports
initialized-but-disabled handles as disabled). Frame numbers count at --frame-rate from TSTART.

--tip-tilt R tilts the tip sensor by R rad about its x-axis (so that a controller sees a bent tip).

Fault injection (counts are over BX replies, times over seconds since the emulator started):
  --crc-error-every N     every N-th BX reply has one body byte flipped after its CRC was computed
  --garbage-every N       every N-th BX reply is preceded by 1..32 random bytes
  --truncate-every N      every N-th BX reply is cut short at a random length (the rest never comes)
  --chunk-bytes N         replies are written in pieces of N bytes, --chunk-delay seconds apart, so
                          the driver reads partial frames
  --out-of-volume-after S from S on (for --out-of-volume-for D seconds, default forever), the tip is
                          reported missing (or, with --oov-keep-transform, valid) with port-status
                          bit --oov-bit (default 0x40)
  --silence-after S       from S on (for --silence-for D seconds, default forever) read and ignore
                          everything: the port stays open but the device no longer answers
  --die-after S           exit (status 0) after S seconds, closing the pty: the driver sees EOF/EIO
  --error-on NAME=XX      answer command NAME with ERRORXX (repeatable), e.g. PINIT=13
  --bx-error XX           answer every BX with ERRORXX (firmware that refuses BX); TX works
  --tx-crc-error-every N  every N-th TX reply has one character changed after its CRC was computed
  --unprogrammed HH       port handle HH has no programmed tool ROM (repeatable): its PINIT is
                          answered with ERROR13 until a tool definition was written to it with
                          PVWR:<HH><AAAA><128 hex> in 64-byte chunks from address 0 on; the first
                          PINIT after that logs the event "SROM HH: <n> bytes, CRC <crc16 hex>"
                          (n: bytes written, a multiple of 64; CRC-16/ARC of them). PHSR lists the
                          handle as usual.

Usage:
  python3 aurora_emulator.py --symlink /tmp/rig/aurora [options]
The slave path is published as a symbolic link (--symlink, like a udev name), written atomically to
--link-file, or printed on stdout when neither is given; link and file are removed again on exit.
--events-file F appends one line per command other than BX (and per reset), e.g. "TSTOP: OKAY", so
that a test can check the session. Stops on SIGINT/SIGTERM.
"""

import argparse
import math
import os
import random
import select
import struct
import sys
import termios
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pty_common import PtyDevice, exit_on_signals, exit_with_parent, write_all  # noqa: E402

# ---------------------------------------------------------------------------------------------
# Protocol helpers
# ---------------------------------------------------------------------------------------------


def crc16_arc(data: bytes) -> int:
    """CRC-16/ARC (reflected poly 0xA001, init 0, no final XOR)."""
    crc = 0
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def ascii_reply(text: str) -> bytes:
    """Reply text + CRC16 as 4 uppercase hex digits + CR."""
    raw = text.encode("ascii")
    return raw + b"%04X\r" % crc16_arc(raw)


def encode_bx(handles, system_status=0) -> bytes:
    """handles: list of dicts with keys handle, status (1/2/4), q (4), t_mm (3), rms_mm, port, frame."""
    body = bytearray([len(handles)])
    for h in handles:
        body += bytes([h["handle"], h["status"]])
        if h["status"] == 0x04:
            continue
        if h["status"] == 0x01:
            body += struct.pack("<8f", *h["q"], *h["t_mm"], h["rms_mm"])
        body += struct.pack("<II", h["port"], h["frame"])
    body += struct.pack("<H", system_status)
    header = b"\xC4\xA5" + struct.pack("<H", len(body))
    header += struct.pack("<H", crc16_arc(header))
    return header + bytes(body) + struct.pack("<H", crc16_arc(bytes(body)))


def encode_tx(handles, system_status=0) -> str:
    """The TX:0001 reply text (without CRC) for the same handle dicts as encode_bx."""

    def signed(x, digits):
        v = int(round(x))
        if abs(v) >= 10 ** digits:
            raise ValueError("%r does not fit in %d digits" % (x, digits))
        return ("-" if v < 0 else "+") + "%0*d" % (digits, abs(v))

    out = "%02X" % len(handles)
    for h in handles:
        out += "%02X" % h["handle"]
        if h["status"] == 0x04:
            out += "DISABLED\n"
            continue
        if h["status"] == 0x01:
            out += "".join(signed(q * 1e4, 5) for q in h["q"])
            out += "".join(signed(t * 1e2, 6) for t in h["t_mm"])
            out += signed(h["rms_mm"] * 1e4, 5)
        else:
            out += "MISSING"
        out += "%08X%08X\n" % (h["port"], h["frame"])
    return out + "%04X" % system_status


# COMM baud-rate digit -> (bits per second, termios constant or None)
BAUD_CODES = {
    "0": 9600, "1": 14400, "2": 19200, "3": 38400, "4": 57600, "5": 115200, "6": 921600, "7": 1228739,
}


def termios_speed(bps):
    return getattr(termios, "B%d" % bps, None)


PORT_OCCUPIED = 0x01
PORT_INITIALIZED = 0x10
PORT_ENABLED = 0x20

# ---------------------------------------------------------------------------------------------
# Emulated device
# ---------------------------------------------------------------------------------------------


class Aurora:
    def __init__(self, args, log):
        self.args = args
        self.log = log
        self.rng = random.Random(args.seed)
        self.t0 = time.monotonic()
        self.bx_count = 0
        self.tx_count = 0
        self.events = open(args.events_file, "a", buffering=1) if args.events_file else None
        self.reset()
        self.start_as_left()

    def event(self, text):
        if self.events:
            self.events.write("%.3f %s\n" % (self.now(), text))

    def reset(self):
        self.baud = 9600
        self.initialized = False
        self.tracking = False
        self.track_t0 = None
        self.handles = {
            0x0A: {"name": "tip", "initialized": False, "enabled": False, "srom": {}},
            0x0B: {"name": "base", "initialized": False, "enabled": False, "srom": {}},
        }

    def start_as_left(self):
        """--start-baud / --start-tracking: the state a previous run left the device in."""
        self.baud = self.args.start_baud
        if self.args.start_tracking:
            self.initialized = True
            for h in self.handles.values():
                h["initialized"] = h["enabled"] = True
            self.tracking = True
            self.track_t0 = self.now()

    def srom_image(self, hid):
        """The bytes written with PVWR, contiguous from address 0 (b"" when none)."""
        chunks = self.handles[hid]["srom"]
        out = b""
        while len(out) in chunks:
            out += chunks[len(out)]
        return out

    def now(self):
        return time.monotonic() - self.t0

    # -- command dispatch ----------------------------------------------------------------------

    def handle_line(self, line: bytes):
        """Returns (reply bytes or None, new baud or None)."""
        if len(line) > 250:
            return ascii_reply("ERROR02"), None
        try:
            s = line.decode("ascii")
        except UnicodeDecodeError:
            return ascii_reply("ERROR01"), None
        if s in ("RESET", "RESET:") or s == "RESET:" + "%04X" % crc16_arc(b"RESET:"):
            if self.args.ignore_break:
                self.event("RESET line ignored: ERROR01")
                return ascii_reply("ERROR01"), None
            self.reset()
            self.event("RESET (command)")
            return ascii_reply("RESET"), None
        if ":" in s:
            name, rest = s.split(":", 1)
            if len(rest) < 4:
                return ascii_reply("ERROR04"), None
            params, crc = rest[:-4], rest[-4:]
            try:
                ok = int(crc, 16) == crc16_arc((name + ":" + params).encode("ascii"))
            except ValueError:
                ok = False
            if not ok:
                return ascii_reply("ERROR04"), None
        elif " " in s:
            name, params = s.split(" ", 1)
        else:
            name, params = s, ""
        if name in self.args.error_on:
            code = self.args.error_on[name]
            self.event("%s:%s ERROR%s (injected)" % (name, params, code))
            return ascii_reply("ERROR" + code), None
        fn = getattr(self, "cmd_" + name, None)
        if fn is None:
            self.event("%s:%s ERROR01" % (name, params))
            return ascii_reply("ERROR01"), None
        reply, baud = fn(params.strip())
        if name not in ("BX", "TX") or reply.startswith(b"ERROR"):
            self.event("%s:%s %s" % (name, params, reply[:-5].decode("ascii", "replace")))
        return reply, baud

    def need_init(self):
        return None if self.initialized else (ascii_reply("ERROR10"), None)

    def cmd_INIT(self, p):
        if self.tracking:
            return ascii_reply("ERROR0C"), None
        self.initialized = True
        for h in self.handles.values():
            h["initialized"] = h["enabled"] = False
        return ascii_reply("OKAY"), None

    def cmd_COMM(self, p):
        if len(p) != 5 or not p.isdigit():
            return ascii_reply("ERROR07"), None
        baud_d, data_d, parity_d, stop_d, hs_d = p
        bps = BAUD_CODES.get(baud_d)
        if bps is None or data_d != "0" or parity_d != "0" or stop_d != "0" or hs_d != "0":
            # Only 8N1 without handshake is emulated.
            return ascii_reply("ERROR06"), None
        return ascii_reply("OKAY"), bps

    def cmd_VER(self, p):
        return ascii_reply("HydroJet Aurora emulator\nprotocol subset: BX option 0001/0800"), None

    def cmd_BEEP(self, p):
        return ascii_reply("1"), None

    def port_status(self, hid):
        h = self.handles[hid]
        st = PORT_OCCUPIED
        if h["initialized"]:
            st |= PORT_INITIALIZED
        if h["enabled"]:
            st |= PORT_ENABLED
        return st

    def cmd_PHSR(self, p):
        e = self.need_init()
        if e:
            return e
        opt = p or "00"
        sel = []
        for hid, h in sorted(self.handles.items()):
            if opt == "00":
                sel.append(hid)
            elif opt == "01":
                pass  # no handles need freeing
            elif opt == "02" and not h["initialized"]:
                sel.append(hid)
            elif opt == "03" and h["initialized"] and not h["enabled"]:
                sel.append(hid)
            elif opt == "04" and h["enabled"]:
                sel.append(hid)
            elif opt not in ("00", "01", "02", "03", "04"):
                return ascii_reply("ERROR07"), None
        text = "%02X" % len(sel) + "".join("%02X%03X" % (hid, self.port_status(hid)) for hid in sel)
        return ascii_reply(text), None

    def lookup(self, p):
        try:
            hid = int(p[:2], 16)
        except ValueError:
            return None
        return hid if len(p) >= 2 and hid in self.handles else None

    def cmd_PINIT(self, p):
        e = self.need_init()
        if e:
            return e
        if self.tracking:
            return ascii_reply("ERROR0C"), None
        hid = self.lookup(p)
        if hid is None or len(p) != 2:
            return ascii_reply("ERROR08"), None
        if hid in self.args.unprogrammed:
            image = self.srom_image(hid)
            if not image:
                return ascii_reply("ERROR13"), None
            self.event("SROM %02X: %d bytes, CRC %04X" % (hid, len(image), crc16_arc(image)))
        self.handles[hid]["initialized"] = True
        return ascii_reply("OKAY"), None

    def cmd_PVWR(self, p):
        e = self.need_init()
        if e:
            return e
        if self.tracking:
            return ascii_reply("ERROR0C"), None
        if len(p) != 2 + 4 + 128 or any(c not in "0123456789ABCDEFabcdef" for c in p):
            return ascii_reply("ERROR07"), None
        hid = self.lookup(p)
        if hid is None:
            return ascii_reply("ERROR08"), None
        addr = int(p[2:6], 16)
        if addr % 64 or addr >= 1024:
            return ascii_reply("ERROR07"), None
        self.handles[hid]["srom"][addr] = bytes.fromhex(p[6:])
        return ascii_reply("OKAY"), None

    def cmd_PENA(self, p):
        e = self.need_init()
        if e:
            return e
        if self.tracking:
            return ascii_reply("ERROR0C"), None
        hid = self.lookup(p)
        if hid is None or len(p) != 3:
            return ascii_reply("ERROR08"), None
        if p[2] not in "SDB":
            return ascii_reply("ERROR09"), None
        if not self.handles[hid]["initialized"]:
            return ascii_reply("ERROR0E"), None
        self.handles[hid]["enabled"] = True
        return ascii_reply("OKAY"), None

    def cmd_PDIS(self, p):
        e = self.need_init()
        if e:
            return e
        if self.tracking:
            return ascii_reply("ERROR0C"), None
        hid = self.lookup(p)
        if hid is None or len(p) != 2:
            return ascii_reply("ERROR08"), None
        self.handles[hid]["enabled"] = False
        return ascii_reply("OKAY"), None

    def cmd_TSTART(self, p):
        e = self.need_init()
        if e:
            return e
        if self.tracking:
            return ascii_reply("ERROR0C"), None
        self.tracking = True
        self.track_t0 = self.now()
        return ascii_reply("OKAY"), None

    def cmd_TSTOP(self, p):
        if not self.tracking:
            return ascii_reply("ERROR0C"), None
        self.tracking = False
        return ascii_reply("OKAY"), None

    def cmd_TX(self, p):
        if not self.tracking:
            return ascii_reply("ERROR0C"), None
        if p not in ("", "0001", "0801"):
            return ascii_reply("ERROR07"), None  # only transforms (+ all-handles) are emulated
        reply = ascii_reply(encode_tx(self.poses(all_handles=p == "0801")))
        self.tx_count += 1
        n = self.args.tx_crc_error_every
        if n and self.tx_count % n == 0:
            b = bytearray(reply)
            i = self.rng.randrange(len(b) - 1)  # any byte but the CR
            b[i] = ord("7") if b[i] != ord("7") else ord("3")
            reply = bytes(b)
            self.log("fault: corrupted TX reply #%d" % self.tx_count)
        return reply, None

    def cmd_BX(self, p):
        if not self.tracking:
            return ascii_reply("ERROR0C"), None
        if self.args.bx_error:
            return ascii_reply("ERROR" + self.args.bx_error), None
        try:
            opt = int(p, 16) if p else 0x0001
        except ValueError:
            return ascii_reply("ERROR07"), None
        if len(p) not in (0, 4) or opt & ~0x0801 or not opt & 0x0001:
            return ascii_reply("ERROR07"), None  # only transforms (+ all-handles) are emulated
        reply = encode_bx(self.poses(all_handles=bool(opt & 0x0800)))
        self.bx_count += 1
        a = self.args
        if a.crc_error_every and self.bx_count % a.crc_error_every == 0:
            b = bytearray(reply)
            b[6 + self.rng.randrange(len(b) - 8)] ^= 1 << self.rng.randrange(8)
            reply = bytes(b)
            self.log("fault: corrupted BX reply #%d" % self.bx_count)
        if a.truncate_every and self.bx_count % a.truncate_every == 0:
            reply = reply[:self.rng.randrange(1, len(reply))]
            self.log("fault: BX reply #%d truncated to %d bytes" % (self.bx_count, len(reply)))
        if a.garbage_every and self.bx_count % a.garbage_every == 0:
            junk = bytes(self.rng.randrange(256) for _ in range(self.rng.randint(1, 32)))
            reply = junk + reply
            self.log("fault: %d garbage bytes before BX reply #%d" % (len(junk), self.bx_count))
        return reply, None

    # -- motion model --------------------------------------------------------------------------

    def poses(self, all_handles):
        a = self.args
        t = self.now()
        tt = t - (self.track_t0 or 0.0)
        frame = int(tt * a.frame_rate) & 0xFFFFFFFF
        phi = 2.0 * math.pi * t / a.circle_period
        oov = a.out_of_volume_after is not None and t >= a.out_of_volume_after and (
            a.out_of_volume_for is None or t < a.out_of_volume_after + a.out_of_volume_for)
        out = []
        for hid in sorted(self.handles):
            h = self.handles[hid]
            if not h["enabled"]:
                if all_handles and h["initialized"]:
                    out.append({"handle": hid, "status": 0x04})
                continue
            port = self.port_status(hid)
            if h["name"] == "tip":
                # Rz(phi) * Rx(tilt): yaw with the motion, tilted by --tip-tilt.
                c, s_ = math.cos(phi / 2), math.sin(phi / 2)
                ct, st = math.cos(a.tip_tilt / 2), math.sin(a.tip_tilt / 2)
                q = [c * ct, c * st, s_ * st, s_ * ct]
                tr = [a.radius_mm * math.cos(phi), a.radius_mm * math.sin(phi), -150.0]
                rms = 0.30
                if oov:
                    port |= a.oov_bit
                    status = 0x01 if a.oov_keep_transform else 0x02
                else:
                    status = 0x01
            else:
                q, tr, rms, status = [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -50.0], 0.20, 0x01
            out.append({"handle": hid, "status": status, "q": q, "t_mm": tr, "rms_mm": rms,
                        "port": port, "frame": frame})
        return out


# ---------------------------------------------------------------------------------------------
# pty plumbing
# ---------------------------------------------------------------------------------------------


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--link-file", help="write the slave pty path to this file (atomically)")
    ap.add_argument("--symlink", help="make this path a symbolic link to the slave pty")
    ap.add_argument("--events-file", help="append the non-BX commands and resets to this file")
    ap.add_argument("--tip-tilt", type=float, default=0.0, help="tip sensor tilt about its x-axis [rad]")
    ap.add_argument("--circle-period", type=float, default=10.0, help="tip circle period [s]")
    ap.add_argument("--radius-mm", type=float, default=20.0, help="tip circle radius [mm]")
    ap.add_argument("--frame-rate", type=float, default=40.0, help="frame counter rate [Hz]")
    ap.add_argument("--crc-error-every", type=int, default=0, metavar="N")
    ap.add_argument("--garbage-every", type=int, default=0, metavar="N")
    ap.add_argument("--truncate-every", type=int, default=0, metavar="N")
    ap.add_argument("--chunk-bytes", type=int, default=0, metavar="N")
    ap.add_argument("--chunk-delay", type=float, default=0.001, metavar="S")
    ap.add_argument("--out-of-volume-after", type=float, default=None, metavar="S")
    ap.add_argument("--out-of-volume-for", type=float, default=None, metavar="D")
    ap.add_argument("--silence-after", type=float, default=None, metavar="S")
    ap.add_argument("--silence-for", type=float, default=None, metavar="D")
    ap.add_argument("--oov-bit", type=lambda s: int(s, 0), default=0x40,
                    help="port-status bit set when out of volume (default 0x40)")
    ap.add_argument("--oov-keep-transform", action="store_true",
                    help="when out of volume, keep sending the transform (status valid)")
    ap.add_argument("--die-after", type=float, default=None, metavar="S")
    ap.add_argument("--error-on", action="append", default=[], metavar="NAME=XX",
                    help="answer command NAME with ERRORXX (2 hex digits)")
    ap.add_argument("--ignore-break", action="store_true",
                    help="neither a NUL byte nor a RESET line resets the device (adapter without BREAK)")
    ap.add_argument("--start-baud", type=int, default=9600, metavar="N",
                    help="the device starts at N baud (left there by a previous run)")
    ap.add_argument("--start-tracking", action="store_true",
                    help="the device starts initialised and tracking (left so by a previous run)")
    ap.add_argument("--unprogrammed", action="append", default=[], metavar="HH",
                    help="port handle HH has no tool ROM: PINIT fails until PVWR wrote one")
    ap.add_argument("--bx-error", default="", metavar="XX", help="answer BX with ERRORXX (TX works)")
    ap.add_argument("--tx-crc-error-every", type=int, default=0, metavar="N")
    ap.add_argument("--strict-baud", action="store_true",
                    help="ignore lines received while the pty speed differs from the device's")
    ap.add_argument("--reply-delay", type=float, default=0.0, help="delay before each reply [s]")
    ap.add_argument("--seed", type=int, default=1, help="seed for injected garbage / corruption")
    ap.add_argument("-v", "--verbose", action="store_true", help="log traffic on stderr")
    ap.add_argument("--exit-with-parent", action="store_true",
                    help="exit when the process that started the emulator dies (tests)")
    args = ap.parse_args(argv)
    for n in ("crc_error_every", "garbage_every", "truncate_every", "chunk_bytes", "tx_crc_error_every"):
        if getattr(args, n) < 0:
            ap.error("--%s must be >= 0" % n.replace("_", "-"))
    errors = {}
    for e in args.error_on:
        name, _, code = e.partition("=")
        if not name or len(code) != 2 or any(c not in "0123456789ABCDEFabcdef" for c in code):
            ap.error("--error-on expects NAME=XX with 2 hex digits, got %r" % e)
        errors[name] = code.upper()
    args.error_on = errors
    if args.start_baud not in BAUD_CODES.values():
        ap.error("--start-baud must be one of %s" % sorted(BAUD_CODES.values()))
    if args.bx_error and (len(args.bx_error) != 2 or any(c not in "0123456789ABCDEFabcdef" for c in args.bx_error)):
        ap.error("--bx-error expects 2 hex digits, got %r" % args.bx_error)
    args.bx_error = args.bx_error.upper()
    try:
        args.unprogrammed = {int(h, 16) for h in args.unprogrammed}
    except ValueError:
        ap.error("--unprogrammed expects a hex port handle, e.g. 0A")
    if args.circle_period <= 0 or args.frame_rate <= 0:
        ap.error("--circle-period and --frame-rate must be > 0")

    def log(msg):
        if args.verbose:
            sys.stderr.write("[aurora_emulator %.3f] %s\n" % (time.monotonic(), msg))
            sys.stderr.flush()

    exit_on_signals()
    if args.exit_with_parent:
        exit_with_parent()
    pty = PtyDevice(symlink=args.symlink, link_file=args.link_file)
    master, slave, path = pty.master, pty.slave, pty.path
    if not args.symlink and not args.link_file:
        print(path, flush=True)
    log("slave %s" % path)

    def silent(t):
        return args.silence_after is not None and t >= args.silence_after and (
            args.silence_for is None or t < args.silence_after + args.silence_for)

    def send(data):
        write_all(master, data, args.chunk_bytes, args.chunk_delay)

    dev = Aurora(args, log)
    buf = b""
    try:
        while True:
            if args.die_after is not None and dev.now() >= args.die_after:
                log("die-after reached: exiting")
                return 0
            r, _, _ = select.select([master], [], [], 0.02)
            if not r:
                continue
            try:
                chunk = os.read(master, 4096)
            except OSError:  # EIO: no slave open (cannot happen while we hold it); keep going
                time.sleep(0.02)
                continue
            if silent(dev.now()):
                buf = b""
                continue
            buf += chunk
            while True:
                nul = -1 if args.ignore_break else buf.find(b"\x00")
                cr = buf.find(b"\r")
                if nul >= 0 and (cr < 0 or nul < cr):
                    buf = buf[nul + 1:]
                    log("BREAK (NUL byte): reset")
                    dev.reset()
                    dev.event("RESET (NUL byte)")
                    send(ascii_reply("RESET"))
                    continue
                if cr < 0:
                    if len(buf) > 4096:
                        buf = b""  # runaway line without CR
                    break
                line, buf = buf[:cr].replace(b"\n", b""), buf[cr + 1:]
                if not line:
                    continue
                if args.strict_baud:
                    ospeed = termios.tcgetattr(slave)[5]
                    want = termios_speed(dev.baud)
                    if want is not None and ospeed != want:
                        log("ignored %r: pty speed does not match device rate %d" % (line, dev.baud))
                        continue
                reply, new_baud = dev.handle_line(line)
                if args.reply_delay > 0:
                    time.sleep(args.reply_delay)
                if reply is not None:
                    send(reply)
                    log("%r -> %r" % (line, reply if len(reply) < 80 else reply[:80] + b"..."))
                if new_baud is not None:
                    dev.baud = new_baud
                    log("device now at %d baud" % new_baud)
    finally:
        pty.close()


if __name__ == "__main__":
    sys.exit(main())
