"""The windows layout: pre-cut 2 s windows, as the paper's public code keeps them (normal training, normal
test and abnormal windows of decimated audio and IMU z velocity).

    SOURCE/normal_train.npz   keys: audio, imu [, imu6] [, sequence]
    SOURCE/normal_val.npz     (optional) same keys
    SOURCE/normal_test.npz    same keys
    SOURCE/abnormal.npz       same keys [, kind] [, sub_kind]

or, instead of GROUP.npz, one .npy file per key: GROUP_audio.npy, GROUP_imu.npy, ... (not both for a group).

- `audio`: (N, L) mono or (N, L, C) windows at `--audio-rate` (default 4410 Hz, so L = 8820; C = 2, or
  more with `--channels`); raw waveforms in [-1, 1].
- `imu`: (N, M) z-velocity windows at `--imu-rate` (default 200 Hz, so M = 400). Absent from every group:
  an audio-only dataset. `imu6`: optional (N, M, 6) accelerometer and gyroscope (zeros when absent).
- `sequence`: optional (N,) integer recording id: windows sharing one, in array order, form one episode
  (the bootstrap's cluster); without it every window is its own episode.
- `kind`: optional (N,) `collision` or `mechanical` (default `--anomaly-kind`); `sub_kind`: optional (N,)
  name (default `unspecified`). Abnormal windows only.

Windows must last 2 s at the given rates (the window contract). Each is resampled to 44.1 kHz and 200 Hz
and laid out in its episode at 2.1 s intervals (0.1 s of silence between windows, so that the dataset's
anti-alias filter never mixes two windows): loading the dataset gives back each window, its audio
band-limited to the dataset's 2 kHz anti-alias cut-off.
"""

from __future__ import annotations

import functools
import zipfile
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal

from benchmarks.importers.config import ANOMALY_KINDS, ImportConfig, SourceError, WindowsConfig
from benchmarks.importers.folder import check_sub_kind
from benchmarks.importers.signals import OUT_AUDIO_RATE, pick_channels, to_stereo_rate
from benchmarks.importers.writer import UNSPECIFIED, Planned, Recording, Span
from msvdd.contract import IMU_RATE, WINDOW_S

GROUPS: dict[str, tuple[str, bool, bool]] = {
    "normal_train": ("fit", False, True),
    "normal_val": ("val", False, False),
    "normal_test": ("test", False, True),
    "abnormal": ("test", True, True),
}
"""Group file stem -> (split pool, anomalous, required)."""
KEYS: tuple[str, ...] = ("audio", "imu", "imu6", "sequence", "kind", "sub_kind")
"""Arrays a group may hold."""
GAP_S = 0.1
"""Silence between two windows of one episode, s (longer than the anti-alias filter's reach)."""
SLOT_S = WINDOW_S + GAP_S
"""Distance between the starts of consecutive windows of one episode, s."""


def _read_group(source: Path, group: str) -> tuple[dict[str, np.ndarray], str] | None:
    """The arrays of one group and the file(s) they came from, or None if the group is absent."""
    npz = source / f"{group}.npz"
    npys = {key: source / f"{group}_{key}.npy" for key in KEYS}
    present = [p for p in npys.values() if p.is_file()]
    if npz.is_file() and present:
        raise SourceError(
            f"{npz} and {present[0]}: group {group} given twice; allowed: the .npz or .npy files"
        )
    arrays: dict[str, np.ndarray] = {}
    try:
        if npz.is_file():
            with np.load(npz, allow_pickle=False) as z:
                unknown = sorted(set(z.files) - set(KEYS))
                if unknown:
                    raise SourceError(f"{npz}: unknown array {unknown[0]!r}; allowed: {', '.join(KEYS)}")
                arrays = {key: z[key] for key in z.files}
            where = str(npz)
        elif present:
            arrays = {
                key: np.load(p, allow_pickle=False, mmap_mode="r") for key, p in npys.items() if p.is_file()
            }
            where = str(source / f"{group}_*.npy")
        else:
            return None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise SourceError(f"{source}: group {group}: not a readable NumPy file ({exc})") from exc
    if "audio" not in arrays:
        raise SourceError(f"{where}: no array 'audio'; allowed keys: {', '.join(KEYS)} (audio required)")
    return arrays, where


