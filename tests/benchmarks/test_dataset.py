"""Dataset generation: layout, determinism, corruption detection, atomicity."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

import benchmarks.dataset as ds
import synth_audio
from benchmarks.episode import EPISODE_AUDIO_BITS, EPISODE_FILES, read_episode, read_events
from benchmarks.manifest import READABLE_DATASET_FORMATS, Manifest
from msvdd.contract import AUDIO_LEN, IMU_LEN
from sim.trace import Trace
from synth_audio.io import quantise


def test_layout_manifest_and_windows(tiny_dataset: Path) -> None:
    dataset = ds.open_dataset(tiny_dataset)
    manifest = dataset.manifest
    assert manifest.format_version == ds.DATASET_FORMAT_VERSION
    assert manifest.preset.name == "tiny"
    for episode in manifest.episodes:
        folder = tiny_dataset / episode.episode_id
        assert sorted(p.name for p in folder.iterdir()) == sorted(EPISODE_FILES)
        assert set(episode.files) == set(EPISODE_FILES)
    kinds = {(r.split, r.kind) for r in dataset.windows}
    assert ("train", "normal") in kinds and ("val", "normal") in kinds
    assert {("test", "normal"), ("test", "collision"), ("test", "mechanical")} <= kinds
    assert all(r.kind == "normal" for r in dataset.windows if r.split != "test")
    assert not list(tiny_dataset.parent.glob(".tiny.partial-*"))


def test_windows_have_the_papers_shapes(tiny_dataset: Path) -> None:
    windows, rows = ds.open_dataset(tiny_dataset).load_windows("test")
    assert windows.audio.shape == (len(rows), AUDIO_LEN, 2)
    assert windows.imu.shape == (len(rows), IMU_LEN)
    # A window's IMU is the episode's IMU at that time, sample for sample.
    row = rows[-1]
    episode = read_episode(tiny_dataset / row.episode)
    i0 = round(row.start_s * 200)
    np.testing.assert_array_equal(windows.imu[-1], episode.imu_vel_z[i0 : i0 + IMU_LEN])


def test_collision_windows_hold_the_contact(tiny_dataset: Path) -> None:
    dataset = ds.open_dataset(tiny_dataset)
    for row in (r for r in dataset.windows if r.kind == "collision"):
        events = read_events(tiny_dataset / row.episode)
        times = [c.time for c in events.contacts if c.obstacle_kind == row.sub_kind]
        assert any(row.start_s - 0.5 <= t <= row.start_s + 2.0 for t in times), (row, times)


def test_same_seed_same_checksums(tiny_dataset: Path, tmp_path: Path) -> None:
    # the session's dataset was built in one process; this one by two worker processes
    again = ds.generate("tiny", 0, tmp_path / "again", workers=2, progress=False)
    first = ds.open_dataset(tiny_dataset, verify=False).manifest
    second = ds.open_dataset(again).manifest
    assert first.episodes == second.episodes
    assert first.windows == second.windows
    assert ds.dataset_fingerprint(first) == ds.dataset_fingerprint(second)


def test_checksum_mismatch_is_named(tiny_dataset: Path, tmp_path: Path) -> None:
    copy = Path(shutil.copytree(tiny_dataset, tmp_path / "copy"))
    episode = ds.open_dataset(copy).windows[0].episode
    target = copy / episode / "imu.npz"
    data = bytearray(target.read_bytes())
    data[-10] ^= 0xFF
    target.write_bytes(bytes(data))
    with pytest.raises(ds.DatasetError, match=rf"checksum mismatch: .*{episode}/imu\.npz"):
        ds.open_dataset(copy)


def test_missing_file_and_other_version_are_named(tiny_dataset: Path, tmp_path: Path) -> None:
    copy = Path(shutil.copytree(tiny_dataset, tmp_path / "copy"))
    episode = ds.open_dataset(copy).windows[0].episode
    (copy / episode / "audio.flac").unlink()
    with pytest.raises(ds.DatasetError, match=r"missing dataset file: .*audio\.flac"):
        ds.open_dataset(copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["format_version"] = 99
    (copy / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(ds.DatasetError, match="format_version 99"):
        ds.open_dataset(copy)


def test_a_dataset_of_an_earlier_format_is_refused_naming_both_versions(
    tiny_dataset: Path, tmp_path: Path
) -> None:
    # Format 3 held the fault kind `imbalance` where `out_of_round` now is: its labels would be misread.
    assert ds.DATASET_FORMAT_VERSION == 12 and READABLE_DATASET_FORMATS == (4, 5, 6, 7, 8, 9, 10, 11, 12)
    copy = tmp_path / "old"
    copy.mkdir()
    manifest = json.loads((tiny_dataset / "manifest.json").read_text())
    manifest["format_version"] = 3
    (copy / "manifest.json").write_text(json.dumps(manifest))
    readable = r"format_version 3, this software reads format_version 4, 5, 6, 7, 8, 9, 10, 11 or 12"
    with pytest.raises(ds.DatasetError, match=readable):
        ds.open_dataset(copy, verify=False)


def test_snr_of_every_episode_is_recorded_from_the_presets_range(tiny_dataset: Path) -> None:
    manifest = ds.open_dataset(tiny_dataset, verify=False).manifest
    low, high = manifest.preset.snr_db
    assert all(low <= e.spec.snr_db <= high for e in manifest.episodes)
    assert ds.open_dataset(tiny_dataset, verify=False).preset.snr_db == (low, high)


def test_interrupted_generation_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = {"n": 0}
    real = ds.build_episode

    def failing(spec: ds.EpisodeSpec, directory: Path) -> Path:
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(spec, directory)

    monkeypatch.setattr(ds, "build_episode", failing)
    with pytest.raises(KeyboardInterrupt):
        ds.generate("tiny", 1, tmp_path / "data", workers=1, progress=False)
    assert list(tmp_path.iterdir()) == []


def test_existing_folder_is_refused(tmp_path: Path) -> None:
    (tmp_path / "data").mkdir()
    with pytest.raises(FileExistsError, match="dataset folder exists already"):
        ds.generate("tiny", 0, tmp_path / "data", workers=1, progress=False)


def test_a_dev_dataset_must_be_another_seed_of_the_same_preset(tiny_dataset: Path, tmp_path: Path) -> None:
    from benchmarks.dataset import DatasetError, check_dev, open_dataset

    evaluated = open_dataset(tiny_dataset, verify=False)

    def copy(seed: int, preset: str) -> Path:
        folder = tmp_path / f"{preset}-{seed}"
        folder.mkdir()
        manifest = json.loads((tiny_dataset / "manifest.json").read_text())
        manifest["seed"], manifest["preset"]["name"] = seed, preset
        (folder / "manifest.json").write_text(json.dumps(manifest))
        shutil.copy(tiny_dataset / "windows.csv", folder / "windows.csv")
        return folder

    seed = evaluated.seed
    text = check_dev(open_dataset(copy(seed + 1, "tiny"), verify=False), evaluated)
    assert f"seed {seed + 1}" in text
    with pytest.raises(DatasetError, match=f"seed {seed} is the evaluated dataset's seed"):
        check_dev(open_dataset(copy(seed, "tiny"), verify=False), evaluated)
    with pytest.raises(DatasetError, match=r"preset 'quick'.*'tiny'"):
        check_dev(open_dataset(copy(seed + 2, "quick"), verify=False), evaluated)


def test_stored_audio_is_the_dithered_render_of_the_stored_trace(tiny_dataset: Path) -> None:
    """Rendering an episode again from its trace.npz (as the audit does) gives its audio.flac back: the file
    holds exactly the 16-bit TPDF quantisation of that render, dithered from the episode's seed, so it lies
    within 1.5 steps (2^-15 of full scale) of it."""
    dataset = ds.open_dataset(tiny_dataset, verify=False)
    spec = next(s for s in dataset.episode_specs().values() if s.category == "collision")
    folder = tiny_dataset / spec.episode_id
    assert sf.info(str(folder / "audio.flac")).subtype == "PCM_16"
    assert json.loads((folder / "meta.json").read_text())["audio_bits"] == EPISODE_AUDIO_BITS == 16
    render = synth_audio.render(
        Trace.load(folder / "trace.npz"), ds.episode_audio_config(spec), seed=spec.seed
    )
    stored = read_episode(folder).audio
    step = 2.0**-15
    np.testing.assert_array_equal(stored, (quantise(render.samples, 16, spec.seed) * step).astype(np.float32))
    assert np.abs(stored.astype(np.float64) - render.samples).max() <= 1.5 * step


@pytest.mark.parametrize(("old", "new"), [("tiny", "smoke"), ("quick", "short"), ("paper", "full")])
def test_a_manifest_with_the_former_budget_names_reads_as_the_budgets(
    tiny_dataset: Path, old: str, new: str
) -> None:
    doc = json.loads((tiny_dataset / "manifest.json").read_text())
    doc["preset"]["method_scale"] = old
    manifest = Manifest.from_dict(doc)
    assert manifest.preset.method_scale == new
    data = ds.open_dataset(tiny_dataset, verify=False)
    assert ds.Dataset(data.path, manifest, data.windows).preset.method_scale == new


def test_fault_severities_are_the_scenarios_fault_severities(tiny_dataset: Path) -> None:
    """Independent reader: the full episode (`read_episode`) holds the scenario the severities come from."""
    data = ds.open_dataset(tiny_dataset)
    found = data.fault_severities()
    faulty = {e for e, c in data.categories().items() if c == "fault"}
    assert found and set(found) == faulty
    for episode, value in found.items():
        faults = read_episode(tiny_dataset / episode).scenario["faults"]
        assert value == max(float(f["severity"]) for f in faults) and 0.0 <= value <= 1.0


def test_fault_severity_names_the_file_it_cannot_read(tmp_path: Path) -> None:
    from benchmarks.episode import EpisodeError, fault_severity

    with pytest.raises(EpisodeError, match=r"meta\.json"):
        fault_severity(tmp_path)
    (tmp_path / "meta.json").write_text(json.dumps({"scenario": {"faults": [{"kind": "bearing"}]}}))
    with pytest.raises(EpisodeError, match=r"meta\.json: a fault of the scenario has no numeric severity"):
        fault_severity(tmp_path)
    (tmp_path / "meta.json").write_text(json.dumps({"scenario": {"faults": []}}))
    assert fault_severity(tmp_path) is None
