"""Error-model families for magnitude calibration, with analytic Jacobians.

Every model maps a sensor reading ``u`` in *nominal units* (counts divided by
the datasheet LSB-per-unit, so g for the accelerometer and gauss for the
magnetometer) to a calibrated vector ``v = A u + c`` and predicts the length
``H`` of that vector: 1 g for the accelerometer, the unknown local field for
the magnetometer.  The fitness is the paper's mean squared magnitude error
``mean((|v| - H)^2)``.

Families
--------
``paper`` -- the seed paper's eqs. 1-5::

    X = (X' + o_x) s_x
    Y = (Y' cos(a_zy) + o_y) s_y
    Z = (Z' cos(a_xz) cos(a_yz) + o_z) s_z

so ``A = diag(s_x, s_y cos a_zy, s_z cos a_xz cos a_yz)`` and
``c = (s_x o_x, s_y o_y, s_z o_z)``.  The angles only multiply scales: they
are an exact re-parametrisation of offset and scale (Jacobian rank 6 of 9)
and cannot represent misalignment.  Any subset of the groups ``offsets``,
``scales``, ``angles`` may be free; the others stay at 0, 1, 0.

``full`` -- bias plus a lower-triangular matrix::

    v = L (u + o),  L = [[s_x, 0, 0], [k_yx, s_y, 0], [k_zx, k_zy, s_z]]

Nine parameters, which is all a magnitude-only fitness can identify: any
matrix is a rotation times a lower-triangular one, and rotations do not
change magnitudes.  The gauge puts the calibrated x axis along the sensor's
x axis and the calibrated y axis in the sensor's x-y plane.

Magnetometer gauge
------------------
With every scale and the field magnitude ``H`` free, the fitness has no
minimum (scale all by k: fitness by k^2).  Two explicit gauges:

* ``"det"`` (default): the geometric-mean scale is the datasheet gain,
  ``det(A) = 1`` in nominal units (``s_z`` is derived from the other
  diagonal terms), so ``H`` is the field in gauss as far as the datasheet
  gain is right;
* ``"field"``: the user gives the local field in gauss; ``H`` is fixed and
  all three scales are free.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ..maths.sphere import unit

PARAM_GROUPS = ("offsets", "scales", "angles")
MODEL_FAMILIES = ("paper", "full")
GAUGES = ("det", "field")

# A-priori ranges (in nominal units): the GA's priors, documented in the README.
PRIOR_OFFSET = {"accel": 0.3, "mag": 1.5}          # +- g, +- gauss
PRIOR_SCALE = (0.7, 1.3)
PRIOR_ANGLE = 0.3                                  # +- rad
PRIOR_CROSS = 0.2
PRIOR_FIELD = (0.1, 1.5)                           # gauss


@dataclass(frozen=True)
class ParamInfo:
    name: str
    default: float
    lo: float
    hi: float
    unit: str
    group: str


class MagnitudeModel:
    """One model family with its free parameters.

    ``theta`` always means the vector of *free* parameters (length ``d``);
    arrays may carry leading population dimensions: ``theta`` of shape
    ``(..., d)`` gives ``A`` of shape ``(..., 3, 3)``, ``c`` ``(..., 3)`` and
    ``H`` ``(...)``.
    """

    family: str = ""

    def __init__(self, sensor: str, groups: tuple[str, ...], gauge: str | None,
                 field: float | None):
        if sensor not in ("accel", "mag"):
            raise ValueError(f"magnitude models are for accel and mag, not {sensor}")
        self.sensor = sensor
        self.groups = tuple(g for g in PARAM_GROUPS + ("cross",) if g in groups)
        self.unit = "g" if sensor == "accel" else "gauss"
        if sensor == "accel":
            self.gauge = None
            self.field = 1.0
        else:
            gauge = default_gauge(gauge, field)
            if gauge not in GAUGES:
                raise UserError(f"unknown magnetometer gauge {gauge!r} (det or field)")
            if gauge == "field" and not (field is not None and np.isfinite(field) and field > 0):
                raise UserError("the 'field' gauge needs a known field magnitude in gauss (> 0)")
            self.gauge = gauge
            self.field = float(field) if gauge == "field" else None
        self.params: list[ParamInfo] = self._params()
        self.names = [p.name for p in self.params]
        self.lo = np.array([p.lo for p in self.params])
        self.hi = np.array([p.hi for p in self.params])
        self.default = np.array([p.default for p in self.params])

    # -- description ----------------------------------------------------------
    @property
    def d(self) -> int:
        return len(self.params)

    @property
    def derived_scale(self) -> bool:
        """s_z follows from the det gauge instead of being free."""
        return self.sensor == "mag" and self.gauge == "det" and "scales" in self.groups

    @property
    def redundant(self) -> bool:
        """Some parameters only re-parametrise others by construction (the
        paper's angles multiply scales or each other): the Jacobian is
        rank-deficient everywhere (see ``fit.polish``)."""
        return "angles" in self.groups

    @property
    def free_field(self) -> bool:
        return self.sensor == "mag" and self.gauge == "det"

    def _offset_params(self):
        r = PRIOR_OFFSET[self.sensor]
        return [ParamInfo(f"o_{a}", 0.0, -r, r, self.unit, "offsets") for a in "xyz"]

    def _scale_params(self):
        axes = "xy" if self.derived_scale else "xyz"
        return [ParamInfo(f"s_{a}", 1.0, *PRIOR_SCALE, "", "scales") for a in axes]

    def _field_params(self):
        if self.free_field:
            return [ParamInfo("B", 0.5, *PRIOR_FIELD, "gauss", "field")]
        return []

    def _params(self) -> list[ParamInfo]:
        raise NotImplementedError

    def prior_box(self, u=None):
        """The GA's a-priori ranges ``(lo, hi)``.  For the magnetometer the
        hard-iron offsets and the field are centred on the data: the offset
        range is the negated mid-range of the readings (0.5th-99.5th
        percentile) +- half their mean half-range, the field 0.6-1.5 times
        that half-range (a sphere much larger than the data has spurious
        minima that fit only one side of it)."""
        lo, hi = self.lo.copy(), self.hi.copy()
        if self.sensor != "mag" or u is None or len(u) < 4:
            return lo, hi
        p_lo, p_hi = np.percentile(u, [0.5, 99.5], axis=0)
        mid = 0.5 * (p_lo + p_hi)
        r = float(np.mean(0.5 * (p_hi - p_lo)))
        if not r > 0:
            return lo, hi
        for i, p in enumerate(self.params):
            if p.group == "offsets":
                k = "xyz".index(p.name[-1])
                lo[i] = -mid[k] - max(0.5 * r, 0.02)
                hi[i] = -mid[k] + max(0.5 * r, 0.02)
            elif p.group == "field":
                lo[i], hi[i] = 0.6 * r, 1.5 * r
        return lo, hi

    # -- evaluation -------------------------------------------------------------
    def affine(self, theta):
        """(A, c, H) for theta of shape (..., d)."""
        raise NotImplementedError

    def affine_jacobian(self, theta):
        """d(A, c, H)/d theta at one theta: (13, d) with rows A (row-major), c, H."""
        raise NotImplementedError

    def full_from_affine(self, A, c):
        """Parameters of this model (all groups free) from an affine map; used to
        express a known truth in this model's gauge.  Only for models whose free
        groups can represent the map."""
        raise NotImplementedError

    def identifiability(self, theta, u):
        """``identify.analyse`` of the Jacobian at theta on samples u, each
        parameter at the scale of its a-priori range, residuals in units of
        the target magnitude."""
        from .identify import analyse
        _, _, H = self.affine(np.asarray(theta, float))
        return analyse(self.jacobian(theta, u), self.names, scale=0.5 * (self.hi - self.lo),
                       unit=float(H))

    # -- residuals --------------------------------------------------------------
    def residuals(self, theta, u):
        """|A u + c| - H for samples u (n, 3): shape (n,)."""
        A, c, H = self.affine(np.asarray(theta, float))
        v = u @ A.T + c
        return np.sqrt(np.einsum("ij,ij->i", v, v)) - H

    def jacobian(self, theta, u):
        """Analytic Jacobian of residuals(theta, u): shape (n, d)."""
        A, c, H = self.affine(np.asarray(theta, float))
        v = u @ A.T + c
        nv = unit(v)
        M = self.affine_jacobian(theta)                   # (13, d)
        # dr/dA_ij = n_i u_j ; dr/dc_i = n_i ; dr/dH = -1
        G = (nv[:, :, None] * u[:, None, :]).reshape(len(u), 9)
        return G @ M[:9] + nv @ M[9:12] - M[12]

    def population_mse(self, pop, u, w=None):
        """Weighted mean squared residual for each row of pop (P, d) on points u (m, 3)."""
        A, c, H = self.affine(pop)
        P = len(A)
        v = (A.reshape(P * 3, 3) @ u.T).reshape(P, 3, -1)   # one matrix product
        v += c[:, :, None]
        r = np.sqrt(np.einsum("pim,pim->pm", v, v)) - np.asarray(H)[:, None]
        r2 = r * r
        if w is None:
            return r2.mean(axis=1)
        return r2 @ w / w.sum()


class PaperModel(MagnitudeModel):
    """The seed paper's eqs. 1-5 (angles multiply scales)."""

    family = "paper"

    def _params(self):
        if not self.groups:
            raise UserError("--params needs at least one of offsets, scales, angles")
        if self.derived_scale is False and self.sensor == "mag" and self.gauge == "det" \
                and "angles" in self.groups:
            raise UserError("magnetometer angles need scales too (angles alone would shrink "
                            "the calibrated field without bound under the det gauge)")
        ps = []
        if "offsets" in self.groups:
            ps += self._offset_params()
        if "scales" in self.groups:
            ps += self._scale_params()
        if "angles" in self.groups:
            ps += [ParamInfo(n, 0.0, -PRIOR_ANGLE, PRIOR_ANGLE, "rad", "angles")
                   for n in ("a_zy", "a_xz", "a_yz")]
        return ps + self._field_params()

    def _split(self, theta):
        theta = np.asarray(theta, float)
        shp = theta.shape[:-1]
        i = 0
        if "offsets" in self.groups:
            o = theta[..., 0:3]
            i = 3
        else:
            o = np.zeros(shp + (3,))
        if "scales" in self.groups:
            if self.derived_scale:
                s = theta[..., i:i + 2]
                i += 2
            else:
                s = theta[..., i:i + 3]
                i += 3
        else:
            s = np.ones(shp + (3,))
        if "angles" in self.groups:
            a = theta[..., i:i + 3]
            i += 3
        else:
            a = np.zeros(shp + (3,))
        H = theta[..., i] if self.free_field else np.full(shp, self.field)
        return o, s, a, H

    def _diag(self, s, a):
        cy = np.cos(a[..., 0])
        cz = np.cos(a[..., 1]) * np.cos(a[..., 2])
        if self.derived_scale:
            sx, sy = s[..., 0], s[..., 1]
            sz = 1.0 / (sx * sy * cy * cz)
        else:
            sx, sy, sz = s[..., 0], s[..., 1], s[..., 2]
        return sx, sy, sz, cy, cz

    def affine(self, theta):
        o, s, a, H = self._split(theta)
        sx, sy, sz, cy, cz = self._diag(s, a)
        shp = o.shape[:-1]
        A = np.zeros(shp + (3, 3))
        A[..., 0, 0] = sx
        A[..., 1, 1] = sy * cy
        A[..., 2, 2] = sz * cz
        c = np.stack([sx * o[..., 0], sy * o[..., 1], sz * o[..., 2]], axis=-1)
        return A, c, H

    def affine_jacobian(self, theta):
        theta = np.asarray(theta, float)
        o, s, a, H = self._split(theta)
        sx, sy, sz, cy, cz = self._diag(s, a)
        M = np.zeros((13, self.d))
        i = 0
        if "offsets" in self.groups:
            M[9, 0], M[10, 1], M[11, 2] = sx, sy, sz
            i = 3
        # sz as a function of the free parameters (derived under the det gauge)
        dsz = np.zeros(self.d)
        if "scales" in self.groups:
            if self.derived_scale:
                jx, jy = i, i + 1
                M[0, jx] = 1.0
                M[4, jy] = cy
                M[9, jx] = o[0]
                M[10, jy] = o[1]
                dsz[jx] = -sz / sx
                dsz[jy] = -sz / sy
                i += 2
            else:
                M[0, i] = 1.0
                M[4, i + 1] = cy
                M[9, i] = o[0]
                M[10, i + 1] = o[1]
                dsz[i + 2] = 1.0
                i += 3
        if "angles" in self.groups:
            azy, axz, ayz = a
            M[4, i] = -sy * np.sin(azy)
            dcz_dxz = -np.sin(axz) * np.cos(ayz)
            dcz_dyz = -np.cos(axz) * np.sin(ayz)
            if self.derived_scale:
                # sz = 1/(sx sy cy cz)
                dsz[i] = -sz * (-np.tan(azy))
                dsz[i + 1] = -sz * (dcz_dxz / cz)
                dsz[i + 2] = -sz * (dcz_dyz / cz)
            M[8, i + 1] += sz * dcz_dxz
            M[8, i + 2] += sz * dcz_dyz
            i += 3
        # A_zz = sz cz, c_z = sz o_z
        M[8] += dsz * cz
        M[11] += dsz * o[2]
        if self.free_field:
            M[12, i] = 1.0
        return M

    def full_from_affine(self, A, c):
        """Offsets and scales of a diagonal map (angles 0)."""
        diag = np.diag(A).copy()
        o = c / diag
        return o, diag


class FullModel(MagnitudeModel):
    """Bias + lower-triangular matrix (identifiable)."""

    family = "full"

    def _params(self):
        ps = self._offset_params() + self._scale_params()
        ps += [ParamInfo(n, 0.0, -PRIOR_CROSS, PRIOR_CROSS, "", "cross")
               for n in ("k_yx", "k_zx", "k_zy")]
        return ps + self._field_params()

    def _split(self, theta):
        theta = np.asarray(theta, float)
        o = theta[..., 0:3]
        if self.derived_scale:
            sx, sy = theta[..., 3], theta[..., 4]
            k = theta[..., 5:8]
            i = 8
        else:
            sx, sy = theta[..., 3], theta[..., 4]
            k = theta[..., 6:9]
            i = 9
        shp = theta.shape[:-1]
        if self.derived_scale:
            sz = 1.0 / (sx * sy)
        else:
            sz = theta[..., 5]
        H = theta[..., i] if self.free_field else np.full(shp, self.field)
        return o, sx, sy, sz, k, H

    def affine(self, theta):
        o, sx, sy, sz, k, H = self._split(theta)
        shp = o.shape[:-1]
        L = np.zeros(shp + (3, 3))
        L[..., 0, 0] = sx
        L[..., 1, 1] = sy
        L[..., 2, 2] = sz
        L[..., 1, 0] = k[..., 0]
        L[..., 2, 0] = k[..., 1]
        L[..., 2, 1] = k[..., 2]
        c = np.einsum("...ij,...j->...i", L, o)
        return L, c, H

    def affine_jacobian(self, theta):
        theta = np.asarray(theta, float)
        o, sx, sy, sz, k, H = self._split(theta)
        L, _, _ = self.affine(theta)
        M = np.zeros((13, self.d))
        # c = L o
        M[9:12, 0:3] = L
        pos = {(0, 0): 3, (1, 1): 4}
        if self.derived_scale:
            pos.update({(1, 0): 5, (2, 0): 6, (2, 1): 7})
            dsz = np.zeros(self.d)
            dsz[3] = -sz / sx
            dsz[4] = -sz / sy
            M[8] += dsz
            M[11] += dsz * o[2]
        else:
            pos.update({(2, 2): 5, (1, 0): 6, (2, 0): 7, (2, 1): 8})
        for (i, j), p in pos.items():
            M[3 * i + j, p] = 1.0
            M[9 + i, p] += o[j]
        if self.free_field:
            M[12, self.d - 1] = 1.0
        return M

    def full_from_affine(self, A, c):
        """Lower-triangular factor L (A = Q L, Q a rotation) and o = A^-1 c."""
        L = lower_factor(A)
        o = np.linalg.solve(A, c)
        return o, L


def lower_factor(A):
    """L lower-triangular with positive diagonal and L^T L = A^T A (A = Q L)."""
    A = np.asarray(A, float)
    P = np.eye(3)[::-1]
    U = np.linalg.cholesky(P @ A.T @ A @ P).T     # upper, U^T U = P M P
    return P @ U @ P


def theta_from_affine(model: MagnitudeModel, A, c, field=None):
    """Free-parameter vector of ``model`` representing the map (A, c) in
    nominal units (and field B for a det-gauge magnetometer).  For the paper
    model A must be diagonal up to the non-identifiable angles (taken as 0)."""
    A = np.asarray(A, float)
    c = np.asarray(c, float)
    theta = []
    if model.family == "full":
        o, L = model.full_from_affine(A, c)
        theta += list(o)
        if model.derived_scale:
            theta += [L[0, 0], L[1, 1]]
        else:
            theta += [L[0, 0], L[1, 1], L[2, 2]]
        theta += [L[1, 0], L[2, 0], L[2, 1]]
    else:
        o, s = model.full_from_affine(A, c)
        if "offsets" in model.groups:
            theta += list(o)
        if "scales" in model.groups:
            theta += list(s[:2]) if model.derived_scale else list(s)
        if "angles" in model.groups:
            theta += [0.0, 0.0, 0.0]
    if model.free_field:
        theta.append(1.0 if field is None else field)
    return np.array(theta)


def default_gauge(gauge: str | None, field: float | None) -> str:
    """The magnetometer gauge when none is given: "field" with a known field
    magnitude, else "det" (det(A) = 1)."""
    if gauge is not None:
        return gauge
    return "field" if field is not None else "det"


def paper_groups(groups) -> tuple:
    """The paper model's parameter groups: ``groups``, or all of
    ``PARAM_GROUPS`` when None."""
    return tuple(PARAM_GROUPS) if groups is None else tuple(groups)


def mag_groups(groups, gauge: str | None = None, field: float | None = None):
    """The paper-model groups the magnetometer is fitted with when ``--params``
    asks for ``groups`` (they select the accelerometer's subset, as in the
    paper's Table I): ``(groups, note)``.  Under the det(A) = 1 gauge the
    angles need the scales (s_z follows from det(A) = 1; angles alone would
    shrink the field without bound), so the nearest fittable family adds the
    scales -- with the same angles, which only re-parametrise them -- and
    ``note`` says so; with a known field (the field gauge) the groups are
    fitted as asked and ``note`` is None."""
    groups = paper_groups(groups)
    if default_gauge(gauge, field) != "det" or "angles" not in groups or "scales" in groups:
        return groups, None
    fitted = tuple(g for g in PARAM_GROUPS if g in groups or g == "scales")
    return fitted, (f"--params {','.join(groups)}: the magnetometer is fitted with "
                    f"{'+'.join(fitted)}: under the det(A) = 1 gauge its angles need the "
                    f"scales (alone they would shrink the field without bound); "
                    f"--mag-field GAUSS fits {'+'.join(groups)} as asked")


def make_model(sensor: str, family: str = "full", groups=None, gauge: str | None = None,
               field: float | None = None) -> MagnitudeModel:
    """A model of ``family`` for ``sensor``; ``groups`` (paper only) is any
    subset of offsets, scales, angles (default offsets+scales+angles for paper)."""
    if family not in MODEL_FAMILIES:
        raise UserError(f"unknown model {family!r}: choose paper or full")
    if family == "full":
        if groups is not None and set(groups) - {"offsets", "scales", "cross"}:
            raise UserError("--params selects parameter groups of the paper model only")
        return FullModel(sensor, ("offsets", "scales", "cross"), gauge, field)
    groups = paper_groups(groups)
    bad = set(groups) - set(PARAM_GROUPS)
    if bad:
        raise UserError(f"unknown parameter group(s) {', '.join(sorted(bad))}: "
                        f"choose from {', '.join(PARAM_GROUPS)}")
    return PaperModel(sensor, groups, gauge, field)


def parse_groups(text: str | None):
    """'offsets,scales' -> ('offsets', 'scales'); None -> None."""
    if text is None:
        return None
    parts = tuple(p.strip() for p in text.split(",") if p.strip())
    bad = set(parts) - set(PARAM_GROUPS)
    if bad or not parts:
        raise UserError(f"--params: expected a comma-separated subset of "
                        f"{','.join(PARAM_GROUPS)}, got {text!r}")
    return parts
