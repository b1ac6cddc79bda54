"""Collision impacts by modal synthesis per material, and scraping during sustained contact.

The excitation is a Hertzian half-sine force pulse: its area is the contact impulse and its length shrinks
with the approach speed (tau ~ v^-1/5), so harder and faster hits excite higher modes. A collision goes
through the robot's rubber bumper, in series with the struck material: the contact lasts
sqrt(tau_bumper^2 + tau_material^2) (`collision_contact_time`), so a hit is a thud with the struck
object's low modes, not a click. The response starts at the event's audio sample, not spread over
MuJoCo's soft-contact force curve.

Level law (physical, never set by a detector's score): the chassis and the struck surface ring in
proportion to the momentum the hit exchanges (linear acoustics), on one scale for collisions, benign
bumps and the impulsive wheel faults (`IMPACT_SCALE`). Measured at the microphones
(`tests/synth_audio/level_kit.py`), a 20 kg robot meeting a plaster wall at 0.7 m/s peaks at about
100 dB SPL, a wheel crossing a 15 mm threshold at 1.3 m/s at about 90 dB SPL (a clear clack over the
drive's 68-75 dB), a pedestrian met at 0.7 m/s at about 80 dB.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import fftconvolve

from synth_audio.dsp import damped_modes, modal_length, one_pole_lowpass, white


@dataclass(frozen=True)
class Material:
    """A modal bank and contact character for one impact material."""

    freqs: tuple[float, ...]
    """Mode frequencies, Hz."""
    t60: tuple[float, ...]
    """60 dB decay time of each mode, s."""
    amps: tuple[float, ...]
    """Relative mode amplitudes."""
    contact_s: float
    """Contact (force pulse) duration at 1 m/s approach speed, s."""
    click: float
    """Level of the broadband contact click relative to the modes."""
    gain: float
    """Overall loudness of the material per unit impulse."""


MATERIALS: dict[str, Material] = {
    "plaster": Material((95, 180, 310, 520, 870, 1400), (0.18, 0.14, 0.1, 0.08, 0.05, 0.03),
                        (1.0, 0.8, 0.6, 0.45, 0.3, 0.15), 0.002, 0.3, 1.0),
    "wood_door": Material((70, 140, 260, 420, 690, 1100, 1900), (0.35, 0.3, 0.25, 0.2, 0.15, 0.1, 0.06),
                          (1.0, 0.9, 0.8, 0.6, 0.45, 0.3, 0.15), 0.0015, 0.35, 1.2),
    "concrete": Material((400, 950, 1800, 3200, 5200), (0.04, 0.03, 0.025, 0.02, 0.015),
                         (0.6, 0.8, 0.7, 0.5, 0.3), 0.0006, 0.8, 0.9),
    "wood": Material((180, 410, 780, 1300, 2100, 3300), (0.2, 0.16, 0.12, 0.09, 0.06, 0.04),
                     (0.8, 1.0, 0.8, 0.6, 0.4, 0.2), 0.001, 0.4, 1.0),
    "metal": Material((620, 1480, 2650, 4100, 5900, 8100), (1.1, 0.9, 0.7, 0.5, 0.35, 0.25),
                      (0.7, 1.0, 0.8, 0.6, 0.4, 0.25), 0.0004, 0.3, 0.7),
    "cardboard": Material((110, 260, 480, 900), (0.05, 0.04, 0.03, 0.02), (1.0, 0.7, 0.4, 0.2),
                          0.004, 0.5, 0.9),
    "hard_plastic": Material((350, 820, 1500, 2600, 4200), (0.14, 0.11, 0.08, 0.06, 0.04),
                             (0.8, 1.0, 0.7, 0.5, 0.3), 0.0008, 0.45, 1.0),
    "soft_body": Material((60, 130, 260), (0.04, 0.03, 0.02), (1.0, 0.5, 0.2), 0.015, 0.2, 0.3),
    "rubber": Material((90, 240, 520), (0.04, 0.03, 0.02), (1.0, 0.6, 0.3), 0.006, 0.2, 1.0),
}  # fmt: skip
"""Every material in `sim.vocab.MATERIALS`. A soft body (a person) yields and barely rings: its gain is a
fraction of a rigid obstacle's, and its contact is long."""

