"""Two uploads to one mote: exit status and message agree (issue 28, item 9).

The first upload printed "commit: accepted, ... version 2 in force", then
lost the port (the simulator's TCP line takes the newest client) and exited
1 with "lost the port" and no word that the set was in force.  Now a failure
after the mote acknowledged the commit says that the set was acknowledged
in force and is neither verified nor known to be stored (exit 1,
``CommittedNotFinished``); a port lost between sending the commit and its
ack says the state is unknown; and the one-step form does not say "not
uploaded" of a set the mote took.
"""
import pytest

from clirun import motecal
from motecal import upload as U
from motecal.errors import UserError
from motecal.line import protocol as P
from motecal.line import sources as S
from motecal.sim.serve import serve_in_thread
from motecal.sim.world import World, WorldPort
from test_upload import cal  # noqa: F401  (the module's calibrated board)


def _acks(frames):
    return any(f.am() and f.am().am_type == P.AM_NINEDOF_CAL_COMMIT_ACK_MSG for f in frames)


class _LostAfterCommitAck(WorldPort):
    """The line, lost right after the mote's commit ack came through."""

    lost = False

    def read(self):
        if self.lost:
            raise S.SourceLost("connection closed")
        frames = super().read()
        self.lost = _acks(frames)
        return frames


class _LostAfterCommitSent(WorldPort):
    """The line, lost as soon as the commit has been sent (before its ack)."""

    sent = False

    def send(self, am, ack_seq=None):
        super().send(am, ack_seq)
        self.sent = self.sent or am.am_type == P.AM_NINEDOF_CAL_COMMIT_MSG

    def read(self):
        if self.sent:
            raise S.SourceLost("connection closed")
        return super().read()


def _world(port_class, seed=21):
    w = World(motes=1, session="idle", seed=seed, duration=3600.0)
    port = port_class(w)
    w.run_until(0.5)
    return w, port


def test_lost_after_the_commit_ack_says_the_set_is_in_force(cal):  # noqa: F811
    w, port = _world(_LostAfterCommitAck)
    with pytest.raises(U.CommittedNotFinished) as e:
        U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    msg = str(e.value)
    assert w.motes[1].cal.version == 1                     # the mote did take it
    assert "acknowledged calibration version 1 in force" in msg and "lost the port" in msg
    assert "not verified and not known to be stored" in msg and "--show" in msg
    assert "\n" not in msg and e.value.exit_code == 1


def test_lost_before_the_commit_ack_says_the_state_is_unknown(cal):  # noqa: F811
    w, port = _world(_LostAfterCommitSent)
    with pytest.raises(U.UploadFailed) as e:
        U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    msg = str(e.value)
    assert not isinstance(e.value, U.CommittedNotFinished)
    assert "the commit of version 1 was sent" in msg and "is unknown" in msg, msg


def test_the_command_line_says_in_force_and_exits_1(cal, monkeypatch, tmp_path):  # noqa: F811
    """``motecal upload`` and the one-step ``calibrate --upload`` form."""
    from motecal.commands import upload as cmd
    w, port = _world(_LostAfterCommitAck)
    monkeypatch.setattr(cmd, "_open", lambda spec: port)
    rc, out, err = motecal("upload", cal.path, "--port", "socket://127.0.0.1:9")
    assert rc == 1 and err.count("\n") == 1, err
    assert "commit: accepted" in out and "version 1 in force" in out
    assert "acknowledged calibration version 1 in force" in err and "not verified" in err
    from motecal.calib.result import BoardCalibration
    board = BoardCalibration.load(cal.path)
    w2, port2 = _world(_LostAfterCommitAck, seed=22)
    monkeypatch.setattr(cmd, "_open", lambda spec: port2)
    args = type("A", (), {"upload": True, "port": "socket://127.0.0.1:9", "baud": None,
                          "force": False})()
    step = cmd.calibrate_step(args)
    with pytest.raises(UserError) as e:                      # exit 1, one line
        step(board, tmp_path / "cal.json")
    msg = str(e.value)
    assert "and committed to mote 1, but the upload did not finish" in msg
    assert "not uploaded" not in msg and e.value.exit_code == 1


def test_two_uploads_on_the_simulators_tcp_line(cal):  # noqa: F811
    """The case of the issue: a second client connects to ``motecal sim
    --serve`` (which takes the newest client) right after the first upload's
    commit was acknowledged; the first upload says the set is in force."""
    world = World(motes=1, session="idle", seed=23, duration=3600.0)
    server, tcp = serve_in_thread(world)
    url = f"socket://127.0.0.1:{tcp}"
    second = []

    class First(S.SerialSource):
        def read_block(self):
            block = super().read_block()
            if not second and _acks(block.frames()):
                second.append(S.open_source(url))         # another upload connects
            return block

    first = First(S.parse_port(url))
    try:
        with pytest.raises(U.CommittedNotFinished) as e:
            U.upload_cal(first, cal, 1, U.Options(), progress=U.NullProgress())
        assert "acknowledged calibration version 1 in force" in str(e.value)
        assert "lost the port" in str(e.value)
        assert world.motes[1].cal.version == 1
    finally:
        first.close()
        for s in second:
            s.close()
        server.stop()
