"""The report's PNG figures (matplotlib, Agg canvas, no pyplot state).

Every function takes plain numpy arrays and a path, draws one figure and
writes it as PNG.  Nothing here fits anything: calibrated vectors come from
the calibration engine's ``A`` and ``c`` (``calibrated = raw @ A.T + c``).

Directions on the sphere are drawn in the Mollweide projection (equal-area),
longitude ``atan2(y, x)`` and latitude ``asin(z / |v|)`` of the vector in the
sensor frame.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..maths import sphere as S

DPI = 100
MAX_POINTS = 6000                 # scatter plots draw at most this many points
MAX_POINTS_3D = 4000
SET_COLORS = {"O": "tab:blue", "R": "tab:orange", "all": "tab:blue"}


# ------------------------------------------------------------------ helpers

def _figure(w: float, h: float) -> Figure:
    fig = Figure(figsize=(w, h), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path) -> Path:
    path = Path(path)
    fig.savefig(path, format="png", dpi=DPI)
    return path


def _thin(n: int, limit: int = MAX_POINTS) -> np.ndarray:
    """Evenly spread row indices, at most ``limit`` of ``n``."""
    if n <= limit:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, limit).astype(int))


def directions(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Longitude and latitude (radians) of vectors v (n, 3)."""
    v = np.asarray(v, float)
    r = np.linalg.norm(v, axis=1)
    r = np.where(r > 0, r, 1.0)
    lon = np.arctan2(v[:, 1], v[:, 0])
    lat = np.arcsin(np.clip(v[:, 2] / r, -1.0, 1.0))
    return lon, lat


def _groups(sets: np.ndarray | None, idx: np.ndarray):
    """(colour, indices) of the rows ``idx`` of each data set (one colour per
    set; drawing each set in one call is much faster than a colour per point)."""
    if sets is None:
        return [(SET_COLORS["all"], idx)]
    out = []
    for name in np.unique(sets[idx]):
        out.append((SET_COLORS.get(str(name), "tab:gray"), idx[sets[idx] == name]))
    return out


def _legend_sets(ax, sets):
    if sets is None:
        return
    from matplotlib.lines import Line2D
    present = [s for s in ("O", "R") if (sets == s).any()]
    if len(present) > 1:
        ax.legend(handles=[Line2D([], [], ls="", marker="o", ms=4, color=SET_COLORS[s],
                                  label=f"{s} set") for s in present],
                  loc="upper right", fontsize=8)


# ------------------------------------------------------------------ magnitude per sample

def magnitude_per_sample(path, before: np.ndarray, after: np.ndarray, ref_before: float,
                         ref_after: float, unit: str, title: str,
                         sets: np.ndarray | None = None) -> Path:
    """The paper's Fig. 3 / 4: |v| of every sample before and after calibration."""
    nb = np.linalg.norm(before, axis=1)
    na = np.linalg.norm(after, axis=1)
    x = np.arange(len(nb))
    fig = _figure(9, 5.5)
    axes = fig.subplots(2, 1, sharex=True)
    for ax, mag, ref, what in ((axes[0], nb, ref_before, "before (datasheet scale)"),
                               (axes[1], na, ref_after, "after calibration")):
        for col, ii in _groups(sets, _thin(len(mag), 20000)):
            ax.scatter(x[ii], mag[ii], s=1.5, c=col, linewidths=0, rasterized=True)
        ax.axhline(ref, color="k", lw=0.8, ls="--")
        ax.set_ylabel(f"|v| ({unit})")
        ax.set_title(f"{what}: min {mag.min():.4f}, max {mag.max():.4f}, "
                     f"MSE {np.mean((mag - ref) ** 2):.3e} {unit}\u00b2 about {ref:.4f}",
                     fontsize=9)
        ax.grid(alpha=0.3)
        _legend_sets(ax, sets)
    lo = min(nb.min(), na.min())
    hi = max(nb.max(), na.max())
    pad = 0.05 * (hi - lo) + 1e-6
    for ax in axes:
        ax.set_ylim(lo - pad, hi + pad)
    axes[1].set_xlabel("sample")
    fig.suptitle(title)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.09, top=0.88, hspace=0.3)
    return _save(fig, path)


