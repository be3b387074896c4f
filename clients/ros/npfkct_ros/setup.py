"""The npfkct_ros Python package (src/npfkct_ros) and the npfkct Python client it uses
(src/npfkct_client, a link to clients/python/npfkct_client), installed by catkin_python_setup():
in a catkin workspace the node imports the client from the devel or install space."""

from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["npfkct_ros", "npfkct_client"],
                                 package_dir={"": "src"}))
