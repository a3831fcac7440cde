"""The one interface between ``Store`` (store.py) and a database: what the
store needs of a backend, and the errors it raises when a database fails.

Each backend is one class, in a module of its own, derived from ``Backend``
below:

* ``store_sqlite.SqliteBackend``     -- a sqlite file (the default)
* ``store_postgres.PostgresBackend`` -- ``postgresql://`` (psycopg 3)
* ``store_mysql.MysqlBackend``       -- ``mysql://`` / ``mariadb://`` (PyMySQL)

``store.open_store`` picks one by the target's form.  The store speaks one
SQL, that of sqlite and PostgreSQL: ``?`` placeholders, ``INSERT ... ON
CONFLICT DO NOTHING`` / ``ON CONFLICT (key) DO UPDATE SET c = excluded.c``,
``INSERT ... RETURNING id``; a backend turns it into its own dialect
(``Backend.sql``, or its cursor as it executes).  The schema's statements
(store_schema.MIGRATIONS) hold ``{int16}``, ``{real}``, ``{id_pk}`` and
``{wr}``, filled in from ``Backend.types``.
"""
from __future__ import annotations

import abc
import re
import urllib.parse
from typing import Any, ClassVar, Iterable, Protocol

from ..errors import UserError


class Cursor(Protocol):
    """What the store uses of a cursor (a DB-API cursor's subset)."""

    rowcount: int                    # rows the last statement inserted or changed; -1 unknown

    def execute(self, sql: str, params: Any = ...) -> Any: ...

    def executemany(self, sql: str, rows: Iterable[tuple]) -> Any: ...

    def fetchone(self) -> tuple | None: ...

    def fetchall(self) -> list[tuple]: ...


class Backend(abc.ABC):
    """A database the store can use.  ``Backend(target, create, readonly)``
    connects or raises ``UserError`` with one line (missing, unreachable, no
    driver); it writes nothing before ``Store`` has recognised the database
    (``tables``, ``columns``, ``app_id``) and called ``prepare_writes``.

    Writes go through a ``cursor()`` between ``begin()`` and ``commit()``
    (or ``rollback()``: all or nothing, ``Store._tx``); reads use a cursor
    outside a transaction.  A driver's error is one of ``errors``; the store
    turns it into a ``StoreError`` (``store_fault``)."""

    name: ClassVar[str]              # "sqlite", "postgresql", "mysql"
    types: ClassVar[dict[str, str]]  # int16, real, id_pk, wr -> this backend's SQL
    display: str                     # the target as shown to the user (no password)
    readonly: bool                   # nothing may be written (asked for, or read-only media)
    errors: tuple[type[Exception], ...]   # the driver's error classes

    # -- the SQL dialect --------------------------------------------------------
    @abc.abstractmethod
    def sql(self, text: str) -> str:
        """The store's SQL in this backend's dialect (as it is, when the cursor
        translates)."""

    # -- recognising a database ----------------------------------------------------
    @abc.abstractmethod
    def tables(self) -> set[str]:
        """The database's table names."""

    @abc.abstractmethod
    def columns(self, table: str) -> set[str]:
        """The column names of one table."""

    @abc.abstractmethod
    def app_id(self) -> int | None:
        """sqlite's application id; None where a database has none (servers)."""

    @abc.abstractmethod
    def set_app_id(self, cur: Cursor) -> None:
        """Mark the database as motecal's (store_schema.APPLICATION_ID), if it can be."""

    @abc.abstractmethod
    def prepare_writes(self) -> None:
        """Settings for writing (sqlite: WAL), once the database is known to be ours."""

    # -- transactions ------------------------------------------------------------------
    @abc.abstractmethod
    def begin(self) -> None:
        """Start a write transaction (waiting for the lock up to the busy timeout)."""

    @abc.abstractmethod
    def commit(self) -> None: ...

    @abc.abstractmethod
    def rollback(self) -> None:
        """Roll back the transaction under way, if any."""

    @abc.abstractmethod
    def lock_schema(self, cur: Cursor) -> None:
        """Within a transaction: one migrating process at a time."""

    @abc.abstractmethod
    def set_busy_timeout(self, seconds: float) -> None:
        """How long one attempt waits for a lock another connection holds."""

    @abc.abstractmethod
    def cursor(self) -> Cursor: ...

    # -- bulk -------------------------------------------------------------------------------
    @abc.abstractmethod
    def insert_samples(self, cur: Cursor, rows: Iterable[tuple]) -> None:
        """Insert whole sample rows (session, mote, seq, t, label, flags, the
        nine counts) as fast as the backend can (COPY, multi-row INSERTs)."""

    @abc.abstractmethod
    def close(self) -> None: ...


