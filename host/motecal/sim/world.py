"""The simulated world: N boards on one rig (physics) + motes, radio,
BaseStation and serial line (network), in one object other code can drive.

    w = World(motes=3, session="static80", seed=1)
    data = w.run_until(10.0)        # serial bytes up to simulated t = 10 s
    w.write(frame)                  # PC -> BaseStation bytes, at w.now
    w.done, w.stats, w.sent[1].seq, w.sent[1].raw, w.truth()
    port = WorldPort(w)             # a motecal.line.sources.Source in simulated time

Mote ids are 1..N; the BaseStation is 0.  The session lasts the trajectory's
duration (or ``duration``); ``done`` is True once it is over and every queue
has drained onto the line.  The motes keep answering calibration messages
after that.  A sequence of kinds (``session="static80,static80"``) samples
through all of them: log the first, calibrate, upload, log the second.
With ``eeprom=FILE`` each mote's EEPROM lives in that file: a calibration
uploaded in one run is restored at boot in the next, as on a real mote.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

from ..errors import UserError
from ..line import protocol as P
from ..line.sources import PortSpec, Source, SourceEnded, baud_problem
from .model import load_model, write_truth
from .network import Network
from .trajectory import KINDS, make_trajectory

MAX_BATCH = 6        # 4 + 18 * 6 = 112 <= 114, the RF230's largest TOSH_DATA_LENGTH
MAX_MOTES = 1000


MAX_DURATION_S = 1e6          # simulated seconds (11.6 days)


def check_options(motes, session, baud, loss, batch, duration) -> None:
    """UserError (one line) for any option out of range."""
    if isinstance(motes, bool) or not isinstance(motes, int) or not 1 <= motes <= MAX_MOTES:
        raise UserError(f"--motes must be an integer 1..{MAX_MOTES}, not {motes}")
    if not isinstance(session, str) or not all(k.strip() in KINDS for k in session.split(",")):
        raise UserError(f"unknown session {session!r} (expected one of {', '.join(KINDS)}, "
                        "or a sequence such as static80,static80)")
    problem = baud_problem(baud)
    if problem:
        raise UserError(f"--baud: {problem}")
    if not (isinstance(loss, (int, float)) and 0.0 <= loss <= 1.0):
        raise UserError(f"--loss must be a probability within 0..1, not {loss}")
    if not isinstance(batch, int) or not 1 <= batch <= MAX_BATCH:
        raise UserError(f"--batch must be 1..{MAX_BATCH} (4 + 18 x batch bytes must fit "
                        f"the RF230's 114-byte payload), not {batch}")
    if duration is not None and not (0 < duration <= MAX_DURATION_S):
        raise UserError(f"--duration must be a number of seconds within 0..{MAX_DURATION_S:g}, "
                        f"not {duration}")


class World(Network):
    def __init__(self, motes: int = 3, session: str = "static80", seed: int = 1,
                 baud: int = 250000, loss: float = 0.0, model=None,
                 batch: int = P.NINEDOF_BATCH, duration: float | None = None,
                 *, cal_factory="auto", eeprom: str | os.PathLike | None = None,
                 temperature: bool = True):
        check_options(motes, session, baud, loss, batch, duration)
        self.eeprom_path = Path(eeprom) if eeprom is not None else None
        self.eeproms = _load_eeproms(self.eeprom_path, motes)
        self.seed = int(seed)
        self.session = session
        self.model = model if hasattr(model, "board") else load_model(model)
        self.trajectory = make_trajectory(session, self.seed, duration=duration,
                                          rate_hz=self.model.rate_hz)
        dur = float(duration) if duration is not None else float(self.trajectory.duration)
        self.boards = {m: self.model.board(m, self.seed) for m in range(1, motes + 1)}
        samplers = {m: b.sampler(self.trajectory, self.seed) for m, b in self.boards.items()}
        ppm = {m: b.clock_ppm for m, b in self.boards.items()}
        super().__init__(samplers, ppm, duration=dur, baud=baud, loss=loss, batch=batch,
                         seed=self.seed, rate_hz=self.model.rate_hz, cal_factory=cal_factory,
                         eeprom=self.eeproms, temperature=temperature)

    def eeprom_written(self, mote_id: int) -> None:
        if self.eeprom_path is not None:
            _save_eeproms(self.eeprom_path, self.eeproms)

    def network_truth(self) -> dict:
        """When each mote sampled: sample k of mote m was taken at true time
        ``t0_s + k * period_s`` and carries sequence number ``k mod 65536``."""
        return {str(m): {"t0_s": mote.t0, "period_s": mote.period,
                         "clock_ppm": mote.clock_ppm, "samples": mote.n_total}
                for m, mote in self.motes.items()}

    def truth(self) -> dict:
        """The physics truth (model.write_truth's JSON: the model with every
        board written out, seed, trajectory, physical truth per board) plus
        ``truth.network`` (see network_truth)."""
        d = write_truth(os.devnull, self.model, self.boards, self.trajectory, self.seed)
        d["truth"]["network"] = self.network_truth()
        d["truth"]["session"] = dict(kind=self.session, duration_s=self.duration,
                                     motes=len(self.motes), baud=self.baud, loss=self.loss,
                                     batch=self.batch)
        return d

    def write_truth(self, path) -> dict:
        d = self.truth()
        try:
            Path(path).write_text(json.dumps(d, indent=1) + "\n", encoding="utf-8")
        except OSError as e:
            raise UserError(f"cannot write truth file {path}: {e.strerror or e}") from None
        return d


EEPROM_FORMAT = "motecal-sim-eeprom"
EEPROM_SIZE = 4096


def _check_writable(path: Path) -> None:
    """The EEPROM file can be written where _save_eeproms writes it (a temp
    file beside it, renamed): checked at start, not when a mote first stores
    a set in the middle of an upload."""
    if path.is_dir():
        raise UserError(f"cannot use EEPROM file {path}: it is a directory")
    if not path.parent.is_dir():
        raise UserError(f"cannot use EEPROM file {path}: folder {path.parent} does not exist")
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_bytes(b"")
        tmp.unlink()
    except OSError as e:
        raise UserError(f"cannot write EEPROM file {path}: {e.strerror or e}") from None


def _load_eeproms(path: Path | None, motes: int) -> dict[int, bytearray]:
    """Each mote's EEPROM (erased: 0xFF) or as the file left it."""
    ee = {m: bytearray(b"\xff" * EEPROM_SIZE) for m in range(1, motes + 1)}
    if path is not None:
        _check_writable(path)
    if path is None or not path.exists():
        return ee
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
        if d.get("format") != EEPROM_FORMAT:
            raise ValueError(f"not a {EEPROM_FORMAT} file")
        for m, hexdata in d["motes"].items():
            data = bytes.fromhex(hexdata)
            if len(data) != EEPROM_SIZE:
                raise ValueError(f"mote {m}: {len(data)} bytes, expected {EEPROM_SIZE}")
            if int(m) in ee:
                ee[int(m)][:] = data
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
        raise UserError(f"cannot read EEPROM file {path}: {e}") from None
    return ee


