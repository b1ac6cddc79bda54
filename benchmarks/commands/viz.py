"""`msvdd-bench viz`: log one episode (and a detector's scores on it) to a Rerun recording, and show it: in
a native viewer (`--spawn`), or in a browser from a headless machine (`--serve-web`)."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from benchmarks.command import Command
from benchmarks.errors import UserError


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", type=Path, required=True, help="dataset folder (from `generate`)")
    p.add_argument("--episode", required=True, help="episode id, e.g. test-collision-000")
    p.add_argument("--model", type=Path, default=None, help="saved model folder (from `train`); adds scores")
    p.add_argument("--save", type=Path, default=None, help="write the recording to this .rrd file")
    show = p.add_mutually_exclusive_group()
    show.add_argument(
        "--spawn", action="store_true", help="open a native Rerun viewer and stream to it (needs a display)"
    )
    show.add_argument(
        "--serve-web",
        action="store_true",
        help="serve the recording to a browser on 127.0.0.1 until Ctrl-C (for machines without a display)",
    )
    p.add_argument("--web-port", type=int, default=None, help="--serve-web: HTTP port of the viewer (9090)")
    p.add_argument("--grpc-port", type=int, default=None, help="--serve-web: port of its data server (9876)")
    p.add_argument("--hop", type=float, default=0.5, help="hop between scored 2 s windows, s")
    p.add_argument("--no-audio", action="store_true", help="do not embed the audio file for playback")


def headless_hint(path: Path) -> str:
    """How to view a written recording, with and without a display."""
    return (
        f"view it with: rerun {path}   (no display, e.g. over SSH: "
        f"rerun --serve-web --bind 127.0.0.1 {path}, then open the printed http://127.0.0.1 URL)"
    )


def _ports(args: argparse.Namespace) -> tuple[int, int]:
    from benchmarks.viz.serve import GRPC_PORT, WEB_PORT

    web = WEB_PORT if args.web_port is None else args.web_port
    grpc = GRPC_PORT if args.grpc_port is None else args.grpc_port
    for flag, port in (("--web-port", web), ("--grpc-port", grpc)):
        if not 1 <= port <= 65535:
            raise UserError(f"{flag} = {port} is invalid; allowed: 1..65535")
    if web == grpc:
        raise UserError(f"--web-port and --grpc-port are both {web}; they must differ")
    return web, grpc


def _serve(args: argparse.Namespace) -> int:
    """Write the recording (to --save or a temporary file) and serve it until Ctrl-C."""
    from benchmarks.viz import log_episode
    from benchmarks.viz.serve import serve_web

    web, grpc = _ports(args)
    with tempfile.TemporaryDirectory(prefix="msvdd-viz-") as tmp:
        target = args.save if args.save is not None else Path(tmp) / f"{args.episode}.rrd"
        path = log_episode(
            args.data,
            args.episode,
            model_dir=args.model,
            save=target,
            hop_s=args.hop,
            audio_playback=not args.no_audio,
        )
        assert path is not None
        if args.save is not None:
            print(f"wrote {path}")
        with serve_web([path], web_port=web, grpc_port=grpc) as url:
            print(f"serving {args.episode} on 127.0.0.1 only; open {url}", flush=True)
            print(
                f"from another machine: ssh -L {web}:127.0.0.1:{web} -L {grpc}:127.0.0.1:{grpc} THIS_HOST, "
                "then open the same URL there; Ctrl-C stops",
                flush=True,
            )
            try:
                _wait_forever()
            except KeyboardInterrupt:
                print("stopped")
    return 0


def _wait_forever() -> None:
    import time

    while True:
        time.sleep(3600)


def _run(args: argparse.Namespace) -> int:
    if args.save is None and not args.spawn and not args.serve_web:
        raise UserError("viz needs --save FILE.rrd, --spawn (a display) or --serve-web (no display)")
    if args.serve_web:
        return _serve(args)
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
        print(f"wrote {path}; {headless_hint(path)}")
    return 0


COMMAND = Command(
    name="viz",
    help="log one episode (3D scene, sensors, labels, detector scores) to a Rerun recording",
    add_arguments=_add_arguments,
    run=_run,
    description=(
        "Log one episode (3D scene, sensors, labels, detector scores) to a Rerun recording: a .rrd file "
        "(--save), a native viewer (--spawn, needs a display), or a browser viewer served on 127.0.0.1 "
        "(--serve-web, for headless machines; forward its two ports over SSH)."
    ),
    example=(
        "msvdd-bench viz --data runs/demo/dataset --episode test-collision-001 "
        "--model runs/demo/models/msvdd-seed0 --save /tmp/collision.rrd\n"
        "msvdd-bench viz --data runs/demo/dataset --episode test-fault-000 "
        "--model runs/demo/models/msvdd-seed0 --serve-web"
    ),
)
