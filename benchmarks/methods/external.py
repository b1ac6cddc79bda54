"""Detectors from outside the project, named on the command line as `module:Class`.

`msvdd-bench run --methods mypkg.detectors:EnergyDetector` (also `train --method`) imports `mypkg.detectors`
(installed, or on `PYTHONPATH`) and builds `EnergyDetector`, which implements the detector contract
`msvdd.contract.Detector` (subclassing it gives the project's threshold rule for free; any class with the
same methods works): `fit(train, val=None)` returning self and setting `threshold_`, `score(batch)`,
`predict(batch)`, `save(path)` and the classmethod `load(path)`. Its constructor is called with whichever of
the keyword arguments `seed`, `scale` and `device` it accepts (none is required). The saved model's
`method.json` records the `module:Class` name, so `evaluate` loads it again through the same import.
An optional class attribute `modality` (`audio+imu`, `audio` or `imu`) is shown in reports.
"""

from __future__ import annotations

import importlib
import inspect
from typing import Any, cast

from benchmarks.errors import UserError
from benchmarks.methods.spec import MODALITIES, MethodSpec
from msvdd.contract import Detector

EXTERNAL_FAMILY = "external"
"""The family every detector from outside the project is reported under."""

CONTRACT_METHODS: tuple[str, ...] = ("fit", "score", "predict", "save", "load")
"""What a class must define to take part (`msvdd.contract.Detector`; `threshold_` is set by `fit`)."""

_FACTORY_ARGS: tuple[str, ...] = ("seed", "scale", "device")
"""Keyword arguments passed to the class's constructor when it accepts them."""

_RESOLVED: dict[str, MethodSpec] = {}


def is_external(name: str) -> bool:
    """Whether a method name is a `module:Class` entry point rather than a registry name."""
    return ":" in name


def external_spec(name: str) -> MethodSpec:
    """The `MethodSpec` of the `module:Class` detector `name`, imported on first use.

    Raises:
        UserError: the name is malformed, the module cannot be imported, it has no such class, or the class
            lacks a method of the detector contract (the message names the string and what is missing).
    """
    if name in _RESOLVED:
        return _RESOLVED[name]
    module_name, _, class_path = name.partition(":")
    if not module_name or not class_path or ":" in class_path:
        raise UserError(
            f"method {name!r}: a detector from outside the project is named module:Class, "
            "e.g. mypkg.detectors:EnergyDetector"
        )
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise UserError(
            f"method {name!r}: cannot import module {module_name!r} ({exc}); install it or put its folder "
            "on PYTHONPATH"
        ) from exc
    found: Any = module
    for part in class_path.split("."):
        found = getattr(found, part, None)
        if found is None:
            raise UserError(f"method {name!r}: module {module_name!r} has no class {class_path!r}")
    if not inspect.isclass(found):
        raise UserError(f"method {name!r}: {class_path!r} is a {type(found).__name__}, not a class")
    missing = [m for m in CONTRACT_METHODS if not callable(getattr(found, m, None))]
    if missing:
        raise UserError(
            f"method {name!r}: class {class_path!r} lacks {', '.join(missing)} of the detector contract "
            "(msvdd.contract.Detector: fit, score, predict, save, classmethod load, threshold_)"
        )
    modality = str(getattr(found, "modality", "audio+imu"))
    if modality not in MODALITIES:
        raise UserError(
            f"method {name!r}: class attribute modality = {modality!r}; allowed: {', '.join(MODALITIES)}"
        )
    doc = inspect.getdoc(found) or ""
    description = doc.splitlines()[0] if doc else f"external detector {name}"
    cls = cast("type[Detector]", found)  # duck-typed: the contract's methods were checked above
    spec = MethodSpec(name, _factory(found), EXTERNAL_FAMILY, modality, description, cls)
    _RESOLVED[name] = spec
    return spec


def _factory(cls: type) -> Any:
    """factory(seed, scale, device) building `cls` with the keyword arguments its constructor accepts."""
    try:
        params = inspect.signature(cls).parameters
    except (TypeError, ValueError):
        params = {}  # type: ignore[assignment]
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    accepted = [k for k in _FACTORY_ARGS if takes_any or k in params]

    def make(seed: int, scale: str, device: str) -> Detector:
        given = {"seed": seed, "scale": scale, "device": device}
        detector: Detector = cls(**{k: given[k] for k in accepted})
        return detector

    return make
