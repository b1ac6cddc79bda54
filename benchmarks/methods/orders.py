"""The fault-aware reference detector: condition monitoring on the wheel encoders, without privileged
information.

What a vibration analyst who knows the robot's drive train computes on every 2 s window, tracking each
wheel's angle from its encoder (the odometry modality, `Windows.odometry`). It reads each fault kind's own
signature (`benchmarks.fault_indicators.INDICATORS`: the same indicators as the audit's oracle), but does not
know which wheel is faulty, at which angle its defect meets the floor, nor which fault to look for. So it
tests every hypothesis in turn and reports the most significant:

- a hypothesis is a fault kind on a wheel with its defect at one of `PHASES` evenly spaced angles (a strike's
  indicators depend on the defect's angle; the others on the wheel only, the vibration on neither);
- the orders are the drive train's (`sim.faults.bpfo_order` with the middle of the balls' slip range; the
  gear-mesh order pinion teeth x gear ratio): a robot team knows its own robot model, not each unit's
  tolerance, so worn gears' mesh line is searched over `MESH_SPAN` around the nominal order;
- a hypothesis' evidence is the summed rarity of its indicators under their nominal distribution
  (`fault_indicators.Rarity`, upper tails: a defect adds to its signature), the kind's evidence the largest
  over its wheels and angles;
- the score is the largest over the kinds of that evidence's own rarity over nominal windows (each kind's
  evidence is calibrated, so a kind with many hypotheses does not dominate).

Every distribution is fitted on the nominal training windows; nothing is tuned. A window without odometry is
refused.
"""

from __future__ import annotations

from typing import Any, Self

import numpy as np

from benchmarks import fault_indicators
from benchmarks.fault_indicators import INDICATORS, PHASED, Rarity
from benchmarks.methods.base import WindowDetector
from msvdd.contract import AUDIO_RATE, WindowError, Windows
from sim.faults import BEARING_SLIP, bpfo_order
from sim.robot import DRIVE_TRAINS

PHASES = 8
"""Defect angles (evenly spaced over one defect period) each strike hypothesis is tested at."""
MESH_SPAN = 0.025
"""Relative span around the drive train's gear-mesh order over which the mesh line is searched (units'
gear ratios vary by up to 2 %)."""
MESH_STEP = 0.25
"""Step of the gear-mesh order search, orders (half the resolution of a 2 s window at two revolutions)."""
_CHUNK = 64


def mesh_orders(model: str) -> tuple[float, int]:
    """The first gear-mesh order searched for a robot model and how many, `MESH_STEP` apart (`MESH_SPAN`
    around pinion teeth x gear ratio)."""
    drive = DRIVE_TRAINS[model]
    mesh = float(drive.pinion_teeth * drive.gear_ratio)
    lo, hi = np.floor(mesh * (1.0 - MESH_SPAN)), np.ceil(mesh * (1.0 + MESH_SPAN))
    return float(lo), round(float(hi - lo) / MESH_STEP) + 1


def hypothesis_features(batch: Windows, model: str = "skid4") -> dict[str, np.ndarray]:
    """For each fault kind, the (N, H, F) indicators of a window batch under its H hypotheses (wheel x defect
    angle, see the module; worn gears: wheel x searched mesh order), F its `INDICATORS`."""
    if batch.odometry is None or batch.imu6 is None:
        raise WindowError("odometry or imu6 is None: the order reference reads wheel encoders and IMU axes")
    chunks = [
        _chunk_features(batch.subset(slice(i, i + _CHUNK)), model) for i in range(0, len(batch), _CHUNK)
    ]
    return {k: np.concatenate([c[k] for c in chunks], axis=0) for k in INDICATORS}


