"""`manifest.json`, a dataset folder's index, as typed records; the only code that reads or writes it.

A dataset folder (`benchmarks.dataset`) holds one folder per episode, `windows.csv` and `manifest.json`: the
format version, the preset, the seed, the software versions, the nominal windows left out, every episode's
plan with the sha256 of each of its files (`ManifestEpisode`), and the window table's sha256 and count
(`ManifestWindows`). A dataset imported from recordings also records `"source": "import"`, the `modalities`
its recordings carry and an `import` section (`ManifestImport`).

`Manifest.load(folder)` reads and checks the file: a missing, ill-typed or unknown field is a `DatasetError`
naming the file and the field, and a format version this software does not read is refused by name.
`Manifest.save(folder)` writes it atomically. `Manifest.to_dict` gives back exactly the document that
`Manifest.from_dict` read for every manifest this software writes, so a preset and seed give the same
`manifest.json` bytes as before the manifest was typed. A manifest of format 2 reads with the fields added
since at their defaults (the preset's and the episodes' speed factors, the preset's floors and environments),
and a training budget of the former names (`LEGACY_SCALES`) reads as today's name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from benchmarks.episode import ALL_MODALITIES, IMPORTED, SIMULATED
from benchmarks.errors import InputNotFoundError, UserError
from benchmarks.json_records import plain, read_field, read_json, read_record, read_value, write_json
from benchmarks.presets import Preset
from sim.random_scenarios import ScenarioOptions

MANIFEST_FILE = "manifest.json"
"""The dataset folder's index."""

DATASET_FORMAT_VERSION = 12
"""Version of the dataset layout (manifest, window table, episode folders).

2: the manifest's preset holds an SNR range (`snr_db` = [low, high], drawn uniformly per episode) and separate
training and test nominal sequence lengths (`nominal_train_duration_s`, `nominal_test_duration_s`).
3: episodes of format 2 (`benchmarks.episode`: 16-bit dithered audio, float32 trace signals); same manifest.
4: episodes of format 3 (wheel odometry, the faults' defect model, `out_of_round` for `imbalance`); a fault
window needs its faulty wheel to have turned (`benchmarks.dataset.MIN_FAULT_REVOLUTIONS`).
5: the same layout; the faults' data changed (a flat's slap reverses its corner's fall and rings the wheel's
bounce on its tread, a spalled bearing grinds loudest where its balls strike), so a seed makes other fault
episodes than under format 4, which stays readable.
6: the same layout; the audio's noise beds are woven from one library of shaped segments per spectral shape
(`synth_audio.dsp.bed_pool`), where each episode shaped its own, so a seed makes other audio than under
format 5, which stays readable.
7: the same layout; obstacles at rest sleep in the simulator (MuJoCo's sleeping islands,
`sim.world.SLEEP_TOLERANCE`), so the robot meets a resting box as a woken one rather than one settling by
the solver's creep, and the audio's damped modes and steady tones are computed by phasors
(`synth_audio.kernels`), which differ from format 6's sines in float32's last bits: a seed makes other bytes
than under format 6, which stays readable.
8: the same layout; the room's reverberation is computed from quarter-length FFTs of its send's polyphase
components (`synth_audio.reverb`) and the audio's sums of squares by a compiled loop
(`synth_audio.kernels.sum_squares`), equal to format 7's sums to float32 rounding: a seed makes other bytes
than under format 7, which stays readable.
9: the same layout and the same signals; the audio's 16-bit dither takes one 32-bit random integer per
sample (`synth_audio.io.quantise`), FLAC files are encoded at FLAC's level 0 (`synth_audio.io.FLAC_LEVEL`)
and the `.npz` members that barely compress are stored uncompressed (`sim.trace_storage.write_npz`): a seed
makes other bytes than under format 8 (its audio differs in the dither alone), which stays readable.
10: the same layout; the two-wheel robot's caster and anti-tip skid are frictionless, as its model says (they
took the floor's friction, dragged and bounced), the dither is a hash of each sample's index and the sources'
reverberation energy is summed from spectra: a seed makes other episodes than under format 9, which stays
readable.
11: the same layout; the steps of a control period run in one compiled `mj_step` loop (`sim.stepper`, where
`mujoco.rollout` ran them), which keeps the solver's warm start from period to period, and the room's
reverberation energy sums its products on one thread (`synth_audio.kernels.sum_products`, where BLAS split
the sum by its thread count): a seed makes other bytes than under format 10, which stays readable.
12: the same layout; the tyres grip by a regularised Coulomb law of their own (`sim.tyre`, each wheel's floor
contact solved by MuJoCo for its normal force only), where MuJoCo's contact friction stuck and slipped in
skid-steer turns and shook the chassis; worn gears ripple their wheel's speed (the transmission error)
rather than its torque: a seed makes other episodes than under format 11, which stays readable.
"""
READABLE_DATASET_FORMATS: tuple[int, ...] = (4, 5, 6, 7, 8, 9, 10, 11, 12)
"""Dataset format versions `Manifest.load` reads."""

