"""Run reports: every AUC with its episode-cluster interval, paired differences against M-SVDD."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from benchmarks import methods
from benchmarks.dataset import WindowRow, open_dataset
from benchmarks.metrics import MethodMetrics, compute_metrics
from benchmarks.pipeline import MethodScores, TrainedModel, score_and_measure, train_method
from benchmarks.report import (
    SVDD_NOTE,
    RunInfo,
    RunIntervals,
    auc_intervals,
    markdown,
    naive_verdict,
    ranking_note,
    results_json,
    write_report,
)
from benchmarks.uncertainty import auc_interval

INFO = RunInfo("tiny", 0, "data", "msvdd-bench run", "test machine", "the test date", {})


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


def test_a_one_seed_method_is_paired_with_the_reference_model_of_its_seed() -> None:
    """Oracle: a copy of M-SVDD's seed-1 model trained once with seed 1 differs from M-SVDD by exactly 0 when
    paired with that seed, while a method with every seed of M-SVDD is compared with the seed mean."""
    rows = _rows()
    reference = [_scores(rows, "msvdd", s, 1.0) for s in (0, 1, 2)]
    copy = MethodScores("msvdd-euclidean", 1, reference[1].scores.copy(), 0.5)
    others = [_scores(rows, "audio-rms", s, 0.5) for s in (0, 1, 2)]
    run = auc_intervals(rows, [*reference, copy, *others], replicates=200)
    assert run.methods["msvdd-euclidean"].reference_seeds == (1,)
    assert all(
        iv.value == iv.low == iv.high == 0.0 for iv in run.methods["msvdd-euclidean"].vs_reference.values()
    )
    assert run.methods["audio-rms"].reference_seeds == run.methods["msvdd"].reference_seeds == (0, 1, 2)
    mean_of_three = run.methods["msvdd"].auc["auc"].value
    rms = run.methods["audio-rms"]
    assert rms.vs_reference["auc"].value == pytest.approx(rms.auc["auc"].value - mean_of_three, abs=1e-12)
    per_method = {m: [compute_metrics(r.scores, 0.5, np.array([w.kind for w in rows]))] for m, r in
                  (("msvdd", reference[0]), ("msvdd-euclidean", copy), ("audio-rms", others[0]))}  # fmt: skip
    assert "msvdd-euclidean (seeds 1)" in markdown(INFO, per_method, run)
    assert results_json(INFO, per_method, run)["methods"]["msvdd-euclidean"]["auc_diff_reference_seeds"] == [
        1
    ]


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
    write_report(tmp_path / "run", INFO, rows, scores, per_method, dataset.fault_severities())

    doc = json.loads((tmp_path / "run" / "results.json").read_text())
    assert doc["uncertainty"]["reference"] == "msvdd"
    assert any("_severity_" in key for key in doc["methods"]["msvdd"]["auc_ci95"])
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


def _severity_rows() -> tuple[list[WindowRow], dict[str, float]]:
    """4 normal episodes of 5 windows; fault episodes of 3 windows at severities on and inside the bin
    edges (0.25 opens the second bin, 1.0 closes the last); `f_unknown` has no recorded severity."""
    severity = {"f0": 0.1, "f1": 0.2, "f2": 0.25, "f3": 0.4, "f4": 0.8, "f5": 1.0}
    rows: list[WindowRow] = []
    plan = [("normal", "none", f"n{i}", 5) for i in range(4)]
    plan += [("mechanical", "bearing" if e in ("f0", "f2", "f4") else "out_of_round", e, 3) for e in severity]
    plan += [("mechanical", "bearing", "f_unknown", 3), ("collision", "wall", "c0", 2)]
    for kind, sub, episode, n in plan:
        for k in range(n):
            rows.append(WindowRow(len(rows), episode, 2.0 * k, "test", 0, kind, sub, -1, 0))
    return rows, severity


def test_aucs_by_fault_severity_are_the_plain_aucs_of_each_bin() -> None:
    """Oracle: each severity bin's AUC is scikit-learn's AUC of the normal windows against that bin's fault
    windows; a fault score that grows with severity gives AUCs that grow bin by bin."""
    from sklearn.metrics import roc_auc_score

    from benchmarks.report import severity_key

    rows, severity = _severity_rows()
    rng = np.random.default_rng(3)
    sev = np.array([severity.get(r.episode, 0.5) for r in rows])
    normal = np.array([r.kind == "normal" for r in rows])
    scores = np.where(normal, rng.normal(size=len(rows)), 4.0 * sev - 1.5 + 0.3 * rng.normal(size=len(rows)))
    run = auc_intervals(rows, [MethodScores("msvdd", 0, scores, 0.0)], replicates=50, severity=severity)
    auc = run.methods["msvdd"].auc
    bins = {"0.00-0.25": ("f0", "f1"), "0.25-0.50": ("f2", "f3"), "0.75-1.00": ("f4", "f5")}
    expected_keys = {  # no fault episode lies in 0.50-0.75
        severity_key(label, sub) for label in bins for sub in ("mechanical", "bearing", "out_of_round")
    }
    assert {k for k in auc if "_severity_" in k} == expected_keys
    episodes = np.array([r.episode for r in rows])
    values = []
    for label, members in bins.items():
        keep = normal | np.isin(episodes, members)
        expected = roc_auc_score(~normal[keep], scores[keep])
        assert auc[severity_key(label)].value == pytest.approx(expected, abs=1e-12)
        values.append(expected)
    assert values[0] < values[1] < values[2]
    keep = normal | (episodes == "f5")  # severity 1.0 belongs to the last bin, as out_of_round there
    assert auc[severity_key("0.75-1.00", "out_of_round")].value == pytest.approx(
        roc_auc_score(~normal[keep], scores[keep]), abs=1e-12
    )


def test_the_severity_table_is_in_the_report_only_when_severities_are_known() -> None:
    rows, severity = _severity_rows()
    kinds = np.array([r.kind for r in rows])
    scores = [_scores(rows, "msvdd", 0, 1.0)]
    per_method = {"msvdd": [compute_metrics(scores[0].scores, 0.5, kinds)]}
    with_sev = markdown(INFO, per_method, auc_intervals(rows, scores, replicates=50, severity=severity))
    assert "by fault severity" in with_sev
    table = with_sev.split("by fault severity")[1].split("\n## ")[0]
    assert "| 0.00-0.25 |" in table and "| 0.75-1.00 |" in table and "| 0.50-0.75 |" not in table
    without = markdown(INFO, per_method, auc_intervals(rows, scores, replicates=50))
    assert "by fault severity" not in without
    assert "by fault kind and severity" not in without


def test_the_reference_gets_a_table_by_fault_kind_and_severity() -> None:
    """Rows are the fault kinds, columns the bins that hold fault windows (the empty 0.50-0.75 is left out);
    each cell is that kind's AUC in that bin with its interval (the AUCs: the oracle test above)."""
    from benchmarks.report import severity_key
    from benchmarks.uncertainty import format_interval

    rows, severity = _severity_rows()
    kinds = np.array([r.kind for r in rows])
    scores = [_scores(rows, "msvdd", 0, 1.0)]
    per_method = {"msvdd": [compute_metrics(scores[0].scores, 0.5, kinds)]}
    run = auc_intervals(rows, scores, replicates=50, severity=severity)
    text = markdown(INFO, per_method, run)
    table = text.split("## Fault AUC (%) of `msvdd` by fault kind and severity")[1].split("\n## ")[0]
    lines = [line for line in table.splitlines() if line.startswith("| ")]
    assert lines[0] == "| Fault kind | 0.00-0.25 | 0.25-0.50 | 0.75-1.00 |"
    auc = run.methods["msvdd"].auc
    bins = ("0.00-0.25", "0.25-0.50", "0.75-1.00")
    for line, kind in zip(lines[1:], ("bearing", "out_of_round"), strict=True):
        # every kind has one episode in each of these bins (bearing f0, f2, f4; out_of_round f1, f3, f5)
        assert (
            line
            == f"| {kind} | " + " | ".join(format_interval(auc[severity_key(b, kind)]) for b in bins) + " |"
        )
    assert len(lines) == 3


