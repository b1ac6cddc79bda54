"""End to end through the real CLI on the tiny preset."""

from __future__ import annotations

import argparse
import csv
import importlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sklearn.metrics import roc_auc_score

from benchmarks.cli import _discover, build_parser, main
from benchmarks.dataset import open_dataset
from benchmarks.errors import FOREIGN_USER_ERRORS, UserError, is_user_error
from benchmarks.resume import code_digest, finished_training, training_key


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in build_parser()._actions if a.dest == "command")
    return dict(action.choices)  # type: ignore[arg-type]


def test_the_console_script_runs_and_lists_every_command() -> None:
    """The one subprocess: the module runs as a program; every other check builds the parser in-process."""
    result = subprocess.run(
        [sys.executable, "-m", "benchmarks.cli", "--help"], capture_output=True, text=True, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("usage: msvdd-bench")
    for name in _subparsers():
        assert f"    {name} " in result.stdout or f"    {name}\n" in result.stdout, name


def test_every_subcommand_help_names_its_example_and_options() -> None:
    subparsers = _subparsers()
    commands = {c.name: c for c in _discover()}
    assert {"generate", "train", "evaluate", "run", "perf", "presets", "demo"} <= set(commands)
    assert set(subparsers) == set(commands)
    for name, command in commands.items():
        parser = subparsers[name]
        text = parser.format_help()
        assert text.startswith(f"usage: msvdd-bench {name}"), name
        assert command.example.strip(), name
        for line in command.example.strip().splitlines():
            assert f"\n  {line}" in text, (name, line)
        for action in parser._actions:
            for option in action.option_strings:
                assert option in text, (name, option)
            if not action.option_strings:
                assert str(action.metavar or action.dest) in text, (name, action.dest)
            if action.help and action.help is not argparse.SUPPRESS:
                assert " ".join(action.help.split()[:3]) in " ".join(text.split()), (name, action.help)


def test_train_then_evaluate(tiny_dataset: Path, tiny_model: Path, tmp_path: Path) -> None:
    model2 = tmp_path / "iforest"
    assert (
        main(["train", "--data", str(tiny_dataset), "--method", "iforest-early", "--out", str(model2)]) == 0
    )
    run = tmp_path / "run"
    assert main(["evaluate", "--data", str(tiny_dataset), "--model", str(tiny_model), str(model2),
                 "--out", str(run)]) == 0  # fmt: skip
    results = json.loads((run / "results.json").read_text())
    assert set(results["methods"]) == {"msvdd", "iforest-early"}
    assert (run / "figures" / "roc_all.png").is_file()
    # scores.csv lets anyone recompute every metric: its AUC is the reported one.
    with open(run / "scores.csv", newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r["method"] == "msvdd"]
    auc = roc_auc_score([int(r["label"]) for r in rows], [float(r["score"]) for r in rows])
    assert auc == pytest.approx(results["methods"]["msvdd"]["auc"], abs=1e-12)
    assert "F1 oracle" in (run / "results.md").read_text()
    # `train` records its fit time under the key `run --resume` would look for, and `evaluate` reports it;
    # a model without the record (the fixture, trained by the library) has no fit time, not a made-up one.
    dataset = open_dataset(tiny_dataset, verify=False)
    key = training_key("iforest-early", 0, dataset.preset.method_scale, "cpu", dataset.fingerprint,
                       code_digest("iforest-early"))  # fmt: skip
    seconds = finished_training(model2, key)
    assert seconds is not None and seconds > 0.0
    assert results["methods"]["iforest-early"]["train_seconds"] == pytest.approx(seconds)
    assert results["methods"]["msvdd"]["train_seconds"] is None
    assert f"| iforest-early | {seconds:.1f} |" in (run / "results.md").read_text()


def test_run_end_to_end(tiny_dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    code = main(["run", "--preset", "tiny", "--data", str(tiny_dataset), "--out", str(out),
                 "--methods", "audio-rms", "imu-kurtosis", "--no-progress"])  # fmt: skip
    assert code == 0
    results = json.loads((out / "results.json").read_text())
    for name in ("audio-rms", "imu-kurtosis"):
        entry = results["methods"][name]
        assert 0.0 <= entry["auc"] <= 1.0
        assert np.isfinite(entry["f1"])
    assert "naive" in results["naive_verdict"]
    assert (results["preset"], results["seed"]) == ("tiny", 0)  # the dataset's, not a default


def test_run_refuses_a_preset_or_seed_the_dataset_was_not_made_with(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for flag, value, says in (("--seed", "5", "generated with seed 0"), ("--preset", "quick", "preset tiny")):
        out = tmp_path / f"run{flag}"
        code = main(["run", flag, value, "--data", str(tiny_dataset), "--out", str(out),
                     "--methods", "audio-rms", "--no-progress"])  # fmt: skip
        assert code == 2
        assert says in capsys.readouterr().err
        assert not out.exists()


def test_bad_input_exits_2_with_a_message(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["generate", "--preset", "huge", "--out", str(tmp_path / "d")]) == 2
    assert "unknown preset 'huge'" in capsys.readouterr().err
    assert main(["evaluate", "--data", str(tmp_path / "nope"), "--model", str(tmp_path), "--out",
                 str(tmp_path / "r")]) == 2  # fmt: skip
    assert "not a dataset" in capsys.readouterr().err
    assert not (tmp_path / "d").exists() and not (tmp_path / "r").exists()


def test_unknown_method_is_refused(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert (
        main(["train", "--data", str(tiny_dataset), "--method", "magic", "--out", str(tmp_path / "m")]) == 2
    )
    assert "method 'magic' is unknown" in capsys.readouterr().err


def test_a_negative_seed_exits_2_naming_the_field_value_and_range(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["generate", "--preset", "tiny", "--seed", "-1", "--out", str(tmp_path / "d")]) == 2
    assert capsys.readouterr().err == (
        "msvdd-bench generate: error: --seed = -1 is invalid; allowed: an integer >= 0\n"
    )
    assert list(tmp_path.iterdir()) == []


def test_user_errors_are_known_by_type() -> None:
    from benchmarks.regression import CompareError

    assert issubclass(CompareError, UserError) and is_user_error(CompareError("bad input"))
    for module_name, class_name in FOREIGN_USER_ERRORS:  # msvdd, sim, synth_audio do not import benchmarks
        error = getattr(importlib.import_module(module_name), class_name)
        assert issubclass(error, Exception) and is_user_error(error("bad input")), class_name
    for bug in (ValueError("x"), FileNotFoundError("x"), KeyError("x"), TypeError("x")):
        assert not is_user_error(bug)


def test_a_library_bug_keeps_its_traceback(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import benchmarks.dataset as ds

    def broken(*args: object, **kwargs: object) -> None:
        np.zeros(3)[:2] += np.ones(3)  # a broadcast error: a bug, not bad input

    monkeypatch.setattr(ds, "generate", broken)  # the command imports it when it runs
    with pytest.raises(ValueError, match="could not be broadcast"):
        main(["generate", "--preset", "tiny", "--out", str(tmp_path / "d")])


@pytest.mark.parametrize("workers", [1, 2])
def test_sigterm_stops_a_command_like_ctrl_c_and_leaves_nothing(tmp_path: Path, workers: int) -> None:
    """`kill PID` (a background job ignores Ctrl-C): exit 143, and the half-generated dataset is removed."""
    import signal
    import time

    out = tmp_path / "data"
    command = ["generate", "--preset", "tiny", "--seed", "3", "--out", str(out), "--workers", str(workers)]
    proc = subprocess.Popen(
        [sys.executable, "-m", "benchmarks.cli", *command, "--no-progress"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".data.partial-*/*")):  # an episode under way
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "msvdd-bench generate: terminated (SIGTERM)" in err
    assert list(tmp_path.iterdir()) == []


def test_a_sigterm_a_finalizer_swallowed_is_signalled_again() -> None:
    """A SIGTERM whose handler runs while an object's `__del__` does (llvmlite's, while numba compiles) raises
    `Terminated` in there, where Python ignores it ("Exception ignored in ..."), and the command would go on;
    the signal is sent again and stops the command where it was. The hook goes when the block ends."""
    import signal
    import time

    from benchmarks.cli import Terminated, stop_on_sigterm

    swallowed: list[bool] = []

    class Finalized:
        def __del__(self) -> None:
            signal.raise_signal(signal.SIGTERM)  # the handler runs here, before the finalizer returns
            swallowed.append(True)  # not reached: the handler's Terminated ended the finalizer

    hook = sys.unraisablehook
    deadline = time.monotonic() + 10.0
    with pytest.raises(Terminated), stop_on_sigterm():
        Finalized()  # dropped at once: its __del__ runs here
        while time.monotonic() < deadline:
            time.sleep(0.001)
    assert time.monotonic() < deadline
    assert swallowed == []
    assert sys.unraisablehook is hook
