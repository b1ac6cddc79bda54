"""Score saved models on a dataset's test windows, clean and cut again from perturbed episode streams.

Each test episode is read once (audio decimated as `benchmarks.dataset.load_window_rows` does); for every
perturbation its streams are perturbed (`benchmarks.robustness.perturb`) and the test windows cut again at
their recorded starts, so the clean windows are bit for bit those `msvdd-bench evaluate` scores. Every
method's AUC (the mean over its training seeds) gets an episode-cluster bootstrap interval, and its ratio
to the clean AUC an interval from the same episode draws (paired, replicate by replicate).

The clean windows and every perturbation are scored as independent tasks on an executor
(`benchmarks.executor`: local worker processes or Ray), one task per (kind, severity). A task names the
dataset folder, the model folders and the test rows; the process that runs it reads the episodes and loads
the models once per run and keeps them for the run's next tasks (`score_condition`). Its scores depend on
the task only: the perturbation draws are keyed by (seed, kind, severity, episode index), and the scoring
runs on one thread (torch and the BLAS pools), so any executor and any number of workers give the same
scores bit for bit. The driver collects the scores in task order and runs the bootstrap.
"""

from __future__ import annotations

import math
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from benchmarks import methods
from benchmarks.dataset import Dataset, DatasetError, WindowRow
from benchmarks.episode import read_episode
from benchmarks.errors import InputNotFoundError, UserError, check_seed
from benchmarks.executor import Executor, LocalExecutor
from benchmarks.methods.registry import METHOD_FILE
from benchmarks.pipeline import TrainedModel
from benchmarks.robustness.perturb import KINDS, Perturbation, Streams, apply, reads_outside, rng_for
from benchmarks.uncertainty import (
    BOOTSTRAP_REPLICATES,
    BOOTSTRAP_SEED,
    CONFIDENCE,
    BootstrapAuc,
    Interval,
    bootstrap_mean_auc,
    episode_draws,
    weighted_auc,
)
from msvdd import preprocess
from msvdd.contract import AUDIO_RATE, IMU_LEN, IMU_RATE, Detector, Windows


@dataclass(frozen=True)
class RobustnessConfig:
    """What a robustness run perturbs and how its intervals are drawn."""

    perturbations: tuple[Perturbation, ...]
    """Every (kind, severity) scored besides the clean windows."""
    seed: int = 0
    """Seed of the perturbations' draws (each also keyed by kind, severity and episode index)."""
    replicates: int = BOOTSTRAP_REPLICATES
    """Episode-cluster bootstrap replicates per interval."""
    bootstrap_seed: int = BOOTSTRAP_SEED
    """Seed of the episode draws (the same draws for every method and perturbation)."""

    def __post_init__(self) -> None:
        check_seed(self.seed, "--perturbation-seed")
        if not self.perturbations:
            raise UserError(
                "--perturbations: no perturbation given; allowed: one or more of " + ", ".join(KINDS)
            )
        if self.replicates < 1:
            raise UserError(f"replicates = {self.replicates} is invalid; allowed: an integer >= 1")


def parse_perturbations(items: Sequence[str]) -> tuple[Perturbation, ...]:
    """`KIND` (its default severities) or `KIND=S1,S2,...` per item, in order, duplicates dropped."""
    out: list[Perturbation] = []
    for item in items:
        kind, _, values = item.partition("=")
        kind = kind.strip()
        if kind not in KINDS:
            raise UserError(f"--perturbations: kind = {kind!r} is unknown; allowed: {', '.join(KINDS)}")
        if not values.strip():
            severities: tuple[float, ...] = KINDS[kind].severities
        else:
            try:
                severities = tuple(float(v) for v in values.split(","))
            except ValueError:
                raise UserError(
                    f"--perturbations {kind}: severities = {values!r} are invalid; allowed: numbers "
                    f"separated by commas, {KINDS[kind].low:g} to {KINDS[kind].high:g} {KINDS[kind].unit}"
                ) from None
        for s in severities:
            p = Perturbation(kind, s)
            if p not in out:
                out.append(p)
    return tuple(out)


# --- models ---------------------------------------------------------------------------------------------


def model_folders(paths: Sequence[Path]) -> list[Path]:
    """Model folders named by `paths`: a model folder itself, or a run folder (or a folder of model folders),
    for each of its `models/*` (or `*`) folders holding a saved model, in name order."""
    found: list[Path] = []
    for path in map(Path, paths):
        if not path.exists():
            raise InputNotFoundError(f"--models {path}: no such folder")
        if (path / METHOD_FILE).is_file():
            found.append(path)
            continue
        inner = [
            p
            for parent in (path / "models", path)
            if parent.is_dir()
            for p in sorted(parent.iterdir())
            if (p / METHOD_FILE).is_file()
        ]
        if not inner:
            raise UserError(
                f"--models {path}: not a model folder (no {METHOD_FILE}) nor a run folder holding model "
                f"folders (models/*/{METHOD_FILE}); allowed: folders written by `train` or `run`"
            )
        found += inner
    return found


