"""`msvdd-bench presets`: the dataset presets and what they contain."""

from __future__ import annotations

import argparse

from benchmarks.command import Command


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", nargs="?", help="show one preset in full")


def _run(args: argparse.Namespace) -> int:
    from benchmarks.dataset import plan_episodes
    from benchmarks.presets import get_preset, preset_names

    names = [args.name] if args.name else preset_names()
    for name in names:
        preset = get_preset(name)
        specs = plan_episodes(preset, 0)
        seconds = sum(s.options.duration for s in specs)
        print(f"{name:<6} {preset.description}")
        print(f"       {len(specs)} episodes, {seconds / 60:.1f} min of driving, methods at scale "
              f"{preset.method_scale!r}, seeds {list(preset.seeds)}")  # fmt: skip
        low, high = preset.snr_db
        n_test = sum(1 for s in specs if s.category == "nominal" and s.split == "test")
        print(f"       SNR drawn uniformly in [{low:g}, {high:g}] dB per episode; {n_test} test nominal "
              f"sequences of {preset.nominal_test_duration_s:g} s")  # fmt: skip
        if args.name:
            for key, value in preset.__dict__.items():
                print(f"       {key} = {value!r}")
    return 0


COMMAND = Command(
    name="presets",
    help="list the dataset presets (tiny, quick, paper, hard, ci) and what they contain",
    add_arguments=_add_arguments,
    run=_run,
    example="msvdd-bench presets\nmsvdd-bench presets quick",
)
