"""The part every layout shares: the split rule, labelled windows, and writing the dataset folder atomically.

A layout module turns its source into `Planned` recordings (name, group, split pool, whether it holds an
anomaly, and a deferred `load`); `assign_splits` applies the split rule; `write_dataset` loads each
recording in turn, writes it as an episode folder (audio.flac, imu.npz, events.json, meta.json: no
trace.npz), cuts and labels its 2 s windows, then writes windows.csv and manifest.json, all in a temporary
folder beside the target that is renamed into place. A recording read from time-stamped streams (the ros2
layout) brings a `StreamReport`: no window overlaps its resets, and its counts go to the manifest's
`import` section under `streams`, by recording, with the windows left out and those holding filled samples.

Split rule: a recording with an anomaly is test data. Nominal recordings whose split the source fixes keep
it; the others are split per group (MIMII: per machine type and id; folder: all together), in name order:
the first ones train, then `val_fraction` of the rest validation, and the last `test_fraction` test
(round half up), so that with time-stamped names the test data is the most recent.
"""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

import synth_audio
from benchmarks.dataset import (
    WindowRow,
    episode_checksums,
    label_windows,
    window_starts,
    write_window_table,
)
from benchmarks.episode import (
    IMPORTED,
    AnomalySpan,
    EpisodeMeta,
    ImuArrays,
    software_versions,
    write_imported_episode,
)
from benchmarks.errors import OutputExistsError
from benchmarks.importers.config import ImportConfig, SourceError
from benchmarks.importers.signals import OUT_AUDIO_RATE
from benchmarks.importers.timed import Span as TimeSpan
from benchmarks.importers.timed import StreamReport
from benchmarks.manifest import (
    DATASET_FORMAT_VERSION,
    EpisodeSpec,
    Manifest,
    ManifestEpisode,
    ManifestImport,
    is_dataset_folder,
)
from benchmarks.presets import Preset
from msvdd.contract import IMU_RATE, WINDOW_S
from sim.random_scenarios import ScenarioOptions
from sim.vocab import COLLISION, LABELS, MECHANICAL, NORMAL, SUB_KINDS

POOLS: tuple[str, ...] = ("auto", "fit", "train", "val", "test")
"""Where a planned recording may go: `auto` (the split rule: train, val or test), `fit` (train or val),
or a split the source fixes."""
UNSPECIFIED = "unspecified"
"""Sub-kind of an anomaly whose source names none."""
RESERVED_SUB_KINDS: tuple[str, ...] = ("none", *LABELS)
"""Names a sub-kind may not take: they are kinds, or the normal sub-kind."""


@dataclass(frozen=True)
class Span:
    """A labelled anomaly in a recording."""

    start_s: float
    """Start, s from the recording's first sample."""
    end_s: float
    """End, s."""
    kind: str
    """`collision` or `mechanical`."""
    sub_kind: str
    """What it was (an obstacle, a fault, a machine type), or `unspecified`."""
    wheel: int = -1
    """Faulty wheel of a mechanical anomaly (its column in the wheel odometry); -1: not known."""


@dataclass(frozen=True)
class Recording:
    """One recording read and brought to the dataset's rates, ready to be written as an episode."""

    audio: np.ndarray
    """(n, 2) float32 at 44.1 kHz."""
    vel_z: np.ndarray | None
    """(m,) float32 z velocity at 200 Hz; None: no IMU (audio-only dataset)."""
    imu6: np.ndarray | None
    """(m, 6) float32 accelerometer and gyroscope at 200 Hz; None: not recorded (zeros are stored)."""
    spans: tuple[Span, ...] = ()
    """Labelled anomalies."""
    starts_s: tuple[float, ...] | None = None
    """Window starts the source fixes (pre-cut windows); None: every 2 s window at the split's hop."""
    provenance: dict[str, Any] = field(default_factory=dict)
    """What the source was (files, original rates and channels), stored in meta.json."""
    wheel_pos: np.ndarray | None = None
    """(m, W) wheel encoder positions at 200 Hz, rad (the odometry modality); None: not recorded."""
    streams: StreamReport | None = None
    """What laying out time-stamped streams met (`benchmarks.importers.timed`); None: not read from them."""

    @property
    def modalities(self) -> tuple[str, ...]:
        """The sensors it carries, in `benchmarks.episode.ALL_MODALITIES` order."""
        if self.vel_z is None:
            return ("audio",)
        return ("audio", "imu") if self.wheel_pos is None else ("audio", "imu", "odometry")


