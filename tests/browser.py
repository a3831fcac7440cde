"""Headless Chromium (Debian's ``chromium``) driven over the DevTools protocol
on a pipe (``--remote-debugging-pipe``: JSON messages ending in NUL on fds 3
and 4), so tests need no WebSocket client and no browser driver.

    with Browser(tmp_path) as b:
        b.open("http://127.0.0.1:8000/")
        b.eval("document.title")
        b.screenshot(tmp_path / "page.png")
"""
from __future__ import annotations

import base64
import fcntl
import json
import os
import shutil
import subprocess
import time

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run",
         "--disable-default-apps", "--disable-extensions", "--mute-audio",
         "--remote-debugging-pipe"]


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


class BrowserError(RuntimeError):
    pass


class Browser:
    def __init__(self, workdir, width: int = 1200, height: int = 1000, timeout: float = 30.0):
        exe = chromium()
        if exe is None:
            raise BrowserError("chromium is not installed (make sysdeps installs it)")
        self.timeout = timeout
        profile = os.path.join(str(workdir), "chromium-profile")
        os.makedirs(profile, exist_ok=True)
        to_r, to_w = os.pipe()          # we write commands -> its fd 3
        from_r, from_w = os.pipe()      # its fd 4 -> we read replies
        # the child's ends above 9, so that moving them to 3 and 4 overwrites neither
        for name in ("to_r", "from_w"):
            fd = locals()[name]
            high = fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10)
            os.close(fd)
            if name == "to_r":
                to_r = high
            else:
                from_w = high
        self.log = open(os.path.join(str(workdir), "chromium.log"), "wb")

        # the shell puts the pipe ends on fds 3 and 4, where chromium expects them
        self.proc = subprocess.Popen(
            ["bash", "-c", f'exec "$0" "$@" 3<&{to_r} 4>&{from_w} {to_r}<&- {from_w}>&-', exe,
             *FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
             "about:blank"],
            stdin=subprocess.DEVNULL, stdout=self.log, stderr=self.log,
            pass_fds=(to_r, from_w))
        os.close(to_r)
        os.close(from_w)
        self._w, self._r = to_w, from_r
        self._buf = b""
        self._id = 0
        self.session = None
        targets = self.call("Target.getTargets")["targetInfos"]
        page = next(t for t in targets if t["type"] == "page")
        self.session = self.call("Target.attachToTarget", targetId=page["targetId"],
                                 flatten=True)["sessionId"]
        self.call("Page.enable")
        self.call("Runtime.enable")
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height,
                  deviceScaleFactor=1, mobile=False)

    # -- protocol ----------------------------------------------------------------------
    def _read_message(self, deadline: float) -> dict:
        import select
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise BrowserError("chromium did not answer in time")
            ready, _, _ = select.select([self._r], [], [], left)
            if ready:
                chunk = os.read(self._r, 1 << 20)
                if not chunk:
                    raise BrowserError("chromium closed its pipe")
                self._buf += chunk
        msg, _, self._buf = self._buf.partition(b"\0")
        return json.loads(msg)

    def call(self, method: str, **params):
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params}
        if self.session and not method.startswith("Target."):
            msg["sessionId"] = self.session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + self.timeout
        while True:
            reply = self._read_message(deadline)
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise BrowserError(f"{method}: {reply['error']}")
                return reply.get("result", {})

    # -- what tests use ------------------------------------------------------------------
    def open(self, url: str) -> None:
        self.call("Page.navigate", url=url)
        self.wait_for("document.readyState === 'complete'")

    def eval(self, expression: str):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True,
                      awaitPromise=True)
        if "exceptionDetails" in r:
            raise BrowserError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait_for(self, expression: str, timeout: float | None = None, every: float = 0.1):
        end = time.monotonic() + (timeout or self.timeout)
        while True:
            v = self.eval(expression)
            if v:
                return v
            if time.monotonic() > end:
                raise BrowserError(f"timed out waiting for {expression}")
            time.sleep(every)

    def screenshot(self, path, clip: dict | None = None) -> None:
        """The viewport as PNG, or the page's region ``clip`` ({x, y, width,
        height} in CSS pixels of the page, beyond the viewport too)."""
        if clip is None:
            data = self.call("Page.captureScreenshot", format="png")["data"]
        else:
            data = self.call("Page.captureScreenshot", format="png", captureBeyondViewport=True,
                             clip=dict(clip, scale=1))["data"]
        with open(path, "wb") as f:
            f.write(base64.b64decode(data))

    def close(self) -> None:
        try:
            self.call("Browser.close")
        except (BrowserError, OSError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        for fd in (self._w, self._r):
            try:
                os.close(fd)
            except OSError:
                pass
        self.log.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
