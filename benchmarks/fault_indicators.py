"""Each wheel fault kind's own signature in a 2 s window, read against a wheel's angle.

One implementation of what condition monitoring reads for each fault kind (`INDICATORS`), shared by the
audit's privileged oracle (`benchmarks.audit.oracle`: the true wheel angle, the defect's angle and order)
and the fault-aware reference detector (`benchmarks.methods.orders`: the wheel encoders' angle, every wheel
and defect angle in turn):

- strikes (flat spot, bearing, loose hub): the response within `STRIKE_GATE_S` of each pass of the defect
  (the angle crossing phase + 2 pi j / order) over the rest of the window (`gated_ratio`), in the audio's
  squared envelope in the kind's band (`sim.faults.envelope_band`) and in the motion power (above 0.5 Hz) of
  the IMU: the time-synchronous average of the defect's strike against everything else;
- once-per-revolution motion (out-of-round wheel, loose hub): the order-1 line of the IMU's smooth motion
  (below `condition.SPLIT_HZ`);
- a loose hub's rattle: the IMU's vibration power above `condition.SPLIT_HZ`;
- worn gears: the level of the gear-mesh line with its wheel-order sidebands (mesh -+ 1 order) in the raw
  audio (`mesh_level`), the tone's amplitude tracked by the wheel's angle (condition monitoring's gear-mesh
  amplitude).

Each IMU indicator is the mean of its logarithm over the seven channels (z-velocity, accelerometer and
gyroscope xyz): the chassis' response, however a strike spreads over the axes, as one indicator (seven
separate ones would each add a chance of a nominal extreme, and bury the audio's evidence).

Which indicators each kind reads was chosen on dev datasets (seeds never audited): an indicator whose
evidence is at chance for a kind only adds nominal extremes to its score. On dev, the chassis did not carry a
bearing's ball strikes (its IMU strike indicator at chance, the audio's far above) nor a flat's
once-per-revolution motion (the rigid four-wheel chassis rests on three wheels while one rolls over its
flat), and an out-of-round wheel did not modulate the rolling sound. A worn pair's mesh line over the lines
around it saturated at low severity (the whine's own wheel- and shaft-rate modulation lifts its neighbours),
where the mesh group's level grows with the wear; its motor-shaft sidebands and the IMU's shaft-order line
were weaker.

`Rarity` turns indicators into evidence: each one's upper tail under its distribution over nominal windows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from benchmarks import condition
from msvdd.contract import AUDIO_RATE, IMU_LEN, IMU_RATE
from sim.faults import envelope_band

STRIKE_GATE_S = 0.05
"""How long before and after a pass of the defect its response is read, s (a flat's dip before its slap,
the tyre's and chassis' ring after a strike)."""
INDICATORS: dict[str, tuple[str, ...]] = {
    "flat_spot": ("strike_audio", "strike_imu"),
    "bearing": ("strike_audio",),
    "loose_wheel": ("strike_audio", "once_per_rev_imu", "vibration_imu"),
    "out_of_round": ("once_per_rev_imu",),
    "motor_degradation": ("mesh_level_audio",),
}
"""The indicators read for each fault kind, in their feature columns' order (see the module)."""
_NAMES = frozenset(name for names in INDICATORS.values() for name in names)
PHASED: frozenset[str] = frozenset({"strike_audio", "strike_imu"})
"""The indicators that depend on the defect's angle (the others read the wheel's angle only, or none)."""


