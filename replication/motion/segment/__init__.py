"""Rigid-motion segmentation, paper 2.3: several rotating regions in one sequence.

- :mod:`.disc_ea`: the evolutionary disc detector with sharing (2.3.2, Fig. 5).
- :mod:`.snakes`: radial snakes (2.3.3, Fig. 6).
- :mod:`.assignment`: per-pixel assignment once every motion is known (beyond the paper).
- :mod:`.pipeline`: the whole method, discs to restricted accumulation (Fig. 7).
- :mod:`.baselines`: NicheGA discs and flow + sequential RANSAC.
"""

from replication.motion.segment.pipeline import segment, settings_from

__all__ = ["segment", "settings_from"]
