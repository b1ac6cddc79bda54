"""Fixtures of the simulator tests."""

from __future__ import annotations

import pytest
from sim_kit import straight

from sim.scenario import Scenario


@pytest.fixture
def straight_scenario() -> Scenario:
    """Six seconds of straight driving at 1 m/s."""
    return straight()
