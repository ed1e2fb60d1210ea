"""``compplan compensate --targets-frame {nominal,base,measurement}``.

A virtual robot (independent physics, geometric errors, joint compliance) is measured,
identified, and asked to reach targets given in the base frame (registered data: the TCP
lands on them on the truth robot) or in the measurement frame (unregistered data: the
measured point lands on them as the truth instrument sees it).  Base-frame targets of a
model identified from unregistered data give a warning naming the parameters that alias
with the registration; missing or inconsistent targets are input errors.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from models import load_robot
from models.arm_file import model_from_robot, model_toml
from models.errors import InputError
from planner.cli import main as cli_main
from planner.identify_report import report_dict
from problems.compensation import CompensationStatus
from problems.identify import (
    ParameterStatus,
    TargetsError,
    TargetsFrame,
    compensate_targets,
    identify,
    predict,
)
from problems.measurements import Measurements, parse_measurements
from problems.virtual import VirtualRobot

#: Measurement noise of the campaigns (per axis), m.
SIGMA_M = 5e-6
#: The compensated commands land within this of their targets on the truth robot, m.
LANDING_TOL_M = 1e-5
#: Under the identified model itself the measurement-frame compensation is exact to this, m.
MODEL_TOL_M = 1e-9
#: The nominal model's commands must miss base-frame targets by more than this, m.
NOMINAL_MISS_MIN_M = 1e-4
GEOMETRIC = {"sigma_length_m": 5e-4, "sigma_angle_rad": 1e-3}
N_TARGETS = 6


def _campaign(registered: bool, seed: int) -> tuple[VirtualRobot, object]:
    cfg = {
        "campaign": {"poses": 30},
        "noise": {"sigma_m": SIGMA_M},
        "registration": {"registered": registered},
        "effects": {"geometric": dict(GEOMETRIC)},
    }
    vr = VirtualRobot(load_robot("ur5"), cfg, seed=seed)
    res = identify(load_robot("ur5"), vr.campaign(), registered=registered, candidates=["geometric"])
    assert "geometric" in res.model.effects
    return vr, res


@pytest.fixture(scope="module")
def registered():
    return _campaign(True, seed=3)


@pytest.fixture(scope="module")
def unregistered():
    return _campaign(False, seed=3)


def _commands(vr: VirtualRobot, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """New poses (rad) and base-frame loads on the TCP (N, N*m)."""
    rng = np.random.default_rng(seed)
    q = vr.sample_poses(N_TARGETS, rng, max_cond=80.0)
    F = np.zeros((N_TARGETS, 6))
    F[:, :3] = rng.normal(0.0, 80.0, (N_TARGETS, 3))
    F[0] = 0.0
    return q, F


def _csv(q: np.ndarray, F: np.ndarray, p_mm: np.ndarray | None) -> str:
    head = [f"q{i}" for i in range(1, 7)] + ["fx", "fy", "fz", "mx", "my", "mz"]
    cols = [q, F]
    if p_mm is not None:
        head += ["x_mm", "y_mm", "z_mm"]
        cols.append(p_mm)
    rows = np.hstack(cols)
    return ",".join(head) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n"


def test_base_frame_targets_land_on_the_truth_robot(registered) -> None:
    vr, res = registered
    q, F = _commands(vr)
    rng = np.random.default_rng(8)
    T_nom = model_from_robot(vr.robot).kinematics.tcp(q)
    target = T_nom[:, :3, 3] + rng.normal(0.0, 3e-3, (N_TARGETS, 3))  # not the nominal TCP
    m = Measurements(q=q, wrench=F, p=target)
    out = compensate_targets(res.model, m, "base")
    assert out.status is CompensationStatus.OK and not out.warnings, out.reason
    assert out.targets_frame is TargetsFrame.BASE
    assert np.allclose(out.target[:, :3, 3], target) and np.allclose(out.target[:, :3, :3], T_nom[:, :3, :3])
    _p, tcp = vr.positions(out.q_command, F)
    err = np.linalg.norm(tcp[:, :3, 3] - target, axis=1)
    assert err.max() < LANDING_TOL_M, err
    # the nominal model's commands miss (so the test can fail)
    nom = compensate_targets(model_from_robot(vr.robot), m, "base")
    _p, tcp0 = vr.positions(nom.q_command, F)
    assert np.linalg.norm(tcp0[:, :3, 3] - target, axis=1).max() > NOMINAL_MISS_MIN_M


def test_measurement_frame_targets_land_in_the_measurement_frame_without_registration(unregistered) -> None:
    vr, res = unregistered
    q, F = _commands(vr)
    rng = np.random.default_rng(9)
    target = vr.measure(q, np.zeros_like(F)) + rng.normal(0.0, 2e-3, (N_TARGETS, 3))
    out = compensate_targets(res.model, Measurements(q=q, wrench=F, p=target), TargetsFrame.MEASUREMENT)
    assert out.status is CompensationStatus.OK and not out.warnings, out.reason
    # exact under the identified model (the load still acts at the robot file's TCP) ...
    p_model = predict(res.model, Measurements(q=out.q_command, wrench=F))
    assert np.abs(p_model - target).max() < MODEL_TOL_M
    # ... and on the truth robot, as its instrument measures it
    err = np.linalg.norm(vr.measure(out.q_command, F) - target, axis=1)
    assert err.max() < LANDING_TOL_M, err


def test_unregistered_model_with_base_frame_targets_warns(unregistered) -> None:
    vr, res = unregistered
    q, F = _commands(vr)
    T_nom = model_from_robot(vr.robot).kinematics.tcp(q)
    m = Measurements(q=q, wrench=F, p=T_nom[:, :3, 3])
    for frame in ("nominal", "base"):
        out = compensate_targets(res.model, m, frame)
        assert out.status is CompensationStatus.WARNING, (frame, out.reason)
        assert out.warnings == [out.reason]
        assert "dtheta[1]" in out.reason and "dd[1]" in out.reason
        assert "dd[3]" not in out.reason  # carried by dd[2]: compensated in the base frame
        assert " mm" in out.reason and "exact in the measurement frame (use --targets-frame measurement)" in out.reason
        assert np.all(np.isfinite(out.q_command)) and out.residual_m.max() < 1e-6


def test_missing_target_columns_is_an_input_error_naming_them(unregistered, tmp_path, capsys) -> None:
    vr, res = unregistered
    q, F = _commands(vr)
    m = parse_measurements(_csv(q, F, None), "cmd.csv", require_position=False)
    with pytest.raises(TargetsError) as ei:
        compensate_targets(res.model, m, "base")
    assert isinstance(ei.value, InputError)
    assert "cmd.csv" in str(ei.value) and "x, y, z" in str(ei.value) and "'base'" in str(ei.value)
    # the command line: one error line naming the file and the columns, exit 2, nothing written
    model = tmp_path / "model.toml"
    model.write_text(model_toml(res.model))
    inp = tmp_path / "cmd.csv"
    inp.write_text(_csv(q, F, None))
    out = tmp_path / "comp.csv"
    capsys.readouterr()
    assert (
        cli_main(
            [
                "compensate",
                "--model",
                str(model),
                "--input",
                str(inp),
                "--out",
                str(out),
                "--targets-frame",
                "measurement",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error" in err and str(inp) in err and "x, y, z" in err
    assert not out.exists()


def test_target_far_from_its_commands_is_an_input_error(registered) -> None:
    vr, res = registered
    q, F = _commands(vr)
    p = model_from_robot(vr.robot).kinematics.tcp(q)[:, :3, 3] * 1e3
    p[2, 0] += 400.0  # 0.4 m off: another frame?
    m = parse_measurements(_csv(q, F, p), "cmd.csv", require_position=False)
    with pytest.raises(TargetsError) as ei:
        compensate_targets(res.model, m, "base")
    msg = str(ei.value)
    assert f"line {int(m.line[2])}" in msg and "x_mm" in msg and f"{p[2, 0]:g}" in msg and "cmd.csv" in msg


def test_cli_targets_frames(unregistered, tmp_path, capsys) -> None:
    vr, res = unregistered
    q, F = _commands(vr)
    model = tmp_path / "model.toml"
    model.write_text(model_toml(res.model))
    # base-frame targets of an unregistered model: written, exit 0, one warning line on stderr
    inp = tmp_path / "base.csv"
    inp.write_text(_csv(q, F, model_from_robot(vr.robot).kinematics.tcp(q)[:, :3, 3] * 1e3))
    out = tmp_path / "comp_base.csv"
    capsys.readouterr()
    assert (
        cli_main(
            ["compensate", "--model", str(model), "--input", str(inp), "--out", str(out), "--targets-frame", "base"]
        )
        == 0
    )
    cap = capsys.readouterr()
    assert cap.err.count("\n") == 1 and cap.err.startswith("compplan: warning: ") and "dtheta[1]" in cap.err
    # q1..q6, sigma_x..z (base frame), outside_range (text)
    assert out.read_text().splitlines()[0] == "q1,q2,q3,q4,q5,q6,sigma_x,sigma_y,sigma_z,outside_range"
    assert np.loadtxt(out, delimiter=",", skiprows=1, usecols=range(9)).shape == (N_TARGETS, 9)
    # measurement-frame targets: no warning, the truth instrument sees the measured point on them
    target = vr.measure(q, np.zeros_like(F)) + 1e-3
    inp = tmp_path / "meas.csv"
    inp.write_text(_csv(q, F, target * 1e3))
    out = tmp_path / "comp_meas.csv"
    assert (
        cli_main(
            [
                "compensate",
                "--model",
                str(model),
                "--input",
                str(inp),
                "--out",
                str(out),
                "--targets-frame",
                "measurement",
            ]
        )
        == 0
    )
    cap = capsys.readouterr()
    assert cap.err == "" and "targets measurement frame, status ok" in cap.out
    qc = np.loadtxt(out, delimiter=",", skiprows=1, usecols=range(6))
    assert np.linalg.norm(vr.measure(qc, F) - target, axis=1).max() < LANDING_TOL_M


def test_parameter_status_is_an_enum_with_the_report_strings(registered) -> None:
    _vr, res = registered
    assert all(isinstance(p.status, ParameterStatus) for p in res.parameters)
    assert {p.status for p in res.parameters} <= {ParameterStatus.FREE, ParameterStatus.HELD}
    rep = json.loads(json.dumps(report_dict(res)))
    assert {p["status"] for p in rep["parameters"]} <= {"free", "held", "inactive"}
    assert [p["status"] for p in rep["parameters"]] == [p.status.value for p in res.parameters]
