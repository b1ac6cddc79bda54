"""Detector speed: M-SVDD training and inference throughput on CPU, and FastMCD against scikit-learn.

Workloads use the toy windows of `msvdd.synthetic` (real shapes: 8820 x 2 audio, 400 IMU) and the paper's
network (d = s = 32, batch 64). Training throughput is the real loss (per-batch MCD, SVDD, reconstruction,
regulariser) with forward, backward and Adam step on 2 threads; inference is `MSVDD.score` (normalisation,
smoothing, network, Mahalanobis, reconstruction) on 1 thread for a batch of one and on 2 threads batched.

The ONNX figures put the exported scoring path (`msvdd.export`, `msvdd.onnx_backend.OnnxScorer`, ONNX Runtime
on 1 thread) against torch eager measured in the same run on the same fitted model: for the paper network
(waveform, z-velocity) and for the registry's `msvdd` (log-mel, all IMU axes, `DEV_CHOICE`):
latency of one window (wall clock, median), and the real-time factor of `StreamingScorer` (raw 44.1 kHz audio
and 200 Hz IMU pushed in 100 ms chunks, a window every 0.5 s, decimation included; recording seconds per CPU
second of the one thread) with each backend.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch
from sklearn.covariance import MinCovDet
from threadpoolctl import threadpool_limits

from benchmarks.methods.msvdd_family import DEV_CHOICE
from benchmarks.perf.base import PerfStage, best_time
from msvdd.config import MSVDDConfig
from msvdd.contract import Windows
from msvdd.export import export_onnx, max_relative_difference
from msvdd.frontend import InputNormalizer
from msvdd.mcd import MCDResult, min_cov_det
from msvdd.model import MSVDD
from msvdd.onnx_backend import OnnxScorer
from msvdd.stream import StreamingScorer, WindowScorer
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


def _fitted_model(n: int, **overrides: object) -> MSVDD:
    train, _ = toy_windows(n, 0, seed=0)
    return MSVDD(MSVDDConfig.full(epochs=1, progress=False, val_fraction=0.0, **overrides)).fit(train)


def _train_rate(quick: bool) -> float:
    n = 128 if quick else 640
    model = MSVDD(MSVDDConfig.full(epochs=1, progress=False, val_fraction=0.0))
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
    fits: dict[str, object] = {}
    with _threads(1):
        t_ref = best_time(
            lambda r: fits.update(ref=MinCovDet(random_state=0).fit(x)),
            1 if quick else 2,
            time.perf_counter,
            warm=False,
        )
        t_ours = best_time(
            lambda r: fits.update(ours=min_cov_det(torch.from_numpy(x), random_state=0)),
            1 if quick else 5,
            time.perf_counter,
        )
    ref, ours = fits["ref"], fits["ours"]
    assert isinstance(ref, MinCovDet) and isinstance(ours, MCDResult)
    support = ours.support.numpy()
    return {
        "mcd_speedup_vs_sklearn": t_ref / t_ours,
        "mcd_ms": 1000.0 * t_ours,
        "mcd_sklearn_ms": 1000.0 * t_ref,
        "mcd_support_agreement": float(np.mean(support == ref.raw_support_)),
        "mcd_logdet_gap": float(ours.log_det - np.linalg.slogdet(ref.raw_covariance_)[1]),
        "mcd_outliers_in_support": float(support[:k].sum()),
    }


def _median_ms(fn: Callable[[], object], reps: int) -> float:
    fn()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1000.0 * float(np.median(times))


def _stream_rtf(backend: WindowScorer, seconds: float) -> float:
    """Recording seconds streamed through `StreamingScorer` (100 ms chunks) per second of this process's CPU
    time (everything runs on one thread, so what one core sustains; other load on the machine does not
    count)."""
    rng = np.random.default_rng(4)
    t = np.arange(int(44100 * seconds)) / 44100
    tone = 0.3 * np.sin(2 * np.pi * 90 * t) + 0.05 * rng.standard_normal(t.size)
    audio = np.stack([tone, 0.8 * tone], axis=1)
    n_imu = int(200 * seconds)
    imu = (0.02 * np.sin(2 * np.pi * np.arange(n_imu) / 200)).astype(np.float32)
    imu6 = (0.03 * rng.standard_normal((n_imu, 6)) + [0, 0, 9.81, 0, 0, 0]).astype(np.float32)
    scorer = StreamingScorer(backend, hop_s=0.5)
    t0 = time.process_time()
    for k in range(int(seconds * 10)):
        scorer.push(audio[4410 * k : 4410 * (k + 1)], imu[20 * k : 20 * (k + 1)], imu6[20 * k : 20 * (k + 1)])
    cpu = time.process_time() - t0
    if scorer.n_emitted < 2 * seconds - 5:
        raise RuntimeError(f"the streaming benchmark emitted only {scorer.n_emitted} windows")
    return seconds / cpu


def _onnx_figures(model: MSVDD, prefix: str, quick: bool, one: Windows) -> dict[str, float]:
    """Export `model`, then ONNX Runtime against torch eager (both 1 thread) on one window and streaming."""
    with tempfile.TemporaryDirectory(prefix="msvdd-perf-onnx-") as tmp:
        t0 = time.perf_counter()
        export_onnx(model, Path(tmp) / "onnx")
        export_s = time.perf_counter() - t0
        scorer = OnnxScorer.load(Path(tmp) / "onnx", threads=1)
    check, _ = toy_windows(8, 8, seed=3)
    reps = 5 if quick else 50
    seconds = 6.0 if quick else 30.0
    with _threads(1):
        parity = max_relative_difference(scorer.score(check), model.score(check))
        onnx_ms = _median_ms(lambda: scorer.score(one), reps)
        torch_ms = _median_ms(lambda: model.score(one), reps)
        rtf_onnx = _stream_rtf(scorer, seconds)
        rtf_torch = _stream_rtf(model, seconds)
    return {
        f"{prefix}onnx_ms_per_window": onnx_ms,
        f"{prefix}onnx_speedup_vs_torch": torch_ms / onnx_ms,
        f"{prefix}onnx_stream_realtime_factor": rtf_onnx,
        f"{prefix}onnx_stream_speedup_vs_torch": rtf_onnx / rtf_torch,
        f"{prefix}onnx_parity_max_rel": parity,
        f"{prefix}onnx_export_s": export_s,
    }


def measure(quick: bool) -> dict[str, float]:
    """Figures of the detector stage (see `describe`)."""
    load = os.getloadavg()[0]
    with _threads(2):
        train_rate = _train_rate(quick)
        model = _fitted_model(64 if quick else 128)
        logmel = _fitted_model(64 if quick else 128, **DEV_CHOICE)
    ms_one, rate = _infer(model, quick)
    one = toy_windows(1, 0, seed=2)[0]
    return {
        "train_windows_per_s": train_rate,
        "paper_train_minutes_2cpu": PAPER_TRAIN_WINDOWS * MSVDDConfig.full().epochs / train_rate / 60.0,
        "infer_ms_per_window": ms_one,
        "infer_windows_per_s": rate,
        **_onnx_figures(model, "", quick, one),
        **_onnx_figures(logmel, "logmel_", quick, one),
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
        **{
            f"{prefix}{key}": f"{what} ({net}): {text}"
            for prefix, net in (("", "paper network"), ("logmel_", "registry msvdd: log-mel, all IMU axes"))
            for key, what, text in (
                ("onnx_ms_per_window", "OnnxScorer.score latency, one window", "1 thread, ms (target <= 1)"),
                ("onnx_speedup_vs_torch", "one-window latency", "torch eager / ONNX Runtime, 1 thread"),
                (
                    "onnx_stream_realtime_factor",
                    "StreamingScorer on ONNX Runtime",
                    "recording s per CPU s, 1 thread, hop 0.5 s (target >= 200)",
                ),
                (
                    "onnx_stream_speedup_vs_torch",
                    "StreamingScorer",
                    "ONNX real-time factor / torch's, 1 thread",
                ),
                (
                    "onnx_parity_max_rel",
                    "ONNX vs MSVDD.score",
                    "max relative difference, 16 windows (<= 1e-4)",
                ),
                ("onnx_export_s", "msvdd.export.export_onnx", "wall time incl. the parity check, s"),
            )
        },
        "mcd_speedup_vs_sklearn": "min_cov_det vs sklearn MinCovDet at n=5000, p=32, 1 thread (target >= 10)",
        "mcd_ms": "min_cov_det wall time at n=5000, p=32, ms (best of 5 after an untimed one)",
        "mcd_sklearn_ms": "sklearn MinCovDet wall time at n=5000, p=32, ms (best of 2)",
        "mcd_support_agreement": "fraction of samples on which both supports agree (same answer: ~1)",
        "mcd_logdet_gap": "log det of our raw covariance minus sklearn's (<= ~0: as good or better)",
        "mcd_outliers_in_support": "planted outliers (15%) inside our support (should be 0)",
        "load_avg_1min_at_start": "1-min load average at the start (above the cores: figures pessimistic)",
    },
    ratios={"mcd_speedup_vs_sklearn": "higher"},
)
