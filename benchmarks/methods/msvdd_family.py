"""M-SVDD and its ablations (paper, Tables II-IV) in the registry.

Each entry is `msvdd.model.MSVDD` with `MSVDDConfig.smoke()`, `.short()` or `.full()`, the dev-set choices
`DEV_CHOICE` and one switch: the paper's configuration, audio only, IMU only, without reconstruction,
Euclidean (without M-SVDD), the fusion variants and the latent dimension s. `msvdd`'s reconstruction term
scores the normalised input frames under learned densities, the IMU's given the audio around it too
(`rec_score="fused"`, `msvdd.context_net`). Two budget rules keep every variant trainable:

- The MCD support of a training batch must be a true subset that can hold a full-rank covariance, so the
  batch grows with s: batch_size = max(scale's batch, 2 s) (s = 32 with batch 64 is the paper's support
  fraction; s = 64 trains with batches of 128). At the smoke budget, max(batch, s + 8) keeps tests small.
- At the smoke budget no validation split is held out (val_fraction = 0): the validation MCD needs more than s
  validation windows, more than a seconds-long test has.

The registry builds `msvdd.model.MSVDD` itself (no wrapper): its threshold follows the one rule of
`msvdd.contract.Detector`, like every other method's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from benchmarks.methods.deep_base import scale_config
from benchmarks.methods.spec import PaperRow
from msvdd.config import MSVDDConfig
from msvdd.model import MSVDD

DEV_CHOICE: dict[str, Any] = {
    "audio_frontend": "logmel",
    "imu_input": "all",
    "rec_score": "fused",
    "w": 100.0,
}
"""What `msvdd` and its ablations change from the paper, chosen on the `paper` preset's dev dataset (seed 1;
docs/detectors.md): log-mel spectrograms, all IMU axes, the reconstruction term as the largest distance of
an input frame per modality under a mixture density network of the training frames given the two frames on
each side and, for the IMU frames, the log-mel frames around them (`msvdd.context_net.ContextNet`), and
w = 100 from a weight sweep."""

PAPER: dict[str, Any] = {k: getattr(MSVDDConfig(), k) for k in DEV_CHOICE}
"""The same fields at `MSVDDConfig`'s defaults (the paper's): waveform, z-velocity, mean Rec, w = 0.01."""


@dataclass(frozen=True)
class Variant:
    """One registry entry of the family: its switch on top of `DEV_CHOICE` and how it is described."""

    overrides: dict[str, Any]
    """`MSVDDConfig` fields set on top of `DEV_CHOICE`."""
    description: str
    """One line for tables and `--help`."""
    paper: tuple[PaperRow, ...]
    """Its rows in the report's tables shaped like the paper's."""


_FULL_MODEL: tuple[PaperRow, ...] = (
    PaperRow("Table I", 11, "M-SVDD (ours)"),
    PaperRow("Table II", 5, "full model"),
    PaperRow("Table III", 4, "Cross-attention"),
    PaperRow("latent-s figure", 5, "s = 32"),
)
"""`msvdd`'s rows: the comparison's last, each ablation's full model."""

ABLATIONS: dict[str, Variant] = {
    "msvdd": Variant(
        {},
        "M-SVDD: cross-attention audio-IMU fusion, Mahalanobis SVDD with MCD, reconstruction term scored by "
        "learned densities of the input frames",
        _FULL_MODEL,
    ),
    "msvdd-paper": Variant(
        PAPER,
        "M-SVDD in the paper's configuration: raw-waveform CRNN, IMU z-velocity, mean reconstruction error, "
        "weight 0.01",
        (PaperRow("Table I", 10, "M-SVDD (the paper's configuration)"),),
    ),
    "msvdd-imu-only": Variant(
        {"use_audio": False}, "M-SVDD ablation: IMU only", (PaperRow("Table II", 1, "w/o audio"),)
    ),
    "msvdd-audio-only": Variant(
        {"use_imu": False}, "M-SVDD ablation: audio only", (PaperRow("Table II", 2, "w/o IMU"),)
    ),
    "msvdd-no-rec": Variant(
        {"use_reconstruction": False},
        "M-SVDD ablation: without the reconstruction branch",
        (PaperRow("Table II", 3, "w/o reconstruction"),),
    ),
    "msvdd-euclidean": Variant(
        {"use_mahalanobis": False},
        "M-SVDD ablation: without M-SVDD (Euclidean Deep SVDD)",
        (PaperRow("Table II", 4, "w/o M-SVDD (Euclidean)"),),
    ),
    "msvdd-fusion-concat": Variant(
        {"fusion": "concat"},
        "M-SVDD fusion ablation: concatenation",
        (PaperRow("Table III", 1, "Concatenate"),),
    ),
    "msvdd-fusion-sum": Variant(
        {"fusion": "sum"},
        "M-SVDD fusion ablation: element-wise sum",
        (PaperRow("Table III", 2, "Element-wise sum"),),
    ),
    "msvdd-fusion-product": Variant(
        {"fusion": "product"},
        "M-SVDD fusion ablation: element-wise product",
        (PaperRow("Table III", 3, "Element-wise product"),),
    ),
    **{
        f"msvdd-s{s}": Variant(
            {"s": s},
            f"M-SVDD latent dimension s = {s}",
            (PaperRow("latent-s figure", position, f"s = {s}"),),
        )
        for s, position in ((2, 1), (4, 2), (8, 3), (16, 4), (64, 6))
    },
}
"""Registry name -> its `Variant`; "msvdd" is s = 32."""


def config_line(name: str) -> str:
    """Entry `name`'s `MSVDDConfig` fields beyond the scale's budget, e.g. `rec_score=fused, w=100.0`."""
    overrides = {**DEV_CHOICE, **ABLATIONS[name].overrides}
    return "MSVDDConfig(" + ", ".join(f"{k}={v!r}" for k, v in overrides.items()) + ")"


def msvdd_config(name: str, seed: int, scale: str, device: str = "cpu") -> MSVDDConfig:
    """The MSVDDConfig of registry entry `name` at `scale` on `device`."""
    overrides = {**DEV_CHOICE, **ABLATIONS[name].overrides}
    base = scale_config(scale, seed)
    s = int(overrides.get("s", base.s))
    extra: dict[str, Any] = {}
    if overrides.get("use_mahalanobis", True):
        extra["batch_size"] = max(base.batch_size, s + 8 if scale == "smoke" else 2 * s)
    if scale == "smoke":
        extra["val_fraction"] = 0.0
    return scale_config(scale, seed, **overrides, **extra, device=device)


def _factory(name: str) -> Any:
    def make(seed: int, scale: str, device: str) -> MSVDD:
        return MSVDD(msvdd_config(name, seed, scale, device))

    return make


def register_methods() -> None:
    """Register "msvdd" and every ablation."""
    from benchmarks.methods.registry import register

    for name, variant in ABLATIONS.items():
        modality = "audio" if variant.overrides.get("use_imu") is False else "audio+imu"
        modality = "imu" if variant.overrides.get("use_audio") is False else modality
        register(
            name,
            _factory(name),
            cls=MSVDD,
            family="msvdd",
            modality=modality,
            description=variant.description,
            paper=variant.paper,
            config=config_line(name),
        )
