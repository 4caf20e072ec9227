"""Frame security: AES-CCM against NIST, the worked examples of docs/protocol.md section 12, round
trips of every message type, and rejection of every tampered, truncated, mis-keyed or replayed-under-
another-epoch frame; the fuzzer and the speed figure."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cryptography.hazmat.primitives.ciphers.aead import AESCCM
from hypothesis import given
from hypothesis import strategies as st

from protocol.strategies import frames as protocol_frames  # tests/ is on sys.path (rootdir packages)
from rescuemesh.checks import fuzz
from rescuemesh.mesh.frames import AUTH_BIT, crc_ok, read_on_air, with_ttl
from rescuemesh.mesh.frames import seal as with_crc
from rescuemesh.mesh.keys import derive_frame_key, team_key_from_seed
from rescuemesh.mesh.security import (
    MIC_BYTES,
    AuthenticationError,
    FrameSealer,
    MicMismatch,
    reseal_with_ttl,
    seal_open_rate,
)
from rescuemesh.mesh.segments import make_segment, parse_segment, segment_count
from rescuemesh.protocol import (
    BROADCAST, DataKind, Follow, ForwardMsg, FrameError, Goto, LandOnTop, MessageType, MoveAround, Pose,
    Return, ResultCode, ShowCam, ShowScan, Stop, decode_frame, encode_frame)
from rescuemesh.protocol.codec import FrameFlags, Header, encode_inner
from rescuemesh.protocol.messages import Confirm, Data, PoseUpdate, SegmentAck

DOCS = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"
KEY = derive_frame_key(bytes(range(16)))
SEALER = FrameSealer(KEY)
EPOCH = 0x0102_0304
P = Pose(1.5, -2.25, 0.1, 1.5707963267948966)


def frame_of(message, src=1, dst=2, seq=7, ttl=3, attempt=0) -> bytes:
    return encode_frame(Header(1, FrameFlags.NONE, ttl, attempt, message.TYPE, src, dst, seq), message)


def heartbeat(epoch: int, src: int = 1, seq: int = 9, ttl: int = 3) -> bytes:
    """A 17-byte Heartbeat announcing `epoch` (active_command, init_ttl, epoch, capabilities), by hand."""
    header = bytes((0x40 | ttl, MessageType.HEARTBEAT, src, BROADCAST, seq >> 8, seq & 0xFF))
    return with_crc(header + bytes((1, ttl)) + epoch.to_bytes(4, "big") + bytes((0x16,)))


def epoch_for(frame: bytes, default: int) -> int:
    """The epoch a frame must be sealed with: a 17-byte Heartbeat's own, `default` otherwise."""
    if frame[1] & 0x3F == MessageType.HEARTBEAT and len(frame) == 17:
        return int.from_bytes(frame[8:12], "big")
    return default


LOGICAL_DATA = frame_of(Data(DataKind.LASER_SCAN, 7, b"rescuemesh scan!ranges"), src=2, dst=1, seq=11, ttl=7)
SEGMENTS = [make_segment(LOGICAL_DATA, i, 0) for i in range(segment_count(len(LOGICAL_DATA)))]

#: One CRC frame of every message type (Heartbeat with its epoch) and a segment frame.
EXAMPLES = {
    MessageType.FOLLOW: frame_of(Follow(P)),
    MessageType.SHOW_CAM: frame_of(ShowCam(P, 0.5, 10)),
    MessageType.SHOW_SCAN: frame_of(ShowScan(P, 2.0, 0)),
    MessageType.LAND_ON_TOP: frame_of(LandOnTop(P)),
    MessageType.GOTO: frame_of(Goto(P)),
    MessageType.STOP: frame_of(Stop()),
    MessageType.FORWARD_MSG: frame_of(ForwardMsg(3, encode_inner(Stop()))),
    MessageType.RETURN: frame_of(Return()),
    MessageType.MOVE_AROUND: frame_of(MoveAround(P, 2.0)),
    MessageType.CONFIRM: frame_of(Confirm(7, MessageType.FOLLOW, ResultCode.ACCEPTED), src=2, dst=1, seq=3),
    MessageType.POSE_UPDATE: frame_of(PoseUpdate(P)),
    MessageType.HEARTBEAT: heartbeat(EPOCH),
    MessageType.SEGMENT_ACK: frame_of(SegmentAck(258, 3, 2**47 + 5), src=2, dst=1),
    MessageType.DATA: frame_of(Data(DataKind.IMAGE_JPEG, 7, b"\xff\xd8\xff"), src=2, dst=1),
}
ALL_FRAMES = [*EXAMPLES.values(), *SEGMENTS]
IDS = [t.name for t in EXAMPLES] + [f"segment-{i}" for i in range(len(SEGMENTS))]


