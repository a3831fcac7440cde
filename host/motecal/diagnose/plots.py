"""Evidence pictures for ``motecal diagnose --report DIR``: one PNG per
finding (the residual against what the cause depends on, before and after
the term), one for the statistics comparison, plus ``diagnosis.json`` (every
test, the comparison tables, notes) and ``summary.txt``."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..maths.sphere import unit
from . import fitting as F
from . import thermal as TH
from . import structure as ST


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _magnitude_panels(ax, st, cause, o):
    pts = st.points
    X, T = pts["X"], pts["T"]
    r0 = st.fit0.residuals(X, T)
    r1 = st.fit.residuals(X, T)
    without = st.fits.get(frozenset(c for c in st.accepted if ST.cause_of(c) != cause))
    rw = without.residuals(X, T) if without is not None else r0
    u = unit(st.fit.calibrate(X, T))
    if cause == "cross_axis":
        A, c, H = st.fit.affine()
        M = np.linalg.inv(A)
        Cm = M / np.diag(M)[:, None] - np.eye(3)
        np.fill_diagonal(Cm, 0)
        i, j = np.unravel_index(np.argmax(np.abs(Cm + Cm.T)), Cm.shape)
        xv, xl = u[:, i] * u[:, j], f"u_{'xyz'[i]} u_{'xyz'[j]} (direction product)"
    elif cause == "nonlinearity":
        e, p = [(e, p) for e, p in zip(st.fit.extras, st.fit.split()[1])
                if e.cause == "nonlinearity"][0]
        a = int(np.argmax(np.abs(p)) % 3)
        xv, xl = u[:, a], f"u_{'xyz'[a]} (reading along the axis / magnitude)"
    else:
        xv, xl = T - T.min(), "time (s)"
    ax[0].plot(xv, rw, ".", ms=3, label=f"without {cause}")
    ax[0].plot(xv, r1, ".", ms=3, label="extended model")
    ax[0].set_xlabel(xl)
    ax[0].set_ylabel(f"magnitude residual ({st.unit})")
    ax[0].legend(fontsize=7)
    if cause in ("bias_drift", "field_disturbance"):
        sd = np.sqrt(st.points["V"])
        bins = np.linspace(-6, 6, 49)
        ax[1].hist(np.clip(rw / sd, -6, 6), bins=bins, alpha=0.6, label=f"without {cause}")
        ax[1].hist(np.clip(r1 / sd, -6, 6), bins=bins, alpha=0.6, label="extended model")
        ax[1].set_xlabel("residual / its noise")
        ax[1].legend(fontsize=7)
    else:
        ax[1].plot(T - T.min(), rw, ".", ms=3, label=f"without {cause}")
        ax[1].plot(T - T.min(), r1, ".", ms=3, label="extended model")
        ax[1].set_xlabel("time (s)")
        ax[1].set_ylabel(f"residual ({st.unit})")


def _linear_panels(ax, st, cause, o):
    pts = st.points
    Xd, _, _ = ST._design(pts, frozenset(st.accepted), pts["trange"])
    r1 = (pts["Y"] - Xd @ st.fit.beta) / o.K
    spec = frozenset(c for c in st.accepted if ST.cause_of(c) != cause)
    Xw, _, _ = ST._design(pts, spec, pts["trange"])
    rw = (pts["Y"] - Xw @ st.fits[spec].beta) / o.K if spec in st.fits else r1
    T = pts["T"] - pts["T"].min()
    if cause == "g_sensitivity" and pts["F"] is not None:
        Gm = st.fit.beta[st.fit.groups["g_sensitivity"]].T
        i, j = np.unravel_index(np.argmax(np.abs(Gm)), Gm.shape)
        ax[0].plot(pts["F"][:, j], rw[:, i], ".", ms=3, label="without g_sensitivity")
        ax[0].plot(pts["F"][:, j], r1[:, i], ".", ms=3, label="extended model")
        ax[0].set_xlabel(f"specific force {'xyz'[j]} (g)")
        ax[0].set_ylabel(f"gyro {'xyz'[i]} residual ({st.unit})")
    else:
        for a in range(3):
            ax[0].plot(T, rw[:, a], ".", ms=3, label=f"{'xyz'[a]} without {cause}")
        ax[0].set_xlabel("time (s)")
        ax[0].set_ylabel(f"block mean residual ({st.unit})")
    ax[0].legend(fontsize=7)
    for a in range(3):
        ax[1].plot(T, r1[:, a], ".", ms=3, label="xyz"[a])
    ax[1].set_xlabel("time (s)")
    ax[1].set_ylabel(f"residual, extended ({st.unit})")


def _screen_panels(ax, f, d, data):
    o = d.obs.get(f.sensor)
    if f.cause == "stale_samples" and o is not None:
        same = np.all(o.x[1:] == o.x[:-1], axis=1)
        runs, k = [], 0
        for v in same:
            if v:
                k += 1
            elif k:
                runs.append(k)
                k = 0
        ax[0].hist(runs or [0], bins=np.arange(0, 12) - 0.5)
        ax[0].set_xlabel("repeats in a row")
        ax[0].set_ylabel("count")
        ax[1].bar(["lag 1", "lag 2", "chance"], [f.evidence.get("repeat_fraction", 0),
                                                f.evidence.get("repeat_fraction_lag2", 0),
                                                f.evidence.get("chance_fraction", 0)])
        ax[1].set_ylabel("fraction of readings equal")
    elif f.cause == "saturation" and o is not None:
        lim = f.evidence.get("limits") or []
        if lim:
            h = lim[0]
            a = "xyz".index(h["axis"])
            L = h["limit_counts"]
            sgn = 1 if h["side"] == "high" else -1
            v = o.x[:, a]
            near = v[np.abs(v - L) <= 60]
            ax[0].hist(near, bins=np.arange(L - 60.5 if sgn > 0 else L - 0.5,
                                            L + 0.5 if sgn > 0 else L + 60.5))
            ax[0].set_xlabel(f"{f.sensor} {h['axis']} (counts) near its limit")
        ax[1].plot(o.t - o.t[0], o.x, lw=0.5)
        ax[1].set_xlabel("time (s)")
        ax[1].set_ylabel("counts")
    elif f.cause == "temperature" and f.sensor in d.temperature:
        tt = d.temperature[f.sensor]
        betas, _, _ = tt.fit(False, tt.with_time)
        r = (tt.y - tt.predict(betas, False, tt.with_time)) / tt.K
        for a in range(3):
            ax[0].plot(tt.temp, r[:, a], ".", ms=3, label="xyz"[a])
            ax[1].plot(tt.t - tt.t.min(), r[:, a], ".", ms=3, label="xyz"[a])
        ax[0].set_xlabel("board temperature (C)")
        ax[0].set_ylabel(f"still block mean, offsets removed ({TH.UNITS[f.sensor]})")
        ax[0].legend(fontsize=7)
        ax[1].set_xlabel("time (s)")
    elif f.cause == "motion":
        acc, gyr = d.obs.get("accel"), d.obs.get("gyro")
        if acc is not None and gyr is not None and acc.segs is not None:
            sd_a = acc.segs.sd.mean(axis=1) / acc.K
            sd_g = gyr.segs.sd.mean(axis=1) / gyr.K if gyr.segs is not None else None
            ax[0].plot(np.arange(len(sd_a)), sd_a, ".", label="accel within-pose sd (g)")
            ax[0].set_xlabel("pose")
            ax[0].legend(fontsize=7)
            if sd_g is not None:
                ax[1].plot(np.arange(len(sd_g)), sd_g, ".", label="gyro within-pose sd (deg/s)")
                ax[1].legend(fontsize=7)
                ax[1].set_xlabel("pose")


def write_report(d, data, folder) -> list[str]:
    """Pictures + diagnosis.json + summary.txt into ``folder``; returns file names."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UserError(f"cannot create report folder {folder}: {e.strerror or e}") from None
    plt = _plt()
    files = []
    for i, f in enumerate(d.findings, 1):
        fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
        st = d.structures.get(f.sensor)
        o = d.obs.get(f.sensor)
        try:
            if st is not None and f.cause in st.causes:
                if isinstance(st.fit, F.MagnitudeFit):
                    _magnitude_panels(ax, st, f.cause, o)
                else:
                    _linear_panels(ax, st, f.cause, o)
            elif st is not None and f.cause in ("field_disturbance", "unexplained") \
                    and isinstance(st.fit, F.MagnitudeFit):
                X, T = st.points["X"], st.points["T"]
                r = st.fit.residuals(X, T)
                ax[0].plot(T - T.min(), r, ".", ms=3)
                ax[0].set_xlabel("time (s)")
                ax[0].set_ylabel(f"residual ({st.unit})")
                z = r / np.sqrt(st.points["V"])
                ax[1].hist(z, bins=40)
                ax[1].set_xlabel("residual / its noise")
            else:
                _screen_panels(ax, f, d, data)
        except Exception as e:                       # noqa: BLE001 - a picture is optional
            ax[0].text(0.1, 0.5, f"no picture: {e}", transform=ax[0].transAxes)
        fig.suptitle(f"{f.sensor} {f.cause}: gain {f.gain if f.gain is None else round(f.gain, 3)}",
                     fontsize=10)
        fig.tight_layout()
        name = f"finding{i}-{f.sensor}-{f.cause}.png"
        fig.savefig(folder / name, dpi=90)
        plt.close(fig)
        files.append(name)
    comp = (d.comparison or {}).get("heldout") or (d.comparison or {}).get("whole")
    if comp:
        per0 = comp.get("per_stat_paper") or comp.get("per_stat", {})
        per1 = comp.get("per_stat_extended", {})
        keys = sorted(per0, key=lambda k: -per0[k])[:20]
        fig, ax = plt.subplots(figsize=(10, 4))
        xs = np.arange(len(keys))
        ax.bar(xs - 0.2, [per0[k] for k in keys], 0.4, label="paper model")
        if per1:
            ax.bar(xs + 0.2, [per1.get(k, 0) for k in keys], 0.4, label="extended model")
        ax.set_xticks(xs)
        ax.set_xticklabels(keys, rotation=60, ha="right", fontsize=7)
        ax.set_ylabel("|log measured / simulated|")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(folder / "statistics.png", dpi=90)
        plt.close(fig)
        files.append("statistics.png")
    full = dict(d.to_json())
    full["details"] = d.details_json()
    (folder / "diagnosis.json").write_text(json.dumps(full, indent=1) + "\n", encoding="utf-8")
    files.append("diagnosis.json")
    from .summary import render
    (folder / "summary.txt").write_text(render(d) + "\n", encoding="utf-8")
    files.append("summary.txt")
    return files
