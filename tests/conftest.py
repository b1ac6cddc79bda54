"""Shared fixtures: a real tiny dataset (simulated and rendered once per test run) and a model on it.

Under pytest-xdist each worker has its own session; the dataset and the model are built once for the whole
run by whichever worker asks first (a file lock in the workers' common temporary folder) and read by all.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
import torch
from filelock import FileLock
from threadpoolctl import threadpool_limits

if os.environ.get("PYTEST_XDIST_WORKER"):  # `make test` runs one worker per core: one thread each
    torch.set_num_threads(1)
    threadpool_limits(1)
else:
    torch.set_num_threads(2)


def _built_once(tmp_path_factory: pytest.TempPathFactory, name: str, build: Callable[[Path], Path]) -> Path:
    """`build(folder)` run once per test run; its folder (shared by the xdist workers, read-only to tests)."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return build(tmp_path_factory.mktemp(name) / name)
    root = tmp_path_factory.getbasetemp().parent  # the same folder for every worker of this run
    target = root / name
    with FileLock(str(root / f"{name}.lock")):
        if not target.exists():
            staging = root / f".{name}.partial"
            shutil.rmtree(staging, ignore_errors=True)  # a worker that failed building it earlier
            staging.mkdir()
            built = build(staging / name)
            built.rename(target)  # complete, or absent
    return target


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A dataset of the `tiny` preset, seed 0, generated through the real pipeline."""
    from benchmarks.dataset import generate

    return _built_once(
        tmp_path_factory, "tiny", lambda out: generate("tiny", 0, out, workers=2, progress=False)
    )


@pytest.fixture(scope="session")
def tiny_model(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """M-SVDD at the `tiny` scale trained on `tiny_dataset`; the saved model folder."""
    from benchmarks.dataset import open_dataset
    from benchmarks.pipeline import train_method

    def train(out: Path) -> Path:
        return train_method(open_dataset(tiny_dataset), "msvdd", 0, "smoke", out).path

    return _built_once(tmp_path_factory, "tiny-msvdd", train)
