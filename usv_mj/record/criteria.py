"""How a controller's run is judged: the success criterion a controller declares.

A controller declares its criterion as the attribute ``criterion`` (a class attribute, or set on the
instance in ``from_scenario`` from its gains). Without one, :func:`criterion_of` gives the funnel
to a controller that declares :data:`usv_mj.controllers.base.FUNNEL_FIELDS` among its diagnostics
and the default :class:`PoseTolerance` to any other. Every output (console, ``summary.json``,
``report.md``, figures, sweeps, the capability search) judges a run by its criterion and in its
words; the criterion travels in the record's metadata (``metadata["criterion"]``, the dict of
:meth:`to_dict`), so outputs made from a log alone judge it the same way.

It imports nothing of the package at import time but the errors (the pose errors of
:mod:`usv_mj.record.summary` and the funnel's field names when called).

Contract (each criterion):

- ``kind``: a short identifier ("funnel", "pose_tolerance", "path_tolerance", "not_judged");
- ``noun``: what holds or is lost, in the outputs' sentences ("the funnel", "the pose tolerance");
- ``describe() -> str``: one line in plain words, for the report and the console;
- ``to_dict() -> dict`` and :func:`criterion_from_dict` (its inverse);
- ``evaluate(record) -> dict`` (the built-ins: :func:`_evaluate` over ``columns``, read chunk by
  chunk through ``judge(chunk)``, so a stored ten-hour record is never loaded whole): ``{"kind": kind, "noun": noun, "description": str, "passed": bool | None,
  "violations": int | None (control steps that broke it), "first_violation_s": float | None,
  "judged_steps": int, ...}`` plus the criterion's own largest errors, every value JSON-ready
  (no inf or NaN: None). ``passed`` is False as soon as one judged step broke it; True when none
  did and the run completed with at least one judged step; None otherwise (a run that stopped
  early without a violation, a record that ends before the settling time, :class:`NotJudged`).
  A non-finite error counts as broken.

Time window: the tolerances judge the control steps with t >= ``settle_time_s``; the funnel every step.
A criterion class of a plug-in's own follows the same contract. It is checked when the controller
that declares it is loaded (:func:`criterion_of`: the attributes, ``to_dict`` naming its ``kind``,
``criterion_from_dict`` of it; a :class:`usv_mj.core.errors.PluginContractError` names the
plug-in, the broken term and the fix) and added to :data:`CRITERIA` under its ``kind`` there (adding
it by hand, as before, still works). The record's metadata names its class too
(``"class": "module:Qualname"``, :func:`criterion_to_dict`), so a later process (``usv-mj plot`` of
the log) imports it back; one that cannot (a class defined in a script) judges the log "not judged"
and says why. Its ``evaluate`` is called through :func:`judge`, which checks the result: an
exception, a result that is not a dict, or a ``passed`` / ``violations`` / ``first_violation_s``
outside the contract leaves the run not judged, the block's ``error`` naming the plug-in and what
was wrong, instead of breaking the outputs.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from usv_mj.core.errors import PluginContractError, ScenarioError
from usv_mj.record.tracking import pose_errors


def _finite(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def _params(criterion) -> dict:
    """The criterion's fields, JSON-ready (an infinite bound: None, "not judged")."""
    return {k: (_finite(v) if isinstance(v, float) else v) for k, v in asdict(criterion).items()}


def _chunks(record, names):
    """Aligned chunks of the columns ``names`` (a dict per chunk): a RunRecord's column_chunks, so
    that a stored ten-hour record is read a few pages at a time; a plain mapping whole."""
    if hasattr(record, "column_chunks"):
        for arrays in zip(*(record.column_chunks(n) for n in names)):
            yield dict(zip(names, arrays))
    else:
        yield {n: np.asarray(record[n]) for n in names}


