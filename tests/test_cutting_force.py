"""The mechanistic milling force (models/cutting/force.py) and the coefficient table
(models/cutting/material.py) against closed forms and independent integrations written here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from models.cutting.cutter import CutterShape, EndMill
from models.cutting.engagement import EngagementBatch
from models.cutting.force import (
    MAX_FEED_PER_TOOTH_M,
    CutWrench,
    cut_wrench,
    instantaneous_wrench,
    mean_force_design,
)
from models.cutting.material import (
    MIN_CUTTING_N_M2,
    MIN_EDGE_N_M,
    CuttingCoefficients,
    material,
    material_names,
)
from models.errors import InputError

#: Flat end mill: the mean is a midpoint sum over 1-degree bins whose edges hit the immersion limits;
#: its error is about (pi/180)^2 / 24 = 1.3e-5 of the integrand's scale.  Tolerance on the wrench,
#: relative to its largest force component.
FLAT_MEAN_RTOL = 1e-3
#: Ball and bull-nose end mills: the module integrates each slice exactly in z
#: (Gauss-Legendre in kappa), so only the 1-degree midpoint sum in phi is left (about 1e-5).
BALL_MEAN_RTOL = 1e-3
#: The mean over a revolution and the average of the instantaneous wrench over rotations at every
#: angle bin are the same sum, reordered (float rounding only).
REORDER_RTOL = 1e-9
#: Peak of one straight tooth: sampled 10 degrees apart (90 deg among them), evaluated at bin centres
#: (0.5 deg off) and in single precision.
PEAK_RTOL = 1e-4
#: Helical flank, instantaneous force against the integral over z: each slice's angle is snapped to its
#: bin (+-0.5 deg) and the entry/exit jumps of the edge force fall within one slice.
HELIX_INSTANT_RTOL = 1e-2

J = 360
DZ = 1e-4
C = 1e-4  # feed per tooth, m (0.1 mm)
COEFFS = CuttingCoefficients(796e6, 168.8e6, 222e6, 27.7e3, 30.8e3, 1.4e3, name="test")


def flat_mill(flutes: int = 4, helix_deg: float = 0.0, d: float = 0.01) -> EndMill:
    return EndMill(CutterShape.FLAT, d, 0.0, flutes, math.radians(helix_deg), 0.02, 0.05)


def ball_mill(flutes: int = 2, helix_deg: float = 30.0, d: float = 0.01) -> EndMill:
    return EndMill(CutterShape.BALL, d, d / 2, flutes, math.radians(helix_deg), 0.02, 0.05)


def batch_for(mill: EndMill, depth_m: float, phi_st: float, phi_ex: float) -> EngagementBatch:
    """Mask of one sample: slices below ``depth_m``, bins whose centre lies in [phi_st, phi_ex]."""
    n_slices = math.ceil(mill.flute_length_m / DZ - 1e-9)
    z = (np.arange(n_slices) + 0.5) * DZ
    phi = (np.arange(J) + 0.5) * 2 * math.pi / J
    mask = (z < depth_m)[:, None] & ((phi >= phi_st) & (phi <= phi_ex))[None, :]
    return EngagementBatch(mask[None], DZ)


def flat_mean_closed_form(k: CuttingCoefficients, n: int, a: float, c: float, R: float, st: float, ex: float):
    """Mean [Fx, Fy, Fz, Mz] of a flat end mill, axial depth a, immersion [st, ex] (force on the tool):
    N a / (2 pi) times the integral over phi of the per-unit-height forces, integrated by hand."""

    def prim(p: float) -> np.ndarray:
        s, co = math.sin(p), math.cos(p)
        fx = -k.Ktc * c * s * s / 2 - k.Kte * s - k.Krc * c * (p / 2 - math.sin(2 * p) / 4) + k.Kre * co
        fy = k.Ktc * c * (p / 2 - math.sin(2 * p) / 4) - k.Kte * co - k.Krc * c * s * s / 2 - k.Kre * s
        fz = k.Kac * c * co - k.Kae * p
        mz = R * (-k.Ktc * c * co + k.Kte * p)
        return np.array([fx, fy, fz, mz])

    return n * a / (2 * math.pi) * (prim(ex) - prim(st))


@pytest.mark.parametrize("helix_deg", [0.0, 30.0])
@pytest.mark.parametrize(
    "st, ex",
    [(0.0, math.pi), (0.0, math.pi / 2), (math.pi / 2, math.pi)],
    ids=["slot", "half_up", "half_down"],
)
def test_flat_mean_matches_closed_form(helix_deg, st, ex):
    mill = flat_mill(4, helix_deg)
    a = 3e-3
    d = mean_force_design(mill, batch_for(mill, a, st, ex), C)
    got = d[0] @ COEFFS.as_vector()
    want = flat_mean_closed_form(COEFFS, 4, a, C, mill.radius_m, st, ex)
    scale = np.abs(want[:3]).max()
    np.testing.assert_allclose(got[[0, 1, 2]], want[:3], atol=FLAT_MEAN_RTOL * scale)
    np.testing.assert_allclose(got[5], want[3], rtol=FLAT_MEAN_RTOL)
    # moments of the flank's slices about the tip: Mx = y Fz - z Fy, My = z Fx - x Fz averaged
    phi = np.linspace(st, ex, 20001)
    fz_phi = -(COEFFS.Kac * C * np.sin(phi) + COEFFS.Kae)
    w = 4 * a / (2 * math.pi)
    mx = w * mill.radius_m * np.trapezoid(np.cos(phi) * fz_phi, phi) - (a / 2) * want[1]
    my = (a / 2) * want[0] - w * mill.radius_m * np.trapezoid(np.sin(phi) * fz_phi, phi)
    np.testing.assert_allclose(got[3:5], [mx, my], atol=FLAT_MEAN_RTOL * scale * a)


def corner_density(u: float, phi: float, R: float, r: float, k: CuttingCoefficients, c: float) -> np.ndarray:
    """Wrench per unit angle ``u = kappa`` (on a corner of radius ``r``, lower part of a ball or a
    torus) and unit ``phi`` of Altintas' general end-mill model: ``z = r (1 - cos u)``,
    ``rho = (R - r) + r sin u``, ``dz = r sin u du``, chip ``h db = c sin(phi) dz``, edge length
    ``dS = r du`` (the meridian's)."""
    sk, ck = math.sin(u), math.cos(u)
    s, co = math.sin(phi), math.cos(phi)
    chip, edge = c * s * r * sk, r
    ft, fr, fa = (k.Ktc * chip + k.Kte * edge, k.Krc * chip + k.Kre * edge, k.Kac * chip + k.Kae * edge)
    f = np.array(
        [-sk * s * fr - co * ft - ck * s * fa, -sk * co * fr + s * ft - ck * co * fa, ck * fr - sk * fa],
    )
    rho = (R - r) + r * sk
    pos = np.array([rho * s, rho * co, r * (1 - ck)])
    return np.concatenate([f, np.cross(pos, f)])


def flank_density(z: float, phi: float, R: float, k: CuttingCoefficients, c: float) -> np.ndarray:
    """Wrench per unit height and unit ``phi`` on the flank (kappa = pi/2, dS = dz)."""
    s, co = math.sin(phi), math.cos(phi)
    ft, fr, fa = k.Ktc * c * s + k.Kte, k.Krc * c * s + k.Kre, k.Kac * c * s + k.Kae
    f = np.array([-s * fr - co * ft, -co * fr + s * ft, -fa])
    return np.concatenate([f, np.cross(np.array([R * s, R * co, z]), f)])


def corner_mill_mean(R: float, r: float, flutes: int, a: float) -> np.ndarray:
    """Mean wrench of a slot [0, pi] at depth ``a`` by scipy: the corner over kappa, the flank over z."""
    want = np.empty(6)
    u_max = math.acos(1 - min(a, r) / r)
    for i in range(6):
        total = integrate.dblquad(
            lambda phi, u, i=i: corner_density(u, phi, R, r, COEFFS, C)[i], 0.0, u_max, 0.0, math.pi, epsabs=1e-10
        )[0]
        if a > r:
            total += integrate.dblquad(
                lambda phi, z, i=i: flank_density(z, phi, R, COEFFS, C)[i], r, a, 0.0, math.pi, epsabs=1e-10
            )[0]
        want[i] = flutes / (2 * math.pi) * total
    return want


@pytest.mark.parametrize(
    "shape, r, a",
    [(CutterShape.BALL, 5e-3, 2e-3), (CutterShape.BULL_NOSE, 1e-3, 2.5e-3)],
    ids=["ball_2mm", "bull_nose_2.5mm"],
)
def test_corner_mill_mean_matches_numerical_integration(shape, r, a):
    mill = EndMill(shape, 0.01, r, 2, math.radians(30.0), 0.02, 0.05)
    got = mean_force_design(mill, batch_for(mill, a, 0.0, math.pi), C)[0] @ COEFFS.as_vector()
    want = corner_mill_mean(mill.radius_m, r, 2, a)
    np.testing.assert_allclose(got[:3], want[:3], atol=BALL_MEAN_RTOL * np.abs(want[:3]).max())
    np.testing.assert_allclose(got[3:], want[3:], atol=BALL_MEAN_RTOL * np.abs(want[3:]).max())


def random_batch(mill: EndMill, n: int, seed: int) -> tuple[EngagementBatch, np.ndarray]:
    rng = np.random.default_rng(seed)
    n_slices = math.ceil(mill.flute_length_m / DZ - 1e-9)
    mask = np.zeros((n, n_slices, J), bool)
    for s in range(n):
        depth = rng.integers(1, 60)
        for k in range(depth):
            j0 = rng.integers(0, 150)
            mask[s, k, j0 : rng.integers(j0 + 1, 181)] = True
    return EngagementBatch(mask, DZ), rng.uniform(2e-5, 2e-4, n)


@pytest.mark.parametrize("mill", [ball_mill(3, 30.0), flat_mill(4, 45.0)], ids=["ball", "flat"])
def test_mean_equals_average_of_instantaneous(mill):
    batch, c = random_batch(mill, 3, seed=1)
    theta = (np.arange(J) + 0.5) * 2 * math.pi / J  # every bin once per flute
    inst = instantaneous_wrench(mill, COEFFS, batch, c, theta)
    mean = mean_force_design(mill, batch, c) @ COEFFS.as_vector()
    np.testing.assert_allclose(inst.mean(axis=1), mean, rtol=REORDER_RTOL, atol=1e-12 * np.abs(mean).max())


def test_peak_of_one_straight_tooth_in_a_slot():
    mill = flat_mill(1, 0.0)
    a = 2e-3
    w = cut_wrench(mill, COEFFS, batch_for(mill, a, 0.0, math.pi), C)
    k = COEFFS
    # |F|^2 = a^2 (Ft^2 + Fr^2 + Fa^2) with each linear in sin(phi) and positive: largest at phi = pi/2
    want = a * math.sqrt((k.Ktc * C + k.Kte) ** 2 + (k.Krc * C + k.Kre) ** 2 + (k.Kac * C + k.Kae) ** 2)
    assert w.peak_force_N[0] == pytest.approx(want, rel=PEAK_RTOL)


def test_helical_instantaneous_force_matches_integral_over_z():
    mill = flat_mill(2, 30.0)
    R, a, tan_b = mill.radius_m, 4e-3, math.tan(mill.helix_rad)
    theta = np.radians([20.0, 75.0, 130.0, 170.0])
    got = instantaneous_wrench(mill, COEFFS, batch_for(mill, a, 0.0, math.pi), C, theta, rows=3)[0]
    k = COEFFS

    def force(z: float, th: float, i: int) -> float:
        out = 0.0
        for n in range(2):
            phi = (th + math.pi * n - z * tan_b / R) % (2 * math.pi)
            if phi > math.pi:
                continue
            s, co = math.sin(phi), math.cos(phi)
            ft, fr, fa = k.Ktc * C * s + k.Kte, k.Krc * C * s + k.Kre, k.Kac * C * s + k.Kae
            out += (-ft * co - fr * s, ft * s - fr * co, -fa)[i]
        return out

    want = np.array(
        [[integrate.quad(force, 0.0, a, args=(th, i), limit=200, points=None)[0] for i in range(3)] for th in theta]
    )
    scale = np.linalg.norm(want, axis=1).max()
    np.testing.assert_allclose(got, want, atol=HELIX_INSTANT_RTOL * scale)


def test_air_gives_exactly_zero():
    mill = ball_mill()
    batch = EngagementBatch(np.zeros((3, 200, J), bool), DZ)
    w = cut_wrench(mill, COEFFS, batch, C)
    assert np.all(w.mean == 0.0) and np.all(w.peak_force_N == 0.0)
    assert np.all(mean_force_design(mill, batch, C) == 0.0)


def test_mean_linear_in_feed_and_design_reproduces_cut_wrench():
    mill = ball_mill(2, 30.0)
    batch, _ = random_batch(mill, 4, seed=2)
    k = COEFFS.as_vector()
    f0, f1, f2 = (mean_force_design(mill, batch, c) @ k for c in (0.0, C, 2 * C))
    np.testing.assert_allclose(f2 - f1, f1 - f0, rtol=1e-12, atol=1e-9 * np.abs(f1).max())
    assert np.abs(f1 - f0).max() > 0.1 * np.abs(f0).max()  # the feed matters
    c = np.array([1e-4, 5e-5, 2e-4, 1e-5])
    w = cut_wrench(mill, COEFFS, batch, c)
    np.testing.assert_allclose(mean_force_design(mill, batch, c) @ k, w.mean, rtol=1e-12)
    assert isinstance(w, CutWrench) and w.torque_Nm.shape == (4,)
    assert np.all(w.torque_Nm > 0) and np.all(w.peak_force_N >= np.linalg.norm(w.mean[:, :3], axis=1) * 0.999)
    np.testing.assert_allclose(w.power_W(-100.0), 100.0 * w.torque_Nm)


def test_feed_in_mm_or_wrong_shape_raises():
    mill = ball_mill()
    batch, _ = random_batch(mill, 2, seed=3)
    with pytest.raises(InputError, match="mm given as m"):
        mean_force_design(mill, batch, 0.1)
    with pytest.raises(InputError, match="shape"):
        mean_force_design(mill, batch, np.ones(3) * 1e-4)
    with pytest.raises(InputError, match="feed per tooth"):
        mean_force_design(mill, batch, -1e-4)
    assert MAX_FEED_PER_TOOTH_M < 0.05  # a typical 0.05 mm/tooth given in mm must be caught


def test_table_rows_have_sources_and_pass_the_si_checks():
    names = material_names()
    assert {"al7075_t6", "al6061_t6"} <= set(names)
    for name in names:
        m = material(name)
        v = m.as_vector()
        assert v.shape == (6,)
        assert 1e8 <= m.Ktc <= 1e10, name  # N/m^2: metals (aluminium ~2e8-1e9 .. nickel alloys ~5e9)
        assert np.abs(v[3:]).max() >= MIN_EDGE_N_M, name
        assert len(m.source) > 80 and "Tool:" in m.source and any(str(y) in m.source for y in range(1990, 2030))
    assert material("AL7075_T6") is material("al7075_t6")
    assert material("al7075_t6").Ktc == pytest.approx(796e6)
    with pytest.raises(InputError, match="al6061_t6"):
        material("unobtainium")


def test_coefficients_in_published_units_raise_with_the_si_value():
    with pytest.raises(InputError, match=r"N/mm\^2.*796000000"):
        CuttingCoefficients(796.0, 168.8, 222.0, 27.7e3, 30.8e3, 1.4e3)
    with pytest.raises(InputError, match=r"N/mm.*27700"):
        CuttingCoefficients(796e6, 168.8e6, 222e6, 27.7, 30.8, 1.4)
    CuttingCoefficients(796e6, 168.8e6, 222e6, 0.0, 0.0, 0.0)  # no edge force is allowed
    assert MIN_CUTTING_N_M2 < 3e8 and MIN_CUTTING_N_M2 > 5e3  # between metals in SI and in N/mm^2
    with pytest.raises(InputError, match="Ktc"):
        CuttingCoefficients(-796e6, 168.8e6, 222e6, 27.7e3, 30.8e3, 1.4e3)
    with pytest.raises(InputError, match="finite"):
        CuttingCoefficients(796e6, float("nan"), 222e6, 27.7e3, 30.8e3, 1.4e3)
