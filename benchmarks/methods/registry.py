"""The method registry: every detector by name, built for a seed and a training scale, saved and loaded."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import platform
from collections.abc import Callable
from importlib import metadata
from pathlib import Path

from benchmarks.errors import InputNotFoundError, UserError, check_seed
from benchmarks.methods.base import check_scale
from benchmarks.methods.spec import (
    DEVICES,
    FAMILIES,
    MODALITIES,
    Factory,
    MethodSpec,
    PaperRow,
    check_spec,
)
from msvdd.atomic import atomic_path, write_text_atomic
from msvdd.contract import Detector, ModelFormatError

__all__ = [
    "DEVICES",
    "FAMILIES",
    "MODALITIES",
    "Factory",
    "MethodSpec",
    "PaperRow",
    "load_detector",
    "make",
    "names",
    "register",
    "save_detector",
    "spec",
]

METHOD_FORMAT_VERSION = 1
"""Version of the `method.json` layout written by `save_detector`."""

METHOD_FILE = "method.json"
MODEL_FILE = "model.bin"

_REGISTRY: dict[str, MethodSpec] = {}


def register(
    name: str,
    factory: Factory,
    *,
    cls: type[Detector],
    family: str,
    modality: str,
    description: str,
    label: str = "",
    paper: tuple[PaperRow, ...] = (),
    config: str = "",
) -> None:
    """Register a method under `name`: its one descriptor (`benchmarks.methods.spec.MethodSpec`, whose
    fields the arguments are)."""
    if name in _REGISTRY:
        raise ValueError(f"method {name!r} is already registered")
    _REGISTRY[name] = check_spec(
        MethodSpec(name, factory, family, modality, description, cls, label, paper, config)
    )


LoadCheck = Callable[[str, Detector], str]
"""Checks a loaded model: (saved method name, detector) -> the name it loads under, or ModelFormatError."""
_LOAD_CHECKS: list[LoadCheck] = []


def register_load_check(check: LoadCheck) -> None:
    """Have `load_detector` pass every loaded model through `check` (a family whose names changed maps its
    old models to their new names, or refuses them); registered once per check."""
    if check not in _LOAD_CHECKS:
        _LOAD_CHECKS.append(check)


def names(family: str | None = None) -> list[str]:
    """Registered method names in registration order, optionally of one family."""
    if family is not None and family not in FAMILIES:
        raise UserError(f"family {family!r} is unknown; allowed: {', '.join(FAMILIES)}")
    return [n for n, s in _REGISTRY.items() if family is None or s.family == family]


def spec(name: str) -> MethodSpec:
    """The `MethodSpec` of `name`; a UserError listing the allowed names if unknown.

    A name `module:Class` is a detector from outside the project, imported on first use
    (`benchmarks.methods.external`).
    """
    if name in _REGISTRY:
        return _REGISTRY[name]
    from benchmarks.methods.external import external_spec, is_external

    if is_external(name):
        return external_spec(name)
    raise UserError(
        f"method {name!r} is unknown; allowed: {', '.join(_REGISTRY)}, "
        "or module:Class for a detector of your own"
    )


def make(name: str, *, seed: int, scale: str, device: str = "cpu", progress: bool | None = None) -> Detector:
    """An unfitted detector of method `name` for `seed` and training `scale` (smoke, short or full).

    `device` (cpu, cuda, auto) is where the torch methods train and score; the others ignore it.
    `progress` turns the training progress bar of the torch methods on or off (None: the scale's
    default, off at smoke); methods without a bar ignore it.
    """
    method = spec(name)
    check_scale(scale)
    check_seed(seed, "seed")
    if device not in DEVICES:
        raise UserError(f"device {device!r} is unknown; allowed: {', '.join(DEVICES)}")
    detector = method.factory(seed, scale, device)
    if progress is not None:
        _set_progress(detector, progress)
    return detector


def _set_progress(detector: Detector, progress: bool) -> None:
    """Set `progress` in the detector's `config` dataclass, if it has such a field (the torch methods:
    `MSVDDConfig`, `DcaseAEConfig`), which their training loop reads when `fit` runs."""
    config = getattr(detector, "config", None)
    if not dataclasses.is_dataclass(config) or isinstance(config, type):
        return
    if any(f.name == "progress" for f in dataclasses.fields(config)):
        detector.config = dataclasses.replace(config, progress=progress)  # type: ignore[attr-defined]


def versions() -> dict[str, str]:
    """Versions of Python and of the packages a saved model depends on."""
    found = {"python": platform.python_version()}
    for dist in ("msvdd-bench", "numpy", "scipy", "torch", "scikit-learn"):
        with contextlib.suppress(metadata.PackageNotFoundError):
            found[dist] = metadata.version(dist)
    return found


def save_detector(detector: Detector, name: str, directory: str | os.PathLike[str]) -> Path:
    """Write `method.json` and the model file of a fitted detector into `directory`.

    `method.json` is written last (and any old one removed first), so a folder with a `method.json`
    always holds a complete model. Returns the directory.
    """
    method = spec(name)
    target = Path(directory)
    target.mkdir(parents=True, exist_ok=True)
    with contextlib.suppress(FileNotFoundError):
        os.unlink(target / METHOD_FILE)
    with atomic_path(target / MODEL_FILE) as tmp:
        detector.save(tmp)
    info = {
        "method": method.name,
        "family": method.family,
        "modality": method.modality,
        "class": f"{type(detector).__module__}.{type(detector).__qualname__}",
        "format_version": METHOD_FORMAT_VERSION,
        "model_file": MODEL_FILE,
        "threshold": float(detector.threshold_),
        "versions": versions(),
    }
    write_text_atomic(target / METHOD_FILE, json.dumps(info, indent=2, sort_keys=True) + "\n")
    return target


def load_detector(directory: str | os.PathLike[str]) -> tuple[str, Detector]:
    """Read a folder written by `save_detector`: (method name, fitted detector).

    Raises:
        FileNotFoundError: `method.json` or the model file is missing (the message names the path).
        ModelFormatError: not a model folder, a file that is not ours, another format version, an unknown
            method, or a malformed `method.json` or model file (the method's own `load` raises it for the
            model file, as `msvdd.model.MSVDD.load` and every baseline do), or an M-SVDD model saved before
            its method changed what it is; one line naming the file and what was expected. A model of a
            renamed method loads under its new name (the checks of `register_load_check`, e.g.
            `benchmarks.methods.msvdd_family.check_saved`).
    """
    folder = Path(directory)
    if folder.is_file():
        raise ModelFormatError(
            f"{folder} is not a msvdd-bench model folder (expected a folder written by `msvdd-bench train`, "
            f"holding {METHOD_FILE} and {MODEL_FILE})"
        )
    meta_path = folder / METHOD_FILE
    if not meta_path.is_file():
        raise InputNotFoundError(f"{meta_path} does not exist; not a saved model folder (or a partial one)")
    try:
        info = json.loads(meta_path.read_text(encoding="utf-8"))
    except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError
        raise ModelFormatError(
            f"{meta_path} is not a msvdd-bench model file (expected the JSON that `msvdd-bench train` writes)"
        ) from exc
    if not isinstance(info, dict):
        raise ModelFormatError(f"{meta_path} is not a msvdd-bench model file (expected a JSON object)")
    version = info.get("format_version")
    if version != METHOD_FORMAT_VERSION:
        raise ModelFormatError(
            f"{meta_path} has format_version {version}; this code reads {METHOD_FORMAT_VERSION}"
        )
    name = info.get("method")
    if not isinstance(name, str):
        raise ModelFormatError(f"{meta_path} names no method (got {name!r})")
    try:
        method = spec(name)
    except ValueError as exc:
        raise ModelFormatError(f"{meta_path} names method {name!r}, which cannot be built: {exc}") from exc
    model_path = folder / str(info.get("model_file", MODEL_FILE))
    if not model_path.is_file():
        raise InputNotFoundError(f"{model_path} does not exist (named by {meta_path})")
    detector: Detector = method.cls.load(model_path)
    try:
        for check in _LOAD_CHECKS:
            name = check(name, detector)
    except ModelFormatError as exc:
        raise ModelFormatError(f"{model_path}: {exc}") from exc
    return name, detector
