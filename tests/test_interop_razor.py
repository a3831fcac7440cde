"""The Razor AHRS user's path, end to end (issue 30, docs/interop.md "A
Razor AHRS board from its tutorial's files"): the files the Razor calibration
tutorial produces -- six accelerometer face recordings and a still gyroscope
recording as text (``sensorstick-boards/razor1``), a magnetometer sweep as
float (``sensorstick-mag-sweep``) -- imported as one session, calibrated with
no flags, exported with ``export-cal --to razor-c``, and the constants
compared with

* the magnetometer: the sweep's ``published_calibration.json`` (the Razor
  AHRS ellipsoid fit the sweep's own repository uses: calibrated = T @ (raw -
  centre));
* the accelerometer and the gyroscope: the tutorial's own method on the same
  face and still files, implemented here as the reference.  The method is
  the one the data's own repository gives (GitHub mxochicale/ros @ 6cb4b4e,
  ``mx_razor_imu_9dof/razor_calibration/Acc_Gyro_Calibration_in_R``: README.md,
  ``acc_cal.R``, ``gyr_cal.R``), after the Razor AHRS wiki's tutorial
  ("Calibrating the accelerometer": the minimum and maximum output of each
  axis for gravity; "the gyroscope": the average of each axis while still):
  ``ACCEL_<A>_MIN/MAX`` = the mean of axis A over the face file in which A
  points down / up, ``GYRO_AVERAGE_OFFSET_<A>`` = the mean of axis A over the
  still file.

Tolerances, and why:

* magnetometer centre within 1 count and the soft-iron shape (the symmetric
  part of the transform, each scaled to det 1) within 2e-3: the two are
  fits of the same model to the same readings; Razor's transform is
  symmetric, motecal's lower-triangular, the two differ by a rotation of the
  frame (printed);
* accelerometer: 256 (1 - cos t) + 0.5 counts per constant, t the face's
  tilt from its axis (from the face's mean reading, less the tutorial's own
  offsets): the tutorial takes the axis's mean as +-1 g, which reads
  cos t of it when the face is not held straight; the half count is the
  tutorial's own rounding (its constants are whole counts);
* gyroscope: twice the standard deviation of the per-file means of the seven
  still recordings: motecal's bias is the mean over every still recording,
  the tutorial's one file's, and the bias wanders between recordings.
"""
import json

import numpy as np
from scipy.linalg import polar

from motecal.commands.main import main
from motecal.sessions.importer import _parse_razor_text
from motecal.targets.razor import parse_c

FACES = ("x_neg", "x_pos", "y_neg", "y_pos", "z_neg", "z_pos")


def tutorial_constants(folder, board="razor1") -> dict:
    """The tutorial's method (module doc) on the face and still files."""
    raw = {p.stem[len(board) + 1:]: _parse_razor_text(p)[0]
           for p in sorted(folder.glob(f"{board}_*.raw"))}
    means = {f: raw[f"acc_{f}"][:, 0:3].mean(axis=0) for f in FACES}
    k, tilt = {}, {}
    for i, a in enumerate("xyz"):
        m = sorted(means[f"{a}_{s}"][i] for s in ("neg", "pos"))
        k[f"ACCEL_{a.upper()}_MIN"], k[f"ACCEL_{a.upper()}_MAX"] = m
    off = np.array([(k[f"ACCEL_{a}_MIN"] + k[f"ACCEL_{a}_MAX"]) / 2 for a in "XYZ"])
    half = np.array([(k[f"ACCEL_{a}_MAX"] - k[f"ACCEL_{a}_MIN"]) / 2 for a in "XYZ"])
    for f, m in means.items():
        i = "xyz".index(f[0])
        g = (m - off) / half
        which = "MIN" if m[i] < off[i] else "MAX"
        tilt[f"ACCEL_{f[0].upper()}_{which}"] = np.arccos(abs(g[i]) / np.linalg.norm(g))
    still = raw["gyr_xyz"][:, 3:6].mean(axis=0)
    for i, a in enumerate("XYZ"):
        k[f"GYRO_AVERAGE_OFFSET_{a}"] = still[i]
    per_file = np.array([r[:, 3:6].mean(axis=0) for r in raw.values()])
    return {"k": k, "tilt": tilt, "gyro_between_sd": per_file.std(axis=0, ddof=1)}


