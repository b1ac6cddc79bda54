"""A detector defined outside the package (`module:Class`) through `train`, `run`, `evaluate`, `compare`."""

from __future__ import annotations

import csv
import json
import textwrap
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from benchmarks import methods
from benchmarks.cli import main
from msvdd.contract import ModelFormatError

MODULE = "msvdd_bench_test_external_detectors"
"""A module name no other test uses (imported modules and resolved names are cached per process)."""

SOURCE = '''
"""Detectors a user writes without touching the benchmark: the contract of msvdd.contract.Detector."""
import json

import numpy as np


class MeanAudioEnergy:
    """How far a window's log audio energy is from the training windows' mean."""

    modality = "audio"

    def __init__(self, seed=0):
        self.seed = seed
        self.mean_ = 0.0
        self.threshold_ = float("nan")

    @staticmethod
    def _energy(batch):
        return np.log(np.mean(np.asarray(batch.audio, dtype=np.float64) ** 2, axis=(1, 2)) + 1e-12)

    def fit(self, train, val=None):
        self.mean_ = float(self._energy(train).mean())
        self.threshold_ = float(np.percentile(self.score(train), 95))
        return self

    def score(self, batch):
        return np.abs(self._energy(batch) - self.mean_)

    def predict(self, batch):
        return self.score(batch) > self.threshold_

    def save(self, path):
        with open(path, "w") as handle:
            json.dump({"mean": self.mean_, "threshold": self.threshold_}, handle)

    @classmethod
    def load(cls, path):
        with open(path) as handle:
            state = json.load(handle)
        detector = cls()
        detector.mean_, detector.threshold_ = state["mean"], state["threshold"]
        return detector


class NoSave:
    """Not a detector: it cannot be saved or loaded."""

    def fit(self, train, val=None):
        return self

    def score(self, batch):
        return np.zeros(len(batch))

    def predict(self, batch):
        return np.zeros(len(batch), dtype=bool)
'''

NAME = f"{MODULE}:MeanAudioEnergy"


@pytest.fixture(scope="module")
def external(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The test's detector module written to a folder on sys.path; yields its `module:Class` name."""
    folder = tmp_path_factory.mktemp("outside")
    (folder / f"{MODULE}.py").write_text(textwrap.dedent(SOURCE))
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(folder))
        yield NAME


def _scores(run: Path, method: str) -> np.ndarray:
    with open(run / "scores.csv", newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r["method"] == method]
    return np.array([float(r["score"]) for r in sorted(rows, key=lambda r: int(r["window_id"]))])


def test_an_outside_detector_runs_through_run_evaluate_and_compare(
    external: str, tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    runs = []
    for name in ("a", "b"):
        out = tmp_path / name
        code = main(["run", "--data", str(tiny_dataset), "--out", str(out),
                     "--methods", external, "audio-rms", "--no-progress"])  # fmt: skip
        assert code == 0
        runs.append(out)
    doc = json.loads((runs[0] / "results.json").read_text())
    entry = doc["methods"][external]
    assert entry["family"] == "external" and 0.0 <= entry["auc"] <= 1.0 and "auc_ci95" in entry
    assert f"`{external}`" in (runs[0] / "results.md").read_text()  # the "other methods" table
    model = runs[0] / "models" / f"{external.replace(':', '.')}-seed0"
    assert json.loads((model / "method.json").read_text())["method"] == external
    # evaluate loads the saved model through the same module:Class and scores the same.
    again = tmp_path / "evaluated"
    assert main(["evaluate", "--data", str(tiny_dataset), "--model", str(model), "--out", str(again)]) == 0
    np.testing.assert_array_equal(_scores(again, external), _scores(runs[0], external))
    capsys.readouterr()
    code = main(["compare", str(runs[0]), str(runs[1]), "--method", external])
    assert code == 0
    assert "no regression" in capsys.readouterr().out


def test_train_accepts_an_outside_detector(external: str, tiny_dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "model"
    assert main(["train", "--data", str(tiny_dataset), "--method", external, "--out", str(out)]) == 0
    name, detector = methods.load_detector(out)
    assert name == external and type(detector).__name__ == "MeanAudioEnergy"
    assert np.isfinite(detector.threshold_)


@pytest.mark.parametrize(
    ("name", "says"),
    [
        ("no_such_module_xyz:Detector", "cannot import module 'no_such_module_xyz'"),
        (f"{MODULE}:Missing", f"module '{MODULE}' has no class 'Missing'"),
        (f"{MODULE}:NoSave", "lacks save, load of the detector contract"),
        (f"{MODULE}:np", "is a module, not a class"),
        (":Detector", "is named module:Class"),
    ],
)
def test_a_bad_outside_detector_is_refused_with_its_name(
    external: str, name: str, says: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    code = main(["run", "--preset", "tiny", "--out", str(out), "--methods", name, "--no-progress"])
    assert code == 2
    err = capsys.readouterr().err
    assert says in err and repr(name) in err
    assert not out.exists()  # refused before generating anything


def test_a_saved_model_whose_module_is_gone_is_refused(
    external: str, tiny_dataset: Path, tmp_path: Path
) -> None:
    out = tmp_path / "model"
    assert main(["train", "--data", str(tiny_dataset), "--method", external, "--out", str(out)]) == 0
    info = json.loads((out / "method.json").read_text())
    info["method"] = "gone_module_xyz:MeanAudioEnergy"
    (out / "method.json").write_text(json.dumps(info))
    with pytest.raises(ModelFormatError, match="cannot import module 'gone_module_xyz'"):
        methods.load_detector(out)
