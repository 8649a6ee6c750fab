"""The shape of the source tree: imports run one way, modules stay small, rooms stay apart.

Static checks over ``src/*/<package>/**.py`` (AST only, nothing imported):

- no import circle between the modules of any package, counting imports inside functions too
  (a circle dodged by a function-level import is still a circle);
- perception imports none of its own modules inside a function: its dependency graph is
  visible at the top of each module (command handlers may import lazily for ``--help`` speed;
  optional heavy third-party dependencies such as torch stay lazy);
- the perception rooms import one way: nodes -> online; cli -> reporting -> training ->
  features / data -> online -> profiles / errors;
- the inference node's import closure holds neither scikit-learn's training stack nor torch;
- nothing but the command line (``ext_sense/cli.py`` and ``ext_sense/commands/``) imports
  ``ext_sense.commands``: library code lives in the packages, and bench and tests use it there;
- no module over 500 lines unless its docstring says why it must be one piece.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
MAX_LINES = 500
ONE_PIECE = "must be one piece"
LAZY_OK = ("cli.py", "cli_", "cli/", "commands/")
"""Module paths whose functions may import own-package modules (command handlers)."""


def _packages() -> dict[str, Path]:
    out = {}
    for pkg_root in sorted(SRC.iterdir()):
        inner = pkg_root / pkg_root.name
        if (inner / "__init__.py").is_file():
            out[pkg_root.name] = inner
    return out


def _module_name(pkg: str, root: Path, path: Path) -> str:
    rel = path.relative_to(root).with_suffix("")
    parts = [pkg, *rel.parts]
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(
    tree: ast.Module, module: str, is_pkg: bool, modules: set[str]
) -> list[tuple[str, bool, int]]:
    """``(imported module, inside a function, line)`` for every import in a module.

    ``from pkg import name`` depends on ``pkg.name`` when that is a module, else on ``pkg``.
    """
    found: list[tuple[str, bool, int]] = []

    def visit(node: ast.AST, in_func: bool) -> None:
        for child in ast.iter_child_nodes(node):
            nested = in_func or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
            if isinstance(child, ast.Import):
                found.extend((a.name, in_func, child.lineno) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    anchor = module.split(".")
                    anchor = anchor if is_pkg else anchor[:-1]
                    anchor = anchor[: len(anchor) - child.level + 1]
                    base = ".".join([*anchor, base] if base else anchor)
                for a in child.names:
                    sub = f"{base}.{a.name}"
                    found.append((sub if sub in modules else base, in_func, child.lineno))
            elif isinstance(child, ast.If) and _is_type_checking(child.test):
                continue  # annotations only: not a runtime dependency
            visit(child, nested)

    visit(tree, False)
    return found


def _is_type_checking(test: ast.expr) -> bool:
    return isinstance(test, ast.Name) and test.id == "TYPE_CHECKING"


def _graph(pkg: str, root: Path) -> tuple[dict[str, set[str]], list[str]]:
    """Module import graph of one package, and own-package imports made inside functions.

    The function-level imports count in the graph (a circle they dodge is still a circle).
    """
    paths = {_module_name(pkg, root, p): p for p in sorted(root.rglob("*.py"))}
    graph: dict[str, set[str]] = {m: set() for m in paths}
    lazy: list[str] = []
    for module, path in paths.items():
        tree = ast.parse(path.read_text(), str(path))
        is_pkg = path.name == "__init__.py"
        for name, in_func, line in _imports(tree, module, is_pkg, set(paths)):
            target = name if name in paths else None
            if target is None or target == module:
                continue
            graph[module].add(target)
            rel = str(path.relative_to(root))
            if in_func and not any(k in rel for k in LAZY_OK):
                lazy.append(f"{rel}:{line} imports {target} inside a function")
    return graph, lazy


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]
    sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))

    def strong(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            strong(v)
    return out


@pytest.mark.parametrize("package", sorted(_packages()))
def test_no_import_circles(package: str) -> None:
    graph, _ = _graph(package, _packages()[package])
    assert _cycles(graph) == []


def test_perception_imports_its_own_modules_at_the_top() -> None:
    """Only command handlers import lazily (``ext-sense --help`` speed); the rest at the top.

    Other packages import a few own modules lazily where those pull optional device libraries
    (python-can, pyserial, rosbags writers); the circle test above still counts those imports.
    """
    _, lazy = _graph("ext_sense_perception", _packages()["ext_sense_perception"])
    assert lazy == []


def test_import_graph_finds_a_circle_hidden_in_a_function(tmp_path: Path) -> None:
    pkg = tmp_path / "demo_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from demo_pkg import b\n")
    (pkg / "b.py").write_text("def f():\n    from demo_pkg.a import x\n    return x\n")
    graph, lazy = _graph("demo_pkg", pkg)
    assert _cycles(graph) == [["demo_pkg.a", "demo_pkg.b"]]
    assert lazy == ["b.py:2 imports demo_pkg.a inside a function"]


ROOMS = (
    "errors",
    "profiles",
    "online",
    "features",
    "data",
    "training",
    "reporting",
    "cli",
    "nodes",
)
ALLOWED = {
    "errors": set(),
    "profiles": {"errors"},
    "online": {"errors", "profiles"},
    "features": {"errors", "profiles", "online"},
    "data": {"errors", "profiles", "online"},
    "training": {"errors", "profiles", "online", "features", "data"},
    "reporting": {"errors", "profiles", "online", "features", "data", "training"},
    "cli": {"errors", "profiles", "online", "features", "data", "training", "reporting"},
    "nodes": {"errors", "profiles", "online"},
}


def _room(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_perception_rooms_import_one_way() -> None:
    graph, _ = _graph("ext_sense_perception", _packages()["ext_sense_perception"])
    wrong = sorted(
        f"{a} -> {b}"
        for a, targets in graph.items()
        for b in targets
        if _room(a) in ALLOWED and _room(b) != _room(a) and _room(b) not in ALLOWED[_room(a)]
    )
    assert {_room(m) for m in graph} - {""} <= set(ROOMS)
    assert wrong == []


def test_inference_node_imports_no_training_stack() -> None:
    code = (
        "import sys\n"
        "import ext_sense_perception.nodes.contact_inference\n"
        "import ext_sense_perception.nodes.contact_window\n"
        "heavy = sorted(m for m in sys.modules if m.split('.')[0] in "
        "('sklearn', 'torch', 'skl2onnx') or m.startswith('ext_sense_perception.training'))\n"
        "print(heavy)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_modules_stay_under_500_lines_unless_they_say_why() -> None:
    long = []
    for root in _packages().values():
        for path in sorted(root.rglob("*.py")):
            text = path.read_text()
            n = text.count("\n")
            if n > MAX_LINES and ONE_PIECE not in (ast.get_docstring(ast.parse(text)) or ""):
                long.append(f"{path.relative_to(SRC)}: {n} lines")
    assert long == []


CLI = (SRC / "ext_sense" / "ext_sense" / "cli.py", SRC / "ext_sense" / "ext_sense" / "commands")


def _imports_commands(tree: ast.Module) -> list[int]:
    """Lines of a module that import ``ext_sense.commands`` or a module of it."""
    lines = []
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        if any(n == "ext_sense.commands" or n.startswith("ext_sense.commands.") for n in names):
            lines.append(node.lineno)
    return lines


def _python_files() -> list[Path]:
    files = [*SRC.rglob("*.py"), *(ROOT / "test").rglob("*.py"), *(ROOT / "bench").rglob("*.py")]
    files += [*(ROOT / "launch").glob("*.py"), *ROOT.glob("*.py")]
    return sorted(p for p in files if not any(p == c or c in p.parents for c in CLI))


def test_only_the_command_line_imports_the_commands() -> None:
    wrong = [
        f"{path.relative_to(ROOT)}:{line}"
        for path in _python_files()
        for line in _imports_commands(ast.parse(path.read_text(), str(path)))
    ]
    assert wrong == []


def test_a_commands_import_is_found(tmp_path: Path) -> None:
    code = "import ext_sense.commands.demo\nfrom ext_sense import commands\nimport ext_sense.cli\n"
    assert _imports_commands(ast.parse(code)) == [1, 2]
