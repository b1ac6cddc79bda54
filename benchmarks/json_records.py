"""JSON files as typed records: how `manifest.json` (`benchmarks.manifest`) and an episode's `events.json`
(`benchmarks.episode`) are read and written.

`read_record(cls, doc, where, error)` builds a frozen dataclass from a JSON object and checks every field
against its annotation: a missing field (one without a default), a value of another type or a key that is no
field raises `error` with a message that starts with `where` (the file and the object's place in it) and
names the field. Lists become tuples; an integer is a valid float and is kept as it was read, so that
writing the record again gives the same text. `plain` turns records back into JSON values and `write_json`
writes a document the way every JSON file of a dataset is written (sorted keys, two-space indent, a final
newline), atomically.
"""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from msvdd.atomic import write_text_atomic

R = TypeVar("R")

ErrorType = Callable[[str], Exception]
"""Makes the exception to raise from a message (a `UserError` subclass, e.g. `DatasetError`)."""


def read_record(cls: type[R], doc: object, where: str, error: ErrorType) -> R:
    """The record `cls` (a dataclass) from the JSON object `doc`, every field checked (module docstring).

    Fields with a default may be missing (files written before the field existed). A `ValueError` the
    record's own checks raise is re-raised as `error`, prefixed with `where`.
    """
    if not isinstance(doc, dict):
        raise error(f"{where}: expected a JSON object, got {_show(doc)}")
    fields = dataclasses.fields(cls)  # type: ignore[arg-type]
    unknown = sorted(set(doc) - {f.name for f in fields})
    if unknown:
        raise error(f"{where}: unknown field {unknown[0]!r}")
    hints = typing.get_type_hints(cls)
    kwargs: dict[str, Any] = {}
    for f in fields:
        if f.name in doc:
            kwargs[f.name] = read_value(doc[f.name], hints[f.name], f"{where}: field {f.name!r}", error)
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise error(f"{where}: missing field {f.name!r}")
    try:
        return cls(**kwargs)
    except ValueError as exc:
        raise error(f"{where}: {exc}") from exc


def read_field(doc: dict[str, Any], name: str, hint: Any, where: str, error: ErrorType) -> Any:
    """`doc[name]` checked against `hint`; a missing field is an `error` naming it."""
    if name not in doc:
        raise error(f"{where}: missing field {name!r}")
    return read_value(doc[name], hint, f"{where}: field {name!r}", error)


def read_value(value: object, hint: Any, where: str, error: ErrorType, expected: str = "") -> Any:
    """`value` (parsed JSON) checked against the annotation `hint`: `str`, `int`, `float`, `bool`, `Any`,
    `X | None`, `tuple[X, ...]`, `tuple[X, Y]`, `dict[str, X]` or a dataclass; lists come back as tuples.
    (`expected`: what a message says was expected, by default `hint` described.)"""
    if hint is Any:
        return value
    expected = expected or _describe(hint)
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        if value is None and type(None) in args:
            return None
        rest = [a for a in args if a is not type(None)]
        if len(rest) != 1:
            raise TypeError(f"read_value: unsupported annotation {hint!r}")
        return read_value(value, rest[0], where, error, expected)
    if origin is tuple:
        if not isinstance(value, list):
            raise error(f"{where}: expected {expected}, got {_show(value)}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(read_value(v, args[0], f"{where}[{i}]", error) for i, v in enumerate(value))
        if len(value) != len(args):
            raise error(f"{where}: expected {expected}, got {_show(value)}")
        return tuple(
            read_value(v, a, f"{where}[{i}]", error) for i, (v, a) in enumerate(zip(value, args, strict=True))
        )
    if origin is dict:
        if not isinstance(value, dict):
            raise error(f"{where}: expected {expected}, got {_show(value)}")
        return {k: read_value(v, args[1], f"{where}[{k!r}]", error) for k, v in value.items()}
    if dataclasses.is_dataclass(hint):
        return read_record(typing.cast(type, hint), value, where, error)
    if hint not in (str, int, float, bool):
        raise TypeError(f"read_value: unsupported annotation {hint!r}")
    number = isinstance(value, int | float) and not isinstance(value, bool)
    ok = {
        str: isinstance(value, str),
        int: isinstance(value, int) and not isinstance(value, bool),
        float: number,
        bool: isinstance(value, bool),
    }[hint]
    if not ok:
        raise error(f"{where}: expected {expected}, got {_show(value)}")
    return value


def plain(value: Any) -> Any:
    """Records, tuples and dicts as JSON values (dicts, lists, numbers, strings, null)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return value


def read_json(path: Path, error: ErrorType) -> object:
    """The parsed JSON document at `path`; text that is not JSON is an `error` naming the file."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise error(f"{path}: not a JSON document ({exc})") from exc


def write_json(path: Path, doc: Any) -> None:
    """Write `doc` with sorted keys, a two-space indent and a final newline (deterministic bytes) atomically
    (`msvdd.atomic`), so that `path` is never half-written."""
    write_text_atomic(path, json.dumps(doc, indent=2, sort_keys=True) + "\n")


def _describe(hint: Any) -> str:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        rest = [a for a in args if a is not type(None)]
        return f"{_describe(rest[0])} or null"
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_plural(args[0])}"
        return f"a list of {len(args)} {_plural(args[0])}"
    if origin is dict:
        return f"an object of {_plural(args[1])}"
    if dataclasses.is_dataclass(hint):
        return "a JSON object"
    return {str: "a string", int: "an integer", float: "a number", bool: "true or false"}.get(hint, str(hint))


def _plural(hint: Any) -> str:
    names = {str: "strings", int: "integers", float: "numbers", bool: "booleans"}
    return names.get(hint, "JSON objects" if dataclasses.is_dataclass(hint) else "values")


def _show(value: object) -> str:
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "an object"
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."
