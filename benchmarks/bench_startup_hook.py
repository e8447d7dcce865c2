"""What the wheel's start-up file (packaging/usv_mj-gymnasium.pth, usv_mj/envs/gymnasium_hook.py) costs.

    python benchmarks/bench_startup_hook.py [--runs 15]

1. At interpreter start-up: ``site.addpackage`` of the file, once in each of ``--runs`` fresh
   interpreters (as site.py runs it while it starts, after the other .pth files), against a
   comment-only ``.pth`` file; the median.
2. Every later import passes the hook's finder once until gymnasium is imported: one ``find_spec``
   call that answers None.
3. When gymnasium is imported: importing and registering usv_mj.envs, timed in fresh interpreters
   after gymnasium's own import (``python -X importtime``: usv_mj.envs's cumulative time).
The machine is shared: the load average is printed with the figures.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PTH = ROOT / "packaging" / "usv_mj-gymnasium.pth"

COLD = """
import site, time
t = time.perf_counter(); site.addpackage({d!r}, {name!r}, set()); print(time.perf_counter() - t)
"""
PASS = """
import site, sys, time
site.addpackage({d!r}, {name!r}, set())
hook = sys.meta_path[0]; n = 200000; t = time.perf_counter()
for _ in range(n):
    hook.find_spec("numpy.core")
print((time.perf_counter() - t) / n)
"""


def _python(code: str, *flags: str) -> str:
    """stdout of a fresh interpreter (stderr with ``-X importtime``, where that report goes)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, *flags, "-c", code], env=env, capture_output=True, text=True, check=True,
                          cwd=ROOT)
    return proc.stderr if "importtime" in flags else proc.stdout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=15)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as d:
        (Path(d) / "empty.pth").write_text("# nothing\n")
        hook = [float(_python(COLD.format(d=str(PTH.parent), name=PTH.name))) for _ in range(args.runs)]
        empty = [float(_python(COLD.format(d=d, name="empty.pth"))) for _ in range(args.runs)]
    per_import = float(_python(PASS.format(d=str(PTH.parent), name=PTH.name)))
    register = []
    for _ in range(max(3, args.runs // 3)):
        log = _python("import gymnasium, usv_mj.envs", "-X", "importtime")
        register.append(next(int(line.split("|")[1]) for line in log.splitlines() if line.rstrip().endswith("| usv_mj.envs")))
    print(f"load average {os.getloadavg()[0]:.1f}")
    print(f"start-up: the hook file {1e6 * statistics.median(hook):.0f} us, a comment-only .pth "
          f"{1e6 * statistics.median(empty):.0f} us (median of {args.runs} fresh interpreters)")
    print(f"each later import until gymnasium's: {1e9 * per_import:.0f} ns")
    print(f"on gymnasium's import: usv_mj.envs imported and registered in {statistics.median(register) / 1e3:.1f} ms")


if __name__ == "__main__":
    main()
