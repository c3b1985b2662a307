"""core.numpy_math: whether NumPy's float64 math is the C library's here, and
the bit-for-bit kernel checks re-run in a process where it is."""
import math
import subprocess
import sys
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest

from sensorispace_ros.core import numpy_math
from sensorispace_ros.core.numpy_math import c_math_environment, numpy_calls_c_math

from shared import REPO


def wide_sample_differences() -> list[int]:
    """Arguments the probe does not use: random over each function's range."""
    rng = np.random.default_rng(7)
    return numpy_math.c_math_differences(rng.uniform(-745.0, 709.0, 100_000),
                                         rng.uniform(-1.0, 1.0, 100_000))


def run_child(code: str) -> str:
    done = subprocess.run([sys.executable, "-c", code], env=c_math_environment(),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_the_probe_agrees_with_a_wider_sample():
    differs = wide_sample_differences()
    # The probe is what the tests trust: it must not call NumPy's math the C
    # library's where 300,000 other arguments tell them apart, nor the reverse.
    assert numpy_calls_c_math() == (not any(differs)), differs


def test_numpy_calls_c_math_in_the_child_environment():
    out = run_child(f"""
import sys
sys.path[:0] = [{str(Path(__file__).parent)!r}, {str(Path(__file__).parents[1])!r}]
from test_numpy_math import numpy_calls_c_math, wide_sample_differences
print(numpy_calls_c_math(), wide_sample_differences())
""")
    assert out.split(None, 1) == ["True", "[0, 0, 0]\n"], out


def test_the_child_environment_switches_off_only_numpys_simd_math():
    env = c_math_environment({"PATH": "/usr/bin"})
    features = numpy_math.numpy_simd_features()
    assert env.get("NPY_DISABLE_CPU_FEATURES", "") == " ".join(features)
    assert all(name.startswith("AVX512") for name in features)
    assert env["PATH"] == "/usr/bin"
    if not numpy_calls_c_math():
        assert features, "NumPy's math is its own, yet no AVX-512 loops were found"


def test_numba_math_is_pythons_math():
    # The premise of the probe: what Python's math.exp / log / acos give (the C
    # library's) is what the compiled kernels' math.* calls give.
    numba = pytest.importorskip("numba")

    @numba.njit
    def c_math(x, unit):
        out = np.empty((3, len(x)))
        for i in range(len(x)):
            out[0, i] = math.exp(x[i])
            out[1, i] = math.log(abs(x[i]) + 1e-300)
            out[2, i] = math.acos(unit[i])
        return out

    rng = np.random.default_rng(8)
    x, unit = rng.uniform(-745.0, 709.0, 100_000), rng.uniform(-1.0, 1.0, 100_000)
    python = np.array([[math.exp(v) for v in x.tolist()],
                       [math.log(abs(v) + 1e-300) for v in x.tolist()],
                       [math.acos(v) for v in unit.tolist()]])
    assert c_math(x, unit).tobytes() == python.tobytes()


def test_bit_contracts_hold_where_numpy_calls_c_math(tmp_path):
    if numpy_calls_c_math():
        pytest.skip("this process's NumPy calls the C library's math: the tests marked "
                    "numpy_bits checked the bits in this run")
    report = tmp_path / "junit.xml"
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-m", "numpy_bits", "-q", "-p", "no:cacheprovider",
         f"--junitxml={report}", "tests/core", "tests/test_bench_smoke.py"],
        cwd=REPO, env=c_math_environment(), capture_output=True, text=True, timeout=600)
    suite = ElementTree.parse(report).getroot()
    suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
    counts = {key: int(suite.get(key)) for key in ("tests", "failures", "errors", "skipped")}
    assert done.returncode == 0 and counts["failures"] == counts["errors"] == 0, \
        done.stdout[-4000:]
    assert counts["tests"] > 0 and counts["skipped"] == 0, counts
    modules = {case.get("classname", "").rpartition(".")[2] for case in suite.iter("testcase")}
    assert {"test_body_simulation", "test_cca", "test_bench_smoke"} <= modules, modules
