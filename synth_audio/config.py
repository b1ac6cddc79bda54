"""The audio stage's public types: `AudioConfig` (how to render), `Audio` (what comes out), `AudioError`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

MIN_SAMPLE_RATE = 16000
"""Lowest sample rate rendered: motor, gear-mesh and impact content reaches several kHz."""
MAX_SAMPLE_RATE = 96000
"""Highest sample rate rendered."""
MAX_NEARFIELD_RATE_HZ = 2.0
"""Highest near-field event rate, events/s (beyond it the room is a crowd, not near-field events)."""

STEM_NAMES: tuple[str, ...] = (
    "motor",
    "rolling",
    "transients",
    "impacts",
    "faults",
    "electronics",
    "room",
    "ambience",
    "nearfield",
    "mic_noise",
)
"""Per-source stems an `Audio` can carry; their sum is the mix before the output limiter."""


MUTABLE_SOURCES: tuple[str, ...] = ("transients", "impacts", "strain", "faults")
"""Source groups `AudioConfig.muted` can leave out (the audit deletes the anomaly's own sound this way);
`strain` is the drive's load from the robot's contacts with obstacles (`drive.unstrained_torque`)."""


class AudioError(ValueError):
    """A trace or config the audio stage cannot render; the message names the problem."""


@dataclass(frozen=True)
class AudioConfig:
    """How to render a trace to binaural audio.

    Levels are physical: sound pressure levels (dB re 20 uPa) at the robot's microphones, mapped to digital
    full scale by the microphone's sensitivity (`full_scale_spl_db`). The robot's own sounds scale with its
    unit's reference drive (`reference_spl_db`); environmental sounds have their own SPL.
    """

    sample_rate: int = 44100
    """Output sample rate, Hz (an integer in [16000, 96000])."""
    snr_db: float = 6.0
    """Robot-to-environment ratio in dB: ambience RMS = robot unit's reference RMS / 10^(snr_db/20)."""
    ambience: bool = True
    """Render the environment: ambience (HVAC, babble, doors / wind, traffic, birds) and near-field events."""
    rt60_s: float = 0.5
    """Reverberation time of the indoor room impulse response, s (0 disables reverberation)."""
    room_send_db: float = -18.0
    """Level of the robot's own sound in the room reverberation relative to its direct sound, dB."""
    mic_noise_spl_db: float = 31.0
    """Microphone self-noise, dB SPL equivalent (a MEMS microphone of 63 dB SNR); -inf disables it."""
    reference_spl_db: float = 68.0
    """SPL of the robot unit's reference drive at its microphones, dB (a small robot heard from on board)."""
    full_scale_spl_db: float = 120.0
    """SPL that reaches digital full scale (a MEMS microphone of sensitivity -26 dBFS at 94 dB SPL)."""
    reference_speed: float = 0.6
    """Linear speed of the reference drive that defines the unit's mean RMS, m/s."""
    stems: bool = False
    """Also return each source group as a stereo stem in `Audio.stems`."""
    gain_motor_db: float = 0.0
    """Extra gain of motor, gearbox, PWM and brush sound, dB."""
    gain_rolling_db: float = 0.0
    """Extra gain of rolling noise, tread tone and chassis rattle, dB."""
    gain_transients_db: float = 0.0
    """Extra gain of benign transients (seams, thresholds, cables, ramps, debris), dB."""
    gain_impacts_db: float = 0.0
    """Extra gain of collision impacts and scraping, dB."""
    gain_faults_db: float = 0.0
    """Extra gain of wheel-fault sound, dB."""
    door_rate_hz: float = 0.08
    """Mean rate of doors closing in other rooms (indoor), events per second."""
    bird_rate_hz: float = 0.3
    """Mean rate of bird calls (outdoor), calls per second."""
    nearfield_rate_hz: float = 0.15
    """Mean rate of near-field events (footsteps, voices, drops: `synth_audio.nearfield`), per s; 0: none."""
    speed_of_sound: float = 343.0
    """Speed of sound, m/s."""
    limiter: bool = True
    """Soft-limit the mix above -6 dBFS so that it never exceeds full scale (monotonic, stems untouched)."""
    muted: tuple[str, ...] = ()
    """Source groups left out entirely (`MUTABLE_SOURCES`); every other source renders as without it."""

    @property
    def reference_level_dbfs(self) -> float:
        """Output RMS of the robot unit's reference drive, dB re full scale."""
        return self.reference_spl_db - self.full_scale_spl_db

    @property
    def mic_noise_dbfs(self) -> float:
        """Microphone self-noise RMS per channel, dB re full scale (-inf: none)."""
        return self.mic_noise_spl_db - self.full_scale_spl_db

    def spl_amplitude(self, spl_db: float) -> float:
        """Digital RMS amplitude (full scale = 1) of a sound of `spl_db` dB SPL at the microphones."""
        return float(10.0 ** ((spl_db - self.full_scale_spl_db) / 20.0))

    def validate(self) -> None:
        """Raise AudioError naming the first field that cannot be honoured."""
        sr = self.sample_rate
        if isinstance(sr, bool) or not isinstance(sr, int | np.integer):
            raise AudioError(f"sample_rate must be an integer number of Hz, got {sr!r}")
        if not MIN_SAMPLE_RATE <= int(sr) <= MAX_SAMPLE_RATE:
            raise AudioError(
                f"sample_rate {sr} Hz cannot be honoured; allowed: {MIN_SAMPLE_RATE}..{MAX_SAMPLE_RATE} Hz"
            )
        finite = {
            "snr_db": self.snr_db,
            "rt60_s": self.rt60_s,
            "room_send_db": self.room_send_db,
            "reference_spl_db": self.reference_spl_db,
            "full_scale_spl_db": self.full_scale_spl_db,
            "reference_speed": self.reference_speed,
            "gain_motor_db": self.gain_motor_db,
            "gain_rolling_db": self.gain_rolling_db,
            "gain_transients_db": self.gain_transients_db,
            "gain_impacts_db": self.gain_impacts_db,
            "gain_faults_db": self.gain_faults_db,
            "door_rate_hz": self.door_rate_hz,
            "bird_rate_hz": self.bird_rate_hz,
            "nearfield_rate_hz": self.nearfield_rate_hz,
            "speed_of_sound": self.speed_of_sound,
        }
        for name, value in finite.items():
            if not isinstance(value, int | float | np.floating | np.integer) or not math.isfinite(value):
                raise AudioError(f"{name} must be a finite number, got {value!r}")
        if not (isinstance(self.mic_noise_spl_db, int | float) and not math.isnan(self.mic_noise_spl_db)):
            raise AudioError(f"mic_noise_spl_db must be a number or -inf, got {self.mic_noise_spl_db!r}")
        if self.mic_noise_spl_db == math.inf:
            raise AudioError("mic_noise_spl_db must be finite or -inf (disabled), got inf")
        if not 0.0 <= self.rt60_s <= 3.0:
            raise AudioError(f"rt60_s {self.rt60_s} out of range; allowed: 0..3 s")
        if not 100.0 <= self.full_scale_spl_db <= 160.0:
            raise AudioError(f"full_scale_spl_db {self.full_scale_spl_db} out of range; allowed: 100..160 dB")
        if not -80.0 <= self.reference_level_dbfs <= -6.0:
            raise AudioError(
                f"reference_spl_db {self.reference_spl_db} is {self.reference_level_dbfs:g} dBFS at "
                f"full_scale_spl_db {self.full_scale_spl_db}; allowed: -80..-6 dBFS"
            )
        if not 0.05 <= self.reference_speed <= 5.0:
            raise AudioError(f"reference_speed {self.reference_speed} out of range; allowed: 0.05..5 m/s")
        if self.door_rate_hz < 0 or self.bird_rate_hz < 0:
            raise AudioError("door_rate_hz and bird_rate_hz must be >= 0")
        if not 0.0 <= self.nearfield_rate_hz <= MAX_NEARFIELD_RATE_HZ:
            raise AudioError(
                f"nearfield_rate_hz {self.nearfield_rate_hz} out of range; "
                f"allowed: 0..{MAX_NEARFIELD_RATE_HZ:g} events/s"
            )
        if not 200.0 <= self.speed_of_sound <= 2000.0:
            raise AudioError(f"speed_of_sound {self.speed_of_sound} out of range; allowed: 200..2000 m/s")
        if not isinstance(self.muted, tuple) or any(m not in MUTABLE_SOURCES for m in self.muted):
            allowed = ", ".join(MUTABLE_SOURCES)
            raise AudioError(f"muted {self.muted!r} is invalid; allowed: a tuple of {allowed}")


@dataclass(frozen=True)
class Audio:
    """Rendered binaural audio: two microphone channels (left, right) plus optional per-source stems."""

    samples: np.ndarray
    """(n, 2) float32 left and right microphone signals, full scale = 1."""
    sample_rate: int
    """Sample rate, Hz."""
    stems: dict[str, np.ndarray] = field(default_factory=dict)
    """Per-source (n, 2) float32 stems by name (see `STEM_NAMES`); empty unless `AudioConfig.stems`."""

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.samples.shape[0] / self.sample_rate
