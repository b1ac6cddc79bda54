"""Sweep specs: a small TOML file, parsed into typed dataclasses; every point is a derived, named Preset.

```toml
title = "Fault severity"                   # optional (default: the file's name)
base = "quick"                             # the preset every point derives from (`msvdd-bench presets`)
seeds = [0]                                # dataset seeds: each point is generated once per seed
methods = ["gaussian-early", "audio-rms"]  # methods or groups, as `run --methods` takes them
scale = "short"                            # optional training budget (default: the base preset's)
train_seeds = [0]                          # optional training seeds (default: the base preset's)
axis = "severity"                          # one of AXES
values = [0.1, 0.3, 0.6, 1.0]              # the points, in the axis's form
labels = ["weak", "mild", "clear", "full"] # optional point names (default: the values)

[overrides]                                # optional: base-preset fields set for every point
nominal_test = 8
```

A bad spec is refused with one line naming the file, the key, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from benchmarks.errors import InputNotFoundError, UserError, check_seed
from benchmarks.methods.base import SCALES
from benchmarks.presets import Preset, get_preset
from sim.random_scenarios import SPEED_SCALE_RANGE
from sim.vocab import ENVIRONMENTS, FAULT_KINDS, OBSTACLE_KINDS, SURFACES

AxisValue = float | tuple[float, float] | tuple[int, ...] | tuple[str, ...]
"""One point's value: a factor, a (low, high) range, robot unit ids or names."""


@dataclass(frozen=True)
class Axis:
    """A quantity a sweep can vary, and the Preset field each point sets."""

    name: str
    """Name in a spec's `axis`."""
    field: str
    """The Preset field a point sets."""
    kind: str
    """`range` (a number v, meaning [v, v], or [low, high]), `factor` (a number), `units` (a list of robot
    unit ids) or `names` (a list of names from `allowed`)."""
    label: str
    """Axis label of the plots."""
    low: float = -math.inf
    """Smallest number allowed (`range`, `factor`)."""
    high: float = math.inf
    """Largest number allowed (`range`, `factor`)."""
    allowed: tuple[str, ...] = ()
    """Names allowed (`names`)."""

    @property
    def numeric(self) -> bool:
        """Whether points sit on a numeric x axis (else one categorical tick per point)."""
        return self.kind in ("range", "factor")

    def allowed_text(self) -> str:
        """What a value of this axis may be, for error messages."""
        if self.kind == "range":
            return f"a number or [low, high] with {self.low:g} <= low <= high <= {self.high:g}"
        if self.kind == "factor":
            return f"a number from {self.low:g} to {self.high:g}"
        if self.kind == "units":
            return "a non-empty list of robot unit ids (integers >= 0)"
        return f"a non-empty list of names from {', '.join(self.allowed)}"


AXES: dict[str, Axis] = {
    a.name: a
    for a in (
        Axis("severity", "severity", "range", "fault severity (0..1)", 0.0, 1.0),
        Axis("snr_db", "snr_db", "range", "robot-to-environment SNR (dB)", -30.0, 40.0),
        Axis("drive_speed", "drive_speed_scale", "factor", "driving speed (x as drawn)", *SPEED_SCALE_RANGE),
        Axis(
            "approach_speed",
            "approach_speed_scale",
            "factor",
            "obstacle approach speed (x as drawn)",
            *SPEED_SCALE_RANGE,
        ),
        Axis("test_units", "test_units", "units", "test robot units"),
        Axis("test_surfaces", "test_surfaces", "names", "test floor surfaces", allowed=SURFACES),
        Axis("test_environments", "test_environments", "names", "test environments", allowed=ENVIRONMENTS),
    )
}
"""Every axis a sweep can vary, by name. The domain-shift axes (`test_*`) pair with the training side set in
`[overrides]` (`train_units`, `train_surfaces`, `train_environments`): test values outside it are unseen."""

_KEYS: dict[str, bool] = {
    "title": False,
    "base": True,
    "seeds": False,
    "methods": True,
    "scale": False,
    "train_seeds": False,
    "axis": True,
    "values": True,
    "labels": False,
    "overrides": False,
    "oracle": False,
}
"""Top-level keys of a spec, and whether each is required."""

