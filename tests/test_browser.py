"""The report in a real browser: headless Chromium loads every page of a generated tree from file://,
with no console error, no failed load and every figure drawn by plotly.js.

Chromium is driven through the DevTools protocol over a pipe (``--remote-debugging-pipe``: JSON messages
ending in NUL on file descriptors 3 and 4), so no extra package is needed. Skips where Chromium is absent
(Debian package ``chromium``; ``make setup`` installs it where it can).
"""

from __future__ import annotations

import json
import os
import re
import select
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fakerun import offset, scale, write_run

from legbench import report as R

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="no Chromium here (Debian: apt-get install -y chromium)")

#: Longest wait for one answer or event of the browser [s]; a deadline, not a sleep (a loaded CI machine
#: needs seconds to start Chromium and draw a WebGL scene in software).
TIMEOUT = 60.0

#: Waits until plotly has drawn (two animation frames after load), then reports what the page holds.
PROBE = """new Promise(done => requestAnimationFrame(() => requestAnimationFrame(() => {
  const divs = [...document.querySelectorAll('div.lb-plot')];
  done(JSON.stringify({
    figures: divs.length,
    drawn: divs.filter(d => d.querySelector('.plot-container .main-svg')).length,
    gl: document.querySelectorAll('div.lb-leg .gl-container canvas').length,
    plotly: typeof Plotly !== 'undefined', links: [...document.querySelectorAll('a[href]')].map(a => a.href)
  }));
})))"""


class Browser:
    """A headless Chromium spoken to over the DevTools pipe."""

    def __init__(self, profile: Path) -> None:
        assert CHROMIUM is not None
        r_cmd, w_cmd = os.pipe()  # we write commands -> Chromium reads fd 3
        r_out, w_out = os.pipe()  # Chromium writes fd 4 -> we read
        argv = [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            "--disable-extensions",
            "--remote-debugging-pipe",
            f"--user-data-dir={profile}",
            "--window-size=1280,900",
            "about:blank",
        ]

        def fds() -> None:  # in the child: the pipe ends on fds 3 and 4, where Chromium expects them
            r, w = os.dup(r_cmd), os.dup(w_out)
            os.dup2(r, 3)
            os.dup2(w, 4)

        self.proc = subprocess.Popen(
            argv, close_fds=False, preexec_fn=fds, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        os.close(r_cmd)
        os.close(w_out)
        self.w, self.r = w_cmd, r_out
        self.buf = b""
        self.next_id = 0
        self.events: list[dict[str, Any]] = []

    def _read(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.r], [], [], left)[0]:
                raise TimeoutError("Chromium did not answer in time")
            chunk = os.read(self.r, 1 << 20)
            if not chunk:
                raise RuntimeError("Chromium closed the DevTools pipe")
            self.buf += chunk
        msg, _, self.buf = self.buf.partition(b"\0")
        return dict(json.loads(msg))

    def send(self, method: str, params: dict[str, Any] | None = None, session: str | None = None) -> dict[str, Any]:
        """Send one command and return its result (events seen meanwhile are kept)."""
        self.next_id += 1
        msg: dict[str, Any] = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self.w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + TIMEOUT
        while True:
            m = self._read(deadline)
            if m.get("id") == self.next_id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return dict(m.get("result", {}))
            self.events.append(m)

    def wait_event(self, method: str, session: str) -> dict[str, Any]:
        deadline = time.monotonic() + TIMEOUT
        while True:
            for i, m in enumerate(self.events):
                if m.get("method") == method and m.get("sessionId") == session:
                    return self.events.pop(i)
            self.events.append(self._read(deadline))

    def close(self) -> None:
        try:
            self.send("Browser.close")
        except (RuntimeError, TimeoutError, OSError):
            pass
        os.close(self.w)
        os.close(self.r)
        try:
            self.proc.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def load(self, url: str, then: str = "") -> tuple[dict[str, Any], list[str]]:
        """Open ``url`` in a new tab; returns what :data:`PROBE` found (with the value of the expression
        ``then``, evaluated after it, under "then") and every error the page produced."""
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Runtime", "Log", "Page"):
            self.send(f"{domain}.enable", session=session)
        self.events.clear()
        self.send("Page.navigate", {"url": url}, session)
        self.wait_event("Page.loadEventFired", session)
        res = self.send("Runtime.evaluate", {"expression": PROBE, "awaitPromise": True, "returnByValue": True}, session)
        if "exceptionDetails" in res:
            raise RuntimeError(f"probe failed on {url}: {res['exceptionDetails']}")
        found = json.loads(res["result"]["value"])
        if then:
            res = self.send("Runtime.evaluate", {"expression": then, "awaitPromise": True, "returnByValue": True},
                            session)  # fmt: skip
            if "exceptionDetails" in res:
                raise RuntimeError(f"{then!r} failed on {url}: {res['exceptionDetails']}")
            found["then"] = res["result"]["value"]
        errors = []
        for ev in self.events:
            if ev.get("sessionId") != session:
                continue
            p = ev.get("params", {})
            if ev.get("method") == "Runtime.exceptionThrown":
                d = p["exceptionDetails"]
                errors.append(f"exception: {d.get('exception', {}).get('description') or d.get('text')}")
            elif ev.get("method") == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
                errors.append(f"console.{p['type']}: {[a.get('value') for a in p.get('args', [])]}")
            elif ev.get("method") == "Log.entryAdded" and p["entry"]["level"] == "error":
                errors.append(f"log: {p['entry']['text']} ({p['entry'].get('url', '')})")
        self.send("Target.closeTarget", {"targetId": target})
        return found, errors


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Browser]:
    b = Browser(tmp_path_factory.mktemp("chromium-profile"))
    try:
        yield b
    finally:
        b.close()


