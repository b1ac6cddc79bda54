"""`MSVDDConfig`: every hyper-parameter of the detector, with the paper's values as defaults."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Self

from msvdd.frontend import AUDIO_FRONTENDS, IMU_INPUTS
from msvdd.mcd import MCDError, support_size
from msvdd.network import FUSIONS, POOLINGS

SVDD_FITS = ("batch", "frozen")
"""Allowed `svdd_fit` values: how mu and Sigma of the training loss are estimated."""
RETIRED_FIELDS = ("rec_components",)
"""Fields of earlier configurations that `from_dict` drops (the residual frame mixtures' size, which only the
retired `rec_score` values "mixture" and "context" read)."""
LEGACY_REC_SCORES = ("mean", "fused")
"""`rec_score` values of configurations saved before the field was retired, which `from_dict` translates:
"mean" is the decoders' reconstruction error (now always the reconstruction term), "fused" the frame-density
term, now `frame_density=True` (it was only in the score while `use_reconstruction` was True)."""
DEVICES = ("cpu", "cuda", "auto")
"""Allowed `device` values ("auto" = CUDA when available, else CPU)."""


@dataclass(frozen=True)
class MSVDDConfig:
    """M-SVDD hyper-parameters (paper, Implementation details) and ablation switches."""

    d: int = 32
    """Token / per-modality feature dimension."""
    s: int = 32
    """Dimension of the fused latent space where the ellipsoid lives."""
    fusion: str = "cross_attention"
    """Fusion: "cross_attention" (paper), or the ablation's "concat", "sum", "product"."""
    pooling: str = "mean+max"
    """How the fusion pools a token sequence before projecting it to z: "mean+max" (their sum per feature: a
    max keeps a short transient that a mean over the tokens dilutes), "stats" (statistics pooling: mean,
    standard deviation and max over the tokens side by side, so that level, rhythm and peak stay apart) or
    "modulation" (mean, max and the standard deviation split into octave bands of modulation frequency, so
    that a rhythm's rate stays apart too; `msvdd.network.modulation_bands`)."""
    order_view: bool = False
    """Also pool each token sequence in the wheels' angle domain (`msvdd.network.order_amplitudes`: the
    tokens' lines at 1-4 cycles per wheel revolution, from the windows' wheel odometry, which the model then
    needs); False: the tokens in time only."""
    audio_frontend: str = "waveform"
    """Audio input: "waveform" (paper: raw-waveform CRNN) or "logmel" (spectrogram 2-D CNN); see frontend."""
    imu_input: str = "z"
    """IMU input: "z" (paper, z-axis velocity) or "all" (z-velocity, accelerometer and gyroscope xyz)."""
    use_audio: bool = True
    """Use the audio modality (False = IMU-only ablation)."""
    use_imu: bool = True
    """Use the IMU modality (False = audio-only ablation)."""
    use_reconstruction: bool = True
    """Train the decoders and score their reconstruction error Rec (False = "w/o reconstruction" ablation:
    no decoders, score D alone)."""
    use_mahalanobis: bool = True
    """Mahalanobis SVDD with MCD (False = Euclidean Deep SVDD with the same network)."""
    svdd_fit: str = "batch"
    """How the training loss gets mu and Sigma. "batch" (the paper): MCD on each batch, differentiable in z,
    with the covariance regulariser; over the MCD support the batch's mean squared distance is
    sum lambda / (lambda + eps) whatever z is (`msvdd.losses`), so it can only learn to shrink eigenvalues.
    "frozen": like Deep SVDD's fixed centre, mu and Sigma by MCD over the embeddings of the whole training
    split after `stats_warmup` epochs and every `stats_every` epochs after that, held fixed in between,
    Sigma's eigenvalues floored at `variance_floor` times their mean; the loss is the mean squared Mahalanobis
    distance under them plus the reconstruction loss (no radius, no regulariser), and the last epoch is kept
    (validation losses under different statistics do not compare)."""
    stats_warmup: int = 1
    """`svdd_fit="frozen"`: epochs trained on the reconstruction loss alone before the first estimate (Deep
    SVDD's autoencoder pre-training; 0, or without reconstruction: the first estimate is of the initial
    network)."""
    stats_every: int = 5
    """`svdd_fit="frozen"`: epochs between two estimates of mu and Sigma."""
    variance_floor: float = 0.01
    """`svdd_fit="frozen"`: Sigma's eigenvalues are raised to at least this fraction of their mean (a bound
    on the condition number that does not depend on the embeddings' scale; eps I is added too)."""
    bias_free: bool = False
    """Biases of the encoders and the fusion (everything z depends on) fixed at 0, as Deep SVDD requires: no
    constant z but 0 is reachable by the network."""
    alpha: tuple[float, float, float] = (1.0, 1.0, 0.001)
    """Loss weights of the SVDD, reconstruction and covariance-regulariser terms."""
    eps: float = 1e-3
    """Ridge eps*I added to Sigma, and eps in the regulariser's denominators."""
    nu: float = 1.0
    """Soft-boundary nu: loss R^2 + 1/(nu N) sum max(0, D^2 - R^2); 1 = the paper's mean."""
    w: float = 0.01
    """Weight of the scaled reconstruction loss in the anomaly score."""
    frame_density: bool = False
    """Score a frame-density term in place of Rec: per modality the largest distance of a normalised input
    frame under a mixture density network of the training input frames given its neighbours and, for the IMU
    of an audio-IMU model, the audio frames around it, over its training mean, summed (`msvdd.context_net`).
    Not the paper's model and not read from the network: the `frame-density-msvdd` method. The decoders
    still train when `use_reconstruction` is True, but do not score."""
    batch_size: int = 64
    """Training batch size (and MCD batch)."""
    lr: float = 1e-4
    """Adam initial learning rate."""
    cosine_decay: bool = True
    """Cosine-decay the learning rate to 0 over the training steps."""
    epochs: int = 40
    """Training epochs."""
    mcd_support_fraction: float | None = None
    """MCD support h/n; None = ceil((n + s + 1) / 2) (must give h < n for a batch)."""
    mcd_trials: int = 30
    """FastMCD random starts."""
    quantile: float = 0.95
    """Threshold = this quantile of the training scores."""
    val_fraction: float = 0.1
    """Fraction of the training windows held out for model selection when no val set is given."""
    smooth_window: int = 5
    """Savitzky-Golay smoothing window (samples, odd; 0 = off), applied per window after z-scoring."""
    smooth_polyorder: int = 2
    """Savitzky-Golay polynomial order."""
    seed: int = 0
    """Seed of every random draw (initialisation, shuffling, splits, MCD starts)."""
    device: str = "cpu"
    """Torch device: "cpu", "cuda" or "auto"."""
    progress: bool = True
    """Show a progress bar while training."""

    def __post_init__(self) -> None:
        _check(self.d >= 1, "d", self.d, ">= 1")
        _check(self.s >= 1, "s", self.s, ">= 1")
        _check(self.fusion in FUSIONS, "fusion", self.fusion, " | ".join(FUSIONS))
        _check(self.pooling in POOLINGS, "pooling", self.pooling, " | ".join(POOLINGS))
        _check(
            self.audio_frontend in AUDIO_FRONTENDS,
            "audio_frontend",
            self.audio_frontend,
            " | ".join(AUDIO_FRONTENDS),
        )
        _check(self.imu_input in IMU_INPUTS, "imu_input", self.imu_input, " | ".join(IMU_INPUTS))
        _check(self.use_audio or self.use_imu, "use_audio/use_imu", False, "at least one modality True")
        _check(len(self.alpha) == 3 and all(a >= 0 for a in self.alpha), "alpha", self.alpha, "3 values >= 0")
        _check(self.eps > 0, "eps", self.eps, "> 0")
        _check(0 < self.nu <= 1, "nu", self.nu, "0 < nu <= 1")
        _check(self.w >= 0, "w", self.w, ">= 0")
        _check(self.svdd_fit in SVDD_FITS, "svdd_fit", self.svdd_fit, " | ".join(SVDD_FITS))
        _check(self.stats_warmup >= 0, "stats_warmup", self.stats_warmup, ">= 0")
        _check(self.stats_every >= 1, "stats_every", self.stats_every, ">= 1")
        _check(0 <= self.variance_floor <= 1, "variance_floor", self.variance_floor, "0 <= floor <= 1")
        _check(self.batch_size >= 2, "batch_size", self.batch_size, ">= 2")
        _check(self.lr > 0, "lr", self.lr, "> 0")
        _check(self.epochs >= 1, "epochs", self.epochs, ">= 1")
        _check(self.mcd_trials >= 1, "mcd_trials", self.mcd_trials, ">= 1")
        _check(0 < self.quantile < 1, "quantile", self.quantile, "0 < quantile < 1")
        _check(0 <= self.val_fraction < 1, "val_fraction", self.val_fraction, "0 <= val_fraction < 1")
        _check(
            self.smooth_window == 0
            or (self.smooth_window % 2 == 1 and self.smooth_window > self.smooth_polyorder),
            "smooth_window",
            self.smooth_window,
            "0 (off) or odd and > smooth_polyorder",
        )
        _check(self.smooth_polyorder >= 0, "smooth_polyorder", self.smooth_polyorder, ">= 0")
        _check(self.device in DEVICES, "device", self.device, " | ".join(DEVICES))
        if self.use_mahalanobis and self.svdd_fit == "batch":
            try:
                support_size(self.batch_size, self.s, self.mcd_support_fraction)
            except MCDError as err:
                raise ValueError(f"batch_size {self.batch_size} with s={self.s}: {err}") from err

    @classmethod
    def full(cls, **overrides: Any) -> Self:
        """The `full` training scale, the paper's setting: d = s = 32, batch 64, 40 epochs, lr 1e-4 cosine,
        alpha (1, 1, 0.001)."""
        return cls(**overrides)

    @classmethod
    def short(cls, **overrides: Any) -> Self:
        """The `short` training scale: the paper's network with 20 epochs at lr 1e-3 (about a minute on 2 CPU
        cores for ~500 windows)."""
        return dataclasses.replace(cls(epochs=20, lr=1e-3), **overrides)

    @classmethod
    def smoke(cls, **overrides: Any) -> Self:
        """The `smoke` training scale: a small, fast setting for tests and smoke runs (seconds on a CPU core
        for ~100 windows)."""
        base = cls(d=8, s=8, batch_size=32, epochs=5, lr=1e-3, mcd_trials=10, progress=False)
        return dataclasses.replace(base, **overrides)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of the fields (alpha as a list), for saving."""
        out = dataclasses.asdict(self)
        out["alpha"] = list(self.alpha)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Self:
        """Inverse of `to_dict`; unknown keys are an error naming them (`RETIRED_FIELDS` are dropped, a
        `rec_score` of `LEGACY_REC_SCORES` translated, any other refused)."""
        names = {f.name for f in dataclasses.fields(cls)}
        values = {k: v for k, v in data.items() if k not in RETIRED_FIELDS}
        if "rec_score" in values:
            rec_score = values.pop("rec_score")
            _check(rec_score in LEGACY_REC_SCORES, "rec_score", rec_score, " | ".join(LEGACY_REC_SCORES))
            if rec_score == "fused":
                values["frame_density"] = bool(values.get("use_reconstruction", True))
        unknown = sorted(set(values) - names)
        if unknown:
            raise ValueError(f"unknown MSVDDConfig fields: {', '.join(unknown)}")
        if "alpha" in values:
            values["alpha"] = tuple(float(a) for a in values["alpha"])
        return cls(**values)


def _check(ok: bool, field: str, value: object, allowed: str) -> None:
    if not ok:
        raise ValueError(f"MSVDDConfig.{field} = {value!r}; allowed: {allowed}")
