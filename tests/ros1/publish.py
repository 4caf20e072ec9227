"""A ROS node that asks a rescuemesh robot for commands, for tests/ros1: publishes rescuemesh_msgs/Command
requests on a robot's input topic, with Debian's rospy and the generated messages on PYTHONPATH.

Owns: turning a JSON list of requests ({"type": ..., "receiver": ..., "frame": [x, y, yaw], any other
Command field}) into messages, 0.2 s apart, once the robot listens (10 s at most, else exit 3).
Must not know: rescuemesh (it imports none of it: any ROS node could do this).
"""

from __future__ import annotations

import json
import math
import sys
import time

import rospy
from rescuemesh_msgs.msg import Command


def to_msg(request: dict) -> Command:
    msg = Command()
    for field, value in request.items():
        if field == "frame":
            x, y, yaw = value
            msg.frame.position.x, msg.frame.position.y = x, y
            msg.frame.orientation.z, msg.frame.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        elif field == "frame_id":
            msg.header.frame_id = value
        else:
            setattr(msg, field, value)
    return msg


def main() -> int:
    topic, requests = sys.argv[1], json.loads(sys.argv[2])
    rospy.init_node("test_publisher", anonymous=True, disable_signals=True)
    publisher = rospy.Publisher(topic, Command, queue_size=len(requests) + 1)
    deadline = time.monotonic() + 10.0
    while publisher.get_num_connections() == 0:
        if time.monotonic() > deadline:
            print(f"no subscriber on {topic}", file=sys.stderr)
            return 3
        time.sleep(0.05)
    for request in requests:
        publisher.publish(to_msg(request))
        time.sleep(0.2)
    time.sleep(0.5)
    rospy.signal_shutdown("published")
    return 0


if __name__ == "__main__":
    sys.exit(main())
