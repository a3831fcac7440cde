"""``motecal calibrate``: calibrate every board of a session, gate, save.

    motecal calibrate --db FILE --session NAME --out cal.json [--mote ID]
                      [--model paper|full] [--params offsets,scales,angles]
                      [--mag-session NAME] [--seed N] [--mag-field GAUSS]
                      [--no-gyro-matrix] [--kfold K] [--diagnosis FILE | --no-diagnosis]
                      [--force] [--upload --port URL [--baud B]]

Per sensor, the model is the richest the session's data determine
(``calib.content``'s judgement: the full model from 9 or more orientations
spread over the sphere or a sweep, offsets and scales from the six faces,
offsets alone from 4 orientations around the sphere); the summary says which
and why.  ``--model`` forces one.  ``--mag-session NAME`` takes the
magnetometer from another session of the same board (its sweep), so one
cal.json holds the board.

A diagnosis of the session (``motecal diagnose`` keeps its result with the
session) is used by default: the findings' treatments and terms, each kept
only when it lowers the held-out error (``calib.loop``); one made from
other data or by another motecal version is not used, and the summary says
so.  ``--diagnosis FILE`` uses a ``diagnose --json`` file instead,
``--no-diagnosis`` none.

Per board (mote): ``calibrate`` (board.calibrate_board) -> ``gate``
(gate.decide) -> ``deliver`` (cal.json + the database).  A further step that
needs the result is a function ``step(board, path)`` called after
``deliver`` in ``run``: ``--upload`` (``motecal.upload.calibrate_step``) sends
each delivered calibration to its mote and verifies it.

Files: one per board.  With one mote the file is ``--out`` itself; with
several, ``-mote<ID>`` goes before the extension (``cal.json`` ->
``cal-mote3.json``), or ``{mote}`` in ``--out`` is replaced by the id.

Exit status: 0 when every board is accepted (or ``--force``); 3
(QualityError) when a board is refused -- the accepted ones are still saved,
the refused ones are not.
"""
from __future__ import annotations

import sys
from pathlib import Path

from ..calib.board import calibrate_board
from ..calib.design import describe_poses_needed, session_poses_needed
from ..calib.gate import decide
from ..calib.models import MODEL_FAMILIES, parse_groups
from ..calib.result import BoardCalibration
from ..calib.loop import calibrate_with_diagnosis
from ..calib.terms import load_diagnosis
from .. import __version__
from ..errors import QualityError, UserError
from ..outputs import check_output, write_text
from ..sessions.fingerprint import data_key, rows_of
from ..sessions.store import StoreError, open_store
from .args import description, int_range, mote_id, positive, seed


MAX_KFOLD = 100          # more folds than poses leave nothing out; each one is a refit


def register(subparsers):
    p = subparsers.add_parser(
        "calibrate", help="calibrate accelerometer, gyroscope and magnetometer of a session",
        description=description(__doc__))
    p.add_argument("--db", required=True, help="database (sqlite file or URL)")
    p.add_argument("--session", required=True, help="session name")
    p.add_argument("--out", required=True, help="calibration file (cal.json); see above for "
                                                "several motes")
    p.add_argument("--mote", type=mote_id, help="calibrate only this mote")
    p.add_argument("--model", choices=MODEL_FAMILIES, default=None,
                   help="force a model for every sensor (default: per sensor, the richest "
                        "the data determine): full: bias + lower-triangular matrix; paper: "
                        "eqs. 1-5")
    p.add_argument("--mag-session", metavar="NAME",
                   help="take the magnetometer from this session of the same board (its "
                        "sweep) instead of this one's")
    p.add_argument("--params", help="paper model: comma-separated subset of "
                                    "offsets,scales,angles (default all three)")
    p.add_argument("--seed", type=seed, help="GA seed (default: random, recorded in cal.json)")
    p.add_argument("--mag-field", type=positive(float, 100.0), metavar="GAUSS",
                   help="known local field magnitude: fixes the magnetometer gauge to it "
                        "instead of det(A) = 1")
    p.add_argument("--no-gyro-matrix", action="store_true",
                   help="gyroscope bias only (no scale/misalignment from the moves)")
    p.add_argument("--kfold", type=int_range("number of folds", 0, MAX_KFOLD), default=5,
                   help=f"held-out validation folds: 0 (off) or 2..{MAX_KFOLD} (default 5)")
    dg = p.add_mutually_exclusive_group()
    dg.add_argument("--diagnosis", metavar="FILE",
                    help="use this diagnosis of the session (motecal diagnose --json) instead "
                         "of the one kept with the session: its findings' treatments and terms, "
                         "each kept when it lowers the held-out error; printed and kept in "
                         "cal.json")
    dg.add_argument("--no-diagnosis", action="store_true",
                    help="ignore any diagnosis of the session (by default the one motecal "
                         "diagnose kept with it is used)")
    p.add_argument("--force", action="store_true",
                   help="save boards the quality gate refuses (the reasons stay in cal.json)")
    from .upload import add_calibrate_options
    add_calibrate_options(p)             # --upload --port --baud: the one-step form
    p.set_defaults(func=run)
    return p


