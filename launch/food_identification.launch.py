"""Launch the food_identification graph.

`ros2 launch ext_sense food_identification.launch.py [name:=value ...]`.

The nodes, parameters and remappings come from `ext_sense.graphs`, the description that
`ext-sense run food_identification` also starts, so both front ends always run the same graph.
"""

from ext_sense.launch_support import generate_launch_description_for


def generate_launch_description():
    """Build the launch description from the shared graph description."""
    return generate_launch_description_for("food_identification")
