"""Datasets: plan episodes from a preset, simulate and render them in parallel, cut and label windows.

A dataset folder holds one folder per episode (see `benchmarks.episode`), `windows.csv` (one row per
2 s window: episode, start, split, label, kind, sub-kind, wheel) and `manifest.json` (format version,
preset, seed, episodes with their split and the sha256 of every file; typed, read and written by
`benchmarks.manifest`). It is written to a temporary folder beside the target and renamed into place, so a
dataset folder is either complete or absent.
"""

from __future__ import annotations

import csv
import functools
import hashlib
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

import sim
import synth_audio
from benchmarks.allocator import keep_freed_memory
from benchmarks.episode import (
    AUDIO_FILE,
    EPISODE_FILES,
    IMPORTED,
    IMPORTED_EPISODE_FILES,
    SIMULATED,
    EpisodeMeta,
    fault_severity,
    read_episode,
    read_imu_signals,
    software_versions,
    write_episode,
)
from benchmarks.errors import OutputExistsError, UserError, check_seed
from benchmarks.executor import Executor, LocalExecutor, publish_dir
from benchmarks.manifest import (
    DATASET_FORMAT_VERSION,
    MANIFEST_FILE,
    DatasetError,
    DroppedWindow,
    EpisodeSpec,
    Manifest,
    ManifestEpisode,
    ManifestWindows,
)
from benchmarks.presets import Preset, get_preset
from msvdd import preprocess
from msvdd.contract import IMU_LEN, IMU_RATE, WINDOW_S, Windows
from sim import vocab
from sim.random_scenarios import OBSTACLE_ENVIRONMENTS, SETTLE_S, scale_speeds
from sim.vocab import COLLISION, LABELS, MECHANICAL, NORMAL, SUB_KINDS

WINDOW_COLUMNS: tuple[str, ...] = (
    "window_id",
    "episode",
    "start_s",
    "split",
    "label",
    "kind",
    "sub_kind",
    "wheel",
    "unit",
)
"""Columns of `windows.csv`."""

MECHANICAL_MIN_FRACTION = 0.5
"""A window is a mechanical-fault window when at least this fraction of it has the fault active..."""
MIN_FAULT_REVOLUTIONS = 1.0
"""... and its faulty wheel turned at least this far (revolutions, either way) while the fault was active.

A wheel defect shows only where it meets the floor or its bearing turns: a flat, a runout or a loose hub once
per revolution, a bearing's spall a few times. A window in which the faulty wheel turned less than once
(the robot waiting, or creeping through a turn) may not hold the defect at all, whatever the severity; it
is left out like a window in which the fault barely started, for every method alike."""


@dataclass(frozen=True)
class WindowRow:
    """One row of `windows.csv`."""

    window_id: int
    """Index in the table."""
    episode: str
    """Episode folder name."""
    start_s: float
    """Window start in the episode, s."""
    split: str
    """`train`, `val` or `test`."""
    label: int
    """Index into `sim.vocab.LABELS`."""
    kind: str
    """`normal`, `collision` or `mechanical`."""
    sub_kind: str
    """`none`, an obstacle kind or a fault kind."""
    wheel: int
    """Faulty wheel of a mechanical window, -1 otherwise."""
    unit: int
    """Robot unit."""


def _episode_seed(dataset_seed: int, index: int) -> int:
    """An episode's seed: from the dataset seed and the episode's index in the plan only (never from the
    process or machine that builds it)."""
    return int(np.random.SeedSequence([dataset_seed, index]).generate_state(1, dtype=np.uint32)[0])


def nominal_floors() -> list[tuple[str, str]]:
    """(environment, surface) pairs nominal sequences take in turn; every surface is in the first six."""
    indoor = list(vocab.INDOOR_SURFACES)
    outdoor_only = [f for f in vocab.OUTDOOR_SURFACES if f not in indoor]
    pairs: list[tuple[str, str]] = []
    for i in range(max(len(indoor), len(outdoor_only))):
        pairs += [("indoor", indoor[i])] if i < len(indoor) else []
        pairs += [("outdoor", outdoor_only[i])] if i < len(outdoor_only) else []
    return pairs + [("outdoor", f) for f in vocab.OUTDOOR_SURFACES if f in indoor]


