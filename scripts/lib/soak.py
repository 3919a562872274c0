#!/usr/bin/env python3
"""The soak run of scripts/soak: the simulated plant and the controller on the real ROS graph in
lockstep for a long stretch of simulated time, under a seeded random schedule of faults and operator
commands, each fault judged against what the safety monitor promises (docs/robustness.md).

The script starts its own roscore, plant_node and controller_node (as separate processes, so that it
can stop and restart them) and drives them through their public interfaces only: plant/fault (the
plant applies a fault and echoes it on plant/fault_applied with its simulated time), the controller's
start/stop services, controller/target_direction and the controller/follow_path action. It reads
controller/status and jets/command.

Per fault it records: injected at (the plant's echo), detected at (the first status 'aborted', or
'idle' for a stop), the reason, when jets/command went all zero, and when the controller ran again
after a restart by service. A fault passes when
  - the reason is the one the safety monitor names for it (EXPECTED below),
  - detected - injected <= its detection bound (DETECT_BOUND, derived from the controller's
    stale_periods x sample_period, one control period and, for a stuck valve, flow_fault_time),
  - jets/command is all zero from the detecting cycle on (zero within one control period),
  - a restart by controller/start runs again for RECOVER_S without an abort.
Operator commands pass when the controller accepts them and does not abort before the next event.
At the end: every node alive (a crash fails), resident memory growth after warm-up <= 5 % for the
controller (alive the whole run) and for the plant over its longest life, and a table printed and
written as Markdown and JSON.

Usage: soak.py --sim-seconds S --seed N --out DIR   (run by scripts/soak, with the devel space
sourced and ROS_MASTER_URI set).
"""
import argparse
import collections
import json
import math
import os
import random
import signal
import subprocess
import sys
import threading
import time
import xmlrpc.client

import actionlib
import rosgraph
import rospy
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped, Vector3, Vector3Stamped
from hydrojet_control.msg import (ControllerStatus, FollowPathAction, FollowPathGoal, JetCommand,
                                  JetState, PlantFault)
from rosgraph_msgs.msg import Clock
from std_srvs.srv import Trigger

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CONTROL_PERIOD = 0.01  # [s] config/controller.yaml rate 100 Hz
STALE_AFTER = 0.03     # [s] safety/stale_periods (3) x safety/sample_period (0.01)
FLOW_FAULT_TIME = 0.5  # [s] safety/flow_fault_time
RECOVER_S = 3.0        # [s] of running after a restart that count as recovered
SETTLED_RAD = 0.03     # [rad] the tip counts as at rest when its direction stayed this close ...
SETTLED_S = 0.5        # [s] ... to the latest for this long (tracker noise is ~0.005 rad per sample)
WARMUP_S = 60.0        # [s] simulated; memory is compared from here on
# The self-test's switches (scripts/ci_selftest): soak_fault_not_recovered: the first fault sent to the
# plant never ends, though it is judged as scheduled, so the controller cannot recover from it;
# soak_restart_not_recovered: the first fault is a plant restart whose new plant loses its tracker for
# good once the controller hears it. This judge must say "not recovered" for each.
INJECT = os.environ.get("HYDROJET_SELFTEST_INJECT", "")
NOT_RECOVERED = INJECT == "soak_fault_not_recovered"
RESTART_NOT_RECOVERED = INJECT == "soak_restart_not_recovered"

# Expected abort reason (prefixes of SafetyMonitor's texts) and detection bound per fault kind.
# The bounds: data older than STALE_AFTER is refused at the next control cycle, so a dropout is seen
# within STALE_AFTER + 2 periods (one for the stale test's strict '>', one for the cycle phase); a bad
# reading is refused at the first cycle that reads it (2 periods: sample and cycle phase); a stuck
# valve trips the flow-fault integral within flow_fault_time once the deviation is twice the
# tolerance; the deviation builds up only as the loop drives that jet's command away from the stuck
# flow (1/kp = 0.33 s) and the flow line follows (~0.1 s): 1.5 s (the hour's worst of 42 was 1.09 s);
# a plant restart is seen at the first cycle after the clock resumes, downtime later.
EXPECTED = {
    "tracker_dropout": ("tracker: tip pose stale",),
    "flow_nan": ("flow: jet {j} reading invalid",),
    "flow_negative": ("flow: jet {j} reading invalid",),
    "flow_silent": ("flow: no valid flow sample",),
    # a valve stuck wide open throws the tip past max_oscillation before the flow integral trips:
    # the oscillation check is then the one that stops the jets (the table counts which fired)
    "stuck_valve": ("flow: jet {j} does not follow its command", "oscillation:"),
    "plant_restart": ("tracker: tip pose stale", "flow: samples stale"),
    "controller_stop": ("",),
}
DETECT_BOUND = {
    "tracker_dropout": STALE_AFTER + 2 * CONTROL_PERIOD,
    "flow_nan": 2 * CONTROL_PERIOD,
    "flow_negative": 2 * CONTROL_PERIOD,
    "flow_silent": 2 * CONTROL_PERIOD,
    "stuck_valve": 3 * FLOW_FAULT_TIME,
    # controller_stop: one period after the service returned (the bound is set per call)
}


