"""Deep Isolation Forest (Xu et al., 2023): isolation forests on random neural representations.

Each of `n_representations` randomly initialised, untrained copies of M-SVDD's network
(`msvdd.network.FusionNet`, no reconstruction branch; each seeded from the method's seed) maps the
normalised windows to its fused embedding z; a small isolation forest is grown on each representation of
the training windows, and the score is the mean over representations of the forests' anomaly scores
(-`score_samples`, higher = more anomalous).

Saving: the random networks' weights go into the `.npz`; the forests are not pickled but refitted on load
from the stored training embeddings (fixed random_state, one thread), and the refit must reproduce the
stored training scores bit for bit (else a clear error: another scikit-learn version).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Self

import numpy as np
import torch
from sklearn.ensemble import IsolationForest

from benchmarks.methods.base import WindowDetector, check_scale
from benchmarks.methods.deep_base import SCORE_CHUNK, scale_config
from msvdd.config import MSVDDConfig
from msvdd.contract import ModelFormatError, Windows
from msvdd.frontend import InputNormalizer
from msvdd.network import FusionNet
from msvdd.training import resolve_device


@dataclass(frozen=True)
class DeepIFConfig:
    """Budget of a Deep Isolation Forest."""

    n_representations: int
    """Random networks (representations)."""
    n_estimators: int
    """Isolation trees per representation."""
    seed: int
    """Seed of the networks and the forests."""

    @classmethod
    def for_scale(cls, seed: int, scale: str) -> DeepIFConfig:
        """smoke 4 x 25 trees, short 8 x 16, full 16 x 12 (Xu et al. use many small forests)."""
        check_scale(scale)
        reps, trees = {"smoke": (4, 25), "short": (8, 16), "full": (16, 12)}[scale]
        return cls(n_representations=reps, n_estimators=trees, seed=seed)


class DeepIsolationForest(WindowDetector):
    """Isolation forests on the embeddings of random, untrained M-SVDD networks."""

    kind = "deep-if"
    min_train = 4

    def __init__(self, config: DeepIFConfig, net_config: MSVDDConfig) -> None:
        super().__init__()
        self.config = config
        self.net_config = net_config
        self.nets: list[FusionNet] = []
        self.forests: list[IsolationForest] = []
        self.train_embeddings: list[np.ndarray] = []
        self.train_scores: list[np.ndarray] = []
        self.normalizer: InputNormalizer | None = None
        self.device = resolve_device(net_config.device)

    def _build_nets(self) -> list[FusionNet]:
        nets = []
        with torch.random.fork_rng(devices=[]):
            for r in range(self.config.n_representations):
                torch.manual_seed(self.config.seed * 1_000 + r)
                nets.append(FusionNet(self.net_config).to(self.device).eval())
        return nets

    def _embed(self, batch: Windows) -> list[np.ndarray]:
        if self.normalizer is None:
            raise RuntimeError("DeepIsolationForest has no normaliser; fit it first")
        cfg = self.net_config
        audio, imu = self.normalizer.tensors(batch, cfg.smooth_window, cfg.smooth_polyorder)
        out = []
        with torch.no_grad():
            for net in self.nets:
                parts = [
                    net(
                        audio[i : i + SCORE_CHUNK].to(self.device), imu[i : i + SCORE_CHUNK].to(self.device)
                    ).z.cpu()
                    for i in range(0, audio.shape[0], SCORE_CHUNK)
                ]
                out.append(torch.cat(parts).double().numpy())
        return out

    def _grow(self, embeddings: list[np.ndarray]) -> None:
        self.forests = [
            IsolationForest(
                n_estimators=self.config.n_estimators, random_state=self.config.seed * 1_000 + r, n_jobs=1
            ).fit(x)
            for r, x in enumerate(embeddings)
        ]
        self.train_embeddings = embeddings
        self.train_scores = [-f.score_samples(x) for f, x in zip(self.forests, embeddings, strict=True)]

    def _fit(self, train: Windows, val: Windows | None) -> None:
        cfg = self.net_config
        self.normalizer = InputNormalizer.fit(train, cfg.audio_frontend, cfg.imu_input)
        self.nets = self._build_nets()
        self._grow(self._embed(train))

    def _score(self, batch: Windows) -> np.ndarray:
        embeddings = self._embed(batch)
        return np.mean([-f.score_samples(x) for f, x in zip(self.forests, embeddings, strict=True)], axis=0)

    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        if self.normalizer is None:
            raise RuntimeError("not fitted")
        c = self.config
        header = {
            "config": {
                "n_representations": c.n_representations,
                "n_estimators": c.n_estimators,
                "seed": c.seed,
            },
            "net_config": self.net_config.to_dict(),
        }
        arrays = {f"norm/{k}": v for k, v in self.normalizer.arrays().items()}
        for r, net in enumerate(self.nets):
            arrays |= {f"net{r}/{k}": v.cpu().numpy() for k, v in net.state_dict().items()}
            arrays[f"emb{r}"] = self.train_embeddings[r]
            arrays[f"train_scores{r}"] = self.train_scores[r]
        return header, arrays

    @classmethod
    def _from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> Self:
        detector = cls(DeepIFConfig(**header["config"]), MSVDDConfig.from_dict(header["net_config"]))
        net_cfg = detector.net_config
        detector.normalizer = InputNormalizer.from_arrays(
            {k[5:]: v for k, v in arrays.items() if k.startswith("norm/")},
            net_cfg.audio_frontend,
            net_cfg.imu_input,
        )
        detector.nets = detector._build_nets()
        for r, net in enumerate(detector.nets):
            prefix = f"net{r}/"
            net.load_state_dict(
                {
                    k[len(prefix) :]: torch.from_numpy(v.copy())
                    for k, v in arrays.items()
                    if k.startswith(prefix)
                }
            )
        n = detector.config.n_representations
        detector._grow([arrays[f"emb{r}"] for r in range(n)])
        if not all(np.array_equal(detector.train_scores[r], arrays[f"train_scores{r}"]) for r in range(n)):
            raise ModelFormatError(
                "refitting the saved Deep Isolation Forest did not reproduce its training scores "
                "(was it saved with another scikit-learn version?); retrain it"
            )
        return detector


def register_methods() -> None:
    """Register `deep-if`."""
    from benchmarks.methods.registry import register
    from benchmarks.methods.spec import PaperRow

    def make(seed: int, scale: str, device: str) -> DeepIsolationForest:
        net = scale_config(
            scale, seed, use_reconstruction=False, use_mahalanobis=False, progress=False, device=device
        )
        return DeepIsolationForest(DeepIFConfig.for_scale(seed, scale), net)

    register(
        "deep-if",
        make,
        cls=DeepIsolationForest,
        family="deep",
        modality="audio+imu",
        description="Deep Isolation Forest: isolation forests on random M-SVDD network representations",
        paper=(PaperRow("Table I", 4, "DeepForest"),),
        config="DeepIFConfig; random MSVDDConfig(use_reconstruction=False, use_mahalanobis=False) networks",
    )
