"""scripts/generate_route: ground-truth formulas, the repeat schedule, and the sign of a rendered yaw."""

import contextlib
import csv
import io
import math
import os
import shutil
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import load, ros_python_available

generate_route = load("generate_route")


class GroundTruthFormulaTest(unittest.TestCase):
    def test_expected_shift(self):
        # 90 deg over 64 px: f = 32 px; 5 deg left -> 32 tan(5 deg) = 2.79964 px to the right
        self.assertAlmostEqual(generate_route.expected_shift_px(math.radians(5), math.radians(90)), 2.799637, places=5)
        self.assertAlmostEqual(generate_route.expected_shift_px(math.radians(-5), math.radians(90)), -2.799637, places=5)
        # 60 deg: f = 32 / tan(30 deg) = 55.42563 px; tan(2 deg) = 0.0349208 -> 1.93550 px
        self.assertAlmostEqual(generate_route.expected_shift_px(math.radians(2), math.radians(60)), 1.93550, places=4)

    def test_mean_shift_exceeds_centre_shift_on_wide_lenses(self):
        self.assertEqual(generate_route.mean_shift_px(0.0, math.radians(90)), 0.0)
        centre = generate_route.expected_shift_px(math.radians(5), math.radians(90))
        mean = generate_route.mean_shift_px(math.radians(5), math.radians(90))
        # the edges of a 90 deg lens move about twice as much as the centre: the mean is ~1.34x the centre
        self.assertGreater(mean / centre, 1.25)
        self.assertLess(mean / centre, 1.45)
        self.assertAlmostEqual(mean, -generate_route.mean_shift_px(math.radians(-5), math.radians(90)), places=9)
        # narrow lens: nearly uniform displacement
        narrow = generate_route.mean_shift_px(math.radians(1), math.radians(20))
        self.assertLess(narrow / generate_route.expected_shift_px(math.radians(1), math.radians(20)), 1.02)

    def test_nearest_teach_frame(self):
        self.assertEqual(generate_route.nearest_teach_frame(0.74, 0.5, 300), 1)
        self.assertEqual(generate_route.nearest_teach_frame(0.75, 0.5, 300), 2)   # halves go up
        self.assertEqual(generate_route.nearest_teach_frame(-1.0, 0.5, 300), 0)
        self.assertEqual(generate_route.nearest_teach_frame(1000.0, 0.5, 300), 299)


class RepeatScheduleTest(unittest.TestCase):
    def setUp(self):
        self.length = 149.5
        self.positions, self.offsets, self.labels = generate_route.repeat_schedule(
            self.length, 0.5, np.random.default_rng([1, 2]))

    def test_covers_the_route_forwards(self):
        self.assertEqual(self.positions[0], 0.0)
        self.assertAlmostEqual(self.positions[-1], self.length)
        self.assertTrue((np.diff(self.positions) >= 0).all())

    def test_has_stops_slow_and_fast_stretches(self):
        steps = np.diff(self.positions)
        labels = np.array(self.labels[:-1])
        self.assertTrue((steps[labels == "stop"] == 0).all())
        self.assertGreaterEqual(np.count_nonzero(labels == "stop"), 3 * 3)   # three stops of 4-10 frames
        self.assertAlmostEqual(float(np.median(steps[labels == "slow"])), 0.25, delta=0.02)
        self.assertAlmostEqual(float(np.median(steps[labels == "fast"])), 0.85, delta=0.05)
        self.assertAlmostEqual(float(np.median(steps[labels == "normal"])), 0.5, delta=0.03)
        self.assertTrue(250 <= len(self.positions) <= 450, len(self.positions))

    def test_heading_offsets_take_the_listed_values_in_stretches(self):
        values = set(np.round(np.degrees(self.offsets), 6))
        plateau = values & {-5.0, -3.5, -2.0, 2.0, 3.5, 5.0}
        self.assertGreaterEqual(len(plateau), 3)
        self.assertTrue(all(abs(v) <= 5.0 + 1e-9 for v in values))
        self.assertEqual(self.offsets[0], 0.0)
        self.assertEqual(self.offsets[-1], 0.0)

    def test_reproducible(self):
        again = generate_route.repeat_schedule(self.length, 0.5, np.random.default_rng([1, 2]))
        np.testing.assert_array_equal(again[0], self.positions)
        np.testing.assert_array_equal(again[1], self.offsets)


def measured_shift(reference, yawed):
    """Sub-pixel horizontal shift of `yawed` against `reference` (both 64x32 float) by brute-force SAD."""
    costs = np.array([np.abs(yawed[:, 8:56] - reference[:, 8 - d:56 - d]).mean() for d in range(-6, 7)])
    i = int(np.argmin(costs))
    a, b, c = costs[i - 1], costs[i], costs[i + 1]
    return i - 6 + 0.5 * (a - c) / (a - 2 * b + c)


