"""`msvdd-bench import`: real recordings into a dataset folder (folder, MIMII/DCASE, windows, ros2)."""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.command import Command, add_progress_argument, add_scale_argument

_LAYOUTS = ("folder", "mimii", "windows", "ros2")  # importers.LAYOUTS, kept here so --help stays light
_TOPIC_FLAGS = ("imu", "velocity", "audio", "audio_info", "joint_states", "labels")
"""Streams with a `--STREAM-topic` flag (benchmarks.ros2.topics.READ_TYPES; a test checks that they agree)."""


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "source", type=Path, help="folder holding the recordings (ros2: a bag file or a folder of bags)"
    )
    p.add_argument("--layout", choices=_LAYOUTS, required=True, help="how the source folder is laid out")
    p.add_argument("--out", type=Path, required=True, help="dataset folder to create")
    p.add_argument(
        "--replace", action="store_true", help="replace an existing dataset folder at --out (once complete)"
    )
    shared = p.add_argument_group("every layout")
    shared.add_argument(
        "--test-fraction",
        type=float,
        default=0.25,
        help="share of the nominal recordings of each group held out for test (the last in name order)",
    )
    shared.add_argument(
        "--val-fraction",
        type=float,
        default=0.1,
        help="share of the other nominal recordings held out as validation (the last before the test ones)",
    )
    shared.add_argument("--train-hop", type=float, default=1.0, help="hop between training windows, s")
    shared.add_argument("--test-hop", type=float, default=2.0, help="hop between test windows, s")
    shared.add_argument(
        "--anomaly-kind",
        choices=("collision", "mechanical"),
        default="mechanical",
        help="kind of an anomaly whose source does not say",
    )
    shared.add_argument(
        "--channels",
        default=None,
        help="channels to keep of multichannel audio: one (duplicated) or two, e.g. 0,1",
    )
    shared.add_argument(
        "--audio-rate",
        type=float,
        default=None,
        help="folder, mimii, ros2: the rate all audio must have, Hz (default: any, resampled); "
        "windows: the rate of the audio windows (default 4410)",
    )
    add_scale_argument(shared, "short", "training budget `train` uses on this dataset by default")
    folder = p.add_argument_group("folder layout")
    folder.add_argument(
        "--imu-columns",
        default=None,
        help="CSV column of each IMU field, e.g. t=time,ax=acc_x,ay=acc_y,az=acc_z,gx=gyr_x,gy=gyr_y,"
        "gz=gyr_z[,vz=vel_z]; a field not named is read from the column of its own name (t, ax, ..., gz; "
        "without vz, the z velocity is estimated from az)",
    )
    folder.add_argument(
        "--time-unit", choices=("s", "ms", "us", "ns"), default="s", help="unit of the time column"
    )
    shared.add_argument(
        "--imu-rate",
        type=float,
        default=None,
        help="folder: the IMU rate the time stamps must show, Hz (default: any, resampled to 200); "
        "windows: the rate of the IMU windows (default 200)",
    )
    folder.add_argument(
        "--labels",
        type=Path,
        default=None,
        help="folder, ros2: label CSV recording,start_s,end_s[,kind][,sub_kind] (ros2: seconds from the "
        "bag's first message)",
    )
    folder.add_argument(
        "--split-file", type=Path, default=None, help="folder, ros2: CSV recording,split fixing some splits"
    )
    folder.add_argument("--no-imu", action="store_true", help="the recordings have no IMU CSVs: audio only")
    folder.add_argument(
        "--max-length-mismatch",
        type=float,
        default=0.1,
        help="largest difference between a recording's audio and IMU lengths, s",
    )
    ros2 = p.add_argument_group("ros2 layout (topics default to what `export-bag` writes)")
    ros2.add_argument(
        "--topics",
        type=Path,
        default=None,
        help='TOML mapping: imu, velocity, audio, audio_info, joint_states, labels = "/topic", '
        'wheel_joints = ["name", ...]; flags win over it',
    )
    for stream in _TOPIC_FLAGS:
        ros2.add_argument(
            f"--{stream.replace('_', '-')}-topic",
            dest=f"{stream}_topic",
            default=None,
            help=f"topic of the {stream.replace('_', ' ')} stream"
            + (" (read the labels from it; otherwise --labels or none)" if stream == "labels" else ""),
        )
    ros2.add_argument(
        "--wheel-joints",
        default=None,
        help="JointState names of the wheels, comma-separated (default: every joint named *wheel*)",
    )
    ros2.add_argument(
        "--jitter",
        type=float,
        default=None,
        help="time stamp offsets up to this are jitter, s (default: the streaming scorer's GapPolicy)",
    )
    ros2.add_argument(
        "--max-fill",
        type=float,
        default=None,
        help="longest gap filled in; longer ones are left out of every window, s (default: the streaming "
        "scorer's GapPolicy)",
    )
    add_progress_argument(p)


