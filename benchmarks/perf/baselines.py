"""Speed of the shallow baselines' path: handcrafted features, our kernel SVDD solver against libsvm, fitting.

Runs on toy windows (`msvdd.synthetic`) and random features; one thread for torch. The kernel SVDD's SMO
solves the same dual as scikit-learn's one-class SVM for an RBF kernel (nu = 0.05), so the ratio of their
times is a like-for-like comparison of the solvers.
"""

from __future__ import annotations

import time

import numpy as np
from sklearn.svm import OneClassSVM

from benchmarks.features import window_features
from benchmarks.methods import make
from benchmarks.methods.kernel_svdd import KernelSVDD
from benchmarks.perf.base import PerfStage
from msvdd.synthetic import toy_windows


def _measure(quick: bool) -> dict[str, float]:
    n_windows = 100 if quick else 1000
    n_rows = 300 if quick else 2000
    windows, _ = toy_windows(n_windows, 0, seed=0)
    started = time.perf_counter()
    feats = window_features(windows)
    features_s = time.perf_counter() - started
    rng = np.random.default_rng(0)
    rows = rng.standard_normal((n_rows, feats.early().shape[1]))
    started = time.perf_counter()
    svdd = KernelSVDD(nu=0.05, max_train=n_rows).fit(rows)
    svdd_s = time.perf_counter() - started
    started = time.perf_counter()
    OneClassSVM(kernel="rbf", nu=0.05, gamma=svdd.gamma_).fit(rows)
    ocsvm_s = time.perf_counter() - started
    figures = {
        "features_ms_per_window": 1000.0 * features_s / n_windows,
        "svdd_solve_s": svdd_s,
        "svdd_vs_libsvm_time_ratio": svdd_s / ocsvm_s,
    }
    for name in ("iforest-early", "svdd-late"):
        detector = make(name, seed=0, scale="quick")
        started = time.perf_counter()
        detector.fit(windows)
        figures[f"{name.replace('-', '_')}_fit_windows_per_s"] = n_windows / (time.perf_counter() - started)
    return figures


STAGE = PerfStage(
    name="baselines",
    measure=_measure,
    describe={
        "features_ms_per_window": "handcrafted log-mel + IMU features, ms per 2 s window (1000 toy windows)",
        "svdd_solve_s": "kernel SVDD dual by our SMO, 2000 x 117 random rows (300 with --quick), s",
        "svdd_vs_libsvm_time_ratio": "our SMO time / scikit-learn OneClassSVM (libsvm) time, same dual",
        "iforest_early_fit_windows_per_s": "iforest-early fit with features, toy windows per s (quick scale)",
        "svdd_late_fit_windows_per_s": "svdd-late fit incl. features, toy windows per s (quick scale)",
    },
)
