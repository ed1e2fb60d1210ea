"""The identification report and the joint error maps: ``report.json`` holds them, the
Markdown and HTML show a "Joint error maps" section near the top (table and a figure with
a panel per map), candidates carry their detail, weak structure is called weak, and the
many joint-angle diagnostics stay in a few figures and a short table."""

from __future__ import annotations

import base64
import dataclasses
import json
import re

import numpy as np
import pytest

from models import load_robot
from planner.identify_report import (
    REPORT_DIAGNOSTIC_PLOTS,
    REPORT_DIAGNOSTIC_ROWS,
    REPORT_MAP_PANELS,
    VARIABLE_LABELS,
    VARIABLE_UNITS,
    report_dict,
    report_html,
    report_markdown,
    structure_sentence,
    write_report,
)
from planner.identify_report.diagnostics import diag_groups
from planner.identify_report.figures import render_figures, x_of
from planner.identify_report.html import md_block
from planner.identify_report.maps import maps_drawn
from problems.identify import Diagnostic, identify
from problems.virtual import VirtualRobot

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
#: The simulated joint error: joint 1, 2 cycles/rev, 1 mrad.
TRUE_JOINT, TRUE_CPR, TRUE_AMP_URAD = 1, 2.0, 1000.0


def _cfg(effects: dict, poses: int) -> dict:
    return {
        "campaign": {"poses": poses},
        "noise": {"sigma_m": 2e-5},
        "registration": {"registered": False},
        "effects": effects,
    }


@pytest.fixture(scope="module")
def maps_run(tmp_path_factory):
    """A small campaign with a periodic error of joint 1, identified with the map candidate."""
    effects = {
        "eccentricity": {
            "joint": [TRUE_JOINT],
            "amplitude_rad": [TRUE_AMP_URAD * 1e-6],
            "harmonic": [TRUE_CPR],
            "phase_rad": [0.3],
        }
    }
    vr = VirtualRobot(load_robot("ur5"), _cfg(effects, 60), seed=3)
    res = identify(load_robot("ur5"), vr.campaign(), candidates=["joint_error_map"])
    folder = tmp_path_factory.mktemp("maps") / "rep"
    rep = write_report(res, folder)
    return res, rep, folder


@pytest.fixture(scope="module")
def plain_run(tmp_path_factory):
    """A campaign identified without any candidate: no map."""
    vr = VirtualRobot(load_robot("ur5"), _cfg({"gravity": {}}, 40), seed=4)
    res = identify(load_robot("ur5"), vr.campaign(), candidates=[])
    folder = tmp_path_factory.mktemp("plain") / "rep"
    rep = write_report(res, folder)
    return res, rep, folder


def _true_map(rep: dict) -> dict:
    maps = [m for m in rep["error_maps"] if m["joint"] == TRUE_JOINT and m["component"] == "theta"]
    assert len(maps) == 1, rep["error_maps"]
    return maps[0]


def test_json_holds_the_maps_with_the_true_harmonic(maps_run) -> None:
    res, rep, folder = maps_run
    on_disk = json.loads((folder / "report.json").read_text())
    assert on_disk["error_maps"] == json.loads(json.dumps(rep["error_maps"]))
    assert len(rep["error_maps"]) == len(res.error_maps) >= 1
    m = _true_map(rep)
    h = m["harmonics"][0]  # the largest first
    assert h["freq_cpr"] == pytest.approx(TRUE_CPR, abs=0.05)
    assert h["amplitude_urad"] == pytest.approx(TRUE_AMP_URAD, rel=0.1)
    assert 0 < h["amplitude_std_urad"] < 0.1 * h["amplitude_urad"]
    assert h["amplitude_tcp_um"] > 0 and m["rms_tcp_um"] > 0 and m["unit"] == "rad"
    lo, hi = m["range_deg"]
    assert -180.0 <= lo < hi <= 180.0
    # the headline names every map; the candidates carry their detail; 'weak' is always there
    assert {(x["joint"], x["component"]) for x in rep["headline"]["error_maps"]} == {
        (x["joint"], x["component"]) for x in rep["error_maps"]
    }
    cands = [c for st in rep["history"] for c in st["candidates"]]
    assert cands and all(isinstance(c["detail"], str) for c in cands)
    assert any(c["effect"] == "joint_error_map" and c["detail"] for c in cands)
    assert isinstance(rep["unexplained"]["weak"], bool)


