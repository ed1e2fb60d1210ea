"""Cutting-coefficient identification (issue 35): the measured-force CSV, the test engagement, the
least-squares fit and ``compplan cutting fit``.

The forces are made by closed forms written here, independent of the force model: the mean forces of a
flat end mill's flank over a revolution (Altintas, *Manufacturing Automation*, 2nd ed., 2012, section
2.3), integrated by hand with the product's sign convention (forces on the tool, feed frame, ``Fz = -Fa``)::

    mean F = N a_p / (2 pi) * integral over [phi_st, phi_ex] of dF(phi) dphi

    Fx = -Ft cos(phi) - Fr sin(phi),  Fy = Ft sin(phi) - Fr cos(phi),  Fz = -Fa,  Mz = R Ft
    Ft = Ktc c sin(phi) + Kte,  Fr = Krc c sin(phi) + Kre,  Fa = Kac c sin(phi) + Kae

which for a slot ``[0, pi]`` is the textbook's ``Fx = -N a Krc c / 4 - N a Kre / pi``,
``Fy = N a Ktc c / 4 + N a Kte / pi``, ``Fz = -N a Kac c / pi - N a Kae / 2``.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from models.cutting.cutter import CutterShape, EndMill
from models.errors import InputError
from planner.cli import main
from problems.cutting.coefficient_fit import COEFFICIENT_NAMES, FitStatus, fit_coefficients
from problems.problem_file.cutter_section import parse_cutter_table
from problems.cutting.force_data import (
    ForceTable,
    ForceTest,
    Milling,
    Spindle,
    engagement_mask,
    engagement_of_test,
    immersion_range,
    read_force_csv,
)

#: A published set (Al6082-T6, SI): Ktc, Krc, Kac (N/m^2), Kte, Kre, Kae (N/m).
TRUE = np.array([631e6, 99e6, 273e6, 13e3, 10e3, 2.8e3])
#: Noise-free data from the closed form are recovered to this (relative): the slot's angle bins
#: make the model's integral exact to ~1e-7.
EXACT_RTOL = 1e-6
#: Partial immersions: the entry/exit angle falls within half an angle bin (0.025 deg) of the exact one.
PARTIAL_RTOL = 5e-3
#: A ball end mill's slot (corner slices of 0.1 mm, exact slice integrals; 1440 angle bins).
BALL_RTOL = 1e-5
#: Noise of the noisy tests, N, and how many standard errors an estimate may be off.
NOISE_N = 1.0
MAX_SIGMAS = 4.0
#: Replicates of the standard-error check, and the band the empirical/reported ratio must fall in.
REPLICATES = 60
STD_RATIO_BAND = (0.7, 1.35)

MILL = EndMill(CutterShape.FLAT, 0.012, 0.0, 3, math.radians(30.0), 0.030, 0.045)
FEEDS_M = (0.025e-3, 0.05e-3, 0.075e-3, 0.1e-3)


def closed_form(k: np.ndarray, c: float, a: float, phi_st: float, phi_ex: float, N: int, R: float) -> np.ndarray:
    """Mean [Fx, Fy, Fz, Mx, My, Mz] of a flat end mill's flank by the integrals above (Mx, My NaN)."""
    Ktc, Krc, Kac, Kte, Kre, Kae = k

    def span(f):
        return f(phi_ex) - f(phi_st)

    i_sc = span(lambda p: math.sin(p) ** 2 / 2.0)
    i_c = span(math.sin)
    i_ss = span(lambda p: p / 2.0 - math.sin(2.0 * p) / 4.0)
    i_s = span(lambda p: -math.cos(p))
    width = phi_ex - phi_st
    g = N * a / (2.0 * math.pi)
    fx = -Ktc * c * i_sc - Kte * i_c - Krc * c * i_ss - Kre * i_s
    fy = Ktc * c * i_ss + Kte * i_s - Krc * c * i_sc - Kre * i_c
    fz = -(Kac * c * i_s + Kae * width)
    mz = R * (Ktc * c * i_s + Kte * width)
    return g * np.array([fx, fy, fz, np.nan, np.nan, mz])


