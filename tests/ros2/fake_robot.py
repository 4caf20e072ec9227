"""A ROS 2 robot stand-in for tests/ros2, run as its own process with rclpy: publishes nav_msgs/msg/Odometry
at ~20 Hz (reliable) and sensor_msgs/msg/LaserScan at ~10 Hz (sensor-data QoS, best effort, as lidar
drivers do), integrates geometry_msgs/msg/Twist (or TwistStamped) from cmd_vel as a unicycle, and writes
its state to a JSON file the test reads.

Owns: a robot's topics as a ROS 2 driver (or Gazebo) offers them, and the base's own safety stop: a
cmd_vel older than --cmd-timeout s (0.5, as a TurtleBot 4's base and diff_drive_controller's
cmd_vel_timeout) stops the wheels. Must not know: rescuemesh (it imports nothing of it), the tests.
The odom frame is the map frame: it starts at --start.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import time

import rclpy
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.qos import qos_profile_sensor_data
from rosgraph_msgs.msg import Clock
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import LaserScan

PHYSICS_HZ, ODOM_HZ, SCAN_HZ, STATE_HZ = 100, 20, 10, 10
BEAMS = 360


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--name", required=True)
    parser.add_argument("--start", default="0,0,0", help="x,y,yaw in m, m, rad")
    parser.add_argument("--state", required=True, help="JSON file to write the state to")
    parser.add_argument("--lifetime", type=float, default=300.0, help="exit after this many s whatever happens")
    parser.add_argument("--cmd-timeout", type=float, default=0.5, help="stop when cmd_vel is older than this, s")
    parser.add_argument("--twist-stamped", action="store_true", help="take TwistStamped on cmd_vel")
    parser.add_argument("--odom-topic", default=None, help="default /NAME/odom")
    parser.add_argument("--clock-rate", type=float, default=None,
                        help="publish /clock (simulated time from 1000 s, this many simulated s per wall s), as Gazebo")
    args = parser.parse_args()
    x, y, yaw = (float(v) for v in args.start.split(","))
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(f"fake_{args.name}")
    odom_pub = node.create_publisher(Odometry, args.odom_topic or f"/{args.name}/odom", 10)
    scan_pub = node.create_publisher(LaserScan, f"/{args.name}/scan", qos_profile_sensor_data)
    cmd = {"v": 0.0, "w": 0.0, "count": 0, "at": None, "stamped": 0, "longest_gap_s": 0.0}

    def on_cmd(msg) -> None:
        twist = msg.twist if args.twist_stamped else msg
        now = time.monotonic()
        if cmd["at"] is not None:  # the longest silence between two cmd_vel, for a failing test's message
            cmd["longest_gap_s"] = max(cmd["longest_gap_s"], now - cmd["at"])
        cmd.update(v=twist.linear.x, w=twist.angular.z, count=cmd["count"] + 1, at=now,
                   stamped=cmd["stamped"] + args.twist_stamped)

    node.create_subscription(TwistStamped if args.twist_stamped else Twist, f"/{args.name}/cmd_vel", on_cmd, 10)
    clock_pub = node.create_publisher(Clock, "/clock", 10) if args.clock_rate else None
    started = last = time.monotonic()
    tick = 0
    path_length = 0.0
    stop_cause = None  # how the wheels last came to rest after moving: "zero_twist" or "timeout"
    timeouts = 0
    while not stop and rclpy.ok() and time.monotonic() - started < args.lifetime:
        rclpy.spin_once(node, timeout_sec=max(0.0, last + 1.0 / PHYSICS_HZ - time.monotonic()))
        now = time.monotonic()
        if now - last < 1.0 / PHYSICS_HZ:
            continue
        dt, last = now - last, now
        silent = cmd["at"] is None or now - cmd["at"] > args.cmd_timeout
        if silent and (cmd["v"] or cmd["w"]):
            cmd.update(v=0.0, w=0.0)
            timeouts += 1
            stop_cause = "timeout"
        v, w = cmd["v"], cmd["w"]
        if not silent and v == 0.0 and w == 0.0 and stop_cause is None and path_length > 0.0:
            stop_cause = "zero_twist"
        if v or w:
            stop_cause = None
        x += v * math.cos(yaw) * dt
        y += v * math.sin(yaw) * dt
        yaw = (yaw + w * dt + math.pi) % (2 * math.pi) - math.pi
        path_length += abs(v) * dt
        tick += 1
        stamp = node.get_clock().now().to_msg()
        if clock_pub is not None:  # simulated time: the physics still steps on the wall clock, time runs slower
            sim_ns = int((1000.0 + (now - started) * args.clock_rate) * 1e9)
            stamp.sec, stamp.nanosec = sim_ns // 1_000_000_000, sim_ns % 1_000_000_000
            clock_pub.publish(Clock(clock=stamp))
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
                     "stop_cause": stop_cause, "timeouts": timeouts, "stamped": cmd["stamped"],
                     "longest_cmd_gap_s": cmd["longest_gap_s"]}
            tmp = f"{args.state}.tmp"
            with open(tmp, "w") as f:
                json.dump(state, f)
            os.replace(tmp, args.state)
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
