"""Trajectories of the simulated rig: what every board of a session goes through.

All motes of a simulated session ride the same rig: one trajectory, N boards.

Frames and units
----------------
* World frame: x north, y west, z up.  ``R(t)`` maps body -> world, so a
  vector known in the world (gravity reaction, the Earth field) reads
  ``R.T @ v`` in the body.
* ``omega`` is the body angular rate in deg/s (``R.T @ dR/dt = [omega]x``,
  in rad/s before the conversion).
* ``specific_force`` is in g in the body frame: the gravity reaction (a still
  board with body z up reads +1 g on z) plus the linear acceleration of the
  sensor, which sits ``lever_m`` metres (body frame) from the point the rig
  turns about: ``a = domega/dt x r + omega x (omega x r)``.

Kinds (``make_trajectory``)
---------------------------
* ``static80``: ``n_poses`` static orientations whose gravity directions form
  a randomly turned Fibonacci lattice (evenly spread over the sphere, ~20 deg
  apart for 80) with a random yaw each, visited in nearest-neighbour order;
  each is held ``still_s`` seconds, with minimum-jerk moves of 1.0-1.5 s
  between them (peak rate <= ~230 deg/s).  Label = pose index while still,
  0 while moving.
* ``rotation``: continuous smooth turning (a fast roll, a pitch sweep from
  pole to pole and a slow yaw, with random wobble) whose gravity and field
  directions cover the whole body sphere within 5000 samples (40 s at
  125 Hz); every sample is labelled ``LABEL_ROT``.
* ``idle``: one still pose (board flat, z up, random heading), default 60 s,
  labelled 1.
* ``free``: random smooth motion (sums of random sinusoids on yaw, pitch and
  roll), default 60 s, label 0.
* a sequence ``"static80,static80"`` (``SequenceTrajectory``): the kinds one
  after the other on the same rig, part i made with seed ``seed + i``, a
  minimum-jerk move (``move_duration``) between consecutive parts.  Pose
  labels continue (the second static80's poses are 81..160).

Outside ``[0, duration]`` the rig holds its first/last orientation and is
still (omega = 0); labels keep the label of the clamped time, except that a
rotation trajectory is not rotating after its end (label 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import UserError
from ..maths.sphere import fibonacci_sphere, unit
from ..sessions.session import LABEL_NONE, LABEL_ROT

KINDS = ("static80", "rotation", "idle", "free")
STANDARD_G = 9.80665                     # m/s^2 per g
DEFAULT_LEVER_M = (0.02, -0.01, 0.04)    # sensor position from the turning point (body, m)
TRAJECTORY_FORMAT = "motecal-sim-trajectory"
_SALT = 0x7A1EC7


@dataclass
class Motion:
    """What the rig does at a set of times (n samples)."""
    R: np.ndarray                 # (n, 3, 3) body -> world
    omega: np.ndarray             # (n, 3) body angular rate, deg/s
    label: np.ndarray             # (n,) int32: pose 1..N, LABEL_ROT, 0
    specific_force: np.ndarray    # (n, 3) g, body frame
    pose: np.ndarray              # (n,) float: continuous pose coordinate
    # (k while still at pose k, k + s(tau) while moving from k to k+1, 0 if no poses)

    def __len__(self):
        return len(self.label)


# --------------------------------------------------------------------------
# small vectorised helpers
# --------------------------------------------------------------------------
def _min_jerk(tau: np.ndarray):
    """s, ds/dtau, d2s/dtau2 of the minimum-jerk profile 10t^3-15t^4+6t^5."""
    tau = np.clip(tau, 0.0, 1.0)
    t2 = tau * tau
    s = t2 * tau * (10.0 - 15.0 * tau + 6.0 * t2)
    ds = 30.0 * t2 * (1.0 - tau) ** 2
    dds = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau)
    return s, ds, dds


def _rodrigues(rotvec: np.ndarray) -> np.ndarray:
    return Rotation.from_rotvec(rotvec).as_matrix()


def _zyx_matrix(a, b, c):
    """Rz(a) @ Ry(b) @ Rx(c) for arrays of angles (rad) -> (n, 3, 3)."""
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    R = np.empty(a.shape + (3, 3))
    R[..., 0, 0] = ca * cb
    R[..., 0, 1] = ca * sb * sc - sa * cc
    R[..., 0, 2] = ca * sb * cc + sa * sc
    R[..., 1, 0] = sa * cb
    R[..., 1, 1] = sa * sb * sc + ca * cc
    R[..., 1, 2] = sa * sb * cc - ca * sc
    R[..., 2, 0] = -sb
    R[..., 2, 1] = cb * sc
    R[..., 2, 2] = cb * cc
    return R


def up_to_rotation(up_body: np.ndarray, yaw: float) -> np.ndarray:
    """Body->world rotation that puts body vector ``up_body`` on world z, then
    turns the board by ``yaw`` (rad) about world z."""
    u = unit(up_body)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(u, z)
    s, c = np.linalg.norm(axis), float(u @ z)
    if s < 1e-12:
        axis = np.array([1.0, 0.0, 0.0]) * (0.0 if c > 0 else np.pi)
    else:
        axis = axis / s * np.arctan2(s, c)
    return Rotation.from_rotvec([0.0, 0.0, yaw]).as_matrix() @ _rodrigues(axis)


def _as_f(a):
    return np.asarray(a, dtype=np.float64)


# --------------------------------------------------------------------------
# trajectories
# --------------------------------------------------------------------------
class Trajectory:
    """Base: subclasses give ``_kin(t) -> (R, omega_rad, domega_rad, pose)``."""

    type_name = ""

    def __init__(self, kind: str, seed: int, duration: float, rate_hz: float,
                 lever_m=DEFAULT_LEVER_M, poses=()):
        self.kind = kind
        self.seed = int(seed)
        self.duration = float(duration)
        self.rate_hz = float(rate_hz)
        self.lever_m = _as_f(lever_m).reshape(3)
        self.poses = [np.asarray(p, float).reshape(3, 3) for p in poses]

    # -- to be provided --------------------------------------------------
    def _kin(self, t):
        raise NotImplementedError

    def _label(self, t):
        raise NotImplementedError

    # -- public ----------------------------------------------------------
    def label_at(self, t) -> np.ndarray:
        """(n,) int32 labels at true times t (cheap; no kinematics)."""
        t = np.atleast_1d(_as_f(t))
        return self._label(np.clip(t, 0.0, self.duration)).astype(np.int32)

    def at(self, t, gravity_g: float = 1.0) -> Motion:
        """Motion at arbitrary (not necessarily uniform or sorted) times t (s)."""
        t = np.atleast_1d(_as_f(t))
        tc = np.clip(t, 0.0, self.duration)
        R, w, dw, pose = self._kin(tc)
        outside = (t < 0.0) | (t > self.duration)
        if outside.any():
            w = w.copy()
            dw = dw.copy()
            w[outside] = 0.0
            dw[outside] = 0.0
        r = self.lever_m
        lin = np.cross(dw, r) + np.cross(w, np.cross(w, r))          # m/s^2, body
        up_body = R[:, 2, :]                                          # R.T @ e_z
        f = gravity_g * up_body + lin / STANDARD_G
        label = self._label(tc).astype(np.int32)
        if self.kind == "rotation":
            label = np.where(outside, LABEL_NONE, label).astype(np.int32)
        return Motion(R=R, omega=np.degrees(w), label=label, specific_force=f, pose=pose)

    @property
    def n_poses(self) -> int:
        return len(self.poses)

    def to_json(self) -> dict:
        d = {"format": TRAJECTORY_FORMAT, "type": self.type_name, "kind": self.kind,
             "seed": self.seed, "duration": self.duration, "rate_hz": self.rate_hz,
             "lever_m": self.lever_m.tolist(), "poses": [p.tolist() for p in self.poses]}
        d.update(self._params_json())
        return d

    @staticmethod
    def from_json(d: dict) -> "Trajectory":
        try:
            if d.get("format") != TRAJECTORY_FORMAT:
                raise ValueError(f"format is not {TRAJECTORY_FORMAT!r}")
            cls = {c.type_name: c for c in (PiecewiseTrajectory, EulerTrajectory,
                                            SequenceTrajectory)}[d["type"]]
            return cls._from_json(d)
        except (KeyError, ValueError, TypeError, AttributeError) as e:
            raise UserError(f"invalid trajectory JSON: {e}") from None

    def __repr__(self):
        return (f"<{type(self).__name__} {self.kind} seed={self.seed} "
                f"duration={self.duration:.1f}s poses={self.n_poses}>")


class PiecewiseTrajectory(Trajectory):
    """Holds and minimum-jerk moves.  Segment i starts at ``t0[i]`` in
    orientation ``R0[i]`` and turns by the body rotation vector ``rotvec[i]``
    (zero for a hold) along s(tau) = 10tau^3 - 15tau^4 + 6tau^5, so omega is
    ``ds/dt * rotvec`` about a fixed body axis."""

    type_name = "piecewise"

    def __init__(self, kind, seed, duration, rate_hz, *, t0, R0, rotvec, label,
                 pose0, pose1, lever_m=DEFAULT_LEVER_M, poses=()):
        super().__init__(kind, seed, duration, rate_hz, lever_m, poses)
        self.t0 = _as_f(t0)
        self.R0 = _as_f(R0).reshape(-1, 3, 3)
        self.rotvec = _as_f(rotvec).reshape(-1, 3)
        self.seg_label = np.asarray(label, np.int32)
        self.pose0 = _as_f(pose0)
        self.pose1 = _as_f(pose1)
        m = len(self.t0)
        if not (m and len(self.R0) == m and len(self.rotvec) == m and len(self.seg_label) == m
                and len(self.pose0) == m and len(self.pose1) == m):
            raise ValueError("segment arrays must be non-empty and of equal length")
        if np.any(np.diff(self.t0) <= 0) or self.t0[0] != 0.0:
            raise ValueError("segment start times must start at 0 and increase")
        self.t1 = np.append(self.t0[1:], max(self.duration, self.t0[-1]))

    def _seg(self, t):
        i = np.clip(np.searchsorted(self.t0, t, side="right") - 1, 0, len(self.t0) - 1)
        T = self.t1[i] - self.t0[i]
        Tsafe = np.where(T > 0, T, 1.0)
        tau = np.where(T > 0, (t - self.t0[i]) / Tsafe, 0.0)
        return i, Tsafe, tau

    def _label(self, t):
        i, _, _ = self._seg(t)
        return self.seg_label[i]

    def _kin(self, t):
        i, T, tau = self._seg(t)
        s, ds, dds = _min_jerk(tau)
        v = self.rotvec[i]
        R = self.R0[i] @ _rodrigues(s[:, None] * v)
        w = (ds / T)[:, None] * v
        dw = (dds / (T * T))[:, None] * v
        pose = self.pose0[i] + s * (self.pose1[i] - self.pose0[i])
        return R, w, dw, pose

    def _params_json(self):
        return {"t0": self.t0.tolist(), "R0": self.R0.tolist(), "rotvec": self.rotvec.tolist(),
                "label": self.seg_label.tolist(), "pose0": self.pose0.tolist(),
                "pose1": self.pose1.tolist()}

    @classmethod
    def _from_json(cls, d):
        return cls(d["kind"], d["seed"], d["duration"], d["rate_hz"], t0=d["t0"], R0=d["R0"],
                   rotvec=d["rotvec"], label=d["label"], pose0=d["pose0"], pose1=d["pose1"],
                   lever_m=d["lever_m"], poses=d["poses"])


class EulerTrajectory(Trajectory):
    """R = Rz(yaw) Ry(pitch) Rx(roll), each angle (rad) =
    offset + rate*t + sum_k amp_k sin(2 pi freq_k t + phase_k)."""

    type_name = "euler"

    def __init__(self, kind, seed, duration, rate_hz, *, offset, rate, amp, freq, phase,
                 label=LABEL_NONE, lever_m=DEFAULT_LEVER_M, poses=()):
        super().__init__(kind, seed, duration, rate_hz, lever_m, poses)
        self.offset = _as_f(offset).reshape(3)
        self.rate = _as_f(rate).reshape(3)
        self.amp = _as_f(amp).reshape(3, -1)
        self.freq = _as_f(freq).reshape(3, -1)
        self.phase = _as_f(phase).reshape(3, -1)
        if not (self.amp.shape == self.freq.shape == self.phase.shape):
            raise ValueError("amp, freq and phase must have the same shape")
        self.const_label = int(label)

    def _angles(self, t):
        """(3, n) angle, rate and acceleration of yaw, pitch, roll."""
        w = 2 * np.pi * self.freq[:, :, None]                      # (3, k, 1)
        arg = w * t[None, None, :] + self.phase[:, :, None]
        a = self.amp[:, :, None]
        ang = self.offset[:, None] + self.rate[:, None] * t + (a * np.sin(arg)).sum(1)
        d1 = self.rate[:, None] + (a * w * np.cos(arg)).sum(1)
        d2 = -(a * w * w * np.sin(arg)).sum(1)
        return ang, d1, d2

    def _label(self, t):
        return np.full(len(t), self.const_label, np.int32)

    def _kin(self, t):
        (al, be, ga), (da, db, dg), (dda, ddb, ddg) = self._angles(t)
        R = _zyx_matrix(al, be, ga)
        sb, cb, sg, cg = np.sin(be), np.cos(be), np.sin(ga), np.cos(ga)
        p = dg - da * sb
        q = db * cg + da * cb * sg
        r = -db * sg + da * cb * cg
        dp = ddg - dda * sb - da * db * cb
        dq = (ddb * cg - db * dg * sg + dda * cb * sg - da * db * sb * sg
              + da * dg * cb * cg)
        dr = (-ddb * sg - db * dg * cg + dda * cb * cg - da * db * sb * cg
              - da * dg * cb * sg)
        return (R, np.column_stack([p, q, r]), np.column_stack([dp, dq, dr]),
                np.zeros(len(t)))

    def _params_json(self):
        return {"offset": self.offset.tolist(), "rate": self.rate.tolist(),
                "amp": self.amp.tolist(), "freq": self.freq.tolist(),
                "phase": self.phase.tolist(), "label": self.const_label}

    @classmethod
    def _from_json(cls, d):
        return cls(d["kind"], d["seed"], d["duration"], d["rate_hz"], offset=d["offset"],
                   rate=d["rate"], amp=d["amp"], freq=d["freq"], phase=d["phase"],
                   label=d["label"], lever_m=d["lever_m"], poses=d["poses"])


class SequenceTrajectory(Trajectory):
    """Parts (trajectories of their own) one after the other on the same rig;
    ``duration`` None = their natural length plus the moves.

    Part i runs from ``start[i]`` for its own duration; between part i and
    i + 1 the rig turns from the last orientation of i to the first of i + 1
    along a minimum-jerk move of ``move_duration`` (label 0).  Pose labels and
    the pose coordinate of part i are shifted by the poses of the parts before
    it, so labels stay unique.  A rotation or free part ends while turning:
    the move after it starts from rest (a step in omega, as a hand stopping).
    Past the last part the rig holds still.
    """

    type_name = "sequence"

    def __init__(self, kind, seed, duration, rate_hz, *, parts, lever_m=DEFAULT_LEVER_M,
                 poses=None):
        parts = list(parts)
        if not parts:
            raise ValueError("a sequence needs at least one part")
        if poses is None:
            poses = [P for part in parts for P in part.poses]
        starts, moves, t = [], [], 0.0
        for i, part in enumerate(parts):
            starts.append(t)
            t += part.duration
            if i + 1 < len(parts):
                R_end = part._kin(np.array([part.duration]))[0][0]
                R_next = parts[i + 1]._kin(np.array([0.0]))[0][0]
                v = Rotation.from_matrix(R_end.T @ R_next).as_rotvec()
                T = move_duration(float(np.linalg.norm(v)))
                moves.append((t, T, R_end, v))
                t += T
        super().__init__(kind, seed, t if duration is None else duration, rate_hz, lever_m,
                         poses)
        self.parts = parts
        self.pose_offset = np.cumsum([0] + [p.n_poses for p in parts[:-1]])
        self.start = np.array(starts)
        self.moves = moves
        # segment table: part i, then move i, ...; kind 0 = part, 1 = move
        bounds, kinds, index = [], [], []
        for i in range(len(parts)):
            bounds.append(self.start[i]); kinds.append(0); index.append(i)
            if i < len(moves):
                bounds.append(moves[i][0]); kinds.append(1); index.append(i)
        self._bounds = np.array(bounds)
        self._seg_kind = np.array(kinds)
        self._seg_index = np.array(index)

    def _segments(self, t):
        j = np.clip(np.searchsorted(self._bounds, t, side="right") - 1, 0, len(self._bounds) - 1)
        return self._seg_kind[j], self._seg_index[j]

    def _pose_coord(self, i, pose):
        pose = np.asarray(pose, float)
        return np.where(pose > 0, pose + self.pose_offset[i], pose)

    def _label(self, t):
        kind, idx = self._segments(t)
        out = np.full(len(t), LABEL_NONE, np.int32)
        for i, part in enumerate(self.parts):
            sel = (kind == 0) & (idx == i)
            if sel.any():
                lab = part._label(np.clip(t[sel] - self.start[i], 0.0, part.duration))
                out[sel] = np.where(lab >= 1, lab + self.pose_offset[i], lab)
        return out

    def _kin(self, t):
        n = len(t)
        R = np.empty((n, 3, 3))
        w = np.zeros((n, 3))
        dw = np.zeros((n, 3))
        pose = np.zeros(n)
        kind, idx = self._segments(t)
        last = len(self.parts) - 1
        for i, part in enumerate(self.parts):
            sel = np.flatnonzero((kind == 0) & (idx == i))
            if not len(sel):
                continue
            local = t[sel] - self.start[i]
            Ri, wi, dwi, pi = part._kin(np.clip(local, 0.0, part.duration))
            R[sel], w[sel], dw[sel], pose[sel] = Ri, wi, dwi, self._pose_coord(i, pi)
            if i == last:                     # holding still after the last part
                after = local > part.duration
                w[sel[after]] = 0.0
                dw[sel[after]] = 0.0
        for i, (t0, T, R_end, v) in enumerate(self.moves):
            sel = np.flatnonzero((kind == 1) & (idx == i))
            if not len(sel):
                continue
            s, ds, dds = _min_jerk((t[sel] - t0) / T)
            R[sel] = R_end @ _rodrigues(s[:, None] * v)
            w[sel] = (ds / T)[:, None] * v
            dw[sel] = (dds / (T * T))[:, None] * v
            a = self._pose_coord(i, self.parts[i]._kin(np.array([self.parts[i].duration]))[3])[0]
            b = self._pose_coord(i + 1, self.parts[i + 1]._kin(np.array([0.0]))[3])[0]
            if a > 0 and b > 0:
                pose[sel] = a + s * (b - a)
            else:
                pose[sel] = np.where(s < 0.5, a, b)
        return R, w, dw, pose

    def at(self, t, gravity_g: float = 1.0) -> Motion:
        m = super().at(t, gravity_g)
        if self.parts[-1].kind == "rotation":     # not rotating once the rotation is over
            t = np.atleast_1d(_as_f(t))
            end = self.start[-1] + self.parts[-1].duration
            m.label[t > end] = LABEL_NONE
        return m

    def _params_json(self):
        return {"parts": [p.to_json() for p in self.parts]}

    @classmethod
    def _from_json(cls, d):
        parts = [Trajectory.from_json(p) for p in d["parts"]]
        return cls(d["kind"], d["seed"], d["duration"], d["rate_hz"], parts=parts,
                   lever_m=d["lever_m"], poses=d["poses"])


# --------------------------------------------------------------------------
# factory
# --------------------------------------------------------------------------
def session_kinds(session: str) -> list[str]:
    """The kinds of a session: ``"static80"`` or a sequence ``"static80,idle"``."""
    kinds = [k.strip() for k in str(session).split(",")]
    for k in kinds:
        if k not in KINDS:
            raise UserError(f"unknown trajectory kind {k!r} (expected one of "
                            f"{', '.join(KINDS)}, or several separated by commas)")
    return kinds


def _rng(kind: str, seed: int) -> np.random.Generator:
    return np.random.default_rng([_SALT, KINDS.index(kind), int(seed) & (2**64 - 1)])


def move_duration(angle_rad: float) -> float:
    """Seconds a person takes for a move of that angle: 1.0 s to 1.5 s (180 deg)."""
    return 1.0 + 0.5 * min(abs(angle_rad), np.pi) / np.pi


def _static_poses(rng, n_poses):
    ups = fibonacci_sphere(n_poses) @ Rotation.random(random_state=rng).as_matrix().T
    # nearest-neighbour tour starting with the pose closest to "flat" (body z up)
    order = [int(np.argmax(ups[:, 2]))]
    left = set(range(n_poses)) - set(order)
    while left:
        cand = np.array(sorted(left))
        nxt = int(cand[np.argmax(ups[cand] @ ups[order[-1]])])
        order.append(nxt)
        left.remove(nxt)
    yaws = rng.uniform(-np.pi, np.pi, n_poses)
    return [up_to_rotation(ups[k], yaws[j]) for j, k in enumerate(order)]


def _piecewise_from_poses(kind, seed, rate_hz, poses, still_s, lever_m, duration):
    t0, R0, rotvec, label, pose0, pose1 = [], [], [], [], [], []
    t = 0.0
    for k, P in enumerate(poses, start=1):
        t0.append(t); R0.append(P); rotvec.append(np.zeros(3)); label.append(k)
        pose0.append(k); pose1.append(k)
        t += still_s
        if k < len(poses):
            v = Rotation.from_matrix(P.T @ poses[k]).as_rotvec()
            t0.append(t); R0.append(P); rotvec.append(v); label.append(LABEL_NONE)
            pose0.append(k); pose1.append(k + 1)
            t += move_duration(np.linalg.norm(v))
    natural = t
    return PiecewiseTrajectory(kind, seed, natural if duration is None else duration, rate_hz,
                               t0=t0, R0=R0, rotvec=rotvec, label=label, pose0=pose0,
                               pose1=pose1, lever_m=lever_m, poses=poses)


def make_trajectory(kind: str, seed: int, *, duration: float | None = None, n_poses: int = 80,
                    still_s: float = 2.5, rate_hz: float = 125.0,
                    lever_m=DEFAULT_LEVER_M) -> Trajectory:
    """The rig's trajectory for a session of that kind (deterministic in seed).

    ``duration`` (s) sets the length of idle/free/rotation and truncates (or,
    if longer, extends with a final hold) static80.
    """
    kinds = session_kinds(kind)
    if duration is not None and not duration > 0:
        raise UserError(f"duration must be > 0 s, not {duration}")
    if n_poses < 1 or still_s <= 0:
        raise UserError("n_poses must be >= 1 and still_s > 0")
    if len(kinds) > 1:
        parts = [make_trajectory(k, int(seed) + i, n_poses=n_poses, still_s=still_s,
                                 rate_hz=rate_hz, lever_m=lever_m)
                 for i, k in enumerate(kinds)]
        return SequenceTrajectory(kind, seed, duration, rate_hz, parts=parts, lever_m=lever_m)
    rng = _rng(kind, seed)
    if kind == "static80":
        poses = _static_poses(rng, int(n_poses))
        return _piecewise_from_poses(kind, seed, rate_hz, poses, float(still_s), lever_m,
                                     duration)
    if kind == "idle":
        pose = up_to_rotation([0.0, 0.0, 1.0], rng.uniform(-np.pi, np.pi))
        return _piecewise_from_poses(kind, seed, rate_hz, [pose], 60.0 if duration is None
                                     else float(duration), lever_m, duration)
    if kind == "rotation":
        dur = 5000.0 / rate_hz if duration is None else float(duration)
        # yaw: slow turn; pitch: pole-to-pole sweep (period 20 s); roll: fast spin
        sign = rng.choice([-1.0, 1.0], 3)
        offset = rng.uniform(-np.pi, np.pi, 3)
        offset[1] = 0.0
        rate = sign * np.array([2 * np.pi / 13.0, 0.0, 2 * np.pi / 1.9])
        k = 3
        amp = np.zeros((3, k + 1))
        freq = np.zeros((3, k + 1))
        phase = rng.uniform(0, 2 * np.pi, (3, k + 1))
        amp[1, 0] = np.radians(86.0)
        freq[1, 0] = 1.0 / 20.0
        amp[:, 1:] = np.radians(rng.uniform(3.0, 8.0, (3, k)))      # hand wobble
        freq[:, 1:] = rng.uniform(0.1, 0.6, (3, k))
        return EulerTrajectory(kind, seed, dur, rate_hz, offset=offset, rate=rate, amp=amp,
                               freq=freq, phase=phase, label=LABEL_ROT, lever_m=lever_m)
    # free
    dur = 60.0 if duration is None else float(duration)
    k = 4
    amp = np.radians(rng.uniform(10.0, 40.0, (3, k)))
    amp[1] *= 0.6
    freq = rng.uniform(0.03, 0.5, (3, k))
    phase = rng.uniform(0, 2 * np.pi, (3, k))
    offset = rng.uniform(-np.pi, np.pi, 3) * np.array([1.0, 0.2, 0.3])
    return EulerTrajectory(kind, seed, dur, rate_hz, offset=offset, rate=np.zeros(3), amp=amp,
                           freq=freq, phase=phase, label=LABEL_NONE, lever_m=lever_m)
