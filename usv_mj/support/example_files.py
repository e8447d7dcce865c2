"""The example scenarios and sweeps, found by name (``--scenario harbour_gap``, ``usv-mj sweep quick``).

They live in ``examples/scenarios/*.toml`` and ``examples/sweeps/*.toml`` of a checkout, and a wheel
carries the same files as the data of ``usv_mj.examples`` (``package-dir`` in pyproject.toml maps
``examples/`` there, as it maps ``controllers/`` and ``models/``). Only those two folders are data:
anything else under ``examples/`` (a plug-in package, say) is not shipped.

A name is a file's stem; a path that exists stays a path, and so does any other value with a folder
or a ``.toml`` in it, except ``.../examples/scenarios/NAME.toml`` (or ``sweeps``) that is not there:
the README's commands, run by a pip user outside a checkout, get the shipped copy.
Each file's first comment line is its one-line description (``usv-mj examples``).
"""

from __future__ import annotations

from pathlib import Path

from usv_mj.support.assets import PACKAGE_DIR

KINDS = ("scenarios", "sweeps")


def examples_root() -> Path | None:
    """``usv_mj/examples`` in an installed wheel, else ``examples/`` beside the package (a checkout)."""
    here = PACKAGE_DIR
    for root in (here / "examples", here.parent / "examples"):
        if (root / "scenarios").is_dir():
            return root
    return None


def names(kind: str) -> list[str]:
    root = examples_root()
    return sorted(p.stem for p in (root / kind).glob("*.toml")) if root else []


def find(value, kind: str) -> Path | None:
    """The example file named ``value`` (a stem) of ``kind``, or None."""
    text = str(value)
    if not text or Path(text).exists():
        return None
    parts = Path(text).parts
    if len(parts) >= 3 and parts[-3:-1] == ("examples", kind) and text.endswith(".toml"):
        text = Path(text).stem          # the README's examples/scenarios/x.toml, outside a checkout
    elif "/" in text or "\\" in text or text.endswith(".toml"):
        return None
    root = examples_root()
    path = root / kind / f"{text}.toml" if root else None
    return path if path is not None and path.is_file() else None


def resolve(value, kind: str) -> Path:
    """``value`` as a file: the example of that name when it names one and no file of that name exists."""
    return find(value, kind) or Path(value)


def describe(path: Path, width: int = 95) -> str:
    """The first sentence of the file's first comment (its one-line description), at most ``width``
    characters (cut at a clause, then a word, if longer)."""
    import re

    block = []
    for line in Path(path).read_text().splitlines():
        if not line.startswith("#"):
            if block or line.strip():
                break
            continue
        text = line.lstrip("#").strip()
        if not text or text.startswith("usv-mj "):
            break
        block.append(text)
    text = " ".join(block)
    end = re.search(r"(?<!Eq)(?<!e\.g)[.?!](?=\s|$)", text)
    if end:
        text = text[:end.end()]
    if len(text) > width:
        cut = max(text.rfind(sep, 0, width) for sep in (": ", "; ", ", ", " ("))
        text = (text[:cut] if cut > width // 2 else text[:text.rfind(" ", 0, width)]) + " ..."
    return text


def listing() -> str:
    """What ``usv-mj examples`` prints: each example by name with its first comment line."""
    root = examples_root()
    if root is None:
        return "no examples found (neither usv_mj/examples nor examples/ beside the package)"
    lines = []
    for kind, how in (("scenarios", "usv-mj run --scenario NAME"), ("sweeps", "usv-mj sweep NAME")):
        lines.append(f"{kind} ({how}; the files are in {root / kind}):")
        for name in names(kind):
            lines.append(f"  {name:16s} {describe(root / kind / f'{name}.toml')}")
        lines.append("")
    return "\n".join(lines).rstrip()
