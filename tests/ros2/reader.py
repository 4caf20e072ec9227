"""A ROS 2 node that reads the paper's topics of one robot as `ros2 topic echo` would and prints each
message as YAML (message_to_yaml, what `ros2 topic echo` prints), separated by `---`; for tests/ros2.

Owns: subscribing to rescuemesh_msgs/msg/Command and geometry_msgs/msg/PoseStamped topics. Must not know:
rescuemesh (it imports only the generated messages), the tests' expectations.
`python reader.py --lifetime S TOPIC:TYPE ...` with TYPE Command or PoseStamped.
"""

import argparse
import signal
import sys
import time

import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.signals import SignalHandlerOptions
from rescuemesh_msgs.msg import Command

try:
    from rosidl_runtime_py import message_to_yaml
except ImportError:  # not among the wheels: the same YAML by hand
    def message_to_yaml(msg, indent: str = "") -> str:
        lines = []
        for name in msg.get_fields_and_field_types():
            value = getattr(msg, name)
            if hasattr(value, "get_fields_and_field_types"):
                lines.append(f"{indent}{name}:\n{message_to_yaml(value, indent + '  ')}")
            elif isinstance(value, str):
                lines.append(f"{indent}{name}: {value!r}" if value == "" else f"{indent}{name}: {value}")
            else:
                lines.append(f"{indent}{name}: {value}")
        return "\n".join(lines) + ("\n" if not indent else "")

TYPES = {"Command": Command, "PoseStamped": PoseStamped}


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--lifetime", type=float, default=120.0)
    parser.add_argument("topics", nargs="+", help="TOPIC:TYPE")
    args = parser.parse_args()
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("paper_reader")
    topics = [spec.rsplit(":", 1) for spec in args.topics]
    for topic, kind in topics:
        # transient local: what the robot published before this reader was discovered comes too
        qos = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL if kind == "Command" else
                         DurabilityPolicy.VOLATILE)
        node.create_subscription(TYPES[kind], topic,
                                 lambda msg, topic=topic: print(f"# {topic}\n{message_to_yaml(msg)}---", flush=True),
                                 qos)
    print("reader: subscribed", flush=True)
    started = time.monotonic()
    seen = set()
    while not stop and time.monotonic() - started < args.lifetime:
        rclpy.spin_once(node, timeout_sec=0.1)
        for topic, _ in topics:
            if topic not in seen and node.count_publishers(topic) > 0:
                seen.add(topic)
                print(f"reader: publisher on {topic}", flush=True)
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
