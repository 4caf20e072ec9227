"""Checks and benches in one place: `rescuemesh bench` (bench.py, with the mesh bench), the frame and
control-plane fuzzers (`make fuzz`, `make fuzz-control`) and `rescuemesh ble-check` with what it measures.
They drive the runtime from above; nothing imports them (the Zenoh link bench imports zenoh: runtime/onboard/)."""
