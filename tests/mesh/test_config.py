"""MeshConfig: defaults, derived timers and validation."""

from __future__ import annotations

import math

import pytest

from rescuemesh.mesh import MeshConfig


def test_defaults_and_derived_timers():
    config = MeshConfig()
    assert (config.relay, config.initial_ttl, config.cache_size) == (True, 7, 128)
    assert config.lost_after_seconds == 3.5
    assert config.ack_delay_s(2) == pytest.approx(0.25)  # 150 + 50 * 2 ms
    assert config.retransmit_timeout_s(2) == pytest.approx(0.3)  # 200 + 50 * 2 ms


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("relay", 1, "relay"),
        ("initial_ttl", 16, "initial_ttl"),
        ("initial_ttl", -1, "initial_ttl"),
        ("cache_size", 0, "cache_size"),
        ("cache_lifetime_s", 0.0, "cache_lifetime_s"),
        ("heartbeat_period_s", math.nan, "heartbeat_period_s"),
        ("lost_after_missed", 0, "lost_after_missed"),
        ("lost_after_missed", 2.5, "lost_after_missed"),
        ("neighbour_expiry_s", 3.0, "must exceed the loss time"),
        ("segment_interval_s", -0.02, "segment_interval_s"),
        ("sar_ack_base_s", math.inf, "sar_ack_base_s"),
        ("sar_per_hop_s", -0.05, "sar_per_hop_s"),
        ("sar_retransmit_base_s", 0, "sar_retransmit_base_s"),
        ("duplicate_ack_interval_s", 0, "duplicate_ack_interval_s"),
        ("max_retransmissions", -1, "max_retransmissions"),
        ("incomplete_timeout_s", 0.0, "incomplete_timeout_s"),
        ("max_reassemblies", 0, "max_reassemblies"),
        ("max_reassemblies_per_source", 9, "must not exceed"),
        ("completed_memory", True, "completed_memory"),
    ],
)
def test_invalid_values_raise_a_clear_value_error(field, value, match):
    with pytest.raises(ValueError, match=match):
        MeshConfig(**{field: value})


def test_zero_retransmissions_and_zero_per_hop_are_allowed():
    config = MeshConfig(max_retransmissions=0, sar_per_hop_s=0.0)
    assert config.ack_delay_s(5) == 0.15
