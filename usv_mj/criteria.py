"""How a controller's run is judged: the success criterion a controller declares.

A controller declares its criterion as the attribute ``criterion`` (a class attribute, or set on the
instance in ``from_scenario`` from its gains). Without one, :func:`criterion_of` gives the funnel
to a controller that declares :data:`usv_mj.controllers.base.FUNNEL_FIELDS` among its diagnostics
and the default :class:`PoseTolerance` to any other. Every output (console, ``summary.json``,
``report.md``, figures, sweeps, the capability search) judges a run by its criterion and in its
words; the criterion travels in the record's metadata (``metadata["criterion"]``, the dict of
:meth:`to_dict`), so outputs made from a log alone judge it the same way.

A leaf module: it imports nothing of the package but the errors.

Contract (each criterion):

- ``kind``: a short identifier ("funnel", "pose_tolerance");
- ``describe() -> str``: one line in plain words, for the report and the console;
- ``to_dict() -> dict`` and :func:`criterion_from_dict` (its inverse);
- ``evaluate(record) -> dict``: ``{"criterion": kind, "description": str, "passed": bool | None,
  "violations": int | None (steps that broke it), "first_violation_s": float | None, ...}``
  (``passed`` None when the record is too short to judge).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from .errors import ScenarioError


@dataclass(frozen=True)
class FunnelCriterion:
    """Kept when every normalized error stays inside its funnel, |z_i| < 1 at every control step
    (the prescribed-performance bound of Eqs. 9 and 14, docs/model.md §3)."""

    kind = "funnel"

    def describe(self) -> str:
        return "the tracking errors stay inside the prescribed-performance funnel (|z_i| < 1 at every step)"

    def to_dict(self) -> dict:
        return {"kind": self.kind}


@dataclass(frozen=True)
class PoseTolerance:
    """Kept when, after ``settle_time_s``, the position error stays under ``position_m`` and the
    heading error under ``heading_deg`` at every control step."""

    settle_time_s: float = 20.0   # s: the errors before this time are not judged
    position_m: float = 1.0       # m: bound on sqrt((x - x_d)^2 + (y - y_d)^2)
    heading_deg: float = 10.0     # deg: bound on |wrap(psi - psi_d)|

    kind = "pose_tolerance"

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

    def __post_init__(self):
        for name in ("settle_time_s", "cross_track_m", "along_track_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v == v and v >= 0):
                raise ScenarioError(f"criterion {self.kind}: {name} = {v!r} must be a number >= 0")

    def describe(self) -> str:
        along = "" if self.along_track_m == float("inf") else f" and the along-track error under {self.along_track_m:g} m"
        return f"after {self.settle_time_s:g} s the cross-track error stays under {self.cross_track_m:g} m{along}"

    def to_dict(self) -> dict:
        return {"kind": self.kind, **asdict(self)}


@dataclass(frozen=True)
class NotJudged:
    """An open-loop input or a manoeuvre: the run has no success criterion (``passed`` is None)."""

    reason: str = "open-loop input"

    kind = "not_judged"

    def describe(self) -> str:
        return f"not judged ({self.reason})"

    def to_dict(self) -> dict:
        return {"kind": self.kind, **asdict(self)}


CRITERIA = {c.kind: c for c in (FunnelCriterion, PoseTolerance, PathTolerance, NotJudged)}


def criterion_from_dict(d: dict):
    """The criterion that :meth:`to_dict` wrote."""
    d = dict(d)
    kind = d.pop("kind", None)
    if kind not in CRITERIA:
        raise ScenarioError(f"unknown success criterion {kind!r}; criteria: {', '.join(CRITERIA)}")
    return CRITERIA[kind](**d)


def criterion_of(controller):
    """The criterion ``controller`` declares (module docstring): its ``criterion``, else the funnel
    for a controller with the funnel block among its diagnostics, else the default pose tolerance."""
    declared = getattr(controller, "criterion", None)
    if declared is not None:
        return declared
    from_fields = set(getattr(controller, "diagnostic_fields", ()))
    funnel = {"e1", "e2", "e3", "rho1", "rho2", "rho3", "z1", "z2", "z3"}  # controllers.base.FUNNEL_FIELDS
    return FunnelCriterion() if funnel <= from_fields else PoseTolerance()
