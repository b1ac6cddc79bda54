"""One conformance test run over every registered method, at the smoke budget, on toy windows: the detector
contract, the same scores from the same seed, and an obvious planted anomaly scored above the normal
windows."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch

from benchmarks import methods
from benchmarks.metrics import roc_auc
from msvdd.contract import AUDIO_LEN, IMU_LEN, MIN_HELD_OUT, Detector, NotFittedError, WindowError, Windows
from msvdd.synthetic import toy_windows

torch.set_num_threads(1)


PLANTED_AUC_MIN = 0.75
"""Every method must rank the planted anomalies above the normal windows they were planted in at least this
often (the AUC); at the smoke budget the weakest (deep-if, dsvdd, vae-svdd) reach about 0.9 at seed 0."""


def plant_obvious_anomaly(windows: Windows, seed: int) -> Windows:
    """`windows` with an anomaly in everything a method may read: a loud broadband burst in both audio
    channels (0.5 s of unit-variance noise, about 2x the window's RMS) and a large 25 ms spike in the IMU
    z-velocity (50x its normal amplitude) and on every imu6 axis."""
    assert windows.imu6 is not None
    rng = np.random.default_rng(seed)
    audio, imu, imu6 = windows.audio.copy(), windows.imu.copy(), windows.imu6.copy()
    a0, a1 = AUDIO_LEN // 4, AUDIO_LEN // 2
    audio[:, a0:a1, :] += rng.standard_normal((len(windows), a1 - a0, 2)).astype(np.float32)
    i0, i1 = IMU_LEN // 2 - 2, IMU_LEN // 2 + 3
    imu[:, i0:i1] += 1.0
    imu6[:, i0:i1, :] += 20.0
    return Windows(audio=audio, imu=imu, imu6=imu6, odometry=windows.odometry)


@dataclass(frozen=True)
class Toy:
    train: Windows
    """Nominal toy windows to fit on."""
    val: Windows
    """Held-out nominal toy windows (`MIN_HELD_OUT` + 4): model selection and the threshold."""
    test: Windows
    """Held-out toy windows, nominal and toy anomalies."""
    normal: Windows
    """The nominal windows of `test`."""
    planted: Windows
    """`normal` with `plant_obvious_anomaly`."""


@pytest.fixture(scope="module")
def toy() -> Toy:
    windows, labels = toy_windows(n_normal=112, n_anomalous=16, seed=11)
    test = windows.subset(slice(80, None))
    normal = test.subset(np.flatnonzero(labels[80:] == 0))
    val, _ = toy_windows(n_normal=MIN_HELD_OUT + 4, n_anomalous=0, seed=12)
    return Toy(windows.subset(slice(0, 80)), val, test, normal, plant_obvious_anomaly(normal, seed=5))


@pytest.mark.parametrize("name", methods.names())
def test_method_conforms(name: str, toy: Toy, tmp_path: Path) -> None:
    train, test = toy.train, toy.test
    detector = methods.make(name, seed=0, scale="smoke")
    assert isinstance(detector, Detector)
    with pytest.raises(NotFittedError):
        detector.score(test)
    assert detector.fit(train, toy.val) is detector

    scores = detector.score(test)
    assert scores.shape == (len(test),) and scores.dtype == np.float64
    assert np.all(np.isfinite(scores))
    assert np.ptp(scores) > 0, "scores are constant"
    if not name.startswith("msvdd-"):  # the ablations share M-SVDD's code path: "msvdd" stands for them
        twin = methods.make(name, seed=0, scale="smoke").fit(train, toy.val)
        np.testing.assert_array_equal(twin.score(test), scores, err_msg="same seed, other scores")

    normal, planted = detector.score(toy.normal), detector.score(toy.planted)
    labels = np.r_[np.zeros(normal.size), np.ones(planted.size)]
    auc = roc_auc(labels, np.r_[normal, planted])
    assert auc >= PLANTED_AUC_MIN, f"{name} ranks obvious anomalies above normal windows with AUC {auc:.2f}"

    # the one threshold rule: the 95th percentile of the held-out nominal windows' scores
    assert detector.threshold_source_ == "val"
    val_scores = detector.score(toy.val)
    assert detector.threshold_ == pytest.approx(np.quantile(val_scores, 0.95), rel=1e-9, abs=1e-12)
    threshold = detector.threshold_
    np.testing.assert_array_equal(detector.predict(test), scores > threshold)
    assert detector.threshold_ == threshold  # scoring other data never moves the threshold

    folder = methods.save_detector(detector, name, tmp_path / "model")
    loaded_name, loaded = methods.load_detector(folder)
    assert loaded_name == name
    assert loaded.threshold_ == threshold and loaded.threshold_source_ == "val"
    np.testing.assert_array_equal(loaded.score(test), scores)

    with pytest.raises(WindowError):
        detector.score(test.audio)  # type: ignore[arg-type]
    with pytest.raises(WindowError):
        methods.make(name, seed=0, scale="smoke").fit(train.subset(slice(0, 1)))


@pytest.mark.parametrize("n_val", [0, MIN_HELD_OUT - 1])
def test_threshold_from_training_windows_without_enough_held_out(n_val: int, toy: Toy) -> None:
    val = toy.val.subset(slice(0, n_val)) if n_val else None
    detector = methods.make("audio-rms", seed=0, scale="smoke").fit(toy.train, val)
    assert detector.threshold_source_ == "train"
    assert detector.threshold_ == np.quantile(detector.score(toy.train), 0.95)
