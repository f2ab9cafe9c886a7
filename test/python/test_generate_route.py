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


class CameraShakeGeometryTest(unittest.TestCase):
    # --camera-shake-deg, worked by hand: focal 100 px, principal point (160, 90).
    F, CX, CY = 100.0, 160.0, 90.0

    def mapped(self, pitch_deg, roll_deg, u, v):
        h = generate_route.shake_homography(math.radians(pitch_deg), math.radians(roll_deg), self.F, self.CX, self.CY)
        p = h.dot([u, v, 1.0])
        return p[0] / p[2], p[1] / p[2]

    def test_pitch_up_moves_the_scene_down_by_f_tan(self):
        # The ray through the principal point is 3 deg above the new optical axis: 100 tan 3 deg = 5.241 px below.
        u, v = self.mapped(3.0, 0.0, self.CX, self.CY)
        self.assertAlmostEqual(u, 160.0, places=9)
        self.assertAlmostEqual(v, 90.0 + 100.0 * math.tan(math.radians(3.0)), places=9)
        u, v = self.mapped(-3.0, 0.0, self.CX, self.CY)
        self.assertAlmostEqual(v, 90.0 - 5.2407779, places=6)

    def test_roll_left_turns_the_scene_clockwise_about_the_principal_point(self):
        # A point 50 px right of the principal point, the camera rolled 10 deg left: 50 (cos 10, sin 10) from it,
        # i.e. 49.240 px right and 8.682 px down (image y grows downwards).
        u, v = self.mapped(0.0, 10.0, self.CX + 50.0, self.CY)
        self.assertAlmostEqual(u, 160.0 + 49.2403877, places=6)
        self.assertAlmostEqual(v, 90.0 + 8.6824089, places=6)

    def test_the_image_moves_as_the_homography_says(self):
        import cv2  # noqa: F401  (generate_route's own import; skip the test where it is missing)
        image = np.zeros((180, 320, 3), np.uint8)
        image[88:93, 208:213] = 255                                   # a 5x5 dot centred at (210, 90)
        shaken = generate_route.shake_image(image, math.radians(3.0), math.radians(10.0), self.F, self.CX, self.CY)
        gray = shaken[:, :, 0].astype(np.float64)
        ys, xs = np.mgrid[0:180, 0:320]
        centre = ((gray * xs).sum() / gray.sum(), (gray * ys).sum() / gray.sum())
        expected = self.mapped(3.0, 10.0, 210.0, 90.0)
        self.assertAlmostEqual(centre[0], expected[0], delta=0.2)
        self.assertAlmostEqual(centre[1], expected[1], delta=0.2)
        self.assertGreater(expected[1], 90.0 + 5.0)                    # moved down by the pitch and the roll

    def test_angles_stay_within_the_amplitude_and_swing_both_ways(self):
        t = np.arange(0, 60.0, 0.1)
        pitch, roll = generate_route.shake_angles(t, 0.05, np.random.default_rng(1))
        for angle in (pitch, roll):
            self.assertLessEqual(np.abs(angle).max(), 0.05 + 1e-12)
            self.assertGreater(angle.max(), 0.03)
            self.assertLess(angle.min(), -0.03)
        again = generate_route.shake_angles(t, 0.05, np.random.default_rng(1))
        np.testing.assert_array_equal(pitch, again[0])


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

    def test_a_camera_moved_left_sees_the_scene_move_right(self):
        # --repeat-lateral-m: parallax; content moves right (positive shift) for a camera moved left.
        for position in (5.0, 20.0):
            x, y, heading = self.world.route.pose(position, 1.0)
            left = self.renderer.render(x, y, heading)
            gray = self.cv2.resize(self.cv2.cvtColor(left, self.cv2.COLOR_BGR2GRAY), (64, 32),
                                   interpolation=self.cv2.INTER_AREA).astype(np.float64)
            self.assertGreater(measured_shift(self.small(position, 0.0), gray), 0.0, position)

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

    def test_a_rerun_into_the_same_folder_leaves_only_its_own_route(self):
        # A rerun with fewer frames left the earlier run's extra teach PNGs (and its bags, with --no-bags)
        # beside the new ground truth: localize_offline loaded 300 keyframes, 280 of another world.
        out = os.path.join(self.tmp, "route")
        base = ["--output", out, "--width", "64", "--height", "32", "--progress", "off", "--images"]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            self.assertEqual(generate_route.main(base + ["--teach-frames", "40", "--seed", "1"]), 0)
        self.assertEqual(len(os.listdir(os.path.join(out, "teach_images"))), 40)
        self.assertTrue(os.path.exists(os.path.join(out, "teach.bag")))
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
            self.assertEqual(generate_route.main(base + ["--teach-frames", "20", "--seed", "2", "--no-bags"]), 0)
        self.assertIn("removed the earlier route in %s: ground_truth.csv, teach.bag, repeat.bag, teach_images/ "
                      "(40 PNGs), repeat_images/" % out, err.getvalue())
        with open(os.path.join(out, "ground_truth.csv")) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(sorted(os.listdir(out)), ["ground_truth.csv", "repeat_images", "teach_images"])
        self.assertEqual(len(os.listdir(os.path.join(out, "teach_images"))), 20)
        self.assertEqual(len(os.listdir(os.path.join(out, "repeat_images"))), len(rows))

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
                         ["--output", self.tmp, "--width", "100000", "--height", "100000"],  # 33 GiB, a MemoryError
                         ["--output", self.tmp, "--rate", "0"], []):
                with self.assertRaises(SystemExit) as caught:
                    generate_route.main(args)
                self.assertNotEqual(caught.exception.code, 0)

    def test_values_that_broke_the_run_are_refused_by_name_before_anything_is_written(self):
        # Each was a traceback (nan, 5e9 s, '' and -1 left a half-written teach.bag.tmp), or, for 1e6 m, a
        # world of many GB built in memory. Refused by argparse (exit 2) with the option named; the
        # output folder stays empty.
        out = os.path.join(self.tmp, "refused")
        base = ["--output", out, "--width", "64", "--height", "32", "--teach-frames", "20"]
        cases = ((["--start-time", "nan"], "--start-time must be in [0, 2^32) s"),
                 (["--start-time", "5e9"], "--start-time must be in [0, 2^32) s"),
                 (["--topic="], "--topic: topic '' is not a ROS topic name"),
                 (["--seed", "-1"], "--seed must be >= 0"),
                 (["--step-m", "inf"], "--step-m must be > 0 and finite"),
                 (["--step-m", "1e6"], "is longer than 1000 m"),
                 (["--rate", "inf"], "--rate must be > 0 and finite"))
        for extra, words in cases:
            with contextlib.redirect_stderr(io.StringIO()) as err:
                with self.assertRaises(SystemExit) as caught:
                    generate_route.main(base + extra)
            self.assertEqual(caught.exception.code, 2, extra)
            self.assertIn(words, err.getvalue(), extra)
            self.assertFalse(os.path.exists(out) and os.listdir(out), extra)
        # The last frame's stamp counts too: a start just below 2^32 s leaves no room for the frames.
        with contextlib.redirect_stderr(io.StringIO()) as err, contextlib.redirect_stdout(io.StringIO()):
            with self.assertRaises(SystemExit) as caught:
                generate_route.main(base + ["--start-time", str(2 ** 32 - 1), "--progress", "off"])
        self.assertEqual(caught.exception.code, 2)
        self.assertIn("do not fit ROS time", err.getvalue())
        self.assertEqual(os.listdir(out), [])


