"""The cause ``temperature`` (issue 16): a drift that follows the board
temperature, told apart from a drift that follows time only (``bias_drift``).

Tested when the session carries a temperature (``SessionData.temp``) whose
still blocks span at least ``calib.content.MIN_TEMP_SPAN_C`` (the span
``calibrate`` needs to fit a temperature term: one judgement), on the
sensors whose still data are blocks in few orientations: the gyroscope
(every still block, one zero-rate offset per axis) and the accelerometer and
magnetometer in one or a few orientations (holds; one offset per axis and
orientation); the accelerometer's static poses too (below).  Per axis, block means (2 s) weighted by their noise:

    M0   offsets only
    T    M0 + offset_per_c * (T - t_ref)          3 parameters
    D    M0 + a time basis per axis               linear + 3, 6, 12 or 24 cosines, and a
                                                  settling 1 - exp(-t/tau) (tau on a grid;
                                                  all by BIC)
    TD   both

``temperature`` is named when temperature is needed beyond time (T on top of
D passes its F-test), or when it is enough on its own (T passes against M0
and D adds nothing on top of T) -- and, as for every fitted term, when it
predicts held-out blocks (5 interleaved folds) better than the model without
it, overall and in ``gain.MIN_FOLD_WINS`` folds.  A drift that needs the time
basis beyond temperature stays ``bias_drift``; one that temperature explains
is ``temperature`` only (the engine's ``bias_drift`` finding for that sensor
is replaced, with a note).  When temperature and time are the same curve (a
warm-up whose drift has the very shape of the temperature), the simpler
explanation wins: temperature.

The accelerometer's poses in many orientations (static80) get the same
test through the magnitude (``PoseTempTest``): one residual per pose mean of
the structure's starting fit, an offset change showing as ``u . o``, a small
change of the map as nuisance (9 columns), the time basis per axis as
``u x basis(t)``.  The magnetometer's poses and sweeps are not tested (its
temperature effect is a gain, which a drift of offsets does not describe).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from ..calib.content import MIN_TEMP_SPAN_C
from ..calib.thermal import sym_cols
from ..maths.heldout import fold_sums, interleaved, kfold_heldout
from ..sessions.session import SessionData
from . import gain as G

N_TIME_CHOICES = (4, 7, 13, 25)   # time basis: linear + n-1 cosines per axis, by BIC ...
TAU_CHOICES = (20.0, 40.0, 80.0, 160.0, 320.0, 640.0, 1280.0)   # ... + a settling 1 - exp(-t/tau)
KFOLD = 5


@dataclass
class TempTest:
    """One sensor's temperature test: its blocks and the fitted models."""
    sensor: str
    y: np.ndarray            # (k, 3) block means, counts
    w: np.ndarray            # (k, 3) weights 1/variance
    temp: np.ndarray         # (k,) block temperature, C
    t: np.ndarray            # (k,) block time, s
    seg: np.ndarray          # (k,) offset group (orientation; all 0 for the gyroscope)
    t_ref: float
    K: float                 # counts per unit
    p_T: float = 1.0         # T vs M0
    p_T_D: float = 1.0       # TD vs D (temperature beyond time)
    p_D_T: float = 1.0       # TD vs T (time beyond temperature)
    n_time: int = 4          # functions of the time basis (chosen by BIC)
    tau: float = 0.0         # its settling time constant (0: none)
    named: bool = False
    keep_drift: bool = True
    coef: np.ndarray | None = None     # counts/C per axis
    coef_std: np.ndarray | None = None
    heldout: tuple = (None, None)
    wins: int = 0
    with_time: bool = False  # the models compared for the gain carry the time basis

    @property
    def span(self) -> float:
        return float(np.ptp(self.temp)) if len(self.temp) else 0.0

    # -- design --------------------------------------------------------------
    def columns(self, temperature: bool, time: bool) -> np.ndarray:
        """Per-axis design (k, p): offsets per group, then dT, then time basis."""
        groups = np.unique(self.seg)
        cols = [(self.seg == g).astype(float) for g in groups]
        if temperature:
            cols.append(self.temp - self.t_ref)
        if time:
            span = max(float(np.ptp(self.t)), 1e-9)
            tau = (self.t - self.t.min()) / span
            cols.append(tau - 0.5)
            cols += [np.cos(np.pi * j * tau) for j in range(1, self.n_time)]
            if self.tau > 0:
                cols.append(1.0 - np.exp(-(self.t - self.t.min()) / self.tau))
        return np.column_stack(cols)

    def fit(self, temperature: bool, time: bool, rows=None, fixed=None):
        """Per axis weighted least squares; ``fixed`` (3,) pins the temperature
        coefficient (then it is not a free parameter).  Returns (beta list,
        rss, n params)."""
        X = self.columns(temperature, time)
        rows = np.ones(len(self.y), bool) if rows is None else rows
        betas, rss, npar = [], 0.0, 0
        ng = len(np.unique(self.seg))
        for a in range(3):
            y = self.y[rows, a].copy()
            Xa = X[rows]
            sw = np.sqrt(self.w[rows, a])
            if fixed is not None and temperature:
                y = y - fixed[a] * Xa[:, ng]
                Xa = np.delete(Xa, ng, axis=1)
            beta, *_ = np.linalg.lstsq(Xa * sw[:, None], y * sw, rcond=None)
            r = (y - Xa @ beta) * sw
            rss += float(r @ r)
            npar += Xa.shape[1]
            if fixed is not None and temperature:
                beta = np.insert(beta, ng, fixed[a])
            betas.append(beta)
        return betas, rss, npar

    def predict(self, betas, temperature: bool, time: bool) -> np.ndarray:
        X = self.columns(temperature, time)
        return np.column_stack([X @ b for b in betas])

    def coefficients(self, betas, s2: float, time: bool):
        """(coefficient, std) per axis in counts/C from the fit with temperature."""
        ng = len(np.unique(self.seg))
        X = self.columns(True, time)
        std = []
        for a in range(3):
            Xa = X * np.sqrt(self.w[:, a])[:, None]
            cov = np.linalg.pinv(Xa.T @ Xa) * max(1.0, s2)
            std.append(float(np.sqrt(max(cov[ng, ng], 0.0))))
        return np.array([b[ng] for b in betas]), np.array(std)

    def heldout_rms(self, temperature: bool, time: bool, fixed=None) -> tuple[float, np.ndarray]:
        """rms (counts) of held-out block means over ``KFOLD`` interleaved folds,
        each predicted by the model fitted on the other folds; per-fold rms."""
        fold = interleaved(len(self.y), KFOLD)

        def score(betas, te):
            pred = self.predict(betas, temperature, time)
            return ((self.y[te] - pred[te]) * np.sqrt(self.w[te] / self.w[te].mean(axis=0))) ** 2
        sums = fold_sums(kfold_heldout(
            fold, lambda tr: self.fit(temperature, time, rows=tr, fixed=fixed)[0], score), fold)
        per = [np.sqrt(s / size) for _, s, size in sums]
        return float(np.sqrt(sum(s for _, s, _ in sums) / self.y.size)), np.array(per)

    def truth_heldout_rms(self, coef_counts) -> float:
        """The held-out rms the *true* coefficients (counts/C per axis, e.g.
        from what was planted) leave, the other parameters refitted per fold:
        the truth's side of the gain."""
        return self.heldout_rms(True, self.with_time, fixed=np.asarray(coef_counts, float))[0]


