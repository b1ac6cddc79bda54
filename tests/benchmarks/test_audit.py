"""The audit: its scalars against analytic oracles, and every probe computed on the tiny dataset."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from benchmarks import fault_indicators
from benchmarks.audit import FAIL, PASS, REPORT, oracle, read, run_audit, stored_audit, write
from benchmarks.audit.core import context_starts
from benchmarks.audit.report import ProbeRow
from benchmarks.audit.signals import (
    acceleration_peak,
    audio_levels,
    behaviour,
    clipped,
    forward_speed,
    level_db,
    repetition,
)
from benchmarks.cli import main
from benchmarks.dataset import open_dataset
from benchmarks.episode import read_trace
from sim.trace import RobotInfo
from sim.vocab import COLLISION, NORMAL
from synth_audio.faults import band_power


def test_forward_speed_follows_the_heading() -> None:
    yaw = np.array([0.0, np.pi / 2, np.pi])
    quat = np.stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)], axis=1)
    vel = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(forward_speed(quat, vel), [1.0, 2.0, -1.0], atol=1e-12)


def test_behaviour_fractions_and_peaks_of_a_known_profile() -> None:
    rate = 400.0
    t = np.arange(0, 4.0, 1 / rate)
    # 1 s forward at 0.5 m/s, brake linearly to 0 in 0.25 s (2 m/s^2), turn in place at 1 rad/s for 0.5 s,
    # stand 0.25 s, then 2 s reversing at 0.2 m/s.
    v = np.select([t < 1.0, t < 1.25, t < 2.0], [0.5, 0.5 - 2.0 * (t - 1.0), 0.0], -0.2)
    w = np.where((t >= 1.25) & (t < 1.75), 1.0, 0.0)
    out = behaviour(v, w, rate, np.array([0.0, 2.0]))
    assert out["reversing"][0] == pytest.approx(0.0)
    assert out["reversing"][1] == pytest.approx(1.0)
    assert out["turning_in_place"][0] == pytest.approx(0.5 / 2.0, abs=0.01)
    # Standing: below 0.05 m/s from 1.225 s, not turning: 1.225-1.25 s and 1.75-2.0 s.
    assert out["standing"][0] == pytest.approx(0.275 / 2.0, abs=0.01)
    assert out["standing"][1] == pytest.approx(0.0, abs=0.01)
    assert out["peak_deceleration"][0] == pytest.approx(2.0, rel=0.05)
    assert out["yaw_rate_peak"].tolist() == pytest.approx([1.0, 0.0])


def test_a_jolt_is_not_a_turn() -> None:
    rate = 400.0
    w = np.zeros(1600)
    w[400:420] = 3.0  # a 50 ms spin of a hit: averaged over 0.25 s it is 0.6 rad/s
    out = behaviour(np.full(1600, 0.5), w, rate, np.array([0.0]))
    assert out["yaw_rate_peak"][0] == pytest.approx(3.0 * 20 / 100, rel=0.01)


def test_audio_levels_of_a_full_scale_sine() -> None:
    sr = 44100
    t = np.arange(4 * sr) / sr
    x = np.stack([np.sin(2 * np.pi * 441.0 * t)] * 2, axis=1).astype(np.float32)
    x[: 3 * sr] *= 0.1  # 20 dB quieter until 3 s, then full scale
    out = audio_levels(x, sr, np.array([0.0, 2.0]))
    assert out["rms"][0] == pytest.approx(-23.01, abs=0.01)
    assert out["peak"][0] == pytest.approx(-20.0, abs=0.01)
    assert out["crest"][0] == pytest.approx(3.01, abs=0.02)
    assert out["peak"][1] == pytest.approx(0.0, abs=0.01)
    assert out["flux"][0] < 1.0  # a steady tone has no onsets
    assert out["flux"][1] > 3.0  # a 20 dB step up is one
    assert clipped(out["peak"]).tolist() == [False, True]


def test_band_power_and_level_of_sines_on_exact_bins() -> None:
    rate, n = 8000.0, 8000
    t = np.arange(n) / rate
    low, high = np.sin(2 * np.pi * 100.0 * t), 0.5 * np.sin(2 * np.pi * 1000.0 * t)
    stereo = np.stack([low + high, low], axis=1)
    # A sine of amplitude A on an exact bin has |X_k| = A n / 2; both channels hold the 100 Hz one.
    assert band_power(stereo, rate, (50.0, 150.0)) == pytest.approx(2 * (n / 2) ** 2, rel=1e-9)
    assert band_power(stereo, rate, (900.0, 1100.0)) == pytest.approx((0.5 * n / 2) ** 2, rel=1e-9)
    assert band_power(stereo, rate, (200.0, 900.0)) == pytest.approx(0.0, abs=1e-9)
    assert level_db(2 * stereo, stereo, rate, (50.0, 150.0)) == pytest.approx(20 * math.log10(2), abs=1e-9)
    assert level_db(high[:, None], low[:, None], rate, (900.0, 1100.0)) > 150.0  # none of `rest` there


def test_acceleration_peak_removes_gravity() -> None:
    acc = np.tile([0.0, 0.0, 9.81], (800, 1))
    acc[500] += [3.0, 4.0, 0.0]
    np.testing.assert_allclose(acceleration_peak(acc, 200.0, np.array([0.0, 2.0])), [0.0, 5.0])


def test_repetition_sees_a_looped_bed_and_not_fresh_noise() -> None:
    rng = np.random.default_rng(0)
    rate = 4000.0
    loop = rng.standard_normal(int(1.5 * rate))
    assert repetition(np.tile(loop, 8), rate) > 0.9
    assert repetition(rng.standard_normal(12 * int(rate)), rate) < 0.05


def test_context_windows_keep_their_distance_from_anomalies() -> None:
    label = np.full(2000, NORMAL)  # 10 s at 200 Hz
    label[1000:1100] = COLLISION  # 5.0 .. 5.5 s
    starts = context_starts(label, hop_s=1.0, margin_s=1.0, first_s=0.0)
    assert starts.tolist() == [0.0, 1.0, 2.0, 7.0, 8.0]
    assert context_starts(label, hop_s=1.0, margin_s=1.0).tolist() == [2.0, 7.0, 8.0]  # from SETTLE_S


def test_audit_computes_every_probe_on_the_tiny_dataset(tiny_dataset: Path, tmp_path: Path) -> None:
    result = run_audit(tiny_dataset, progress=False)
    groups = {r.group for r in result.rows}
    assert groups == {
        "behaviour", "naive", "clipping", "context", "reference", "leak", "deleted", "level", "ambience",
        "oracle",
    }  # fmt: skip
    probes = {(r.group, r.probe) for r in result.rows}
    for name in ("reversing", "turning_in_place", "standing", "yaw_rate_peak", "peak_deceleration"):
        assert ("behaviour", name) in probes
    for name in ("rms", "peak", "crest", "flux", "acc_peak"):
        assert ("naive", name) in probes
    for row in result.rows:
        assert row.status in (PASS, FAIL, REPORT)
        if row.unit in ("auc", "auc2"):
            assert 0.0 <= row.figure <= 1.0 or math.isnan(row.figure)
        if row.unit == "auc2":
            assert row.figure >= 0.5
    deleted = [r for r in result.rows if r.group == "deleted" and r.target in ("collision", "mechanical")]
    assert {r.target for r in deleted} == {"collision", "mechanical"}
    kinds = {r.sub_kind for r in open_dataset(tiny_dataset).rows("test") if r.kind == "mechanical"}
    oracle_rows = [r for r in result.rows if r.group == "oracle" and r.probe == oracle.ORACLE_PROBE]
    assert {r.target for r in oracle_rows} >= {f"sub:{k}" for k in kinds}
    assert all(r.floor == oracle.ORACLE_FLOOR for r in oracle_rows if r.target.endswith("severity 0.75-1"))
    controls = [r for r in result.rows if r.group == "oracle" and r.probe == oracle.CONTROL_PROBE]
    assert {r.target for r in controls} == {f"sub:{k}" for k in kinds}
    assert all(r.limit == oracle.CONTROL_LIMIT and r.unit == "auc2" for r in controls)
    json_path, md_path = write(result, tmp_path / "audit")
    doc = json.loads(json_path.read_text())
    assert doc["passed"] == (not result.failed)
    assert len(doc["probes"]) == len(result.rows)
    assert "| group | probe |" in md_path.read_text()


def test_reuse_prints_the_stored_audit_only_while_dataset_and_code_match(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "audit"
    assert main(["audit", str(tiny_dataset), "--out", str(out), "--reuse", "--no-progress"]) in (0, 1)
    assert "wrote" in capsys.readouterr().out  # nothing stored yet: it ran
    stored = read(out)
    assert stored is not None and len(stored.key) == 64
    written = (out / "audit.json").read_bytes()
    status = main(["audit", str(tiny_dataset), "--out", str(out), "--reuse", "--no-progress"])
    printed = capsys.readouterr().out
    assert "reused" in printed and f"{len(stored.rows)} probes" in printed
    assert status == (1 if stored.failed else 0)
    assert (out / "audit.json").read_bytes() == written  # reused, not rewritten
    again = stored_audit(tiny_dataset, out)
    assert again is not None
    assert [(r.probe, r.target, r.status, r.detail) for r in again.rows] == [
        (r.probe, r.target, r.status, r.detail) for r in stored.rows
    ]
    # Other code (or package versions, or data) gives another key: the stored audit is not reused.
    monkeypatch.setattr("benchmarks.audit.core.source_digest", lambda *_: "edited")
    assert stored_audit(tiny_dataset, out) is None
    monkeypatch.undo()
    (out / "audit.json").write_text("{ truncated")
    assert stored_audit(tiny_dataset, out) is None


def test_audit_command_refuses_a_missing_dataset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["audit", str(tmp_path / "nothing")]) == 2
    assert "nothing" in capsys.readouterr().err


def test_standing_still_is_a_stop_without_turning() -> None:
    rate = 400.0
    t = np.arange(0, 4.0, 1 / rate)
    v = np.where(t < 2.5, 0.0, 0.5)  # stands 2.5 s, then drives
    out = behaviour(v, np.zeros_like(t), rate, np.array([0.0, 2.0]))
    assert out["standing"].tolist() == pytest.approx([1.0, 0.25], abs=0.01)


def test_fault_level_isolates_the_fault_sound_as_its_stem_does(tiny_dataset: Path) -> None:
    """The level probe takes the fault's sound as the stored mix less its muted re-render; a render with stems
    gives the fault's own stem: the two levels in the fault's band agree (the difference holds the fault's
    reverberation and the 16-bit storage too)."""
    import dataclasses

    import synth_audio
    from benchmarks.audit.core import MUTED_ANOMALY_SOURCES, _fault_level, fault_span
    from benchmarks.dataset import episode_audio_config, open_dataset
    from benchmarks.episode import read_trace

    data = open_dataset(tiny_dataset)
    specs = data.episode_specs()
    episode = next(e for e, s in specs.items() if s.category == "fault" and s.split == "test")
    trace = read_trace(tiny_dataset / episode)
    config = episode_audio_config(specs[episode])
    muted = synth_audio.render(
        trace, episode_audio_config(specs[episode], MUTED_ANOMALY_SOURCES), specs[episode].seed
    )
    probe = _fault_level(tiny_dataset / episode, trace, muted)
    stems = synth_audio.render(trace, dataclasses.replace(config, stems=True), specs[episode].seed)
    span = fault_span(trace, 44100)
    assert span is not None
    start, band = span
    own = stems.stems["faults"][start:].astype(np.float64)
    rest = stems.samples[start:].astype(np.float64) - own
    assert math.isfinite(probe)
    assert probe == pytest.approx(level_db(own, rest, 44100.0, band), abs=1.5)


def test_a_probe_with_a_floor_fails_below_it_and_one_with_both_bounds_outside_either() -> None:
    assert ProbeRow("oracle", "p", "t", 0.95, None, "auc", floor=0.9).status == PASS
    assert ProbeRow("oracle", "p", "t", 0.85, None, "auc", floor=0.9).status == FAIL
    assert ProbeRow("oracle", "p", "t", 0.5, 0.65, "auc2", floor=0.0).status == PASS
    assert ProbeRow("oracle", "p", "t", 0.7, 0.65, "auc2", floor=0.0).status == FAIL
    assert ProbeRow("oracle", "p", "t", math.nan, None, "auc", floor=0.9).status == REPORT


def test_severity_bins_cover_zero_to_one_and_one_belongs_to_the_top_bin() -> None:
    assert oracle.severity_bin(0.0) == "0-0.5" and oracle.severity_bin(0.49) == "0-0.5"
    assert oracle.severity_bin(0.5) == "0.5-0.75" and oracle.severity_bin(1.0) == "0.75-1"
    with pytest.raises(ValueError, match="severity"):
        oracle.severity_bin(1.2)


def test_the_oracle_reads_one_column_per_indicator_of_each_kind() -> None:
    rng = np.random.default_rng(0)
    seconds = 6.0
    m, n = int(seconds * 200), int(seconds * 4410)
    angle = np.outer(np.arange(m) / 200.0, 2 * np.pi * np.array([1.0, 1.1, 0.9, 1.2]))
    sig = oracle.Signals(rng.normal(size=(n, 2)), rng.normal(size=(m, 7)), angle)
    starts = np.array([0.0, 1.5, 3.5])
    site = fault_indicators.WheelSite(0, 1.0, 1.0)
    for kind, names in fault_indicators.INDICATORS.items():
        views = [oracle.View(kind, w, 0.3, 3.0 if kind == "bearing" else 1.0, 30.0, site) for w in (0, 2)]
        feats = oracle.window_features(sig, starts, views)
        assert [f.shape for f in feats] == [(3, len(names))] * 2, kind
        assert all(np.isfinite(f).all() for f in feats)


def test_the_oracle_sums_each_indicators_tail_evidence() -> None:
    nominal = np.stack([np.arange(99.0), np.arange(99.0)[::-1]], axis=1)  # 99 rows, two indicators
    baseline = fault_indicators.Rarity.fit(nominal)
    far, median = np.array([[500.0, 500.0]]), np.array([[49.0, 98.0]])
    # beyond every nominal row, twice: log10(100), then an exponential tail with the top tenth's slope (the
    # 9 rows above the 90th, 89, reach 98: one decade per 9)
    assert baseline.score(far)[0] == pytest.approx(2 * (math.log10(100) + (500.0 - 98.0) / 9.0))
    assert baseline.score(np.array([[98.5, 98.5]]))[0] < baseline.score(far)[0]
    # the first indicator at its median (50 of 99 nominal rows at or above it): its tail is 51 / 100; the
    # second at the largest nominal value (1 row at or above it): 2 / 100
    assert baseline.score(median)[0] == pytest.approx(-math.log10(0.51) - math.log10(0.02))


def test_the_oracle_looks_at_each_nominal_episode_through_its_own_robot_unit(
    tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # units differ in gear ratio, so in their gear-mesh order: a nominal window looked at with another unit's
    # order reads the wrong line (it made the severity-0 control of worn gears tell fault episodes apart)
    seen: list[float] = []
    real = oracle.nominal_views

    def spy(kind: str, robot: RobotInfo) -> list[oracle.View]:
        seen.append(robot.gear_ratio)
        return real(kind, robot)

    monkeypatch.setattr(oracle, "nominal_views", spy)
    data = open_dataset(tiny_dataset)
    oracle.score_faults(data, control=False)
    nominal = {r.episode for split in ("train", "test") for r in data.rows(split) if r.kind == "normal"}
    own = {read_trace(tiny_dataset / e).robot.gear_ratio for e in nominal}
    assert set(seen) == own and len(own) > 1


def test_the_severity_gradient_compares_how_far_the_bins_stand_out_not_their_auc() -> None:
    negative = np.linspace(0.0, 1.0, 50)  # nominal scores up to 1
    severity = np.repeat([0.3, 0.9], 20)
    for low, high, passes in ((5.0, 9.0, True), (9.0, 5.0, False)):
        positive = np.where(severity > 0.5, high, low) + np.tile(np.linspace(0.0, 0.5, 20), 2)
        scored = oracle.Scored(
            "bearing", positive, np.repeat([f"f{i}" for i in range(8)], 5), severity, negative,
            np.repeat([f"n{i}" for i in range(10)], 5),
        )  # fmt: skip
        rows = {r.probe: r for r in oracle.oracle_rows([scored]) if r.target == "sub:bearing"}
        gradient = rows[oracle.GRADIENT_PROBE]
        assert gradient.figure == pytest.approx(high - low)  # both bins at AUC 1: the margin orders them
        assert gradient.status == ("PASS" if passes else "FAIL")


def test_the_severity_gradient_reads_the_defects_size_not_a_scale_free_indicator() -> None:
    # an out-of-round wheel's corner_rise (relative to the motion's deviation) is as high at every severity
    # and spread by the driving; its rise_level grows with the runout: the gradient reads rise_level alone
    negative = np.linspace(0.0, 1.0, 50)
    severity = np.repeat([0.3, 0.9], 20)
    both = np.where(severity > 0.5, 5.0, 6.0)  # the sum: the low bin's driving happened to stand out more
    size = np.where(severity > 0.5, 1.2, 0.8)
    scored = oracle.Scored(
        "out_of_round", both, np.repeat([f"f{i}" for i in range(8)], 5), severity, negative,
        np.repeat([f"n{i}" for i in range(10)], 5), positive_size=size,
    )  # fmt: skip
    rows = {r.probe: r for r in oracle.oracle_rows([scored]) if r.target == "sub:out_of_round"}
    assert rows[oracle.GRADIENT_PROBE].figure == pytest.approx(0.4)
    assert rows[oracle.GRADIENT_PROBE].status == "PASS"
    assert fault_indicators.size_columns("out_of_round") == [1]  # rise_level, not corner_rise
    assert all(fault_indicators.size_columns(k) == list(range(len(names)))
               for k, names in fault_indicators.INDICATORS.items() if k != "out_of_round")  # fmt: skip


def test_a_rarity_of_some_columns_sums_their_evidence() -> None:
    x = np.random.default_rng(3).normal(size=(200, 3))
    fitted = fault_indicators.Rarity.fit(x)
    rows = np.array([[0.5, 2.0, -1.0], [3.0, 0.0, 4.0]])
    parts = [fitted.only([c]).score(rows[:, [c]]) for c in range(3)]
    np.testing.assert_allclose(fitted.only([0, 2]).score(rows[:, [0, 2]]), parts[0] + parts[2])
    np.testing.assert_allclose(fitted.score(rows), sum(parts))
