#!/usr/bin/python3
"""Bad input at the running nodelets: each bad image is dropped with a message naming what is wrong,
and the good frames around it still go through; a burst keeps its newest frame; the localizer unloaded
and loaded again in its running manager localizes again."""

import os
import re
import shutil
import time
import unittest

import numpy as np
import rosbag
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticStatus
from dynamic_reconfigure.client import Client as ReconfigureClient
from nodelet.srv import NodeletLoad, NodeletUnload
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import Image
from std_msgs.msg import String
from std_srvs.srv import Trigger

from along_route_localization.msg import Localization
from along_route_localization.srv import LoadMap
import route_fixture as fx

FRAMES = 40
MANAGER = '/repeat/repeat_manager'


def image(encoding, width, height, data, step=None):
    msg = Image()
    msg.encoding, msg.width, msg.height = encoding, width, height
    msg.step = step if step is not None else (len(data) // height if height else 0)
    msg.data = data
    return msg


class RobustnessTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        fx.set_up_route(cls, 'robustness_test', FRAMES, 'along_route_robustness_test_')
        cls.map_path = rospy.get_param('~map')
        cls.teach = fx.read_messages(os.path.join(cls.tmp, 'teach.bag'), fx.CAMERA_TOPIC)
        cls.rosout = fx.RosoutCollector()
        cls.preprocessed = fx.Collector('/repeat/image_preprocessed', Image)
        cls.localizations = fx.Collector('/repeat/localization', Localization, queue_size=10000)
        cls.diagnostics = fx.DiagnosticsCollector()
        cls.camera = rospy.Publisher('/repeat_camera/image_raw', Image, queue_size=10000)
        cls.direct = rospy.Publisher('/repeat/image_preprocessed', Image, queue_size=100)
        finish, loaded = fx.teach_and_load(os.path.join(cls.tmp, 'teach.bag'), FRAMES, cls.map_path)
        assert finish.success, finish.message
        assert loaded.success, loaded.message
        fx.wait_for(lambda: cls.camera.get_num_connections() > 0 and cls.direct.get_num_connections() > 0, 30,
                    'the nodelets to subscribe')
        cls.next_stamp = 5000.0
        cls.announcers = []  # load_recorder's latched preprocessing parameters

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)
        fx.remove(cls.map_path)

    @classmethod
    def stamped(cls, msg):
        msg.header.stamp = rospy.Time.from_sec(cls.next_stamp)
        msg.header.frame_id = 'camera'
        cls.next_stamp += 0.1
        return msg

    def good(self, index):
        msg = self.teach[index % FRAMES]
        return self.stamped(image(msg.encoding, msg.width, msg.height, msg.data, msg.step))

    def send_good(self, indices):
        """Publishes the good frames of these teach indices on the repeat camera, 20 a second; returns them."""
        sent = []
        for i in indices:
            sent.append(self.good(i))
            self.camera.publish(sent[-1])
            time.sleep(0.05)
        return sent

    def wait_for_stamp(self, collector, stamp, what):
        fx.wait_for(lambda: any(m.header.stamp == stamp for m in collector.snapshot()), 20, what)

    def test_bad_images_are_dropped_with_a_message_and_good_ones_pass(self):
        w, h = 32, 16
        nan_frame = np.full((h, w), 0.5, np.float32)
        nan_frame[3, 4] = np.nan
        bad = [
            ("unsupported encoding 'yuv422'", image('yuv422', w, h, bytes(w * h * 2))),
            ('malformed', image('bgr8', 0, 0, b'')),
            ('malformed', image('bgr8', w, h, bytes(w * h * 3), step=w)),        # step < width * 3
            ('malformed', image('mono8', w, h, bytes(w * h - 1), step=w)),       # data too short
            ('NaN', image('32FC1', w, h, nan_frame.tobytes(), step=w * 4)),
        ]
        stamps = []
        for text, msg in bad:
            stamps.append(self.stamped(msg).header.stamp)
            self.camera.publish(msg)
            good = self.good(len(stamps))
            self.camera.publish(good)
            self.wait_for_stamp(self.preprocessed, good.header.stamp, 'the good frame after a bad one')
            fx.wait_for(lambda: self.rosout.matching(text), 10, 'an error naming %r' % text)
        # An odd size is no error: 63 x 31 bgr8 becomes a 64 x 32 image.
        odd = self.stamped(image('bgr8', 63, 31, bytes(range(256)) * (63 * 31 * 3 // 256) + bytes(63 * 31 * 3 % 256)))
        self.camera.publish(odd)
        self.wait_for_stamp(self.preprocessed, odd.header.stamp, 'the odd-sized frame')
        produced = {m.header.stamp: m for m in self.preprocessed.snapshot()}
        for stamp in stamps:
            self.assertNotIn(stamp, produced)
        self.assertEqual((produced[odd.header.stamp].width, produced[odd.header.stamp].height), (64, 32))

    def test_float_frames_outside_zero_to_one_pass_clipped_with_a_warning(self):
        # A thermal camera in kelvin: 32FC1 from 250 to 310. Used (clipped to white), and said.
        w, h = 32, 16
        kelvin = np.linspace(250.0, 310.0, w * h, dtype=np.float32).reshape(h, w)
        hot = self.stamped(image('32FC1', w, h, kelvin.tobytes(), step=w * 4))
        self.camera.publish(hot)
        self.wait_for_stamp(self.preprocessed, hot.header.stamp, 'the clipped float frame')
        fx.wait_for(lambda: self.rosout.matching('32FC1 values from 250 to 310, outside the [0, 1] read as '
                                                 'intensity: clipped'), 10, 'the warning')

    def test_diagnostics_say_why_frames_are_dropped_until_good_ones_come(self):
        # Only bad frames: each nodelet's diagnostics turn to ERROR, naming what is wrong. A good frame
        # turns them back; the count of dropped frames stays.
        preprocessor, localizer = 'repeat/preprocessor: preprocessing', 'repeat/localizer: localization'
        status, error = self.diagnostics.next_status, DiagnosticStatus.ERROR
        self.camera.publish(self.stamped(image('yuv422', 32, 16, bytes(32 * 16 * 2))))
        status(preprocessor, lambda s: s.level == error and "unsupported encoding 'yuv422'" in s.message,
               'the preprocessor diagnostics naming the encoding')
        self.direct.publish(self.stamped(image('mono8', 32, 16, bytes(32 * 16))))
        status(localizer, lambda s: s.level == error and 'dropping a 32x16' in s.message
               and 'holds 64x32 mono8 keyframes' in s.message, 'the localizer diagnostics naming the size')
        self.direct.publish(self.stamped(image('bgr8', 64, 32, bytes(64 * 32 * 3))))
        status(localizer, lambda s: s.level == error and "a 64x32 'bgr8' frame" in s.message
               and 'takes the preprocessor' in s.message, 'the localizer diagnostics naming the encoding')
        good = self.good(5)
        self.camera.publish(good)
        self.wait_for_stamp(self.localizations, good.header.stamp, 'the good frame localized')
        ok = fx.status_values(status(preprocessor, lambda s: s.level == DiagnosticStatus.OK,
                                     'the preprocessor OK again'))
        self.assertGreaterEqual(int(ok['images dropped']), 1)
        self.assertIn("unsupported encoding 'yuv422'", ok['last dropped image'])
        back = fx.status_values(status(localizer, lambda s: s.level != error, 'the localizer without error again'))
        self.assertGreaterEqual(int(back['frames dropped']), 2)
        self.assertIn("'bgr8'", back['last dropped frame'])

    def test_a_recorder_given_frames_it_cannot_record_says_so(self):
        # A recorder loaded into the repeat manager, recording the repeat's preprocessed images: a frame
        # of the wrong size is not recorded and its diagnostics say why, until a good one is.
        name = '/repeat/second_recorder'
        path = os.path.join(self.tmp, 'second_map.bag')
        # ~motion_type: a topic's name for its type: said, twist used
        self.load_recorder(name, {'map': path, 'motion_type': 'cmd_vel'})
        status, suffix = self.diagnostics.next_status, 'repeat/second_recorder: recording'
        try:
            text = "~motion_type 'cmd_vel' is not one of none | twist | odometry; using twist"
            fx.wait_for(lambda: self.rosout.matching(text, Log.ERROR), 10, 'a message starting %r' % text)
            fx.wait_for(lambda: self.direct.get_num_connections() > 1, 10, 'the recorder to subscribe')
            waiting = status(suffix, lambda s: True, 'the recorder to report')
            self.assertEqual((waiting.level, waiting.message), (DiagnosticStatus.WARN,
                             'recording, waiting for images on /repeat/image_preprocessed'))
            self.direct.publish(self.stamped(image('mono8', 32, 16, bytes(32 * 16))))
            refused = status(suffix, lambda s: s.level == DiagnosticStatus.ERROR, 'the recorder to refuse the frame')
            self.assertEqual(refused.message, "not recording the frames: a 32x16 'mono8' frame: the preprocessing "
                                              "parameters make 64x32 mono8")
            good = self.good(2)
            self.camera.publish(good)
            recording = status(suffix, lambda s: s.level == DiagnosticStatus.OK, 'the recorder to record again')
            self.assertEqual(recording.message, 'recording: 1 keyframe')
            values = fx.status_values(recording)
            self.assertEqual((values['frames dropped'], values['frames seen while recording']), ('1', '2'))
            # Issue 33: ~finish said success and nothing of the frames not recorded.
            finish = rospy.ServiceProxy(name + '/finish', Trigger)()
            self.assertTrue(finish.success, finish.message)
            self.assertEqual(finish.message, "map %s holds 1 keyframes; not recorded: 1 of the 2 frames seen while "
                             "recording (1 frame: a 32x16 'mono8' frame: the preprocessing parameters make 64x32 "
                             "mono8)" % path)
            fx.wait_for(lambda: self.rosout.matching('~finish: ' + finish.message, Log.WARN), 10,
                        'the finish said at WARN')
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
            fx.remove(path)

    def test_start_says_when_a_leftover_active_file_will_make_the_recording_fail(self):
        # Issue 33: ~start said success while a `.active` left by a killed recorder (holding keyframes)
        # would make ~finish fail. It now refuses, naming the file; once the file is moved away it starts.
        name = '/repeat/leftover_recorder'
        path = os.path.join(self.tmp, 'leftover_map.bag')
        fx.write_bag(path + '.active', 'keyframes', [self.good(0)])
        self.load_recorder(name, {'map': path, 'autostart': False})
        try:
            fx.wait_for_service(name + '/start')
            refused = rospy.ServiceProxy(name + '/start', Trigger)()
            self.assertFalse(refused.success, refused.message)
            self.assertIn("cannot record %s: '%s.active' exists" % (path, path), refused.message)
            os.rename(path + '.active', path + '.recovered')
            started = rospy.ServiceProxy(name + '/start', Trigger)()
            self.assertTrue(started.success, started.message)
            self.assertEqual(started.message, 'started recording ' + path)
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
            fx.remove(path, path + '.recovered')

    def test_a_recorder_whose_map_folder_is_missing_refuses_to_start(self):
        # The folder was found missing only at the first keyframe: ~start said success and the whole teach
        # was lost. ~start now refuses, naming the folder; once it exists, recording starts. Nor does the
        # recorder subscribe to its images before then (with ~autostart too): a `rosbag play
        # --wait-for-subscribers` played the whole teach into it while it could not record.
        name = '/repeat/nofolder_recorder'
        folder = os.path.join(self.tmp, 'not_yet')
        path = os.path.join(folder, 'map.bag')
        topic = '/nofolder_test/image_preprocessed'
        frames = rospy.Publisher(topic, Image, queue_size=1)
        self.load_recorder(name, {'map': path}, topic, records=False)
        try:
            fx.wait_for_service(name + '/start')
            text = "Nothing will be recorded until ~start succeeds: the folder '%s' of map file" % folder
            fx.wait_for(lambda: self.rosout.matching(text, Log.ERROR), 10, 'a message starting %r' % text)
            time.sleep(1.0)
            self.assertEqual(frames.get_num_connections(), 0, 'a recorder that cannot record subscribed')
            refused = rospy.ServiceProxy(name + '/start', Trigger)()
            self.assertFalse(refused.success, refused.message)
            self.assertEqual(refused.message, "cannot record %s: the folder '%s' of map file '%s' does not exist; "
                                              "create it" % (path, folder, path))
            os.makedirs(folder)
            started = rospy.ServiceProxy(name + '/start', Trigger)()
            self.assertTrue(started.success, started.message)
            self.assertEqual(started.message, 'started recording ' + path)  # it said "already recording"
            fx.wait_for(lambda: frames.get_num_connections() > 0, 10, 'the recorder to subscribe once started')
            again = rospy.ServiceProxy(name + '/start', Trigger)()  # it said "started" again
            self.assertEqual((again.success, again.message), (True, 'already recording ' + path))
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
            shutil.rmtree(folder, ignore_errors=True)

    def test_a_recorder_does_not_record_frames_stamped_before_its_last_keyframe(self):
        # A looping `rosbag play` of the teach drive recorded the route three times over without a word,
        # and the repeat then found every place three times and went lost. Frames stamped before the
        # last keyframe are not recorded, and ~finish says how many and why. (Its own topic: the
        # localizer would take the stamps going back for a looping bag of its own.)
        name = '/repeat/loop_recorder'
        path = os.path.join(self.tmp, 'loop_map.bag')
        try:
            publish = self.load_recorder(name, {'map': path}, '/loop_test/image_preprocessed', seed=4)
            stamps = (100.0, 100.1, 100.2, 100.0, 100.1)  # the drive, then the same drive again
            for stamp in stamps:
                publish(stamp)
            fx.wait_for(lambda: self.rosout.matching('Not recording frames stamped before the last keyframe',
                                                     Log.WARN), 10, 'the recorder to say time went back')
            seen = self.diagnostics.next_status(
                'repeat/loop_recorder: recording',
                lambda s: fx.status_values(s)['frames seen while recording'] == str(len(stamps)),
                'the recorder to have seen every frame')
            self.assertEqual(fx.status_values(seen)['keyframes taken'], '3')
            finish = rospy.ServiceProxy(name + '/finish', Trigger)()
            self.assertTrue(finish.success, finish.message)
            self.assertIn('map %s holds 3 keyframes; not recorded: 2 of the 5 frames seen while recording' % path,
                          finish.message)
            self.assertIn('time went back', finish.message)
            keyframes, _ = fx.map_keyframes(path)
            self.assertEqual([round(k.header.stamp.to_sec(), 3) for k in keyframes], [100.0, 100.1, 100.2])
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
            fx.remove(path)

    def test_a_map_folder_gone_mid_teach_is_said_once_and_its_keyframes_counted_as_lost(self):
        # A flush that failed was retried at once, forever: 125 804 errors in 6.6 s, the manager at full CPU.
        # Now it is said once and retried every flush_period; ~finish says which keyframes were not written.
        name = '/repeat/gone_recorder'
        folder = os.path.join(self.tmp, 'gone')
        os.makedirs(folder)
        path = os.path.join(folder, 'map.bag')
        try:
            publish = self.load_recorder(name, {'map': path, 'flush_period': 0.1}, '/gone_test/image_preprocessed',
                                         seed=5)
            publish(200.0)
            publish(200.1)
            self.diagnostics.next_status('repeat/gone_recorder: recording',
                                         lambda s: fx.status_values(s)['keyframes written'] == '2',
                                         'the first two keyframes written')
            shutil.rmtree(folder)
            publish(200.2)
            publish(200.3)
            time.sleep(2.0)  # 20 flush periods
            errors = self.rosout.matching('Map %s: ' % path, Log.ERROR)
            self.assertTrue(1 <= len(errors) <= 2, '%d errors: %s' % (len(errors), errors[:3]))
            finish = rospy.ServiceProxy(name + '/finish', Trigger)()
            self.assertFalse(finish.success, finish.message)
            self.assertIn('2 of the 4 keyframes taken were not written', finish.message)
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
            shutil.rmtree(folder, ignore_errors=True)

    def test_a_transports_topic_given_as_the_image_is_named(self):
        # image:=/camera/image_raw/compressed: every message was dropped for its type, and the preprocessor
        # said nothing (its diagnostics waited for images).
        name = '/repeat/compressed_preprocessor'
        loaded = rospy.ServiceProxy(MANAGER + '/load_nodelet', NodeletLoad)(
            name, 'along_route_localization/preprocessor', ['/repeat/image', '/repeat/image_preprocessed'],
            ['/some_camera/image_raw/compressed', '/compressed_test/image_preprocessed'], [], '')
        self.assertTrue(loaded.success)
        try:
            text = ("The image topic /some_camera/image_raw/compressed is the 'compressed' transport of "
                    "/some_camera/image_raw, which this nodelet cannot read as an image: give the base topic "
                    "(image:=/some_camera/image_raw) and set ~image_transport to compressed")
            fx.wait_for(lambda: self.rosout.matching(text, Log.ERROR), 10, 'the preprocessor to name the transport')
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)

    def test_a_transport_whose_plugin_is_missing_is_named_and_the_manager_lives_on(self):
        # ~image_transport compressed without compressed_image_transport installed: image_transport threw when
        # the preprocessor subscribed (on its first subscriber), and the exception ended the whole manager (a
        # new user's teach.launch). Now each nodelet names the transport at load and takes no images; the
        # manager and the nodelets in it go on. (A name no plugin has: the same path wherever this runs.)
        missing = "~image_transport 'no_such_transport' cannot be used: image_transport cannot load its plugin"
        said_before = len(self.rosout.matching(missing, Log.ERROR))
        pre, rec = '/repeat/transport_preprocessor', '/repeat/transport_recorder'
        rospy.set_param(pre + '/image_transport', 'no_such_transport')
        output = '/transport_test/image_preprocessed'
        loaded = rospy.ServiceProxy(MANAGER + '/load_nodelet', NodeletLoad)(
            pre, 'along_route_localization/preprocessor', ['/repeat/image', '/repeat/image_preprocessed'],
            ['/repeat_camera/image_raw', output], [], '')
        self.assertTrue(loaded.success)
        downstream = fx.Collector(output, Image)  # a subscriber: the preprocessor subscribes to its camera now
        try:
            self.load_recorder(rec, {'map': os.path.join(self.tmp, 'transport_map.bag'), 'autostart': True,
                                     'image_transport': 'no_such_transport'})
            fx.wait_for_service(rec + '/start')
            fx.wait_for(lambda: len(self.rosout.matching(missing, Log.ERROR)) >= said_before + 2, 10,
                        'both nodelets to name the transport')
            status = self.diagnostics.next_status('repeat/transport_preprocessor: preprocessing', lambda s: True,
                                                  'the preprocessor to report')
            self.assertEqual(status.level, DiagnosticStatus.ERROR)
            self.assertIn('not subscribed to /repeat_camera/image_raw: ' + missing, status.message)
            refused = rospy.ServiceProxy(rec + '/start', Trigger)()
            self.assertFalse(refused.success, refused.message)
            self.assertIn('cannot take images from /repeat/image_preprocessed: ' + missing, refused.message)
            # The manager lives: the repeat's own chain still localizes a frame published now.
            before = len(self.localizations.snapshot())
            self.camera.publish(self.good(3))
            fx.wait_for(lambda: len(self.localizations.snapshot()) > before, 20, 'a localization after the loads')
            self.assertEqual(downstream.snapshot(), [])
        finally:
            downstream.subscriber.unregister()
            for name in (pre, rec):
                rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
                rospy.delete_param(name)

    def test_a_motion_topic_of_another_type_is_named_and_finish_says_the_map_has_no_taught_motion(self):
        # motion:=/ground_truth/odom with motion_type twist: roscpp dropped the connection with a line in the
        # publisher's log only; ~finish said "holds 3 keyframes" as for a good map, and the follower refused it
        # later. Now the recorder names the topic's type while recording, and ~finish says so.
        from nav_msgs.msg import Odometry
        name, motion = '/repeat/wrongtype_recorder', '/wrongtype_test/odom'
        odometry = rospy.Publisher(motion, Odometry, queue_size=1, latch=True)
        odometry.publish(Odometry())
        path = os.path.join(self.tmp, 'wrongtype_map.bag')
        try:
            publish = self.load_recorder(name, {'map': path, 'motion_type': 'twist'},
                                         '/wrongtype_test/image_preprocessed', seed=4,
                                         remaps=[('/repeat/motion', motion)])
            for k in range(3):
                publish(7000.0 + k)
            problem = ('the motion topic %s carries nav_msgs/Odometry, not the geometry_msgs/Twist ~motion_type '
                       'twist reads (~motion_type odometry reads it): no motion message can come' % motion)
            fx.wait_for(lambda: self.rosout.matching('The keyframes get no taught motion: ' + problem, Log.ERROR),
                        15, 'the recorder to name the motion topic\'s type')
            finished = rospy.ServiceProxy(name + '/finish', Trigger)()
            self.assertTrue(finished.success, finished.message)
            self.assertIn('; no keyframe has taught motion (%s): it localizes, but the route follower refuses it'
                          % problem, finished.message)
        finally:
            odometry.unregister()
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
            rospy.delete_param(name)
            fx.remove(path)

    def test_a_recorders_autostart_given_as_0_or_maybe_is_read_or_named(self):
        # teach.launch autostart:=0 reached the recorder as the integer 0, which it ignored without a word:
        # it recorded from the first frame. 0 is false now; a value that is no bool is named.
        for given, state, words in ((0, 'idle: call ~start to record', None),
                                    ('maybe', 'recording, waiting for images on /autostart_test/image_preprocessed',
                                     "~autostart = 'maybe' is not true or false; using true")):
            name = '/repeat/autostart_recorder'
            try:
                self.load_recorder(name, {'map': os.path.join(self.tmp, 'autostart_map.bag'), 'autostart': given},
                                   '/autostart_test/image_preprocessed', records=given != 0)
                status = self.diagnostics.next_status('repeat/autostart_recorder: recording', lambda s: True,
                                                      'the recorder to report (autostart %r)' % given)
                self.assertEqual(status.message, state)
                if words:
                    fx.wait_for(lambda: self.rosout.matching(words, Log.ERROR), 10, 'a message %r' % words)
            finally:
                rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
                rospy.delete_param(name)

    def test_a_recorders_static_numbers_of_the_wrong_type_are_named(self):
        # ~queue_size 2.5 was read as 3 and ~flush_period 'soon' ignored, without a word: each is named
        # with the value kept, and the recorder records.
        name = '/repeat/typed_recorder'
        try:
            self.load_recorder(name, {'map': os.path.join(self.tmp, 'typed_map.bag'), 'queue_size': 2.5,
                                      'flush_period': 'soon', 'max_queue': True}, '/typed_test/image_preprocessed')
            for words in ('~queue_size = 2.5 is not an integer; refused, keeping 100',
                          "~flush_period = 'soon' is not a number; refused, keeping 1",
                          '~max_queue = true is not an integer; refused, keeping '):
                fx.wait_for(lambda: self.rosout.matching(words, Log.ERROR), 10, 'a message %r' % words)
            status = self.diagnostics.next_status('repeat/typed_recorder: recording', lambda s: True,
                                                  'the recorder to report')
            self.assertEqual(status.message, 'recording, waiting for images on /typed_test/image_preprocessed')
            # The parameter server shows the values kept, as for the dynamic parameters.
            self.assertEqual(rospy.get_param(name + '/queue_size'), 100)
            self.assertEqual(rospy.get_param(name + '/flush_period'), 1.0)
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
            rospy.delete_param(name)

    def test_a_map_path_that_is_not_a_string_is_named(self):
        # ~map: 2024 (YAML reads it as a number) was ignored without a word; the localizer then said only
        # that no ~map was set.
        name = '/repeat/numbered_localizer'
        self.load_localizer(name, {'map': 2024}, '/repeat/numbered_localization')
        try:
            words = '~map = 2024 is not a string; ignored'
            fx.wait_for(lambda: self.rosout.matching(words, Log.ERROR), 10, 'a message %r' % words)
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
            rospy.delete_param(name)

    def test_a_refusal_that_ends_mid_drive_does_not_restart_at_the_route_start(self):
        # Issue 33: after the preprocessing was changed and set back mid-drive, the localizer started
        # over at keyframe 0 (start_keyframe) and said tracking there for about 10 frames. The robot is
        # further along: the place is unknown, a global search (initializing) until one is confirmed.
        first = self.send_good(range(0, 20))
        self.wait_for_stamp(self.localizations, first[-1].header.stamp, 'the first half of the drive')
        preprocessor = ReconfigureClient('/repeat/preprocessor', timeout=30)
        preprocessor.update_configuration({'sky_fraction': 0.25})
        try:
            refused = self.send_good([20])
            self.wait_for_stamp(self.preprocessed, refused[0].header.stamp, 'a frame made with sky_fraction 0.25')
        finally:
            preprocessor.update_configuration({'sky_fraction': 0.0})
        second = self.send_good(range(21, FRAMES))
        self.wait_for_stamp(self.localizations, second[-1].header.stamp, 'the second half of the drive')
        after = [m for m in self.localizations.snapshot() if m.header.stamp >= second[0].header.stamp]
        answers = [(m.status, m.keyframe) for m in after]
        self.assertEqual(after[0].status, Localization.STATUS_INITIALIZING, answers)
        self.assertEqual([a for a in answers if a[0] == Localization.STATUS_TRACKING and a[1] < 15], [], answers)

    def test_a_map_loaded_mid_drive_starts_from_an_unknown_place(self):
        # A ~load_map while the images came (a new user's repeat at keyframe 56) started at start_keyframe 0 and
        # answered keyframes 0-35 at "tracking" for 3.5 s. Mid-drive the place is unknown: a global search. A
        # load once the images have stopped for longer than the period of ~min_rate (1 Hz) is a next drive.
        load_map = rospy.ServiceProxy('/repeat/localizer/load_map', LoadMap)
        first = self.send_good(range(0, 20))
        self.wait_for_stamp(self.localizations, first[-1].header.stamp, 'the first half of the drive')
        loaded = load_map(self.map_path)
        self.assertTrue(loaded.success, loaded.message)
        self.assertIn('; localizing from an unknown place (a global search), since it was loaded mid-drive',
                      loaded.message)
        second = self.send_good(range(20, FRAMES))
        self.wait_for_stamp(self.localizations, second[-1].header.stamp, 'the second half of the drive')
        after = [m for m in self.localizations.snapshot() if m.header.stamp >= second[0].header.stamp]
        answers = [(m.status, m.keyframe) for m in after]
        self.assertEqual(after[0].status, Localization.STATUS_INITIALIZING, answers)
        self.assertEqual([a for a in answers if a[0] == Localization.STATUS_TRACKING and a[1] < 15], [], answers)
        time.sleep(1.5)  # no image for longer than 1 / min_rate
        between = load_map(self.map_path)
        self.assertTrue(between.success, between.message)
        self.assertNotIn('mid-drive', between.message)

    def test_frames_smaller_than_the_output_pass_enlarged_with_a_warning(self):
        dot = self.stamped(image('mono8', 1, 1, b'\x80'))
        self.camera.publish(dot)
        self.wait_for_stamp(self.preprocessed, dot.header.stamp, 'the enlarged frame')
        words = "a 1x1 'mono8' image smaller than the 64x32 output: enlarged"
        fx.wait_for(lambda: self.rosout.matching('Using ' + words), 10, 'the warning')
        said = self.diagnostics.next_status('repeat/preprocessor: preprocessing', lambda s: words in s.message,
                                            'the preprocessor diagnostics saying so')
        self.assertEqual(said.level, DiagnosticStatus.WARN)

    def test_frames_of_another_size_than_the_map_are_refused(self):
        small = self.stamped(image('mono8', 32, 16, bytes(32 * 16)))
        self.direct.publish(small)
        fx.wait_for(lambda: self.rosout.matching('Dropping a 32x16'), 10, 'an error naming the size')
        good = self.good(7)
        self.camera.publish(good)
        self.wait_for_stamp(self.localizations, good.header.stamp, 'a localization after the refused frame')
        self.assertFalse([m for m in self.localizations.snapshot() if m.header.stamp == small.header.stamp])

    def test_a_burst_keeps_its_newest_frame_in_order(self):
        self.localizations.take()
        burst = [self.good(i) for i in range(300)]
        for msg in burst:
            self.camera.publish(msg)
        self.wait_for_stamp(self.localizations, burst[-1].header.stamp, 'the newest frame of the burst')
        stamps = [m.header.stamp for m in self.localizations.take()]
        self.assertEqual(stamps, sorted(stamps))
        self.assertLessEqual(len(stamps), len(burst))
        self.assertEqual(stamps[-1], burst[-1].header.stamp)

    def test_map_made_with_other_preprocessing_is_refused_until_they_match(self):
        preprocessor = ReconfigureClient('/repeat/preprocessor', timeout=30)
        preprocessor.update_configuration({'sky_fraction': 0.25})
        try:
            other = self.good(11)
            self.camera.publish(other)
            self.wait_for_stamp(self.preprocessed, other.header.stamp, 'a frame made with sky_fraction 0.25')
            fx.wait_for(lambda: self.rosout.matching('other preprocessing parameters'), 10,
                        'an error saying the map was made with other parameters')
            self.assertTrue([m for m in self.rosout.matching('other preprocessing parameters') if 'sky_fraction' in m.msg])
            time.sleep(0.5)
            self.assertFalse([m for m in self.localizations.snapshot() if m.header.stamp == other.header.stamp])
        finally:
            preprocessor.update_configuration({'sky_fraction': 0.0})
        again = self.good(12)
        self.camera.publish(again)
        self.wait_for_stamp(self.localizations, again.header.stamp, 'localizations once the parameters match again')

    def test_new_preprocessing_is_announced_before_any_image(self):
        # The preprocessor announced new parameters only with the next image, and a localizer without a map
        # subscribes to no image, so none came: a map made with the new parameters was refused, quoting the
        # old ones, until a relaunch. Here no frame is published while the parameters change.
        sky_map = os.path.join(self.tmp, 'sky_map.bag')
        with rosbag.Bag(self.map_path) as source, rosbag.Bag(sky_map, 'w') as target:
            for topic, msg, t in source.read_messages():
                if topic == 'preprocessing':
                    msg.data = re.sub(r'sky_fraction=[^;]*', 'sky_fraction=0.25', msg.data)
                target.write(topic, msg, t)
        name = '/repeat/mapless_localizer'
        rospy.set_param(name + '/map', '')
        loaded = rospy.ServiceProxy(MANAGER + '/load_nodelet', NodeletLoad)(
            name, 'along_route_localization/localizer', [], [], [], '')
        self.assertTrue(loaded.success)
        preprocessor = ReconfigureClient('/repeat/preprocessor', timeout=30)
        try:
            fx.wait_for_service(name + '/load_map')
            load_map = rospy.ServiceProxy(name + '/load_map', LoadMap)
            refused = load_map(sky_map)
            self.assertFalse(refused.success)
            self.assertIn('sky_fraction', refused.message)
            preprocessor.update_configuration({'sky_fraction': 0.25})
            fx.wait_for(lambda: load_map(sky_map).success, 10, 'the map made with sky_fraction 0.25 to load')
        finally:
            preprocessor.update_configuration({'sky_fraction': 0.0})
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)
        again = self.good(13)
        self.camera.publish(again)
        self.wait_for_stamp(self.localizations, again.header.stamp, 'localizations with sky_fraction 0 again')

    def test_an_even_filter_window_is_corrected_by_the_core_rule(self):
        # The nodelet and localize_offline's parameter files share PreprocessingParams::correctCombinations.
        preprocessor = ReconfigureClient('/repeat/preprocessor', timeout=30)
        try:
            corrected = preprocessor.update_configuration({'filter_window': 8})
            self.assertEqual(corrected['filter_window'], 9)
        finally:
            preprocessor.update_configuration({'filter_window': 7})
        again = self.good(14)
        self.camera.publish(again)
        self.wait_for_stamp(self.localizations, again.header.stamp, 'localizations with filter_window 7 again')

    def test_localizer_unloaded_and_loaded_again(self):
        unloaded = rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)('/repeat/localizer')
        self.assertTrue(unloaded.success)
        probe = self.good(3)
        self.camera.publish(probe)
        self.wait_for_stamp(self.preprocessed, probe.header.stamp, 'the preprocessor to go on alone')
        time.sleep(0.5)
        self.assertFalse([m for m in self.localizations.snapshot() if m.header.stamp == probe.header.stamp])
        loaded = rospy.ServiceProxy(MANAGER + '/load_nodelet', NodeletLoad)(
            '/repeat/localizer', 'along_route_localization/localizer', [], [], [], '')
        self.assertTrue(loaded.success)
        fx.wait_for_service('/repeat/localizer/load_map')
        self.assertTrue(rospy.ServiceProxy('/repeat/localizer/load_map', LoadMap)(self.map_path).success)
        self.drive_teach_frames(self.localizations, 'localizations from the reloaded localizer', count=20)

    def load_recorder(self, name, params, topic=None, seed=0, records=True, remaps=()):
        """Loads a map recorder `name` into the running manager with the private parameters `params` (`map`
        among them). With `topic`, it records that topic instead of /repeat/image_preprocessed (frames a test
        stamps as it likes then reach no localizer), the repeat preprocessor's parameters announced beside
        it; it returns a function that publishes a random 64x32 mono8 frame there at a stamp (s). A recorder
        subscribes to its images once it records (`records`: at load)."""
        for key, value in params.items():
            rospy.set_param(name + '/' + key, value)
        remap_from, remap_to = [], []
        if topic:
            announced = rospy.wait_for_message('/repeat/preprocessing_params', String, timeout=10)
            announcer = rospy.Publisher(topic.rsplit('/', 1)[0] + '/preprocessing_params', String, queue_size=1,
                                        latch=True)
            announcer.publish(announced)
            self.announcers.append(announcer)  # latched: kept for the recorder
            frames = rospy.Publisher(topic, Image, queue_size=100)
            remap_from, remap_to = ['/repeat/image_preprocessed'], [topic]
        remap_from += [a for a, _ in remaps]
        remap_to += [b for _, b in remaps]
        loaded = rospy.ServiceProxy(MANAGER + '/load_nodelet', NodeletLoad)(
            name, 'along_route_localization/map_recorder', remap_from, remap_to, [], '')
        self.assertTrue(loaded.success)
        if not topic:
            return None
        if records:
            fx.wait_for(lambda: frames.get_num_connections() > 0, 10, 'the recorder to subscribe')
        rng = np.random.RandomState(seed)

        def publish(stamp):
            msg = image('mono8', 64, 32, rng.randint(0, 256, 64 * 32).astype(np.uint8).tobytes())
            msg.header.stamp = rospy.Time.from_sec(stamp)
            frames.publish(msg)
            time.sleep(0.05)
        return publish

    def load_localizer(self, name, params, output):
        """Loads another localizer `name` into the running manager, with the map and the private
        parameters `params`; its answers are collected from `output`."""
        rospy.set_param(name + '/map', self.map_path)
        for key, value in params.items():
            rospy.set_param(name + '/' + key, value)
        answers = fx.Collector(output, Localization, queue_size=1000)
        loaded = rospy.ServiceProxy(MANAGER + '/load_nodelet', NodeletLoad)(
            name, 'along_route_localization/localizer', ['/repeat/localization'], [output], [], '')
        self.assertTrue(loaded.success)
        return answers

    def drive_teach_frames(self, answers, what, count=FRAMES):
        """Sends `count` teach frames through the preprocessor once a new localizer listens; the statuses
        collected in `answers`."""
        fx.wait_for(lambda: self.camera.get_num_connections() > 0, 10, 'the preprocessor')
        time.sleep(1.0)  # the new localizer's subscription to image_preprocessed
        sent = [self.good(i) for i in range(count)]
        for msg in sent:
            self.camera.publish(msg)
            time.sleep(0.05)
        self.wait_for_stamp(answers, sent[-1].header.stamp, what)
        return [m.status for m in answers.snapshot()]

    def test_a_start_beyond_the_map_is_unknown_with_a_warning(self):
        # ~start_keyframe given for a longer route: this map keeps working, with the start unknown (a
        # global search first, status initializing), and the warning names the value and the map.
        name = '/repeat/start_localizer'
        answers = self.load_localizer(name, {'start_keyframe': 1000}, '/repeat/start_localization')
        try:
            text = '~start_keyframe = 1000 is beyond map %s' % self.map_path
            fx.wait_for(lambda: self.rosout.matching(text), 10, 'a message starting %r' % text)
            statuses = self.drive_teach_frames(answers, 'localizations from the started localizer')
            self.assertEqual(statuses[0], Localization.STATUS_INITIALIZING, statuses)
            self.assertIn(Localization.STATUS_TRACKING, statuses)
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)

    def test_static_parameters_are_checked_one_by_one(self):
        # A second localizer in the running manager, given valid static parameters, one outside its range,
        # one that does not parse, a dynamic one outside its range, one misspelt and one that is the
        # preprocessor's: the valid ones apply (before, one bad value reset them all to the defaults), and
        # each of the others is named with the value used (before, all but one were ignored or clamped
        # without a word).
        name = '/repeat/checked_localizer'
        checked = self.load_localizer(name, {
            'start_keyframe': -1,  # the start unknown: a global search, and
            'min_init_frames': 25,  # (default 5) tracking from about frame 10
            'exclusion_radius': -1,
            'cost_function': 'SAD',
            # Valid only together (the default minimum is 0.8): both must be taken.
            'seqslam_min_velocity': 0.1, 'seqslam_max_velocity': 0.5,
            'max_step': 0,
            # A fraction for an integer: roscpp would read it rounded (13) under a log saying 30 is kept.
            'ring_buffer_rows': 12.7,
            # The static ones the same: param<int> read 2.5 as 3, param<double> and param<bool> ignored a
            # string, each without a word.
            'debug_image_scale': 2.5, 'min_rate': 'fast', 'report_input_buffer': 'maybe',
            # Taken as given: an integer for a number, a whole number for an integer (roscpp reads both).
            'max_rate': 500, 'search_radius': 20.0,
            'ring_bufer_rows': 10,
            'normalization_strength': 0.2,
            'motion_type': 'odom',
        }, '/repeat/checked_localization')
        try:
            for text in ('~exclusion_radius -1 is outside 1 .. 1000000 keyframes; using 1',
                         "~motion_type 'odom' is not one of none | twist | odometry; using none: the images alone",
                         "~cost_function 'SAD' is not one of sad | census; keeping sad",
                         'max_step 0 is outside 1 .. 16 keyframes per frame; using 1',
                         '~ring_buffer_rows = 12.7 is not an integer; refused, keeping 30',
                         '~debug_image_scale = 2.5 is not an integer; refused, keeping 8',
                         "~min_rate = 'fast' is not a number; refused, keeping 1",
                         "~report_input_buffer = 'maybe' is not true or false; using false",
                         '~ring_bufer_rows is not a parameter of the localizer and is ignored (did you mean '
                         'ring_buffer_rows?). It reads: ',
                         "~normalization_strength is not read here: it is the preprocessor's"):
                fx.wait_for(lambda: self.rosout.matching(text), 10, 'a message starting %r' % text)
            self.assertEqual(self.rosout.matching('Ignoring ~seqslam'), [])
            # The value the log says is kept is the one used (the reconfigure server writes it back).
            self.assertEqual(rospy.get_param(name + '/ring_buffer_rows'), 30)
            self.assertEqual(rospy.get_param(name + '/debug_image_scale'), 8)
            self.assertEqual(rospy.get_param(name + '/search_radius'), 20)
            self.assertEqual(self.rosout.matching('~max_rate'), [])
            self.assertEqual(self.rosout.matching('~search_radius'), [])
            # What is used is said once: the corrected value, the values taken.
            self.assertTrue(self.rosout.matching('exclusion_radius 5 -> 1'))
            self.assertTrue(self.rosout.matching('min_init_frames 5 -> 25'))
            statuses = self.drive_teach_frames(checked, 'localizations from the checked localizer')
            self.assertGreaterEqual(len(statuses), 30)
            first_tracking = statuses.index(Localization.STATUS_TRACKING)
            self.assertGreaterEqual(first_tracking + (FRAMES - len(statuses)), 24, statuses)
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)

if __name__ == '__main__':
    rostest.rosrun('along_route_localization', 'robustness', RobustnessTest)
