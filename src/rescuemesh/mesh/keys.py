"""Team keys: the key file (create without overwriting, load with permission checks), the simulation
key from a seed, and HKDF-SHA256 key derivation (RFC 5869). The one mesh module that touches files
and the OS random source; the node never calls it: a runtime loads the key and hands a sealer down.
"""

from __future__ import annotations

import os
import stat

from cryptography.hazmat.primitives import hashes
from cryptography.hazmat.primitives.kdf.hkdf import HKDF

TEAM_KEY_BYTES = 16  # AES-128, as a Bluetooth Mesh NetKey
FRAME_KEY_BYTES = 16
#: HKDF salt and info of the frame key (docs/security.md). A new protocol version, or another use of
#: the team key, gets its own info string, so no two uses ever share a derived key.
FRAME_KEY_SALT = b"rescuemesh v1"
FRAME_KEY_INFO = b"frame encryption"
#: Simulation keys: public constants, so a simulated team's key is known to anyone with the seed.
SIMULATION_SALT = b"rescuemesh simulation key"
SIMULATION_INFO = b"team key"
_HEX_DIGITS = frozenset("0123456789abcdef")
_GROUP_OTHER_BITS = 0o077


class KeyFileError(ValueError):
    """A team key file that cannot be created or used; the message is one line naming the file."""


def hkdf_sha256(ikm: bytes, salt: bytes, info: bytes, length: int) -> bytes:
    """HKDF-SHA256 (RFC 5869: extract with `salt`, expand with `info`) of `length` bytes (1..8160),
    from the `cryptography` package. The one KDF of the project: tests run RFC 5869 cases 1-3
    through it."""
    return HKDF(algorithm=hashes.SHA256(), length=length, salt=salt, info=info).derive(ikm)


def derive_frame_key(team_key: bytes) -> bytes:
    """The AES-128 key that seals frames, derived from the 16-byte team key (never used directly):
    HKDF-SHA256(team_key, salt b"rescuemesh v1", info b"frame encryption", 16 bytes)."""
    if not isinstance(team_key, (bytes, bytearray)) or len(team_key) != TEAM_KEY_BYTES:
        raise ValueError(f"a team key is {TEAM_KEY_BYTES} bytes")
    return hkdf_sha256(bytes(team_key), FRAME_KEY_SALT, FRAME_KEY_INFO, FRAME_KEY_BYTES)


def team_key_from_seed(seed: int) -> bytes:
    """A team key for simulation only, the same for the same scenario seed (0..2**64-1): HKDF-SHA256
    (ikm = seed as 8 bytes big-endian, salt b"rescuemesh simulation key", info b"team key"). It is
    NOT secret: anyone who knows the seed, or tries small seeds, has the key."""
    if not isinstance(seed, int) or not 0 <= seed < 1 << 64:
        raise ValueError(f"seed {seed!r} is not an integer in 0..2**64-1")
    return hkdf_sha256(seed.to_bytes(8, "big"), SIMULATION_SALT, SIMULATION_INFO, TEAM_KEY_BYTES)


def format_team_key(key: bytes) -> str:
    """The key file's content: 32 lowercase hex digits and a newline."""
    return key.hex() + "\n"


def write_team_key(path: str | os.PathLike[str]) -> bytes:
    """Create a key file with a new random team key (os.urandom), mode 0600, and return the key.
    Refuses to overwrite (O_EXCL): a team's robots must all hold the same key, and replacing the
    file by mistake would cut this robot off. KeyFileError if the file exists or cannot be made."""
    key = os.urandom(TEAM_KEY_BYTES)
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise KeyFileError(f"{os.fsdecode(path)} exists: not overwriting a team key") from None
    except OSError as exc:
        raise KeyFileError(f"cannot create {os.fsdecode(path)}: {exc.strerror}") from None
    try:
        os.fchmod(fd, 0o600)  # the umask may have narrowed it already; never widen it
        os.write(fd, format_team_key(key).encode("ascii"))
    finally:
        os.close(fd)
    return key


def load_team_key(path: str | os.PathLike[str]) -> bytes:
    """The 16-byte team key in `path` (one line of 32 hex digits). KeyFileError, one line naming the
    file, if it is missing, unreadable, readable or writable by group or others ("chmod 600 FILE"),
    or not exactly one line of 32 hex digits."""
    name = os.fsdecode(path)
    try:
        # O_NONBLOCK: a FIFO (or a device) opens at once instead of waiting for a writer, and is
        # refused below before anything is read from it; this used to hang the start on a FIFO
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        with os.fdopen(fd, "rb") as handle:
            mode = os.fstat(handle.fileno()).st_mode
            raw = handle.read(4096) if stat.S_ISREG(mode) else b""
    except FileNotFoundError:
        raise KeyFileError(f"{name}: no such key file (make one with: rescuemesh keys new FILE)") from None
    except OSError as exc:
        raise KeyFileError(f"{name}: cannot read the key file: {exc.strerror}") from None
    if not stat.S_ISREG(mode):
        raise KeyFileError(f"{name}: not a regular file")
    if mode & _GROUP_OTHER_BITS:
        perms = f"{mode & 0o777:03o}"
        raise KeyFileError(f"{name}: key file is open to group or others (mode {perms}); chmod 600 {name}")
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        raise KeyFileError(f"{name}: not a key file (non-ASCII bytes)") from None
    digits = text[:-1] if text.endswith("\n") else text
    if len(digits) != 2 * TEAM_KEY_BYTES:
        want = 2 * TEAM_KEY_BYTES
        raise KeyFileError(f"{name}: expected one line of {want} hex digits, got {len(raw)} bytes")
    if not _HEX_DIGITS.issuperset(digits.lower()):
        raise KeyFileError(f"{name}: the key is not hexadecimal (expected 32 digits 0-9 a-f)")
    return bytes.fromhex(digits)
