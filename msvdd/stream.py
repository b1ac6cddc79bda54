"""Streaming scoring: raw 44.1 kHz audio and 200 Hz IMU chunks in, one score per hop out.

The scorer decimates incrementally with exactly the filter of `msvdd.preprocess.decimate_audio`: output
sample q is computed once input samples up to 10 q + 200 have arrived (the centred FIR's look-ahead), so a
window's audio equals what batch decimation of the whole recording gives (away from the recording's end,
where batch decimation zero-pads). A window starting at t = k * hop_s is scored as soon as its audio and IMU
are complete. Buffers are trimmed as windows are emitted, so memory stays bounded. A model that reads all
IMU axes (`imu_input="all"`) needs the (j, 6) accelerometer and gyroscope chunk with every IMU chunk.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE, WindowError, Windows
from msvdd.model import MSVDD
from msvdd.preprocess import DECIMATION, FIR_HALF, FIR_TAPS


class StreamingScorer:
    """Scores a live recording window by window (2 s windows every `hop_s` seconds)."""

    def __init__(self, model: MSVDD, hop_s: float = 0.5) -> None:
        if not hop_s > 0:
            raise ValueError(f"hop_s {hop_s}; allowed: > 0 seconds")
        self.model = model
        self.hop_s = float(hop_s)
        self._raw = np.zeros((FIR_HALF, 2))
        """Raw audio not yet consumed, preceded at the start by the FIR's zero padding."""
        self._raw0 = -FIR_HALF
        """Global index of `_raw[0]` (negative indices are the zeros before the recording)."""
        self._dec = np.zeros((0, 2), dtype=np.float32)
        self._dec0 = 0
        self._imu = np.zeros(0, dtype=np.float32)
        self._imu6 = np.zeros((0, 6), dtype=np.float32)
        self._imu0 = 0
        self._next = 0

    @property
    def n_emitted(self) -> int:
        """Windows scored so far."""
        return self._next

    def push(
        self, audio44k_chunk: np.ndarray, imu_z_chunk: np.ndarray, imu6_chunk: np.ndarray | None = None
    ) -> list[tuple[float, float]]:
        """Append (k, 2) 44.1 kHz audio, (j,) 200 Hz IMU z-velocity and, for a model that reads all IMU axes,
        (j, 6) accelerometer and gyroscope xyz; -> [(window_start_s, score), ...].

        Raises:
            WindowError: wrong shapes, NaN/inf samples, or a missing imu6 chunk the model needs.
        """
        a = np.asarray(audio44k_chunk, dtype=np.float64)
        i = np.asarray(imu_z_chunk, dtype=np.float32)
        if a.ndim != 2 or a.shape[1] != 2:
            raise WindowError(f"audio chunk shape {a.shape}; expected (k, 2) at 44100 Hz")
        if i.ndim != 1:
            raise WindowError(f"imu chunk shape {i.shape}; expected (j,) at {IMU_RATE} Hz")
        needs6 = self.model.config.imu_input == "all"
        if needs6 and imu6_chunk is None:
            raise WindowError('the model reads all IMU axes (imu_input "all"): push an imu6 chunk (j, 6) too')
        i6 = (
            np.zeros((i.shape[0], 6), np.float32)
            if imu6_chunk is None
            else np.asarray(imu6_chunk, np.float32)
        )
        if i6.shape != (i.shape[0], 6):
            raise WindowError(f"imu6 chunk shape {i6.shape}; expected ({i.shape[0]}, 6), aligned with imu")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(i)) and np.all(np.isfinite(i6))):
            raise WindowError("stream chunk holds NaN or inf")
        self._raw = np.concatenate([self._raw, a])
        self._imu = np.concatenate([self._imu, i])
        self._imu6 = np.concatenate([self._imu6, i6])
        self._decimate_ready()
        return self._emit()

    def _decimate_ready(self) -> None:
        n_dec = self._dec0 + self._dec.shape[0]
        raw_end = self._raw0 + self._raw.shape[0]
        q_last = (raw_end - 1 - FIR_HALF) // DECIMATION
        if q_last < n_dec:
            return
        start = DECIMATION * n_dec - FIR_HALF - self._raw0
        stop = DECIMATION * q_last + FIR_HALF + 1 - self._raw0
        u = signal.upfirdn(FIR_TAPS, self._raw[start:stop], up=1, down=DECIMATION, axis=0)
        skip = 2 * FIR_HALF // DECIMATION
        new = u[skip : skip + q_last - n_dec + 1].astype(np.float32)
        self._dec = np.concatenate([self._dec, new])
        keep_from = DECIMATION * (q_last + 1) - FIR_HALF - self._raw0
        self._raw = self._raw[keep_from:]
        self._raw0 += keep_from

    def _emit(self) -> list[tuple[float, float]]:
        dec_end = self._dec0 + self._dec.shape[0]
        imu_end = self._imu0 + self._imu.shape[0]
        starts: list[float] = []
        k = self._next
        while True:
            t = k * self.hop_s
            if round(t * AUDIO_RATE) + AUDIO_LEN > dec_end or round(t * IMU_RATE) + IMU_LEN > imu_end:
                break
            starts.append(t)
            k += 1
        if not starts:
            return []
        st = np.asarray(starts)
        a_idx = (np.rint(st * AUDIO_RATE).astype(np.int64) - self._dec0)[:, None] + np.arange(AUDIO_LEN)
        i_idx = (np.rint(st * IMU_RATE).astype(np.int64) - self._imu0)[:, None] + np.arange(IMU_LEN)
        windows = Windows(audio=self._dec[a_idx], imu=self._imu[i_idx], imu6=self._imu6[i_idx])
        scores = self.model.score(windows)
        self._next = k
        t_next = k * self.hop_s
        drop_a = int(np.rint(t_next * AUDIO_RATE)) - self._dec0
        drop_i = int(np.rint(t_next * IMU_RATE)) - self._imu0
        self._dec, self._dec0 = self._dec[drop_a:], self._dec0 + drop_a
        self._imu, self._imu6, self._imu0 = self._imu[drop_i:], self._imu6[drop_i:], self._imu0 + drop_i
        return [(float(t), float(s)) for t, s in zip(starts, scores, strict=True)]
