"""What the network reads of a window: the audio front end and the IMU channels, z-scored with training stats.

- Audio front ends (`AUDIO_FRONTENDS`): "waveform", the paper's (N, 8820, 2) decimated binaural samples, and
  "logmel", per-channel log-mel spectrograms (N, 2, 67, 32) of the same 4410 Hz audio (Hann frames of 256
  samples, hop 128, 32 HTK mel bands 20-2205 Hz; `msvdd.logmel`), like the 2-D spectrogram autoencoder of
  the paper's MIMII experiment.
- IMU inputs (`IMU_INPUTS`): "z", the paper's z-axis velocity (N, 400), and "all", the z-velocity with the
  accelerometer and gyroscope axes (N, 400, 7); a collision lives in the acceleration.
- `InputNormalizer`: per-channel (per channel and mel band for log-mel) mean and standard deviation of the
  training windows only, saved with the model; M-SVDD and every deep baseline that reuses its network read
  their inputs through it. The paper's Savitzky-Golay smoothing is applied along time to
  the waveform and the IMU channels after z-scoring; a log-mel frame is already an average over 58 ms.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Self

import numpy as np
import torch

from msvdd.contract import AUDIO_LEN, AUDIO_RATE, WindowError, Windows
from msvdd.logmel import log_mel_frames
from msvdd.preprocess import smooth

AUDIO_FRONTENDS = ("waveform", "logmel")
"""Audio front ends: the paper's decimated waveform, or log-mel spectrograms of it."""
IMU_INPUTS = ("z", "all")
"""IMU inputs: the paper's z-velocity, or z-velocity plus accelerometer and gyroscope xyz."""
LOGMEL_N_FFT = 256
"""Log-mel frame length, samples at 4410 Hz (58 ms)."""
LOGMEL_HOP = 128
"""Log-mel hop, samples (29 ms)."""
LOGMEL_N_MELS = 32
"""Mel bands."""
LOGMEL_F_MIN = 20.0
"""Lowest mel edge, Hz (the highest is the 2205 Hz Nyquist)."""
LOGMEL_FRAMES = (AUDIO_LEN - LOGMEL_N_FFT) // LOGMEL_HOP + 1
"""Log-mel frames per 2 s window (67)."""
IMU_ALL_CHANNELS = 7
"""Channels of the "all" IMU input: z-velocity, acc xyz, gyro xyz."""
_CHUNK = 256
_STD_FLOOR = 1e-8
_STAT_FIELDS = ("audio_mean", "audio_std", "imu_mean", "imu_std")


def check_frontend(audio_frontend: str, imu_input: str) -> None:
    """Raise ValueError naming the field when a front-end name is unknown."""
    if audio_frontend not in AUDIO_FRONTENDS:
        raise ValueError(f"audio_frontend {audio_frontend!r}; allowed: {' | '.join(AUDIO_FRONTENDS)}")
    if imu_input not in IMU_INPUTS:
        raise ValueError(f"imu_input {imu_input!r}; allowed: {' | '.join(IMU_INPUTS)}")


def raw_inputs(batch: Windows, audio_frontend: str, imu_input: str) -> tuple[np.ndarray, np.ndarray]:
    """(audio, imu) float32 arrays the network reads, before z-scoring.

    Raises:
        WindowError: imu_input "all" with windows that carry no `imu6`.
    """
    check_frontend(audio_frontend, imu_input)
    if audio_frontend == "waveform":
        audio = np.asarray(batch.audio, dtype=np.float32)
    else:
        audio = np.concatenate(
            [
                log_mel_frames(
                    batch.audio[i : i + _CHUNK],
                    AUDIO_RATE,
                    LOGMEL_N_FFT,
                    LOGMEL_HOP,
                    LOGMEL_N_MELS,
                    LOGMEL_F_MIN,
                    AUDIO_RATE / 2,
                    average_channels=False,
                )
                for i in range(0, len(batch), _CHUNK)
            ]
        ).astype(np.float32)
    if imu_input == "z":
        imu = np.asarray(batch.imu, dtype=np.float32)
    else:
        if batch.imu6 is None:
            raise WindowError('imu_input "all" reads the six IMU axes, but the windows carry no imu6')
        imu = np.concatenate([batch.imu[:, :, None], batch.imu6], axis=2).astype(np.float32)
    return audio, imu


def _nonempty(train: Windows) -> Windows:
    if len(train) == 0:
        raise WindowError("InputNormalizer.fit needs at least one training window")
    return train


def _channel_axes(x: np.ndarray, kind: str) -> tuple[int, ...]:
    """Axes averaged over for the statistics: all but the channel axes."""
    if kind == "audio":
        return (0, 1) if x.ndim == 3 else (0, 2)  # waveform (N, L, 2); log-mel (N, 2, T, M)
    return (0, 1) if x.ndim == 3 else (0,)  # imu (N, 400, C) or (N, 400)