class ConditionLayoutTest(unittest.TestCase):
    """--conditions: which stretches, how strong, and the option's parsing."""

    def test_parse_conditions(self):
        self.assertEqual(generate_route.parse_conditions("all"), generate_route.CONDITIONS)
        # kept in CONDITIONS order, spaces ignored
        self.assertEqual(generate_route.parse_conditions("contrast-collapse, low-texture"),
                         ("low-texture", "contrast-collapse"))
        for bad in ("fog", "", "glare,snow", "all,glare"):
            with self.assertRaises(ValueError):
                generate_route.parse_conditions(bad)

    def test_stretches_are_disjoint_sized_and_apart(self):
        length = 149.5
        for seed in range(1, 21):
            stretches = generate_route.condition_stretches(length, np.random.default_rng([seed, 7]))
            self.assertEqual(sorted(stretches), sorted(generate_route.CONDITIONS))
            ordered = sorted(stretches.values())
            for name, (start, end) in stretches.items():
                low, high = generate_route.CONDITION_SHARES[name]
                self.assertTrue(low * length <= end - start <= high * length, (seed, name, start, end))
            self.assertGreaterEqual(ordered[0][0], 0.15 * length)
            self.assertLessEqual(ordered[-1][1], 0.90 * length + 1e-9)
            for (_, end), (start, _) in zip(ordered, ordered[1:]):
                self.assertGreaterEqual(start - end, 0.10 * length - 1e-9, seed)

    def test_the_same_places_whichever_conditions_are_picked(self):
        one = generate_route.Conditions(("glare",), 100.0, np.random.default_rng([4, 7]))
        every = generate_route.Conditions(generate_route.CONDITIONS, 100.0, np.random.default_rng([4, 7]))
        self.assertEqual(one.stretches, every.stretches)
        start, end = one.stretches["low-texture"]
        middle = 0.5 * (start + end)
        self.assertEqual(one.label(middle), "")           # not picked: no label, no effect
        self.assertEqual(one.strength("low-texture", middle), 0.0)
        self.assertEqual(every.label(middle), "low-texture")
        self.assertTrue(0.8 <= every.collapse_weight <= 0.9)

    def test_strength_ramps_at_the_ends(self):
        conditions = generate_route.Conditions(generate_route.CONDITIONS, 100.0, np.random.default_rng([4, 7]))
        start, end = conditions.stretches["glare"]   # ramp 1.5 m: 0.5 at the ends, 1 from 0.75 m inside
        self.assertEqual(conditions.strength("glare", start - 0.01), 0.0)
        self.assertAlmostEqual(conditions.strength("glare", start), 0.5)
        self.assertAlmostEqual(conditions.strength("glare", start + 0.375), 0.75)
        self.assertAlmostEqual(conditions.strength("glare", 0.5 * (start + end)), 1.0)
        self.assertAlmostEqual(conditions.strength("glare", end), 0.5)
        self.assertEqual(conditions.strength("glare", end + 0.01), 0.0)


