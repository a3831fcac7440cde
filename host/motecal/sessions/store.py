"""The motecal database: sessions, samples, link statistics and calibrations.

``open_store(target)`` opens a sqlite file (the default) or, with a
``postgresql://`` URL, a PostgreSQL server, or with a ``mysql://`` URL a MySQL
or MariaDB server (store_mysql.py).  All hold the same schema, versioned in
the ``schema_version`` table and migrated forward on open (store_schema.py).

Samples are one row each: session, mote, unwrapped sequence number, host time
``t`` (seconds since the session started, NULL if unknown), label (text as in
CSV: ``"1".."80"``, ``"rot"`` or ``""``), message flags and the nine raw
int16 counts (NULL where a sensor has no value).  ``(session, mote, seq)`` is
the primary key, so a sample can never be stored twice.

Crash safety (sqlite): write-ahead log, ``synchronous=NORMAL``; a live session
is written through a ``SessionWriter`` that commits a transaction of whole
batches every ``commit_every`` seconds, so killing the process at any moment
leaves a consistent database that lacks at most the uncommitted batch.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import itertools
import json
import os
import socket
import time
from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from .session import NOMINAL_CHIPS, NOMINAL_SCALES, SessionData, label_from_text, label_to_text
from .store_backend import Backend, StoreBusy, StoreError, store_fault  # noqa: F401
from .store_schema import (APPLICATION_ID, LINE_COUNTERS, LINK_COUNTERS, MIGRATIONS,  # noqa: F401
                           SAMPLE_COLUMNS, SCHEMA_VERSION, SIGNATURE, SIGNATURE_SINCE)
from .store_sqlite import SqliteBackend
from .temperature import rows_from_readings

INT16_MIN, INT16_MAX = -32768, 32767

_NULL = 1 << 40                    # a stored NULL, when samples are compared

# A live session waits this long for a write lock another process holds,
# buffering samples meanwhile, before it gives up (SessionWriter.commit).
LOCK_TIMEOUT_S = 60.0
LOCK_BUFFER_SAMPLES = 2_000_000     # ~0.3 GB of queued samples at most


def check_session_name(name) -> str:
    """A session name is text with something besides white space (an empty
    name could not be asked for again); UserError otherwise."""
    if not isinstance(name, str) or not name.strip():
        raise UserError(f"session name {name!r}: a session needs a name that is not "
                        "empty or blank")
    return name



# --------------------------------------------------------------------------
# Backends
# --------------------------------------------------------------------------
def _backend_for(target: str, create: bool, readonly: bool = False) -> Backend:
    if target.startswith(("postgresql://", "postgres://")):
        from .store_postgres import PostgresBackend  # its driver only when asked for
        return PostgresBackend(target, create, readonly)
    if target.startswith(("mysql://", "mariadb://")):
        from .store_mysql import MysqlBackend        # its driver only when asked for
        return MysqlBackend(target, create, readonly)
    if target.startswith("sqlite:///"):
        target = target[len("sqlite:///") - 1:] if target.startswith("sqlite:////") \
            else target[len("sqlite:///"):]
    elif "://" in target:
        raise UserError(f"unsupported database URL {target} (use a sqlite file path, "
                        "postgresql://... or mysql://...)")
    return SqliteBackend(target, create, readonly)


# --------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------
def _iso(ts: float | None) -> str | None:
    if ts is None:
        return None
    return _dt.datetime.fromtimestamp(ts, _dt.timezone.utc).isoformat(timespec="milliseconds") \
        .replace("+00:00", "Z")


def _from_iso(value) -> float | None:
    if value is None or value == "":
        return None
    if isinstance(value, (int, float)):
        return float(value)
    try:
        d = _dt.datetime.fromisoformat(str(value).replace("Z", "+00:00"))
    except ValueError:
        raise UserError(f"bad time {value!r} in session metadata (want ISO 8601)") from None
    if d.tzinfo is None:
        d = d.replace(tzinfo=_dt.timezone.utc)
    return d.timestamp()


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def _dumps(obj) -> str:
    return json.dumps(obj, default=_json_default, sort_keys=True)


def _document(obj, what: str) -> str:
    """``obj`` as stored JSON text; one line (UserError) naming ``what`` when
    it is not JSON-able."""
    try:
        return _dumps(obj)
    except (TypeError, ValueError) as e:
        raise UserError(f"{what} is not JSON: {e}") from None


def _label_texts(label: np.ndarray) -> list[str]:
    """int labels -> their text form (session.label_to_text), vectorised."""
    uniq, inv = np.unique(np.asarray(label), return_inverse=True)
    texts = np.array([label_to_text(int(u)) for u in uniq], dtype=object)
    return texts[inv].tolist()


def _labels_from_texts(texts: list[str]) -> np.ndarray:
    uniq, inv = np.unique(np.asarray(texts, dtype=object).astype(str), return_inverse=True)
    vals = np.array([label_from_text(u) for u in uniq], dtype=np.int32)
    return vals[inv] if len(texts) else np.zeros(0, np.int32)


_META_COLUMNS = ("source", "rate_hz", "notes")


@dataclass
class SessionInfo:
    id: int
    name: str
    kind: str
    started: float
    ended: float | None


# --------------------------------------------------------------------------
# The store
# --------------------------------------------------------------------------
class Store:
    """An open motecal database.  Use ``open_store``; close it (or use ``with``)."""

    def __init__(self, backend: Backend, create: bool = False):
        self._b = backend
        self.target = backend.display
        self._check_schema(create)

    # -- context manager ---------------------------------------------------
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        if self._b is not None:
            self._b.close()
            self._b = None

    # -- schema ------------------------------------------------------------
    def _foreign(self, why: str) -> UserError:
        return UserError(f"{self.target} is not a motecal database ({why}); nothing was "
                         "written to it")

    def _version(self, tables: set[str], create: bool) -> int:
        """Schema version of the database (0: empty and may be created).

        A motecal database is recognised by its application id (sqlite) and
        its signature: the tables and columns of ``SIGNATURE`` (and of the
        later versions, ``SIGNATURE_SINCE``), one whole-number version.  Any
        other file is refused before anything is written to it."""
        b = self._b
        app = b.app_id()
        if app not in (None, 0, APPLICATION_ID):
            raise self._foreign(f"its sqlite application id is {app:#x}, another program's")
        if not tables:
            if not create or b.readonly:
                raise self._foreign("it is empty")
            return 0
        missing = [t for t in SIGNATURE if t not in tables]
        if missing:
            raise self._foreign(f"no {', '.join(missing)} table; it holds "
                                f"{', '.join(sorted(tables)[:5])}")
        for table, cols in SIGNATURE.items():
            lack = cols - b.columns(table)
            if lack:
                raise self._foreign(f"table {table} lacks {', '.join(sorted(lack))}")
        rows = self._query("SELECT version FROM schema_version")
        if len(rows) != 1 or not isinstance(rows[0][0], int) or isinstance(rows[0][0], bool) \
                or rows[0][0] < 1:
            raise self._foreign("its schema_version is not one whole number")
        version = rows[0][0]
        if version > SCHEMA_VERSION:
            raise UserError(f"{self.target} has schema version {version}, newer than this "
                            f"motecal understands ({SCHEMA_VERSION}); upgrade motecal")
        for since, names in SIGNATURE_SINCE.items():
            lack = [t for t in names if since <= version and t not in tables]
            if lack:
                raise self._foreign(f"schema version {version} without {', '.join(lack)}")
        return version

    def _check_schema(self, create: bool):
        b = self._b
        try:
            self._tables = b.tables()
            version = self._version(self._tables, create)
        except b.errors as e:
            raise self._foreign(" ".join(str(e).split())[:200]) from None
        self.version = version
        if b.readonly:
            return                  # an older schema is read as it is (see the readers)
        b.prepare_writes()          # only now: never on a foreign file
        if version < SCHEMA_VERSION or b.app_id() not in (None, APPLICATION_ID):
            self._migrate(create)
            self._tables = b.tables()
            self.version = SCHEMA_VERSION

    @property
    def readonly(self) -> bool:
        """Opened read-only (asked for, or the file or its folder cannot be written)."""
        return bool(self._b.readonly)

    def _migrate(self, create: bool):
        """Bring the schema to SCHEMA_VERSION in one transaction (re-checked under
        the lock, as another process may have done it meanwhile), and mark the
        file as motecal's (sqlite application id)."""
        b = self._b
        with self._tx() as cur:
            b.lock_schema(cur)
            current = self._version(b.tables(), create)
            for v in range(current + 1, SCHEMA_VERSION + 1):
                for stmt in MIGRATIONS[v]:
                    cur.execute(stmt.format(**b.types))
            if current == 0:
                cur.execute(b.sql("INSERT INTO schema_version (version) VALUES (?)"),
                            (SCHEMA_VERSION,))
            elif current < SCHEMA_VERSION:
                cur.execute(b.sql("UPDATE schema_version SET version = ?"), (SCHEMA_VERSION,))
            b.set_app_id(cur)

    @property
    def schema_version(self) -> int:
        return int(self._query("SELECT version FROM schema_version")[0][0])

    # -- low level -----------------------------------------------------------
    @contextlib.contextmanager
    def _tx(self):
        """One transaction: everything inside is committed together or not at
        all.  A driver error (disk full, lock, I/O) rolls back and becomes a
        ``StoreError`` (``StoreBusy`` for a lock another process holds)."""
        b = self._b
        try:
            b.begin()
        except b.errors as e:
            raise store_fault(self.target, e) from None
        cur = b.cursor()
        try:
            yield cur
            b.commit()
        except BaseException as e:
            with contextlib.suppress(Exception):
                b.rollback()
            if isinstance(e, b.errors):
                raise store_fault(self.target, e) from None
            raise

    def set_busy_timeout(self, seconds: float) -> None:
        """How long one attempt waits for another process's write lock (sqlite)."""
        self._b.set_busy_timeout(seconds)

    def _query(self, sql: str, params=()) -> list[tuple]:
        cur = self._b.cursor()
        cur.execute(self._b.sql(sql), params)
        return cur.fetchall()

    def _info(self, name: str) -> SessionInfo | None:
        rows = self._query("SELECT id, name, kind, started, ended FROM sessions WHERE name = ?",
                           (name,))
        return SessionInfo(*rows[0]) if rows else None

    def _require(self, name: str) -> SessionInfo:
        info = self._info(name)
        if info is None:
            names = [r[0] for r in self._query("SELECT name FROM sessions ORDER BY id")]
            known = ", ".join(names[:20]) + (" ..." if len(names) > 20 else "")
            raise UserError(f"unknown session {name!r} in {self.target}"
                            + (f" (known: {known})" if names else " (it holds no sessions)"))
        return info

    # -- sessions --------------------------------------------------------------
    def sessions(self) -> list[dict]:
        """Every session: name, kind, started/ended (ISO), source, notes, rate_hz,
        samples, motes, poses (distinct static labels), in creation order."""
        counts: dict[int, dict] = {}
        for sid, mote, n, npose in self._query(
                "SELECT session, mote, COUNT(*), "
                "COUNT(DISTINCT CASE WHEN label NOT IN ('', 'rot') THEN label END) "
                "FROM samples GROUP BY session, mote"):
            c = counts.setdefault(sid, {"samples": 0, "motes": [], "poses": 0})
            c["samples"] += int(n)
            c["motes"].append(int(mote))
            c["poses"] = max(c["poses"], int(npose))
        out = []
        for sid, name, kind, started, ended, source, rate, notes in self._query(
                "SELECT id, name, kind, started, ended, source, rate_hz, notes "
                "FROM sessions ORDER BY id"):
            c = counts.get(sid, {"samples": 0, "motes": [], "poses": 0})
            out.append(dict(name=name, kind=kind, started=_iso(started), ended=_iso(ended),
                            source=source, rate_hz=rate, notes=notes, **c))
        return out

    def session_exists(self, name: str) -> bool:
        return self._info(name) is not None

    def _meta_row(self, name, kind, scales, chips, meta):
        meta = dict(meta or {})
        started = _from_iso(meta.pop("started", None)) or time.time()
        ended = _from_iso(meta.pop("ended", None))
        cols = {k: meta.pop(k, None) for k in _META_COLUMNS}
        if cols["rate_hz"] is not None:
            cols["rate_hz"] = float(cols["rate_hz"])
        return (name, kind, started, ended, cols["source"], cols["rate_hz"], cols["notes"],
                _dumps(dict(scales or NOMINAL_SCALES)), _dumps(dict(chips or NOMINAL_CHIPS)),
                _dumps(meta))

    def _insert_session(self, cur, row) -> int:
        cur.execute(self._b.sql(
            "INSERT INTO sessions (name, kind, started, ended, source, rate_hz, notes, "
            "scales, chips, meta) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?) RETURNING id"), row)
        return int(cur.fetchone()[0])

    def _delete_session(self, cur, sid: int):
        for table in ("samples", "calibrations", "link_stats", "line_stats", "events",
                      "writers", "sample_conflicts", "temps", "diagnoses"):
            cur.execute(self._b.sql(f"DELETE FROM {table} WHERE session = ?"), (sid,))
        cur.execute(self._b.sql("DELETE FROM sessions WHERE id = ?"), (sid,))

    def save_session(self, data: SessionData, *, replace: bool = False) -> None:
        """Store a whole session (an import) in one transaction: all or nothing.

        ``raw`` must hold integer counts within int16 (NaN = missing); (mote,
        seq) must be unique.  An existing session of that name is a UserError
        unless ``replace``, which deletes it (and its calibrations) first.
        """
        check_session_name(data.name)
        raw = np.asarray(data.raw, float)
        finite = np.isfinite(raw)
        if np.isinf(raw).any():
            raise UserError(f"session {data.name!r}: infinite sample values")
        vals = raw[finite]
        if vals.size and (np.any(vals != np.round(vals)) or vals.min() < INT16_MIN
                          or vals.max() > INT16_MAX):
            raise UserError(f"session {data.name!r}: samples must be integer counts "
                            f"within {INT16_MIN}..{INT16_MAX}")
        order = np.lexsort((data.seq, data.mote))
        m, s = data.mote[order], data.seq[order]
        dup = (m[1:] == m[:-1]) & (s[1:] == s[:-1])
        if dup.any():
            i = int(np.flatnonzero(dup)[0])
            raise UserError(f"session {data.name!r}: mote {int(m[i])} has sequence number "
                            f"{int(s[i])} twice")
        t = np.where(np.isfinite(data.t), data.t, np.nan)
        row = self._meta_row(data.name, data.kind, data.scales, data.chips, data.meta)
        with self._tx() as cur:
            info = self._info(data.name)
            if info is not None:
                if not replace:
                    raise UserError(f"session {data.name!r} already exists in {self.target}")
                self._delete_session(cur, info.id)
            sid = self._insert_session(cur, row)
            n = len(data)
            step = 100_000
            labels = _label_texts(data.label)
            int_rows = np.where(finite, raw, 0).astype(np.int64)
            for a in range(0, n, step):
                sl = slice(a, a + step)
                cols = [np.where(finite[sl, j], int_rows[sl, j], None).tolist() for j in range(9)]
                tt = t[sl]
                tcol = np.where(np.isnan(tt), None, tt).tolist()
                self._b_insert(cur, zip(itertools.repeat(sid), data.mote[sl].tolist(),
                                        data.seq[sl].tolist(), tcol, labels[sl],
                                        data.flags[sl].tolist(), *cols))
            if data.temp is not None:
                has = np.isfinite(data.temp)
                tt = t[has]
                cur.executemany(self._b.sql(_INSERT_TEMPS), zip(
                    itertools.repeat(sid), data.mote[has].tolist(), data.seq[has].tolist(),
                    np.where(np.isnan(tt), None, tt).tolist(), data.temp[has].tolist(),
                    itertools.repeat(1)))

    def _b_insert(self, cur, rows):
        """Insert full sample rows (session, mote, seq, t, label, flags, 9 values)."""
        self._b.insert_samples(cur, rows)

    def load_session(self, name: str, mote: int | None = None) -> SessionData:
        """A session's samples ordered by mote and sequence number, with its metadata."""
        info = self._require(name)
        (kind, started, ended, source, rate, notes, scales, chips, meta), = self._query(
            "SELECT kind, started, ended, source, rate_hz, notes, scales, chips, meta "
            "FROM sessions WHERE id = ?", (info.id,))
        sql = ("SELECT mote, seq, t, flags, ax, ay, az, gx, gy, gz, mx, my, mz, label "
               "FROM samples WHERE session = ?")
        params: tuple = (info.id,)
        if mote is not None:
            sql += " AND mote = ?"
            params += (int(mote),)
        rows = self._query(sql + " ORDER BY mote, seq", params)
        if mote is not None and not rows:
            motes = [r[0] for r in self._query(
                "SELECT DISTINCT mote FROM samples WHERE session = ? ORDER BY mote", (info.id,))]
            raise UserError(f"session {name!r} has no samples of mote {mote}"
                            + (f" (motes: {', '.join(map(str, motes))})" if motes else ""))
        if rows:
            num = np.array([r[:13] for r in rows], dtype=float)
            labels = _labels_from_texts([r[13] for r in rows])
        else:
            num = np.zeros((0, 13))
            labels = np.zeros(0, np.int32)
        meta = json.loads(meta)
        meta.update({k: v for k, v in (("source", source), ("rate_hz", rate), ("notes", notes))
                     if v is not None})
        meta["started"] = _iso(started)
        if ended is not None:
            meta["ended"] = _iso(ended)
        data = SessionData(name=name, raw=num[:, 4:13], mote=num[:, 0].astype(np.int32),
                           seq=num[:, 1].astype(np.int64), t=num[:, 2], label=labels,
                           flags=num[:, 3].astype(np.uint8), kind=kind,
                           scales=json.loads(scales), chips=json.loads(chips), meta=meta)
        data.temp = self._temps_of(info.id, data, mote)
        return data

    def temps(self, session: str, mote: int | None = None) -> np.ndarray:
        """A session's temperature readings as stored: (k, 5) float array of
        mote, seq, t (NaN unknown), degrees C, readings averaged; ordered by
        mote and seq."""
        return self._readings(self._require(session).id, mote)

    def _readings(self, sid: int, mote: int | None) -> np.ndarray:
        if "temps" not in self._tables:        # an older schema, opened read-only
            return np.zeros((0, 5))
        sql = "SELECT mote, seq, t, temp_c, count FROM temps WHERE session = ?"
        params: tuple = (sid,)
        if mote is not None:
            sql += " AND mote = ?"
            params += (int(mote),)
        rows = self._query(sql + " ORDER BY mote, seq", params)
        return np.array([[np.nan if v is None else v for v in r] for r in rows],
                        dtype=float).reshape(-1, 5)

    def _temps_of(self, sid: int, data: SessionData, mote: int | None):
        """SessionData.temp from the stored readings (None when there are none)."""
        r = self._readings(sid, mote)
        if not len(r):
            return None
        return rows_from_readings(data.mote, data.seq, r[:, 0], r[:, 1], r[:, 3], r[:, 4],
                                  data.rate())

    # -- calibrations ----------------------------------------------------------
    def save_calibration(self, session: str, mote: int, cal: dict) -> int:
        """Store a calibration (JSON-able dict) of one mote of a session; returns its id."""
        info = self._require(session)
        text = _document(cal, f"calibration for {session!r} mote {mote}")
        with self._tx() as cur:
            cur.execute(self._b.sql(
                "INSERT INTO calibrations (session, mote, created, cal) VALUES (?, ?, ?, ?) "
                "RETURNING id"), (info.id, int(mote), time.time(), text))
            return int(cur.fetchone()[0])

    def load_calibration(self, session: str, mote: int | None = None) -> dict:
        """The latest calibration of a session (of one mote, or of any mote)."""
        info = self._require(session)
        sql = "SELECT cal FROM calibrations WHERE session = ?"
        params: tuple = (info.id,)
        if mote is not None:
            sql += " AND mote = ?"
            params += (int(mote),)
        rows = self._query(sql + " ORDER BY id DESC LIMIT 1", params)
        if not rows:
            raise UserError(f"no calibration stored for session {session!r}"
                            + (f" mote {mote}" if mote is not None else ""))
        return json.loads(rows[0][0])

    # -- diagnoses -------------------------------------------------------------------
    def save_diagnosis(self, session: str, mote: int, diagnosis: dict, *, tool: str,
                       data_key: str) -> int:
        """Keep a diagnosis (``motecal diagnose``'s JSON) of one mote of a
        session with the tool version that made it and the fingerprint of the
        rows it saw; returns its id."""
        info = self._require(session)
        text = _document(diagnosis, f"diagnosis for {session!r} mote {mote}")
        with self._tx() as cur:
            cur.execute(self._b.sql(
                "INSERT INTO diagnoses (session, mote, created, tool, data_key, diagnosis) "
                "VALUES (?, ?, ?, ?, ?, ?) RETURNING id"),
                (info.id, int(mote), time.time(), str(tool), str(data_key), text))
            return int(cur.fetchone()[0])

    def load_diagnosis(self, session: str, mote: int) -> dict | None:
        """The latest diagnosis kept for one mote of a session, ``{"id",
        "created" (ISO), "tool", "data_key", "diagnosis"}``, or None (none
        kept, or a database older than the diagnoses table)."""
        info = self._require(session)
        if "diagnoses" not in self._tables:
            return None
        rows = self._query("SELECT id, created, tool, data_key, diagnosis FROM diagnoses "
                           "WHERE session = ? AND mote = ? ORDER BY id DESC LIMIT 1",
                           (info.id, int(mote)))
        if not rows:
            return None
        i, created, tool, key, text = rows[0]
        try:
            d = json.loads(text)
        except (TypeError, ValueError):
            d = None
        return {"id": int(i), "created": _iso(created), "tool": tool, "data_key": key,
                "diagnosis": d}

    # -- link statistics and events ------------------------------------------------
    def link_stats(self, session: str) -> dict:
        """``{"line": {...}, "motes": {mote: {...}}}`` counters of a session."""
        info = self._require(session)
        if "link_stats" not in self._tables:        # schema 1, opened read-only
            return {"line": {}, "motes": {}}
        have_link = self._b.columns("link_stats")   # an older schema lacks later counters
        names = [n for n in LINK_COUNTERS if n in have_link]
        motes = {int(r[0]): {**dict(zip(names, (int(v) for v in r[1:]))),
                             **{n: 0 for n in LINK_COUNTERS if n not in have_link}}
                 for r in self._query(f"SELECT mote, {', '.join(names)} FROM link_stats "
                                      "WHERE session = ? ORDER BY mote", (info.id,))}
        have = self._b.columns("line_stats")        # an older schema lacks later counters
        lnames = [n for n in LINE_COUNTERS if n in have]
        rows = self._query(f"SELECT {', '.join(lnames)} FROM line_stats WHERE session = ?",
                           (info.id,))
        line = {n: (float(v) if n == "gap_s" else int(v))
                for n, v in zip(lnames, rows[0])} if rows else {}
        if rows:
            line.update({n: 0 for n in LINE_COUNTERS if n not in have})
        return {"line": line, "motes": motes}

    def events(self, session: str) -> list[dict]:
        info = self._require(session)
        if "events" not in self._tables:
            return []
        return [dict(t=t, kind=k, mote=m, detail=d) for t, k, m, d in self._query(
            "SELECT t, kind, mote, detail FROM events WHERE session = ? ORDER BY t",
            (info.id,))]

    # -- live sessions ---------------------------------------------------------------
    def open_session(self, name: str, *, kind: str, meta: dict | None = None,
                     scales: dict | None = None, chips: dict | None = None,
                     append: bool = False, commit_every: float = 0.25,
                     lock_timeout: float = LOCK_TIMEOUT_S) -> "SessionWriter":
        """Start (or, with ``append``, continue) a live session; returns its writer."""
        check_session_name(name)
        info = self._info(name)
        if info is not None and not append:
            raise UserError(f"session {name!r} already exists in {self.target} "
                            "(choose another name, or --append to add to it)")
        if info is None and append:
            raise UserError(f"session {name!r} does not exist in {self.target}: --append "
                            "continues a session (see motecal sessions; leave --append out "
                            "to start one)")
        if info is None:
            with self._tx() as cur:
                sid = self._insert_session(cur, self._meta_row(name, kind, scales, chips, meta))
            info = self._info(name)
        else:
            with self._tx() as cur:
                cur.execute(self._b.sql("UPDATE sessions SET ended = NULL WHERE id = ?"),
                            (info.id,))
            sid = info.id
        w = SessionWriter(self, sid, name, info.started, commit_every, lock_timeout)
        w.source = (meta or {}).get("source")
        return w

    def writers(self, session: str) -> list[dict]:
        """The live writers that logged into a session, each with its own counts:
        samples it stored, duplicates (already stored the same by another
        writer) and conflicts (stored with other values; kept in
        ``sample_conflicts``)."""
        info = self._require(session)
        if "writers" not in self._tables:
            return []                            # an older schema, opened read-only
        return [dict(writer=w, source=src, started=_iso(a), ended=_iso(e), stored=int(n),
                     duplicates=int(d), conflicts=int(c)) for w, src, a, e, n, d, c in self._query(
            "SELECT writer, source, started, ended, stored, duplicates, conflicts FROM writers "
            "WHERE session = ? ORDER BY started, writer", (info.id,))]

    def conflicts(self, session: str) -> SessionData:
        """The samples writers received under a stored key with other values."""
        info = self._require(session)
        rows = self._query("SELECT mote, seq, t, flags, ax, ay, az, gx, gy, gz, mx, my, mz "
                           "FROM sample_conflicts WHERE session = ? ORDER BY mote, seq",
                           (info.id,)) if "sample_conflicts" in self._tables else []
        num = np.array([[np.nan if v is None else v for v in r] for r in rows],
                       dtype=float).reshape(-1, 13)
        return SessionData(name=session, raw=num[:, 4:13], mote=num[:, 0].astype(np.int32),
                           seq=num[:, 1].astype(np.int64), t=num[:, 2],
                           label=np.zeros(len(num), np.int32),
                           flags=num[:, 3].astype(np.uint8), kind="conflicts")

    def last_seqs(self, session: str) -> dict[int, int]:
        """Highest stored sequence number per mote (to continue an appended session)."""
        info = self._require(session)
        return {int(m): int(s) for m, s in self._query(
            "SELECT mote, MAX(seq) FROM samples WHERE session = ? GROUP BY mote", (info.id,))}


