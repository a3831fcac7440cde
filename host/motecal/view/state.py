"""What the browser view shows, as one JSON document: the live state of a
logging run (``LiveView``, a display of ``capture.logger.Logger``) or of a
stored session (``session_state``, for the report).

The guided flow's decisions stay in ``capture.guide``: the view reads the
numbers its state machines expose (``status()`` for the words, ``picture()``
for the directions, cells and points) and decides nothing again.

The logging thread never waits for the view: every ``every`` seconds
``LiveView.tick`` takes a *snapshot* (counters copied, the guide's arrays by
reference -- they are replaced, not changed) and swaps it in as one
reference.  Turning it into JSON (downsampling the sweep, the fit quality)
happens in the server's threads, once per snapshot (``LiveView.document``).
Nothing is queued: a slow or absent browser only ever misses snapshots.

One document, the same for both sources::

    {"mode": "live"|"static", "version": n, "session": ..., "source": ...,
     "flow": "static80"|"rotation"|null, "elapsed": s, "connected": bool,
     "ended": bool, "stop_reason": str,
     "line": {frames, crc_errors, garbage_bytes, disconnects, ...},
     "motes": [{"id": m, "link": {samples, rate, lost, duplicates, reordered, ...},
                "state": "receiving"|"silent"|"stored",
                "live": {"acc": [3], "mag": [3]} | null,      # raw counts, last row
                "static": {...} | null, "sweep": {...} | null}],
     "events": [{"t": s, "kind": k, "mote": m, "text": str}]}
"""
from __future__ import annotations

import json
import math
import threading
import time
from collections import deque

import numpy as np

from ..capture.guide import DEFAULT_POSES, MAG_OVERFLOW, sweep_centre
from ..jsonable import jsonable
from ..maths.sphere import COVERAGE_BANDS, COVERAGE_SECTORS, coverage_counts, fibonacci_sphere, unit
from ..sessions.session import LABEL_ROT

MAX_POINTS = 1500        # sweep points sent per mote (an even subsample of all)
MAX_EVENTS = 40
SILENT_S = 1.0           # a mote with no sample for this long is shown as silent
RATE_WINDOW_S = 2.0      # samples/s over the last seconds


def _round(a, nd=4):
    return np.round(np.asarray(a, float), nd)


def sweep_numbers(points: np.ndarray, centre, hits, bands: int, sectors: int,
                  max_points: int = MAX_POINTS) -> dict:
    """The sweep as drawn: raw points (an even subsample), the fitted centre,
    radius, the fit error (spread of |m - centre| in % of the radius, as
    MotionCal's "fit error"), the cells hit and the share of them."""
    pts = np.asarray(points, float).reshape(-1, 3)
    c = np.asarray(centre, float)
    if len(pts):
        r = np.linalg.norm(pts - c, axis=1)
        radius = float(r.mean())
        fit_error = float(100.0 * r.std() / radius) if radius > 0 else None
    else:
        radius, fit_error = None, None
    stride = max(1, math.ceil(len(pts) / max_points))
    hits = np.asarray(hits).reshape(-1)
    return dict(count=len(pts), points=np.round(pts[::stride], 1), centre=_round(c, 2),
                radius=radius, fit_error=fit_error, bands=bands, sectors=sectors,
                hits=(hits > 0).astype(int), coverage=float((hits > 0).mean()))


def _static_numbers(pic: dict, st: dict | None) -> dict:
    out = dict(targets=_round(pic["targets"]), accepted=_round(pic["accepted"]),
               target=None if pic["target"] is None else _round(pic["target"]),
               still=bool(pic["still"]), hits=(np.asarray(pic["hits"]) > 0).astype(int),
               bands=pic["bands"], sectors=pic["sectors"], discards=pic["discards"])
    if st is not None:
        out.update(phase=st["phase"], pose=st["pose"], poses=st["poses"],
                   captured=st["captured"], samples=st["samples"], armed=st["armed"],
                   warning=st["warning"], coverage=st["coverage"], target_text=st["target"],
                   done=st["target"] is None)
    return out


