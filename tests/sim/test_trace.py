"""Trace round trip through .npz at each field's stated precision; format 1 still read, others refused."""

from __future__ import annotations

import dataclasses
import zipfile
from pathlib import Path

import numpy as np
import pytest

import sim
from sim import trace_storage
from sim.trace import (
    TRACE_FORMAT_VERSION,
    ContactEvents,
    FaultRecord,
    ObstacleRecord,
    RobotInfo,
    Trace,
    TraceError,
    TransientEvents,
    _flatten,
)

FLOAT32_STEP = 2.0**-24
"""Largest relative error of a float32-stored signal (round to nearest)."""


def _tiny_trace() -> Trace:
    rng = np.random.default_rng(0)
    n, m = 50, 20
    robot = RobotInfo(
        "skid4", 3, 20.0, ("fl", "fr"), np.full(2, 0.08), rng.normal(size=(2, 3)), rng.normal(size=(2, 3)),
        np.zeros(3), 20.0, 12, 4, 20000.0, 30, 0.45, 0.3,
    )  # fmt: skip
    contacts = ContactEvents(
        np.array([0.5]), np.ones((1, 3)), np.array([[1.0, 0, 0]]), np.array([12.5]), np.array([1.2]),
        np.array([0.05]), ("wall",), ("plaster",),
    )  # fmt: skip
    transients = TransientEvents(
        np.zeros(0), np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros(0), (), np.zeros(0)
    )
    return Trace(
        "tiny", 7, "indoor", "tile", 1.0, 0.002, 200.0, robot, np.array([5.0, 4.0]),
        np.arange(n) * 0.002, rng.normal(size=(n, 2)), rng.normal(size=(n, 2)), rng.normal(size=(n, 2)),
        rng.normal(size=(n, 3)), rng.normal(size=(n, 4)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3)),
        rng.normal(size=(n, 2, 3)), np.arange(m) / 200.0, rng.normal(size=m), rng.normal(size=(m, 3)),
        rng.normal(size=(m, 3)), contacts, transients,
        (FaultRecord("bearing", 1, 0.5, 0.1, 0.5, 3.57, 2100.0, 0.04),),
        (ObstacleRecord("wall", "plaster", np.array([1.0, 2, 0.5]), np.array([0.1, 2, 0.5]), 0.3),),
        rng.normal(size=(m, 1, 3)), np.zeros(m, np.int8), np.zeros(m, np.int16), -np.ones(m, np.int8),
    )  # fmt: skip


def _stored_names(path: Path) -> set[str]:
    return {name.removesuffix(".npy") for name in zipfile.ZipFile(path).namelist()}


def _assert_within_stated_precision(loaded: Trace, trace: Trace) -> None:
    """float32 signals within 2^-24 of each value, every other array and scalar exact."""
    got, want = _flatten(loaded), _flatten(trace)
    assert set(got) == set(want)
    for name, value in want.items():
        assert got[name].dtype == value.dtype or name == "format_version", name
        if name in trace_storage.FLOAT32_FIELDS:
            np.testing.assert_allclose(got[name], value, rtol=FLOAT32_STEP, atol=0, err_msg=name)
        elif name != "format_version" and name not in ("wheel_angle", "mic_pos"):
            np.testing.assert_array_equal(got[name], value, err_msg=name)


def test_round_trip_keeps_every_field_at_its_stated_precision(tmp_path: Path) -> None:
    """A hand-made trace follows none of the laws, so time, imu_time and wheel_angle are stored exactly
    and mic_pos as float32."""
    trace = _tiny_trace()
    path = trace.save(tmp_path / "t.npz")
    assert {"time", "imu_time", "wheel_angle", "mic_pos"} <= _stored_names(path)
    loaded = Trace.load(path)
    assert loaded.format_version == TRACE_FORMAT_VERSION
    assert loaded.faults == trace.faults
    assert loaded.contacts.obstacle_kind == ("wall",)
    assert loaded.robot.wheel_names == ("fl", "fr")
    _assert_within_stated_precision(loaded, trace)
    np.testing.assert_array_equal(loaded.wheel_angle, trace.wheel_angle)
    np.testing.assert_allclose(loaded.mic_pos, trace.mic_pos, rtol=FLOAT32_STEP, atol=0)
    np.testing.assert_array_equal(loaded.obstacles[0].position, trace.obstacles[0].position)
    assert loaded.non_finite_fields() == []