LEGACY_SCALES: dict[str, str] = {"tiny": "smoke", "quick": "short", "paper": "full"}
"""Training budgets of manifests written when budgets shared the dataset presets' names."""


class DatasetError(UserError):
    """A dataset folder is incomplete, corrupt or of another format; the message names the file."""


@dataclass(frozen=True)
class EpisodeSpec:
    """One planned episode: enough to simulate and render it in any process (`benchmarks.dataset`
    plans it; the manifest records it).

    In the file the plan is one flat object (`_PlanRecord`): the fields below and the scenario options.
    """

    episode_id: str
    """Folder name."""
    category: str
    """`nominal`, `collision` or `fault`."""
    split: str
    """`train`, `val` or `test`."""
    seed: int
    """Seed of scenario and audio."""
    snr_db: float
    """Mix SNR, dB (drawn uniformly from the preset's `snr_db` range)."""
    options: ScenarioOptions
    """What `sim.draw_scenario` draws the episode's scenario with (before `scale_speeds`): its length, its
    robot unit (always given), and the environment, surface, obstacle and fault kinds and wheel (None:
    drawn by the scenario sampler), the fault severity range and the benign transient density. The robot
    model is the default one (the manifest does not record it)."""
    drive_speed_scale: float = 1.0
    """Factor on the cruise speeds (`sim.random_scenarios.scale_speeds`)."""
    approach_speed_scale: float = 1.0
    """Factor on the speeds of the legs driven at an obstacle."""

    def __post_init__(self) -> None:
        """Refuse options the manifest cannot record: a unit left to draw, another robot model."""
        if self.options.unit_id is None:
            raise ValueError("field 'unit_id': a plan gives the robot unit")
        if self.options.robot_model != ScenarioOptions.robot_model:
            raise ValueError(
                f"robot model {self.options.robot_model!r}: a plan drives the {ScenarioOptions.robot_model}"
            )

    @property
    def unit_id(self) -> int:
        """Robot unit (`options.unit_id`, which a plan always gives)."""
        assert self.options.unit_id is not None  # __post_init__
        return self.options.unit_id

    def to_dict(self) -> dict[str, Any]:
        """The plan as it is written: one flat object (`_PlanRecord`)."""
        o = self.options
        record = _PlanRecord(
            self.episode_id, self.category, self.split, self.seed, self.unit_id, self.snr_db, o.duration,
            o.environment, o.obstacle_kind, o.fault_kind, o.wheel, o.severity, o.transient_density,
            o.surface, self.drive_speed_scale, self.approach_speed_scale,
        )  # fmt: skip
        doc: dict[str, Any] = plain(record)
        return doc

    @classmethod
    def from_dict(cls, doc: dict[str, Any], where: str) -> EpisodeSpec:
        """Read a plan written by `to_dict` (`where`: the file and the entry, for messages); a missing,
        ill-typed or unknown field is a `DatasetError` naming it."""
        r = read_record(_PlanRecord, doc, where, DatasetError)
        try:
            options = ScenarioOptions(
                duration=r.duration_s, environment=r.environment, obstacle_kind=r.obstacle_kind,
                fault_kind=r.fault_kind, wheel=r.wheel, severity=r.severity, unit_id=r.unit_id,
                transient_density=r.transient_density, surface=r.surface,
            )  # fmt: skip
            return cls(
                r.episode_id, r.category, r.split, r.seed, r.snr_db, options,
                r.drive_speed_scale, r.approach_speed_scale,
            )  # fmt: skip
        except ValueError as exc:
            raise DatasetError(f"{where}: {exc}") from exc


