"""Shared pieces of the rostests: a synthetic route rendered by scripts/generate_route, bags derived
from it, `rosbag play`, and bounded waits for topics and files."""

import os
import subprocess
import sys
import threading
import time

import numpy as np
import rosbag
import rospy

PACKAGE_DIR = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
GENERATOR = os.path.join(PACKAGE_DIR, 'scripts', 'generate_route')
CAMERA_TOPIC = '/camera/image_raw'

# Frames of 256 x 128 px shrink to the default 64 x 32 by exactly 4, so a shift of 8 camera px is
# exactly 2 px of the preprocessed image.
WIDTH, HEIGHT = 256, 128
SCALE = 64.0 / WIDTH


def generate_route(output, frames=60, seed=3, rate=10.0):
    """Writes output/teach.bag, output/repeat.bag and output/ground_truth.csv (see the generator)."""
    subprocess.run([sys.executable, GENERATOR, '--output', output, '--seed', str(seed),
                    '--teach-frames', str(frames), '--width', str(WIDTH), '--height', str(HEIGHT),
                    '--rate', str(rate), '--compression', 'none'],
                   check=True, timeout=300, stdout=subprocess.DEVNULL)


def set_up_route(test_class, node_name, frames, prefix):
    """The start of a rostest's setUpClass: the test node, a fresh folder test_class.tmp and the synthetic
    route rendered into it (teach.bag, repeat.bag, ground_truth.csv)."""
    import tempfile
    rospy.init_node(node_name)
    test_class.tmp = tempfile.mkdtemp(prefix=prefix)
    generate_route(test_class.tmp, frames=frames)


def read_ground_truth(path):
    import csv
    with open(path) as f:
        return list(csv.DictReader(f))


def read_messages(bag_path, topic):
    with rosbag.Bag(bag_path) as bag:
        return [msg for _, msg, _ in bag.read_messages(topics=[topic])]


def image_array(msg):
    channels = {'mono8': 1, '8UC1': 1, 'bgr8': 3, 'rgb8': 3}[msg.encoding]
    data = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.step)
    return data[:, :msg.width * channels].reshape(msg.height, msg.width, channels)


def shifted(msg, shift_px):
    """A copy of a bgr8/rgb8/mono8 image whose content is moved shift_px to the right (left edge
    replicated, nothing wraps): a camera yawed to the left by the matching angle."""
    image = image_array(msg)
    out = np.empty_like(image)
    out[:, shift_px:] = image[:, :image.shape[1] - shift_px]
    out[:, :shift_px] = image[:, :1]
    copy = type(msg)()
    copy.header = msg.header
    copy.height, copy.width, copy.encoding = msg.height, msg.width, msg.encoding
    copy.is_bigendian, copy.step = 0, msg.width * image.shape[2]
    copy.data = out.tobytes()
    return copy


def write_bag(path, topic, messages):
    with rosbag.Bag(path, 'w') as bag:
        for msg in messages:
            bag.write(topic, msg, msg.header.stamp)


def play(bag_path, topic_remaps=None, timeout=120.0, extra=()):
    """rosbag play, waiting 1 s after advertising so that subscribers are connected before the first
    message. Returns when the bag has been played."""
    args = ['rosbag', 'play', '-q', '-d', '1'] + list(extra) + [bag_path]
    for source, target in (topic_remaps or {}).items():
        args.append('%s:=%s' % (source, target))
    subprocess.run(args, check=True, timeout=timeout, stdout=subprocess.DEVNULL, stdin=subprocess.DEVNULL)


