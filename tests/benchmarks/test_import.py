"""`msvdd-bench import`: the three layouts on small synthesised sources, the datasets they give read back
through the real train / evaluate / audit / viz code, and bad input named in one clear error."""

from __future__ import annotations

import csv
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from rerun.chunk import RrdReader

from benchmarks.cli import main
from benchmarks.dataset import Dataset, open_dataset
from benchmarks.episode import AnomalySpan, EpisodeError, read_episode, read_events
from benchmarks.errors import OutputExistsError
from benchmarks.importers import (
    FolderConfig,
    ImportConfig,
    SourceError,
    SplitConfig,
    WindowsConfig,
    import_dataset,
    parse_imu_columns,
)
from benchmarks.importers.writer import Planned, Recording, assign_splits
from benchmarks.manifest import Manifest
from benchmarks.modalities import MissingModalityError
from benchmarks.pipeline import score_and_measure, train_method
from msvdd.contract import AUDIO_LEN, IMU_LEN

HUM_HZ, FAULT_HZ = 120.0, 1200.0
"""Machine hum and the fault's added tone (below the 2 kHz anti-alias cut-off of the windows)."""
IMU_COLUMNS = "t=time_ms,ax=acc_x,ay=acc_y,az=acc_z,gx=gyr_x,gy=gyr_y,gz=gyr_z"
TINY = ImportConfig(scale="smoke")


def _machine(rng: np.random.Generator, seconds: float, rate: int, abnormal: bool) -> np.ndarray:
    """A hum with harmonics, a level and pitch that vary per clip, noise; abnormal clips add a clear tone."""
    t = np.arange(round(seconds * rate)) / rate
    f0, level = HUM_HZ * rng.uniform(0.97, 1.03), rng.uniform(0.12, 0.2)
    x = sum(level / k * np.sin(2 * np.pi * k * f0 * t + rng.uniform(0, 6.3)) for k in (1, 2, 3))
    x = x + 0.02 * rng.standard_normal(t.size)
    if abnormal:
        x = x + 0.06 * np.sin(2 * np.pi * FAULT_HZ * rng.uniform(0.98, 1.02) * t)
    return np.asarray(x, dtype=np.float32)


# ---------------------------------------------------------------------------------------------- sources


@pytest.fixture(scope="module")
def mimii_source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """MIMII layout: fan/id_00 (8 normal, 3 abnormal) and fan/id_02 (4 normal, 2 abnormal), 16 kHz mono."""
    root = tmp_path_factory.mktemp("src") / "mimii"
    rng = np.random.default_rng(1)
    for ident, counts in (("id_00", (8, 3)), ("id_02", (4, 2))):
        for label, n in zip(("normal", "abnormal"), counts, strict=True):
            folder = root / "-6_dB_fan" / "fan" / ident / label
            folder.mkdir(parents=True)
            for i in range(n):
                sf.write(folder / f"{i:08d}.wav", _machine(rng, 4.0, 16000, label == "abnormal"), 16000)
    (root / "-6_dB_fan" / "fan" / "id_00" / "normal" / "._00000000.wav").write_bytes(b"macOS metadata")
    return root