def gated_ratio(power: np.ndarray, angle: np.ndarray, phase: float, order: float, rate: float) -> np.ndarray:
    """(k,) mean of (k, n) `power` sampled at `rate` within `STRIKE_GATE_S` of each pass of a defect at
    wheel angle `phase` (rad) with `order` events per revolution (the angle (k, n) passing phase + 2 pi j /
    order) over its mean elsewhere; 1 for a window without a pass (floored at 1e-3)."""
    cycles = np.floor(order * (angle - phase) / (2 * np.pi))
    hit = np.zeros(angle.shape, dtype=np.int64)
    hit[:, 1:] = cycles[:, 1:] != cycles[:, :-1]
    span = max(1, round(STRIKE_GATE_S * rate))
    counts = np.concatenate([np.zeros((len(hit), span + 1), np.int64), np.cumsum(hit, axis=1)], axis=1)
    counts = np.concatenate([counts, np.repeat(counts[:, -1:], span, axis=1)], axis=1)
    n = angle.shape[1]
    gate = (counts[:, 2 * span + 1 : 2 * span + 1 + n] - counts[:, :n]) > 0
    inside = (power * gate).sum(axis=1) / np.maximum(gate.sum(axis=1), 1)
    outside = (power * ~gate).sum(axis=1) / np.maximum((~gate).sum(axis=1), 1)
    ratio = np.where(gate.any(axis=1), inside / np.maximum(outside, 1e-30), 1.0)
    return np.asarray(np.maximum(ratio, 1e-3))


def mesh_level(audio: np.ndarray, angle: np.ndarray, mesh: float) -> np.ndarray:
    """(k,) log level of the gear-mesh line at order `mesh` with its two wheel-order sidebands (mesh -+ 1), in
    (k, n) audio at wheel angles `angle` (k, n): the three lines' sum (relative to the audio's standard
    deviation, `condition.order_lines`) times that deviation."""
    lines = condition.order_lines(audio, angle, mesh + np.array([-1.0, 0.0, 1.0]))
    return np.asarray(np.log(lines.sum(axis=1) * audio.std(axis=-1) + 1e-12))