# ------------------------------------------------------------------ scatter

def _sphere_wire(ax, r: float):
    u = np.linspace(0, 2 * np.pi, 25)
    w = np.linspace(0, np.pi, 13)
    ax.plot_wireframe(r * np.outer(np.cos(u), np.sin(w)), r * np.outer(np.sin(u), np.sin(w)),
                      r * np.outer(np.ones_like(u), np.cos(w)), color="0.6", lw=0.3)


def scatter_3d(path, before: np.ndarray, after: np.ndarray, ref_before: float,
               ref_after: float, unit: str, title: str, sets: np.ndarray | None = None) -> Path:
    """The paper's Fig. 5 / 6 in 3D: samples before and after, with the sphere
    of the expected magnitude."""
    fig = _figure(11, 5.5)
    groups = _groups(sets, _thin(len(before), MAX_POINTS_3D))
    for k, (v, ref, what) in enumerate(((before, ref_before, "before"),
                                        (after, ref_after, "after"))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        _sphere_wire(ax, ref)
        for col, ii in groups:
            p = v[ii]
            ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=2, c=col, depthshade=False, linewidths=0)
        lim = max(float(np.abs(v).max()), ref) * 1.05
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_zlim(-lim, lim)
        ax.set_box_aspect((1, 1, 1))
        ax.set_xlabel(f"x ({unit})")
        ax.set_ylabel(f"y ({unit})")
        ax.set_zlabel(f"z ({unit})")
        ax.set_title(f"{what} (sphere: {ref:.4f} {unit})", fontsize=10)
    fig.suptitle(title)
    fig.subplots_adjust(left=0.02, right=0.96, bottom=0.04, top=0.9, wspace=0.1)
    return _save(fig, path)


PLANES = (("x", "y", 0, 1), ("x", "z", 0, 2), ("y", "z", 1, 2))


def scatter_planes(path, before: np.ndarray, after: np.ndarray, ref_before: float,
                   ref_after: float, unit: str, title: str,
                   sets: np.ndarray | None = None) -> Path:
    """The paper's Fig. 5 / 6 as three planes (xy, xz, yz), before (top) and after
    (bottom), with the circle of the expected magnitude."""
    fig = _figure(12, 8)
    axes = fig.subplots(2, 3)
    groups = _groups(sets, _thin(len(before)))
    phi = np.linspace(0, 2 * np.pi, 200)
    lim = max(float(np.abs(before).max()), float(np.abs(after).max()),
              ref_before, ref_after) * 1.05
    for row, (v, ref, what) in enumerate(((before, ref_before, "before"),
                                          (after, ref_after, "after"))):
        for col, (a, b, i, j) in enumerate(PLANES):
            ax = axes[row, col]
            ax.plot(ref * np.cos(phi), ref * np.sin(phi), color="k", lw=0.7, ls="--")
            for colour, ii in groups:
                ax.scatter(v[ii, i], v[ii, j], s=1.5, c=colour, linewidths=0)
            ax.set_xlim(-lim, lim)
            ax.set_ylim(-lim, lim)
            ax.set_aspect("equal")
            ax.set_xlabel(f"{a} ({unit})")
            ax.set_ylabel(f"{b} ({unit})")
            ax.set_title(f"{what}: {a}{b} plane", fontsize=10)
            ax.grid(alpha=0.3)
    _legend_sets(axes[0, 2], sets)
    fig.suptitle(title)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.07, top=0.91, wspace=0.35, hspace=0.3)
    return _save(fig, path)


# ------------------------------------------------------------------ sphere maps

