"""The paper hull's open-loop yaw instability (docs/model.md §8): the numbers and the figure.

    python scripts/yaw_instability.py [--out docs/images/yaw_instability.png]

Prints the eigenvalues of the linearized sway-yaw dynamics A = -M_sy^-1 N(u0)
(:func:`usv_mj.physics.ship.sway_yaw_linearization`) over the surge speed, the speed where the straight run
turns unstable, and the growth of a 1e-3 rad/s yaw rate with no yaw moment in the scenario
``examples/scenarios/yaw_instability.toml`` (the ``open_loop`` controller, both plants), then draws:
(a) |r(t)| on a log axis against the linear prediction expm(A t) (v0, r0); (b) the track;
(c) the eigenvalues against u0.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this checkout's usv_mj, wherever the script is run from

from usv_mj import load_scenario, simulate  # noqa: E402
from usv_mj.physics.ship import ShipParams, damping_coefficients, sway_yaw_linearization  # noqa: E402

SCENARIO = ROOT / "examples" / "scenarios" / "yaw_instability.toml"
U0 = 0.6  # m/s: the straight run of the scenario


def linear_response(a: np.ndarray, x0, times) -> np.ndarray:
    """(v, r)(t) = expm(A t) x0 by the eigen-decomposition of A (distinct real eigenvalues here)."""
    lam, vec = np.linalg.eig(a)
    c = np.linalg.solve(vec, np.asarray(x0, dtype=float))
    return np.real((vec * c) @ np.exp(np.outer(lam, times))).T


def critical_speed(ship: ShipParams, hi: float = 2.0) -> float:
    """The surge speed [m/s] above which the largest eigenvalue is positive (bisection)."""
    lo = 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if np.max(np.linalg.eigvals(sway_yaw_linearization(ship, mid)).real) > 0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "images" / "yaw_instability.png"))
    args = ap.parse_args(argv)
    ship = ShipParams()
    speeds = np.linspace(0.0, 1.2, 61)
    eig = np.array([np.sort(np.linalg.eigvals(sway_yaw_linearization(ship, u)).real) for u in speeds])
    a = sway_yaw_linearization(ship, U0)
    lam = np.sort(np.linalg.eigvals(a).real)
    u_crit = critical_speed(ship)
    print(f"A(u0 = {U0} m/s) = {np.array2string(a, precision=4)}")
    print(f"eigenvalues at u0 = {U0} m/s: {lam[1]:+.4f}, {lam[0]:+.4f} 1/s "
          f"(e-folding {1 / lam[1]:.2f} s); unstable above u0 = {u_crit:.3f} m/s")
    for u in (0.0, 0.3, 1.0):
        lam_u = np.sort(np.linalg.eigvals(sway_yaw_linearization(ship, u)).real)
        print(f"  u0 = {u:.1f} m/s: {np.array2string(lam_u, precision=4)}")
    drag = damping_coefficients(ship.as_array(), (U0, 0.0, 0.0))[0] * U0
    print(f"straight-run drag at {U0} m/s: d11 u0 = {drag:.4f} N")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_r, ax_xy, ax_l) = plt.subplots(1, 3, figsize=(15, 4.6))
    runs = {}
    for plant in ("analytic", "mujoco"):
        rec = simulate(load_scenario(SCENARIO), plant_kind=plant)
        runs[plant] = rec
        t, r = rec["t"], rec["r"]
        i4, i6 = np.searchsorted(t, 4.0), np.searchsorted(t, 6.0)
        rate = np.log(r[i6] / r[i4]) / (t[i6] - t[i4])
        print(f"{plant:8s}: r(0) = {r[0]:.1e}, growth rate over 4-6 s {rate:+.4f} 1/s, max r {r.max():.3f} rad/s "
              f"at {t[np.argmax(r)]:.1f} s, r(end) = {r[-1]:.3f} rad/s at u = {rec['u'][-1]:.3f} m/s")
    rec = runs["analytic"]
    t = rec["t"]
    lin = linear_response(a, (0.0, rec["r"][0]), t)
    ax_r.semilogy(t, np.abs(rec["r"]), label="analytic plant", lw=2)
    ax_r.semilogy(runs["mujoco"]["t"], np.abs(runs["mujoco"]["r"]), "--", label="MuJoCo plant", lw=1.5)
    m = lin[:, 1] < 1.0
    ax_r.semilogy(t[m], np.abs(lin[m, 1]), ":", color="k", label=f"linear: expm(A t), lambda = {lam[1]:+.3f} 1/s")
    ax_r.set(xlabel="t [s]", ylabel="|r| [rad/s]", title="(a) yaw rate, no yaw moment, r(0) = 1e-3 rad/s")
    ax_r.legend(fontsize=8)
    ax_r.grid(True, which="both", alpha=0.3)
    ax_xy.plot(rec["x"], rec["y"], lw=1.5)
    ax_xy.plot(rec["x"][0], rec["y"][0], "ko")
    ax_xy.set(xlabel="x (east) [m]", ylabel="y (north) [m]", title="(b) track, tau_u = 53.73 N, tau_r = 0")
    ax_xy.set_aspect("equal", "datalim")
    ax_xy.grid(True, alpha=0.3)
    ax_l.plot(speeds, eig[:, 1], label="lambda_1")
    ax_l.plot(speeds, eig[:, 0], label="lambda_2")
    ax_l.axhline(0.0, color="k", lw=0.8)
    ax_l.axvline(u_crit, color="r", ls="--", lw=0.8, label=f"u0 = {u_crit:.3f} m/s")
    ax_l.set(xlabel="u0 [m/s]", ylabel="eigenvalue [1/s]", title="(c) linearized sway-yaw A = -M^-1 N(u0)")
    ax_l.legend(fontsize=8)
    ax_l.grid(True, alpha=0.3)
    fig.tight_layout()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
