"""The C allocator's settings in processes that generate episodes: freed memory is kept for reuse.

An episode allocates and frees arrays of tens of MB (a minute of stereo float32 is 21 MB) over and over.
glibc's malloc serves blocks above its mmap threshold (128 kB at start, raised on each free up to 32 MB) from
fresh mappings and returns heap memory beyond its trim threshold to the kernel, so those arrays come back as
new pages, each zeroed by the kernel on its first write (a page fault per page), a real share of a
minute-long episode's time. With the threshold fixed at `MMAP_THRESHOLD` and trimming only beyond
`TRIM_THRESHOLD`, freed blocks are reused: the process's peak memory is the same (the episode's peak), and
it keeps it. Other C libraries (and other systems) are left as they are: the setting changes speed only,
never what is computed.
"""

from __future__ import annotations

import ctypes
import sys

MMAP_THRESHOLD = 32 << 20
"""Blocks of at least this many bytes are mapped on their own (glibc's own upper bound for its adaptive
threshold): an episode's arrays up to a minute of stereo float32 come from the heap."""

TRIM_THRESHOLD = 1 << 30
"""Free memory at the top of the heap returned to the kernel only beyond this many bytes."""

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
"""glibc's `mallopt` parameter numbers (malloc.h)."""

_applied = False


def keep_freed_memory() -> bool:
    """Set glibc's mmap and trim thresholds in this process (once); whether they are set. False where the
    C library is not glibc's or refuses them (nothing changes then)."""
    global _applied
    if _applied:
        return True
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)
        mallopt = libc.mallopt
        libc.gnu_get_libc_version  # noqa: B018 - glibc only (musl's mallopt ignores everything)
    except (OSError, AttributeError):
        return False
    # the mmap threshold first: setting any parameter turns glibc's adaptive threshold off
    _applied = (
        mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1 and mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1
    )
    return _applied
