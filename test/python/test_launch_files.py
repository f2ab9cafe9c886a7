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


if __name__ == '__main__':
    unittest.main()