@pytest.fixture(scope="module")
def simulated() -> Trace:
    """A real 6 s collision episode from the simulator (turns, a contact, a moving base)."""
    return sim.simulate(sim.draw_scenario(5, "collision", sim.ScenarioOptions(duration=6.0)))


def test_a_simulated_trace_keeps_its_derived_fields_within_tolerance(
    simulated: Trace, tmp_path: Path
) -> None:
    """The simulator's time stamps, wheel angles and microphone positions follow their laws, so the file
    leaves them out, and they come back exactly (time) or within the stated tolerance."""
    path = simulated.save(tmp_path / "t.npz")
    names = _stored_names(path)
    assert not {"time", "imu_time", "wheel_angle", "mic_pos"} & names
    assert trace_storage.ANGLE_START in names
    with np.load(path) as data:
        assert all(data[name].dtype == np.float32 for name in trace_storage.FLOAT32_FIELDS)
    loaded = Trace.load(path)
    _assert_within_stated_precision(loaded, simulated)
    np.testing.assert_array_equal(loaded.time, simulated.time)
    np.testing.assert_array_equal(loaded.imu_time, simulated.imu_time)
    np.testing.assert_array_equal(loaded.wheel_angle[0], simulated.wheel_angle[0])
    assert np.abs(loaded.wheel_angle - simulated.wheel_angle).max() <= trace_storage.ANGLE_TOLERANCE_RAD
    assert np.abs(loaded.mic_pos - simulated.mic_pos).max() <= trace_storage.MIC_TOLERANCE_M
    assert np.ptp(simulated.wheel_angle) > 10.0 and np.ptp(simulated.base_quat[:, 3]) > 0.01  # not trivial


def test_load_gives_exactly_the_trace_at_storage_precision(simulated: Trace, tmp_path: Path) -> None:
    """What a reader gets is what the dataset writer renders from, bit for bit, and saving it again (or
    saving the simulator's trace) writes the same bytes: deterministic, idempotent."""
    stored = simulated.at_storage_precision()
    loaded = Trace.load(simulated.save(tmp_path / "a.npz"))
    for name, value in _flatten(stored).items():
        np.testing.assert_array_equal(_flatten(loaded)[name], value, err_msg=name)
        assert _flatten(loaded)[name].dtype == value.dtype, name
    again = stored.save(tmp_path / "b.npz")  # the arrays `stored` was decoded from
    assert again.read_bytes() == (tmp_path / "a.npz").read_bytes()
    assert simulated.save(tmp_path / "c.npz").read_bytes() == again.read_bytes()
    # encoding the stored trace's own fields (a copy, or the loaded trace) gives those arrays again
    assert dataclasses.replace(stored).save(tmp_path / "d.npz").read_bytes() == again.read_bytes()
    assert loaded.save(tmp_path / "e.npz").read_bytes() == again.read_bytes()


