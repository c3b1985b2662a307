"""Whether NumPy's float64 math on this machine is the C library's.

The compiled kernels (numba: ``body.simulate``, the CCA step loop, the
Hausdorff kernel) call the C library's ``exp``, ``log``, ``acos``, ``cos``
... one value at a time. NumPy calls the same functions, except where it
has SIMD loops of its own for the CPU it runs on: on an AVX-512 machine
(``numpy._core._multiarray_umath.__cpu_features__``) its float64 ``exp``,
``log`` and ``arccos`` are NumPy's own, and differ from the C library's by
one unit in the last place in 4.4 %, 0.013 % and 1.6 % of the arguments
(NumPy 2.2.6, AMD EPYC with AVX-512, 2,000,001 arguments each; never more
than 1 ulp). So a kernel gives its NumPy path's bits only where
``numpy_calls_c_math()`` is True; elsewhere the two agree to a few ulp per
operation (tests/core/test_numpy_math.py runs the bit-for-bit checks a
second time in a process whose NumPy has those loops switched off,
``c_math_environment()``).

This never changes which numbers a run gives on one machine: the ROS body
and the offline run call the same kernel. It is why two machines with
different CPUs may differ in the last bits of the NumPy path.
"""
from __future__ import annotations

import functools
import math
import os

import numpy as np

# Probe arguments: exp over its whole finite range, log over magnitudes, arccos over
# [-1, 1]. 20,001 each; on the AVX-512 machine above 910, 1 and 1,903 of them differ.
_PROBE_SIZE = 20_001


def _dispatched_features() -> list[str]:
    """The CPU features NumPy found here and has dispatched loops for."""
    try:
        from numpy._core import _multiarray_umath as umath
    except ImportError:         # NumPy < 2
        from numpy.core import _multiarray_umath as umath
    found = umath.__cpu_features__
    return [name for name in umath.__cpu_dispatch__ if found.get(name)]


def c_math_differences(x: np.ndarray, unit: np.ndarray) -> list[int]:
    """How many of NumPy's ``exp(x)``, ``log(|x| + 1e-300)`` and
    ``arccos(unit)`` differ from the C library's (Python's ``math``)."""
    x, unit = np.asarray(x, dtype=float), np.asarray(unit, dtype=float)
    counts = []
    for numpy_function, c_function, arguments in ((np.exp, math.exp, x),
                                                  (np.log, math.log, np.abs(x) + 1e-300),
                                                  (np.arccos, math.acos, unit)):
        c_values = np.array([c_function(v) for v in arguments.tolist()])
        counts.append(int(np.count_nonzero(numpy_function(arguments).view(np.uint64)
                                           != c_values.view(np.uint64))))
    return counts


@functools.lru_cache(maxsize=1)
def numpy_calls_c_math() -> bool:
    """True when NumPy's float64 ``exp``, ``log`` and ``arccos`` give the C
    library's bits on a probe of 20,001 arguments each (the functions the
    kernels' NumPy paths use and NumPy has SIMD loops for)."""
    return not any(c_math_differences(np.linspace(-745.0, 709.0, _PROBE_SIZE),
                                      np.linspace(-1.0, 1.0, _PROBE_SIZE)))


def numpy_simd_features() -> list[str]:
    """The CPU features NumPy found here that carry float64 math loops of
    its own (the AVX-512 family)."""
    return [name for name in _dispatched_features() if name.startswith("AVX512")]


def c_math_environment(base: dict[str, str] | None = None) -> dict[str, str]:
    """An environment for a child process whose NumPy calls the C library's
    math: ``NPY_DISABLE_CPU_FEATURES`` lists ``numpy_simd_features()`` (read
    when NumPy is imported). NumPy's other SIMD loops (AVX2 and below) stay."""
    env = dict(os.environ if base is None else base)
    features = numpy_simd_features()
    if features:
        env["NPY_DISABLE_CPU_FEATURES"] = " ".join(features)
    return env
