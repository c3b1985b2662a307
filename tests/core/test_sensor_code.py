"""Sensor codes: the formulas, the mixing matrix's conditioning, shapes and errors."""
import numpy as np
import pytest

from sensorispace_ros.core.sensor_code import CODES, SensorCode

R = 6
VALUES = {"identity": 1.0, "scale": 3.7, "log": 0.05, "power": 2.5, "mix": 10.0}


def code(kind, value=None, receptors=R, seed=0):
    value = VALUES[kind] if value is None else value
    return SensorCode(kind, value, receptors, np.random.default_rng(seed))


def sensations(shape=(200, R), seed=1):
    return np.random.default_rng(seed).uniform(0.0, 1.2, size=shape)


def test_identity_returns_the_same_bits():
    s = sensations()
    s[0, :4] = [0.0, -0.0, 5e-324, np.nextafter(1.0, 2.0)]
    out = code("identity").apply(s)
    assert out.dtype == np.float64
    assert out.tobytes() == s.tobytes()
    assert code("identity").is_identity and not code("scale").is_identity


def test_identity_converts_lists_to_float_arrays():
    out = code("identity", receptors=3).apply([[0, 1, 2]])
    assert out.dtype == np.float64 and out.tolist() == [[0.0, 1.0, 2.0]]


@pytest.mark.parametrize("kind, formula", [
    ("scale", lambda v, s: v * s),
    ("log", lambda v, s: np.log(v + s)),
    ("power", lambda v, s: s ** v),
])
def test_elementwise_codes_follow_their_formula(kind, formula):
    s = sensations()
    for value in (0.3, 1.0, VALUES[kind], 7.0):
        c = code(kind, value)
        np.testing.assert_allclose(c.apply(s), formula(value, s), rtol=1e-15, atol=0)
        assert c.matrix is None


def test_log_is_finite_at_zero():
    out = code("log", 1e-3).apply(np.zeros((2, R)))
    assert np.all(np.isfinite(out)) and np.allclose(out, np.log(1e-3))


@pytest.mark.parametrize("receptors", [6, 12])
def test_mix_matrix_has_the_requested_condition_number(receptors):
    matrix = code("mix", 10.0, receptors).matrix
    assert matrix.shape == (receptors, receptors)
    assert abs(np.linalg.cond(matrix) - 10.0) <= 1.0
    assert np.isclose(np.linalg.norm(matrix, 2), 1.0)


def test_mix_actually_mixes_the_receptors():
    matrix = code("mix").matrix
    off_diagonal = matrix - np.diag(np.diag(matrix))
    assert np.min(np.abs(off_diagonal) + np.eye(R)) > 1e-6


def test_mix_matrix_depends_on_the_seed_only():
    assert np.array_equal(code("mix", seed=4).matrix, code("mix", seed=4).matrix)
    assert not np.allclose(code("mix", seed=4).matrix, code("mix", seed=5).matrix)


def test_mix_applies_the_matrix_and_is_invertible():
    c, s = code("mix"), sensations()
    out = c.apply(s)
    np.testing.assert_allclose(out, (c.matrix @ s.T).T, rtol=1e-13, atol=1e-15)
    back = np.linalg.solve(c.matrix, out.T).T
    assert np.max(np.abs(back - s)) <= 1e-12 * np.max(np.abs(s))


def test_mix_with_one_receptor_is_the_unit_matrix():
    c = code("mix", 10.0, receptors=1)
    assert c.matrix.tolist() == [[1.0]]
    s = sensations((4, 1))
    assert np.array_equal(c.apply(s), s)


@pytest.mark.parametrize("kind", CODES)
def test_codes_broadcast_over_leading_axes(kind):
    c, s = code(kind), sensations((3, 5, R))
    out = c.apply(s)
    assert out.shape == (3, 5, R)
    np.testing.assert_allclose(out.reshape(-1, R), c.apply(s.reshape(-1, R)), rtol=1e-15)
    np.testing.assert_allclose(out[2, 4], c.apply(s[2, 4]), rtol=1e-15)


@pytest.mark.parametrize("kind", CODES)
def test_codes_keep_distinct_sensations_distinct(kind):
    s = sensations((300, R), seed=2)
    s[1] = s[0]
    s[1, 3] = np.nextafter(s[0, 3], 2.0) + 1e-9          # a near-duplicate
    s[2] = 0.0
    out = code(kind).apply(s)
    rows = {row.tobytes() for row in out}
    assert len(rows) == len(s)


@pytest.mark.parametrize("shape", [(4, R + 1), (R - 1,), ()])
def test_wrong_last_axis_is_rejected(shape):
    with pytest.raises(ValueError, match="receptors"):
        code("scale").apply(np.zeros(shape))


@pytest.mark.parametrize("kind", ["foo", "Identity", ""])
def test_unknown_kind_is_rejected(kind):
    with pytest.raises(ValueError, match=r"world\.retina\.code: must be one of"):
        SensorCode(kind, 1.0, R)


@pytest.mark.parametrize("kind", CODES)
@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf")])
def test_non_positive_value_is_rejected(kind, value):
    with pytest.raises(ValueError, match=r"world\.retina\.code_value"):
        code(kind, value)


def test_mix_rejects_condition_below_one():
    with pytest.raises(ValueError, match=r"world\.retina\.code_value.*mix"):
        code("mix", 0.5)
    assert np.isclose(np.linalg.cond(code("mix", 1.0).matrix), 1.0)


def test_mix_needs_a_generator():
    with pytest.raises(ValueError, match="rng"):
        SensorCode("mix", 10.0, R)
    assert SensorCode("power", 2.0, R).matrix is None


@pytest.mark.parametrize("receptors", [0, -2, 2.5])
def test_bad_receptor_count_is_rejected(receptors):
    with pytest.raises(ValueError, match=r"world\.retina\.receptors"):
        SensorCode("scale", 1.0, receptors)


def test_attributes_are_kept():
    c = code("log", 2)
    assert (c.kind, c.value, c.receptors) == ("log", 2.0, R)
    assert isinstance(c.value, float)
