"""Deep baselines on M-SVDD's network (paper, Table I): Deep SVDD, deep autoencoder, VAE-SVDD and DAGMM.

All four share `msvdd.network.FusionNet` (encoders, fusion, decoders), its normaliser and its training loop
(`deep_base`); only the head, the loss and the score differ:

- `dsvdd`: one-class Deep SVDD (Ruff et al., 2018) on the fused embedding z with M-SVDD's reconstruction
  branch (the paper's DSVDD): loss mean ||z - c||^2 + Huber reconstruction, c the mean initial embedding
  (coordinates pushed away from 0 by 0.1, as Ruff et al.); score ||z - c||^2 + w (mean D / mean Rec) Rec
  with training means, the M-SVDD score with the Euclidean distance.
- `dae`: the encoders and decoders as an autoencoder; score = per-window Huber reconstruction error. The
  decoders read the encoder token sequences, so the bottleneck is the token sequence, as in M-SVDD.
- `vae-svdd`: a variational autoencoder over the encoder tokens (a linear log-variance head per modality,
  reparameterised samples decoded, KL to N(0, I) weighted by `VAE_BETA`) with a Deep SVDD loss on the fused
  embedding of the token means; score as `dsvdd`, with reconstructions of the means.
- `dagmm`: DAGMM (Zong et al., 2018): the compression network is FusionNet (z plus, per modality, the
  relative reconstruction error and the cosine similarity), the estimation network an MLP giving soft
  memberships of `DAGMM_COMPONENTS` Gaussians; loss reconstruction + 0.1 energy + 0.005 inverse-diagonal
  penalty; score = sample energy under the mixture estimated over the whole training set.
"""

from __future__ import annotations

import abc
import math
from typing import Any, ClassVar

import torch
from torch import nn
from torch.nn import functional as F

from benchmarks.methods.deep_base import DeepDetector, reconstruction_error, scale_config
from msvdd.config import MSVDDConfig
from msvdd.losses import huber_per_window
from msvdd.network import FusionNet

CENTER_MIN = 0.1
"""Deep SVDD: centre coordinates closer to 0 than this are moved to +-this (avoids a trivial solution)."""
VAE_BETA = 0.1
"""VAE-SVDD: weight of the KL term relative to the per-sample Huber reconstruction error."""
DAGMM_COMPONENTS = 4
"""DAGMM: Gaussian mixture components."""
DAGMM_LAMBDA_ENERGY = 0.1
"""DAGMM: weight of the sample energy in the loss (Zong et al.)."""
DAGMM_LAMBDA_COV = 0.005
"""DAGMM: weight of the inverse-diagonal covariance penalty (Zong et al.)."""
DAGMM_RIDGE = 1e-3
"""DAGMM: ridge added to every component covariance."""


def _center(z: torch.Tensor) -> torch.Tensor:
    c = z.mean(dim=0)
    small = c.abs() < CENTER_MIN
    return torch.where(small & (c < 0), -CENTER_MIN, torch.where(small, CENTER_MIN, c))


