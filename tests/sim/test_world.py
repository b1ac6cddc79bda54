"""The world's MJCF text, written directly, against dm_control.mjcf's for the same world (the reference)."""

from __future__ import annotations

import pytest

import sim
from sim import vocab
from sim.random_scenarios import ScenarioOptions, draw_scenario
from sim.scenario import Scenario
from sim.world import SURFACES, build_world, world_xml
from sim.world_mjcf import mjcf_world


def _scenarios() -> list[Scenario]:
    """Every preset, and drawn worlds with what the presets lack: diff2 on rough floors with free
    obstacles, pedestrians, no transients."""
    out = [make(seed) for make in sim.scenario_presets().values() for seed in (0, 1)]
    out += [
        draw_scenario(7, "collision", ScenarioOptions(12.0, environment="outdoor", surface="gravel",
                                                      obstacle_kind="box", robot_model="diff2")),
        draw_scenario(8, "fault", ScenarioOptions(12.0, environment="outdoor", surface="grass",
                                                  robot_model="diff2", transient_density=5.0)),
        draw_scenario(9, "collision", ScenarioOptions(12.0, obstacle_kind="pedestrian", robot_model="diff2")),
        draw_scenario(10, "nominal", ScenarioOptions(12.0, transient_density=0.0)),
    ]  # fmt: skip
    return out


SCENARIOS = _scenarios()


def test_the_scenarios_cover_every_world_feature() -> None:
    assert {s.robot.model for s in SCENARIOS} == {"skid4", "diff2"}
    assert any(SURFACES[s.surface].roughness > 0 and s.robot.model == "diff2" for s in SCENARIOS)
    assert any(not s.transients for s in SCENARIOS)
    assert {ob.kind for s in SCENARIOS for ob in s.obstacles} >= set(vocab.OBSTACLE_KINDS)
    assert {t.kind for s in SCENARIOS for t in s.transients} >= set(vocab.TRANSIENT_KINDS)


@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda s: f"{s.name}-{s.seed}")
def test_world_text_is_dm_controls(scenario: Scenario) -> None:
    xml, _, _ = world_xml(scenario)
    assert xml == mjcf_world(scenario).to_xml_string()


def test_worlds_of_one_unit_do_not_share_robot_arrays() -> None:
    scenario = sim.scenario_presets()["nominal_indoor"](0)
    a, b = build_world(scenario), build_world(scenario)
    assert a.robot.info.wheel_radius is not b.robot.info.wheel_radius
    assert a.robot.info.wheel_radius.tolist() == b.robot.info.wheel_radius.tolist()


@pytest.mark.parametrize("surface", sorted(SURFACES))
def test_every_contact_is_at_least_two_steps_soft(surface: str) -> None:
    """MuJoCo's soft contact is stable when its time constant is at least two physics steps
    (`sim.world.PHYSICS_DT`): every geom pair that can touch, on every floor, with the time constant MuJoCo
    gives their contact (the higher-priority geom's, else the solmix-weighted mean)."""
    allowed = {"indoor": vocab.INDOOR_SURFACES, "outdoor": vocab.OUTDOOR_SURFACES}
    worlds = [build_world(s.replace(surface=surface)) for s in SCENARIOS if surface in allowed[s.environment]]
    assert worlds
    for world in worlds:
        m = world.model
        for i in range(m.ngeom):
            for j in range(i + 1, m.ngeom):
                touch = m.geom_contype[i] & m.geom_conaffinity[j] or m.geom_contype[j] & m.geom_conaffinity[i]
                if not touch or m.geom_bodyid[i] == m.geom_bodyid[j]:
                    continue
                if m.geom_priority[i] != m.geom_priority[j]:
                    tau = m.geom_solref[i if m.geom_priority[i] > m.geom_priority[j] else j, 0]
                else:
                    mix = m.geom_solmix[i] / (m.geom_solmix[i] + m.geom_solmix[j])
                    tau = mix * m.geom_solref[i, 0] + (1 - mix) * m.geom_solref[j, 0]
                assert tau >= 2 * m.opt.timestep - 1e-12, (surface, i, j, tau)