SERVER_SCHEMES = ("postgresql", "postgres", "mysql", "mariadb")
# query options whose value is a secret (libpq's password/sslpassword, and the
# like): never shown
_SECRET_OPTION = re.compile(r"(?i)([?&;](?:[a-z_]*pass(?:word|wd)?|pwd|secret|token|"
                            r"[a-z_]*key)=)[^&;#]*")


def shown_url(url) -> str:
    """A database target as shown to the user, with every secret replaced by
    ``***``: the password of ``user:password@`` (for a scheme motecal does not
    know, the whole user part), and the value of a ``password=`` (or
    ``sslpassword=``, ``secret=``, ``token=``, ``...key=``) option."""
    text = str(url)
    head, sep, tail = text.partition("://")
    if sep:
        cred, at, rest = tail.rpartition("@")
        if at:
            user, colon, _ = cred.partition(":")
            known = head.lower() in SERVER_SCHEMES
            cred = f"{user}:***" if colon and known and "/" not in user else \
                (cred if known and not colon and "/" not in cred else "***")
            tail = f"{cred}@{rest}"
        text = f"{head}{sep}{tail}"
    return _SECRET_OPTION.sub(r"\1***", text)


def url_secrets(url) -> list[str]:
    """The secrets ``shown_url`` hides, as written and percent-decoded (to
    scrub them from a driver's message, which may quote them)."""
    text = str(url)
    found = []
    head, sep, tail = text.partition("://")
    if sep:
        cred, at, _ = tail.rpartition("@")
        if at:
            user, colon, pw = cred.partition(":")
            found += [pw] if colon else [cred]
    for m in re.finditer(r"(?i)[?&;](?:[a-z_]*pass(?:word|wd)?|pwd|secret|token|[a-z_]*key)="
                         r"([^&;#]*)", text):
        found.append(m.group(1))
    out = set()
    for f in found:
        if f:
            out |= {f, urllib.parse.unquote(f), urllib.parse.unquote_plus(f)}
    return sorted((f for f in out if f), key=len, reverse=True)


def scrubbed(message: str, url) -> str:
    """A driver's message with the URL's secrets (``url_secrets``) replaced by ``***``."""
    for secret in url_secrets(url):
        message = message.replace(secret, "***")
    return message


class StoreError(UserError):
    """The database failed under a command: disk full, I/O error, a lock held
    too long.  One line on stderr; exit status 1 (the user's input was fine)."""

    exit_code = 1


class StoreBusy(StoreError):
    """Another process holds the database's write lock."""


def store_fault(target: str, e: Exception) -> StoreError:
    """A database driver's error as one line (StoreBusy for a held lock)."""
    text = " ".join(str(e).split()) or type(e).__name__
    low = text.lower()
    if "locked" in low or "busy" in low or "lock timeout" in low:
        return StoreBusy(f"{target}: the database is locked by another process")
    if "full" in low or "no space" in low or "diskfull" in low:
        return StoreError(f"{target}: the database or its disk is full")
    if "i/o" in low or "ioerr" in low:
        return StoreError(f"{target}: disk I/O error")
    if "readonly" in low or "read-only" in low or "read only" in low:
        return StoreError(f"{target}: the database is read-only")
    return StoreError(f"{target}: database error: {text[:200]}")
