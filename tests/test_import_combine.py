"""One session from files of different formats, and ``motecal import
--append`` (issue 30; ``sessions.combine``): each file read by its own
reader, the same session whichever way it was put together, and the checks
``log --append`` makes (the session exists, the board's chips and scales,
its motes, no rows twice) -- a refused append stores nothing."""
import re

import numpy as np
import pytest

from motecal.commands.main import main
from motecal.errors import UserError
from motecal.sessions import importer as I
from motecal.sessions.combine import append, combine
from motecal.sessions.session import LABEL_ROT
from motecal.sessions.store import open_store


@pytest.fixture(scope="module")
def files(measured):
    faces = sorted((measured / "sensorstick-boards" / "razor1").glob("razor1_acc_*.raw"))
    return {"faces": faces[:3], "sweep": measured / "sensorstick-mag-sweep" / "magnetom.float",
            "other": measured / "hmc5843-disturbed-sweep" / "magnetom.float"}


def test_mixed_import_reads_each_file_by_its_reader(files):
    text = I.read_razor_text(files["faces"])
    flt = I.read_razor_float(files["sweep"])
    d = I.read_any([*files["faces"], files["sweep"]])
    n = len(text)
    np.testing.assert_array_equal(d.raw, np.vstack([text.raw, flt.raw]))
    np.testing.assert_array_equal(d.label[:n], text.label)
    assert (d.label[n:] == LABEL_ROT).all() and d.poses() == [1, 2, 3]
    assert [f["format"] for f in d.meta["files"]] == ["razor-text"] * 3 + ["razor-float"]
    assert d.meta["files"][-1]["rows"] == [n, n + len(flt)]
    assert [f["pose"] for f in d.meta["files"][:3]] == [1, 2, 3]
    assert np.all(np.diff(d.seq) == 1) and np.all(np.diff(d.t) > 0)
    assert d.kind == "static+rotation" and d.meta["format"] == "razor-text+razor-float"
    assert d.meta["axis_frame"].startswith("as recorded: Razor AHRS firmware board frame")
    # the same chip named differently for one sensor: refused, naming the files
    with pytest.raises(UserError, match="mag: .* HMC5883L at 1090 .* HMC5843 at 1300: one board"):
        combine([text, I.read_razor_float(files["other"], chip="hmc5843")])


def test_append_is_the_mixed_import(files, tmp_path, capsys):
    """Faces, then the sweep appended: the session of one mixed import (rows,
    labels, files); the checks refuse an append that does not fit, and the
    database is then unchanged."""
    db = tmp_path / "a.db"
    faces, sweep = [str(p) for p in files["faces"]], str(files["sweep"])
    assert main(["import", *faces, "--db", str(db), "--session", "s"]) == 0
    assert main(["import", sweep, "--db", str(db), "--session", "s", "--append"]) == 0
    assert "Appended 10000 rows to session 's'" in capsys.readouterr().out
    assert main(["import", *faces, sweep, "--db", str(db), "--session", "one"]) == 0
    with open_store(str(db)) as st:
        a, b = st.load_session("s"), st.load_session("one")
    np.testing.assert_array_equal(a.raw, b.raw)
    np.testing.assert_array_equal(a.label, b.label)
    np.testing.assert_array_equal(a.seq, b.seq)
    assert a.meta["files"] == b.meta["files"] and a.kind == b.kind
    before = db.read_bytes()
    bad = [([sweep], "its readings are already in session 's'"),           # twice
           ([faces[0]], "its readings are already in session 's'"),
           ([str(files["other"]), "--chip", "mag=hmc5843"], "one board per session")]
    bad += [(["--session", "nope"], "does not exist in .*--append continues a session"),
            (["--replace"], "--append adds to a session, --replace replaces it")]
    for args, why in bad:
        if args[0].startswith("--"):
            args = [sweep] + args
        cmd = ["import", *args, "--db", str(db), "--append"]
        if "--session" not in cmd:
            cmd += ["--session", "s"]
        capsys.readouterr()
        assert main(cmd) == 2, cmd
        err = capsys.readouterr().err
        assert err.startswith("motecal: error: ") and len(err.splitlines()) == 1, err
        assert re.search(why, err), (why, err)
    assert db.read_bytes() == before
    assert main(["import", sweep, "--db", str(tmp_path / "new.db"), "--session", "s",
                 "--append"]) == 2                     # no database: none is made
    assert not (tmp_path / "new.db").exists()


def test_append_csv_keeps_its_motes_and_refuses_stored_samples(files, tmp_path):
    """A project CSV carries mote ids and sequence numbers: appended as they
    are, unless a (mote, seq) is stored already (the same readings: imported
    before; other readings: a conflict)."""
    text = I.read_razor_text(files["faces"][:1])
    old = text.select(np.arange(500))
    csv = tmp_path / "part.csv"
    I.write_csv(text.select(np.arange(500, 800)), csv)
    more = I.read_any([csv])
    out = append(old, more)
    np.testing.assert_array_equal(out.seq[500:], np.arange(500, 800))
    np.testing.assert_array_equal(out.raw[500:], text.raw[500:800])
    I.write_csv(text.select(np.arange(400, 600)), csv)
    with pytest.raises(UserError, match="mote 1 samples 400...499 are already in the session "
                                        "with the same readings"):
        append(old, I.read_any([csv]))
