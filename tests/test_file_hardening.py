"""Files a user (or another user on the host) could plant: a symlink where the output folder's write
probe goes, a FIFO given as the team key file (issue 17)."""

from __future__ import annotations

import os
import threading

import pytest

from rescuemesh.cli import UsageError, _writable_folder
from rescuemesh.mesh.keys import KeyFileError, load_team_key


def test_the_output_folders_write_probe_follows_no_planted_symlink(tmp_path):
    # this used to open `.rescuemesh-write-test` for writing through the symlink: its target truncated
    victim = tmp_path / "precious.txt"
    victim.write_text("keep me")
    out = tmp_path / "out"
    out.mkdir()
    (out / ".rescuemesh-write-test").symlink_to(victim)
    assert _writable_folder(out) == out
    assert victim.read_text() == "keep me"
    assert sorted(p.name for p in out.iterdir()) == [".rescuemesh-write-test"]  # the probe left nothing


def test_an_output_folder_that_cannot_be_made_is_still_refused(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    with pytest.raises(UsageError, match="cannot write to output folder"):
        _writable_folder(blocker / "below")


def test_a_fifo_given_as_key_file_is_refused_at_once(tmp_path):
    # this used to block the start for ever, waiting for a writer on the FIFO
    fifo = tmp_path / "team.key"
    os.mkfifo(fifo, 0o600)
    outcome: list[BaseException | bytes] = []
    reader = threading.Thread(target=lambda: outcome.append(_try(load_team_key, fifo)), daemon=True)
    reader.start()
    reader.join(5.0)
    assert not reader.is_alive(), "load_team_key blocked on a FIFO"
    assert isinstance(outcome[0], KeyFileError) and "not a regular file" in str(outcome[0])


def _try(function, *args):
    try:
        return function(*args)
    except BaseException as exc:  # noqa: BLE001 - handed to the test thread
        return exc
