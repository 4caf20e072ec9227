"""One robot process on a real network: a KinematicBody, the robot's software, a ZenohLink, in real time.
`python -m rescuemesh.runtime.onboard.linked_robot --name robot_2 --listen tcp/IP:PORT --connect tcp/IP:PORT`.

Owns: the process's arguments, its boot counter (runtime/onboard/boot_counter.py: the epoch, on disk before
the first frame), a small mission (command a peer to Follow, drive to a goal), its JSON report.
Must not know: MuJoCo, the simulated radio, what is inside a frame.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn, TextIO

from rescuemesh.geometry import Pose2D
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.protocol import EncodeError, ResultCode
from rescuemesh.robot import RobotBrain, robot_address, robot_name
from rescuemesh.runtime.assembly import assemble_robot, team_sealer
from rescuemesh.runtime.onboard.boot_counter import BootCounter, BootCounterError, default_state_dir
from rescuemesh.runtime.config import SimConfig
from rescuemesh.runtime.onboard.kinematic_body import KinematicBody, empty_grid
from rescuemesh.runtime.onboard.realtime import RealtimeLoop, monotonic_from_zero
from rescuemesh.transport.zenoh_link import ZenohLink, check_endpoint, check_team, link_secret

#: The leader asks this many times (each one retried by the protocol) before giving the Follow up.
FOLLOW_ATTEMPTS = 5
#: Resend after this long without a Confirm, in s. Zenoh runs over TCP, which resends a lost segment
#: itself after at least 0.2 s (Linux's minimum RTO) and then doubles: the radio's 0.15 s would give a
#: command up (3 sends in 0.45 s) while TCP is still delivering it. 0.5 s: sends at 0, 0.5, 1.0 s.
ZENOH_ACK_TIMEOUT_S = 0.5
#: After the mission (or a commanded behaviour) ends, the robot stays this long, in s, so that its
#: last reports and their repeats (0.25 s apart) go out, then exits.
EXIT_LINGER_S = 0.8
#: The leader waits this long, in s, after reaching its goal (the follower closes in), then sends Stop.
LEADER_LINGER_S = 3.0
#: A robot without a map plans on a free square this many m a side, centred on the origin.
EMPTY_MAP_SIZE_M = 40.0
#: The leader's Stop at the end waits at most this long for its Confirm, in s.
STOP_WAIT_S = 1.5
#: Pose samples in the report, one every this many s.
TRAJECTORY_PERIOD_S = 0.25


class UsageError(ValueError):
    """Bad arguments; the message is one line for the user."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, no usage block
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="rescuemesh robot", description="one robot on a real network: its frames over Zenoh (IP) or "
                                                     "Bluetooth LE advertising (--link ble --hci SPEC)")
    p.add_argument("--name", required=True, help="robot_N")
    p.add_argument("--link", choices=["zenoh", "ble"], default="zenoh",
                   help="zenoh: frames over Zenoh on an IP network (--listen/--connect); ble: over a Bluetooth LE "
                        "controller as Bluetooth Mesh advertising (--hci; docs/ble.md)")
    p.add_argument("--hci", default=None, metavar="SPEC",
                   help="--link ble: the controller, a bumble transport (usb:0, hci-socket:0, "
                        "serial:/dev/ttyACM0,1000000, tcp-client:127.0.0.1:PORT)")
    p.add_argument("--listen", action="append", default=[], metavar="tcp/IP:PORT", help="endpoint to listen on")
    p.add_argument("--connect", action="append", default=[], metavar="tcp/IP:PORT", help="peer endpoint to connect to")
    p.add_argument("--team", default="team", help="team name: the key expressions' chunk (default team)")
    p.add_argument("--seed", type=int, default=0,
                   help="team key derived from this seed when no --key (simulation only)")
    p.add_argument("--key", default=None, metavar="FILE", help="team key file (rescuemesh keys new FILE)")
    p.add_argument("--insecure", action="store_true",
                   help="CRC frames and an open Zenoh link: no authentication (both ends must agree)")
    p.add_argument("--state-dir", default=None, metavar="DIR",
                   help="where the robot keeps its boot counter, DIR/TEAM/ROBOT.epoch (default "
                        "$XDG_STATE_HOME/rescuemesh, else ~/.local/state/rescuemesh)")
    p.add_argument("--no-relay", action="store_true", help="this robot relays no one's frames (mesh relay off)")
    p.add_argument("--start", default="0,0,0", metavar="X,Y[,YAW]", help="start pose in m and rad")
    p.add_argument("--map", default=None, metavar="FILE",
                   help=f"a map file (default: an empty {EMPTY_MAP_SIZE_M:g} m square centred on the origin)")
    p.add_argument("--follow", default=None, metavar="ROBOT", help="command ROBOT to follow this robot")
    p.add_argument("--goal", default=None, metavar="X,Y[,YAW]", help="drive there (after the Follow is accepted)")
    p.add_argument("--linger", type=float, default=LEADER_LINGER_S, metavar="S",
                   help=f"the leader waits S s at its goal before it sends Stop (default {LEADER_LINGER_S:g})")
    p.add_argument("--ack-timeout", type=float, default=ZENOH_ACK_TIMEOUT_S, metavar="S",
                   help=f"resend a command after S s without its Confirm (default {ZENOH_ACK_TIMEOUT_S:g})")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="run at most S s (default: until stopped)")
    p.add_argument("--exit-when-done", action="store_true",
                   help="exit when the mission is over, or (no mission) when a commanded behaviour has ended")
    p.add_argument("--json-out", default=None, metavar="FILE", help="write a report of the run here")
    p.add_argument("--body", choices=["kinematic", "ros1", "ros2"], default="kinematic",
                   help="kinematic: a simulated unicycle (default); ros1: a ROS 1 robot's /ROBOT/odom, /ROBOT/scan "
                        "and /ROBOT/cmd_vel, with the paper's topics (docs/ros1.md); ros2: the same on ROS 2, this "
                        "process a ROS 2 node in namespace /ROBOT, with the SendCommand action (docs/ros2.md)")
    p.add_argument("--odometry-wait", type=float, default=10.0, metavar="S",
                   help="--body ros1/ros2: how long to wait for the first odometry (default 10 s)")
    from rescuemesh.runtime.ros.ros_options import add_ros_arguments

    add_ros_arguments(p)  # topic names, pose source, laser mount, limits; then `--ros-args ...` for ros2
    return p


