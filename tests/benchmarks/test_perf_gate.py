"""`msvdd-bench perf`'s ratios and its baseline gate, on synthetic figures and fake clocks: nothing timed."""

from __future__ import annotations

import itertools
import json
import types
from pathlib import Path
from typing import Any

import pytest

from benchmarks.cli import main
from benchmarks.docs_pages import read_perf
from benchmarks.errors import UserError
from benchmarks.perf.base import REFERENCE_BLOCK, PerfStage, best_time, fft_reference_s
from benchmarks.perf_gate import RatioCheck, compare_perf


def _doc(quick: bool = False, ratios: dict[str, str] | None = None, **figures: float) -> dict[str, Any]:
    doc: dict[str, Any] = {"machine": {"cpus": 2}, "quick": quick, "command": "x", "descriptions": {}}
    if ratios is not None:
        doc["ratios"] = ratios
    return {**doc, **figures}


def test_a_cost_ratio_regresses_when_more_than_the_limit_above_the_baseline() -> None:
    at_limit = RatioCheck("audio_vs_fft_indoor", "lower", 10.0, 12.0, 0.2)
    over = RatioCheck("audio_vs_fft_indoor", "lower", 10.0, 12.5, 0.2)
    faster = RatioCheck("audio_vs_fft_indoor", "lower", 10.0, 5.0, 0.2)
    assert at_limit.slowdown == pytest.approx(1.2) and at_limit.limit == pytest.approx(12.0)
    assert not at_limit.regressed and over.regressed and not faster.regressed
    assert over.slowdown == pytest.approx(1.25) and faster.slowdown == pytest.approx(0.5)


def test_a_speed_up_regresses_when_it_drops_below_the_baseline_over_the_limit() -> None:
    at_limit = RatioCheck("mcd_speedup_vs_sklearn", "higher", 18.0, 15.0, 0.2)
    over = RatioCheck("mcd_speedup_vs_sklearn", "higher", 18.0, 14.0, 0.2)
    assert at_limit.limit == pytest.approx(15.0) and not at_limit.regressed
    assert over.regressed and over.slowdown == pytest.approx(18.0 / 14.0)
    assert RatioCheck("x", "higher", 18.0, 0.0, 0.2).regressed  # a zero speed-up: infinitely slower
    assert RatioCheck("x", "lower", 1.0, float("nan"), 0.2).regressed


def test_the_message_names_the_figure_both_values_and_the_limit() -> None:
    line = RatioCheck("generate_vs_fft", "lower", 40.0, 50.0, 0.2).message()
    assert "\n" not in line and line.startswith("REGRESSED: generate_vs_fft")
    assert "40 (baseline)" in line and "50 (this run)" in line and "x1.25 slower" in line
    assert "limit <= 48" in line and "(x1.2)" in line
    ok = RatioCheck("mcd_speedup_vs_sklearn", "higher", 18.0, 20.0, 0.2).message()
    assert ok.startswith("ok: ") and "limit >= 15" in ok


def test_compare_gates_only_the_ratio_figures_both_runs_have() -> None:
    ratios = {
        "audio_vs_fft_indoor": "lower",
        "sim_overhead_vs_bare": "lower",
        "mcd_speedup_vs_sklearn": "higher",
    }
    baseline = _doc(audio_vs_fft_indoor=10.0, audio_rtf=100.0, mcd_speedup_vs_sklearn=18.0)
    # the absolute rate halves (a slower machine), the ratios hold: not a regression
    candidate = _doc(ratios=ratios, audio_vs_fft_indoor=10.5, audio_rtf=50.0, sim_overhead_vs_bare=1.1,
                     mcd_speedup_vs_sklearn=17.0)  # fmt: skip
    checks = compare_perf(baseline, candidate)
    assert [c.figure for c in checks] == ["audio_vs_fft_indoor", "mcd_speedup_vs_sklearn"]
    assert not any(c.regressed for c in checks)
    # the directions come from the baseline when this run's JSON has none
    checks = compare_perf(_doc(ratios=ratios, sim_overhead_vs_bare=1.0), _doc(sim_overhead_vs_bare=1.3))
    assert [c.figure for c in checks] == ["sim_overhead_vs_bare"] and checks[0].regressed


