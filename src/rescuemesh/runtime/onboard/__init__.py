"""The real-time robot: one robot's brain and network stack on wall-clock time over a frame link (Zenoh or
Bluetooth LE), with its boot counter and a kinematic body when there is no hardware
(`rescuemesh robot`, linked_robot.py)."""