def parse_pose(text: str, what: str) -> Pose2D:
    parts = text.split(",")
    try:
        values = [float(v) for v in parts]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise UsageError(f"{what} takes X,Y[,YAW] in m and rad, got {text!r}")
    return Pose2D(*values)


def build_ros1_robot(options: dict):
    """A ROS 1 robot's body (its odometry, scan and cmd_vel topics), brain, stack and the paper's
    topics: (body, brain, stack, paper). Raises Ros1Unavailable or NoOdometryError (one line each)."""
    from rescuemesh.runtime.ros.ros1_body import Ros1Body, init_node
    from rescuemesh.runtime.ros.ros1_paper import Ros1Paper

    from rescuemesh.runtime.ros.ros_options import ros1_body_kwargs

    name = options["name"]
    init_node(f"rescuemesh_{name}")
    body = Ros1Body(name, odometry_wait_s=options["odometry_wait"], **ros1_body_kwargs(options["ros"]))
    brain, stack = _software(name, body, options["config"], _grid(options["grid"]), body.pose(),
                             options.get("epoch", 0))
    return body, brain, stack, Ros1Paper(brain)


def build_ros2_robot(options: dict):
    """A ROS 2 robot: this process a ROS 2 node (runtime/ros/ros2_body.py), its body, brain, stack and the
    paper's topics and action: (body, brain, stack, paper). Raises Ros2Unavailable, Ros2MsgsUnavailable
    or NoOdometryError (one line each); the node is closed again when it fails."""
    from rescuemesh.runtime.ros.ros2_body import Ros2Body, Ros2Node
    from rescuemesh.runtime.ros.ros2_paper import Ros2Paper
    from rescuemesh.runtime.ros.ros_options import ros2_body_kwargs

    name, grid = options["name"], _grid(options["grid"])
    ros = Ros2Node(name, namespace=options["ros"]["namespace"], ros_args=options["ros_args"])
    try:
        body = Ros2Body(ros, name, odometry_wait_s=options["odometry_wait"], **ros2_body_kwargs(options["ros"]))
        brain, stack = _software(name, body, options["config"], grid, body.pose(), options.get("epoch", 0))
        paper = Ros2Paper(brain, ros, on_map=lambda x, y: not grid.is_occupied(x, y))
    except BaseException:
        ros.close()
        raise
    return body, brain, stack, paper


