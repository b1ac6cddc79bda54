"""The MIMII and DCASE (2020-2023 task 2) layouts: machine sounds, audio only, normal and anomalous clips.

    MIMII:  SOURCE/.../MACHINE/id_XX/normal/*.wav        SOURCE/.../MACHINE/id_XX/abnormal/*.wav
    DCASE:  SOURCE/.../MACHINE/train/*normal*.wav        SOURCE/.../MACHINE/test/*(normal|anomaly)*.wav
            (also `source_test`, `target_test`; the label is the `normal` or `anomaly` token of the file
            name, e.g. `normal_id_00_00000000.wav`, `section_00_source_test_anomaly_0001_*.wav`)

Every clip is one episode. An abnormal or anomaly clip is an anomaly over its whole length, of kind
`--anomaly-kind` (default `mechanical`) and sub-kind its machine type (so reports give an AUC per machine
type). MIMII normal clips are split per machine type and id by the split rule; DCASE `train` clips are
training data (minus `--val-fraction` for validation) and test clips test data. The unit is the index of
the (machine type, id or section) pair in sorted order (the manifest lists them). There is no IMU: the
dataset records audio as its only modality.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

from benchmarks.importers.config import ImportConfig, SourceError
from benchmarks.importers.folder import audio_files, check_sub_kind
from benchmarks.importers.signals import OUT_AUDIO_RATE, read_audio
from benchmarks.importers.writer import Planned, Recording, Span

MIMII_LABEL_FOLDERS: dict[str, bool] = {"normal": False, "abnormal": True}
"""MIMII label folder -> anomalous."""
DCASE_SPLIT_FOLDERS: dict[str, str] = {
    "train": "fit",
    "test": "test",
    "source_test": "test",
    "target_test": "test",
}
"""DCASE split folder -> split pool (`fit`: train, with the validation share held out)."""
DCASE_LABEL_TOKENS: dict[str, bool] = {"normal": False, "anomaly": True, "abnormal": True}
"""File-name token -> anomalous."""
_ID = re.compile(r"id_\d+")


def _dcase_id(tokens: list[str]) -> str:
    """`id_XX` (2020) or `section_XX` (2021-2023) from a DCASE file name's tokens; `id_unknown` if neither."""
    for key in ("id", "section"):
        if key in tokens[:-1]:
            return f"{key}_{tokens[tokens.index(key) + 1]}"
    return "id_unknown"


def _classify(path: Path) -> tuple[str, str, str, bool]:
    """(machine type, id, split pool, anomalous) of one clip, from its folders and name."""
    parent = path.parent
    if parent.name in MIMII_LABEL_FOLDERS and _ID.fullmatch(parent.parent.name):
        anomalous = MIMII_LABEL_FOLDERS[parent.name]
        return parent.parent.parent.name, parent.parent.name, "test" if anomalous else "auto", anomalous
    if parent.name in DCASE_SPLIT_FOLDERS:
        tokens = path.stem.split("_")
        labels = [DCASE_LABEL_TOKENS[t] for t in tokens if t in DCASE_LABEL_TOKENS]
        if len(labels) != 1:
            raise SourceError(
                f"{path}: file name has {'no' if not labels else 'more than one'} normal/anomaly token; "
                "allowed: DCASE names such as normal_id_00_00000000.wav or "
                "section_00_source_test_anomaly_0001.wav (unlabelled evaluation clips cannot be imported)"
            )
        pool = DCASE_SPLIT_FOLDERS[parent.name]
        if labels[0] and pool == "fit":
            raise SourceError(
                f"{path}: an anomaly clip in a train folder; allowed: normal clips only in train"
            )
        return parent.parent.name, _dcase_id(tokens), pool, labels[0]
    raise SourceError(
        f"{path}: not in a MIMII folder (MACHINE/id_XX/normal|abnormal/) nor a DCASE folder "
        f"(MACHINE/{'|'.join(DCASE_SPLIT_FOLDERS)}/); allowed: one of those layouts"
    )


def _load(path: Path, anomalous: bool, kind: str, machine: str, config: ImportConfig) -> Recording:
    audio, info = read_audio(path, config)
    spans = (Span(0.0, audio.shape[0] / OUT_AUDIO_RATE, kind, machine),) if anomalous else ()
    provenance = {"audio_file": str(path), "audio_rate": info.rate, "audio_channels": info.channels}
    return Recording(audio, None, None, spans, provenance=provenance)


def plan(source: Path, config: ImportConfig) -> tuple[list[Planned], dict[str, object]]:
    """The clips of a MIMII or DCASE source, and its facts for the manifest (the units).

    Raises:
        SourceError: no audio, a clip outside both layouts, or a DCASE name without its label.
    """
    found = [(path, *_classify(path)) for path in audio_files(source)]
    pairs = sorted({(machine, ident) for _, machine, ident, _, _ in found})
    units = {pair: i for i, pair in enumerate(pairs)}
    plans = []
    for path, machine, ident, pool, anomalous in found:
        sub_kind = check_sub_kind(machine, str(path.parent))
        plans.append(
            Planned(
                name=path.relative_to(source).with_suffix("").as_posix(),
                group=f"{machine}/{ident}",
                pool=pool,
                anomalous=anomalous,
                unit_id=units[(machine, ident)],
                load=functools.partial(_load, path, anomalous, config.anomaly_kind, sub_kind, config),
            )
        )
    return plans, {"units": {str(i): f"{m}/{ident}" for (m, ident), i in units.items()}}
