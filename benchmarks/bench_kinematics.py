"""Batch throughput of FK+J+C and of the all-branch IK, beside pinocchio, ur-analytic-ik and an
independent OPW solver.

Run: ``python benchmarks/bench_kinematics.py [--n 1000000]``.  Prints poses/s
(best of several runs) and the ratios to the references measured in the same run.
Targets on the 2-core reference machine: FK+J+C >= 10x the pinocchio Python loop
and >= 3 M poses/s; UR IK >= 8x the ur-analytic-ik Python loop and >= 0.6 M poses/s;
OPW IK (the KUKA KR 6 R900, all 8 branches, joint limits applied) >= 2x py-opw-kinematics'
batch call (all 8 branches, ``Robot.reach``) on the same poses.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def best_rate(fn, n: int, repeats: int = 5) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return n / best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1_000_000, help="poses per batch")
    ap.add_argument("--n-ref", type=int, default=20_000, help="poses for the Python-loop references")
    args = ap.parse_args()

    import pinocchio as pin
    import ur_analytic_ik

    from models import AnalyticIK, KinematicModel, load_robot

    robot = load_robot("ur5")
    km = KinematicModel(robot)
    ik = AnalyticIK(robot)
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (args.n, 6))
    km.batch(km.kinetostatics, q[:10])  # build / load the compiled code
    fkjc = best_rate(lambda: km.batch(km.kinetostatics, q), args.n)

    # pinocchio reference: same DH table, Python loop over poses, FK + frame Jacobian + C
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.test_kinematics import pinocchio_from_dh

    pm, fid = pinocchio_from_dh(robot)
    pd = pm.createData()
    kinv = np.diag(1.0 / robot.stiffness)
    qr = q[: args.n_ref]

    def pin_loop() -> None:
        for qi in qr:
            pin.forwardKinematics(pm, pd, qi)
            pin.updateFramePlacements(pm, pd)
            J = pin.computeFrameJacobian(pm, pd, qi, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            _ = J @ kinv @ J.T

    pin_rate = best_rate(pin_loop, args.n_ref, repeats=3)

    T = km.tcp(q[: min(args.n, 1_000_000)])
    n_ik = len(T)
    ik.solve(T[:10])
    ik_rate = best_rate(lambda: ik.solve(T), n_ik)
    Tr = [np.ascontiguousarray(t) for t in T[: args.n_ref]]

    def urik_loop() -> None:
        for t in Tr:
            ur_analytic_ik.ur5.inverse_kinematics(t)

    urik_rate = best_rate(urik_loop, args.n_ref, repeats=3)

    print(f"FK+J+C batch (compiled CasADi, {args.n} poses): {fkjc / 1e6:8.3f} M poses/s")
    print(f"pinocchio Python loop (FK + frame J + C):      {pin_rate / 1e6:8.3f} M poses/s")
    print(f"  ratio {fkjc / pin_rate:6.1f}x   (target >= 10x and >= 3 M poses/s)")
    print(f"IK all 8 branches batch ({n_ik} poses):         {ik_rate / 1e6:8.3f} M poses/s")
    print(f"ur-analytic-ik Python loop:                    {urik_rate / 1e6:8.3f} M poses/s")
    print(f"  ratio {ik_rate / urik_rate:6.1f}x   (target >= 8x and >= 0.6 M poses/s)")
    bench_opw(min(args.n, 200_000))


def bench_opw(n: int) -> None:
    """All-branch OPW IK of the shipped KUKA beside py-opw-kinematics' batch call, same poses."""
    import math

    import py_opw_kinematics as pko
    from scipy.spatial.transform import RigidTransform

    from models import KinematicModel, ik_solver, load_robot

    robot = load_robot("kr6_r900")
    km, ik = KinematicModel(robot), ik_solver(robot)
    rng = np.random.default_rng(1)
    q = rng.uniform(np.maximum(robot.q_min, -np.pi), np.minimum(robot.q_max, np.pi), (n, 6))
    T = km.tcp(q)
    ik.solve(T[:10])  # build / load the compiled code
    ours = best_rate(lambda: ik.solve(T), n)
    ref = pko.Robot(
        pko.KinematicModel(
            a1=0.025,
            a2=-0.035,
            b=0.0,
            c1=0.400,
            c2=0.455,
            c3=0.420,
            c4=0.080,
            offsets=(0.0, -math.pi / 2, 0.0, 0.0, 0.0, 0.0),
            flip_axes=(True, False, False, True, False, True),
        ),
        degrees=False,
    )
    RT = RigidTransform.from_matrix(T)
    theirs = best_rate(lambda: ref.reach(RT).joints, n)
    print(f"OPW IK all 8 branches, KR 6 R900 ({n} poses):   {ours / 1e6:8.3f} M poses/s")
    print(f"py-opw-kinematics Robot.reach batch (8 br.):   {theirs / 1e6:8.3f} M poses/s")
    print(f"  ratio {ours / theirs:6.1f}x   (target >= 2x)")


if __name__ == "__main__":
    main()
