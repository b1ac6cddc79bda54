"""Gymnasium and dm_env environments over the simulator."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from dm_env import StepType
from gymnasium.utils.env_checker import check_env
from sim_kit import straight

import sim
from sim import Fault, Obstacle, make_dm_env, make_env
from sim.engine import CONTROL_STEPS
from sim.world import PHYSICS_DT

PERIOD = CONTROL_STEPS * PHYSICS_DT
"""One environment step, s."""


def test_registered_env_passes_check_env() -> None:
    env = gym.make("robot_anomaly/DiffDrive-v0")
    check_env(env.unwrapped, skip_render_check=True)


def test_reset_is_deterministic_per_seed_and_drives() -> None:
    env = make_env(straight(duration=2.0))
    obs_a, _ = env.reset(seed=5)
    obs_b, _ = env.reset(seed=5)
    np.testing.assert_array_equal(obs_a, obs_b)
    assert env.observation_space.contains(obs_a)
    total = 0.0
    for _ in range(20):
        _, reward, _, _, info = env.step(np.array([0.6, 0.6], dtype=np.float32))
        total += reward
        assert info["label"] == 0 and info["contacts"] == []
    assert total > 0.3  # moved forward


def test_info_labels_faults_and_collisions() -> None:
    scenario = straight(
        duration=5.0, faults=(Fault("bearing", 1, 0.8, 0.0),), obstacles=(Obstacle("box", -9.0, 0.0),)
    )
    env = make_env(scenario)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert (
        info["label"] == sim.vocab.MECHANICAL and info["sub_kind"] == "bearing" and info["label_wheel"] == 1
    )
    seen = []
    for _ in range(40):
        info = env.step(np.array([1.0, 1.0], dtype=np.float32))[4]
        seen += [c["obstacle_kind"] for c in info["contacts"]]
        if seen:
            assert info["label"] == sim.vocab.COLLISION and info["sub_kind"] == "box"
            break
    assert seen == ["box"]


def test_episode_truncates_at_scenario_duration() -> None:
    env = make_env(straight(duration=0.5))
    env.reset(seed=1)
    steps = 0
    truncated = False
    while not truncated:
        truncated = env.step(np.zeros(2, dtype=np.float32))[3]
        steps += 1
    assert steps == pytest.approx(0.5 / PERIOD, abs=1)


def test_dm_env_specs_reset_and_step() -> None:
    env = make_dm_env(straight(duration=10 * PERIOD), seed=2)
    spec = env.observation_spec()
    assert spec["imu"].shape == (7,) and spec["wheels"].shape == (8,)
    action = env.action_spec()
    assert action.shape == (2,) and float(action.minimum) == -1.0 and float(action.maximum) == 1.0
    first = env.reset()
    assert first.step_type == StepType.FIRST and first.reward is None
    for key, value in first.observation.items():
        spec[key].validate(value)
        assert np.all(np.isfinite(value))
    kinds = []
    while True:
        ts = env.step(np.array([0.5, -0.5], dtype=np.float32))
        kinds.append(ts.step_type)
        if ts.last():
            break
    assert kinds[:-1] == [StepType.MID] * (len(kinds) - 1) and len(kinds) == 10
    assert env.step(np.zeros(2, dtype=np.float32)).step_type == StepType.FIRST


def test_make_dm_env_default_scenario() -> None:
    env = make_dm_env(seed=4)
    ts = env.reset()
    assert ts.observation["wheels"].dtype == np.float32


def test_observations_and_labels_are_the_traces_own() -> None:
    """The env's IMU observation and label at each step equal those of the trace `simulate`'s code assembles
    from the same physics (`assemble_trace`): the same decimation, the same noise, the same labels."""
    from sim.events import LABEL_MARGIN_BEFORE
    from sim.rollout import assemble_trace

    scenario = straight(  # a whole number of steps, as the trace's IMU noise is drawn for its duration
        duration=round(3.0 / PERIOD) * PERIOD,
        faults=(Fault("bearing", 1, 0.8, 0.1),),
        obstacles=(Obstacle("box", -8.5, 0.0),),
    )
    env = make_env(scenario)
    env.reset()
    physics, observed, infos = [], [], []
    while True:
        obs, _, _, truncated, info = env.step(np.array([1.0, 1.0], dtype=np.float32))
        physics.append(env._buffer.copy())
        observed.append(obs)
        infos.append(info)
        if truncated:
            break
    trace = assemble_trace(scenario, env.world, np.concatenate(physics), env.engine.dt)
    per_step = len(trace.imu_time) // len(observed)
    last = np.arange(1, len(observed) + 1) * per_step - 1
    imu = np.concatenate([trace.imu_acc, trace.imu_gyro, trace.imu_vel_z[:, None]], axis=1)[last]
    np.testing.assert_allclose(np.stack(observed)[:, :7], imu.astype(np.float32), rtol=0, atol=0)
    times = np.array([i["time"] for i in infos])
    np.testing.assert_allclose(trace.imu_time[last], times, rtol=0, atol=1e-9)
    got = np.array([i["label"] for i in infos])
    want = trace.label[last]
    assert {sim.vocab.MECHANICAL, sim.vocab.COLLISION} <= set(got.tolist())
    first_step = float(trace.contacts.time[0]) - env.engine.dt  # the contact's first physics step starts here
    acausal = (times >= first_step - LABEL_MARGIN_BEFORE - 1e-9) & (times < first_step + env.engine.dt)
    np.testing.assert_array_equal(got[~acausal], want[~acausal])
    subs = [sim.vocab.SUB_KINDS[k] for k in trace.sub_kind[last]]
    assert [i["sub_kind"] for i in np.array(infos)[~acausal]] == list(np.array(subs)[~acausal])


def _for_model(scenario: sim.Scenario, model: str) -> sim.Scenario:
    """`scenario` driven by robot `model` (a fault on a wheel the model lacks moves to wheel % its wheels)."""
    wheels = len(sim.scenario.wheel_names(model))
    faults = tuple(dataclasses.replace(f, wheel=f.wheel % wheels) for f in scenario.faults)
    return scenario.replace(robot=dataclasses.replace(scenario.robot, model=model), faults=faults)


@pytest.mark.parametrize("model", sim.scenario.ROBOT_MODELS)
@pytest.mark.parametrize("preset", list(sim.scenario_presets()))
def test_every_scenario_preset_runs_for_every_robot_model(preset: str, model: str) -> None:
    """dm_control's suite test, here: each scenario preset for each robot model loads, resets and steps
    with random actions, and every observation conforms to its spec and is finite."""
    scenario = _for_model(sim.scenario_presets()[preset](3), model)
    env = make_dm_env(scenario, seed=3)
    spec = env.observation_spec()
    assert spec["wheels"].shape == (2 * len(sim.scenario.wheel_names(model)),)
    rng = np.random.default_rng(0)
    ts = env.reset()
    for _ in range(12):
        for key, value in ts.observation.items():
            spec[key].validate(value)
            assert np.all(np.isfinite(value)), (preset, model, key)
        assert env.last_info["label"] in (sim.vocab.NORMAL, sim.vocab.COLLISION, sim.vocab.MECHANICAL)
        ts = env.step(rng.uniform(-1, 1, 2).astype(np.float32))


@pytest.mark.parametrize("chunk", [1, 7, 16])
def test_contact_runs_built_chunk_by_chunk_equal_the_whole_episodes(chunk: int) -> None:
    from sim.events import extend_runs, runs

    mask = np.random.default_rng(chunk).random(500) < 0.15
    found: list[tuple[int, int]] = []
    for start in range(0, mask.size, chunk):
        extend_runs(found, start + np.flatnonzero(mask[start : start + chunk]), 4)
    assert found == runs(mask, 4) and len(found) > 5
