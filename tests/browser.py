"""Headless Chromium driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``:
commands on the child's fd 3, answers on its fd 4, each a JSON text ending in a NUL byte).
Just what the page tests need: open a file, collect console errors and failed loads,
evaluate an expression, take a screenshot. No network, no package beyond the standard
library."""

from __future__ import annotations

import base64
import fcntl
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: The browsers tried, in order.
BROWSERS = ("chromium", "chromium-browser", "google-chrome")

_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--hide-scrollbars",
    "--mute-audio",
]


def find_browser() -> str | None:
    """The path of the first installed browser of :data:`BROWSERS`, or None."""
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


@dataclass
class PageCheck:
    """What a page did when it loaded."""

    errors: list[str] = field(default_factory=list)  # console errors, failed loads
    result: Any = None  # the value of the expression evaluated after the load
    screenshot: bytes = b""  # PNG of the first screen


class Browser:
    """One headless Chromium; :meth:`check` opens a page in a new tab."""

    def __init__(self, path: str, *, width: int = 1200, height: int = 900) -> None:
        self.width, self.height = width, height
        self._profile = tempfile.mkdtemp(prefix="dgli-chromium-")
        to_child_r, self._to_child = os.pipe()
        self._from_child, from_child_w = os.pipe()
        # the child's fd 3 and 4, duplicated high first so that dup2 cannot clobber them
        high = [fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10) for fd in (to_child_r, from_child_w)]

        def child_fds() -> None:  # dup2's copy is inherited, the rest are close-on-exec
            os.dup2(high[0], 3)
            os.dup2(high[1], 4)

        self._proc = subprocess.Popen(
            [path, *_FLAGS, f"--user-data-dir={self._profile}", "--remote-debugging-pipe",
             f"--window-size={width},{height}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            close_fds=False, preexec_fn=child_fds,
        )
        for fd in (to_child_r, from_child_w, *high):
            os.close(fd)
        self._next_id = 0
        self._buffer = b""
        self._events: list[dict] = []

    def close(self) -> None:
        """End the browser and remove its profile."""
        try:
            self._send("Browser.close")
        except OSError:
            pass
        try:
            self._proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        os.close(self._to_child)
        os.close(self._from_child)
        shutil.rmtree(self._profile, ignore_errors=True)

    def _send(self, method: str, params: dict | None = None, session: str | None = None) -> int:
        self._next_id += 1
        message: dict[str, Any] = {"id": self._next_id, "method": method,
                                   "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self._to_child, json.dumps(message).encode() + b"\0")
        return self._next_id

    def _read(self, deadline: float) -> dict:
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._from_child], [], [], left)[0]:
                raise TimeoutError("the browser did not answer in time")
            chunk = os.read(self._from_child, 1 << 20)
            if not chunk:
                raise OSError("the browser closed its pipe")
            self._buffer += chunk
        text, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(text)

    def call(self, method: str, params: dict | None = None, session: str | None = None,
             timeout: float = 60.0) -> dict:
        """Send a command and wait for its answer (events met meanwhile are kept)."""
        wanted = self._send(method, params, session)
        deadline = time.monotonic() + timeout
        while True:
            message = self._read(deadline)
            if message.get("id") == wanted:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})
            self._events.append(message)

    def _wait_event(self, method: str, session: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not any(e.get("method") == method and e.get("sessionId") == session
                      for e in self._events):
            self._events.append(self._read(deadline))

    def check(self, url: str, expression: str) -> PageCheck:
        """Open ``url`` in a new tab at the window's size, wait for its load event, and
        give its console errors and failed loads, the value of ``expression`` and a
        screenshot of the first screen."""
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.call("Target.attachToTarget",
                            {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            self.call(f"{domain}.enable", session=session)
        self.call("Emulation.setDeviceMetricsOverride",
                  {"width": self.width, "height": self.height, "deviceScaleFactor": 1,
                   "mobile": False}, session=session)
        self._events = []
        self.call("Page.navigate", {"url": url}, session=session)
        self._wait_event("Page.loadEventFired", session, 60.0)
        value = self.call("Runtime.evaluate", {"expression": expression,
                                               "returnByValue": True}, session=session)
        shot = self.call("Page.captureScreenshot", {"format": "png"}, session=session)
        check = PageCheck(result=value.get("result", {}).get("value"),
                          screenshot=base64.b64decode(shot["data"]))
        for e in self._events:
            if e.get("sessionId") != session:
                continue
            p = e.get("params", {})
            if e["method"] == "Runtime.consoleAPICalled" and p.get("type") == "error":
                check.errors.append("console: " + " ".join(
                    str(a.get("value", a.get("description", ""))) for a in p.get("args", [])))
            elif e["method"] == "Runtime.exceptionThrown":
                check.errors.append("exception: " + str(p.get("exceptionDetails", {})))
            elif e["method"] == "Log.entryAdded" and p["entry"].get("level") == "error":
                entry = p["entry"]
                check.errors.append(f"log: {entry.get('text')} {entry.get('url', '')}")
            elif e["method"] == "Network.loadingFailed":
                check.errors.append(f"load failed: {p.get('errorText')}")
        self.call("Target.closeTarget", {"targetId": target})
        return check


def file_url(path: Path) -> str:
    """The file:// address of a local file."""
    return path.resolve().as_uri()
