"""`ScoreGraph`: a fitted `MSVDD`'s whole scoring path as one torch module, windows in, scores out.

This is what `msvdd.export` hands to the ONNX exporter. Its forward pass takes the arrays of a `Windows` batch
and returns the anomaly score delta of `MSVDD.score`, with every step as a tensor operation:

1. Audio front end. "waveform": per-channel z-score, then the Savitzky-Golay smoothing along time (a
   convolution with mirrored edges, like `scipy.ndimage.convolve1d(mode="mirror")`). "logmel": Hann frames
   of 256 samples every 128, their real DFT at the FFT bins some mel band covers as matrix products, power,
   the HTK mel filterbank, log(. + 1e-6), then the per channel and band z-score (`msvdd.logmel`,
   `msvdd.frontend`).
2. IMU input: the z-velocity (with the six accelerometer and gyroscope axes for `imu_input="all"`),
   z-scored per channel and smoothed like the waveform.
3. The network (`msvdd.network.FusionNet`): encoders, fusion, decoders.
4. D = ||L^-1 (z - mu)||, L the Cholesky factor of the fitted Sigma (L^-1 stored: the inverse covariance as
   Sigma^-1 = L^-T L^-1), in float64 like `msvdd.mcd.mahalanobis`; the Euclidean ablation stores mu = c and
   L^-1 = I.
5. The second term (the decoders' mean Huber error per modality, Rec; or with `frame_density` the largest
   distance of an input frame under the model's `msvdd.context_net.ContextNet`), over `rec_scale_`, summed,
   and delta = D + w (mean_D / mean_Rec) Rec, in float64.

The graph computes the same function as `MSVDD.score` (to float32 rounding), written for a fast single-thread
ONNX Runtime session at batch 1:

- Signals travel as (N, C, 1, L) images, so that the 1-D convolutions are 2-D convolutions with 1 x K
  kernels, which ONNX Runtime runs in its blocked (NCHWc) layout (about twice as fast as its 1-D
  convolutions); the waveform decoder's transposed convolutions are ordinary convolutions of their
  polyphase components followed by an interleave (`PolyphaseUpsample`), faster than ONNX Runtime's
  ConvTranspose.
- The z-score's division is folded into the smoothing kernel (the mean is still subtracted first: the
  accelerometer's z axis sits at 9.81 with a small spread, which folding the mean would cancel badly).
- The log-mel DFT is two half-size matrix products (`LogMel`) instead of a strided convolution, and the
  Huber error needs no select (Where).
- Each LSTM layer is one `lstm_layer` op with its weights already in ONNX's gate order: it becomes one ONNX
  LSTM node without initial states (ONNX Runtime starts from zeros), where the exporter's own translation
  adds zero states built from the batch size and a shape-computed reshape around it, few-element nodes that
  cost more than the LSTM's arithmetic at batch 1.

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

from msvdd.context_net import ContextNet
from msvdd.contract import AUDIO_RATE
from msvdd.frontend import LOGMEL_F_MIN, LOGMEL_HOP, LOGMEL_N_FFT, LOGMEL_N_MELS
from msvdd.logmel import LOG_MEL_FLOOR, mel_filterbank
from msvdd.model import AUDIO_SAMPLES_PER_TOKEN, MSVDD, NotFittedError
from msvdd.network import IMU_FRAME, AudioDecoder, AudioEncoder
from msvdd.residual import cut_frames


def _f32(x: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))


def _f64(x: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float64))


def _constant(x: torch.Tensor) -> nn.Parameter:
    """A fixed float64 CPU copy of a fitted tensor, kept with the graph's parameters (no gradient)."""
    return nn.Parameter(x.detach().cpu().double(), requires_grad=False)


