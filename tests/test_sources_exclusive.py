"""A serial device is one program's at a time (issue 28, item 1).

Two ``motecal log`` on one port each lost hundreds of samples, and an upload
beside a log made the logger lose samples with CRC errors: every reader took
bytes from the other.  A device is now opened with an exclusive flock (and a
UUCP lock file of a running process is honoured): the second opener gets one
line and exit 2, and the first keeps every byte.  pty pairs (``os.openpty``)
stand for the device; URLs, SerialForwarder and files are not locked.
"""
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from clirun import motecal
from motecal.line import protocol as P
from motecal.line import sources as S


@pytest.fixture
def pty():
    master, slave = os.openpty()
    name = os.ttyname(slave)
    yield master, name
    os.close(master)
    os.close(slave)


def _frames(n):
    rec = np.zeros((5, 9), np.int16)
    return [P.encode_am(P.AMPacket(0xFFFF, 1, 0x22, P.AM_NINEDOF_SAMPLES_MSG,
                                   P.pack_samples(5 * i, 0, rec))) for i in range(n)]


def _read(src, want, timeout=5.0):
    got, end = [], time.monotonic() + timeout
    while len(got) < want and time.monotonic() < end:
        got += src.read()
    return got


def test_the_second_opener_is_refused_and_the_first_keeps_every_byte(pty):
    master, name = pty
    first = S.open_source(name)
    try:
        with pytest.raises(S.PortError) as e:
            S.open_source(f"serial@{name}:57600")
        msg = str(e.value)
        assert "in use by another program" in msg and "sf@" in msg and "\n" not in msg
        frames = _frames(40)
        os.write(master, b"".join(frames))
        got = _read(first, 40)
        assert len(got) == 40 and first.stats.crc_errors == 0
    finally:
        first.close()
    again = S.open_source(name)                 # released with the first
    again.close()


def test_log_and_upload_beside_a_holder_are_one_line_and_exit_2(pty, tmp_path):
    master, name = pty
    holder = S.open_source(name)
    try:
        db = tmp_path / "s.db"
        rc, out, err = motecal("log", "--port", name, "--db", db, "--session", "s",
                               "--duration", "1", "--yes")
        assert rc == 2 and "in use by another program" in err and err.count("\n") == 1, err
        assert not db.exists()                  # the port first: nothing made
        from test_safety_fuzz import real_cal
        cal = tmp_path / "cal.json"
        cal.write_text(real_cal())
        rc, out, err = motecal("upload", cal, "--port", name)
        assert rc == 2 and "in use by another program" in err and err.count("\n") == 1, err
    finally:
        holder.close()


def test_urls_and_files_are_not_locked(tmp_path):
    a, b = S.open_source("loop://"), S.open_source("loop://")
    a.close()
    b.close()
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"".join(_frames(3)))
    f1, f2 = S.open_source(str(rec)), S.open_source(str(rec))
    assert len(_read(f1, 3, 1)) == 3 and len(_read(f2, 3, 1)) == 3
    f1.close()
    f2.close()


def test_a_uucp_lock_file_of_a_running_process_is_honoured(pty, tmp_path, monkeypatch):
    master, name = pty
    monkeypatch.setattr(S, "LOCK_DIRS", (str(tmp_path),))
    lock = tmp_path / ("LCK.." + os.path.basename(name))
    lock.write_text(f"{os.getppid():10d}\n")                # alive, and not us
    with pytest.raises(S.PortError) as e:
        S.open_source(name)
    assert f"process {os.getppid()} holds its lock file" in str(e.value)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    lock.write_text(f"{int(dead):10d}\n")                    # stale: its process is gone
    S.open_source(name).close()
    lock.write_text("garbage")
    S.open_source(name).close()
