"""Run a sweep: one task per (point, dataset seed) on an executor; each is a whole `msvdd-bench run`.

A task generates its point's dataset (from the point's derived preset and the dataset seed), trains and
scores the methods with `benchmarks.runner.run_benchmark`, and reads the AUCs and their episode-cluster
bootstrap intervals back from the run's `results.json`. Its folder, `DIR/points/pNN-seedS/`, is a complete
run folder (dataset, models, results, scores), renamed into place when done: a retried task, or a sweep
resumed with `--resume`, finds a finished folder and reuses it instead of running it again, and an unfinished
one's dataset and finished models (`benchmarks.resume`).
"""

from __future__ import annotations

import datetime
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from benchmarks.errors import OutputExistsError, UserError
from benchmarks.executor import Executor
from benchmarks.presets import Preset, expand_methods
from benchmarks.sweeps.spec import SweepPoint, SweepSpec
from benchmarks.uncertainty import Interval

AUC_KEYS: tuple[str, ...] = ("auc", "auc_collision", "auc_mechanical")
"""The AUCs a sweep reports (all anomalies, collisions only, mechanical faults only, against normal)."""

SPEC_COPY = "spec.toml"
"""The spec, copied into the sweep folder (what `--resume` compares with)."""


@dataclass(frozen=True)
class PointTask:
    """One point on one dataset seed: everything a worker needs, picklable."""

    point: int
    """Index of the point in the spec."""
    seed: int
    """Dataset seed."""
    preset: Preset
    """The point's derived preset."""
    methods: tuple[str, ...]
    """Methods trained (groups expanded)."""
    scale: str | None
    """Training budget (None: the preset's)."""
    train_seeds: tuple[int, ...] | None
    """Training seeds (None: the preset's)."""
    out: Path
    """The point's run folder."""
    device: str
    """Where torch methods train."""
    command: str
    """The sweep's command line, recorded in the point's report."""


@dataclass(frozen=True)
class MethodPoint:
    """One method's AUCs at one point and dataset seed."""

    auc: dict[str, Interval]
    """By key of `AUC_KEYS`: the seed-mean AUC with its 95 % episode-cluster bootstrap interval."""
    train_seconds: float | None
    """Mean fit time, s."""


@dataclass(frozen=True)
class PointResult:
    """What a point task reports back."""

    point: int
    """Index of the point in the spec."""
    seed: int
    """Dataset seed."""
    folder: Path
    """The point's run folder."""
    dataset_sha256: str
    """Fingerprint of the point's dataset (`benchmarks.dataset.dataset_fingerprint`)."""
    methods: dict[str, MethodPoint]
    """By method name."""
    normal_episodes: int
    """Test episodes with normal windows (the bootstrap's normal clusters)."""
    anomalous_episodes: int
    """Test episodes with anomalous windows."""


@dataclass(frozen=True)
class SweepResult:
    """A finished sweep: its spec, points and every task's result."""

    spec: SweepSpec
    """The spec."""
    out: Path
    """The sweep folder."""
    points: list[SweepPoint]
    """The points, in spec order."""
    results: list[PointResult]
    """One per (point, dataset seed), point-major."""
    command: str
    """The command line."""
    executor: str
    """What ran the tasks (`Executor.describe`)."""
    seconds: float
    """Wall-clock time of the whole sweep, s."""
    date: str
    """UTC date."""
    machine: str
    """Where the driver ran."""


def point_folder(out: Path, point: int, seed: int) -> Path:
    """Where a point's run lives in the sweep folder."""
    return out / "points" / f"p{point:02d}-seed{seed}"


def run_point(task: PointTask) -> PointResult:
    """Generate, train and score one point (runs in a worker); a finished folder is reused as it is."""
    from benchmarks.runner import run_benchmark

    results = task.out / "results.json"
    if not results.is_file():
        try:
            run_benchmark(
                task.out,
                preset_name=None,
                preset=task.preset,
                seed=task.seed,
                method_names=list(task.methods),
                data=None,
                workers=1,
                scale=task.scale,
                seeds=None if task.train_seeds is None else list(task.train_seeds),
                command=task.command,
                progress=False,
                device=task.device,
                resume=True,  # a retried task (its worker died) reuses the models the first attempt finished
            )
        except OSError:  # another attempt of this task finished first: its folder is as good
            if not results.is_file():
                raise
    return read_point(task.point, task.seed, task.out)


