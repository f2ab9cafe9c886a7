#!/usr/bin/python3
"""A teach whose disk fills up between two flushes: the map as flushed stays readable, the recorder says
why it stopped, the keyframe taken before the failure waits in memory, and once there is room again the
recording goes on and the finished map holds every keyframe taken, none twice. The room runs out by the
nodelet manager's file size limit (ulimit -f, set on the running process as `prlimit` does): the writer
checks it before a flush exactly as it checks the free space of the disk."""

import os
import resource
import shutil
import unittest
import xmlrpc.client

import rosgraph
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticStatus
from sensor_msgs.msg import Image
from std_srvs.srv import Trigger

import route_fixture as fx

FRAMES = 30
BEFORE, REFUSED = 10, 5  # frames recorded before the limit; frames sent while the recorder refuses them
MANAGER = '/full/full_manager'
RECORDER = 'full/map_recorder: recording'


class TeachFullDiskTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        fx.set_up_route(cls, 'teach_full_disk_test', FRAMES, 'along_route_teach_full_disk_')
        cls.map = rospy.get_param('~map')
        frames = fx.read_messages(os.path.join(cls.tmp, 'teach.bag'), fx.CAMERA_TOPIC)
        cls.diagnostics = fx.DiagnosticsCollector()
        cls.rosout = fx.RosoutCollector()
        preprocessed = fx.Collector('/full/image_preprocessed', Image)
        camera = rospy.Publisher(fx.CAMERA_TOPIC, Image, queue_size=100)
        fx.wait_for_service('/full/map_recorder/finish')
        fx.wait_for(lambda: camera.get_num_connections() > 0 and preprocessed.subscriber.get_num_connections() > 0,
                    30, 'the preprocessor to subscribe')

        def send(batch):
            target = preprocessed.count() + len(batch)
            for frame in batch:
                camera.publish(frame)
                rospy.sleep(0.05)
            fx.wait_for(lambda: preprocessed.count() >= target, 30, 'the frames to be preprocessed')

        # 1. Recorded and flushed.
        send(frames[:BEFORE])
        cls.flushed = cls.diagnostics.next_status(
            RECORDER, lambda s: fx.status_values(s)['keyframes written'] == str(BEFORE), 'the first frames flushed')
        # 2. The room runs out: the file may grow by 8 KiB, a flush needs more. One keyframe is taken; its
        # flush fails.
        cls.pid = cls.manager_pid()
        soft, hard = resource.prlimit(cls.pid, resource.RLIMIT_FSIZE)
        cls.size_before = os.path.getsize(cls.map)
        resource.prlimit(cls.pid, resource.RLIMIT_FSIZE, (cls.size_before + 8192, hard))
        send(frames[BEFORE:BEFORE + 1])
        cls.failed = cls.diagnostics.next_status(RECORDER, lambda s: s.level == DiagnosticStatus.ERROR,
                                                 'the recorder to report the failed flush')
        cls.keyframes_while_full, _ = fx.map_keyframes(cls.map)
        cls.size_while_full = os.path.getsize(cls.map)
        # 3. Frames while it cannot write are refused, not queued without bound.
        send(frames[BEFORE + 1:BEFORE + 1 + REFUSED])
        cls.refusing = cls.diagnostics.next_status(RECORDER, lambda s: True, 'the recorder to report')
        # 4. Room again: the next flush writes the waiting keyframe, and recording goes on.
        resource.prlimit(cls.pid, resource.RLIMIT_FSIZE, (soft, hard))
        cls.again = cls.diagnostics.next_status(
            RECORDER, lambda s: fx.status_values(s)['keyframes written'] == str(BEFORE + 1),
            'the recorder to write again')
        send(frames[BEFORE + 1 + REFUSED:])
        cls.finish = rospy.ServiceProxy('/full/map_recorder/finish', Trigger)()
        cls.frames = frames

    @staticmethod
    def manager_pid():
        uri = rosgraph.Master(rospy.get_name()).lookupNode(MANAGER)
        code, message, pid = xmlrpc.client.ServerProxy(uri).getPid(rospy.get_name())
        assert code == 1, message
        return pid

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)
        fx.remove(cls.map)

    def test_the_map_as_flushed_stays_readable_while_the_disk_is_full(self):
        self.assertEqual(self.size_while_full, self.size_before)
        self.assertEqual([k.header.stamp for k in self.keyframes_while_full],
                         [f.header.stamp for f in self.frames[:BEFORE]])

    def test_the_recorder_says_why_it_stopped_and_that_the_keyframe_waits(self):
        self.assertIn('not recording: no room to write 1 keyframes to', self.failed.message)
        self.assertIn("file size limit (%d bytes, ulimit -f)" % (self.size_before + 8192), self.failed.message)
        self.assertIn('the map as flushed is kept and the keyframes stay buffered', self.failed.message)
        values = fx.status_values(self.failed)
        self.assertEqual((values['keyframes taken'], values['keyframes written']), (str(BEFORE + 1), str(BEFORE)))
        self.assertEqual(self.refusing.level, DiagnosticStatus.ERROR)
        self.assertEqual(fx.status_values(self.refusing)['keyframes taken'], str(BEFORE + 1))
        self.assertTrue(self.rosout.matching('no room to write'), 'the failure is logged')

    def test_recording_goes_on_once_there_is_room(self):
        # Before the next frame comes: the frames refused while the disk was full are not news any more.
        self.assertEqual((self.again.level, self.again.message),
                         (DiagnosticStatus.OK, 'recording: %d keyframes' % (BEFORE + 1)))
        self.assertTrue(self.rosout.matching('written again (%d keyframes); recording goes on' % (BEFORE + 1)))
        expected = self.frames[:BEFORE + 1] + self.frames[BEFORE + 1 + REFUSED:]
        self.assertTrue(self.finish.success, self.finish.message)
        self.assertIn('holds %d keyframes' % len(expected), self.finish.message)
        keyframes, _ = fx.map_keyframes(self.map)
        self.assertEqual([k.header.stamp for k in keyframes], [f.header.stamp for f in expected])


if __name__ == '__main__':
    rostest.rosrun('along_route_localization', 'teach_full_disk', TeachFullDiskTest)
