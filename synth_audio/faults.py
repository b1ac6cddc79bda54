"""Wheel-fault sounds, derived from the trace's defect model (`sim.faults`), on the common impact scale.

The audio stage sounds what the physics did; it keeps no defect parameters of its own:

- flat_spot, bearing, loose_wheel: every strike the physics applied (`Trace.fault_strikes`: its time, wheel
  and impulse J from `sim.faults.strike_impulse`) rings a kernel of J times the unit impulse's sound on
  `impacts.IMPACT_SCALE`, like collisions and benign transients: the flat's far edge slaps the floor like a
  step (the tyre and the chassis ring: the same character as a benign threshold); a ball striking the spall
  clicks through the hub's resonance; a loose hub clunks metal on metal. A spalled bearing also grinds:
  the wheel's own drive sound in the hub's resonance octave, times `sim.faults.BEARING_GROWL` x size /
  `sim.faults.SPALL_M`, swelling as each ball crosses the spall (at the ball-pass rate).
- out_of_round: the runout e loads and unloads its wheel once per revolution (vertical acceleration
  e omega^2 at the corner), so the wheel's rolling and motor sound is amplitude-modulated at the rotation
  rate with depth e omega^2 / g; its motor's varying effort is in the trace's torque, which the motor sound
  follows already (`synth_audio.motor`).
- motor_degradation: worn gears raise the gear-mesh transmission error to (1 + size) times a healthy pair's
  (`FaultRecord.size`, `sim.faults.WEAR_GAIN` at severity 1): the mesh tone grows by size times the healthy
  mesh tone (`motor._MESH`), modulated at the wheel and motor shaft rates (eccentric worn gears).

`fault_band` is each fault's characteristic band, where the audit's level probe reads it.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from sim.faults import BEARING_GROWL, SPALL_M
from sim.trace import FaultRecord, FaultStrikes
from synth_audio.drive import BLOCK, GRAVITY, Drive
from synth_audio.dsp import bandpass_sos, overlap_add
from synth_audio.impacts import IMPACT_SCALE, Material, struck_response
from synth_audio.motor import MESH_WEIGHT, load_envelope

DETECTOR_NYQUIST_HZ = 2205.0
"""Nyquist frequency of the detectors' audio (44.1 kHz decimated by 10): characteristic bands stay below."""
_EDGE_S = 0.02
_GROWL_SETTLE_S = 0.05
"""How long before the gate opens the growl's band-pass starts filtering, s. Its slowest pole decays by
e^(-0.05 x 2 pi x 0.31 f0) in that time (e^-49 at 500 Hz; the bearing's hub resonance, `sim.faults.RESONANCE`,
is about 1.6 kHz: e^-156), so the growl equals the whole episode's filtering to the precision of its samples,
at the gated span's cost."""
_REFERENCE_SPEED = 0.8
"""Approach speed of the kernels' contact time, m/s (the strike speed changes only the impulse)."""
FAULT_KINDS: tuple[str, ...] = ("flat_spot", "out_of_round", "bearing", "loose_wheel", "motor_degradation")
"""Kinds this module sounds (`sim.vocab.FAULT_KINDS`)."""


def band_power(x: np.ndarray, rate: float, band: tuple[float, float]) -> float:
    """Energy of (n,) or (n, C) samples between band[0] (included) and band[1] (excluded) Hz, summed over the
    channels: the sum of |rfft|^2 over the band's bins (Parseval up to the factor 2 / n of one-sided bins).
    The measure of a fault's level in its `fault_band` (the calibration kit's and the audit's)."""
    spectrum = np.abs(np.fft.rfft(np.asarray(x, dtype=np.float64), axis=0)) ** 2
    freqs = np.fft.rfftfreq(np.asarray(x).shape[0], 1.0 / rate)
    keep = (freqs >= band[0]) & (freqs < band[1])
    return float(spectrum[keep].sum())