def _severity_run(shifts: dict[str, float]) -> tuple[RunIntervals, str, str]:
    """A run on `_severity_rows` of methods whose anomalous windows are shifted by `shifts`: its intervals,
    its report, and the report of the same run without severities."""
    rows, severity = _severity_rows()
    kinds = np.array([r.kind for r in rows])
    scores = [_scores(rows, m, 0, shift) for m, shift in shifts.items()]
    per_method = {s.method: [compute_metrics(s.scores, 0.5, kinds)] for s in scores}
    run = auc_intervals(rows, scores, replicates=50, severity=severity)
    without = markdown(INFO, per_method, auc_intervals(rows, scores, replicates=50))
    return run, markdown(INFO, per_method, run), without


def _table_rows(text: str, heading: str) -> list[str]:
    """The rows (header first, no separator) of the table under `heading` in a report."""
    table = text.split(heading)[1].split("\n## ")[0]
    return [line for line in table.splitlines() if line.startswith("| ")]


def test_every_method_gets_its_fault_aucs_by_kind_in_the_top_severity_bin() -> None:
    """Rows are the fault kinds, columns every method of the tables; each cell is that method's AUC of the
    kind in the highest bin holding faults (0.75-1.00 here), the row's largest in bold."""
    from benchmarks.report import severity_key
    from benchmarks.uncertainty import format_interval

    run, text, without = _severity_run({"msvdd": 1.0, "dae": 0.2})
    lines = _table_rows(text, "## Fault AUC (%) at severity 0.75-1.00 by fault kind")
    assert lines[0] == "| Fault kind | dae | msvdd |"
    for line, kind in zip(lines[1:], ("bearing", "out_of_round"), strict=True):
        cells = {m: run.methods[m].auc[severity_key("0.75-1.00", kind)] for m in ("dae", "msvdd")}
        best = max(iv.value for iv in cells.values())
        shown = [
            f"**{format_interval(iv)}**" if iv.value == best else format_interval(iv) for iv in cells.values()
        ]
        assert line == f"| {kind} | " + " | ".join(shown) + " |"
        assert line.count("**") == 2
    assert len(lines) == 3
    assert "at severity" not in without


