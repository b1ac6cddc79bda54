"""`msvdd-bench import`: real recordings as a dataset folder that train, evaluate, audit and viz read.

One module per source layout turns its files into planned recordings (`folder`: audio files with IMU CSVs
and a label CSV; `mimii`: MIMII and DCASE machine sounds, audio only; `windows`: pre-cut window arrays;
`ros2`: ROS 2 bags in MCAP, their streams laid out by the streaming scorer's gap policy in `timed`);
`writer` applies the split rule and writes the dataset the way `generate` does (episode folders,
windows.csv, manifest.json, atomically), with `"source": "import"` and the `modalities` present recorded in
the manifest and in each episode's meta.json. Imported episodes have no simulator trace (no trace.npz, an
empty scenario); the audit skips the probes that need one and the viewer shows what exists.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

from benchmarks.importers import folder, mimii, ros2, windows
from benchmarks.importers.config import (
    LAYOUTS,
    FolderConfig,
    ImportConfig,
    ImuColumns,
    Ros2Config,
    SourceError,
    SplitConfig,
    WindowsConfig,
    gap_policy,
    parse_channels,
    parse_imu_columns,
    read_topic_mapping,
    ros2_config,
)
from benchmarks.importers.writer import write_dataset

__all__ = [
    "LAYOUTS",
    "FolderConfig",
    "ImportConfig",
    "ImuColumns",
    "Ros2Config",
    "SourceError",
    "SplitConfig",
    "WindowsConfig",
    "gap_policy",
    "import_dataset",
    "parse_channels",
    "parse_imu_columns",
    "read_topic_mapping",
    "ros2_config",
]


def import_dataset(
    layout: str,
    source: Path,
    out: Path,
    config: ImportConfig | None = None,
    layout_config: FolderConfig | WindowsConfig | Ros2Config | None = None,
    *,
    replace: bool = False,
    progress: bool = True,
) -> Path:
    """Import the recordings at `source` (in `layout`) as a dataset folder `out`; returns `out`.

    Args:
        layout: one of `LAYOUTS`.
        source: the source folder (ros2: a bag file or a folder of bags).
        out: the dataset folder to create (must not exist unless `replace`, which swaps out an existing
            dataset folder only once the new one is complete).
        config: options shared by every layout (default `ImportConfig()`).
        layout_config: `FolderConfig` for `folder`, `WindowsConfig` for `windows`, `Ros2Config` for `ros2`
            (defaults if None).
        replace: replace an existing dataset folder.
        progress: a progress bar over the recordings.

    Raises:
        SourceError: the source is missing, unreadable or inconsistent (the message names the file).
        OutputExistsError: `out` exists and `replace` is off, or it is not a dataset folder.
    """
    config = config or ImportConfig()
    source = Path(source)
    if layout == "folder":
        fcfg = layout_config if isinstance(layout_config, FolderConfig) else FolderConfig()
        plans, facts = folder.plan(source, config, fcfg)
        options = {**asdict(config), **asdict(fcfg)}
    elif layout == "mimii":
        plans, facts = mimii.plan(source, config)
        options = asdict(config)
    elif layout == "windows":
        wcfg = layout_config if isinstance(layout_config, WindowsConfig) else WindowsConfig()
        plans, facts = windows.plan(source, config, wcfg)
        options = {**asdict(config), **asdict(wcfg)}
    elif layout == "ros2":
        rcfg = layout_config if isinstance(layout_config, Ros2Config) else Ros2Config()
        plans, facts = ros2.plan(source, config, rcfg)
        options = {**asdict(config), **asdict(rcfg)}
    else:
        raise SourceError(f"--layout {layout!r} is unknown; allowed: {', '.join(LAYOUTS)}")
    extra = {"options": options, "recordings": len(plans), **facts}
    return write_dataset(layout, source, out, plans, config, extra, replace=replace, progress=progress)
