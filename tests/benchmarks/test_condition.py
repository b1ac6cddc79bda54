"""Condition-monitoring signal processing (`benchmarks.condition`) against analytic oracles."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import condition


def test_an_order_locked_tone_has_a_line_of_one_half_and_noise_next_to_none() -> None:
    n, revs = 800, 4.0
    angle = np.linspace(0.0, 2 * np.pi * revs, n, endpoint=False)[None]
    tone = np.cos(3.0 * angle + 0.4)
    lines = condition.order_lines(tone, angle, np.array([3.0, 2.0, 5.0]))
    assert lines[0, 0] == pytest.approx(0.5 * np.sqrt(2.0), rel=1e-9)  # |mean(cos e^-i)| / std(cos)
    assert lines[0, 1] < 1e-9 and lines[0, 2] < 1e-9  # other whole orders over whole revolutions
    noise = np.random.default_rng(0).normal(size=(200, n))
    assert np.median(
        condition.order_lines(noise, np.repeat(angle, 200, axis=0), np.array([3.0]))
    ) < 3 / np.sqrt(n)


def test_a_wheel_that_stands_still_has_no_lines() -> None:
    x = np.random.default_rng(1).normal(size=(1, 400))
    angle = np.full((1, 400), 1.3)
    assert condition.order_lines(x, angle, np.array([1.0]))[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert condition.revolutions(angle)[0] == 0.0


def test_the_squared_envelope_of_an_am_tone_is_its_squared_modulation() -> None:
    rate, n = 4000.0, 4000
    t = np.arange(n) / rate
    modulation = 1.0 + 0.5 * np.cos(2 * np.pi * 5.0 * t)
    x = modulation * np.cos(2 * np.pi * 500.0 * t)
    env = condition.squared_envelope(x[None], rate, (400.0, 600.0))[0]
    np.testing.assert_allclose(env[200:-200], modulation[200:-200] ** 2, rtol=1e-6, atol=1e-9)
    with pytest.raises(ValueError, match="band"):
        condition.squared_envelope(x[None], rate, (500.0, 2500.0))


def test_band_pass_keeps_the_tones_inside_the_band_only() -> None:
    rate, n = 200.0, 400
    t = np.arange(n) / rate
    x = np.sin(2 * np.pi * 2.0 * t) + np.sin(2 * np.pi * 30.0 * t)
    kept = condition.band_pass(x[None], rate, (10.0, 100.0))[0]
    np.testing.assert_allclose(kept, np.sin(2 * np.pi * 30.0 * t), atol=1e-9)


def test_revolutions_count_either_way() -> None:
    angle = np.r_[np.linspace(0, 2 * np.pi, 50), np.linspace(2 * np.pi, 0, 50)][None]
    assert condition.revolutions(angle)[0] == pytest.approx(2.0, rel=1e-9)
    wheels = np.stack([angle[0], 0.5 * angle[0]], axis=1)[None]  # (1, n, 2): time along axis 1
    np.testing.assert_allclose(condition.revolutions(wheels, axis=1), [[2.0, 1.0]], rtol=1e-9)
