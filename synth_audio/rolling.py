"""Tyre-floor rolling noise shaped by surface and speed, tread-pitch tone, grain and chassis rattle."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synth_audio import kernels
from synth_audio.drive import BLOCK, NOMINAL_SPEED, Drive
from synth_audio.dsp import damped_modes, harmonic_table, overlap_add_into, white


@dataclass(frozen=True)
class Surface:
    """Acoustic character of a floor surface."""

    points_hz: tuple[float, ...]
    """Frequencies of the rolling-noise spectral shape, Hz."""
    gains_db: tuple[float, ...]
    """Rolling-noise spectral shape at those frequencies, dB."""
    level: float
    """Rolling-noise RMS at the nominal speed."""
    tread: float
    """Tread-pitch tone amplitude at the nominal speed."""
    grain_per_m: float
    """Grain clicks (pebbles, twigs, grit) per metre rolled per wheel."""
    grain_level: float
    """Grain click amplitude at the nominal speed."""
    rattle_per_m: float
    """Chassis/caster rattle events per metre travelled."""


SURFACES: dict[str, Surface] = {
    "tile": Surface((100, 400, 1500, 4000, 10000), (-10, -4, 0, -4, -14), 0.40, 0.22, 0.0, 0.0, 5.0),
    "carpet": Surface((100, 300, 800, 2500, 8000), (-4, 0, -6, -18, -30), 0.28, 0.05, 0.0, 0.0, 1.5),
    "concrete": Surface((100, 500, 2000, 5000, 12000), (-8, -2, 0, -6, -16), 0.50, 0.15, 15.0, 0.12, 7.0),
    "asphalt": Surface((80, 400, 1500, 5000, 12000), (-4, 0, -2, -8, -18), 0.65, 0.12, 40.0, 0.12, 9.0),
    "gravel": Surface((100, 600, 2000, 6000, 12000), (-8, -2, 0, -2, -10), 0.85, 0.04, 300.0, 0.3, 20.0),
    "grass": Surface((60, 200, 800, 3000, 10000), (-2, 0, -6, -14, -24), 0.35, 0.02, 25.0, 0.08, 10.0),
}
"""Every surface in `sim.vocab.SURFACES`."""

_CHASSIS_HZ = np.array([230.0, 640.0, 1450.0, 2900.0])
_CHASSIS_T60 = np.array([0.08, 0.06, 0.04, 0.03])
_CHASSIS_AMP = np.array([0.5, 1.0, 0.7, 0.35])
_RATTLE_LEVEL = 0.12
_TREAD_TABLE = harmonic_table(
    np.array([1.0, 2.0, 3.0]), np.array([1.0, 0.4, 0.15]), np.array([0.0, 1.1, 2.3])
)
_NO_TABLE = np.zeros(0, dtype=np.float32)


def speed_law(drive: Drive, wheel: int, exponent: float) -> np.ndarray:
    """(v / nominal)^exponent at block boundaries, v capped at 5x nominal."""
    return np.minimum(drive.speed_mps[wheel] / NOMINAL_SPEED, 5.0) ** exponent


def rolling_wheel(
    drive: Drive,
    wheel: int,
    surface: Surface,
    noise: np.ndarray,
    rng: np.random.Generator,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Mono rolling sound of one wheel (shaped noise, tread tone, grain clicks), added into `out` if given."""
    robot = drive.robot
    if out is None:
        out = np.zeros(drive.n, dtype=np.float32)
    noise_env = surface.level * speed_law(drive, wheel, 1.2)
    tread_env = surface.tread * speed_law(drive, wheel, 1.0)
    table = _TREAD_TABLE if surface.tread > 0 else _NO_TABLE
    cycles = drive.cycles[wheel] * float(robot.tread_blocks)
    for span in drive.spans():
        a, b = span
        kernels.rolling_mix(
            out[a:b], noise[a:b], drive.boundaries(noise_env, span), drive.boundaries(cycles, span), table,
            drive.boundaries(tread_env, span), BLOCK,
        )  # fmt: skip
    if surface.grain_per_m > 0:
        distance = drive.speed_mps[wheel][:-1] * np.diff(drive.block_time)
        pos, amp = poisson_events(rng, distance * surface.grain_per_m, drive.n)
        level = speed_law(drive, wheel, 0.5)
        amp *= surface.grain_level * np.interp(pos / drive.sample_rate, drive.block_time, level)
        click_len = max(int(0.003 * drive.sample_rate), 8)
        click = white(rng, click_len) * np.exp(-np.arange(click_len) / (0.0006 * drive.sample_rate))
        click -= np.float32(np.mean(click))
        overlap_add_into(out, pos, amp, click.astype(np.float32))
    return out


def poisson_events(rng: np.random.Generator, expected: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Random event sample positions with `expected[b]` events in block b; amplitudes exponential(1)."""
    counts = rng.poisson(np.maximum(expected, 0.0))
    block = np.repeat(np.arange(expected.size), counts)
    size = n / max(expected.size, 1)
    pos = np.floor((block + rng.random(block.size)) * size).astype(np.int64)
    keep = pos < n
    return pos[keep], rng.exponential(1.0, block.size)[keep]


def chassis_rattle(drive: Drive, surface: Surface, rng: np.random.Generator) -> np.ndarray:
    """Mono chassis and caster rattle excited by the floor, rate proportional to distance travelled."""
    sr = drive.sample_rate
    mean_speed = np.mean(drive.speed_mps, axis=0)
    distance = mean_speed[:-1] * np.diff(drive.block_time)
    pos, amp = poisson_events(rng, distance * surface.rattle_per_m, drive.n)
    if pos.size == 0:
        return np.zeros(drive.n, dtype=np.float32)
    level = np.minimum(mean_speed / NOMINAL_SPEED, 3.0) ** 0.7
    amp *= _RATTLE_LEVEL * np.interp(pos / sr, drive.block_time, level)
    length = int(0.12 * sr)
    kernel = damped_modes(_CHASSIS_HZ, _CHASSIS_T60, _CHASSIS_AMP, np.zeros(4), sr, length)
    out = np.zeros(drive.n, dtype=np.float32)
    overlap_add_into(out, pos, amp, kernel)
    return out
