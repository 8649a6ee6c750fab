"""``ext-sense collect``: labelled sessions recorded from a running task graph.

- :mod:`.session`: the functional core (prompts, trial sequences, session state; no ROS).
- :mod:`.loop`: one trial at a time between the operator, the node and the core.
- :mod:`.graph`: the task graph as collect runs it (a few wires changed; plain data).
- :mod:`.node`: the ``collector`` node, which records the session and hands events on.

The command (:mod:`ext_sense.commands.collect`) parses and starts them.
"""
