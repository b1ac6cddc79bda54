"""Where independent tasks run: a local process pool (the default) or a Ray cluster (`--executor ray`).

An `Executor` maps a picklable module-level function over a list of tasks and returns the results in task
order, with a progress bar over completions. What a task computes must depend only on the task (its seed
comes from the preset seed and the task's index, never from the worker that runs it), and what it writes
must be idempotent: a task that Ray retries after a worker died writes the same bytes again, through a
temporary file or folder renamed into place (`publish_dir`). Ray is imported only when a `RayExecutor` is
first used; it is the optional extra `msvdd-bench[ray]`.

With a Ray cluster of several machines, every output folder must be on a file system that all of them
mount at the same path: the tasks write there, and the driver checks that what they wrote is visible.
"""

from __future__ import annotations

import importlib.util
import logging
import multiprocessing
import os
import shutil
import socket
import tempfile
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any, Protocol, TypeVar

from tqdm import tqdm

from benchmarks.errors import UserError

T = TypeVar("T")
R = TypeVar("R")

EXECUTORS: tuple[str, ...] = ("local", "ray")
"""`--executor` choices."""

RAY_MISSING = "--executor ray needs Ray: pip install -c constraints.txt 'msvdd-bench[ray]'"
"""The error when Ray is not installed."""

CONNECT_TIMEOUT_S = 5.0
"""How long `--address` may take to accept a TCP connection before the Ray executor gives up, s."""


class Executor(Protocol):
    """Runs independent tasks somewhere and gives their results back in task order."""

    def map(
        self, fn: Callable[[T], R], tasks: Sequence[T], *, desc: str = "tasks", progress: bool = True
    ) -> list[R]:
        """`[fn(t) for t in tasks]`, run in parallel; a bar named `desc` counts completions.

        The first task that raises cancels those not started and re-raises its exception.
        """
        ...

    def describe(self) -> str:
        """One line for logs: what runs the tasks."""
        ...

    def close(self) -> None:
        """Release what the executor started (a Ray instance it started itself); idempotent."""
        ...


class LocalExecutor:
    """Spawned worker processes on this machine (one task in this process when `workers` is 1)."""

    def __init__(self, workers: int | None = None) -> None:
        """`workers`: processes (default: one per CPU)."""
        if workers is not None and (isinstance(workers, bool) or workers < 1):
            raise UserError(f"--workers = {workers} is invalid; allowed: an integer >= 1")
        self.workers = workers or os.cpu_count() or 1

    def describe(self) -> str:
        """`local, N processes`."""
        return f"local, {self.workers} process{'es' if self.workers > 1 else ''}"

    def close(self) -> None:
        """Nothing to release: each `map` has its own pool."""

    def map(
        self, fn: Callable[[T], R], tasks: Sequence[T], *, desc: str = "tasks", progress: bool = True
    ) -> list[R]:
        """Run every task in the pool (or here, with one worker); results in task order."""
        results: list[Any] = [None] * len(tasks)
        with tqdm(total=len(tasks), desc=desc, disable=not progress) as bar:
            if self.workers == 1 or len(tasks) <= 1:
                for i, task in enumerate(tasks):
                    results[i] = fn(task)
                    bar.update()
                return results
            context = multiprocessing.get_context("spawn")
            workers = min(self.workers, len(tasks))
            with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
                futures: dict[Future[R], int] = {pool.submit(fn, task): i for i, task in enumerate(tasks)}
                try:
                    for future in as_completed(futures):
                        results[futures[future]] = future.result()
                        bar.update()
                except BaseException:
                    for future in futures:
                        future.cancel()
                    raise
        return results


