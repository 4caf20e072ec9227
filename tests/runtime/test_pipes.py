"""The control plane over pipes (runtime/processes/pipes.py), as `run --processes` uses it: messages
cross whole, in order, however the pipe splits them; a reader's wait is bounded; a writer that goes
is seen at once; a length over the limit is refused without reading on; the world's calls answer
or fail with a ControlError; a robot's loop refuses a forged request and leaves on a garbage stream.

Each robot here is a thread with real pipes; tests/runtime/test_processes.py runs real processes.
Every wait is bounded.
"""

from __future__ import annotations

import io
import os
import queue
import signal
import struct
import subprocess
import sys
import threading
import time

import pytest

from rescuemesh.runtime.processes import control_messages as msg
from rescuemesh.runtime.processes.control import MAX_SEALED_BYTES, Answerer, ControlError, ControlKey
from rescuemesh.runtime.processes.control_codec import encode
from rescuemesh.runtime.processes.pipes import (
    READY,
    PipeCaller,
    PipeChannel,
    PipeHost,
    PipeReader,
    write_frame,
)
from rescuemesh.runtime.processes.robot_process import serve_robot_over_pipes

KEY = ControlKey(bytes(range(32)))
OTHER_KEY = ControlKey(bytes(range(1, 33)))
RESCUEMESH = [sys.executable, "-m", "rescuemesh"]


@pytest.fixture()
def pipe():
    read_end, write_end = os.pipe()
    reader = PipeReader(read_end)
    yield reader, write_end
    reader.close()
    try:
        os.close(write_end)
    except OSError:
        pass


def test_messages_cross_whole_and_in_order_however_the_pipe_splits_them(pipe):
    reader, write_end = pipe
    messages = [bytes([i % 256]) * n for i, n in enumerate([0, 1, 5, 300, 70_000, 2, 3_000_000, 17])]
    stream = b"".join(struct.pack(">I", len(m)) + m for m in messages)

    def dribble():  # in pieces of odd sizes, cutting lengths and messages anywhere
        view, sizes = memoryview(stream), [1, 3, 2, 7, 65_537, 11, 1_000_003]
        k = 0
        while view:
            size = sizes[k % len(sizes)]
            os.write(write_end, view[:size])
            view, k = view[size:], k + 1

    writer = threading.Thread(target=dribble)
    writer.start()
    got = [reader.next(10.0) for _ in messages]
    writer.join(10.0)
    assert got == messages


def test_a_long_message_crosses_while_the_reader_reads(pipe):
    reader, write_end = pipe
    big = os.urandom(5_000_000)  # far over the pipe's 64 KiB: the write blocks until the reader reads
    writer = threading.Thread(target=write_frame, args=(write_end, big))
    writer.start()
    assert reader.next(10.0) == big
    writer.join(10.0)
    assert not writer.is_alive()


def test_the_wait_is_bounded_and_a_gone_writer_is_seen_at_once():
    read_end, write_end = os.pipe()
    reader = PipeReader(read_end)
    start = time.monotonic()
    with pytest.raises(queue.Empty):
        reader.next(0.1)
    assert 0.09 <= time.monotonic() - start < 2.0
    os.write(write_end, struct.pack(">I", 10) + b"cut")  # a message cut off by the writer's end
    threading.Timer(0.05, os.close, args=(write_end,)).start()
    start = time.monotonic()
    assert reader.next(5.0) is None and reader.ended  # the cut message is no message
    assert time.monotonic() - start < 2.0
    assert reader.next(5.0) is None
    reader.close()


def test_a_length_over_the_limit_is_refused_without_reading_on(pipe):
    reader, write_end = pipe
    os.write(write_end, struct.pack(">I", 0xFFFF_FFFF) + b"x" * 100)  # "4 GiB follow"
    with pytest.raises(ControlError, match="over the .* byte limit"):
        reader.next(1.0)
    with pytest.raises(ControlError, match="over the control message limit"):
        write_frame(write_end, b"x" * (MAX_SEALED_BYTES + 1))


class _Robot:
    """A robot's side in a thread: reads requests, answers with `answerer` (None: sends `replies`)."""

    def __init__(self, answerer=None, replies=(), leave_after: int | None = None):
        self.leave_after = leave_after  # requests answered before this robot's process "dies"
        self.requests_in, self.requests_out = os.pipe()
        self.replies_in, self.replies_out = os.pipe()
        self.answerer, self.replies = answerer, list(replies)
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self):
        reader = PipeReader(self.requests_in)
        try:
            while True:
                try:
                    request = reader.next(10.0)
                except queue.Empty:
                    return
                if request is None:
                    return
                answers = self.replies if self.answerer is None else [self.answerer.answer(request)]
                for answer in answers:
                    if answer is not None:
                        write_frame(self.replies_out, answer)
                if self.leave_after is not None:
                    self.leave_after -= 1
                    if self.leave_after == 0:
                        return
        finally:
            reader.close()
            os.close(self.replies_out)

    def channel(self) -> PipeChannel:
        return PipeChannel(self.requests_out, PipeReader(self.replies_in))


def test_a_call_over_pipes_is_answered_and_a_gone_robot_fails_the_call():
    robot = _Robot(Answerer("robot_1", KEY, lambda request: msg.StatsReply(4242, 1.5)), leave_after=1)
    channel = robot.channel()
    caller = PipeCaller({"robot_1": channel}, KEY, timeout_s=5.0)
    try:
        hello = caller.call("robot_1", msg.Hello())
        assert isinstance(hello, msg.HelloReply)
        robot.thread.join(5.0)  # and then the robot's process is gone: its ends are closed
        assert not robot.thread.is_alive()
        start = time.monotonic()
        with pytest.raises(ControlError, match="robot_1's process is gone"):
            caller.call("robot_1", msg.Stats())
        answers = caller.call_all({"robot_1": msg.Stats()}, tolerate=True)
        assert isinstance(answers["robot_1"], ControlError)
        assert time.monotonic() - start < 2.0  # at once, not after the call's time limit
    finally:
        channel.close()