_INSERT_TEMPS = ("INSERT INTO temps (session, mote, seq, t, temp_c, count) "
                 "VALUES (?, ?, ?, ?, ?, ?) ON CONFLICT DO NOTHING")


class SessionWriter:
    """Batched writer of one live session; the logger's side of the store.

    ``add_samples`` and ``set_label`` only queue; ``commit`` writes everything
    queued in one transaction (samples first, then labels, counters, events),
    and ``due`` says when ``commit_every`` seconds have passed.

    Several writers may log into one session at once (two BaseStations that
    hear the same motes, or other motes): a sample whose (mote, seq) is not
    stored yet is stored, and belongs to the writer that committed it first;
    one stored already with the same flags and values is a duplicate
    (counted); one stored with other values is a conflict: kept whole in
    ``sample_conflicts`` with this writer's id and counted, never dropped.
    Each writer keeps its counts in its own ``writers`` row (``writer_id``).
    """

    _INSERT = ("INSERT INTO samples (session, mote, seq, t, flags, ax, ay, az, gx, gy, gz, "
               "mx, my, mz) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
               "ON CONFLICT DO NOTHING")

    def __init__(self, store: Store, sid: int, name: str, started: float, commit_every: float,
                 lock_timeout: float = LOCK_TIMEOUT_S):
        self.store = store
        self.lock_timeout = lock_timeout
        self.locked_since: float | None = None   # monotonic time the lock wait began
        self.lock_waits = 0                       # times a commit found the lock held
        self.id = sid
        self.name = name
        self.started = started          # unix seconds; t is relative to it
        self.commit_every = commit_every
        self._rows: list[tuple] = []    # (mote, seq, t, flags, raw) arrays
        self._labels: list[tuple] = []
        self._events: list[tuple] = []
        self._temps: list[tuple] = []   # (session, mote, seq, t, temp_c, count)
        self._link: dict[int, dict] = {}
        self._line: dict | None = None
        self._last_commit = time.monotonic()
        self.committed_samples = 0
        self.commits = 0
        self.duplicates = 0              # samples another writer had stored the same
        self.conflicts = 0               # ... had stored with other values (kept aside)
        self.writer_id = f"{socket.gethostname()}:{os.getpid()}:{id(self):x}"
        self.source: str | None = None

    def now(self) -> float:
        """Seconds since the session started (the ``t`` column's clock)."""
        return time.time() - self.started

    @property
    def pending(self) -> int:
        return sum(len(r[1]) for r in self._rows)

    def add_samples(self, mote, seq, t, flags, raw) -> None:
        """Queue records: arrays of mote, unwrapped seq, t, flags and (n, 9) int counts."""
        if len(seq):
            self._rows.append((np.asarray(mote), np.asarray(seq), np.asarray(t, float),
                               np.asarray(flags), np.asarray(raw)))

    def add_temp(self, mote: int, seq: int, t: float, temp_c: float, count: int) -> None:
        """Queue one temperature reading of a mote: the mean of ``count`` readings,
        in degrees C, the newest of the sample with unwrapped sequence number
        ``seq``; ``t`` when it came (the ``t`` column's clock).  A reading
        stored already (the same message twice) is kept once."""
        self._temps.append((self.id, int(mote), int(seq), float(t), float(temp_c), int(count)))

    def set_label(self, mote: int, seq_lo: int, seq_hi: int, label: int) -> None:
        """Label the stored records of one mote with seq_lo <= seq <= seq_hi."""
        self._labels.append((label_to_text(label), self.id, int(mote), int(seq_lo), int(seq_hi)))

    def add_event(self, kind: str, detail: str = "", mote: int | None = None,
                  t: float | None = None) -> None:
        self._events.append((self.id, self.now() if t is None else t, kind, mote, detail))

    def set_link_stats(self, mote: int, counters: dict) -> None:
        unknown = set(counters) - set(LINK_COUNTERS)
        if unknown:
            raise ValueError(f"unknown link counters {sorted(unknown)}")
        self._link[int(mote)] = dict(counters)

    def set_line_stats(self, counters: dict) -> None:
        unknown = set(counters) - set(LINE_COUNTERS)
        if unknown:
            raise ValueError(f"unknown line counters {sorted(unknown)}")
        self._line = dict(counters)

    @property
    def due(self) -> bool:
        """``commit_every`` seconds have passed since the last commit."""
        return time.monotonic() - self._last_commit >= self.commit_every

    def commit(self) -> bool:
        """Write everything queued in one transaction; True when done.

        When another process holds the write lock nothing is lost: the queue
        is kept and False returned (the caller goes on reading and tries again);
        after ``lock_timeout`` seconds of that, or ``LOCK_BUFFER_SAMPLES``
        queued, ``StoreBusy`` is raised.  Other failures (disk full, I/O) raise
        ``StoreError``; the queue is then kept too (``pending``)."""
        try:
            self._commit()
        except StoreBusy:
            now = time.monotonic()
            if self.locked_since is None:
                self.locked_since = now
                self.lock_waits += 1
            waited = now - self.locked_since
            if waited >= self.lock_timeout or self.pending > LOCK_BUFFER_SAMPLES:
                raise StoreBusy(f"{self.store.target}: the database stayed locked by another "
                                f"process for {waited:.0f} s ({self.pending} samples held in "
                                "memory could not be stored)") from None
            return False
        self.locked_since = None
        return True

    def discard(self) -> int:
        """Drop what is queued (it cannot be stored); returns the samples dropped."""
        n = self.pending
        self._rows, self._labels, self._events, self._temps = [], [], [], []
        self._link, self._line = {}, None
        return n

    def _commit(self) -> None:
        st = self.store
        b = st._b
        rows, labels, events, temps = self._rows, self._labels, self._events, self._temps
        link, line = self._link, self._line
        n = 0
        with st._tx() as cur:
            if rows:
                mote = np.concatenate([r[0] for r in rows])
                seq = np.concatenate([r[1] for r in rows])
                t = np.concatenate([r[2] for r in rows])
                flags = np.concatenate([r[3] for r in rows])
                raw = np.concatenate([r[4] for r in rows]).astype(np.int64)
                n, dups, clash = self._insert(cur, mote, seq, t, flags, raw)
                self._writer_row(cur, n, dups, clash)
            elif self.commits == 0:
                self._writer_row(cur, 0, 0, 0)
            if temps:
                cur.executemany(b.sql(_INSERT_TEMPS), temps)
            if labels:
                cur.executemany(b.sql("UPDATE samples SET label = ? WHERE session = ? AND "
                                      "mote = ? AND seq BETWEEN ? AND ?"), labels)
            if events:
                cur.executemany(b.sql("INSERT INTO events (session, t, kind, mote, detail) "
                                      "VALUES (?, ?, ?, ?, ?)"), events)
            for mote_id, c in link.items():
                self._upsert(cur, "link_stats", {"session": self.id, "mote": mote_id}, c)
            if line is not None:
                self._upsert(cur, "line_stats", {"session": self.id}, line)
        self._rows, self._labels, self._events, self._temps = [], [], [], []
        self._link, self._line = {}, None
        self.committed_samples += n
        self.commits += 1
        self._last_commit = time.monotonic()

    # -- several writers ----------------------------------------------------------
    _KEY_COLS = "seq, flags, ax, ay, az, gx, gy, gz, mx, my, mz"

    def _stored(self, cur, m: int, seqs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stored (seq, [flags + 9 values]) of mote ``m`` within the span of ``seqs``
        (NULL read as a value no sample has)."""
        cur.execute(self.store._b.sql(
            f"SELECT {self._KEY_COLS} FROM samples WHERE session = ? AND mote = ? "
            "AND seq BETWEEN ? AND ? ORDER BY seq"), (self.id, m, int(seqs.min()), int(seqs.max())))
        got = cur.fetchall()
        if not got:
            return np.zeros(0, np.int64), np.zeros((0, 10), np.int64)
        arr = np.array([[_NULL if v is None else v for v in r] for r in got], dtype=np.int64)
        return arr[:, 0], arr[:, 1:]

    def _classify(self, cur, mote, seq, flags, raw):
        """Per row: 0 new, 1 duplicate of a stored sample, 2 conflict with one."""
        kind = np.zeros(len(seq), np.int8)
        vals = np.column_stack([flags.astype(np.int64), raw])
        for m in np.unique(mote):
            rows = np.flatnonzero(mote == m)
            sseq, svals = self._stored(cur, int(m), seq[rows])
            if not len(sseq):
                continue
            pos = np.searchsorted(sseq, seq[rows])
            hit = pos < len(sseq)
            hit[hit] = sseq[pos[hit]] == seq[rows][hit]
            same = np.zeros(len(rows), bool)
            same[hit] = (svals[pos[hit]] == vals[rows[hit]]).all(axis=1)
            kind[rows[hit & same]] = 1
            kind[rows[hit & ~same]] = 2
        return kind

    def _insert(self, cur, mote, seq, t, flags, raw) -> tuple[int, int, int]:
        """Store the new samples, count duplicates, keep conflicts aside;
        returns (stored, duplicates, conflicts)."""
        b = self.store._b
        kind = self._classify(cur, mote, seq, flags, raw)
        new = kind == 0
        rows = lambda sel: zip(itertools.repeat(self.id), mote[sel].tolist(),  # noqa: E731
                               seq[sel].tolist(), t[sel].tolist(), flags[sel].tolist(),
                               *raw[sel].T.tolist())
        cur.executemany(b.sql(self._INSERT), rows(new))
        stored = cur.rowcount if cur.rowcount is not None and cur.rowcount >= 0 \
            else int(new.sum())
        if stored < new.sum():
            # another writer committed some of these keys meanwhile (PostgreSQL
            # runs writers side by side): what differs from ours is a conflict
            again = self._classify(cur, mote[new], seq[new], flags[new], raw[new])
            idx = np.flatnonzero(new)
            kind[idx[again == 2]] = 2
            twins = int(new.sum()) - stored - int((again == 2).sum())
        else:
            twins = 0
        clash = kind == 2
        if clash.any():
            cur.executemany(b.sql(
                "INSERT INTO sample_conflicts (session, mote, seq, t, flags, ax, ay, az, gx, "
                "gy, gz, mx, my, mz, writer, found) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
                "?, ?, ?, ?, ?)"),
                [r + (self.writer_id, time.time()) for r in rows(clash)])
        return stored, int((kind == 1).sum()) + twins, int(clash.sum())

    def _writer_row(self, cur, stored: int, dups: int, clash: int) -> None:
        """This writer's own row of counts (added to in the same transaction)."""
        now = time.time()
        cur.execute(self.store._b.sql(
            "INSERT INTO writers (session, writer, source, started, updated, stored, duplicates, "
            "conflicts) VALUES (?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (session, writer) DO UPDATE "
            "SET updated = excluded.updated, stored = writers.stored + excluded.stored, "
            "duplicates = writers.duplicates + excluded.duplicates, "
            "conflicts = writers.conflicts + excluded.conflicts"),
            (self.id, self.writer_id, self.source, now, now, stored, dups, clash))
        self.duplicates += dups
        self.conflicts += clash

    def _upsert(self, cur, table: str, key: dict, counters: dict) -> None:
        """Set a row of counters (link_stats / line_stats) to these values."""
        values = {**key, **counters, "updated": time.time()}
        names = list(values)
        cur.execute(self.store._b.sql(
            f"INSERT INTO {table} ({', '.join(names)}) VALUES ({', '.join('?' * len(names))}) "
            f"ON CONFLICT ({', '.join(key)}) DO UPDATE SET "
            + ", ".join(f"{k} = excluded.{k}" for k in names if k not in key)),
            tuple(values.values()))

    def end(self) -> None:
        """Commit what is queued and mark the session ended (waiting for a
        held lock up to ``lock_timeout``)."""
        while not self.commit():
            time.sleep(0.05)
        self.mark_ended()

    def mark_ended(self) -> None:
        """Mark the session ended, with what was committed."""
        st = self.store
        now = time.time()
        with st._tx() as cur:
            cur.execute(st._b.sql("UPDATE sessions SET ended = ? WHERE id = ?"), (now, self.id))
            cur.execute(st._b.sql("UPDATE writers SET ended = ? WHERE session = ? AND writer = ?"),
                        (now, self.id, self.writer_id))


def open_store(target: str, *, create: bool = False, readonly: bool = False) -> Store:
    """Open a motecal database: a sqlite file path (or ``sqlite:///path``), a
    ``postgresql://`` or a ``mysql://`` URL.  ``create`` makes a new sqlite file if there is none.
    ``readonly`` (commands that only read) opens it read-only: nothing is
    written, an older schema is read as it is, read-only media work; a file
    that cannot be written is opened so anyway (``Store.readonly``).
    Problems (missing, unwritable, not a motecal database, newer schema) raise
    UserError with one line; nothing is written to a file that is not a
    motecal database."""
    if not target:
        raise UserError("no database given (--db FILE)")
    if str(target) == "-":
        raise UserError("--db -: a database is a file or a URL, not standard input/output")
    if create and readonly:
        raise ValueError("create and readonly exclude each other")
    backend = _backend_for(str(target), create, readonly)
    try:
        return Store(backend, create=create or backend.name != "sqlite")
    except BaseException:
        backend.close()
        raise
