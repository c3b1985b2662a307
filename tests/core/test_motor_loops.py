"""Closed loops of motor samples that double back on themselves."""
import numpy as np
import pytest

from sensorispace_ros.core.motor_loops import doubles_back


def _ellipse(n: int = 100, shift: float = 0.0) -> np.ndarray:
    """``(n, 4)`` samples round a tilted ellipse in four joints."""
    phase = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.stack([1.2 * np.cos(phase), 0.4 * np.sin(phase),
                     0.3 * np.cos(phase) + 0.2 * np.sin(phase), np.full(n, shift)], axis=1)


def _out_and_back(n: int = 100) -> np.ndarray:
    """Half the ellipse walked out and back: what a front that turned round leaves."""
    half = _ellipse(n)[: n // 2 + 1]
    return np.vstack([half, half[-2:0:-1]])


def test_a_smooth_loop_does_not_double_back_even_across_the_phase_wrap():
    loops = np.stack([_ellipse(), _ellipse(shift=np.pi - 1e-9), _ellipse() + [3.0, 0.0, 0.0, 0.0]])
    assert loops[2, :, 0].max() > np.pi    # crosses the wrap at pi
    assert not doubles_back(loops).any()


def test_a_loop_walked_out_and_back_doubles_back():
    loops = np.stack([_ellipse(), _out_and_back(), _ellipse()])
    assert doubles_back(loops).tolist() == [False, True, False]


def test_one_sharp_cusp_doubles_back_and_a_right_angle_does_not():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float) * 0.5
    spike = np.array([[0, 0], [1, 0], [0.2, 0.05], [0, 1]], dtype=float) * 0.5
    flags = doubles_back(np.stack([square, spike]))
    assert flags.tolist() == [False, True]


def test_samples_must_be_loops_of_three_or_more():
    with pytest.raises(ValueError, match="samples must have shape"):
        doubles_back(np.zeros((2, 2, 4)))


def _walked(noisy: bool):
    """``SearchAndSample._whole_on_level_set`` on a smooth loop and one walked
    out and back, every sample of both sensing its start's sensation."""
    from types import SimpleNamespace

    from sensorispace_ros.core.naive.searching import SearchAndSample

    loops = np.stack([_ellipse(), _out_and_back()])
    target = np.array([[0.3, 0.5], [0.2, 0.1]])
    owner = np.repeat(np.arange(2), loops.shape[1])
    agent = SimpleNamespace(
        _noisy=noisy, params=SimpleNamespace(noise_confidence=0.999),
        structure=SimpleNamespace(noise=1e-3),
        _body=SimpleNamespace(sense=lambda states: target[owner[:len(states)]]))
    agent._level_set_allowance = lambda walk, n, s: SearchAndSample._level_set_allowance(
        agent, walk, n, s)
    walk = SimpleNamespace(samples=loops, valid=np.array([True, True]), target_sensations=target)
    return SearchAndSample._whole_on_level_set(agent, walk)


def test_under_noise_the_agent_keeps_no_walk_that_doubles_back():
    assert _walked(noisy=True).tolist() == [True, False]
    assert _walked(noisy=False).tolist() == [True, True]
