"""Declaring parameters with descriptors, the way the rclpy node API enforces them.

Every parameter gets a description with its unit, a range where one makes sense, and
``read_only`` for things that cannot change while running (port, baud, window sizes).
Doubles must get float defaults: an int default would escape a ``FloatingPointRange``.
"""

from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.node import Node


def declare(
    node: Node,
    name: str,
    default: Any,
    description: str,
    *,
    low: float | int | None = None,
    high: float | int | None = None,
    step: float | int = 0,
    read_only: bool = False,
    dynamic_typing: bool = False,
) -> Any:
    """Declare one parameter with a descriptor and return its current value.

    Args:
        node: The node that owns the parameter.
        name: Parameter name.
        default: Default value; its Python type fixes the parameter type (use ``1.0``, not
            ``1``, for doubles).
        description: What it does, with its unit (REP-103: metres, seconds).
        low: Inclusive lower bound, given together with ``high``.
        high: Inclusive upper bound; given together. Float range for float defaults, integer
            range for int defaults.
        step: Range step (0 = continuous).
        read_only: Refuse changes after start-up.
        dynamic_typing: Allow the type to change (e.g. a value that may be empty).

    Returns:
        The parameter's value after overrides (launch file, YAML, command line).
    """
    descriptor = ParameterDescriptor(
        description=description, read_only=read_only, dynamic_typing=dynamic_typing
    )
    if (low is None) != (high is None):
        raise ValueError(f"Parameter '{name}': give both low and high, or neither.")
    if low is not None:
        if isinstance(default, bool):
            raise ValueError(f"Parameter '{name}': a bool parameter cannot have a range.")
        if isinstance(default, float):
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(low), to_value=float(high), step=float(step))
            ]
        elif isinstance(default, int):
            descriptor.integer_range = [
                IntegerRange(from_value=int(low), to_value=int(high), step=int(step))
            ]
        else:
            raise ValueError(f"Parameter '{name}': a range needs a numeric default.")
    return node.declare_parameter(name, default, descriptor).value


def refused(err: Exception) -> SetParametersResult:
    """The answer of an on-set callback that raised: the change is refused, with the cause.

    The ``fallback`` of a guarded on-set callback
    (``guard.wrap(self._on_set, fallback=refused)``): rclpy needs a result, not ``None``.
    """
    return SetParametersResult(successful=False, reason=f"{type(err).__name__}: {err}")
