"""The paper's ROS 2 interface to a robot: what it sends and receives on `/ROBOT/comm_protocol/command`
(rescuemesh_msgs/msg/Command with the paper's type names), the leader's pose on
`/ROBOT/comm_protocol/follow` (geometry_msgs/msg/PoseStamped), requests on
`/ROBOT/comm_protocol/command/input`, and the action `/ROBOT/comm_protocol/send_command`
(rescuemesh_msgs/action/SendCommand): a ROS 2 node makes the robot send a command and learns its result.

Owns: the action's tickets (a request, the Confirms heard for it, its final result) and the ROS 2
publishers, subscription and action server. Must not know: frames, the mesh, the transport, the loop
(the runtime calls `step(now)` each tick, on its own thread: the brain is not thread-safe). The
conversions, the endpoint tap and the request checks are ros1_paper's (the message has the same fields).
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from rescuemesh.protocol import MessageType, ResultCode
from rescuemesh.protocol.messages import Confirm, PoseUpdate
from rescuemesh.runtime.ros.ros1_paper import (FRAME_REQUIRED, LEADER_POSE, RECEIVED, REQUESTS, TYPE_NAME, EndpointTap,
                                           Request, RequestError, Traffic, _name, fill_command, fill_pose,
                                           parse_request)
from rescuemesh.runtime.ros.ros2_body import Ros2Node
from rescuemesh.runtime.ros.ros2_msgs import import_messages

#: Results a command reports on its way (ResultCode's interim codes).
INTERIM = frozenset({ResultCode.ACCEPTED, ResultCode.IN_PROGRESS})
#: The action's result when this robot refused the request itself, and when the protocol gave it up.
REFUSED, NO_ANSWER = "REFUSED", "NO_ANSWER"
#: Messages of the command topic kept for subscribers that join late (transient local durability).
COMMAND_HISTORY = 100


def open_ended(request: Request) -> bool:
    """Whether `request`'s behaviour runs until stopped, so that ACCEPTED is its outcome."""
    return request.type in (MessageType.FOLLOW, MessageType.MOVE_AROUND) or (
        request.type in (MessageType.SHOW_CAM, MessageType.SHOW_SCAN) and request.count == 0)


@dataclass
class Ticket:
    """One action goal: the request, then (runtime thread) the command's seq and the Confirms heard."""

    request: Request
    seq: int | None = None
    confirms: "queue.SimpleQueue" = field(default_factory=queue.SimpleQueue)  # Command msgs of Confirms
    result: str | None = None  # final: a ResultCode name, REFUSED or NO_ANSWER
    reason: str = "NONE"
    error: str = ""
    done: threading.Event = field(default_factory=threading.Event)
    last_confirm: object | None = None