def build_robot(name: str, start: Pose2D, config: SimConfig, clock: Callable[[], float],
                grid: OccupancyGrid | None = None, epoch: int = 0):
    """Robot `name`'s body, brain and network stack, without a link: (body, brain, stack). `epoch`:
    its boot counter (a process keeps it on disk, BootCounter)."""
    grid = _grid(grid)
    body = KinematicBody(name, start, clock, grid=grid)
    brain, stack = _software(name, body, config, grid, start, epoch)
    return body, brain, stack


def _grid(grid: OccupancyGrid | None) -> OccupancyGrid:
    """The robot's map, or an empty square centred on the origin for a robot without one."""
    return grid if grid is not None else empty_grid(size_m=EMPTY_MAP_SIZE_M)


def _software(name: str, body, config: SimConfig, grid: OccupancyGrid, start: Pose2D, epoch: int = 0):
    """The robot's brain and network stack on `body` (runtime/assembly.py): (brain, stack)."""
    from rescuemesh.nav import Costmap

    return assemble_robot(name, body, Costmap(grid), config, team_sealer(config), start, epoch=epoch)


def team_link_secret(config: SimConfig) -> bytes | None:
    """The Zenoh link's password for the team's key (None with --insecure: an open link)."""
    if not config.secure:
        return None
    from rescuemesh.mesh.keys import team_key_from_seed

    return link_secret(config.team_key if config.team_key is not None else team_key_from_seed(config.seed))


class EpochGuardLink:
    """A link that records the endpoint's epoch on disk before a frame sealed under a new one leaves
    (the endpoint opens a new epoch at every wrap of its 16-bit seq). A BootCounterError stops the
    run: a frame under an epoch not on disk could repeat a nonce after a restart."""

    def __init__(self, link, endpoint, counter: BootCounter) -> None:
        self.link, self.endpoint, self.counter = link, endpoint, counter

    def send(self, frame: bytes) -> None:
        if self.endpoint.epoch != self.counter.epoch:
            self.counter.advance(self.endpoint.epoch)
        self.link.send(frame)

    def send_all(self, frames) -> None:
        for frame in frames:
            self.send(frame)

    def wait(self, timeout_s: float | None) -> bool:
        return self.link.wait(timeout_s)

    def drain(self, limit: int | None = None) -> list[bytes]:
        return self.link.drain(limit)


