"""`rescuemesh robot --link ble --hci SPEC`: robot processes whose authenticated frames cross Bluetooth LE
advertising bearers (transport/ble.py) on bumble's virtual controllers. The controllers run in a process
of their own (bumble's controllers app, one LocalLink) and each robot process reaches its controller over
HCI on a loopback TCP transport, as it would reach a dongle over USB."""

import json
import os
import signal
import socket
import subprocess
import sys
import time

import pytest

pytest.importorskip("bumble")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _robot(name: str, port: int, out, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "rescuemesh", "robot", "--link", "ble", "--hci",
                             f"tcp-client:127.0.0.1:{port}", "--name", name, "--duration", "60", "--exit-when-done",
                             "--json-out", str(out / f"{name}.json"), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _listening(port: int, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    raise AssertionError(f"no controller on 127.0.0.1:{port}")


@pytest.fixture
def controllers():
    ports = [_free_port(), _free_port()]
    proc = subprocess.Popen([sys.executable, "-m", "bumble.apps.controllers",
                             *(f"tcp-server:127.0.0.1:{p}" for p in ports)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        for port in ports:
            _listening(port, 20.0)  # (the probe connection closes at once; the transport serves the next client)
        yield ports
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(10)


def test_two_robot_processes_complete_a_follow_over_ble_on_virtual_controllers(controllers, tmp_path):
    follower = _robot("robot_2", controllers[1], tmp_path, "--start=-1,0")
    leader = _robot("robot_1", controllers[0], tmp_path, "--follow", "robot_2", "--goal", "2,0")
    try:
        out, err = leader.communicate(timeout=90)
        assert leader.returncode == 0, out + err[-2000:]
        f_out, f_err = follower.communicate(timeout=30)
        assert follower.returncode == 0, f_out + f_err[-2000:]
    finally:
        for proc in (leader, follower):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
    one, two = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("robot_1", "robot_2"))
    assert one["secure"] and two["secure"]  # authenticated frames (AES-CCM, the team key)
    assert one["mission"]["follow_result"] == "ACCEPTED" and one["mission"]["ok"]
    assert two["behaviours"][0]["name"] == "follow" and two["final_pose"][0] > 0.3  # it came along
    assert one["link"]["frames_received"] > 5 and one["link"]["frames_too_long"] == 0
    assert one["frames_rejected"] == 0 and two["frames_rejected"] == 0


@pytest.mark.parametrize("args, message", [
    (["--link", "ble"], "--link ble needs --hci SPEC"),
    (["--link", "ble", "--hci", "usb:0", "--listen", "tcp/127.0.0.1:7447"], "--listen and --connect are for"),
    (["--link", "ble", "--hci", "tcp-client:127.0.0.1:{closed}"], "--link ble: "),
])
def test_bad_ble_link_arguments_are_one_line_errors(args, message):
    args = [a.replace("{closed}", str(_free_port())) for a in args]
    done = subprocess.run([sys.executable, "-m", "rescuemesh", "robot", "--name", "robot_1", *args],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and message in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
