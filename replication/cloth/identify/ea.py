"""The paper's evolutionary algorithm for the cloth parameters (section 3.3).

At each generation the population is sorted by cost (ranking, not cost values, drives
selection); the best ``keep`` fraction survives unchanged; a ``mutation`` fraction of new
individuals are copies of individuals drawn from the best ``mutate_from`` fraction with
randomly chosen parameters mutated; a ``crossover`` fraction are made by uniform crossover
from ``n_parents`` (default: as many as there are parameters) parents drawn from the best
``crossover_from`` fraction. It stops after ``generations`` generations or when the best
cost falls below ``stop_cost`` (the paper's own suggestion, 3.4).

The paper leaves the mutation's size open: here a mutated parameter receives Gaussian
noise of standard deviation ``mutation_scale`` times its bound width, and is reflected
into the bounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replication.errors import InputError, check
from replication.optim.objective import BudgetExhausted
from replication.progress import bar


@dataclass(frozen=True)
class EASettings:
    """Rates and sizes of the paper's EA (paper 3.3 defaults)."""

    pop_size: int = 100
    generations: int = 49
    keep: float = 0.5
    mutation: float = 0.2
    crossover: float = 0.3
    mutate_from: float = 0.8
    crossover_from: float = 0.5
    mutation_scale: float = 0.05
    mutated_params: int = 1
    n_parents: int | None = None
    stop_cost: float | None = None

    @classmethod
    def from_config(cls, cfg):
        """Settings from a config block (unknown keys are refused)."""
        unknown = set(cfg) - set(cls.__dataclass_fields__)
        check(not unknown, f"ea: unknown setting(s) {sorted(unknown)}; expected some of "
                           f"{sorted(cls.__dataclass_fields__)}")
        settings = cls(**cfg)
        settings.validate()
        return settings

    def counts(self):
        """Numbers of kept, mutated and crossed individuals per generation."""
        n_keep = int(round(self.keep * self.pop_size))
        n_mut = int(round(self.mutation * self.pop_size))
        return n_keep, n_mut, self.pop_size - n_keep - n_mut

    def validate(self):
        """Refuse settings the EA cannot run with (InputError naming the setting)."""
        check(self.pop_size >= 4, f"ea.pop_size={self.pop_size}: a population under 4; "
                                  "expected at least 4 individuals")
        check(self.generations >= 0, f"ea.generations={self.generations}: expected >= 0")
        for name in ("keep", "mutation", "crossover", "mutate_from", "crossover_from"):
            value = getattr(self, name)
            check(0.0 <= value <= 1.0, f"ea.{name}={value}: expected a fraction in [0, 1]")
        total = self.keep + self.mutation + self.crossover
        check(abs(total - 1.0) < 1e-9,
              f"ea.keep + ea.mutation + ea.crossover = {self.keep} + {self.mutation} + "
              f"{self.crossover} = {total:g}: rates do not add up; expected 1")
        check(self.keep > 0, f"ea.keep={self.keep}: expected a positive fraction")
        n_keep, n_mut, n_cross = self.counts()
        check(n_keep >= 1 and n_cross >= 0,
              f"ea rates give {n_keep} kept, {n_mut} mutated, {n_cross} crossed of "
              f"{self.pop_size}: expected at least one kept individual")
        check(self.mutation_scale > 0, f"ea.mutation_scale={self.mutation_scale}: "
                                       "expected > 0")
        check(self.mutated_params >= 1, f"ea.mutated_params={self.mutated_params}: "
                                        "expected >= 1")
        check(self.n_parents is None or self.n_parents >= 1,
              f"ea.n_parents={self.n_parents}: expected >= 1 or null")


def _pool(size, fraction):
    """Number of best-ranked individuals that a fraction selects (at least one)."""
    return max(1, int(round(fraction * size)))


def reflect(X, lower, upper):
    """Reflect values outside ``[lower, upper]`` back inside (then clip), same shape.

    Parameters
    ----------
    X : ndarray
    lower, upper : ndarray
        Bounds, broadcast against ``X``.
    """
    width = upper - lower
    Y = np.abs((X - lower) % (2.0 * width))
    Y = np.where(Y > width, 2.0 * width - Y, Y)
    return np.clip(lower + Y, lower, upper)