@dataclass(frozen=True)
class Planned:
    """A recording found in the source, not read yet."""

    name: str
    """Its name in the source (a relative path without suffix, or group/index)."""
    group: str
    """Split-rule group (a machine type and id, or empty)."""
    pool: str
    """One of `POOLS`."""
    anomalous: bool
    """Whether it holds a labelled anomaly (then it is test data)."""
    unit_id: int
    """Unit (robot, machine) it was recorded on."""
    load: Callable[[], Recording]
    """Reads and converts it."""


def _round_half_up(x: float) -> int:
    return math.floor(x + 0.5)


def assign_splits(plans: Sequence[Planned], config: ImportConfig) -> list[str]:
    """The split of each planned recording (see the module docstring for the rule).

    Raises:
        SourceError: an anomalous recording fixed to train or val, or no training recording at all.
    """
    splits: list[str | None] = [None] * len(plans)
    groups: dict[str, list[int]] = {}
    for i, plan in enumerate(plans):
        if plan.anomalous:
            if plan.pool not in ("auto", "test"):
                raise SourceError(
                    f"recording {plan.name!r} holds a labelled anomaly but its split is {plan.pool!r}; "
                    "allowed: anomalies are test data only"
                )
            splits[i] = "test"
        elif plan.pool in ("train", "val", "test"):
            splits[i] = plan.pool
        else:
            groups.setdefault(f"{plan.pool}:{plan.group}", []).append(i)
    for key, members in groups.items():
        order = sorted(members, key=lambda i: plans[i].name)
        n = len(order)
        n_test = _round_half_up(config.split.test_fraction * n) if key.startswith("auto:") else 0
        n_val = _round_half_up(config.split.val_fraction * (n - n_test))
        n_train = n - n_test - n_val
        for rank, i in enumerate(order):
            splits[i] = "train" if rank < n_train else "val" if rank < n_train + n_val else "test"
    if "train" not in splits:
        raise SourceError(
            "no nominal training recording: every recording is anomalous or held out "
            f"({len(plans)} found); allowed: at least one nominal recording in training"
        )
    return [s or "test" for s in splits]


def _label_timeline(
    spans: Sequence[Span], n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str], np.ndarray]:
    """Per 200 Hz sample: label index, `SUB_KINDS` index (0 for names outside it), local sub-kind index; the
    local names; the faulty wheel (-1 where none or not known)."""
    label = np.zeros(n, dtype=np.int8)
    sub_global = np.zeros(n, dtype=np.int16)
    sub_local = np.zeros(n, dtype=np.int16)
    wheel = np.full(n, -1, dtype=np.int8)
    names = ["none"]
    # Mechanical spans first: a collision overlapping a fault wins its samples.
    for span in sorted(spans, key=lambda s: s.kind == "collision"):
        i0 = max(0, math.ceil(span.start_s * IMU_RATE - 1e-9))
        i1 = min(n, math.ceil(span.end_s * IMU_RATE - 1e-9))
        if span.sub_kind not in names:
            names.append(span.sub_kind)
        label[i0:i1] = COLLISION if span.kind == "collision" else MECHANICAL
        sub_global[i0:i1] = SUB_KINDS.index(span.sub_kind) if span.sub_kind in SUB_KINDS else 0
        sub_local[i0:i1] = names.index(span.sub_kind)
        wheel[i0:i1] = span.wheel if span.kind == "mechanical" else -1
    return label, sub_global, sub_local, names, wheel


