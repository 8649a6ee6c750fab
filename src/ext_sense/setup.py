import glob
import os

from setuptools import find_packages, setup

package_name = "ext_sense"

# The launch files live at the repository root (launch/), next to the colcon workspace; this
# bringup package installs them so that `ros2 launch ext_sense <graph>.launch.py` resolves.
# The path is resolved physically, so it also holds when colcon reaches this package through
# the ros2_ws/src symlink.
HERE = os.path.dirname(os.path.realpath(__file__))
LAUNCH_DIR = os.path.relpath(os.path.join(HERE, "..", "..", "launch"), os.getcwd())

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed", "view/foxglove_layout.json"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", sorted(glob.glob(LAUNCH_DIR + "/*.launch.py"))),
        ("share/" + package_name + "/config", glob.glob("config/*.yaml")),
        # the live view's Foxglove layout (docs/view.md), where a ROS install looks for shares
        ("share/" + package_name + "/foxglove", ["ext_sense/view/foxglove_layout.json"]),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="ext_sense developers",
    maintainer_email="dev@ext-sense.invalid",
    description="Bringup and command line of ext_sense.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "ext-sense = ext_sense.cli:main",
            "estimate_monitor = ext_sense.nodes.estimate_monitor:main",
            "bag_player = ext_sense.nodes.bag_player:main",
            "foxglove_view = ext_sense.view.node:main",
            # several nodes of a graph on one executor (hot_path:=one_process)
            "node_group = ext_sense.runner:main",
        ],
    },
)
