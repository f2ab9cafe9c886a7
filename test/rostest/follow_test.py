#!/usr/bin/python3
"""Follow: teach.launch records the taught motion from cmd_vel into the map; follow.launch's route_follower
drives from Localization messages (published here) with it: the command worked out by hand, the watchdog,
stop on lost, slow then stop on low confidence, stop on a localization from another map, stop at the end
of the route, the services,
dynamic_reconfigure, and a map without taught motion refused with a clear error."""

import os
import shutil
import threading
import time
import unittest

import rosbag
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticStatus
from dynamic_reconfigure.client import Client as ReconfigureClient
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from nodelet.srv import NodeletLoad, NodeletUnload
from sensor_msgs.msg import Image
from std_srvs.srv import Trigger

from along_route_localization.msg import KeyframeMotion, Localization
import route_fixture as fx

FRAMES = 40
TAUGHT_LINEAR, TAUGHT_ANGULAR = 0.5, 0.125   # the cmd_vel published during the teach (exact in binary)
FOLLOWER = '/follow/route_follower'
MANAGER = '/follow/repeat_manager'
DIAGNOSTIC = 'follow/route_follower: following'
EPS = 1e-6


class OdometryPublisher(object):
    """The teach robot's odometry at 20 Hz: 0.5 m/s and 0.125 rad/s in its twist, poses 0.25 m apart
    along x (exact in binary, so every distance the recorder sums from them is a whole multiple)."""

    def __init__(self, topic):
        self.publisher = rospy.Publisher(topic, Odometry, queue_size=100)
        self.running = True
        self.thread = threading.Thread(target=self._run)
        self.thread.daemon = True
        self.thread.start()

    def _run(self):
        rate = rospy.Rate(20.0)
        step = 0
        while self.running and not rospy.is_shutdown():
            msg = Odometry()
            msg.header.stamp = rospy.Time.now()
            msg.pose.pose.position.x = 0.25 * step
            msg.pose.pose.orientation.w = 1.0
            msg.twist.twist.linear.x, msg.twist.twist.angular.z = TAUGHT_LINEAR, TAUGHT_ANGULAR
            self.publisher.publish(msg)
            step += 1
            rate.sleep()


class Repeater(object):
    """Publishes a message at a fixed rate from a thread while one is set."""

    def __init__(self, topic, msg_type, rate_hz):
        self.publisher = rospy.Publisher(topic, msg_type, queue_size=10)
        self.lock = threading.Lock()
        self.message = None
        self.rate_hz = rate_hz
        self.thread = threading.Thread(target=self._run)
        self.thread.daemon = True
        self.thread.start()

    def set(self, message):
        with self.lock:
            self.message = message

    def _run(self):
        rate = rospy.Rate(self.rate_hz)
        while not rospy.is_shutdown():
            with self.lock:
                message = self.message
            if message is not None:
                if hasattr(message, 'header'):
                    message.header.stamp = rospy.Time.now()
                self.publisher.publish(message)
            rate.sleep()


def localization(status=Localization.STATUS_TRACKING, keyframe=10, confidence=0.9, homing_angle=0.1):
    msg = Localization()
    msg.status, msg.keyframe, msg.confidence, msg.homing_angle = status, keyframe, confidence, homing_angle
    msg.query_informative = True
    return msg


class FollowTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        fx.set_up_route(cls, 'follow_test', FRAMES, 'along_route_follow_test_')
        cls.map_path = rospy.get_param('~map')
        cls.map_odom_path = rospy.get_param('~map_odom')
        cls.map_manual_path = rospy.get_param('~map_manual')
        cls.diagnostics = fx.DiagnosticsCollector()
        cls.rosout = fx.RosoutCollector()
        cls.commands = fx.Collector('/follow/cmd_vel', Twist, queue_size=10000)
        cls.localizations = Repeater('/follow/localization', Localization, 10.0)

        # Before the map exists the follower cannot drive, and says why.
        fx.wait_for_service(FOLLOWER + '/start')
        cls.start_without_map = rospy.ServiceProxy(FOLLOWER + '/start', Trigger)()

        # Teach while the robot's cmd_vel is published; once the recorder has heard it, every keyframe
        # gets the taught motion.
        cmd_vel = Twist()
        cmd_vel.linear.x, cmd_vel.angular.z = TAUGHT_LINEAR, TAUGHT_ANGULAR
        cls.teach_cmd_vel = Repeater('/teach/cmd_vel', Twist, 20.0)
        cls.teach_cmd_vel.set(cmd_vel)
        cls.teach_odom = OdometryPublisher('/teach_odom/odom')
        for ns in ('teach', 'teach_odom'):
            fx.wait_for_service('/%s/map_recorder/finish' % ns)
            cls.diagnostics.next_status('%s/map_recorder: recording' % ns,
                                        lambda s: int(fx.status_values(s)['motion messages']) > 0,
                                        '%s/map_recorder to hear the motion' % ns, timeout=30)
        # The manual teach's robot backs up at 0.5 m/s, turning the other way, before ~start; then drives
        # as the others do.
        reverse = Twist()
        reverse.linear.x, reverse.angular.z = -TAUGHT_LINEAR, -TAUGHT_ANGULAR
        cls.teach_manual_cmd_vel = Repeater('/teach_manual/cmd_vel', Twist, 20.0)
        cls.teach_manual_cmd_vel.set(reverse)
        fx.wait_for_service('/teach_manual/map_recorder/start')
        cls.diagnostics.next_status('teach_manual/map_recorder: recording',
                                    lambda s: int(fx.status_values(s)['motion messages']) >= 20,
                                    'teach_manual/map_recorder to hear the robot back up', timeout=30)
        cls.teach_manual_cmd_vel.set(None)
        rospy.sleep(0.2)
        cls.start_manual = rospy.ServiceProxy('/teach_manual/map_recorder/start', Trigger)()
        # Its first command after ~start only once the recorder has its first 3 frames (queued before this
        # test saw the third): keyframes 0-2 come with no motion heard while recording.
        manual_frames = []

        def drive_after_three(msg):
            manual_frames.append(msg.header.stamp)
            if len(manual_frames) == 3:
                cls.teach_manual_cmd_vel.set(cmd_vel)
        cls.manual_frames = rospy.Subscriber('/teach_manual/image_preprocessed', Image, drive_after_three)
        fx.wait_for(lambda: cls.manual_frames.get_num_connections() > 0, 30, 'the manual teach\'s frames')
        preprocessed = fx.Collector('/teach/image_preprocessed', Image)
        fx.play(os.path.join(cls.tmp, 'teach.bag'), {fx.CAMERA_TOPIC: '/teach_camera/image_raw'})
        fx.wait_for(lambda: preprocessed.count() >= FRAMES, 60, 'the teach drive to be preprocessed')
        cls.finish = rospy.ServiceProxy('/teach/map_recorder/finish', Trigger)()
        cls.finish_odom = rospy.ServiceProxy('/teach_odom/map_recorder/finish', Trigger)()
        cls.finish_manual = rospy.ServiceProxy('/teach_manual/map_recorder/finish', Trigger)()
        cls.teach_cmd_vel.set(None)
        cls.teach_manual_cmd_vel.set(None)
        cls.teach_odom.running = False

    @classmethod
    def tearDownClass(cls):
        cls.localizations.set(None)
        shutil.rmtree(cls.tmp, ignore_errors=True)
        fx.remove(cls.map_path, cls.map_odom_path, cls.map_manual_path)

    def call(self, service):
        return rospy.ServiceProxy(FOLLOWER + '/' + service, Trigger)()

    def wait_for_command(self, linear, angular, what, timeout=10.0):
        """Until the newest cmd_vel is (linear, angular)."""
        def reached():
            latest = self.commands.snapshot()[-1:]
            return bool(latest) and abs(latest[0].linear.x - linear) < EPS and abs(latest[0].angular.z - angular) < EPS
        fx.wait_for(reached, timeout, '%s: cmd_vel (%g, %g)' % (what, linear, angular))

    def status(self, predicate, what):
        return self.diagnostics.next_status(DIAGNOSTIC, predicate, what)

    def drive(self, what):
        """Tracking at keyframe 10 with a homing angle of 0.1 rad: v = 1.0 x 0.5 = 0.5 m/s,
        w = 1.0 x 0.125 + 1.0 x 0.1 = 0.225 rad/s (gain 1, speed factor 1, no filter)."""
        self.localizations.set(localization())
        self.wait_for_command(TAUGHT_LINEAR, TAUGHT_ANGULAR + 0.1, what)

    def test_a_teach_records_one_motion_message_per_keyframe(self):
        self.assertTrue(self.finish.success, self.finish.message)
        with rosbag.Bag(self.map_path) as bag:
            keyframes = [m for _, m, _ in bag.read_messages(topics=['keyframes'])]
            motion = [m for _, m, _ in bag.read_messages(topics=['motion'])]
            self.assertEqual(bag.get_type_and_topic_info().topics['motion'].msg_type,
                             'along_route_localization/KeyframeMotion')
        self.assertEqual(len(keyframes), FRAMES)
        self.assertEqual([m.keyframe for m in motion], list(range(FRAMES)))
        self.assertEqual([m.header.stamp for m in motion], [k.header.stamp for k in keyframes])
        for m in motion:
            self.assertEqual((m.linear_mps, m.angular_rps), (TAUGHT_LINEAR, TAUGHT_ANGULAR))
        # Distance since the previous keyframe: none before the first; the robot moved during the teach.
        self.assertEqual(motion[0].distance_m, 0.0)
        self.assertTrue(all(m.distance_m >= 0.0 for m in motion), [m.distance_m for m in motion])
        self.assertGreater(sum(m.distance_m for m in motion), 0.0)

    def test_a_teach_records_the_motion_from_odometry(self):
        self.assertTrue(self.finish_odom.success, self.finish_odom.message)
        with rosbag.Bag(self.map_odom_path) as bag:
            keyframes = [m for _, m, _ in bag.read_messages(topics=['keyframes'])]
            motion = [m for _, m, _ in bag.read_messages(topics=['motion'])]
        self.assertEqual(len(keyframes), FRAMES)
        self.assertEqual([m.keyframe for m in motion], list(range(FRAMES)))
        for m in motion:
            self.assertEqual((m.linear_mps, m.angular_rps), (TAUGHT_LINEAR, TAUGHT_ANGULAR))
        # The distances come from the poses (whole multiples of their 0.25 m spacing), not from the twist.
        self.assertEqual(motion[0].distance_m, 0.0)
        self.assertTrue(all(m.distance_m / 0.25 == round(m.distance_m / 0.25) for m in motion),
                        [m.distance_m for m in motion])
        self.assertGreater(sum(m.distance_m for m in motion), 0.0)

    def test_a_teach_records_only_the_motion_while_recording(self):
        # Before the fix, keyframe 0 held the mean of the 20+ messages backing up before ~start and the few
        # after it: a negative or small speed, which the follower would have driven at the start; then, with
        # no message after ~start yet, the last one from before it.
        self.assertTrue(self.start_manual.success, self.start_manual.message)
        self.assertTrue(self.finish_manual.success, self.finish_manual.message)
        with rosbag.Bag(self.map_manual_path) as bag:
            motion = [m for _, m, _ in bag.read_messages(topics=['motion'])]
        # Keyframes 0-2 (and maybe 3, taken before the first command reached the recorder) have no record:
        # the latest velocity then was the backing up before ~start (kept for keyframe 0-2 before the fix).
        recorded = [m.keyframe for m in motion]
        self.assertFalse(set(recorded) & {0, 1, 2}, recorded)
        self.assertTrue(set(range(5, FRAMES)) <= set(recorded), recorded)
        for m in motion:
            self.assertEqual((m.linear_mps, m.angular_rps), (TAUGHT_LINEAR, TAUGHT_ANGULAR))

    def test_b_follower_drives_stops_and_answers_its_services(self):
        self.assertFalse(self.start_without_map.success)
        self.assertIn('does not exist', self.start_without_map.message)

        # Not started (and no map read yet): localizations arrive, nothing is commanded.
        self.localizations.set(localization())
        idle = self.status(lambda s: int(fx.status_values(s)['localizations received']) > 0, 'localizations')
        self.assertEqual(fx.status_values(idle)['state'], 'no map')
        self.assertEqual(idle.level, DiagnosticStatus.ERROR)
        self.assertIn('will not drive: ', idle.message)
        self.assertEqual(fx.status_values(idle)['commands published'], '0')
        self.assertEqual(self.commands.count(), 0)

        # ~start reads the map taught since the follower started.
        started = self.call('start')
        self.assertTrue(started.success, started.message)
        self.assertEqual(started.message, 'started following')
        self.drive('following')

        # dynamic_reconfigure: half the speed, and half the taught turn rate: w = 0.5 x 0.125 + 0.1.
        reconfigure = ReconfigureClient(FOLLOWER, timeout=30)
        reconfigure.update_configuration({'speed_factor': 0.5})
        self.wait_for_command(0.5 * TAUGHT_LINEAR, 0.5 * TAUGHT_ANGULAR + 0.1, 'speed_factor 0.5')
        reconfigure.update_configuration({'speed_factor': 1.0})
        self.drive('speed_factor 1 again')

        # Watchdog: localizations stop coming, the robot stops; they come again, it drives again.
        said_before = len(self.rosout.matching('stopped: no localization for'))
        self.localizations.set(None)
        self.wait_for_command(0.0, 0.0, 'watchdog')
        stopped = self.status(lambda s: 'no localization' in s.message, 'the watchdog in the diagnostics')
        self.assertEqual(fx.status_values(stopped)['state'], 'following')
        time.sleep(1.0)  # 20 control ticks: the warning, whose seconds grow each tick, was logged at each
        said = self.rosout.matching('stopped: no localization for')[said_before:]
        self.assertEqual(len(said), 1, [m.msg for m in said])
        self.drive('localizations again')

        # Lost with the camera covered (a featureless view): stop at once, no creep.
        covered = localization(status=Localization.STATUS_LOST, keyframe=-1, confidence=0.0)
        covered.query_informative = False
        self.localizations.set(covered)
        self.wait_for_command(0.0, 0.0, 'lost, covered')
        self.status(lambda s: s.message.startswith('stopped: the localization is lost; the view is featureless'),
                    'featureless in the diagnostics')
        # Lost with views: creep at slow_factor (0.5) along the motion taught at keyframe 10 (the last one
        # tracked), without the homing term: (0.25, 0.0625); after recovery_distance (0.25 m here) stop.
        reconfigure.update_configuration({'recovery_distance': 0.25})
        self.localizations.set(localization(status=Localization.STATUS_LOST, keyframe=-1, confidence=0.0))
        self.wait_for_command(0.5 * TAUGHT_LINEAR, 0.5 * TAUGHT_ANGULAR, 'lost, creeping')
        self.wait_for_command(0.0, 0.0, 'lost, after the creep')
        self.status(lambda s: s.message.startswith('stopped: the localization is lost (crept '),
                    'the creep in the diagnostics')
        # The track found again: drive.
        self.drive('tracking again')

        # Low confidence (below 0.2): half the speed after 3 localizations, stopped after 8.
        first = self.commands.count()
        self.localizations.set(localization(confidence=0.05))
        self.wait_for_command(0.0, 0.0, 'low confidence')
        linear = [m.linear.x for m in self.commands.snapshot()[first:]]
        self.assertTrue(any(abs(v - 0.5 * TAUGHT_LINEAR) < EPS for v in linear), linear)
        self.drive('confident again')

        # ~pause, ~start resumes; ~stop, ~start again.
        paused = self.call('pause')
        self.assertTrue(paused.success, paused.message)
        self.wait_for_command(0.0, 0.0, 'paused')
        resumed = self.call('start')
        self.assertEqual((resumed.success, resumed.message), (True, 'resumed following'))
        self.drive('resumed')
        # A stop ramps down at max_linear_decel (0.1 m/s^2 here: 5 s from 0.5 m/s). Meanwhile the diagnostics
        # say the robot is still braking; at rest, that it stopped.
        reconfigure.update_configuration({'max_linear_decel': 0.1})
        stop = self.call('stop')
        self.assertTrue(stop.success, stop.message)
        braking = self.status(lambda s: s.message.startswith('braking to a stop: stopped by the stop service'),
                              'braking in the diagnostics')
        self.assertGreater(float(fx.status_values(braking)['linear command (m/s)']), 0.0)
        self.wait_for_command(0.0, 0.0, 'stopped')
        self.status(lambda s: s.message.startswith('stopped by the stop service'), 'at rest in the diagnostics')
        reconfigure.update_configuration({'max_linear_decel': 2.0})
        self.assertFalse(self.call('stop').success)
        self.assertTrue(self.call('start').success)
        self.drive('started again')

        # A localization from another map (the localizer loaded one whose keyframe 10 was taught at another
        # time): its index would drive this map's motion; stop, saying so. With this map's stamp: drive.
        with rosbag.Bag(self.map_path) as bag:
            stamps = [m.header.stamp for _, m, _ in bag.read_messages(topics=['keyframes'])]
        other = localization()
        other.keyframe_stamp = stamps[10] + rospy.Duration(100.0)
        self.localizations.set(other)
        self.wait_for_command(0.0, 0.0, 'another map')
        self.status(lambda s: 'they are different maps' in s.message, 'another map in the diagnostics')
        same = localization()
        same.keyframe_stamp = stamps[10]
        self.localizations.set(same)
        self.wait_for_command(TAUGHT_LINEAR, TAUGHT_ANGULAR + 0.1, 'this map again')

        # End of the route: stop, and stay stopped while localizations on the route keep coming.
        self.localizations.set(localization(status=Localization.STATUS_END_OF_ROUTE, keyframe=FRAMES - 1))
        self.wait_for_command(0.0, 0.0, 'end of route')
        finished = self.status(lambda s: fx.status_values(s)['state'] == 'finished', 'finished in the diagnostics')
        self.assertEqual(finished.level, DiagnosticStatus.OK)
        self.assertIn('the end of the route (keyframe %d of %d)' % (FRAMES - 1, FRAMES), finished.message)
        self.localizations.set(localization())
        count = int(fx.status_values(finished)['localizations received'])
        later = self.status(lambda s: int(fx.status_values(s)['localizations received']) >= count + 5,
                            'five more localizations')
        self.assertEqual(fx.status_values(later)['state'], 'finished')
        self.assertEqual(fx.status_values(later)['linear command (m/s)'], '0.000')
        self.localizations.set(None)

    def test_c_a_map_without_taught_motion_is_refused(self):
        old_map = os.path.join(self.tmp, 'without_motion.bag')
        with rosbag.Bag(self.map_path) as source, rosbag.Bag(old_map, 'w') as target:
            for topic, msg, t in source.read_messages(raw=True):
                if topic != 'motion':
                    target.write(topic, msg, t, raw=True)
        name = '/follow/old_map_follower'
        rospy.set_param(name + '/map', old_map)
        loaded = rospy.ServiceProxy(MANAGER + '/load_nodelet', NodeletLoad)(
            name, 'along_route_localization/route_follower', [], [], [], '')
        self.assertTrue(loaded.success)
        try:
            fx.wait_for_service(name + '/start', timeout=30)
            refused = rospy.ServiceProxy(name + '/start', Trigger)()
            self.assertFalse(refused.success)
            self.assertIn('holds no taught motion', refused.message)
            self.assertIn('motion:=', refused.message)
        finally:
            rospy.ServiceProxy(MANAGER + '/unload_nodelet', NodeletUnload)(name)

    def test_d_the_closed_loop_localizer_does_not_look_for_a_kidnapped_robot(self):
        # follow.launch: the robot repeats its route from the taught start and only moves as it drives, so
        # the localizer's checks for a robot carried elsewhere are off (detect_kidnapping false, a bool).
        self.assertIs(rospy.get_param('/follow/localizer/detect_kidnapping'), False)
        # and low confidence alone does not make it lost (loss_needs_contradiction true, a bool).
        self.assertIs(rospy.get_param('/follow/localizer/loss_needs_contradiction'), True)


if __name__ == '__main__':
    rostest.rosrun('along_route_localization', 'follow', FollowTest)