def _window_labels(
    label: np.ndarray,
    sub_local: np.ndarray,
    names: list[str],
    starts: np.ndarray,
    wheel: np.ndarray,
    wheel_pos: np.ndarray | None,
) -> list[tuple[int, str, int] | None]:
    """(label, sub-kind name, wheel) of each window, by the generated datasets' rule (`label_windows`: with
    the wheel odometry, a fault window needs its known faulty wheel to have turned)."""
    out: list[tuple[int, str, int] | None] = []
    for start, lab in zip(starts, label_windows(label, sub_local, wheel, starts, wheel_pos), strict=True):
        if lab is None:
            out.append(None)
            continue
        if lab[0] == NORMAL:
            out.append((NORMAL, "none", -1))
            continue
        i0 = round(float(start) * IMU_RATE)
        i1 = i0 + round(WINDOW_S * IMU_RATE)
        seg_label, seg_sub = label[i0:i1], sub_local[i0:i1]
        out.append((lab[0], names[int(np.bincount(seg_sub[seg_label == lab[0]]).argmax())], lab[2]))
    return out


def _overlaps(starts: np.ndarray, spans: Sequence[TimeSpan]) -> np.ndarray:
    """Which 2 s windows starting at `starts` overlap any of `spans`."""
    hit = np.zeros(starts.shape, dtype=bool)
    for lo, hi in spans:
        hit |= (starts < hi) & (starts + WINDOW_S > lo)
    return hit


@dataclass
class _Written:
    """What the writer keeps of each episode for the window table and the manifest."""

    spec: EpisodeSpec
    name: str
    rows: list[WindowRow]
    files: dict[str, str]
    streams: dict[str, Any] | None


def _category(spans: Sequence[Span]) -> str:
    if not spans:
        return "nominal"
    return "fault" if any(s.kind == "mechanical" for s in spans) else "collision"


