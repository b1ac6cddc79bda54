"""Atomic, pickle-free model files: a JSON header plus named float arrays in one `.npz`."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.errors import InputNotFoundError
from msvdd.atomic import atomic_file
from msvdd.contract import ModelFormatError

_HEADER_KEY = "__header__"


def save_npz(
    path: str | os.PathLike[str],
    kind: str,
    version: int,
    header: dict[str, Any],
    arrays: dict[str, np.ndarray],
) -> None:
    """Write a header (JSON-able dict) and numeric arrays to one `.npz` file, atomically, without pickle.

    Args:
        path: destination file (any suffix; nothing is appended).
        kind: model kind stored in the header and checked by `load_npz`.
        version: format version stored in the header and checked by `load_npz`.
        header: extra JSON-able fields.
        arrays: numeric arrays (no object dtype).
    """
    full = {"kind": kind, "format_version": version, **header}
    payload = {_HEADER_KEY: np.array(json.dumps(full, sort_keys=True))}
    for name, arr in arrays.items():
        a = np.asarray(arr)
        if a.dtype == object:
            raise TypeError(f"array {name!r} has object dtype; model files hold numeric arrays only")
        payload[name] = a
    with atomic_file(path) as fh:
        np.savez(fh, **payload)  # type: ignore[arg-type]


def load_npz(
    path: str | os.PathLike[str], kind: str, version: int
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Read a file written by `save_npz`; check its kind and format version.

    Raises:
        FileNotFoundError: the file does not exist.
        ModelFormatError: the file is not such a model file, or has another kind or format version.
    """
    p = Path(path)
    if not p.is_file():
        raise InputNotFoundError(f"model file {p} does not exist")
    not_ours = ModelFormatError(
        f"{p} is not a msvdd-bench model file (expected a {kind!r} model: an .npz archive with a JSON header)"
    )
    try:
        with np.load(p, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        header = json.loads(str(arrays.pop(_HEADER_KEY)))
    except (OSError, ValueError, KeyError, EOFError) as exc:  # not an .npz, or not ours: no header
        raise not_ours from exc
    if not isinstance(header, dict):
        raise not_ours
    if header.get("kind") != kind:
        raise ModelFormatError(f"model file {p} holds a {header.get('kind')!r} model, expected {kind!r}")
    if header.get("format_version") != version:
        raise ModelFormatError(
            f"model file {p} has format_version {header.get('format_version')}; this code reads {version}"
        )
    return header, arrays
