"""The POVs moved onto one lattice by what their sweep matches measured.

Every POV was placed by a compensation whose pose error the noise left, on
top of the error of the POV it was found from: along the chains of
compensations the POVs drift off the lattice of the world's displacements.
A located sweep match says that POV ``b``, sensed at event ``k``, sits
relative to the object where POV ``a`` sat at the snapshot's event ``k'``;
the two POVs' own averages then differ by ``r = s_k(b) - s_k'(a) = G (pose
error of b - pose error of a) + noise``, with ``G`` the sensation's slope at
that one relative pose in that one light layout. Where the agent sensed the
Jacobians of both sides in their own worlds (``J_b = G P_b`` at ``k``,
``J_a = G P_a`` at ``k'``: one ``G``; a stencil across a jump gives no
slope and ties nothing), moves ``c`` of the POVs' first samples that make
the pair agree satisfy ``r + J_b c_b - J_a c_a = 0``. Every such pair of
the run gives one weighted linear least-squares problem over all POVs
(``relaxed_corrections``). Each POV's move is held to the scale of the
offsets the agent measured (``match_discrepancy``), so that what few pairs
tie (a shift of many POVs together, a POV in one or two pairs) does not
move far on their noise. Matches the agent did not keep never enter it.

A POV is one pose along its loop, so its other samples must move by what
moves that pose. The world at the end pins few loops well enough to sense
that, so the agent reads it from its own POVs instead
(``neighbour_transport``): the neighbouring POVs' loops are the loops of
the neighbouring poses, and the displacement from each sample to the
nearest point of a neighbour's loop is how that sample moves toward the
neighbour's pose. The move of the first sample, fitted by those
displacements there, gives every other sample's by the same combination
(what of it no lattice step holds, a turn of the eye or a step along the
loop, stays); the first sample, the one every pair sensed, moves by its
solved move itself. No motor state is probed.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import block_diag, coo_matrix
from scipy.sparse.linalg import spsolve
from scipy.stats import chi2

from sensorispace_ros.core.motor_loops import wrap_phase
from sensorispace_ros.core.naive.neighbours import curve_distances

__all__ = ["MatchEvidence", "RelaxedPOVs", "loop_displacements", "neighbour_transport",
           "off_loop", "relaxed_corrections"]

# A ridge under the prior, relative to its mean diagonal: what no Jacobian
# measures (each loop's own direction, POVs in no pair) stays put.
RIDGE = 1e-9
# The nearest POVs whose loops carry a POV's move, within this many times
# the POVs' separation.
NEIGHBOURS = 6
NEIGHBOUR_REACH = 2.0
# A stencil whose one-sided differences disagree by more than this share of
# their sum (one side three times the other: ``jacobians.stencil_bend``).
STRAIGHT = 0.5
# Directions of the displacements toward the neighbours weaker than this
# share of the strongest carry none of a correction (``neighbour_transport``).
SPAN = 0.2


@dataclass
class MatchEvidence:
    """What the sweeps' verified matches measured: every POV's first sample
    sensed at an event, averaged, with its Jacobian (``(pov, event) ->
    (jacobian (S, M), mean (S,), variance of the mean per receptor)``), and
    every kept match's POVs, events and the discrepancy measured then.

    A match's residual is the two POVs' own averages, not the snapshot's
    row: a snapshot row pools the sensings of every POV its chain of matches
    joined (``anchors.pooled_sweep``), each with a pose error of its own, so
    it stands between them and its difference understates the pair's."""

    sensed: dict = field(default_factory=dict)
    matches: list = field(default_factory=list)

    def discrepancy(self) -> float:
        """The median over the kept matches of the discrepancy noted with each."""
        return float(np.median([m[4] for m in self.matches])) if self.matches else 0.0

    def note(self, event: int, povs: np.ndarray, jac: np.ndarray, mean: np.ndarray,
             whole: np.ndarray, mean_variance: float, snapshot_event: int, rows: np.ndarray,
             kept: np.ndarray, discrepancy: float) -> None:
        """One snapshot's verified matches at ``event``: POVs ``povs`` (K,)
        sensed with Jacobians ``jac`` and averages ``mean`` (K, S) of
        per-receptor variance ``mean_variance`` (``whole`` where every
        stencil row came back), matching the POVs ``rows`` (K,) of the
        snapshot of ``snapshot_event`` (the ``discrepancy`` measured then);
        the matches ``kept`` enter the problem."""
        for k in np.flatnonzero(whole):
            if np.all(np.isfinite(mean[k])):
                self.sensed[(int(povs[k]), int(event))] = (
                    np.array(jac[k], dtype=float), np.array(mean[k], dtype=float),
                    float(mean_variance))
        for k in np.flatnonzero(np.asarray(kept) & np.asarray(whole)):
            self.matches.append((int(povs[k]), int(event), int(rows[k]), int(snapshot_event),
                                 float(discrepancy)))

    def pairs(self):
        """``(b, a, J_b, J_a, residual, variance)`` of the matches whose two
        sides were both sensed (arrays, K first): the residual ``(K, S)`` of
        their averages, its per-receptor variance ``(K,)`` theirs plus the
        discrepancy."""
        both = [(self.sensed[m[:2]], self.sensed[m[2:4]], m) for m in self.matches
                if m[:2] in self.sensed and m[2:4] in self.sensed]
        if not both:
            return None
        jac_b = np.stack([b[0] for b, _, _ in both])
        jac_a = np.stack([a[0] for _, a, _ in both])
        residual = np.stack([b[1] - a[1] for b, a, _ in both])
        variance = np.array([b[2] + a[2] + m[4] for b, a, m in both])
        return (np.array([m[0] for *_, m in both]), np.array([m[2] for *_, m in both]),
                jac_b, jac_a, residual, variance)


