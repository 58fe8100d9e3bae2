"""Numerical search for singular postures (R = 0) over the whole joint box: R^2 minimised
from random starts and the minima clustered into families up to the mirror phi -> -phi
(:ref:`manipulability`); BLAS on one thread meanwhile (:doc:`/performance`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize
from threadpoolctl import threadpool_limits

from ._validation import check_params, finite_number, flag, integer
from .exceptions import ParameterError, RunInterrupted
from .manipulability import free_joints, r_batch, task_split
from .params import SnakeParams

__all__ = ["MAX_SEED", "MAX_STARTS", "SingularFamily", "SingularSearch",
           "find_singular_postures"]

#: Most random starts of one search (10,000 take minutes at n = 10): the single-linkage
#: clustering of the minima holds starts^2 / 2 distances (10,000 minima: 400 MB).
MAX_STARTS = 10_000
#: Seeds are 32-bit unsigned integers (``0 .. 2**32 - 1``), as NumPy's legacy seeding takes.
MAX_SEED = 2**32 - 1


@dataclass
class SingularFamily:
    """Connected set of minima with R = 0, up to the mirror phi -> -phi.

    Parameters
    ----------
    phi, R, members, straight, low, high
        Representative posture (the member with the smallest R), its R, how many starts
        ended in this family, whether ``phi`` is straight, and per-joint bounds of phi over
        the members (mirror-canonical).
    """

    phi: np.ndarray
    R: float
    members: int
    straight: bool
    low: np.ndarray
    high: np.ndarray

    @property
    def span(self) -> np.ndarray:
        """high - low per joint: joints that vary freely along the family stand out."""
        return self.high - self.low


@dataclass
class SingularSearch:
    """Result of :func:`find_singular_postures`.

    Parameters
    ----------
    params, bound, starts
        The robot searched, the box ``abs(phi_i) <= bound`` [rad], the starts that ran.
    free_joint
        The free joint(s) (the robot's passive joints included), or None.
    R_typical, threshold
        Median R over random postures in the box; R below ``relative * R_typical`` is zero.
    minima_phi, minima_R, families
        Every polished local minimum (one per start); the distinct ones with R <= threshold.
    status, starts_requested
        ``"completed"`` or ``"interrupted"``; the starts asked for (None: ``starts``).
    """

    params: SnakeParams
    bound: float
    starts: int
    free_joint: int | tuple[int, ...] | None
    R_typical: float
    threshold: float
    minima_phi: np.ndarray
    minima_R: np.ndarray
    families: list[SingularFamily] = field(default_factory=list)
    status: str = "completed"
    starts_requested: int | None = None

    @property
    def non_straight(self) -> list[SingularFamily]:
        """Families other than the straight posture."""
        return [f for f in self.families if not f.straight]

    def _smallest_non_straight_R(self, straight_tol: float = 1e-3) -> float:
        """The smallest R among minima with some ``abs(phi_i) > straight_tol`` [rad], or NaN."""
        mask = np.max(np.abs(self.minima_phi), axis=1) > straight_tol
        return float(self.minima_R[mask].min()) if np.any(mask) else float("nan")

    def to_dict(self) -> dict[str, object]:
        """Plain JSON data of the search.

        Returns
        -------
        dict
            Per family ``postures``, ``R``, ``straight``, ``members``, ``span``; settings, status.
        """
        families = self.families
        return {"postures": [f.phi.tolist() for f in families], "R": [f.R for f in families],
                "straight": [f.straight for f in families],
                "members": [f.members for f in families],
                "span": [f.span.tolist() for f in families],
                "R_typical": self.R_typical, "threshold": self.threshold,
                "starts": self.starts, "bound": self.bound,
                "free_joint": (list(self.free_joint) if isinstance(self.free_joint, tuple)
                               else self.free_joint),
                "status": self.status,
                "starts_requested": self.starts_requested or self.starts,
                "smallest_non_straight_R": self._smallest_non_straight_R(),
                "non_straight_singular_exists": bool(self.non_straight)}


def find_singular_postures(params: SnakeParams, *, starts: int = 200, bound: float = np.pi / 2,
                           free_joint: int | Sequence[int] | None = None, seed: int = 0,
                           relative: float = 1e-6, progress: bool = False) -> SingularSearch:
    """Search ``abs(phi_i) <= bound`` for postures with R = 0 from ``starts`` random starts.

    Parameters
    ----------
    params, starts, seed
        The robot; random starts (uniform in the box), 1 .. :data:`MAX_STARTS`; their seed,
        0 .. ``MAX_SEED``.
    bound, free_joint
        Joint limit of the box [rad]; joint(s) free for R~, beside the passive joints.
    relative, progress
        ``R <= relative * (median R of random postures)`` counts as zero; show a progress
        bar on stderr when it is a terminal.

    Returns
    -------
    SingularSearch
        The minima and the families they cluster into.

    Raises
    ------
    RunInterrupted, ParameterError
        On Ctrl-C or SIGTERM (``partial``: the search so far); a bad argument, free joints
        that leave no task, or R zero everywhere.
    """
    check_params(params)
    starts = integer(starts, "starts", low=1, high=MAX_STARTS)
    seed = integer(seed, "seed", low=0, high=MAX_SEED)
    bound = finite_number(bound, "bound")
    if not 0 < bound <= np.pi:
        raise ParameterError(f"bound must lie in (0, pi], got {bound}")
    relative = finite_number(relative, "relative", non_negative=True)
    progress = flag(progress, "progress")
    free = sorted(set(params.passive) | set(free_joints(params.n, free_joint)))
    free_joint = (free[0] if len(free) == 1 else tuple(free)) if free else None
    task_split(params.n, free_joint)  # n large enough for all of them
    free_all = tuple(free)
    with threadpool_limits(limits=1):  # tiny matrices: one BLAS thread (module doc)
        dim = params.n - 1
        rng = np.random.default_rng(seed)
        typical = r_batch(params, rng.uniform(-bound, bound, (2000, dim)), free_all, True)
        scale = float(np.median(typical))
        if not scale > 0:
            raise ParameterError(
                f"R is zero at every posture of this robot (n = {params.n}"
                + (f", joint {free_joint} free" if free_joint else "")
                + "): the coupling block has fewer columns than rows, nothing to search")
        step = 1e-6
        offsets = np.vstack([np.zeros(dim), step * np.eye(dim), -step * np.eye(dim)])

        def objective(phi: np.ndarray) -> tuple[float, np.ndarray]:
            r = r_batch(params, phi[None, :] + offsets, free_all, True)
            f = (r / scale) ** 2
            return float(f[0]), (f[1:dim + 1] - f[dim + 1:]) / (2 * step)

        box = [(-bound, bound)] * dim
        phis, values = np.empty((starts, dim)), np.empty(starts)
        iterator = range(starts)
        if progress:
            from tqdm import tqdm

            iterator = tqdm(iterator, desc="singular search", unit="start", leave=False,
                            disable=None)
        done = 0
        try:
            for i in iterator:
                start = rng.uniform(-bound, bound, dim)
                first = minimize(objective, start, jac=True, method="L-BFGS-B", bounds=box,
                                 options={"maxiter": 400, "ftol": 1e-16, "gtol": 1e-12})
                polish = minimize(objective, first.x, jac=True, method="L-BFGS-B", bounds=box,
                                  options={"maxiter": 400, "ftol": 0.0, "gtol": 1e-16})
                best = polish if polish.fun <= first.fun else first
                phis[i] = best.x
                values[i] = np.sqrt(max(best.fun, 0.0)) * scale
                done = i + 1
        except KeyboardInterrupt as exc:
            if done == 0:
                raise
            partial = _result(params, bound, free_joint, scale, relative * scale, phis[:done],
                              values[:done])
            partial.status, partial.starts_requested = "interrupted", int(starts)
            raise RunInterrupted(f"singular search interrupted after {done} of {starts} starts",
                                 partial=partial) from exc
        return _result(params, bound, free_joint, scale, relative * scale, phis, values)


def _result(params: SnakeParams, bound: float, free_joint: int | tuple[int, ...] | None,
            scale: float, threshold: float, phis: np.ndarray,
            values: np.ndarray) -> SingularSearch:
    """The search over the minima ``phis`` (R ``values``), clustered into families."""
    result = SingularSearch(params, bound, len(values), free_joint, scale, threshold, phis,
                            values)
    zero = values <= threshold
    result.families = _cluster(phis[zero], values[zero])
    return result


def _canonical(phis: np.ndarray) -> np.ndarray:
    """Pick the mirror image (phi or -phi) whose joints 2..n-1 sum is non-negative."""
    signs = np.where(phis[:, 1:].sum(axis=1) < 0, -1.0, 1.0)
    return phis * signs[:, None]


def _cluster(phis: np.ndarray, values: np.ndarray, link: float = 0.3) -> list[SingularFamily]:
    """Single-linkage clusters (max-norm distance ``link``) of mirror-canonical postures."""
    if len(phis) == 0:
        return []
    canon = _canonical(phis)
    if len(phis) == 1:
        labels = np.zeros(1, dtype=int)
    else:
        from scipy.cluster.hierarchy import fcluster, linkage

        labels = fcluster(linkage(canon, method="single", metric="chebyshev"), t=link,
                          criterion="distance")
    families = []
    for label in np.unique(labels):
        members = np.flatnonzero(labels == label)
        best = members[np.argmin(values[members])]
        families.append(SingularFamily(
            phi=canon[best], R=float(values[best]), members=len(members),
            straight=bool(np.max(np.abs(canon[best])) < 1e-3),
            low=canon[members].min(axis=0), high=canon[members].max(axis=0)))
    return sorted(families, key=lambda f: -f.members)
