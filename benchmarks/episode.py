"""One episode on disk: a folder with `audio.flac`, `imu.npz`, `trace.npz`, `events.json`, `meta.json`.

`write_episode` writes the five files into a folder that must not exist yet (through a temporary folder
renamed into place); `read_episode` reads them back and checks the format version. The files are
deterministic: the same trace and audio give the same bytes, so the manifest's sha256 are reproducible.

An episode imported from real recordings (`msvdd-bench import`, `benchmarks.importers`) has no simulator
trace: its `meta.json` says `"source": "import"` and lists its `modalities`, and it holds every file but
`trace.npz` (`IMPORTED_EPISODE_FILES`); `write_imported_episode` writes it.

This module owns the episode folder: no other module opens an episode's files by name. Readers that need
one file only use `read_events`, `read_trace`, `read_trace_signals` or `audio_file`. `events.json` is typed
(`EpisodeEvents`: contacts, benign transients, faults, and an import's labelled anomaly spans).
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

import synth_audio
from benchmarks.errors import InputNotFoundError, UserError
from benchmarks.json_records import plain, read_json, read_record, write_json
from sim.odometry import wheel_encoders
from sim.trace import Trace
from sim.trace_storage import write_npz
from sim.vocab import LABELS, SUB_KINDS

EPISODE_FORMAT_VERSION = 3
"""Version of the episode folder layout; bumped on any change of file names, fields or sample formats.

2: a simulated episode's `audio.flac` is 16-bit with TPDF dither (`EPISODE_AUDIO_BITS`; `meta.json` says
`audio_bits`), its `trace.npz` is trace format 2 (`sim.trace_storage`).
3: `imu.npz` holds the wheel encoders (`wheel_pos`, the odometry modality), `trace.npz` is trace format 3
(the faults' defect model), and the fault kinds are those of `sim.vocab.FAULT_KINDS` (`out_of_round` in
place of `imbalance`): older episodes' label indices mean other kinds, so they are not read.
"""
READABLE_EPISODE_FORMATS: tuple[int, ...] = (3,)
"""Episode format versions `read_episode` reads."""

EPISODE_AUDIO_BITS = 16
"""Bits per sample of a simulated episode's `audio.flac`, TPDF-dithered from the episode's seed.

