"""A body with imperfections no parameter names, for the naive agent's tests
and bench/noisy_naive.py: ``ImperfectSensing`` wraps a body's ``sense``."""
import numpy as np

from sensorispace_ros.core.body import SensingOnly


class ImperfectSensing(SensingOnly):
    """``SensingOnly`` whose ``sense`` perturbs joints, then sensations.

    ``motor_noise`` sd (body units) added to each commanded joint before the
    true sense; ``noise`` sd of additive Gaussian noise per receptor;
    ``laplace`` scale of additive Laplace (heavy-tailed) noise;
    ``relative`` sd of noise proportional to each output; ``quantum`` the
    step outputs are rounded to; ``float32`` rounds to single precision;
    ``dropout`` the chance a row comes back all NaN."""

    __slots__ = ("_rng", "_imperfections")

    def __init__(self, body, *, seed: int = 0, **imperfections):
        super().__init__(body)
        self._rng = np.random.default_rng(seed)
        self._imperfections = imperfections

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        knobs = self._imperfections
        motor = np.array(motor_states, dtype=float)
        if knobs.get("motor_noise"):
            motor = motor + self._rng.normal(0.0, knobs["motor_noise"], motor.shape)
        out = np.array(self._sense(motor), dtype=float)
        if knobs.get("noise"):
            out = out + self._rng.normal(0.0, knobs["noise"], out.shape)
        if knobs.get("laplace"):
            out = out + self._rng.laplace(0.0, knobs["laplace"], out.shape)
        if knobs.get("relative"):
            out = out * (1.0 + self._rng.normal(0.0, knobs["relative"], out.shape))
        if knobs.get("quantum"):
            out = np.round(out / knobs["quantum"]) * knobs["quantum"]
        if knobs.get("float32"):
            out = out.astype(np.float32).astype(float)
        if knobs.get("dropout"):
            out[self._rng.random(len(out)) < knobs["dropout"]] = np.nan
        return out


class SmoothBody:
    """Six smooth outputs of two joints (outputs ~0.5, slopes ~1 per rad);
    ``second`` scales what the second joint moves them by."""

    n_motors, n_sensors = 2, 6

    def __init__(self, second: float = 1.0):
        self.second = second

    def sense(self, motor_states):
        m = np.asarray(motor_states, dtype=float)
        k = np.arange(1, 7)
        return 0.5 + 0.3 * np.sin(k * m[:, :1] + self.second * m[:, 1:] * np.cos(k) + k)

    def jacobian(self, m):
        """The exact Jacobian at one motor state ``m``."""
        k = np.arange(1, 7)
        c = 0.3 * np.cos(k * m[0] + self.second * m[1] * np.cos(k) + k)
        return np.stack([c * k, self.second * c * np.cos(k)], axis=1)
