"""`msvdd-bench run`: generate (or reuse) a dataset, train every method, evaluate, report, in one go."""

from __future__ import annotations

import datetime
import math
import os
import platform
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks import methods
from benchmarks.cache import cache_key, cached_dataset
from benchmarks.dataset import Dataset, check_dev, generate, open_dataset
from benchmarks.errors import OutputExistsError, UserError, check_seed
from benchmarks.executor import Executor
from benchmarks.methods.base import check_scale
from benchmarks.pipeline import TrainedModel, score_and_measure, test_windows, train_method
from benchmarks.presets import Preset, expand_methods, get_preset, preset_names
from benchmarks.provenance import code_version
from benchmarks.report import RunInfo, write_report
from benchmarks.resume import (
    TRAINING_FILE,
    code_digest,
    finished_training,
    partial_folder,
    record_training,
    training_key,
)
from msvdd.atomic import write_text_atomic
from msvdd.contract import Windows

DATASET_KEY_FILE = "dataset.key"
"""Beside the dataset a run generated, in its partial folder: the dataset's `cache_key`, for `--resume`."""
DEFAULT_PRESET = "quick"
"""The dataset preset of `run` and `demo` when neither --preset nor --data names one."""


@dataclass(frozen=True)
class _Plan:
    """What a run does, resolved from its arguments."""

    preset: Preset
    seed: int
    """The dataset seed."""
    names: list[str]
    """The methods, groups expanded."""
    scale: str
    train_seeds: list[int]
    code: dict[str, str]
    """Each method's `benchmarks.resume.code_digest`, taken when the run starts (its models' resume keys)."""


def run_benchmark(
    out: Path,
    *,
    preset_name: str | None,
    seed: int | None,
    method_names: list[str] | None,
    data: Path | None,
    workers: int | None,
    scale: str | None,
    seeds: list[int] | None,
    command: str,
    progress: bool = True,
    dev: Path | None = None,
    cache: Path | None = None,
    device: str = "cpu",
    executor: Executor | None = None,
    preset: Preset | None = None,
    resume: bool = False,
) -> Path:
    """Generate (or reuse) a dataset, train every method for every seed, evaluate, and write the report.

    Everything is written into `.<out>.partial/` beside `out` and renamed into place at the end, so an
    interrupted run leaves no folder that looks complete; it keeps the models it finished there, and the
    same run with `resume` reuses them (`benchmarks.resume`); without `resume`, such a folder is refused.
    `dev` names the dev dataset the methods' choices were made on (checked against the evaluated one and
    recorded in the report). With `data`, the preset and dataset seed are the dataset's (`preset_name` and
    `seed`, when given, must agree with it); without, they default to `DEFAULT_PRESET` and 0. With `cache`
    (not with `data`), the dataset is taken from that cache folder, generated there first if needed
    (`benchmarks.cache`). `device` is where the torch methods train and score; `progress` shows every bar,
    training ones included. `executor` builds the episodes of a generated dataset (default: local
    processes, `workers` of them). `preset`, instead of `preset_name`, is a preset that is not registered (a
    sweep point's; not with `data` or `cache`).
    Returns `out`.
    """
    out = Path(out)
    _check_arguments(out, preset_name=preset_name, data=data, cache=cache, preset=preset)
    tmp = partial_folder(out)
    if tmp.exists() and not resume:
        raise OutputExistsError(
            f"an interrupted run left {tmp} (the models it finished): run again with --resume to reuse "
            "them, or remove it"
        )
    plan = _plan(preset_name, seed, method_names, data, scale, seeds, preset)
    if cache is not None:
        data, reused = cached_dataset(
            Path(cache), plan.preset.name, plan.seed, workers=workers, progress=progress, executor=executor
        )
        print(f"{'reusing' if reused else 'generated'} cached dataset {data}", flush=True)
    tmp.mkdir(parents=True, exist_ok=True)
    try:
        data_path = (
            Path(data) if data is not None else _generated_dataset(tmp, plan, workers, progress, executor)
        )
        # a cache entry was verified just now
        dataset = open_dataset(data_path, verify=cache is None, progress=progress)
        dataset_text = str(data_path if data is not None else out / "dataset")
        _train_and_report(tmp, dataset, dataset_text, plan, dev, command, device, progress)
        (tmp / DATASET_KEY_FILE).unlink(missing_ok=True)
        os.replace(tmp, out)
    except BaseException:
        _keep_finished(tmp)
        raise
    return out


