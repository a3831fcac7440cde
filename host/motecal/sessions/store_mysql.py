"""The store's MySQL / MariaDB backend (PyMySQL, pure Python): the seed paper's
database.  Same schema, same migrations and the same ``Store`` on top as the
sqlite and PostgreSQL backends, behind the same interface (store_backend.py);
this module only speaks the dialect.

URLs::

    mysql://user[:password]@host[:port]/db          TCP (port 3306 by default)
    mysql://user[:password]@/db?unix_socket=/path   a unix socket
    mysql://user@/db                                the default socket, /run/mysqld/mysqld.sock

(``mariadb://`` is the same.)  The database must exist; the motecal tables
are made in it when it has none.

What differs from the other two, all of it here:

- Types: ``DOUBLE``, ``BIGINT AUTO_INCREMENT``, InnoDB tables in utf8mb4 with
  a binary, no-pad collation (names compare exactly as in sqlite and
  PostgreSQL: case and trailing blanks count); the session name is a
  ``VARCHAR(700)`` (a unique key cannot be a ``TEXT``), the label a ``VARCHAR(16)``.
- ``INSERT ... RETURNING id`` -> the connection's last insert id;
  ``ON CONFLICT DO NOTHING`` / ``DO UPDATE`` -> ``ON DUPLICATE KEY UPDATE``.
- Sample rows go in as multi-row ``INSERT``s of up to ~1 MB each.
- Transactions are READ COMMITTED (as PostgreSQL's), so loggers writing
  their own sessions into one server do not lock each other's key ranges.
- MySQL commits every ``CREATE``/``ALTER`` at once, and shows the table to
  everyone: a migration runs under a named lock (``GET_LOCK``), one process
  at a time, and the schema is read under that lock, so nobody sees half of
  it; but a migration cut off half-way is not rolled back (the database then
  needs the missing tables made by hand, or to be emptied).
"""
from __future__ import annotations

import functools
import itertools
import math
import re
import urllib.parse

from ..errors import UserError
from .store_backend import Backend, scrubbed, shown_url

SCHEMES = ("mysql://", "mariadb://")
DEFAULT_SOCKET = "/run/mysqld/mysqld.sock"
DEFAULT_PORT = 3306
MIGRATION_LOCK = "motecal_schema"
MIGRATION_LOCK_WAIT_S = 60
MAX_STATEMENT = 1 << 20          # bytes of one multi-row INSERT (servers allow >= 4 MB)

# A chunk of sample rows as repr() gives it: texts of word characters only
# ('7', 'rot', ''), ints, finite floats, None, nan.  Anything else (another
# quote, a backslash, inf, any other object) goes the slow, escaped way.
_CHUNK_ROWS = 4096
_WORD_TEXT = re.compile(r"'\w*'")
_NAMES = re.compile(r"None|nan|True|False")
_NOT_NUMBER = re.compile(r"[^-+., ()\deE]")
_NULLS = re.compile(r"(?<=[( ])(?:None|nan)(?=[,)])")

# Binary, no-pad collations, best first (MariaDB >= 10.2, MySQL 8, older MySQL).
_COLLATIONS = ("utf8mb4_nopad_bin", "utf8mb4_0900_bin", "utf8mb4_bin")


def parse_url(url: str) -> tuple[dict, str]:
    """PyMySQL connect arguments of a ``mysql://`` URL, and the URL to show
    (password hidden).  UserError on a malformed URL."""
    try:
        u = urllib.parse.urlsplit(url)
        port = u.port
    except ValueError as e:
        raise UserError(f"bad database URL {shown_url(url)}: {scrubbed(str(e), url)}") from None
    db = urllib.parse.unquote(u.path.lstrip("/"))
    if not db or "/" in db:
        raise UserError(f"database URL {shown_url(url)} names no database "
                        "(mysql://user@host/DATABASE)")
    args = dict(database=db, user=urllib.parse.unquote(u.username) if u.username else None,
                password=urllib.parse.unquote(u.password) if u.password else "")
    query = urllib.parse.parse_qs(u.query, keep_blank_values=True)
    if query.get("password") and not u.password:
        args["password"] = query["password"][-1]
    unknown = set(query) - {"unix_socket", "socket", "password"}
    if unknown:
        raise UserError(f"database URL {shown_url(url)}: unknown option(s) "
                        f"{', '.join(sorted(unknown))} (known: unix_socket)")
    sockets = query.get("unix_socket", []) + query.get("socket", [])
    if sockets:
        args["unix_socket"] = sockets[-1]
    elif u.hostname:
        args["host"] = u.hostname
        args["port"] = port or DEFAULT_PORT
    else:
        args["unix_socket"] = DEFAULT_SOCKET
    return args, shown_url(url)


