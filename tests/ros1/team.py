"""A team of rescuemesh robots on ROS 1 bodies in one process, for tests/ros1: each robot's brain,
navigation and network stack on a Ros1Body, with the paper's topics (Ros1Paper), the stacks joined
by an in-memory frame exchange, stepped every 50 ms at ROS time (= wall time).

Owns: the test's stand-in for `rescuemesh robot --body ros1` (one node for the whole team), an
optional mission script, a JSON report. Must not know: what the test asserts. Prints "ready" once
every topic is set up; writes the report every second and at the end; stops on SIGTERM/SIGINT or
after --duration s, the wheels commanded to zero.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time

import numpy as np

from rescuemesh.geometry import Pose2D
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.nav import Costmap
from rescuemesh.protocol import ResultCode
from rescuemesh.robot import robot_address
from rescuemesh.runtime.assembly import assemble_robot, team_sealer
from rescuemesh.runtime.config import SimConfig
from rescuemesh.runtime.ros.ros1_body import NoOdometryError, Ros1Body, import_rospy, init_node
from rescuemesh.runtime.ros.ros1_paper import Ros1Paper

CONTROL_DT = 0.05  # s


def empty_costmap(half_size_m: float = 15.0, resolution: float = 0.05) -> Costmap:
    """A robot with no map: free floor around the origin."""
    cells = int(2 * half_size_m / resolution)
    grid = OccupancyGrid(np.zeros((cells, cells), dtype=bool), resolution, -half_size_m, -half_size_m)
    return Costmap(grid)


class FollowScript:
    """The leader sends Follow, then drives to `goal` once it is ACCEPTED; done 4 s after it arrives."""

    def __init__(self, leader, follower: str, goal: Pose2D, start_s: float) -> None:
        self.leader, self.peer, self.goal, self.start_s = leader, robot_address(follower), goal, start_s
        self.seq = self.accepted_s = self.arrived_s = None

    def tick(self, now: float) -> None:
        if self.seq is None and now >= self.start_s:
            self.seq = self.leader.command_follow(self.peer, now)
        elif self.seq is not None and self.accepted_s is None:
            if self.leader.outgoing[self.seq].result == ResultCode.ACCEPTED:
                self.accepted_s = now
                self.leader.navigate_to(self.goal, now)
        elif self.accepted_s is not None and self.arrived_s is None and self.leader.running is None:
            self.arrived_s = now

    def done(self, now: float) -> bool:
        return self.arrived_s is not None and now - self.arrived_s > 4.0

    def report(self) -> dict:
        return {"accepted_s": self.accepted_s, "arrived_s": self.arrived_s}


def exchange(stacks: dict, now: float) -> None:
    """Every frame each stack puts on the air reaches every other stack (a perfect radio)."""
    for _ in range(8):  # relays answer in kind; a few rounds drain them
        sent = [(name, t.data) for name, stack in stacks.items() for t in stack.transmissions(now)]
        if not sent:
            return
        for src, data in sent:
            for name, stack in stacks.items():
                if name != src:
                    stack.receive(data, now)


def report(path: str, brains: dict, papers: dict, script, now: float) -> None:
    out = {"now": now, "script": script.report() if script else None, "robots": {}}
    for name, brain in brains.items():
        pose = brain.body.pose()
        out["robots"][name] = {
            "pose": [pose.x, pose.y, pose.yaw], "behaviour": brain.behaviour,
            "log": [[e.time_s, e.kind, e.detail] for e in brain.log],
            "outgoing": [[c.seq, c.kind, c.peer, c.result.name if c.result is not None else None, c.failed]
                         for c in brain.outgoing.values()],
            "requests_done": papers[name].requests_done, "requests_refused": papers[name].requests_refused,
        }
    with open(f"{path}.tmp", "w") as f:
        json.dump(out, f, indent=1)
    os.replace(f"{path}.tmp", path)


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--robot", action="append", required=True, help="robot name (repeat)")
    parser.add_argument("--follow", help="LEADER,FOLLOWER,GOAL_X,GOAL_Y: the leader sends Follow, then drives")
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--odometry-wait", type=float, default=10.0)
    parser.add_argument("--report", required=True)
    parser.add_argument("--listen", action="append", default=[],
                        help="wait (10 s at most) until this robot's command topic has a subscriber")
    args = parser.parse_args()
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    rospy = import_rospy()
    init_node("rescuemesh_team")
    t0 = rospy.get_time()
    try:
        bodies = {name: Ros1Body(name, time_origin=t0, odometry_wait_s=args.odometry_wait) for name in args.robot}
    except NoOdometryError as exc:
        print(f"error: {exc}", file=sys.stderr, flush=True)
        return 3
    costmap, config = empty_costmap(), SimConfig(seed=0)
    sealer = team_sealer(config)
    brains, stacks, papers = {}, {}, {}
    for name, body in bodies.items():
        brains[name], stacks[name] = assemble_robot(name, body, costmap, config, sealer, body.pose())
        papers[name] = Ros1Paper(brains[name])
    deadline = time.monotonic() + 10.0
    while any(papers[name].listeners() == 0 for name in args.listen) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)  # the subscribers of the other topics connect in the same way
    print("ready", flush=True)
    script = None
    if args.follow:
        leader, follower, gx, gy = args.follow.split(",")
        script = FollowScript(brains[leader], follower, Pose2D(float(gx), float(gy), 0.0),
                              start_s=rospy.get_time() - t0 + 0.5)
    now, next_report, tick = 0.0, 0.0, time.monotonic()
    try:
        while not stop and not rospy.is_shutdown():
            now = rospy.get_time() - t0
            if now > args.duration or (script is not None and script.done(now)):
                break
            for stack in stacks.values():
                timer = stack.get_timer()
                if timer is not None and timer <= now:
                    stack.handle_timer(now)
            exchange(stacks, now)
            for name, brain in brains.items():
                papers[name].step(now)
                brain.step(now)
            if script is not None:
                script.tick(now)
            exchange(stacks, now)
            if now >= next_report:
                report(args.report, brains, papers, script, now)
                next_report = now + 1.0
            tick += CONTROL_DT
            time.sleep(max(0.0, tick - time.monotonic()))
    finally:
        for body in bodies.values():
            body.set_velocity(0.0, 0.0)
        report(args.report, brains, papers, script, now)
        time.sleep(0.2)  # the zero twists leave before the node goes
        rospy.signal_shutdown("team done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
