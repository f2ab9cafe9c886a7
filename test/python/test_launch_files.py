"""teach.launch, repeat.launch and follow.launch as roslaunch reads them: the arguments it lists, the nodes it starts and
the parameters it loads for the default arguments and for the ones users pass (no roscore needed)."""

import os
import shutil
import subprocess
import tempfile
import unittest

LAUNCH_DIR = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'launch'))
ROSLAUNCH = shutil.which('roslaunch', path='/usr/bin:' + os.environ.get('PATH', ''))
# Each launch file: its own manager, and the nodelet that follows the preprocessor.
LAUNCH_FILES = {'teach.launch': ('teach_manager', 'map_recorder'), 'repeat.launch': ('repeat_manager', 'localizer')}


def roslaunch(*args):
    done = subprocess.run([ROSLAUNCH] + list(args), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          universal_newlines=True, timeout=60)
    if done.returncode != 0:
        raise AssertionError('roslaunch {} failed:\n{}'.format(' '.join(args), done.stdout))
    return done.stdout


@unittest.skipIf(ROSLAUNCH is None, 'roslaunch not installed')
class LaunchFileTest(unittest.TestCase):
    def test_every_argument_is_optional(self):
        # roslaunch --ros-args lists an argument whose default is "" as required.
        for name in LAUNCH_FILES:
            with self.subTest(launch=name):
                listed = roslaunch('--ros-args', os.path.join(LAUNCH_DIR, name))
                self.assertNotIn('Required Arguments', listed)
                for argument in ('image', 'map', 'manager', 'params_file', 'output'):
                    self.assertIn('  {} (default'.format(argument), listed)

    def test_starts_its_own_manager_by_default(self):
        for name, (manager, nodelet) in LAUNCH_FILES.items():
            for extra in ([], ['manager:=' + manager], ['manager:=']):  # "" is the old spelling
                with self.subTest(launch=name, args=extra):
                    path = os.path.join(LAUNCH_DIR, name)
                    nodes = roslaunch('--nodes', path, *extra).split()
                    self.assertEqual(sorted(nodes), sorted(['/' + manager, '/preprocessor', '/' + nodelet]))
                    for loaded in ('preprocessor', nodelet):
                        self.assertIn(' {} '.format(manager), roslaunch('--args', loaded, path, *extra))

    def test_loads_into_a_named_manager_without_starting_one(self):
        for name, (manager, nodelet) in LAUNCH_FILES.items():
            with self.subTest(launch=name):
                path = os.path.join(LAUNCH_DIR, name)
                nodes = roslaunch('--nodes', path, 'manager:=camera_manager').split()
                self.assertEqual(sorted(nodes), sorted(['/preprocessor', '/' + nodelet]))
                for loaded in ('preprocessor', nodelet):
                    command = roslaunch('--args', loaded, path, 'manager:=camera_manager')
                    self.assertIn(' camera_manager ', command)
                    self.assertNotIn(manager, command)

    def test_params_file_is_loaded_and_none_loads_nothing(self):
        with tempfile.TemporaryDirectory() as folder:
            params = os.path.join(folder, 'params.yaml')
            with open(params, 'w') as out:
                out.write('preprocessor: {output_width: 32}\nlocalizer: {window_rows: 17}\n'
                          'map_recorder: {min_distance: 3}\n')
            for name in LAUNCH_FILES:
                with self.subTest(launch=name):
                    path = os.path.join(LAUNCH_DIR, name)
                    loaded = roslaunch('--dump-params', path, 'params_file:=' + params)
                    self.assertIn('/preprocessor/output_width: 32', loaded)
                    # Each file loads its own nodelet's section (and the other's too: one file serves both).
                    self.assertIn('/localizer/window_rows: 17', loaded)
                    self.assertIn('/map_recorder/min_distance: 3', loaded)
                    default = roslaunch('--dump-params', path)
                    self.assertNotIn('/preprocessor/', default)
                    self.assertEqual(default, roslaunch('--dump-params', path, 'params_file:=none'))

    def test_a_relative_map_is_taken_from_where_roslaunch_was_started(self):
        # Issue 33: map:=route.bag was written under $ROS_HOME, the nodelets' working directory.
        nodelet_of = {'teach.launch': 'map_recorder', 'repeat.launch': 'localizer'}
        with tempfile.TemporaryDirectory() as folder:
            env = dict(os.environ, PWD=folder, HOME='/home/someone')
            for name, nodelet in nodelet_of.items():
                path = os.path.join(LAUNCH_DIR, name)
                for given, expected in (('route.bag', os.path.join(folder, 'route.bag')),
                                        ('maps/route.bag', os.path.join(folder, 'maps/route.bag')),
                                        ('~/route.bag', '/home/someone/route.bag'),
                                        ('/data/route.bag', '/data/route.bag')):
                    with self.subTest(launch=name, map=given):
                        done = subprocess.run([ROSLAUNCH, '--dump-params', path, 'map:=' + given], cwd=folder,
                                              env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                              universal_newlines=True, timeout=60)
                        self.assertEqual(done.returncode, 0, done.stdout)
                        self.assertIn('/{}/map: {}\n'.format(nodelet, expected), done.stdout)


    def test_teach_names_the_motion_topic_and_its_type(self):
        path = os.path.join(LAUNCH_DIR, 'teach.launch')
        self.assertIn(' motion:=cmd_vel', roslaunch('--args', 'map_recorder', path))
        self.assertIn('/map_recorder/motion_type: twist', roslaunch('--dump-params', path))
        given = ('motion:=/robot/odom', 'motion_type:=odometry')
        self.assertIn(' motion:=/robot/odom', roslaunch('--args', 'map_recorder', path, *given))
        self.assertIn('/map_recorder/motion_type: odometry', roslaunch('--dump-params', path, *given))

    def test_follow_adds_the_route_follower_to_the_repeat_nodelets(self):
        path = os.path.join(LAUNCH_DIR, 'follow.launch')
        listed = roslaunch('--ros-args', path)
        self.assertNotIn('Required Arguments', listed)
        for argument in ('image', 'map', 'manager', 'params_file', 'output', 'cmd_vel', 'autostart'):
            self.assertIn('  {} (default'.format(argument), listed)
        for extra, manager, nodes in (([], 'repeat_manager', ['/repeat_manager']),
                                      (['manager:=camera_manager'], 'camera_manager', [])):
            with self.subTest(args=extra):
                self.assertEqual(sorted(roslaunch('--nodes', path, *extra).split()),
                                 sorted(nodes + ['/preprocessor', '/localizer', '/route_follower']))
                for loaded in ('preprocessor', 'localizer', 'route_follower'):
                    self.assertIn(' {} '.format(manager), roslaunch('--args', loaded, path, *extra))
        command = roslaunch('--args', 'route_follower', path, 'cmd_vel:=/robot/cmd_vel')
        self.assertIn('along_route_localization/route_follower', command)
        self.assertIn(' cmd_vel:=/robot/cmd_vel', command)
        params = roslaunch('--dump-params', path, 'map:=/maps/route.bag', 'autostart:=true')
        self.assertIn('/route_follower/map: /maps/route.bag', params)
        self.assertIn('/localizer/map: /maps/route.bag', params)
        self.assertIn('/route_follower/autostart: true', params)

    def test_follow_coasts_on_weak_evidence_and_repeat_keeps_the_params_file(self):
        # follow.launch: low confidence alone does not make the closed loop's track lost (a lost robot stops,
        # and standing still it shows no new view to be found by); its argument overrides the params file.
        # repeat.launch leaves the value to the params file (else the localizer's default, false).
        follow = os.path.join(LAUNCH_DIR, 'follow.launch')
        repeat = os.path.join(LAUNCH_DIR, 'repeat.launch')
        self.assertIn('/localizer/loss_needs_contradiction: true', roslaunch('--dump-params', follow))
        self.assertIn('/localizer/loss_needs_contradiction: false',
                      roslaunch('--dump-params', follow, 'loss_needs_contradiction:=false'))
        self.assertNotIn('loss_needs_contradiction', roslaunch('--dump-params', repeat))
        self.assertIn('/localizer/loss_needs_contradiction: true',
                      roslaunch('--dump-params', repeat, 'loss_needs_contradiction:=true'))


