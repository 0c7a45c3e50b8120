"""A small headless-Chromium driver for the page tests and the page benchmark (DevTools protocol over a pipe).

Chromium started with ``--remote-debugging-pipe`` reads DevTools-protocol
commands from file descriptor 3 and writes replies and events to descriptor 4,
each message a JSON object terminated by a NUL byte. That is all this module
speaks: no websocket, no third-party client, no network port. It opens a page
(a local file), collects console messages, uncaught exceptions and failed
requests while it loads, and can evaluate JavaScript and take screenshots.

Only tests and benchmarks use it; the planner itself never starts a browser.

>>> with Browser() as b:                                  # doctest: +SKIP
...     page = b.open(Path("outputs/latest/index.html"))
...     page.errors                                       # console errors, exceptions
...     page.eval("document.querySelectorAll('table').length")
"""
from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    """Path of a Chromium/Chrome executable, or None (``$CHROMIUM`` first)."""
    env = os.environ.get("CHROMIUM")
    if env and shutil.which(env):
        return shutil.which(env)
    for name in CANDIDATES:
        p = shutil.which(name)
        if p:
            return p
    return None


class BrowserError(RuntimeError):
    pass


@dataclass
class Page:
    """What happened while a page loaded, and a handle to script it."""

    browser: "Browser"
    session: str
    url: str
    console: list[tuple[str, str]] = field(default_factory=list)
    """(level, text) of every console message."""
    exceptions: list[str] = field(default_factory=list)
    """Uncaught exceptions (text and description)."""
    failed: list[str] = field(default_factory=list)
    """Requests that failed (URL and reason); a self-contained page makes none."""
    requests: list[str] = field(default_factory=list)
    """URLs of every request the page made (the page itself first)."""
    load_ms: float = float("nan")
    """Navigation start to the load event, from the page's own performance timing [ms]."""
    metrics: dict = field(default_factory=dict)
    """Chromium's Performance.getMetrics after the load; ``TaskDuration``, ``ScriptDuration``,
    ``LayoutDuration`` … are main-thread CPU time [s] (thread ticks)."""

    @property
    def errors(self) -> list[str]:
        """Console errors and uncaught exceptions: a clean page has none."""
        return [t for lvl, t in self.console if lvl in ("error", "assert")] + self.exceptions

    def eval(self, expression: str, timeout_s: float = 30.0):
        """Value of a JavaScript expression (awaited when it is a promise), as JSON."""
        r = self.browser.send("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                   "awaitPromise": True}, session=self.session, timeout_s=timeout_s)
        if "exceptionDetails" in r:
            d = r["exceptionDetails"]
            raise BrowserError(f"evaluating {expression[:60]!r}: {d.get('exception', {}).get('description') or d.get('text')}")
        return r["result"].get("value")

    def mouse(self, x: float, y: float, action: str = "move") -> None:
        """A real mouse event at viewport pixel (x, y): ``move``, or ``click`` (press and release)."""
        if action == "move":
            self.browser.send("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": x, "y": y}, session=self.session)
            return
        for kind in ("mousePressed", "mouseReleased"):
            self.browser.send("Input.dispatchMouseEvent", {"type": kind, "x": x, "y": y, "button": "left",
                                                            "clickCount": 1}, session=self.session)

    def screenshot(self, path: Path, full_page: bool = False) -> Path:
        """A PNG of the viewport (or of the whole page)."""
        params: dict = {"format": "png"}
        if full_page:
            m = self.browser.send("Page.getLayoutMetrics", session=self.session)
            size = m.get("cssContentSize") or m["contentSize"]
            params["clip"] = {"x": 0, "y": 0, "width": size["width"], "height": size["height"], "scale": 1}
            params["captureBeyondViewport"] = True
        r = self.browser.send("Page.captureScreenshot", params, session=self.session, timeout_s=60)
        Path(path).write_bytes(base64.b64decode(r["data"]))
        return Path(path)


