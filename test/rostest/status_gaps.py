#!/usr/bin/python3
"""A listener of its own for hostile_inputs.test: the wall-clock gaps between controller/status messages,
measured in a process that does nothing else (the test's own process builds 5000-point goals and
would add its own pauses to what it measured).

Subscribes controller/status; after a message on status_gaps/reset (std_msgs/Empty) it publishes on
status_gaps/report, 5 times a second, Float64MultiArray [resets seen, longest gap since the last reset
[s], statuses since the last reset]."""
import threading
import time

import rospy
from hydrojet_control.msg import ControllerStatus
from std_msgs.msg import Empty, Float64MultiArray


class Gaps:
    def __init__(self):
        self.lock = threading.Lock()
        self.resets, self.longest, self.count, self.last = 0, 0.0, 0, None
        self.report = rospy.Publisher("status_gaps/report", Float64MultiArray, queue_size=10)
        rospy.Subscriber("status_gaps/reset", Empty, self.on_reset, queue_size=10)
        rospy.Subscriber("controller/status", ControllerStatus, self.on_status, queue_size=1000)

    def on_reset(self, _):
        with self.lock:
            self.resets += 1
            self.longest, self.count, self.last = 0.0, 0, None

    def on_status(self, _):
        now = time.monotonic()
        with self.lock:
            if self.resets == 0:
                return
            if self.last is not None:
                self.longest = max(self.longest, now - self.last)
            self.last = now
            self.count += 1

    def publish(self):
        with self.lock:
            data = [float(self.resets), self.longest, float(self.count)]
        self.report.publish(Float64MultiArray(data=data))


if __name__ == "__main__":
    rospy.init_node("status_gaps")
    gaps = Gaps()
    while not rospy.is_shutdown():
        gaps.publish()
        time.sleep(0.2)  # wall time: the report does not wait on the simulated clock