def split_floors(preset: Preset, side: str) -> list[tuple[str, str]] | None:
    """The (environment, surface) pairs episodes of `side` (`train` or `test`) may take, in
    `nominal_floors` order; None when the preset does not restrict them (the sampler draws freely)."""
    environments = getattr(preset, f"{side}_environments")
    surfaces = getattr(preset, f"{side}_surfaces")
    if not environments and not surfaces:
        return None
    floors = [
        (env, surface)
        for env, surface in nominal_floors()
        if (not environments or env in environments) and (not surfaces or surface in surfaces)
    ]
    if not floors:
        raise UserError(
            f"preset {preset.name!r}: no floor is in both {side}_environments {list(environments)} and "
            f"{side}_surfaces {list(surfaces)}; indoor surfaces: {', '.join(vocab.INDOOR_SURFACES)}, "
            f"outdoor: {', '.join(vocab.OUTDOOR_SURFACES)}"
        )
    return floors


def _anomaly_floor(
    floors: list[tuple[str, str]] | None, obstacle_kind: str | None, count: int, preset: Preset
) -> tuple[str | None, str | None]:
    """The environment and surface of the `count`-th test anomaly episode (None each: drawn freely)."""
    if floors is None:
        return None, None
    where = OBSTACLE_ENVIRONMENTS.get(obstacle_kind or "", vocab.ENVIRONMENTS)
    usable = [f for f in floors if f[0] in where]
    if not usable:
        raise UserError(
            f"preset {preset.name!r}: obstacle kind {obstacle_kind!r} stands only {' or '.join(where)}, "
            f"outside every test floor {floors}"
        )
    return usable[count % len(usable)]


def plan_episodes(preset: Preset, seed: int) -> list[EpisodeSpec]:
    """Every episode of a dataset, deterministically from the preset and seed."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 7919]))
    specs: list[EpisodeSpec] = []

    def add(
        category: str,
        split: str,
        units: tuple[int, ...],
        duration: float,
        *,
        environment: str | None = None,
        surface: str | None = None,
        obstacle_kind: str | None = None,
        fault_kind: str | None = None,
        wheel: int | None = None,
    ) -> None:
        index = len(specs)
        count = sum(1 for s in specs if s.category == category and s.split == split)
        specs.append(
            EpisodeSpec(
                episode_id=f"{split}-{category}-{count:03d}",
                category=category,
                split=split,
                seed=_episode_seed(seed, index),
                snr_db=float(rng.uniform(*preset.snr_db)),
                options=sim.ScenarioOptions(
                    duration=duration,
                    environment=environment,
                    obstacle_kind=obstacle_kind,
                    fault_kind=fault_kind,
                    wheel=wheel,
                    severity=preset.severity,
                    unit_id=int(units[index % len(units)]),
                    transient_density=preset.transient_density,
                    surface=surface,
                ),
                drive_speed_scale=preset.drive_speed_scale,
                approach_speed_scale=preset.approach_speed_scale,
            )
        )

    # Nominal sequences take the floors in turn, so training and testing both cover every surface
    # (one surface per sequence: drawn at random, six test sequences left test normals on three). Units
    # cycle with the episode index and SNR and arena are drawn per episode, so many short test sequences
    # cover floors x SNR x unit x arena.
    # A preset that restricts the training or test floors (a domain-shift sweep) takes only those, and its
    # anomaly episodes take the test floors in turn too.
    train_floors, test_floors = split_floors(preset, "train"), split_floors(preset, "test")
    floors = {"train": train_floors or nominal_floors(), "test": test_floors or nominal_floors()}
    train_s, test_s = preset.nominal_train_duration_s, preset.nominal_test_duration_s
    for i in range(preset.nominal_train):
        split = "val" if i >= preset.nominal_train - preset.nominal_val else "train"
        env, floor = floors["train"][i % len(floors["train"])]
        add("nominal", split, preset.train_units, train_s, environment=env, surface=floor)
    for i in range(preset.nominal_test):
        env, floor = floors["test"][i % len(floors["test"])]
        add("nominal", "test", preset.test_units, test_s, environment=env, surface=floor)
    anomalies = 0
    for kind in preset.obstacle_kinds:
        for _ in range(preset.collisions_per_kind):
            environment, surface = _anomaly_floor(test_floors, kind, anomalies, preset)
            anomalies += 1
            duration = preset.collision_duration_s
            add("collision", "test", preset.test_units, duration, obstacle_kind=kind,
                environment=environment, surface=surface)  # fmt: skip
    for fault in preset.fault_kinds:
        for wheel in preset.wheels:
            for _ in range(preset.faults_per_kind_wheel):
                environment, surface = _anomaly_floor(test_floors, None, anomalies, preset)
                anomalies += 1
                duration = preset.fault_duration_s
                add("fault", "test", preset.test_units, duration, fault_kind=fault, wheel=wheel,
                    environment=environment, surface=surface)  # fmt: skip
    return specs


def episode_audio_config(spec: EpisodeSpec, muted: tuple[str, ...] = ()) -> synth_audio.AudioConfig:
    """How an episode's audio is rendered (`muted`: source groups left out, for the audit)."""
    return synth_audio.AudioConfig(snr_db=spec.snr_db, muted=muted)