BUMPER_CONTACT_S = 0.006
"""Contact time of the robot's rubber bumper at 1 m/s, s: in series with every struck material."""

ROBOT_BODY = Material((230, 640, 1450, 2900), (0.1, 0.08, 0.05, 0.04), (0.5, 1.0, 0.7, 0.35), 0.002, 0.0, 0.5)
"""The robot's own chassis, excited by every hit (collisions and benign bumps alike)."""

IMPACT_SCALE = 3.5
"""Modal amplitude per N s of impact impulse, relative to the nominal per-wheel rolling level.

One scale for collisions, benign transients and impulsive wheel faults alike: the robot's chassis and the
struck surface ring in proportion to the momentum the hit exchanges (linear acoustics). The resulting
levels at the microphones are in the module docstring.
"""
ELASTIC_LIMIT = 2.0
"""Most momentum a hit can exchange, in units of reduced mass x approach speed (a fully elastic bounce)."""


def impact_impulse(
    impulse: float, normal_speed: float, robot_mass: float, obstacle_mass: float | None
) -> float:
    """The impulsive part of a contact's impulse, N s: what makes the bang.

    MuJoCo's contact impulse integrates the whole contact; if the robot keeps pushing after the hit, the
    push adds impulse without adding impact. A hit exchanges at most `ELASTIC_LIMIT` x mu x v, with mu the
    reduced mass of the robot and the obstacle (the robot's mass for fixed obstacles, `obstacle_mass`
    None) and v the approach speed; the rest of the impulse is pushing, which scrapes.
    """
    mu = robot_mass if obstacle_mass is None else robot_mass * obstacle_mass / (robot_mass + obstacle_mass)
    return float(min(max(float(impulse), 0.0), ELASTIC_LIMIT * mu * abs(float(normal_speed))))


SCRAPE_SCALE = 0.35
"""Scrape amplitude per sqrt(mean contact force in N), relative to the same level."""
MIN_SCRAPE_S = 0.05
"""Contacts longer than this scrape, s."""


def contact_time(material: Material, normal_speed: float) -> float:
    """Hertzian contact time: shorter for faster approach (tau ~ v^-1/5), clipped to 0.2..30 ms."""
    v = max(abs(float(normal_speed)), 0.02)
    return float(np.clip(material.contact_s * v ** (-0.2), 2e-4, 0.03))


def collision_contact_time(material: Material, normal_speed: float) -> float:
    """Contact time of the robot's bumper against `material`: the two compliances in series, s."""
    v = max(abs(float(normal_speed)), 0.02)
    bumper = BUMPER_CONTACT_S * v ** (-0.2)
    return float(np.clip(np.hypot(bumper, contact_time(material, normal_speed)), 2e-4, 0.03))


def pulse_spectrum(freqs: np.ndarray, tau: float) -> np.ndarray:
    """Smoothed magnitude spectrum of a unit-area half-sine pulse of length tau (1 at DC)."""
    return 1.0 / np.sqrt(1.0 + (1.6 * np.asarray(freqs) * tau) ** 4)


