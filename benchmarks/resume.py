"""Resuming an interrupted `msvdd-bench run`: which finished models it may reuse.

A run works in `.<out>.partial/` beside its output folder and saves every model there as soon as it is
trained. An interrupted run (Ctrl-C, a crash, a session that ended) keeps that folder; `msvdd-bench run
... --resume` with the same `--out` then reuses each finished model instead of training it again, and trains
the rest. A model is reused only if its `training.json` (written after the model itself, so a model folder
without it is incomplete) records the same key: a sha256 over the method, its training seed, scale and
device, the dataset's fingerprint, the package versions and the source of the code that trains and saves it
(`TRAINING_PACKAGES`, `TRAINING_MODULES`, and the module of a `module:Class` detector). Change any of them and
the model is trained again, so a resumed run reports what an uninterrupted run of this code would report.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
from pathlib import Path

from benchmarks.cache import source_digest
from benchmarks.methods.external import is_external
from benchmarks.methods.registry import versions
from msvdd.atomic import write_text_atomic

TRAINING_FILE = "training.json"
"""Written into a model folder after the model: its resume key and its training time."""
TRAINING_PACKAGES: tuple[str, ...] = ("msvdd", "benchmarks.methods")
"""Packages whose every file is part of the code that trains a model."""
TRAINING_MODULES: tuple[str, ...] = (
    "benchmarks.dataset",
    "benchmarks.features",
    "benchmarks.modalities",
    "benchmarks.pipeline",
)
"""Single modules that are part of it (the training windows are read by `benchmarks.dataset`)."""


def partial_folder(out: Path) -> Path:
    """Where a run writing `out` works until it is done (and where an interrupted one left its models)."""
    return out.parent / f".{out.name}.partial"


def _method_files(method: str) -> tuple[Path, ...]:
    """The source file of a `module:Class` detector's module (none for a registered method)."""
    if not is_external(method):
        return ()
    found = importlib.util.find_spec(method.split(":", 1)[0])
    origin = None if found is None else found.origin
    return (Path(origin),) if origin and Path(origin).is_file() else ()


def code_digest(method: str) -> str:
    """sha256 of the source that trains `method` (`TRAINING_PACKAGES`, `TRAINING_MODULES`, its own module);
    a run takes it once, when it starts, so that every model's key names the code the run loaded."""
    return source_digest(TRAINING_PACKAGES, TRAINING_MODULES, _method_files(method))


def training_key(method: str, seed: int, scale: str, device: str, dataset_fingerprint: str, code: str) -> str:
    """The key a model must carry to be reused for `method` with these settings and `code_digest` `code`
    (module docstring); device "auto" counts as the device it picks on this machine."""
    if device == "auto":
        import torch

        device = "cuda" if torch.cuda.is_available() else "cpu"
    recipe = {
        "method": method,
        "seed": seed,
        "scale": scale,
        "device": device,
        "dataset": dataset_fingerprint,
        "versions": versions(),
        "code": code,
    }
    return hashlib.sha256(json.dumps(recipe, sort_keys=True).encode()).hexdigest()


def record_training(folder: Path, key: str, train_seconds: float) -> None:
    """Mark the model saved in `folder` as finished: its key and fit time, written atomically."""
    text = json.dumps({"key": key, "train_seconds": train_seconds}, indent=2, sort_keys=True) + "\n"
    write_text_atomic(folder / TRAINING_FILE, text)


def _training_record(folder: Path) -> dict[str, object] | None:
    """The `training.json` of the model in `folder`, or None if it has none or it cannot be read."""
    try:
        record = json.loads((folder / TRAINING_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def _seconds(record: dict[str, object]) -> float | None:
    seconds = record.get("train_seconds")
    return float(seconds) if isinstance(seconds, int | float) else None


def finished_training(folder: Path, key: str) -> float | None:
    """The fit time of the finished model in `folder` if it was trained with `key`; None otherwise."""
    record = _training_record(folder)
    if record is None or record.get("key") != key:
        return None
    return _seconds(record)


def recorded_train_seconds(folder: Path) -> float | None:
    """The fit time `training.json` records for the model in `folder`, whatever its key; None without one
    (a model trained before `msvdd-bench train` wrote it)."""
    record = _training_record(folder)
    return None if record is None else _seconds(record)
