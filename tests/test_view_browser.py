"""The view in a real browser: Debian's headless Chromium (installed by
``make test``, driven over the DevTools pipe, tests/browser.py) opens the page
of ``motecal log --guided ... --yes --view 127.0.0.1:0`` reading
``motecal sim --serve``, and the DOM shows poses advancing, coverage rising,
and at the end the counters the database holds; a reload mid-run resumes with
the full state; the sweep draws its points; the report's view.html (the
stored session, data embedded) shows the same session from disk.

Screenshots land in the test's temporary folder (``VIEW_SHOTS=DIR`` puts them
there instead: docs/img/ is made that way).
"""
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from browser import Browser, chromium
from motecal.sessions.store import open_store
from motecal.view import static_page
from motecal.view.state import session_state

if chromium() is None:
    pytest.fail("chromium is missing: `make test` installs it (TEST_PACKAGES)",
                pytrace=False)

SHOTS = os.environ.get("VIEW_SHOTS")


def _shot(b, tmp_path, name):
    path = Path(SHOTS or tmp_path) / name
    b.screenshot(path)
    return path


class Procs:
    def __init__(self):
        self.procs = []

    def start(self, args, **kw):
        p = subprocess.Popen([sys.executable, "-m", "motecal", *args], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True, **kw)
        self.procs.append(p)
        return p

    def close(self):
        for p in self.procs:
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()


@pytest.fixture
def procs():
    p = Procs()
    yield p
    p.close()


def _serve_and_log(procs, tmp_path, kind, motes, speed, seed):
    sim = procs.start(["sim", "--serve", "127.0.0.1:0", "--motes", str(motes), "--session", kind,
                       "--seed", str(seed), "--speed", str(speed), "--quiet"])
    url = sim.stdout.readline().strip()
    assert url.startswith("socket://"), sim.stderr.read()
    db = str(tmp_path / f"{kind}.db")
    log = procs.start(["log", "--port", url, "--db", db, "--session", kind, "--guided", kind,
                       "--yes", "--view", "127.0.0.1:0"])
    first = log.stdout.readline()
    assert first.startswith("view: http://127.0.0.1:"), log.stderr.read()
    threading.Thread(target=log.stdout.read, daemon=True).start()     # never blocks the logger
    return log, first.split()[1], db


def _num(b, id_):
    return b.eval(f"(function(){{var e=document.getElementById('{id_}');"
                  f"return e ? Number(e.dataset.value) : null;}})()")


INK = """(function(id){var c=document.getElementById(id); var d=c.getContext('2d')
  .getImageData(0,0,c.width,c.height).data, n=0; for (var i=3;i<d.length;i+=4) if (d[i]>0) n++;
  return n;})"""


@pytest.mark.slow
def test_static80_in_chromium(procs, tmp_path):
    with Browser(tmp_path) as b:        # the browser first: its start-up is no race
        log, url, db = _serve_and_log(procs, tmp_path, "static80", motes=2, speed=15, seed=8)
        b.open(url)
        b.wait_for("document.getElementById('m1-pose') && "
                   "Number(document.getElementById('m1-pose').dataset.value) >= 2", timeout=30)
        seen = []
        for _ in range(12):
            seen.append((_num(b, "m1-pose"), _num(b, "m1-coverage"), _num(b, "m1-samples")))
            time.sleep(0.4)
        poses, cov, samples = zip(*seen)
        assert poses[-1] > poses[0] and cov[-1] > cov[0] and samples[-1] > samples[0], seen
        assert b.eval("document.getElementById('conn').textContent") == "live"
        assert b.eval("document.querySelectorAll('#tabs button').length") == 2
        for cv in ("m1-board-target", "m1-board-live", "m1-gravity", "m1-grid"):
            assert b.eval(f"{INK}('{cv}')") > 500, cv           # something is drawn
        _shot(b, tmp_path, "view-static80.png")
        # the other mote's tab
        b.eval("document.getElementById('m2-tab').click()")
        b.wait_for("document.getElementById('m2-panel').style.display === ''")
        assert b.eval("document.getElementById('m1-panel').style.display") == "none"
        # a reload (the browser went away and came back): the full state again
        before = _num(b, "m1-pose")
        b.open(url)
        b.wait_for(f"Number((document.getElementById('m1-pose')||{{dataset:{{}}}})"
                   f".dataset.value) >= {before}", timeout=10)
        assert b.eval("document.querySelectorAll('#links tbody tr').length") == 2
        assert log.wait(timeout=120) == 0
        b.wait_for("document.getElementById('conn').textContent.indexOf('ended') >= 0",
                   timeout=10)
        with open_store(db) as st:
            stats = st.link_stats("static80")
            data = st.load_session("static80")
        for m in (1, 2):
            for k in ("samples", "lost", "duplicates", "reordered"):
                assert _num(b, f"m{m}-{k}") == stats["motes"][m][k], (m, k)
            assert _num(b, f"m{m}-accepted") == len(data.for_mote(m).poses()) == 80
        # the stored session, as the report writes it (view.html, from disk)
        page = tmp_path / "view.html"
        page.write_text(static_page(session_state(data, stats, st_events(db))))
        b.open(page.as_uri())
        b.wait_for("!!document.getElementById('m1-accepted')")
        assert _num(b, "m1-accepted") == 80 and _num(b, "m2-accepted") == 80
        assert _num(b, "m1-samples") == stats["motes"][1]["samples"]
        assert b.eval("document.getElementById('conn').textContent") == "stored session"
        assert b.eval(f"{INK}('m1-gravity')") > 500
        _shot(b, tmp_path, "view-report.png")


def st_events(db):
    with open_store(db) as st:
        return st.events("static80")


@pytest.mark.slow
def test_sweep_in_chromium(procs, tmp_path):
    with Browser(tmp_path) as b:
        log, url, db = _serve_and_log(procs, tmp_path, "rotation", motes=1, speed=2, seed=9)
        b.open(url)
        b.wait_for("Number((document.getElementById('m1-points')||{dataset:{}}).dataset.value)"
                   " >= 300", timeout=60)
        first = (_num(b, "m1-points"), _num(b, "m1-scoverage"))
        b.wait_for(f"Number(document.getElementById('m1-points').dataset.value) > {first[0]}"
                   f" && Number(document.getElementById('m1-scoverage').dataset.value) > "
                   f"{first[1]}", timeout=60)
        assert b.eval("document.getElementById('m1-sweep').style.display") == ""
        assert b.eval("document.getElementById('m1-static').style.display") == "none"
        fit = b.eval("document.getElementById('m1-fiterror').textContent")
        assert fit.endswith("%") and float(fit[:-1]) < 30, fit
        for cv in ("m1-raw", "m1-fitted", "m1-sgrid"):
            assert b.eval(f"{INK}('{cv}')") > 500, cv
        _shot(b, tmp_path, "view-sweep.png")
        doc = json.loads(b.eval("JSON.stringify(window.motecalView.state())"))
        assert doc["motes"][0]["sweep"]["count"] >= first[0]
        log.terminate()                     # ends the session cleanly (SIGTERM)
        assert log.wait(timeout=60) == 0
