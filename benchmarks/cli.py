"""`msvdd-bench`: the one console script. Subcommands live in `benchmarks.commands`, one module each."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import pkgutil
import signal
import sys
import textwrap
import threading
from collections.abc import Callable, Iterator, Sequence
from types import FrameType
from typing import Any

from benchmarks import commands
from benchmarks.command import Command
from benchmarks.errors import is_user_error


def _discover() -> list[Command]:
    found: list[Command] = []
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        command = getattr(module, "COMMAND", None)
        if isinstance(command, Command):
            found.append(command)
    return found


class HelpFormatter(argparse.HelpFormatter):
    """Wraps prose, keeps indented lines (examples) as written, and shows a default only where it says
    something: not for required options, positionals, flags, or a default of None."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        return "\n".join(
            indent + line
            if line.startswith(" ") or not line
            else textwrap.fill(line, width, initial_indent=indent, subsequent_indent=indent)
            for line in text.splitlines()
        )

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if (
            "%(default)" in text
            or "(default" in text
            or action.required
            or not action.option_strings
            or default is None
            or default is argparse.SUPPRESS
            or isinstance(default, bool)
        ):
            return action.help
        shown = " ".join(map(str, default)) if isinstance(default, list | tuple) else str(default)
        return f"{text} (default: {shown.replace('%', '%%')})"


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser, with one sub-parser per discovered command.

    Building it imports no heavy package (torch, mujoco, the method registry): commands import those when
    they run, so that `--help` is fast.
    """
    parser = argparse.ArgumentParser(
        prog="msvdd-bench",
        description="Simulation-driven audio-IMU anomaly benchmark for wheeled robots (M-SVDD).",
        epilog="Every command has --help with an example, e.g. msvdd-bench run --help.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in _discover():
        example = "\n".join(f"  {line}" for line in command.example.strip().splitlines())
        p = sub.add_parser(
            command.name,
            help=command.help,
            description=command.description or command.help,
            epilog=f"example:\n{example}" if example else None,
            formatter_class=HelpFormatter,
        )
        command.add_arguments(p)
        p.set_defaults(_run=command.run, _name=command.name)
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM (a `kill`, a CI timeout, a machine taken back), raised where the command was so that it stops
    as after Ctrl-C: temporary folders removed, a stopped run's finished models kept."""


def _terminate(signum: int, frame: FrameType | None) -> None:
    raise Terminated


REDELIVERY_DELAY_S = 0.01
"""How long after a stop was swallowed it is signalled again, s: the finalizer that swallowed it has
returned by then."""


def _redeliver_swallowed_stops(previous: Callable[[Any], object]) -> Callable[[Any], object]:
    """A `sys.unraisablehook` that signals a swallowed stop again, and hands everything else to `previous`.

    A signal's exception raised while a finalizer runs (an object's `__del__`, such as llvmlite's while
    numba compiles, or a weakref's callback) cannot leave it: Python prints "Exception ignored in ..." and the
    command would carry on as if nothing had been asked. The same signal is sent again a moment later, from
    another thread, so that its handler raises where the exception propagates."""

    def hook(unraisable: Any) -> None:
        kind = unraisable.exc_type
        if kind is not None and issubclass(kind, KeyboardInterrupt):
            signum = signal.SIGTERM if issubclass(kind, Terminated) else signal.SIGINT
            timer = threading.Timer(REDELIVERY_DELAY_S, os.kill, (os.getpid(), signum))
            timer.daemon = True
            timer.start()
            return
        previous(unraisable)

    return hook


@contextlib.contextmanager
def stop_on_sigterm() -> Iterator[None]:
    """While inside, SIGTERM raises `Terminated` in the main thread, and a SIGTERM or Ctrl-C whose exception
    a finalizer swallowed is signalled again (`_redeliver_swallowed_stops`); elsewhere nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _terminate)
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _redeliver_swallowed_stops(previous_hook)
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        signal.signal(signal.SIGTERM, previous)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `msvdd-bench`.

    Bad input (`benchmarks.errors.is_user_error`) exits 2 with its one-line message; any other exception
    is a bug and keeps its traceback. Ctrl-C exits 130 and SIGTERM 143, each after the command cleaned up
    (a shell starts background jobs with Ctrl-C ignored; `kill PID` stops them the same way).
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        with stop_on_sigterm():
            return int(args._run(args))
    except Terminated:
        print(f"msvdd-bench {args._name}: terminated (SIGTERM)", file=sys.stderr)
        return 128 + signal.SIGTERM
    except KeyboardInterrupt:
        print(f"msvdd-bench {args._name}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        if not is_user_error(exc):
            raise
        print(f"msvdd-bench {args._name}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
