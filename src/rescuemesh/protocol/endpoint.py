"""The sans-IO endpoint, one per robot (aioquic's QuicConnection shape): calls and received bytes in;
frames to send, a timer and events out. Must not know sockets, radios, clocks or threads: every
entry point takes `now` in s, and the caller moves the bytes (docs/design.md, docs/protocol.md).
"""

from __future__ import annotations

from collections import OrderedDict, deque
from dataclasses import replace

from .codec import (BROADCAST, MAX_ATTEMPT, MAX_CONTROL_FRAME_BYTES, MAX_EPOCH, MAX_SEQ,
                    MAX_UNICAST_ADDRESS, PROTOCOL_VERSION, TYPE_MASK, FrameFlags, Header, decode_frame, encode_frame)
from .errors import FrameError
from .events import (
    CommandReceived,
    ConfirmReceived,
    DataReceived,
    DeliveryFailed,
    EndpointEvent,
    FrameRejected,
    PoseUpdateReceived,
    heartbeat_received,
)
from .messages import (
    COMMAND_TYPES,
    PROGRESS_UNKNOWN,
    Command,
    Confirm,
    Data,
    DataKind,
    Heartbeat,
    Message,
    MessageType,
    Pose,
    PoseUpdate,
    Reason,
    ResultCode,
    is_command,
)
from .endpoint_config import EndpointConfig, EndpointStats
from .reliability import DuplicateCache, RetransmissionQueue, TimeoutAction, Verdict


#: Results after which a command's final report is still to come.
_INTERIM = frozenset({ResultCode.ACCEPTED, ResultCode.IN_PROGRESS})
#: Commands awaiting a final report, at most (the oldest are forgotten first).
MAX_OPEN_COMMANDS = 256
#: Heartbeats repeated for one robot that has not answered us, at most, per epoch of ours
#: (docs/protocol.md section 7): each costs a broadcast, and a robot that knows our epoch but
#: whose Confirms are lost would otherwise draw one at every resend.
EPOCH_ANNOUNCEMENTS_PER_PEER = 3


