"""The layers of docs/architecture.md, held against every import of the package.

Each folder of ``usv_mj/`` is a layer (``controllers/`` at the repository's top is one too). A
layer may import itself and the layers below it (:data:`ALLOWED`, the transitive closure of the
arrows of docs/architecture.md), never the ones it must not know (:data:`NEVER`). Every import
counts, the ones inside functions included: an import put inside a function to dodge a cycle is
still an edge of the graph, and the graph of files has no cycle at all.

Run it alone: ``python -m pytest tests/test_layers.py``.
"""

from __future__ import annotations

import ast
from functools import lru_cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

#: a module's layer: the first folder under usv_mj/ (or controllers/ at the top), or a root module's name
LAYER_OF_FOLDER = {
    "core": "core", "support": "core", "physics": "physics", "vessels": "vessels", "controllers": "controllers",
    "scenario": "scenario", "scene": "scene", "plants": "plants", "obstacles": "obstacles",
    "references": "references", "record": "record", "loop": "loop", "outputs": "outputs", "envs": "envs",
    "jobs": "jobs", "cli": "cli", "models": "models",
}
ROOT_MODULES = {"usv_mj": "api", "usv_mj.builder": "build"}

#: the arrows of docs/architecture.md: who may import whom (directly; the closure is taken below)
ARROWS = {
    "core": (),
    "physics": ("core",),
    "scenario": ("core", "physics"),
    "vessels": ("physics", "core"),
    "record": ("core", "physics"),     # the summary reads the physics' formulas (the one angle wrap)
    "controllers": ("physics", "core", "record"),
    "scene": ("vessels", "scenario"),
    "plants": ("scene", "physics"),
    # a reference planned around obstacles sees the hull's shape (scene), the funnel the controller
    # will keep (controllers) and reports its events into the record
    "references": ("physics", "scenario", "scene", "controllers", "record"),
    "obstacles": ("scene", "record", "references"),
    "build": ("scenario", "controllers", "references", "obstacles", "plants"),   # a fleet of single plants
    "loop": ("build", "record"),
    "outputs": ("record", "scene", "physics"),
    "envs": ("build", "loop", "outputs", "plants"),   # the dm_control Physics is a view of the MuJoCo plant
    "jobs": ("build", "loop", "outputs", "envs"),
    "cli": ("jobs", "outputs", "envs", "scenario"),
    "api": ("cli",),
    "models": (),
}

#: what must never be, whatever the closure allows (docs/architecture.md)
NEVER = {
    ("scenario", "build"), ("scenario", "jobs"), ("scenario", "vessels"), ("vessels", "jobs"),
    ("physics", "plants"), ("physics", "scenario"), ("controllers", "plants"), ("controllers", "loop"),
    ("scene", "plants"), ("plants", "obstacles"), ("record", "build"), ("outputs", "plants"),
    ("outputs", "build"), ("outputs", "loop"), ("build", "outputs"),
    *((layer, "cli") for layer in ("core", "physics", "scenario", "vessels", "controllers", "scene", "plants",
                                   "obstacles", "references", "record", "build", "loop", "outputs", "envs", "jobs")),
}

#: the package root holds these modules and no others (everything else lives in a layer's folder)
ROOT_FILES = {"__init__.py", "builder.py"}


def _closure() -> dict[str, set[str]]:
    allowed = {}
    for layer in ARROWS:
        seen, todo = {layer}, list(ARROWS[layer])
        while todo:
            nxt = todo.pop()
            if nxt not in seen:
                seen.add(nxt)
                todo.extend(ARROWS[nxt])
        allowed[layer] = seen - {b for a, b in NEVER if a == layer} | {layer}
    return allowed


ALLOWED = _closure()


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[0] in ("controllers", "models"):
        parts = ["usv_mj"] + parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


@lru_cache(maxsize=1)
def modules() -> dict[str, Path]:
    found = {}
    for top in ("usv_mj", "controllers"):
        for path in (ROOT / top).rglob("*.py"):
            if "__pycache__" not in path.parts:
                found[_module_name(path)] = path
    return found


def layer_of(module: str) -> str:
    if module in ROOT_MODULES:
        return ROOT_MODULES[module]
    parts = module.split(".")
    return LAYER_OF_FOLDER[parts[1]]


