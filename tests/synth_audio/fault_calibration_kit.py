"""Physical calibration of the wheel faults, measured on simulated traces and rendered stems.

Measured on the calibration drive: a straight cruise at `CRUISE` m/s on tile, the fault on the front-left
wheel from 1 s, over `WINDOW`:

- Audio: the fault stem's power in the fault's band (`synth_audio.faults.fault_band`, below the
  detectors' 2205 Hz Nyquist) over the power of the healthy robot's drive sound (motor, rolling and
  electronics stems of the same drive without the fault) in that band, dB. The fault sounds follow level
  laws from the defect's size (`synth_audio.faults`), so this is a measurement, not a target.
- IMU: the z-velocity amplitude at the fault's frequency (rotation, bearing defect or motor shaft
  frequency, at the faulty wheel's own speed) over the healthy drive's; the loose wheel's rattle (random
  impulses, no line): its z-velocity RMS.

Criterion (`test_fault_calibration.py`): every kind is detectable in principle at severity 1, at least
6 dB over the healthy drive in its band in the audio, or in the IMU (a ratio of at least 2).

`.venv/bin/python tests/synth_audio/fault_calibration_kit.py` prints the table per fault kind.
"""

from __future__ import annotations

import functools

import numpy as np

from sim import Fault, Trace, simulate
from sim.scenario import Route, Scenario, Unit, Waypoint
from sim.vocab import FAULT_KINDS
from synth_audio import AudioConfig, render
from synth_audio.faults import band_power, fault_band

CRUISE = 0.8
"""Cruise speed of the calibration drive, m/s (the presets draw 0.3-1.4 m/s)."""
WINDOW = (2.0, 7.0)
"""Steady-cruise interval measured, s (the fault starts at 1 s)."""
RATE = 44100
"""Audio sample rate, Hz."""
SEVERITIES = (0.3, 0.6, 1.0)
"""Severities tabulated."""


def _scenario(kind: str, severity: float) -> Scenario:
    faults = (Fault(kind, 0, severity, 1.0),) if kind else ()
    return Scenario(
        name="fault_calibration",
        seed=11,
        duration=WINDOW[1],
        environment="indoor",
        surface="tile",
        arena=(12.0, 4.0),
        robot=Unit(model="skid4", unit_id=0, variation=0.0),
        route=Route(start=(-10.0, 0.0, 0.0), waypoints=(Waypoint(11.0, 0.0, CRUISE),), accel=1.0, loop=False),
        faults=faults,
    )


@functools.cache
def trace(kind: str = "", severity: float = 0.0) -> Trace:
    """The calibration drive with one fault (kind "" is the nominal drive)."""
    return simulate(_scenario(kind, severity))


@functools.cache
def _stems(kind: str, severity: float) -> dict[str, np.ndarray]:
    """Robot-only stems of the calibration drive over the steady window, float64 (n, 2)."""
    config = AudioConfig(ambience=False, rt60_s=0.0, mic_noise_spl_db=float("-inf"), stems=True)
    audio = render(trace(kind, severity), config, seed=7)
    sl = slice(int(WINDOW[0] * RATE), int(WINDOW[1] * RATE))
    return {k: v[sl].astype(np.float64) for k, v in audio.stems.items()}


@functools.cache
def audio_level_db(kind: str, severity: float) -> float:
    """Fault stem over the healthy robot's drive sound (motor + rolling stems) in the fault's band, dB."""
    tr = trace(kind, severity)
    band = fault_band(tr.faults[0], _rotation_hz(tr), RATE)
    nominal = _stems("", 0.0)
    fault = band_power(_stems(kind, severity)["faults"], RATE, band)
    healthy = nominal["motor"] + nominal["rolling"] + nominal["electronics"]
    return 10.0 * np.log10(fault / band_power(healthy, RATE, band))


def _rotation_hz(tr: Trace) -> float:
    keep = (tr.time > WINDOW[0]) & (tr.time < WINDOW[1])
    return float(np.abs(tr.wheel_speed[keep, 0]).mean() / (2 * np.pi))


def imu_frequency(tr: Trace) -> float:
    """Characteristic IMU frequency of the trace's fault at the faulty wheel's own rotation rate, Hz."""
    f_r = _rotation_hz(tr)
    kind = tr.faults[0].kind
    if kind == "motor_degradation":
        return tr.robot.gear_ratio * f_r
    return float(tr.faults[0].defect_order) * f_r


def _zvel(tr: Trace) -> np.ndarray:
    keep = (tr.imu_time > WINDOW[0]) & (tr.imu_time < WINDOW[1])
    return tr.imu_vel_z[keep] - tr.imu_vel_z[keep].mean()


def _line(tr: Trace, freq: float, width: float = 0.3) -> float:
    x = _zvel(tr)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    f = np.fft.rfftfreq(x.size, 1.0 / tr.imu_rate)
    band = (f > freq - width) & (f < freq + width)
    return float(spectrum[band].max())


@functools.cache
def imu_ratio(kind: str, severity: float = 1.0) -> float:
    """IMU signature of a fault: faulty over nominal drive, in the same scenario.

    The z-velocity amplitude at the fault's frequency (a spectral line) for every kind but the loose
    wheel, whose rattle is random impulses (no line): its z-velocity RMS.
    """
    tr, base = trace(kind, severity), trace()
    if kind == "loose_wheel":
        return float(np.std(_zvel(tr)) / np.std(_zvel(base)))
    freq = imu_frequency(tr)
    return _line(tr, freq) / _line(base, freq)


def table() -> str:
    """Markdown table: audio level over drive sound per severity, and the IMU line ratio at severity 1."""
    head = "| kind | " + " | ".join(f"dB @ {s}" for s in SEVERITIES) + " | IMU x @ 1.0 |"
    rows = [head, "|" + " --- |" * (len(SEVERITIES) + 2)]
    for kind in FAULT_KINDS:
        levels = " | ".join(f"{audio_level_db(kind, s):+.1f}" for s in SEVERITIES)
        rows.append(f"| {kind} | {levels} | {imu_ratio(kind):.1f} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(table())
