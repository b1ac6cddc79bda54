"""One conformance test run over every registered method, at tiny scale, on the toy windows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from benchmarks import methods
from msvdd.contract import Detector, Windows
from msvdd.synthetic import toy_windows

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def toy() -> tuple[Windows, Windows, np.ndarray]:
    windows, labels = toy_windows(n_normal=112, n_anomalous=16, seed=11)
    train = windows.subset(slice(0, 80))
    test = windows.subset(slice(80, None))
    return train, test, labels[80:]


@pytest.mark.parametrize("name", methods.names())
def test_method_conforms(name: str, toy: tuple[Windows, Windows, np.ndarray], tmp_path: Path) -> None:
    train, test, _ = toy
    detector = methods.make(name, seed=0, scale="tiny")
    assert isinstance(detector, Detector)
    with pytest.raises((RuntimeError, ValueError)):
        detector.score(test)  # not fitted yet
    assert detector.fit(train) is detector

    scores = detector.score(test)
    assert scores.shape == (len(test),) and scores.dtype == np.float64
    assert np.all(np.isfinite(scores))
    assert np.ptp(scores) > 0, "scores are constant"

    train_scores = detector.score(train)
    assert detector.threshold_ == pytest.approx(np.percentile(train_scores, 95), rel=1e-9, abs=1e-12)
    threshold = detector.threshold_
    np.testing.assert_array_equal(detector.predict(test), scores > threshold)
    assert detector.threshold_ == threshold  # scoring other data never moves the threshold

    folder = methods.save_detector(detector, name, tmp_path / "model")
    loaded_name, loaded = methods.load_detector(folder)
    assert loaded_name == name
    assert loaded.threshold_ == threshold
    np.testing.assert_array_equal(loaded.score(test), scores)

    with pytest.raises((TypeError, ValueError)):
        detector.score(test.audio)  # type: ignore[arg-type]
    with pytest.raises((TypeError, ValueError)):
        methods.make(name, seed=0, scale="tiny").fit(train.subset(slice(0, 1)))


# The ablations share M-SVDD's code path: "msvdd" stands for them here (each runs the test above).
@pytest.mark.parametrize("name", [n for n in methods.names() if not n.startswith("msvdd-")])
def test_method_is_deterministic_for_a_seed(name: str, toy: tuple[Windows, Windows, np.ndarray]) -> None:
    train, test, _ = toy
    a = methods.make(name, seed=3, scale="tiny").fit(train).score(test)
    b = methods.make(name, seed=3, scale="tiny").fit(train).score(test)
    np.testing.assert_array_equal(a, b)
