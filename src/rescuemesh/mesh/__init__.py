"""Sans-IO mesh network layer between a robot's endpoint and its transport, after Bluetooth Mesh:
managed flooding (TTL, network message cache), neighbours and liveness, segmentation and
reassembly with block acks (docs/mesh.md). Imports only the stdlib and rescuemesh.protocol.
"""

from .config import TEAM_RELAY_RETRANSMIT_COUNT, MeshConfig
from .events import (
    FrameDelivered,
    MeshEvent,
    NeighbourFound,
    NeighbourLost,
    PeerRestarted,
    SegmentsResent,
    TransferComplete,
    TransferFailed,
)
from .neighbours import NeighbourInfo
from .node import MeshNode, Transmission
from .stack import NetworkStack
from .stats import MeshStats

__all__ = [
    "FrameDelivered",
    "MeshConfig",
    "MeshEvent",
    "MeshNode",
    "MeshStats",
    "NeighbourFound",
    "NeighbourInfo",
    "NeighbourLost",
    "NetworkStack",
    "PeerRestarted",
    "SegmentsResent",
    "TEAM_RELAY_RETRANSMIT_COUNT",
    "TransferComplete",
    "TransferFailed",
    "Transmission",
]