class Mission:
    """The leader's mission: have `follower` Follow this robot (asked up to FOLLOW_ATTEMPTS times once
    it is heard), then drive to `goal`, wait `linger_s`, send Stop. Without a follower, just the
    drive; without a goal, the Follow then `linger_s`. `done` when over; `ok` whether it worked."""

    def __init__(self, follower: int | None, goal: Pose2D | None, linger_s: float) -> None:
        self.follower, self.goal, self.linger_s = follower, goal, linger_s
        self.follow_seqs: list[int] = []
        self.follow_result: ResultCode | None = None
        self.goal_sent = False
        self.accepted_s: float | None = None
        self.arrived_s: float | None = None
        self.goal_result: ResultCode | None = None
        self.stop_seq: int | None = None
        self.stop_sent_s: float | None = None
        self.done_s: float | None = None
        self.ok = False

    def on_step(self, loop: RealtimeLoop, now: float) -> None:
        brain: RobotBrain = loop.brain
        if self.done_s is not None:
            return
        if self.follower is not None and self.accepted_s is None:
            self._ask_follow(loop, brain, now)
            return
        if self.goal is not None and self.arrived_s is None:
            if not self.goal_sent:
                brain.navigate_to(self.goal, now)
                self.goal_sent = True
                return
            if brain.running is not None:
                return
            self.arrived_s = now
            self.goal_result = next((f.result for f in reversed(brain.finished) if f.name == "navigate"), None)
        end_of_drive = self.arrived_s if self.goal is not None else self.accepted_s
        if self.stop_seq is None:
            if now - end_of_drive < self.linger_s:
                return
            if self.follower is None:
                return self._finish(now)
            self.stop_seq, self.stop_sent_s = brain.command_stop(self.follower, now), now
            return
        stop = brain.outgoing[self.stop_seq]
        if stop.result is not None or stop.failed or now - self.stop_sent_s > STOP_WAIT_S:
            self._finish(now)

    def _ask_follow(self, loop: RealtimeLoop, brain: RobotBrain, now: float) -> None:
        for seq in self.follow_seqs:
            sent = brain.outgoing[seq]
            if sent.result is not None and not sent.failed:
                self.follow_result = sent.result
                if sent.result == ResultCode.ACCEPTED:
                    self.accepted_s = now
                else:
                    self._finish(now)  # refused: the mission is over, not done
                return
        pending = any(not c.failed and c.result is None for c in brain.outgoing.values() if c.peer == self.follower)
        if pending or not loop.stack.is_reachable(self.follower, now):
            return
        if brain.pose_fault is not None:
            return  # our pose cannot be sent: ask once it can
        if len(self.follow_seqs) < FOLLOW_ATTEMPTS:
            try:
                self.follow_seqs.append(brain.command_follow(self.follower, now))
            except EncodeError:  # the pose left the wire's range since the step: the next step reports it
                return
        else:
            self._finish(now)  # given up

    def _finish(self, now: float) -> None:
        self.done_s = now
        follow_ok = self.follower is None or self.accepted_s is not None
        goal_ok = self.goal is None or self.goal_result == ResultCode.DONE
        self.ok = follow_ok and goal_ok

    def report(self) -> dict:
        return {"follower": robot_name(self.follower) if self.follower is not None else None,
                "goal": [self.goal.x, self.goal.y] if self.goal is not None else None,
                "follow_result": self.follow_result.name if self.follow_result is not None else None,
                "follow_attempts": len(self.follow_seqs), "accepted_s": _r(self.accepted_s),
                "arrived_s": _r(self.arrived_s),
                "goal_result": self.goal_result.name if self.goal_result is not None else None,
                "done_s": _r(self.done_s), "ok": self.ok}


def _r(value: float | None) -> float | None:
    return None if value is None else round(value, 3)


class ExitWhenDone:
    """The run's end for --exit-when-done: EXIT_LINGER_S s after the mission is over or, without a
    mission, after a behaviour has ended and nothing runs, counted from the latest moment it became so
    (a new command in between starts the count again)."""

    def __init__(self, brain: RobotBrain, mission: Mission | None) -> None:
        self.brain, self.mission = brain, mission
        self.over_since: float | None = None

    def __call__(self, now: float) -> bool:
        if self.mission is not None:
            over = self.mission.done_s is not None
        else:
            over = self.brain.running is None and bool(self.brain.finished)
        if not over:
            self.over_since = None  # this used to exit 0.8 s after a Stop although a new Follow had come since
        elif self.over_since is None:
            self.over_since = now
        return self.over_since is not None and now - self.over_since >= EXIT_LINGER_S


