"""Each fault kind's indicators (`benchmarks.fault_indicators`) and the fault-aware reference detector that
tests them per wheel and defect angle (`benchmarks.methods.orders`), against planted defects."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import fault_indicators
from benchmarks.methods.orders import OrderReference, hypothesis_features, mesh_orders
from benchmarks.metrics import roc_auc
from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE, WindowError, Windows
from sim.faults import envelope_band


def test_the_gate_reads_the_power_at_each_pass_of_the_defect_over_the_rest() -> None:
    n, rate = 400, 200.0
    angle = np.linspace(0.0, 4 * np.pi, n, endpoint=False)[None]  # two revolutions
    power = np.ones((1, n))
    assert fault_indicators.gated_ratio(power, angle, 1.0, 1.0, rate)[0] == pytest.approx(1.0)
    passes = np.flatnonzero(np.diff(np.floor((angle[0] - 1.0) / (2 * np.pi))) != 0) + 1
    power[0, passes] = 101.0  # a strike at each pass, nothing elsewhere
    span = round(fault_indicators.STRIKE_GATE_S * rate)
    inside = 2 * span + 1  # samples of each gate
    expected = (inside - 1 + 101.0) / inside  # the gate's mean over the rest's (1)
    assert fault_indicators.gated_ratio(power, angle, 1.0, 1.0, rate)[0] == pytest.approx(expected)
    still = np.full((1, n), 0.5)  # no pass: no evidence
    assert fault_indicators.gated_ratio(power, still, 1.0, 1.0, rate)[0] == 1.0


def test_the_mesh_level_finds_a_tone_locked_to_the_wheel_and_refuses_a_step_that_misses_its_sidebands() -> (
    None
):
    rng = np.random.default_rng(0)
    angle = np.cumsum(rng.uniform(0.0, 0.004, size=(2, AUDIO_LEN)), axis=1)  # about 2.8 revolutions
    audio = 0.3 * rng.normal(size=(2, AUDIO_LEN)) + np.cos(199.0 * angle)
    first, count = mesh_orders("skid4")
    levels = fault_indicators.mesh_level(audio, angle, first, 0.25, count)
    meshes = first + 0.25 * np.arange(count)
    best = meshes[np.argmax(levels, axis=1)]
    assert np.all(np.abs(best - 199.0) <= 1.0)  # the mesh or a sideband on the tone: the same three lines
    far = np.abs(meshes - 199.0) > 2.0
    assert np.all(levels[:, meshes == 199.0][:, 0] > levels[:, far].max(axis=1) + 1.0)
    with pytest.raises(ValueError, match="step"):
        fault_indicators.mesh_level(audio, angle, first, 0.3, count)


def _windows(n: int, seed: int, strike: float) -> Windows:
    """Noise windows with four wheels turning at 1 to 2 rev/s; `strike` > 0 plants a flat spot on wheel 2:
    a 20 ms burst in the flat spot's band each time that wheel passes its defect angle."""
    rng = np.random.default_rng(seed)
    speed = rng.uniform(1.0, 2.0, size=(n, 1, 4)) * 2 * np.pi
    odometry = speed * (np.arange(IMU_LEN) / IMU_RATE)[None, :, None]
    audio = rng.normal(size=(n, AUDIO_LEN, 2))
    if strike > 0:
        lo, hi = envelope_band("flat_spot", AUDIO_RATE)
        t = np.arange(AUDIO_LEN) / AUDIO_RATE
        burst = np.sin(2 * np.pi * 0.5 * (lo + hi) * t[: int(0.02 * AUDIO_RATE)])
        for i in range(n):
            wheel = np.interp(t, np.arange(IMU_LEN) / IMU_RATE, odometry[i, :, 2]) + rng.uniform(0, 2 * np.pi)
            for j in np.flatnonzero(np.diff(np.floor(wheel / (2 * np.pi))) != 0):
                end = min(int(j) + burst.size, AUDIO_LEN)
                audio[i, j:end, :] += strike * burst[: end - j, None]
    return Windows(
        audio=audio.astype(np.float32),
        imu=rng.normal(size=(n, IMU_LEN)).astype(np.float32),
        imu6=rng.normal(size=(n, IMU_LEN, 6)).astype(np.float32),
        odometry=odometry.astype(np.float32),
    )


def test_the_order_reference_finds_a_strike_at_a_fixed_wheel_angle_it_was_not_told() -> None:
    train, val = _windows(120, 1, 0.0), _windows(40, 2, 0.0)
    nominal, faulty = _windows(40, 3, 0.0), _windows(40, 3, 3.0)  # the same windows, with the flat's strikes
    detector = OrderReference().fit(train, val)
    scores = np.r_[detector.score(nominal), detector.score(faulty)]
    assert roc_auc(np.r_[np.zeros(40), np.ones(40)].astype(int), scores) > 0.95
    evidence = detector._kind_evidence(hypothesis_features(faulty))
    assert np.median(evidence["flat_spot"]) > np.median(evidence["out_of_round"])
    with pytest.raises(WindowError, match="odometry"):
        detector.score(Windows(nominal.audio, nominal.imu, nominal.imu6))