class HardConditionRenderingTest(unittest.TestCase):
    """The effects on rendered frames, against numbers worked out from their definitions."""

    @classmethod
    def setUpClass(cls):
        import cv2
        cls.cv2 = cv2
        cls.world = generate_route.World(30.0, np.random.default_rng([5, 1]))
        cls.renderer = generate_route.Renderer(cls.world, generate_route.Lighting(**generate_route.REPEAT_LIGHT),
                                               256, 192, math.radians(90), np.random.default_rng(3))

    def gray64(self, image):
        gray = self.cv2.cvtColor(image, self.cv2.COLOR_BGR2GRAY)
        return self.cv2.resize(gray, (64, 32), interpolation=self.cv2.INTER_AREA).astype(np.float64)

    def test_glare_on_a_flat_image(self):
        r = self.renderer
        flat = np.full((192, 256, 3), 100, np.uint8)
        out = r._glare(flat, 0.3, 1.0, 0.3, 0.0)   # the sun straight ahead, on the horizon row
        # f = 128 px, cx = 127.5, cy = 0.45 * 192 - 0.5 = 85.9; at the sun: 100 + 255 * (3 + 0.8 + 0.35) -> 255
        self.assertEqual(int(out[86, 127, 0]), 255)
        # column 0 of row 86: ray (-127.5, -0.1, 128) / |.|, angle to the axis acos(128 / 180.666) = 0.78501 rad;
        # bloom 3 exp(-(0.78501 / 0.05)^2) ~ 0, halo 0.8 / (1 + (0.78501 / 0.15)^2) = 0.028178, veil 0.35;
        # (100 + 255 * 0.378178) / 1.3 = 151.10
        self.assertAlmostEqual(float(out[86, 0, 0]), 151.1, delta=1.0)
        # half strength: (100 + 127.5 * 0.378178) / 1.15 = 128.88
        self.assertAlmostEqual(float(r._glare(flat, 0.3, 0.5, 0.3, 0.0)[86, 0, 0]), 128.9, delta=1.0)
        # the sun 90 deg to the left: the left edge (45 deg from it) is now the brightest column
        side = r._glare(flat, 0.0, 1.0, math.pi / 2, 0.0)
        self.assertGreater(int(side[86, 0, 0]), int(side[86, 255, 0]))

    def test_glare_and_collapse_lower_the_contrast_of_a_frame(self):
        x, y, heading = self.world.route.pose(12.0)
        plain = self.gray64(self.renderer.render(x, y, heading))
        glare = self.gray64(self.renderer.render(x, y, heading, None, (1.0, heading + 0.1, math.radians(4))))
        # away from the sun (the ground, rows 20-31 of 32) the relative contrast std / mean drops
        self.assertLess(glare[20:].std() / glare[20:].mean(), 0.8 * plain[20:].std() / plain[20:].mean())
        white = self.gray64(self.renderer._expose(np.full((192, 256, 3), 255, np.uint8), None))
        self.assertGreaterEqual(glare.max(), white.max() - 1.0)   # the bloom saturates (full scale, exposed)
        # collapse 0.85 toward 185, without noise: std * 0.15, mean 0.15 mean + 0.85 * 185 (up to rounding)
        fog = self.gray64(self.renderer.render(x, y, heading, None, None, (0.85, 185.0)))
        self.assertAlmostEqual(fog.std() / plain.std(), 0.15, delta=0.01)
        self.assertAlmostEqual(fog.mean(), 0.15 * plain.mean() + 0.85 * 185.0, delta=1.0)
        np.testing.assert_array_equal(self.gray64(self.renderer.render(x, y, heading, None, (0.0, 0.0, 0.0),
                                                                       (0.0, 185.0))), plain)

    def test_low_texture_plain(self):
        plain_world = generate_route.World(30.0, np.random.default_rng([5, 1]),
                                           plain=(12.0, 20.0, np.random.default_rng([5, 8])))
        # the same world elsewhere: the objects far from the plain are all still there
        clearance = generate_route.World.PLAIN_CLEARANCE_M

        def far(world):
            points = np.array([[t[0], t[1]] for t in world.trees])
            s = world.nearest_route_position(points)
            keep = [t for t, position in zip(world.trees, s)
                    if position < 12.0 - clearance - 5.0 or position > 20.0 + clearance + 5.0]
            return [(t[0], t[1]) for t in keep]
        self.assertEqual(far(plain_world), far(self.world))
        self.assertGreater(len(self.world.trees), len(plain_world.trees))
        for items in (plain_world.trees, plain_world.poles, plain_world.boulders, plain_world.houses):
            if items:
                s = plain_world.nearest_route_position(np.array([[i[0], i[1]] for i in items]))
                self.assertFalse(((s >= 12.0) & (s <= 20.0)).any())
        # near-uniform ground beside the track in the plain: the albedo 6 m to the left varies far less
        # there than at the same offset outside it
        def albedo_std(positions):
            values = []
            for s in positions:
                x, y = plain_world.route.offset_point(s, 6.0)
                col = int((x - plain_world.ground_origin[0]) / generate_route.GROUND_RES_M)
                row = int((y - plain_world.ground_origin[1]) / generate_route.GROUND_RES_M)
                values.append(plain_world.ground_albedo[row, col].mean())
            return float(np.std(values))
        self.assertLess(albedo_std(np.arange(14.0, 18.0, 0.1)), 0.25 * albedo_std(np.arange(2.0, 6.0, 0.1)))


