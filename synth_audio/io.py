"""FLAC / WAV file I/O for `Audio` (via soundfile), written atomically.

FLAC is fixed-point: 24-bit by default (rounded by libsndfile; the error, at most 2^-24 of full scale, lies
50 dB under any microphone's self-noise), or `bits` = 16..23 with TPDF dither (`quantise`): the error is then
white, independent of the signal, zero-mean, of RMS 2^-bits x full scale (-96.3 dBFS at 16 bits) and at most
1.5 steps. 16 bits go into a 16-bit file; 17..23 bits into a 24-bit file whose low bits are zero (FLAC stores
them at no cost). The dither comes from `dither_seed`, so the same audio and seed give the same bytes. FLAC
files are encoded at compression level `FLAC_LEVEL`: the samples are the same at every level.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import soundfile as sf

from msvdd.atomic import atomic_path
from synth_audio import kernels
from synth_audio.config import Audio, AudioError

FORMATS: dict[str, tuple[str, str]] = {".flac": ("FLAC", "PCM_24"), ".wav": ("WAV", "FLOAT")}
"""Suffix -> (soundfile format, default subtype): FLAC is 24-bit PCM, WAV is 32-bit float (exact)."""

FLAC_BITS: tuple[int, ...] = tuple(range(16, 25))
"""Sample resolutions `write` can give a FLAC file."""

FLAC_LEVEL = 0.0
"""libsndfile's FLAC compression level (0..1 for FLAC's levels 0..8; libsndfile's default is FLAC level 5).
Rendered audio is noise to FLAC's predictors in its low bits, so the higher levels search longer for little:
level 0 encodes faster, in slightly larger files."""
_DITHER_STREAM = 0xD17E
"""Mixed into the dither seed, so that the dither never repeats another generator seeded alike."""


def _format(path: Path) -> tuple[str, str]:
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise AudioError(f"{path}: unsupported audio suffix {path.suffix!r}; allowed: {', '.join(FORMATS)}")
    return fmt


def quantise(samples: np.ndarray, bits: int, dither_seed: int) -> np.ndarray:
    """(n, c) samples (full scale = 1) -> integers of `bits` bits with TPDF dither, deterministically.

    Each sample becomes floor(x 2^(bits-1) + u1 - u2 + 1/2), clipped to the integer range, where u1 and u2
    are uniform on {0, 1/2^16, ..., 1 - 1/2^16}: the two halves of a 32-bit hash of the sample's index in
    the interleaved file and a key drawn from a generator seeded by `dither_seed` (`kernels.tpdf_quantise`).
    The dither is triangular over +-1 step, which makes the error's mean and variance independent of the
    signal. Returns int16 for 16 bits, int32 otherwise.
    """
    if bits not in FLAC_BITS:
        raise AudioError(f"bits = {bits} is invalid; allowed: {FLAC_BITS[0]}..{FLAC_BITS[-1]}")
    scale = float(2 ** (bits - 1))
    key = int(np.random.default_rng([int(dither_seed), _DITHER_STREAM]).integers(0, 1 << 32))
    x = np.asarray(samples)
    if x.dtype not in (np.float32, np.float64):
        x = x.astype(np.float64)
    out = np.empty(x.shape, dtype=np.int16 if bits == 16 else np.int32)
    # every sample of every frame in one row, frame by frame (x is copied where it is not C-contiguous)
    kernels.tpdf_quantise(np.ascontiguousarray(x).reshape(-1), key, scale, out.reshape(-1))
    return out


def write(path: str | os.PathLike[str], audio: Audio, bits: int = 24, dither_seed: int = 0) -> Path:
    """Write audio to FLAC (fixed point, `bits` per sample) or WAV (float32) chosen by suffix, atomically.

    Args:
        path: target file; `.flac` or `.wav`.
        audio: the samples, full scale = 1.
        bits: FLAC resolution, 16..24; below 24 the samples are TPDF-dithered (`quantise`). Ignored for WAV.
        dither_seed: seed of that dither.

    Raises:
        AudioError: unsupported suffix or bits, samples not (n, 2) finite, or a FLAC sample beyond full scale.
    """
    target = Path(path)
    fmt, subtype = _format(target)
    samples = np.asarray(audio.samples)
    if samples.ndim != 2 or samples.shape[1] != 2 or samples.shape[0] == 0:
        raise AudioError(f"audio.samples must be (n > 0, 2), got {samples.shape}")
    if not np.all(np.isfinite(samples)):
        raise AudioError("audio.samples holds NaN or inf")
    peak = float(np.max(np.abs(samples)))
    if fmt == "FLAC" and peak > 1.0:
        raise AudioError(f"{target}: peak {peak:.3f} exceeds full scale; FLAC is fixed-point (use .wav)")
    data: np.ndarray = samples
    if fmt == "FLAC" and bits != 24:
        data = quantise(samples, bits, dither_seed)
        if bits > 16:  # libsndfile takes int32 and keeps its top 24 bits
            data <<= 32 - bits
        subtype = "PCM_16" if bits == 16 else "PCM_24"
    with atomic_path(target, suffix=target.suffix) as tmp:
        level = {"compression_level": FLAC_LEVEL} if fmt == "FLAC" else {}
        sf.write(tmp, data, int(audio.sample_rate), subtype=subtype, format=fmt, **level)
    return target


def read(path: str | os.PathLike[str]) -> Audio:
    """Read a two-channel FLAC or WAV file written by `write` (or any stereo file) as float32 Audio."""
    source = Path(path)
    _format(source)
    if not source.is_file():
        raise FileNotFoundError(f"audio file not found: {source}")
    try:
        data, rate = sf.read(source, dtype="float32", always_2d=True)
    except (sf.LibsndfileError, RuntimeError) as exc:
        raise AudioError(f"{source}: not a readable audio file ({exc})") from exc
    if data.shape[1] != 2:
        raise AudioError(f"{source}: expected 2 channels (left, right), found {data.shape[1]}")
    return Audio(samples=np.ascontiguousarray(data), sample_rate=int(rate))
