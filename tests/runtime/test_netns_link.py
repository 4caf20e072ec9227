"""Robot processes on a real network: `linked_robot`'s argument errors, and two robot processes in their
own network namespaces joined by a veth pair losing 20 % of packets, where a Follow still completes.

The loss is netem's (`tc qdisc add dev X root netem loss 20%`) where the kernel has it; a kernel
without sch_netem (some VMs) gets the same loss from a userspace bridge in a third namespace, which
drops 20 % of the Ethernet frames it passes each way. Without root or `ip netns` the test is skipped,
with the reason. Run as a script, this file is that bridge (and the tx-checksum switch it needs).
"""

from __future__ import annotations

import io
import json
import os
import secrets
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rescuemesh.runtime.onboard.linked_robot import main as robot_main

LOSS = 0.2
SUBNET = "10.231.0"
PORT = 7447
RTO_MIN = "50ms"  # the robots' route's TCP resend floor (Linux's default: 200 ms)
ROBOT_TIMEOUT_S = 45.0  # both robot processes end by then, whatever happens (killed after)


# --- linked_robot's arguments ----------------------------------------------------------------------

@pytest.mark.parametrize("argv, words", [
    ([], "--name"),
    (["--name", "robot_0", "--listen", "tcp/127.0.0.1:7447"], "unknown robot"),
    (["--name", "robot_2"], "--listen or --connect"),
    (["--name", "robot_2", "--listen", "127.0.0.1:7447"], "bad endpoint"),
    (["--name", "robot_2", "--connect", "tcp/127.0.0.1:70000"], "bad endpoint"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--start", "1,x"], "--start"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--goal", "nan,0"], "--goal"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--follow", "robot_2"], "itself"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--goal", "30,0"], "off the map"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--duration", "-1"], "--duration"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--team", "a/b"], "team"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--key", "/nonexistent/key"], "key file"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--map", "/nonexistent.yaml"], "nonexistent"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--json-out", "/nonexistent/r.json"], "--json-out"),
    (["--name", "robot_2", "--listen", "tcp/127.0.0.1:1", "--bogus"], "--bogus"),
])
def test_bad_arguments_are_one_line_and_exit_2(argv, words):
    out, err = io.StringIO(), io.StringIO()
    assert robot_main(argv, out=out, err=err) == 2
    lines = err.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rescuemesh robot: error:") and words in lines[0], lines
    assert out.getvalue() == ""


