"""Per-window scalars the audit's shortcut probes score: behaviour, naive audio levels, IMU peaks.

Each function maps the raw signals of one episode and the start times of its 2 s windows to one number
per window. None of them learns anything: if one of them separates anomalies from normal driving, the
benchmark can be solved without hearing or feeling the anomaly itself.
"""

from __future__ import annotations

import numpy as np

from msvdd.contract import WINDOW_S
from synth_audio.faults import band_power

REVERSE_SPEED = 0.05
"""Forward speed below minus this counts as reversing, m/s."""
REVERSE_MIN_S = 0.25
"""Reversing counts when it lasts at least this long, s: a manoeuvre, not the rebound of a hit."""
STILL_SPEED = 0.05
"""Forward speed under this (in magnitude) counts as not driving, m/s."""
TURN_RATE = 0.3
"""Yaw rate above this while not driving counts as turning in place, rad/s."""
STAND_RATE = 0.1
"""Yaw rate under this while not driving counts as standing still, rad/s."""
DECEL_SMOOTH_S = 0.04
"""Forward speed is smoothed over this long before differentiating it, s."""
YAW_SMOOTH_S = 0.25
"""The yaw-rate peak is of the yaw rate averaged over this long, s: a turn, not the jolt of a hit."""
FLUX_FRAME = 1024
"""Frame of the spectral-flux STFT at the audio rate, samples (23 ms at 44.1 kHz)."""
FLUX_RANGE_DB = 80.0
"""Dynamic range of the spectral flux below the window's loudest bin, dB."""
_TINY = 1e-12


def _spans(starts_s: np.ndarray, rate: float, n: int) -> list[slice]:
    length = round(WINDOW_S * rate)
    out = []
    for start in np.asarray(starts_s, dtype=np.float64):
        i0 = round(float(start) * rate)
        if i0 < 0 or i0 + length > n:
            raise ValueError(f"window at {start:.3f} s runs past the signal ({n / rate:.3f} s)")
        out.append(slice(i0, i0 + length))
    return out


def forward_speed(base_quat: np.ndarray, base_linvel: np.ndarray) -> np.ndarray:
    """(n,) speed along the robot's heading, m/s, from (n, 4) quaternions (w, x, y, z) and world velocity."""
    q = np.asarray(base_quat, dtype=np.float64)
    qw, qx, qy, qz = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    forward = np.stack(
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy + qw * qz), 2 * (qx * qz - qw * qy)], axis=1
    )
    return np.einsum("ij,ij->i", forward, np.asarray(base_linvel, dtype=np.float64))


def behaviour(
    speed: np.ndarray, yaw_rate: np.ndarray, rate: float, starts_s: np.ndarray
) -> dict[str, np.ndarray]:
    """Per window: fraction reversing, turning in place, standing still; peak deceleration and yaw rate.

    Reversing is backing at more than `REVERSE_SPEED` for at least `REVERSE_MIN_S`, and the yaw-rate peak
    is of the yaw rate averaged over `YAW_SMOOTH_S`: manoeuvres; the rebound and the spin of a hit are the
    impact, like the deceleration.

    Args:
        speed: (n,) forward speed at `rate`, m/s.
        yaw_rate: (n,) yaw rate about the body z axis, rad/s.
        rate: sample rate of both, Hz.
        starts_s: window start times, s.
    """
    v = np.asarray(speed, dtype=np.float64)
    w = np.abs(np.asarray(yaw_rate, dtype=np.float64))
    k = max(1, round(DECEL_SMOOTH_S * rate))
    smooth = np.convolve(np.abs(v), np.ones(k) / k, mode="same")
    decel = -np.gradient(smooth, 1.0 / rate)
    k_yaw = max(1, round(YAW_SMOOTH_S * rate))
    turning = np.convolve(w, np.ones(k_yaw) / k_yaw, mode="same")
    spans = _spans(starts_s, rate, v.size)
    still = np.abs(v) < STILL_SPEED
    backing = _runs_at_least(v < -REVERSE_SPEED, max(1, round(REVERSE_MIN_S * rate)))
    return {
        "reversing": np.array([np.mean(backing[s]) for s in spans]),
        "turning_in_place": np.array([np.mean(still[s] & (w[s] > TURN_RATE)) for s in spans]),
        "standing": np.array([np.mean(still[s] & (w[s] < STAND_RATE)) for s in spans]),
        "peak_deceleration": np.array([np.max(decel[s]) for s in spans]),
        "yaw_rate_peak": np.array([np.max(turning[s]) for s in spans]),
    }


def _runs_at_least(mask: np.ndarray, length: int) -> np.ndarray:
    """`mask` with its runs of True shorter than `length` samples cleared."""
    m = np.asarray(mask, dtype=bool)
    edges = np.diff(np.r_[0, m.astype(np.int8), 0])
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    out = np.zeros_like(m)
    for a, b in zip(starts, stops, strict=True):
        if b - a >= length:
            out[a:b] = True
    return out


