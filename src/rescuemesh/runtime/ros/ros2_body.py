"""A Body over ROS 2 topics, so the same brain, navigation and protocol drive any ROS 2 robot or a Gazebo
TurtleBot: nav_msgs/msg/Odometry and sensor_msgs/msg/LaserScan in, geometry_msgs/msg/Twist (or
TwistStamped) out; the ROS 2 node the robot process is, with ROS's own command-line conventions.

Owns: Ros2Node (rclpy's context, one node in the robot's namespace, and an executor spinning on its own
threads; `--ros-args` remapping, parameters and `use_sim_time` come through rclpy), Ros2Topics (the
topic names: relative names resolve in the node's namespace, `/ROBOT` by default), Ros2Body (the latest
odometry, localised pose and scan under a lock; set_velocity publishes). Must not know: the brain, the
protocol, the mesh, the loop (the runtime owns time: `now()` is the node's ROS time since the body was
made, simulated time under `use_sim_time`). rclpy comes from ROS 2, not from PyPI: imported on first use.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace

from rescuemesh.geometry import Pose2D
from rescuemesh.runtime.ros.ros_body_common import (
    ODOMETRY_WAIT_S,
    TURTLEBOT2_MAX_ANGULAR_SPEED,
    TURTLEBOT2_MAX_LINEAR_SPEED,
    TURTLEBOT2_RADIUS,
    RosBodyState,
    import_or_explain,
)

ROS2_INSTALL_HINT = ("rclpy comes with ROS 2: install ROS 2 (Humble, Jazzy or Kilted: apt-get install "
                     "ros-DISTRO-ros-base), `source /opt/ros/DISTRO/setup.bash`, and run rescuemesh from a virtualenv "
                     "made with --system-site-packages (docs/ros2.md)")
#: Threads for the callbacks that block (the paper's action: one per command awaited at once).
COMMAND_THREADS = 4


class Ros2Unavailable(ImportError):
    """rclpy or the ROS 2 message packages cannot be imported: ROS 2 is not installed or not sourced."""


def import_rclpy():
    """rclpy, or Ros2Unavailable naming what to install."""
    return import_or_explain("rclpy", Ros2Unavailable, ROS2_INSTALL_HINT)


def stamp_seconds(stamp) -> float:
    """A builtin_interfaces/msg/Time in s."""
    return stamp.sec + stamp.nanosec * 1e-9


class Ros2Node:
    """This process as a ROS 2 node `rescuemesh` in namespace `namespace` (default `/ROBOT`), with its own
    rclpy context (rclpy's signal handlers left out: the runtime decides how it stops) and a
    single-threaded executor spinning in a daemon thread. `ros_args`: what follows `--ros-args` on a ROS 2
    command line (`-r odom:=/odom`, `-r __ns:=/tb4`, `-p use_sim_time:=true`, `--log-level debug` ...).

    Callbacks that block (the paper's action, which waits for its command's end) go on a second node,
    `rescuemesh_commands` in the same namespace (`commands_node()`), spun by a multi-threaded executor of
    its own. rclpy's multi-threaded executor, spinning the robot's sensor subscriptions, took about 65 %
    of a core on its own and held the interpreter so long that the robot's control loop stalled for up
    to 2.6 s while driving (docs/ros2.md); the single-threaded one takes about 3 %."""

    def __init__(self, robot: str, *, namespace: str | None = None, ros_args: list[str] | None = None,
                 node_name: str = "rescuemesh") -> None:
        rclpy = import_rclpy()
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.rclpy = rclpy
        self.robot, self.node_name = robot, node_name
        self.context = rclpy.Context()
        args = ["rescuemesh", "--ros-args", *ros_args] if ros_args else ["rescuemesh"]
        rclpy.init(args=args, context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.namespace = namespace if namespace is not None else f"/{robot}"
        self.node = rclpy.create_node(node_name, namespace=self.namespace, context=self.context,
                                      automatically_declare_parameters_from_overrides=True)
        self.logger = self.node.get_logger()
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._commands = None  # (node, executor, thread) once commands_node() is asked for
        self._thread = self._spin_in_thread(self.executor, f"rclpy-{robot}")

    def _spin_in_thread(self, executor, name: str) -> threading.Thread:
        def spin() -> None:
            try:
                executor.spin()
            except Exception:  # the context was shut down under it: the process is closing
                pass

        thread = threading.Thread(target=spin, name=name, daemon=True)
        thread.start()
        return thread

    def commands_node(self):
        """The node for callbacks that block (made on first use): `NODE_commands`, same namespace,
        its callbacks on COMMAND_THREADS threads of their own."""
        if self._commands is None:
            from rclpy.executors import MultiThreadedExecutor

            node = self.rclpy.create_node(f"{self.node_name}_commands", namespace=self.namespace,
                                          context=self.context,  # `-p use_sim_time:=true` reaches its clock too
                                          automatically_declare_parameters_from_overrides=True)
            executor = MultiThreadedExecutor(num_threads=COMMAND_THREADS, context=self.context)
            executor.add_node(node)
            self._commands = (node, executor, self._spin_in_thread(executor, f"rclpy-{self.robot}-commands"))
        return self._commands[0]

    def parameter(self, name: str, default):
        """The node's parameter `name` (from `--ros-args -p name:=value`), declared with `default`."""
        if not self.node.has_parameter(name):
            self.node.declare_parameter(name, default)
        value = self.node.get_parameter(name).value
        return default if value is None else value

    def seconds(self) -> float:
        """The node's clock in s (ROS time: /clock under use_sim_time)."""
        return self.node.get_clock().now().nanoseconds * 1e-9

    def resolve(self, topic: str) -> str:
        """`topic` as the node resolves it (namespace and remapping applied)."""
        return self.node.resolve_topic_name(topic)

    def close(self) -> None:
        """Stop the executors, destroy the nodes, shut the context down. Safe to call twice."""
        if not self.context.ok():
            return
        spun = [(self.node, self.executor, self._thread)] + ([self._commands] if self._commands else [])
        for node, executor, _ in spun:
            executor.shutdown(timeout_sec=1.0)
            node.destroy_node()
        self.rclpy.shutdown(context=self.context)
        for _, _, thread in spun:
            thread.join(timeout=2.0)


@dataclass(frozen=True)
class Ros2Topics:
    """ROS 2 topic names of one robot. Relative names (the defaults) resolve in the node's namespace
    (`/robot_2/odom` for robot_2), and `--ros-args -r odom:=/odom` remaps them as in any ROS 2 node.
    `pose`: a geometry_msgs/msg/PoseWithCovarianceStamped topic with the localised pose in the map frame
    (AMCL's `amcl_pose`); None takes the odometry's pose as the map pose (the odom frame is the map frame).
    `twist_stamped`: publish geometry_msgs/msg/TwistStamped (ros2_control's diff_drive_controller since
    Jazzy, the TurtleBot 4 on Jazzy) instead of Twist."""

    odom: str = "odom"
    scan: str = "scan"
    cmd_vel: str = "cmd_vel"
    pose: str | None = None
    twist_stamped: bool = False


class Ros2Body(RosBodyState):
    """A ground robot reached through ROS 2 topics on `ros` (a Ros2Node).

    Odometry: reliable, depth 10 (what robot drivers publish); the scan: sensor-data QoS (best effort,
    which hears best-effort and reliable publishers alike); cmd_vel: reliable, depth 10. `laser_offset`:
    the laser's pose in the base frame (no TF lookup; the node parameters `laser_x`, `laser_y`,
    `laser_yaw` override it). Construction waits up to `odometry_wait_s` s for the first Odometry and
    raises NoOdometryError naming the topic when none comes.
    """

    def __init__(self, ros: Ros2Node, name: str, topics: Ros2Topics | None = None, *,
                 max_linear_speed: float = TURTLEBOT2_MAX_LINEAR_SPEED,
                 max_angular_speed: float = TURTLEBOT2_MAX_ANGULAR_SPEED, radius: float = TURTLEBOT2_RADIUS,
                 laser_offset: Pose2D = Pose2D(0.0, 0.0, 0.0), odometry_wait_s: float = ODOMETRY_WAIT_S,
                 base_frame: str = "base_link") -> None:
        try:
            from geometry_msgs.msg import PoseWithCovarianceStamped, Twist, TwistStamped
            from nav_msgs.msg import Odometry
            from rclpy.qos import qos_profile_sensor_data
            from sensor_msgs.msg import LaserScan as ScanMsg
        except ImportError as exc:
            raise Ros2Unavailable(f"cannot import the ROS 2 message packages ({exc}). {ROS2_INSTALL_HINT}") from exc
        self.ros, self.name = ros, name
        topics = topics or Ros2Topics()
        topics = replace(topics, twist_stamped=bool(ros.parameter("twist_stamped", topics.twist_stamped)))
        self.topics = topics
        self.max_linear_speed = float(ros.parameter("max_linear_speed", float(max_linear_speed)))
        self.max_angular_speed = float(ros.parameter("max_angular_speed", float(max_angular_speed)))
        self.radius = radius
        self.laser_offset = Pose2D(float(ros.parameter("laser_x", float(laser_offset.x))),
                                   float(ros.parameter("laser_y", float(laser_offset.y))),
                                   float(ros.parameter("laser_yaw", float(laser_offset.yaw))))
        self.base_frame = base_frame
        self._twist = TwistStamped if topics.twist_stamped else Twist
        self._init_state(ros.seconds())
        node = ros.node
        self._cmd = node.create_publisher(self._twist, topics.cmd_vel, 10)
        self._subscriptions = [node.create_subscription(Odometry, topics.odom, self._on_odom, 10),
                               node.create_subscription(ScanMsg, topics.scan, self._on_scan, qos_profile_sensor_data)]
        if topics.pose is not None:
            self._subscriptions.append(node.create_subscription(PoseWithCovarianceStamped, topics.pose,
                                                                self._on_pose, 10))
        #: the resolved names (namespace and remapping applied), for messages and the report
        self.resolved = {"odom": ros.resolve(topics.odom), "scan": ros.resolve(topics.scan),
                         "cmd_vel": ros.resolve(topics.cmd_vel),
                         "pose": ros.resolve(topics.pose) if topics.pose is not None else None}
        self.time_origin = ros.seconds()
        self.wait_for_odometry(odometry_wait_s)
        self.time_origin = ros.seconds()  # under use_sim_time the clock starts with the first /clock

    # ----- what the shared callbacks ask (the executor's threads) -----

    def _scan_stamp(self, msg) -> float:
        stamp = stamp_seconds(msg.header.stamp)
        return (stamp if stamp > 0.0 else self.ros.seconds()) - self.time_origin

    def _log_warning(self, text: str) -> None:
        self.ros.node.get_logger().warning(text)

    def _topic(self, which: str) -> str:
        return self.resolved[which]

    # ----- the Body interface (the runtime's thread) -----

    odometry_type = "nav_msgs/msg/Odometry"

    def _ros_seconds(self) -> float:
        return self.ros.seconds()

    def _ros_running(self) -> bool:
        return self.ros.context.ok()

    def _no_odometry_hint(self) -> str:
        return ("is the robot (or Gazebo) running, on this ROS_DOMAIN_ID and RMW_IMPLEMENTATION, is the topic right "
                "(--odom-topic, or --ros-args -r odom:=...)?")

    def set_velocity(self, linear: float, angular: float) -> None:
        linear, angular = self._clamped(linear, angular)
        msg = self._twist()
        twist = msg.twist if self.topics.twist_stamped else msg
        if self.topics.twist_stamped:
            msg.header.stamp = self.ros.node.get_clock().now().to_msg()
            msg.header.frame_id = self.base_frame
        twist.linear.x, twist.angular.z = linear, angular
        if self.ros.context.ok():
            self._cmd.publish(msg)

    def close(self, ack_timeout_s: float = 1.0) -> None:
        """Stop the wheels (a zero Twist, waited for until the subscribers acknowledged it or
        `ack_timeout_s` passed) and leave the topics."""
        if not self.ros.context.ok():
            return
        try:
            self.set_velocity(0.0, 0.0)
            self._cmd.wait_for_all_acked(self.ros.rclpy.duration.Duration(seconds=ack_timeout_s))
        finally:
            for subscription in self._subscriptions:
                self.ros.node.destroy_subscription(subscription)
            self.ros.node.destroy_publisher(self._cmd)