def test_markdown_and_html_show_the_maps_near_the_top(maps_run) -> None:
    _res, rep, folder = maps_run
    md = (folder / "report.md").read_text()
    assert md.index("## Joint error maps") < md.index("## Unexplained structure") < md.index("## Selection history")
    row = next(ln for ln in md.splitlines() if ln.startswith(f"| {TRUE_JOINT} | θ (theta): angular positioning"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert len(cells) == 5, row  # joint, component, range, harmonics, RMS
    assert re.match(r"2 cycles/rev: \d+(\.\d+)? ± \d+(\.\d+)? µrad → \d+(\.\d+)? µm at the TCP", cells[3]), cells
    lo, hi = _true_map(rep)["range_deg"]
    assert cells[2].startswith(f"{lo:.3g}") and "…" in cells[2]
    assert float(cells[4]) == pytest.approx(_true_map(rep)["rms_tcp_um"], rel=0.01)
    assert "it continues beyond the angle range of the data" in md
    detail = next(c["detail"] for st in rep["history"] for c in st["candidates"] if c["detail"])
    assert detail in md  # the candidate's detail under its table

    html_text = (folder / "report.html").read_text()
    assert (
        html_text.index('class="summary headline"')
        < html_text.index('<h2 id="error_maps">Joint error maps</h2>')
        < html_text.index('data-figure="error_maps"')
        < html_text.index("<h2>Figures</h2>")
    )
    assert html_text.count("Joint error maps</h2>") == 1  # not repeated with the other sections
    assert "±2 standard deviations" in html_text and "the map continued (dashed)" in html_text
    src = re.search(r'data-figure="error_maps" [^>]*src="data:image/png;base64,([^"]+)"', html_text).group(1)
    assert base64.b64decode(src).startswith(PNG_MAGIC)
    # the figure numbers stay in order
    nums = [int(n) for n in re.findall(r"<h3 id=\"[^\"]+\">Figure (\d+)\.", html_text)]
    assert nums == list(range(1, len(nums) + 1))


def test_report_without_maps_has_no_maps_section(plain_run) -> None:
    _res, rep, folder = plain_run
    assert rep["error_maps"] == [] and rep["headline"]["error_maps"] == []
    md = (folder / "report.md").read_text()
    html_text = (folder / "report.html").read_text()
    assert "Joint error maps" not in md and "Joint error maps" not in html_text
    assert 'data-figure="error_maps"' not in html_text
    assert "joint error maps" not in md  # no headline row either


@pytest.mark.slow
def test_many_maps_are_drawn_in_at_most_the_panel_limit(maps_run) -> None:
    res, _rep, _folder = maps_run
    base = res.error_maps[0]
    many = [
        dataclasses.replace(
            base,
            joint=1 + i % 6,
            component=("theta", "d", "a")[i % 3],
            unit="rad" if i % 3 == 0 else "m",
            rms_tcp_m=1e-6 * (i + 1),
        )
        for i in range(REPORT_MAP_PANELS + 3)
    ]
    drawn = maps_drawn(many)
    assert len(drawn) == REPORT_MAP_PANELS
    assert {m.rms_tcp_m for m in drawn} == {m.rms_tcp_m for m in many[-REPORT_MAP_PANELS:]}  # the largest
    res_many = dataclasses.replace(res, error_maps=many)
    figs = render_figures(res_many, report_dict(res_many))
    assert figs["error_maps"].png.startswith(PNG_MAGIC) and figs["error_maps"].pdf.startswith(b"%PDF")
    md = report_markdown(report_dict(res_many))
    assert f"the {REPORT_MAP_PANELS} maps with the largest RMS at the TCP; 3 more" in md


@pytest.mark.parametrize("weak", [True, False])
def test_weak_structure_is_called_weak(maps_run, weak) -> None:
    res, _rep, _folder = maps_run
    msg = ("weak " if weak else "") + (
        "structure remains that no library effect explains: the residual depends on "
        "q3 (cross-validated regression explains 7 % of its variance, p = 1e-9)"
    )
    unexplained = {
        "present": True,
        "variable": "q3",
        "diagnostic": "residual vs q3",
        "weak": weak,
        "explained_fraction": 0.07,
        "p_value": 1e-9,
        "message": msg,
    }
    r = dataclasses.replace(res, unexplained=unexplained)
    rep = report_dict(r)
    assert rep["unexplained"]["weak"] is weak
    assert rep["headline"]["unexplained"].startswith("weak structure remains") is weak
    md = report_markdown(rep)
    head = md.split("\n## ")[0]
    assert ("| structure left in the residual | weak structure remains |" in head) is weak
    section = md.split("## Unexplained structure")[1].split("\n## ")[0]
    assert ("Weak structure remains" in section) is weak and "None:" not in section
    assert "no structure" not in structure_sentence(rep)
    assert ("weak structure remains" in report_html(rep, {})) is weak


def test_no_structure_is_said_as_none(plain_run) -> None:
    res, _rep, _folder = plain_run
    r = dataclasses.replace(
        res,
        unexplained={
            "present": False,
            "weak": False,
            "variable": None,
            "message": "no diagnostic shows structure the model leaves unexplained",
        },
    )
    rep = report_dict(r)
    assert rep["headline"]["unexplained"].startswith("no diagnostic shows structure")
    assert "| structure left in the residual | none |" in report_markdown(rep)
    # an older record without 'weak' reads as not weak
    r = dataclasses.replace(res, unexplained={"present": True, "variable": "time", "message": "structure remains"})
    assert report_dict(r)["unexplained"]["weak"] is False


def test_joint_angle_diagnostic_labels_are_in_degrees() -> None:
    assert VARIABLE_LABELS["q3"] == ("joint 3 angle (error of joint 3)", "deg")
    assert VARIABLE_LABELS["q3.x"] == ("joint 3 angle (residual x)", "deg")
    assert {f"q{j}.{a}" for j in range(1, 7) for a in "xyz"} <= set(VARIABLE_UNITS)
    q = np.linspace(-np.pi, np.pi, 7)
    x, label = x_of(Diagnostic("q2.y", 0.1, 1e-9, True, q))
    assert np.allclose(x, np.degrees(q)) and label.endswith("[deg]")
    x, label = x_of(Diagnostic("temperature", 0.1, 1e-9, True, q))
    assert np.allclose(x, q) and label.endswith("[°C]")


@pytest.mark.slow
def test_many_diagnostics_stay_in_a_few_figures_and_a_short_table(maps_run) -> None:
    res, _rep, _folder = maps_run
    inl = res.inliers
    q = np.asarray(res.data.q, dtype=float)[inl]
    R = np.asarray(res.residual_after, dtype=float)[inl]
    diags = []
    for j in range(6):  # every joint significant on x and z
        for k, a in enumerate("xyz"):
            diags.append(
                Diagnostic(
                    f"q{j + 1}.{a}",
                    0.3 - 0.01 * (3 * j + k),
                    1e-12,
                    a != "y",
                    q[:, j],
                    y=R[:, k],
                    y_label=f"weighted residual {a}",
                )
            )
        diags.append(
            Diagnostic(
                f"q{j + 1}",
                0.02,
                0.5,
                False,
                q[:, j],
                y=np.zeros(len(q)),
                y_label=f"equivalent joint-{j + 1} error (mrad)",
            )
        )
    diags.append(Diagnostic("time", 0.01, 0.3, False, np.arange(len(q), dtype=float)))
    diags.sort(key=lambda d: -d.explained_fraction)
    want = "q5.z"
    r = dataclasses.replace(res, diagnostics=diags, unexplained={**res.unexplained, "variable": want})
    groups = diag_groups(r)
    assert len(groups) == REPORT_DIAGNOSTIC_PLOTS
    assert groups[0][0] == "q5.xyz"  # the unexplained structure's variable first
    assert all(any(d.significant for d in g) for _k, g in groups)  # significant ones before the rest
    figs = render_figures(r, report_dict(r))
    assert len([k for k in figs if k.startswith("diag_")]) == REPORT_DIAGNOSTIC_PLOTS
    md = report_markdown(report_dict(r))
    table = md.split("## Diagnostics of the final residual")[1].split("\n## ")[0]
    listed = [ln.split("|")[1].strip() for ln in table.splitlines() if ln.startswith("| q") or ln.startswith("| time")]
    sig = [d.variable for d in diags if d.significant]
    assert set(sig) <= set(listed) and len(listed) == len(sig) + REPORT_DIAGNOSTIC_ROWS
    hidden = len(diags) - len(listed)
    assert f"{hidden} other diagnostics not shown" in table
    assert "| q3.x | joint 3 angle (residual x) |" in table


def test_pipes_in_table_cells_stay_in_their_cell() -> None:
    out = md_block("| variable | what |\n|---|---|\n| load_magnitude | applied force \\|f\\| |")
    assert "<td>load_magnitude</td><td>applied force |f|</td>" in out


@pytest.mark.parametrize(
    "significant", [set(), {"q2.x"}, {"q2.x", "q2.z", "time"}, {"q1", "q3.y", "q4", "q6.x", "time"}]
)
def test_only_significant_diagnostics_are_drawn(maps_run, significant) -> None:
    """Non-significant diagnostics get no panel (however strong); the significant ones do, up to the limit."""
    res, _rep, _folder = maps_run
    n = int(np.count_nonzero(res.inliers))
    x = np.linspace(-1.0, 1.0, n)
    names = [f"q{j}{a}" for j in range(1, 7) for a in ("", ".x", ".y", ".z")] + ["time", "pose"]
    diags = [Diagnostic(v, 0.5 - 0.01 * i, 1e-12, v in significant, x) for i, v in enumerate(names)]
    r = dataclasses.replace(res, diagnostics=diags, unexplained={**res.unexplained, "variable": None})
    keys = [k for k, _g in diag_groups(r)]
    want = {f"{v[:2]}.xyz" if "." in v else v for v in significant}
    assert set(keys) <= want and len(keys) == min(len(want), REPORT_DIAGNOSTIC_PLOTS)
    assert all(d.significant for _k, g in diag_groups(r) for d in g)
