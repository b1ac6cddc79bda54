"""`benchmarks.manifest`: the typed `manifest.json` gives back the file byte for byte, names a bad field
with its file, reads the former format, and leaves every dataset's fingerprint as it was; `events.json`
(`benchmarks.episode.EpisodeEvents`) likewise."""

from __future__ import annotations

import hashlib
import json
import math
import re
import shutil
from pathlib import Path
from typing import Any

import pytest

import benchmarks.dataset as ds
from benchmarks.episode import EPISODE_FILES, EpisodeError, EpisodeEvents, read_events
from benchmarks.manifest import (
    MANIFEST_FILE,
    DatasetError,
    EpisodeSpec,
    Manifest,
    ManifestEpisode,
    ManifestWindows,
)
from benchmarks.presets import get_preset
from sim.random_scenarios import ScenarioOptions


def _raw(dataset: Path) -> tuple[str, dict[str, Any]]:
    text = (dataset / MANIFEST_FILE).read_text()
    return text, json.loads(text)


def _fingerprint_of_the_raw_manifest(doc: dict[str, Any]) -> str:
    """`dataset_fingerprint` as it read the manifest when it was a dict (its first form): the oracle."""
    entries = [f"windows.csv {doc['windows']['sha256']}"]
    for episode in doc["episodes"]:
        for name, digest in sorted(episode["files"].items()):
            entries.append(f"{episode['episode_id']}/{name} {digest}")
    return hashlib.sha256("\n".join(sorted(entries)).encode()).hexdigest()


def test_a_generated_manifest_round_trips_byte_for_byte(tiny_dataset: Path, tmp_path: Path) -> None:
    text, doc = _raw(tiny_dataset)
    manifest = Manifest.load(tiny_dataset)
    assert manifest.to_dict() == doc
    assert Manifest.from_dict(manifest.to_dict()) == manifest
    assert manifest.save(tmp_path).read_bytes() == text.encode()
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST_FILE]  # no temporary file left
    assert manifest.source == "simulate" and manifest.imported is None
    assert manifest.preset == get_preset("tiny") and manifest.seed == 0
    assert [e.spec for e in manifest.episodes] == ds.plan_episodes(get_preset("tiny"), 0)


def test_the_fingerprint_is_the_one_the_raw_manifest_gave(tiny_dataset: Path) -> None:
    _, doc = _raw(tiny_dataset)
    data = ds.open_dataset(tiny_dataset, verify=False)
    assert data.fingerprint == ds.dataset_fingerprint(data.manifest) == _fingerprint_of_the_raw_manifest(doc)


def test_the_fingerprint_of_a_fixed_manifest_is_unchanged() -> None:
    """Pinned: the value the dict-based code gave for these checksums (a pure function of them)."""
    options = ScenarioOptions(30.0, "indoor", severity=(0, 0), unit_id=0, transient_density=1)
    episodes = tuple(
        ManifestEpisode(
            EpisodeSpec(name, "nominal", "train", 1, 6.0, options),
            {file: hashlib.sha256(f"{name}/{file}".encode()).hexdigest() for file in EPISODE_FILES},
        )
        for name in ("train-nominal-000", "test-fault-000")
    )
    manifest = Manifest(
        format_version=3,
        preset=get_preset("tiny"),
        seed=0,
        software={},
        dropped_nominal_windows=(),
        episodes=episodes,
        windows=ManifestWindows("windows.csv", hashlib.sha256(b"windows.csv").hexdigest(), 0),
    )
    expected = "350118889476232a931ddf7d204c6e05b2422b514ba00df20e41f3dabb957156"
    assert ds.dataset_fingerprint(manifest) == expected
    assert _fingerprint_of_the_raw_manifest(manifest.to_dict()) == expected