_NOT_OVERRIDABLE: dict[str, str] = {
    "name": "points are named after the base preset and the axis",
    "description": "points are described after the base preset and the axis",
    "methods": "use the spec's `methods`",
    "seeds": "use the spec's `train_seeds`",
}
"""Preset fields `[overrides]` refuses, with the reason."""

SPECS_PACKAGE = "assets.sweeps"
"""Where the example specs ship (`msvdd-bench sweep NAME` finds `assets/sweeps/NAME.toml`)."""


@dataclass(frozen=True)
class SweepPoint:
    """One point of the curve: its value and the preset its datasets are generated from."""

    index: int
    """Position in the spec's `values`."""
    label: str
    """Name in tables and on categorical plots."""
    x: float
    """Position on the plot's x axis (the value, a range's midpoint, or the index)."""
    value: AxisValue
    """The axis value as parsed."""
    preset: Preset
    """The base preset (with overrides) with the axis field set to `value`."""


@dataclass(frozen=True)
class SweepSpec:
    """A parsed, validated sweep spec."""

    source: str
    """The spec file it was read from."""
    title: str
    """Report title."""
    base: str
    """Name of the base preset."""
    seeds: tuple[int, ...]
    """Dataset seeds; every point is generated once per seed."""
    methods: tuple[str, ...]
    """Methods (or groups) trained at every point."""
    scale: str | None
    """Training budget (None: the base preset's)."""
    train_seeds: tuple[int, ...] | None
    """Training seeds per method (None: the base preset's)."""
    axis: Axis
    """The swept axis."""
    values: tuple[AxisValue, ...]
    """The points' values, in order."""
    labels: tuple[str, ...]
    """The points' names, in order."""
    overrides: tuple[tuple[str, Any], ...] = ()
    """(Preset field, value) set on the base for every point."""
    oracle: bool = False
    """Whether every point's dataset is also scored by the audit's privileged fault oracle
    (`benchmarks.audit.oracle`), reported as the method `oracle`, per fault kind."""

    def base_preset(self) -> Preset:
        """The base preset with the overrides applied."""
        try:
            return dataclasses.replace(get_preset(self.base), **dict(self.overrides))
        except UserError as exc:
            raise UserError(f"{self.source}: [overrides]: {exc}") from None

    def points(self) -> list[SweepPoint]:
        """Every point, with its derived preset (validated)."""
        base = self.base_preset()
        out: list[SweepPoint] = []
        for i, (value, label) in enumerate(zip(self.values, self.labels, strict=True)):
            field_value: Any = (
                (float(value), float(value))
                if self.axis.kind == "range" and isinstance(value, float)
                else value
            )
            text = _value_text(value)
            try:
                preset = dataclasses.replace(
                    base,
                    name=f"{base.name}+{self.axis.name}={text}",
                    description=f"{base.description} | sweep point: {self.axis.name} = {text}",
                    **{self.axis.field: field_value},
                )
            except UserError as exc:
                raise UserError(f"{self.source}: values[{i}] = {value!r}: {exc}") from None
            out.append(SweepPoint(i, label, _x(self.axis, i, field_value), value, preset))
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, in the spec's own keys."""
        return {
            "title": self.title,
            "base": self.base,
            "seeds": list(self.seeds),
            "methods": list(self.methods),
            "scale": self.scale,
            "train_seeds": None if self.train_seeds is None else list(self.train_seeds),
            "axis": self.axis.name,
            "values": [list(v) if isinstance(v, tuple) else v for v in self.values],
            "labels": list(self.labels),
            "overrides": {k: list(v) if isinstance(v, tuple) else v for k, v in self.overrides},
            "oracle": self.oracle,
        }


def _value_text(value: AxisValue) -> str:
    if isinstance(value, tuple):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    return f"{value:g}"


def _x(axis: Axis, index: int, value: Any) -> float:
    if axis.kind == "range":
        return 0.5 * (value[0] + value[1])
    return float(value) if axis.kind == "factor" else float(index)