def package_found():
    rospack = shutil.which('rospack', path='/usr/bin:' + os.environ.get('PATH', ''))
    return rospack is not None and subprocess.run([rospack, 'find', 'along_route_localization'], stdout=subprocess.PIPE,
                                                  stderr=subprocess.PIPE).returncode == 0


@unittest.skipIf(ROSLAUNCH is None, 'roslaunch not installed')
class DemoLaunchTest(unittest.TestCase):
    def test_view_starts_viewers_that_exist(self):
        # Issue 33: view:=true named image_view/image_view, which roslaunch cannot launch on Debian.
        if not package_found():
            self.skipTest('along_route_localization is not on ROS_PACKAGE_PATH (source the workspace)')
        path = os.path.join(LAUNCH_DIR, 'demo.launch')
        nodes = roslaunch('--nodes', path, 'view:=true').split()
        self.assertIn('/camera_view', nodes)
        self.assertIn('/debug_view', nodes)
        self.assertNotIn('/camera_view', roslaunch('--nodes', path).split())
        for node, topic in (('camera_view', '/camera/image_raw'), ('debug_view', '/localization_debug_image')):
            with self.subTest(node=node):
                command = roslaunch('--args', node, path, 'view:=true').split()
                self.assertTrue(os.access(command[0], os.X_OK), command)  # roslaunch found the program
                self.assertIn('image:=' + topic, command)


if __name__ == '__main__':
    unittest.main()
