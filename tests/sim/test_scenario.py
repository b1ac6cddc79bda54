"""Scenario validation, TOML/dict round trips and randomised scenarios."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from sim_kit import straight

from sim import (
    ScenarioError,
    ScenarioOptions,
    draw_scenario,
    scenario_presets,
    simulate,
    vocab,
)
from sim.robot import asset_path
from sim.scenario import Fault, Obstacle, Route, Scenario, Unit, Waypoint


def test_dict_round_trip_is_exact_and_json_able() -> None:
    sc = draw_scenario(5, "collision", ScenarioOptions(duration=90.0, obstacle_kind="pedestrian"))
    data = json.loads(json.dumps(sc.to_dict()))
    assert Scenario.from_dict(data) == sc


def test_fault_duration_inf_round_trips() -> None:
    sc = straight(faults=(Fault("bearing", 1, 0.5, 1.0),))
    assert sc.faults[0].duration == math.inf
    assert Scenario.from_dict(json.loads(json.dumps(sc.to_dict()))) == sc


@pytest.mark.parametrize(
    ("change", "field", "value"),
    [
        (lambda: Fault("cracked_rim", 0, 0.5, 1.0), "fault.kind", "cracked_rim"),
        (lambda: Fault("bearing", 0, 1.5, 1.0), "fault.severity", "1.5"),
        (lambda: Fault("bearing", 0, -0.1, 1.0), "fault.severity", "-0.1"),
        (lambda: Fault("bearing", 7, 0.5, 1.0), "fault.wheel", "7"),
        (lambda: Waypoint(1.0, 0.0, speed=-0.5), "route.waypoint.speed", "-0.5"),
        (lambda: Obstacle("sofa", 0.0, 0.0), "obstacle.kind", "sofa"),
        (lambda: Unit(model="hexapod"), "robot.model", "hexapod"),
    ],
)
def test_bad_parts_are_refused_naming_field_value_allowed(change, field: str, value: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ScenarioError, match="allowed") as info:
        change()
    assert field in str(info.value)
    assert value in str(info.value)


def test_wheel_outside_robot_is_refused() -> None:
    with pytest.raises(ScenarioError, match=r"faults\[0\]\.wheel = 2 .*0 \.\. 1 for robot diff2"):
        straight(model="diff2", faults=(Fault("out_of_round", 2, 0.5, 1.0),))


def test_onset_after_end_is_refused() -> None:
    with pytest.raises(ScenarioError, match=r"faults\[0\]\.onset = 9\.0 .*allowed: 0 \.\. 6 s"):
        straight(duration=6.0, faults=(Fault("out_of_round", 0, 0.5, 9.0),))


def test_obstacle_outside_arena_is_refused() -> None:
    with pytest.raises(ScenarioError, match=r"obstacles\[0\]\.position = \(20\.0, 0\.0\).*inside the arena"):
        straight(obstacles=(Obstacle("box", 20.0, 0.0),))


def test_unknown_surface_and_wrong_environment_are_refused() -> None:
    with pytest.raises(ScenarioError, match=r"surface = 'lava'.*tile"):
        straight().replace(surface="lava")
    with pytest.raises(ScenarioError, match=r"surface \(for indoor\) = 'grass'.*tile, carpet, concrete"):
        straight().replace(surface="grass")


def test_unknown_toml_key_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text('name = "x"\nseed = 1\nduration = 5.0\nspeeed = 2\n')
    with pytest.raises(ScenarioError, match=r"scenario key = 'speeed'.*allowed: name, seed, duration"):
        Scenario.from_toml(path)
    fault = '[[faults]]\nkind = "bearing"\nwheel = 0\nseverity = 0.5\nonset = 1.0\nphase = 2\n'
    path.write_text('name = "x"\nseed = 1\nduration = 5.0\n' + fault)
    with pytest.raises(ScenarioError, match=r"faults\[0\] key = 'phase'"):
        Scenario.from_toml(path)


def test_missing_toml_file_names_path(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"nope\.toml"):
        Scenario.from_toml(tmp_path / "nope.toml")


def test_shipped_example_scenarios_load() -> None:
    folder = Path(asset_path("scenarios/nominal_indoor.toml")).parent
    files = sorted(folder.glob("*.toml"))
    assert len(files) >= 3
    for path in files:
        sc = Scenario.from_toml(path)
        assert sc.name


def test_draw_scenario_depends_only_on_its_arguments() -> None:
    a = draw_scenario(11, "fault", ScenarioOptions(duration=120.0, fault_kind="bearing"))
    b = draw_scenario(11, "fault", ScenarioOptions(duration=120.0, fault_kind="bearing"))
    c = draw_scenario(12, "fault", ScenarioOptions(duration=120.0, fault_kind="bearing"))
    assert a == b
    assert a != c
    assert a.faults[0].kind == "bearing" and 0.3 <= a.faults[0].severity <= 1.0
    assert 0.0 < a.faults[0].onset < a.duration


def test_draw_scenario_keeps_what_the_options_give() -> None:
    options = ScenarioOptions(
        duration=30.0, environment="indoor", fault_kind="out_of_round", wheel=2, unit_id=5, surface="carpet"
    )
    drawn = draw_scenario(4, "fault", options)
    assert (drawn.surface, drawn.robot.unit_id, drawn.faults[0].wheel) == ("carpet", 5, 2)
    assert (drawn.environment, drawn.faults[0].kind, drawn.duration) == ("indoor", "out_of_round", 30.0)


def test_a_given_surface_changes_the_floor_and_nothing_else() -> None:
    drawn = draw_scenario(5, "nominal", ScenarioOptions(duration=60.0, environment="outdoor"))
    other = next(f for f in ("asphalt", "gravel") if f != drawn.surface)
    given = draw_scenario(5, "nominal", ScenarioOptions(duration=60.0, environment="outdoor", surface=other))
    assert given.surface == other
    assert dataclasses.replace(given, surface=drawn.surface) == drawn


@pytest.mark.parametrize("category", ["nominal", "collision", "fault"])
@pytest.mark.parametrize("duration", [20.0, 340.0])
def test_drawn_scenarios_are_valid_for_short_and_long_episodes(category: str, duration: float) -> None:
    for seed in range(3):
        sc = draw_scenario(
            seed, category, ScenarioOptions(duration=duration, robot_model="diff2" if seed == 2 else "skid4")
        )
        assert sc.route.loop and len(sc.route.waypoints) >= 2
        assert len(sc.transients) >= 2
        hits = [w for w in sc.route.waypoints if w.ram >= 0 and w.stop_short == 0]
        assert (len(hits) >= 1) == (category == "collision")
        assert all(w.ram == 0 for w in hits)  # only the collision target is driven into
        if category == "collision":
            assert sc.route.waypoints[1] == hits[0]  # the hit is the route's second leg


def test_every_category_draws_the_same_manoeuvres() -> None:
    # Near misses, back-outs, emergency stops and the reflex are nominal driving: every category has them.
    for category in ("nominal", "collision", "fault"):
        counts = {"near": 0, "back": 0, "estop": 0}
        reflexes = set()
        for seed in range(8):
            sc = draw_scenario(seed, category, ScenarioOptions(duration=120.0))
            wps = sc.route.waypoints
            counts["near"] += sum(w.stop_short > 0 for w in wps)
            counts["back"] += sum(w.reverse for w in wps)
            counts["estop"] += sum(w.hard_stop for w in wps)
            reflexes.add(sc.route.reflex.kind)
        assert min(counts.values()) >= 3, (category, counts)
        assert len(reflexes) >= 2, (category, reflexes)


def test_obstacles_stand_where_they_belong() -> None:
    for seed in range(6):
        for kind, where in (("door", "indoor"), ("desk", "indoor"), ("curb", "outdoor")):
            assert (
                draw_scenario(
                    seed, "collision", ScenarioOptions(duration=24.0, obstacle_kind=kind)
                ).environment
                == where
            )
    with pytest.raises(ScenarioError, match=r"environment = 'outdoor'.*obstacle_kind 'door'.*indoor"):
        draw_scenario(
            0, "collision", ScenarioOptions(duration=24.0, obstacle_kind="door", environment="outdoor")
        )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"category": "crash"}, "category = 'crash'.*nominal, collision, fault"),
        ({"obstacle_kind": "sofa"}, "obstacle_kind = 'sofa'"),
        ({"fault_kind": "rust"}, "fault_kind = 'rust'"),
        ({"wheel": 4}, "wheel = 4.*0 .. 3"),
        ({"severity": (0.5, 1.2)}, r"severity = \(0.5, 1.2\)"),
        ({"environment": "moon"}, "environment = 'moon'"),
        ({"duration": -1.0}, "duration = -1.0"),
        ({"environment": "indoor", "surface": "grass"}, "surface = 'grass'.*indoor.*tile, carpet, concrete"),
        ({"surface": "tile"}, "surface = 'tile' needs an environment"),
    ],
)
def test_draw_scenario_refuses_bad_arguments(kwargs: dict, message: str) -> None:  # type: ignore[type-arg]
    args = {"category": "fault", "duration": 30.0, **kwargs}
    category = args.pop("category")
    duration = args.pop("duration")
    with pytest.raises(ScenarioError, match=message):
        draw_scenario(0, category, ScenarioOptions(duration=duration, **args))


def test_presets_cover_every_obstacle_and_fault_kind() -> None:
    presets = scenario_presets()
    for kind in vocab.OBSTACLE_KINDS:
        sc = presets[f"collision_{kind}"](1)
        assert sc.obstacles[0].kind == kind
    for kind in vocab.FAULT_KINDS:
        assert presets[f"fault_{kind}"](1).faults[0].kind == kind
    assert {"nominal_indoor", "nominal_outdoor"} <= set(presets)


def test_route_refuses_ram_at_missing_obstacle() -> None:
    with pytest.raises(ScenarioError, match=r"route.waypoints\[0\].ram = 2"):
        straight().replace(route=Route(waypoints=(Waypoint(1.0, 0.0, ram=2),)))


def test_benign_bumps_per_second_do_not_grow_with_the_episode_length() -> None:
    # A long route crisscrosses its arena; laying strips per second of episode made a 343 s nominal
    # sequence meet ~3x more bumps per second than a 37 s fault episode. The wheels' actual encounters:
    def rate(category: str, duration: float) -> float:
        events = [
            len(simulate(draw_scenario(s, category, ScenarioOptions(duration=duration))).transients.time)
            for s in range(2)
        ]
        return sum(events) / (2 * duration)

    long_nominal, short_fault = rate("nominal", 343.0), rate("fault", 37.0)
    assert 0.5 < long_nominal / short_fault < 2.0, (long_nominal, short_fault)
    assert 0.25 < long_nominal < 1.0  # four wheels over one strip every ~8 s: ~0.5 events/s


def test_clearance_is_the_plain_distance_to_every_footprint_and_walked_path_with_its_cache_full() -> None:
    """The sampler's clearance (footprints kept per obstacle list, compiled loops) against the plain numpy
    distances: to each rotated rectangle, and to each pedestrian's walked points less its radius; over more
    obstacle lists than the cache keeps, so that lists dropped from it are made again."""
    from sim import random_scenarios as rs

    rng = np.random.default_rng(5)

    def obstacle(kind: str) -> Obstacle:
        x, y, yaw = rng.uniform(-4, 4), rng.uniform(-3, 3), rng.uniform(-math.pi, math.pi)
        if kind == "pedestrian":
            path = ((x + rng.uniform(-2, 2), y + rng.uniform(-2, 2)),)
            return Obstacle(kind, x, y, 0.0, (0.25, 0.25, 0.9), path=path, walk_speed=1.0)
        return Obstacle(kind, x, y, yaw, (rng.uniform(0.2, 0.8), rng.uniform(0.2, 0.6), 0.5))

    def plain(points: np.ndarray, obstacles: list[Obstacle]) -> float:
        best = math.inf
        for ob in obstacles:
            c, s = math.cos(ob.yaw), math.sin(ob.yaw)
            rel = points - np.array([ob.x, ob.y])
            local = np.abs(np.stack([rel @ np.array([c, s]), rel @ np.array([-s, c])], axis=1))
            excess = np.maximum(local - np.array(ob.size[:2]), 0.0)
            best = min(best, float(np.linalg.norm(excess, axis=1).min()))
            if ob.path:
                start = np.array([ob.x, ob.y])
                line = start + np.linspace(0.0, 1.0, 50)[:, None] * (np.array(ob.path[-1]) - start)
                walked = np.concatenate([np.array(ob.path), line])
                best = min(best, float(np.linalg.norm(points[:, None] - walked, axis=-1).min()) - ob.size[0])
        return best

    lists = [[obstacle(k) for k in rng.choice(["box", "desk", "pedestrian"], size=4)] for _ in range(40)]
    for round_ in range(rs._FOOTPRINTS_KEPT // len(lists) + 2):  # more lists than kept: some made again
        for obstacles in lists if round_ % 2 == 0 else [list(reversed(o)) for o in lists]:
            points = rng.uniform(-5, 5, size=(int(rng.integers(1, 30)), 2))
            # rectangles alike to rounding; the plain walked line is sampled more finely than the sampler's
            # (every 0.2 m), so with a pedestrian they agree within 0.1 m
            walking = any(ob.path for ob in obstacles)
            expected = pytest.approx(plain(points, obstacles), abs=0.1 if walking else 1e-12)
            assert rs._clearance(points, obstacles) == expected
    assert len(rs._footprints_made) <= rs._FOOTPRINTS_KEPT
    assert rs._clearance(np.zeros((3, 2)), []) == math.inf
