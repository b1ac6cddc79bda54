"""The audit's privileged fault oracle: is each wheel fault physically in the sensors?

A detector that fails on faults may be weak, or the faults may not be there. The oracle answers the second
question with what condition monitoring computes, given information no detector has: the simulator's true
angle of every wheel, which wheel is faulty, the angle at which its defect meets the floor and the defect's
order (`sim.trace.FaultRecord`: `phase`, `defect_order`). On each 2 s window of the benchmark (the
detectors' 4410 Hz audio and the 200 Hz IMU, `benchmarks.condition`) it reads each fault kind's own
signature (`benchmarks.fault_indicators.INDICATORS`, shared with the fault-aware reference detector), not
its loudness (the naive probes read that).

A fault window is looked at through its faulty wheel at its defect's angle and order; a nominal window
through every wheel at `NOMINAL_PHASES` angles (`nominal_views`), where that wheel turned as far as a
fault window's must (`benchmarks.dataset.MIN_FAULT_REVOLUTIONS`): a defect is compared with healthy wheels
that rolled as far, not with a robot standing still (whose quiet would tell a moving robot, not a defect),
at the orders of the episode's own robot unit (units differ in gear ratio, so in their gear-mesh order).
Each indicator is compared with its distribution over nominal training windows (looked at the same way); a
window's score is the summed rarity of its kind's indicators (`fault_indicators.Rarity`). Reported per fault
kind and severity bin (`SEVERITY_BINS`) as an AUC against the nominal test windows, with its episode-cluster
bootstrap interval; at severity >= 0.75 each kind must reach `ORACLE_FLOOR`, and its fault windows must
stand out further than at severity < 0.5 in the indicators of the defect's size (`GRADIENT_PROBE`).

The control keeps it honest: every fault episode simulated and rendered again with its fault at severity
0 (same seed, same driving, same defect angle), scored on the same windows through the same view, must be
at chance (two-sided AUC at most `CONTROL_LIMIT`): the oracle finds the fault, not the episode.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

import sim
import synth_audio
from benchmarks import condition, fault_indicators
from benchmarks.audit.report import ProbeRow
from benchmarks.dataset import MIN_FAULT_REVOLUTIONS, Dataset, WindowRow, episode_audio_config
from benchmarks.episode import read_episode, read_trace
from benchmarks.fault_indicators import INDICATORS, Rarity, WheelSite
from benchmarks.uncertainty import Interval, auc_interval
from msvdd import preprocess
from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE
from sim.faults import BEARING_SLIP, defect_order
from sim.random_scenarios import scale_speeds
from sim.trace import FaultRecord, RobotInfo, Trace

ORACLE_FLOOR = 0.90
"""Least AUC the oracle must reach on each fault kind at severity >= 0.75."""
CONTROL_LIMIT = 0.65
"""Most the oracle may separate the fault episodes re-simulated at severity 0 (two-sided AUC)."""
SEVERITY_BINS: tuple[tuple[float, float], ...] = ((0.0, 0.5), (0.5, 0.75), (0.75, 1.0))
"""Severity bins the oracle and the level probe are reported in (low included; the last includes 1)."""
TRAIN_WINDOWS = 1500
"""Most nominal training windows the oracle's baseline is fitted on (evenly over the episodes)."""
NOMINAL_PHASES = 4
"""Defect angles (evenly spaced) a nominal window is looked at with, for each wheel."""
PASS_POOLING = "mean"
"""How the oracle pools a strike's passes (`fault_indicators.PASS_POOLINGS`): their mean log ratio, how far
each strike stands out, so that the severity gradient (`GRADIENT_PROBE`) compares defects, not how many
passes their windows held (which the driving speed sets)."""


def severity_bin(severity: float) -> str:
    """The label of the `SEVERITY_BINS` bin holding `severity`, e.g. `0.75-1`."""
    for lo, hi in SEVERITY_BINS:
        if lo <= severity < hi or (hi == SEVERITY_BINS[-1][1] and severity == hi):
            return f"{lo:g}-{hi:g}"
    raise ValueError(f"severity = {severity!r} is invalid; allowed: 0 .. 1")


@dataclass(frozen=True)
class Signals:
    """One episode's detector-rate signals and the simulator's true wheel angles."""

    audio: np.ndarray
    """(n, 2) audio at 4410 Hz."""
    imu7: np.ndarray
    """(m, 7) z-velocity, accelerometer xyz, gyroscope xyz at 200 Hz."""
    angle: np.ndarray
    """(m, W) true wheel angles at the IMU samples, rad."""


