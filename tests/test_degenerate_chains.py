"""Degenerate 6R chains are refused at load, naming the joints and why.

The class (``models/degenerate.py``, ``docs/robot-file.md`` "Degenerate chains"): a chain whose
Jacobian has rank < 6 at every configuration.  Each case below is a member of the class built from
a sound arm by one edit (coaxial joints 2-3, 4-5 or 5-6, all links of zero length, a planar arm,
four parallel axes, a wrist centre on the elbow axis; a DH table in both conventions and a URDF),
and the test first confirms, by an independent finite-difference Jacobian of the DH chain, that it
really is rank-deficient everywhere; then that loading it fails with the one line naming the joints
and the rank.  Sound arms (the built-ins, and near misses a fraction of a millimetre or a milliradian
away from a degenerate one) load.  The CLI (``robot check``, ``map``, ``plan``) gives that line and
exits 2.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from models import BUILTIN_ROBOTS, load_robot
from models.robot import Robot, RobotFileError, robot_from_dict, robot_to_toml
from models.transforms import dh_chain_frames
from planner.cli import main
from tests.conftest import as_modified_dh

#: Finite-difference step of the independent Jacobian (rad) and the singular-value threshold
#: (relative) below which a direction is missing: central differences are good to ~1e-10 here.
FD_STEP = 1e-6
FD_RANK_RTOL = 1e-6
#: Random configurations at which the independent Jacobian is evaluated.
N_CONFIGS = 20

UR5 = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")


def _ur5(**rows: dict) -> dict:
    """The UR5 robot dictionary with some joint rows (1-based ``j2=...``) updated."""
    d = load_robot("ur5").to_dict()
    for key, upd in rows.items():
        d["joints"][int(key[1:]) - 1].update(upd)
    return d


def _all_rows(**upd: float) -> dict:
    d = load_robot("ur5").to_dict()
    for row in d["joints"]:
        row.update(upd)
    return d


def _wrist_on_elbow_axis() -> dict:
    """An ortho-parallel arm (KUKA-like twists) with a3 = d4 = 0: the spherical wrist's centre lies
    on joint 3's axis, so joints 3, 4, 5 and 6 all pass through one point."""
    d = load_robot("ur5").to_dict()
    al = np.radians([-90.0, 0.0, -90.0, 90.0, -90.0, 0.0])
    for row, alpha, a, dd in zip(d["joints"], al, [0.025, 0.455, 0.0, 0.0, 0.0, 0.0], [0.4, 0, 0, 0.0, 0, 0.08]):
        row.update(alpha=float(alpha), a=a, d=dd)
    return d


def _names(*idx: int) -> str:
    items = [f"{i} ({UR5[i - 1]})" for i in idx]
    return "joints " + ", ".join(items[:-1]) + " and " + items[-1]


#: id -> (robot dictionary, what the message must say, the Jacobian's rank everywhere).
DH_CASES = {
    "coaxial_2_3": (_ur5(j2={"a": 0.0}), _names(2, 3) + " turn about one and the same axis line", 5),
    "coaxial_2_3_modified_dh": (
        as_modified_dh(_ur5(j2={"a": 0.0})),
        _names(2, 3) + " turn about one and the same axis line",
        5,
    ),
    "coaxial_4_5": (_ur5(j4={"alpha": 0.0}), _names(4, 5) + " turn about one and the same axis line", 5),
    "coaxial_5_6": (_ur5(j5={"alpha": 0.0}), _names(5, 6) + " turn about one and the same axis line", 5),
    "all_zero_links": (_all_rows(a=0.0, d=0.0), "all 6 joints have axes through one point", 3),
    "planar": (_all_rows(alpha=0.0, a=0.3), "all 6 joints have parallel axes", 3),
    "four_parallel": (_ur5(j4={"alpha": 0.0, "a": 0.1}), _names(2, 3, 4, 5) + " have parallel axes", 5),
    "wrist_on_elbow_axis": (_wrist_on_elbow_axis(), "joints 3 (elbow_joint), 4 (wrist_1_joint), 5", 5),
}

#: Sound arms a small step away from a degenerate one: they must load.
NEAR_MISSES = {
    "a2_0.1mm": _ur5(j2={"a": 1e-4}),
    "alpha5_1mrad": _ur5(j5={"alpha": 1e-3}),
    "wrist_centre_1mm_off_elbow_axis": (lambda d: (d["joints"][3].update(d=1e-3), d)[1])(_wrist_on_elbow_axis()),
}


def _unchecked(d: dict) -> Robot:
    """The robot of a dictionary without the load's checks (to examine a degenerate chain)."""
    base = load_robot("ur5")
    joints = tuple(
        replace(j, a=float(r["a"]), alpha=float(r["alpha"]), d=float(r["d"]), theta_offset=float(r["theta_offset"]))
        for j, r in zip(base.joints, d["joints"])
    )
    return replace(base, convention=d["convention"], joints=joints)


def _fd_rank(robot: Robot, seed: int = 0) -> int:
    """Largest rank of the flange Jacobian (finite differences of the DH chain's flange pose) at
    random configurations: independent of models/degenerate.py (no screws, no axis geometry)."""
    rng = np.random.default_rng(seed)
    args = (robot.convention, robot.a, robot.alpha, robot.d, robot.theta_offset)
    best = 0
    for q in rng.uniform(-np.pi, np.pi, (N_CONFIGS, 6)):
        J = np.zeros((6, 6))
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = FD_STEP
            Tp, Tm = dh_chain_frames(*args, q + dq)[6], dh_chain_frames(*args, q - dq)[6]
            dR = (Tp[:3, :3] - Tm[:3, :3]) / (2 * FD_STEP) @ dh_chain_frames(*args, q)[6][:3, :3].T
            J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * FD_STEP)
            J[3:, i] = [dR[2, 1], dR[0, 2], dR[1, 0]]
        s = np.linalg.svd(J, compute_uv=False)
        best = max(best, int(np.sum(s > FD_RANK_RTOL * s[0])))
    return best


