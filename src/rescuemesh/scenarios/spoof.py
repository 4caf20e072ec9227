"""Scenario `spoof`: the follow scenario with an intruder radio next to robot_2 that is not in the
team. It forges Stops and Follows "from robot_1", a Confirm "from robot_2" for each of robot_1's
commands, and replays every frame it overhears 0.5 s, 15 s and 60 s later and again at the end.

Owns: the intruder (a radio with no key or a wrong key) and the security verdict. Must not know:
how frames are sealed or checked (it counts what the robots accepted). `--insecure` must fail.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import heapq
import itertools
from collections import Counter
from dataclasses import dataclass

from rescuemesh.mesh import Transmission
from rescuemesh.mesh.keys import hkdf_sha256
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.protocol import BROADCAST, Follow, MessageType, Pose, ResultCode, Stop, encode_frame
from rescuemesh.protocol.codec import PROTOCOL_VERSION, FrameFlags, Header
from rescuemesh.protocol.messages import CONFIRMABLE_TYPES, Confirm
from rescuemesh.robot import events as ev
from rescuemesh.scenarios.base import Verdict
from rescuemesh.scenarios.follow import FollowScenario

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

#: The intruder's radio address on the simulated medium (not a robot; its frames claim others').
INTRUDER_ADDRESS = 200
#: Where the intruder stands: this offset (m) from robot_2, wherever robot_2 goes.
INTRUDER_OFFSET = (0.0, 0.6)
FORGE_EVERY_S = 2.0
REPLAY_DELAYS_S = (0.5, 15.0, 60.0)
#: The run lasts at least this long (s) so that the 60 s replays happen, then the final burst.
RUN_AT_LEAST_S = 62.0
FINAL_WATCH_S = 3.0
_HEADER_BYTES = 6


class FrameKind:
    FORGED = "forged"
    REPLAY = "replay"


@dataclass
class IntruderStats:
    forged_sent: int = 0
    replays_sent: int = 0
    forged_rejected: int = 0
    replays_rejected: int = 0
    first_heard_via_intruder: int = 0  # genuine team frames a robot had not heard, replayed to it
    accepted: Counter = None  # by kind: forged frames, and replays of frames a robot already had

    def __post_init__(self) -> None:
        self.accepted = Counter()


class Intruder:
    """A radio on the medium with the stack interface, outside the team: it hears everything
    near it, forges frames (half with no key, as CRC frames; half sealed with a wrong key) and
    replays what it heard. `now` comes from the medium; it draws no random numbers."""

    def __init__(self, seed: int) -> None:
        wrong_key = hkdf_sha256(seed.to_bytes(8, "big"), b"intruder", b"a key not the team's", 16)
        self.wrong = FrameSealer.from_team_key(wrong_key)
        self.address = INTRUDER_ADDRESS
        self.stats = IntruderStats()
        self.kind_of: dict[bytes, str] = {}
        self._due: list = []
        self._order = itertools.count()
        self._seen_headers: set[bytes] = set()
        self._heard: list[bytes] = []
        self._seq = 0x4000  # numbers a forger would guess; anything will do
        self._next_forgery_s = FORGE_EVERY_S
        self._final_sent = False

    # --- the stack interface the medium drives --------------------------------------------------

    def receive(self, data: bytes, now: float, *, rssi_dbm=None, relay_delay_s: float = 0.0) -> None:
        if len(data) < _HEADER_BYTES + 4 or data[0] & 0x10:  # segments: not worth it here
            return
        header = bytes([data[1]]) + data[2:_HEADER_BYTES]  # attempt+type, src, dst, seq (TTL aside)
        if header in self._seen_headers:
            return
        self._seen_headers.add(header)
        self._heard.append(data)
        for delay in REPLAY_DELAYS_S:
            self._schedule(now + delay, data, FrameKind.REPLAY)
        msg_type, src, dst, seq = data[1] & 0x3F, data[2], data[3], int.from_bytes(data[4:6], "big")
        if src == 1 and dst != BROADCAST and data[1] >> 6 == 0 and msg_type in CONFIRMABLE_TYPES:
            # a Confirm "from" the addressee for each of robot_1's commands: DONE, so retries stop
            confirm = Confirm(seq, MessageType(msg_type), ResultCode.DONE)
            self._schedule(now + 0.002, self._forge(dst, src, confirm, keyed=seq % 2 == 0), FrameKind.FORGED)

    def transmissions(self, now: float) -> list[Transmission]:
        if now >= self._next_forgery_s:
            keyed = int(self._next_forgery_s / FORGE_EVERY_S) % 2 == 0
            self._schedule(now, self._forge(1, 2, Stop(), keyed), FrameKind.FORGED)
            self._schedule(now + 0.05, self._forge(1, 2, Follow(Pose(1.0, 8.0, 0.0, 0.0)), not keyed), FrameKind.FORGED)
            self._next_forgery_s += FORGE_EVERY_S
        out = []
        while self._due and self._due[0][0] <= now:
            _, _, data, kind = heapq.heappop(self._due)
            self.kind_of[data] = kind
            if kind == FrameKind.FORGED:
                self.stats.forged_sent += 1
            else:
                self.stats.replays_sent += 1
            out.append(Transmission(data, data[2], data[3], data[1] & 0x3F, int.from_bytes(data[4:6], "big"),
                                    data[0] & 0x0F, False, None, None))
        return out

    def get_timer(self) -> float | None:
        times = [t for t in (self._due[0][0] if self._due else None, self._next_forgery_s) if t is not None]
        return min(times) if times else None

    def handle_timer(self, now: float) -> None:
        """Nothing to do: transmissions() releases what is due."""

    def replay_everything(self, now: float) -> None:
        """The final burst: every frame heard, once more."""
        if not self._final_sent:
            self._final_sent = True
            for data in self._heard:
                self._schedule(now, data, FrameKind.REPLAY)

    # --- internals -----------------------------------------------------------------------------

    def _forge(self, src: int, dst: int, message, keyed: bool) -> bytes:
        self._seq = (self._seq + 1) & 0xFFFF
        frame = encode_frame(Header(PROTOCOL_VERSION, FrameFlags.NONE, 7, 0, message.TYPE, src, dst, self._seq),
                             message)
        return self.wrong.seal(frame, 0) if keyed else frame

    def _schedule(self, at: float, data: bytes, kind: str) -> None:
        heapq.heappush(self._due, (at, next(self._order), data, kind))


class SpoofScenario(FollowScenario):
    name = "spoof"
    runs_as_processes = False  # it taps the medium and opens frames with the robots' own nodes
    summary = "the follow scenario while an intruder forges Stops, Follows and Confirms and replays what it hears"
    time_limit_s = 150.0

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self.intruder = Intruder(options.seed)
        self._attached = False
        self._final_s: float | None = None

    def _attach(self, rt: SimRuntime) -> None:
        body = rt.world.bodies[self.follower]

        def position() -> tuple[float, float]:
            pose = body.pose()
            return (pose.x + INTRUDER_OFFSET[0], pose.y + INTRUDER_OFFSET[1])

        rt.medium.attach(self.intruder.address, self.intruder, position)
        rt.medium.observe = self._observe
        self._nodes = {stack.address: stack.node for stack in rt.stacks.values()}
        self._accepted_frames: set[tuple[int, bytes]] = set()  # (robot, header bytes 1-5) it accepted
        self._attached = True

    def _observe(self, transmitter: int, receiver: int, data: bytes, now: float, deliver) -> None:
        """Count what becomes of every intruder frame at every robot. A frame's identity is its
        clear header (attempt and type, source, destination, seq)."""
        node = self._nodes.get(receiver)
        if node is None:
            deliver()
            return
        before = node.stats.accepted
        deliver()
        identity = (receiver, data[1:6])
        accepted = node.stats.accepted > before
        if transmitter != self.intruder.address:
            if accepted:
                self._accepted_frames.add(identity)
            return
        kind = self.intruder.kind_of.get(data, FrameKind.REPLAY)
        if accepted and kind == FrameKind.REPLAY and identity not in self._accepted_frames:
            # a genuine frame this robot never heard, heard now through the intruder: a late relay
            self.intruder.stats.first_heard_via_intruder += 1
            self._accepted_frames.add(identity)
        elif accepted:
            self.intruder.stats.accepted[kind] += 1
        elif kind == FrameKind.FORGED:
            self.intruder.stats.forged_rejected += 1
        else:
            self.intruder.stats.replays_rejected += 1

    def tick(self, rt: SimRuntime) -> None:
        if not self._attached:
            self._attach(rt)
        super().tick(rt)
        if rt.time >= RUN_AT_LEAST_S and self._final_s is None:
            self._final_s = rt.time
            self.intruder.replay_everything(rt.time)

    def finished(self, rt: SimRuntime) -> bool:
        if self._final_s is None or rt.time < self._final_s + FINAL_WATCH_S:
            return super().finished(rt) and self.accepted_s is None  # a Follow never confirmed ends it early
        return True

    def evaluate(self, rt: SimRuntime) -> Verdict:
        verdict = super().evaluate(rt)
        s = self.intruder.stats
        accepted = sum(s.accepted.values())
        doubles = _double_executions(rt)
        criteria = list(verdict.criteria)
        criteria += [
            (f"the intruder was heard: {s.forged_rejected + s.replays_rejected + accepted} of its frames reached robots",
             s.forged_rejected + s.replays_rejected + accepted > 0 and s.forged_sent > 0 and s.replays_sent > 0),
            (f"nothing from the intruder accepted ({accepted})", accepted == 0),
            (f"no command executed twice ({doubles})", doubles == 0),
        ]
        metrics = dict(verdict.metrics)
        metrics["security"] = security_summary(rt, s, doubles)
        metrics["security"]["forged_commands_obeyed"] = _forged_commands_obeyed(rt)
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)


def _double_executions(rt: SimRuntime) -> int:
    """Commands a robot acted on twice: the same (source, seq) received as new more than once."""
    doubles = 0
    for brain in rt.brains.values():
        seen = Counter((e.command, e.src, e.seq) for e in brain.log if isinstance(e, ev.CommandReceived))
        doubles += sum(n - 1 for n in seen.values() if n > 1)
    return doubles


def _forged_commands_obeyed(rt: SimRuntime) -> dict[str, int]:
    """Commands robots acted on that their claimed sender never sent, by type ("Stop": 3)."""
    obeyed: Counter = Counter()
    by_address = {brain.address: brain for brain in rt.brains.values()}
    for brain in rt.brains.values():
        for e in brain.log:
            if not isinstance(e, ev.CommandReceived):
                continue
            claimed = by_address.get(e.src)
            if claimed is not None and e.seq not in claimed.outgoing:
                obeyed[ev.message_name(e.command)] += 1
    return dict(obeyed)


def security_summary(rt: SimRuntime, s: IntruderStats, doubles: int) -> dict:
    nodes = [stack.node.stats for stack in rt.stacks.values()]
    return {
        "authenticated": rt.config.secure,
        "forged_injected": s.forged_sent,
        "replayed": s.replays_sent,
        "forged_rejected": s.forged_rejected,
        "replays_rejected": s.replays_rejected,
        "accepted_from_intruder": sum(s.accepted.values()),
        "accepted_forged": s.accepted[FrameKind.FORGED],
        "accepted_replays": s.accepted[FrameKind.REPLAY],
        "first_heard_via_intruder": s.first_heard_via_intruder,
        "double_executions": doubles,
        "robots_dropped": {
            "unauthenticated": sum(n.dropped_unauthenticated for n in nodes),
            "forged": sum(n.dropped_forged for n in nodes),
            "replay": sum(n.dropped_replay for n in nodes),
            "unknown_epoch": sum(n.dropped_unknown_epoch for n in nodes),
            "cached": sum(n.dropped_cached for n in nodes),
        },
    }
