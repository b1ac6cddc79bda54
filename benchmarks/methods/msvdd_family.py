"""M-SVDD and its ablations (paper, Tables II-IV) in the registry, and the frame-density detector that carries
M-SVDD's network beside it.

Each entry is `msvdd.model.MSVDD` with `MSVDDConfig.smoke()`, `.short()` or `.full()` and its overrides:

- `msvdd`: the paper's model, score D + w (mean_D / mean_Rec) Rec with D the latent Mahalanobis distance and
  Rec the mean Huber error of its own decoders, with the repairs that keep it the paper's model (`REPAIRS`:
  mu and Sigma held fixed between estimates over the whole training split, Sigma's spectrum floored, a
  bias-free encoder and fusion) and the dev-set front end (`DEV_CHOICE`).
- Its ablations (Tables II and III, the latent-s figure): one switch each on top of `msvdd`'s configuration:
  audio only, IMU only, without reconstruction (no decoders: D alone), Euclidean (Deep SVDD with the same
  network and schedule), the fusion variants and the latent dimension s.
- `msvdd-paper`: the paper's configuration and loss as written (MCD on each batch with the covariance
  regulariser, raw waveform, IMU z-velocity, w = 0.01).
- `frame-density-msvdd`: not the paper's model. Densities of the normalised input frames (a mixture density
  network per modality, the IMU's given the audio frames too; `msvdd.context_net`) with w = 100 beside the
  latent distance of a network trained with the paper's loss, which is a small share of its score
  (`msvdd-bench diagnose` measures it). In version 0.1.0 it was the method named `msvdd`
  (its saved models load under the new name, `check_saved`); its no-network twin is `frame-density`
  (`benchmarks.methods.frames`).

Two budget rules keep every variant trainable:

- With the paper's per-batch MCD the support of a training batch must be a true subset that can hold a
  full-rank covariance, so the batch grows with s: batch_size = max(scale's batch, 2 s) (s = 32 with batch
  64 is the paper's support fraction; s = 64 trains with batches of 128); at the smoke budget max(batch,
  s + 8) keeps tests small. `svdd_fit="frozen"` estimates over the whole training split and keeps the
  scale's batch for every s.
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
from msvdd.contract import Detector, ModelFormatError
from msvdd.model import MSVDD

DEV_CHOICE: dict[str, Any] = {
    "audio_frontend": "logmel",
    "imu_input": "all",
}
"""The front end `msvdd`, its ablations and `frame-density-msvdd` use instead of the paper's, chosen on the
`paper` preset's dev dataset (seed 1; docs/detectors.md): log-mel spectrograms and all IMU axes."""

REPAIRS: dict[str, Any] = {
    "svdd_fit": "frozen",
    "bias_free": True,
    "w": 0.1,
    "pooling": "stats",
}
"""What `msvdd` and its ablations change in the paper's model so that the latent distance can learn and see a
wheel defect (`msvdd.model`): mu and Sigma by MCD over the whole training split's embeddings after a warm-up
epoch and every `stats_every` epochs, held fixed in between, Sigma's spectrum floored; bias-free encoders and
fusion; statistics pooling of the tokens (mean, std and max side by side). w and the pooling were chosen on
the `paper` preset's dev dataset (docs/detectors.md): w = 0.1, the largest weight of the decoders' error
that cost nothing against D alone there (a paired interval holding 0 for collisions and faults); statistics
pooling traded a little on collisions for more on faults at the same overall AUC."""


FRAME_DENSITY: dict[str, Any] = {
    "frame_density": True,
    "w": 100.0,
}
"""`frame-density-msvdd`: the frame-density term in place of Rec with w = 100 (from a weight sweep on the
dev dataset), beside the paper's per-batch training."""

PAPER: dict[str, Any] = {k: getattr(MSVDDConfig(), k) for k in (*DEV_CHOICE, *REPAIRS)}
"""The same fields at `MSVDDConfig`'s defaults (the paper's): waveform, z-velocity, per-batch MCD, biases,
w = 0.01."""


