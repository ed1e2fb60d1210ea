"""``compplan cutting fit | materials``: a material's cutting coefficients.

* ``fit``: identify the six mechanistic cutting coefficients from measured mean cutting forces (a
  CSV of steady cuts, ``docs/cutting.md``) and a cutter file, and write ``coefficients.toml`` (a
  ``[material]`` table for a problem file), ``fit.json`` and ``report.html`` into a folder.
* ``materials``: the shipped coefficient table (name and source of each material).

Only this module prints.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from planner.commands.common import add_force_argument, check_output, releases_outputs

#: Sub-commands defined here.
COMMANDS = ("cutting",)


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``compplan cutting`` and its actions."""
    p = sub.add_parser(
        "cutting",
        help="cutting coefficients: fit them to measured forces, list the shipped ones",
        description="A material's mechanistic cutting coefficients (Ktc, Krc, Kac in N/m^2; Kte, Kre, Kae in "
        "N/m): identify them from measured cutting forces, or list the shipped table (docs/cutting.md).",
    )
    actions = p.add_subparsers(dest="action", required=True)
    f = actions.add_parser(
        "fit",
        help="identify the cutting coefficients from measured mean cutting forces",
        description="Fit the six cutting coefficients to the mean forces of steady cuts (slots or partial "
        "immersions at several feeds per tooth) by linear least squares, and write coefficients.toml, "
        "fit.json and report.html into the --out folder (all three or none).",
    )
    f.add_argument(
        "--data",
        required=True,
        help="measured-force CSV: one row per test, columns feed_per_tooth_mm, axial_depth_mm, radial_width_mm, "
        "milling, Fx_N, Fy_N (Fz_N, moments, spindle optional; docs/cutting.md)",
    )
    f.add_argument(
        "--cutter",
        required=True,
        help="cutter TOML file with a [cutter] table: shape, diameter, corner_radius, flutes, helix_deg, "
        "flute_length (metres, degrees)",
    )
    f.add_argument("--out", required=True, help="output folder (coefficients.toml, fit.json, report.html)")
    f.add_argument(
        "--name", default=None, help="the material's name in coefficients.toml (default: the --data file's stem)"
    )
    add_force_argument(f)
    f.set_defaults(func=run_fit)
    m = actions.add_parser(
        "materials",
        help="list the shipped cutting coefficients (name and source)",
        description="List the materials of the shipped cutting-coefficient table, with the source of each.",
    )
    m.set_defaults(func=run_materials)


@releases_outputs
def run_fit(args: argparse.Namespace) -> int:
    """Fit, write the three files, print the coefficients."""
    from models.errors import InputError
    from planner.cutting_report import CUTTING_FIT_FILES, cutting_fit_outputs
    from planner.output import output_folder_kind
    from problems.cutting.coefficient_fit import COEFFICIENT_NAMES, COEFFICIENT_UNITS, fit_coefficients
    from problems.cutting.cutter_table import read_cutter_file
    from problems.cutting.force_data import read_force_csv

    out = Path(args.out)
    kind = output_folder_kind(out) if out.is_dir() else None
    if kind is not None and not args.force:
        raise InputError(
            f"--out {out}: holds {kind.phrase} ({kind.command}), which a cutting fit would replace whole; use "
            "--force to replace it, or another --out"
        )
    check_output(out, {"--data": args.data, "--cutter": args.cutter}, "folder", writes=CUTTING_FIT_FILES)
    mill = read_cutter_file(args.cutter)
    table = read_force_csv(args.data)
    fit = fit_coefficients(mill, table)
    if not fit.status.usable:
        raise InputError(f"{args.data}: cannot identify the cutting coefficients: {fit.reason}")
    name = args.name if args.name is not None else Path(args.data).stem
    cutting_fit_outputs(fit, mill, out, str(args.data), str(args.cutter), name).publish()
    print(
        f"cutting fit: {table.n} tests, {fit.n_rows} measured components, status {fit.status.value}, "
        f"condition number {fit.condition_number:.3g}"
    )
    for n, v, s, u in zip(COEFFICIENT_NAMES, fit.values, fit.std_errors, COEFFICIENT_UNITS):
        spread = f" +- {2.0 * s:.3g}" if s == s else ""
        print(f"  {n} = {v:.4g}{spread} {u}{' (2 sigma)' if spread else ''}")
    r2 = ", ".join(f"{a} {r:.4f}" for a, r in zip(("Fx", "Fy", "Fz", "Mx", "My", "Mz"), fit.r_squared) if r == r)
    if r2:
        print(f"  R^2: {r2}")
    for note in fit.notes:
        print(f"  note: {note}")
    if not fit.status.ok:
        print(f"compplan: warning: {fit.status.value}: {fit.reason}", file=sys.stderr)
    print(f"wrote {out}/: {', '.join(CUTTING_FIT_FILES)}")
    return 0


def run_materials(args: argparse.Namespace) -> int:
    """Print the shipped materials, one per line: name and source."""
    from models.cutting.material import material, material_names

    names = list(material_names())
    width = max((len(n) for n in names), default=0)
    for n in names:
        m = material(n)
        print(f"{n:<{width}}  {m.name}: {m.source}")
    return 0
