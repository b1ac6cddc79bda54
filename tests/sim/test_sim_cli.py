"""`msvdd-bench simulate` and `msvdd-bench scenarios` end to end."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks.cli import main
from sim import Trace
from sim.robot import asset_path


def test_simulate_preset_writes_a_loadable_trace(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "t.npz"
    assert main(["simulate", "--scenario", "fault_bearing", "--scenario-seed", "2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "fault      bearing" in text and "duration" in text and "distance" in text
    trace = Trace.load(out)
    assert trace.scenario_name == "fault_bearing" and trace.seed == 2
    assert trace.non_finite_fields() == []
    assert trace.imu_acc.shape == (len(trace.imu_time), 3) and trace.imu_rate == 200.0


def test_simulate_scenario_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "wall.npz"
    source = asset_path("scenarios/collision_wall.toml")
    assert main(["simulate", "--scenario", source, "--scenario-seed", "9", "--out", str(out)]) == 0
    trace = Trace.load(out)
    assert trace.seed == 9 and "wall" in trace.contacts.obstacle_kind
    assert "wall" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenario", "nope"], "--scenario = 'nope' is unknown; allowed: a .toml file or one of nominal"),
        (["--scenario", "nominal_indoor", "--scenario-seed", "-3"], "--scenario-seed = -3 is invalid"),
        (["--scenario", "missing.toml"], "scenario file not found: missing.toml"),
    ],
)
def test_simulate_bad_input_exits_2_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    out = tmp_path / "x.npz"
    assert main(["simulate", *args, "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_simulate_refuses_bad_scenario_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nseed = 1\nduration = 5.0\nsurface = "ice"\n')
    out = tmp_path / "out" / "x.npz"
    assert main(["simulate", "--scenario", str(bad), "--out", str(out)]) == 2
    assert "surface = 'ice' is invalid; allowed: tile, carpet" in capsys.readouterr().err
    assert not out.parent.exists()


def test_scenarios_lists_presets_kinds_and_parameters(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["scenarios", "--scenario-seed", "3"]) == 0
    text = capsys.readouterr().out
    assert "presets (scenario seed 3; `msvdd-bench simulate --scenario NAME --scenario-seed N" in text
    for word in (
        "collision_pedestrian",
        "fault_motor_degradation",
        "BPFO",
        "soft_body",
        "kerb_ramp",
        "gravel",
    ):
        assert word in text
