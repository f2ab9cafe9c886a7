"""scripts/make_nordland_scenarios: scenario definitions and the files written, on a tiny fake dataset."""

import contextlib
import csv
import io
import os
import shutil
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # finds scripts_under_test
from scripts_under_test import load, ros_python_available

scenarios = load("make_nordland_scenarios")


def runs(values):
    """[(value, run length), ...] of consecutive equal values."""
    out = []
    for v in values:
        if out and out[-1][0] == v:
            out[-1][1] += 1
        else:
            out.append([v, 1])
    return [tuple(r) for r in out]


class DefinitionTest(unittest.TestCase):
    def test_spacing_2to1_rounds_halves_up_and_clamps(self):
        map_frames, query, keyframes, shifts = scenarios.spacing_2to1(7)
        self.assertEqual(map_frames, [0, 2, 4, 6])
        self.assertEqual(query, list(range(7)))
        self.assertEqual(keyframes, [0, 1, 1, 2, 2, 3, 3])
        self.assertEqual(shifts, [0] * 7)
        # 6 frames: map 0, 2, 4; query 5 would round to map index 3, which does not exist -> 2
        self.assertEqual(scenarios.spacing_2to1(6)[2], [0, 1, 1, 2, 2, 2])

    def test_stop_and_go_has_stops_slow_and_fast_stretches(self):
        sequence, labels = scenarios.stop_and_go_sequence(1500, np.random.default_rng([7, 2]))
        steps = np.diff(sequence)
        self.assertEqual(sequence[0], 0)
        self.assertGreaterEqual(sequence[-1], 1498)
        self.assertTrue(set(steps.tolist()) <= {0, 1, 2}, "frames only repeat, advance or skip one")
        stops = [n for (v, n) in runs(list(zip(sequence, labels))) if v[1] == "stop"]
        self.assertTrue(stops and all(3 <= n <= 8 for n in stops), stops)
        slow = [i for i in range(0, len(labels) - 1) if labels[i] == "slow" == labels[i + 1]]
        self.assertTrue(slow)
        # slow frames come in identical pairs
        slow_runs = [n for (v, n) in runs([(s, l) for s, l in zip(sequence, labels)]) if v[1] == "slow"]
        self.assertTrue(all(n == 2 for n in slow_runs), slow_runs)
        fast_steps = [sequence[i + 1] - sequence[i] for i in range(len(labels) - 1)
                      if labels[i] == "fast" == labels[i + 1]]
        self.assertTrue(fast_steps and all(step == 2 for step in fast_steps))

    def test_stop_and_go_is_reproducible(self):
        a = scenarios.stop_and_go_sequence(300, np.random.default_rng([1, 2]))
        b = scenarios.stop_and_go_sequence(300, np.random.default_rng([1, 2]))
        c = scenarios.stop_and_go_sequence(300, np.random.default_rng([2, 2]))
        self.assertEqual(a, b)
        self.assertNotEqual(a, c)

    def test_heading_offsets(self):
        shifts = scenarios.heading_offsets(2000, np.random.default_rng([3, 3]))
        self.assertEqual(len(shifts), 2000)
        self.assertEqual(set(shifts), {-3, -2, -1, 0, 1, 2, 3})
        stretch_lengths = [n for v, n in runs(shifts)[:-1] if v != 0]
        self.assertTrue(all(20 <= n <= 60 for n in stretch_lengths), stretch_lengths)