def out_path(out: str, mote: int, several: bool) -> Path:
    """File for one board (see the module doc)."""
    if "{mote}" in out:
        return Path(out.replace("{mote}", str(mote)))
    p = Path(out)
    if not several:
        return p
    return p.with_name(f"{p.stem}-mote{mote}{p.suffix}")


def calibrate(data, args, mag_data=None) -> BoardCalibration:
    groups = parse_groups(args.params)
    if groups is not None and args.model != "paper":
        raise UserError("--params selects parameter groups of --model paper")
    if args.kfold == 1:
        raise UserError("--kfold must be 0 (off) or at least 2")
    return calibrate_board(data, model=args.model, groups=groups, seed=args.seed,
                           field=args.mag_field, gyro_matrix=not args.no_gyro_matrix,
                           kfold=args.kfold, mag_data=mag_data)


def mag_session(store, args, data, mote: int):
    """The magnetometer's session for one mote (``--mag-session``): the same
    board (mote id) with the same magnetometer chip and scale as the
    calibrated session, if that one has a magnetometer at all."""
    name = getattr(args, "mag_session", None)
    if not name:
        return None
    if name == args.session:
        raise UserError("--mag-session names the session being calibrated")
    other = store.load_session(name)
    if mote not in other.motes:
        raise UserError(f"--mag-session {name}: no mote {mote} in it (motes "
                        f"{', '.join(map(str, other.motes)) or 'none'}): the magnetometer must "
                        "come from the same board")
    other = other.for_mote(mote)
    if not other.has("mag").any():
        raise UserError(f"--mag-session {name}: it holds no magnetometer readings")
    if data.has("mag").any():
        a = (data.chips or {}).get("mag"), float(data.scales["mag"])
        b = (other.chips or {}).get("mag"), float(other.scales["mag"])
        if a != b:
            raise UserError(f"--mag-session {name}: its magnetometer is {b[0]} at {b[1]:g} "
                            f"LSB/gauss, session {args.session!r}'s {a[0]} at {a[1]:g}: not "
                            "the same board's chip")
    return other


TOOL = f"motecal {__version__}"


def pick_diagnosis(args, store, data, mote) -> tuple[dict | None, dict]:
    """The diagnosis to use for one mote and where it came from: ``--diagnosis
    FILE``; none with ``--no-diagnosis``; else the latest kept with the
    session, when it was made from these very rows by this motecal version
    (otherwise not used, and ``source["not_used"]`` says why)."""
    if getattr(args, "no_diagnosis", False):
        return None, {"not_used": "--no-diagnosis"}
    if getattr(args, "diagnosis", None):
        return load_diagnosis(args.diagnosis), {"file": str(args.diagnosis)}
    rec = store.load_diagnosis(args.session, mote)
    if rec is None:
        return None, {"not_used": "none kept with the session (motecal diagnose keeps one)"}
    src = {"kept": rec["id"], "created": rec["created"], "tool": rec["tool"]}
    what = f"the diagnosis of {rec['created']} ({rec['tool']})"
    if not isinstance(rec["diagnosis"], dict) or not isinstance(
            rec["diagnosis"].get("findings"), list):
        return None, dict(src, not_used=f"{what} is not readable; run motecal diagnose again")
    if rec["data_key"] != data_key(data):
        then, now = rows_of(rec["data_key"]), len(data)
        return None, dict(src, not_used=(
            f"{what} was made from other data ({then} rows then, {now} now): run motecal "
            "diagnose again"))
    if rec["tool"] != TOOL:
        return None, dict(src, not_used=f"{what} was made by another version (this is {TOOL}): "
                                        "run motecal diagnose again")
    return rec["diagnosis"], src


def deliver(board: BoardCalibration, args, store, path: Path) -> int | None:
    """Write cal.json (``outputs.write_text``: never over the database, a
    device or half-written) and record the calibration in the database;
    returns its id, or None when the database cannot take it (read-only
    media, full disk: cal.json is written all the same, and a note says so)."""
    write_text(path, board.dumps(), inputs=[args.db], what="--out")
    if store.readonly:
        return None
    try:
        return store.save_calibration(board.session, board.mote, board.to_json())
    except StoreError as e:
        print(f"  note: not recorded in the database: {e}", file=sys.stderr)
        return None


def _fmt(x, spec=".3e"):
    return "-" if x is None else format(x, spec)


