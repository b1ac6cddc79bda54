"""`MSVDD`: the paper's detector (Algorithm 1) behind the shared `Detector` contract.

fit: z-score statistics from the training windows; train the network with
alpha1 * L_MSVDD + alpha2 * L_Rec + alpha3 * L_Reg, mu and Sigma by MCD on each batch of `batch_size`; then mu
and Sigma by MCD over the embeddings of the whole training split (with `rec_score="fused"` also the mixture
density networks of the training windows' input frames, `msvdd.context_net`, their epochs chosen on the
validation windows), the training means of D and Rec, and
the score delta = D + w (mean_D / mean_Rec) Rec, Rec the reconstruction term `rec_score` names; the
threshold follows the rule of `msvdd.contract.Detector` (the `quantile` of the scores of held-out nominal
windows). No test label is ever seen. With
`use_mahalanobis=False` the same network is trained as a Euclidean soft-boundary Deep SVDD around a fixed
centre c (the mean initial embedding, Ruff et al. 2018) and scored by ||z - c||.
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
    huber_per_window,
    reconstruction_loss,
    svdd_loss,
)
from msvdd.mcd import MCDError, mahalanobis, mahalanobis_sq, min_cov_det, support_size
from msvdd.network import AUDIO_STRIDES, IMU_FRAME, FusionNet, NetOutput
from msvdd.residual import cut_frames
from msvdd.training import TrainResult, batched_loss, resolve_device, split_train_val, train_network

FORMAT_VERSION = 3
"""Version of the file written by `MSVDD.save` (2: front-end choice and per-channel statistics, training
history; 3: the frame densities of the reconstruction term); `load` also reads versions 1 (the paper's
waveform and z-velocity) and 2, refuses any other, and refuses a model of a retired `rec_score` by its
config."""
_FORMAT_NAME = "msvdd-model"
_INFER_BATCH = 256
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
    """Covariance regulariser (0 for Euclidean SVDD)."""


class _Module(nn.Module):
    """The network plus the learnable radius R and the (Euclidean mode) fixed centre."""

    def __init__(self, config: MSVDDConfig) -> None:
        super().__init__()
        self.net = FusionNet(config)
        self.center: torch.Tensor
        self.radius = nn.Parameter(torch.tensor(float(np.sqrt(config.s))))
        self.register_buffer("center", torch.zeros(config.s))


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
        self.rec_density_: list[ContextNet] | None = None
        self.threshold_ = float("nan")
        self.history_: TrainResult | None = None
        self._mcd_calls = 0
        self._terms: list[tuple[float, float, float]] = []

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
        if cfg.use_mahalanobis and n_val > 0 and not _mcd_possible(min(n_val, cfg.batch_size), cfg):
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
        self.normalizer, train_t = InputNormalizer.fit_tensors(
            fit_part, cfg.audio_frontend, cfg.imu_input, cfg.smooth_window, cfg.smooth_polyorder
        )
        val_t = None if val is None or len(val) == 0 else self._tensors(val)
        if not cfg.use_mahalanobis:
            self._init_center(train_t)
        self._mcd_calls = 0
        self._terms = []
        self.history_ = train_network(
            self.module,
            self.batch_loss,
            train_t,
            val_t,
            cfg,
            val_loss_fn=self._val_loss,
            epoch_probe=self._epoch_figures,
        )
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
                if n_val:
                    support_size(min(n_val, cfg.batch_size), cfg.s, cfg.mcd_support_fraction)
            except MCDError as err:
                raise WindowError(f"too few windows for the MCD in s={cfg.s} dimensions: {err}") from err

    def _tensors(self, batch: Windows) -> tuple[torch.Tensor, torch.Tensor]:
        if self.normalizer is None:
            raise NotFittedError("MSVDD is not fitted: call fit() or MSVDD.load()")
        return self.normalizer.tensors(batch, self.config.smooth_window, self.config.smooth_polyorder)

    def _init_center(self, train_t: tuple[torch.Tensor, torch.Tensor]) -> None:
        """Euclidean mode: c = mean initial embedding, entries near 0 pushed to +-eps (Ruff et al.)."""
        z = self._embed_tensors(train_t).mean(dim=0)
        eps = self.config.eps
        z = torch.where(z.abs() < eps, torch.where(z < 0, -eps, eps), z)
        self.module.center.copy_(z.to(self.module.center.dtype))

    def loss_terms(self, out: NetOutput, audio: torch.Tensor, imu: torch.Tensor, seed: int) -> LossTerms:
        """The loss of one batch given the network output (public for tests)."""
        cfg = self.config
        z = out.z
        zero = torch.zeros((), device=z.device)
        if cfg.use_mahalanobis:
            mu, sigma, _ = batch_statistics(z, cfg.eps, cfg.mcd_support_fraction, seed, cfg.mcd_trials)
            d2 = mahalanobis_sq(z, mu, sigma)
            reg = covariance_regulariser(sigma, cfg.eps)
        else:
            d2 = ((z - self.module.center) ** 2).sum(dim=1)
            reg = zero
        svdd = svdd_loss(d2, self.module.radius, cfg.nu)
        rec = zero
        if cfg.use_reconstruction:
            rec = reconstruction_loss(
                audio if cfg.use_audio else None, out.audio_rec, imu if cfg.use_imu else None, out.imu_rec
            ).mean()
        a1, a2, a3 = cfg.alpha
        return LossTerms(total=a1 * svdd + a2 * rec + a3 * reg, svdd=svdd, rec=rec, reg=reg)

    def batch_loss(self, module: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
        """Training loss of one (audio, imu) batch (the `loss_fn` given to `train_network`)."""
        audio, imu = batch
        self._mcd_calls += 1
        seed = self.config.seed * 1_000_003 + self._mcd_calls
        terms = self.loss_terms(self.module.net(audio, imu), audio, imu, seed)
        self._terms.append((float(terms.svdd.detach()), float(terms.rec.detach()), float(terms.reg.detach())))
        return terms.total

    def _epoch_figures(self) -> dict[str, float]:
        """The radius R after an epoch and the epoch's mean SVDD, reconstruction and regulariser terms."""
        means = np.mean(np.asarray(self._terms, dtype=np.float64), axis=0) if self._terms else np.zeros(3)
        self._terms = []
        return {"radius": self.radius_, "svdd": means[0], "rec": means[1], "reg": means[2]}

    def _val_loss(self, module: nn.Module, tensors: tuple[torch.Tensor, ...]) -> float:
        seed = self.config.seed

        def fixed(m: nn.Module, batch: tuple[torch.Tensor, ...]) -> torch.Tensor:
            audio, imu = batch
            return self.loss_terms(self.module.net(audio, imu), audio, imu, seed).total

        return batched_loss(fixed, self.config.batch_size, self.device)(module, tensors)

    def _finalise(
        self,
        train_t: tuple[torch.Tensor, torch.Tensor],
        val_t: tuple[torch.Tensor, torch.Tensor] | None = None,
    ) -> None:
        """mu, Sigma over the whole training split; the frame densities (`"fused"`: their epochs chosen on
        `val_t`); the training means of D and Rec."""
        cfg = self.config
        z = self._embed_tensors(train_t).to(torch.float64)
        if cfg.use_mahalanobis:
            mcd = min_cov_det(
                z, cfg.mcd_support_fraction, random_state=cfg.seed, n_trials=cfg.mcd_trials, ridge=cfg.eps
            )
            self.mu_ = mcd.location
            self.sigma_ = mcd.covariance + cfg.eps * torch.eye(cfg.s, dtype=torch.float64, device=z.device)
        else:
            self.mu_ = self.module.center.detach().to(torch.float64)
            self.sigma_ = torch.eye(cfg.s, dtype=torch.float64, device=z.device)
        if cfg.rec_score == "fused" and cfg.use_reconstruction:
            self.rec_density_ = self._fit_input_densities(train_t, val_t)
        d, parts = self._distance_and_parts(train_t)
        if cfg.rec_score != "mean" and parts.shape[1]:
            self.rec_scale_ = np.where(parts.mean(axis=0) > 0, parts.mean(axis=0), 1.0)
        else:
            self.rec_scale_ = np.ones(parts.shape[1])
        rec = self._rec(parts)
        self.mean_d_ = float(d.mean())
        self.mean_rec_ = float(rec.mean()) if cfg.use_reconstruction else 1.0
        if not np.isfinite(self.mean_d_) or self.mean_d_ <= 0 or not np.isfinite(self.mean_rec_):
            raise ValueError(
                f"training produced degenerate scores (mean D {self.mean_d_}, mean Rec {self.mean_rec_})"
            )

    # ---------------------------------------------------------------- scoring

    def _embed_tensors(self, tensors: tuple[torch.Tensor, torch.Tensor]) -> torch.Tensor:
        outs = []
        with torch.inference_mode():
            for a, i in zip(tensors[0].split(_INFER_BATCH), tensors[1].split(_INFER_BATCH), strict=True):
                outs.append(self.module.net(a.to(self.device), i.to(self.device)).z)
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

    def rec_parts(self, out: NetOutput, audio: torch.Tensor, imu: torch.Tensor) -> list[torch.Tensor]:
        """(N,) reconstruction error of each reconstructed modality, as `rec_score` measures it: the mean
        Huber error of the window ("mean"), or the largest input-frame distance under its density network
        ("fused")."""
        if self.config.rec_score == "fused":
            frames = self.input_frames(audio, imu)
            nets = self.rec_density_ or []
            if len(nets) != len(frames):
                raise NotFittedError("MSVDD is not fitted: its frame density networks are missing")
            return [g.peak_distance(f, _cross(g, frames)) for g, f in zip(nets, frames, strict=True)]
        return [huber_per_window(x, x_hat) for x, x_hat in self._rec_pairs(out, audio, imu)]

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

    def _fit_input_densities(
        self, train_t: tuple[torch.Tensor, torch.Tensor], val_t: tuple[torch.Tensor, torch.Tensor] | None
    ) -> list[ContextNet]:
        """`rec_score="fused"`: a `ContextNet` of each used modality's input frames given its neighbours; the
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

    def _distance_and_parts(
        self, tensors: tuple[torch.Tensor, torch.Tensor]
    ) -> tuple[np.ndarray, np.ndarray]:
        """(D (N,), reconstruction error per modality (N, M); M = 0 without reconstruction)."""
        if self.mu_ is None or self.sigma_ is None:
            raise NotFittedError("MSVDD is not fitted: call fit() or MSVDD.load()")
        d_all, parts_all = [], []
        with torch.inference_mode():
            for a, i in zip(tensors[0].split(_INFER_BATCH), tensors[1].split(_INFER_BATCH), strict=True):
                a, i = a.to(self.device), i.to(self.device)
                out = self.module.net(a, i)
                d_all.append(mahalanobis(out.z.to(torch.float64), self.mu_, self.sigma_).cpu())
                parts = self.rec_parts(out, a, i) if self.config.use_reconstruction else []
                parts_all.append(
                    torch.stack(parts, dim=1).to(torch.float64).cpu()
                    if parts
                    else torch.zeros(a.shape[0], 0, dtype=torch.float64)
                )
        return torch.cat(d_all).numpy(), torch.cat(parts_all).numpy()

    def _rec(self, parts: np.ndarray) -> np.ndarray:
        """The reconstruction term: the modalities' errors (in units of `rec_scale_`) summed; 0 without."""
        return (parts / self.rec_scale_[: parts.shape[1]]).sum(axis=1)

    def _components_tensors(
        self, tensors: tuple[torch.Tensor, torch.Tensor]
    ) -> tuple[np.ndarray, np.ndarray]:
        d, parts = self._distance_and_parts(tensors)
        return d, self._rec(parts)

    def _delta(self, d: np.ndarray, rec: np.ndarray) -> np.ndarray:
        if not self.config.use_reconstruction:
            return d.astype(np.float64)
        return (d + self.config.w * (self.mean_d_ / self.mean_rec_) * rec).astype(np.float64)

    def score_components(self, batch: Windows) -> tuple[np.ndarray, np.ndarray]:
        """(D (N,) Mahalanobis (or Euclidean) distance, Rec (N,) reconstruction loss; zeros without it)."""
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
            "rec_gauss": None if self.rec_density_ is None else [g.state() for g in self.rec_density_],
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
        if version not in (1, 2, FORMAT_VERSION):
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
        if model.config.rec_score == "fused" and model.config.use_reconstruction:
            model.rec_density_ = [ContextNet.from_state(g, model.device) for g in payload["rec_gauss"]]
        model._set_threshold(float(payload["threshold"]), str(payload.get("threshold_source", "train")))
        history = payload.get("history")
        model.history_ = None if history is None else TrainResult.from_dict(history)
        return model

    @property
    def radius_(self) -> float:
        """The learned soft-boundary radius R."""
        return float(self.module.radius.detach())


def _cross(density: ContextNet, frames: list[torch.Tensor]) -> torch.Tensor | None:
    """The cross-modal frames a `ContextNet` of `rec_score="fused"` reads: the audio's (the first modality)
    when it has a cross-modal context, else None."""
    return frames[0] if density.cross_p > 0 else None


def _mcd_possible(n: int, config: MSVDDConfig) -> bool:
    """Whether `n` windows can hold the MCD support of a full-rank covariance in s dimensions."""
    try:
        support_size(n, config.s, config.mcd_support_fraction)
    except MCDError:
        return False
    return True