def _chunk_features(batch: Windows, model: str) -> dict[str, np.ndarray]:
    assert batch.odometry is not None and batch.imu6 is not None
    imu7 = np.concatenate([batch.imu[:, :, None], batch.imu6], axis=2).transpose(0, 2, 1).astype(np.float64)
    audio = batch.audio.astype(np.float64).sum(axis=-1)
    angles = [batch.odometry[:, :, w].astype(np.float64) for w in range(batch.odometry.shape[2])]
    out: dict[str, np.ndarray] = {}
    for kind in INDICATORS:
        prep = fault_indicators.prepare(kind, audio, imu7)
        if kind == "motor_degradation":
            times = np.arange(audio.shape[-1]) / AUDIO_RATE
            first, count = mesh_orders(model)
            levels = [
                fault_indicators.mesh_level(
                    audio, fault_indicators.resampled(a, times), first, MESH_STEP, count
                )
                for a in angles
            ]
            out[kind] = np.concatenate(levels, axis=1)[:, :, None]
            continue
        order = bpfo_order() * (1.0 - 0.5 * sum(BEARING_SLIP)) if kind == "bearing" else 1.0
        count = PHASES if PHASED.intersection(INDICATORS[kind]) else 1
        phases = 2 * np.pi * np.arange(count) / (count * order)
        views = [fault_indicators.indicators(prep, a, float(p), order) for a in angles for p in phases]
        out[kind] = np.stack(views, axis=1)
    return out


class OrderReference(WindowDetector):
    """Each fault kind's indicators per wheel and defect angle; the most significant hypothesis' rarity."""

    kind = "order-reference"
    format_version = 2

    def __init__(self, model: str = "skid4") -> None:
        super().__init__()
        if model not in DRIVE_TRAINS:
            raise ValueError(f"model {model!r} is unknown; allowed: {', '.join(DRIVE_TRAINS)}")
        self.model = model
        self.indicators: dict[str, Rarity] = {}
        self.evidence: dict[str, Rarity] = {}

    def _kind_evidence(self, features: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """For each kind, (N,) the largest summed rarity of its indicators over its hypotheses."""
        out = {}
        for kind, x in features.items():
            n, h, f = x.shape
            out[kind] = self.indicators[kind].score(x.reshape(n * h, f)).reshape(n, h).max(axis=1)
        return out

    def _fit(self, train: Windows, val: Windows | None) -> None:
        features = hypothesis_features(train, self.model)
        self.indicators = {k: Rarity.fit(x.reshape(-1, x.shape[-1])) for k, x in features.items()}
        self.evidence = {k: Rarity.fit(e[:, None]) for k, e in self._kind_evidence(features).items()}

    def _score(self, batch: Windows) -> np.ndarray:
        evidence = self._kind_evidence(hypothesis_features(batch, self.model))
        if set(evidence) != set(self.evidence):
            raise WindowError(
                f"the batch gives kinds {sorted(evidence)}; the model has {sorted(self.evidence)}"
            )
        return np.max([self.evidence[k].score(e[:, None]) for k, e in evidence.items()], axis=0)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        arrays = {f"indicators/{k}": r.sorted_values for k, r in self.indicators.items()}
        arrays |= {f"evidence/{k}": r.sorted_values for k, r in self.evidence.items()}
        return {"model": self.model}, arrays

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        out = cls(str(header["model"]))
        for key, values in arrays.items():
            group, kind = key.split("/", 1)
            {"indicators": out.indicators, "evidence": out.evidence}[group][kind] = Rarity(values)
        return out


def register_methods() -> None:
    """Register `order-reference`."""
    from benchmarks.methods.registry import register

    register(
        "order-reference",
        lambda seed, scale, device: OrderReference(),
        cls=OrderReference,
        family="reference",
        modality="audio+imu+odometry",
        description="reference: each fault kind's condition-monitoring indicators on the wheel encoders' "
        "angle (strikes at the defect's passes, order-1 line, vibration, gear-mesh level), every wheel and "
        "defect angle tested, the most significant hypothesis' nominal rarity",
        label="Order tracking, wheel encoders",
        config="OrderReference(model='skid4')",
    )
