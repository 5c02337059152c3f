from setuptools import setup

package_name = "actaim2_ros"

setup(
    name=package_name,
    version="0.1.0",
    packages=[package_name],
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="actaim2 developers",
    maintainer_email="actaim2@example.com",
    description=open("package.xml").read().split("<description>")[1].split("</description>")[0],
    license="MIT",
)
