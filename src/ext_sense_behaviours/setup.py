import glob

from setuptools import find_packages, setup

package_name = "ext_sense_behaviours"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed", "**/*.yaml", "**/*.json"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob.glob("config/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="ext_sense developers",
    maintainer_email="dev@ext-sense.invalid",
    description="Behaviour nodes for the Robotiq gripper and the Panda arm.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "robotiq_gripper = ext_sense_behaviours.nodes.robotiq_gripper:main",
            "handover_behaviour = ext_sense_behaviours.nodes.handover_behaviour:main",
            "food_behaviour = ext_sense_behaviours.nodes.food_behaviour:main",
            "tap_marker = ext_sense_behaviours.nodes.tap_marker:main",
        ],
    },
)