def load_models(folders: Sequence[Path], progress: bool = False) -> list[TrainedModel]:
    """Load each saved model as `msvdd-bench evaluate` does (the seed column counts runs of a method)."""
    models: list[TrainedModel] = []
    for folder in tqdm(folders, desc="loading models", unit="model", disable=not progress):
        name, detector = methods.load_detector(folder)
        run_index = sum(1 for m in models if m.method == name)
        models.append(TrainedModel(name, run_index, detector, Path(folder), float("nan")))
    return models


# --- streams and windows --------------------------------------------------------------------------------


def episode_streams(folder: Path, rows: Sequence[WindowRow], progress: bool = False) -> dict[str, Streams]:
    """The continuous streams of every episode behind `rows` in the dataset `folder`, decimated as the
    dataset loader does."""
    out: dict[str, Streams] = {}
    for episode_id in tqdm(
        dict.fromkeys(r.episode for r in rows), desc="loading test episodes", unit="ep", disable=not progress
    ):
        episode = read_episode(Path(folder) / episode_id)
        out[episode_id] = Streams(
            audio=preprocess.decimate_audio(episode.audio), imu=episode.imu_vel_z, imu6=episode.imu6
        )
    return out


def cut_windows(
    streams: dict[str, Streams],
    rows: Sequence[WindowRow],
    perturbation: Perturbation | None,
    seed: int,
    episode_index: dict[str, int],
) -> tuple[Windows, int]:
    """The windows of `rows` (in their order), cut from each episode's streams under `perturbation`, and how
    many of them hold IMU samples read from outside the recording (mirrored: `perturb.mirror`)."""
    audio: list[np.ndarray] = [np.empty(0)] * len(rows)
    imu: list[np.ndarray] = [np.empty(0)] * len(rows)
    imu6: list[np.ndarray] = [np.empty(0)] * len(rows)
    touched = 0
    by_episode: dict[str, list[int]] = {}
    for i, row in enumerate(rows):
        by_episode.setdefault(row.episode, []).append(i)
    for episode_id, indices in by_episode.items():
        s = streams[episode_id]
        if perturbation is not None:
            rng = rng_for(seed, perturbation, episode_index[episode_id])
            s = apply(s, perturbation, rng, AUDIO_RATE, IMU_RATE)
        starts = np.array([rows[i].start_s for i in indices])
        if perturbation is not None:
            mirrored = np.cumsum(np.r_[0, reads_outside(perturbation, s.imu.shape[0], IMU_RATE)])
            first = np.rint(starts * IMU_RATE).astype(np.int64)
            touched += int(np.count_nonzero(mirrored[first + IMU_LEN] - mirrored[first]))
        w = preprocess.frame_windows(s.audio, s.imu, starts, imu6=s.imu6)
        assert w.imu6 is not None
        for j, i in enumerate(indices):
            audio[i], imu[i], imu6[i] = w.audio[j], w.imu[j], w.imu6[j]
    return Windows(audio=np.stack(audio), imu=np.stack(imu), imu6=np.stack(imu6)), touched


# --- tasks ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ScoringTask:
    """One condition (the clean windows or one perturbation) to score with every model; picklable."""

    run: str
    """Identifies the run: a worker keeps one run's episodes and models between its tasks."""
    data: Path
    """Absolute dataset folder."""
    models: tuple[Path, ...]
    """Absolute model folders, in the run's model order."""
    rows: tuple[WindowRow, ...]
    """The test windows, in the run's order."""
    episode_index: tuple[tuple[str, int], ...]
    """(episode folder, index in manifest.json) of every episode behind `rows`: keys the draws."""
    perturbation: Perturbation | None
    """None: the clean windows."""
    seed: int
    """Seed of the perturbations' draws."""


@dataclass(frozen=True)
class ConditionScores:
    """What a task gives back: every model's scores of one condition's windows."""

    scores: tuple[np.ndarray, ...]
    """Per model (task order), its scores of the windows in row order, as the detector returned them."""
    mirrored_windows: int
    """Windows holding IMU samples from past the recording's ends."""


@dataclass
class _Loaded:
    """One run's inputs, kept by the process that scores its tasks."""

    run: str
    streams: dict[str, Streams] | None = None
    detectors: list[Detector] | None = None


_LOADED: _Loaded | None = None
"""This process's inputs of the run it scores now (one run at a time)."""