def _save_eeproms(path: Path, ee: dict[int, bytearray]) -> None:
    """Write atomically (temp file + rename): a crash keeps the old file."""
    old = {}
    if path.exists():
        try:
            old = json.loads(path.read_text(encoding="utf-8")).get("motes", {})
        except (OSError, ValueError):
            old = {}
    old.update({str(m): bytes(v).hex() for m, v in ee.items()})
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps({"format": EEPROM_FORMAT, "motes": old}) + "\n",
                       encoding="utf-8")
        os.replace(tmp, path)
    except OSError as e:
        raise UserError(f"cannot write EEPROM file {path}: {e.strerror or e}") from None


class WorldPort(Source):
    """The world's serial line as a ``motecal.line.sources.Source``, in process and
    in simulated time: every ``read()`` runs the world ``step`` simulated
    seconds further and returns the frames completed meanwhile; ``send()``
    puts a frame into the BaseStation's UART.  ``clock()`` is the simulated
    time, for code that waits (the uploader's timeouts then count simulated
    seconds, and a run is deterministic in the seed).  With ``until`` the
    port ends (``SourceEnded``, as a recorded file does) at that simulated
    time, so a logger reading it stops exactly there."""

    def __init__(self, world: World, step: float = 0.005, until: float | None = None):
        super().__init__(PortSpec("serial", "world", world.baud, 0, "<simulated world>"))
        self.world = world
        self.step = float(step)
        self.until = until
        self.decoder = P.FrameDecoder()
        self.stats = self.decoder.stats

    def clock(self) -> float:
        return self.world.now

    def read(self) -> list:
        t = self.world.now + self.step
        if self.until is not None:
            if self.world.now >= self.until:
                raise SourceEnded(str(self.spec))
            t = min(t, self.until)
        return self.decoder.feed(self.world.run_until(t))

    def send(self, am: P.AMPacket, ack_seq: int | None = None) -> None:
        self.world.write(P.encode_am(am, ack_seq=ack_seq))

    def close(self) -> None:
        pass