@dataclass(frozen=True)
class Variant:
    """One registry entry of the family: its configuration on top of `DEV_CHOICE` and how it is described."""

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
        REPAIRS,
        "M-SVDD: cross-attention audio-IMU fusion; score = latent Mahalanobis distance D + w x the decoders' "
        "reconstruction error; mu and Sigma by MCD over the training set, held fixed between estimates",
        _FULL_MODEL,
    ),
    "msvdd-paper": Variant(
        PAPER,
        "M-SVDD as the paper trains it: MCD on each batch with the covariance regulariser, raw-waveform "
        "CRNN, IMU z-velocity, mean reconstruction error, weight 0.01",
        (PaperRow("Table I", 10, "M-SVDD (the paper's configuration)"),),
    ),
    "msvdd-imu-only": Variant(
        {**REPAIRS, "use_audio": False},
        "M-SVDD ablation: IMU only",
        (PaperRow("Table II", 1, "w/o audio"),),
    ),
    "msvdd-audio-only": Variant(
        {**REPAIRS, "use_imu": False},
        "M-SVDD ablation: audio only",
        (PaperRow("Table II", 2, "w/o IMU"),),
    ),
    "msvdd-no-rec": Variant(
        {**REPAIRS, "use_reconstruction": False},
        "M-SVDD ablation: without the reconstruction branch (no decoders; the score is D alone)",
        (PaperRow("Table II", 3, "w/o reconstruction"),),
    ),
    "msvdd-euclidean": Variant(
        {**REPAIRS, "use_mahalanobis": False},
        "M-SVDD ablation: Euclidean Deep SVDD (fixed centre, identity covariance) with the same network and "
        "reconstruction",
        (PaperRow("Table II", 4, "w/o M-SVDD (Euclidean)"),),
    ),
    "msvdd-fusion-concat": Variant(
        {**REPAIRS, "fusion": "concat"},
        "M-SVDD fusion ablation: concatenation",
        (PaperRow("Table III", 1, "Concatenate"),),
    ),
    "msvdd-fusion-sum": Variant(
        {**REPAIRS, "fusion": "sum"},
        "M-SVDD fusion ablation: element-wise sum",
        (PaperRow("Table III", 2, "Element-wise sum"),),
    ),
    "msvdd-fusion-product": Variant(
        {**REPAIRS, "fusion": "product"},
        "M-SVDD fusion ablation: element-wise product",
        (PaperRow("Table III", 3, "Element-wise product"),),
    ),
    **{
        f"msvdd-s{s}": Variant(
            {**REPAIRS, "s": s},
            f"M-SVDD latent dimension s = {s}",
            (PaperRow("latent-s figure", position, f"s = {s}"),),
        )
        for s, position in ((2, 1), (4, 2), (8, 3), (16, 4), (64, 6))
    },
    "frame-density-msvdd": Variant(
        FRAME_DENSITY,
        "reference: frame densities of the normalised log-mel and IMU input frames (a mixture density "
        "network per modality, the IMU's given the audio; largest frame distance) at w = 100, plus the "
        "latent distance of an M-SVDD network trained with the paper's per-batch loss (a small share of the "
        "score)",
        (),
    ),
}
"""Registry name -> its `Variant`; "msvdd" is s = 32."""

FAMILY: dict[str, str] = {"frame-density-msvdd": "reference"}
"""Entries registered outside the `msvdd` family (the others are in it)."""

LABELS: dict[str, str] = {
    "frame-density-msvdd": "frame densities + M-SVDD distance (`frame-density-msvdd`)",
}
"""Row labels of the entries outside the paper's tables."""

RENAMED: dict[str, str] = {"msvdd": "frame-density-msvdd"}
"""Saved models (model format 3 or older) of a method renamed since: old name -> the name their
configuration now has. The other entries of the family changed what they are; their older models are
refused (`check_saved`)."""


def config_line(name: str) -> str:
    """Entry `name`'s `MSVDDConfig` fields beyond the scale's budget, e.g. `frame_density=True, w=100.0`."""
    overrides = {**DEV_CHOICE, **ABLATIONS[name].overrides}
    return "MSVDDConfig(" + ", ".join(f"{k}={v!r}" for k, v in overrides.items()) + ")"


def msvdd_config(name: str, seed: int, scale: str, device: str = "cpu") -> MSVDDConfig:
    """The MSVDDConfig of registry entry `name` at `scale` on `device`."""
    overrides = {**DEV_CHOICE, **ABLATIONS[name].overrides}
    base = scale_config(scale, seed)
    s = int(overrides.get("s", base.s))
    extra: dict[str, Any] = {}
    if overrides.get("use_mahalanobis", True) and overrides.get("svdd_fit", base.svdd_fit) == "batch":
        extra["batch_size"] = max(base.batch_size, s + 8 if scale == "smoke" else 2 * s)
    if scale == "smoke":
        extra["val_fraction"] = 0.0
    return scale_config(scale, seed, **overrides, **extra, device=device)


def _factory(name: str) -> Any:
    def make(seed: int, scale: str, device: str) -> MSVDD:
        return MSVDD(msvdd_config(name, seed, scale, device))

    return make


def check_saved(name: str, detector: Detector) -> str:
    """The name a saved model of method `name` loads under: `name`, or its new name (`RENAMED`) for a model
    saved before the family's names changed (model format 3 or older).

    Raises:
        ModelFormatError: an older model of an entry that changed what it is (its configuration is not the
            entry's any more): the message says what to do.
    """
    loaded = getattr(detector, "loaded_format_", None)
    if name not in ABLATIONS or not isinstance(detector, MSVDD) or loaded is None or loaded >= 4:
        return name
    if name == "msvdd-paper":
        return name
    if name in RENAMED and detector.config.frame_density:
        return RENAMED[name]
    raise ModelFormatError(
        f"this {name!r} model was saved (model format {loaded}) when {name!r} scored the frame-density term "
        f"or trained with the paper's per-batch loss; {name!r} is now the repaired M-SVDD. Train it again "
        "(`msvdd-bench train`); the old `msvdd` is `frame-density-msvdd`"
    )


def register_methods() -> None:
    """Register "msvdd", every ablation and `frame-density-msvdd`."""
    from benchmarks.methods.registry import register, register_load_check

    register_load_check(check_saved)
    for name, variant in ABLATIONS.items():
        modality = "audio" if variant.overrides.get("use_imu") is False else "audio+imu"
        modality = "imu" if variant.overrides.get("use_audio") is False else modality
        register(
            name,
            _factory(name),
            cls=MSVDD,
            family=FAMILY.get(name, "msvdd"),
            modality=modality,
            description=variant.description,
            label=LABELS.get(name, ""),
            paper=variant.paper,
            config=config_line(name),
        )