def resolve_spec(name: str | Path) -> Path:
    """The spec file `name` names: a path, or the name of a spec shipped in `assets/sweeps/`."""
    path = Path(name)
    if path.is_file():
        return path
    shipped = _specs_dir() / f"{path.stem}.toml"
    if path.suffix in ("", ".toml") and path.parent == Path(".") and shipped.is_file():
        return shipped
    raise InputNotFoundError(
        f"sweep spec not found: {name} (a TOML file, or one of: {', '.join(shipped_specs())})"
    )


def shipped_specs() -> list[str]:
    """Names of the example specs in `assets/sweeps/`."""
    return sorted(p.name.removesuffix(".toml") for p in _specs_dir().glob("*.toml"))


def _specs_dir() -> Path:
    """The folder of the shipped specs. `importlib.resources.files` fails on Python 3.11 for a namespace
    package installed in editable mode (see `sim.robot.asset_path`), so the package's paths are searched."""
    package = importlib.import_module(SPECS_PACKAGE)
    for entry in getattr(package, "__path__", []):
        if Path(entry).is_dir():
            return Path(entry)
    return Path(str(resources.files(SPECS_PACKAGE)))


def load_spec(name: str | Path) -> SweepSpec:
    """Read and validate a sweep spec (a path, or the name of a shipped one)."""
    path = resolve_spec(name)
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: not valid TOML ({exc})") from None
    return parse_spec(doc, str(path))


def parse_spec(doc: dict[str, Any], source: str) -> SweepSpec:
    """A SweepSpec from a parsed TOML document; UserError naming `source`, the key, value and allowed."""

    def bad(key: str, value: object, allowed: str) -> UserError:
        return UserError(f"{source}: {key} = {value!r} is invalid; allowed: {allowed}")

    for key in doc:
        if key not in _KEYS:
            raise bad(key, doc[key], f"the keys {', '.join(_KEYS)}")
    for key, required in _KEYS.items():
        if required and key not in doc:
            raise UserError(
                f"{source}: missing key {key!r}; a spec needs {', '.join(k for k, r in _KEYS.items() if r)}"
            )
    base = doc["base"]
    if not isinstance(base, str):
        raise bad("base", base, "a preset name (msvdd-bench presets)")
    try:
        get_preset(base)
    except UserError as exc:
        raise UserError(f"{source}: base: {exc}") from None
    axis_name = doc["axis"]
    if axis_name not in AXES:
        raise bad("axis", axis_name, ", ".join(AXES))
    axis = AXES[axis_name]
    raw_values = doc["values"]
    if not isinstance(raw_values, list) or not raw_values:
        raise bad("values", raw_values, f"a non-empty list, each value {axis.allowed_text()}")
    values: list[AxisValue] = []
    for i, raw in enumerate(raw_values):
        values.append(_axis_value(axis, raw, bad(f"values[{i}]", raw, axis.allowed_text())))
    if len(set(values)) != len(values):
        raise bad("values", raw_values, "distinct values")
    labels = doc.get("labels", [_value_text(v) for v in values])
    if not (
        isinstance(labels, list) and len(labels) == len(values) and all(isinstance(s, str) for s in labels)
    ):
        raise bad("labels", labels, f"a list of {len(values)} strings, one per value")
    seed_list = "a non-empty list of integers >= 0"
    seeds = _int_list(doc.get("seeds", [0]), bad("seeds", doc.get("seeds"), seed_list))
    raw_train_seeds = doc.get("train_seeds")
    train_seeds = None
    if raw_train_seeds is not None:
        train_seeds = _int_list(raw_train_seeds, bad("train_seeds", raw_train_seeds, seed_list))
    methods = doc["methods"]
    if not (isinstance(methods, list) and methods and all(isinstance(m, str) for m in methods)):
        raise bad("methods", methods, "a non-empty list of method names or groups (msvdd-bench methods)")
    scale = doc.get("scale")
    if scale is not None and scale not in SCALES:
        raise bad("scale", scale, ", ".join(SCALES))
    title = doc.get("title", Path(source).stem)
    if not isinstance(title, str):
        raise bad("title", title, "a string")
    raw_overrides = doc.get("overrides", {})
    if not isinstance(raw_overrides, dict):
        raise bad("overrides", raw_overrides, "a table of preset fields")
    overrides = tuple((key, _override(key, value, axis, bad)) for key, value in raw_overrides.items())
    oracle = doc.get("oracle", False)
    if not isinstance(oracle, bool):
        raise bad("oracle", oracle, "true or false")
    spec = SweepSpec(
        source=source,
        title=title,
        base=base,
        seeds=seeds,
        methods=tuple(methods),
        scale=scale,
        train_seeds=train_seeds,
        axis=axis,
        values=tuple(values),
        labels=tuple(labels),
        overrides=overrides,
        oracle=oracle,
    )
    spec.points()  # every derived preset validates
    return spec