def test_a_forged_reply_on_the_pipe_is_refused_and_counted_and_the_call_times_out():
    forged = OTHER_KEY.seal(2, b"w" * 16, 1, "robot_1", encode(msg.HelloReply(b"n" * 16)))
    robot = _Robot(replies=[forged, b"garbage"])
    channel = robot.channel()
    caller = PipeCaller({"robot_1": channel}, KEY, timeout_s=0.3)
    try:
        with pytest.raises(ControlError, match="did not answer with the run's control key"):
            caller.call("robot_1", msg.Hello())
        assert caller.refusals.count == 2
    finally:
        channel.close()
        robot.thread.join(5.0)


def test_the_host_joins_a_robot_once_it_says_ready_and_never_one_that_says_something_else():
    channels = {}
    for name in ("robot_1", "robot_2"):
        requests_in, requests_out = os.pipe()
        replies_in, replies_out = os.pipe()
        channels[name] = (PipeChannel(requests_out, PipeReader(replies_in)), requests_in, replies_out)
    host = PipeHost({name: c[0] for name, c in channels.items()}, bytes(32))
    try:
        assert host.take_events() == [] and host.alive() == set()  # both still "importing"
        assert not host.wait_for_any(["robot_1", "robot_2"], 0.1)
        write_frame(channels["robot_1"][2], READY)
        write_frame(channels["robot_2"][2], b"x" * 40)  # not READY: a broken robot
        assert host.wait_for_any(["robot_1"], 5.0)
        assert host.take_events() == [("robot_1", True)] and host.take_events() == []
        assert host.alive() == {"robot_1"}
        assert "not READY" in channels["robot_2"][0].broken
        os.close(channels["robot_1"][2])  # robot_1's process is gone
        assert host.alive() == set()
    finally:
        for channel, requests_in, replies_out in channels.values():
            channel.close()
            os.close(requests_in)
            if channel is channels["robot_2"][0]:
                os.close(replies_out)


class _RobotPipes:
    """A robot loop's pipes: the loop owns (and closes) requests_in and replies_out; the world's end
    of the requests is closed once, by the test or at teardown."""

    def __init__(self):
        self.requests_in, self.requests_out = os.pipe()
        replies_in, self.replies_out = os.pipe()
        self.replies = PipeReader(replies_in)

    def close_world(self):
        if self.requests_out >= 0:
            fd, self.requests_out = self.requests_out, -1
            os.close(fd)

    def serve(self, out) -> int:
        return serve_robot_over_pipes("robot_1", self.requests_in, self.replies_out, idle_timeout_s=10.0, out=out)


@pytest.fixture()
def robot_pipes(monkeypatch):
    """Run on this (the main) thread: the test writes the requests first, so the loop returns.
    SIGTERM's handler is restored after."""
    monkeypatch.setenv("RESCUEMESH_CONTROL_KEY", bytes(range(32)).hex())
    handler = signal.getsignal(signal.SIGTERM)
    pipes = _RobotPipes()
    yield pipes
    signal.signal(signal.SIGTERM, handler)
    pipes.close_world()
    pipes.replies.close()


def test_a_robots_loop_refuses_a_forged_request_answers_a_genuine_one_and_leaves_when_the_world_goes(robot_pipes):
    write_frame(robot_pipes.requests_out, OTHER_KEY.seal(1, b"w" * 16, 1, "robot_1", encode(msg.Hello())))  # forged
    write_frame(robot_pipes.requests_out, KEY.seal(1, b"w" * 16, 2, "robot_1", encode(msg.Hello())))
    robot_pipes.close_world()  # then the world is gone
    out = io.StringIO()
    assert robot_pipes.serve(out) == 0
    replies = robot_pipes.replies
    assert replies.next(5.0) == READY  # first, before any request was read
    assert KEY.open(replies.next(5.0))[2] == 2  # the genuine one's answer, and only that one
    assert replies.next(5.0) is None  # the robot closed its end
    assert "world gone: wheels halted, leaving" in out.getvalue()
    assert "1 control messages refused" in out.getvalue()


def test_a_robots_loop_leaves_on_a_garbage_length_without_reading_it(robot_pipes):
    os.write(robot_pipes.requests_out, struct.pack(">I", 0x7FFF_FFFF))  # "a 2 GB message follows"; left open
    out = io.StringIO()
    start = time.monotonic()
    assert robot_pipes.serve(out) == 1
    assert time.monotonic() - start < 5.0
    assert "the world's pipe is unreadable" in out.getvalue()


@pytest.mark.parametrize("argv, message", [
    (["--control-fds", "3"], "--control-fds takes R,W"),
    (["--control-fds", "a,b"], "--control-fds takes R,W"),
    (["--control-fds", "900,901"], "is not an open file descriptor"),
    (["--control-fds", "0,1"], "is not a pipe"),
    (["--control-fds", "900,901", "--connect", "tcp/127.0.0.1:7447"], "not both"),
    ([], "give the world's endpoint"),
])
def test_bad_control_fds_are_one_line_errors(argv, message):
    done = subprocess.run(RESCUEMESH + ["robot", "--name", "robot_2"] + argv, capture_output=True, text=True,
                          timeout=60, stdin=subprocess.DEVNULL)
    assert done.returncode == 2, done.stderr
    assert message in done.stderr and "Traceback" not in done.stderr
