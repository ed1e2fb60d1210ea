"""The content of ``report.json``: :func:`report_dict`, its ``headline`` and the one-sentence
summaries of the structure left and of the compensation check."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from planner.numbers import format_number
from planner.provenance import builtin_robot_file, input_file, provenance
from problems.identify import IdentificationResult
from problems.identify.results import CandidateScore, held_summary


#: The base-frame and measurement-frame results of the compensation check agree when their fractions
#: of the error left differ by at most this (two points of the error before, the compensation tests'
#: acceptance level); otherwise :func:`compensation_sentence` says which to read and why they differ.
FRACTION_LEFT_AGREE = 0.02


def _mm(v: float | None) -> float | None:
    return None if v is None else float(v) * 1e3


def _history_dicts(res: IdentificationResult) -> list[dict[str, Any]]:
    """The selection history: one entry per step, with its candidates (mm)."""
    return [
        {
            "step": st.index,
            "effects": st.effects,
            "n_params": st.n_params,
            "rms_mm": _mm(st.rms_m),
            "cv_rms_mm": _mm(st.cv_rms_m),
            "bic": st.bic,
            "n_excluded": st.n_excluded,
            "accepted": st.accepted,
            "reason": st.reason,
            "candidates": [_candidate_dict(c) for c in st.candidates],
        }
        for st in res.history
    ]


def _candidate_dict(c: CandidateScore) -> dict[str, Any]:
    """One candidate's score at one step (mm)."""
    return {
        "effect": c.effect,
        "n_params": c.n_params,
        "cv_rms_mm": _mm(c.cv_rms_m),
        "rms_mm": _mm(c.rms_m),
        "bic": c.bic,
        "delta_bic": c.delta_bic,
        "f_pvalue": c.f_pvalue,
        "explained_share": c.explained_share,
        "refined": c.refined,
        "accepted": c.accepted,
        "reason": c.reason,
        "detail": getattr(c, "detail", "") or "",
        "held": c.held,
    }


def _parameter_dicts(res: IdentificationResult) -> list[dict[str, Any]]:
    """The identified parameters (SI), with their status."""
    return [
        {
            "name": p.name,
            "effect": p.effect,
            "value": p.value,
            "std": p.std,
            "unit": p.unit,
            "status": p.status.value,
            "reason": p.reason,
        }
        for p in res.parameters
    ]


def _diagnostic_dicts(res: IdentificationResult) -> list[dict[str, Any]]:
    """The diagnostics of the final residual."""
    return [
        {
            "variable": d.variable,
            "explained_fraction": d.explained_fraction,
            "p_value": d.p_value,
            "significant": d.significant,
            "description": d.description,
        }
        for d in res.diagnostics
    ]


def report_dict(
    res: IdentificationResult, model_path: str | None = None, data_path: str | None = None
) -> dict[str, Any]:
    """The content of ``report.json`` (SI inside the library, mm in the report)."""
    m = res.data
    out: dict[str, Any] = {
        "status": res.status.value,
        "reason": res.reason,
        "rms_before_mm": res.rms_before_mm,
        "rms_after_mm": res.rms_after_mm,
        "heldout_rms_before_mm": _mm(res.cv_rms_before_m),
        "heldout_rms_after_mm": _mm(res.cv_rms_after_m),
        "rms_definition": (
            "per-axis RMS sqrt(mean over rows and x, y, z of r^2), r = predicted - measured, "
            "inlier rows; 'before': nominal robot file with only the registration and the "
            "measured point fitted; 'heldout': K-fold cross-validation over whole poses"
        ),
        "noise_sigma_mm": _mm(res.noise_sigma_m),
        "noise_source": res.noise_source,
        "effects_added": list(res.effects_added),
        "error_maps": [s.to_dict() for s in getattr(res, "error_maps", None) or []],
        "unexplained": {**res.unexplained, "weak": bool(res.unexplained.get("weak", False))},
        "excluded_rows": res.excluded,
        "parameters": _parameter_dicts(res),
        "identifiability": res.identifiability,
        "diagnostics": _diagnostic_dicts(res),
        "history": _history_dicts(res),
        "notes": res.notes,
        "warnings": list(getattr(res, "warnings", [])),
        "data": {
            "file": data_path or m.source,
            "n_rows": m.n,
            "n_poses": res.identifiability.get("n_poses"),
            "registered": res.model.registered,
            "columns": sorted(m.units),
        },
        "model_file": model_path,
    }
    if res.identifiability.get("campaigns"):  # several campaigns (problems.identify.campaigns)
        out["campaigns"] = res.identifiability["campaigns"]
    if res.validation is not None:
        out["validation"] = res.validation
    if res.compensation_check is not None:
        out["compensation_check"] = res.compensation_check
    out["base_frame_aliases"] = _aliases(res)
    out["held_parameters"] = held_summary(res).to_dict()
    head = {"headline": headline(out), "provenance": provenance(_inputs(res, data_path))}
    return {**head, **out}


