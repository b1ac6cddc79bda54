"""A rerunnable diagnosis of a trained M-SVDD model: `msvdd-bench diagnose MODEL --data DIR`.

It reads the training history saved with the model (the radius R per epoch), the final Sigma and its raw
estimate (before the ridge or the variance floor), the estimates of mu and Sigma a `svdd_fit="frozen"` model
held during training (each one's spectrum and effective rank: does Sigma keep its rank?), the embeddings z of
(seeded, stratified subsamples of) the training and test windows, the two terms of the score
delta = D + w (mean_D / mean_Rec) Rec per test kind and anomaly sub-kind (D's share of the score, and D
alone's AUC on collisions and faults), and how much of z a window's loudness and motion explain. Rec is the
decoders' reconstruction error, or for `frame-density-msvdd` its frame-density term. Nothing here changes the
model; the same inputs give the same report.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import tempfile
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import spearmanr
from sklearn.metrics import roc_auc_score

from benchmarks import methods
from benchmarks.dataset import WindowRow, load_window_rows, open_dataset
from benchmarks.errors import OutputExistsError, UserError
from benchmarks.uncertainty import Interval, auc_interval, format_interval
from msvdd.contract import Windows
from msvdd.model import MSVDD, StatsFit
from msvdd.training import TrainResult

R_COLLAPSE_FRACTION = 1e-2
"""R is called collapsed when |R| at the kept epoch is below this fraction of its initial value sqrt(s)."""
RIDGE_FACTOR = 10.0
"""A Sigma eigenvalue within this factor of the ridge added to it (`ridge_of`) is a direction the ridge
dominates."""
Z_COLLAPSE_VARIANCE = 1e-6
"""A z dimension whose training variance is below this is collapsed."""
KINDS: tuple[str, ...] = ("normal", "collision", "mechanical")
"""Test window kinds, in report order."""


@dataclass(frozen=True)
class Counts:
    """How many windows the diagnosis read, of how many."""

    train_total: int
    """Training windows in the dataset."""
    train_used: int
    """Training windows in the seeded subsample."""
    test_total: dict[str, int]
    """Test windows in the dataset, per kind."""
    test_used: dict[str, int]
    """Test windows in the stratified subsample, per kind."""
    seed: int
    """Seed of the subsampling RNG."""


@dataclass(frozen=True)
class HistorySummary:
    """The radius R and the losses over the training epochs."""

    epochs: int
    """Epochs trained."""
    kept_epoch: int
    """Epoch (0-based) whose weights were kept (best validation loss, else the last)."""
    radius_initial: float
    """R before training: sqrt(s)."""
    radius_first: float
    """R after the first epoch."""
    radius_min: float
    """Smallest R after any epoch."""
    radius_max: float
    """Largest R after any epoch."""
    radius_last: float
    """R after the last epoch."""
    radius_kept: float
    """R at the kept epoch."""
    collapsed: bool
    """|R| at the kept epoch < R_COLLAPSE_FRACTION * sqrt(s)."""
    rule: str
    """The collapse rule, in words."""
    train_loss: list[float]
    """Mean training loss of each epoch."""
    val_loss: list[float]
    """Validation loss of each epoch (empty without validation)."""
    terms_kept: dict[str, float]
    """Mean SVDD, reconstruction and regulariser terms of the kept epoch."""


@dataclass(frozen=True)
class Spectrum:
    """The eigen-spectrum of a covariance matrix."""

    eigenvalues: list[float]
    """Eigenvalues, largest first."""
    condition_number: float
    """Largest / smallest eigenvalue."""
    effective_rank: float
    """exp(entropy of the eigenvalues normalised to sum 1); between 1 and the dimension."""
    n_ridge_dominated: int
    """Eigenvalues <= RIDGE_FACTOR * eps (only for Sigma; 0 for the z covariances)."""


@dataclass(frozen=True)
class HeldEstimate:
    """One estimate of mu and Sigma that a `svdd_fit="frozen"` model held fixed during training."""

    epoch: int
    """Epochs trained when it was made (0: the initial network; -1: the final estimate after training)."""
    effective_rank: float
    """Effective rank of the raw MCD covariance (before the floor)."""
    smallest_over_largest: float
    """Its smallest eigenvalue over its largest."""
    floored: int
    """Eigenvalues the variance floor raised."""
    trace: float
    """Its trace (the embeddings' scale)."""


@dataclass(frozen=True)
class EmbeddingSummary:
    """The spread of the embeddings z."""

    train_variance: list[float]
    """Per-dimension variance of z on the training windows, largest first."""
    test_variance: list[float]
    """Per-dimension variance of z on the test windows, in the order of `train_variance`."""
    n_collapsed: int
    """Dimensions whose training variance is below Z_COLLAPSE_VARIANCE."""
    train_spectrum: Spectrum
    """Spectrum of the training z covariance."""
    test_spectrum: Spectrum
    """Spectrum of the test z covariance."""


@dataclass(frozen=True)
class GroupTerms:
    """The two score terms on one group of test windows."""

    group: str
    """`normal`, `collision`, `mechanical`, `all anomalies` or an anomaly sub-kind."""
    n: int
    """Windows in the group."""
    mean_d: float
    """Mean D (Mahalanobis, or Euclidean, distance)."""
    mean_rec: float
    """Mean weighted reconstruction term w (mean_D / mean_Rec) Rec."""
    share_d: float
    """mean_d / mean score."""
    share_rec: float
    """mean_rec / mean score."""
    auc_d: float | None
    """ROC AUC of D alone, group vs normal test windows (None for the normal group)."""
    auc_rec: float | None
    """ROC AUC of the weighted Rec term alone (None for normal, or without reconstruction)."""
    auc_score: float | None
    """ROC AUC of the full score (None for the normal group)."""


WEIGHT_GRID: tuple[float, ...] = (0.0, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0)
"""Weights w of the reconstruction term tried by `weight_sweep` (0.01 is the paper's)."""


@dataclass(frozen=True)
class WeightAUC:
    """The AUCs the score D + w (mean_D / mean_Rec) Rec would have with another w."""

    w: float
    """Weight of the scaled reconstruction term."""
    auc: float
    """ROC AUC, every anomalous test window against the normal ones."""
    auc_collision: float | None
    """ROC AUC, collision windows against normal (None without collisions)."""
    auc_mechanical: float | None
    """ROC AUC, fault windows against normal (None without faults)."""


@dataclass(frozen=True)
class Encoding:
    """How much of z window loudness and motion explain."""

    covariates: list[str]
    """Covariates computed per window (see `window_covariates`)."""
    r2: dict[str, float]
    """Covariate set -> variance-weighted R^2 of the OLS of z on it (training windows)."""
    spearman_d: dict[str, float | None]
    """Covariate -> Spearman correlation with D on normal test windows (None if either is constant)."""


@dataclass(frozen=True)
class Diagnosis:
    """Everything `msvdd-bench diagnose` reports."""

    model: str
    """Model folder."""
    method: str
    """Registry name of the model's method."""
    dataset: str
    """Dataset folder."""
    config: dict[str, Any]
    """The model's MSVDDConfig fields that matter here."""
    rec_weight: float
    """w * mean_D / mean_Rec, the factor of Rec in the score (0 without reconstruction)."""
    counts: Counts
    """Windows read."""
    history: HistorySummary | None
    """Training history; None for a model file saved before histories were kept."""
    sigma: Spectrum
    """Spectrum of the final Sigma (eps I included)."""
    sigma_raw: Spectrum | None
    """Spectrum of its raw MCD estimate, before the ridge or the variance floor (None: not saved with the
    model, or a Euclidean model)."""
    held: list[HeldEstimate]
    """The estimates a `svdd_fit="frozen"` model held during training, and its final one (empty else)."""
    second_term: str
    """What Rec is: `reconstruction` (the decoders'), `frame density` (`frame_density`) or `none`."""
    embeddings: EmbeddingSummary
    """Spread of z."""
    terms: list[GroupTerms]
    """Score decomposition per test kind and anomaly sub-kind."""
    d_alone: dict[str, Interval]
    """`collision`, `mechanical`, `all anomalies` -> AUC of D alone against the normal test windows read, with
    its episode-cluster bootstrap interval (`benchmarks.uncertainty`), for the groups the windows hold."""
    weights: list[WeightAUC]
    """AUCs for each w of `WEIGHT_GRID` (empty without reconstruction): the choice of w, on a dev set."""
    encoding: Encoding
    """What z encodes."""


# ---------------------------------------------------------------- small analytic pieces


def effective_rank(eigenvalues: np.ndarray) -> float:
    """exp(Shannon entropy of p = lambda / sum lambda), negative eigenvalues clipped to 0; nan if all 0."""
    lam = np.clip(np.asarray(eigenvalues, dtype=np.float64), 0.0, None)
    total = lam.sum()
    if total <= 0:
        return float("nan")
    p = lam[lam > 0] / total
    return float(np.exp(-(p * np.log(p)).sum()))


def spectrum(cov: np.ndarray, eps: float | None = None) -> Spectrum:
    """Eigenvalues (largest first), condition number, effective rank; ridge-dominated count if `eps`."""
    lam = np.sort(np.linalg.eigvalsh(np.asarray(cov, dtype=np.float64)))[::-1]
    smallest = lam[-1]
    cond = float(lam[0] / smallest) if smallest > 0 else float("inf")
    ridge = int(np.sum(lam <= RIDGE_FACTOR * eps)) if eps is not None else 0
    return Spectrum([float(v) for v in lam], cond, effective_rank(lam), ridge)


def ridge_of(model: MSVDD) -> float:
    """The ridge added to the model's Sigma: eps I with the paper's per-batch fit; with held statistics
    (`svdd_fit="frozen"`) eps times the raw estimate's mean eigenvalue, relative to the embeddings' scale."""
    cfg = model.config
    if cfg.svdd_fit == "frozen" and model.sigma_raw_ is not None:
        raw = model.sigma_raw_.detach().cpu().numpy()
        return float(cfg.eps * np.trace(raw) / raw.shape[0])
    return float(cfg.eps)


def explained_variance(z: np.ndarray, x: np.ndarray) -> float:
    """Variance-weighted R^2 of the OLS (with intercept) of every column of z (N, s) on x (N, k).

    1 - sum_j SS_res_j / sum_j SS_tot_j: the share of z's total variance the covariates explain linearly.
    """
    z = np.asarray(z, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64).reshape(len(z), -1)
    scale = x.std(axis=0)
    x = (x - x.mean(axis=0)) / np.where(scale > 0, scale, 1.0)
    design = np.column_stack([np.ones(len(z)), x])
    coef, *_ = np.linalg.lstsq(design, z, rcond=None)
    ss_res = float(((z - design @ coef) ** 2).sum())
    ss_tot = float(((z - z.mean(axis=0)) ** 2).sum())
    return 1.0 - ss_res / ss_tot if ss_tot > 0 else float("nan")


def window_covariates(windows: Windows, chunk: int = 256) -> dict[str, np.ndarray]:
    """Per-window loudness, motion and (with imu6) acceleration roughness, each (N,) float64.

    loudness: log RMS of the audio (both channels); motion: std of the IMU z-velocity;
    acc: RMS of |a| minus its window mean, |a| the accelerometer magnitude (only if `imu6` is present).
    """
    ms = np.concatenate(
        [np.mean(np.square(windows.audio[i : i + chunk], dtype=np.float64), axis=(1, 2))
         for i in range(0, len(windows), chunk)]
    )  # fmt: skip
    out = {
        "loudness": 0.5 * np.log(ms + 1e-30),
        "motion": np.asarray(windows.imu, dtype=np.float64).std(axis=1),
    }
    if windows.imu6 is not None:
        magnitude = np.linalg.norm(np.asarray(windows.imu6[:, :, :3], dtype=np.float64), axis=2)
        out["acc"] = magnitude.std(axis=1)
    return out


def _quotas(counts: np.ndarray, n: int) -> np.ndarray:
    """Split n over groups in proportion to `counts` (largest remainder; ties to the earlier group)."""
    quota = counts * n / counts.sum()
    take = np.floor(quota).astype(np.int64)
    order = np.argsort(-(quota - take), kind="stable")
    take[order[: n - int(take.sum())]] += 1
    return take


def stratified_subsample(kinds: Sequence[str], sub_kinds: Sequence[str], n_max: int, seed: int) -> np.ndarray:
    """Sorted indices of min(n_max, N) items: each kind keeps its share, and each sub-kind within its kind.

    Shares are split by largest remainder; the items of each (kind, sub-kind) are drawn without replacement
    by a `numpy.random.default_rng(seed)`, so the same inputs give the same indices.
    """
    kind_arr, sub_arr = np.asarray(kinds, dtype=str), np.asarray(sub_kinds, dtype=str)
    if len(kind_arr) <= n_max:
        return np.arange(len(kind_arr))
    rng = np.random.default_rng(seed)
    chosen: list[np.ndarray] = []
    kind_names = sorted(set(kind_arr.tolist()))
    per_kind = _quotas(np.array([np.sum(kind_arr == k) for k in kind_names]), n_max)
    for kind, n_kind in zip(kind_names, per_kind, strict=True):
        subs = sorted(set(sub_arr[kind_arr == kind].tolist()))
        members = [np.flatnonzero((kind_arr == kind) & (sub_arr == s)) for s in subs]
        for idx, n_sub in zip(
            members, _quotas(np.array([len(m) for m in members]), int(n_kind)), strict=True
        ):
            chosen.append(rng.choice(idx, size=int(n_sub), replace=False))
    return np.sort(np.concatenate(chosen))


# ---------------------------------------------------------------- the five parts


def summarise_history(history: TrainResult | None, s: int) -> HistorySummary | None:
    """R trajectory and losses; None without a history or without a recorded radius."""
    radius = [] if history is None else history.epochs.get("radius", [])
    if history is None or not radius:
        return None
    n = len(radius)
    kept = history.best_epoch if 0 <= history.best_epoch < n else n - 1
    initial = math.sqrt(s)
    terms = {k: float(v[kept]) for k, v in history.epochs.items() if k != "radius" and len(v) > kept}
    return HistorySummary(
        epochs=n,
        kept_epoch=kept,
        radius_initial=initial,
        radius_first=radius[0],
        radius_min=min(radius),
        radius_max=max(radius),
        radius_last=radius[-1],
        radius_kept=radius[kept],
        collapsed=abs(radius[kept]) < R_COLLAPSE_FRACTION * initial,
        rule=f"collapsed if |R| at the kept epoch < {R_COLLAPSE_FRACTION:g} x sqrt(s) = "
        f"{R_COLLAPSE_FRACTION * initial:.4g}",
        train_loss=list(history.train_loss),
        val_loss=list(history.val_loss),
        terms_kept=terms,
    )


def rec_weight(model: MSVDD) -> float:
    """The factor of Rec in the score: w * mean_D / mean_Rec (0 without a second term)."""
    return float(model.config.w * model.mean_d_ / model.mean_rec_) if model.has_term else 0.0


def second_term(model: MSVDD) -> str:
    """What the score's second term is: `frame density`, `reconstruction` or `none`."""
    if model.config.frame_density:
        return "frame density"
    return "reconstruction" if model.config.use_reconstruction else "none"


def held_estimate(fit: StatsFit) -> HeldEstimate:
    """A `StatsFit` of the model, summarised."""
    lam = np.asarray(fit.eigenvalues, dtype=np.float64)
    top = float(lam.max()) if lam.size else float("nan")
    return HeldEstimate(
        epoch=fit.epoch,
        effective_rank=fit.effective_rank,
        smallest_over_largest=float(lam.min()) / top if lam.size and top > 0 else float("nan"),
        floored=fit.floored,
        trace=float(lam.sum()),
    )


def score_terms(model: MSVDD, windows: Windows) -> tuple[np.ndarray, np.ndarray]:
    """(D, weighted Rec) per window; their sum is `model.score(windows)`."""
    d, rec = model.score_components(windows)
    return np.asarray(d, dtype=np.float64), rec_weight(model) * np.asarray(rec, dtype=np.float64)


def _auc(normal: np.ndarray, group: np.ndarray) -> float:
    y = np.r_[np.zeros(len(normal)), np.ones(len(group))]
    return float(roc_auc_score(y, np.r_[normal, group]))


def decompose(
    d: np.ndarray, wrec: np.ndarray, kinds: Sequence[str], sub_kinds: Sequence[str], has_rec: bool = True
) -> list[GroupTerms]:
    """The score terms per kind, over all anomalies and per anomaly sub-kind; AUCs against `normal`."""
    kind_arr, sub_arr = np.asarray(kinds, dtype=str), np.asarray(sub_kinds, dtype=str)
    score = d + wrec
    normal = kind_arr == "normal"
    groups: list[tuple[str, np.ndarray]] = [(k, kind_arr == k) for k in KINDS if np.any(kind_arr == k)]
    groups.append(("all anomalies", ~normal))
    for kind in KINDS[1:]:
        groups += [(s, (kind_arr == kind) & (sub_arr == s)) for s in sorted(set(sub_arr[kind_arr == kind]))]
    out: list[GroupTerms] = []
    for name, mask in groups:
        if not np.any(mask):
            continue
        md, mr = float(d[mask].mean()), float(wrec[mask].mean())
        total = md + mr
        vs = name != "normal" and bool(np.any(normal))
        out.append(
            GroupTerms(
                group=name,
                n=int(mask.sum()),
                mean_d=md,
                mean_rec=mr,
                share_d=md / total if total else float("nan"),
                share_rec=mr / total if total else float("nan"),
                auc_d=_auc(d[normal], d[mask]) if vs else None,
                auc_rec=_auc(wrec[normal], wrec[mask]) if vs and has_rec else None,
                auc_score=_auc(score[normal], score[mask]) if vs else None,
            )
        )
    return out


def d_alone_intervals(d: np.ndarray, kinds: Sequence[str], episodes: Sequence[str]) -> dict[str, Interval]:
    """AUC of D alone with its episode-cluster interval, collisions, faults and all anomalies each against
    every normal window, for the groups present."""
    kind_arr, episode_arr = np.asarray(kinds, dtype=str), np.asarray(episodes, dtype=str)
    normal = kind_arr == "normal"
    groups = {
        "collision": kind_arr == "collision",
        "mechanical": kind_arr == "mechanical",
        "all anomalies": ~normal,
    }
    return {
        name: auc_interval(d[normal | mask], mask[normal | mask], episode_arr[normal | mask])
        for name, mask in groups.items()
        if np.any(mask) and np.any(normal)
    }


def weight_sweep(d: np.ndarray, rec: np.ndarray, ratio: float, kinds: Sequence[str]) -> list[WeightAUC]:
    """AUCs of D + w ratio Rec for every w of `WEIGHT_GRID`; `ratio` = mean_D / mean_Rec of training."""
    kind_arr = np.asarray(kinds, dtype=str)
    normal = kind_arr == "normal"
    out = []
    for w in WEIGHT_GRID:
        score = d + w * ratio * rec
        per_kind = {
            k: _auc(score[normal], score[kind_arr == k]) if np.any(kind_arr == k) else None
            for k in ("collision", "mechanical")
        }
        out.append(
            WeightAUC(w, _auc(score[normal], score[~normal]), per_kind["collision"], per_kind["mechanical"])
        )
    return out


def _spearman(a: np.ndarray, b: np.ndarray) -> float | None:
    if len(a) < 3 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rho = float(spearmanr(a, b).statistic)
    return rho if np.isfinite(rho) else None


def encoding(
    z_train: np.ndarray,
    cov_train: dict[str, np.ndarray],
    d_normal: np.ndarray,
    cov_normal: dict[str, np.ndarray],
) -> Encoding:
    """R^2 of z on each covariate alone and on all together; Spearman of D with each on normal test
    windows."""
    names = list(cov_train)
    sets = {name: [name] for name in names}
    sets["all (" + " + ".join(names) + ")"] = names
    r2 = {
        label: explained_variance(z_train, np.column_stack([cov_train[c] for c in cols]))
        for label, cols in sets.items()
    }
    return Encoding(names, r2, {c: _spearman(d_normal, cov_normal[c]) for c in names})


# ---------------------------------------------------------------- the whole diagnosis


def load_msvdd(folder: Path) -> tuple[str, MSVDD]:
    """(method name, model) of an M-SVDD family model folder; ValueError naming the method otherwise."""
    name, detector = methods.load_detector(folder)
    if not isinstance(detector, MSVDD):
        family = methods.spec(name).family
        raise UserError(
            f"{folder} holds method {name!r} (family {family!r}), not an M-SVDD model; diagnose reads "
            f"the msvdd family only: {', '.join(methods.names('msvdd'))} (a frame-density reference's "
            "modality terms: `msvdd-bench terms`)"
        )
    return name, detector


def _load(
    dataset_path: Path, rows: list[WindowRow], index: np.ndarray, progress: bool, what: str
) -> tuple[Windows, list[WindowRow]]:
    return load_window_rows(dataset_path, [rows[i] for i in index], progress=progress, what=what)


def diagnose(
    model_dir: Path,
    data_dir: Path,
    max_windows: int = 3000,
    seed: int = 0,
    verify: bool = False,
    progress: bool = False,
) -> Diagnosis:
    """Diagnose the M-SVDD model in `model_dir` on (subsamples of) the dataset in `data_dir`.

    Raises:
        ValueError: not an M-SVDD model, max_windows too small, or a test split without both kinds.
    """
    if max_windows < 20:
        raise UserError(f"--max-windows = {max_windows} is invalid; allowed: an integer >= 20")
    name, model = load_msvdd(model_dir)
    dataset = open_dataset(data_dir, verify=verify, progress=progress)
    train_rows, test_rows = dataset.rows("train"), dataset.rows("test")
    test_kinds = [r.kind for r in test_rows]
    if "normal" not in test_kinds or set(test_kinds) == {"normal"}:
        raise UserError(f"{data_dir}: the test split needs nominal and anomalous windows")
    tr_idx = stratified_subsample(["normal"] * len(train_rows), ["none"] * len(train_rows), max_windows, seed)
    te_idx = stratified_subsample(test_kinds, [r.sub_kind for r in test_rows], max_windows, seed + 1)
    train, _ = _load(dataset.path, train_rows, tr_idx, progress, "loading train")
    test, rows = _load(dataset.path, test_rows, te_idx, progress, "loading test")
    kinds, sub_kinds = [r.kind for r in rows], [r.sub_kind for r in rows]

    cfg = model.config
    z_train = model.embed(train).astype(np.float64)
    z_test = model.embed(test).astype(np.float64)
    d, wrec = score_terms(model, test)
    var_train, var_test = z_train.var(axis=0), z_test.var(axis=0)
    order = np.argsort(-var_train, kind="stable")
    embeddings = EmbeddingSummary(
        train_variance=[float(v) for v in var_train[order]],
        test_variance=[float(v) for v in var_test[order]],
        n_collapsed=int(np.sum(var_train < Z_COLLAPSE_VARIANCE)),
        train_spectrum=spectrum(np.cov(z_train, rowvar=False).reshape(cfg.s, cfg.s)),
        test_spectrum=spectrum(np.cov(z_test, rowvar=False).reshape(cfg.s, cfg.s)),
    )
    assert model.sigma_ is not None  # a loaded model always has one
    normal = np.asarray(kinds) == "normal"
    cov_test = window_covariates(test)
    return Diagnosis(
        model=str(model_dir),
        method=name,
        dataset=str(data_dir),
        config={k: v for k, v in cfg.to_dict().items() if k not in ("device", "progress")},
        rec_weight=rec_weight(model),
        counts=Counts(
            train_total=len(train_rows),
            train_used=len(tr_idx),
            test_total={k: test_kinds.count(k) for k in KINDS},
            test_used={k: kinds.count(k) for k in KINDS},
            seed=seed,
        ),
        history=summarise_history(model.history_, cfg.s),
        sigma=spectrum(model.sigma_.detach().cpu().numpy(), ridge_of(model)),
        sigma_raw=None if model.sigma_raw_ is None else spectrum(model.sigma_raw_.detach().cpu().numpy()),
        held=[held_estimate(f) for f in model.stats_fits_],
        second_term=second_term(model),
        embeddings=embeddings,
        terms=decompose(d, wrec, kinds, sub_kinds, has_rec=model.has_term),
        d_alone=d_alone_intervals(d, kinds, [r.episode for r in rows]),
        weights=(
            weight_sweep(d, wrec / rec_weight(model), model.mean_d_ / model.mean_rec_, kinds)
            if model.has_term and rec_weight(model) > 0
            else []
        ),
        encoding=encoding(
            z_train, window_covariates(train), d[normal], {k: v[normal] for k, v in cov_test.items()}
        ),
    )


# ---------------------------------------------------------------- output


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def diagnosis_json(d: Diagnosis) -> str:
    """The diagnosis as JSON (nan and inf written as null)."""
    return json.dumps(_finite(dataclasses.asdict(d)), indent=2, sort_keys=True) + "\n"


def _f(value: float | None, digits: int = 4) -> str:
    return "—" if value is None or not math.isfinite(value) else f"{value:.{digits}g}"


def _pct(value: float) -> str:
    return f"{value:.1%}" if math.isfinite(value) else "—"


def _spectrum_line(s: Spectrum) -> str:
    rank = f"effective rank {_f(s.effective_rank, 3)} of {len(s.eigenvalues)}"
    return f"condition number {_f(s.condition_number)}, {rank}"


def diagnosis_markdown(d: Diagnosis) -> str:
    """The diagnosis as a markdown report."""
    sections = [
        _header_lines(d),
        _history_lines(d.history, d.config.get("svdd_fit", "batch")),
        _sigma_lines(d),
        _embedding_lines(d.embeddings),
        _decomposition_lines(d),
        _encoding_lines(d.encoding),
    ]
    return "\n\n".join("\n".join(lines) for lines in sections)


def _header_lines(d: Diagnosis) -> list[str]:
    """Title, the model's configuration and the windows read."""
    c = d.counts
    cfg = d.config
    return [
        f"# Diagnosis of `{d.model}` ({d.method})",
        "",
        f"Dataset `{d.dataset}`; s = {cfg['s']}, eps = {cfg['eps']:g}, w = {cfg['w']:g}, "
        f"Mahalanobis {cfg['use_mahalanobis']}, reconstruction {cfg['use_reconstruction']}, "
        f"fusion {cfg['fusion']}"
        + "".join(
            f", {k} {cfg[k]}"
            for k in ("audio_frontend", "imu_input", "svdd_fit", "bias_free", "frame_density")
            if k in cfg
        )
        + f"; the score's second term: {d.second_term}.",
        f"Windows (seeded subsample, seed {c.seed}): train {c.train_used} of {c.train_total}; test "
        + ", ".join(f"{k} {c.test_used[k]} of {c.test_total[k]}" for k in KINDS)
        + " (kinds and sub-kinds kept in proportion).",
    ]


def _history_lines(h: HistorySummary | None, svdd_fit: str = "batch") -> list[str]:
    """Section 1: the radius R over training, and the losses."""
    lines = ["## 1. Training history", ""]
    if h is None:
        lines.append(
            "No training history with a per-epoch R in the model file (saved before histories were kept)."
        )
        return lines
    radius = (
        [
            f"{h.epochs} epochs, kept epoch {h.kept_epoch}. The loss holds mu and Sigma fixed between "
            "estimates (svdd_fit frozen): the radius R is not trained.",
        ]
        if svdd_fit == "frozen"
        else [
            f"{h.epochs} epochs, kept epoch {h.kept_epoch}. R: initial sqrt(s) = {_f(h.radius_initial)}, "
            f"first {_f(h.radius_first)}, min {_f(h.radius_min)}, max {_f(h.radius_max)}, "
            f"last {_f(h.radius_last)}, kept {_f(h.radius_kept)}.",
            f"R collapsed: **{'yes' if h.collapsed else 'no'}** ({h.rule}).",
        ]
    )
    lines += [
        *radius,
        f"Training loss first {_f(h.train_loss[0])}, last {_f(h.train_loss[-1])}"
        + (
            f"; validation loss at the kept epoch {_f(h.val_loss[h.kept_epoch])}"
            if len(h.val_loss) > h.kept_epoch
            else ""
        )
        + "; kept epoch's terms: "
        + ", ".join(f"{k} {_f(v)}" for k, v in h.terms_kept.items())
        + ".",
    ]
    return lines


def _sigma_lines(d: Diagnosis) -> list[str]:
    """Section 2: the eigen-spectrum of Sigma, of its raw estimate, and of the estimates held in training."""
    sig = d.sigma
    lines = [
        "## 2. Sigma",
        "",
        f"{_spectrum_line(sig)}; {sig.n_ridge_dominated} eigenvalue(s) within {RIDGE_FACTOR:g} x the ridge "
        "added to it (eps I, or eps times the mean eigenvalue with held statistics), which dominates there.",
        "Eigenvalues: " + ", ".join(_f(v, 3) for v in sig.eigenvalues) + ".",
    ]
    if d.sigma_raw is not None:
        lines += [
            "",
            f"Raw MCD estimate (before the ridge or the variance floor): {_spectrum_line(d.sigma_raw)}.",
            "Eigenvalues: " + ", ".join(_f(v, 3) for v in d.sigma_raw.eigenvalues) + ".",
        ]
    if d.held:
        lines += [
            "",
            "The estimates of mu and Sigma held fixed during training (after that many epochs; final = after "
            "training, the one the score uses), raw MCD covariance before the floor; an effective rank that "
            "falls from one estimate to the next is Sigma losing rank:",
            "",
            "| after epoch | effective rank | smallest / largest eigenvalue | raised by the floor | trace |",
            "|---|---:|---:|---:|---:|",
            *[
                f"| {'final' if h.epoch < 0 else h.epoch} | {_f(h.effective_rank, 3)} "
                f"| {_f(h.smallest_over_largest, 3)} | {h.floored} | {_f(h.trace, 3)} |"
                for h in d.held
            ],
        ]
    return lines


def _embedding_lines(e: EmbeddingSummary) -> list[str]:
    """Section 3: the spread of the embeddings z."""
    return [
        "## 3. Embeddings z",
        "",
        f"Training z covariance: {_spectrum_line(e.train_spectrum)}; test z covariance: "
        f"{_spectrum_line(e.test_spectrum)}.",
        f"{e.n_collapsed} dimension(s) with training variance < {Z_COLLAPSE_VARIANCE:g} (collapsed).",
        "Per-dimension variance, train (largest first): "
        + ", ".join(_f(v, 3) for v in e.train_variance)
        + ".",
        "Same dimensions, test: " + ", ".join(_f(v, 3) for v in e.test_variance) + ".",
    ]


def _decomposition_lines(d: Diagnosis) -> list[str]:
    """Section 4: the D and Rec terms of the score per group, and the score with other weights w."""
    by_group = {t.group: t for t in d.terms}
    alone = ", ".join(
        f"{label} {format_interval(d.d_alone[g], percent=False, digits=3)}"
        for g, label in (("collision", "collisions"), ("mechanical", "faults"), ("all anomalies", "all"))
        if g in d.d_alone
    )
    normal = by_group.get("normal")
    rec_is = {
        "frame density": "the frame-density term",
        "reconstruction": "the decoders' reconstruction error",
    }
    lines = [
        "## 4. Score decomposition",
        "",
        f"score = D + {_f(d.rec_weight)} Rec (w mean_D / mean_Rec), Rec "
        f"{rec_is.get(d.second_term, 'absent')}. AUCs are each group against the normal test windows.",
        f"D alone: AUC {alone} (95 % episode-cluster intervals); D's share of the mean score on normal test "
        f"windows: {_pct(normal.share_d) if normal is not None else '—'}.",
        "",
        "| group | n | mean D | mean w·Rec | D share | Rec share | AUC D | AUC Rec | AUC score |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for t in d.terms:
        lines.append(
            f"| {t.group} | {t.n} | {_f(t.mean_d)} | {_f(t.mean_rec)} | {_pct(t.share_d)} "
            f"| {_pct(t.share_rec)} | {_f(t.auc_d, 3)} | {_f(t.auc_rec, 3)} | {_f(t.auc_score, 3)} |"
        )
    if d.weights:
        lines += [
            "",
            "The same score with other weights w of the reconstruction term (the model's: "
            f"{_f(d.config['w'])}; choose w on a dev dataset, never on the reported one):",
            "",
            "| w | AUC | AUC collision | AUC mechanical |",
            "|---:|---:|---:|---:|",
        ]
        lines += [
            f"| {_f(x.w)} | {_f(x.auc, 3)} | {_f(x.auc_collision, 3)} | {_f(x.auc_mechanical, 3)} |"
            for x in d.weights
        ]
    return lines


def _encoding_lines(e: Encoding) -> list[str]:
    """Section 5: how much of z the covariates explain (the report ends with a newline)."""
    return [
        "## 5. What z encodes",
        "",
        "Covariates per window: loudness = log RMS of the audio; motion = std of the IMU z-velocity"
        + (
            "; acc = RMS of the accelerometer magnitude about its window mean"
            if "acc" in e.covariates
            else ""
        )
        + ". Variance-weighted R^2 of an OLS (with intercept) of z on them, training windows:",
        "",
        "| covariates | R^2 |",
        "|---|---:|",
        *[f"| {k} | {_f(v, 3)} |" for k, v in e.r2.items()],
        "",
        "Spearman correlation of D with each covariate on normal test windows: "
        + ", ".join(f"{k} {_f(v, 3)}" for k, v in e.spearman_d.items())
        + ".",
        "",
    ]


OUTPUT_FILES: tuple[str, ...] = ("diagnosis.json", "diagnosis.md")
"""What `write_diagnosis` writes."""


def check_output(out: Path) -> None:
    """Refuse (OutputExistsError) an existing `out` that is not an earlier diagnosis folder."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(p.name not in OUTPUT_FILES for p in out.iterdir())):
        raise OutputExistsError(f"{out} exists and is not an earlier diagnosis folder; choose another --out")


def write_diagnosis(d: Diagnosis, out: Path) -> Path:
    """Write diagnosis.json and diagnosis.md into folder `out` atomically (temp folder, then rename).

    An existing `out` holding only those files (an earlier diagnosis) is replaced; any other existing
    folder is refused (`check_output`).
    """
    out = Path(out)
    check_output(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    old = out.parent / f".{out.name}.old-{tmp.name.rsplit('-', 1)[-1]}"
    try:
        (tmp / "diagnosis.json").write_text(diagnosis_json(d), encoding="utf-8")
        (tmp / "diagnosis.md").write_text(diagnosis_markdown(d), encoding="utf-8")
        if out.exists():
            os.replace(out, old)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        if old.exists() and not out.exists():
            os.replace(old, out)
        raise
    shutil.rmtree(old, ignore_errors=True)
    return out
