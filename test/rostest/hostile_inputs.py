#!/usr/bin/python3
"""Hostile inputs at the controller's ROS interfaces (hostile_inputs.test: the simulated plant in
lockstep and the controller holding its start direction). A few hundred randomised inputs drawn from
wide ranges (NaN, +-inf, 1e+-300, huge counts, wrong frames, special files, bytes), one after another:
target directions, look-at points, view rates, joystick messages, follow_path goals, reconfigure
requests and scene reloads. Then a valid goal.

Asserts: both nodes alive; controller/status never silent for more than 0.5 s of wall time (measured
by status_gaps.py, a listener process of its own); the controller never aborts; the desired direction
a finite unit vector in every status; every message, reply and result text (no byte that was not
UTF-8: genpy decodes those as U+FFFD, no control character); a scene reload refused for what is wrong
with the scene (the controller stopped) or because the controller runs, a good one loaded; the valid
goal succeeds afterwards. The seed is printed (and set by ~seed).
"""
import math
import os
import random
import sys
import tempfile
import threading
import time
import unittest
import xmlrpc.client

import actionlib
import dynamic_reconfigure.client
import rosgraph
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import PointStamped, TwistStamped, Vector3, Vector3Stamped
from hydrojet_control.msg import ControllerStatus, FollowPathAction, FollowPathGoal
from sensor_msgs.msg import Joy
from std_msgs.msg import Empty, Float64MultiArray
from std_srvs.srv import Trigger

SILENCE_LIMIT = 0.5  # [s] of wall time between two controller/status messages (status_gaps.py)
SPECIAL = [float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 1.5e154, 1e-300, -1e-300, 0.0, -0.0,
           1e300, 5e-324, 2147483647.0, -2147483648.0]


def number(rng):
    """A float from wide ranges: special values, huge and tiny magnitudes, ordinary ones."""
    r = rng.random()
    if r < 0.35:
        return rng.choice(SPECIAL)
    if r < 0.55:
        return rng.choice((-1, 1)) * 10.0 ** rng.uniform(-300, 300)
    return rng.uniform(-4.0, 4.0)


def number32(rng):
    """The same as a float32 can carry it (beyond its range: an infinity)."""
    v = number(rng)
    return math.copysign(float("inf"), v) if math.isfinite(v) and abs(v) > 3.4e38 else v


def text_fault(s):
    """Why `s` is not text as the controller promises it (util::printable), or None: a byte that was not
    UTF-8 (decoded by genpy as U+FFFD or a surrogate), or a control character but tab and newline."""
    for c in s:
        if c == "\ufffd" or 0xD800 <= ord(c) <= 0xDFFF:
            return "a byte that was not UTF-8 (%r)" % c
        if (ord(c) < 0x20 and c not in "\t\n") or ord(c) == 0x7F:
            return "a control character %r" % c
    return None


def count(rng):
    return rng.choice([0, 1, 2, 3, 7, 50, rng.randrange(0, 2000), 2147483647, -1, -2147483648])


