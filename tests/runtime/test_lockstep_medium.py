"""The medium of a world with robot processes (runtime/processes/lockstep_medium.py): a frame that
ends on the air goes to all the robots that hear it in one round of requests, and the air is the same
as when the medium calls each stack in turn (same frames, same times, same receptions)."""

from __future__ import annotations

from rescuemesh.checks.mesh_bench import _team
from rescuemesh.protocol import CommandReceived, ResultCode, Stop
from rescuemesh.runtime.processes import control_messages as msg
from rescuemesh.runtime.processes.lockstep_medium import LockstepMedium
from rescuemesh.runtime.processes.remote import RemoteStack
from rescuemesh.transport.sim_medium import SimMedium

#: Five robots 6 m apart on a 10 m disc: a frame is heard by one or two neighbours, and relayed.
POSITIONS = [(6.0 * i, 0.0) for i in range(5)]
STEP_S = 0.05


class _Robots:
    """What ProcessRuntime is to the stand-ins and the medium, with each "process" a real stack here.
    It logs the order of what reaches the robots: ("send", robot, batch) when a request goes out,
    ("read", robot) when the medium reads a stand-in's transmissions."""

    def __init__(self, stacks) -> None:
        self.stacks = {f"robot_{s.address}": s for s in stacks}
        self.log: list[tuple] = []
        self.rounds: list[int] = []  # the number of robots each arrival's round went to
        self._batch: list | None = None

    @property
    def batching(self) -> bool:
        return self._batch is not None

    def _answer(self, robot: str, request):
        stack = self.stacks[robot]
        if isinstance(request, msg.Receive):
            stack.receive(request.data, request.now, rssi_dbm=request.rssi_dbm, relay_delay_s=request.relay_delay_s)
        else:
            stack.handle_timer(request.now)
        return stack.transmissions(request.now), stack.get_timer()

    def call_stack(self, robot: str, request):
        self.log.append(("send", robot, False))
        return self._answer(robot, request)

    def deliver_later(self, stand_in, request) -> None:
        self._batch.append((stand_in, request))

    def begin(self) -> None:
        self._batch = []

    def end(self) -> list:
        batch, self._batch = self._batch, None
        if batch:  # (a frame that no one heard: no round)
            self.rounds.append(len(batch))
        for stand_in, _ in batch:
            self.log.append(("send", stand_in.robot, True))
        for stand_in, request in batch:
            stand_in.prime(*self._answer(stand_in.robot, request))
        return [stand_in for stand_in, _ in batch]


class _LoggedStandIn(RemoteStack):
    def transmissions(self, now: float) -> list:
        self._link.log.append(("read", self.robot))
        return super().transmissions(now)


def _drive(medium, stacks, prime=None, until_s: float = 6.0) -> None:
    """Every robot sends a Heartbeat every 0.5 s, from 1 s on a Stop to the one two places on every
    0.5 s; each Stop is confirmed."""
    t = 0.0
    while t < until_s:
        t = round(t + STEP_S, 9)
        medium.pump(t)
        for stack in stacks:
            while (event := stack.endpoint.next_event()) is not None:
                if isinstance(event, CommandReceived):
                    stack.endpoint.confirm(event.src, event.seq, event.command.TYPE, ResultCode.DONE, t)
            if round(t / STEP_S) % 10 == stack.address:
                stack.endpoint.send_heartbeat(t)
            if round(t / STEP_S) % 10 == stack.address + 3 and t > 1.0:
                stack.endpoint.send_command((stack.address + 1) % len(stacks) + 1, Stop(), t)
        if prime is not None:  # what a Tick's reply brings: the stack's transmissions and timer
            prime(t)
        medium.flush(t)


def _in_one_process(loss: float):
    unused, stacks = _team(POSITIONS, 7, extra_loss=loss)  # the team's stacks, on a medium that records
    medium = SimMedium(unused.channel, 7, extra_loss=loss, record=True)
    for stack, xy in zip(stacks, POSITIONS):
        medium.attach(stack.address, stack, lambda xy=xy: xy)
    _drive(medium, stacks)
    return medium, stacks


def _as_processes(loss: float):
    reference, stacks = _team(POSITIONS, 7, extra_loss=loss)  # the robots' own stacks ("their processes")
    medium = LockstepMedium(reference.channel, 7, extra_loss=loss, record=True)
    robots = _Robots(stacks)
    stand_ins = [_LoggedStandIn(robots, f"robot_{s.address}", s.address) for s in stacks]
    for stand_in, xy in zip(stand_ins, POSITIONS):
        medium.attach(stand_in.address, stand_in, lambda xy=xy: xy)
    medium.deliveries = robots

    def prime(t):
        for stand_in, stack in zip(stand_ins, stacks):
            stand_in.prime(stack.transmissions(t), stack.get_timer())

    _drive(medium, stacks, prime)
    return medium, stacks, robots


def test_an_arrival_goes_to_every_receiver_before_any_answer_is_read_and_the_air_is_the_same():
    for loss in (0.0, 0.2):
        one, one_stacks = _in_one_process(loss)
        many, stacks, robots = _as_processes(loss)
        # the same air: every frame at the same times, heard by the same radios, the same counts
        assert many.stats.as_dict() == one.stats.as_dict()
        assert [(r.start_s, r.transmitter, r.frame, r.heard_by, r.collided) for r in many.records] == \
               [(r.start_s, r.transmitter, r.frame, r.heard_by, r.collided) for r in one.records]
        assert [s.node.stats for s in stacks] == [s.node.stats for s in one_stacks]
        assert one.stats.receptions_delivered > 100 and one.stats.relayed_transmissions > 50
        # one round of requests per arrival, many of them to several robots at once, and after each
        # round the medium reads the answers of the same robots, in the same order
        assert len(robots.rounds) > 50 and max(robots.rounds) >= 2
        entries = iter(robots.log)
        for size in robots.rounds:
            entry = next(entries)
            while entry != ("send", entry[1], True):
                entry = next(entries)
            sent = [entry[1]] + [next(entries)[1] for _ in range(size - 1)]
            assert [next(entries) for _ in range(size)] == [("read", robot) for robot in sent]
