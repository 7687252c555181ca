"""What the browser tests share: Debian's Chromium under Playwright, a barsynth web server in a
process of its own, and the folder their screenshots are kept in.

Chromium comes from Debian (`apt-get install chromium`, done by the README's test command and
`.ci/run`); Playwright never downloads a browser here. Screenshots go to $BARSYNTH_SCREENSHOTS,
or to `test-artifacts/screenshots/` in the checkout, kept after the run as the tests' artefacts.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import select
import signal
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

CHROMIUM = os.environ.get("BARSYNTH_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [  # the closed network refuses Chromium's background connections; don't make them
    "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
]
START_TIMEOUT_S = 120.0  # the first start may compile numba kernels
EXPECT_TIMEOUT_MS = 30_000  # Playwright's expect() waits this long (its 5 s is short on a machine busy elsewhere)


def _patient_expect() -> None:
    from playwright.sync_api import expect

    expect.set_options(timeout=EXPECT_TIMEOUT_MS)


_patient_expect()


@contextlib.contextmanager
def chromium() -> Iterator:
    """Debian's Chromium, launched headless by Playwright (a clear failure if it is missing)."""
    from playwright.sync_api import sync_playwright

    if not os.access(CHROMIUM, os.X_OK):
        pytest.fail(f"{CHROMIUM} is missing: install Debian's chromium (apt-get install chromium), "
                    "as the README's test command does")
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


def screenshot_folder() -> Path:
    """Where screenshots are kept: $BARSYNTH_SCREENSHOTS, else test-artifacts/screenshots."""
    folder = Path(os.environ.get("BARSYNTH_SCREENSHOTS")
                  or Path(__file__).resolve().parents[1] / "test-artifacts" / "screenshots")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


class ServerProcess:
    """A barsynth web server (``command()``) in a process of its own, its stderr in ``log``.
    ``start`` waits for its first line (the address) and its health; the port it got is
    kept, so a restart comes back at the same address."""

    what = "server"

    def __init__(self, log: Path):
        self.log = log
        self.process: subprocess.Popen | None = None
        self.port = 0

    def command(self) -> list[str]:
        raise NotImplementedError

    def start(self) -> str:
        with open(self.log, "ab") as log:
            self.process = subprocess.Popen(self.command(), stdout=subprocess.PIPE, stderr=log, text=True)
        line = self._first_line()
        match = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
        assert match, f"unexpected start-up line {line!r}; log: {self.log.read_text()}"
        self.port = int(match.group(1))
        self.url = f"http://127.0.0.1:{self.port}/"
        with urllib.request.urlopen(self.url + "api/health", timeout=10) as response:
            assert json.load(response)["ok"] is True
        return self.url

    def _first_line(self) -> str:
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            ready, _, _ = select.select([self.process.stdout], [], [], 0.5)
            if ready:
                return self.process.stdout.readline()
            if self.process.poll() is not None:
                pytest.fail(f"{self.what} exited with {self.process.returncode}: {self.log.read_text()}")
        pytest.fail(f"{self.what} did not start in time")

    def kill(self) -> None:
        """SIGKILL: no chance to flush or close anything."""
        self.process.send_signal(signal.SIGKILL)
        self.process.wait(timeout=10)
        self.process.stdout.close()

    def stop(self) -> int | None:
        """SIGTERM, and its exit status (None if it never started)."""
        if self.process is None:
            return None
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            self.process.wait(timeout=20)
        if not self.process.stdout.closed:
            self.process.stdout.close()
        return self.process.returncode