def _evaluate(criterion, record) -> dict:
    """The result dict of the module docstring, from ``criterion.judge(chunk) -> (broken, judged,
    errors)`` over the record's chunks: ``broken`` (a step broke the criterion), ``judged`` (the
    step is in the criterion's window), ``errors`` (name -> values whose largest |value| over the
    judged steps is reported as ``name``; a non-finite one as None)."""
    names = ("t",) + tuple(c for c in criterion.columns if c != "t")
    n_bad = n_judged = 0
    first, peaks = None, {}
    for c in _chunks(record, names):
        broken, judged, errors = criterion.judge(c)
        bad = broken & judged
        k = int(bad.sum())
        if k and first is None:
            first = _finite(c["t"][np.argmax(bad)])
        n_bad += k
        n_judged += int(judged.sum())
        for name, values in errors.items():
            peaks.setdefault(name, None)
            if judged.any():
                m = np.max(np.abs(values[judged]))
                peaks[name] = m if peaks[name] is None else np.maximum(peaks[name], m)   # NaN wins, as np.max
    completed = getattr(record, "status", "completed") == "completed"
    passed = False if n_bad else (True if completed and n_judged else None)
    return {"kind": criterion.kind, "noun": criterion.noun, "description": criterion.describe(), "passed": passed,
            "violations": n_bad, "first_violation_s": first, "judged_steps": n_judged,
            **{k: (_finite(v) if v is not None else None) for k, v in peaks.items()}, "params": _params(criterion)}


@dataclass(frozen=True)
class FunnelCriterion:
    """Kept when every normalized error stays inside its funnel, |z_i| < 1 at every control step
    (the prescribed-performance bound of Eqs. 9 and 14, docs/model.md §3)."""

    kind = "funnel"
    noun = "the funnel"

    def describe(self) -> str:
        return "the tracking errors stay inside the prescribed-performance funnel (|z_i| < 1 at every step)"

    def to_dict(self) -> dict:
        return {"kind": self.kind}

    def evaluate(self, record) -> dict:
        """Every step is judged: broken where any |z_i| >= 1 (or z_i is not finite)."""
        if not all(f"z{i}" in record for i in (1, 2, 3)):
            raise ScenarioError(f"criterion {self.kind}: the record has no funnel columns z1, z2, z3 "
                                f"(controller {record.metadata.get('controller', '?')!r} declares none)")
        return _evaluate(self, record)

    columns = ("t", "z1", "z2", "z3")

    def judge(self, c):
        broken = ~(np.abs(c["z1"]) < 1.0) | ~(np.abs(c["z2"]) < 1.0) | ~(np.abs(c["z3"]) < 1.0)
        return broken, np.ones(len(broken), bool), {}


@dataclass(frozen=True)
class PoseTolerance:
    """Kept when, after ``settle_time_s``, the position error stays under ``position_m`` and the
    heading error under ``heading_deg`` at every control step."""

    settle_time_s: float = 20.0   # s: the errors before this time are not judged
    position_m: float = 1.0       # m: bound on sqrt((x - x_d)^2 + (y - y_d)^2)
    heading_deg: float = 10.0     # deg: bound on |wrap(psi - psi_d)|

    kind = "pose_tolerance"
    noun = "the pose tolerance"

    def __post_init__(self):
        for name in ("settle_time_s", "position_m", "heading_deg"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v == v and 0 <= v < float("inf")):
                raise ScenarioError(f"criterion {self.kind}: {name} = {v!r} must be a finite number >= 0")

    def describe(self) -> str:
        return (f"after {self.settle_time_s:g} s the position error stays under {self.position_m:g} m and "
                f"the heading error under {self.heading_deg:g} deg")

    def to_dict(self) -> dict:
        return {"kind": self.kind, **asdict(self)}

    def errors(self, record) -> dict:
        """The judged errors at every row: ``position`` sqrt((x - x_d)^2 + (y - y_d)^2) [m] and
        ``heading`` |wrap(psi - psi_d)| [rad] (from :func:`usv_mj.record.summary.pose_errors`)."""

        e = pose_errors(record)
        return {"position": np.hypot(e["x"], e["y"]), "heading": np.abs(e["psi"])}

    columns = ("t", "x", "x_d", "y", "y_d", "psi", "psi_d")

    def evaluate(self, record) -> dict:
        return _evaluate(self, record)

    def judge(self, c):
        e = self.errors(c)
        judged = c["t"] >= self.settle_time_s
        broken = ~(e["position"] < self.position_m) | ~(e["heading"] < math.radians(self.heading_deg))
        return broken, judged, {"max_position_error_m": e["position"], "max_heading_error_rad": e["heading"]}


