"""Each fault leaves its signature in the trace, growing with severity; zero severity equals no fault."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from sim_kit import straight

from sim import Fault, Trace, simulate
from sim.faults import FaultForcing, fault_record, strike_impulse
from sim.trace import _flatten

SPEED = 1.0
WINDOW = (2.0, 9.0)


@functools.cache
def _run(kind: str, severity: float) -> Trace:
    faults = (Fault(kind, 0, severity, 1.0),) if kind else ()
    return simulate(straight(duration=9.0, speed=SPEED, faults=faults))


def _amplitude(signal: np.ndarray, rate: float, freq: float, width: float = 0.25) -> float:
    """Peak one-sided amplitude of `signal` within `freq` +- `width` Hz (Hann window)."""
    x = signal - signal.mean()
    spectrum = np.abs(np.fft.rfft(x * np.hanning(len(x)))) * 2 / (0.5 * len(x))
    f = np.fft.rfftfreq(len(x), 1 / rate)
    band = (f > freq - width) & (f < freq + width)
    return float(spectrum[band].max())


def _imu(trace: Trace, column: str, axis: int) -> tuple[np.ndarray, float]:
    keep = (trace.imu_time > WINDOW[0]) & (trace.imu_time < WINDOW[1])
    data = getattr(trace, column)[keep]
    return (data[:, axis] if data.ndim == 2 else data), trace.imu_rate


def _rotation_hz(trace: Trace) -> float:
    keep = (trace.time > WINDOW[0]) & (trace.time < WINDOW[1])
    return float(trace.wheel_speed[keep, 0].mean() / (2 * np.pi))


@pytest.mark.parametrize(
    ("kind", "column", "axis"), [("out_of_round", "imu_gyro", 0), ("flat_spot", "imu_acc", 2)]
)
def test_once_per_revolution_faults_peak_at_wheel_rotation_frequency(
    kind: str, column: str, axis: int
) -> None:
    base = _run("", 0.0)
    f_r = _rotation_hz(base)
    assert f_r == pytest.approx(SPEED / (2 * np.pi * 0.08), rel=0.06)
    amps = [_amplitude(*_imu(_run(kind, s) if s else base, column, axis), f_r) for s in (0.0, 0.5, 1.0)]
    assert amps[0] < amps[1] < amps[2]
    assert amps[2] > 5 * amps[0]


def test_bearing_fault_is_an_impulse_train_at_the_defect_frequency() -> None:
    base = _run("", 0.0)
    f_d = _run("bearing", 1.0).faults[0].defect_order * _rotation_hz(base)
    amps = [_amplitude(*_imu(_run("bearing", s) if s else base, "imu_acc", 2), f_d) for s in (0.0, 0.5, 1.0)]
    assert amps[0] < amps[1] < amps[2]
    assert amps[2] > 5 * amps[0]
    # impulses: the knocks are spaced by one defect period (a knock at severity 1 unloads the wheel, whose
    # landing ~35 ms later is a second spike of the same knock: spikes closer than 1/4 period are grouped)
    z, rate = _imu(_run("bearing", 1.0), "imu_acc", 2)
    spikes = np.flatnonzero(z - np.median(z) > 6 * np.std(_imu(base, "imu_acc", 2)[0]))
    starts = spikes[np.concatenate([[True], np.diff(spikes) > 0.25 * rate / f_d])]
    period = np.median(np.diff(starts)) / rate
    assert period == pytest.approx(1 / f_d, rel=0.1)


def test_loose_wheel_wobbles_the_yaw_at_the_rotation_frequency() -> None:
    base = _run("", 0.0)
    f_r = _rotation_hz(base)
    amps = [
        _amplitude(*_imu(_run("loose_wheel", s) if s else base, "imu_gyro", 2), f_r) for s in (0.0, 0.5, 1.0)
    ]
    assert amps[0] < amps[1] < amps[2]
    assert amps[2] > 3 * amps[0]


def test_motor_degradation_ripples_the_torque_and_droops_the_wheel() -> None:
    base = _run("", 0.0)
    keep = (base.time > WINDOW[0]) & (base.time < WINDOW[1])
    rate = 1 / base.physics_dt
    ripple = []
    for s in (0.0, 0.5, 1.0):  # at each wheel's own motor rate (worn gears droop)
        trace = _run("motor_degradation", s) if s else base
        f_motor = trace.robot.gear_ratio * _rotation_hz(trace)
        ripple.append(_amplitude(trace.wheel_torque[keep, 0], rate, f_motor, 1.0))
    assert ripple[0] < ripple[1] < ripple[2]
    worn = _run("motor_degradation", 1.0)
    # the worn wheel's motor works against the three healthy ones: it brakes on average
    assert worn.wheel_torque[keep, 0].mean() < base.wheel_torque[keep, 0].mean() - 0.2


def _fault_hz(trace: Trace) -> float:
    """Frequency of the trace's fault at the faulty wheel's own rotation rate (worn gears droop)."""
    f_r = _rotation_hz(trace)
    fault = trace.faults[0]
    return trace.robot.gear_ratio * f_r if fault.kind == "motor_degradation" else fault.defect_order * f_r


@pytest.mark.parametrize("kind", ["flat_spot", "out_of_round"])
def test_severity_one_stands_well_above_the_nominal_z_velocity_spectrum(kind: str) -> None:
    # the heave of a flat or a runout: >= 4x the healthy drive's z-velocity
    base, worn = _run("", 0.0), _run(kind, 1.0)
    freq = _fault_hz(worn)
    line = _amplitude(*_imu(worn, "imu_vel_z", 0), freq)
    assert line > 4 * _amplitude(*_imu(base, "imu_vel_z", 0), freq)


def test_worn_gears_rock_the_chassis_fore_and_aft_at_the_motor_rate() -> None:
    # the transmission error's speed ripple, passed on by the tyre: >= 4x the healthy drive's forward
    # acceleration at the motor rate, and a pitch the healthy drive does not have
    base, worn = _run("", 0.0), _run("motor_degradation", 1.0)
    freq = _fault_hz(worn)
    surge = _amplitude(*_imu(worn, "imu_acc", 0), freq)
    assert surge > 4 * _amplitude(*_imu(base, "imu_acc", 0), freq)
    assert _amplitude(*_imu(worn, "imu_gyro", 1), freq) > 2 * _amplitude(*_imu(base, "imu_gyro", 1), freq)


def test_loose_wheel_rattle_shakes_the_z_velocity_at_severity_one() -> None:
    base, loose = _run("", 0.0), _run("loose_wheel", 1.0)
    assert np.std(_imu(loose, "imu_vel_z", 0)[0]) > 4 * np.std(_imu(base, "imu_vel_z", 0)[0])


@pytest.mark.parametrize("kind", ["out_of_round", "bearing", "loose_wheel", "motor_degradation", "flat_spot"])
def test_zero_severity_equals_no_fault_bit_for_bit(kind: str) -> None:
    base = simulate(straight(duration=2.0))
    zero = simulate(straight(duration=2.0, faults=(Fault(kind, 1, 0.0, 0.5),)))
    a, b = _flatten(base), _flatten(zero)
    for key, value in a.items():
        if key.startswith("faults.") or key == "scenario_name":
            continue
        np.testing.assert_array_equal(value, b[key], err_msg=key)
    assert zero.faults[0].severity == 0.0 and np.all(zero.label == 0)


def test_fault_labels_mark_the_active_interval() -> None:
    trace = simulate(straight(duration=4.0, faults=(Fault("out_of_round", 2, 0.8, 1.5, 1.0),)))
    on = (trace.imu_time >= 1.5) & (trace.imu_time < 2.5)
    assert np.all(trace.label[on] == 2) and np.all(trace.label[~on] == 0)
    assert np.all(trace.label_wheel[on] == 2) and np.all(trace.label_wheel[~on] == -1)
    assert trace.faults[0].defect_order == 1.0 and trace.faults[0].resonance_hz > 0


def test_same_scenario_gives_the_same_trace_bit_for_bit() -> None:
    from sim import ScenarioOptions, draw_scenario

    scenario = draw_scenario(
        8, "fault", ScenarioOptions(duration=6.0, fault_kind="loose_wheel", severity=(0.9, 1.0))
    )
    scenario = scenario.replace(faults=(Fault("loose_wheel", 0, 0.9, 0.5),))
    a, b = _flatten(simulate(scenario)), _flatten(simulate(scenario))
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_a_flat_lifts_the_wheel_by_its_geometry() -> None:
    # A flat of depth h at angle phase: the axle stands r - h above the floor when the flat lies flush,
    # r outside +-acos(1 - h / r), and the lift is continuous between.
    trace = _run("flat_spot", 1.0)
    record = trace.faults[0]
    forcing = FaultForcing(record, trace.robot, np.random.default_rng(0))
    r = float(trace.robot.wheel_radius[0])
    half = np.arccos(1.0 - record.size / r)
    t = record.onset + 1.0
    assert forcing.flat_lift(t, record.phase) == pytest.approx(record.size)
    assert forcing.flat_lift(t, record.phase + half + 1e-6) == 0.0
    assert forcing.flat_lift(t, record.phase - half - 1e-6) == 0.0
    assert forcing.flat_lift(t, record.phase + half - 1e-6) == pytest.approx(0.0, abs=1e-7)
    assert forcing.flat_lift(record.onset - 0.1, record.phase) == 0.0


def test_a_flat_strikes_once_a_revolution_with_the_step_law() -> None:
    trace = _run("flat_spot", 1.0)
    record, strikes = trace.faults[0], trace.fault_strikes
    keep = (strikes.time > WINDOW[0]) & (strikes.time < WINDOW[1])
    period = np.median(np.diff(strikes.time[keep]))
    assert period == pytest.approx(1.0 / _rotation_hz(trace), rel=0.05)
    r = float(trace.robot.wheel_radius[0])
    corner = trace.robot.mass / 4
    speed = np.interp(strikes.time[keep], trace.time, np.abs(trace.wheel_speed[:, 0])) * r
    np.testing.assert_allclose(strikes.impulse[keep], strike_impulse(record, speed, corner, r), rtol=0.05)


def test_fault_records_draw_the_defect_angle_from_the_scenario() -> None:
    # The defect's angle and a bearing's slip come from the scenario seed and the fault's index.
    trace = _run("bearing", 1.0)
    fault = Fault("bearing", 0, 1.0, 1.0)
    a = fault_record(fault, trace.robot, 9.0, seed=1)
    b = fault_record(fault, trace.robot, 9.0, seed=2)
    assert a.phase != b.phase and a.defect_order != b.defect_order
    assert fault_record(fault, trace.robot, 9.0, seed=1) == a
    assert 0.97 < a.defect_order / 3.1 < 1.03
