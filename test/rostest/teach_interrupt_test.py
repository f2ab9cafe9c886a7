#!/usr/bin/python3
"""An interrupted teach keeps what it recorded: teach.launch stopped with SIGINT in the middle of a bag
leaves a closed map of every frame it got; a nodelet manager killed with SIGKILL leaves a readable map
holding every keyframe up to the last flush (flush_period 1 s)."""

import os
import shutil
import signal
import subprocess
import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import Image

import route_fixture as fx

FRAMES = 60
PLAYED_S = 2.95   # rosbag play -u: the first 30 frames of a 10 Hz bag


def start(args, namespace):
    env = dict(os.environ, ROS_NAMESPACE=namespace)
    return subprocess.Popen(args, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


def stop(process, sig, timeout=30.0):
    process.send_signal(sig)
    try:
        process.wait(timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait(10)
        raise AssertionError('process %d did not stop within %.0f s of signal %d' % (process.pid, timeout, sig))


class TeachInterruptTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        fx.set_up_route(cls, 'teach_interrupt_test', FRAMES, 'along_route_interrupt_test_')
        cls.teach = fx.read_messages(os.path.join(cls.tmp, 'teach.bag'), fx.CAMERA_TOPIC)
        cls.processes = []

    @classmethod
    def tearDownClass(cls):
        for process in cls.processes:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(10)
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def teach_half(self, namespace, map_path, manager=''):
        """Starts teach.launch in namespace, plays the first half of the bag, returns (launch, frames the
        recorder's input topic carried)."""
        received = fx.Collector('/%s/image_preprocessed' % namespace, Image)
        launch = start(['roslaunch', 'along_route_localization', 'teach.launch', 'image:=/%s/camera' % namespace,
                        'map:=' + map_path, 'manager:=' + manager, 'output:=log'], namespace)
        self.processes.append(launch)
        fx.wait_for_service('/%s/map_recorder/finish' % namespace)
        fx.play(os.path.join(self.tmp, 'teach.bag'), {fx.CAMERA_TOPIC: '/%s/camera' % namespace},
                extra=['-u', str(PLAYED_S)])
        fx.wait_for(lambda: received.count() >= 25, 30, 'the played frames to be preprocessed')
        time.sleep(0.5)  # the last ones too
        return launch, received.snapshot()

    def test_sigint_closes_the_map_with_every_frame(self):
        map_path = os.path.join(self.tmp, 'sigint.bag')
        launch, received = self.teach_half('sigint', map_path)
        self.assertLess(len(received), FRAMES)
        stop(launch, signal.SIGINT)
        self.assertTrue(os.path.exists(map_path))
        self.assertFalse(os.path.exists(map_path + '.active'))
        keyframes, preprocessing = fx.map_keyframes(map_path)
        self.assertEqual([k.header.stamp for k in keyframes], [m.header.stamp for m in received])
        self.assertEqual([k.data for k in keyframes], [m.data for m in received])
        self.assertEqual(len(preprocessing), 1)

    def test_sigkill_keeps_everything_up_to_the_last_flush(self):
        map_path = os.path.join(self.tmp, 'sigkill.bag')
        manager = start(['rosrun', 'nodelet', 'nodelet', 'manager', '__name:=killed_manager'], 'sigkill')
        self.processes.append(manager)
        launch, received = self.teach_half('sigkill', map_path, manager='killed_manager')
        time.sleep(1.5)  # > flush_period: the last frame is on disk
        os.kill(manager.pid, signal.SIGKILL)
        manager.wait(10)
        stop(launch, signal.SIGINT)
        self.assertTrue(os.path.exists(map_path))
        keyframes, preprocessing = fx.map_keyframes(map_path)
        self.assertEqual([k.header.stamp for k in keyframes], [m.header.stamp for m in received])
        self.assertEqual(len(preprocessing), 1)


if __name__ == '__main__':
    rostest.rosrun('along_route_localization', 'teach_interrupt', TeachInterruptTest)
