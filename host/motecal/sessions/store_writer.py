"""The live session's writer: ``SessionWriter``, the logger's side of the
store (``Store.open_session`` makes one).

It queues what the logger hands it (samples, labels, temperature readings,
events, counters) and writes it in one transaction per ``commit``, through
the ``Store`` it was made by (its ``_tx`` and backend); several writers may
log into one session at once (docs/guarantees.md, "several writers").
"""
from __future__ import annotations

import itertools
import os
import socket
import time

import numpy as np

from .session import label_to_text
from .store_backend import StoreBusy
from .store_schema import LINE_COUNTERS, LINK_COUNTERS

_NULL = 1 << 40                    # a stored NULL, when samples are compared

# A live session waits this long for a write lock another process holds,
# buffering samples meanwhile, before it gives up (SessionWriter.commit).
LOCK_TIMEOUT_S = 60.0
LOCK_BUFFER_SAMPLES = 2_000_000     # ~0.3 GB of queued samples at most

# a temperature reading (the writer's and Store.save_session's); kept once
INSERT_TEMPS = ("INSERT INTO temps (session, mote, seq, t, temp_c, count) "
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

    def __init__(self, store, sid: int, name: str, started: float, commit_every: float,
                 lock_timeout: float = LOCK_TIMEOUT_S):
        self.store = store              # the Store (store.py) that opened the session
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
                cur.executemany(b.sql(INSERT_TEMPS), temps)
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