class _CentreDistanceScoring(DeepDetector):
    """Scores squared distance to the centre plus reconstruction, weighted as M-SVDD's delta.

    The reconstruction weight is w x mean distance / mean reconstruction over the training windows.
    """

    @abc.abstractmethod
    def _parts(self, audio: torch.Tensor, imu: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(squared distance to the centre, reconstruction loss) per window."""

    def after_training(self, audio: torch.Tensor, imu: torch.Tensor) -> None:
        parts = [self._parts(a, i) for a, i in self.chunks(audio, imu)]
        dist2 = torch.cat([p[0] for p in parts])
        rec = torch.cat([p[1] for p in parts])
        weight = self.config.w * float(dist2.mean()) / max(float(rec.mean()), 1e-12)
        self.extra["rec_weight"] = torch.tensor([weight], dtype=torch.float64)

    def batch_scores(self, audio: torch.Tensor, imu: torch.Tensor) -> torch.Tensor:
        dist2, rec = self._parts(audio, imu)
        return dist2.double() + float(self.extra["rec_weight"][0]) * rec.double()


class DeepSVDD(_CentreDistanceScoring):
    """One-class Deep SVDD with the reconstruction branch, on M-SVDD's network."""

    kind = "dsvdd"
    extra_keys: ClassVar[tuple[str, ...]] = ("center", "rec_weight")

    def build(self) -> nn.Module:
        return FusionNet(self.config)

    def _embed(
        self, module: nn.Module, audio: torch.Tensor, imu: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        out = module(audio, imu)
        return out.z, reconstruction_error(out, audio, imu)

    def before_training(self, audio: torch.Tensor, imu: torch.Tensor) -> None:
        self.module.eval()
        with torch.no_grad():
            z = torch.cat([self._embed(self.module, a, i)[0] for a, i in self.chunks(audio, imu)])
        self.extra["center"] = _center(z)

    def loss(self, module: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        z, rec = self._embed(module, batch[0], batch[1])
        dist2 = ((z - self.extra["center"]) ** 2).sum(dim=1)
        return self.config.alpha[0] * dist2.mean() + self.config.alpha[1] * rec.mean()

    def _parts(self, audio: torch.Tensor, imu: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        z, rec = self._embed(self.module, audio, imu)
        return ((z - self.extra["center"]) ** 2).sum(dim=1), rec


class DeepAutoencoder(DeepDetector):
    """M-SVDD's encoders and decoders as an autoencoder; score = reconstruction error."""

    kind = "dae"

    def build(self) -> nn.Module:
        return FusionNet(self.config)

    def _rec(self, module: nn.Module, audio: torch.Tensor, imu: torch.Tensor) -> torch.Tensor:
        net: Any = module
        a_tok = net.audio_encoder(audio) if net.audio_encoder is not None else None
        i_tok = net.imu_encoder(imu) if net.imu_encoder is not None else None
        err = torch.zeros(audio.shape[0], dtype=audio.dtype, device=audio.device)
        if a_tok is not None:
            err = err + huber_per_window(audio, net.audio_decoder(a_tok))
        if i_tok is not None:
            err = err + huber_per_window(imu, net.imu_decoder(i_tok))
        return err

    def loss(self, module: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        return self._rec(module, batch[0], batch[1]).mean()

    def batch_scores(self, audio: torch.Tensor, imu: torch.Tensor) -> torch.Tensor:
        return self._rec(self.module, audio, imu).double()


class _VAEModule(nn.Module):
    """FusionNet plus a log-variance head per modality: a VAE over the encoder tokens."""

    def __init__(self, config: MSVDDConfig) -> None:
        super().__init__()
        self.net = FusionNet(config)
        self.logvar_a = nn.Linear(config.d, config.d) if config.use_audio else None
        self.logvar_i = nn.Linear(config.d, config.d) if config.use_imu else None

    def forward(
        self, audio: torch.Tensor, imu: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(z of the token means, per-window reconstruction error, per-window KL); samples when training."""
        net = self.net
        a_tok = net.audio_encoder(audio) if net.audio_encoder is not None else None
        i_tok = net.imu_encoder(imu) if net.imu_encoder is not None else None
        z = net.fusion(a_tok, i_tok).z
        rec = torch.zeros(audio.shape[0], dtype=audio.dtype, device=audio.device)
        kl = torch.zeros(audio.shape[0], dtype=audio.dtype, device=audio.device)
        branches = (
            (a_tok, self.logvar_a, net.audio_decoder, audio),
            (i_tok, self.logvar_i, net.imu_decoder, imu),
        )
        for tok, head, decoder, target in branches:
            if tok is None or head is None or decoder is None:
                continue
            logvar = head(tok).clamp(-10.0, 10.0)
            sample = tok + torch.exp(0.5 * logvar) * torch.randn_like(tok) if self.training else tok
            rec = rec + huber_per_window(target, decoder(sample))
            kl = kl + 0.5 * (tok**2 + logvar.exp() - 1.0 - logvar).mean(dim=(1, 2))
        return z, rec, kl


class VAESVDD(_CentreDistanceScoring):
    """A token-level VAE with a Deep SVDD loss on the fused embedding."""

    kind = "vae-svdd"
    extra_keys: ClassVar[tuple[str, ...]] = ("center", "rec_weight")

    def build(self) -> nn.Module:
        return _VAEModule(self.config)

    def before_training(self, audio: torch.Tensor, imu: torch.Tensor) -> None:
        self.module.eval()
        with torch.no_grad():
            z = torch.cat([self.module(a, i)[0] for a, i in self.chunks(audio, imu)])
        self.extra["center"] = _center(z)

    def loss(self, module: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        z, rec, kl = module(batch[0], batch[1])
        dist2 = ((z - self.extra["center"]) ** 2).sum(dim=1)
        return self.config.alpha[0] * dist2.mean() + self.config.alpha[1] * (rec + VAE_BETA * kl).mean()

    def _parts(self, audio: torch.Tensor, imu: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        z, rec, _ = self.module(audio, imu)
        return ((z - self.extra["center"]) ** 2).sum(dim=1), rec


class _DAGMMModule(nn.Module):
    """Compression network (FusionNet + reconstruction features) and estimation network (soft memberships)."""

    def __init__(self, config: MSVDDConfig) -> None:
        super().__init__()
        self.net = FusionNet(config)
        n_rec = 2 * (int(config.use_audio) + int(config.use_imu))
        self.estimate = nn.Sequential(
            nn.Linear(config.s + n_rec, 10),
            nn.Tanh(),
            nn.Dropout(0.5),
            nn.Linear(10, DAGMM_COMPONENTS),
            nn.Softmax(dim=1),
        )

    def forward(
        self, audio: torch.Tensor, imu: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(features (N, s + 2 m), memberships (N, K), per-window reconstruction error (N,))."""
        out = self.net(audio, imu)
        feats = [out.z]
        for rec, target in ((out.audio_rec, audio), (out.imu_rec, imu)):
            if rec is None:
                continue
            x, y = target.flatten(1), rec.flatten(1)
            feats.append(
                (torch.linalg.vector_norm(x - y, dim=1) / (torch.linalg.vector_norm(x, dim=1) + 1e-8))[
                    :, None
                ]
            )
            feats.append(F.cosine_similarity(x, y, dim=1, eps=1e-8)[:, None])
        features = torch.cat(feats, dim=1)
        return features, self.estimate(features), reconstruction_error(out, audio, imu)


def gmm_parameters(
    features: torch.Tensor, gamma: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Mixture weights (K,), means (K, p), ridge-regularised covariances (K, p, p) from memberships."""
    mass = gamma.sum(dim=0) + 1e-12
    phi = mass / features.shape[0]
    mu = gamma.T @ features / mass[:, None]
    centred = features[None, :, :] - mu[:, None, :]
    cov = torch.einsum("nk,kni,knj->kij", gamma, centred, centred) / mass[:, None, None]
    return (
        phi,
        mu,
        cov + DAGMM_RIDGE * torch.eye(features.shape[1], dtype=features.dtype, device=features.device),
    )


def gmm_energy(
    features: torch.Tensor, phi: torch.Tensor, mu: torch.Tensor, cov: torch.Tensor
) -> torch.Tensor:
    """(N,) sample energy -log sum_k phi_k N(x | mu_k, cov_k)."""
    chol = torch.linalg.cholesky(cov)
    centred = features[None, :, :] - mu[:, None, :]
    y = torch.linalg.solve_triangular(chol, centred.transpose(1, 2), upper=False)
    maha = (y * y).sum(dim=1)
    log_det = 2.0 * torch.log(torch.diagonal(chol, dim1=1, dim2=2)).sum(dim=1)
    log_norm = 0.5 * (features.shape[1] * math.log(2 * math.pi) + log_det)
    return -torch.logsumexp(torch.log(phi + 1e-12)[:, None] - 0.5 * maha - log_norm[:, None], dim=0)


class DAGMM(DeepDetector):
    """Deep Autoencoding Gaussian Mixture Model on M-SVDD's network."""

    kind = "dagmm"
    extra_keys: ClassVar[tuple[str, ...]] = ("phi", "mu", "cov")

    def build(self) -> nn.Module:
        return _DAGMMModule(self.config)

    def loss(self, module: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        features, gamma, rec = module(batch[0], batch[1])
        phi, mu, cov = gmm_parameters(features, gamma)
        energy = gmm_energy(features, phi, mu, cov)
        penalty = (1.0 / torch.diagonal(cov, dim1=1, dim2=2)).sum()
        return rec.mean() + DAGMM_LAMBDA_ENERGY * energy.mean() + DAGMM_LAMBDA_COV * penalty

    def after_training(self, audio: torch.Tensor, imu: torch.Tensor) -> None:
        parts = [self.module(a, i) for a, i in self.chunks(audio, imu)]
        features = torch.cat([p[0] for p in parts]).double()
        gamma = torch.cat([p[1] for p in parts]).double()
        phi, mu, cov = gmm_parameters(features, gamma)
        self.extra |= {"phi": phi, "mu": mu, "cov": cov}

    def batch_scores(self, audio: torch.Tensor, imu: torch.Tensor) -> torch.Tensor:
        features, _, _ = self.module(audio, imu)
        return gmm_energy(features.double(), self.extra["phi"], self.extra["mu"], self.extra["cov"])


def register_methods() -> None:
    """Register `dsvdd`, `dae`, `vae-svdd` and `dagmm`."""
    from benchmarks.methods.registry import register
    from benchmarks.methods.spec import PaperRow

    table: tuple[tuple[str, type[DeepDetector], str, PaperRow], ...] = (
        (
            "dsvdd",
            DeepSVDD,
            "Deep SVDD (one-class) with the reconstruction branch, M-SVDD's network",
            PaperRow("Table I", 9, "DSVDD"),
        ),
        (
            "dae",
            DeepAutoencoder,
            "deep autoencoder (M-SVDD's encoders and decoders), reconstruction error",
            PaperRow("Table I", 6, "DAE"),
        ),
        (
            "vae-svdd",
            VAESVDD,
            "token-level VAE with a Deep SVDD loss on the fused embedding",
            PaperRow("Table I", 8, "VAE-SVDD"),
        ),
        (
            "dagmm",
            DAGMM,
            "DAGMM: FusionNet compression network and a Gaussian-mixture estimation network",
            PaperRow("Table I", 5, "DAGMM"),
        ),
    )
    for name, cls, text, row in table:
        register(
            name,
            _factory(cls),
            cls=cls,
            family="deep",
            modality="audio+imu",
            description=text,
            paper=(row,),
            config="MSVDDConfig(use_mahalanobis=False): M-SVDD's network and budget",
        )


def _factory(cls: type[DeepDetector]) -> Any:
    def make(seed: int, scale: str, device: str) -> DeepDetector:
        return cls(scale_config(scale, seed, use_mahalanobis=False, device=device))

    return make