def test_every_message_type_has_an_example():
    assert set(EXAMPLES) == set(MessageType)


# --- known answers ------------------------------------------------------------------------------


def test_aes_ccm_matches_nist_sp800_38c_example_1():
    """NIST SP 800-38C, Appendix C, Example 1: a 7-byte nonce and a 4-byte tag, through AESCCM with
    the tag length the sealer uses."""
    ccm = AESCCM(bytes.fromhex("404142434445464748494a4b4c4d4e4f"), tag_length=MIC_BYTES)
    nonce, aad = bytes.fromhex("10111213141516"), bytes.fromhex("0001020304050607")
    plain = bytes.fromhex("20212223")
    assert ccm.encrypt(nonce, plain, aad).hex() == "7162015b" + "4dac255d"
    assert ccm.decrypt(nonce, bytes.fromhex("7162015b4dac255d"), aad) == plain


def _doc_examples() -> list[dict[str, str]]:
    text = DOCS.read_text(encoding="utf-8")
    section = text[text.index("## 12. Authenticated frames"):]
    blocks = re.findall(r"```text\n(.*?)```", section, flags=re.DOTALL)
    examples = []
    for block in blocks:
        fields = dict(line.split(":", 1) for line in block.strip().splitlines())
        examples.append({name.strip(): value.strip() for name, value in fields.items()})
    return [e for e in examples if "sealed" in e]


def _hex(value: str) -> bytes:
    return b"" if value == "(empty)" else bytes.fromhex(value)


def test_docs_worked_examples():
    """docs/protocol.md section 12: every block's frame key, nonce, aad, plaintext and sealed frame
    follow from its team key, epoch and CRC frame, through raw AES-CCM and through FrameSealer."""
    examples = _doc_examples()
    types = set()
    for ex in examples:
        frame, sealed, epoch = _hex(ex["frame"]), _hex(ex["sealed"]), int(ex["epoch"])
        frame_key = derive_frame_key(bytes.fromhex(ex["team key"]))
        assert frame_key.hex() == ex["frame key"]
        assert crc_ok(frame) and len(sealed) == len(frame)
        nonce, aad, plain = _hex(ex["nonce"]), _hex(ex["aad"]), _hex(ex["plaintext"])
        segment_header = sealed[6:9] if frame[0] & 0x10 else bytes(3)
        assert nonce == sealed[:6] + segment_header + epoch.to_bytes(4, "big")
        assert aad == sealed[: len(aad)] and sealed[0] == frame[0] | AUTH_BIT
        assert plain == frame[len(aad):-4]
        assert AESCCM(frame_key, tag_length=4).encrypt(nonce, plain, aad) == sealed[len(aad):]
        sealer = FrameSealer(frame_key)
        assert sealer.seal(frame, epoch) == sealed
        assert sealer.open(sealed, epoch) == frame
        if "relayed with TTL 2" in ex:
            assert reseal_with_ttl(sealer, sealed, epoch, 2) == _hex(ex["relayed with TTL 2"])
        types.add((frame[1] & 0x3F, bool(frame[0] & 0x10)))
    assert {(6, False), (1, False), (32, False), (34, False), (36, True)} <= types


