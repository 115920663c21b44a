"""Replication suite for Louchet, Boccara, Crochemore and Provot (EA'95).

``replication.motion`` covers the paper's section 2 (rigid motion from image derivatives),
``replication.cloth`` its section 3 (physics from motion), ``replication.optim`` what the
paper's EAs and the baselines share, ``replication.figures`` draws, ``replication.report``
writes REPORT.md from results.
"""

from replication.blas import pin_kernels

# before anything imports numpy: the same BLAS kernels on every x86-64 CPU (replication/blas.py)
pin_kernels()

__version__ = "0.1.0"