The dither's white noise (one least significant bit of TPDF: 2^-16 / sqrt(6) RMS over the whole band) lies
under the microphones' self-noise (`synth_audio.AudioConfig.mic_noise_spl_db`) and, since the robot's fan and
the environment's noise beds never stop, under the rendered audio's spectrum in the band the detectors see:
16 bits keep what 24 bits keep, in fewer bytes.
"""

AUDIO_FILE, IMU_FILE, TRACE_FILE, EVENTS_FILE, META_FILE = (
    "audio.flac",
    "imu.npz",
    "trace.npz",
    "events.json",
    "meta.json",
)
EPISODE_FILES: tuple[str, ...] = (AUDIO_FILE, IMU_FILE, TRACE_FILE, EVENTS_FILE, META_FILE)
"""The files of one episode folder."""

SIMULATED, IMPORTED = "simulate", "import"
"""Where an episode comes from (`meta.json` `source`; absent means simulated)."""
IMPORTED_EPISODE_FILES: tuple[str, ...] = (AUDIO_FILE, IMU_FILE, EVENTS_FILE, META_FILE)
"""The files of an imported episode folder: no `trace.npz`, there is no simulator behind it."""
ALL_MODALITIES: tuple[str, ...] = ("audio", "imu", "odometry")
"""Sensors an episode can carry; a simulated one carries every one (odometry: the wheel encoders)."""


class EpisodeError(UserError):
    """An episode folder is missing a file, has another format version or is inconsistent."""


@dataclass(frozen=True)
class EpisodeMeta:
    """What `meta.json` holds besides the scenario."""

    episode_id: str
    """Folder name, unique in the dataset (e.g. `train-nominal-003`)."""
    category: str
    """`nominal`, `collision` or `fault`."""
    split: str
    """`train`, `val` or `test`."""
    unit_id: int
    """Robot unit the episode was driven with."""
    seed: int
    """Seed of the scenario and the audio rendering."""
    snr_db: float
    """Robot-to-environment SNR the audio was mixed at, dB."""
    duration_s: float
    """Length, s."""


@dataclass(frozen=True)
class Episode:
    """An episode read back from disk."""

    path: Path
    """The episode folder."""
    meta: EpisodeMeta
    """Identity and split."""
    scenario: dict[str, Any]
    """The scenario as written by `sim.Scenario.to_dict()`."""
    audio: np.ndarray
    """(n, 2) float32 binaural audio."""
    audio_rate: int
    """Audio sample rate, Hz."""
    imu_time: np.ndarray
    """(m,) IMU time stamps, s."""
    imu_vel_z: np.ndarray
    """(m,) IMU z-axis velocity, m/s."""
    imu6: np.ndarray
    """(m, 6) accelerometer xyz, gyro xyz."""
    label: np.ndarray
    """(m,) label index per IMU sample (`sim.vocab.LABELS`)."""
    sub_kind: np.ndarray
    """(m,) sub-kind index per IMU sample (`sim.vocab.SUB_KINDS`)."""
    label_wheel: np.ndarray
    """(m,) wheel index of a mechanical label, -1 otherwise."""
    wheel_pos: np.ndarray
    """(m, W) wheel encoder positions, rad (`sim.odometry`); (m, 0) without the odometry modality."""
    source: str = SIMULATED
    """`simulate` (generated) or `import` (real recordings: no trace, `scenario` empty)."""
    modalities: tuple[str, ...] = ALL_MODALITIES
    """Sensors recorded; without `imu`, the IMU arrays are all-zero placeholders of the right length."""

    def trace(self) -> Trace:
        """The full simulator trace (read on demand: it is the largest file).

        Raises:
            EpisodeError: the episode was imported from recordings and has no trace.
        """
        if self.source == IMPORTED:
            raise EpisodeError(f"{self.path}: imported from recordings, so it has no simulator trace")
        return read_trace(self.path)

    def events(self) -> EpisodeEvents:
        """The human-readable events (contacts, transients, faults; `anomalies` of an import)."""
        return read_events(self.path)

    def audio_bytes(self) -> bytes:
        """The encoded `audio.flac` as stored (for players that take the file itself)."""
        return audio_file(self.path).read_bytes()


def is_episode_folder(path: Path) -> bool:
    """Whether `path` looks like an episode folder (it holds a `meta.json`)."""
    return (Path(path) / META_FILE).is_file()


def fault_severity(folder: Path) -> float | None:
    """The severity (0..1) of an episode's fault, read from its `meta.json` scenario alone (no signal is
    loaded): the largest over its faults; None for an episode without faults or imported from recordings.

    Raises:
        EpisodeError: no `meta.json`, or a fault without a numeric severity.
    """
    path = Path(folder) / META_FILE
    if not path.is_file():
        raise EpisodeError(f"{folder}: missing episode file {META_FILE}")
    faults = json.loads(path.read_text()).get("scenario", {}).get("faults", [])
    try:
        return max((float(f["severity"]) for f in faults), default=None)
    except (KeyError, TypeError, ValueError) as err:
        raise EpisodeError(f"{path}: a fault of the scenario has no numeric severity ({err})") from err


def audio_file(folder: Path) -> Path:
    """The path of an episode folder's encoded audio."""
    return Path(folder) / AUDIO_FILE


def read_events(folder: Path) -> EpisodeEvents:
    """An episode folder's `events.json`: contacts, transients, faults (and an import's `anomalies`)."""
    return EpisodeEvents.load(folder)


def read_trace(folder: Path) -> Trace:
    """An episode folder's full simulator trace (`sim.Trace.load`; a TraceError names a bad file)."""
    return Trace.load(Path(folder) / TRACE_FILE)


