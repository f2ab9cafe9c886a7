#!/usr/bin/python3
"""Teach: the recorder turns a played bag into a map file with the expected keyframes."""

import glob
import os
import shutil
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticStatus
from sensor_msgs.msg import Image
from std_msgs.msg import String
from std_srvs.srv import Trigger

import route_fixture as fx

FRAMES = 60


class TeachTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        fx.set_up_route(cls, 'teach_test', FRAMES, 'along_route_teach_test_')
        cls.teach = fx.read_messages(os.path.join(cls.tmp, 'teach.bag'), fx.CAMERA_TOPIC)
        cls.maps = {ns: rospy.get_param('~map_' + ns) for ns in ('every', 'nth', 'manual')}
        cls.preprocessed = fx.Collector('/every/image_preprocessed', Image)
        cls.manual_preprocessed = fx.Collector('/manual/image_preprocessed', Image)
        cls.diagnostics = fx.DiagnosticsCollector()
        for ns in cls.maps:
            fx.wait_for_service('/%s/map_recorder/finish' % ns)
        cls.announced = rospy.wait_for_message('/every/preprocessing_params', String, timeout=30)

        # A file from an earlier teach already has the manual recorder's map name; it is kept, not
        # overwritten, once the new recording writes its first keyframe.
        cls.earlier_manual_map = b'#ROSBAG V2.0\nan earlier teach of this route'
        with open(cls.maps['manual'], 'wb') as f:
            f.write(cls.earlier_manual_map)

        # First play: the manual recorder has not been started and must record nothing.
        nth_preprocessed = fx.Collector('/nth/image_preprocessed', Image)
        fx.play(os.path.join(cls.tmp, 'teach.bag'))
        # A recorder gets each image in-process before this node gets it over TCP, so once all
        # arrived here, the service calls below queue behind them in the recorder's callback queue.
        fx.wait_for(lambda: min(cls.preprocessed.count(), nth_preprocessed.count(),
                                cls.manual_preprocessed.count()) >= FRAMES, 30, 'the first play to be preprocessed')
        # What the recorders' diagnostics say now: every/ has taken and written the whole play, manual/
        # waits for ~start.
        cls.recording = cls.diagnostics.next_status(
            'every/map_recorder: recording', lambda s: fx.status_values(s)['keyframes written'] == str(FRAMES),
            'every/ to report the first play written')
        cls.idle = cls.diagnostics.next_status('manual/map_recorder: recording', lambda s: True, 'manual/ to report')
        cls.manual_start = rospy.ServiceProxy('/manual/map_recorder/start', Trigger)()
        # Second play: every/ and nth/ see the route twice, so they are finished after the first.
        cls.finish = {}
        for ns in ('every', 'nth'):
            cls.finish[ns] = rospy.ServiceProxy('/%s/map_recorder/finish' % ns, Trigger)()
        fx.play(os.path.join(cls.tmp, 'teach.bag'))
        fx.wait_for(lambda: cls.manual_preprocessed.count() >= 2 * FRAMES, 30, 'the second play')
        cls.finish['manual'] = rospy.ServiceProxy('/manual/map_recorder/finish', Trigger)()
        cls.start_after_finish = rospy.ServiceProxy('/every/map_recorder/start', Trigger)()
        cls.finished = cls.diagnostics.next_status('every/map_recorder: recording', lambda s: True,
                                                   'every/ to report after its finish')

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)
        fx.remove(*cls.maps.values())
        fx.remove(*cls.replaced(cls.maps['manual']))

    @staticmethod
    def replaced(path):
        return glob.glob(os.path.splitext(path)[0] + '.replaced-*.bag')

    def check_map(self, ns, expected_frames):
        path = self.maps[ns]
        self.assertTrue(self.finish[ns].success, self.finish[ns].message)
        self.assertIn('holds %d keyframes' % len(expected_frames), self.finish[ns].message)
        self.assertTrue(os.path.exists(path), path)
        self.assertFalse(os.path.exists(path + '.active'), 'a finished map leaves no .active file')
        keyframes, preprocessing = fx.map_keyframes(path)
        self.assertEqual(len(keyframes), len(expected_frames))
        # Source stamps, in map order, are those of the chosen camera frames.
        self.assertEqual([k.header.stamp for k in keyframes], [f.header.stamp for f in expected_frames])
        for k in keyframes:
            self.assertEqual((k.encoding, k.width, k.height), ('mono8', 64, 32))
        # The stored parameters are the ones the preprocessor announced for these images.
        self.assertEqual(preprocessing, [self.announced.data])
        # One connection per topic, as `rosbag record` writes (issue 33: one per flush, here about 6).
        import rosbag
        with rosbag.Bag(path) as bag:
            topics = bag.get_type_and_topic_info().topics
        self.assertEqual({topic: info.connections for topic, info in topics.items()},
                         {'keyframes': 1, 'preprocessing': 1, 'info': 1})
        return keyframes

    def test_every_frame_is_a_keyframe_by_default(self):
        keyframes = self.check_map('every', self.teach)
        # The bytes stored are the bytes the preprocessor published for that frame (first play).
        published = {m.header.stamp: m.data for m in self.preprocessed.snapshot()[:FRAMES]}
        self.assertEqual(len(published), FRAMES)
        for k in keyframes:
            self.assertEqual(k.data, published[k.header.stamp])

    def test_every_third_frame(self):
        self.check_map('nth', self.teach[0::3])

    def test_manual_recorder_records_only_after_start(self):
        self.assertTrue(self.manual_start.success, self.manual_start.message)
        self.check_map('manual', self.teach)  # the second play only: 60 keyframes, not 120

    def test_a_map_that_was_there_is_kept_under_another_name(self):
        kept = self.replaced(self.maps['manual'])
        self.assertEqual(len(kept), 1, kept)
        with open(kept[0], 'rb') as f:
            self.assertEqual(f.read(), self.earlier_manual_map)
        self.assertIn('the map that was there before is kept as ' + kept[0], self.finish['manual'].message)
        self.assertEqual(self.replaced(self.maps['every']), [], 'no file was there: nothing to keep')

    def test_diagnostics_say_what_the_recorder_is_doing(self):
        values = fx.status_values(self.recording)
        self.assertEqual(self.recording.level, DiagnosticStatus.OK)
        self.assertEqual(self.recording.message, 'recording: %d keyframes' % FRAMES)
        self.assertEqual((values['state'], values['keyframes taken'], values['frames seen while recording']),
                         ('recording', str(FRAMES), str(FRAMES)))
        self.assertEqual((values['frames dropped'], values['map']), ('0', self.maps['every']))
        self.assertEqual((self.idle.level, self.idle.message), (DiagnosticStatus.OK, 'idle: call ~start to record'))
        self.assertEqual(fx.status_values(self.idle)['keyframes taken'], '0')
        # every/ was finished after the first play and ignored the second.
        self.assertEqual(self.finished.message, 'finished: ' + self.finish['every'].message)
        self.assertEqual(fx.status_values(self.finished)['frames seen while recording'], str(FRAMES))

    def test_finished_recorder_refuses_to_start_again(self):
        self.assertFalse(self.start_after_finish.success)
        self.assertIn('finished', self.start_after_finish.message)


if __name__ == '__main__':
    rostest.rosrun('along_route_localization', 'teach', TeachTest)