class WriteTest(unittest.TestCase):
    """A fake 'Nordland' of 12 frames (8x4 px): frame k is filled with 10 k (summer) or 10 k + 5 (winter)."""

    def setUp(self):
        import cv2
        self.cv2 = cv2
        self.tmp = tempfile.mkdtemp(prefix="test_scenarios_")
        self.data = os.path.join(self.tmp, "nordland")
        for season, offset in (("summer", 0), ("winter", 5)):
            os.makedirs(os.path.join(self.data, season))
            for k in range(12):
                image = np.full((4, 8, 3), 10 * k + offset + 40, np.uint8)
                image[:, 0] = 0          # left edge column
                image[:, 7] = 255        # right edge column
                cv2.imwrite(os.path.join(self.data, season, "images-%05d.png" % (10 * (k + 1))), image)
        self.out = os.path.join(self.tmp, "out")

    def tearDown(self):
        shutil.rmtree(self.tmp)

    def run_main(self, args):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
            code = scenarios.main(args)
        return code, err.getvalue()

    def ground_truth(self, name):
        with open(os.path.join(self.out, name, "ground_truth.csv")) as f:
            return list(csv.DictReader(f))

    def test_all_scenarios(self):
        code, err = self.run_main(["--output", self.out, "--data", self.data, "--seed", "4"])
        self.assertEqual(code, 0, err)
        # aligned: symlinks to the originals, in order
        aligned_query = sorted(os.listdir(os.path.join(self.out, "aligned", "query")))
        self.assertEqual(aligned_query[:2], ["00000.png", "00001.png"])
        link = os.path.join(self.out, "aligned", "query", "00003.png")
        self.assertTrue(os.path.islink(link))
        self.assertEqual(os.path.realpath(link), os.path.realpath(os.path.join(self.data, "winter", "images-00040.png")))
        rows = self.ground_truth("aligned")
        self.assertEqual([int(r["keyframe"]) for r in rows], list(range(12)))
        # 2:1 spacing: the map holds summer frames 0, 2, ..., 10
        self.assertEqual(len(os.listdir(os.path.join(self.out, "spacing_2to1", "map"))), 6)
        self.assertEqual(os.path.realpath(os.path.join(self.out, "spacing_2to1", "map", "00002.png")),
                         os.path.realpath(os.path.join(self.data, "summer", "images-00050.png")))
        rows = self.ground_truth("spacing_2to1")
        self.assertEqual([int(r["keyframe"]) for r in rows], [0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 5])
        self.assertEqual(rows[3]["keyframe_exact"], "1.5")
        # stop and go: each query image is the winter frame its ground truth names
        for r in self.ground_truth("stop_and_go"):
            image = self.cv2.imread(os.path.join(self.out, "stop_and_go", "query", "%05d.png" % int(r["query_index"])))
            self.assertEqual(int(image[0, 3, 0]), 10 * int(r["keyframe"]) + 45)
            self.assertEqual(r["query_source"], "winter/images-%05d.png" % (10 * (int(r["keyframe"]) + 1)))
        # heading offset: 12 frames are too few for a stretch (first one starts at 20 or later): nothing shifted
        rows = self.ground_truth("heading_offset")
        self.assertTrue(all(r["true_shift_px"] == "0" for r in rows))

    def test_stationary_frames_are_marked(self):
        # summer frames 4 and 5 identical (the train stands), winter frame 9 differs from 8 by 1 gray level only
        self.cv2.imwrite(os.path.join(self.data, "summer", "images-00060.png"),
                         self.cv2.imread(os.path.join(self.data, "summer", "images-00050.png")))
        image = self.cv2.imread(os.path.join(self.data, "winter", "images-00090.png"))
        image[:, 1:7] += 1
        self.cv2.imwrite(os.path.join(self.data, "winter", "images-00100.png"), image)
        code, err = self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "aligned,spacing_2to1"])
        self.assertEqual(code, 0, err)
        rows = self.ground_truth("aligned")
        self.assertEqual([int(r["keyframe_stationary"]) for r in rows], [1 if k in (4, 5) else 0 for k in range(12)])
        self.assertEqual([int(r["query_stationary"]) for r in rows], [1 if k in (8, 9) else 0 for k in range(12)])
        # 2:1 spacing: query 4 -> keyframe 2 = summer frame 4 (stationary), query 5 -> keyframe 3 = summer frame 6
        rows = self.ground_truth("spacing_2to1")
        self.assertEqual([int(r["keyframe_stationary"]) for r in rows[3:7]], [1, 1, 0, 0])

    def test_shifted_frames_are_new_files_with_replicated_edges(self):
        # make stretches start early by shifting every frame: patch the scenario's shift schedule
        original = scenarios.heading_offsets
        scenarios.heading_offsets = lambda count, rng: [2 if k % 2 else -1 for k in range(count)]
        try:
            code, err = self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "heading_offset"])
        finally:
            scenarios.heading_offsets = original
        self.assertEqual(code, 0, err)
        rows = self.ground_truth("heading_offset")
        self.assertEqual([int(r["true_shift_px"]) for r in rows[:3]], [-1, 2, -1])
        path = os.path.join(self.out, "heading_offset", "query", "00001.png")
        self.assertFalse(os.path.islink(path))
        shifted = self.cv2.imread(path)
        original_image = self.cv2.imread(os.path.join(self.data, "winter", "images-00020.png"))
        # content moved 2 px right: columns 0..2 replicate the old left edge (0), column 7 is old column 5
        np.testing.assert_array_equal(shifted[:, :3], 0)
        np.testing.assert_array_equal(shifted[:, 3:], original_image[:, 1:6])
        shifted = self.cv2.imread(os.path.join(self.out, "heading_offset", "query", "00000.png"))
        np.testing.assert_array_equal(shifted[:, 6:], 255)   # moved 1 px left, right edge replicated

    def test_rerun_replaces_old_frames(self):
        self.assertEqual(self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "aligned"])[0], 0)
        self.assertEqual(self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "aligned",
                                        "--first", "2", "--count", "10"])[0], 0)
        self.assertEqual(len(os.listdir(os.path.join(self.out, "aligned", "query"))), 10)
        rows = self.ground_truth("aligned")
        self.assertEqual(rows[0]["query_source"], "winter/images-00030.png")

    @unittest.skipUnless(ros_python_available(), "rosbag / sensor_msgs not importable (use /usr/bin/python3)")
    def test_bags(self):
        import rosbag
        code, err = self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "spacing_2to1", "--bags"])
        self.assertEqual(code, 0, err)
        messages = {}
        for name, count in (("map", 6), ("query", 12)):
            with rosbag.Bag(os.path.join(self.out, "spacing_2to1", name + ".bag")) as bag:
                messages[name] = [m for _, m, _ in bag.read_messages(topics=["/camera/image_raw"])]
            self.assertEqual(len(messages[name]), count)
            self.assertEqual((messages[name][0].width, messages[name][0].height, messages[name][0].encoding),
                             (8, 4, "bgr8"))

        def pixel(msg):   # row 0, column 3, blue
            return int(np.frombuffer(msg.data, np.uint8)[3 * 3])
        self.assertEqual(pixel(messages["map"][1]), 10 * 2 + 40)     # keyframe 1 = summer frame 2
        self.assertEqual(pixel(messages["query"][3]), 10 * 3 + 45)   # query 3 = winter frame 3

    def test_bad_input(self):
        code, err = self.run_main(["--output", self.out, "--data", os.path.join(self.tmp, "missing")])
        self.assertEqual(code, 2)
        code, err = self.run_main(["--output", os.path.join(self.data, "x"), "--data", self.data])
        self.assertEqual(code, 2)
        self.assertIn("inside the data folder", err)
        code, err = self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "sideways"])
        self.assertEqual(code, 2)
        os.remove(os.path.join(self.data, "winter", "images-00050.png"))
        code, err = self.run_main(["--output", self.out, "--data", self.data])
        self.assertEqual(code, 2)
        self.assertIn("not frame-aligned", err)


if __name__ == "__main__":
    unittest.main()
