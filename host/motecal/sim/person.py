"""A person at the bench following the guided flow's suggestions (issue 19).

``PersonTrajectory`` is a trajectory decided as the session goes: the board
is held still (with hand tremor) until the person is asked to move, then
turned along a minimum-jerk move (``trajectory.move_duration``) to a new
orientation, held again, and so on.  ``Person`` watches a guided capture
(``capture.guide.PoseCapture`` / ``AdaptiveCapture``) the way a person
watches the screen: when the flow asks for a move, after a reaction time it
places the board on the suggested gravity direction -- off by a placement
error (a random tilt, rms ``placement_deg``) and at a heading of its own
choosing (the suggestion leaves it free) -- and holds it until asked again.

Nothing of the future is decided early: a move starts after every sample
already read (``PersonTrajectory.read_until``), so the motes read it with
``read_ahead = 1`` (``person_network``) and the whole path (sim ->
BaseStation -> serial -> logger -> guide -> person) is causal.

``run_guided`` drives a flow straight from one board's samples (no radio:
the bench's fast path, same state machine and same person); the person-time
it reports is the trajectory's time from the start to the flow's end.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from ..capture.guide import Phase
from ..capture.logger import NullDisplay
from ..maths.sphere import unit
from ..sessions.session import LABEL_NONE, SessionData
from .network import Network
from .physics import SineProcess, _Tremor
from .trajectory import (DEFAULT_LEVER_M, Motion, Trajectory, _min_jerk, _rodrigues,
                         move_duration, up_to_rotation)

PLACEMENT_DEG = 6.0           # rms tilt of a placed board away from the suggestion
REACTION_S = (1.0, 2.0)       # reading the screen and taking hold of the board (uniform)
TREMOR_DEG = 0.04             # rms hand tremor about each axis while holding
TREMOR_HZ = 3.0               # its band


class PersonTrajectory(Trajectory):
    """Holds and moves appended as the person decides (module doc).  Segment
    i starts at ``t0[i]`` in ``R0[i]`` and turns by ``rotvec[i]`` over
    ``dur[i]`` seconds (0: a hold, open-ended for the last one)."""

    type_name = "person"

    def __init__(self, seed: int, rate_hz: float = 125.0, *, max_poses: int = 200,
                 tremor_deg: float = TREMOR_DEG, lever_m=DEFAULT_LEVER_M):
        super().__init__("person", seed, math.inf, rate_hz, lever_m, ())
        rng = np.random.default_rng([0x9E450, int(seed)])
        self.rng = rng
        self.max_poses = int(max_poses)
        self.t0 = [0.0]
        self.R0 = [up_to_rotation([0.0, 0.0, 1.0], rng.uniform(-np.pi, np.pi))]
        self.rotvec = [np.zeros(3)]
        self.dur = [0.0]
        self.seg_label = [LABEL_NONE]
        self.read_until = -math.inf
        self.holds = 0
        self.tremor = None
        if tremor_deg > 0:
            k = 8
            freqs = rng.uniform(0.1, TREMOR_HZ, (3, k))
            self.tremor = _Tremor(SineProcess(rng, np.radians(tremor_deg), freqs))

    @property
    def n_poses(self) -> int:
        return self.max_poses

    def _seg(self, t):
        t0 = np.asarray(self.t0)
        i = np.clip(np.searchsorted(t0, t, side="right") - 1, 0, len(t0) - 1)
        return i

    def _label(self, t):
        return np.asarray(self.seg_label, np.int32)[self._seg(t)]

    def _kin(self, t):
        t = np.asarray(t, float)
        if len(t):
            self.read_until = max(self.read_until, float(np.max(t)))
        i = self._seg(t)
        t0 = np.asarray(self.t0)[i]
        dur = np.asarray(self.dur)[i]
        moving = dur > 0
        T = np.where(moving, dur, 1.0)
        tau = np.where(moving, (t - t0) / T, 0.0)
        s, ds, dds = _min_jerk(tau)
        s = np.where(moving, s, 0.0)
        v = np.asarray(self.rotvec)[i]
        R = np.asarray(self.R0)[i] @ _rodrigues(s[:, None] * v)
        w = np.where(moving, ds / T, 0.0)[:, None] * v
        dw = np.where(moving, dds / (T * T), 0.0)[:, None] * v
        lab = np.asarray(self.seg_label)[i].astype(float)
        return R, w, dw, lab

    def at(self, t, gravity_g: float = 1.0) -> Motion:
        m = super().at(t, gravity_g)
        if self.tremor is not None:
            m = self.tremor.apply_motion(m, np.atleast_1d(np.asarray(t, float)))
        return m

    def orientation_at(self, t: float) -> np.ndarray:
        return self._kin(np.array([t]))[0][0]

    def place(self, t_start: float, up_target, placement_deg: float = PLACEMENT_DEG) -> float:
        """Move, from ``t_start`` (or just after the last sample read), to a
        board whose up direction (body frame) is ``up_target`` tilted by a
        random placement error, at a random heading; hold it from the end of
        the move on.  Returns the time the hold begins."""
        rate = self.rate_hz
        t_start = max(float(t_start), self.read_until + 1.0 / rate, self.t0[-1] + self.dur[-1])
        R_from = self.orientation_at(t_start)
        up = unit(np.asarray(up_target, float))
        tilt = np.radians(abs(self.rng.normal(0.0, placement_deg)))
        axis = unit(np.cross(up, unit(self.rng.normal(size=3))))
        up = Rotation.from_rotvec(axis * tilt).apply(up)
        R_to = up_to_rotation(up, self.rng.uniform(-np.pi, np.pi))
        v = Rotation.from_matrix(R_from.T @ R_to).as_rotvec()
        T = move_duration(float(np.linalg.norm(v)))
        if self.dur[-1] == 0.0 and self.t0[-1] < t_start:       # end the current hold
            self.t0.append(t_start); self.R0.append(R_from); self.rotvec.append(v)
            self.dur.append(T); self.seg_label.append(LABEL_NONE)
        else:                                                   # (nothing held yet)
            self.t0[-1], self.R0[-1], self.rotvec[-1], self.dur[-1] = t_start, R_from, v, T
            self.seg_label[-1] = LABEL_NONE
        self.holds += 1
        self.t0.append(t_start + T); self.R0.append(R_to); self.rotvec.append(np.zeros(3))
        self.dur.append(0.0); self.seg_label.append(self.holds)
        return t_start + T

    def _params_json(self):
        return {"t0": list(self.t0), "R0": [np.asarray(r).tolist() for r in self.R0],
                "rotvec": [np.asarray(v).tolist() for v in self.rotvec], "dur": list(self.dur),
                "label": [int(x) for x in self.seg_label]}


class Person:
    """Follows one guided capture's suggestions (module doc)."""

    def __init__(self, trajectory: PersonTrajectory, *, placement_deg: float = PLACEMENT_DEG,
                 reaction_s=REACTION_S):
        self.traj = trajectory
        self.placement = float(placement_deg)
        self.reaction = tuple(reaction_s)
        self.busy_until = -math.inf
        self.moves = 0
        self.done_at = None

    def observe(self, now: float, capture) -> None:
        """The person looks at the flow at simulated time ``now``."""
        if capture is None:
            return
        if capture.done:
            if self.done_at is None:
                self.done_at = now
            return
        first = self.moves == 0
        if (first or capture.phase is Phase.MOVE) and now >= self.busy_until:
            start = now + self.traj.rng.uniform(*self.reaction)
            self.busy_until = self.traj.place(start, capture.target, self.placement)
            self.moves += 1


