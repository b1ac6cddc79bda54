"""The CLI: fast help with examples, no empty defaults, `methods`, `--device`, `--no-progress`, bad models."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import NoReturn

import pytest

from benchmarks.cli import build_parser, main
from benchmarks.command import DEVICES, SCALES

HEAVY = ("torch", "mujoco", "sklearn", "scipy", "rerun", "matplotlib", "benchmarks.methods", "sim")


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in build_parser()._actions if a.dest == "command")
    return dict(action.choices)  # type: ignore[arg-type]


def test_building_the_parser_and_every_help_imports_nothing_heavy() -> None:
    code = (
        "import sys, contextlib, io\n"
        "from benchmarks.cli import build_parser\n"
        "parser = build_parser()\n"
        "sub = next(a for a in parser._actions if a.dest == 'command')\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    parser.print_help()\n"
        "    for p in sub.choices.values(): p.print_help()\n"
        f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_every_help_has_an_example_and_no_empty_default() -> None:
    for name, parser in _subparsers().items():
        text = parser.format_help()
        assert f"example:\n  msvdd-bench {name}" in text, name
        assert "(default: None)" not in text and "(default: False)" not in text, name
        assert not re.search(r"\(default[^)]*\)\s+\(default", text), name  # never two defaults
    assert "(default: 0)" in _subparsers()["train"].format_help()  # a meaningful default is still shown


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--scenario", "nominal_indoor", "--out", "x.npz", "--seed", "1"],
        ["scenarios", "--seed", "1"],
        ["synth", "--trace", "t.npz", "--out", "a.flac", "--seed", "1"],
        ["run", "--out", "r", "--seeds", "0"],
        ["demo", "--out", "r", "--seeds", "0"],
    ],
)
def test_seed_flags_have_one_meaning_and_no_old_names(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """`--seed` is a dataset seed only (the scenario seed is `--scenario-seed`, the render seed
    `--render-seed`), and `--seeds` is no alias of `--train-seeds`: argparse refuses the old names."""
    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args(argv)
    assert exit_info.value.code == 2
    assert f"error: unrecognized arguments: {argv[-2]} {argv[-1]}\n" in capsys.readouterr().err


def test_the_new_seed_flag_names_parse() -> None:
    parser = build_parser()
    assert parser.parse_args(["run", "--out", "r", "--train-seeds", "0", "1"]).train_seeds == [0, 1]
    assert parser.parse_args(["demo", "--out", "r", "--train-seeds", "2"]).train_seeds == [2]
    assert parser.parse_args(["scenarios", "--scenario-seed", "3"]).scenario_seed == 3
    synth = parser.parse_args(["synth", "--trace", "t.npz", "--out", "a.flac", "--render-seed", "4"])
    assert synth.render_seed == 4


def test_perf_stage_lists_every_stage() -> None:
    from benchmarks.commands.perf import stages

    help_text = _subparsers()["perf"].format_help()
    for stage in [*stages(), "all"]:
        assert stage in help_text
    with pytest.raises(SystemExit):
        build_parser().parse_args(["perf", "--stage", "nope", "--json", "x.json"])


def test_device_and_no_progress_where_training_runs() -> None:
    from benchmarks.methods.base import SCALES as METHOD_SCALES
    from benchmarks.methods.registry import DEVICES as REGISTRY_DEVICES

    assert DEVICES == REGISTRY_DEVICES and SCALES == METHOD_SCALES
    parser = build_parser()
    required = {
        "train": ["--data", "d", "--method", "m", "--out", "o"],
        "run": ["--out", "o"],
        "demo": ["--out", "o"],
    }
    for command, rest in required.items():
        assert parser.parse_args([command, *rest, "--device", "auto"]).device == "auto"
        assert parser.parse_args([command, *rest]).device == "cpu"
    for command in ("generate", "train", "evaluate", "run", "demo", "audit"):
        assert "--no-progress" in _subparsers()[command].format_help(), command


def test_make_passes_progress_to_the_training_config() -> None:
    from benchmarks.methods import make

    assert make("msvdd", seed=0, scale="smoke").config.progress is False  # type: ignore[attr-defined]
    assert make("msvdd", seed=0, scale="smoke", progress=True).config.progress is True  # type: ignore[attr-defined]
    assert make("dae", seed=0, scale="short", progress=False).config.progress is False  # type: ignore[attr-defined]
    assert make("dcase-ae", seed=0, scale="smoke", progress=True).config.progress is True  # type: ignore[attr-defined]
    make("iforest-early", seed=0, scale="smoke", progress=True)  # no bar: ignored


def test_methods_lists_every_method_without_building_one(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from benchmarks.methods import registry

    def boom(seed: int, scale: str, device: str) -> NoReturn:
        raise AssertionError("listing built a model")

    for name, spec in list(registry._REGISTRY.items()):
        monkeypatch.setitem(registry._REGISTRY, name, dataclasses.replace(spec, factory=boom))
    assert main(["methods", "--json"]) == 0
    entries = {e["name"]: e for e in json.loads(capsys.readouterr().out)}
    assert list(entries) == registry.names()
    assert entries["iforest-late"]["paper"] == ["Table I: IF (late fusion)"]
    assert "Table II: full model" in entries["msvdd"]["paper"]
    assert entries["audio-rms"]["paper"] == [] and entries["audio-rms"]["family"] == "naive"
    assert main(["methods", "--family", "deep"]) == 0
    table = capsys.readouterr().out
    assert "dsvdd" in table and "iforest-early" not in table and "Table I: DAGMM" in table
    assert main(["methods", "--family", "nope"]) == 2
    assert "family 'nope' is unknown" in capsys.readouterr().err


def _model_folder(root: Path, method: str, model_bytes: bytes, meta: bytes | None = None) -> Path:
    folder = root / method
    folder.mkdir()
    info = {"method": method, "format_version": 1, "model_file": "model.bin"}
    (folder / "method.json").write_bytes(meta if meta is not None else json.dumps(info).encode())
    (folder / "model.bin").write_bytes(model_bytes)
    return folder


def test_a_model_file_that_is_not_ours_is_one_line(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    noise = os.urandom(4096)
    cases = [
        (_model_folder(tmp_path, "msvdd", noise), "model.bin is not an M-SVDD model file (expected"),
        (
            _model_folder(tmp_path, "iforest-early", noise),
            "model.bin is not a msvdd-bench model file (expected",
        ),
        (
            _model_folder(tmp_path, "dae", noise, meta=noise),
            "method.json is not a msvdd-bench model file (expected",
        ),
    ]
    cases.append((cases[0][0] / "model.bin", "model.bin is not a msvdd-bench model folder (expected"))
    for i, (model, says) in enumerate(cases):
        out = tmp_path / f"run{i}"
        argv = [
            "evaluate",
            "--data",
            str(tiny_dataset),
            "--model",
            str(model),
            "--out",
            str(out),
            "--no-progress",
        ]
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and says in err and "weights_only" not in err, err
        assert str(model) in err and not out.exists()


def test_train_and_evaluate_show_progress_unless_told_not_to(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = tmp_path / "rms"
    assert main(["train", "--data", str(tiny_dataset), "--method", "audio-rms", "--out", str(model)]) == 0
    assert "loading train" in capsys.readouterr().err
    assert (
        main(["evaluate", "--data", str(tiny_dataset), "--model", str(model), "--out", str(tmp_path / "r")])
        == 0
    )
    err = capsys.readouterr().err
    assert "verifying sha256" in err and "loading test" in err and "scoring" in err
    quiet = tmp_path / "rms-quiet"
    argv = [
        "train",
        "--data",
        str(tiny_dataset),
        "--method",
        "audio-rms",
        "--out",
        str(quiet),
        "--no-progress",
    ]
    assert main(argv) == 0
    assert main(["evaluate", "--data", str(tiny_dataset), "--model", str(quiet), "--out", str(tmp_path / "q"),
                 "--no-progress"]) == 0  # fmt: skip
    assert capsys.readouterr().err == ""
