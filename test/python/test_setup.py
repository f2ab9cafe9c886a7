"""scripts/setup.sh picks its way by the system it runs on (issue 33: on Ubuntu without /opt/ros/noetic it
installed Debian-only package names and failed without saying why). Checked with a fake os-release, a fake
Noetic root and fake apt sources, in --dry-run mode, which prints what it would run and changes nothing."""

import os
import subprocess
import tempfile
import unittest

SETUP = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'scripts', 'setup.sh'))
UBUNTU_FOCAL = 'NAME="Ubuntu"\nVERSION_ID="20.04"\nID=ubuntu\nPRETTY_NAME="Ubuntu 20.04.6 LTS"\n'
DEBIAN_12 = 'PRETTY_NAME="Debian GNU/Linux 12 (bookworm)"\nVERSION_ID="12"\nID=debian\n'
ROS_SOURCE = 'deb [signed-by=/usr/share/keyrings/ros-archive-keyring.gpg] http://packages.ros.org/ros/ubuntu focal main\n'


class SetupTest(unittest.TestCase):
    def setUp(self):
        self.folder = tempfile.TemporaryDirectory()
        self.root = self.folder.name
        self.apt = os.path.join(self.root, 'apt')
        os.makedirs(os.path.join(self.apt, 'sources.list.d'))
        self.noetic = os.path.join(self.root, 'opt_ros_noetic')  # not there unless a test makes it
        self.workspace = os.path.join(self.root, 'ws')

    def tearDown(self):
        self.folder.cleanup()

    def setup(self, os_release, *args):
        path = os.path.join(self.root, 'os-release')
        with open(path, 'w') as out:
            out.write(os_release)
        env = dict(os.environ, ALONG_ROUTE_OS_RELEASE=path, ALONG_ROUTE_ROS_ROOT=self.noetic,
                   ALONG_ROUTE_APT_SOURCES=self.apt)
        done = subprocess.run(['bash', SETUP, '--dry-run'] + list(args) + [self.workspace], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True, timeout=60)
        self.assertFalse(os.path.exists(self.workspace), 'a dry run created the workspace')
        return done

    def installed(self, output):
        return ' '.join(line for line in output.splitlines() if 'apt-get install' in line).split()

    def test_ubuntu_focal_without_noetic_or_its_source_says_how_to_get_it(self):
        done = self.setup(UBUNTU_FOCAL)
        self.assertEqual(done.returncode, 1)
        self.assertNotIn('apt-get install', done.stdout)  # no Debian-only names tried
        self.assertIn('ROS Noetic is not installed', done.stderr)
        self.assertIn('http://packages.ros.org/ros/ubuntu focal main', done.stderr)
        self.assertIn('sources.list.d/ros1.list', done.stderr)

    def test_ubuntu_focal_with_the_ros_source_installs_noetic_then_uses_rosdep(self):
        with open(os.path.join(self.apt, 'sources.list.d', 'ros1.list'), 'w') as out:
            out.write(ROS_SOURCE)
        done = self.setup(UBUNTU_FOCAL)
        self.assertEqual(done.returncode, 0, done.stderr)
        installed = self.installed(done.stdout)
        self.assertIn('ros-noetic-ros-base', installed)
        self.assertNotIn('ros-core-dev', installed)
        self.assertIn('rosdep install --from-paths', done.stdout)
        self.assertLess(done.stdout.index('ros-noetic-ros-base'), done.stdout.index('rosdep install'))

    def test_a_commented_out_ros_source_does_not_count(self):
        with open(os.path.join(self.apt, 'sources.list'), 'w') as out:
            out.write('# ' + ROS_SOURCE)
        self.assertEqual(self.setup(UBUNTU_FOCAL).returncode, 1)

    def test_an_installed_noetic_uses_rosdep_on_any_system(self):
        os.makedirs(self.noetic)
        open(os.path.join(self.noetic, 'setup.bash'), 'w').close()
        done = self.setup(UBUNTU_FOCAL)
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertIn('source {}/setup.bash'.format(self.noetic), done.stdout)
        self.assertIn('rosdep install --from-paths', done.stdout)
        self.assertNotIn('ros-noetic-ros-base', self.installed(done.stdout))

    def test_debian_12_installs_debian_packages(self):
        done = self.setup(DEBIAN_12)
        self.assertEqual(done.returncode, 0, done.stderr)
        installed = self.installed(done.stdout)
        self.assertIn('ros-core-dev', installed)
        self.assertNotIn('rosdep', done.stdout)
        self.assertIn('would link', done.stdout)

    def test_an_unknown_system_is_named_and_refused(self):
        for release in ('ID=fedora\nVERSION_ID=39\nPRETTY_NAME="Fedora Linux 39"\n',
                        'ID=ubuntu\nVERSION_ID="22.04"\nPRETTY_NAME="Ubuntu 22.04.4 LTS"\n'):
            with self.subTest(release=release):
                done = self.setup(release)
                self.assertEqual(done.returncode, 1)
                self.assertNotIn('apt-get install', done.stdout)
                self.assertIn('is not supported', done.stderr)
                self.assertIn(release.split('PRETTY_NAME="')[1].rstrip('"\n'), done.stderr)

    def test_a_missing_os_release_is_refused(self):
        env = dict(os.environ, ALONG_ROUTE_OS_RELEASE=os.path.join(self.root, 'none'), ALONG_ROUTE_ROS_ROOT=self.noetic)
        done = subprocess.run(['bash', SETUP, '--dry-run', self.workspace], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, universal_newlines=True, timeout=60)
        self.assertEqual(done.returncode, 1)
        self.assertIn('cannot read', done.stderr)


if __name__ == '__main__':
    unittest.main()
