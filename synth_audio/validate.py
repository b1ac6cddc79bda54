"""Refuse traces the renderer cannot honour, with a message that names the field and what is allowed."""

from __future__ import annotations

import math

import numpy as np

from sim import vocab
from sim.trace import Trace
from synth_audio.config import AudioError
from synth_audio.impacts import MATERIALS
from synth_audio.rolling import SURFACES
from synth_audio.transients import KINDS

MAX_DURATION_S = 3600.0
"""Longest trace rendered in one call, s."""


def check_seed(seed: int) -> int:
    """The seed as a non-negative int, or AudioError."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or int(seed) < 0:
        raise AudioError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def check_trace(trace: Trace) -> None:
    """Raise AudioError naming the first problem that would make the render meaningless."""
    if not isinstance(trace, Trace):
        raise AudioError(f"expected a sim.Trace, got {type(trace).__name__}")
    bad = trace.non_finite_fields()
    if bad:
        raise AudioError(f"trace holds NaN or inf in: {', '.join(bad)}")
    if not (math.isfinite(trace.duration) and 0.0 < trace.duration <= MAX_DURATION_S):
        raise AudioError(
            f"trace.duration {trace.duration} s out of range; allowed: (0, {MAX_DURATION_S:g}] s"
        )
    robot = trace.robot
    t = np.asarray(trace.time)
    if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0):
        raise AudioError("trace.time must hold at least 2 strictly increasing time stamps")
    mic_body = np.asarray(robot.mic_pos_body)
    mic = np.asarray(trace.mic_pos)
    if mic_body.shape != (2, 3) or mic.ndim != 3 or mic.shape[1:] != (2, 3) or mic.shape[0] != t.size:
        raise AudioError(
            "trace has no usable microphone sites: robot.mic_pos_body must be (2, 3) and trace.mic_pos "
            f"(len(time), 2, 3); got {mic_body.shape} and {mic.shape}"
        )
    if float(np.linalg.norm(mic_body[0] - mic_body[1])) < 1e-4:
        raise AudioError("robot.mic_pos_body: left and right microphones coincide")
    w = len(robot.wheel_names)
    if w < 1:
        raise AudioError("robot.wheel_names is empty: no driven wheel to render")
    for name in ("wheel_angle", "wheel_speed", "wheel_torque"):
        shape = np.shape(getattr(trace, name))
        if shape != (t.size, w):
            raise AudioError(f"trace.{name} has shape {shape}, expected ({t.size}, {w})")
    if np.shape(robot.wheel_pos_body) != (w, 3) or np.shape(robot.wheel_radius) != (w,):
        raise AudioError(f"robot.wheel_pos_body must be ({w}, 3) and robot.wheel_radius ({w},)")
    if np.any(np.asarray(robot.wheel_radius) <= 0):
        raise AudioError("robot.wheel_radius must be > 0")
    if np.shape(trace.base_quat) != (t.size, 4) or np.shape(trace.base_linvel) != (t.size, 3):
        raise AudioError("trace.base_quat must be (len(time), 4) and trace.base_linvel (len(time), 3)")
    positive = {
        "robot.mass": robot.mass,
        "robot.gear_ratio": robot.gear_ratio,
        "robot.pinion_teeth": robot.pinion_teeth,
        "robot.motor_pole_pairs": robot.motor_pole_pairs,
        "robot.pwm_hz": robot.pwm_hz,
        "robot.tread_blocks": robot.tread_blocks,
    }
    for name, value in positive.items():
        if not value > 0:
            raise AudioError(f"{name} must be > 0, got {value!r}")
    if trace.environment not in vocab.ENVIRONMENTS:
        raise AudioError(
            f"unknown environment {trace.environment!r}; allowed: {', '.join(vocab.ENVIRONMENTS)}"
        )
    if trace.surface not in SURFACES:
        raise AudioError(f"unknown surface {trace.surface!r}; allowed: {', '.join(SURFACES)}")
    _check_contacts(trace)
    _check_transients(trace, w)
    _check_faults(trace, w)


def _check_contacts(trace: Trace) -> None:
    c = trace.contacts
    k = np.shape(c.time)[0] if np.ndim(c.time) else -1
    for name in ("impulse", "normal_speed", "duration"):
        if np.shape(getattr(c, name)) != (k,):
            raise AudioError(f"contacts.{name} has shape {np.shape(getattr(c, name))}, expected ({k},)")
    if np.shape(c.position) != (k, 3) or len(c.material) != k:
        raise AudioError(f"contacts.position must be ({k}, 3) and contacts.material hold {k} names")
    for i, material in enumerate(c.material):
        if material not in MATERIALS:
            raise AudioError(
                f"unknown material {material!r} in contacts.material[{i}]; allowed: {', '.join(MATERIALS)}"
            )
    if np.any(np.asarray(c.impulse) < 0) or np.any(np.asarray(c.duration) < 0):
        raise AudioError("contacts.impulse and contacts.duration must be >= 0")


def _check_transients(trace: Trace, n_wheels: int) -> None:
    tr = trace.transients
    k = np.shape(tr.time)[0] if np.ndim(tr.time) else -1
    if np.shape(tr.impulse) != (k,) or np.shape(tr.wheel) != (k,) or len(tr.kind) != k:
        raise AudioError(f"transients: time, impulse, wheel and kind must all hold {k} entries")
    for i, kind in enumerate(tr.kind):
        if kind not in KINDS:
            raise AudioError(
                f"unknown transient kind {kind!r} in transients.kind[{i}]; allowed: {', '.join(KINDS)}"
            )
    wheels = np.asarray(tr.wheel)
    if wheels.size and (np.any(wheels < 0) or np.any(wheels >= n_wheels)):
        raise AudioError(f"transients.wheel out of range; allowed: 0..{n_wheels - 1}")
    if np.any(np.asarray(tr.impulse) < 0):
        raise AudioError("transients.impulse must be >= 0")


def _check_faults(trace: Trace, n_wheels: int) -> None:
    for i, fault in enumerate(trace.faults):
        if fault.kind not in vocab.FAULT_KINDS:
            raise AudioError(
                f"unknown fault kind {fault.kind!r} in faults[{i}]; allowed: {', '.join(vocab.FAULT_KINDS)}"
            )
        if not 0 <= fault.wheel < n_wheels:
            raise AudioError(f"faults[{i}].wheel {fault.wheel} out of range; allowed: 0..{n_wheels - 1}")
        values = (
            fault.severity,
            fault.onset,
            fault.duration,
            fault.defect_order,
            fault.resonance_hz,
            fault.damping_ratio,
        )
        if not all(math.isfinite(v) for v in values):
            raise AudioError(f"faults[{i}] holds NaN or inf")
        if not 0.0 <= fault.severity <= 1.0:
            raise AudioError(f"faults[{i}].severity {fault.severity} out of range; allowed: 0..1")
        if fault.duration < 0 or fault.resonance_hz <= 0 or fault.damping_ratio <= 0:
            raise AudioError(f"faults[{i}]: duration must be >= 0, resonance_hz and damping_ratio > 0")
