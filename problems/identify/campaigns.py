"""Several measurement campaigns in one fit: one robot model, one registration per campaign.

A campaign is one measurement file: the arm measured with the instrument (tracker) set up once.
Between campaigns the instrument may have been moved, so each campaign ``c`` has its own
registration ``base2meas_c`` (base frame -> that campaign's measurement frame); the robot (its
geometry, stiffness and effects) and the measured point (the same tool or reflector) are shared.

Method (:func:`identify_campaigns`; the engine :func:`problems.identify.identify` has one
registration in its parameter vector and is used unchanged):

1. **Reference frame** -- the reference campaign's measurement frame: the campaign named
   (``reference``), else the one with the most rows (:func:`.campaign_checks.reference_index`); it is
   placed last in the merged table.  Each other campaign ``c`` gets
   a rigid transform ``A_c`` (campaign ``c``'s measurement frame -> the reference frame); its start
   is Kabsch of the nominal model's points (base frame, the same for every campaign) to the
   measured points of ``c`` and of the reference: ``A_c = B_ref inv(B_c)``.
2. **Merge** -- every campaign's measured points mapped by ``A_c`` into the reference frame, one
   table (:func:`merge_campaigns`: pose ids kept apart per campaign, time since each campaign's
   start, weights from each campaign's ``sigma``), and the engine identifies the model on it with
   its full effect selection.
3. **Joint Gauss-Newton** -- at that model, Gauss-Newton steps on the joint least-squares
   objective over the free robot parameters *and* the six parameters of every ``A_c``
   (``r = p_model - (exp([dphi]x) p' + dt)``, ``p' = A_c p``: ``dr/dphi = [p']x``, ``dr/dt = -I``),
   to :data:`CAMPAIGN_TOL_M` / :data:`CAMPAIGN_TOL_RAD` or :data:`CAMPAIGN_GN_MAX_ITER` steps.
   A step over both blocks (not a Kabsch re-estimate of ``A_c`` alone with the robot held) is what
   converges in a few steps when the robot's parameters and the transforms are correlated.
4. **Re-merge and re-fit** -- with the new ``A_c``, the model of step 2 is re-fitted
   (:func:`.refit.refit_selection`: the same effects, joint error map frequencies and constants, held
   parameters and inlier rows; Levenberg-Marquardt over the same free parameters from the joint
   solution of step 3; no selection again), and step 3 repeated, until ``A_c`` changes by less than
   the tolerances between two rounds, at most :data:`CAMPAIGN_MAX_ROUNDS` rounds.  The result's
   notes say how many rounds and the last change.
5. **Covariance** -- ``s^2 (J^T J)^-1`` of the joint problem (weighted Jacobian over the free robot
   parameters and 6 columns per non-reference campaign, inlier rows, ``s^2`` the weighted residual
   over ``3 n - k - 6 (C - 1)`` degrees of freedom).  The robot block (and the reference
   registration) is the model's :attr:`~models.arm.ArmModel.covariance`; each campaign's
   registration covariance (:attr:`models.arm.CampaignFrame.registration_cov`) is the joint
   covariance carried to that campaign's registration parameters ``reg.t`` (m) and ``reg.w``
   (Cayley vector of the correction on the measurement side around the rotation of its
   ``base2meas``, the parametrisation of :meth:`models.arm.ArmModel.for_campaign`) by the
   Jacobian of the map, taken by central differences, and so is its cross-covariance with the robot's
   free parameters (:attr:`models.arm.CampaignFrame.registration_cross_cov`), so that the sigma in a
   campaign's frame keeps the correlation between its registration and the robot.

Before anything, rows that repeat an earlier row exactly (the same joint angles, load and measured
point) are dropped, so a copied campaign or row does not double its weight
(:func:`.campaign_checks.drop_repeated_rows`; the result's ``warnings`` say how many and where).
After the fit, a campaign whose registration differs from the reference's by more than an instrument
that was not moved shows is warned with the figures (:func:`.campaign_checks.frame_warnings`).

With ``shared=("registration",)`` (or data declared registered) every campaign is in one frame and
the campaigns are only concatenated.  One campaign is exactly :func:`problems.identify.identify`
(``model.campaigns`` stays empty).  Everything is SI; the library prints nothing.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from models import effects as fx
from models.arm import ArmModel, CampaignFrame
from models.errors import InputError
from models.robot import Robot
from models.transforms import invert, matrix_to_rotvec, transform

from ..measurements import Measurements
from .apply import predict
from .campaign_checks import drop_repeated_rows, frame_warnings, reference_index
from .campaign_joint import (
    CAMPAIGN_TOL_M,
    CAMPAIGN_TOL_RAD,
    JointFit,
    campaign_registration,
    free_names,
    joint_covariance,
    registration_jacobian,
    transform_change,
)
from .campaign_merge import campaign_names, merge_campaigns
from .engine import Selection, identify, select_model
from .lsq import kabsch
from .refit import refit_selection
from .results import DataError, IdentificationResult, Progress

#: Parts of the set-up ``shared`` may name.  ``measured_point`` is always shared (the same tool or
#: reflector in every campaign): naming it changes nothing.
SHARED_PARTS = ("registration", "measured_point")
#: Rounds of (engine re-fit, joint Gauss-Newton) at most.
CAMPAIGN_MAX_ROUNDS = 4
#: Fewest distinct poses of a campaign with its own registration (a rigid transform needs 3 points).
CAMPAIGN_MIN_POSES = 3


# ----------------------------------------------------------------------------------
# The entry point
# ----------------------------------------------------------------------------------


def _check_shared(shared: Sequence[str]) -> bool:
    bad = [s for s in shared if s not in SHARED_PARTS]
    if bad:
        raise InputError(f"shared part(s) {bad}: expected any of {list(SHARED_PARTS)}")
    return "registration" in shared


def _start_transforms(
    robot: Robot, campaigns: Sequence[Measurements], names: Sequence[str], identify_kwargs: Mapping[str, Any]
) -> tuple[list[np.ndarray], str]:
    """``A_c`` (campaign frame -> reference frame) to start from, and how they were found.

    The campaign with the most poses is identified alone (``identify_kwargs``); Kabsch of its model's
    points (its measurement frame) to each campaign's measured points gives every campaign's frame
    relative to it.  A start from the nominal model (Kabsch of its points) is off by the nominal
    model's error, which the first merged fit then explains with wrong effects; with the identified
    model of one campaign the start is off by what that model mispredicts.  When that campaign cannot
    be identified alone (:class:`DataError`), the nominal model is used."""
    sizes = [len(np.unique(m.pose_groups())) for m in campaigns]
    big = int(np.argmax(sizes))
    how = f"Kabsch of the model identified from campaign '{names[big]}' alone"
    try:
        model = identify(robot, campaigns[big], **identify_kwargs).model
    except DataError as exc:
        model = ArmModel.from_robot(robot)
        how = f"Kabsch of the nominal model (campaign '{names[big]}' alone cannot be identified: {exc})"
    frames = []
    for m in campaigns:
        p = predict(model, _no_time(m))
        R, t = kabsch(p, m.p)
        frames.append(transform(R, t))
    return [frames[-1] @ invert(B) for B in frames], how


def _no_time(m: Measurements) -> Measurements:
    """``m`` without its time column (the nominal model has no drift; this keeps it so)."""
    out = m.subset(np.arange(m.n))
    out.t = None
    return out


def _campaign_table(
    res: IdentificationResult,
    names: Sequence[str],
    campaigns: Sequence[Measurements],
    campaign: np.ndarray,
    frames: Sequence[CampaignFrame],
    ref_index: int,
) -> list[dict[str, Any]]:
    """``identifiability['campaigns']``: per campaign rows, poses, inlier RMS after (mm per axis), its
    registration, whether it is the reference (the last of ``frames``) and its registration's difference
    from the reference's (mm, deg)."""
    ref = frames[ref_index].base2meas
    out = []
    for c, (name, m, f) in enumerate(zip(names, campaigns, frames)):
        sel = campaign == c
        r = res.residual_after[sel & res.inliers]
        std = None if f.registration_cov is None else np.sqrt(np.maximum(np.diag(f.registration_cov), 0.0))
        out.append(
            {
                "name": name,
                "file": m.source,
                "n_rows": int(m.n),
                "n_inliers": int(f.n_rows),
                "n_poses": int(len(np.unique(m.pose_groups()))),
                "rms_after_mm": float(np.sqrt(np.mean(r**2)) * 1e3) if r.size else None,
                "base2meas": {
                    "xyz_m": f.base2meas[:3, 3].tolist(),
                    "rotvec_rad": matrix_to_rotvec(f.base2meas[:3, :3]).tolist(),
                },
                "registration_std": (None if std is None else {"t_m": std[:3].tolist(), "w": std[3:].tolist()}),
                "reference": c == ref_index,
                "translation_from_reference_mm": float(np.linalg.norm(f.base2meas[:3, 3] - ref[:3, 3]) * 1e3),
                "rotation_from_reference_deg": float(
                    np.degrees(np.linalg.norm(matrix_to_rotvec(f.base2meas[:3, :3] @ ref[:3, :3].T)))
                ),
            }
        )
    return out


