"""Near-field environmental sounds: people and things sharing the robot's room or street.

Real robots work among people: footsteps, voices, dropped objects, carts, doors. These sounds reach the
robot's two microphones but not its IMU (nothing touches the robot), so a loud transient alone does not
mean a collision, and the robot's own silence is not the only quiet. They are environment: rendered with
the ambience (`AudioConfig.ambience`), never muted by `AudioConfig.muted`, and independent of `snr_db`:
every kind has its own physical level.

Events: a Poisson process of rate `AudioConfig.nearfield_rate_hz` (onsets uniform in time, also up to
`LEAD_S` before the clip, so a passer-by can already be under way when it starts); the kind is drawn with
the fixed weights `WEIGHTS` of the environment. Each event draws everything else from its own generator,
seeded from the stream's generator in schedule order (`schedule`), so the same seed gives the same
samples, and leaving out an event that cannot be heard changes no other.

Levels (`KINDS`), dB re 20 uPa at 1 m from the source, drawn uniformly; impulsive kinds: peak SPL (the
largest |pressure| of the event, i.e. of its loudest hit), continuous kinds: RMS SPL over the event:

    kind        environment level at 1 m            where                          what
    footsteps   both        68-78 dB peak (hard)    passing at 0.8-4 m, 1.2-1.6 m/s heel strikes at 1.7-2.1 Hz
    voice       both        58-68 dB RMS            standing at 1-4 m, mouth 1.6 m  1.5-5 s of speech
    drop        both        82-95 dB peak           1-6 m, on the floor             book, tool, box, bottle
    cart        indoor      65-75 dB RMS            passing at 0.8-4 m, 0.8-1.4 m/s rolling + rattle, 3-8 s
    robot       indoor      60-68 dB RMS            passing at 0.8-4 m, 0.4-1.2 m/s motor whine + rolling
    door        indoor      85-95 dB peak           2-6 m                           panel thud + latch
    bicycle     outdoor     60-70 dB RMS            passing at 1-5 m, 3-7 m/s       tyre hiss + freewheel
    car_door    outdoor     95-105 dB peak          4-10 m                          slam
    dog         outdoor     90-100 dB peak          5-15 m                          1-4 barks

Footsteps are on the robot's own floor (`Trace.surface`): tile, concrete and asphalt are hard (heel and
toe clicks); carpet is 12 dB softer and duller; grass is as soft, with a swish; gravel crunches
(`FOOTSTEP_SURFACE_DB`). Speech is conversational (about 60 dB RMS at 1 m) to raised (66-68 dB).

Propagation: every source has a position in the world, static or moving on a straight line at a constant
speed (`Emission`). At each microphone the pressure at time t is the source's 1 m signal emitted at the
retarded time t - r / c, times ((1 - D) + D cos theta) / max(r, `MIN_RANGE_M`): spherical spreading from
1 m, and the microphones' sub-cardioid directivity D (`spatial.DIRECTIVITY`, theta the angle off the
microphone's axis) as for every source of the renderer; r is the distance from the source at the retarded
time to the microphone at time t (`Trace.mic_pos`, world). The delay is read by third-order Lagrange
interpolation, so moving sources carry their Doppler shift.

Room: indoors with reverberation, every event also feeds the room (`reverb.Room`, the robot's room) with
the robot's send law, by sound power rather than by the level at the microphones (the reverberant field
does not depend on where the source is): `render_nearfield` returns the 1 m signals as the send, and
`render` scales them by (1 m / `spatial.REF_DISTANCE`) x 10^(room_send_db / 20), the robot's send
`room_send_db` being defined on its sound at the microphones, i.e. at about REF_DISTANCE (the
spatialiser's unit-gain distance). For a full-band send the reverberant field then equals a source's
direct sound at REF_DISTANCE x 10^(-room_send_db / 20) (2 m at the default -18 dB, the critical distance
of a room of a few hundred m^3 with RT60 0.5 s); `reverb.Room` gives sends band-limited below
sample_rate / 8 some 6-8 dB more reverberant power, to the robot's sound and these events alike. With
stems, an event's reverberation is part of the `nearfield` stem. Outdoors the events arrive dry (free
field).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import sosfilt

from synth_audio import kernels
from synth_audio.config import AudioConfig
from synth_audio.dsp import (
    add_at,
    bandpass_sos,
    bed_pool,
    block_wavetable,
    damped_modes,
    harmonic_table,
    noise_bed,
    normalise_rms,
    one_pole_lowpass,
    overlap_add_into,
    resonate,
    wavetable,
    white,
)
from synth_audio.impacts import MATERIALS, Material, struck_response
from synth_audio.spatial import DIRECTIVITY

GRAVITY = 9.81
"""Standard gravity, m/s^2 (drop speeds)."""
LEAD_S = 12.0
"""Events start up to this long before the clip (the longest passes last 12 s), s."""
MIN_RANGE_M = 0.5
"""Spherical spreading is capped at this distance (a source is never closer to a microphone), m."""
IMPULSIVE_MAX_S = 3.0
"""Longest impulsive event (barks, bounces and their ring), s."""
_CONTROL = 128
"""Samples between the control points of a propagation path (delays and gains are interpolated)."""
_SPAN = 16384
"""Samples per span of the reception (a multiple of _CONTROL; silent spans are skipped)."""
_QUIET = 256
"""Samples per block of the signal's silence map."""
_PAD = 4
"""Zeros padded on either side of a signal before interpolating it."""
_BLOCK = 64
"""Samples per control block of the synthesised tones' frequencies."""
_SINE = harmonic_table(np.array([1.0]), np.array([1.0]), np.array([0.0]))
"""One cycle of a sine, for `dsp.wavetable`."""


