"""Detector speed: M-SVDD training and inference throughput on CPU, and FastMCD against scikit-learn.

Workloads use the toy windows of `msvdd.synthetic` (real shapes: 8820 x 2 audio, 400 IMU) and the paper's
network (d = s = 32, batch 64). Training throughput is the real loss (per-batch MCD, SVDD, reconstruction,
regulariser) with forward, backward and Adam step on 2 threads; inference is `MSVDD.score` (normalisation,
smoothing, network, Mahalanobis, reconstruction) on 1 thread for a batch of one and on 2 threads batched.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import torch
from sklearn.covariance import MinCovDet
from threadpoolctl import threadpool_limits

from benchmarks.perf.base import PerfStage
from msvdd.config import MSVDDConfig
from msvdd.frontend import InputNormalizer
from msvdd.mcd import min_cov_det
from msvdd.model import MSVDD
from msvdd.synthetic import toy_windows
from msvdd.training import train_network

PAPER_TRAIN_WINDOWS = 5000
"""Training windows of the paper preset (42 training sequences of 120 s at a 1 s hop: 4998)."""


@contextmanager
def _threads(n: int) -> Iterator[None]:
    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        with threadpool_limits(limits=n):
            yield
    finally:
        torch.set_num_threads(before)


def _fitted_model(n: int) -> MSVDD:
    train, _ = toy_windows(n, 0, seed=0)
    return MSVDD(MSVDDConfig.paper(epochs=1, progress=False, val_fraction=0.0)).fit(train)


def _train_rate(quick: bool) -> float:
    n = 128 if quick else 640
    model = MSVDD(MSVDDConfig.paper(epochs=1, progress=False, val_fraction=0.0))
    train, _ = toy_windows(n, 0, seed=1)
    cfg = model.config
    model.normalizer, tensors = InputNormalizer.fit_tensors(
        train, cfg.audio_frontend, cfg.imu_input, cfg.smooth_window, cfg.smooth_polyorder
    )
    warm = tuple(t[:128] for t in tensors)
    train_network(model.module, model.batch_loss, warm, None, model.config)
    result = train_network(model.module, model.batch_loss, tensors, None, model.config)
    return result.windows_per_s


def _infer(model: MSVDD, quick: bool) -> tuple[float, float]:
    batch, _ = toy_windows(64 if quick else 256, 0, seed=2)
    one = batch.subset(slice(0, 1))
    with _threads(1):
        model.score(one)
        times = []
        for _ in range(5 if quick else 30):
            t0 = time.perf_counter()
            model.score(one)
            times.append(time.perf_counter() - t0)
        ms_one = 1000.0 * float(np.median(times))
    with _threads(2):
        model.score(batch.subset(slice(0, 8)))
        t0 = time.perf_counter()
        model.score(batch)
        rate = len(batch) / (time.perf_counter() - t0)
    return ms_one, rate


def _mcd(quick: bool) -> dict[str, float]:
    n, p = (1500, 32) if quick else (5000, 32)
    rng = np.random.default_rng(0)
    mix = np.eye(p) + 0.3 * rng.standard_normal((p, p))
    x = rng.standard_normal((n, p)) @ mix.T
    k = int(0.15 * n)
    x[:k] = rng.standard_normal((k, p)) + 6.0
    with _threads(1):
        t0 = time.perf_counter()
        ref = MinCovDet(random_state=0).fit(x)
        t_ref = time.perf_counter() - t0
        min_cov_det(torch.from_numpy(x[:200]), random_state=0)
        t0 = time.perf_counter()
        ours = min_cov_det(torch.from_numpy(x), random_state=0)
        t_ours = time.perf_counter() - t0
    support = ours.support.numpy()
    return {
        "mcd_speedup_vs_sklearn": t_ref / t_ours,
        "mcd_ms": 1000.0 * t_ours,
        "mcd_sklearn_ms": 1000.0 * t_ref,
        "mcd_support_agreement": float(np.mean(support == ref.raw_support_)),
        "mcd_logdet_gap": float(ours.log_det - np.linalg.slogdet(ref.raw_covariance_)[1]),
        "mcd_outliers_in_support": float(support[:k].sum()),
    }


def measure(quick: bool) -> dict[str, float]:
    """Figures of the detector stage (see `describe`)."""
    load = os.getloadavg()[0]
    with _threads(2):
        train_rate = _train_rate(quick)
        model = _fitted_model(64 if quick else 128)
    ms_one, rate = _infer(model, quick)
    return {
        "train_windows_per_s": train_rate,
        "paper_train_minutes_2cpu": PAPER_TRAIN_WINDOWS * MSVDDConfig.paper().epochs / train_rate / 60.0,
        "infer_ms_per_window": ms_one,
        "infer_windows_per_s": rate,
        **_mcd(quick),
        "load_avg_1min_at_start": load,
    }


STAGE = PerfStage(
    name="detector",
    measure=measure,
    describe={
        "train_windows_per_s": "M-SVDD paper network training windows/s, 2 CPU threads (target >= 220)",
        "paper_train_minutes_2cpu": "estimated paper preset training (5000 windows x 40 epochs), min (<= 15)",
        "infer_ms_per_window": "MSVDD.score latency for one window, 1 CPU thread, ms (target <= 3)",
        "infer_windows_per_s": "MSVDD.score batched throughput, 2 CPU threads, windows/s",
        "mcd_speedup_vs_sklearn": "min_cov_det vs sklearn MinCovDet at n=5000, p=32, 1 thread (target >= 10)",
        "mcd_ms": "min_cov_det wall time at n=5000, p=32, ms",
        "mcd_sklearn_ms": "sklearn MinCovDet wall time at n=5000, p=32, ms",
        "mcd_support_agreement": "fraction of samples on which both supports agree (same answer: ~1)",
        "mcd_logdet_gap": "log det of our raw covariance minus sklearn's (<= ~0: as good or better)",
        "mcd_outliers_in_support": "planted outliers (15%) inside our support (should be 0)",
        "load_avg_1min_at_start": "1-min load average at the start (above the cores: figures pessimistic)",
    },
)