def textbook_slot(k: np.ndarray, c: float, a: float, N: int) -> np.ndarray:
    """The textbook's slot averages [Fx, Fy, Fz]."""
    Ktc, Krc, Kac, Kte, Kre, Kae = k
    return np.array(
        [
            -N * a * Krc * c / 4.0 - N * a * Kre / math.pi,
            N * a * Ktc * c / 4.0 + N * a * Kte / math.pi,
            -N * a * Kac * c / math.pi - N * a * Kae / 2.0,
        ]
    )


def make_test(c, a, milling, width=None, spindle=Spindle.CW, k=TRUE, noise=None, moments=False, line=2):
    """A test with closed-form forces (Mz kept only with ``moments``)."""
    ae = MILL.diameter_m if width is None else width
    st, ex = (0.0, math.pi) if milling is Milling.SLOT else _range(ae, milling)
    w = closed_form(k, c, a, st, ex, MILL.flutes, MILL.radius_m)
    if not moments:
        w[3:] = np.nan
    if spindle is Spindle.CCW:
        w[[1, 3, 5]] *= -1.0
    if noise is not None:
        w[:3] += noise
    return ForceTest(line, f"line {line}", c, a, width, milling, spindle, w)


def _range(ae, milling):
    """Entry/exit angles written out (up: [0, acos(1 - 2 ae/D)], down: [pi - that, pi])."""
    span = math.acos(1.0 - 2.0 * ae / MILL.diameter_m)
    return (0.0, span) if milling is Milling.UP else (math.pi - span, math.pi)


def slot_tests(depths=(2e-3, 3e-3), feeds=FEEDS_M, **kw):
    return [make_test(c, a, Milling.SLOT, **kw) for a in depths for c in feeds]


def test_closed_form_reduces_to_the_textbook_slot_averages() -> None:
    for c in FEEDS_M:
        w = closed_form(TRUE, c, 3e-3, 0.0, math.pi, 3, 0.006)
        np.testing.assert_allclose(w[:3], textbook_slot(TRUE, c, 3e-3, 3), rtol=1e-12)


def test_noise_free_slots_give_the_coefficients_exactly() -> None:
    fit = fit_coefficients(MILL, slot_tests())
    assert fit.status is FitStatus.OK, fit.reason
    np.testing.assert_allclose(fit.values, TRUE, rtol=EXACT_RTOL)
    assert fit.complete and fit.rank == 6 and fit.n_rows == 3 * 8
    np.testing.assert_allclose(fit.r_squared[:3], 1.0, atol=1e-9)
    assert np.all(np.isnan(fit.r_squared[3:]))


def test_mixed_engagements_and_a_ccw_spindle_are_fitted_together() -> None:
    tests = [make_test(c, 2e-3, Milling.SLOT) for c in FEEDS_M[:2]]
    tests += [make_test(c, 3e-3, Milling.UP, width=0.3 * MILL.diameter_m) for c in FEEDS_M]
    tests += [make_test(c, 4e-3, Milling.DOWN, width=0.45 * MILL.diameter_m, spindle=Spindle.CCW) for c in FEEDS_M]
    fit = fit_coefficients(MILL, tests)
    assert fit.status is FitStatus.OK, fit.reason
    np.testing.assert_allclose(fit.values, TRUE, rtol=PARTIAL_RTOL)


def test_partial_immersions_alone_identify_the_coefficients() -> None:
    tests = [make_test(c, 3e-3, m, width=0.27 * MILL.diameter_m) for m in (Milling.UP, Milling.DOWN) for c in FEEDS_M]
    fit = fit_coefficients(MILL, tests)
    assert fit.status is FitStatus.OK, fit.reason
    np.testing.assert_allclose(fit.values, TRUE, rtol=PARTIAL_RTOL)


