"""Identification of the cloth parameters (paper 3.3, and beyond it).

- :mod:`.problem`: the problem every identifier shares (search space, costs, objective).
- :mod:`.ea`: the paper's evolutionary algorithm.
- :mod:`.structured`: the structured identifier (regression, tau scan, EA refinement).
- :mod:`.api`: :func:`identify`, the entry point for other code.
"""

from replication.cloth.identify.api import DEFAULT_BOUNDS, DEFAULT_STRUCTURED, identify
from replication.cloth.identify.ea import EASettings, PaperEA, mutate, reflect, uniform_crossover
from replication.cloth.identify.structured import structured_identify

__all__ = ["DEFAULT_BOUNDS", "DEFAULT_STRUCTURED", "EASettings", "PaperEA", "identify",
           "mutate", "reflect", "structured_identify", "uniform_crossover"]
