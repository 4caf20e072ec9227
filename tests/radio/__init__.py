"""Tests of rescuemesh.radio and its radio map (a package so test_ble.py does not clash with tests/transport/)."""
