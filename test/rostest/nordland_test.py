#!/usr/bin/python3
"""Real frames through the real nodelets: 300 summer Nordland frames as a bag taught with teach.launch,
the 300 winter frames of the same stretch as a bag repeated with repeat.launch. The nodelets must give,
frame by frame, the answers of localize_offline on the same images (the same core code path), and
follow the ground truth (same frame number = same place). Skipped when ../shared/data/nordland is
missing."""

import csv
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import rospy
import rostest

from along_route_localization.msg import Localization
import route_fixture as fx

sys.path.insert(0, os.path.join(fx.PACKAGE_DIR, 'test', 'python'))
from scripts_under_test import built_executable  # noqa: E402

DATA = os.path.normpath(os.path.join(os.path.realpath(fx.PACKAGE_DIR), '..', 'shared', 'data', 'nordland'))
FIRST, COUNT = 1000, 300   # the stretch of test/core/test_localizer.cpp: stations and a tunnel
TRACKING = (Localization.STATUS_TRACKING, Localization.STATUS_END_OF_ROUTE)




@unittest.skipUnless(os.path.isdir(os.path.join(DATA, 'summer')) and os.path.isdir(os.path.join(DATA, 'winter')),
                     'Nordland frames not found at %s' % DATA)
class NordlandTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node('nordland_test')
        cls.tmp = tempfile.mkdtemp(prefix='along_route_nordland_test_')
        cls.map_path = rospy.get_param('~map')
        folders = {}
        for season in ('summer', 'winter'):
            # A folder of links to the stretch: localize_offline reads it, images_to_bag turns it into a bag.
            folders[season] = os.path.join(cls.tmp, season)
            os.makedirs(folders[season])
            names = sorted(os.listdir(os.path.join(DATA, season)))[FIRST:FIRST + COUNT]
            for name in names:
                os.symlink(os.path.join(DATA, season, name), os.path.join(folders[season], name))
            subprocess.run([sys.executable, os.path.join(fx.PACKAGE_DIR, 'scripts', 'images_to_bag'), folders[season],
                            os.path.join(cls.tmp, season + '.bag'), '--rate', '20'],
                           check=True, timeout=120, stdout=subprocess.DEVNULL)
        cls.offline_csv = os.path.join(cls.tmp, 'offline.csv')
        subprocess.run([built_executable('localize_offline'), '--quiet', '--map', folders['summer'], '--query', folders['winter'],
                        '--output', cls.offline_csv], check=True, timeout=300)

        cls.localizations = fx.Collector('/repeat/localization', Localization, queue_size=1000)
        cls.finish, cls.loaded = fx.teach_and_load(os.path.join(cls.tmp, 'summer.bag'), COUNT, cls.map_path)
        fx.play(os.path.join(cls.tmp, 'winter.bag'), {fx.CAMERA_TOPIC: '/repeat_camera/image_raw'})
        fx.wait_for(lambda: cls.localizations.count() >= COUNT, 60, 'a Localization per winter frame')
        cls.answers = cls.localizations.take()

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)
        fx.remove(cls.map_path)

    def test_map_holds_every_summer_frame(self):
        self.assertTrue(self.finish.success, self.finish.message)
        self.assertTrue(self.loaded.success, self.loaded.message)
        self.assertEqual(self.loaded.keyframes, COUNT)

    def test_nodelets_answer_as_the_offline_runner(self):
        with open(self.offline_csv) as f:
            offline = list(csv.DictReader(f))
        self.assertEqual(len(self.answers), COUNT)
        self.assertEqual([m.keyframe for m in self.answers], [int(r['keyframe']) for r in offline])
        for m, r in zip(self.answers, offline):
            self.assertAlmostEqual(m.confidence, float(r['confidence']), places=4)

    def test_follows_the_ground_truth(self):
        tracked = [(i, m) for i, m in enumerate(self.answers) if m.status in TRACKING]
        self.assertGreaterEqual(len(tracked), 0.8 * COUNT)
        within_one = sum(1 for i, m in tracked if abs(m.keyframe - i) <= 1)
        self.assertGreaterEqual(within_one, 0.7 * len(tracked))


if __name__ == '__main__':
    rostest.rosrun('along_route_localization', 'nordland', NordlandTest)
