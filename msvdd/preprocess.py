"""Preprocessing (paper, Experimental Setting): decimation, framing, smoothing (z-scores: `msvdd.frontend`).

- `decimate_audio`: 44.1 kHz -> 4410 Hz by a zero-phase (centred, delay-compensated) linear-phase FIR
  anti-alias filter (Kaiser window, 401 taps, cutoff 2 kHz) followed by keeping every 10th sample, applied
  to a whole continuous recording. Output sample k is sum_j h[j] x[10 k + 200 - j], x zero outside the
  recording, so any stretch away from the recording's ends can be computed from a finite stretch of input
  (what `msvdd.stream` relies on).
- `frame_windows`: 2 s windows at given start times.
- `smooth`: the paper's smoothing filter, a Savitzky-Golay filter along time within each window
  (edges mirrored within the window; no state crosses a window boundary).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy import ndimage, signal

from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE, WindowError, Windows

RAW_AUDIO_RATE = 44100.0
"""Sample rate of recorded audio, Hz."""
DECIMATION = 10
"""Audio decimation factor (44.1 kHz -> 4410 Hz)."""
FIR_HALF = 200
"""Half length of the anti-alias FIR (401 taps, group delay 200 input samples = 20 output samples)."""
FIR_CUTOFF_HZ = 2000.0
"""Anti-alias cutoff, Hz (below the 2205 Hz Nyquist of the decimated rate)."""
FIR_TAPS = signal.firwin(2 * FIR_HALF + 1, FIR_CUTOFF_HZ, window=("kaiser", 8.0), fs=RAW_AUDIO_RATE)
"""Anti-alias FIR coefficients (unit DC gain)."""


def decimate_audio(audio: np.ndarray, rate: float = RAW_AUDIO_RATE) -> np.ndarray:
    """Anti-alias filter and decimate a continuous (n, 2) 44.1 kHz recording to (n // 10, 2) float32, 4410 Hz.

    Raises:
        WindowError: wrong shape, rate other than 44100 Hz, or NaN/inf samples.
    """
    if rate != RAW_AUDIO_RATE:
        raise WindowError(f"audio rate {rate} Hz; decimate_audio needs {RAW_AUDIO_RATE} Hz input")
    x = np.asarray(audio)
    if x.ndim != 2 or x.shape[1] != 2:
        raise WindowError(f"audio shape {x.shape}; expected (n, 2) binaural samples")
    if not np.all(np.isfinite(x)):
        raise WindowError("audio holds NaN or inf")
    n_out = x.shape[0] // DECIMATION
    if n_out == 0:
        return np.zeros((0, 2), dtype=np.float32)
    y = signal.upfirdn(FIR_TAPS, x.astype(np.float64), up=1, down=DECIMATION, axis=0)
    skip = FIR_HALF // DECIMATION
    return y[skip : skip + n_out].astype(np.float32)


def frame_windows(
    audio4410: np.ndarray,
    imu_z: np.ndarray,
    starts_s: np.ndarray,
    imu6: np.ndarray | None = None,
    odometry: np.ndarray | None = None,
) -> Windows:
    """2 s windows starting at `starts_s` (seconds) of one episode's decimated audio and IMU.

    Args:
        audio4410: (n, 2) audio at 4410 Hz (from `decimate_audio`).
        imu_z: (m,) IMU z-axis velocity at 200 Hz.
        starts_s: (k,) window start times, s; each window must lie inside both signals.
        imu6: optional (m, 6) accelerometer xyz and gyro xyz at 200 Hz.
        odometry: optional (m, W) wheel encoder positions at 200 Hz, rad (each window's is taken relative to
            its first sample).

    Raises:
        WindowError: wrong shapes, a window past the end of a signal, or a negative start.
    """
    a = np.asarray(audio4410)
    i = np.asarray(imu_z)
    st = np.asarray(starts_s, dtype=np.float64).reshape(-1)
    if a.ndim != 2 or a.shape[1] != 2:
        raise WindowError(f"audio4410 shape {a.shape}; expected (n, 2) at {AUDIO_RATE} Hz")
    if i.ndim != 1:
        raise WindowError(f"imu_z shape {i.shape}; expected (m,) at {IMU_RATE} Hz")
    if imu6 is not None and np.asarray(imu6).shape != (i.shape[0], 6):
        raise WindowError(f"imu6 shape {np.asarray(imu6).shape}; expected ({i.shape[0]}, 6)")
    if odometry is not None and (np.ndim(odometry) != 2 or np.shape(odometry)[0] != i.shape[0]):
        raise WindowError(f"odometry shape {np.shape(odometry)}; expected ({i.shape[0]}, W)")
    if st.size and (not np.all(np.isfinite(st)) or st.min() < 0):
        raise WindowError(f"window starts must be finite and >= 0 s, got min {st.min()}")
    a0 = np.rint(st * AUDIO_RATE).astype(np.int64)
    i0 = np.rint(st * IMU_RATE).astype(np.int64)
    if st.size and (a0.max() + AUDIO_LEN > a.shape[0] or i0.max() + IMU_LEN > i.shape[0]):
        raise WindowError(
            f"a window starting at {st.max():.3f} s runs past the end of the signals "
            f"(audio {a.shape[0] / AUDIO_RATE:.3f} s, imu {i.shape[0] / IMU_RATE:.3f} s)"
        )
    a_idx = a0[:, None] + np.arange(AUDIO_LEN)
    i_idx = i0[:, None] + np.arange(IMU_LEN)
    return Windows(
        audio=a[a_idx].astype(np.float32),
        imu=i[i_idx].astype(np.float32),
        imu6=None if imu6 is None else np.asarray(imu6)[i_idx].astype(np.float32),
        odometry=None if odometry is None else _relative(np.asarray(odometry, dtype=np.float64)[i_idx]),
    )


def _relative(angle: np.ndarray) -> np.ndarray:
    """(k, n, W) wheel angles relative to each window's first sample, float32."""
    return np.asarray(angle - angle[:, :1, :], dtype=np.float32)


def smooth(x: np.ndarray, window: int, polyorder: int) -> np.ndarray:
    """Savitzky-Golay smoothing along axis 1 (time) of (N, L) or (N, L, C), each window on its own."""
    if window == 0:
        return x
    coeffs = _savgol_coeffs(window, polyorder)
    return ndimage.convolve1d(x.astype(np.float32, copy=False), coeffs, axis=1, mode="mirror")


@functools.lru_cache(maxsize=8)
def _savgol_coeffs(window: int, polyorder: int) -> np.ndarray:
    return signal.savgol_coeffs(window, polyorder).astype(np.float32)
