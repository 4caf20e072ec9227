"""Team keys: HKDF against RFC 5869, the derived frame key, simulation keys, and the key file
(created 0600 without overwriting, loaded with one-line errors)."""

from __future__ import annotations

import os
import stat

import pytest

from rescuemesh.mesh.keys import (
    KeyFileError,
    derive_frame_key,
    hkdf_sha256,
    load_team_key,
    team_key_from_seed,
    write_team_key,
)

# RFC 5869, Appendix A, test cases 1-3 (SHA-256): IKM, salt, info, L, OKM.
RFC5869 = [
    pytest.param(
        "0b" * 22, "000102030405060708090a0b0c", "f0f1f2f3f4f5f6f7f8f9", 42,
        "3cb25f25faacd57a90434f64d0362f2a2d2d0a90cf1a5a4c5db02d56ecc4c5bf34007208d5b887185865",
        id="case-1",
    ),
    pytest.param(
        bytes(range(0x00, 0x50)).hex(), bytes(range(0x60, 0xB0)).hex(), bytes(range(0xB0, 0x100)).hex(), 82,
        "b11e398dc80327a1c8e7f78c596a49344f012eda2d4efad8a050cc4c19afa97c"
        "59045a99cac7827271cb41c65e590e09da3275600c2f09b8367793a9aca3db71"
        "cc30c58179ec3e87c14c01d5c1f3434f1d87",
        id="case-2",
    ),
    pytest.param(
        "0b" * 22, "", "", 42,
        "8da4e775a563c18f715f802a063c5a31b8a11f5c5ee1879ec3454e5f3c738d2d9d201395faa4b61a96c8",
        id="case-3-empty-salt-and-info",
    ),
]


@pytest.mark.parametrize("ikm, salt, info, length, okm", RFC5869)
def test_hkdf_sha256_matches_rfc5869(ikm, salt, info, length, okm):
    assert hkdf_sha256(bytes.fromhex(ikm), bytes.fromhex(salt), bytes.fromhex(info), length).hex() == okm


def test_frame_key_is_derived_not_the_team_key():
    team_key = bytes(range(16))
    frame_key = derive_frame_key(team_key)
    # docs/security.md section 2 and docs/protocol.md section 12 quote this value
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
