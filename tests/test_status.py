"""One kind of status enum (``models.status.Status``), and reasons that do not repeat their status.

Every enum named ``*Status`` in ``models``, ``problems`` and ``planner`` is found by importing
every module of the three packages, so a new status enum of another kind fails here.
"""

from __future__ import annotations

import enum
import importlib
import inspect
import pkgutil
from pathlib import Path

import numpy as np
import pytest

import models
import planner
import problems
from models import load_robot
from models.arm_file import model_from_robot
from models.load import Load
from models.robot import robot_from_dict
from models.status import CodedStatus, Status

#: Status enums that must be among those discovered (a discovery that finds none cannot pass).
EXPECTED = {
    "IKStatus",
    "OPWStatus",
    "GeneralIKStatus",
    "IdentifyStatus",
    "ParameterStatus",
    "BranchStatus",
    "PostureStatus",
    "ElasticStatus",
    "PlacementStatus",
    "SweepStatus",
    "CompensationStatus",
    "DynamicStatus",
    "PlanStatus",
    "TimingStatus",
    "DynamicStageStatus",
    "StudyStatus",
}
#: Half-width of the joint limits around a command that the compensation must leave, rad.
TIGHT_LIMIT_RAD = 1e-7


def _status_enums() -> dict[str, type[enum.Enum]]:
    """Every ``enum.Enum`` subclass named ``*Status`` defined in the three packages."""
    found: dict[str, type[enum.Enum]] = {}
    for pkg in (models, problems, planner):
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            if info.name.rsplit(".", 1)[-1] == "__main__":  # runs the command line
                continue
            mod = importlib.import_module(info.name)
            for obj in vars(mod).values():
                if (
                    inspect.isclass(obj)
                    and issubclass(obj, enum.Enum)
                    and obj.__name__.endswith("Status")
                    and obj.__module__ == mod.__name__
                    and obj not in (Status, CodedStatus)
                ):
                    found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return found


@pytest.fixture(scope="module")
def status_enums() -> dict[str, type[enum.Enum]]:
    return _status_enums()


def test_every_status_enum_derives_from_the_one_base(status_enums):
    assert EXPECTED <= {cls.__name__ for cls in status_enums.values()}, sorted(status_enums)
    other = [name for name, cls in status_enums.items() if not issubclass(cls, Status)]
    assert not other, f"status enums of another kind: {other}"
    mixed = [name for name, cls in status_enums.items() if issubclass(cls, (int, str))]
    assert not mixed, f"status enums that are also int or str (compared as values): {mixed}"


def test_status_values_are_strings_and_print_as_their_value(status_enums):
    for name, cls in status_enums.items():
        assert len(cls) > 0, name
        for member in cls:
            assert isinstance(member.value, str) and member.value, (name, member)
            assert str(member) == member.value and f"{member:>4}" == format(member.value, ">4")
            assert member != member.value  # compared as members, never as strings
            assert member.ok is (member.name == "OK")


def test_coded_statuses_map_array_codes_both_ways(status_enums):
    coded = {n: c for n, c in status_enums.items() if issubclass(c, CodedStatus)}
    assert {c.__name__ for c in coded.values()} == {"IKStatus", "OPWStatus", "GeneralIKStatus", "PlacementStatus"}
    for name, cls in coded.items():
        codes = [m.code for m in cls]
        assert len(set(codes)) == len(codes) and all(isinstance(c, int) for c in codes), name
        for m in cls:
            assert cls.from_code(np.int8(m.code)) is m and cls.from_code(float(m.code)) is m
        with pytest.raises(ValueError, match="no status with code"):
            cls.from_code(max(codes) + 1)


def _repeats(status: Status, reason: str) -> bool:
    """The reason starts with its status's word (``"unreachable: ..."``, ``"solver failed ..."``)."""
    text = reason.strip().lower()
    return any(text.startswith(w) for w in {status.value.lower(), status.value.replace("_", " ").lower()})


def _problem(tmp_path: Path, path: str, rest: str = "") -> Path:
    p = tmp_path / "status.toml"
    p.write_text(
        'name = "status"\n[robot]\nmodel = "ar5"\ntool = { xyz = [0.1, 0.0, 0.05] }\n'
        + path
        + '[orientation]\nrule = "free_tool_axis"\n[wrench]\nforce = [15.0, -25.0, 30.0]\n'
        + rest
    )
    return p


def test_an_unreachable_plan_does_not_repeat_its_status(tmp_path):
    from planner.plan import PlanStatus, plan
    from problems.problem import load_problem

    path = '[path]\nkind = "waypoints"\npositions = [[0.3, 0.0, 0.3], [1.5, 0.0, 0.3], [0.3, 0.1, 0.3]]\n'
    res = plan(load_problem(str(_problem(tmp_path, path))))
    assert res.status is PlanStatus.UNREACHABLE and "waypoint 1" in res.reason
    assert not _repeats(res.status, res.reason), res.reason
    assert res.posture is not None and not _repeats(res.posture.status, res.posture.reason)


def test_a_posture_failure_does_not_repeat_its_status(tmp_path):
    from planner.plan import PlanStatus, plan
    from problems.posture import PostureStatus
    from problems.problem import load_problem

    path = '[path]\nkind = "line"\nstart = [0.20, 0.40, 0.30]\nend = [0.45, -0.10, 0.30]\npoints = 10\n'
    res = plan(load_problem(str(_problem(tmp_path, path, "[limits]\nmax_joint_step = 0.01\n"))))
    assert res.status is PlanStatus.NO_BRANCH and res.posture.status is PostureStatus.NO_BRANCH
    assert "flip between waypoints" in res.reason
    for status, reason in ((res.status, res.reason), (res.posture.status, res.posture.reason)):
        assert not _repeats(status, reason), reason


def test_a_compensation_failure_does_not_repeat_its_status():
    from problems.compensation import CompensationStatus
    from problems.identify import compensate

    q = np.array([[0.1, -1.2, 1.4, -0.5, -1.5, 0.3]])
    d = load_robot("ur5").to_dict()
    for j, row in enumerate(d["joints"]):
        row["q_min"], row["q_max"] = float(q[0, j] - TIGHT_LIMIT_RAD), float(q[0, j] + TIGHT_LIMIT_RAD)
    out = compensate(model_from_robot(robot_from_dict(d, "tight.toml")), q, np.array([0.0, 0.0, -80.0, 0.0, 0.0, 0.0]))
    assert out.status is CompensationStatus.FAILED and not out.status.usable
    assert "outside the joint limits" in out.reason
    assert not _repeats(out.status, out.reason), out.reason


def test_dynamic_and_freedom_reasons_do_not_repeat_their_status():
    from problems.dynamic import DynamicStatus, motor_command
    from problems.posture import OrientationRule, analyse_freedom

    robot = load_robot("ar5")  # no link masses: no inertial torques
    q = np.zeros((3, 6))
    cmd = motor_command(model_from_robot(robot), q, q, q, Load.base(np.zeros(6)))
    assert cmd.status is DynamicStatus.FAILED and "no link masses" in cmd.reason
    assert not _repeats(cmd.status, cmd.reason), cmd.reason
    kind, note = analyse_freedom(robot, OrientationRule.FREE_TOOL_AXIS)  # tool on the joint-6 axis
    assert kind == "degenerate" and not note.startswith("degenerate"), note
