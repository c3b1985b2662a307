"""Bit-for-bit checks of a compiled kernel against its NumPy path.

Where this process's NumPy calls the C library's math
(``core.numpy_math.numpy_calls_c_math``) the bits must be equal, as they are
between numba's calls and NumPy's. Where NumPy has float64 math loops of its
own (AVX-512) the check here is closeness; test_numpy_math.py then runs every
test marked ``numpy_bits`` again in a child process whose NumPy calls the C
library, where they check the bits."""
import numpy as np

from sensorispace_ros.core.numpy_math import numpy_calls_c_math


def assert_numpy_bits(got, expected, rtol: float, atol: float = 0.0) -> None:
    """``got`` has ``expected``'s bits (NaN at the same places); where NumPy's
    math is its own, NaN and exact zeros at the same places and the values
    within ``rtol`` / ``atol``."""
    got, expected = np.asarray(got), np.asarray(expected)
    assert got.shape == expected.shape, (got.shape, expected.shape)
    if numpy_calls_c_math():
        assert got.tobytes() == expected.tobytes()
        return
    np.testing.assert_array_equal(np.isnan(got), np.isnan(expected))
    np.testing.assert_array_equal(got == 0.0, expected == 0.0)
    np.testing.assert_allclose(got, expected, rtol=rtol, atol=atol)
