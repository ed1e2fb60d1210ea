"""Write the shipped example of ``compplan cutting fit``: ``docs/examples/slot_forces.csv`` (SYNTHETIC
mean cutting forces) and its cutter file ``docs/examples/slot_cutter.toml``.

The forces are not measured: they are the mechanistic model's mean forces
(:func:`problems.cutting.coefficient_fit.design_of_tests`) for the published coefficient set
``al6082_t6`` of the shipped table (``models/tables/cutting_materials.toml``: Al6082-T6, a review's
Table 5, doi:10.1186/s10033-021-00536-9) plus independent normal noise of standard deviation
:data:`NOISE_N` on every force component, seeded (:data:`SEED`), so the file is the same on every run.

Tests: slots at five feeds per tooth (the textbook identification) and down-milling half immersions at
two feeds, with a 12 mm three-flute flat end mill.

Run from the repository root: ``python benchmarks/make_slot_forces.py`` (``--check``: only compare
with the shipped files, exit 1 if they differ).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from models.cutting.cutter import CutterShape, EndMill
from models.cutting.material import material
from problems.cutting.coefficient_fit import design_of_tests
from problems.cutting.force_data import ForceTest, Milling, Spindle

#: Seed of the noise.
SEED = 35
#: Standard deviation of the noise on each force component, N.
NOISE_N = 2.0
#: The coefficient set the forces come from (a key of the shipped table).
MATERIAL = "al6082_t6"
#: The cutter: diameter, flutes, helix, flute length, stick-out (m, deg).
CUTTER = {"diameter": 0.012, "flutes": 3, "helix_deg": 30.0, "flute_length": 0.030, "length": 0.045}
#: (feed per tooth mm, axial depth mm, radial width mm or None, milling).
TESTS = [(c, 3.0, None, "slot") for c in (0.025, 0.05, 0.075, 0.1, 0.125)] + [
    (c, 3.0, 6.0, "down") for c in (0.05, 0.1)
]
ROOT = Path(__file__).resolve().parents[1]
CSV_PATH = ROOT / "docs" / "examples" / "slot_forces.csv"
CUTTER_PATH = ROOT / "docs" / "examples" / "slot_cutter.toml"


def mill() -> EndMill:
    c = CUTTER
    return EndMill(
        CutterShape.FLAT, c["diameter"], 0.0, c["flutes"], math.radians(c["helix_deg"]), c["flute_length"], c["length"]
    )


def csv_text() -> str:
    """The example's CSV text."""
    coeffs = material(MATERIAL)
    tests = [
        ForceTest(0, "", c * 1e-3, ap * 1e-3, None if ae is None else ae * 1e-3, Milling(m), Spindle.CW, np.zeros(6))
        for c, ap, ae, m in TESTS
    ]
    wrench = design_of_tests(mill(), tests, "example") @ coeffs.as_vector()
    noise = np.random.default_rng(SEED).normal(0.0, NOISE_N, size=(len(tests), 3))
    forces = wrench[:, :3] + noise
    k = coeffs.as_vector()
    lines = [
        "# SYNTHETIC example of a measured-force file (docs/cutting.md), not a measurement:",
        f"# mean forces of the mechanistic model for the shipped coefficient set '{MATERIAL}' ({coeffs.name}:",
        f"# Ktc {k[0] / 1e6:g}, Krc {k[1] / 1e6:g}, Kac {k[2] / 1e6:g} N/mm^2; Kte {k[3] / 1e3:g}, "
        f"Kre {k[4] / 1e3:g}, Kae {k[5] / 1e3:g} N/mm)",
        f"# plus normal noise of {NOISE_N:g} N on each force component (seed {SEED}); cutter: slot_cutter.toml.",
        "# Written by benchmarks/make_slot_forces.py.  Forces on the TOOL, feed frame, means over whole revolutions.",
        "test,feed_per_tooth_mm,axial_depth_mm,radial_width_mm,milling,Fx_N,Fy_N,Fz_N",
    ]
    for i, ((c, ap, ae, m), f) in enumerate(zip(TESTS, forces)):
        width = "" if ae is None else f"{ae:g}"
        lines.append(f"T{i + 1},{c:g},{ap:g},{width},{m},{f[0]:.2f},{f[1]:.2f},{f[2]:.2f}")
    return "\n".join(lines) + "\n"


def cutter_text() -> str:
    """The example's cutter file."""
    c = CUTTER
    return (
        "# The cutter of docs/examples/slot_forces.csv (compplan cutting fit --cutter; docs/cutting.md).\n"
        "[cutter]\n"
        'shape = "flat"\n'
        f"diameter = {c['diameter']!r}        # m\n"
        f"flutes = {c['flutes']}\n"
        f"helix_deg = {c['helix_deg']!r}\n"
        f"flute_length = {c['flute_length']!r}     # m\n"
        f"length = {c['length']!r}           # m, stick-out\n"
    )


def main(argv: list[str]) -> int:
    files = {CSV_PATH: csv_text(), CUTTER_PATH: cutter_text()}
    if "--check" in argv:
        stale = [str(p) for p, text in files.items() if not p.is_file() or p.read_text(encoding="utf-8") != text]
        if stale:
            print(f"differ from the generator: {', '.join(stale)}")
            return 1
        return 0
    for p, text in files.items():
        p.write_text(text, encoding="utf-8")
        print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