class Graph:
    """roscore, plant_node and controller_node as child processes; logs in out/."""

    def __init__(self, out, seed):
        self.out, self.seed = out, seed
        self.bin = os.path.join(os.environ["HYDROJET_BIN_DIR"])
        self.procs = {}
        self.plant_lives = []  # [start sim time, pid, rss samples [(t, kB)]]

    def spawn(self, name, argv):
        log = open(os.path.join(self.out, name + ".log"), "a")
        p = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        self.procs[name] = p
        return p

    def start_master(self):
        port = os.environ["ROS_MASTER_URI"].rsplit(":", 1)[1]
        self.spawn("roscore", ["roscore", "-p", port])
        for _ in range(200):
            if subprocess.call(["rosparam", "list"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) == 0:
                return
            time.sleep(0.1)
        raise RuntimeError("roscore did not come up")

    def set_params(self):
        scene = os.path.join(ROOT, "config/scenes/hydrojet_0deg.yaml")
        rospy.set_param("/use_sim_time", True)
        subprocess.check_call(["rosparam", "load", os.path.join(ROOT, "config/controller.yaml"), "/controller"])
        # The rostests' shortened spiral (below the plant's oscillation-prone large bends), rerun at
        # each restart; operator targets and paths interleave.
        # One key at a time: setting a mapping would replace the whole namespace just loaded.
        for key, value in (("scene", scene), ("autostart", True), ("path/duration", 40.0),
                           ("path/theta_end", 0.7), ("path/phi_end", 6.0)):
            rospy.set_param("/controller/" + key, value)
        for key, value in (("scene", scene), ("plant", os.path.join(ROOT, "config/plant.yaml")), ("seed", self.seed)):
            rospy.set_param("/plant/" + key, value)

    def start_plant(self, start_time):
        rospy.set_param("/plant/start_time", float(start_time))
        p = self.spawn("plant", [os.path.join(self.bin, "plant_node"), "__name:=plant"])
        self.plant_lives.append([start_time, p.pid, []])
        return p

    def start_controller(self):
        return self.spawn("controller", [os.path.join(self.bin, "controller_node"), "__name:=controller"])

    def stop(self, name, sig=signal.SIGTERM, timeout=10.0):
        """Signals a node and waits for its exit; its exit status (None when it had to be killed)."""
        p = self.procs.get(name)
        if p is None or p.poll() is not None:
            return p.returncode if p else None
        p.send_signal(sig)
        try:
            return p.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
            return None

    def shutdown(self):
        for name in ("controller", "plant", "roscore"):
            self.stop(name, signal.SIGINT if name == "roscore" else signal.SIGTERM)


def rss_kb(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


class Monitor:
    """What the graph says: simulated time, controller state changes, jets/command zero or not."""

    def __init__(self):
        self.t = 0.0
        self.status = None
        self.transitions = []  # (stamp, state, reason)
        self.zero_changes = []  # (stamp, all_zero)
        self.applied = []      # PlantFault echoes
        self.last_zero = None
        self.last_command = -1.0  # stamp of the latest jets/command
        self.last_state = -1.0    # stamp of the latest jets/state (the plant's own time)
        self.directions = collections.deque()  # (stamp, measured tip direction), the last SETTLED_S
        rospy.Subscriber("/clock", Clock, self.on_clock, queue_size=100)
        rospy.Subscriber("/controller/status", ControllerStatus, self.on_status, queue_size=1000)
        rospy.Subscriber("/jets/command", JetCommand, self.on_command, queue_size=1000)
        rospy.Subscriber("/tracker/tip_pose", PoseStamped, self.on_tip, queue_size=1000)
        rospy.Subscriber("/jets/state", JetState, self.on_state, queue_size=1000)
        self.applied_sub = rospy.Subscriber("/plant/fault_applied", PlantFault, self.applied.append, queue_size=100)

    def on_state(self, m):
        self.last_state = max(self.last_state, m.header.stamp.to_sec())

    def on_clock(self, m):
        self.t = m.clock.to_sec()

    def on_status(self, m):
        # A new state, or an abort for another reason (a restart that aborts again in its first cycle
        # never reports 'running').
        if self.status is None or m.state != self.status.state or (
                m.state == "aborted" and m.reason != self.status.reason):
            self.transitions.append((m.header.stamp.to_sec(), m.state, m.reason))
        self.status = m

    def on_tip(self, m):
        """The tip sensor's z-axis in the tracker frame (the base does not move: its spread over time
        is the tip's motion, whatever the controller's state)."""
        q = m.pose.orientation
        t = m.header.stamp.to_sec()
        self.directions.append((t, (2 * (q.x * q.z + q.w * q.y), 2 * (q.y * q.z - q.w * q.x),
                                    1 - 2 * (q.x * q.x + q.y * q.y))))
        while self.directions and self.directions[0][0] < t - SETTLED_S:
            self.directions.popleft()

    def settled(self):
        """The tip at rest: over the last SETTLED_S every measured direction within SETTLED_RAD of the
        latest (a ringing rod swings through more than that within one period)."""
        snap = list(self.directions)  # one copy: the subscriber thread appends and pops meanwhile
        if len(snap) < 2 or snap[-1][0] - snap[0][0] < SETTLED_S - 0.02:
            return False
        last = snap[-1][1]
        return all(math.acos(max(-1.0, min(1.0, sum(a * b for a, b in zip(d, last))))) < SETTLED_RAD
                   for _, d in snap)

    def on_command(self, m):
        self.last_command = m.header.stamp.to_sec()
        zero = all(v == 0.0 for v in m.valve_command)
        if zero != self.last_zero:
            self.zero_changes.append((m.header.stamp.to_sec(), zero))
            self.last_zero = zero

    def state(self):
        return self.status.state if self.status else "none"

    def first_transition(self, after, states):
        for stamp, state, reason in self.transitions:
            if stamp >= after and state in states:
                return stamp, state, reason
        return None

    def zero_from(self, after):
        """The first stamp >= after from which jets/command stayed all zero up to the next change."""
        for stamp, zero in self.zero_changes:
            if stamp >= after - 1e-9 and zero:
                return stamp
        # all zero already before `after`, and still
        if self.zero_changes and self.zero_changes[-1][1] and self.zero_changes[-1][0] <= after:
            return after
        return None


FAULT_KINDS = ("tracker_dropout", "flow_nan", "flow_negative", "flow_silent", "stuck_valve", "controller_stop",
               "plant_restart")


def schedule(rng, sim_seconds):
    """The seeded list of events: (sim time, kind, parameters)."""
    kinds = ["tracker_dropout", "flow_nan", "flow_negative", "flow_silent", "stuck_valve", "controller_stop",
             "plant_restart", "target", "path"]
    weights = [3, 1, 1, 1, 2, 1, 1, 2, 2]
    events, t = [], 20.0
    while True:
        t += rng.uniform(8.0, 20.0)
        if t > sim_seconds - 10.0:
            return events
        kind = rng.choices(kinds, weights)[0]
        if RESTART_NOT_RECOVERED and not any(e[1] in FAULT_KINDS for e in events) and kind in FAULT_KINDS:
            kind = "plant_restart"
        p = {"jet": rng.randrange(3)}
        if kind == "tracker_dropout":
            p["duration"] = rng.uniform(0.05, 2.0)
        elif kind in ("flow_nan", "flow_negative", "flow_silent"):
            p["duration"] = rng.uniform(0.05, 2.0)
        elif kind == "stuck_valve":
            # at least the detection bound: a valve freed earlier resets the flow-fault integral
            p["duration"], p["value"] = rng.uniform(1.5, 3.0), rng.uniform(0.3, 1.0)
        elif kind == "controller_stop":
            p["duration"] = rng.uniform(0.5, 3.0)
        elif kind == "plant_restart":
            p["duration"] = rng.uniform(0.2, 1.0)  # simulated downtime
        elif kind == "target":
            p["theta"], p["phi"] = rng.uniform(0.1, 0.5), rng.uniform(-math.pi, math.pi)
        elif kind == "path":
            p["type"] = rng.choice(["spiral", "raster", "waypoints"])
            p["theta"], p["phi"] = rng.uniform(0.2, 0.5), rng.uniform(-math.pi, math.pi)
        events.append((t, kind, p))


class Soak:
    def __init__(self, args):
        self.args = args
        self.graph = Graph(args.out, args.seed)
        self.rows = []
        self.failures = []

    # --- waiting on simulated time (wall-time guarded) -------------------------------------------
    def wait_until(self, cond, wall_timeout=60.0):
        end = time.time() + wall_timeout
        while time.time() < end:
            if self.mon.t >= self.next_mem:
                self.sample_memory()
                self.next_mem = self.mon.t + 10.0
            if cond():
                return True
            self.check_alive()
            time.sleep(0.002)
        return False

    def wait_sim(self, t):
        """Until simulated time t; fails only when the clock makes no progress for 30 s of wall time
        (a slow machine is no fault)."""
        while self.mon.t < t:
            t0 = self.mon.t
            if not self.wait_until(lambda: self.mon.t >= t or self.mon.t > t0, 30.0):
                raise RuntimeError("simulated time stuck at %.2f s (waiting for %.2f s)" % (self.mon.t, t))

    def check_alive(self):
        for name in ("plant", "controller"):
            p = self.graph.procs.get(name)
            if p is not None and p.poll() is not None and not getattr(self, "restarting", False):
                raise RuntimeError("%s exited with status %s at %.2f s" % (name, p.returncode, self.mon.t))

    def call(self, service, timeout=30.0):
        """A Trigger service, failing the run when it does not answer within `timeout` wall seconds."""
        rospy.wait_for_service(service, timeout=10.0)
        result = []
        th = threading.Thread(target=lambda: result.append(rospy.ServiceProxy(service, Trigger)()), daemon=True)
        th.start()
        th.join(timeout)
        if not result:
            raise RuntimeError("%s did not answer within %.0f s" % (service, timeout))
        return result[0]

    def ensure_running(self):
        """Running before the next event; an abort since the last event's judgement is a row of its own
        (the restart here would clear it unrecorded)."""
        if self.mon.state() == "aborted":
            self.unplanned("between events")
        if self.mon.state() not in ("running", "finished"):
            self.call("/controller/start")
            if not self.wait_until(lambda: self.mon.state() in ("running", "finished"), 10.0):
                raise RuntimeError("the controller did not start (state %s)" % self.mon.state())

    def sample_memory(self):
        for life in self.graph.plant_lives:
            r = rss_kb(life[1])
            if r is not None and self.graph.procs["plant"].pid == life[1]:
                life[2].append((self.mon.t, r))
        r = rss_kb(self.graph.procs["controller"].pid)
        if r is not None:
            self.controller_rss.append((self.mon.t, r))

    # --- faults -------------------------------------------------------------------------------------
    def inject(self, kind, p):
        n = len(self.mon.applied)
        duration = p["duration"]
        if NOT_RECOVERED and n == 0:
            duration = 1e6
        m = PlantFault(kind=kind, actuator=p["jet"], duration=duration, value=p.get("value", 0.0))
        # A restarted plant connects its fault subscriber and its echo's publisher anew: a fault sent
        # before both are up is lost, or applied unheard.
        if not self.wait_until(lambda: self.fault_pub.get_num_connections() > 0
                               and self.mon.applied_sub.get_num_connections() > 0
                               and self.plant_connected_for_faults(), 10.0):
            raise RuntimeError("the plant's /plant/fault or /plant/fault_applied is not connected")
        self.fault_pub.publish(m)
        if not self.wait_until(lambda: len(self.mon.applied) > n, 10.0):
            raise RuntimeError("the plant did not apply %s" % kind)
        return self.mon.applied[n].header.stamp.to_sec()

    def fault(self, kind, p):
        self.ensure_running()
        self.wait_sim(self.mon.t + 1.0)  # running for a second before the fault
        if self.mon.state() not in ("running", "finished"):
            return self.unplanned("before " + kind)
        row = {"kind": kind, "jet": p["jet"] + 1 if kind not in ("tracker_dropout", "controller_stop",
                                                                  "plant_restart") else None,
               "duration": round(p["duration"], 3)}
        if kind == "controller_stop":
            injected = self.mon.t
            self.call("/controller/stop")
            # The stop is handled between two cycles, while the clock runs on: the jets must be zero
            # by the first cycle after the call returned. This script's reading of the clock lags the
            # plant's by up to two periods (messages in flight): the bound allows for them.
            stop_bound = self.mon.t - injected + 3 * CONTROL_PERIOD
            detect_states = ("idle",)
        elif kind == "plant_restart":
            self.restarting = True
            row["plant_exit"] = self.graph.stop("plant")
            time.sleep(0.2)  # its last jets/state (valves closed) in flight
            injected = max(self.mon.t, self.mon.last_state)  # the old plant's last time
            self.graph.start_plant(injected + p["duration"])
            self.restarting = False
            detect_states = ("aborted",)
        else:
            injected = self.inject(kind, p)
            detect_states = ("aborted",)
        row["injected"] = round(injected, 3)
        # plant_restart: the first cycle after the clock resumes, downtime later
        bound = stop_bound if kind == "controller_stop" else DETECT_BOUND.get(kind, p["duration"] + CONTROL_PERIOD)
        self.wait_until(lambda: self.mon.first_transition(injected, detect_states) is not None
                        or self.mon.t > injected + p["duration"] + bound + 1.0, 120.0)
        det = self.mon.first_transition(injected, detect_states)
        expected = [e.format(j=p["jet"] + 1) for e in EXPECTED[kind]]
        if det:
            # Status and command travel on two topics: wait for the detecting cycle's command too.
            self.wait_until(lambda: self.mon.last_command >= det[0] - 1e-9, 10.0)
            row["detected"] = round(det[0], 3)
            row["reason"] = det[2]
            row["latency"] = round(det[0] - injected, 3)
            zero = self.mon.zero_from(det[0])
            row["jets_zero"] = round(zero, 3) if zero is not None else None
        else:
            row.update(detected=None, reason="(not detected)", latency=None, jets_zero=None)
        row["detect_ok"] = det is not None and row["latency"] <= bound + 1e-6
        row["reason_ok"] = det is not None and any(det[2].startswith(e) for e in expected)
        row["zero_ok"] = row["jets_zero"] is not None and row["jets_zero"] - det[0] <= CONTROL_PERIOD + 1e-6
        if kind == "plant_restart":
            row["zero_ok"] = row["zero_ok"] and row["plant_exit"] == 0
        row["bound"] = round(bound, 3)
        # Restart once the fault is over (a stop: after its pause) and the tip has come to rest, as an
        # operator would (a restart into a still-ringing rod trips the oscillation check at once).
        self.wait_sim(injected + p["duration"] + 0.2)
        if kind == "plant_restart":  # as an operator would: once the controller hears the new plant
            row["heard_plant"] = self.wait_until(self.controller_hears_plant, 30.0)
            if not row["heard_plant"]:
                row["note"] = "the controller did not hear the new plant within 30 s"
        resting = self.wait_until(lambda: self.mon.settled(), 30.0)
        row["settled"] = round(self.mon.t, 3) if resting else None
        if det and row["zero_ok"]:  # and they stayed zero until the restart
            row["zero_ok"] = not any(not zero for stamp, zero in self.mon.zero_changes if det[0] <= stamp <= self.mon.t)
        # The restart comes after the abort it restarts from, whatever the clock says (/clock arrives
        # on a topic of its own and can lag the status that reported the abort): an abort again is a
        # transition recorded after the call.
        started = max(self.mon.t, det[0] if det else self.mon.t)
        seen = len(self.mon.transitions)
        if kind == "plant_restart" and RESTART_NOT_RECOVERED:  # the new plant's tracker goes dark for good
            self.inject("tracker_dropout", {"jet": 0, "duration": 1e6})
        self.call("/controller/start")
        # Judged on controller/status itself, stamped RECOVER_S after the restart: the clock arrives on
        # a topic of its own and can run ahead of the status this script has read (a restart was once
        # judged "not recovered" on a status 4 s of simulated time old).
        ok = self.wait_until(lambda: self.mon.status is not None
                             and self.mon.status.header.stamp.to_sec() >= started + RECOVER_S, 60.0)
        again = next((tr for tr in self.mon.transitions[seen:] if tr[1] == "aborted"), None)
        row["recovered"] = bool(ok and again is None and self.mon.state() in ("running", "finished"))
        if again:
            row["after_restart"] = again[2]
        elif not row["recovered"] and self.mon.status is not None:
            row["after_restart"] = "%s: %s" % (self.mon.state(), self.mon.status.reason)
        row["ok"] = row["detect_ok"] and row["reason_ok"] and row["zero_ok"] and row["recovered"]
        self.rows.append(row)
        if not row["ok"]:
            self.failures.append(row)
        self.say(row)

    def plant_connected_for_faults(self):
        """The running plant has its /plant/fault subscription and its /plant/fault_applied publication
        connected, asked of the plant itself (this side's counts keep a dead plant's connection until
        the next publish on it)."""
        try:
            master = rosgraph.Master("/soak")
            node = xmlrpc.client.ServerProxy(master.lookupNode("/plant"))
            _, _, bus = node.getBusInfo("/soak")
        except Exception:  # not (yet) registered, or busy: ask again
            return False
        # bus info: [connection id, peer, direction, transport, topic, ...]
        links = {(c[2], c[4]) for c in bus if len(c) > 4}
        return ("i", "/plant/fault") in links and ("o", "/plant/fault_applied") in links

    def controller_hears_plant(self):
        """The controller node has received messages from the running plant on each of its sensor
        topics: after a plant restart ROS connects the subscribers anew, and in lockstep the clock
        can run on meanwhile (a start before that aborts again on the old plant's last pose). The
        handshake is judged by the messages counted on the connections to the new plant (bus info's
        'connected' field is true from the connection's creation on)."""
        try:
            master = rosgraph.Master("/soak")
            plant = master.lookupNode("/plant")
            node = xmlrpc.client.ServerProxy(master.lookupNode("/controller"))
            _, _, bus = node.getBusInfo("/soak")
            stats = node.getBusStats("/soak")
        except Exception:  # a node not (yet) registered, or busy: ask again
            return False
        # roscpp answers getBusStats with [publications, subscriptions] alone (no code and message).
        if len(stats) == 3 and isinstance(stats[0], int):
            stats = stats[2]
        # bus info: [connection id, peer, direction, transport, topic, ...];
        # subscriptions' stats: [topic, [[connection id, bytes, messages, drops, connected], ...]]
        from_plant = {c[0] for c in bus if len(c) > 4 and c[2] == "i" and c[1] == plant}
        heard = {topic for topic, conns in (stats[1] if len(stats) > 1 else [])
                 for conn in conns if conn[0] in from_plant and len(conn) > 2 and conn[2] > 0}
        return {"/tracker/tip_pose", "/tracker/base_pose", "/jets/state"} <= heard

    def unplanned(self, when):
        tr = self.mon.transitions[-1] if self.mon.transitions else (self.mon.t, "?", "")
        row = {"kind": "unplanned_abort", "injected": None, "detected": round(tr[0], 3), "reason": tr[2],
               "ok": False, "note": when}
        self.rows.append(row)
        self.failures.append(row)
        self.say(row)
        self.call("/controller/start")

    # --- operator commands -------------------------------------------------------------------------
    def operator(self, kind, p, until):
        self.ensure_running()
        t0 = self.mon.t
        th, ph = p["theta"], p["phi"]
        if kind == "target":
            m = Vector3Stamped()
            m.header.stamp = rospy.Time.from_sec(self.mon.t)
            m.header.frame_id = "base"
            m.vector = Vector3(math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th))
            self.target_pub.publish(m)
            target = (m.vector.x, m.vector.y, m.vector.z)

            def reached():  # the reference is on the target (or on its clipped image)
                st = self.mon.status
                d = st.desired_direction
                cos = max(-1.0, min(1.0, d.x * target[0] + d.y * target[1] + d.z * target[2]))
                return st.header.stamp.to_sec() > t0 and st.source == "direction" and (
                    math.acos(cos) < 0.05 or st.clipped)
            accepted = self.wait_until(reached, 30.0)
        else:
            g = FollowPathGoal(type=p["type"])
            if p["type"] == "spiral":
                g.theta_start, g.theta_end, g.phi_start, g.phi_end, g.duration = 0.0, th, ph, ph + 3.0, 20.0
            elif p["type"] == "raster":
                g.theta_min, g.theta_max, g.rows = 0.1, th, 3
                g.raster_phi_start, g.raster_phi_end, g.speed = ph - 0.6, ph + 0.6, 0.15
            else:
                g.times = [0.0, 5.0, 10.0]
                g.directions = [Vector3(0, 0, 1),
                                Vector3(math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)),
                                Vector3(math.sin(th) * math.cos(ph + 1), math.sin(th) * math.sin(ph + 1), math.cos(th))]
            self.action.send_goal(g)
            accepted = self.wait_until(lambda: self.action.get_state() in (GoalStatus.ACTIVE, GoalStatus.SUCCEEDED)
                                       and self.mon.status.source == "path"
                                       and self.mon.status.header.stamp.to_sec() > t0, 30.0)
        self.wait_sim(min(until, t0 + 15.0))
        abort = self.mon.first_transition(t0, ("aborted",))
        row = {"kind": kind + ("" if kind == "target" else " " + p["type"]), "injected": round(t0, 3),
               "detected": round(abort[0], 3) if abort else None, "reason": abort[2] if abort else "",
               "ok": bool(accepted and abort is None)}
        self.rows.append(row)
        if not row["ok"]:
            self.failures.append(row)
        self.say(row)

    def say(self, row):
        why = [k for k in ("detect_ok", "reason_ok", "zero_ok", "recovered") if k in row and not row[k]]
        extra = "".join("; %s: %s" % (k.replace("_", " "), row[k]) for k in ("after_restart", "note") if row.get(k))
        print("  %8.2f s  %-18s %s  %s%s" % (row.get("injected") or row.get("detected") or 0.0, row["kind"],
                                           "ok  " if row["ok"] else "FAIL", row.get("reason", ""),
                                           "  (failed: %s%s)" % (", ".join(why), extra) if why else ""), flush=True)

    # --- the run ------------------------------------------------------------------------------------
    def run(self):
        a = self.args
        wall0 = time.time()
        self.graph.start_master()
        rospy.init_node("soak", disable_signals=True)
        self.graph.set_params()
        self.mon = Monitor()
        self.fault_pub = rospy.Publisher("/plant/fault", PlantFault, queue_size=10)
        self.target_pub = rospy.Publisher("/controller/target_direction", Vector3Stamped, queue_size=10)
        self.action = actionlib.SimpleActionClient("/controller/follow_path", FollowPathAction)
        self.controller_rss = []
        self.next_mem = 0.0
        self.graph.start_plant(0.0)
        self.graph.start_controller()
        if not self.action.wait_for_server(rospy.Duration(30.0)):
            raise RuntimeError("controller/follow_path never came up")
        self.wait_until(lambda: self.mon.state() == "running", 60.0)
        events = schedule(random.Random(a.seed), a.sim_seconds)
        print("soak: %.0f s simulated, seed %d, %d events" % (a.sim_seconds, a.seed, len(events)), flush=True)
        for i, (t, kind, p) in enumerate(events):
            while self.mon.t < t:
                self.wait_sim(min(t, self.mon.t + 1.0))
                if self.mon.state() == "aborted":
                    self.unplanned("between events")
            until = events[i + 1][0] if i + 1 < len(events) else a.sim_seconds
            if kind in ("target", "path"):
                self.operator(kind, p, until)
            else:
                self.fault(kind, p)
        self.wait_sim(a.sim_seconds)
        self.sample_memory()
        return time.time() - wall0

    def memory(self):
        """Growth after warm-up, (last - first) / first over the samples WARMUP_S or more after the
        process started: the controller over the whole run, the plant over its longest life."""
        def after_warmup(start, samples):
            return [r for t, r in samples if t >= start + WARMUP_S]

        def growth(s):
            return (s[-1] - s[0]) / s[0] if len(s) >= 2 else None
        lives = [after_warmup(start, samples) for start, _, samples in self.graph.plant_lives]
        plant = max(lives, key=len)
        controller = after_warmup(0.0, self.controller_rss)
        return {"controller": growth(controller), "plant": growth(plant),
                "controller_kb": controller[-1] if controller else None, "plant_kb": plant[-1] if plant else None}