def resampled(angle: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(k, len(times)) the (k, `IMU_LEN`) wheel angles at the IMU's samples, interpolated at `times` (s from
    the window's start)."""
    t_imu = np.arange(IMU_LEN) / IMU_RATE
    return np.stack([np.interp(times, t_imu, a) for a in angle])


@dataclass(frozen=True)
class Prepared:
    """A window batch's signals, filtered once for the indicators of one fault kind."""

    kind: str
    """Fault kind (which `INDICATORS`)."""
    audio: np.ndarray
    """(k, n) mono audio at `msvdd.contract.AUDIO_RATE`."""
    envelope: np.ndarray | None
    """(k, e) the audio's squared envelope in the kind's band, block means (strikes)."""
    envelope_time: np.ndarray | None
    """(e,) the envelope's sample times (block centres), s."""
    motion: np.ndarray | None
    """(k, 7, m) the IMU's motion power above 0.5 Hz (strikes)."""
    smooth: np.ndarray | None
    """(k, 7, m) the IMU's smooth motion below `condition.SPLIT_HZ` (once-per-revolution motion)."""
    vibration: np.ndarray | None
    """(k,) mean over the channels of the log of the IMU's vibration power above `condition.SPLIT_HZ`."""


def prepare(kind: str, audio: np.ndarray, imu7: np.ndarray) -> Prepared:
    """Filter (k, n) mono audio and the (k, 7, m) IMU channels for `kind`'s indicators."""
    wanted = INDICATORS[kind]
    envelope = envelope_time = motion = smooth = vibration = None
    if "strike_audio" in wanted:
        envelope, envelope_time = condition.block_envelope(audio, AUDIO_RATE, envelope_band(kind, AUDIO_RATE))
    if "strike_imu" in wanted:
        motion = condition.band_pass(imu7, IMU_RATE, (0.5, IMU_RATE / 2)) ** 2
    if "once_per_rev_imu" in wanted:
        smooth = condition.band_pass(imu7, IMU_RATE, (0.3, condition.SPLIT_HZ))
    if "vibration_imu" in wanted:
        power = condition.band_pass(imu7, IMU_RATE, (condition.SPLIT_HZ, IMU_RATE / 2)) ** 2
        vibration = np.mean(
            [np.log(power[:, c].mean(axis=-1) + 1e-20) for c in range(power.shape[1])], axis=0
        )
    return Prepared(kind, audio, envelope, envelope_time, motion, smooth, vibration)


def indicators(prep: Prepared, angle: np.ndarray, phases: np.ndarray, order: float) -> np.ndarray:
    """(k, P, F) the `INDICATORS` of `prep.kind` of the prepared windows (columns in that order), looked at
    through a wheel at angles `angle` (k, `IMU_LEN`) with a defect at each of the wheel angles `phases` (P,)
    (rad) and `order` events per revolution (for worn gears, the gear-mesh order; its level does not depend on
    the defect's angle)."""
    phases = np.atleast_1d(np.asarray(phases, dtype=np.float64))
    k, count = angle.shape[0], phases.size
    columns: list[np.ndarray] = []
    for name in INDICATORS[prep.kind]:
        if name == "mesh_level_audio":
            audio_angle = resampled(angle, np.arange(prep.audio.shape[-1]) / AUDIO_RATE)
            column = np.repeat(mesh_level(prep.audio, audio_angle, order)[:, None], count, axis=1)
        elif name == "strike_audio":
            assert prep.envelope is not None and prep.envelope_time is not None
            env_angle = resampled(angle, prep.envelope_time)
            rate = AUDIO_RATE / condition.ENVELOPE_BLOCK
            column = np.stack(
                [np.log(gated_ratio(prep.envelope, env_angle, p, order, rate)) for p in phases], axis=1
            )
        elif name == "strike_imu":
            assert prep.motion is not None
            channels = range(prep.motion.shape[1])
            column = np.stack(
                [
                    np.mean(
                        [np.log(gated_ratio(prep.motion[:, c], angle, p, order, IMU_RATE)) for c in channels],
                        0,
                    )
                    for p in phases
                ],
                axis=1,
            )
        elif name == "once_per_rev_imu":
            assert prep.smooth is not None
            one = np.array([1.0])
            lines = [
                condition.log_lines(channel, angle, one)[:, 0] for channel in prep.smooth.transpose(1, 0, 2)
            ]
            column = np.repeat(np.mean(lines, axis=0)[:, None], count, axis=1)
        elif name == "vibration_imu":
            assert prep.vibration is not None
            column = np.repeat(prep.vibration[:, None], count, axis=1)
        else:
            raise ValueError(f"indicator {name!r} is unknown; allowed: {', '.join(sorted(_NAMES))}")
        columns.append(column.reshape(k, count))
    return np.stack(columns, axis=2)


TAIL_FRACTION = 0.1
"""The upper fraction of the nominal values whose spread sets the slope of `Rarity`'s tail beyond them."""


@dataclass
class Rarity:
    """Each indicator's distribution over nominal windows; a window's evidence is the summed rarity of its
    indicators."""

    sorted_values: np.ndarray
    """(n, F) each indicator's nominal values, sorted."""

    @classmethod
    def fit(cls, x: np.ndarray) -> Rarity:
        """Fit on (n, F) nominal rows."""
        return cls(np.sort(np.asarray(x, dtype=np.float64), axis=0))

    def score(self, x: np.ndarray) -> np.ndarray:
        """(k,) the sum over the features of (k, F) rows of -log10 of each one's upper-tail probability under
        the nominal distribution: Fisher's combination of the indicators' evidence, each on its own scale.

        Within the nominal values the tail is empirical, counting the row itself (at most log10(n + 1));
        beyond the largest, it falls on as an exponential tail (a peaks-over-threshold model) whose slope is
        the range estimate over the top `TAIL_FRACTION` (k rows): log10(k + 1) decades between the (k + 1)-th
        largest value and the largest, so that a row far beyond every nominal one is rarer than one just
        beyond (no tail if those values are all equal)."""
        n = self.sorted_values.shape[0]
        k = max(1, int(TAIL_FRACTION * n))
        total = np.zeros(x.shape[0])
        for f in range(x.shape[1]):
            values = self.sorted_values[:, f]
            above = n - np.searchsorted(values, x[:, f], side="left")
            total -= np.log10((above + 1.0) / (n + 1.0))
            spread = values[-1] - values[n - 1 - k] if n > k else 0.0
            if spread > 0:
                total += np.maximum(x[:, f] - values[-1], 0.0) * math.log10(k + 1.0) / spread
        return total
