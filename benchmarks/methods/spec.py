"""What a method is: its one descriptor (`MethodSpec`), read by the registry, `msvdd-bench methods`, the
report and the docs generator, and the vocabularies its fields take (families, modalities, paper tables).

`benchmarks.methods.registry` (methods by name) and `benchmarks.methods.external` (`module:Class` detectors)
both build `MethodSpec`s; neither imports the other's module to do so.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from msvdd.contract import Detector

FAMILIES: tuple[str, ...] = ("msvdd", "deep", "shallow", "reference", "naive", "external")
"""Method families: M-SVDD and its ablations, deep baselines, shallow baselines, the reference detectors
(window statistics and densities of the inputs that a learned representation has to beat; one of them,
`frame-density-msvdd`, adds an M-SVDD network's latent distance to its frame densities), naive sanity
baselines, and detectors from outside the project (`module:Class`, `benchmarks.methods.external`; never in
the registry itself)."""

MODALITIES: tuple[str, ...] = ("audio+imu", "audio", "imu", "audio+imu+odometry")
"""Which sensors a method reads (odometry: the wheel encoders)."""

DEVICES: tuple[str, ...] = ("cpu", "cuda", "auto")
"""Torch devices a method may be built for ("auto" = CUDA when available)."""

PAPER_TABLES: tuple[str, ...] = ("Table I", "Table II", "Table III", "latent-s figure")
"""The paper's tables (and its latent-dimension figure) that a run's `results.md` reproduces."""

Factory = Callable[[int, str, str], Detector]
"""factory(seed, scale, device) -> an unfitted detector; CPU-only methods ignore the device."""


@dataclass(frozen=True)
class PaperRow:
    """Where a method appears in one of the report's tables shaped like the paper's."""

    table: str
    """One of `PAPER_TABLES`."""
    position: int
    """Its row in that table, from the top (rows of equal position keep the registration order)."""
    label: str
    """The row's label, e.g. `IF (early fusion)`, `w/o audio`, `s = 2`."""


@dataclass(frozen=True)
class MethodSpec:
    """One method, described once."""

    name: str
    """Registry name, e.g. `msvdd`, `iforest-early`; `module:Class` for a detector from outside."""
    factory: Factory
    """factory(seed, scale, device) -> an unfitted detector."""
    family: str
    """One of `FAMILIES`."""
    modality: str
    """One of `MODALITIES`."""
    description: str
    """One line for tables and `--help`: what it reads and what its score is."""
    cls: type[Detector]
    """The class of the detectors `factory` builds; its `load` reads saved models."""
    label: str = ""
    """Its row label in the report's tables outside the paper's (reference, naive); empty: the name."""
    paper: tuple[PaperRow, ...] = ()
    """Its rows in the report's tables shaped like the paper's (empty: in none)."""
    config: str = ""
    """Its configuration in one line: what it sets beyond the training scale's budget (empty: nothing)."""

    def row_label(self) -> str:
        """`label`, or the name when it has none."""
        return self.label or self.name

    def paper_rows(self) -> list[str]:
        """Where it appears in the paper's tables, e.g. `["Table I: IF (early fusion)"]`."""
        return [f"{row.table}: {row.label}" for row in self.paper]


def check_spec(spec: MethodSpec) -> MethodSpec:
    """`spec` if its family, modality and paper rows take allowed values; ValueError naming the field else."""
    if spec.family not in FAMILIES:
        raise ValueError(f"family {spec.family!r} is unknown; allowed: {', '.join(FAMILIES)}")
    if spec.modality not in MODALITIES:
        raise ValueError(f"modality {spec.modality!r} is unknown; allowed: {', '.join(MODALITIES)}")
    for row in spec.paper:
        if row.table not in PAPER_TABLES:
            raise ValueError(f"paper table {row.table!r} is unknown; allowed: {', '.join(PAPER_TABLES)}")
    return spec