def _first_line(e: Exception) -> str:
    """One line from a PyMySQL error: (code, message) -> message."""
    args = getattr(e, "args", ())
    text = str(args[1]) if len(args) > 1 else str(e)
    return (text.strip().splitlines() or [type(e).__name__])[0]


# --------------------------------------------------------------------------
# The dialect: the store's SQL (sqlite / PostgreSQL) -> MySQL.
# --------------------------------------------------------------------------
_TEXT_COLUMN = {            # text columns that MySQL needs as VARCHAR
    "name": "VARCHAR(700)",         # unique key: no TEXT
    "label": "VARCHAR(16)",         # "1".."80", "rot" or ""
    "writer": "VARCHAR(255)",       # a writer's id (key of writers): host, pid, time
}


def _ddl(sql: str, table_options: str) -> str:
    """A CREATE TABLE of the migrations, MySQL's way: ``col TEXT`` becomes a
    VARCHAR where keyed or short, LONGTEXT otherwise (whose default must be an
    expression), and the table gets InnoDB, utf8mb4 and a binary collation."""
    sql = re.sub(r"\b(\w+) TEXT\b",
                 lambda m: f"{m.group(1)} {_TEXT_COLUMN.get(m.group(1), 'LONGTEXT')}", sql)
    sql = re.sub(r"(LONGTEXT[^,]*?) DEFAULT ''", r"\1 DEFAULT ('')", sql)
    return sql.rstrip() + " " + table_options


_INSERT = re.compile(r"^\s*INSERT INTO (\w+) \(([^)]*)\)", re.S)
_DO_NOTHING = re.compile(r"\s+ON CONFLICT DO NOTHING\s*$", re.S)
_DO_UPDATE = re.compile(r"\s+ON CONFLICT \([^)]*\) DO UPDATE SET (.*)$", re.S)
_RETURNING = re.compile(r"\s+RETURNING (\w+)\s*$", re.S)


@functools.lru_cache(maxsize=256)
def translate(sql: str, table_options: str) -> tuple[str, bool]:
    """(MySQL statement, whether it asked for the new row's id via RETURNING)."""
    if sql.lstrip().upper().startswith("CREATE TABLE"):
        return _ddl(sql, table_options), False
    q = sql.replace("?", "%s")
    returning = False
    m = _RETURNING.search(q)
    if m:
        q, returning = q[:m.start()], True
    m = _DO_NOTHING.search(q)
    if m:
        first = _INSERT.match(q).group(2).split(",")[0].strip()
        q = q[:m.start()] + f" ON DUPLICATE KEY UPDATE {first} = {first}"
    m = _DO_UPDATE.search(q)
    if m:
        sets = re.sub(r"\bexcluded\.(\w+)", r"VALUES(\1)", m.group(1))
        q = q[:m.start()] + " ON DUPLICATE KEY UPDATE " + sets
    return q, returning


def _nan_free(row):
    """NaN has no place in MySQL's DOUBLE: NULL, as sqlite stores it."""
    return tuple(None if type(v) is float and v != v else v for v in row)


