"""Team keys: HKDF against RFC 5869, the derived frame key, simulation keys, and the key file
(created 0600 without overwriting, loaded with one-line errors)."""

from __future__ import annotations

import hashlib
import hmac
import os
import re
import stat
from pathlib import Path

import pytest

from rescuemesh.mesh.keys import (
    FRAME_KEY_INFO,
    FRAME_KEY_SALT,
    KeyFileError,
    derive_frame_key,
    hkdf_sha256,
    load_team_key,
    team_key_from_seed,
    write_team_key,
)

DOCS = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"


def _doc_blocks(kind: str) -> list[dict[str, str]]:
    """The `name: value` blocks of docs/protocol.md section 12 that have a `kind` line."""
    text = DOCS.read_text(encoding="utf-8")
    blocks = re.findall(r"```text\n(.*?)```", text[text.index("## 12. Authenticated frames"):], flags=re.DOTALL)
    fields = [dict(line.split(":", 1) for line in block.strip().splitlines()) for block in blocks]
    return [{k.strip(): v.strip() for k, v in f.items()} for f in fields if kind in {k.strip() for k in f}]


def _bytes(value: str) -> bytes:
    return b"" if value == "(empty)" else bytes.fromhex(value)


RFC5869 = [pytest.param(case, id=case["hkdf case"]) for case in _doc_blocks("hkdf case")]


def test_docs_reproduce_rfc5869_cases_1_to_3():
    assert [case.values[0]["hkdf case"] for case in RFC5869] == ["RFC 5869 A.1", "RFC 5869 A.2", "RFC 5869 A.3"]


@pytest.mark.parametrize("case", RFC5869)
def test_hkdf_sha256_matches_rfc5869(case):
    """RFC 5869, Appendix A, test cases 1-3 (SHA-256), as docs/protocol.md section 12 reproduces them:
    the PRK is HMAC-SHA256(salt, IKM), an empty salt being 32 zero bytes; the OKM is what
    hkdf_sha256 gives."""
    ikm, salt, info = _bytes(case["ikm"]), _bytes(case["salt"]), _bytes(case["info"])
    assert hmac.new(salt or bytes(32), ikm, hashlib.sha256).hexdigest() == case["prk"]
    assert hkdf_sha256(ikm, salt, info, int(case["length"])).hex() == case["okm"]


def test_frame_key_salt_and_info_are_the_documented_ascii_bytes():
    [use] = _doc_blocks("hkdf use")
    assert use["hkdf use"] == "frame key" and int(use["length"]) == 16
    assert _bytes(use["salt"]) == FRAME_KEY_SALT == "rescuemesh v1".encode("ascii")
    assert _bytes(use["info"]) == FRAME_KEY_INFO == "frame encryption".encode("ascii")
    team_key = bytes(range(16))
    assert derive_frame_key(team_key) == hkdf_sha256(team_key, _bytes(use["salt"]), _bytes(use["info"]), 16)


def test_frame_key_is_derived_not_the_team_key():
    team_key = bytes(range(16))
    frame_key = derive_frame_key(team_key)
    # docs/protocol.md section 12 quotes this value (its worked examples)
    assert frame_key.hex() == "c206d32b7be45ab519faaf940d4dc529"
    assert frame_key == hkdf_sha256(team_key, b"rescuemesh v1", b"frame encryption", 16)
    assert derive_frame_key(bytes(16)) != derive_frame_key(bytes(15) + b"\x01")


@pytest.mark.parametrize("bad", [b"", bytes(15), bytes(17), "00" * 16, None])
def test_derive_frame_key_wants_16_bytes(bad):
    with pytest.raises(ValueError):
        derive_frame_key(bad)


def test_simulation_key_is_a_function_of_the_seed():
    # documented in docs/security.md section 2
    assert team_key_from_seed(0).hex() == "6ac01d6acd597dfa971253b2d2728ffe"
    assert team_key_from_seed(0) == hkdf_sha256(bytes(8), b"rescuemesh simulation key", b"team key", 16)
    assert team_key_from_seed(1) == team_key_from_seed(1) != team_key_from_seed(2)
    assert len(team_key_from_seed(2**64 - 1)) == 16


