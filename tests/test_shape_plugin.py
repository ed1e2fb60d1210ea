"""A shape kind is one module: a plug-in from a folder of ``$COMPPLAN_SHAPE_PATH`` goes from a
problem file's ``[cell]`` through the posture NLP's clearance constraints, the plan's check, the
placement kernel, the summary and both reports, with no other edit (``models/collision/shapes``).

The plug-in (:data:`PLUGIN`) is a rod: a capsule-shaped obstacle (``size = [radius, length]``, its
axis along the object's z, round ends), exact in every closed form (the distance of a point or a
segment from its axis minus its radius).  Registration happens at import, so everything runs in a
fresh interpreter (a subprocess) with the variable set.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The plug-in's kind and module file.
KIND = "rod"
MODULE = "rod_shape.py"
#: A subprocess that plans (posture, compensation, timing, report) gets this long, s.
TIMEOUT_S = 900
#: The NLP's bound may exceed coal's distance by this much (m), as for the built-in kinds.
BOUND_ABOVE_TOL_M = 1e-6
#: The closed forms agree with coal to this (m): GJK's tolerance.
COAL_TOL_M = 1e-6

PLUGIN = '''
"""A rod: a capsule-shaped obstacle, size = [radius, length] (m), its axis along z (a shape plug-in)."""
import numpy as np

from models.collision.segments import segment_distance
from models.collision.shapes import NORM_EPS_M, Shape, register_shape


@register_shape
class Rod(Shape):
    kind = "rod"
    size_length = 2
    size_meaning = "[radius, length] (m), the axis along the object's z, round ends"

    @property
    def ends(self):
        h = 0.5 * self.size[1]
        return np.array([0.0, 0.0, -h]), np.array([0.0, 0.0, h])

    def geometry(self):
        import coal

        return coal.Capsule(float(self.size[0]), float(self.size[1]))

    def signed_distance(self, q):
        z = np.clip(q[..., 2], -0.5 * self.size[1], 0.5 * self.size[1])
        return np.linalg.norm(q - np.stack([0.0 * z, 0.0 * z, z], axis=-1), axis=-1) - self.size[0]

    def signed_distance_sx(self, local):
        import casadi as ca

        h = 0.5 * float(self.size[1])
        z = ca.fmin(ca.fmax(local[2], -h), h)
        return ca.sqrt(ca.sumsqr(local - ca.vertcat(0, 0, z)) + NORM_EPS_M**2) - float(self.size[0])

    def capsule_distance(self, p0, p1, radii):
        a, b = self.ends
        dist, _, _ = segment_distance(p0, p1, a, b)
        return dist - self.size[0] - radii

    @property
    def half_extents(self):
        r, h = self.size[0], 0.5 * self.size[1]
        return np.array([r, r, h + r])

    @property
    def bounding_radius(self):
        return float(0.5 * self.size[1] + self.size[0])

    def bounding_capsule(self):
        a, b = self.ends
        return a, b, float(self.size[0])

    def triangles(self):
        import trimesh

        m = trimesh.creation.capsule(height=float(self.size[1]), radius=float(self.size[0]))
        return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)
'''

#: A post beside the end of cell_table's line (the shipped cell: a table and the fixture): within
#: the NLP's near distance of the arm, and close enough that a branch is set aside for it.
POST = f'\n[[cell.objects]]\nname = "post"\nshape = "{KIND}"\nsize = [0.03, 0.3]\nxyz = [0.75, 0.55, 0.22]\n'

#: Run in the plug-in's interpreter: the NLP's bound against coal, the kernel's closed form and
#: its decision against coal, the tool element of the plug-in's kind; prints one JSON line.
PROBE = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    from models.collision import capsule_shape_distance
    from models.collision.shapes import shape_kinds
    from models.collision.vectorised import capsule_object_distance
    from planner.cell_check import cell_geometry
    from problems.placement.collide import KernelCell
    from problems.posture.clearance import clearance_spec, distance_function
    from problems.problem import load_problem

    p = load_problem(sys.argv[1])
    scene = cell_geometry(p.robot, p.cell)
    spec = clearance_spec(scene)
    rng = np.random.default_rng(36)
    q = rng.uniform(p.robot.q_min, p.robot.q_max, (60, 6))
    seg, r = scene.segments(q), scene.model.radius
    rows = [i for i, pr in enumerate(spec.pairs) if pr.kind == "rod"]
    bound = np.asarray(distance_function(spec).map(len(q))(q.T)).T[:, rows]
    post = scene.objects[[o.name for o in scene.objects].index("post")]
    exact = np.array([[capsule_shape_distance(seg[n, spec.pairs[i].capsule, 0], seg[n, spec.pairs[i].capsule, 1],
                                              r[spec.pairs[i].capsule], post).distance for i in rows]
                      for n in range(len(q))])
    kc = KernelCell(p.robot, p.cell)
    caps = [spec.pairs[i].capsule for i in rows]
    closed = capsule_object_distance(seg[:, caps], r[caps], post.proxy(nlp=False))
    b2c = np.tile(np.eye(4), (len(q), 1, 1))
    print(json.dumps({
        "kinds": list(shape_kinds()),
        "pairs": len(rows),
        "bound_over_coal_m": float(np.max(bound - exact)),
        "closed_vs_coal_m": float(np.max(np.abs(closed - exact))),
        "kernel_segments_m": float(np.max(np.abs(kc.segments(q, b2c) - seg))),
        "kernel_min_m": kc.min_distance(q, b2c).tolist(),
    }))
    """
)


