"""The Imazu problem: 22 encounter situations, placed in usv_mj's frame (docs/encounters.md §4).

The 22 situations of Imazu, H. (1987), *Research on collision avoidance manoeuvre* (PhD thesis,
Univ. of Tokyo), with the geometry of Sawada, Sato & Majima (2021), J. Mar. Sci. Technol.
26:509-524, doi 10.1007/s00773-020-00755-0, **Table 4**, as transcribed identically by three public
repositories (research note §1.1-1.3; case 2's heading read as -90 deg, the only reading that points
the target at the collision point).

**The normalised geometry.** Own ship (OS) at the origin, course 000, speed U. Every target is on
a straight course to the common collision point C, R ahead of the OS, and reaches it at the same
time T = R / U as the OS if nobody manoeuvres (DCPA = 0 and TCPA = T for every OS-target pair).
A target of course c (clockwise from the OS's course) and speed ratio k starts at
C - k R (sin c, cos c) in (starboard, ahead) axes; for k = 1 its range is 2 R sin(c / 2) and its
relative bearing c / 2 - 90 deg. Sawada: R = 6 nm; only the speed ratio 0.7 of the slow vessel
being overtaken and the common arrival are confirmed by the geometry.

**Counts.** Cases 1-4 have one target, 5-11 two, 12-22 three (TUD_RL ``MMG_Imazu.py`` since commit
6ba5824 and NTNU colav-sim's ``imazu12..22``): the canonical case 12 is the three-target variant
(head-on, plus Table 4's two crossing targets). Table 4 as transcribed has case 12 with two targets
(5-12 two, 13-22 three): ``variant="table4"``. Table 4's duplicates are kept, not silently merged:
case 8 = case 5, case 22 = case 15, and Table 4's case 12 = case 6 (targets in the other order).

**The placement in usv_mj's frame** (research note §1.6): OS start p0, heading psi0 (ENU, rad),
speed U, scale R = k_R L (k_R = 50 by default: the closest start is 0.1743 R = 8.7 L, the slow
target 0.3 R = 15 L ahead)::

    f = (cos psi0, sin psi0)        OS forward;   s = (sin psi0, -cos psi0)   OS starboard
    C = p0 + R f                    reached at T = R / U
    p_i = C - k_i R (cos psi_i, sin psi_i),   psi_i = psi0 - radians(c_i),   U_i = k_i U

Every vessel starts at its steady speed (u = U_i, v = r = 0), as TUD_RL does: an acceleration
phase would move the CPA.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from usv_mj.core.errors import ScenarioError

K_R_DEFAULT = 50.0
VARIANTS = ("canonical", "table4")
#: cases whose targets equal another case's (Table 4 as transcribed): case -> the case it repeats
DUPLICATES = {8: 5, 22: 15}
SOURCE = ("Imazu (1987); geometry of Sawada, Sato & Majima (2021) J. Mar. Sci. Technol. 26:509-524, "
          "Table 4, via three public transcriptions (research note §1)")


@dataclass(frozen=True)
class ImazuTarget:
    """One target of a case, in the normalised geometry (module docstring).

    Attributes
    ----------
    course_rel_deg:
        The target's course minus the OS's, clockwise [deg, 0..360).
    speed_ratio:
        The target's speed / the OS's speed [-] (0.7 only for the slow vessel being overtaken).
    bearing_deg, range_R, x_R, y_R:
        The published start (Table 4, rounded to its 0.001 nm): relative bearing from the OS's bow
        [deg, + starboard], range / R, starboard and ahead offsets / R. The placement computes the
        start from the course and the speed ratio (exact common arrival); these are the check.
    situation:
        The encounter for the OS at the start (usv_mj.physics.colregs' names, research note §1.2).
    """

    course_rel_deg: float
    speed_ratio: float
    bearing_deg: float
    range_R: float
    x_R: float
    y_R: float
    situation: str


@dataclass(frozen=True)
class ImazuCase:
    id: int
    targets: tuple[ImazuTarget, ...]
    variant: str = "canonical"

    @property
    def n_targets(self) -> int:
        return len(self.targets)


def _t(bearing, range_r, course, ratio, x, y, situation):
    return ImazuTarget(float(course), float(ratio), float(bearing), float(range_r), float(x), float(y), situation)


HO, GW, SO, OT = "head_on", "crossing_give_way", "crossing_stand_on", "overtaking"
# the rows of research note §1.3 (bearing_deg, range_R, course_rel_deg, speed_ratio, x_R, y_R, situation)
_HEAD_ON = _t(0.00, 2.0000, 180.0, 1.0, 0.0000, 2.0000, HO)
_S45 = _t(45.00, 1.4142, 270.0, 1.0, 1.0000, 1.0000, GW)
_SLOW = _t(0.00, 0.3000, 0.0, 0.7, 0.0000, 0.3000, OT)
_P67 = _t(-67.50, 0.7654, 45.0, 1.0, -0.7071, 0.2929, SO)
_S85 = _t(85.00, 0.1743, 350.0, 1.0, 0.1736, 0.0152, GW)
_S67 = _t(67.50, 0.7654, 315.0, 1.0, 0.7071, 0.2929, GW)
_S75 = _t(75.00, 0.5176, 330.0, 1.0, 0.5000, 0.1340, GW)
_P82 = _t(-82.50, 0.2611, 15.0, 1.0, -0.2588, 0.0341, SO)
_P45 = _t(-45.00, 1.4142, 90.0, 1.0, -1.0000, 1.0000, SO)
_P85 = _t(-85.00, 0.1743, 10.0, 1.0, -0.1736, 0.0152, SO)
_P44_SLOW = _t(-44.42, 0.7071, 45.0, 0.7, -0.4950, 0.5050, SO)
_S22 = _t(22.50, 1.8478, 225.0, 1.0, 0.7071, 1.7071, GW)
_S82 = _t(82.50, 0.2611, 345.0, 1.0, 0.2588, 0.0341, GW)

_CASES = {
    1: (_HEAD_ON,),
    2: (_S45,),
    3: (_SLOW,),
    4: (_P67,),
    5: (_HEAD_ON, _S45),
    6: (_S85, _S67),
    7: (_SLOW, _S67),
    8: (_HEAD_ON, _S45),
    9: (_S75, _S45),
    10: (_S45, _P82),
    11: (_P45, _S75),
    12: (_HEAD_ON, _S67, _S85),     # TUD_RL's three-target case 12 (the head-on target listed first)
    13: (_HEAD_ON, _P85, _P67),
    14: (_S85, _S67, _S45),
    15: (_SLOW, _S67, _S45),
    16: (_P44_SLOW, _P45, _S45),
    17: (_SLOW, _P85, _S67),
    18: (_S22, _S82, _S75),
    19: (_P82, _S82, _S22),
    20: (_SLOW, _S82, _S45),
    21: (_S82, _P82, _S45),
    22: (_SLOW, _S67, _S45),
}
#: Table 4's case 12 as transcribed: two targets (= case 6, in the other order)
_TABLE4_CASE12 = (_S67, _S85)

IMAZU_CASES: dict[int, ImazuCase] = {i: ImazuCase(i, targets) for i, targets in _CASES.items()}


def imazu_case(case_id: int, variant: str = "canonical") -> ImazuCase:
    """Case ``case_id`` (1..22) in the normalised geometry; ``variant="table4"`` gives Table 4's
    two-target case 12 (every other case is the same in both variants)."""
    if isinstance(case_id, bool) or not isinstance(case_id, int) or case_id not in IMAZU_CASES:
        raise ScenarioError(f"imazu: case must be an integer 1..22, got {case_id!r}")
    if variant not in VARIANTS:
        raise ScenarioError(f"imazu: variant must be one of {', '.join(VARIANTS)}, got {variant!r}")
    if variant == "table4" and case_id == 12:
        return ImazuCase(12, _TABLE4_CASE12, "table4")
    return IMAZU_CASES[case_id]


@dataclass(frozen=True)
class VesselStart:
    """Where and how one vessel starts (plain data for a ``[[vessels]]`` table).

    Attributes
    ----------
    name:
        "own" for the own ship, "ts1", "ts2", "ts3" for the targets in the case's order.
    eta:
        (x [m], y [m], psi [rad]): position and heading in usv_mj's frame.
    speed:
        The steady speed [m/s]: start with nu = (speed, 0, 0).
    heading_deg:
        The same heading as a compass course [deg, clockwise from north].
    speed_ratio:
        speed / the own ship's speed [-].
    """

    name: str
    eta: tuple[float, float, float]
    speed: float
    heading_deg: float
    speed_ratio: float

    @property
    def nu(self) -> tuple[float, float, float]:
        return (self.speed, 0.0, 0.0)

    @property
    def state(self) -> tuple[float, float, float, float, float, float]:
        """(x, y, psi, u, v, r) at the start."""
        return self.eta + self.nu

    def as_table(self) -> dict:
        """``{"name", "eta", "speed"}``: the keys of a vessel's start in a scenario table."""
        return {"name": self.name, "eta": list(self.eta), "speed": self.speed}


@dataclass(frozen=True)
class ImazuSituation:
    """A case placed and scaled (module docstring): the vessels, the own ship first.

    Attributes
    ----------
    case, variant:
        Which case (1..22) and variant.
    length_m, speed_mps, k_R:
        The own ship's length L [m] and speed U [m/s], and the scale factor: R = k_R L.
    R_m, T_cpa_s:
        The distance to the common collision point [m] and the time every vessel reaches it [s].
    collision_point, goal:
        C = p0 + R f and the own ship's goal p0 + 2 R f (the CPA point plus the same distance again,
        as TUD_RL) [m]; run at least 2 T_cpa_s.
    vessels:
        The own ship, then the targets (:class:`VesselStart`).
    target_situations:
        The published situation of each target for the own ship (usv_mj.physics.colregs' names).
    """

    case: int
    variant: str
    length_m: float
    speed_mps: float
    k_R: float
    R_m: float
    T_cpa_s: float
    collision_point: tuple[float, float]
    goal: tuple[float, float]
    vessels: tuple[VesselStart, ...]
    target_situations: tuple[str, ...] = ()

    @property
    def situations(self) -> dict[int, str]:
        """``{vessel index: the own ship's situation}`` for the targets (1, 2, 3): what
        :func:`usv_mj.record.colregs_scores.score_encounters` takes as ``situations``."""
        return {i: name for i, name in enumerate(self.target_situations, start=1)}

    @property
    def own(self) -> VesselStart:
        return self.vessels[0]

    @property
    def targets(self) -> tuple[VesselStart, ...]:
        return self.vessels[1:]


def _positive(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ScenarioError(f"imazu: {name} must be a positive number, got {value!r}")
    return float(value)


def imazu_situation(case_id: int, length_m: float, speed_mps: float, *, k_R: float = K_R_DEFAULT,
                    origin: tuple[float, float] = (0.0, 0.0), psi0: float = math.pi / 2,
                    variant: str = "canonical") -> ImazuSituation:
    """Case ``case_id`` placed in usv_mj's frame for an own ship of length ``length_m`` [m] at
    ``speed_mps`` [m/s]: R = k_R L, the own ship at ``origin`` [m] heading ``psi0`` [rad, ENU; north by
    default, so that the picture is Table 4's], every target on its collision course at its steady
    speed (module docstring)."""
    case = imazu_case(case_id, variant)
    length_m, speed_mps, k_R = _positive("length_m", length_m), _positive("speed_mps", speed_mps), _positive("k_R", k_R)
    x0, y0 = float(origin[0]), float(origin[1])
    psi0 = float(psi0)
    R = k_R * length_m
    T = R / speed_mps
    fx, fy = math.cos(psi0), math.sin(psi0)
    cx, cy = x0 + R * fx, y0 + R * fy
    own_heading = (90.0 - math.degrees(psi0)) % 360.0
    vessels = [VesselStart("own", (x0, y0, psi0), speed_mps, own_heading, 1.0)]
    for n, target in enumerate(case.targets, start=1):
        psi = psi0 - math.radians(target.course_rel_deg)
        psi = math.atan2(math.sin(psi), math.cos(psi))
        run = target.speed_ratio * R   # the distance it covers in T
        vessels.append(VesselStart(
            f"ts{n}", (cx - run * math.cos(psi), cy - run * math.sin(psi), psi), target.speed_ratio * speed_mps,
            (own_heading + target.course_rel_deg) % 360.0, target.speed_ratio))
    return ImazuSituation(case.id, case.variant, length_m, speed_mps, k_R, R, T, (cx, cy),
                          (x0 + 2.0 * R * fx, y0 + 2.0 * R * fy), tuple(vessels),
                          tuple(t.situation for t in case.targets))
