"""Environment sound: indoor (HVAC, distant babble, doors in other rooms, room reverberation) and outdoor
(wind with gusts, traffic, birds).

Continuous beds are diffuse (partly coherent between the mics). Outdoor events (birds) come from a direction
in the world and are spatialised as plane waves for the robot's heading at that moment. Indoor babble and
doors are in other rooms: they reach the robot through the reverberant field, so they are synthesised at the
reverberation's reduced rate as a send that `synth_audio.reverb.Room` convolves.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.signal import sosfilt

from synth_audio import kernels
from synth_audio.dsp import (
    add_at,
    bandpass_sos,
    bed_pool,
    block_ramp,
    damped_modes,
    frac_phase,
    noise_bed,
    one_pole_lowpass,
)
from synth_audio.spatial import plane_wave_gains, spatialize_into

_BLOCK = 256
INTONATION = 0.2
"""Standard deviation of a talker's log pitch (speech moves over a few semitones, ~20 %)."""


@dataclass(frozen=True)
class Scene:
    """What the ambience needs to know about the robot: microphones and heading over time."""

    n: int
    """Samples to render."""
    sample_rate: int
    """Sample rate, Hz."""
    mic_body: np.ndarray
    """(2, 3) microphone positions in the base frame, m."""
    axes: np.ndarray
    """(2, 3) microphone facing directions in the base frame."""
    speed_of_sound: float
    """m/s."""
    world_to_body: Callable[[float], np.ndarray]
    """Time -> (3, 3) rotation taking world vectors to the base frame."""


def _diffuse(rng: np.random.Generator, n: int, pool: np.ndarray, coherence: float) -> np.ndarray:
    """(2, n) unit-RMS diffuse-field bed: a part shared by both microphones plus a part of each's own.

    The three parts are independent, non-repeating beds woven from one spectral `pool`
    (`dsp.noise_bed`), so the two channels have the given coherence and neither repeats.
    """
    own = np.float32(np.sqrt(1.0 - coherence))
    out = np.stack([noise_bed(rng, n, pool), noise_bed(rng, n, pool)])
    out *= own
    if coherence > 0:
        shared = noise_bed(rng, n, pool)
        shared *= np.float32(np.sqrt(coherence))
        out += shared
    return out


def _slow_process(rng: np.random.Generator, n_ctrl: int, ctrl_rate: float, corner_hz: float) -> np.ndarray:
    """Unit-variance low-pass Gaussian process at control rate (for gusts, phrases, traffic swells)."""
    x = one_pole_lowpass(rng.standard_normal(n_ctrl + 64).astype(np.float32), corner_hz, int(ctrl_rate))
    x = x[64:]
    return (x - np.mean(x)) / max(float(np.std(x)), 1e-9)


def _event_into(out: np.ndarray, scene: Scene, signal: np.ndarray, t: float, azimuth: float) -> None:
    """Place a mono event at time t arriving from a world azimuth (horizontal plane wave)."""
    direction = scene.world_to_body(t) @ np.array([np.cos(azimuth), np.sin(azimuth), 0.1])
    delays, gains = plane_wave_gains(
        direction, scene.mic_body, scene.axes, scene.sample_rate, scene.speed_of_sound
    )
    spatialize_into(out, signal, delays, gains, int(t * scene.sample_rate))


def _event_times(rng: np.random.Generator, rate: float, duration: float) -> np.ndarray:
    count = int(rng.poisson(rate * duration))
    return np.sort(rng.uniform(0.0, duration, count))


def _door(rng: np.random.Generator, sr: int) -> np.ndarray:
    """A door closing in another room: a low panel thud, a latch click, muffled by the walls."""
    length = int(0.6 * sr)
    freqs = np.array([45.0, 92.0, 180.0, 410.0]) * rng.uniform(0.85, 1.15)
    thud = damped_modes(freqs, np.array([0.3, 0.25, 0.15, 0.08]), np.array([1.0, 0.8, 0.5, 0.25]),
                        rng.uniform(0, 6.28, 4), sr, length)  # fmt: skip
    latch_at = int(rng.uniform(0.0, 0.03) * sr)
    latch = damped_modes(np.array([1800.0, 3100.0]) * rng.uniform(0.9, 1.1), np.array([0.03, 0.02]),
                         np.array([0.4, 0.25]), rng.uniform(0, 6.28, 2), sr, int(0.05 * sr))  # fmt: skip
    add_at(thud, latch_at, latch)
    return one_pole_lowpass(thud, 900.0, sr) * np.float32(rng.lognormal(0.0, 0.4))


