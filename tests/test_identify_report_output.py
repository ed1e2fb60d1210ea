"""What ``identify`` prints and its report say (issue 24 of the identification output).

One command-line run on a virtual robot (unregistered data with geometric errors, so parameters
alias with the registration and the measured point; a held-out validation file of the same robot;
the truth file) and the report it writes:

* the truth line and the report name the figure to read first (the measured point's error in the
  measurement frame, mm) and say in the same sentence why the base frame's "% left" differs;
* the validation file's RMS before -> after is in the headline;
* every figure is a file (PNG and PDF) linked from the report, and every file is one of its figures;
* no signed percentage contradicts the change it sits beside; no explained share is negative;
* diagnostics are drawn only where significant, the others named in one line;
* every terminal line is short, the held parameters are one line that names an action, and the
  report lists each held parameter in exactly one group.
"""

from __future__ import annotations

import contextlib
import copy
import html
import io
import json
import re

import numpy as np
import pytest

from models import load_robot
from planner.cli import main as cli_main
from planner.identify_report import compensation_sentence, report_markdown
from planner.identify_report.data import FRACTION_LEFT_AGREE, headline
from planner.identify_report.diagnostics import not_significant_line
from planner.numbers import format_number, round_sig
from problems.identify.diagnostics import regress_cv, run_diagnostics
from problems.identify.results import HELD_MESSAGE_MAX_CHARS, HeldGroup, HeldSummary, joints_text
from problems.identify.selection_scores import Score, candidate_score, significance
from problems.measurements import Measurements, measurements_to_csv
from problems.virtual import VirtualRobot

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
#: The longest line ``identify`` prints (characters): a line, not a wall of text.
LINE_MAX_CHARS = 300
#: Words that name an action in a warning or in the held-parameters line.
ACTION = re.compile(r"\b(add|use|check|calibrate|identify|give|measure|nothing to do|none)\b")
#: "a -> b mm (+x %)" or "a → b mm (-x %)": a change and its signed percentage.
SIGNED_CHANGE = re.compile(r"([0-9.]+(?:e-?\d+)?) (?:->|→) ([0-9.]+(?:e-?\d+)?) mm \(([+-][0-9.]+) %\)")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """``simulate`` then ``identify --truth --validation`` on ur5 with geometric errors, unregistered
    (40 poses; candidates that lower and that raise the held-out RMS)."""
    d = tmp_path_factory.mktemp("ident_out")
    cfg = d / "sim.toml"
    cfg.write_text("seed = 5\n[campaign]\nposes = 40\n[noise]\nsigma_m = 2e-5\n[effects.geometric]\n")
    data = d / "data.csv"
    assert cli_main(["simulate", "--robot", "ur5", "--config", str(cfg), "--out", str(data)]) == 0
    from problems.virtual import load_config

    vr = VirtualRobot(load_robot("ur5"), load_config(str(cfg)))  # the same robot: new poses and loads
    val = d / "val.csv"
    val.write_text(measurements_to_csv(vr.campaign(seed=1234)))
    rep = d / "rep"
    out, err = io.StringIO(), io.StringIO()
    args = ["identify", "--robot", "ur5", "--data", str(data), "--out", str(d / "m.toml"), "--report", str(rep)]
    args += ["--truth", str(d / "data.truth.toml"), "--validation", str(val), "--no-progress"]
    args += ["--candidates", "geometric,drift,load_offset"]
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        assert cli_main(args) == 0, err.getvalue()
    report = json.loads((rep / "report.json").read_text())
    return report, rep, out.getvalue(), err.getvalue()


def _line(stdout: str, start: str) -> str:
    lines = [ln for ln in stdout.splitlines() if ln.strip().startswith(start)]
    assert len(lines) == 1, stdout
    return lines[0]


# ------------------------------------------------------------------------------ the truth line