def _doc_error_rows() -> list[tuple[bytes, str, int, str]]:
    text = DOCS.read_text(encoding="utf-8")
    table = text[text.index("### Errors, worked"):]
    rows = re.findall(r"^\| `([0-9A-F ]+)` \| `(seal|open)`, epoch (\d+) \| `(\w+)` \|", table, flags=re.MULTILINE)
    return [(bytes.fromhex(data), call, int(epoch), error) for data, call, epoch, error in rows]


ERRORS = {"ValueError": ValueError, "AuthenticationError": AuthenticationError, "MicMismatch": MicMismatch}


def test_docs_error_table():
    """docs/protocol.md section 12, "Errors, worked": every row raises exactly the class it names."""
    rows = _doc_error_rows()
    assert len(rows) >= 7
    for data, call, epoch, error in rows:
        with pytest.raises(ERRORS[error]) as caught:
            getattr(SEALER, call)(data, epoch)
        assert type(caught.value) is ERRORS[error], (data.hex(" "), call, epoch)


@pytest.mark.parametrize("length", [10, 12, 16, 18, 20])
def test_a_heartbeat_is_sealed_and_opened_at_17_bytes_only(length):
    # this used to seal and open a type-34 frame of any length 10..20 (then dropped as malformed)
    crc_frame = with_crc(heartbeat(7)[:6] + bytes(length - 10))
    with pytest.raises(ValueError):
        SEALER.seal(crc_frame, 7)
    body = bytes((crc_frame[0] | AUTH_BIT,)) + crc_frame[1:-4]
    nonce = body[:6] + bytes(3) + (7).to_bytes(4, "big")
    sealed = body + AESCCM(KEY, tag_length=4).encrypt(nonce, b"", body)  # the MIC a team member would make
    with pytest.raises(AuthenticationError) as caught:
        SEALER.open(sealed, 7)
    assert type(caught.value) is AuthenticationError  # rejected before the MIC check


def test_docs_examples_stay_out_of_the_crc_frame_check():
    """tests/protocol/test_codec.py decodes every bare hex line of docs/protocol.md as a CRC frame;
    section 12's lines carry a prefix, so none of them is picked up (a sealed frame would fail)."""
    text = DOCS.read_text(encoding="utf-8")
    section = text[text.index("## 12. Authenticated frames"):]
    assert re.findall(r"^((?:[0-9A-F]{2} ?)+)$", section, flags=re.MULTILINE) == []


# --- round trips --------------------------------------------------------------------------------


@pytest.mark.parametrize("frame", ALL_FRAMES, ids=IDS)
def test_round_trip_keeps_length_header_and_frame(frame):
    epoch = epoch_for(frame, EPOCH)
    sealed = SEALER.seal(frame, epoch)
    assert len(sealed) == len(frame)
    assert sealed[0] == frame[0] | AUTH_BIT and sealed[1:6] == frame[1:6]
    assert sealed != frame
    assert SEALER.open(sealed, epoch) == frame
    assert SEALER.seal(frame, epoch) == sealed  # deterministic: relays agree byte for byte


@given(protocol_frames(), st.integers(0, 2**32 - 1))
def test_every_codec_frame_round_trips(pair, epoch):
    frame = encode_frame(*pair)
    epoch = epoch_for(frame, epoch)
    sealed = SEALER.seal(frame, epoch)
    assert len(sealed) == len(frame) <= 20
    opened = SEALER.open(sealed, epoch)
    assert opened == frame
    assert decode_frame(opened) == decode_frame(frame)  # the endpoint sees what it would have seen


def test_payload_is_encrypted_heartbeat_is_not():
    follow = EXAMPLES[MessageType.FOLLOW]
    assert SEALER.seal(follow, EPOCH)[6:-4] != follow[6:-4]
    beat = EXAMPLES[MessageType.HEARTBEAT]
    assert SEALER.seal(beat, EPOCH)[6:-4] == beat[6:-4]


