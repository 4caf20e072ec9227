"""The simulated medium's per-reception work, compiled: one call per transmission opens its
receptions at every radio, one call per pair of overlapping transmissions collides them, one call
when it ends decides each reception's fate. The channel's reception law in the form they read.

Owns: reception states as arrays over the radios (attach order), the counter-based draws per
reception, the reception counters. Must not know: stacks, queues, the heap, frame contents, how the
mean power is computed (the medium hands in the channel's mean power per receiver).
"""

# Arrays are indexed by radio (attach order). A transmission's `state[r]` is NOT_RECEIVER for a
# radio that cannot hear it at all (itself, a radio off, one out of range), OK while nothing has
# spoiled the reception, else the code of the first LossCause that did (as the medium's Python loops
# did with `lost[k] = lost[k] or cause`). `rssi[r]` and `ok[r]` are the channel's draw for it.
#
# Draws (radio/streams.py): the fading and packet-error draw of the reception of the sender's
# `counter`-th transmission at radio r is keyed (seed, FADING, sender, r, counter): uniforms 0 and 1
# make the Rician gain, uniform 2 decides the packet error; the extra loss (seed, EXTRA_LOSS, sender,
# r, counter) and the relay delay handed to r's stack (seed, RELAY_DELAY, r, sender, counter) the
# same way. No draw depends on which other radios exist or in what order they are visited.

from __future__ import annotations

import math
from dataclasses import dataclass


from rescuemesh.jit import compiled
from rescuemesh.radio import BleChannel, ChannelModel, DiscChannel, LossCause
from rescuemesh.radio.fading import rician_gain_from_uniforms
from rescuemesh.radio.per import packet_error_rate_scalar
from rescuemesh.radio.streams import counter_key, counter_uniform

NOT_RECEIVER = -1
OK = 0
#: The code of each LossCause in a state array (0 is OK, -1 NOT_RECEIVER).
CODE = {cause: i + 1 for i, cause in enumerate(LossCause)}
#: LossCause by code (index 0: None, delivered).
CAUSE: tuple = (None, *LossCause)
OUT_OF_RANGE = CODE[LossCause.OUT_OF_RANGE]
BIT_ERRORS = CODE[LossCause.BIT_ERRORS]
COLLISION = CODE[LossCause.COLLISION]
EXTRA_LOSS = CODE[LossCause.EXTRA_LOSS]
RADIO_OFF = CODE[LossCause.RADIO_OFF]
HALF_DUPLEX = CODE[LossCause.HALF_DUPLEX]
BELOW_SENSITIVITY = CODE[LossCause.BELOW_SENSITIVITY]

#: Purposes of the counter-based draws (keys of radio.streams.counter_key).
FADING, EXTRA, RELAY_DELAY, RESPONSE_DELAY = 2, 3, 4, 5

#: Reception counters, indices into the medium's int64 counts array: delivered, then lost by
#: cause code (1..7), then, at the intended receivers, the source's own unicast delivered / lost,
#: broadcast delivered / lost, and the relays' copies delivered / lost (a relayed copy is not a
#: unicast delivery: docs/results.md).
DELIVERED = 0
UNICAST_DELIVERED = len(LossCause) + 1
UNICAST_LOST = UNICAST_DELIVERED + 1
BROADCAST_DELIVERED = UNICAST_DELIVERED + 2
BROADCAST_LOST = UNICAST_DELIVERED + 3
RELAYED_DELIVERED = UNICAST_DELIVERED + 4
RELAYED_LOST = UNICAST_DELIVERED + 5
N_COUNTS = UNICAST_DELIVERED + 6

#: The floor below which a mean power is out of earshot for a channel whose mean power is -inf
#: there (the disc): finite, so that -inf fails it and 0 passes.
_DISC_FLOOR_DBM = -1e300


@dataclass(frozen=True)
class ReceptionLaw:
    """How a channel decides one reception from its mean power `P` (dBm), in numbers a kernel reads.

    - audible iff `P >= floor_dbm` (else out of range: nothing drawn, nothing disturbed);
    - `fading`: rssi = P + 10 log10(g), g Rician of K-factor `rician_k` (radio/fading.py); else rssi = P;
    - `packet_errors`: lost with probability PER(rssi - sensitivity_dbm, bits) (radio/per.py); else
      every audible frame is delivered;
    - `quantum_m`, `origin`: the mean power depends only on the cells of this size holding the two
      radios (0: on the exact positions); `symmetric`: P(a, b) == P(b, a).
    """

    floor_dbm: float
    fading: bool
    rician_k: float
    packet_errors: bool
    sensitivity_dbm: float
    quantum_m: float
    origin: tuple[float, float]
    symmetric: bool