def audio_levels(audio: np.ndarray, rate: int, starts_s: np.ndarray) -> dict[str, np.ndarray]:
    """Per window of (n, C) audio: RMS and peak level (dBFS), crest factor (dB), spectral flux peak.

    The spectral flux is the largest frame-to-frame rise of the log-magnitude spectrum of the channel
    mean (Hann frames of `FLUX_FRAME`, hop half a frame), averaged over bins, in dB: an onset detector.
    Magnitudes are floored `FLUX_RANGE_DB` below the window's largest, so bins holding only leakage and
    rounding do not count as onsets.
    """
    x = np.asarray(audio, dtype=np.float32)
    if x.ndim == 1:
        x = x[:, None]
    spans = _spans(starts_s, float(rate), x.shape[0])
    window = np.hanning(FLUX_FRAME + 1)[:-1].astype(np.float32)
    rms, peak, flux = [], [], []
    for s in spans:
        seg = x[s]
        rms.append(10.0 * np.log10(float(np.mean(np.square(seg, dtype=np.float64))) + _TINY))
        peak.append(20.0 * np.log10(float(np.max(np.abs(seg))) + _TINY))
        mono = seg.mean(axis=1)
        frames = np.lib.stride_tricks.sliding_window_view(mono, FLUX_FRAME)[:: FLUX_FRAME // 2]
        mag = np.abs(np.fft.rfft(frames * window, axis=1))
        mag = 20.0 * np.log10(np.maximum(mag, float(mag.max()) * 10.0 ** (-FLUX_RANGE_DB / 20.0) + _TINY))
        rise = np.clip(np.diff(mag, axis=0), 0.0, None).mean(axis=1)
        flux.append(float(rise.max()) if rise.size else 0.0)
    rms_a, peak_a = np.array(rms), np.array(peak)
    return {"rms": rms_a, "peak": peak_a, "crest": peak_a - rms_a, "flux": np.array(flux)}


def acceleration_peak(acc: np.ndarray, rate: float, starts_s: np.ndarray) -> np.ndarray:
    """Per window of (m, 3) accelerometer samples: the largest |a - median(a)| (gravity removed), m/s^2."""
    a = np.asarray(acc, dtype=np.float64)
    out = []
    for s in _spans(starts_s, rate, a.shape[0]):
        seg = a[s]
        out.append(float(np.linalg.norm(seg - np.median(seg, axis=0), axis=1).max()))
    return np.array(out)


def clipped(peak_dbfs: np.ndarray, margin_db: float = 1.0) -> np.ndarray:
    """Whether each window's peak is within `margin_db` of full scale."""
    return np.asarray(peak_dbfs) >= -margin_db


REPETITION_HIGHPASS_HZ = 500.0
"""The repetition probe looks above this frequency: mains hum and fan blade tones below it are periodic by
nature (a pure tone correlates with itself at every multiple of its period), a looped bed at every
frequency."""


def repetition(
    signal: np.ndarray, rate: float, min_lag_s: float = 1.0, highpass_hz: float = REPETITION_HIGHPASS_HZ
) -> float:
    """Largest normalised autocorrelation of a (n,) or (n, C) signal at lags beyond `min_lag_s`.

    A looped noise bed shows a peak near 1 at its loop length; independent noise stays near 0. Content
    below `highpass_hz` is left out (see `REPETITION_HIGHPASS_HZ`).
    """
    x = np.asarray(signal, dtype=np.float64)
    x = x.mean(axis=1) if x.ndim == 2 else x
    x = x - x.mean()
    n = x.size
    lag0 = int(min_lag_s * rate)
    if n <= 2 * lag0:
        raise ValueError(f"signal of {n / rate:.2f} s is too short for lags beyond {min_lag_s} s")
    size = 1 << int(np.ceil(np.log2(2 * n)))
    spectrum = np.fft.rfft(x, size)
    spectrum[: int(np.ceil(highpass_hz * size / rate))] = 0.0
    acf = np.fft.irfft(spectrum * np.conj(spectrum), size)[:n]
    # Unbiased: each lag's sum has n - lag terms; only lags with at least half the signal are trusted.
    lags = np.arange(n)
    acf = acf / np.maximum(n - lags, 1) / (acf[0] / n + _TINY)
    return float(np.max(acf[lag0 : n // 2]))


def level_db(part: np.ndarray, rest: np.ndarray, rate: float, band: tuple[float, float]) -> float:
    """Level of `part` over `rest` in `band`, dB (both (n, C) at `rate`; `synth_audio.faults.band_power`)."""
    ratio = (band_power(part, rate, band) + _TINY) / (band_power(rest, rate, band) + _TINY)
    return float(10.0 * np.log10(ratio))
