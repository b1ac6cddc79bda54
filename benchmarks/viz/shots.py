"""Screenshots of the Rerun web viewer as a person first sees it, taken without a display.

python -m benchmarks.viz.shots --data runs/demo/dataset --model runs/demo/models/msvdd-seed0 \\
    --episode test-collision-001 --episode test-fault-000 --out assets/screenshots

For each episode: log it to a temporary .rrd (as `msvdd-bench viz --save` does), serve it with
`rerun --serve-web --bind 127.0.0.1`, open the viewer in headless Chromium (software rendering), wait until
the page stops changing, and write `EPISODE-WIDTHxHEIGHT.png` for each size. One browser at a time: software
WebGL is heavy. Nothing is clicked: the shots show the recording's own blueprint.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from benchmarks.errors import UserError, is_user_error
from benchmarks.viz.chromium import Chromium, wait_until_still
from benchmarks.viz.serve import free_port, serve_web
from msvdd.atomic import write_bytes_atomic

SIZES: tuple[tuple[int, int], ...] = ((1440, 900), (1920, 1080))
"""Screen sizes photographed by default, CSS pixels."""


@dataclass(frozen=True)
class Shot:
    """One screenshot written."""

    path: Path
    """The PNG."""
    settled: bool
    """Whether the page stopped changing before the time limit (False: it may show a half-loaded view)."""
    seconds: float
    """Time from opening the page to the screenshot, s."""


def parse_size(text: str) -> tuple[int, int]:
    """`1440x900` -> (1440, 900)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UserError(f"--size {text!r} is invalid; allowed: WIDTHxHEIGHT, e.g. 1440x900") from None
    if not (320 <= w <= 7680 and 240 <= h <= 4320):
        raise UserError(f"--size {text!r} is out of range; allowed: 320x240 to 7680x4320")
    return w, h


def shrink_png(data: bytes) -> bytes:
    """The screenshot as a 256-colour PNG: the viewer's flat colours survive, the file gets far smaller."""
    import io

    from PIL import Image

    image = Image.open(io.BytesIO(data)).convert("RGB")
    out = io.BytesIO()
    image.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(
        out, format="PNG", optimize=True
    )
    return out.getvalue()


def photograph(
    url: str, size: tuple[int, int], out: Path, browser: str | None, min_wait_s: float, max_wait_s: float
) -> Shot:
    """Open `url` in a fresh headless Chromium of `size` and save a screenshot once the page is still."""
    started = time.monotonic()
    with Chromium(*size, executable=browser, timeout_s=max(60.0, max_wait_s)) as page:
        page.open(url)
        png, settled = wait_until_still(page, min_wait_s, max_wait_s)
    return Shot(write_bytes_atomic(out, shrink_png(png)), settled, time.monotonic() - started)


def describe_scores(data: Path, episode: str, model: Path, hop_s: float) -> str:
    """One line: where the first anomaly is and whether the detector's score crosses its threshold."""
    from benchmarks.episode import read_episode
    from benchmarks.viz.focus import anomaly_spans
    from benchmarks.viz.recording import find_episode, load_model
    from benchmarks.viz.scoring import score_episode

    ep = read_episode(find_episode(data, episode))
    spans = anomaly_spans(ep.imu_time, ep.label)
    first = f"first anomaly {spans[0].label} at {spans[0].start:.2f} s" if spans else "no anomaly"
    method, detector = load_model(model)
    scores = score_episode(ep, detector, method, hop_s, model_dir=model)
    hits = scores.end_s[scores.detected]
    crossing = (
        f"score crosses the threshold {scores.threshold:.4g} first at {hits[0]:.2f} s ({hits.size} windows)"
        if hits.size
        else f"score never crosses the threshold {scores.threshold:.4g} (max {scores.score.max():.4g})"
    )
    return f"{episode}: {first}; {method} {crossing}"


def take_shots(
    data: Path,
    episodes: Sequence[str],
    out_dir: Path,
    model: Path | None = None,
    sizes: Sequence[tuple[int, int]] = SIZES,
    browser: str | None = None,
    hop_s: float = 0.5,
    min_wait_s: float = 8.0,
    max_wait_s: float = 180.0,
) -> list[Shot]:
    """Screenshots of each episode at each size in `out_dir` (see the module docstring)."""
    from benchmarks.viz import log_episode

    shots: list[Shot] = []
    with tempfile.TemporaryDirectory(prefix="msvdd-shots-") as tmp:
        for episode in episodes:
            if model is not None:
                print(describe_scores(data, episode, model, hop_s), flush=True)
            rrd = log_episode(data, episode, model_dir=model, save=Path(tmp) / f"{episode}.rrd", hop_s=hop_s)
            assert rrd is not None
            with serve_web([rrd], web_port=free_port(), grpc_port=free_port()) as url:
                for w, h in sizes:
                    shot = photograph(url, (w, h), out_dir / f"{episode}-{w}x{h}.png", browser, min_wait_s,
                                      max_wait_s)  # fmt: skip
                    note = "" if shot.settled else " (still changing at the time limit)"
                    kb = shot.path.stat().st_size / 1024
                    print(f"wrote {shot.path} ({kb:.0f} KiB, {shot.seconds:.0f} s){note}", flush=True)
                    shots.append(shot)
    return shots


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.viz.shots",
        description="Screenshots of the Rerun web viewer (headless Chromium) for episodes of a dataset.",
    )
    p.add_argument("--data", type=Path, required=True, help="dataset folder")
    p.add_argument("--model", type=Path, default=None, help="saved model folder (adds scores)")
    p.add_argument("--episode", action="append", required=True, help="episode id (repeat for several)")
    p.add_argument("--out", type=Path, required=True, help="folder for the PNG files")
    p.add_argument(
        "--size", action="append", default=None, help="WIDTHxHEIGHT (repeat; default 1440x900 and 1920x1080)"
    )
    p.add_argument("--browser", default=None, help="Chromium executable (default: chromium on PATH)")
    p.add_argument("--max-wait", type=float, default=180.0, help="longest wait for one page to settle, s")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry; bad input prints one line and exits 2."""
    args = _parser().parse_args(argv)
    try:
        sizes = [parse_size(s) for s in args.size] if args.size else list(SIZES)
        shots = take_shots(
            args.data, args.episode, args.out, args.model, sizes, args.browser, max_wait_s=args.max_wait
        )
    except Exception as exc:
        if is_user_error(exc):
            print(f"shots: error: {exc}", file=sys.stderr)
            return 2
        raise
    return 0 if all(s.settled for s in shots) else 1


if __name__ == "__main__":
    sys.exit(main())
