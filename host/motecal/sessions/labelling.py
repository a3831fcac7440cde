"""Labels of an imported session: stillness, poses, rotations (the rules in
``motecal.sessions.importer``'s docstring), and the last step of every reader,
:func:`_finish` (``--chip`` overrides, counts, clipping, labels).
"""
from __future__ import annotations

from dataclasses import asdict

import numpy as np

from ..errors import UserError
from .chips import parse_chip_overrides
from .imported import _clipped, _sensor_counts, add_note, check_imported
from .session import LABEL_ROT, UNITS, SessionData
from .still import StillThresholds, segment_recording, window_rows

KINDS = ("auto", "static", "rotation", "idle")
AUTO_ROTATION_BELOW = 0.5       # auto kind: rotation when the still fraction is lower


def _longest_segment(seg: np.ndarray) -> int:
    if not (seg > 0).any():
        return 0
    counts = np.bincount(seg[seg > 0])
    return int(np.argmax(counts))


def assign_labels(data: SessionData, kind: str = "auto", parts=None, pose_per_part=False,
                  th: StillThresholds = StillThresholds()) -> SessionData:
    """Label the rows of ``data`` in place from stillness and set ``data.kind``.

    ``parts`` is a list of ``(start, stop)`` row ranges recorded separately
    (files, motes); each is segmented on its own and its still segments are
    numbered 1..K.  With ``pose_per_part`` (several files of one pose each),
    part i (1-based) is pose i instead: its longest still segment.
    Records the decision in ``meta["kind_decision"]`` and ``meta["still_fraction"]``.
    """
    if kind not in KINDS:
        raise UserError(f"kind must be one of {', '.join(KINDS)}, not {kind!r}")
    n = len(data)
    parts = parts or [(0, n)]
    rate = data.rate()
    seg = np.zeros(n, np.int32)
    per_part = np.zeros(n, np.int32)
    missing, n_segments, max_segments = [], 0, 0
    for i, (a, b) in enumerate(parts, start=1):
        s = segment_recording(data.raw[a:b], data.t[a:b], rate, data.scales, th)
        seg[a:b] = s
        k_max = int(s.max()) if len(s) else 0
        n_segments += k_max
        max_segments = max(max_segments, k_max)
        k = _longest_segment(s)
        if k:
            per_part[a:b][s == k] = i
        else:
            missing.append(i)
    still_fraction = float((seg > 0).mean()) if n else 0.0
    short = [i for i, (a, b) in enumerate(parts, start=1) if b - a < window_rows(rate, th)]
    if short:
        which = ("the recording is" if len(parts) == 1
                 else f"recordings {', '.join(map(str, short))} are")
        add_note(data.meta, f"{which} shorter than the stillness window ({th.window_s:g} s): "
                 "no row can be judged still")
    if pose_per_part and len(parts) > 1:
        labels, n_poses = per_part, len(parts) - len(missing)
        how = f"one pose per file, {n_poses} of {len(parts)} files have a still part"
    else:
        labels, n_poses = seg, max_segments
        how = f"{n_segments} still segment{'s' if n_segments != 1 else ''}"
        if len(parts) > 1:
            how += f" in {len(parts)} recordings"
    if kind == "auto":
        if still_fraction < AUTO_ROTATION_BELOW:
            chosen = "rotation"
            why = f"{still_fraction:.1%} of rows still < {AUTO_ROTATION_BELOW:.0%}"
        else:
            chosen = "static" if n_poses >= 2 else "idle"
            why = f"{still_fraction:.1%} of rows still, {how}"
        decision = f"auto: {chosen} ({why})"
    else:
        chosen = kind
        decision = f"given: {kind} ({still_fraction:.1%} of rows still, {how})"
    files = data.meta.get("files")
    if chosen == "rotation":
        data.label[:] = LABEL_ROT
    else:
        data.label[:] = labels
        if pose_per_part and len(parts) > 1:
            if files and len(files) == len(parts):
                for i, f in enumerate(files, start=1):
                    f["pose"] = None if i in missing else i
            if missing:
                names = [str(files[i - 1]["file"]) if files else f"part {i}" for i in missing]
                add_note(data.meta,
                    f"no still part in {', '.join(names)}: pose label(s) "
                    f"{', '.join(map(str, missing))} absent")
    data.kind = chosen
    data.meta["kind_decision"] = decision
    data.meta["still_fraction"] = round(still_fraction, 4)
    data.meta["still_thresholds"] = asdict(th)
    return data


def _finish(data: SessionData, chip, kind, parts, has_labels=False,
            pose_per_part=False) -> SessionData:
    """Apply --chip overrides, fill counts/clipping, label (unless labelled)."""
    over = data.raw == 32768
    if over.any():
        data.raw[over] = 32767
        add_note(data.meta, f"{int(over.sum())} values of 32768 (one past the 16-bit full scale) "
                 f"stored as 32767")
    overrides = parse_chip_overrides(chip)
    for sensor, (name, scale) in overrides.items():
        data.chips[sensor] = name
        data.scales[sensor] = float(scale)
    if overrides:
        data.meta["chips_from"] = "--chip " + ", ".join(
            f"{s}={n}" for s, (n, _) in sorted(overrides.items()))
    data.meta["samples"] = _sensor_counts(data.raw)
    check_imported(data)
    data.meta["clipped"] = _clipped(data.raw, data.chips)
    data.meta["units"] = dict(UNITS)
    if has_labels:
        rot = bool((data.label == LABEL_ROT).any())
        poses = data.poses()
        if kind == "auto":
            data.kind = "rotation" if rot and not poses else ("static" if poses else "free")
            data.meta["kind_decision"] = f"auto: {data.kind} (labels from the file)"
        else:
            data.kind = kind
            data.meta["kind_decision"] = f"given: {kind} (labels from the file)"
    else:
        assign_labels(data, kind, parts, pose_per_part=pose_per_part)
    return data