@pytest.fixture(scope="module")
def mimii(mimii_source: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    config = ImportConfig(scale="smoke", train_hop_s=0.5)  # 40 training windows: M-SVDD's batch is 32
    return import_dataset(
        "mimii", mimii_source, tmp_path_factory.mktemp("ds") / "mimii", config, progress=False
    )


def _imu_csv(path: Path, seconds: float, rate: float = 400.0, drop: tuple[str, ...] = ()) -> None:
    """IMU at `rate` with time in ms: acc_x = sin(2 pi 3 t), acc_z = 9.81 + sin(2 pi 2 t), gyro small."""
    t = np.arange(round(seconds * rate)) / rate
    columns = {
        "time_ms": 1000.0 * t,
        "acc_x": np.sin(2 * np.pi * 3.0 * t),
        "acc_y": 0.1 * np.cos(2 * np.pi * 1.0 * t),
        "acc_z": 9.81 + np.sin(2 * np.pi * 2.0 * t),
        "gyr_x": 0.01 * t,
        "gyr_y": np.zeros_like(t),
        "gyr_z": 0.2 * np.sin(2 * np.pi * 0.5 * t),
    }
    names = [c for c in columns if c not in drop]
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(names)
        for i in range(t.size):
            writer.writerow([f"{columns[c][i]:.9g}" for c in names])


@pytest.fixture(scope="module")
def folder_source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Folder layout: four 6 s recordings (48 kHz stereo WAV, one 22.05 kHz mono FLAC in a subfolder), IMU
    CSVs at 400 Hz in ms, and labels: a wall collision in rec_b, a bearing fault in day2/rec_c."""
    root = tmp_path_factory.mktemp("src") / "folder"
    (root / "day2").mkdir(parents=True)
    rng = np.random.default_rng(2)
    t = np.arange(6 * 48000) / 48000
    for name in ("rec_a", "rec_b", "rec_d"):
        left = 0.3 * np.sin(2 * np.pi * 440.0 * t)
        right = _machine(rng, 6.0, 48000, False)
        sf.write(root / f"{name}.wav", np.stack([left, right], axis=1).astype(np.float32), 48000)
        _imu_csv(root / f"{name}.csv", 6.0)
    sf.write(root / "day2" / "rec_c.flac", _machine(rng, 6.0, 22050, True), 22050)
    _imu_csv(root / "day2" / "rec_c.csv", 6.0)
    (root / "labels.csv").write_text(
        "recording,start_s,end_s,kind,sub_kind\nrec_b,2.2,2.6,collision,wall\nday2/rec_c,2.0,6.0,,bearing\n"
    )
    return root


@pytest.fixture(scope="module")
def folder(folder_source: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    config = ImportConfig(scale="smoke", split=SplitConfig(test_fraction=0.5, val_fraction=0.0))
    layout = FolderConfig(
        imu_columns=parse_imu_columns(IMU_COLUMNS), time_unit="ms", labels=str(folder_source / "labels.csv")
    )
    out = tmp_path_factory.mktemp("ds") / "folder"
    return import_dataset("folder", folder_source, out, config, layout, progress=False)


def _sine_windows(n: int, hz: float, rng: np.random.Generator) -> np.ndarray:
    t = np.arange(AUDIO_LEN) / 4410.0
    return np.stack([0.4 * np.sin(2 * np.pi * hz * t + rng.uniform(0, 6.3)) for _ in range(n)]).astype(
        np.float32
    )


@pytest.fixture(scope="module")
def windows_source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Windows layout: normal_train.npz (6 mono windows), normal_test as .npy files (3 stereo windows),
    abnormal.npz (4 windows in two sequences, with kind and sub_kind)."""
    root = tmp_path_factory.mktemp("src") / "windows"
    root.mkdir()
    rng = np.random.default_rng(3)
    imu = rng.standard_normal((13, IMU_LEN)).cumsum(axis=1).astype(np.float32) * 0.01
    np.savez(root / "normal_train.npz", audio=_sine_windows(6, 300.0, rng), imu=imu[:6])
    stereo = np.stack([_sine_windows(3, 300.0, rng), _sine_windows(3, 500.0, rng)], axis=-1)
    np.save(root / "normal_test_audio.npy", stereo)
    np.save(root / "normal_test_imu.npy", imu[6:9])
    fault = _sine_windows(4, 300.0, rng) + _sine_windows(4, FAULT_HZ, rng) / 4
    np.savez(
        root / "abnormal.npz",
        audio=fault,
        imu=imu[9:],
        sequence=np.array([7, 7, 9, 9]),
        kind=np.array(["collision", "collision", "mechanical", "mechanical"]),
        sub_kind=np.array(["door", "door", "bearing", "bearing"]),
    )
    return root


@pytest.fixture(scope="module")
def windows(windows_source: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ds") / "windows"
    return import_dataset("windows", windows_source, out, TINY, WindowsConfig(), progress=False)


# ----------------------------------------------------------------------------------------------- mimii


def test_mimii_dataset_is_audio_only_split_per_machine_and_has_no_trace(mimii: Path) -> None:
    data = open_dataset(mimii)  # every sha256 verified
    manifest = data.manifest
    assert manifest.source == "import" and manifest.modalities == ("audio",)
    assert manifest.imported is not None and manifest.imported.layout == "mimii"
    assert manifest.imported.facts["units"] == {"0": "fan/id_00", "1": "fan/id_02"}
    assert data.preset.name == "import-mimii" and data.preset.method_scale == "smoke"
    recordings = {e.recording: e for e in manifest.episodes}
    assert len(recordings) == 17  # the hidden ._ file is not a clip
    split_of = {str(name).split("/", 2)[2]: e.spec.split for name, e in recordings.items()}
    # id_00: 8 normal -> last 2 (25 %) test, then 1 of the other 6 (10 %, rounded) val; id_02: 1 test, 0 val.
    assert [split_of[f"id_00/normal/{i:08d}"] for i in range(8)] == ["train"] * 5 + ["val"] + ["test"] * 2
    assert [split_of[f"id_02/normal/{i:08d}"] for i in range(4)] == ["train"] * 3 + ["test"]
    assert all(
        split_of[f"{i}/abnormal/{j:08d}"] == "test" for i, n in (("id_00", 3), ("id_02", 2)) for j in range(n)
    )
    rows = data.windows
    assert {(r.split, r.kind, r.sub_kind) for r in rows if r.kind != "normal"} == {
        ("test", "mechanical", "fan")
    }
    assert sum(r.split == "train" for r in rows) == 8 * 5  # 4 s clips, 0.5 s hop: starts 0, 0.5, ..., 2
    assert sum(r.split == "test" and r.kind == "mechanical" for r in rows) == 5 * 2  # 2 s hop: starts 0, 2
    first = data.path / manifest.episodes[0].episode_id
    assert sorted(p.name for p in first.iterdir()) == ["audio.flac", "events.json", "imu.npz", "meta.json"]
    episode = read_episode(first)
    assert episode.source == "import" and episode.modalities == ("audio",)
    assert episode.audio_rate == 44100 and episode.audio.shape == (4 * 44100, 2)
    assert not np.any(episode.imu_vel_z) and episode.imu_vel_z.shape == (4 * 200,)
    with pytest.raises(EpisodeError, match="no simulator trace"):
        episode.trace()


def test_audio_only_methods_detect_mimii_anomalies_through_the_cli(mimii: Path, tmp_path: Path) -> None:
    model = tmp_path / "gaussian-audio"
    assert main(["train", "--data", str(mimii), "--method", "gaussian-audio", "--out", str(model),
                 "--no-progress"]) == 0  # fmt: skip
    run = tmp_path / "eval"
    assert (
        main(["evaluate", "--data", str(mimii), "--model", str(model), "--out", str(run), "--no-progress"])
        == 0
    )
    results = json.loads((run / "results.json").read_text())
    assert results["preset"] == "import-mimii"
    auc = results["methods"]["gaussian-audio"]["auc"]
    assert auc > 0.9, auc
    assert (run / "scores.csv").is_file()


@pytest.mark.filterwarnings("ignore:the val set has:UserWarning")  # 5 val windows: M-SVDD skips its MCD check
def test_audio_only_msvdd_scores_mimii_anomalies_above_normals(mimii: Path, tmp_path: Path) -> None:
    data = open_dataset(mimii, verify=False)
    model = train_method(data, "msvdd-audio-only", 0, "smoke", tmp_path / "m")
    scores, per_method, _ = score_and_measure(data, [model], progress=False)
    s = scores[0].scores
    assert np.all(np.isfinite(s)) and np.ptp(s) > 0
    metrics = per_method["msvdd-audio-only"][0]
    assert metrics.auc > 0.9, metrics.auc
    assert metrics.n_events == 5  # one labelled onset per abnormal clip, from events.json


def test_imu_methods_are_refused_on_an_audio_only_dataset(
    mimii: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        ["train", "--data", str(mimii), "--method", "msvdd", "--out", str(tmp_path / "m"), "--no-progress"]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err
    assert str(mimii) in err and "no imu modality" in err and "'msvdd' reads audio+imu" in err
    assert "gaussian-audio" in err  # what can run instead
    assert not (tmp_path / "m").exists()
    with pytest.raises(MissingModalityError, match="no imu modality"):
        train_method(open_dataset(mimii, verify=False), "imu-kurtosis", 0, "smoke", tmp_path / "k")


def test_dcase_flat_layout(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    files = {
        "ToyCar/train": [f"normal_id_01_{i:08d}" for i in range(3)],
        "ToyCar/test": ["normal_id_01_00000000", "anomaly_id_01_00000000", "anomaly_id_01_00000001"],
        "valve/train": [
            "section_00_source_train_normal_0000_pat_00",
            "section_00_source_train_normal_0001_pat_01",
        ],
        "valve/source_test": ["section_00_source_test_anomaly_0000_pat_00"],
    }
    for folder_name, names in files.items():
        (tmp_path / "dev" / folder_name).mkdir(parents=True)
        for name in names:
            wav = tmp_path / "dev" / folder_name / f"{name}.wav"
            sf.write(wav, _machine(rng, 2.5, 16000, "anomaly" in name), 16000)
    out = import_dataset("mimii", tmp_path / "dev", tmp_path / "ds", TINY, progress=False)
    data = open_dataset(out)
    assert data.manifest.imported is not None
    assert data.manifest.imported.facts["units"] == {"0": "ToyCar/id_01", "1": "valve/section_00"}
    by_name = {e.recording: (e.spec.split, e.spec.category, e.spec.unit_id) for e in data.manifest.episodes}
    assert by_name["ToyCar/train/normal_id_01_00000002"] == ("train", "nominal", 0)
    assert by_name["ToyCar/test/normal_id_01_00000000"] == ("test", "nominal", 0)
    assert by_name["ToyCar/test/anomaly_id_01_00000001"] == ("test", "fault", 0)
    assert by_name["valve/source_test/section_00_source_test_anomaly_0000_pat_00"] == ("test", "fault", 1)
    assert {r.sub_kind for r in data.windows if r.kind != "normal"} == {"ToyCar", "valve"}
    (tmp_path / "dev" / "valve" / "source_test" / "section_00_0007.wav").write_bytes(
        (tmp_path / "dev" / "ToyCar" / "train" / "normal_id_01_00000000.wav").read_bytes()
    )
    with pytest.raises(SourceError, match=r"section_00_0007\.wav: file name has no normal/anomaly token"):
        import_dataset("mimii", tmp_path / "dev", tmp_path / "ds2", TINY, progress=False)


def test_two_imports_of_different_recordings_are_a_dev_eval_pair(mimii: Path, tmp_path: Path) -> None:
    """Imports have no seed: a dev import must share no recording with the evaluated one (by checksum)."""
    from benchmarks.dataset import DatasetError, check_dev

    evaluated = open_dataset(mimii, verify=False)
    assert "recordings disjoint" in check_dev(_reimported_with_other_audio(mimii, tmp_path), evaluated)
    with pytest.raises(DatasetError, match=r"of its recordings are also in the evaluated dataset"):
        check_dev(open_dataset(mimii, verify=False), evaluated)


def _reimported_with_other_audio(mimii: Path, tmp_path: Path) -> Dataset:
    """The MIMII fixture's dataset with every audio checksum changed (as if recorded again)."""
    data = open_dataset(mimii, verify=False)
    episodes = tuple(replace(e, files={**e.files, "audio.flac": f"{i:064d}"})
                     for i, e in enumerate(data.manifest.episodes))  # fmt: skip
    return Dataset(data.path, replace(data.manifest, episodes=episodes), data.windows)


# ---------------------------------------------------------------------------------------------- folder


def test_folder_import_resamples_audio_and_imu_and_labels_windows(folder: Path) -> None:
    data = open_dataset(folder)
    assert data.manifest.modalities == ("audio", "imu")
    by_name = {e.recording: e.spec for e in data.manifest.episodes}
    assert {n: (e.split, e.category) for n, e in by_name.items()} == {
        "rec_a": ("train", "nominal"),  # two nominal recordings, test fraction 0.5: the last one is test
        "rec_b": ("test", "collision"),
        "day2/rec_c": ("test", "fault"),
        "rec_d": ("test", "nominal"),
    }
    labels = {(r.episode, r.start_s): (r.kind, r.sub_kind) for r in data.windows}
    b, c = by_name["rec_b"].episode_id, by_name["day2/rec_c"].episode_id
    assert [labels[(b, s)] for s in (0.0, 2.0, 4.0)] == [
        ("normal", "none"),
        ("collision", "wall"),
        ("normal", "none"),
    ]
    fault = ("mechanical", "bearing")
    assert [labels[(c, s)] for s in (0.0, 2.0, 4.0)] == [("normal", "none"), fault, fault]
    episode = read_episode(data.path / by_name["rec_a"].episode_id)
    assert episode.modalities == ("audio", "imu")
    # 48 kHz -> 44.1 kHz: the left channel is still the 440 Hz sine (away from the filter's edges).
    n = episode.audio.shape[0]
    assert abs(n - 6 * 44100) <= 1
    t = np.arange(n) / 44100
    middle = slice(4410, n - 4410)
    assert np.max(np.abs(episode.audio[middle, 0] - 0.3 * np.sin(2 * np.pi * 440.0 * t[middle]))) < 2e-3
    # 400 Hz IMU -> 200 Hz: acc_x is the 3 Hz sine on the new grid; z velocity estimated from acc_z.
    ti = episode.imu_time
    assert np.allclose(np.diff(ti), 1 / 200) and abs(ti.size - 6 * 200) <= 1
    assert np.max(np.abs(episode.imu6[:, 0] - np.sin(2 * np.pi * 3.0 * ti))) < 0.01
    assert np.max(np.abs(episode.imu6[:, 2] - 9.81 - np.sin(2 * np.pi * 2.0 * ti))) < 0.01
    inner = (ti > 1.5) & (ti < 4.5)
    expected_vz = -np.cos(2 * np.pi * 2.0 * ti) / (2 * np.pi * 2.0)
    assert np.max(np.abs(episode.imu_vel_z[inner] - expected_vz[inner])) < 0.05 * np.max(np.abs(expected_vz))
    meta = json.loads((data.path / by_name["rec_a"].episode_id / "meta.json").read_text())
    assert meta["recording"]["audio_rate"] == 48000 and meta["recording"]["vel_z_estimated_from_az"] is True
    mono = read_episode(data.path / c)
    assert np.array_equal(mono.audio[:, 0], mono.audio[:, 1])  # mono FLAC duplicated into both channels
    assert read_events(data.path / c).anomalies == (AnomalySpan(2.0, 6.0, "mechanical", "bearing"),)
    events = json.loads((data.path / c / "events.json").read_text())
    assert events["anomalies"] == [{"onset": 2.0, "end": 6.0, "kind": "mechanical", "sub_kind": "bearing"}]


def test_folder_import_through_the_cli_with_a_split_file(folder_source: Path, tmp_path: Path) -> None:
    splits = tmp_path / "splits.csv"
    splits.write_text("recording,split\nrec_d,val\n")
    out = tmp_path / "ds"
    labels = str(folder_source / "labels.csv")
    assert main(["import", str(folder_source), "--layout", "folder", "--out", str(out), "--labels", labels,
                 "--imu-columns", IMU_COLUMNS, "--time-unit", "ms", "--split-file", str(splits),
                 "--imu-rate", "400", "--scale", "smoke", "--no-progress"]) == 0  # fmt: skip
    split_of = {e.recording: e.spec.split for e in open_dataset(out).manifest.episodes}
    assert split_of == {"rec_a": "train", "rec_b": "test", "day2/rec_c": "test", "rec_d": "val"}


def test_audit_skips_simulator_probes_with_a_reason_and_runs_the_rest(folder: Path, mimii: Path) -> None:
    from benchmarks.audit import SKIP, markdown, run_audit

    result = run_audit(folder, progress=False)
    skipped = {r.group for r in result.rows if r.status == SKIP}
    assert skipped == {"behaviour", "context", "deleted", "level", "ambience", "oracle"}
    assert all("no simulator trace" in r.skipped for r in result.rows if r.status == SKIP)
    ran = {(r.group, r.probe) for r in result.rows if r.status != SKIP}
    assert {("naive", "rms"), ("naive", "acc_peak"), ("reference", "gaussian-early")} <= ran
    assert "6 probe(s) skipped" in markdown(result) and result.preset == "import-folder"
    audio_only = run_audit(mimii, progress=False)
    assert {r.probe for r in audio_only.rows if r.status == SKIP} == {"every probe", "acc_peak"}
    assert any(r.probe == "gaussian-audio" and r.target == "overall" for r in audio_only.rows)


def _entities(path: Path) -> set[str]:
    return {line.split()[0] for line in RrdReader(path).store().summary().splitlines()}


def test_viz_shows_what_an_imported_episode_has(folder: Path, mimii: Path, tmp_path: Path) -> None:
    from benchmarks.viz import log_episode

    data = open_dataset(mimii, verify=False)
    episode = next(r.episode for r in data.windows if r.kind != "normal")
    model = train_method(data, "gaussian-audio", 0, "smoke", tmp_path / "model").path
    rrd = log_episode(mimii, episode, model_dir=model, save=tmp_path / "mimii.rrd")
    assert rrd is not None
    seen = _entities(rrd)
    assert {"/signals/audio/left", "/truth/label", "/detector/score", "/events"} <= seen
    assert not any(e.startswith(("/signals/imu", "/world", "/signals/wheels")) for e in seen)
    collision = next(e.episode_id for e in open_dataset(folder, verify=False).manifest.episodes
                     if e.spec.category == "collision")  # fmt: skip
    seen = _entities(log_episode(folder, collision, save=tmp_path / "folder.rrd"))  # type: ignore[arg-type]
    assert {"/signals/imu/vel_z", "/signals/imu/acc", "/events"} <= seen
    imu_model = train_method(
        open_dataset(folder, verify=False), "gaussian-early", 0, "smoke", tmp_path / "e"
    ).path
    with pytest.raises(MissingModalityError, match="no imu modality"):
        log_episode(mimii, episode, model_dir=imu_model, save=tmp_path / "refused.rrd")
    assert not (tmp_path / "refused.rrd").exists()


# --------------------------------------------------------------------------------------------- windows


def test_windows_import_gives_the_windows_back(windows: Path, windows_source: Path) -> None:
    data = open_dataset(windows)
    assert data.manifest.modalities == ("audio", "imu")
    episodes = data.manifest.episodes
    assert sum(e.spec.split in ("train", "val") for e in episodes) == 6  # one episode per window
    assert sum(e.spec.split == "val" for e in episodes) == 1
    abnormal = [e for e in episodes if e.spec.category != "nominal"]
    assert sorted(str(e.recording) for e in abnormal) == ["abnormal/sequence-7", "abnormal/sequence-9"]
    test, rows = data.load_windows("test")
    assert [(r.kind, r.sub_kind) for r in rows if r.kind != "normal"] == [("collision", "door")] * 2 + [
        ("mechanical", "bearing")
    ] * 2
    normal = [i for i, r in enumerate(rows) if r.kind == "normal"]
    original_audio = np.load(windows_source / "normal_test_audio.npy")
    original_imu = np.load(windows_source / "normal_test_imu.npy")
    np.testing.assert_array_equal(test.imu[normal], original_imu)  # 200 Hz windows stored as they are
    inner = slice(100, AUDIO_LEN - 100)  # the round trip 4410 -> 44100 -> 4410 Hz, away from the edges
    assert np.max(np.abs(test.audio[normal][:, inner] - original_audio[:, inner])) < 5e-3
    with np.load(windows_source / "abnormal.npz") as z:
        np.testing.assert_array_equal(test.imu[[i for i in range(len(rows)) if i not in normal]], z["imu"])


def test_audio_only_windows_and_other_rates(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    t = np.arange(2 * 16000) / 16000
    audio = np.stack([0.3 * np.sin(2 * np.pi * 700 * t + rng.uniform(0, 6)) for _ in range(3)]).astype(
        np.float32
    )
    for group in ("normal_train", "normal_test", "abnormal"):
        np.savez(tmp_path / f"{group}.npz", audio=audio)
    out = import_dataset("windows", tmp_path, tmp_path.parent / "w-ds", TINY, WindowsConfig(audio_rate=16000))
    data = open_dataset(out)
    assert data.manifest.modalities == ("audio",)
    train, _ = data.load_windows("train")
    assert train.audio.shape[1:] == (AUDIO_LEN, 2) and not np.any(train.imu)
    amplitude = np.abs(np.fft.rfft(train.audio[0, :, 0] * np.hanning(AUDIO_LEN)))
    assert abs(np.fft.rfftfreq(AUDIO_LEN, 1 / 4410)[np.argmax(amplitude)] - 700) < 1  # pitch kept


@pytest.mark.parametrize("layout", ["mimii", "folder", "windows"])
def test_an_imported_manifest_round_trips_byte_for_byte(
    layout: str, request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    dataset: Path = request.getfixturevalue(layout)
    text = (dataset / "manifest.json").read_text()
    manifest = Manifest.load(dataset)
    assert manifest.source == "import" and manifest.imported is not None
    assert manifest.imported.layout == layout and manifest.imported.options
    assert manifest.to_dict() == json.loads(text)
    assert manifest.save(tmp_path).read_text() == text
    for episode_id in open_dataset(dataset, verify=False).episode_ids:
        events = read_events(dataset / episode_id)
        assert events.contacts == events.transients == events.faults == () and events.anomalies is not None
        assert events.to_dict() == json.loads((dataset / episode_id / "events.json").read_text())


# ----------------------------------------------------------------------------------------- bad input


def _folder_with(tmp_path: Path, seconds_audio: float = 4.0, seconds_imu: float = 4.0, drop=()) -> Path:
    src = tmp_path / "src"
    src.mkdir()
    rng = np.random.default_rng(6)
    for name in ("a", "b"):
        sf.write(src / f"{name}.wav", _machine(rng, seconds_audio, 16000, False), 16000)
        _imu_csv(src / f"{name}.csv", seconds_imu if name == "b" else seconds_audio, drop=drop)
    return src


def _folder_import(src: Path, out: Path, **layout: object) -> Path:
    config = FolderConfig(imu_columns=parse_imu_columns(IMU_COLUMNS), time_unit="ms", **layout)  # type: ignore[arg-type]
    return import_dataset("folder", src, out, TINY, config, progress=False)


def test_missing_column_is_named_with_the_file_and_the_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = _folder_with(tmp_path, drop=("acc_z",))
    with pytest.raises(
        SourceError, match=r"a\.csv: no column 'acc_z' for IMU field az; .*--imu-columns az=COLUMN"
    ):
        _folder_import(src, tmp_path / "out")
    code = main(["import", str(src), "--layout", "folder", "--out", str(tmp_path / "out"), "--imu-columns",
                 IMU_COLUMNS, "--time-unit", "ms", "--no-progress"])  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "acc_z" in err and "a.csv" in err
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob(".out*"))  # nothing half written


def test_unequal_lengths_are_refused_and_nothing_is_left(tmp_path: Path) -> None:
    src = _folder_with(tmp_path, seconds_audio=4.0, seconds_imu=3.0)
    with pytest.raises(
        SourceError, match=r"b\.wav and .*b\.csv: unequal lengths: audio 4\.000 s, IMU 3\.0\d+ s"
    ):
        _folder_import(src, tmp_path / "out")
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob(".out*"))
    assert _folder_import(src, tmp_path / "out", max_length_mismatch_s=1.5).is_dir()  # within the tolerance
    audio_only = open_dataset(_folder_import(src, tmp_path / "audio-only", no_imu=True))
    assert audio_only.manifest.modalities == ("audio",)


def test_rates_that_do_not_match(tmp_path: Path, mimii_source: Path) -> None:
    src = _folder_with(tmp_path)
    with pytest.raises(
        SourceError,
        match=r"a\.csv: column 'time_ms' \(unit ms\) gives an IMU rate of 400 Hz, but --imu-rate is 100 Hz",
    ):
        _folder_import(src, tmp_path / "out", imu_rate=100.0)
    with pytest.raises(
        SourceError, match=r"00000000\.wav: sample rate 16000 Hz, but --audio-rate is 44100 Hz"
    ):
        import_dataset("mimii", mimii_source, tmp_path / "m", ImportConfig(audio_rate=44100), progress=False)
    win = tmp_path / "win"
    win.mkdir()
    for group in ("normal_train", "normal_test", "abnormal"):
        np.savez(
            win / f"{group}.npz",
            audio=np.zeros((2, AUDIO_LEN), np.float32),
            imu=np.zeros((2, 400), np.float32),
        )
    with pytest.raises(
        SourceError,
        match=r"normal_train\.npz: audio windows of 8820 samples at --audio-rate 8000 Hz .* allowed: rates",
    ):
        import_dataset("windows", win, tmp_path / "w", TINY, WindowsConfig(audio_rate=8000.0), progress=False)
    np.savez(
        win / "normal_test.npz",
        audio=np.zeros((3, AUDIO_LEN), np.float32),
        imu=np.zeros((2, 400), np.float32),
    )
    with pytest.raises(
        SourceError, match=r"normal_test\.npz: unequal lengths: audio has 3 windows, imu has 2"
    ):
        import_dataset("windows", win, tmp_path / "w", TINY, progress=False)


def test_unreadable_files_are_named(tmp_path: Path) -> None:
    src = tmp_path / "mimii" / "pump" / "id_04"
    (src / "normal").mkdir(parents=True)
    (src / "normal" / "00000000.wav").write_bytes(b"RIFF not really a wave file")
    with pytest.raises(SourceError, match=r"00000000\.wav: not a readable audio file"):
        import_dataset("mimii", tmp_path / "mimii", tmp_path / "out", TINY, progress=False)
    win = tmp_path / "win"
    win.mkdir()
    (win / "normal_train.npz").write_bytes(b"not a zip")
    with pytest.raises(SourceError, match=r"group normal_train: not a readable NumPy file"):
        import_dataset("windows", win, tmp_path / "out", TINY, progress=False)
    (tmp_path / "loose").mkdir()
    sf.write(tmp_path / "loose" / "x.wav", np.zeros(100), 8000)
    with pytest.raises(SourceError, match=r"x\.wav: not in a MIMII folder .* nor a DCASE folder"):
        import_dataset("mimii", tmp_path / "loose", tmp_path / "out", TINY, progress=False)


def test_bad_labels_and_channels(tmp_path: Path) -> None:
    src = _folder_with(tmp_path)
    labels = tmp_path / "labels.csv"
    labels.write_text("recording,start_s,end_s,kind\nc,0,1,collision\n")
    with pytest.raises(SourceError, match=r"labels\.csv, line 2, column 'recording': 'c' is not a recording"):
        _folder_import(src, tmp_path / "out", labels=str(labels))
    labels.write_text("recording,start_s,end_s,kind\na,0,1,explosion\n")
    with pytest.raises(
        SourceError, match=r"line 2, column 'kind': 'explosion'; allowed: collision, mechanical"
    ):
        _folder_import(src, tmp_path / "out", labels=str(labels))
    labels.write_text("recording,start,end\na,0,1\n")
    with pytest.raises(SourceError, match=r"labels\.csv: no column 'start_s'"):
        _folder_import(src, tmp_path / "out", labels=str(labels))
    sf.write(src / "a.wav", np.zeros((64000, 8), np.float32), 16000)
    with pytest.raises(SourceError, match=r"a\.wav: 8 audio channels; pass --channels"):
        _folder_import(src, tmp_path / "out")


def test_existing_output_needs_replace_and_only_a_dataset_is_replaced(
    mimii_source: Path, tmp_path: Path
) -> None:
    out = import_dataset("mimii", mimii_source, tmp_path / "ds", TINY, progress=False)
    before = open_dataset(out).fingerprint
    with pytest.raises(OutputExistsError, match="pass --replace"):
        import_dataset("mimii", mimii_source, out, TINY, progress=False)
    config = ImportConfig(scale="smoke", split=SplitConfig(test_fraction=0.5, val_fraction=0.0))
    import_dataset("mimii", mimii_source, out, config, replace=True, progress=False)
    assert open_dataset(out).fingerprint != before and not list(tmp_path.glob(".ds*"))
    other = tmp_path / "notes"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    with pytest.raises(OutputExistsError, match="not a dataset folder"):
        import_dataset("mimii", mimii_source, other, TINY, replace=True, progress=False)
    assert (other / "keep.txt").read_text() == "mine"


def test_split_rule(tmp_path: Path) -> None:
    def planned(name: str, group: str, pool: str = "auto", anomalous: bool = False) -> Planned:
        return Planned(name, group, pool, anomalous, 0, lambda: Recording(np.zeros((1, 2)), None, None))

    plans = [planned(f"g1/{i:02d}", "g1") for i in range(10)] + [planned(f"g2/{i}", "g2") for i in range(3)]
    plans += [planned("g1/x", "g1", anomalous=True), planned("g2/fixed", "g2", pool="test")]
    config = ImportConfig(split=SplitConfig(test_fraction=0.3, val_fraction=0.25))
    splits = dict(zip([p.name for p in plans], assign_splits(plans, config), strict=True))
    g1 = [splits[f"g1/{i:02d}"] for i in range(10)]
    assert g1 == ["train"] * 5 + ["val"] * 2 + ["test"] * 3  # 3 of 10 test, round(0.25 x 7) = 2 val
    assert [splits[f"g2/{i}"] for i in range(3)] == ["train", "val", "test"]  # round(0.9), round(0.5): 1, 1
    assert splits["g1/x"] == "test" and splits["g2/fixed"] == "test"
    with pytest.raises(SourceError, match="labelled anomaly but its split is 'train'"):
        assign_splits([planned("a", "", pool="train", anomalous=True)], config)
    with pytest.raises(SourceError, match="no nominal training recording"):
        assign_splits([planned("a", "", anomalous=True)], config)
    assert math.isclose(SplitConfig().test_fraction, 0.25)