class HostileInputs(unittest.TestCase):
    def setUp(self):
        self.rng = random.Random(rospy.get_param("~seed", 1))
        self.statuses = []
        self.results = []  # follow_path results, from actionlib's thread (checked in this one)
        self.gap_report = None
        self.lock = threading.Lock()
        rospy.Subscriber("controller/status", ControllerStatus, self.on_status, queue_size=100)
        rospy.Subscriber("status_gaps/report", Float64MultiArray, self.on_gaps, queue_size=10)
        self.gap_reset = rospy.Publisher("status_gaps/reset", Empty, queue_size=1, latch=True)
        self.target = rospy.Publisher("controller/target_direction", Vector3Stamped, queue_size=100)
        self.look = rospy.Publisher("controller/look_at", PointStamped, queue_size=100)
        self.rate = rospy.Publisher("controller/view_rate", TwistStamped, queue_size=100)
        self.joy = rospy.Publisher("joy", Joy, queue_size=100)
        self.action = actionlib.SimpleActionClient("controller/follow_path", FollowPathAction)
        self.files = self.make_files()

    def on_status(self, m):
        with self.lock:
            self.statuses.append(m)

    def on_gaps(self, m):
        with self.lock:
            self.gap_report = list(m.data)

    def make_files(self):
        """Path files a goal may name: special files, bytes, a huge sparse file, a directory, good ones."""
        d = tempfile.mkdtemp(prefix="hostile_")
        fifo = os.path.join(d, "fifo.csv")
        os.mkfifo(fifo)
        binary = os.path.join(d, "binary.csv")
        with open(binary, "wb") as f:
            f.write(bytes(self.rng.randrange(256) for _ in range(4096)))
        huge = os.path.join(d, "huge.csv")
        with open(huge, "wb") as f:
            f.truncate(64 << 20)
        many = os.path.join(d, "many.csv")
        with open(many, "w") as f:
            f.writelines("%d 0.1 0\n" % i for i in range(200001))
        good = os.path.join(d, "good.yaml")
        with open(good, "w") as f:
            f.write("- [0, 0.05, 0]\n- [3, 0.2, 1]\n")
        fast = os.path.join(d, "fast.csv")
        with open(fast, "w") as f:
            f.write("0 0 0\n1e-9 3.0 0\n")
        # A scene whose reachable-set sweep would run for minutes: jets of 1e12 N.
        scene = rospy.get_param("/controller/scene")
        with open(scene) as f:
            text = f.read()
        self.absurd_scene = os.path.join(d, "absurd.yaml")
        with open(self.absurd_scene, "w") as f:
            f.write(text.replace("max_force: [0.243, 0.224, 0.244]", "max_force: [1e12, 1e12, 1e12]"))
        return ["/dev/zero", "/dev/null", "/dev/urandom", fifo, binary, huge, many, d, good, fast,
                "/nonexistent/path.csv", "", "\u00ff.csv", "x" * 5000 + ".yaml"]

    # --- the inputs --------------------------------------------------------------------------------
    def frame(self):
        return self.rng.choice(["", "base", "world", "tracker", "nowhere", "/base", "\u00ff\ufffe", "base" * 300])

    def send_target(self):
        m = Vector3Stamped()
        m.header.stamp = rospy.Time.now()
        m.header.frame_id = self.frame()
        m.vector = Vector3(number(self.rng), number(self.rng), number(self.rng))
        self.target.publish(m)

    def send_look_at(self):
        m = PointStamped()
        m.header.stamp = rospy.Time.now()
        m.header.frame_id = self.frame()
        m.point.x, m.point.y, m.point.z = number(self.rng), number(self.rng), number(self.rng)
        self.look.publish(m)

    def send_rate(self):
        m = TwistStamped()
        m.header.stamp = rospy.Time.now()
        m.twist.angular.x, m.twist.angular.y, m.twist.angular.z = number(self.rng), number(self.rng), number(self.rng)
        self.rate.publish(m)

    def send_joy(self):
        m = Joy()
        m.header.stamp = rospy.Time.now()
        m.axes = [number32(self.rng) for _ in range(self.rng.choice([0, 1, 4, 8, 64]))]
        m.buttons = [self.rng.choice([0, 1, -1, 2147483647]) for _ in range(self.rng.choice([0, 1, 4, 12, 64]))]
        self.joy.publish(m)

    def send_goal(self):
        rng = self.rng
        g = FollowPathGoal()
        g.type = rng.choice(["spiral", "raster", "waypoints", "file", "", "SPIRAL", "lissajous", "\u00ff"])
        g.theta_start, g.theta_end, g.phi_start, g.phi_end = (number(rng) for _ in range(4))
        g.duration = rng.choice([number(rng), 0.0, 5.0, 20.0, 1e300])
        g.theta_min, g.theta_max = number(rng), rng.choice([number(rng), 3.0, 0.5])
        g.rows = max(-2147483648, min(2147483647, count(rng)))
        g.raster_phi_start, g.raster_phi_end = number(rng), number(rng)
        g.speed = rng.choice([number(rng), 1e-300, 0.1])
        n = rng.choice([0, 1, 2, 5, 100, 5000])
        g.times = [number(rng) if rng.random() < 0.3 else float(i) for i in range(n)]
        g.directions = [Vector3(number(rng), number(rng), number(rng)) for _ in range(rng.choice([n, n, 0, 3]))]
        g.file = rng.choice(self.files)
        self.action.send_goal(g, done_cb=self.on_done)

    def on_done(self, state, result):
        with self.lock:  # an assertion here, in actionlib's thread, would fail nothing
            self.results.append(result)

    def reconfigure(self):
        names = ["kp", "kd", "feedforward", "damping", "max_force", "max_force_rate"]
        change = {n: number(self.rng) for n in self.rng.sample(names, self.rng.randrange(1, len(names) + 1))}
        try:
            self.reconf.update_configuration(change)
        except Exception as e:  # a refusal is an answer; a dead service is not (checked below)
            if "service" in str(e).lower() and "unavailable" in str(e).lower():
                raise

    def reload_scene(self):
        """A reload of a good or a bad ~scene: the controller stopped first, the reply names what is
        wrong (or the good scene is loaded), then started again; now and then one while it runs,
        refused for that."""
        good = rospy.get_param("/controller/scene")
        with self.lock:
            running = bool(self.statuses) and self.statuses[-1].state == "running"
        if running and self.rng.random() < 0.2:
            reply = self.reload_srv()
            self.assert_text(reply.message, "reload_scene's reply")
            self.assertFalse(reply.success, reply.message)
            self.assertIn("the controller is running", reply.message)
            return
        bad, why = self.rng.choice(self.scenes)
        self.stop_srv()
        # The rod comes to rest before the start below, as an operator waits: a start into a rod still
        # swinging back from the jets' last force trips the oscillation check, rightly.
        rospy.sleep(2.0)
        if bad == 42:
            rospy.set_param("/controller/scene", 42)
        elif bad is None:
            rospy.delete_param("/controller/scene")
        else:
            rospy.set_param("/controller/scene", bad)
        reply = self.reload_srv()
        rospy.set_param("/controller/scene", good)
        self.assert_text(reply.message, "reload_scene's reply")
        if why is None:
            self.assertTrue(reply.success, "%r: %s" % (bad, reply.message))
            self.assertIn("loaded", reply.message)
        else:
            self.assertFalse(reply.success, "%r: %s" % (bad, reply.message))
            self.assertRegex(reply.message, why, "%r refused for another reason" % (bad,))
        self.start_srv()

    def assert_text(self, s, what):
        fault = text_fault(s)
        self.assertIsNone(fault, "%s is not text: %s in %r" % (what, fault, s[:200]))

    # --- the test ----------------------------------------------------------------------------------
    def test_hostile_inputs_change_nothing_but_what_is_valid(self):
        until = time.monotonic() + 60.0
        while not self.statuses or self.statuses[-1].state != "running":
            self.assertLess(time.monotonic(), until, "the controller never ran")
            time.sleep(0.05)
        self.assertTrue(self.action.wait_for_server(rospy.Duration(30.0)))
        self.reconf = dynamic_reconfigure.client.Client("controller", timeout=30)
        rospy.wait_for_service("controller/reload_scene", 30.0)
        self.reload_srv = rospy.ServiceProxy("controller/reload_scene", Trigger)
        self.stop_srv = rospy.ServiceProxy("controller/stop", Trigger)
        self.start_srv = rospy.ServiceProxy("controller/start", Trigger)
        # ~scene values and the reason each is refused for (None: the good scene, loaded).
        self.scenes = [(42, "~scene is not a file name"), (None, "~scene is not set"),
                       ("/dev/zero", "not a regular file"), ("/nonexistent.yaml", r"cannot be read \(No such file"),
                       (self.files[4], "malformed YAML|must be|missing|unknown key"),
                       (self.files[7], "not a regular file"),
                       (self.absurd_scene, "the sweep took more than max_time"),
                       (rospy.get_param("/controller/scene"), None)]
        # The listener's measure of silence starts now.
        self.gap_reset.publish(Empty())
        until = time.monotonic() + 30.0
        while not (self.gap_report and self.gap_report[0] >= 1):
            self.assertLess(time.monotonic(), until, "no report from status_gaps")
            time.sleep(0.05)
        with self.lock:
            first = len(self.statuses)
        senders = [(self.send_target, 5), (self.send_look_at, 3), (self.send_rate, 4), (self.send_joy, 2),
                   (self.send_goal, 5), (self.reconfigure, 3), (self.reload_scene, 1)]
        kinds = [f for f, w in senders for _ in range(w)]
        sent = {}
        for _ in range(rospy.get_param("~inputs", 300)):
            f = self.rng.choice(kinds)
            f()
            sent[f.__name__] = sent.get(f.__name__, 0) + 1
            time.sleep(self.rng.choice([0.0, 0.01, 0.05]))
            self.check(first)
        print("sent: %s" % sent)
        # Afterwards a valid goal runs to its end.
        self.reconf.update_configuration({"kp": 3.0, "kd": 0.0, "feedforward": 1.0, "damping": 0.02,
                                          "max_force": 0.3, "max_force_rate": 1.0})
        self.action.cancel_all_goals()
        time.sleep(0.5)
        g = FollowPathGoal(type="waypoints", times=[0.0, 4.0, 8.0],
                           directions=[Vector3(0, 0, 1), Vector3(0.2, 0, 0.98), Vector3(0, 0.2, 0.98)])
        self.action.send_goal(g)
        self.assertTrue(self.action.wait_for_result(rospy.Duration(120.0)), "the valid goal did not end")
        self.assertEqual(self.action.get_state(), GoalStatus.SUCCEEDED, self.action.get_result())
        self.check(first)
        for node in ("/controller", "/plant"):  # each answers its XML-RPC getPid
            uri = rosgraph.Master("/hostile_inputs_test").lookupNode(node)
            code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/hostile_inputs_test")
            self.assertEqual(code, 1, node + " is not alive")
        time.sleep(0.5)  # the listener's next report
        with self.lock:
            report = list(self.gap_report)
        print("statuses %d (the listener counted %d), longest silence %.3f s" % (
            len(self.statuses) - first, report[2], report[1]))
        self.assertGreater(report[2], 0, "the listener heard no status")

    def test_reconfigure_reports_the_configuration_in_force(self):
        """A refused request changes nothing and is answered with the configuration in force; a valid
        one alone is then accepted (dynamic_reconfigure::Server kept a refused NaN and refused what
        came after it)."""
        reconf = dynamic_reconfigure.client.Client("controller", timeout=30)
        before = reconf.get_configuration(timeout=10)
        for bad in ({"kp": float("nan")}, {"kd": 1e9}, {"kp": -1.0}, {"max_force": float("inf")},
                    {"kp": 2.0, "damping": 0.0}):
            reply = reconf.update_configuration(bad)
            for name in ("kp", "kd", "feedforward", "damping", "max_force", "max_force_rate"):
                self.assertEqual(reply[name], before[name], "%s after %s" % (name, bad))
                self.assertEqual(rospy.get_param("/controller/" + name), before[name], name)
        reply = reconf.update_configuration({"kd": 0.1})
        self.assertEqual(reply["kd"], 0.1)
        self.assertEqual(rospy.get_param("/controller/kd"), 0.1)
        until = time.monotonic() + 10.0  # the client's copy follows ~parameter_updates
        while reconf.get_configuration(timeout=10)["kd"] != 0.1 and time.monotonic() < until:
            time.sleep(0.05)
        self.assertEqual(reconf.get_configuration(timeout=10)["kd"], 0.1)
        reconf.update_configuration({"kd": before["kd"]})

    def check(self, first):
        with self.lock:
            report, statuses = list(self.gap_report), self.statuses[first:]
            results, self.results = self.results, []
        self.assertLessEqual(report[1], SILENCE_LIMIT, "controller/status was silent (status_gaps)")
        for s in statuses:
            self.assertNotEqual(s.state, "aborted", "aborted: " + s.reason)
            d = s.desired_direction
            n = math.sqrt(d.x * d.x + d.y * d.y + d.z * d.z)
            self.assertTrue(math.isfinite(n) and abs(n - 1.0) < 1e-9, "desired direction %s" % d)
            self.assert_text(s.message, "status message")
            self.assert_text(s.reason, "status reason")
        for r in results:
            if r is not None:
                self.assert_text(r.reason, "follow_path result")
        with self.lock:
            del self.statuses[first:first + len(statuses) - 1]


if __name__ == "__main__":
    rospy.init_node("hostile_inputs_test", anonymous=True)
    rostest.rosrun("hydrojet_control", "hostile_inputs", HostileInputs, sys.argv)
