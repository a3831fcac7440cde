"""The store's sqlite backend: a database in one file, the default.

Write-ahead log and ``synchronous=NORMAL`` (switched on only once the file is
known to be a motecal database, or a new one); writers queue on ``BEGIN
IMMEDIATE`` with a busy timeout; read-only opens use ``mode=ro`` (and
``immutable`` without a live write-ahead log) so that read-only media work
and nothing is made beside the file.  The database is marked as motecal's by
its ``PRAGMA application_id`` (store_schema.APPLICATION_ID).
"""
from __future__ import annotations

import contextlib
import os
import sqlite3
import stat
import urllib.parse

from ..errors import UserError
from .store_backend import Backend
from .store_schema import APPLICATION_ID


class SqliteBackend(Backend):
    """A sqlite file: WAL journal, synchronous=NORMAL (a crash loses no
    committed transaction; power loss at most the last ones, never consistency)."""

    name = "sqlite"
    types = {"int16": "INTEGER", "real": "REAL", "id_pk": "INTEGER PRIMARY KEY",
             "wr": " WITHOUT ROWID"}
    errors = (sqlite3.Error,)

    def __init__(self, path: str, create: bool, readonly: bool = False):
        self.path = path
        self.display = path
        if os.path.isdir(path):
            raise UserError(f"{path} is a directory, not a database file")
        exists = os.path.exists(path)
        if not exists and not create:
            raise UserError(f"no database {path}")
        folder = os.path.dirname(os.path.abspath(path))
        if not exists:
            if not os.path.isdir(folder):
                raise UserError(f"cannot create database {path}: folder {folder} does not exist")
            if not os.access(folder, os.W_OK):
                raise UserError(f"cannot create database {path}: folder {folder} is not writable")
        else:
            mode = os.stat(path).st_mode
            if not stat.S_ISREG(mode):
                raise UserError(f"{path} is not a database file (it is a device, FIFO or "
                                "socket)")
            if create and not os.access(path, os.W_OK):
                raise UserError(f"database {path} is not writable")
            if create and not os.access(folder, os.W_OK):
                raise UserError(f"database {path} cannot be written: its folder {folder} is "
                                "read-only")
        # read-only: asked for (commands that only read), or the file or its
        # folder (where the WAL lives) cannot be written -- read-only media
        self.readonly = exists and (readonly or not os.access(path, os.W_OK)
                                    or not os.access(folder, os.W_OK))
        try:
            if self.readonly:
                self.conn = sqlite3.connect(self._ro_uri(path), uri=True, isolation_level=None,
                                            check_same_thread=False)
            else:
                self.conn = sqlite3.connect(path, isolation_level=None, timeout=10.0,
                                            check_same_thread=False)
            self.conn.execute("PRAGMA busy_timeout = 10000")
            self.tables()                         # fails on a non-sqlite file
        except sqlite3.DatabaseError as e:
            with contextlib.suppress(Exception):
                self.conn.close()
            if "not a database" in str(e) or "malformed" in str(e):
                raise UserError(f"{path} is not a motecal database ({e})") from None
            raise UserError(f"cannot open database {path}: {e}") from None

    @staticmethod
    def _ro_uri(path: str) -> str:
        """Read-only URI: ``immutable`` (no lock, no -shm/-wal made: works on
        read-only media and leaves the folder as it was) unless a write-ahead
        log with data is there -- a logger may be writing, or crashed before
        checkpointing -- which only a normal read-only open sees."""
        wal = path + "-wal"
        live = os.path.exists(wal) and os.path.getsize(wal) > 0
        return ("file:" + urllib.parse.quote(os.path.abspath(path)) + "?mode=ro"
                + ("" if live else "&immutable=1"))

    def prepare_writes(self):
        """Write-ahead log, synchronous=NORMAL: only once the file is known to
        be a motecal database (or a new one), never on a foreign file."""
        self.conn.execute("PRAGMA journal_mode = WAL")
        self.conn.execute("PRAGMA synchronous = NORMAL")

    def app_id(self) -> int:
        return int(self.conn.execute("PRAGMA application_id").fetchone()[0])

    def set_app_id(self, cur):
        cur.execute(f"PRAGMA application_id = {APPLICATION_ID}")

    def columns(self, table: str) -> set[str]:
        return {r[1] for r in self.conn.execute(f"PRAGMA table_info({table})")}

    def sql(self, text: str) -> str:
        return text

    def tables(self) -> set[str]:
        return {r[0] for r in self.conn.execute(
            "SELECT name FROM sqlite_master WHERE type = 'table'")}

    def begin(self):
        self.conn.execute("BEGIN IMMEDIATE")        # writers queue here (busy_timeout)

    def set_busy_timeout(self, seconds: float):
        self.conn.execute(f"PRAGMA busy_timeout = {max(0, int(seconds * 1000))}")

    def lock_schema(self, cur):
        pass                                         # BEGIN IMMEDIATE already serialises

    def commit(self):
        self.conn.execute("COMMIT")

    def rollback(self):
        if self.conn.in_transaction:
            self.conn.execute("ROLLBACK")

    def cursor(self):
        return self.conn.cursor()

    def insert_samples(self, cur, rows):
        cur.executemany(
            "INSERT INTO samples (session, mote, seq, t, label, flags, ax, ay, az, gx, gy, gz, "
            "mx, my, mz) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", rows)

    def close(self):
        self.conn.close()
