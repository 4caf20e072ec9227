"""Final reports kept for a commander out of reach, delivered when it is heard again (store and
forward, as ForwardMsg holds messages), so that a commander learns how its command ended.

Owns: the bounded store of held reports and its rules. Must not know: the wire, the radio, the
clock (handed `now`). The brain hands it reports and asks which are due.
"""

# Theory of operation
# ===================
#
# A final report (DONE, FAILED, CANCELLED, ...) is an unsolicited Confirm: nobody confirms it, so
# it goes out in copies (BrainConfig.final_report_copies). When its commander is not reachable at
# that moment (lost by the mesh layer's heartbeat rule), every copy is likely lost: the brain also
# hands the report here. Once the commander is reachable again (heard, not lost), the report is
# sent again, in copies, and leaves the store. A newer report on the same (commander, seq) replaces
# the older one. The store holds `capacity` reports (the oldest is dropped for a new one) for at
# most `hold_s` each; what is dropped is counted.
#
# Limit: a report sent in the few seconds between a commander falling silent and the mesh layer
# declaring it lost (3.5 s by default) is not held: its copies go out as usual.

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from rescuemesh.protocol import MessageType, Reason, ResultCode


@dataclass(frozen=True, slots=True)
class HeldReport:
    """A final report waiting for its commander: what to send again, and since when (s)."""

    commander: int
    seq: int
    msg_type: MessageType
    result: ResultCode
    reason: Reason
    progress: int
    held_s: float


class ReportCustody:
    """Held final reports of one robot. `capacity`: how many at once; `hold_s`: how long each, in s."""

    def __init__(self, *, capacity: int = 16, hold_s: float = 600.0) -> None:
        if capacity < 1 or not hold_s > 0.0:
            raise ValueError(f"report custody needs capacity >= 1 and hold_s > 0, got {capacity!r}, {hold_s!r}")
        self.capacity, self.hold_s = capacity, hold_s
        self.reports: list[HeldReport] = []
        self.dropped = 0  # reports dropped unsent: the store was full, or they waited past hold_s

    def __len__(self) -> int:
        return len(self.reports)

    def hold(self, report: HeldReport) -> None:
        self.reports = [r for r in self.reports if (r.commander, r.seq) != (report.commander, report.seq)]
        if len(self.reports) >= self.capacity:
            self.reports.pop(0)
            self.dropped += 1
        self.reports.append(report)

    def due(self, now: float, is_reachable: Callable[[int, float], bool]) -> list[HeldReport]:
        """Reports whose commander is reachable now (they leave the store: send them)."""
        due = [r for r in self.reports if is_reachable(r.commander, now)]
        if due:
            self.reports = [r for r in self.reports if r not in due]
        return due

    def expired(self, now: float) -> list[HeldReport]:
        """Reports held past `hold_s` (they leave the store unsent)."""
        old = [r for r in self.reports if now >= r.held_s + self.hold_s]
        if old:
            self.reports = [r for r in self.reports if r not in old]
            self.dropped += len(old)
        return old
