"""A ROS 2 node that makes a robot send a command through its SendCommand action
(/ROBOT/comm_protocol/send_command) and prints each feedback and the result as JSON lines; for tests/ros2.

Owns: an rclpy ActionClient. Must not know: rescuemesh (it imports only the generated messages).
`python commander.py ROBOT '{"type": "COMMAND_GOTO", "receiver": "robot_2", "x": 1.0, "y": 0.0}'`;
`--copies N` sends N such goals at once and prints each one's result (feedback is not printed then).
"""

import argparse
import json
import sys
import time

import rclpy
from rclpy.action import ActionClient
from rescuemesh_msgs.action import SendCommand
from rescuemesh_msgs.msg import Command


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("robot")
    parser.add_argument("request", help="JSON: type, receiver, and x, y, radius, period, count, frame_id, sender")
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("--copies", type=int, default=1, help="send this many goals at once")
    args = parser.parse_args()
    request = json.loads(args.request)
    rclpy.init()
    node = rclpy.create_node("commander")
    client = ActionClient(node, SendCommand, f"/{args.robot}/comm_protocol/send_command")
    if not client.wait_for_server(timeout_sec=args.timeout):
        print(json.dumps({"error": "no action server"}), flush=True)
        return 3
    command = Command(type=request["type"], receiver=request.get("receiver", ""), sender=request.get("sender", ""),
                      direction=request.get("direction", ""))
    command.header.frame_id = request.get("frame_id", "map")
    command.frame.position.x = float(request.get("x", 0.0))
    command.frame.position.y = float(request.get("y", 0.0))
    command.radius = float(request.get("radius", 0.0))
    command.period = float(request.get("period", 0.0))
    command.count = int(request.get("count", 0))

    def on_feedback(message) -> None:
        fb = message.feedback
        print(json.dumps({"feedback": fb.result, "progress": fb.progress, "confirm_type": fb.confirm.type,
                          "ref_type": fb.confirm.ref_type}), flush=True)

    if args.copies > 1:
        return _burst(node, client, SendCommand.Goal(command=command), args.copies, args.timeout)
    sent = client.send_goal_async(SendCommand.Goal(command=command), feedback_callback=on_feedback)
    rclpy.spin_until_future_complete(node, sent, timeout_sec=args.timeout)
    handle = sent.result()
    if handle is None or not handle.accepted:
        print(json.dumps({"error": "goal not accepted"}), flush=True)
        return 4
    result_future = handle.get_result_async()
    rclpy.spin_until_future_complete(node, result_future, timeout_sec=args.timeout)
    if not result_future.done():
        print(json.dumps({"error": "no result in time"}), flush=True)
        return 5
    _print_result(result_future.result())
    node.destroy_node()
    rclpy.shutdown()
    return 0


def _print_result(outcome) -> None:
    r = outcome.result
    print(json.dumps({"status": outcome.status, "result": r.result, "reason": r.reason, "seq": r.seq,
                      "error": r.error, "confirm_result": r.confirm.result, "confirm_sender": r.confirm.sender}),
          flush=True)


def _burst(node, client, goal, copies: int, timeout_s: float) -> int:
    """`copies` goals sent at once; each result printed as it comes. 4 if one was not accepted, 5 if
    any had no result in time."""
    deadline = time.monotonic() + timeout_s
    handles = [client.send_goal_async(goal) for _ in range(copies)]
    results, printed = [], 0
    while time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
        for future in [f for f in handles if f.done()]:
            handles.remove(future)
            handle = future.result()
            if handle is None or not handle.accepted:
                print(json.dumps({"error": "goal not accepted"}), flush=True)
                return 4
            results.append(handle.get_result_async())
        for future in [f for f in results if f.done()]:
            results.remove(future)
            _print_result(future.result())
            printed += 1
        if printed == copies:
            return 0
    print(json.dumps({"error": "no result in time"}), flush=True)
    return 5


if __name__ == "__main__":
    sys.exit(main())