def test_truth_line_reads_the_measurement_frame_first_and_says_why_the_base_frame_differs(run) -> None:
    rep, folder, stdout, _err = run
    c = rep["compensation_check"]
    assert rep["base_frame_aliases"] and not rep["data"]["registered"]  # the case of the issue
    assert c["fraction_left"] - c["meas_frame_fraction_left"] > FRACTION_LEFT_AGREE
    line = _line(stdout, "compensation on the virtual robot:")
    first = re.search(r"([0-9.]+) -> ([0-9.]+) mm RMS in the measurement frame", line)
    assert first and line.index(first.group(0)) < line.index("base frame")
    assert first.groups() == (format_number(c["meas_frame_rms_before_mm"]), format_number(c["meas_frame_rms_after_mm"]))
    assert f"absorb {len(rep['base_frame_aliases'])} aliased parameters" in line and "predictions agree" in line
    # the report says the same sentence, in its headline, its Markdown and its HTML
    sentence = compensation_sentence(rep)
    assert rep["headline"]["compensation"] == sentence
    assert line.endswith(compensation_sentence(rep, arrow="->"))
    assert sentence in (folder / "report.md").read_text()
    assert html.escape(sentence) in (folder / "report.html").read_text()


@pytest.mark.parametrize(
    "base_left, registered, aliases",
    [(0.005, False, ["dd[1]"]), (0.4, False, ["dd[1]", "dtheta[1]"]), (0.4, True, []), (0.4, False, [])],
)
def test_the_compensation_sentence_says_why_whenever_the_frames_differ(run, base_left, registered, aliases) -> None:
    """Every case: the measurement frame first; "differs as <reason>" exactly when the two fractions
    left differ by more than FRACTION_LEFT_AGREE; never a bare second figure that contradicts the first."""
    rep = copy.deepcopy(run[0])
    rep["compensation_check"]["fraction_left"] = base_left
    rep["data"]["registered"] = registered
    rep["base_frame_aliases"] = aliases
    s = compensation_sentence(rep)
    assert s.index("measurement frame") < s.index("base frame")
    differs = abs(base_left - rep["compensation_check"]["meas_frame_fraction_left"]) > FRACTION_LEFT_AGREE
    assert ("differs as " in s) is differs and ("read this" in s) is differs
    if differs and aliases and not registered:
        assert f"absorb {len(aliases)} aliased parameters" in s


# ------------------------------------------------------------------------------ validation in the headline


def test_the_validation_file_is_in_the_headline(run) -> None:
    rep, folder, stdout, _err = run
    v, h = rep["validation"], rep["headline"]
    assert (h["validation_rms_before_mm"], h["validation_rms_after_mm"]) == (
        round_sig(v["rms_nominal_mm"]),
        round_sig(v["rms_mm"]),
    )
    assert h["validation_held_out"] is True and v["rms_mm"] < v["rms_nominal_mm"]
    head = (folder / "report.md").read_text().split("\n## ")[0]
    row = next(ln for ln in head.splitlines() if ln.startswith("| validation file RMS"))
    assert f"{h['validation_rms_before_mm']:.4g} → {h['validation_rms_after_mm']:.4g} mm" in row
    assert "never used in the fit" in row
    line = _line(stdout, "validation file (held out")
    assert f"{v['rms_nominal_mm']:.4f} -> {v['rms_mm']:.4f} mm" in line
    # where it holds: the coverage on the file, on the terminal as in report.json
    w = v["where_it_holds"]
    assert 0.0 <= w["coverage_2sigma"] <= 1.0
    cover = _line(stdout, "validation file: 2-sigma coverage")
    assert f"2-sigma coverage {100 * w['coverage_2sigma']:.1f} % per axis" in cover
    assert h["validation_coverage_2sigma"] == w["coverage_2sigma"]
    assert f"| validation file 2σ coverage | {100 * w['coverage_2sigma']:.1f} % per axis |" in head
    if w["joints"]:
        assert "### Where the model holds" in (folder / "report.md").read_text()
    # the data file given as its own validation is not called held out
    same = copy.deepcopy(rep)
    same["validation"]["file"] = rep["data"]["file"]
    same["headline"] = headline(same)
    assert same["headline"]["validation_held_out"] is False
    assert "not held out" in report_markdown(same).split("\n## ")[0]


# ------------------------------------------------------------------------------ figures as files