def _run(args: list[str], plugins: Path, module: str | None = "planner") -> subprocess.CompletedProcess:
    """``python -m planner ARGS`` (or ``python -c ARGS``) in a fresh interpreter with
    ``$COMPPLAN_SHAPE_PATH`` = ``plugins``."""
    cmd = [sys.executable, "-m", module, *args] if module else [sys.executable, "-c", *args]
    env = {**os.environ, "COMPPLAN_SHAPE_PATH": str(plugins)}
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S, env=env, check=False, cwd=ROOT)
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}"
    return r


@pytest.fixture(scope="module")
def plugin_case(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The plug-in's folder and a problem file: cell_table with a post of the plug-in's kind."""
    tmp = tmp_path_factory.mktemp("shape_plugin")
    plugins = tmp / "plugins"
    plugins.mkdir()
    (plugins / MODULE).write_text(PLUGIN, encoding="utf-8")
    problem = tmp / "cell_post.toml"
    text = (ROOT / "problems" / "files" / "cell_table.toml").read_text(encoding="utf-8")
    problem.write_text(text.replace('name = "cell_table"', 'name = "cell_post"') + POST, encoding="utf-8")
    return {"tmp": tmp, "plugins": plugins, "problem": problem}


@pytest.mark.slow
def test_the_nlp_and_the_kernel_measure_the_plugin_shape(plugin_case):
    r = _run([PROBE, str(plugin_case["problem"])], plugin_case["plugins"], module=None)
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got["kinds"] == ["box", "cylinder", "sphere", "mesh", KIND]
    assert got["pairs"] > 0  # the arm's capsules and the tool's are checked against the post
    assert got["bound_over_coal_m"] <= BOUND_ABOVE_TOL_M  # the NLP's bound never exceeds coal's distance
    assert got["closed_vs_coal_m"] < COAL_TOL_M  # the kernel's closed form is coal's distance
    assert got["kernel_segments_m"] < 1e-12  # the kernel's capsules are the scene's


@pytest.mark.slow
def test_a_plan_checks_and_reports_the_plugin_shape(plugin_case):
    out = plugin_case["tmp"] / "plan"
    r = _run(["plan", str(plugin_case["problem"]), "--out", str(out)], plugin_case["plugins"])
    s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert s["plan_status"] == "ok"
    assert {"name": "post", "shape": KIND, "role": "obstacle"} in s["cell"]["objects"]
    rec = s["problem"]["cell"]["objects"][-1]
    assert rec["shape"] == KIND and rec["size"] == [0.03, 0.3]  # its dictionary form
    # the plan's check measured the post: a branch that came too close to it was set aside
    assert any("post" in (b or {}).get("reason", "") for b in s["cell"]["branches"].values()), r.stdout
    html = (out / "report.html").read_text(encoding="utf-8")
    assert (out / "figures" / "fig11_cell.png").is_file() and f"post ({KIND}, obstacle)" in html
    # the report from the folder draws it again (the recorded dictionary read back)
    _run(["report", str(out)], plugin_case["plugins"])
    assert f"post ({KIND}, obstacle)" in (out / "report.html").read_text(encoding="utf-8")


@pytest.mark.slow
def test_a_placement_study_checks_the_plugin_shape(plugin_case):
    out = plugin_case["tmp"] / "place"
    args = [
        "place",
        str(plugin_case["problem"]),
        "--out",
        str(out),
        "--grid",
        "x_m=0,y_m=0:0.1:2",
        "--grid",
        "yaw_deg=0",
        # the kernel and the report are what this test is for: one placement planned in full, its
        # postures the analytic ones (the NLP with the plug-in's constraints: the plan test above)
        "--top",
        "1",
        "--no-optimise",
    ]
    _run(args, plugin_case["plugins"])
    s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert (out / "report.html").is_file() and (out / "scores.csv").is_file()
    assert "post" in json.dumps(s)


def test_a_shape_table_names_the_plugin_kind(plugin_case, tmp_path):
    """An unknown shape's message lists the plug-in's kind; the plug-in's own keys are checked."""
    bad = tmp_path / "bad.toml"
    bad.write_text(plugin_case["problem"].read_text(encoding="utf-8").replace(f'shape = "{KIND}"', 'shape = "cone"'))
    code = (
        "import sys\nfrom problems.problem import load_problem, ProblemFileError\n"
        "try:\n    load_problem(sys.argv[1])\nexcept ProblemFileError as e:\n    print(e)\n"
    )
    msg = _run([code, str(bad)], plugin_case["plugins"], module=None).stdout
    assert "must be one of ['box', 'cylinder', 'sphere', 'mesh', 'rod']" in msg
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(plugin_case["problem"].read_text(encoding="utf-8").replace("size = [0.03, 0.3]", "size = [0.03]"))
    msg = _run([code, str(wrong)], plugin_case["plugins"], module=None).stdout
    assert "must be 2 number(s) for a rod: [radius, length] (m)" in msg


def test_a_kind_registered_twice_is_refused(tmp_path):
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    (plugins / "second_box.py").write_text(
        "from models.collision.shapes.box import Box\nfrom models.collision.shapes import register_shape\n\n"
        "@register_shape\nclass Box2(Box):\n    kind = 'box'\n",
        encoding="utf-8",
    )
    env = {**os.environ, "COMPPLAN_SHAPE_PATH": str(plugins)}
    r = subprocess.run(
        [sys.executable, "-c", "import models.collision.shapes"], capture_output=True, text=True, env=env, cwd=ROOT
    )
    assert r.returncode != 0
    assert "$COMPPLAN_SHAPE_PATH" in r.stderr and "second_box.py" in r.stderr and "registered already" in r.stderr
