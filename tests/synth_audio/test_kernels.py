"""The compiled loops against what they compute: scatter-adds by numpy's `add.at`, a fractional delay by its
Lagrange taps and a sine's phase, a Doppler read by a polynomial that third-order Lagrange interpolates
exactly, the one- and two-pole filters by scipy's `lfilter`."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from synth_audio import kernels
from synth_audio.dsp import delay_into, fractional_taps, one_pole_lowpass, overlap_add_into, resonate


def test_overlap_add_is_every_copy_of_the_kernel_clipped_to_the_signal() -> None:
    rng = np.random.default_rng(0)
    n, size = 500, 37
    positions = np.array([-20, -37, 0, 3, 3, 250, 480, 499, 500, 700])  # before, across and after both ends
    amps = rng.uniform(-2.0, 2.0, positions.size).astype(np.float32)
    kernel = rng.standard_normal(size).astype(np.float32)
    out = rng.standard_normal(n).astype(np.float32)
    expected = out.astype(np.float64)
    for p, a in zip(positions, amps, strict=True):
        idx = p + np.arange(size)
        ok = (idx >= 0) & (idx < n)
        np.add.at(expected, idx[ok], float(a) * kernel[ok].astype(np.float64))
    overlap_add_into(out, positions, amps, kernel)
    assert np.allclose(out, expected, atol=1e-5)


@pytest.mark.parametrize("delay", [1.0, 1.25, 3.5, 17.9])
def test_a_delayed_impulse_is_the_delays_lagrange_taps(delay: float) -> None:
    shift, taps = fractional_taps(delay)
    x = np.zeros(64, dtype=np.float32)
    x[10] = 1.0
    out = np.zeros(64, dtype=np.float32)
    delay_into(out, x, delay, 0.5)
    expected = np.zeros(64, dtype=np.float32)
    expected[10 + shift : 10 + shift + 4] = 0.5 * taps
    assert np.allclose(out, expected, atol=1e-7)
    assert float(np.sum(out * np.arange(64))) / float(np.sum(out)) == pytest.approx(10 + delay, abs=1e-4)


def test_a_delayed_sine_lags_by_the_fractional_delay() -> None:
    sr, f, delay = 44100, 440.0, 7.3
    t = np.arange(4096)
    x = np.sin(2 * np.pi * f * t / sr).astype(np.float32)
    out = np.zeros(4096, dtype=np.float32)
    delay_into(out, x, delay, 1.0)
    expected = np.sin(2 * np.pi * f * (t - delay) / sr)
    assert np.max(np.abs(out[20:] - expected[20:])) < 1e-5


def test_a_delay_that_starts_before_or_runs_past_the_output_keeps_what_lands_inside() -> None:
    rng = np.random.default_rng(1)
    x = rng.standard_normal(100).astype(np.float32)
    for start in (-50, -3, 0, 60, 95, 120):
        out = np.zeros(100, dtype=np.float32)
        shift, taps = fractional_taps(2.4)
        kernels.fractional_delay_into(out, x, shift, taps, start)
        expected = np.zeros(100, dtype=np.float64)
        for k in range(4):
            idx = start + shift + k + np.arange(x.size)
            ok = (idx >= 0) & (idx < 100)
            np.add.at(expected, idx[ok], float(taps[k]) * x[ok].astype(np.float64))
        assert np.allclose(out, expected, atol=1e-5), start


def test_a_doppler_read_of_a_cubic_is_exact_and_ramps_the_gain() -> None:
    pad, control = 4, 8
    i = np.arange(200, dtype=np.float64)
    x = 1e-6 * (i - 90.0) ** 3 + 0.01 * i  # third-order Lagrange is exact on cubics
    padded = np.concatenate([np.zeros(pad), x, np.zeros(pad)]).astype(np.float32)
    position = np.linspace(20.3, 150.8, 11)  # 10 control blocks of 8 samples, a moving read
    gain = np.linspace(1.0, 0.5, 11)
    out = np.zeros(10 * control, dtype=np.float32)
    kernels.lagrange_read(padded, pad, position, gain, control, out)
    j = np.arange(out.size)
    p = np.interp(j / control, np.arange(11), position)
    g = np.interp(j / control, np.arange(11), gain)
    assert np.allclose(out, g * (1e-6 * (p - 90.0) ** 3 + 0.01 * p), atol=2e-5)


def test_a_doppler_read_beyond_the_signal_reads_zeros() -> None:
    padded = np.concatenate([np.zeros(4), np.ones(10), np.zeros(4)]).astype(np.float32)
    out = np.zeros(24, dtype=np.float32)
    kernels.lagrange_read(padded, 4, np.array([-30.0, -14.0, 40.0, 60.0]), np.ones(4), 8, out)
    assert np.all(out[:8] == 0.0) and np.all(out[16:] == 0.0)  # before and after the signal
    assert np.any(out[8:16] != 0.0)  # the read sweeps across it


def test_weaving_adds_each_snippet_read_circularly_under_the_window() -> None:
    rng = np.random.default_rng(3)
    size, hop = 16, 8
    pool = rng.standard_normal((3, size)).astype(np.float32)
    window = rng.uniform(0.0, 1.0, size).astype(np.float32)
    segments, offsets = np.array([2, 0, 1, 2]), np.array([0, 5, 15, 9])
    out = np.zeros(4 * hop + size, dtype=np.float32)
    kernels.weave(out, pool, segments, offsets, window, hop)
    expected = np.zeros(out.size)
    for s, (seg, offset) in enumerate(zip(segments, offsets, strict=True)):
        expected[s * hop : s * hop + size] += np.roll(pool[seg], -offset) * window
    assert np.allclose(out, expected, atol=1e-6)


@pytest.mark.parametrize("channels", [2, 3])
def test_the_soft_limiter_is_the_identity_below_its_knee_and_bounded_and_monotonic_above(
    channels: int,
) -> None:
    """Both of the kernel's interleaving loops (two channels, any number): identity below the knee, the tanh
    law above it, NaN passed through."""
    n = 6000 // channels
    x = np.linspace(-3.0, 3.0, channels * n, dtype=np.float32).reshape(channels, -1)
    unlimited = np.empty((n, channels), dtype=np.float32)
    kernels.limit_interleave(x, np.inf, unlimited)
    assert np.array_equal(unlimited.T, x)
    out = np.empty((n, channels), dtype=np.float32)
    kernels.limit_interleave(x, 0.5, out)
    y = out.T
    below = np.abs(x) <= 0.5
    assert np.array_equal(y[below], x[below])
    assert np.all(np.abs(y) < 1.0) and np.all(np.diff(y.ravel()) >= 0.0)
    assert np.array_equal(np.sign(y), np.sign(x))
    assert float(y.ravel()[-1]) == pytest.approx(0.5 + 0.5 * np.tanh(5.0), abs=1e-6)
    quiet = x * np.float32(0.1)
    quiet[0, 3] = np.nan
    kernels.limit_interleave(quiet, 0.5, out)
    assert np.array_equal(out.T, quiet, equal_nan=True)


def test_the_table_kernels_read_their_table_at_the_nearest_point_of_the_ramped_phase() -> None:
    from synth_audio.dsp import frac_phase, table_index

    rng = np.random.default_rng(4)
    cycles = np.cumsum(rng.uniform(-0.2, 0.9, 41))  # forwards and backwards, many cycles
    n, ones = 40 * 64 - 5, np.ones(41)
    expected = table_index(frac_phase(cycles[None, :], 64, n)[0], 4096)
    points = np.arange(4096, dtype=np.float32)  # a table that holds its own index
    rolled = np.zeros(n, dtype=np.float32)
    kernels.rolling_mix(rolled, np.zeros(n, dtype=np.float32), ones, cycles, points, ones, 64)
    motor = np.zeros(n, dtype=np.float32)
    zero, silent = np.zeros((4096, 2), np.float32), np.zeros(0, np.float32)
    no_noise = np.zeros(n, np.float32)
    kernels.motor_mix(motor, cycles, points, zero, ones, no_noise, ones, silent, ones, 64)
    for got in (rolled, motor):
        gap = np.abs(got.astype(np.int64) - expected)
        assert np.all(np.minimum(gap, 4096 - gap) <= 1)  # float64 against float32 phases: one point at most


def test_the_mix_kernels_ramp_every_envelope_linearly_within_its_block() -> None:
    from synth_audio.dsp import block_ramp

    rng = np.random.default_rng(5)
    n, block = 10 * 32 - 7, 32
    env = [rng.uniform(0.0, 2.0, 11) for _ in range(3)]
    noise, carrier = (rng.standard_normal(n).astype(np.float32) for _ in range(2))
    ramp = [block_ramp(e, block, n).astype(np.float64) for e in env]
    rolled = np.zeros(n, dtype=np.float32)
    kernels.rolling_mix(rolled, noise, env[0], np.zeros(11), np.zeros(0, np.float32), env[1], block)
    assert np.allclose(rolled, noise * ramp[0], atol=1e-5)  # no table: the noise alone
    motor = np.zeros(n, dtype=np.float32)
    flat, flat2 = np.ones(64, dtype=np.float32), np.ones((16, 2), dtype=np.float32)
    kernels.motor_mix(motor, np.zeros(11), flat, flat2, env[0], noise, env[1], carrier, env[2], block)
    assert np.allclose(motor, ramp[0] + noise * ramp[1] + carrier * ramp[2], atol=1e-5)
    quiet = np.zeros(n, dtype=np.float32)  # no carrier: the tone and the brush noise only
    kernels.motor_mix(
        quiet, np.zeros(11), flat, flat2, env[0], noise, env[1], np.zeros(0, np.float32), env[2], block
    )
    assert np.allclose(quiet, ramp[0] + noise * ramp[1], atol=1e-5)


def test_the_motor_kernel_reads_its_modulations_at_the_tone_index_modulo_their_period() -> None:
    rng = np.random.default_rng(6)
    cycles = np.cumsum(rng.uniform(0.0, 0.9, 41))
    n, ones = 40 * 64, np.ones(41)
    full = rng.uniform(0.5, 1.5, (4096, 2)).astype(np.float32)
    full[1024:] = np.tile(full[:1024], (3, 1))  # a period of 1024 points
    noise, carrier = (rng.standard_normal(n).astype(np.float32) for _ in range(2))
    tone = rng.standard_normal(4096).astype(np.float32)
    whole, period = np.zeros(n, np.float32), np.zeros(n, np.float32)
    kernels.motor_mix(whole, cycles, tone, full, ones, noise, ones, carrier, ones, 64)
    kernels.motor_mix(
        period, cycles, tone, np.ascontiguousarray(full[:1024]), ones, noise, ones, carrier, ones, 64
    )
    assert np.array_equal(whole, period)


@pytest.mark.parametrize("pole_pairs", [3, 4, 5])
def test_the_motor_modulations_hold_one_period_of_the_functions_on_the_tone_table(pole_pairs: int) -> None:
    from synth_audio.dsp import TABLE_SIZE
    from synth_audio.motor import _modulations

    x = np.arange(TABLE_SIZE) / TABLE_SIZE
    brush = (1.0 + 0.4 * np.cos(2.0 * np.pi * 2 * pole_pairs * x)).astype(np.float32)
    side = (1.0 + 0.5 * np.cos(4.0 * np.pi * pole_pairs * x)).astype(np.float32)
    for sidebands in (False, True):
        table = _modulations(pole_pairs, sidebands)
        rows = table[np.arange(TABLE_SIZE) & (table.shape[0] - 1)]
        assert TABLE_SIZE % table.shape[0] == 0 and table.shape[0] < TABLE_SIZE
        assert np.array_equal(rows[:, 0], brush)
        assert np.array_equal(rows[:, 1], side if sidebands else np.ones(TABLE_SIZE, np.float32))


@pytest.mark.parametrize("cosine", [False, True])
def test_a_steady_tone_is_the_sinusoid_of_its_phase_across_restarts_and_its_tail(cosine: bool) -> None:
    n = 3 * 4096 + 13  # three restarts from the exact phase and a tail shorter than the eight lanes
    start, step, amp = 0.37, 1234.5 / 44100.0, 0.8
    out = np.full(n, 0.25, dtype=np.float32)
    kernels.sinusoid_into(out, start, step, amp, cosine)
    angle = 2.0 * np.pi * (start + step * np.arange(n))
    expected = 0.25 + amp * (np.cos(angle) if cosine else np.sin(angle))
    assert np.allclose(out, expected, rtol=0.0, atol=1e-6)


def test_damped_modes_are_decaying_sinusoids_each_stopped_140_db_down() -> None:
    from synth_audio.dsp import MODE_FLOOR_DB, damped_modes

    sr, length = 8000, 4000
    freqs, t60 = np.array([440.0, 1000.0, 5000.0]), np.array([0.3, 0.02, 0.1])  # 5 kHz: above 0.48 sr
    amps, phases = np.array([1.0, 0.5, 2.0]), np.array([0.3, 1.0, 0.0])
    got = damped_modes(freqs, t60, amps, phases, sr, length)
    t = np.arange(length) / sr
    expected = np.zeros(length)
    for f, d, a, p in zip(freqs[:2], t60[:2], amps[:2], phases[:2], strict=True):
        stop = int(np.ceil(MODE_FLOOR_DB / 60.0 * d * sr)) + 1
        expected[:stop] += (a * np.exp(-6.907755 * t / d) * np.sin(2 * np.pi * f * t + p))[:stop]
    assert got.dtype == np.float32 and np.allclose(got, expected, rtol=0.0, atol=1e-6)
    short = int(np.ceil(MODE_FLOOR_DB / 60.0 * 0.02 * sr)) + 1
    assert 0.5 * np.exp(-6.907755 * short / sr / 0.02) < 2**-24  # what is left out lies under float32's step


@pytest.mark.parametrize("block", [64, 256])
def test_a_wavetable_read_in_one_pass_is_the_table_at_the_ramped_phase_bit_for_bit(block: int) -> None:
    from synth_audio.dsp import block_wavetable, frac_phase, harmonic_table, wavetable

    rng = np.random.default_rng(block)
    table = harmonic_table(np.array([1.0, 3.0]), np.array([1.0, 0.3]), np.array([0.1, 0.2]))
    for _ in range(10):
        nb = int(rng.integers(2, 100))
        n = nb * block - int(rng.integers(0, block))  # a last block cut short
        cycles = np.cumsum(rng.uniform(-0.5, 3.0, nb + 1)) * rng.uniform(0.1, 1000.0)  # and going backwards
        expected = wavetable(frac_phase(cycles[None, :], block, n)[0], table)
        assert np.array_equal(block_wavetable(cycles, block, n, table), expected)


def test_the_silence_scan_answers_as_numpy_any() -> None:
    for x in ([0.0, -0.0, 0.0], [0.0, 0.0, 1e-30], [np.nan, 0.0], [], [0.0] * 1000 + [-2.0]):
        array = np.asarray(x, dtype=np.float32)
        assert kernels.any_nonzero(array) == bool(np.any(array)), x


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_a_sum_of_squares_is_the_float64_sum_of_the_squares(dtype: type) -> None:
    rng = np.random.default_rng(9)
    for n in (0, 1, 7, 8, 9, 1001, 100_000):
        x = (rng.standard_normal(n) * 1e3).astype(dtype)
        exact = float(np.sum(x.astype(np.float64) ** 2))
        assert kernels.sum_squares(x) == pytest.approx(exact, rel=1e-13, abs=0.0)
    assert kernels.sum_squares(np.full(8, 1e20, dtype=np.float32)) == pytest.approx(8e40, rel=1e-6)


def test_a_sum_of_products_is_the_exact_dot_product_to_float64_rounding() -> None:
    rng = np.random.default_rng(10)
    for n in (0, 1, 7, 8, 9, 1001, 300_000):
        x, y = rng.standard_normal(n) * 1e3, rng.exponential(size=n)
        exact = math.fsum((x * y).tolist())  # each product rounded once, the sum exactly
        assert kernels.sum_products(x, y) == pytest.approx(exact, rel=1e-12, abs=1e-9)
    x, y = rng.random(300_000), rng.random(300_000)
    assert kernels.sum_products(x, y) == kernels.sum_products(x.copy(), y.copy())  # nothing but the values


def test_twiddles_are_the_complex_exponentials_to_float32_rounding() -> None:
    length, d, m = 2_700_000, 4, 337_500
    out = np.empty((d, m), dtype=np.complex64)
    kernels.twiddles_into(length, out)
    exact = np.exp(-2j * np.pi * np.arange(d)[:, None] * np.arange(m)[None, :] / length)
    assert np.max(np.abs(out - exact)) < 1e-7


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_filters_are_scipys_lfilter_sample_for_sample(dtype: type) -> None:
    """The compiled recursions run lfilter's transposed direct form in its order of operations: the same
    float64 samples, rounded to float32 alike."""
    rng = np.random.default_rng(5)
    x = rng.standard_normal(20000).astype(dtype)
    x[100:110] = 0.0  # zeros inside the signal
    a = float(np.exp(-2.0 * np.pi * 900.0 / 44100.0))
    expected = lfilter([1.0 - a], [1.0, -a], x).astype(np.float32)
    np.testing.assert_array_equal(one_pole_lowpass(x, 900.0, 44100.0), expected)
    f, zeta = 700.0, 0.05
    r = float(np.exp(-2.0 * np.pi * f * zeta / 44100.0))
    w = 2.0 * np.pi * f / 44100.0
    expected = lfilter([1.0 - r], [1.0, -2.0 * r * np.cos(w), r * r], x).astype(np.float32)
    np.testing.assert_array_equal(resonate(x, f, zeta, 44100), expected)
    assert one_pole_lowpass(x[:0], 900.0, 44100.0).shape == (0,)