def diagnosis_lines(dg: dict) -> list:
    """What the summary says about the diagnosis used (``settings.diagnosis``)."""
    if "file" in dg:
        head = f"  diagnosis {dg['file']}"
    elif "kept" in dg:
        head = f"  diagnosis of {dg.get('created')} ({dg.get('tool')}), kept with the session"
    else:
        head = "  diagnosis"
    if "used" not in dg:
        return [f"{head}: not used: {dg.get('not_used')}"]
    out = [f"{head}:" + ("" if dg["used"] else " nothing used")]
    out += [f"    used: {u}" for u in dg["used"]]
    out += [f"    not used: {u}" for u in dg.get("not_used") or []]
    return out


def summary(board: BoardCalibration) -> str:
    """What ``calibrate`` prints for one board."""
    s = board.settings
    lines = [f"mote {board.mote}  session {board.session}  model {s.get('model')}"
             + (f" ({','.join(s['params'])})" if s.get("params") else "")
             + (f"  magnetometer from session {s['mag_session']}" if s.get("mag_session")
                else "")
             + f"  seed {s.get('seed')}",
             f"  {'sensor':<9}{'model':<28}{'n':>7}  {'mse before':>10}  {'mse after':>10}  "
             f"{'held-out':>10}  {'|v| before':>13}  {'|v| after':>13}"]
    for name, sc in board.sensors():
        label = name + (f" ({sc.dataset})" if name == "mag" else "")
        ho = sc.validation.get("mse_heldout") if sc.validation else None
        lines.append(f"  {label:<9}{sc.model:<28}{sc.n_samples:>7}  {_fmt(sc.mse_before):>10}  "
                     f"{_fmt(sc.mse_after):>10}  {_fmt(ho):>10}  "
                     f"{sc.min_before:6.3f}-{sc.max_before:<6.3f}  "
                     f"{sc.min_after:6.3f}-{sc.max_after:<6.3f} {sc.unit}")
    if board.mag is not None and board.mag.field_gauss is not None:
        sd = board.mag.field_std
        lines.append(f"  magnetometer field {board.mag.field_gauss:.4f}"
                     + (f" +- {sd:.1e}" if sd else " (given)") + " gauss"
                     + "".join(f"; set {k}: {v['field_gauss']:.4f}"
                               for k, v in board.mag_sets.items() if not v.get("used")))
    if s.get("diagnosis"):
        lines += diagnosis_lines(s["diagnosis"])
    if s.get("poses_found"):
        lines.append(f"  session: {s['poses_found']}")
    for name, sc in board.sensors():
        for n in sc.notes:
            lines.append(f"  {name}: {n}")
    if board.accel is not None and board.accel.quality.get("poses_needed"):
        lines += describe_poses_needed(board.accel.quality["poses_needed"])
    g = board.gate
    if g:
        state = "accepted" if g.get("accepted") else ("refused, saved anyway (--force)"
                                                    if g.get("forced") else "refused")
        lines.append(f"  gate: {state}")
        for r in g.get("reasons", []):
            lines.append(f"    reason: {r}")
        for w in g.get("warnings", []):
            lines.append(f"    warning: {w}")
    return "\n".join(lines)


def run(args) -> int:
    from .upload import calibrate_step
    step = calibrate_step(args)          # None without --upload; checks the port first
    with open_store(args.db) as store:
        data = store.load_session(args.session, args.mote)
        motes = [args.mote] if args.mote is not None else data.motes
        if not motes or len(data) == 0:
            raise UserError(f"session {args.session!r} has no samples")
        several = len(motes) > 1
        for m in motes:                  # every output checked before any work
            check_output(out_path(args.out, m, several), inputs=[args.db], what="--out")
        refused = []
        if getattr(args, "diagnosis", None):
            load_diagnosis(args.diagnosis)           # a bad file: one line before any work
        mags = {m: mag_session(store, args, data.for_mote(m), m) for m in motes}
        for m in motes:
            dm = data.for_mote(m)
            mag = mags[m]
            diag, source = pick_diagnosis(args, store, dm, m)
            if diag is not None:
                board, rep = calibrate_with_diagnosis(dm, diag,
                                                      lambda d: calibrate(d, args, mag),
                                                      kfold=args.kfold)
                source = dict(source, **rep)
            else:
                board = calibrate(dm, args, mag)
            board.settings["diagnosis"] = source
            session_poses_needed(board, dm)
            decision = decide(board, force=args.force)
            print(summary(board))
            if not decision.accepted and not args.force:
                refused.append(f"mote {m}: " + "; ".join(decision.reasons))
                print(f"  not saved (refused; --force saves it anyway)")
                continue
            path = out_path(args.out, m, several)
            cid = deliver(board, args, store, path)
            print(f"  wrote {path} " + (f"(database calibration {cid})" if cid is not None
                                        else "(not recorded in the database: it is read-only)"
                                        if store.readonly else
                                        "(not recorded in the database)"))
            if step is not None:
                step(board, path)
    sys.stdout.flush()
    if refused:
        raise QualityError("calibration refused: " + " | ".join(refused))
    return 0
