"""The 22 Imazu situations and the COLREGs sectors (docs/encounters.md): the figure.

    python scripts/imazu_figure.py [--out docs/images/imazu_cases.png]

Draws every case as :func:`usv_mj.scenario.imazu.imazu_situation` places it (own ship at the origin
heading north, R = 1 in units of R), each vessel's start with its track to the common collision
point C, coloured by the own ship's situation from :func:`usv_mj.physics.colregs.classify_pair`; and
a last panel with the sectors of the Woerner-style classifier seen from the own ship's bow.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this checkout's usv_mj, wherever the script is run from

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Wedge  # noqa: E402

from usv_mj.physics.colregs import SITUATION_NAMES, ColregsParams, classify_pair  # noqa: E402
from usv_mj.scenario.imazu import imazu_situation  # noqa: E402

COLOURS = {"head_on": "tab:red", "crossing_give_way": "tab:orange", "crossing_stand_on": "tab:green",
           "overtaking": "tab:purple", "overtaken": "tab:brown", "none": "grey"}
LABELS = {"head_on": "head-on (R14)", "crossing_give_way": "crossing, own gives way (R15/16)",
          "crossing_stand_on": "crossing, own stands on (R15/17)", "overtaking": "own overtaking (R13/16)"}


def arrow(ax, x, y, psi, colour, size=0.3):
    ax.annotate("", xy=(x + size * math.cos(psi), y + size * math.sin(psi)), xytext=(x, y),
                arrowprops=dict(arrowstyle="-|>", color=colour, lw=1.4, mutation_scale=10))


def draw_case(ax, case):
    sit = imazu_situation(case, 1.0, 1.0, k_R=1.0)   # R = 1: axes in units of R
    cx, cy = sit.collision_point
    ax.plot([0, cx], [0, cy], color="k", lw=0.6, ls=":")
    arrow(ax, 0.0, 0.0, sit.own.eta[2], "k")
    ax.plot(0, 0, "ko", ms=3)
    for v in sit.targets:
        name = SITUATION_NAMES[classify_pair(sit.own.state, v.state)]
        x, y, psi = v.eta
        ax.plot([x, cx], [y, cy], color=COLOURS[name], lw=0.6, ls=":")
        ax.plot(x, y, "o", color=COLOURS[name], ms=3 if v.speed_ratio == 1.0 else 5, mfc="none" if v.speed_ratio < 1 else None)
        arrow(ax, x, y, psi, COLOURS[name])
    ax.plot(cx, cy, "x", color="k", ms=4)
    ax.set_title(f"{case}", fontsize=8, pad=2)
    ax.set_xlim(-1.15, 1.15)
    ax.set_ylim(-0.15, 2.15)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def draw_sectors(ax, p: ColregsParams):
    """The own ship's sectors of the target's relative bearing beta (compass-like: up = the bow)."""
    def wedge(b0, b1, colour, r=1.0):   # bearings clockwise from the bow -> matplotlib's CCW from +x
        ax.add_patch(Wedge((0, 0), r, 90 - b1, 90 - b0, color=colour, alpha=0.35, lw=0))
    wedge(-p.a14_deg, p.a14_deg, COLOURS["head_on"], 1.0)
    wedge(p.a14_deg, p.stern_deg, COLOURS["crossing_give_way"], 0.9)
    wedge(-p.stern_deg, -p.a14_deg, COLOURS["crossing_stand_on"], 0.9)
    wedge(p.stern_deg, 360 - p.stern_deg, COLOURS["overtaken"], 0.9)
    arrow(ax, 0, -0.25, math.pi / 2, "k", 0.5)
    for b, text in ((0, f"±{p.a14_deg:g}°"), (p.stern_deg, f"{p.stern_deg:g}°"), (-p.stern_deg, f"-{p.stern_deg:g}°")):
        ax.text(1.12 * math.sin(math.radians(b)), 1.12 * math.cos(math.radians(b)), text, ha="center",
                va="center", fontsize=6)
    ax.set_xlim(-1.3, 1.3)
    ax.set_ylim(-1.3, 1.3)
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.set_title("beta sectors (with alpha)", fontsize=7, pad=2)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "images" / "imazu_cases.png"))
    args = parser.parse_args(argv)
    fig, axes = plt.subplots(4, 6, figsize=(9.0, 6.9))
    for case, ax in zip(range(1, 23), axes.flat):
        draw_case(ax, case)
    draw_sectors(axes.flat[22], ColregsParams())
    legend = axes.flat[23]
    legend.set_axis_off()
    for name, label in LABELS.items():
        legend.plot([], [], "o", color=COLOURS[name], label=label)
    legend.plot([], [], "o", color=COLOURS["overtaken"], alpha=0.5, label="stern sector (R13)")
    legend.plot([], [], "o", color="grey", mfc="none", ms=5, label="slow target (0.7 U)")
    legend.plot([], [], "kx", label="collision point C")
    legend.legend(loc="center", fontsize=6, frameon=False)
    fig.suptitle("The 22 Imazu situations in usv_mj (own ship at the origin heading north; axes in R; "
                 "every vessel reaches C at T = R / U)", fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 0.97), h_pad=0.4, w_pad=0.2)
    fig.savefig(args.out, dpi=130)
    print(args.out)


if __name__ == "__main__":
    main()
