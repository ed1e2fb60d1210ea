"""Robot files: built-ins load, every field is validated, and bad input gives one clear line
naming the file and key, a non-zero exit and no traceback."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models import BUILTIN_ROBOTS, load_robot
from models.robot import RobotFileError, robot_from_dict, robot_to_toml
from planner.cli import main


def test_builtins_load_with_published_values():
    ur5 = load_robot("ur5")
    assert np.allclose(ur5.d, [0.089159, 0, 0, 0.10915, 0.09465, 0.0823])
    assert np.allclose(ur5.a, [0, -0.425, -0.39225, 0, 0, 0])
    ar5 = load_robot("ar5")
    # paper-notes item 1 (consistent reading) and item 4 (stiffness in SI)
    assert np.allclose(np.degrees(ar5.alpha), [90, 0, 0, 90, -90, 0])
    assert np.allclose(ar5.stiffness, [1.27e3] * 3 + [3.3e4] * 3)
    assert np.isclose(ar5.d[1] + ar5.d[3], 0.109875)
    for name in BUILTIN_ROBOTS:
        r = load_robot(name)
        assert r.n_joints == 6 and np.all(r.stiffness > 0)
    assert load_robot("ur10").has_masses and not load_robot("ar5").has_masses


def test_roundtrip_toml(tmp_path):
    r = load_robot("ur10")
    p = tmp_path / "r.toml"
    p.write_text(robot_to_toml(r))
    r2 = load_robot(p)
    assert np.allclose(r2.a, r.a) and np.allclose(r2.coms, r.coms) and r2.name == r.name


def _base() -> dict:
    return load_robot("ur5").to_dict()


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda d: d.pop("name"), "'name'"),
        (lambda d: d.update(convention="dh"), "convention"),
        (lambda d: d.update(joints=d["joints"][:5]), "6"),
        (lambda d: d["joints"][2].pop("stiffness"), r"joints\[3\].*stiffness"),
        (lambda d: d["joints"][1].update(stiffness=-1.0), r"joints\[2\].*stiffness.*> 0"),
        (lambda d: d["joints"][0].update(a=math.nan), r"joints\[1\].*'a'.*finite"),
        (lambda d: d["joints"][0].update(d="0.1"), r"joints\[1\].*'d'.*number"),
        (lambda d: d["joints"][4].update(q_min=1.0, q_max=0.0), r"joints\[5\].*q_min"),
        (lambda d: d["joints"][0].update(alpha_deg=90.0), "either 'alpha'"),
        (lambda d: d["joints"][0].update(colour=1), "unknown key"),
        (lambda d: d.update(tool={"xyz": [0, 0]}), "xyz"),
        (lambda d: d["joints"][0].update(com=[0, 0]), "com"),
        (lambda d: d["joints"][0].pop("com"), "together"),
        (lambda d: d.update(gravity=[0, 0, math.inf]), "gravity"),
        (lambda d: d.update(gravity=[0, 0, -98.0665]), r"'gravity'.*implausible.*multiple of g"),  # 10 g
        (lambda d: d.update(gravity=[0, 0, -980.665]), r"'gravity'.*cm/s\^2 given"),
        (lambda d: d.update(extra=1), "unknown top-level"),
        (lambda d: d["joints"][1].update(a=-425.0), r"joints\[2\].*'a'.*millimetres"),
        (lambda d: d.update(tool={"xyz": [0, 0, 31.0]}), "millimetres"),
        (lambda d: d["joints"][5].update(v_max=180.0), r"joints\[6\].*'v_max'.*degrees per second"),
        (lambda d: d["joints"][1].update(mass=8393.0), r"joints\[2\].*'mass'.*grams"),
        # every link in grams, none above the per-link bound: the arm's mass for its size gives it away
        (lambda d: [j.update(mass=j["mass"] * 1e3) for j in d["joints"] if j["mass"] < 5], r"'mass'.*grams"),
    ],
)
def test_validation_names_the_key(mutate, match):
    d = _base()
    mutate(d)
    with pytest.raises(RobotFileError, match=match):
        robot_from_dict(d, where="test.toml")


def _write_variants(tmp_path):
    good = robot_to_toml(load_robot("ur5"))
    files = {
        "not_toml.toml": ("name = = 3\n", "not valid TOML"),
        "nan.toml": (good.replace("stiffness = 40000.0", "stiffness = nan", 1), "finite"),
        "missing.toml": (good.replace('convention = "standard_dh"\n', ""), "convention"),
    }
    out = {}
    for name, (text, match) in files.items():
        p = tmp_path / name
        p.write_text(text)
        out[p] = match
    return out


@pytest.mark.slow
def test_cli_bad_robot_file_one_line_no_traceback(tmp_path, capsys):
    for path, match in _write_variants(tmp_path).items():
        rc = main(["demo", "--out", str(tmp_path / "o"), "--robot", str(path)])
        err = capsys.readouterr().err
        assert rc == 2
        assert err.count("\n") == 1 and err.startswith("compplan: error:")
        assert str(path) in err and match in err
        assert "Traceback" not in err
    assert not (tmp_path / "o").exists()  # nothing written on failure


def test_cli_unknown_robot_and_unreachable_path(tmp_path, capsys):
    rc = main(["demo", "--out", str(tmp_path / "o"), "--robot", "ur99"])
    err = capsys.readouterr().err
    assert rc == 2 and "ur99" in err and "built-in" in err
    # a small arm cannot reach the paper's path: names the branches and the waypoint
    d = load_robot("ur5").to_dict()
    d["joints"][1]["a"] = -0.2
    d["joints"][2]["a"] = -0.15
    p = tmp_path / "small.toml"
    p.write_text(robot_to_toml(robot_from_dict(d)))
    rc = main(["demo", "--out", str(tmp_path / "o"), "--robot", str(p)])
    err = capsys.readouterr().err
    assert rc == 2 and "no IK branch" in err and "waypoint" in err
    assert "Traceback" not in err