def read_imu_signals(folder: Path, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Only the named arrays of an episode's `imu.npz` (fields of `ImuArrays`), as stored."""
    with np.load(Path(folder) / IMU_FILE, allow_pickle=False) as arrays:
        return {name: arrays[name] for name in names}


def read_trace_signals(folder: Path, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Only the named arrays of an episode's `trace.npz`, as float64 (far faster than `read_trace`).

    Stored fields only: the ones `sim.trace_storage` derives on load (`time`, `wheel_angle`, `mic_pos`)
    need `read_trace`.
    """
    with np.load(Path(folder) / TRACE_FILE, allow_pickle=False) as arrays:
        return {name: np.asarray(arrays[name], dtype=np.float64) for name in names}


def software_versions() -> dict[str, str]:
    """Versions of the packages that shape the data, for `meta.json` and `manifest.json`."""
    return dict(_installed_versions())


@functools.cache
def _installed_versions() -> dict[str, str]:
    """`software_versions`, read once per process (reading the packages' metadata costs milliseconds, once
    per episode written otherwise)."""
    import importlib.metadata as md

    names = ("msvdd-bench", "mujoco", "dm-control", "numpy", "scipy", "soundfile", "torch")
    out: dict[str, str] = {}
    for name in names:
        try:
            out[name] = md.version(name)
        except md.PackageNotFoundError:
            out[name] = "not installed"
    return out


@dataclass(frozen=True)
class ContactEvent:
    """A robot-obstacle contact (one row of `sim.trace.ContactEvents`)."""

    time: float
    """Time of first contact, s."""
    position: tuple[float, ...]
    """(x, y, z) contact point in the world frame, m."""
    normal: tuple[float, ...]
    """(x, y, z) unit contact normal, from the obstacle to the robot."""
    impulse: float
    """Normal impulse over the event, N s."""
    normal_speed: float
    """Approach speed along the normal at first contact, m/s."""
    duration: float
    """How long the contact lasted, s."""
    obstacle_kind: str
    """Obstacle kind (`sim.vocab.OBSTACLE_KINDS`)."""
    material: str
    """Its material (`sim.vocab.MATERIALS`)."""


@dataclass(frozen=True)
class TransientEvent:
    """A wheel meeting a benign floor feature (one row of `sim.trace.TransientEvents`)."""

    time: float
    """Time of the strike, s."""
    position: tuple[float, ...]
    """(x, y, z) where, in the world frame, m."""
    wheel: int
    """Index of the wheel that met it."""
    impulse: float
    """Impulse of the strike, N s."""
    kind: str
    """Feature kind (`sim.vocab.TRANSIENT_KINDS`)."""


@dataclass(frozen=True)
class FaultEvent:
    """An injected wheel fault (`sim.trace.FaultRecord`, with its wheel's name)."""

    kind: str
    """Fault kind (`sim.vocab.FAULT_KINDS`)."""
    wheel: int
    """Index of the faulty wheel."""
    wheel_name: str
    """Its name (`sim.trace.RobotInfo.wheel_names`)."""
    severity: float
    """0 (no effect) .. 1 (severe)."""
    onset: float
    """Start time, s."""
    duration: float
    """Length, s."""
    defect_order: float
    """Defect events per wheel revolution."""
    resonance_hz: float
    """Structural resonance the defect excites, Hz."""


@dataclass(frozen=True)
class AnomalySpan:
    """A labelled anomaly of an imported recording."""

    onset: float
    """Start, s."""
    end: float
    """End, s."""
    kind: str
    """`collision` or `mechanical`."""
    sub_kind: str
    """What it was (free text from the source, or `unspecified`)."""


@dataclass(frozen=True)
class EpisodeEvents:
    """An episode's `events.json`: what happened in it, human-readable."""

    contacts: tuple[ContactEvent, ...] = ()
    """Robot-obstacle contacts."""
    transients: tuple[TransientEvent, ...] = ()
    """Benign floor features met."""
    faults: tuple[FaultEvent, ...] = ()
    """The fault schedule."""
    anomalies: tuple[AnomalySpan, ...] | None = None
    """An imported episode's labelled anomaly spans; None (not written) for a simulated one."""

    @classmethod
    def of_trace(cls, trace: Trace) -> EpisodeEvents:
        """The events of a simulated trace."""
        c, t = trace.contacts, trace.transients
        return cls(
            contacts=tuple(
                ContactEvent(
                    time=float(c.time[i]),
                    position=tuple(float(v) for v in c.position[i]),
                    normal=tuple(float(v) for v in c.normal[i]),
                    impulse=float(c.impulse[i]),
                    normal_speed=float(c.normal_speed[i]),
                    duration=float(c.duration[i]),
                    obstacle_kind=c.obstacle_kind[i],
                    material=c.material[i],
                )
                for i in range(len(c.time))
            ),
            transients=tuple(
                TransientEvent(
                    time=float(t.time[i]),
                    position=tuple(float(v) for v in t.position[i]),
                    wheel=int(t.wheel[i]),
                    impulse=float(t.impulse[i]),
                    kind=t.kind[i],
                )
                for i in range(len(t.time))
            ),
            faults=tuple(
                FaultEvent(
                    kind=f.kind,
                    wheel=f.wheel,
                    wheel_name=trace.robot.wheel_names[f.wheel],
                    severity=f.severity,
                    onset=f.onset,
                    duration=f.duration,
                    defect_order=f.defect_order,
                    resonance_hz=f.resonance_hz,
                )
                for f in trace.faults
            ),
        )

    def to_dict(self) -> dict[str, Any]:
        """The document `save` writes (JSON values only)."""
        doc: dict[str, Any] = plain(self)
        if self.anomalies is None:
            del doc["anomalies"]
        return doc

    @classmethod
    def from_dict(cls, doc: object, file: Path | str = EVENTS_FILE) -> EpisodeEvents:
        """Read and check an events document; `file` names it in an `EpisodeError`."""
        return read_record(cls, doc, str(file), EpisodeError)

    @classmethod
    def load(cls, folder: Path) -> EpisodeEvents:
        """Read the `events.json` of the episode folder `folder`; an `EpisodeError` names a missing file or
        a missing, ill-typed or unknown field."""
        path = Path(folder) / EVENTS_FILE
        if not path.is_file():
            raise EpisodeError(f"{folder}: missing episode file {EVENTS_FILE}")
        return cls.from_dict(read_json(path, EpisodeError), path)

    def save(self, folder: Path) -> Path:
        """Write `events.json` into the episode folder `folder` (atomically); returns its path."""
        path = Path(folder) / EVENTS_FILE
        write_json(path, self.to_dict())
        return path


def write_episode(
    directory: Path,
    meta: EpisodeMeta,
    scenario: dict[str, Any],
    trace: Trace,
    audio: synth_audio.Audio,
) -> Path:
    """Write one episode folder (atomically: a temporary sibling renamed into place).

    `audio` should be rendered from `trace.at_storage_precision()`, so that rendering the stored trace again
    gives it back; it is written with `EPISODE_AUDIO_BITS` bits, dithered from `meta.seed`.

    Raises:
        FileExistsError: if `directory` exists already.
    """
    imu = ImuArrays(
        time=trace.imu_time,
        vel_z=trace.imu_vel_z.astype(np.float32),
        imu6=np.concatenate([trace.imu_acc, trace.imu_gyro], axis=1).astype(np.float32),
        label=trace.label.astype(np.int8),
        sub_kind=trace.sub_kind.astype(np.int16),
        label_wheel=trace.label_wheel.astype(np.int8),
        wheel_pos=wheel_encoders(trace),
    )
    meta_doc = {
        "format_version": EPISODE_FORMAT_VERSION,
        "episode": meta.__dict__,
        "audio_rate": audio.sample_rate,
        "audio_bits": EPISODE_AUDIO_BITS,
        "labels": list(LABELS),
        "sub_kinds": list(SUB_KINDS),
        "scenario": scenario,
        "software": software_versions(),
    }
    with _staged(directory) as tmp:
        synth_audio.write(tmp / AUDIO_FILE, audio, bits=EPISODE_AUDIO_BITS, dither_seed=meta.seed)
        imu.write(tmp / IMU_FILE)
        trace.save(tmp / TRACE_FILE)
        EpisodeEvents.of_trace(trace).save(tmp)
        write_json(tmp / META_FILE, meta_doc)
    return directory


IMPORTED_AUDIO_BITS = 24
"""Bits per sample of an imported episode's `audio.flac`: recordings keep their own noise floor."""


def write_imported_episode(
    directory: Path,
    meta: EpisodeMeta,
    audio: synth_audio.Audio,
    imu: ImuArrays,
    anomalies: tuple[AnomalySpan, ...],
    modalities: tuple[str, ...],
    recording: dict[str, Any],
) -> Path:
    """Write an episode imported from a recording (no trace), atomically like `write_episode`.

    Args:
        directory: the episode folder to create (must not exist).
        meta: identity and split (`snr_db` is not known for a recording and is written as null).
        audio: the resampled recording.
        imu: the IMU at 200 Hz with its label timeline (zeros where the recording has no IMU).
        anomalies: the labelled spans.
        modalities: the sensors recorded (`ALL_MODALITIES` or a part of it).
        recording: provenance of the recording (name, source file, options).
    """
    meta_doc = {
        "format_version": EPISODE_FORMAT_VERSION,
        "episode": {**meta.__dict__, "snr_db": None},
        "audio_rate": audio.sample_rate,
        "audio_bits": IMPORTED_AUDIO_BITS,
        "labels": list(LABELS),
        "sub_kinds": list(SUB_KINDS),
        "scenario": {},
        "source": IMPORTED,
        "modalities": list(modalities),
        "recording": recording,
        "software": software_versions(),
    }
    with _staged(directory) as tmp:
        synth_audio.write(tmp / AUDIO_FILE, audio, bits=IMPORTED_AUDIO_BITS)
        imu.write(tmp / IMU_FILE)
        EpisodeEvents(anomalies=tuple(anomalies)).save(tmp)
        write_json(tmp / META_FILE, meta_doc)
    return directory


@dataclass(frozen=True)
class ImuArrays:
    """What `imu.npz` holds, at the IMU rate."""

    time: np.ndarray
    """(m,) time stamps, s."""
    vel_z: np.ndarray
    """(m,) float32 z-axis velocity, m/s."""
    imu6: np.ndarray
    """(m, 6) float32 accelerometer xyz, gyro xyz."""
    label: np.ndarray
    """(m,) int8 label index (`sim.vocab.LABELS`)."""
    sub_kind: np.ndarray
    """(m,) int16 sub-kind index (`sim.vocab.SUB_KINDS`)."""
    label_wheel: np.ndarray
    """(m,) int8 wheel of a mechanical label, -1 otherwise."""
    wheel_pos: np.ndarray
    """(m, W) float64 wheel encoder positions, rad; (m, 0) without wheel odometry."""

    def write(self, path: Path) -> None:
        """Write the arrays to a compressed `.npz` (deterministic bytes)."""
        with open(path, "wb") as handle:
            write_npz(handle, {name: getattr(self, name) for name in IMU_SIGNALS})


IMU_SIGNALS: tuple[str, ...] = tuple(f.name for f in fields(ImuArrays))
"""The arrays of `imu.npz`."""


@contextlib.contextmanager
def _staged(directory: Path) -> Iterator[Path]:
    """A temporary sibling folder to write into, renamed to `directory` when the block ends without error
    (and removed otherwise). Raises FileExistsError if `directory` exists already."""
    directory = Path(directory)
    if directory.exists():
        raise FileExistsError(f"episode folder exists already: {directory}")
    directory.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{directory.name}-", dir=directory.parent))
    try:
        yield tmp
        os.replace(tmp, directory)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def read_episode(directory: Path) -> Episode:
    """Read an episode folder; raises EpisodeError naming the missing file or bad version."""
    directory = Path(directory)
    if not directory.is_dir():
        raise InputNotFoundError(f"episode folder not found: {directory}")
    if not is_episode_folder(directory):
        raise EpisodeError(f"{directory}: missing episode file {META_FILE}")
    meta_doc = json.loads((directory / META_FILE).read_text())
    source = str(meta_doc.get("source", SIMULATED))
    for name in IMPORTED_EPISODE_FILES if source == IMPORTED else EPISODE_FILES:
        if not (directory / name).is_file():
            raise EpisodeError(f"{directory}: missing episode file {name}")
    version = meta_doc.get("format_version")
    if version not in READABLE_EPISODE_FORMATS:
        readable = " or ".join(str(v) for v in READABLE_EPISODE_FORMATS)
        raise EpisodeError(
            f"{directory / META_FILE}: episode format_version {version}, this software reads {readable}"
        )
    audio = synth_audio.read(audio_file(directory))
    arrays = read_imu_signals(directory, IMU_SIGNALS)
    return Episode(
        path=directory,
        meta=EpisodeMeta(**meta_doc["episode"]),
        scenario=meta_doc["scenario"],
        audio=audio.samples,
        audio_rate=audio.sample_rate,
        imu_time=arrays["time"],
        imu_vel_z=arrays["vel_z"],
        imu6=arrays["imu6"],
        label=arrays["label"],
        sub_kind=arrays["sub_kind"],
        label_wheel=arrays["label_wheel"],
        wheel_pos=arrays["wheel_pos"],
        source=source,
        modalities=tuple(meta_doc.get("modalities", ALL_MODALITIES)),
    )
