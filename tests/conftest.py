"""Shared fixtures: a real tiny dataset (simulated and rendered once per session) and a model on it."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import torch
from threadpoolctl import threadpool_limits

if os.environ.get("PYTEST_XDIST_WORKER"):  # `make test` runs one worker per core: one thread each
    torch.set_num_threads(1)
    threadpool_limits(1)
else:
    torch.set_num_threads(2)


def pytest_runtest_setup(item: pytest.Item) -> None:
    """Fail a grouped test when `--dist loadgroup` did not keep its `xdist_group` on one worker: the groups
    exist because their tests share a costly session fixture (a Ray instance, an ONNX export, a sweep)."""
    grouped = item.get_closest_marker("xdist_group") is not None
    if grouped and getattr(item.config.option, "loadgroup", False) and "@" not in item.nodeid:
        pytest.fail(
            f"pytest {pytest.__version__} with this pytest-xdist ignores xdist_group (the test id has no "
            "group suffix); install the tested versions: pip install -c constraints.txt -e '.[dev]'",
            pytrace=False,
        )


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A dataset of the `tiny` preset, seed 0, generated through the real pipeline (in this process: each
    worker process would import the pipeline anew; `test_same_seed_same_checksums` builds it with two)."""
    from benchmarks.dataset import generate

    return generate("tiny", 0, tmp_path_factory.mktemp("data") / "tiny", workers=1, progress=False)


@pytest.fixture(scope="session")
def tiny_model(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """M-SVDD at the `smoke` scale trained on `tiny_dataset`; the saved model folder."""
    from benchmarks.dataset import open_dataset
    from benchmarks.pipeline import train_method

    out = tmp_path_factory.mktemp("models") / "msvdd"
    return train_method(open_dataset(tiny_dataset), "msvdd", 0, "smoke", out).path
