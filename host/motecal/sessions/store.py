"""The motecal database: sessions, samples, link statistics and calibrations.

``open_store(target)`` opens a sqlite file (the default) or, with a
``postgresql://`` URL, a PostgreSQL server, or with a ``mysql://`` URL a MySQL
or MariaDB server.  All hold the same schema, versioned in the
``schema_version`` table and migrated forward on open.  The parts:

* store.py          -- ``Store`` (sessions in and out, calibrations, diagnoses,
                       counters, the schema check and migration), ``open_store``;
* store_backend.py  -- the one interface a backend implements, the store's errors;
* store_sqlite.py, store_postgres.py, store_mysql.py -- the backends;
* store_schema.py   -- schema version, migrations, link and line counters;
* store_writer.py   -- ``SessionWriter``, a live session's batched writer;
* store_values.py   -- times, JSON documents and labels as stored.

Other modules import all of it from here (``__all__``).

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
import itertools
import json
import time
from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from .session import NOMINAL_CHIPS, NOMINAL_SCALES, SessionData
from .store_backend import Backend, StoreBusy, StoreError, shown_url, store_fault
from .store_schema import (APPLICATION_ID, LINE_COUNTERS, LINK_COUNTERS, MIGRATIONS,
                           SAMPLE_COLUMNS, SCHEMA_VERSION, SIGNATURE, SIGNATURE_SINCE)
from .store_sqlite import SqliteBackend
from .store_values import (check_rows, document, dumps, from_iso, iso, label_texts,
                           labels_from_texts)
from .store_writer import INSERT_TEMPS, LOCK_BUFFER_SAMPLES, LOCK_TIMEOUT_S, SessionWriter
from .temperature import rows_from_readings

# What other modules import from here: the store itself, and the names of the
# modules it is made of (one import path for the database).
__all__ = ["Store", "SessionInfo", "open_store", "check_session_name", "INT16_MIN", "INT16_MAX",
           "Backend", "StoreError", "StoreBusy", "store_fault",
           "SessionWriter", "LOCK_TIMEOUT_S", "LOCK_BUFFER_SAMPLES",
           "SCHEMA_VERSION", "MIGRATIONS", "SAMPLE_COLUMNS", "LINK_COUNTERS", "LINE_COUNTERS",
           "APPLICATION_ID", "SIGNATURE", "SIGNATURE_SINCE"]

INT16_MIN, INT16_MAX = -32768, 32767


def check_session_name(name) -> str:
    """A session name is text with something besides white space (an empty
    name could not be asked for again); UserError otherwise."""
    if not isinstance(name, str) or not name.strip():
        raise UserError(f"session name {name!r}: a session needs a name that is not "
                        "empty or blank")
    return name


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
            out.append(dict(name=name, kind=kind, started=iso(started), ended=iso(ended),
                            source=source, rate_hz=rate, notes=notes, **c))
        return out

    def session_exists(self, name: str) -> bool:
        return self._info(name) is not None

    def _meta_row(self, name, kind, scales, chips, meta):
        meta = dict(meta or {})
        started = from_iso(meta.pop("started", None)) or time.time()
        ended = from_iso(meta.pop("ended", None))
        cols = {k: meta.pop(k, None) for k in _META_COLUMNS}
        if cols["rate_hz"] is not None:
            cols["rate_hz"] = float(cols["rate_hz"])
        return (name, kind, started, ended, cols["source"], cols["rate_hz"], cols["notes"],
                dumps(dict(scales or NOMINAL_SCALES)), dumps(dict(chips or NOMINAL_CHIPS)),
                dumps(meta))

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
        check_rows(data, INT16_MIN, INT16_MAX)
        row = self._meta_row(data.name, data.kind, data.scales, data.chips, data.meta)
        with self._tx() as cur:
            info = self._info(data.name)
            if info is not None:
                if not replace:
                    raise UserError(f"session {data.name!r} already exists in {self.target}")
                self._delete_session(cur, info.id)
            sid = self._insert_session(cur, row)
            self._insert_rows(cur, sid, data)

    def append_session(self, data: SessionData, rows: SessionData) -> None:
        """Add ``rows`` to the stored session ``data.name`` and give it
        ``data``'s kind, scales, chips and metadata, in one transaction
        (``motecal import --append``: ``sessions.combine.append`` made both
        and checked that no row is stored already).  Its calibrations and
        diagnoses stay."""
        info = self._require(data.name)
        check_rows(rows, INT16_MIN, INT16_MAX)
        _, kind, _, _, source, rate, notes, scales, chips, meta = self._meta_row(
            data.name, data.kind, data.scales, data.chips, data.meta)
        with self._tx() as cur:
            cur.execute(self._b.sql(
                "UPDATE sessions SET kind = ?, source = ?, rate_hz = ?, notes = ?, scales = ?, "
                "chips = ?, meta = ? WHERE id = ?"),
                (kind, source, rate, notes, scales, chips, meta, info.id))
            self._insert_rows(cur, info.id, rows)

    def _insert_rows(self, cur, sid: int, data: SessionData) -> None:
        """Insert a session's sample rows and temperature readings."""
        raw = np.asarray(data.raw, float)
        finite = np.isfinite(raw)
        t = np.where(np.isfinite(data.t), data.t, np.nan)
        n = len(data)
        step = 100_000
        labels = label_texts(data.label)
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
            cur.executemany(self._b.sql(INSERT_TEMPS), zip(
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
            labels = labels_from_texts([r[13] for r in rows])
        else:
            num = np.zeros((0, 13))
            labels = np.zeros(0, np.int32)
        meta = json.loads(meta)
        meta.update({k: v for k, v in (("source", source), ("rate_hz", rate), ("notes", notes))
                     if v is not None})
        meta["started"] = iso(started)
        if ended is not None:
            meta["ended"] = iso(ended)
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
        text = document(cal, f"calibration for {session!r} mote {mote}")
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
        text = document(diagnosis, f"diagnosis for {session!r} mote {mote}")
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
        return {"id": int(i), "created": iso(created), "tool": tool, "data_key": key,
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
        return [dict(writer=w, source=src, started=iso(a), ended=iso(e), stored=int(n),
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


def _backend_for(target: str, create: bool, readonly: bool = False) -> Backend:
    """The backend a target names: ``postgresql://`` (or ``postgres://``),
    ``mysql://`` (or ``mariadb://``), else a sqlite file (``sqlite:///path`` or
    a path)."""
    if target.startswith(("postgresql://", "postgres://")):
        from .store_postgres import PostgresBackend  # its driver only when asked for
        return PostgresBackend(target, create, readonly)
    if target.startswith(("mysql://", "mariadb://")):
        from .store_mysql import MysqlBackend        # its driver only when asked for
        return MysqlBackend(target, create, readonly)
    if target.startswith("sqlite:///"):
        if "?" in target:
            raise UserError(f"database URL {shown_url(target)}: a sqlite:/// URL takes no "
                            "options (sqlite files have no passwords)")
        target = target[len("sqlite:///") - 1:] if target.startswith("sqlite:////") \
            else target[len("sqlite:///"):]
    elif "://" in target:
        raise UserError(f"unsupported database URL {shown_url(target)} (use a sqlite file "
                        "path, postgresql://... or mysql://...)")
    return SqliteBackend(target, create, readonly)


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