def reception_law(channel: ChannelModel) -> ReceptionLaw:
    """The law of the channel models the medium runs compiled: BleChannel's (docs/radio.md) and the
    disc's (every audible frame delivered at its mean power). Raises TypeError for another model, or
    one that overrides its `reception`: the medium would not draw what it says."""
    kind = type(channel)
    if isinstance(channel, BleChannel) and kind.reception is BleChannel.reception:
        p = channel.params
        grid = channel.grid
        if grid is not None:
            quantum, origin = float(grid.resolution), (float(grid.origin_x), float(grid.origin_y))
        else:
            from rescuemesh.radio.ble import DEFAULT_QUANTUM_M

            quantum, origin = DEFAULT_QUANTUM_M, (0.0, 0.0)
        return ReceptionLaw(p.sensitivity_dbm - p.out_of_range_margin_db, True, p.rician_k, True,
                            p.sensitivity_dbm, quantum, origin, True)
    if isinstance(channel, DiscChannel) and kind.reception is DiscChannel.reception:
        return ReceptionLaw(_DISC_FLOOR_DBM, False, 0.0, False, 0.0, 0.0, (0.0, 0.0), True)
    raise TypeError(f"the simulated medium has no compiled reception for channel model {kind.__name__} "
                    f"({getattr(channel, 'name', '?')!r}): it runs BleChannel and DiscChannel, whose "
                    f"`reception` it reproduces (transport/medium_kernels.py)")


@compiled(inline="always")
def _count(counts, code, dst, receiver, broadcast, relayed):
    """Count one reception of a frame to `dst` at `receiver` that ended with `code` (OK: delivered);
    at an intended receiver also as the source's own unicast or broadcast, or as a relay's copy."""
    counts[code] += 1
    if dst != broadcast and dst != receiver:
        return
    if relayed:
        counts[RELAYED_DELIVERED if code == OK else RELAYED_LOST] += 1
    elif dst == broadcast:
        counts[BROADCAST_DELIVERED if code == OK else BROADCAST_LOST] += 1
    else:
        counts[UNICAST_DELIVERED if code == OK else UNICAST_LOST] += 1


@compiled("i8(i8, i8[::1], b1[::1], f8[::1], f8[::1], f8, i8, i8, i8, f8, b1, f8, b1, f8, u8, i8, b1, "
          "i1[::1], f8[::1], i1[::1], i8[::1])")
def open_receptions(sender, addresses, enabled, on_air_until, mean_dbm, start, dst, broadcast, bits,
                    floor_dbm, fading, rician_k, packet_errors, sensitivity_dbm, seed, counter, relayed,
                    state, rssi, ok, counts):
    """Open the receptions of the sender's `counter`-th transmission (started at `start`, to `dst`;
    `relayed`: a relay's copy) at every other radio: fill `state`, `rssi`, and `ok` (OK, or the
    channel's loss: BIT_ERRORS, or BELOW_SENSITIVITY on a link whose mean power is below the
    receiver's sensitivity); count the intended receptions that cannot happen (radio off, out of
    range) in `counts`. Returns how many radios receive it."""
    n = 0
    me = addresses[sender]
    for r in range(len(addresses)):
        state[r] = NOT_RECEIVER
        if r == sender:
            continue
        address = addresses[r]
        if not enabled[r]:
            if dst == broadcast or dst == address:
                _count(counts, RADIO_OFF, dst, address, broadcast, relayed)
            continue
        mean = mean_dbm[r]
        if not mean >= floor_dbm:
            if dst == broadcast or dst == address:
                _count(counts, OUT_OF_RANGE, dst, address, broadcast, relayed)
            continue
        power = mean
        delivered = True
        if fading:
            key = counter_key(seed, FADING, me, address, counter)
            gain = rician_gain_from_uniforms(counter_uniform(key, 0), counter_uniform(key, 1), rician_k)
            if gain <= 0.0:
                power = -math.inf
                delivered = False
            else:
                power = mean + 10.0 * math.log10(gain)
            if delivered and packet_errors:
                delivered = not counter_uniform(key, 2) < packet_error_rate_scalar(power - sensitivity_dbm, bits)
        elif packet_errors:
            key = counter_key(seed, FADING, me, address, counter)
            delivered = not counter_uniform(key, 2) < packet_error_rate_scalar(power - sensitivity_dbm, bits)
        rssi[r] = power
        ok[r] = OK if delivered else (BELOW_SENSITIVITY if mean < sensitivity_dbm else BIT_ERRORS)
        state[r] = HALF_DUPLEX if on_air_until[r] > start else OK
        n += 1
    return n


