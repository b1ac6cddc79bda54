"""`msvdd-bench synth`: render a simulated trace to a binaural audio file a person can listen to."""

from __future__ import annotations

import argparse
import math
import os
import shutil
import tempfile
from pathlib import Path

from benchmarks.command import Command
from benchmarks.errors import UserError, check_seed


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--trace", type=Path, required=True, help="trace .npz written by the simulator")
    p.add_argument("--out", type=Path, required=True, help="output audio file (.flac or .wav)")
    p.add_argument("--snr", type=float, default=6.0, help="robot-to-environment ratio, dB")
    p.add_argument("--stems", type=Path, default=None, help="also write one float WAV per source into DIR")
    p.add_argument(
        "--render-seed",
        type=int,
        default=0,
        help="render seed: seeds every random draw of the audio render (each source's sound, the ambience, "
        "the room, microphone noise), not the simulation (the trace's scenario seed fixed that); the same "
        "trace, options and render seed give the same samples bit for bit",
    )
    p.add_argument("--sample-rate", type=int, default=44100, help="output sample rate, Hz")
    p.add_argument("--no-ambience", action="store_true", help="robot sound only (no environment)")


def _run(args: argparse.Namespace) -> int:
    # Imported here so that `msvdd-bench --help` stays fast.
    from sim.trace import Trace
    from synth_audio import Audio, AudioConfig, render, write
    from synth_audio.io import FORMATS

    out: Path = args.out
    if out.suffix.lower() not in FORMATS:
        raise UserError(f"--out {out}: unsupported suffix {out.suffix!r}; allowed: {', '.join(FORMATS)}")
    if not math.isfinite(args.snr):
        raise UserError(f"--snr = {args.snr} is invalid; allowed: a finite number of dB")
    seed = check_seed(args.render_seed, "--render-seed")
    trace = Trace.load(args.trace)
    config = AudioConfig(
        sample_rate=args.sample_rate,
        snr_db=args.snr,
        ambience=not args.no_ambience,
        stems=args.stems is not None,
    )
    audio = render(trace, config, seed)
    if args.stems is not None:
        stems_dir: Path = args.stems
        stems_dir.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=".stems-", dir=stems_dir.parent))
        try:
            for name, stem in audio.stems.items():
                write(staging / f"{name}.wav", Audio(samples=stem, sample_rate=audio.sample_rate))
            if stems_dir.exists():
                for item in staging.iterdir():
                    os.replace(item, stems_dir / item.name)
                staging.rmdir()
            else:
                os.replace(staging, stems_dir)
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            raise
    write(out, audio)
    peak = float(abs(audio.samples).max())
    print(f"wrote {out}: {audio.duration:.2f} s, {audio.sample_rate} Hz, 2 channels, peak {peak:.3f}")
    return 0


COMMAND = Command(
    name="synth",
    help="render a simulated trace (.npz) to binaural audio (.flac/.wav), optionally with per-source stems",
    add_arguments=_add_arguments,
    run=_run,
    example="msvdd-bench synth --trace /tmp/collision.npz --out /tmp/collision.flac --stems /tmp/stems",
)
