"""Imports the package's command-line scripts (scripts/<name>, no .py suffix) as modules for testing."""

import importlib.machinery
import importlib.util
import os

SCRIPTS_DIR = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts"))


def load(name):
    path = os.path.join(SCRIPTS_DIR, name)
    loader = importlib.machinery.SourceFileLoader(name.replace("-", "_"), path)
    spec = importlib.util.spec_from_loader(loader.name, loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def built_executable(name):
    """Path of the package's built program `name` in the sourced catkin workspace (devel or install), or
    None when no workspace with it is sourced."""
    for prefix in os.environ.get('CMAKE_PREFIX_PATH', '').split(os.pathsep):
        path = os.path.join(prefix, 'lib', 'along_route_localization', name)
        if prefix and os.access(path, os.X_OK):
            return path
    return None


def ros_python_available():
    try:
        import genpy  # noqa: F401
        import rosbag  # noqa: F401
        import sensor_msgs.msg  # noqa: F401
    except ImportError:
        return False
    return True


def fake_nordland(folder, frames=0, image=None):
    """Makes folder/summer and folder/winter, each with `frames` files images-NNNNN.png: image(season, k) (a
    uint8 array) written as a PNG when given, else empty files (enough for scripts that only list them).
    Returns folder."""
    for season in ("summer", "winter"):
        os.makedirs(os.path.join(folder, season))
        for k in range(frames):
            path = os.path.join(folder, season, "images-%05d.png" % k)
            if image is None:
                open(path, "w").close()
            else:
                import cv2
                cv2.imwrite(path, image(season, k))
    return folder
