"""Executors: the same checksums locally and on Ray, seeds from the task index, idempotent retries, and a
fast one-line error for a Ray address where nothing answers."""

from __future__ import annotations

import functools
import operator
import shutil
import socket
import time
from pathlib import Path

import pytest

from benchmarks import dataset as ds
from benchmarks.cli import main
from benchmarks.command import EXECUTORS as PARSER_EXECUTORS
from benchmarks.errors import UserError, check_seed
from benchmarks.executor import (
    CONNECT_TIMEOUT_S,
    EXECUTORS,
    LocalExecutor,
    RayExecutor,
    make_executor,
    publish_dir,
)
from benchmarks.presets import get_preset


def _ray_available() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


needs_ray = pytest.mark.skipif(
    not _ray_available(), reason="ray is not installed (pip install -c constraints.txt -e '.[ray]')"
)  # the `local_ray` fixture is in conftest.py


def _seed_after_pause(spec: ds.EpisodeSpec) -> int:
    """A spec's seed, returned later for earlier tasks (so tasks finish out of order)."""
    time.sleep(0.3 if spec.episode_id.startswith("train") else 0.0)
    return spec.seed


def test_parser_and_executor_agree_on_the_choices() -> None:
    assert PARSER_EXECUTORS == EXECUTORS


def test_episode_seeds_come_from_the_dataset_seed_and_the_index_only() -> None:
    plan = ds.plan_episodes(get_preset("tiny"), 5)
    assert [s.seed for s in plan] == [ds._episode_seed(5, i) for i in range(len(plan))]
    assert len({s.seed for s in plan}) == len(plan)
    # The plan is made here; each spec carries its seed to whatever worker builds it, and results come back
    # in task order even when the first tasks finish last.
    assert LocalExecutor(2).map(_seed_after_pause, plan, progress=False) == [s.seed for s in plan]
    assert LocalExecutor(1).map(_seed_after_pause, plan[:2], progress=False) == [s.seed for s in plan[:2]]


@needs_ray
@pytest.mark.xdist_group("ray")  # with `pytest -n`, the tests that start Ray share one worker
def test_ray_gives_the_same_checksums_as_local_processes(
    tiny_dataset: Path, tmp_path: Path, local_ray: None
) -> None:
    # One episode of each category, built by Ray workers exactly as `generate` builds them, against the
    # local processes' files of the same plan (the whole tiny dataset takes minutes on Ray on 2 cores).
    local = ds.open_dataset(tiny_dataset, verify=False).manifest
    firsts = {e.spec.category: e for e in reversed(local.episodes)}
    assert set(firsts) >= {"nominal", "collision", "fault"}
    build = functools.partial(ds.build_episode, directory=tmp_path)
    paths = RayExecutor().map(build, [e.spec for e in firsts.values()], progress=False)
    assert [Path(p).name for p in paths] == [e.episode_id for e in firsts.values()]
    for entry in firsts.values():
        assert ds.episode_checksums(tmp_path / entry.episode_id) == entry.files, entry.episode_id


@needs_ray
@pytest.mark.xdist_group("ray")  # with `pytest -n`, the tests that start Ray share one worker
def test_ray_keeps_task_order_and_reraises_a_tasks_own_error(local_ray: None) -> None:
    # Ray workers import what a task names: functions of installed modules (this test file is not one).
    executor = RayExecutor()
    plan = ds.plan_episodes(get_preset("tiny"), 5)
    assert executor.map(operator.attrgetter("seed"), plan, progress=False) == [s.seed for s in plan]
    with pytest.raises(UserError, match="--seed = -1 is invalid"):
        executor.map(check_seed, [0, -1, 2], progress=False)
    executor.close()  # leaves the Ray it did not start running
    import ray

    assert ray.is_initialized()


def test_a_retried_episode_task_leaves_the_same_files(tiny_dataset: Path, tmp_path: Path) -> None:
    manifest = ds.open_dataset(tiny_dataset, verify=False).manifest
    entry = next(e for e in manifest.episodes if e.episode_id == "test-nominal-000")
    spec = ds.open_dataset(tiny_dataset, verify=False).episode_specs()["test-nominal-000"]
    # An earlier attempt left a copy at the episode's place (with a stray file in it): the retry replaces
    # it with the same bytes, whole.
    shutil.copytree(tiny_dataset / spec.episode_id, tmp_path / spec.episode_id)
    (tmp_path / spec.episode_id / "junk").write_text("half-written")
    path = ds.build_episode(spec, tmp_path)
    assert path == tmp_path / spec.episode_id
    assert ds.episode_checksums(path) == entry.files
    assert sorted(p.name for p in tmp_path.iterdir()) == [spec.episode_id]  # no staging folder left
    assert not (path / "junk").exists()


def test_publish_dir_replaces_an_earlier_copy(tmp_path: Path) -> None:
    for text in ("first", "second"):
        staged = tmp_path / f"staged-{text}"
        staged.mkdir()
        (staged / "f.txt").write_text(text)
        publish_dir(staged, tmp_path / "target")
    assert (tmp_path / "target" / "f.txt").read_text() == "second"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["target"]


def _closed_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@needs_ray
@pytest.mark.xdist_group("ray")  # with `pytest -n`, the tests that start Ray share one worker
def test_an_unreachable_address_is_a_fast_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    address = f"127.0.0.1:{_closed_port()}"
    started = time.perf_counter()
    out = str(tmp_path / "d")
    code = main(["generate", "--preset", "tiny", "--out", out, "--executor", "ray", "--address", address])
    elapsed = time.perf_counter() - started
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and address in err and "no Ray cluster reachable" in err
    assert elapsed < CONNECT_TIMEOUT_S + 5
    assert not (tmp_path / "d").exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("kind", "kwargs", "message"),
    [
        ("local", {"address": "127.0.0.1:6379"}, "--address 127.0.0.1:6379 needs --executor ray"),
        ("dask", {}, "--executor 'dask' is invalid; allowed: local, ray"),
        ("local", {"workers": 0}, "--workers = 0 is invalid"),
    ],
)
def test_bad_executor_options_are_refused(kind: str, kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(UserError, match=message):
        make_executor(kind, **kwargs)  # type: ignore[arg-type]


@needs_ray
@pytest.mark.xdist_group("ray")  # with `pytest -n`, the tests that start Ray share one worker
@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"address": "nohost"}, "--address 'nohost' is invalid; allowed: HOST:PORT"),
        ({"address": "10.0.0.5:6379", "workers": 2}, "the Ray cluster decides"),
    ],
)
def test_bad_ray_options_are_refused(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(UserError, match=message):
        make_executor("ray", **kwargs)  # type: ignore[arg-type]
