"""``ext-sense collect``: labelled sessions recorded from a running task graph.

:mod:`.session` (the core, no ROS), :mod:`.loop` (the operator's loop), :mod:`.graph` (the
rewired task graph) and :mod:`.node` (the ``collector`` node that records).
"""
