"""Bad input from the user, as opposed to a bug: `msvdd-bench` prints such an error's message on one line
and exits 2; every other exception keeps its traceback.

Code in `benchmarks` reports bad input (a flag's value, a path, a dataset or model folder) by raising
`UserError` or a subclass. The packages below it (`msvdd`, `sim`, `synth_audio`) do not import
`benchmarks`; their own input errors are listed in `FOREIGN_USER_ERRORS` and count as user errors too.
"""

from __future__ import annotations

import numbers
import sys


class UserError(ValueError):
    """Bad input; the message names what is wrong and what is allowed."""


class InputNotFoundError(UserError, FileNotFoundError):
    """A file or folder the user named does not exist."""


class OutputExistsError(UserError, FileExistsError):
    """An output folder the user named exists already."""


FOREIGN_USER_ERRORS: tuple[tuple[str, str], ...] = (
    ("msvdd.contract", "WindowError"),
    ("msvdd.contract", "ModelFormatError"),
    ("sim.scenario", "ScenarioError"),
    ("sim.trace", "TraceError"),
    ("synth_audio.config", "AudioError"),
)
"""(module, class) of the input errors of modules that do not import this one. They are looked up in
`sys.modules` only: an error of a module never imported cannot have been raised, and `msvdd-bench --help`
stays free of torch and mujoco."""


def is_user_error(exc: BaseException) -> bool:
    """Whether `exc` reports bad input (`UserError` or one of `FOREIGN_USER_ERRORS`), not a bug."""
    if isinstance(exc, UserError):
        return True
    for module_name, class_name in FOREIGN_USER_ERRORS:
        module = sys.modules.get(module_name)
        if module is not None and isinstance(exc, getattr(module, class_name)):
            return True
    return False


def check_seed(seed: object, flag: str = "--seed") -> int:
    """`seed` if it is an integer >= 0; otherwise a `UserError` naming the flag, the value and the range."""
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise UserError(f"{flag} = {seed!r} is invalid; allowed: an integer >= 0")
    return int(seed)
