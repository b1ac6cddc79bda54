"""`context-net-frames` and `frame-density` (densities of the normalised input frames given their neighbours,
without a network) against `msvdd.context` and `msvdd.context_net` by hand, and `frame-density` against the
frame term of `frame-density-msvdd`."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

from benchmarks import methods
from benchmarks.methods.frames import MIXTURE_COMPONENTS, ContextNetFrames
from msvdd.context import fit_context_mixture
from msvdd.context_net import fit_context_net
from msvdd.contract import WindowError
from msvdd.frontend import InputNormalizer
from msvdd.model import MSVDD
from msvdd.synthetic import toy_windows


def _input_frames(norm: InputNormalizer, batch: object) -> list[np.ndarray]:
    """msvdd's normalised inputs cut into log-mel frames (67 x 64) and IMU frames (50 x 56), float64."""
    audio, imu = norm.tensors(batch)  # type: ignore[arg-type]
    n = audio.shape[0]
    return [
        audio.permute(0, 2, 1, 3).reshape(n, 67, 64).numpy().astype(np.float64),
        imu.reshape(n, 50, 56).numpy().astype(np.float64),
    ]


def test_context_net_scores_the_audio_by_its_network_and_the_imu_by_the_context_mixture(
    tmp_path: Path,
) -> None:
    train, _ = toy_windows(40, 0, seed=3)
    val, _ = toy_windows(10, 0, seed=7)
    test, labels = toy_windows(3, 3, seed=4)
    det = methods.make("context-net-frames", seed=5, scale="smoke").fit(train, val)
    assert isinstance(det, ContextNetFrames)
    # By hand: the log-mel frames' `ContextNet` (the validation windows' frames choosing its epoch; tested in
    # tests/msvdd/test_context_net.py), the IMU frames' context mixture, each window's largest distance over
    # its training mean, summed.
    norm = InputNormalizer.fit(train, "logmel", "all")
    (a_tr, i_tr), (a_te, i_te) = _input_frames(norm, train), _input_frames(norm, test)
    a_val = torch.from_numpy(_input_frames(norm, val)[0])
    net = fit_context_net(torch.from_numpy(a_tr).float(), a_val.float(), seed=5)
    imu = fit_context_mixture(torch.from_numpy(i_tr), MIXTURE_COMPONENTS, seed=5)
    want = np.zeros(len(test))
    for model, tr, te in ((net, a_tr, a_te), (imu, i_tr, i_te)):
        want += (
            model.peak_distance(torch.from_numpy(te)).numpy()
            / model.peak_distance(torch.from_numpy(tr)).numpy().mean()
        )
    np.testing.assert_allclose(det.score(test), want, rtol=1e-5)
    assert det.score(test)[labels == 1].min() > det.score(test)[labels == 0].max()  # the toy anomalies
    det.save(tmp_path / "m.npz")
    loaded = ContextNetFrames.load(tmp_path / "m.npz")
    np.testing.assert_array_equal(loaded.score(test), det.score(test))
    again = methods.make("context-net-frames", seed=5, scale="smoke").fit(train, val)
    np.testing.assert_array_equal(again.score(test), det.score(test))
    with pytest.raises(WindowError, match="at least 200 training frames per modality; got 100"):
        ContextNetFrames(seed=0, components=200).fit(toy_windows(2, 0, seed=6)[0])


def test_components_must_be_positive() -> None:
    with pytest.raises(ValueError, match="components = 0 is invalid"):
        ContextNetFrames(components=0)


def test_frame_density_is_the_frame_term_of_frame_density_msvdd_without_its_network(tmp_path: Path) -> None:
    torch.set_num_threads(1)
    train, _ = toy_windows(40, 0, seed=3)
    val, _ = toy_windows(12, 0, seed=7)  # enough for the validation MCD of s = 8: both choose epochs on it
    test, _ = toy_windows(3, 3, seed=4)
    twin = methods.make("frame-density", seed=5, scale="smoke").fit(train, val)
    assert isinstance(twin, ContextNetFrames) and twin.imu_net
    with_net = methods.make("frame-density-msvdd", seed=5, scale="smoke")
    with_net.config = dataclasses.replace(with_net.config, epochs=1, batch_size=16)  # type: ignore[attr-defined]
    with_net.fit(train, val)
    assert isinstance(with_net, MSVDD) and with_net.config.frame_density
    # The same densities of the same frames: the twin's terms are frame-density-msvdd's second term, and its
    # score that term; frame-density-msvdd adds its network's D.
    _, term = with_net.score_components(test)
    np.testing.assert_allclose(twin.modality_scores(test).sum(axis=1), term, rtol=1e-5)
    d, _ = with_net.score_components(test)
    ratio = with_net.mean_d_ / with_net.mean_rec_
    np.testing.assert_allclose(with_net.score(test), d + with_net.config.w * ratio * term, rtol=1e-12)
    # Persistence of the IMU network.
    methods.save_detector(twin, "frame-density", tmp_path / "m")
    name, again = methods.load_detector(tmp_path / "m")
    assert name == "frame-density"
    np.testing.assert_array_equal(again.score(test), twin.score(test))
