"""A folder of generated datasets reused across runs: `msvdd-bench run --preset ci --cache DIR`.

A cached dataset lives in `DIR/<preset>-seed<seed>-<key>/`, where `key` is the start of a sha256 over what
decides the dataset's bytes: the dataset format version, the preset's recipe, the seed, the versions of the
packages that shape the data (`benchmarks.episode.software_versions`) and the source of the code that
generates it (`sim`, `synth_audio`, the `assets` robot models, `benchmarks.dataset`, `manifest`, `episode`,
`json_records` and `presets`).
Change any of them and the key changes, so a stale dataset is never reused; older entries stay in `DIR`
until removed by hand.

An entry is reused only if its manifest verifies (every file's sha256, `benchmarks.dataset.open_dataset`);
one that does not (a truncated cache restore, a file edited by hand) is moved aside and generated again.
`generate` writes to a temporary folder and renames it into place, so an entry is complete or absent.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import json
import shutil
import tempfile
from pathlib import Path

from benchmarks.dataset import DATASET_FORMAT_VERSION, DatasetError, generate, open_dataset
from benchmarks.episode import software_versions
from benchmarks.errors import check_seed
from benchmarks.executor import Executor
from benchmarks.presets import Preset, get_preset

KEY_LENGTH = 16
"""Hex digits of the key in a cache entry's folder name."""

_GENERATOR_PACKAGES: tuple[str, ...] = ("sim", "synth_audio", "assets")
"""Packages whose every file is part of the generating code."""
_GENERATOR_MODULES: tuple[str, ...] = (
    "benchmarks.dataset",
    "benchmarks.manifest",
    "benchmarks.episode",
    "benchmarks.json_records",
    "benchmarks.presets",
)
"""Single modules that are part of it."""


def _package_files(name: str) -> list[Path]:
    module = importlib.import_module(name)
    found: list[Path] = []
    for folder in getattr(module, "__path__", []):
        found += [p for p in Path(folder).rglob("*") if p.is_file() and "__pycache__" not in p.parts]
    return found


def source_digest(packages: tuple[str, ...], modules: tuple[str, ...], files: tuple[Path, ...] = ()) -> str:
    """sha256 over the relative path and bytes of every file of `packages`, `modules` and `files`."""
    digest = hashlib.sha256()
    entries: list[tuple[str, Path]] = []
    for name in packages:
        module = importlib.import_module(name)
        roots = [Path(f) for f in getattr(module, "__path__", [])]
        for path in _package_files(name):
            root = next(r for r in roots if path.is_relative_to(r))
            entries.append((f"{name}/{path.relative_to(root).as_posix()}", path))
    for name in modules:
        file = importlib.import_module(name).__file__
        assert file is not None
        entries.append((name, Path(file)))
    entries += [(f"file:{path.name}", Path(path)) for path in files]
    for label, path in sorted(entries, key=lambda e: e[0]):
        digest.update(label.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def generator_digest() -> str:
    """sha256 over the relative path and bytes of every file of the code that generates datasets."""
    return source_digest(_GENERATOR_PACKAGES, _GENERATOR_MODULES)


def cache_key(preset: str | Preset, seed: int) -> str:
    """The key of a preset and seed's dataset for this software (see the module docstring); a `Preset`
    object (a sweep point's) is keyed by its recipe like a registered one."""
    recipe = {
        "format_version": DATASET_FORMAT_VERSION,
        "preset": dataclasses.asdict(get_preset(preset) if isinstance(preset, str) else preset),
        "seed": seed,
        "software": software_versions(),
        "generator": generator_digest(),
    }
    return hashlib.sha256(json.dumps(recipe, sort_keys=True).encode()).hexdigest()[:KEY_LENGTH]


def cache_entry(cache: Path, preset_name: str, seed: int) -> Path:
    """Where the dataset of a preset and seed lives in the cache folder `cache`."""
    return Path(cache) / f"{preset_name}-seed{seed}-{cache_key(preset_name, seed)}"


def cached_dataset(
    cache: Path,
    preset_name: str,
    seed: int,
    workers: int | None = None,
    progress: bool = True,
    executor: Executor | None = None,
) -> tuple[Path, bool]:
    """The cached dataset of a preset and seed, generated into `cache` first if absent or corrupt (its
    episodes built by `executor`, default local processes).

    Returns (dataset folder, whether it was reused). A corrupt entry is moved aside, removed and generated
    again; the reason is printed.
    """
    check_seed(seed)
    entry = cache_entry(Path(cache), preset_name, seed)
    if entry.exists():
        try:
            open_dataset(entry)
            return entry, True
        except (DatasetError, FileNotFoundError, json.JSONDecodeError, KeyError) as exc:
            print(f"cached dataset {entry} does not verify ({exc}); generating it again", flush=True)
            trash = Path(tempfile.mkdtemp(prefix=f".{entry.name}.corrupt-", dir=entry.parent))
            entry.rename(trash / entry.name)
            shutil.rmtree(trash, ignore_errors=True)
    entry.parent.mkdir(parents=True, exist_ok=True)
    try:
        generate(preset_name, seed, entry, workers=workers, progress=progress, executor=executor)
    except OSError:
        if not entry.exists():  # another process did not just create it: a real error
            raise
        open_dataset(entry)  # another process finished the same entry first: use it if it verifies
        return entry, True
    return entry, False
