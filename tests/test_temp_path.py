"""The board temperature end to end: the simulated mote sends
ninedof_mote_temp_msg as the firmware does, and sim -> BaseStation -> serial
-> logger -> store -> export -> import carries it; a mote without the
message (an older image) gives a session without temperature.  (~15 s)"""
import csv

import numpy as np
import pytest

from motecal.commands.main import main
from motecal.line import protocol as P
from motecal.sessions.importer import read_csv
from motecal.sessions.store import open_store
from motecal.sim.serve import write_file
from motecal.sim.world import World

SEEDS = (1, 2, 3)


def warm(t):
    """A planted board temperature: 21 C at power-on, warming 6 C over the first minute."""
    t = np.asarray(t, float)
    return 21.0 + 6.0 * (1 - np.exp(-t / 60.0))


def _world(seed, motes=2, duration=12.0, temperature=True, plant=True):
    w = World(motes=motes, session="idle", seed=seed, duration=duration,
              temperature=temperature)
    if plant:
        w.motes[1].temperature_c = warm          # mote 2 keeps the board's own (25 C)
    return w


def _temp_messages(stream: bytes):
    out = []
    for f in P.decode_stream(stream):
        am = f.am()
        if am is not None and am.am_type == P.AM_NINEDOF_MOTE_TEMP_MSG:
            out.append((am.src, P.decode_message(am)))
    return out


@pytest.mark.parametrize("seed", SEEDS)
def test_sim_mote_sends_the_firmwares_temperature_message(seed, tmp_path):
    w = _world(seed)
    with open(tmp_path / "s.bin", "wb") as fh:
        write_file(w, fh)
    msgs = _temp_messages((tmp_path / "s.bin").read_bytes())
    mote = w.motes[1]
    mine = [m for src, m in msgs if src == 1]
    assert len(mine) >= 10, f"seed {seed}: {len(mine)} temperature messages of mote 1"
    assert {src for src, _ in msgs} == {1, 2}
    prev_newest = None
    for m in mine:
        # the truth: every sample read since the previous message, at its time
        newest = next(k for k, c, s in mote.temps if k & 0xFFFF == m["seq"] and c == m["count"])
        first = newest - m["count"] + 1
        t = mote.t0 + np.arange(first, newest + 1) * mote.period
        want = int(np.rint(P.temp_raw(warm(t))).sum())
        assert m["temp_sum"] == want, f"seed {seed}"
        if prev_newest is None:            # the first period starts at power-on
            assert first == 0 and m["count"] <= 126, f"seed {seed}"
        else:
            assert abs(m["count"] - 125) <= 1, f"seed {seed}: count {m['count']}"
            assert first == prev_newest + 1, f"seed {seed}: a sample counted twice or never"
        prev_newest = newest
    assert all(abs(P.temp_c(m["temp_sum"] / m["count"]) - 25.0) < 0.01
               for src, m in msgs if src == 2)


def _log(stream_path, db, session="s"):
    assert main(["log", "--port", str(stream_path), "--db", str(db), "--session", session,
                 "--kind", "idle"]) == 0


@pytest.mark.parametrize("seed", SEEDS)
def test_sim_to_export_and_back_carries_the_temperature(seed, tmp_path, capsys):
    w = _world(seed, duration=15.0)
    rec, db, out, db2 = (tmp_path / n for n in ("s.bin", "log.db", "s.csv", "imp.db"))
    with open(rec, "wb") as fh:
        write_file(w, fh)
    _log(rec, db)
    summary = capsys.readouterr().out
    lo, hi = warm(0.0), warm(15.0)
    assert f"temperature {lo:.1f}.." in summary or f"temperature {lo + 0.1:.1f}.." in summary
    assert f"..{hi:.1f} C" in summary or f"..{hi - 0.1:.1f} C" in summary, summary
    with open_store(str(db)) as st:
        d = st.load_session("s")
        readings = st.temps("s")
    assert d.has_temp and len(readings) >= 2 * 12
    # mote 1 against the planted temperature at each sample's true time
    one = d.for_mote(1)
    mote = w.motes[1]
    truth = warm(mote.t0 + one.seq * mote.period)
    ok = np.isfinite(one.temp)
    assert ok.mean() > 0.95, f"seed {seed}"
    err = np.abs(one.temp - truth)
    r = readings[readings[:, 0] == 1]
    centre = r[:, 1] - (r[:, 4] - 1) / 2
    inside = (one.seq >= centre.min()) & (one.seq <= centre.max())
    # between readings: 1-s means of readings rounded to 1/280 C, interpolated
    assert err[inside].max() < 0.01, f"seed {seed}: max error {err[inside].max():.4f} C"
    # at the ends the nearest reading, at most 2 s away (warming <= 0.1 C/s)
    assert err[ok & ~inside].max() < 0.1 * 2 + 0.01, f"seed {seed}"
    assert np.allclose(d.for_mote(2).temp[np.isfinite(d.for_mote(2).temp)], 25.0, atol=0.01)
    # export: a temp column after the nine sensor columns; import gives it back
    assert main(["export", "--db", str(db), "--session", "s", "--csv", str(out)]) == 0
    rows = list(csv.reader(out.open()))
    assert rows[0][-1] == "temp" and rows[0][4:13] == ["ax", "ay", "az", "gx", "gy", "gz",
                                                        "mx", "my", "mz"]
    assert main(["import", str(out), "--db", str(db2), "--session", "r"]) == 0
    with open_store(str(db2)) as st:
        back = st.load_session("r")
    np.testing.assert_array_equal(back.temp, d.temp)
    assert np.array_equal(back.raw, d.raw)
    capsys.readouterr()


def test_an_old_image_gives_a_session_without_temperature(tmp_path):
    w = _world(4, duration=6.0, temperature=False)
    rec, db, out = tmp_path / "s.bin", tmp_path / "log.db", tmp_path / "s.csv"
    with open(rec, "wb") as fh:
        write_file(w, fh)
    assert _temp_messages(rec.read_bytes()) == []
    _log(rec, db)
    with open_store(str(db)) as st:
        d = st.load_session("s")
    assert d.temp is None and len(d) > 1000
    assert main(["export", "--db", str(db), "--session", "s", "--csv", str(out)]) == 0
    assert out.read_text().splitlines()[0] == "mote,seq,t,label,ax,ay,az,gx,gy,gz,mx,my,mz"
    assert read_csv(out).temp is None


def test_sim_command_no_temp(tmp_path):
    a, b = tmp_path / "a.bin", tmp_path / "b.bin"
    for path, extra in ((a, []), (b, ["--no-temp"])):
        assert main(["sim", "--motes", "2", "--session", "idle", "--duration", "4", "--seed", "3",
                     "--out", str(path), "--quiet", *extra]) == 0
    assert len(_temp_messages(a.read_bytes())) >= 6
    assert _temp_messages(b.read_bytes()) == []
