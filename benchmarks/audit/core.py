"""`run_audit(dataset)`: every shortcut probe of a dataset, measured on its test windows.

The probes (limits in `benchmarks.audit.report`):

- behaviour: what the robot does, from the simulator's ground-truth motion (fraction of the window
  reversing, turning in place and standing still, peak deceleration, peak yaw rate), scored as they are
  (standing still is what "the drive noise stops" means);
- naive: window audio RMS, peak level, crest factor and spectral-flux peak at 44.1 kHz, and the IMU
  acceleration peak, overall, per kind and per sub-kind;
- deleted: the test anomaly episodes rendered again from their stored traces without their own sound
  (impacts, scrapes, the motors' strain against the obstacle during a contact, and fault sounds muted; same
  seed, same physics), scored by the audio-only reference detector; if it still finds them, it hears
  something other than the anomaly (the robot's manoeuvres before and after a contact stay in);
- level: in each fault test episode, the fault's own sound (the stored mix less its muted re-render)
  against the rest of the mix in the fault's characteristic band after onset, dB; the median per sub-kind and
  per sub-kind and severity bin is reported (far below 0 dB, the fault is buried in the sound);
- leak: windows of anomaly episodes at least 1 s away from any anomalous sample, against nominal test
  windows, scored by the reference detector;
- clipping: share of windows of each class within 1 dB of full scale;
- reference: the reference detector (`gaussian-early`) with its episode-cluster bootstrap 95 % interval and
  its spread over the nominal test sequences;
- ambience: repetition of the environment's noise beds (autocorrelation beyond 1 s), on nominal test
  episodes rendered again with stems;
- context: the arena's area as a score (anomaly episodes must be drawn like nominal ones);
- oracle: is each wheel fault physically in the sensors? A privileged condition-monitoring oracle
  (`benchmarks.audit.oracle`: the true wheel angle, the defect's angle and order) per fault kind and severity
  bin, at least `oracle.ORACLE_FLOOR` at severity >= 0.75 and higher there than below 0.5; and its control,
  the fault episodes simulated again at severity 0, at chance.

Scalars carry no direction, so they are judged two-sided (max(AUC, 1 - AUC)); detectors are judged by
their AUC as it is (higher = flagged as more anomalous).

A dataset imported from recordings (`msvdd-bench import`) has no simulator behind it: the behaviour,
deleted-sound, fault-level, ambience and context probes are skipped (rows with status SKIP and the reason),
and the others run on what was recorded. Without IMU (an audio-only import) the IMU acceleration peak is
skipped and the reference detector is the audio-only one (`gaussian-audio`).

An audit records its key (`audit_key`: the dataset's fingerprint, the package versions and the source of
the project's code); `msvdd-bench audit --reuse` prints a stored audit whose key matches instead of
computing it again (`make bench`, which audits both datasets on every call).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

import synth_audio
from benchmarks.allocator import keep_freed_memory
from benchmarks.audit import oracle, signals
from benchmarks.audit.report import (
    BEHAVIOUR_LIMIT,
    CLIPPING_LIMIT,
    CONTEXT_LIMIT,
    DELETED_LIMIT,
    LEAK_LIMIT,
    NAIVE_OVERALL_LIMIT,
    NAIVE_SUB_KIND_LIMIT,
    REFERENCE_HALF_WIDTH_LIMIT,
    REPETITION_LIMIT,
    AuditResult,
    ProbeRow,
    read,
)
from benchmarks.cache import source_digest
from benchmarks.dataset import Dataset, DatasetError, WindowRow, episode_audio_config, open_dataset
from benchmarks.episode import (
    IMPORTED,
    audio_file,
    read_episode,
    read_trace,
    read_trace_signals,
    software_versions,
)
from benchmarks.methods.gaussian import GaussianReference
from benchmarks.metrics import roc_auc
from benchmarks.uncertainty import auc_interval, auc_per_normal_episode
from msvdd import preprocess
from msvdd.contract import IMU_RATE, WINDOW_S, Windows
from sim.random_scenarios import SETTLE_S
from sim.trace import Trace
from sim.vocab import NORMAL
from synth_audio.faults import fault_band

CONTEXT_MARGIN_S = 1.0
"""A context window stays this far from any anomalous sample of its episode, s."""
CONTEXT_HOP_S = 1.0
"""Hop between context windows, s."""
AMBIENCE_EPISODES = 3
"""Nominal test episodes rendered again with stems for the ambience repetition probe."""
MUTED_ANOMALY_SOURCES: tuple[str, ...] = ("impacts", "strain", "faults")
"""What the deleted-sound probe mutes: collision impacts and scrapes, the drive's strain while the robot
touches an obstacle (its motors' load held at the load before the contact), and wheel-fault sounds."""

BEHAVIOUR_PROBES = ("reversing", "turning_in_place", "yaw_rate_peak")
"""Behaviour scalars with a limit on collisions. Peak deceleration is the impact itself, and standing still
is what a contact does to a robot (it stops against the obstacle, then its reflex runs): both reported;
what audio hears of the stop is limited by the deleted-sound probe."""
NAIVE_AUDIO = ("rms", "peak", "crest", "flux")
"""Naive audio scalars with limits (the IMU acceleration peak is reported)."""
FAULT_LEVEL_PROBE = "fault sound over the rest of the mix, in its band"
"""The level probe's name: the fault's sound against everything else in the fault's band after onset."""
NO_TRACE = "imported data has no simulator trace"
"""Why the probes that need the simulator's ground truth are skipped on an imported dataset."""
TRACE_PROBES: tuple[tuple[str, str], ...] = (
    ("behaviour", "reads the robot's ground-truth motion"),
    ("context", "reads the simulated arena's size"),
    ("deleted", "renders the anomaly episodes again without their own sound"),
    ("level", "compares the fault episodes' audio with its re-render without the fault's sound"),
    ("ambience", "renders the environment's noise beds again"),
    ("oracle", "reads the true wheel angles and simulates the fault episodes again without their fault"),
)
"""(group, what it needs) of the probes that need the simulator."""


@dataclass
class _Collected:
    """Per-window data gathered in one pass over the test episodes."""

    rows: list[WindowRow] = field(default_factory=list)
    scalars: dict[str, list[float]] = field(default_factory=dict)
    area: list[float] = field(default_factory=list)
    audio: list[np.ndarray] = field(default_factory=list)
    imu: list[np.ndarray] = field(default_factory=list)
    imu6: list[np.ndarray] = field(default_factory=list)
    context: list[Windows] = field(default_factory=list)
    context_episode: list[str] = field(default_factory=list)
    context_category: list[str] = field(default_factory=list)

    def add(self, name: str, values: np.ndarray) -> None:
        self.scalars.setdefault(name, []).extend(float(v) for v in values)

    def windows(self) -> Windows:
        return Windows(
            audio=np.concatenate(self.audio), imu=np.concatenate(self.imu), imu6=np.concatenate(self.imu6)
        )


def _kinematics(episode: Path, starts: np.ndarray) -> dict[str, np.ndarray]:
    got = read_trace_signals(episode, ("base_quat", "base_linvel", "base_angvel", "physics_dt"))
    quat, linvel, angvel = got["base_quat"], got["base_linvel"], got["base_angvel"]
    dt = float(got["physics_dt"])
    speed = signals.forward_speed(quat, linvel)
    # The first physics sample is at dt: pad one sample so index = time x rate.
    speed = np.r_[speed[:1], speed]
    yaw = np.r_[angvel[:1, 2], angvel[:, 2]]
    return signals.behaviour(speed, yaw, 1.0 / dt, starts)


def context_starts(
    label: np.ndarray,
    hop_s: float = CONTEXT_HOP_S,
    margin_s: float = CONTEXT_MARGIN_S,
    first_s: float = SETTLE_S,
) -> np.ndarray:
    """Starts of 2 s windows whose span, widened by `margin_s` each side, holds only normal samples.

    Like the dataset's windows, they start `first_s` into the episode at the earliest.
    """
    n = len(label)
    duration = n / IMU_RATE
    anomalous = np.asarray(label) != NORMAL
    bad = np.r_[0, np.cumsum(anomalous)]
    out = []
    start = float(first_s)
    while start + WINDOW_S <= duration + 1e-9:
        i0 = max(0, round((start - margin_s) * IMU_RATE))
        i1 = min(n, round((start + WINDOW_S + margin_s) * IMU_RATE))
        if bad[i1] - bad[i0] == 0:
            out.append(start)
        start += hop_s
    return np.array(out)


def _collect(data: Dataset, progress: bool, simulated: bool, has_imu: bool) -> _Collected:
    specs = data.episode_specs()
    by_episode: dict[str, list[WindowRow]] = {}
    for row in data.rows("test"):
        by_episode.setdefault(row.episode, []).append(row)
    got = _Collected()
    for episode_id, rows in tqdm(by_episode.items(), desc="audit: test episodes", disable=not progress):
        episode = read_episode(data.path / episode_id)
        starts = np.array([r.start_s for r in rows])
        got.rows += rows
        for name, values in signals.audio_levels(episode.audio, episode.audio_rate, starts).items():
            got.add(name, values)
        if has_imu:
            got.add("acc_peak", signals.acceleration_peak(episode.imu6[:, :3], IMU_RATE, starts))
        if simulated:
            for name, values in _kinematics(data.path / episode_id, starts).items():
                got.add(name, values)
            hx, hy = episode.scenario["arena"]
            got.area += [4.0 * hx * hy] * len(rows)
        audio4410 = preprocess.decimate_audio(episode.audio)
        w = preprocess.frame_windows(audio4410, episode.imu_vel_z, starts, imu6=episode.imu6)
        assert w.imu6 is not None
        got.audio.append(w.audio)
        got.imu.append(w.imu)
        got.imu6.append(w.imu6)
        category = specs[episode_id].category
        if category != "nominal":
            ctx = context_starts(episode.label)
            if ctx.size:
                got.context.append(
                    preprocess.frame_windows(audio4410, episode.imu_vel_z, ctx, imu6=episode.imu6)
                )
                got.context_episode += [episode_id] * ctx.size
                got.context_category += [category] * ctx.size
    return got


def _deleted_windows(
    data: Dataset, rows: list[WindowRow], progress: bool
) -> tuple[Windows, list[WindowRow], list[tuple[str, float, float]]]:
    """Anomalous test windows cut from audio rendered again without the anomaly's own sound, and per fault
    episode (sub-kind, severity, level of its fault sound in the mix: `_fault_level`)."""
    specs = data.episode_specs()
    by_episode: dict[str, list[WindowRow]] = {}
    for row in rows:
        if row.kind != "normal":
            by_episode.setdefault(row.episode, []).append(row)
    parts: list[Windows] = []
    kept: list[WindowRow] = []
    levels: list[tuple[str, float, float]] = []
    for episode_id, ep_rows in tqdm(by_episode.items(), desc="audit: re-render muted", disable=not progress):
        spec = specs[episode_id]
        trace = read_trace(data.path / episode_id)
        audio = synth_audio.render(trace, episode_audio_config(spec, MUTED_ANOMALY_SOURCES), seed=spec.seed)
        faulty = [r.sub_kind for r in ep_rows if r.kind == "mechanical"]
        if faulty and trace.faults:
            level = _fault_level(data.path / episode_id, trace, audio)
            levels.append((faulty[0], trace.faults[0].severity, level))
        starts = np.array([r.start_s for r in ep_rows])
        parts.append(
            preprocess.frame_windows(
                preprocess.decimate_audio(audio.samples),
                trace.imu_vel_z,
                starts,
                imu6=np.concatenate([trace.imu_acc, trace.imu_gyro], axis=1),
            )
        )
        kept += ep_rows
    return _concat(parts), kept, levels


def fault_span(trace: Trace, rate: int) -> tuple[int, tuple[float, float]] | None:
    """(first audio sample at `rate` after the trace's fault onset, the fault's characteristic band in Hz
    (`synth_audio.faults.fault_band` at the faulty wheel's mean rotation rate after onset)); None when the
    fault starts after the trace ends."""
    fault = trace.faults[0]
    after = trace.time >= fault.onset
    if not after.any():
        return None
    rotation_hz = float(np.abs(trace.wheel_speed[after, fault.wheel]).mean()) / (2 * np.pi)
    return round(fault.onset * rate), fault_band(fault, rotation_hz, rate)


def _fault_level(folder: Path, trace: Trace, muted: synth_audio.Audio) -> float:
    """The fault's sound in the stored mix over the rest of the mix, dB: the stored audio less its re-render
    without the anomaly's sound, against that re-render, in the fault's band after onset (`fault_span`)."""
    span = fault_span(trace, muted.sample_rate)
    if span is None:
        return math.nan
    start, band = span
    mix = synth_audio.read(audio_file(folder)).samples[start:].astype(np.float64)
    rest = muted.samples[start:].astype(np.float64)
    return signals.level_db(mix - rest, rest, muted.sample_rate, band)


def _concat(parts: list[Windows]) -> Windows:
    imu6 = [p.imu6 for p in parts]
    return Windows(
        audio=np.concatenate([p.audio for p in parts]),
        imu=np.concatenate([p.imu for p in parts]),
        imu6=None if any(x is None for x in imu6) else np.concatenate(imu6),  # type: ignore[arg-type]
    )


def _ambience_repetition(data: Dataset, episodes: list[str]) -> list[tuple[str, float]]:
    specs = data.episode_specs()
    out = []
    for episode_id in episodes:
        spec = specs[episode_id]
        trace = read_trace(data.path / episode_id)
        config = episode_audio_config(spec)
        audio = synth_audio.render(
            trace, synth_audio.AudioConfig(**{**config.__dict__, "stems": True}), seed=spec.seed
        )
        bed = audio.stems["ambience"]
        if bed.shape[0] > 4 * audio.sample_rate:  # lags of 1 s up to half the signal
            out.append((episode_id, signals.repetition(bed, audio.sample_rate)))
    return out


def _auc(scores: np.ndarray, normal: np.ndarray, positive: np.ndarray) -> float:
    keep = normal | positive
    if not normal.any() or not positive.any():
        return math.nan
    return roc_auc(positive[keep].astype(int), scores[keep])


def _two_sided(a: float) -> float:
    return max(a, 1.0 - a) if math.isfinite(a) else math.nan


def _targets(kinds: np.ndarray, subs: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """(name, mask) of overall, each kind and each sub-kind present among anomalous windows."""
    anomalous = kinds != "normal"
    out = [("overall", anomalous)]
    out += [(k, kinds == k) for k in ("collision", "mechanical") if np.any(kinds == k)]
    out += [(f"sub:{s}", anomalous & (subs == s)) for s in sorted(set(subs[anomalous]))]
    return out


@dataclass(frozen=True)
class _Labels:
    """The labels of the collected test windows, one entry per window, and the targets they define."""

    kinds: np.ndarray
    subs: np.ndarray
    episodes: np.ndarray
    normal: np.ndarray
    targets: list[tuple[str, np.ndarray]]


def _labels(data: Dataset, got: _Collected) -> _Labels:
    """The windows' labels; a test split without both nominal and anomalous windows is an error."""
    kinds = np.array([r.kind for r in got.rows])
    subs = np.array([r.sub_kind for r in got.rows])
    episodes = np.array([r.episode for r in got.rows])
    normal = kinds == "normal"
    if not normal.any() or normal.all():
        raise DatasetError(f"{data.path}: the test split needs nominal and anomalous windows to audit")
    return _Labels(kinds, subs, episodes, normal, _targets(kinds, subs))


@dataclass(frozen=True)
class _References:
    """The reference detectors, fitted on the nominal training windows, and their test scores."""

    name: str
    """`early`, or `audio` without an IMU."""
    early: GaussianReference
    audio_only: GaussianReference
    s_early: np.ndarray
    s_audio: np.ndarray


def run_audit(dataset: Path, *, progress: bool = True) -> AuditResult:
    """Every probe on a dataset's test windows (the dataset is verified first). The audit re-simulates and
    re-renders episodes as `generate` does, and keeps the memory they free as it does
    (`allocator.keep_freed_memory`)."""
    started = time.perf_counter()
    keep_freed_memory()
    data = open_dataset(Path(dataset))
    simulated = data.source != IMPORTED
    has_imu = "imu" in data.modalities
    got = _collect(data, progress, simulated, has_imu)
    labels = _labels(data, got)
    rows = _behaviour_rows(got, labels) if simulated else _trace_skip_rows()
    rows += _naive_rows(got, labels, has_imu)
    rows += _clipping_rows(got, labels)
    if simulated:
        rows.append(_context_row(got, labels))
    refs = _fit_references(data, got, has_imu)
    rows += _reference_rows(refs, labels)
    rows += _leak_rows(got, refs, labels)
    if simulated:
        rows += _simulator_probes(data, got, refs.s_audio, refs.audio_only, progress)
        rows += oracle.oracle_rows(oracle.score_faults(data, progress=progress))
    preset = data.preset_name
    seconds = time.perf_counter() - started
    return AuditResult(str(data.path), preset, data.seed, tuple(rows), seconds, audit_key(data))


AUDIT_CODE: tuple[str, ...] = ("benchmarks", "msvdd", "sim", "synth_audio", "assets")
"""Packages whose source is part of an audit's key: all of the project's code, so any edit reruns it."""


def audit_key(data: Dataset) -> str:
    """sha256 over what decides an audit's figures: the dataset's fingerprint, the package versions and the
    source of the project's code (`AUDIT_CODE`)."""
    recipe = {
        "dataset": data.fingerprint,
        "software": software_versions(),
        "code": source_digest(AUDIT_CODE, ()),
    }
    return hashlib.sha256(json.dumps(recipe, sort_keys=True).encode()).hexdigest()


def stored_audit(dataset: Path, out: Path) -> AuditResult | None:
    """The audit of `dataset` stored in `out` if its key is this dataset's and this software's (the dataset
    is verified first, as `run_audit` does); None if there is none, it is unreadable or its key differs."""
    stored = read(out)
    if stored is None or stored.key != audit_key(open_dataset(Path(dataset))):
        return None
    return stored


def _scalar_rows(
    got: _Collected, labels: _Labels, group: str, name: str, limit_for: Callable[[str], float | None]
) -> list[ProbeRow]:
    """One scalar judged two-sided on every target, against the nominal test windows."""
    values = np.asarray(got.scalars[name])
    normal = labels.normal
    rows = []
    for target, mask in labels.targets:
        raw = _auc(values, normal, mask)
        rows.append(
            ProbeRow(
                group,
                name,
                target,
                _two_sided(raw),
                limit_for(target),
                "auc2",
                f"AUC {raw:.3f}; {int(mask.sum())} vs {int(normal.sum())} windows",
            )
        )
    return rows


def _no_limit(target: str) -> float | None:
    return None


def _behaviour_limit(target: str) -> float | None:
    """Behaviour: limits on collisions only."""
    return BEHAVIOUR_LIMIT if target == "collision" else None


def _naive_limit(target: str) -> float | None:
    if target == "overall":
        return NAIVE_OVERALL_LIMIT
    return NAIVE_SUB_KIND_LIMIT if target.startswith("sub:") else None


def _skip_row(group: str, probe: str, reason: str) -> ProbeRow:
    return ProbeRow(group, probe, "-", math.nan, None, "-", skipped=reason)


def _trace_skip_rows() -> list[ProbeRow]:
    """The probes that need the simulator, skipped on an imported dataset."""
    return [
        _skip_row(group, "every probe", f"{NO_TRACE}; this probe {needs}") for group, needs in TRACE_PROBES
    ]


def _behaviour_rows(got: _Collected, labels: _Labels) -> list[ProbeRow]:
    rows: list[ProbeRow] = []
    for name in BEHAVIOUR_PROBES:
        rows += _scalar_rows(got, labels, "behaviour", name, _behaviour_limit)
    rows += _scalar_rows(got, labels, "behaviour", "standing", _no_limit)
    rows += _scalar_rows(got, labels, "behaviour", "peak_deceleration", _no_limit)
    return rows


def _naive_rows(got: _Collected, labels: _Labels, has_imu: bool) -> list[ProbeRow]:
    rows: list[ProbeRow] = []
    for name in NAIVE_AUDIO:
        rows += _scalar_rows(got, labels, "naive", name, _naive_limit)
    if has_imu:
        rows += _scalar_rows(got, labels, "naive", "acc_peak", _no_limit)
    else:
        rows.append(_skip_row("naive", "acc_peak", "the dataset has no IMU modality"))
    return rows


def _clipping_row(clip: np.ndarray, mask: np.ndarray, target: str, limit: float | None) -> ProbeRow:
    return ProbeRow(
        "clipping",
        "peak >= -1 dBFS",
        target,
        float(clip[mask].mean()),
        limit,
        "share",
        f"{int(clip[mask].sum())} of {int(mask.sum())} windows",
    )


def _clipping_rows(got: _Collected, labels: _Labels) -> list[ProbeRow]:
    """Share of clipped windows per kind (with a limit) and per anomalous sub-kind (reported)."""
    clip = signals.clipped(np.asarray(got.scalars["peak"]))
    rows = []
    for label in ("normal", "collision", "mechanical"):
        mask = labels.kinds == label
        if mask.any():
            rows.append(_clipping_row(clip, mask, label, CLIPPING_LIMIT))
    for sub in sorted(set(labels.subs[~labels.normal])):
        rows.append(_clipping_row(clip, labels.subs == sub, f"sub:{sub}", None))
    return rows


def _context_row(got: _Collected, labels: _Labels) -> ProbeRow:
    """Context: the arena's area as a score."""
    area = np.asarray(got.area)
    normal = labels.normal
    raw = _auc(area, normal, ~normal)
    return ProbeRow(
        "context",
        "arena area",
        "overall",
        _two_sided(raw),
        CONTEXT_LIMIT,
        "auc2",
        f"AUC {raw:.3f}; median m2 normal {np.median(area[normal]):.0f}, "
        f"anomalous {np.median(area[~normal]):.0f}",
    )


def _fit_references(data: Dataset, got: _Collected, has_imu: bool) -> _References:
    """Reference detectors, fitted on the nominal training windows (audio only without an IMU)."""
    train, _ = data.load_windows("train")
    test = got.windows()
    reference = "early" if has_imu else "audio"
    early = GaussianReference(reference).fit(train)
    if reference == "audio":  # without an IMU the reference is the audio-only model itself
        s_early = early.score(test)
        return _References(reference, early, early, s_early, s_early)
    audio_only = GaussianReference("audio").fit(train)
    del train
    return _References(reference, early, audio_only, early.score(test), audio_only.score(test))


def _reference_rows(refs: _References, labels: _Labels) -> list[ProbeRow]:
    """The reference detector's AUC with its interval and spread, per target; the audio-only one beside."""
    normal, episodes, reference = labels.normal, labels.episodes, refs.name
    interval = auc_interval(refs.s_early, ~normal, episodes)
    spread = auc_per_normal_episode(refs.s_early, ~normal, episodes)
    rows = [
        ProbeRow(
            "reference",
            f"gaussian-{reference} CI half-width",
            "overall",
            interval.half_width,
            REFERENCE_HALF_WIDTH_LIMIT,
            "half-width",
            f"AUC {interval.value:.3f} [{interval.low:.3f}, {interval.high:.3f}]; "
            f"over {len(spread)} normal sequences {min(spread.values()):.3f}..{max(spread.values()):.3f}",
        )
    ]
    for target, mask in labels.targets:
        keep = normal | mask
        ci = auc_interval(refs.s_early[keep], mask[keep], episodes[keep])
        rows.append(
            ProbeRow(
                "reference",
                f"gaussian-{reference}",
                target,
                ci.value,
                None,
                "auc",
                f"[{ci.low:.3f}, {ci.high:.3f}]",
            )
        )
    audio_targets = labels.targets[:3] if reference != "audio" else ()  # audio-only: the reference itself
    for target, mask in audio_targets:
        rows.append(
            ProbeRow(
                "reference",
                "gaussian-audio",
                target,
                _auc(refs.s_audio, normal, mask),
                None,
                "auc",
                "audio-only reference with the anomaly's sound",
            )
        )
    return rows


def _leak_rows(got: _Collected, refs: _References, labels: _Labels) -> list[ProbeRow]:
    """Leak: normal stretches of anomaly episodes against nominal test windows."""
    if not got.context:
        return []
    normal = labels.normal
    s_ctx = refs.early.score(_concat(got.context))
    cat = np.array(got.context_category)
    rows = []
    for category, target in (("collision", "collision episodes"), ("fault", "fault episodes")):
        mask = cat == category
        if mask.any():
            scores = np.r_[refs.s_early[normal], s_ctx[mask]]
            raw = roc_auc(np.r_[np.zeros(int(normal.sum())), np.ones(int(mask.sum()))].astype(int), scores)
            rows.append(
                ProbeRow(
                    "leak",
                    f"gaussian-{refs.name}",
                    target,
                    raw,
                    LEAK_LIMIT,
                    "auc",
                    f"{int(mask.sum())} context windows vs {int(normal.sum())} nominal",
                )
            )
    return rows


def _fault_level_rows(levels: list[tuple[str, float, float]]) -> list[ProbeRow]:
    """Level: how loud the fault episodes' own sound is in their mix (median over episodes, dB; reported),
    overall, per sub-kind and per sub-kind and severity bin."""
    rows = []
    kinds = sorted({k for k, _, _ in levels})
    bins = [oracle.severity_bin(lo) for lo, _ in oracle.SEVERITY_BINS]
    groups = [("mechanical", [v for _, _, v in levels])]
    groups += [(f"sub:{k}", [v for s, _, v in levels if s == k]) for k in kinds]
    groups += [
        (f"sub:{k} severity {b}", [v for s, sev, v in levels if s == k and oracle.severity_bin(sev) == b])
        for k in kinds
        for b in bins
    ]
    for target, values in groups:
        finite = np.array([v for v in values if math.isfinite(v)])
        if finite.size:
            rows.append(
                ProbeRow(
                    "level",
                    FAULT_LEVEL_PROBE,
                    target,
                    float(np.median(finite)),
                    None,
                    "dB",
                    f"median of {finite.size} episodes; range {finite.min():+.1f} to {finite.max():+.1f} dB",
                )
            )
    return rows


def _simulator_probes(
    data: Dataset, got: _Collected, s_audio: np.ndarray, audio_only: GaussianReference, progress: bool
) -> list[ProbeRow]:
    """The deleted-sound and ambience probes: they render audio again from the stored simulator traces."""
    rows: list[ProbeRow] = []
    kinds = np.array([r.kind for r in got.rows])
    normal = kinds == "normal"
    # Deleted sound: re-render the anomaly episodes without it.
    muted, muted_rows, levels = _deleted_windows(data, got.rows, progress)
    s_muted = audio_only.score(muted)
    muted_kinds = np.array([r.kind for r in muted_rows])
    for label in ("collision", "mechanical"):
        mask = muted_kinds == label
        if mask.any():
            scores = np.r_[s_audio[normal], s_muted[mask]]
            raw = roc_auc(np.r_[np.zeros(int(normal.sum())), np.ones(int(mask.sum()))].astype(int), scores)
            with_sound = _auc(s_audio, normal, kinds == label)
            rows.append(
                ProbeRow(
                    "deleted",
                    "gaussian-audio, sound muted",
                    label,
                    raw,
                    DELETED_LIMIT,
                    "auc",
                    f"with the sound {with_sound:.3f}; muted: {', '.join(MUTED_ANOMALY_SOURCES)}",
                )
            )
    for sub in sorted({r.sub_kind for r in muted_rows}):
        mask = np.array([r.sub_kind == sub for r in muted_rows])
        scores = np.r_[s_audio[normal], s_muted[mask]]
        raw = roc_auc(np.r_[np.zeros(int(normal.sum())), np.ones(int(mask.sum()))].astype(int), scores)
        rows.append(ProbeRow("deleted", "gaussian-audio, sound muted", f"sub:{sub}", raw, None, "auc", ""))
    rows += _fault_level_rows(levels)

    # Ambience beds.
    nominal_eps = sorted({r.episode for r in got.rows if r.kind == "normal"})[:AMBIENCE_EPISODES]
    for episode_id, value in _ambience_repetition(data, nominal_eps):
        rows.append(
            ProbeRow("ambience", "autocorrelation beyond 1 s", episode_id, value, REPETITION_LIMIT, "acf")
        )
    return rows
