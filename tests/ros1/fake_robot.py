"""A ROS 1 robot stand-in for tests/ros1, run as its own process with Debian's rospy: publishes
nav_msgs/Odometry at ~20 Hz and sensor_msgs/LaserScan at ~10 Hz, integrates geometry_msgs/Twist
from cmd_vel as a unicycle, and writes its state to a JSON file the test reads.

Owns: a robot's topics as a ROS driver (or Gazebo) offers them. Must not know: rescuemesh (it
imports nothing of it), the tests' expectations. The odom frame is the map frame: it starts at
--start. A cmd_vel is held until the next one (no timeout), so a brain that stops commanding zero
shows as a robot that keeps moving.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import time

import rospy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

PHYSICS_HZ, ODOM_HZ, SCAN_HZ, STATE_HZ = 100, 20, 10, 10
BEAMS = 360


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--name", required=True)
    parser.add_argument("--start", default="0,0,0", help="x,y,yaw in m, m, rad")
    parser.add_argument("--state", required=True, help="JSON file to write the state to")
    parser.add_argument("--lifetime", type=float, default=300.0, help="exit after this many s whatever happens")
    args = parser.parse_args()
    x, y, yaw = (float(v) for v in args.start.split(","))
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    rospy.init_node(f"fake_{args.name}", disable_signals=True)
    odom_pub = rospy.Publisher(f"/{args.name}/odom", Odometry, queue_size=10)
    scan_pub = rospy.Publisher(f"/{args.name}/scan", LaserScan, queue_size=10)
    cmd = {"v": 0.0, "w": 0.0, "count": 0, "at": None, "longest_gap_s": 0.0}

    def on_cmd(msg: Twist) -> None:
        now = time.monotonic()
        if cmd["at"] is not None:  # the longest silence between two cmd_vel, for a failing test's message
            cmd["longest_gap_s"] = max(cmd["longest_gap_s"], now - cmd["at"])
        cmd.update(v=msg.linear.x, w=msg.angular.z, count=cmd["count"] + 1, at=now)

    rospy.Subscriber(f"/{args.name}/cmd_vel", Twist, on_cmd, queue_size=10)
    started = last = time.monotonic()
    tick = 0
    path_length = 0.0
    while not stop and not rospy.is_shutdown() and time.monotonic() - started < args.lifetime:
        time.sleep(max(0.0, last + 1.0 / PHYSICS_HZ - time.monotonic()))
        now = time.monotonic()
        dt, last = now - last, now
        v, w = cmd["v"], cmd["w"]
        x += v * math.cos(yaw) * dt
        y += v * math.sin(yaw) * dt
        yaw = (yaw + w * dt + math.pi) % (2 * math.pi) - math.pi
        path_length += abs(v) * dt
        tick += 1
        stamp = rospy.Time.now()
        if tick % (PHYSICS_HZ // ODOM_HZ) == 0:
            odom = Odometry()
            odom.header.stamp, odom.header.frame_id, odom.child_frame_id = stamp, "odom", "base_footprint"
            odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
            odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            odom.twist.twist.linear.x, odom.twist.twist.angular.z = v, w
            odom_pub.publish(odom)
        if tick % (PHYSICS_HZ // SCAN_HZ) == 0:
            scan = LaserScan()
            scan.header.stamp, scan.header.frame_id = stamp, "base_scan"
            scan.angle_min, scan.angle_max = -math.pi, math.pi - 2 * math.pi / BEAMS
            scan.angle_increment = 2 * math.pi / BEAMS
            scan.range_min, scan.range_max = 0.12, 3.5
            scan.ranges = [float("inf")] * BEAMS  # an open floor: no return
            scan_pub.publish(scan)
        if tick % (PHYSICS_HZ // STATE_HZ) == 0:
            state = {"x": x, "y": y, "yaw": yaw, "v": v, "w": w, "cmd_count": cmd["count"],
                     "cmd_age_s": None if cmd["at"] is None else now - cmd["at"], "path_length": path_length,
                     "longest_cmd_gap_s": cmd["longest_gap_s"]}
            tmp = f"{args.state}.tmp"
            with open(tmp, "w") as f:
                json.dump(state, f)
            os.replace(tmp, args.state)
    rospy.signal_shutdown("done")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
