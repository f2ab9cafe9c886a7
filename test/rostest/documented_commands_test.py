#!/usr/bin/python3
"""The README's commands lose no frame (issue 33): teach.launch is started and, at the same moment, the
README's `rosbag play` line for the teach drive; then `rosservice call /map_recorder/finish`; then the
same with repeat.launch and the repeat drive. The map holds every frame of the teach drive and the
localizer answers every frame of the repeat drive (a plain `rosbag play` publishes before the
preprocessor has connected, and those frames are lost). roslaunch is started in a directory of the
user's with map:=route.bag: the map is written there, not under ROS_HOME, and named absolutely."""

import os
import shlex
import shutil
import signal
import subprocess
import unittest

import rospy
import rostest
from std_srvs.srv import Trigger

from along_route_localization.srv import LoadMap
import route_fixture as fx

FRAMES = 60
README = os.path.join(fx.PACKAGE_DIR, 'README.md')


def documented_plays():
    """The `rosbag play` lines of the README's 'Using it on your own robot' block: (teach, repeat)."""
    with open(README) as f:
        section = f.read().split('## Using it on your own robot', 1)[1]
    block = section.split('```bash', 1)[1].split('```', 1)[0]
    plays = [shlex.split(line.split('#', 1)[0]) for line in block.splitlines() if line.startswith('rosbag play')]
    assert len(plays) == 2, plays
    return plays


def start(args, cwd):
    # As from a shell in cwd: PWD is what a shell sets.
    env = dict(os.environ, PWD=cwd)
    return subprocess.Popen(args, cwd=cwd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


def stop(process, timeout=30.0):
    if process.poll() is not None:
        return
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait(10)


class DocumentedCommandsTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        fx.set_up_route(cls, 'documented_commands_test', FRAMES, 'along_route_documented_test_')
        cls.user_dir = os.path.join(cls.tmp, 'user')
        os.mkdir(cls.user_dir)
        cls.map_path = os.path.join(cls.user_dir, 'route.bag')
        cls.repeat_frames = len(fx.read_messages(os.path.join(cls.tmp, 'repeat.bag'), fx.CAMERA_TOPIC))
        cls.diagnostics = fx.DiagnosticsCollector()
        cls.processes = []
        teach_play, repeat_play = documented_plays()
        cls.teach_play = [os.path.join(cls.tmp, 'teach.bag') if a == 'my_teach_drive.bag' else a for a in teach_play]
        cls.repeat_play = [os.path.join(cls.tmp, 'repeat.bag') if a == 'my_repeat_drive.bag' else a
                           for a in repeat_play]

        # Teach: roslaunch and the README's rosbag play started together, as in two terminals.
        teach = cls.launch('teach.launch')
        cls.play(cls.teach_play)
        cls.wait_quietly('map_recorder: recording', 'frames seen while recording', FRAMES)
        fx.wait_for_service('/map_recorder/finish')
        cls.map_param = rospy.get_param('/map_recorder/map')
        cls.finish = rospy.ServiceProxy('/map_recorder/finish', Trigger)()
        stop(teach)

        # Repeat, the same way.
        repeat = cls.launch('repeat.launch')
        cls.play(cls.repeat_play)
        cls.processed = cls.wait_quietly('localizer: localization', 'frames processed', cls.repeat_frames)
        fx.wait_for_service('/localizer/load_map')
        cls.relative = rospy.ServiceProxy('/localizer/load_map', LoadMap)('route.bag')
        stop(repeat)

    @classmethod
    def tearDownClass(cls):
        for process in cls.processes:
            stop(process, timeout=10)
        shutil.rmtree(cls.tmp, ignore_errors=True)

    @classmethod
    def launch(cls, launch_file):
        process = start(['roslaunch', 'along_route_localization', launch_file, 'image:=' + fx.CAMERA_TOPIC,
                         'map:=route.bag'], cls.user_dir)
        cls.processes.append(process)
        return process

    @classmethod
    def play(cls, args):
        subprocess.run(args, check=True, timeout=120, stdout=subprocess.DEVNULL, stdin=subprocess.DEVNULL)

    @classmethod
    def wait_quietly(cls, suffix, key, count):
        """The value of `key` in the first status named ...`suffix` that reaches `count` (bounded: 20 s),
        else the last one seen, for the test to compare."""
        seen = []

        def reached(status):
            values = fx.status_values(status)
            if key in values:
                seen.append(int(values[key]))
            return seen and seen[-1] >= count
        try:
            cls.diagnostics.next_status(suffix, reached, '%s to reach %d' % (key, count), timeout=20)
        except AssertionError:
            pass
        return seen[-1] if seen else 0

    def test_the_readme_plays_only_the_camera_and_waits_for_subscribers(self):
        for play in (self.teach_play, self.repeat_play):
            self.assertIn('--wait-for-subscribers', play)
            self.assertEqual(play[-2:], ['--topics', fx.CAMERA_TOPIC])

    def test_teach_records_every_frame_into_the_users_directory(self):
        self.assertTrue(self.finish.success, self.finish.message)
        self.assertEqual(self.finish.message, 'map %s holds %d keyframes' % (self.map_path, FRAMES))
        self.assertEqual(self.map_param, self.map_path)
        keyframes, _ = fx.map_keyframes(self.map_path)
        self.assertEqual(len(keyframes), FRAMES)

    def test_repeat_answers_every_frame(self):
        self.assertEqual(self.processed, self.repeat_frames)

    def test_a_relative_map_path_is_refused_by_the_nodelet_naming_where_it_would_be(self):
        self.assertFalse(self.relative.success)
        self.assertIn("map file 'route.bag' is a relative path", self.relative.message)


if __name__ == '__main__':
    rostest.rosrun('along_route_localization', 'documented_commands', DocumentedCommandsTest)
