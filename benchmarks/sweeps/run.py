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
from msvdd.atomic import write_text_atomic
from sim.vocab import FAULT_KINDS

AUC_KEYS: tuple[str, ...] = ("auc", "auc_collision", "auc_mechanical")
"""The AUCs a sweep reports (all anomalies, collisions only, mechanical faults only, against normal)."""
KIND_KEYS: tuple[str, ...] = tuple(f"auc_{kind}" for kind in FAULT_KINDS)
"""The AUCs a sweep reports per fault kind (that kind's windows against normal), where a point has them."""
ORACLE = "oracle"
"""The name the audit's privileged fault oracle is reported under (a spec's `oracle = true`)."""
ORACLE_FILE = "oracle.json"
"""In a point's folder: the oracle's AUC per fault kind (`KIND_KEYS`), with its interval."""

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
    oracle: bool = False
    """Whether the audit's fault oracle scores the point's dataset too (`ORACLE_FILE`)."""


@dataclass(frozen=True)
class MethodPoint:
    """One method's AUCs at one point and dataset seed."""

    auc: dict[str, Interval]
    """By key of `AUC_KEYS` and `KIND_KEYS`: the seed-mean AUC with its 95 % episode-cluster bootstrap
    interval (NaN where the point has no such windows, or the method gives no such AUC)."""
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
    if task.oracle and not (task.out / ORACLE_FILE).is_file():
        write_oracle(task.out)
    return read_point(task.point, task.seed, task.out)


def write_oracle(folder: Path) -> Path:
    """Score a point's dataset (`folder`/dataset) with the audit's privileged fault oracle (no control) and
    write its AUC per fault kind with the episode-cluster interval to `folder`/`ORACLE_FILE`."""
    from benchmarks.audit import oracle
    from benchmarks.dataset import open_dataset

    scored = oracle.score_faults(open_dataset(folder / "dataset", verify=False), control=False)
    doc = {f"auc_{s.kind}": oracle.kind_interval(s).to_dict() for s in scored}
    return write_text_atomic(folder / ORACLE_FILE, json.dumps(doc, indent=2) + "\n")


def read_point(point: int, seed: int, folder: Path) -> PointResult:
    """A point's result from its run folder's `results.json`."""
    doc = json.loads((folder / "results.json").read_text())
    methods: dict[str, MethodPoint] = {}
    for name, entry in doc["methods"].items():
        ci = entry.get("auc_ci95", {})
        methods[name] = MethodPoint(
            auc={key: _interval(ci.get(key)) for key in (*AUC_KEYS, *KIND_KEYS)},
            train_seconds=entry.get("train_seconds"),
        )
    if (folder / ORACLE_FILE).is_file():
        kinds = json.loads((folder / ORACLE_FILE).read_text())
        methods[ORACLE] = MethodPoint(
            auc={key: _interval(kinds.get(key)) for key in (*AUC_KEYS, *KIND_KEYS)}, train_seconds=None
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


def read_sweep(out: Path) -> SweepResult:
    """A finished sweep read back from its folder: the spec's copy, every point's run folder and the setting
    recorded in `sweep.json` (what `msvdd-bench docs --sweep` formats).

    Raises:
        InputNotFoundError: `out` has no `sweep.json` or spec copy (not a finished sweep folder).
    """
    import tomllib

    from benchmarks.errors import InputNotFoundError
    from benchmarks.sweeps.spec import parse_spec

    out = Path(out)
    record, copy = out / "sweep.json", out / SPEC_COPY
    if not record.is_file() or not copy.is_file():
        raise InputNotFoundError(f"not a finished sweep folder (no sweep.json or {SPEC_COPY}): {out}")
    doc = json.loads(record.read_text())
    spec = parse_spec(tomllib.loads(copy.read_text()), str(copy))
    results = [
        read_point(p["index"], int(r["seed"]), out / r["folder"]) for p in doc["points"] for r in p["runs"]
    ]
    return SweepResult(
        spec=spec,
        out=out,
        points=spec.points(),
        results=results,
        command=str(doc["command"]),
        executor=str(doc["executor"]),
        seconds=float(doc["seconds"]),
        date=str(doc["date"]),
        machine=str(doc["machine"]),
    )


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
            oracle=spec.oracle,
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
