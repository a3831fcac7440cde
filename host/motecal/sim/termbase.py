"""What every simulator term is built from: its parameters (``Param``), the
context it sees for a block of samples (``Ctx``), the ``Term`` base class,
and the counter-based random streams terms draw from (``NormalStream``,
``SineProcess``), keyed by ``seed_key`` so that a sampler gives the same
samples however the times are split into blocks.

The terms themselves live in ``physics`` (the sensors' static and motion
terms), ``thermal`` (the board's temperature, each chip's own, and what it
does to the sensors) and ``field`` (the local magnetic field); ``physics``
collects them in ``TERMS``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sessions.session import ADXL345_LSB_PER_G, HMC5883L_LSB_PER_GAUSS, ITG3200_LSB_PER_DPS
from .trajectory import Motion, Trajectory

SENSORS = ("accel", "gyro", "mag")
K_NOMINAL = {"accel": ADXL345_LSB_PER_G, "gyro": ITG3200_LSB_PER_DPS,
             "mag": HMC5883L_LSB_PER_GAUSS}
DEFAULT_TEMP_C = 25.0     # a board without a ``thermal`` term sits at this temperature


# --------------------------------------------------------------------------
# random streams
# --------------------------------------------------------------------------
def seed_key(*parts: int) -> list[int]:
    return [int(p) & (2**64 - 1) for p in parts]


class NormalStream:
    """Standard normals addressed by a non-negative integer index (counter
    based: chunk c of the stream comes from SeedSequence(key + [c])), so a
    value depends only on (key, index), never on how reads are split."""

    CHUNK = 8192

    def __init__(self, key: list[int], dim: int):
        self.key = list(key)
        self.dim = dim
        self._cache: dict[int, np.ndarray] = {}

    def _chunk(self, c: int) -> np.ndarray:
        blk = self._cache.get(c)
        if blk is None:
            if len(self._cache) >= 4:
                self._cache.pop(next(iter(self._cache)))
            rng = np.random.default_rng(np.random.SeedSequence(self.key + [int(c)]))
            blk = self._cache[c] = rng.standard_normal((self.CHUNK, self.dim))
        return blk

    def get(self, idx) -> np.ndarray:
        idx = np.asarray(idx, np.int64)
        out = np.empty((len(idx), self.dim))
        if not len(idx):
            return out
        if idx.min() < 0:
            raise ValueError("stream index must be >= 0")
        c = idx // self.CHUNK
        for ci in np.unique(c):
            m = c == ci
            out[m] = self._chunk(int(ci))[idx[m] - ci * self.CHUNK]
        return out


class SineProcess:
    """A smooth random process: per axis a sum of ``k`` sinusoids with random
    phases and given frequencies, amplitudes sqrt(2/k)*rms, so its rms over
    time is ``rms``.  A pure function of t (any order, any block split)."""

    def __init__(self, rng: np.random.Generator, rms, freqs: np.ndarray):
        self.freqs = np.asarray(freqs, float)                     # (dim, k)
        dim, k = self.freqs.shape
        self.amp = np.broadcast_to(np.asarray(rms, float), (dim,))[:, None] * np.sqrt(2.0 / k)
        self.phase = rng.uniform(0, 2 * np.pi, (dim, k))

    def __call__(self, t, deriv: bool = False):
        w = 2 * np.pi * self.freqs
        arg = w[None] * t[:, None, None] + self.phase[None]       # (n, dim, k)
        val = np.einsum("ndk,dk->nd", np.sin(arg), self.amp)
        if not deriv:
            return val
        return val, np.einsum("ndk,dk->nd", np.cos(arg), self.amp * w)


# --------------------------------------------------------------------------
# terms
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Param:
    name: str
    shape: tuple            # (), (3,) or (3, 3)
    default: object         # number, "zeros", "identity", None (= null) or REQUIRED
    unit: str
    doc: str
    nullable: bool = False
    positive: bool = False


REQUIRED = object()


@dataclass
class Ctx:
    """What a term sees for one block of samples of one sensor."""
    sensor: str
    K: float
    t: np.ndarray                  # (n,) seconds since session start (sensor's sample time)
    index: np.ndarray              # (n,) noise index (read count, or update index when stale)
    motion: Motion                 # the board's motion at t
    field_world: np.ndarray        # (3,) gauss
    temp_c: np.ndarray | None = None   # (n,) the chip's temperature at t, degrees C
    temp_of: object = None             # t -> the chip's temperature (its history: hysteresis)


class Term:
    """A forward error term.  ``p`` holds its parameters as float arrays."""
    id = ""
    level = "sensor"                       # "sensor" or "board"
    sensors = SENSORS
    params: tuple = ()
    summary = ""

    def __init__(self, p: dict):
        self.p = p
        self.check()

    def check(self):
        pass

    def to_json(self) -> dict:
        d = {"term": self.id}
        for prm in self.params:
            v = self.p[prm.name]
            d[prm.name] = None if v is None else (np.asarray(v).tolist())
        return d

    # -- forward -------------------------------------------------------
    def runtime(self, key: list[int], trajectory: Trajectory, board) -> "Term":
        """Per-sampler instance (stateful terms override)."""
        return self

    def apply(self, x: np.ndarray, ctx: Ctx) -> np.ndarray:
        return x

    # -- truth -----------------------------------------------------------
    def affine(self):
        """(A, c) with x -> A x + c when the term is an affine map of x, else None."""
        return None

    def is_null(self) -> bool:
        """True when the term has no effect with these parameters."""
        return False
