"""A real robot's boot counter: the epoch it seals its frames under, kept in a state file per (team,
robot) and synced to disk before its first frame (docs/security.md, "A robot's epoch on disk").
Owns: the file's place and format, its lock and its atomic update. Must not know: Zenoh, frames.
"""

# Theory of operation. AES-CCM's nonce holds (epoch, seq, ...); a robot that started again at epoch 0
# would seal new frames under the nonces of its last run. So the file `STATE_DIR/TEAM/ROBOT.epoch`
# holds the highest epoch the robot has used, as one decimal line. At start the robot takes the
# file's lock (flock: one process per robot and state folder), reads E (no file: 0), writes E + 1 the
# way a crash cannot tear (a new file, fsync, rename over the old one, fsync of the folder) and only
# then seals its first frame under E + 1. During the run the endpoint opens a new epoch at every wrap
# of its 16-bit seq; `advance(epoch)` writes that one the same way before a frame sealed under it
# leaves (linked_robot's link guard). A file that cannot be read, written or locked, or does not hold
# one epoch, refuses the start: guessing would risk reusing a nonce.

from __future__ import annotations

import fcntl
import os
import stat
from pathlib import Path

from rescuemesh.mesh.security import MAX_EPOCH

#: The folder's name under $XDG_STATE_HOME (default ~/.local/state), per the XDG base directories.
APP_FOLDER = "rescuemesh"
_MAX_FILE_BYTES = 64


class BootCounterError(RuntimeError):
    """The epoch cannot be kept safely; the message is one line naming the file."""


def default_state_dir(environ: dict[str, str] | None = None) -> Path:
    """$XDG_STATE_HOME/rescuemesh, or ~/.local/state/rescuemesh when it is unset or not absolute."""
    environ = os.environ if environ is None else environ
    base = environ.get("XDG_STATE_HOME", "")
    if not base or not os.path.isabs(base):
        base = os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / APP_FOLDER


class BootCounter:
    """The epoch file of robot `name` in `team` under `state_dir`. `boot()` takes the lock and returns
    this run's epoch, already on disk; `advance(epoch)` records a later one; `close()` releases."""

    def __init__(self, state_dir: str | os.PathLike[str], team: str, name: str) -> None:
        self.folder = Path(state_dir) / team
        self.path = self.folder / f"{name}.epoch"
        self._lock_path = self.folder / f"{name}.lock"
        self._lock_fd: int | None = None
        self.epoch: int | None = None

    def boot(self) -> int:
        """This run's epoch: the stored one plus 1, synced to disk. BootCounterError (one line)."""
        try:
            self.folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        except OSError as exc:
            raise BootCounterError(f"cannot make the state folder {self.folder}: {exc.strerror}") from None
        self._lock()
        last = self._read()
        if last >= MAX_EPOCH:
            raise BootCounterError(f"{self.path}: epoch {last} is the last one; the team needs a new key")
        self._write(last + 1)
        self.epoch = last + 1
        return self.epoch

    def advance(self, epoch: int) -> None:
        """Record `epoch` (the endpoint moved on at a seq wrap) before a frame sealed under it leaves."""
        if self.epoch is None:
            raise BootCounterError("advance() before boot()")
        if epoch > self.epoch:
            self._write(epoch)
            self.epoch = epoch

    def close(self) -> None:
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # releases the flock
            self._lock_fd = None

    # internals

    def _lock(self) -> None:
        try:
            fd = os.open(self._lock_path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
        except OSError as exc:
            raise BootCounterError(f"cannot open the lock file {self._lock_path}: {exc.strerror}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise BootCounterError(f"{self.path} is in use: this robot already runs with this state folder") from None
        self._lock_fd = fd

    def _read(self) -> int:
        try:
            fd = os.open(self.path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
        except FileNotFoundError:
            return 0
        except OSError as exc:
            raise BootCounterError(f"cannot read the epoch file {self.path}: {exc.strerror}") from None
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise BootCounterError(f"{self.path}: the epoch file is not a regular file")
            raw = os.read(fd, _MAX_FILE_BYTES + 1)
        finally:
            os.close(fd)
        text = raw.decode("ascii", errors="replace").strip()
        if len(raw) > _MAX_FILE_BYTES or not text.isdigit() or not text.isascii() or int(text) > MAX_EPOCH:
            raise BootCounterError(f"{self.path}: not an epoch file (expected one decimal number); "
                                   "fix it by hand to at least the robot's last epoch, never lower")
        return int(text)

    def _write(self, epoch: int) -> None:
        tmp = self.folder / f".{self.path.name}.{os.getpid()}.tmp"
        try:
            try:
                os.unlink(tmp)  # a leftover of a crashed run of ours (the lock is held)
            except FileNotFoundError:
                pass
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
            try:
                os.write(fd, f"{epoch}\n".encode("ascii"))
                os.fsync(fd)
            finally:
                os.close(fd)
            os.replace(tmp, self.path)
            folder = os.open(self.folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
            try:
                os.fsync(folder)
            finally:
                os.close(folder)
        except OSError as exc:
            raise BootCounterError(f"cannot write the epoch file {self.path}: {exc.strerror}") from None
