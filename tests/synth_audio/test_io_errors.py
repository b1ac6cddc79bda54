"""File I/O round trips, refusal of every bad input, and the `msvdd-bench synth` command."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from audio_trace_kit import contacts, make_trace

from benchmarks.cli import main
from sim.trace import FaultRecord, Trace
from synth_audio import Audio, AudioConfig, AudioError, read, render, write


@pytest.fixture(scope="module")
def audio() -> Audio:
    return render(make_trace(1.0, 9.0, contact_events=contacts([0.5], [6.0])), AudioConfig(), seed=0)


def test_flac_round_trip_within_24_bit_quantisation(tmp_path: Path, audio: Audio) -> None:
    back = read(write(tmp_path / "a.flac", audio))
    assert back.sample_rate == audio.sample_rate and back.samples.shape == audio.samples.shape
    assert np.max(np.abs(back.samples - audio.samples)) <= 2.0**-23


def test_wav_round_trip_is_exact(tmp_path: Path, audio: Audio) -> None:
    back = read(write(tmp_path / "a.wav", audio))
    np.testing.assert_array_equal(back.samples, audio.samples)


def test_unsupported_suffix_and_over_range_flac_write_nothing(tmp_path: Path, audio: Audio) -> None:
    with pytest.raises(AudioError, match="suffix"):
        write(tmp_path / "a.mp3", audio)
    over = 1.5 / float(np.abs(audio.samples).max())  # 3.5 dB over full scale
    loud = Audio(samples=audio.samples * over, sample_rate=audio.sample_rate)
    with pytest.raises(AudioError, match="full scale"):
        write(tmp_path / "loud.flac", loud)
    assert list(tmp_path.iterdir()) == []


def _with(trace: Trace, **changes: object) -> Trace:
    return dataclasses.replace(trace, **changes)  # type: ignore[arg-type]


def _bad_traces() -> dict[str, tuple[Trace, str]]:
    good = make_trace(0.5, 8.0)
    speed = good.wheel_speed.copy()
    speed[10, 2] = np.nan
    torque = good.wheel_torque.copy()
    torque[3, 0] = np.inf
    robot_no_mics = dataclasses.replace(good.robot, mic_pos_body=np.zeros((0, 3)))
    return {
        "nan": (_with(good, wheel_speed=speed), "wheel_speed"),
        "inf": (_with(good, wheel_torque=torque), "wheel_torque"),
        "no mic_pos": (_with(good, mic_pos=np.zeros((good.time.size, 0, 3))), "microphone"),
        "no mic_pos_body": (_with(good, robot=robot_no_mics), "microphone"),
        "material": (_with(good, contacts=contacts([0.1], [1.0], materials=["adamantium"])), "material"),
        "surface": (_with(good, surface="ice"), "surface"),
        "fault wheel": (_with(good, faults=(FaultRecord("bearing", 9, 0.5, 0, 1, 3, 2000, 0.05),)), "wheel"),
        "fault kind": (
            _with(good, faults=(FaultRecord("wobble", 0, 0.5, 0, 1, 3, 2000, 0.05),)),
            "fault kind",
        ),
    }


@pytest.mark.parametrize("case", list(_bad_traces()))
def test_bad_traces_are_refused_by_name(case: str) -> None:
    trace, words = _bad_traces()[case]
    with pytest.raises(AudioError, match=words):
        render(trace, AudioConfig(), seed=0)


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"sample_rate": 8000}, "sample_rate"),
        ({"sample_rate": 200000}, "sample_rate"),
        ({"sample_rate": 44100.5}, "sample_rate"),
        ({"snr_db": float("nan")}, "snr_db"),
        ({"snr_db": float("inf")}, "snr_db"),
        ({"rt60_s": -1.0}, "rt60_s"),
    ],
)
def test_bad_configs_are_refused_by_name(changes: dict[str, object], words: str) -> None:
    with pytest.raises(AudioError, match=words):
        render(make_trace(0.3, 5.0), AudioConfig(**changes), seed=0)  # type: ignore[arg-type]


def test_negative_seed_is_refused() -> None:
    with pytest.raises(AudioError, match="seed"):
        render(make_trace(0.3, 5.0), AudioConfig(), seed=-1)


def test_cli_synth_writes_audio_and_stems(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    trace_path = make_trace(1.0, 9.0, contact_events=contacts([0.5], [3.0])).save(tmp_path / "t.npz")
    out = tmp_path / "out" / "a.flac"
    stems = tmp_path / "stems"
    argv = ["synth", "--trace", str(trace_path), "--out", str(out), "--snr", "0", "--stems", str(stems)]
    code = main([*argv, "--render-seed", "1"])
    assert code == 0, capsys.readouterr().err
    assert read(out).samples.shape == (44100, 2)
    assert sorted(p.name for p in stems.iterdir())[:3] == ["ambience.wav", "electronics.wav", "faults.wav"]


@pytest.mark.parametrize("case", ["nan", "no mic_pos", "material", "snr", "rate", "render seed"])
def test_cli_synth_refuses_bad_input_and_writes_nothing(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trace = make_trace(0.5, 8.0) if case in ("snr", "rate", "render seed") else _bad_traces()[case][0]
    trace_path = trace.save(tmp_path / "t.npz")
    out = tmp_path / "out.flac"
    extra = {
        "snr": ["--snr", "nan"],
        "rate": ["--sample-rate", "8000"],
        "render seed": ["--render-seed", "-1"],
    }.get(case, [])
    args = ["synth", "--trace", str(trace_path), "--out", str(out), "--stems", str(tmp_path / "st"), *extra]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "error" in err
    if case == "render seed":
        assert "--render-seed = -1 is invalid; allowed: an integer >= 0" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.npz"]


def test_perf_audio_stage_times_the_real_render_in_both_environments(monkeypatch: pytest.MonkeyPatch) -> None:
    """The stage renders its workload with `synth_audio.render` (once to warm up, then timed) indoors and
    outdoors, and reports audio seconds per CPU second, the worse environment as `audio_rtf`."""
    import synth_audio
    from benchmarks.perf import audio as perf_audio

    rendered: list[tuple[str, Audio]] = []

    def spy(trace: Trace, config: AudioConfig, seed: int) -> Audio:
        out = render(trace, config, seed)
        rendered.append((trace.environment, out))
        return out

    clock = iter([0.0, 0.01, 1.0, 1.04])  # CPU seconds at the start and end of each timed render
    monkeypatch.setattr(synth_audio, "render", spy)
    monkeypatch.setattr(perf_audio, "time", SimpleNamespace(process_time=lambda: next(clock)))
    figures = perf_audio.STAGE.measure(True)  # quick: a 2 s workload, one timed render per environment
    assert [env for env, _ in rendered] == ["indoor"] * 2 + ["outdoor"] * 2
    for _, out in rendered:
        assert out.samples.shape == (2 * 44100, 2) and out.sample_rate == 44100
        assert np.all(np.isfinite(out.samples)) and np.sqrt(np.mean(out.samples**2)) > 1e-3
    assert figures["audio_rtf_indoor"] == pytest.approx(2.0 / 0.01)
    assert figures["audio_rtf_outdoor"] == pytest.approx(2.0 / 0.04)
    assert figures["audio_rtf"] == figures["audio_rtf_outdoor"]
    assert set(perf_audio.STAGE.describe) <= set(figures)