def _load_error(tmp_path: Path, doc: dict[str, Any]) -> str:
    (tmp_path / MANIFEST_FILE).write_text(json.dumps(doc))
    with pytest.raises(DatasetError) as info:
        ds.open_dataset(tmp_path, verify=False)
    return str(info.value)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            lambda d: d["episodes"][1].pop("seed"),
            r"episodes\[1\] \(train-nominal-001\): missing field 'seed'",
        ),
        (lambda d: d["episodes"][0].pop("files"), r"episodes\[0\] \(\S+\): missing field 'files'"),
        (lambda d: d.pop("windows"), r"manifest\.json: missing field 'windows'"),
        (lambda d: d["windows"].pop("sha256"), r"manifest\.json: field 'windows': missing field 'sha256'"),
        (lambda d: d["preset"].pop("name"), r"manifest\.json: preset: missing field 'name'"),
        (
            lambda d: d["preset"].update(snr_db=[0, "12"]),
            r"preset: field 'snr_db'\[1\]: expected a number, got \"12\"",
        ),
        (lambda d: d.update(seed="0"), r"field 'seed': expected an integer, got \"0\""),
        (lambda d: d["episodes"][0].update(wheel=1.5), r"'wheel': expected an integer or null, got 1\.5"),
        (lambda d: d["episodes"][0].pop("duration_s"), r"episodes\[0\] \(\S+\): missing field 'duration_s'"),
        (lambda d: d["episodes"][0].update(unit_id=None), r"field 'unit_id': expected an integer, got null"),
        (
            lambda d: d["episodes"][0].update(robot_model="diff2"),
            r"episodes\[0\] \(\S+\): unknown field 'robot_model'",
        ),
        (lambda d: d["episodes"][0]["files"].update(x=1), r"field 'files'\['x'\]: expected a string, got 1"),
        (lambda d: d.update(modalities=["audio"]), r"'modalities': \['audio'\] in a generated dataset"),
        (lambda d: d.update(extra=1), r"manifest\.json: unknown field 'extra'"),
        (lambda d: d["preset"].update(snr_db=[3, 1]), r"preset: preset 'tiny': snr_db must be a \("),
    ],
)
def test_a_bad_field_is_named_with_the_file(
    tiny_dataset: Path, tmp_path: Path, change: Any, message: str
) -> None:
    _, doc = _raw(tiny_dataset)
    change(doc)
    text = _load_error(tmp_path, doc)
    assert text.startswith(str(tmp_path / MANIFEST_FILE))
    assert re.search(message, text), text


def test_the_format_version_is_checked_before_any_field(tmp_path: Path) -> None:
    assert "format_version 99, this software reads format_version 4" in _load_error(
        tmp_path, {"format_version": 99}
    )
    assert "format_version None" in _load_error(tmp_path, {"seed": 0})
    (tmp_path / MANIFEST_FILE).write_text("{not json")
    with pytest.raises(DatasetError, match=r"manifest\.json: not a JSON document"):
        Manifest.load(tmp_path)


def test_an_imported_episode_has_no_snr_and_names_its_recording() -> None:
    options = ScenarioOptions(4.0, severity=(0, 0), unit_id=1, transient_density=0.0)
    spec = EpisodeSpec("test-fault-0000", "fault", "test", 0, math.nan, options)
    entry = ManifestEpisode(spec, {"audio.flac": "0" * 64}, recording="fan/id_00/abnormal/00000000")
    doc = entry.to_dict()
    assert doc["snr_db"] is None and doc["recording"] == "fan/id_00/abnormal/00000000"
    back = ManifestEpisode.from_dict(json.loads(json.dumps(doc)), "manifest.json: episodes[0]")
    assert math.isnan(back.spec.snr_db) and back.to_dict() == doc


def test_events_round_trip_byte_for_byte_and_name_a_bad_field(tiny_dataset: Path, tmp_path: Path) -> None:
    data = ds.open_dataset(tiny_dataset, verify=False)
    for episode_id in data.episode_ids:
        folder = tiny_dataset / episode_id
        text = (folder / "events.json").read_text()
        events = read_events(folder)
        assert events.to_dict() == json.loads(text) and events.anomalies is None
        out = tmp_path / episode_id
        out.mkdir()
        assert events.save(out).read_text() == text
    collision = next(i for i, c in data.categories().items() if c == "collision")
    assert read_events(tiny_dataset / collision).contacts  # a collision episode has its contact
    shutil.copy(tiny_dataset / collision / "events.json", tmp_path / "events.json")
    doc = json.loads((tmp_path / "events.json").read_text())
    del doc["contacts"][0]["impulse"]
    (tmp_path / "events.json").write_text(json.dumps(doc))
    with pytest.raises(EpisodeError, match=r"events\.json: field 'contacts'\[0\]: missing field 'impulse'"):
        EpisodeEvents.load(tmp_path)
    with pytest.raises(EpisodeError, match=r"missing episode file events\.json"):
        EpisodeEvents.load(tmp_path / "nowhere")
