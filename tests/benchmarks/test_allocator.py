"""The generating processes' allocator setting: freed blocks of tens of MB come back without new pages."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

_PROBE = textwrap.dedent(
    """
    import resource, sys
    import numpy as np
    from benchmarks.allocator import keep_freed_memory

    applied = keep_freed_memory() if sys.argv[1] == "keep" else False
    faults = []
    for _ in range(3):  # four minutes of stereo float32 at once, written, freed, and again
        before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        blocks = [np.empty((2, 60 * 44100), dtype=np.float32) for _ in range(4)]
        for block in blocks:
            block.fill(1.0)
        del blocks, block
        faults.append(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
    print(applied, faults[-1])
    """
)


def _faults(mode: str) -> tuple[str, int]:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, mode], capture_output=True, text=True, check=True
    ).stdout.split()
    return out[0], int(out[1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_kept_memory_is_reused_without_page_faults_where_the_default_maps_it_afresh() -> None:
    applied, kept = _faults("keep")
    if applied != "True":
        pytest.skip("the C library is not glibc's")
    _, default = _faults("default")
    # by default glibc returns what is freed at the heap's top beyond twice its adaptive threshold, so the
    # next blocks are new pages, faulting when first written (a fault per 4 kB page, or per 2 MB huge page
    # where numpy asks for them); kept, the freed blocks are reused
    assert default >= 40  # 84 MB in 2 MB huge pages at least
    assert kept <= default // 20
