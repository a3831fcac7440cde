"""Test data in other tools' shapes, with planted truths (tests/test_interop_*.py).

``ferraris(seed)``: a Ferraris session of a 6-DOF board: six faces held
still, then a 360-degree turn by hand about the vertical on the x_p, y_p and
z_p faces; planted accelerometer offsets and scales (counts = s * 2048 * a +
o) and gyroscope bias and matrix (w_cal = G (raw / 16.4 - b)).  Writers put
it in imucal's annotated CSV (counts) or its continuous session CSV (m/s^2
at g = 9.81 and deg/s, imucal's example) with the section list.

``turntable(seed)``: FreeIMU-cal's gyroscope turntable log (rad/s, three
numbers a line) at 33 1/3 rpm with the board on three faces, rests between.
"""
from __future__ import annotations

import json
import lzma
from pathlib import Path

import numpy as np

ACC_LSB, GYR_LSB = 2048.0, 16.4
IMUCAL_DIR = Path(__file__).resolve().parent / "data" / "imucal"
FACES = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")


def imucal_annotated(tmp_path) -> Path:
    """imucal's own example session (MIT, tests/data/imucal), decompressed."""
    out = Path(tmp_path) / "annotated_session.csv"
    out.write_bytes(lzma.decompress((IMUCAL_DIR / "annotated_session.csv.xz").read_bytes()))
    return out


def imucal_published() -> dict:
    return json.loads((IMUCAL_DIR / "published_cal.json").read_text())


def ferraris(seed: int, rate=200.0, hold_s=2.0, turn_s=3.0, acc_noise=3.0, gyr_noise=0.5,
             sign=+1):
    rng = np.random.default_rng(seed)
    s_acc = rng.uniform(0.97, 1.03, 3)
    o_acc = rng.uniform(-60, 60, 3)
    G = np.eye(3) + np.diag(rng.uniform(-0.03, 0.03, 3)) \
        + (1 - np.eye(3)) * rng.uniform(-0.01, 0.01, (3, 3))
    b = rng.uniform(-3, 3, 3)                           # deg/s, nominal
    Ginv = np.linalg.inv(G)
    acc, gyr, parts = [], [], []

    def add(a_g, w_dps, part):
        n = len(a_g)
        acc.append(s_acc * ACC_LSB * a_g + o_acc + rng.normal(0, acc_noise, (n, 3)))
        gyr.append(GYR_LSB * (w_dps @ Ginv.T + b) + rng.normal(0, gyr_noise, (n, 3)))
        parts.extend([part] * n)

    nh = int(hold_s * rate)
    for f in FACES:
        up = np.eye(3)["xyz".index(f[0])] * (1 if f[2] == "p" else -1)
        add(np.tile(up, (nh, 1)), np.zeros((nh, 3)), f)
    nt = int(turn_s * rate)
    tt = np.arange(nt) / rate
    prof = 360.0 / turn_s * (1 - np.cos(2 * np.pi * tt / turn_s))     # integrates to 360
    for ax in "xyz":
        up = np.eye(3)["xyz".index(ax)]
        quiet = int(0.5 * rate)
        w = np.vstack([np.zeros((quiet, 3)), sign * prof[:, None] * up, np.zeros((quiet, 3))])
        add(np.tile(up, (len(w), 1)), w, f"{ax}_rot")
    acc = np.rint(np.vstack(acc))
    gyr = np.rint(np.vstack(gyr))
    return {"acc": acc, "gyr": gyr, "parts": parts, "rate": rate, "s_acc": s_acc,
            "o_acc": o_acc, "G": G, "b": b}


def write_annotated(sess, path, order_by_part=True) -> Path:
    """imucal's annotated CSV: part,samples,acc_*,gyr_* (rows grouped by part,
    as imucal writes them)."""
    n = len(sess["parts"])
    idx = sorted(range(n), key=lambda i: (sess["parts"][i], i)) if order_by_part else range(n)
    lines = ["part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z"]
    for i in idx:
        a, g = sess["acc"][i], sess["gyr"][i]
        lines.append(f"{sess['parts'][i]},{i},"
                     + ",".join(f"{v:.1f}" for v in np.concatenate([a, g])))
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def write_session(sess, path, gravity=9.81, with_list=True):
    """imucal's continuous session: n_samples,gyr_*,acc_* in deg/s and m/s^2
    (imucal's example: 16 g range at g = 9.81 and 2000 deg/s on 16 bits),
    and the section list ``<stem>_list.json``."""
    acc = sess["acc"] * gravity / ACC_LSB
    gyr = sess["gyr"] / GYR_LSB
    lines = ["n_samples,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z"]
    for i in range(len(acc)):
        lines.append(f"{i}," + ",".join(repr(float(v)) for v in np.concatenate([gyr[i], acc[i]])))
    Path(path).write_text("\n".join(lines) + "\n")
    sections = {}
    for i, p in enumerate(sess["parts"]):
        a, b = sections.get(p, (i, i))
        sections[p] = (a, i + 1)
    lst = Path(path).with_name(Path(path).stem + "_list.json")
    if with_list:
        lst.write_text(json.dumps({k: {"start": a, "end": b} for k, (a, b) in sections.items()}))
    return Path(path), lst


