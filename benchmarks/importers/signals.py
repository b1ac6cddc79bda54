"""Reading recorded signals and bringing them to the dataset's rates: audio to stereo 44.1 kHz, IMU to 200 Hz.

- Audio (WAV or FLAC, any rate, any channel count) is read as float32; a mono file (or one channel picked
  with `--channels`) is duplicated into both channels, a stereo file kept, a file with more channels needs
  `--channels`. It is resampled to 44.1 kHz with a polyphase FIR (`scipy.signal.resample_poly`, exact
  rational ratio) and clipped to full scale (only the filter's overshoot of a file that already peaks near
  it is clipped: a file peaking above full scale is refused).
- IMU CSVs (a time column and six axes, optionally a z velocity) are low-passed at 80 Hz when recorded
  faster than 250 Hz and linearly interpolated onto a 200 Hz grid starting at the first time stamp; the
  audio's first sample is taken to be that time stamp. Without a z-velocity column it is estimated from the
  z acceleration: high-passed at 0.5 Hz (removing gravity and bias), integrated, high-passed again (drift).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
import soundfile as sf
from scipy import integrate, signal

from benchmarks.importers.config import IMU_FIELDS, TIME_UNITS, FolderConfig, ImportConfig, SourceError
from msvdd.contract import IMU_RATE
from msvdd.preprocess import RAW_AUDIO_RATE

OUT_AUDIO_RATE = int(RAW_AUDIO_RATE)
"""Rate of the audio an episode stores, Hz (the dataset decimates it to the window rate itself)."""
IMU_ANTI_ALIAS_HZ = 80.0
"""Low-pass applied to IMU recorded faster than `IMU_ANTI_ALIAS_ABOVE` before it is resampled, Hz."""
IMU_ANTI_ALIAS_ABOVE = 1.25 * IMU_RATE
"""IMU rates above this are low-passed before resampling, Hz."""
IMU_RATE_TOLERANCE = 0.05
"""Largest relative difference between the time stamps' rate and `--imu-rate`."""
VEL_Z_HIGHPASS_HZ = 0.5
"""High-pass corner of the z-velocity estimate from z acceleration, Hz."""


@dataclass(frozen=True)
class AudioInfo:
    """What an audio file was before conversion."""

    rate: int
    """Sample rate, Hz."""
    channels: int
    """Channel count."""
    duration_s: float
    """Length, s."""


def read_audio(path: Path, config: ImportConfig) -> tuple[np.ndarray, AudioInfo]:
    """(n, 2) float32 audio at 44.1 kHz from a WAV or FLAC file, and what the file was.

    Raises:
        SourceError: unreadable, empty, a rate other than `config.audio_rate`, channels that cannot be
            chosen, NaN/inf samples or a peak beyond full scale.
    """
    try:
        data, rate = sf.read(path, dtype="float32", always_2d=True)
    except (sf.LibsndfileError, RuntimeError, OSError) as exc:
        raise SourceError(f"{path}: not a readable audio file ({exc}); allowed: WAV or FLAC") from exc
    info = AudioInfo(int(rate), int(data.shape[1]), data.shape[0] / rate if rate else 0.0)
    if data.shape[0] == 0:
        raise SourceError(f"{path}: the audio file holds no samples")
    if config.audio_rate is not None and rate != config.audio_rate:
        raise SourceError(
            f"{path}: sample rate {rate} Hz, but --audio-rate is {config.audio_rate:g} Hz; allowed: files at "
            "--audio-rate only (leave --audio-rate out to resample files of any rate)"
        )
    stereo = pick_channels(data, config.channels, str(path))
    return to_stereo_rate(stereo, float(rate), str(path)), info


