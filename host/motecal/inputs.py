"""Files a command reads whole (data files, cal.json, model files): checked
before they are read, so a device such as /dev/zero, a FIFO or a folder never
hangs or crashes a command, and a file too large for what it claims to be is
refused.  One line (UserError) naming the file."""
from __future__ import annotations

import os
import stat

from .errors import UserError

MAX_DATA_BYTES = 2 << 30          # a data file (CSV, logs): 2 GiB
MAX_JSON_BYTES = 64 << 20         # a cal.json or model file: 64 MiB


def file_kind(mode: int) -> str:
    """What a non-regular file is, in words (for one-line errors)."""
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def check_input_file(path, *, what: str = "", max_bytes: int | None = MAX_DATA_BYTES) -> str:
    """``path`` exists, is a regular file (symlinks followed) and holds at
    most ``max_bytes``; returns it.  UserError otherwise."""
    p = os.fspath(path)
    label = f"{what} {p}" if what else p
    try:
        st = os.stat(p)
    except (OSError, ValueError) as e:
        raise UserError(f"cannot read {label}: {getattr(e, 'strerror', None) or e}") from None
    if not stat.S_ISREG(st.st_mode):
        raise UserError(f"cannot read {label}: it is {file_kind(st.st_mode)}, not a regular file")
    if max_bytes is not None and st.st_size > max_bytes:
        raise UserError(f"cannot read {label}: {st.st_size} bytes, more than the "
                        f"{max_bytes} such a file may have")
    return p


def read_input_bytes(path, *, what: str = "", max_bytes: int | None = MAX_DATA_BYTES) -> bytes:
    """A checked input file's bytes (``check_input_file``)."""
    p = check_input_file(path, what=what, max_bytes=max_bytes)
    label = f"{what} {p}" if what else p
    try:
        with open(p, "rb") as f:
            data = f.read(max_bytes + 1) if max_bytes is not None else f.read()
    except OSError as e:
        raise UserError(f"cannot read {label}: {e.strerror or e}") from None
    if max_bytes is not None and len(data) > max_bytes:
        raise UserError(f"cannot read {label}: more than the {max_bytes} bytes such a file "
                        "may have")
    return data


def read_input_text(path, *, what: str = "", max_bytes: int | None = MAX_JSON_BYTES) -> str:
    """A checked input file as UTF-8 text (one line naming it if it is not)."""
    data = read_input_bytes(path, what=what, max_bytes=max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        label = f"{what} {os.fspath(path)}" if what else os.fspath(path)
        raise UserError(f"{label} is not UTF-8 text (byte {e.start})") from None
