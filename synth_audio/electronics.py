"""The robot's electronics while it is powered: the cooling fan of its computer and motor drivers.

Law: one small axial fan on the chassis runs at a constant speed through the whole episode (a trace is
always of a powered robot). The fan is the unit's own: its blade count (5-9) and speed (3000-6000 rpm) are
drawn from a generator fixed by the unit id (`unit_fan`), so the same unit always sounds the same. Its
sound is the blade-pass tone (blades x rpm / 60: 250-900 Hz) with its 2nd and 3rd harmonics (on average
-6 and -12 dB, each unit within +-3 dB), a weak line at the shaft rate (rotor unbalance, -20 dB) and
broadband aerodynamic noise (a hump at 1-3 kHz, woven by `dsp.noise_bed`); tones and noise carry equal
power. Its RMS at the microphones is `FAN_DB` re the unit's reference drive: 48 dB SPL with the default
68 dB SPL reference, what a 40-60 mm fan about 0.25 m from the microphones gives (data sheets: 25-35 dB(A)
at 1 m, so 37-47 dB(A) at 0.25 m, a few dB more unweighted for a tone below 1 kHz). It is the robot's own
sound: `render` puts it on the chassis bus, scaled with the unit's reference level like motor and rolling.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.trace import RobotInfo
from synth_audio.dsp import bed_pool, block_wavetable, noise_bed, normalise_rms, unit_table

FAN_DB = -20.0
"""RMS of the fan at the microphones re the unit's reference drive, dB (48 dB SPL at the default 68)."""
BLADES = (5, 9)
"""Range of the fan's blade count (inclusive)."""
RPM = (3000.0, 6000.0)
"""Range of the fan's speed, revolutions per minute."""
_HARMONIC_DB = (0.0, -6.0, -12.0)
"""Mean level of the blade-pass tone and its 2nd and 3rd harmonics, dB."""
_SHAFT_DB = -20.0
"""Level of the shaft-rate line (unbalance) re the blade-pass tone, dB."""
_UNIT_SPREAD_DB = 3.0
"""Each unit's harmonic levels lie within +- this of the mean, dB."""
_NOISE_POINTS_HZ = (150.0, 600.0, 1500.0, 3000.0, 8000.0, 16000.0)
_NOISE_GAINS_DB = (-18.0, -6.0, 0.0, -1.0, -12.0, -24.0)
_BLOCK = 256
_FAN_KEY = 0xFA7
"""Slot of the fan in the unit's generators (`render._unit_rng` uses the wheel index there)."""


@dataclass(frozen=True)
class Fan:
    """One unit's cooling fan."""

    blades: int
    """Number of blades."""
    rpm: float
    """Shaft speed, revolutions per minute."""
    harmonics: tuple[float, float, float]
    """Amplitudes of the blade-pass tone and its 2nd and 3rd harmonics (relative)."""
    shaft: float
    """Amplitude of the shaft-rate line (relative, same scale)."""
    phases: tuple[float, float, float, float]
    """Phases of the shaft line and the three blade-pass harmonics, rad."""

    @property
    def blade_pass_hz(self) -> float:
        """Blade-pass frequency, Hz."""
        return self.blades * self.rpm / 60.0


def unit_fan(robot: RobotInfo) -> Fan:
    """The unit's fan, drawn from a generator fixed by the unit id (the same unit always sounds the same)."""
    unit = int(robot.unit_id)
    rng = np.random.default_rng([abs(unit), int(unit < 0), _FAN_KEY, 0xA0D10])
    blades = int(rng.integers(BLADES[0], BLADES[1] + 1))
    rpm = float(rng.uniform(*RPM))
    levels = np.asarray(_HARMONIC_DB) + rng.uniform(-_UNIT_SPREAD_DB, _UNIT_SPREAD_DB, 3)
    amps = 10.0 ** (levels / 20.0)
    phases = rng.uniform(0.0, 2.0 * np.pi, 4)
    return Fan(
        blades=blades,
        rpm=rpm,
        harmonics=(float(amps[0]), float(amps[1]), float(amps[2])),
        shaft=float(amps[0] * 10.0 ** (_SHAFT_DB / 20.0)),
        phases=(float(phases[0]), float(phases[1]), float(phases[2]), float(phases[3])),
    )


def fan_sound(fan: Fan, n: int, sample_rate: int, rng: np.random.Generator) -> np.ndarray:
    """(n,) unit-RMS mono sound of the fan: steady blade-pass harmonics plus broadband noise, float32.

    The tones are read from one wavetable of the shaft phase (all are shaft harmonics); the noise bed is woven
    by `rng` (the render's stream) from its shape's library (`dsp.bed_pool`), so only the fan's character
    is the unit's.
    """
    if n <= 0:
        return np.zeros(0, dtype=np.float32)
    b = fan.blades
    ks = np.array([1.0, b, 2.0 * b, 3.0 * b])
    amps = np.array([fan.shaft, *fan.harmonics])
    keep = ks * fan.rpm / 60.0 < 0.45 * sample_rate
    table = unit_table(ks[keep], amps[keep], np.asarray(fan.phases)[keep])
    nb = -(-n // _BLOCK)
    cycles = np.arange(nb + 1, dtype=np.float64) * (_BLOCK / sample_rate) * (fan.rpm / 60.0)
    tones = normalise_rms(block_wavetable(cycles, _BLOCK, n, table))
    pool = bed_pool(sample_rate, _NOISE_POINTS_HZ, _NOISE_GAINS_DB)
    out = noise_bed(rng, n, pool)
    out += tones
    return normalise_rms(out)
