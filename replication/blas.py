"""One set of BLAS kernels on every x86-64 CPU, so that results repeat across machines.

OpenBLAS (numpy's and scipy's) picks the kernels of the CPU it runs on: SkylakeX kernels on
a CPU with AVX-512, Haswell kernels on one with AVX2. They round differently, so the same
config and seed gave other numbers on another CPU (at round-off, and more where a run is
chaotic). :func:`pin_kernels` sets ``OPENBLAS_CORETYPE=Haswell`` wherever the CPU has those
kernels' instructions (AVX2 and FMA), unless the user set ``OPENBLAS_CORETYPE``. OpenBLAS
reads it when it is loaded, so this runs before numpy is imported (``replication``'s
``__init__``); processes started afterwards inherit it.
"""

from __future__ import annotations

import os
import platform

PINNED = "Haswell"
NEEDS = frozenset({"avx2", "fma"})  # the instructions of OpenBLAS's Haswell kernels


def cpu_flags(cpuinfo="/proc/cpuinfo"):
    """The CPU's feature flags from the first ``flags`` line of ``cpuinfo`` (Linux); an
    empty set where there is none."""
    try:
        with open(cpuinfo, encoding="utf-8", errors="replace") as handle:
            for line in handle:
                if line.startswith("flags"):
                    return frozenset(line.partition(":")[2].split())
    except OSError:
        pass
    return frozenset()


def pin_kernels(environ=None, *, machine=None, flags=None):
    """Set ``OPENBLAS_CORETYPE`` to :data:`PINNED` in ``environ`` (default ``os.environ``)
    on an x86-64 CPU with AVX2 and FMA, unless it is set already; return its value then
    (``None``: left unset, on other CPUs, where OpenBLAS keeps its own choice)."""
    environ = os.environ if environ is None else environ
    if "OPENBLAS_CORETYPE" in environ:
        return environ["OPENBLAS_CORETYPE"]
    machine = platform.machine() if machine is None else machine
    if machine.lower() not in ("x86_64", "amd64"):
        return None
    if not NEEDS <= (cpu_flags() if flags is None else frozenset(flags)):
        return None
    environ["OPENBLAS_CORETYPE"] = PINNED
    return PINNED
