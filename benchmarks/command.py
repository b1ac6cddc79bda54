"""The shape of a `msvdd-bench` subcommand; `benchmarks.cli` discovers them in `benchmarks.commands`.

A command module imports only the standard library at the top (heavy packages such as torch, mujoco or
the method registry inside its `run`), so that `msvdd-bench --help` stays fast.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass

DEVICES: tuple[str, ...] = ("cpu", "cuda", "auto")
"""`--device` choices; the same as `benchmarks.methods.registry.DEVICES` (kept here so that building the
parser does not import the registry and torch; a test checks that they agree)."""

EXECUTORS: tuple[str, ...] = ("local", "ray")
"""`--executor` choices; the same as `benchmarks.executor.EXECUTORS` (a test checks that they agree)."""

SCALES: tuple[str, ...] = ("smoke", "short", "full")
"""`--scale` values, the training budgets; the same as `benchmarks.methods.base.SCALES` (a test checks that
they agree; the methods check the value, naming the allowed ones)."""


@dataclass(frozen=True)
class Command:
    """A subcommand: its name, one-line help, argument set-up and entry point."""

    name: str
    """Subcommand name as typed on the command line."""
    help: str
    """One line shown by `msvdd-bench --help`."""
    add_arguments: Callable[[argparse.ArgumentParser], None]
    """Adds the subcommand's options to its parser."""
    run: Callable[[argparse.Namespace], int]
    """Runs the subcommand; returns the process exit code."""
    description: str = ""
    """Longer text shown by `msvdd-bench NAME --help` (defaults to `help`)."""
    example: str = ""
    """One or two command lines, one a line, shown under "example:" by `msvdd-bench NAME --help`."""


def add_dataset_arguments(p: argparse.ArgumentParser, preset_default: str | None) -> None:
    """`--preset` and `--seed`, the dataset preset and the dataset seed: the one meaning of both flags in
    every command (`preset_default` None: a given dataset decides, else quick and seed 0)."""
    given = " (default: quick; with --data, the dataset's)" if preset_default is None else ""
    p.add_argument(
        "--preset", default=preset_default, help=f"dataset preset, see `msvdd-bench presets`{given}"
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None if preset_default is None else 0,
        help="dataset seed: the same preset and seed give the same checksums"
        + (" (default: 0; with --data, the dataset's)" if preset_default is None else ""),
    )


def add_scale_argument(
    p: argparse.ArgumentParser | argparse._ArgumentGroup,
    default: str | None,
    what: str,
    default_text: str = "",
) -> None:
    """`--scale`: a training budget, one of `SCALES` (`what`: whose budget; `default_text`: how a None default
    reads)."""
    suffix = f" ({default_text})" if default_text else ""
    p.add_argument("--scale", default=default, help=f"{what}: {', '.join(SCALES)}{suffix}")


def add_progress_argument(p: argparse.ArgumentParser) -> None:
    """`--no-progress`: no progress bars (they go to stderr)."""
    p.add_argument("--no-progress", action="store_true", help="no progress bars (they are on stderr)")


def add_device_argument(p: argparse.ArgumentParser) -> None:
    """`--device`: where the torch methods train and score."""
    p.add_argument(
        "--device",
        choices=DEVICES,
        default="cpu",
        help="where the torch methods train and score (auto: CUDA when available); others ignore it",
    )


def add_executor_arguments(
    p: argparse.ArgumentParser,
    what: str = "the episodes are built",
    same: str = "the same preset and seed give the same dataset checksums with either",
    shared: str = "the output folder's file system",
) -> None:
    """`--executor`, `--address` and `--workers`: where the independent tasks run (`what`: which they are;
    `same`: what does not depend on the executor; `shared`: what a cluster's nodes must all see)."""
    p.add_argument(
        "--executor",
        choices=EXECUTORS,
        default="local",
        help=f"where {what}: local worker processes, or Ray (pip install 'msvdd-bench[ray]'); {same}",
    )
    p.add_argument(
        "--address",
        default=None,
        help="with --executor ray: HOST:PORT of a running Ray cluster's head, or auto (default: RAY_ADDRESS, "
        f"else a Ray started on this machine); its nodes must share {shared}",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes (default: one per CPU); with --executor ray and no --address, the CPUs of the "
        "Ray started here",
    )