@pytest.fixture(scope="module")
def tree(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small results tree: two scenarios (one with a failed backend, one in both contact modes)."""
    root = tmp_path_factory.mktemp("results") / "latest"
    write_run(root / "one", {"ref": None, "a": scale(1.1), "b": offset(0.002)}, name="one", skip=0.2)
    write_run(
        root / "one__reference",
        {"ref": None, "a": scale(1.01), "b": offset(0.001)},
        name="one",
        contact_mode="reference",
    )
    write_run(root / "two", {"ref": None, "a": scale(1.2)}, name="two", failed={"c": "no engine"})
    R.write_all(root, jobs=1)
    return root


def _pages(root: Path) -> list[Path]:
    return [root / "report.html", *sorted(root.glob("*/report.html"))]


def test_every_page_loads_from_file_urls_with_no_console_error_and_every_figure_drawn(
    browser: Browser, tree: Path
) -> None:
    """Index and run pages from file://: no exception, console error or failed load; on a run page every
    figure div holds a drawn plotly chart (its SVG), the 3D leg view a WebGL canvas; links resolve to files."""
    pages = _pages(tree)
    assert len(pages) == 4
    for page in pages:
        found, errors = browser.load(page.as_uri())
        assert errors == [], f"{page}: {errors}"
        if page.parent == tree:
            assert found["figures"] == 0
        else:
            assert found["plotly"] is True
            assert found["figures"] >= 10 and found["drawn"] == found["figures"], f"{page}: {found}"
            assert found["gl"] >= 1, f"{page}: the 3D leg view has no WebGL canvas"
        for href in found["links"]:
            if href.startswith("file://"):
                target = Path(re.sub(r"#.*$", "", href.removeprefix("file://")))
                assert target.exists(), f"{page}: broken link {href}"


#: Moves the 3D view's slider to its middle step: the time label and the drawn legs must follow.
SLIDE = """new Promise(done => {
  const plot = document.getElementById('leg-plot'), slider = document.getElementById('leg-plot-slider');
  const label = document.getElementById('leg-plot-time'), n = plot.data.length;
  const before = [label.textContent, Array.from(plot.data[n - 1].z)];
  slider.value = 100; slider.dispatchEvent(new Event('input'));
  requestAnimationFrame(() => done(JSON.stringify({max: +slider.max, before: before,
                                                   after: [label.textContent, Array.from(plot.data[n - 1].z)]})));
})"""


def test_the_leg_view_follows_its_time_slider(browser: Browser, tree: Path) -> None:
    """Moving the slider to step 100 of 200 redraws each leg at the logged pose of that time: the label reads
    t = 100 x 2 s / 199 and the last backend's joint heights are kinematics.chain of its q there (to float32,
    1e-6 m), not those of t = 0."""
    import numpy as np

    from legbench import kinematics
    from legbench.results import load_run

    found, errors = browser.load((tree / "one" / "report.html").as_uri(), SLIDE)
    assert errors == []
    out = json.loads(found["then"])
    t_step = 100 * 2.0 / 199
    assert out["max"] == 199 and out["before"][0] == "t = 0.000 s" and out["after"][0] == f"t = {t_step:.3f} s"
    b = load_run(tree / "one").traces["b"]
    k = int(np.searchsorted(b.t, t_step))
    assert out["after"][1] == pytest.approx(list(kinematics.chain(b.q[k])[:, 2]), abs=1e-6)
    assert out["before"][1] == pytest.approx(list(kinematics.chain(b.q[0])[:, 2]), abs=1e-6)
    assert abs(out["after"][1][-1] - out["before"][1][-1]) > 1e-3  # the foot moved


def test_pages_need_no_network_and_share_one_plotly(tree: Path) -> None:
    """No page refers to anything outside the tree (no http, no //host); plotly.min.js exists once, in assets/,
    and each run page loads it through the same relative path."""
    for page in _pages(tree):
        text = page.read_text()
        assert not re.search(r'(src|href)="(https?:|//)', text), page
    assert [p.relative_to(tree).as_posix() for p in tree.rglob("plotly.min.js")] == ["assets/plotly.min.js"]
    for page in sorted(tree.glob("*/report.html")):
        assert '<script src="../assets/plotly.min.js"></script>' in page.read_text()


def test_a_page_with_a_missing_asset_is_caught(browser: Browser, tree: Path, tmp_path: Path) -> None:
    """The check can fail: a copy of a run page whose plotly.js is absent reports the failed load and the
    undrawn figures."""
    shutil.copytree(tree / "one", tmp_path / "one")
    found, errors = browser.load((tmp_path / "one" / "report.html").as_uri())
    assert any("plotly.min.js" in e or "Plotly" in e or "legbench" in e for e in errors), errors
    assert found["drawn"] == 0
