"""How a robot's brain treats link loss and final reports: the paper's pause, reconnect window and
give-up (IV.A) as each command type's link-loss policy allows, and final reports sent in copies and
held for a commander out of reach (robot/custody.py) until it is heard again.

Owns: these handlers, as a mixin of RobotBrain (robot/brain.py), on the brain's own state. Must not
know: the simulator, the transport, the clock (handed `now`).
"""

from __future__ import annotations

from rescuemesh.mesh import NeighbourFound, NeighbourLost
from rescuemesh.protocol import MessageType, Reason, ResultCode
from rescuemesh.robot import events as ev
from rescuemesh.robot.behaviours import NavigateBehaviour
from rescuemesh.robot.custody import HeldReport
from rescuemesh.robot.records import LinkLossPolicy, Running


class LinkLossAndReports:
    """Link loss and final reports; RobotBrain provides the state (config, running, streams,
    lost_peers, custody, endpoint, network, body) and `_note`, `_start`, `_end_running`, `command_stop`."""

    # ----- link loss (paper IV.A): pause, reconnect window, give up -----

    def _shares_command_with(self, peer: int) -> bool:
        running = self.running
        return (running is not None and running.commander == peer) or peer in self.streams

    def _on_neighbour_lost(self, event: NeighbourLost, now: float) -> None:
        peer = event.address
        if not self._shares_command_with(peer) or peer in self.lost_peers:
            return
        running = self.running
        if running is not None and running.commander == peer and peer not in self.streams:
            policy = self.config.policy_for(running.msg_type)
            if policy is LinkLossPolicy.CONTINUE:
                self._note(ev.LinkLost(now, self.name, peer, event.last_heard_s, policy, running.behaviour.name))
                return
            if policy is LinkLossPolicy.RETURN_TO_BASE:
                self._note(ev.LinkLost(now, self.name, peer, event.last_heard_s, policy))
                self._end_running(now, ResultCode.FAILED, Reason.LINK_LOST, "link lost: returned to base")
                base = self.config.base if self.config.base is not None else self.body.pose()
                self._start(Running(NavigateBehaviour(self.nav, base, now), now), now)
                return
        self.lost_peers[peer] = now + self.config.reconnect_window_s
        if running is not None and running.commander == peer:
            running.behaviour.pause(now)
            running.paused_for_link = True
            self.body.set_velocity(0.0, 0.0)
        if peer in self.streams:
            self.streams[peer].paused = True
        self._note(ev.LinkLost(now, self.name, peer, event.last_heard_s, LinkLossPolicy.HOLD,
                               window_s=self.config.reconnect_window_s))

    def _on_neighbour_found(self, event: NeighbourFound, now: float) -> None:
        peer = event.address
        if self.lost_peers.pop(peer, None) is None:
            return
        if self.running is not None and self.running.commander == peer and self.running.paused_for_link:
            self.running.behaviour.resume(now)
            self.running.paused_for_link = False
        stream = self.streams.get(peer)
        if stream is not None:
            stream.paused, stream.last_confirmed_s = False, now
            stream.next_send_s = now
        self._note(ev.LinkResumed(now, self.name, peer, event.hops))

    def _end_lost_links(self, now: float) -> None:
        for peer, deadline in list(self.lost_peers.items()):
            if now < deadline:
                continue
            del self.lost_peers[peer]
            if self.running is not None and self.running.commander == peer and self.running.paused_for_link:
                self._end_running(now, ResultCode.FAILED, Reason.LINK_LOST, "link lost")
            if peer in self.streams:
                self._end_stream(peer, now, Reason.LINK_LOST)
        for peer, stream in list(self.streams.items()):
            if not stream.paused and now - stream.last_confirmed_s > self.config.partner_give_up_s:
                self._end_stream(peer, now, Reason.PARTNER_SILENT, silent_s=now - stream.last_confirmed_s)

    def _end_stream(self, peer: int, now: float, reason: Reason, silent_s: float | None = None) -> None:
        stream = self.streams.pop(peer)
        sent = self.outgoing.get(stream.follow_seq)
        if sent is not None:
            sent.result, sent.reason = ResultCode.FAILED, reason
        self.commands_failed += 1
        self._note(ev.FollowGivenUp(now, self.name, peer, reason, silent_s))
        self.command_stop(peer, now, automatic=True)  # best effort: "both sides stop it"

    # ----- final reports: copies, and custody for a commander out of reach -----

    def _repeat_final_reports(self, now: float) -> None:
        due, self._repeats = [r for r in self._repeats if r[0] <= now], [r for r in self._repeats if r[0] > now]
        for _, commander, seq, left in due:
            if self.endpoint.repeat_report(commander, seq) and left > 1:
                self._repeats.append((now + self.config.final_report_spacing_s, commander, seq, left - 1))

    def _final_report(self, commander: int, seq: int, msg_type: MessageType, result: ResultCode, code: Reason,
                      now: float, progress: int) -> None:
        """Report a command's final result to its commander: an unsolicited Confirm, not confirmed
        in turn, so it goes out `final_report_copies` times, `final_report_spacing_s` apart."""
        self._send_final_report(commander, seq, msg_type, result, code, now, progress)
        if not self.network.is_reachable(commander, now):  # its copies are likely lost: keep it
            self.custody.hold(HeldReport(commander, seq, msg_type, result, code, progress, now))
            self._note(ev.ReportHeld(now, self.name, msg_type, result, commander))

    def _send_final_report(self, commander: int, seq: int, msg_type: MessageType, result: ResultCode, code: Reason,
                           now: float, progress: int) -> None:
        self.endpoint.confirm(commander, seq, msg_type, result, now, progress=progress, reason=code)
        if self.config.final_report_copies > 1:
            self._repeats.append((now + self.config.final_report_spacing_s, commander, seq,
                                  self.config.final_report_copies - 1))

    def _deliver_held_reports(self, now: float) -> None:
        """Held final reports whose commander is reachable again go out (in copies); old ones are dropped."""
        copies, spacing = self.config.final_report_copies, self.config.final_report_spacing_s
        for r in self.custody.due(now, self.network.is_reachable):
            if not self.endpoint.repeat_report(r.commander, r.seq):  # the endpoint forgot it: report afresh
                self.endpoint.confirm(r.commander, r.seq, r.msg_type, r.result, now, progress=r.progress,
                                      reason=r.reason)
            if copies > 1:
                self._repeats.append((now + spacing, r.commander, r.seq, copies - 1))
            self._note(ev.ReportDelivered(now, self.name, r.msg_type, r.result, r.commander, now - r.held_s))
        for r in self.custody.expired(now):
            self._note(ev.ReportDropped(now, self.name, r.msg_type, r.result, r.commander, self.custody.hold_s))
