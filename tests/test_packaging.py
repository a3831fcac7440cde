"""`pip install ./host`: the wheel holds the `motecal` command, the core
dependencies only, the database drivers as extras (postgres, mysql) and the
mote's C code the simulator compiles; the pins agree.  Built offline from a
copy of host/ in a temporary folder (setuptools from requirements-test.txt)."""
import re
import shutil
import subprocess
import sys
import zipfile

from conftest import REPO

CORE = {"numpy", "scipy", "pyserial", "matplotlib", "rich"}
EXTRAS = {"postgres": "psycopg", "mysql": "PyMySQL"}


def _pins(name):
    text = (REPO / "host" / name).read_text()
    return {m.group(1).lower(): m.group(2) for m in re.finditer(r"^([\w.-]+)==(\S+)", text, re.M)}


def test_wheel_command_core_dependencies_extras_and_c_code(tmp_path):
    src = tmp_path / "host"
    shutil.copytree(REPO / "host", src,            # the csrc link is copied as files
                    ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-index",
                        "--no-build-isolation", "--disable-pip-version-check",
                        "-w", str(tmp_path / "dist"), str(src)],
                       capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    whl, = (tmp_path / "dist").glob("motecal-*.whl")
    with zipfile.ZipFile(whl) as z:
        names = set(z.namelist())
        meta = z.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
        entry = z.read(next(n for n in names if n.endswith("entry_points.txt"))).decode()
    assert re.search(r"^motecal = motecal\.commands\.main:main$", entry, re.M)
    requires = re.findall(r"^Requires-Dist: (.*)$", meta, re.M)
    core = {re.match(r"[\w.-]+", q).group(0) for q in requires if "extra ==" not in q}
    assert core == CORE
    assert set(re.findall(r"^Provides-Extra: (\S+)$", meta, re.M)) == set(EXTRAS)
    for extra, driver in EXTRAS.items():
        assert any(q.startswith(driver) and f'extra == "{extra}"' in q for q in requires), requires
    # the simulator's C code: every .c/.h of tinyos/, the same bytes
    c_files = sorted(p for p in (REPO / "tinyos").iterdir() if p.suffix in (".c", ".h"))
    assert c_files
    with zipfile.ZipFile(whl) as z:
        for p in c_files:
            assert z.read(f"motecal/firmware/csrc/{p.name}") == p.read_bytes(), p.name
    assert sorted(n for n in names if "/csrc/" in n) == \
        sorted(f"motecal/firmware/csrc/{p.name}" for p in c_files)
    # in the repository the package's csrc is the firmware's folder itself
    assert (REPO / "host/motecal/firmware/csrc").resolve() == (REPO / "tinyos").resolve()


def test_pins_core_then_tests_and_drivers():
    core, test = _pins("requirements.txt"), _pins("requirements-test.txt")
    assert CORE <= set(core)
    assert not {"psycopg", "pymysql"} & set(core)             # drivers are extras
    assert {"psycopg", "psycopg-binary", "pymysql", "pytest"} <= set(test)
    assert not set(core) & set(test)                          # each pin once
    assert "-r requirements.txt" in (REPO / "host/requirements-test.txt").read_text()