def test_bad_arguments_from_the_command_line_print_no_traceback():
    run = subprocess.run([sys.executable, "-m", "rescuemesh.runtime.onboard.linked_robot", "--name", "robot_x"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and "Traceback" not in run.stderr, run.stderr


# --- two robot processes over a lossy veth ---------------------------------------------------------

def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    done = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20)
    if check and done.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {done.stderr.strip()}")
    return done


class LossyLink:
    """Namespaces `<tag>a` (robot_1, SUBNET.1) and `<tag>b` (robot_2, SUBNET.2), joined by a veth
    pair with netem loss, or through `<tag>m`'s lossy bridge. `close()` deletes every namespace."""

    def __init__(self) -> None:
        self.tag = f"rm{os.getpid() % 100000}{secrets.token_hex(2)}"  # unique per run; <= 15 chars with a suffix
        self.a, self.b, self.m = f"{self.tag}a", f"{self.tag}b", f"{self.tag}m"
        self.namespaces: list[str] = []
        self.bridge: subprocess.Popen | None = None
        self.how = ""
        self.thin = False  # linear timeouts for thin TCP streams in both robots' namespaces

    def open(self) -> None:
        for ns in (self.a, self.b):
            _ip("netns", "add", ns)
            self.namespaces.append(ns)
        # A robot's Zenoh stream is thin (a frame or two in flight): Linux then retries a lost segment
        # at a steady RTO for its first 6 tries instead of doubling it, so a run of losses stalls the
        # link for about a second, not 6-13 s (docs/networks.md, "Lossy links"). Per namespace.
        self.thin = all(subprocess.run(["ip", "netns", "exec", ns, "sysctl", "-qw",
                                        "net.ipv4.tcp_thin_linear_timeouts=1"],
                                       capture_output=True, timeout=20).returncode == 0 for ns in (self.a, self.b))
        va, vb = f"{self.tag}va", f"{self.tag}vb"
        _ip("link", "add", va, "netns", self.a, "type", "veth", "peer", "name", vb, "netns", self.b)
        self._address(self.a, va, 1)
        self._address(self.b, vb, 2)
        netem = [self._netem(self.a, va), self._netem(self.b, vb)]
        if all(r.returncode == 0 for r in netem):
            self.how = f"netem loss {LOSS:.0%} on both ends of the veth pair"
            return
        why = next(r.stderr.strip() for r in netem if r.returncode != 0)
        _ip("-n", self.a, "link", "del", "dev", va)  # the pair goes; a bridge namespace takes its place
        _ip("netns", "add", self.m)
        self.namespaces.append(self.m)
        ma, mb = f"{self.tag}ma", f"{self.tag}mb"
        _ip("link", "add", va, "netns", self.a, "type", "veth", "peer", "name", ma, "netns", self.m)
        _ip("link", "add", vb, "netns", self.b, "type", "veth", "peer", "name", mb, "netns", self.m)
        self._address(self.a, va, 1)
        self._address(self.b, vb, 2)
        for dev in (ma, mb):
            _ip("-n", self.m, "link", "set", "dev", dev, "up")
        for ns, dev in ((self.a, va), (self.b, vb)):  # frames leave with full checksums: the bridge copies them
            subprocess.run(["ip", "netns", "exec", ns, sys.executable, __file__, "tx-checksum-off", dev],
                           check=True, capture_output=True, timeout=20)
        self.bridge = subprocess.Popen(["ip", "netns", "exec", self.m, sys.executable, __file__, "bridge", ma, mb,
                                        str(LOSS), str(ROBOT_TIMEOUT_S + 10)], stdout=subprocess.PIPE,
                                       stderr=subprocess.PIPE, text=True)
        try:  # a bridge that cannot open its packet sockets exits at once
            _, failure = self.bridge.communicate(timeout=0.5)
            raise RuntimeError(f"the lossy bridge did not start: {failure.strip().splitlines()[-1:]}")
        except subprocess.TimeoutExpired:
            pass
        self.how = (f"netem unavailable ({why}): loss {LOSS:.0%} each way by a userspace bridge "
                    f"in namespace {self.m}")

    def _address(self, ns: str, dev: str, host: int) -> None:
        _ip("-n", ns, "addr", "add", f"{SUBNET}.{host}/24", "dev", dev)
        _ip("-n", ns, "link", "set", "dev", dev, "up")
        _ip("-n", ns, "link", "set", "dev", "lo", "up")
        # TCP's resend timeout starts at its floor, 200 ms by default, and doubles at each loss of the same
        # segment. A route's rto_min lowers the floor for this link, whose round trip is under a
        # millisecond, so a run of losses costs a quarter of the stall (docs/networks.md, "Lossy links")
        _ip("-n", ns, "route", "replace", f"{SUBNET}.0/24", "dev", dev, "src", f"{SUBNET}.{host}",
            "rto_min", RTO_MIN)

    def _netem(self, ns: str, dev: str) -> subprocess.CompletedProcess:
        if shutil.which("tc") is None:
            return subprocess.CompletedProcess([], 1, "", "no tc command")
        return subprocess.run(["ip", "netns", "exec", ns, "tc", "qdisc", "add", "dev", dev, "root", "netem", "loss",
                               f"{LOSS * 100:g}%"], capture_output=True, text=True, timeout=20)

    def bridge_counts(self) -> str:
        if self.bridge is None:
            return ""
        if self.bridge.poll() is None:
            self.bridge.terminate()
        out, _ = self.bridge.communicate(timeout=10)
        return out.strip()

    def close(self) -> None:
        if self.bridge is not None and self.bridge.poll() is None:
            self.bridge.kill()
            self.bridge.wait(10)
        for ns in reversed(self.namespaces):
            _ip("netns", "del", ns, check=False)


def _robot(ns: str, name: str, args: list[str], folder: Path) -> tuple[subprocess.Popen, Path]:
    report = folder / f"{name}.json"
    log = open(folder / f"{name}.log", "w")
    command = ["ip", "netns", "exec", ns, sys.executable, "-m", "rescuemesh.runtime.onboard.linked_robot", "--name", name,
               "--duration", "30", "--exit-when-done", "--json-out", str(report), *args]
    return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT), report


