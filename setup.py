# The Python package along_route_localization (src/along_route_localization: what the scripts share), for
# catkin_python_setup() in CMakeLists.txt: it puts the package on the devel space's Python path and installs
# it. Not for running by hand (catkin passes the version and the install layout).
from setuptools import setup
from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(packages=["along_route_localization"], package_dir={"": "src"}))