def test_noisy_slots_recovered_within_their_standard_errors() -> None:
    rng = np.random.default_rng(7)
    tests = slot_tests(feeds=(0.02e-3, 0.04e-3, 0.06e-3, 0.08e-3, 0.1e-3, 0.12e-3), noise=None)
    noisy = [
        ForceTest(t.line, t.label, t.feed_per_tooth_m, t.axial_depth_m, None, t.milling, t.spindle, w)
        for t, w in zip(tests, _noisy([t.wrench for t in tests], rng))
    ]
    fit = fit_coefficients(MILL, noisy)
    assert fit.status is FitStatus.OK, fit.reason
    err = np.abs(fit.values - TRUE)
    assert np.all(err < MAX_SIGMAS * fit.std_errors), dict(zip(COEFFICIENT_NAMES, err / fit.std_errors))
    assert np.all(fit.std_errors / TRUE < 0.1)  # 1 N of noise on ~100 N: the coefficients to a few per cent
    assert fit.dof == fit.n_rows - 6 and np.all(fit.r_squared[:3] > 0.99)


def _noisy(wrenches, rng):
    out = []
    for w in wrenches:
        w = np.array(w, dtype=float)
        w[:3] += rng.normal(0.0, NOISE_N, 3)
        out.append(w)
    return out


def test_standard_errors_match_the_scatter_of_repeated_fits() -> None:
    tests = slot_tests(depths=(3e-3,), feeds=(0.03e-3, 0.06e-3, 0.09e-3, 0.12e-3))
    rng = np.random.default_rng(11)
    est, reported = [], []
    for _ in range(REPLICATES):
        noisy = [
            ForceTest(t.line, t.label, t.feed_per_tooth_m, t.axial_depth_m, None, t.milling, t.spindle, w)
            for t, w in zip(tests, _noisy([t.wrench for t in tests], rng))
        ]
        fit = fit_coefficients(MILL, noisy)
        est.append(fit.values)
        reported.append(fit.std_errors)
    ratio = np.std(est, axis=0, ddof=1) / np.sqrt(np.mean(np.square(reported), axis=0))
    lo, hi = STD_RATIO_BAND
    assert np.all((ratio > lo) & (ratio < hi)), dict(zip(COEFFICIENT_NAMES, ratio))


def test_one_feed_only_is_underdetermined_with_a_reason() -> None:
    fit = fit_coefficients(MILL, slot_tests(feeds=(0.05e-3,)))
    assert fit.status is FitStatus.UNDERDETERMINED
    assert "one feed per tooth only" in fit.reason and "two or more feeds" in fit.reason
    assert not fit.identified.any() and np.all(np.isnan(fit.values))
    with pytest.raises(InputError, match="not identified"):
        fit.coefficients("x", "y")


def test_no_axial_force_leaves_kac_and_kae_unidentified() -> None:
    tests = slot_tests()
    for t in tests:
        t.wrench[2] = np.nan
    fit = fit_coefficients(MILL, tests)
    assert fit.status is FitStatus.UNDERDETERMINED
    assert "Fz_N" in fit.reason and "Kac" in fit.reason
    assert fit.identified.tolist() == [True, True, False, True, True, False]
    np.testing.assert_allclose(fit.values[[0, 1, 3, 4]], TRUE[[0, 1, 3, 4]], rtol=EXACT_RTOL)


def test_two_feeds_fit_exactly_without_standard_errors() -> None:
    fit = fit_coefficients(MILL, slot_tests(depths=(3e-3,), feeds=FEEDS_M[:2]))
    assert fit.status is FitStatus.OK and fit.dof == 0
    assert np.all(np.isnan(fit.std_errors)) and any("no standard errors" in n for n in fit.notes)


def test_measured_torque_is_a_row_of_the_fit() -> None:
    tests = slot_tests(moments=True)
    fit = fit_coefficients(MILL, tests)
    assert fit.n_rows == 4 * len(tests)
    np.testing.assert_allclose(fit.values, TRUE, rtol=EXACT_RTOL)
    assert fit.r_squared[5] > 1.0 - 1e-9


