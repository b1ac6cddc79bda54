"""Window labelling and episode planning: hand cases with a known answer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from benchmarks.dataset import label_windows, nominal_floors, plan_episodes, window_starts
from benchmarks.errors import UserError
from benchmarks.presets import get_preset, preset_names
from sim.random_scenarios import SETTLE_S
from sim.vocab import COLLISION, MECHANICAL, NORMAL, SURFACES, sub_kind_index

RATE = 200


def _timeline(seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = int(seconds * RATE)
    return np.zeros(n, np.int8), np.zeros(n, np.int16), -np.ones(n, np.int8)


def test_window_starts_cover_whole_windows_only() -> None:
    np.testing.assert_allclose(window_starts(10.0, 2.0, first_s=0.0), [0, 2, 4, 6, 8])
    np.testing.assert_allclose(window_starts(5.5, 1.0, first_s=0.0), [0, 1, 2, 3])
    assert window_starts(1.5, 1.0, first_s=0.0).size == 0
    with pytest.raises(UserError, match=r"hop_s = 0\.0 is invalid"):
        window_starts(10.0, 0.0)


def test_windows_start_once_the_robot_is_under_way() -> None:
    assert SETTLE_S == 2.0
    np.testing.assert_allclose(window_starts(10.0, 2.0), [2, 4, 6, 8])
    assert window_starts(3.5, 1.0).size == 0


def test_collision_sample_makes_a_collision_window() -> None:
    label, sub, wheel = _timeline(8.0)
    label[int(3.1 * RATE) : int(3.2 * RATE)] = COLLISION
    sub[int(3.1 * RATE) : int(3.2 * RATE)] = sub_kind_index("door")
    out = label_windows(label, sub, wheel, np.array([0.0, 2.0, 4.0, 6.0]))
    assert out == [(NORMAL, "none", -1), (COLLISION, "door", -1), (NORMAL, "none", -1), (NORMAL, "none", -1)]


def test_mechanical_needs_half_the_window_and_partial_is_ambiguous() -> None:
    label, sub, wheel = _timeline(8.0)
    onset = int(3.5 * RATE)  # fault active from 3.5 s on
    label[onset:] = MECHANICAL
    sub[onset:] = sub_kind_index("bearing")
    wheel[onset:] = 2
    out = label_windows(label, sub, wheel, np.array([0.0, 2.0, 3.0, 4.0, 6.0]))
    # [2, 4): 0.5 s of fault -> ambiguous; [3, 5): 1.5 s -> mechanical; later windows: mechanical.
    assert out == [(NORMAL, "none", -1), None, (MECHANICAL, "bearing", 2), (MECHANICAL, "bearing", 2),
                   (MECHANICAL, "bearing", 2)]  # fmt: skip


@pytest.mark.parametrize("name", preset_names())
def test_plans_are_deterministic_and_cover_every_kind(name: str) -> None:
    preset = get_preset(name)
    plan = plan_episodes(preset, 3)
    assert plan == plan_episodes(preset, 3)
    assert plan != plan_episodes(preset, 4)
    assert len({s.episode_id for s in plan}) == len(plan)
    assert {s.options.obstacle_kind for s in plan if s.category == "collision"} == set(preset.obstacle_kinds)
    assert {(s.options.fault_kind, s.options.wheel) for s in plan if s.category == "fault"} == {
        (f, w) for f in preset.fault_kinds for w in preset.wheels
    }
    train = [s for s in plan if s.split in ("train", "val")]
    assert all(s.category == "nominal" for s in train)
    assert sum(s.split == "val" for s in plan) == preset.nominal_val
    assert {s.unit_id for s in train} <= set(preset.train_units)
    assert {s.unit_id for s in plan if s.split == "test"} <= set(preset.test_units)


@pytest.mark.parametrize("name", ["paper", "hard"])
def test_nominal_training_and_test_sequences_each_cover_every_surface(name: str) -> None:
    plan = plan_episodes(get_preset(name), 0)
    for splits in (("train",), ("test",)):
        floors = {s.options.surface for s in plan if s.category == "nominal" and s.split in splits}
        assert floors == set(SURFACES), splits


def test_paper_preset_has_the_papers_size() -> None:
    plan = plan_episodes(get_preset("paper"), 0)
    nominal = [s for s in plan if s.category == "nominal"]
    assert sum(s.split in ("train", "val") for s in nominal) == 48
    hours = sum(s.options.duration for s in nominal) / 3600
    assert hours == pytest.approx(3.0, abs=0.1)


@pytest.mark.parametrize("name", ["paper", "hard"])
def test_many_short_test_nominal_sequences_cover_every_floor_and_unit(name: str) -> None:
    preset = get_preset(name)
    plan = plan_episodes(preset, 0)
    test = [s for s in plan if s.category == "nominal" and s.split == "test"]
    assert len(test) >= 36
    floors = [(s.options.environment, s.options.surface) for s in test]
    assert set(floors) == set(nominal_floors())
    assert min(floors.count(f) for f in set(floors)) >= 5  # every floor several times, not once
    for floor in set(floors):  # every floor is driven by every test unit
        assert {s.unit_id for s in test if (s.options.environment, s.options.surface) == floor} == set(
            preset.test_units
        )


@pytest.mark.parametrize("name", preset_names())
def test_snr_is_drawn_uniformly_inside_the_presets_range(name: str) -> None:
    preset = get_preset(name)
    low, high = preset.snr_db
    snr = np.array([s.snr_db for s in plan_episodes(preset, 0)])
    assert np.all((snr >= low) & (snr <= high))
    if high > low:
        assert np.unique(snr).size == snr.size  # continuous draws, not a few values chosen from
        for split in ("train", "test"):  # every split draws from the whole range
            part = np.array([s.snr_db for s in plan_episodes(preset, 0) if s.split == split])
            assert part.min() < low + 0.25 * (high - low) and part.max() > high - 0.25 * (high - low)


def test_an_snr_range_must_be_low_high() -> None:
    import dataclasses

    with pytest.raises(ValueError, match="snr_db must be a \\(low, high\\) range"):
        dataclasses.replace(get_preset("tiny"), snr_db=(6.0, 0.0))


def test_unknown_preset_names_the_allowed_ones() -> None:
    with pytest.raises(ValueError, match="unknown preset 'huge'; allowed: tiny, quick, paper, hard"):
        get_preset("huge")


def test_method_groups_expand_to_registered_methods() -> None:
    from benchmarks import methods
    from benchmarks.presets import ABLATION_METHODS, TABLE1_METHODS, expand_methods

    registered = methods.names()
    assert set(TABLE1_METHODS) <= set(registered) and set(ABLATION_METHODS) <= set(registered)
    assert expand_methods(["table1", "msvdd"], registered) == list(TABLE1_METHODS)
    assert expand_methods(["ablations"], registered)[0] == "msvdd"
    assert expand_methods(["all"], registered) == registered


def test_anomalous_windows_of_nominal_episodes_are_left_out_and_listed(tmp_path: Path) -> None:
    from benchmarks.dataset import _window_rows

    preset = get_preset("tiny")
    spec = next(s for s in plan_episodes(preset, 0) if s.category == "nominal")
    label, sub, wheel = _timeline(6.0)
    label[int(4.5 * RATE) : int(4.6 * RATE)] = COLLISION  # the route grazed an obstacle
    sub[int(4.5 * RATE) : int(4.6 * RATE)] = sub_kind_index("pedestrian")
    (tmp_path / spec.episode_id).mkdir()
    np.savez(tmp_path / spec.episode_id / "imu.npz", label=label, sub_kind=sub, label_wheel=wheel,
             wheel_pos=np.zeros((label.size, 0)))  # fmt: skip
    rows, dropped = _window_rows(tmp_path, preset, [spec])
    assert all(r.kind == "normal" for r in rows)
    assert {d.start_s for d in dropped} == {3.0, 3.5, 4.0} and {d.sub_kind for d in dropped} == {"pedestrian"}
    assert len(rows) + len(dropped) == window_starts(6.0, preset.train_hop_s).size


def test_a_fault_window_needs_its_faulty_wheel_to_turn_a_revolution() -> None:
    # Wheel 2 is faulty from 1 s; it turns at 0.6 rev/s for 5 s, then stands for 3 s. A window holds the
    # defect only where wheel 2 turned at least once while the fault was active.
    label, sub, wheel = _timeline(8.0)
    label[RATE:], sub[RATE:], wheel[RATE:] = MECHANICAL, sub_kind_index("flat_spot"), 2
    t = np.arange(label.size) / RATE
    turned = 2 * np.pi * 0.6 * np.minimum(t, 5.0)
    wheel_pos = np.zeros((label.size, 4))
    wheel_pos[:, 2] = turned
    wheel_pos[:, 0] = 2 * np.pi * 3.0 * t  # another wheel's turning does not count
    starts = np.array([1.0, 3.0, 4.0, 6.0])
    got = label_windows(label, sub, wheel, starts, wheel_pos)
    assert got[0] == (MECHANICAL, "flat_spot", 2) and got[1] == (MECHANICAL, "flat_spot", 2)
    assert got[2] is None  # 4-6 s: 0.6 revolutions
    assert got[3] is None  # standing
    assert label_windows(label, sub, wheel, starts)[3] == (MECHANICAL, "flat_spot", 2)  # no encoders
