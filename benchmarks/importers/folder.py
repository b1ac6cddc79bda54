"""The folder layout: audio files, an IMU CSV beside each, an optional label CSV of anomaly spans.

    SOURCE/
      run01.wav        audio (WAV or FLAC, mono or stereo, any rate); subfolders allowed
      run01.csv        its IMU: a time column and six axes (names set with --imu-columns)
      ...
    labels.csv         recording,start_s,end_s[,kind][,sub_kind]   (--labels; anywhere)
    splits.csv         recording,split                             (--split-file; optional)

A recording is named by its audio file's path under SOURCE without the suffix (`run01`, `day2/run07`). The
label CSV's `kind` is `collision` or `mechanical` (empty or absent: `--anomaly-kind`); `sub_kind` is a free
name such as `bearing` or `wall` (default `unspecified`). A recording with a span is test data; the others
follow the split file, then the split rule (`benchmarks.importers.writer`).
"""

from __future__ import annotations

import csv
import functools
import re
from collections.abc import Iterable
from pathlib import Path

from benchmarks.importers.config import ANOMALY_KINDS, FolderConfig, ImportConfig, SourceError
from benchmarks.importers.signals import OUT_AUDIO_RATE, read_audio, read_imu_csv
from benchmarks.importers.writer import RESERVED_SUB_KINDS, UNSPECIFIED, Planned, Recording, Span

AUDIO_SUFFIXES: tuple[str, ...] = (".wav", ".flac")
"""Audio files the folder and MIMII layouts read (case-insensitive)."""
LABEL_COLUMNS: tuple[str, ...] = ("recording", "start_s", "end_s")
"""Required columns of the label CSV (optional: `kind`, `sub_kind`)."""
SPLIT_COLUMNS: tuple[str, ...] = ("recording", "split")
"""Columns of the split file."""
SPLITS: tuple[str, ...] = ("train", "val", "test")
"""Splits a split file may name."""
_TOKEN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]*")


def audio_files(source: Path) -> list[Path]:
    """Every WAV or FLAC file under `source`, sorted, hidden files and folders left out."""
    if not source.is_dir():
        raise SourceError(f"source folder not found: {source}")
    found = [
        p
        for p in source.rglob("*")
        if p.suffix.lower() in AUDIO_SUFFIXES
        and p.is_file()
        and not any(part.startswith(".") for part in p.relative_to(source).parts)
    ]
    if not found:
        raise SourceError(f"{source}: no audio files ({', '.join(AUDIO_SUFFIXES)}) found in it or below")
    return sorted(found)


def check_sub_kind(name: str, where: str) -> str:
    """`name` if it is a usable sub-kind (a token, not a kind); else a SourceError naming `where`."""
    if not _TOKEN.fullmatch(name) or name in RESERVED_SUB_KINDS:
        raise SourceError(
            f"{where}: sub_kind {name!r} is invalid; allowed: letters, digits and _ . + - (not "
            f"{', '.join(RESERVED_SUB_KINDS)})"
        )
    return name


def _read_csv(path: Path, required: Iterable[str], what: str) -> list[tuple[int, dict[str, str]]]:
    """(line number, row) of a CSV with a header that has every `required` column."""
    if not path.is_file():
        raise SourceError(f"{what} not found: {path}")
    try:
        with open(path, newline="", encoding="utf-8-sig") as handle:
            reader = csv.DictReader(handle)
            header = [h.strip() for h in reader.fieldnames or []]
            missing = [c for c in required if c not in header]
            if missing:
                raise SourceError(
                    f"{path}: no column {missing[0]!r}; its columns are {', '.join(header) or '(none)'}; "
                    f"allowed: a header with {', '.join(required)}"
                )
            return [
                (reader.line_num, {k.strip(): (v or "").strip() for k, v in row.items() if k is not None})
                for row in reader
                if any((v or "").strip() for v in row.values() if isinstance(v, str))
            ]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise SourceError(f"{path}: not a readable CSV file ({exc})") from exc


