"""Showing a recording without a display: the web viewer served on 127.0.0.1, and the check that refuses to
spawn a native viewer where no display exists (it would hang without a word)."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from urllib.parse import quote

from benchmarks.errors import UserError

LOCALHOST = "127.0.0.1"
"""The only address the web viewer and its data server bind: nothing is exposed to the network."""
WEB_PORT = 9090
"""Default HTTP port of the web viewer (rerun's own default)."""
GRPC_PORT = 9876
"""Default port of the gRPC server the web viewer reads the recording from (rerun's own default)."""


def has_display(env: Mapping[str, str] | None = None, platform: str | None = None) -> bool:
    """Whether a native window can open: on Linux and the BSDs, DISPLAY (X11) or WAYLAND_DISPLAY is set."""
    env = os.environ if env is None else env
    platform = sys.platform if platform is None else platform
    if platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))
    return True  # macOS and Windows always have a window server in a user session


def require_display(env: Mapping[str, str] | None = None, platform: str | None = None) -> None:
    """Raise a one-line `UserError` (suggesting --serve-web or --save) when no display exists."""
    if not has_display(env, platform):
        raise UserError(
            "--spawn needs a display, and neither DISPLAY nor WAYLAND_DISPLAY is set; on a headless machine "
            "use --serve-web (then open the printed http://127.0.0.1 URL, e.g. through an SSH tunnel) "
            "or --save FILE.rrd"
        )


def rerun_executable() -> str:
    """The rerun viewer binary shipped with rerun-sdk (RERUN_CLI_PATH overrides it, as for `rerun` itself).

    The binary is started directly, not through its Python wrapper, so that stopping it stops the server.
    """
    override = os.environ.get("RERUN_CLI_PATH")
    if override:
        return override
    try:
        import rerun_cli

        suffix = ".exe" if sys.platform.startswith("win") else ""
        bundled = Path(rerun_cli.__file__).parent / f"rerun{suffix}"
        if bundled.is_file():
            return str(bundled)
    except ImportError:
        pass
    found = shutil.which("rerun")
    if found is None:
        raise UserError("the rerun viewer was not found: install rerun-sdk (it ships the `rerun` command)")
    return found


def free_port(host: str = LOCALHOST) -> int:
    """A TCP port nobody listens on right now (another program may take it before it is used)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


def viewer_url(web_port: int, grpc_port: int, host: str = LOCALHOST) -> str:
    """The page to open: the web viewer, told where to read the recording from."""
    source = f"rerun+http://{host}:{grpc_port}/proxy"
    return f"http://{host}:{web_port}/?url={quote(source, safe='')}"


def serve_command(files: Sequence[str | os.PathLike[str]], web_port: int, grpc_port: int) -> list[str]:
    """`rerun --serve-web` bound to 127.0.0.1 for `files` (the command a person can also type)."""
    return [
        rerun_executable(), "--serve-web", "--bind", LOCALHOST, "--web-viewer-port", str(web_port),
        "--port", str(grpc_port), *(str(f) for f in files),
    ]  # fmt: skip


def _answers(url: str) -> bool:
    try:
        with urllib.request.urlopen(url, timeout=2) as response:
            return bool(response.status == 200)
    except (urllib.error.URLError, OSError):
        return False


def _listens(host: str, port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.settimeout(1.0)
        return s.connect_ex((host, port)) == 0


@contextmanager
def serve_web(
    files: Sequence[str | os.PathLike[str]],
    web_port: int = WEB_PORT,
    grpc_port: int = GRPC_PORT,
    timeout_s: float = 60.0,
) -> Iterator[str]:
    """Serve recordings to the web viewer on 127.0.0.1 while the block runs; yields the URL to open.

    Runs `rerun --serve-web --bind 127.0.0.1 ... FILES` and waits until both ports answer.

    Raises:
        UserError: a file is missing, or the server did not start (the message has its last output line,
            e.g. a port already in use).
    """
    for f in files:
        if not Path(f).is_file():
            raise UserError(f"recording not found: {f}")
    with tempfile.TemporaryFile() as log:
        proc = subprocess.Popen(
            serve_command(files, web_port, grpc_port), stdin=subprocess.DEVNULL, stdout=log, stderr=log
        )
        try:
            url = viewer_url(web_port, grpc_port)
            deadline = time.monotonic() + timeout_s
            while not (_answers(f"http://{LOCALHOST}:{web_port}/") and _listens(LOCALHOST, grpc_port)):
                if proc.poll() is not None or time.monotonic() > deadline:
                    log.seek(0)
                    lines = [ln for ln in log.read().decode(errors="replace").splitlines() if ln.strip()]
                    last = lines[-1].strip() if lines else "no output"
                    state = f"exited with {proc.returncode}" if proc.poll() is not None else "did not answer"
                    raise UserError(
                        f"rerun --serve-web on ports {web_port} (web) and {grpc_port} (gRPC) {state}: {last}"
                    )
                time.sleep(0.2)
            yield url
        finally:
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()


def move_time_cursor(grpc_url: str, timeline: str, seconds: float) -> str | None:
    """Put a native viewer's time cursor at `seconds` on `timeline`, paused; None, or why it failed.

    Only a native viewer (e.g. one from `--spawn`) takes such commands: a web viewer does not, and a
    recording file cannot carry a cursor position in rerun 0.41 (its blueprint selects the time instead).
    """
    try:
        from rerun.experimental import ViewerClient

        ViewerClient.connect(grpc_url).set_time(timeline, duration=seconds, play_state="paused")
    except Exception as exc:  # an experimental API of a viewer we do not control: report, do not fail
        return f"{type(exc).__name__}: {exc}"
    return None