def _check_group(
    arrays: dict[str, np.ndarray], where: str, anomalous: bool, config: WindowsConfig
) -> tuple[int, int | None]:
    """Check shapes, lengths and rates of one group; (audio window length, IMU window length or None)."""
    audio = arrays["audio"]
    n = audio.shape[0] if audio.ndim else 0
    if audio.ndim not in (2, 3) or n == 0:
        raise SourceError(f"{where}: audio shape {audio.shape}; allowed: (N, L) mono or (N, L, C), N > 0")
    for key, arr in arrays.items():
        if arr.shape[:1] != (n,):
            raise SourceError(
                f"{where}: unequal lengths: audio has {n} windows, {key} has "
                f"{arr.shape[0] if arr.ndim else 'no'} (shape {arr.shape}); allowed: one entry per window"
            )
    if not anomalous:
        for key in ("kind", "sub_kind"):
            if key in arrays:
                raise SourceError(f"{where}: array {key!r} in a normal group; allowed: abnormal windows only")
    expected = {"audio": f"{WINDOW_S * config.audio_rate:g}"}
    length_a = audio.shape[1]
    duration_a = length_a / config.audio_rate
    length_i: int | None = None
    if "imu" in arrays:
        imu = arrays["imu"]
        if imu.ndim != 2:
            raise SourceError(f"{where}: imu shape {imu.shape}; allowed: (N, M) z-velocity windows")
        length_i = imu.shape[1]
        duration_i = length_i / config.imu_rate
        if abs(duration_a - duration_i) > 0.5 / config.imu_rate:
            raise SourceError(
                f"{where}: audio windows of {length_a} samples at --audio-rate {config.audio_rate:g} Hz last "
                f"{duration_a:.4g} s, IMU windows of {length_i} samples at --imu-rate {config.imu_rate:g} Hz "
                f"last {duration_i:.4g} s; allowed: rates that give both the same length (check the rates)"
            )
        expected["imu"] = f"{WINDOW_S * config.imu_rate:g}"
        if "imu6" in arrays and arrays["imu6"].shape[1:] != (length_i, 6):
            raise SourceError(f"{where}: imu6 shape {arrays['imu6'].shape}; allowed: (N, {length_i}, 6)")
    elif "imu6" in arrays:
        raise SourceError(f"{where}: imu6 without imu; allowed: imu6 only beside the z-velocity windows imu")
    if abs(duration_a - WINDOW_S) > 0.5 / config.audio_rate:
        raise SourceError(
            f"{where}: windows last {duration_a:.4g} s ({length_a} audio samples at --audio-rate "
            f"{config.audio_rate:g} Hz); allowed: {WINDOW_S:g} s windows, i.e. "
            + ", ".join(f"{v} {k} samples" for k, v in expected.items())
        )
    for key in ("audio", "imu", "imu6"):
        if key in arrays and not np.all(np.isfinite(arrays[key])):
            raise SourceError(f"{where}: array {key!r} holds NaN or inf; allowed: finite values")
    if "kind" in arrays:
        bad = sorted(set(np.asarray(arrays["kind"]).astype(str)) - set(ANOMALY_KINDS))
        if bad:
            raise SourceError(f"{where}: kind {bad[0]!r}; allowed: {', '.join(ANOMALY_KINDS)}")
    return length_a, length_i


def _resample_imu(x: np.ndarray, rate: float) -> np.ndarray:
    """IMU windows (N, M[, 6]) at `rate` -> (N, 400[, 6]) at 200 Hz (polyphase, exact rational ratio)."""
    length = round(WINDOW_S * IMU_RATE)
    if rate == IMU_RATE:
        return np.asarray(x, dtype=np.float32)[:, :length]
    ratio = Fraction(IMU_RATE).limit_denominator() / Fraction(rate).limit_denominator(1_000_000)
    y = signal.resample_poly(np.asarray(x, dtype=np.float64), ratio.numerator, ratio.denominator, axis=1)
    if y.shape[1] < length:
        y = np.concatenate([y, np.repeat(y[:, -1:], length - y.shape[1], axis=1)], axis=1)
    return y[:, :length].astype(np.float32)


