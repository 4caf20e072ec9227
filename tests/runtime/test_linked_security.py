"""Linked robots (`rescuemesh robot --link zenoh`) as an attacker or a crash would meet them, over real
Zenoh sessions on 127.0.0.1: a robot killed and restarted counts its epoch on disk and is obeyed at
once, with no nonce twice; a peer without the team key cannot connect; a huge message does not reach
the robot's memory; a junk flood from a member does not starve a Follow (issue 17)."""

from __future__ import annotations

import os
import re
import select
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import zenoh

from rescuemesh.mesh.frames import SEG_BIT
from rescuemesh.mesh.keys import write_team_key
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.protocol import FrameError
from rescuemesh.runtime.onboard.boot_counter import BootCounter
from rescuemesh.runtime.onboard.link_bench import free_port
from rescuemesh.transport.zenoh_link import air_key, link_secret, open_session

TEAM = f"sec{os.getpid()}"
ACCEPTED = re.compile(r"accepted the Follow after ([0-9.]+) s")


def _listening(process: subprocess.Popen, port: int, timeout_s: float = 15.0) -> None:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end and process.poll() is None:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return
        except OSError:
            time.sleep(0.05)
    raise AssertionError(f"the robot never listened on {port} (exit {process.poll()})")


def _robot(name: str, key: Path, state: Path, *args: str) -> subprocess.Popen:
    command = [sys.executable, "-m", "rescuemesh.runtime.onboard.linked_robot", "--name", name, "--team", TEAM,
               "--key", str(key), "--state-dir", str(state), *args]
    return subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def _line_matching(process: subprocess.Popen, pattern: re.Pattern, timeout_s: float) -> re.Match:
    """The first line of `process`'s output that matches, read within `timeout_s` s."""
    end, seen, buffer = time.monotonic() + timeout_s, [], b""
    fd = process.stdout.fileno()
    while time.monotonic() < end:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if not ready:
            continue
        chunk = os.read(fd, 4096)
        if not chunk:
            break
        buffer += chunk
        *lines, buffer = buffer.split(b"\n")
        for line in lines:
            text = line.decode("utf-8", "replace")
            seen.append(text)
            match = pattern.search(text)
            if match:
                return match
    raise AssertionError(f"no line matching {pattern.pattern!r}; output: {seen[-5:]}")


