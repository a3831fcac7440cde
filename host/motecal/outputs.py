"""Where a command's output files go: the one place that decides whether a
path may be written and writes it without ever destroying anything else.

Every command that writes a file (``export --csv``, ``calibrate --out``,
``diagnose --json/--model-out``, ``sim --out/--truth``, ``report --out``)
goes through here:

* ``-`` means standard output (``open_output``, ``write_text``);
* an output that is the database or any input of the same command (the same
  file, through a symlink, a hard link, or the database's ``-wal``/``-shm``/
  ``-journal`` companions) is refused;
* a symlink is written through: its target is replaced, the link stays;
* a path that exists and is not a regular file (a device, a FIFO, a socket,
  a directory) is refused, never replaced;
* an existing sqlite database is never overwritten by an output unless
  ``force``;
* a regular file is written to a temporary file in the same folder, flushed
  to disk and renamed over the target only when complete (keeping the old
  file's permission bits), so a full disk or an error never leaves half a
  file and the old one stays as it was.

Problems raise ``UserError`` (one line, exit 2).  docs/guarantees.md lists
the promises and their tests.
"""
from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
import sys

from .errors import UserError
from .inputs import file_kind

STDOUT = "-"
SQLITE_MAGIC = b"SQLite format 3\x00"
_COMPANIONS = ("-wal", "-shm", "-journal")


def is_stdout(path) -> bool:
    return path is not None and str(path) == STDOUT


def file_path(target) -> str | None:
    """The local file behind a database target or input (``sqlite:///`` URLs
    included); None for server URLs and stdin/stdout."""
    if target is None:
        return None
    t = os.fspath(target)
    if t == STDOUT:
        return None
    if t.startswith("sqlite:///"):
        return t[len("sqlite:///") - 1:] if t.startswith("sqlite:////") else t[len("sqlite:///"):]
    if "://" in t:
        return None
    return t


def is_sqlite_file(path) -> bool:
    try:
        with open(path, "rb") as f:
            return f.read(len(SQLITE_MAGIC)) == SQLITE_MAGIC
    except OSError:
        return False


def same_file(a, b) -> bool:
    """``a`` and ``b`` name one file (symlinks and hard links resolved), or one
    is a sqlite companion (``-wal``...) of the other."""
    pa, pb = file_path(a), file_path(b)
    if pa is None or pb is None:
        return False
    try:
        if os.path.exists(pa) and os.path.exists(pb) and os.path.samefile(pa, pb):
            return True
    except OSError:
        pass
    ra, rb = os.path.realpath(pa), os.path.realpath(pb)
    return ra == rb or any(ra == rb + c or rb == ra + c for c in _COMPANIONS)


def check_output(path, *, inputs=(), force: bool = False, what: str = "") -> str:
    """Check that ``path`` may be written; returns the real path that will be
    replaced (a symlink resolved), or ``"-"`` for stdout.  UserError if not."""
    if path is None or str(path) == "":
        raise UserError(f"no {what or 'output'} file given")
    p = os.fspath(path)
    if p == STDOUT:
        return STDOUT
    label = f"{what} {p}" if what else p
    if "\x00" in p:
        raise UserError(f"cannot write {label!r}: the name holds a NUL byte")
    for inp in inputs:
        if inp is not None and same_file(p, inp):
            raise UserError(f"refusing to write {label}: it is {os.fspath(inp)}, an input of "
                            "this command (choose another output file)")
    try:
        real = os.path.realpath(p)
    except (OSError, ValueError) as e:
        raise UserError(f"cannot write {label}: {e}") from None
    try:
        st = os.stat(real)
    except FileNotFoundError:
        st = None
    except OSError as e:
        raise UserError(f"cannot write {label}: {e.strerror or e}") from None
    if st is not None:
        if stat.S_ISDIR(st.st_mode):
            raise UserError(f"cannot write {label}: it is a directory")
        if not stat.S_ISREG(st.st_mode):
            raise UserError(f"refusing to replace {label}: it is {file_kind(st.st_mode)}, not a "
                            "regular file (use '-' for standard output)")
        if not force and is_sqlite_file(real):
            raise UserError(f"refusing to overwrite {label}: it is a sqlite database "
                            "(choose another output file, or delete it first)")
    folder = os.path.dirname(real) or "."
    if not os.path.isdir(folder):
        raise UserError(f"cannot write {label}: folder {os.path.dirname(p) or '.'} "
                        "does not exist")
    return real