@pytest.mark.parametrize(
    ("baseline", "candidate", "max_slowdown", "says"),
    [
        (_doc(a=1.0), _doc(ratios={"a": "lower"}, b=1.0), 0.2, "no ratio figure in common"),
        (_doc(quick=True, a=1.0), _doc(ratios={"a": "lower"}, a=1.0), 0.2, "--quick"),
        (_doc(a=1.0), _doc(ratios={"a": "sideways"}, a=1.0), 0.2, "allowed: lower, higher"),
        (_doc(a=1.0), _doc(ratios={"a": "lower"}, a=1.0), -0.1, ">= 0"),
    ],
)
def test_runs_that_cannot_be_compared_are_bad_input(
    baseline: dict[str, Any], candidate: dict[str, Any], max_slowdown: float, says: str
) -> None:
    with pytest.raises(UserError, match=says):
        compare_perf(baseline, candidate, max_slowdown)


def _fake_stage(monkeypatch: pytest.MonkeyPatch, figures: dict[str, float]) -> None:
    stage = PerfStage(
        "sim",
        lambda quick: dict(figures),
        {k: f"meaning of {k}" for k in figures},
        {"sim_overhead_vs_bare": "lower", "mcd_speedup_vs_sklearn": "higher"},
    )
    monkeypatch.setattr("benchmarks.commands.perf.stages", lambda: {"sim": stage})