def relaxed_corrections(evidence: MatchEvidence, n_povs: int, n_motors: int,
                        threshold: float = 0.0):
    """``(moves (P, M), justified (P,))``: the moves of the POVs' first samples
    that make every pair of ``evidence`` agree in the least-squares sense
    (module docstring), each POV's move held to the offsets the agent
    measured (a prior: its Jacobians' mean ``J^T J`` over the discrepancy,
    the per-receptor variance matched POVs differ by beyond the noise, so
    that a move few pairs tie stays small); and where the moves lower the
    weighted squared residuals of the POV's own pairs by more than
    ``threshold`` (a likelihood-ratio test). Zeros where no pair ties a POV
    or no discrepancy was measured."""
    pairs, discrepancy = evidence.pairs(), evidence.discrepancy()
    if pairs is None or not discrepancy > 0.0:
        return np.zeros((n_povs, n_motors)), np.zeros(n_povs, dtype=bool)
    b, a, jac_b, jac_a, residual, variance = pairs
    weight = 1.0 / np.sqrt(variance)
    n_pairs, n_sensors = residual.shape
    rows = np.tile(np.repeat(np.arange(n_pairs * n_sensors), n_motors), 2)
    motor = np.tile(np.arange(n_motors), n_pairs * n_sensors)
    columns = np.concatenate([np.repeat(b, n_sensors * n_motors) * n_motors + motor,
                              np.repeat(a, n_sensors * n_motors) * n_motors + motor])
    values = np.concatenate([(jac_b * weight[:, None, None]).ravel(),
                             -(jac_a * weight[:, None, None]).ravel()])
    design = coo_matrix((values, (rows, columns)),
                        shape=(n_pairs * n_sensors, n_povs * n_motors)).tocsr()
    weighted = (residual * weight[:, None]).ravel()
    solved = spsolve((design.T @ design + _prior(b, a, jac_b, jac_a, n_povs, discrepancy)).tocsc(),
                     design.T @ -weighted)
    after = np.sum((weighted + design @ solved).reshape(n_pairs, n_sensors) ** 2, axis=1)
    gain = np.sum(weighted.reshape(n_pairs, n_sensors) ** 2, axis=1) - after
    per_pov = np.zeros(n_povs)
    np.add.at(per_pov, b, gain)
    np.add.at(per_pov, a, gain)
    return np.asarray(solved, dtype=float).reshape(n_povs, n_motors), per_pov > threshold


def _prior(b, a, jac_b, jac_a, n_povs: int, discrepancy: float):
    """The block-diagonal precision of the moves: each POV's mean ``J^T J``
    over ``discrepancy`` (a POV in no pair: a ridge of ``RIDGE``)."""
    n_motors = jac_b.shape[2]
    blocks, counts = np.zeros((n_povs, n_motors, n_motors)), np.zeros(n_povs)
    np.add.at(blocks, b, np.einsum("ksm,ksn->kmn", jac_b, jac_b))
    np.add.at(blocks, a, np.einsum("ksm,ksn->kmn", jac_a, jac_a))
    np.add.at(counts, b, 1.0)
    np.add.at(counts, a, 1.0)
    blocks /= np.maximum(counts, 1.0)[:, None, None] * discrepancy
    scale = float(np.mean(np.trace(blocks, axis1=1, axis2=2))) / n_motors
    blocks += RIDGE * scale * np.eye(n_motors)
    return block_diag(list(blocks), format="csr")


def loop_displacements(loop: np.ndarray, other: np.ndarray) -> np.ndarray:
    """``(N, M)``: from each sample of ``loop`` ``(N, M)`` to the nearest
    point of the closed polyline through ``other``'s samples ``(N', M)``
    (torus of phases)."""
    to_vertex = wrap_phase(other[None, :, :] - loop[:, None, :])
    edge = wrap_phase(np.roll(other, -1, axis=0) - other)
    with np.errstate(invalid="ignore", divide="ignore"):
        along = -np.einsum("nkm,km->nk", to_vertex, edge) / np.sum(edge * edge, axis=1)
    foot = to_vertex + np.clip(np.nan_to_num(along), 0.0, 1.0)[..., None] * edge
    nearest = np.argmin(np.sum(foot * foot, axis=2), axis=1)
    return foot[np.arange(len(loop)), nearest]


