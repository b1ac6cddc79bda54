"""Fixtures shared by the benchmark tests: a small local Ray (test_executor.py, test_robustness.py)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest


@pytest.fixture(scope="session")
def local_ray() -> Iterator[None]:
    """A small Ray on this machine (2 CPUs, no dashboard), started once and shut down after the session."""
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, object_store_memory=100 * 1024**2)
    try:
        yield
    finally:
        ray.shutdown()
