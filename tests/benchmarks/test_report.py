"""Run reports: every AUC with its episode-cluster interval, paired differences against M-SVDD."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from benchmarks import methods
from benchmarks.dataset import WindowRow, open_dataset
from benchmarks.metrics import compute_metrics
from benchmarks.pipeline import MethodScores, TrainedModel, score_and_measure, train_method
from benchmarks.report import SVDD_NOTE, RunInfo, auc_intervals, markdown, results_json, write_report
from benchmarks.uncertainty import auc_interval

INFO = RunInfo("tiny", 0, "data", "msvdd-bench run", "test machine", "2026-01-01", {})


def _rows() -> list[WindowRow]:
    """6 normal episodes of 5 windows, 4 collision and 4 fault episodes of 2 windows."""
    rows: list[WindowRow] = []
    plan = [("normal", "none", f"n{i}", 5) for i in range(6)]
    plan += [("collision", "wall" if i % 2 else "box", f"c{i}", 2) for i in range(4)]
    plan += [("mechanical", "bearing", f"f{i}", 2) for i in range(4)]
    for kind, sub, episode, n in plan:
        for k in range(n):
            rows.append(WindowRow(len(rows), episode, 2.0 * k, "test", 0, kind, sub, -1, 0))
    return rows


def _scores(rows: list[WindowRow], method: str, seed: int, shift: float) -> MethodScores:
    rng = np.random.default_rng(seed + 100 * len(method))
    anomalous = np.array([r.kind != "normal" for r in rows])
    return MethodScores(method, seed, rng.normal(size=len(rows)) + shift * anomalous, 0.5)


def test_intervals_cover_every_auc_and_the_reference_against_itself_is_zero() -> None:
    rows = _rows()
    scores = [_scores(rows, "msvdd", s, 1.0) for s in (0, 1)] + [_scores(rows, "audio-rms", 0, 0.5)]
    run = auc_intervals(rows, scores, replicates=200)
    assert run.reference == "msvdd" and (run.normal_episodes, run.anomalous_episodes) == (6, 8)
    for name in ("msvdd", "audio-rms"):
        keys = set(run.methods[name].auc)
        assert keys == {"auc", "auc_collision", "auc_mechanical", "auc_wall", "auc_box", "auc_bearing"}
        for iv in run.methods[name].auc.values():
            assert iv.low <= iv.value <= iv.high
    same = run.methods["msvdd"].vs_reference
    assert all(iv.value == iv.low == iv.high == 0.0 for iv in same.values())
    # One seed: the plain episode-cluster interval of that seed's scores.
    anomalous = np.array([r.kind != "normal" for r in rows])
    episodes = [r.episode for r in rows]
    single = auc_interval(scores[2].scores, anomalous, episodes, replicates=200)
    assert run.methods["audio-rms"].auc["auc"] == single


def test_report_without_msvdd_has_intervals_but_no_differences() -> None:
    rows = _rows()
    kinds = np.array([r.kind for r in rows])
    scores = [_scores(rows, "audio-rms", 0, 0.5)]
    per_method = {"audio-rms": [compute_metrics(scores[0].scores, 0.5, kinds)]}
    run = auc_intervals(rows, scores, replicates=100)
    assert run.reference is None and run.methods["audio-rms"].vs_reference == {}
    text = markdown(INFO, per_method, run)
    assert "ΔAUC" not in text and "not a ranking" in text
    doc = results_json(INFO, per_method, run)
    assert doc["uncertainty"]["reference"] is None
    assert doc["methods"]["audio-rms"]["auc_diff_vs_reference"] == {}


def test_a_real_tiny_run_reports_intervals_and_differences(
    tiny_dataset: Path, tiny_model: Path, tmp_path: Path
) -> None:
    dataset = open_dataset(tiny_dataset)
    name, detector = methods.load_detector(tiny_model)
    models = [TrainedModel(name, 0, detector, tiny_model, 1.0)]
    models += [train_method(dataset, "audio-rms", s, "smoke", tmp_path / f"rms{s}") for s in (0, 1)]
    scores, per_method, rows = score_and_measure(dataset, models, progress=False)
    write_report(tmp_path / "run", INFO, rows, scores, per_method)

    doc = json.loads((tmp_path / "run" / "results.json").read_text())
    assert doc["uncertainty"]["reference"] == "msvdd"
    assert doc["uncertainty"]["normal_episodes"] == 2
    for method in ("msvdd", "audio-rms"):
        entry = doc["methods"][method]
        assert {"auc", "auc_collision", "auc_mechanical", "auc_bearing"} <= set(entry["auc_ci95"])
        for key in ("auc", "auc_mechanical"):  # 2 normal and at least 2 anomalous episodes
            ci = entry["auc_ci95"][key]
            assert ci["low"] <= ci["value"] <= ci["high"]
        assert entry["auc_ci95"]["auc"]["value"] == pytest.approx(entry["auc"], abs=1e-12)  # mean over seeds
        assert entry["auc_ci95"]["auc_bearing"]["low"] is None  # one bearing episode: no interval
    zero = doc["methods"]["msvdd"]["auc_diff_vs_reference"]["auc"]
    assert zero == {"value": 0.0, "low": 0.0, "high": 0.0, "excludes_zero": False}
    diff = doc["methods"]["audio-rms"]["auc_diff_vs_reference"]["auc"]
    assert diff["low"] <= diff["value"] <= diff["high"] and isinstance(diff["excludes_zero"], bool)

    text = (tmp_path / "run" / "results.md").read_text()
    msvdd_auc = doc["methods"]["msvdd"]["auc_ci95"]["auc"]
    cell = f"{100 * msvdd_auc['value']:.1f} [{100 * msvdd_auc['low']:.1f}, {100 * msvdd_auc['high']:.1f}]"
    assert cell in text
    assert "ΔAUC vs M-SVDD (%)" in text and "not a ranking" in text and "F1 oracle" in text


def test_table1_marks_the_svdd_rows_as_ocsvm_and_labels_the_dcase_baseline() -> None:
    rows = _rows()
    kinds = np.array([r.kind for r in rows])
    names = ("ocsvm-early", "svdd-early", "dcase-ae")
    per_method = {n: [compute_metrics(_scores(rows, n, 0, 1.0).scores, 0.5, kinds)] for n in names}
    text = markdown(INFO, per_method)
    assert "| SVDD † (early fusion) |" in text and "| DCASE AE (log-mel) |" in text
    assert SVDD_NOTE in text and "duals coincide" in SVDD_NOTE
    assert SVDD_NOTE not in markdown(INFO, {"dcase-ae": per_method["dcase-ae"]})
