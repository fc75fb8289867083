"""The engine's module structure stays clean: every module imports without the studio, and the
imports inside engine/ form no cycle (module-level and function-level imports alike)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
ENGINE = REPO / "engine"

# Violations that predate these checks, from other work merged into main; listed so that any NEW
# studio import or cycle fails. Each entry should disappear when its module is fixed.
KNOWN_STUDIO_IMPORTS: set[str] = set()
KNOWN_CYCLE_EDGES: set[tuple[str, str]] = set()


def engine_modules() -> dict[str, Path]:
    mods = {}
    for path in sorted(ENGINE.rglob("*.py")):
        rel = path.relative_to(REPO).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if parts[-1] == "__main__":
            continue
        mods[".".join(parts)] = path
    return mods


def imports_of(module: str, path: Path, known: set[str]) -> set[str]:
    """Engine modules ``module`` imports (anywhere in the file): ``import a.b`` and ``from a.b import
    c`` name ``a.b``, or ``a.b.c`` when that is a module itself."""
    tree = ast.parse(path.read_text())
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name in known}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else []))
            for a in node.names:
                sub = f"{base}.{a.name}"
                if sub in known:
                    found.add(sub)
                elif base in known:
                    found.add(base)
    found.discard(module)
    # a submodule reaching back into its own package's __init__ is Python's ordinary package
    # initialisation order, not a cycle between concepts
    return {m for m in found if not module.startswith(m + ".")}


def test_every_engine_module_imports_without_the_studio() -> None:
    mods = [m for m in engine_modules() if m != "engine"]
    code = ("import importlib, sys\n"
            f"for m in {mods!r}:\n    importlib.import_module(m)\n"
            "bad = sorted(k for k in sys.modules if k == 'studio' or k.startswith('studio.'))\n"
            "assert not bad, bad\nprint(len(sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]


def test_no_engine_module_imports_the_studio() -> None:
    offenders = []
    for module, path in engine_modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            offenders += [f"{module} imports {n}" for n in names if n == "studio" or n.startswith("studio.")]
    assert not set(offenders) - KNOWN_STUDIO_IMPORTS, sorted(set(offenders) - KNOWN_STUDIO_IMPORTS)


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                cycle = visit(nxt)
                if cycle:
                    return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def test_no_import_cycle_inside_the_engine() -> None:
    mods = engine_modules()
    known = set(mods)
    graph = {m: imports_of(m, p, known) for m, p in mods.items()}
    for a, b in KNOWN_CYCLE_EDGES:
        graph.get(a, set()).discard(b)
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " → ".join(cycle)


def test_the_cycle_finder_finds_cycles() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a"}}) is None
