from setuptools import find_packages, setup

package_name = "ext_sense_runtime"

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
    zip_safe=True,
    maintainer="ext_sense developers",
    maintainer_email="dev@ext-sense.invalid",
    description="Node plumbing shared by every ext_sense node.",
    license="Apache-2.0",
)
