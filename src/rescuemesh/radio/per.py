"""Packet error rate of one BLE frame as a function of its received power.

Owns: the bit-error curve of the BLE receiver and the frame's bit count. Must not know: where the
power came from (path loss, walls, fading), the medium, frame contents.

Theory: a BLE 1M receiver is specified at a bit error rate of 0.1 % at its sensitivity (Bluetooth
Core 5.4, Vol 6 Part A 4.1). GFSK with modulation index 0.5 is modelled as non-coherent binary FSK,
BER = 1/2 exp(-gamma/2) (Proakis, Digital Communications, 5th ed., 4.5-4), with the effective
signal-to-noise ratio gamma scaled so that BER = 1e-3 exactly at the sensitivity:

    gamma(P) = 2 ln(500) * 10^((P - P_sens)/10).

Errors are independent bits; a frame survives when every bit its CRC covers is right:
PER = 1 - (1 - BER)^bits. The curve is steep: about 23 % at the sensitivity for a 20-byte frame,
under 1 % two dB above.
"""

from __future__ import annotations

import math

import numpy as np

from rescuemesh.jit import compiled

#: BER a BLE receiver must reach at its sensitivity (Bluetooth Core 5.4, Vol 6 Part A 4.1).
BER_AT_SENSITIVITY = 1e-3
#: Effective SNR (linear) at which non-coherent BFSK has BER_AT_SENSITIVITY: 2 ln(1 / (2 BER)).
GAMMA_AT_SENSITIVITY = 2.0 * math.log(1.0 / (2.0 * BER_AT_SENSITIVITY))

#: Bytes of a legacy ADV_NONCONN_IND PDU around a Bluetooth Mesh message that the CRC covers
#: besides the message itself: 2 B PDU header + 6 B AdvA + 1 B AD length + 1 B AD type (0x2A),
#: plus the 3 B CRC whose own bits must be right too (Core Vol 6 Part B 2.1, 2.3; Mesh 3.3.1).
CRC_COVERED_OVERHEAD_BYTES = 2 + 6 + 1 + 1 + 3


def crc_covered_bits(frame_bytes: int) -> int:
    """Bits of the on-air PDU (header, AdvA, AD header, frame, CRC) that must arrive intact."""
    if frame_bytes < 0:
        raise ValueError(f"frame size must be >= 0 bytes, got {frame_bytes}")
    return 8 * (CRC_COVERED_OVERHEAD_BYTES + frame_bytes)


def bit_error_rate(margin_db):
    """BER at `margin_db` = received power minus sensitivity, in dB (scalar or array)."""
    gamma = GAMMA_AT_SENSITIVITY * np.power(10.0, np.asarray(margin_db, dtype=float) / 10.0)
    ber = 0.5 * np.exp(-0.5 * gamma)
    return float(ber) if np.ndim(ber) == 0 else ber


def packet_error_rate(margin_db, frame_bytes: int):
    """PER of a `frame_bytes`-byte frame received `margin_db` dB above sensitivity (scalar or array)."""
    bits = crc_covered_bits(frame_bytes)
    ber = np.asarray(bit_error_rate(margin_db), dtype=float)
    per = -np.expm1(bits * np.log1p(-ber))
    return float(per) if np.ndim(per) == 0 else per


@compiled("f8(f8, i8)")
def packet_error_rate_scalar(margin_db: float, bits: int) -> float:
    """packet_error_rate for one value (the per-frame hot path, compiled; same formula)."""
    exponent = 0.5 * GAMMA_AT_SENSITIVITY * 10.0 ** (margin_db / 10.0)
    if exponent > 700.0:  # exp underflows: BER is 0
        return 0.0
    ber = 0.5 * math.exp(-exponent)
    return -math.expm1(bits * math.log1p(-ber))
