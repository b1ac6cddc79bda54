"""Each fault kind's indicators (`benchmarks.fault_indicators`) and the fault-aware reference detector that
tests them per wheel and defect angle (`benchmarks.methods.orders`), against planted defects."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from benchmarks import condition, fault_indicators
from benchmarks.methods._io import save_npz
from benchmarks.methods.orders import OrderReference, revolution_bin
from benchmarks.metrics import roc_auc
from msvdd.contract import AUDIO_LEN, AUDIO_RATE, IMU_LEN, IMU_RATE, ModelFormatError, WindowError, Windows
from sim import Fault, Scenario, simulate
from sim.faults import RUNOUT_M, envelope_band
from sim.scenario import Route, Unit, Waypoint


def test_the_strike_statistic_pools_each_pass_log_ratio_as_a_mean_or_a_t_statistic() -> None:
    n, rate = 400, 200.0
    angle = np.linspace(0.0, 4 * np.pi, n, endpoint=False)[None]  # two revolutions, pi / 100 a sample
    power = np.ones((1, n))

    def statistic(
        power: np.ndarray, angle: np.ndarray, phase: float, order: float, rate: float
    ) -> np.ndarray:
        return fault_indicators.strike_statistic(power, angle, phase, order, rate, pooling="t")

    assert statistic(power, angle, 1.0, 3.0, rate)[0] == pytest.approx(0.0)
    # order 3 at phase pi / 2: passes at pi / 2 + 2 pi j / 3, i.e. every 200 / 3 samples from sample 50
    passes = np.array([50, 117, 183, 250, 317, 383])
    power[0, passes] = 101.0  # a strike at each pass, nothing elsewhere
    span = round(fault_indicators.STRIKE_GATE_S * rate)
    inside = 2 * span + 1  # samples of each gate (passes far enough apart for the gates not to overlap)
    ratio = (inside - 1 + 101.0) / inside  # each gate's mean over the rest's (1)
    expected = 6 * np.log(ratio) / np.sqrt(6)
    assert statistic(power, angle, np.pi / 2, 3.0, rate)[0] == pytest.approx(expected)
    assert statistic(power, angle, np.pi / 2 + np.pi / 3, 3.0, rate)[0] < 0.0  # between the strikes
    # the same strikes over one revolution (three passes): the evidence grows as the root of the passes
    first = angle[:, : n // 2]
    assert statistic(power[:, : n // 2], first, np.pi / 2, 3.0, rate)[0] == pytest.approx(
        expected / np.sqrt(2)
    )
    # their mean: how far each strike stands out, whatever the number of passes
    for window, turned in ((power, angle), (power[:, : n // 2], first)):
        mean = fault_indicators.strike_statistic(window, turned, np.pi / 2, 3.0, rate, pooling="mean")
        assert mean[0] == pytest.approx(np.log(ratio))
    still = np.full((1, n), 0.5)  # no pass: no evidence
    assert statistic(power, still, 1.0, 1.0, rate)[0] == 0.0
    with pytest.raises(ValueError, match=r"pooling 'median' is unknown; allowed: mean, t"):
        fault_indicators.strike_statistic(power, angle, 1.0, 3.0, rate, pooling="median")
    # the same energy in one pass: that gate stands out 6 x as far, the other five not at all; it adds its
    # log ratio once
    once = np.ones((1, n))
    once[0, passes[2]] = 1.0 + 6 * 100.0
    single = (inside - 1 + once[0, passes[2]]) / inside
    got = statistic(once, angle, np.pi / 2, 3.0, rate)[0]
    assert got == pytest.approx(np.log(single) / np.sqrt(6))
    assert got < expected
    # 50 passes in 400 samples: gates of +-10 samples would cover the whole window and leave nothing to
    # compare with; each reaches a quarter of the pass interval (2 samples) and even power stays at 0
    assert statistic(np.ones((1, n)), angle, 0.1, 25.0, rate)[0] == pytest.approx(0.0)
    fast = np.ones((1, n))
    fast_passes = np.flatnonzero(np.diff(np.floor(25.0 * (angle[0] - 0.1) / (2 * np.pi))) != 0) + 1
    fast[0, fast_passes] = 6.0  # a strike at each pass: each 5-sample gate holds it once, a ratio of 2
    got = statistic(fast, angle, 0.1, 25.0, rate)[0]
    assert got == pytest.approx(np.sqrt(len(fast_passes)) * np.log(2.0), rel=0.05)


def test_a_strike_and_its_band_are_read_at_the_wheels_microphone_and_against_the_other() -> None:
    rng = np.random.default_rng(0)
    k = 3
    angle = np.outer(np.ones(k), np.linspace(0.0, 4 * np.pi, IMU_LEN, endpoint=False))  # 1 rev/s
    audio = 0.1 * rng.normal(size=(k, AUDIO_LEN, 2))
    imu7 = rng.normal(size=(k, 7, IMU_LEN))
    lo, hi = envelope_band("bearing", AUDIO_RATE)
    t = np.arange(AUDIO_LEN) / AUDIO_RATE
    burst = np.sin(2 * np.pi * 0.5 * (lo + hi) * t[: int(0.01 * AUDIO_RATE)])
    for start in (0.25, 1.25):  # a strike at wheel angle pi / 2 each revolution, at the left microphone only
        i = int(start * AUDIO_RATE)
        audio[:, i : i + burst.size, 0] += burst
    prep = fault_indicators.prepare("bearing", audio, imu7)
    assert fault_indicators.INDICATORS["bearing"] == ("strike_audio", "strike_side", "level_side")
    at_left, at_right = fault_indicators.WheelSite(0, 1.0, 1.0), fault_indicators.WheelSite(1, -1.0, 1.0)
    left = fault_indicators.indicators(prep, angle, np.array([np.pi / 2]), 1.0, at_left, pooling="mean")[:, 0]
    right = fault_indicators.indicators(prep, angle, np.array([np.pi / 2]), 1.0, at_right, pooling="mean")
    right = right[:, 0]
    assert np.all(left[:, 0] > 2.0) and np.all(np.abs(right[:, 0]) < 0.5)  # heard at the left microphone
    np.testing.assert_allclose(left[:, 1], left[:, 0] - right[:, 0])  # louder there than at the other
    np.testing.assert_allclose(right[:, 1], -left[:, 1])
    assert np.all(left[:, 2] > 0.0)  # the band is louder at the left microphone, by what the strikes add
    np.testing.assert_allclose(right[:, 2], -left[:, 2])
    # the same sound twice as loud at one microphone: the band's power there is four times the other's
    louder = np.stack([2.0 * audio[..., 1], audio[..., 1]], axis=-1)
    doubled = fault_indicators.prepare("bearing", louder, imu7)
    sides = fault_indicators.indicators(doubled, angle, np.array([np.pi / 2]), 1.0, at_left, pooling="mean")
    np.testing.assert_allclose(sides[:, 0, 2], np.log(4.0), rtol=1e-9)
    layout = np.array([[0.18, 0.225, 0.0], [0.18, -0.225, 0.0], [-0.18, 0.225, 0.0], [-0.18, -0.225, 0.0]])
    microphones = np.array([[0.05, 0.1, 0.12], [0.05, -0.1, 0.12]])
    sites = fault_indicators.wheel_sites(layout, microphones)
    assert [(s.microphone, s.lateral, s.longitudinal) for s in sites] == [
        (0, 1.0, 1.0), (1, -1.0, 1.0), (0, 1.0, -1.0), (1, -1.0, -1.0)
    ]  # fmt: skip
    two = fault_indicators.wheel_sites(layout[:2] * [0.0, 1.0, 1.0], microphones)  # a two-wheel robot
    assert [(s.microphone, s.lateral, s.longitudinal) for s in two] == [(0, 1.0, 0.0), (1, -1.0, 0.0)]


def test_a_corners_strike_is_read_in_the_roll_and_pitch_rates_only() -> None:
    rng = np.random.default_rng(1)
    angle = np.linspace(0.0, 4 * np.pi, IMU_LEN, endpoint=False)[None]
    audio = rng.normal(size=(1, AUDIO_LEN, 2))
    quiet = rng.normal(size=(1, 7, IMU_LEN))
    strikes = np.zeros(IMU_LEN)
    strikes[[50, 250]] = 30.0  # at wheel angle pi / 2 of each revolution
    tilt = fault_indicators.TILT_CHANNELS
    assert tilt == (4, 5)

    column = fault_indicators.INDICATORS["flat_spot"].index("strike_tilt")

    def strike_tilt(imu7: np.ndarray) -> float:
        prep = fault_indicators.prepare("flat_spot", audio, imu7)
        site = fault_indicators.WheelSite(0, 1.0, 1.0)
        out = fault_indicators.indicators(prep, angle, np.array([np.pi / 2]), 1.0, site, pooling="t")
        return float(out[0, 0, column])

    heave = quiet.copy()
    heave[0, 3] += strikes  # the vertical acceleration alone: not a corner's tilt
    rocked = quiet.copy()
    rocked[0, list(tilt)] += strikes
    assert strike_tilt(heave) == pytest.approx(strike_tilt(quiet))
    assert strike_tilt(rocked) > strike_tilt(quiet) + 1.0


def test_a_corners_rise_adds_up_in_phase_with_the_signs_of_its_place_either_way_it_rolls() -> None:
    rng = np.random.default_rng(2)
    t = np.arange(IMU_LEN) / IMU_RATE
    phi = 1.0
    phases = phi + np.linspace(0.0, 2 * np.pi, 8, endpoint=False)  # the runout's angle first
    site = fault_indicators.WheelSite(1, -1.0, 1.0)  # front right
    for direction in (1.0, -1.0):
        angle = direction * 2 * np.pi * 1.2 * t  # 2.4 revolutions, forwards or backwards
        rise = np.sin(angle - phi)  # the axle's height
        rate = direction * np.cos(angle - phi)  # its rate of change, signed by the rolling direction
        motion = np.stack([-rise, site.lateral * rate, -site.longitudinal * rate])[None]  # az, roll, pitch
        value = fault_indicators.corner_rise(motion, angle[None], phases, site)[0]
        assert value[0] == pytest.approx(np.sqrt(0.5), abs=0.02)  # each line 1 / sqrt(2), all in phase
        assert np.argmax(value) == 0 and value[4] == pytest.approx(-value[0])  # half a turn off: opposite
        wrong = fault_indicators.WheelSite(
            1, 1.0, -1.0
        )  # the diagonal corner tilts the chassis the other way
        assert fault_indicators.corner_rise(motion, angle[None], phases, wrong)[0, 0] < 0.25
    noise = rng.normal(size=(200, 3, IMU_LEN))
    angle = np.tile(2 * np.pi * 1.2 * t, (200, 1))
    quiet = fault_indicators.corner_rise(noise, angle, phases[:1], site)[:, 0]
    assert abs(quiet.mean()) < 0.01 and quiet.std() < 0.05


def test_a_corners_rise_level_is_the_runouts_vertical_acceleration_in_phase() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(IMU_LEN) / IMU_RATE
    phi, e, w = 1.0, 0.004, 2 * np.pi * 1.5  # a 4 mm runout at 1.5 rev/s: three whole revolutions
    phases = phi + np.array([0.0, np.pi / 2, np.pi])
    for direction in (1.0, -1.0):
        angle = direction * w * t
        vertical = -e * w**2 * np.sin(angle - phi)  # the axle lifted by e sin(angle - phi)
        motion = np.stack([vertical, np.zeros_like(t), np.zeros_like(t)])[None]
        level = fault_indicators.rise_level(motion, angle[None], phases)[0]
        np.testing.assert_allclose(level, [e * w**2, 0.0, -e * w**2], atol=1e-9)
    noise = 0.1 * rng.normal(size=(200, 3, IMU_LEN))
    angle = np.tile(w * t, (200, 1))
    quiet = fault_indicators.rise_level(noise, angle, phases[:1])[:, 0]
    assert abs(quiet.mean()) < 0.003 and quiet.std() < 0.02  # about 0.1 x 2 / sqrt(2 x 400)


def test_the_mesh_level_is_the_mesh_line_and_its_wheel_order_sidebands() -> None:
    rng = np.random.default_rng(0)
    angle = np.cumsum(rng.uniform(0.0, 0.004, size=(2, AUDIO_LEN)), axis=1)  # about 2.8 revolutions
    noise = 0.3 * rng.normal(size=(2, AUDIO_LEN))
    levels = {}
    for tone in (197.0, 198.0, 199.0, 204.0):  # a lower sideband, the mesh, an upper sideband, a line beyond
        audio = noise + np.cos(tone * angle)
        levels[tone] = fault_indicators.mesh_level(audio, angle, 198.0)
        lines = condition.order_lines(audio, angle, np.array([197.0, 198.0, 199.0]))
        np.testing.assert_allclose(levels[tone], np.log(lines.sum(axis=1) * audio.std(axis=1) + 1e-12))
    for tone in (197.0, 198.0, 199.0):
        assert np.all(levels[tone] > levels[204.0] + 1.0), tone


def _windows(n: int, seed: int, strike: float) -> Windows:
    """Noise windows with four wheels turning at 1 to 2 rev/s; `strike` > 0 plants a flat spot on wheel 2
    (back left): a 20 ms burst in the flat spot's band each time that wheel passes its defect angle, at the
    left microphone 10 dB louder than at the right."""
    rng = np.random.default_rng(seed)
    speed = rng.uniform(1.0, 2.0, size=(n, 1, 4)) * 2 * np.pi
    odometry = speed * (np.arange(IMU_LEN) / IMU_RATE)[None, :, None]
    audio = rng.normal(size=(n, AUDIO_LEN, 2))
    imu, imu6 = rng.normal(size=(n, IMU_LEN)), rng.normal(size=(n, IMU_LEN, 6))
    if strike > 0:
        lo, hi = envelope_band("flat_spot", AUDIO_RATE)
        t = np.arange(AUDIO_LEN) / AUDIO_RATE
        burst = np.sin(2 * np.pi * 0.5 * (lo + hi) * t[: int(0.02 * AUDIO_RATE)])
        for i in range(n):
            wheel = np.interp(t, np.arange(IMU_LEN) / IMU_RATE, odometry[i, :, 2]) + rng.uniform(0, 2 * np.pi)
            for j in np.flatnonzero(np.diff(np.floor(wheel / (2 * np.pi))) != 0):
                end = min(int(j) + burst.size, AUDIO_LEN)
                audio[i, j:end, :] += strike * burst[: end - j, None] * np.array([1.0, 0.3])
    return Windows(
        audio=audio.astype(np.float32),
        imu=imu.astype(np.float32),
        imu6=imu6.astype(np.float32),
        odometry=odometry.astype(np.float32),
    )


def test_the_order_reference_finds_a_strike_at_a_fixed_wheel_angle_it_was_not_told(tmp_path: Path) -> None:
    train, val = _windows(120, 1, 0.0), _windows(40, 2, 0.0)
    nominal, faulty = _windows(40, 3, 0.0), _windows(40, 3, 3.0)  # the same windows, with the flat's strikes
    detector = OrderReference().fit(train, val)
    scores = np.r_[detector.score(nominal), detector.score(faulty)]
    assert roc_auc(np.r_[np.zeros(40), np.ones(40)].astype(int), scores) > 0.95
    evidence = detector._kind_evidence(faulty)
    bins = revolution_bin(faulty)
    calibrated = {
        k: np.array(
            [detector.evidence_rarity[k, b].score(np.array([[v]]))[0] for b, v in zip(bins, e, strict=True)]
        )
        for k, e in evidence.items()
    }
    assert all(
        np.median(calibrated["flat_spot"]) > np.median(v) for k, v in calibrated.items() if k != "flat_spot"
    )
    detector.save(tmp_path / "m.npz")
    np.testing.assert_array_equal(OrderReference.load(tmp_path / "m.npz").score(faulty), scores[40:])
    with pytest.raises(WindowError, match="odometry"):
        detector.score(Windows(nominal.audio, nominal.imu, nominal.imu6))
    assert nominal.odometry is not None
    with pytest.raises(WindowError, match="4"):  # fit on four wheels
        detector.score(Windows(nominal.audio, nominal.imu, nominal.imu6, nominal.odometry[:, :, :2]))


def test_an_order_reference_file_without_a_kinds_distribution_is_refused(tmp_path: Path) -> None:
    detector = OrderReference().fit(_windows(30, 1, 0.0), None)
    header, arrays = detector._state()
    save_npz(tmp_path / "m.npz", OrderReference.kind, OrderReference.format_version,
             {**header, "threshold": 1.0, "threshold_source": "train"},
             {k: v for k, v in arrays.items() if k != "evidence/bearing/0"})  # fmt: skip
    with pytest.raises(ModelFormatError, match=r"m\.npz"):
        OrderReference.load(tmp_path / "m.npz")


@pytest.mark.parametrize("wheel", [1, 2])  # front right, back left: both signs of both lever arms
def test_a_simulated_out_of_round_wheel_rises_in_phase_with_its_defect(wheel: int) -> None:
    scenario = Scenario(
        name="straight", seed=3, duration=6.0, environment="indoor", surface="tile", arena=(12.0, 4.0),
        robot=Unit(model="skid4", unit_id=0, variation=0.0),
        route=Route(start=(-10.0, 0.0, 0.0), waypoints=(Waypoint(11.0, 0.0, 1.0),), accel=1.0, loop=False),
        faults=(Fault("out_of_round", wheel, 1.0, 1.0),),
    )  # fmt: skip
    trace = simulate(scenario)
    angle = np.interp(trace.imu_time, trace.time, trace.wheel_angle[:, wheel])
    imu7 = np.concatenate([trace.imu_vel_z[:, None], trace.imu_acc, trace.imu_gyro], axis=1).T
    starts = [
        int(2.0 * IMU_RATE),
        int(4.0 * IMU_RATE),
    ]  # two windows after the onset, about 4 revolutions each
    windows = np.stack([imu7[:, s : s + IMU_LEN] for s in starts])
    rise = condition.band_pass(
        windows[:, fault_indicators.RISE_CHANNELS], IMU_RATE, (0.3, condition.SPLIT_HZ)
    )
    phases = trace.faults[0].phase + np.linspace(0.0, 2 * np.pi, 8, endpoint=False)
    site = fault_indicators.wheel_sites(trace.robot.wheel_pos_body, trace.robot.mic_pos_body)[wheel]
    value = fault_indicators.corner_rise(
        rise, np.stack([angle[s : s + IMU_LEN] for s in starts]), phases, site
    )
    assert np.all(np.argmax(value, axis=1) == 0)  # in phase with the defect the physics placed
    assert np.all(value[:, 0] > 0.3)  # and far above what noise gives (about 0.05)
    level = fault_indicators.rise_level(rise, np.stack([angle[s : s + IMU_LEN] for s in starts]), phases)
    w = np.array([np.ptp(angle[s : s + IMU_LEN]) for s in starts]) / (IMU_LEN / IMU_RATE)
    assert np.all(np.argmax(level, axis=1) == 0)
    # a rigid chassis with one of its four corners lifted by e rises by about e / 4 at its centre, where the
    # IMU is: about a quarter of the runout's e w^2 (the severity-1 runout `sim.faults.RUNOUT_M`)
    ratio = level[:, 0] / (RUNOUT_M * w**2)
    assert np.all((ratio > 0.15) & (ratio < 0.4)), ratio


def test_a_loose_hubs_vibration_is_the_vertical_channels_power_in_the_chassis_band() -> None:
    t = np.arange(IMU_LEN) / IMU_RATE
    audio = np.zeros((1, AUDIO_LEN, 2))

    def vibration(channel: int, hz: float, amplitude: float) -> float:
        imu7 = np.zeros((1, 7, IMU_LEN))
        imu7[0, channel] = amplitude * np.sin(2 * np.pi * hz * t)
        prep = fault_indicators.prepare("loose_wheel", audio, imu7)
        assert prep.vibration is not None
        return float(prep.vibration[0])

    channels = fault_indicators.VIBRATION_CHANNELS
    low, high = fault_indicators.VIBRATION_BAND
    quiet = float(np.log(1e-20))  # no power in any channel
    assert vibration(channels[0], 12.0, 0.0) == pytest.approx(quiet)
    # a 12 Hz ring of amplitude a in one of the channels: mean power a^2 / 2 there, nothing in the others
    for channel in channels:
        expected = (np.log(2.0**2 / 2 + 1e-20) + (len(channels) - 1) * quiet) / len(channels)
        assert vibration(channel, 12.0, 2.0) == pytest.approx(expected)
    # outside the band, or in a channel a vertical strike does not move (surge, sway, yaw): nothing
    assert vibration(channels[0], low / 2, 2.0) == pytest.approx(quiet)
    assert vibration(channels[0], high + 10.0, 2.0) == pytest.approx(quiet)
    for channel in sorted(set(range(7)) - set(channels)):
        assert vibration(channel, 12.0, 2.0) == pytest.approx(quiet)
