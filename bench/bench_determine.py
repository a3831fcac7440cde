"""What calibrate fits on each session, with no --model (issues 30, 31): the
model per sensor that the one judgement (``calib.determine``) chose, or why a
sensor was not fitted, and the gate's decision -- on every shared measured
data set (``../shared/data/measured``, when present) and on the standard
simulated sessions.

Goals: the six-face Razor sessions calibrate with no flags (offsets +
scales, accepted); the 80-pose sessions get the full model (the calibration
benches unchanged).

    .venv/bin/python bench/bench_determine.py
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "host"))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))   # test helpers

import numpy as np  # noqa: E402

from motecal.calib.board import calibrate_board  # noqa: E402
from motecal.calib.gate import decide  # noqa: E402
from motecal.sessions import importer  # noqa: E402
from motecal.sessions.session import LABEL_NONE  # noqa: E402
from results import record  # noqa: E402


def measured_dir() -> Path | None:
    if os.environ.get("MOTECAL_MEASURED"):
        return Path(os.environ["MOTECAL_MEASURED"])
    for d in Path(__file__).resolve().parents:
        if (d / "shared" / "data" / "measured").is_dir():
            return d / "shared" / "data" / "measured"
    return None


def sessions():
    """(name, SessionData) of the measured data sets, then the simulated."""
    m = measured_dir()
    if m is not None:
        sb = m / "sensorstick-boards"
        for b in ("razor1", "razor2"):
            yield f"{b} faces + still", importer.read_any(sorted((sb / b).glob("*.raw")))
            yield f"{b} still file", importer.read_any([sb / b / f"{b}_gyr_xyz.raw"])
        yield "razor1 + sensorstick sweep", importer.read_any(
            sorted((sb / "razor1").glob("*.raw")) + [m / "sensorstick-mag-sweep" / "magnetom.float"])
        yield "sensorstick-mag-sweep", importer.read_any([m / "sensorstick-mag-sweep" / "magnetom.float"])
        yield "metal-hull-sweep", importer.read_any([m / "metal-hull-sweep" / "magnetom.float"])
        yield "hmc5843-disturbed-sweep", importer.read_any(
            [m / "hmc5843-disturbed-sweep" / "magnetom.float"], chip="mag=hmc5843")
        ts = m / "mpu6050-hmc5883l-timestamped"
        for run in sorted(p.name for p in ts.iterdir() if p.is_dir()):
            yield f"mpu6050 {run}", importer.read_any([ts / run])
    else:
        print("(measured data not found: simulated sessions only)")
    from motecal.sim import simulate_session
    from synthetic import paper_sized_session
    yield "sim paper-sized (80 x 200 + sweep)", paper_sized_session(1)
    for kind in ("static80", "rotation", "idle"):
        yield f"sim {kind}", simulate_session(kind, seed=1)[1]
    idle = simulate_session("idle", seed=1, model="thermal", duration=300)[1]
    idle.label[:] = LABEL_NONE
    yield "sim idle 300 s thermal, unlabelled (as logged)", idle
    s80 = simulate_session("static80", seed=2)[1]
    x = s80.sensor("accel")
    labs = np.unique(s80.label[s80.label >= 1])
    dirs = np.array([x[s80.label == p].mean(axis=0) for p in labs])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    faces = [labs[np.argmax(dirs @ f)] for f in np.vstack([np.eye(3), -np.eye(3)])]
    yield "sim static80: the 6 poses nearest the faces", s80.select(np.isin(s80.label, faces))


def describe(b, sensor) -> str:
    sc = getattr(b, sensor)
    if sc is not None:
        return sc.model
    why = b.settings["skipped"].get(sensor) or b.settings["insufficient"].get(sensor) or ""
    state = "refused" if sensor in b.settings["insufficient"] else "skipped"
    return f"- ({state}: {why[:48]}{'...' if len(why) > 48 else ''})"


def main() -> int:
    rows, razor_ok, full80 = [], [], []
    for name, d in sessions():
        b = calibrate_board(d, seed=1, kfold=0)
        dec = decide(b)
        cells = [describe(b, s) for s in ("accel", "gyro", "mag")]
        rows.append((name, *cells, "accepted" if dec.accepted else "refused"))
        if name.endswith("faces + still"):
            razor_ok.append(dec.accepted and b.accel.model == "paper(offsets+scales)")
        if "80" in name and "faces" not in name:
            full80.append(b.accel is not None and b.accel.model == "full")
    w = [max(len(r[i]) for r in rows) for i in range(5)]
    head = ("session", "accel", "gyro", "mag", "gate")
    print("  ".join(h.ljust(w[i]) for i, h in enumerate(head)))
    for r in rows:
        print("  ".join(c.ljust(w[i]) for i, c in enumerate(r)))
    if razor_ok:
        record("Razor six-face sessions calibrated with no flags (offsets + scales, accepted)",
               "2 of 2 (#30)", sum(razor_ok), f"of {len(razor_ok)}",
               sum(razor_ok) == len(razor_ok), digits=0)
    record("80-pose sessions given the full model with no --model", "all (#30)", sum(full80),
           f"of {len(full80)}", all(full80), digits=0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
