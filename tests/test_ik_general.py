"""General 6R IK (models/ik/general_solver.py) on three synthetic arms:

(a) spherical wrist, axis 2 tilted 20 deg from perpendicular to axis 1, axes 2 and 3
    neither parallel nor perpendicular (EAIK: SPHERICAL_SECOND_TWO_INTERSECTING);
(b) axes 2, 3, 4 parallel, axis 1 tilted 15 deg, wrist axes 5 and 6 not intersecting
    (EAIK: THREE_INNER_PARALLEL, solved with SP6);
(c) a general arm, no parallel or intersecting axes (numeric multi-start).

FK(IK(T)) = T on every returned branch, the generating configuration among them,
solution counts, continuity of the labels and constancy of the guard sign along smooth
paths, the CasADi Jacobian against finite differences, singular and bad inputs.
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import pytest

from models.constants import IK_ROUNDTRIP_TOL
from models.errors import InputError
from models.ik.general_numeric import arm_length_scale, general_guard_factors, poe_jacobian_sx
from models.ik.general_solver import (
    EAIK_MAX_BRANCHES,
    NUMERIC_MAX_BRANCHES,
    NUMERIC_N_STARTS,
    GeneralIK,
    GeneralIKStatus,
)
from models.transforms import poe_fk, rotation_angle, rotvec_to_matrix

#: The generating configuration is "among the branches" when some branch is within this (rad).
SAME_CONFIG_TOL = 1e-8
#: Largest joint step (rad) of a tracked branch between consecutive poses of a smooth path.
STEP_TOL = 0.1
#: |guard| above this: away from singularities (typical |guard| ~ 3e-3 for these arms).
GUARD_MARGIN = 2e-4
#: Central finite-difference step (rad) and the agreement expected of the Jacobian.
FD_STEP, FD_TOL = 1e-6, 1e-8
N_EAIK_POSES = 300
N_NUMERIC_POSES = 12


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _arm_a() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    tilt = np.deg2rad(20.0)
    w = np.array(
        [[0, 0, 1], [0, np.cos(tilt), np.sin(tilt)], _unit([0.2, 1, -0.1]), [1, 0, 0], [0, 1, 0], [1, 0, 0]],
        dtype=float,
    )
    c = np.array([0.55, 0.05, 0.7])  # wrist centre
    p = np.array([[0, 0, 0], [0.1, 0, 0.4], [0, 0, 0], c, c, c], dtype=float)
    p[2] = p[1] + 0.3 * w[1]  # axis 3 meets axis 2
    M0 = np.eye(4)
    M0[:3, :3] = rotvec_to_matrix(0.3 * _unit([1, 1, 0]))
    M0[:3, 3] = c + [0.1, 0.0, 0.0]
    return w, p, M0


def _arm_b() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    tilt = np.deg2rad(15.0)
    y = [0.0, 1.0, 0.0]
    w = np.array([[0, np.sin(tilt), np.cos(tilt)], y, y, y, [0, 0, 1], _unit([1, 0.3, 0])])
    p = np.array(
        [[0, 0, 0], [0.05, 0.02, 0.35], [0.05, 0.1, 0.85], [0.45, -0.05, 0.85], [0.45, 0.1, 0.85], [0.5, 0.1, 0.7]]
    )
    M0 = np.eye(4)
    M0[:3, :3] = rotvec_to_matrix(0.5 * _unit([0, 1, 1]))
    M0[:3, 3] = [0.6, 0.15, 0.65]
    return w, p, M0


def _arm_c() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    w = np.array(
        [_unit(v) for v in ([0, 0, 1], [0.1, 1, 0.2], [0.05, 1, -0.15], [1, 0.1, 0.2], [0.2, 1, 0.1], [1, -0.2, 0.3])]
    )
    p = np.array(
        [[0, 0, 0], [0.08, 0.0, 0.4], [0.1, 0.05, 0.85], [0.3, -0.04, 0.9], [0.62, 0.06, 0.88], [0.7, -0.02, 0.8]]
    )
    M0 = np.eye(4)
    M0[:3, :3] = rotvec_to_matrix([0.2, -0.3, 0.4])
    M0[:3, 3] = [0.8, 0.03, 0.78]
    return w, p, M0


ARMS = {"a": _arm_a, "b": _arm_b, "c": _arm_c}


@functools.cache
def _ik(name: str) -> GeneralIK:
    return GeneralIK(*ARMS[name]())


def _wrapdiff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)


def _smooth_path(seed: int, n: int, span: float) -> np.ndarray:
    """(n, 6) joint path with smoothstep timing, span (rad) per joint at most."""
    rng = np.random.default_rng(seed)
    qa = rng.uniform(-np.pi, np.pi, 6)
    qb = qa + rng.uniform(-span, span, 6)
    s = np.linspace(0.0, 1.0, n)[:, None]
    return qa + (qb - qa) * (3 * s**2 - 2 * s**3)


def test_methods_and_families():
    a, b, c = _ik("a"), _ik("b"), _ik("c")
    assert (a.kind, a.family) == ("eaik", "6R-SPHERICAL_SECOND_TWO_INTERSECTING")
    assert (b.kind, b.family) == ("eaik", "6R-THREE_INNER_PARALLEL")
    assert c.kind == c.method == "numeric" and "Unknown" in c.family
    assert a.n_branches == b.n_branches == EAIK_MAX_BRANCHES
    assert c.n_branches == NUMERIC_MAX_BRANCHES
    assert c.labels == tuple(f"b{k}" for k in range(1, 17))


@pytest.mark.parametrize("name", ["a", "b"])
def test_eaik_hp_convention_is_the_poe(name):
    """EAIK's own FK of the H-P parameters built here equals the POE (flange rotation I at 0)."""
    w, p, M0 = ARMS[name]()
    ik = _ik(name)
    q = np.random.default_rng(1).uniform(-np.pi, np.pi, (20, 6))
    T_eaik = np.array([ik._eaik.fwdKin(qi) for qi in q])
    T_eaik[:, :3, :3] = T_eaik[:, :3, :3] @ M0[:3, :3]
    assert np.abs(T_eaik - poe_fk(w, p, M0, q)).max() < 1e-12