def _ftest(rss0, rss1, q, dof1) -> float:
    if dof1 <= 0 or q <= 0 or rss1 <= 0:
        return 1.0
    F = ((rss0 - rss1) / q) / (rss1 / dof1)
    return float(stats.f.sf(F, q, dof1)) if F > 0 else 1.0


def make_test(data: SessionData, o, regime: str | None) -> TempTest | None:
    """The sensor's blocks with temperatures, or None when it cannot be tested
    (no temperature, a regime with many orientations, too small a span)."""
    if not data.has_temp or o is None or o.blocks is None or len(o.blocks) < 8:
        return None
    if o.sensor == "gyro":
        if regime != "still":
            return None
    elif regime != "single":
        return None
    b = o.blocks
    def mean_temp(r):
        v = data.temp[o.rows[r]] if len(r) else np.empty(0)
        v = v[np.isfinite(v)]
        return float(v.mean()) if len(v) else np.nan
    temp = np.array([mean_temp(r) for r in b.rows])
    ok = np.isfinite(temp)
    if ok.sum() < 8:
        return None
    var = o.var_of_mean(b.n)
    if not np.all(np.isfinite(var)):
        return None
    var = np.maximum(var, 1e-12)
    seg = np.zeros(len(b), int) if o.sensor == "gyro" else np.asarray(b.seg)
    tt = TempTest(o.sensor, b.mean[ok], 1.0 / var[ok], temp[ok], b.t[ok], seg[ok],
                  float(np.mean(temp[ok])), float(o.K))
    if tt.span < MIN_TEMP_SPAN_C:
        return None
    return tt


