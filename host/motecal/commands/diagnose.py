"""``motecal diagnose``: what the simulation gets wrong, why, the extended
model and its gain.

    motecal diagnose --db FILE --session NAME [--mote ID] [--json OUT]
                     [--report DIR] [--model-out extended.json]
                     [--alpha A] [--seed N] [--no-sim]

Prints one paragraph per finding (ending with its held-out gain).  With
several motes and no ``--mote`` every mote is diagnosed and the output
files get ``-mote<ID>`` before their extension (as ``motecal calibrate``).
"""
from __future__ import annotations

import json
import os
import sys
import textwrap
from pathlib import Path

from ..diagnose.gain import DEFAULT_ALPHA, MIN_FOLD_WINS, per_test_alpha
from ..errors import UserError
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
    p.set_defaults(func=run)
    return p


def _fmt(v):
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def render(d) -> str:
    """The human-readable summary of one diagnosis."""
    out = [f"session {d.session}  mote {d.mote}  kind {d.kind}"]
    level = per_test_alpha(d.alpha, d.n_tests)
    comp = d.comparison or {}
    whole = comp.get("whole")
    out.append("")
    out.append("1. What the simulation gets wrong (the paper's model fitted to the session, "
               "the session simulated with it):")
    if whole:
        rows = {(r["sensor"], r["statistic"]): r for r in whole["table"]}
        worst = sorted(whole["per_stat"].items(), key=lambda kv: -kv[1])[:8]
        out.append(f"   {'statistic':<28}{'measured':>12}{'simulated':>12}  distance")
        for key, dist in worst:
            s, k = key.split(".", 1)
            r = rows.get((s, k), {})
            out.append(f"   {s + ' ' + k:<28}{_fmt(r.get('measured')):>12}"
                       f"{_fmt(r.get('simulated_paper')):>12}  {dist:.2f}")
        out.append(f"   overall distance {whole['distance_paper']:.3f} "
                   f"(rms |log measured/simulated| over {len(whole['per_stat'])} statistics)")
    else:
        out.append("   (no simulation: " + comp.get("note", "--no-sim") + ")")
    out.append("")
    out.append(f"2-4. Causes, extension and gain ({d.n_tests} tests; a finding needs "
               f"p < {d.alpha:g}/{d.n_tests} = {level:.2g}, and a fitted term a held-out "
               f"gain > 1 in >= {MIN_FOLD_WINS} of 5 folds):")
    if d.clean:
        out.append("   clean: nothing beyond the paper's starting model.")
    for f in d.findings:
        out.append("")
        out.append(textwrap.fill(f"[{f.sensor}] {f.cause}: {f.summary}", width=96,
                                 initial_indent="   ", subsequent_indent="   "))
    ho = comp.get("heldout")
    if ho and "distance_extended" in ho:
        out.append("")
        out.append(f"   Simulated statistics on the held-out half: distance "
                   f"{ho['distance_paper']:.3f} (paper) -> {ho['distance_extended']:.3f} "
                   f"(extended)" + (f", {ho['gain']:.3g}x closer." if ho.get("gain") else "."))
    for n in d.notes:
        out.append(textwrap.fill("note: " + n, width=96, initial_indent="   ",
                                 subsequent_indent="         "))
    return "\n".join(out)


def _write_json(path: Path, obj):
    try:
        path.write_text(json.dumps(obj, indent=1) + "\n", encoding="utf-8")
    except OSError as e:
        raise UserError(f"cannot write {path}: {e.strerror or e}") from None


def run(args) -> int:
    from .calibrate import out_path
    from ..sessions.store import open_store
    from ..diagnose.engine import diagnose
    for opt in ("json", "model_out"):
        v = getattr(args, opt)
        if v:
            folder = os.path.dirname(os.path.abspath(v))
            if not os.path.isdir(folder):
                raise UserError(f"--{opt.replace('_', '-')} {v}: folder {folder} does not exist")
    with open_store(args.db) as store:
        data = store.load_session(args.session, args.mote)
    if len(data) == 0:
        raise UserError(f"session {args.session!r} has no samples"
                        + (f" for mote {args.mote}" if args.mote is not None else ""))
    motes = data.motes
    several = len(motes) > 1
    for m in motes:
        d = diagnose(data.for_mote(m), alpha=args.alpha, seed=args.seed,
                     simulate=not args.no_sim)
        print(render(d))
        if args.json:
            _write_json(out_path(args.json, m, several), d.to_json())
        if args.model_out:
            p = out_path(args.model_out, m, several)
            _write_json(p, d.model)
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