def _generated_dataset(
    tmp: Path, plan: _Plan, workers: int | None, progress: bool, executor: Executor | None
) -> Path:
    """The run's own dataset in `tmp`: one an interrupted run generated with the same recipe, seed and
    generating code (`benchmarks.cache.cache_key`, kept beside it), or a new one."""
    data_path, key_file = tmp / "dataset", tmp / DATASET_KEY_FILE
    key = cache_key(plan.preset, plan.seed)
    for killed in tmp.glob(".dataset.partial-*"):  # a generation killed before it could clean up
        shutil.rmtree(killed, ignore_errors=True)
    if data_path.exists():
        if key_file.is_file() and key_file.read_text().strip() == key:
            return data_path
        print(f"{data_path} was generated by other code or settings; generating it again", flush=True)
        shutil.rmtree(data_path)
    generate(plan.preset, plan.seed, data_path, workers=workers, progress=progress, executor=executor)
    write_text_atomic(key_file, key + "\n")
    return data_path


def _keep_finished(tmp: Path) -> None:
    """After a failure: keep `tmp` if it holds finished models or a generated dataset, else remove it."""
    finished = list(tmp.glob(f"models/*/{TRAINING_FILE}"))
    dataset = (tmp / "dataset").is_dir()
    if not finished and not dataset:
        shutil.rmtree(tmp, ignore_errors=True)
        return
    kept = f"{len(finished)} finished model(s)" + (" and the generated dataset" if dataset else "")
    print(f"run stopped: {kept} kept in {tmp}; the same command with --resume reuses them", file=sys.stderr)


def _check_arguments(
    out: Path, *, preset_name: str | None, data: Path | None, cache: Path | None, preset: Preset | None
) -> None:
    """Refuse an existing run folder and arguments that exclude each other."""
    if out.exists():
        raise OutputExistsError(f"run folder exists already: {out} (remove it or choose another --out)")
    if data is not None and cache is not None:
        raise UserError("--data and --cache exclude each other (a dataset folder, or a cache folder)")
    if preset is not None and (preset_name is not None or data is not None or cache is not None):
        raise UserError("a preset object excludes a preset name, --data and --cache")


def _plan(
    preset_name: str | None,
    seed: int | None,
    method_names: list[str] | None,
    data: Path | None,
    scale: str | None,
    seeds: list[int] | None,
    preset: Preset | None,
) -> _Plan:
    """The preset and dataset seed (the dataset's, with `data`), the methods (checked), scale and seeds."""
    if data is not None:
        preset_name, seed = _dataset_identity(Path(data), preset_name, seed)
        if preset_name not in preset_names():  # a derived preset (a sweep point's): the manifest's
            preset = open_dataset(Path(data), verify=False).preset
    if preset is None:
        preset = get_preset(preset_name or DEFAULT_PRESET)
    seed = 0 if seed is None else check_seed(seed)
    names = expand_methods(method_names or list(preset.methods) or ["all"], methods.names())
    for name in names:
        methods.spec(name)
    chosen_scale = check_scale(scale or preset.method_scale)
    train_seeds = seeds if seeds else list(preset.seeds)
    return _Plan(preset, seed, names, chosen_scale, train_seeds, {n: code_digest(n) for n in names})