def _is_number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _int_list(v: object, error: UserError) -> tuple[int, ...]:
    if not isinstance(v, list) or not v:
        raise error
    try:
        return tuple(check_seed(x) for x in v)
    except UserError:
        raise error from None


def _axis_value(axis: Axis, v: object, error: UserError) -> AxisValue:
    """One value of `axis`, parsed and range-checked (`error` is raised otherwise)."""
    if axis.kind in ("range", "factor"):
        if _is_number(v):
            x = float(v)  # type: ignore[arg-type]
            if not axis.low <= x <= axis.high:
                raise error
            return x
        if axis.kind == "range" and isinstance(v, list) and len(v) == 2 and all(map(_is_number, v)):
            low, high = float(v[0]), float(v[1])
            if not axis.low <= low <= high <= axis.high:
                raise error
            return (low, high)
        raise error
    if not isinstance(v, list) or not v or len(set(map(str, v))) != len(v):
        raise error
    if axis.kind == "units":
        if not all(isinstance(u, int) and not isinstance(u, bool) and u >= 0 for u in v):
            raise error
        return tuple(int(u) for u in v)
    if not all(isinstance(n, str) and n in axis.allowed for n in v):
        raise error
    return tuple(str(n) for n in v)


_NAMED_FIELDS: dict[str, tuple[str, ...]] = {"fault_kinds": FAULT_KINDS, "obstacle_kinds": OBSTACLE_KINDS}
"""Preset fields whose names the simulator must know (the floor fields are checked by Preset itself)."""

_FIELD_TYPES: dict[str, str] = {f.name: str(f.type) for f in dataclasses.fields(Preset)}
"""Preset field name -> its annotation (a string: presets.py uses postponed annotations)."""


def _override(key: str, value: object, axis: Axis, bad: Any) -> Any:
    """An `[overrides]` entry converted to its Preset field's type."""
    where = f"overrides.{key}"
    if key not in _FIELD_TYPES:
        allowed = [k for k in _FIELD_TYPES if k not in _NOT_OVERRIDABLE]
        raise bad(where, value, f"a preset field: {', '.join(allowed)}")
    if key in _NOT_OVERRIDABLE:
        raise bad(where, value, f"not overridable ({_NOT_OVERRIDABLE[key]})")
    if key == axis.field:
        raise bad(where, value, f"not the swept field (axis {axis.name} sets {key} at every point)")
    kind = _FIELD_TYPES[key]
    if kind == "int" and isinstance(value, int) and not isinstance(value, bool) and value >= 0:
        return value
    if kind == "float" and _is_number(value):
        return float(value)  # type: ignore[arg-type]
    if kind == "str" and isinstance(value, str):
        return value
    if isinstance(value, list):
        if kind == "tuple[float, float]" and len(value) == 2 and all(map(_is_number, value)):
            return (float(value[0]), float(value[1]))
        if kind == "tuple[int, ...]" and all(isinstance(v, int) and not isinstance(v, bool) for v in value):
            return tuple(value)
        if kind == "tuple[str, ...]" and all(isinstance(v, str) for v in value):
            allowed_names = _NAMED_FIELDS.get(key)
            unknown = [v for v in value if allowed_names is not None and v not in allowed_names]
            if unknown:
                raise bad(where, value, f"names from {', '.join(allowed_names or ())}")
            return tuple(value)
    shapes = {
        "int": "an integer >= 0",
        "float": "a number",
        "str": "a string",
        "tuple[float, float]": "[low, high]",
        "tuple[int, ...]": "a list of integers",
        "tuple[str, ...]": "a list of strings",
    }
    raise bad(where, value, shapes.get(kind, kind))
