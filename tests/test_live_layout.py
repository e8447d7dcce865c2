"""The Foxglove layout shipped with the package names only topics and fields a run log has."""

from __future__ import annotations

import json
import re

from usv_mj.record.run_record import COLUMNS
from usv_mj.outputs.log.live import layout_path
from usv_mj.outputs.log.topics import frame_for, row_topics


def test_layout_paths_exist_in_the_log():
    layout = json.loads(open(layout_path()).read())
    fields = {f"/usv/{name}": set(f) for name, _, f in row_topics(COLUMNS)}
    plots = {k: v for k, v in layout["configById"].items() if k.startswith("Plot!")}
    assert {"Plot!errx", "Plot!erry", "Plot!forces", "Plot!moments"} <= set(plots)
    seen = set()
    for cfg in plots.values():
        for p in cfg["paths"]:
            m = re.fullmatch(r"(/usv/\w+)\.(\w+)(\.@negative)?", p["value"])
            assert m, p["value"]
            assert m.group(2) in fields[m.group(1)], p["value"]
            seen.add(m.group(2))
    assert {"e1", "rho1", "e2", "rho2", "tau_u", "f_u", "tau_r", "f_r"} <= seen
    three_d = layout["configById"]["3D!usvscene"]
    assert three_d["followTf"] == frame_for("main")
    # every panel the layout tree names is configured
    names = re.findall(r'"((?:3D|Plot|RawMessages)![a-z]+)"', json.dumps(layout["layout"]))
    assert set(names) == set(layout["configById"])
