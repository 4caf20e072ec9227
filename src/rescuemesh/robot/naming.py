"""Robot names (`robot_1`, as in the paper's ROS topics `robot_1/comm_protocol/command`) and addresses.

Owns: the mapping between a robot's name and its one-byte protocol address. Must not know: anything else.
"""

from __future__ import annotations

import re

_NAME = re.compile(r"robot_(\d{1,3})")
#: Largest unicast address (255 is broadcast in the wire format, docs/protocol.md).
MAX_ROBOT_ADDRESS = 254


def robot_address(name: str) -> int:
    """Address of `robot_N` (N in 1..254). ValueError for any other name."""
    match = _NAME.fullmatch(name)
    if not match or not 1 <= int(match.group(1)) <= MAX_ROBOT_ADDRESS:
        raise ValueError(f"unknown robot {name!r}: robot names are robot_1 .. robot_{MAX_ROBOT_ADDRESS}")
    return int(match.group(1))


def robot_name(address: int) -> str:
    """Name of the robot at `address`."""
    if not 1 <= address <= MAX_ROBOT_ADDRESS:
        raise ValueError(f"no robot has address {address}")
    return f"robot_{address}"


def command_topic(name: str) -> str:
    """The ROS topic of the paper that carries commands to robot `name`."""
    return f"{name}/comm_protocol/command"