def mutate(parents, rng, *, lower, upper, scale, n_params):
    """Paper 3.3 mutation: ``n_params`` randomly chosen parameters of each parent row get
    Gaussian noise of ``scale`` times the bound width. parents: (m, n_var) -> (m, n_var).

    Parameters
    ----------
    parents : (m, n_var) ndarray
    rng : np.random.Generator
    lower, upper : (n_var,) ndarray
    scale : float
        Noise standard deviation as a fraction of the bound width.
    n_params : int
        Parameters mutated per child.
    """
    children = parents.copy()
    m, n_var = parents.shape
    n_params = min(n_params, n_var)
    for row in range(m):
        which = rng.choice(n_var, size=n_params, replace=False)
        children[row, which] += scale * (upper[which] - lower[which]) * rng.standard_normal(
            n_params)
    return reflect(children, lower, upper)


def uniform_crossover(pool, n_children, n_parents, rng):
    """Paper 3.3 crossover: for each child, ``n_parents`` parents drawn (without
    replacement when possible) from ``pool`` (k, n_var); each parameter is copied from one
    of them chosen uniformly. Returns (n_children, n_var).

    Parameters
    ----------
    pool : (k, n_var) ndarray
        The best-ranked individuals.
    n_children, n_parents : int
    rng : np.random.Generator
    """
    k, n_var = pool.shape
    children = np.empty((n_children, n_var))
    for row in range(n_children):
        parents = rng.choice(k, size=n_parents, replace=n_parents > k)
        children[row] = pool[parents[rng.integers(n_parents, size=n_var)], np.arange(n_var)]
    return children


class PaperEA:
    """The paper's EA on a batched objective (``objective.evaluate(X) -> (pop,)``).

    Parameters
    ----------
    objective : Objective
    settings : EASettings
    rng : np.random.Generator
    initial : (pop_size, n_var) ndarray
        The initial population (see ``problem.random_population``).

    Attributes after :meth:`run`: ``X`` (pop, n_var) and ``F`` (pop,) sorted best first,
    ``history`` (list per generation of ``{generation, n_evals, best, best_point}``).
    """

    def __init__(self, objective, settings, rng, initial):
        self.objective = objective
        self.settings = settings
        self.rng = rng
        initial = np.asarray(initial, dtype=float)
        if initial.shape != (settings.pop_size, objective.n_var):
            raise InputError(f"initial population of shape {initial.shape}; expected "
                             f"({settings.pop_size}, {objective.n_var})")
        self.X = initial.copy()
        self.F = None
        self.generation = 0
        self.history = []

    def _sort(self):
        order = np.argsort(self.F, kind="stable")
        self.X, self.F = self.X[order], self.F[order]

    def _record(self):
        self.history.append({"generation": self.generation,
                             "n_evals": self.objective.n_evals,
                             "best": float(self.F[0]), "best_point": self.X[0].tolist()})

    def offspring(self):
        """New individuals of one generation from the sorted population: mutants then
        crossed children, shape (pop_size - kept, n_var)."""
        s, lower, upper = self.settings, self.objective.lower, self.objective.upper
        n_keep, n_mut, n_cross = s.counts()
        size = self.X.shape[0]
        parents = self.X[self.rng.integers(_pool(size, s.mutate_from), size=n_mut)]
        mutants = mutate(parents, self.rng, lower=lower, upper=upper,
                         scale=s.mutation_scale, n_params=s.mutated_params)
        n_parents = s.n_parents if s.n_parents is not None else self.objective.n_var
        crossed = uniform_crossover(self.X[:_pool(size, s.crossover_from)], n_cross,
                                    n_parents, self.rng)
        return np.vstack([mutants, crossed])

    def step(self):
        """One generation: keep the best, replace the rest by mutants and crossed ones."""
        n_keep = self.settings.counts()[0]
        children = self.offspring()
        values = self.objective.evaluate(children)
        self.X = np.vstack([self.X[:n_keep], children])
        self.F = np.concatenate([self.F[:n_keep], values])
        self._sort()
        self.generation += 1
        self._record()

    def done(self):
        s = self.settings
        return (self.generation >= s.generations
                or (s.stop_cost is not None and self.F[0] < s.stop_cost))

    def run(self):
        """Evaluate the initial population and evolve until :meth:`done` or the budget."""
        try:
            self.F = self.objective.evaluate(self.X)
            self._sort()
            self._record()
            with bar(self.settings.generations, "EA generations") as shown:
                while not self.done():
                    self.step()
                    shown.update()
        except BudgetExhausted:
            pass
        return self