@dataclass(frozen=True)
class _PlanRecord:
    """An `EpisodeSpec` as manifest.json holds it, one flat object; the fields mean what `EpisodeSpec`'s and
    `ScenarioOptions`' do (`duration_s` is `ScenarioOptions.duration`). The last three were added later:
    a file without them reads at their defaults."""

    episode_id: str
    category: str
    split: str
    seed: int
    unit_id: int
    snr_db: float
    duration_s: float
    environment: str | None
    obstacle_kind: str | None
    fault_kind: str | None
    wheel: int | None
    severity: tuple[float, float]
    transient_density: float
    surface: str | None = None
    drive_speed_scale: float = 1.0
    approach_speed_scale: float = 1.0


@dataclass(frozen=True)
class DroppedWindow:
    """A window of a nominal episode left out because something anomalous happened in it."""

    episode: str
    """Episode folder name."""
    start_s: float
    """Window start, s."""
    kind: str
    """What happened (`collision` or `mechanical`)."""
    sub_kind: str
    """Obstacle or fault kind."""


@dataclass(frozen=True)
class ManifestWindows:
    """The manifest's `windows` entry: the window table's file, checksum and row count."""

    file: str
    """File name in the dataset folder (`windows.csv`)."""
    sha256: str
    """Hex sha256 of the file."""
    count: int
    """Windows (rows) in it."""


@dataclass(frozen=True)
class ManifestEpisode:
    """One entry of the manifest's `episodes`: the episode's plan and the sha256 of each of its files.

    In the file the entry is the plan's fields, `files` and (an import's) `recording`, side by side.
    """

    spec: EpisodeSpec
    """The plan it was simulated and rendered from (an import's: split, unit and length; `snr_db` NaN)."""
    files: dict[str, str]
    """File name -> hex sha256, for every file of the episode folder."""
    recording: str | None = None
    """An imported episode's recording name; None for a generated one."""

    @property
    def episode_id(self) -> str:
        """Folder name."""
        return self.spec.episode_id

    def to_dict(self) -> dict[str, Any]:
        """The entry as it is written (an SNR that is not known, NaN, as null: JSON has no NaN)."""
        doc = self.spec.to_dict()
        if math.isnan(self.spec.snr_db):
            doc["snr_db"] = None
        if self.recording is not None:
            doc["recording"] = self.recording
        doc["files"] = dict(self.files)
        return doc

    @classmethod
    def from_dict(cls, doc: object, where: str) -> ManifestEpisode:
        """Read an entry (`where`: the file and the entry, for messages)."""
        if not isinstance(doc, dict):
            raise DatasetError(f"{where}: expected a JSON object")
        plan = {k: v for k, v in doc.items() if k not in ("files", "recording")}
        if "snr_db" in plan and plan["snr_db"] is None:
            plan["snr_db"] = math.nan  # an import's: not known
        return cls(
            spec=EpisodeSpec.from_dict(plan, where),
            files=read_field(doc, "files", dict[str, str], where, DatasetError),
            recording=read_value(
                doc.get("recording"), str | None, f"{where}: field 'recording'", DatasetError
            ),
        )


