"""The npfkct_ros Python package (src/npfkct_ros), installed by catkin_python_setup()."""

from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["npfkct_ros"], package_dir={"": "src"}))