class Endpoint:
    """One robot's protocol state. Drive it with:

    - send_command / send_pose_update / send_heartbeat / confirm, and receive(data, now) for each
      frame heard;
    - frames_to_send(now) after any of those, to get the bytes to transmit;
    - get_timer() and handle_timer(now) when that time comes, for resends and give-ups;
    - next_event() until None, to learn what happened.
    """

    def __init__(self, address: int, config: EndpointConfig | None = None) -> None:
        if not (isinstance(address, int) and 0 <= address <= MAX_UNICAST_ADDRESS):
            raise ValueError(f"address must be 0..{MAX_UNICAST_ADDRESS}, got {address!r}")
        self.address = address
        self.config = config if config is not None else EndpointConfig()
        self.stats = EndpointStats()
        self._seq = self.config.initial_seq
        #: This endpoint's epoch (docs/protocol.md section 12): persisted boot counter + seq wraps.
        self.epoch = self.config.initial_epoch
        self._numbered = False  # no number handed out yet (seq 0 then opens no new epoch)
        self._outbox: list[tuple[bytes, int]] = []  # (frame, epoch it was numbered in)
        self._open: OrderedDict[tuple[int, int], MessageType] = OrderedDict()  # awaiting a final report
        self._events: deque[EndpointEvent] = deque()
        self._pending = RetransmissionQueue(self.config.reliability)
        self._seen = DuplicateCache(self.config.reliability)
        # received message type -> handler; every MessageType has one
        self._handlers = {t: self._on_command for t in COMMAND_TYPES}
        self._handlers[MessageType.POSE_UPDATE] = self._on_pose_update
        self._handlers[MessageType.CONFIRM] = self._on_confirm
        self._handlers[MessageType.HEARTBEAT] = self._on_heartbeat
        self._handlers[MessageType.DATA] = self._on_data
        self._handlers[MessageType.SEGMENT_ACK] = self._on_mesh_control
        self._path_hops: dict[int, int] = {}
        self._hops = 1  # hops of the frame being handled, for its events
        self._answered: set[int] = set()  # robots whose Confirm matched a frame of ours: they know our epoch
        self._announced: dict[int, int] = {}  # Heartbeats repeated for each robot not yet in _answered
        self._heartbeat: tuple[int, int] | None = None  # our latest Heartbeat's (active_command, capabilities)
        self._heartbeat_s = float("-inf")  # when it was queued

    # --- sending -------------------------------------------------------------------------------

    def send_command(self, dst: int, command: Command, now: float) -> int:
        """Queue `command` to robot `dst`, confirmed and retried; returns its sequence number.

        Raises ValueError for a non-command or a broadcast/own/out-of-range `dst`, EncodeError (a
        ValueError) for values that do not fit the wire format.
        """
        if not is_command(command):
            raise ValueError(f"not a command: {command!r}")
        return self._send_confirmable(dst, command, now)

    def send_pose_update(self, dst: int, pose: Pose, now: float) -> int:
        """Queue a PoseUpdate to follower `dst`, confirmed and retried like a command; returns its seq."""
        return self._send_confirmable(dst, PoseUpdate(pose), now)

    def send_data(self, dst: int, kind: DataKind, ref_seq: int, data: bytes, now: float) -> int:
        """Queue bulk `data` (answering our command `ref_seq` of `dst`'s) to `dst`, confirmed and
        retried; a frame longer than a control frame is segmented by the mesh layer. Returns its seq."""
        return self._send_confirmable(dst, Data(kind, ref_seq, bytes(data)), now)

    def set_path_hops(self, dst: int, hops: int | None) -> None:
        """Tell the endpoint how many hops away `dst` is (the mesh layer learns it from heartbeats):
        frames to it wait `per_hop_timeout_s` longer per hop beyond the first. None forgets it."""
        if hops is None or hops <= 1:
            self._path_hops.pop(dst, None)
        else:
            self._path_hops[dst] = int(hops)

    def confirm_timeout_s(self, dst: int, frame_bytes: int) -> float:
        """How long, in s, a frame of `frame_bytes` to `dst` waits for its Confirm before a resend."""
        rel = self.config.reliability
        timeout = rel.ack_timeout_s + rel.per_hop_timeout_s * (self._path_hops.get(dst, 1) - 1)
        if frame_bytes > MAX_CONTROL_FRAME_BYTES:  # segmented: 16 frame bytes per segment (docs/mesh.md)
            segments = -(-(frame_bytes - 6) // 16)  # each crosses every hop: the time grows with both
            timeout += rel.per_segment_timeout_s * segments * self._path_hops.get(dst, 1)
        return timeout

    def send_heartbeat(self, now: float, active_command: int = 0, capabilities: int = 0) -> None:
        """Queue a broadcast Heartbeat (not confirmed, not retried). `active_command`: a command's
        MessageType value, 0 when idle; `capabilities`: Capability bits of this robot."""
        seq = self.allocate_seq()
        ttl = self.config.initial_ttl if self.config.heartbeat_ttl is None else self.config.heartbeat_ttl
        self._queue(self._encode(BROADCAST, seq, Heartbeat(active_command, ttl, self.epoch, capabilities), ttl))
        self._heartbeat, self._heartbeat_s = (active_command, capabilities), now

    def allocate_seq(self) -> int:
        """The next sequence number of this endpoint, for any frame it originates (the mesh layer's
        SegmentAcks too: one counter per robot, so replay protection sees one sequence). At the
        wrap 65535 -> 0 a new epoch starts and every frame still awaiting its Confirm is given up
        (DeliveryFailed): its resends would reuse an old number in the new epoch."""
        seq = self._seq
        if seq == 0 and self._numbered:  # the counter came round: number 0 opens a new epoch
            self._new_epoch()
        self._numbered = True
        self._seq = (seq + 1) & MAX_SEQ
        return seq

    def confirm(
        self,
        dst: int,
        ref_seq: int,
        ref_type: MessageType,
        result: ResultCode,
        now: float,
        progress: int = PROGRESS_UNKNOWN,
        reason: Reason = Reason.NONE,
    ) -> None:
        """Answer frame `ref_seq` from `dst` (progress 0-100 %, 255 unknown; `reason` why it ended).

        The Confirm is cached for (dst, ref_seq): a resend of that frame gets it again. A later call
        for the same frame (IN_PROGRESS, DONE, FAILED, CANCELLED) replaces the cached Confirm and is
        sent once, unsolicited. Raises ValueError for a report RESULT_TRANSITIONS forbids (anything
        after a final result) or a ref_type that does not match the frame, EncodeError for bad values.
        """
        self._check_unicast(dst)
        message = Confirm(ref_seq, ref_type, result, progress, reason)
        frame = self._encode(dst, self._seq, message)  # EncodeError before anything changes
        self._seen.check_report(dst, ref_seq, ref_type, result)
        self._seen.record_confirm(dst, ref_seq, result, message)
        self._send_confirm(dst, message)

    def repeat_report(self, dst: int, ref_seq: int) -> bool:
        """Send the latest report on `ref_seq` from `dst` again (final results are not confirmed:
        repeating makes their loss unlikely). False if nothing was reported or it is forgotten."""
        entry = self._seen.lookup(dst, ref_seq)
        if entry is None or entry.confirm_frame is None:
            return False
        self._send_confirm(dst, entry.confirm_frame)
        return True

    def answer_resend(self, src: int, seq: int, now: float) -> None:
        """`src` resent its frame `seq` below us (the mesh layer saw segments of a frame it had
        reassembled): answer it as a resend we hear, with the cached Confirm if there is one."""
        if self._seen.lookup(src, seq) is None:
            return
        self.stats.duplicates += 1
        self._announce_epoch(src, now)
        self.repeat_report(src, seq)

    def awaits(self, dst: int, seq: int) -> bool:
        """True while our frame `seq` to `dst` waits for its Confirm (sent, not confirmed, not given
        up, not cancelled): the mesh layer ends a segmented frame's transfer once this is False."""
        return (dst, seq) in self._pending

    def cancel_pending(self, dst: int | None = None) -> int:
        """Stop retrying the frames to `dst` (all if None), without DeliveryFailed; returns how many."""
        return len(self._pending.cancel(dst))

    def forget_peer(self, src: int) -> None:
        """`src` restarted (the mesh layer saw a new epoch from it): its old sequence numbers mean
        nothing now, so forget what was seen from it and what it still owed us reports for."""
        self._seen.forget(src)
        self._answered.discard(src)  # it rebooted: it knows no epoch of ours any more
        self._announced.pop(src, None)
        for key in [k for k in self._open if k[0] == src]:
            del self._open[key]

    # --- the aioquic loop ----------------------------------------------------------------------

    def receive(self, data: bytes, now: float, hops: int = 1) -> None:
        """Handle one received frame that crossed `hops` radio hops (the mesh layer knows; 1 without
        one). Never raises for any bytes: a bad frame becomes a FrameRejected event and a
        `frames_rejected` count."""
        self.stats.frames_received += 1
        try:
            header, message = decode_frame(data)
        except FrameError as exc:
            self.stats.frames_rejected += 1
            self._events.append(FrameRejected(str(exc), type(exc).__name__, now))
            return
        if header.src == self.address or (header.dst != self.address and header.dst != BROADCAST):
            self.stats.frames_not_for_us += 1
            return
        self._hops = hops
        self._handlers[header.msg_type](header, message, now)

    def frames_to_send(self, now: float) -> list[bytes]:
        """Drain the frames queued since the last call, oldest first."""
        return [frame for frame, _ in self.drain(now)]

    def drain(self, now: float) -> list[tuple[bytes, int]]:
        """The same as frames_to_send, each frame with the epoch it was numbered in (what an
        authenticated frame's nonce needs)."""
        frames, self._outbox = self._outbox, []
        stats = self.stats
        for frame, _ in frames:
            size = len(frame)
            stats.frames_sent += 1
            stats.bytes_sent += size
            if frame[3] == BROADCAST:
                stats.broadcasts_sent += 1
            if size > stats.max_frame_bytes:
                stats.max_frame_bytes = size
            if frame[1] & TYPE_MASK == MessageType.CONFIRM:
                stats.confirms_sent += 1
        return frames

    def get_timer(self) -> float | None:
        """Time in s at which handle_timer() has work (the earliest resend deadline), or None."""
        return self._pending.next_deadline()

    def handle_timer(self, now: float) -> None:
        """Resend every frame whose deadline has passed (same seq, attempt bits raised), or give up
        after max_sends sends with a DeliveryFailed event."""
        for action, frame in self._pending.expire(now):
            if action is TimeoutAction.RESEND:
                self._announce_epoch(frame.dst, now)
                attempt = min(frame.sends - 1, MAX_ATTEMPT)
                self._queue(encode_frame(replace(frame.header, attempt=attempt), frame.message))
                self.stats.retries += 1
            else:
                self.stats.delivery_failures += 1
                self._events.append(DeliveryFailed(frame.dst, frame.seq, frame.message, frame.sends, now))

    def next_event(self) -> EndpointEvent | None:
        """The oldest event not yet pulled, or None."""
        return self._events.popleft() if self._events else None

    # --- internals -----------------------------------------------------------------------------

    def _check_unicast(self, dst: int) -> None:
        if not (isinstance(dst, int) and 0 <= dst <= MAX_UNICAST_ADDRESS):
            raise ValueError(f"destination must be a robot address 0..{MAX_UNICAST_ADDRESS}, got {dst!r}")
        if dst == self.address:
            raise ValueError(f"destination {dst} is this endpoint's own address")

    def _header(self, dst: int, seq: int, message: Message, ttl: int | None = None) -> Header:
        ttl = self.config.initial_ttl if ttl is None else ttl
        return Header(PROTOCOL_VERSION, FrameFlags.NONE, ttl, 0, message.TYPE, self.address, dst, seq)

    def _encode(self, dst: int, seq: int, message: Message, ttl: int | None = None) -> bytes:
        return encode_frame(self._header(dst, seq, message, ttl), message)

    def _queue(self, frame: bytes) -> None:
        self._outbox.append((frame, self.epoch))

    def _announce_epoch(self, peer: int, now: float) -> None:
        """Before a frame to `peer` that answers a sign it missed ours (our resend, or its resend
        of what we confirmed): our latest Heartbeat again, under a fresh number, so a robot that
        missed our Heartbeats can open what follows. Not for a robot that has answered one of our
        frames; at most EPOCH_ANNOUNCEMENTS_PER_PEER times a robot; a Heartbeat that went out
        within ack_timeout_s serves instead. Only with EndpointConfig.announce_epoch_on_resend."""
        if not self.config.announce_epoch_on_resend:
            return
        count = self._announced.get(peer, 0)
        if peer in self._answered or self._heartbeat is None or count >= EPOCH_ANNOUNCEMENTS_PER_PEER:
            return
        self._announced[peer] = count + 1
        if now - self._heartbeat_s >= self.config.reliability.ack_timeout_s:
            self.stats.epoch_announcements += 1
            self.send_heartbeat(now, *self._heartbeat)

    def _send_confirm(self, dst: int, message: Confirm) -> None:
        """A Confirm always goes out under a fresh sequence number, a cached one re-sent too, so
        that replay protection, which accepts each number once, lets it through."""
        self._queue(self._encode(dst, self.allocate_seq(), message))

    def _new_epoch(self) -> None:
        self.epoch = (self.epoch + 1) & MAX_EPOCH
        self._answered.clear()  # nobody knows the new epoch before our next Heartbeat
        self._announced.clear()
        self.stats.epochs += 1
        for frame in self._pending.cancel(None):
            self.stats.delivery_failures += 1
            self._events.append(DeliveryFailed(frame.dst, frame.seq, frame.message, frame.sends, frame.last_sent_s))

    def _send_confirmable(self, dst: int, message: Message, now: float) -> int:
        self._check_unicast(dst)
        header = self._header(dst, self._seq, message)
        frame = encode_frame(header, message)  # EncodeError before the number is spent
        seq = self.allocate_seq()
        self._pending.add(dst, seq, header, message, now, self.confirm_timeout_s(dst, len(frame)))
        self._queue(frame)
        return seq

    def _is_new(self, header: Header, message: Message, now: float) -> bool:
        verdict, cached_confirm = self._seen.observe(header.src, header.seq, message, now)
        if verdict is Verdict.NEW:
            return True
        self.stats.duplicates += 1
        if cached_confirm is not None:  # Verdict.DUPLICATE_ANSWERED: our Confirm was lost
            self._announce_epoch(header.src, now)  # it lost our Confirm, or could not open it
            self._send_confirm(header.src, cached_confirm)
        return False

    def _on_command(self, header: Header, message: Command, now: float) -> None:
        if self._is_new(header, message, now):
            self._events.append(CommandReceived(header.src, header.seq, message, now, self._hops))

    def _on_pose_update(self, header: Header, message: PoseUpdate, now: float) -> None:
        if self._is_new(header, message, now):
            self._events.append(PoseUpdateReceived(header.src, header.seq, message.pose, now, self._hops))

    def _on_confirm(self, header: Header, message: Confirm, now: float) -> None:
        """A Confirm counts only if it answers a frame we still retry, or reports on a command whose
        final result we still await, from the robot we sent it to; any other is dropped and counted
        (it can never cancel a resend). Commands answered with an interim result stay open for their
        final report (bounded: the oldest open ones are forgotten first)."""
        key = (header.src, message.ref_seq)
        frame = self._pending.acknowledge(header.src, message.ref_seq, message.ref_type)
        if frame is not None:
            self._answered.add(header.src)
            solicited, sends, rtt_s = True, frame.sends, now - frame.last_sent_s
            if message.result in _INTERIM and message.ref_type in COMMAND_TYPES:
                self._open[key] = message.ref_type
                while len(self._open) > MAX_OPEN_COMMANDS:
                    self._open.popitem(last=False)
        elif self._open.get(key) == message.ref_type:  # a later result report
            solicited, sends, rtt_s = False, 0, None
            if message.result not in _INTERIM:
                del self._open[key]
        else:
            self.stats.confirms_unmatched += 1
            return
        self.stats.confirms_received += 1
        self._events.append(
            ConfirmReceived(
                header.src, message.ref_seq, message.ref_type, message.result, message.progress,
                solicited, sends, rtt_s, now, message.reason, self._hops,
            )
        )

    def _on_heartbeat(self, header: Header, message: Heartbeat, now: float) -> None:
        self._events.append(heartbeat_received(header.src, message.active_command, now, self._hops, message.capabilities))

    def _on_data(self, header: Header, message: Data, now: float) -> None:
        if self._is_new(header, message, now):
            self._events.append(DataReceived(header.src, header.seq, message.kind, message.ref_seq, message.data, now,
                                             self._hops))

    def _on_mesh_control(self, header: Header, message, now: float) -> None:
        """SegmentAcks belong to the mesh layer below; one that reaches the endpoint is not for it."""
        self.stats.frames_not_for_us += 1
