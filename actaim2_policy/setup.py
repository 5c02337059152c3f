from glob import glob

from setuptools import setup

package_name = "actaim2_policy"

setup(
    name=package_name,
    version="0.1.0",
    packages=[package_name],
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
        ("share/" + package_name + "/launch", glob("launch/*.yaml") + glob("launch/*.launch.xml")),
        # the committed policy checkpoints (safetensors + JSON, and the encoder E beside those that have it)
        # that policy_node's `checkpoint` names
        ("share/" + package_name + "/checkpoints",
         glob("checkpoints/*.json") + glob("checkpoints/*.safetensors") + glob("checkpoints/*.encoder.pt")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="actaim2 developers",
    maintainer_email="actaim2@example.com",
    description=open("package.xml").read().split("<description>")[1].split("</description>")[0],
    license="MIT",
    entry_points={
        "console_scripts": [
            "bag_player = actaim2_policy.bag_player:main",
            "bag_recorder = actaim2_policy.bag_recorder:main",
            "episode_runner = actaim2_policy.episode_runner:main",
            "policy_node = actaim2_policy.policy_node:main",
            "service_probe = actaim2_policy.service_probe:main",
            "viz_node = actaim2_policy.viz_node:main",
        ],
    },
)
