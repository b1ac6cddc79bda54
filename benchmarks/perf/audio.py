"""Audio stage speed: real-time factor of the full binaural mix at 44.1 kHz on one core, and its cost against
the reference kernel (`benchmarks.perf.base.fft_reference_s`: one FFT convolution of the rendered audio's
length) measured in the same process just before each environment's renders."""

from __future__ import annotations

import os
import time

import numpy as np

from benchmarks.perf.base import PerfStage, fft_reference_s
from sim.trace import ContactEvents, FaultRecord, RobotInfo, Trace, TransientEvents
from sim.vocab import TRANSIENT_HEIGHT


def _robot() -> RobotInfo:
    """The default robot unit as the simulator builds it (real geometry, compiled mass)."""
    import sim
    from sim.world import build_world

    return build_world(sim.scenario_presets()["nominal_indoor"](0)).robot.info


def workload(duration: float, environment: str = "indoor") -> Trace:
    """A driving trace with speed changes, collisions, benign transients and a bearing fault."""
    dt = 0.002
    t = np.arange(0.0, duration + dt / 2, dt)
    n = t.size
    omega = 10.0 + 4.0 * np.sin(2 * np.pi * 0.2 * t)
    omega4 = np.stack([omega, omega * 1.02, omega, omega * 1.02], axis=1)
    angle = np.concatenate([np.zeros((1, 4)), np.cumsum(0.5 * (omega4[1:] + omega4[:-1]) * dt, axis=0)])
    torque = 0.05 + 0.1 * np.gradient(omega4, dt, axis=0) / 10.0
    yaw = 0.1 * t
    quat = np.stack([np.cos(yaw / 2), np.zeros(n), np.zeros(n), np.sin(yaw / 2)], axis=1)
    robot = _robot()
    k = max(int(duration / 4), 1)
    rng = np.random.default_rng(0)
    contacts = ContactEvents(
        time=np.sort(rng.uniform(0, duration, k)),
        position=np.tile([0.3, 0.0, 0.1], (k, 1)),
        normal=np.tile([-1.0, 0, 0], (k, 1)),
        impulse=rng.uniform(1, 5, k),
        normal_speed=rng.uniform(0.2, 1, k),
        duration=rng.uniform(0.01, 0.3, k),
        obstacle_kind=("wall",) * k,
        material=("plaster",) * k,
    )
    m = 2 * k
    transients = TransientEvents(
        time=np.sort(rng.uniform(0, duration, m)),
        position=np.zeros((m, 3)),
        wheel=rng.integers(0, 4, m),
        impulse=rng.uniform(0.5, 3, m),
        kind=("seam", "cable") * k,
        height=np.array([TRANSIENT_HEIGHT[kind] for kind in ("seam", "cable") * k]),
    )
    imu_n = int(duration * 200) + 1
    return Trace(
        "perf",
        0,
        environment,
        "concrete",
        duration,
        dt,
        200.0,
        robot,
        np.array([5.0, 5.0]),
        t,
        angle,
        omega4,
        torque,
        np.zeros((n, 3)),
        quat,
        np.zeros((n, 3)),
        np.zeros((n, 3)),
        np.broadcast_to(robot.mic_pos_body, (n, 2, 3)).copy(),
        np.arange(imu_n) / 200.0,
        np.zeros(imu_n),
        np.zeros((imu_n, 3)),
        np.zeros((imu_n, 3)),
        contacts,
        transients,
        (FaultRecord("bearing", 1, 0.7, duration / 2, duration / 2, 3.57, 2100.0, 0.04),),
        (),
        np.zeros((imu_n, 0, 3)),
        np.zeros(imu_n, np.int8),
        np.zeros(imu_n, np.int16),
        -np.ones(imu_n, np.int8),
    )


def _measure(quick: bool) -> dict[str, float]:
    from synth_audio import AudioConfig, render

    duration = 2.0 if quick else 20.0
    repeats = 1 if quick else 5
    figures: dict[str, float] = {}
    fastest_reference = float("inf")
    for environment in ("indoor", "outdoor"):
        trace = workload(duration, environment)
        config = AudioConfig(sample_rate=44100)
        render(trace, config, 0)  # warm the unit's reference level cache and the allocator
        reference = fft_reference_s(round(duration * config.sample_rate), repeats=repeats)
        fastest_reference = min(fastest_reference, reference)
        best = float("inf")
        for r in range(repeats):
            start = time.process_time()
            render(trace, config, r)
            best = min(best, time.process_time() - start)
        figures[f"audio_rtf_{environment}"] = duration / max(best, 1e-9)
        figures[f"audio_vs_fft_{environment}"] = max(best, 1e-9) / reference
    figures["audio_rtf"] = min(figures["audio_rtf_indoor"], figures["audio_rtf_outdoor"])
    figures["audio_vs_fft"] = max(figures["audio_vs_fft_indoor"], figures["audio_vs_fft_outdoor"])
    figures["audio_fft_reference_rtf"] = duration / fastest_reference
    figures["audio_load_average"] = os.getloadavg()[0]
    return figures


STAGE = PerfStage(
    name="audio",
    measure=_measure,
    describe={
        "audio_rtf": "real-time factor of the full binaural mix at 44.1 kHz, one core, worst environment "
        "(target >= 200)",
        "audio_rtf_indoor": "same, indoor (HVAC, babble, doors, reverberation)",
        "audio_rtf_outdoor": "same, outdoor (wind, traffic, birds)",
        "audio_load_average": "1-minute load average when measured (other processes share the cores)",
        "audio_vs_fft": "render CPU time / one FFT convolution of the same length (stereo, 4096 taps) in the "
        "same process, worst environment (lower is better)",
        "audio_vs_fft_indoor": "same, indoor",
        "audio_vs_fft_outdoor": "same, outdoor",
        "audio_fft_reference_rtf": "real-time factor of the reference FFT convolution (the machine's speed)",
    },
    ratios={"audio_vs_fft_indoor": "lower", "audio_vs_fft_outdoor": "lower"},
)
