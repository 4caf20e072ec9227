"""The benchmark helper runs on any clock (a behaviour test: nothing here fails on speed)."""

from __future__ import annotations

from rescuemesh.protocol.bench import BENCH_MESSAGES, codec_roundtrip_rate


def test_rate_is_counted_on_the_callers_clock():
    ticks = iter(range(1000))
    rate = codec_roundtrip_rate(2.0, lambda: float(next(ticks)))  # 1 s per clock call
    # one batch (100 passes over the mix) per clock reading: two batches reach 2 s
    assert rate == 2 * 100 * len(BENCH_MESSAGES) / 2.0


def test_mix_covers_the_follow_stream():
    types = {type(m).__name__ for m in BENCH_MESSAGES}
    assert {"PoseUpdate", "Confirm", "Follow", "Heartbeat"} <= types
