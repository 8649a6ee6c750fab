import glob

from setuptools import find_packages, setup

package_name = "ext_sense_sim"

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
    description="Scene simulator and emulated devices.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "sim_device = ext_sense_sim.nodes.sim_device:main",
            "sim_arm = ext_sense_sim.nodes.sim_arm:main",
        ],
    },
)