def build_episode(spec: EpisodeSpec, directory: Path) -> Path:
    """Simulate, render and write one episode folder (runs in a worker process); idempotent.

    The folder is written beside its place and renamed into it, replacing a copy an earlier attempt of the
    same task left (the same spec always gives the same bytes), so a retried task is harmless. The process
    keeps the memory its episodes free for the next (`allocator.keep_freed_memory`).
    """
    keep_freed_memory()
    scenario = sim.draw_scenario(spec.seed, spec.category, spec.options)
    scenario = scale_speeds(scenario, spec.drive_speed_scale, spec.approach_speed_scale)
    # Render what the file keeps, so that the audit's re-render from trace.npz reproduces this audio exactly.
    trace = sim.simulate(scenario).at_storage_precision()
    audio = synth_audio.render(trace, episode_audio_config(spec), seed=spec.seed)
    meta = EpisodeMeta(
        episode_id=spec.episode_id,
        category=spec.category,
        split=spec.split,
        unit_id=spec.unit_id,
        seed=spec.seed,
        snr_db=spec.snr_db,
        duration_s=spec.options.duration,
    )
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f"{_STAGING}{spec.episode_id}-", dir=directory))
    try:
        written = write_episode(staging / spec.episode_id, meta, scenario.to_dict(), trace, audio)
        return publish_dir(written, directory / spec.episode_id)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _build_and_checksum(spec: EpisodeSpec, directory: Path) -> tuple[str, dict[str, str]]:
    """`build_episode`, then its files' checksums (`episode_checksums`), in the worker: the manifest's
    entry, read while the files are fresh in the worker's cache instead of all of them again at the end."""
    path = build_episode(spec, directory)
    return str(path), episode_checksums(path)


_STAGING = ".staging-"
"""Prefix of the folder an episode is written into before it is renamed into the dataset."""


