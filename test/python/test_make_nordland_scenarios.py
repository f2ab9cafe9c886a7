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

    def test_distractor_plan_is_route_like_and_never_this_route(self):
        count = 200
        plan = scenarios.distractor_plan(count, 1000, np.random.default_rng([5, 4]), ("summer", "winter"))
        self.assertEqual(len(plan), 1000)
        self.assertEqual({e["season"] for e in plan}, {"summer", "winter"})
        stretch_keys = [(e["season"], e["blend_weight"], e["shift_rows"], e["gain"]) for e in plan]
        lengths = [n for _, n in runs(stretch_keys)]
        self.assertTrue(all(20 <= n <= 100 for n in lengths[:-1]), lengths)   # the last one is cut at 1000
        for a, b in zip(plan, plan[1:]):
            if (a["season"], a["gain"]) == (b["season"], b["gain"]):   # within a stretch: consecutive frames
                self.assertEqual(b["frame"], a["frame"] + 1)
        for e in plan:
            self.assertTrue(0 <= e["frame"] < count)
            distance = (e["blend_frame"] - e["frame"]) % count
            self.assertTrue(count // 4 <= min(distance, count - distance), e)
            self.assertIn(e["shift_rows"], (-4, -3, -2, 2, 3, 4))
            self.assertTrue(0.25 <= e["blend_weight"] <= 0.4 and 0.75 <= e["gain"] <= 1.25, e)
        summer_only = scenarios.distractor_plan(count, 300, np.random.default_rng([5, 4]))
        self.assertEqual({e["season"] for e in summer_only}, {"summer"})

    def test_distractor_image_mirrors_blends_shifts_and_scales(self):
        image = np.array([[10, 20, 30], [40, 50, 60], [70, 80, 90]], np.uint8)
        blend = np.full((3, 3), 100, np.uint8)
        # mirrored: rows [30 20 10], [60 50 40], [90 80 70]; blend 0.5 with 100; down 1 row, top row replicated
        out = scenarios.distractor_image(image, blend, 0.5, 1, 2.0)
        np.testing.assert_array_equal(out, [[130, 120, 110], [130, 120, 110], [160, 150, 140]])
        out = scenarios.distractor_image(image, blend, 0.0, -1, 3.0)   # up 1 row; 90 * 3 saturates
        np.testing.assert_array_equal(out, [[180, 150, 120], [255, 240, 210], [255, 240, 210]])

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
        self.assertFalse(os.path.exists(os.path.join(self.out, "distractors")), "only made when asked for")

    def test_distractors_follow_the_route_in_the_map(self):
        code, err = self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "distractors",
                                   "--distractors", "30", "--distractor-seasons", "summer,winter"])
        self.assertEqual(code, 0, err)
        folder = os.path.join(self.out, "distractors")
        map_files = sorted(os.listdir(os.path.join(folder, "map")))
        self.assertEqual(map_files, ["%05d.png" % k for k in range(42)])
        self.assertEqual(len(os.listdir(os.path.join(folder, "query"))), 12)
        # the route first, as in aligned: links to the summer frames in order
        self.assertEqual(os.path.realpath(os.path.join(folder, "map", "00011.png")),
                         os.path.realpath(os.path.join(self.data, "summer", "images-00120.png")))
        self.assertEqual([int(r["keyframe"]) for r in self.ground_truth("distractors")], list(range(12)))
        with open(os.path.join(folder, "distractors.csv")) as f:
            made = list(csv.DictReader(f))
        self.assertEqual([int(r["keyframe"]) for r in made], list(range(12, 42)))
        for r in made:
            path = os.path.join(folder, "map", "%05d.png" % int(r["keyframe"]))
            self.assertFalse(os.path.islink(path))
            distractor = self.cv2.imread(path)
            # mirrored: the fake frames' dark left and bright right edge columns swap sides
            self.assertTrue((distractor[:, 0] >= 190).all() and (distractor[:, 7] == 0).all(), r)
            frame, blend_frame = int(r["frame"]), int(r["blend_frame"])
            expected = scenarios.distractor_image(
                self.cv2.imread(os.path.join(self.data, r["season"], "images-%05d.png" % (10 * (frame + 1)))),
                self.cv2.imread(os.path.join(self.data, r["season"], "images-%05d.png" % (10 * (blend_frame + 1)))),
                float(r["blend_weight"]), int(r["shift_rows"]), float(r["gain"]))
            np.testing.assert_allclose(distractor, expected, atol=1)   # csv rounds weight and gain to 4 decimals

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

    def test_map_season_winter_swaps_the_roles(self):
        # summer frames 4 and 5 identical (the summer train stands): with the winter map they are query frames;
        # summer frame 2 and winter frame 6 black (dark): the query's and the keyframe's flags of their season
        self.cv2.imwrite(os.path.join(self.data, "summer", "images-00060.png"),
                         self.cv2.imread(os.path.join(self.data, "summer", "images-00050.png")))
        self.cv2.imwrite(os.path.join(self.data, "summer", "images-00030.png"), np.zeros((4, 8, 3), np.uint8))
        self.cv2.imwrite(os.path.join(self.data, "winter", "images-00070.png"), np.zeros((4, 8, 3), np.uint8))
        code, err = self.run_main(["--output", self.out, "--data", self.data, "--map-season", "winter",
                                   "--scenarios", "aligned,spacing_2to1,stop_and_go,distractors", "--distractors", "5"])
        self.assertEqual(code, 0, err)
        self.assertEqual(os.path.realpath(os.path.join(self.out, "aligned", "map", "00003.png")),
                         os.path.realpath(os.path.join(self.data, "winter", "images-00040.png")))
        self.assertEqual(os.path.realpath(os.path.join(self.out, "aligned", "query", "00003.png")),
                         os.path.realpath(os.path.join(self.data, "summer", "images-00040.png")))
        self.assertEqual(os.path.realpath(os.path.join(self.out, "spacing_2to1", "map", "00002.png")),
                         os.path.realpath(os.path.join(self.data, "winter", "images-00050.png")))
        rows = self.ground_truth("aligned")
        self.assertEqual([int(r["query_stationary"]) for r in rows], [1 if k in (4, 5) else 0 for k in range(12)])
        self.assertEqual([int(r["keyframe_stationary"]) for r in rows], [0] * 12)
        self.assertEqual([int(r["query_dark"]) for r in rows], [1 if k == 2 else 0 for k in range(12)])
        self.assertEqual([int(r["keyframe_dark"]) for r in rows], [1 if k == 6 else 0 for k in range(12)])
        # 2:1: query 5 -> keyframe 3 = winter frame 6 (dark); query 2 (summer frame 2) dark
        rows = self.ground_truth("spacing_2to1")
        self.assertEqual([int(r["keyframe_dark"]) for r in rows], [1 if k in (5, 6) else 0 for k in range(12)])
        self.assertEqual([int(r["query_dark"]) for r in rows], [1 if k == 2 else 0 for k in range(12)])
        for r in self.ground_truth("stop_and_go"):   # each query image is the summer frame its ground truth names
            image = self.cv2.imread(os.path.join(self.out, "stop_and_go", "query", "%05d.png" % int(r["query_index"])))
            keyframe = int(r["keyframe"])
            self.assertEqual(int(image[0, 3, 0]), 0 if keyframe == 2 else 10 * (4 if keyframe == 5 else keyframe) + 40)
            self.assertEqual(r["query_source"], "summer/images-%05d.png" % (10 * (int(r["keyframe"]) + 1)))
        with open(os.path.join(self.out, "distractors", "distractors.csv")) as f:
            self.assertEqual({r["season"] for r in csv.DictReader(f)}, {"winter"}, "the map's season by default")

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

    def test_a_rerun_without_bags_removes_the_earlier_runs_bags(self):
        # a map.bag of an earlier run (perhaps of the other season) was left beside the new frames
        if not ros_python_available():
            self.skipTest("needs the ROS Python modules (rosbag)")
        code, err = self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "aligned", "--bags"])
        self.assertEqual(code, 0, err)
        self.assertTrue(os.path.exists(os.path.join(self.out, "aligned", "map.bag")))
        code, err = self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "aligned",
                                   "--map-season", "winter"])
        self.assertEqual(code, 0, err)
        self.assertEqual(sorted(os.listdir(os.path.join(self.out, "aligned"))), ["ground_truth.csv", "map", "query"])

    def test_a_scenario_stopped_half_way_has_no_ground_truth(self):
        # An interrupted distractors scenario kept its ground truth beside part of its map, and run_benchmarks
        # timed it as the whole. The ground truth is now written last: a rerun stopped while it writes the
        # distractors (here by an error there) leaves the scenario without one, the earlier run's gone too.
        args = ["--output", self.out, "--data", self.data, "--scenarios", "distractors", "--distractors", "30"]
        code, err = self.run_main(args)
        self.assertEqual(code, 0, err)
        folder = os.path.join(self.out, "distractors")
        self.assertEqual(sorted(os.listdir(folder)), ["distractors.csv", "ground_truth.csv", "map", "query"])
        from unittest import mock
        with mock.patch.object(scenarios, "write_distractors", side_effect=scenarios.InputError("stopped here")):
            code, err = self.run_main(args)
        self.assertEqual(code, 2, err)
        self.assertIn("stopped here", err)
        self.assertNotIn("ground_truth.csv", os.listdir(folder))
        self.assertNotIn("distractors.csv", os.listdir(folder))

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
        # distractors: the map bag holds the route and then the distractors
        code, err = self.run_main(["--output", self.out, "--data", self.data, "--scenarios", "distractors", "--bags",
                                   "--distractors", "5"])
        self.assertEqual(code, 0, err)
        for name, count in (("map", 17), ("query", 12)):
            with rosbag.Bag(os.path.join(self.out, "distractors", name + ".bag")) as bag:
                self.assertEqual(bag.get_message_count(), count)

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

    def test_values_that_were_a_traceback_or_silently_nothing_are_refused(self):
        # --seed -1 was a numpy traceback; --dark-mean nan marked no frame dark (nan compares false),
        # while --stationary-change nan was refused.
        for option, value, words in (("--seed", "-1", "--seed must be >= 0"),
                                     ("--dark-mean", "nan", "--dark-mean must be a gray level in [0, 255], got nan"),
                                     ("--dark-std", "nan", "--dark-std must be a gray level in [0, 255], got nan"),
                                     ("--dark-mean", "-3", "--dark-mean must be a gray level"),
                                     ("--rate", "inf", "--rate must be > 0 and finite"),  # a traceback, bags half made
                                     ("--count", "11", "--first 2 --count 11 asks for frames up to 12; the data has 12 "
                                                       "(frames 0-11)")):  # cut short to 10 without a word
            code, err = self.run_main(["--output", self.out, "--data", self.data, "--first", "2", option, value])
            self.assertEqual(code, 2, option + " " + value)
            self.assertIn(words, err)
            self.assertFalse(os.path.exists(self.out) and os.listdir(self.out), option)


if __name__ == "__main__":
    unittest.main()
