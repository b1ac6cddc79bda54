"""`ScoreGraph`: a fitted `MSVDD`'s whole scoring path as one torch module, windows in, scores out.

This is what `msvdd.export` hands to the ONNX exporter. Its forward pass takes the arrays of a `Windows` batch
and returns the anomaly score delta of `MSVDD.score`, with every step as a tensor operation:

1. Audio front end. "waveform": per-channel z-score, then the Savitzky-Golay smoothing along time (a
   convolution with mirrored edges, like `scipy.ndimage.convolve1d(mode="mirror")`). "logmel": Hann frames
   of 256 samples every 128 and their real DFT as one strided convolution (cosine and sine rows, only the
   FFT bins some mel band covers), power, the HTK mel filterbank, log(. + 1e-6), then the per channel and
   band z-score (`msvdd.logmel`, `msvdd.frontend`).
2. IMU input: the z-velocity (with the six accelerometer and gyroscope axes for `imu_input="all"`),
   z-scored per channel and smoothed like the waveform.
3. The network (`msvdd.network.FusionNet`): encoders, fusion, decoders.
4. D = ||L^-1 (z - mu)||, L the Cholesky factor of the fitted Sigma (L^-1 stored: the inverse covariance as
   Sigma^-1 = L^-T L^-1), in float64 like `msvdd.mcd.mahalanobis`; the Euclidean ablation stores mu = c and
   L^-1 = I.
5. The reconstruction term (mean or peak Huber error per modality, over `rec_scale_`, summed) and
   delta = D + w (mean_D / mean_Rec) Rec, in float64.

Nothing of the scoring stays outside but checking the window batch and casting it to float32. Decimating
44.1 kHz audio to the windows' 4410 Hz is not part of scoring (`MSVDD.score` reads decimated windows too):
`msvdd.preprocess.decimate_audio` or `msvdd.stream.StreamingScorer` do it before.
"""

from __future__ import annotations

import copy

import numpy as np
import torch
import torch.nn.functional as F
from scipy import signal
from torch import nn

from msvdd.contract import AUDIO_RATE
from msvdd.frontend import LOGMEL_F_MIN, LOGMEL_HOP, LOGMEL_N_FFT, LOGMEL_N_MELS
from msvdd.logmel import LOG_MEL_FLOOR, mel_filterbank
from msvdd.model import MSVDD, NotFittedError


def _f32(x: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))


def _f64(x: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float64))


