"""The regression gate: `msvdd-bench compare` on real tiny runs, and its rule on synthetic scores."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from sklearn.metrics import roc_auc_score

from benchmarks.cli import main
from benchmarks.dataset import open_dataset
from benchmarks.methods.gaussian import GaussianReference
from benchmarks.regression import (
    CompareError,
    GateConfig,
    RunScores,
    compare_runs,
    pair_methods,
)
from benchmarks.uncertainty import bootstrap_mean_pauc, counted_pauc, episode_draws

METHODS = ["audio-rms", "gaussian-early"]

Compare = Callable[..., tuple[int, str, str]]
"""compare(*args) -> (exit code, stdout, stderr) of `msvdd-bench compare ARGS`."""


def _run(dataset: Path, out: Path, methods: list[str]) -> Path:
    code = main(["run", "--data", str(dataset), "--out", str(out), "--methods", *methods, "--no-progress"])
    assert code == 0
    return out


@pytest.fixture(scope="module")
def baseline_run(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run of cheap methods on the tiny dataset: the baseline of the gate."""
    return _run(tiny_dataset, tmp_path_factory.mktemp("compare") / "baseline", METHODS)


@pytest.fixture()
def compare(capsys: pytest.CaptureFixture[str]) -> Compare:
    def call(*args: str) -> tuple[int, str, str]:
        capsys.readouterr()
        code = main(["compare", *args])
        out, err = capsys.readouterr()
        return code, out, err

    return call


def test_the_report_records_the_dataset_fingerprint(baseline_run: Path, tiny_dataset: Path) -> None:
    doc = json.loads((baseline_run / "results.json").read_text())
    assert doc["dataset_sha256"] == open_dataset(tiny_dataset, verify=False).fingerprint
    assert len(doc["dataset_sha256"]) == 64
    assert doc["dataset_sha256"][:16] in (baseline_run / "results.md").read_text()


def test_two_runs_of_the_same_code_are_no_regression(
    baseline_run: Path, tiny_dataset: Path, tmp_path: Path, compare: Compare
) -> None:
    again = _run(tiny_dataset, tmp_path / "again", METHODS)
    report = tmp_path / "cmp.json"
    code, out, _ = compare(str(baseline_run), str(again), "--json", str(report))
    assert code == 0
    assert "no regression (exit 0)" in out
    doc = json.loads(report.read_text())
    assert doc["exit_code"] == 0 and not doc["regression"]
    assert [m["method"] for m in doc["methods"]] == METHODS
    for entry in doc["methods"]:
        for key in ("auc", "pauc", "auc_collision", "auc_mechanical"):
            assert entry["metrics"][key]["difference"] == {"value": 0.0, "low": 0.0, "high": 0.0}
            assert entry["metrics"][key]["verdict"] == "identical"


