"""Where a result comes from: the code version a run records in its results file."""

from __future__ import annotations

import subprocess
from importlib import metadata
from pathlib import Path

_ROOT = Path(__file__).resolve().parent.parent
"""The checkout (or install) folder that holds the `benchmarks` package."""


def package_version() -> str:
    """The installed `msvdd-bench` version, or "unknown" outside an install."""
    try:
        return metadata.version("msvdd-bench")
    except metadata.PackageNotFoundError:
        return "unknown"


def _git(*args: str) -> str | None:
    """The stripped output of a git command in `_ROOT`, or None when git or the checkout is missing."""
    try:
        done = subprocess.run(
            ["git", "-C", str(_ROOT), *args], capture_output=True, text=True, timeout=10, check=False
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def code_version() -> str:
    """`msvdd-bench 0.1.0`, with the git commit when run from a checkout (`+ local changes` when the
    tracked files differ from it)."""
    text = f"msvdd-bench {package_version()}"
    commit = _git("rev-parse", "--short=12", "HEAD")
    if not commit:
        return text
    dirty = _git("status", "--porcelain", "--untracked-files=no")
    return f"{text} (git {commit}{' + local changes' if dirty else ''})"