def trace_signals(trace: Trace, audio44k: np.ndarray) -> Signals:
    """The detector-rate signals of a trace and its rendered (n, 2) audio."""
    angle = np.stack(
        [np.interp(trace.imu_time, trace.time, trace.wheel_angle[:, w]) for w in range(trace.n_wheels)],
        axis=1,
    )
    imu7 = np.concatenate([trace.imu_vel_z[:, None], trace.imu_acc, trace.imu_gyro], axis=1)
    return Signals(preprocess.decimate_audio(audio44k), imu7, angle)


def _cut(x: np.ndarray, starts: np.ndarray, rate: float, length: int) -> np.ndarray:
    i0 = np.rint(starts * rate).astype(np.int64)
    return np.asarray(x[i0[:, None] + np.arange(length)])


def _turned(sig: Signals, starts: np.ndarray) -> np.ndarray:
    """(k, W) revolutions each wheel turned (either way) in the windows at `starts` (s)."""
    angle = _cut(sig.angle, np.asarray(starts, dtype=np.float64), IMU_RATE, IMU_LEN)  # (k, 400, W)
    return condition.revolutions(angle, axis=1)


@dataclass(frozen=True)
class View:
    """Through which wheel, at which defect angle and order a window is looked at."""

    kind: str
    """Fault kind (which features)."""
    wheel: int
    """The wheel whose angle is tracked."""
    phase: float
    """Wheel angle at which the defect meets the floor (`sim.trace.FaultRecord.phase`), rad."""
    order: float
    """Defect events per revolution (`sim.trace.FaultRecord.defect_order`)."""
    shaft: float
    """Motor shaft revolutions per wheel revolution (worn gears' sidebands and speed ripple)."""
    site: WheelSite
    """Where the wheel sits on the robot (`fault_indicators.wheel_sites`)."""


def fault_view(record: FaultRecord, robot: RobotInfo) -> View:
    """How the oracle looks at a window of a fault episode: through its defect."""
    site = _sites(robot)[record.wheel]
    return View(record.kind, record.wheel, record.phase, record.defect_order, float(robot.gear_ratio), site)


def _sites(robot: RobotInfo) -> list[WheelSite]:
    return fault_indicators.wheel_sites(robot.wheel_pos_body, robot.mic_pos_body)


def nominal_views(kind: str, robot: RobotInfo) -> list[View]:
    """How the oracle looks at a nominal window of a `robot` unit for `kind`: every wheel, `NOMINAL_PHASES`
    defect angles (one for worn gears, whose features do not depend on it), the kind's order on that unit (a
    bearing's at the middle of its slip range; the gear mesh's at the unit's gear ratio)."""
    order = defect_order(kind, robot) * (1.0 - 0.5 * sum(BEARING_SLIP) if kind == "bearing" else 1.0)
    count = 1 if kind == "motor_degradation" else NOMINAL_PHASES
    phases = 2 * np.pi * np.arange(count) / count
    shaft = float(robot.gear_ratio)
    sites = _sites(robot)
    return [
        View(kind, w, float(p), order, shaft, sites[w]) for w in range(len(robot.wheel_names)) for p in phases
    ]


def window_features(sig: Signals, starts: np.ndarray, views: list[View]) -> list[np.ndarray]:
    """(k, F) oracle features of the windows at `starts` (s), looked at through each of `views` (all of one
    fault kind; `fault_indicators.indicators`)."""
    starts = np.asarray(starts, dtype=np.float64)
    audio = _cut(sig.audio, starts, AUDIO_RATE, AUDIO_LEN)  # (k, 8820, 2)
    channels = _cut(sig.imu7, starts, IMU_RATE, IMU_LEN).transpose(0, 2, 1)  # (k, 7, 400)
    prep = fault_indicators.prepare(views[0].kind, audio, channels)
    angles = {w: _cut(sig.angle[:, w], starts, IMU_RATE, IMU_LEN) for w in sorted({v.wheel for v in views})}
    return [
        fault_indicators.indicators(
            prep, angles[v.wheel], np.array([v.phase]), v.order, v.site, pooling=PASS_POOLING
        )[:, 0]
        for v in views
    ]