def label_windows(
    label: np.ndarray,
    sub_kind: np.ndarray,
    wheel: np.ndarray,
    starts_s: np.ndarray,
    wheel_pos: np.ndarray | None = None,
) -> list[tuple[int, str, int] | None]:
    """Label each 2 s window from per-IMU-sample labels: (label, sub-kind, wheel), or None if ambiguous.

    A window touching any collision sample is a collision; one with the fault active for at least
    `MECHANICAL_MIN_FRACTION` of it, and (given the wheels' encoder positions `wheel_pos`, (m, W) rad) its
    faulty wheel turning at least `MIN_FAULT_REVOLUTIONS` meanwhile, is mechanical; one with every sample
    normal is normal; anything else (a fault barely started or ended, or a faulty wheel that barely turned)
    is ambiguous and left out.
    """
    out: list[tuple[int, str, int] | None] = []
    for start in starts_s:
        i0 = round(float(start) * IMU_RATE)
        lab, sub, whl = label[i0 : i0 + IMU_LEN], sub_kind[i0 : i0 + IMU_LEN], wheel[i0 : i0 + IMU_LEN]
        coll = lab == COLLISION
        mech = lab == MECHANICAL
        if coll.any():
            out.append((COLLISION, SUB_KINDS[int(np.bincount(sub[coll]).argmax())], -1))
        elif mech.mean() >= MECHANICAL_MIN_FRACTION:
            faulty = int(np.median(whl[mech]))
            if wheel_pos is not None and wheel_pos.shape[1] > faulty:
                turned = np.abs(np.diff(wheel_pos[i0 : i0 + IMU_LEN, faulty]))[mech[1:]].sum() / (2 * np.pi)
                if turned < MIN_FAULT_REVOLUTIONS:
                    out.append(None)
                    continue
            out.append((MECHANICAL, SUB_KINDS[int(np.bincount(sub[mech]).argmax())], faulty))
        elif (lab == NORMAL).all():
            out.append((NORMAL, "none", -1))
        else:
            out.append(None)
    return out


def window_starts(duration_s: float, hop_s: float, first_s: float = SETTLE_S) -> np.ndarray:
    """Start times of every whole 2 s window at the given hop, from `first_s` (default: the robot under
    way; the viewer scores a whole episode from 0); empty if none fits."""
    if not hop_s > 0:
        raise UserError(f"hop_s = {hop_s} is invalid; allowed: > 0 s")
    n = int(np.floor((duration_s - WINDOW_S - first_s) / hop_s + 1e-9)) + 1
    return first_s + np.arange(max(n, 0)) * hop_s


def _window_rows(
    dataset: Path, preset: Preset, specs: list[EpisodeSpec]
) -> tuple[list[WindowRow], list[DroppedWindow]]:
    """The window table, and the nominal-episode windows left out because they are not normal.

    Nominal routes avoid obstacles, but a long route can still graze one (the format-1 paper preset, seed 0,
    had a curb and a wall touched in the last seconds of two 343 s sequences); the simulator labels such a
    window a collision, and it must not enter nominal training or testing.
    """
    rows: list[WindowRow] = []
    dropped: list[DroppedWindow] = []
    for spec in specs:
        imu = read_imu_signals(dataset / spec.episode_id, ("label", "sub_kind", "label_wheel", "wheel_pos"))
        label, sub_kind, wheel = imu["label"], imu["sub_kind"], imu["label_wheel"]
        hop = preset.train_hop_s if spec.split in ("train", "val") else preset.test_hop_s
        starts = window_starts(len(label) / IMU_RATE, hop)
        labelled = label_windows(label, sub_kind, wheel, starts, imu["wheel_pos"])
        for start, lab in zip(starts, labelled, strict=True):
            if lab is None:
                continue
            if spec.category == "nominal" and lab[0] != NORMAL:
                dropped.append(DroppedWindow(spec.episode_id, float(start), LABELS[lab[0]], lab[1]))
                continue
            if spec.category != "nominal" and lab[0] == NORMAL:
                continue  # anomaly episodes contribute their anomalous windows only
            label_id, sub_kind_name, wheel_id = lab
            rows.append(
                WindowRow(len(rows), spec.episode_id, float(start), spec.split, label_id, LABELS[label_id],
                          sub_kind_name, wheel_id, spec.unit_id)
            )  # fmt: skip
    return rows, dropped