def _reg_block(model: ArmModel) -> np.ndarray | None:
    """The model's own registration covariance ``[reg.t, reg.w]`` (6, 6) (None without)."""
    reg = list(fx.REGISTRATION_NAMES)
    if model.covariance is None or any(n not in model.covariance_names for n in reg):
        return None
    idx = [model.covariance_names.index(n) for n in reg]
    return np.asarray(model.covariance)[np.ix_(idx, idx)].copy()


def _reg_rows(model: ArmModel) -> np.ndarray | None:
    """The registration's rows of the model's covariance (6, k) (None without): its cross-covariance with
    every free parameter, the campaign's own when every campaign shares the model's registration."""
    if _reg_block(model) is None:
        return None
    idx = [model.covariance_names.index(n) for n in fx.REGISTRATION_NAMES]
    return np.asarray(model.covariance)[idx].copy()


def _checked_names(campaigns: Sequence[Measurements], names: Sequence[str] | None) -> list[str]:
    """The campaigns' names (default: from their sources), checked distinct and non-empty."""
    names = campaign_names([m.source for m in campaigns]) if names is None else [str(n) for n in names]
    if len(names) != len(campaigns) or len(set(names)) != len(names) or any(not n for n in names):
        raise InputError(f"campaign names {names}: expected {len(campaigns)} distinct non-empty names")
    return names