@dataclass(frozen=True)
class KindSpec:
    """Level and placement of one kind of near-field event."""

    level_db: tuple[float, float]
    """SPL at 1 m, dB re 20 uPa (uniform draw): peak for impulsive kinds, RMS over the event otherwise."""
    impulsive: bool
    """`level_db` is a peak level (hits); otherwise an RMS level (sustained sound)."""
    distance_m: tuple[float, float]
    """Horizontal distance from the robot (passers-by: at the closest approach), m."""
    height_m: float
    """Height of the sound above the floor, m."""
    speed_mps: tuple[float, float]
    """Speed of a passing source, m/s; (0, 0): the source stays where it is."""
    seconds: tuple[float, float]
    """Length of a sustained sound or of the audible pass, s; (0, 0): set by the hit's physics."""


KINDS: dict[str, KindSpec] = {
    "footsteps": KindSpec((68.0, 78.0), True, (0.8, 4.0), 0.0, (1.2, 1.6), (6.0, 12.0)),
    "voice": KindSpec((58.0, 68.0), False, (1.0, 4.0), 1.6, (0.0, 0.0), (1.5, 5.0)),
    "drop": KindSpec((82.0, 95.0), True, (1.0, 6.0), 0.0, (0.0, 0.0), (0.0, 0.0)),
    "cart": KindSpec((65.0, 75.0), False, (0.8, 4.0), 0.3, (0.8, 1.4), (3.0, 8.0)),
    "robot": KindSpec((60.0, 68.0), False, (0.8, 4.0), 0.15, (0.4, 1.2), (4.0, 10.0)),
    "door": KindSpec((85.0, 95.0), True, (2.0, 6.0), 1.0, (0.0, 0.0), (0.0, 0.0)),
    "bicycle": KindSpec((60.0, 70.0), False, (1.0, 5.0), 0.35, (3.0, 7.0), (3.0, 8.0)),
    "car_door": KindSpec((95.0, 105.0), True, (4.0, 10.0), 1.0, (0.0, 0.0), (0.0, 0.0)),
    "dog": KindSpec((90.0, 100.0), True, (5.0, 15.0), 0.5, (0.0, 0.0), (0.0, 0.0)),
}
"""Every kind of near-field event (levels, distances and speeds: see the module docstring)."""

WEIGHTS: dict[str, dict[str, float]] = {
    "indoor": {"footsteps": 0.32, "voice": 0.28, "drop": 0.10, "cart": 0.10, "robot": 0.08, "door": 0.12},
    "outdoor": {
        "footsteps": 0.32, "voice": 0.26, "drop": 0.07, "bicycle": 0.17, "car_door": 0.08, "dog": 0.10,
    },
}  # fmt: skip
"""Probability of each kind per environment: people walking and talking are the commonest near sounds; loud
hits (drops, doors, car doors, barks) are about one event in three to four."""

FOOTSTEP_SURFACE_DB: dict[str, float] = {
    "tile": 0.0,
    "concrete": 0.0,
    "asphalt": 0.0,
    "gravel": 0.0,
    "carpet": -12.0,
    "grass": -12.0,
}
"""Footstep level re a hard floor, dB, per surface (a soft floor spreads the heel's impact over ~10 ms)."""