def _stop(process: subprocess.Popen, sig: int = signal.SIGKILL) -> None:
    if process.poll() is None:
        process.send_signal(sig)
    try:
        process.wait(10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    process.stdout.close()


def _rss_kib(pid: int) -> int:
    with open(f"/proc/{pid}/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise AssertionError("no VmRSS")


@pytest.fixture()
def key(tmp_path) -> tuple[Path, bytes]:
    path = tmp_path / "team.key"
    return path, write_team_key(path)


def _nonce(sealed: bytes, epoch: int) -> bytes:
    """The AES-CCM nonce a sealed frame went out under (docs/security.md section 4)."""
    segment = sealed[6:9] if sealed[0] & SEG_BIT else bytes(3)
    return sealed[:6] + segment + epoch.to_bytes(4, "big")


def test_a_robot_killed_and_restarted_twice_counts_1_2_3_is_obeyed_at_once_and_never_repeats_a_nonce(
        tmp_path, key):
    # this used to start every linked robot at epoch 0: robot_2 took the second run's Follow under
    # the first run's nonces (two plaintexts under one AES-CCM nonce) and only after 17 resends
    path, team_key = key
    state = tmp_path / "state"
    port_2, port_rec = free_port(), free_port()
    recorded: list[bytes] = []
    recorder = open_session(TEAM, listen=[f"tcp/127.0.0.1:{port_rec}"], secret=link_secret(team_key))
    recorder.declare_subscriber(air_key(TEAM, 1), lambda sample: recorded.append(sample.payload.to_bytes()))
    follower = _robot("robot_2", path, state, "--listen", f"tcp/127.0.0.1:{port_2}", "--duration", "90")
    leaders, epochs, accepted = [], [], []
    try:
        _listening(follower, port_2)
        for run in range(3):
            leader = _robot("robot_1", path, state, "--connect", f"tcp/127.0.0.1:{port_2}",
                            "--connect", f"tcp/127.0.0.1:{port_rec}", "--follow", "robot_2",
                            "--start", f"{0.5 * run},0,0",  # each run from elsewhere: other plaintexts
                            "--linger", "60", "--duration", "60")
            leaders.append(leader)
            accepted.append(float(_line_matching(leader, ACCEPTED, 20.0).group(1)))
            epochs.append(int((state / TEAM / "robot_1.epoch").read_text()))
            time.sleep(0.5)  # its Heartbeats and PoseUpdates go out under this epoch
            _stop(leader)  # killed: no goodbye, no report
    finally:
        for process in leaders + [follower]:
            _stop(process)
        recorder.close()
    assert epochs == [1, 2, 3]
    assert all(s < 1.0 for s in accepted[1:]), accepted  # heard and obeyed at once after each return
    sealer = FrameSealer.from_team_key(team_key)
    by_nonce: dict[bytes, set[bytes]] = {}
    opened_in = set()
    for sealed in recorded:
        for epoch in (1, 2, 3):
            try:
                sealer.open(sealed, epoch)
            except FrameError:
                continue
            opened_in.add(epoch)
            by_nonce.setdefault(_nonce(sealed, epoch), set()).add(sealed)
            break
    assert opened_in == {1, 2, 3} and len(recorded) >= 6, (opened_in, len(recorded))
    reused = {n.hex(): len(f) for n, f in by_nonce.items() if len(f) > 1}
    assert not reused, f"{len(reused)} nonces sealed more than one frame"


def test_the_epoch_is_on_disk_before_the_robot_starts_and_a_bad_state_file_refuses_the_start(tmp_path, key):
    path, _ = key
    state = tmp_path / "state"
    counter = BootCounter(state, TEAM, "robot_1")
    assert counter.boot() == 1
    assert (state / TEAM / "robot_1.epoch").read_text() == "1\n"
    other = BootCounter(state, TEAM, "robot_1")
    with pytest.raises(RuntimeError, match="in use"):  # one process per robot and state folder
        other.boot()
    other.close()
    counter.advance(5)  # a seq wrap during the run
    counter.close()
    assert BootCounter(state, TEAM, "robot_1").boot() == 6
    (state / TEAM / "robot_3.epoch").write_text("not a number\n")
    run = subprocess.run([sys.executable, "-m", "rescuemesh.runtime.onboard.linked_robot", "--name", "robot_3",
                          "--team", TEAM, "--key", str(path), "--state-dir", str(state),
                          "--listen", f"tcp/127.0.0.1:{free_port()}", "--duration", "1"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and "robot_3.epoch" in run.stderr and "Traceback" not in run.stderr
    blocked = tmp_path / "file"
    blocked.write_text("")  # a state folder that cannot be made
    run = subprocess.run([sys.executable, "-m", "rescuemesh.runtime.onboard.linked_robot", "--name", "robot_3",
                          "--team", TEAM, "--key", str(path), "--state-dir", str(blocked / "s"),
                          "--listen", f"tcp/127.0.0.1:{free_port()}", "--duration", "1"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and run.stderr.count("\n") == 1 and "state folder" in run.stderr


def test_a_non_member_cannot_connect_and_a_huge_message_stays_out_of_the_robots_memory(tmp_path, key):
    # this used to let any Zenoh peer in, and a 10^9-byte put took the robot from 87 MB to 2 GB;
    # here 10^8 bytes (a 1 GB put costs the test process itself 1 GB): the robot must stay within 8 MB
    path, team_key = key
    port = free_port()
    robot = _robot("robot_2", path, tmp_path / "state", "--listen", f"tcp/127.0.0.1:{port}", "--duration", "60")
    outsider = member = None
    try:
        _listening(robot, port)
        _line_matching(robot, re.compile("epoch 1"), 10.0)
        outsider = open_session(TEAM, connect=[f"tcp/127.0.0.1:{port}"])  # no secret: a non-member
        wrong = open_session(TEAM, connect=[f"tcp/127.0.0.1:{port}"], secret=link_secret(bytes(16)))
        member = open_session(TEAM, connect=[f"tcp/127.0.0.1:{port}"], secret=link_secret(team_key))
        end = time.monotonic() + 10.0
        while not list(member.info.peers_zid()) and time.monotonic() < end:
            time.sleep(0.05)
        assert list(member.info.peers_zid()), "a member could not connect"
        time.sleep(1.0)  # the outsiders had as long as the member, and a retry
        assert not list(outsider.info.peers_zid()) and not list(wrong.info.peers_zid())
        wrong.close()
        before = _rss_kib(robot.pid)
        huge = member.declare_publisher(air_key(TEAM, 7))
        huge.put(bytes(10**8))
        time.sleep(3.0)
        grew = _rss_kib(robot.pid) - before
        assert grew < 8 * 1024, f"the robot grew by {grew} KiB"
        assert robot.poll() is None
    finally:
        for session in (outsider, member):
            if session is not None:
                session.close()
        _stop(robot, signal.SIGTERM)


def _follow_time(tmp_path: Path, path: Path, team_key: bytes, flood_per_s: float, tag: str) -> float:
    """s until robot_1's Follow is accepted by robot_2 while a member floods robot_2 with junk."""
    port = free_port()
    state = tmp_path / f"state-{tag}"
    follower = _robot("robot_2", path, state, "--listen", f"tcp/127.0.0.1:{port}", "--duration", "60")
    flooder, stop, rate, sprayer = None, threading.Event(), [], None
    leader = None
    try:
        _listening(follower, port)
        if flood_per_s:
            flooder = open_session(TEAM, connect=[f"tcp/127.0.0.1:{port}"], secret=link_secret(team_key))
            junk = flooder.declare_publisher(air_key(TEAM, 9), express=True,
                                             congestion_control=zenoh.CongestionControl.DROP)
            frames = [bytes([0x41, i & 0xFF, 9, 2]) + os.urandom(16) for i in range(256)]

            def spray() -> None:
                sent, t0 = 0, time.monotonic()
                rate.append(t0)
                while not stop.is_set():
                    for frame in frames[:64]:
                        junk.put(frame)
                    sent += 64
                    rate[1:] = [sent / (time.monotonic() - t0)]
                    ahead = sent / flood_per_s - (time.monotonic() - t0)
                    if ahead > 0:
                        time.sleep(ahead)

            sprayer = threading.Thread(target=spray, daemon=True)
            sprayer.start()
            time.sleep(1.0)
        leader = _robot("robot_1", path, state, "--connect", f"tcp/127.0.0.1:{port}", "--follow", "robot_2",
                        "--linger", "60", "--duration", "60")
        accepted = float(_line_matching(leader, ACCEPTED, 30.0).group(1))
        if flood_per_s:
            assert rate[1] > flood_per_s / 2, f"the flood reached only {rate[1]:.0f} frames/s"
        return accepted
    finally:
        stop.set()
        if sprayer is not None:
            sprayer.join(10.0)
        if flooder is not None:
            flooder.close()
        for process in (leader, follower):
            if process is not None:
                _stop(process, signal.SIGTERM)


@pytest.mark.slow
def test_a_junk_flood_from_a_member_leaves_the_follow_within_twice_its_clean_time(tmp_path, key):
    # this used to drop 47 % of every frame at 85,000 junk frames/s, genuine ones alike (the loop kept
    # the first 256 frames of each wake-up): a Follow took 2.6 s instead of 0.9 s. Measured here with
    # the loop cut back to its old tail drop: 0.84 s flooded against 0.23 s clean (46,000 frames/s
    # reached on a loaded 2-core machine; the test asks for at least half of 85,000)
    path, team_key = key
    clean = _follow_time(tmp_path, path, team_key, 0, "clean")
    flooded = _follow_time(tmp_path, path, team_key, 85_000, "flood")
    assert flooded <= 2 * max(clean, 0.3), (clean, flooded)