def sha256_file(path: Path) -> str:
    """Hex sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def generate(
    preset: str | Preset,
    seed: int,
    out: Path,
    workers: int | None = None,
    progress: bool = True,
    executor: Executor | None = None,
) -> Path:
    """Generate a whole dataset into `out` (which must not exist), atomically.

    Args:
        preset: a preset name from `benchmarks.presets`, or a Preset (one derived by a sweep).
        seed: dataset seed; the same preset and seed give the same file checksums, with any executor.
        out: target folder.
        workers: worker processes of the default local executor (default: one per CPU); 1 runs in this
            process. Not with `executor`.
        progress: show a progress bar.
        executor: where the episodes are built (default: `LocalExecutor(workers)`); a Ray cluster of
            several machines needs `out` on a file system they all mount at the same path.
    """
    preset = get_preset(preset) if isinstance(preset, str) else preset
    seed = check_seed(seed)
    out = Path(out)
    if out.exists():
        raise OutputExistsError(f"dataset folder exists already: {out} (remove it or choose another --out)")
    if workers is not None and workers < 1:
        raise UserError(f"--workers = {workers} is invalid; allowed: an integer >= 1")
    if executor is not None and workers is not None:
        raise UserError("--workers applies to the local executor only; give it to the executor instead")
    specs = plan_episodes(preset, seed)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        run = executor if executor is not None else LocalExecutor(workers)
        build = functools.partial(_build_and_checksum, directory=tmp)
        checksums: dict[str, dict[str, str]] = {}
        for path, files in run.map(build, specs, desc="episodes", progress=progress):
            if not Path(path).is_dir():
                raise DatasetError(
                    f"{path}: written by a worker but not visible here; with a Ray cluster of several "
                    "machines, --out must be on a file system every node mounts at the same path"
                )
            checksums[Path(path).name] = files
        for leftover in tmp.glob(f"{_STAGING}*"):  # from attempts of a retried task that were killed
            shutil.rmtree(leftover, ignore_errors=True)
        rows, dropped = _window_rows(tmp, preset, specs)
        if dropped and progress:
            print(
                f"left out {len(dropped)} window(s) of nominal episodes with an anomaly in them "
                "(listed in manifest.json)"
            )
        Manifest(
            format_version=DATASET_FORMAT_VERSION,
            preset=preset,
            seed=seed,
            software=software_versions(),
            dropped_nominal_windows=tuple(dropped),
            episodes=tuple(ManifestEpisode(s, checksums[s.episode_id]) for s in specs),
            windows=write_window_table(tmp, rows),
        ).save(tmp)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


WINDOWS_FILE = "windows.csv"
"""The dataset folder's window table (its manifest is `benchmarks.manifest`'s, each episode's files are
`benchmarks.episode`'s)."""


def write_window_table(folder: Path, rows: list[WindowRow]) -> ManifestWindows:
    """Write `windows.csv` into a dataset folder being built; its manifest entry (checksum and count). The
    generator and the importer both finish with it and `Manifest.save`."""
    _write_windows_csv(folder / WINDOWS_FILE, rows)
    return ManifestWindows(file=WINDOWS_FILE, sha256=sha256_file(folder / WINDOWS_FILE), count=len(rows))


def episode_checksums(folder: Path, source: str = SIMULATED) -> dict[str, str]:
    """File name -> sha256 of every file of the episode folder `folder` (a `simulate`d or an `import`ed
    one): its manifest entry's `files`."""
    names = IMPORTED_EPISODE_FILES if source == IMPORTED else EPISODE_FILES
    return {name: sha256_file(Path(folder) / name) for name in names}


def _write_windows_csv(path: Path, rows: list[WindowRow]) -> None:
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(WINDOW_COLUMNS)
        for row in rows:
            writer.writerow([getattr(row, c) for c in WINDOW_COLUMNS])


