#!/usr/bin/python3
"""Issue 33: parameters left on the parameter server by an earlier launch (a stale ~normalization: patch,
~ring_buffer_rows from a dynparam session) were used by the next launch, whose repeat then refused its map.
repeat.launch, teach.launch and follow.launch clear their nodelets' private parameters (clear_params) and then load
their own; in the params_file, a misspelt one is named with the parameters the nodelet reads, a bad value is
refused by name while the good ones are used, and what is logged is what is used."""

import os
import shutil
import signal
import subprocess
import tempfile
import unittest

import rosgraph
import rospy
import rostest
from rosgraph_msgs.msg import Log
from std_msgs.msg import String

import route_fixture as fx


class CleanSlateTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('clean_slate_test')
        cls.tmp = tempfile.mkdtemp(prefix='along_route_clean_slate_')
        cls.rosout = fx.RosoutCollector()

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def launch(self, launch_file, *args):
        """roslaunch along_route_localization `launch_file` on this test's master; stopped by the caller."""
        env = dict(os.environ, ROS_MASTER_URI=rosgraph.get_master_uri())
        return subprocess.Popen(['roslaunch', 'along_route_localization', launch_file, 'output:=log'] + list(args),
                                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True)

    def stop(self, process):
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=10)

    def test_repeat_launch_ignores_what_an_earlier_launch_left(self):
        # What an earlier launch left: a preprocessing a map was not made with, a window set by dynparam,
        # a static parameter of another params_file.
        rospy.set_param('/preprocessor/normalization', 'patch')
        rospy.set_param('/localizer/ring_buffer_rows', 7)
        rospy.set_param('/localizer/min_texture_ratio', 0.9)
        params = os.path.join(self.tmp, 'repeat_params.yaml')
        with open(params, 'w') as f:
            # One bad value (method: DTW) and one outside its range among good ones: before, the whole file
            # was rejected and the defaults used, while a WARN claimed the clamped value was used.
            f.write('localizer:\n  max_step: 3\n  ring_bufer_rows: 10\n  method: DTW\n  lost_window_frames: 50000\n')
        announced = fx.Collector('/preprocessing_params', String)
        process = self.launch('repeat.launch', 'map:=', 'params_file:=' + params)
        try:
            fx.wait_for(lambda: announced.count() > 0, 60, "the preprocessor's parameters")
            self.assertIn('normalization=divisive', announced.snapshot()[-1].data)
            # The reconfigure server writes the values it uses back: the default K, this file's s.
            fx.wait_for(lambda: rospy.get_param('/localizer/max_step', None) == 3, 30, 'max_step 3 from the file')
            fx.wait_for(lambda: rospy.get_param('/localizer/ring_buffer_rows', None) == 30, 30, 'the default K')
            self.assertFalse(rospy.has_param('/localizer/min_texture_ratio'))
            fx.wait_for(lambda: rospy.get_param('/preprocessor/normalization', None) == 'divisive', 30,
                        'normalization divisive on the parameter server')
            # The misspelt name is named with the parameters the localizer reads, not a header file.
            text = '~ring_bufer_rows is not a parameter of the localizer and is ignored (did you mean ring_buffer_rows?)'
            fx.wait_for(lambda: self.rosout.matching(text, Log.WARN), 30, 'the warning about ring_bufer_rows')
            warning = self.rosout.matching(text)[0].msg
            self.assertIn('It reads: ', warning)
            self.assertIn('min_texture_ratio', warning)
            self.assertNotIn('.h', warning)
            # What the file set is said once, with the value used; the bad value is named, the good ones used.
            self.assertTrue(self.rosout.matching('max_step 2 -> 3', Log.INFO))
            self.assertTrue(self.rosout.matching("method 'DTW' is not one of dtw | seqslam; keeping dtw", Log.WARN))
            fx.wait_for(lambda: rospy.get_param('/localizer/method', None) == 'dtw', 30, 'method dtw written back')
            self.assertTrue(self.rosout.matching('lost_window_frames 50000 is outside 1 .. 10000 frames; using 10000',
                                                 Log.WARN))
            self.assertTrue(self.rosout.matching('lost_window_frames 8 -> 10000', Log.INFO))
            # Written back by the reconfigure server, which may come after the log lines above.
            fx.wait_for(lambda: rospy.get_param('/localizer/lost_window_frames', None) == 10000, 30,
                        'lost_window_frames 10000 written back')
        finally:
            self.stop(process)

    def test_teach_launch_ignores_what_an_earlier_launch_left(self):
        rospy.set_param('/map_recorder/every_nth', 4)
        rospy.set_param('/preprocessor/sky_fraction', 0.5)
        map_path = os.path.join(self.tmp, 'never_written.bag')
        process = self.launch('teach.launch', 'map:=' + map_path, 'autostart:=false')
        try:
            fx.wait_for(lambda: rospy.get_param('/map_recorder/every_nth', None) == 1, 60, 'the default every_nth')
            fx.wait_for(lambda: rospy.get_param('/preprocessor/sky_fraction', None) == 0.0, 30,
                        'the default sky_fraction')
        finally:
            self.stop(process)

    def test_follow_launch_ignores_what_an_earlier_launch_left(self):
        # Left by an earlier follow.launch tuned in rqt (the reconfigure server writes every value back):
        # a speed factor of 3 and a watchdog of 30 s would drive the next repeat 3x as fast and stop it
        # only after 30 s without a localization. The params file's own route_follower: value is used.
        rospy.set_param('/route_follower/speed_factor', 3.0)
        rospy.set_param('/route_follower/watchdog_timeout', 30.0)
        params = os.path.join(self.tmp, 'follow_params.yaml')
        with open(params, 'w') as f:
            f.write('route_follower:\n  homing_gain: 2.5\n')
        process = self.launch('follow.launch', 'map:=', 'params_file:=' + params)
        try:
            fx.wait_for(lambda: rospy.get_param('/route_follower/homing_gain', None) == 2.5, 60,
                        "homing_gain 2.5 from the params file")
            fx.wait_for(lambda: rospy.get_param('/route_follower/speed_factor', None) == 1.0, 30,
                        'the default speed_factor')
            self.assertEqual(rospy.get_param('/route_follower/watchdog_timeout'), 1.0)
        finally:
            self.stop(process)


if __name__ == '__main__':
    rostest.rosrun('along_route_localization', 'clean_slate', CleanSlateTest)