def _targets(module: str, node, is_package: bool) -> list[str]:
    names = []
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    else:
        if node.level:
            base = module.split(".") if is_package else module.split(".")[:-1]
            base = base[: len(base) - (node.level - 1)]
            prefix = ".".join(base + ([node.module] if node.module else []))
        else:
            prefix = node.module or ""
        names = [f"{prefix}.{a.name}" for a in node.names] + [prefix]
    out = []
    mods = modules()
    for name in names:
        if not (name == "usv_mj" or name.startswith("usv_mj.")):
            continue
        while name not in mods and "." in name:
            name = name.rsplit(".", 1)[0]
        out.append(name)
    return out


@lru_cache(maxsize=1)
def edges() -> list[tuple[str, str, int, bool]]:
    """(importer, imported, line, inside a function) for every import of a usv_mj module."""
    found = []
    for module, path in modules().items():
        tree = ast.parse(path.read_text(), str(path))
        is_package = path.name == "__init__.py"

        def visit(node, in_function):
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.Import, ast.ImportFrom)):
                    for target in dict.fromkeys(_targets(module, child, is_package)):
                        if target != module:
                            found.append((module, target, child.lineno, in_function))
                elif isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                    continue
                else:
                    visit(child, in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

        visit(tree, False)
    return found


def test_every_import_names_a_module_that_exists():
    """usv_mj's own code imports modules by their place in the layers (no old name, no typo)."""
    bad = []
    for module, path in modules().items():
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and not node.level and node.module and node.module.startswith("usv_mj"):
                if node.module not in modules():
                    bad.append(f"{path.relative_to(ROOT)}:{node.lineno} imports {node.module}")
            elif isinstance(node, ast.Import):
                bad.extend(f"{path.relative_to(ROOT)}:{node.lineno} imports {a.name}" for a in node.names
                           if a.name.startswith("usv_mj") and a.name not in modules())
    assert not bad, "\n".join(bad)


def test_the_package_root_holds_only_the_api_and_the_build():
    extra = sorted(p.name for p in (ROOT / "usv_mj").glob("*.py") if p.name not in ROOT_FILES)
    assert not extra, f"modules in usv_mj/ outside a layer's folder: {extra}"
    folders = sorted(p.name for p in (ROOT / "usv_mj").iterdir() if p.is_dir() and p.name != "__pycache__")
    assert set(folders) <= set(LAYER_OF_FOLDER), f"folders that are no layer: {set(folders) - set(LAYER_OF_FOLDER)}"


def test_every_import_goes_down_the_layers():
    bad = [f"{a} ({layer_of(a)}) imports {b} ({layer_of(b)}) at line {line}" + (" inside a function" if fn else "")
           for a, b, line, fn in edges() if layer_of(b) not in ALLOWED[layer_of(a)]]
    assert not bad, f"{len(bad)} imports against the layers:\n" + "\n".join(sorted(bad))


def test_no_cycle_between_files_counting_every_import():
    import networkx as nx

    graph = nx.DiGraph()
    graph.add_nodes_from(modules())
    for a, b, _, _ in edges():
        # a package's __init__ importing its own modules is the package's face, not a cycle
        if not b.startswith(a + "."):
            graph.add_edge(a, b)
    cycles = [sorted(c) for c in nx.strongly_connected_components(graph) if len(c) > 1]
    assert not cycles, "import cycles (function-level imports counted):\n" + "\n".join(map(str, cycles))


def test_argparse_only_in_the_command_line():
    users = sorted(str(p.relative_to(ROOT)) for m, p in modules().items()
                   if layer_of(m) != "cli" and "argparse" in {a.name for n in ast.walk(ast.parse(p.read_text()))
                                                              if isinstance(n, ast.Import) for a in n.names})
    assert not users, f"argparse outside usv_mj/cli/: {users}"


@pytest.mark.parametrize("a, b", sorted(NEVER))
def test_the_nevers_are_not_allowed_by_the_matrix(a, b):
    """The matrix itself keeps docs/architecture.md's nevers (a wrong arrow would let one through)."""
    assert b not in ALLOWED[a] or a == b
