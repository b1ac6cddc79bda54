"""`msvdd-bench run --resume`: an interrupted run keeps its finished models; the resumed run reuses exactly
those a run of this code would have trained, and reports what an uninterrupted run reports."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import benchmarks.resume as resume_mod
import benchmarks.runner as runner
from benchmarks.cli import main
from benchmarks.resume import TRAINING_FILE, partial_folder

METHODS = ["iforest-early", "audio-rms", "imu-kurtosis"]


def _run(data: Path, out: Path, *extra: str) -> int:
    argv = ["run", "--data", str(data), "--out", str(out), "--methods", *METHODS, "--no-progress"]
    return main([*argv, *extra])


def _count_training(monkeypatch: pytest.MonkeyPatch, stop_at: str | None = None) -> list[str]:
    """Record each method `run` trains; with `stop_at`, interrupt (Ctrl-C) when that method starts."""
    trained: list[str] = []
    real: Callable[..., Any] = runner.train_method

    def counting(dataset: Any, name: str, *args: Any, **kwargs: Any) -> Any:
        if name == stop_at:
            raise KeyboardInterrupt
        trained.append(name)
        return real(dataset, name, *args, **kwargs)

    monkeypatch.setattr(runner, "train_method", counting)
    return trained


def test_an_interrupted_run_resumes_with_the_models_it_finished(
    tiny_dataset: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    clean = tmp_path / "clean"
    assert _run(tiny_dataset, clean) == 0

    out = tmp_path / "run"
    with monkeypatch.context() as m:
        trained = _count_training(m, stop_at="imu-kurtosis")
        assert _run(tiny_dataset, out) == 130
    assert trained == ["iforest-early", "audio-rms"]
    partial = partial_folder(out)
    assert not out.exists()
    assert sorted(p.parent.name for p in partial.glob(f"models/*/{TRAINING_FILE}")) == [
        "audio-rms-seed0",
        "iforest-early-seed0",
    ]
    assert "2 finished model(s) kept in" in capsys.readouterr().err

    # Without --resume the leftover folder is refused, and left as it is.
    assert _run(tiny_dataset, out) == 2
    assert "--resume" in capsys.readouterr().err and partial.is_dir()

    with monkeypatch.context() as m:
        trained = _count_training(m)
        assert _run(tiny_dataset, out, "--resume") == 0
    assert trained == ["imu-kurtosis"]
    assert "reusing iforest-early (seed 0)" in capsys.readouterr().out
    assert not partial.exists()
    # The same scores, bit for bit, and the same metrics as the run that was never interrupted.
    assert (out / "scores.csv").read_bytes() == (clean / "scores.csv").read_bytes()
    got, want = (json.loads((d / "results.json").read_text())["methods"] for d in (out, clean))
    for name in METHODS:
        assert {k: v for k, v in got[name].items() if k != "train_seconds"} == {
            k: v for k, v in want[name].items() if k != "train_seconds"
        }


def test_resume_retrains_what_another_code_or_an_unfinished_save_left(
    tiny_dataset: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "run"
    with monkeypatch.context() as m:
        _count_training(m, stop_at="imu-kurtosis")
        assert _run(tiny_dataset, out) == 130
    models = partial_folder(out) / "models"
    (models / "audio-rms-seed0" / TRAINING_FILE).unlink()  # as if killed between the model and its record
    (models / "stale-seed0").mkdir()  # a method this run does not train
    digest = resume_mod.source_digest
    with monkeypatch.context() as m:
        trained = _count_training(m)
        m.setattr(resume_mod, "source_digest", lambda *a: digest(*a) + "edited")  # the training code changed
        assert _run(tiny_dataset, out, "--resume") == 0
    assert trained == METHODS
    assert sorted(p.name for p in (out / "models").iterdir()) == [f"{n}-seed0" for n in sorted(METHODS)]


def test_the_key_names_method_seed_scale_device_dataset_and_code(monkeypatch: pytest.MonkeyPatch) -> None:
    code = resume_mod.code_digest("iforest-early")
    key = resume_mod.training_key("iforest-early", 0, "smoke", "cpu", "abc", code)
    assert key == resume_mod.training_key("iforest-early", 0, "smoke", "cpu", "abc", code)
    monkeypatch.setattr("torch.cuda.is_available", lambda: False)
    assert key == resume_mod.training_key("iforest-early", 0, "smoke", "auto", "abc", code)  # auto = cpu here
    others = [
        resume_mod.training_key("iforest-late", 0, "smoke", "cpu", "abc", code),
        resume_mod.training_key("iforest-early", 1, "smoke", "cpu", "abc", code),
        resume_mod.training_key("iforest-early", 0, "full", "cpu", "abc", code),
        resume_mod.training_key("iforest-early", 0, "smoke", "cuda", "abc", code),
        resume_mod.training_key("iforest-early", 0, "smoke", "cpu", "abd", code),
        resume_mod.training_key("iforest-early", 0, "smoke", "cpu", "abc", code + "edited"),
    ]
    monkeypatch.setattr("torch.cuda.is_available", lambda: True)
    auto = resume_mod.training_key("iforest-early", 0, "smoke", "auto", "abc", code)
    assert auto == others[3]  # auto = cuda here
    monkeypatch.setattr(resume_mod, "versions", lambda: {"torch": "0"})
    others.append(resume_mod.training_key("iforest-early", 0, "smoke", "cpu", "abc", code))
    assert len({key, *others}) == len(others) + 1


def test_a_resumed_run_regenerates_a_dataset_only_when_its_recipe_changed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "run"
    argv = ["run", "--preset", "tiny", "--out", str(out), "--methods", "audio-rms", "--no-progress"]
    with monkeypatch.context() as m:
        _count_training(m, stop_at="audio-rms")
        assert main(argv) == 130
    dataset = partial_folder(out) / "dataset"
    manifest = (dataset / "manifest.json").read_bytes()
    generated: list[Path] = []
    real_generate = runner.generate

    def recording_generate(*args: Any, **kwargs: Any) -> Path:
        generated.append(args[2])
        return real_generate(*args, **kwargs)

    monkeypatch.setattr(runner, "generate", recording_generate)
    assert main([*argv, "--resume"]) == 0
    assert generated == []  # the interrupted run's dataset, reused
    assert (out / "dataset" / "manifest.json").read_bytes() == manifest
    assert not (out / runner.DATASET_KEY_FILE).exists()

    out2 = tmp_path / "run2"
    argv2 = ["run", "--preset", "tiny", "--out", str(out2), "--methods", "audio-rms", "--no-progress"]
    with monkeypatch.context() as m:
        _count_training(m, stop_at="audio-rms")
        assert main(argv2) == 130
    (partial_folder(out2) / runner.DATASET_KEY_FILE).write_text("made by other code\n")
    generated.clear()
    assert main([*argv2, "--resume"]) == 0
    assert generated == [partial_folder(out2) / "dataset"]
    assert (out2 / "dataset" / "manifest.json").read_bytes() == manifest  # the same seed: the same bytes


def test_a_run_that_fails_before_any_model_leaves_nothing(tiny_dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert main(["run", "--seed", "5", "--data", str(tiny_dataset), "--out", str(out), "--no-progress"]) == 2
    with pytest.MonkeyPatch.context() as m:
        _count_training(m, stop_at="iforest-early")
        assert _run(tiny_dataset, out) == 130
    assert not out.exists() and not partial_folder(out).exists()


def test_demo_replace_clears_what_a_stopped_demo_left_unless_resumed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import benchmarks.commands.demo as demo

    out = tmp_path / "demo"
    seen: list[bool] = []

    def stop(args: Any) -> Path:
        seen.append(partial_folder(out).exists())
        raise KeyboardInterrupt

    monkeypatch.setattr(demo, "run_from_args", stop)
    for flags, kept in ((["--replace", "--resume"], True), (["--replace"], False)):
        (partial_folder(out) / "models").mkdir(parents=True, exist_ok=True)
        assert main(["demo", "--out", str(out), "--no-progress", *flags]) == 130
        assert seen.pop() is kept
