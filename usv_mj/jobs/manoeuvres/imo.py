"""The manoeuvrability criteria of IMO Resolution MSC.137(76) (2002), Standards for ship manoeuvrability, §5.

They apply (§1.2) to ships of 100 m in length and over, and to chemical and gas carriers of any
length, with the rudder at its maximum angle for the turning circle (35 deg) and at 10 / 20 deg for
the zig-zags, in deep unrestricted water at the test speed (85 % of the engine output). For a smaller
vessel, or one with no rudder (the paper's 2 m hull, turned by a commanded yaw moment), they do not
formally apply; they are printed beside its results for orientation only.

- §5.2.1 initial turning ability: with 10 deg of rudder, the ship has travelled no more than 2.5 L
  by the time the heading has changed by 10 deg (measured in the 10/10 zig-zag: the track to its
  second execute);
- §5.2.2 turning ability: advance < 4.5 L, tactical diameter < 5 L;
- §5.2.3 yaw-checking and course-keeping, 10/10 zig-zag: the first overshoot angle is below
  10 deg if L/V < 10 s, 20 deg if L/V >= 30 s, (5 + 0.5 L/V) deg in between; the second overshoot
  is below the first one's limit plus 15 deg (25 deg if L/V < 10 s, 40 deg if L/V >= 30 s,
  (17.5 + 0.75 L/V) deg in between); 20/20 zig-zag: the first overshoot is below 25 deg;
- §5.2.4 stopping ability: the track reach of the full astern stopping test is below 15 L (the
  administration may allow up to 20 L for large ships).

L is the length between perpendiculars [m], V the test speed [m/s].

A vessel that is the model of a ship at scale 1:lambda (``scale``; the KVLCC2 7 m model is 1:45.714)
is judged as that ship: under Froude similarity the measures in L and the angles are the ship's,
its length is lambda L and its speed sqrt(lambda) V, so the standards apply by the ship's length and
the overshoot limits take the ship's L/V = sqrt(lambda) (L/V)_model (both L/V are printed).
"""

from __future__ import annotations

MIN_LENGTH_M = 100.0   # §1.2: the standards apply to ships of 100 m and over


def applies(length: float) -> bool:
    """True when the standards apply by length (chemical and gas carriers of any length aside)."""
    return length >= MIN_LENGTH_M


def first_overshoot_limit_10(length: float, speed: float) -> float:
    """The 10/10 zig-zag's first overshoot limit [deg] at L [m] and V [m/s] (§5.2.3.1)."""
    lv = length / speed
    return 10.0 if lv < 10 else 20.0 if lv >= 30 else 5.0 + 0.5 * lv


def second_overshoot_limit_10(length: float, speed: float) -> float:
    """The 10/10 zig-zag's second overshoot limit [deg] (§5.2.3.2): the first's plus 15 deg."""
    lv = length / speed
    return 25.0 if lv < 10 else 40.0 if lv >= 30 else 17.5 + 0.75 * lv


def _row(name: str, value, limit: float, unit: str) -> dict:
    return {"criterion": name, "value": value, "limit": limit, "unit": unit,
            "met": None if value is None else bool(value < limit)}


def criteria(kind: str, measures: dict, length: float, speed: float, switch_deg: float | None = None,
             scale: float | None = None) -> dict:
    """The criteria of MSC.137(76) that concern manoeuvre ``kind`` ("turning", "zigzag", "stopping";
    the spiral has none) against ``measures`` (in ship lengths where the criterion is), with
    ``applies`` saying whether they formally apply to a vessel of ``length`` [m] (a model at
    ``scale``: to its full-scale ship, module docstring)."""
    model_lv = length / speed if speed else None
    full = None
    if scale:
        full = {"scale": scale, "length_m": length * scale, "speed_m_s": speed * scale ** 0.5,
                "L_over_V_s": model_lv * scale ** 0.5 if model_lv is not None else None}
        length, speed = full["length_m"], full["speed_m_s"]
    rows = []
    if kind == "turning":
        rows = [_row("advance < 4.5 L", measures.get("advance_L"), 4.5, "L"),
                _row("tactical diameter < 5 L", measures.get("tactical_diameter_L"), 5.0, "L")]
    elif kind == "zigzag" and switch_deg is not None and round(switch_deg) == 10:
        rows = [_row("initial turning: track to 10 deg < 2.5 L", measures.get("track_to_second_execute_L"), 2.5, "L"),
                _row("10/10 first overshoot", measures.get("first_overshoot_deg"),
                     first_overshoot_limit_10(length, speed), "deg"),
                _row("10/10 second overshoot", measures.get("second_overshoot_deg"),
                     second_overshoot_limit_10(length, speed), "deg")]
    elif kind == "zigzag" and switch_deg is not None and round(switch_deg) == 20:
        rows = [_row("20/20 first overshoot", measures.get("first_overshoot_deg"), 25.0, "deg")]
    elif kind == "stopping":
        rows = [_row("track reach < 15 L", measures.get("track_reach_L"), 15.0, "L")]
    ok = applies(length)
    note = ("the vessel is 100 m or longer: the criteria apply" if ok else
            f"the vessel is {length:g} m long (under 100 m): IMO MSC.137(76) does not formally apply; "
            "the criteria are printed for orientation")
    if full is not None:
        note = (f"a 1:{scale:g} model of a {full['length_m']:.0f} m ship: the criteria "
                f"{'apply to' if ok else 'do not formally apply to'} that ship (L/V = {model_lv:.2f} s at model "
                f"scale, {full['L_over_V_s']:.1f} s at full scale, which sets the overshoot limits)")
    out = {"standard": "IMO MSC.137(76)", "applies": ok, "note": note, "length_m": length,
           "speed_m_s": speed, "L_over_V_s": length / speed if speed else None, "rows": rows}
    if full is not None:
        out["model_L_over_V_s"] = model_lv
        out["full_scale"] = full
    return out