def _aliases(res: IdentificationResult) -> list[str]:
    """Parameters an unregistered identification cannot tell from the registration or the
    measured point (held at nominal): the base frame is not checkable through them."""
    try:
        from problems.identify import unobservable_in_base

        return list(unobservable_in_base(res.model))
    except Exception:
        return []


def _inputs(res: IdentificationResult, data_path: str | None) -> list[dict[str, Any]]:
    """Provenance inputs: the declared robot (its file when it is a built-in one unchanged), the
    measurement file and the validation file."""
    from models import load_robot

    nominal = res.model.nominal
    robot_file = builtin_robot_file(nominal.name)
    if robot_file is not None and load_robot(nominal.name).to_dict() != nominal.to_dict():
        robot_file = None
    entries = [input_file("declared robot", robot_file, name=nominal.name)]
    if robot_file is None:
        entries[0]["note"] = "a robot file of the user's (its path is the command line's --robot)"
    for role, f in (
        ("measurements", data_path or res.data.source),
        ("validation measurements", (res.validation or {}).get("file")),
    ):
        if not f:
            continue
        path = Path(str(f))
        entries.append(input_file(role, path if path.is_file() else None, name=path.name or str(f)))
    return entries


def compensation_sentence(rep: dict[str, Any], arrow: str = "→") -> str:
    """The compensation check in one sentence: first the figure to read (the measured point's error in
    the measurement frame, what an instrument checks, mm RMS before → after on new poses), then the
    base-frame figure and, when the two differ by more than :data:`FRACTION_LEFT_AGREE`, why (the
    terminal prints the same sentence with ``arrow="->"``)."""
    c = rep.get("compensation_check")
    if not c:
        return (
            "compensation not re-measured (no --truth): the held-out RMS is the estimate of what the "
            "model predicts on new poses"
        )

    def pct(f: float) -> str:
        return format_number(100 * f, 3)

    meas = (
        f"{format_number(c['meas_frame_rms_before_mm'])} {arrow} {format_number(c['meas_frame_rms_after_mm'])} mm "
        f"RMS in the measurement frame ({pct(c['meas_frame_fraction_left'])} % left, {c['n_poses']} new poses)"
    )
    base = f"{format_number(c['rms_before_mm'])} {arrow} {format_number(c['rms_after_mm'])} mm"
    if abs(c["fraction_left"] - c["meas_frame_fraction_left"]) <= FRACTION_LEFT_AGREE:
        return f"{meas}; in the base frame {base} ({pct(c['fraction_left'])} % left)"
    aliases = rep.get("base_frame_aliases") or []
    if aliases and not rep["data"]["registered"]:
        why = (
            f"the registration and measured point absorb {len(aliases)} aliased parameters held at nominal "
            "(parameters differ, predictions agree)"
        )
    else:
        why = "parameters held at nominal (held_parameters) move the TCP and the measured point differently"
    return f"{meas}: read this; the base frame's {pct(c['fraction_left'])} % left differs as {why}"


