"""`msvdd-bench viz`: log one episode (and a detector's scores on it) to a Rerun recording."""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.command import Command


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", type=Path, required=True, help="dataset folder (from `generate`)")
    p.add_argument("--episode", required=True, help="episode id, e.g. test-collision-000")
    p.add_argument("--model", type=Path, default=None, help="saved model folder (from `train`); adds scores")
    out = p.add_mutually_exclusive_group(required=True)
    out.add_argument("--save", type=Path, default=None, help="write the recording to this .rrd file")
    out.add_argument("--spawn", action="store_true", help="open a Rerun viewer and stream to it")
    p.add_argument("--hop", type=float, default=0.5, help="hop between scored 2 s windows, s")
    p.add_argument("--no-audio", action="store_true", help="do not embed the audio file for playback")


def _run(args: argparse.Namespace) -> int:
    from benchmarks.viz import log_episode

    path = log_episode(
        args.data,
        args.episode,
        model_dir=args.model,
        save=args.save,
        spawn=args.spawn,
        hop_s=args.hop,
        audio_playback=not args.no_audio,
    )
    if path is not None:
        print(f"wrote {path}; view it with: rerun {path}")
    return 0


COMMAND = Command(
    name="viz",
    help="log one episode (3D scene, sensors, labels, detector scores) to a Rerun recording",
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench viz --data runs/demo/dataset --episode test-collision-000 "
        "--model runs/demo/models/msvdd-seed0 --save /tmp/collision.rrd"
    ),
)
