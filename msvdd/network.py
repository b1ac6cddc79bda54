"""The paper's audio-IMU network: encoders emitting token sequences, fusion, and decoders.

Shapes (defaults, d = 32, s = 32):

- audio (N, 8820, 2) -> `AudioEncoder` (six strided 1-D convolutions, then an LSTM) -> (N, 49, d) tokens,
  one per 180 audio samples (40.8 ms, matching the 40 ms IMU tokens).
- or, with the spectrogram front end, log-mel (N, 2, 67, 32) -> `LogMelEncoder` (three 3x3 2-D convolutions,
  the last two halving the mel axis, then an LSTM over frames) -> (N, 67, d) tokens, one per 29 ms frame.
- imu (N, 400) (or (N, 400, 7) with all axes) -> frames of 8 samples (40 ms) -> `ImuEncoder` (two LSTM
  layers) -> (N, 50, d) tokens.
- `Fusion("cross_attention")`: audio tokens query IMU tokens and IMU tokens query audio tokens
  (softmax(Q K^T / sqrt(d)) V over the real sequences), each followed by an MLP with residuals, pooled
  (`pool`: mean + max over tokens, a mean alone dilutes a 30 ms impact among 49 tokens; or statistics
  pooling, mean, std and max side by side; or modulation pooling, the std split into octave bands of
  modulation frequency), summed and projected to s. The ablation variants concatenate,
  add or multiply the pooled encoder features.
- With `order_view`, every pooled sequence also carries its order amplitudes (`order_amplitudes`): each
  token feature's once-, twice-, ... per-revolution line in each wheel's angle from the encoders (the
  odometry, resampled to the token times by `token_angles`), the largest over the wheels: an order-domain
  view in which a defect that repeats once per revolution stands out at any speed.
- `AudioDecoder` (six transposed convolutions), `LogMelDecoder` (a per-frame MLP) and `ImuDecoder` (LSTM
  layers) reconstruct the inputs from the encoders' token sequences.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import torch
from torch import nn

from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE
from msvdd.frontend import (
    IMU_ALL_CHANNELS,
    LOGMEL_FRAMES,
    LOGMEL_HOP,
    LOGMEL_N_FFT,
    LOGMEL_N_MELS,
    check_frontend,
)

FUSIONS = ("cross_attention", "concat", "sum", "product")
"""Fusion variants: the paper's cross-attention and the three ablation alternatives."""
POOLINGS = ("mean+max", "stats", "modulation")
"""How a token sequence is pooled before the projection to z (`pool`)."""
MODULATION_EDGES = (1, 2, 4, 8, 16)
"""Lower edges of the "modulation" pooling's octave bands, in DFT bins over a window's tokens (k cycles per
window: k / 2 Hz for a 2 s window); the last band reaches the tokens' Nyquist bin. Bin 1 alone is half a
hertz, a once-per-revolution defect at a slow 0.5 rev/s; its rhythm at 1 rev/s and its harmonics land in
the next bands."""

ORDERS = (1, 2, 3, 4)
"""Orders of wheel revolution (cycles per revolution) whose amplitudes `order_amplitudes` reads: a flat spot,
a corner's rise and a loose hub's wobble repeat once per revolution, an oval wheel twice, and a strike's
harmonics fill the next orders; at 2 rev/s order 4 is 8 Hz, under the tokens' Nyquist rate (12-17 Hz)."""

AUDIO_STRIDES = (5, 3, 3, 2, 2, 1)
"""Stride of each of the six audio convolutions; their product (180) is the audio samples per token."""
AUDIO_CHANNELS = (16, 32, 48, 64, 64, 64)
"""Output channels of each audio convolution."""
AUDIO_TOKENS = AUDIO_LEN // math.prod(AUDIO_STRIDES)
"""Audio tokens per window (49)."""
IMU_FRAME = 8
"""IMU samples per IMU token (40 ms at 200 Hz)."""
IMU_TOKENS = IMU_LEN // IMU_FRAME
"""IMU tokens per window (50)."""
LOGMEL_CHANNELS = (16, 32, 32)
"""Output channels of the log-mel encoder's three 2-D convolutions."""


