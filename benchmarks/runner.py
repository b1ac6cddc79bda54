"""`msvdd-bench run`: generate (or reuse) a dataset, train every method, evaluate, report, in one go."""

from __future__ import annotations

import datetime
import os
import platform
import shutil
import tempfile
from pathlib import Path

import numpy as np

from benchmarks import methods
from benchmarks.cache import cached_dataset
from benchmarks.dataset import check_dev, generate, open_dataset
from benchmarks.errors import OutputExistsError, UserError, check_seed
from benchmarks.executor import Executor
from benchmarks.methods.base import check_scale
from benchmarks.pipeline import TrainedModel, score_and_measure, test_windows, train_method
from benchmarks.presets import Preset, expand_methods, get_preset, preset_names
from benchmarks.report import RunInfo, write_report

DEFAULT_PRESET = "quick"
"""The dataset preset of `run` and `demo` when neither --preset nor --data names one."""


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
) -> Path:
    """Generate (or reuse) a dataset, train every method for every seed, evaluate, and write the report.

    Everything is written into a temporary folder beside `out` and renamed into place at the end, so an
    interrupted run leaves no folder that looks complete. `dev` names the dev dataset the methods'
    choices were made on (checked against the evaluated one and recorded in the report). With `data`, the
    preset and dataset seed are the dataset's (`preset_name` and `seed`, when given, must agree with it);
    without, they default to `DEFAULT_PRESET` and 0. With `cache` (not with `data`), the dataset is taken
    from that cache folder, generated there first if needed (`benchmarks.cache`). `device` is where the
    torch methods train and score; `progress` shows every bar, training ones included. `executor` builds
    the episodes of a generated dataset (default: local processes, `workers` of them). `preset`, instead of
    `preset_name`, is a preset that is not registered (a sweep point's; not with `data` or `cache`).
    Returns `out`.
    """
    out = Path(out)
    if out.exists():
        raise OutputExistsError(f"run folder exists already: {out} (remove it or choose another --out)")
    if data is not None and cache is not None:
        raise UserError("--data and --cache exclude each other (a dataset folder, or a cache folder)")
    if preset is not None and (preset_name is not None or data is not None or cache is not None):
        raise UserError("a preset object excludes a preset name, --data and --cache")
    if data is not None:
        preset_name, seed = _dataset_identity(Path(data), preset_name, seed)
        if preset_name not in preset_names():  # a derived preset (a sweep point's): the manifest's
            preset = open_dataset(Path(data), verify=False).preset
    if preset is None:
        preset = get_preset(preset_name or DEFAULT_PRESET)
    preset_name = preset.name
    seed = 0 if seed is None else check_seed(seed)
    names = expand_methods(method_names or list(preset.methods) or ["all"], methods.names())
    for name in names:
        methods.spec(name)
    chosen_scale = check_scale(scale or preset.method_scale)
    train_seeds = seeds if seeds else list(preset.seeds)
    if cache is not None:
        data, reused = cached_dataset(
            Path(cache), preset_name, seed, workers=workers, progress=progress, executor=executor
        )
        print(f"{'reusing' if reused else 'generated'} cached dataset {data}", flush=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        if data is None:
            data_path = generate(
                preset, seed, tmp / "dataset", workers=workers, progress=progress, executor=executor
            )
        else:
            data_path = Path(data)
        # a cache entry was verified just now
        dataset = open_dataset(data_path, verify=cache is None, progress=progress)
        dev_text = check_dev(open_dataset(Path(dev), verify=False), dataset) if dev is not None else ""
        train, _ = dataset.load_windows("train", progress=progress)
        val = dataset.load_windows("val", progress=progress)[0] if dataset.rows("val") else None
        test = test_windows(dataset, progress=progress)
        models: list[TrainedModel] = []
        for name in names:
            for s in train_seeds:
                if progress:
                    print(
                        f"training {name} (seed {s}, scale {chosen_scale}) on {len(train)} windows",
                        flush=True,
                    )
                folder = tmp / "models" / f"{name.replace(':', '.')}-seed{s}"  # module:Class -> module.Class
                models.append(
                    train_method(
                        dataset, name, s, chosen_scale, folder, train, val, device=device, progress=progress
                    )
                )
        scores, per_method, rows = score_and_measure(dataset, models, test=test, progress=progress)
        fit_time: dict[str, list[float]] = {}
        for m in models:
            fit_time.setdefault(m.method, []).append(m.train_seconds)
        info = RunInfo(
            preset=preset_name,
            dataset_seed=seed,
            dataset=str(data_path if data is not None else out / "dataset"),
            command=command,
            machine=machine_description(),
            date=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
            train_seconds={k: float(np.mean(v)) for k, v in fit_time.items()},
            dev=dev_text,
            dataset_fingerprint=dataset.fingerprint,
        )
        write_report(tmp, info, rows, scores, per_method)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


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