def test_razor_user_path(measured, tmp_path, capsys, request):
    """Import -> calibrate (no flags) -> export-cal --to razor-c, against the
    published magnetometer calibration and the tutorial's method (module
    doc); the magnetometer taken from a session of its own
    (``--mag-session``) gives the same constants.  The figures are printed
    (pytest -s) for docs/interop.md."""
    lines = []
    boards = measured / "sensorstick-boards" / "razor1"
    sweep = measured / "sensorstick-mag-sweep"
    texts = sorted(boards.glob("razor1_*.raw"))
    db, cal, out = tmp_path / "r.db", tmp_path / "cal.json", tmp_path / "razor.h"
    assert main(["import", *map(str, texts), str(sweep / "magnetom.float"), "--db", str(db),
                 "--session", "razor1"]) == 0
    text = capsys.readouterr().out
    assert "from 8 razor-text+razor-float files" in text
    assert "axes as recorded: Razor AHRS firmware board frame (every file" in text
    assert main(["calibrate", "--db", str(db), "--session", "razor1", "--out", str(cal),
                 "--seed", "1"]) == 0
    text = capsys.readouterr().out
    assert "accel    paper(offsets+scales)" in text and "mag (R)  full" in text
    assert ("accel: offsets and scales from 6 faces; cross-axis terms need at least 9 "
            "orientations spread over the sphere: add poses to fit them") in text
    assert "mag: offsets, scales and cross-axis terms from a sweep covering" in text
    assert "gate: accepted" in text
    c = json.loads(cal.read_text())
    assert c["settings"]["axis_frame"].startswith("as recorded: Razor AHRS firmware board frame")
    assert main(["export-cal", str(cal), "--to", "razor-c", "--out", str(out)]) == 0
    capsys.readouterr()
    k = parse_c(out.read_text())

    # the magnetometer against the published Razor calibration of the sweep
    pub = json.loads((sweep / "published_calibration.json").read_text())["magnetom.float"]
    centre = np.array(k["magn_ellipsoid_center"])
    d_centre = centre - np.array(pub["magn_ellipsoid_center"])
    U, P = polar(np.array(k["magn_ellipsoid_transform"]))
    T = np.array(pub["magn_ellipsoid_transform"])
    shape = np.abs(P / np.linalg.det(P) ** (1 / 3) - T / np.linalg.det(T) ** (1 / 3)).max()
    turn = np.degrees(np.arccos(np.clip((np.trace(U) - 1) / 2, -1, 1)))
    lines.append(f"magnetometer: centre - published {np.round(d_centre, 3)} counts (tolerance 1); "
          f"shape max |difference| {shape:.2e} (tolerance 2e-3); frame turned by {turn:.2f} deg "
          f"(lower-triangular vs symmetric transform)")
    assert np.all(np.abs(d_centre) < 1.0) and shape < 2e-3, lines[-1]

    # the accelerometer and the gyroscope against the tutorial's method
    ref = tutorial_constants(boards)
    for name, t in ref["tilt"].items():
        tol = 256 * (1 - np.cos(t)) + 0.5
        diff = k[name] - ref["k"][name]
        lines.append(f"{name}: motecal {k[name]:.2f}, tutorial {ref['k'][name]:.2f}, difference "
              f"{diff:+.2f} (tolerance {tol:.2f}: face tilt {np.degrees(t):.1f} deg)")
        assert abs(diff) <= tol, lines[-1]
        # on the side the tilt predicts: further out than the tutorial's mean
        assert diff < 0 if name.endswith("MIN") else diff > 0, lines[-1]
    for i, a in enumerate("XYZ"):
        name = f"GYRO_AVERAGE_OFFSET_{a}"
        tol = 2 * ref["gyro_between_sd"][i]
        diff = k[name] - ref["k"][name]
        lines.append(f"{name}: motecal {k[name]:.3f}, tutorial {ref['k'][name]:.3f}, difference "
              f"{diff:+.3f} counts (tolerance {tol:.2f}: twice the bias's sd between recordings)")
        assert abs(diff) <= tol, lines[-1]

    if request.config.getoption("capture") == "no":          # pytest -s: the figures
        with capsys.disabled():
            print("\n" + "\n".join(lines))

    # one cal.json per board whatever the sessions: the magnetometer from the
    # sweep imported as a session of its own
    assert main(["import", str(sweep / "magnetom.float"), "--db", str(db),
                 "--session", "sweep"]) == 0
    cal2 = tmp_path / "cal2.json"
    assert main(["calibrate", "--db", str(db), "--session", "razor1", "--mag-session", "sweep",
                 "--out", str(cal2), "--seed", "1", "--kfold", "0"]) == 0
    assert "magnetometer from session sweep" in capsys.readouterr().out
    c2 = json.loads(cal2.read_text())
    assert c2["settings"]["mag_session"] == "sweep"
    for s in ("accel", "gyro", "mag"):
        assert c2[s]["A"] == c[s]["A"] and c2[s]["c"] == c[s]["c"], s