def structure_sentence(rep: dict[str, Any]) -> str:
    """The structure left in the residual in one sentence: "no structure ...", "weak structure
    remains ..." (significant but small: the status stays OK) or "structure remains ..."."""
    u = rep.get("unexplained") or {}
    msg = str(u.get("message") or "").strip()
    if not u.get("present"):
        return msg if msg.startswith("no ") else "no structure left" + (f": {msg}" if msg else "")
    if u.get("weak"):
        return (
            msg if msg.startswith("weak structure remains") else "weak structure remains" + (f": {msg}" if msg else "")
        )
    return msg if msg.startswith("structure remains") else "structure remains" + (f": {msg}" if msg else "")


def structure_value(rep: dict[str, Any]) -> str:
    """The short value of the headline's structure row."""
    u = rep.get("unexplained") or {}
    if not u.get("present"):
        return "none"
    return "weak structure remains" if u.get("weak") else "structure remains"


def _same_file(a: Any, b: Any) -> bool:
    """Whether two file names name the same file (the validation file given as the data itself)."""
    if not a or not b:
        return False
    try:
        return Path(str(a)).resolve() == Path(str(b)).resolve()
    except OSError:
        return str(a) == str(b)


def headline(rep: dict[str, Any]) -> dict[str, Any]:
    """What an engineer reads first: status, the validation file's RMS before/after (with
    ``--validation``), RMS before/after in-sample and held-out, noise floor, effects, structure left,
    joint error maps, held parameters, compensation."""

    def r4(v: float | None) -> float | None:
        from planner.numbers import round_sig

        return None if v is None else round_sig(float(v))

    maps = [
        {
            "joint": m["joint"],
            "component": m["component"],
            "main_freq_cpr": r4(m["harmonics"][0]["freq_cpr"]) if m["harmonics"] else None,
            "rms_tcp_um": r4(m["rms_tcp_um"]),
        }
        for m in rep.get("error_maps") or []
    ]
    v = rep.get("validation") or {}
    return {
        "status": rep["status"],
        "reason": rep["reason"],
        "validation_rms_before_mm": r4(v.get("rms_nominal_mm")),
        "validation_rms_after_mm": r4(v.get("rms_mm")),
        "validation_euclidean_mm": (
            {
                k: {q: r4(v[src][f"{q}_mm"]) for q in ("mean", "rms", "max")}
                for k, src in (("before", "euclidean_nominal"), ("after", "euclidean"))
            }
            if v.get("euclidean")
            else None
        ),
        "validation_held_out": (not _same_file(v.get("file"), rep["data"]["file"])) if v else None,
        "validation_coverage_2sigma": (v.get("where_it_holds") or {}).get("coverage_2sigma") if v else None,
        "rms_before_mm": r4(rep["rms_before_mm"]),
        "rms_after_mm": r4(rep["rms_after_mm"]),
        "heldout_rms_before_mm": r4(rep["heldout_rms_before_mm"]),
        "heldout_rms_after_mm": r4(rep["heldout_rms_after_mm"]),
        "noise_sigma_mm": r4(rep["noise_sigma_mm"]),
        "noise_source": rep["noise_source"],
        "effects_added": list(rep["effects_added"]),
        "registered": bool(rep["data"]["registered"]),
        "unexplained": structure_sentence(rep),
        "error_maps": maps,
        "held_parameters": (rep.get("held_parameters") or {}).get("message", ""),
        "compensation": compensation_sentence(rep),
        "definition": "per-axis RMS of predicted - measured, measurement frame, mm, 4 significant digits; "
        "validation: the --validation file, never used in the fit (before: the nominal robot file with the "
        "identified registration and measured point)",
    }
