"""The clearance rows of the posture NLP: each pair's constraint on the waypoints where it is posed.

Pair p is posed at waypoints ``W_p`` (:mod:`problems.posture.clearance_active`); its one-pair
functions (:func:`problems.posture.clearance.pair_functions`: value, Jacobian (1, 6), Hessian) are
mapped over ``X[:, W_p]`` (``casadi.Function.map``), so the NLP evaluates a pair only where it can
come near.  Row order: pair by pair (ascending), each over its waypoints (ascending).  The
Jacobian of the rows is sparse: row (p, k) has its six entries in waypoint k's columns.

Units: constraints in mm (:data:`~problems.posture.clearance.CLEARANCE_SCALE`), joints in rad.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from problems.posture.clearance import CLEARANCE_EXACT_HESSIAN, ClearanceSpec, pair_functions

__all__ = ["ClearanceRows"]


class ClearanceRows:
    """The clearance constraints of a cell posed pair by pair on their waypoints.

    Parameters
    ----------
    spec : ClearanceSpec
    posed : ndarray of bool, shape (P, N)
        Where each pair is posed.
    exact_hessian : bool
        Whether the rows' second derivatives enter the Lagrangian Hessian.

    Attributes
    ----------
    pairs : list of int
        The pairs posed somewhere.
    where : list of ndarray of int
        Each one's waypoints.
    count : int
        Number of rows.
    """

    def __init__(self, spec: ClearanceSpec, posed: np.ndarray, exact_hessian: bool = CLEARANCE_EXACT_HESSIAN) -> None:
        self.spec, self.posed, self.exact_hessian = spec, np.asarray(posed, dtype=bool), bool(exact_hessian)
        self.n = self.posed.shape[1]
        self.pairs = [int(p) for p in np.flatnonzero(self.posed.any(axis=1))]
        self.where = [np.flatnonzero(self.posed[p]) for p in self.pairs]
        self.count = int(sum(len(w) for w in self.where))
        self.fns = pair_functions(spec, self.pairs, exact_hessian)

    def _cols(self, X: ca.MX, w: np.ndarray) -> ca.MX:
        return X if len(w) == self.n else X[:, [int(k) for k in w]]

    def g(self, X: ca.MX) -> ca.MX:
        """The rows (count,) at the joints ``X`` (6, N)."""
        rows = [ca.vec(f["g"].map(len(w))(self._cols(X, w))) for f, w in zip(self.fns, self.where)]
        return ca.vertcat(*rows) if rows else ca.MX(0, 1)

    def jac(self, X: ca.MX) -> tuple[ca.MX, ca.MX]:
        """The rows (count,) and their Jacobian (count, 6 N), sparse, at ``X`` (6, N)."""
        g, blocks = [], []
        for f, w in zip(self.fns, self.where):
            gv, J = f["jac"].map(len(w))(self._cols(X, w))
            rows = np.repeat(np.arange(len(w)), 6)
            cols = (6 * w[:, None] + np.arange(6)[None]).reshape(-1)
            sp = ca.Sparsity.triplet(len(w), 6 * self.n, rows.tolist(), cols.tolist())
            g.append(ca.vec(gv))
            blocks.append(ca.MX(sp, ca.vec(J)))
        if not g:
            return ca.MX(0, 1), ca.MX(0, 6 * self.n)
        return ca.vertcat(*g), ca.vertcat(*blocks)

    def hess(self, X: ca.MX, lam: ca.MX) -> ca.MX | None:
        """The rows' Hessian of ``lam . g`` (``lam`` (count,)) as (6, 6 N) blocks (waypoint k's in
        columns 6k..6k+5, as the stage Hessian's map), or None when left out."""
        if not self.exact_hessian or not self.count:
            return None
        out, start = None, 0
        for f, w in zip(self.fns, self.where):
            H = f["hess"].map(len(w))(self._cols(X, w), ca.reshape(lam[start : start + len(w)], 1, len(w)))
            start += len(w)
            rows = np.arange(6 * len(w))
            cols = (6 * w[:, None] + np.arange(6)[None]).reshape(-1)
            S = ca.DM(ca.Sparsity.triplet(6 * len(w), 6 * self.n, rows.tolist(), cols.tolist()), 1.0)
            H = ca.mtimes(H, S)
            out = H if out is None else out + H
        return out
