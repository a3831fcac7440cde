"""Run ``motecal`` in-process for the safety tests: the exit status, stdout
and stderr, and any exception (a traceback a user would see) left to
propagate so the test fails on it."""
from __future__ import annotations

import contextlib
import hashlib
import io
import os
from pathlib import Path

import numpy as np

from motecal.commands.main import main
from motecal.sessions.session import SessionData


def motecal(*argv) -> tuple[int, str, str]:
    """(exit status, stdout, stderr) of ``motecal ARGV``."""
    raw = io.BytesIO()
    out = io.TextIOWrapper(raw, encoding="utf-8", newline="", write_through=True)
    err = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as e:          # argparse --help / --version
            rc = e.code if isinstance(e.code, int) else 0
    out.flush()
    return rc, raw.getvalue().decode("utf-8", "replace"), err.getvalue()


def session(name="board", n=400, motes=(1,), seed=0) -> SessionData:
    """A small session of plausible integer counts."""
    rng = np.random.default_rng(seed)
    k = n // len(motes)
    mote = np.repeat(motes, k).astype(np.int32)
    seq = np.tile(np.arange(k), len(motes)).astype(np.int64)
    raw = rng.integers(-300, 300, (len(mote), 9)).astype(float)
    t = np.tile(np.arange(k) / 125.0, len(motes))
    label = np.zeros(len(mote), np.int32)
    return SessionData(name, raw, mote, seq, t, label, np.zeros(len(mote), np.uint8),
                       kind="free", meta={"source": "test"})


def make_db(path, *names, **kw) -> str:
    from motecal.sessions.store import open_store
    with open_store(str(path), create=True) as st:
        for i, name in enumerate(names or ("board",)):
            st.save_session(session(name, seed=i, **kw))
    return str(path)


def store_db(folder, data: SessionData, name: str = "s") -> str:
    """A new sqlite store ``folder/t.db`` holding ``data`` as session ``name``."""
    from motecal.sessions.store import open_store
    path = Path(folder) / "t.db"
    data.name = name
    with open_store(str(path), create=True) as st:
        st.save_session(data)
    return str(path)


def digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def snapshot(folder) -> dict[str, tuple]:
    """Every entry under ``folder``: kind, size, mtime and content hash (files)."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for n in dirs + files:
            p = os.path.join(root, n)
            st = os.lstat(p)
            h = digest(p) if os.path.isfile(p) and not os.path.islink(p) else None
            out[os.path.relpath(p, folder)] = (st.st_mode, st.st_size, st.st_mtime_ns, h)
    return out