_HARD_HEEL = Material(
    (160.0, 420.0, 950.0, 1900.0, 3600.0, 6200.0), (0.05, 0.035, 0.025, 0.018, 0.012, 0.008),
    (0.6, 1.0, 0.8, 0.55, 0.35, 0.2), 0.0003, 0.9, 1.0,
)  # fmt: skip
"""A shoe heel on a hard floor: a short, bright click."""
_SOFT_HEEL = Material(
    (55.0, 120.0, 240.0, 480.0), (0.05, 0.04, 0.03, 0.02), (1.0, 0.6, 0.25, 0.08), 0.006, 0.15, 1.0
)
"""A shoe heel on carpet or grass: a dull thud (long contact)."""
_BOOK = Material(
    (120.0, 290.0, 560.0, 1100.0), (0.04, 0.03, 0.02, 0.015), (1.0, 0.6, 0.35, 0.2), 0.003, 0.7, 1.0
)
"""A book landing flat: a slap."""
_BOTTLE = Material(
    (900.0, 2100.0, 3700.0, 5400.0, 7600.0), (0.35, 0.3, 0.22, 0.16, 0.1), (0.7, 1.0, 0.8, 0.5, 0.3),
    0.0003, 0.4, 1.0,
)  # fmt: skip
"""A glass bottle: high, ringing modes."""
_LATCH = Material(
    (1800.0, 3100.0, 4700.0, 6900.0), (0.05, 0.04, 0.03, 0.02), (1.0, 0.7, 0.5, 0.3), 0.0003, 1.0, 1.0
)
"""A door latch snapping into its strike plate."""
_CAR_DOOR = Material(
    (38.0, 75.0, 140.0, 260.0, 480.0, 900.0, 1700.0, 3100.0), (0.25, 0.2, 0.15, 0.12, 0.08, 0.06, 0.04, 0.03),
    (1.0, 0.9, 0.8, 0.6, 0.45, 0.3, 0.2, 0.12), 0.004, 0.5, 1.0,
)  # fmt: skip
"""A car door slamming: body and panel modes."""
_DROPPED: dict[str, tuple[Material, float]] = {
    "book": (_BOOK, 0.1),
    "tool": (MATERIALS["metal"], 0.4),
    "plastic_box": (MATERIALS["hard_plastic"], 0.35),
    "bottle": (_BOTTLE, 0.5),
}
"""Dropped objects: (modal bank, coefficient of restitution on the floor)."""
_VOWELS = (
    (730.0, 1090.0, 2440.0), (270.0, 2290.0, 3010.0), (300.0, 870.0, 2240.0), (530.0, 1840.0, 2480.0),
    (570.0, 840.0, 2410.0), (660.0, 1720.0, 2410.0), (490.0, 1350.0, 1690.0), (440.0, 1020.0, 2240.0),
)  # fmt: skip
"""First three formants of English vowels, Hz (Peterson & Barney 1952, adult male averages)."""


@dataclass(frozen=True)
class Event:
    """One scheduled near-field event."""

    kind: str
    """Kind (a key of `KINDS`)."""
    onset: float
    """Time its sound starts at the source, s (negative: it began before the clip)."""
    seed: int
    """Seed of the event's own generator (everything else about it)."""


@dataclass(frozen=True)
class Emission:
    """A sound at its source: the pressure 1 m away, and where the source is."""

    signal: np.ndarray
    """(m,) float32 pressure at 1 m from the source, digital units (full scale = 1)."""
    start: float
    """Emission time of signal[0], s."""
    origin: np.ndarray
    """(3,) world position of the source at `start`, m."""
    velocity: np.ndarray
    """(3,) world velocity of the source, m/s (zero: static)."""


@dataclass(frozen=True)
class Listener:
    """The robot's two microphones over time, in the world."""

    time: np.ndarray
    """(T,) increasing time stamps, s."""
    mic_pos: np.ndarray
    """(T, 2, 3) left and right microphone positions in the world, m."""

    def mics_at(self, t: np.ndarray) -> np.ndarray:
        """(len(t), 2, 3) microphone positions at times t (held outside the stamps)."""
        flat = np.asarray(self.mic_pos, dtype=np.float64).reshape(len(self.time), 6)
        out = np.stack([np.interp(t, self.time, flat[:, j]) for j in range(6)], axis=-1)
        return out.reshape(-1, 2, 3)


def schedule(rng: np.random.Generator, rate_hz: float, duration: float, environment: str) -> list[Event]:
    """Poisson events of rate `rate_hz` with onsets in [-LEAD_S, duration), kinds by `WEIGHTS`, sorted."""
    if rate_hz <= 0:
        return []
    weights = WEIGHTS[environment]
    names = tuple(weights)
    p = np.asarray([weights[k] for k in names], dtype=np.float64)
    count = int(rng.poisson(rate_hz * (duration + LEAD_S)))
    onsets = np.sort(rng.uniform(-LEAD_S, duration, count))
    kinds = rng.choice(len(names), size=count, p=p / p.sum())
    seeds = rng.integers(0, 2**63 - 1, size=count)
    return [Event(names[int(k)], float(t), int(s)) for t, k, s in zip(onsets, kinds, seeds, strict=True)]