def fault_band(fault: FaultRecord, rotation_hz: float, sample_rate: int) -> tuple[float, float]:
    """Characteristic band of a fault's sound, Hz, where its calibrated level is measured.

    One octave centred on the structural resonance the fault excites (`fault.resonance_hz`), or +-20 %
    around the gear-mesh tone (`defect_order` x `rotation_hz`) for motor degradation; clipped to
    [20 Hz, DETECTOR_NYQUIST_HZ] and to the sample rate's Nyquist.
    """
    top = min(DETECTOR_NYQUIST_HZ, 0.5 * sample_rate)
    if fault.kind == "motor_degradation":
        centre, half = float(fault.defect_order) * abs(rotation_hz), 1.2
    else:
        centre, half = float(fault.resonance_hz), float(np.sqrt(2.0))
    lo = float(np.clip(centre / half, 20.0, top))
    hi = float(np.clip(centre * half, 20.0, top))
    if hi <= lo:
        raise ValueError(f"fault band of {fault.kind!r} is empty: centre {centre:.1f} Hz, limit {top:.0f} Hz")
    return lo, hi


def window(drive: Drive, fault: FaultRecord) -> np.ndarray:
    """Gate at block boundaries: 1 inside [onset, onset + duration], with 20 ms ramps, else 0."""
    t = drive.block_time
    start, end = fault.onset, fault.onset + fault.duration
    rise = np.clip((t - start) / _EDGE_S + 1.0, 0.0, 1.0)
    fall = np.clip((end - t) / _EDGE_S + 1.0, 0.0, 1.0)
    return rise * fall


def _kernel(fault: FaultRecord, sample_rate: int, rng: np.random.Generator) -> np.ndarray:
    """Sound of one strike of 1 N s for an impulsive fault: what its defect rings, on `IMPACT_SCALE`."""
    f = float(np.clip(fault.resonance_hz, 20.0, 0.45 * sample_rate))
    t60 = float(min(6.907755 / (2.0 * np.pi * f * float(np.clip(fault.damping_ratio, 0.002, 0.5))), 0.25))
    if fault.kind == "flat_spot":  # the tread's edge slaps the floor: tyre, floor and chassis ring
        material = Material((95.0, 230.0, f, 1350.0, 2700.0), (0.09, 0.06, t60, 0.035, 0.02),
                            (1.0, 0.7, 0.8, 0.45, 0.25), 0.002, 0.35, 1.0)  # fmt: skip
        body = 1.0
    elif fault.kind == "bearing":  # steel on steel: a short click through the hub's resonance
        material = Material((f, 1.5 * f), (t60, 0.5 * t60), (1.0, 0.4), 0.0002, 0.6, 1.0)
        body = 0.3
    else:  # loose_wheel: metal clunk of the hub in its seat
        material = Material((f, 1100.0, 2300.0, 3900.0, 160.0), (0.04, 0.04, 0.03, 0.02, 0.03),
                            (1.0, 0.8, 1.0, 0.6, 0.7), 0.0005, 0.6, 1.0)  # fmt: skip
        body = 0.5
    return struck_response(material, 1.0, _REFERENCE_SPEED, sample_rate, rng, IMPACT_SCALE, body)


def _growl(
    drive: Drive, fault: FaultRecord, wheel_sound: np.ndarray, gate: np.ndarray, span: tuple[int, int]
) -> np.ndarray:
    """A spalled bearing's grinding over the gate's `span` of samples: the wheel's drive sound in the octave
    around the hub's resonance, times `BEARING_GROWL` x size / `SPALL_M`, modulated at the ball-pass rate
    (float32 (span length,))."""
    f0 = float(fault.resonance_hz)
    top = 0.45 * drive.sample_rate
    band = (min(f0 / np.sqrt(2.0), top / 2), min(f0 * np.sqrt(2.0), top))
    sos = bandpass_sos(float(band[0]), float(band[1]), drive.sample_rate)
    a, b = span
    lead = min(a, round(_GROWL_SETTLE_S * drive.sample_rate))
    rough = signal.sosfilt(sos, wheel_sound[a - lead : b].astype(np.float64))[lead:].astype(np.float32)
    passes = np.float32(2 * np.pi) * drive.phase(fault.wheel, float(fault.defect_order), span)
    at_spall = np.float32(fault.defect_order * fault.phase)  # where a ball meets the spall (the strikes)
    swell = np.float32(0.6) + np.float32(0.4) * np.cos(passes - at_spall)
    gain = BEARING_GROWL * min(fault.size / SPALL_M, 1.0)
    return rough * swell * drive.ramp(gain * gate, span)