def _check_own_registrations(campaigns: Sequence[Measurements], names: Sequence[str]) -> None:
    """Raise :class:`DataError` when a campaign has too few poses for a registration of its own."""
    for m, name in zip(campaigns, names):
        n_poses = len(np.unique(m.pose_groups()))
        if n_poses < CAMPAIGN_MIN_POSES:
            raise DataError(
                f"{m.source}: campaign '{name}' has {n_poses} distinct pose(s); its own registration needs at "
                f"least {CAMPAIGN_MIN_POSES} (many more for a useful fit); if the instrument did not move "
                "between the campaigns, give --shared registration (shared=('registration',))"
            )


def identify_campaigns(
    robot: Robot,
    campaigns: Sequence[Measurements],
    names: Sequence[str] | None = None,
    shared: Sequence[str] = (),
    progress: Progress | None = None,
    reference: str | None = None,
    **identify_kwargs: Any,
) -> IdentificationResult:
    """Identify one robot model from several measurement campaigns.

    Parameters
    ----------
    robot : Robot
        Nominal description.
    campaigns : sequence of Measurements
        Each with positions ``p`` in its own measurement frame, m.  Rows that repeat an earlier row
        exactly (joint angles, load, measured point; within or across campaigns) are dropped, and
        the result's ``warnings`` say so.
    names : sequence of str, optional
        Unique campaign names (default: :func:`campaign_names` of the sources).
    shared : sequence of str
        Parts of the set-up shared by every campaign (:data:`SHARED_PARTS`): ``"registration"``
        puts every campaign in one measurement frame (they are concatenated).  The measured point
        is always shared.
    progress : callable, optional
        ``progress(message, done, total)`` of the engine.
    reference : str, optional
        Name of the reference campaign (the model's own registration, what ``predict`` and
        ``compensate`` use by default); default: the campaign with the most rows (of several equally
        large, the last given).
    **identify_kwargs
        Passed to :func:`problems.identify.identify` (``candidates``, ``include``, ``folds``,
        ``known``, ``registered``, ``max_steps``, ``map_components``).  Data declared registered
        (``registered=True`` or ``"registration"`` in ``known``) share the base frame: as
        ``shared=("registration",)``.

    Returns
    -------
    IdentificationResult
        On the merged table (``res.data``, reference frame, the reference campaign's rows last);
        ``res.model.campaigns`` holds one :class:`~models.arm.CampaignFrame` per campaign in the order
        given (empty for one campaign), the model's registration is the reference campaign's;
        ``res.identifiability["campaigns"]`` the per-campaign figures (in the order given),
        ``["campaign_fit"]["reference"]`` the reference's name and ``["repeated_rows"]`` the rows
        dropped; the notes say how the campaigns were fitted, the ``warnings`` what the user must
        know (rows dropped, registrations far apart).

    Raises
    ------
    DataError
        A campaign without positions, one with its own registration and fewer than
        :data:`CAMPAIGN_MIN_POSES` distinct poses, or one whose every row repeats an earlier
        campaign's (naming the file).
    InputError
        Bad ``names``/``shared``/``reference``, orientation data with per-campaign registrations.
    """
    campaigns = list(campaigns)
    if not campaigns:
        raise InputError("identify_campaigns: no campaign given")
    names = _checked_names(campaigns, names)
    one_frame = _check_shared(shared)
    ref = reference_index(campaigns, names, reference)
    campaigns, repeated = drop_repeated_rows(campaigns, names)
    warnings = [repeated.message()] if repeated.n_dropped else []
    if len(campaigns) == 1:
        res = identify(robot, campaigns[0], progress=progress, **identify_kwargs)
    else:
        res = _several(robot, campaigns, names, one_frame, ref, progress, identify_kwargs)
    res.identifiability["repeated_rows"] = repeated.to_dict()
    res.warnings = warnings + list(res.warnings)
    return res


