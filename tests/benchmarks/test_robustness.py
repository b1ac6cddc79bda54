"""`msvdd-bench robustness`: analytic oracles for every perturbation, determinism, and a run on `tiny`."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benchmarks.cli import main
from benchmarks.errors import UserError
from benchmarks.robustness import perturb
from benchmarks.robustness.perturb import KINDS, Perturbation, Streams, apply, rng_for
from benchmarks.robustness.run import RobustnessConfig, parse_perturbations

IMU_RATE = 200.0
AUDIO_RATE = 4410.0


def _bump(n: int, rate: float, at_s: float, width_s: float = 0.02) -> np.ndarray:
    t = np.arange(n) / rate
    return np.exp(-0.5 * ((t - at_s) / width_s) ** 2)


def _centroid_s(x: np.ndarray, rate: float, around_s: float, half_s: float = 0.2) -> float:
    t = np.arange(x.size) / rate
    keep = np.abs(t - around_s) < half_s
    return float(np.sum(t[keep] * x[keep]) / np.sum(x[keep]))


def _streams(seconds: float = 30.0, seed: int = 0) -> Streams:
    rng = np.random.default_rng(seed)
    n, m = int(seconds * AUDIO_RATE), int(seconds * IMU_RATE)
    return Streams(
        audio=rng.normal(size=(n, 2)).astype(np.float32),
        imu=rng.normal(size=m).astype(np.float32),
        imu6=rng.normal(size=(m, 6)).astype(np.float32),
    )


def _apply(s: Streams, kind: str, severity: float, episode: int = 3, seed: int = 0) -> Streams:
    p = Perturbation(kind, severity)
    return apply(s, p, rng_for(seed, p, episode), AUDIO_RATE, IMU_RATE)


# --- offset and drift ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("offset_ms", [-200.0, -50.0, -10.0, 10.0, 50.0, 200.0])
def test_an_offset_of_k_ms_moves_an_impulse_by_k_ms_and_leaves_the_audio(offset_ms: float) -> None:
    s = _streams(10.0)
    imu = np.zeros(2000, dtype=np.float32)
    imu[1000] = 1.0
    imu6 = np.zeros((2000, 6), dtype=np.float32)
    imu6[1000, 2] = 9.81
    out = _apply(Streams(s.audio, imu, imu6), "offset", offset_ms)
    moved = 1000 + round(offset_ms * 1e-3 * IMU_RATE)
    assert np.flatnonzero(out.imu).tolist() == [moved] and out.imu[moved] == 1.0
    assert np.flatnonzero(out.imu6[:, 2]).tolist() == [moved] and out.imu6[moved, 2] == np.float32(9.81)
    assert out.audio is s.audio
    assert out.imu.dtype == np.float32 and out.imu.shape == imu.shape


def test_a_fractional_offset_moves_a_smooth_marker_by_exactly_that_much() -> None:
    x = _bump(4000, IMU_RATE, 10.0).astype(np.float32)
    for offset_ms in (1.0, 2.5, -7.0, 33.3):
        y = perturb.shift(x, IMU_RATE, offset_ms)
        moved = _centroid_s(y, IMU_RATE, 10.0) - _centroid_s(x, IMU_RATE, 10.0)
        assert moved == pytest.approx(offset_ms * 1e-3, abs=2e-6)


@pytest.mark.parametrize("ppm", [100.0, 500.0, 2000.0, -500.0])
def test_drift_of_p_ppm_moves_a_marker_at_t_by_t_p_1e6(ppm: float) -> None:
    n = int(30 * IMU_RATE)
    for at_s in (5.0, 15.0, 25.0):
        x = _bump(n, IMU_RATE, at_s)
        y = perturb.drift(x, IMU_RATE, ppm)
        moved = _centroid_s(y, IMU_RATE, at_s) - _centroid_s(x, IMU_RATE, at_s)
        assert moved == pytest.approx(at_s * ppm * 1e-6, abs=2e-6), at_s


def test_samples_from_past_the_recording_are_mirrored_and_counted() -> None:
    x = np.arange(100, dtype=np.float32)
    early = perturb.shift(x, IMU_RATE, -50.0)  # 10 samples: the last 10 read past the end
    assert early[:90].tolist() == x[10:].tolist() and early[90:].tolist() == x[98:88:-1].tolist()
    late = perturb.shift(x, IMU_RATE, 50.0)
    assert late[:10].tolist() == x[10:0:-1].tolist() and late[10:].tolist() == x[:90].tolist()
    assert perturb.reads_outside(Perturbation("offset", -50.0), 100, IMU_RATE).nonzero()[0].tolist() == list(
        range(90, 100)
    )
    assert (
        perturb.reads_outside(Perturbation("drift", 2000.0), 100, IMU_RATE).sum() == 0
    )  # reads earlier only
    assert perturb.reads_outside(Perturbation("drift", -2e4), 100, IMU_RATE).sum() == 2  # 99 * 1.0204 > 99
    assert perturb.reads_outside(Perturbation("imu-drop", 20.0), 100, IMU_RATE).sum() == 0


def test_drift_moves_the_imu_only() -> None:
    s = _streams(10.0)
    out = _apply(s, "drift", 2000.0)
    assert out.audio is s.audio
    assert out.imu[0] == s.imu[0]  # the episode start is the fixed point
    assert not np.array_equal(out.imu, s.imu) and not np.array_equal(out.imu6, s.imu6)


def test_band_limited_reads_match_a_sinusoid_between_samples() -> None:
    t = np.arange(2000) / IMU_RATE
    x = np.sin(2 * np.pi * 17.0 * t)
    positions = np.arange(100, 1900) + 0.37
    y = perturb.resample_at(x, positions)
    assert np.max(np.abs(y - np.sin(2 * np.pi * 17.0 * positions / IMU_RATE))) < 1e-3
    assert np.array_equal(perturb.resample_at(x, np.arange(2000.0)), x)  # on the grid: exact
    assert perturb.resample_at(x, np.array([-5.0, 2004.0])).tolist() == [x[5], x[1994]]  # mirrored


# --- jitter -------------------------------------------------------------------------------------------------


def test_small_jitter_of_s_ms_rms_misplaces_a_ramp_by_s_ms_rms() -> None:
    """Stamps off by e put the value of time t - e at t: on a ramp of slope a, an error of -a e (to first
    order in s / T, T = 5 ms the IMU period)."""
    n, slope, sigma_ms = 40000, 3.0, 0.05
    x = slope * np.arange(n) / IMU_RATE
    stamps = perturb.jittered_stamps(n, IMU_RATE, sigma_ms, np.random.default_rng(1))
    error_ms = (perturb.regrid(x, stamps, IMU_RATE) - x)[10:-10] / slope * 1e3
    assert np.sqrt(np.mean(error_ms**2)) == pytest.approx(sigma_ms, rel=0.05)
    offset_ms = (stamps - np.arange(n) / IMU_RATE)[10:-10] * 1e3
    assert np.corrcoef(error_ms, offset_ms)[0, 1] < -0.999


@pytest.mark.parametrize("sigma_ms", [0.25, 0.5])
def test_jitter_regrids_a_ramp_exactly_as_linear_interpolation_through_the_stamps_says(
    sigma_ms: float,
) -> None:
    """Without reordered stamps, grid time t_k falls between the stamps of samples k-1 and k (e_k > 0) or
    k and k+1 (e_k < 0), and the ramp reads t_k - T e_k / (T + e_k - e_(k-1)), resp. (T + e_(k+1) - e_k)."""
    n, period = 20000, 1.0 / IMU_RATE
    t = np.arange(n) * period
    stamps = perturb.jittered_stamps(n, IMU_RATE, sigma_ms, np.random.default_rng(5))
    e = stamps - t
    assert np.all(np.diff(stamps) > 0)  # no reordering at these levels with this draw
    k = np.arange(1, n - 1)
    late = -period * e[k] / (period + e[k] - e[k - 1])
    early = -period * e[k] / (period + e[k + 1] - e[k])
    expected = np.where(e[k] >= 0, late, early)
    got = perturb.regrid(t, stamps, IMU_RATE)[k] - t[k]
    assert np.max(np.abs(got - expected)) < 1e-12


def test_jitter_resamples_both_imu_streams_with_the_same_stamps() -> None:
    s = _streams(10.0)
    out = _apply(s, "jitter", 2.0)
    same = Streams(s.audio, s.imu6[:, 0].copy(), s.imu6)
    twin = _apply(same, "jitter", 2.0)
    assert np.array_equal(twin.imu, twin.imu6[:, 0])  # one set of stamps for the whole IMU
    assert out.audio is s.audio and not np.array_equal(out.imu, s.imu)


# --- dropped samples and audio gaps -------------------------------------------------------------------------


@pytest.mark.parametrize("percent", [1.0, 5.0, 20.0])
def test_the_drop_rate_is_binomial_and_dropped_samples_hold_the_last_kept(percent: float) -> None:
    n = 100_000
    dropped = perturb.drop_mask(n, percent, np.random.default_rng(2))
    p = percent / 100
    assert abs(dropped.sum() - n * p) < 5 * math.sqrt(n * p * (1 - p))
    x = np.arange(n, dtype=np.float64)  # the value is the index: the held index is read back
    y = perturb.hold_last(x, dropped)
    kept = np.flatnonzero(~dropped)
    assert np.array_equal(y[kept], x[kept])
    expect = np.maximum.accumulate(np.where(dropped, -1, np.arange(n)))
    expect[expect < 0] = kept[0]
    assert np.array_equal(y, expect)


def test_dropping_hits_every_imu_channel_of_a_sample_together() -> None:
    s = _streams(20.0)
    base = np.arange(s.imu.size, dtype=np.float32)
    out = _apply(Streams(s.audio, base, np.repeat(base[:, None], 6, axis=1)), "imu-drop", 20.0)
    assert np.all(out.imu6 == out.imu[:, None])
    assert 0.15 < np.mean(out.imu != base) < 0.25


@pytest.mark.parametrize("ms_per_s", [10.0, 50.0, 200.0, 37.0])
def test_a_gap_zeroes_exactly_the_stated_fraction_one_span_per_second(ms_per_s: float) -> None:
    seconds = 13.5
    s = _streams(seconds)
    audio = np.abs(s.audio) + 1.0  # no zero anywhere before
    out = _apply(Streams(audio, s.imu, s.imu6), "audio-gap", ms_per_s).audio
    zero = out == 0
    assert np.array_equal(zero[:, 0], zero[:, 1])
    n = audio.shape[0]
    assert zero[:, 0].sum() == math.floor(n * ms_per_s / 1000 + 0.5)
    block = int(AUDIO_RATE)
    for start in range(0, block * int(seconds), block):
        z = zero[start : start + block, 0]
        idx = np.flatnonzero(z)
        assert idx.size in (math.floor(ms_per_s * AUDIO_RATE / 1000), math.ceil(ms_per_s * AUDIO_RATE / 1000))
        assert idx[-1] - idx[0] + 1 == idx.size  # one contiguous span
    assert np.array_equal(out[~zero], audio[~zero])


def test_a_missing_modality_reads_zero_and_leaves_the_other() -> None:
    s = _streams(5.0)
    no_audio = _apply(s, "audio-missing", 100.0)
    assert not no_audio.audio.any() and no_audio.imu is s.imu and no_audio.imu6 is s.imu6
    no_imu = _apply(s, "imu-missing", 100.0)
    assert not no_imu.imu.any() and not no_imu.imu6.any() and no_imu.audio is s.audio


# --- identity, determinism, input checks --------------------------------------------------------------------


@pytest.mark.parametrize("kind", list(KINDS))
def test_zero_severity_is_the_identity_bit_for_bit(kind: str) -> None:
    s = _streams(6.0)
    out = _apply(s, kind, 0.0)
    for name in ("audio", "imu", "imu6"):
        assert np.array_equal(getattr(out, name), getattr(s, name)), name
    rng = np.random.default_rng(0)
    x = s.imu6
    assert np.array_equal(perturb.shift(x, IMU_RATE, 0.0), x)
    assert np.array_equal(perturb.resample_at(x, perturb.warp_positions(x.shape[0], IMU_RATE)), x)
    assert np.array_equal(perturb.hold_last(x, perturb.drop_mask(x.shape[0], 0.0, rng)), x)
    assert not perturb.gap_mask(1000, AUDIO_RATE, 0.0, rng).any()


@pytest.mark.parametrize("kind", ["jitter", "imu-drop", "audio-gap"])
def test_the_draws_depend_on_seed_kind_severity_and_episode_only(kind: str) -> None:
    s = _streams(6.0)
    severity = KINDS[kind].severities[1]
    a, b = _apply(s, kind, severity), _apply(s, kind, severity)
    for name in ("audio", "imu", "imu6"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    changed = "audio" if kind == "audio-gap" else "imu"
    for other in (
        _apply(s, kind, severity, episode=4),
        _apply(s, kind, severity, seed=1),
        _apply(s, kind, KINDS[kind].severities[2]),
    ):
        assert not np.array_equal(getattr(a, changed), getattr(other, changed))


def test_rng_for_is_stable() -> None:
    p = Perturbation("jitter", 0.5)
    assert rng_for(0, p, 7).integers(0, 2**31, 4).tolist() == rng_for(0, p, 7).integers(0, 2**31, 4).tolist()
    assert rng_for(0, p, 7).random() != rng_for(0, Perturbation("jitter", 0.1), 7).random()
    assert rng_for(0, p, 7).random() != rng_for(0, Perturbation("imu-drop", 0.5), 7).random()


def test_bad_perturbations_are_one_line_user_errors_naming_field_value_and_range() -> None:
    with pytest.raises(UserError, match=r"offset: severity = 5000.0 is invalid; allowed: -1000 to 1000 ms"):
        Perturbation("offset", 5000.0)
    with pytest.raises(UserError, match=r"kind = 'wobble' is unknown; allowed: offset, drift"):
        parse_perturbations(["wobble"])
    with pytest.raises(UserError, match=r"imu-drop: severities = 'a,b' are invalid"):
        parse_perturbations(["imu-drop=a,b"])
    with pytest.raises(UserError, match=r"imu-missing: severity = 50.0 is invalid; allowed: 0 or 100"):
        parse_perturbations(["imu-missing=50"])
    with pytest.raises(UserError, match="no perturbation given"):
        RobustnessConfig(perturbations=())
    with pytest.raises(UserError, match="--perturbation-seed"):
        RobustnessConfig(perturbations=parse_perturbations(["drift"]), seed=-1)
    parsed = parse_perturbations(["offset=-20,5", "drift", "offset=5"])
    assert [(p.kind, p.severity) for p in parsed] == [
        ("offset", -20.0), ("offset", 5.0), ("drift", 100.0), ("drift", 500.0), ("drift", 2000.0)
    ]  # fmt: skip


def test_the_command_lists_every_kind() -> None:
    from benchmarks.commands.robustness import KIND_NAMES

    assert tuple(KINDS) == KIND_NAMES


# --- end to end ---------------------------------------------------------------------------------------------


CHOSEN = ["offset=-50,0", "drift=500", "jitter=0.5", "imu-drop=5", "audio-gap=50", "audio-missing",
          "imu-missing"]  # fmt: skip
"""One severity per kind (and offset 0, the identity)."""


def _robustness_argv(data: Path, model: Path, out: Path, *extra: str) -> list[str]:
    return ["robustness", "--data", str(data), "--models", str(model.parent), "--out", str(out),
            "--no-progress", "--perturbations", *CHOSEN, *extra]  # fmt: skip


@pytest.fixture(scope="module")
def in_process_run(tiny_dataset: Path, tiny_model: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`robustness` on `tiny` with every task in this process (--workers 1); its output folder."""
    out = tmp_path_factory.mktemp("robustness") / "robust"
    assert main(_robustness_argv(tiny_dataset, tiny_model, out, "--workers", "1")) == 0
    return out