@compiled("void(i1[::1], f8[::1], i1[::1], f8[::1], f8)")
def collide(state, rssi, other_state, other_rssi, capture_db):
    """Two transmissions whose PDUs overlap on one channel: at every radio receiving both, each is
    lost (COLLISION, unless already lost) unless it is at least `capture_db` stronger than the other."""
    for r in range(min(len(state), len(other_state))):
        if state[r] == NOT_RECEIVER or other_state[r] == NOT_RECEIVER:
            continue
        margin = rssi[r] - other_rssi[r]
        if margin < capture_db and state[r] == OK:
            state[r] = COLLISION
        if -margin < capture_db and other_state[r] == OK:
            other_state[r] = COLLISION


@compiled("UniTuple(i8, 3)(i8, i8[::1], b1[::1], i1[::1], i1[::1], i8, i8, f8, f8, u8, i8, b1, f8[::1], i8[::1])")
def close_receptions(sender, addresses, enabled, state, ok, dst, broadcast, extra_loss, relay_delay_max_s,
                     seed, counter, relayed, relay_delay, counts):
    """The transmission has ended: settle each reception (radio off now, the channel's packet error,
    the extra loss, in that order), count it, and draw the relay delay of each one delivered.
    Returns (receptions delivered, whether a collision spoiled any, whether `dst` received it)."""
    me = addresses[sender]
    delivered = collided = dst_heard = 0
    for r in range(len(state)):
        code = state[r]
        if code == NOT_RECEIVER:
            continue
        address = addresses[r]
        if code == OK and not enabled[r]:
            code = RADIO_OFF
        if code == OK and ok[r] != OK:
            code = ok[r]
        if code == OK and extra_loss > 0.0:
            if counter_uniform(counter_key(seed, EXTRA, me, address, counter), 0) < extra_loss:
                code = EXTRA_LOSS
        state[r] = code
        _count(counts, code, dst, address, broadcast, relayed)
        if code == COLLISION:
            collided = 1
        if code == OK:
            delivered += 1
            if address == dst:
                dst_heard = 1
            relay_delay[r] = counter_uniform(counter_key(seed, RELAY_DELAY, address, me, counter), 0) \
                * relay_delay_max_s
    return delivered, collided, dst_heard


@compiled("void(i8[::1], i8[::1], i8, u8, i8, f8, f8, f8[::1])")
def response_delays(receivers, addresses, sender, seed, counter, low, high, out):
    """The response delay handed to each radio in `receivers` with the sender's `counter`-th
    transmission: uniform in [low, high], keyed (seed, RESPONSE_DELAY, receiver, sender, counter)."""
    me = addresses[sender]
    for r in receivers:
        out[r] = low + counter_uniform(counter_key(seed, RESPONSE_DELAY, addresses[r], me, counter), 0) * (high - low)


@compiled("void(f8[:, ::1], f8, f8, f8, f8[:, ::1], b1[:, ::1])")
def move_radios(xy, quantum_m, origin_x, origin_y, cells, valid):
    """The radios are at `xy` now: a radio whose cell (the key the mean power depends on: the position's
    cell as floats, or the position itself when `quantum_m` is 0) is not `cells[i]` gets it there, and
    every mean power of a pair it is in stops being valid (`valid[i, :]`, `valid[:, i]`; a radio's own
    pair stays valid: it never hears itself). A cell of NaN (not yet known) is never the radio's."""
    n = xy.shape[0]
    for i in range(n):
        if quantum_m > 0.0:
            ci = math.floor((xy[i, 0] - origin_x) / quantum_m)
            cj = math.floor((xy[i, 1] - origin_y) / quantum_m)
        else:
            ci = xy[i, 0]
            cj = xy[i, 1]
        if ci != cells[i, 0] or cj != cells[i, 1]:
            cells[i, 0] = ci
            cells[i, 1] = cj
            for j in range(n):
                valid[i, j] = False
                valid[j, i] = False
            valid[i, i] = True