@dataclass(frozen=True)
class ManifestImport:
    """The manifest's `import` section: where an imported dataset's recordings came from."""

    layout: str
    """Source layout (`folder`, `mimii`, `windows`)."""
    source: str
    """The source folder, resolved."""
    options: dict[str, Any]
    """The import options (`benchmarks.importers.config`), as given."""
    recordings: int
    """Recordings found in the source."""
    facts: dict[str, Any] = field(default_factory=dict)
    """The layout's own facts, side by side with the fields above in the file: `units` (mimii), `labels`,
    `split_file`, `imu` (folder), `window_slot_s`, `audio_rate`, `imu_rate` (windows)."""

    def to_dict(self) -> dict[str, Any]:
        """The section as it is written."""
        return {**self.facts, "layout": self.layout, "source": self.source, "options": self.options,
                "recordings": self.recordings}  # fmt: skip

    @classmethod
    def from_dict(cls, doc: object, where: str) -> ManifestImport:
        """Read the section (`where`: the file and the section, for messages)."""
        if not isinstance(doc, dict):
            raise DatasetError(f"{where}: expected a JSON object")
        own = ("layout", "source", "options", "recordings")
        section = read_record(cls, {k: v for k, v in doc.items() if k in own}, where, DatasetError)
        return cls(section.layout, section.source, section.options, section.recordings,
                   {k: v for k, v in doc.items() if k not in own})  # fmt: skip


_FIELDS: tuple[str, ...] = (
    "format_version",
    "preset",
    "seed",
    "software",
    "dropped_nominal_windows",
    "episodes",
    "windows",
    "source",
    "modalities",
    "import",
)
"""Top-level keys of `manifest.json` (the last three in an imported dataset's only)."""