def read_labels(path: Path, names: set[str], default_kind: str) -> dict[str, list[Span]]:
    """Spans by recording name from a label CSV; every value checked (the message names line and column)."""
    spans: dict[str, list[Span]] = {}
    for line, row in _read_csv(path, LABEL_COLUMNS, "label CSV"):
        where = f"{path}, line {line}"
        name = row["recording"]
        if name not in names:
            known = ", ".join(sorted(names)[:5])
            raise SourceError(
                f"{where}, column 'recording': {name!r} is not a recording of the source; allowed: a "
                f"recording's file path under the source without suffix, e.g. {known}"
            )
        bounds = []
        for column in ("start_s", "end_s"):
            try:
                bounds.append(float(row[column]))
            except ValueError:
                raise SourceError(
                    f"{where}, column {column!r}: value {row[column]!r} is not a number"
                ) from None
        start, end = bounds
        if not (0.0 <= start < end):
            raise SourceError(f"{where}: start_s {start:g}, end_s {end:g}; allowed: 0 <= start_s < end_s")
        kind = row.get("kind") or default_kind
        if kind not in ANOMALY_KINDS:
            raise SourceError(f"{where}, column 'kind': {kind!r}; allowed: {', '.join(ANOMALY_KINDS)}")
        sub_kind = check_sub_kind(row.get("sub_kind") or UNSPECIFIED, where)
        spans.setdefault(name, []).append(Span(start, end, kind, sub_kind))
    return spans


def read_split_file(path: Path, names: set[str]) -> dict[str, str]:
    """Split by recording name from a CSV (recording, split)."""
    out: dict[str, str] = {}
    for line, row in _read_csv(path, SPLIT_COLUMNS, "split file"):
        where = f"{path}, line {line}"
        if row["recording"] not in names:
            raise SourceError(
                f"{where}, column 'recording': {row['recording']!r} is not a recording of the source"
            )
        if row["split"] not in SPLITS:
            raise SourceError(f"{where}, column 'split': {row['split']!r}; allowed: {', '.join(SPLITS)}")
        out[row["recording"]] = row["split"]
    return out


def _load(
    audio_path: Path,
    imu_path: Path | None,
    spans: tuple[Span, ...],
    config: ImportConfig,
    folder: FolderConfig,
) -> Recording:
    audio, info = read_audio(audio_path, config)
    provenance: dict[str, object] = {
        "audio_file": str(audio_path),
        "audio_rate": info.rate,
        "audio_channels": info.channels,
    }
    if imu_path is None:
        return Recording(audio, None, None, spans, provenance=provenance)
    imu = read_imu_csv(imu_path, folder)
    audio_s = audio.shape[0] / OUT_AUDIO_RATE
    if abs(audio_s - imu.duration_s) > folder.max_length_mismatch_s:
        raise SourceError(
            f"{audio_path} and {imu_path}: unequal lengths: audio {audio_s:.3f} s, IMU "
            f"{imu.duration_s:.3f} s; allowed: a difference of at most --max-length-mismatch "
            f"{folder.max_length_mismatch_s:g} s"
        )
    provenance |= {
        "imu_file": str(imu_path),
        "imu_rate": round(imu.source_rate, 6),
        "vel_z_estimated_from_az": imu.vel_z_estimated,
    }
    return Recording(audio, imu.vel_z, imu.imu6, spans, provenance=provenance)


def plan(source: Path, config: ImportConfig, folder: FolderConfig) -> tuple[list[Planned], dict[str, object]]:
    """The recordings of a folder-layout source, and its facts for the manifest.

    Raises:
        SourceError: no audio, a missing IMU CSV, two audio files of one name, a bad label or split file.
    """
    files = audio_files(source)
    by_name: dict[str, Path] = {}
    for path in files:
        name = path.relative_to(source).with_suffix("").as_posix()
        if name in by_name:
            raise SourceError(f"{by_name[name]} and {path}: two audio files for recording {name!r}")
        by_name[name] = path
    names = set(by_name)
    spans = read_labels(Path(folder.labels), names, config.anomaly_kind) if folder.labels else {}
    fixed = read_split_file(Path(folder.split_file), names) if folder.split_file else {}
    plans: list[Planned] = []
    for name, audio_path in sorted(by_name.items()):
        imu_path: Path | None = None
        if not folder.no_imu:
            imu_path = audio_path.with_suffix(".csv")
            if not imu_path.is_file():
                raise SourceError(
                    f"{audio_path}: no IMU file {imu_path.name} beside it; allowed: every recording "
                    "NAME.wav or NAME.flac has NAME.csv (or pass --no-imu to import audio only)"
                )
        rec_spans = tuple(spans.get(name, ()))
        plans.append(
            Planned(
                name=name,
                group="",
                pool=fixed.get(name, "auto"),
                anomalous=bool(rec_spans),
                unit_id=0,
                load=functools.partial(_load, audio_path, imu_path, rec_spans, config, folder),
            )
        )
    return plans, {"labels": folder.labels, "split_file": folder.split_file, "imu": not folder.no_imu}
