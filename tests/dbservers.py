"""Real database servers for the store's tests and benches, started from
Debian's packages (``make sysdeps``: postgresql, mariadb-server-core and
mariadb-client-core) in a fresh temporary folder: their own data directory,
their unix socket in that folder, TCP (MariaDB only) on 127.0.0.1 alone, no
system service.  Both work when run as root.

    with postgres_server() as srv:      # srv.url: postgresql://motecal@/motecal?host=DIR
        ...
    with mariadb_server() as srv:       # srv.url (socket), srv.tcp_url (127.0.0.1:PORT)
        ...

A server that cannot be started raises ServerError with its log's tail;
tests turn that into a failure (the packages are part of the test set-up).
"""
from __future__ import annotations

import contextlib
import glob
import os
import pathlib
import pwd
import shutil
import socket
import subprocess
import tempfile
import time
from dataclasses import dataclass

START_TIMEOUT = 60.0


class ServerError(RuntimeError):
    pass


@dataclass
class Server:
    url: str                 # over the unix socket
    root: pathlib.Path       # the temporary folder: data, socket, log
    tcp_url: str | None = None


def _has_user(name: str) -> bool:
    try:
        pwd.getpwnam(name)
        return True
    except KeyError:
        return False


def _tail(path: pathlib.Path, n: int = 5) -> str:
    try:
        return " | ".join(path.read_text(errors="replace").strip().splitlines()[-n:])
    except OSError:
        return "(no log)"


def _wait(connect, server: subprocess.Popen, what: str, log: pathlib.Path):
    deadline = time.monotonic() + START_TIMEOUT
    while True:
        try:
            return connect()
        except Exception:
            if server.poll() is not None or time.monotonic() > deadline:
                server.kill()
                server.wait(10)
                raise ServerError(f"{what} did not start: {_tail(log)}") from None
            time.sleep(0.1)


def _stop(server: subprocess.Popen):
    if server.poll() is None:
        server.terminate()
        try:
            server.wait(30)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait(10)


# --------------------------------------------------------------------------
# PostgreSQL (Debian's postgresql): reachable only through its unix socket.
# --------------------------------------------------------------------------
@contextlib.contextmanager
def postgres_server():
    import psycopg
    bins = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    if not bins:
        raise ServerError("PostgreSQL server not installed (Debian package postgresql; "
                          "make sysdeps)")
    bindir = os.path.dirname(bins[-1])
    # not under pytest's private (0700) folders: the server's user must reach it
    root = pathlib.Path(tempfile.mkdtemp(prefix="motecal-pg-"))
    user = None
    if os.geteuid() == 0:                      # initdb refuses to run as root
        user = "postgres" if _has_user("postgres") else "nobody"
        os.chown(root, pwd.getpwnam(user).pw_uid, pwd.getpwnam(user).pw_gid)
    server = None
    try:
        data = root / "data"
        subprocess.run([f"{bindir}/initdb", "-D", str(data), "-U", "motecal", "--auth=trust",
                        "-E", "UTF8", "--no-sync"], check=True, capture_output=True, user=user,
                       cwd=root)
        log = root / "server.log"
        with open(log, "wb") as logf:
            server = subprocess.Popen([f"{bindir}/postgres", "-D", str(data), "-k", str(root),
                                       "-c", "listen_addresses=", "-c", "fsync=off"],
                                      stdout=logf, stderr=subprocess.STDOUT, user=user,
                                      cwd=root)

        def create():
            with psycopg.connect(f"postgresql://motecal@/postgres?host={root}",
                                 autocommit=True) as con:
                con.execute("CREATE DATABASE motecal")

        _wait(create, server, "PostgreSQL server", log)
        yield Server(url=f"postgresql://motecal@/motecal?host={root}", root=root)
    finally:
        if server is not None:
            _stop(server)
        shutil.rmtree(root, ignore_errors=True)


# --------------------------------------------------------------------------
# MariaDB (Debian's mariadb-server-core + mariadb-client-core): unix socket in
# the folder, TCP on 127.0.0.1 at a free port; a user `motecal` with a
# password and a database `motecal`.
# --------------------------------------------------------------------------
MARIADB_PASSWORD = "motecal-test"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _mariadb_bin() -> tuple[str, str]:
    server = shutil.which("mariadbd", path="/usr/sbin:/usr/bin:/sbin") \
        or shutil.which("mysqld", path="/usr/sbin:/usr/bin:/sbin")
    install = shutil.which("mariadb-install-db") or shutil.which("mysql_install_db")
    if not server or not install:
        raise ServerError("MariaDB server not installed (Debian packages mariadb-server-core "
                          "and mariadb-client-core; make sysdeps)")
    return server, install


@contextlib.contextmanager
def mariadb_server(durable: bool = False):
    """``durable``: flush the InnoDB log at every commit (the server's default);
    otherwise once a second, like sqlite's synchronous=NORMAL (a crash of the
    machine may lose the last second, never consistency)."""
    import pymysql
    mariadbd, install_db = _mariadb_bin()
    root = pathlib.Path(tempfile.mkdtemp(prefix="motecal-mysql-"))
    user_opt = ["--user=root"] if os.geteuid() == 0 else []
    server = None
    try:
        data = root / "data"
        log = root / "server.log"
        r = subprocess.run([install_db, "--no-defaults", f"--datadir={data}", *user_opt,
                            "--auth-root-authentication-method=normal", "--skip-test-db",
                            "--skip-name-resolve"], capture_output=True, text=True, cwd=root)
        if r.returncode:
            raise ServerError("mariadb-install-db failed: "
                              + " | ".join((r.stdout + r.stderr).strip().splitlines()[-5:]))
        sock = root / "mysql.sock"
        port = _free_port()
        server = subprocess.Popen(
            [mariadbd, "--no-defaults", f"--datadir={data}", f"--socket={sock}",
             f"--pid-file={root / 'mysqld.pid'}", f"--log-error={log}", *user_opt,
             "--bind-address=127.0.0.1", f"--port={port}", "--skip-name-resolve",
             f"--innodb-flush-log-at-trx-commit={1 if durable else 2}",
             "--innodb-buffer-pool-size=128M"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=root)

        def setup():
            con = pymysql.connect(unix_socket=str(sock), user="root", autocommit=True,
                                  connect_timeout=5)
            with con, con.cursor() as cur:
                cur.execute("CREATE DATABASE motecal")
                for host in ("localhost", "127.0.0.1"):
                    cur.execute(f"CREATE USER 'motecal'@'{host}' IDENTIFIED BY %s",
                                (MARIADB_PASSWORD,))
                    cur.execute(f"GRANT ALL ON motecal.* TO 'motecal'@'{host}'")

        _wait(setup, server, "MariaDB server", log)
        cred = f"motecal:{MARIADB_PASSWORD}"
        yield Server(url=f"mysql://{cred}@/motecal?unix_socket={sock}", root=root,
                     tcp_url=f"mysql://{cred}@127.0.0.1:{port}/motecal")
    finally:
        if server is not None:
            _stop(server)
        shutil.rmtree(root, ignore_errors=True)


def new_database(srv: Server, name: str) -> str:
    """Another empty database on a MariaDB test server; its URL (unix socket)."""
    import pymysql
    con = pymysql.connect(unix_socket=str(srv.root / "mysql.sock"), user="root",
                          autocommit=True)
    with con, con.cursor() as cur:
        cur.execute(f"CREATE DATABASE `{name}`")
        for host in ("localhost", "127.0.0.1"):
            cur.execute(f"GRANT ALL ON `{name}`.* TO 'motecal'@'{host}'")
    return srv.url.replace("/motecal?", f"/{name}?")
