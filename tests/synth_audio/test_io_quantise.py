"""Fixed-point FLAC below 24 bits: TPDF-dithered quantisation against its analytic error statistics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from synth_audio import Audio, AudioError, read, write
from synth_audio.io import quantise

RATE = 44100


@pytest.fixture(scope="module")
def signal() -> Audio:
    """2 s of a quiet tone in noise (-50 dBFS, like a rendered drive), and full-scale samples at the start."""
    rng = np.random.default_rng(4)
    t = np.arange(2 * RATE) / RATE
    x = 3e-3 * np.sin(2 * np.pi * 440.0 * t)[:, None] + 1e-3 * rng.standard_normal((t.size, 2))
    x[:2] = [[1.0, -1.0], [-1.0, 1.0]]
    return Audio(samples=x.astype(np.float32), sample_rate=RATE)


@pytest.mark.parametrize(("bits", "subtype"), [(16, "PCM_16"), (18, "PCM_24")])
def test_stored_audio_is_the_dithered_signal_within_one_and_a_half_steps(
    bits: int, subtype: str, signal: Audio, tmp_path: Path
) -> None:
    """TPDF dither over +-1 step plus rounding: error at most 1.5 steps, mean 0, variance 1/12 + 1/6 =
    1/4 step^2 (RMS half a step), uncorrelated with the signal; the file holds `quantise`'s integers."""
    path = write(tmp_path / "a.flac", signal, bits=bits, dither_seed=7)
    assert sf.info(str(path)).subtype == subtype
    back = read(path).samples
    step = 2.0 ** (1 - bits)
    np.testing.assert_array_equal(back, (quantise(signal.samples, bits, 7) * step).astype(np.float32))
    error = (back.astype(np.float64) - signal.samples) / step
    assert np.abs(error).max() <= 1.5
    assert abs(error.mean()) < 0.01
    assert error.std() == pytest.approx(0.5, rel=0.02)
    assert abs(np.corrcoef(error[:, 0], signal.samples[:, 0])[0, 1]) < 0.01


def test_the_dither_is_white_across_samples_and_channels(signal: Audio) -> None:
    """The dither comes from a hash of each sample's index: the errors of neighbouring samples and of the
    two channels are uncorrelated (|r| within 4 standard errors of 0 over 176 400 samples)."""
    x = signal.samples[2:].astype(np.float64)  # not the full-scale frames, which clip
    error = quantise(x, 16, 11) - x * 2.0**15
    flat = error.reshape(-1)  # the file's interleaved order
    limit = 4.0 / np.sqrt(flat.size)
    for lag in (1, 2, 3, 4):
        assert abs(np.corrcoef(flat[:-lag], flat[lag:])[0, 1]) < limit
    assert abs(np.corrcoef(error[:, 0], error[:, 1])[0, 1]) < 4.0 / np.sqrt(error.shape[0])


def test_the_dither_is_deterministic_and_seeded(signal: Audio, tmp_path: Path) -> None:
    first = write(tmp_path / "a.flac", signal, bits=16, dither_seed=3).read_bytes()
    assert write(tmp_path / "b.flac", signal, bits=16, dither_seed=3).read_bytes() == first
    assert write(tmp_path / "c.flac", signal, bits=16, dither_seed=4).read_bytes() != first


def test_sixteen_bits_take_well_under_the_bytes_of_twenty_four(signal: Audio, tmp_path: Path) -> None:
    """The low 8 bits of a noisy signal are incompressible: 16 bits save about 8 of ~15 bits per sample."""
    size16 = write(tmp_path / "a.flac", signal, bits=16).stat().st_size
    size24 = write(tmp_path / "b.flac", signal).stat().st_size
    assert size16 < 0.6 * size24


@pytest.mark.parametrize("bits", [8, 15, 25])
def test_other_resolutions_are_refused_and_nothing_is_written(
    bits: int, signal: Audio, tmp_path: Path
) -> None:
    with pytest.raises(AudioError, match=f"bits = {bits} is invalid; allowed: 16..24"):
        write(tmp_path / "a.flac", signal, bits=bits)
    assert list(tmp_path.iterdir()) == []