@dataclass(frozen=True)
class Scored:
    """The oracle's scores of one fault kind: fault windows through their defect, nominal ones through
    every `nominal_views` view."""

    kind: str
    """Fault kind."""
    positive: np.ndarray
    """(p,) scores of the kind's fault windows."""
    positive_episode: np.ndarray
    """(p,) their episodes."""
    positive_severity: np.ndarray
    """(p,) their episodes' severities."""
    negative: np.ndarray
    """(q,) scores of the nominal test windows, every view in turn."""
    negative_episode: np.ndarray
    """(q,) their episodes."""
    control: np.ndarray | None = None
    """(p,) scores of the same windows re-simulated with the fault at severity 0 (None: not run)."""
    positive_size: np.ndarray | None = None
    """(p,) the fault windows' evidence from the kind's indicators of the defect's size alone
    (`fault_indicators.size_columns`; None: all of them measure it, the same as `positive`)."""


def _train_rows(data: Dataset) -> list[WindowRow]:
    rows = data.rows("train")
    if len(rows) <= TRAIN_WINDOWS:
        return rows
    pick = np.linspace(0, len(rows) - 1, TRAIN_WINDOWS).round().astype(np.int64)
    return [rows[i] for i in pick]


def _by_episode(rows: list[WindowRow]) -> dict[str, np.ndarray]:
    out: dict[str, list[float]] = {}
    for r in rows:
        out.setdefault(r.episode, []).append(r.start_s)
    return {e: np.array(s) for e, s in out.items()}


def control_trace(data: Dataset, episode_id: str) -> tuple[Trace, synth_audio.Audio]:
    """A fault episode simulated and rendered again with its faults at severity 0 (the same seed, driving
    and defect records)."""
    spec = data.episode_specs()[episode_id]
    scenario = sim.draw_scenario(spec.seed, spec.category, spec.options)
    scenario = scale_speeds(scenario, spec.drive_speed_scale, spec.approach_speed_scale)
    scenario = scenario.replace(faults=tuple(dataclasses.replace(f, severity=0.0) for f in scenario.faults))
    trace = sim.simulate(scenario).at_storage_precision()
    return trace, synth_audio.render(trace, episode_audio_config(spec), seed=spec.seed)


def score_faults(
    data: Dataset, control: bool = True, progress: bool = False, kinds: tuple[str, ...] | None = None
) -> list[Scored]:
    """The oracle's scores of every fault kind (or of `kinds`) of a simulated dataset's test split."""
    from tqdm import tqdm

    test = data.rows("test")
    faults = [r for r in test if r.kind == "mechanical" and (kinds is None or r.sub_kind in kinds)]
    if not faults:
        return []
    found = sorted({r.sub_kind for r in faults})

    def nominal(episodes: dict[str, np.ndarray], what: str) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        feats: dict[str, list[np.ndarray]] = {k: [] for k in found}
        names: dict[str, list[str]] = {k: [] for k in found}
        for episode_id, starts in tqdm(episodes.items(), desc=what, disable=not progress):
            trace = read_trace(data.path / episode_id)
            sig = trace_signals(trace, read_episode(data.path / episode_id).audio)
            turned = _turned(sig, starts)
            for k in found:
                views = nominal_views(k, trace.robot)  # the unit's own gear ratio sets the orders
                for v, x in zip(views, window_features(sig, starts, views), strict=True):
                    keep = turned[:, v.wheel] >= MIN_FAULT_REVOLUTIONS
                    feats[k].append(x[keep])
                    names[k] += [episode_id] * int(keep.sum())
        return {k: (np.concatenate(feats[k]), np.array(names[k])) for k in found}

    train = nominal(_by_episode(_train_rows(data)), "oracle: train")
    fitted = {k: Rarity.fit(x) for k, (x, _) in train.items()}
    normal = nominal(_by_episode([r for r in test if r.kind == "normal"]), "oracle: nominal test")
    severities = data.fault_severities()
    out = []
    for k in found:
        pos, ctl, eps, sev, size = [], [], [], [], []
        columns = fault_indicators.size_columns(k)
        sized = fitted[k].only(columns) if len(columns) < len(INDICATORS[k]) else None
        for episode_id, starts in tqdm(_by_episode([r for r in faults if r.sub_kind == k]).items(),
                                       desc=f"oracle: {k}", disable=not progress):  # fmt: skip
            trace = read_trace(data.path / episode_id)
            view = fault_view(trace.faults[0], trace.robot)
            sig = trace_signals(trace, read_episode(data.path / episode_id).audio)
            x = window_features(sig, starts, [view])[0]
            pos.append(fitted[k].score(x))
            if sized is not None:
                size.append(sized.score(x[:, columns]))
            if control:
                trace0, audio0 = control_trace(data, episode_id)
                sig0 = trace_signals(trace0, audio0.samples)
                ctl.append(fitted[k].score(window_features(sig0, starts, [view])[0]))
            eps += [episode_id] * len(starts)
            sev += [severities.get(episode_id, math.nan)] * len(starts)
        x_neg, neg_eps = normal[k]
        out.append(
            Scored(
                kind=k,
                positive=np.concatenate(pos),
                positive_episode=np.array(eps),
                positive_severity=np.array(sev),
                negative=fitted[k].score(x_neg),
                negative_episode=neg_eps,
                control=np.concatenate(ctl) if control else None,
                positive_size=None if sized is None else np.concatenate(size),
            )
        )
    return out


