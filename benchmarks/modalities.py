"""Which sensors a dataset carries and which a method reads; a method that needs a missing one is refused.

A generated dataset carries audio, IMU and wheel odometry (the encoders). A dataset imported from
recordings (`msvdd-bench import`) may carry audio only (the MIMII / DCASE layouts): its `manifest.json`
lists `modalities`, its episodes hold all-zero IMU placeholders (the window contract needs the arrays), and
every method whose registry modality reads the IMU (`audio+imu`, `imu`) or the encoders is refused on it
with `MissingModalityError` rather than fitted on zeros.
"""

from __future__ import annotations

from pathlib import Path

from benchmarks.episode import ALL_MODALITIES
from benchmarks.errors import UserError

METHOD_READS: dict[str, tuple[str, ...]] = {
    "audio+imu": ("audio", "imu"),
    "audio": ("audio",),
    "imu": ("imu",),
    "audio+imu+odometry": ("audio", "imu", "odometry"),
}
"""Sensors each registry modality (`benchmarks.methods.registry.MODALITIES`) reads."""


class MissingModalityError(UserError):
    """A method reads a sensor the dataset does not carry; the message names both."""


def require_modalities(dataset: Path, have: tuple[str, ...], method: str) -> None:
    """Refuse method `method` on a dataset (or episode) carrying only the sensors `have` when it reads
    another (one line naming both; `Dataset.modalities`, `Episode.modalities`).

    Raises:
        MissingModalityError: the dataset lacks a sensor the method's registry modality reads.
        UserError: the method is unknown.
    """
    from benchmarks import methods

    modality = methods.spec(method).modality
    missing = [m for m in METHOD_READS.get(modality, ALL_MODALITIES) if m not in have]
    if missing:
        readers = [n for n in methods.names() if set(METHOD_READS[methods.spec(n).modality]) <= set(have)]
        raise MissingModalityError(
            f"dataset {dataset} has no {' and no '.join(missing)} modality (it carries "
            f"{', '.join(have) or 'nothing'}); method {method!r} reads {modality}; methods that can run on "
            f"it: {', '.join(readers) or 'none'}"
        )