def _several(
    robot: Robot,
    campaigns: list[Measurements],
    names: list[str],
    one_frame: bool,
    ref: int,
    progress: Progress | None,
    identify_kwargs: dict[str, Any],
) -> IdentificationResult:
    """Several campaigns (``ref``: the reference's index): one frame, or one registration each."""
    for m in campaigns:
        if m.p is None:
            raise DataError(f"{m.source}: no measured positions (columns x, y, z) to identify from")
    known = tuple(identify_kwargs.get("known", ()))
    notes: list[str] = []
    if not one_frame and (identify_kwargs.get("registered") or "registration" in known):
        one_frame = True
        notes.append("campaigns: the data are declared registered: every campaign is in the base frame (one frame)")
    if one_frame:
        return _one_frame(robot, campaigns, names, ref, progress, notes, identify_kwargs)
    _check_own_registrations(campaigns, names)
    order = [c for c in range(len(campaigns)) if c != ref] + [ref]  # the reference last
    camps, nms = [campaigns[c] for c in order], [names[c] for c in order]
    A, how = _start_transforms(robot, camps, nms, identify_kwargs)
    notes.append(f"campaigns: the start of every campaign's transform: {how}")
    first, res, A, joint, campaign, rounds, gn_steps, change = _fit_rounds(
        robot, camps, nms, A, progress, identify_kwargs, notes
    )
    converged = change[0] < CAMPAIGN_TOL_M and change[1] < CAMPAIGN_TOL_RAD
    res = _finish(res, first, joint, A, nms, camps, campaign, notes, rounds, gn_steps, change, converged)
    back = [order.index(c) for c in range(len(campaigns))]  # to the order given
    res.model.campaigns = [res.model.campaigns[k] for k in back]
    res.identifiability["campaigns"] = [res.identifiability["campaigns"][k] for k in back]
    res.warnings = frame_warnings(res.identifiability["campaigns"], names[ref])
    return res