def _run(args: argparse.Namespace) -> int:
    from benchmarks.dataset import open_dataset
    from benchmarks.importers import (
        FolderConfig,
        ImportConfig,
        Ros2Config,
        SplitConfig,
        WindowsConfig,
        gap_policy,
        import_dataset,
        parse_channels,
        parse_imu_columns,
        read_topic_mapping,
        ros2_config,
    )

    config = ImportConfig(
        train_hop_s=args.train_hop,
        test_hop_s=args.test_hop,
        scale=args.scale,
        anomaly_kind=args.anomaly_kind,
        channels=parse_channels(args.channels) if args.channels else None,
        audio_rate=args.audio_rate if args.layout != "windows" else None,
        split=SplitConfig(test_fraction=args.test_fraction, val_fraction=args.val_fraction),
    )
    layout_config: FolderConfig | WindowsConfig | Ros2Config | None = None
    if args.layout == "folder":
        layout_config = FolderConfig(
            imu_columns=parse_imu_columns(args.imu_columns or ""),
            time_unit=args.time_unit,
            imu_rate=args.imu_rate,
            labels=str(args.labels) if args.labels else None,
            split_file=str(args.split_file) if args.split_file else None,
            no_imu=args.no_imu,
            max_length_mismatch_s=args.max_length_mismatch,
        )
    elif args.layout == "ros2":
        mapping: dict[str, str | tuple[str, ...]] = read_topic_mapping(args.topics) if args.topics else {}
        if args.wheel_joints:
            mapping["wheel_joints"] = tuple(j.strip() for j in args.wheel_joints.split(",") if j.strip())
        layout_config = ros2_config(
            mapping,
            {stream: getattr(args, f"{stream}_topic") for stream in _TOPIC_FLAGS},
            labels=str(args.labels) if args.labels else None,
            split_file=str(args.split_file) if args.split_file else None,
            policy=gap_policy(args.jitter, args.max_fill),
        )
    elif args.layout == "windows":
        layout_config = WindowsConfig(
            audio_rate=args.audio_rate if args.audio_rate is not None else 4410.0,
            imu_rate=args.imu_rate if args.imu_rate is not None else 200.0,
        )
    path = import_dataset(
        args.layout,
        args.source,
        args.out,
        config,
        layout_config,
        replace=args.replace,
        progress=not args.no_progress,
    )
    dataset = open_dataset(path, verify=False)
    counts: dict[tuple[str, str], int] = {}
    for row in dataset.windows:
        counts[(row.split, row.kind)] = counts.get((row.split, row.kind), 0) + 1
    modalities = ", ".join(dataset.modalities)
    print(
        f"wrote {path}: {len(dataset.episode_ids)} episodes, {len(dataset.windows)} windows; "
        f"modalities: {modalities}"
    )
    for (split, kind), n in sorted(counts.items()):
        print(f"  {split:<5} {kind:<10} {n:>6}")
    return 0


COMMAND = Command(
    name="import",
    help="turn real recordings (audio+IMU folder, MIMII/DCASE, or pre-cut windows) into a dataset folder",
    description=(
        "Read recordings in one of four layouts and write a dataset folder that train, evaluate, audit and "
        "viz read like a generated one: audio resampled to 44.1 kHz stereo, IMU to 200 Hz, 2 s windows "
        "labelled from the anomaly spans. A recording with an anomaly is test data; nominal recordings are "
        "split per group in name order: the last --test-fraction for test, then --val-fraction for "
        "validation. The mimii layout (and folder --no-imu) has no IMU: methods that read the IMU are "
        "refused on it. The ros2 layout reads ROS 2 bags in MCAP (IMU, audio_common audio, wheel joint "
        "states); their header stamps align the streams, and gaps, jitter, duplicate and late messages "
        "follow the streaming scorer's policy, counted in the manifest."
    ),
    add_arguments=_add_arguments,
    run=_run,
    example=(
        "msvdd-bench import recordings/ --layout folder --labels recordings/labels.csv "
        "--imu-columns t=time,ax=acc_x,ay=acc_y,az=acc_z,gx=gyr_x,gy=gyr_y,gz=gyr_z --out runs/real\n"
        "msvdd-bench import MIMII/fan --layout mimii --channels 0 --out runs/mimii-fan\n"
        "msvdd-bench import paper-windows/ --layout windows --out runs/paper-windows\n"
        "msvdd-bench import bags/ --layout ros2 --labels-topic /ground_truth/anomalies --out runs/bags"
    ),
)
