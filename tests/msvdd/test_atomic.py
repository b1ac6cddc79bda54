"""`msvdd.atomic`: a file appears complete or not at all, no temporary is left behind, the folder is made,
and the module imports only the standard library."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from msvdd.atomic import atomic_file, atomic_path, write_bytes_atomic, write_text_atomic


class Boom(Exception):
    """Raised inside a write to interrupt it."""


def _names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_bytes_and_text_round_trip_into_a_new_folder(tmp_path: Path) -> None:
    data = bytes(range(256)) * 3
    text = "ünïcode ± line one\nline two\n"
    assert write_bytes_atomic(tmp_path / "a" / "b" / "f.bin", data) == tmp_path / "a" / "b" / "f.bin"
    assert (tmp_path / "a" / "b" / "f.bin").read_bytes() == data
    assert write_text_atomic(str(tmp_path / "c" / "f.txt"), text) == tmp_path / "c" / "f.txt"
    assert (tmp_path / "c" / "f.txt").read_bytes() == text.encode("utf-8")  # UTF-8, "\n" kept as it is
    assert _names(tmp_path / "a" / "b") == ["f.bin"]
    assert _names(tmp_path / "c") == ["f.txt"]


def test_a_second_write_replaces_the_file(tmp_path: Path) -> None:
    target = tmp_path / "f.txt"
    write_text_atomic(target, "a long first version\n")
    write_text_atomic(target, "short\n")
    assert target.read_text(encoding="utf-8") == "short\n"
    assert _names(tmp_path) == ["f.txt"]


def test_atomic_file_binary_and_text_handles(tmp_path: Path) -> None:
    with atomic_file(tmp_path / "f.bin") as handle:
        handle.write(b"\x00\x01")
        handle.write(b"\x02")
    assert (tmp_path / "f.bin").read_bytes() == b"\x00\x01\x02"
    with atomic_file(tmp_path / "f.txt", "w") as text:
        text.write("é\n")
    assert (tmp_path / "f.txt").read_bytes() == "é\n".encode()


def test_the_file_appears_only_when_the_block_ends(tmp_path: Path) -> None:
    target = tmp_path / "f.bin"
    with atomic_file(target) as handle:
        handle.write(b"partial")
        handle.flush()
        assert not target.exists()
        (tmp,) = [p for p in tmp_path.iterdir()]
        assert tmp.name.startswith(".f.bin.")  # a hidden sibling in the same folder
    assert target.read_bytes() == b"partial"
    assert _names(tmp_path) == ["f.bin"]


@pytest.mark.parametrize("error", [Boom, KeyboardInterrupt])
def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path: Path, error: type) -> None:
    target = tmp_path / "f.bin"
    target.write_bytes(b"old")
    with pytest.raises(error), atomic_file(target) as handle:
        handle.write(b"new, half written")
        raise error("interrupted")
    assert target.read_bytes() == b"old"
    with pytest.raises(error), atomic_path(target) as tmp:
        tmp.write_bytes(b"new")
        raise error("interrupted")
    assert target.read_bytes() == b"old"
    assert _names(tmp_path) == ["f.bin"]


def test_a_failed_first_write_leaves_no_file(tmp_path: Path) -> None:
    with pytest.raises(Boom, match="disk full"), atomic_file(tmp_path / "new" / "f.txt", "w") as handle:
        handle.write("x")
        raise Boom("disk full")
    with pytest.raises(Boom), atomic_path(tmp_path / "new" / "g.png", suffix=".png"):
        raise Boom("plot failed")
    assert _names(tmp_path / "new") == []  # the folder was made, nothing is in it


def test_atomic_path_yields_an_empty_sibling_with_the_suffix(tmp_path: Path) -> None:
    target = tmp_path / "sub" / "audio.flac"
    with atomic_path(target, suffix=".flac") as tmp:
        assert tmp.parent == target.parent
        assert tmp.name.startswith(".audio.flac.") and tmp.suffix == ".flac"
        assert tmp.read_bytes() == b""
        tmp.write_bytes(b"fLaC")
    assert target.read_bytes() == b"fLaC"
    assert _names(target.parent) == ["audio.flac"]


def test_atomic_path_when_the_block_removes_the_temporary(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError), atomic_path(tmp_path / "f") as tmp:
        tmp.unlink()
    assert _names(tmp_path) == []


def test_a_failed_rename_leaves_no_temporary(tmp_path: Path) -> None:
    (tmp_path / "f").mkdir()
    (tmp_path / "f" / "keep").write_text("x")
    with pytest.raises(OSError):
        write_bytes_atomic(tmp_path / "f", b"data")  # a non-empty folder cannot be replaced by a file
    assert _names(tmp_path) == ["f"]


def test_another_mode_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="mode 'ab' is invalid"), atomic_file(tmp_path / "f", "ab"):  # type: ignore[call-overload]
        pass
    assert _names(tmp_path) == []


def test_permissions_are_those_of_a_plain_write(tmp_path: Path) -> None:
    plain = tmp_path / "plain"
    plain.write_bytes(b"x")
    write_bytes_atomic(tmp_path / "atomic", b"x")
    assert stat.S_IMODE((tmp_path / "atomic").stat().st_mode) == stat.S_IMODE(plain.stat().st_mode)


def test_concurrent_writers_use_distinct_temporaries(tmp_path: Path) -> None:
    target = tmp_path / "f"
    with atomic_file(target) as first, atomic_file(target) as second:
        first.write(b"first")
        second.write(b"second")
        assert len(os.listdir(tmp_path)) == 2
    assert target.read_bytes() == b"first"  # the outer block ends last: its file wins
    assert _names(tmp_path) == ["f"]


def test_the_module_imports_only_the_standard_library() -> None:
    code = (
        "import sys; before = set(sys.modules); import msvdd.atomic; "
        "new = {m.split('.')[0] for m in set(sys.modules) - before}; "
        "print(sorted(new - set(sys.stdlib_module_names) - {'msvdd'}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
