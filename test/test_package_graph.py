"""The ROS package graph: acyclic through every kind of depend, and true to what the code imports.

colcon orders a workspace by every kind of dependency a ``package.xml`` declares (build,
buildtool, exec, test, ...): one circle anywhere and ``colcon build`` stops before building
anything ("Unable to order packages topologically"). Static checks over ``src/*/package.xml``
and ``interfaces/**/package.xml`` (parsed with catkin_pkg, as colcon-ros does) and over the
imports of each package's code and tests (AST only, nothing imported):

- no circle through any kind of depend, naming the circle and the kind of each edge;
- every ROS package a package's code imports is a build or exec depend of it, and every one
  its tests import is a test, build or exec depend (a ROS package: one of this repository's or
  one in the venv's ament index).
"""

from __future__ import annotations

import ast
import os
import sys
from collections import deque
from itertools import pairwise
from pathlib import Path

from catkin_pkg.package import Package, parse_package

ROOT = Path(__file__).resolve().parent.parent
KINDS = (
    "build",
    "buildtool",
    "build_export",
    "buildtool_export",
    "exec",
    "test",
    "doc",
)
"""The depend kinds of package format 3 (``<depend>`` is build, build_export and exec)."""

RUN_KINDS = ("build", "build_export", "exec")

KNOWN_UPWARD_TEST_IMPORTS = {
    ("ext_sense_bags", "ext_sense_perception"): "test_recorded.py windows a simulator bag",
    ("ext_sense_bags", "ext_sense_sim"): "test_recorded.py windows a simulator bag",
    ("ext_sense_perception", "ext_sense"): "its command tests drive the ext-sense CLI",
    ("ext_sense_sim", "ext_sense"): "its command tests drive the ext-sense CLI (ext-sense sim)",
}
"""Tests that import a package above their own: declaring it would close a circle, so they
are known and listed here until they move to the top-level ``test/`` (as the behaviours tests
against the simulator did, ``test/behaviours/``). A pair that no longer occurs fails the test,
so the list only shrinks."""


def package_xmls(root: Path = ROOT) -> list[Path]:
    """Every ``package.xml`` of the repository's ROS packages: ``src/*`` and ``interfaces/**``."""
    return sorted(root.glob("src/*/package.xml")) + sorted(root.glob("interfaces/**/package.xml"))


def load_packages(paths: list[Path]) -> dict[str, Package]:
    """Parse each ``package.xml``, keyed by package name."""
    return {p.name: p for p in (parse_package(str(path.parent)) for path in paths)}


def dependency_edges(packages: dict[str, Package]) -> dict[str, dict[str, list[str]]]:
    """``{package: {dependency: [kinds]}}`` between the given packages only.

    A dependency outside the set (``rclpy``, ``python3-numpy``) is not an edge: colcon orders
    the workspace alone.
    """
    edges: dict[str, dict[str, list[str]]] = {name: {} for name in packages}
    for name, pkg in packages.items():
        for kind in KINDS:
            for dep in getattr(pkg, f"{kind}_depends"):
                if dep.name in packages and dep.name != name:
                    edges[name].setdefault(dep.name, []).append(kind)
    return edges


def find_cycles(edges: dict[str, dict[str, list[str]]]) -> list[str]:
    """One circle per strongly connected group of packages, as ``a -[test]-> b -[exec]-> a``."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[set[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.add(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(group)

    for v in sorted(edges):
        if v not in index:
            strong(v)
    return sorted(_circle_in(group, edges) for group in groups)


def _circle_in(group: set[str], edges: dict[str, dict[str, list[str]]]) -> str:
    """A shortest circle from the group's first package back to itself (breadth first)."""
    start = min(group)
    came_from: dict[str, str] = {}
    queue = deque([start])
    while start not in came_from:
        v = queue.popleft()
        for w in sorted(edges[v]):
            if w in group and w not in came_from:
                came_from[w] = v
                queue.append(w)
    path = [start]
    while (prev := came_from[path[-1]]) != start:
        path.append(prev)
    path.append(start)
    path.reverse()
    return "".join(f"{a} -[{','.join(edges[a][b])}]-> " for a, b in pairwise(path)) + start


def ros_package_names(packages: dict[str, Package]) -> set[str]:
    """This repository's packages and every package in the ament indexes of this environment."""
    prefixes = [sys.prefix, *filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(":"))]
    names = set(packages)
    for prefix in prefixes:
        index = Path(prefix) / "share" / "ament_index" / "resource_index" / "packages"
        if index.is_dir():
            names.update(p.name for p in index.iterdir())
    return names