class RayExecutor:
    """Tasks on a Ray cluster: the one at `address`, or a Ray started on this machine.

    Ray is imported and connected on the first `map` (an `address` where nothing answers is refused first,
    `check_reachable`). A Ray already initialised in this process is used as it is (and left running);
    else `ray.init()` connects to `address`, or without one to `RAY_ADDRESS` if set, or starts a local Ray
    with `num_cpus` CPUs (default: every CPU) and no dashboard. `close` shuts down only a Ray that this
    executor initialised.
    """

    def __init__(self, address: str | None = None, num_cpus: int | None = None) -> None:
        """`address`: `host:port` of a running cluster's head (GCS), `auto`, or None; `num_cpus`: CPUs of a
        Ray started here."""
        if num_cpus is not None and (isinstance(num_cpus, bool) or num_cpus < 1):
            raise UserError(f"--workers = {num_cpus} is invalid; allowed: an integer >= 1")
        if address is not None and num_cpus is not None:
            raise UserError(
                f"--workers {num_cpus} with --address {address}: the Ray cluster decides how many tasks "
                "run at once; give --workers only for a Ray started here (no --address)"
            )
        self.address = address
        self.num_cpus = num_cpus
        self._owns_ray = False

    def describe(self) -> str:
        """`ray at ADDR` or `ray, local`."""
        return f"ray at {self.address}" if self.address else "ray, local"

    def _connect(self) -> Any:
        try:
            import ray
        except ImportError:
            raise UserError(RAY_MISSING) from None
        if self.address is not None:
            check_reachable(self.address)
        if ray.is_initialized():
            return ray
        kwargs: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "logging_level": logging.WARNING,
        }
        if self.address is None and not os.environ.get("RAY_ADDRESS"):
            kwargs["num_cpus"] = self.num_cpus or os.cpu_count() or 1
        try:
            ray.init(address=self.address, **kwargs)
        except Exception as exc:  # Ray raises ConnectionError, RuntimeError or ValueError here
            where = f"--address {self.address}" if self.address else "a local Ray"
            first = (str(exc).strip().splitlines() or [""])[0]
            reason = f"{type(exc).__name__}: {first}"
            raise UserError(f"{where}: Ray could not start or connect ({reason})") from None
        self._owns_ray = True
        return ray

    def map(
        self, fn: Callable[[T], R], tasks: Sequence[T], *, desc: str = "tasks", progress: bool = True
    ) -> list[R]:
        """Submit every task as a Ray task (1 CPU each); results in task order."""
        ray = self._connect()
        remote = ray.remote(num_cpus=1)(_apply)
        fn_ref = ray.put(fn)  # shipped once, not with every task
        refs = [remote.remote(fn_ref, task) for task in tasks]
        index = {ref: i for i, ref in enumerate(refs)}
        results: list[Any] = [None] * len(tasks)
        pending = list(refs)
        with tqdm(total=len(tasks), desc=desc, disable=not progress) as bar:
            try:
                while pending:
                    done, pending = ray.wait(pending, num_returns=1)
                    for ref in done:
                        results[index[ref]] = _unwrap(ray, ref)
                        bar.update()
            except BaseException:
                for ref in pending:
                    ray.cancel(ref)
                raise
        return results

    def close(self) -> None:
        """Shut down the Ray this executor initialised (not one that was running before)."""
        if self._owns_ray:
            import ray

            ray.shutdown()
            self._owns_ray = False


def _apply(fn: Callable[[T], R], task: T) -> R:
    """A Ray task: `fn(task)` (Ray's remote functions must be plain functions, `fn` may be a partial)."""
    return fn(task)


def _unwrap(ray: Any, ref: Any) -> Any:
    """The task's result; a task's own exception is re-raised as itself (not wrapped by Ray)."""
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as exc:
        cause = exc.as_instanceof_cause()
        original = getattr(exc, "cause", None)
        raise (original if isinstance(original, BaseException) else cause) from None


def parse_address(address: str) -> tuple[str, int]:
    """(host, port) of `host:port` or `[v6]:port` (a `ray://` prefix is read too, though Ray Client needs
    `ray[client]`, which the `ray` extra leaves out); a UserError naming the address."""
    text = address.removeprefix("ray://")
    host, sep, port = text.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise UserError(
            f"--address {address!r} is invalid; allowed: HOST:PORT of a Ray head (e.g. 10.0.0.5:6379) or auto"
        )
    return host, int(port)


def check_reachable(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Refuse, within `timeout_s`, a Ray address where nothing accepts a TCP connection.

    Ray itself waits minutes for an absent cluster; this check makes the usual mistakes (no cluster, a wrong
    host or port, a firewall) a one-line error. `auto` and `local` are Ray's own and are not checked.
    """
    if address in ("auto", "local"):
        return
    host, port = parse_address(address)
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:
        reason = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or type(exc).__name__)
        raise UserError(
            f"--address {address}: no Ray cluster reachable there ({reason.lower()}; TCP timeout "
            f"{timeout_s:g} s); start one with `ray start --head` or leave --address out for a local Ray"
        ) from None


def make_executor(kind: str, *, workers: int | None = None, address: str | None = None) -> Executor:
    """The executor `--executor KIND [--address ADDR] [--workers N]` asks for."""
    if kind not in EXECUTORS:
        raise UserError(f"--executor {kind!r} is invalid; allowed: {', '.join(EXECUTORS)}")
    if kind == "local":
        if address is not None:
            raise UserError(f"--address {address} needs --executor ray")
        return LocalExecutor(workers)
    if importlib.util.find_spec("ray") is None:
        raise UserError(RAY_MISSING)
    if address is not None and address not in ("auto", "local"):
        parse_address(address)  # a malformed address is refused before anything starts
    return RayExecutor(address=address, num_cpus=workers)


def publish_dir(staged: Path, target: Path) -> Path:
    """Rename the finished folder `staged` to `target`, replacing a `target` left by an earlier attempt.

    A retried task re-creates identical contents, so whichever complete copy ends at `target` is right; the
    old copy is moved into a trash folder first (a rename, never a half-deleted folder at `target`).
    """
    for _ in range(5):
        try:
            os.replace(staged, target)
            return target
        except OSError:
            if not target.exists():
                raise
            trash = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
            try:
                os.replace(target, trash / target.name)
            except FileNotFoundError:
                pass  # another attempt moved it first
            finally:
                shutil.rmtree(trash, ignore_errors=True)
    raise OSError(f"could not rename {staged} to {target}: another writer keeps replacing it")
