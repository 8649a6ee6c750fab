"""The node-graph description both front ends (launch files, ``ext-sense run``) build from."""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

ParameterValue = bool | int | float | str | list[int] | list[float] | list[str]


class GraphError(ValueError):
    """A graph, its arguments or a node spec is malformed."""


@dataclass(frozen=True)
class ArgumentSpec:
    """One launch argument ``name:=value``: a string parsed as ``kind`` in ``[low, high]``."""

    name: str
    default: str
    description: str
    choices: tuple[str, ...] = ()
    kind: type = str
    low: float | None = None
    high: float | None = None

    def expected(self) -> str:
        """What a value must be, in words (``"an integer in [0, 1000000]"``)."""
        if self.choices:
            return f"one of {list(self.choices)}"
        what = {int: "an integer", float: "a number"}.get(self.kind, "a string")
        low, high = _number(self.low), _number(self.high)
        if self.low is not None and self.high is not None:
            return f"{what} in [{low}, {high}]"
        if self.low is not None:
            return f"{what} >= {low}"
        if self.high is not None:
            return f"{what} <= {high}"
        return what

    def check(self, value: str) -> None:
        """Refuse (GraphError) a value not of the argument's kind, range or choices."""
        wrong = GraphError(
            f"The '{self.name}' argument must be {self.expected()}. Got '{value}' instead."
        )
        if self.choices:
            if value not in self.choices:
                raise wrong
            return
        if self.kind is str:
            return
        try:
            number = self.kind(value.strip())
        except ValueError:
            raise wrong from None
        if not math.isfinite(number):
            raise wrong
        if (self.low is not None and number < self.low) or (
            self.high is not None and number > self.high
        ):
            raise wrong


@dataclass(frozen=True)
class NodeSpec:
    """One node to start: ``ros2 run package executable``, or ``plugin`` (``"module:Class"``).

    ``parameters`` are typed overrides; when a ``required`` node exits the graph stops; a
    ``lifecycle`` node starts unconfigured and is configured and activated by the front end if
    it ``manage``s it; nodes of one ``process`` name share a process (empty: their own).
    """

    package: str
    executable: str
    name: str
    plugin: str
    parameters: Mapping[str, ParameterValue] = field(default_factory=dict)
    remappings: tuple[tuple[str, str], ...] = ()
    required: bool = False
    lifecycle: bool = False
    manage: bool = True
    process: str = ""

    def node_class(self) -> type:
        """Import and return the Node subclass named by :attr:`plugin`."""
        module_name, _, class_name = self.plugin.partition(":")
        try:
            return getattr(importlib.import_module(module_name), class_name)
        except (ImportError, AttributeError) as err:
            raise GraphError(f"Node '{self.name}': cannot import plugin '{self.plugin}'") from err

    def ros_args(self) -> list[str]:
        """Node name and remappings as ``--ros-args -r __node:=NAME -r from:=to ...``."""
        args = ["-r", f"__node:={self.name}"]
        for src, dst in self.remappings:
            args += ["-r", f"{src}:={dst}"]
        return ["--ros-args", *args]


@dataclass(frozen=True)
class GraphSpec:
    """A named node graph: its arguments and the function that builds its nodes."""

    name: str
    description: str
    arguments: tuple[ArgumentSpec, ...]
    build: Callable[[Mapping[str, str]], tuple[NodeSpec, ...]]
    files: Callable[[Mapping[str, str]], None] | None = None
    """Checks that the files the arguments name exist (bag, pty directory, scene file)."""

    def resolve(self, overrides: Mapping[str, str] | None = None) -> dict[str, str]:
        """Defaults updated with ``overrides``, each checked (GraphError: unknown or refused)."""
        values = {a.name: a.default for a in self.arguments}
        known = {a.name: a for a in self.arguments}
        for key, value in (overrides or {}).items():
            if key not in known:
                raise GraphError(
                    f"Graph '{self.name}' has no argument '{key}'. "
                    f"Expected one of: {', '.join(sorted(known))}."
                )
            values[key] = value
        for argument in self.arguments:
            argument.check(values[argument.name])
        return values

    def check_files(self, values: Mapping[str, str]) -> None:
        """Refuse (GraphError) resolved values naming files the graph cannot use."""
        if self.files is not None:
            self.files(values)

    def nodes(self, overrides: Mapping[str, str] | None = None) -> tuple[NodeSpec, ...]:
        """The nodes to start for these argument values."""
        return self.build(self.resolve(overrides))


def _number(x: float | None) -> str:
    return str(int(x)) if x is not None and float(x).is_integer() else f"{x}"


def parse_assignments(items: list[str]) -> dict[str, str]:
    """Parse ``name:=value`` items as ``ros2 launch`` does (GraphError: no ``:=``)."""
    out = {}
    for item in items:
        key, sep, value = item.partition(":=")
        if not sep or not key:
            raise GraphError(f"Launch arguments are written name:=value. Got '{item}' instead.")
        out[key] = value
    return out


def launch_node_kwargs(spec: NodeSpec, use_sim_time: bool) -> dict[str, Any]:
    """Keyword arguments of ``launch_ros.actions.Node`` for one node spec."""
    return {
        "package": spec.package,
        "executable": spec.executable,
        "name": spec.name,
        "parameters": [{**dict(spec.parameters), "use_sim_time": use_sim_time}],
        "remappings": list(spec.remappings),
        "output": "screen",
        "emulate_tty": True,
    }


def as_bool(value: str) -> bool:
    """A launch-argument string as a bool (``true``/``false``, ``1``/``0``; else GraphError)."""
    lowered = value.strip().lower()
    if lowered in ("true", "1", "yes", "on"):
        return True
    if lowered in ("false", "0", "no", "off"):
        return False
    raise GraphError(f"Expected a boolean (true/false). Got '{value}' instead.")