GYR_STEP_DPS = 0.07                          # FreeIMU-cal's example: 70 mdps per LSB


def turntable(seed: int, rpm=100.0 / 3, rate=100.0, turn_s=20.0, rest_s=5.0, noise=0.6):
    """Gyro-only turntable runs: rest, then turn on the z, x and y faces, with
    planted per-axis scales k (w_cal = k * (raw - b)) and bias b."""
    rng = np.random.default_rng(seed)
    k = rng.uniform(0.97, 1.03, 3)
    b = rng.uniform(-1.5, 1.5, 3)
    w_true = rpm * 6.0
    rows = []
    nr, nt = int(rest_s * rate), int(turn_s * rate)
    lsb = 1 / GYR_STEP_DPS
    for ax in "zxy":
        rows.append(np.tile(b, (nr, 1)))
        e = np.eye(3)["xyz".index(ax)] * rng.choice([-1, 1])
        rows.append(np.tile(w_true * e / k + b, (nt, 1)))
    w = np.vstack(rows)
    counts = np.rint(w * lsb + rng.normal(0, noise, w.shape))
    return {"counts": counts, "rad_s": np.deg2rad(counts / lsb), "k": k, "b": b,
            "rate_dps": w_true, "rate": rate, "lsb": lsb}


def write_float_log(values, path, fmt="{:.6f}") -> Path:
    Path(path).write_text("\n".join(" ".join(fmt.format(v) for v in row) for row in values)
                          + "\n")
    return Path(path)


def turntable6(seed: int, rpm=100.0 / 3, rate=100.0, steady_s=10.0, hold_s=3.0):
    """A 6-DOF board: six faces held still, then turned on the platter lying on
    its x_p, y_p and z_p faces (spin up 1 s, steady, spin down 1 s); planted
    accelerometer offsets/scales and gyroscope bias and matrix G
    (w_cal = G (raw / lsb - b)).  Floats: m/s^2 (2048 LSB/g) and rad/s
    (0.07 deg/s per LSB), as FreeIMU-cal logs them, six columns a line."""
    rng = np.random.default_rng(seed)
    lsb_g = 1 / GYR_STEP_DPS
    s_acc = rng.uniform(0.97, 1.03, 3)
    o_acc = rng.uniform(-60, 60, 3)
    G = np.eye(3) + np.diag(rng.uniform(-0.03, 0.03, 3)) \
        + (1 - np.eye(3)) * rng.uniform(-0.01, 0.01, (3, 3))
    b = rng.uniform(-1.5, 1.5, 3)
    Ginv = np.linalg.inv(G)
    acc, gyr = [], []

    def add(up, w):
        n = len(w)
        acc.append(s_acc * ACC_LSB * np.tile(up, (n, 1)) + o_acc + rng.normal(0, 3, (n, 3)))
        gyr.append(lsb_g * (w @ Ginv.T + b) + rng.normal(0, 0.6, (n, 3)))

    nh = int(hold_s * rate)
    for f in FACES:
        up = np.eye(3)["xyz".index(f[0])] * (1 if f[2] == "p" else -1)
        add(up, np.zeros((nh, 3)))
    w0 = rpm * 6.0
    ramp = np.linspace(0, 1, int(rate))[:, None]
    for ax in "xyz":
        up = np.eye(3)["xyz".index(ax)]
        sign = rng.choice([-1, 1])
        prof = np.vstack([ramp, np.ones((int(steady_s * rate), 1)), ramp[::-1]])
        add(up, sign * w0 * prof * up)
        add(up, np.zeros((nh, 3)))
    acc, gyr = np.rint(np.vstack(acc)), np.rint(np.vstack(gyr))
    floats = np.hstack([acc * 9.80665 / ACC_LSB, np.deg2rad(gyr / lsb_g)])
    return {"floats": floats, "acc": acc, "gyr": gyr, "G": G, "b": b, "rate": rate,
            "rate_dps": w0, "lsb": lsb_g}