class Ros2Paper:
    """The paper's topics and the SendCommand action for one robot's brain, on `ros`'s node.

    Topic names are relative (`comm_protocol/command` ...), so they live in the node's namespace
    (`/ROBOT`) and remap as any ROS 2 name. `on_map(x, y)`: whether a requested pose is on this
    robot's map (a Goto off the map is refused). A malformed request is a ROS warning and, through the
    action, an aborted goal with result REFUSED and the reason in `error`; never a crash of the robot.
    """

    def __init__(self, brain, ros: Ros2Node, *, on_map: Callable[[float, float], bool] | None = None) -> None:
        from geometry_msgs.msg import PoseStamped
        from rclpy.action import ActionServer, CancelResponse, GoalResponse
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        self.Command, self.SendCommand = import_messages()
        self._pose_stamped = PoseStamped
        self.brain, self.ros, self.on_map = brain, ros, on_map
        node = ros.node
        self.command_topic = ros.resolve("comm_protocol/command")
        self.follow_topic = ros.resolve("comm_protocol/follow")
        self.input_topic = ros.resolve("comm_protocol/command/input")
        self.requests_done = 0
        self.requests_refused = 0
        self._requests: queue.SimpleQueue = queue.SimpleQueue()  # Request or Ticket
        self._active: dict[tuple[int, int], Ticket] = {}  # (receiver, seq) -> ticket (runtime thread)
        # the record keeps its latest 100 for late joiners (a recorder, `ros2 topic echo --qos-durability
        # transient_local`), as a latched ROS 1 topic; a volatile subscriber matches it too
        self._commands = node.create_publisher(self.Command, "comm_protocol/command", QoSProfile(
            depth=COMMAND_HISTORY, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE))
        self._follow = node.create_publisher(PoseStamped, "comm_protocol/follow", 10)
        self._input = node.create_subscription(self.Command, "comm_protocol/command/input", self._on_input, 100)
        self._action = ActionServer(ros.commands_node(), self.SendCommand, "comm_protocol/send_command", self._execute,
                                    goal_callback=lambda goal: GoalResponse.ACCEPT,
                                    cancel_callback=lambda goal: CancelResponse.REJECT,
                                    callback_group=ReentrantCallbackGroup())
        self.action_name = ros.resolve("comm_protocol/send_command")
        if not isinstance(brain.endpoint, EndpointTap):
            brain.endpoint = EndpointTap(brain.endpoint, self._publish)
        else:  # a tap already there (a paper made before): this one hears through it too
            previous = brain.endpoint._sink
            brain.endpoint._sink = lambda traffic: (previous(traffic), self._publish(traffic))

    # ----- requests (the executor's threads) -----

    def _warn(self, where: str, text: str) -> None:
        self.requests_refused += 1
        self.ros.logger.warning(f"{self.brain.name}: refused a Command on {where}: {text}")

    def _parse(self, msg) -> Request:
        request = parse_request(msg, self.brain.name)
        if request.type in FRAME_REQUIRED and self.on_map is not None \
                and not self.on_map(request.frame.x, request.frame.y):
            raise RequestError(f"frame ({request.frame.x:g}, {request.frame.y:g}) is off {self.brain.name}'s map "
                               f"or inside an obstacle")
        if not (0 <= msg.count <= 255):
            raise RequestError(f"count must be 0..255, got {msg.count}")
        return request

    def _on_input(self, msg) -> None:
        try:
            self._requests.put(self._parse(msg))
        except RequestError as exc:
            self._warn(self.input_topic, str(exc))

    def _execute(self, goal_handle):
        """The action's execute callback: queue the request, relay each Confirm as feedback, return the end."""
        Result = self.SendCommand.Result
        try:
            request = self._parse(goal_handle.request.command)
        except RequestError as exc:
            self._warn(self.action_name, str(exc))
            goal_handle.abort()
            return Result(result=REFUSED, error=str(exc))
        ticket = Ticket(request)
        self._requests.put(ticket)
        while not ticket.done.wait(0.05):
            self._relay_feedback(goal_handle, ticket)
            if not self.ros.context.ok():
                break
            if ticket.seq is None and not goal_handle.is_active:
                break
        self._relay_feedback(goal_handle, ticket)
        result = Result(result=ticket.result or NO_ANSWER, reason=ticket.reason, seq=ticket.seq or 0,
                        error=ticket.error)
        if ticket.last_confirm is not None:
            result.confirm = ticket.last_confirm
        if ticket.result in (ResultCode.DONE.name, ResultCode.ACCEPTED.name):
            goal_handle.succeed()
        else:
            goal_handle.abort()
        return result

    def _relay_feedback(self, goal_handle, ticket: Ticket) -> None:
        while True:
            try:
                confirm = ticket.confirms.get_nowait()
            except queue.Empty:
                return
            ticket.last_confirm = confirm
            feedback = self.SendCommand.Feedback(result=confirm.result, progress=confirm.progress, confirm=confirm)
            goal_handle.publish_feedback(feedback)

    # ----- the runtime's thread -----

    def step(self, now: float) -> None:
        """Carry out the requests that arrived since the last step, and settle the action goals whose
        command has ended (or was given up); call it each control tick."""
        while True:
            try:
                item = self._requests.get_nowait()
            except queue.Empty:
                break
            ticket = item if isinstance(item, Ticket) else None
            request = item.request if ticket is not None else item
            try:
                seq = REQUESTS[request.type](self.brain, request, now)
                self.requests_done += 1
            except ValueError as exc:  # values the wire format cannot carry, a bad peer
                text = f"{TYPE_NAME[request.type]} to {_name(request.receiver)}: {exc}"
                self._warn(self.action_name if ticket else self.input_topic, text)
                if ticket is not None:
                    ticket.result, ticket.error = REFUSED, text
                    ticket.done.set()
                continue
            if ticket is not None:
                ticket.seq = seq
                self._active[(request.receiver, seq)] = ticket
        for key, ticket in list(self._active.items()):
            sent = self.brain.outgoing.get(ticket.seq)
            if sent is None:
                continue
            if sent.result is not None and (sent.result not in INTERIM or (
                    sent.result == ResultCode.ACCEPTED and open_ended(ticket.request))):
                ticket.result, ticket.reason = sent.result.name, sent.reason.name
            elif sent.failed:
                ticket.result, ticket.error = NO_ANSWER, "no Confirm came: the protocol gave the command up"
            else:
                continue
            del self._active[key]
            ticket.done.set()

    def _publish(self, traffic: Traffic) -> None:
        """The tap's sink, on the runtime's thread inside brain.step."""
        if not self.ros.context.ok():
            return
        stamp = self.ros.node.get_clock().now().to_msg()
        msg = self.Command()
        fill_command(msg, traffic)
        msg.header.stamp = stamp
        self._commands.publish(msg)
        m = traffic.message
        if traffic.direction == RECEIVED and isinstance(m, Confirm):
            ticket = self._active.get((traffic.sender, m.ref_seq))
            if ticket is not None:
                ticket.confirms.put(msg)
        if traffic.direction == RECEIVED and m.TYPE in LEADER_POSE:
            pose = self._pose_stamped()
            pose.header.stamp, pose.header.frame_id = stamp, "map"
            fill_pose(pose.pose, m.pose if isinstance(m, PoseUpdate) else m.frame)
            self._follow.publish(pose)

    def listeners(self) -> int:
        """How many subscribers the command topic has now (a runtime may wait for a recorder)."""
        return self._commands.get_subscription_count()

    def close(self) -> None:
        """Settle open goals (NO_ANSWER: the robot is leaving) and leave the topics and the action."""
        for ticket in self._active.values():
            ticket.result, ticket.error = NO_ANSWER, "the robot process is closing"
            ticket.done.set()
        self._active.clear()
        if self.ros.context.ok():
            self._action.destroy()
            node = self.ros.node
            node.destroy_subscription(self._input)
            node.destroy_publisher(self._commands)
            node.destroy_publisher(self._follow)
