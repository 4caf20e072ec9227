"""The network bench harnesses measure what they say (behaviour, not speed: no figure is a goal here)."""

import pytest

from rescuemesh.checks.mesh_bench import chain_confirm_latency, delivery_ratio


def test_confirm_latency_grows_with_the_hops_of_the_chain():
    one, four = chain_confirm_latency(1, trials=20), chain_confirm_latency(4, trials=20)
    assert one.confirmed == four.confirmed == 20
    # each hop adds at least one frame's airtime and a relay delay each way
    assert 1.0 < one.p50_ms < four.p50_ms and four.p50_ms > 3 * one.p50_ms


def test_a_direct_link_at_30_percent_loss_delivers_what_three_sends_allow_and_relays_add_paths():
    direct = delivery_ratio(0, trials=400)
    assert direct == pytest.approx(1 - (1 - 0.7 * 0.7) ** 3, abs=0.05)  # the paper's 3 sends: 86.7 %
    assert delivery_ratio(2, trials=400) > direct + 0.05


def test_without_loss_everything_arrives():
    assert delivery_ratio(0, extra_loss=0.0, trials=50) == 1.0
