#!/usr/bin/env python3
"""Pseudo-terminal emulator of the HydroJet valve-driver board (three solenoid valves), for driver
tests. Standard library only.

Protocol (include/hydrojet_control/devices/line_protocols.h), one ASCII line per message:
  host -> board   V,<d1>,<d2>,<d3>*<XX>\\n     duty per valve in [0, 1]
  board -> host   A,<d1>,<d2>,<d3>*<XX>\\n     ack: the duties now applied (4 decimals)
                  N,<reason>*<XX>\\n           nack: command rejected, nothing applied
<XX> = XOR of all bytes before '*', 2 hex digits. A '\\r' before '\\n' is tolerated.

The board answers every line: a valid command with an ack, a malformed one (bad checksum, framing,
duty outside [0, 1]) with a nack. Like a real board should, it closes all valves by itself when no
valid command arrived for --watchdog seconds (0 disables).

--state-file F is rewritten (atomically) whenever the applied duties change and at least every
0.1 s, as one JSON object:
  {"duty": [d1, d2, d3], "commands": n, "nonzero_commands": k, "max_duty": m,
   "acked": a, "nacked": b, "watchdog_trips": w, "time": t}
flow_emulator.py reads "duty" from it (the water that flows through the valves); tests read it to
see what reached the board. On exit the file gets "exited": true and zero duties (an unpowered
board's solenoids close).

Fault injection (times in seconds since the emulator started):
  --silence-after S      from S on (for --silence-for D seconds, default forever) read and ignore
                         every line (valves keep their state until the watchdog closes them)
  --die-after S          exit after S seconds: the driver sees EOF/EIO (unplugged board)
  --nack-every N         answer every N-th valid command with a nack instead of applying it
  --bad-checksum-every N every N-th ack carries a wrong checksum (the duties are applied)
  --reply-delay S        delay before each reply

Usage: python3 valve_emulator.py --symlink /tmp/rig/valves --state-file /tmp/rig/valves.json
"""

import argparse
import json
import os
import select
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pty_common import PtyDevice, exit_on_signals, exit_with_parent, write_all, write_atomic  # noqa: E402


def checksum(payload: str) -> int:
    x = 0
    for c in payload.encode("ascii"):
        x ^= c
    return x


def frame(payload: str, corrupt=False) -> bytes:
    cs = checksum(payload) ^ (0x5A if corrupt else 0)
    return ("%s*%02X\n" % (payload, cs)).encode("ascii")


def parse_command(line: bytes):
    """Returns (duties, None) or (None, reason)."""
    try:
        s = line.decode("ascii")
    except UnicodeDecodeError:
        return None, "non-ASCII"
    if len(s) > 80:
        return None, "too long"
    star = s.find("*")
    if star < 0 or star + 3 != len(s):
        return None, "framing"
    payload, cs = s[:star], s[star + 1:]
    try:
        if int(cs, 16) != checksum(payload):
            return None, "checksum"
    except ValueError:
        return None, "checksum"
    fields = payload.split(",")
    if fields[0] != "V" or len(fields) != 4:
        return None, "not a V command"
    try:
        d = [float(x) for x in fields[1:]]
    except ValueError:
        return None, "bad number"
    if any(not (0.0 <= x <= 1.0) for x in d):
        return None, "duty out of range"
    return d, None


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--symlink", help="make this path a symbolic link to the slave pty")
    ap.add_argument("--link-file", help="write the slave pty path to this file")
    ap.add_argument("--state-file", help="JSON state (applied duties, counters), rewritten on change")
    ap.add_argument("--watchdog", type=float, default=0.5, help="close valves without commands [s]")
    ap.add_argument("--silence-after", type=float, default=None, metavar="S")
    ap.add_argument("--silence-for", type=float, default=None, metavar="D")
    ap.add_argument("--die-after", type=float, default=None, metavar="S")
    ap.add_argument("--nack-every", type=int, default=0, metavar="N")
    ap.add_argument("--bad-checksum-every", type=int, default=0, metavar="N")
    ap.add_argument("--reply-delay", type=float, default=0.0)
    ap.add_argument("-v", "--verbose", action="store_true")
    ap.add_argument("--exit-with-parent", action="store_true",
                    help="exit when the process that started the emulator dies (tests)")
    args = ap.parse_args(argv)

    def log(msg):
        if args.verbose:
            sys.stderr.write("[valve_emulator %.3f] %s\n" % (time.monotonic(), msg))
            sys.stderr.flush()

    exit_on_signals()
    if args.exit_with_parent:
        exit_with_parent()
    pty = PtyDevice(symlink=args.symlink, link_file=args.link_file)
    if not args.symlink and not args.link_file:
        print(pty.path, flush=True)
    t0 = time.monotonic()
    st = {"duty": [0.0, 0.0, 0.0], "commands": 0, "nonzero_commands": 0, "max_duty": 0.0,
          "acked": 0, "nacked": 0, "watchdog_trips": 0, "time": 0.0}
    last_valid = None
    last_write = -1.0
    dirty = True
    buf = b""

    def now():
        return time.monotonic() - t0

    def silent(t):
        return args.silence_after is not None and t >= args.silence_after and (
            args.silence_for is None or t < args.silence_after + args.silence_for)

    try:
        while True:
            t = now()
            if args.die_after is not None and t >= args.die_after:
                log("die-after reached")
                return 0
            if args.watchdog > 0 and last_valid is not None and t - last_valid > args.watchdog \
                    and any(st["duty"]):
                st["duty"] = [0.0, 0.0, 0.0]
                st["watchdog_trips"] += 1
                dirty = True
                log("watchdog: valves closed")
            if args.state_file and (dirty or t - last_write > 0.1):
                st["time"] = t
                write_atomic(args.state_file, json.dumps(st) + "\n")
                last_write, dirty = t, False
            r, _, _ = select.select([pty.master], [], [], 0.01)
            if not r:
                continue
            try:
                chunk = os.read(pty.master, 4096)
            except OSError:
                time.sleep(0.01)
                continue
            if silent(now()):
                buf = b""
                continue
            buf += chunk
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                line = line.rstrip(b"\r")
                if not line:
                    continue
                d, reason = parse_command(line)
                if d is None:
                    reply = frame("N," + reason)
                    st["nacked"] += 1
                else:
                    st["commands"] += 1
                    if args.nack_every and st["commands"] % args.nack_every == 0:
                        reply = frame("N,injected")
                        st["nacked"] += 1
                    else:
                        last_valid = now()
                        st["duty"] = d
                        st["acked"] += 1
                        if any(d):
                            st["nonzero_commands"] += 1
                        st["max_duty"] = max(st["max_duty"], max(d))
                        corrupt = bool(args.bad_checksum_every and st["acked"] % args.bad_checksum_every == 0)
                        reply = frame("A,%.4f,%.4f,%.4f" % tuple(d), corrupt)
                    dirty = True
                if args.reply_delay > 0:
                    time.sleep(args.reply_delay)
                write_all(pty.master, reply)
                log("%r -> %r" % (line, reply))
            if len(buf) > 4096:
                buf = b""
    finally:
        if args.state_file:
            st["time"] = now()
            st["exited"] = True
            st["duty"] = [0.0, 0.0, 0.0]  # a board without power de-energises (closes) its valves
            try:
                write_atomic(args.state_file, json.dumps(st) + "\n")
            except OSError:
                pass
        pty.close()


if __name__ == "__main__":
    sys.exit(main())
