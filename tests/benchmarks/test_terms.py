"""`msvdd-bench terms`: the frame reference's modality terms sum to its score, each term's AUC is
scikit-learn's on that term, and groups whose answer is known by construction get it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sklearn.metrics import roc_auc_score

from benchmarks import methods, pipeline
from benchmarks.cli import main
from benchmarks.dataset import open_dataset
from benchmarks.errors import UserError
from benchmarks.methods.frames import MODALITY_NAMES, ContextNetFrames
from benchmarks.pipeline import train_method
from benchmarks.terms import FUSION, frame_methods, group_terms, load_references, modality_terms
from msvdd.contract import NotFittedError, WindowError
from msvdd.synthetic import toy_windows


def test_modality_scores_sum_to_the_score() -> None:
    train, _ = toy_windows(40, 0, seed=3)
    test, _ = toy_windows(4, 4, seed=4)
    with pytest.raises(NotFittedError):
        ContextNetFrames().modality_scores(test)
    det = methods.make("context-net-frames", seed=0, scale="smoke").fit(train)
    assert isinstance(det, ContextNetFrames)
    terms = det.modality_scores(test)
    assert terms.shape == (len(test), len(MODALITY_NAMES)) and terms.dtype == np.float64
    np.testing.assert_array_equal(terms.sum(axis=1), det.score(test))
    # each term is over its training mean: 1 on average over the training windows
    np.testing.assert_allclose(det.modality_scores(train).mean(axis=0), 1.0, rtol=1e-6)
    with pytest.raises(WindowError):
        det.modality_scores("not windows")  # type: ignore[arg-type]


def test_frame_methods_are_the_frame_density_reference() -> None:
    assert frame_methods() == ["frame-density", "context-net-frames"]


def test_groups_known_by_construction() -> None:
    # 40 normal windows (8 episodes), 20 collision windows (4 episodes) and 20 mechanical ones of two
    # sub-kinds (2 episodes each). Audio: every group holds the same ten values, each as often, as the
    # normal windows, so its AUC is exactly 0.5 in every group. IMU: collisions above every normal window
    # (AUC 1), faults below (AUC 0).
    rng = np.random.default_rng(0)
    values = rng.normal(size=10)
    audio = np.r_[np.tile(values, 4), np.tile(values, 2), values, values]
    imu = np.r_[rng.uniform(1, 2, 40), rng.uniform(3, 4, 20), rng.uniform(-2, 0, 20)]
    kinds = np.array(["normal"] * 40 + ["collision"] * 20 + ["mechanical"] * 20)
    subs = np.array(["none"] * 40 + ["bump"] * 20 + ["bearing"] * 10 + ["loose"] * 10)
    clusters = np.array([f"n{i // 5}" for i in range(40)] + [f"a{i // 5}" for i in range(40)])
    terms = np.stack([audio, imu], axis=1)[None]  # one model
    groups = {g.group: g for g in group_terms(terms, kinds, subs, clusters)}
    assert list(groups) == ["all anomalies", "collision", "bump", "mechanical", "bearing", "loose"]
    assert [groups[k].windows for k in groups] == [40, 20, 20, 20, 10, 10]
    assert [groups[k].episodes for k in groups] == [8, 4, 4, 4, 2, 2]
    for g in groups.values():
        assert g.auc["audio"].value == pytest.approx(0.5, abs=1e-12)
    assert groups["collision"].auc["imu"].value == 1.0 == groups["bump"].auc["imu"].value
    assert groups["mechanical"].auc["imu"].value == 0.0 == groups["loose"].auc["imu"].value
    assert groups["all anomalies"].auc["imu"].value == 0.5
    fused = audio + imu
    for g in groups.values():
        if g.group == "all anomalies":
            member = kinds != "normal"
        else:
            member = (kinds == g.group) if g.group in ("collision", "mechanical") else (subs == g.group)
        y = np.r_[np.zeros(40), np.ones(g.windows)]
        assert g.auc[FUSION].value == pytest.approx(roc_auc_score(y, np.r_[fused[:40], fused[member]]))
        for m in MODALITY_NAMES:
            assert g.fusion_minus[m].value == pytest.approx(g.auc[FUSION].value - g.auc[m].value)
    # two identical models give the same seed means as one
    twice = group_terms(np.concatenate([terms, terms]), kinds, subs, clusters)
    assert [g.auc[FUSION].value for g in twice] == [g.auc[FUSION].value for g in groups.values()]


@pytest.fixture(scope="module")
def frame_models(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """`context-net-frames` at the smoke scale on `tiny_dataset`, two training seeds."""
    root = tmp_path_factory.mktemp("frame-models")
    data = open_dataset(tiny_dataset)
    return [
        train_method(data, "context-net-frames", k, "smoke", root / f"context-net-frames-seed{k}").path
        for k in (0, 1)
    ]


def test_report_matches_the_models_scores(
    tiny_dataset: Path, frame_models: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = modality_terms(frame_models, tiny_dataset)
    windows, rows = pipeline.test_windows(open_dataset(tiny_dataset))
    y = np.array([r.kind != "normal" for r in rows])
    dets = [load_references([p])[1][0] for p in frame_models]
    overall = report.groups[0]
    assert overall.group == "all anomalies" and overall.windows == int(y.sum())
    assert report.normal_windows == int((~y).sum()) and report.method == "context-net-frames"
    want_fusion = np.mean([roc_auc_score(y, d.score(windows)) for d in dets])
    assert overall.auc[FUSION].value == pytest.approx(want_fusion)
    for m, name in enumerate(MODALITY_NAMES):
        want = np.mean([roc_auc_score(y, d.modality_scores(windows)[:, m]) for d in dets])
        assert overall.auc[name].value == pytest.approx(want)

    out = tmp_path / "terms.json"
    md = tmp_path / "sub" / "terms.md"
    files = ["--json", str(out), "--md", str(md)]
    assert main(["terms", *map(str, frame_models), "--data", str(tiny_dataset), *files]) == 0
    printed = capsys.readouterr().out
    assert md.read_text(encoding="utf-8") == printed
    assert printed.startswith("# Modality terms of `context-net-frames` (2 model(s))")
    assert "| all anomalies |" in printed and "Over all anomalies" in printed
    doc = json.loads(out.read_text(encoding="utf-8"))
    assert doc["groups"][0]["auc"]["fusion"]["value"] == pytest.approx(want_fusion)
    assert [g["group"] for g in doc["groups"]] == [g.group for g in report.groups]


def test_refuses_other_methods(
    tiny_dataset: Path, tiny_model: Path, frame_models: list[Path], tmp_path: Path
) -> None:
    with pytest.raises(UserError, match=r"holds method 'msvdd'.*context-net-frames.*diagnose"):
        load_references([tiny_model])
    with pytest.raises(UserError, match="at least one model"):
        load_references([])
    assert main(["terms", str(tiny_model), "--data", str(tiny_dataset)]) == 2