def test_each_ablation_gets_its_paired_fault_differences_by_kind_and_severity() -> None:
    """Rows are each ablation's faults (all, then by kind), columns all severities and the bins that hold
    faults; each cell the paired difference against M-SVDD that the run computed, in bold where its
    interval excludes 0. A run without ablations has no such table."""
    from benchmarks.report import severity_key
    from benchmarks.uncertainty import excludes_zero, format_interval

    # msvdd-imu-only ignores the faults (shift 0): a large negative difference against M-SVDD's shift 3
    run, text, _ = _severity_run({"msvdd": 3.0, "msvdd-imu-only": 0.0})
    lines = _table_rows(text, "## Paired fault AUC differences (%) of the ablations")
    bins = ("0.00-0.25", "0.25-0.50", "0.75-1.00")
    assert lines[0] == "| Ablation | Fault kind | all severities | " + " | ".join(bins) + " |"
    diff = run.methods["msvdd-imu-only"].vs_reference
    for line, kind in zip(lines[1:], ("mechanical", "bearing", "out_of_round"), strict=True):
        ivs = [diff[f"auc_{kind}"], *(diff[severity_key(b, kind)] for b in bins)]
        cells = [
            f"**{format_interval(iv, signed=True)}**"
            if excludes_zero(iv)
            else format_interval(iv, signed=True)
            for iv in ivs
        ]
        shown = "all faults" if kind == "mechanical" else kind
        assert line == f"| `msvdd-imu-only` | {shown} | " + " | ".join(cells) + " |"
    assert len(lines) == 4 and diff["auc_mechanical"].high < 0 and "**" in lines[1]
    _, alone, _ = _severity_run({"msvdd": 3.0})
    assert "by fault kind and severity" in alone and "of the ablations" not in alone


def _run_of(shifts: dict[str, float]) -> tuple[dict[str, list[MethodMetrics]], RunIntervals]:
    """Per-method metrics and intervals of methods whose anomalous windows are shifted by `shifts`."""
    rows = _rows()
    kinds = np.array([r.kind for r in rows])
    scores = [_scores(rows, m, 0, shift) for m, shift in shifts.items()]
    per_method = {s.method: [compute_metrics(s.scores, 0.5, kinds)] for s in scores}
    return per_method, auc_intervals(rows, scores, replicates=200)


def test_naive_verdict_compares_the_best_naive_baseline_with_the_best_detector() -> None:
    # Level: audio RMS scores every window as M-SVDD does, so their paired difference is 0 in every
    # replicate and the verdict says "level", never "stay below".
    rows = _rows()
    kinds = np.array([r.kind for r in rows])
    same = _scores(rows, "msvdd", 0, 0.6)
    scores = [same, MethodScores("audio-rms", 0, same.scores.copy(), 0.5)]
    level = {s.method: [compute_metrics(s.scores, 0.5, kinds)] for s in scores}
    run = auc_intervals(rows, scores, replicates=200)
    assert run.naive_vs_best is not None and run.naive_vs_best.best == "msvdd"
    assert run.naive_vs_best.difference.low == run.naive_vs_best.difference.high == 0.0
    text = naive_verdict(level, run)
    assert "level with the best detector" in text and "stay below" not in text
    # Below: M-SVDD separates the classes, the naive baselines do not.
    per_method, run = _run_of({"msvdd": 6.0, "audio-rms": 0.0, "imu-kurtosis": 0.0})
    text = naive_verdict(per_method, run)
    assert "stay below the best detector of this run" in text and "msvdd" in text
    doc = results_json(INFO, per_method, run)
    assert doc["naive_vs_best"]["best"] == "msvdd" and doc["naive_vs_best"]["difference"]["excludes_zero"]
    assert doc["naive_verdict"] == text
    # Without intervals nothing is claimed about solving the benchmark.
    assert "does not say" in naive_verdict(per_method)


def test_ranking_note_counts_the_differences_that_contain_zero() -> None:
    per_method, run = _run_of({"msvdd": 0.5, "dae": 0.5, "audio-rms": 8.0})
    note = ranking_note(run)
    level = [
        m
        for m, mi in run.methods.items()
        if m != "msvdd" and mi.vs_reference["auc"].low <= 0.0 <= mi.vs_reference["auc"].high
    ]
    assert level == ["dae"]
    assert note.startswith("**This test set cannot rank 1 of the 2 other methods against M-SVDD**")
    text = markdown(INFO, per_method, run)
    table1 = text.split("## Comparison (paper Table I)\n\n", 1)[1]
    assert table1.startswith(note)  # the first line of the first table
    assert ranking_note(None).startswith("**Ranking**: M-SVDD is not in this run")
