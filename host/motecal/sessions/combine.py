"""One session from several parts (issue 30): files of different formats
imported together, each read by its own reader (``motecal import``), and
files added to a stored session (``motecal import --append``).

``combine(parts)`` puts the parts' rows one after the other, as separate
recordings:

* sequence numbers continue per mote (a part's own numbers keep their gaps);
  times continue after the previous part (one sample interval later);
* pose labels are renumbered so that each part's poses stay distinct (the
  six face files are poses 1-6, a still gyro file pose 7); rotation rows
  stay ``rot``;
* every sensor's chip and scale must agree between the parts that hold it
  (one board per session: a mismatch is one line naming both files);
* ``meta["files"]`` lists every file with its rows, format, samples, the
  pose it became and a digest of its readings (``digest``), so that
  appending the same file twice is refused; ``meta["format"]`` is the
  formats joined by '+', and ``meta["axis_frame"]`` the parts' frame when
  they agree (the Razor text and float logs are both in the Razor
  firmware's board frame), else each file's.

``append(old, new)`` is ``combine`` with the checks ``motecal log --append``
makes on a continued session: the files' motes (a format without mote ids
goes to the session's one mote), the chips and scales, and no rows twice
(a project CSV's (mote, seq) already stored, or a file whose readings are
already in the session).
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from ..errors import UserError
from .session import SENSOR_SLICES, SessionData

SEP = "; "
RAZOR_FRAME_HEAD = "as recorded: Razor AHRS firmware board frame"


def digest(raw: np.ndarray) -> str:
    """A digest of a block of readings (raw counts, NaN = missing)."""
    x = np.where(np.isfinite(raw), raw, -99999.0).astype("<f8")
    return hashlib.sha1(x.tobytes()).hexdigest()[:16]


def _files(d: SessionData) -> list[dict]:
    """The session's file list with row ranges (the whole session as one
    file when it has none), each with its digest."""
    files = [dict(f) for f in (d.meta.get("files") or []) if isinstance(f, dict)]
    if not files:
        files = [{"file": str(d.meta.get("source") or d.name), "rows": [0, len(d)],
                  "samples": len(d)}]
    for f in files:
        f.setdefault("format", d.meta.get("format"))
        f.setdefault("axis_frame", d.meta.get("axis_frame"))
        a, b = (int(v) for v in f.get("rows") or (0, len(d)))
        f.setdefault("digest", digest(d.raw[a:b]))
    return files


def _name(d: SessionData) -> str:
    return ", ".join(Path(f["file"]).name for f in _files(d)[:3]) or d.name


def check_sensors(parts: list[SessionData]) -> tuple[dict, dict]:
    """(chips, scales) of the combined session: each sensor's from the parts
    that hold it, whose scales must agree (UserError naming the files
    otherwise); the first chip name is kept."""
    chips, scales, where = {}, {}, {}
    for d in parts:
        for s in SENSOR_SLICES:
            if not d.has(s).any():
                continue
            c, k = (d.chips or {}).get(s), float(d.scales[s])
            if s in scales and k != scales[s]:
                raise UserError(
                    f"{s}: {where[s]} was read as {chips[s]} at {scales[s]:g} LSB per unit, "
                    f"{_name(d)} as {c} at {k:g}: one board per session (give --chip to "
                    f"read them alike)")
            if s not in scales:
                chips[s], scales[s], where[s] = c, k, _name(d)
    for d in parts:                       # sensors no part holds: the first part's
        for s in SENSOR_SLICES:
            chips.setdefault(s, (d.chips or {}).get(s))
            scales.setdefault(s, float(d.scales[s]))
    return chips, scales


def combine(parts: list[SessionData], name: str | None = None) -> SessionData:
    """The parts as one session (see the module doc)."""
    parts = [p for p in parts if p is not None]
    if not parts:
        raise UserError("nothing to combine")
    if len(parts) == 1:
        return parts[0]
    chips, scales = check_sensors(parts)
    raws, motes, seqs, ts, labels, flags, temps = [], [], [], [], [], [], []
    files, notes, rates, kinds, formats, sources = [], [], {}, [], [], []
    last_seq: dict[int, int] = {}
    t_end, pose_top, row = None, 0, 0
    has_temp = any(p.temp is not None for p in parts)
    for d in parts:
        n = len(d)
        seq = d.seq.astype(np.int64).copy()
        for m in np.unique(d.mote):
            sel = d.mote == m
            if int(m) in last_seq:
                seq[sel] = seq[sel] - seq[sel].min() + last_seq[int(m)] + 1
            last_seq[int(m)] = int(seq[sel].max())
        t = np.asarray(d.t, float).copy()
        fin = np.isfinite(t)
        if fin.any():
            rate = d.rate() or 1.0
            if t_end is not None:
                t[fin] += t_end + 1.0 / rate - np.min(t[fin])
            t_end = float(np.max(t[fin]))
        lab = d.label.copy()
        pose = lab >= 1
        lab[pose] += pose_top
        pose_top = max(pose_top, int(lab.max()) if pose.any() else pose_top)
        raws.append(d.raw); motes.append(d.mote); seqs.append(seq); ts.append(t)
        labels.append(lab); flags.append(d.flags)
        temps.append(d.temp if d.temp is not None else np.full(n, np.nan))
        for f in _files(d):
            f = dict(f)
            a, b = (int(v) for v in f["rows"])
            f["rows"] = [a + row, b + row]
            files.append(f)
        row += n
        meta = d.meta or {}
        if meta.get("notes"):
            notes.append(str(meta["notes"]))
        for s, r in (meta.get("rates_hz") or {}).items():
            if r and d.has(s).any():
                rates.setdefault(s, float(r))
        kinds.append(d.kind)
        formats.append(str(meta.get("format") or "?"))
        sources.append(str(meta.get("source") or d.name))
    # each file's pose after renumbering: the label its rows carry
    label = np.concatenate(labels)
    for f in files:
        a, b = f["rows"]
        poses = np.unique(label[a:b][label[a:b] >= 1])
        if "pose" in f or len(poses) == 1:
            f["pose"] = int(poses[0]) if len(poses) == 1 else None
    first = parts[0].meta or {}
    frames = [f.get("axis_frame") for f in files]
    meta = {k: v for k, v in first.items() if k in ("still_thresholds", "units")}
    meta.update({
        "format": "+".join(dict.fromkeys(formats)),
        "source": SEP.join(sources), "files": files,
        "rate_hz": first.get("rate_hz") or parts[0].rate(),
        "rates_hz": rates,
        "clocks": "separate recordings, one after the other (" + SEP.join(
            dict.fromkeys(str((p.meta or {}).get("clocks") or "?") for p in parts)) + ")",
        "samples": {s: int(sum(int(p.has(s).sum()) for p in parts)) for s in SENSOR_SLICES},
        "kind_decision": SEP.join(f"{Path(_files(p)[0]['file']).name}: "
                                  f"{(p.meta or {}).get('kind_decision', p.kind)}"
                                  for p in parts),
    })
    if all(fr and str(fr).startswith(RAZOR_FRAME_HEAD) for fr in frames):
        meta["axis_frame"] = (f"{RAZOR_FRAME_HEAD} (every file: accel x = chip y, accel y = "
                              f"chip x; gyroscope and magnetometer sign flips)")
    elif len(set(frames)) == 1:
        meta["axis_frame"] = frames[0]
    else:
        meta["axis_frame"] = "per file (meta files): " + SEP.join(
            f"{Path(f['file']).name}: {f.get('axis_frame')}" for f in files)
    clipped = {}
    for p in parts:
        for s, k in ((p.meta or {}).get("clipped") or {}).items():
            clipped[s] = clipped.get(s, 0) + int(k)
    meta["clipped"] = clipped
    if notes:
        meta["notes"] = SEP.join(notes)
    kind = "+".join(dict.fromkeys(kinds))
    temp = np.concatenate(temps) if has_temp else None
    return SessionData(name or parts[0].name, np.vstack(raws), np.concatenate(motes),
                       np.concatenate(seqs), np.concatenate(ts), label,
                       np.concatenate(flags), kind, scales, chips, meta, temp)


def append(old: SessionData, new: SessionData) -> SessionData:
    """The stored session ``old`` with ``new`` after it, checked as ``log
    --append`` checks a continued session (module doc).  The new rows are
    the last ``len(new)`` of the result."""
    if len(old) == 0:
        raise UserError(f"session {old.name!r} has no samples to append to")
    new = SessionData(new.name, new.raw, new.mote.copy(), new.seq, new.t, new.label, new.flags,
                      new.kind, dict(new.scales), dict(new.chips), dict(new.meta), new.temp)
    fmt = str(new.meta.get("format") or "")
    if "csv" not in fmt.split("+"):
        # a format without mote ids: the rows are the session's one board
        if len(old.motes) != 1:
            raise UserError(f"session {old.name!r} holds motes "
                            f"{', '.join(map(str, old.motes))}; {_name(new)} carries no mote id: "
                            "append such files to a session of one board")
        new.mote[:] = old.motes[0]
    else:
        # a project CSV keeps its motes and sequence numbers: none may be stored already
        for m in np.unique(new.mote):
            have = old.seq[old.mote == m]
            sel = new.mote == m
            both = np.isin(new.seq[sel], have)
            if both.any():
                s = new.seq[sel][both]
                same = _same_rows(old, new, int(m), s)
                what = ("already in the session with the same readings (imported before?)"
                        if same else "already in the session with other readings")
                raise UserError(f"{_name(new)}: mote {int(m)} samples {int(s.min())}..."
                                f"{int(s.max())} are {what}: nothing appended")
    have = {f["digest"]: f["file"] for f in _files(old)}
    for f in _files(new):
        if f["digest"] in have:
            raise UserError(f"{f['file']}: its readings are already in session {old.name!r} "
                            f"(from {have[f['digest']]}): nothing appended")
    out = combine([old, new], name=old.name)
    if "csv" in fmt.split("+"):            # keep the CSV's own sequence numbers
        out.seq[len(old):] = new.seq
    return out


def _same_rows(old: SessionData, new: SessionData, mote: int, seqs) -> bool:
    a = old.raw[(old.mote == mote) & np.isin(old.seq, seqs)]
    b = new.raw[(new.mote == mote) & np.isin(new.seq, seqs)]
    return a.shape == b.shape and bool(np.array_equal(np.nan_to_num(a, nan=-1e9),
                                                     np.nan_to_num(b, nan=-1e9)))
