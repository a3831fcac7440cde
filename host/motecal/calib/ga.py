"""The project's real-coded evolutionary algorithm (a genetic algorithm over
double-valued parameters, the seed paper's method), vectorised over the
population.

* Genome: the model's free parameters as float64 (the paper's phenotype).
* Priors: every parameter has an a-priori range ``[lo, hi]``; the first
  population is uniform in the ranges plus the prior's nominal point, and
  children are clipped to the ranges.
* Selection: binary tournament; elitism keeps the best ``elite`` individuals.
* Crossover: BLX-alpha (blend) on every gene.
* Mutation: Gaussian, probability ``1/d`` per gene, with a step that follows
  the spread of the current population (self-adapting as it converges) and
  never falls below ``min_step`` times the prior range.
* Fitness: ``fitness(pop)`` gets the whole population as one ``(P, d)`` array
  and returns ``(P,)`` values (lower is better).
* Stop rule, independent of the size of the fitness: stop when the best value
  improved by less than ``rtol`` *relative* over the last ``window``
  generations, or after ``max_gen`` generations.  The result is then meant to
  be polished by a local least-squares method (see ``fit.py``).
* Local refinement (optional, ``refine``): in the first population and every
  ``refine_every`` generations the ``refine_k`` best individuals are replaced
  by ``refine(x)`` (a memetic, Lamarckian GA).  The robust fit refines with a
  few concentration steps on the reduction (``robust.py``): its objective has
  a narrow global basin that mutation and crossover alone rarely hit, while
  a concentration step from anywhere near it lands in it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class GAOptions:
    pop_size: int = 0              # 0: 6*d + 12
    max_gen: int = 300
    elite: int = 2
    alpha: float = 0.3             # BLX-alpha
    rtol: float = 1e-2             # relative improvement of the best over `window` generations
    window: int = 6
    min_gen: int = 10
    min_step: float = 1e-6         # floor of the mutation step, fraction of the prior range


@dataclass
class GAResult:
    x: np.ndarray                  # best individual
    f: float                       # its fitness
    trace: list = field(default_factory=list)   # best fitness per generation (gen 0 = initial)
    generations: int = 0
    evaluations: int = 0
    stop: str = ""                 # why it stopped
    seed: int | None = None


def minimize(fitness, lo, hi, *, seed=None, x0=None, options: GAOptions = GAOptions(),
             refine=None, refine_every: int = 5, refine_k: int = 4) -> GAResult:
    """Minimise ``fitness`` over the box ``[lo, hi]`` with the GA (``refine``:
    the module doc's local refinement)."""
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    d = len(lo)
    span = hi - lo
    rng = np.random.default_rng(seed)
    P = options.pop_size or (6 * d + 12)
    n_child = P - options.elite
    X = lo + span * rng.random((P, d))
    if x0 is not None:
        X[0] = np.clip(np.asarray(x0, float), lo, hi)
    f = np.asarray(fitness(X), float)
    f = np.where(np.isfinite(f), f, np.inf)
    evals = P

    def refined(X, f):
        best = np.argsort(f)[:refine_k]
        X[best] = np.clip(np.array([refine(x) for x in X[best]]), lo, hi)
        fb = np.asarray(fitness(X[best]), float)
        f[best] = np.where(np.isfinite(fb), fb, np.inf)
        return X, f, len(best)
    if refine is not None:
        X, f, k = refined(X, f)
        evals += k
    best = int(np.argmin(f))
    trace = [float(f[best])]
    stop = "max_gen"
    pm = 1.0 / d
    gen = 0
    for gen in range(1, options.max_gen + 1):
        order = np.argsort(f)
        elites = X[order[:options.elite]]
        # binary tournaments: 2 parents per child
        a = rng.integers(0, P, (2, n_child))
        b = rng.integers(0, P, (2, n_child))
        win = np.where(f[a] <= f[b], a, b)
        p1, p2 = X[win[0]], X[win[1]]
        # BLX-alpha crossover
        lo_c = np.minimum(p1, p2)
        w = np.abs(p1 - p2)
        child = lo_c - options.alpha * w + rng.random((n_child, d)) * w * (1 + 2 * options.alpha)
        # Gaussian mutation, step from the population spread
        step = np.maximum(X.std(axis=0), options.min_step * span)
        mut = rng.random((n_child, d)) < pm
        child = child + mut * rng.standard_normal((n_child, d)) * step
        np.clip(child, lo, hi, out=child)
        X = np.vstack([elites, child])
        fc = np.asarray(fitness(child), float)
        fc = np.where(np.isfinite(fc), fc, np.inf)
        f = np.concatenate([f[order[:options.elite]], fc])
        evals += n_child
        if refine is not None and gen % refine_every == 0:
            X, f, k = refined(X, f)
            evals += k
        best = int(np.argmin(f))
        trace.append(float(f[best]))
        if gen >= max(options.min_gen, options.window):
            old = trace[-1 - options.window]
            if old - trace[-1] <= options.rtol * abs(trace[-1]):
                stop = f"stagnation: best improved < {options.rtol:g} relative in {options.window} generations"
                break
    return GAResult(X[best].copy(), float(f[best]), trace, gen, evals, stop, seed)
