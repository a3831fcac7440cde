"""Issue 15, cases 1-3: an output never clobbers an input, the database or a
special file (motecal.outputs; docs/guarantees.md)."""
import os
import stat

import pytest

from clirun import digest, make_db, motecal
from motecal.errors import UserError
from motecal.outputs import check_output, open_output, same_file, write_text


def test_case1_export_over_its_database_is_refused(tmp_path):
    db = make_db(tmp_path / "e.db", "board", "other")
    before = digest(db)
    rc, out, err = motecal("export", "--db", db, "--session", "board", "--csv", db)
    assert rc == 2 and "input of this command" in err and err.count("\n") == 1
    assert digest(db) == before
    # through a symlink, a hard link, or the database's WAL companion: refused too
    os.symlink(db, tmp_path / "link.db")
    os.link(db, tmp_path / "hard.db")
    for out_path in (tmp_path / "link.db", tmp_path / "hard.db", db + "-wal", db + "-shm"):
        rc, _, err = motecal("export", "--db", db, "--session", "board", "--csv", out_path)
        assert rc == 2, (out_path, err)
    assert digest(db) == before
    assert sorted(os.listdir(tmp_path)) == ["e.db", "hard.db", "link.db"]


def test_case1_another_database_is_never_overwritten(tmp_path):
    db = make_db(tmp_path / "e.db")
    other = make_db(tmp_path / "other.db")
    before = digest(other)
    rc, _, err = motecal("export", "--db", db, "--session", "board", "--csv", other)
    assert rc == 2 and "sqlite database" in err
    assert digest(other) == before


def test_case2_calibrate_out_over_its_database_is_refused(tmp_path):
    db = make_db(tmp_path / "c.db")
    before = digest(db)
    rc, out, err = motecal("calibrate", "--db", db, "--session", "board", "--out", db)
    assert rc == 2 and "input of this command" in err and "Traceback" not in err
    assert digest(db) == before
    assert sorted(os.listdir(tmp_path)) == ["c.db"]


def test_case2_diagnose_and_sim_outputs_over_inputs_are_refused(tmp_path):
    db = make_db(tmp_path / "d.db")
    before = digest(db)
    for opt in ("--json", "--model-out"):
        rc, _, err = motecal("diagnose", "--db", db, "--session", "board", opt, db)
        assert rc == 2 and "input of this command" in err
    rc, _, err = motecal("diagnose", "--db", db, "--session", "board", "--report", tmp_path)
    assert rc == 2 and "inside it" in err
    rc, _, err = motecal("report", "--db", db, "--session", "board", "--out", tmp_path)
    assert rc == 2 and "inside it" in err
    assert digest(db) == before
    rc, _, err = motecal("sim", "--out", tmp_path / "s.bin", "--truth", tmp_path / "s.bin",
                         "--duration", "0.1")
    assert rc == 2 and "input of this command" in err
    assert sorted(os.listdir(tmp_path)) == ["d.db"]


def test_case3_symlink_is_written_through(tmp_path):
    db = make_db(tmp_path / "e.db")
    real = tmp_path / "real.csv"
    real.write_text("old\n")
    os.chmod(real, 0o640)
    link = tmp_path / "link.csv"
    os.symlink("real.csv", link)
    rc, out, err = motecal("export", "--db", db, "--session", "board", "--csv", link)
    assert rc == 0, err
    assert os.path.islink(link) and os.readlink(link) == "real.csv"
    assert real.read_text().startswith("mote,seq,t,label")
    assert stat.S_IMODE(os.stat(real).st_mode) == 0o640        # its mode kept
    # a dangling link: its target is created
    os.symlink("new.csv", tmp_path / "dangling.csv")
    rc, _, err = motecal("export", "--db", db, "--session", "board", "--csv",
                         tmp_path / "dangling.csv")
    assert rc == 0, err
    assert (tmp_path / "new.csv").read_text().startswith("mote,seq")
    assert os.path.islink(tmp_path / "dangling.csv")


def test_case3_fifo_and_special_files_are_never_replaced(tmp_path):
    db = make_db(tmp_path / "e.db")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    link = tmp_path / "null"                   # a symlink to a special file, like /dev/null
    os.symlink(fifo, link)
    for target in (fifo, link):
        rc, _, err = motecal("export", "--db", db, "--session", "board", "--csv", target)
        assert rc == 2 and "FIFO" in err, err
        rc, _, err = motecal("sim", "--out", target, "--duration", "0.1", "--quiet")
        assert rc == 2 and "FIFO" in err, err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and os.path.islink(link)
    rc, _, err = motecal("export", "--db", db, "--session", "board", "--csv", tmp_path)
    assert rc == 2 and "directory" in err
    assert sorted(os.listdir(tmp_path)) == ["e.db", "fifo", "null"]


def test_case3_dash_is_stdout(tmp_path, monkeypatch):
    db = make_db(tmp_path / "e.db")
    monkeypatch.chdir(tmp_path)
    rc, out, err = motecal("export", "--db", db, "--session", "board", "--csv", "-")
    assert rc == 0, err
    assert out.startswith("mote,seq,t,label") and out.count("\n") == 401
    assert "standard output" in err
    rc, out, err = motecal("sim", "--out", "-", "--duration", "0.1", "--quiet")
    assert rc == 0 and out
    # where a folder or a database is expected, '-' is refused (found by the fuzz test)
    rec = tmp_path / "rec.bin"
    rec.write_bytes(b"")
    for argv in (("report", "--db", db, "--session", "board", "--out", "-"),
                 ("diagnose", "--db", db, "--session", "board", "--report", "-"),
                 ("log", "--port", rec, "--db", "-", "--session", "s"),
                 ("sessions", "--db", "-")):
        rc, _, err = motecal(*argv)
        assert rc == 2 and "standard" in err, (argv, err)
    rec.unlink()
    assert sorted(os.listdir(tmp_path)) == ["e.db"]             # no file named '-'


def test_open_output_failure_keeps_the_old_file(tmp_path):
    target = tmp_path / "out.json"
    target.write_text("old\n")
    with pytest.raises(RuntimeError):
        with open_output(target) as f:
            f.write("half")
            raise RuntimeError("boom")
    assert target.read_text() == "old\n"
    assert os.listdir(tmp_path) == ["out.json"]
    write_text(target, "new\n")
    assert target.read_text() == "new\n" and os.listdir(tmp_path) == ["out.json"]


def test_check_output_rules(tmp_path):
    (tmp_path / "in.txt").write_text("x")
    assert same_file(tmp_path / "in.txt", f"sqlite:///{tmp_path}/in.txt")
    assert not same_file(tmp_path / "in.txt", "postgresql://u@h/db")
    with pytest.raises(UserError, match="folder"):
        check_output(tmp_path / "missing" / "x.csv")
    with pytest.raises(UserError, match="input"):
        check_output(tmp_path / "sub" / ".." / "in.txt", inputs=[tmp_path / "in.txt"])
    assert check_output("-") == "-"
