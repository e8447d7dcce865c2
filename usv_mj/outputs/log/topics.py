"""The topics of a run log (``run.mcap``), their schemas and the number conventions.

A file holds the runs given to its writer; the main job writes one run per file: the main run to
``run.mcap`` and the PI baseline to ``baseline.mcap`` beside it (a companion: ``read_run`` of the
first adds the second), so that each file is in log-time order. Each run has a topic prefix: the
main controller's run ``"main"`` uses ``/usv``, the PI baseline ``"baseline"`` uses
``/baseline/usv``, any other run name ``NAME`` uses ``/NAME/usv``. Under a prefix ``P``:

Per control step (one message per row of the :class:`~usv_mj.record.run_record.RunRecord`, ``log_time`` =
``publish_time`` = round(t * 1e9) ns, ``sequence`` = row index k; message encoding ``protobuf``,
schema a ``FileDescriptorSet`` of the proto3 message named in the table, every field a ``double``
numbered in the order shown, documented (units, conventions) in the descriptor's comments:
:mod:`usv_mj.outputs.log.protobuf_rows`), laid out from the run's own columns (:func:`row_topics`):

=====================  ==========================================================================
``P/state``            ``usv_mj.State``: t, x, y, psi, u, v, r (psi unwrapped; conventions below)
``P/reference``        ``usv_mj.Reference``: t, x_d, y_d, psi_d, x_d_dot, y_d_dot, r_d, u_d
``P/control``          ``usv_mj.Control``: t, tau_u, tau_r (the law's output), q_tau_u, q_tau_r (the quantized command),
                       k_u, k_r (the quantizers' signed level indices), f_u, f_r (the force the
                       actuators realize, what the plant gets), sat_u, sat_r (1 where a limit cut it)
``P/errors``           ``usv_mj.Errors``: t, e1, e2, e3 (Eq. 14), rho1, rho2, rho3 (Eq. 9), z1, z2, z3: only when the
                       controller declares this funnel block (the PPC law, the PI baseline)
``P/diagnostics``      ``usv_mj.Diagnostics``: t and the rest of the controller's declared ``diagnostic_fields`` in their
                       order (schema ``usv_mj.Diagnostics``, generated from the names: the PPC law's
                       e1s..e3s, psi_a, u_e.., alpha_*, w_*_norm, s2, s2_clamped; the PI baseline's
                       e1s..e3s, psi_a, u_e, r_e, integral_u, integral_r; a user's controller's own)
=====================  ==========================================================================

so that the whole record is rebuilt bit-exactly from these topics; the run's ``run_start``
metadata lists its ``columns``, ``diagnostic_fields`` and ``diagnostic_events``.

As they happen: ``P/events``: t, seq (the event's index in ``record.events`` as appended), kind
("funnel_violation", "funnel_recovered", "s2_clamp", "divergence", "interrupted", "failed", ...),
message, values (an object); at the run's end one more message with kind "run_end",
"synthetic": true, the status and the stop reason (not part of ``record.events``). An event
reported after later rows were written is logged at the log time already reached (its ``t`` is
its own), so that the file stays in log-time order.

For Foxglove's 3D panel (schemas: Foxglove's published ``foxglove.FrameTransform`` and
``foxglove.SceneUpdate``, embedded as published: ``schemas/``), every ``FRAME_PERIOD`` = 20 ms of
simulated time (every round(0.02 / dt)-th row, reduced rate to keep the file small):

- ``P/tf/hull``: ``foxglove.FrameTransform`` ``map`` -> ``B`` (x, y, 0; yaw psi about z);
- ``P/tf/reference``: ``foxglove.FrameTransform`` ``map`` -> ``R`` (x_d, y_d, 0; yaw psi_d);
- ``P/scene/funnel`` (runs with the funnel block): ``foxglove.SceneUpdate``, entity "funnel": the
  box |x - x_d| < rho1, |y - y_d| < rho2 around the reference point (a LINE_LOOP in ``map``; the
  controller bounds the offset point x + eps cos psi of Eq. 14, eps = m23/m22 is a few mm, not drawn);

and at t = 0 and every 10 s: ``P/scene/path`` (entity "reference_path", the run's reference
sampled every 0.5 s over the whole run, LINE_STRIP in ``map``) and ``P/scene/hull`` (entity "hull",
a box of the CyberShip II's size locked to frame ``B``).

Frames and axes (REP-103, REP-105): ``map`` is the world-fixed frame, x east, y north, z up (ENU);
``B`` = ``base_link`` is the hull (body x forward, y to port, z up): "base_link" for the main run,
"baseline/base_link" for the baseline, "NAME/base_link" otherwise; ``R`` is the reference pose:
"reference", "baseline/reference", "NAME/reference". psi is the heading counter-clockwise from
east (a yaw about z up: psi turns x towards y as in the kinematics of :mod:`usv_mj.physics.ship`); u, v
are the body-frame surge (forward) and sway (to port) speeds, r the yaw rate (counter-clockwise).

When the run has them (:mod:`usv_mj.outputs.log.extra_topics`): ``P/obstacles`` (per control step: t and,
per obstacle, name, clearance_m, normal_force_N, center {x, y}), ``P/scene/obstacles``
(``foxglove.SceneUpdate`` of the obstacles and their inflated boundaries in ``map``, at t = 0 and
every 10 s, moving obstacles every 20 ms) and ``P/environment`` (per control step in a non-calm sea:
t, zeta, tau_wave, tau_drift, tau_wind {x, y, n} body frame, current {x, y} world frame, wind
{speed, direction}).

Inside each chunk the messages are in log-time order, and chunks follow each other in time, so a
reader going through a one-run file front to back sees log time never go back.

Numbers: in the protobuf topics (the per-step ones) a float64 is a protobuf ``double``, its IEEE
bits as they are (NaN payloads, -0.0 and +-inf included), so the record is rebuilt bit for bit.
The events and the Foxglove topics are JSON (schema encoding ``jsonschema``; Foxglove's published
schemas for its own): a float64 is the shortest decimal that reads back to the same double
(orjson's formatting, ``repr``-equivalent); JSON has no NaN or infinity, so NaN is ``null`` and
+-inf is ``1e999`` / ``-1e999`` in the frames and the funnel (valid JSON numbers that IEEE
parsers, JavaScript's JSON.parse and Python's json, read as +-Infinity), ``null`` in an event's
values. Logs of schema version 2 (the per-step topics in JSON, same fields) still read.
"""

