"""Typed errors of the protocol core: what can be wrong with received bytes or with values to send.
Owns the hierarchy only; must not know who catches them (the endpoint turns a FrameError into a
FrameRejected event; an EncodeError reaches the caller that asked to send the value).
"""

from __future__ import annotations


class FrameError(ValueError):
    """A received frame cannot be used; it is dropped and counted, never allowed to crash a robot."""


class TruncatedFrame(FrameError):
    """Shorter than the 10-byte minimum (6-byte header + 4-byte integrity field)."""


class IntegrityError(FrameError):
    """The CRC-32 in the last 4 bytes does not match the bytes before it (corrupted in transit)."""


class UnsupportedVersion(FrameError):
    """Version bits (byte 0, bits 7-6) are not PROTOCOL_VERSION."""


class UnknownMessageType(FrameError):
    """Message type (byte 1, bits 5-0) is not a MessageType."""


class MalformedPayload(FrameError):
    """Intact frame (CRC good) with a field of the wrong length or an out-of-range value."""


class UnsupportedFeature(FrameError):
    """AUTH (MIC-32) or SEG (segmented bulk data) flag set: implemented by later issues."""


class EncodeError(ValueError):
    """A value cannot be put on the wire (pose out of range, radius <= 0, message too long ...)."""