@pytest.mark.parametrize(
    "change",
    [
        pytest.param(lambda f: f[:1] + bytes((f[1] | 0x40,)) + f[2:], id="attempt"),
        pytest.param(lambda f: f[:2] + b"\x05" + f[3:], id="src"),
        pytest.param(lambda f: f[:3] + b"\x05" + f[4:], id="dst"),
        pytest.param(lambda f: f[:4] + b"\x01" + f[5:], id="seq-high"),
        pytest.param(lambda f: f[:5] + b"\x08" + f[6:], id="seq-low"),
        pytest.param(lambda f: bytes((f[0] - 1,)) + f[1:], id="ttl"),
    ],
)
def test_every_header_field_is_in_the_nonce(change):
    """The same payload under any other header value is encrypted with another keystream."""
    follow = EXAMPLES[MessageType.FOLLOW]
    other = with_crc(change(follow)[:-4])
    assert other[6:-4] == follow[6:-4]
    assert SEALER.seal(other, EPOCH)[6:-4] != SEALER.seal(follow, EPOCH)[6:-4]


def test_epoch_and_segment_header_are_in_the_nonce():
    follow = EXAMPLES[MessageType.FOLLOW]
    assert SEALER.seal(follow, EPOCH)[6:-4] != SEALER.seal(follow, EPOCH + 1)[6:-4]
    first = SEGMENTS[0]
    moved = with_crc(first[:6] + b"\x00\x10\x01" + first[9:-4])  # same data, SegO 1
    assert SEALER.seal(moved, EPOCH)[9:-4] != SEALER.seal(first, EPOCH)[9:-4]


# --- rejection ----------------------------------------------------------------------------------


@pytest.mark.parametrize("frame", ALL_FRAMES, ids=IDS)
def test_every_single_bit_flip_is_rejected(frame):
    epoch = epoch_for(frame, EPOCH)
    sealed = SEALER.seal(frame, epoch)
    for bit in range(8 * len(sealed)):
        flipped = bytearray(sealed)
        flipped[bit >> 3] ^= 1 << (bit & 7)
        with pytest.raises(AuthenticationError):
            SEALER.open(bytes(flipped), epoch)


@pytest.mark.parametrize("frame", ALL_FRAMES, ids=IDS)
def test_truncated_and_extended_frames_are_rejected(frame):
    epoch = epoch_for(frame, EPOCH)
    sealed = SEALER.seal(frame, epoch)
    for cut in range(len(sealed)):
        for piece in (sealed[:cut], sealed[cut + 1:]):
            with pytest.raises(AuthenticationError):
                SEALER.open(piece, epoch)
    with pytest.raises(AuthenticationError):
        SEALER.open(sealed + b"\x00", epoch)


@pytest.mark.parametrize("frame", ALL_FRAMES, ids=IDS)
def test_wrong_key_and_wrong_epoch_are_rejected(frame):
    epoch = epoch_for(frame, EPOCH)
    sealed = SEALER.seal(frame, epoch)
    other_key = FrameSealer(derive_frame_key(bytes(range(1, 17))))
    with pytest.raises(MicMismatch):
        other_key.open(sealed, epoch)
    with pytest.raises(MicMismatch):
        FrameSealer(bytes(range(16))).open(sealed, epoch)  # the team key used directly: not the frame key
    for wrong in (epoch + 1, epoch - 1, epoch ^ 0x8000_0000):
        with pytest.raises(AuthenticationError):
            SEALER.open(sealed, wrong % 2**32)


@pytest.mark.parametrize("frame", ALL_FRAMES, ids=IDS)
def test_auth_flag_cleared_or_plain_frame_is_rejected(frame):
    epoch = epoch_for(frame, EPOCH)
    sealed = SEALER.seal(frame, epoch)
    with pytest.raises(AuthenticationError, match="not a sealed"):
        SEALER.open(bytes((sealed[0] & ~AUTH_BIT,)) + sealed[1:], epoch)
    with pytest.raises(AuthenticationError):
        SEALER.open(frame, epoch)  # the CRC frame itself
    with pytest.raises(MicMismatch):
        SEALER.open(bytes((frame[0] | AUTH_BIT,)) + frame[1:], epoch)  # AUTH set on a CRC frame