class Smoother(nn.Module):
    """Savitzky-Golay smoothing along time of (N, C, L) signals, each channel and window on its own."""

    def __init__(self, window: int, polyorder: int) -> None:
        super().__init__()
        self.edge = window // 2
        self.kernel: torch.Tensor | None
        if window == 0:
            self.register_buffer("kernel", None)
        else:
            # convolve1d convolves; conv1d correlates: flip the coefficients.
            coeffs = signal.savgol_coeffs(window, polyorder)[::-1]
            self.register_buffer("kernel", _f32(coeffs).reshape(1, 1, -1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(N, C, L) -> (N, C, L)."""
        if self.kernel is None:
            return x
        n, c, length = x.shape
        padded = F.pad(x.reshape(n * c, 1, length), (self.edge, self.edge), mode="reflect")
        return F.conv1d(padded, self.kernel).reshape(n, c, length)


class LogMel(nn.Module):
    """(N, L, 2) audio -> (N, 2, frames, n_mels) log-mel energies, as `msvdd.logmel.log_mel_frames`."""

    def __init__(self) -> None:
        super().__init__()
        bank = mel_filterbank(LOGMEL_N_MELS, LOGMEL_N_FFT, AUDIO_RATE, LOGMEL_F_MIN, AUDIO_RATE / 2)
        bins = np.flatnonzero(bank.sum(axis=0) > 0)  # FFT bins outside every band do not matter
        n = np.arange(LOGMEL_N_FFT)
        window = np.hanning(LOGMEL_N_FFT + 1)[:-1]
        angle = 2.0 * np.pi * np.outer(bins, n) / LOGMEL_N_FFT
        dft = np.concatenate([np.cos(angle) * window, -np.sin(angle) * window])
        self.n_bins = int(bins.size)
        self.dft: torch.Tensor
        self.bank_t: torch.Tensor
        self.register_buffer("dft", _f32(dft)[:, None, :])
        self.register_buffer("bank_t", _f32(bank[:, bins].T))

    def forward(self, audio: torch.Tensor) -> torch.Tensor:
        """(N, L, 2) -> (N, 2, T, M)."""
        n, length, channels = audio.shape
        x = audio.transpose(1, 2).reshape(n * channels, 1, length)
        spec = F.conv1d(x, self.dft, stride=LOGMEL_HOP)  # (N C, 2 bins, T)
        real, imag = spec[:, : self.n_bins], spec[:, self.n_bins :]
        power = (real * real + imag * imag).transpose(1, 2)  # (N C, T, bins)
        mel = torch.log(power @ self.bank_t + LOG_MEL_FLOOR)
        return mel.reshape(n, channels, mel.shape[1], mel.shape[2])


class ScoreGraph(nn.Module):
    """A fitted `MSVDD`'s scoring path: (audio, imu[, imu6]) float32 windows -> (N,) float64 delta.

    The network is a CPU copy of the model's (the model itself is left as it is). `forward` takes
    audio (N, 8820, 2), imu (N, 400) and, when the model reads all IMU axes, imu6 (N, 400, 6).
    """

    def __init__(self, model: MSVDD) -> None:
        super().__init__()
        cfg = model.config
        norm = model.normalizer
        if norm is None or model.mu_ is None or model.sigma_ is None:
            raise NotFittedError("MSVDD is not fitted: call fit() or MSVDD.load() before exporting")
        self.model = model
        self.logmel_input = cfg.audio_frontend == "logmel"
        self.imu_all = cfg.imu_input == "all"
        self.use_reconstruction = cfg.use_reconstruction
        self.net = copy.deepcopy(model.module.net).cpu().eval()
        self.logmel = LogMel() if self.logmel_input else None
        self.smoother = Smoother(cfg.smooth_window, cfg.smooth_polyorder)
        self.audio_mean: torch.Tensor
        self.audio_std: torch.Tensor
        self.imu_mean: torch.Tensor
        self.imu_std: torch.Tensor
        self.mu: torch.Tensor
        self.whiten: torch.Tensor
        self.rec_scale: torch.Tensor
        # Statistics shaped to broadcast: log-mel (1, 2, 1, M); waveform and IMU (1, C, 1) on (N, C, L).
        a_shape = (1, 2, 1, -1) if self.logmel_input else (1, 2, 1)
        self.register_buffer("audio_mean", _f32(norm.audio_mean).reshape(a_shape))
        self.register_buffer("audio_std", _f32(norm.audio_std).reshape(a_shape))
        self.register_buffer("imu_mean", _f32(norm.imu_mean).reshape(1, -1, 1))
        self.register_buffer("imu_std", _f32(norm.imu_std).reshape(1, -1, 1))
        sigma = model.sigma_.detach().cpu().to(torch.float64)
        chol = torch.linalg.cholesky(sigma)
        eye = torch.eye(sigma.shape[0], dtype=torch.float64)
        self.register_buffer("mu", model.mu_.detach().cpu().to(torch.float64).reshape(1, -1))
        self.register_buffer("whiten", torch.linalg.solve_triangular(chol, eye, upper=False).T.contiguous())
        self.register_buffer("rec_scale", _f64(np.asarray(model.rec_scale_, dtype=np.float64)))
        mean_rec = model.mean_rec_ if cfg.use_reconstruction else 1.0
        self.rec_weight = float(cfg.w * model.mean_d_ / mean_rec)

    def inputs(
        self, audio: torch.Tensor, imu: torch.Tensor, imu6: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalised network inputs: audio (N, 8820, 2) or log-mel (N, 2, 67, 32), IMU (N, 400[, 7])."""
        if self.logmel is not None:
            a = (self.logmel(audio) - self.audio_mean) / self.audio_std
        else:
            a = self.smoother((audio.transpose(1, 2) - self.audio_mean) / self.audio_std).transpose(1, 2)
        if self.imu_all:
            if imu6 is None:
                raise ValueError("this model reads all IMU axes: imu6 (N, 400, 6) is needed")
            i = torch.cat([imu.unsqueeze(1), imu6.transpose(1, 2)], dim=1)
        else:
            i = imu.unsqueeze(1)
        i = self.smoother((i - self.imu_mean) / self.imu_std)
        i = i.transpose(1, 2) if self.imu_all else i[:, 0]
        return a, i

    def forward(
        self, audio: torch.Tensor, imu: torch.Tensor, imu6: torch.Tensor | None = None
    ) -> torch.Tensor:
        """(N,) float64 anomaly scores delta = D + w (mean_D / mean_Rec) Rec."""
        a, i = self.inputs(audio, imu, imu6)
        out = self.net(a, i)
        y = (out.z.to(torch.float64) - self.mu) @ self.whiten
        score = torch.sqrt((y * y).sum(dim=1))
        if self.use_reconstruction:
            parts = self.model.rec_parts(out, a, i)
            if parts:
                rec = (torch.stack(parts, dim=1).to(torch.float64) / self.rec_scale[: len(parts)]).sum(dim=1)
                score = score + self.rec_weight * rec
        return score
