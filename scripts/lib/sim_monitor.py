"""Follows a simulated run through /controller/status: prints progress every 10 % of the path and,
at the end, the RMS of the geodesic error between desired and measured tip z-axes.

Exit status: 0 when the path completed, 1 when the controller aborted, 2 on a time-out.
Usage: sim_monitor.py --duration SECONDS [--timeout WALL_SECONDS]
"""
import argparse
import math
import sys
import time

import rospy
from hydrojet_control.msg import ControllerStatus


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, required=True, help="path duration [s]")
    ap.add_argument("--timeout", type=float, default=900.0, help="wall-clock limit [s]")
    args = ap.parse_args(rospy.myargv()[1:])
    rospy.init_node("sim_monitor", anonymous=True, disable_signals=True)
    state = {"n": 0, "sum2": 0.0, "next": 0.1, "done": None, "t": 0.0, "wall0": time.time()}

    def callback(m):
        if state["done"]:
            return
        if m.state in ("running", "finished"):
            state["n"] += 1
            state["sum2"] += m.error_geodesic ** 2
            state["t"] = m.path_time
            frac = m.path_time / args.duration
            if frac >= state["next"]:
                rms = math.sqrt(state["sum2"] / state["n"])
                wall = time.time() - state["wall0"]
                print("  %3.0f %%  t = %6.1f s  error %.4f rad  RMS so far %.4f rad  (%.1fx real time)"
                      % (100 * state["next"], m.path_time, m.error_geodesic, rms, m.path_time / max(wall, 1e-6)),
                      flush=True)
                state["next"] += 0.1
        if m.state == "finished":
            state["done"] = "completed"
        elif m.state == "aborted":
            state["done"] = "aborted at %.2f s: %s" % (m.path_time, m.reason)

    rospy.Subscriber("/controller/status", ControllerStatus, callback, queue_size=1000)
    deadline = time.time() + args.timeout
    while not state["done"] and time.time() < deadline and not rospy.is_shutdown():
        time.sleep(0.05)
    rms = math.sqrt(state["sum2"] / state["n"]) if state["n"] else float("nan")
    outcome = state["done"] or "timed out"
    print("spiral %s; RMS geodesic error %.4f rad over %.1f s of path (paper, hardware: 0.03 rad)"
          % (outcome, rms, state["t"]), flush=True)
    sys.exit(0 if outcome == "completed" else (1 if state["done"] else 2))


if __name__ == "__main__":
    main()