@dataclass(frozen=True)
class PathTolerance:
    """Kept when, after ``settle_time_s``, the cross-track error (the vessel's offset from the
    reference point normal to the reference's course, in the path frame of the reference velocity
    (x_d_dot, y_d_dot)) stays under ``cross_track_m`` and the along-track error under
    ``along_track_m`` at every control step: the criterion of a path-following law (LOS)."""

    settle_time_s: float = 20.0           # s: the errors before this time are not judged
    cross_track_m: float = 1.0            # m: bound on the path-normal error
    along_track_m: float = float("inf")   # m: bound on the path-tangential error (inf: not judged)

    kind = "path_tolerance"
    noun = "the path tolerance"
    still_speed = 1e-6  # m/s: below this reference speed the course is psi_d

    def __post_init__(self):
        for name in ("settle_time_s", "cross_track_m", "along_track_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v == v and v >= 0):
                raise ScenarioError(f"criterion {self.kind}: {name} = {v!r} must be a number >= 0")

    def describe(self) -> str:
        along = ("" if self.along_track_m == float("inf")
                 else f" and the along-track error under {self.along_track_m:g} m")
        return f"after {self.settle_time_s:g} s the cross-track error stays under {self.cross_track_m:g} m{along}"

    def to_dict(self) -> dict:
        return {"kind": self.kind, **asdict(self)}

    def errors(self, record) -> dict:
        """The path-frame errors at every row [m]: with the course chi = atan2(y_d_dot, x_d_dot)
        (psi_d where the reference speed is below ``still_speed``) and (ex, ey) = (x - x_d, y - y_d),
        ``along`` = cos(chi) ex + sin(chi) ey (> 0: ahead of the reference point) and
        ``cross`` = -sin(chi) ex + cos(chi) ey (> 0: left of the path, the z-up frame)."""

        e = pose_errors(record)
        xd, yd = record["x_d_dot"], record["y_d_dot"]
        chi = np.where(np.hypot(xd, yd) >= self.still_speed, np.arctan2(yd, xd), record["psi_d"])
        c, s = np.cos(chi), np.sin(chi)
        return {"along": c * e["x"] + s * e["y"], "cross": -s * e["x"] + c * e["y"]}

    columns = ("t", "x", "x_d", "y", "y_d", "psi", "psi_d", "x_d_dot", "y_d_dot")

    def evaluate(self, record) -> dict:
        return _evaluate(self, record)

    def judge(self, c):
        e = self.errors(c)
        judged = c["t"] >= self.settle_time_s
        broken = ~(np.abs(e["cross"]) < self.cross_track_m)
        if self.along_track_m != float("inf"):
            broken |= ~(np.abs(e["along"]) < self.along_track_m)
        else:  # not judged along the path, but a non-finite error is
            broken |= ~np.isfinite(e["along"])
        return broken, judged, {"max_cross_track_m": e["cross"], "max_along_track_m": e["along"]}


@dataclass(frozen=True)
class NotJudged:
    """An open-loop input or a manoeuvre: the run has no success criterion (``passed`` is None)."""

    reason: str = "open-loop input"

    kind = "not_judged"
    noun = "no criterion"

    def describe(self) -> str:
        return f"not judged ({self.reason})"

    def to_dict(self) -> dict:
        return {"kind": self.kind, **asdict(self)}

    def evaluate(self, record) -> dict:
        return {"kind": self.kind, "noun": self.noun, "description": self.describe(), "passed": None,
                "violations": None, "first_violation_s": None, "judged_steps": 0, "params": _params(self)}


BUILT_IN = (FunnelCriterion, PoseTolerance, PathTolerance, NotJudged)
CRITERIA = {c.kind: c for c in BUILT_IN}
CONTRACT = "the criterion contract: usv_mj.record.criteria"


def class_path(obj) -> str:
    """``module:Qualname`` of ``obj``'s class (of ``obj`` itself when it is a class)."""
    cls = obj if isinstance(obj, type) else type(obj)
    return f"{cls.__module__}:{cls.__qualname__}"


def _who(criterion) -> str:
    return f"criterion {getattr(criterion, 'kind', '?')!r} ({class_path(criterion)})"


def criterion_to_dict(criterion) -> dict:
    """``criterion.to_dict()``, with ``"class": "module:Qualname"`` for a plug-in's criterion (not for
    a built-in: their records stay as they were), so that another process finds its class."""
    d = criterion.to_dict()
    return d if isinstance(criterion, BUILT_IN) else {**d, "class": class_path(criterion)}


def _import_class(path: str, kind: str):
    """The criterion class ``module:Qualname`` a record names, imported and added to :data:`CRITERIA`;
    None (and why) when it cannot be."""
    import importlib

    module_name, _, qualname = str(path).partition(":")
    try:
        obj = importlib.import_module(module_name)
        for part in qualname.split("."):
            obj = getattr(obj, part)
    except Exception as exc:
        return None, f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    if not isinstance(obj, type) or getattr(obj, "kind", None) != kind:
        return None, f"{path} is not a criterion class of kind {kind!r}"
    CRITERIA.setdefault(kind, obj)
    return obj, ""


def criterion_from_dict(d: dict):
    """The criterion that :meth:`to_dict` wrote (a JSON null bound, as ``summary.json`` writes an
    infinite one, reads back as inf); a plug-in's kind not known in this process is imported from
    the ``class`` the dict names (:func:`criterion_to_dict`)."""
    d = dict(d)
    kind = d.pop("kind", None)
    path = d.pop("class", None)
    if kind not in CRITERIA and path:
        found, why = _import_class(path, kind)
        if found is None:
            raise ScenarioError(f"success criterion {kind!r} of the plug-in {path} cannot be loaded here ({why})")
    if kind not in CRITERIA:
        raise ScenarioError(f"unknown success criterion {kind!r}; criteria: {', '.join(CRITERIA)}")
    d = {k: (float("inf") if v is None and k.endswith("_m") else v) for k, v in d.items()}
    try:
        return CRITERIA[kind](**d)
    except TypeError as exc:
        raise ScenarioError(f"success criterion {kind!r}: {exc}") from None


def check_criterion(criterion, owner: str):
    """The contract of a declared criterion, checked when its controller is loaded (module
    docstring); a plug-in's class is added to :data:`CRITERIA` under its kind. Returns it."""
    who = f"{owner}: its criterion {criterion!r} ({class_path(criterion)})"
    missing = [m for m in ("kind", "describe", "to_dict", "evaluate") if not hasattr(criterion, m)]
    if missing:
        raise PluginContractError(f"{who} has no {', '.join(missing)}; a criterion has kind, noun, describe(), "
                                  f"to_dict() and evaluate(record) ({CONTRACT})")
    kind = criterion.kind
    if not isinstance(kind, str) or not kind:
        raise PluginContractError(f"{who}: kind must be a non-empty string, got {kind!r} ({CONTRACT})")
    if isinstance(criterion, BUILT_IN):
        return criterion
    taken = CRITERIA.get(kind)
    if taken is not None and taken is not type(criterion) and class_path(taken) != class_path(criterion):
        raise PluginContractError(f"{who}: kind {kind!r} is already the criterion {class_path(taken)}; give the "
                                  f"class a kind of its own")
    try:
        d = criterion.to_dict()
    except Exception as exc:
        raise PluginContractError(f"{who}: to_dict() raised {type(exc).__name__}: {exc} ({CONTRACT})") from None
    if not isinstance(d, dict) or d.get("kind") != kind:
        raise PluginContractError(f"{who}: to_dict() must return a dict with \"kind\": {kind!r} (what "
                                  f"criterion_from_dict reads back), got {d!r} ({CONTRACT})")
    CRITERIA.setdefault(kind, type(criterion))
    try:
        criterion_from_dict(criterion_to_dict(criterion))
    except Exception as exc:
        raise PluginContractError(f"{who}: its class cannot be rebuilt from to_dict() {d!r} ({type(exc).__name__}: "
                                  f"{exc}); the keys of to_dict() besides kind must be its constructor's "
                                  f"({CONTRACT})") from None
    return criterion


def _result_problem(out) -> str | None:
    """What is wrong with an ``evaluate`` result (None: it keeps the contract)."""
    import json

    if not isinstance(out, dict):
        return f"a {type(out).__name__} instead of a dict"
    passed = out.get("passed", "missing")
    if passed is not None and not isinstance(passed, (bool, np.bool_)):
        return f"passed = {passed!r} (True, False or None)"
    v = out.get("violations")
    if v is not None and (isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or v < 0):
        return f"violations = {v!r} (an integer >= 0 or None)"
    f = out.get("first_violation_s")
    if f is not None and (isinstance(f, (bool, np.bool_)) or not isinstance(f, (int, float, np.floating))
                          or not math.isfinite(f)):
        return f"first_violation_s = {f!r} (a finite time [s] or None)"
    try:
        json.dumps(out, allow_nan=False, default=lambda o: o.item() if hasattr(o, "item") else str(o))
    except ValueError:
        bad = [k for k, x in out.items() if isinstance(x, float) and not math.isfinite(x)]
        return f"values that are not JSON ({', '.join(bad) or 'nested NaN or inf'}: write None)"
    return None


def judge(criterion, record) -> dict:
    """``criterion.evaluate(record)``, checked (module docstring): the result with the contract's
    defaults filled in (kind, noun, description, violations and first_violation_s None,
    judged_steps 0). A plug-in's evaluate that raises or returns what the contract does not allow
    gives a "not judged" block whose ``error`` names it and what was wrong; a built-in's error
    propagates (it is usv_mj's)."""
    try:
        out = criterion.evaluate(record)
        problem = _result_problem(out)
    except Exception as exc:
        if isinstance(criterion, BUILT_IN):
            raise
        out, problem = None, f"evaluate raised {type(exc).__name__}: {' '.join(str(exc).split())}"
    else:
        problem = None if problem is None else f"evaluate returned {problem}"
    base = {"kind": getattr(criterion, "kind", "?"), "noun": getattr(criterion, "noun", "the criterion"),
            "description": _describe(criterion), "passed": None, "violations": None, "first_violation_s": None,
            "judged_steps": 0}
    if problem is not None:
        return {**base, "error": f"{_who(criterion)} broke its contract: {problem} ({CONTRACT})"}
    out = {**base, **out}
    out["passed"] = None if out["passed"] is None else bool(out["passed"])
    return out


def _describe(criterion) -> str:
    try:
        return str(criterion.describe())
    except Exception as exc:   # a plug-in's: its words are not worth the run's outputs
        return f"{_who(criterion)} (describe raised {type(exc).__name__})"


def criterion_of(controller):
    """The criterion ``controller`` declares (module docstring): its ``criterion``, else the funnel
    for a controller with the funnel block among its diagnostics, else the default pose tolerance."""
    declared = getattr(controller, "criterion", None)
    if declared is not None:
        check_criterion(declared, f"controller {getattr(controller, 'name', '?')!r}")
    from usv_mj.core.layouts import FUNNEL_FIELDS

    has_funnel = set(FUNNEL_FIELDS) <= set(getattr(controller, "diagnostic_fields", ()))
    if declared is not None:
        if declared.kind == "funnel" and not has_funnel:
            raise ScenarioError(f"controller {getattr(controller, 'name', '?')!r} declares the funnel criterion "
                                f"but not the funnel fields {', '.join(FUNNEL_FIELDS)} among its diagnostic_fields")
        return declared
    return FunnelCriterion() if has_funnel else PoseTolerance()


def criterion_of_record(record):
    """The criterion a run is judged by: the one in ``record.metadata["criterion"]`` (the loop puts
    the controller's there); a record without one (a log older than the criteria) is judged by the
    funnel when it has the funnel columns, else by the default :class:`PoseTolerance`."""
    d = record.metadata.get("criterion")
    if d:
        if isinstance(d, dict) and d.get("kind") not in CRITERIA and d.get("class"):
            try:
                return criterion_from_dict(d)
            except ScenarioError as exc:   # a plug-in's class this process cannot import: say so, judge nothing
                return NotJudged(f"{exc}")
        return criterion_from_dict(d)
    return FunnelCriterion() if getattr(record, "has_funnel", False) else PoseTolerance()