@pytest.mark.parametrize("frame", ALL_FRAMES, ids=IDS)
def test_a_relay_must_reseal_not_rewrite_the_ttl(frame):
    """This is what frames.with_ttl does to a CRC frame: on a sealed frame the MIC no longer fits."""
    epoch = epoch_for(frame, EPOCH)
    sealed = SEALER.seal(frame, epoch)
    ttl = (frame[0] & 0x0F) - 1
    rewritten = bytes(((sealed[0] & 0xF0) | ttl,)) + sealed[1:]
    with pytest.raises(MicMismatch):
        SEALER.open(rewritten, epoch)
    with pytest.raises(AuthenticationError):
        SEALER.open(with_ttl(sealed, ttl), epoch)  # a CRC relay over a sealed frame
    relayed = reseal_with_ttl(SEALER, sealed, epoch, ttl)
    assert relayed[0] == rewritten[0] and relayed[1:6] == sealed[1:6]
    assert SEALER.open(relayed, epoch) == with_ttl(frame, ttl)
    assert reseal_with_ttl(SEALER, sealed, epoch, ttl) == relayed  # two relays, one result
    with pytest.raises(MicMismatch):
        reseal_with_ttl(SEALER, rewritten, epoch, ttl)


@pytest.mark.parametrize("ttl", [-1, 16, 1.0, None])
def test_reseal_ttl_out_of_range(ttl):
    with pytest.raises(ValueError):
        reseal_with_ttl(SEALER, SEALER.seal(EXAMPLES[MessageType.STOP], EPOCH), EPOCH, ttl)


# --- segments and heartbeats --------------------------------------------------------------------


def test_segments_keep_their_segment_header_clear_and_rebuild():
    sealed = [SEALER.seal(s, EPOCH) for s in SEGMENTS]
    assert [len(s) for s in sealed] == [29, 26]
    assert all(s[6:9] == plain[6:9] and s[9:-4] != plain[9:-4] for s, plain in zip(sealed, SEGMENTS))
    opened = [SEALER.open(s, EPOCH) for s in sealed]
    assert opened == SEGMENTS
    pieces = [parse_segment(o).data for o in opened if read_on_air(o)]
    assert LOGICAL_DATA[:6] + b"".join(pieces) == LOGICAL_DATA


def test_a_segment_moved_to_another_index_is_rejected():
    sealed = SEALER.seal(SEGMENTS[0], EPOCH)
    with pytest.raises(MicMismatch):
        SEALER.open(sealed[:6] + b"\x00\x10\x01" + sealed[9:], EPOCH)


def test_retransmitted_segments_differ_by_round_and_repeat_identically():
    rounds = [SEALER.seal(make_segment(LOGICAL_DATA, 0, r), EPOCH) for r in range(5)]
    assert len(set(rounds[:4])) == 4
    assert rounds[4] == rounds[0]  # round 4 is round 0 on the wire: the same bytes, nothing leaks


def test_heartbeat_epoch_is_readable_before_open_and_bound_by_the_mic():
    sealed = SEALER.seal(heartbeat(EPOCH), EPOCH)
    assert FrameSealer.heartbeat_epoch(sealed) == EPOCH
    assert SEALER.open(sealed, FrameSealer.heartbeat_epoch(sealed)) == heartbeat(EPOCH)
    forged = sealed[:8] + (EPOCH + 1).to_bytes(4, "big") + sealed[12:]
    assert FrameSealer.heartbeat_epoch(forged) == EPOCH + 1
    with pytest.raises(MicMismatch):
        SEALER.open(forged, EPOCH + 1)
    with pytest.raises(AuthenticationError, match="announces epoch"):
        SEALER.open(sealed, EPOCH + 1)


def test_a_heartbeat_is_sealed_only_under_the_epoch_it_announces():
    with pytest.raises(ValueError, match="announces epoch"):
        SEALER.seal(heartbeat(5), 6)


