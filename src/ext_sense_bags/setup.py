from setuptools import find_packages, setup

package_name = "ext_sense_bags"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="ext_sense developers",
    maintainer_email="dev@ext-sense.invalid",
    description="Pure-Python rosbag2 (mcap, sqlite3) reading and writing of ext_sense messages.",
    license="Apache-2.0",
)
