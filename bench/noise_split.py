"""Is the agent's noise in its receptors or in its joints? A split, and two uses of it.

A joint that lands off its command moves the sensation along the sensory
Jacobian's range (``J delta``); a receptor's noise spreads in every
direction. Right after the naive agent's own noise and structure measure
this senses its start again, 16 times and with one Jacobian stencil (one
call), and splits the repeats' spread into

* ``sd_across``: per receptor, outside the Jacobian's ``pose_rank`` leading
  directions (the receptors' own noise: it can fake a direction the pose
  does not have);
* ``motor_sd``: per joint (phase units), the joint error that explains the
  spread inside them, the receptors' share taken off (joints alike assumed);

beside ``sd_all``, the isotropic figure of the same repeats. With
``--rank-floor`` the pinning and rank tests' floor is taken from
``sd_across``; with ``--precision`` a compensation's predicted pose error is
``sqrt(n * (sd_across^2 / s_r^2 + motor_sd^2))`` instead of
``sqrt(n) * sd / s_r`` (``n`` the sensings' variance in units of the
measured ``sd^2``, ``s_r`` the weakest singular value); with ``--whiten``
that error, and the residual inside the Jacobian's range, whitened by the
split (``confirm._judge``'s settle test). Only where the split is clear
(``sd_across`` below half ``sd_all``). Prints the split and
``bench/noisy_naive.py``'s summary line::

    .venv/bin/python bench/noise_split.py --config config/paper.yaml --motor_noise 1e-3 --precision

Diagnostics only: nothing here is the agent's.
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from sensorispace_ros.core.naive import confirm as confirm_mod
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.jacobians import sensory_jacobian
from sensorispace_ros.core.naive.noise import jacobian_noise
from sensorispace_ros.core.naive.searching import SearchAndSample

sys.path.insert(0, str(Path(__file__).resolve().parent))
from noisy_naive import run  # noqa: E402

REPEATS = 16
SPLIT: dict = {}


def split_noise(body, m0: np.ndarray, rank: int, fd_step) -> dict:
    """The repeats' spread at ``m0`` across and inside the Jacobian's range."""
    with body.fresh():
        repeats = np.asarray(body.sense(np.repeat(m0[None], REPEATS, axis=0)), dtype=float)
        _, jac, _ = sensory_jacobian(body, m0[None], fd_step)
    u, singular, _ = np.linalg.svd(jac[0], full_matrices=False)
    deviation = repeats - repeats.mean(axis=0)
    inside = deviation @ u[:, :rank]
    dof, n_sensors = REPEATS - 1, repeats.shape[1]
    across = (np.sum(deviation ** 2) - np.sum(inside ** 2)) / (dof * (n_sensors - rank))
    # Inside: s_i^2 motor_sd^2 + across along each direction i; the strong
    # directions carry the joints' share (the weak ones mostly the receptors').
    joints = (np.sum(inside ** 2) / dof - rank * across) / np.sum(singular[:rank] ** 2)
    return {"sd_all": float(np.sqrt(np.sum(deviation ** 2) / (dof * n_sensors))),
            "sd_across": float(np.sqrt(across)), "motor_sd": float(np.sqrt(max(joints, 0.0))),
            "singular": singular[:rank].round(5).tolist()}


def patch(rank_floor: bool, precision: bool, whiten: bool = False) -> None:
    measure, judge, floor = NaiveAgent._measure_body, confirm_mod._judge, \
        SearchAndSample._pinning_floor

    def measure_body(self, m0, seed):
        m0 = measure(self, m0, seed)
        if not self._noisy:
            return m0
        SPLIT.update(split_noise(self._body, m0, self.structure.pose_rank, self._fd_step))
        SPLIT["sd_measured"] = float(self.structure.noise)
        SPLIT["clear"] = SPLIT["sd_across"] < 0.5 * SPLIT["sd_all"]
        if SPLIT["clear"] and rank_floor:
            across = replace(self.structure, noise=SPLIT["sd_across"])
            self._across_floor = jacobian_noise(across, self._body.n_sensors, self._fd_step)
            self._tol = replace(self._tol, min_singular=max(
                self.params.min_singular * self.structure.gain, self._across_floor))
        return m0

    def judged(jac, residual, rank, whole, variances, limits, bounds, max_step):
        step, explained, settled = judge(jac, residual, rank, whole, variances, limits,
                                         bounds, max_step)
        if not ((precision or whiten) and SPLIT.get("clear")):
            return step, explained, settled
        # The same test without its isotropic precision bound, then the split's bound:
        # the pose error of n sensings, sqrt(n (sd_across^2 / s_r^2 + motor_sd^2)).
        _, loose, loose_settled = judge(jac, residual, rank, whole, variances, limits,
                                        (np.inf, bounds[1]), max_step)
        u, singular, _ = np.linalg.svd(jac, full_matrices=False)
        sensings = [v / SPLIT["sd_measured"] ** 2 for v in variances]
        across, joints = SPLIT["sd_across"] ** 2, SPLIT["motor_sd"] ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            within = np.sqrt(sensings[0] * (across / singular[:, rank - 1] ** 2 + joints)) \
                <= bounds[0]
        if not whiten:      # re-decide only the states the isotropic bound refused
            return step, explained | (loose & within), settled | (within & loose_settled)
        explained = loose & within
        if max_step is not None:
            return step, explained, explained & loose_settled
        # Settled: the residual inside the range whitened by the split, along its
        # i-th direction n (sd_across^2 + motor_sd^2 s_i^2).
        along = np.einsum("bsk,bs->bk", u[:, :, :rank], residual)
        with np.errstate(divide="ignore", invalid="ignore"):
            inside = np.sum(along ** 2 / (sensings[1][:, None]
                                          * (across + joints * singular[:, :rank] ** 2)), axis=1)
        return step, explained, explained & (inside <= limits[1])

    def pinning_floor(self):
        return getattr(self, "_across_floor", None) or floor(self)

    NaiveAgent._measure_body = measure_body
    confirm_mod._judge = judged
    SearchAndSample._pinning_floor = pinning_floor


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="config/smoke.yaml")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="/tmp/noise_split")
    for name in ("noise", "laplace", "relative", "motor_noise"):
        parser.add_argument(f"--{name}", type=float, default=0.0)
    parser.add_argument("--rank-floor", action="store_true")
    parser.add_argument("--precision", action="store_true")
    parser.add_argument("--whiten", action="store_true")
    args = vars(parser.parse_args())
    patch(args.pop("rank_floor"), args.pop("precision"), args.pop("whiten"))
    summary = run(args.pop("config"), args.pop("seed"), args.pop("out"),
                  **{k: v for k, v in args.items() if v})
    print(json.dumps({"split": SPLIT}))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