def _stats(x: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    axes = _channel_axes(x, kind)
    mean = x.mean(axis=axes, dtype=np.float64)
    std = x.std(axis=axes, dtype=np.float64)
    if kind == "imu" and x.ndim == 2:  # one z-velocity channel: a scalar per statistic
        mean, std = x.mean(dtype=np.float64).reshape(1), x.std(dtype=np.float64).reshape(1)
    return mean, np.where(std > _STD_FLOOR, std, 1.0)


@dataclass(frozen=True)
class InputNormalizer:
    """Front-end choice and per-channel z-score statistics of training windows."""

    audio_frontend: str
    """One of `AUDIO_FRONTENDS`."""
    imu_input: str
    """One of `IMU_INPUTS`."""
    audio_mean: np.ndarray
    """Mean per audio channel (2,) for the waveform, per channel and band (2, 32) for log-mel."""
    audio_std: np.ndarray
    """Standard deviation, same shape (1 where a channel is constant)."""
    imu_mean: np.ndarray
    """Mean per IMU channel: (1,) for "z", (7,) for "all"."""
    imu_std: np.ndarray
    """Standard deviation per IMU channel (1 where constant)."""

    @classmethod
    def fit(cls, train: Windows, audio_frontend: str = "waveform", imu_input: str = "z") -> Self:
        """Statistics of `train` (never of validation or test windows)."""
        return cls._fit_raw(
            *raw_inputs(_nonempty(train), audio_frontend, imu_input), audio_frontend, imu_input
        )

    @classmethod
    def fit_tensors(
        cls,
        train: Windows,
        audio_frontend: str = "waveform",
        imu_input: str = "z",
        smooth_window: int = 5,
        smooth_polyorder: int = 2,
    ) -> tuple[Self, tuple[torch.Tensor, torch.Tensor]]:
        """`fit` and `tensors` of the same training windows, with their front end computed once."""
        audio, imu = raw_inputs(_nonempty(train), audio_frontend, imu_input)
        normalizer = cls._fit_raw(audio, imu, audio_frontend, imu_input)
        return normalizer, normalizer._normalise(audio, imu, smooth_window, smooth_polyorder)

    @classmethod
    def _fit_raw(cls, audio: np.ndarray, imu: np.ndarray, audio_frontend: str, imu_input: str) -> Self:
        a_mean, a_std = _stats(audio, "audio")
        i_mean, i_std = _stats(imu, "imu")
        return cls(audio_frontend, imu_input, a_mean, a_std, i_mean, i_std)

    def tensors(
        self, batch: Windows, smooth_window: int = 5, smooth_polyorder: int = 2
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(audio, imu) float32 CPU tensors: front end, z-score, then smoothing along time."""
        audio, imu = raw_inputs(batch, self.audio_frontend, self.imu_input)
        return self._normalise(audio, imu, smooth_window, smooth_polyorder)

    def _normalise(
        self, audio: np.ndarray, imu: np.ndarray, smooth_window: int, smooth_polyorder: int
    ) -> tuple[torch.Tensor, torch.Tensor]:
        if self.audio_frontend == "waveform":
            audio = (audio - self.audio_mean.astype(np.float32)) / self.audio_std.astype(np.float32)
            audio = smooth(audio, smooth_window, smooth_polyorder)
        else:
            mean = self.audio_mean.astype(np.float32)[None, :, None, :]
            audio = (audio - mean) / self.audio_std.astype(np.float32)[None, :, None, :]
        if self.imu_input == "z":
            imu = (imu - np.float32(self.imu_mean[0])) / np.float32(self.imu_std[0])
        else:
            imu = (imu - self.imu_mean.astype(np.float32)) / self.imu_std.astype(np.float32)
        imu = smooth(imu, smooth_window, smooth_polyorder)
        return (
            torch.from_numpy(np.ascontiguousarray(audio, dtype=np.float32)),
            torch.from_numpy(np.ascontiguousarray(imu, dtype=np.float32)),
        )

    def arrays(self) -> dict[str, np.ndarray]:
        """The statistics as float64 arrays (the front-end names live in the model's config)."""
        return {k: np.asarray(getattr(self, k), dtype=np.float64) for k in _STAT_FIELDS}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], audio_frontend: str, imu_input: str) -> Self:
        """Inverse of `arrays`; the IMU statistics may be scalars (files of the paper's z-velocity input)."""
        check_frontend(audio_frontend, imu_input)
        stats = {k: np.asarray(arrays[k], dtype=np.float64) for k in _STAT_FIELDS}
        for k in ("imu_mean", "imu_std"):
            stats[k] = stats[k].reshape(-1)
        return cls(audio_frontend, imu_input, **stats)

    def state(self) -> dict[str, torch.Tensor | str]:
        """Tensors and names for a weights-only checkpoint."""
        tensors = {k: torch.from_numpy(v) for k, v in self.arrays().items()}
        return {"audio_frontend": self.audio_frontend, "imu_input": self.imu_input, **tensors}

    @classmethod
    def from_state(cls, state: Mapping[str, object]) -> Self:
        """Inverse of `state`."""
        arrays = {}
        for k in _STAT_FIELDS:
            value = state[k]
            if not isinstance(value, torch.Tensor):
                raise ValueError(f"normalizer state {k!r} is not a tensor")
            arrays[k] = value.numpy()
        return cls.from_arrays(arrays, str(state["audio_frontend"]), str(state["imu_input"]))