def pick_channels(data: np.ndarray, channels: tuple[int, ...] | None, where: str) -> np.ndarray:
    """(n, 2) from (n, c): mono duplicated, stereo kept, or the chosen `channels` (one is duplicated)."""
    count = data.shape[-1]
    if channels is None:
        if count == 1:
            return np.repeat(data, 2, axis=-1)
        if count == 2:
            return data
        raise SourceError(
            f"{where}: {count} audio channels; pass --channels to keep one or two of them "
            f"(indices 0..{count - 1}, e.g. --channels 0,1)"
        )
    if max(channels) >= count:
        raise SourceError(
            f"{where}: --channels {','.join(map(str, channels))} names channel {max(channels)}, but the "
            f"audio has {count} channel(s); allowed: indices 0..{count - 1}"
        )
    picked = data[..., list(channels)]
    return np.repeat(picked, 2, axis=-1) if len(channels) == 1 else picked


def to_stereo_rate(stereo: np.ndarray, rate: float, where: str) -> np.ndarray:
    """(n', 2) float32 at 44.1 kHz from (n, 2) at `rate`, resampled along axis -2 (a batch axis may lead).

    Raises:
        SourceError: NaN/inf samples, or a peak beyond full scale (FLAC is fixed point).
    """
    if not np.all(np.isfinite(stereo)):
        raise SourceError(f"{where}: the audio holds NaN or inf samples; allowed: finite samples")
    peak = float(np.max(np.abs(stereo))) if stereo.size else 0.0
    if peak > 1.0:
        raise SourceError(
            f"{where}: audio peak {peak:.3g} exceeds full scale; allowed: samples in [-1, 1] (a raw "
            "waveform; normalise the file first)"
        )
    ratio = Fraction(OUT_AUDIO_RATE) / Fraction(rate).limit_denominator(1_000_000)
    if ratio == 1:
        return np.ascontiguousarray(stereo, dtype=np.float32)
    out = signal.resample_poly(stereo.astype(np.float64), ratio.numerator, ratio.denominator, axis=-2)
    return np.clip(out, -1.0, 1.0).astype(np.float32)


@dataclass(frozen=True)
class ImuSeries:
    """IMU of one recording on the 200 Hz grid."""

    vel_z: np.ndarray
    """(m,) float32 z-axis velocity, m/s (recorded, or estimated from `az`)."""
    imu6: np.ndarray
    """(m, 6) float32 accelerometer xyz (m/s^2) and gyroscope xyz (rad/s)."""
    source_rate: float
    """Rate the time stamps show (1 / median interval), Hz."""
    vel_z_estimated: bool
    """Whether `vel_z` was estimated from `az` (no z-velocity column)."""

    @property
    def duration_s(self) -> float:
        """Length, s."""
        return self.vel_z.shape[0] / IMU_RATE


