"""The simulated radio link pumps frames between endpoints in time order."""

import numpy as np

from rescuemesh.protocol import Endpoint, Follow, Pose
from rescuemesh.protocol.events import CommandReceived, ConfirmReceived
from rescuemesh.protocol.messages import MessageType, ResultCode
from rescuemesh.radio import RangeLossChannel
from rescuemesh.transport import SimRadioLink


def _team(loss=0.0, positions=None, record=False):
    positions = positions or {1: (0.0, 0.0), 2: (1.0, 0.0), 3: (2.0, 0.0)}
    link = SimRadioLink(RangeLossChannel(loss=loss, latency_s=0.01), np.random.default_rng(1), record=record)
    endpoints = {}
    for address, xy in positions.items():
        endpoints[address] = Endpoint(address)
        link.attach(address, endpoints[address], lambda xy=xy: xy)
    return link, endpoints


def _drain(endpoint):
    events = []
    while (event := endpoint.next_event()) is not None:
        events.append(event)
    return events


def test_command_and_confirm_cross_the_link_within_one_pump():
    link, ep = _team()
    seq = ep[1].send_command(2, Follow(Pose(1, 2, 0, 0)), 0.0)
    link.flush(0.0)
    assert _drain(ep[2]) == []  # still in flight
    link.pump(0.05)
    (received,) = [e for e in _drain(ep[2]) if isinstance(e, CommandReceived)]
    assert received.seq == seq and abs(received.now - (0.01 + 8 * 18 / 1e6)) < 1e-9  # latency + airtime of 18 B
    ep[2].confirm(1, seq, MessageType.FOLLOW, ResultCode.ACCEPTED, 0.05)
    link.flush(0.05)
    link.pump(0.1)
    confirms = [e for e in _drain(ep[1]) if isinstance(e, ConfirmReceived)]
    assert [c.result for c in confirms] == [ResultCode.ACCEPTED]
    assert link.stats.frames_sent == 2 and link.stats.frames_delivered == 2 and link.stats.frames_lost == 0


def test_third_robot_hears_unicast_but_it_is_not_counted_or_delivered_as_its_own():
    link, ep = _team()
    ep[1].send_command(2, Follow(Pose(0, 0, 0, 0)), 0.0)
    link.flush(0.0)
    link.pump(0.1)
    assert not any(isinstance(e, CommandReceived) for e in _drain(ep[3]))
    assert ep[3].stats.frames_not_for_us == 1
    assert link.stats.frames_delivered == 1


def test_out_of_range_frames_are_lost_and_retried_until_given_up():
    link, ep = _team(positions={1: (0.0, 0.0), 2: (50.0, 0.0)}, record=True)
    ep[1].send_command(2, Follow(Pose(0, 0, 0, 0)), 0.0)
    for k in range(1, 40):
        link.pump(k * 0.05)
    assert link.stats.frames_sent == 3  # three sends in all, then given up
    assert link.stats.frames_lost == 3 and link.stats.frames_out_of_range == 3
    assert [r.arrived_s for r in link.records] == [None, None, None]


def test_timers_fire_at_their_deadline_not_at_the_tick():
    link, ep = _team(positions={1: (0.0, 0.0), 2: (50.0, 0.0)}, record=True)
    ep[1].send_command(2, Follow(Pose(0, 0, 0, 0)), 0.0)
    link.flush(0.0)
    link.pump(1.0)  # one long pump: the resends happen at their own deadlines inside it
    sent = [r.sent_s for r in link.records]
    timeout = ep[1].config.reliability.ack_timeout_s
    assert sent == [0.0, timeout, 2 * timeout]


def test_same_seed_same_fates():
    def run():
        link, ep = _team(loss=0.3, record=True)
        for k in range(50):
            ep[1].send_heartbeat(k * 0.1)
            link.pump(k * 0.1)
        return [(r.dst, r.arrived_s) for r in link.records]

    assert run() == run()