def _gated_span(drive: Drive, gate: np.ndarray) -> tuple[int, int]:
    """The samples [a, b) where a gate given at block boundaries (ramped within each block) is not zero:
    from the start of the block before its first non-zero boundary to the end of the block after its last."""
    on = np.flatnonzero(gate > 0)
    return max(int(on[0]) - 1, 0) * BLOCK, min((int(on[-1]) + 1) * BLOCK, drive.n)


def fault_sound(
    drive: Drive,
    fault: FaultRecord,
    strikes: FaultStrikes,
    wheel_sound: np.ndarray,
    rng: np.random.Generator,
) -> np.ndarray:
    """Mono sound of one fault at its wheel, float32 (n,).

    Args:
        drive: the trace's drive train at audio rate.
        fault: the fault's record.
        strikes: the trace's fault strikes (those of `fault.wheel` are this fault's).
        wheel_sound: that wheel's nominal sound (motor and rolling).
        rng: the fault stream's generator.
    """
    sr, n, w = drive.sample_rate, drive.n, fault.wheel
    if fault.kind not in FAULT_KINDS:
        raise ValueError(f"unknown fault kind {fault.kind!r}; allowed: {', '.join(FAULT_KINDS)}")
    gate = window(drive, fault)
    if fault.severity <= 0.0 or not np.any(gate > 0):
        return np.zeros(n, dtype=np.float32)
    kind = fault.kind
    span = _gated_span(drive, gate)  # the gated sounds are computed there only
    a, b = span
    if kind in ("flat_spot", "bearing", "loose_wheel"):
        mine = (strikes.wheel == w) & (strikes.time < n / sr)
        pos = np.round(strikes.time[mine] * sr)
        out = overlap_add(n, pos, strikes.impulse[mine], _kernel(fault, sr, rng))
        if kind == "bearing":
            out[a:b] += _growl(drive, fault, wheel_sound, gate, span)
        return out
    out = np.zeros(n, dtype=np.float32)
    if kind == "out_of_round":
        omega = np.abs(drive.rev_s[w]) * 2.0 * np.pi
        depth = np.minimum(fault.size * omega**2 / GRAVITY, 1.0)
        phase = np.float32(2 * np.pi) * drive.phase(w, 1.0, span) - np.float32(fault.phase)
        out[a:b] = wheel_sound[a:b] * np.cos(phase) * drive.ramp(depth * gate, span)
        return out
    # motor_degradation
    robot = drive.robot
    order = float(fault.defect_order) if fault.defect_order > 0 else robot.pinion_teeth * robot.gear_ratio
    mesh = np.sin(np.float32(2 * np.pi) * drive.phase(w, order, span) + np.float32(rng.uniform(0, 6.28)))
    wheel_mod = np.cos(np.float32(2 * np.pi) * drive.phase(w, 1.0, span))
    shaft_mod = np.cos(np.float32(2 * np.pi) * drive.phase(w, robot.gear_ratio, span))
    mesh *= np.float32(1.0) + np.float32(0.4) * wheel_mod + np.float32(0.25) * shaft_mod
    speed, load_factor = load_envelope(drive, w)
    tone_env = speed * (0.7 + 0.3 * load_factor)
    out[a:b] = mesh * drive.ramp(MESH_WEIGHT * fault.size * tone_env * gate, span)
    return out
