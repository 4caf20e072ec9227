"""Checks and benches in one place: `rescuemesh bench` (bench.py, with the mesh and Zenoh link benches),
the frame and control-plane fuzzers (`make fuzz`, `make fuzz-control`) and `rescuemesh ble-check`
with what it measures. They drive the runtime and the scenarios from above; nothing imports them."""