@pytest.mark.parametrize("name", ["a", "b", "c"])
def test_roundtrip_and_generating_configuration(name):
    w, p, M0 = ARMS[name]()
    ik = _ik(name)
    n = N_EAIK_POSES if ik.method == "eaik" else N_NUMERIC_POSES
    q = np.random.default_rng(7).uniform(-np.pi, np.pi, (n, 6))
    T = poe_fk(w, p, M0, q)
    res = ik.solve(T)
    K = ik.n_branches
    assert res.q.shape == (n, K, 6) and res.status.shape == (n, K) and res.labels == ik.labels
    present = ~np.isnan(res.q[..., 0])
    assert np.array_equal(present, res.status != GeneralIKStatus.UNREACHABLE.code)
    assert np.all(res.q[present] > -np.pi) and np.all(res.q[present] <= np.pi)
    # every returned branch reproduces the target
    Tq = poe_fk(w, p, M0, res.q[present])
    Tt = np.broadcast_to(T[:, None], (n, K, 4, 4))[present]
    assert np.linalg.norm(Tq[:, :3, 3] - Tt[:, :3, 3], axis=1).max() <= IK_ROUNDTRIP_TOL
    assert rotation_angle(Tq[:, :3, :3], Tt[:, :3, :3]).max() <= IK_ROUNDTRIP_TOL
    # the configuration that made T is one of the branches (mod 2 pi)
    d = np.max(_wrapdiff(res.q, q[:, None, :]), axis=2)  # NaN where absent
    assert np.all(np.nanmin(d, axis=1) < SAME_CONFIG_TOL)
    # distinct branches; a generic pose has an even number of real solutions
    count = present.sum(axis=1)
    assert np.all(count >= 1) and np.all(count <= K)
    assert np.all(count[~np.any(res.status == GeneralIKStatus.SINGULAR.code, axis=1)] % 2 == 0)
    for i in range(n):
        qi = res.q[i, present[i]]
        dd = np.max(_wrapdiff(qi[:, None], qi[None]), axis=2) + np.eye(len(qi))
        assert dd.min() > SAME_CONFIG_TOL
    if ik.method == "eaik":
        assert res.complete and res.n_starts is None and set(np.unique(count)) <= {2, 4, 6, 8}
    else:
        assert not res.complete and "may have missed a branch" in res.note
        assert np.all(res.n_starts[present] >= 1) and np.all(res.n_starts[~present] == 0)
        assert np.all(res.n_starts.sum(axis=1) <= NUMERIC_N_STARTS)


@pytest.mark.parametrize("name", ["a", "b"])
def test_eaik_branch_set_equals_numeric_multistart(name):
    """The closed form finds exactly the solutions the 128-start LM finds (completeness check)."""
    w, p, M0 = ARMS[name]()
    q = np.random.default_rng(3).uniform(-np.pi, np.pi, (6, 6))
    T = poe_fk(w, p, M0, q)
    exact = _ik(name).solve(T, track=False)
    numeric = GeneralIK(w, p, M0, method="numeric").solve(T, track=False)
    assert numeric.method == "numeric"
    for i in range(len(T)):
        A = exact.q[i][exact.status[i] != GeneralIKStatus.UNREACHABLE.code]
        B = numeric.q[i][numeric.status[i] != GeneralIKStatus.UNREACHABLE.code]
        d = np.max(_wrapdiff(A[:, None], B[None]), axis=2)
        assert len(A) == len(B) and np.all(d.min(axis=1) < SAME_CONFIG_TOL)