def test_every_figure_is_a_file_and_every_file_a_figure(run) -> None:
    rep, folder, _out, _err = run
    figs = rep["figures"]
    assert [f["number"] for f in figs] == list(range(1, len(figs) + 1))
    assert {"residuals", "history", "compensation"} <= {f["key"] for f in figs}
    for f in figs:
        assert (folder / f["png"]).read_bytes().startswith(PNG_MAGIC), f
        assert (folder / f["pdf"]).read_bytes().startswith(b"%PDF"), f
    on_disk = {str(p.relative_to(folder)) for p in (folder / "figures").iterdir()}
    assert on_disk == {f["png"] for f in figs} | {f["pdf"] for f in figs}
    html_text = (folder / "report.html").read_text()
    md = (folder / "report.md").read_text()
    embedded = re.findall(r'data-figure="([^"]+)"', html_text)
    assert sorted(embedded) == sorted(f["key"] for f in figs)
    for f in figs:
        assert f'href="{f["png"]}"' in html_text and f'href="{f["pdf"]}"' in html_text
        assert f"]({f['png']})" in md and f"]({f['pdf']})" in md
    for link in re.findall(r'href="(figures/[^"]+)"', html_text) + re.findall(r"\]\((figures/[^)]+)\)", md):
        assert (folder / link).is_file(), link


# ------------------------------------------------------------------------------ signs and shares


def _signed_changes(text: str) -> list[tuple[float, float, float]]:
    return [(float(a), float(b), float(p)) for a, b, p in SIGNED_CHANGE.findall(text)]


def test_no_percentage_contradicts_its_change(run) -> None:
    """Every "a -> b mm (±x %)" of the report and the terminal: the sign is that of b - a, and x the
    relative change (to the rounding of a and b)."""
    rep, folder, stdout, _err = run
    changes = _signed_changes((folder / "report.md").read_text() + stdout + json.dumps(rep, ensure_ascii=False))
    assert any(p < 0 for _a, _b, p in changes) and any(p > 0 for _a, _b, p in changes)  # both directions seen
    for a, b, p in changes:
        assert p == pytest.approx(100 * (b / a - 1), abs=0.051 + 0.1 * b / a), (a, b, p)


@pytest.mark.parametrize("new_cv_mm", [0.05, 0.099, 0.1, 0.101, 0.2])
def test_a_candidate_score_reads_as_its_direction(new_cv_mm) -> None:
    """A candidate that lowers the held-out RMS shows a negative change and a share >= 0; one that
    raises it shows a positive change and explains none (share 0, never negative)."""
    n, k = 300, 6
    cur = Score(rss=n * 1e-8, cv_rss=n * 1e-8, cv_rms_m=1e-4, rms_m=1e-4, n=n, k=k)
    ss = n * (new_cv_mm * 1e-3) ** 2
    new = Score(rss=ss, cv_rss=ss, cv_rms_m=new_cv_mm * 1e-3, rms_m=1e-4, n=n, k=k + 3)
    cs = candidate_score("drift", new, cur, 2e-5, 3)
    assert cs.explained_share >= 0.0
    if new_cv_mm >= 0.1:
        assert cs.explained_share == 0.0
    _basic, _share_ok, text = significance(cs, cur)
    ((a, b, p),) = _signed_changes(text)
    assert np.sign(p) == np.sign(round(b - a, 6)) or abs(p) < 0.05
    assert "explains -" not in text


def test_no_explained_share_is_negative(run) -> None:
    rep, folder, _out, _err = run
    shares = [c["explained_share"] for st in rep["history"] for c in st["candidates"]]
    fractions = [d["explained_fraction"] for d in rep["diagnostics"]]
    assert shares and fractions and min(shares + fractions) >= 0.0
    md = (folder / "report.md").read_text()
    assert "explains -" not in md
    cells = _column(md, "share") + _column(md, "CV explained fraction")
    assert len(cells) >= len(shares) and all(not c.startswith("-") for c in cells), cells


def _column(md: str, name: str) -> list[str]:
    """The cells of every Markdown table column headed ``name``."""
    out: list[str] = []
    col = None
    for ln in md.splitlines():
        if not ln.startswith("|"):
            col = None
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", ln.strip().strip("|"))]
        if col is None:
            col = cells.index(name) if name in cells else -1
        elif col >= 0 and not set("".join(cells)) <= set("-"):
            out.append(cells[col])
    return out


