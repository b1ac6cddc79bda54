"""Dataset presets: how much nominal, collision and fault driving to simulate, and how hard it is."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from benchmarks.errors import UserError
from sim.random_scenarios import SPEED_SCALE_RANGE
from sim.vocab import ENVIRONMENTS, FAULT_KINDS, OBSTACLE_KINDS, SURFACES


@dataclass(frozen=True)
class Preset:
    """A dataset recipe and the training budget that goes with it."""

    name: str
    """Preset name (`tiny`, `quick`, `paper`, `hard`, `ci`)."""
    description: str
    """One line for `msvdd-bench scenarios` and reports."""
    nominal_train: int
    """Nominal sequences used for training."""
    nominal_val: int
    """Of the training sequences, how many are held out as nominal validation (model selection only)."""
    nominal_train_duration_s: float
    """Length of each training (and validation) nominal sequence, s."""
    nominal_test: int
    """Nominal sequences used for testing (many short ones: each is one cluster of the bootstrap)."""
    nominal_test_duration_s: float
    """Length of each test nominal sequence, s."""
    collisions_per_kind: int
    """Collision episodes per obstacle kind (test only)."""
    collision_duration_s: float
    """Length of each collision episode, s."""
    faults_per_kind_wheel: int
    """Fault episodes per (fault kind, wheel) pair (test only)."""
    fault_duration_s: float
    """Length of each fault episode, s."""
    severity: tuple[float, float]
    """Range fault severities are drawn from, 0..1."""
    snr_db: tuple[float, float]
    """(low, high) robot-to-environment SNR range, dB: each episode of every split draws its SNR uniformly."""
    transient_density: float
    """Benign transients per metre relative to the default (1.0)."""
    train_units: tuple[int, ...]
    """Robot units driven in training sequences."""
    test_units: tuple[int, ...]
    """Robot units driven in test episodes (units outside `train_units` are unseen)."""
    train_hop_s: float
    """Hop between training windows, s (windows are 2 s)."""
    test_hop_s: float
    """Hop between test windows, s."""
    method_scale: str
    """Training budget passed to every method (`tiny`, `quick`, `paper`)."""
    seeds: tuple[int, ...]
    """Training seeds per method; metrics are reported as mean and std over them."""
    methods: tuple[str, ...] = field(default=())
    """Methods `msvdd-bench run` trains by default (empty = every registered method)."""
    fault_kinds: tuple[str, ...] = FAULT_KINDS
    """Fault kinds generated."""
    obstacle_kinds: tuple[str, ...] = OBSTACLE_KINDS
    """Obstacle kinds generated."""
    wheels: tuple[int, ...] = (0, 1, 2, 3)
    """Wheels faults are injected on."""
    drive_speed_scale: float = 1.0
    """Factor on every cruise speed (`sim.random_scenarios.scale_speeds`; 1 = as drawn)."""
    approach_speed_scale: float = 1.0
    """Factor on the speed of legs driven at an obstacle: collision hits and near misses (1 = as drawn)."""
    train_environments: tuple[str, ...] = ()
    """Environments of training (and validation) sequences (empty = every one)."""
    test_environments: tuple[str, ...] = ()
    """Environments of test episodes (empty = every one; outside `train_environments`: unseen)."""
    train_surfaces: tuple[str, ...] = ()
    """Floor surfaces of training (and validation) sequences (empty = every one)."""
    test_surfaces: tuple[str, ...] = ()
    """Floor surfaces of test episodes (empty = every one; outside `train_surfaces`: unseen)."""

    def __post_init__(self) -> None:
        """Refuse an SNR range that is not (low, high) with low <= high, unknown floors, and speed factors
        out of range."""
        if len(self.snr_db) != 2 or not self.snr_db[0] <= self.snr_db[1]:
            raise UserError(
                f"preset {self.name!r}: snr_db must be a (low, high) range in dB with low <= high, "
                f"got {self.snr_db}"
            )
        for name, allowed in (
            ("train_environments", ENVIRONMENTS),
            ("test_environments", ENVIRONMENTS),
            ("train_surfaces", SURFACES),
            ("test_surfaces", SURFACES),
        ):
            for value in getattr(self, name):
                if value not in allowed:
                    raise UserError(
                        f"preset {self.name!r}: {name} has {value!r}; allowed: {', '.join(allowed)}"
                    )
        low, high = SPEED_SCALE_RANGE
        for name in ("drive_speed_scale", "approach_speed_scale"):
            value = getattr(self, name)
            if not low <= value <= high:
                raise UserError(
                    f"preset {self.name!r}: {name} = {value!r} is invalid; allowed: {low} to {high}"
                )


QUICK_METHODS: tuple[str, ...] = (
    "msvdd",
    "msvdd-euclidean",
    "dae",
    "gaussian-early",
    "frame-density-msvdd",
    "frame-density",
    "iforest-early",
    "ocsvm-early",
    "dcase-ae",
    "audio-rms",
    "imu-kurtosis",
)

TABLE1_METHODS: tuple[str, ...] = (
    "msvdd",
    "msvdd-paper",
    "dsvdd",
    "dae",
    "vae-svdd",
    "dagmm",
    "deep-if",
    "dcase-ae",
    "iforest-early",
    "iforest-late",
    "ocsvm-early",
    "ocsvm-late",
    "svdd-early",
    "svdd-late",
    "gaussian-early",
    "frame-density-msvdd",
    "frame-density",
    "context-net-frames",
    "audio-rms",
    "imu-kurtosis",
)
"""The paper's comparison (Table I), the reference detectors (the audit's window statistics; the
frame-density detector with M-SVDD's distance, its no-network twin and the frame densities with fixed IMU
mixtures) and the naive sanity baselines: what `make bench` trains."""

ABLATION_METHODS: tuple[str, ...] = (
    "msvdd-audio-only",
    "msvdd-imu-only",
    "msvdd-no-rec",
    "msvdd-euclidean",
    "msvdd-fusion-concat",
    "msvdd-fusion-sum",
    "msvdd-fusion-product",
    "msvdd-s2",
    "msvdd-s4",
    "msvdd-s8",
    "msvdd-s16",
    "msvdd-s64",
)
"""The module, fusion and latent-dimension ablations (`make ablations`)."""

_PRESETS: dict[str, Preset] = {
    "tiny": Preset(
        name="tiny",
        description="seconds: a handful of short episodes, for tests",
        nominal_train=3,
        nominal_val=1,
        nominal_train_duration_s=20.0,
        nominal_test=2,
        nominal_test_duration_s=10.0,
        collisions_per_kind=1,
        collision_duration_s=14.0,
        faults_per_kind_wheel=1,
        fault_duration_s=12.0,
        severity=(0.6, 1.0),
        snr_db=(6.0, 6.0),
        transient_density=1.0,
        train_units=(0, 1),
        test_units=(0, 1),
        train_hop_s=0.5,
        test_hop_s=2.0,
        method_scale="smoke",
        seeds=(0,),
        methods=("msvdd", "iforest-early", "audio-rms"),
        obstacle_kinds=("wall", "box"),
        fault_kinds=("out_of_round", "bearing"),
        wheels=(0,),
    ),
    "quick": Preset(
        name="quick",
        description="the default: a few minutes on 2 cores (what `make demo` runs)",
        nominal_train=6,
        nominal_val=1,
        nominal_train_duration_s=90.0,
        nominal_test=6,
        nominal_test_duration_s=30.0,
        collisions_per_kind=2,
        collision_duration_s=14.0,
        faults_per_kind_wheel=1,
        fault_duration_s=16.0,
        severity=(0.4, 1.0),
        snr_db=(0.0, 12.0),
        transient_density=1.0,
        train_units=(0, 1, 2),
        test_units=(0, 1, 2),
        train_hop_s=1.0,
        test_hop_s=2.0,
        method_scale="short",
        seeds=(0,),
        methods=QUICK_METHODS,
        wheels=(0, 3),
    ),
    "paper": Preset(
        name="paper",
        description="the paper's size in many short episodes (statistical power): ~3 h nominal, 48 "
        "training sequences of 120 s (6 validation) and 168 test ones of 30 s (24 per floor); 56 collisions "
        "of 16 s per obstacle kind, 10 faults of 20 s per fault kind and wheel; SNR 0-12 dB",
        nominal_train=48,
        nominal_val=6,
        nominal_train_duration_s=120.0,
        nominal_test=168,
        nominal_test_duration_s=30.0,
        collisions_per_kind=56,
        collision_duration_s=16.0,
        faults_per_kind_wheel=10,
        fault_duration_s=20.0,
        severity=(0.3, 1.0),
        snr_db=(0.0, 12.0),
        transient_density=1.0,
        train_units=(0, 1, 2, 3),
        test_units=(0, 1, 2, 3),
        train_hop_s=1.0,
        test_hop_s=1.0,
        method_scale="full",
        seeds=(0, 1, 2),
        methods=TABLE1_METHODS,
    ),
}


METHOD_GROUPS: dict[str, tuple[str, ...]] = {
    "table1": TABLE1_METHODS,
    "ablations": ("msvdd", *ABLATION_METHODS),
}
"""Names `--methods` accepts for a group of methods (plus `all`, every registered method)."""


def expand_methods(names: list[str], registered: list[str]) -> list[str]:
    """Method names with groups (`table1`, `ablations`, `all`) expanded, in order, without repeats."""
    out: list[str] = []
    for name in names:
        group = registered if name == "all" else METHOD_GROUPS.get(name, (name,))
        out += [n for n in group if n not in out]
    return out


_PRESETS["hard"] = dataclasses.replace(
    _PRESETS["paper"],
    name="hard",
    description="the paper's size with low-severity faults, SNR -6 to 3 dB, twice the benign transients, "
    "robot units unseen in training",
    severity=(0.05, 0.35),
    snr_db=(-6.0, 3.0),
    transient_density=2.0,
    train_units=(0, 1, 2),
    test_units=(3, 4),
)


CI_METHODS: tuple[str, ...] = ("msvdd", "gaussian-early", "audio-rms")
"""What the `ci` preset trains by default: M-SVDD at the short budget, the reference detector and the naive
audio RMS (the regression gate's reference points)."""

_PRESETS["ci"] = dataclasses.replace(
    _PRESETS["quick"],
    name="ci",
    description="a CI regression gate: quick's training set, a test set of many short episodes (16 nominal "
    "sequences, 16 collisions, 10 faults, windows every 1 s) for tighter paired intervals; M-SVDD at quick "
    "scale, the reference and audio RMS",
    nominal_test=16,
    nominal_test_duration_s=20.0,
    test_hop_s=1.0,
    methods=CI_METHODS,
)


def preset_names() -> list[str]:
    """Names of every preset."""
    return list(_PRESETS)


def get_preset(name: str) -> Preset:
    """The preset called `name`; a UserError naming the allowed presets otherwise."""
    try:
        return _PRESETS[name]
    except KeyError:
        raise UserError(f"unknown preset {name!r}; allowed: {', '.join(_PRESETS)}") from None
