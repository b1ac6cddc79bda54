"""`msvdd-bench`: the one console script. Subcommands live in `benchmarks.commands`, one module each."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence

from benchmarks import commands
from benchmarks.command import Command


def _discover() -> list[Command]:
    found: list[Command] = []
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        command = getattr(module, "COMMAND", None)
        if isinstance(command, Command):
            found.append(command)
    return found


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser, with one sub-parser per discovered command."""
    parser = argparse.ArgumentParser(
        prog="msvdd-bench",
        description="Simulation-driven audio-IMU anomaly benchmark for wheeled robots (M-SVDD).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in _discover():
        p = sub.add_parser(
            command.name,
            help=command.help,
            description=command.description or command.help,
            formatter_class=argparse.ArgumentDefaultsHelpFormatter,
        )
        command.add_arguments(p)
        p.set_defaults(_run=command.run, _name=command.name)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `msvdd-bench`; bad input exits 2 with a message naming what is wrong."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._run(args))
    except (ValueError, FileNotFoundError, FileExistsError, KeyError) as exc:
        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"msvdd-bench {args._name}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"msvdd-bench {args._name}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