def _loaded(run: str) -> _Loaded:
    global _LOADED
    if _LOADED is None or _LOADED.run != run:
        _LOADED = _Loaded(run)  # drops an earlier run's inputs
    return _LOADED


def _forget(run: str) -> None:
    global _LOADED
    if _LOADED is not None and _LOADED.run == run:
        _LOADED = None


@contextmanager
def _one_thread() -> Iterator[None]:
    """torch and the BLAS / OpenMP pools on one thread: scores that do not depend on the worker's threads."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with threadpool_limits(limits=1):
            yield
    finally:
        torch.set_num_threads(before)


def score_condition(task: ScoringTask) -> ConditionScores:
    """Cut one condition's windows and score them with every model (runs in a worker).

    The episodes are read and the models loaded on this process's first task of the run, then reused.
    """
    with _one_thread():
        inputs = _loaded(task.run)
        if inputs.streams is None:
            inputs.streams = episode_streams(task.data, task.rows)
        if inputs.detectors is None:
            inputs.detectors = [methods.load_detector(folder)[1] for folder in task.models]
        windows, touched = cut_windows(
            inputs.streams, task.rows, task.perturbation, task.seed, dict(task.episode_index)
        )
        scores = tuple(np.asarray(d.score(windows)) for d in inputs.detectors)
    return ConditionScores(scores=scores, mirrored_windows=touched)


# --- measuring ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ConditionResult:
    """One method under one perturbation (or clean): its AUC and how it compares with the clean one."""

    method: str
    """Registry name."""
    kind: str
    """Perturbation kind, or `clean`."""
    severity: float
    """In the kind's unit (0 for clean)."""
    auc: Interval
    """Seed-mean ROC-AUC, normal against every anomaly, with its 95 % interval."""
    ratio: Interval
    """AUC(perturbed) / AUC(clean), with the interval from the same episode draws."""
    delta: Interval
    """AUC(perturbed) - AUC(clean), paired the same way."""
    auc_collision: float
    """Seed-mean AUC, normal against collision windows (NaN without any)."""
    auc_mechanical: float
    """Seed-mean AUC, normal against mechanical-fault windows (NaN without any)."""
    nonfinite_scores: int
    """Scores that were NaN or infinite (ranked as the least, resp. most, anomalous), over every seed."""
    mirrored_windows: int
    """Test windows holding IMU samples from past the recording's ends (mirrored into it)."""


@dataclass(frozen=True)
class RobustnessResult:
    """Everything a robustness run measured."""

    config: RobustnessConfig
    """What was perturbed."""
    methods: dict[str, list[Path]]
    """Each method's model folders (one per training seed)."""
    results: list[ConditionResult]
    """Clean first, then every perturbation, each for every method."""
    normal_episodes: int
    """Test episodes with normal windows (the normal clusters)."""
    anomalous_episodes: int
    """Test episodes with anomalous windows."""
    windows: dict[str, int] = field(default_factory=dict)
    """Test windows by kind."""

    def clean(self, method: str) -> ConditionResult:
        """The method's clean result."""
        return next(r for r in self.results if r.method == method and r.kind == "clean")


def finite_scores(scores: np.ndarray) -> tuple[np.ndarray, int]:
    """Scores with NaN and -inf put below every finite score and +inf above it, and how many there were."""
    s = np.asarray(scores, dtype=np.float64)
    bad = ~np.isfinite(s)
    if not bad.any():
        return s, 0
    good = s[~bad]
    low, high = (float(good.min()), float(good.max())) if good.size else (0.0, 0.0)
    return np.where(np.isposinf(s), high + 1.0, np.where(bad, low - 1.0, s)), int(bad.sum())


