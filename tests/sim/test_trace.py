"""Trace round trip through .npz, and refusal of files of another format."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim.trace import (
    ContactEvents,
    FaultRecord,
    ObstacleRecord,
    RobotInfo,
    Trace,
    TraceError,
    TransientEvents,
)


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
    transients = TransientEvents(np.zeros(0), np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros(0), ())
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


def test_round_trip_is_bit_exact(tmp_path: Path) -> None:
    trace = _tiny_trace()
    loaded = Trace.load(trace.save(tmp_path / "t.npz"))
    assert loaded.faults == trace.faults
    assert loaded.contacts.obstacle_kind == ("wall",)
    assert loaded.robot.wheel_names == ("fl", "fr")
    np.testing.assert_array_equal(loaded.mic_pos, trace.mic_pos)
    np.testing.assert_array_equal(loaded.obstacles[0].position, trace.obstacles[0].position)
    assert loaded.non_finite_fields() == []


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
    with pytest.raises(TraceError, match="format_version 99"):
        Trace.load(path)


def test_missing_file_names_path(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"nope\.npz"):
        Trace.load(tmp_path / "nope.npz")