def _babble(n: int, sr: int, rng: np.random.Generator, talkers: int) -> np.ndarray:
    """Mono distant speech-like babble through a wall: voiced buzz and noise under syllabic envelopes."""
    nb = -(-n // _BLOCK) + 1
    ctrl = sr / _BLOCK
    pool = bed_pool(sr, (100, 300, 700, 2000, 5000), (-12, 0, -2, -14, -30))
    out = np.zeros(n, dtype=np.float32)
    for _ in range(talkers):
        f0 = rng.uniform(95.0, 220.0) * np.exp(INTONATION * _slow_process(rng, nb, ctrl, 3.0))
        cycles = np.cumsum(f0 / ctrl)
        phase = frac_phase(cycles[None, :], _BLOCK, n)[0]
        phase -= np.floor(phase)  # frac_phase is only wrapped at block starts: a sawtooth needs [0, 1)
        buzz = phase * np.float32(2.0) - np.float32(1.0)
        syllable = np.clip(_slow_process(rng, nb, ctrl, 4.5), 0.0, None)
        phrase = (_slow_process(rng, nb, ctrl, 0.3) > rng.uniform(-0.6, 0.2)).astype(np.float64)
        env = syllable * one_pole_lowpass(phrase.astype(np.float32), 8.0, int(ctrl)) * rng.uniform(0.5, 1.0)
        mix = buzz * np.float32(0.6) + noise_bed(rng, n, pool) * np.float32(0.5)
        out += mix * block_ramp(env[None, :], _BLOCK, n)[0]
    return sosfilt(bandpass_sos(150.0, 1200.0, sr), out).astype(np.float32)


def indoor(
    scene: Scene, rng: np.random.Generator, door_rate: float, decimation: int
) -> tuple[np.ndarray, np.ndarray]:
    """(2, n) dry indoor ambience and the mono reverberation send at sample_rate / decimation.

    Babble and doors are in other rooms: they reach the robot through the reverberant field, which is
    band-limited, so they are synthesised directly at the reduced rate of the room's impulse response.
    """
    n, sr = scene.n, scene.sample_rate
    duration = n / sr
    fan = bed_pool(sr, (30, 80, 200, 600, 2000, 8000), (0, 2, -4, -14, -26, -42))
    mains = 50.0 if rng.uniform() < 0.5 else 60.0
    blade = rng.uniform(70.0, 120.0)
    hum = np.zeros(n, dtype=np.float32)
    for freq, amp in ((mains * 2, 0.08), (mains * 3, 0.04), (blade, 0.12)):
        kernels.sinusoid_into(hum, rng.uniform(), freq / sr, amp, False)
    dry = _diffuse(rng, n, fan, 0.3)
    dry *= np.float32(0.6)
    dry += hum[None, :]
    low_sr = sr // decimation
    low_n = -(-n // decimation)
    send = _babble(low_n, low_sr, rng, int(rng.integers(2, 5))) * np.float32(0.6)
    for t in _event_times(rng, door_rate, duration):
        add_at(send, int(t * low_sr), _door(rng, low_sr) * np.float32(2.5))
    return dry, send


def _chirp(rng: np.random.Generator, sr: int) -> np.ndarray:
    """One bird call: a short trill of frequency-modulated notes between 2 and 7 kHz."""
    notes = int(rng.integers(2, 7))
    note_len = rng.uniform(0.04, 0.15)
    gap = rng.uniform(0.02, 0.08)
    f_lo = min(rng.uniform(2000.0, 5000.0), 0.4 * sr)
    f_hi = min(f_lo * rng.uniform(1.1, 1.6), 0.45 * sr)
    m = int(note_len * sr)
    t = np.arange(m) / m
    freq = (
        f_lo + (f_hi - f_lo) * (t if rng.uniform() < 0.5 else 1.0 - t) + 150.0 * np.sin(2 * np.pi * 18.0 * t)
    )
    note = (np.sin(2 * np.pi * np.cumsum(freq) / sr) * np.sin(np.pi * t) ** 2).astype(np.float32)
    step = int((note_len + gap) * sr)
    out = np.zeros(step * notes + m, dtype=np.float32)
    for i in range(notes):
        add_at(out, i * step, note * np.float32(rng.uniform(0.6, 1.0)))
    return out


def outdoor(scene: Scene, rng: np.random.Generator, bird_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """(2, n) outdoor ambience (no reverberation send: free field, the send is empty)."""
    n, sr = scene.n, scene.sample_rate
    duration = n / sr
    nb = -(-n // _BLOCK) + 1
    ctrl = sr / _BLOCK
    gust = np.exp(0.7 * _slow_process(rng, nb, ctrl, 0.25)) * rng.uniform(0.6, 1.2)
    gust_env = block_ramp(gust[None, :], _BLOCK, n)[0]
    wind = bed_pool(sr, (20, 60, 200, 800, 3000), (0, -3, -12, -26, -44))
    out = _diffuse(rng, n, wind, 0.0) * (gust_env * np.float32(0.8))  # wind noise is incoherent
    rustle = bed_pool(sr, (500, 2000, 6000, 12000), (-12, 0, -4, -14))
    out += _diffuse(rng, n, rustle, 0.4) * (gust_env * np.float32(0.15))
    rumble = bed_pool(sr, (30, 100, 300, 1000, 4000), (0, 0, -6, -20, -38))
    swell = 0.6 + 0.4 * np.clip(_slow_process(rng, nb, ctrl, 0.05) + 1.0, 0.0, None)
    for t in _event_times(rng, 0.08, duration):  # vehicles passing by
        swell += rng.uniform(0.5, 1.5) * np.exp(
            -0.5 * ((np.arange(nb) / ctrl - t) / rng.uniform(1.0, 2.5)) ** 2
        )
    out += _diffuse(rng, n, rumble, 0.7) * (block_ramp(swell[None, :], _BLOCK, n)[0] * np.float32(0.5))
    for t in _event_times(rng, bird_rate, duration):
        azimuth = float(rng.uniform(0, 2 * np.pi))
        _event_into(out, scene, _chirp(rng, sr) * np.float32(rng.lognormal(-1.2, 0.5)), float(t), azimuth)
    return out, np.zeros(0, dtype=np.float32)