def test_nearly_equal_feeds_are_ill_conditioned() -> None:
    fit = fit_coefficients(MILL, slot_tests(feeds=(0.1e-3, 0.101e-3, 0.102e-3)))
    assert fit.status is FitStatus.ILL_CONDITIONED and fit.condition_number > 100.0
    assert "spread the feeds" in fit.reason
    textbook = fit_coefficients(MILL, slot_tests())
    assert textbook.condition_number < 10.0


def test_an_outlier_makes_a_poor_fit() -> None:
    tests = slot_tests()
    tests[3].wrench[1] += 200.0
    fit = fit_coefficients(MILL, tests)
    assert fit.status is FitStatus.POOR_FIT and "Fy R^2" in fit.reason
    assert np.nanargmax(np.abs(fit.residuals[:, 1])) == 3


def test_forces_on_the_workpiece_are_implausible() -> None:
    tests = slot_tests()
    for t in tests:
        t.wrench[:3] *= -1.0
    fit = fit_coefficients(MILL, tests)
    assert fit.status is FitStatus.IMPLAUSIBLE and "workpiece" in fit.reason


def ball_slot(k: np.ndarray, c: float, a: float, N: int, r: float) -> np.ndarray:
    """Mean [Fx, Fy, Fz] of a ball end mill (radius r) in a slot of depth a <= r, integrated by hand.

    On the ball ``z = r (1 - cos kappa)``, ``dz = r sin(kappa) dkappa``, the chip ``h db = c sin(phi) dz``
    and the edge element the meridian's ``dS = r dkappa``; the force on the tool
    ``dFx = -sin k sin phi dFr - cos phi dFt - cos k sin phi dFa``, ``dFy = -sin k cos phi dFr + sin phi dFt
    - cos k cos phi dFa``, ``dFz = cos k dFr - sin k dFa``; over phi in [0, pi]: int sin^2 = pi/2,
    int sin = 2, int sin cos = int cos = 0, int 1 = pi."""
    Ktc, Krc, Kac, Kte, Kre, Kae = k
    k1 = math.acos((r - a) / r)
    int_sin_dz = r * (k1 / 2.0 - math.sin(2.0 * k1) / 4.0)  # int sin(kappa) dz
    int_cos_dz = r * math.sin(k1) ** 2 / 2.0  # int cos(kappa) dz
    int_ds, int_sin_ds, int_cos_ds = r * k1, a, r * math.sin(k1)  # int dS, int sin dS, int cos dS
    g = N / (2.0 * math.pi)
    fx = -(Krc * c * math.pi / 2 * int_sin_dz + 2 * Kre * int_sin_ds + Kac * c * math.pi / 2 * int_cos_dz)
    fx -= 2 * Kae * int_cos_ds
    fy = Ktc * c * math.pi / 2 * a + 2 * Kte * int_ds
    fz = 2 * Krc * c * int_cos_dz + math.pi * Kre * int_cos_ds - 2 * Kac * c * int_sin_dz - math.pi * Kae * a
    return g * np.array([fx, fy, fz])


def test_ball_end_mill_slots_recover_the_coefficients() -> None:
    ball = EndMill(CutterShape.BALL, 0.010, 0.005, 2, math.radians(30.0), 0.020, 0.040)
    tests = []
    for a in (2e-3, 4e-3):
        for c in FEEDS_M:
            w = np.full(6, np.nan)
            w[:3] = ball_slot(TRUE, c, a, ball.flutes, ball.radius_m)
            tests.append(ForceTest(2, "", c, a, None, Milling.SLOT, Spindle.CW, w))
    fit = fit_coefficients(ball, tests)
    assert fit.status is FitStatus.OK, fit.reason
    np.testing.assert_allclose(fit.values, TRUE, rtol=BALL_RTOL)