def _fit_rounds(
    robot: Robot,
    campaigns: list[Measurements],
    names: list[str],
    A: list[np.ndarray],
    progress: Progress | None,
    identify_kwargs: Mapping[str, Any],
    notes: list[str],
) -> tuple[
    IdentificationResult, IdentificationResult, list[np.ndarray], JointFit, np.ndarray, int, int, tuple[float, float]
]:
    """Steps 2-4 of the method (docs/identification.md, section 11): merge, identify (the only effect
    selection), joint Gauss-Newton, then re-merge and re-fit the selected model (no selection) until the
    transforms ``A`` settle; the round of smallest joint RMS is kept.

    Returns the first round's result (its selection history), the kept result, its transforms and joint
    problem, the campaign index of the merged rows, the rounds, the Gauss-Newton steps and the last
    change of a transform (m, rad)."""
    merged, campaign = merge_campaigns(campaigns, names, A, notes)
    sel: Selection = select_model(robot, merged, progress=progress, **identify_kwargs)
    res = first = sel.result()
    rounds, gn_steps, change = 0, 0, (float("inf"), float("inf"))
    tried: list[tuple[float, int, IdentificationResult, list[np.ndarray], JointFit]] = []
    while True:
        rounds += 1
        joint = JointFit(res.model, free_names(res), campaigns, campaign, merged, res.inliers)
        tried.append((joint.rms(res.model.theta, A), rounds, res, A, joint))
        theta, A_new, steps = joint.solve(res.model.theta, A)
        gn_steps += steps
        change = max(
            (transform_change(a, b) for a, b in zip(A, A_new)),
            key=lambda d: d[0] / CAMPAIGN_TOL_M + d[1] / CAMPAIGN_TOL_RAD,
        )
        if (change[0] < CAMPAIGN_TOL_M and change[1] < CAMPAIGN_TOL_RAD) or rounds >= CAMPAIGN_MAX_ROUNDS:
            break
        A = A_new
        merged, campaign = merge_campaigns(campaigns, names, A)
        sel = refit_selection(sel, merged, theta)
        res = sel.result()
    best = min(tried, key=lambda t: t[0])
    if best[1] != rounds:  # a re-fit can end worse than an earlier round: keep the best of them
        notes.append(
            f"campaigns: round {best[1]}'s fit is kept (RMS per axis {best[0] * 1e3:.4g} mm over the inlier rows of "
            f"every campaign; the last round's {tried[-1][0] * 1e3:.4g} mm)"
        )
        _rms, _k, res, A, joint = best
    return first, res, A, joint, campaign, rounds, gn_steps, change


def _finish(
    res: IdentificationResult,
    first: IdentificationResult,
    joint: JointFit,
    A: list[np.ndarray],
    names: list[str],
    campaigns: list[Measurements],
    campaign: np.ndarray,
    notes: list[str],
    rounds: int,
    gn_steps: int,
    change: tuple[float, float],
    converged: bool,
) -> IdentificationResult:
    """The result of the joint fit: the joint covariance, the campaigns' frames, the notes."""
    model = res.model
    C = len(campaigns)
    k = len(joint.idx)
    cov, s2, dof = joint_covariance(joint, model.theta, A)
    names_free = joint.names
    model.covariance = cov[:k, :k].copy()
    model.covariance_names = list(names_free)
    r = joint.residual(model.theta, A)[joint.mask]
    if r.size:
        model.residual_sigma_m = float(np.sqrt(np.sum(r**2) / max(r.size - k - 6 * (C - 1), 1)))
    model.campaigns = [
        _campaign_frame(model, cov, names_free, k, c, A[c] if c < C - 1 else None, names[c], campaigns[c].source,
                        int(np.sum(res.inliers & (campaign == c))))
        for c in range(C)
    ]  # fmt: skip
    res.history = first.history
    res.effects_added = list(first.effects_added)
    for e in res.model.effects:
        if e not in res.effects_added:
            res.effects_added.append(e)
    res.identifiability["campaigns"] = _campaign_table(res, names, campaigns, campaign, model.campaigns, C - 1)
    res.identifiability["campaign_fit"] = {
        "reference": names[-1],
        "rounds": rounds,
        "gauss_newton_steps": gn_steps,
        "last_change_m": change[0],
        "last_change_rad": change[1],
        "converged": converged,
        "residual_variance_weighted": s2,
        "dof": dof,
    }
    res.notes = (
        list(first.notes)
        + notes
        + [
            f"campaigns: {C} ({', '.join(names)}), one registration each (reference: '{names[-1]}', the model's "
            f"own, {campaigns[-1].n} rows); fitted jointly in {rounds} round(s) of re-fit and Gauss-Newton "
            f"({gn_steps} steps), "
            f"last change of a campaign's transform {change[0] * 1e3:.2g} mm / {change[1]:.2g} rad"
            + ("" if converged else f" (not converged in {CAMPAIGN_MAX_ROUNDS} rounds)")
        ]
    )
    return res