@pytest.mark.parametrize("name,seed", [("a", 0), ("a", 5), ("b", 2), ("b", 3), ("c", 0)])
def test_labels_continuous_and_guard_sign_constant_along_path(name, seed):
    w, p, M0 = ARMS[name]()
    ik = _ik(name)
    n = 300 if ik.method == "eaik" else 40
    q = _smooth_path(seed, n, 0.6)
    res = ik.solve(poe_fk(w, p, M0, q))
    regular = (res.status == GeneralIKStatus.OK.code) & (np.abs(res.guard) > GUARD_MARGIN)
    both = regular[1:] & regular[:-1]
    assert both.sum() >= n  # the check is not vacuous
    step = np.max(_wrapdiff(res.q[1:], res.q[:-1]), axis=2)
    assert step[both].max() < STEP_TOL
    assert np.all(np.sign(res.guard[1:])[both] == np.sign(res.guard[:-1])[both])
    # the generating configuration stays in one slot along the path
    d = np.max(_wrapdiff(res.q, q[:, None, :]), axis=2)
    slot = np.argmin(np.where(np.isnan(d), np.inf, d), axis=1)
    if np.all(np.abs(general_guard_factors(w, p, M0, q)) > GUARD_MARGIN):
        assert len(set(slot.tolist())) == 1


@pytest.mark.parametrize("name", ["a", "c"])
def test_guard_factor_sx_numpy_and_jacobian(name):
    w, p, M0 = ARMS[name]()
    qs = ca.SX.sym("q", 6)
    g_sx = general_guard_factors(w, p, M0, qs)
    assert isinstance(g_sx, ca.SX) and g_sx.shape == (1, 1)
    f = ca.Function("g", [qs], [g_sx])
    q = np.random.default_rng(11).uniform(-np.pi, np.pi, (4, 5, 6))
    g_np = general_guard_factors(w, p, M0, q)
    assert g_np.shape == (4, 5, 1)
    g_ref = np.array([float(f(qi)) for qi in q.reshape(-1, 6)]).reshape(4, 5, 1)
    assert np.allclose(g_np, g_ref, rtol=1e-9, atol=1e-15)
    # det J is dimensionless after / L^3, and J matches finite differences of the POE FK
    L = arm_length_scale(w, p, M0)
    fJ = ca.Function("J", [qs], [poe_jacobian_sx(w, p, M0, qs)])
    for qi in q.reshape(-1, 6)[:5]:
        J = np.asarray(fJ(qi))
        assert np.isclose(np.linalg.det(J) / L**3, general_guard_factors(w, p, M0, qi)[0])
        for j in range(6):
            dq = np.zeros(6)
            dq[j] = FD_STEP
            Tp, Tm = poe_fk(w, p, M0, qi + dq), poe_fk(w, p, M0, qi - dq)
            v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * FD_STEP)
            dR = (Tp[:3, :3] - Tm[:3, :3]) / (2 * FD_STEP) @ poe_fk(w, p, M0, qi)[:3, :3].T
            omega = np.array([dR[2, 1], dR[0, 2], dR[1, 0]])
            assert np.allclose(J[:, j], np.r_[v, omega], atol=FD_TOL)


def test_singular_wrist_reported_singular():
    """Axes 4 and 6 of arm (a) coincide at q5 = 0: the branch is returned with status 3."""
    w, p, M0 = _arm_a()
    q = np.array([0.3, -0.5, 0.8, 0.4, 0.0, -0.2])
    assert abs(general_guard_factors(w, p, M0, q)[0]) < 1e-15
    res = _ik("a").solve(poe_fk(w, p, M0, q))
    singular = res.status[0] == GeneralIKStatus.SINGULAR.code
    assert singular.sum() == 1
    assert np.all(np.abs(res.guard[0][res.status[0] == GeneralIKStatus.OK.code]) > GUARD_MARGIN)
    assert res.valid.sum() == 6


def test_bad_inputs():
    w, p, M0 = _arm_a()
    with pytest.raises(InputError):
        GeneralIK(w * 2.0, p, M0)
    with pytest.raises(InputError):
        GeneralIK(w[:5], p[:5], M0)
    with pytest.raises(InputError):
        GeneralIK(w, p, M0, method="fast")
    with pytest.raises(InputError):
        _ik("a").solve(np.eye(3))
    empty = _ik("a").solve(np.zeros((0, 4, 4)))
    assert empty.q.shape == (0, EAIK_MAX_BRANCHES, 6)
