"""ForwardMsg, executed (paper Table III: "Forward message to target"): the jobs a robot holds on a
sender's behalf, store-and-forward, until the target confirms or the timeout passes.

Owns: the job table and its rules. Must not know: the wire, radios, the clock (handed `now`).
The brain asks it what to send and tells it what the target answered.
"""

# Theory of operation
# ===================
#
# A ForwardMsg(target, inner) from S is answered ACCEPTED at once and becomes a job, unless it is
# refused: the target is us or broadcast (DENIED, UNKNOWN_TARGET), the inner message is not a
# command or Data (DENIED, BAD_REQUEST), or `capacity` jobs are held already (DENIED, BUSY).
#
#   WAITING --target reachable (heard, not lost)---> SENT (inner sent to target, confirmed/retried)
#   SENT    --target confirms, any result----------> removed, S gets DONE (progress 100)
#   SENT    --DeliveryFailed (all sends unanswered)-> WAITING (try again when reachable)
#   any     --deadline (received + timeout_s)------> removed, S gets FAILED: TIMEOUT if never
#                                                    sent, NOT_DELIVERED if sent but unconfirmed
#
# The inner message leaves from the forwarder's own address (it is the one that will get the
# Confirm); a long one (over 9 bytes, or a Data) is segmented by the mesh layer like any frame.

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from rescuemesh.protocol import BROADCAST, Data, FrameError, Message, Reason, ResultCode, decode_inner, is_command


class JobState(Enum):
    WAITING = "waiting"
    SENT = "sent"


@dataclass
class ForwardJob:
    """One ForwardMsg held for `sender` (its seq `seq`): `inner` goes to `target` by `deadline_s`."""

    sender: int
    seq: int
    target: int
    inner: Message
    received_s: float
    deadline_s: float
    state: JobState = JobState.WAITING
    sent_seq: int | None = None
    sends: int = 0  # times the inner message was sent (each with the protocol's own retries)


@dataclass(frozen=True, slots=True)
class JobEnded:
    """What to report to the job's sender: `result` with `reason`."""

    job: ForwardJob
    result: ResultCode
    reason: Reason


class Forwarder:
    """The jobs of one robot. `timeout_s`: how long a job is held, in s; `capacity`: how many at once."""

    def __init__(self, own_address: int, *, timeout_s: float = 30.0, capacity: int = 8) -> None:
        if not timeout_s > 0.0 or capacity < 1:
            raise ValueError(f"forwarding needs timeout_s > 0 and capacity >= 1, got {timeout_s!r}, {capacity!r}")
        self.own_address = own_address
        self.timeout_s = timeout_s
        self.capacity = capacity
        self.jobs: list[ForwardJob] = []

    def accept(self, sender: int, seq: int, target: int, inner_bytes: bytes, now: float) -> ForwardJob | Reason:
        """A new job, or the reason to refuse it (DENIED)."""
        if target in (self.own_address, BROADCAST):
            return Reason.UNKNOWN_TARGET
        try:
            inner = decode_inner(inner_bytes)
        except FrameError:
            return Reason.BAD_REQUEST
        if not (is_command(inner) or isinstance(inner, Data)):
            return Reason.BAD_REQUEST
        if len(self.jobs) >= self.capacity:
            return Reason.BUSY
        job = ForwardJob(sender, seq, target, inner, now, now + self.timeout_s)
        self.jobs.append(job)
        return job

    def due(self, now: float, is_reachable) -> list[ForwardJob]:
        """Jobs waiting for a target that is reachable now: send their inner message."""
        return [j for j in self.jobs if j.state is JobState.WAITING and is_reachable(j.target, now)]

    def sent(self, job: ForwardJob, seq: int) -> None:
        job.state, job.sent_seq = JobState.SENT, seq
        job.sends += 1

    def confirmed(self, src: int, ref_seq: int) -> JobEnded | None:
        """The target answered the inner message: the job is done."""
        job = self._sent_job(src, ref_seq)
        if job is None:
            return None
        self.jobs.remove(job)
        return JobEnded(job, ResultCode.DONE, Reason.NONE)

    def undelivered(self, dst: int, seq: int) -> bool:
        """All sends of the inner message went unanswered: wait for the target again. False if
        (dst, seq) was not a forwarded message."""
        job = self._sent_job(dst, seq)
        if job is None:
            return False
        job.state, job.sent_seq = JobState.WAITING, None
        return True

    def expired(self, now: float) -> list[JobEnded]:
        ended = []
        for job in [j for j in self.jobs if now >= j.deadline_s]:
            self.jobs.remove(job)
            ended.append(JobEnded(job, ResultCode.FAILED, Reason.NOT_DELIVERED if job.sends else Reason.TIMEOUT))
        return ended

    def _sent_job(self, target: int, seq: int) -> ForwardJob | None:
        return next((j for j in self.jobs if j.state is JobState.SENT and j.target == target and j.sent_seq == seq),
                    None)