@pytest.mark.parametrize("seed", [-1, 2**64, 1.5, "1"])
def test_simulation_seed_out_of_range(seed):
    with pytest.raises(ValueError):
        team_key_from_seed(seed)


# --- the key file -------------------------------------------------------------------------------


@pytest.fixture
def open_umask():
    """A umask that would leave new files world-readable: the writer must not rely on the umask."""
    old = os.umask(0)
    yield
    os.umask(old)


def test_write_team_key_makes_a_0600_file_that_loads(tmp_path, open_umask):
    path = tmp_path / "team.key"
    key = write_team_key(path)
    assert len(key) == 16
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert path.read_text(encoding="ascii") == key.hex() + "\n"
    assert load_team_key(path) == key
    assert write_team_key(tmp_path / "other.key") != key  # os.urandom, not a constant


def test_write_team_key_refuses_to_overwrite(tmp_path):
    path = tmp_path / "team.key"
    key = write_team_key(path)
    with pytest.raises(KeyFileError, match="exists") as info:
        write_team_key(path)
    assert "\n" not in str(info.value)
    assert load_team_key(path) == key  # untouched


def test_write_team_key_into_a_missing_directory(tmp_path):
    with pytest.raises(KeyFileError, match="cannot create"):
        write_team_key(tmp_path / "no-such-dir" / "team.key")


def test_upper_case_digits_load(tmp_path):
    path = tmp_path / "team.key"
    path.write_text("000102030405060708090A0B0C0D0E0F\n")
    path.chmod(0o600)
    assert load_team_key(path) == bytes(range(16))


def test_a_key_without_its_newline_loads(tmp_path):
    path = tmp_path / "team.key"
    path.write_text("00" * 16)
    path.chmod(0o600)
    assert load_team_key(path) == bytes(16)


@pytest.mark.parametrize(
    "content, mode, match",
    [
        pytest.param("00" * 16 + "\n", 0o644, "chmod 600", id="world-readable"),
        pytest.param("00" * 16 + "\n", 0o640, "chmod 600", id="group-readable"),
        pytest.param("00" * 16 + "\n", 0o602, "chmod 600", id="world-writable"),
        pytest.param("", 0o600, "32 hex digits", id="empty"),
        pytest.param("00" * 15 + "\n", 0o600, "32 hex digits", id="short"),
        pytest.param("00" * 17 + "\n", 0o600, "32 hex digits", id="long"),
        pytest.param("00" * 16 + "\n" + "00" * 16 + "\n", 0o600, "32 hex digits", id="two-lines"),
        pytest.param("00" * 16 + "\r\n", 0o600, "32 hex digits", id="crlf"),
        pytest.param(" " + "00" * 15 + "0\n", 0o600, "not hexadecimal", id="space"),
        pytest.param("zz" * 16 + "\n", 0o600, "not hexadecimal", id="not-hex"),
        pytest.param("00" * 15 + "0x\n", 0o600, "not hexadecimal", id="0x"),
        pytest.param("é" * 16 + "\n", 0o600, "non-ASCII", id="non-ascii"),
    ],
)
def test_bad_key_files_give_one_line_errors(tmp_path, content, mode, match):
    path = tmp_path / "team.key"
    path.write_text(content, encoding="utf-8", newline="")
    path.chmod(mode)
    with pytest.raises(KeyFileError, match=match) as info:
        load_team_key(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_missing_key_file(tmp_path):
    with pytest.raises(KeyFileError, match="no such key file") as info:
        load_team_key(tmp_path / "absent.key")
    assert "\n" not in str(info.value)


def test_a_directory_is_not_a_key_file(tmp_path):
    with pytest.raises(KeyFileError):
        load_team_key(tmp_path)


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads a mode-000 file")
def test_unreadable_key_file(tmp_path):
    path = tmp_path / "team.key"
    path.write_text("00" * 16 + "\n")
    path.chmod(0)
    with pytest.raises(KeyFileError, match="cannot read") as info:
        load_team_key(path)
    assert "\n" not in str(info.value)