class LiveView:
    """A logger display that keeps the latest snapshot for the web page.

    All ``Logger`` calls come from the logging thread and return at once;
    ``document()`` is called from the server's threads.
    """

    def __init__(self, every: float = 0.2, max_points: int = MAX_POINTS):
        self.every = every
        self.max_points = max_points
        self._snap = None                   # (version, dict): swapped as one reference
        self._version = 0
        self._next = 0.0
        self._last_rows: dict[int, np.ndarray] = {}
        self._last_seen: dict[int, float] = {}
        self._rows_next = 0.0
        self._rates: dict[int, deque] = {}
        self._events: deque = deque(maxlen=MAX_EVENTS)
        self._t0 = time.monotonic()
        self._doc = (0, b"{}")              # (version, JSON) cache
        self._doc_lock = threading.Lock()

    # -- the logger's side --------------------------------------------------------
    def start(self, logger):
        self._t0 = logger.started
        self._publish(logger)

    def event(self, text):
        if text:
            self._events.append((time.monotonic() - self._t0, "line", None, text, None))

    def guide_event(self, ev):
        if ev.text:
            self._events.append((time.monotonic() - self._t0, ev.kind, ev.mote, ev.text,
                                 ev.pose or None))

    def rows(self, rows):
        now = time.monotonic()
        if now < self._rows_next or not len(rows):
            return
        self._rows_next = now + 0.05
        # the last row of each mote in this read
        rev = rows.mote[::-1]
        motes, idx = np.unique(rev, return_index=True)
        for m, i in zip(motes.tolist(), (len(rev) - 1 - idx).tolist()):
            self._last_rows[m] = np.array(rows.raw[i], float)
            self._last_seen[m] = now

    def tick(self, logger):
        if time.monotonic() >= self._next:
            self._publish(logger)

    def stop(self, logger):
        self._publish(logger, ended=True)

    def _publish(self, logger, ended: bool = False) -> None:
        now = time.monotonic()
        self._next = now + self.every
        motes = {}
        for m, link in logger.tracker.seen().items():
            c = dict(link.c)
            hist = self._rates.setdefault(m, deque())
            hist.append((now, c["samples"]))
            while len(hist) > 2 and now - hist[1][0] >= RATE_WINDOW_S:
                hist.popleft()
            t0, s0 = hist[0]
            c["rate"] = (c["samples"] - s0) / (now - t0) if now > t0 else 0.0
            c["temp_c"] = link.temp_c          # latest temperature message (None: none yet)
            seen = self._last_seen.get(m)
            motes[m] = dict(id=m, link=c, row=self._last_rows.get(m),
                            state="receiving" if seen is not None and now - seen < SILENT_S
                            else "silent")
        guide = logger.guide
        if guide is not None:
            for st in guide.status():
                cap = guide.captures[st["mote"]]
                entry = motes.setdefault(st["mote"], dict(
                    id=st["mote"], link={}, row=self._last_rows.get(st["mote"]), state="silent"))
                entry[cap.kind] = (st, cap.picture())
        self._version += 1
        self._snap = (self._version, dict(
            session=logger.writer.name, source=str(logger.spec),
            flow=guide.kind if guide is not None else None, elapsed=logger.elapsed,
            connected=bool(logger.connected), ended=ended, stop_reason=logger.stop_reason,
            line=dict(logger.tracker.line), motes=[motes[m] for m in sorted(motes)],
            events=list(self._events)))

    # -- the server's side ----------------------------------------------------------
    @property
    def version(self) -> int:
        snap = self._snap
        return snap[0] if snap else 0

    @property
    def ended(self) -> bool:
        snap = self._snap
        return bool(snap and snap[1]["ended"])

    def document(self) -> tuple[int, bytes]:
        """(version, JSON bytes) of the latest snapshot (built once per snapshot)."""
        snap = self._snap
        if snap is None:
            return 0, dumps(EMPTY)
        with self._doc_lock:
            if self._doc[0] != snap[0]:
                self._doc = (snap[0], dumps(self._render(*snap)))
            return self._doc

    def _render(self, version: int, s: dict) -> dict:
        motes = []
        for e in s["motes"]:
            row = e["row"]
            out = dict(id=e["id"], link=e["link"], state=e["state"],
                       live=None if row is None else dict(acc=row[:3], mag=row[6:9]),
                       static=None, sweep=None)
            for flow in ("static80", "adaptive"):         # flows that suggest poses
                if flow in e:
                    st, pic = e[flow]
                    out["static"] = _static_numbers(pic, st)
            if "rotation" in e:
                st, pic = e["rotation"]
                sw = sweep_numbers(pic["points"], pic["centre"], pic["hits"], pic["bands"],
                                   pic["sectors"], self.max_points)
                sw.update(phase=st["phase"], samples_seen=st["count"], samples=st["samples"],
                          target_coverage=st["target_coverage"], armed=st["armed"],
                          coverage=st["coverage"])
                out["sweep"] = sw
            motes.append(out)
        events = [dict(t=round(t, 2), kind=k, mote=m, text=x, pose=p)
                  for t, k, m, x, p in s["events"]]
        return dict(mode="live", version=version, session=s["session"], source=s["source"],
                    flow=s["flow"], elapsed=s["elapsed"], connected=s["connected"],
                    ended=s["ended"], stop_reason=s["stop_reason"], line=s["line"],
                    motes=motes, events=events)