def _write_episode(
    directory: Path, episode_id: str, split: str, plan: Planned, rec: Recording, config: ImportConfig
) -> tuple[EpisodeSpec, list[WindowRow], dict[str, Any] | None]:
    """Write one episode folder; its spec, its window rows (window_id filled in later) and, for a recording
    read from time-stamped streams, its counts for the manifest."""
    audio = np.asarray(rec.audio, dtype=np.float32)
    duration = audio.shape[0] / OUT_AUDIO_RATE
    if rec.vel_z is not None:
        duration = min(duration, rec.vel_z.shape[0] / IMU_RATE)
    n_imu = math.floor(duration * IMU_RATE + 1e-9)
    audio = audio[: math.floor(duration * OUT_AUDIO_RATE + 1e-9)]
    vel_z = np.zeros(n_imu, np.float32) if rec.vel_z is None else rec.vel_z[:n_imu].astype(np.float32)
    imu6 = np.zeros((n_imu, 6), np.float32) if rec.imu6 is None else rec.imu6[:n_imu].astype(np.float32)
    wheel_pos = None if rec.wheel_pos is None else np.asarray(rec.wheel_pos[:n_imu], dtype=np.float64)
    for span in rec.spans:
        if span.start_s >= duration:
            raise SourceError(
                f"recording {plan.name!r}: anomaly span start {span.start_s:g} s is past its end "
                f"({duration:.3f} s); allowed: spans inside the recording"
            )
    label, sub_global, sub_local, names, wheel = _label_timeline(rec.spans, n_imu)
    if rec.starts_s is not None:
        starts = np.asarray(rec.starts_s, dtype=np.float64)
    else:
        hop = config.test_hop_s if split == "test" else config.train_hop_s
        starts = window_starts(duration, hop, first_s=0.0)
    if starts.size == 0:
        raise SourceError(
            f"recording {plan.name!r}: {duration:.3f} s long; allowed: at least one {WINDOW_S:g} s window"
        )
    counts: dict[str, Any] | None = None
    if rec.streams is not None:
        skipped = _overlaps(starts, rec.streams.reset_s)
        starts = starts[~skipped]
        counts = {name: dataclasses.asdict(c) for name, c in rec.streams.counts.items()}
        counts |= {
            "windows_skipped": int(skipped.sum()),
            "windows_with_fill": int(_overlaps(starts, rec.streams.filled_s).sum()),
        }
    category = _category(rec.spans)
    anomalies = tuple(
        AnomalySpan(onset=s.start_s, end=min(s.end_s, duration), kind=s.kind, sub_kind=s.sub_kind)
        for s in sorted(rec.spans, key=lambda s: s.start_s)
    )
    imu = ImuArrays(
        time=np.arange(n_imu, dtype=np.float64) / IMU_RATE,
        vel_z=vel_z,
        imu6=imu6,
        label=label,
        sub_kind=sub_global,
        label_wheel=wheel,
        wheel_pos=np.zeros((n_imu, 0)) if wheel_pos is None else wheel_pos,
    )
    write_imported_episode(
        directory / episode_id,
        EpisodeMeta(episode_id, category, split, plan.unit_id, 0, math.nan, duration),
        synth_audio.Audio(samples=audio, sample_rate=OUT_AUDIO_RATE),
        imu,
        anomalies,
        rec.modalities,
        {"name": plan.name, **rec.provenance},
    )
    rows = []
    # The revolution rule of a fault window needs the faulty wheel: where some fault's wheel is not known,
    # every fault window is kept as the label says.
    known = wheel_pos is not None and not np.any((label == MECHANICAL) & (wheel < 0))
    labelled = _window_labels(label, sub_local, names, starts, wheel, wheel_pos if known else None)
    for start, lab in zip(starts, labelled, strict=True):
        if lab is None:
            continue  # a window only partly in a fault: ambiguous, as in generated datasets
        rows.append(
            WindowRow(
                0, episode_id, float(start), split, lab[0], LABELS[lab[0]], lab[1], lab[2], plan.unit_id
            )
        )
    spec = EpisodeSpec(
        episode_id=episode_id,
        category=category,
        split=split,
        seed=0,
        snr_db=math.nan,
        options=ScenarioOptions(duration, unit_id=plan.unit_id, severity=(0.0, 0.0), transient_density=0.0),
    )
    return spec, rows, counts


def _preset(layout: str, source: Path, config: ImportConfig, written: Sequence[_Written]) -> Preset:
    """The manifest's preset of an import: counts and hops of the data; simulation fields zero or empty."""

    def of(split: str, category: str | None = "nominal") -> list[_Written]:
        return [
            w for w in written if w.spec.split == split and (category is None or w.spec.category == category)
        ]

    def mean_duration(items: list[_Written]) -> float:
        return float(np.mean([w.spec.options.duration for w in items])) if items else 0.0

    fit = of("train") + of("val")
    return Preset(
        name=f"import-{layout}",
        description=f"imported from {source} ({layout} layout)",
        nominal_train=len(fit),
        nominal_val=len(of("val")),
        nominal_train_duration_s=mean_duration(fit),
        nominal_test=len(of("test")),
        nominal_test_duration_s=mean_duration(of("test")),
        collisions_per_kind=0,
        collision_duration_s=0.0,
        faults_per_kind_wheel=0,
        fault_duration_s=0.0,
        severity=(0.0, 0.0),
        snr_db=(0.0, 0.0),
        transient_density=0.0,
        train_units=tuple(sorted({w.spec.unit_id for w in fit})),
        test_units=tuple(sorted({w.spec.unit_id for w in of("test", None)})),
        train_hop_s=config.train_hop_s,
        test_hop_s=config.test_hop_s,
        method_scale=config.scale,
        seeds=(0,),
        fault_kinds=(),
        obstacle_kinds=(),
        wheels=(),
    )