class RenderingTest(unittest.TestCase):
    """A short route rendered at 256x192; the 64x32 gray image must move as expected_shift_px says."""

    @classmethod
    def setUpClass(cls):
        import cv2
        cls.cv2 = cv2
        cls.world = generate_route.World(30.0, np.random.default_rng([5, 1]))
        cls.renderer = generate_route.Renderer(cls.world, generate_route.Lighting(**generate_route.TEACH_LIGHT),
                                               256, 192, math.radians(90), np.random.default_rng(3))

    def small(self, position, yaw_offset):
        x, y, heading = self.world.route.pose(position)
        image = self.renderer.render(x, y, heading + yaw_offset)
        self.assertEqual(image.shape, (192, 256, 3))
        self.assertEqual(image.dtype, np.uint8)
        gray = self.cv2.cvtColor(image, self.cv2.COLOR_BGR2GRAY)
        return self.cv2.resize(gray, (64, 32), interpolation=self.cv2.INTER_AREA).astype(np.float64)

    def test_yaw_left_moves_content_right(self):
        for position in (5.0, 20.0):
            reference = self.small(position, 0.0)
            for degrees in (-4.0, 4.0):
                shift = measured_shift(reference, self.small(position, math.radians(degrees)))
                expected = generate_route.expected_shift_px(math.radians(degrees), math.radians(90))
                self.assertEqual(np.sign(shift), np.sign(degrees), (position, degrees, shift))
                # a whole-image shift search on a 90 deg lens measures between the centre and the mean shift
                mean = generate_route.mean_shift_px(math.radians(degrees), math.radians(90))
                self.assertGreater(abs(shift), 0.8 * abs(expected), (position, degrees, shift, expected))
                self.assertLess(abs(shift), 1.1 * abs(mean), (position, degrees, shift, mean))

    def test_same_pose_same_image_and_nearby_frames_differ(self):
        a = self.small(10.0, 0.0)
        np.testing.assert_array_equal(a, self.small(10.0, 0.0))
        near = np.abs(a - self.small(10.5, 0.0)).mean()
        far = np.abs(a - self.small(25.0, 0.0)).mean()
        self.assertGreater(near, 0.2)       # one teach step changes the image ...
        self.assertGreater(far, 2.0 * near)  # ... less than a long way along the route does


@unittest.skipUnless(ros_python_available(), "rosbag / sensor_msgs not importable (use /usr/bin/python3)")
class CommandLineTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="test_generate_route_")

    def tearDown(self):
        shutil.rmtree(self.tmp)

    def test_small_run(self):
        import rosbag
        out = os.path.join(self.tmp, "route")
        with contextlib.redirect_stdout(io.StringIO()) as stdout, contextlib.redirect_stderr(io.StringIO()) as stderr:
            code = generate_route.main(["--output", out, "--teach-frames", "40", "--width", "96", "--height", "64",
                                        "--rate", "20", "--start-time", "50", "--seed", "3", "--progress", "lines"])
        self.assertEqual(code, 0)
        # Issue 33: silent for ~15 s. Progress on stderr (the setup's stages, then a line at every 10 % of
        # each run); stdout holds only the summary.
        self.assertEqual(len(stdout.getvalue().splitlines()), 1)
        self.assertTrue(stdout.getvalue().startswith("generate_route: 40 teach frames"))
        progress = stderr.getvalue().splitlines()
        for stage in ("setup 1/3", "setup 2/3", "setup 3/3"):
            self.assertTrue(any(stage in line for line in progress), progress)
        teach = [line for line in progress if "teach frames:" in line]
        self.assertEqual(len(teach), 10, progress)
        self.assertTrue(teach[0].startswith("generate_route: teach frames: 4/40 (10 %)"), teach)
        self.assertTrue(teach[-1].startswith("generate_route: teach frames: 40/40 (100 %)"), teach)
        with open(os.path.join(out, "ground_truth.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(list(rows[0].keys())[:4], ["query_index", "teach_frame", "heading_offset_rad",
                                                    "expected_shift_px_64"])
        for row in rows:
            offset = float(row["heading_offset_rad"])
            self.assertAlmostEqual(float(row["expected_shift_px_64"]), 32.0 * math.tan(offset), places=3)
            self.assertTrue(0 <= int(row["teach_frame"]) < 40)
        self.assertEqual(int(rows[-1]["teach_frame"]), 39)
        for name, count in (("teach", 40), ("repeat", len(rows))):
            with rosbag.Bag(os.path.join(out, name + ".bag")) as bag:
                messages = [(m, t) for _, m, t in bag.read_messages(topics=["/camera/image_raw"])]
            self.assertEqual(len(messages), count)
            first, t0 = messages[0]
            self.assertEqual((first.width, first.height, first.encoding, first.header.frame_id),
                             (96, 64, "bgr8", "camera"))
            self.assertAlmostEqual(t0.to_sec(), 50.0)
            self.assertAlmostEqual(messages[1][0].header.stamp.to_sec(), 50.05, places=6)
        self.assertFalse(any(n.endswith(".tmp") for n in os.listdir(out)))

    def test_progress_modes(self):
        def run(mode, total, isatty):
            stream = io.StringIO()
            stream.isatty = lambda: isatty
            progress = generate_route.Progress("x", total, mode, stream)
            for done in range(1, total + 1):
                progress.update(done)
            return stream.getvalue()

        self.assertEqual(run("off", 50, True), "")
        lines = run("auto", 50, False).splitlines()  # not a terminal: lines
        self.assertEqual([line.split(",")[0] for line in lines],
                         ["x: %d/50 (%d %%)" % (5 * k, 10 * k) for k in range(1, 11)])
        bar = run("auto", 50, True)  # a terminal: one line redrawn in place, ended once
        self.assertTrue(bar.startswith("\rx ["))
        self.assertEqual(bar.count("\n"), 1)
        self.assertIn("50/50", bar.rsplit("\r", 1)[1])

    def test_bad_arguments(self):
        with contextlib.redirect_stderr(io.StringIO()):
            for args in (["--output", self.tmp, "--width", "10"], ["--output", self.tmp, "--hfov-deg", "200"],
                         ["--output", self.tmp, "--rate", "0"], []):
                with self.assertRaises(SystemExit) as caught:
                    generate_route.main(args)
                self.assertNotEqual(caught.exception.code, 0)


if __name__ == "__main__":
    unittest.main()