class ChannelSmoother(nn.Module):
    """Per-channel z-score, then Savitzky-Golay smoothing along time: (N, C, 1, L) -> (N, C, 1, L).

    One grouped 1 x window convolution per channel with the smoothing coefficients over the channel's std
    (mirrored edges); the mean is subtracted before, so no precision is lost on channels far from zero.
    `window` 0: no smoothing (the convolution is then the division alone).
    """

    def __init__(self, mean: np.ndarray, std: np.ndarray, window: int, polyorder: int) -> None:
        super().__init__()
        mean = np.asarray(mean, dtype=np.float64).reshape(-1)
        std = np.asarray(std, dtype=np.float64).reshape(-1)
        self.channels = int(mean.size)
        self.edge = window // 2
        # convolve1d convolves; conv2d correlates: flip the coefficients.
        coeffs = signal.savgol_coeffs(window, polyorder)[::-1] if window else np.ones(1)
        self.mean: torch.Tensor
        self.weight: torch.Tensor
        self.register_buffer("mean", _f32(mean).reshape(1, -1, 1, 1))
        self.register_buffer("weight", _f32(coeffs[None, :] / std[:, None]).reshape(self.channels, 1, 1, -1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(N, C, 1, L) -> (N, C, 1, L)."""
        x = x - self.mean
        if self.edge:
            x = F.pad(x, (self.edge, self.edge, 0, 0), mode="reflect")
        return F.conv2d(x, self.weight, groups=self.channels)


class LogMel(nn.Module):
    """(N, L, 2) audio -> (N, 2, frames, n_mels) log-mel energies, as `msvdd.logmel.log_mel_frames`.

    A frame of n_fft = 2 hop samples is two consecutive hop-long blocks, a and b (times the two halves of
    the Hann window). FFT bin k of the frame is sum_n (a[n] + (-1)^k b[n]) e^(-2 pi i k n / n_fft) over
    n < hop (the first step of a radix-2 FFT), so the bins some mel band covers are two matrix products of
    half the size: the even bins of a + b, the odd bins of a - b (cosine and sine columns). Then power, the
    HTK mel filterbank (one product over the stacked real and imaginary parts), log(. + 1e-6).
    """

    def __init__(self) -> None:
        super().__init__()
        if LOGMEL_N_FFT != 2 * LOGMEL_HOP:
            raise ValueError(f"LogMel needs n_fft = 2 hop, got {LOGMEL_N_FFT} and {LOGMEL_HOP}")
        bank = mel_filterbank(LOGMEL_N_MELS, LOGMEL_N_FFT, AUDIO_RATE, LOGMEL_F_MIN, AUDIO_RATE / 2)
        bins = np.flatnonzero(bank.sum(axis=0) > 0)  # FFT bins outside every band do not matter
        even, odd = bins[bins % 2 == 0], bins[bins % 2 == 1]
        n = np.arange(LOGMEL_HOP)
        window = np.hanning(LOGMEL_N_FFT + 1)[:-1]

        def dft(k: np.ndarray) -> np.ndarray:
            angle = 2.0 * np.pi * np.outer(n, k) / LOGMEL_N_FFT
            return np.concatenate([np.cos(angle), -np.sin(angle)], axis=1)

        self.hop = LOGMEL_HOP
        self.win_a: torch.Tensor
        self.win_b: torch.Tensor
        self.dft_even: torch.Tensor
        self.dft_odd: torch.Tensor
        self.bank: torch.Tensor
        self.register_buffer("win_a", _f32(window[:LOGMEL_HOP]))
        self.register_buffer("win_b", _f32(window[LOGMEL_HOP:]))
        self.register_buffer("dft_even", _f32(dft(even)))
        self.register_buffer("dft_odd", _f32(dft(odd)))
        bank_t = bank.T
        self.register_buffer("bank", _f32(np.concatenate([bank_t[even]] * 2 + [bank_t[odd]] * 2)))

    def forward(self, audio: torch.Tensor) -> torch.Tensor:
        """(N, L, 2) -> (N, 2, T, M)."""
        _, length, channels = audio.shape
        frames = (length - 2 * self.hop) // self.hop + 1
        blocks = audio[:, : (frames + 1) * self.hop].transpose(1, 2)
        blocks = blocks.reshape(-1, channels, frames + 1, self.hop)
        a = blocks[:, :, :frames] * self.win_a
        b = blocks[:, :, 1:] * self.win_b
        spec = torch.cat([(a + b) @ self.dft_even, (a - b) @ self.dft_odd], dim=3)
        return torch.log((spec * spec) @ self.bank + LOG_MEL_FLOOR)


def _onnx_gate_order(m: torch.Tensor) -> torch.Tensor:
    """Gate blocks along dim 0 from torch's (input, forget, cell, output) to ONNX's (input, output, forget,
    cell)."""
    i, f, g, o = m.chunk(4, dim=0)
    return torch.cat([i, o, f, g])


def _torch_gate_order(m: torch.Tensor) -> torch.Tensor:
    """The inverse of `_onnx_gate_order`."""
    i, o, f, g = m.chunk(4, dim=0)
    return torch.cat([i, f, g, o])


@torch.library.custom_op("msvdd::lstm_layer", mutates_args=())
def lstm_layer(x: torch.Tensor, w: torch.Tensor, r: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """One forward LSTM layer from zero states: x (N, T, I) -> hidden states (N, T, H).

    The weights are in ONNX's layout (W (1, 4H, I), R (1, 4H, H), B (1, 8H), gates input, output, forget,
    cell), so that the exporter maps the op onto one ONNX LSTM node (`msvdd.export`) with nothing around it;
    here it runs as `torch.lstm`. As one opaque op, tracing it for export costs the same for any sequence
    length (the exporter otherwise traces the LSTM one time step at a time, with a symbolic batch size).
    """
    hidden = r.shape[2]
    params = [_torch_gate_order(w[0]), _torch_gate_order(r[0])]
    params += [_torch_gate_order(b[0, : 4 * hidden]), _torch_gate_order(b[0, 4 * hidden :])]
    zeros = x.new_zeros(1, x.shape[0], hidden)
    out, _, _ = torch.lstm(x, (zeros, zeros), params, True, 1, 0.0, False, False, True)
    return out


@lstm_layer.register_fake
def _lstm_layer_shape(x: torch.Tensor, w: torch.Tensor, r: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    return x.new_empty(x.shape[0], x.shape[1], r.shape[2])


class ExportLSTM(nn.Module):
    """A batch-first, one-directional `nn.LSTM` called without initial states, as `lstm_layer` ops.

    `forward(x)` returns `(output, None)`: the network's call sites read the output only.
    """

    def __init__(self, lstm: nn.LSTM) -> None:
        super().__init__()
        if not lstm.batch_first or lstm.bidirectional or lstm.proj_size or not lstm.bias:
            raise ValueError(f"unsupported LSTM {lstm} (batch first, one direction, biases, no projection)")
        self.layers = lstm.num_layers
        for k in range(self.layers):
            w_ih, w_hh, b_ih, b_hh = (
                getattr(lstm, f"{name}_l{k}").detach().cpu()
                for name in ("weight_ih", "weight_hh", "bias_ih", "bias_hh")
            )
            self.register_buffer(f"w{k}", _onnx_gate_order(w_ih)[None].contiguous())
            self.register_buffer(f"r{k}", _onnx_gate_order(w_hh)[None].contiguous())
            self.register_buffer(f"b{k}", torch.cat([_onnx_gate_order(b_ih), _onnx_gate_order(b_hh)])[None])

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, None]:
        """(N, T, I) -> ((N, T, H), None)."""
        for k in range(self.layers):
            w, r, b = (getattr(self, f"{name}{k}") for name in "wrb")
            x = lstm_layer(x, w, r, b)
        return x, None


def _export_lstms(module: nn.Module) -> None:
    """Replace, in place, every `nn.LSTM` inside `module` by its `ExportLSTM`."""
    for name, child in module.named_children():
        if isinstance(child, nn.LSTM):
            setattr(module, name, ExportLSTM(child))
        else:
            _export_lstms(child)


def _conv2d(conv: nn.Conv1d) -> nn.Conv2d:
    """The 1 x K 2-D convolution computing `conv` on (N, C, 1, L)."""
    if conv.groups != 1 or conv.dilation != (1,) or not isinstance(conv.padding, tuple):
        raise ValueError(f"unsupported convolution {conv}")
    out = nn.Conv2d(
        conv.in_channels,
        conv.out_channels,
        (1, conv.kernel_size[0]),
        stride=(1, conv.stride[0]),
        padding=(0, conv.padding[0]),
        bias=conv.bias is not None,
    )
    with torch.no_grad():
        out.weight.copy_(conv.weight[:, :, None, :])
        if conv.bias is not None and out.bias is not None:
            out.bias.copy_(conv.bias)
    return out


class PolyphaseUpsample(nn.Module):
    """A `ConvTranspose1d` of stride s, kernel s + 2 p and padding p (output length s L) on (N, C, 1, L).

    Output sample u s + r of channel o is sum_{c, m} W[c, o, m s + r + p] x[c, u - m] over the taps m with
    0 <= m s + r + p < kernel (|m| <= 1 + (p - 1) // s): an ordinary convolution of x for each phase r. One
    2-D convolution computes the s phases as s C_out output channels (phase r, channel o); the phases are
    then interleaved into (N, C_out, 1, s L).
    """

    def __init__(self, deconv: nn.ConvTranspose1d) -> None:
        super().__init__()
        if not isinstance(deconv.padding, tuple):
            raise ValueError(f"unsupported transposed convolution {deconv}")
        s, k, p = deconv.stride[0], deconv.kernel_size[0], deconv.padding[0]
        if deconv.groups != 1 or deconv.dilation != (1,) or deconv.output_padding != (0,) or k != s + 2 * p:
            raise ValueError(f"unsupported transposed convolution {deconv}")
        weight = deconv.weight.detach().cpu().to(torch.float64)  # (C_in, C_out, K)
        c_in, c_out = weight.shape[0], weight.shape[1]
        reach = 1 + (p - 1) // s if p > 0 else 0  # the taps m run over -reach..reach
        poly = torch.zeros(s, c_out, c_in, 2 * reach + 1, dtype=torch.float64)
        for r in range(s):
            for m in range(-reach, reach + 1):
                j = m * s + r + p
                if 0 <= j < k:
                    poly[r, :, :, reach - m] = weight[:, :, j].T  # correlation tap reach - m reads x[u - m]
        bias = torch.zeros(c_out) if deconv.bias is None else deconv.bias.detach().cpu()
        self.stride = s
        self.c_out = c_out
        self.conv = nn.Conv2d(c_in, s * c_out, (1, 2 * reach + 1), padding=(0, reach))
        with torch.no_grad():
            self.conv.weight.copy_(poly.reshape(s * c_out, c_in, 1, -1).to(torch.float32))
            assert self.conv.bias is not None
            self.conv.bias.copy_(bias.to(torch.float32).repeat(s))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(N, C_in, 1, L) -> (N, C_out, 1, s L)."""
        h = self.conv(x)
        if self.stride == 1:
            return h
        length = h.shape[3]
        h = h.reshape(-1, self.stride, self.c_out, length).permute(0, 2, 3, 1)
        return h.reshape(-1, self.c_out, 1, length * self.stride)


class AudioEncoder2d(nn.Module):
    """`msvdd.network.AudioEncoder` on (N, 2, 1, L) images: its convolutions as 1 x K 2-D ones, its LSTM."""

    def __init__(self, encoder: AudioEncoder) -> None:
        super().__init__()
        self.convs = nn.Sequential(*(_conv2d(m) if isinstance(m, nn.Conv1d) else m for m in encoder.convs))
        self.lstm = encoder.lstm

    def forward(self, audio: torch.Tensor) -> torch.Tensor:
        """(N, 2, 1, L) -> tokens (N, L / 180, d)."""
        h = self.convs(audio).flatten(2)
        tokens, _ = self.lstm(h.transpose(1, 2))
        return tokens


class AudioDecoder2d(nn.Module):
    """`msvdd.network.AudioDecoder` with (N, 2, 1, L) output, its transposed convolutions polyphase."""

    def __init__(self, decoder: AudioDecoder) -> None:
        super().__init__()
        self.deconvs = nn.Sequential(
            *(PolyphaseUpsample(m) if isinstance(m, nn.ConvTranspose1d) else m for m in decoder.deconvs)
        )

    def forward(self, tokens: torch.Tensor) -> torch.Tensor:
        """tokens (N, T_A, d) -> audio (N, 2, 1, 180 T_A)."""
        return self.deconvs(tokens.transpose(1, 2).unsqueeze(2))


def huber(x: torch.Tensor, x_hat: torch.Tensor) -> torch.Tensor:
    """Elementwise Huber loss (delta 1) of `x_hat` against `x`: c (|e| - c / 2), c = min(|e|, 1)."""
    err = (x_hat - x).abs()
    clipped = err.clamp(max=1.0)
    return clipped * (err - 0.5 * clipped)


class ScoreGraph(nn.Module):
    """A fitted `MSVDD`'s scoring path: (audio, imu[, imu6]) float32 windows -> (N,) float64 delta.

    The network's modules are a CPU copy of the model's (the model itself is left as it is), the waveform
    encoder and decoder rewritten as `AudioEncoder2d` and `AudioDecoder2d`, every LSTM as `ExportLSTM`.
    `forward` takes audio
    (N, 8820, 2), imu (N, 400) and, when the model reads all IMU axes, imu6 (N, 400, 6).
    """

    def __init__(self, model: MSVDD) -> None:
        super().__init__()
        cfg = model.config
        norm = model.normalizer
        if norm is None or model.mu_ is None or model.sigma_ is None:
            raise NotFittedError("MSVDD is not fitted: call fit() or MSVDD.load() before exporting")
        if cfg.order_view:
            raise ValueError(
                "order_view=True: the model reads the wheels' odometry, which the score graph's inputs "
                "(audio, imu, imu6) do not carry; export a model with order_view=False"
            )
        self.logmel_input = cfg.audio_frontend == "logmel"
        self.imu_all = cfg.imu_input == "all"
        self.has_term = model.has_term
        self.frame_density = cfg.frame_density
        net = copy.deepcopy(model.module.net).cpu().eval()
        _export_lstms(net)
        self.audio_encoder = (
            AudioEncoder2d(net.audio_encoder)
            if isinstance(net.audio_encoder, AudioEncoder)
            else net.audio_encoder
        )
        self.imu_encoder = net.imu_encoder
        self.fusion = net.fusion
        self.audio_decoder = (
            AudioDecoder2d(net.audio_decoder)
            if isinstance(net.audio_decoder, AudioDecoder)
            else net.audio_decoder
        )
        self.imu_decoder = net.imu_decoder
        window, order = cfg.smooth_window, cfg.smooth_polyorder
        self.logmel = LogMel() if self.logmel_input else None
        self.audio_smoother = (
            None if self.logmel_input else ChannelSmoother(norm.audio_mean, norm.audio_std, window, order)
        )
        self.imu_smoother = ChannelSmoother(norm.imu_mean, norm.imu_std, window, order)
        self.logmel_mean: torch.Tensor | None
        self.logmel_std: torch.Tensor | None
        self.mu: torch.Tensor
        self.whiten: torch.Tensor
        self.rec_scale: torch.Tensor
        # Log-mel statistics shaped to broadcast on (N, 2, T, M).
        stats = (norm.audio_mean, norm.audio_std) if self.logmel_input else (None, None)
        for name, value in zip(("logmel_mean", "logmel_std"), stats, strict=True):
            self.register_buffer(name, None if value is None else _f32(value).reshape(1, 2, 1, -1))
        sigma = model.sigma_.detach().cpu().to(torch.float64)
        chol = torch.linalg.cholesky(sigma)
        eye = torch.eye(sigma.shape[0], dtype=torch.float64)
        self.register_buffer("mu", model.mu_.detach().cpu().to(torch.float64).reshape(1, -1))
        self.register_buffer("whiten", torch.linalg.solve_triangular(chol, eye, upper=False).T.contiguous())
        self.register_buffer("rec_scale", _f64(np.asarray(model.rec_scale_, dtype=np.float64)))
        # `frame_density`: each modality's input-frame density network (`msvdd.context_net.ContextNet`).
        self.frame_nets = nn.ModuleDict()
        if cfg.frame_density:
            if model.frame_density_ is None:
                raise NotFittedError("MSVDD is not fitted: its frame density networks are missing")
            names = [name for name, used in (("audio", cfg.use_audio), ("imu", cfg.use_imu)) if used]
            for name, density in zip(names, model.frame_density_, strict=True):
                self.frame_nets[name] = copy.deepcopy(density).cpu().eval()
        mean_rec = model.mean_rec_ if model.has_term else 1.0
        self.rec_weight = float(cfg.w * model.mean_d_ / mean_rec)

    def audio_input(self, audio: torch.Tensor) -> torch.Tensor:
        """Normalised audio: log-mel (N, 2, 67, 32), or the smoothed waveform as (N, 2, 1, 8820)."""
        if self.logmel is not None and self.logmel_mean is not None and self.logmel_std is not None:
            return (self.logmel(audio) - self.logmel_mean) / self.logmel_std
        if self.audio_smoother is None:
            raise RuntimeError("ScoreGraph has neither a log-mel nor a waveform front end")
        return self.audio_smoother(audio.transpose(1, 2).unsqueeze(2))

    def imu_input(self, imu: torch.Tensor, imu6: torch.Tensor | None) -> torch.Tensor:
        """Normalised, smoothed IMU input of the network: (N, 400), or (N, 400, 7) for all axes."""
        if not self.imu_all:
            return self.imu_smoother(imu[:, None, None, :]).flatten(1)
        if imu6 is None:
            raise ValueError("this model reads all IMU axes: imu6 (N, 400, 6) is needed")
        channels = torch.cat([imu.unsqueeze(1), imu6.transpose(1, 2)], dim=1)
        return self.imu_smoother(channels.unsqueeze(2)).flatten(2).transpose(1, 2)

    def audio_error(self, a: torch.Tensor, a_rec: torch.Tensor) -> torch.Tensor:
        """(N,) mean Huber error of the audio input (log-mel (N, 2, T, M) or waveform (N, 2, 1, L)), as
        `MSVDD.rec_parts` measures it."""
        return huber(a, a_rec).mean(dim=(1, 2, 3))

    def imu_error(self, i: torch.Tensor, i_rec: torch.Tensor) -> torch.Tensor:
        """(N,) mean Huber error of the IMU input ((N, 400) or (N, 400, 7)), as `MSVDD.rec_parts` measures
        it."""
        err = huber(i, i_rec)
        return err.mean(dim=tuple(range(1, err.dim())))

    def input_term(self, a: torch.Tensor | None, i: torch.Tensor | None) -> torch.Tensor:
        """(N,) the frame-density term (`frame_density`): each used modality's largest input-frame distance
        under its density network (the IMU's given the audio frames too when it reads them), over its training
        mean, summed (as `MSVDD.frame_parts`)."""
        frames: dict[str, torch.Tensor] = {}
        if a is not None:
            frames["audio"] = (
                cut_frames(a, 2, 1)
                if self.logmel_input
                else cut_frames(a.squeeze(2).transpose(1, 2), 1, AUDIO_SAMPLES_PER_TOKEN)
            )
        if i is not None:
            frames["imu"] = cut_frames(i, 1, IMU_FRAME)
        parts = []
        for name, x in frames.items():
            net = self.frame_nets[name]
            if not isinstance(net, ContextNet):
                raise TypeError(f"frame_nets[{name!r}] is not a ContextNet")
            cross = frames["audio"] if net.cross_p > 0 else None
            nll = net.window_nll(x, cross).to(torch.float64).amax(dim=1)
            parts.append(torch.sqrt(2.0 * (nll - net.floor).clamp_min(0.0)))
        return (torch.stack(parts, dim=1) / self.rec_scale[: len(parts)]).sum(dim=1)

    def forward(
        self, audio: torch.Tensor, imu: torch.Tensor, imu6: torch.Tensor | None = None
    ) -> torch.Tensor:
        """(N,) float64 anomaly scores delta = D + w (mean_D / mean_Rec) Rec."""
        a = a_tokens = i = i_tokens = None
        if self.audio_encoder is not None:
            a = self.audio_input(audio)
            a_tokens = self.audio_encoder(a)
        if self.imu_encoder is not None:
            i = self.imu_input(imu, imu6)
            i_tokens = self.imu_encoder(i)
        z = self.fusion(a_tokens, i_tokens).z
        y = (z.to(torch.float64) - self.mu) @ self.whiten
        score = torch.sqrt((y * y).sum(dim=1))
        if not self.has_term:
            return score
        if self.frame_density:
            return score + self.rec_weight * self.input_term(a, i)
        parts = []
        if self.audio_decoder is not None and a is not None and a_tokens is not None:
            parts.append(self.audio_error(a, self.audio_decoder(a_tokens)))
        if self.imu_decoder is not None and i is not None and i_tokens is not None:
            parts.append(self.imu_error(i, self.imu_decoder(i_tokens)))
        if parts:
            rec = (torch.stack(parts, dim=1).to(torch.float64) / self.rec_scale[: len(parts)]).sum(dim=1)
            score = score + self.rec_weight * rec
        return score