EMPTY = dict(mode="live", version=0, session=None, source=None, flow=None, elapsed=0.0,
             connected=False, ended=False, stop_reason="", line={}, motes=[], events=[])


def dumps(doc: dict) -> bytes:
    return json.dumps(jsonable(doc), separators=(",", ":")).encode()


# --------------------------------------------------------------------------
# A stored session (the report's static view)
# --------------------------------------------------------------------------
def session_state(data, stats: dict | None = None, events: list | None = None,
                  max_points: int = MAX_POINTS) -> dict:
    """The same document for a stored session (``SessionData``): per mote its
    poses' mean gravity directions (labels 1..N) beside the suggested ones
    (``fibonacci_sphere``, as the guide suggests them), its sweep (rows
    labelled ``rot``: centre as the guide fits it, ``guide.sweep_centre``,
    and the 10 x 10 cells), and the link counters of ``store.link_stats``."""
    stats = stats or {"line": {}, "motes": {}}
    motes = []
    for m in data.motes:
        d = data.for_mote(m)
        acc, mag = d.raw[:, 0:3].astype(float), d.raw[:, 6:9].astype(float)
        entry = dict(id=m, link=dict(stats["motes"].get(m, {}), samples=len(d)),
                     state="stored", live=None, static=None, sweep=None)
        poses = d.poses()
        if poses:
            acc_ok = np.isfinite(acc).all(axis=1)
            dirs = np.array([unit(acc[(d.label == k) & acc_ok].mean(axis=0)) for k in poses])
            n = max(DEFAULT_POSES, len(poses))
            hits = coverage_counts(dirs, 4, 5)
            entry["static"] = dict(
                targets=_round(fibonacci_sphere(n)), accepted=_round(dirs), target=None,
                still=False, hits=(hits > 0).astype(int).reshape(-1), bands=4, sectors=5,
                discards=None, phase="stored", pose=len(poses), poses=n, captured=0,
                samples=int(np.bincount(d.label[d.label > 0]).max()), armed=False,
                warning="", coverage=float((hits > 0).mean()), target_text=None, done=True,
                labels=poses)
        rot = ((d.label == LABEL_ROT) & np.isfinite(mag).all(axis=1)
               & (mag != MAG_OVERFLOW).all(axis=1))
        if rot.any():
            pts = mag[rot]
            c = sweep_centre(pts)
            hits = coverage_counts(pts - c, COVERAGE_BANDS, COVERAGE_SECTORS)
            sw = sweep_numbers(pts, c, hits, COVERAGE_BANDS, COVERAGE_SECTORS, max_points)
            sw.update(phase="stored", samples_seen=int(rot.sum()), samples=int(rot.sum()),
                      target_coverage=None, armed=False)
            entry["sweep"] = sw
        motes.append(entry)
    evs = [dict(t=e["t"], kind=e["kind"], mote=e["mote"], text=e["detail"])
           for e in (events or [])][-MAX_EVENTS:]
    return dict(mode="static", version=1, session=data.name, source=data.meta.get("source"),
                flow=data.kind, elapsed=None, connected=False, ended=True, stop_reason="stored",
                line=stats["line"], motes=motes, events=evs)
