"""The shape of a performance stage measured by `msvdd-bench perf`, and the reference kernel its ratios use.

Absolute rates move with the machine and with whatever else runs on it, so each stage also reports ratios
against a reference measured in the same process during the same run: a kernel of known cost (one FFT
convolution, `fft_reference_s`) or a bare loop over the same work (the simulator's `mj_step` loop). A stage
names those figures in `PerfStage.ratios`, with the direction that is better; `benchmarks.perf_gate` compares
them against a baseline run.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

Better = Literal["lower", "higher"]
"""Which way a ratio figure improves: a cost against the reference (lower) or a speed-up (higher)."""

REFERENCE_TAPS = 4096
"""Length of the reference convolution's kernel (a room impulse response's order of magnitude)."""

REFERENCE_BLOCK = 2**19
"""The longest reference convolution run (about 12 s at 44.1 kHz, 8 MB in stereo): a longer one is this
block's time scaled by its length (overlap-add costs the same per sample), so that the reference measures
arithmetic, not how fast the process can map hundreds of MB of fresh memory (which varies run to run)."""


@dataclass(frozen=True)
class PerfStage:
    """A stage benchmark: runs the real code path and returns named figures (ratios, rates, ms)."""

    name: str
    """Stage name for `--stage` (sim, audio, detector, generate)."""
    measure: Callable[[bool], dict[str, float]]
    """measure(quick) -> figures; `quick` shrinks the workload for smoke tests."""
    describe: dict[str, str]
    """One line per figure: what it means and its target."""
    ratios: Mapping[str, Better] = field(default_factory=dict)
    """The figures that are ratios against a reference measured in the same run, and which way is better:
    the ones a baseline comparison (`msvdd-bench perf --baseline`) gates."""


def best_time(
    fn: Callable[[int], object], repeats: int, clock: Callable[[], float], warm: bool = True
) -> float:
    """Best-of-`repeats` seconds on `clock` of `fn(r)` for r = 0, 1, ...; after one untimed `fn(-1)` when
    `warm` (first calls pay one-time costs: imports, caches, allocator growth)."""
    if warm:
        fn(-1)
    best = float("inf")
    for r in range(max(repeats, 1)):
        start = clock()
        fn(r)
        best = min(best, clock() - start)
    return best


def fft_reference_s(
    n_samples: int, channels: int = 2, repeats: int = 3, clock: Callable[[], float] = time.process_time
) -> float:
    """Best-of-`repeats` seconds on `clock` of the reference kernel: one FFT convolution
    (`scipy.signal.oaconvolve`) of `channels` x `n_samples` seeded noise with a fixed `REFERENCE_TAPS`-tap
    kernel, the shape of the audio render's work. Its cost depends only on `n_samples` and the machine, so
    a figure divided by it measured in the same run cancels the machine's speed and its load. Beyond
    `REFERENCE_BLOCK` samples, the block's time x n_samples / REFERENCE_BLOCK."""
    from scipy.signal import oaconvolve

    n_samples = max(int(n_samples), 1)
    if n_samples > REFERENCE_BLOCK:
        block = fft_reference_s(REFERENCE_BLOCK, channels, repeats, clock)
        return block * n_samples / REFERENCE_BLOCK
    rng = np.random.default_rng(0)
    signal = rng.standard_normal((n_samples, channels))
    kernel = rng.standard_normal((REFERENCE_TAPS, 1)) * np.hanning(REFERENCE_TAPS)[:, None]
    best = float("inf")
    for _ in range(max(repeats, 1)):
        start = clock()
        out = oaconvolve(signal, kernel, mode="full", axes=0)
        best = min(best, clock() - start)
    if out.shape != (signal.shape[0] + REFERENCE_TAPS - 1, channels):  # keeps the result alive
        raise RuntimeError(f"the reference convolution returned shape {out.shape}")
    return max(best, 1e-9)
