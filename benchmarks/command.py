"""The shape of a `msvdd-bench` subcommand; `benchmarks.cli` discovers them in `benchmarks.commands`."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass


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