def main(argv: Sequence[str] | None = None, *, out: TextIO | None = None, err: TextIO | None = None) -> int:
    """Run one robot process; 0 when its mission (if any) worked, 1 when not, 2 for bad arguments or
    a session that cannot open (one line on `err`)."""
    out = out if out is not None else sys.stdout
    err = err if err is not None else sys.stderr
    try:
        from rescuemesh.runtime.ros.ros_options import split_ros_args

        argv, ros_args = split_ros_args(sys.argv[1:] if argv is None else argv)
        options = _options(build_parser().parse_args(argv))
        if ros_args and options["body"] != "ros2":
            raise UsageError("--ros-args is for --body ros2")
        options["ros_args"] = ros_args
    except (UsageError, ValueError) as exc:
        print(f"rescuemesh robot: error: {exc}", file=err)
        return 2
    import zenoh

    counter = BootCounter(options["state_dir"], options["team"], options["name"])
    try:
        options["epoch"] = counter.boot()  # on disk before anything is sealed under it
    except BootCounterError as exc:
        counter.close()
        print(f"rescuemesh robot: error: {exc}", file=err)
        return 2
    try:
        return _run(options, counter, out, err, zenoh)
    finally:
        counter.close()


def _run(options: dict, counter: BootCounter, out: TextIO, err: TextIO, zenoh) -> int:
    print(f"{options['name']}: epoch {options['epoch']} ({counter.path})", file=out, flush=True)
    paper = None
    if options["body"] in ("ros1", "ros2"):
        try:
            build = build_ros1_robot if options["body"] == "ros1" else build_ros2_robot
            body, brain, stack, paper = build(options)
        except (ImportError, RuntimeError) as exc:  # Ros1/2Unavailable, NoOdometryError: one line
            print(f"rescuemesh robot: error: {str(exc).splitlines()[0]}", file=err)
            return 2
        from rescuemesh.runtime.ros.ros_options import map_frame_warning

        warning = map_frame_warning(options["name"], options["ros"], getattr(body, "resolved", {}).get(
            "odom", getattr(getattr(body, "topics", None), "odom", "odom")))
        if warning is not None:
            print(warning, file=err)
        clock = body.now
    else:
        clock = monotonic_from_zero()
        body, brain, stack = build_robot(options["name"], options["start"], options["config"], clock, options["grid"],
                                         options["epoch"])
    try:
        if options["link"] == "ble":
            from rescuemesh.runtime.onboard.ble_link import BleLink

            link = BleLink.open(options["hci"], name=options["name"])
        else:
            link = ZenohLink.open(options["team"], robot_address(options["name"]),
                                  listen=options["listen"], connect=options["connect"],
                                  secret=team_link_secret(options["config"]))
    except (zenoh.ZError, ValueError) as exc:
        print(f"rescuemesh robot: error: cannot open the Zenoh session: {str(exc).splitlines()[0]}", file=err)
        return 2
    except (ImportError, RuntimeError, TimeoutError) as exc:  # bumble missing, BleSetupError, no answer
        print(f"rescuemesh robot: error: --link ble: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}",
              file=err)
        return 2
    mission = Mission(options["follower"], options["goal"], options["linger"]) \
        if options["follower"] is not None or options["goal"] is not None else None
    trajectory: list[list[float]] = []

    def on_step(loop: RealtimeLoop, now: float) -> None:
        if link.new_peers():  # a robot's link came: it hears our epoch now, not at our next Heartbeat
            brain.heartbeat_now()
        if paper is not None:
            paper.step(now)  # requests from ROS nodes, on this thread (the brain is not thread-safe)
        if mission is not None:
            accepted = mission.accepted_s
            mission.on_step(loop, now)
            if accepted is None and mission.accepted_s is not None:
                print(f"{options['name']}: {robot_name(mission.follower)} accepted the Follow after "
                      f"{mission.accepted_s:.2f} s", file=out, flush=True)
        if not trajectory or now - trajectory[-1][0] >= TRAJECTORY_PERIOD_S:
            pose = body.pose()
            trajectory.append([round(now, 3), round(pose.x, 3), round(pose.y, 3), round(pose.yaw, 3)])

    guarded = EpochGuardLink(link, stack.endpoint, counter)
    loop = RealtimeLoop(brain, stack, guarded, control_dt=options["config"].control_dt, clock=clock, on_step=on_step)
    until = ExitWhenDone(brain, mission) if options["exit_when_done"] else None
    restore = _on_signals(loop.stop)
    failure = None
    try:
        loop.run(options["duration"] if options["duration"] is not None else math.inf, until)
    except BootCounterError as exc:  # the body was halted on the way out
        failure = str(exc)
    finally:
        restore()
        watchdog = _close_watchdog(options["name"], err)
        closing = time.monotonic()
        closed = link.close()
        close_s = time.monotonic() - closing
        if options["body"] == "ros2":  # a zero Twist waited for, then the node leaves the graph
            body.close()
            paper.close()
            body.ros.close()
        watchdog.cancel()
    report = _report(options, brain, stack, body, link, loop, mission, trajectory)
    report["link_close"] = {"clean": closed, "took_s": round(close_s, 3)}
    report["epoch"] = {"boot": options["epoch"], "last": counter.epoch, "file": str(counter.path)}
    if failure is not None:
        print(f"rescuemesh robot: error: {failure}", file=err)
        report["error"] = failure
    if options["json_out"] is not None:
        Path(options["json_out"]).write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    ok = (mission is None or mission.ok) and failure is None
    final = report["final_pose"]
    print(f"{options['name']}: {'ok' if ok else 'FAILED'} after {report['ran_s']:.1f} s, drove "
          f"{report['path_length_m']:.2f} m to ({final[0]:.2f}, {final[1]:.2f}); "
          f"frames {link.stats.frames_sent} sent, {link.stats.frames_received} heard", file=out)
    return 0 if ok else 1