# ------------------------------------------------------------------ the engagement
def test_flank_masks_engage_the_textbook_angles() -> None:
    D = MILL.diameter_m
    for milling, ae in ((Milling.UP, 0.25 * D), (Milling.DOWN, 0.25 * D), (Milling.SLOT, D)):
        st, ex = (0.0, math.pi) if milling is Milling.SLOT else _range(ae, milling)
        assert immersion_range(D, ae, milling) == pytest.approx((st, ex), abs=1e-12)
        batch = engagement_mask(MILL, 2e-3, ae, milling, angle_bins=360)
        phi = batch.angles_rad()
        on = batch.mask[0].all(axis=0)
        assert np.array_equal(on, (phi >= st) & (phi <= ex))
        assert batch.axial_depth_m()[0] == pytest.approx(2e-3)


def test_ball_end_mill_slices_below_the_wall_are_not_engaged() -> None:
    ball = EndMill(CutterShape.BALL, 0.010, 0.005, 2, math.radians(30.0), 0.020, 0.040)
    ae = 0.002  # wall at 3 mm from the axis: slices with rho(z) < 3 mm are in air
    batch = engagement_mask(ball, 3e-3, ae, Milling.UP, angle_bins=360)
    rho = ball.radius_at(batch.slice_heights_m())
    engaged = batch.mask[0].any(axis=1)
    assert np.array_equal(engaged, rho >= ball.radius_m - ae)
    k = int(np.argmax(engaged))
    phi = batch.angles_rad()[batch.mask[0, k]]
    assert np.all(rho[k] * np.cos(phi) >= ball.radius_m - ae)


def test_a_test_the_cutter_cannot_make_is_refused() -> None:
    deep = make_test(0.05e-3, 0.04, Milling.SLOT, line=7)
    with pytest.raises(InputError, match=r"f\.csv: line 7, column 'axial_depth_mm'.*flute length"):
        engagement_of_test(MILL, "f.csv", deep)
    narrow_slot = make_test(0.05e-3, 2e-3, Milling.SLOT, width=0.008, line=4)
    with pytest.raises(InputError, match=r"line 4, column 'radial_width_mm'.*slot cuts the cutter's diameter"):
        engagement_of_test(MILL, "f.csv", narrow_slot)


# ------------------------------------------------------------------ the CSV
HEADER = "test,feed_per_tooth_mm,axial_depth_mm,radial_width_mm,milling,Fx_N,Fy_N,Fz_N"


