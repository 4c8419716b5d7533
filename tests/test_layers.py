"""The package tree shows the architecture: every import goes to the same or a lower layer, and there are no cycles."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "nnphd"
# lower number = lower layer; a module may import its own layer and the layers below
LAYERS = {
    "_extras": 0,
    "_config": 0,
    "parallel": 0,
    "io": 0,
    "engine": 1,
    "explain": 2,
    "user": 3,
    "paper": 4,
    "astro": 4,
    "api": 5,
    "cli": 6,
    "__init__": 6,
}


def _modules() -> dict[str, Path]:
    out = {}
    for p in SRC.rglob("*.py"):
        parts = p.relative_to(SRC.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = p
    return out


def _imports(path: Path, mods: dict[str, Path]) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("nnphd"):
            assert node.level == 0, f"{path}: relative import"
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                found.add(sub if sub in mods else node.module)
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("nnphd")}
    return found  # "nnphd" itself (``from nnphd import configure``): the front door, the top layer


def _layer(mod: str) -> int:
    parts = mod.split(".")
    return LAYERS[parts[1] if len(parts) > 1 else "__init__"]


def test_no_import_from_a_higher_layer():
    mods = _modules()
    bad = [(m, i) for m, p in mods.items() for i in _imports(p, mods) if _layer(i) > _layer(m)]
    assert bad == []


def test_no_private_name_is_imported_from_another_module():
    """A helper another module needs is public, in a module named for what it does: no module of the package imports
    a ``_name`` from another one."""
    mods = _modules()
    bad = []
    for m, p in mods.items():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("nnphd"):
                bad += [(m, node.module, a.name) for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]  # fmt: skip
    assert bad == []


def test_every_subpackage_has_a_layer():
    assert {m.split(".")[1] for m in _modules() if "." in m} <= set(LAYERS)


def test_import_graph_has_no_cycles():
    mods = _modules()
    graph = {m: {i for i in _imports(p, mods) if i in mods and i != m} for m, p in mods.items()}
    state: dict[str, int] = {}
    cycle: list[str] = []

    def visit(m, stack):
        state[m] = 1
        for n in graph[m]:
            if state.get(n) == 1:
                cycle.extend(stack[stack.index(n) :] + [n])
                return True
            if n not in state and visit(n, stack + [n]):
                return True
        state[m] = 2
        return False

    for m in sorted(graph):
        if m not in state and visit(m, [m]):
            break
    assert cycle == []


def test_the_parser_sees_the_imports():  # the checks above are only as good as the edges they see
    mods = _modules()
    assert {"nnphd.engine.train", "nnphd.user.checks"} <= _imports(mods["nnphd.user.rounds"], mods)
    assert "nnphd.user.sampling" in _imports(mods["nnphd.user.assess"], mods)  # a lazy import, inside assess()
    assert _layer("nnphd.paper.discover") > _layer("nnphd.engine.train")


def test_the_tests_reach_the_code_through_public_names():
    """No test imports a ``_name`` of nnphd, reads a ``_attribute`` of an nnphd module or object it imported, or
    stands in a private function: the tests exercise what a user can call."""
    tests = Path(__file__).resolve().parent
    bad = []
    for p in sorted(tests.rglob("*.py")):
        tree = ast.parse(p.read_text())
        nnphd_names = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("nnphd"):
                bad += [(p.name, node.module, a.name) for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]  # fmt: skip
                nnphd_names |= {a.asname or a.name for a in node.names}
            elif isinstance(node, ast.Import):
                nnphd_names |= {a.asname or a.name.split(".")[0] for a in node.names if a.name.startswith("nnphd")}
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
                and isinstance(node.value, ast.Name)
                and node.value.id in nnphd_names
            ):
                bad.append((p.name, node.value.id, node.attr))
            if (
                isinstance(node, ast.Call)
                and getattr(node.func, "attr", "") == "setattr"
                and len(node.args) >= 2
                and isinstance(node.args[0], ast.Name)
                and node.args[0].id in nnphd_names
                and isinstance(node.args[1], ast.Constant)
                and str(node.args[1].value).startswith("_")
            ):
                bad.append((p.name, "setattr", node.args[1].value))
    assert bad == []