#: How long closing the link and the ROS node may take once the run is over, in s. The body was
#: halted when the loop ended; a middleware that hangs on its way out must not keep the process.
CLOSE_WATCHDOG_S = 10.0


def _close_watchdog(name: str, err: TextIO) -> threading.Timer:
    """A timer that ends the process (exit 1) with one line if closing takes over CLOSE_WATCHDOG_S."""
    def give_up() -> None:
        print(f"rescuemesh robot: error: {name}: closing the link and the ROS node took over "
              f"{CLOSE_WATCHDOG_S:g} s: exiting now (the wheels were stopped when the run ended)", file=err, flush=True)
        os._exit(1)

    timer = threading.Timer(CLOSE_WATCHDOG_S, give_up)
    timer.daemon = True
    timer.start()
    return timer


def _options(args: argparse.Namespace) -> dict:
    from rescuemesh.runtime.ros.ros_options import ros_body_options

    robot_address(args.name)  # ValueError: unknown robot
    for endpoint in args.listen + args.connect:
        check_endpoint(endpoint)
    if args.link == "zenoh" and not args.listen and not args.connect:
        raise UsageError("give at least one --listen or --connect endpoint (tcp/IP:PORT)")
    if args.link == "ble" and (args.listen or args.connect):
        raise UsageError("--listen and --connect are for --link zenoh; --link ble takes --hci SPEC")
    if args.link == "ble" and not args.hci:
        raise UsageError("--link ble needs --hci SPEC: the Bluetooth controller (usb:0, hci-socket:0, ...)")
    if args.hci is not None and args.link != "ble":
        raise UsageError("--hci is for --link ble")
    check_team(args.team)
    if args.duration is not None and not (args.duration > 0 and math.isfinite(args.duration)):
        raise UsageError(f"--duration must be a positive number of s, got {args.duration}")
    if not (0 < args.odometry_wait < 3600):
        raise UsageError(f"--odometry-wait must be in (0, 3600) s, got {args.odometry_wait}")
    if not (0 <= args.linger < 3600):
        raise UsageError(f"--linger must be in [0, 3600) s, got {args.linger}")
    if not (0.01 <= args.ack_timeout <= 10):
        raise UsageError(f"--ack-timeout must be in [0.01, 10] s, got {args.ack_timeout}")
    follower = robot_address(args.follow) if args.follow is not None else None
    if follower is not None and follower == robot_address(args.name):
        raise UsageError(f"{args.name} cannot follow itself")
    key = None
    if args.key is not None:
        from rescuemesh.mesh.keys import load_team_key

        key = load_team_key(args.key)
    if not 0 <= args.seed < 1 << 64:
        raise UsageError(f"--seed must be in 0..2**64-1, got {args.seed}")
    grid = None
    if args.map is not None:
        from rescuemesh.maps import load_map

        grid = load_map(args.map).grid
    if args.json_out is not None:
        folder = Path(args.json_out).resolve().parent
        if not folder.is_dir() or not os.access(folder, os.W_OK):
            raise UsageError(f"--json-out {args.json_out}: folder {folder} cannot be written")
    start = parse_pose(args.start, "--start")
    goal = parse_pose(args.goal, "--goal") if args.goal is not None else None
    where = grid if grid is not None else empty_grid(size_m=EMPTY_MAP_SIZE_M)
    for what, pose in (("--start", start), ("--goal", goal)):
        if pose is not None and where.is_occupied(pose.x, pose.y):
            raise UsageError(f"{what} ({pose.x:g}, {pose.y:g}) is inside an obstacle or off the map")
    config = SimConfig(seed=args.seed, team_key=key, secure=not args.insecure, ack_timeout_s=args.ack_timeout,
                       relay=not args.no_relay)
    return {"name": args.name, "listen": args.listen, "connect": args.connect, "team": args.team, "config": config,
            "start": start, "goal": goal, "follower": follower, "duration": args.duration, "grid": grid,
            "exit_when_done": args.exit_when_done, "json_out": args.json_out, "linger": args.linger,
            "body": args.body, "odometry_wait": args.odometry_wait, "ros": ros_body_options(args, UsageError),
            "link": args.link, "hci": args.hci,
            "state_dir": Path(args.state_dir) if args.state_dir is not None else default_state_dir()}