def test_a_diagnostic_with_no_structure_explains_nothing_not_less() -> None:
    """Noise regressed on an unrelated variable: the cross-validated fit predicts held-out rows worse
    than their mean (1 - CV RSS / RSS < 0); the share reported is 0."""
    rng = np.random.default_rng(3)
    n = 60
    R = rng.normal(0.0, 1.0, (n, 3))
    x = rng.uniform(-1.0, 1.0, n)
    X = np.stack([np.column_stack([x**k for k in range(1, 9)])] * 3, axis=1)  # (n, 3, 8): overfits noise
    m = Measurements(q=np.zeros((n, 6)), wrench=np.zeros((n, 6)), p=np.zeros((n, 3)), point=np.arange(n))
    folds = np.arange(n) % 5
    raw, _p = regress_cv(R, X, folds)
    assert raw < 0.0  # the case: worse than the mean out of fold
    diags = run_diagnostics(R, m, {"time": (x, X, "noise")}, folds)
    assert {d.variable for d in diags} == {"time", "pose"}
    assert all(d.explained_fraction >= 0.0 and not d.significant for d in diags)


# ------------------------------------------------------------------------------ diagnostic panels


def test_diagnostics_are_drawn_only_where_significant(run) -> None:
    rep, folder, _out, _err = run
    sig = {d["variable"] for d in rep["diagnostics"] if d["significant"]}
    drawn = [f["key"][5:] for f in rep["figures"] if f["key"].startswith("diag_")]
    for v in drawn:
        names = {f"{v[:2]}.{a}" for a in "xyz"} if v.endswith(".xyz") else {v}
        assert names & sig, (v, sig)
    line = not_significant_line(rep["diagnostics"])
    assert line and line in (folder / "report.md").read_text() and line in (folder / "report.html").read_text()
    if not sig:
        assert drawn == [] and line.startswith("no diagnostic is significant on joints 1-6")


@pytest.mark.parametrize("significant", [[], ["q2.x"], ["q2.x", "q5", "time"], [f"q{j}" for j in range(1, 7)]])
def test_the_not_significant_line_names_every_joint_and_variable_left_out(significant) -> None:
    names = [f"q{j}{a}" for j in range(1, 7) for a in ("", ".x")]
    diags = [{"variable": v, "significant": v in significant} for v in names]
    diags += [{"variable": v, "significant": v in significant} for v in ("time", "pose")]
    line = not_significant_line(diags)
    quiet = sorted(set(range(1, 7)) - {int(v[1]) for v in significant if v.startswith("q")})
    assert (joints_text(quiet) in line) if quiet else ("joint" not in line), line
    assert ("time" in line) is ("time" not in significant) and "pose" in line
    assert line.startswith("no diagnostic is significant") is (not significant)


# ------------------------------------------------------------------------------ terminal lines and held parameters


def test_every_terminal_line_is_short_and_every_warning_names_an_action(run) -> None:
    rep, _folder, stdout, err = run
    for ln in (stdout + err).splitlines():
        assert len(ln) <= LINE_MAX_CHARS, (len(ln), ln)
        if ln.startswith("compplan: warning:"):
            assert ACTION.search(ln), ln
    held = _line(stdout, f"{rep['held_parameters']['count']} parameters held at nominal")
    assert ACTION.search(held) and "report.json 'held_parameters'" in held


def test_every_held_parameter_is_in_one_group(run) -> None:
    rep, folder, _out, _err = run
    hp = rep["held_parameters"]
    names = [n for g in hp["groups"] for n in g["names"]]
    assert sorted(names) == sorted(h["name"] for h in rep["identifiability"]["held"])  # each exactly once
    kinds = {g["kind"]: g for g in hp["groups"]}
    assert set(kinds["setup_alias"]["names"]) == set(rep["base_frame_aliases"])
    assert all(g["action"] for g in hp["groups"]) and hp["count"] == len(names)
    md = (folder / "report.md").read_text()
    section = md.split("## Held parameters")[1].split("\n## ")[0]
    assert all(n in section for n in names)


def test_the_held_line_stays_one_line_at_its_longest() -> None:
    many = [f"p{i}" for i in range(150)]
    worst = HeldSummary(
        [
            HeldGroup("setup_alias", many[:100], "", "none"),
            HeldGroup("redundant", many[:110], "", "none"),
            HeldGroup("undetermined", many, "", "add poses and loads exercising joints 1, 2, 4, 5", [1, 2, 4, 5]),
        ]
    )
    assert len("  " + worst.message) <= min(HELD_MESSAGE_MAX_CHARS, LINE_MAX_CHARS)