def test_members_that_barely_compress_are_stored_and_the_rest_deflated(tmp_path: Path) -> None:
    """`write_npz` deflates a member unless zlib shrinks its first bytes by less than 1 - STORE_RATIO; numpy
    reads both kinds back exactly."""
    rng = np.random.default_rng(3)
    arrays = {
        "noise": rng.standard_normal(20000).astype(np.float32),  # random mantissas: barely compress
        "steps": np.repeat(np.arange(50, dtype=np.float32), 400),  # long runs: compress well
        "empty": np.zeros(0),
        "labels": np.array(["a", "bb"]),
    }
    path = tmp_path / "m.npz"
    with path.open("wb") as handle:
        trace_storage.write_npz(handle, arrays)
    with zipfile.ZipFile(path) as archive:
        kinds = {info.filename: info.compress_type for info in archive.infolist()}
        noise = archive.getinfo("noise.npy")
        assert noise.compress_type == zipfile.ZIP_STORED and noise.compress_size >= noise.file_size
        steps = archive.getinfo("steps.npy")
        assert steps.compress_type == zipfile.ZIP_DEFLATED and steps.compress_size < 0.1 * steps.file_size
    assert kinds["empty.npy"] == zipfile.ZIP_DEFLATED
    with np.load(path) as data:
        for name, value in arrays.items():
            np.testing.assert_array_equal(data[name], value)
            assert data[name].dtype == value.dtype


def test_a_format_1_file_is_read_bit_for_bit(simulated: Trace, tmp_path: Path) -> None:
    """Format 1 (every array as simulated, float64): datasets written before format 2 still open."""
    arrays = _flatten(simulated)
    arrays["format_version"] = np.asarray(1)
    path = tmp_path / "v1.npz"
    np.savez_compressed(path, **arrays)  # type: ignore[arg-type]
    loaded = Trace.load(path)
    assert loaded.format_version == 1
    for name, value in _flatten(simulated).items():
        if name != "format_version":
            np.testing.assert_array_equal(_flatten(loaded)[name], value, err_msg=name)


def test_transient_heights_travel_in_the_trace_and_older_files_get_the_simulators(
    simulated: Trace, tmp_path: Path
) -> None:
    """The audio's strike needs each floor feature's height: a simulated trace carries the heights the world
    was built with; a file written before the field existed gets the same values from the scenario table."""
    from sim.vocab import TRANSIENT_HEIGHT

    tr = simulated.transients
    assert len(tr.kind) > 0, "the fixture crosses no floor feature"
    np.testing.assert_array_equal(tr.height, [TRANSIENT_HEIGHT[k] for k in tr.kind])
    arrays = {k: v for k, v in _flatten(simulated).items() if k != "transients.height"}
    arrays["format_version"] = np.asarray(1)
    np.savez_compressed(tmp_path / "old.npz", **arrays)  # type: ignore[arg-type]
    np.testing.assert_array_equal(Trace.load(tmp_path / "old.npz").transients.height, tr.height)


def test_a_non_finite_signal_survives_the_round_trip(tmp_path: Path) -> None:
    trace = _tiny_trace()
    trace.wheel_speed[4, 1] = np.nan
    assert "wheel_speed" in Trace.load(trace.save(tmp_path / "t.npz")).non_finite_fields()


def test_non_finite_fields_are_named() -> None:
    trace = _tiny_trace()
    trace.imu_acc[3, 1] = np.nan
    assert trace.non_finite_fields() == ["imu_acc"]


def test_other_format_version_is_refused(tmp_path: Path) -> None:
    path = _tiny_trace().save(tmp_path / "t.npz")
    with np.load(path) as data:
        arrays = dict(data)
    arrays["format_version"] = np.asarray(99)
    np.savez(path, **arrays)
    with pytest.raises(TraceError, match="format_version 99, this software reads 1 or 2"):
        Trace.load(path)


def test_missing_file_names_path(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"nope\.npz"):
        Trace.load(tmp_path / "nope.npz")


def test_a_format_2_file_without_a_derived_field_is_named(simulated: Trace, tmp_path: Path) -> None:
    path = simulated.save(tmp_path / "t.npz")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k != trace_storage.ANGLE_START}
    np.savez(path, **arrays)  # type: ignore[arg-type]
    with pytest.raises(TraceError, match=f"missing field {trace_storage.ANGLE_START}"):
        Trace.load(path)
