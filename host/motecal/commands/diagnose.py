"""``motecal diagnose``: what the simulation gets wrong, why, the extended
model and its gain.

    motecal diagnose --db FILE --session NAME [--mote ID] [--json OUT]
                     [--report DIR] [--model-out extended.json]
                     [--alpha A] [--seed N] [--no-sim] [--no-keep]

Prints one paragraph per finding (ending with its held-out gain).  The
diagnosis is kept with the session in the database (with the motecal version
and the fingerprint of the rows it saw): ``motecal calibrate`` uses it by
default; ``--no-keep`` leaves the database as it was.  With
several motes and no ``--mote`` every mote is diagnosed and the output
files get ``-mote<ID>`` before their extension (as ``motecal calibrate``).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..diagnose.gain import DEFAULT_ALPHA
from ..diagnose.summary import render
from ..errors import UserError
from ..outputs import check_output, check_output_dir, write_text
from .args import between, description, mote_id, seed


def register(subparsers):
    p = subparsers.add_parser(
        "diagnose", help="what the simulation gets wrong, the cause, the extended model, "
                         "the gain", description=description(__doc__))
    p.add_argument("--db", required=True, help="database (sqlite file or URL)")
    p.add_argument("--session", required=True, help="session name")
    p.add_argument("--mote", type=mote_id, help="diagnose only this mote")
    p.add_argument("--json", metavar="OUT", help="write {clean, findings, model} as JSON")
    p.add_argument("--report", metavar="DIR", help="write evidence pictures and the full "
                                                     "diagnosis (diagnosis.json) into DIR")
    p.add_argument("--model-out", metavar="FILE",
                   help="write the extended simulator model (motecal sim --model FILE)")
    p.add_argument("--alpha", type=between(0.0, 1.0), default=DEFAULT_ALPHA,
                   help=f"false-alarm level for the whole diagnosis ({DEFAULT_ALPHA})")
    p.add_argument("--seed", type=seed, default=0, help="simulation seed (0)")
    p.add_argument("--no-sim", action="store_true",
                   help="skip the side-by-side simulation (statistics comparison)")
    p.add_argument("--no-keep", action="store_true",
                   help="do not keep the diagnosis with the session (calibrate uses a kept "
                        "one by default)")
    p.set_defaults(func=run)
    return p


def _write_json(path: Path, obj, inputs=()):
    write_text(path, json.dumps(obj, indent=1) + "\n", inputs=inputs)


def keep(args, mote, diagnosis: dict, data) -> None:
    """Keep the diagnosis with the session (``Store.save_diagnosis``), with
    the version and the rows' fingerprint; a database that cannot take it
    (read-only) gets a note, and nothing else changes."""
    from .. import __version__
    from ..sessions.fingerprint import data_key
    from ..sessions.store import StoreError, open_store
    try:
        with open_store(args.db) as store:
            if store.readonly:
                print("   not kept with the session: the database is read-only")
                return
            i = store.save_diagnosis(args.session, mote, diagnosis, tool=f"motecal {__version__}",
                                     data_key=data_key(data))
    except StoreError as e:
        print(f"   note: not kept with the session: {e}", file=sys.stderr)
        return
    print(f"   kept with the session (database diagnosis {i}): motecal calibrate uses it "
          "by default")


def run(args) -> int:
    from .calibrate import out_path
    from ..sessions.store import open_store
    from ..diagnose.engine import diagnose
    inputs = [args.db]
    for opt in ("json", "model_out"):
        v = getattr(args, opt)
        if v:
            check_output(v, inputs=inputs, what=f"--{opt.replace('_', '-')}")
            inputs.append(v)             # --json and --model-out must differ too
    if args.report:
        check_output_dir(args.report, inputs=[args.db], what="--report")
    with open_store(args.db, readonly=True) as store:
        data = store.load_session(args.session, args.mote)
    if len(data) == 0:
        raise UserError(f"session {args.session!r} has no samples"
                        + (f" for mote {args.mote}" if args.mote is not None else ""))
    motes = data.motes
    several = len(motes) > 1
    for m in motes:
        dm = data.for_mote(m)
        d = diagnose(dm, alpha=args.alpha, seed=args.seed, simulate=not args.no_sim)
        print(render(d))
        if not args.no_keep:
            keep(args, m, d.to_json(), dm)
        if args.json:
            _write_json(out_path(args.json, m, several), d.to_json(), [args.db, args.model_out])
        if args.model_out:
            p = out_path(args.model_out, m, several)
            _write_json(p, d.model, [args.db, args.json])
            print(f"   extended model written to {p} (motecal sim --model {p})")
        if args.report:
            from ..diagnose.plots import write_report
            folder = Path(args.report) / (f"mote{m}" if several else "")
            files = write_report(d, data.for_mote(m), folder)
            print(f"   report: {len(files)} files in {folder}")
        if several:
            print()
    sys.stdout.flush()
    return 0
