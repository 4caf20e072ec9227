"""The Zenoh link's bench: a command's round trip to its Confirm between two robot processes on loopback,
and raw Zenoh ping-pong between two processes beside it. Figures are returned, never printed.

Owns: the two measurements, their helper processes (a robot_2, an echo) and their bounds in time.
Must not know: what is inside a frame (robot_1's brain sends, the protocol confirms).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import queue
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence

from rescuemesh.geometry import Pose2D
from rescuemesh.robot import robot_address
from rescuemesh.runtime.config import SimConfig
from rescuemesh.runtime.onboard.linked_robot import ZENOH_ACK_TIMEOUT_S, build_robot, team_link_secret
from rescuemesh.runtime.onboard.realtime import RealtimeLoop, monotonic_from_zero
from rescuemesh.transport.handoff import Handoff
from rescuemesh.transport.zenoh_link import KEY_PREFIX, ZenohLink, session_config

#: Round trips thrown away first (connections warming up, first-use code paths).
WARMUP = 20
#: How long a helper process gets to start listening, in s.
START_TIMEOUT_S = 20.0
#: How long a helper process gets to exit after SIGTERM before it is killed, in s.
STOP_TIMEOUT_S = 3.0
#: A raw ping waits this long for its pong, in s, before it counts as lost.
RAW_REPLY_TIMEOUT_S = 1.0


def zenoh_confirm_rtt(samples: int = 1000, *, raw_samples: int | None = None, timeout_s: float = 60.0,
                      secure: bool = True, python: str = sys.executable) -> dict:
    """Between two processes on 127.0.0.1 over Zenoh (TCP, peer to peer): robot_1 (here) sends
    robot_2 (a `linked_robot` process) `samples` Stop commands one after another, each as soon as
    the previous one's Confirm arrived, and times send -> Confirm handled by robot_1's brain; then
    `raw_samples` (default `samples`) raw Zenoh put -> echoed put round trips with an echo process.
    Times in ms: p50, p99, mean, max; n measured; lost (given up or unanswered) and loss ratio.
    Bounded by `timeout_s` s in all (a part that runs out reports what it measured)."""
    if samples < 1:
        raise ValueError(f"samples must be >= 1, got {samples}")
    raw_samples = samples if raw_samples is None else raw_samples
    started = time.monotonic()
    deadline = started + timeout_s
    team = f"bench{os.getpid()}"
    protocol = _protocol_rtt(samples, team, deadline, secure, python)
    raw = _raw_rtt(raw_samples, team, deadline, python) if raw_samples > 0 else _figures([], 0)
    return {"protocol": protocol, "raw": raw, "secure": secure, "transport": "zenoh peer-to-peer, tcp on 127.0.0.1",
            "command": "Stop (robot_1 -> robot_2), answered by robot_2's brain with Confirm DONE",
            "duration_s": round(time.monotonic() - started, 3)}


def _protocol_rtt(samples: int, team: str, deadline: float, secure: bool, python: str) -> dict:
    port_1, port_2 = free_port(), free_port()
    args = [python, "-m", "rescuemesh.runtime.onboard.linked_robot", "--name", "robot_2", "--team", team,
            "--listen", f"tcp/127.0.0.1:{port_2}", "--duration", f"{max(1.0, deadline - time.monotonic()):.1f}"]
    if not secure:
        args.append("--insecure")
    state = tempfile.TemporaryDirectory(prefix="rescuemesh-bench-state-")  # robot_2's boot counter, not ~'s
    args += ["--state-dir", state.name]
    with state, _Helper(args) as helper:
        if not helper.listening(port_2, min(deadline, time.monotonic() + START_TIMEOUT_S)):
            return _figures([], samples, failure=f"robot_2 did not start: {helper.output()}")
        clock = monotonic_from_zero()
        config = SimConfig(secure=secure, ack_timeout_s=ZENOH_ACK_TIMEOUT_S)
        _, brain, stack = build_robot("robot_1", Pose2D(0.0, 0.0), config, clock)
        link = ZenohLink.open(team, robot_address("robot_1"), listen=[f"tcp/127.0.0.1:{port_1}"],
                              connect=[f"tcp/127.0.0.1:{port_2}"], secret=team_link_secret(config))
        peer, rtts, state = robot_address("robot_2"), [], {"seq": None, "sent": 0.0, "lost": 0, "asked": 0}

        def on_step(loop: RealtimeLoop, now: float) -> None:
            seq = state["seq"]
            if seq is not None:
                sent = brain.outgoing[seq]
                if sent.result is not None:
                    rtts.append(time.perf_counter() - state["sent"])
                elif sent.failed:
                    state["lost"] += 1
                else:
                    return  # still waiting
                state["seq"] = None
            if state["asked"] >= samples + WARMUP:
                loop.stop()
            elif stack.is_reachable(peer, now):
                state["asked"] += 1
                state["seq"] = brain.command_stop(peer, now)
                state["sent"] = time.perf_counter()  # the frame is sealed and put right after this hook

        loop = RealtimeLoop(brain, stack, link, control_dt=config.control_dt, clock=clock, on_step=on_step)
        try:
            loop.run(max(0.0, deadline - time.monotonic()))
        finally:
            link.close()
    measured = rtts[WARMUP:] if len(rtts) > WARMUP else []
    lost = state["lost"] + (1 if state["seq"] is not None else 0)
    return _figures(measured, samples, lost=lost)


def _raw_rtt(samples: int, team: str, deadline: float, python: str) -> dict:
    import zenoh

    port = free_port()
    args = [python, "-m", "rescuemesh.runtime.onboard.link_bench", "--echo", "--team", team,
            "--listen", f"tcp/127.0.0.1:{port}", "--duration", f"{max(1.0, deadline - time.monotonic()):.1f}"]
    with _Helper(args) as helper:
        if not helper.listening(port, min(deadline, time.monotonic() + START_TIMEOUT_S)):
            return _figures([], samples, failure=f"echo did not start: {helper.output()}")
        session = zenoh.open(session_config(connect=[f"tcp/127.0.0.1:{port}"]))
        try:
            replies: Handoff[bytes] = Handoff()
            ping = session.declare_publisher(f"{KEY_PREFIX}/{team}/bench/ping", express=True)
            session.declare_subscriber(f"{KEY_PREFIX}/{team}/bench/pong", lambda s: replies.put(s.payload.to_bytes()))
            if not _echo_ready(ping, replies, deadline):
                return _figures([], samples, failure="the echo never answered")
            rtts, lost = [], 0
            for i in range(samples + WARMUP):
                if time.monotonic() >= deadline:
                    break
                payload = i.to_bytes(4, "big") + bytes(16)  # a 20-byte frame's size
                t = time.perf_counter()
                ping.put(payload)
                if _reply(replies, payload, RAW_REPLY_TIMEOUT_S):
                    rtts.append(time.perf_counter() - t)
                else:
                    lost += 1
        finally:
            session.close()
    return _figures(rtts[WARMUP:] if len(rtts) > WARMUP else [], samples, lost=lost)


def _echo_ready(ping, replies: Handoff, deadline: float) -> bool:
    """Ping until the echo's subscription has reached us (its first pong), within the deadline."""
    while time.monotonic() < deadline:
        ping.put(b"ready")
        if _reply(replies, b"ready", 0.1):
            return True
    return False


