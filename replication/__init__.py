"""Replication suite for Louchet, Boccara, Crochemore and Provot (EA'95).

``replication.motion`` covers the paper's section 2 (rigid motion from image derivatives),
``replication.cloth`` its section 3 (physics from motion), ``replication.optim`` what the
paper's EAs and the baselines share, ``replication.figures`` draws, ``replication.report``
writes REPORT.md from results.
"""

__version__ = "0.1.0"