@pytest.mark.parametrize("case", list(DH_CASES))
def test_a_degenerate_dh_chain_is_refused_naming_the_joints(case: str) -> None:
    d, needle, rank = DH_CASES[case]
    assert _fd_rank(_unchecked(d)) == rank  # the premise: rank-deficient everywhere
    with pytest.raises(RobotFileError) as ei:
        robot_from_dict(d, "bad.toml")
    msg = str(ei.value)
    assert msg.startswith("bad.toml: degenerate chain: ") and "\n" not in msg
    assert needle in msg
    assert f"rank {rank} < 6 at every configuration" in msg
    assert "check a, alpha and d of those joints" in msg


@pytest.mark.parametrize("name", list(NEAR_MISSES))
def test_a_sound_chain_near_a_degenerate_one_loads(name: str) -> None:
    d = NEAR_MISSES[name]
    assert _fd_rank(_unchecked(d)) == 6
    robot_from_dict(d, "near.toml")


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_builtins_are_sound(name: str) -> None:
    r = load_robot(name)
    assert _fd_rank(r) == 6


# --------------------------------------------------------------------------------------
# URDF: the same check, the same line, URDF joint names
# --------------------------------------------------------------------------------------

_LIMIT = '<limit lower="-3" upper="3" velocity="2" effort="1"/>'


def _urdf(joints: list[tuple[str, str]]) -> str:
    """A serial URDF of revolute joints given as (origin xyz, axis xyz)."""
    out = ['<robot name="t">', '<link name="base_link"/>']
    prev = "base_link"
    for i, (xyz, axis) in enumerate(joints):
        out.append(f'<link name="l{i + 1}"/>')
        out.append(
            f'<joint name="j{i + 1}" type="revolute"><parent link="{prev}"/><child link="l{i + 1}"/>'
            f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>{_LIMIT}</joint>'
        )
        prev = f"l{i + 1}"
    out.append('<link name="flange"/>')
    out.append(f'<joint name="jf" type="fixed"><parent link="{prev}"/><child link="flange"/></joint></robot>')
    return "\n".join(out)


def _urdf_robot(tmp_path: Path, joints: list[tuple[str, str]]) -> Path:
    (tmp_path / "arm.urdf").write_text(_urdf(joints), encoding="utf-8")
    p = tmp_path / "arm.toml"
    p.write_text(
        'name = "t"\nurdf = "arm.urdf"\nbase_link = "base_link"\ntip_link = "flange"\nstiffness = [1, 1, 1, 1, 1, 1]\n',
        encoding="utf-8",
    )
    return p


_SOUND = [("0 0 0.1", "0 0 1"), ("0 0 0.1", "0 1 0"), ("0 0 0.3", "0 1 0")]
_SOUND += [("0.1 0 0", "0 0 1"), ("0 0 0.1", "0 1 0"), ("0.1 0 0", "0 0 1")]
URDF_CASES = {
    # joint 3 at joint 2's origin about the same axis: one line
    "coaxial_2_3": (_SOUND[:2] + [("0 0 0", "0 1 0")] + _SOUND[3:], "joints 2 (j2) and 3 (j3) turn about one", 5),
    # every origin at the base origin: all axes through one point
    "all_zero_links": (
        [("0 0 0", a) for a in ("0 0 1", "0 1 0", "1 0 0", "0 0 1", "0 1 0", "1 0 0")],
        "all 6 joints have axes through one point",
        3,
    ),
}


def test_the_sound_urdf_loads(tmp_path: Path) -> None:
    load_robot(_urdf_robot(tmp_path, _SOUND))


@pytest.mark.parametrize("case", list(URDF_CASES))
def test_a_degenerate_urdf_chain_is_refused_naming_the_joints(tmp_path: Path, case: str) -> None:
    joints, needle, rank = URDF_CASES[case]
    p = _urdf_robot(tmp_path, joints)
    with pytest.raises(RobotFileError) as ei:
        load_robot(p)
    msg = str(ei.value)
    assert msg.startswith(f"{p}: degenerate chain: ") and needle in msg
    assert f"rank {rank} < 6" in msg and "<axis> and <origin>" in msg


# --------------------------------------------------------------------------------------
# The command line: robot check, map and plan give the same one line, exit 2
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "argv",
    [
        ["robot", "check", "{p}"],
        ["map", "--robot", "{p}", "--out", "{o}"],
        ["plan", "paper_4_4", "--robot", "{p}", "--out", "{o}"],
    ],
    ids=["robot check", "map", "plan"],
)
def test_the_cli_refuses_a_degenerate_robot_at_load(tmp_path: Path, capsys, argv: list[str]) -> None:
    p = tmp_path / "coaxial.toml"
    p.write_text(robot_to_toml(_unchecked(DH_CASES["coaxial_2_3"][0])), encoding="utf-8")
    rc = main([a.format(p=p, o=tmp_path / "out") for a in argv])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"compplan: error: {p}: degenerate chain: {_names(2, 3)} turn about one")
    assert not (tmp_path / "out").exists()