def struck_response(
    material: Material,
    impulse: float,
    normal_speed: float,
    sample_rate: int,
    rng: np.random.Generator,
    scale: float,
    body_gain: float = 1.0,
    tau: float | None = None,
) -> np.ndarray:
    """Mono response of `material` (and the robot body) to one hit, starting at sample 0.

    `tau` is the contact time (default: `material`'s own, `contact_time`).
    """
    tau = contact_time(material, normal_speed) if tau is None else float(tau)
    banks = [material, ROBOT_BODY] if body_gain > 0 else [material]
    freqs = np.concatenate([np.asarray(b.freqs) for b in banks])
    t60 = np.concatenate([np.asarray(b.t60) for b in banks])
    amps = np.concatenate([np.asarray(b.amps) * (b.gain if b is ROBOT_BODY else 1.0) for b in banks])
    if body_gain != 1.0 and len(banks) == 2:
        amps[len(material.freqs) :] *= body_gain
    freqs = freqs * (1.0 + 0.03 * rng.standard_normal(freqs.size))
    amps = amps * pulse_spectrum(freqs, tau) * 10.0 ** (rng.normal(0.0, 1.5, freqs.size) / 20.0)
    phases = rng.uniform(0.0, 2.0 * np.pi, freqs.size)
    length = modal_length(t60, sample_rate)
    out = damped_modes(freqs, t60, amps, phases, sample_rate, length)
    click_len = max(int(4 * tau * sample_rate), 4)
    if click_len > out.size:  # a soft, slow contact outlasts the modal ring
        out = np.pad(out, (0, click_len - out.size))
    env = np.exp(-np.arange(click_len) / (tau * sample_rate)).astype(np.float32)
    click = one_pole_lowpass(white(rng, click_len) * env, 0.6 / tau, sample_rate)
    out[:click_len] += np.float32(material.click) * click
    rise = max(min(int(0.5 * tau * sample_rate), int(0.001 * sample_rate)), 1)
    out[:rise] *= np.sin(0.5 * np.pi * (np.arange(rise) + 1) / rise).astype(np.float32) ** 2
    out *= np.float32(scale * max(float(impulse), 0.0))
    return out


def impact(
    material_name: str, impulse: float, normal_speed: float, sample_rate: int, rng: np.random.Generator
) -> np.ndarray:
    """Mono sound of one collision at the contact point, float32, starting at the contact instant.

    `impulse` is the impulsive part of the contact (`impact_impulse`), N s; the amplitude is linear in it.
    """
    material = MATERIALS[material_name]
    tau = collision_contact_time(material, normal_speed)
    return struck_response(
        material, impulse, normal_speed, sample_rate, rng, IMPACT_SCALE * material.gain, tau=tau
    )


def scrape(
    material_name: str,
    impulse: float,
    duration: float,
    slide_speed: float,
    sample_rate: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Mono scraping noise of a sustained contact, coloured by the material's modes (empty if short)."""
    if duration < MIN_SCRAPE_S:
        return np.zeros(0, dtype=np.float32)
    material = MATERIALS[material_name]
    n = int(duration * sample_rate)
    force = max(float(impulse), 0.0) / duration
    level = SCRAPE_SCALE * material.gain * np.sqrt(force) * min(abs(float(slide_speed)) + 0.05, 1.0) ** 0.8
    # Stick-slip roughness: a slowly wandering, occasionally catching envelope.
    slow = one_pole_lowpass(white(rng, n), 25.0, sample_rate)
    slow /= np.float32(max(float(np.std(slow)), 1e-9))
    env = np.clip(1.0 + 0.5 * slow, 0.1, None).astype(np.float32)
    fade = min(int(0.01 * sample_rate), n // 2)
    if fade > 0:
        ramp = np.linspace(0.0, 1.0, fade, dtype=np.float32)
        env[:fade] *= ramp
        env[-fade:] *= ramp[::-1]
    ir_len = int(0.05 * sample_rate)
    ir = damped_modes(
        np.asarray(material.freqs), np.minimum(np.asarray(material.t60), 0.05), np.asarray(material.amps),
        rng.uniform(0, 2 * np.pi, len(material.freqs)), sample_rate, ir_len,
    )  # fmt: skip
    ir /= np.float32(max(float(np.sqrt(np.sum(ir**2))), 1e-9))
    out = fftconvolve(white(rng, n) * env, ir)[:n].astype(np.float32)
    return out * np.float32(level)