from __future__ import annotations

import json

from usv_mj.core.layouts import FUNNEL_FIELDS, REF_FIELDS
from usv_mj.record.run_record import COLUMNS, CONTROL_FIELDS, CORE_COLUMNS, STATE_FIELDS
from usv_mj.outputs.log.protobuf_rows import Message, file_descriptor_set, flat_message

SCHEMA_VERSION = "usv_mj.outputs.log/3"   # 3: per-step topics in protobuf (2: JSON)
FRAME_PERIOD = 0.02      # s of simulated time between FrameTransform / funnel SceneUpdate messages
SLOW_PERIOD = 10.0       # s between the path and hull SceneUpdate messages
PATH_SAMPLE = 0.5        # s between the points of the drawn reference path
HULL_SIZE = (1.255, 0.29, 0.25)   # m: CyberShip II length, beam, a display height (display only)

#: the row topics every run has (the record's core columns)
CORE_ROW_TOPICS = (
    ("state", "usv_mj.State", ("t",) + STATE_FIELDS),
    ("reference", "usv_mj.Reference", ("t",) + REF_FIELDS),
    ("control", "usv_mj.Control", ("t",) + CONTROL_FIELDS),
)
ERRORS_TOPIC = ("errors", "usv_mj.Errors", ("t",) + FUNNEL_FIELDS)
DIAGNOSTICS_TITLE = "usv_mj.Diagnostics"
#: schema titles of row topics (one message per control step, flat numbers), this version's and
#: version 1's (usv_mj.Adaptation / usv_mj.Internal), so that older logs still read
ROW_SCHEMAS = frozenset({t for _, t, _ in CORE_ROW_TOPICS} | {ERRORS_TOPIC[1], DIAGNOSTICS_TITLE,
                                                              "usv_mj.Adaptation", "usv_mj.Internal"})


