import math

import numpy as np
import pytest

from rescuemesh.radio import RangeLossChannel, make_channel


def test_in_range_frame_arrives_after_latency_plus_airtime():
    channel = RangeLossChannel(loss=0.0, latency_s=0.01, range_m=10.0)
    delay = channel.transmit((0, 0), (3, 4), 20, np.random.default_rng(0))
    assert delay == pytest.approx(0.01 + 8 * 20 / 1e6)


def test_out_of_range_is_always_lost():
    channel = RangeLossChannel(range_m=10.0)
    rng = np.random.default_rng(0)
    assert channel.transmit((0, 0), (10.01, 0), 20, rng) is None
    assert channel.transmit((0, 0), (10.0, 0), 20, rng) is not None


def test_loss_rate_matches_probability_and_seed():
    channel = RangeLossChannel(loss=0.2)
    fates = [channel.transmit((0, 0), (1, 0), 20, np.random.default_rng(7)) for _ in range(1)]
    rng = np.random.default_rng(7)
    lost = sum(channel.transmit((0, 0), (1, 0), 20, rng) is None for _ in range(20_000))
    assert lost / 20_000 == pytest.approx(0.2, abs=0.015)
    again = np.random.default_rng(7)
    assert [channel.transmit((0, 0), (1, 0), 20, again) for _ in range(1)] == fates


@pytest.mark.parametrize("kwargs", [{"loss": 1.0}, {"loss": -0.1}, {"loss": math.nan}, {"latency_s": -1.0},
                                    {"range_m": 0.0}, {"range_m": -5.0}, {"bitrate_bps": 0.0}])
def test_bad_parameters_are_refused(kwargs):
    with pytest.raises(ValueError):
        RangeLossChannel(**kwargs)


def test_registry_builds_by_name_and_names_unknown():
    assert isinstance(make_channel("range-loss", loss=0.1), RangeLossChannel)
    with pytest.raises(ValueError, match="range-loss"):
        make_channel("ble-mesh")
