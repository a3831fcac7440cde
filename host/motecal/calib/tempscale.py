"""The gyroscope's sensitivity against temperature, from the moves between
still poses whose temperatures span ``content.MIN_TEMP_SPAN_C`` (issue 16;
``calib.thermal`` adds it to the gyroscope's temperature model when it is
determined): the rotation each move integrates, scaled by 1 + s dT, must
turn one pose's gravity direction into the next's.
"""
from __future__ import annotations

import numpy as np

from ..sessions.session import SessionData
from .content import MIN_TEMP_SPAN_C, recording_parts
from .result import TempModel

FOLDS = 5                  # held-out folds of the temperature fits (here and calib.thermal)
SCALE_STD_LIMIT = 4e-4      # 1/C: half the ITG-3200's worst (0.08 %/C); tighter is rarely met


def _move_residuals(ms, G, b_moves, scale):
    """Gravity direction errors (n, 3) of the moves with a bias and an
    output-axis scale per move (``scale`` (n, 3))."""
    from . import gyro as _g
    rate = np.einsum("nlj,ij->nli", ms.wm - b_moves[:, None, :], G) * scale[:, None, :]
    q = _g._rotvec_quat(np.deg2rad(rate) * ms.dt[..., None])
    while q.shape[1] > 1:
        q = _g._qmul(q[:, 0::2], q[:, 1::2])
    return _g._rotate_inv(q[:, 0], ms.a0) - ms.a1


def gyro_scale_fit(board, main: SessionData, tm: TempModel) -> dict:
    """The gyroscope's relative sensitivity per C and output axis from the
    moves between still poses (the ones its matrix was fitted on) whose
    temperatures span ``MIN_TEMP_SPAN_C``: the rotation each move integrates,
    scaled by 1 + s dT, must turn one pose's gravity direction into the
    next's.  Linearised around s = 0 (the static fit's G, the temperature
    model's bias per move), least squares, 5 interleaved folds of moves.
    ``{"s", "std", "why" (None: usable), ...}``."""
    from . import gyro as _g
    from ..maths.sphere import unit
    sc, acc = board.gyro, board.accel
    if sc is None or acc is None or sc.model != "bias+matrix":
        return {"why": "no scale and misalignment fit from moves"}
    lsb = main.scales["gyro"]
    G = sc.A * lsb
    b = -np.linalg.solve(G, sc.c)
    slope_raw = -np.linalg.solve(G, tm.offset_per_c)          # raw deg/s per C
    grav, ptemp = {}, {}
    x = main.sensor("accel")
    for p in np.unique(main.label[main.label >= 1]):
        sel = (main.label == p) & main.has("accel")
        if sel.any():
            grav[int(p)] = unit(acc.apply(x[sel].mean(axis=0)[None])[0])
            T = main.temp[sel]
            ptemp[int(p)] = float(np.nanmean(T)) if np.isfinite(T).any() else np.nan
    moves = _g.find_moves(main.label, main.sample_times(), main.seq, main.sensor("gyro") / lsb,
                          main.sensor("gyro"), grav, main.meta.get("rate_hz") or 125.0,
                          part=recording_parts(main))
    temp = np.array([0.5 * (ptemp[m.pose0] + ptemp[m.pose1]) for m in moves]) if moves \
        else np.empty(0)
    ok = np.isfinite(temp)
    moves = [m for m, k in zip(moves, ok) if k]
    temp = temp[ok]
    if len(moves) < _g.MIN_MOVES or float(np.ptp(temp)) < MIN_TEMP_SPAN_C:
        return {"why": f"{len(moves)} moves over {float(np.ptp(temp)) if len(temp) else 0:.2f} C "
                       f"(needs {_g.MIN_MOVES} over {MIN_TEMP_SPAN_C:g} C)"}
    ms = _g.MoveSet(moves)
    dT = tm.dt(temp)
    bm = b + np.outer(dT, slope_raw)
    one = np.ones((len(moves), 3))
    r0 = _move_residuals(ms, G, bm, one)
    eps = 1e-4
    J = np.stack([((_move_residuals(ms, G, bm, one + eps * np.outer(dT, np.eye(3)[i])) - r0)
                   / eps) for i in range(3)], axis=-1)                # (n, 3, 3)
    Jf, rf = J.reshape(-1, 3), r0.reshape(-1)

    def solve(rows):
        s, *_ = np.linalg.lstsq(Jf[rows], -rf[rows], rcond=None)
        return s
    s = solve(np.ones(len(rf), bool))
    res = rf + Jf @ s
    dof = max(1, len(rf) - 3)
    cov = np.linalg.pinv(Jf.T @ Jf) * float(res @ res) / dof
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    fold = np.repeat(np.arange(len(moves)) % FOLDS, 3)
    before = after = 0.0
    for f in range(FOLDS):
        te = fold == f
        sf = solve(~te)
        before += float(rf[te] @ rf[te])
        after += float(np.sum((rf[te] + Jf[te] @ sf) ** 2))
    out = {"s": s, "std": std, "moves": len(moves), "span_c": float(np.ptp(temp)),
           "heldout_rms_deg_before": float(np.degrees(np.sqrt(before / len(rf)))),
           "heldout_rms_deg_after": float(np.degrees(np.sqrt(after / len(rf))))}
    if std.max() > SCALE_STD_LIMIT:
        out["why"] = f"poorly determined: std {std.max():.2g} /C (limit {SCALE_STD_LIMIT:g})"
    elif not after < before:
        out["why"] = "it does not predict held-out moves better"
    else:
        out["why"] = None
    return out
