#!/usr/bin/env python3
"""Pseudo-terminal emulator of the HydroJet's flow sensors (one pty per sensor), for driver tests.
Standard library only.

No public serial protocol of the Titan Atrato flow sensors is known, so this emulator streams a
configurable ASCII line per reading, which the driver's configurable line reader
(include/hydrojet_control/devices/line_protocols.h, FlowLineFormat) must be set up to read. Default
line: "<flow in mL/min, 2 decimals>,<total in mL, 1 decimal>\\r\\n", e.g. "480.12,1532.5\\r\\n"
(config/rig.yaml: field_index 0, separator ",", unit mL/min). --format changes it (Python format
with the fields flow [mL/min], flow_lpm [L/min], total [mL], seq, temp [degC]).

Sensor k (1-based, in --sensor order) measures the water through valve k: flow = duty_k x
--full-scale [mL/min] through a first-order lag (--tau) plus noise, with duty_k read from the valve
emulator's --valve-state file (see valve_emulator.py), or fixed by --duty d1,d2,d3.

Each sensor writes --rate lines per second whether or not anybody listens; like a UART nobody
reads, bytes that do not fit into the pty are lost.

Fault injection (counts are over each sensor's lines, times in seconds since start):
  --garbage-every N      every N-th line is replaced by random bytes (no line end inside)
  --bad-every N          every N-th line carries an invalid value (nan, -12.5, ERR in turn)
  --long-every N         every N-th line is 300 characters long (longer than any reader accepts)
  --split                every line is written in two pieces 2 ms apart (partial lines)
  --silence-after S      from S on (for --silence-for D s, default forever) sensor
                         --silence-sensor K (0 = all) sends nothing
  --die-after S          exit after S seconds (all sensors unplugged)

Usage: python3 flow_emulator.py --sensor /tmp/rig/flow1 --sensor /tmp/rig/flow2 \\
           --sensor /tmp/rig/flow3 --valve-state /tmp/rig/valves.json
"""

import argparse
import fcntl
import json
import math
import os
import random
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pty_common import PtyDevice, exit_on_signals, exit_with_parent  # noqa: E402


def write_lossy(fd, data):
    """Non-blocking write; what does not fit is dropped (returns bytes written)."""
    try:
        return os.write(fd, data)
    except (BlockingIOError, InterruptedError):
        return 0
    except OSError:
        return 0


