"""Speed of the shallow baselines' path: handcrafted features, the one-class SVM solve (libsvm), fitting.

Runs on toy windows (`msvdd.synthetic`) and random features; one thread for torch. `svdd-*` is the same
one-class SVM as `ocsvm-*` (identical duals with an RBF kernel, `benchmarks.methods.shallow`), so one
solve time stands for both. The feature extraction (log-mel spectra: FFTs; best of 3) is also given
against the reference kernel (`benchmarks.perf.base.fft_reference_s`: one FFT convolution as long as the
windows' audio) measured in the same process just before it, on the same clock.
"""

from __future__ import annotations

import time

import numpy as np
from sklearn.svm import OneClassSVM

from benchmarks.features import window_features
from benchmarks.methods import make
from benchmarks.methods.shallow import NU
from benchmarks.perf.base import PerfStage, best_time, fft_reference_s
from msvdd.synthetic import toy_windows


def _measure(quick: bool) -> dict[str, float]:
    n_windows = 100 if quick else 1000
    n_rows = 300 if quick else 2000
    windows, _ = toy_windows(n_windows, 0, seed=0)
    reference = fft_reference_s(windows.audio.shape[0] * windows.audio.shape[1], clock=time.perf_counter)
    features_s = best_time(
        lambda r: window_features(windows), 1 if quick else 3, time.perf_counter, warm=False
    )
    feats = window_features(windows.subset(slice(0, 8)))
    rng = np.random.default_rng(0)
    rows = rng.standard_normal((n_rows, feats.early().shape[1]))
    started = time.perf_counter()
    OneClassSVM(kernel="rbf", nu=NU, gamma="scale").fit(rows)
    ocsvm_s = time.perf_counter() - started
    figures = {
        "features_ms_per_window": 1000.0 * features_s / n_windows,
        "features_vs_fft": features_s / reference,
        "ocsvm_solve_s": ocsvm_s,
    }
    for name in ("iforest-early", "ocsvm-late"):
        detector = make(name, seed=0, scale="short")
        started = time.perf_counter()
        detector.fit(windows)
        figures[f"{name.replace('-', '_')}_fit_windows_per_s"] = n_windows / (time.perf_counter() - started)
    return figures


STAGE = PerfStage(
    name="baselines",
    measure=_measure,
    describe={
        "features_ms_per_window": "handcrafted log-mel + IMU features, ms per 2 s window (1000 toy windows)",
        "features_vs_fft": "feature extraction time / one FFT convolution as long as the windows' audio "
        "(stereo, 4096 taps) in the same process (lower is better)",
        "ocsvm_solve_s": "one-class SVM (libsvm; = kernel SVDD), 2000 random rows (300 with --quick), s",
        "iforest_early_fit_windows_per_s": "iforest-early fit with features, windows per s (short budget)",
        "ocsvm_late_fit_windows_per_s": "ocsvm-late (= svdd-late) fit with features, toy windows per s",
    },
    ratios={"features_vs_fft": "lower"},
)
