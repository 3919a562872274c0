#!/usr/bin/python3
"""scripts/teleop driven through a pseudo-terminal against plant_node + controller_node (real time,
path/type none, autostart; teleop_keyboard.test): holding 'up' tilts the view up, i.e. turns the tip
z-axis about the tip's +x axis, towards the tip's -y axis (the contract of controller/view_rate);
the status names the keyboard as the source; after the key is released the direction holds (source
hold); 'q' quits with status 0 and leaves the terminal as it found it.
"""
import math
import os
import select
import subprocess
import sys
import termios
import time
import unittest

import numpy as np
import rospy
import rostest
from hydrojet_control.msg import ControllerStatus, RodState

TELEOP = os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..", "scripts", "teleop")
UP_KEY = b"\x1b[A"
MOVE_ANGLE = 0.15  # [rad] of desired direction to command with the key before letting go


def vec(v):
    return np.array([v.x, v.y, v.z])


def angle(a, b):
    return math.acos(max(-1.0, min(1.0, float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))))))


def tip_y_axis(pose):
    """The tip frame's y-axis in the base frame, from the tip orientation quaternion."""
    w, x, y, z = pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z
    return np.array([2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)])


class Pty:
    """scripts/teleop on a fresh pseudo-terminal; keeps everything it prints."""

    def __init__(self):
        self.master, self.slave = os.openpty()
        self.saved = termios.tcgetattr(self.slave)
        self.proc = subprocess.Popen([TELEOP], stdin=self.slave, stdout=self.slave, stderr=self.slave,
                                     start_new_session=True)
        self.output = b""

    def pump(self, seconds=0.0):
        until = time.monotonic() + seconds
        while True:
            ready, _, _ = select.select([self.master], [], [], max(0.0, min(0.02, until - time.monotonic())))
            if ready:
                try:
                    self.output += os.read(self.master, 65536)
                except OSError:  # the child closed the terminal
                    return
            elif time.monotonic() >= until:
                return

    def screen(self):
        """The last complete frame teleop drew."""
        text = self.output.decode("utf-8", "replace")
        frames = [f for f in text.split("\x1b[H") if "\x1b[J" in f]
        return frames[-1].replace("\x1b[K", "") if frames else ""

    def type(self, data):
        os.write(self.master, data)

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        os.close(self.master)
        os.close(self.slave)


class TeleopKeyboard(unittest.TestCase):
    def setUp(self):
        self.status = None
        self.rod = None
        rospy.Subscriber("controller/status", ControllerStatus, self._on_status, queue_size=10)
        rospy.Subscriber("rod/state", RodState, self._on_rod, queue_size=1)

    def _on_status(self, m):
        if m.state == "running":
            self.ran = True
        elif getattr(self, "ran", False) and getattr(self, "stopped", None) is None:
            self.stopped = "%s: %s" % (m.state, m.reason)  # the first time the controller left running
        self.status = m

    def assert_running(self):
        """The controller has run without a stop since it started: directions of a stopped controller
        (its resting output) say nothing about teleop."""
        self.assertIsNone(getattr(self, "stopped", None), "the controller stopped after it ran")

    def _on_rod(self, m):
        self.rod = m

    def wait_for(self, what, condition, wall_timeout):
        until = time.monotonic() + wall_timeout
        while not condition():
            self.assertLess(time.monotonic(), until,
                            "timed out waiting for %s; teleop's screen:\n%s" % (what, self.pty.screen()))
            self.pty.pump(0.05)

    def sim_sleep(self, seconds):
        """Waits `seconds` of ROS time while reading the terminal."""
        end = rospy.get_time() + seconds
        self.wait_for("%.1f s of simulated time" % seconds, lambda: rospy.get_time() >= end, 60.0)

    def test_up_key_tilts_the_view_up(self):
        self.pty = None
        self.wait_for_controller()
        self.pty = Pty()
        try:
            self.drive_up_then_quit()
        finally:
            self.pty.close()

    def wait_for_controller(self):
        until = time.monotonic() + 60
        while not (self.status and self.status.state == "running" and self.rod):
            self.assertLess(time.monotonic(), until, "controller not running (status: %s)" % self.status)
            time.sleep(0.05)

    def drive_up_then_quit(self):
        screen_ready = lambda: "arrows or W A S D" in self.pty.screen() and "waiting" not in self.pty.screen()
        self.wait_for("the teleop screen, connected to controller/view_rate", screen_ready, 30.0)
        self.sim_sleep(1.0)
        d0, m0 = vec(self.status.desired_direction), vec(self.status.measured_direction)
        up_direction = -tip_y_axis(self.rod.tip_pose)  # up = about tip +x: z turns towards tip -y
        # Hold the key as a terminal does: a byte sequence every 30 ms (auto-repeat).
        until = time.monotonic() + 30.0
        while angle(vec(self.status.desired_direction), d0) < MOVE_ANGLE:
            self.assertLess(time.monotonic(), until, "the desired direction did not move: %s" % self.status)
            self.pty.type(UP_KEY)
            self.pty.pump(0.03)
        self.assertEqual(self.status.source, "keyboard")
        self.assertIn("tilt up", self.pty.screen())
        # Released: the reference stops within the key's window, the tip follows and settles.
        self.sim_sleep(4.0)
        # A stopped controller's status carries the resting output (directions +z): once, in a
        # sanitized run, that read as "the reference snapped back" (0.016 rad from the start, which
        # is the plant's rest direction's distance from +z). Its reason is what to look at.
        self.assert_running()
        d1, m1 = vec(self.status.desired_direction), vec(self.status.measured_direction)
        for name, a, b in (("desired", d0, d1), ("measured", m0, m1)):
            moved = b - a
            toward_up = np.dot(moved, up_direction) / np.linalg.norm(moved)
            print("%s direction moved %.3f rad, %.3f of it toward 'up'" % (name, angle(a, b), toward_up))
            self.assertGreater(angle(a, b), 0.1, name)
            self.assertGreater(toward_up, 0.9, "%s moved %s, up is %s" % (name, moved, up_direction))
        # Holding: no drift of the desired direction.
        self.sim_sleep(2.0)
        self.assertLess(angle(vec(self.status.desired_direction), d1), 0.02)
        self.assertEqual(self.status.state, "running")
        self.assertEqual(self.status.source, "hold")  # the zero twist teleop sent on release
        self.pty.type(b"q")
        self.wait_for("teleop to quit", lambda: self.pty.proc.poll() is not None, 10.0)
        self.assertEqual(self.pty.proc.returncode, 0, self.pty.output.decode("utf-8", "replace")[-2000:])
        self.assertEqual(termios.tcgetattr(self.pty.slave), self.pty.saved, "terminal not restored")


if __name__ == "__main__":
    rospy.init_node("teleop_keyboard_test", anonymous=True)
    rostest.rosrun("hydrojet_control", "teleop_keyboard", TeleopKeyboard, sys.argv)