class ConditionsCommandLineTest(unittest.TestCase):
    """--conditions on a short route (no bags: ROS not needed): the condition column, and that the option
    changes only what it says."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="test_generate_route_conditions_")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp)

    def generate(self, name, *extra):
        out = os.path.join(self.tmp, name)
        with contextlib.redirect_stdout(io.StringIO()) as stdout, contextlib.redirect_stderr(io.StringIO()):
            code = generate_route.main(["--output", out, "--teach-frames", "40", "--width", "96", "--height", "64",
                                        "--seed", "2", "--images", "--no-bags", "--progress", "off"] + list(extra))
        self.assertEqual(code, 0)
        with open(os.path.join(out, "ground_truth.csv")) as f:
            return out, list(csv.DictReader(f)), stdout.getvalue()

    def images(self, folder, run):
        import cv2
        path = os.path.join(folder, run + "_images")
        return [cv2.imread(os.path.join(path, name)) for name in sorted(os.listdir(path))]

    def test_repeat_only_conditions_touch_only_their_stretches(self):
        base, base_rows, _ = self.generate("base")
        hard, rows, summary = self.generate("hard", "--conditions", "glare,contrast-collapse")
        self.assertNotIn("condition", base_rows[0])          # without the option: the columns of before
        self.assertEqual(list(rows[0].keys()), list(base_rows[0].keys()) + ["condition"])
        self.assertIn("conditions: glare", summary)
        conditions = generate_route.Conditions(("glare", "contrast-collapse"), 39 * 0.5,
                                               np.random.default_rng([2, 7]))
        for row, base_row in zip(rows, base_rows):
            self.assertEqual(row["condition"], conditions.label(float(row["route_position_m"])))
            self.assertEqual({k: v for k, v in row.items() if k != "condition"}, base_row)
        labels = [row["condition"] for row in rows]
        self.assertIn("glare", labels)
        self.assertIn("contrast-collapse", labels)
        for a, b in zip(self.images(base, "teach"), self.images(hard, "teach")):
            np.testing.assert_array_equal(a, b)                # the teach run is untouched
        for row, a, b in zip(rows, self.images(base, "repeat"), self.images(hard, "repeat")):
            if row["condition"]:
                self.assertGreater(np.abs(a.astype(int) - b.astype(int)).mean(), 2.0, row)
            else:
                np.testing.assert_array_equal(a, b)

    def test_lateral_offset_moves_only_the_repeat_run(self):
        base, base_rows, _ = self.generate("base_lateral")
        side, rows, _ = self.generate("side", "--repeat-lateral-m", "1.5")
        self.assertNotIn("repeat_lateral_m", base_rows[0])   # without the option: the columns of before
        self.assertEqual(list(rows[0].keys()), list(base_rows[0].keys()) + ["repeat_lateral_m"])
        for row, base_row in zip(rows, base_rows):
            self.assertEqual(row["repeat_lateral_m"], "1.500")
            self.assertEqual({k: v for k, v in row.items() if k != "repeat_lateral_m"}, base_row)
        for a, b in zip(self.images(base, "teach"), self.images(side, "teach")):
            np.testing.assert_array_equal(a, b)                # the teach run is untouched
        for a, b in zip(self.images(base, "repeat"), self.images(side, "repeat")):
            self.assertGreater(np.abs(a.astype(int) - b.astype(int)).mean(), 2.0)
        with contextlib.redirect_stderr(io.StringIO()) as stderr:
            with self.assertRaises(SystemExit) as caught:
                generate_route.main(["--output", self.tmp, "--repeat-lateral-m", "3.5"])
        self.assertEqual(caught.exception.code, 2)
        self.assertIn("--repeat-lateral-m must be in [-3, 3]", stderr.getvalue())

    def test_camera_shake_moves_only_the_repeat_run(self):
        base, base_rows, _ = self.generate("base_shake")
        shaken, rows, _ = self.generate("shaken", "--camera-shake-deg", "3")
        self.assertNotIn("camera_pitch_deg", base_rows[0])   # without the option: the columns of before
        self.assertEqual(list(rows[0].keys()), list(base_rows[0].keys()) + ["camera_pitch_deg", "camera_roll_deg"])
        for axis in ("camera_pitch_deg", "camera_roll_deg"):
            angles = [float(row[axis]) for row in rows]
            self.assertLessEqual(max(abs(a) for a in angles), 3.0)
            self.assertLess(min(angles), -0.5)                # both ways over a run of tens of frames
            self.assertGreater(max(angles), 0.5)
        for row, base_row in zip(rows, base_rows):
            self.assertEqual({k: v for k, v in row.items() if not k.startswith("camera_")}, base_row)
        for a, b in zip(self.images(base, "teach"), self.images(shaken, "teach")):
            np.testing.assert_array_equal(a, b)                # the teach run is untouched
        moved = [np.abs(a.astype(int) - b.astype(int)).mean()
                 for a, b in zip(self.images(base, "repeat"), self.images(shaken, "repeat"))]
        self.assertGreater(np.median(moved), 2.0)
        with contextlib.redirect_stderr(io.StringIO()) as stderr:
            with self.assertRaises(SystemExit) as caught:
                generate_route.main(["--output", self.tmp, "--camera-shake-deg", "12"])
        self.assertEqual(caught.exception.code, 2)
        self.assertIn("--camera-shake-deg must be in [0, 10]", stderr.getvalue())

    def test_bad_conditions_are_refused(self):
        with contextlib.redirect_stderr(io.StringIO()) as stderr:
            with self.assertRaises(SystemExit) as caught:
                generate_route.main(["--output", self.tmp, "--conditions", "glare,snow"])
        self.assertEqual(caught.exception.code, 2)
        self.assertIn("--conditions takes a comma-separated list", stderr.getvalue())


if __name__ == "__main__":
    unittest.main()