def _without_command(doc: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in doc.items() if k not in ("command", "date")}


def test_robustness_end_to_end_on_tiny(
    tiny_dataset: Path, tiny_model: Path, in_process_run: Path, tmp_path: Path
) -> None:
    evaluated = tmp_path / "eval"
    assert main(["evaluate", "--data", str(tiny_dataset), "--model", str(tiny_model), "--out", str(evaluated),
                 "--no-progress"]) == 0  # fmt: skip
    reported = json.loads((evaluated / "results.json").read_text())["methods"]["msvdd"]

    out = in_process_run
    for name in ("robustness.md", "robustness.json", "robustness.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert not list(out.parent.glob(".robust.partial-*"))
    doc = json.loads((out / "robustness.json").read_text())
    results = doc["results"]
    clean = next(r for r in results if r["perturbation"] == "clean")
    assert clean["method"] == "msvdd"
    assert clean["auc"]["value"] == reported["auc_ci95"]["auc"]["value"]
    assert clean["auc"]["value"] == pytest.approx(reported["auc"], abs=1e-12)
    assert clean["ratio_to_clean"]["value"] == 1.0
    assert [(r["perturbation"], r["severity"]) for r in results[1:]] == [
        ("offset", -50.0), ("offset", 0.0), ("drift", 500.0), ("jitter", 0.5), ("imu-drop", 5.0),
        ("audio-gap", 50.0), ("audio-missing", 100.0), ("imu-missing", 100.0),
    ]  # fmt: skip
    zero = next(r for r in results if r["perturbation"] == "offset" and r["severity"] == 0.0)
    assert zero["auc"] == clean["auc"]  # no perturbation: the clean windows, bit for bit
    assert zero["mirrored_windows"] == 0 and results[1]["mirrored_windows"] > 0  # -50 ms reads past the end
    for r in results:
        v, ratio = r["auc"]["value"], r["ratio_to_clean"]["value"]
        assert 0.0 <= v <= 1.0 and ratio == pytest.approx(v / clean["auc"]["value"])
    table = (out / "robustness.md").read_text()
    assert "| offset | -50 ms |" in table and "| audio-gap | 50 ms per s |" in table
    assert doc["perturbations"]["offset"]["severities"] == [-50.0, 0.0]
    assert main(_robustness_argv(tiny_dataset, tiny_model, out)) == 2  # the output folder exists now


# Ray runs the same `Executor.map` (tests/benchmarks/test_executor.py checks its checksums, task order and
# errors); the spawned processes here pickle every task and result just as Ray does.
def test_worker_processes_give_the_in_process_results_bit_for_bit(
    tiny_dataset: Path, tiny_model: Path, in_process_run: Path, tmp_path: Path
) -> None:
    out = tmp_path / "robust"
    assert main(_robustness_argv(tiny_dataset, tiny_model, out, "--workers", "2")) == 0
    doc = json.loads((out / "robustness.json").read_text())
    reference = json.loads((in_process_run / "robustness.json").read_text())
    assert _without_command(doc) == _without_command(reference)
    assert doc["results"] == reference["results"]  # every AUC, interval, ratio and count, bit for bit


def test_bad_executor_flags_are_refused_before_any_work(tiny_dataset: Path, tmp_path: Path) -> None:
    base = ["robustness", "--data", str(tiny_dataset), "--models", str(tmp_path / "none"), "--no-progress"]
    assert main([*base, "--out", str(tmp_path / "a"), "--address", "10.0.0.5:6379"]) == 2  # needs ray
    assert main([*base, "--out", str(tmp_path / "b"), "--workers", "0"]) == 2
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_models_must_be_model_or_run_folders(tiny_dataset: Path, tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    argv = ["robustness", "--data", str(tiny_dataset), "--models", str(tmp_path / "empty"),
            "--out", str(tmp_path / "o"), "--no-progress"]  # fmt: skip
    assert main(argv) == 2
    assert not (tmp_path / "o").exists()
