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
#   SENT    --target answers a final result--------> removed, S gets that result and reason (see below)
#   SENT    --target ACCEPTED a command that reports progress (Goto, Return, MoveAround, ShowScan,
#             ShowCam, LandOnTop)---------------------> RUNNING, S gets IN_PROGRESS; the deadline
#                                                    becomes accepted + result_timeout_s
#   RUNNING --target reports IN_PROGRESS-----------> S gets IN_PROGRESS with the target's progress
#   RUNNING --target reports a final result--------> removed, S gets that result and reason
#   SENT    --DeliveryFailed (all sends unanswered)-> WAITING (try again when reachable)
#   any     --deadline------------------------------> removed, S gets FAILED: TIMEOUT if never
#                                                    sent or never finished, NOT_DELIVERED if
#                                                    sent but unconfirmed
#
# So S's result is the inner command's own outcome, end to end: DONE when the target finished it.
# A command that does not report progress (Stop, Follow, a ForwardMsg) and Data end with the
# target's first answer. After the forwarder's own ACCEPTED only IN_PROGRESS, DONE, FAILED or
# CANCELLED may follow (docs/protocol.md, result transitions), so the target's answer is mapped:
# ACCEPTED (a Follow taken, Data arrived) and DONE -> DONE; FAILED and CANCELLED as they are;
# DENIED, UNSUPPORTED and TEMPORARILY_REJECTED -> FAILED with the target's reason (BAD_REQUEST
# when it gave none). Data the target sends in answer to the inner command (a ShowScan's scans) is forwarded
# to S as Data answering S's ForwardMsg (ref_seq = the ForwardMsg's seq).
#
# A ForwardMsg equal to an open job's (same sender, target and inner message) under a new seq is
# that job asked again (its sender gave the first copy up unconfirmed and retried): it is answered
# ACCEPTED, and the job's reports go to the new seq. Otherwise the target would get the inner
# command twice, and the second would replace the first.
#
# The inner message leaves from the forwarder's own address (it is the one that will get the
# Confirm); a long one (over 9 bytes, or a Data) is segmented by the mesh layer like any frame.

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from rescuemesh.protocol import BROADCAST, FrameError, Reason, ResultCode
from rescuemesh.protocol.codec import decode_inner
from rescuemesh.protocol.messages import Data, Message, is_command
from rescuemesh.robot.commands import traits

#: Results after which the target does no more with a command (MAVLink: anything but IN_PROGRESS
#: and, for a long-running command, ACCEPTED).
FINAL_RESULTS = frozenset({ResultCode.DONE, ResultCode.FAILED, ResultCode.CANCELLED, ResultCode.DENIED,
                           ResultCode.UNSUPPORTED, ResultCode.TEMPORARILY_REJECTED})


class JobState(Enum):
    WAITING = "waiting"
    SENT = "sent"
    RUNNING = "running"  # the target accepted a long-running command: its result is awaited


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
    """What to report to the job's sender, finally: `result` with `reason`."""

    job: ForwardJob
    result: ResultCode
    reason: Reason
    progress: int = 255


@dataclass(frozen=True, slots=True)
class JobProgress:
    """The target runs the forwarded command: report IN_PROGRESS with `progress` to the sender."""

    job: ForwardJob
    progress: int


class Forwarder:
    """The jobs of one robot. `timeout_s`: how long a job is held, in s; `capacity`: how many at once."""

    def __init__(self, own_address: int, *, timeout_s: float = 30.0, capacity: int = 8,
                 result_timeout_s: float = 600.0) -> None:
        if not timeout_s > 0.0 or capacity < 1 or not result_timeout_s > 0.0:
            raise ValueError(f"forwarding needs timeouts > 0 and capacity >= 1, got {timeout_s!r}, {capacity!r}, "
                             f"{result_timeout_s!r}")
        self.own_address = own_address
        self.timeout_s = timeout_s
        self.result_timeout_s = result_timeout_s
        self.capacity = capacity
        self.jobs: list[ForwardJob] = []
        #: Jobs that ended lately, by (target, inner seq): data the target sent before its final
        #: report but that arrives after it (a segmented scan is slower than a Confirm) still finds
        #: the robot that asked. Bounded: the last `capacity` jobs.
        self._ended: dict[tuple[int, int], ForwardJob] = {}

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
        same = next((j for j in self.jobs if (j.sender, j.target, j.inner) == (sender, target, inner)), None)
        if same is not None:  # the sender asked again (it gave its first copy up): the same job, reported to the new seq
            same.seq = seq
            return same
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

    def confirmed(self, src: int, ref_seq: int, result: ResultCode, reason: Reason, progress: int,
                  now: float) -> JobEnded | JobProgress | None:
        """The target answered or reported on the inner message: what to tell the job's sender
        (None: `src`/`ref_seq` is not a forwarded message)."""
        job = self._sent_job(src, ref_seq)
        if job is None:
            return None
        long_running = is_command(job.inner) and traits(job.inner.TYPE).reports_progress
        if long_running and result not in FINAL_RESULTS:
            if job.state is JobState.SENT:
                job.state, job.deadline_s = JobState.RUNNING, now + self.result_timeout_s
            return JobProgress(job, progress if result == ResultCode.IN_PROGRESS else 0)
        self._end(job)
        if result in (ResultCode.ACCEPTED, ResultCode.DONE):  # a short command taken, data arrived, a drive done
            return JobEnded(job, ResultCode.DONE, Reason.NONE if result == ResultCode.ACCEPTED else reason, 100)
        if result in (ResultCode.FAILED, ResultCode.CANCELLED):
            return JobEnded(job, result, reason, progress)
        # DENIED, UNSUPPORTED, TEMPORARILY_REJECTED: after our ACCEPTED only FAILED may say it
        return JobEnded(job, ResultCode.FAILED, reason if reason is not Reason.NONE else Reason.BAD_REQUEST, progress)

    def answering(self, src: int, ref_seq: int) -> ForwardJob | None:
        """The job (running, or ended lately) whose inner command `src` answers with Data (ref_seq:
        the inner frame's seq)."""
        return self._sent_job(src, ref_seq) or self._ended.get((src, ref_seq))

    def _end(self, job: ForwardJob) -> None:
        self.jobs.remove(job)
        self._ended[(job.target, job.sent_seq)] = job
        while len(self._ended) > self.capacity:
            del self._ended[next(iter(self._ended))]

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
            unconfirmed = job.sends and job.state is not JobState.RUNNING
            ended.append(JobEnded(job, ResultCode.FAILED, Reason.NOT_DELIVERED if unconfirmed else Reason.TIMEOUT))
        return ended

    def _sent_job(self, target: int, seq: int) -> ForwardJob | None:
        return next((j for j in self.jobs if j.state is not JobState.WAITING and j.target == target
                     and j.sent_seq == seq), None)