class Browser:
    """Headless Chromium driven over ``--remote-debugging-pipe``.

    Parameters
    ----------
    width, height : int
        Window size [CSS px].
    executable : str, optional
        Browser binary (default :func:`find_chromium`).
    """

    def __init__(self, width: int = 1400, height: int = 900, executable: str | None = None):
        exe = executable or find_chromium()
        if not exe:
            raise BrowserError("no chromium found; install Debian's `chromium` package")
        self._tmp = tempfile.TemporaryDirectory(prefix="planner-chromium-")
        r3, w3 = os.pipe()   # commands: we write w3, chromium reads fd 3
        r4, w4 = os.pipe()   # replies: chromium writes fd 4, we read r4
        args = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--disable-extensions", "--disable-default-apps", "--no-first-run", "--no-default-browser-check",
                "--mute-audio", "--hide-scrollbars", f"--window-size={width},{height}",
                f"--user-data-dir={self._tmp.name}", "--remote-debugging-pipe", "about:blank"]

        def fds():
            os.dup2(r3, 3)
            os.dup2(w4, 4)

        self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL, preexec_fn=fds, pass_fds=(3, 4))
        os.close(r3)
        os.close(w4)
        self._out = os.fdopen(w3, "wb", buffering=0)
        self._in = r4
        self._buf = b""
        self._id = 0
        self._events: list[dict] = []
        self.width, self.height = width, height

    # --- protocol ------------------------------------------------------------
    def _read_message(self, deadline: float) -> dict:
        import select

        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise BrowserError("chromium did not answer in time")
            ready, _, _ = select.select([self._in], [], [], left)
            if ready:
                chunk = os.read(self._in, 1 << 20)
                if not chunk:
                    raise BrowserError("chromium closed the DevTools pipe")
                self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def send(self, method: str, params: dict | None = None, *, session: str | None = None,
             timeout_s: float = 30.0) -> dict:
        """Send one command and return its result; events that arrive meanwhile are kept."""
        self._id += 1
        msg: dict = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        self._out.write(json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout_s
        while True:
            m = self._read_message(deadline)
            if m.get("id") == self._id:
                if "error" in m:
                    raise BrowserError(f"{method}: {m['error'].get('message')}")
                return m.get("result", {})
            self._events.append(m)

    def _wait_event(self, method: str, session: str, deadline: float) -> dict:
        while True:
            for k, e in enumerate(self._events):
                if e.get("method") == method and e.get("sessionId") == session:
                    return self._events.pop(k)
            self._events.append(self._read_message(deadline))

    # --- pages ---------------------------------------------------------------
    def open(self, path: Path | str, timeout_s: float = 60.0) -> Page:
        """Load a local file (or URL) in a fresh tab and wait for its load event."""
        url = Path(path).resolve().as_uri() if not str(path).startswith(("file:", "http:", "https:", "about:", "data:")) else str(path)
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for dom in ("Page", "Runtime", "Log", "Network"):
            self.send(f"{dom}.enable", session=session)
        # durations in CPU time of the renderer's main thread, which other load on the machine does not inflate
        self.send("Performance.enable", {"timeDomain": "threadTicks"}, session=session)
        self.send("Emulation.setDeviceMetricsOverride", {"width": self.width, "height": self.height,
                                                          "deviceScaleFactor": 1, "mobile": False}, session=session)
        page = Page(self, session, url)
        self._events.clear()
        self.send("Page.navigate", {"url": url}, session=session)
        self._wait_event("Page.loadEventFired", session, time.monotonic() + timeout_s)
        # let queued console events and timers of the load settle (one animation frame + a task)
        page.eval("new Promise(r => requestAnimationFrame(() => setTimeout(r, 0)))")
        page.load_ms = float(page.eval(
            "(() => { const n = performance.getEntriesByType('navigation')[0];"
            " return n ? n.loadEventEnd - n.startTime : NaN; })()") or float("nan"))
        m = self.send("Performance.getMetrics", session=session)["metrics"]
        page.metrics = {x["name"]: float(x["value"]) for x in m}
        for e in self._events:
            if e.get("sessionId") != session:
                continue
            m, p = e.get("method"), e.get("params", {})
            if m == "Runtime.consoleAPICalled":
                text = " ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", []))
                page.console.append((p.get("type", ""), text))
            elif m == "Runtime.exceptionThrown":
                d = p.get("exceptionDetails", {})
                page.exceptions.append(d.get("exception", {}).get("description") or d.get("text", "exception"))
            elif m == "Log.entryAdded":
                entry = p.get("entry", {})
                page.console.append((entry.get("level", ""), f"{entry.get('source')}: {entry.get('text')} {entry.get('url', '')}"))
            elif m == "Network.requestWillBeSent":
                page.requests.append(p.get("request", {}).get("url", ""))
            elif m == "Network.loadingFailed":
                page.failed.append(f"{p.get('errorText')} ({p.get('requestId')})")
        self._events.clear()
        return page

    def close(self) -> None:
        try:
            self.send("Browser.close", timeout_s=5)
        except Exception:  # noqa: BLE001 - closing anyway
            pass
        try:
            self._out.close()
        except OSError:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._in)
        self._tmp.cleanup()

    def __enter__(self) -> "Browser":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
