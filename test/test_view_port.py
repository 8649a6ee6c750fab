"""The view's server cannot listen (its port is taken): one clear error, and a clean teardown."""

from __future__ import annotations

import socket

import pytest

pytestmark = pytest.mark.ros


def test_a_taken_port_is_refused_with_what_to_do() -> None:
    import rclpy
    from rclpy.context import Context
    from rclpy.parameter import Parameter

    from ext_sense.view.node import FoxgloveViewNode

    context = Context()
    rclpy.init(context=context, args=[])
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        try:
            with pytest.raises(ValueError, match=rf"cannot listen on ws://127\.0\.0\.1:{port}.*"):
                FoxgloveViewNode(
                    context=context,
                    parameter_overrides=[Parameter("port", value=port), Parameter("nice", value=0)],
                )
        finally:
            # the context destroys the half-built node: its teardown must not fail in turn
            context.try_shutdown()