class _Cursor:
    """A PyMySQL cursor that takes the store's SQL (translated on the fly)."""

    def __init__(self, backend: "MysqlBackend"):
        self._b = backend
        self._c = backend.conn.cursor()
        self._id: tuple | None = None
        self.rowcount = -1          # rows the last statement(s) inserted or changed

    def execute(self, sql: str, params=()):
        q, returning = translate(sql, self._b.table_options)
        self._c.execute(q, _nan_free(params) if params else None)
        self.rowcount = self._c.rowcount
        self._id = (self._c.lastrowid,) if returning else None
        return self

    def executemany(self, sql: str, rows):
        q, _ = translate(sql, self._b.table_options)
        m = _INSERT.match(q)
        if m and " VALUES " in q:
            self.rowcount = self._b.insert_rows(self._c, q, rows)
        else:
            self._c.executemany(q, [_nan_free(r) for r in rows])
            self.rowcount = self._c.rowcount
        self._id = None

    def fetchone(self):
        if self._id is not None:
            row, self._id = self._id, None
            return row
        return self._c.fetchone()

    def fetchall(self):
        return list(self._c.fetchall())

    def close(self):
        self._c.close()


class MysqlBackend(Backend):
    """A MySQL or MariaDB server (PyMySQL).  ``create`` is implied: the
    database must exist, the motecal tables are made in it when it has none."""

    name = "mysql"
    types = {"int16": "SMALLINT", "real": "DOUBLE",
             "id_pk": "BIGINT AUTO_INCREMENT PRIMARY KEY", "wr": ""}
    def __init__(self, url: str, create: bool, readonly: bool = False):
        self.readonly = readonly
        try:
            import pymysql
        except ImportError:
            raise UserError("a mysql:// database needs the PyMySQL package "
                            "(pip install './host[mysql]')") from None
        self.pymysql = pymysql
        self.errors = (pymysql.Error,)
        args, self.display = parse_url(url)
        try:
            self.conn = pymysql.connect(**args, charset="utf8mb4", autocommit=True,
                                        connect_timeout=10)
        except pymysql.Error as e:
            raise UserError(f"cannot connect to {self.display}: "
                            f"{scrubbed(_first_line(e), url)}") from None
        self._locked = False
        self.lock_name = f"{MIGRATION_LOCK}.{args['database']}"[:64]
        try:
            with self.conn.cursor() as cur:
                cur.execute("SET SESSION sql_mode = 'STRICT_ALL_TABLES,NO_ENGINE_SUBSTITUTION,"
                            "ERROR_FOR_DIVISION_BY_ZERO'")
                cur.execute("SET SESSION TRANSACTION ISOLATION LEVEL READ COMMITTED")
                if readonly:
                    cur.execute("SET SESSION TRANSACTION READ ONLY")
                cur.execute("SELECT COLLATION_NAME FROM information_schema.COLLATIONS "
                            "WHERE COLLATION_NAME IN (%s, %s, %s)", _COLLATIONS)
                have = {r[0] for r in cur.fetchall()}
                cur.execute("SELECT @@max_allowed_packet")
                self.max_statement = min(MAX_STATEMENT, int(cur.fetchone()[0]) // 2)
        except pymysql.Error as e:
            self.conn.close()
            raise UserError(f"cannot use {self.display}: {scrubbed(_first_line(e), url)}") from None
        collation = next((c for c in _COLLATIONS if c in have), "utf8mb4_bin")
        self.table_options = f"ENGINE=InnoDB DEFAULT CHARSET=utf8mb4 COLLATE={collation}"

    def sql(self, text: str) -> str:
        return text                      # the cursor translates (it must see RETURNING)

    def prepare_writes(self):
        pass

    def app_id(self) -> None:
        return None                          # a server database: recognised by its tables

    def set_app_id(self, cur):
        pass

    def columns(self, table: str) -> set[str]:
        with self.conn.cursor() as cur:
            cur.execute("SELECT column_name FROM information_schema.columns "
                        "WHERE table_schema = DATABASE() AND table_name = %s", (table,))
            return {r[0] for r in cur.fetchall()}

    def set_busy_timeout(self, seconds: float):
        with self.conn.cursor() as cur:
            cur.execute(f"SET SESSION innodb_lock_wait_timeout = {max(1, int(seconds))}")

    def tables(self) -> set[str]:
        """The database's tables, read under the migration lock: MySQL shows
        each table of a migration as soon as it is made, so this waits for one
        under way and never sees half a schema."""
        hold = not self._locked
        if hold:
            self._get_lock()
        try:
            with self.conn.cursor() as cur:
                cur.execute("SELECT table_name FROM information_schema.tables "
                            "WHERE table_schema = DATABASE()")
                return {r[0] for r in cur.fetchall()}
        finally:
            if hold:
                self._release_lock()

    def _get_lock(self):
        with self.conn.cursor() as c:
            c.execute("SELECT GET_LOCK(%s, %s)", (self.lock_name, MIGRATION_LOCK_WAIT_S))
            if c.fetchone()[0] != 1:
                raise UserError(f"{self.display}: another process is migrating the schema "
                                f"(waited {MIGRATION_LOCK_WAIT_S} s)")

    def _release_lock(self):
        with self.conn.cursor() as c:
            c.execute("SELECT RELEASE_LOCK(%s)", (self.lock_name,))

    def begin(self):
        self.conn.begin()

    def lock_schema(self, cur):
        """One migrator at a time (a named lock, held until the commit: MySQL
        commits DDL at once, so a transaction cannot hold it)."""
        self._get_lock()
        self._locked = True

    def _unlock(self):
        if self._locked:
            self._locked = False
            self._release_lock()

    def commit(self):
        self.conn.commit()
        self._unlock()

    def rollback(self):
        try:
            self.conn.rollback()
        finally:
            self._unlock()

    def cursor(self):
        return _Cursor(self)

    def insert_samples(self, cur, rows):
        cur.executemany("INSERT INTO samples (session, mote, seq, t, label, flags, ax, ay, az, "
                        "gx, gy, gz, mx, my, mz) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
                        "?, ?, ?)", rows)

    def insert_rows(self, raw_cursor, q: str, rows):
        """Many rows of one ``INSERT ... VALUES (%s, ...) [ON DUPLICATE ...]`` as
        multi-row statements of at most ``max_statement`` bytes.

        The rows (ints, floats, None, texts) are written as SQL literals here:
        a chunk of plain rows (numbers, None, NaN and texts of word characters
        only: sample rows) through Python's own tuple ``repr``, which is
        already SQL once None/NaN read NULL; any other chunk value by value
        with the driver's escaping.  Returns the rows inserted (a duplicate
        key left as it is counts 0: the connection does not ask for found rows)."""
        head, _, rest = q.partition(" VALUES ")
        tail = rest[rest.index(")") + 1:]
        prefix = head + " VALUES "
        limit = self.max_statement - len(prefix) - len(tail)
        rows = iter(rows)
        done = 0
        while True:
            chunk = list(itertools.islice(rows, _CHUNK_ROWS))
            if not chunk:
                return done
            for body in self._bodies(chunk, limit):
                raw_cursor.execute(prefix + body + tail)
                done += max(raw_cursor.rowcount, 0)

    def _bodies(self, chunk: list, limit: int):
        body = ",".join(map(repr, chunk))
        if not _NOT_NUMBER.search(body) or not _NOT_NUMBER.search(
                _NAMES.sub("", _WORD_TEXT.sub("", body))):
            if "None" in body or "nan" in body:
                body = _NULLS.sub("NULL", body)
        else:
            body = ",".join(["(" + ",".join([self._literal(v) for v in row]) + ")"
                             for row in chunk])
        if len(body) <= limit or len(chunk) == 1:
            yield body
        else:
            half = len(chunk) // 2
            yield from self._bodies(chunk[:half], limit)
            yield from self._bodies(chunk[half:], limit)

    def _literal(self, v) -> str:
        if type(v) is float and not math.isfinite(v):
            return "NULL"            # NaN: NULL, as sqlite stores it
        return self.conn.escape(v)

    def close(self):
        try:
            self.conn.close()
        except self.pymysql.Error:
            pass                         # the server went away: nothing left to close