def _reply(replies: Handoff, payload: bytes, timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while (left := end - time.monotonic()) > 0:
        try:
            if replies.get(timeout=left) == payload:
                return True
        except queue.Empty:
            return False
    return False


def _figures(rtts_s: Sequence[float], asked: int, *, lost: int = 0, failure: str | None = None) -> dict:
    ms = sorted(r * 1e3 for r in rtts_s)
    out = {"p50_ms": _round(_percentile(ms, 50)), "p99_ms": _round(_percentile(ms, 99)),
           "mean_ms": _round(sum(ms) / len(ms)) if ms else None, "max_ms": _round(ms[-1]) if ms else None,
           "n": len(ms), "asked": asked, "lost": lost, "loss": round(lost / max(1, len(ms) + lost), 4)}
    if failure is not None:
        out["failure"] = failure
    return out


def _percentile(ordered: Sequence[float], q: float) -> float | None:
    if not ordered:
        return None
    rank = (len(ordered) - 1) * q / 100.0
    low = math.floor(rank)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (rank - low)


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 4)


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago (bound to port 0, then released)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


class _Helper:
    """A helper process, ended (SIGTERM, then SIGKILL) on the way out of its `with` block."""

    def __init__(self, args: list[str]) -> None:
        self.process = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                        stderr=subprocess.PIPE)

    def listening(self, port: int, deadline: float) -> bool:
        """Whether the helper accepts TCP connections on `port` before `deadline` (and is alive)."""
        while time.monotonic() < deadline and self.process.poll() is None:
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                    return True
            except OSError:
                time.sleep(0.05)
        return False

    def output(self) -> str:
        if self.process.poll() is None:
            return "still starting"
        err = self.process.stderr.read().decode("utf-8", "replace").strip().splitlines()
        return err[-1] if err else f"exit status {self.process.returncode}"

    def __enter__(self) -> "_Helper":
        return self

    def __exit__(self, *exc) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process.stderr.close()


def _echo(team: str, listen: str, duration_s: float) -> int:
    """The raw ping-pong's other end: every ping comes back as a pong, until `duration_s` s or SIGTERM."""
    import signal

    import zenoh

    session = zenoh.open(session_config(listen=[listen]))
    pong = session.declare_publisher(f"{KEY_PREFIX}/{team}/bench/pong", express=True)
    session.declare_subscriber(f"{KEY_PREFIX}/{team}/bench/ping", lambda s: pong.put(s.payload.to_bytes()))
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    end = time.monotonic() + duration_s
    while not stop and time.monotonic() < end:
        time.sleep(0.05)
    session.close()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m rescuemesh.runtime.onboard.link_bench [--samples N]` prints the figures as JSON; `--echo`
    is the raw ping-pong's other end (used by the bench itself)."""
    p = argparse.ArgumentParser(prog="python -m rescuemesh.runtime.onboard.link_bench")
    p.add_argument("--echo", action="store_true")
    p.add_argument("--team", default="bench")
    p.add_argument("--listen", default="tcp/127.0.0.1:7447")
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--samples", type=int, default=1000)
    args = p.parse_args(argv)
    if args.echo:
        return _echo(args.team, args.listen, args.duration)
    print(json.dumps(zenoh_confirm_rtt(args.samples), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