class Sensor:
    def __init__(self, k, path, args, rng):
        self.k = k
        self.pty = PtyDevice(symlink=path)
        fl = fcntl.fcntl(self.pty.master, fcntl.F_GETFL)
        fcntl.fcntl(self.pty.master, fcntl.F_SETFL, fl | os.O_NONBLOCK)
        self.args = args
        self.rng = rng
        self.flow = 0.0  # [mL/min], lagged
        self.total = 0.0  # [mL]
        self.seq = 0
        self.next_t = 0.0
        self.pending = None  # second half of a split line: (time, bytes)

    def line(self, t, dt, duty):
        a = self.args
        target = max(0.0, duty * a.full_scale)
        alpha = 1.0 - math.exp(-dt / a.tau) if a.tau > 0 else 1.0
        self.flow += alpha * (target - self.flow)
        self.total += self.flow * dt / 60.0
        self.seq += 1
        q = max(0.0, self.flow + self.rng.gauss(0.0, a.noise)) if self.flow > 0 else 0.0
        if a.garbage_every and self.seq % a.garbage_every == 0:
            return bytes(self.rng.randrange(256) for _ in range(self.rng.randint(3, 20))).replace(
                b"\n", b"x").replace(b"\r", b"y")
        if a.long_every and self.seq % a.long_every == 0:
            return b"9" * 300 + b"\r\n"
        text = a.format.format(flow=q, flow_lpm=q / 1000.0, total=self.total, seq=self.seq, temp=21.5)
        if a.bad_every and self.seq % a.bad_every == 0:
            bad = ["nan", "-12.5", "ERR"][(self.seq // a.bad_every) % 3]
            text = a.format.replace("{flow:.2f}", "{bad}").replace("{flow}", "{bad}").format(
                bad=bad, flow=q, flow_lpm=q / 1000.0, total=self.total, seq=self.seq, temp=21.5)
        return text.encode("ascii")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sensor", action="append", required=True, metavar="PATH",
                    help="symbolic link to create for the next sensor's pty (repeat per sensor)")
    ap.add_argument("--valve-state", help="valve_emulator.py --state-file to read the duties from")
    ap.add_argument("--duty", default="0,0,0", help="fixed duties d1,d2,d3 without --valve-state")
    ap.add_argument("--full-scale", type=float, default=960.0, help="flow at duty 1 [mL/min]")
    ap.add_argument("--tau", type=float, default=0.03, help="flow lag time constant [s]")
    ap.add_argument("--noise", type=float, default=0.5, help="flow noise std [mL/min]")
    ap.add_argument("--rate", type=float, default=50.0, help="lines per second per sensor")
    ap.add_argument("--format", default="{flow:.2f},{total:.1f}\r\n")
    ap.add_argument("--garbage-every", type=int, default=0, metavar="N")
    ap.add_argument("--bad-every", type=int, default=0, metavar="N")
    ap.add_argument("--long-every", type=int, default=0, metavar="N")
    ap.add_argument("--split", action="store_true")
    ap.add_argument("--silence-after", type=float, default=None, metavar="S")
    ap.add_argument("--silence-for", type=float, default=None, metavar="D")
    ap.add_argument("--silence-sensor", type=int, default=0, metavar="K")
    ap.add_argument("--die-after", type=float, default=None, metavar="S")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--exit-with-parent", action="store_true",
                    help="exit when the process that started the emulator dies (tests)")
    args = ap.parse_args(argv)
    if args.rate <= 0:
        ap.error("--rate must be > 0")
    args.format = args.format.encode().decode("unicode_escape")  # allow "\r\n" on the command line

    exit_on_signals()
    if args.exit_with_parent:
        exit_with_parent()
    rng = random.Random(args.seed)
    sensors = []
    try:
        for k, path in enumerate(args.sensor, start=1):
            sensors.append(Sensor(k, path, args, rng))
        fixed = [float(x) for x in args.duty.split(",")]
        duty = fixed + [0.0] * (len(sensors) - len(fixed))
        t0 = time.monotonic()
        period = 1.0 / args.rate
        for s in sensors:  # spread the sensors over the period, like independent devices
            s.next_t = period * (s.k - 1) / max(1, len(sensors))
        last_read = -1.0
        while True:
            t = time.monotonic() - t0
            if args.die_after is not None and t >= args.die_after:
                return 0
            if args.valve_state and t - last_read >= 0.005:
                last_read = t
                try:
                    with open(args.valve_state) as f:
                        d = json.load(f)["duty"]
                    duty = [float(x) for x in d] + [0.0] * max(0, len(sensors) - len(d))
                except (OSError, ValueError, KeyError, TypeError):
                    pass  # no valve board yet (or mid-replace): keep the last duties
            for s in sensors:
                if s.pending and t >= s.pending[0]:
                    write_lossy(s.pty.master, s.pending[1])
                    s.pending = None
                if t < s.next_t:
                    continue
                s.next_t += period
                if s.next_t < t:  # fell behind (suspended): do not burst
                    s.next_t = t + period
                silent = args.silence_after is not None and t >= args.silence_after and (
                    args.silence_for is None or t < args.silence_after + args.silence_for) and (
                    args.silence_sensor in (0, s.k))
                line = s.line(t, period, duty[s.k - 1])
                if silent:
                    continue
                if args.split and len(line) > 2:
                    cut = len(line) // 2
                    write_lossy(s.pty.master, line[:cut])
                    s.pending = (t + 0.002, line[cut:])
                else:
                    write_lossy(s.pty.master, line)
            nxt = min([s.next_t for s in sensors] + [s.pending[0] for s in sensors if s.pending])
            time.sleep(min(0.005, max(0.0, nxt - (time.monotonic() - t0))))
    finally:
        for s in sensors:
            s.pty.close()


if __name__ == "__main__":
    sys.exit(main())