def test_perf_with_a_baseline_exits_1_with_one_line_per_regressed_figure(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    baseline = tmp_path / "old.json"
    old = _doc(sim_overhead_vs_bare=1.1, mcd_speedup_vs_sklearn=18.0, sim_rtf=150.0)
    baseline.write_text(json.dumps(old))
    _fake_stage(monkeypatch, {"sim_overhead_vs_bare": 1.5, "mcd_speedup_vs_sklearn": 17.0, "sim_rtf": 10.0})
    out = tmp_path / "new.json"
    code = main(["perf", "--stage", "sim", "--json", str(out), "--baseline", str(baseline)])
    printed = capsys.readouterr().out.splitlines()
    assert code == 1
    regressed = [line for line in printed if line.startswith("REGRESSED")]
    assert len(regressed) == 1 and "sim_overhead_vs_bare 1.1 (baseline) -> 1.5 (this run)" in regressed[0]
    assert "limit <= 1.32" in regressed[0]
    assert any("1 of 2 ratio figures more than 20 % slower" in line for line in printed)
    written = json.loads(out.read_text())
    assert written["ratios"] == {"sim_overhead_vs_bare": "lower", "mcd_speedup_vs_sklearn": "higher"}
    # a looser limit passes the same figures
    argv = ["perf", "--stage", "sim", "--json", str(out), "--baseline", str(baseline)]
    assert main([*argv, "--max-slowdown", "0.5"]) == 0


def test_perf_refuses_a_missing_or_mismatched_baseline_before_measuring(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    def never(quick: bool) -> dict[str, float]:
        raise AssertionError("measured before the baseline was checked")

    monkeypatch.setattr(
        "benchmarks.commands.perf.stages", lambda: {"sim": PerfStage("sim", never, {}, {"a": "lower"})}
    )
    out = tmp_path / "new.json"
    argv = ["perf", "--stage", "sim", "--json", str(out), "--baseline"]
    assert main([*argv, str(tmp_path / "none.json")]) == 2
    quick = tmp_path / "quick.json"
    quick.write_text(json.dumps(_doc(quick=True, a=1.0)))
    assert main([*argv, str(quick)]) == 2


def test_read_perf_keeps_the_ratio_directions_out_of_the_figures(tmp_path: Path) -> None:
    path = tmp_path / "perf.json"
    path.write_text(json.dumps(_doc(ratios={"a": "lower"}, a=2.0, b=3.0)))
    assert read_perf(path).figures == {"a": 2.0, "b": 3.0}


def test_the_reference_kernel_runs_on_the_clock_it_is_given() -> None:
    ticks = itertools.count()
    calls: list[int] = []

    def clock() -> float:
        calls.append(1)
        return 0.25 * next(ticks)

    assert fft_reference_s(1000, repeats=3, clock=clock) == pytest.approx(0.25)
    assert len(calls) == 6


def test_a_long_reference_is_one_block_scaled_by_its_length() -> None:
    clock = _FakeTime(0.5)  # every reading 0.5 s later: each convolution takes 0.5 s
    assert fft_reference_s(3 * REFERENCE_BLOCK, channels=1, repeats=1, clock=clock.read) == pytest.approx(1.5)
    assert clock.now == pytest.approx(1.0)  # one block convolved (two readings), not three


class _FakeTime:
    """A clock that advances `step` seconds per reading, as `time.process_time` and `time.perf_counter`."""

    def __init__(self, step: float) -> None:
        self.now, self.step = 0.0, step

    def read(self) -> float:
        self.now += self.step
        return self.now

    process_time = perf_counter = read


def test_the_audio_stage_divides_each_render_by_a_reference_of_its_length_measured_in_the_run(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import synth_audio
    from benchmarks.perf import audio

    events: list[tuple[str, object]] = []

    def reference(n_samples: int, channels: int = 2, repeats: int = 3, clock: object = None) -> float:
        events.append(("reference", n_samples))
        return 0.5

    monkeypatch.setattr(audio, "workload", lambda duration, environment: environment)
    monkeypatch.setattr(synth_audio, "render", lambda trace, config, seed: events.append(("render", trace)))
    monkeypatch.setattr(audio, "fft_reference_s", reference)
    monkeypatch.setattr(audio, "time", _FakeTime(0.1))  # every render takes 0.1 s on the fake clock
    figures = audio.STAGE.measure(True)
    assert ("reference", 2 * 44100) in events and events.count(("reference", 2 * 44100)) == 2
    assert events.index(("reference", 88200)) < events.index(("render", "outdoor"))  # same run, same process
    assert figures["audio_vs_fft_indoor"] == pytest.approx(0.1 / 0.5)
    assert figures["audio_vs_fft"] == pytest.approx(0.2)
    assert figures["audio_fft_reference_rtf"] == pytest.approx(2.0 / 0.5)
    assert set(audio.STAGE.ratios) <= set(figures)


def test_the_generate_stage_divides_by_a_reference_as_long_as_its_audio(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from benchmarks.perf import generate

    lengths: list[int] = []
    values = iter([0.4, 0.2])  # before and after the episodes: the faster one counts

    def reference(n_samples: int, channels: int = 2, repeats: int = 3, clock: object = None) -> float:
        lengths.append(n_samples)
        return next(values)

    built: list[tuple[str, float]] = []
    monkeypatch.setattr(
        generate, "build_episode", lambda spec, root: built.append((spec.episode_id, spec.options.duration))
    )
    monkeypatch.setattr(generate, "fft_reference_s", reference)
    monkeypatch.setattr(generate, "time", types.SimpleNamespace(perf_counter=_FakeTime(1.0).read))
    figures = generate.STAGE.measure(True)
    assert lengths == [3 * 10 * 44100] * 2
    # the first episode, as long as the timed ones, is built before them and counts in its own figure, not
    # in the rate
    assert built == [(name, 10.0) for name in ("perf-first", "perf-nominal", "perf-collision", "perf-fault")]
    assert figures["generate_first_episode_s"] == pytest.approx(1.0)
    assert figures["generate_vs_fft"] == pytest.approx(1.0 / 0.2)
    assert figures["generate_rtf"] == pytest.approx(30.0)


def test_every_stage_gates_only_figures_it_describes() -> None:
    from benchmarks.commands.perf import stages

    for stage in stages().values():
        assert set(stage.ratios) <= set(stage.describe), stage.name
        assert set(stage.ratios.values()) <= {"lower", "higher"}, stage.name


def test_the_feature_extraction_is_divided_by_a_reference_as_long_as_the_windows_audio(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from benchmarks.perf import baselines

    lengths: list[int] = []

    def reference(n_samples: int, channels: int = 2, repeats: int = 3, clock: object = None) -> float:
        lengths.append(n_samples)
        return 0.5

    monkeypatch.setattr(baselines, "fft_reference_s", reference)
    monkeypatch.setattr(baselines, "time", types.SimpleNamespace(perf_counter=_FakeTime(1.0).read))
    figures = baselines.STAGE.measure(True)
    assert lengths == [100 * 8820]  # 100 toy windows of 8820 stereo samples
    assert figures["features_vs_fft"] == pytest.approx(1.0 / 0.5)


def test_best_time_takes_the_fastest_repeat_after_an_untimed_warm_up() -> None:
    costs = {-1: 100.0, 0: 3.0, 1: 2.0, 2: 5.0}  # the warm-up call is the slowest and is not timed
    clock = _FakeTime(0.0)
    calls: list[int] = []

    def fn(r: int) -> None:
        calls.append(r)
        clock.now += costs[r]

    assert best_time(fn, 3, clock.read) == pytest.approx(2.0)
    assert calls == [-1, 0, 1, 2]
    calls.clear()
    assert best_time(fn, 1, clock.read, warm=False) == pytest.approx(3.0) and calls == [0]