def row_topics(column_names=COLUMNS) -> tuple:
    """The row topics of a run whose record has ``column_names`` (the core, then the controller's
    declared fields): (name, schema title, fields) triples covering every column exactly once
    (``t`` on each). ``errors`` only when the block declares the funnel (e, rho, z);
    ``diagnostics`` holds the rest of the block in its declared order (absent when it is empty)."""
    names = tuple(column_names)
    if names[:len(CORE_COLUMNS)] != CORE_COLUMNS:
        raise ValueError(f"a record's columns start with the core {CORE_COLUMNS}, got {names[:len(CORE_COLUMNS)]}")
    block = names[len(CORE_COLUMNS):]
    funnel = all(f in block for f in FUNNEL_FIELDS)
    out = list(CORE_ROW_TOPICS)
    if funnel:
        out.append(ERRORS_TOPIC)
    rest = tuple(f for f in block if not (funnel and f in FUNNEL_FIELDS))
    if rest:
        out.append(("diagnostics", DIAGNOSTICS_TITLE, ("t",) + rest))
    return tuple(out)


#: the row topics of a run of the paper's PPC law (the default record layout)
ROW_TOPICS = row_topics(COLUMNS)
assert sorted(f for _, _, fields in ROW_TOPICS for f in fields if f != "t") == sorted(COLUMNS[1:])

FIELD_DOC = {
    "t": "time [s]",
    "x": "position x [m] in the world frame (REP-103 ENU: x east, y north, z up)",
    "y": "position y [m] in the world frame (north)",
    "psi": "heading psi [rad], counter-clockwise from east (the world x axis) about z up; unwrapped",
    "u": "surge speed [m/s], along the body x axis (forward)",
    "v": "sway speed [m/s], along the body y axis (to port)",
    "r": "yaw rate [rad/s], counter-clockwise positive (about z up)",
    "x_d": "reference x_d [m] (world, east)", "y_d": "reference y_d [m] (world, north)",
    "psi_d": "reference heading psi_d [rad], counter-clockwise from east", "u_d": "reference surge speed u_d [m/s]",
    "r_d": "reference yaw rate r_d [rad/s]", "x_d_dot": "dx_d/dt [m/s]", "y_d_dot": "dy_d/dt [m/s]",
    "e1": "e1 = x_bar - x_bar_d [m] (Eq. 14)", "e2": "e2 = y_bar - y_bar_d [m] (Eq. 14)",
    "e3": "e3 = wrap(psi - psi_a) [rad]", "rho1": "funnel bound rho1 [m] (Eq. 9)",
    "rho2": "funnel bound rho2 [m] (Eq. 9)", "rho3": "funnel bound rho3 [rad] (Eq. 9)",
    "z1": "z1 = e1 / rho1", "z2": "z2 = e2 / rho2", "z3": "z3 = e3 / rho3",
    "e1s": "transformed error e1* (Eq. 10)", "e2s": "transformed error e2* (Eq. 10)",
    "e3s": "transformed error e3* (Eq. 10)", "psi_a": "psi_a [rad] (Eq. 15)",
    "u_e": "surge velocity error u_e [m/s] (Eq. 19)", "v_e": "sway velocity error v_e [m/s] (Eq. 19)",
    "r_e": "yaw-rate error r_e [rad/s] (Eq. 19)", "alpha_u": "virtual control alpha_u (Eq. 17)",
    "alpha_v": "virtual control alpha_v (Eq. 17)", "alpha_r": "virtual control alpha_r (Eq. 17)",
    "w_u_norm": "|W_u| (Eq. 29)", "w_v_norm": "|W_v|", "w_r_norm": "|W_r| (Eq. 37)",
    "s2": "s2 = tanh(gamma_2)", "s2_clamped": "1 when s2 hit its clamp this step, else 0",
    "tau_u": "surge force from the law [N]", "tau_r": "yaw moment from the law [N m]",
    "q_tau_u": "quantized surge force applied [N]", "q_tau_r": "quantized yaw moment applied [N m]",
    "k_u": "surge quantizer level index (signed)", "k_r": "yaw quantizer level index (signed)",
    "f_u": "surge force the actuators realize, what the plant receives [N] (a ruddered vessel's n_P [1/s]: "
           "the metadata's channels)",
    "f_r": "yaw moment the actuators realize, what the plant receives [N m] (a ruddered vessel's rudder "
           "angle [rad]: the metadata's channels)",
    "sat_u": "1 where an actuator limit cut the surge command, else 0",
    "sat_r": "1 where an actuator limit cut the yaw command, else 0",
    "integral_u": "PI baseline: integral of u_c - u [m]", "integral_r": "PI baseline: integral of e3 [rad s]",
}


