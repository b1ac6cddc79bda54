"""`MSVDD`: the paper's detector (Algorithm 1) behind the shared `Detector` contract.

fit: z-score statistics from the training windows; train the network; then mu and Sigma by MCD over the
embeddings of the whole training split, the training means of D and Rec, and the score
delta = D + w (mean_D / mean_Rec) Rec, D the latent Mahalanobis distance and Rec the mean Huber error of the
network's own decoders; the threshold follows the rule of `msvdd.contract.Detector` (the `quantile` of the
scores of held-out nominal windows). No test label is ever seen.

Training, by `svdd_fit`:

- "batch" (the paper): alpha1 * L_MSVDD + alpha2 * L_Rec + alpha3 * L_Reg, mu and Sigma by MCD on each batch
  of `batch_size` (degenerate by construction: `msvdd.losses`); the epoch of the best validation loss is kept.
- "frozen": Deep SVDD's fixed centre extended to the ellipsoid. `stats_warmup` epochs of alpha2 * L_Rec alone,
  then mu and Sigma by MCD over the embeddings of the whole training split (Sigma's spectrum floored,
  `msvdd.losses.floored_covariance`), re-estimated every `stats_every` epochs and held fixed in between; the
  loss is alpha1 * mean D^2 + alpha2 * L_Rec under the held statistics, and the last epoch is kept. The
  estimates are scale-equivariant (MCD on z over its RMS spread, a relative floor and ridge), so D after an
  estimate does not depend on the embeddings' scale. Each estimate's spectrum is kept in the training history
  (`stats_*` figures), which `msvdd-bench diagnose` reports.

With `use_mahalanobis=False` the same network is trained as a Euclidean Deep SVDD around a fixed centre c
(the mean embedding, Ruff et al. 2018: of the initial network in "batch" mode, soft boundary; after the
warm-up in "frozen" mode, fixed from then on, loss mean ||z - c||^2) and scored by ||z - c||. With
`bias_free` the encoders' and the fusion's biases stay 0, so that the network cannot map every window to one
constant z other than 0.

`frame_density=True` replaces Rec in the score by a frame-density term of the normalised input frames
(`msvdd.context_net`), which reads no part of the network: that is the `frame-density-msvdd` method, not the
paper's model.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

import numpy as np
import torch
from torch import nn

from msvdd.atomic import atomic_file
from msvdd.config import MSVDDConfig
from msvdd.context_net import ContextNet, fit_context_net
from msvdd.contract import (
    Detector,
    ModelFormatError,
    NotFittedError,
    WindowError,
    Windows,
    check_windows,
    model_fields,
)
from msvdd.frontend import InputNormalizer
from msvdd.losses import (
    batch_statistics,
    covariance_regulariser,
    effective_rank,
    floored_covariance,
    huber_per_window,
    reconstruction_loss,
    svdd_loss,
)
from msvdd.mcd import MCDError, mahalanobis, mahalanobis_sq, min_cov_det, support_size
from msvdd.network import AUDIO_STRIDES, IMU_FRAME, FusionNet, NetOutput
from msvdd.residual import cut_frames
from msvdd.training import TrainResult, batched_loss, resolve_device, split_train_val, train_network

FORMAT_VERSION = 4
"""Version of the file written by `MSVDD.save` (2: front-end choice and per-channel statistics, training
history; 3: the frame densities of the reconstruction term; 4: the frame-density term under its own name,
`frame_density`, and Sigma's raw estimate); `load` also reads versions 1 (the paper's waveform and
z-velocity), 2 and 3, refuses any other, and refuses a model of a retired `rec_score` by its config."""
_FORMAT_NAME = "msvdd-model"
_INFER_BATCH = 256
Inputs = tuple[torch.Tensor, ...]
"""The network's inputs of a batch of windows: normalised audio and IMU, and with `order_view` the wheels'
odometry (`MSVDD._tensors`)."""
AUDIO_SAMPLES_PER_TOKEN = math.prod(AUDIO_STRIDES)
"""Waveform samples per audio token (180): the length of a waveform frame of the input."""


@dataclass(frozen=True)
class LossTerms:
    """The loss of one batch and its parts."""

    total: torch.Tensor
    """alpha1 * svdd + alpha2 * rec + alpha3 * reg."""
    svdd: torch.Tensor
    """Soft-boundary SVDD term."""
    rec: torch.Tensor
    """Mean reconstruction loss (0 without the reconstruction branch)."""
    reg: torch.Tensor
    """Covariance regulariser (0 for Euclidean SVDD and for `svdd_fit="frozen"`)."""


class _Module(nn.Module):
    """The network plus the learnable radius R and the (Euclidean mode) fixed centre."""

    def __init__(self, config: MSVDDConfig) -> None:
        super().__init__()
        self.net = FusionNet(config)
        self.center: torch.Tensor
        self.radius = nn.Parameter(torch.tensor(float(np.sqrt(config.s))))
        self.register_buffer("center", torch.zeros(config.s))
        if config.bias_free:
            for param in z_biases(self.net):
                param.requires_grad_(False)
                with torch.no_grad():
                    param.zero_()


def z_biases(net: FusionNet) -> list[torch.Tensor]:
    """The biases z depends on (the encoders' and the fusion's) of a network, for checks."""
    return [
        param
        for part in (net.audio_encoder, net.imu_encoder, net.fusion)
        if part is not None
        for name, param in part.named_parameters()
        if name.split(".")[-1].startswith("bias")
    ]


@dataclass(frozen=True)
class StatsFit:
    """One estimate of mu and Sigma of `svdd_fit="frozen"` (or the final one)."""

    epoch: int
    """Epochs trained when it was made (0: the initial network)."""
    eigenvalues: list[float]
    """Eigenvalues of the raw MCD covariance (before the floor), largest first."""
    effective_rank: float
    """exp(entropy) of `eigenvalues`: s when every direction carries the same variance, 1 for one."""
    floored: int
    """Eigenvalues the variance floor raised."""


class MSVDD(Detector):
    """Mahalanobis SVDD with audio-IMU fusion. `MSVDD(MSVDDConfig.full()).fit(train, val)`."""

    def __init__(self, config: MSVDDConfig | None = None) -> None:
        self.config = config or MSVDDConfig()
        self.quantile = self.config.quantile
        self.device = resolve_device(self.config.device)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(self.config.seed)
            self.module = _Module(self.config).to(self.device)
        self.normalizer: InputNormalizer | None = None
        self.mu_: torch.Tensor | None = None
        self.sigma_: torch.Tensor | None = None
        self.mean_d_ = 1.0
        self.mean_rec_ = 1.0
        self.rec_scale_ = np.ones(2)
        self.frame_density_: list[ContextNet] | None = None
        self.sigma_raw_: torch.Tensor | None = None
        self.stats_fits_: list[StatsFit] = []
        self.loaded_format_: int | None = None
        self.threshold_ = float("nan")
        self.history_: TrainResult | None = None
        self._mcd_calls = 0
        self._terms: list[tuple[float, float, float]] = []
        self._held: tuple[torch.Tensor, torch.Tensor] | None = None
        self._epochs_done = 0
        self._train_t: Inputs | None = None

    @property
    def has_term(self) -> bool:
        """Whether the score has a second term (Rec, or the frame-density term) beside D."""
        return self.config.frame_density or self.config.use_reconstruction

    @property
    def frozen(self) -> bool:
        """Whether training holds mu and Sigma (or c) fixed between estimates (`svdd_fit="frozen"`)."""
        return self.config.svdd_fit == "frozen"

    def _warmup(self) -> int:
        """Epochs before the first estimate: `stats_warmup`, or 0 without a reconstruction loss to train."""
        return self.config.stats_warmup if self.config.use_reconstruction else 0

    # ---------------------------------------------------------------- training

    def _fit(self, train: Windows, val: Windows | None) -> None:
        """Train on nominal `train` windows; `val` (nominal) selects the best epoch, else a held-out split.

        A validation set too small for the validation MCD (fewer than about s + 3 windows) cannot select
        an epoch: M-SVDD then trains without one (keeping the last epoch) and says so in a warning.

        Raises:
            WindowError: fewer training windows than a batch or the final MCD needs.
        """
        cfg = self.config
        n_val = len(val) if val is not None else round(len(train) * cfg.val_fraction)
        batch_mcd = cfg.use_mahalanobis and not self.frozen
        if batch_mcd and n_val > 0 and not _mcd_possible(min(n_val, cfg.batch_size), cfg):
            source = "the val set" if val is not None else f"a {cfg.val_fraction:.0%} validation split"
            warnings.warn(
                f"{source} has {n_val} windows, too few for the validation MCD in s={cfg.s} dimensions; "
                "M-SVDD trains without validation (last epoch kept)",
                stacklevel=3,
            )
            self.config = cfg = dataclasses.replace(cfg, val_fraction=0.0)
            val = None
        fit_part = train
        if val is None and cfg.val_fraction > 0:
            tr, va = split_train_val(len(train), cfg.val_fraction, cfg.seed)
            fit_part, val = train.subset(tr), train.subset(va)
        self._check_sizes(len(fit_part), 0 if val is None else len(val))
        self.normalizer, inputs = InputNormalizer.fit_tensors(
            fit_part, cfg.audio_frontend, cfg.imu_input, cfg.smooth_window, cfg.smooth_polyorder
        )
        train_t: Inputs = (*inputs, *self._odometry(fit_part))
        val_t = None if val is None or len(val) == 0 else self._tensors(val)
        self._mcd_calls = 0
        self._terms = []
        self._held = None
        self._epochs_done = 0
        self.stats_fits_ = []
        self._train_t = train_t
        if not cfg.use_mahalanobis and not self.frozen:
            self._init_center(train_t)
        if self.frozen and self._warmup() == 0:
            self._fit_held_statistics()
        try:
            self.history_ = train_network(
                self.module,
                self.batch_loss,
                train_t,
                None if self.frozen else val_t,
                cfg,
                val_loss_fn=self._val_loss,
                epoch_probe=self._epoch_figures,
            )
        finally:
            self._train_t = None
            self._held = None
        self._finalise(train_t, val_t)

    def _check_sizes(self, n_train: int, n_val: int) -> None:
        cfg = self.config
        if n_train < cfg.batch_size:
            raise WindowError(
                f"{n_train} training windows (after the validation split); at least batch_size="
                f"{cfg.batch_size} are needed"
            )
        if cfg.use_mahalanobis:
            try:
                support_size(n_train, cfg.s, cfg.mcd_support_fraction)
                if n_val and not self.frozen:
                    support_size(min(n_val, cfg.batch_size), cfg.s, cfg.mcd_support_fraction)
            except MCDError as err:
                raise WindowError(f"too few windows for the MCD in s={cfg.s} dimensions: {err}") from err

    def _tensors(self, batch: Windows) -> Inputs:
        """The network's inputs of a batch: normalised (audio, imu), and with `order_view` the odometry."""
        if self.normalizer is None:
            raise NotFittedError("MSVDD is not fitted: call fit() or MSVDD.load()")
        inputs = self.normalizer.tensors(batch, self.config.smooth_window, self.config.smooth_polyorder)
        return (*inputs, *self._odometry(batch))

    def _odometry(self, batch: Windows) -> tuple[torch.Tensor, ...]:
        """With `order_view`, (the wheels' angles (N, 400, W) float32,); else ().

        Raises:
            WindowError: `order_view` and the windows carry no odometry.
        """
        if not self.config.order_view:
            return ()
        if batch.odometry is None:
            raise WindowError(
                "odometry is None: this M-SVDD has order_view=True and reads the wheels' encoder angles "
                "(Windows.odometry, (N, 400, W) rad)"
            )
        return (torch.from_numpy(np.ascontiguousarray(batch.odometry, dtype=np.float32)),)

    def _init_center(self, train_t: Inputs) -> None:
        """Euclidean mode: c = mean initial embedding, entries near 0 pushed to +-eps (Ruff et al.)."""
        self._set_center(self._embed_tensors(train_t).mean(dim=0))

    def _set_center(self, z: torch.Tensor) -> None:
        """c = z (s,), entries near 0 pushed to +-eps (Ruff et al.)."""
        eps = self.config.eps
        z = torch.where(z.abs() < eps, torch.where(z < 0, -eps, eps), z)
        self.module.center.copy_(z.to(self.module.center.dtype))

    def _fit_held_statistics(self) -> None:
        """`svdd_fit="frozen"`: estimate the statistics the loss holds fixed until the next estimate, from the
        embeddings of the whole training split (Mahalanobis: mu and floored Sigma by MCD; Euclidean: the
        centre c, once, at the first estimate), and record the estimate's spectrum."""
        if self._train_t is None:
            raise RuntimeError("the held statistics are estimated during fit only")
        cfg = self.config
        z = self._embed_tensors(self._train_t).to(torch.float64)
        if not cfg.use_mahalanobis:
            if self._held is None:
                self._set_center(z.mean(dim=0))
                self._held = (self.module.center.detach().clone(), torch.eye(cfg.s, device=self.device))
            return
        mu, raw, sigma = self._robust_statistics(z, cfg.seed * 1_000_003 + 7919 * (self._epochs_done + 1))
        self._held = (mu.to(torch.float32), sigma.to(torch.float32))
        self.stats_fits_.append(_stats_fit(self._epochs_done, raw, cfg.variance_floor))

    def _robust_statistics(
        self, z: torch.Tensor, seed: int
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(mu, raw MCD covariance, floored Sigma) of embeddings z (n, s) for `svdd_fit="frozen"`: MCD on z
        over its RMS spread (so that the ridge of the MCD's selection is relative), the floor and eps relative
        to the mean eigenvalue; scaling z by a scales mu by a and both covariances by a^2.

        Raises:
            ValueError: the embeddings do not spread (every window maps to one z).
        """
        cfg = self.config
        spread = float(torch.sqrt(z.var(dim=0).mean()))
        if not math.isfinite(spread) or spread <= 0:
            raise ValueError("the embeddings z do not spread (every training window maps to one z)")
        mcd = min_cov_det(
            z / spread, cfg.mcd_support_fraction, random_state=seed, n_trials=cfg.mcd_trials, ridge=cfg.eps
        )
        raw = mcd.covariance * spread**2
        mean_eig = float(torch.diagonal(raw).mean())
        sigma = floored_covariance(raw, cfg.variance_floor, cfg.eps * mean_eig)
        return mcd.location * spread, raw, sigma

    def loss_terms(self, out: NetOutput, audio: torch.Tensor, imu: torch.Tensor, seed: int) -> LossTerms:
        """The loss of one batch given the network output (public for tests)."""
        cfg = self.config
        z = out.z
        zero = torch.zeros((), device=z.device)
        if self.frozen:
            return self._frozen_loss_terms(out, audio, imu)
        if cfg.use_mahalanobis:
            mu, sigma, _ = batch_statistics(z, cfg.eps, cfg.mcd_support_fraction, seed, cfg.mcd_trials)
            d2 = mahalanobis_sq(z, mu, sigma)
            reg = covariance_regulariser(sigma, cfg.eps)
        else:
            d2 = ((z - self.module.center) ** 2).sum(dim=1)
            reg = zero
        svdd = svdd_loss(d2, self.module.radius, cfg.nu)
        rec = self._reconstruction(out, audio, imu) if cfg.use_reconstruction else zero
        a1, a2, a3 = cfg.alpha
        return LossTerms(total=a1 * svdd + a2 * rec + a3 * reg, svdd=svdd, rec=rec, reg=reg)

    def _reconstruction(self, out: NetOutput, audio: torch.Tensor, imu: torch.Tensor) -> torch.Tensor:
        cfg = self.config
        return reconstruction_loss(
            audio if cfg.use_audio else None, out.audio_rec, imu if cfg.use_imu else None, out.imu_rec
        ).mean()

    def _frozen_loss_terms(self, out: NetOutput, audio: torch.Tensor, imu: torch.Tensor) -> LossTerms:
        """`svdd_fit="frozen"`: alpha1 * mean D^2 under the held statistics + alpha2 * L_Rec; before the
        first estimate (the warm-up) alpha2 * L_Rec alone."""
        cfg = self.config
        zero = torch.zeros((), device=out.z.device)
        rec = self._reconstruction(out, audio, imu) if cfg.use_reconstruction else zero
        a1, a2, _ = cfg.alpha
        if self._held is None:
            return LossTerms(total=a2 * rec, svdd=zero, rec=rec, reg=zero)
        mu, sigma = self._held
        if cfg.use_mahalanobis:
            d2 = mahalanobis_sq(out.z, mu.to(out.z.dtype), sigma.to(out.z.dtype))
        else:
            d2 = ((out.z - mu.to(out.z.dtype)) ** 2).sum(dim=1)
        svdd = d2.mean()
        return LossTerms(total=a1 * svdd + a2 * rec, svdd=svdd, rec=rec, reg=zero)

    def batch_loss(self, module: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        """Training loss of one (audio, imu[, odometry]) batch (the `loss_fn` given to `train_network`)."""
        audio, imu, *odometry = batch
        self._mcd_calls += 1
        seed = self.config.seed * 1_000_003 + self._mcd_calls
        terms = self.loss_terms(self.module.net(audio, imu, *odometry), audio, imu, seed)
        self._terms.append((float(terms.svdd.detach()), float(terms.rec.detach()), float(terms.reg.detach())))
        return terms.total

    def _epoch_figures(self) -> dict[str, float]:
        """The radius R after an epoch and the epoch's mean SVDD, reconstruction and regulariser terms; with
        `svdd_fit="frozen"` the estimate of the held statistics when one is due after this epoch (`stats_fit`
        1), and the held Sigma's raw spectrum: its effective rank, its eigenvalues the floor raised, its trace
        (nan before the first estimate, and for the Euclidean model)."""
        means = np.mean(np.asarray(self._terms, dtype=np.float64), axis=0) if self._terms else np.zeros(3)
        self._terms = []
        figures = {"radius": self.radius_, "svdd": means[0], "rec": means[1], "reg": means[2]}
        if not self.frozen:
            return figures
        self._epochs_done += 1
        done, warmup, every = self._epochs_done, self._warmup(), self.config.stats_every
        due = done >= warmup and (done - warmup) % every == 0 and done < self.config.epochs
        if due:
            self._fit_held_statistics()
        last = self.stats_fits_[-1] if self.stats_fits_ else None
        figures.update(
            stats_fit=float(due),
            stats_effective_rank=float("nan") if last is None else last.effective_rank,
            stats_floored=float("nan") if last is None else float(last.floored),
            stats_trace=float("nan") if last is None else float(sum(last.eigenvalues)),
        )
        return figures

    def _val_loss(self, module: nn.Module, tensors: tuple[torch.Tensor, ...]) -> float:
        seed = self.config.seed

        def fixed(m: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
            audio, imu, *odometry = batch
            return self.loss_terms(self.module.net(audio, imu, *odometry), audio, imu, seed).total

        return batched_loss(fixed, self.config.batch_size, self.device)(module, tensors)

    def _finalise(
        self,
        train_t: Inputs,
        val_t: Inputs | None = None,
    ) -> None:
        """mu, Sigma over the whole training split; the frame densities (`frame_density`: their epochs chosen
        on `val_t`); the training means of D and of the second term."""
        cfg = self.config
        z = self._embed_tensors(train_t).to(torch.float64)
        if cfg.use_mahalanobis and self.frozen:
            self.mu_, self.sigma_raw_, self.sigma_ = self._robust_statistics(z, cfg.seed)
            self.stats_fits_.append(_stats_fit(-1, self.sigma_raw_, cfg.variance_floor))
        elif cfg.use_mahalanobis:
            mcd = min_cov_det(
                z, cfg.mcd_support_fraction, random_state=cfg.seed, n_trials=cfg.mcd_trials, ridge=cfg.eps
            )
            self.mu_ = mcd.location
            self.sigma_raw_ = mcd.covariance
            self.sigma_ = mcd.covariance + cfg.eps * torch.eye(cfg.s, dtype=torch.float64, device=z.device)
        else:
            self.mu_ = self.module.center.detach().to(torch.float64)
            self.sigma_ = torch.eye(cfg.s, dtype=torch.float64, device=z.device)
        if cfg.frame_density:
            self.frame_density_ = self._fit_input_densities(train_t, val_t)
        d, parts = self._distance_and_parts(train_t)
        if cfg.frame_density and parts.shape[1]:
            self.rec_scale_ = np.where(parts.mean(axis=0) > 0, parts.mean(axis=0), 1.0)
        else:
            self.rec_scale_ = np.ones(parts.shape[1])
        rec = self._rec(parts)
        self.mean_d_ = float(d.mean())
        self.mean_rec_ = float(rec.mean()) if self.has_term else 1.0
        if not np.isfinite(self.mean_d_) or self.mean_d_ <= 0 or not np.isfinite(self.mean_rec_):
            raise ValueError(
                f"training produced degenerate scores (mean D {self.mean_d_}, mean Rec {self.mean_rec_})"
            )

    # ---------------------------------------------------------------- scoring

    def _embed_tensors(self, tensors: Inputs) -> torch.Tensor:
        outs = []
        with torch.inference_mode():
            for part in _batches(tensors):
                outs.append(self.module.net(*(t.to(self.device) for t in part)).z)
        return torch.cat(outs)

    def _rec_pairs(
        self, out: NetOutput, audio: torch.Tensor, imu: torch.Tensor
    ) -> list[tuple[torch.Tensor, torch.Tensor]]:
        """(input, reconstruction) of each reconstructed modality, audio first."""
        cfg = self.config
        pairs = []
        if cfg.use_audio and out.audio_rec is not None:
            pairs.append((audio, out.audio_rec))
        if cfg.use_imu and out.imu_rec is not None:
            pairs.append((imu, out.imu_rec))
        return pairs

    def term_parts(self, out: NetOutput, audio: torch.Tensor, imu: torch.Tensor) -> list[torch.Tensor]:
        """(N,) the score's second term per modality: the frame-density term's (`frame_density`, read from
        the inputs), else the decoders' mean Huber error of the window (`rec_parts`)."""
        if self.config.frame_density:
            return self.frame_parts(audio, imu)
        return self.rec_parts(out, audio, imu)

    def rec_parts(self, out: NetOutput, audio: torch.Tensor, imu: torch.Tensor) -> list[torch.Tensor]:
        """(N,) reconstruction error of each reconstructed modality: the mean Huber error of the window."""
        return [huber_per_window(x, x_hat) for x, x_hat in self._rec_pairs(out, audio, imu)]

    def frame_parts(self, audio: torch.Tensor, imu: torch.Tensor) -> list[torch.Tensor]:
        """(N,) the largest input-frame distance of each used modality under its density network."""
        frames = self.input_frames(audio, imu)
        nets = self.frame_density_ or []
        if len(nets) != len(frames):
            raise NotFittedError("MSVDD is not fitted: its frame density networks are missing")
        return [g.peak_distance(f, _cross(g, frames)) for g, f in zip(nets, frames, strict=True)]

    def input_frames(self, audio: torch.Tensor, imu: torch.Tensor) -> list[torch.Tensor]:
        """(N, T, p) frames of each used modality's normalised input, audio first, one per token (a log-mel
        frame of both channels, or 180 waveform samples of both; 8 IMU samples of every axis)."""
        cfg = self.config
        frames = []
        if cfg.use_audio:
            logmel = cfg.audio_frontend == "logmel"
            frames.append(
                cut_frames(audio, 2, 1) if logmel else cut_frames(audio, 1, AUDIO_SAMPLES_PER_TOKEN)
            )
        if cfg.use_imu:
            frames.append(cut_frames(imu, 1, IMU_FRAME))
        return frames

    def _fit_input_densities(self, train_t: Inputs, val_t: Inputs | None) -> list[ContextNet]:
        """`frame_density`: a `ContextNet` of each used modality's input frames given its neighbours; the
        IMU's also given the audio frames around it when both modalities are used (`msvdd.context_net`)."""
        device = self.device
        train = self.input_frames(train_t[0].to(device), train_t[1].to(device))
        val = None if val_t is None else self.input_frames(val_t[0].to(device), val_t[1].to(device))
        seed = self.config.seed
        densities: list[ContextNet] = []
        for m, frames in enumerate(train):
            v = None if val is None else val[m]
            cross = None
            if m == 1:  # the IMU of an audio-IMU model: its frames given the audio frames too
                cross = (train[0], None if val is None else val[0])
            densities.append(fit_context_net(frames, v, seed, cross=cross))
        return densities

    def _distance_and_parts(self, tensors: Inputs) -> tuple[np.ndarray, np.ndarray]:
        """(D (N,), the second term per modality (N, M); M = 0 without one)."""
        if self.mu_ is None or self.sigma_ is None:
            raise NotFittedError("MSVDD is not fitted: call fit() or MSVDD.load()")
        d_all, parts_all = [], []
        with torch.inference_mode():
            for part in _batches(tensors):
                a, i, *odometry = (t.to(self.device) for t in part)
                out = self.module.net(a, i, *odometry)
                d_all.append(mahalanobis(out.z.to(torch.float64), self.mu_, self.sigma_).cpu())
                parts = self.term_parts(out, a, i) if self.has_term else []
                parts_all.append(
                    torch.stack(parts, dim=1).to(torch.float64).cpu()
                    if parts
                    else torch.zeros(a.shape[0], 0, dtype=torch.float64)
                )
        return torch.cat(d_all).numpy(), torch.cat(parts_all).numpy()

    def _rec(self, parts: np.ndarray) -> np.ndarray:
        """The second term: the modalities' parts (in units of `rec_scale_`) summed; 0 without."""
        return (parts / self.rec_scale_[: parts.shape[1]]).sum(axis=1)

    def _components_tensors(self, tensors: Inputs) -> tuple[np.ndarray, np.ndarray]:
        d, parts = self._distance_and_parts(tensors)
        return d, self._rec(parts)

    def _delta(self, d: np.ndarray, rec: np.ndarray) -> np.ndarray:
        if not self.has_term:
            return d.astype(np.float64)
        return (d + self.config.w * (self.mean_d_ / self.mean_rec_) * rec).astype(np.float64)

    def score_components(self, batch: Windows) -> tuple[np.ndarray, np.ndarray]:
        """(D (N,) Mahalanobis (or Euclidean) distance, the second term (N,): the decoders' reconstruction
        error Rec, or the frame-density term with `frame_density`; zeros without one)."""
        check_windows(batch, "batch")
        return self._components_tensors(self._tensors(batch))

    def _score(self, batch: Windows) -> np.ndarray:
        """(N,) float64 anomaly scores delta = D + w (mean_D / mean_Rec) Rec; higher = more anomalous."""
        return self._delta(*self._components_tensors(self._tensors(batch)))

    def embed(self, batch: Windows) -> np.ndarray:
        """(N, s) float32 fused embeddings z."""
        check_windows(batch, "batch")
        return self._embed_tensors(self._tensors(batch)).cpu().numpy()

    # ---------------------------------------------------------------- persistence

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write weights, config, normalisation, mu, Sigma, R, training means and threshold to one file."""
        if self.normalizer is None or self.mu_ is None or self.sigma_ is None:
            raise NotFittedError("MSVDD is not fitted: nothing to save")
        payload: dict[str, Any] = {
            "format": _FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "config": self.config.to_dict(),
            "state_dict": {k: v.detach().cpu() for k, v in self.module.state_dict().items()},
            "normalizer": self.normalizer.state(),
            "mu": self.mu_.cpu(),
            "sigma": self.sigma_.cpu(),
            "mean_d": self.mean_d_,
            "mean_rec": self.mean_rec_,
            "rec_scale": torch.from_numpy(np.asarray(self.rec_scale_, dtype=np.float64)),
            "frame_density": (
                None if self.frame_density_ is None else [g.state() for g in self.frame_density_]
            ),
            "sigma_raw": None if self.sigma_raw_ is None else self.sigma_raw_.cpu(),
            "stats_fits": [dataclasses.asdict(f) for f in self.stats_fits_],
            "threshold": self.threshold_,
            "threshold_source": self.threshold_source_,
            "history": None if self.history_ is None else self.history_.to_dict(),
        }
        with atomic_file(path) as fh:
            torch.save(payload, fh)

    @classmethod
    def load(cls, path: str | os.PathLike[str], device: str | None = None) -> Self:
        """Read a file written by `save` (weights_only); `device` overrides the saved config's device.

        Raises:
            FileNotFoundError: no such file.
            ModelFormatError: not an M-SVDD model file, another format version, or a field missing or
                malformed (the message names the file and the field).
        """
        source = Path(path)
        if not source.is_file():
            raise FileNotFoundError(f"model file {source} does not exist")
        try:
            payload = torch.load(source, map_location="cpu", weights_only=True)
        except Exception as err:
            raise ModelFormatError(
                f"{source} is not an M-SVDD model file (expected a file written by MSVDD.save)"
            ) from err
        if not isinstance(payload, dict) or payload.get("format") != _FORMAT_NAME:
            raise ModelFormatError(f"{source} is not an M-SVDD model file")
        version = payload.get("format_version")
        if version not in (1, 2, 3, FORMAT_VERSION):
            raise ModelFormatError(
                f"{source} has model format version {version}; this code reads versions 1 to {FORMAT_VERSION}"
            )
        with model_fields(source):
            return cls._from_payload(payload, version, device)

    @classmethod
    def _from_payload(cls, payload: dict[str, Any], version: int, device: str | None) -> Self:
        """The model a checked `save` payload of format `version` holds (a missing field: KeyError)."""
        cfg_dict = dict(payload["config"])
        if device is not None:
            cfg_dict["device"] = device
        model = cls(MSVDDConfig.from_dict(cfg_dict))
        model.module.load_state_dict(payload["state_dict"])
        model.module.eval()
        state = dict(payload["normalizer"])
        if version == 1:  # the paper's inputs, one z-velocity statistic
            state.update(audio_frontend="waveform", imu_input="z")
        model.normalizer = InputNormalizer.from_state(state)
        model.mu_ = payload["mu"].to(model.device)
        model.sigma_ = payload["sigma"].to(model.device)
        model.mean_d_ = float(payload["mean_d"])
        model.mean_rec_ = float(payload["mean_rec"])
        model.rec_scale_ = payload["rec_scale"].numpy() if "rec_scale" in payload else np.ones(2)
        if model.config.frame_density:
            key = "frame_density" if version >= 4 else "rec_gauss"
            model.frame_density_ = [ContextNet.from_state(g, model.device) for g in payload[key]]
        if version >= 4:
            raw = payload["sigma_raw"]
            model.sigma_raw_ = None if raw is None else raw.to(model.device)
            model.stats_fits_ = [StatsFit(**f) for f in payload["stats_fits"]]
        model.loaded_format_ = int(version)
        model._set_threshold(float(payload["threshold"]), str(payload.get("threshold_source", "train")))
        history = payload.get("history")
        model.history_ = None if history is None else TrainResult.from_dict(history)
        return model

    @property
    def radius_(self) -> float:
        """The learned soft-boundary radius R."""
        return float(self.module.radius.detach())


def _batches(tensors: Inputs) -> list[tuple[torch.Tensor, ...]]:
    """The network's inputs cut into inference batches of `_INFER_BATCH` windows."""
    return list(zip(*(t.split(_INFER_BATCH) for t in tensors), strict=True))


def _stats_fit(epoch: int, raw: torch.Tensor, floor: float) -> StatsFit:
    """The record of one estimate: the raw covariance's spectrum and how many eigenvalues the floor raised."""
    lam = torch.linalg.eigvalsh(0.5 * (raw + raw.T).to(torch.float64)).flip(0).clamp_min(0.0)
    return StatsFit(
        epoch=epoch,
        eigenvalues=[float(v) for v in lam],
        effective_rank=effective_rank(lam),
        floored=int((lam < floor * lam.mean()).sum()),
    )


def _cross(density: ContextNet, frames: list[torch.Tensor]) -> torch.Tensor | None:
    """The cross-modal frames a `ContextNet` of `frame_density` reads: the audio's (the first modality)
    when it has a cross-modal context, else None."""
    return frames[0] if density.cross_p > 0 else None


def _mcd_possible(n: int, config: MSVDDConfig) -> bool:
    """Whether `n` windows can hold the MCD support of a full-rank covariance in s dimensions."""
    try:
        support_size(n, config.s, config.mcd_support_fraction)
    except MCDError:
        return False
    return True
