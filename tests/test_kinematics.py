"""FK, Jacobian and compliance against independent references:
pinocchio (model built here from the same DH table), CasADi AD, finite differences."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from models import KinematicModel, load_robot
from models.robot import robot_from_dict
from models.symbolic import cartesian_stiffness, directional_stiffness
from models.transforms import rot_x, rot_z, transform

from .conftest import ROBOTS, as_modified_dh, get_model

#: FK and Jacobian agreement with pinocchio (m, rad, dimensionless).
PIN_TOL = 1e-12
#: Jacobian vs central finite differences of FK (step 1e-6 rad): truncation ~1e-12, rounding ~1e-10.
FD_TOL = 1e-8
FD_STEP = 1e-6
N_POSES = 200


def pinocchio_from_dh(robot) -> tuple[pin.Model, int]:
    """Build a pinocchio model from a standard-DH table, independently of our code."""
    model = pin.Model()
    parent = 0
    static_prev = pin.SE3.Identity()
    for i, j in enumerate(robot.joints):
        placement = static_prev * pin.SE3(rot_z(j.theta_offset), np.zeros(3))
        parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i + 1}")
        model.appendBodyToJoint(parent, pin.Inertia.Random(), pin.SE3.Identity())
        # Tz(d) Tx(a) Rx(alpha) of this link
        static_prev = pin.SE3(np.eye(3), np.array([0.0, 0.0, j.d])) * pin.SE3(rot_x(j.alpha), np.array([j.a, 0.0, 0.0]))
    tcp = static_prev * pin.SE3(robot.tcp2flange[:3, :3], robot.tcp2flange[:3, 3])
    fid = model.addFrame(pin.Frame("tcp", parent, 0, tcp, pin.FrameType.OP_FRAME))
    return model, fid


def _robot_with_tool(name: str):
    r = load_robot(name)
    tool = transform(rot_z(0.3) @ rot_x(-0.4), np.array([0.1, -0.02, 0.15]))
    return r.with_tool(tool)


@pytest.mark.parametrize("name", ROBOTS)
@pytest.mark.parametrize("with_tool", [False, True])
def test_fk_and_jacobian_match_pinocchio(name, with_tool, rng):
    robot = _robot_with_tool(name) if with_tool else load_robot(name)
    km = KinematicModel(robot)
    pm, fid = pinocchio_from_dh(robot)
    pd = pm.createData()
    q = rng.uniform(-np.pi, np.pi, (N_POSES, 6))
    T = km.tcp(q)
    J = km.J(q)
    for i in range(N_POSES):
        pin.forwardKinematics(pm, pd, q[i])
        pin.updateFramePlacements(pm, pd)
        oMf = pd.oMf[fid]
        assert np.max(np.abs(T[i, :3, :3] - oMf.rotation)) < PIN_TOL
        assert np.max(np.abs(T[i, :3, 3] - oMf.translation)) < PIN_TOL
        Jp = pin.computeFrameJacobian(pm, pd, q[i], fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        assert np.max(np.abs(J[i] - Jp)) < PIN_TOL


@pytest.mark.parametrize("name", ROBOTS)
def test_jacobian_matches_casadi_ad_and_finite_differences(name, rng):
    robot = _robot_with_tool(name)
    km = KinematicModel(robot)
    q = ca.SX.sym("q", 6)
    T = km.fk_tcp(q)
    jac_p = ca.Function("jp", [q], [ca.jacobian(T[:3, 3], q)])
    R = T[:3, :3]
    for qi in rng.uniform(-np.pi, np.pi, (20, 6)):
        J = np.asarray(km.jacobian(qi))
        assert np.max(np.abs(J[:3] - np.asarray(jac_p(qi)))) < PIN_TOL
        # finite differences: position and rotation (omega from dR R^T)
        R0 = km.tcp(qi)[:3, :3]
        for k in range(6):
            dq = np.zeros(6)
            dq[k] = FD_STEP
            Tp, Tm = km.tcp(qi + dq), km.tcp(qi - dq)
            v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * FD_STEP)
            dR = (Tp[:3, :3] - Tm[:3, :3]) / (2 * FD_STEP)
            W = dR @ R0.T
            w = np.array([W[2, 1], W[0, 2], W[1, 0]])
            assert np.max(np.abs(J[:3, k] - v)) < FD_TOL
            assert np.max(np.abs(J[3:, k] - w)) < FD_TOL
    assert R.shape == (3, 3)


@pytest.mark.parametrize("name", ROBOTS)
def test_compliance_definition_and_deflection(name, rng):
    robot, km, _ = get_model(name)
    q = rng.uniform(-np.pi, np.pi, (50, 6))
    J, C = km.J(q), km.C(q)
    Kinv = np.diag(1.0 / robot.stiffness)
    C_ref = J @ Kinv @ np.swapaxes(J, 1, 2)
    assert np.max(np.abs(C - C_ref)) < 1e-15 + 1e-12 * np.max(np.abs(C_ref))
    assert np.allclose(C, np.swapaxes(C, 1, 2), rtol=0, atol=1e-18)
    assert np.min(np.linalg.eigvalsh(C)) > -1e-15
    F = np.array([5.0, 10.0, 20.0, 0.3, -0.2, 0.1])
    D = km.D(q, F)
    assert np.allclose(D, C @ F, rtol=1e-12, atol=1e-18)
    # Physical meaning: small wrench -> FK displacement of the deflected joints equals C F to 2nd order.
    eps = 1e-3
    dq = Kinv @ np.swapaxes(J, 1, 2) @ (eps * F)
    dp = km.tcp(q + dq)[:, :3, 3] - km.tcp(q)[:, :3, 3]
    assert np.max(np.abs(dp - eps * D[:, :3])) < 1e-3 * np.max(np.abs(eps * D[:, :3]))


def test_directional_and_cartesian_stiffness(rng):
    robot, km, _ = get_model("ar5")
    q = rng.uniform(-np.pi, np.pi, (20, 6))
    C = km.C(q)
    kx = directional_stiffness(C, np.array([2.0, 0.0, 0.0]))
    assert np.allclose(kx, 1.0 / C[:, 0, 0])
    Kx = cartesian_stiffness(C[0])
    assert np.allclose(Kx @ C[0], np.eye(6), atol=1e-8)
    # At a wrist singularity (q5 = 0) the compliance is singular and K_x does not exist.
    q_sing = np.array([0.3, -1.0, 1.2, 0.4, 0.0, 0.2])
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        cartesian_stiffness(km.C(q_sing))


def test_batch_compiled_equals_casadi_vm(rng):
    robot, km, _ = get_model("ur10")
    q = rng.uniform(-np.pi, np.pi, (300, 6))
    p, R, J, C = km.batch(km.kinetostatics, q)
    for i in (0, 17, 299):
        pv, Rv, Jv, Cv = (np.asarray(x) for x in km.kinetostatics(q[i]))
        assert np.allclose(p[i], pv.ravel(), atol=1e-15)
        assert np.allclose(R[i], Rv, atol=1e-15)
        assert np.allclose(J[i], Jv, atol=1e-15)
        assert np.allclose(C[i], Cv, atol=1e-18)
    # broadcasting a single wrench against many poses
    F = np.array([1.0, 2.0, 3.0, 0.0, 0.0, 0.0])
    D = km.batch(km.deflection, q, F)[0]
    assert np.allclose(D, C @ F, atol=1e-18)


def test_modified_dh_equals_standard_dh(rng):
    """The same UR5 written in modified DH gives the same flange pose (conversion documented)."""
    r = load_robot("ur5")
    rm = robot_from_dict(as_modified_dh(r.to_dict()))
    km_s, km_m = KinematicModel(r), KinematicModel(rm)
    q = rng.uniform(-np.pi, np.pi, (100, 6))
    assert np.allclose(km_s.tcp(q), km_m.tcp(q), atol=1e-12)
    assert np.allclose(km_s.J(q), km_m.J(q), atol=1e-12)