def table(rows):
    def f(v):
        return "—" if v is None else ("%.3f" % v if isinstance(v, float) else str(v))
    out = ["| # | event | jet | injected [s] | detected [s] | latency [s] (bound) | reason | jets zero [s] | recovered | verdict |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for i, r in enumerate(rows, 1):
        lat = "%s (≤ %s)" % (f(r.get("latency")), f(r.get("bound"))) if "bound" in r else "—"
        rec = "—" if "recovered" not in r else ("yes" if r["recovered"] else "NO" + (
            " (%s)" % r["after_restart"].replace("|", "/") if r.get("after_restart") else ""))
        out.append("| %d | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            i, r["kind"], f(r.get("jet")), f(r.get("injected")), f(r.get("detected")), lat,
            (r.get("reason") or "").replace("|", "/"), f(r.get("jets_zero")), rec, "ok" if r["ok"] else "FAIL"))
    return "\n".join(out)


def summary_table(rows):
    """Per kind of event: count, passed, detection latency median and max, and its bound."""
    kinds = []
    for r in rows:
        if r["kind"] not in kinds:
            kinds.append(r["kind"])
    out = ["| event | count | passed | latency median [s] | latency max [s] | bound [s] |", "|---|---|---|---|---|---|"]
    kinds_note = []
    for k in kinds:
        rs = [r for r in rows if r["kind"] == k]
        if k == "stuck_valve":  # which check stopped the jets
            for check in ("flow", "oscillation"):
                n = sum(1 for r in rs if (r.get("reason") or "").startswith(check))
                kinds_note.append("%s: %d by the %s check" % (k, n, check))
        lat = sorted(r["latency"] for r in rs if r.get("latency") is not None)
        bounds = [r["bound"] for r in rs if "bound" in r]
        med = "%.3f" % lat[len(lat) // 2] if lat else "—"
        mx = "%.3f" % lat[-1] if lat else "—"
        bd = ("%.3f" % min(bounds) if min(bounds) == max(bounds) else "%.3f–%.3f" % (min(bounds), max(bounds))) if bounds else "—"
        out.append("| %s | %d | %d | %s | %s | %s |" % (k, len(rs), sum(r["ok"] for r in rs), med, mx, bd))
    return "\n".join(out) + ("\n\n" + "; ".join(kinds_note) + "." if kinds_note else "")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sim-seconds", type=float, default=3600.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    soak = Soak(a)
    error = None
    wall = None
    try:
        wall = soak.run()
    except Exception as e:  # a node that died, a stuck clock: the run fails with the reason
        error = str(e)
    mem = soak.memory() if soak.graph.plant_lives else {}
    alive = {n: soak.graph.procs[n].poll() is None for n in ("plant", "controller") if n in soak.graph.procs}
    exits = {}
    soak.graph.procs.get("controller") and exits.update(controller=soak.graph.stop("controller"))
    soak.graph.procs.get("plant") and exits.update(plant=soak.graph.stop("plant"))
    soak.graph.shutdown()
    faults = [r for r in soak.rows if r["kind"] not in ("target",) and not r["kind"].startswith("path")]
    ops = [r for r in soak.rows if r not in faults]
    mem_ok = all(g is not None and g <= 0.05 for g in (mem.get("controller"), mem.get("plant")))
    ok = error is None and not soak.failures and mem_ok and all(alive.values()) and all(v == 0 for v in exits.values())
    summary = {
        "sim_seconds": a.sim_seconds, "seed": a.seed, "wall_seconds": wall, "error": error,
        "faults": len(faults), "faults_ok": sum(r["ok"] for r in faults),
        "operator_commands": len(ops), "operator_ok": sum(r["ok"] for r in ops),
        "memory_growth": mem, "memory_ok": mem_ok, "alive_at_end": alive, "exit_status_on_sigterm": exits,
        "ok": ok, "rows": soak.rows,
    }
    with open(os.path.join(a.out, "soak.json"), "w") as f:
        json.dump(summary, f, indent=1)
    md = table(soak.rows)
    by_kind = summary_table(soak.rows)
    with open(os.path.join(a.out, "soak_table.md"), "w") as f:
        f.write(by_kind + "\n\n" + md + "\n")
    print(md)
    print()
    print(by_kind)
    def pct(v):
        return "n/a" if v is None else "%+.2f %%" % (100 * v)
    print("soak: %s simulated s, seed %d, wall %s s; faults %d/%d ok, operator commands %d/%d ok; "
          "RSS growth after %d s: controller %s, plant %s; nodes alive %s, SIGTERM exits %s%s"
          % (a.sim_seconds, a.seed, "%.0f" % wall if wall else "?", summary["faults_ok"], len(faults),
             summary["operator_ok"], len(ops), WARMUP_S, pct(mem.get("controller")), pct(mem.get("plant")), alive,
             exits, "" if error is None else "; ERROR: " + error), flush=True)
    print("soak: %s" % ("PASSED" if ok else "FAILED"))
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
