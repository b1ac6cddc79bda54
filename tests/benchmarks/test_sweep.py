"""`msvdd-bench sweep`: a two-point sweep end to end, resuming, bad specs, the axes' dataset knobs."""

from __future__ import annotations

import dataclasses
import json
import re
import tomllib
from pathlib import Path
from typing import Any

import pytest

from benchmarks.cli import main
from benchmarks.dataset import open_dataset, plan_episodes
from benchmarks.errors import UserError
from benchmarks.presets import get_preset
from benchmarks.sweeps.spec import AXES, load_spec, parse_spec, shipped_specs
from sim import vocab
from sim.random_scenarios import BRAKE_DECEL, ScenarioOptions, draw_scenario, scale_speeds
from sim.scenario import MAX_WHEEL_SPEED, ScenarioError

METHODS = ("gaussian-early", "audio-rms")

SPEC = """
title = "tiny severity"
base = "tiny"
seeds = [0]
methods = ["gaussian-early", "audio-rms"]
oracle = true
axis = "severity"
values = [0.3, 1.0]

# Smaller than tiny (two short training sequences, one fault kind), two episodes per test class still.
[overrides]
nominal_train = 2
nominal_val = 0
nominal_train_duration_s = 16.0
nominal_test_duration_s = 8.0
collision_duration_s = 10.0
fault_kinds = ["out_of_round"]
faults_per_kind_wheel = 2
fault_duration_s = 10.0
"""


pytestmark = pytest.mark.xdist_group("sweep")  # with `pytest -n`: one worker, the module fixtures once


