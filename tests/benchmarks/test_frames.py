"""`gaussian-frames` (msvdd's frame-wise Mahalanobis term without the network) against scikit-learn, scipy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.distance import mahalanobis
from sklearn.covariance import LedoitWolf

from benchmarks import methods
from benchmarks.methods.frames import FrameReference
from msvdd.frontend import InputNormalizer
from msvdd.synthetic import toy_windows


def test_scores_are_the_largest_frame_distances_by_hand(tmp_path: Path) -> None:
    train, _ = toy_windows(40, 0, seed=3)
    test, labels = toy_windows(3, 3, seed=4)
    det = methods.make("gaussian-frames", seed=0, scale="smoke").fit(train)
    assert isinstance(det, FrameReference)
    # By hand: msvdd's normalised inputs, cut into log-mel frames (both channels' 32 bands) and 8-sample IMU
    # frames (7 axes); per modality scikit-learn's Ledoit-Wolf Gaussian of the training frames, scipy's
    # Mahalanobis distance, the largest over a window's frames, over its training mean; summed.
    norm = InputNormalizer.fit(train, "logmel", "all")

    def frames(batch: object) -> list[np.ndarray]:
        audio, imu = norm.tensors(batch)  # type: ignore[arg-type]
        n = audio.shape[0]
        return [
            audio.permute(0, 2, 1, 3).reshape(n, 67, 64).numpy().astype(np.float64),
            imu.reshape(n, 50, 56).numpy().astype(np.float64),
        ]

    want = np.zeros(len(test))
    for tr, te in zip(frames(train), frames(test), strict=True):
        peer = LedoitWolf().fit(tr.reshape(-1, tr.shape[2]))
        precision = np.linalg.inv(peer.covariance_)

        def peak(x: np.ndarray, p: LedoitWolf = peer, inv: np.ndarray = precision) -> np.ndarray:
            return np.array([max(mahalanobis(f, p.location_, inv) for f in w) for w in x])

        want += peak(te) / peak(tr).mean()
    np.testing.assert_allclose(det.score(test), want, rtol=1e-5)
    assert det.score(test)[labels == 1].min() > det.score(test)[labels == 0].max()  # the toy anomalies
    det.save(tmp_path / "m.npz")
    np.testing.assert_array_equal(FrameReference.load(tmp_path / "m.npz").score(test), det.score(test))
