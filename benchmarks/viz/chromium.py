"""A headless Chromium driven over the DevTools protocol on a pipe (standard library only).

Chromium started with `--remote-debugging-pipe` reads JSON commands, each ended by a NUL byte, on its
file descriptor 3 and writes answers and events the same way on its descriptor 4. This module opens one
page at a given size, loads a URL, and takes PNG screenshots of it: enough to photograph the Rerun web
viewer without a display. Rendering is software (SwiftShader through ANGLE), so no GPU is needed.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import shutil
import subprocess
import tempfile
import time
from types import TracebackType
from typing import IO, Any

from benchmarks.errors import UserError

BROWSERS: tuple[str, ...] = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
"""Executable names tried, in order, when no browser path is given."""

FLAGS: tuple[str, ...] = (
    "--headless=new",
    "--remote-debugging-pipe",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-extensions",
    "--disable-background-networking",
    "--disable-sync",
    "--hide-scrollbars",
    "--mute-audio",
    "--force-device-scale-factor=1",
)
"""Command-line flags of the headless browser (software WebGL through SwiftShader, no sound)."""


class BrowserError(RuntimeError):
    """The browser could not be started, quit, or answered a command with an error."""


def find_browser(path: str | None = None) -> str:
    """The Chromium executable: `path` if given, else the first of `BROWSERS` on PATH.

    Raises:
        UserError: none found (the message says how to install one).
    """
    if path is not None:
        found = shutil.which(path)
        if found is None:
            raise UserError(f"browser {path!r} not found or not executable")
        return found
    for name in BROWSERS:
        found = shutil.which(name)
        if found is not None:
            return found
    raise UserError(
        "no Chromium found (tried " + ", ".join(BROWSERS) + "); install one, e.g. `apt-get install chromium`"
    )


def _bash() -> str:
    """bash (which, unlike dash, redirects descriptors numbered above 9)."""
    found = shutil.which("bash")
    if found is None:
        raise UserError("bash not found: it starts the browser with its DevTools pipes")
    return found


class Chromium:
    """One headless Chromium with one page, used as a context manager.

    with Chromium(width=1440, height=900) as browser:
        browser.open("http://127.0.0.1:9090/")
        png = browser.screenshot()
    """

    def __init__(
        self, width: int, height: int, executable: str | None = None, timeout_s: float = 30.0
    ) -> None:
        """Start the browser (nothing is shown) with a `width` x `height` CSS-pixel page.

        Args:
            width: page width, px.
            height: page height, px.
            executable: Chromium executable (name or path); default: the first of `BROWSERS` found.
            timeout_s: longest wait for one answer of the browser, s.
        """
        if width < 1 or height < 1:
            raise ValueError(f"page size must be positive, got {width}x{height}")
        self.width = width
        self.height = height
        self.timeout_s = timeout_s
        self._profile = tempfile.TemporaryDirectory(prefix="msvdd-chromium-")
        args = [find_browser(executable), *FLAGS, f"--window-size={width},{height}"]
        args.append(f"--user-data-dir={self._profile.name}")
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            args.append("--no-sandbox")  # Chromium refuses to run as root with its sandbox
        to_browser_r, to_browser_w = os.pipe()
        from_browser_r, from_browser_w = os.pipe()
        os.set_inheritable(to_browser_r, True)
        os.set_inheritable(from_browser_w, True)
        # The child gets the pipes as descriptors 3 and 4, where --remote-debugging-pipe expects them.
        redirect = f'exec "$@" 3<&{to_browser_r} 4>&{from_browser_w}'
        launcher = [_bash(), "-c", redirect, "chromium", *args, "about:blank"]
        self._proc = subprocess.Popen(
            launcher,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            pass_fds=(to_browser_r, from_browser_w),
        )
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._send_pipe: IO[bytes] = os.fdopen(to_browser_w, "wb", buffering=0)
        self._recv_pipe: IO[bytes] = os.fdopen(from_browser_r, "rb", buffering=0)
        self._buffer = b""
        self._next_id = 0
        self._session = ""
        try:
            target = self.call("Target.createTarget", url="about:blank")
            attached = self.call("Target.attachToTarget", targetId=target["targetId"], flatten=True)
            self._session = str(attached["sessionId"])
            self.call(
                "Emulation.setDeviceMetricsOverride",
                width=width,
                height=height,
                deviceScaleFactor=1,
                mobile=False,
            )
            self.call("Page.enable")
        except BaseException:
            self.close()
            raise

    def __enter__(self) -> Chromium:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        """Send one DevTools command (to the page once attached) and return its result.

        Raises:
            BrowserError: the browser answered with an error, quit, or did not answer in time.
        """
        self._next_id += 1
        message: dict[str, Any] = {"id": self._next_id, "method": method, "params": params}
        if self._session:
            message["sessionId"] = self._session
        try:
            self._send_pipe.write(json.dumps(message).encode() + b"\0")
        except OSError as exc:
            raise BrowserError(f"the browser quit before {method}: {exc}") from exc
        deadline = time.monotonic() + self.timeout_s
        while True:
            answer = self._read_message(deadline, method)
            if answer.get("id") != self._next_id:
                continue  # an event, or the answer to an earlier command
            if "error" in answer:
                raise BrowserError(f"{method} failed: {answer['error'].get('message', answer['error'])}")
            result: dict[str, Any] = answer.get("result", {})
            return result

    def _read_message(self, deadline: float, method: str) -> dict[str, Any]:
        import select

        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                raise BrowserError(f"no answer to {method} within {self.timeout_s:g} s")
            ready, _, _ = select.select([self._recv_pipe], [], [], left)
            if not ready:
                continue
            chunk = self._recv_pipe.read(1 << 16)
            if not chunk:
                raise BrowserError(f"the browser quit while waiting for {method}")
            self._buffer += chunk
        raw, self._buffer = self._buffer.split(b"\0", 1)
        message: dict[str, Any] = json.loads(raw)
        return message

    def open(self, url: str) -> None:
        """Load `url` in the page (returns once navigation starts; the page may still be loading)."""
        result = self.call("Page.navigate", url=url)
        if result.get("errorText"):
            raise BrowserError(f"could not open {url}: {result['errorText']}")

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return result.get("result", {}).get("value")

    def screenshot(self) -> bytes:
        """The page as PNG bytes, `width` x `height` pixels."""
        clip = {"x": 0, "y": 0, "width": self.width, "height": self.height, "scale": 1}
        result = self.call("Page.captureScreenshot", format="png", clip=clip, captureBeyondViewport=False)
        return base64.b64decode(result["data"])

    def close(self) -> None:
        """Quit the browser and remove its temporary profile (safe to call twice)."""
        if self._proc.poll() is None:
            try:
                self._session = ""
                self._send_pipe.write(json.dumps({"id": 0, "method": "Browser.close"}).encode() + b"\0")
            except OSError:
                pass
            try:
                self._proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        for pipe in (self._send_pipe, self._recv_pipe):
            with contextlib.suppress(OSError):
                pipe.close()
        self._profile.cleanup()


def wait_until_still(
    browser: Chromium, min_wait_s: float, max_wait_s: float, interval_s: float = 2.0, repeats: int = 2
) -> tuple[bytes, bool]:
    """Screenshots until `repeats` in a row are identical (the page stopped drawing), after `min_wait_s`.

    Returns:
        (the last screenshot, whether it settled before `max_wait_s`).
    """
    start = time.monotonic()
    time.sleep(min_wait_s)
    last = browser.screenshot()
    same = 0
    while time.monotonic() - start < max_wait_s:
        time.sleep(interval_s)
        shot = browser.screenshot()
        same = same + 1 if shot == last else 0
        last = shot
        if same >= repeats:
            return last, True
    return last, False