def test_follow_completes_between_two_network_namespaces_with_20_percent_loss(tmp_path):
    if os.geteuid() != 0:
        pytest.skip("needs root to make network namespaces (ip netns)")
    if shutil.which("ip") is None:
        pytest.skip("no `ip` command (iproute2)")
    link = LossyLink()
    processes: list[subprocess.Popen] = []
    started = time.monotonic()
    try:
        try:
            link.open()
        except (RuntimeError, subprocess.SubprocessError, OSError) as exc:
            pytest.skip(f"cannot build the namespaces and veth pair here: {exc}")
        team = link.tag
        follower, follower_json = _robot(link.b, "robot_2", ["--team", team, "--start=-1.5,0,0",
                                                             "--listen", f"tcp/{SUBNET}.2:{PORT}"], tmp_path)
        processes.append(follower)
        leader, leader_json = _robot(link.a, "robot_1", ["--team", team, "--follow", "robot_2", "--goal", "2.5,0",
                                                         "--linger", "6", "--listen", f"tcp/{SUBNET}.1:{PORT}",
                                                         "--connect", f"tcp/{SUBNET}.2:{PORT}"], tmp_path)
        processes.append(leader)
        deadline = time.monotonic() + ROBOT_TIMEOUT_S
        for process in processes:
            process.wait(max(0.1, deadline - time.monotonic()))
        counts = link.bridge_counts()
    finally:
        for process in processes:
            if process.poll() is None:
                process.kill()
                process.wait(10)
        link.close()
    logs = {name: (tmp_path / f"{name}.log").read_text() for name in ("robot_1", "robot_2")}
    assert leader.returncode == 0 and follower.returncode == 0, logs
    one, two = json.loads(leader_json.read_text()), json.loads(follower_json.read_text())
    print(f"\nnetns Follow: {link.how}; thin-stream linear timeouts {'on' if link.thin else 'unavailable'}; TCP rto_min {RTO_MIN}; "
          f"{time.monotonic() - started:.1f} s; {counts}; "
          f"robot_1 {one['mission']}; robot_2 drove {two['path_length_m']} m")
    assert one["mission"]["follow_result"] == "ACCEPTED" and one["mission"]["goal_result"] == "DONE"
    # FAILED "link lost" here has meant a TCP stall longer than the link-loss rule's silence and
    # reconnect window (8.5 s with nothing heard, once in a full `make test`): the log says so
    assert ["follow", "CANCELLED"] == [two["behaviours"][0]["name"], two["behaviours"][0]["result"]], \
        (two["log"], two["link"], counts)
    leader_end, follower_start, follower_end = one["final_pose"], two["start"], two["final_pose"]
    gap_before = ((leader_end[0] - follower_start[0]) ** 2 + (leader_end[1] - follower_start[1]) ** 2) ** 0.5
    gap_after = ((leader_end[0] - follower_end[0]) ** 2 + (leader_end[1] - follower_end[1]) ** 2) ** 0.5
    # moved toward the leader; not always all the way: a TCP stall of a few seconds under this loss
    # trips the link-loss rule (the follower halts until the leader is heard again), as it should.
    # This used to fail once in a while with a 2 s linger (the follower drove 0.8 m): the leader now
    # waits 6 s at its goal before its Stop, time for a follower held up by stalls to close in.
    assert two["path_length_m"] > 1.0 and gap_after < gap_before - 1.0, (gap_before, gap_after)
    if link.bridge is not None:
        assert "dropped" in counts and int(counts.split("dropped ")[1].split()[0]) > 0  # the loss was real


# --- this file as a script: the lossy bridge, and the switch it needs -------------------------------

def _bridge(dev_a: str, dev_b: str, loss: float, duration_s: float) -> None:
    """Copy every Ethernet frame heard on one device to the other, dropping `loss` of them at random,
    until `duration_s` s or SIGTERM; then print what was passed and dropped."""
    import random
    import select
    import signal
    import socket

    eth_p_all = 0x0003
    sockets = {}
    for dev in (dev_a, dev_b):
        sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(eth_p_all))
        sock.bind((dev, eth_p_all))
        sock.setblocking(False)
        sockets[sock] = dev
    other = dict(zip(sockets, reversed(list(sockets))))
    rng, passed, dropped, stop = random.Random(), 0, 0, []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    started = time.monotonic()
    end = started + duration_s
    arp_dropped: list[float] = []  # when, in s since the bridge started
    while not stop and time.monotonic() < end:
        ready, _, _ = select.select(list(sockets), [], [], 0.1)
        for sock in ready:
            while True:
                try:
                    frame, address = sock.recvfrom(65536)
                except (BlockingIOError, InterruptedError):
                    break
                if address[2] == socket.PACKET_OUTGOING:
                    continue  # our own copy going out
                if rng.random() < loss:
                    dropped += 1
                    if frame[12:14] == b"\x08\x06":  # ARP: a lost reply delays the robots' first frames
                        arp_dropped.append(round(time.monotonic() - started, 2))
                    continue
                try:
                    other[sock].send(frame)
                    passed += 1
                except OSError:
                    dropped += 1
    print(f"bridge passed {passed} dropped {dropped} frames (ARP dropped at {arp_dropped} s)")


def _tx_checksum_off(dev: str) -> None:
    """`ethtool -K DEV tx off` without ethtool (SIOCETHTOOL, ETHTOOL_STXCSUM): a veth otherwise sends
    TCP segments with their checksum left to the receiver's kernel, which a copied frame lacks."""
    import ctypes
    import fcntl
    import socket
    import struct

    value = ctypes.create_string_buffer(struct.pack("II", 0x17, 0))  # ETHTOOL_STXCSUM, off
    request = struct.pack("16sP", dev.encode(), ctypes.addressof(value))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        fcntl.ioctl(sock.fileno(), 0x8946, request)  # SIOCETHTOOL


if __name__ == "__main__":
    if sys.argv[1] == "bridge":
        _bridge(sys.argv[2], sys.argv[3], float(sys.argv[4]), float(sys.argv[5]))
    elif sys.argv[1] == "tx-checksum-off":
        _tx_checksum_off(sys.argv[2])
