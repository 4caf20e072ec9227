"""A robot process whose link or ROS node hangs while closing still ends (the body was halted)."""

import subprocess
import sys
import time


def test_a_hung_close_ends_the_process_with_one_line():
    # this used to leave a ROS 2 robot running after Ctrl-C when rclpy's shutdown hung (seen once in
    # nine runs of test_ctrl_c_of_the_robot_process_sends_a_zero_twist)
    code = ("import sys, time\n"
            "from rescuemesh.runtime.onboard import linked_robot\n"
            "linked_robot.CLOSE_WATCHDOG_S = 0.3\n"
            "linked_robot._close_watchdog('robot_1', sys.stderr)\n"
            "time.sleep(30)\n")
    started = time.monotonic()
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=20)
    assert result.returncode == 1 and time.monotonic() - started < 15
    assert "robot_1: closing the link and the ROS node took over 0.3 s: exiting now" in result.stderr
    assert "Traceback" not in result.stderr


def test_a_close_in_time_cancels_the_watchdog():
    code = ("import sys, time\n"
            "from rescuemesh.runtime.onboard import linked_robot\n"
            "linked_robot.CLOSE_WATCHDOG_S = 0.3\n"
            "linked_robot._close_watchdog('robot_1', sys.stderr).cancel()\n"
            "time.sleep(0.8)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=20)
    assert result.returncode == 0 and result.stderr == ""