@dataclass(frozen=True)
class Manifest:
    """A dataset's `manifest.json`, typed."""

    format_version: int
    """Dataset format version (`DATASET_FORMAT_VERSION` when written by this software)."""
    preset: Preset
    """The preset it was generated with (an import's: counts and hops of its data)."""
    seed: int
    """Dataset seed (0 for an import, which has none)."""
    software: dict[str, str]
    """Package -> version, of the packages that shape the data (`benchmarks.episode.software_versions`)."""
    dropped_nominal_windows: tuple[DroppedWindow, ...]
    """Windows of nominal episodes left out because something anomalous happened in them."""
    episodes: tuple[ManifestEpisode, ...]
    """Every episode, in plan order (an episode's index here seeds its robustness draws)."""
    windows: ManifestWindows
    """The window table."""
    imported: ManifestImport | None = None
    """Where an imported dataset came from; None for a generated one."""
    modalities: tuple[str, ...] = ALL_MODALITIES
    """The sensors the dataset carries (a generated one: every one)."""

    def __post_init__(self) -> None:
        """Refuse a generated manifest that claims fewer sensors, and sensors that do not exist."""
        unknown = [m for m in self.modalities if m not in ALL_MODALITIES]
        if unknown or not self.modalities:
            raise ValueError(
                f"field 'modalities': {list(self.modalities)}; allowed: a non-empty list of "
                f"{', '.join(ALL_MODALITIES)}"
            )
        if self.imported is None and self.modalities != ALL_MODALITIES:
            raise ValueError(
                f"field 'modalities': {list(self.modalities)} in a generated dataset, which carries every "
                "sensor; allowed: only with 'source': 'import'"
            )

    @property
    def source(self) -> str:
        """`simulate` (generated) or `import` (recordings)."""
        return SIMULATED if self.imported is None else IMPORTED

    def to_dict(self) -> dict[str, Any]:
        """The document `save` writes (JSON values only)."""
        doc: dict[str, Any] = {
            "format_version": self.format_version,
            "preset": plain(self.preset),
            "seed": self.seed,
            "software": dict(self.software),
            "dropped_nominal_windows": plain(self.dropped_nominal_windows),
            "episodes": [e.to_dict() for e in self.episodes],
            "windows": plain(self.windows),
        }
        if self.imported is not None:
            doc["source"] = IMPORTED
            doc["modalities"] = list(self.modalities)
            doc["import"] = self.imported.to_dict()
        return doc

    @classmethod
    def from_dict(cls, doc: object, file: Path | str = MANIFEST_FILE) -> Manifest:
        """Read and check a manifest document; `file` names it in a `DatasetError`."""
        where = str(file)
        if not isinstance(doc, dict):
            raise DatasetError(f"{where}: expected a JSON object")
        version = doc.get("format_version")
        if (
            isinstance(version, bool)
            or not isinstance(version, int)
            or version not in READABLE_DATASET_FORMATS
        ):
            *older, newest = (str(v) for v in READABLE_DATASET_FORMATS)
            readable = f"{', '.join(older)} or {newest}" if older else newest
            raise DatasetError(
                f"{where}: dataset format_version {version}, this software reads format_version "
                f"{readable}; generate the dataset again with `msvdd-bench generate`"
            )
        unknown = sorted(set(doc) - set(_FIELDS))
        if unknown:
            raise DatasetError(f"{where}: unknown field {unknown[0]!r}")
        source = read_value(doc.get("source", SIMULATED), str, f"{where}: field 'source'", DatasetError)
        if source not in (SIMULATED, IMPORTED):
            raise DatasetError(f"{where}: field 'source': {source!r}; allowed: {SIMULATED}, {IMPORTED}")
        if (source == IMPORTED) != ("import" in doc):
            raise DatasetError(f"{where}: field 'import' is required with 'source': 'import' and only there")
        preset = read_field(doc, "preset", dict[str, Any], where, DatasetError)
        scale = preset.get("method_scale")
        if isinstance(scale, str) and scale in LEGACY_SCALES:  # written before budgets were named apart
            preset = {**preset, "method_scale": LEGACY_SCALES[scale]}
        entries = read_field(doc, "episodes", tuple[Any, ...], where, DatasetError)
        episodes = tuple(ManifestEpisode.from_dict(e, _entry(where, i, e)) for i, e in enumerate(entries))
        imported = ManifestImport.from_dict(doc["import"], f"{where}: import") if "import" in doc else None
        modalities = doc.get("modalities", list(ALL_MODALITIES))
        try:
            return cls(
                format_version=version,
                preset=read_record(Preset, preset, f"{where}: preset", DatasetError),
                seed=read_field(doc, "seed", int, where, DatasetError),
                software=read_field(doc, "software", dict[str, str], where, DatasetError),
                dropped_nominal_windows=read_field(
                    doc, "dropped_nominal_windows", tuple[DroppedWindow, ...], where, DatasetError
                ),
                episodes=episodes,
                windows=read_field(doc, "windows", ManifestWindows, where, DatasetError),
                imported=imported,
                modalities=read_value(
                    modalities, tuple[str, ...], f"{where}: field 'modalities'", DatasetError
                ),
            )
        except DatasetError:
            raise
        except ValueError as exc:  # the manifest's own checks (`__post_init__`)
            raise DatasetError(f"{where}: {exc}") from exc

    @classmethod
    def load(cls, folder: Path) -> Manifest:
        """Read the manifest of the dataset folder `folder`.

        Raises:
            InputNotFoundError: `folder` has no manifest (it is not a dataset).
            DatasetError: the manifest is not JSON, or a field is missing, ill-typed or unknown, or its format
                version is not one this software reads (the message names the file and the field).
        """
        path = Path(folder) / MANIFEST_FILE
        if not path.is_file():
            raise InputNotFoundError(f"not a dataset (no {MANIFEST_FILE}): {folder}")
        return cls.from_dict(read_json(path, DatasetError), path)

    def save(self, folder: Path) -> Path:
        """Write `manifest.json` into the dataset folder `folder` (atomically); returns its path."""
        path = Path(folder) / MANIFEST_FILE
        write_json(path, self.to_dict())
        return path


def _entry(where: str, index: int, doc: object) -> str:
    """How messages name the episode entry `doc` at `index`: its position and, when it has one, its id."""
    name = doc.get("episode_id") if isinstance(doc, dict) else None
    return f"{where}: episodes[{index}]" + (f" ({name})" if isinstance(name, str) else "")


def is_dataset_folder(folder: Path) -> bool:
    """Whether `folder` holds a dataset manifest."""
    return (Path(folder) / MANIFEST_FILE).is_file()
