"""Experiment runners: one module per family, named by the configs' ``runner:`` keys.

A runner reads a resolved config, calls the libraries (:mod:`replication.cloth`,
:mod:`replication.motion`, :mod:`replication.discrepancy`) and the figures, and returns the
result dict that ``replicate`` writes (docs/results.md). Libraries never import this
package; the REPORT.md sections (:mod:`replication.report`) read results only.
"""
