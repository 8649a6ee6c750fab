"""Node parameters from one schema: a frozen dataclass per node, declared with descriptors.

Each field is one parameter made with :func:`param`; checks across fields go in the schema's
``__post_init__`` (raise ``ValueError``). :func:`declare_all` declares them on a node,
validates start-up values and runtime changes, and returns the typed config for the pure core;
:func:`specs` lists them without a node (``docs/parameters.md``). No rclpy at module level.
"""

from __future__ import annotations

import dataclasses
import functools
import typing
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.node import Node

    from ext_sense_runtime.callback_guard import CallbackGuard

T = TypeVar("T")
_KEY = "ext_sense_parameter"
_ARRAY_TYPES = {"bool": "bool[]", "int": "int[]", "float": "double[]", "str": "string[]"}
_EMPTY_ARRAY_TYPES = {
    "bool[]": "BOOL_ARRAY",
    "int[]": "INTEGER_ARRAY",
    "double[]": "DOUBLE_ARRAY",
    "string[]": "STRING_ARRAY",
}


@dataclasses.dataclass(frozen=True)
class ParamSpec:
    """One declared parameter: what the descriptor and ``docs/parameters.md`` show.

    ``name`` is the parameter's, ``field`` the schema's attribute holding it.
    """

    name: str
    field: str
    type_name: str
    default: Any
    description: str
    low: float | int | None
    high: float | int | None
    read_only: bool
    choices: tuple[Any, ...]
    check: Callable[[Any], str | None] | None

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is refused (choices, range, the field's check), or ``None``."""
        if self.choices and value not in self.choices:
            return (
                f"The '{self.name}' parameter must be one of {list(self.choices)}. "
                f"Got {value!r} instead."
            )
        if self.low is not None and not self.low <= value <= self.high:
            return (
                f"The '{self.name}' parameter must be in [{self.low}, {self.high}]. "
                f"Got {value!r} instead."
            )
        reason = self.check(value) if self.check is not None else None
        if reason:
            return f"The '{self.name}' parameter {reason}. Got {value!r} instead."
        return None


def param(
    default: Any,
    description: str,
    *,
    low: float | int | None = None,
    high: float | int | None = None,
    read_only: bool = False,
    choices: Sequence[Any] = (),
    check: Callable[[Any], str | None] | None = None,
    name: str = "",
) -> Any:
    """A schema field that is a node parameter.

    ``default`` has the parameter's type (``1.0`` for a double; lists are tuples);
    ``description`` says its unit; ``low`` and ``high`` are inclusive, given together;
    ``check`` returns why a value is refused (completing "The 'x' parameter ...") or a falsy
    value; ``name`` is the parameter's when not the field's (``franka.state_topic``).
    """
    if (low is None) != (high is None):
        raise ValueError(f"parameter {name or description!r}: give both low and high, or neither")
    meta = ParamSpec(
        name, "", "", default, description, low, high, read_only, tuple(choices), check
    )
    return dataclasses.field(default=default, metadata={_KEY: meta})


def _type_name(annotation: Any, default: Any, where: str) -> str:
    origin = typing.get_origin(annotation)
    if origin is tuple:
        item = typing.get_args(annotation)[0]
        return _ARRAY_TYPES[item.__name__]
    names = {bool: "bool", int: "int", float: "double", str: "string"}
    if annotation not in names:
        raise TypeError(f"{where}: a parameter is bool, int, float, str or tuple[...]")
    if type(default) is not annotation:
        raise TypeError(f"{where}: default {default!r} is not a {annotation.__name__}")
    return names[annotation]


@functools.cache
def specs(schema: type) -> tuple[ParamSpec, ...]:
    """The parameters of a schema dataclass, in field order.

    Raises:
        TypeError: A field is not a parameter, or its default does not have its type (an int
            default for a double would escape a float range).
    """
    hints = typing.get_type_hints(schema)
    out = []
    for f in dataclasses.fields(schema):
        meta = f.metadata.get(_KEY)
        where = f"{schema.__name__}.{f.name}"
        if meta is None:
            raise TypeError(f"{where} is not a parameter (make it with param())")
        type_name = _type_name(hints[f.name], f.default, where)
        if meta.low is not None and type_name not in ("int", "double"):
            raise TypeError(f"{where}: a range needs an int or float parameter")
        name = meta.name or f.name
        out.append(dataclasses.replace(meta, name=name, field=f.name, type_name=type_name))
    return tuple(out)


def build(schema: type[T], values: dict[str, Any]) -> T:
    """The config of ``values`` (by parameter name; missing ones take their defaults).

    Raises:
        ValueError: A value is refused (range, choices, check) or the schema's
            ``__post_init__`` refused the combination; the message names the parameter.
    """
    fields = {}
    for spec in specs(schema):
        if spec.name not in values:
            continue
        value = values[spec.name]
        if isinstance(value, list | tuple):
            value = tuple(value)
        reason = spec.problem(value)
        if reason:
            raise ValueError(reason)
        fields[spec.field] = value
    return schema(**fields)


def _descriptor(spec: ParamSpec) -> Any:
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

    descriptor = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
    if spec.type_name == "double" and spec.low is not None:
        descriptor.floating_point_range = [
            FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high))
        ]
    elif spec.type_name == "int" and spec.low is not None:
        descriptor.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high))]
    return descriptor


def declare_all(
    node: Node,
    schema: type[T],
    on_change: Callable[[T], str | None] | None = None,
    guard: CallbackGuard | None = None,
) -> T:
    """Declare every parameter of ``schema`` on ``node`` and return the typed config.

    Runtime changes are validated by an on-set callback (rclpy enforces type, range and
    ``read_only``), then handed to ``on_change``, which may refuse by returning a reason;
    ``guard`` wraps the callback (an exception refuses the change).

    Raises:
        ValueError: A value given at start-up is refused, with the parameter's name.
    """
    from rclpy.parameter import Parameter

    all_specs = specs(schema)
    values = {}
    for spec in all_specs:
        default = spec.default
        if isinstance(default, tuple) and not default:  # an empty list has no type of its own
            default = getattr(Parameter.Type, _EMPTY_ARRAY_TYPES[spec.type_name])
        value = node.declare_parameter(spec.name, default, _descriptor(spec)).value
        values[spec.name] = spec.default if value is None else value
    config = [build(schema, values)]
    by_name = {spec.name: spec for spec in all_specs}

    def on_set(params: list) -> SetParametersResult:
        changes = {p.name: p.value for p in params if p.name in by_name}
        if changes:
            current = {s.name: getattr(config[0], s.field) for s in all_specs}
            try:
                new = build(schema, {**current, **changes})
            except ValueError as err:
                return _result(str(err))
            reason = on_change(new) if on_change is not None else None
            if reason:
                return _result(reason)
            config[0] = new
        return _result(None)

    callback = guard.wrap(on_set, fallback=refused) if guard is not None else on_set
    node.add_on_set_parameters_callback(callback)
    return config[0]


def _result(reason: str | None) -> SetParametersResult:
    from rcl_interfaces.msg import SetParametersResult

    return SetParametersResult(successful=reason is None, reason=reason or "")


def refused(err: Exception) -> SetParametersResult:
    """The ``fallback`` of a guarded on-set callback that raised: refused, with the cause."""
    return _result(f"{type(err).__name__}: {err}")