class PersonDisplay(NullDisplay):
    """A logger display through which the person sees the flow of one mote
    (in-process sessions: ``capture.logger.Logger`` calls ``tick`` after
    every read)."""

    def __init__(self, person: Person, clock, mote: int):
        self.person = person
        self.clock = clock
        self.mote = mote

    def tick(self, logger):
        if logger.guide is not None:
            self.person.observe(self.clock(), logger.guide.captures.get(self.mote))


def person_network(trajectory: PersonTrajectory, model, seed: int, mote: int = 1, **kw) -> Network:
    """One mote on the person's trajectory, its radio, the BaseStation and the
    serial line (``Network``; ``sim.world.WorldPort`` reads it), sampling as
    it goes (``read_ahead = 1``)."""
    board = model.board(mote, seed)
    net = Network({mote: board.sampler(trajectory, seed)}, {mote: board.clock_ppm},
                  duration=math.inf, seed=seed, rate_hz=model.rate_hz, **kw)
    for m in net.motes.values():
        m.read_ahead = 1
    net.boards = {mote: board}
    return net


def run_guided(capture, model, seed: int, *, mote: int = 1, trajectory=None,
               person: Person | None = None, step_s: float = 0.04,
               max_s: float = 3600.0) -> tuple[SessionData, dict]:
    """One board's samples straight into ``capture`` (no radio) while
    ``person`` follows it, until the flow is done (or ``max_s``).  Returns the
    session (labels as the flow set them, ``meta["truth"]``, ``physical_truth``;
    a warming board -- a ``thermal`` term, e.g. the mismatch suite's -- gives
    ``temp``, the ITG3200's reading per row, as ``simulate_session`` does)
    and the person's figures: ``time_s`` (from the start to the flow's end:
    holds, moves and reactions), ``moves``, ``poses``."""
    traj = trajectory or PersonTrajectory(seed, model.rate_hz)
    person = person or Person(traj)
    board = model.board(mote, seed)
    sampler = board.sampler(traj, seed)
    period = 1.0 / (model.rate_hz * (1.0 + board.clock_ppm * 1e-6))
    per_step = max(1, int(round(step_s / period)))
    raws, labels = [], []
    k = 0
    mote_arr = np.full(per_step, mote, np.int32)
    while not capture.done and k * period < max_s:
        person.observe(k * period, capture)
        t = (k + np.arange(per_step)) * period
        raw = sampler.read(t)
        seq = k + np.arange(per_step, dtype=np.int64)
        raws.append(raw)
        labels.append(np.zeros(per_step, np.int32))
        for ev in capture.update(seq, raw):
            if ev.kind == "label":
                lab = np.concatenate(labels) if len(labels) > 1 else labels[0]
                lab[ev.seq_lo:ev.seq_hi + 1] = ev.label
                labels = [lab]
        k += per_step
    del mote_arr
    raw = np.vstack(raws).astype(np.float64)
    label = np.concatenate(labels)
    n = len(raw)
    t = np.arange(n) * period
    data = SessionData(
        name=f"person-{capture.kind}-seed{seed}", raw=raw, mote=np.full(n, mote, np.int32),
        seq=np.arange(n, dtype=np.int64), t=t, label=label, flags=np.zeros(n, np.uint8),
        kind=capture.kind,
        meta={"source": "sim", "rate_hz": model.rate_hz, "seed": int(seed), "model": model.name,
              "truth": board.to_json(), "physical_truth": board.physical_truth()},
        temp=board.temperature_reading_c(t) if board.thermal is not None else None)
    figures = {"time_s": float(n * period), "moves": person.moves,
               "poses": len(getattr(capture, "accepted", ())),
               "samples_in_poses": int((label >= 1).sum())}
    return data, figures
