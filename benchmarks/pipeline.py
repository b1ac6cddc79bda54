"""Train methods on a dataset's nominal windows and score them on its test windows.

This is the glue of `msvdd-bench train`, `evaluate` and `run`: it reads only the dataset contract
(`benchmarks.dataset`) and the detector contract (`msvdd.contract`, `benchmarks.methods`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from benchmarks import methods
from benchmarks.dataset import Dataset, DatasetError, WindowRow
from benchmarks.episode import read_events
from benchmarks.metrics import MethodMetrics, compute_metrics
from benchmarks.modalities import require_modalities
from msvdd.contract import Detector, Windows


@dataclass(frozen=True)
class TrainedModel:
    """A fitted detector and where it was saved."""

    method: str
    """Registry name."""
    seed: int
    """Training seed."""
    detector: Detector
    """The fitted detector."""
    path: Path
    """Saved model folder."""
    train_seconds: float
    """Wall-clock fit time, s."""


@dataclass(frozen=True)
class MethodScores:
    """One method's scores on the test windows, for one training seed."""

    method: str
    """Registry name."""
    seed: int
    """Training seed."""
    scores: np.ndarray
    """(N,) test scores, in test-row order."""
    threshold: float
    """The detector's threshold_ (fixed at fit time from nominal data: `msvdd.contract.Detector`)."""


def train_method(
    dataset: Dataset,
    name: str,
    seed: int,
    scale: str,
    out: Path,
    train: Windows | None = None,
    val: Windows | None = None,
    device: str = "cpu",
    progress: bool | None = None,
) -> TrainedModel:
    """Fit method `name` on the dataset's train windows (val for model selection) and save it to `out`.

    `device` is where a torch method trains; `progress` shows the bars of loading the windows and of
    training (None: no loading bar, the method's own training default). A method that reads a sensor the
    dataset lacks (an audio-only import) is refused (`benchmarks.modalities.MissingModalityError`).
    """
    require_modalities(dataset.path, dataset.modalities, name)
    if train is None:
        train, _ = dataset.load_windows("train", progress=bool(progress))
    if val is None and dataset.rows("val"):
        val, _ = dataset.load_windows("val", progress=bool(progress))
    detector = methods.make(name, seed=seed, scale=scale, device=device, progress=progress)
    started = time.perf_counter()
    detector.fit(train, val)
    elapsed = time.perf_counter() - started
    path = methods.save_detector(detector, name, out)
    return TrainedModel(name, seed, detector, path, elapsed)


def test_rows(dataset: Dataset) -> list[WindowRow]:
    """The test rows; refuses a test split without anomalies or without nominal windows."""
    rows = dataset.rows("test")
    kinds = {r.kind for r in rows}
    if "normal" not in kinds or kinds == {"normal"}:
        raise DatasetError(
            f"{dataset.path}: the test split needs nominal and anomalous windows; "
            f"it has kinds {sorted(kinds)}"
        )
    return rows


def test_windows(dataset: Dataset, progress: bool = False) -> tuple[Windows, list[WindowRow]]:
    """The test windows (`test_rows`' checks first)."""
    test_rows(dataset)
    return dataset.load_windows("test", progress=progress)


def event_onsets(dataset: Dataset, rows: list[WindowRow]) -> tuple[np.ndarray, np.ndarray]:
    """(episode ids, onset times) of every anomalous event in the test episodes behind `rows`.

    Collision events are the contact events of collision episodes; fault events are the onsets of the
    faults of fault episodes; imported episodes list the onsets of their labelled spans (`anomalies`).
    Used for detection delays.
    """
    category = dataset.categories()
    episodes: list[str] = []
    onsets: list[float] = []
    for episode_id in sorted({r.episode for r in rows if r.kind != "normal"}):
        events = read_events(dataset.path / episode_id)
        times = [c.time for c in events.contacts] if category[episode_id] == "collision" else []
        times += [f.onset for f in events.faults if f.severity > 0]
        times += [a.onset for a in events.anomalies or ()]
        episodes += [episode_id] * len(times)
        onsets += times
    return np.asarray(episodes, dtype=str), np.asarray(onsets, dtype=np.float64)


def score_and_measure(
    dataset: Dataset,
    models: list[TrainedModel],
    test: tuple[Windows, list[WindowRow]] | None = None,
    progress: bool = True,
) -> tuple[list[MethodScores], dict[str, list[MethodMetrics]], list[WindowRow]]:
    """Score every model on the test windows and compute its metrics (one entry per seed).

    A model whose method reads a sensor the dataset lacks is refused before any scoring.
    """
    for model in models:
        require_modalities(dataset.path, dataset.modalities, model.method)
    windows, rows = test if test is not None else test_windows(dataset)
    kinds = np.array([r.kind for r in rows])
    sub_kinds = np.array([r.sub_kind for r in rows])
    w_episode = np.array([r.episode for r in rows])
    w_start = np.array([r.start_s for r in rows])
    e_episode, e_onset = event_onsets(dataset, rows)
    all_scores: list[MethodScores] = []
    per_method: dict[str, list[MethodMetrics]] = {}
    bar = tqdm(models, desc="scoring", unit="model", disable=not progress)
    for model in bar:
        bar.set_postfix_str(f"{model.method} seed {model.seed}")
        scores = np.asarray(model.detector.score(windows), dtype=np.float64)
        threshold = float(model.detector.threshold_)
        all_scores.append(MethodScores(model.method, model.seed, scores, threshold))
        per_method.setdefault(model.method, []).append(
            compute_metrics(
                scores, threshold, kinds, sub_kinds,
                window_episode=w_episode, window_start=w_start, event_episode=e_episode, event_onset=e_onset,
            )
        )  # fmt: skip
    return all_scores, per_method, rows