class NetConfig(Protocol):
    """The fields of `MSVDDConfig` the network reads (any object with them will do)."""

    @property
    def d(self) -> int: ...
    @property
    def s(self) -> int: ...
    @property
    def fusion(self) -> str: ...
    @property
    def pooling(self) -> str: ...
    @property
    def use_audio(self) -> bool: ...
    @property
    def use_imu(self) -> bool: ...
    @property
    def use_reconstruction(self) -> bool: ...
    @property
    def audio_frontend(self) -> str: ...
    @property
    def imu_input(self) -> str: ...
    @property
    def order_view(self) -> bool: ...


def _conv_padding(stride: int) -> tuple[int, int]:
    """(kernel, padding) so that a convolution maps length L (divisible by stride) to L / stride."""
    pad = max(1, stride // 2 + 1)
    return stride + 2 * pad, pad


def modulation_bands(tokens: torch.Tensor) -> torch.Tensor:
    """(N, T, d) -> (N, len(`MODULATION_EDGES`), d): the RMS of each feature's deviation from its mean over
    the tokens in each octave band of modulation frequency (`MODULATION_EDGES`): the square root of the
    band's share of the one-sided DFT power over the tokens. The bands' squares sum to the population
    variance over the tokens (Parseval): the standard deviation split by how fast the feature swings, so
    that a rhythm (a defect striking once per revolution) and its rate stay apart from noise of the same
    level. The DFT is a product with a cosine and a sine basis (traceable for ONNX)."""
    t = tokens.shape[1]
    bins = torch.arange(t // 2 + 1, dtype=tokens.dtype, device=tokens.device)
    steps = torch.arange(t, dtype=tokens.dtype, device=tokens.device)
    phase = (2 * math.pi / t) * bins[:, None] * steps[None, :]  # (K, T)
    centred = tokens - tokens.mean(dim=1, keepdim=True)
    power = torch.einsum("kt,ntd->nkd", torch.cos(phase), centred) ** 2
    power = power + torch.einsum("kt,ntd->nkd", torch.sin(phase), centred) ** 2
    weight = torch.full((t // 2 + 1,), 2.0, dtype=tokens.dtype, device=tokens.device)
    if t % 2 == 0:
        weight[-1] = 1.0  # the Nyquist bin has no mirror image
    power = power * weight[None, :, None] / t**2
    edges = [*MODULATION_EDGES, t // 2 + 1]
    return torch.stack(
        [torch.sqrt(power[:, lo:hi].sum(dim=1) + 1e-12) for lo, hi in itertools.pairwise(edges)],
        dim=1,
    )


def token_times(modality: str, audio_frontend: str = "logmel") -> np.ndarray:
    """(T,) the centre of each token of `modality` ("audio" or "imu") in a window, in seconds from its first
    sample: a log-mel frame's (`LOGMEL_N_FFT` samples every `LOGMEL_HOP`), a waveform token's (180 samples)
    or an IMU token's (`IMU_FRAME` samples)."""
    if modality == "imu":
        return (np.arange(IMU_TOKENS) * IMU_FRAME + (IMU_FRAME - 1) / 2) / IMU_RATE
    if audio_frontend == "logmel":
        return (np.arange(LOGMEL_FRAMES) * LOGMEL_HOP + (LOGMEL_N_FFT - 1) / 2) / AUDIO_RATE
    step = math.prod(AUDIO_STRIDES)
    return (np.arange(AUDIO_TOKENS) * step + (step - 1) / 2) / AUDIO_RATE


def interpolation_matrix(times: np.ndarray, rate: float = IMU_RATE, length: int = IMU_LEN) -> np.ndarray:
    """(T, length) float32 weights that read a signal sampled at `rate` (`length` samples from time 0) at
    `times` by linear interpolation (clamped to the first and last sample)."""
    pos = np.clip(np.asarray(times, dtype=np.float64) * rate, 0.0, length - 1.0)
    lo = np.minimum(np.floor(pos).astype(np.int64), length - 2)
    frac = pos - lo
    out = np.zeros((len(pos), length), dtype=np.float64)
    rows = np.arange(len(pos))
    out[rows, lo] = 1.0 - frac
    out[rows, lo + 1] = frac
    return out.astype(np.float32)


def token_angles(odometry: torch.Tensor, matrix: torch.Tensor) -> torch.Tensor:
    """Wheel angles (N, 400, W) at 200 Hz -> (N, T, W) at the token times `matrix` (`interpolation_matrix`)
    reads; angles unwrapped by the encoders, so that linear interpolation is exact for a steady wheel."""
    return torch.einsum("tl,nlw->ntw", matrix, odometry)


def order_amplitudes(tokens: torch.Tensor, angles: torch.Tensor) -> torch.Tensor:
    """(N, T, d) tokens, (N, T, W) each wheel's angle at the tokens (rad) -> (N, len(`ORDERS`), d): for each
    order k, the amplitude of each feature's line at k cycles per revolution of a wheel (twice the modulus
    of the mean of its deviation from its mean times exp(-i k angle): a feature that swings as A cos(k angle
    + phase) over whole revolutions of a steadily turning wheel reads A; over part of a revolution or at a
    changing speed, part of it leaks into the other orders), the largest over the wheels. The order
    domain: a defect that repeats once per revolution of its wheel is one line at any speed, where in time
    it moves with the speed; a wheel that does not turn reads about 0."""
    centred = tokens - tokens.mean(dim=1, keepdim=True)
    t = tokens.shape[1]
    out = []
    for k in ORDERS:
        phase = k * angles  # (N, T, W)
        re = torch.einsum("ntw,ntd->nwd", torch.cos(phase), centred)
        im = torch.einsum("ntw,ntd->nwd", torch.sin(phase), centred)
        amplitude = (2.0 / t) * torch.sqrt(re**2 + im**2 + 1e-12)
        out.append(amplitude.amax(dim=1))
    return torch.stack(out, dim=1)


def pool(tokens: torch.Tensor, kind: str = "mean+max", angles: torch.Tensor | None = None) -> torch.Tensor:
    """(N, T, d) -> (N, d) mean + max over the tokens (the max keeps short transients such as impacts); or,
    `kind` "stats", (N, 3 d) their mean, standard deviation and max side by side (statistics pooling); or,
    `kind` "modulation", (N, (2 + len(`MODULATION_EDGES`)) d) their mean, max and the standard deviation
    split into octave bands of modulation frequency (`modulation_bands`). With the wheels' `angles` at the
    tokens (N, T, W) (the order view), their `order_amplitudes` follow, len(`ORDERS`) d more."""
    if kind == "stats":
        pooled = torch.cat([tokens.mean(dim=1), tokens.std(dim=1), tokens.amax(dim=1)], dim=1)
    elif kind == "modulation":
        bands = modulation_bands(tokens).flatten(1)
        pooled = torch.cat([tokens.mean(dim=1), tokens.amax(dim=1), bands], dim=1)
    else:
        pooled = tokens.mean(dim=1) + tokens.amax(dim=1)
    if angles is None:
        return pooled
    return torch.cat([pooled, order_amplitudes(tokens, angles).flatten(1)], dim=1)


def pooled_width(d: int, kind: str, order_view: bool = False) -> int:
    """Width of `pool`'s output for d-wide tokens (with the order view's amplitudes if `order_view`)."""
    base = {"stats": 3 * d, "modulation": (2 + len(MODULATION_EDGES)) * d}.get(kind, d)
    return base + (len(ORDERS) * d if order_view else 0)


class AudioEncoder(nn.Module):
    """CRNN: six 1-D convolutions (strided, ReLU) and one LSTM; (N, 8820, 2) -> (N, T_A, d) tokens."""

    def __init__(self, d: int) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        c_in = 2
        for stride, c_out in zip(AUDIO_STRIDES, AUDIO_CHANNELS, strict=True):
            kernel, pad = _conv_padding(stride)
            layers += [nn.Conv1d(c_in, c_out, kernel, stride=stride, padding=pad), nn.GELU()]
            c_in = c_out
        self.convs = nn.Sequential(*layers)
        self.lstm = nn.LSTM(c_in, d, batch_first=True)

    def forward(self, audio: torch.Tensor) -> torch.Tensor:
        """audio (N, L, 2) -> tokens (N, L / 180, d)."""
        h = self.convs(audio.transpose(1, 2))
        tokens, _ = self.lstm(h.transpose(1, 2))
        return tokens


class LogMelEncoder(nn.Module):
    """2-D CNN over (channel, frame, mel) and an LSTM over frames; (N, 2, T, M) -> (N, T, d) tokens."""

    def __init__(self, d: int, n_mels: int = LOGMEL_N_MELS) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        c_in, width = 2, n_mels
        for i, c_out in enumerate(LOGMEL_CHANNELS):
            stride = (1, 1) if i == 0 else (1, 2)
            layers += [nn.Conv2d(c_in, c_out, 3, stride=stride, padding=1), nn.GELU()]
            c_in, width = c_out, width if i == 0 else (width + 1) // 2
        self.convs = nn.Sequential(*layers)
        self.lstm = nn.LSTM(c_in * width, d, batch_first=True)

    def forward(self, logmel: torch.Tensor) -> torch.Tensor:
        """logmel (N, 2, T, M) -> tokens (N, T, d)."""
        h = self.convs(logmel)  # (N, C, T, M')
        tokens, _ = self.lstm(h.permute(0, 2, 1, 3).flatten(2))
        return tokens


class LogMelDecoder(nn.Module):
    """A per-frame MLP from each token to that frame's two log-mel spectra; (N, T, d) -> (N, 2, T, M)."""

    def __init__(self, d: int, n_mels: int = LOGMEL_N_MELS) -> None:
        super().__init__()
        self.n_mels = n_mels
        self.mlp = nn.Sequential(nn.Linear(d, 4 * d), nn.GELU(), nn.Linear(4 * d, 2 * n_mels))

    def forward(self, tokens: torch.Tensor) -> torch.Tensor:
        """tokens (N, T, d) -> log-mel (N, 2, T, M)."""
        out = self.mlp(tokens)  # (N, T, 2 M)
        return out.reshape(out.shape[0], out.shape[1], 2, self.n_mels).transpose(1, 2)


class ImuEncoder(nn.Module):
    """Two LSTM layers over 8-sample IMU frames; (N, 400) or (N, 400, C) -> (N, 50, d) tokens."""

    def __init__(self, d: int, channels: int = 1) -> None:
        super().__init__()
        self.lstm = nn.LSTM(IMU_FRAME * channels, d, num_layers=2, batch_first=True)

    def forward(self, imu: torch.Tensor) -> torch.Tensor:
        """imu (N, 400) or (N, 400, C) -> tokens (N, 50, d)."""
        frames = imu.reshape(imu.shape[0], IMU_TOKENS, -1)
        tokens, _ = self.lstm(frames)
        return tokens


class AudioDecoder(nn.Module):
    """Six 1-D transposed convolutions mirroring `AudioEncoder`; (N, T_A, d) -> (N, 8820, 2)."""

    def __init__(self, d: int) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        chans = (d, *reversed(AUDIO_CHANNELS[:-1]))
        outs = (*reversed(AUDIO_CHANNELS[:-1]), 2)
        for i, (stride, c_in, c_out) in enumerate(zip(reversed(AUDIO_STRIDES), chans, outs, strict=True)):
            kernel, pad = _conv_padding(stride)
            layers.append(nn.ConvTranspose1d(c_in, c_out, kernel, stride=stride, padding=pad))
            if i < len(AUDIO_STRIDES) - 1:
                layers.append(nn.GELU())
        self.deconvs = nn.Sequential(*layers)

    def forward(self, tokens: torch.Tensor) -> torch.Tensor:
        """tokens (N, T_A, d) -> audio (N, 180 T_A, 2)."""
        out = self.deconvs(tokens.transpose(1, 2))
        return out.transpose(1, 2)


class ImuDecoder(nn.Module):
    """Two LSTM layers and a linear read-out of 8 samples per token; (N, 50, d) -> (N, 400) or (N, 400, C)."""

    def __init__(self, d: int, channels: int = 1) -> None:
        super().__init__()
        self.channels = channels
        self.lstm = nn.LSTM(d, d, num_layers=2, batch_first=True)
        self.out = nn.Linear(d, IMU_FRAME * channels)

    def forward(self, tokens: torch.Tensor) -> torch.Tensor:
        """tokens (N, T_I, d) -> imu (N, 8 T_I), or (N, 8 T_I, C) for C > 1 channels."""
        h, _ = self.lstm(tokens)
        out = self.out(h).reshape(tokens.shape[0], -1, self.channels)
        return out[:, :, 0] if self.channels == 1 else out


class CrossAttentionBlock(nn.Module):
    """Single-head cross-attention softmax(Q K^T / sqrt(d)) V, then an MLP; both with residuals."""

    def __init__(self, d: int) -> None:
        super().__init__()
        self.norm_q = nn.LayerNorm(d)
        self.norm_kv = nn.LayerNorm(d)
        self.q = nn.Linear(d, d)
        self.k = nn.Linear(d, d)
        self.v = nn.Linear(d, d)
        self.o = nn.Linear(d, d)
        self.norm_mlp = nn.LayerNorm(d)
        self.mlp = nn.Sequential(nn.Linear(d, 2 * d), nn.GELU(), nn.Linear(2 * d, d))
        self.scale = 1.0 / math.sqrt(d)

    def attention(self, queries: torch.Tensor, context: torch.Tensor) -> torch.Tensor:
        """(N, Tq, Tk) attention weights of `queries` (N, Tq, d) over `context` (N, Tk, d)."""
        q = self.q(self.norm_q(queries))
        k = self.k(self.norm_kv(context))
        return torch.softmax(q @ k.transpose(1, 2) * self.scale, dim=-1)

    def forward(self, queries: torch.Tensor, context: torch.Tensor) -> torch.Tensor:
        """queries (N, Tq, d), context (N, Tk, d) -> (N, Tq, d)."""
        weights = self.attention(queries, context)
        h = queries + self.o(weights @ self.v(self.norm_kv(context)))
        return h + self.mlp(self.norm_mlp(h))


@dataclass
class FusionOutput:
    """What `Fusion` returns."""

    z: torch.Tensor
    """(N, s) fused feature."""
    fused_a: torch.Tensor | None
    """(N, d) pooled audio branch after fusion (z_IA: audio queries IMU); None if not applicable."""
    fused_i: torch.Tensor | None
    """(N, d) pooled IMU branch after fusion (z_AI: IMU queries audio); None if not applicable."""


class Fusion(nn.Module):
    """Fuses audio and IMU token sequences into z (N, s): cross-attention, concat, sum or product.

    With only one modality present, the pooled tokens of that modality are projected to s. With
    `order_view`, each sequence is pooled with the wheels' angles at its tokens (`pool`).
    """

    def __init__(
        self,
        d: int,
        s: int,
        kind: str,
        use_audio: bool = True,
        use_imu: bool = True,
        pooling: str = "mean+max",
        order_view: bool = False,
    ) -> None:
        super().__init__()
        if kind not in FUSIONS:
            raise ValueError(f"fusion {kind!r}; allowed: {', '.join(FUSIONS)}")
        if pooling not in POOLINGS:
            raise ValueError(f"pooling {pooling!r}; allowed: {', '.join(POOLINGS)}")
        if not (use_audio or use_imu):
            raise ValueError("use_audio and use_imu are both False; at least one modality is needed")
        self.kind = kind
        self.pooling = pooling
        self.order_view = order_view
        self.both = use_audio and use_imu
        self.audio_queries_imu: CrossAttentionBlock | None = None
        self.imu_queries_audio: CrossAttentionBlock | None = None
        if self.both and kind == "cross_attention":
            self.audio_queries_imu = CrossAttentionBlock(d)
            self.imu_queries_audio = CrossAttentionBlock(d)
        width = pooled_width(d, pooling, order_view)
        self.project = nn.Linear(2 * width if (self.both and kind == "concat") else width, s)

    def forward(
        self,
        audio_tokens: torch.Tensor | None,
        imu_tokens: torch.Tensor | None,
        audio_angles: torch.Tensor | None = None,
        imu_angles: torch.Tensor | None = None,
    ) -> FusionOutput:
        """Token sequences (N, T, d) (None for an absent modality) and, with `order_view`, the wheels'
        angles at their tokens (N, T, W) -> `FusionOutput`."""
        missing_a = audio_tokens is not None and audio_angles is None
        missing_i = imu_tokens is not None and imu_angles is None
        if self.order_view and (missing_a or missing_i):
            raise ValueError("order_view: the wheels' angles at the tokens (from the odometry) are needed")
        if audio_tokens is None or imu_tokens is None:
            tokens = audio_tokens if audio_tokens is not None else imu_tokens
            if tokens is None:
                raise ValueError("Fusion needs at least one token sequence")
            angles = audio_angles if audio_tokens is not None else imu_angles
            return FusionOutput(z=self.project(self.pool(tokens, angles)), fused_a=None, fused_i=None)
        if self.audio_queries_imu is not None and self.imu_queries_audio is not None:
            z_ia = self.pool(self.audio_queries_imu(audio_tokens, imu_tokens), audio_angles)
            z_ai = self.pool(self.imu_queries_audio(imu_tokens, audio_tokens), imu_angles)
            return FusionOutput(z=self.project(z_ia + z_ai), fused_a=z_ia, fused_i=z_ai)
        z_a, z_i = self.pool(audio_tokens, audio_angles), self.pool(imu_tokens, imu_angles)
        if self.kind == "concat":
            fused = torch.cat([z_a, z_i], dim=1)
        elif self.kind == "sum":
            fused = z_a + z_i
        else:
            fused = z_a * z_i
        return FusionOutput(z=self.project(fused), fused_a=None, fused_i=None)

    def pool(self, tokens: torch.Tensor, angles: torch.Tensor | None) -> torch.Tensor:
        """`pool` with this fusion's kind and the angles (given with `order_view` only)."""
        return pool(tokens, self.pooling, angles)


@dataclass
class NetOutput:
    """What `FusionNet.forward` returns (None where a modality or branch is switched off)."""

    z: torch.Tensor
    """(N, s) fused embedding."""
    audio_tokens: torch.Tensor | None
    """(N, T_A, d) audio encoder tokens."""
    imu_tokens: torch.Tensor | None
    """(N, T_I, d) IMU encoder tokens."""
    z_a: torch.Tensor | None
    """(N, d) pooled audio encoder feature (`pool`; (N, 3 d) with statistics pooling)."""
    z_i: torch.Tensor | None
    """(N, d) pooled IMU encoder feature (likewise)."""
    fused_a: torch.Tensor | None
    """(N, d) pooled audio branch after cross-attention (z_IA; likewise)."""
    fused_i: torch.Tensor | None
    """(N, d) pooled IMU branch after cross-attention (z_AI; likewise)."""
    audio_rec: torch.Tensor | None
    """Reconstructed audio input: (N, 8820, 2) waveform or (N, 2, 67, 32) log-mel."""
    imu_rec: torch.Tensor | None
    """Reconstructed IMU input: (N, 400) or (N, 400, 7)."""


class FusionNet(nn.Module):
    """Encoders, fusion and decoders as switched by the config (use_audio, use_imu, use_reconstruction,
    order_view)."""

    def __init__(self, config: NetConfig) -> None:
        super().__init__()
        d, s = config.d, config.s
        check_frontend(config.audio_frontend, config.imu_input)
        self.use_audio = config.use_audio
        self.use_imu = config.use_imu
        self.order_view = config.order_view
        logmel = config.audio_frontend == "logmel"
        imu_channels = IMU_ALL_CHANNELS if config.imu_input == "all" else 1
        # Modules are built in this order so that a seed gives the same initial weights as before.
        self.audio_encoder: nn.Module | None = None
        if config.use_audio:
            self.audio_encoder = LogMelEncoder(d) if logmel else AudioEncoder(d)
        self.imu_encoder = ImuEncoder(d, imu_channels) if config.use_imu else None
        self.fusion = Fusion(
            d, s, config.fusion, config.use_audio, config.use_imu, config.pooling, config.order_view
        )
        rec = config.use_reconstruction
        self.audio_decoder: nn.Module | None = None
        if rec and config.use_audio:
            self.audio_decoder = LogMelDecoder(d) if logmel else AudioDecoder(d)
        self.imu_decoder = ImuDecoder(d, imu_channels) if (rec and config.use_imu) else None
        self.audio_angle_reader: torch.Tensor
        self.imu_angle_reader: torch.Tensor
        audio_times = token_times("audio", config.audio_frontend)
        self.register_buffer(
            "audio_angle_reader", torch.from_numpy(interpolation_matrix(audio_times)), persistent=False
        )
        self.register_buffer(
            "imu_angle_reader", torch.from_numpy(interpolation_matrix(token_times("imu"))), persistent=False
        )

    def forward(
        self, audio: torch.Tensor, imu: torch.Tensor, odometry: torch.Tensor | None = None
    ) -> NetOutput:
        """audio (N, 8820, 2) or log-mel (N, 2, 67, 32), imu (N, 400) or (N, 400, 7), normalised, and with
        `order_view` the wheels' encoder angles (N, 400, W) (rad, from the window's first sample) ->
        output."""
        a_ang = i_ang = None
        if self.order_view and odometry is not None:  # without it, the fusion says what is missing
            a_ang = token_angles(odometry, self.audio_angle_reader)
            i_ang = token_angles(odometry, self.imu_angle_reader)
        a_tok = self.audio_encoder(audio) if self.audio_encoder is not None else None
        i_tok = self.imu_encoder(imu) if self.imu_encoder is not None else None
        fused = self.fusion(a_tok, i_tok, a_ang, i_ang)
        a_rec = self.audio_decoder(a_tok) if (self.audio_decoder is not None and a_tok is not None) else None
        i_rec = self.imu_decoder(i_tok) if (self.imu_decoder is not None and i_tok is not None) else None
        return NetOutput(
            z=fused.z,
            audio_tokens=a_tok,
            imu_tokens=i_tok,
            z_a=None if a_tok is None else self.fusion.pool(a_tok, a_ang),
            z_i=None if i_tok is None else self.fusion.pool(i_tok, i_ang),
            fused_a=fused.fused_a,
            fused_i=fused.fused_i,
            audio_rec=a_rec,
            imu_rec=i_rec,
        )