@dataclass(frozen=True)
class Dataset:
    """A generated dataset read back (and verified) from disk."""

    path: Path
    """Dataset folder."""
    manifest: Manifest
    """The manifest."""
    windows: list[WindowRow]
    """The window table."""

    @property
    def preset(self) -> Preset:
        """The preset the dataset was generated with."""
        return self.manifest.preset

    def episode_specs(self) -> dict[str, EpisodeSpec]:
        """Every episode's plan, by episode id, as `generate` recorded it in the manifest."""
        return {e.episode_id: e.spec for e in self.manifest.episodes}

    @property
    def fingerprint(self) -> str:
        """`dataset_fingerprint` of the manifest: what identifies this dataset in run reports."""
        return dataset_fingerprint(self.manifest)

    @property
    def seed(self) -> int:
        """The dataset seed (0 for an import, which has none)."""
        return self.manifest.seed

    @property
    def preset_name(self) -> str:
        """Name of the preset it was generated with (`import-<layout>` for an import)."""
        return self.manifest.preset.name

    @property
    def source(self) -> str:
        """`simulate` (generated) or `import` (recordings)."""
        return self.manifest.source

    @property
    def modalities(self) -> tuple[str, ...]:
        """The sensors the dataset carries (a generated one: audio and IMU)."""
        return self.manifest.modalities

    @property
    def episode_ids(self) -> list[str]:
        """Every episode id, in manifest order (an episode's index here seeds its robustness draws)."""
        return [e.episode_id for e in self.manifest.episodes]

    def categories(self) -> dict[str, str]:
        """Episode id -> category (`nominal`, `collision`, `fault`)."""
        return {e.episode_id: e.spec.category for e in self.manifest.episodes}

    def fault_severities(self) -> dict[str, float]:
        """Fault severity (0..1) of every fault episode that has a window in the table, by episode id, from
        its scenario (`benchmarks.episode.fault_severity`); empty for a dataset of recordings."""
        if self.source == IMPORTED:
            return {}
        windowed = {r.episode for r in self.windows}
        faulty = sorted(e for e, c in self.categories().items() if c == "fault" and e in windowed)
        found = {e: fault_severity(self.path / e) for e in faulty}
        return {e: s for e, s in found.items() if s is not None}

    def rows(self, split: str) -> list[WindowRow]:
        """Window rows of one split."""
        return [r for r in self.windows if r.split == split]

    def load_windows(self, split: str, progress: bool = False) -> tuple[Windows, list[WindowRow]]:
        """Decimated, cut windows of one split, in window-table order (a bar per episode if `progress`)."""
        return load_window_rows(self.path, self.rows(split), progress=progress, what=f"loading {split}")


def load_window_rows(
    dataset: Path, rows: list[WindowRow], progress: bool = False, what: str = "loading windows"
) -> tuple[Windows, list[WindowRow]]:
    """Read the episodes behind `rows`, decimate their audio and cut the windows (table order kept).

    `progress` shows a bar over the episodes, described by `what`.
    """
    if not rows:
        raise DatasetError(f"{dataset}: no windows to load")
    by_episode: dict[str, list[int]] = {}
    for i, row in enumerate(rows):
        by_episode.setdefault(row.episode, []).append(i)
    audio_parts: list[np.ndarray] = [np.empty(0)] * len(rows)
    imu_parts: list[np.ndarray] = [np.empty(0)] * len(rows)
    imu6_parts: list[np.ndarray] = [np.empty(0)] * len(rows)
    odometry_parts: list[np.ndarray] = [np.empty(0)] * len(rows)
    for episode_id, indices in tqdm(by_episode.items(), desc=what, unit="ep", disable=not progress):
        episode = read_episode(dataset / episode_id)
        audio4410 = preprocess.decimate_audio(episode.audio)
        starts = np.array([rows[i].start_s for i in indices])
        odometry = episode.wheel_pos if episode.wheel_pos.shape[1] else None
        windows = preprocess.frame_windows(
            audio4410, episode.imu_vel_z, starts, imu6=episode.imu6, odometry=odometry
        )
        for j, i in enumerate(indices):
            audio_parts[i] = windows.audio[j]
            imu_parts[i] = windows.imu[j]
            assert windows.imu6 is not None
            imu6_parts[i] = windows.imu6[j]
            if windows.odometry is not None:
                odometry_parts[i] = windows.odometry[j]
    same = len({p.shape for p in odometry_parts}) == 1 and odometry_parts[0].ndim == 2
    return (
        Windows(
            audio=np.stack(audio_parts),
            imu=np.stack(imu_parts),
            imu6=np.stack(imu6_parts),
            odometry=np.stack(odometry_parts) if same else None,
        ),
        rows,
    )


