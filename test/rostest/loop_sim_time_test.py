#!/usr/bin/python3
"""rosbag play --clock --loop under /use_sim_time: at each loop the stamps jump back; the localizer says
so, restarts (status initializing), tracks the route again on the next pass, and keeps publishing its
diagnostics although ROS time went back."""

import os
import shutil
import signal
import subprocess
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray

from along_route_localization.msg import Localization
import route_fixture as fx

FRAMES = 60
TRACKING = (Localization.STATUS_TRACKING, Localization.STATUS_END_OF_ROUTE)


def passes_after_a_jump(answers, first_stamp, frames):
    """Indices of the answers to the drive's first frame that begin a complete pass after the clock went
    back. The very first pass does not count: the first frame or two may be missed while the subscribers
    connect, so only a pass that starts after an earlier answer (a time jump) is asked to be whole."""
    return [i for i, m in enumerate(answers)
            if i > 0 and m.header.stamp == first_stamp and i + frames <= len(answers)]


class LoopSimTimeTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        fx.set_up_route(cls, 'loop_sim_time_test', FRAMES, 'along_route_loop_test_')
        cls.map_path = rospy.get_param('~map')
        cls.repeat = fx.read_messages(os.path.join(cls.tmp, 'repeat.bag'), fx.CAMERA_TOPIC)
        cls.truth = [int(t['teach_frame']) for t in fx.read_ground_truth(os.path.join(cls.tmp, 'ground_truth.csv'))]
        cls.rosout = fx.RosoutCollector()
        cls.localizations = fx.Collector('/repeat/localization', Localization, queue_size=10000)
        finish, loaded = fx.teach_and_load(os.path.join(cls.tmp, 'teach.bag'), FRAMES, cls.map_path,
                                           play_extra=['--clock'])
        assert finish.success, finish.message
        assert loaded.success, loaded.message
        cls.diagnostics = fx.Collector('/diagnostics', DiagnosticArray, queue_size=10000)

        player = subprocess.Popen(['rosbag', 'play', '-q', '-d', '1', '--clock', '--loop',
                                   os.path.join(cls.tmp, 'repeat.bag'), fx.CAMERA_TOPIC + ':=/repeat_camera/image_raw'],
                                  stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, start_new_session=True)
        try:
            first_stamp = cls.repeat[0].header.stamp
            fx.wait_for(lambda: passes_after_a_jump(cls.localizations.snapshot(), first_stamp, len(cls.repeat)),
                        150, 'a complete pass of the drive after the clock went back')
        finally:
            player.send_signal(signal.SIGINT)
            try:
                player.wait(10)
            except subprocess.TimeoutExpired:
                player.kill()
                player.wait(5)
        cls.answers = cls.localizations.take()
        cls.localizer_diagnostics = [d for d in cls.diagnostics.take()
                                     if any('localization' in status.name for status in d.status)]

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)
        fx.remove(cls.map_path)

    def test_each_loop_restarts_and_tracks_again(self):
        first_stamp = self.repeat[0].header.stamp
        complete = passes_after_a_jump(self.answers, first_stamp, len(self.repeat))
        self.assertTrue(complete, 'no complete pass after the clock went back')
        self.assertTrue(self.rosout.matching('Time went backwards'))
        index = {m.header.stamp: i for i, m in enumerate(self.repeat)}
        for start in complete:
            # The first frame after the jump starts over at the route's start (start_keyframe 0) instead of
            # continuing from its end.
            self.assertIn(self.answers[start].status, TRACKING)
            self.assertLessEqual(abs(self.answers[start].keyframe - self.truth[0]), 2)
            loop = self.answers[start:start + len(self.repeat)]
            tracked = [m for m in loop if m.status in TRACKING]
            self.assertGreaterEqual(len(tracked), 0.7 * len(loop))
            close = [m for m in tracked if abs(m.keyframe - self.truth[index[m.header.stamp]]) <= 2]
            self.assertGreaterEqual(len(close), 0.9 * len(tracked))

    def test_diagnostics_go_on_after_time_went_back(self):
        # The diagnostics are stamped with ROS time, here the bag's clock. Split where that clock went
        # back: at least two passes of the repeat drive must each hold diagnostics.
        first, last = self.repeat[0].header.stamp, self.repeat[-1].header.stamp
        passes, previous = [], None
        for d in self.localizer_diagnostics:
            if previous is None or d.header.stamp < previous:
                passes.append([])
            previous = d.header.stamp
            if first <= d.header.stamp <= last:
                passes[-1].append(d)
        self.assertGreaterEqual(len([p for p in passes if len(p) >= 2]), 2,
                                'diagnostics per pass of the drive: %s' % [len(p) for p in passes])


if __name__ == '__main__':
    rostest.rosrun('along_route_localization', 'loop_sim_time', LoopSimTimeTest)
