"""REPORT.md: written from results, never by hand.

:mod:`.build` assembles the report from the experiments' ``report`` blocks; the other
modules are the sections, one per experiment family. They read results and compute
nothing.
"""