def _campaign_frame(
    model: ArmModel, cov: np.ndarray, names_free: list[str], k: int, c: int, A: np.ndarray | None, name: str,
    source: str, n_rows: int,
) -> CampaignFrame:  # fmt: skip
    """Campaign ``c``'s frame: its registration, the registration's covariance and its cross-covariance with the
    robot's ``k`` free parameters, from the joint covariance ``cov`` (free parameters, then 6 per non-reference
    campaign; ``A`` None for the reference)."""
    reg_idx = [names_free.index(n) if n in names_free else -1 for n in fx.REGISTRATION_NAMES]
    sub = [i for i in reg_idx if i >= 0]
    a_idx = list(range(k + 6 * c, k + 6 * c + 6)) if A is not None else []
    pos = [j for j, i in enumerate(reg_idx) if i >= 0] + list(range(6, 6 + len(a_idx)))
    full = np.zeros((6 + len(a_idx), 6 + len(a_idx)))
    full[np.ix_(pos, pos)] = cov[np.ix_(sub + a_idx, sub + a_idx)]
    cross = np.zeros((6 + len(a_idx), k))
    cross[pos] = cov[np.ix_(sub + a_idx, list(range(k)))]
    G = registration_jacobian(model, 6 + len(a_idx), A)
    return CampaignFrame(
        name=name,
        base2meas=campaign_registration(model, np.zeros(6 + len(a_idx)), A),
        n_rows=n_rows,
        data=source,
        registration_cov=G @ full @ G.T,
        registration_cross_cov=G @ cross,
    )


def _one_frame(
    robot: Robot,
    campaigns: list[Measurements],
    names: list[str],
    ref: int,
    progress: Progress | None,
    notes: list[str],
    identify_kwargs: dict[str, Any],
) -> IdentificationResult:
    """Every campaign in one measurement frame: the engine on the concatenation (``ref``: the index of
    the campaign reported as the reference; every campaign has the model's registration)."""
    merged, campaign = merge_campaigns(campaigns, names, None, notes)
    res = identify(robot, merged, progress=progress, **identify_kwargs)
    model = res.model
    reg_cov = _reg_block(model)
    frames = [
        CampaignFrame(
            name=names[c],
            base2meas=model.base2meas(),
            n_rows=int(np.sum(res.inliers & (campaign == c))),
            data=campaigns[c].source,
            registration_cov=None if reg_cov is None else reg_cov.copy(),
            registration_cross_cov=_reg_rows(model),
        )
        for c in range(len(campaigns))
    ]
    model.campaigns = frames
    res.identifiability["campaigns"] = _campaign_table(res, names, campaigns, campaign, frames, ref)
    res.identifiability["campaign_fit"] = {"reference": names[ref], "shared": ["registration"]}
    res.notes = (
        list(res.notes)
        + notes
        + [f"campaigns: {len(campaigns)} ({', '.join(names)}) in one shared measurement frame (concatenated)"]
    )
    return res
