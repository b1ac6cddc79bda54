"""Shared fixtures: a real tiny dataset (simulated and rendered once per session) and a model on it."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

torch.set_num_threads(2)


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A dataset of the `tiny` preset, seed 0, generated through the real pipeline."""
    from benchmarks.dataset import generate

    return generate("tiny", 0, tmp_path_factory.mktemp("data") / "tiny", workers=2, progress=False)


@pytest.fixture(scope="session")
def tiny_model(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """M-SVDD at the `tiny` scale trained on `tiny_dataset`; the saved model folder."""
    from benchmarks.dataset import open_dataset
    from benchmarks.pipeline import train_method

    out = tmp_path_factory.mktemp("models") / "msvdd"
    return train_method(open_dataset(tiny_dataset), "msvdd", 0, "tiny", out).path
