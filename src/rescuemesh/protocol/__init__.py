"""Sans-IO protocol core: messages, wire codec, reliability (confirm, retry, duplicates), endpoint.
Owns what robots say to each other and how it goes on the wire (docs/protocol.md). Must not know
clocks, randomness, I/O or any other rescuemesh package: it imports only the stdlib and itself.
"""

# The public surface (docs/protocol.md, "The Python surface"): what an application needs to command
# robots and read what comes back. Everything else is imported from its module
# (rescuemesh.protocol.codec, .messages, .events, .errors, .reliability, .endpoint, .wire, .payloads).

from .codec import encode_frame, decode_frame, BROADCAST
from .endpoint import Endpoint, EndpointConfig
from .errors import FrameError, EncodeError
from .events import (
    EndpointEvent, CommandReceived, ConfirmReceived, PoseUpdateReceived, DataReceived, DeliveryFailed,
    HeartbeatReceived, FrameRejected)
from .messages import (
    Follow, Stop, MoveAround, Goto, Return, ShowCam, ShowScan, LandOnTop, ForwardMsg, Pose, MessageType,
    ResultCode, Reason, DataKind)
from .reliability import ReliabilityConfig

__all__ = [
    "Follow",
    "Stop",
    "MoveAround",
    "Goto",
    "Return",
    "ShowCam",
    "ShowScan",
    "LandOnTop",
    "ForwardMsg",
    "Pose",
    "MessageType",
    "ResultCode",
    "Reason",
    "DataKind",
    "Endpoint",
    "EndpointConfig",
    "ReliabilityConfig",
    "EndpointEvent",
    "CommandReceived",
    "ConfirmReceived",
    "PoseUpdateReceived",
    "DataReceived",
    "DeliveryFailed",
    "HeartbeatReceived",
    "FrameRejected",
    "encode_frame",
    "decode_frame",
    "FrameError",
    "EncodeError",
    "BROADCAST",
]