def off_loop(samples: np.ndarray, moves: np.ndarray) -> np.ndarray:
    """``(P,)``: how far each POV's first sample of ``samples`` ``(P, N, M)``
    moved by ``moves`` ``(P, M)`` lands from the POV's own loop. A move along
    the loop stays on the POV's pose (what no Jacobian measures, the noise of
    the Jacobians may fill), so only this part changes the pose."""
    moved = samples[:, 0] + moves
    return np.array([np.linalg.norm(loop_displacements(moved[p][None], samples[p])[0])
                     for p in range(len(samples))])


def neighbour_transport(loop: np.ndarray, neighbours: np.ndarray,
                        correction: np.ndarray) -> np.ndarray | None:
    """``(N, M)`` the move of every sample of ``loop`` whose first sample
    should move by ``correction``: the combination of the displacements
    toward ``neighbours``' loops ``(K, N', M)`` that fits ``correction`` at
    the first sample (least squares, least norm, over the directions of
    those displacements at least ``SPAN`` times the strongest: the weaker
    ones are the neighbours' own offsets, and fitting them would move the
    other samples anywhere). None without a neighbour."""
    if not len(neighbours):
        return None
    toward = np.stack([loop_displacements(loop, other) for other in neighbours])
    weights = np.linalg.lstsq(toward[:, 0, :].T, correction, rcond=SPAN)[0]
    return np.einsum("knm,k->nm", toward, weights)


class RelaxedPOVs:
    """The agent's side (a mixin of ``NaiveAgent``, ``naive.relax_povs``,
    where the repeats spread: elsewhere the matches' residuals hold no pose
    error the noise hid): ``_note_verified`` keeps what
    ``SnapshotMatching._verify_matches`` sensed, ``relax_povs`` moves the
    POVs at the end of exploring."""

    def _note_verified(self, snap, before, after, sensed, repeats, kept) -> None:
        """Note one snapshot's verified matches (``sensed``: ``verify_matches``'s
        ``(mean, jac, whole, bend)`` of the POVs ``after``, each averaged
        ``repeats`` times, matching the snapshot's rows ``before``). A POV
        whose stencil bends beyond ``STRAIGHT`` ties no pair: its Jacobian is
        the secant across a jump, not the slope its pose error moves along."""
        if not (self.params.relax_povs and self._repeats > 1):
            return
        if getattr(self, "_match_evidence", None) is None:
            self._match_evidence = MatchEvidence()
        mean, jac, whole, bend = sensed
        self._match_evidence.note(self._event, after, jac, mean, whole & (bend <= STRAIGHT),
                                  self.structure.noise ** 2 / repeats, snap.event, before, kept,
                                  self._discrepancy)

    def relax_povs(self) -> int:
        """Move every POV by ``relaxed_corrections`` where its move explains its
        pairs better than the ``noise_confidence`` quantile of chi-square
        with ``pose_rank`` degrees allows of noise, and lands at most half the
        POVs' separation off its own loop (``off_loop``; beyond, it would not
        correct a pose error but put the POV on another pose): its first
        sample, which every pair sensed, by that move, the other samples by
        ``neighbour_transport``.
        Returns how many POVs moved; ``relaxed_ids`` are which (a second call
        moves nothing more and returns the same)."""
        evidence = getattr(self, "_match_evidence", None)
        if evidence is None:            # kept only with relax_povs (_note_verified), or moved
            self.relaxed_ids = getattr(self, "relaxed_ids", np.zeros(0, dtype=np.int64))
            self.povs_relaxed = len(self.relaxed_ids)
            return self.povs_relaxed
        samples = self._store.samples.copy()
        threshold = chi2.ppf(self.params.noise_confidence, self.structure.pose_rank)
        moves, justified = relaxed_corrections(evidence, *samples.shape[::2], threshold)
        separation = self._store.separation()
        size = off_loop(samples, moves)
        everyone = np.ones(len(samples), dtype=bool)
        shifts = {}
        for pov in np.flatnonzero(justified & (size > 0) & (size <= 0.5 * separation)):
            everyone[pov] = False
            near = self._store.nearest(samples[pov, 0], everyone, NEIGHBOURS)
            everyone[pov] = True
            near = near[curve_distances(samples[pov, 0], samples[near]) <=
                        NEIGHBOUR_REACH * separation]
            shifts[pov] = neighbour_transport(samples[pov], samples[near], moves[pov])
        for pov, shift in shifts.items():
            if shift is not None:
                shift[0] = moves[pov]       # what its pairs measured, a turn of the eye too
                self._store.replace(int(pov), samples[pov] + shift)
        self._match_evidence = None
        self.relaxed_ids = np.array(sorted(int(pov) for pov, shift in shifts.items()
                                           if shift is not None), dtype=np.int64)
        self.povs_relaxed = len(self.relaxed_ids)
        return self.povs_relaxed
