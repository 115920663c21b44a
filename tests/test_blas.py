"""replication/blas.py: one set of OpenBLAS kernels on every x86-64 CPU with AVX2."""

import os
import subprocess
import sys

from replication.blas import PINNED, cpu_flags, pin_kernels


def test_haswell_kernels_are_pinned_where_the_cpu_has_them_and_the_user_did_not_choose():
    env = {}
    assert pin_kernels(env, machine="x86_64", flags={"sse2", "avx2", "fma", "avx512f"}) \
        == PINNED == "Haswell"
    assert env == {"OPENBLAS_CORETYPE": "Haswell"}
    for machine, flags in (("x86_64", {"sse2", "avx"}), ("x86_64", {"avx2"}),
                           ("aarch64", {"avx2", "fma"})):
        env = {}
        assert pin_kernels(env, machine=machine, flags=flags) is None and env == {}
    env = {"OPENBLAS_CORETYPE": "SkylakeX"}   # the user's choice stays
    assert pin_kernels(env, machine="x86_64", flags={"avx2", "fma"}) == "SkylakeX"
    assert env == {"OPENBLAS_CORETYPE": "SkylakeX"}


def test_cpu_flags_are_read_from_the_first_flags_line(tmp_path):
    info = tmp_path / "cpuinfo"
    info.write_text("processor\t: 0\nflags\t\t: fpu sse2 avx2 fma\n\nprocessor\t: 1\n"
                    "flags\t\t: fpu\n")
    assert cpu_flags(info) == {"fpu", "sse2", "avx2", "fma"}
    assert cpu_flags(tmp_path / "missing") == frozenset()


def test_importing_the_package_pins_the_kernels_before_numpy_loads_them():
    """A fresh interpreter that imports the package (as `replicate` does) carries the pin
    in its environment, for OpenBLAS at numpy's import and for every process it starts."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    out = subprocess.run([sys.executable, "-c", "import sys, os, replication; "
                          "print('numpy' in sys.modules, os.environ.get('OPENBLAS_CORETYPE'))"],
                         env=env, capture_output=True, text=True, check=True).stdout.split()
    expected = pin_kernels({})
    assert out == ["False", str(expected)]
