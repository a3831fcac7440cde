"""Benchmark of the diagnosis: detection and false-alarm rates over generated
cases (prints figures next to the goals; exit 0).

Cases (``tests/plant.py``):
* planted: every (cause, sensor) of the vocabulary at a random size between
  its documented threshold and 3x it, random seed, in the session kind it
  needs (static80, idle or rotation); the diagnosis is not told what;
* clean: the paper's model only (static80, idle, rotation; static80 and idle
  also without labels, as an unguided log stores them);
* pairs: two different causes planted at once (static80).

Goals: planted cause named in >= 95 % of cases; false alarms (any finding on a
clean board) <= 5 %; both causes of a pair named in >= 95 %.  Also printed:
cases where something else was named too, and the fitted gain against the
truth's gain (median ratio per cause).
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from multiprocessing import Pool  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "host"))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))   # test helpers

import numpy as np  # noqa: E402

import plant as P  # noqa: E402
from motecal.diagnose.engine import diagnose  # noqa: E402
from results import record  # noqa: E402


SCALE = 1.0


def run_case(case):
    kind, keys, seed, labelled = case
    rng = np.random.default_rng([seed, 7919])
    plants = [P.make_plant(c, s, rng, SCALE) for c, s in keys]
    t0 = time.time()
    ses = P.simulate(plants, kind, seed, labelled=labelled)
    d = diagnose(ses, simulate=False)
    dt = time.time() - t0
    named = [(p.sensor, p.cause) in d.causes() for p in plants]
    planted = {(p.sensor, p.cause) for p in plants}
    extra = sorted(c for c in d.causes() if c not in planted)
    ratios = []
    for p, ok in zip(plants, named):
        if ok:
            f = next(f for f in d.findings if (f.sensor, f.cause) == (p.sensor, p.cause))
            tg = P.truth_gain(d, p)
            ratios.append(f.gain / tg if (tg and f.gain) else np.nan)
        else:
            ratios.append(np.nan)
    if not labelled:
        kind += " (unlabelled)"
    return {"kind": kind, "keys": keys, "seed": seed, "named": named, "extra": extra,
            "ratios": ratios, "sizes": [p.size for p in plants], "time": dt}


def _set_scale(s):
    global SCALE
    SCALE = s


def _bound(hits: list[bool], lower: bool) -> float:
    """Clopper-Pearson one-sided 95 % bound of the rate of ``hits``: lower for
    a planted cause named, upper for a clean board with any finding."""
    from scipy.stats import beta
    n, k = len(hits), sum(hits)
    if n == 0:
        return float("nan")
    if lower:
        return 0.0 if k == 0 else float(beta.ppf(0.05, k, n - k + 1))
    return 1.0 if k == n else float(beta.ppf(0.95, k + 1, n - k))


def cases(per: int, n_clean: int, n_pairs: int, seed0: int):
    out = []
    keys = list(P.THRESHOLDS)
    for i, key in enumerate(keys):
        kind = P.THRESHOLDS[key][0]
        for j in range(per):
            out.append((kind, [key], seed0 + 1000 * i + j, True))
    fifth = n_clean // 5
    kinds = [("static80", True)] * (n_clean - 3 * fifth) + [("static80", False)] * fifth + \
        [("idle", True)] * (fifth - fifth // 2) + [("idle", False)] * (fifth // 2) + \
        [("rotation", True)] * fifth
    for j, (kind, labelled) in enumerate(kinds):
        out.append((kind, [], seed0 + 900000 + j, labelled))
    static = [k for k in keys if P.THRESHOLDS[k][0] == "static80"]
    rng = np.random.default_rng(seed0)
    for j in range(n_pairs):
        while True:
            a, b = rng.choice(len(static), 2, replace=False)
            ka, kb = static[a], static[b]
            if ka[1].split("-")[0] != kb[1].split("-")[0] or ka[0] != kb[0]:
                break
        out.append(("static80", [ka, kb], seed0 + 800000 + j, True))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per", type=int, default=12, help="cases per (cause, sensor) (12)")
    ap.add_argument("--clean", type=int, default=150, help="clean cases (150)")
    ap.add_argument("--pairs", type=int, default=30, help="two-cause cases (30)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--only", help="only (cause, sensor) keys containing this text")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="plant sizes x this (e.g. 0.5 probes below the thresholds)")
    a = ap.parse_args(argv)
    global SCALE
    SCALE = a.scale
    cs = cases(a.per, a.clean, a.pairs, a.seed)
    if a.only:
        cs = [c for c in cs if c[1] and any(a.only in f"{k[0]}:{k[1]}" for k in c[1])]
    t0 = time.time()
    with Pool(a.jobs, initializer=_set_scale, initargs=(a.scale,)) as pool:
        res = pool.map(run_case, cs, chunksize=1)
    wall = time.time() - t0
    planted = [r for r in res if len(r["keys"]) == 1]
    clean = [r for r in res if not r["keys"]]
    pairs = [r for r in res if len(r["keys"]) == 2]
    print(f"diagnosis bench: {len(res)} cases ({len(planted)} planted, {len(clean)} clean, "
          f"{len(pairs)} pairs) in {wall:.0f} s wall, {np.mean([r['time'] for r in res]):.2f} "
          f"s per case")
    print()
    print(f"{'cause':<18}{'sensor':<14}{'kind':<10}{'threshold':>10}  {'named':>7}  "
          f"{'only it':>7}  {'gain/truth':>10}  other causes named")
    by = defaultdict(list)
    for r in planted:
        by[tuple(r["keys"][0])].append(r)
    for key in P.THRESHOLDS:
        rs = by.get(key, [])
        if not rs:
            continue
        named = np.mean([r["named"][0] for r in rs])
        only = np.mean([r["named"][0] and not r["extra"] for r in rs])
        ratio = np.nanmedian([r["ratios"][0] for r in rs]) if any(
            np.isfinite(r["ratios"][0]) for r in rs) else float("nan")
        others = sorted({f"{s}:{c}" for r in rs for s, c in r["extra"]})
        kind, thr, _ = P.THRESHOLDS[key]
        print(f"{key[0]:<18}{key[1]:<14}{kind:<10}{thr:>10.4g}  {100 * named:6.1f}%  "
              f"{100 * only:6.1f}%  {ratio:10.3f}  {', '.join(others)}")
    named = [bool(r["named"][0]) for r in planted]
    det = np.mean(named) if planted else float("nan")
    exact = np.mean([r["named"][0] and not r["extra"] for r in planted]) if planted else \
        float("nan")
    alarms = [bool(r["extra"]) for r in clean]
    fa = np.mean(alarms) if clean else float("nan")
    fa_kind = {k: np.mean([bool(r["extra"]) for r in clean if r["kind"] == k])
               for k in sorted({r["kind"] for r in clean})}
    both = np.mean([all(r["named"]) for r in pairs]) if pairs else float("nan")
    ratios = np.array([x for r in planted + pairs for x in r["ratios"]], float)
    ratios = ratios[np.isfinite(ratios)]
    print()
    print(f"planted cause named:        {100 * det:5.1f} %   (goal >= 95 %)  "
          f"95 % lower bound {100 * _bound(named, lower=True):.1f} %")
    print(f"  named and nothing else:   {100 * exact:5.1f} %")
    print(f"false alarms (clean boards):{100 * fa:5.1f} %   (goal <= 5 %)  "
          f"95 % upper bound {100 * _bound(alarms, lower=False):.1f} %  "
          + ", ".join(f"{r['kind']} seed {r['seed']}: {r['extra']}" for r in clean if r["extra"]))
    print("  by kind: " + ", ".join(
        f"{k} {100 * v:.1f} % of {sum(r['kind'] == k for r in clean)}" for k, v in fa_kind.items()))
    print(f"both causes of a pair named:{100 * both:5.1f} %   (goal >= 95 %)")
    for r in pairs:
        if not all(r["named"]):
            print(f"    missed in pair {r['keys']} seed {r['seed']}: named {r['named']}, "
                  f"extra {r['extra']}")
    record("diagnosis: planted cause named", ">= 95 % (#7)", 100 * det, "%", det >= 0.95,
           digits=3, note=f"{len(planted)} cases; 95 % lower bound "
                          f"{100 * _bound(named, lower=True):.1f} %")
    record("diagnosis: false alarms on clean boards", "<= 5 % (#7)", 100 * fa, "%", fa <= 0.05,
           digits=2, note=f"{sum(alarms)} of {len(clean)}; 95 % upper bound "
                          f"{100 * _bound(alarms, lower=False):.1f} %")
    record("diagnosis: both causes of a pair named", ">= 95 % (#7)", 100 * both, "%",
           both >= 0.95, digits=3, note=f"{len(pairs)} pairs")
    if len(ratios):
        record("diagnosis: fitted gain / the planted truth's gain", "", np.median(ratios), "",
               None, digits=2, note=f"median; 10-90 % {np.percentile(ratios, 10):.2f}-"
                                    f"{np.percentile(ratios, 90):.2f}")
        print(f"fitted gain / truth's gain: median {np.median(ratios):.3f}, 10-90 % "
              f"{np.percentile(ratios, 10):.3f}-{np.percentile(ratios, 90):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