def run_test(tt: TempTest, level: float) -> TempTest:
    """The nested F-tests and the held-out check (see the module doc)."""
    k3 = tt.y.size
    best = None
    for n in N_TIME_CHOICES:           # the time basis: as flexible as the data ask
        tt.n_time, tt.tau = n, TAU_CHOICES[0]
        if tt.fit(True, True)[2] > k3 / 3:
            break
        for tau in (0.0,) + TAU_CHOICES:
            tt.n_time, tt.tau = n, tau
            _, r, npar = tt.fit(False, True)
            bic = k3 * np.log(max(r, 1e-300) / k3) + (npar + (tau > 0)) * np.log(k3)
            if best is None or bic < best[0]:
                best = (bic, n, tau)
    tt.n_time, tt.tau = (best[1], best[2]) if best else (N_TIME_CHOICES[0], 0.0)
    _, r0, p0 = tt.fit(False, False)
    _, rT, pT = tt.fit(True, False)
    _, rD, pD = tt.fit(False, True)
    bTD, rTD, pTD = tt.fit(True, True)
    tt.p_T = _ftest(r0, rT, pT - p0, k3 - pT)
    tt.p_T_D = _ftest(rD, rTD, pTD - pD, k3 - pTD)
    tt.p_D_T = _ftest(rT, rTD, pTD - pT, k3 - pTD)
    time_needed = tt.p_D_T < level
    significant = tt.p_T_D < level or (tt.p_T < level and not time_needed)
    tt.with_time = time_needed
    betas, rss, npar = tt.fit(True, time_needed)
    tt.coef, tt.coef_std = tt.coefficients(betas, rss / max(1, k3 - npar), time_needed)
    before, per_b = tt.heldout_rms(False, time_needed)
    after, per_a = tt.heldout_rms(True, time_needed)
    tt.heldout = (before, after)
    tt.wins = int(np.sum(per_a < per_b))
    g = before / after if after > 0 else None
    p = tt.p_T_D if tt.p_T_D < level else tt.p_T
    tt.named = significant and G.accepted(p, level, g, True, tt.wins)
    tt.keep_drift = time_needed or not tt.named
    return tt


UNITS = {"accel": "g", "gyro": "deg/s", "mag": "gauss"}


