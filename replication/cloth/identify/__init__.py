"""Identification of the cloth parameters (paper 3.3, and beyond it).

- :mod:`.problem`: the problem every identifier shares (search space, costs, objective).
- :mod:`.ea`: the paper's evolutionary algorithm.
- :mod:`.structured`: the structured identifier (regression, tau scan, EA refinement).
- :mod:`.api`: :func:`identify`, the entry point for other code, and :func:`solve` over the
  one solver table :data:`SOLVERS`.
"""

from replication.cloth.identify.api import (DEFAULT_BOUNDS, SOLVERS, default_structured, identify,
                                            solve)
from replication.cloth.identify.ea import EASettings, PaperEA, mutate, reflect, uniform_crossover
from replication.cloth.identify.structured import structured_identify

__all__ = ["DEFAULT_BOUNDS", "SOLVERS", "EASettings", "PaperEA", "default_structured",
           "identify", "mutate", "reflect", "solve", "structured_identify", "uniform_crossover"]