def read_imu_csv(path: Path, folder: FolderConfig) -> ImuSeries:
    """Read one IMU CSV (columns named by `folder.imu_columns`) and resample it to 200 Hz.

    Raises:
        SourceError: unreadable file, missing column, non-numeric value, time stamps that do not increase,
            fewer than two rows, or a rate other than `folder.imu_rate`.
    """
    cols = folder.imu_columns
    wanted = {f: getattr(cols, f) for f in IMU_FIELDS}
    if cols.vz is not None:
        wanted["vz"] = cols.vz
    try:
        with open(path, newline="", encoding="utf-8-sig") as handle:
            reader = csv.reader(handle)
            header = [h.strip() for h in next(reader, [])]
            index: dict[str, int] = {}
            for field_name, column in wanted.items():
                if column not in header:
                    raise SourceError(
                        f"{path}: no column {column!r} for IMU field {field_name}; its columns are "
                        f"{', '.join(header) or '(none)'}; name the column with "
                        f"--imu-columns {field_name}=COLUMN"
                    )
                index[field_name] = header.index(column)
            rows = [row for row in reader if any(cell.strip() for cell in row)]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise SourceError(f"{path}: not a readable CSV file ({exc})") from exc
    if len(rows) < 2:
        raise SourceError(f"{path}: {len(rows)} data row(s); allowed: at least two IMU samples")
    values = np.empty((len(rows), len(wanted)), dtype=np.float64)
    for r, row in enumerate(rows):
        for c, (field_name, i) in enumerate(index.items()):
            cell = row[i].strip() if i < len(row) else ""
            try:
                values[r, c] = float(cell)
            except ValueError:
                raise SourceError(
                    f"{path}, data row {r + 1}, column {wanted[field_name]!r}: value {cell!r} is not a number"
                ) from None
            if not math.isfinite(values[r, c]):
                raise SourceError(
                    f"{path}, data row {r + 1}, column {wanted[field_name]!r}: value {cell!r}; "
                    "allowed: a finite number"
                )
    t = values[:, 0] * TIME_UNITS[folder.time_unit]
    dt = np.diff(t)
    if np.any(dt <= 0):
        bad = int(np.argmax(dt <= 0)) + 1
        raise SourceError(
            f"{path}, data row {bad + 1}, column {cols.t!r}: time {values[bad, 0]!r} does not increase "
            f"(previous {values[bad - 1, 0]!r}); allowed: strictly increasing time stamps"
        )
    rate = float(1.0 / np.median(dt))
    if folder.imu_rate is not None and abs(rate - folder.imu_rate) > IMU_RATE_TOLERANCE * folder.imu_rate:
        raise SourceError(
            f"{path}: column {cols.t!r} (unit {folder.time_unit}) gives an IMU rate of {rate:.4g} Hz, but "
            f"--imu-rate is {folder.imu_rate:g} Hz; allowed: within {IMU_RATE_TOLERANCE:.0%} (check "
            "--imu-rate and --time-unit)"
        )
    grid = t[0] + np.arange(math.floor((t[-1] - t[0]) * IMU_RATE + 1e-9) + 1) / IMU_RATE
    resampled = resample_to_grid(t, values[:, 1:], grid, rate)
    imu6 = resampled[:, :6]
    vel_z = resampled[:, 6] if cols.vz is not None else estimate_vel_z(imu6[:, 2])
    return ImuSeries(vel_z.astype(np.float32), imu6.astype(np.float32), rate, cols.vz is None)


def resample_to_grid(t: np.ndarray, data: np.ndarray, grid: np.ndarray, rate: float) -> np.ndarray:
    """(len(grid), c) float64 from (n, c) samples at times `t` (s, increasing; `rate`: theirs, Hz): low-passed
    at `IMU_ANTI_ALIAS_HZ` when faster than `IMU_ANTI_ALIAS_ABOVE`, then linearly interpolated at `grid`."""
    x = np.asarray(data, dtype=np.float64)
    if rate > IMU_ANTI_ALIAS_ABOVE:
        x = _lowpass(x, IMU_ANTI_ALIAS_HZ, rate)
    return np.stack([np.interp(grid, t, x[:, c]) for c in range(x.shape[1])], axis=1)


def _lowpass(x: np.ndarray, cutoff_hz: float, rate: float) -> np.ndarray:
    sos = signal.butter(4, cutoff_hz, btype="lowpass", fs=rate, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0) if x.shape[0] > 3 * (2 * len(sos) + 1) else x


def estimate_vel_z(acc_z: np.ndarray, rate: float = IMU_RATE) -> np.ndarray:
    """z-axis velocity from z acceleration: high-pass (gravity, bias), integrate, high-pass (drift)."""
    a = np.asarray(acc_z, dtype=np.float64)
    a = a - a.mean()
    sos = signal.butter(2, VEL_Z_HIGHPASS_HZ, btype="highpass", fs=rate, output="sos")
    # Pad by one corner period (mirrored): the default pad is far shorter than this filter's transient.
    pad = min(a.shape[0] - 1, round(rate / VEL_Z_HIGHPASS_HZ))
    long_enough = a.shape[0] > 3 * (2 * len(sos) + 1)
    if long_enough:
        a = signal.sosfiltfilt(sos, a, padtype="even", padlen=pad)
    v = integrate.cumulative_trapezoid(a, dx=1.0 / rate, initial=0.0)
    return signal.sosfiltfilt(sos, v, padtype="even", padlen=pad) if long_enough else v - v.mean()
