"""OPW closed-form IK (models/ik/opw_closed_form.py): structure detection and canonical parameters
(KUKA KR 6 R900 sixx, ABB IRB 2400), FK(IK(T)) = T on every branch, the branch set
against py_opw_kinematics, branch guards, refusals and statuses."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import RigidTransform, Rotation

from models.errors import InputError
from models.ik import IKStatus
from models.ik.opw_closed_form import (
    OPW_BRANCH_LABELS,
    NotOPW,
    OPWGeometry,
    OPWStatus,
    opw_branch_signs,
    opw_canonical_fk,
    opw_guard_factors,
    opw_ik,
    opw_ik_function,
)
from models.ik.opw_detect import opw_from_axes, poe_fk

#: Extracted parameters vs published ones (m, rad).
PARAM_TOL = 1e-12
#: Canonical FK (with the mapping) vs PoE FK: matrix entries (rotation; positions in m).
FK_TOL = 1e-10
#: FK(IK(T)) vs T: positions (m) and rotation-matrix entries.
ROUNDTRIP_TOL = 1e-10
#: The generating configuration among the branches, per wrapped joint (rad).
SAME_Q_TOL = 1e-8
#: Agreement with py_opw_kinematics, per wrapped joint (rad).
PYOPW_TOL = 1e-8
#: Guard factors smaller than this in magnitude are too near a singularity for a sign test.
GUARD_MARGIN = 1e-6
#: Shoulder-wrist lines flatter than this horizontal extent (m) are skipped in the elbow test.
LINE_MIN_DX = 0.05
#: The CasADi and NumPy guard factors agree to rounding.
GUARD_SX_TOL = 1e-15
#: Random poses are mostly away from every limit of reach: at least this share of branches is OK.
MIN_OK_FRACTION = 0.9
#: Random joint range (rad): +-170 deg.
Q_RANGE = np.radians(170.0)
N_ROUNDTRIP = 2000
N_PYOPW = 500

# URDF joints (origin relative to the previous link frame, axis), zero rotations.
KR6_URDF = [
    ((0, 0, 0.400), (0, 0, -1)),
    ((0.025, 0, 0), (0, 1, 0)),
    ((0.455, 0, 0), (0, 1, 0)),
    ((0, 0, 0.035), (-1, 0, 0)),
    ((0.420, 0, 0), (0, 1, 0)),
    ((0.080, 0, 0), (-1, 0, 0)),
]
IRB2400_URDF = [
    ((0, 0, 0), (0, 0, 1)),
    ((0.1, 0, 0.615), (0, 1, 0)),
    ((0, 0, 0.705), (0, 1, 0)),
    ((0.258, 0, 0.135), (1, 0, 0)),
    ((0.497, 0, 0), (0, 1, 0)),
    ((0.085, 0, 0), (1, 0, 0)),
]
KR6_PARAMS = dict(a1=0.025, a2=-0.035, b=0.0, c1=0.400, c2=0.455, c3=0.420, c4=0.080)
KR6_SIGNS = (-1, 1, 1, -1, 1, -1)
KR6_OFFSETS_OPW = (0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0)  # phi = sign * q - offset
IRB2400_PARAMS = dict(a1=0.100, a2=-0.135, b=0.0, c1=0.615, c2=0.705, c3=0.755, c4=0.085)
IRB2400_OFFSETS_OPW = (0.0, 0.0, -np.pi / 2, 0.0, 0.0, 0.0)
#: KUKA tool0 ($FLANGE) is link_6 turned by Ry(90 deg).
KR6_TOOL0 = Rotation.from_euler("y", 90, degrees=True).as_matrix()


def _urdf_chain(joints, flange_rot=None):
    """PoE data (w, p, M0) of a URDF chain with zero joint rotations."""
    T, w, p = np.eye(4), [], []
    for xyz, axis in joints:
        A = np.eye(4)
        A[:3, 3] = xyz
        T = T @ A
        w.append(T[:3, :3] @ np.asarray(axis, float))
        p.append(T[:3, 3].copy())
    M0 = T.copy()
    M0[:3, :3] = T[:3, :3] @ (np.eye(3) if flange_rot is None else flange_rot)
    return np.array(w), np.array(p), M0


def _canonical_chain(params, signs, offsets_opw):
    """PoE data of a canonical OPW arm whose q = 0 is phi = -offsets_opw (opw convention)."""
    o = -np.asarray(offsets_opw, float)
    Rz = lambda a: Rotation.from_rotvec([0, 0, a]).as_matrix()  # noqa: E731 - a one-line helper local to this test
    Ry = lambda a: Rotation.from_rotvec([0, a, 0]).as_matrix()  # noqa: E731 - a one-line helper local to this test
    a1, a2, b, c1, c2, c3 = (params[k] for k in ("a1", "a2", "b", "c1", "c2", "c3"))
    R1 = Rz(o[0])
    s2p = R1 @ np.array([a1, 0, c1])
    s3p = s2p + R1 @ Ry(o[1]) @ np.array([0, 0, c2])
    C = s3p + R1 @ Ry(o[1] + o[2]) @ np.array([a2, b, c3])
    R3 = R1 @ Ry(o[1] + o[2])
    R4 = R3 @ Rz(o[3])
    R5 = R4 @ Ry(o[4])
    ez, ey = np.array([0, 0, 1.0]), np.array([0, 1.0, 0])
    w = np.array([ez, R1 @ ey, R1 @ ey, R3 @ ez, R4 @ ey, R5 @ ez]) * np.asarray(signs, float)[:, None]
    p = np.array([np.zeros(3), s2p, s3p, C, C, C])
    g = OPWGeometry(
        **params, signs=np.ones(6), offsets=np.zeros(6), canon2base=np.eye(4), flange2canon_flange=np.eye(4), scale=1.0
    )
    return w, p, opw_canonical_fk(g, o[None])[0]


def _transformed(chain, base, flips):
    """The chain seen from another base frame (``base``: old base -> new base) with some axes reversed."""
    w, p, M0 = chain
    s = np.where(flips, -1.0, 1.0)[:, None]
    return (w @ base[:3, :3].T) * s, p @ base[:3, :3].T + base[:3, 3], base @ M0


def _random_base(rng):
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-1, 1, 3)
    return T


def _wrapdiff(a, b):
    return np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)


CHAINS = {
    "kr6": lambda: _urdf_chain(KR6_URDF, KR6_TOOL0),
    "irb2400": lambda: _urdf_chain(IRB2400_URDF),
    "irb2400_canonical": lambda: _canonical_chain(IRB2400_PARAMS, (1,) * 6, IRB2400_OFFSETS_OPW),
}


# ----------------------------------------------------------------------------- extraction


@pytest.mark.parametrize("name", ["kr6", "irb2400"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_canonical_fk_matches_poe(name, seed):
    rng = np.random.default_rng(seed)
    flips = rng.random(6) < 0.5
    chain = _transformed(CHAINS[name](), _random_base(rng), flips)
    g = opw_from_axes(*chain)
    q = rng.uniform(-np.pi, np.pi, (200, 6))
    T = poe_fk(*chain, q)
    Tc = g.canon2base @ opw_canonical_fk(g, q * g.signs + g.offsets) @ g.flange2canon_flange
    assert np.abs(Tc - T).max() < FK_TOL
    assert np.abs(g.fk(q) - T).max() < FK_TOL
    assert g.a1 >= 0 and g.c2 > 0 and g.c3 > 0 and g.c4 >= 0
    assert g.canon2base[2, 2] >= 0  # canonical z not pointing down
    assert np.all(np.abs(g.offsets[3:5]) <= np.pi / 2 + PARAM_TOL)


@pytest.mark.parametrize(
    "name, params, signs, offsets",
    [
        ("kr6", KR6_PARAMS, KR6_SIGNS, KR6_OFFSETS_OPW),
        ("irb2400", IRB2400_PARAMS, (1,) * 6, IRB2400_OFFSETS_OPW),
        ("irb2400_canonical", IRB2400_PARAMS, (1,) * 6, IRB2400_OFFSETS_OPW),
    ],
)
@pytest.mark.parametrize("flip", [None, 0, 1, 2, 3, 4, 5])
def test_published_parameters(name, params, signs, offsets, flip):
    flips = np.zeros(6, bool)
    if flip is not None:
        flips[flip] = True  # a reversed axis only reverses that joint's sign
    g = opw_from_axes(*_transformed(CHAINS[name](), np.eye(4), flips))
    got = g.opw_parameters()
    for key, value in params.items():
        assert abs(got[key] - value) < PARAM_TOL, key
    assert got["sign_corrections"] == tuple(int(s) for s in np.where(flips, -1, 1) * signs)
    assert np.abs(_wrapdiff(np.array(got["offsets"]), np.array(offsets))).max() < PARAM_TOL
    assert np.abs(g.offsets + np.array(offsets)).max() < PARAM_TOL  # ours: phi = s q + o


def test_kr6_flange_is_canonical_flange():
    g = opw_from_axes(*CHAINS["kr6"]())
    assert np.abs(g.canon2base - np.eye(4)).max() < PARAM_TOL
    assert np.abs(g.flange2canon_flange - np.eye(4)).max() < PARAM_TOL


def test_not_opw_ur5_like():
    # UR5 at q = 0: axes 2, 3, 4 parallel.
    w = np.array([[0, 0, 1], [0, 1, 0], [0, 1, 0], [0, 1, 0], [0, 0, -1], [0, 1, 0]], float)
    p = np.array(
        [[0, 0, 0], [0, 0, 0.0892], [-0.425, 0, 0.0892], [-0.817, 0, 0.0892], [-0.817, 0.109, 0], [-0.817, 0, -0.0055]]
    )
    M0 = np.eye(4)
    M0[:3, 3] = (-0.817, 0.191, -0.0055)
    with pytest.raises(NotOPW, match=r"axes 3 and 4 are not perpendicular \(angle 0 rad") as err:
        opw_from_axes(w, p, M0)
    assert isinstance(err.value, InputError)


@pytest.mark.parametrize("joint, match", [(5, "axes 4, 5 and 6 do not meet"), (4, "axes 4 and 5 do not intersect")])
def test_not_opw_wrist_axes_do_not_meet(joint, match):
    w, p, M0 = CHAINS["kr6"]()
    p = p.copy()
    p[joint] += (0.0, 0.0, 0.001)  # 1 mm off the wrist centre
    with pytest.raises(NotOPW, match=match + r".*0\.001 m"):
        opw_from_axes(w, p, M0)


def test_not_opw_parallel_and_coincident():
    w, p, M0 = CHAINS["kr6"]()
    w2 = w.copy()
    w2[2] = Rotation.from_rotvec([0.31, 0, 0]).apply(w[2])
    with pytest.raises(NotOPW, match=r"axes 2 and 3 are not parallel \(angle 0\.31 rad\)"):
        opw_from_axes(w2, p, M0)
    p2 = p.copy()
    p2[2] = p[1] + (0, 0.2, 0)
    with pytest.raises(NotOPW, match="axes 2 and 3 coincide"):
        opw_from_axes(w, p2, M0)


# ----------------------------------------------------------------------------- closed form


def _solve(name, n, seed, base=None):
    rng = np.random.default_rng(seed)
    chain = CHAINS[name]()
    if base is not None:
        chain = _transformed(chain, base, np.zeros(6, bool))
    g = opw_from_axes(*chain)
    q = rng.uniform(-Q_RANGE, Q_RANGE, (n, 6))
    T = poe_fk(*chain, q)
    Q, st = opw_ik(opw_ik_function(g), T)
    return chain, g, q, T, Q, st


@pytest.mark.parametrize("name", ["kr6", "irb2400"])
def test_roundtrip_every_branch(name):
    base = _random_base(np.random.default_rng(7)) if name == "irb2400" else None
    chain, g, q, T, Q, st = _solve(name, N_ROUNDTRIP, 11, base)
    assert Q.shape == (N_ROUNDTRIP, 8, 6) and st.shape == (N_ROUNDTRIP, 8)
    assert np.all(np.isfinite(Q))
    assert np.all((Q > -np.pi) & (Q <= np.pi))
    ok = st == OPWStatus.OK.code
    assert ok.sum() > MIN_OK_FRACTION * ok.size
    Tb = poe_fk(*chain, Q[ok])
    Tt = np.broadcast_to(T[:, None], (N_ROUNDTRIP, 8, 4, 4))[ok]
    assert np.abs(Tb[:, :3, 3] - Tt[:, :3, 3]).max() < ROUNDTRIP_TOL
    assert np.abs(Tb[:, :3, :3] - Tt[:, :3, :3]).max() < ROUNDTRIP_TOL
    d = np.where(ok, _wrapdiff(Q, q[:, None, :]).max(axis=-1), np.inf)
    assert d.min(axis=1).max() < SAME_Q_TOL


def test_branch_set_matches_py_opw_kinematics():
    from py_opw_kinematics import KinematicModel, Robot

    km = KinematicModel(**KR6_PARAMS, offsets=KR6_OFFSETS_OPW, flip_axes=tuple(s < 0 for s in KR6_SIGNS))
    robot = Robot(km, degrees=False)
    chain, g, q, T, Q, st = _solve("kr6", N_PYOPW, 5)
    # Same robot, same flange frame: its FK is the URDF chain's.
    assert np.abs(robot.batch_forward(q).as_matrix() - T).max() < FK_TOL
    theirs = robot.reach(RigidTransform.from_matrix(T)).joints  # (n, 8, 6), NaN = none
    counts = []
    for i in range(N_PYOPW):
        mine = Q[i][st[i] == OPWStatus.OK.code]
        other = theirs[i][~np.isnan(theirs[i]).any(axis=1)]
        assert len(mine) == len(other) >= 4
        counts.append(len(mine))
        d = _wrapdiff(mine[:, None, :], other[None, :, :]).max(axis=-1)
        assert d.min(axis=1).max() < PYOPW_TOL and d.min(axis=0).max() < PYOPW_TOL
    assert set(counts) == {4, 8}  # the back branches are out of reach for some poses


def test_guard_signs_identify_branches():
    chain, g, q, T, Q, st = _solve("irb2400", 500, 13)
    f = opw_guard_factors(g, Q)  # (n, 8, 3)
    clear = (st == OPWStatus.OK.code)[..., None] & (np.abs(f) > GUARD_MARGIN)
    expected = np.broadcast_to(opw_branch_signs()[None], f.shape)
    assert clear.mean() > MIN_OK_FRACTION
    assert np.all(np.sign(f)[clear] == expected[clear])
    # The generating configuration's signs name the branch it is found in.
    d = np.where(st == OPWStatus.OK.code, _wrapdiff(Q, q[:, None, :]).max(axis=-1), np.inf)
    branch = d.argmin(axis=1)
    fq = opw_guard_factors(g, q)
    sure = (np.abs(fq) > GUARD_MARGIN).all(axis=1)
    assert np.all(np.sign(fq[sure]) == opw_branch_signs()[branch[sure]])
    # The CasADi form is the same function.
    qs = ca.SX.sym("q", 6)
    fsx = ca.Function("guards", [qs], [opw_guard_factors(g, qs)])
    assert np.abs(np.asarray(fsx(q[0])).ravel() - fq[0]).max() < GUARD_SX_TOL


def test_elbow_up_is_above_the_shoulder_wrist_line():
    chain, g, q, T, Q, st = _solve("kr6", 500, 17)
    phi = Q * g.signs + g.offsets
    p2, p23 = phi[..., 1], phi[..., 1] + phi[..., 2]
    sx, sz = g.a1, g.c1  # shoulder, arm plane
    ex, ez = sx + g.c2 * np.sin(p2), sz + g.c2 * np.cos(p2)  # elbow
    wx = ex + g.c3 * np.sin(p23) + g.a2 * np.cos(p23)  # wrist centre
    wz = ez + g.c3 * np.cos(p23) - g.a2 * np.sin(p23)
    usable = (st == OPWStatus.OK.code) & (np.abs(wx - sx) > LINE_MIN_DX)
    front = np.arange(8)[None, :] < 4
    usable &= ~front | (wx > sx)  # front: wrist ahead of the shoulder
    above = ez > sz + (wz - sz) * (ex - sx) / np.where(usable, wx - sx, 1.0)
    up = np.isin(np.arange(8), [0, 1, 4, 5])[None, :].repeat(len(q), 0)
    assert usable.sum() > 1000
    assert np.all(above[usable] == up[usable])
    assert OPW_BRANCH_LABELS[0] == "front-up-noflip" and OPW_BRANCH_LABELS[7] == "back-down-flip"


# ----------------------------------------------------------------------------- statuses


def test_far_target_elbow_unreachable():
    g = opw_from_axes(*CHAINS["kr6"]())
    T = np.eye(4)
    T[:3, 3] = (5.0, 1.0, 2.0)
    Q, st = opw_ik(opw_ik_function(g), T)
    assert np.all(st == OPWStatus.ELBOW_UNREACHABLE.code)
    assert np.all(np.isfinite(Q))


def test_wrist_singular_pose():
    chain = CHAINS["kr6"]()
    g = opw_from_axes(*chain)
    q = np.array([0.3, -0.9, 0.4, 0.7, 0.0, -0.2])
    q[4] = -g.offsets[4] * g.signs[4]  # phi5 = 0
    T = poe_fk(*chain, q)
    Q, st = opw_ik(opw_ik_function(g), T)
    singular = np.flatnonzero(st[0] == OPWStatus.WRIST_SINGULAR.code)
    assert len(singular) >= 2
    # Still a valid solution: it reproduces the pose, with joint 4 at 0 on "noflip".
    assert np.abs(poe_fk(*chain, Q[0, singular]) - T).max() < ROUNDTRIP_TOL
    assert np.any(np.abs(Q[0, singular, 3]) < ROUNDTRIP_TOL)


def test_shoulder_singular_and_unreachable():
    g = opw_from_axes(*CHAINS["kr6"]())
    Tc = np.eye(4)
    Tc[:3, 3] = (0.0, 0.0, 1.0 + g.c4)  # wrist centre on axis 1
    T = g.canon2base @ Tc @ g.flange2canon_flange
    Q, st = opw_ik(opw_ik_function(g), T)
    assert np.all(st == OPWStatus.SHOULDER_SINGULAR.code)
    assert np.abs(g.fk(Q[0]) - T).max() < ROUNDTRIP_TOL
    offset = dict(IRB2400_PARAMS, b=0.1)
    chain = _canonical_chain(offset, (1,) * 6, IRB2400_OFFSETS_OPW)
    g = opw_from_axes(*chain)
    assert abs(g.b - 0.1) < PARAM_TOL
    Tc[:3, 3] = (0.05, 0.0, 1.0 + g.c4)  # 5 cm from axis 1 < |b|
    Q, st = opw_ik(opw_ik_function(g), g.canon2base @ Tc @ g.flange2canon_flange)
    assert np.all(st == OPWStatus.SHOULDER_UNREACHABLE.code)
    assert np.all(np.isfinite(Q))


def test_function_interface():
    g = opw_from_axes(*CHAINS["irb2400"]())
    f = opw_ik_function(g)
    assert f.name() == "opw_ik"
    assert f.name_in() == ["flange2base"] and f.name_out() == ["q", "status"]
    assert f.size_out(0) == (6, 8) and f.size_out(1) == (8, 1)
    assert isinstance(f, ca.Function) and f.is_a("SXFunction")
    cg = ca.CodeGenerator("opw_ik_check.c")
    cg.add(f)
    assert "opw_ik" in cg.dump()
    assert [s.code for s in OPWStatus] == [0, 1, 3, 4, 6]
    assert all(IKStatus(s.value).code == s.code for s in OPWStatus)  # the OPW family stores IK codes