def _train_and_report(
    tmp: Path,
    dataset: Dataset,
    dataset_text: str,
    plan: _Plan,
    dev: Path | None,
    command: str,
    device: str,
    progress: bool,
) -> None:
    """Train every method for every seed on `dataset`, score the test windows and write the report in `tmp`.

    `dataset_text` is the dataset's folder as the report names it.
    """
    dev_text = check_dev(open_dataset(Path(dev), verify=False), dataset) if dev is not None else ""
    train, _ = dataset.load_windows("train", progress=progress)
    val = dataset.load_windows("val", progress=progress)[0] if dataset.rows("val") else None
    test = test_windows(dataset, progress=progress)
    models = _train_models(tmp / "models", dataset, plan, train, val, device, progress)
    scores, per_method, rows = score_and_measure(dataset, models, test=test, progress=progress)
    info = RunInfo(
        preset=plan.preset.name,
        dataset_seed=plan.seed,
        dataset=dataset_text,
        command=command,
        machine=machine_description(),
        date=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
        train_seconds=mean_train_seconds(models),
        dev=dev_text,
        dataset_fingerprint=dataset.fingerprint,
        code_version=code_version(),
    )
    write_report(tmp, info, rows, scores, per_method, dataset.fault_severities())


def _train_models(
    folder: Path,
    dataset: Dataset,
    plan: _Plan,
    train: Windows,
    val: Windows | None,
    device: str,
    progress: bool,
) -> list[TrainedModel]:
    """Every method of the plan for every training seed, each saved in its folder under `folder`."""
    models: list[TrainedModel] = []
    for name in plan.names:
        for s in plan.train_seeds:
            model_folder = folder / f"{name.replace(':', '.')}-seed{s}"  # module:Class -> module.Class
            key = training_key(name, s, plan.scale, device, dataset.fingerprint, plan.code[name])
            seconds = finished_training(model_folder, key)
            if seconds is not None:
                print(f"reusing {name} (seed {s}) from {model_folder}", flush=True)
                _, detector = methods.load_detector(model_folder)
                models.append(TrainedModel(name, s, detector, model_folder, seconds))
                continue
            if progress:
                print(f"training {name} (seed {s}, scale {plan.scale}) on {len(train)} windows", flush=True)
            if model_folder.exists():  # unfinished, or trained with another key
                shutil.rmtree(model_folder)
            model = train_method(
                dataset, name, s, plan.scale, model_folder, train, val, device=device, progress=progress
            )
            record_training(model_folder, key, model.train_seconds)
            models.append(model)
    planned = {m.path.name for m in models}
    for other in folder.iterdir():  # models of an interrupted run with other methods or seeds
        if other.name not in planned:
            shutil.rmtree(other)
    return models


def mean_train_seconds(models: list[TrainedModel]) -> dict[str, float]:
    """Mean training time of each method over its seeds whose time is known (not NaN); a method with
    none is left out."""
    fit_time: dict[str, list[float]] = {}
    for m in models:
        if math.isfinite(m.train_seconds):
            fit_time.setdefault(m.method, []).append(m.train_seconds)
    return {k: float(np.mean(v)) for k, v in fit_time.items()}


def _dataset_identity(data: Path, preset_name: str | None, seed: int | None) -> tuple[str, int]:
    """The preset and seed `data` was generated with; a `--preset` or `--seed` that disagrees is an error."""
    dataset = open_dataset(data, verify=False)
    ds_preset, ds_seed = dataset.preset_name, dataset.seed
    if preset_name is not None and preset_name != ds_preset:
        raise UserError(f"--preset {preset_name}: dataset {data} was generated with preset {ds_preset}")
    if seed is not None and seed != ds_seed:
        raise UserError(f"--seed {seed}: dataset {data} was generated with seed {ds_seed}")
    return ds_preset, ds_seed


def machine_description() -> str:
    """CPU model, core count and accelerator, for reports."""
    import torch

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else "no GPU"
    return f"{cpu}, {os.cpu_count()} cores, {gpu}"