def ratio_interval(a: BootstrapAuc, b: BootstrapAuc) -> Interval:
    """a / b, on the data and replicate by replicate (same draws), with its percentile interval."""
    value = a.value / b.value if b.value else math.nan
    if not (a.defined and b.defined) or not math.isfinite(value):
        return Interval(value, math.nan, math.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = a.replicates / b.replicates
    r = r[np.isfinite(r)]
    if r.size == 0:
        return Interval(value, math.nan, math.nan)
    tail = 100.0 * (1.0 - CONFIDENCE) / 2.0
    low, high = np.percentile(r, [tail, 100.0 - tail])
    return Interval(value, float(low), float(high))


def _subset_auc(scores: list[np.ndarray], positive: np.ndarray, keep: np.ndarray) -> float:
    if not positive[keep].any() or positive[keep].all():
        return math.nan
    ones = np.ones(int(keep.sum()))
    return float(np.mean([weighted_auc(s[keep], positive[keep], ones) for s in scores]))


def _score_conditions(
    dataset: Dataset,
    models: Sequence[TrainedModel],
    config: RobustnessConfig,
    rows: list[WindowRow],
    conditions: list[Perturbation | None],
    progress: bool,
    executor: Executor | None,
) -> list[ConditionScores]:
    """One scoring task per condition (None: clean), run on `executor`; their scores in condition order."""
    manifest_index = {e: i for i, e in enumerate(dataset.episode_ids)}
    missing = sorted({r.episode for r in rows} - set(manifest_index))
    if missing:
        raise DatasetError(f"{dataset.path}: test episode {missing[0]} is not in manifest.json")
    episode_index = tuple((e, manifest_index[e]) for e in dict.fromkeys(r.episode for r in rows))
    run = uuid.uuid4().hex
    tasks = [
        ScoringTask(
            run=run,
            data=Path(dataset.path).absolute(),
            models=tuple(Path(m.path).absolute() for m in models),
            rows=tuple(rows),
            episode_index=episode_index,
            perturbation=condition,
            seed=config.seed,
        )
        for condition in conditions
    ]
    _loaded(run).detectors = [m.detector for m in models]  # what tasks run here use
    try:
        return (executor or LocalExecutor(1)).map(
            score_condition, tasks, desc="perturbing and scoring", progress=progress
        )
    finally:
        _forget(run)


@dataclass(frozen=True)
class _Truth:
    """The test windows' labels, as the AUCs need them (built once per run)."""

    positive: np.ndarray
    """Anomalous windows."""
    collision: np.ndarray
    """Normal and collision windows (the collision AUC's subset)."""
    mechanical: np.ndarray
    """Normal and mechanical windows (the mechanical AUC's subset)."""


def _condition_result(
    method: str,
    condition: Perturbation | None,
    finite: list[tuple[np.ndarray, int]],
    mirrored_windows: int,
    boot: BootstrapAuc,
    clean: BootstrapAuc,
    truth: _Truth,
) -> ConditionResult:
    """One method's row for one condition: its AUC, against the clean one (`clean`), and per anomaly kind."""
    scores = [s for s, _ in finite]
    return ConditionResult(
        method=method,
        kind="clean" if condition is None else condition.kind,
        severity=0.0 if condition is None else float(condition.severity),
        auc=boot.interval(),
        ratio=ratio_interval(boot, clean),
        delta=boot.minus(clean),
        auc_collision=_subset_auc(scores, truth.positive, truth.collision),
        auc_mechanical=_subset_auc(scores, truth.positive, truth.mechanical),
        nonfinite_scores=sum(n for _, n in finite),
        mirrored_windows=mirrored_windows,
    )


def run_robustness(
    dataset: Dataset,
    models: Sequence[TrainedModel],
    config: RobustnessConfig,
    rows: Sequence[WindowRow],
    progress: bool = False,
    executor: Executor | None = None,
) -> RobustnessResult:
    """Score every model on the clean and every perturbed version of the test windows `rows`.

    One task per condition runs on `executor` (default: in this process, `LocalExecutor(1)`); tasks that
    run in this process use `models` as they are, those in other processes load them from their folders.
    The results are the same bit for bit with any executor.
    """
    rows = list(rows)
    kinds = np.array([r.kind for r in rows]).astype(str)
    episodes = np.array([r.episode for r in rows]).astype(str)
    positive = kinds != "normal"
    by_method: dict[str, list[int]] = {}
    for i, m in enumerate(models):
        by_method.setdefault(m.method, []).append(i)
    conditions: list[Perturbation | None] = [None, *config.perturbations]
    scored = _score_conditions(dataset, models, config, rows, conditions, progress, executor)
    weights = episode_draws(episodes, positive, config.replicates, config.bootstrap_seed)
    truth = _Truth(positive, ~positive | (kinds == "collision"), ~positive | (kinds == "mechanical"))
    results: list[ConditionResult] = []
    clean_boot: dict[str, BootstrapAuc] = {}
    for condition, condition_scores in zip(conditions, scored, strict=True):
        for method, indices in by_method.items():
            finite = [finite_scores(condition_scores.scores[i]) for i in indices]
            boot = bootstrap_mean_auc(np.stack([s for s, _ in finite]), positive, episodes, weights)
            if condition is None:
                clean_boot[method] = boot
            mirrored = condition_scores.mirrored_windows
            results.append(
                _condition_result(method, condition, finite, mirrored, boot, clean_boot[method], truth)
            )
    return RobustnessResult(
        config=config,
        methods={name: [models[i].path for i in indices] for name, indices in by_method.items()},
        results=results,
        normal_episodes=len(set(episodes[~positive])),
        anomalous_episodes=len(set(episodes[positive])),
        windows={k: int((kinds == k).sum()) for k in sorted(set(kinds))},
    )