@pytest.mark.parametrize(
    "frame",
    [
        pytest.param(heartbeat(EPOCH), id="not-sealed"),
        pytest.param(SEALER.seal(EXAMPLES[MessageType.FOLLOW], EPOCH)[:16], id="not-a-heartbeat"),
        pytest.param(SEALER.seal(heartbeat(EPOCH), EPOCH)[:15], id="short"),
        pytest.param(bytes((0xB3,)) + SEALER.seal(heartbeat(EPOCH), EPOCH)[1:], id="version-2"),
        pytest.param(bytes((0x73,)) + SEALER.seal(heartbeat(EPOCH), EPOCH)[1:], id="seg-flag"),
        pytest.param(b"", id="empty"),
    ],
)
def test_heartbeat_epoch_of_anything_else_is_none(frame):
    assert FrameSealer.heartbeat_epoch(frame) is None


# --- inputs that are not frames -----------------------------------------------------------------


@given(st.binary(max_size=40), st.integers(0, 2**32 - 1))
def test_open_raises_only_authentication_error_for_arbitrary_bytes(data, epoch):
    try:
        SEALER.open(data, epoch)
    except AuthenticationError as exc:
        assert isinstance(exc, FrameError)


@given(st.integers(10, 29), st.binary(min_size=29, max_size=29), st.sampled_from([0x60, 0x70]),
       st.integers(0, 15))
def test_open_raises_only_authentication_error_for_plausible_sealed_frames(n, body, flags, ttl):
    """Byte 0 right (version 1, AUTH, maybe SEG): these reach the length rules and the MIC check."""
    with pytest.raises(AuthenticationError):
        SEALER.open(bytes((flags | ttl,)) + body[1:n], EPOCH)


STOP = EXAMPLES[MessageType.STOP]


@pytest.mark.parametrize(
    "data",
    [
        pytest.param(bytes((0x63,)) + bytes(20), id="unsegmented-21"),
        pytest.param(bytes((0x73,)) + bytes(12), id="segment-13"),
        pytest.param(bytes((0x73,)) + bytes(29), id="segment-30"),
        pytest.param(bytes((0x63,)) + bytes(8), id="9-bytes"),
    ],
)
def test_lengths_outside_the_rules_never_reach_the_mic_check(data):
    with pytest.raises(AuthenticationError) as info:
        SEALER.open(data, EPOCH)
    assert not isinstance(info.value, MicMismatch)


@pytest.mark.parametrize(
    "data",
    [
        pytest.param(STOP[:9], id="short"),
        pytest.param(with_crc(bytes((0x43,)) + bytes(16)), id="unsegmented-21"),
        pytest.param(with_crc(SEGMENTS[0][:-4] + b"\x00"), id="segment-30"),
        pytest.param(SEGMENTS[1][:9] + SEGMENTS[1][-4:], id="segment-13"),
        pytest.param(bytes((0x83,)) + STOP[1:], id="version-2"),
        pytest.param(SEALER.seal(STOP, EPOCH), id="already-sealed"),
        pytest.param(STOP[:-1] + bytes((STOP[-1] ^ 1,)), id="bad-crc"),
    ],
)
def test_seal_refuses_what_is_not_a_crc_frame(data):
    with pytest.raises(ValueError):
        SEALER.seal(data, EPOCH)


@pytest.mark.parametrize("epoch", [-1, 2**32, 1.5, None])
def test_an_epoch_out_of_range_is_a_caller_bug(epoch):
    with pytest.raises(ValueError) as info:
        SEALER.seal(STOP, epoch)
    assert not isinstance(info.value, FrameError)
    with pytest.raises(ValueError) as info:
        SEALER.open(SEALER.seal(STOP, 0), epoch)
    assert not isinstance(info.value, FrameError)  # not counted as a bad frame: a bug upstream


@pytest.mark.parametrize("key", [bytes(15), bytes(32), "00" * 16])
def test_frame_key_must_be_16_bytes(key):
    with pytest.raises(ValueError):
        FrameSealer(key)


def test_from_team_key_derives_the_frame_key():
    team_key = team_key_from_seed(3)
    sealed = FrameSealer.from_team_key(team_key).seal(STOP, EPOCH)
    assert FrameSealer(derive_frame_key(team_key)).open(sealed, EPOCH) == STOP


# --- speed and fuzzing --------------------------------------------------------------------------