def open_dataset(path: Path, verify: bool = True, progress: bool = False) -> Dataset:
    """Open a dataset folder, checking its format version and (by default) every file's sha256.

    `progress` shows a bar over the files while their sha256 is checked.
    """
    path = Path(path)
    manifest = Manifest.load(path)
    if verify:
        verify_dataset(path, manifest, progress=progress)
    windows_path = path / WINDOWS_FILE
    if not windows_path.is_file():
        raise DatasetError(f"{path}: missing window table windows.csv")
    with open(windows_path, newline="") as handle:
        reader = csv.DictReader(handle)
        rows = [
            WindowRow(int(r["window_id"]), r["episode"], float(r["start_s"]), r["split"], int(r["label"]),
                      r["kind"], r["sub_kind"], int(r["wheel"]), int(r["unit"]))
            for r in reader
        ]  # fmt: skip
    return Dataset(path=path, manifest=manifest, windows=rows)


def check_dev(dev: Dataset, evaluated: Dataset) -> str:
    """Refuse a dev dataset that is not another draw of the evaluated one; describe it for reports.

    Every choice a method makes is made on the dev dataset; the evaluated (eval) dataset is only
    reported. They must come from the same preset and from different seeds; datasets imported from
    recordings (which have no seed) must share no recording instead.
    """
    dev_preset, eval_preset = dev.preset_name, evaluated.preset_name
    if dev_preset != eval_preset:
        raise DatasetError(
            f"--dev {dev.path}: preset {dev_preset!r}, but the evaluated dataset is {eval_preset!r}; "
            "a dev dataset must be another draw of the same preset"
        )
    if IMPORTED in (dev.source, evaluated.source):
        shared = _audio_checksums(dev) & _audio_checksums(evaluated)
        if shared:
            raise DatasetError(
                f"--dev {dev.path}: {len(shared)} of its recordings are also in the evaluated dataset; "
                "dev and eval must be imported from different recordings"
            )
        return f"`{dev.path}` (preset {dev_preset}, recordings disjoint from the evaluated dataset's)"
    if dev.seed == evaluated.seed:
        raise DatasetError(
            f"--dev {dev.path}: seed {dev.seed} is the evaluated dataset's seed; "
            "dev and eval must be generated from different seeds"
        )
    return f"`{dev.path}` (preset {dev_preset}, seed {dev.seed})"


def _audio_checksums(data: Dataset) -> set[str]:
    """The sha256 of every episode's audio: what identifies a recording whatever it was named."""
    return {e.files[AUDIO_FILE] for e in data.manifest.episodes}


def dataset_fingerprint(manifest: Manifest) -> str:
    """The dataset's identity: sha256 over the sha256 of every file its manifest lists, with their paths.

    Two datasets with the same fingerprint hold the same bytes in every verified file (the window table and
    every episode file), whatever folder they sit in; the same preset and seed generated with the same
    software give the same fingerprint. Run reports record it, and `msvdd-bench compare` refuses runs whose
    fingerprints differ.
    """
    entries = [f"windows.csv {manifest.windows.sha256}"]
    for episode in manifest.episodes:
        for name, digest in sorted(episode.files.items()):
            entries.append(f"{episode.episode_id}/{name} {digest}")
    return hashlib.sha256("\n".join(sorted(entries)).encode()).hexdigest()


def verify_dataset(path: Path, manifest: Manifest, progress: bool = False) -> None:
    """Check that every file the manifest lists exists and has its recorded sha256 (a bar if `progress`)."""
    expected: list[tuple[Path, str]] = [(path / WINDOWS_FILE, manifest.windows.sha256)]
    for episode in manifest.episodes:
        for name, digest in episode.files.items():
            expected.append((path / episode.episode_id / name, digest))
    for file, digest in tqdm(expected, desc="verifying sha256", unit="file", disable=not progress):
        if not file.is_file():
            raise DatasetError(f"missing dataset file: {file}")
        if sha256_file(file) != digest:
            raise DatasetError(f"checksum mismatch: {file} (sha256 differs from {MANIFEST_FILE})")
