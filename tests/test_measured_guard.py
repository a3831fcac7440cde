"""The rule for the measured data (tests/conftest.py): a test that reads them
goes through need_measured() or the `measured` fixture, which skip it where
the data are absent (fail under CI=true); a test that reads them any other way
fails, on every machine, data present or not (the guard in conftest.py).

Checked on a small synthetic test file run by pytest in a subprocess with the
real conftest as its plugin, against a measured folder of its own: once with
data, once with an empty folder, once with the empty folder under CI=true.
"""
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent

SYNTH = '''
import subprocess
import numpy as np
import pytest
from conftest import MEASURED, need_measured


def test_plain():
    assert 1 + 1 == 2


# --- through the lookup: run with data, skipped without ---------------------
def test_fixture(measured):
    assert (measured / "a.txt").read_text() == "data"


def test_calls_the_lookup():
    assert (need_measured() / "a.txt").read_text() == "data"


@pytest.fixture(scope="module")
def through_lookup():
    return (need_measured() / "a.txt").read_text()


def test_module_fixture_first(through_lookup):
    assert through_lookup == "data"


def test_module_fixture_later_reads_again(through_lookup):
    assert (MEASURED / "a.txt").read_text() == through_lookup


# --- around it: each fails, data present or not ----------------------------
def test_direct_read():
    assert (MEASURED / "a.txt").read_text() == "data"


def test_read_before_the_lookup():
    text = (MEASURED / "a.txt").read_text()
    assert (need_measured() / "a.txt").read_text() == text


def test_only_when_present():
    if MEASURED.is_dir():
        (MEASURED / "a.txt").read_text()


def test_error_swallowed():
    try:
        (MEASURED / "missing.txt").read_bytes()
    except OSError:
        pass


def test_numpy_reads():
    np.fromfile(str(MEASURED / "a.txt"), dtype=np.uint8)


def test_listing():
    sorted(MEASURED.glob("*.txt"))


def test_subprocess_reads():
    subprocess.run(["cat", str(MEASURED / "a.txt")], capture_output=True)


@pytest.fixture
def sneaky():
    return (MEASURED / "a.txt").read_text()


def test_fixture_reads_without(sneaky):
    pass
'''

COLLECT = '''
from conftest import MEASURED

DATA = [p.name for p in MEASURED.iterdir()] if MEASURED.is_dir() else []


def test_uses_module_data():
    assert isinstance(DATA, list)
'''

THROUGH = {"test_fixture", "test_calls_the_lookup", "test_module_fixture_first",
           "test_module_fixture_later_reads_again"}
AROUND = {"test_direct_read", "test_read_before_the_lookup", "test_only_when_present",
          "test_error_swallowed", "test_numpy_reads", "test_listing", "test_subprocess_reads",
          "test_fixture_reads_without"}


def _run(tmp_path, measured: Path, ci: bool) -> dict:
    """Run the synthetic files; {test name: (outcome, message)}."""
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    (tmp_path / "test_synth.py").write_text(SYNTH)
    (tmp_path / "test_collect.py").write_text(COLLECT)
    junit = tmp_path / "junit.xml"
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("PYTEST_", "MOTECAL_MEASURED", "CI"))}
    env.update(PYTHONPATH=str(TESTS), MOTECAL_MEASURED=str(measured),
               PYTEST_DISABLE_PLUGIN_AUTOLOAD="1")
    if ci:
        env["CI"] = "true"
    res = subprocess.run([sys.executable, "-m", "pytest", "-p", "conftest", "-p",
                          "no:cacheprovider", "-q", "--continue-on-collection-errors",
                          f"--junitxml={junit}",
                          "test_synth.py", "test_collect.py"],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert junit.exists(), res.stdout + res.stderr
    out = {}
    for case in ET.parse(junit).iter("testcase"):
        name = case.get("name") or case.get("classname")
        kids = [k for k in case if k.tag in ("failure", "error", "skipped")]
        if not kids:
            out[name] = ("passed", "")
        else:
            k = kids[0]
            out[name] = ({"failure": "failed", "error": "error"}.get(k.tag, "skipped"),
                         (k.get("message") or "") + (k.text or ""))
    return out


def _check_around(out):
    for name in AROUND:
        outcome, msg = out[name]
        assert outcome in ("failed", "error"), (name, out[name])
        assert "reads the measured data without the lookup" in msg, (name, msg)
    collect = [v for k, v in out.items() if k not in THROUGH | AROUND | {"test_plain"}]
    assert len(collect) == 1 and collect[0][0] == "error", out
    assert "collecting it reads the measured data without the lookup" in collect[0][1]


@pytest.mark.parametrize("case", ["present", "empty", "empty-ci"])
def test_reads_without_the_lookup_fail_and_lookups_skip(tmp_path, case):
    """Data present: the lookups pass; empty folder: they are skipped (under
    CI=true they fail); and whatever reads the folder around the lookup (at
    once, before it, only when present, catching the error, by numpy, a
    listing, a subprocess, a fixture, at collection) fails in all three."""
    measured = tmp_path / "measured"
    measured.mkdir()
    if case == "present":
        (measured / "a.txt").write_text("data")
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    out = _run(run_dir, measured, ci=case == "empty-ci")
    assert out["test_plain"][0] == "passed", out
    want = {"present": ("passed",), "empty": ("skipped",), "empty-ci": ("failed", "error")}[case]
    for name in THROUGH:
        assert out[name][0] in want, (name, out[name])
        if case != "present":
            assert "measured data not found" in out[name][1], (name, out[name])
    _check_around(out)
