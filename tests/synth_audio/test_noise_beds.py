"""Noise beds never repeat: no autocorrelation peak beyond 1 s, in a bed or in the rendered ambience."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.audit.signals import repetition
from synth_audio.ambience import Scene, indoor, outdoor
from synth_audio.dsp import BED_SEGMENT, bed_pool, noise_bed

SR = 44100


def test_bed_is_unit_rms_and_has_no_repetition() -> None:
    rng = np.random.default_rng(0)
    pool = bed_pool(SR, (100, 1000, 5000), (0, -6, -20))
    bed = noise_bed(rng, 20 * SR, pool)
    assert bed.shape == (20 * SR,) and bed.dtype == np.float32
    assert float(np.sqrt(np.mean(bed.astype(np.float64) ** 2))) == pytest.approx(1.0, rel=0.05)
    # Power is constant along the bed (the squared sine windows sum to one).
    quarter = BED_SEGMENT // 4
    blocks = bed[: (bed.size // quarter) * quarter].reshape(-1, quarter) ** 2
    assert np.std(blocks.mean(axis=1)) / np.mean(blocks) < 0.1
    assert repetition(bed, SR) < 0.1  # the estimate's own noise over 400k lags; a loop gives ~1


def test_two_beds_from_one_pool_are_uncorrelated() -> None:
    rng = np.random.default_rng(1)
    pool = bed_pool(SR, (100, 1000, 5000), (0, -6, -20))
    a, b = noise_bed(rng, 10 * SR, pool), noise_bed(rng, 10 * SR, pool)
    assert abs(float(np.corrcoef(a, b)[0, 1])) < 0.02


@pytest.mark.parametrize("where", ["indoor", "outdoor"])
def test_ambience_does_not_repeat(where: str) -> None:
    n = 14 * SR
    mics = np.array([[0.1, 0.08, 0.2], [0.1, -0.08, 0.2]])
    axes = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    scene = Scene(n, SR, mics, axes, 343.0, lambda t: np.eye(3))
    rng = np.random.default_rng(2)
    dry, _ = indoor(scene, rng, 0.0, 10) if where == "indoor" else outdoor(scene, rng, 0.0)
    assert repetition(dry.T, SR) < 0.2


def test_distant_babble_is_voiced_at_its_pitch_not_at_the_block_rate() -> None:
    # The voiced buzz is a sawtooth at the talker's pitch; a phase left unwrapped within control blocks
    # once made it a 43 Hz block-rate ramp that repeated exactly (autocorrelation 0.95 at 8.4 s).
    from synth_audio.ambience import _babble

    low = SR // 4
    assert repetition(_babble(20 * low, low, np.random.default_rng(1), 3), low) < 0.1


def test_a_shape_has_one_library_made_once_and_read_only() -> None:
    shape = ((100, 1000, 5000), (0, -6, -20))
    pool = bed_pool(SR, *shape)
    assert bed_pool(SR, *shape) is pool  # made once per process
    assert not pool.flags.writeable
    # The library is the shape's, not the process's: ints and floats name the same shape.
    assert np.array_equal(bed_pool.__wrapped__(SR, (100.0, 1000.0, 5000.0), (0.0, -6.0, -20.0)), pool)
    other = bed_pool(SR, (100, 1000, 5000), (0, -6, -21))
    assert abs(float(np.corrcoef(pool.ravel(), other.ravel())[0, 1])) < 0.01
