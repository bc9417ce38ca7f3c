"""The package's layout rules: data flows one way (no import cycle among module-level imports),
no module over ~700 lines, no kernel loaded by an import, the typed config read only by the
``from_config`` builders, tests mirroring the package."""

from __future__ import annotations

import ast
import re
import subprocess
import sys

from tests.helpers.paths import REPO

PACKAGE = REPO / "ivslam_cli"
MAX_LINES = 700


def _module_name(path) -> str:
    rel = path.relative_to(REPO).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, ast.Module]:
    return {_module_name(p): ast.parse(p.read_text(), str(p)) for p in sorted(PACKAGE.rglob("*.py"))}


def _top_level_imports(name: str, tree: ast.Module, known: set[str]) -> set[str]:
    """Modules of the package imported at module level (not inside functions: lazy imports)."""
    is_pkg = name in known and any(k.startswith(name + ".") for k in known)
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    out = set()
    for node in tree.body:
        stmts = [node]
        if isinstance(node, ast.If):  # `if TYPE_CHECKING:` blocks are not imports at run time
            continue
        for st in stmts:
            if isinstance(st, ast.Import):
                out |= {a.name for a in st.names if a.name in known}
            elif isinstance(st, ast.ImportFrom):
                mod = st.module or ""
                if st.level:
                    mod = ".".join(base[: len(base) - st.level + 1] + ([mod] if mod else []))
                for a in st.names:
                    sub = f"{mod}.{a.name}"
                    if sub in known:
                        out.add(sub)
                    elif mod in known:
                        out.add(mod)
    out.discard(name)
    return out


def test_no_import_cycle():
    mods = _modules()
    known = set(mods)
    graph = {m: _top_level_imports(m, t, known) for m, t in mods.items()}
    # a package importing its own submodules (its API) is not a cycle of the data flow
    graph = {m: {d for d in deps if not d.startswith(m + ".")} for m, deps in graph.items()}
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                cycles.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_cycle_detection_can_fail():
    tree_a = ast.parse("from ivslam_cli.b import f\n")
    tree_b = ast.parse("import ivslam_cli.a\n")
    known = {"ivslam_cli.a", "ivslam_cli.b"}
    assert _top_level_imports("ivslam_cli.a", tree_a, known) == {"ivslam_cli.b"}
    assert _top_level_imports("ivslam_cli.b", tree_b, known) == {"ivslam_cli.a"}


def test_no_module_over_the_line_limit():
    long = {str(p.relative_to(REPO)): n for p in PACKAGE.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"


_IMPORT_EVERY_MODULE = """
import importlib, pkgutil, sys
import ivslam_cli
from numba.core.dispatcher import Dispatcher
for m in pkgutil.walk_packages(ivslam_cli.__path__, "ivslam_cli."):
    if m.name != "ivslam_cli.__main__":
        importlib.import_module(m.name)
ours = [m for n, m in list(sys.modules.items()) if n.startswith("ivslam_cli")]
loaded = {f"{d.py_func.__module__}.{d.py_func.__name__}" for m in ours for d in vars(m).values()
          if isinstance(d, Dispatcher) and d.overloads}
print(len(ours), *sorted(loaded))
"""


def test_importing_a_module_loads_no_kernel():
    """No module compiles or loads a numba kernel when imported: a command loads the kernels it
    calls, when it calls them, and no others."""
    out = subprocess.run([sys.executable, "-c", _IMPORT_EVERY_MODULE], capture_output=True, text=True,
                         check=True, cwd=REPO)
    count, *loaded = out.stdout.split()
    assert int(count) == len([p for p in PACKAGE.rglob("*.py") if p.name != "__main__.py"]), "a module not imported"
    assert not loaded, f"kernels loaded by importing their modules: {loaded}"


def test_config_read_only_by_the_builders():
    """``cfg["..."]`` inside ``slam/`` only in ``from_config`` classmethods."""
    offenders = []
    for p in (PACKAGE / "slam").rglob("*.py"):
        tree = ast.parse(p.read_text())
        allowed = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and node.name == "from_config":
                allowed |= {id(n) for n in ast.walk(node)}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) and node.value.id == "cfg"
                    and id(node) not in allowed):
                offenders.append(f"{p.relative_to(REPO)}:{node.lineno}")
    assert not offenders, offenders


def test_tests_mirror_the_package():
    """A test module sits in the folder of what it tests: ``tests/<subpackage>/...`` for every
    folder under tests/ (apart from helpers and the cross-cutting hostile-input corpus)."""
    extra = {"helpers", "hostile", "bench"}
    for d in (REPO / "tests").rglob("*"):
        if not d.is_dir() or d.name == "__pycache__" or d.name in extra or d.parent.name in extra:
            continue
        rel = d.relative_to(REPO / "tests")
        assert (PACKAGE / rel).is_dir(), f"tests/{rel} mirrors no package folder ivslam_cli/{rel}"
    flat = [p.name for p in (REPO / "tests").glob("test_*.py")]
    top = {p.stem for p in PACKAGE.glob("*.py")} | {"layout"}
    stray = [n for n in flat if re.sub(r"^test_|\.py$", "", n) not in top]
    assert not stray, f"test modules at the top of tests/ that test a subpackage: {stray}"