def read_point(point: int, seed: int, folder: Path) -> PointResult:
    """A point's result from its run folder's `results.json`."""
    doc = json.loads((folder / "results.json").read_text())
    methods: dict[str, MethodPoint] = {}
    for name, entry in doc["methods"].items():
        ci = entry.get("auc_ci95", {})
        methods[name] = MethodPoint(
            auc={key: _interval(ci.get(key)) for key in AUC_KEYS},
            train_seconds=entry.get("train_seconds"),
        )
    uncertainty = doc.get("uncertainty", {})
    return PointResult(
        point=point,
        seed=seed,
        folder=folder,
        dataset_sha256=str(doc.get("dataset_sha256") or ""),
        methods=methods,
        normal_episodes=int(uncertainty.get("normal_episodes", 0)),
        anomalous_episodes=int(uncertainty.get("anomalous_episodes", 0)),
    )


def _interval(doc: dict[str, Any] | None) -> Interval:
    def num(v: Any) -> float:
        return float("nan") if v is None else float(v)

    if not doc:
        return Interval(float("nan"), float("nan"), float("nan"))
    return Interval(num(doc.get("value")), num(doc.get("low")), num(doc.get("high")))


def prepare_folder(spec: SweepSpec, spec_text: str, out: Path, resume: bool) -> None:
    """Create the sweep folder with a copy of the spec; with `resume`, reuse one made by the same spec."""
    copy = out / SPEC_COPY
    if out.exists():
        if not resume:
            raise OutputExistsError(
                f"sweep folder exists already: {out} (remove it, choose another --out, or --resume it)"
            )
        if not copy.is_file() or copy.read_text() != spec_text:
            raise UserError(
                f"--resume {out}: its {SPEC_COPY} is not {spec.source}; resume with the same spec"
            )
        return
    out.mkdir(parents=True)
    copy.write_text(spec_text)


def run_sweep(
    spec: SweepSpec,
    out: Path,
    executor: Executor,
    *,
    command: str,
    progress: bool = True,
    device: str = "cpu",
    resume: bool = False,
) -> SweepResult:
    """Run every (point, dataset seed) task on `executor` and collect the results (spec order).

    `out` must not exist (unless `resume`, with the same spec); the methods are checked before any work.
    """
    from benchmarks import methods
    from benchmarks.dataset import plan_episodes
    from benchmarks.runner import machine_description

    started = time.perf_counter()
    names = tuple(expand_methods(list(spec.methods), methods.names()))
    for name in names:
        try:
            methods.spec(name)
        except UserError as exc:
            raise UserError(f"{spec.source}: methods: {exc}") from None
    points = spec.points()
    for p in points:  # a point whose floors or obstacles cannot be planned is refused before any work
        try:
            plan_episodes(p.preset, spec.seeds[0])
        except UserError as exc:
            raise UserError(f"{spec.source}: point {p.label!r}: {exc}") from None
    out = Path(out)
    prepare_folder(spec, Path(spec.source).read_text(), out, resume)
    tasks = [
        PointTask(
            point=p.index,
            seed=seed,
            preset=p.preset,
            methods=names,
            scale=spec.scale,
            train_seeds=spec.train_seeds,
            out=point_folder(out, p.index, seed).absolute(),
            device=device,
            command=f"{command}  # point {p.index} ({spec.axis.name} = {p.label}), dataset seed {seed}",
        )
        for p in points
        for seed in spec.seeds
    ]
    (out / "points").mkdir(exist_ok=True)
    for leftover in (out / "points").glob(".*.partial-*"):  # runs of an interrupted sweep
        shutil.rmtree(leftover, ignore_errors=True)
    results = executor.map(run_point, tasks, desc="sweep points", progress=progress)
    for task, result in zip(tasks, results, strict=True):
        if not (result.folder / "results.json").is_file():
            raise UserError(
                f"{task.out}: written by a worker but not visible here; with a Ray cluster of several "
                "machines, --out must be on a file system every node mounts at the same path"
            )
    return SweepResult(
        spec=spec,
        out=out,
        points=points,
        results=results,
        command=command,
        executor=executor.describe(),
        seconds=time.perf_counter() - started,
        date=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
        machine=machine_description(),
    )
