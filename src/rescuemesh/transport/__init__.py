"""Transports: thin pumps that move frames between sans-IO network stacks.

Owns: the simulated radio medium (airtime, queues, collisions), the BLE bearer (bumble, in
transport.ble, imported on demand). Must not know: robots, behaviours, what frames mean.
"""

from rescuemesh.transport.sim_medium import AirRecord, AirTiming, MediumStats, NetworkStack, SimMedium

__all__ = ["AirRecord", "AirTiming", "MediumStats", "NetworkStack", "SimMedium"]