def wait_for(predicate, timeout, what):
    """Polls predicate() every 50 ms until it is true; fails the test after timeout seconds."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return
        if rospy.is_shutdown():
            break
        time.sleep(0.05)
    raise AssertionError('timed out after %.0f s waiting for %s' % (timeout, what))


def subscribers(topic):
    """The nodes the ROS master lists as subscribed to `topic` (resolved name), sorted."""
    import rosgraph
    _, subscribed, _ = rosgraph.Master(rospy.get_name()).getSystemState()
    return sorted(node for name, nodes in subscribed if name == topic for node in nodes)


def wait_for_service(name, timeout=60.0):
    rospy.wait_for_service(name, timeout=timeout)


class Collector(object):
    """Keeps every message of a topic."""

    def __init__(self, topic, msg_type, queue_size=1000):
        self.lock = threading.Lock()
        self.messages = []
        self.subscriber = rospy.Subscriber(topic, msg_type, self._callback, queue_size=queue_size)

    def _callback(self, msg):
        with self.lock:
            self.messages.append(msg)

    def count(self):
        with self.lock:
            return len(self.messages)

    def take(self):
        with self.lock:
            messages, self.messages = self.messages, []
            return messages

    def snapshot(self):
        with self.lock:
            return list(self.messages)


class RosoutCollector(Collector):
    def __init__(self):
        from rosgraph_msgs.msg import Log
        # /rosout itself: every node publishes there (the aggregated topic may lag or drop).
        Collector.__init__(self, '/rosout', Log)

    def matching(self, text, level=None):
        return [m for m in self.snapshot() if text in m.msg and (level is None or m.level == level)]


class DiagnosticsCollector(Collector):
    """Keeps /diagnostics; finds a nodelet's status in what arrives."""

    def __init__(self):
        from diagnostic_msgs.msg import DiagnosticArray
        Collector.__init__(self, '/diagnostics', DiagnosticArray, queue_size=10000)

    def next_status(self, suffix, predicate, what, timeout=15.0):
        """The first status arriving from now on whose name ends with suffix (e.g. 'repeat/localizer:
        localization') and that satisfies predicate."""
        self.take()
        found = []

        def seen():
            found.extend(s for d in self.take() for s in d.status if s.name.endswith(suffix) and predicate(s))
            return bool(found)
        wait_for(seen, timeout, what)
        return found[0]


def status_values(status):
    """A diagnostic status's key-value pairs as a dict."""
    return {v.key: v.value for v in status.values}


def map_keyframes(path):
    """(keyframe messages, preprocessing text) of a map file, read with the Python rosbag API."""
    with rosbag.Bag(path) as bag:
        keyframes = [msg for _, msg, _ in bag.read_messages(topics=['keyframes'])]
        preprocessing = [msg.data for _, msg, _ in bag.read_messages(topics=['preprocessing'])]
    return keyframes, preprocessing


def teach_and_load(teach_bag, frames, map_path, play_extra=()):
    """For a test launching teach.launch in teach/ (camera /teach_camera/image_raw) and repeat.launch in
    repeat/: plays teach_bag (camera on CAMERA_TOPIC) into the teach pipeline, waits until its `frames`
    images were preprocessed, finishes the map and loads it into the localizer.
    Returns (finish response, load_map response)."""
    from sensor_msgs.msg import Image
    from std_srvs.srv import Trigger
    from along_route_localization.srv import LoadMap
    preprocessed = Collector('/teach/image_preprocessed', Image, queue_size=max(1000, frames))
    wait_for_service('/teach/map_recorder/finish')
    wait_for_service('/repeat/localizer/load_map')
    play(teach_bag, {CAMERA_TOPIC: '/teach_camera/image_raw'}, extra=play_extra)
    wait_for(lambda: preprocessed.count() >= frames, 60, 'the teach drive to be preprocessed')
    finish = rospy.ServiceProxy('/teach/map_recorder/finish', Trigger)()
    loaded = rospy.ServiceProxy('/repeat/localizer/load_map', LoadMap)(map_path)
    preprocessed.subscriber.unregister()
    return finish, loaded


def remove(*paths):
    for path in paths:
        for candidate in (path, path + '.active'):
            if os.path.exists(candidate):
                os.remove(candidate)
