"""Launch the handover graph.

`ros2 launch ext_sense handover.launch.py [name:=value ...]`.

The nodes, parameters and remappings come from `ext_sense.graphs`, the description that
`ext-sense run handover` also starts, so both front ends always run the same graph.
"""

from ext_sense.launch_support import generate_launch_description_for


def generate_launch_description():
    """Build the launch description from the shared graph description."""
    return generate_launch_description_for("handover")