def imported_tops(root: Path) -> dict[str, set[str]]:
    """``{top-level module: {files}}`` for every absolute import under ``root``, nested too."""
    found: dict[str, set[str]] = {}
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                modules = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules = [node.module]
            else:
                continue
            for module in modules:
                found.setdefault(module.split(".")[0], set()).add(path.name)
    return found


def undeclared_imports(
    packages: dict[str, Package], ros_names: set[str], src: Path = ROOT / "src"
) -> dict[tuple[str, str, str], list[str]]:
    """``{(package, 'code' or 'test', imported package): [files]}`` not declared in package.xml."""
    out: dict[tuple[str, str, str], list[str]] = {}
    for name, pkg in packages.items():
        run = {d.name for kind in RUN_KINDS for d in getattr(pkg, f"{kind}_depends")}
        test = run | {d.name for d in pkg.test_depends}
        for part, root, declared in (
            ("code", src / name / name, run),
            ("test", src / name / "test", test),
        ):
            if not root.is_dir():
                continue
            for top, files in imported_tops(root).items():
                if top in ros_names and top != name and top not in declared:
                    out[(name, part, top)] = sorted(files)
    return out


def test_the_package_graph_has_no_cycle_through_any_kind_of_depend() -> None:
    edges = dependency_edges(load_packages(package_xmls()))
    assert {"ext_sense", "ext_sense_msgs", "control_msgs", "franka_msgs"} <= set(edges)
    assert find_cycles(edges) == []


def _write_package(root: Path, name: str, depends: str) -> None:
    (root / name).mkdir(parents=True)
    (root / name / "package.xml").write_text(
        f'<?xml version="1.0"?>\n<package format="3"><name>{name}</name><version>0.1.0</version>'
        f"<description>d</description><maintainer email='a@b.invalid'>m</maintainer>"
        f"<license>Apache-2.0</license>{depends}</package>\n"
    )


def test_a_cycle_through_a_test_depend_is_found_and_named(tmp_path: Path) -> None:
    """The circle colcon refused in issue 32, and a longer one through a build depend."""
    _write_package(tmp_path / "src", "sim", "<exec_depend>behaviours</exec_depend>")
    _write_package(
        tmp_path / "src",
        "behaviours",
        "<exec_depend>rclpy</exec_depend><test_depend>sim</test_depend>",
    )
    _write_package(tmp_path / "src", "a", "<depend>b</depend>")
    _write_package(tmp_path / "src", "b", "<build_depend>c</build_depend>")
    _write_package(tmp_path / "interfaces" / "x", "c", "<buildtool_depend>a</buildtool_depend>")
    _write_package(tmp_path / "src", "d", "<exec_depend>a</exec_depend>")
    edges = dependency_edges(load_packages(package_xmls(tmp_path)))
    assert find_cycles(edges) == [
        "a -[build,build_export,exec]-> b -[build]-> c -[buildtool]-> a",
        "behaviours -[test]-> sim -[exec]-> behaviours",
    ]


def test_every_imported_ros_package_is_declared() -> None:
    packages = load_packages(package_xmls())
    found = undeclared_imports(packages, ros_package_names(packages))
    known = {(pkg, "test", dep) for pkg, dep in KNOWN_UPWARD_TEST_IMPORTS}
    missing = {key: files for key, files in found.items() if key not in known}
    assert missing == {}
    assert known <= set(found), f"no longer imported, drop from the list: {known - set(found)}"


def test_an_undeclared_import_inside_a_function_is_found(tmp_path: Path) -> None:
    _write_package(tmp_path, "lower", "<exec_depend>rclpy</exec_depend>")
    (tmp_path / "lower" / "lower").mkdir()
    (tmp_path / "lower" / "lower" / "node.py").write_text("import rclpy.node\n")
    (tmp_path / "lower" / "test").mkdir()
    (tmp_path / "lower" / "test" / "test_up.py").write_text(
        "def test_x():\n    from upper.cli import main\n    import numpy\n"
    )
    _write_package(tmp_path, "upper", "<exec_depend>lower</exec_depend>")
    packages = load_packages(sorted(tmp_path.glob("*/package.xml")))
    found = undeclared_imports(packages, {"lower", "upper", "rclpy"}, src=tmp_path)
    assert found == {("lower", "test", "upper"): ["test_up.py"]}