def residual_sphere(path, before: np.ndarray, after: np.ndarray, ref_before: float,
                    ref_after: float, unit: str, title: str) -> Path:
    """Magnitude residual |v| - H against the direction of v (Mollweide map),
    before and after: systematic errors show as smooth patterns."""
    fig = _figure(12, 4.8)
    idx = _thin(len(before))
    for k, (v, ref, what) in enumerate(((before, ref_before, "before"),
                                        (after, ref_after, "after"))):
        ax = fig.add_subplot(1, 2, k + 1, projection="mollweide")
        p = v[idx]
        lon, lat = directions(p)
        res = np.linalg.norm(p, axis=1) - ref
        lim = float(np.max(np.abs(res))) or 1e-9
        sc = ax.scatter(lon, lat, c=res, s=4, cmap="coolwarm", vmin=-lim, vmax=lim,
                        linewidths=0)
        ax.grid(alpha=0.4)
        ax.tick_params(labelsize=7)
        ax.set_title(f"{what}: residual rms {np.sqrt(np.mean(res ** 2)):.2e} {unit}",
                     fontsize=10, pad=12)
        cb = fig.colorbar(sc, ax=ax, orientation="horizontal", shrink=0.7, pad=0.08)
        cb.set_label(f"|v| - {ref:.4f} ({unit})", fontsize=8)
        cb.ax.tick_params(labelsize=7)
    fig.suptitle(title)
    return _save(fig, path)


def coverage(path, sets: list[tuple[str, np.ndarray]], title: str) -> Path:
    """Samples per equal-area cell of the sphere of directions (``sphere``'s
    cells), one map per set; the title of each gives its coverage, the share
    of cells with at least one sample (the number the logger and the quality
    gate use)."""
    fig = _figure(6 * len(sets), 4.6)
    lon_e, z_e = S.cell_edges()
    lat_e = np.arcsin(z_e[::-1])                  # ascending: bands bottom (-Z) up
    for k, (name, v) in enumerate(sets):
        ax = fig.add_subplot(1, len(sets), k + 1, projection="mollweide")
        counts = S.coverage_counts(v)[::-1]
        masked = np.ma.masked_equal(counts, 0)
        mesh = ax.pcolormesh(lon_e, lat_e, masked, cmap="viridis", shading="flat")
        ax.grid(alpha=0.4)
        ax.tick_params(labelsize=7)
        ax.set_title(f"{name}: {len(v)} samples, coverage {(counts > 0).mean():.0%} of "
                     f"{counts.size} cells", fontsize=10, pad=12)
        cb = fig.colorbar(mesh, ax=ax, orientation="horizontal", shrink=0.7, pad=0.08)
        cb.set_label("samples per cell", fontsize=8)
        cb.ax.tick_params(labelsize=7)
    fig.suptitle(title)
    return _save(fig, path)


# ------------------------------------------------------------------ readings set aside

ASIDE_COLOR = "tab:red"


def set_aside(path, after: np.ndarray, aside: np.ndarray, t: np.ndarray, ref: float,
              unit: str, title: str) -> Path:
    """The calibrated readings in three planes and their magnitude against
    time, those the robust fit set aside (``aside``) in red over the ones it
    kept (grey): where the glitches and the disturbed stretches were."""
    fig = _figure(12, 8)
    axes = fig.subplots(2, 2)
    aside = np.asarray(aside, bool)
    keep_i = np.flatnonzero(~aside)[_thin(int((~aside).sum()))]
    out_i = np.flatnonzero(aside)[_thin(int(aside.sum()))]
    phi = np.linspace(0, 2 * np.pi, 200)
    lim = max(float(np.abs(after).max()), ref) * 1.05
    for ax, (a, b, i, j) in zip((axes[0, 0], axes[0, 1], axes[1, 0]), PLANES):
        ax.plot(ref * np.cos(phi), ref * np.sin(phi), color="k", lw=0.7, ls="--")
        ax.scatter(after[keep_i, i], after[keep_i, j], s=1.5, c="0.6", linewidths=0)
        ax.scatter(after[out_i, i], after[out_i, j], s=4, c=ASIDE_COLOR, linewidths=0)
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_xlabel(f"{a} ({unit})")
        ax.set_ylabel(f"{b} ({unit})")
        ax.set_title(f"{a}{b} plane", fontsize=10)
        ax.grid(alpha=0.3)
    ax = axes[1, 1]
    m = np.linalg.norm(after, axis=1)
    ax.scatter(t[keep_i], m[keep_i], s=1.5, c="0.6", linewidths=0, label="kept")
    ax.scatter(t[out_i], m[out_i], s=4, c=ASIDE_COLOR, linewidths=0,
               label=f"set aside ({int(aside.sum())} of {len(aside)})")
    ax.axhline(ref, color="k", lw=0.7, ls="--")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"|v| ({unit})")
    ax.set_title("magnitude after calibration", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, markerscale=3, loc="best")
    fig.suptitle(title)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.07, top=0.91, wspace=0.3, hspace=0.3)
    return _save(fig, path)


