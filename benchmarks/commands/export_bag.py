"""`msvdd-bench export-bag`: a dataset's episodes as ROS 2 bags (MCAP) that Foxglove and `ros2 bag` read.

`benchmarks.ros2.writer` says what a bag holds; `msvdd-bench import BAGS --layout ros2 --labels-topic
/ground_truth/anomalies` reads it back to the same windows.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.command import Command, add_progress_argument


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("dataset", type=Path, metavar="DATASET", help="dataset folder (generated or imported)")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--episode", default=None, help="the episode to export (an episode folder's name)")
    which.add_argument(
        "--all", action="store_true", help="every episode, one bag each, into the folder --out"
    )
    p.add_argument(
        "--out",
        type=Path,
        required=True,
        help="the bag to write (FILE.mcap), or with --all the folder to create (EPISODE.mcap in it)",
    )
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    import secrets
    import shutil

    from tqdm import tqdm

    from benchmarks.dataset import dataset_fingerprint, open_dataset
    from benchmarks.errors import OutputExistsError, UserError
    from benchmarks.executor import publish_dir
    from benchmarks.ros2.writer import BagSummary, write_bag

    out: Path = args.out
    if out.exists() or out.is_symlink():
        raise OutputExistsError(f"--out {out} exists already (remove it or choose another)")
    data = open_dataset(args.dataset)
    metadata = {
        "dataset": str(data.path.resolve()),
        "dataset_fingerprint": dataset_fingerprint(data.manifest),
    }
    if args.episode is not None:
        if args.episode not in data.episode_ids:
            raise UserError(
                f"--episode {args.episode!r} is not an episode of {args.dataset}; allowed: one of "
                f"{', '.join(data.episode_ids[:6])}{', ...' if len(data.episode_ids) > 6 else ''}"
            )
        if out.suffix.lower() != ".mcap":
            raise UserError(f"--out {out}: allowed: a file name ending in .mcap")
        summary = write_bag(data.path / args.episode, out, metadata)
        topics = ", ".join(f"{topic} {n}" for topic, n in sorted(summary.messages.items()))
        print(f"wrote {summary.path} ({summary.duration_s:.2f} s): {topics}")
        return 0
    staging = out.with_name(f".{out.name}.partial-{secrets.token_hex(4)}")
    staging.mkdir(parents=True)  # renamed to --out once every bag is written
    try:
        written: list[BagSummary] = []
        for episode_id in tqdm(data.episode_ids, desc="exporting", unit="bag", disable=args.no_progress):
            written.append(write_bag(data.path / episode_id, staging / f"{episode_id}.mcap", metadata))
        publish_dir(staging, out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    total = sum(sum(s.messages.values()) for s in written)
    print(f"wrote {out}: {len(written)} bags, {total} messages")
    return 0


COMMAND = Command(
    name="export-bag",
    help="write episodes as ROS 2 bags (MCAP): IMU, audio, wheel joints, pose, contacts, ground truth",
    description=(
        "Write one episode (--episode) or every episode (--all) of a dataset as a ROS 2 bag in MCAP, with "
        "its schemas embedded, for Foxglove, `ros2 bag info` and `ros2 bag play` (which needs the "
        "msvdd_bench_msgs package only for the ground-truth topics): sensor_msgs/Imu at 200 Hz, the z "
        "velocity as geometry_msgs/TwistStamped, the binaural audio as audio_common_msgs/AudioDataStamped "
        "chunks with its AudioInfo, the wheels as sensor_msgs/JointState, the pose as tf2_msgs/TFMessage, "
        "contacts and the ground-truth anomaly intervals on their own topics. `msvdd-bench import BAGS "
        "--layout ros2 --labels-topic /ground_truth/anomalies` reads the bags back to the same windows."
    ),
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench export-bag runs/demo/dataset --episode test-fault-000 --out test-fault-000.mcap\n"
        "msvdd-bench export-bag runs/demo/dataset --all --out runs/demo-bags"
    ),
)
