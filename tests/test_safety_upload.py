"""Issue 15, case 10: upload truth -- versions strictly increase unless
--force; format_version and types are checked; when every commit ack is lost
the read-back decides what is reported (simulated network, in process)."""
import json

import pytest

from clirun import motecal
from motecal import upload as U
from motecal.errors import UserError
from motecal.firmware import mote_c
from motecal.line import protocol as P
from motecal.sim.world import World, WorldPort
from test_upload import cal  # noqa: F401  (the module's calibrated board)


def _world(seed=11, cal_factory="auto"):
    w = World(motes=1, session="idle", seed=seed, duration=3600.0, cal_factory=cal_factory)
    port = WorldPort(w)
    w.run_until(0.5)
    return w, port


class _NoCommitAcks(WorldPort):
    """The line, but every CAL_COMMIT_ACK from the mote is lost on the way."""

    def read(self):
        return [f for f in super().read()
                if not (f.am() and f.am().am_type == P.AM_NINEDOF_CAL_COMMIT_ACK_MSG)]


class _IgnoresApply(mote_c.CalReceiver):
    """A mote that never answers nor applies a commit (its radio lost them all)."""

    def handle(self, am_type, payload):
        if am_type == P.AM_NINEDOF_CAL_COMMIT_MSG:
            return None
        return super().handle(am_type, payload)


def test_case10_versions_strictly_increase_unless_force(cal):  # noqa: F811
    w, port = _world()
    opts = dict(progress=U.NullProgress())
    assert U.upload_cal(port, cal, 1, U.Options(version=5), **opts).version == 5
    crc = w.motes[1].cal.crc
    for v in (5, 4):                       # the version in force, an older one
        with pytest.raises(UserError, match=f"version 5 in force: --version {v} is not newer"):
            U.upload_cal(port, cal, 1, U.Options(version=v), **opts)
        assert w.motes[1].cal.version == 5 and w.motes[1].cal.crc == crc   # nothing sent
    assert U.upload_cal(port, cal, 1, U.Options(version=5, force=True), **opts).version == 5
    assert U.upload_cal(port, cal, 1, U.Options(), **opts).version == 6


def test_case10_lost_commit_ack_the_read_back_decides_success(cal):  # noqa: F811
    w = World(motes=1, session="idle", seed=12, duration=3600.0)
    port = _NoCommitAcks(w)
    w.run_until(0.5)
    notes = []

    class Notes(U.NullProgress):
        def note(self, text):
            notes.append(text)

    res = U.upload_cal(port, cal, 1, U.Options(timeout=0.1, retries=2), progress=Notes())
    calset = U.build_set(cal, 1, 1)[0]
    assert res.version == 1 and res.readback
    assert w.motes[1].cal.active_calset() == calset
    assert any("commit ack lost, but the read-back shows version 1 in force" in n
               for n in notes)


def test_case10_lost_commit_the_read_back_says_nothing_changed(cal):  # noqa: F811
    w, port = _world(seed=13, cal_factory=_IgnoresApply)
    with pytest.raises(U.UploadFailed) as e:
        U.upload_cal(port, cal, 1, U.Options(timeout=0.1, retries=2),
                     progress=U.NullProgress())
    msg = str(e.value)
    assert "did not acknowledge the commit of version 1" in msg
    assert "read-back shows version 0" in msg and "not applied" in msg and "\n" not in msg
    assert w.motes[1].cal.version == 0


@pytest.mark.parametrize("field,value,words", [
    ("format_version", 0, "format_version 0"), ("format_version", -1, "format_version -1"),
    ("format_version", "1", "format_version '1'"), ("format_version", True, "format_version"),
    ("mote", "1", "mote id"), ("A", [["1.0", 0, 0], [0, 1, 0], [0, 0, 1]], "not a list of numbers"),
    ("A", [[True, 0, 0], [0, 1, 0], [0, 0, 1]], "not a list of numbers"),
    ("c", [0, 0, 1e400], "infinite"), ("A", [[0, 0], [0, 0]], "must be 3x3"),
])
def test_case10_cal_json_types_are_checked(cal, tmp_path, field, value, words):  # noqa: F811
    d = json.loads(open(cal.path).read())
    if field in ("A", "c"):
        d["accel"][field] = value
    else:
        d[field] = value
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d).replace("Infinity", "1e400"))
    rc, out, err = motecal("upload", "--dry-run", bad)
    assert rc == 2 and words in err and err.count("\n") == 1 and "Traceback" not in err, err
