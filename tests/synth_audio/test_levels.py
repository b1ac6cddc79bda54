"""Physical levels at the microphones (`level_kit`): a clear threshold clack, soft bodies, the impulse law."""

from __future__ import annotations

import pytest
from level_kit import bump_level, drive_level, hit_level


def test_a_wheel_crossing_a_threshold_at_1_3_m_s_is_a_clear_clack() -> None:
    rms, peak = drive_level(1.3)
    clack = bump_level("threshold", 1.3)
    assert clack >= rms + 15.0
    assert clack >= peak + 6.0


def test_the_reference_drive_is_near_its_stated_level() -> None:
    rms, _ = drive_level(0.7)  # the unit's reference drive is 68 dB SPL at 0.6 m/s, turning torque
    assert 64.0 < rms < 72.0


@pytest.mark.parametrize("speed", [0.3, 0.7, 1.3])
def test_a_pedestrian_is_quieter_than_a_wall_met_at_the_same_speed(speed: float) -> None:
    assert hit_level("pedestrian", speed) < hit_level("wall", speed) - 6.0


def test_a_wall_hit_grows_with_the_approach_speed_and_stays_under_full_scale() -> None:
    slow, mid, fast = (hit_level("wall", v) for v in (0.3, 0.7, 1.3))
    assert slow < mid < fast < 120.0  # 0 dBFS = 120 dB SPL: the limiter is a last resort
