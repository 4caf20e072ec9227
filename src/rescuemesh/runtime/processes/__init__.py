"""Processes over Zenoh: a world process (physics, sensors, medium) and one process per robot, stepped in
lockstep over the authenticated control plane (control.py, control_codec.py, control_messages.py);
spawn.py starts and ends them for `rescuemesh run --processes`."""
