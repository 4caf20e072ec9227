"""Transports: thin pumps that move protocol frames between sans-IO endpoints.

Owns: the in-process simulated radio link (later: Zenoh, BLE, ROS). Must not know: robots, behaviours.
"""

from rescuemesh.transport.sim_link import FrameEndpoint, LinkStats, RadioRecord, SimRadioLink

__all__ = ["FrameEndpoint", "LinkStats", "RadioRecord", "SimRadioLink"]
