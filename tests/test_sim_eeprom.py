"""The simulated mote persists an uploaded set with the firmware's own
background EEPROM writer; a World started on the same EEPROM file boots with
that set in force, as a real mote does after a reset."""
import json

import numpy as np
import pytest

from motecal import upload as U
from motecal.calib.board import calibrate_board
from motecal.errors import UserError
from motecal.firmware.mote_c import EepromWriter
from motecal.line import protocol as P
from motecal.sim import simulate_session
from motecal.sim.world import World, WorldPort


@pytest.fixture(scope="module")
def cal(tmp_path_factory):
    data = simulate_session("static80", motes=(1,), seed=1)[1]
    path = tmp_path_factory.mktemp("cal") / "cal.json"
    calibrate_board(data, seed=1, kfold=0).save(path)
    return U.load_cal(path)


def test_uploaded_set_survives_a_reboot(tmp_path, cal):
    ee = tmp_path / "eeprom.json"
    w = World(motes=2, session="idle", seed=1, duration=600.0, eeprom=ee)
    port = WorldPort(w)
    w.run_until(0.5)
    res = U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    assert res.version == 1
    # the image is written byte by byte in the background (108 bytes x 3.4 ms
    # = 0.37 s), read back, and only then reported stored: the upload waited
    assert res.stored.reported and res.stored.seconds > 0.37
    assert w.motes[1].eeprom_writes == 1 and w.motes[2].eeprom_writes == 0
    saved = json.loads(ee.read_text())
    assert saved["format"] == "motecal-sim-eeprom" and set(saved["motes"]) == {"1", "2"}

    # reboot: a new world on the same EEPROM file
    w2 = World(motes=2, session="idle", seed=1, duration=5.0, eeprom=ee)
    rx1, rx2 = w2.motes[1].cal, w2.motes[2].cal
    assert rx1.version == 1 and rx1.active_calset() == w.motes[1].cal.active_calset()
    assert rx2.version == 0 and rx2.sensors == 0
    w2.run_until(5.0)
    assert np.all(w2.sent[1].flags == U.flags_for(1, 0b111))
    assert np.all(w2.sent[2].flags == 0)
    assert not np.array_equal(w2.sent[1].records, w2.sent[1].raw)


def test_torn_write_falls_back_to_the_older_set(tmp_path, cal):
    """Power lost while the second image is being written: the first stays."""
    ee = tmp_path / "eeprom.json"
    w = World(motes=1, session="idle", seed=2, duration=600.0, eeprom=ee)
    port = WorldPort(w)
    w.run_until(0.5)
    U.upload_cal(port, cal, 1, U.Options(), progress=U.NullProgress())
    w.run_until(w.now + 1.0)
    first = w.motes[1].cal.active_calset()
    up = U.Uploader(U.Link(port), 1)
    calset = U.build_set(cal, 1, 7)[0]
    up.stage(calset)
    up.apply(7, P.crc16(calset))
    w.run_until(w.now + 0.1)            # about 30 of 108 bytes written, then "power off"
    assert w.motes[1].ee.busy and w.motes[1].cal.stored_version == 1
    from motecal.sim.world import _save_eeproms
    _save_eeproms(ee, w.eeproms)        # what the chip holds at that moment
    w2 = World(motes=1, session="idle", seed=2, duration=1.0, eeprom=ee)
    assert w2.motes[1].cal.version == 1 and w2.motes[1].cal.active_calset() == first


def test_bad_eeprom_file_is_one_clear_error(tmp_path):
    bad = tmp_path / "e.json"
    bad.write_text('{"format": "something else"}')
    with pytest.raises(UserError, match="cannot read EEPROM file"):
        World(motes=1, session="idle", duration=1.0, eeprom=bad)
    bad.write_text('{"format": "motecal-sim-eeprom", "motes": {"1": "ff"}}')
    with pytest.raises(UserError, match="expected 4096"):
        World(motes=1, session="idle", duration=1.0, eeprom=bad)


def test_eeprom_file_that_cannot_be_written_is_refused_at_start(tmp_path):
    for path, why in ((tmp_path / "no" / "ee.json", "does not exist"),
                      (tmp_path, "is a directory")):
        with pytest.raises(UserError, match=f"EEPROM file .*{why}"):
            World(motes=1, session="idle", duration=1.0, eeprom=path)


def test_erased_eeprom_boots_raw():
    from motecal.firmware.mote_c import CalReceiver
    w = EepromWriter(CalReceiver(3))
    assert w.restored.slot is None and not w.busy and not w.step()