def _temp_beside(real: str) -> tuple[str, int]:
    folder = os.path.dirname(real) or "."
    base = os.path.basename(real)
    for _ in range(100):
        tmp = os.path.join(folder, f".{base}.{secrets.token_hex(4)}.tmp")
        try:
            # 0666 less the umask: the mode a plain open() would give a new file
            return tmp, os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
    raise FileExistsError(errno.EEXIST, "no free temporary name", folder)


# the disk failed or filled up (exit 1), rather than a path the user got wrong (2)
_DISK_FAULTS = (errno.ENOSPC, errno.EFBIG, errno.EIO, errno.EDQUOT)


def _why(e: OSError) -> str:
    if e.errno == errno.ENOSPC:
        return "no space left on device"
    return e.strerror or str(e)


def _fault(label: str, e: OSError) -> UserError:
    return UserError(f"cannot write {label}: {_why(e)} (nothing written)",
                     exit_code=1 if e.errno in _DISK_FAULTS else 2)


@contextlib.contextmanager
def open_output(path, *, inputs=(), force: bool = False, binary: bool = False,
                what: str = "", newline: str | None = None):
    """A file object for an output (see the module doc); ``-`` is stdout.

    The data goes to a temporary file renamed over the target when the block
    ends without an exception; on an exception the temporary file is removed
    and the target stays as it was.  OSError becomes UserError."""
    real = check_output(path, inputs=inputs, force=force, what=what)
    if real == STDOUT:
        out = sys.stdout.buffer if binary else sys.stdout
        yield out
        out.flush()
        return
    label = os.fspath(path)
    try:
        tmp, fd = _temp_beside(real)
    except OSError as e:
        raise _fault(label, e) from None
    try:
        with contextlib.suppress(FileNotFoundError):
            old = os.stat(real)
            os.chmod(tmp, stat.S_IMODE(old.st_mode))
        f = os.fdopen(fd, "wb" if binary else "w",
                      **({} if binary else {"encoding": "utf-8", "newline": newline}))
        with f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        # checked again just before the rename: never over something that
        # became a device, FIFO or directory meanwhile
        with contextlib.suppress(FileNotFoundError):
            if not stat.S_ISREG(os.stat(real).st_mode):
                raise UserError(f"refusing to replace {label}: it is no longer a regular file")
        os.replace(tmp, real)
        _sync_folder(os.path.dirname(real) or ".")
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(e, OSError):
            raise _fault(label, e) from None
        raise


def _sync_folder(folder: str) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def write_text(path, text: str, **kw) -> str:
    """Write ``text`` to an output (``open_output``); returns the path written
    (``-`` for stdout)."""
    with open_output(path, **kw) as f:
        f.write(text)
    return os.fspath(path)


def write_bytes(path, data: bytes, **kw) -> str:
    with open_output(path, binary=True, **kw) as f:
        f.write(data)
    return os.fspath(path)


def check_output_dir(path, *, inputs=(), what: str = "") -> str:
    """A folder a command writes files into (and may replace as a whole): no
    input may be the folder or lie inside it; an existing non-folder is
    refused.  Returns its real path."""
    if path is None or str(path) == "":
        raise UserError(f"no {what or 'output'} folder given")
    p = os.fspath(path)
    label = f"{what} {p}" if what else p
    if p == STDOUT:
        raise UserError(f"{label}: a folder is needed here, not standard output")
    real = os.path.realpath(p)
    for inp in inputs:
        f = file_path(inp)
        if f is None:
            continue
        ri = os.path.realpath(f)
        if ri == real or ri.startswith(real.rstrip(os.sep) + os.sep):
            raise UserError(f"refusing to write into {label}: {os.fspath(inp)}, an input of "
                            "this command, is inside it (choose another folder)")
    if os.path.exists(real) and not os.path.isdir(real):
        raise UserError(f"cannot write into {label}: it exists and is not a folder")
    return real