def prefix_for(run: str) -> str:
    """Topic prefix of a run: "/usv" for "main", "/baseline/usv" for "baseline", "/NAME/usv" else."""
    if not run or "/" in run or run.strip() != run:
        raise ValueError(f"run name must be a non-empty word without '/' or spaces, got {run!r}")
    return "/usv" if run == "main" else f"/{run}/usv"


WORLD_FRAME = "map"   # REP-105: the world-fixed frame (x east, y north, z up: REP-103 ENU)


def frame_for(run: str) -> str:
    """Name of the hull frame of a run (REP-105 ``base_link``: "base_link" for the main run,
    "baseline/base_link", "NAME/base_link" otherwise, so that two runs open side by side do not clash)."""
    return "base_link" if run == "main" else f"{run}/base_link"


def reference_frame_for(run: str) -> str:
    """Name of the frame of a run's reference pose ("reference", "baseline/reference", ...)."""
    return "reference" if run == "main" else f"{run}/reference"


def row_message(title: str, fields: tuple, description: str = "") -> Message:
    """The protobuf message of a row topic: ``fields`` as doubles, documented from :data:`FIELD_DOC`."""
    return flat_message(title, fields, FIELD_DOC,
                        description or "one control step of a usv_mj run (see usv_mj.outputs.log.topics)")


def row_topic_schema(title: str, fields: tuple, description: str = "") -> bytes:
    """The MCAP schema data of a row topic (a serialized protobuf ``FileDescriptorSet``)."""
    return file_descriptor_set(row_message(title, fields, description))


EVENT_SCHEMA = json.dumps({
    "title": "usv_mj.Event", "type": "object",
    "description": "something that happened in the run: funnel violation, s2 clamp, divergence, stop",
    "properties": {
        "t": {"type": "number", "description": "time [s]"},
        "seq": {"type": "integer", "description": "index of the event in record.events as appended"},
        "kind": {"type": "string"}, "message": {"type": "string"},
        "values": {"type": "object", "description": "the numbers behind the message"},
        "synthetic": {"type": "boolean", "description": "true for the run_end marker (not a record event)"},
        "status": {"type": "string"}, "stop_reason": {"type": "string"},
    },
    "required": ["t", "seq", "kind", "message", "values"],
}, indent=1).encode()

# --- Foxglove well-known schemas: the published JSON schemas, embedded as they are (schemas/NOTICE.md) ---


def foxglove_schema(name: str) -> bytes:
    """The published JSON schema of ``foxglove.NAME`` (``schemas/foxglove.NAME.json``), bytes as published."""
    from importlib import resources

    return (resources.files(__package__) / "schemas" / f"{name}.json").read_bytes()


FRAME_TRANSFORM_SCHEMA = foxglove_schema("foxglove.FrameTransform")
SCENE_UPDATE_SCHEMA = foxglove_schema("foxglove.SceneUpdate")


def topic_table(run: str, column_names=COLUMNS) -> list[dict]:
    """Every topic of one run whose record has ``column_names``: name, schema name, kind ("rows",
    "events", "foxglove"), fields (the per-run extras of extra_topics are not listed)."""
    p = prefix_for(run)
    rows = row_topics(column_names)
    table = [{"topic": f"{p}/{name}", "schema": title, "kind": "rows", "fields": fields}
             for name, title, fields in rows]
    table.append({"topic": f"{p}/events", "schema": "usv_mj.Event", "kind": "events", "fields": ()})
    funnel = any(name == "errors" for name, _, _ in rows)
    for name, schema in (("tf/hull", "foxglove.FrameTransform"), ("tf/reference", "foxglove.FrameTransform"),
                         ("scene/funnel", "foxglove.SceneUpdate"), ("scene/path", "foxglove.SceneUpdate"),
                         ("scene/hull", "foxglove.SceneUpdate")):
        if name == "scene/funnel" and not funnel:
            continue
        table.append({"topic": f"{p}/{name}", "schema": schema, "kind": "foxglove", "fields": ()})
    return table