def finding_parts(tt: TempTest) -> tuple[dict, dict, float | None]:
    """(evidence, params, gain) of a ``temperature`` finding."""
    unit = UNITS[tt.sensor]
    before, after = tt.heldout
    ev = {"coef_per_c": (tt.coef / tt.K).tolist(), "coef_std_per_c": (tt.coef_std / tt.K).tolist(),
          "unit": f"{unit}/C", "span_c": tt.span, "t_ref_c": tt.t_ref,
          "range_c": [float(tt.temp.min()), float(tt.temp.max())],
          "p": min(tt.p_T_D, tt.p_T) if tt.p_T_D < tt.p_T else tt.p_T,
          "p_temperature": tt.p_T, "p_temperature_beyond_time": tt.p_T_D,
          "p_time_beyond_temperature": tt.p_D_T, "blocks": int(len(tt.y)),
          "time_drift_too": bool(tt.with_time),
          "heldout_rms_before": before / tt.K if before is not None else None,
          "heldout_rms_after": after / tt.K if after is not None else None,
          "fold_wins": tt.wins,
          "gain_basis": "held-out rms of 2 s still block means (5 interleaved folds), "
                        "without vs with the temperature term"
                        + (" (both with the time basis)" if tt.with_time else "")}
    params = {"offset_per_c": [round(float(v), 6) for v in tt.coef],
              "t_ref_c": round(tt.t_ref, 4)}
    g = before / after if before and after else None
    return ev, params, g


def thermal_term(data: SessionData) -> dict | None:
    """The simulator's board ``thermal`` term that reproduces the session's
    temperature (warm-up from its first value plus a linear room change,
    least squares), for the extended model."""
    if not data.has_temp:
        return None
    from scipy.optimize import least_squares
    t = data.sample_times()
    ok = np.isfinite(data.temp)
    t, T = t[ok] - t[ok].min(), data.temp[ok]
    if len(T) > 4000:
        i = np.linspace(0, len(T) - 1, 4000).astype(int)
        t, T = t[i], T[i]
    span = max(float(t.max()), 1.0)

    def res(p):
        a, r, lt, sl = p
        return a + r * (1 - np.exp(-t / np.exp(lt))) + sl * t / 3600.0 - T

    p0 = [float(T[0]), float(T[-1] - T[0]), np.log(span / 3), 0.0]
    sol = least_squares(res, p0)
    a, r, lt, sl = sol.x
    return {"term": "thermal", "ambient_c": round(float(a), 4), "rise_c": round(float(r), 4),
            "tau_s": round(float(np.exp(lt)), 3), "room_slope_c_per_h": round(float(sl), 4)}