ORACLE_PROBE = "privileged oracle (true wheel angle, defect angle and order)"
"""The oracle probe's name in the audit table."""
CONTROL_PROBE = "oracle on the same episodes re-simulated at severity 0"
"""The control probe's name."""
GRADIENT_PROBE = "oracle size evidence at severity >= 0.75 over < 0.5"
"""The severity gradient probe's name: a more severe defect must stand out further (the median evidence of
the top bin's fault windows over the bottom bin's; an AUC near 1 in both bins no longer tells them apart),
read in the indicators that measure its size (`Scored.positive_size`): an indicator relative to its
channels' deviation stops growing once the defect dominates them (`fault_indicators.SCALE_FREE`), and its
spread over the driving then decides the comparison."""


def oracle_rows(scored: list[Scored]) -> list[ProbeRow]:
    """The audit's `oracle` rows: per fault kind its AUC overall and per severity bin (the top bin with the
    floor `ORACLE_FLOOR`), the severity gradient (`GRADIENT_PROBE`: the top bin's median size evidence over
    the bottom one's, at least 0) and the control (two-sided, at most `CONTROL_LIMIT`)."""
    rows: list[ProbeRow] = []
    for s in scored:
        bins = np.array([severity_bin(v) for v in s.positive_severity])
        top, bottom = severity_bin(1.0), severity_bin(0.0)
        aucs: dict[str, float] = {}
        for name in ["all", *sorted(set(bins))]:
            mask = np.ones(bins.size, dtype=bool) if name == "all" else bins == name
            ci = _interval(s.positive[mask], s.negative, s.positive_episode[mask], s.negative_episode)
            aucs[name] = ci.value
            target = f"sub:{s.kind}" + ("" if name == "all" else f" severity {name}")
            rows.append(
                ProbeRow(
                    "oracle", ORACLE_PROBE, target, ci.value, None, "auc",
                    f"[{ci.low:.3f}, {ci.high:.3f}]; {int(mask.sum())} windows of "
                    f"{len(set(s.positive_episode[mask]))} episodes",
                    floor=ORACLE_FLOOR if name == top else None,
                )
            )  # fmt: skip
        if top in aucs and bottom in aucs:
            size = s.positive if s.positive_size is None else s.positive_size
            high, low = (float(np.median(size[bins == b])) for b in (top, bottom))
            rows.append(
                ProbeRow(
                    "oracle", GRADIENT_PROBE, f"sub:{s.kind}", high - low, None, "evidence",
                    f"median {high:.2f} - {low:.2f}; AUC {aucs[top]:.3f} - {aucs[bottom]:.3f}", floor=0.0,
                )
            )  # fmt: skip
        if s.control is not None:
            ci = _interval(s.control, s.negative, s.positive_episode, s.negative_episode)
            rows.append(
                ProbeRow(
                    "oracle", CONTROL_PROBE, f"sub:{s.kind}", max(ci.value, 1.0 - ci.value), CONTROL_LIMIT,
                    "auc2", f"AUC {ci.value:.3f} [{ci.low:.3f}, {ci.high:.3f}]",
                )
            )  # fmt: skip
    return rows


def kind_interval(scored: Scored) -> Interval:
    """The oracle's AUC on a fault kind (every severity) with its episode-cluster bootstrap interval."""
    return _interval(scored.positive, scored.negative, scored.positive_episode, scored.negative_episode)


def _interval(positive: np.ndarray, negative: np.ndarray, pos_ep: np.ndarray, neg_ep: np.ndarray) -> Interval:
    """AUC of `positive` over `negative` scores with its episode-cluster bootstrap interval."""
    scores = np.r_[positive, negative]
    labels = np.r_[np.ones(positive.size, dtype=bool), np.zeros(negative.size, dtype=bool)]
    return auc_interval(scores, labels, np.r_[pos_ep, neg_ep])