# ------------------------------------------------------------------ gyroscope noise

GAP_FACTOR = 10.0      # interleaved rows: an interval over this many mean intervals is a gap


def still_runs(label: np.ndarray, seq: np.ndarray, ok: np.ndarray, t: np.ndarray | None = None,
               min_len: int = 8) -> list[np.ndarray]:
    """Row indices of contiguous runs of one sensor's samples: rows where ``ok``
    (the sensor has a value) with the same static label >= 1, split where the
    label changes or samples are missing.  Missing means a jump in ``seq``
    other than 1 when the sensor has a value in consecutive rows (sensors
    sampled together); for sensors on their own clocks (rows interleaved with
    other sensors', timestamps often bursty) an interval of ``t`` over
    ``GAP_FACTOR`` times the mean interval.  Runs under ``min_len`` rows are
    dropped."""
    label = np.asarray(label)
    good = (label >= 1) & np.asarray(ok)
    idx = np.flatnonzero(good)
    if len(idx) < 2:
        return []
    brk = np.diff(label[idx]) != 0
    dseq = np.diff(np.asarray(seq)[idx])
    tt = None if t is None else np.asarray(t, float)[idx]
    interleaved = not np.all(ok)          # rows without this sensor in between
    if interleaved and tt is not None and np.isfinite(tt).all():
        dt = np.diff(tt)
        typical = dt[(dt > 0) & (dt < 1.0)]
        mean = float(typical.mean()) if len(typical) else 0.0
        brk |= (dt < 0) | (dt > GAP_FACTOR * mean)
    else:
        brk |= dseq != 1
    runs = np.split(idx, np.flatnonzero(brk) + 1)
    return [r for r in runs if len(r) >= min_len]


def allan(path, tau: np.ndarray, adev: np.ndarray, unit: str, title: str,
          note: str = "") -> Path:
    fig = _figure(7, 5)
    ax = fig.subplots()
    for j, (axis, col) in enumerate(zip("xyz", ("tab:red", "tab:green", "tab:blue"))):
        ax.loglog(tau, adev[:, j], "o-", ms=3, color=col, label=f"{axis}")
    ax.set_xlabel("averaging time tau (s)")
    ax.set_ylabel(f"Allan deviation ({unit})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    ax.set_title(note, fontsize=9)
    fig.suptitle(title)
    fig.subplots_adjust(left=0.14, right=0.97, bottom=0.11, top=0.88)
    return _save(fig, path)


# ------------------------------------------------------------------ GA convergence

def convergence(path, traces: list[tuple[str, list]], title: str) -> Path:
    """Best fitness per generation of every GA run named in ``traces``."""
    fig = _figure(8, 5)
    ax = fig.subplots()
    for name, tr in traces:
        tr = np.asarray(tr, float)
        tr = np.where(tr > 0, tr, np.nan)
        ax.semilogy(np.arange(len(tr)), tr, lw=1.2, label=f"{name} ({len(tr) - 1} gen.)")
    ax.set_xlabel("generation")
    ax.set_ylabel("best fitness (GA objective)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.11, top=0.9)
    return _save(fig, path)