@pytest.fixture(scope="module")
def sweep(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(spec file, sweep folder) of the two-point sweep, run once through the CLI with two local workers."""
    root = tmp_path_factory.mktemp("sweep")
    spec = root / "spec.toml"
    spec.write_text(SPEC)
    out = root / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "2", "--no-progress"]) == 0
    return spec, out


def test_a_two_point_sweep_writes_tables_and_plots_with_intervals(sweep: tuple[Path, Path]) -> None:
    _, out = sweep
    doc = json.loads((out / "sweep.json").read_text())
    assert [p["label"] for p in doc["points"]] == ["0.3", "1"]
    for point, severity in zip(doc["points"], (0.3, 1.0), strict=True):
        assert point["preset"]["severity"] == [severity, severity]
        (run,) = point["runs"]
        assert set(run["methods"]) == {*METHODS, "oracle"}
        assert run["normal_episodes"] >= 2 and run["anomalous_episodes"] >= 2
        for method in METHODS:
            for key in ("auc", "auc_collision", "auc_mechanical", "auc_out_of_round"):
                iv = run["methods"][method][key]
                assert 0.0 <= iv["low"] <= iv["value"] <= iv["high"] <= 1.0, (method, key, iv)
        # The oracle scores faults per kind only: this dataset's one kind, nothing else.
        assert set(run["methods"]["oracle"]) == {"auc", "auc_collision", "auc_mechanical", "auc_out_of_round",
                                                 "train_seconds"}  # fmt: skip
        iv = run["methods"]["oracle"]["auc_out_of_round"]
        assert 0.0 <= iv["low"] <= iv["value"] <= iv["high"] <= 1.0, iv
        assert run["methods"]["oracle"]["auc"]["value"] is None
        dataset = open_dataset(out / run["folder"] / "dataset")  # a whole dataset, verified
        assert (
            dataset.preset.severity == (severity, severity) and dataset.preset.name == point["preset"]["name"]
        )
        assert run["dataset_sha256"] == dataset.fingerprint
    faults = [
        e.spec
        for p in doc["points"]
        for e in open_dataset(out / p["runs"][0]["folder"] / "dataset", verify=False).manifest.episodes
        if e.spec.category == "fault"
    ]
    assert {e.options.severity for e in faults} == {(0.3, 0.3), (1.0, 1.0)}
    text = (out / "sweep.md").read_text()
    assert "| severity | dataset seed | gaussian-early | audio-rms |" in text
    assert "| severity | dataset seed | gaussian-early | audio-rms | oracle |" in text  # per kind
    assert "## AUC, out_of_round faults against normal" in text
    assert not re.search(r"## AUC, (flat_spot|bearing|loose_wheel|motor_degradation)", text)
    for key in ("auc", "auc_collision", "auc_mechanical", "auc_out_of_round"):
        png = (out / "figures" / f"{key}.png").read_bytes()
        assert png.startswith(b"\x89PNG") and len(png) > 5000
    assert not [p for p in out.rglob(".*") if p.name != ".gitignore"]  # no temporary file left


def test_resume_reuses_finished_points_and_an_existing_folder_needs_it(
    sweep: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    spec, out = sweep
    results = sorted(out.glob("points/*/results.json"))
    stamps = [p.stat().st_mtime_ns for p in results]
    before = json.loads((out / "sweep.json").read_text())["points"]
    assert main(["sweep", str(spec), "--out", str(out), "--no-progress"]) == 2
    assert "exists already" in capsys.readouterr().err
    assert main(["sweep", str(spec), "--out", str(out), "--resume", "--workers", "1", "--no-progress"]) == 0
    assert [p.stat().st_mtime_ns for p in results] == stamps  # nothing ran again
    assert json.loads((out / "sweep.json").read_text())["points"] == before
    other = spec.with_name("other.toml")
    other.write_text(SPEC.replace("[0.3, 1.0]", "[0.3, 0.9]"))
    assert main(["sweep", str(other), "--out", str(out), "--resume", "--no-progress"]) == 2
    assert "resume with the same spec" in capsys.readouterr().err


def test_run_takes_a_sweep_points_dataset(sweep: tuple[Path, Path], tmp_path: Path) -> None:
    _, out = sweep
    data = out / "points" / "p00-seed0" / "dataset"
    args = [
        "run",
        "--data",
        str(data),
        "--methods",
        "audio-rms",
        "--out",
        str(tmp_path / "r"),
        "--no-progress",
    ]
    assert main(args) == 0
    assert json.loads((tmp_path / "r" / "results.json").read_text())["preset"] == "tiny+severity=0.3"


def _doc(**changes: Any) -> dict[str, Any]:
    doc = tomllib.loads(SPEC)
    for key, value in changes.items():
        if value is None:
            doc.pop(key)
        else:
            doc[key] = value
    return doc


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"axis": "speed"},
            "axis = 'speed' is invalid; allowed: severity, snr_db, drive_speed, approach_speed",
        ),
        ({"values": [1.5]}, "values[0] = 1.5 is invalid; allowed: a number or [low, high] with 0 <= low"),
        ({"values": [0.2, 0.2]}, "values = [0.2, 0.2] is invalid; allowed: distinct values"),
        ({"valuez": [0.2]}, "valuez = [0.2] is invalid; allowed: the keys title, base"),
        ({"methods": None}, "missing key 'methods'"),
        ({"base": "huge"}, "unknown preset 'huge'; allowed: tiny"),
        ({"labels": ["a"]}, "labels = ['a'] is invalid; allowed: a list of 2 strings"),
        ({"seeds": [-1]}, "seeds = [-1] is invalid; allowed: a non-empty list of integers >= 0"),
        ({"scale": "huge"}, "scale = 'huge' is invalid; allowed: smoke, short, full"),
        (
            {"axis": "drive_speed", "values": [3.0]},
            "values[0] = 3.0 is invalid; allowed: a number from 0.5 to 2",
        ),
        (
            {"axis": "test_surfaces", "values": [["ice"]]},
            "allowed: a non-empty list of names from tile, carpet",
        ),
        ({"axis": "test_units", "values": [[1, -2]]}, "allowed: a non-empty list of robot unit ids"),
        (
            {"overrides": {"nominal_tset": 3}},
            "overrides.nominal_tset = 3 is invalid; allowed: a preset field",
        ),
        (
            {"overrides": {"severity": [0.1, 0.2]}},
            "allowed: not the swept field (axis severity sets severity",
        ),
        (
            {"overrides": {"nominal_test": "many"}},
            "overrides.nominal_test = 'many' is invalid; allowed: an integer",
        ),
        ({"overrides": {"seeds": [1]}}, "not overridable (use the spec's `train_seeds`)"),
        ({"overrides": {"train_surfaces": ["ice"]}}, "train_surfaces has 'ice'; allowed: tile, carpet"),
        (
            {"overrides": {"fault_kinds": ["rust"]}},
            "fault_kinds = ['rust'] is invalid; allowed: names from flat_spot",
        ),
    ],
)
def test_a_bad_spec_names_the_key_the_value_and_what_is_allowed(
    changes: dict[str, Any], message: str
) -> None:
    with pytest.raises(UserError, match=re.escape(message)) as info:
        parse_spec(_doc(**changes), "bad.toml")
    assert str(info.value).startswith("bad.toml: ") and "\n" not in str(info.value)


def test_a_bad_spec_is_one_line_on_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = tmp_path / "bad.toml"
    spec.write_text(SPEC.replace('axis = "severity"', 'axis = "weather"'))
    assert main(["sweep", str(spec), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "axis = 'weather' is invalid" in err and str(spec) in err
    spec.write_text(SPEC.replace('"audio-rms"]', '"nope"]'))
    assert main(["sweep", str(spec), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    assert "nope" in capsys.readouterr().err and not (tmp_path / "o").exists()
    assert main(["sweep", "no-such-spec", "--out", str(tmp_path / "o")]) == 2
    assert "sweep spec not found: no-such-spec" in capsys.readouterr().err


def test_every_shipped_spec_loads_and_plans() -> None:
    names = shipped_specs()
    assert {"severity", "snr", "drive_speed", "approach_speed", "unseen_units", "unseen_surfaces"} <= set(
        names
    )
    for name in names:
        spec = load_spec(name)
        assert spec.axis.name in AXES
        for point in spec.points():
            assert getattr(point.preset, spec.axis.field) is not None
            for seed in spec.seeds:
                plan_episodes(point.preset, seed)


def test_domain_shift_presets_put_train_and_test_on_their_floors() -> None:
    tiny = get_preset("tiny")
    shifted = dataclasses.replace(tiny, train_surfaces=("tile", "carpet"), test_surfaces=("grass", "gravel"))
    plan = plan_episodes(shifted, 0)
    assert {s.options.surface for s in plan if s.split != "test"} == {"tile", "carpet"}
    assert {s.options.surface for s in plan if s.split == "test"} == {"grass", "gravel"}
    assert {s.category for s in plan if s.split == "test"} == {"nominal", "collision", "fault"}
    outdoor = dataclasses.replace(tiny, train_environments=("indoor",), test_environments=("outdoor",))
    plan = plan_episodes(outdoor, 0)
    assert {s.options.environment for s in plan if s.split != "test"} == {"indoor"}
    assert {s.options.environment for s in plan if s.split == "test"} == {"outdoor"}
    assert plan_episodes(tiny, 0)[-1].options.environment is None  # unrestricted: the sampler draws as before
    with pytest.raises(UserError, match="obstacle kind 'door' stands only indoor"):
        plan_episodes(dataclasses.replace(outdoor, obstacle_kinds=("door",)), 0)
    with pytest.raises(UserError, match="no floor is in both test_environments"):
        plan_episodes(dataclasses.replace(tiny, test_environments=("indoor",), test_surfaces=("grass",)), 0)


def test_speed_factors_scale_cruise_and_obstacle_legs_and_keep_near_miss_margins() -> None:
    scenario = draw_scenario(
        11, "collision", ScenarioOptions(duration=40.0, obstacle_kind="wall", surface=None)
    )
    assert scale_speeds(scenario) is scenario
    faster = scale_speeds(scenario, drive=1.5, approach=0.5)
    pairs = list(zip(scenario.route.waypoints, faster.route.waypoints, strict=True))
    assert any(w.ram >= 0 and w.stop_short == 0 for w, _ in pairs)  # the hit
    for old, new in pairs:
        if old.reverse:
            assert new == old
        elif old.ram >= 0:
            assert new.speed == pytest.approx(0.5 * old.speed)
            if old.stop_short > 0:  # a near miss: the margin beyond the braking distance is kept
                margin = old.stop_short - old.speed**2 / (2 * BRAKE_DECEL)
                assert new.stop_short - new.speed**2 / (2 * BRAKE_DECEL) == pytest.approx(margin)
        else:
            assert new.speed == pytest.approx(min(1.5 * old.speed, MAX_WHEEL_SPEED))
    with pytest.raises(
        ScenarioError, match=re.escape("drive speed factor = 0.1 is invalid; allowed: 0.5 to 2.0")
    ):
        scale_speeds(scenario, drive=0.1)
    assert set(vocab.SURFACES) == set(AXES["test_surfaces"].allowed)


def test_docs_write_a_sweeps_curves_per_fault_kind_from_its_folder(
    sweep: tuple[Path, Path], tmp_path: Path
) -> None:
    from benchmarks.docs_pages import DocsTargets, render
    from benchmarks.sweeps.run import read_sweep
    from benchmarks.uncertainty import Interval, format_interval

    _, out = sweep
    page = tmp_path / "sweeps.md"
    page.write_text("head\n<!-- severity:begin -->\nSTALE\n<!-- severity:end -->\ntail\n")
    targets = DocsTargets(results=tmp_path / "results.md", readme=None, detectors=None, sweeps=page)
    text = render([], None, targets, sweep=read_sweep(out))[page]
    assert text.startswith("head\n<!-- severity:begin -->\n") and text.endswith(
        "<!-- severity:end -->\ntail\n"
    )
    assert "STALE" not in text and "**AUC, out_of_round faults against normal**" in text
    assert "| severity | dataset seed | gaussian-early | audio-rms | oracle |" in text
    doc = json.loads((out / "sweep.json").read_text())
    for point in doc["points"]:
        methods = point["runs"][0]["methods"]
        ivs = [methods[m]["auc_out_of_round"] for m in ("gaussian-early", "audio-rms", "oracle")]
        cells = [format_interval(Interval(**{k: float(v) for k, v in iv.items()})) for iv in ivs]
        assert f"| {point['label']} | 0 | {' | '.join(cells)} |" in text