def _check_output(out: Path, source: Path, replace: bool) -> None:
    if out.resolve() == source.resolve() or source.resolve() in out.resolve().parents:
        raise SourceError(f"--out {out} is inside the source folder {source}; allowed: a folder outside it")
    if out.exists() or out.is_symlink():
        if not replace:
            raise OutputExistsError(
                f"dataset folder exists already: {out} (remove it, choose another --out, or pass --replace)"
            )
        if not out.is_dir() or (any(out.iterdir()) and not is_dataset_folder(out)):
            raise OutputExistsError(
                f"--replace: {out} is not a dataset folder (no manifest.json); it is left alone"
            )


def write_dataset(
    layout: str,
    source: Path,
    out: Path,
    plans: Sequence[Planned],
    config: ImportConfig,
    extra: dict[str, Any],
    *,
    replace: bool = False,
    progress: bool = True,
) -> Path:
    """Split, load and write every planned recording into the dataset folder `out`, atomically.

    Args:
        layout: the source layout (recorded in the manifest).
        source: the source folder.
        out: the dataset folder to create (with `replace`, an existing dataset folder is swapped out).
        plans: the recordings found (`Planned`).
        config: the shared import options.
        extra: layout facts for the manifest's `import` section (options, units).
        replace: replace an existing dataset folder at `out`.
        progress: a bar over the recordings.
    """
    out = Path(out)
    _check_output(out, Path(source), replace)
    splits = assign_splits(plans, config)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        written: list[_Written] = []
        counts: dict[tuple[str, str], int] = {}
        modalities: set[tuple[str, ...]] = set()
        for plan, split in tqdm(
            list(zip(plans, splits, strict=True)), desc="importing", unit="rec", disable=not progress
        ):
            rec = plan.load()
            category = _category(rec.spans)
            if plan.anomalous != bool(rec.spans):
                raise RuntimeError(
                    f"{layout} layout bug: {plan.name!r} planned anomalous={plan.anomalous}, "
                    f"loaded with {len(rec.spans)} span(s)"
                )
            index = counts.get((split, category), 0)
            counts[(split, category)] = index + 1
            episode_id = f"{split}-{category}-{index:04d}"
            spec, rows, streams = _write_episode(tmp, episode_id, split, plan, rec, config)
            files = episode_checksums(tmp / episode_id, IMPORTED)
            written.append(_Written(spec, plan.name, rows, files, streams))
            modalities.add(rec.modalities)
        if len(modalities) > 1:
            kinds = " and ".join(sorted("+".join(m) for m in modalities))
            raise SourceError(
                f"{source}: the recordings carry different sensors ({kinds}); allowed: the same in all"
            )
        streams = {w.name: w.streams for w in written if w.streams is not None}
        if streams:
            extra = {**extra, "streams": streams}
        rows = [r for w in written for r in w.rows]
        rows = [dataclasses.replace(r, window_id=i) for i, r in enumerate(rows)]
        preset = _preset(layout, Path(source), config, written)
        Manifest(
            format_version=DATASET_FORMAT_VERSION,
            preset=preset,
            seed=0,
            software=software_versions(),
            dropped_nominal_windows=(),
            episodes=tuple(ManifestEpisode(w.spec, w.files, recording=w.name) for w in written),
            windows=write_window_table(tmp, rows),
            imported=_import_section(layout, Path(source), extra),
            modalities=next(iter(modalities)),
        ).save(tmp)
        _swap_into_place(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def _import_section(layout: str, source: Path, extra: dict[str, Any]) -> ManifestImport:
    """The manifest's `import` section from the layout's `extra` (options, recordings and its own facts)."""
    facts = {k: v for k, v in extra.items() if k not in ("options", "recordings")}
    return ManifestImport(layout, str(source.resolve()), extra["options"], extra["recordings"], facts)


def _swap_into_place(tmp: Path, out: Path) -> None:
    """Rename `tmp` to `out`; an existing `out` (a dataset, checked) is moved aside first, then removed."""
    old: Path | None = None
    if out.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
        os.replace(out, old / out.name)
    try:
        os.replace(tmp, out)
    except BaseException:
        if old is not None:
            os.replace(old / out.name, out)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
