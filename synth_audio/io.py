"""FLAC / WAV file I/O for `Audio` (via soundfile), written atomically."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import soundfile as sf

from synth_audio.config import Audio, AudioError

FORMATS: dict[str, tuple[str, str]] = {".flac": ("FLAC", "PCM_24"), ".wav": ("WAV", "FLOAT")}
"""Suffix -> (soundfile format, subtype): FLAC is 24-bit PCM, WAV is 32-bit float (exact)."""


def _format(path: Path) -> tuple[str, str]:
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise AudioError(f"{path}: unsupported audio suffix {path.suffix!r}; allowed: {', '.join(FORMATS)}")
    return fmt


def write(path: str | os.PathLike[str], audio: Audio) -> Path:
    """Write audio to FLAC (24-bit) or WAV (float32) chosen by suffix, atomically; returns the path.

    Raises:
        AudioError: unsupported suffix, samples not (n, 2) finite, or a FLAC sample beyond full scale.
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
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".audio-", suffix=target.suffix, dir=target.parent)
    os.close(fd)
    try:
        sf.write(tmp, samples, int(audio.sample_rate), subtype=subtype, format=fmt)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
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
