"""The run record (planner/record/) is a leaf: the report reads it without importing the plan, and
the column names load without the reader's imports."""

from __future__ import annotations

import subprocess
import sys


def _modules_after(code: str) -> set[str]:
    out = subprocess.run(
        [sys.executable, "-c", f"{code}\nimport sys\nprint('\\n'.join(sorted(sys.modules)))"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return set(out.split())


def test_the_report_and_the_record_do_not_import_the_plan():
    mods = _modules_after("import planner.report.writer, planner.report.figures, planner.record.read")
    assert "planner.record.record" in mods
    plan = sorted(m for m in mods if m.startswith("planner.plan"))
    assert not plan, plan


def test_the_column_names_load_without_the_arm_model():
    mods = _modules_after("import planner.record.columns")
    assert "casadi" not in mods and "planner.record.read" not in mods