class FakeClock:
    def __init__(self, step: float) -> None:
        self.t, self.step = 0.0, step

    def __call__(self) -> float:
        self.t += self.step
        return self.t


def test_seal_open_rate_counts_pairs_per_clock_second():
    rate = seal_open_rate(0.5, FakeClock(1.0))  # one pass: 900 pairs between two readings 1 s apart
    assert rate == 900.0


def test_fuzz_accepts_nothing_and_tries_every_kind():
    report = fuzz.run_fuzz(3000, seed=1, clock=FakeClock(0.0))
    assert report.frames == 3000 and report.accepted == 0 and report.crashes == 0
    assert set(report.by_kind) == set(fuzz.KINDS)
    assert report.mic_checked > 1000


class _AcceptsAnyMic(FrameSealer):
    """This used to be the bug the fuzzer exists for: a MIC failure turned into a frame."""

    def open(self, frame: bytes, epoch: int) -> bytes:
        try:
            return super().open(frame, epoch)
        except MicMismatch:
            return frame


def test_fuzz_catches_a_sealer_that_accepts_forgeries():
    report = fuzz.run_fuzz(2000, seed=1, clock=FakeClock(0.0), make_sealer=_AcceptsAnyMic)
    assert report.accepted > 0 and "accepted" in report.first_failure


def test_fuzz_command_exit_status(capsys):
    assert fuzz.main(["--frames", "500", "--seed", "2"]) == 0
    out = capsys.readouterr().out
    assert "accepted: 0" in out and "frames: 500" in out


def test_fuzz_stops_at_its_time_bound(monkeypatch):
    report = fuzz.run_fuzz(10**6, seed=1, clock=FakeClock(1.0), max_seconds=0.5)
    assert report.timed_out and report.frames == 0
    monkeypatch.setattr(fuzz.time, "perf_counter", FakeClock(1.0))
    assert fuzz.main(["--frames", "100000", "--max-seconds", "0.5"]) == 2


# --- remembered results ---------------------------------------------------------------------------


@given(protocol_frames(), st.integers(0, 2**32 - 1))
def test_a_remembering_sealer_gives_what_a_plain_one_computes(pair, epoch):
    frame = encode_frame(*pair)
    epoch = epoch_for(frame, epoch)
    remembering = FrameSealer(KEY, remember=4)
    for _ in range(2):  # computed, then remembered
        sealed = remembering.seal(frame, epoch)
        assert sealed == SEALER.seal(frame, epoch)
        assert remembering.open(bytearray(sealed), epoch) == frame
    forged = bytes((sealed[0],)) + bytes((sealed[1] ^ 0x40,)) + sealed[2:]
    with pytest.raises(AuthenticationError):
        remembering.open(forged, epoch)
    with pytest.raises(AuthenticationError):  # a failure is not remembered as a success
        remembering.open(forged, epoch)


def test_a_sealer_remembers_a_bounded_number_of_openings():
    sealer = FrameSealer(KEY, remember=3)
    decrypted = []
    decrypt = sealer._decrypt
    sealer._decrypt = lambda *args: decrypted.append(args[0]) or decrypt(*args)
    sealed = [SEALER.seal(f, epoch_for(f, EPOCH)) for f in ALL_FRAMES[:5]]
    epochs = [epoch_for(f, EPOCH) for f in ALL_FRAMES[:5]]
    sealer.open(sealed[0], epochs[0])
    sealer.open(sealed[0], epochs[0])
    assert len(decrypted) == 1  # the copy heard again is not decrypted again
    for frame, epoch in zip(sealed[1:4], epochs[1:4]):
        sealer.open(frame, epoch)
    assert len(decrypted) == 4
    assert sealer.open(sealed[0], epochs[0]) == ALL_FRAMES[0]  # forgotten (3 kept): decrypted again
    assert len(decrypted) == 5


@pytest.mark.parametrize("remember", [-1, 1.5, "3"])
def test_remember_must_be_a_whole_number(remember):
    with pytest.raises(ValueError, match="remember"):
        FrameSealer(KEY, remember=remember)
