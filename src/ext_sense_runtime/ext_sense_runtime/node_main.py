"""The ``main`` shared by every node executable: init, spin, clean shutdown.

Ends cleanly on Ctrl-C and on external shutdown (``try/finally`` with ``destroy_node`` and
``rclpy.try_shutdown``, which works on Jazzy and Kilted alike).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from ext_sense_runtime.executor import make_executor, spin_until_shutdown


def run_node(factory: Callable[[], Node], args: Sequence[str] | None = None) -> int:
    """Create the node after ``rclpy.init`` and spin it until shutdown.

    Args:
        factory: Builds the node (usually the Node subclass itself).
        args: Command-line arguments (``--ros-args ...``); ``None`` reads ``sys.argv``.

    Returns:
        Process exit code: 0 on a clean stop.
    """
    rclpy.init(args=args)
    node = None
    try:
        node = factory()
        executor = make_executor()
        executor.add_node(node)
        spin_until_shutdown(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