def _on_signals(stop: Callable[[], None]) -> Callable[[], None]:
    """SIGINT and SIGTERM end the run (the body is halted, the report written); returns the undo."""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    old = {s: signal.signal(s, lambda *_: stop()) for s in (signal.SIGINT, signal.SIGTERM)}

    def restore() -> None:
        for sig, handler in old.items():
            signal.signal(sig, handler)

    return restore


def _length(trajectory: list[list[float]]) -> float:
    """Path length in m of [time, x, y, yaw] samples (a ROS body does not count its distance)."""
    return sum(math.hypot(b[1] - a[1], b[2] - a[2]) for a, b in zip(trajectory, trajectory[1:]))


def _report(options, brain, stack, body, link, loop, mission, trajectory) -> dict:
    pose = body.pose()
    return {
        "name": options["name"], "address": robot_address(options["name"]), "team": options["team"],
        "secure": options["config"].secure, "ran_s": round(loop.stats.ran_s, 3),
        "start": [options["start"].x, options["start"].y, options["start"].yaw],
        "final_pose": [round(pose.x, 3), round(pose.y, 3), round(pose.yaw, 3)],
        "path_length_m": round(body.distance_m if hasattr(body, "distance_m") else _length(trajectory), 3),
        "mission": mission.report() if mission is not None else None,
        "behaviours": [{"name": f.name, "started_s": _r(f.started_s), "ended_s": _r(f.ended_s),
                        "result": f.result.name, "reason": f.reason} for f in brain.finished],
        "running": brain.behaviour,
        "frames_rejected": brain.frames_rejected,
        "endpoint": stack.endpoint.stats.as_dict(),
        "link": link.stats.as_dict(), "loop": loop.stats.as_dict(),
        "trajectory": trajectory,
        "log": [[e.time_s, e.kind, e.detail] for e in brain.log],
        "log_dropped": brain.log.dropped,
    }


def exit_process(code: int) -> NoReturn:
    """End a robot process with `code` once its output is flushed, without Python's finalisation: a
    Zenoh session that did not finish closing (a lossy link can hold it for seconds) still has
    threads that would call back into a finalising interpreter, which aborts it (SIGABRT)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


if __name__ == "__main__":
    exit_process(main())
