"""`msvdd-bench demo`: the main job on the small default preset, then Rerun recordings of two episodes."""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from benchmarks.command import Command
from benchmarks.commands.run import add_run_arguments, run_from_args
from benchmarks.errors import OutputExistsError


def _add_arguments(p: argparse.ArgumentParser) -> None:
    add_run_arguments(p)
    p.add_argument(
        "--replace",
        action="store_true",
        help="replace an existing run folder at --out (and, without --resume, what an interrupted demo left)",
    )


def _pick_episodes(data: Path) -> list[str]:
    """One collision episode and one fault episode of the test split."""
    from benchmarks.dataset import open_dataset

    dataset = open_dataset(data, verify=False)
    chosen: list[str] = []
    for kind in ("collision", "mechanical"):
        episode = next((r.episode for r in dataset.windows if r.kind == kind), None)
        if episode is not None:
            chosen.append(episode)
    return chosen


def _run(args: argparse.Namespace) -> int:
    out: Path = args.out
    old = out.with_name(f".{out.name}.old")
    if out.exists():
        if not args.replace:
            raise OutputExistsError(
                f"run folder exists already: {out} (pass --replace to run the demo again)"
            )
        shutil.rmtree(old, ignore_errors=True)
        out.rename(old)
    if args.replace and not args.resume:
        from benchmarks.resume import partial_folder

        shutil.rmtree(partial_folder(out), ignore_errors=True)
    try:
        run_from_args(args)
    except BaseException:
        if old.exists() and not out.exists():
            old.rename(out)
        raise
    shutil.rmtree(old, ignore_errors=True)
    print((out / "results.md").read_text())
    data = Path(json.loads((out / "results.json").read_text())["dataset"])  # --data, --cache or generated
    model = out / "models" / "msvdd-seed0"
    from benchmarks.viz import log_episode

    recordings = []
    for episode in _pick_episodes(data):
        path = out / "recordings" / f"{episode}.rrd"
        log_episode(data, episode, model_dir=model if model.exists() else None, save=path)
        recordings.append(path)
    print(f"wrote {out}: results.md, results.json, scores.csv, figures/")
    for path in recordings:
        print(f"view a recording: rerun {path}  (no display: rerun --serve-web --bind 127.0.0.1 {path})")
    return 0


COMMAND = Command(
    name="demo",
    help="run the benchmark on the quick preset and write Rerun recordings of a collision and a fault",
    add_arguments=_add_arguments,
    run=_run,
    example="msvdd-bench demo --out runs/demo --replace",
)
