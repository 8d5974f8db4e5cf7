"""ament_python package sweep_ros: the engine sweep_core (no ROS) and the ROS 2 node sweep_ros."""
from glob import glob

from setuptools import find_packages, setup

package_name = "sweep_ros"

setup(
    name=package_name,
    version="0.4.3",
    packages=find_packages(include=["sweep_core", "sweep_core.*", "sweep_ros"]),
    package_data={"sweep_core": ["scenes/*.yaml", "scenes/maps/*", "scenes/rimea/*.yaml",
                                 "analysis/data/*.csv", "py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config",
         glob("config/*.yaml") + glob("config/*.json") + glob("config/*.rviz")),
        ("share/" + package_name + "/config/scenes", glob("sweep_core/scenes/*.yaml")),
        ("share/" + package_name + "/config/scenes/maps", glob("sweep_core/scenes/maps/*")),
        ("share/" + package_name + "/launch", glob("launch/*.py")),
    ],
    python_requires=">=3.10",
    install_requires=[
        "numpy>=1.24",
        "scipy>=1.10",
        "proxsuite>=0.6",
        "clarabel>=0.9",
        "piqp==0.6.4",
        "qpsolvers>=4.0",
        "PyYAML>=6",
        "mcap>=1.6",
        "tqdm>=4.60",
        "matplotlib>=3.7",
        "imageio-ffmpeg==0.8.1",
        "numba>=0.60",
        "cvxopt>=1.3",
        "pyrvo==0.4.3",
    ],
    # sweep verify and sweep export (PedPy needs Python >= 3.11); the Gymnasium environment;
    # sweep run --live (the Foxglove WebSocket server)
    extras_require={"verify": ["pedpy==1.5.1", "distributed", "pandas"],
                    "gym": ["gymnasium==1.4.0"], "live": ["foxglove-sdk==0.30.3"]},
    zip_safe=True,
    maintainer="sweep_ros developers",
    maintainer_email="sweep-ros@example.org",
    description="Stochastic sweeping-process crowd simulation with exact non-overlap, for ROS 2.",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "sweep = sweep_core.cli:main",
            "sweep_node = sweep_ros.main:main",
            "sweep_client = sweep_ros.client:cli",
            "sweep_robot_controller = sweep_ros.controller:main",
        ],
    },
)
