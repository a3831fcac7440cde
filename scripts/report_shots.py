"""The screenshots of the report's calibration sections in docs/img.

    .venv/bin/python scripts/report_shots.py [--out docs/img]

runs the headless-Chromium test of the report
(tests/test_report_calibration.py::test_report_in_chromium), which writes
its screenshots into its own temporary folder only, and copies them from
there into ``--out`` (docs/img by default): report-choices.png,
report-temperature.png, report-poses.png, report-diagnosis.png and
view-report-calibration.png.  Exit status: the test's, or 1 when a
screenshot is missing.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
NAMES = ("report-choices.png", "report-temperature.png", "report-poses.png",
         "report-diagnosis.png", "view-report-calibration.png")
TEST = "tests/test_report_calibration.py::test_report_in_chromium"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(REPO / "docs" / "img"),
                    help="where the screenshots go (docs/img)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="report-shots-") as tmp:
        base = Path(tmp) / "pytest"
        rc = subprocess.call([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                              "-p", "no:xdist", f"--basetemp={base}", TEST], cwd=REPO)
        if rc != 0:
            print(f"report_shots: the test failed (exit {rc}); nothing copied", file=sys.stderr)
            return rc
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        missing = []
        for name in NAMES:
            found = sorted(base.rglob(f"shots/{name}"))
            if not found:
                missing.append(name)
                continue
            shutil.copyfile(found[-1], out / name)
            print(f"{out / name}")
        if missing:
            print(f"report_shots: not made by the test: {', '.join(missing)}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
