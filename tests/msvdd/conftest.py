"""Shared fixtures: one small trained model on the toy task, reused by the slower tests."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from msvdd.config import MSVDDConfig
from msvdd.contract import Windows
from msvdd.model import MSVDD
from msvdd.synthetic import toy_windows

torch.set_num_threads(1)


@pytest.fixture(scope="session")
def toy_train() -> Windows:
    return toy_windows(128, 0, seed=0)[0]


@pytest.fixture(scope="session")
def toy_test() -> tuple[Windows, np.ndarray]:
    return toy_windows(40, 40, seed=1)


@pytest.fixture(scope="session")
def small_model(toy_train: Windows) -> MSVDD:
    """A briefly trained model (2 epochs): enough for contract, persistence and streaming checks."""
    return MSVDD(MSVDDConfig.smoke(epochs=2)).fit(toy_train)
