"""report.html in a real browser: headless Chromium, driven over the Chrome DevTools Protocol (a
websocket, `websocket-client`), opens a diagnosis's report and checks that the finding's text is
on the page, that every figure decodes (complete, non-zero natural size), that nothing was asked
of the network (every request a file: or data: URL) and that a full-page screenshot is no blank.

Skipped where no Chromium is installed (Debian: apt-get install chromium) or websocket-client is
missing. The report is the demo's kind (a synthetic sheet hiding a stiffer disc) made once for
the module on a coarse grid with one frame, one region and no other laws or discretisation refit,
so that it takes about a minute and a half on 2 loaded cores (``nonrigid demo`` itself takes
minutes): the module is marked slow, run it with ``-m browser``.
"""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import subprocess
import tempfile
import time

import numpy as np
import pytest

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
BROWSER = os.environ.get("NONRIGID_CHROMIUM") or next((b for b in map(shutil.which, BROWSERS) if b), None)
websocket = pytest.importorskip("websocket", reason="needs websocket-client (the test extra) to drive Chromium")
pytestmark = [pytest.mark.browser, pytest.mark.slow,  # the diagnosis behind the report: about 85 s on 2 loaded cores
              pytest.mark.skipif(BROWSER is None, reason="no Chromium found (apt-get install chromium, or set "
                                 "NONRIGID_CHROMIUM to its path)")]


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A diagnosis of a sheet hiding a stiffer disc: (its Diagnosis, report.html's path)."""
    import jaxfem as jf
    from refine.bundle import write_bundle
    from refine.cli import diagnose
    from refine.demo_data import Inclusion, Truth, synthetic_bundle

    root = tmp_path_factory.mktemp("browser")
    truth = Truth(inclusions=(Inclusion(jf.Ellipse(72.0, 38.0, 14.0, 10.0, 0.4), ratio=6.0),))
    bundle = synthetic_bundle(truth, seed=8, spacing=8.0, noise=0.02, fractions=(1.0,), name="browser")
    write_bundle(root / "bundle", bundle)
    d = diagnose(root / "bundle", root / "out", quiet=True,
                 config={"try_laws": False, "seed": 3, "max_regions": 1, "discretisation_error": False})
    return d, root / "out" / "report.html"


class Chromium:
    """Headless Chromium and one page of it, spoken to over CDP (flat sessions on the browser's socket)."""

    def __init__(self, browser: str):
        self.profile = tempfile.mkdtemp(prefix="nonrigid-chromium-")
        self.proc = subprocess.Popen([browser, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
                                      "--disable-extensions", "--disable-background-networking",
                                      "--remote-debugging-port=0", f"--user-data-dir={self.profile}",
                                      "--window-size=1200,900", "about:blank"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        url, deadline = None, time.monotonic() + 30
        while url is None and time.monotonic() < deadline:
            line = self.proc.stderr.readline()
            if not line and self.proc.poll() is not None:
                break
            m = re.search(r"DevTools listening on (ws://\S+)", line)
            url = m.group(1) if m else None
        if url is None:
            self.close()
            pytest.fail(f"{browser} did not open its DevTools socket within 30 s")
        self.ws = websocket.create_connection(url, timeout=30, suppress_origin=True)
        self.next_id, self.events = 0, []
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        for domain in ("Page", "Network", "Runtime"):
            self.call(f"{domain}.enable", session=True)

    def call(self, method: str, session: bool = False, **params):
        """Send ``method`` (to the page's session where ``session``); its result, events kept aside."""
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params}
        if session:
            msg["sessionId"] = self.session
        self.ws.send(json.dumps(msg))
        while True:
            reply = json.loads(self.ws.recv())
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]
            if "method" in reply:
                self.events.append(reply)

    def wait_for(self, method: str, timeout: float = 30.0):
        deadline = time.monotonic() + timeout
        while not any(e["method"] == method for e in self.events):
            if time.monotonic() > deadline:
                raise TimeoutError(f"no {method} within {timeout} s")
            reply = json.loads(self.ws.recv())
            if "method" in reply:
                self.events.append(reply)

    def evaluate(self, expression: str):
        r = self.call("Runtime.evaluate", session=True, expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression[:60]}...: {r['exceptionDetails']}")
        return r["result"]["value"]

    def close(self):
        if getattr(self, "ws", None) is not None:
            self.ws.close()
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        shutil.rmtree(self.profile, ignore_errors=True)


@pytest.fixture(scope="module")
def page(report):
    d, html = report
    browser = Chromium(BROWSER)
    try:
        browser.call("Page.navigate", session=True, url=html.as_uri())
        browser.wait_for("Page.loadEventFired")
        yield browser, d, html
    finally:
        browser.close()


def test_the_page_shows_the_finding(page):
    browser, d, _ = page
    [finding] = d.findings
    text = browser.evaluate("document.body.innerText")
    assert finding["cause"] == "stiffer-region" and "Finding: stiffer-region" in text
    assert f"{finding['relative_elasticity']:.2f} +- {finding['relative_elasticity_std']:.2f}" in text
    assert "Hypotheses tried, and why the chosen one won" in text


def test_every_figure_renders(page):
    browser, _, html = page
    images = browser.evaluate("Promise.all([...document.images].map(i => i.decode().then(() => true, () => false)"
                              ".then(ok => ({ok, complete: i.complete, w: i.naturalWidth, h: i.naturalHeight, "
                              "shown: i.getBoundingClientRect().width, src: i.src.slice(0, 30)}))))")
    expected = len(re.findall(r"<img\b", html.read_text()))
    assert expected >= 3 and len(images) == expected
    for im in images:
        assert im["ok"] and im["complete"] and im["w"] > 0 and im["h"] > 0 and im["shown"] > 0, im


def test_nothing_is_fetched_from_the_network(page):
    browser, _, html = page
    urls = [e["params"]["request"]["url"] for e in browser.events if e["method"] == "Network.requestWillBeSent"]
    assert html.as_uri() in urls  # the page itself was seen, so the record is live
    assert all(u.startswith(("file:", "data:")) for u in urls), [u for u in urls if not u.startswith("file:")]
    assert not [e for e in browser.events if e["method"] == "Network.loadingFailed"]


def test_a_full_page_screenshot_is_not_blank(page, tmp_path):
    browser, _, _ = page
    shot = browser.call("Page.captureScreenshot", session=True, format="png", captureBeyondViewport=True)
    png = base64.b64decode(shot["data"])
    (tmp_path / "report.png").write_bytes(png)
    import cv2

    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_GRAYSCALE)
    assert img is not None and img.shape[1] >= 1000 and img.shape[0] > 900  # the whole page, taller than the window
    assert img.std() > 10  # figures and text, not a blank page