# ---------------------------------------------------------------------------
# static poses in many orientations: the drift seen through the magnitude
# ---------------------------------------------------------------------------
@dataclass
class PoseTempTest(TempTest):
    """The same test on static poses: one magnitude residual per pose mean
    (the structure's starting fit), an offset change o (unit) showing as
    u . o; temperature u dT, time u x basis(t), nuisance a small change of
    the map.  ``y``/``w`` hold the residual in column 0 (unit, weights)."""
    u: np.ndarray | None = None
    v: np.ndarray | None = None

    def _blocks(self, temperature: bool, time: bool):
        cols = [sym_cols(self.u, self.v)]
        if temperature:
            cols.append(self.u * (self.temp - self.t_ref)[:, None])
        if time:
            span = max(float(np.ptp(self.t)), 1e-9)
            tau = (self.t - self.t.min()) / span
            basis = [tau - 0.5] + [np.cos(np.pi * j * tau) for j in range(1, self.n_time)]
            if self.tau > 0:
                basis.append(1.0 - np.exp(-(self.t - self.t.min()) / self.tau))
            cols += [self.u * b[:, None] for b in basis]
        return np.hstack(cols)

    def fit(self, temperature: bool, time: bool, rows=None, fixed=None):
        X = self._blocks(temperature, time)
        rows = np.ones(len(self.y), bool) if rows is None else rows
        y, Xr = self.y[rows, 0].copy(), X[rows]
        sw = np.sqrt(self.w[rows, 0])
        if fixed is not None and temperature:
            y = y - Xr[:, 9:12] @ (np.asarray(fixed, float) / self.K)
            Xr = np.delete(Xr, np.s_[9:12], axis=1)
        beta, *_ = np.linalg.lstsq(Xr * sw[:, None], y * sw, rcond=None)
        r = (y - Xr @ beta) * sw
        if fixed is not None and temperature:
            beta = np.insert(beta, 9, np.asarray(fixed, float) / self.K)
        return [beta], float(r @ r), Xr.shape[1]

    def predict(self, betas, temperature: bool, time: bool) -> np.ndarray:
        return (self._blocks(temperature, time) @ betas[0])[:, None]

    def coefficients(self, betas, s2: float, time: bool):
        X = self._blocks(True, time) * np.sqrt(self.w[:, 0])[:, None]
        cov = np.linalg.pinv(X.T @ X) * max(1.0, s2)
        return betas[0][9:12] * self.K, np.sqrt(np.clip(np.diag(cov)[9:12], 0, None)) * self.K

    def heldout_rms(self, temperature: bool, time: bool, fixed=None):
        fold = interleaved(len(self.y), KFOLD)

        def score(betas, te):
            return ((self.y[te, 0] - self.predict(betas, temperature, time)[te, 0])
                    * np.sqrt(self.w[te, 0] / self.w[te, 0].mean())) ** 2
        sums = fold_sums(kfold_heldout(
            fold, lambda tr: self.fit(temperature, time, rows=tr, fixed=fixed)[0], score), fold)
        per = [np.sqrt(s / size) for _, s, size in sums]
        return float(np.sqrt(sum(s for _, s, _ in sums) / len(self.y))) * self.K, np.array(per)


def make_pose_test(data: SessionData, o, st) -> PoseTempTest | None:
    """The poses regime's test (the accelerometer's offsets), on the pose
    means of the structure ``st`` (its starting fit), or None.  (A
    magnetometer's sensitivity is a gain, not an offset: not tested on
    poses.)"""
    if not data.has_temp or o is None or st is None or st.regime != "poses" \
            or o.sensor != "accel":
        return None
    pts = st.points
    X, T = pts["X"], pts["T"]
    idx = pts["group"]
    temp = []
    for i in idx:
        v = data.temp[o.rows[o.segs.rows[i]]] if len(o.segs.rows[i]) else np.empty(0)
        v = v[np.isfinite(v)]
        temp.append(float(v.mean()) if len(v) else np.nan)
    temp = np.array(temp)
    ok = np.isfinite(temp)
    if ok.sum() < 24:
        return None
    fit = st.fit0
    r = fit.residuals(X, T)
    v = fit.calibrate(X, T)
    u = v / np.linalg.norm(v, axis=1)[:, None]
    V = pts["V"]
    tt = PoseTempTest(o.sensor, r[ok][:, None], (1.0 / np.maximum(V[ok], 1e-30))[:, None],
                      temp[ok], T[ok], np.zeros(ok.sum(), int), float(np.mean(temp[ok])),
                      float(o.K), u=u[ok], v=v[ok])
    if tt.span < MIN_TEMP_SPAN_C:
        return None
    return tt


def testable(data: SessionData, o, regime: str | None) -> bool:
    """Whether the temperature test runs for this sensor (for the plan's
    count): still blocks (``make_test``) or, for the accelerometer and
    magnetometer in the poses regime, pose means spanning the temperature."""
    if regime == "poses" and o is not None and o.sensor == "accel" \
            and data.has_temp and o.segs is not None:
        temp = np.array([np.nanmean(data.temp[o.rows[r]]) if len(r) and
                         np.isfinite(data.temp[o.rows[r]]).any() else np.nan
                         for r in o.segs.rows])
        ok = np.isfinite(temp)
        return ok.sum() >= 24 and float(np.ptp(temp[ok])) >= MIN_TEMP_SPAN_C
    return make_test(data, o, regime) is not None