def _write(tmp_path: Path, rows: list[str], header: str = HEADER, name: str = "f.csv") -> Path:
    p = tmp_path / name
    p.write_text("# a comment\n" + header + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return p


def test_reader_converts_units_and_defaults(tmp_path: Path) -> None:
    p = _write(
        tmp_path,
        ["A,0.05,3,,slot,-40,110,-50", "B,0.1,2.5,4,Down,20,70,"],
        header=HEADER + ",spindle",
    )
    p.write_text(p.read_text().replace("-50\n", "-50,ccw\n").replace("70,\n", "70,,\n"))
    table = read_force_csv(p)
    a, b = table.tests
    assert (a.label, a.line, a.milling, a.spindle, a.radial_width_m) == ("A", 3, Milling.SLOT, Spindle.CCW, None)
    assert a.feed_per_tooth_m == pytest.approx(5e-5) and a.axial_depth_m == pytest.approx(3e-3)
    assert b.milling is Milling.DOWN and b.spindle is Spindle.CW and b.radial_width_m == pytest.approx(4e-3)
    assert np.isnan(b.wrench[2]) and np.all(np.isnan(a.wrench[3:]))


@pytest.mark.parametrize(
    "row,pattern",
    [
        ("A,0.05,3,,slot,abc,110,-50", r"f\.csv: line 3, column 'Fx_N': 'abc' is not a number"),
        ("A,-0.05,3,,slot,-40,110,-50", r"line 3, column 'feed_per_tooth_mm': -0\.05 is out of range; expected a feed"),
        ("A,5,3,,slot,-40,110,-50", r"column 'feed_per_tooth_mm': 5 is out of range.*\(0, 1\] mm"),
        ("A,0.05,3,,side,-40,110,-50", r"column 'milling': 'side' is not a choice; expected slot, up"),
        ("A,0.05,3,,up,-40,110,-50", r"column 'radial_width_mm': empty cell"),
        ("A,0.05,3,,slot,-40,,-50", r"column 'Fy_N': empty cell"),
        ("A,0.05,3,,slot,-40,110", r"line 3: 7 cells; expected 8"),
    ],
)
def test_bad_cells_name_file_line_and_column(tmp_path: Path, row: str, pattern: str) -> None:
    with pytest.raises(InputError, match=pattern):
        read_force_csv(_write(tmp_path, [row]))


@pytest.mark.parametrize(
    "header,pattern",
    [
        ("feed_per_tooth_mm,axial_depth_mm,radial_width_mm,milling,Fx,Fy_N", r"unknown column 'Fx'.*units belong"),
        ("feed_per_tooth_mm,axial_depth_mm,radial_width_mm,milling,fx_n,Fy_N", r"did you mean 'Fx_N'"),
        ("feed_per_tooth_mm,axial_depth_mm,milling,Fx_N,Fy_N", r"missing column\(s\) radial_width_mm"),
        ("feed_per_tooth_mm;axial_depth_mm;radial_width_mm;milling;Fx_N;Fy_N", r"separated by ';'"),
    ],
)
def test_bad_headers_are_named(tmp_path: Path, header: str, pattern: str) -> None:
    with pytest.raises(InputError, match=r"f\.csv: line 2: .*" + pattern):
        read_force_csv(_write(tmp_path, ["0.05,3,,slot,1,2"], header=header))


def test_empty_and_headerless_files(tmp_path: Path) -> None:
    p = tmp_path / "e.csv"
    p.write_text("# only a comment\n")
    with pytest.raises(InputError, match="e.csv: empty file"):
        read_force_csv(p)
    p.write_text(HEADER + "\n")
    with pytest.raises(InputError, match="e.csv: no test rows"):
        read_force_csv(p)


# ------------------------------------------------------------------ the cutter table
def test_cutter_table_reads_an_end_mill_and_names_keys_with_the_prefix() -> None:
    table = {"shape": "bull_nose", "diameter": 0.01, "corner_radius": 0.001, "flutes": 4, "helix_deg": 35}
    table |= {"flute_length": 0.02, "length": 0.05}
    m = parse_cutter_table("p.toml", table, "robot.tool.cutter")
    assert (m.shape, m.diameter_m, m.corner_radius_m, m.flutes) == (CutterShape.BULL_NOSE, 0.01, 0.001, 4)
    assert m.helix_rad == pytest.approx(math.radians(35))
    with pytest.raises(InputError, match=r"p\.toml: key 'robot\.tool\.cutter\.diameter'.*in metres \(millimetres"):
        parse_cutter_table("p.toml", table | {"diameter": 10}, "robot.tool.cutter")
    with pytest.raises(InputError, match=r"key 'cutter\.corner_radius' is required"):
        parse_cutter_table("c.toml", {k: v for k, v in table.items() if k != "corner_radius"}, "cutter")
    with pytest.raises(InputError, match=r"c\.toml.*cutter.*radius"):
        parse_cutter_table("c.toml", table | {"radius": 1}, "cutter")
    with pytest.raises(InputError, match=r"key 'cutter\.length' is required"):
        parse_cutter_table("c.toml", {k: v for k, v in table.items() if k != "length"}, "cutter")
    ball = parse_cutter_table("c.toml", {"shape": "ball", "diameter": 0.01, "flutes": 2, "helix_deg": 0,
                                         "flute_length": 0.02}, "cutter", length_required=False)  # fmt: skip
    assert ball.corner_radius_m == 0.005 and ball.length_m == 0.02


# ------------------------------------------------------------------ the command line
CUTTER_TOML = '[cutter]\nshape = "flat"\ndiameter = 0.012\nflutes = 3\nhelix_deg = 30.0\nflute_length = 0.03\n'


def _csv_rows(tests: list[ForceTest]) -> list[str]:
    rows = []
    for i, t in enumerate(tests):
        forces = ",".join(repr(float(x)) for x in t.wrench[:3])
        rows.append(f"T{i},{t.feed_per_tooth_m * 1e3!r},{t.axial_depth_m * 1e3!r},,slot,{forces}")
    return rows


def test_cli_fit_writes_the_three_files(tmp_path: Path, capsys) -> None:
    data = _write(tmp_path, _csv_rows(slot_tests()), name="al.csv")
    cutter = tmp_path / "cutter.toml"
    cutter.write_text(CUTTER_TOML)
    out = tmp_path / "fit"
    assert main(["cutting", "fit", "--data", str(data), "--cutter", str(cutter), "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["coefficients.toml", "fit.json", "report.html"]
    mat = tomllib.loads((out / "coefficients.toml").read_text())["material"]
    np.testing.assert_allclose([mat[n] for n in COEFFICIENT_NAMES], TRUE, rtol=1e-5)  # 6 digits written
    assert mat["name"] == "al" and mat["source"].startswith("fitted from al.csv on ")
    assert "data:image/png;base64," in (out / "report.html").read_text()
    assert "Ktc = 6.31e+08" in capsys.readouterr().out
    # a second run replaces its own earlier output
    assert main(["cutting", "fit", "--data", str(data), "--cutter", str(cutter), "--out", str(out)]) == 0


@pytest.mark.parametrize(
    "rows,cutter,pattern",
    [
        (["T1,0.05,3,,slot,x,1,1"], CUTTER_TOML, r"al\.csv: line 3, column 'Fx_N': 'x' is not a number"),
        (None, CUTTER_TOML.replace("0.012", "12"), r"key 'cutter\.diameter'.*in metres \(millimetres given\?\)"),
        ("one feed", CUTTER_TOML, r"cannot identify the cutting coefficients: one feed per tooth only"),
    ],
)
def test_cli_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path: Path, capsys, rows, cutter, pattern) -> None:
    if rows is None:
        rows = _csv_rows(slot_tests())
    elif rows == "one feed":
        rows = _csv_rows(slot_tests(feeds=(0.05e-3,)))
    data = _write(tmp_path, rows, name="al.csv")
    cutter_file = tmp_path / "cutter.toml"
    cutter_file.write_text(cutter)
    out = tmp_path / "fit"
    assert main(["cutting", "fit", "--data", str(data), "--cutter", str(cutter_file), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("compplan: error: ")
    assert __import__("re").search(pattern, err), err
    assert not out.exists()


def test_cli_materials_lists_the_shipped_table(capsys) -> None:
    from models.cutting.material import material_names

    assert main(["cutting", "materials"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in lines] == material_names()


def test_shipped_example_is_what_its_generator_writes_and_fits() -> None:
    import importlib.util

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("make_slot_forces", root / "benchmarks" / "make_slot_forces.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    assert gen.main(["--check"]) == 0
    table = read_force_csv(gen.CSV_PATH)
    fit = fit_coefficients(gen.mill(), table)
    assert fit.status is FitStatus.OK
    from models.cutting.material import material

    truth = material(gen.MATERIAL).as_vector()
    assert np.all(np.abs(fit.values - truth) < 2.0 * fit.std_errors)  # docs/cutting-fit.md: within +-2 sigma


def test_fit_accepts_a_force_table_and_rejects_none(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no tests"):
        fit_coefficients(MILL, ForceTable("t.csv", ()))


def test_cli_refuses_another_commands_folder_without_force(tmp_path: Path, capsys) -> None:
    data = _write(tmp_path, _csv_rows(slot_tests()), name="al.csv")
    cutter = tmp_path / "cutter.toml"
    cutter.write_text(CUTTER_TOML)
    out = tmp_path / "run"
    out.mkdir()
    (out / "pose.json").write_text("{}")
    args = ["cutting", "fit", "--data", str(data), "--cutter", str(cutter), "--out", str(out)]
    assert main(args) == 2
    assert "use --force" in capsys.readouterr().err and (out / "pose.json").exists()
    assert main([*args, "--force"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["coefficients.toml", "fit.json", "report.html"]