def _fade(x: np.ndarray, sample_rate: int, seconds: float) -> np.ndarray:
    """Raised-cosine fade in and out (in place)."""
    m = min(int(seconds * sample_rate), x.size // 2)
    if m > 0:
        ramp = (0.5 - 0.5 * np.cos(np.pi * (np.arange(m) + 0.5) / m)).astype(np.float32)
        x[:m] *= ramp
        x[-m:] *= ramp[::-1]
    return x


def _peak_normalise(x: np.ndarray) -> np.ndarray:
    """x scaled to peak |x| = 1 in place (all-zero input unchanged)."""
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if peak > 0:
        x *= np.float32(1.0 / peak)
    return x


def _bandpass(x: np.ndarray, lo: float, hi: float, sample_rate: int) -> np.ndarray:
    hi = min(hi, 0.45 * sample_rate)
    return sosfilt(bandpass_sos(lo, hi, sample_rate), x).astype(np.float32)


def _slow(rng: np.random.Generator, n: int, rate: float, corner_hz: float) -> np.ndarray:
    """Unit-variance low-pass Gaussian process of n points at `rate` Hz."""
    x = one_pole_lowpass(rng.standard_normal(n + 64).astype(np.float32), corner_hz, rate)[64:]
    return (x - np.mean(x)) / max(float(np.std(x)), 1e-9)


def _block_times(n: int, sample_rate: int) -> np.ndarray:
    """Times of the `_BLOCK` boundaries covering n samples, s."""
    return np.arange(-(-n // _BLOCK) + 1, dtype=np.float64) * (_BLOCK / sample_rate)


def _tone(
    freq_hz: np.ndarray | float, n: int, sample_rate: int, table: np.ndarray, start: float = 0.0
) -> np.ndarray:
    """(n,) wavetable `table` (one cycle) read at the phase of a tone whose frequency is given at
    `_block_times`, starting at `start` cycles (`dsp.block_wavetable`)."""
    nb = -(-n // _BLOCK)
    f = np.broadcast_to(np.asarray(freq_hz, dtype=np.float64), (nb + 1,))
    cycles = start + np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * (_BLOCK / sample_rate))])
    return block_wavetable(cycles, _BLOCK, n, table)


def _hit(material: Material, speed: float, sample_rate: int, rng: np.random.Generator) -> np.ndarray:
    """Modal response of one hit (no robot body), peak 1."""
    return _peak_normalise(struck_response(material, 1.0, speed, sample_rate, rng, 1.0, body_gain=0.0))


def _crunch(rng: np.random.Generator, sample_rate: int) -> np.ndarray:
    """A foot on gravel: a 100-180 ms burst of grain clicks in noise, 0.7-7 kHz."""
    m = int(rng.uniform(0.1, 0.18) * sample_rate)
    t = np.arange(m) / sample_rate
    env = ((1.0 - np.exp(-t / 0.008)) * np.exp(-t / (0.35 * m / sample_rate))).astype(np.float32)
    grains = np.zeros(m, dtype=np.float32)
    k = int(rng.poisson(400.0 * m / sample_rate))
    np.add.at(grains, rng.integers(0, m, k), (rng.exponential(1.0, k) * rng.choice([-1.0, 1.0], k)))
    return _bandpass((grains + np.float32(0.3) * white(rng, m)) * env, 700.0, 7000.0, sample_rate)


def _footsteps(rng: np.random.Generator, sr: int, seconds: float, surface: str) -> np.ndarray:
    """A walker's footsteps over `seconds`, peak 1: heel strikes at 1.7-2.1 Hz, sounding as the floor."""
    rate = rng.uniform(1.7, 2.1)
    n = int(seconds * sr)
    out = np.zeros(n + int(0.3 * sr), dtype=np.float32)
    steps = np.arange(int(seconds * rate)) + rng.uniform(0.0, 1.0)
    times = steps / rate + rng.normal(0.0, 0.008, steps.size)
    hard = FOOTSTEP_SURFACE_DB.get(surface, 0.0) == 0.0 and surface != "gravel"
    for t in times:
        if not 0.0 <= t < seconds:
            continue
        amp = np.float32(10.0 ** (rng.normal(0.0, 1.5) / 20.0))
        at = int(t * sr)
        if surface == "gravel":
            add_at(out, at, _crunch(rng, sr) * amp)
        elif hard:
            add_at(out, at, _hit(_HARD_HEEL, rng.uniform(0.3, 0.6), sr, rng) * amp)
            toe = _hit(_HARD_HEEL, rng.uniform(0.15, 0.3), sr, rng) * np.float32(rng.uniform(0.2, 0.45))
            add_at(out, at + int(rng.uniform(0.06, 0.11) * sr), toe * amp)
        else:  # carpet, grass: a dull thud; grass adds the swish of the blades
            add_at(out, at, _hit(_SOFT_HEEL, rng.uniform(0.3, 0.6), sr, rng) * amp)
            if surface == "grass":
                m = int(rng.uniform(0.06, 0.12) * sr)
                swish = _bandpass(white(rng, m) * np.hanning(m).astype(np.float32), 300.0, 3000.0, sr)
                add_at(out, at, _peak_normalise(swish) * np.float32(0.4) * amp)
    return _peak_normalise(out)


def _voice(rng: np.random.Generator, sr: int, seconds: float) -> np.ndarray:
    """One talker's speech-like sound over `seconds`, unit RMS.

    A glottal source (harmonics of a 90-250 Hz pitch with 1/k amplitudes: -12 dB/octave glottal pulses
    with +6 dB/octave lip radiation) wandering in pitch and falling over each phrase, shaped by the
    three formants of a vowel drawn per syllable (4-8 syllables/s), under syllable envelopes, with
    fricative onsets and pauses between phrases.
    """
    n = int(seconds * sr)
    f0_mean = rng.uniform(90.0, 250.0)
    tract = 1.0 + 0.17 * float(np.clip((f0_mean - 110.0) / 100.0, 0.0, 1.0))  # shorter vocal tracts
    ctrl = 100.0
    nc = int(seconds * ctrl) + 2
    tc = np.arange(nc) / ctrl
    f0_c = f0_mean * np.exp(0.1 * _slow(rng, nc, ctrl, 2.0)) * (1.0 - 0.12 * (tc / max(seconds, 1e-3)))
    k = max(1, min(40, int(0.45 * sr / float(np.max(f0_c)))))
    ks = np.arange(1, k + 1, dtype=np.float64)
    table = harmonic_table(ks, 1.0 / ks, rng.uniform(0.0, 2.0 * np.pi, k))
    source = _tone(np.interp(_block_times(n, sr), tc, f0_c), n, sr, table)
    source += np.float32(0.05) * white(rng, n)  # breath
    out = np.zeros(n, dtype=np.float32)
    t = 0.0
    while t < seconds:
        length = rng.uniform(0.12, 0.25)
        a, b = int(t * sr), min(int((t + length) * sr), n)
        if b - a > 16:
            vowel = np.asarray(_VOWELS[int(rng.integers(len(_VOWELS)))])
            f1, f2, f3 = vowel * tract * rng.uniform(0.95, 1.05)
            seg = source[a:b]
            voiced = resonate(seg, f1, 0.06, sr) + 0.7 * resonate(seg, f2, 0.04, sr)
            voiced += 0.4 * resonate(seg, f3, 0.03, sr)
            x = (np.arange(b - a) + 0.5) / (b - a)
            voiced *= (np.sin(np.pi * x) ** 0.7).astype(np.float32) * np.float32(rng.uniform(0.4, 1.0))
            add_at(out, a, voiced)
            if rng.uniform() < 0.5:  # a fricative or plosive onset
                m = int(rng.uniform(0.03, 0.09) * sr)
                noise = white(rng, m)
                hiss = noise - one_pole_lowpass(noise, rng.uniform(2000.0, 4500.0), sr)
                hiss *= np.hanning(m).astype(np.float32) * np.float32(rng.uniform(0.1, 0.3))
                add_at(out, max(a - m // 2, 0), hiss)
        t += length
        if rng.uniform() < 0.15:  # a pause between phrases
            t += rng.uniform(0.15, 0.45)
    return normalise_rms(_fade(out, sr, 0.01))


def _drop(rng: np.random.Generator, sr: int) -> np.ndarray:
    """An object dropped on the floor from 0.4-1.5 m, bouncing until it rests, peak 1."""
    name = ("book", "tool", "plastic_box", "bottle")[int(rng.integers(4))]
    material, restitution = _DROPPED[name]
    v = float(np.sqrt(2.0 * GRAVITY * rng.uniform(0.4, 1.5)))
    out = np.zeros(int(IMPULSIVE_MAX_S * sr), dtype=np.float32)
    t = 0.0
    while v > 0.3 and t < IMPULSIVE_MAX_S - 0.5:
        add_at(out, int(t * sr), _hit(material, v, sr, rng) * np.float32(v))  # amplitude ~ momentum
        t += 2.0 * restitution * v / GRAVITY  # flight to the next bounce
        v *= restitution * rng.uniform(0.8, 1.0)
    return _peak_normalise(out)


def _door(rng: np.random.Generator, sr: int) -> np.ndarray:
    """A door in the same room closing: the panel's thud and the latch, peak 1."""
    out = _hit(MATERIALS["wood_door"], rng.uniform(0.5, 1.5), sr, rng)
    out = np.pad(out, (0, int(0.1 * sr)))
    latch = _hit(_LATCH, 1.0, sr, rng) * np.float32(rng.uniform(0.3, 0.7))
    add_at(out, int(rng.uniform(0.0, 0.03) * sr), latch)
    return _peak_normalise(out)


def _car_door(rng: np.random.Generator, sr: int) -> np.ndarray:
    """A car door slammed: body and panel thud and the latch's clack, peak 1."""
    out = np.pad(_hit(_CAR_DOOR, rng.uniform(1.0, 2.0), sr, rng), (0, int(0.1 * sr)))
    latch = _hit(_LATCH, 1.5, sr, rng) * np.float32(rng.uniform(0.2, 0.5))
    add_at(out, int(rng.uniform(0.0, 0.02) * sr), latch)
    return _peak_normalise(out)


def _dog(rng: np.random.Generator, sr: int) -> np.ndarray:
    """1-4 barks: harsh harmonic bursts (pitch 300-900 Hz, up then down) through two formants, peak 1."""
    f0_start = rng.uniform(300.0, 900.0)
    formants = (rng.uniform(900.0, 1600.0), rng.uniform(2000.0, 3200.0))
    out = np.zeros(int(IMPULSIVE_MAX_S * sr), dtype=np.float32)
    t = 0.0
    for _ in range(int(rng.integers(1, 5))):
        m = int(rng.uniform(0.1, 0.22) * sr)
        x = np.arange(m) / m
        f0 = f0_start * rng.uniform(0.9, 1.1) * (1.0 + 0.2 * np.sin(np.pi * x) - 0.3 * x)
        k = max(1, min(12, int(0.45 * sr / (1.3 * f0_start))))
        ks = np.arange(1, k + 1, dtype=np.float64)
        table = harmonic_table(ks, 1.0 / ks, rng.uniform(0.0, 2.0 * np.pi, k))
        cycles = np.cumsum(f0) / sr
        src = wavetable((cycles - np.floor(cycles)).astype(np.float32), table)
        src += np.float32(0.4) * white(rng, m)
        tt = np.arange(m) / sr
        src *= ((1.0 - np.exp(-tt / 0.004)) * np.exp(-tt / (0.35 * m / sr))).astype(np.float32)
        bark = resonate(src, formants[0], 0.08, sr) + 0.6 * resonate(src, formants[1], 0.06, sr)
        add_at(out, int(t * sr), bark * np.float32(rng.uniform(0.7, 1.0)))
        t += m / sr + rng.uniform(0.15, 0.45)
    return _peak_normalise(out)


def _cart(rng: np.random.Generator, sr: int, seconds: float, speed: float) -> np.ndarray:
    """A cart or trolley rolling by: castor rolling noise, out-of-round wheel beat and rattle, unit RMS."""
    n = int(seconds * sr)
    roll = noise_bed(
        rng, n, bed_pool(sr, (80.0, 300.0, 1200.0, 4000.0, 12000.0), (-8.0, 0.0, -3.0, -12.0, -24.0))
    )
    wheel_hz = speed / (2.0 * np.pi * rng.uniform(0.04, 0.06))
    beat = _tone(wheel_hz, n, sr, _SINE, rng.uniform())
    beat *= np.float32(0.35)
    beat += np.float32(1.0)
    roll *= beat
    k = int(rng.poisson(rng.uniform(8.0, 25.0) * seconds))
    modes = np.array([480.0, 1150.0, 2300.0, 3700.0, 5200.0]) * rng.uniform(0.85, 1.15)
    t60 = np.array([0.06, 0.05, 0.04, 0.03, 0.02])
    weights = np.array([0.6, 1.0, 0.8, 0.5, 0.3])
    kernel = damped_modes(modes, t60, weights, rng.uniform(0.0, 2.0 * np.pi, 5), sr, int(0.08 * sr))
    rattle = np.zeros(n, dtype=np.float32)
    overlap_add_into(rattle, rng.integers(0, max(n, 1), k), rng.exponential(1.0, k), kernel)
    out = roll + normalise_rms(rattle) * np.float32(10.0 ** (rng.uniform(-6.0, 0.0) / 20.0))
    return normalise_rms(_fade(out, sr, 0.5))


def _robot(rng: np.random.Generator, sr: int, seconds: float, speed: float) -> np.ndarray:
    """Another robot rolling by: motor, torque-ripple and gear-mesh tones, PWM whine, rolling; unit RMS."""
    n = int(seconds * sr)
    shaft_hz = speed / (2.0 * np.pi * rng.uniform(0.05, 0.09)) * rng.uniform(20.0, 40.0)
    poles, teeth = int(rng.integers(2, 5)), int(rng.integers(10, 19))
    ks = np.array([1.0, 2.0, 2.0 * poles, 4.0 * poles, teeth, 2.0 * teeth])
    amps = np.array([0.2, 0.25, 0.5, 0.2, 0.45, 0.2])
    keep = ks * shaft_hz * 1.05 < 0.45 * sr
    table = harmonic_table(ks[keep], amps[keep], rng.uniform(0.0, 2.0 * np.pi, int(np.sum(keep))))
    nc = int(seconds * 100.0) + 2
    wobble = np.interp(_block_times(n, sr), np.arange(nc) / 100.0, 0.01 * _slow(rng, nc, 100.0, 1.0))
    out = normalise_rms(_tone(shaft_hz * (1.0 + wobble), n, sr, table))
    pwm_hz = rng.uniform(8000.0, 20000.0)
    if pwm_hz < 0.45 * sr:
        pwm = _tone(pwm_hz, n, sr, _SINE)
        pwm *= np.float32(0.25)
        out += pwm
    roll = noise_bed(
        rng, n, bed_pool(sr, (100.0, 400.0, 1500.0, 4000.0, 10000.0), (-10.0, -4.0, 0.0, -4.0, -14.0))
    )
    out += roll * np.float32(10.0 ** (rng.uniform(-6.0, 0.0) / 20.0))
    return normalise_rms(_fade(out, sr, 0.5))


def _bicycle(rng: np.random.Generator, sr: int, seconds: float, speed: float) -> np.ndarray:
    """A bicycle or scooter rolling by: tyre hiss and, while coasting, freewheel ticking; unit RMS."""
    n = int(seconds * sr)
    hiss = noise_bed(
        rng, n, bed_pool(sr, (200.0, 800.0, 2500.0, 6000.0, 14000.0), (-14.0, -6.0, 0.0, -4.0, -16.0))
    )
    tick_hz = speed / (2.0 * np.pi * 0.34) * float(rng.choice([18, 24, 36]))  # wheel rev/s x pawl points
    pos = np.arange(0.0, n, sr / tick_hz) + rng.uniform(0.0, sr / tick_hz)
    pos = pos + rng.normal(0.0, 0.03 * sr / tick_hz, pos.size)
    # Coasting and pedalling alternate every 0.8-3 s; only coasting ticks.
    edges = np.cumsum(rng.uniform(0.8, 3.0, int(seconds / 0.8) + 2)) * sr
    coasting = (np.searchsorted(edges, pos) % 2 == int(rng.integers(2))) & (pos >= 0) & (pos < n)
    kernel = damped_modes(np.array([2800.0, 4600.0, 7200.0]) * rng.uniform(0.9, 1.1),
                          np.array([0.012, 0.009, 0.006]), np.array([1.0, 0.7, 0.4]),
                          rng.uniform(0.0, 2.0 * np.pi, 3), sr, int(0.015 * sr))  # fmt: skip
    ticks = np.zeros(n, dtype=np.float32)
    amps = rng.lognormal(0.0, 0.3, int(np.sum(coasting)))
    overlap_add_into(ticks, pos[coasting].astype(np.int64), amps, kernel)
    out = hiss + normalise_rms(ticks) * np.float32(10.0 ** (rng.uniform(-8.0, -2.0) / 20.0))
    return normalise_rms(_fade(out, sr, 0.5))


def synthesise(kind: str, rng: np.random.Generator, sample_rate: int, seconds: float, speed: float,
               surface: str) -> np.ndarray:  # fmt: skip
    """Mono sound of one event at 1 m, float32: peak 1 for impulsive kinds, unit RMS for sustained ones."""
    if kind == "footsteps":
        return _footsteps(rng, sample_rate, seconds, surface)
    if kind == "voice":
        return _voice(rng, sample_rate, seconds)
    if kind == "drop":
        return _drop(rng, sample_rate)
    if kind == "cart":
        return _cart(rng, sample_rate, seconds, speed)
    if kind == "robot":
        return _robot(rng, sample_rate, seconds, speed)
    if kind == "door":
        return _door(rng, sample_rate)
    if kind == "bicycle":
        return _bicycle(rng, sample_rate, seconds, speed)
    if kind == "car_door":
        return _car_door(rng, sample_rate)
    if kind == "dog":
        return _dog(rng, sample_rate)
    raise ValueError(f"unknown near-field kind {kind!r}; allowed: {', '.join(KINDS)}")


def plan(
    event: Event, listener: Listener, surface: str, config: AudioConfig, duration: float
) -> Emission | None:
    """Place and synthesise one event (None if it ends before the clip starts)."""
    spec = KINDS[event.kind]
    rng = np.random.default_rng(event.seed)
    seconds = float(rng.uniform(*spec.seconds)) if spec.seconds[1] > 0 else IMPULSIVE_MAX_S
    if event.onset + seconds < 0.0:
        return None
    distance = float(rng.uniform(*spec.distance_m))
    heading = float(rng.uniform(0.0, 2.0 * np.pi))
    level = float(rng.uniform(*spec.level_db))
    if event.kind == "footsteps":
        level += FOOTSTEP_SURFACE_DB.get(surface, 0.0)
    moving = spec.speed_mps[1] > 0
    speed = float(rng.uniform(*spec.speed_mps)) if moving else 0.0
    if moving:  # a straight pass, closest to the robot a little before or after its middle
        closest = event.onset + seconds * float(rng.uniform(0.35, 0.65))
        centre = np.mean(listener.mics_at(np.array([min(max(closest, 0.0), duration)]))[0], axis=0)
        side = float(rng.choice([-1.0, 1.0]))
        along = np.array([np.cos(heading), np.sin(heading), 0.0])
        across = side * np.array([-np.sin(heading), np.cos(heading), 0.0])
        point = np.array([centre[0], centre[1], spec.height_m]) + distance * across
        origin = point - along * speed * (closest - event.onset)
        velocity = along * speed
    else:
        centre = np.mean(listener.mics_at(np.array([min(max(event.onset, 0.0), duration)]))[0], axis=0)
        origin = np.array([centre[0] + distance * np.cos(heading), centre[1] + distance * np.sin(heading),
                           spec.height_m])  # fmt: skip
        velocity = np.zeros(3)
    unit = synthesise(event.kind, rng, config.sample_rate, seconds, speed, surface)
    if spec.impulsive:  # hits ring out before IMPULSIVE_MAX_S
        unit = unit[: unit.size - int(np.argmax(unit[::-1] != 0))] if np.any(unit) else unit[:0]
    signal = unit * np.float32(config.spl_amplitude(level))
    return Emission(signal=signal, start=event.onset, origin=origin, velocity=velocity)


def _paths(
    emission: Emission, listener: Listener, ctrl_t: np.ndarray, speed_of_sound: float
) -> tuple[np.ndarray, np.ndarray]:
    """Retarded emission times (2, C) and gains (2, C) at the microphones at reception times `ctrl_t`.

    Two fixed-point steps for the retarded time: exact for a static source; for a moving one the residual is
    (v / c)^2 of the delay. Gain: ((1 - D) + D cos theta) / max(r, MIN_RANGE_M).
    """
    mics = listener.mics_at(ctrl_t)  # (C, 2, 3)
    axis = mics[:, 0] - mics[:, 1]
    axis /= np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), 1e-9)
    taus, gains = [], []
    for ch, sign in ((0, 1.0), (1, -1.0)):
        m = mics[:, ch]
        tau = ctrl_t.copy()
        for _ in range(2):
            src = emission.origin + emission.velocity * (tau - emission.start)[:, None]
            tau = ctrl_t - np.linalg.norm(src - m, axis=-1) / speed_of_sound
        rel = emission.origin + emission.velocity * (tau - emission.start)[:, None] - m
        r = np.linalg.norm(rel, axis=-1)
        cos = sign * np.sum(rel * axis, axis=-1) / np.maximum(r, 1e-9)
        taus.append(tau)
        gains.append(((1.0 - DIRECTIVITY) + DIRECTIVITY * cos) / np.maximum(r, MIN_RANGE_M))
    return np.stack(taus), np.stack(gains)


def receive_into(
    out: np.ndarray, emission: Emission, listener: Listener, sample_rate: int, speed_of_sound: float
) -> tuple[int, float]:
    """Add an emission as heard at the two microphones to the (2, n) `out` (in place).

    Retarded times and gains are computed every `_CONTROL` samples (`_paths`) and ramped linearly in
    between; the signal is read there by Lagrange interpolation (`kernels.lagrange_read`), span by span,
    skipping spans whose part of the signal is silent (footsteps, bounces and barks are mostly silence).

    Returns:
        (sample at which the sound first reaches the robot, distance then, m): where the room send goes.
    """
    sig = emission.signal
    n = out.shape[1]
    sr = float(sample_rate)
    c = float(speed_of_sound)
    t0 = emission.start
    t1 = t0 + sig.size / sr
    p_end = emission.origin + emission.velocity * (t1 - t0)
    span = listener.mics_at(np.linspace(max(t0, 0.0), max(t1, 0.0), 16)).reshape(-1, 3)
    reach = max(float(np.max(np.linalg.norm(span - emission.origin, axis=-1))),
                float(np.max(np.linalg.norm(span - p_end, axis=-1))))  # fmt: skip
    r0 = float(np.min(np.linalg.norm(span[:2] - emission.origin, axis=-1)))
    first = round((t0 + r0 / c) * sr)
    a = max(int(np.floor(t0 * sr)), 0)
    b = min(int(np.ceil((t1 + reach / c) * sr)) + 4, n)
    if b <= a or sig.size == 0:
        return first, r0
    nb = -(-(b - a) // _CONTROL)
    ctrl = a + _CONTROL * np.arange(nb + 1, dtype=np.float64)
    taus, gains = _paths(emission, listener, ctrl / sr, c)
    positions = (taus - t0) * sr  # (2, nb + 1) emission sample read at each control point
    padded = np.concatenate([np.zeros(_PAD, np.float32), sig.astype(np.float32, copy=False),
                             np.zeros(_PAD, np.float32)])  # fmt: skip
    # Silence map: live[q] - live[p] = blocks of _QUIET samples in p..q-1 that hold any sound.
    blocks = -(-sig.size // _QUIET)
    loud = np.abs(np.pad(sig, (0, blocks * _QUIET - sig.size))).reshape(blocks, _QUIET).max(axis=1) > 0
    live = np.concatenate([[0], np.cumsum(loud)])
    step = _SPAN // _CONTROL
    for ch in range(2):
        pos, gain = positions[ch], gains[ch]
        for k0 in range(0, nb, step):
            k1 = min(k0 + step, nb)
            lo = int(np.floor(pos[k0])) - 2
            hi = int(np.ceil(pos[k1])) + 2
            q0 = min(max(lo // _QUIET, 0), blocks)
            q1 = min(max(hi // _QUIET + 1, 0), blocks)
            if live[q1] == live[q0]:  # silent, or outside the signal
                continue
            s0 = a + k0 * _CONTROL
            s1 = min(a + k1 * _CONTROL, b)
            kernels.lagrange_read(padded, _PAD, pos[k0 : k1 + 1], gain[k0 : k1 + 1], _CONTROL, out[ch, s0:s1])
    return first, r0


def render_nearfield(
    listener: Listener,
    environment: str,
    surface: str,
    n: int,
    config: AudioConfig,
    rng: np.random.Generator,
    with_send: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """(2, n) near-field events at the microphones and their mono room send (n,), at 1 m (empty if not asked).

    `render` scales the send by (1 m / spatial.REF_DISTANCE) x 10^(room_send_db / 20) (see the module).
    """
    sr = config.sample_rate
    duration = n / sr
    out = np.zeros((2, n), dtype=np.float32)
    send = np.zeros(n if with_send else 0, dtype=np.float32)
    for event in schedule(rng, config.nearfield_rate_hz, duration, environment):
        emission = plan(event, listener, surface, config, duration)
        if emission is None:
            continue
        first, _ = receive_into(out, emission, listener, sr, config.speed_of_sound)
        if with_send:
            add_at(send, first, emission.signal)
    return out, send
