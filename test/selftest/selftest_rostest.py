#!/usr/bin/python3
"""The self-test's rostest probe (selftest_rostest.test): the probe node's selftest/alive counter must arrive and
increase; HYDROJET_SELFTEST_INJECT=rostest_failure makes the test expect what it cannot see."""
import os
import sys
import time
import unittest

import rospy
import rostest
from std_msgs.msg import UInt32


class SelfTestProbe(unittest.TestCase):
    def test_probe_node_is_alive(self):
        counts = []
        rospy.Subscriber("selftest/alive", UInt32, lambda m: counts.append(m.data), queue_size=100)
        until = time.monotonic() + 30.0
        while len(counts) < 3 and time.monotonic() < until:
            time.sleep(0.05)
        self.assertGreaterEqual(len(counts), 3, "selftest/alive: %d messages in 30 s" % len(counts))
        self.assertLess(counts[0], counts[-1])
        if os.environ.get("HYDROJET_SELFTEST_INJECT") == "rostest_failure":
            self.assertEqual(counts[-1], -1, "injected failure")


if __name__ == "__main__":
    rospy.init_node("selftest_probe_test", anonymous=True)
    rostest.rosrun("hydrojet_control", "selftest_rostest", SelfTestProbe, sys.argv)
