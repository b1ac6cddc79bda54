"""M-SVDD and its ablations (paper, Tables II-IV) in the registry.

Each entry is `msvdd.model.MSVDD` with `MSVDDConfig.smoke()`, `.short()` or `.full()` and one switch:
audio only, IMU only, without reconstruction, Euclidean (without M-SVDD), the fusion variants, the latent
dimension s, and two earlier `msvdd`s: `msvdd-context`, whose reconstruction term scores each residual frame
given its neighbouring residual frames under fixed mixtures (`rec_score="context"`; 70.4 % AUC on the dev
dataset), and `msvdd-mixture`, which scores each residual frame on its own (`rec_score="mixture"`, 69.2 %).
`msvdd` scores the input frames under learned densities instead, the IMU's given the audio around it too
(`rec_score="fused"`; its term 71.9 % on the dev dataset). Two budget rules keep every variant trainable:

- The MCD support of a training batch must be a true subset that can hold a full-rank covariance, so the
  batch grows with s: batch_size = max(scale's batch, 2 s) (s = 32 with batch 64 is the paper's support
  fraction; s = 64 trains with batches of 128). At the smoke budget, max(batch, s + 8) keeps tests small.
- At the smoke budget no validation split is held out (val_fraction = 0): the validation MCD needs more than s
  validation windows, more than a seconds-long test has.

The registry builds `msvdd.model.MSVDD` itself (no wrapper): its threshold follows the one rule of
`msvdd.contract.Detector`, like every other method's.
"""

from __future__ import annotations

from typing import Any

from benchmarks.methods.deep_base import scale_config
from msvdd.config import MSVDDConfig
from msvdd.model import MSVDD

DEV_CHOICE: dict[str, Any] = {
    "audio_frontend": "logmel",
    "imu_input": "all",
    "rec_score": "fused",
    "w": 100.0,
}
"""What `msvdd` and its ablations change from the paper, chosen on the `paper` preset's dev dataset (seed 1;
README "The detector"): log-mel spectrograms, all IMU axes, the reconstruction term as the largest distance of
an input frame per modality under a mixture density network of the training frames given the two frames on
each side and, for the IMU frames, the log-mel frames around them (`msvdd.context_net.ContextNet`), and
w = 100 from a weight sweep (made with the unconditional mixture of the residual frames, `msvdd-mixture`)."""

PAPER: dict[str, Any] = {k: getattr(MSVDDConfig(), k) for k in DEV_CHOICE}
"""The same fields at `MSVDDConfig`'s defaults (the paper's): waveform, z-velocity, mean Rec, w = 0.01."""

ABLATIONS: dict[str, tuple[dict[str, Any], str]] = {
    "msvdd": ({}, "M-SVDD: cross-attention audio-IMU fusion, Mahalanobis SVDD with MCD, reconstruction"),
    "msvdd-paper": (
        PAPER,
        "M-SVDD in the paper's configuration: raw-waveform CRNN, IMU z-velocity, reconstruction weight 0.01",
    ),
    "msvdd-audio-only": ({"use_imu": False}, "M-SVDD ablation: audio only"),
    "msvdd-imu-only": ({"use_audio": False}, "M-SVDD ablation: IMU only"),
    "msvdd-no-rec": ({"use_reconstruction": False}, "M-SVDD ablation: without the reconstruction branch"),
    "msvdd-context": (
        {"rec_score": "context"},
        "M-SVDD with each residual frame scored given its neighbouring residual frames (fixed mixtures; the "
        "previous msvdd)",
    ),
    "msvdd-mixture": (
        {"rec_score": "mixture"},
        "M-SVDD with each residual frame scored on its own (one frame mixture; the msvdd before "
        "msvdd-context)",
    ),
    "msvdd-euclidean": ({"use_mahalanobis": False}, "M-SVDD ablation: without M-SVDD (Euclidean Deep SVDD)"),
    "msvdd-fusion-concat": ({"fusion": "concat"}, "M-SVDD fusion ablation: concatenation"),
    "msvdd-fusion-sum": ({"fusion": "sum"}, "M-SVDD fusion ablation: element-wise sum"),
    "msvdd-fusion-product": ({"fusion": "product"}, "M-SVDD fusion ablation: element-wise product"),
    **{f"msvdd-s{s}": ({"s": s}, f"M-SVDD latent dimension s = {s}") for s in (2, 4, 8, 16, 64)},
}
"""Registry name -> (MSVDDConfig overrides on top of `DEV_CHOICE`, description); "msvdd" is s = 32."""


def msvdd_config(name: str, seed: int, scale: str, device: str = "cpu") -> MSVDDConfig:
    """The MSVDDConfig of registry entry `name` at `scale` on `device`."""
    overrides = {**DEV_CHOICE, **ABLATIONS[name][0]}
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

    for name, (overrides, text) in ABLATIONS.items():
        modality = "audio" if overrides.get("use_imu") is False else "audio+imu"
        modality = "imu" if overrides.get("use_audio") is False else modality
        register(name, _factory(name), cls=MSVDD, family="msvdd", modality=modality, description=text)
