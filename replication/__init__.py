"""Replication suite for Louchet, Boccara, Crochemore and Provot (EA'95).

``replication.motion`` covers the paper's section 2 (rigid motion from image derivatives),
``replication.cloth`` its section 3 (physics from motion), ``replication.optim`` what the
paper's EAs and the baselines share, ``replication.figures`` draws, ``replication.report``
writes REPORT.md from results.

Sub-packages: ``replication.cloth.identify`` (the identifiers), ``replication.motion.segment``
(paper 2.3), ``replication.experiments`` (runners), ``replication.report`` (REPORT.md).

OpenBLAS sums in another order with another number of threads, and that shows in the
numbers (up to 2e-7 relative in the discrepancy studies, more where residuals are
round-off), so every run of the suite uses one BLAS thread, whether alone, beside other
experiments in ``replicate-all`` or in a worker: the same config and seed give the same
numbers in every mode. Set before numpy loads, so only when ``replication`` is imported
first (as the commands do); a value already set is kept.
"""

import os

for _name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

__version__ = "0.1.0"