def _load(
    arrays: dict[str, np.ndarray],
    index: np.ndarray,
    where: str,
    anomalous: bool,
    config: ImportConfig,
    windows: WindowsConfig,
) -> Recording:
    audio = np.asarray(arrays["audio"][index], dtype=np.float32)
    audio = pick_channels(audio[..., None] if audio.ndim == 2 else audio, config.channels, where)
    audio = to_stereo_rate(audio, windows.audio_rate, where)  # (k, 88200, 2)
    k, per = audio.shape[0], round(WINDOW_S * OUT_AUDIO_RATE)
    slot_a, slot_i, per_i = (
        round(SLOT_S * OUT_AUDIO_RATE),
        round(SLOT_S * IMU_RATE),
        round(WINDOW_S * IMU_RATE),
    )
    out_audio = np.zeros(((k - 1) * slot_a + per, 2), dtype=np.float32)
    for j in range(k):
        out_audio[j * slot_a : j * slot_a + per] = audio[j, :per]
    vel_z = imu6 = None
    if "imu" in arrays:
        imu = _resample_imu(arrays["imu"][index], windows.imu_rate)
        vel_z = np.zeros((k - 1) * slot_i + per_i, dtype=np.float32)
        for j in range(k):
            vel_z[j * slot_i : j * slot_i + per_i] = imu[j]
        if "imu6" in arrays:
            six = _resample_imu(arrays["imu6"][index], windows.imu_rate)
            imu6 = np.zeros((vel_z.shape[0], 6), dtype=np.float32)
            for j in range(k):
                imu6[j * slot_i : j * slot_i + per_i] = six[j]
    starts = tuple(j * SLOT_S for j in range(k))
    spans: tuple[Span, ...] = ()
    if anomalous:
        kinds = (
            np.asarray(arrays["kind"][index]).astype(str) if "kind" in arrays else [config.anomaly_kind] * k
        )
        subs = (
            np.asarray(arrays["sub_kind"][index]).astype(str) if "sub_kind" in arrays else [UNSPECIFIED] * k
        )
        spans = tuple(
            Span(s, s + WINDOW_S, str(kind), check_sub_kind(str(sub), where))
            for s, kind, sub in zip(starts, kinds, subs, strict=True)
        )
    provenance: dict[str, Any] = {
        "windows_file": where,
        "window_indices": [int(i) for i in index],
        "audio_rate": windows.audio_rate,
        "imu_rate": windows.imu_rate,
    }
    return Recording(out_audio, vel_z, imu6, spans, starts, provenance)


def plan(
    source: Path, config: ImportConfig, windows: WindowsConfig
) -> tuple[list[Planned], dict[str, object]]:
    """The episodes of a windows-layout source (one per window, or per `sequence`), and its facts.

    Raises:
        SourceError: a missing required group, unreadable files, wrong shapes, unequal lengths, windows that
            are not 2 s at the given rates, IMU in some groups only.
    """
    if not source.is_dir():
        raise SourceError(f"source folder not found: {source}")
    plans: list[Planned] = []
    with_imu: dict[str, bool] = {}
    has_val = (source / "normal_val.npz").is_file() or (source / "normal_val_audio.npy").is_file()
    for group, (pool, anomalous, required) in GROUPS.items():
        found = _read_group(source, group)
        if found is None:
            if required:
                raise SourceError(
                    f"{source}: no {group}.npz (nor {group}_audio.npy); allowed: the files normal_train, "
                    "normal_test and abnormal (.npz, or .npy per key), optionally normal_val"
                )
            continue
        arrays, where = found
        _check_group(arrays, where, anomalous, windows)
        with_imu[group] = "imu" in arrays
        n = arrays["audio"].shape[0]
        if "sequence" in arrays:
            seq = np.asarray(arrays["sequence"])
            if not np.issubdtype(seq.dtype, np.integer):
                raise SourceError(f"{where}: sequence dtype {seq.dtype}; allowed: integers")
            ids = list(dict.fromkeys(seq.tolist()))
            members = [(f"{group}/sequence-{v}", np.flatnonzero(seq == v)) for v in ids]
        else:
            width = len(str(n - 1))
            members = [(f"{group}/{i:0{width}d}", np.array([i])) for i in range(n)]
        for name, index in members:
            plans.append(
                Planned(
                    name=name,
                    group=group,
                    pool="train" if pool == "fit" and has_val else pool,
                    anomalous=anomalous,
                    unit_id=0,
                    load=functools.partial(_load, arrays, index, where, anomalous, config, windows),
                )
            )
    if len(set(with_imu.values())) > 1:
        missing = [g for g, v in with_imu.items() if not v]
        raise SourceError(
            f"{source}: group {missing[0]} has no imu array but others do; allowed: imu in every group "
            "or in none"
        )
    return plans, {"window_slot_s": SLOT_S, "audio_rate": windows.audio_rate, "imu_rate": windows.imu_rate}
