"""Shallow baselines on handcrafted features: Isolation Forest, OCSVM and kernel SVDD, early and late fusion.

Early fusion: one model on the concatenated audio and IMU features. Late fusion: one model per modality;
each modality's scores are z-normalised with the mean and standard deviation of its TRAINING scores and
the two are averaged. Features are standardised with training statistics first.

Kernel SVDD (Tax & Duin, 2004) with the RBF kernel IS the one-class SVM (Schölkopf et al., 2001): with
K(x, x) = 1 the SVDD dual, min a'Ka - a'diag(K) subject to sum a = 1 and 0 <= a <= 1 / (nu n), is the
one-class SVM dual up to the factor nu n on the weights, and the squared distance to the centre,
1 - 2 sum_i a_i K(x_i, x) + a'Ka, is a decreasing affine function of the one-class SVM's decision function.
The paper names no other kernel or setting for its SVDD, so `svdd-*` is fitted as the same scikit-learn
`OneClassSVM` (same nu, gamma and training rows) as `ocsvm-*`: its scores are identical by construction,
and the report says so next to the SVDD rows. `tests/benchmarks/test_baselines.py` checks the dual identity
against an independent QP solve.

Saving: scikit-learn models are not pickled: the file stores the standardised training features and the
hyper-parameters, and `load` refits deterministically (fixed random_state, one thread), then checks that the
refit reproduces the stored training scores bit for bit; a different scikit-learn version that changes them
is refused with a clear error.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Self

import numpy as np
from sklearn.ensemble import IsolationForest
from sklearn.svm import OneClassSVM

from benchmarks.features import FeatureConfig, window_features
from benchmarks.methods.base import WindowDetector, check_scale
from msvdd.contract import ModelFormatError, Windows

MODELS: tuple[str, ...] = ("iforest", "ocsvm", "svdd")
"""Shallow model kinds."""
FUSIONS: tuple[str, ...] = ("early", "late")
"""Feature fusion modes."""
NU = 0.05
"""OCSVM nu (= the SVDD outlier fraction, C = 1 / (nu n)), matching the 95th-percentile threshold."""
_STD_FLOOR = 1e-8


@dataclass(frozen=True)
class ShallowConfig:
    """Hyper-parameters of a shallow baseline."""

    model: str
    """One of `MODELS`."""
    fusion: str
    """`early` (one model on concatenated features) or `late` (one per modality, scores z-normalised)."""
    seed: int = 0
    """Seed of the Isolation Forest and of any subsample."""
    n_estimators: int = 100
    """Isolation Forest trees."""
    max_train: int = 2000
    """Training rows for OCSVM and SVDD (uniform subsample without replacement if more)."""

    @classmethod
    def for_scale(cls, model: str, fusion: str, seed: int, scale: str) -> ShallowConfig:
        """The budget of each scale: smoke (tests), short, full."""
        check_scale(scale)
        trees = {"smoke": 50, "short": 100, "full": 200}[scale]
        rows = {"smoke": 300, "short": 1500, "full": 3000}[scale]
        return cls(model=model, fusion=fusion, seed=seed, n_estimators=trees, max_train=rows)

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"model {self.model!r} is unknown; allowed: {', '.join(MODELS)}")
        if self.fusion not in FUSIONS:
            raise ValueError(f"fusion {self.fusion!r} is unknown; allowed: {', '.join(FUSIONS)}")


class _Block:
    """One model on one feature block: standardisation, the model, and its training-score statistics."""

    def __init__(self, config: ShallowConfig, mean: np.ndarray, std: np.ndarray) -> None:
        self.config = config
        self.mean = mean
        self.std = std
        self.train_x = np.zeros((0, mean.size))
        self.train_scores = np.zeros(0)
        self.sklearn: IsolationForest | OneClassSVM | None = None
        self.rows = (0, 0)
        """(training rows offered, rows the model was fitted on): OCSVM and SVDD subsample above max_train."""

    @classmethod
    def fit(cls, config: ShallowConfig, features: np.ndarray) -> _Block:
        block = cls(config, features.mean(axis=0), np.maximum(features.std(axis=0), _STD_FLOOR))
        block._fit_model(block.standardise(features))
        return block

    def standardise(self, features: np.ndarray) -> np.ndarray:
        return (features - self.mean) / self.std

    def _fit_model(self, x: np.ndarray) -> None:
        c = self.config
        offered = x.shape[0]
        if c.model == "iforest":
            self.sklearn = IsolationForest(n_estimators=c.n_estimators, random_state=c.seed, n_jobs=1).fit(x)
        else:  # ocsvm, and svdd: the same model (see the module docstring)
            if x.shape[0] > c.max_train:
                pick = np.random.default_rng(c.seed).choice(x.shape[0], c.max_train, replace=False)
                x = x[np.sort(pick)]
            self.sklearn = OneClassSVM(kernel="rbf", nu=NU, gamma="scale").fit(x)
        self.train_x = x
        self.rows = (offered, x.shape[0])
        self.train_scores = self.raw_scores(x)

    def raw_scores(self, x: np.ndarray) -> np.ndarray:
        """Model scores of standardised rows, higher = more anomalous."""
        if isinstance(self.sklearn, IsolationForest):
            return -self.sklearn.score_samples(x)
        if isinstance(self.sklearn, OneClassSVM):
            return -self.sklearn.decision_function(x)
        raise RuntimeError("block has no fitted model")

    def state(self, prefix: str) -> dict[str, np.ndarray]:
        arrays = {
            "mean": self.mean,
            "std": self.std,
            "train_x": self.train_x,
            "train_scores": self.train_scores,
        }
        return {f"{prefix}{k}": v for k, v in arrays.items()}

    @classmethod
    def from_state(cls, config: ShallowConfig, prefix: str, arrays: dict[str, np.ndarray]) -> _Block:
        block = cls(config, arrays[f"{prefix}mean"], arrays[f"{prefix}std"])
        block.train_scores = arrays[f"{prefix}train_scores"]
        if f"{prefix}support" in arrays:
            raise ModelFormatError(
                f"this {config.model} model was saved by the former hand-written SVDD solver, which was "
                "replaced by scikit-learn's one-class SVM (the same dual); retrain it"
            )
        stored = block.train_scores
        block._fit_model(arrays[f"{prefix}train_x"])
        if not np.array_equal(block.train_scores, stored):
            raise ModelFormatError(
                f"refitting the saved {config.model} did not reproduce its training scores "
                "(was it saved with another scikit-learn version?); retrain it"
            )
        return block


class ShallowDetector(WindowDetector):
    """A shallow model on handcrafted log-mel and IMU features, in early or late fusion."""

    kind = "shallow"
    min_train = 4

    def __init__(self, config: ShallowConfig, features: FeatureConfig | None = None) -> None:
        super().__init__()
        self.config = config
        self.features = features if features is not None else FeatureConfig()
        self._blocks: list[_Block] = []

    @property
    def training_rows(self) -> list[tuple[int, int]]:
        """Per model: (training windows offered, windows it was fitted on); they differ when subsampled."""
        return [b.rows for b in self._blocks]

    def _feature_blocks(self, batch: Windows) -> list[np.ndarray]:
        f = window_features(batch, self.features)
        return [f.early()] if self.config.fusion == "early" else [f.audio, f.imu]

    def _fit(self, train: Windows, val: Windows | None) -> None:
        self._blocks = [_Block.fit(self.config, x) for x in self._feature_blocks(train)]

    def _score(self, batch: Windows) -> np.ndarray:
        parts = []
        for block, x in zip(self._blocks, self._feature_blocks(batch), strict=True):
            raw = block.raw_scores(block.standardise(x))
            if len(self._blocks) > 1:
                ref = block.train_scores
                raw = (raw - ref.mean()) / max(float(ref.std()), _STD_FLOOR)
            parts.append(raw)
        return np.mean(parts, axis=0)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        c = self.config
        header = {
            "config": {
                "model": c.model,
                "fusion": c.fusion,
                "seed": c.seed,
                "n_estimators": c.n_estimators,
                "max_train": c.max_train,
            },
            "features": {**self.features.__dict__, "imu_band_edges": list(self.features.imu_band_edges)},
            "n_blocks": len(self._blocks),
            "rows": [list(b.rows) for b in self._blocks],
        }
        arrays: dict[str, np.ndarray] = {}
        for b, block in enumerate(self._blocks):
            arrays |= block.state(f"b{b}_")
        return header, arrays

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        config = ShallowConfig(**header["config"])
        feat = dict(header["features"])
        feat["imu_band_edges"] = tuple(feat["imu_band_edges"])
        detector = cls(config, FeatureConfig(**feat))
        detector._blocks = [
            _Block.from_state(config, f"b{b}_", arrays) for b in range(int(header["n_blocks"]))
        ]
        for block, rows in zip(detector._blocks, header["rows"], strict=True):
            block.rows = (int(rows[0]), int(rows[1]))
        return detector


_TITLES = {
    "iforest": "Isolation Forest",
    "ocsvm": "one-class SVM (RBF)",
    "svdd": "kernel SVDD (RBF): the one-class SVM's model (identical duals), scores equal ocsvm's",
}


_PAPER_ROWS: dict[str, tuple[int, str]] = {"iforest": (1, "IF"), "ocsvm": (2, "OCSVM"), "svdd": (3, "SVDD †")}
"""Each model's position and label in the paper's Table I (the † marks the footnote on SVDD = OCSVM)."""


def _factory(model: str, fusion: str) -> Any:
    def make(seed: int, scale: str, device: str) -> ShallowDetector:
        return ShallowDetector(ShallowConfig.for_scale(model, fusion, seed, scale))

    return make


def register_methods() -> None:
    """Register `iforest-early`, `iforest-late`, `ocsvm-early`, `ocsvm-late`, `svdd-early`, `svdd-late`."""
    from benchmarks.methods.registry import register
    from benchmarks.methods.spec import PaperRow

    for model in MODELS:
        for fusion in FUSIONS:
            how = "one model on concatenated" if fusion == "early" else "one model per modality on"
            position, label = _PAPER_ROWS[model]
            register(
                f"{model}-{fusion}",
                _factory(model, fusion),
                cls=ShallowDetector,
                family="shallow",
                modality="audio+imu",
                description=f"{_TITLES[model]}, {fusion} fusion: {how} log-mel + IMU features",
                paper=(PaperRow("Table I", position, f"{label} ({fusion} fusion)"),),
                config=f"ShallowConfig(model={model!r}, fusion={fusion!r})",
            )
