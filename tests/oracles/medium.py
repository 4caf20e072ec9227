"""Oracle of the medium's reception kernels (transport/medium_kernels.py): the per-receiver Python
loops of transport/sim_medium.py before they were compiled (`_start_transmission`'s receiver loop,
`_collide`, `_arrive`'s settling), restated on the kernels' arrays and with their counter-based
draws, one receiver at a time, as plainly as possible."""

from __future__ import annotations

import math

from rescuemesh.transport import medium_kernels as k

from . import radio as ref


def _count(counts, code, dst, receiver, broadcast, relayed):
    counts[code] += 1
    if dst != broadcast and dst != receiver:
        return
    if relayed:
        counts[k.RELAYED_DELIVERED if code == k.OK else k.RELAYED_LOST] += 1
    elif dst == broadcast:
        counts[k.BROADCAST_DELIVERED if code == k.OK else k.BROADCAST_LOST] += 1
    else:
        counts[k.UNICAST_DELIVERED if code == k.OK else k.UNICAST_LOST] += 1


def open_receptions(sender, addresses, enabled, on_air_until, mean_dbm, start, dst, broadcast, bits, law, seed,
                    counter, counts, relayed=False):
    """(state, rssi, ok) lists: the receiver loop of `_start_transmission` with `channel.reception`."""
    n = len(addresses)
    state, rssi, ok = [k.NOT_RECEIVER] * n, [None] * n, [None] * n
    for r in range(n):
        if r == sender:
            continue
        intended = dst == broadcast or dst == addresses[r]
        if not enabled[r] or not mean_dbm[r] >= law.floor_dbm:
            if intended:
                _count(counts, k.RADIO_OFF if not enabled[r] else k.OUT_OF_RANGE, dst, addresses[r], broadcast, relayed)
            continue
        key = ref.counter_key(seed, k.FADING, addresses[sender], addresses[r], counter)
        u = [ref.counter_uniform(key, j) for j in range(3)]
        power, delivered = mean_dbm[r], True
        if law.fading:
            gain = ref.rician_gain_from_uniforms(u[0], u[1], law.rician_k)
            if gain <= 0.0:
                power, delivered = -math.inf, False
            else:
                power = mean_dbm[r] + 10.0 * math.log10(gain)
        if delivered and law.packet_errors:
            delivered = not u[2] < ref.packet_error_rate_scalar(power - law.sensitivity_dbm, bits)
        # the channel's loss: below sensitivity on average (the link's reach), else bit errors
        lost = k.BELOW_SENSITIVITY if mean_dbm[r] < law.sensitivity_dbm else k.BIT_ERRORS
        rssi[r], ok[r] = power, k.OK if delivered else lost
        state[r] = k.HALF_DUPLEX if on_air_until[r] > start else k.OK
    return state, rssi, ok


def collide(state, rssi, other_state, other_rssi, capture_db):
    """`_collide` at every radio that hears both (first cause wins)."""
    for r in range(len(state)):
        if state[r] == k.NOT_RECEIVER or other_state[r] == k.NOT_RECEIVER:
            continue
        margin = rssi[r] - other_rssi[r]
        if margin < capture_db:
            state[r] = state[r] or k.COLLISION
        if -margin < capture_db:
            other_state[r] = other_state[r] or k.COLLISION


def close_receptions(sender, addresses, enabled, state, ok, dst, broadcast, extra_loss, relay_delay_max_s, seed,
                     counter, counts, relayed=False):
    """`_arrive`'s settling: (final states, relay delays by receiver, delivered, collided, dst heard)."""
    delays, delivered, collided, dst_heard = {}, 0, 0, 0
    state = list(state)
    for r, code in enumerate(state):
        if code == k.NOT_RECEIVER:
            continue
        if code == k.OK and not enabled[r]:
            code = k.RADIO_OFF
        if code == k.OK and ok[r] != k.OK:
            code = ok[r]
        if code == k.OK and extra_loss > 0.0:
            if ref.counter_uniform(ref.counter_key(seed, k.EXTRA, addresses[sender], addresses[r], counter), 0) \
                    < extra_loss:
                code = k.EXTRA_LOSS
        state[r] = code
        _count(counts, code, dst, addresses[r], broadcast, relayed)
        collided |= code == k.COLLISION
        if code == k.OK:
            delivered += 1
            dst_heard |= addresses[r] == dst
            delays[r] = ref.counter_uniform(
                ref.counter_key(seed, k.RELAY_DELAY, addresses[r], addresses[sender], counter), 0) * relay_delay_max_s
    return state, delays, delivered, int(collided), int(dst_heard)
