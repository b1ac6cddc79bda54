"""Reading ROS 2 bags (MCAP) for the ros2 layout: finding them, listing their topics, reading the messages of
some topics.

A bag is one `.mcap` file, or the `.mcap` files of one rosbag2 folder (a folder with `metadata.yaml`: a bag
split into several files, read in the order of their trailing number). The topics come from the file's
summary (its channels, schemas and message counts); messages are decoded by `mcap_ros2`'s decoder, in log
time order (the order the recorder received them). A file the reader cannot read is refused with one line:
a truncated one (a recorder stopped by force) says how far it is readable.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zstandard
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory

from benchmarks.importers.config import SourceError
from benchmarks.ros2 import msgs

BAG_SUFFIX = ".mcap"
"""The suffix of a bag file."""
ROSBAG2_METADATA = "metadata.yaml"
"""The file that makes a folder one rosbag2 bag (its `.mcap` files are parts of one recording)."""
_READ_ERRORS = (McapError, struct.error, ValueError, EOFError, IndexError, RuntimeError, zstandard.ZstdError)
"""What a damaged or foreign file raises inside `mcap` (its decompressors and CDR decoder included)."""
_TRAILING_NUMBER = re.compile(r"(\d+)$")


@dataclass(frozen=True)
class Bag:
    """One recording: its name and its files, in order."""

    name: str
    """Its path under the source without the suffix (a rosbag2 folder: the folder's path)."""
    files: tuple[Path, ...]
    """Its `.mcap` files, in recording order."""


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a bag."""

    topic: str
    """Its name."""
    type: str
    """Its message type, `pkg/msg/Type` (as the schema names it, made canonical)."""
    count: int
    """Messages on it."""


@dataclass(frozen=True)
class BagInfo:
    """What a bag's summary says."""

    topics: dict[str, TopicInfo]
    """Every topic, by name."""
    start_ns: int
    """Log time of its first message, ns (what `ros2 bag info` calls its start)."""


def _part_order(path: Path) -> tuple[int, str]:
    match = _TRAILING_NUMBER.search(path.stem)
    return (int(match.group(1)) if match else -1, path.name)


def find_bags(source: Path) -> list[Bag]:
    """The bags at `source`: the file itself, or every bag under the folder (hidden ones left out).

    Raises:
        SourceError: no such file or folder, a file that is not `.mcap`, or a folder without bags.
    """
    source = Path(source)
    if source.is_file():
        if source.suffix.lower() != BAG_SUFFIX:
            raise SourceError(f"{source}: not a bag file; allowed: an .mcap file or a folder of them")
        return [Bag(source.stem, (source,))]
    if not source.is_dir():
        raise SourceError(f"bag or folder not found: {source}")
    files = [
        p
        for p in source.rglob(f"*{BAG_SUFFIX}")
        if p.is_file() and not any(part.startswith(".") for part in p.relative_to(source).parts)
    ]
    if not files:
        raise SourceError(f"{source}: no bag ({BAG_SUFFIX} file) found in it or below")
    groups: dict[Path, list[Path]] = {}
    for path in files:
        folder = path.parent
        key = folder if (folder / ROSBAG2_METADATA).is_file() else path
        groups.setdefault(key, []).append(path)
    bags = []
    for key, members in groups.items():
        name = (key if key.is_dir() else key.with_suffix("")).relative_to(source).as_posix()
        bags.append(Bag(name if name != "." else source.name, tuple(sorted(members, key=_part_order))))
    return sorted(bags, key=lambda b: b.name)


def _where_it_ends(path: Path) -> str:
    """How far a file that cannot be read whole is readable (read record by record from its start)."""
    size = path.stat().st_size
    complete, first, last = 0, None, None
    with open(path, "rb") as handle:
        try:
            for record in StreamReader(handle).records:
                complete = handle.tell()
                if isinstance(record, Message):
                    first = record.log_time if first is None else first
                    last = record.log_time
        except _READ_ERRORS:
            pass
    where = f"the file ends after {size} bytes, inside the record that starts at byte {complete}"
    if first is None or last is None:
        return f"{where}, before its first complete message"
    return f"{where}; its last complete message was logged {(last - first) / msgs.NS:.3f} s after its first"


def _summary(path: Path) -> Any:
    """The summary of one file (None: the file has none)."""
    try:
        with open(path, "rb") as handle:
            return make_reader(handle).get_summary()
    except OSError as exc:
        raise SourceError(f"{path}: not a readable file ({exc})") from exc
    except _READ_ERRORS as exc:
        with open(path, "rb") as handle:
            magic_ok = handle.read(8) == b"\x89MCAP0\r\n"
        if not magic_ok:
            raise SourceError(f"{path}: not an MCAP file (no MCAP magic at its start)") from exc
        raise SourceError(
            f"{path}: truncated: {_where_it_ends(path)}; allowed: a complete MCAP file (`mcap recover` "
            "rewrites the readable part of a recording that was stopped by force)"
        ) from exc


def bag_info(bag: Bag) -> BagInfo:
    """Every topic of the bag with its message type and count (summed over its files), and its start.

    Raises:
        SourceError: an unreadable or truncated file (one line saying where), a file without a summary, or a
            bag without messages.
    """
    found: dict[str, TopicInfo] = {}
    starts: list[int] = []
    for path in bag.files:
        summary = _summary(path)
        if summary is None or summary.statistics is None:
            raise SourceError(
                f"{path}: the MCAP file has no summary section (topics and message counts); allowed: a "
                "file written whole (`mcap recover` writes one from a file without it)"
            )
        counts = summary.statistics.channel_message_counts
        if summary.statistics.message_count:
            starts.append(summary.statistics.message_start_time)
        for channel_id, channel in summary.channels.items():
            schema = summary.schemas.get(channel.schema_id)
            type_name = msgs.full_name(schema.name) if schema is not None else "(no schema)"
            before = found.get(channel.topic)
            count = counts.get(channel_id, 0) + (before.count if before else 0)
            if before is not None and before.type != type_name:
                raise SourceError(
                    f"{path}: topic {channel.topic!r} carries {type_name}, but {before.type} in an "
                    "earlier file of the bag; allowed: one type per topic"
                )
            found[channel.topic] = TopicInfo(channel.topic, type_name, count)
    if not starts:
        raise SourceError(f"{bag.files[0]}: the bag holds no message")
    return BagInfo(found, min(starts))


def describe(topics: dict[str, TopicInfo]) -> str:
    """`/a (pkg/msg/T, 12 messages), ...`: a bag's topics for a message."""
    if not topics:
        return "(none)"
    return ", ".join(
        f"{t.topic} ({t.type}, {t.count})" for t in sorted(topics.values(), key=lambda t: t.topic)
    )


def read(bag: Bag, topics: list[str]) -> Iterator[tuple[str, int, Any]]:
    """(topic, log time in ns, decoded message) of every message on `topics`, file by file in log time order.

    Raises:
        SourceError: a file that cannot be read or decoded (naming it and the reason).
    """
    for path in bag.files:
        try:
            with open(path, "rb") as handle:
                reader = make_reader(handle, decoder_factories=[DecoderFactory()])
                for _schema, channel, message, decoded in reader.iter_decoded_messages(topics=topics):
                    yield channel.topic, message.log_time, decoded
        except OSError as exc:
            raise SourceError(f"{path}: not a readable file ({exc})") from exc
        except _READ_ERRORS as exc:
            raise SourceError(f"{path}: a message cannot be read or decoded ({exc})") from exc
