"""Atomic file writes: a file appears at its path complete, or not at all.

Every single-file writer of the project (traces, audio, model files, JSON records, reports, figures) writes
through this module. The bytes go to a temporary sibling in the target's folder (a hidden name,
`.<name>.<random><suffix>`, so listings and `*` globs skip it), which is renamed onto the target with
`os.replace` only when the writing succeeded and removed when it raised (any exception, KeyboardInterrupt
included). The rename is atomic on a POSIX file system: a reader sees the old file or the new one, never a
half-written one. The temporary is made like `open` makes a file (mode 0o666 less the umask), so the file
gets the permissions a plain write would give it. A missing folder of the target is created. Nothing is
synced to disk (`fsync`): the guarantee is against interrupted writers, not against a power cut.

`atomic_file` yields an open handle; `atomic_path` yields the temporary's path, for a library that writes
only to a file name (it is renamed into place in the same way). `write_bytes_atomic` and `write_text_atomic`
write a whole file at once.

Standard library only: `sim` and `synth_audio` import this module, and importing it must not import torch.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO, Literal, TextIO, overload

StrPath = str | os.PathLike[str]
"""A file path as the writers take it."""

ENCODING = "utf-8"
"""Encoding of the text written by `atomic_file(path, "w")` and `write_text_atomic`."""

_ATTEMPTS = 100
"""Temporary names tried before giving up (each is random: a clash means another writer holds the name)."""


def _create_temporary(target: Path, suffix: str) -> tuple[int, Path]:
    """Create an empty, unused temporary sibling of `target` (folder made first); its descriptor and path."""
    target.parent.mkdir(parents=True, exist_ok=True)
    for _ in range(_ATTEMPTS):
        tmp = target.with_name(f".{target.name}.{secrets.token_hex(4)}{suffix}")
        try:
            return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no unused temporary name beside {target} after {_ATTEMPTS} tries")


@contextlib.contextmanager
def _replacing(tmp: Path, target: Path) -> Iterator[None]:
    """Rename `tmp` onto `target` when the block succeeds; remove `tmp` and re-raise when it raises."""
    try:
        yield
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def atomic_path(path: StrPath, suffix: str = "") -> Iterator[Path]:
    """Yield an empty temporary sibling path of `path`, renamed onto `path` when the block succeeds.

    Args:
        path: the file to write.
        suffix: the temporary's suffix, for a library that picks the format by the file name (e.g. `.png`).

    Raises:
        Whatever the block raises (the temporary is removed first); OSError if the rename fails.
    """
    target = Path(path)
    fd, tmp = _create_temporary(target, suffix)
    os.close(fd)
    with _replacing(tmp, target):
        yield tmp


@overload
def atomic_file(path: StrPath, mode: Literal["wb"] = "wb") -> contextlib.AbstractContextManager[BinaryIO]: ...


@overload
def atomic_file(path: StrPath, mode: Literal["w"]) -> contextlib.AbstractContextManager[TextIO]: ...


@contextlib.contextmanager
def atomic_file(path: StrPath, mode: str = "wb") -> Iterator[Any]:  # the overloads type the handle
    """Yield a handle on a temporary sibling of `path`, closed and renamed onto `path` if the block succeeds.

    Args:
        path: the file to write.
        mode: `"wb"` (bytes) or `"w"` (text, UTF-8, `\\n` line ends).

    Raises:
        ValueError: another mode.
        Whatever the block raises (the temporary is removed first); OSError if the rename fails.
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"atomic_file: mode {mode!r} is invalid; allowed: 'wb' or 'w'")
    target = Path(path)
    fd, tmp = _create_temporary(target, ".tmp")
    with _replacing(tmp, target):
        try:
            handle = os.fdopen(fd, mode, encoding=None if mode == "wb" else ENCODING)
        except BaseException:
            os.close(fd)
            raise
        with handle:
            yield handle


def write_bytes_atomic(path: StrPath, data: bytes) -> Path:
    """Write `data` to `path` atomically (`atomic_file`); returns the path."""
    with atomic_file(path) as handle:
        handle.write(data)
    return Path(path)


def write_text_atomic(path: StrPath, text: str) -> Path:
    """Write `text` to `path` atomically, UTF-8 encoded (`atomic_file`); returns the path."""
    with atomic_file(path, "w") as handle:
        handle.write(text)
    return Path(path)