def test_a_degraded_detector_is_caught(
    baseline_run: Path,
    tiny_dataset: Path,
    tmp_path: Path,
    compare: Compare,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # A sign bug in the reference detector: the same method name, worse code.
    original = GaussianReference._score
    monkeypatch.setattr(GaussianReference, "_score", lambda self, batch: -original(self, batch))
    degraded = _run(tiny_dataset, tmp_path / "degraded", ["gaussian-early"])
    report = tmp_path / "cmp.json"
    code, out, _ = compare(str(baseline_run), str(degraded), "--json", str(report))
    assert code == 1
    assert "REGRESSION (exit 1): gaussian-early AUC" in out
    doc = json.loads(report.read_text())
    assert [m["method"] for m in doc["methods"]] == ["gaussian-early"]  # the only method in both runs
    auc = doc["methods"][0]["metrics"]["auc"]
    assert auc["regression"] and auc["difference"]["high"] < 0 and auc["difference"]["value"] < -0.01
    # The same drop inside a wider tolerance passes (both conditions are needed).
    code, out, _ = compare(str(baseline_run), str(degraded), "--max-drop", "100")
    assert code == 0 and "worse, within --max-drop" in out


def test_runs_on_different_datasets_are_refused(baseline_run: Path, tmp_path: Path, compare: Compare) -> None:
    other = tmp_path / "other"
    shutil.copytree(baseline_run, other)
    doc = json.loads((other / "results.json").read_text())
    theirs, ours = doc["dataset_sha256"], "f" * 64
    doc["dataset_sha256"] = ours
    (other / "results.json").write_text(json.dumps(doc))
    code, _, err = compare(str(baseline_run), str(other))
    assert code == 2
    assert "different datasets" in err and theirs in err and ours in err
    del doc["dataset_sha256"]
    (other / "results.json").write_text(json.dumps(doc))
    code, _, err = compare(str(baseline_run), str(other))
    assert code == 2 and "records no dataset fingerprint" in err
    code, _, err = compare(str(baseline_run), str(tmp_path / "nope"))
    assert code == 2 and "not a run folder" in err
    code, _, err = compare(str(baseline_run), str(baseline_run), "--method", "msvdd")
    assert code == 2 and "--method msvdd: not in the candidate run" in err


# --- the rule, on synthetic scores -------------------------------------------------------------------------


def _synthetic(
    n_normal_eps: int = 10, n_anom_eps: int = 10, per_normal: int = 10, per_anom: int = 50
) -> RunScores:
    rng = np.random.default_rng(0)
    episodes = [f"n{i}" for i in range(n_normal_eps) for _ in range(per_normal)]
    episodes += [f"a{i}" for i in range(n_anom_eps) for _ in range(per_anom)]
    positive = np.array([e.startswith("a") for e in episodes])
    scores = rng.normal(size=positive.size) + 10.0 * positive  # separable: AUC 1
    kinds = np.where(positive, "collision", "normal")
    return RunScores(
        path=Path("synthetic"),
        fingerprint="x" * 64,
        preset="synthetic",
        dataset_seed=0,
        window_ids=np.arange(positive.size),
        positive=positive,
        kinds=kinds,
        episodes=np.array(episodes),
        scores={"m": scores[None, :]},
        seeds={"m": (0,)},
    )


def _with_scores(run: RunScores, scores: np.ndarray) -> RunScores:
    return RunScores(**{**run.__dict__, "scores": {"m": scores[None, :]}})


def test_a_small_certain_drop_regresses_only_beyond_the_tolerance() -> None:
    base = _synthetic()
    worse = base.scores["m"][0].copy()
    first_of_each = np.flatnonzero(np.r_[True, base.episodes[1:] != base.episodes[:-1]] & base.positive)
    worse[first_of_each] = -10.0  # one window in 50 of every anomalous episode: AUC 1 -> 0.98 everywhere
    cand = _with_scores(base, worse)
    strict = compare_runs(base, cand, [("m", "m")], GateConfig(max_drop=1.0, gate=("auc",)))
    auc = strict.methods[0].metrics[0]
    assert auc.difference.value == pytest.approx(-0.02)
    assert auc.difference.high < 0 and auc.regression and strict.exit_code == 1
    lenient = compare_runs(base, cand, [("m", "m")], GateConfig(max_drop=3.0, gate=("auc",)))
    assert lenient.exit_code == 0 and lenient.methods[0].metrics[0].verdict == "worse, within --max-drop"


def test_a_large_drop_the_interval_cannot_tell_from_noise_is_not_a_regression() -> None:
    base = _synthetic()
    worse = base.scores["m"][0].copy()
    worse[base.episodes == "a0"] = -10.0  # one anomalous episode of ten missed: AUC -10 points
    cand = _with_scores(base, worse)
    result = compare_runs(base, cand, [("m", "m")], GateConfig(max_drop=1.0, gate=("auc",)))
    auc = result.methods[0].metrics[0]
    assert auc.difference.value == pytest.approx(-0.1)
    assert auc.difference.high == 0.0  # replicates without episode a0 see no change
    assert not auc.regression and result.exit_code == 0 and auc.verdict == "within noise"


def test_gate_and_method_pairing_are_checked() -> None:
    base = _synthetic()
    with pytest.raises(CompareError, match="--max-drop must be"):
        GateConfig(max_drop=-1.0)
    with pytest.raises(CompareError, match="allowed metrics"):
        GateConfig(gate=("f1",))
    with pytest.raises(CompareError, match="exactly one --method"):
        pair_methods(base, base, None, "m")
    assert pair_methods(base, base) == [("m", "m")]
    no_mechanical = compare_runs(base, base, [("m", "m")], GateConfig(gate=("auc",)))
    assert no_mechanical.methods[0].metrics[3].verdict == "n/a"  # no fault windows: reported, not gated
    with pytest.raises(CompareError, match="has no interval"):
        compare_runs(base, base, [("m", "m")], GateConfig(gate=("auc_mechanical",)))


def test_bootstrap_pauc_is_the_reports_pauc_on_the_resampled_windows() -> None:
    base = _synthetic(n_normal_eps=6, n_anom_eps=4, per_anom=5)
    rng = np.random.default_rng(1)
    scores = rng.normal(size=base.positive.size) + 1.0 * base.positive
    counts = episode_draws(base.episodes, base.positive, replicates=3, seed=5)
    for draw in counts:
        keep = draw > 0
        reps = draw[keep].astype(int)
        expected = roc_auc_score(
            np.repeat(base.positive[keep], reps), np.repeat(scores[keep], reps), max_fpr=0.1
        )
        assert counted_pauc(scores, base.positive, draw) == pytest.approx(expected, abs=1e-12)
    boot = bootstrap_mean_pauc(np.stack([scores, scores]), base.positive, base.episodes, counts)
    assert boot.value == pytest.approx(roc_auc_score(base.positive, scores, max_fpr=0.1), abs=1e-12)
    assert boot.minus(boot).value == 0.0 and boot.replicates.shape == (3,)
